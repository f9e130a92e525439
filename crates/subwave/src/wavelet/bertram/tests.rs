//! Tests of the generalized B-spline wavelets against independent computations: 1-D lifting
//! on the rows and columns of a periodic grid (§4.2), B-spline subdivision masks (Table 2),
//! Catmull-Clark at regular vertices and MLCA by hand (eq. 4.7). The stability experiment of
//! §5.2 is in [`crate::wavelet::stability`].

use glam::DVec3;

use super::*;
use crate::generate;
use crate::subdivision::{subdivide, Refinement};
use crate::wavelet::floor_div_const;

/// splitmix64: deterministic noise without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [-1, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
    fn vec3(&mut self) -> DVec3 {
        DVec3::new(self.unit(), self.unit(), self.unit())
    }
    fn int(&mut self, range: i64) -> i64 {
        (self.next() % (2 * range as u64 + 1)) as i64 - range
    }
}

fn test_meshes() -> Vec<(&'static str, Mesh)> {
    vec![
        ("cube", generate::cube()),
        ("torus", generate::torus(1.0, 0.4, 5, 4, false)),
        ("grid", generate::grid(3, 2, false)),
        ("pyramid", generate::pyramid()),
    ]
}

fn hierarchy(mesh: &Mesh, levels: u32) -> Refinement {
    quad_hierarchy(mesh, levels).unwrap()
}

fn max_diff(a: &[DVec3], b: &[DVec3]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length())
        .fold(0.0, f64::max)
}

const BOUNDARIES: [Boundary; 2] = [Boundary::Averages, Boundary::Symmetric];

#[test]
fn table_1_inverse_lifts() {
    // Table 1, lower half (in order of computation).
    let expect: [&[(LiftKind, f64, f64)]; 3] = [
        &[(S, -0.25, 1.0), (W, 0.5, 1.0)],
        &[(S, -3.0 / 16.0, 0.5), (W, 1.0, 1.0), (S, 0.25, 1.0)],
        &[
            (S, -5.0 / 32.0, 0.25),
            (W, 4.0 / 3.0, 1.0),
            (S, 9.0 / 16.0, 1.0),
            (W, 1.0 / 6.0, 1.0),
        ],
    ];
    for (d, e) in Degree::ALL.iter().zip(expect) {
        let got = d.synthesis_lifts();
        assert_eq!(got.len(), e.len());
        for (g, &(k, a, b)) in got.iter().zip(e) {
            assert_eq!(g.kind, k);
            assert!((g.a - a).abs() < 1e-15 && (g.b - b).abs() < 1e-15, "{d:?}");
        }
        // §4.3: the integer lifts are Table 1 with the last s-lift divided by 1, 2, 4.
        let div = [1.0, 2.0, 4.0][d.analysis_lifts().len() - 2];
        for (i, (f, n)) in d.analysis_lifts().iter().zip(d.integer_lifts()).enumerate() {
            let last = i + 1 == d.analysis_lifts().len();
            let s = if last { div } else { 1.0 };
            assert_eq!(f.kind, n.kind);
            assert!((f.a / s - n.a_num as f64 / n.a_den as f64).abs() < 1e-15);
            assert_eq!(f.b / s, n.b as f64);
        }
    }
}

#[test]
fn eq_4_7_bicubic_analysis_rules() {
    // The cubic analysis composed by hand from eq. 4.7, on the pyramid (valences 3 and 4,
    // triangles and a quad): v ← v + ¼f̄ − ē; e ← e − ½f̄; f ← f + 4v̄ − 4ē; e ← e − 2v̄;
    // v ← 4v + 9/16 f̄ + 3ē; e ← 2e + ¾ f̄.
    let r = hierarchy(&generate::pyramid(), 1);
    let t = &r.topologies[0];
    let mut rng = Rng(7);
    let data: Vec<DVec3> = (0..r.positions.len()).map(|_| rng.vec3()).collect();
    let (nv, ne) = (t.num_vertices as usize, t.num_edges());
    let mut h = data.clone();
    let m = |idx: &[u32], off: usize, h: &[DVec3]| {
        idx.iter().map(|&i| h[off + i as usize]).sum::<DVec3>() / idx.len() as f64
    };
    let (fo, eo) = (nv + ne, nv);
    let upd_v = |h: &mut Vec<DVec3>, cv: f64, cf: f64, ce: f64| {
        let old = h.clone();
        for v in 0..nv {
            h[v] = cv * old[v]
                + cf * m(t.vertex_faces(v), fo, &old)
                + ce * m(t.vertex_edges(v), eo, &old);
        }
    };
    let upd_e_f = |h: &mut Vec<DVec3>, ce: f64, cf: f64| {
        let old = h.clone();
        for e in 0..ne {
            h[eo + e] = ce * old[eo + e] + cf * m(t.edge_faces(e), fo, &old);
        }
    };
    upd_v(&mut h, 1.0, 0.25, -1.0);
    upd_e_f(&mut h, 1.0, -0.5);
    let old = h.clone();
    for f in 0..t.num_faces() {
        h[fo + f] =
            old[fo + f] + 4.0 * m(t.face_vertices(f), 0, &old) - 4.0 * m(t.face_edges(f), eo, &old);
    }
    let old = h.clone();
    for e in 0..ne {
        h[eo + e] = old[eo + e] - 2.0 * m(&t.edge_vertices[e], 0, &old);
    }
    upd_v(&mut h, 4.0, 9.0 / 16.0, 3.0);
    upd_e_f(&mut h, 2.0, 0.75);
    let mut got = data;
    BSplineWavelet::new(Degree::Cubic)
        .analyze_level(t, &mut got)
        .unwrap();
    assert!(max_diff(&got, &h) < 1e-13, "{}", max_diff(&got, &h));
}

#[test]
fn perfect_reconstruction_float() {
    for (name, mesh) in test_meshes() {
        let r = hierarchy(&mesh, 3);
        let mut rng = Rng(1);
        let fine: Vec<DVec3> = r.positions.iter().map(|p| *p + 0.1 * rng.vec3()).collect();
        let diag = crate::mesh::diagonal_of(&fine);
        for degree in Degree::ALL {
            for boundary in BOUNDARIES {
                let w = BSplineWavelet { degree, boundary };
                let mut data = fine.clone();
                w.analyze(&r.topologies, &mut data).unwrap();
                assert!(
                    max_diff(&data, &fine) > 1e-3,
                    "{name} {degree:?}: analysis did nothing"
                );
                w.synthesize(&r.topologies, &mut data).unwrap();
                let err = max_diff(&data, &fine);
                assert!(err <= 1e-12 * diag, "{name} {degree:?} {boundary:?}: {err}");
            }
        }
    }
}

fn to_int(p: &[DVec3], scale: f64) -> Vec<[i64; 3]> {
    p.iter()
        .map(|x| {
            [
                (x.x * scale).round() as i64,
                (x.y * scale).round() as i64,
                (x.z * scale).round() as i64,
            ]
        })
        .collect()
}

#[test]
fn perfect_reconstruction_integer() {
    for (name, mesh) in test_meshes() {
        let r = hierarchy(&mesh, 3);
        let mut rng = Rng(2);
        let fine: Vec<[i64; 3]> = to_int(&r.positions, 1e6)
            .into_iter()
            .map(|p| p.map(|c| c + rng.int(1000)))
            .collect();
        for degree in Degree::ALL {
            for boundary in BOUNDARIES {
                let w = BSplineWavelet { degree, boundary };
                let mut data = fine.clone();
                w.analyze_int(&r.topologies, &mut data).unwrap();
                assert_ne!(data, fine);
                w.synthesize_int(&r.topologies, &mut data).unwrap();
                assert_eq!(data, fine, "{name} {degree:?} {boundary:?}");
                // i32 coordinates.
                let small: Vec<[i32; 3]> =
                    fine.iter().map(|p| p.map(|c| (c / 1000) as i32)).collect();
                let mut d32 = small.clone();
                w.analyze_int(&r.topologies, &mut d32).unwrap();
                w.synthesize_int(&r.topologies, &mut d32).unwrap();
                assert_eq!(d32, small, "{name} {degree:?} i32");
            }
        }
    }
}

#[test]
fn integer_transform_tracks_rescaled_float_transform() {
    // The integer coefficients differ from the float transform with the same (rescaled) lifts
    // only by the accumulated rounding: a few units, whatever the coordinate scale.
    let r = hierarchy(&generate::pyramid(), 2);
    let mut rng = Rng(3);
    let fine: Vec<[i64; 3]> = to_int(&r.positions, 1e6)
        .into_iter()
        .map(|p| p.map(|c| c + rng.int(100_000)))
        .collect();
    for degree in Degree::ALL {
        let w = BSplineWavelet::new(degree);
        let mut ints = fine.clone();
        w.analyze_int(&r.topologies, &mut ints).unwrap();
        let mut floats: Vec<DVec3> = fine
            .iter()
            .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
            .collect();
        let sizes = level_sizes(&r.topologies).unwrap();
        for (j, t) in r.topologies.iter().enumerate().rev() {
            let ctx = Ctx::new(t, Boundary::Averages);
            for l in degree.integer_lifts() {
                let fl = Lift {
                    kind: l.kind,
                    a: l.a_num as f64 / l.a_den as f64,
                    b: l.b as f64,
                };
                ctx.lift(fl, &mut floats[..sizes[j + 1]]);
            }
        }
        let err = ints
            .iter()
            .zip(&floats)
            .map(|(i, f)| {
                (DVec3::new(i[0] as f64, i[1] as f64, i[2] as f64) - *f)
                    .abs()
                    .max_element()
            })
            .fold(0.0, f64::max);
        assert!(err < 50.0, "{degree:?}: integer vs float {err}");
        assert!(
            floats
                .iter()
                .map(|f| f.abs().max_element())
                .fold(0.0, f64::max)
                > 1e5
        );
    }
}

/// The `i64` fast path of the integer lifts gives the `i128` results bit for bit, including
/// coordinates large enough that some updates overflow `i64` and take the `i128` path.
#[test]
fn integer_fast_path_matches_i128() {
    let mut rng = Rng(11);
    for _ in 0..20_000 {
        let n = rng.int(1 << 40) as i128 * rng.int(1 << 20) as i128;
        let d = 1 + rng.int(1 << 12).unsigned_abs() as i128;
        assert_eq!(
            round_div64(n as i64, d as i64).map(i128::from),
            Some(round_div(n, d)),
            "{n}/{d}"
        );
    }
    let mut meshes = test_meshes();
    meshes.push(("grid", generate::grid(4, 3, false)));
    for (name, mesh) in meshes {
        let r = hierarchy(&mesh, 3);
        let sizes = level_sizes(&r.topologies).unwrap();
        for scale in [1e6, 1e17] {
            let fine: Vec<[i64; 3]> = to_int(&r.positions, scale)
                .into_iter()
                .map(|p| p.map(|c| c + rng.int(1000)))
                .collect();
            for degree in Degree::ALL {
                for boundary in BOUNDARIES {
                    let run = |int64: bool, inverse: bool, data: &mut [[i64; 3]]| {
                        let order: Vec<usize> = if inverse {
                            (0..r.topologies.len()).collect()
                        } else {
                            (0..r.topologies.len()).rev().collect()
                        };
                        for j in order {
                            let mut ctx = Ctx::new(&r.topologies[j], boundary);
                            ctx.int64 = int64;
                            let d = &mut data[..sizes[j + 1]];
                            let lifts = degree.integer_lifts();
                            if inverse {
                                for l in lifts.iter().rev() {
                                    ctx.int_lift(*l, d, true).unwrap();
                                }
                            } else {
                                for l in lifts {
                                    ctx.int_lift(*l, d, false).unwrap();
                                }
                            }
                        }
                    };
                    let (mut fast, mut slow) = (fine.clone(), fine.clone());
                    run(true, false, &mut fast);
                    run(false, false, &mut slow);
                    assert_eq!(fast, slow, "{name} {degree:?} {boundary:?} {scale} forward");
                    // The whole-hierarchy transforms carry each level's smallness to the next
                    // instead of scanning it again: the same coefficients.
                    let w = BSplineWavelet { degree, boundary };
                    let mut public = fine.clone();
                    w.analyze_int(&r.topologies, &mut public).unwrap();
                    assert_eq!(
                        public, slow,
                        "{name} {degree:?} {boundary:?} {scale} analyze_int"
                    );
                    run(true, true, &mut fast);
                    run(false, true, &mut slow);
                    assert_eq!(fast, slow, "{name} {degree:?} {boundary:?} {scale} inverse");
                    assert_eq!(fast, fine);
                    w.synthesize_int(&r.topologies, &mut public).unwrap();
                    assert_eq!(
                        public, fine,
                        "{name} {degree:?} {boundary:?} {scale} synthesize_int"
                    );
                    // Arbitrary coefficients, small except for the finest face details, far
                    // beyond the fast bound (the quintic's first inverse pass, reading them,
                    // would overflow `i64`): the synthesis scans the details it did not
                    // produce.
                    let mut coeffs: Vec<[i64; 3]> =
                        fine.iter().map(|p| p.map(|c| c / 1000)).collect();
                    let last = &r.topologies[r.topologies.len() - 1];
                    let f0 = last.num_vertices as usize + last.num_edges();
                    for c in &mut coeffs[f0..] {
                        c[0] = (1 << 59) + rng.int(1000);
                    }
                    let (mut a, mut b) = (coeffs.clone(), coeffs);
                    w.synthesize_int(&r.topologies, &mut a).unwrap();
                    run(false, true, &mut b);
                    assert_eq!(a, b, "{name} {degree:?} {boundary:?} {scale} large details");
                }
            }
        }
    }
}

#[test]
fn integer_overflow_is_an_error() {
    let r = hierarchy(&generate::cube(), 1);
    let mut data = vec![[i32::MAX - 1, 0, i32::MIN + 1]; r.positions.len()];
    for (i, d) in data.iter_mut().enumerate() {
        if i % 2 == 1 {
            d[0] = i32::MIN + 1;
        }
    }
    let err = BSplineWavelet::new(Degree::Quintic).analyze_int(&r.topologies, &mut data);
    assert!(err.unwrap_err().to_string().contains("does not fit in i32"));
}

#[test]
fn wrong_lengths_are_errors() {
    let r = hierarchy(&generate::cube(), 2);
    let w = BSplineWavelet::new(Degree::Cubic);
    let mut short = vec![DVec3::ZERO; r.positions.len() - 1];
    assert!(w.analyze(&r.topologies, &mut short).is_err());
    assert!(w.synthesize_level(&r.topologies[0], &mut short).is_err());
    assert!(w.subdivide(&r.topologies, &[DVec3::ZERO; 3]).is_err());
    // Levels that are not successive splits.
    let other = hierarchy(&generate::pyramid(), 1);
    let mixed = vec![r.topologies[0].clone(), other.topologies[0].clone()];
    assert!(level_sizes(&mixed).is_err());
    assert!(level_sizes(&[]).is_err());
    assert_eq!(detail_range(&r.topologies, 0).unwrap(), 8..26);
    assert!(detail_range(&r.topologies, 2).is_err());
}

#[test]
fn linear_synthesis_is_bilinear_subdivision() {
    for (name, mesh) in test_meshes() {
        let r = hierarchy(&mesh, 3);
        let got = BSplineWavelet::new(Degree::Linear)
            .subdivide(&r.topologies, &mesh.positions)
            .unwrap();
        // `r.positions` are the crate's bilinear scheme (`Scheme::Bilinear`).
        let err = max_diff(&got, &r.positions);
        assert!(err < 1e-14, "{name}: {err}");
    }
}

fn cc_opts(levels: u32) -> SubdivideOptions {
    SubdivideOptions {
        scheme: Scheme::CatmullClark,
        levels,
        ..SubdivideOptions::default()
    }
}

#[test]
fn bicubic_is_catmull_clark_on_regular_torus() {
    // Every vertex of a quad torus has valence 4: MLCA and Catmull-Clark coincide.
    let mut mesh = generate::torus(1.0, 0.4, 6, 5, false);
    let mut rng = Rng(4);
    for p in &mut mesh.positions {
        *p += 0.05 * rng.vec3();
    }
    let r = hierarchy(&mesh, 3);
    let cc = subdivide(&mesh, &cc_opts(3)).unwrap();
    for boundary in BOUNDARIES {
        let w = BSplineWavelet {
            degree: Degree::Cubic,
            boundary,
        };
        let got = w.subdivide(&r.topologies, &mesh.positions).unwrap();
        let err = max_diff(&got, &cc.positions);
        assert!(err < 1e-14, "{err}");
    }
}

#[test]
fn bicubic_is_catmull_clark_away_from_boundary() {
    let (nx, ny) = (8, 7);
    let flat = generate::grid(nx, ny, false);
    let mut mesh = flat.clone();
    let mut rng = Rng(5);
    for p in &mut mesh.positions {
        p.z = rng.unit();
    }
    let levels = 3;
    let r = hierarchy(&mesh, levels);
    // Parameter coordinates of the fine vertices: the bilinear refinement of the flat grid.
    let param = hierarchy(&flat, levels).positions;
    let cc = subdivide(&mesh, &cc_opts(levels)).unwrap();
    let got = BSplineWavelet::new(Degree::Cubic)
        .subdivide(&r.topologies, &mesh.positions)
        .unwrap();
    let (mut compared, mut differ_near_boundary) = (0, 0);
    for (i, u) in param.iter().enumerate() {
        let dist = u.x.min(nx as f64 - u.x).min(u.y).min(ny as f64 - u.y);
        let d = (got[i] - cc.positions[i]).length();
        if dist > 2.0 {
            assert!(d < 1e-14, "vertex {i} at {u}: {d}");
            compared += 1;
        } else if d > 1e-6 {
            differ_near_boundary += 1;
        }
    }
    assert!(compared > 300, "{compared}");
    // The boundary rules do differ (Catmull-Clark has B-spline boundary curves).
    assert!(differ_near_boundary > 10);
}

#[test]
fn bicubic_is_mlca_at_extraordinary_vertices() {
    // One level on the cube (all vertices of valence 3), by the MLCA rules of eq. 4.7's
    // inverse: f = centroid, e = ¼(v0 + v1 + f0 + f1), v = ½v + ¼ v̄_v + ¼ f̄_v.
    let mesh = generate::cube();
    let r = hierarchy(&mesh, 1);
    let t = &r.topologies[0];
    let got = BSplineWavelet::new(Degree::Cubic)
        .subdivide(&r.topologies, &mesh.positions)
        .unwrap();
    let p = &mesh.positions;
    let (nv, ne) = (t.num_vertices as usize, t.num_edges());
    let fp: Vec<DVec3> = (0..t.num_faces())
        .map(|f| {
            t.face_vertices(f)
                .iter()
                .map(|&v| p[v as usize])
                .sum::<DVec3>()
                / 4.0
        })
        .collect();
    for v in 0..nv {
        let ring: DVec3 = t.ring(v).map(|u| p[u as usize]).sum::<DVec3>() / 3.0;
        let faces: DVec3 = t
            .vertex_faces(v)
            .iter()
            .map(|&f| fp[f as usize])
            .sum::<DVec3>()
            / 3.0;
        let want = 0.5 * p[v] + 0.25 * ring + 0.25 * faces;
        assert!((got[v] - want).length() < 1e-15);
        // Catmull-Clark would give (n-2)/n v + ...: different at valence 3.
        assert!((got[v] - p[v] * (11.0 / 18.0)).length() > 0.01 || want.length() < 1e-9);
    }
    for e in 0..ne {
        let [a, b] = t.edge_vertices[e];
        let f = t.edge_faces(e);
        let want = 0.25 * (p[a as usize] + p[b as usize] + fp[f[0] as usize] + fp[f[1] as usize]);
        assert!((got[nv + e] - want).length() < 1e-15);
    }
    for (f, c) in fp.iter().enumerate() {
        assert!((got[nv + ne + f] - *c).length() < 1e-15);
    }
}

/// Map from grid coordinates `(i, j)` of a periodic `nu × nv` quad torus (as
/// `generate::torus` numbers it) to vertex indices, for each level of its hierarchy.
fn torus_grid_maps(nu: usize, nv: usize, levels: &[Topology]) -> Vec<Vec<Vec<usize>>> {
    let mut maps = vec![(0..nu)
        .map(|i| (0..nv).map(|j| i * nv + j).collect::<Vec<_>>())
        .collect::<Vec<_>>()];
    for t in levels {
        let prev = maps.last().unwrap();
        let (n, m) = (prev.len(), prev[0].len());
        let (vc, ec) = (t.num_vertices as usize, t.num_edges());
        let edge = |a: usize, b: usize| vc + t.find_edge(a as u32, b as u32).unwrap() as usize;
        // The face with corners (i, j), (i+1, j), (i+1, j+1), (i, j+1).
        let face = |i: usize, j: usize| {
            let want = prev[i][j] as u32;
            let diag = prev[(i + 1) % n][(j + 1) % m] as u32;
            (0..t.num_faces())
                .find(|&f| {
                    let fv = t.face_vertices(f);
                    fv.contains(&want) && fv.contains(&diag)
                })
                .unwrap()
                + vc
                + ec
        };
        let mut next = vec![vec![0; 2 * m]; 2 * n];
        for i in 0..n {
            for j in 0..m {
                next[2 * i][2 * j] = prev[i][j];
                next[2 * i + 1][2 * j] = edge(prev[i][j], prev[(i + 1) % n][j]);
                next[2 * i][2 * j + 1] = edge(prev[i][j], prev[i][(j + 1) % m]);
                next[2 * i + 1][2 * j + 1] = face(i, j);
            }
        }
        maps.push(next);
    }
    maps
}

/// The 1-D periodic DWT of eqs. 3.8–3.10 in place (`s_i` at `2i`, `w_i` at `2i + 1`).
fn dwt_1d(x: &mut [DVec3], lifts: &[Lift]) {
    let n = x.len() / 2;
    for l in lifts {
        let old = x.to_vec();
        for i in 0..n {
            match l.kind {
                S => {
                    let wl = old[(2 * i + 2 * n - 1) % (2 * n)];
                    x[2 * i] = l.a * wl + l.b * old[2 * i] + l.a * old[2 * i + 1];
                }
                W => {
                    let sr = old[(2 * i + 2) % (2 * n)];
                    x[2 * i + 1] = l.a * old[2 * i] + l.b * old[2 * i + 1] + l.a * sr;
                }
            }
        }
    }
}

#[test]
#[allow(clippy::needless_range_loop)] // grid indices read clearer than iterators here
fn regular_grid_is_tensor_product_of_1d_dwt() {
    // §4.2: on a rectilinear grid the generalized lifts are the tensor product of the 1-D
    // ones. A 1-D DWT of every row, then of every column, must give the mesh transform.
    let (nu, nv) = (4, 3);
    let mesh = generate::torus(1.0, 0.4, nu as u32, nv as u32, false);
    let r = hierarchy(&mesh, 1);
    let maps = torus_grid_maps(nu, nv, &r.topologies);
    let map = &maps[1];
    let mut rng = Rng(6);
    let fine: Vec<DVec3> = (0..r.positions.len()).map(|_| rng.vec3()).collect();
    for degree in Degree::ALL {
        let mut got = fine.clone();
        BSplineWavelet::new(degree)
            .analyze_level(&r.topologies[0], &mut got)
            .unwrap();
        let (n, m) = (2 * nu, 2 * nv);
        let mut grid: Vec<Vec<DVec3>> = (0..n)
            .map(|i| (0..m).map(|j| fine[map[i][j]]).collect())
            .collect();
        for row in &mut grid {
            dwt_1d(row, degree.analysis_lifts());
        }
        for j in 0..m {
            let mut col: Vec<DVec3> = (0..n).map(|i| grid[i][j]).collect();
            dwt_1d(&mut col, degree.analysis_lifts());
            for i in 0..n {
                grid[i][j] = col[i];
            }
        }
        for i in 0..n {
            for j in 0..m {
                let d = (grid[i][j] - got[map[i][j]]).length();
                assert!(d < 1e-12, "{degree:?} ({i}, {j}): {d}");
            }
        }
    }
}

#[test]
fn zero_detail_synthesis_is_tensor_bspline_subdivision() {
    // Table 2's l̃ (Pascal's triangle / 2^n): B-spline refinement of degree 1, 3, 5 applied to
    // the rows and columns of a periodic grid, two levels.
    let masks: [(&[f64], &[f64]); 3] = [
        (&[1.0], &[0.5, 0.5]),
        (&[0.125, 0.75, 0.125], &[0.5, 0.5]),
        (
            &[3.0 / 16.0, 5.0 / 8.0, 3.0 / 16.0],
            &[1.0 / 32.0, 15.0 / 32.0, 15.0 / 32.0, 1.0 / 32.0],
        ),
    ];
    let refine_1d = |x: &[DVec3], even: &[f64], odd: &[f64]| -> Vec<DVec3> {
        let n = x.len() as isize;
        let at = |k: isize| x[k.rem_euclid(n) as usize];
        let mut y = Vec::new();
        for i in 0..n {
            let h = (even.len() / 2) as isize;
            y.push(
                (0..even.len())
                    .map(|k| even[k] * at(i + k as isize - h))
                    .sum(),
            );
            let h = (odd.len() / 2 - 1) as isize;
            y.push(
                (0..odd.len())
                    .map(|k| odd[k] * at(i + k as isize - h))
                    .sum(),
            );
        }
        y
    };
    let (nu, nv) = (5, 4);
    let mut mesh = generate::torus(1.0, 0.4, nu as u32, nv as u32, false);
    let mut rng = Rng(8);
    for p in &mut mesh.positions {
        *p += 0.1 * rng.vec3();
    }
    let r = hierarchy(&mesh, 2);
    let maps = torus_grid_maps(nu, nv, &r.topologies);
    for (degree, (even, odd)) in Degree::ALL.into_iter().zip(masks) {
        let got = BSplineWavelet::new(degree)
            .subdivide(&r.topologies, &mesh.positions)
            .unwrap();
        let mut grid: Vec<Vec<DVec3>> = maps[0]
            .iter()
            .map(|row| row.iter().map(|&k| mesh.positions[k]).collect())
            .collect();
        for _ in 0..2 {
            let rows: Vec<Vec<DVec3>> = grid.iter().map(|r| refine_1d(r, even, odd)).collect();
            let m = rows[0].len();
            let cols: Vec<Vec<DVec3>> = (0..m)
                .map(|j| {
                    let c: Vec<DVec3> = rows.iter().map(|r| r[j]).collect();
                    refine_1d(&c, even, odd)
                })
                .collect();
            grid = (0..cols[0].len())
                .map(|i| (0..m).map(|j| cols[j][i]).collect())
                .collect();
        }
        let map = &maps[2];
        for (i, row) in grid.iter().enumerate() {
            for (j, want) in row.iter().enumerate() {
                let d = (got[map[i][j]] - *want).length();
                assert!(d < 1e-13, "{degree:?} ({i}, {j}): {d}");
            }
        }
    }
}

#[test]
fn energy_compaction_on_a_sphere() {
    // A smooth surface sampled on the finest level: details shrink with the level.
    let levels = 5;
    let r = hierarchy(&generate::cube(), levels);
    let sphere: Vec<DVec3> = r.positions.iter().map(|p| p.normalize()).collect();
    for degree in Degree::ALL {
        let mut data = sphere.clone();
        BSplineWavelet::new(degree)
            .analyze(&r.topologies, &mut data)
            .unwrap();
        let mean = |j: usize| {
            let d = &data[detail_range(&r.topologies, j).unwrap()];
            d.iter().map(|x| x.length()).sum::<f64>() / d.len() as f64
        };
        let (coarse, fine) = (mean(0), mean(levels as usize - 1));
        eprintln!(
            "{degree:?}: mean detail level 0 {coarse:.3e}, level {} {fine:.3e}",
            levels - 1
        );
        assert!(fine * 10.0 <= coarse, "{degree:?}: {coarse} vs {fine}");
    }
}

#[test]
fn bspline_schemes_through_subdivide() {
    let mut mesh = generate::pyramid();
    mesh.colors = Some(vec![[1.0, 0.0, 0.0]; 5]);
    let r = hierarchy(&mesh, 2);
    for (scheme, degree) in [
        (Scheme::Bicubic, Degree::Cubic),
        (Scheme::Biquintic, Degree::Quintic),
    ] {
        let opts = SubdivideOptions {
            scheme,
            levels: 2,
            ..SubdivideOptions::default()
        };
        let out = subdivide(&mesh, &opts).unwrap();
        let want = BSplineWavelet::new(degree)
            .subdivide(&r.topologies, &mesh.positions)
            .unwrap();
        assert_eq!(out.positions, want);
        assert_eq!(out.face_indices, r.face_vertices);
        // Colours are affine combinations: a constant colour stays constant.
        for c in out.colors.as_ref().unwrap() {
            assert!((c[0] - 1.0).abs() < 1e-6 && c[1].abs() < 1e-6);
        }
        let built = Refinement::build(&mesh, &opts, false).unwrap();
        assert_eq!(built.positions, want);
        assert_eq!(built.topologies.len(), 2);
        assert!(Refinement::build(&mesh, &opts, true).is_err());
        let zero = subdivide(&mesh, &SubdivideOptions { levels: 0, ..opts }).unwrap();
        assert_eq!(zero.positions, mesh.positions);
    }
}

#[test]
#[ignore = "timing: cargo test -p subwave --lib wavelet::bertram::tests::throughput -- --ignored --nocapture"]
fn throughput() {
    // A cube refined 9 times: 1.57 M vertices at the finest level.
    let r = hierarchy(&generate::cube(), 9);
    let n = r.positions.len();
    for degree in Degree::ALL {
        let w = BSplineWavelet::new(degree);
        let mut data = r.positions.clone();
        let t = std::time::Instant::now();
        w.analyze(&r.topologies, &mut data).unwrap();
        let fwd = t.elapsed().as_secs_f64();
        let t = std::time::Instant::now();
        w.synthesize(&r.topologies, &mut data).unwrap();
        let inv = t.elapsed().as_secs_f64();
        let mut ints = to_int(&r.positions, 1e6);
        let t = std::time::Instant::now();
        w.analyze_int(&r.topologies, &mut ints).unwrap();
        let ifwd = t.elapsed().as_secs_f64();
        eprintln!(
            "{degree:?}: {n} vertices, analysis {:.1} M/s, synthesis {:.1} M/s, integer analysis {:.1} M/s",
            n as f64 / fwd / 1e6,
            n as f64 / inv / 1e6,
            n as f64 / ifwd / 1e6
        );
    }
}

// ---- Reference: the straightforward per-lift implementation (before the optimized passes),
// ---- to check that the optimized float transform agrees within 1e-12 relative.

/// `self = Σ w_i x_i`.
#[inline]
fn combo<T: Interpolate>(terms: &[(&T, f64)]) -> T {
    let mut y = T::zero();
    for (x, w) in terms {
        y.add_scaled(x, *w);
    }
    y
}

/// Mean of `data[idx]` (zero if `idx` is empty).
#[inline]
fn mean<T: Interpolate>(idx: &[u32], data: &[T]) -> T {
    let mut y = T::zero();
    if !idx.is_empty() {
        let w = 1.0 / idx.len() as f64;
        for &i in idx {
            y.add_scaled(&data[i as usize], w);
        }
    }
    y
}

fn ref_lift<T: Interpolate>(ctx: &Ctx, l: Lift, data: &mut [T]) {
    let t = ctx.t;
    let (v, e, f) = split3(t, data);
    let (a, b) = (l.a, l.b);
    let (kk, kb, b2) = (4.0 * a * a, 4.0 * a * b, b * b);
    match l.kind {
        S => {
            let (e_ro, f_ro): (&[T], &[T]) = (e, f);
            for (i, x) in v.iter_mut().enumerate() {
                let fb = mean(t.vertex_faces(i), f_ro);
                let eb = ctx.e_bar_v(i, e_ro);
                *x = combo(&[(x, b2), (&fb, kk), (&eb, kb)]);
            }
            for (i, x) in e.iter_mut().enumerate() {
                let fb = mean(t.edge_faces(i), f_ro);
                *x = combo(&[(x, b), (&fb, 2.0 * a)]);
            }
        }
        W => {
            let (v_ro, e_ro): (&[T], &[T]) = (v, e);
            for (i, x) in f.iter_mut().enumerate() {
                let vb = mean(t.face_vertices(i), v_ro);
                let eb = mean(t.face_edges(i), e_ro);
                *x = combo(&[(x, b2), (&vb, kk), (&eb, kb)]);
            }
            for (i, x) in e.iter_mut().enumerate() {
                let vb = mean(&t.edge_vertices[i], v_ro);
                *x = combo(&[(x, b), (&vb, 2.0 * a)]);
            }
        }
    }
}

fn ref_unlift<T: Interpolate>(ctx: &Ctx, l: Lift, data: &mut [T]) {
    let t = ctx.t;
    let (v, e, f) = split3(t, data);
    let (a, b) = (l.a, l.b);
    let (kk, kb, b2) = (4.0 * a * a, 4.0 * a * b, b * b);
    match l.kind {
        S => {
            let f_ro: &[T] = f;
            for (i, x) in e.iter_mut().enumerate() {
                let fb = mean(t.edge_faces(i), f_ro);
                *x = combo(&[(x, 1.0 / b), (&fb, -2.0 * a / b)]);
            }
            let e_ro: &[T] = e;
            for (i, x) in v.iter_mut().enumerate() {
                let fb = mean(t.vertex_faces(i), f_ro);
                let eb = ctx.e_bar_v(i, e_ro);
                *x = combo(&[(x, 1.0 / b2), (&fb, -kk / b2), (&eb, -kb / b2)]);
            }
        }
        W => {
            let v_ro: &[T] = v;
            for (i, x) in e.iter_mut().enumerate() {
                let vb = mean(&t.edge_vertices[i], v_ro);
                *x = combo(&[(x, 1.0 / b), (&vb, -2.0 * a / b)]);
            }
            let e_ro: &[T] = e;
            for (i, x) in f.iter_mut().enumerate() {
                let vb = mean(t.face_vertices(i), v_ro);
                let eb = mean(t.face_edges(i), e_ro);
                *x = combo(&[(x, 1.0 / b2), (&vb, -kk / b2), (&eb, -kb / b2)]);
            }
        }
    }
}

/// The optimized float transform agrees with the reference implementation within 1e-12
/// relative to the data's scale, forward and inverse, every degree and boundary rule.
#[test]
fn optimized_passes_match_reference() {
    let mut meshes = test_meshes();
    meshes.push(("grid", generate::grid(4, 3, false)));
    for (name, mesh) in meshes {
        let r = hierarchy(&mesh, 3);
        let levels = &r.topologies;
        let mut rng = Rng(7);
        let fine: Vec<DVec3> = r.positions.iter().map(|p| *p + 0.05 * rng.vec3()).collect();
        let scale = crate::mesh::diagonal_of(&fine);
        let sizes = level_sizes(levels).unwrap();
        for boundary in BOUNDARIES {
            for degree in Degree::ALL {
                let w = BSplineWavelet { degree, boundary };
                let mut got = fine.clone();
                w.analyze(levels, &mut got).unwrap();
                let mut want = fine.clone();
                for (j, topo) in levels.iter().enumerate().rev() {
                    let ctx = Ctx::new(topo, boundary);
                    for l in degree.analysis_lifts() {
                        ref_lift(&ctx, *l, &mut want[..sizes[j + 1]]);
                    }
                }
                let d = max_diff(&got, &want);
                assert!(
                    d <= 1e-12 * scale,
                    "{name} {degree:?} {boundary:?} forward: {d}"
                );
                let mut back = want.clone();
                w.synthesize(levels, &mut back).unwrap();
                let mut rback = want;
                for (j, topo) in levels.iter().enumerate() {
                    let ctx = Ctx::new(topo, boundary);
                    for l in degree.analysis_lifts().iter().rev() {
                        ref_unlift(&ctx, *l, &mut rback[..sizes[j + 1]]);
                    }
                }
                let d = max_diff(&back, &rback);
                assert!(
                    d <= 1e-12 * scale,
                    "{name} {degree:?} {boundary:?} inverse: {d}"
                );
                assert!(max_diff(&back, &fine) <= 1e-9 * scale);
            }
        }
    }
}

/// The constant floor divisions of the regular integer formulas equal `div_euclid` on both
/// sides of zero, at the edges of the unsigned path (`|n >> k| < 2^58`) and beyond it.
#[test]
fn floor_div_const_equals_div_euclid() {
    fn check<const D: i64>() {
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut values: Vec<i64> = Vec::new();
        for e in [0, 1, 2, 3, 10, 40, 57] {
            for d in -3..=3 {
                values.push((1i64 << e) + d);
                values.push(-(1i64 << e) + d);
            }
        }
        let k = D.trailing_zeros();
        let mut edges = vec![i64::MAX, i64::MIN + 1];
        if let Some(e) = (1i64 << 58).checked_mul(1 << k) {
            edges.extend([e, e - 1]);
        }
        for edge in edges {
            values.extend([
                edge,
                edge.wrapping_neg(),
                edge.wrapping_sub(1),
                1i64.wrapping_sub(edge),
            ]);
        }
        for _ in 0..2000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            values.push((x as i64) >> (x % 40));
        }
        for n in values {
            assert_eq!(floor_div_const::<D>(n), n.div_euclid(D), "{n} / {D}");
            if (n >> D.trailing_zeros()).unsigned_abs() < 1 << 58 {
                assert_eq!(floor_div_const_small::<D>(n), n.div_euclid(D), "{n} / {D}");
            }
        }
    }
    check::<2>();
    check::<4>();
    check::<6>();
    check::<8>();
    check::<12>();
    check::<18>();
    check::<32>();
    check::<64>();
    check::<72>();
    check::<512>();
    check::<2048>();
}

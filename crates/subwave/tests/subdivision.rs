//! Properties of the plain-subdivision engine (issue: plain subdivision, verification).

use glam::{DMat3, DVec3};
use proptest::prelude::*;
use subwave::generate;
use subwave::subdivision::rules::Creasing;
use subwave::subdivision::{subdivide, BoundaryMode, Refinement, Scheme, SubdivideOptions};
use subwave::{EdgeTag, Mesh, Topology, VertexTag, SHARPNESS_INFINITE};

fn opts(scheme: Scheme, levels: u32) -> SubdivideOptions {
    SubdivideOptions {
        scheme,
        levels,
        ..Default::default()
    }
}

fn counts(m: &Mesh) -> (usize, usize, usize, i64) {
    let t = Topology::build(m);
    (
        m.num_vertices(),
        t.num_edges(),
        m.num_faces(),
        t.euler_characteristic(),
    )
}

fn tri_meshes() -> Vec<Mesh> {
    vec![
        generate::tetrahedron(),
        generate::icosphere(1),
        generate::torus(1.0, 0.4, 6, 5, true),
        generate::disk(7),
        generate::triangle_grid(3),
    ]
}

fn poly_meshes() -> Vec<Mesh> {
    vec![
        generate::cube(),
        generate::pyramid(),
        generate::torus(1.0, 0.4, 6, 5, false),
        generate::grid(3, 2, false),
    ]
}

#[test]
fn counts_and_euler() {
    for m in tri_meshes() {
        for scheme in [Scheme::Loop, Scheme::Midpoint] {
            let (v, e, f, chi) = counts(&m);
            let out = subdivide(&m, &opts(scheme, 1)).unwrap();
            let (v1, _, f1, chi1) = counts(&out);
            assert_eq!((v1, f1, chi1), (v + e, 4 * f, chi));
        }
    }
    for m in poly_meshes() {
        for scheme in [Scheme::CatmullClark, Scheme::Bilinear] {
            let (v, e, f, chi) = counts(&m);
            let out = subdivide(&m, &opts(scheme, 1)).unwrap();
            let (v1, _, f1, chi1) = counts(&out);
            assert_eq!((v1, f1, chi1), (v + e + f, m.face_indices.len(), chi));
            let out2 = subdivide(&m, &opts(scheme, 2)).unwrap();
            assert_eq!(out2.num_faces(), 4 * m.face_indices.len());
        }
    }
}

fn affine(p: DVec3) -> DVec3 {
    DMat3::from_cols(
        DVec3::new(1.2, 0.3, -0.1),
        DVec3::new(-0.4, 0.9, 0.2),
        DVec3::new(0.1, 0.5, 1.7),
    ) * p
        + DVec3::new(3.0, -2.0, 0.5)
}

#[test]
fn affine_invariance() {
    let cases: Vec<(Mesh, Scheme)> = tri_meshes()
        .into_iter()
        .map(|m| (m, Scheme::Loop))
        .chain(poly_meshes().into_iter().map(|m| (m, Scheme::CatmullClark)))
        .collect();
    for (m, scheme) in cases {
        let mut moved = m.clone();
        moved.positions.iter_mut().for_each(|p| *p = affine(*p));
        let a = subdivide(&m, &opts(scheme, 2)).unwrap();
        let b = subdivide(&moved, &opts(scheme, 2)).unwrap();
        for (p, q) in a.positions.iter().zip(&b.positions) {
            assert!((affine(*p) - *q).length() < 1e-12, "{scheme:?}");
        }
    }
}

#[test]
fn planar_stays_planar() {
    for (m, scheme) in [
        (generate::triangle_grid(4), Scheme::Loop),
        (generate::disk(6), Scheme::Loop),
        (generate::grid(4, 3, false), Scheme::CatmullClark),
        (generate::grid(4, 3, true), Scheme::Midpoint),
    ] {
        let out = subdivide(&m, &opts(scheme, 3)).unwrap();
        assert!(out.positions.iter().all(|p| p.z == 0.0));
    }
}

#[test]
fn loop_on_regular_grid_is_the_quartic_box_spline() {
    // Lattice heights on a regular triangle grid (diagonals along (1,1)).
    let n = 6u32;
    let mut m = generate::triangle_grid(n);
    let h = |i: i64, j: i64| ((i * 7 + j * 3) % 5) as f64 + 0.1 * (i * j) as f64;
    for j in 0..=n as i64 {
        for i in 0..=n as i64 {
            m.positions[(j * (n as i64 + 1) + i) as usize].z = h(i, j);
        }
    }
    let out = subdivide(
        &m,
        &SubdivideOptions {
            boundary: BoundaryMode::OpenSubdiv,
            ..opts(Scheme::Loop, 1)
        },
    )
    .unwrap();
    // Find child vertices by their (x, y) on the refined lattice.
    let lattice = |p: DVec3| {
        let y = p.y / (3f64.sqrt() / 2.0);
        (
            (2.0 * (p.x - 0.5 * y)).round() as i64,
            (2.0 * y).round() as i64,
        )
    };
    let mut checked = 0;
    for p in &out.positions {
        let (x2, y2) = lattice(*p);
        // Interior only (the box-spline rules hold away from the boundary).
        if x2 < 2 || y2 < 2 || x2 > 2 * n as i64 - 2 || y2 > 2 * n as i64 - 2 {
            continue;
        }
        let expect = match (x2 % 2, y2 % 2) {
            (0, 0) => {
                let (i, j) = (x2 / 2, y2 / 2);
                10.0 / 16.0 * h(i, j)
                    + (h(i + 1, j)
                        + h(i - 1, j)
                        + h(i, j + 1)
                        + h(i, j - 1)
                        + h(i + 1, j + 1)
                        + h(i - 1, j - 1))
                        / 16.0
            }
            (1, 0) => {
                let (i, j) = ((x2 - 1) / 2, y2 / 2);
                0.375 * (h(i, j) + h(i + 1, j)) + 0.125 * (h(i + 1, j + 1) + h(i, j - 1))
            }
            (0, 1) => {
                let (i, j) = (x2 / 2, (y2 - 1) / 2);
                0.375 * (h(i, j) + h(i, j + 1)) + 0.125 * (h(i + 1, j + 1) + h(i - 1, j))
            }
            _ => {
                let (i, j) = ((x2 - 1) / 2, (y2 - 1) / 2);
                0.375 * (h(i, j) + h(i + 1, j + 1)) + 0.125 * (h(i + 1, j) + h(i, j + 1))
            }
        };
        assert!(
            (p.z - expect).abs() < 1e-12,
            "at {x2},{y2}: {} vs {expect}",
            p.z
        );
        checked += 1;
    }
    assert!(checked > 50);
}

#[test]
fn catmull_clark_on_regular_grid_is_the_bicubic_b_spline() {
    let n = 6u32;
    let mut m = generate::grid(n, n, false);
    let h = |i: i64, j: i64| ((i * 5 + j * 11) % 7) as f64 - 0.2 * (i * j) as f64;
    for j in 0..=n as i64 {
        for i in 0..=n as i64 {
            m.positions[(j * (n as i64 + 1) + i) as usize].z = h(i, j);
        }
    }
    let out = subdivide(&m, &opts(Scheme::CatmullClark, 1)).unwrap();
    // Uniform cubic B-spline refinement: even (1/8, 6/8, 1/8), odd (1/2, 1/2), tensored.
    let w = |k: i64| -> Vec<(i64, f64)> {
        if k % 2 == 0 {
            vec![(k / 2 - 1, 0.125), (k / 2, 0.75), (k / 2 + 1, 0.125)]
        } else {
            vec![((k - 1) / 2, 0.5), ((k + 1) / 2, 0.5)]
        }
    };
    let mut checked = 0;
    for p in &out.positions {
        let (x2, y2) = ((p.x * 2.0).round() as i64, (p.y * 2.0).round() as i64);
        if x2 < 2 || y2 < 2 || x2 > 2 * n as i64 - 2 || y2 > 2 * n as i64 - 2 {
            continue;
        }
        let mut expect = 0.0;
        for (i, wi) in w(x2) {
            for (j, wj) in w(y2) {
                expect += wi * wj * h(i, j);
            }
        }
        assert!((p.z - expect).abs() < 1e-12, "at {x2},{y2}");
        checked += 1;
    }
    assert!(checked > 50);
}

#[test]
fn corners_never_move_and_sharp_cube_stays_a_cube() {
    let mut m = generate::cube();
    let t = Topology::build(&m);
    m.edge_tags = t
        .edge_vertices
        .iter()
        .map(|&v| EdgeTag {
            vertices: v,
            sharpness: SHARPNESS_INFINITE,
        })
        .collect();
    let out = subdivide(&m, &opts(Scheme::CatmullClark, 3)).unwrap();
    for (v, p) in out.positions.iter().enumerate().take(8) {
        assert_eq!(*p, m.positions[v]);
    }
    // Every point lies on the cube's surface.
    for p in &out.positions {
        let a = p.abs();
        assert!((a.max_element() - 1.0).abs() < 1e-12);
    }
    // A corner tag on a smooth icosphere vertex pins it.
    let mut s = generate::icosphere(1);
    s.vertex_tags.push(VertexTag {
        vertex: 3,
        sharpness: SHARPNESS_INFINITE,
    });
    let out = subdivide(&s, &opts(Scheme::Loop, 3)).unwrap();
    assert_eq!(out.positions[3], s.positions[3]);
    assert_ne!(out.positions[4], s.positions[4]);
}

#[test]
fn loop_on_quads_names_the_faces() {
    let err = subdivide(&generate::pyramid(), &opts(Scheme::Loop, 1))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("face") && err.contains('0') && err.contains("catmull-clark"),
        "{err}"
    );
    let err = subdivide(&generate::fin(), &opts(Scheme::Loop, 1))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("non-manifold edge") && err.contains("0-1"),
        "{err}"
    );
    let err = subdivide(&generate::bowtie(), &opts(Scheme::Loop, 1))
        .unwrap_err()
        .to_string();
    assert!(err.contains("non-manifold vertex"), "{err}");
}

#[test]
fn semi_sharp_creases_interpolate_between_smooth_and_sharp() {
    // A crease of sharpness s on the cube: the vertex moves less and less as s grows.
    let base = generate::cube();
    let topo = Topology::build(&base);
    let e = topo.edge_vertices[0];
    let run = |s: f64, creasing: Creasing| {
        let mut m = base.clone();
        m.edge_tags = vec![EdgeTag {
            vertices: e,
            sharpness: s,
        }];
        let o = SubdivideOptions {
            creasing,
            ..opts(Scheme::CatmullClark, 4)
        };
        subdivide(&m, &o).unwrap().positions[e[0] as usize]
    };
    for creasing in [Creasing::Uniform, Creasing::Chaikin] {
        let d: Vec<f64> = [0.0, 0.5, 1.0, 2.0, 3.0, SHARPNESS_INFINITE]
            .iter()
            .map(|&s| (run(s, creasing) - base.positions[e[0] as usize]).length())
            .collect();
        for w in d.windows(2) {
            assert!(w[1] <= w[0] + 1e-12, "{creasing:?}: {d:?}");
        }
        assert!(d[0] > d[5]);
    }
}

#[test]
fn stencils_reevaluate_bit_for_bit() {
    for (m, scheme) in [
        (generate::torus(1.0, 0.4, 6, 5, true), Scheme::Loop),
        (generate::disk(6), Scheme::Loop),
        (generate::torus(1.0, 0.4, 6, 5, false), Scheme::CatmullClark),
        (generate::grid(3, 3, false), Scheme::CatmullClark),
    ] {
        let o = opts(scheme, 3);
        let r = Refinement::build(&m, &o, true).unwrap();
        let mut moved = m.clone();
        for (i, p) in moved.positions.iter_mut().enumerate() {
            *p += DVec3::new((i as f64).sin(), (i as f64 * 0.7).cos(), 0.1 * i as f64);
        }
        let cached = r.evaluate(&moved.positions).unwrap();
        let direct = subdivide(&moved, &o).unwrap();
        assert_eq!(cached, direct.positions);
        // Vertex-varying data through the same tables.
        let uv: Vec<[f64; 2]> = m.positions.iter().map(|p| [p.x, p.y]).collect();
        let uv1 = r.evaluate(&uv).unwrap();
        assert_eq!(uv1.len(), direct.num_vertices());
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
    /// Random crease tags on a torus: affine invariance with semi-sharp creases.
    #[test]
    fn random_tags(seed in 0u64..1000, levels in 1u32..3, chaikin in any::<bool>()) {
        let mut m = generate::torus(1.0, 0.4, 5, 4, seed % 2 == 0);
        let t = Topology::build(&m);
        let mut x = seed;
        for e in 0..t.num_edges() {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            if (x >> 60) < 4 {
                m.edge_tags.push(EdgeTag { vertices: t.edge_vertices[e], sharpness: ((x >> 40) % 40) as f64 / 8.0 });
            }
        }
        let scheme = if m.is_triangle_mesh() { Scheme::Loop } else { Scheme::CatmullClark };
        let o = SubdivideOptions {
            creasing: if chaikin { Creasing::Chaikin } else { Creasing::Uniform },
            boundary: BoundaryMode::OpenSubdiv,
            ..opts(scheme, levels)
        };
        let a = subdivide(&m, &o).unwrap();
        let mut moved = m.clone();
        moved.positions.iter_mut().for_each(|p| *p = affine(*p));
        let b = subdivide(&moved, &o).unwrap();
        for (p, q) in a.positions.iter().zip(&b.positions) {
            prop_assert!((affine(*p) - *q).length() < 1e-11);
        }
    }
}

/// `BoundaryMode::None` (OpenSubdiv's `VTX_BOUNDARY_NONE`): closed meshes are unchanged; on a
/// grid the faces touching the boundary become holes, and what remains is exactly the
/// "edge only" surface over the interior faces.
#[test]
fn boundary_none_drops_boundary_faces() {
    for scheme in [Scheme::Loop, Scheme::CatmullClark] {
        let closed = generate::icosphere(1);
        let o = SubdivideOptions {
            scheme,
            levels: 2,
            boundary: BoundaryMode::None,
            ..Default::default()
        };
        let edge_only = SubdivideOptions {
            boundary: BoundaryMode::OpenSubdiv,
            ..o
        };
        let a = subdivide(&closed, &o).unwrap();
        let b = subdivide(&closed, &edge_only).unwrap();
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.face_indices, b.face_indices);

        // A 5×5 grid: the 3×3 interior faces survive (each gives 4^2 or 2·4^2 faces).
        let grid = generate::grid(5, 5, scheme == Scheme::Loop);
        let a = subdivide(&grid, &o).unwrap();
        let b = subdivide(&grid, &edge_only).unwrap();
        let per_face = if scheme == Scheme::Loop { 2 * 16 } else { 16 };
        assert_eq!(a.num_faces(), 9 * per_face, "{scheme:?}");
        // Every surviving face is a face of the edge-only result, with the same positions.
        let key = |m: &Mesh, f: usize| {
            let (s, e) = (m.face_offsets[f] as usize, m.face_offsets[f + 1] as usize);
            m.face_indices[s..e]
                .iter()
                .map(|&v| {
                    let p = m.positions[v as usize];
                    [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]
                })
                .collect::<Vec<_>>()
        };
        let all: std::collections::HashSet<_> = (0..b.num_faces()).map(|f| key(&b, f)).collect();
        assert!((0..a.num_faces()).all(|f| all.contains(&key(&a, f))));
        // No vertex is left unused.
        assert!(a.referenced().iter().all(|&u| u));

        // Explicitly sharpened boundary edges keep their faces.
        let mut tagged = grid.clone();
        let t = Topology::build(&grid);
        for e in 0..t.num_edges() {
            if t.is_boundary_edge(e) {
                tagged.edge_tags.push(EdgeTag {
                    vertices: t.edge_vertices[e],
                    sharpness: SHARPNESS_INFINITE,
                });
            }
        }
        let a = subdivide(&tagged, &o).unwrap();
        assert_eq!(a.num_faces(), b.num_faces(), "{scheme:?}");
    }
}

/// Face-varying texture coordinates follow the faces: one per child corner, linear on each face,
/// for every scheme and with holes dropped.
#[test]
fn face_varying_uvs_are_refined() {
    use subwave::mesh::FaceVarying;
    for (mesh, scheme) in [
        (generate::cube(), Scheme::CatmullClark),
        (generate::icosphere(0), Scheme::Loop),
        (generate::grid(3, 3, false), Scheme::CatmullClark),
    ] {
        let mut m = mesh.clone();
        // Planar projection per corner, every face with its own values (all seams).
        let coords: Vec<[f64; 2]> = m
            .face_indices
            .iter()
            .map(|&v| [m.positions[v as usize].x, m.positions[v as usize].y])
            .collect();
        m.face_uvs = Some(FaceVarying {
            indices: (0..coords.len() as u32).collect(),
            coords,
        });
        for boundary in [BoundaryMode::Crease, BoundaryMode::None] {
            let o = SubdivideOptions {
                scheme,
                levels: 2,
                boundary,
                ..Default::default()
            };
            let r = subdivide(&m, &o).unwrap();
            r.check_indices().unwrap();
            let fv = r.face_uvs.as_ref().expect("face-varying data kept");
            assert_eq!(fv.indices.len(), r.face_indices.len());
            // The bilinear scheme moves vertices linearly too, so its positions' x, y equal
            // the face-varying values corner by corner.
            let lin = subdivide(
                &m,
                &SubdivideOptions {
                    scheme: Scheme::Bilinear,
                    boundary,
                    ..o
                },
            )
            .unwrap();
            if scheme == Scheme::CatmullClark {
                let fv = lin.face_uvs.as_ref().unwrap();
                for (c, &v) in lin.face_indices.iter().enumerate() {
                    let p = lin.positions[v as usize];
                    let t = fv.coords[fv.indices[c] as usize];
                    assert!((p.x - t[0]).abs() < 1e-12 && (p.y - t[1]).abs() < 1e-12);
                }
            }
        }
    }
}

// ---- Modified butterfly (subdivision::butterfly) ----

fn butterfly(levels: u32) -> SubdivideOptions {
    opts(Scheme::Butterfly, levels)
}

#[test]
fn butterfly_counts_interpolation_affine_planar() {
    for m in tri_meshes() {
        let (v, e, f, chi) = counts(&m);
        let out = subdivide(&m, &butterfly(1)).unwrap();
        let (v1, _, f1, chi1) = counts(&out);
        assert_eq!((v1, f1, chi1), (v + e, 4 * f, chi));
        // Interpolating: old vertices do not move, at every level.
        let out3 = subdivide(&m, &butterfly(3)).unwrap();
        assert_eq!(&out3.positions[..v], &m.positions[..]);
        assert_eq!(&out3.positions[..v1], &out.positions[..]);
        // Affine invariance.
        let mut moved = m.clone();
        moved.positions.iter_mut().for_each(|p| *p = affine(*p));
        let b = subdivide(&moved, &butterfly(2)).unwrap();
        let a = subdivide(&m, &butterfly(2)).unwrap();
        for (p, q) in a.positions.iter().zip(&b.positions) {
            assert!((affine(*p) - *q).length() < 1e-12);
        }
    }
    for m in [
        generate::triangle_grid(4),
        generate::disk(5),
        generate::disk(9),
    ] {
        let out = subdivide(&m, &butterfly(3)).unwrap();
        assert!(out.positions.iter().all(|p| p.z == 0.0));
    }
    let err = subdivide(&generate::pyramid(), &butterfly(1))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("butterfly") && err.contains("face") && err.contains("catmull-clark"),
        "{err}"
    );
}

/// Lattice coordinates (doubled) of a point of a refined `triangle_grid`.
fn lattice2(p: DVec3) -> (i64, i64) {
    let y = p.y / (3f64.sqrt() / 2.0);
    (
        (2.0 * (p.x - 0.5 * y)).round() as i64,
        (2.0 * y).round() as i64,
    )
}

#[test]
fn butterfly_on_regular_grid_is_the_8_point_stencil() {
    let n = 7u32;
    let mut m = generate::triangle_grid(n);
    let h = |i: i64, j: i64| ((i * 7 + j * 3) % 5) as f64 + 0.1 * (i * j) as f64;
    let idx = |i: i64, j: i64| (j * (n as i64 + 1) + i) as usize;
    for j in 0..=n as i64 {
        for i in 0..=n as i64 {
            m.positions[idx(i, j)].z = h(i, j);
        }
    }
    let out = subdivide(&m, &butterfly(1)).unwrap();
    let interior = |(i, j): (i64, i64)| i > 0 && j > 0 && i < n as i64 && j < n as i64;
    let mut checked = 0;
    for p in &out.positions[m.num_vertices()..] {
        let (x2, y2) = lattice2(*p);
        // Edge ends A, B and opposite vertices C, D (lattice diagonals along (1, 1)).
        let (a, b, c, d) = match (x2 % 2, y2 % 2) {
            (1, 0) => {
                let (i, j) = ((x2 - 1) / 2, y2 / 2);
                ((i, j), (i + 1, j), (i + 1, j + 1), (i, j - 1))
            }
            (0, 1) => {
                let (i, j) = (x2 / 2, (y2 - 1) / 2);
                ((i, j), (i, j + 1), (i + 1, j + 1), (i - 1, j))
            }
            _ => {
                let (i, j) = ((x2 - 1) / 2, (y2 - 1) / 2);
                ((i, j), (i + 1, j + 1), (i + 1, j), (i, j + 1))
            }
        };
        if !interior(a) || !interior(b) {
            continue;
        }
        let hp = |q: (i64, i64)| h(q.0, q.1);
        let wing =
            |x: (i64, i64), y: (i64, i64), z: (i64, i64)| hp((x.0 + y.0 - z.0, x.1 + y.1 - z.1));
        let expect = 0.5 * (hp(a) + hp(b)) + 0.125 * (hp(c) + hp(d))
            - (wing(a, c, b) + wing(b, c, a) + wing(a, d, b) + wing(b, d, a)) / 16.0;
        assert!(
            (p.z - expect).abs() < 1e-12,
            "at {x2},{y2}: {} vs {expect}",
            p.z
        );
        checked += 1;
    }
    assert!(checked > 80, "{checked}");

    // The stencil table holds exactly the eight butterfly weights at such an edge.
    let r = Refinement::build(&m, &butterfly(1), true).unwrap();
    let t = &r.stencils[0];
    let topo = &r.topologies[0];
    let e = topo.find_edge(idx(3, 3) as u32, idx(4, 3) as u32).unwrap() as usize;
    let j = m.num_vertices() + e;
    let (lo, hi) = (t.offsets[j] as usize, t.offsets[j + 1] as usize);
    let mut w: Vec<f64> = t.weights[lo..hi].to_vec();
    w.sort_by(f64::total_cmp);
    assert_eq!(
        w,
        [-0.0625, -0.0625, -0.0625, -0.0625, 0.125, 0.125, 0.5, 0.5]
    );
}

#[test]
fn butterfly_reproduces_linear_and_cubic_functions() {
    // Linear heights are reproduced everywhere, boundary and boundary-adjacent edges included
    // (4-point rule, reflected sectors); cubic heights at regular interior edges.
    let n = 8u32;
    let base = generate::triangle_grid(n);
    let lin = |p: DVec3| 0.3 * p.x - 1.7 * p.y + 0.25;
    let cub = |p: DVec3| p.x * p.x * p.x - 2.0 * p.x * p.y * p.y + 0.5 * p.y * p.y - p.x + 1.0;
    for (f, everywhere) in [(&lin as &dyn Fn(DVec3) -> f64, true), (&cub, false)] {
        let mut m = base.clone();
        m.positions.iter_mut().for_each(|p| p.z = f(*p));
        let out = subdivide(&m, &butterfly(1)).unwrap();
        let mut checked = 0;
        for p in &out.positions {
            let (x2, y2) = lattice2(*p);
            let margin = if everywhere { 0 } else { 3 };
            if x2.min(y2) < margin || x2.max(y2) > 2 * n as i64 - margin {
                continue;
            }
            let flat = DVec3::new(p.x, p.y, 0.0);
            assert!(
                (p.z - f(flat)).abs() < 1e-11,
                "{x2},{y2}: {} vs {}",
                p.z,
                f(flat)
            );
            checked += 1;
        }
        assert!(checked > 100);
    }
}

#[test]
fn butterfly_crease_edges_follow_the_4_point_rule() {
    // A closed torus with one loop of crease edges: the crease edge points depend on the crease
    // vertices only (the 4-point curve), so moving a vertex off the crease leaves them alone.
    let m = generate::torus(1.0, 0.4, 8, 6, true);
    let t = Topology::build(&m);
    // Vertices 0..6 are the minor circle at u = 0 (generate::torus numbering): tag its edges.
    let nu = 6u32;
    let mut tagged = m.clone();
    for i in 0..nu {
        let (a, b) = (i, (i + 1) % nu);
        assert!(t.find_edge(a, b).is_some());
        tagged.edge_tags.push(EdgeTag {
            vertices: [a, b],
            sharpness: SHARPNESS_INFINITE,
        });
    }
    let out = subdivide(&tagged, &butterfly(1)).unwrap();
    let nv = m.num_vertices();
    for i in 0..nu {
        let e = t.find_edge(i, (i + 1) % nu).unwrap() as usize;
        let p = |k: u32| m.positions[(k % nu) as usize];
        let expect = (p(i) + p(i + 1)) * (9.0 / 16.0) - (p(i + nu - 1) + p(i + 2)) / 16.0;
        assert!((out.positions[nv + e] - expect).length() < 1e-14);
    }
}

#[test]
fn butterfly_converges_on_an_icosphere() {
    // Interpolating: level k + 1 keeps level k's vertices. The new points' offsets from their
    // edges' midpoints, across the surface (along the midpoint's direction from the sphere's
    // centre), are second differences: they shrink geometrically (measured: by 0.296 then
    // 0.294 per level, 1/4 on regular patches). Along the surface they shrink only ~2 times
    // per level near valence-5 vertices, whose characteristic map does not keep midpoints.
    let m = generate::icosphere(1);
    let offsets = |levels: u32| {
        let coarse = subdivide(&m, &butterfly(levels - 1)).unwrap();
        let fine = subdivide(&m, &butterfly(levels)).unwrap();
        assert_eq!(
            &fine.positions[..coarse.num_vertices()],
            &coarse.positions[..]
        );
        let t = Topology::build(&coarse);
        (0..t.num_edges())
            .map(|e| {
                let [a, b] = t.edge_vertices[e];
                let mid = 0.5 * (coarse.positions[a as usize] + coarse.positions[b as usize]);
                let d = fine.positions[coarse.num_vertices() + e] - mid;
                (d.dot(mid.normalize()).abs(), d.length())
            })
            .fold((0.0, 0.0), |(x, y), (a, b)| {
                (f64::max(x, a), f64::max(y, b))
            })
    };
    let ((n2, _), (n3, t3), (n4, t4)) = (offsets(2), offsets(3), offsets(4));
    assert!(n3 < 0.32 * n2 && n4 < 0.32 * n3, "{n2} {n3} {n4}");
    assert!(t4 < 0.55 * t3, "{t3} {t4}");
    // Level 3 and level 4 are close: every level-4 point within 1e-3 of its level-3 edge.
    assert!(t4 < 4e-3 && n4 < 2e-3, "{t4} {n4}");
    eprintln!("normal offsets {n2:.3e} {n3:.3e} {n4:.3e}, along {t3:.3e} {t4:.3e}");
}

#[test]
fn butterfly_stencils_reevaluate_bit_for_bit() {
    for m in [
        generate::torus(1.0, 0.4, 6, 5, true),
        generate::disk(6),
        generate::icosphere(1),
        generate::triangle_grid(3),
    ] {
        let o = butterfly(3);
        let r = Refinement::build(&m, &o, true).unwrap();
        let direct = subdivide(&m, &o).unwrap();
        assert_eq!(r.positions, direct.positions);
        let mut moved = m.clone();
        for (i, p) in moved.positions.iter_mut().enumerate() {
            *p += DVec3::new((i as f64).sin(), (i as f64 * 0.7).cos(), 0.1 * i as f64);
        }
        let cached = r.evaluate(&moved.positions).unwrap();
        assert_eq!(cached, subdivide(&moved, &o).unwrap().positions);
    }
}

/// The original butterfly computed from scratch on a closed triangle mesh with a half-edge
/// map (independent of the rings): the point of each edge, in `Topology` edge order.
fn brute_force_8_point(m: &Mesh) -> Vec<DVec3> {
    let mut opp = std::collections::HashMap::new();
    for f in 0..m.num_faces() {
        let v = m.face(f);
        for i in 0..3 {
            opp.insert((v[i], v[(i + 1) % 3]), v[(i + 2) % 3]);
        }
    }
    let t = Topology::build(m);
    let p = |i: u32| m.positions[i as usize];
    t.edge_vertices
        .iter()
        .map(|&[a, b]| {
            let (c, d) = (opp[&(a, b)], opp[&(b, a)]);
            let wings = [opp[&(a, c)], opp[&(c, b)], opp[&(b, d)], opp[&(d, a)]];
            0.5 * (p(a) + p(b)) + 0.125 * (p(c) + p(d))
                - wings.iter().map(|&w| p(w)).sum::<DVec3>() / 16.0
        })
        .collect()
}

#[test]
fn butterfly_original_matches_a_brute_force_8_point_rule() {
    // Valences 3 (tetrahedron), 5 and 6 (icosphere), 6 (torus).
    for m in [
        generate::tetrahedron(),
        generate::icosphere(1),
        generate::torus(1.0, 0.4, 5, 4, true),
    ] {
        let o = opts(Scheme::ButterflyOriginal, 1);
        let mut level = m.clone();
        for _ in 0..3 {
            let next = subdivide(&level, &o).unwrap();
            let expect = brute_force_8_point(&level);
            let got = &next.positions[level.num_vertices()..];
            assert_eq!(got.len(), expect.len());
            for (g, e) in got.iter().zip(&expect) {
                assert!((*g - *e).length() < 1e-13, "{g} vs {e}");
            }
            level = next;
        }
        // Level by level equals all levels at once (child numbering = Topology::build's).
        let all = subdivide(&m, &opts(Scheme::ButterflyOriginal, 3)).unwrap();
        assert_eq!(all.positions, level.positions);
    }
}

/// Zero levels return the input, attributes included.
#[test]
fn zero_levels_keep_colours_and_uvs() {
    let mut m = generate::icosphere(0);
    m.colors = Some(vec![[0.5, 0.25, 1.0]; m.num_vertices()]);
    m.uvs = Some(vec![[0.1, 0.2]; m.num_vertices()]);
    for scheme in [Scheme::Loop, Scheme::CatmullClark, Scheme::Butterfly] {
        let r = subdivide(&m, &opts(scheme, 0)).unwrap();
        assert_eq!(r.positions, m.positions);
        assert_eq!(r.colors, m.colors);
        assert_eq!(r.uvs, m.uvs);
    }
}

/// The finest level carries the tags that are still sharp, and none when the input has no
/// interior crease or corner (boundaries are sharp without being tags).
#[test]
fn finest_level_tags_follow_the_creases() {
    for scheme in [Scheme::CatmullClark, Scheme::Loop] {
        let base = if scheme == Scheme::Loop {
            generate::icosphere(1)
        } else {
            generate::cube()
        };
        let plain = subdivide(&base, &opts(scheme, 2)).unwrap();
        assert!(plain.edge_tags.is_empty() && plain.vertex_tags.is_empty());
        let mut tagged = base.clone();
        let t = Topology::build(&base);
        tagged.edge_tags.push(EdgeTag {
            vertices: t.edge_vertices[0],
            sharpness: 2.5,
        });
        tagged.vertex_tags.push(VertexTag {
            vertex: 3,
            sharpness: 3.0,
        });
        for (levels, edges, vertex) in [(1, 2, Some(2.0)), (2, 4, Some(1.0)), (3, 0, None)] {
            let fine = subdivide(&tagged, &opts(scheme, levels)).unwrap();
            assert_eq!(fine.edge_tags.len(), edges, "{scheme:?} {levels}");
            assert!(fine
                .edge_tags
                .iter()
                .all(|e| (e.sharpness - (2.5 - levels as f64)).abs() < 1e-12));
            assert_eq!(fine.vertex_tags.first().map(|v| v.sharpness), vertex);
        }
    }
    // A boundary only: sharp under every boundary mode, and never a tag.
    for boundary in [BoundaryMode::Crease, BoundaryMode::OpenSubdiv] {
        let fine = subdivide(
            &generate::grid(3, 3, false),
            &SubdivideOptions {
                boundary,
                ..opts(Scheme::CatmullClark, 2)
            },
        )
        .unwrap();
        assert!(fine.edge_tags.is_empty() && fine.vertex_tags.is_empty());
    }
}

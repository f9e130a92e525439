//! Quad/triangle subdivision (Stam & Loop 2003; Lavoué et al. §III.2) and its agreement with
//! the subdivision curves of Lavoué §V.1.

use glam::{DMat3, DVec3};
use subwave::generate;
use subwave::subdivision::curves::SubdivisionCurve;
use subwave::subdivision::refine::{child_faces, Split};
use subwave::subdivision::rules::Creasing;
use subwave::subdivision::{subdivide, BoundaryMode, Refinement, Scheme, SubdivideOptions};
use subwave::{EdgeTag, Mesh, MeshError, Topology, VertexTag, SHARPNESS_INFINITE};

fn opts(scheme: Scheme, levels: u32) -> SubdivideOptions {
    SubdivideOptions {
        scheme,
        levels,
        ..Default::default()
    }
}

fn max_dist(a: &[DVec3], b: &[DVec3]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| x.distance(*y))
        .fold(0.0, f64::max)
}

/// `m` with the faces listed in `split` cut into two triangles along their diagonal 0-2.
fn triangulate_some(m: &Mesh, split: &[usize]) -> Mesh {
    let mut faces: Vec<Vec<u32>> = Vec::new();
    for (k, f) in m.faces().enumerate() {
        if split.contains(&k) {
            faces.push(vec![f[0], f[1], f[2]]);
            faces.push(vec![f[0], f[2], f[3]]);
        } else {
            faces.push(f.to_vec());
        }
    }
    let mut out = Mesh::from_faces(m.positions.clone(), faces);
    out.edge_tags = m.edge_tags.clone();
    out.vertex_tags = m.vertex_tags.clone();
    out
}

/// The cube with its top and one side face triangulated (closed, mixed).
fn mixed_cube() -> Mesh {
    triangulate_some(&generate::cube(), &[1, 2])
}

/// A triangular prism: two triangles, three quads.
fn prism() -> Mesh {
    let p = vec![
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(0.7, 1.5, 0.0),
        DVec3::new(0.1, 0.2, 2.0),
        DVec3::new(2.1, 0.1, 2.2),
        DVec3::new(0.8, 1.6, 1.9),
    ];
    Mesh::from_faces(
        p,
        vec![
            vec![0, 2, 1],
            vec![3, 4, 5],
            vec![0, 1, 4, 3],
            vec![1, 2, 5, 4],
            vec![2, 0, 3, 5],
        ],
    )
}

/// A planar grid of quads with every other quad triangulated (open, mixed).
fn strip() -> Mesh {
    let g = generate::grid(4, 3, false);
    let split: Vec<usize> = (0..g.num_faces()).filter(|k| k % 2 == 0).collect();
    triangulate_some(&g, &split)
}

fn mixed_meshes() -> Vec<Mesh> {
    vec![mixed_cube(), prism(), strip()]
}

fn count_quads(m: &Mesh) -> usize {
    (0..m.num_faces()).filter(|&f| m.face_arity(f) == 4).count()
}

#[test]
fn counts_and_euler() {
    for m in mixed_meshes() {
        let t = Topology::build(&m);
        let (v, e, f, q) = (
            m.num_vertices(),
            t.num_edges(),
            m.num_faces(),
            count_quads(&m),
        );
        let out = subdivide(&m, &opts(Scheme::QuadTri, 1)).unwrap();
        let t1 = Topology::build(&out);
        assert_eq!(out.num_vertices(), v + e + q);
        assert_eq!(out.num_faces(), 4 * f);
        assert_eq!(count_quads(&out), 4 * q);
        assert_eq!(t1.euler_characteristic(), t.euler_characteristic());
        assert!(t1.is_manifold());
        let out2 = subdivide(&m, &opts(Scheme::QuadTri, 3)).unwrap();
        assert_eq!(out2.num_faces(), 64 * f);
        assert_eq!(
            Topology::build(&out2).euler_characteristic(),
            t.euler_characteristic()
        );
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
    for m in mixed_meshes() {
        let mut img = m.clone();
        img.positions.iter_mut().for_each(|p| *p = affine(*p));
        let a = subdivide(&m, &opts(Scheme::QuadTri, 3)).unwrap();
        let b = subdivide(&img, &opts(Scheme::QuadTri, 3)).unwrap();
        let a: Vec<DVec3> = a.positions.into_iter().map(affine).collect();
        assert!(max_dist(&a, &b.positions) < 1e-12);
    }
}

#[test]
fn planar_mesh_stays_planar() {
    let m = strip();
    let out = subdivide(&m, &opts(Scheme::QuadTri, 3)).unwrap();
    assert!(out.positions.iter().all(|p| p.z.abs() < 1e-15));
    // The boundary is a closed crease of four corners... none tagged: a cubic B-spline curve
    // inside the grid's bounding box.
    let (lo, hi) = m.bounding_box().unwrap();
    assert!(out
        .positions
        .iter()
        .all(|p| p.cmpge(lo - 1e-12).all() && p.cmple(hi + 1e-12).all()));
}

/// Tags: a few infinitely sharp and semi-sharp edges and a corner.
fn tagged(mut m: Mesh, seed: u64) -> Mesh {
    let t = Topology::build(&m);
    let mut x = seed;
    for e in 0..t.num_edges() {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        if (x >> 60) < 4 {
            let s = if (x >> 56) & 1 == 0 {
                ((x >> 40) % 40) as f64 / 8.0
            } else {
                SHARPNESS_INFINITE
            };
            m.edge_tags.push(EdgeTag {
                vertices: t.edge_vertices[e],
                sharpness: s,
            });
        }
    }
    m.vertex_tags.push(VertexTag {
        vertex: 1,
        sharpness: 1.5,
    });
    m
}

/// On triangle meshes the scheme is Loop (with Hoppe's unmodified edge rules next to
/// creases: the crate's Loop under `BoundaryMode::OpenSubdiv`).
#[test]
fn equals_loop_on_triangle_meshes() {
    let meshes = [
        generate::icosphere(1),
        generate::torus(1.0, 0.4, 6, 5, true),
        generate::disk(7),
        generate::triangle_grid(3),
        generate::tetrahedron(),
    ];
    let mut worst: f64 = 0.0;
    for (k, m) in meshes.into_iter().enumerate() {
        for seed in 0..3u64 {
            let m = if seed == 0 {
                m.clone()
            } else {
                tagged(m.clone(), seed + 7 * k as u64)
            };
            for creasing in [Creasing::Uniform, Creasing::Chaikin] {
                let o = SubdivideOptions {
                    boundary: BoundaryMode::OpenSubdiv,
                    creasing,
                    ..opts(Scheme::Loop, 3)
                };
                let l = subdivide(&m, &o).unwrap();
                let q = subdivide(
                    &m,
                    &SubdivideOptions {
                        scheme: Scheme::QuadTri,
                        ..o
                    },
                )
                .unwrap();
                assert_eq!(l.face_indices, q.face_indices);
                assert_eq!(l.edge_tags, q.edge_tags);
                let d = max_dist(&l.positions, &q.positions);
                worst = worst.max(d);
                assert!(d < 1e-12, "mesh {k} seed {seed}: {d}");
            }
        }
    }
    eprintln!("quad-tri vs loop: max difference {worst:e}");
}

#[test]
fn equals_catmull_clark_on_quad_meshes() {
    let meshes = [
        generate::cube(),
        generate::torus(1.0, 0.4, 6, 5, false),
        generate::grid(3, 2, false),
    ];
    let mut worst: f64 = 0.0;
    for (k, m) in meshes.into_iter().enumerate() {
        for seed in 0..3u64 {
            let m = if seed == 0 {
                m.clone()
            } else {
                tagged(m.clone(), seed + 11 * k as u64)
            };
            for boundary in [BoundaryMode::Crease, BoundaryMode::OpenSubdivCorners] {
                let o = SubdivideOptions {
                    boundary,
                    ..opts(Scheme::CatmullClark, 3)
                };
                let c = subdivide(&m, &o).unwrap();
                let q = subdivide(
                    &m,
                    &SubdivideOptions {
                        scheme: Scheme::QuadTri,
                        ..o
                    },
                )
                .unwrap();
                assert_eq!(c.face_indices, q.face_indices);
                let d = max_dist(&c.positions, &q.positions);
                worst = worst.max(d);
                assert!(d < 1e-12, "mesh {k} seed {seed}: {d}");
            }
        }
    }
    eprintln!("quad-tri vs catmull-clark: max difference {worst:e}");
}

/// One step of Stam & Loop's scheme computed independently, as the paper states it: linear
/// subdivision, then every vertex of the linear mesh smoothed by the mask of Lavoué Fig. 4
/// (Loop's among triangles, Catmull-Clark's among quads, the quad/triangle mask otherwise),
/// crease vertices of the linear mesh by `1/4 1/2 1/4`, corners fixed. Infinitely sharp tags
/// only. Returns the refined mesh with its tags.
fn two_step(m: &Mesh) -> Mesh {
    let topo = Topology::build(m);
    let nv = topo.num_vertices as usize;
    let ne = topo.num_edges();
    // Linear subdivision.
    let mut lin = m.positions.clone();
    for ev in &topo.edge_vertices {
        lin.push(0.5 * (m.positions[ev[0] as usize] + m.positions[ev[1] as usize]));
    }
    for f in 0..topo.num_faces() {
        let fv = topo.face_vertices(f);
        if fv.len() == 4 {
            lin.push(fv.iter().map(|&v| m.positions[v as usize]).sum::<DVec3>() / 4.0);
        }
    }
    let (off, fv) = child_faces(&topo, Split::QuadTri);
    let mut child = Mesh {
        positions: lin.clone(),
        face_offsets: off,
        face_indices: fv,
        ..Mesh::new()
    };
    for e in 0..ne {
        if topo.edge_sharpness[e] > 0.0 {
            for &w in &topo.edge_vertices[e] {
                child.edge_tags.push(EdgeTag {
                    vertices: [w, (nv + e) as u32],
                    sharpness: SHARPNESS_INFINITE,
                });
            }
        }
    }
    child.vertex_tags = m.vertex_tags.clone();
    // Smoothing.
    let ct = Topology::build(&child);
    let beta_loop = |n: f64| {
        let c = 0.375 + 0.25 * (std::f64::consts::TAU / n).cos();
        (0.625 - c * c) / n
    };
    let mut out = vec![DVec3::ZERO; lin.len()];
    for (p, o) in out.iter_mut().enumerate() {
        let edges = ct.vertex_edges(p);
        let sharp: Vec<u32> = edges
            .iter()
            .copied()
            .filter(|&e| ct.is_crease_edge(e as usize))
            .collect();
        let x = lin[p];
        if ct.vertex_sharpness[p] > 0.0 || sharp.len() > 2 {
            *o = x;
            continue;
        }
        if sharp.len() == 2 {
            let a = lin[ct.other_vertex(sharp[0] as usize, p as u32) as usize];
            let b = lin[ct.other_vertex(sharp[1] as usize, p as u32) as usize];
            *o = 0.25 * a + 0.5 * x + 0.25 * b;
            continue;
        }
        let nbrs: Vec<DVec3> = edges
            .iter()
            .map(|&e| lin[ct.other_vertex(e as usize, p as u32) as usize])
            .collect();
        let mut diag = Vec::new();
        let mut n_q = 0;
        for &f in ct.vertex_faces(p) {
            let fv = ct.face_vertices(f as usize);
            if fv.len() == 4 {
                n_q += 1;
                let i = fv.iter().position(|&v| v as usize == p).unwrap();
                diag.push(lin[fv[(i + 2) % 4] as usize]);
            }
        }
        let n_e = nbrs.len();
        let n = n_e as f64;
        let sum_n: DVec3 = nbrs.iter().sum();
        let sum_d: DVec3 = diag.iter().sum();
        *o = if n_q == 0 {
            // Loop's smoothing mask: the centre weight for which linear + smoothing is Loop.
            let a = 1.0 - 2.0 * n * beta_loop(n);
            a * x + (1.0 - a) / n * sum_n
        } else if n_q == ct.vertex_faces(p).len() {
            (n - 3.0) / n * x + 2.0 / (n * n) * sum_n + 1.0 / (n * n) * sum_d
        } else {
            let alpha = 1.0 / (1.0 + n / 2.0 + n_q as f64 / 4.0);
            alpha * x + alpha / 2.0 * sum_n + alpha / 4.0 * sum_d
        };
    }
    child.positions = out;
    child
}

#[test]
fn equals_linear_subdivision_then_smoothing() {
    let mut crease_cube = mixed_cube();
    // A crease loop around the bottom face, and a corner.
    for [a, b] in [[0, 2], [2, 3], [3, 1], [1, 0]] {
        crease_cube.edge_tags.push(EdgeTag {
            vertices: [a, b],
            sharpness: SHARPNESS_INFINITE,
        });
    }
    crease_cube.vertex_tags.push(VertexTag {
        vertex: 7,
        sharpness: SHARPNESS_INFINITE,
    });
    let mut worst: f64 = 0.0;
    for m in [mixed_cube(), prism(), strip(), crease_cube] {
        let mut reference = m.clone();
        for level in 1..=3u32 {
            reference = two_step(&reference);
            let q = subdivide(&m, &opts(Scheme::QuadTri, level)).unwrap();
            assert_eq!(q.face_indices, reference.face_indices);
            let d = max_dist(&q.positions, &reference.positions);
            worst = worst.max(d);
            assert!(d < 1e-12, "level {level}: {d}");
        }
    }
    eprintln!("quad-tri vs linear+smoothing: max difference {worst:e}");
}

/// The mixed edge and vertex rules on the prism, against hand-computed masks.
#[test]
fn mixed_rules_by_hand() {
    let m = prism();
    let p = &m.positions;
    let t = Topology::build(&m);
    let out = subdivide(&m, &opts(Scheme::QuadTri, 1)).unwrap();
    // Edge 0-2: triangle (0 2 1) opposite 1; quad (2 0 3 5) other corners 3, 5.
    let e = t.find_edge(0, 2).unwrap() as usize;
    let want = 0.375 * (p[0] + p[2]) + 0.125 * p[1] + 0.0625 * (p[3] + p[5]);
    assert!(out.positions[6 + e].distance(want) < 1e-14);
    // Vertex 0: 3 edges (to 1, 2, 3), 1 triangle, 2 quads (0 1 4 3), (2 0 3 5).
    let (ne, nq) = (3.0, 2.0);
    let alpha = 1.0 / (1.0 + ne / 2.0 + nq / 4.0);
    let mids = [1, 2, 3].map(|j| 0.5 * (p[0] + p[j]));
    let c1 = (p[0] + p[1] + p[4] + p[3]) / 4.0;
    let c2 = (p[2] + p[0] + p[3] + p[5]) / 4.0;
    let want = alpha * p[0] + alpha / 2.0 * mids.iter().sum::<DVec3>() + alpha / 4.0 * (c1 + c2);
    assert!(out.positions[0].distance(want) < 1e-14);
    // Face points of quads are centroids, after the edge points.
    assert!(out.positions[6 + t.num_edges()].distance(c1) < 1e-14);
}

#[test]
fn cached_stencils_are_bit_identical() {
    for m in mixed_meshes().into_iter().chain([tagged(mixed_cube(), 3)]) {
        for creasing in [Creasing::Uniform, Creasing::Chaikin] {
            let o = SubdivideOptions {
                creasing,
                ..opts(Scheme::QuadTri, 3)
            };
            let r = Refinement::build(&m, &o, true).unwrap();
            let direct = subdivide(&m, &o).unwrap();
            assert_eq!(r.positions, direct.positions);
            assert_eq!(r.evaluate(&m.positions).unwrap(), direct.positions);
            assert_eq!(r.face_vertices, direct.face_indices);
            // Moved control points: the cached tables equal refining from scratch.
            let mut moved = m.clone();
            moved
                .positions
                .iter_mut()
                .enumerate()
                .for_each(|(i, p)| *p += DVec3::new(0.1 * i as f64, -0.05, 0.02 * (i % 3) as f64));
            let again = subdivide(&moved, &o).unwrap();
            assert_eq!(r.evaluate(&moved.positions).unwrap(), again.positions);
        }
    }
}

#[test]
fn rejects_other_polygons() {
    let mut m = prism();
    // Add a pentagon cap on a separate component.
    let base = m.positions.len() as u32;
    for i in 0..5 {
        let a = std::f64::consts::TAU * i as f64 / 5.0;
        m.positions.push(DVec3::new(5.0 + a.cos(), a.sin(), 0.0));
    }
    m.push_face(&[base, base + 1, base + 2, base + 3, base + 4]);
    let err = subdivide(&m, &opts(Scheme::QuadTri, 1)).unwrap_err();
    let s = err.to_string();
    assert!(
        s.contains("quad-tri") && s.contains('5') && s.contains("catmull-clark"),
        "{s}"
    );
    assert!(matches!(
        err,
        subwave::Error::Mesh(MeshError::UnsupportedFaces { ref faces, .. }) if faces == &[5]
    ));
}

/// The positions of the vertices of a crease loop `l` (vertex ids of level `k`) at level
/// `k + 1`: the loop's vertices keep their ids, the edge between two consecutive ones becomes
/// vertex `V + e`.
fn refine_loop(t: &Topology, l: &[u32], closed: bool) -> Vec<u32> {
    let nv = t.num_vertices;
    let mut out = Vec::new();
    for i in 0..l.len() {
        out.push(l[i]);
        if closed || i + 1 < l.len() {
            let e = t.find_edge(l[i], l[(i + 1) % l.len()]).unwrap();
            out.push(nv + e);
        }
    }
    out
}

/// Lavoué §V.1: a crease of the surface refines as the subdivision curve of its control
/// polygon (eqs. 2-3), corners and ends fixed.
#[test]
fn creases_follow_the_subdivision_curve() {
    // A closed crease loop through triangles and quads (the mixed cube's top is triangulated),
    // and an open crease with corner ends on the prism.
    let mut cube = mixed_cube();
    let top = [4u32, 5, 7, 6];
    for i in 0..4 {
        cube.edge_tags.push(EdgeTag {
            vertices: [top[i], top[(i + 1) % 4]],
            sharpness: SHARPNESS_INFINITE,
        });
    }
    let mut prism = prism();
    let path = [3u32, 0, 1, 4];
    for i in 0..3 {
        prism.edge_tags.push(EdgeTag {
            vertices: [path[i], path[i + 1]],
            sharpness: SHARPNESS_INFINITE,
        });
    }
    for v in [3, 4] {
        prism.vertex_tags.push(VertexTag {
            vertex: v,
            sharpness: SHARPNESS_INFINITE,
        });
    }
    // A closed crease with a corner in the middle (vertex 5 tagged).
    let mut cube2 = mixed_cube();
    for i in 0..4 {
        cube2.edge_tags.push(EdgeTag {
            vertices: [top[i], top[(i + 1) % 4]],
            sharpness: SHARPNESS_INFINITE,
        });
    }
    cube2.vertex_tags.push(VertexTag {
        vertex: 5,
        sharpness: SHARPNESS_INFINITE,
    });
    let cases: [(Mesh, Vec<u32>, bool, Vec<u32>); 4] = [
        (cube, top.to_vec(), true, vec![]),
        (prism, path.to_vec(), false, vec![]),
        (cube2, top.to_vec(), true, vec![1]),
        // The boundary of the open strip: a closed crease (boundary) loop without corners.
        (strip(), strip_boundary(), true, vec![]),
    ];
    let mut worst: f64 = 0.0;
    for (m, l0, closed, corners) in cases {
        let levels = 4;
        let r = Refinement::build(&m, &opts(Scheme::QuadTri, levels), true).unwrap();
        let all = r.evaluate_levels(&m.positions).unwrap();
        let pts: Vec<DVec3> = l0.iter().map(|&v| m.positions[v as usize]).collect();
        let mut curve = SubdivisionCurve::new(pts, closed, corners).unwrap();
        let mut l = l0.clone();
        for (k, (topo, level)) in r.topologies.iter().zip(&all).enumerate() {
            l = refine_loop(topo, &l, closed);
            curve = curve.subdivide();
            let mesh_pts: Vec<DVec3> = l.iter().map(|&v| level[v as usize]).collect();
            let d = max_dist(&mesh_pts, &curve.points);
            worst = worst.max(d);
            assert!(d < 1e-13, "level {}: {d}", k + 1);
        }
    }
    eprintln!("crease vs subdivision curve: max difference {worst:e}");
}

/// The boundary loop of [`strip`] (the grid's boundary, in order).
fn strip_boundary() -> Vec<u32> {
    let m = strip();
    let t = Topology::build(&m);
    let bedges: Vec<usize> = (0..t.num_edges())
        .filter(|&e| t.is_boundary_edge(e))
        .collect();
    let mut l = vec![t.edge_vertices[bedges[0]][0]];
    let mut prev = u32::MAX;
    loop {
        let v = *l.last().unwrap();
        let next = bedges
            .iter()
            .map(|&e| t.edge_vertices[e])
            .filter(|ev| ev.contains(&v))
            .map(|ev| if ev[0] == v { ev[1] } else { ev[0] })
            .find(|&w| w != prev)
            .unwrap();
        if next == l[0] {
            break;
        }
        prev = v;
        l.push(next);
    }
    assert_eq!(l.len(), bedges.len());
    l
}

/// The shared corpus's mixed mesh (Suzanne: 468 quads, 32 triangles, open), against the
/// linear-subdivision-then-smoothing reference. Skipped if the corpus is absent.
#[test]
fn corpus_mixed_mesh_matches_reference() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/meshes/suzanne.obj");
    let Ok(mut m) = subwave::io::read_mesh(&path, None) else {
        eprintln!("skipped: {} not found", path.display());
        return;
    };
    m.remove_unreferenced();
    assert!(count_quads(&m) > 0 && count_quads(&m) < m.num_faces());
    let chi = Topology::build(&m).euler_characteristic();
    let mut reference = m.clone();
    for level in 1..=2u32 {
        reference = two_step(&reference);
        let q = subdivide(&m, &opts(Scheme::QuadTri, level)).unwrap();
        assert_eq!(q.face_indices, reference.face_indices);
        let d = max_dist(&q.positions, &reference.positions);
        assert!(d < 1e-12, "level {level}: {d}");
        assert_eq!(Topology::build(&q).euler_characteristic(), chi);
    }
}

//! Tests of the OpenSubdiv harness itself: counts, known positions, the documented vertex
//! order, and the ordered permutation.

use glam::DVec3;
use subwave::generate;
use subwave::mesh::{EdgeTag, Mesh, VertexTag};
use subwave_osd::{
    max_vertex_distance, max_vertex_set_distance, refine, refine_ordered, refine_ordered_levels,
    refine_timed, OsdBoundary, OsdCreasing, OsdOptions, OsdScheme,
};

const TOL: f64 = 1e-6;

fn opts(scheme: OsdScheme, levels: u32) -> OsdOptions {
    OsdOptions {
        scheme,
        levels,
        ..OsdOptions::default()
    }
}

/// Edges by first appearance (edge `c` of a face joins corners `c` and `c + 1`).
fn edges(m: &Mesh) -> Vec<[u32; 2]> {
    let mut out: Vec<[u32; 2]> = Vec::new();
    for f in m.faces() {
        for c in 0..f.len() {
            let (a, b) = (f[c], f[(c + 1) % f.len()]);
            if !out
                .iter()
                .any(|e| (e[0] == a && e[1] == b) || (e[0] == b && e[1] == a))
            {
                out.push([a, b]);
            }
        }
    }
    out
}

fn centroid(m: &Mesh, f: &[u32]) -> DVec3 {
    f.iter().map(|&v| m.positions[v as usize]).sum::<DVec3>() / f.len() as f64
}

#[test]
fn cube_catmull_clark_two_levels_counts() {
    let cube = generate::cube();
    let r = refine(&cube, &opts(OsdScheme::CatmullClark, 2)).unwrap();
    assert_eq!(r.num_vertices(), 98);
    assert_eq!(r.num_faces(), 96);
    assert!(r.is_quad_mesh());
    r.check_indices().unwrap();
    let o = refine_ordered(&cube, &opts(OsdScheme::CatmullClark, 2)).unwrap();
    assert_eq!((o.num_vertices(), o.num_faces()), (98, 96));
    o.check_indices().unwrap();
    // Same point sets, different orders.
    assert!(max_vertex_set_distance(&r, &o) < TOL);
    // Symmetric result: every vertex on the cube's circumscribed-ish surface, inside [-1, 1]^3.
    for p in &r.positions {
        assert!(p.abs().max_element() < 1.0);
    }
}

#[test]
fn cube_level_one_points() {
    let cube = generate::cube();
    let levels = refine_ordered_levels(&cube, &opts(OsdScheme::CatmullClark, 1)).unwrap();
    assert_eq!(levels.len(), 2);
    assert_eq!(levels[0].mesh.positions, cube.positions);
    let l1 = &levels[1].mesh;
    let e = edges(&cube);
    let (nv, ne) = (8, e.len());
    assert_eq!(ne, 12);
    assert_eq!(l1.num_vertices(), nv + ne + 6);
    // Face points: centroids (in face order after vertices and edges).
    for (f, fv) in cube.faces().enumerate() {
        let c = centroid(&cube, fv);
        assert!(l1.positions[nv + ne + f].distance(c) < TOL, "face {f}");
    }
    // Edge points: average of the ends and the two adjacent face points.
    for (i, [a, b]) in e.iter().enumerate() {
        let adj: Vec<DVec3> = cube
            .faces()
            .filter(|f| f.contains(a) && f.contains(b))
            .map(|f| centroid(&cube, f))
            .collect();
        assert_eq!(adj.len(), 2);
        let expect =
            (cube.positions[*a as usize] + cube.positions[*b as usize] + adj[0] + adj[1]) / 4.0;
        assert!(l1.positions[nv + i].distance(expect) < TOL, "edge {i}");
    }
    // Vertex points of valence 3: (Q + 2R) / 3 = 5/9 of the corner.
    for v in 0..nv {
        let expect = cube.positions[v] * (5.0 / 9.0);
        assert!(l1.positions[v].distance(expect) < TOL, "vertex {v}");
    }
    // Children of quad k are 4k..4k+3 = (v_i, m_i, c, m_{i-1}).
    let e_of = |a: u32, b: u32| {
        e.iter()
            .position(|x| (x[0] == a && x[1] == b) || (x[0] == b && x[1] == a))
            .unwrap() as u32
    };
    for (k, fv) in cube.faces().enumerate() {
        for i in 0..4 {
            let m = |j: usize| nv as u32 + e_of(fv[j % 4], fv[(j + 1) % 4]);
            let expect = [fv[i], m(i), (nv + ne + k) as u32, m(i + 3)];
            assert_eq!(l1.face(4 * k + i), &expect, "child {i} of face {k}");
        }
    }
}

/// Pins the facts documented in the crate docs: at level 1 OpenSubdiv orders vertex children,
/// then face children, then edge children, and its level-0 edges are in first-appearance order.
#[test]
fn opensubdiv_level_one_order_is_vertices_faces_edges() {
    for (mesh, scheme) in [
        (generate::cube(), OsdScheme::CatmullClark),
        (generate::pyramid(), OsdScheme::CatmullClark),
        (generate::grid(3, 2, false), OsdScheme::Bilinear),
        (generate::icosahedron(), OsdScheme::Loop),
    ] {
        let levels = refine_ordered_levels(&mesh, &opts(scheme, 1)).unwrap();
        let map = &levels[1].subwave_to_osd;
        let (nv, ne, nf) = (mesh.num_vertices(), edges(&mesh).len(), mesh.num_faces());
        let face_block = if scheme == OsdScheme::Loop { 0 } else { nf };
        for (v, &o) in map[..nv].iter().enumerate() {
            assert_eq!(o as usize, v);
        }
        for e in 0..ne {
            assert_eq!(
                map[nv + e] as usize,
                nv + face_block + e,
                "{scheme:?}: edge {e}"
            );
        }
        if scheme != OsdScheme::Loop {
            for f in 0..nf {
                assert_eq!(map[nv + ne + f] as usize, nv + f);
            }
        }
    }
}

#[test]
fn ordered_and_unordered_agree_as_sets() {
    let cases: Vec<(Mesh, OsdScheme, OsdBoundary, u32)> = vec![
        (
            generate::cube(),
            OsdScheme::CatmullClark,
            OsdBoundary::EdgeOnly,
            3,
        ),
        (
            generate::pyramid(),
            OsdScheme::CatmullClark,
            OsdBoundary::EdgeOnly,
            2,
        ),
        (
            generate::tetrahedron(),
            OsdScheme::Bilinear,
            OsdBoundary::EdgeOnly,
            2,
        ),
        (
            generate::grid(3, 2, false),
            OsdScheme::CatmullClark,
            OsdBoundary::EdgeAndCorner,
            2,
        ),
        (
            generate::grid(3, 2, true),
            OsdScheme::Loop,
            OsdBoundary::EdgeOnly,
            2,
        ),
        (
            generate::disk(6),
            OsdScheme::Loop,
            OsdBoundary::EdgeAndCorner,
            3,
        ),
        (
            generate::torus(1.0, 0.4, 6, 5, false),
            OsdScheme::CatmullClark,
            OsdBoundary::None,
            2,
        ),
        (
            generate::icosphere(1),
            OsdScheme::Loop,
            OsdBoundary::EdgeOnly,
            3,
        ),
    ];
    for (mesh, scheme, boundary, levels) in cases {
        let o = OsdOptions {
            scheme,
            boundary,
            creasing: OsdCreasing::Uniform,
            levels,
        };
        let plain = refine(&mesh, &o).unwrap();
        let ordered = refine_ordered(&mesh, &o).unwrap();
        ordered.check_indices().unwrap();
        assert_eq!(plain.num_faces(), ordered.num_faces());
        let d = max_vertex_set_distance(&plain, &ordered);
        assert!(d < TOL, "{scheme:?} {levels}: {d}");
        // Every level of the ordered hierarchy follows the vertex-count contract.
        let all = refine_ordered_levels(&mesh, &o).unwrap();
        for w in all.windows(2) {
            let (p, c) = (&w[0].mesh, &w[1].mesh);
            let faces = if scheme == OsdScheme::Loop {
                0
            } else {
                p.num_faces()
            };
            assert_eq!(c.num_vertices(), p.num_vertices() + edges(p).len() + faces);
            // Parent vertices keep their index: for bilinear they do not move.
            if scheme == OsdScheme::Bilinear {
                assert!(
                    max_vertex_distance(
                        p,
                        &Mesh {
                            positions: c.positions[..p.num_vertices()].to_vec(),
                            ..p.clone()
                        }
                    ) < TOL
                );
            }
        }
    }
}

#[test]
fn icosahedron_loop_one_level() {
    let ico = generate::icosahedron();
    let r = refine(&ico, &opts(OsdScheme::Loop, 1)).unwrap();
    assert_eq!((r.num_vertices(), r.num_faces()), (42, 80));
    assert!(r.is_triangle_mesh());
    let o = refine_ordered(&ico, &opts(OsdScheme::Loop, 1)).unwrap();
    // Edge points: 3/8 of the ends + 1/8 of the two opposite vertices.
    for (i, [a, b]) in edges(&ico).iter().enumerate() {
        let opp: Vec<u32> = ico
            .faces()
            .filter(|f| f.contains(a) && f.contains(b))
            .map(|f| *f.iter().find(|v| *v != a && *v != b).unwrap())
            .collect();
        let p = |v: u32| ico.positions[v as usize];
        let expect = 0.375 * (p(*a) + p(*b)) + 0.125 * (p(opp[0]) + p(opp[1]));
        assert!(o.positions[12 + i].distance(expect) < TOL, "edge {i}");
    }
    // Vertex points with Loop's beta for valence 5.
    let n = 5.0f64;
    let beta = (0.625 - (0.375 + 0.25 * (std::f64::consts::TAU / n).cos()).powi(2)) / n;
    for v in 0..12u32 {
        let ring: Vec<u32> = edges(&ico)
            .iter()
            .filter_map(|e| {
                if e[0] == v {
                    Some(e[1])
                } else if e[1] == v {
                    Some(e[0])
                } else {
                    None
                }
            })
            .collect();
        assert_eq!(ring.len(), 5);
        let sum: DVec3 = ring.iter().map(|&w| ico.positions[w as usize]).sum();
        let expect = (1.0 - n * beta) * ico.positions[v as usize] + beta * sum;
        assert!(o.positions[v as usize].distance(expect) < TOL, "vertex {v}");
    }
}

#[test]
fn tagged_crease_and_corner() {
    let mut cube = generate::cube();
    cube.edge_tags.push(EdgeTag {
        vertices: [0, 2],
        sharpness: 10.0,
    });
    let o = opts(OsdScheme::CatmullClark, 1);
    let tagged = refine_ordered(&cube, &o).unwrap();
    let smooth = refine_ordered(&generate::cube(), &o).unwrap();
    let e = edges(&cube);
    let i = e.iter().position(|x| x == &[0, 2]).unwrap();
    // An infinitely sharp edge's point is its midpoint.
    let mid = 0.5 * (cube.positions[0] + cube.positions[2]);
    assert!(tagged.positions[8 + i].distance(mid) < TOL);
    assert!(smooth.positions[8 + i].distance(mid) > 0.1);
    // Runs with two levels, a semi-sharp crease, a corner and Chaikin creasing.
    cube.edge_tags.push(EdgeTag {
        vertices: [7, 6],
        sharpness: 1.5,
    });
    cube.vertex_tags.push(VertexTag {
        vertex: 5,
        sharpness: 10.0,
    });
    for creasing in [OsdCreasing::Uniform, OsdCreasing::Chaikin] {
        let o = OsdOptions {
            creasing,
            levels: 2,
            ..OsdOptions::default()
        };
        let r = refine(&cube, &o).unwrap();
        let ordered = refine_ordered(&cube, &o).unwrap();
        assert_eq!(r.num_faces(), 96);
        assert!(max_vertex_set_distance(&r, &ordered) < TOL);
        // The infinitely sharp corner stays put.
        assert!(ordered.positions[5].distance(cube.positions[5]) < TOL);
    }
}

#[test]
fn timed_reports_all_phases() {
    let (m, t) = refine_timed(&generate::icosphere(2), &opts(OsdScheme::Loop, 2)).unwrap();
    assert_eq!(m.num_faces(), 320 * 16);
    assert!(t.topology_ms >= 0.0 && t.positions_ms >= 0.0);
    assert!(t.stencil_build_ms.is_some() && t.stencil_eval_ms.is_some());
    let (m0, t0) = refine_timed(&generate::cube(), &opts(OsdScheme::CatmullClark, 0)).unwrap();
    assert_eq!(m0.positions, generate::cube().positions);
    assert_eq!(t0.stencil_build_ms, None);
}

#[test]
fn errors_are_reported() {
    let loop1 = opts(OsdScheme::Loop, 1);
    assert!(refine(&generate::cube(), &loop1)
        .unwrap_err()
        .contains("triangles"));
    assert!(refine(&Mesh::new(), &loop1).is_err());
    let mut bad = generate::tetrahedron();
    bad.face_indices[0] = 99;
    assert!(refine(&bad, &loop1).is_err());
    let mut bad_tag = generate::tetrahedron();
    bad_tag.edge_tags.push(EdgeTag {
        vertices: [0, 42],
        sharpness: 1.0,
    });
    assert!(refine(&bad_tag, &loop1).is_err());
    assert!(refine(&generate::tetrahedron(), &opts(OsdScheme::Loop, 11)).is_err());
}

#[test]
fn set_distance_detects_differences() {
    let a = generate::icosphere(2);
    let mut b = a.clone();
    b.positions.reverse();
    assert!(max_vertex_set_distance(&a, &b) < 1e-15);
    b.positions[3].x += 0.5;
    let d = max_vertex_set_distance(&a, &b);
    assert!(d > 0.01 && d <= 0.5 + 1e-12, "{d}");
    assert_eq!(
        max_vertex_set_distance(&a, &generate::icosphere(1)),
        f64::INFINITY
    );
}

#[test]
fn options_take_effect() {
    let grid = generate::grid(3, 2, false);
    let with = |boundary, creasing, mesh: &Mesh| {
        let o = OsdOptions {
            scheme: OsdScheme::CatmullClark,
            boundary,
            creasing,
            levels: 2,
        };
        refine_ordered(mesh, &o).unwrap()
    };
    let edge_only = with(OsdBoundary::EdgeOnly, OsdCreasing::Uniform, &grid);
    let corners = with(OsdBoundary::EdgeAndCorner, OsdCreasing::Uniform, &grid);
    let none = with(OsdBoundary::None, OsdCreasing::Uniform, &grid);
    assert!(max_vertex_distance(&edge_only, &corners) > 1e-3);
    // Documented fact: OpenSubdiv always makes boundary edges infinitely sharp; `None` only
    // tags the faces at boundary vertices as holes (for patches), so uniform refinement gives
    // the same faces and positions as `EdgeOnly`.
    assert_eq!(edge_only, none);
    let mut cube = generate::cube();
    for (a, b, s) in [(0, 2, 1.7), (2, 3, 0.6)] {
        cube.edge_tags.push(EdgeTag {
            vertices: [a, b],
            sharpness: s,
        });
    }
    let uniform = with(OsdBoundary::EdgeOnly, OsdCreasing::Uniform, &cube);
    let chaikin = with(OsdBoundary::EdgeOnly, OsdCreasing::Chaikin, &cube);
    let d = max_vertex_distance(&uniform, &chaikin);
    assert!(d > 1e-4, "{d}");
}

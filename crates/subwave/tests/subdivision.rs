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

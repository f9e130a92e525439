//! Limit positions and normals (Maret §3.4) on whole meshes: box splines on regular grids,
//! invariance under refinement, convergence, creases, corners, normals.

use glam::DVec3;
use subwave::generate;
use subwave::subdivision::limit::{
    subdivide_limit, subdivide_limit_positions, LimitScheme, LimitSurface,
};
use subwave::subdivision::loop_scheme::LoopWeights;
use subwave::subdivision::{subdivide, BoundaryMode, Refinement, Scheme, SubdivideOptions};
use subwave::{EdgeTag, Error, Mesh, SHARPNESS_INFINITE};

fn opts(scheme: Scheme, levels: u32) -> SubdivideOptions {
    SubdivideOptions {
        scheme,
        levels,
        ..Default::default()
    }
}

fn limit_of(mesh: &Mesh, o: &SubdivideOptions) -> (Refinement, LimitSurface) {
    let r = Refinement::build(mesh, o, false).unwrap();
    let l = r.limit(LimitScheme::from_options(o).unwrap()).unwrap();
    (r, l)
}

#[test]
fn loop_limit_on_regular_grid_is_the_quartic_box_spline() {
    // The quartic box spline at a lattice point: 1/2 the point, 1/12 each of its 6 neighbours.
    let n = 6u32;
    let mut m = generate::triangle_grid(n);
    let h = |i: i64, j: i64| ((i * 7 + j * 3) % 5) as f64 + 0.1 * (i * j) as f64;
    let id = |i: i64, j: i64| (j * (n as i64 + 1) + i) as usize;
    for j in 0..=n as i64 {
        for i in 0..=n as i64 {
            m.positions[id(i, j)].z = h(i, j);
        }
    }
    for weights in [LoopWeights::Loop, LoopWeights::Warren] {
        let o = SubdivideOptions {
            loop_weights: weights,
            boundary: BoundaryMode::OpenSubdiv,
            ..opts(Scheme::Loop, 0)
        };
        let (out, l) = subdivide_limit(&m, &o).unwrap();
        assert_eq!(out.positions, l.positions);
        for j in 1..n as i64 {
            for i in 1..n as i64 {
                let ring = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1)];
                let expect =
                    0.5 * h(i, j) + ring.iter().map(|(a, b)| h(i + a, j + b)).sum::<f64>() / 12.0;
                let got = l.positions[id(i, j)].z;
                assert!((got - expect).abs() < 1e-12, "{i},{j}: {got} vs {expect}");
            }
        }
    }
}

#[test]
fn catmull_clark_limit_on_regular_grid_is_the_bicubic_b_spline() {
    let n = 6u32;
    let mut m = generate::grid(n, n, false);
    let h = |i: i64, j: i64| ((i * 5 + j * 11) % 7) as f64 - 0.2 * (i * j) as f64;
    let id = |i: i64, j: i64| (j * (n as i64 + 1) + i) as usize;
    for j in 0..=n as i64 {
        for i in 0..=n as i64 {
            m.positions[id(i, j)].z = h(i, j);
        }
    }
    let (_, l) = limit_of(&m, &opts(Scheme::CatmullClark, 0));
    let w = [(-1, 1.0), (0, 4.0), (1, 1.0)];
    for j in 1..n as i64 {
        for i in 1..n as i64 {
            let mut expect = 0.0;
            for (a, wa) in w {
                for (b, wb) in w {
                    expect += wa * wb / 36.0 * h(i + a, j + b);
                }
            }
            let got = l.positions[id(i, j)];
            assert!(
                (got.z - expect).abs() < 1e-12,
                "{i},{j}: {} vs {expect}",
                got.z
            );
            assert!((got.x - i as f64).abs() < 1e-12 && (got.y - j as f64).abs() < 1e-12);
        }
    }
    // Boundary vertices: the cubic B-spline of the boundary curve, (1, 4, 1)/6.
    for i in 1..n as i64 {
        let expect = (h(i - 1, 0) + 4.0 * h(i, 0) + h(i + 1, 0)) / 6.0;
        assert!((l.positions[id(i, 0)].z - expect).abs() < 1e-12);
    }
}

fn with_crease_line(mut m: Mesh, line: &[u32]) -> Mesh {
    for w in line.windows(2) {
        m.edge_tags.push(EdgeTag {
            vertices: [w[0], w[1]],
            sharpness: SHARPNESS_INFINITE,
        });
    }
    m
}

/// A bumpy closed quad mesh: the torus with some vertices pushed.
fn bumpy(mut m: Mesh) -> Mesh {
    for (i, p) in m.positions.iter_mut().enumerate() {
        *p *= 1.0 + 0.15 * ((i * 7 % 5) as f64 - 2.0) / 2.0;
    }
    m
}

/// Cases without darts (whose limit masks are approximate, as in OpenSubdiv).
fn invariance_cases() -> Vec<(&'static str, Mesh, SubdivideOptions)> {
    let osd = |scheme, levels| SubdivideOptions {
        boundary: BoundaryMode::OpenSubdiv,
        ..opts(scheme, levels)
    };
    let mut grid = generate::grid(5, 4, false);
    grid.positions
        .iter_mut()
        .for_each(|p| p.z = (p.x * 1.3).sin() + 0.3 * p.y * p.y);
    let creased_grid = with_crease_line(grid.clone(), &[2, 8, 14, 20, 26]);
    let mut tri_grid = generate::triangle_grid(5);
    tri_grid
        .positions
        .iter_mut()
        .for_each(|p| p.z = (p.x * 0.9).cos() * p.y);
    let creased_tri = with_crease_line(tri_grid.clone(), &[3, 9, 15, 21, 27, 33]);
    let sharp_cube = generate::cube();
    // The loop around the face z = -1.
    let sharp_cube = with_crease_line(sharp_cube, &[0, 2, 3, 1, 0]);
    vec![
        (
            "icosahedron",
            generate::icosahedron(),
            opts(Scheme::Loop, 0),
        ),
        (
            "tetrahedron",
            generate::tetrahedron(),
            opts(Scheme::Loop, 0),
        ),
        (
            "tri torus",
            bumpy(generate::torus(1.0, 0.4, 6, 5, true)),
            opts(Scheme::Loop, 0),
        ),
        (
            "warren icosphere",
            bumpy(generate::icosphere(1)),
            SubdivideOptions {
                loop_weights: LoopWeights::Warren,
                ..opts(Scheme::Loop, 0)
            },
        ),
        ("disk", generate::disk(7), osd(Scheme::Loop, 0)),
        ("tri grid", tri_grid, osd(Scheme::Loop, 0)),
        ("creased tri grid", creased_tri, osd(Scheme::Loop, 0)),
        (
            "corners",
            generate::triangle_grid(3),
            SubdivideOptions {
                boundary: BoundaryMode::OpenSubdivCorners,
                ..opts(Scheme::Loop, 0)
            },
        ),
        ("cube", generate::cube(), opts(Scheme::CatmullClark, 1)),
        (
            "pyramid",
            generate::pyramid(),
            opts(Scheme::CatmullClark, 1),
        ),
        (
            "quad torus",
            bumpy(generate::torus(1.0, 0.4, 6, 5, false)),
            opts(Scheme::CatmullClark, 0),
        ),
        ("grid", grid, opts(Scheme::CatmullClark, 0)),
        ("creased grid", creased_grid, opts(Scheme::CatmullClark, 0)),
        ("sharp cube face", sharp_cube, opts(Scheme::CatmullClark, 1)),
    ]
}

#[test]
fn limit_positions_and_normals_are_invariant_under_refinement() {
    for (name, m, o) in invariance_cases() {
        for extra in 0..2 {
            let coarse = SubdivideOptions {
                levels: o.levels + extra,
                ..o
            };
            let fine = SubdivideOptions {
                levels: coarse.levels + 1,
                ..o
            };
            let (rc, a) = limit_of(&m, &coarse);
            let (_, b) = limit_of(&m, &fine);
            let mut moved = 0.0f64;
            let topo = rc.finest_topology();
            let mut checked_normals = 0;
            for v in 0..rc.positions.len() {
                let d = (a.positions[v] - b.positions[v]).length();
                assert!(
                    d < 1e-12,
                    "{name} level {}: vertex {v} moved {d}",
                    coarse.levels
                );
                moved = moved.max((a.positions[v] - rc.positions[v]).length());
                // Tangent masks are eigenvectors at smooth vertices and regular boundary
                // vertices (3 triangles, 2 quads): the tangents scale, normals stay.
                let sharp = topo
                    .vertex_edges(v)
                    .iter()
                    .filter(|&&e| topo.edge_sharpness[e as usize] > 0.0)
                    .count();
                let faces = topo.vertex_faces(v).len();
                let regular_boundary = sharp == 2
                    && topo.vertex_sharpness[v] == 0.0
                    && faces == if o.scheme == Scheme::Loop { 3 } else { 2 }
                    && topo.vertex_edges(v).len() == faces + 1;
                if sharp > 0 && !regular_boundary {
                    continue;
                }
                checked_normals += 1;
                let dn = (a.normals[v] - b.normals[v]).length();
                assert!(
                    dn < 1e-9,
                    "{name} level {}: normal of {v} changed by {dn}: {} vs {}",
                    coarse.levels,
                    a.normals[v],
                    b.normals[v]
                );
            }
            assert!(checked_normals > 0, "{name}");
            // The test is not vacuous: the limit differs from the control points.
            if name != "corners" {
                assert!(moved > 1e-3, "{name}: limit equals control points");
            }
        }
    }
}

/// Area-weighted vertex normals of a mesh.
fn mesh_normals(positions: &[DVec3], m: &Mesh) -> Vec<DVec3> {
    Mesh {
        positions: positions.to_vec(),
        ..m.clone()
    }
    .vertex_normals()
}

#[test]
fn limit_at_level_3_is_closer_to_level_6_than_level_3() {
    for (m, scheme) in [
        (bumpy(generate::icosahedron()), Scheme::Loop),
        (bumpy(generate::cube()), Scheme::CatmullClark),
    ] {
        let (r3, l3) = limit_of(&m, &opts(scheme, 3));
        let r6 = Refinement::build(&m, &opts(scheme, 6), false).unwrap();
        let (mut d_limit, mut d_plain) = (0.0f64, 0.0f64);
        for v in 0..r3.positions.len() {
            // Old vertices keep their indices (ordering contract).
            d_limit = d_limit.max((l3.positions[v] - r6.positions[v]).length());
            d_plain = d_plain.max((r3.positions[v] - r6.positions[v]).length());
        }
        assert!(
            d_limit < 0.05 * d_plain,
            "{scheme:?}: limit {d_limit} vs level 3 {d_plain}"
        );
        // Limit normals agree with the level-6 mesh normals.
        let n6 = mesh_normals(&r6.positions, &r6.to_mesh());
        let worst = (0..r3.positions.len())
            .map(|v| l3.normals[v].dot(n6[v]))
            .fold(1.0f64, f64::min);
        assert!(worst > 0.999, "{scheme:?}: normal agreement {worst}");
        eprintln!("{scheme:?}: max |limit3 - level6| {d_limit:.3e}, |level3 - level6| {d_plain:.3e}, min normal dot {worst:.6}");
    }
}

#[test]
fn normals_are_unit_orthogonal_and_outward() {
    for (name, m, o) in invariance_cases() {
        let o = SubdivideOptions {
            levels: o.levels + 2,
            ..o
        };
        let (r, l) = limit_of(&m, &o);
        let fine = mesh_normals(&r.positions, &r.to_mesh());
        let topo = r.finest_topology();
        for (v, &n) in l.normals.iter().enumerate() {
            assert!((n.length() - 1.0).abs() < 1e-12, "{name}: |n| of {v}");
            for t in [l.tangents1[v], l.tangents2[v]] {
                assert!(n.dot(t).abs() < 1e-12 * t.length().max(1.0), "{name}");
            }
            // Same side as the faces (outward on closed meshes, which are oriented so): as
            // the area-weighted normal at smooth vertices; at creases and corners the normal
            // is one side's, as one of the incident faces'.
            let smooth = topo
                .vertex_edges(v)
                .iter()
                .all(|&e| topo.edge_sharpness[e as usize] == 0.0);
            let agree = if smooth {
                n.dot(fine[v])
            } else {
                topo.vertex_faces(v)
                    .iter()
                    .map(|&f| {
                        let fv = topo.face_vertices(f as usize);
                        let q = |k: usize| r.positions[fv[k % fv.len()] as usize];
                        n.dot((q(1) - q(0)).cross(q(2) - q(1)).normalize())
                    })
                    .fold(-1.0, f64::max)
            };
            assert!(agree > 0.5, "{name}: normal of {v} points inward: {n}");
        }
    }
    // On the sphere-like icosphere, outward is away from the centre.
    let (_, l) = limit_of(&generate::icosphere(1), &opts(Scheme::Loop, 2));
    for (p, n) in l.positions.iter().zip(&l.normals) {
        assert!(p.normalize().dot(*n) > 0.99);
    }
}

#[test]
fn crease_vertices_lie_on_the_crease_curve_and_corners_stay() {
    // A crease line x = 2 across a bumpy grid: its limit is the cubic B-spline of the line's
    // control points, (1/6, 2/3, 1/6), whatever the surface around it.
    let mut grid = generate::grid(4, 4, false);
    grid.positions
        .iter_mut()
        .for_each(|p| p.z = (p.x * p.y).sin() + 0.2 * p.x);
    let line = [2u32, 7, 12, 17, 22];
    let m = with_crease_line(grid, &line);
    for levels in 0..3 {
        let (r, l) = limit_of(&m, &opts(Scheme::CatmullClark, levels));
        // The crease control points at this level are the line's vertices, refined.
        let topo = r.finest_topology();
        let p = &r.positions;
        let mut checked = 0;
        for v in 0..p.len() {
            let sharp: Vec<u32> = topo
                .vertex_edges(v)
                .iter()
                .filter(|&&e| topo.edge_sharpness[e as usize] > 0.0)
                .map(|&e| topo.other_vertex(e as usize, v as u32))
                .collect();
            if sharp.len() == 2
                && !topo
                    .vertex_edges(v)
                    .iter()
                    .any(|&e| topo.is_boundary_edge(e as usize))
            {
                let expect = (p[sharp[0] as usize] + 4.0 * p[v] + p[sharp[1] as usize]) / 6.0;
                assert!((l.positions[v] - expect).length() < 1e-12);
                // The crease tangent is along the crease.
                let along = p[sharp[0] as usize] - p[sharp[1] as usize];
                assert!(l.tangents1[v].normalize().cross(along.normalize()).length() < 0.2);
                checked += 1;
            }
        }
        assert_eq!(checked, 4 * (1 << levels) - 1);
    }
    // Corners do not move.
    let mut m = generate::triangle_grid(3);
    m.positions.iter_mut().for_each(|p| p.z = p.x * p.y);
    let o = SubdivideOptions {
        boundary: BoundaryMode::OpenSubdivCorners,
        ..opts(Scheme::Loop, 2)
    };
    let (r, l) = limit_of(&m, &o);
    for v in [3usize, 12] {
        assert_eq!(l.positions[v], r.positions[v]);
        assert_eq!(l.positions[v], m.positions[v]);
    }
}

#[test]
fn limit_stencils_reevaluate_moving_control_points() {
    let m = generate::torus(1.0, 0.4, 6, 5, false);
    let o = opts(Scheme::CatmullClark, 2);
    let r = Refinement::build(&m, &o, true).unwrap();
    let stencils = r.limit_stencils(LimitScheme::CatmullClark).unwrap();
    let mut moved = m.clone();
    moved
        .positions
        .iter_mut()
        .enumerate()
        .for_each(|(i, p)| p.z += 0.1 * (i as f64).sin());
    let fine = r.evaluate(&moved.positions).unwrap();
    let animated = stencils.evaluate(&fine);
    let (direct, l) = subdivide_limit(&moved, &o).unwrap();
    for (a, b) in animated.positions.iter().zip(&direct.positions) {
        assert!((*a - *b).length() < 1e-14);
    }
    for (a, b) in animated.normals.iter().zip(&l.normals) {
        assert!((*a - *b).length() < 1e-12);
    }
    // Each position stencil sums to 1, each tangent stencil to 0.
    for j in 0..stencils.position.len() {
        let sum = |t: &subwave::subdivision::stencil::StencilTable| {
            t.weights[t.offsets[j] as usize..t.offsets[j + 1] as usize]
                .iter()
                .sum::<f64>()
        };
        assert!((sum(&stencils.position) - 1.0).abs() < 1e-14);
        assert!(sum(&stencils.tangent1).abs() < 1e-13);
        assert!(sum(&stencils.tangent2).abs() < 1e-13);
    }
}

#[test]
fn limit_errors_name_the_problem() {
    let e = subdivide_limit(&generate::icosahedron(), &opts(Scheme::Midpoint, 1)).unwrap_err();
    assert!(
        matches!(e, Error::InvalidArgument(ref s) if s.contains("midpoint")),
        "{e}"
    );
    // Catmull-Clark limit masks need quads: level 0 of the pyramid has triangles.
    let e = subdivide_limit(&generate::pyramid(), &opts(Scheme::CatmullClark, 0)).unwrap_err();
    assert!(
        matches!(e, Error::InvalidArgument(ref s) if s.contains("face 1")),
        "{e}"
    );
    assert!(subdivide_limit(&generate::pyramid(), &opts(Scheme::CatmullClark, 1)).is_ok());
    // Colours survive, at the refined values.
    let mut m = generate::cube();
    m.colors = Some(vec![[0.5, 0.25, 1.0]; 8]);
    let (out, _) = subdivide_limit(&m, &opts(Scheme::CatmullClark, 1)).unwrap();
    let plain = subdivide(&m, &opts(Scheme::CatmullClark, 1)).unwrap();
    assert_eq!(out.colors, plain.colors);
    assert_eq!(out.face_indices, plain.face_indices);
}

#[test]
fn semi_sharp_creases_are_exact_once_relaxed() {
    // Sharpness 1.5 on the loop around one cube face: after 2 levels every sharpness is 0, so
    // the limit is exact (invariant); after 1 level the edges keep sharpness 0.5 and their
    // vertices are projected as crease vertices (OpenSubdiv's `PrimvarRefiner::Limit`).
    let mut m = generate::cube();
    m.edge_tags = [[0u32, 2], [2, 3], [3, 1], [1, 0]]
        .iter()
        .map(|&v| EdgeTag {
            vertices: v,
            sharpness: 1.5,
        })
        .collect();
    let (r2, a) = limit_of(&m, &opts(Scheme::CatmullClark, 2));
    let (_, b) = limit_of(&m, &opts(Scheme::CatmullClark, 3));
    for v in 0..r2.positions.len() {
        assert!((a.positions[v] - b.positions[v]).length() < 1e-12);
    }
    let (r1, l1) = limit_of(&m, &opts(Scheme::CatmullClark, 1));
    let topo = r1.finest_topology();
    let sharp: Vec<u32> = topo
        .vertex_edges(0)
        .iter()
        .filter(|&&e| topo.edge_sharpness[e as usize] > 0.0)
        .map(|&e| topo.other_vertex(e as usize, 0))
        .collect();
    assert_eq!(sharp.len(), 2);
    let p = &r1.positions;
    let crease = (p[sharp[0] as usize] + 4.0 * p[0] + p[sharp[1] as usize]) / 6.0;
    assert!((l1.positions[0] - crease).length() < 1e-12);
    // ... which is not the exact limit (0.19 away on this cube of side 2).
    let d = (l1.positions[0] - a.positions[0]).length();
    assert!(d > 1e-4 && d < 0.5, "{d}");
}

#[test]
fn fast_paths_agree_with_the_general_one() {
    for (name, m, o) in invariance_cases() {
        for levels in [o.levels, o.levels + 2] {
            let o = SubdivideOptions { levels, ..o };
            let (_, general) = limit_of(&m, &o);
            let (out, fast) = subdivide_limit(&m, &o).unwrap();
            assert_eq!(general, fast, "{name} {levels}");
            assert_eq!(out.positions, fast.positions);
            let positions = subdivide_limit_positions(&m, &o).unwrap();
            // Unordered 1-rings sum the same weights in another order.
            for (a, b) in positions.positions.iter().zip(&fast.positions) {
                assert!((*a - *b).length() < 1e-14, "{name} {levels}");
            }
            assert_eq!(positions.face_indices, out.face_indices);
        }
    }
}

#[test]
#[ignore = "timing"]
fn timing_limit() {
    use std::time::Instant;
    let m = generate::icosphere(4);
    let o = opts(Scheme::Loop, 3);
    let t = Instant::now();
    let r = subdivide(&m, &o).unwrap();
    eprintln!(
        "subdivide {:?} ({} vertices)",
        t.elapsed(),
        r.positions.len()
    );
    let t = Instant::now();
    let _ = subdivide_limit(&m, &o).unwrap();
    eprintln!("subdivide_limit {:?}", t.elapsed());
    let t = Instant::now();
    let _ = subdivide_limit_positions(&m, &o).unwrap();
    eprintln!("subdivide_limit_positions {:?}", t.elapsed());
}

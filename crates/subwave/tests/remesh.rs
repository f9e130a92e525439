//! Remeshing to subdivision connectivity: generated meshes of several topologies, repair of
//! non-manifold input, the ordering contract (detected by `Hierarchy::detect`), and the
//! corpus when `../shared/data/meshes` exists.

use std::path::PathBuf;

use subwave::distance::distance;
use subwave::generate;
use subwave::hierarchy::Hierarchy;
use subwave::remesh::{remesh, Method, MethodChoice, RemeshOptions, Remeshed};
use subwave::{DVec3, Mesh, MeshError, Topology};

fn topo_summary(m: &Mesh) -> (Option<u64>, usize, usize) {
    let t = Topology::build(m);
    let (_, loops) = t.boundary_loops();
    let (_, comps) = t.face_components();
    (t.genus(), loops, comps)
}

fn opts(levels: u32, base_faces: usize) -> RemeshOptions {
    RemeshOptions {
        levels,
        base_faces,
        ..RemeshOptions::default()
    }
}

/// Checks the invariants every remesh must satisfy, returns the PSNR against the input.
fn check(input: &Mesh, r: &Remeshed, levels: u32) -> f64 {
    let m = &r.mesh;
    assert_eq!(m.num_faces(), r.base.num_faces() * 4usize.pow(levels));
    // Same topology as the input (genus, boundary loops, components).
    assert_eq!(topo_summary(m), topo_summary(input), "topology changed");
    assert_eq!(topo_summary(&r.base), topo_summary(input), "base topology");
    // Subdivision connectivity in contract order: detection finds it with the identity.
    if levels > 0 {
        let (h, ren) = Hierarchy::detect(m, Some(levels)).expect("detectable hierarchy");
        assert_eq!(h.levels(), levels as usize);
        assert!(ren.vertices.iter().enumerate().all(|(i, &v)| i as u32 == v));
    }
    assert!(m.positions.iter().all(|p| p.is_finite()));
    // No face turned over against the input, none degenerate.
    assert_eq!(
        (r.quality.flipped, r.quality.degenerate),
        (0, 0),
        "flipped / degenerate faces: {:?}",
        r.quality
    );
    let d = distance(input, m, 20_000).unwrap();
    d.psnr
}

#[test]
fn sphere_remeshes_onto_the_surface() {
    let input = generate::icosphere(4);
    let r = remesh(&input, &opts(3, 40)).unwrap();
    assert_eq!(r.method, Method::Maps);
    assert!(r.base.num_faces() <= 60, "{}", r.base.num_faces());
    let psnr = check(&input, &r, 3);
    assert!(psnr > 60.0, "psnr {psnr}");
    // Every vertex on the input surface (up to the chordal error of the icosphere).
    let worst = r
        .mesh
        .positions
        .iter()
        .map(|p| (p.length() - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.01, "{worst}");
    assert!(r.quality.min_angle > 1.0, "{:?}", r.quality);
}

#[test]
fn torus_keeps_its_genus() {
    let input = generate::torus(1.0, 0.35, 48, 24, true);
    let r = remesh(&input, &opts(2, 60)).unwrap();
    let psnr = check(&input, &r, 2);
    assert!(psnr > 50.0, "psnr {psnr}");
}

#[test]
fn grid_keeps_its_boundary_on_the_input_boundary() {
    let input = generate::grid(20, 14, true);
    let o = RemeshOptions {
        sharp_angle: Some(30.0),
        ..opts(2, 16)
    };
    let r = remesh(&input, &o).unwrap();
    check(&input, &r, 2);
    // The plane stays a plane and the boundary stays on the rectangle.
    let t = Topology::build(&r.mesh);
    for e in 0..t.num_edges() {
        if t.is_boundary_edge(e) {
            for v in t.edge_vertices[e] {
                let p = r.mesh.positions[v as usize];
                let on = p.x.abs() < 1e-9
                    || (p.x - 20.0).abs() < 1e-9
                    || p.y.abs() < 1e-9
                    || (p.y - 14.0).abs() < 1e-9;
                assert!(on, "boundary vertex {v} at {p} left the input boundary");
            }
        }
    }
    assert!(r.mesh.positions.iter().all(|p| p.z.abs() < 1e-12));
}

#[test]
fn two_components_are_remeshed_independently() {
    let a = generate::icosphere(3);
    let mut b = generate::torus(1.0, 0.3, 32, 16, true);
    for p in &mut b.positions {
        *p += DVec3::new(4.0, 0.0, 0.0);
    }
    let n = a.positions.len() as u32;
    let mut input = a.clone();
    input.positions.extend(b.positions.iter().copied());
    for f in b.faces() {
        let g: Vec<u32> = f.iter().map(|&i| i + n).collect();
        input.push_face(&g);
    }
    let r = remesh(&input, &opts(2, 80)).unwrap();
    check(&input, &r, 2);
}

#[test]
fn quads_build_a_catmull_clark_hierarchy() {
    let input = generate::icosphere(3);
    let o = RemeshOptions {
        quads: true,
        ..opts(2, 30)
    };
    let r = remesh(&input, &o).unwrap();
    assert!(r.mesh.is_quad_mesh());
    assert_eq!(r.base.num_faces() * 16, r.mesh.num_faces());
    let (h, ren) = Hierarchy::detect(&r.mesh, Some(2)).expect("quad hierarchy");
    assert_eq!(h.levels(), 2);
    assert!(ren.vertices.iter().enumerate().all(|(i, &v)| i as u32 == v));
    assert_eq!(topo_summary(&r.mesh), topo_summary(&input));
}

#[test]
fn non_manifold_input_is_an_error_naming_elements_unless_repaired() {
    // Two spheres glued at one vertex plus a fin edge: a pinched vertex and a shared edge.
    let bow = generate::bowtie();
    let err = remesh(&bow, &opts(1, 2)).unwrap_err();
    match err {
        subwave::Error::Mesh(MeshError::NonManifold { vertices, .. }) => {
            assert_eq!(vertices, vec![0])
        }
        e => panic!("unexpected error {e}"),
    }
    let fin = generate::fin();
    let err = remesh(&fin, &opts(1, 3)).unwrap_err().to_string();
    assert!(err.contains("0-1") && err.contains("--repair"), "{err}");
    for m in [bow, fin] {
        let o = RemeshOptions {
            repair: true,
            ..opts(2, 3)
        };
        let r = remesh(&m, &o).unwrap();
        assert!(r.repair.added_vertices > 0);
        let t = Topology::build(&r.mesh);
        assert!(t.is_manifold());
        Hierarchy::detect(&r.mesh, Some(2)).unwrap();
    }
}

#[test]
fn shrink_wrap_runs_on_genus_zero() {
    let input = generate::icosphere(4);
    let o = RemeshOptions {
        method: MethodChoice::ShrinkWrap,
        ..opts(2, 40)
    };
    let r = remesh(&input, &o).unwrap();
    assert_eq!(r.method, Method::ShrinkWrap);
    let psnr = check(&input, &r, 2);
    assert!(psnr > 50.0, "{psnr}");
}

fn corpus(name: &str) -> Option<Mesh> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/meshes")
        .join(name);
    if !p.exists() {
        eprintln!("skipping: {} not found", p.display());
        return None;
    }
    Some(subwave::io::read_mesh(&p, None).unwrap())
}

/// Every corpus mesh remeshes at two levels (with repair where non-manifold; suzanne's
/// quads are split along a diagonal that is not already an edge, so it needs none): same
/// topology as the prepared input, detectable hierarchy, few flipped faces.
#[test]
fn corpus_meshes_remesh() {
    let all = [
        ("woody.obj", false),
        ("spot.obj", false),
        ("cheburashka.obj", false),
        ("rocker-arm.obj", false),
        ("fandisk.obj", false),
        ("suzanne.obj", false),
        ("cow.obj", true),
        ("teapot.obj", true),
        ("beetle.obj", true),
    ];
    for (name, repair) in all {
        let Some(input) = corpus(name) else { return };
        let o = RemeshOptions {
            repair,
            ..opts(2, 200)
        };
        let r = remesh(&input, &o).unwrap_or_else(|e| panic!("{name}: {e}"));
        let d = distance(&input, &r.mesh, 20_000).unwrap();
        eprintln!(
            "{name}: method {} base {} psnr {:.1} max {:.3}% min angle {:.2} mean {:.1} flipped {}/{} degenerate {}",
            r.method.name(),
            r.base.num_faces(),
            d.psnr,
            100.0 * d.max / d.diagonal,
            r.quality.min_angle,
            r.quality.mean_angle,
            r.quality.flipped,
            r.mesh.num_faces(),
            r.quality.degenerate
        );
        assert!(d.psnr > 40.0, "{name}: {}", d.psnr);
        assert!(r.quality.flipped * 10 < r.mesh.num_faces(), "{name}");
        if ["woody.obj", "spot.obj", "rocker-arm.obj", "fandisk.obj"].contains(&name) {
            assert_eq!(
                (r.quality.flipped, r.quality.degenerate),
                (0, 0),
                "{name}: flipped / degenerate"
            );
        }
        assert!(Topology::build(&r.mesh).is_manifold(), "{name}");
        Hierarchy::detect(&r.mesh, Some(2)).unwrap_or_else(|e| panic!("{name}: {e}"));
        if !repair {
            assert_eq!(topo_summary(&r.mesh), topo_summary(&input), "{name}");
        }
    }
}

/// The beetle's repair removes the nine lids of the parts glued onto its body (a mirror,
/// headlights: pockets of one to three faces over a triangle left in place), so that only
/// 20 of its 47 non-manifold edges are cut, and stitches the two slits its modeller left
/// between panels (four T-junctions: 32 boundary loops become 30); the remesh over 200 base
/// faces folds less than with the lids cut apart (8 flipped faces at 3 levels, 4 with the
/// lids removed, 2 with the slits stitched too).
#[test]
fn corpus_beetle_pocket_lids_are_removed() {
    let Some(input) = corpus("beetle.obj") else {
        return;
    };
    let (pos, tris, r) = subwave::remesh::repair::prepare(&input, true).unwrap();
    assert_eq!(
        (r.lid_faces, r.non_manifold_edges, r.stitched_vertices),
        (9, 20, 4),
        "{r:?}"
    );
    let t = Topology::build(&Mesh::from_triangles(pos, &tris));
    assert!(t.is_manifold() && t.inconsistent_edges.is_empty());
    assert_eq!(t.boundary_loops().1, 30);
    let o = RemeshOptions {
        repair: true,
        ..opts(3, 200)
    };
    let m = remesh(&input, &o).unwrap();
    eprintln!("beetle 3 levels over 200: {:?}", m.quality);
    assert!(
        m.quality.flipped + m.quality.degenerate <= 3,
        "{:?}",
        m.quality
    );
}

/// The bunny's five holes stay holes and the genus and component count are kept.
#[test]
fn corpus_bunny_keeps_its_holes() {
    let Some(input) = corpus("stanford-bunny.obj") else {
        return;
    };
    let r = remesh(&input, &opts(2, 200)).unwrap();
    let t = Topology::build(&r.mesh);
    assert_eq!(t.boundary_loops().1, 5);
    assert_eq!(topo_summary(&r.mesh), topo_summary(&input));
    assert!(r.base.num_faces() <= 220, "{}", r.base.num_faces());
}

/// Fandisk keeps its creases: Hausdorff distance below 0.5% of the diagonal (3 levels here;
/// 5 levels in the ignored test below).
#[test]
fn corpus_fandisk_keeps_its_creases() {
    let Some(input) = corpus("fandisk.obj") else {
        return;
    };
    let o = RemeshOptions {
        sharp_angle: Some(40.0),
        ..opts(3, 200)
    };
    let r = remesh(&input, &o).unwrap();
    let d = distance(&input, &r.mesh, 50_000).unwrap();
    eprintln!(
        "fandisk 3 levels: psnr {:.1} max {:.4}%",
        d.psnr,
        100.0 * d.max / d.diagonal
    );
    assert!(d.max < 0.005 * d.diagonal, "{}", d.max / d.diagonal);
}

/// The targets at full size (slow in the test profile; run with `--ignored`):
/// bunny 5 levels ≥ 75 dB, 6 levels ≥ 85 dB, fandisk 5 levels Hausdorff ≤ 0.5% of the
/// diagonal and no flipped or degenerate face (nor on the bunny at 5 and 6 levels, spot,
/// woody, rocker-arm and cheburashka).
#[test]
#[ignore]
fn corpus_targets_at_five_levels() {
    if let Some(input) = corpus("stanford-bunny.obj") {
        let r = remesh(&input, &opts(5, 200)).unwrap();
        let d = distance(&input, &r.mesh, 200_000).unwrap();
        eprintln!(
            "bunny 5 levels: psnr {:.2} max {:.3}%",
            d.psnr,
            100.0 * d.max / d.diagonal
        );
        assert!(d.psnr >= 75.0, "{}", d.psnr);
        assert_eq!(Topology::build(&r.mesh).boundary_loops().1, 5);
        // The last flipped face (a sliver across a hole rim that rolls over, where the
        // tangent-plane kernel is empty) went with the fold repair's star search.
        assert_eq!((r.quality.flipped, r.quality.degenerate), (0, 0), "bunny");
        let r = remesh(&input, &opts(6, 200)).unwrap();
        let d = distance(&input, &r.mesh, 200_000).unwrap();
        eprintln!("bunny 6 levels: psnr {:.2}", d.psnr);
        assert!(d.psnr >= 85.0, "{}", d.psnr);
        // Its last flipped face (in a strip of level-4 triangles the resampling crushed)
        // went with the re-embedded ancestors of `remesh::ancestor_flatten`, the one before
        // with the simultaneous untangling of `remesh::flatten`'s discs.
        assert_eq!((r.quality.flipped, r.quality.degenerate), (0, 0), "bunny 6");
    }
    if let Some(input) = corpus("fandisk.obj") {
        let o = RemeshOptions {
            sharp_angle: Some(40.0),
            ..opts(5, 200)
        };
        let r = remesh(&input, &o).unwrap();
        let d = distance(&input, &r.mesh, 200_000).unwrap();
        eprintln!("fandisk 5 levels: max {:.4}%", 100.0 * d.max / d.diagonal);
        assert!(d.max <= 0.005 * d.diagonal);
        assert_eq!((r.quality.flipped, r.quality.degenerate), (0, 0), "fandisk");
    }
    // No flipped or degenerate face at 5 levels where the parameterization is an embedding
    // up to the base vertices (spot had 1 flipped face, woody 12, before the re-attachment
    // of chain points in the flattened star and the location in neighbouring frames;
    // rocker-arm 4, before the fold repair's discs grew along the faces a flat
    // re-embedding leaves turned over; cheburashka 1, before the re-subdivision of its
    // nearest unfolded ancestor, `remesh::ancestor_flatten`).
    for name in ["spot.obj", "woody.obj", "rocker-arm.obj", "cheburashka.obj"] {
        if let Some(input) = corpus(name) {
            let r = remesh(&input, &opts(5, 200)).unwrap();
            eprintln!("{name} 5 levels: {:?}", r.quality);
            assert_eq!((r.quality.flipped, r.quality.degenerate), (0, 0), "{name}");
        }
    }
}

/// A folded parameterization (two neighbouring input vertices with swapped parameters, so
/// their triangles' images turn over) is untangled: the number of input triangles with an
/// inverted or degenerate image goes back to what it was without the swaps.
#[test]
fn folded_parameters_are_untangled() {
    use subwave::remesh::{param, simplify};
    let input = generate::icosphere(4);
    let tris: Vec<[u32; 3]> = input.faces().map(|f| [f[0], f[1], f[2]]).collect();
    let s = simplify::simplify(
        &input.positions,
        &tris,
        &simplify::PairSet::default(),
        60,
        None,
        &mut |_| {},
    );
    let base = Mesh::from_triangles(s.positions.clone(), &s.triangles);
    let fixed: Vec<bool> = s.params.iter().map(|p| p.bary.contains(&1.0)).collect();
    // The tracked parameterization, untangled.
    let mut params = s.params.clone();
    let u0 = param::untangle_params(&base, &tris, &mut params, &fixed, 4, &[]);
    let (b0, a0) = (u0.before, u0.after);
    assert!(a0 <= b0);
    // Swap the parameters of the two free corners of a few triangles whose corners are all
    // free.
    let mut swapped = 0;
    let mut used = vec![false; params.len()];
    for t in &tris {
        let [a, b, c] = t.map(|v| v as usize);
        if swapped == 3 || [a, b, c].iter().any(|&v| fixed[v] || used[v]) {
            continue;
        }
        params.swap(a, b);
        for v in [a, b, c] {
            used[v] = true;
        }
        swapped += 1;
    }
    assert_eq!(swapped, 3);
    let u = param::untangle_params(&base, &tris, &mut params, &fixed, 4, &[]);
    let (before, after) = (u.before, u.after);
    assert!(before >= a0 + 3, "{before}");
    assert!(after <= a0, "{before} -> {after} (untouched: {b0} -> {a0})");
    // Every input vertex keeps a valid parameter.
    for p in &params {
        assert!((p.face as usize) < s.triangles.len());
        assert!(p.bary.iter().all(|&x| (0.0..=1.0).contains(&x)));
        assert!((p.bary.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }
}

/// Folds injected into a clean remesh of a sphere (a few vertices pushed over a neighbour,
/// onto the surface, so that their faces turn over) are found and removed by the final
/// repair pass, which moves positions only and leaves no flipped or degenerate face.
#[test]
fn fold_repair_removes_injected_folds() {
    use subwave::remesh::fold_repair::repair_folds;
    use subwave::remesh::resample::Projector;
    let input = generate::icosphere(3);
    let tris: Vec<[u32; 3]> = input.faces().map(|f| [f[0], f[1], f[2]]).collect();
    let proj = Projector::new(&input.positions, &tris).unwrap();
    let r = remesh(&input, &opts(3, 40)).unwrap();
    let topo = Topology::build(&r.mesh);
    let mut pos = r.mesh.positions.clone();
    let mut hints: Vec<u32> = pos.iter().map(|&p| proj.closest(p).1).collect();
    let fixed = vec![false; pos.len()];
    // Push every 97th vertex (far apart) over its first neighbour.
    let mut pushed = 0;
    for v in (0..pos.len()).step_by(97) {
        let e = topo.vertex_edges(v)[0];
        let w = topo.other_vertex(e as usize, v as u32) as usize;
        let target = pos[w] + 0.6 * (pos[w] - pos[v]);
        let (q, t) = proj.closest(target);
        pos[v] = q;
        hints[v] = t;
        pushed += 1;
    }
    let before = pos.clone();
    let fr = repair_folds(
        &mut pos,
        &mut hints,
        &topo,
        &fixed,
        &[],
        &proj,
        12,
        None,
        f64::INFINITY,
    );
    assert!(
        fr.flipped_before >= pushed,
        "{pushed} pushes gave only {fr:?}"
    );
    assert_eq!((fr.flipped_after, fr.degenerate_after), (0, 0), "{fr:?}");
    // Connectivity untouched, every vertex still on the sphere, only the pushed vertices'
    // neighbourhoods moved.
    assert_eq!(pos.len(), before.len());
    for p in &pos {
        let (q, _) = proj.closest(*p);
        assert!(q.distance(*p) < 1e-9);
    }
    let moved = pos.iter().zip(&before).filter(|(a, b)| a != b).count();
    assert!(moved <= 40 * pushed, "{moved} vertices moved");
    // And the measure agrees.
    let mesh = Mesh {
        positions: pos,
        ..r.mesh.clone()
    };
    let q = subwave::remesh::quality::measure(&mesh, &proj);
    assert_eq!((q.flipped, q.degenerate), (0, 0), "{q:?}");
}

/// A fold that only the boundary can open: two remesh vertices on the input's boundary in
/// swapped order turn the face on the edge between them over, whatever the interior does.
/// With those vertices pinned the repair cannot remove it; allowed to slide along the
/// input's boundary (between the corners, which stay), they are spaced out again, and no
/// face is left flipped.
#[test]
fn fold_repair_slides_rim_vertices_along_the_boundary() {
    use subwave::remesh::fold_repair::repair_folds;
    use subwave::remesh::resample::Projector;
    let scale = |m: &mut Mesh, s: f64| m.positions.iter_mut().for_each(|p| *p *= s);
    let mut input = generate::grid(20, 20, true);
    scale(&mut input, 1.0 / 20.0);
    let tris: Vec<[u32; 3]> = input.faces().map(|f| [f[0], f[1], f[2]]).collect();
    let proj = Projector::new(&input.positions, &tris).unwrap();
    let mut rem = generate::grid(5, 5, true);
    scale(&mut rem, 1.0 / 5.0);
    let topo = Topology::build(&rem);
    // The bottom row's vertices 2 and 3 (x = 0.4, 0.6) in swapped order.
    rem.positions.swap(2, 3);
    let fixed: Vec<bool> = (0..rem.num_vertices())
        .map(|v| {
            topo.vertex_edges(v)
                .iter()
                .any(|&e| topo.is_boundary_edge(e as usize))
        })
        .collect();
    let slides: Vec<bool> = (0..rem.num_vertices())
        .map(|v| (1..=4).contains(&v))
        .collect();
    let run = |slides: &[bool]| {
        let mut pos = rem.positions.clone();
        let mut hints: Vec<u32> = pos.iter().map(|&p| proj.closest(p).1).collect();
        let fr = repair_folds(
            &mut pos,
            &mut hints,
            &topo,
            &fixed,
            slides,
            &proj,
            12,
            None,
            f64::INFINITY,
        );
        (fr, pos)
    };
    let (pinned, _) = run(&[]);
    assert!(pinned.flipped_before >= 1, "{pinned:?}");
    assert!(
        pinned.flipped_after > 0,
        "pinned, the fold cannot open: {pinned:?}"
    );
    let (slid, pos) = run(&slides);
    assert_eq!(
        (slid.flipped_after, slid.degenerate_after),
        (0, 0),
        "{slid:?}"
    );
    // The bottom row stays on the boundary, in order between the corners, which stay.
    assert_eq!(pos[0], rem.positions[0]);
    assert_eq!(pos[5], rem.positions[5]);
    for v in 0..5 {
        assert!(
            pos[v].y.abs() < 1e-12 && pos[v].z.abs() < 1e-12,
            "{:?}",
            pos[v]
        );
        assert!(pos[v].x < pos[v + 1].x, "{:?}", &pos[..6]);
    }
    // Only the sliding vertices moved among the fixed ones.
    for v in 0..rem.num_vertices() {
        if fixed[v] && !slides[v] {
            assert_eq!(pos[v], rem.positions[v], "vertex {v}");
        }
    }
}

/// A sphere with a finger: a protrusion that the base mesh cuts off, so that its image in
/// the base domain is small and the dyadic samples undersample it.
fn finger() -> Mesh {
    let mut m = subwave::generate::icosphere(4);
    for p in &mut m.positions {
        if p.z > 0.6 {
            let t = (p.z - 0.6) / 0.4;
            p.z += 4.0 * t * t;
            p.x *= 1.0 - 0.7 * t;
            p.y *= 1.0 - 0.7 * t;
        }
    }
    m
}

#[test]
fn relaxed_sampling_spreads_the_samples_evenly() {
    let input = finger();
    let run = |n: u32| {
        let o = RemeshOptions {
            param_relax_iterations: n,
            ..opts(4, 60)
        };
        let r = remesh(&input, &o).unwrap();
        let psnr = check(&input, &r, 4);
        // Spread of the face areas: standard deviation over mean.
        let p = &r.mesh.positions;
        let areas: Vec<f64> = r
            .mesh
            .faces()
            .map(|f| {
                let (a, b, c) = (p[f[0] as usize], p[f[1] as usize], p[f[2] as usize]);
                (b - a).cross(c - a).length() / 2.0
            })
            .collect();
        let mean = areas.iter().sum::<f64>() / areas.len() as f64;
        let var = areas.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / areas.len() as f64;
        (psnr, var.sqrt() / mean)
    };
    let (dyadic, dyadic_spread) = run(0);
    let (relaxed, relaxed_spread) = run(30);
    eprintln!("dyadic {dyadic:.2} dB (area spread {dyadic_spread:.3}), relaxed {relaxed:.2} dB ({relaxed_spread:.3})");
    assert!(
        relaxed_spread < 0.8 * dyadic_spread,
        "{relaxed_spread:.3} vs {dyadic_spread:.3}"
    );
    assert!(relaxed > dyadic - 0.5, "{relaxed:.2} vs {dyadic:.2} dB");
}

/// On two coincident sheets of opposite orientation (a unit square and its reversed copy
/// a hair below it), a point keeps the sheet its hint names while the other is closer by
/// less than `SHEET_TOLERANCE` of the diagonal; with no usable hint, or sheets farther
/// apart than that, it gets the global closest point.
#[test]
fn closest_near_keeps_the_hinted_sheet_on_coincident_sheets() {
    use subwave::remesh::resample::{Projector, SHEET_TOLERANCE};
    let gap = 1e-6;
    let pos = vec![
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(0.0, 0.0, -gap),
        DVec3::new(1.0, 0.0, -gap),
        DVec3::new(1.0, 1.0, -gap),
        DVec3::new(0.0, 1.0, -gap),
    ];
    // Top sheet facing +z (triangles 0, 1), bottom sheet facing -z (triangles 2, 3).
    let tris = vec![[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]];
    let proj = Projector::new(&pos, &tris).unwrap();
    let diagonal = (1.0f64 + 1.0 + gap * gap).sqrt();
    assert!(gap < SHEET_TOLERANCE * diagonal);
    // Just below the bottom sheet: the bottom sheet is closer, the hint names the top.
    let p = DVec3::new(0.3, 0.6, -2.0 * gap);
    let (q, t) = proj.closest_near(p, &[1]);
    assert!(t < 2, "left the hinted top sheet for triangle {t}");
    assert!((q.z - 0.0).abs() < 1e-15 && proj.normals[t as usize].z > 0.0);
    // Without a hint, or hinting the bottom: the bottom sheet.
    assert!(proj.closest_near(p, &[u32::MAX]).1 >= 2);
    assert!(proj.closest_near(p, &[3]).1 >= 2);
    // Sheets farther apart than the tolerance: the closer sheet, whatever the hint.
    let wide = 1e-3;
    assert!(wide > SHEET_TOLERANCE * 2f64.sqrt() * 1.01);
    let pos: Vec<DVec3> = pos
        .iter()
        .map(|&p| {
            if p.z < 0.0 {
                DVec3::new(p.x, p.y, -wide)
            } else {
                p
            }
        })
        .collect();
    let proj = Projector::new(&pos, &tris).unwrap();
    let below = DVec3::new(0.3, 0.6, -2.0 * wide);
    assert!(proj.closest_near(below, &[1]).1 >= 2);
}

/// With default levels, a remesh that misses part of the input is redone finer: the cow's
/// 3-level remesh over 200 base faces passes its tail between two samples (Hausdorff from the
/// input 8.9% of the diagonal), the one over 400 base faces still misses (3.5%), the one over
/// 800 does not but tops out below the ceiling, so the codec codes 4 levels over 800; given
/// levels are kept, and the miss is reported.
#[test]
fn corpus_prepare_remeshes_finer_where_the_remesh_misses_the_input() {
    use subwave::codec::prepare::{prepare, Missed, PrepareOptions, CEILING_DB, MISS_FRACTION};
    let Some(input) = corpus("cow.obj") else {
        return;
    };
    let opts = PrepareOptions {
        normal: Some(false),
        fit: false,
        ..PrepareOptions::default()
    };
    let p = prepare(&input, &opts, &mut |_, _| {}).unwrap();
    let missed = |base_faces| Missed {
        base_faces,
        levels: 3,
    };
    assert_eq!(p.missed, vec![missed(200), missed(400)]);
    let base = p.hierarchy.base.num_faces();
    assert!((700..=900).contains(&base), "{base} base faces");
    // The 3-level remesh over 800 base faces keeps the tail but tops out below the ceiling
    // (73.7 dB): one level more.
    let raised = p.raised.expect("raised above the 3-level remesh");
    assert_eq!((raised.levels, raised.base_faces), (3, base));
    assert!(raised.psnr < CEILING_DB, "{}", raised.psnr);
    assert_eq!(p.hierarchy.levels(), 4);
    let psnr = subwave::distance::psnr(input.diagonal(), p.remesh_rms.unwrap());
    assert!(
        psnr > raised.psnr + 3.0,
        "{psnr} dB after {} dB",
        raised.psnr
    );
    // Given base faces are kept: one level finer instead.
    let faces = PrepareOptions {
        base_faces: Some(200),
        ..opts
    };
    let p = prepare(&input, &faces, &mut |_, _| {}).unwrap();
    assert_eq!(p.missed.first(), Some(&missed(200)));
    assert!(p.hierarchy.levels() > 3);
    let given = PrepareOptions {
        levels: Some(3),
        ..opts
    };
    let p = prepare(&input, &given, &mut |_, _| {}).unwrap();
    assert!(p.missed.is_empty() && p.raised.is_none());
    assert_eq!(p.hierarchy.levels(), 3);
    let (rms, max) = p.input_distance.expect("measured on a coarse remesh");
    assert!(max > MISS_FRACTION * input.diagonal(), "{max}");
    assert!(rms > p.remesh_rms.unwrap(), "{rms}");
}

//! Semi-regular hierarchies and triangle wavelets on the shared test corpus
//! (`../shared/data/meshes` beside the checkout; skipped if absent): split real meshes,
//! shuffle them, detect the subdivision connectivity, and run the wavelets on the result.

use std::path::PathBuf;

use subwave::hierarchy::Hierarchy;
use subwave::io::read_mesh;
use subwave::subdivision::refine::Split;
use subwave::subdivision::{subdivide, Scheme, SubdivideOptions};
use subwave::wavelet::triangle::{DetailFrame, TriangleWavelet};
use subwave::{DVec3, Mesh};

fn corpus(name: &str) -> Option<Mesh> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/meshes");
    let path = dir.join(name);
    if !path.exists() {
        eprintln!("corpus mesh {} absent: skipped", path.display());
        return None;
    }
    Some(read_mesh(&path, None).unwrap())
}

/// `m` with vertices and faces permuted and corners rotated (deterministically), and the
/// permutation (old vertex → new vertex).
fn shuffle(m: &Mesh) -> (Mesh, Vec<u32>) {
    let n = m.num_vertices();
    let mut x = 0x2545F4914F6CDD1Du64;
    let mut next = |k: usize| {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x % k as u64) as usize
    };
    let mut perm: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        perm.swap(i, next(i + 1));
    }
    let mut pos = vec![DVec3::ZERO; n];
    for (old, &new) in perm.iter().enumerate() {
        pos[new as usize] = m.positions[old];
    }
    let mut tris: Vec<[u32; 3]> = m
        .faces()
        .map(|f| {
            let r = next(3);
            [f[r], f[(r + 1) % 3], f[(r + 2) % 3]].map(|v| perm[v as usize])
        })
        .collect();
    for i in (1..tris.len()).rev() {
        tris.swap(i, next(i + 1));
    }
    (Mesh::from_triangles(pos, &tris), perm)
}

fn max_dist(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.distance(*y))
        .fold(0.0, f64::max)
}

/// Loop-subdivide a corpus mesh, shuffle, detect, and check that Loop analysis recovers the
/// corpus mesh (to 1e-12 of the diagonal) with zero details, and that every wavelet
/// reconstructs the input.
fn check(name: &str, levels: u32) {
    let Some(base) = corpus(name) else { return };
    let opts = SubdivideOptions {
        scheme: Scheme::Loop,
        levels,
        ..Default::default()
    };
    let fine = subdivide(&base, &opts).unwrap();
    let (input, perm) = shuffle(&fine);
    let (h, r) = Hierarchy::detect(&input, None).unwrap();
    assert_eq!(h.levels(), levels as usize, "{name}");
    assert_eq!(h.base.num_vertices(), base.num_vertices(), "{name}");
    assert_eq!(h.base.num_faces(), base.num_faces(), "{name}");
    let diag = base.diagonal();
    let w = TriangleWavelet::loop_pgc(&h, &opts).unwrap();
    let d = w.decompose(&h.positions).unwrap();
    // Detected base vertex i is input vertex r.vertices[i], i.e. the shuffled image of a
    // corpus vertex (the even vertices of the Loop refinement keep the corpus numbering).
    let mut old_of = vec![0u32; perm.len()];
    for (old, &new) in perm.iter().enumerate() {
        old_of[new as usize] = old as u32;
    }
    let mut err = 0.0f64;
    for (i, p) in d.base.iter().enumerate() {
        let old = old_of[r.vertices[i] as usize] as usize;
        assert!(
            old < base.num_vertices(),
            "{name}: base vertex {i} is not a corpus vertex"
        );
        err = err.max(p.distance(base.positions[old]));
    }
    println!("{name}: Loop analysis recovers the corpus mesh to {err:.2e}");
    assert!(err <= 1e-12 * diag, "{name}: {err}");
    let dmax = d
        .details
        .iter()
        .flatten()
        .map(|x| x.length())
        .fold(0.0, f64::max);
    println!("{name}: {} vertices, {levels} levels detected; Loop analysis max |detail| {dmax:.2e} (diagonal {diag:.3})", input.num_vertices());
    assert!(dmax <= 1e-12 * diag, "{name}: {dmax}");
    for frame in [DetailFrame::Global, DetailFrame::Local] {
        for w in [
            TriangleWavelet::loop_pgc(&h, &opts).unwrap(),
            TriangleWavelet::midpoint(&h, false).unwrap(),
            TriangleWavelet::midpoint(&h, true).unwrap(),
        ] {
            let w = w.with_frame(frame);
            let d = w.decompose(&h.positions).unwrap();
            let back = r.to_input(&w.reconstruct(&d).unwrap());
            let err = max_dist(&back, &input.positions);
            assert!(
                err <= 1e-12 * diag,
                "{name} {:?} {frame:?}: {err}",
                w.kind()
            );
        }
    }
}

#[test]
fn spot_closed() {
    check("spot.obj", 2);
}

#[test]
fn woody_with_boundary() {
    check("woody.obj", 2);
}

#[test]
fn cheburashka_closed() {
    check("cheburashka.obj", 1);
}

/// The bunny has holes and 1,113 unreferenced vertices (which stay isolated base vertices).
#[test]
fn bunny_holes_and_unreferenced_vertices() {
    let Some(base) = corpus("stanford-bunny.obj") else {
        return;
    };
    let h = Hierarchy::new(&base, 1, Split::Triangles, None).unwrap();
    let (input, _) = shuffle(&h.finest_mesh());
    let (d, r) = Hierarchy::detect(&input, None).unwrap();
    assert_eq!(d.levels(), 1);
    assert_eq!(d.base.num_vertices(), base.num_vertices());
    assert_eq!(r.to_input(&d.positions), input.positions);
    let w = TriangleWavelet::midpoint(&d, true).unwrap();
    let dec = w.decompose(&d.positions).unwrap();
    let err = max_dist(&w.reconstruct(&dec).unwrap(), &d.positions);
    assert!(err <= 1e-12 * base.diagonal());
}

/// Non-manifold corpus meshes are refused with the mesh error, not a panic.
#[test]
fn non_manifold_meshes_are_refused() {
    for name in ["cow.obj", "beetle.obj"] {
        let Some(m) = corpus(name) else { return };
        let e = Hierarchy::new(&m, 1, Split::Triangles, None).unwrap_err();
        assert!(e.to_string().contains("non-manifold"), "{name}: {e}");
        let e = Hierarchy::detect(&m, None).unwrap_err();
        assert!(e.to_string().contains("non-manifold"), "{name}: {e}");
    }
    // A real mesh that was never split has no subdivision connectivity.
    if let Some(m) = corpus("spot.obj") {
        let e = Hierarchy::detect(&m, None).unwrap_err();
        assert!(e.to_string().contains("coarsening step 1"), "{e}");
        println!("spot.obj: {e}");
    }
}

//! Timings of OpenSubdiv on the Stanford bunny (ignored by default: slow, and needs the shared
//! data). Run with
//! `cargo test --release -p subwave-osd --test bunny -- --ignored --nocapture`.

use std::path::Path;

use subwave::mesh::Mesh;
use subwave::subdivision::{subdivide, BoundaryMode, Scheme, SubdivideOptions};
use subwave_osd::{max_vertex_distance, refine_ordered, refine_timed, OsdOptions, OsdScheme};

const BUNNY: &str = "/work/shared/data/meshes/stanford-bunny.obj";

fn load() -> Option<Mesh> {
    let path = Path::new(BUNNY);
    if !path.exists() {
        eprintln!("{BUNNY} not found; skipping");
        return None;
    }
    Some(subwave::io::read_mesh(path, None).expect("read the bunny"))
}

fn run(mesh: &Mesh, scheme: OsdScheme, levels: u32) {
    let opts = OsdOptions {
        scheme,
        levels,
        ..OsdOptions::default()
    };
    let (r, t) = refine_timed(mesh, &opts).unwrap();
    println!(
        "{scheme:?} level {levels}: {} -> {} vertices, {} faces; topology {:.1} ms, positions {:.1} ms, \
         stencil build {:.1} ms, stencil eval {:.1} ms",
        mesh.num_vertices(),
        r.num_vertices(),
        r.num_faces(),
        t.topology_ms,
        t.positions_ms,
        t.stencil_build_ms.unwrap_or(f64::NAN),
        t.stencil_eval_ms.unwrap_or(f64::NAN),
    );
    let start = std::time::Instant::now();
    let o = refine_ordered(mesh, &opts).unwrap();
    println!(
        "  refine_ordered (refinement + permutation): {:.1} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    assert_eq!(o.num_faces(), r.num_faces());
    // subwave's own refinement of the same mesh, compared vertex by vertex.
    let s = SubdivideOptions {
        scheme: if scheme == OsdScheme::Loop {
            Scheme::Loop
        } else {
            Scheme::CatmullClark
        },
        levels,
        boundary: BoundaryMode::OpenSubdiv,
        ..SubdivideOptions::default()
    };
    let start = std::time::Instant::now();
    let ours = subdivide(mesh, &s).unwrap();
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let d = max_vertex_distance(&ours, &o);
    println!(
        "  subwave subdivide: {ms:.1} ms; max distance to OpenSubdiv {d:.3e} (diagonal {:.3})",
        mesh.diagonal()
    );
    assert_eq!(ours.face_indices, o.face_indices);
    assert!(d <= 1e-5 * mesh.diagonal());
}

#[test]
#[ignore = "slow; needs /work/shared/data/meshes/stanford-bunny.obj"]
fn bunny_timings() {
    let Some(mesh) = load() else { return };
    run(&mesh, OsdScheme::Loop, 3);
    run(&mesh, OsdScheme::CatmullClark, 3);
}

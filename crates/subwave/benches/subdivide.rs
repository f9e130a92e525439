//! Plain subdivision on the Stanford bunny (34,834 vertices, 69,451 triangles), three levels:
//! Loop and Catmull-Clark from scratch, and cached stencil re-evaluation of Loop.
//!
//! Needs the corpus file `/work/shared/data/meshes/stanford-bunny.obj` (or the path in
//! `SUBWAVE_BUNNY`); skips with a message without it.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use subwave::subdivision::{subdivide, BoundaryMode, Refinement, Scheme, SubdivideOptions};
use subwave::Mesh;

/// Large buffers in transparent huge pages (fewer first-touch page faults; `subwave::alloc`).
#[global_allocator]
static ALLOC: subwave::alloc::HugePages = subwave::alloc::HugePages;

fn bunny() -> Option<Mesh> {
    let path = std::env::var_os("SUBWAVE_BUNNY").map_or_else(
        || PathBuf::from("/work/shared/data/meshes/stanford-bunny.obj"),
        PathBuf::from,
    );
    if !path.exists() {
        eprintln!(
            "skipping the subdivision benches: {} not found",
            path.display()
        );
        return None;
    }
    let mut mesh = subwave::io::read_mesh(&path, None).expect("readable bunny");
    mesh.remove_unreferenced();
    Some(mesh)
}

fn options(scheme: Scheme) -> SubdivideOptions {
    SubdivideOptions {
        scheme,
        levels: 3,
        boundary: BoundaryMode::OpenSubdiv,
        ..Default::default()
    }
}

fn benches(c: &mut Criterion) {
    let Some(mesh) = bunny() else { return };
    for (group, scheme) in [
        ("loop_l3_bunny", Scheme::Loop),
        ("catmark_l3_bunny", Scheme::CatmullClark),
    ] {
        let mut g = c.benchmark_group(group);
        g.sample_size(10);
        g.bench_function("subdivide", |b| {
            b.iter(|| subdivide(&mesh, &options(scheme)).unwrap())
        });
        g.finish();
    }
    let refinement = Refinement::build(&mesh, &options(Scheme::Loop), true).unwrap();
    let mut g = c.benchmark_group("reevaluate_loop_l3_bunny");
    g.sample_size(10);
    g.bench_function("evaluate", |b| {
        b.iter(|| refinement.evaluate(&mesh.positions).unwrap())
    });
    g.finish();
}

criterion_group!(subdivision, benches);
criterion_main!(subdivision);

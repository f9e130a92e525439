//! Plain subdivision, subwave beside OpenSubdiv in one process: the benchmark of the plain
//! subdivision issue ("Performance"). Release build:
//!
//! ```text
//! cargo run --release -p subwave-osd --example vs_opensubdiv -- MESH [loop|catmull-clark] [LEVELS] [RUNS]
//! ```
//!
//! Both refine uniformly with OpenSubdiv's "edge only" boundaries and uniform creasing. Times
//! are medians of RUNS runs (default 5); OpenSubdiv's total is its topology (factory and
//! `RefineUniform`) plus position interpolation (`PrimvarRefiner`), subwave's total is
//! `subdivide` end to end. Re-evaluation: subwave applies its cached per-level stencil tables,
//! OpenSubdiv evaluates its factorized finest-level stencil table (`Osd::CpuEvaluator`). Peak
//! memory is the resident-set high-water mark, reset before each side. Last, the totals are
//! measured again in RUNS rounds of one OpenSubdiv refinement followed by one subwave
//! refinement, with the median of the rounds' ratios (robust to the machine's speed drifting
//! between the blocks of runs).

use std::path::PathBuf;
use std::time::Instant;

use subwave::subdivision::profile::{peak_rss_mb, profile_subdivide, reset_peak_rss};
use subwave::subdivision::{subdivide, BoundaryMode, Scheme, SubdivideOptions};
use subwave_osd::{refine_timed, OsdOptions, OsdScheme};

/// Large buffers in transparent huge pages (fewer first-touch page faults; `subwave::alloc`).
#[global_allocator]
static ALLOC: subwave::alloc::HugePages = subwave::alloc::HugePages;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first().map(PathBuf::from) else {
        eprintln!("usage: vs_opensubdiv MESH [loop|catmull-clark] [LEVELS] [RUNS]");
        std::process::exit(2);
    };
    let (scheme, osd_scheme) = match args.get(1).map_or("loop", String::as_str) {
        "loop" => (Scheme::Loop, OsdScheme::Loop),
        "catmull-clark" => (Scheme::CatmullClark, OsdScheme::CatmullClark),
        other => {
            eprintln!("unknown scheme {other}: loop or catmull-clark");
            std::process::exit(2);
        }
    };
    let levels: u32 = args.get(2).map_or(3, |s| s.parse().expect("LEVELS"));
    let runs: usize = args.get(3).map_or(5, |s| s.parse().expect("RUNS"));
    let mut mesh = match subwave::io::read_mesh(&path, None) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    };
    mesh.remove_unreferenced();

    // OpenSubdiv.
    let opts = OsdOptions {
        scheme: osd_scheme,
        levels,
        ..OsdOptions::default()
    };
    reset_peak_rss();
    let mut t = Vec::new();
    let mut faces = 0;
    // One untimed warm-up run, as `profile_subdivide` does for subwave.
    refine_timed(&mesh, &opts).expect("OpenSubdiv refines the mesh");
    for _ in 0..runs {
        let (m, timing) = refine_timed(&mesh, &opts).expect("OpenSubdiv refines the mesh");
        faces = m.num_faces();
        t.push(timing);
    }
    let osd_peak = peak_rss_mb().unwrap_or(f64::NAN);
    let osd_topology = median(t.iter().map(|x| x.topology_ms).collect());
    let osd_positions = median(t.iter().map(|x| x.positions_ms).collect());
    let osd_total = median(t.iter().map(|x| x.topology_ms + x.positions_ms).collect());
    let osd_stencil_build = median(
        t.iter()
            .map(|x| x.stencil_build_ms.unwrap_or(f64::NAN))
            .collect(),
    );
    let osd_eval = median(
        t.iter()
            .map(|x| x.stencil_eval_ms.unwrap_or(f64::NAN))
            .collect(),
    );

    // subwave.
    let ours = SubdivideOptions {
        scheme,
        levels,
        boundary: BoundaryMode::OpenSubdiv,
        ..SubdivideOptions::default()
    };
    let p = profile_subdivide(&mesh, &ours, runs).expect("subwave refines the mesh");
    assert_eq!(p.faces, faces, "both produce the same number of faces");

    println!(
        "{}: {} levels of {}, {} -> {} faces, medians of {runs} runs",
        path.display(),
        levels,
        scheme.name(),
        mesh.num_faces(),
        p.faces
    );
    println!(
        "{:<34} {:>12} {:>12} {:>8}",
        "", "subwave", "OpenSubdiv", "ratio"
    );
    let row = |label: &str, a: f64, b: f64, unit: &str| {
        println!(
            "{label:<34} {:>9.1} {unit:<2} {:>9.1} {unit:<2} {:>8.3}",
            a,
            b,
            a / b
        );
    };
    row(
        "topology",
        p.topology_ms.unwrap_or(f64::NAN),
        osd_topology,
        "ms",
    );
    row(
        "positions",
        p.positions_ms.unwrap_or(f64::NAN),
        osd_positions,
        "ms",
    );
    row("total", p.total_ms, osd_total, "ms");
    row(
        "re-evaluation vs OSD positions",
        p.reevaluate_ms.unwrap_or(f64::NAN),
        osd_positions,
        "ms",
    );
    row(
        "re-evaluation vs OSD stencil eval",
        p.reevaluate_ms.unwrap_or(f64::NAN),
        osd_eval,
        "ms",
    );
    row(
        "peak memory (subdivide)",
        p.peak_rss_mb.unwrap_or(f64::NAN),
        osd_peak,
        "MB",
    );
    row(
        "stencil tables built (once)",
        p.stencil_build_ms.unwrap_or(f64::NAN),
        osd_stencil_build,
        "ms",
    );
    println!(
        "subwave stencils: {:.1} ms to build, {:.0} MiB; peak with stencils {:.0} MiB",
        p.stencil_build_ms.unwrap_or(f64::NAN),
        p.stencil_mb,
        p.peak_rss_reevaluate_mb.unwrap_or(f64::NAN)
    );

    // The totals again, one OpenSubdiv refinement then one subwave refinement per round, so
    // that both sides see the same state of the machine (on a shared virtual machine its
    // speed drifts between the blocks of runs above: OpenSubdiv's median total has varied by
    // a quarter between invocations).
    let (mut osd_t, mut our_t, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..runs {
        let (_, timing) = refine_timed(&mesh, &opts).expect("OpenSubdiv refines the mesh");
        let a = timing.topology_ms + timing.positions_ms;
        let t0 = Instant::now();
        let fine = subdivide(&mesh, &ours).expect("subwave refines the mesh");
        let b = t0.elapsed().as_secs_f64() * 1e3;
        drop(fine);
        osd_t.push(a);
        our_t.push(b);
        ratios.push(b / a);
    }
    println!(
        "interleaved totals ({runs} rounds)      {:>9.1} ms {:>9.1} ms {:>8.3}  (median of the rounds' ratios; range {:.3}-{:.3})",
        median(our_t),
        median(osd_t),
        median(ratios.clone()),
        ratios.iter().copied().fold(f64::INFINITY, f64::min),
        ratios.iter().copied().fold(0.0, f64::max),
    );
}

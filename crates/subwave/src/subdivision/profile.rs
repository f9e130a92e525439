//! Timing and memory profile of plain subdivision: what `subwave bench subdivide` reports.
//!
//! The benchmark (plain subdivision, "Performance") asks for the topology time, the
//! position time, the total, the re-evaluation time with cached stencils (Maret §5.1.1) and the
//! peak memory, each a median of several runs (after an untimed warm-up run), without file
//! output. Topology and positions overlap in [`subdivide`] (they run in parallel), so they
//! are timed here apart:
//! - *topology*: `prepare` and, per level, the child tables ([`refine::refine_topology`]) and
//!   sharpness, the finest level's faces and tags;
//! - *positions*: per level, the child positions from the prepared topologies
//!   ([`stencil::level_apply`]);
//! - *total*: [`subdivide`] end to end (mesh in, mesh out);
//! - *re-evaluation*: [`Refinement::evaluate`] of the level-0 positions with the stencils kept.
//!
//! Peak memory is the process's resident-set high-water mark (`VmHWM` of `/proc/self/status`),
//! reset before each phase (`/proc/self/clear_refs`); `None` where Linux's `/proc` is missing.

use std::time::Instant;

use glam::DVec3;

use super::stencil::{self, LevelContext};
use super::{
    child_sharpness, finest_tags, has_interior_tags, prepare, refine, subdivide, Refinement,
};
use super::{SubdivideOptions, Topology};
use crate::mesh::Mesh;
use crate::Result;

/// Medians of `runs` runs of each phase, in milliseconds, and the sizes of the result.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SubdivideProfile {
    /// Topology of every level (tables, sharpness, finest faces and tags); `None` for schemes
    /// whose refinement does not separate the two (√3).
    pub topology_ms: Option<f64>,
    /// Positions of every level from the prepared topologies; `None` as `topology_ms`.
    pub positions_ms: Option<f64>,
    /// [`subdivide`] end to end, topology and positions overlapped.
    pub total_ms: f64,
    /// Re-evaluation of the finest positions with cached stencil tables; `None` for schemes
    /// without stencil tables (Bertram's B-splines, evaluated by lifting).
    pub reevaluate_ms: Option<f64>,
    /// Building the refinement with its stencil tables (once, not a median).
    pub stencil_build_ms: Option<f64>,
    /// Peak resident memory of [`subdivide`], MiB (`None` off Linux).
    pub peak_rss_mb: Option<f64>,
    /// Peak resident memory while the stencil tables are built and applied, MiB.
    pub peak_rss_reevaluate_mb: Option<f64>,
    /// Memory of the cached stencil tables, MiB.
    pub stencil_mb: f64,
    /// Vertices of the finest level.
    pub vertices: usize,
    /// Faces of the finest level.
    pub faces: usize,
    /// Runs per median.
    pub runs: usize,
}

/// Profiles `opts` on `mesh` with `runs` runs per phase (at least 1).
///
/// # Errors
/// As [`Refinement::build`].
pub fn profile_subdivide(
    mesh: &Mesh,
    opts: &SubdivideOptions,
    runs: usize,
) -> Result<SubdivideProfile> {
    let runs = runs.max(1);
    reset_peak_rss();
    let mut out = None;
    let total_ms = median(runs, || {
        out = None; // free the previous result before the next run
        let t = Instant::now();
        out = Some(subdivide(mesh, opts));
        t.elapsed()
    });
    let fine = out.expect("runs >= 1")?;
    let peak_subdivide = peak_rss_mb();
    let (vertices, faces) = (fine.num_vertices(), fine.num_faces());
    drop(fine);

    let separable = rules_apply(opts.scheme);
    let mut topologies = Vec::new();
    let topology_ms = separable.then(|| {
        median(runs, || {
            topologies.clear();
            let t = Instant::now();
            topologies = topology_levels(mesh, opts);
            t.elapsed()
        })
    });
    let positions_ms = if separable {
        let prepared = prepare(mesh, opts)?;
        Some(median(runs, || {
            let t = Instant::now();
            let mut p: Vec<DVec3> = mesh.positions.clone();
            for topo in &topologies {
                let ctx = LevelContext {
                    rules: prepared.rules.as_ref(),
                    creasing: opts.creasing,
                    positions: &p,
                    features: None,
                };
                p = stencil::level_apply(topo, &ctx, &p);
            }
            std::hint::black_box(&p);
            t.elapsed()
        }))
    } else {
        None
    };
    drop(topologies);

    reset_peak_rss();
    let t = Instant::now();
    let (mut stencil_build_ms, mut reevaluate_ms, mut stencil_mb) = (None, None, 0.0);
    if let Ok(r) = Refinement::build(mesh, opts, true) {
        stencil_build_ms = Some(t.elapsed().as_secs_f64() * 1e3);
        stencil_mb =
            r.stencils.iter().map(|s| s.memory_bytes()).sum::<usize>() as f64 / (1 << 20) as f64;
        reevaluate_ms = Some(median(runs, || {
            let t = Instant::now();
            std::hint::black_box(r.evaluate(&mesh.positions).expect("stencils kept"));
            t.elapsed()
        }));
    }
    let peak_rss_reevaluate_mb = peak_rss_mb();
    Ok(SubdivideProfile {
        topology_ms,
        positions_ms,
        total_ms,
        reevaluate_ms,
        stencil_build_ms,
        peak_rss_mb: peak_subdivide,
        peak_rss_reevaluate_mb,
        stencil_mb,
        vertices,
        faces,
        runs,
    })
}

/// True if the scheme refines through [`prepare`]'s rules (topology and positions apart).
fn rules_apply(scheme: super::Scheme) -> bool {
    !matches!(
        scheme,
        super::Scheme::Sqrt3 | super::Scheme::Bicubic | super::Scheme::Biquintic
    )
}

/// The topology phase: level-0 preparation, then every level's child tables and sharpness
/// (the finest level's faces and tags only). Returns the topologies of levels `0..levels`
/// (empty on error: the total phase has reported errors already).
fn topology_levels(mesh: &Mesh, opts: &SubdivideOptions) -> Vec<Topology> {
    let Ok(p) = prepare(mesh, opts) else {
        return Vec::new();
    };
    let tagged = has_interior_tags(&p.topo);
    let mut topo = p.topo;
    let mut levels = Vec::with_capacity(opts.levels as usize);
    for level in 0..opts.levels {
        if level + 1 < opts.levels {
            // The levels are only evaluated, as `subdivide` does: lean where it builds them so.
            let vertex_faces = !super::lean_levels(p.split, p.rules.as_ref());
            let (mut child, halves) =
                refine::refine_topology_with(&topo, p.split, false, vertex_faces);
            child_sharpness(&topo, &mut child, &halves, opts.creasing);
            levels.push(std::mem::replace(&mut topo, child));
        } else {
            std::hint::black_box(refine::child_faces(&topo, p.split));
            std::hint::black_box(finest_tags(&topo, opts.creasing, tagged));
            levels.push(std::mem::take(&mut topo));
        }
    }
    levels
}

/// Median of `runs` timings of `f`, in milliseconds, after one untimed warm-up call.
///
/// A process's first refinement faults in the memory that later ones reuse
/// ([`crate::alloc::HugePages`] keeps freed memory), and its second still faults part of it:
/// the bunny's third Catmull-Clark level took 640, 166, 99, 96, 106 ms in a process's first
/// five runs (2026-12-05), so a median of five cold-started runs read 106–141 ms for a
/// steady state of 87–100 ms.
fn median(runs: usize, mut f: impl FnMut() -> std::time::Duration) -> f64 {
    f();
    let mut t: Vec<f64> = (0..runs).map(|_| f().as_secs_f64() * 1e3).collect();
    t.sort_by(f64::total_cmp);
    if runs % 2 == 1 {
        t[runs / 2]
    } else {
        0.5 * (t[runs / 2 - 1] + t[runs / 2])
    }
}

/// Resets the resident-set high-water mark (Linux `clear_refs` value 5); a no-op elsewhere.
pub fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The resident-set high-water mark in MiB (Linux `VmHWM`), `None` where unavailable.
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;
    use crate::subdivision::Scheme;

    #[test]
    fn profile_reports_the_result_sizes() {
        let mesh = generate::icosphere(1);
        for scheme in [Scheme::Loop, Scheme::CatmullClark] {
            let opts = SubdivideOptions {
                scheme,
                levels: 2,
                ..Default::default()
            };
            let p = profile_subdivide(&mesh, &opts, 3).unwrap();
            let fine = subdivide(&mesh, &opts).unwrap();
            assert_eq!(
                (p.vertices, p.faces),
                (fine.num_vertices(), fine.num_faces())
            );
            assert!(p.total_ms > 0.0 && p.topology_ms > Some(0.0) && p.positions_ms > Some(0.0));
            assert!(p.reevaluate_ms.is_some());
            assert!(p.stencil_mb > 0.0);
            if cfg!(target_os = "linux") {
                assert!(p.peak_rss_mb.unwrap() > 1.0);
            }
        }
        // Errors come through: Loop on quads.
        let opts = SubdivideOptions::default();
        assert!(profile_subdivide(&generate::cube(), &opts, 1).is_err());
    }

    #[test]
    fn median_of_runs() {
        let mut k = 0u64;
        let m = median(3, || {
            k += 1;
            std::time::Duration::from_millis([100, 5, 1, 3][(k - 1) as usize])
        });
        assert_eq!((m, k), (3.0, 4), "the warm-up call is not timed");
    }
}

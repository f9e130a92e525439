//! Remeshing an arbitrary triangle or polygon mesh to subdivision connectivity.
//!
//! The wavelet transforms (Maret 2003 ch. 4, Bertram et al.) and the codec need a
//! *semi-regular* mesh: a base mesh split `L` times. [`remesh`] builds one that approximates
//! an arbitrary input and has its topology (genus, boundaries, components), following MAPS
//! (Lee, Sweldens, Schröder, Cowsar & Dobkin, SIGGRAPH 1998):
//!
//! 1. [`repair`]: triangulate, drop degenerate faces and unreferenced vertices, and (on
//!    request) cut non-manifold edges and split non-manifold vertices;
//! 2. [`simplify`]: topology-preserving QEM simplification to about `base_faces` triangles,
//!    boundary and feature edges kept as chains, each removed vertex's parameter tracked over
//!    the simplified triangles (MAPS §3);
//! 3. [`param`]: the resulting map from the base domain onto the input (MAPS §3.4);
//! 4. [`param_relax`]: the sample points of the `L` splits of the base domain, relaxed in
//!    the base domain coarse to fine so that they spread evenly over the input (MAPS §4;
//!    the dyadic points are resampled too when the relaxed ones end with more bad faces);
//!    [`resample`]: every vertex mapped onto the input through the parameterization, then
//!    a tangential relaxation with guarded re-projection for well-shaped triangles;
//!    boundary and feature base edges keep their vertices on the input's boundary curves
//!    and creases (notches finer than the samples cut);
//!    then [`fold_repair`] moves the vertices of faces still flipped against the input or
//!    degenerate into the kernels of their stars (re-embedding discs where single moves
//!    do not suffice: as a membrane, or by Tutte's embedding in a flattening of the input
//!    under them, `flatten`; last, single moves searched over points of the input around
//!    each star), positions only; where folds remain, [`ancestor_flatten`] re-subdivides
//!    their nearest ancestor triangles that can hold them (midpoint subdivision, projected
//!    or flat) when that leaves fewer bad faces;
//! 5. [`shrinkwrap`]: the fallback (Kobbelt et al. 1999, as Bertram §5.3) for genus-0
//!    inputs when the parameterization fails;
//! 6. [`quality`]: angles, flipped and degenerate faces.
//!
//! The result's vertex order is the ordering contract of [`crate::subdivision::refine`]
//! (base vertices, then one vertex per edge per level in edge order; children `4k..4k+3`,
//! Maret eq. 5.7), so [`crate::hierarchy::Hierarchy::detect`] accepts it and the wavelet
//! transforms take it directly; [`Remeshed::hierarchy`] is that hierarchy.

pub mod ancestor_flatten;
pub mod default_base;
mod flatten;
pub mod fold_repair;
pub mod normal;
pub mod normal_fit;
pub mod param;
pub mod param_relax;
pub mod quality;
pub mod repair;
pub mod resample;
pub mod shrinkwrap;
pub mod simplify;
pub mod stitch;
mod untangle_energy;

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::hierarchy::Hierarchy;
use crate::mesh::Mesh;
use crate::subdivision::refine::Split;
use crate::subdivision::sharp_edges_by_angle;
use crate::topology::Topology;
use crate::{Error, Result};

pub use quality::Quality;
pub use repair::RepairReport;

/// Which remeshing method to run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MethodChoice {
    /// MAPS, falling back to shrink-wrapping for genus-0 components when the
    /// parameterization misses.
    #[default]
    Auto,
    /// MAPS only.
    Maps,
    /// Shrink-wrapping only.
    ShrinkWrap,
}

/// The method that produced a remesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Parameterization by simplification and resampling (Lee et al. 1998).
    Maps,
    /// Shrink-wrapping (Kobbelt et al. 1999).
    ShrinkWrap,
}

impl Method {
    /// A short name (`maps`, `shrink-wrap`).
    pub fn name(self) -> &'static str {
        match self {
            Method::Maps => "maps",
            Method::ShrinkWrap => "shrink-wrap",
        }
    }
}

/// Options of [`remesh`].
#[derive(Clone, Debug, PartialEq)]
pub struct RemeshOptions {
    /// Number of subdivision levels `L` over the base mesh.
    pub levels: u32,
    /// Target number of base triangles (the simplification stops at about this many, more
    /// where topology, boundaries or features forbid further collapses).
    pub base_faces: usize,
    /// Build a quad hierarchy (each base triangle into three quads, then 1-to-4 quad splits;
    /// for Bertram et al.'s B-spline wavelets) instead of 1-to-4 triangle splits.
    pub quads: bool,
    /// Edges with a dihedral angle above this many degrees are features: kept on base edges so
    /// creases stay sharp, and boundary or crease vertices where the curve turns by more than
    /// this angle are kept as base vertices. `None`: no features (boundaries are always kept
    /// as boundaries).
    pub sharp_angle: Option<f64>,
    /// Cut non-manifold edges and split non-manifold vertices instead of failing.
    pub repair: bool,
    /// Relaxation iterations on the finest level.
    pub relax_iterations: u32,
    /// Steps of the coarse-to-fine relaxation of the resampling parameters
    /// ([`param_relax`]) on each level from the third on (fewer on the finest and on large
    /// levels, [`param_relax::schedule`]); 0 keeps the dyadic parameters. Triangle
    /// hierarchies only.
    pub param_relax_iterations: u32,
    /// Which method to run.
    pub method: MethodChoice,
}

impl Default for RemeshOptions {
    fn default() -> Self {
        RemeshOptions {
            levels: 3,
            base_faces: 200,
            quads: false,
            sharp_angle: None,
            repair: false,
            relax_iterations: 6,
            param_relax_iterations: 30,
            method: MethodChoice::Auto,
        }
    }
}

/// Wall-clock times of the stages, in milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Timings {
    /// Triangulation, cleaning, repair.
    pub prepare_ms: f64,
    /// QEM simplification with parameter tracking.
    pub simplify_ms: f64,
    /// Charts and point-location grids.
    pub parameterize_ms: f64,
    /// Coarse-to-fine relaxation of the sampling in the base domain ([`param_relax`]).
    pub param_relax_ms: f64,
    /// Splitting and mapping (or shrink-wrapping), of both samplings when both ran.
    pub resample_ms: f64,
    /// Relaxation, untangling and fold repair (of both samplings when both ran).
    pub relax_ms: f64,
    /// Everything, including the quality measurement.
    pub total_ms: f64,
}

/// A semi-regular remesh.
#[derive(Clone, Debug)]
pub struct Remeshed {
    /// The finest level, vertices and faces in contract order (equal to
    /// `hierarchy.finest_mesh()`).
    pub mesh: Mesh,
    /// The base mesh (triangles; with [`RemeshOptions::quads`], the quads made of them), with
    /// the positions its vertices have in [`Remeshed::mesh`].
    pub base: Mesh,
    /// The hierarchy over [`Remeshed::base`].
    pub hierarchy: Hierarchy,
    /// The method that ran.
    pub method: Method,
    /// Face quality of the finest level.
    pub quality: Quality,
    /// What the input preparation changed.
    pub repair: RepairReport,
    /// Base-domain points farther than 0.02 (barycentric) from every input triangle's image,
    /// in their base triangle's frame and in the frames around it, which took the closest
    /// input point of their point on the base mesh (MAPS only).
    pub param_misses: usize,
    /// Warnings for the user (degenerate faces removed, fallbacks taken).
    pub warnings: Vec<String>,
    /// Stage times.
    pub timings: Timings,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Remeshes `mesh` to subdivision connectivity (see the module documentation).
///
/// # Errors
/// As [`remesh_with_progress`].
pub fn remesh(mesh: &Mesh, opts: &RemeshOptions) -> Result<Remeshed> {
    remesh_with_progress(mesh, opts, &mut |_, _| {})
}

/// [`remesh`] reporting progress: `progress(stage, fraction)` is called with the stage name
/// (`prepare`, `simplify`, `parameterize`, `resample`, `relax`, `quality`) and the fraction of
/// that stage done, from the calling thread.
///
/// # Errors
/// [`Error::Mesh`] for bad indices, or (without [`RemeshOptions::repair`]) a non-manifold or
/// inconsistently oriented input ([`crate::MeshError::NonManifold`] names the edges and
/// vertices); [`Error::InvalidArgument`] for an input without faces, `base_faces == 0`, or a
/// result above [`crate::subdivision::MAX_FACES`] faces.
pub fn remesh_with_progress(
    mesh: &Mesh,
    opts: &RemeshOptions,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Remeshed> {
    let t_all = Instant::now();
    let mut timings = Timings::default();
    if opts.base_faces == 0 {
        return Err(Error::InvalidArgument(
            "base faces must be at least 1".to_string(),
        ));
    }
    let mut warnings = Vec::new();
    // 1. Prepare.
    let t = Instant::now();
    progress("prepare", 0.0);
    let (pos, tris, repair) = repair::prepare(mesh, opts.repair)?;
    if tris.is_empty() {
        return Err(Error::InvalidArgument(
            "the mesh has no (non-degenerate) faces to remesh".to_string(),
        ));
    }
    warnings.extend(repair.warnings());
    let prepared = Mesh::from_triangles(pos.clone(), &tris);
    let features: simplify::PairSet = match opts.sharp_angle {
        Some(deg) => {
            let topo = Topology::build(&prepared);
            sharp_edges_by_angle(&prepared, &topo, deg)
                .into_iter()
                .map(|e| {
                    let [a, b] = topo.edge_vertices[e as usize];
                    (a.min(b), a.max(b))
                })
                .collect()
        }
        None => simplify::PairSet::default(),
    };
    timings.prepare_ms = ms(t);
    progress("prepare", 1.0);

    // 2. Simplify with parameter tracking.
    let t = Instant::now();
    // The (serial) simplification and the input's BVH side by side (the progress callback
    // is not `Send`: the simplification stays on this thread).
    let (mut s, proj) = std::thread::scope(|scope| {
        let bvh = scope.spawn(|| resample::Projector::new(&pos, &tris));
        let s = simplify::simplify(
            &pos,
            &tris,
            &features,
            opts.base_faces,
            opts.sharp_angle,
            &mut |f| progress("simplify", f),
        );
        let proj = bvh.join().unwrap_or_else(|e| std::panic::resume_unwind(e));
        (s, proj)
    });
    let proj = proj?;
    let base_tri = Mesh::from_triangles(s.positions.clone(), &s.triangles);
    timings.simplify_ms = ms(t);

    // 3. Parameterization.
    let t = Instant::now();
    progress("parameterize", 0.0);
    // Input vertices whose parameter is a base vertex or on a boundary or feature chain.
    let param_fixed: Vec<bool> = s
        .params
        .iter()
        .map(|p| p.is_pinned(s.triangles[p.face as usize], &s.chain_edges))
        .collect();
    let (_, spread) =
        param::untangle_spreading_fans(&base_tri, &tris, &mut s.params, &param_fixed, 4);
    let map = param::ParamMap::new(&base_tri, &pos, &tris, &s.params, &spread);
    timings.parameterize_ms = ms(t);
    progress("parameterize", 1.0);

    // 4. Hierarchy and resampling.
    let t_h = Instant::now();
    let (split, base) = if opts.quads {
        let h1 = Hierarchy::new(&base_tri, 1, Split::Polygons, None)?;
        (Split::Polygons, h1.finest_mesh())
    } else {
        // Feature chains become infinitely sharp creases of the base mesh, so that the
        // subdivision rules and wavelets of the hierarchy keep them sharp (boundary chains
        // are boundaries already).
        let mut b = base_tri.clone();
        let topo0 = Topology::build(&b);
        let mut chains: Vec<(u32, u32)> = s.chain_edges.iter().copied().collect();
        chains.sort_unstable();
        for (x, y) in chains {
            if topo0
                .find_edge(x, y)
                .is_some_and(|e| !topo0.is_boundary_edge(e as usize))
            {
                b.edge_tags.push(crate::mesh::EdgeTag {
                    vertices: [x, y],
                    sharpness: crate::mesh::SHARPNESS_INFINITE,
                });
            }
        }
        (Split::Triangles, b)
    };
    let mut h = Hierarchy::new(&base, opts.levels, split, None)?;
    // Off-surface tolerance of the final repair: coarser levels stand farther off the input
    // (chordal error, about four times per level).
    let off_surface =
        OFF_SURFACE * prepared.diagonal() * 4f64.powi((5 - opts.levels as i32).max(0));
    // The resampling, relaxation and repair of one set of parameters (dyadic, or relaxed
    // in the base domain).
    let sample = |params: Vec<simplify::Param>, progress: &mut dyn FnMut(&str, f64)| -> Sampled {
        let t = Instant::now();
        let mut run_warnings = Vec::new();
        let located: Vec<param::Located> = params.par_iter().map(|p| map.locate(p)).collect();
        // Points outside every image registered in their base triangle: the nearest image in
        // the frames of the triangles around it.
        let around: Vec<Option<param::Located>> = located
            .par_iter()
            .zip(&params)
            .map(|(l, p)| {
                if l.inside >= -OUTSIDE {
                    None
                } else {
                    map.locate_around(p)
                        .filter(|a| a.inside > l.inside && a.inside >= -NEAR_IMAGE)
                }
            })
            .collect();
        let param_misses = located
            .iter()
            .zip(&around)
            .filter(|(l, a)| l.inside < -NEAR_IMAGE && a.is_none())
            .count();
        if tracing::enabled!(tracing::Level::DEBUG) {
            let diag = prepared.diagonal();
            let errs: Vec<f64> = s
                .params
                .par_iter()
                .zip(&pos)
                .map(|(p, x)| {
                    let l = map.locate(p);
                    map.point(&l)
                        .map_or(f64::INFINITY, |q| q.distance(*x) / diag)
                })
                .collect();
            tracing::debug!(
                max = errs.iter().copied().fold(0.0, f64::max),
                mean = errs.iter().sum::<f64>() / errs.len() as f64,
                over_1pc = errs.iter().filter(|&&e| e > 0.01).count(),
                over_01pc = errs.iter().filter(|&&e| e > 0.001).count(),
                "map at the input vertices' own parameters (relative to the diagonal)"
            );
        }
        tracing::debug!(
            unregistered = map.unregistered,
            param_misses,
            slightly_outside = located.iter().filter(|l| l.inside < -1e-6).count(),
            base_vertices = s.positions.len(),
            chain_edges = s.chain_edges.len(),
            "parameterization"
        );
        let (mut fine, mut hints) = initial_positions(&map, &located, &around, &params, &s, &proj);
        // Base vertices are input vertices; vertices on boundary and feature base edges follow
        // the input's chain between them (1D parameterization along the chain).
        let chains = chain_polylines(&s, &pos, opts.levels);
        fine.par_iter_mut().zip(&params).for_each(|(p, prm)| {
            let t = s.triangles[prm.face as usize];
            if let Some(k) = prm.bary.iter().position(|&x| x == 1.0) {
                *p = s.positions[t[k] as usize];
                return;
            }
            if let Some((e, along)) = prm.on_edge(t, |e| chains.contains_key(&e)) {
                *p = polyline_at(&chains[&e], along);
            }
        });
        progress("resample", 1.0);
        // Fixed vertices: base vertices and vertices on chain base edges.
        let fixed: Vec<bool> = params
            .iter()
            .map(|p| p.is_pinned(s.triangles[p.face as usize], &s.chain_edges))
            .collect();
        let genus0 = Topology::build(&prepared).genus() == Some(0);
        let mut method = Method::Maps;
        let miss_limit = (fine.len() / 20).max(8);
        let use_shrinkwrap = match opts.method {
            MethodChoice::ShrinkWrap => true,
            MethodChoice::Maps => false,
            MethodChoice::Auto => param_misses > miss_limit && genus0,
        };
        if opts.method == MethodChoice::Auto && param_misses > miss_limit && !genus0 {
            run_warnings.push(format!(
                "{param_misses} resampled points fell outside the parameterization (kept their nearest image); shrink-wrapping needs genus 0"
            ));
        }
        let resample_ms = ms(t);
        let t = Instant::now();
        // Faces flipped against the input (quality measure), as the final repair counted them.
        let flipped_after;
        let degenerate_after;
        if use_shrinkwrap {
            if opts.method == MethodChoice::Auto {
                run_warnings.push(format!(
                    "parameterization missed {param_misses} points: fell back to shrink-wrapping"
                ));
            }
            method = Method::ShrinkWrap;
            let nb = h.base.positions.len();
            hints.fill(u32::MAX);
            fine = shrinkwrap::shrinkwrap(
                &h,
                &fixed[..nb],
                &proj,
                opts.relax_iterations.max(2),
                &mut |f| progress("resample", f),
            );
            // The same final repair as after MAPS (the base vertices stay).
            hints = fine.par_iter().map(|&p| proj.closest(p).1).collect();
            let mut base_fixed = vec![false; fine.len()];
            base_fixed[..nb].fill(true);
            let topo = &h.topologies[opts.levels as usize];
            let fr = fold_repair::repair_folds(
                &mut fine,
                &mut hints,
                topo,
                &base_fixed,
                &[],
                &proj,
                12,
                None,
                off_surface,
            );
            tracing::debug!(?fr, "fold repair after shrink-wrapping");
            (flipped_after, degenerate_after) = flatten_left(
                &mut fine,
                &mut hints,
                &h,
                &proj,
                (fr.flipped_after, fr.degenerate_after),
                off_surface,
            );
        } else {
            progress("relax", 0.0);
            let topo = &h.topologies[opts.levels as usize];
            resample::relax(
                &mut fine,
                &mut hints,
                topo,
                &fixed,
                &proj,
                opts.relax_iterations,
                0.5,
            );
            // Untangling may also slide base vertices that are not on a boundary or feature
            // chain (they are not corners of any curve) tangentially on the input.
            let mut on_chain = vec![false; s.positions.len()];
            for &(a, b) in &s.chain_edges {
                on_chain[a as usize] = true;
                on_chain[b as usize] = true;
            }
            let pinned: Vec<bool> = params
                .iter()
                .zip(&fixed)
                .map(|(p, &f)| {
                    f && match p.bary.iter().position(|&x| x == 1.0) {
                        Some(k) => on_chain[s.triangles[p.face as usize][k] as usize],
                        None => true,
                    }
                })
                .collect();
            let relaxed_ms = ms(t);
            resample::untangle(&mut fine, &mut hints, topo, &pinned, &proj, 6);
            let untangled_ms = ms(t);
            // Final guarded projection of every free vertex onto its closest input point (a
            // relaxation step of length zero), then untangling again.
            resample::relax(&mut fine, &mut hints, topo, &pinned, &proj, 1, 0.0);
            let suspects = resample::untangle_bad(&mut fine, &mut hints, topo, &pinned, &proj, 12);
            // Last, the faces still flipped or degenerate: vertices into their stars' kernels,
            // discs re-embedded.
            // Vertices on the remesh boundary below the base level may slide along the input's
            // boundary where a fold next to a hole needs it.
            let nb = h.base.positions.len();
            let slides: Vec<bool> = (0..fine.len())
                .map(|v| {
                    v >= nb
                        && pinned[v]
                        && topo
                            .vertex_edges(v)
                            .iter()
                            .any(|&e| topo.is_boundary_edge(e as usize))
                })
                .collect();
            let fr = fold_repair::repair_folds(
                &mut fine,
                &mut hints,
                topo,
                &pinned,
                &slides,
                &proj,
                12,
                Some(&suspects),
                off_surface,
            );
            tracing::debug!(suspects = suspects.len(), ?fr, "fold repair");
            (flipped_after, degenerate_after) = flatten_left(
                &mut fine,
                &mut hints,
                &h,
                &proj,
                (fr.flipped_after, fr.degenerate_after),
                off_surface,
            );
            let left = flipped_after;
            tracing::debug!(
                relaxed_ms,
                untangled_ms,
                total_ms = ms(t),
                "relaxation stage times (cumulative)"
            );
            if tracing::enabled!(tracing::Level::DEBUG) {
                let flips = resample::flipped_faces(topo, &fine, &hints, &proj);
                let nbv = h.base.positions.len() as u32;
                let mut at_base = 0;
                let mut at_fixed = 0;
                let mut at_miss = 0;
                for (f, &fl) in flips.iter().enumerate() {
                    if !fl {
                        continue;
                    }
                    let fv = topo.face_vertices(f);
                    if fv.iter().any(|&v| v < nbv) {
                        at_base += 1;
                    }
                    if fv.iter().any(|&v| fixed[v as usize]) {
                        at_fixed += 1;
                    }
                    if fv.iter().any(|&v| located[v as usize].inside < -1e-6) {
                        at_miss += 1;
                    }
                }
                tracing::debug!(left, at_base, at_fixed, at_miss, "flipped faces");
            }
            if left > 0 {
                run_warnings.push(format!("{left} {STILL_FLIPPED}"));
            }
            progress("relax", 1.0);
        }
        Sampled {
            fine,
            hints,
            method,
            flipped: flipped_after,
            degenerate: degenerate_after,
            param_misses,
            warnings: run_warnings,
            resample_ms,
            relax_ms: ms(t),
        }
    };
    let hierarchy_ms = ms(t_h);
    let levels = opts.levels as usize;
    let n = if opts.quads {
        0
    } else {
        opts.param_relax_iterations
    };
    // The relaxed sampling first; where it leaves flipped or degenerate faces, the dyadic
    // one too, kept if it has none or [`DYADIC_MARGIN`] fewer (the repairs after either are
    // not monotone: on the corpus at 5 levels, each has fewer on some meshes).
    let mut run = if n > 0 {
        let t = Instant::now();
        progress("sampling", 0.0);
        let relaxed = param_relax::relaxed_params(&h, levels, &map, &s.chain_edges, |l| {
            param_relax::schedule(n, l, levels, h.topologies[l].num_faces())
        });
        timings.param_relax_ms = ms(t);
        progress("sampling", 1.0);
        sample(relaxed, progress)
    } else {
        sample(resample::level_params(&h, levels, opts.quads), progress)
    };
    if n > 0 && run.flipped + run.degenerate > 0 {
        // (The progress bar stays where the first run left it.)
        let dyadic = sample(
            resample::level_params(&h, levels, opts.quads),
            &mut |_, _| {},
        );
        tracing::debug!(
            relaxed = run.flipped + run.degenerate,
            dyadic = dyadic.flipped + dyadic.degenerate,
            "bad faces of the relaxed and dyadic samplings"
        );
        let resample_ms = run.resample_ms + dyadic.resample_ms;
        let relax_ms = run.relax_ms + dyadic.relax_ms;
        let (bad_dyadic, bad_relaxed) = (
            dyadic.flipped + dyadic.degenerate,
            run.flipped + run.degenerate,
        );
        let mut other = dyadic;
        if bad_dyadic == 0 || bad_dyadic + DYADIC_MARGIN <= bad_relaxed {
            std::mem::swap(&mut run, &mut other);
        }
        // Where both fold, in different places: the kept one's folds patched with the other's
        // subtrees.
        if run.flipped + run.degenerate > 0
            && run.method == Method::Maps
            && other.method == Method::Maps
            && h.split == Split::Triangles
        {
            let r = ancestor_flatten::patch_folds(
                &mut run.fine,
                &mut run.hints,
                &h.topologies,
                &proj,
                2,
                off_surface,
                (&other.fine, &other.hints),
            );
            tracing::debug!(?r, "folds patched from the other sampling");
            if r.flipped_after + r.degenerate_after < run.flipped + run.degenerate {
                (run.flipped, run.degenerate) = (r.flipped_after, r.degenerate_after);
                run.warnings.retain(|w| !w.ends_with(STILL_FLIPPED));
                if run.flipped > 0 {
                    run.warnings
                        .push(format!("{} {STILL_FLIPPED}", run.flipped));
                }
            }
        }
        run.resample_ms = resample_ms;
        run.relax_ms = relax_ms;
    }
    timings.resample_ms = hierarchy_ms + run.resample_ms;
    timings.relax_ms = run.relax_ms;
    warnings.append(&mut run.warnings);
    let Sampled {
        fine,
        method,
        flipped: flipped_after,
        param_misses,
        ..
    } = run;
    let nb = h.base.positions.len();
    h.base.positions.copy_from_slice(&fine[..nb]);
    h.positions = fine;
    let out = h.finest_mesh();
    let base = h.base.clone();
    progress("quality", 0.0);
    let quality = quality::measure_with_flipped(&out, flipped_after);
    progress("quality", 1.0);
    timings.total_ms = ms(t_all);
    Ok(Remeshed {
        mesh: out,
        base,
        hierarchy: h,
        method,
        quality,
        repair,
        param_misses,
        warnings,
        timings,
    })
}

/// Faces of the finest level whose centroid is farther from the input than this fraction of
/// its bounding-box diagonal (at 5 levels and more; four times as much per level fewer) are
/// repaired as folds are ([`fold_repair::repair_folds`]). Cow at 2 levels with 0.3%
/// unscaled: 47.6 → 37.4 dB, the chordal error of coarse faces taken for folds.
/// Where images of the parameterization overlap, a patch can be stretched across the input
/// without a flipped or thin face: beetle at 5 levels had 86% of its squared distance in
/// two base triangles so, and whether a neighbouring fold's re-embedding happened to cover
/// them decided between 63 and 78 dB (the gap points located in neighbouring frames
/// removed that fold). 0.3%: beetle 63.0 → 77.0 dB, bunny 77.4 → 79.6 dB, cheburashka
/// 75.3 → 79.5 dB; 0.5% misses most of beetle's patch (70.0 dB), 0.2% is no better there (76.7 dB, 502 flipped).
const OFF_SURFACE: f64 = 0.003;

/// The flipped and degenerate faces `left` by the fold repair, re-subdivided from their
/// nearest unfolded ancestors ([`ancestor_flatten`], triangle hierarchies only); the counts
/// after.
fn flatten_left(
    fine: &mut [DVec3],
    hints: &mut [u32],
    h: &Hierarchy,
    proj: &resample::Projector,
    left: (usize, usize),
    off_surface: f64,
) -> (usize, usize) {
    if left.0 + left.1 == 0 || h.split != Split::Triangles {
        return left;
    }
    let r = ancestor_flatten::flatten_folds(fine, hints, &h.topologies, proj, 2, off_surface);
    tracing::debug!(?r, "ancestor flattening");
    (r.flipped_after, r.degenerate_after)
}

/// How many fewer flipped and degenerate faces the dyadic sampling must leave to be kept
/// instead of the relaxed one (unless it leaves none), which is closer to the input (bunny
/// at 5 levels 81.0 dB against 79.6, at 6 levels 87.9 against 85.4): with the last-resort
/// re-subdivision ([`ancestor_flatten`]) the bunny at 6 levels ends with 3 against 2, and
/// keeping the dyadic one for that face cost 2.5 dB.
const DYADIC_MARGIN: usize = 3;

/// The warning on the faces a remesh leaves flipped, after their number.
const STILL_FLIPPED: &str = "face(s) still flipped after untangling and repair";

/// One resampling of the finest level ([`remesh_with_progress`]).
struct Sampled {
    fine: Vec<DVec3>,
    /// An input triangle near each vertex of `fine`.
    hints: Vec<u32>,
    method: Method,
    flipped: usize,
    degenerate: usize,
    param_misses: usize,
    warnings: Vec<String>,
    resample_ms: f64,
    relax_ms: f64,
}

/// Points whose coordinates in the nearest image are below `-OUTSIDE` are outside it.
const OUTSIDE: f64 = 1e-6;

/// Points within this (barycentric) distance of an image are mapped through it, clamped.
const NEAR_IMAGE: f64 = 0.02;

/// Each resampled point's position on the input and an input triangle near it (the hint of
/// later closest-point queries): the image of its parameter through the nearest image, in
/// its base triangle's frame or in the frames around it (`around`,
/// [`param::ParamMap::locate_around`]), clamped, if that is within [`NEAR_IMAGE`]; else (outside
/// every image) the closest input point of its point on the base mesh.
fn initial_positions(
    map: &param::ParamMap,
    located: &[param::Located],
    around: &[Option<param::Located>],
    params: &[simplify::Param],
    s: &simplify::Simplified,
    proj: &resample::Projector,
) -> (Vec<DVec3>, Vec<u32>) {
    located
        .par_iter()
        .zip(around)
        .zip(params)
        .map(|((l, a), p)| {
            let l = match a {
                Some(a) if a.inside > l.inside => a,
                _ => l,
            };
            match map.point(l) {
                Some(q) if l.inside >= -NEAR_IMAGE => (q, l.tri),
                _ => {
                    let t = s.triangles[p.face as usize];
                    let b: DVec3 = (0..3).map(|k| s.positions[t[k] as usize] * p.bary[k]).sum();
                    proj.closest_near(b, &[l.tri])
                }
            }
        })
        .unzip()
}

/// For each chain base edge (sorted vertex pair), the input chain vertices parameterized on
/// it as `(parameter from the smaller to the larger base vertex, position)`, sorted, with the
/// two base vertices at 0 and 1.
fn chain_polylines(
    s: &simplify::Simplified,
    pos: &[DVec3],
    levels: u32,
) -> std::collections::HashMap<(u32, u32), Vec<(f64, DVec3)>> {
    let mut out: std::collections::HashMap<(u32, u32), Vec<(f64, DVec3)>> = s
        .chain_edges
        .iter()
        .map(|&(a, b)| {
            (
                (a, b),
                vec![
                    (0.0, s.positions[a as usize]),
                    (1.0, s.positions[b as usize]),
                ],
            )
        })
        .collect();
    for (v, p) in s.params.iter().enumerate() {
        let t = s.triangles[p.face as usize];
        if let Some((e, along)) = p.on_edge(t, |e| out.contains_key(&e)) {
            if let Some(line) = out.get_mut(&e) {
                line.push((along, pos[v]));
            }
        }
    }
    // Sorted by their parameter. The parameter is the one the simplification tracked, as for
    // the points beside the chain: re-parameterizing by arc length (evenly spread boundary
    // vertices) sheared the first rows of faces along boundaries and creases against the
    // interior, which follows the tracked parameterization, and folded them.
    for line in out.values_mut() {
        line.sort_by(|x, y| x.0.total_cmp(&y.0));
        drop_spikes(line, levels);
    }
    out
}

/// Removes the spikes of a chain polyline that are finer than the resampling: interior
/// points where the curve turns back (by more than 120°) with both segments shorter than
/// four spacings of the `2^levels` samples along the chain. The resampled chain through such
/// a point has an edge pointing backwards, and the face on it is flipped whatever its third
/// corner (bunny at 5 levels: 2 of its 3 flipped faces, on hole rims whose input has
/// 0.3 mm sliver notches). Cutting the spike keeps the samples on its base, within the
/// notch's width of the input.
fn drop_spikes(line: &mut Vec<(f64, DVec3)>, levels: u32) {
    let length: f64 = line.windows(2).map(|w| w[0].1.distance(w[1].1)).sum();
    let spacing = length / f64::from(1u32 << levels.min(30));
    let mut i = 1;
    while i + 1 < line.len() {
        let (a, b) = (line[i].1 - line[i - 1].1, line[i + 1].1 - line[i].1);
        let (la, lb) = (a.length(), b.length());
        if la < 4.0 * spacing && lb < 4.0 * spacing && a.dot(b) < -0.5 * la * lb {
            line.remove(i);
            i = i.saturating_sub(1).max(1);
        } else {
            i += 1;
        }
    }
}

/// The point at parameter `s` of a sorted polyline.
fn polyline_at(line: &[(f64, DVec3)], s: f64) -> DVec3 {
    let i = line.partition_point(|x| x.0 <= s);
    if i == 0 {
        return line[0].1;
    }
    if i >= line.len() {
        return line[line.len() - 1].1;
    }
    let (s0, p0) = line[i - 1];
    let (s1, p1) = line[i];
    if s1 - s0 <= 0.0 {
        p0
    } else {
        p0.lerp(p1, (s - s0) / (s1 - s0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(points: &[[f64; 2]]) -> Vec<(f64, DVec3)> {
        let n = (points.len() - 1) as f64;
        points
            .iter()
            .enumerate()
            .map(|(i, p)| (i as f64 / n, DVec3::new(p[0], p[1], 0.0)))
            .collect()
    }

    #[test]
    fn spikes_finer_than_the_sampling_are_cut() {
        // A straight chain of length 1 with a notch 0.02 deep (a turn back of ~160°).
        let mut l = line(&[
            [0.0, 0.0],
            [0.5, 0.0],
            [0.49, 0.02],
            [0.51, 0.0],
            [1.0, 0.0],
        ]);
        drop_spikes(&mut l, 5);
        let xs: Vec<f64> = l.iter().map(|p| p.1.x).collect();
        assert_eq!(xs, vec![0.0, 0.5, 0.51, 1.0], "{l:?}");
        // The same notch is kept when the samples are finer than it.
        let mut l = line(&[
            [0.0, 0.0],
            [0.5, 0.0],
            [0.49, 0.02],
            [0.51, 0.0],
            [1.0, 0.0],
        ]);
        drop_spikes(&mut l, 9);
        assert_eq!(l.len(), 5);
        // A hairpin of long segments is a shape, not a spike.
        let mut l = line(&[[0.0, 0.0], [1.0, 0.0], [0.0, 0.1]]);
        drop_spikes(&mut l, 3);
        assert_eq!(l.len(), 3);
    }
}

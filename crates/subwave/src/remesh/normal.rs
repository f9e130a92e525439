//! Normal remeshing: re-sampling a semi-regular remesh so that its unlifted butterfly details
//! are (mostly) scalars along the predicted normal.
//!
//! Guskov, Vidimče, Sweldens & Schröder, "Normal Meshes" (SIGGRAPH 2000), §3: every vertex
//! added by a refinement step is found by a *piercing* — the line through the vertex's
//! predicted position (the interpolating subdivision of the coarser level), along the
//! predicted surface's normal, intersected with the input surface. The detail that the
//! wavelet transform then finds is the signed distance along that line: one scalar instead of
//! a 3-vector. Khodakovsky & Guskov ("Compression of Normal Meshes", 2002) code such meshes
//! with the unlifted butterfly wavelet in local frames and find them markedly better than
//! PGC's MAPS remeshes (Maret 2003 §4.4.3 describes the same local frames): the two tangential
//! components of a local-frame detail (Maret Fig. 4.8) are exactly zero and cost SPIHT nothing.
//!
//! # The method here
//! Starting from the MAPS remesh of [`super::remesh`] (its base vertices and its boundary and
//! feature curves), level by level, coarse to fine, each odd vertex (one per parent edge,
//! ordering contract of [`crate::subdivision::refine`]):
//! 1. is predicted with the modified butterfly stencils of the hierarchy (the
//!    [`TriangleWavelet`] that the codec uses, unlifted) from the already final coarser level;
//! 2. gets the normal of the codec's local frame ([`odd_vertex_frames`]) on that predicted
//!    surface, so the piercing direction is the very axis of the coder's first component;
//! 3. is moved to the nearest intersection of that line with the input, at most
//!    [`NormalOptions::reach`] parent-edge lengths away in either direction, provided the hit
//!    input triangle faces the same way as the predicted normal (which refuses the far sheet
//!    of a thin part); otherwise (Guskov et al.'s *non-normal* vertices, §3) to the closest
//!    input point of the prediction under the same conditions, whose detail is along the
//!    input's normal there; failing both, it keeps its MAPS position.
//!
//! Vertices on boundary and feature (crease) edges keep their MAPS positions: they lie on the
//! input's curves, which a normal line does not follow. Unlike Guskov et al. the piercing is
//! not restricted by the parameterization, so on strongly curved, coarsely sampled regions a
//! level can fold; [`normal_resample`] leaves the check to [`super::quality`].
//!
//! The piercings of a coarsely sampled, strongly curved region can cross and fold faces that
//! the MAPS remesh did not have (bunny at 5 levels: 68 folded and 2 degenerate faces of
//! 204,800, rocker-arm at 4 levels 37). The re-sampling entry points of the codec and of
//! `subwave remesh --normal` ([`resample_remesh`]) repair them in place with the remesher's
//! final repair ([`super::fold_repair`]): bunny 70 + 2 → 11, rocker-arm 37 → 0, at the same
//! distance to the input (bunny 85.74 → 85.79 dB, the coded stream 0.7% larger);
//! [`resample_remesh`] then puts the MAPS positions back around the faces left.
//!
//! Every re-sampled vertex lies on the input, so each triangle is a chord of it and the
//! remesh's error is one-sided; [`normal_resample_fitted_on`] then offsets the re-sampled
//! vertices along their piercing lines to the least-squares fit of the input
//! ([`super::normal_fit`]), which keeps their details along the same axes.

use glam::DVec3;
use rayon::prelude::*;

use super::resample::Projector;
use crate::hierarchy::Hierarchy;
use crate::subdivision::refine::Split;
use crate::subdivision::{Scheme, SubdivideOptions};
use crate::topology::Topology;
use crate::wavelet::frames::odd_vertex_frames;
use crate::wavelet::triangle::TriangleWavelet;
use crate::{Error, Result};

/// Options of [`normal_resample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalOptions {
    /// How far from its prediction an odd vertex may move (along the normal line, or to the
    /// closest input point), in lengths of its parent edge (default 1).
    pub reach: f64,
    /// The smallest cosine between the piercing line and the hit input triangle's normal
    /// (default 0.17, about 80°): grazing hits are refused.
    pub min_cos: f64,
    /// The first refinement step that is re-sampled: the odd vertices of levels
    /// `1..=from_level` keep their MAPS positions (default 2). On the coarsest levels the
    /// prediction is far from the input and a piercing can land on another part of it.
    pub from_level: usize,
    /// Keep the MAPS positions of odd vertices whose parent edge touches a boundary or
    /// feature curve (default true).
    pub keep_near_curves: bool,
    /// With [`NormalOptions::keep_near_curves`], keep the vertices next to feature (crease)
    /// curves too, not only those next to boundaries (default true). The lossless grid's
    /// re-sampling pierces next to creases (`false`): its prediction has no crease rules, so
    /// the lines there are the decoder's (fandisk, lossless at 12 bits: 13.8 → 9.8 KB, at
    /// the same 85.7–85.9 dB from the input).
    pub keep_near_creases: bool,
    /// Predict with the butterfly rules alone, ignoring the hierarchy's crease tags, as the
    /// lossless coder does (default false): the piercing lines are then the lossless
    /// decoder's, which a snap to the lossless grid ([`crate::codec::normal_line`]) needs.
    /// The vertices on and next to feature curves are kept as before.
    pub untagged_prediction: bool,
}

impl Default for NormalOptions {
    fn default() -> Self {
        NormalOptions {
            reach: 1.0,
            min_cos: 0.17,
            from_level: 2,
            keep_near_curves: true,
            keep_near_creases: true,
            untagged_prediction: false,
        }
    }
}

/// What [`normal_resample`] did, per level.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct NormalStats {
    /// For each refinement step `j → j + 1`: the odd vertices of level `j + 1`.
    pub odd: Vec<usize>,
    /// For each step: the odd vertices moved onto their normal line (normal vertices).
    pub normal: Vec<usize>,
    /// For each step: the other odd vertices moved to the closest input point of their
    /// prediction (their details are nearly normal).
    pub projected: Vec<usize>,
    /// The least-squares offsets off the input ([`normal_resample_fitted_on`]), if
    /// they were applied.
    pub fit: Option<super::normal_fit::FitStats>,
    /// Vertices put back where the remesh had them because their faces were still folded
    /// after the repair in place ([`resample_remesh`]; in the codec's preparation, where an
    /// earlier re-sampling for a lossless grid got the later one's positions back; else 0).
    pub unfolded: usize,
    /// Faces of the finest level the re-sampling folded or made degenerate, before and
    /// after their repair in place ([`resample_remesh`] and the codec's preparation; both
    /// counted as [`super::quality::measure`] counts flipped and degenerate faces).
    pub repaired: [usize; 2],
}

impl NormalStats {
    /// The fraction of all odd vertices that are normal (1 if there are none).
    pub fn normal_fraction(&self) -> f64 {
        share(&self.normal, &self.odd)
    }
}

/// `Σ part / Σ whole` of per-step counts (1 if `whole` sums to 0).
pub(crate) fn share(part: &[usize], whole: &[usize]) -> f64 {
    let whole: usize = whole.iter().sum();
    if whole == 0 {
        return 1.0;
    }
    part.iter().sum::<usize>() as f64 / whole as f64
}

/// Re-samples the triangle hierarchy `h` (a remesh of the surface `input_pos` /
/// `input_tris`) into a normal mesh with respect to the unlifted modified butterfly
/// prediction (see the module documentation). Base vertices, boundary and feature vertices
/// keep their positions; the connectivity is unchanged.
///
/// # Errors
/// [`Error::InvalidArgument`] if `h` is not a triangle hierarchy, if an input triangle
/// names a vertex that does not exist, or if the input has no triangles.
pub fn normal_resample(
    h: &mut Hierarchy,
    input_pos: &[DVec3],
    input_tris: &[[u32; 3]],
    opts: &NormalOptions,
) -> Result<NormalStats> {
    if h.split != Split::Triangles {
        return Err(Error::InvalidArgument(
            "normal remeshing needs a triangle hierarchy (not --quads)".to_string(),
        ));
    }
    let surface = NormalSurface::new(input_pos, input_tris)?;
    normal_resample_on(h, &surface, opts)
}

/// The input surface of [`normal_resample_on`]: its triangles' BVH and oriented normals
/// (built once, e.g. while the remesh runs).
pub struct NormalSurface {
    surface: Surface,
}

impl NormalSurface {
    /// Indexes the surface `input_pos` / `input_tris`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if an input triangle names a vertex that does not exist,
    /// or if the input has no triangles.
    pub fn new(input_pos: &[DVec3], input_tris: &[[u32; 3]]) -> Result<NormalSurface> {
        if input_tris.is_empty() {
            return Err(Error::InvalidArgument(
                "normal remeshing: the input has no triangles".to_string(),
            ));
        }
        if let Some((k, t)) = input_tris
            .iter()
            .enumerate()
            .find(|(_, t)| t.iter().any(|&i| i as usize >= input_pos.len()))
        {
            return Err(Error::InvalidArgument(format!(
                "normal remeshing: input triangle {k} names vertex {} of {}",
                t.iter().max().copied().unwrap_or(0),
                input_pos.len()
            )));
        }
        Ok(NormalSurface {
            surface: Surface {
                proj: Projector::new(input_pos, input_tris)?,
            },
        })
    }

    /// The index of the input surface (closest points, ray casts).
    pub(crate) fn projector(&self) -> &Projector {
        &self.surface.proj
    }
}

/// [`normal_resample`] on an indexed input surface.
///
/// # Errors
/// [`Error::InvalidArgument`] if `h` is not a triangle hierarchy.
pub fn normal_resample_on(
    h: &mut Hierarchy,
    surface: &NormalSurface,
    opts: &NormalOptions,
) -> Result<NormalStats> {
    Ok(resample_with_axes(h, surface, opts, true)?.0)
}

/// [`normal_resample_on`], then [`super::normal_fit`]'s least-squares offsets along the
/// same piercing lines ([`NormalStats::fit`]): the normal mesh moved off the input to fit it
/// in the L2 sense.
///
/// # Errors
/// As [`normal_resample_on`].
pub fn normal_resample_fitted_on(
    h: &mut Hierarchy,
    surface: &NormalSurface,
    opts: &NormalOptions,
) -> Result<NormalStats> {
    let (mut stats, axes) = resample_with_axes(h, surface, opts, true)?;
    let n0 = h.num_vertices(opts.from_level.min(h.levels()));
    stats.fit = Some(super::normal_fit::fit_along(h, surface, &axes, n0));
    Ok(stats)
}

/// [`super::normal_fit`]'s least-squares offsets alone, for a remesh that is not re-sampled
/// (a MAPS remesh, whose vertices lie on the input too): the vertices that
/// [`normal_resample_on`] would re-sample move along the normals of the butterfly-predicted
/// surface (the axes it would pierce along) to the offsets that fit the input best. Measured
/// on fandisk (4 levels, creases detected): the remesh goes from 89.3 to 91.8 dB from the
/// input, and the stream needs 0.61× Draco's bytes at 84 dB instead of 0.64×.
///
/// # Errors
/// As [`normal_resample_on`].
pub fn fit_on(
    h: &mut Hierarchy,
    surface: &NormalSurface,
    opts: &NormalOptions,
) -> Result<super::normal_fit::FitStats> {
    let (_, axes) = resample_with_axes(h, surface, opts, false)?;
    let n0 = h.num_vertices(opts.from_level.min(h.levels()));
    Ok(super::normal_fit::fit_along(h, surface, &axes, n0))
}

/// Re-samples the triangle remesh `r` of `input` in place, as the codec prepares a remesh
/// for coding: with `normal`, into a normal mesh ([`normal_resample_on`]); with `fit`, with
/// the least-squares offsets off the input ([`normal_resample_fitted_on`], or [`fit_on`]
/// on the MAPS positions without `normal`); neither: nothing changes. Updates
/// `r.hierarchy`, `r.mesh` (positions only: the connectivity and the base mesh are kept)
/// and re-measures `r.quality` against `input` (a normal re-sampling can fold a level where
/// the piercings of a coarsely sampled, strongly curved region cross: the count says so,
/// with a warning in `r.warnings`).
///
/// # Errors
/// [`Error::InvalidArgument`] if `r` is a quad hierarchy (`--quads`), if `input` has no
/// triangles or names a vertex that does not exist.
pub fn resample_remesh(
    r: &mut super::Remeshed,
    input: &crate::mesh::Mesh,
    normal: bool,
    fit: bool,
    opts: &NormalOptions,
) -> Result<NormalStats> {
    if !normal && !fit {
        return Ok(NormalStats::default());
    }
    if r.hierarchy.split != Split::Triangles {
        return Err(Error::InvalidArgument(
            "normal re-sampling and least-squares offsets need a triangle remesh (not --quads)"
                .to_string(),
        ));
    }
    let surface = NormalSurface::new(&input.positions, &input.triangulate().0)?;
    let stats = resample_hierarchy(&mut r.hierarchy, &surface, normal, fit, opts, true)?;
    r.mesh.positions.clone_from(&r.hierarchy.positions);
    r.quality = super::quality::measure(&r.mesh, surface.projector());
    if r.quality.flipped > 0 {
        r.warnings.push(format!(
            "{} face(s) flipped after the {}",
            r.quality.flipped,
            if normal {
                "normal re-sampling"
            } else {
                "least-squares offsets"
            }
        ));
    }
    Ok(stats)
}

/// The re-sampling of [`resample_remesh`] on the triangle hierarchy `h`, on an indexed input (the codec's preparation calls it too):
/// [`normal_resample_on`] or [`normal_resample_fitted_on`] with `normal`, [`fit_on`] with
/// `fit` alone; then the faces it folded are repaired in place ([`repair_in_place`]) and,
/// with `unfold`, the vertices of those left go back to the positions `h` had before
/// ([`unfold_to`]).
///
/// The codec does not unfold: on the bunny at 5 levels, putting back the MAPS positions
/// alone (no repair in place) took the normal mesh with offsets from 85.4 to 83.6 dB from the
/// input (the vertices put back stretch faces across the normal mesh's drift), and the coded
/// stream's highest PSNR fell by as much (0.53× Draco's bytes at 79.2 dB, 1.27× at 83.2 dB;
/// measured 2026-12-04); after the repair in place, `remesh --normal --fit` puts back 675
/// vertices around the 11 faces left and measures 84.3 dB.
///
/// # Errors
/// As [`normal_resample_on`].
pub(crate) fn resample_hierarchy(
    h: &mut Hierarchy,
    surface: &NormalSurface,
    normal: bool,
    fit: bool,
    opts: &NormalOptions,
    unfold: bool,
) -> Result<NormalStats> {
    let before = if unfold {
        h.positions.clone()
    } else {
        Vec::new()
    };
    let mut stats = match (normal, fit) {
        (true, true) => normal_resample_fitted_on(h, surface, opts)?,
        (true, false) => normal_resample_on(h, surface, opts)?,
        (false, true) => NormalStats {
            fit: Some(fit_on(h, surface, opts)?),
            ..NormalStats::default()
        },
        (false, false) => return Ok(NormalStats::default()),
    };
    let (before_repair, after_repair) = repair_in_place(h, surface.projector());
    stats.repaired = [before_repair, after_repair];
    if unfold {
        let finest = &h.topologies[h.levels()];
        stats.unfolded = unfold_to(&mut h.positions, &before, finest, surface.projector());
        tracing::debug!(unfolded = stats.unfolded, "re-sampling: vertices put back");
    }
    Ok(stats)
}

/// Rings around the bad faces whose vertices [`repair_in_place`] finds an input triangle for.
const HINT_RINGS: usize = 16;

/// Repairs the faces of the finest level of `h` that a re-sampling folded or made
/// degenerate (as [`folded`] counts them) in place, with the remesher's final repair
/// ([`super::fold_repair::repair_folds`]: free vertices moved on the input into the kernels
/// of their stars, discs re-embedded, stars searched; each move kept only if it lowers the
/// bad faces around it). Base vertices and the vertices on boundary and feature edges stay
/// where they are. The vertices moved lose their normal (scalar) details and their
/// least-squares offsets, the others keep theirs. Returns the bad faces before and after
/// ([`count_folded`]).
fn repair_in_place(h: &mut Hierarchy, proj: &Projector) -> (usize, usize) {
    let t0 = std::time::Instant::now();
    let levels = h.levels();
    let nb = h.num_vertices(0);
    let topo = &h.topologies[levels];
    let bad: Vec<u32> = (0..topo.num_faces() as u32)
        .into_par_iter()
        .filter(|&f| folded(topo.face_vertices(f as usize), &h.positions, proj))
        .collect();
    if bad.is_empty() {
        return (0, 0);
    }
    let features = feature_edges(&h.topologies);
    let mut fixed = vec![false; h.positions.len()];
    fixed[..nb].fill(true);
    for (e, &[a, b]) in topo.edge_vertices.iter().enumerate() {
        if features[levels][e] {
            fixed[a as usize] = true;
            fixed[b as usize] = true;
        }
    }
    // The input triangles closest to the vertices within HINT_RINGS rings of the bad faces
    // (which the repair's discs reach), from which its closest-point queries start; unknown
    // (a global query) farther away.
    let near = super::resample::face_region(
        topo,
        h.positions.len(),
        bad.iter().map(|&f| f as usize),
        HINT_RINGS,
    );
    let mut hints: Vec<u32> = h
        .positions
        .par_iter()
        .zip(&near)
        .map(|(&p, &n)| {
            if n {
                proj.closest_near(p, &[]).1
            } else {
                u32::MAX
            }
        })
        .collect();
    let slides = vec![false; h.positions.len()];
    tracing::debug!(
        ms = t0.elapsed().as_secs_f64() * 1e3,
        "re-sampling: measured, hinted"
    );
    let fr = super::fold_repair::repair_folds(
        &mut h.positions,
        &mut hints,
        topo,
        &fixed,
        &slides,
        proj,
        12,
        Some(&bad),
        f64::INFINITY,
    );
    tracing::debug!(
        ms = t0.elapsed().as_secs_f64() * 1e3,
        ?fr,
        "re-sampling: fold repair"
    );
    // Counted as before the repair (and as `quality::measure` counts them): the repair's own
    // counts use its vertices' nearest input triangles, and only in its regions.
    (bad.len(), count_folded(topo, &h.positions, proj))
}

/// Rounds of [`unfold_to`] at most.
const UNFOLD_ROUNDS: usize = 40;

/// Whether the face `fv` of a re-sampled remesh is folded or degenerate, as
/// [`super::quality::measure`] counts them: its normal opposes the input's at the closest
/// input point of its centroid, or its smallest angle is below
/// [`super::quality::DEGENERATE_DEGREES`].
fn folded(fv: &[u32], pos: &[DVec3], proj: &Projector) -> bool {
    let (_, flipped, degenerate) = super::quality::face_quality(fv, pos, proj, &[]);
    flipped || degenerate
}

/// How many faces of `topo` are [`folded`] (flipped or degenerate) at `pos`.
pub(crate) fn count_folded(topo: &Topology, pos: &[DVec3], proj: &Projector) -> usize {
    (0..topo.num_faces())
        .into_par_iter()
        .filter(|&f| folded(topo.face_vertices(f), pos, proj))
        .count()
}

/// Whether face `fv` is [`folded`] at `pos` but not at `before`.
fn worse(fv: &[u32], pos: &[DVec3], before: &[DVec3], proj: &Projector) -> bool {
    folded(fv, pos, proj) && !folded(fv, before, proj)
}

/// Puts back the positions `before` (a fold-free remesh, e.g. the MAPS remesh that a normal
/// re-sampling started from) of the vertices of the finest faces that the re-sampling
/// folded or made degenerate (as [`super::quality::measure`] counts them; faces already bad
/// at `before` are left as they are), growing the set
/// one ring around the faces whose vertices are all back already, for at most
/// [`UNFOLD_ROUNDS`] rounds. The vertices put back lose their normal (scalar) details, the
/// others keep theirs. Returns the vertices put back.
///
/// Measured on the bunny at 5 levels (default options), alone: the normal mesh has 68 folded
/// and 2 degenerate faces, none after 853 vertices are put back (82.98 → 81.90 dB from the
/// input; with the least-squares offsets, 70 and 2 faces, 1,056 vertices, 85.4 → 83.6 dB).
/// After [`repair_in_place`]: 4 faces left, 410 vertices put back, 81.87 dB; with the
/// offsets 11, 675 vertices, 84.34 dB.
pub(crate) fn unfold_to(
    pos: &mut [DVec3],
    before: &[DVec3],
    topo: &Topology,
    proj: &Projector,
) -> usize {
    let mut bad: Vec<u32> = (0..topo.num_faces() as u32)
        .into_par_iter()
        .filter(|&f| worse(topo.face_vertices(f as usize), pos, before, proj))
        .collect();
    let mut put_back = 0;
    for _ in 0..UNFOLD_ROUNDS {
        if bad.is_empty() {
            break;
        }
        let mut verts: Vec<u32> = bad
            .iter()
            .flat_map(|&f| topo.face_vertices(f as usize).iter().copied())
            .filter(|&v| pos[v as usize] != before[v as usize])
            .collect();
        if verts.is_empty() {
            // Every vertex of the bad faces is back: one ring more around them.
            verts = bad
                .iter()
                .flat_map(|&f| topo.face_vertices(f as usize).iter().copied())
                .flat_map(|v| {
                    topo.vertex_edges(v as usize)
                        .iter()
                        .copied()
                        .map(move |e| (e, v))
                })
                .map(|(e, v)| topo.other_vertex(e as usize, v))
                .filter(|&v| pos[v as usize] != before[v as usize])
                .collect();
            if verts.is_empty() {
                break;
            }
        }
        verts.sort_unstable();
        verts.dedup();
        for &v in &verts {
            pos[v as usize] = before[v as usize];
        }
        put_back += verts.len();
        let mut faces: Vec<u32> = verts
            .iter()
            .flat_map(|&v| topo.vertex_faces(v as usize).iter().copied())
            .chain(bad.iter().copied())
            .collect();
        faces.sort_unstable();
        faces.dedup();
        bad = faces
            .into_par_iter()
            .filter(|&f| worse(topo.face_vertices(f as usize), pos, before, proj))
            .collect();
    }
    put_back
}

/// The re-sampling of [`normal_resample_on`] (only if `pierce`), also returning each
/// re-sampled vertex's piercing axis: from the vertex `h.num_vertices(opts.from_level)` on,
/// its unit normal and the largest offset along it ([`super::normal_fit::MAX_OFFSET`]
/// parent edges), `None` for the vertices that keep their MAPS positions by rule (on or
/// next to curves).
fn resample_with_axes(
    h: &mut Hierarchy,
    surface: &NormalSurface,
    opts: &NormalOptions,
    pierce: bool,
) -> Result<(NormalStats, Vec<super::normal_fit::Axis>)> {
    if h.split != Split::Triangles {
        return Err(Error::InvalidArgument(
            "normal remeshing needs a triangle hierarchy (not --quads)".to_string(),
        ));
    }
    let surface = &surface.surface;
    let levels = h.levels();
    let features = feature_edges(&h.topologies);
    let mut stats = NormalStats::default();
    let n0 = h.num_vertices(opts.from_level.min(levels));
    let mut axes: Vec<super::normal_fit::Axis> = vec![None; h.positions.len() - n0];
    // The wavelet borrows `h`; work on a copy of the positions and write them back.
    let mut pos = h.positions.clone();
    // The lossless coder predicts without crease rules: so do its lines.
    let untagged = if opts.untagged_prediction {
        let mut base = h.base.clone();
        base.edge_tags.clear();
        base.vertex_tags.clear();
        Some(Hierarchy::new(&base, levels as u32, h.split, None)?)
    } else {
        None
    };
    {
        let w = TriangleWavelet::from_scheme(
            untagged.as_ref().unwrap_or(h),
            &SubdivideOptions {
                scheme: Scheme::Butterfly,
                ..Default::default()
            },
            false,
        )?;
        for (j, feature) in features.iter().enumerate().take(levels) {
            let coarse_topo = h.topology(j);
            let fine_topo = h.topology(j + 1);
            let nc = coarse_topo.num_vertices as usize;
            let nf = fine_topo.num_vertices as usize;
            let predicted = w.predict(j, &pos[..nc])?;
            let frames = odd_vertex_frames(coarse_topo, fine_topo, &predicted);
            // Vertices on a boundary or feature curve of this level: the odd vertices of edges
            // touching them keep their MAPS positions (a normal line next to a crease can
            // cross to the crease's other side).
            let mut on_curve = vec![false; nc];
            for (e, [a, b]) in coarse_topo.edge_vertices.iter().enumerate() {
                if feature[e] && (opts.keep_near_creases || coarse_topo.is_boundary_edge(e)) {
                    on_curve[*a as usize] = true;
                    on_curve[*b as usize] = true;
                }
            }
            if j >= opts.from_level {
                for (e, &[a, b]) in coarse_topo.edge_vertices.iter().enumerate() {
                    let near = on_curve[a as usize] || on_curve[b as usize];
                    if feature[e] || (opts.keep_near_curves && near) {
                        continue;
                    }
                    let len = pos[a as usize].distance(pos[b as usize]);
                    let n = frames[e].normal;
                    if len.is_finite() && len > 0.0 && n.is_finite() {
                        axes[nc + e - n0] = Some((n, super::normal_fit::MAX_OFFSET * len));
                    }
                }
            }
            let (coarse, odd) = pos[..nf].split_at_mut(nc);
            let coarse: &[DVec3] = coarse;
            let (pierced, projected) = odd
                .par_iter_mut()
                .with_min_len(1024)
                .enumerate()
                .map(|(e, x)| {
                    // The vertices with an axis: not on or next to a curve, a finite parent
                    // edge and normal.
                    if !pierce || j < opts.from_level {
                        return (0, 0);
                    }
                    let Some((n, _)) = axes[nc + e - n0] else {
                        return (0, 0);
                    };
                    let p = predicted[nc + e];
                    if !p.is_finite() {
                        return (0, 0);
                    }
                    let [a, b] = coarse_topo.edge_vertices[e];
                    let reach = opts.reach * coarse[a as usize].distance(coarse[b as usize]);
                    if let Some(q) = surface.pierce(p, n, reach, opts.min_cos) {
                        *x = q;
                        return (1, 0);
                    }
                    // Not pierced: the closest input point of the prediction (its detail is
                    // along the input's normal there, nearly the predicted normal).
                    match surface.closest(p, n, opts.min_cos) {
                        Some(q) if q.distance(p) <= reach => *x = q,
                        _ => return (0, 0),
                    }
                    (0, 1)
                })
                .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
            stats.odd.push(nf - nc);
            stats.normal.push(pierced);
            stats.projected.push(projected);
        }
    }
    h.positions = pos;
    Ok((stats, axes))
}

/// The input surface (a BVH and oriented triangle normals).
struct Surface {
    proj: Projector,
}

impl Surface {
    /// The nearest intersection of the line `p + t n`, `|t| ≤ reach`, with the input, if the
    /// hit triangle faces the same way as `n` (cosine at least `min_cos`).
    fn pierce(&self, p: DVec3, n: DVec3, reach: f64, min_cos: f64) -> Option<DVec3> {
        // (signed distance along n, hit triangle) of the nearest hit.
        let mut best: Option<(f64, u32)> = None;
        for sign in [1.0, -1.0] {
            if let Some((t, tri)) = self.proj.cast_ray(p, sign * n, reach) {
                if best.is_none_or(|(bt, _)| t < bt.abs()) {
                    best = Some((sign * t, tri));
                }
            }
        }
        let (t, tri) = best?;
        (self.proj.normals.get(tri as usize)?.dot(n) >= min_cos).then_some(p + t * n)
    }

    /// The closest input point to `p`, if its triangle faces the same way as `n`.
    fn closest(&self, p: DVec3, n: DVec3, min_cos: f64) -> Option<DVec3> {
        let (q, tri) = self.proj.closest(p);
        (self.proj.normals.get(tri as usize)?.dot(n) >= min_cos).then_some(q)
    }
}

/// For each level `j < L`, which of its edges lie on a boundary or on a base feature edge
/// (crease sharpness > 0 at level 0; halves of such edges at finer levels).
pub(super) fn feature_edges(topologies: &[Topology]) -> Vec<Vec<bool>> {
    let mut out: Vec<Vec<bool>> = Vec::with_capacity(topologies.len());
    for (j, t) in topologies.iter().enumerate() {
        let mut f: Vec<bool> = (0..t.num_edges())
            .map(|e| t.is_boundary_edge(e) || t.edge_sharpness.get(e).is_some_and(|&s| s > 0.0))
            .collect();
        if j > 0 {
            let parent = &topologies[j - 1];
            let nc = parent.num_vertices;
            let pf = &out[j - 1];
            for (e, [a, b]) in t.edge_vertices.iter().enumerate() {
                // A half of parent edge `m - nc` joins the odd vertex `m` to an end of it.
                let (m, o) = if *a >= nc && *b < nc {
                    (*a, *b)
                } else if *b >= nc && *a < nc {
                    (*b, *a)
                } else {
                    continue;
                };
                let pe = (m - nc) as usize;
                if pe < pf.len() && pf[pe] && parent.edge_vertices[pe].contains(&o) {
                    f[e] = true;
                }
            }
        }
        out.push(f);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;
    use crate::remesh::{remesh, RemeshOptions};
    use crate::wavelet::triangle::DetailFrame;

    /// A torus remeshed over about 60 base faces, 3 levels, and the input.
    fn torus_remesh() -> (crate::mesh::Mesh, crate::remesh::Remeshed) {
        let input = generate::torus(1.0, 0.4, 64, 32, true);
        let r = remesh(
            &input,
            &RemeshOptions {
                levels: 3,
                base_faces: 60,
                ..Default::default()
            },
        )
        .unwrap();
        (input, r)
    }

    /// A vertex pushed through its star folds faces; [`unfold_to`] puts it back where the
    /// fold-free mesh had it, and moves nothing else.
    #[test]
    fn unfold_puts_folded_vertices_back() {
        let m = generate::icosphere(3);
        let tris: Vec<[u32; 3]> = m.faces().map(|f| [f[0], f[1], f[2]]).collect();
        let proj = Projector::new(&m.positions, &tris).unwrap();
        let topo = Topology::build(&m);
        let before = m.positions.clone();
        let mut pos = before.clone();
        // Vertex 0 moved past its ring along the surface: its faces turn over.
        let far = topo.other_vertex(topo.vertex_edges(0)[0] as usize, 0) as usize;
        pos[0] = (before[0] + 2.5 * (before[far] - before[0])).normalize();
        let folded_faces = (0..topo.num_faces())
            .filter(|&f| folded(topo.face_vertices(f), &pos, &proj))
            .count();
        assert!(folded_faces > 0);
        let n = unfold_to(&mut pos, &before, &topo, &proj);
        assert!(n >= 1);
        assert_eq!(pos, before);
        // Nothing to do on a fold-free mesh.
        assert_eq!(unfold_to(&mut pos, &before, &topo, &proj), 0);
    }

    /// A vertex of a remesh pushed across its star folds faces; [`repair_in_place`] opens
    /// them by moving free vertices on the input, and leaves the base vertices where they are.
    #[test]
    fn repair_in_place_opens_a_pushed_fold() {
        let (input, mut r) = torus_remesh();
        let tris: Vec<[u32; 3]> = input.faces().map(|f| [f[0], f[1], f[2]]).collect();
        let proj = Projector::new(&input.positions, &tris).unwrap();
        let h = &mut r.hierarchy;
        assert_eq!(
            repair_in_place(h, &proj),
            (0, 0),
            "the MAPS remesh is fold-free"
        );
        let nb = h.num_vertices(0);
        let base = h.positions[..nb].to_vec();
        let topo = h.topology(h.levels()).clone();
        let v = h.positions.len() - 1;
        let far = topo.other_vertex(topo.vertex_edges(v)[0] as usize, v as u32) as usize;
        let pushed = h.positions[v] + 2.5 * (h.positions[far] - h.positions[v]);
        h.positions[v] = proj.closest_near(pushed, &[]).0;
        let (before, after) = repair_in_place(h, &proj);
        assert!(before > 0);
        assert_eq!(after, 0);
        assert_eq!(&h.positions[..nb], &base[..]);
        let still = (0..topo.num_faces())
            .filter(|&f| folded(topo.face_vertices(f), &h.positions, &proj))
            .count();
        assert_eq!(still, 0);
    }

    /// [`resample_remesh`] keeps the connectivity, writes the hierarchy's positions into the
    /// mesh, re-measures the quality (no folds left) and refuses quad remeshes.
    #[test]
    fn resample_remesh_updates_mesh_and_quality() {
        let input = generate::torus(1.0, 0.4, 64, 32, true);
        let opts = RemeshOptions {
            levels: 3,
            base_faces: 60,
            ..Default::default()
        };
        let mut r = remesh(&input, &opts).unwrap();
        let faces = r.mesh.face_indices.clone();
        let maps = r.mesh.positions.clone();
        let stats = resample_remesh(&mut r, &input, true, true, &NormalOptions::default()).unwrap();
        assert!(stats.normal_fraction() > 0.5, "{stats:?}");
        assert!(stats.fit.is_some());
        assert_eq!(r.mesh.face_indices, faces);
        assert_eq!(r.mesh.positions, r.hierarchy.positions);
        assert_ne!(r.mesh.positions, maps);
        assert_eq!((r.quality.flipped, r.quality.degenerate), (0, 0));
        // Neither re-sampling nor offsets: nothing changes.
        let mut r2 = remesh(&input, &opts).unwrap();
        let same = r2.mesh.positions.clone();
        resample_remesh(&mut r2, &input, false, false, &NormalOptions::default()).unwrap();
        assert_eq!(r2.mesh.positions, same);
        let mut q = remesh(
            &input,
            &RemeshOptions {
                quads: true,
                ..opts
            },
        )
        .unwrap();
        assert!(resample_remesh(&mut q, &input, true, false, &NormalOptions::default()).is_err());
    }

    /// A sphere remeshed from an irregular-ish input: after normal re-sampling most odd
    /// vertices are normal, every moved vertex lies on the input, and the unlifted butterfly
    /// details of the moved vertices have (numerically) zero tangential components.
    /// Next to crease curves the default keeps the MAPS positions; the lossless grid's options
    /// pierce there (along crease-free lines) and still keep the crease vertices themselves.
    #[test]
    fn vertices_next_to_creases_are_pierced_for_the_lossless_grid() {
        let (input, r) = torus_remesh();
        let tris = input.triangulate().0;
        let mut base = r.hierarchy.base.clone();
        base.edge_tags = (0..base.num_faces())
            .take(4)
            .map(|f| {
                let fv = base.face(f);
                crate::mesh::EdgeTag {
                    vertices: [fv[0], fv[1]],
                    sharpness: crate::mesh::SHARPNESS_INFINITE,
                }
            })
            .collect();
        let tagged = Hierarchy::new(
            &base,
            3,
            Split::Triangles,
            Some(r.hierarchy.positions.clone()),
        )
        .unwrap();
        let crease_vertices: Vec<usize> = {
            let f = feature_edges(&tagged.topologies);
            let mut v = Vec::new();
            for (j, fj) in f.iter().enumerate().take(3) {
                let nc = tagged.num_vertices(j);
                for (e, &on) in fj.iter().enumerate() {
                    if on && !tagged.topology(j).is_boundary_edge(e) {
                        v.push(nc + e);
                    }
                }
            }
            v
        };
        assert!(!crease_vertices.is_empty());
        let mut kept = tagged.clone();
        let d = normal_resample(
            &mut kept,
            &input.positions,
            &tris,
            &NormalOptions::default(),
        )
        .unwrap();
        let mut lossless = tagged.clone();
        let o = NormalOptions {
            keep_near_creases: false,
            untagged_prediction: true,
            ..Default::default()
        };
        let l = normal_resample(&mut lossless, &input.positions, &tris, &o).unwrap();
        let pierced = |s: &NormalStats| s.normal.iter().sum::<usize>();
        assert!(pierced(&l) > pierced(&d), "{l:?} vs {d:?}");
        for v in crease_vertices {
            assert_eq!(
                lossless.positions[v], tagged.positions[v],
                "crease vertex {v}"
            );
        }
    }

    #[test]
    fn normal_vertices_have_scalar_details() {
        let (input, r) = torus_remesh();
        let mut h = r.hierarchy.clone();
        let tris: Vec<[u32; 3]> = input
            .faces()
            .flat_map(|f| (1..f.len() - 1).map(move |k| [f[0], f[k], f[k + 1]]))
            .collect();
        // The default leaves the first two steps to MAPS.
        let mut h2 = r.hierarchy.clone();
        let s2 =
            normal_resample(&mut h2, &input.positions, &tris, &NormalOptions::default()).unwrap();
        assert_eq!(&s2.normal[..2], &[0, 0]);
        assert!(s2.normal[2] > 0);
        let all = NormalOptions {
            from_level: 0,
            ..Default::default()
        };
        let stats = normal_resample(&mut h, &input.positions, &tris, &all).unwrap();
        assert_eq!(stats.odd.len(), 3);
        // The unlifted butterfly details in local frames.
        let w = TriangleWavelet::from_scheme(
            &h,
            &SubdivideOptions {
                scheme: Scheme::Butterfly,
                ..Default::default()
            },
            false,
        )
        .unwrap()
        .with_frame(DetailFrame::Local);
        let mut data = h.positions.clone();
        w.decompose_in_place(&mut data).unwrap();
        // Distance to the torus (major radius 1, minor 0.4, around z).
        let torus = |p: &DVec3| (DVec3::new(p.x.hypot(p.y) - 1.0, p.z, 0.0).length() - 0.4).abs();
        let nb = h.num_vertices(0);
        let (mut tangential, mut normal) = (0.0f64, 0.0f64);
        for d in &data[nb..] {
            normal += d.x * d.x;
            tangential += d.y * d.y + d.z * d.z;
        }
        assert!(
            tangential < 1e-6 * normal,
            "tangential energy {tangential:e} vs normal {normal:e}"
        );
        // Moved vertices lie on the input (within its chord error, < 0.004 here).
        let before = &r.hierarchy.positions;
        let mut moved = 0;
        for (i, (p, q)) in h.positions.iter().zip(before).enumerate() {
            if p != q {
                moved += 1;
                assert!(torus(p) < 5e-3, "vertex {i} at {p}: {}", torus(p));
            }
        }
        assert_eq!(
            moved,
            stats.normal.iter().chain(&stats.projected).sum::<usize>()
        );
        assert!(
            stats.normal_fraction() > 0.8,
            "only {:.1}% normal: {stats:?}",
            100.0 * stats.normal_fraction()
        );
    }

    #[test]
    fn refuses_quads_and_bad_input() {
        let input = generate::torus(1.0, 0.4, 16, 8, true);
        let r = remesh(
            &input,
            &RemeshOptions {
                levels: 1,
                base_faces: 40,
                quads: true,
                ..Default::default()
            },
        )
        .unwrap();
        let mut h = r.hierarchy.clone();
        assert!(
            normal_resample(&mut h, &input.positions, &[[0, 1, 2]], &Default::default()).is_err()
        );
        let r = remesh(
            &input,
            &RemeshOptions {
                levels: 1,
                base_faces: 40,
                ..Default::default()
            },
        )
        .unwrap();
        let mut h = r.hierarchy.clone();
        let err = normal_resample(
            &mut h,
            &input.positions,
            &[[0, 1, 99999]],
            &Default::default(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("triangle 0"), "{err}");
        assert!(normal_resample(&mut h, &input.positions, &[], &Default::default()).is_err());
    }
}

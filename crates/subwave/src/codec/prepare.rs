//! From any input mesh to the semi-regular hierarchy the progressive codec takes
//! (`subwave encode`, `subwave eval`, the demo).
//!
//! A mesh that already has subdivision connectivity — 1-to-4 triangle splits or
//! Catmull-Clark quad splits, in any vertex order — is recognised by inverting the splitting
//! step (Maret 2003 Fig. 4.4, [`Hierarchy::detect`]) and coded as it is; any other mesh is
//! remeshed first ([`crate::remesh`], MAPS with the shrink-wrap fallback; Maret §4.2.3
//! "Decimation in meshes", Bertram §5.3).

use crate::codec::progressive::{EncodeOptions, Wavelet};
use crate::distance::{sample_surface, sampled_rms_to, ClosestPoint};
use crate::hierarchy::Hierarchy;
use crate::mesh::Mesh;
// The base-size rule is the remesher's; re-exported here, where the codec applies it.
use super::normal_line::{snap_to_lines, SnapOptions, SnapStats};
pub use crate::remesh::default_base::{
    finer_base, Missed, DEFAULT_BASE_FACES, MAX_DEFAULT_BASE_FACES,
};
use crate::remesh::normal::{
    count_folded, resample_hierarchy, unfold_to, NormalOptions, NormalStats, NormalSurface,
};
use crate::remesh::normal_fit::FitStats;
use crate::remesh::{remesh_with_progress, RemeshOptions, Remeshed};
use crate::subdivision::sharp_edges_by_angle;
use crate::topology::Topology;
use crate::{Error, Result};
use rayon::prelude::*;

/// The finest level of a remesh (without explicit levels) has at least this many times the
/// input's triangles: enough samples that the remesh is not the bottleneck of the
/// rate–distortion curve (Maret §4.2.3), few enough that small meshes are not inflated.
pub const FACE_RATIO: usize = 2;
/// Most levels [`default_levels`] chooses.
pub const MAX_DEFAULT_LEVELS: u32 = 6;
/// Area samples of [`Prepared::remesh_rms`].
pub const REMESH_SAMPLES: usize = 20_000;
/// The quantization error [`Prepared::encode_options`] allows, as a share of the remesh's
/// own RMS distance to the input ([`EncodeOptions::max_rms`]): the two errors add roughly
/// in quadrature, so the full stream is at most `sqrt(1 + share²)` times further from the
/// input than the remesh (0.26 dB at 1/4), while the bit planes below it, which only
/// describe the remesh's own sampling noise, are not sent.
pub const QUANTIZATION_SHARE: f64 = 0.25;

/// A remesh of at most this many levels put on a lossless grid ([`PrepareOptions::snap`]) is
/// normal re-sampled from its second level on (not its third,
/// [`NormalOptions::from_level`]) where that leaves no more folded faces than the later
/// re-sampling, once the later one's positions are put back around the faces only the
/// earlier one folds (both counted alike, as `remesh` reports flipped and degenerate
/// faces): its first two levels, which would keep their MAPS positions and cost a residual
/// vector per vertex, are a quarter of its vertices at 3 levels. Measured (snap reach 2),
/// lossless at 12 bits (bytes, from the third level → from the second): spot 6,794 → 5,898,
/// teapot 6,699 → 5,236, suzanne (2 levels) 4,601 → 3,663, cow 20,280 → 15,697 (0.570× →
/// 0.436× Draco's bytes; 17 folded faces left instead of 22); at 4 levels it does not pay
/// everywhere (rocker-arm 12,509 → 11,327, cheburashka 12,989 → 13,362; measured
/// 2026-12-05), nor at 5 (stanford-bunny +1.1%).
pub const SNAP_EARLY_MAX_LEVELS: usize = 3;

/// Dihedral angle (degrees) of the feature edges [`detect_feature_angle`] looks for.
pub const FEATURE_ANGLE: f64 = 40.0;

/// A remesh whose distance from the input (Hausdorff, input → remesh) exceeds this fraction
/// of the input's bounding-box diagonal misses part of the input; with default levels
/// ([`PrepareOptions::levels`] `None`) [`prepare`] then remeshes finer: over twice the base
/// faces while they are the default and below [`MAX_DEFAULT_BASE_FACES`], else one level
/// finer, up to [`MAX_DEFAULT_LEVELS`]. Measured over 200 base faces (MAPS remeshes): cow at
/// 3 levels 8.9% (its tail between two samples: 44.0 dB), 4 levels 3.3%, 5 levels 1.2%
/// (74.8 dB); the coded streams of the other corpus meshes at their default levels: spot
/// 0.9%, cheburashka 1.5%, suzanne 1.6%, teapot 2.0%.
pub const MISS_FRACTION: f64 = 0.025;

/// With default levels, a remesh that does not miss the input but stays farther from it
/// than this PSNR (dB; the larger of the one-sided RMS distances against the input's
/// diagonal, which is where the coded stream tops out) is redone with more levels: about
/// one per [`GAIN_PER_LEVEL_DB`] below it, at most [`MAX_RAISE`], while the finest level
/// keeps at most [`MAX_RAISED_FACES`] faces.
///
/// The default levels ([`default_levels`]) follow the input's size, but where they top out
/// depends on its shape, and one level more costs few bytes below that top and many fewer
/// near and above it. Measured 2026-12-05 (`subwave eval`, default options otherwise;
/// bytes at equal PSNR with one level more / at the default levels): spot 3 → 4 levels
/// 1.10 at 56.6 dB, 1.04 at 69.1, 0.91 at 69.4, 0.67 at 71.4, top 71.5 → 80.5 dB; teapot
/// 3 → 4 1.05 at 54.3, 0.96 at 62.0, 0.73 at 65.3, top 66.2 → 75.7 (4 → 5: 1.04 at 56.4,
/// 0.87 at 73.0, top 86.7); cheburashka 4 → 5 1.06 at 53.8, 0.91 at 62.6, 0.71 at 68.3, top
/// 69.9 → 78.3; rocker-arm 4 → 5 1.03–1.06 up to 75.2, 0.82 at 79.0, top 79.3 → 86.6;
/// suzanne 2 → 3 → 4 tops 54.2, 59.7, 66.8; fandisk 4 → 5 1.03–1.10 up to 87.9 dB, where
/// its default already tops out at 91.4 (so it keeps 4), woody 116 dB at 2 levels.
pub const CEILING_DB: f64 = 80.0;

/// The PSNR one more level adds to a remesh, as [`CEILING_DB`] assumes it (measured:
/// 7.0–11.0 dB over the corpus, mostly 8–9; suzanne 5.4 and 7.2).
pub const GAIN_PER_LEVEL_DB: f64 = 9.0;

/// Most faces of the finest level that [`CEILING_DB`] raises a remesh to: 2^18, five levels
/// over 256 base faces (the bunny's default is five levels over 200).
pub const MAX_RAISED_FACES: usize = 1 << 18;
// A remesh that can be raised has at most a quarter of MAX_RAISED_FACES faces: the distance
// from the input to it is measured (Prepared::input_distance), so the raise sees both sides.
const _: () = assert!(MAX_RAISED_FACES / 4 <= MISS_CHECK_FACES);

/// Most levels [`CEILING_DB`] adds: two (16 times the faces). Suzanne (500 faces, 54.2 dB at
/// its default 2 levels) would want three: at 5 levels it tops out at 75.3 dB but takes
/// 6–10 s to encode (the fold repairs of 205k faces), at 4 levels 66.8 dB in about 2 s.
pub const MAX_RAISE: u32 = 2;

/// A remesh that [`prepare`] redid with more levels because it topped out below
/// [`CEILING_DB`] (JSON keys `base_faces`, `levels`, `psnr`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Raised {
    /// Its base faces.
    pub base_faces: usize,
    /// Its levels.
    pub levels: u32,
    /// Its PSNR against the input (dB).
    pub psnr: f64,
}

/// The levels [`prepare`] raises a remesh of `levels` levels over `base_faces` base faces
/// to when it is `psnr` dB from the input ([`CEILING_DB`]); `levels` itself if none.
pub fn raised_levels(levels: u32, base_faces: usize, psnr: f64) -> u32 {
    if psnr.is_nan() || psnr >= CEILING_DB {
        return levels;
    }
    let lacking = ((CEILING_DB - psnr) / GAIN_PER_LEVEL_DB).ceil() as u32;
    let wanted = levels.saturating_add(lacking.min(MAX_RAISE));
    let mut raised = levels;
    while raised < wanted.min(MAX_DEFAULT_LEVELS)
        && base_faces
            .max(1)
            .saturating_mul(1usize << (2 * (raised + 1)).min(62))
            <= MAX_RAISED_FACES
    {
        raised += 1;
    }
    raised
}

/// The distance from the input to a remesh ([`Prepared::input_distance`]) is measured only
/// while the remesh has at most this many faces: indexing the remesh costs about 2.5 µs a
/// face (half a second for the bunny's 204,800), and the misses of [`MISS_FRACTION`] are
/// those of coarse remeshes (cow: 12,800 and 51,200 faces).
pub const MISS_CHECK_FACES: usize = 1 << 16;

/// The feature angle for a remesh of `mesh` when none is given: [`FEATURE_ANGLE`] if the
/// edges sharper than it form a CAD-like crease network, else `None`.
///
/// A crease network is (all three): at least 12 such edges; *stable* — at least 90% of them
/// are still sharper than 60° (true creases, where the faces meet at a clear angle, not the
/// spread of angles of a scanned or coarse organic surface); and *curves* — at least 85% of
/// the vertices they touch have exactly two of them. Measured on the corpus (sharp edges at
/// 40°, share left at 60°, share of curve vertices): fandisk 710, 99%, 97% (detected);
/// stanford-bunny 551, 20%, 39%; rocker-arm 394, 13%, 34%; spot 57, 18%, 33%; cheburashka
/// 316, 72%, 73%; suzanne 430, 60%, 40%; teapot 95, 4%, 73%; cow 843, 36%, 49%; beetle
/// 502, 65%, 50%; woody none. On fandisk the creases matter: at about 67 dB the stream is
/// 0.38× Draco's bytes with them and 0.71× without.
pub fn detect_feature_angle(mesh: &Mesh) -> Option<f64> {
    if mesh.check_indices().is_err() {
        return None;
    }
    let topo = Topology::build(mesh);
    let sharp = sharp_edges_by_angle(mesh, &topo, FEATURE_ANGLE);
    if sharp.len() < 12 {
        return None;
    }
    let sharper = sharp_edges_by_angle(mesh, &topo, 60.0).len();
    let mut degree = vec![0u8; mesh.num_vertices()];
    for &e in &sharp {
        for v in topo.edge_vertices[e as usize] {
            degree[v as usize] = degree[v as usize].saturating_add(1);
        }
    }
    let touched = degree.iter().filter(|&&d| d > 0).count();
    let curve = degree.iter().filter(|&&d| d == 2).count();
    let stable = sharper as f64 >= 0.9 * sharp.len() as f64;
    let curves = curve as f64 >= 0.85 * touched as f64;
    (stable && curves).then_some(FEATURE_ANGLE)
}

/// Options of [`prepare`].
#[derive(Clone, Debug, PartialEq)]
pub struct PrepareOptions {
    /// Levels: required levels of a detected hierarchy (`None`: as many as the mesh has), and
    /// the levels of a remesh (`None`: [`default_levels`]).
    pub levels: Option<u32>,
    /// Base faces of a remesh (`None`: [`DEFAULT_BASE_FACES`]); ignored for a detected
    /// hierarchy.
    pub base_faces: Option<usize>,
    /// Which split the hierarchy has: [`Quads::No`] (the default) detects a semi-regular
    /// triangle mesh and remeshes anything else into triangles; [`Quads::Yes`] detects a
    /// Catmull-Clark quad mesh and remeshes anything else into quads (Bertram's wavelets);
    /// [`Quads::IfSemiRegular`] detects either split and remeshes into triangles.
    pub quads: Quads,
    /// Feature edges of a remesh: dihedral angle in degrees (`None`: see
    /// [`PrepareOptions::detect_features`]).
    pub sharp_angle: Option<f64>,
    /// Without [`PrepareOptions::sharp_angle`], remesh with the feature angle of
    /// [`detect_feature_angle`] when the input has a CAD-like crease network (default on).
    pub detect_features: bool,
    /// Remesh even if the input has subdivision connectivity.
    pub force_remesh: bool,
    /// Re-sample a triangle remesh into a normal mesh ([`crate::remesh::normal`]) for the
    /// unlifted butterfly wavelet, so that most details become scalars along the local
    /// normal. `None` (the default): only when there are no feature edges (no
    /// [`PrepareOptions::sharp_angle`], none detected) — measured: on smooth surfaces a normal mesh
    /// halves the bytes at equal PSNR (stanford-bunny, rocker-arm), while on a CAD part with
    /// creases the MAPS remesh with crease-tagged base edges and the lifted butterfly is
    /// better (fandisk) — or when [`PrepareOptions::snap`] asks for a lossless grid (fandisk,
    /// lossless at 12 bits: 22.5 KB as a MAPS remesh, 9.8 KB as a snapped normal mesh whose
    /// vertices next to the creases are re-sampled along the decoder's crease-free lines,
    /// [`NormalOptions::keep_near_creases`] and [`NormalOptions::untagged_prediction`]).
    /// Ignored for quads and for a detected hierarchy.
    pub normal: Option<bool>,
    /// After the normal re-sampling, move its vertices off the input along their piercing
    /// lines to the least-squares fit of the input ([`crate::remesh::normal_fit`]; default
    /// true): measured on the bunny, the remesh's distance to the input drops by 2.6 dB and
    /// the stream needs fewer bytes at every PSNR above 75 dB. A MAPS remesh (feature edges,
    /// [`PrepareOptions::normal`] false) gets the same offsets along the normals of its
    /// butterfly prediction ([`crate::remesh::normal::fit_on`]; fandisk: 2.5 dB closer).
    /// `false` keeps every vertex on the input. Ignored for quads.
    pub fit: bool,
    /// With default levels, remesh with more levels where the remesh tops out below
    /// [`CEILING_DB`] (default true): the lossy stream then reaches a higher PSNR for few
    /// more bytes below the old top. `false` for a lossless stream of an irregular input,
    /// which codes every vertex of the remesh exactly whatever its distance to the input
    /// (teapot: 8.8 KB at the size-based 3 levels, 40.9 KB raised to 5).
    pub raise_levels: bool,
    /// Put a normal re-sampled triangle remesh on the lossless grid, its normal vertices on
    /// the lossless coder's normal lines ([`crate::codec::normal_line::snap_to_lines`]), for
    /// a lossless stream at the same bits (default `None`: the remesh is not snapped).
    /// Measured (stanford-bunny, 12 bits, `scripts/lossless_vs_draco.py` on the written
    /// remesh): 5 levels 0.675× → 0.401× Draco's bytes (0.395× since the snap's reach is 4
    /// grid steps, [`SnapOptions::reach`]), 4 levels 0.459×. Ignored unless the
    /// normal re-sampling runs ([`PrepareOptions::normal`], which it makes the default).
    pub snap: Option<SnapOptions>,
}

/// The split of the hierarchy [`prepare`] returns ([`PrepareOptions::quads`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Quads {
    /// Triangles: a semi-regular triangle mesh as it is, anything else remeshed.
    #[default]
    No,
    /// Quads: a Catmull-Clark quad mesh as it is, anything else remeshed into quads.
    Yes,
    /// A semi-regular mesh of either split as it is (a Catmull-Clark one with quads);
    /// anything else remeshed into triangles.
    IfSemiRegular,
}

impl Default for PrepareOptions {
    fn default() -> Self {
        PrepareOptions {
            levels: None,
            base_faces: None,
            quads: Quads::No,
            sharp_angle: None,
            detect_features: true,
            force_remesh: false,
            normal: None,
            fit: true,
            raise_levels: true,
            snap: None,
        }
    }
}

/// The levels of a remesh of `input_triangles` triangles over about `base_faces` base
/// triangles when none are given: the fewest with `base_faces · 4^L ≥ FACE_RATIO ·
/// input_triangles`, between 1 and [`MAX_DEFAULT_LEVELS`] (bunny, 69k triangles over 200: 5;
/// fandisk, 13k: 4; spot, 5.9k: 3).
pub fn default_levels(input_triangles: usize, base_faces: usize) -> u32 {
    let target = FACE_RATIO.saturating_mul(input_triangles);
    let mut faces = base_faces.max(1);
    let mut levels = 1;
    faces = faces.saturating_mul(4);
    while faces < target && levels < MAX_DEFAULT_LEVELS {
        faces = faces.saturating_mul(4);
        levels += 1;
    }
    levels
}

/// What [`prepare`] produced.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The hierarchy to code.
    pub hierarchy: Hierarchy,
    /// The remesh, if the input was remeshed (`None`: detected as it is).
    pub remeshed: Option<Remeshed>,
    /// What the normal re-sampling did, if it ran ([`PrepareOptions::normal`]).
    pub normal: Option<NormalStats>,
    /// The feature angle of the remesh, if any: [`PrepareOptions::sharp_angle`] or, when
    /// [`Prepared::features_detected`], [`detect_feature_angle`]'s.
    pub sharp_angle: Option<f64>,
    /// Whether [`Prepared::sharp_angle`] was detected rather than given.
    pub features_detected: bool,
    /// The least-squares offsets off the input ([`PrepareOptions::fit`]), on the normal mesh
    /// (also in [`NormalStats::fit`]) or on the MAPS remesh, if they were applied.
    pub fit: Option<FitStats>,
    /// What the snap to the lossless grid did, if it ran ([`PrepareOptions::snap`]).
    pub snap: Option<SnapStats>,
    /// The RMS distance from the hierarchy's finest level to the input
    /// ([`sampled_rms_to`] with [`REMESH_SAMPLES`] area samples), if the input was remeshed.
    /// One-sided: PSNR takes the larger of both directions, so this may underestimate the
    /// remesh's error, which only makes [`Prepared::encode_options`] keep more bit planes.
    pub remesh_rms: Option<f64>,
    /// The RMS distance from the input to the hierarchy's finest level ([`REMESH_SAMPLES`]
    /// area samples) and the largest (over those and the input's vertices), if the input
    /// was remeshed into at most [`MISS_CHECK_FACES`] faces: large where the remesh misses
    /// part of the input (see [`MISS_FRACTION`]).
    pub input_distance: Option<(f64, f64)>,
    /// The remeshes that missed part of the input before the one kept (empty unless the
    /// levels were the default, see [`MISS_FRACTION`]).
    pub missed: Vec<Missed>,
    /// The remesh redone with more levels because it topped out below [`CEILING_DB`], if
    /// any (only with default levels and [`PrepareOptions::raise_levels`]).
    pub raised: Option<Raised>,
    /// Milliseconds spent measuring [`Prepared::remesh_rms`] and
    /// [`Prepared::input_distance`].
    pub distance_ms: f64,
}

impl Prepared {
    /// The default encoder options for this hierarchy ([`EncodeOptions::for_hierarchy`]),
    /// with the unlifted butterfly if the normal re-sampling ran (a normal mesh is normal
    /// with respect to the interpolating prediction; the update step would spread the
    /// scalar details back into three components).
    pub fn encode_options(&self) -> EncodeOptions {
        let mut o = EncodeOptions::for_hierarchy(&self.hierarchy);
        if self.normal.is_some() {
            o.wavelet = Wavelet::Butterfly;
            o.lifted = false;
        }
        o.max_rms = self
            .remesh_rms
            .map(|d| d * QUANTIZATION_SHARE)
            .filter(|t| *t > 0.0);
        o
    }
}

/// The hierarchy to code for `mesh`: detected if `mesh` is semi-regular (with a split
/// [`PrepareOptions::quads`] takes), else remeshed, non-manifold input being repaired
/// (split) rather than refused. `progress(stage, fraction)` reports the remesher's stages.
///
/// # Errors
/// [`Error::InvalidArgument`] for a mesh without faces; the remesher's errors (see
/// [`crate::remesh::remesh_with_progress`]).
pub fn prepare(
    mesh: &Mesh,
    opts: &PrepareOptions,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Prepared> {
    prepare_screened(mesh, opts, progress, &mut |_| Ok(true))
}

/// [`prepare`], asking `raise(remesh)` before it redoes a remesh with more levels
/// ([`PrepareOptions::raise_levels`]): `false` returns that remesh as it is (`raised`
/// `None`). `subwave encode` screens there whether the input coded as it is
/// ([`super::direct`]) already beats the remesh, so that it need not build the larger one.
///
/// # Errors
/// As [`prepare`], and `raise`'s.
pub fn prepare_screened(
    mesh: &Mesh,
    opts: &PrepareOptions,
    progress: &mut dyn FnMut(&str, f64),
    raise: &mut dyn FnMut(&Prepared) -> Result<bool>,
) -> Result<Prepared> {
    if mesh.num_faces() == 0 {
        return Err(Error::InvalidArgument(
            "the mesh has no faces: nothing to code".to_string(),
        ));
    }
    let shape_fits = match opts.quads {
        Quads::No => mesh.is_triangle_mesh(),
        Quads::Yes => mesh.is_quad_mesh(),
        Quads::IfSemiRegular => mesh.is_triangle_mesh() || mesh.is_quad_mesh(),
    };
    // The split of a remesh.
    let quads = opts.quads == Quads::Yes;
    if shape_fits && !opts.force_remesh {
        if let Ok((hierarchy, _)) = Hierarchy::detect(mesh, opts.levels) {
            return Ok(Prepared {
                hierarchy,
                remeshed: None,
                normal: None,
                sharp_angle: None,
                features_detected: false,
                fit: None,
                snap: None,
                remesh_rms: None,
                input_distance: None,
                missed: Vec::new(),
                raised: None,
                distance_ms: 0.0,
            });
        }
    }
    let detected = match opts.sharp_angle {
        None if opts.detect_features => detect_feature_angle(mesh),
        _ => None,
    };
    let sharp_angle = opts.sharp_angle.or(detected);
    let base_faces = opts.base_faces.unwrap_or(DEFAULT_BASE_FACES);
    let triangles: usize = mesh.faces().map(|f| f.len().saturating_sub(2)).sum();
    let mut ro = RemeshOptions {
        levels: opts
            .levels
            .unwrap_or_else(|| default_levels(triangles, base_faces)),
        base_faces,
        quads,
        sharp_angle,
        repair: true,
        ..RemeshOptions::default()
    };
    // Auto: without feature edges, or for a lossless stream (a snap).
    let run_normal = opts
        .normal
        .unwrap_or(sharp_angle.is_none() || opts.snap.is_some())
        && !quads;
    // The input's index for the normal re-sampling or, on a MAPS remesh, the offsets alone.
    let index_surface = (run_normal || opts.fit) && !quads;
    // The normal re-sampling's index of the input, the one that measures the remesh's
    // distance, and the input's samples are made beside the first remesh.
    let (first, surface, input_bvh, input_samples) = std::thread::scope(|scope| {
        let indexes = scope.spawn(|| {
            let surface =
                index_surface.then(|| NormalSurface::new(&mesh.positions, &mesh.triangulate().0));
            let samples = crate::distance::triangles(mesh, "the input")
                .map(|t| sample_surface(&mesh.positions, &t, REMESH_SAMPLES));
            (surface, ClosestPoint::new(mesh), samples)
        });
        let r = remesh_with_progress(mesh, &ro, progress);
        let (surface, bvh, samples) = indexes
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        (r, surface, bvh, samples)
    });
    let mut r = first?;
    let surface = surface.transpose()?;
    let (input_bvh, input_samples) = (input_bvh?, input_samples?);
    let diagonal = mesh.diagonal();
    let mut missed = Vec::new();
    let mut raised = None;
    let mut distance_ms = 0.0;
    loop {
        let (mut normal, mut fit, mut snap) = (None, None, None);
        if let Some(surface) = &surface {
            // A lossless grid's lines are the decoder's, which has no crease rules.
            let no = NormalOptions {
                untagged_prediction: opts.snap.is_some(),
                keep_near_creases: opts.snap.is_none(),
                ..NormalOptions::default()
            };
            let stage = if run_normal { "normal" } else { "fit" };
            progress(stage, 0.0);
            // For a lossless grid over few levels, the levels below the default first
            // re-sampled one are a large share of the vertices: pierce from level 2 too,
            // unless that leaves more folded faces.
            let early = (opts.snap.is_some()
                && run_normal
                && r.hierarchy.levels() <= SNAP_EARLY_MAX_LEVELS)
                .then(|| {
                    let mut h = r.hierarchy.clone();
                    let o = NormalOptions {
                        from_level: 1,
                        ..no
                    };
                    resample_hierarchy(&mut h, surface, true, opts.fit, &o, false).map(|s| (h, s))
                })
                .transpose()?;
            let mut stats =
                resample_hierarchy(&mut r.hierarchy, surface, run_normal, opts.fit, &no, false)?;
            if let Some((mut h, mut s)) = early {
                if s.repaired[1] > stats.repaired[1] {
                    // Around the folds the later piercing does not have, its positions.
                    let finest = &h.topologies[h.levels()];
                    let proj = surface.projector();
                    s.unfolded = unfold_to(&mut h.positions, &r.hierarchy.positions, finest, proj);
                    s.repaired[1] = count_folded(finest, &h.positions, proj);
                }
                if s.repaired[1] <= stats.repaired[1] {
                    r.hierarchy = h;
                    stats = s;
                }
            }
            fit = stats.fit;
            if run_normal {
                normal = Some(stats);
            }
            progress(stage, 1.0);
            r.mesh.positions.clone_from(&r.hierarchy.positions);
            if let (Some(o), true) = (&opts.snap, run_normal) {
                snap = Some(snap_to_lines(&mut r.hierarchy, o)?);
                r.mesh.positions.clone_from(&r.hierarchy.positions);
            }
        }
        progress("distance", 0.0);
        let t = std::time::Instant::now();
        let remesh_rms = sampled_rms_to(&r.mesh, &input_bvh, REMESH_SAMPLES)?;
        let input_distance = if r.mesh.num_faces() <= MISS_CHECK_FACES {
            Some(distance_from(&input_samples, &mesh.positions, &r.mesh)?)
        } else {
            None
        };
        distance_ms += t.elapsed().as_secs_f64() * 1e3;
        progress("distance", 1.0);
        if opts.levels.is_none() && input_distance.is_some_and(|d| d.1 > MISS_FRACTION * diagonal) {
            let before = Missed {
                base_faces: ro.base_faces,
                levels: ro.levels,
            };
            if let Some(b) = finer_base(ro.base_faces).filter(|_| opts.base_faces.is_none()) {
                ro.base_faces = b;
            } else if ro.levels < MAX_DEFAULT_LEVELS {
                ro.levels += 1;
            }
            if (ro.base_faces, ro.levels) != (before.base_faces, before.levels) {
                tracing::debug!(
                    ?before,
                    hausdorff = input_distance.map(|d| d.1 / diagonal),
                    base_faces = ro.base_faces,
                    levels = ro.levels,
                    "the remesh misses part of the input: remeshing finer"
                );
                missed.push(before);
                r = remesh_with_progress(mesh, &ro, progress)?;
                continue;
            }
        }
        if opts.levels.is_none() && opts.raise_levels && raised.is_none() {
            // Where it tops out: the larger one-sided RMS. The input's side is measured on
            // remeshes of up to MISS_CHECK_FACES faces, which every remesh that can still be
            // raised is (one level more must stay within MAX_RAISED_FACES).
            let rms = input_distance.map_or(remesh_rms, |d| d.0.max(remesh_rms));
            let psnr = crate::distance::psnr(diagonal, rms);
            let base_faces = r.hierarchy.base.num_faces();
            let levels = raised_levels(ro.levels, base_faces, psnr);
            let prepared = |r: &Remeshed| Prepared {
                hierarchy: r.hierarchy.clone(),
                remeshed: Some(r.clone()),
                normal: normal.clone(),
                sharp_angle,
                features_detected: detected.is_some(),
                fit,
                snap: snap.clone(),
                remesh_rms: Some(remesh_rms),
                input_distance,
                missed: missed.clone(),
                raised: None,
                distance_ms,
            };
            if levels > ro.levels && !raise(&prepared(&r))? {
                return Ok(prepared(&r));
            }
            if levels > ro.levels {
                tracing::debug!(
                    psnr,
                    from = ro.levels,
                    to = levels,
                    "the remesh tops out below the ceiling: remeshing with more levels"
                );
                raised = Some(Raised {
                    base_faces,
                    levels: ro.levels,
                    psnr,
                });
                ro.levels = levels;
                r = remesh_with_progress(mesh, &ro, progress)?;
                continue;
            }
        }
        return Ok(Prepared {
            hierarchy: r.hierarchy.clone(),
            remeshed: Some(r),
            normal,
            sharp_angle,
            features_detected: detected.is_some(),
            fit,
            snap,
            remesh_rms: Some(remesh_rms),
            input_distance,
            missed,
            raised,
            distance_ms,
        });
    }
}

/// The RMS distance from the area samples `samples` to the surface of `mesh`, and the
/// largest from them and the points `vertices`.
fn distance_from(
    samples: &[glam::DVec3],
    vertices: &[glam::DVec3],
    mesh: &Mesh,
) -> Result<(f64, f64)> {
    let bvh = ClosestPoint::new(mesh)?;
    let (sum, max) = samples
        .par_iter()
        .map(|&p| {
            let d = bvh.distance(p);
            (d * d, d)
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1.max(b.1)));
    let max = vertices
        .par_iter()
        .map(|&p| bvh.distance(p))
        .reduce(|| max, f64::max);
    Ok(((sum / samples.len().max(1) as f64).sqrt(), max))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;
    use crate::subdivision::refine::Split;

    #[test]
    fn semi_regular_input_is_detected_not_remeshed() {
        let m = generate::icosphere(3);
        let p = prepare(&m, &PrepareOptions::default(), &mut |_, _| {}).unwrap();
        assert!(p.remeshed.is_none());
        assert_eq!(p.hierarchy.levels(), 3);
        assert_eq!(p.hierarchy.base.num_faces(), 20);
        let p = prepare(
            &m,
            &PrepareOptions {
                levels: Some(2),
                ..Default::default()
            },
            &mut |_, _| {},
        )
        .unwrap();
        assert_eq!(p.hierarchy.levels(), 2);
    }

    #[test]
    fn irregular_input_is_remeshed() {
        // Odd grid sizes: no 1-to-4 structure (a regular even grid would be detected).
        let m = generate::torus(1.0, 0.4, 25, 13, true);
        let opts = PrepareOptions {
            levels: Some(2),
            base_faces: Some(64),
            ..Default::default()
        };
        let mut stages = Vec::new();
        let p = prepare(&m, &opts, &mut |s, _| stages.push(s.to_string())).unwrap();
        let r = p.remeshed.as_ref().expect("remeshed");
        assert_eq!(p.hierarchy.levels(), 2);
        assert_eq!(p.hierarchy.split, Split::Triangles);
        assert_eq!(r.mesh.num_vertices(), p.hierarchy.positions.len());
        assert!(!stages.is_empty());
    }

    #[test]
    fn normal_resampling_runs_on_smooth_input_unless_told_otherwise() {
        let m = generate::torus(1.0, 0.4, 25, 13, true);
        let run = |sharp_angle, normal| {
            let opts = PrepareOptions {
                levels: Some(3),
                base_faces: Some(64),
                sharp_angle,
                normal,
                ..Default::default()
            };
            prepare(&m, &opts, &mut |_, _| {}).unwrap()
        };
        // Auto without features: normal mesh, unlifted butterfly.
        let p = run(None, None);
        let n = p.normal.as_ref().expect("normal re-sampling ran");
        assert!(n.normal.iter().sum::<usize>() > 0, "{n:?}");
        let o = p.encode_options();
        assert_eq!((o.wavelet, o.lifted), (Wavelet::Butterfly, false));
        assert_eq!(
            p.remeshed.as_ref().unwrap().mesh.positions,
            p.hierarchy.positions
        );
        // Auto with features, or switched off: MAPS, lifted butterfly.
        for p in [run(Some(40.0), None), run(None, Some(false))] {
            assert!(p.normal.is_none());
            assert!(p.encode_options().lifted);
        }
        assert!(run(Some(40.0), Some(true)).normal.is_some());
    }

    /// For a lossless grid, a remesh of at most [`SNAP_EARLY_MAX_LEVELS`] levels is pierced
    /// from its second level on when that leaves no more folded faces than the later
    /// piercing (none on a torus); deeper remeshes from their third.
    #[test]
    fn a_shallow_snapped_remesh_is_pierced_one_level_earlier() {
        let m = generate::torus(1.0, 0.4, 49, 25, true);
        let run = |levels| {
            let opts = PrepareOptions {
                levels: Some(levels),
                base_faces: Some(64),
                snap: Some(SnapOptions::default()),
                ..Default::default()
            };
            prepare(&m, &opts, &mut |_, _| {}).unwrap()
        };
        let shallow = run(2);
        let n = shallow
            .normal
            .as_ref()
            .expect("a snap runs the normal re-sampling");
        assert_eq!(n.normal[0], 0, "{n:?}");
        assert!(n.normal[1] > n.odd[1] / 2, "{n:?}");
        assert_eq!(n.repaired[1], 0, "{n:?}");
        let r = shallow.remeshed.as_ref().unwrap();
        assert_eq!(r.mesh.positions, shallow.hierarchy.positions);
        let deep = run(4);
        let n = deep.normal.as_ref().unwrap();
        assert_eq!(n.normal[..2], [0, 0], "{n:?}");
        assert!(n.normal[2] > 0, "{n:?}");
    }

    #[test]
    fn a_remesh_codes_only_the_planes_its_own_error_needs() {
        use crate::codec::progressive::{decode, encode_with_info, inspect, DecodeOptions};
        let m = generate::torus(1.0, 0.4, 25, 13, true);
        let opts = PrepareOptions {
            levels: Some(3),
            base_faces: Some(64),
            ..Default::default()
        };
        let p = prepare(&m, &opts, &mut |_, _| {}).unwrap();
        let d = p.remesh_rms.expect("remeshed input has a distance");
        assert!(d > 0.0 && d < 0.01 * m.diagonal(), "{d}");
        let o = p.encode_options();
        let tol = o.max_rms.expect("a remesh sets max_rms");
        assert_eq!(tol, d * QUANTIZATION_SHARE);
        let (bytes, sh) = encode_with_info(&p.hierarchy, &o).unwrap();
        let planes = inspect(&bytes).unwrap().bits;
        assert!(planes < o.bits, "{planes} planes of {}", o.bits);
        // The full decode is within the tolerance of the hierarchy (the base grid adds a
        // little), and one plane fewer would not be.
        let rms = |bytes: &[u8]| {
            let dec = decode(bytes, &DecodeOptions::default()).unwrap();
            let s: f64 = dec
                .mesh
                .positions
                .iter()
                .zip(&sh.positions)
                .map(|(a, b)| a.distance_squared(*b))
                .sum();
            (s / sh.positions.len() as f64).sqrt()
        };
        assert!(rms(&bytes) <= tol * 1.05, "{} > {tol}", rms(&bytes));
        let fewer = EncodeOptions {
            bits: planes - 1,
            max_rms: None,
            ..o.clone()
        };
        let (fewer, _) = encode_with_info(&p.hierarchy, &fewer).unwrap();
        assert!(rms(&fewer) > tol, "{} <= {tol}", rms(&fewer));
        // Without a tolerance every plane is coded; a detected hierarchy has none.
        let all = EncodeOptions {
            max_rms: None,
            ..o.clone()
        };
        assert_eq!(
            inspect(&encode_with_info(&p.hierarchy, &all).unwrap().0)
                .unwrap()
                .bits,
            o.bits
        );
        let sr = prepare(
            &generate::icosphere(2),
            &PrepareOptions::default(),
            &mut |_, _| {},
        )
        .unwrap();
        assert!(sr.remesh_rms.is_none() && sr.encode_options().max_rms.is_none());
    }

    #[test]
    fn crease_networks_are_detected_and_organic_surfaces_are_not() {
        // A cube with each edge cut in 8: 96 edges at 90°, 84 of 92 crease vertices on curves.
        let c = generate::cube();
        let (tris, _) = c.triangulate();
        let mut m = Mesh::from_triangles(c.positions.clone(), &tris);
        for _ in 0..3 {
            m = generate::midpoint_split(&m);
        }
        assert_eq!(detect_feature_angle(&m), Some(FEATURE_ANGLE));
        // The unsplit cube: its 8 corners are all the crease vertices, none on a curve.
        assert_eq!(
            detect_feature_angle(&Mesh::from_triangles(c.positions.clone(), &tris)),
            None
        );
        // Smooth, and rough: a sphere with every vertex pushed in or out at random has
        // sharp edges everywhere, but neither stable nor on curves.
        assert_eq!(detect_feature_angle(&generate::icosphere(3)), None);
        let mut rough = generate::icosphere(3);
        let mut seed = 7u64;
        for p in &mut rough.positions {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *p *= 1.0 + 0.15 * ((seed >> 33) as f64 / (1u64 << 31) as f64 - 0.5);
        }
        let sharp = sharp_edges_by_angle(&rough, &Topology::build(&rough), FEATURE_ANGLE);
        assert!(sharp.len() > 12, "{}", sharp.len());
        assert_eq!(detect_feature_angle(&rough), None);
        // prepare uses it unless told otherwise (and then the normal mesh is off).
        let opts = PrepareOptions {
            levels: Some(1),
            base_faces: Some(48),
            force_remesh: true,
            ..Default::default()
        };
        let p = prepare(&m, &opts, &mut |_, _| {}).unwrap();
        assert!(p.features_detected && p.sharp_angle == Some(FEATURE_ANGLE) && p.normal.is_none());
        let off = PrepareOptions {
            detect_features: false,
            ..opts
        };
        let p = prepare(&m, &off, &mut |_, _| {}).unwrap();
        assert!(!p.features_detected && p.sharp_angle.is_none() && p.normal.is_some());
    }

    #[test]
    fn default_levels_follow_the_input_size() {
        assert_eq!(default_levels(69_451, 200), 5);
        assert_eq!(default_levels(12_946, 200), 4);
        assert_eq!(default_levels(5_856, 200), 3);
        assert_eq!(default_levels(10, 200), 1);
        assert_eq!(default_levels(100_000_000, 200), MAX_DEFAULT_LEVELS);
        assert_eq!(default_levels(1000, 0), 6.min(MAX_DEFAULT_LEVELS));
    }

    #[test]
    fn raised_levels_follow_the_ceiling() {
        // At or above the ceiling: kept.
        assert_eq!(raised_levels(4, 200, 91.4), 4);
        assert_eq!(raised_levels(4, 200, CEILING_DB), 4);
        // One level per GAIN_PER_LEVEL_DB below it (spot 71.5 dB: one; teapot 66.2: two).
        assert_eq!(raised_levels(3, 200, 71.5), 4);
        assert_eq!(raised_levels(3, 199, 66.2), 5);
        // Up to MAX_RAISED_FACES faces: cheburashka (69.9 dB at 4 levels) gets one, not two.
        assert_eq!(raised_levels(4, 200, 69.9), 5);
        assert_eq!(raised_levels(3, 800, 60.0), 4);
        assert_eq!(raised_levels(5, 200, 50.0), 5);
        // At most MAX_RAISE levels more (suzanne, 54.2 dB at 2 levels: 4, not 5).
        assert_eq!(raised_levels(2, 201, 54.2), 4);
        assert_eq!(raised_levels(2, 0, 10.0), 2 + MAX_RAISE);
        assert_eq!(raised_levels(3, 200, f64::NAN), 3);
    }

    #[test]
    fn empty_mesh_is_an_error() {
        let e = prepare(&Mesh::new(), &PrepareOptions::default(), &mut |_, _| {}).unwrap_err();
        assert!(e.to_string().contains("no faces"), "{e}");
    }
}

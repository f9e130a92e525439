//! Multiresolution analysis report of a semi-regular mesh: the `subwave wavelet` command.
//!
//! [`analyze_report`] detects the hierarchy ([`Hierarchy::detect`]), runs the forward
//! transform level by level keeping each low-pass level, and reports, per level, the
//! approximation error against the finest mesh as Bertram et al. Table 5 does ("approximation
//! errors for different levels of resolution with respect to the highest-resolution mesh"),
//! the detail statistics, the reconstruction error of analysis followed by synthesis, and the
//! wall times.
//!
//! # Choices
//! - **Approximation error of level `j`**: the low-pass level `j` is synthesized with all
//!   details zero up to the finest level `L` (plain subdivision by the wavelet's own synthesis:
//!   linear / butterfly / Loop / bilinear / MLCA / biquintic), and compared vertex by vertex
//!   with the finest mesh: `l2_error` is the RMS of the vertex distances, `max_error` their
//!   maximum (model units; `l2_percent` is the RMS in percent of the bounding-box diagonal,
//!   Table 5's unit). Comparing vertex by vertex (not surface to surface) is what the transform
//!   controls and needs no distance query.
//! - **Integer transforms** (§4.3 of Bertram et al.; the lifted midpoint and butterfly of
//!   [`super::triangle_int`]): positions are first quantized to
//!   integers, `q = round((p − min) · s)` with `s = (2^20 − 1) / (largest bounding-box side)`
//!   ([`QUANT_BITS`]), so the bounding box fits `[0, 2^20)`. The transform, the zero-detail
//!   synthesis and the reconstruction run on these integers (`i64`), and the errors are against
//!   the quantized finest mesh, divided by `s` (model units). The reconstruction error is then
//!   exactly 0. Integer detail magnitudes are reported divided by `s` too, in the transform's
//!   own scaling (the §4.3 rescaling shrinks the coarse coefficients, not the details).
//! - **Timings** (separate from the statistics above, which use the allocating level-by-level
//!   transforms): `forward_ms` is the median over [`ReportOptions::runs`] runs of the full
//!   analysis *in place* on the finest level already in memory (the buffer is allocated and
//!   filled outside the timed region), `inverse_ms` the median of the full synthesis in place
//!   from the flat layout `[base | details …]`. The plan of the transform — the prediction
//!   tables of the triangle wavelets, the per-level index tables of the B-spline wavelets —
//!   is built once per hierarchy before, and timed separately as `plan_ms`. File I/O,
//!   hierarchy detection and quantization are never timed.
//! - Detail magnitudes are Euclidean norms; with local frames ([`DetailFrame::Local`],
//!   triangle wavelets only) the frames are orthonormal, so the norms are the same.

use std::time::Instant;

use glam::DVec3;
use serde::Serialize;

use super::bertram::{BSplineWavelet, Degree};
use super::triangle::{DetailFrame, TriangleWavelet};
use super::triangle_int::IntTriangleWavelet;
use crate::hierarchy::Hierarchy;
use crate::mesh::Mesh;
use crate::subdivision::refine::Split;
use crate::subdivision::{Scheme, SubdivideOptions};
use crate::{Error, Result};

/// Bits of the integer quantization of [`analyze_report`]'s integer transforms.
pub const QUANT_BITS: u32 = 20;

/// The wavelets of [`analyze_report`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WaveletKind {
    /// Lazy midpoint wavelet (linear prediction, no update), triangles.
    Midpoint,
    /// Midpoint with the update (lifting) step, triangles.
    MidpointLifted,
    /// Butterfly prediction, no update, triangles (MPEG-4 AFX, Maret §4.5).
    Butterfly,
    /// Butterfly prediction with the update step, triangles.
    ButterflyLifted,
    /// Loop wavelet of PGC (analysis by a sparse solve), triangles.
    Loop,
    /// Lifted midpoint wavelet, integer-to-integer (triangles, [`super::triangle_int`]).
    MidpointInt,
    /// Lifted butterfly wavelet, integer-to-integer (triangles).
    ButterflyInt,
    /// Bertram linear B-spline wavelet, quads (float).
    Linear,
    /// Bertram cubic B-spline wavelet, quads (float).
    Cubic,
    /// Bertram quintic B-spline wavelet, quads (float).
    Quintic,
    /// Bertram linear B-spline wavelet, integer-to-integer (§4.3).
    LinearInt,
    /// Bertram cubic B-spline wavelet, integer-to-integer.
    CubicInt,
    /// Bertram quintic B-spline wavelet, integer-to-integer.
    QuinticInt,
}

impl WaveletKind {
    /// Every wavelet, triangle ones first.
    pub const ALL: [WaveletKind; 13] = [
        WaveletKind::Midpoint,
        WaveletKind::MidpointLifted,
        WaveletKind::Butterfly,
        WaveletKind::ButterflyLifted,
        WaveletKind::Loop,
        WaveletKind::MidpointInt,
        WaveletKind::ButterflyInt,
        WaveletKind::Linear,
        WaveletKind::Cubic,
        WaveletKind::Quintic,
        WaveletKind::LinearInt,
        WaveletKind::CubicInt,
        WaveletKind::QuinticInt,
    ];

    /// Command-line name (`midpoint`, `butterfly-lifted`, `cubic-int`, …).
    pub fn name(self) -> &'static str {
        match self {
            WaveletKind::Midpoint => "midpoint",
            WaveletKind::MidpointLifted => "midpoint-lifted",
            WaveletKind::Butterfly => "butterfly",
            WaveletKind::ButterflyLifted => "butterfly-lifted",
            WaveletKind::Loop => "loop",
            WaveletKind::MidpointInt => "midpoint-int",
            WaveletKind::ButterflyInt => "butterfly-int",
            WaveletKind::Linear => "linear",
            WaveletKind::Cubic => "cubic",
            WaveletKind::Quintic => "quintic",
            WaveletKind::LinearInt => "linear-int",
            WaveletKind::CubicInt => "cubic-int",
            WaveletKind::QuinticInt => "quintic-int",
        }
    }

    /// The wavelet of a command-line name.
    pub fn from_name(name: &str) -> Option<WaveletKind> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The hierarchy the wavelet needs: [`Split::Triangles`] or [`Split::Polygons`] (quads).
    pub fn split(self) -> Split {
        match self {
            WaveletKind::Midpoint
            | WaveletKind::MidpointLifted
            | WaveletKind::Butterfly
            | WaveletKind::ButterflyLifted
            | WaveletKind::Loop
            | WaveletKind::MidpointInt
            | WaveletKind::ButterflyInt => Split::Triangles,
            _ => Split::Polygons,
        }
    }

    /// B-spline degree and integer flag of the quad wavelets.
    fn bspline(self) -> Option<(Degree, bool)> {
        Some(match self {
            WaveletKind::Linear => (Degree::Linear, false),
            WaveletKind::Cubic => (Degree::Cubic, false),
            WaveletKind::Quintic => (Degree::Quintic, false),
            WaveletKind::LinearInt => (Degree::Linear, true),
            WaveletKind::CubicInt => (Degree::Cubic, true),
            WaveletKind::QuinticInt => (Degree::Quintic, true),
            _ => return None,
        })
    }

    /// Comma-separated names of the wavelets for a split.
    pub fn names_for(split: Split) -> String {
        Self::ALL
            .iter()
            .filter(|k| k.split() == split)
            .map(|k| k.name())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// One resolution level of a [`WaveletReport`].
#[derive(Clone, Debug, Serialize)]
pub struct LevelReport {
    /// Level `j` (0 = base mesh).
    pub level: usize,
    /// Number of vertices `V_j`.
    pub vertices: usize,
    /// RMS vertex distance between the zero-detail synthesis of low-pass level `j` and the
    /// finest mesh (model units).
    pub l2_error: f64,
    /// `l2_error` in percent of the bounding-box diagonal (Bertram Table 5's unit).
    pub l2_percent: f64,
    /// Maximum vertex distance of the same comparison.
    pub max_error: f64,
    /// Number of detail coefficients of level `j → j + 1` (0 at the finest level).
    pub details: usize,
    /// Mean magnitude of those details (0 if none).
    pub mean_detail: f64,
    /// Maximum magnitude of those details (0 if none).
    pub max_detail: f64,
}

/// The result of [`analyze_report`] (serialized by `subwave wavelet --json`).
#[derive(Clone, Debug, Serialize)]
pub struct WaveletReport {
    /// Wavelet name ([`WaveletKind::name`]).
    pub wavelet: String,
    /// Detail frame (`global` or `local`).
    pub frames: String,
    /// `triangles` (1-to-4 splits) or `quads` (Catmull-Clark splits).
    pub split: String,
    /// Number of subdivision levels `L` detected.
    pub num_levels: usize,
    /// Base mesh vertices.
    pub base_vertices: usize,
    /// Base mesh faces.
    pub base_faces: usize,
    /// Finest mesh vertices.
    pub vertices: usize,
    /// Finest mesh faces.
    pub faces: usize,
    /// Bounding-box diagonal of the mesh.
    pub diagonal: f64,
    /// Quantization bits of the integer transforms (`None` for float ones).
    pub quantization_bits: Option<u32>,
    /// Levels `0..=L`, coarsest first.
    pub levels: Vec<LevelReport>,
    /// Maximum vertex distance between the input and its analysis followed by synthesis
    /// (model units; 0 exactly for the integer transforms).
    pub reconstruction_max_error: f64,
    /// Wall time of building the transform's plan once for the hierarchy (ms; see the module
    /// documentation).
    pub plan_ms: f64,
    /// Number of timed runs of each direction.
    pub runs: usize,
    /// Median wall time of the in-place forward transform of the whole hierarchy (ms).
    pub forward_ms: f64,
    /// Median wall time of the in-place inverse transform of the whole hierarchy (ms).
    pub inverse_ms: f64,
    /// Fastest of the timed forward runs (ms; the least disturbed on a shared machine).
    pub forward_min_ms: f64,
    /// Fastest of the timed inverse runs (ms).
    pub inverse_min_ms: f64,
    /// Finest-level vertices per second of the forward transform (millions).
    pub forward_mvert_per_s: f64,
    /// Finest-level vertices per second of the inverse transform (millions).
    pub inverse_mvert_per_s: f64,
}

/// Options of [`analyze_report_with`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReportOptions {
    /// Detail frame of the triangle wavelets.
    pub frame: DetailFrame,
    /// Timed runs of each direction (at least 1; the median is reported).
    pub runs: usize,
}

impl Default for ReportOptions {
    fn default() -> Self {
        ReportOptions {
            frame: DetailFrame::Global,
            runs: 1,
        }
    }
}

/// Per-level results of one transform, before the statistics.
struct Run {
    /// Zero-detail synthesis of each low-pass level `0..=L`, at the finest level.
    approximations: Vec<Vec<DVec3>>,
    /// Detail magnitudes per level `0..L`.
    detail_norms: Vec<Vec<f64>>,
    reconstructed: Vec<DVec3>,
    reference: Vec<DVec3>,
    timing: Timing,
}

/// Plan time and median in-place transform times.
struct Timing {
    plan_ms: f64,
    forward_ms: f64,
    inverse_ms: f64,
    forward_min_ms: f64,
    inverse_min_ms: f64,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    let n = x.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        x[n / 2]
    } else {
        0.5 * (x[n / 2 - 1] + x[n / 2])
    }
}

/// Median times of `runs` in-place forward and inverse transforms of `input`: each run copies
/// `input` into a buffer allocated once (untimed), then times `forward` on it, then `inverse`
/// on the coefficients it left.
fn time_in_place<T: Copy>(
    input: &[T],
    runs: usize,
    plan_ms: f64,
    mut forward: impl FnMut(&mut [T]) -> Result<()>,
    mut inverse: impl FnMut(&mut [T]) -> Result<()>,
) -> Result<Timing> {
    let mut buf = input.to_vec();
    let (mut f, mut i) = (Vec::new(), Vec::new());
    for _ in 0..runs.max(1) {
        buf.copy_from_slice(input);
        let t = Instant::now();
        forward(&mut buf)?;
        f.push(ms(t));
        let t = Instant::now();
        inverse(&mut buf)?;
        i.push(ms(t));
    }
    let min = |x: &[f64]| x.iter().copied().fold(f64::INFINITY, f64::min);
    Ok(Timing {
        plan_ms,
        forward_min_ms: min(&f),
        inverse_min_ms: min(&i),
        forward_ms: median(f),
        inverse_ms: median(i),
    })
}

/// Detects the semi-regular structure of `mesh`, runs `kind` on it and reports per-level
/// approximation errors, detail statistics, reconstruction error and timings (see the module
/// documentation for the choices). `frame` applies to the triangle wavelets. One timed run:
/// [`analyze_report_with`] with [`ReportOptions::runs`] = 1.
///
/// # Errors
/// [`Error::InvalidArgument`] if the wavelet does not fit the mesh (triangle wavelets on a
/// quad mesh or the reverse; the message lists the wavelets that fit) or local frames are
/// asked for a B-spline wavelet; [`Error::Hierarchy`] / [`Error::Mesh`] from
/// [`Hierarchy::detect`] if the mesh has no subdivision connectivity; the transforms' errors.
pub fn analyze_report(mesh: &Mesh, kind: WaveletKind, frame: DetailFrame) -> Result<WaveletReport> {
    analyze_report_with(mesh, kind, &ReportOptions { frame, runs: 1 })
}

/// [`analyze_report`] with the median of `opts.runs` timed runs of each direction.
///
/// # Errors
/// As [`analyze_report`].
pub fn analyze_report_with(
    mesh: &Mesh,
    kind: WaveletKind,
    opts: &ReportOptions,
) -> Result<WaveletReport> {
    let (frame, runs) = (opts.frame, opts.runs.max(1));
    let want = kind.split();
    let (quads, tris) = (mesh.is_quad_mesh(), mesh.is_triangle_mesh());
    let mismatch = |what: &str, fits: Split| {
        Error::InvalidArgument(format!(
            "the {} wavelet needs a {} semi-regular mesh, but this is {what}; wavelets that fit it: {}",
            kind.name(),
            if want == Split::Triangles {
                "triangle (1-to-4 split)"
            } else {
                "quad (Catmull-Clark split)"
            },
            WaveletKind::names_for(fits)
        ))
    };
    if mesh.num_faces() > 0 {
        if want == Split::Triangles && quads {
            return Err(mismatch("an all-quad mesh", Split::Polygons));
        }
        if want == Split::Polygons && tris {
            return Err(mismatch("a triangle mesh", Split::Triangles));
        }
    }
    if frame == DetailFrame::Local && want == Split::Polygons {
        return Err(Error::InvalidArgument(format!(
            "local detail frames are only available for the triangle wavelets ({}); use global frames with {}",
            WaveletKind::names_for(Split::Triangles),
            kind.name()
        )));
    }
    let (h, _) = Hierarchy::detect(mesh, None)?;
    if h.split != want {
        return Err(mismatch("another kind of hierarchy", h.split));
    }
    let int_triangle = matches!(kind, WaveletKind::MidpointInt | WaveletKind::ButterflyInt);
    if int_triangle && frame == DetailFrame::Local {
        return Err(Error::InvalidArgument(format!(
            "the integer wavelet {} keeps details in global (integer) coordinates; use --frames global",
            kind.name()
        )));
    }
    let run = match kind.bspline() {
        None if int_triangle => run_triangle_int(&h, kind, runs)?,
        None => run_triangle(&h, kind, frame, runs)?,
        Some((degree, false)) => run_bspline(&h, degree, runs)?,
        Some((degree, true)) => run_bspline_int(&h, degree, runs)?,
    };
    let diagonal = mesh.diagonal();
    let dist = |a: &[DVec3]| -> (f64, f64) {
        let mut sq = 0.0f64;
        let mut mx = 0.0f64;
        for (p, q) in a.iter().zip(&run.reference) {
            let d = p.distance(*q);
            sq += d * d;
            mx = mx.max(d);
        }
        ((sq / a.len().max(1) as f64).sqrt(), mx)
    };
    let l = h.levels();
    let levels = (0..=l)
        .map(|j| {
            let (l2, mx) = dist(&run.approximations[j]);
            let norms: &[f64] = if j < l { &run.detail_norms[j] } else { &[] };
            LevelReport {
                level: j,
                vertices: h.num_vertices(j),
                l2_error: l2,
                l2_percent: if diagonal > 0.0 {
                    100.0 * l2 / diagonal
                } else {
                    0.0
                },
                max_error: mx,
                details: norms.len(),
                mean_detail: if norms.is_empty() {
                    0.0
                } else {
                    norms.iter().sum::<f64>() / norms.len() as f64
                },
                max_detail: norms.iter().copied().fold(0.0, f64::max),
            }
        })
        .collect();
    let (_, rec) = dist(&run.reconstructed);
    Ok(WaveletReport {
        wavelet: kind.name().into(),
        frames: match frame {
            DetailFrame::Global => "global",
            DetailFrame::Local => "local",
        }
        .into(),
        split: if want == Split::Triangles {
            "triangles"
        } else {
            "quads"
        }
        .into(),
        num_levels: l,
        base_vertices: h.base.num_vertices(),
        base_faces: h.base.num_faces(),
        vertices: mesh.num_vertices(),
        faces: mesh.num_faces(),
        diagonal,
        quantization_bits: (int_triangle || kind.bspline().is_some_and(|b| b.1))
            .then_some(QUANT_BITS),
        levels,
        reconstruction_max_error: rec,
        plan_ms: run.timing.plan_ms,
        runs,
        forward_ms: run.timing.forward_ms,
        inverse_ms: run.timing.inverse_ms,
        forward_min_ms: run.timing.forward_min_ms,
        inverse_min_ms: run.timing.inverse_min_ms,
        forward_mvert_per_s: mvert_per_s(mesh.num_vertices(), run.timing.forward_ms),
        inverse_mvert_per_s: mvert_per_s(mesh.num_vertices(), run.timing.inverse_ms),
    })
}

fn mvert_per_s(n: usize, ms: f64) -> f64 {
    if ms > 0.0 {
        n as f64 / ms * 1e-3
    } else {
        0.0
    }
}

fn run_triangle(h: &Hierarchy, kind: WaveletKind, frame: DetailFrame, runs: usize) -> Result<Run> {
    let opts = SubdivideOptions::default();
    let t = Instant::now();
    let w = match kind {
        WaveletKind::Midpoint => TriangleWavelet::midpoint(h, false)?,
        WaveletKind::MidpointLifted => TriangleWavelet::midpoint(h, true)?,
        // `from_scheme` with `Scheme::Butterfly`, bit for bit, with the tables built from the
        // level topologies when the hierarchy is untagged (the codec's path).
        WaveletKind::Butterfly | WaveletKind::ButterflyLifted => {
            TriangleWavelet::butterfly(h, kind == WaveletKind::ButterflyLifted)?
        }
        _ => TriangleWavelet::loop_pgc(h, &opts)?,
    }
    .with_frame(frame);
    let plan_ms = ms(t);
    let l = h.levels();
    let mut lowpass = vec![Vec::new(); l + 1];
    let mut details = vec![Vec::new(); l];
    lowpass[l] = h.positions.clone();
    for j in (0..l).rev() {
        let (c, d) = w.analyze_level(j, &lowpass[j + 1])?;
        lowpass[j] = c;
        details[j] = d;
    }
    let mut signal = lowpass[0].clone();
    for (j, d) in details.iter().enumerate() {
        signal = w.synthesize_level(j, &signal, d)?;
    }
    let timing = time_in_place(
        &h.positions,
        runs,
        plan_ms,
        |d| w.decompose_in_place(d),
        |d| w.reconstruct_in_place(d),
    )?;
    let mut approximations = Vec::with_capacity(l + 1);
    for (j, low) in lowpass.iter().enumerate() {
        let mut s = low.clone();
        for k in j..l {
            let zeros = vec![DVec3::ZERO; h.num_vertices(k + 1) - h.num_vertices(k)];
            s = w.synthesize_level(k, &s, &zeros)?;
        }
        approximations.push(s);
    }
    Ok(Run {
        approximations,
        detail_norms: details
            .iter()
            .map(|d| d.iter().map(|x| x.length()).collect())
            .collect(),
        reconstructed: signal,
        reference: h.positions.clone(),
        timing,
    })
}

fn run_bspline(h: &Hierarchy, degree: Degree, runs: usize) -> Result<Run> {
    let w = BSplineWavelet::new(degree);
    let l = h.levels();
    let topo = &h.topologies[..l];
    let sizes: Vec<usize> = (0..=l).map(|j| h.num_vertices(j)).collect();
    let mut data = h.positions.clone();
    let mut lowpass = vec![Vec::new(); l + 1];
    for j in (0..l).rev() {
        w.analyze_level(&topo[j], &mut data[..sizes[j + 1]])?;
        lowpass[j] = data[..sizes[j]].to_vec();
    }
    lowpass[l] = h.positions.clone();
    let detail_norms = (0..l)
        .map(|j| {
            data[sizes[j]..sizes[j + 1]]
                .iter()
                .map(|d| d.length())
                .collect()
        })
        .collect();
    for j in 0..l {
        w.synthesize_level(&topo[j], &mut data[..sizes[j + 1]])?;
    }
    let timing = time_in_place(
        &h.positions,
        runs,
        0.0,
        |d| w.analyze(topo, d),
        |d| w.synthesize(topo, d),
    )?;
    let mut approximations = Vec::with_capacity(l + 1);
    for (j, low) in lowpass.iter().enumerate() {
        let mut s = low.clone();
        s.resize(sizes[l], DVec3::ZERO);
        for k in j..l {
            w.synthesize_level(&topo[k], &mut s[..sizes[k + 1]])?;
        }
        approximations.push(s);
    }
    Ok(Run {
        approximations,
        detail_norms,
        reconstructed: data,
        reference: h.positions.clone(),
        timing,
    })
}

fn run_bspline_int(h: &Hierarchy, degree: Degree, runs: usize) -> Result<Run> {
    let w = BSplineWavelet::new(degree);
    let topo = &h.topologies;
    let coarse = &topo[..h.levels()];
    // Timed through the whole-hierarchy transforms, as the codec calls them (each level
    // then knows which of its inputs the previous level left small, see `analyze_int`).
    run_int(
        h,
        runs,
        0.0,
        |j, d| w.analyze_level_int(&topo[j], d),
        |j, d| w.synthesize_level_int(&topo[j], d),
        Some((&|d| w.analyze_int(coarse, d), &|d| {
            w.synthesize_int(coarse, d)
        })),
    )
}

fn run_triangle_int(h: &Hierarchy, kind: WaveletKind, runs: usize) -> Result<Run> {
    let scheme = if kind == WaveletKind::ButterflyInt {
        Scheme::Butterfly
    } else {
        Scheme::Midpoint
    };
    let opts = SubdivideOptions {
        scheme,
        ..Default::default()
    };
    let t = Instant::now();
    let w = IntTriangleWavelet::from_scheme(h, &opts, true)?;
    let plan_ms = ms(t);
    run_int(
        h,
        runs,
        plan_ms,
        |j, d| {
            w.forward_level(j, d);
            Ok(())
        },
        |j, d| {
            w.inverse_level(j, d);
            Ok(())
        },
        None,
    )
}

/// The whole-hierarchy analysis and synthesis of an integer transform.
type IntWhole<'a> = (
    &'a dyn Fn(&mut [[i64; 3]]) -> Result<()>,
    &'a dyn Fn(&mut [[i64; 3]]) -> Result<()>,
);

/// An integer transform given by its level steps, on the positions quantized into
/// `[0, 2^QUANT_BITS)`; timed through `whole` if given (the same results as the level steps
/// in turn), else through the level steps.
fn run_int(
    h: &Hierarchy,
    runs: usize,
    plan_ms: f64,
    analyze: impl Fn(usize, &mut [[i64; 3]]) -> Result<()>,
    synthesize: impl Fn(usize, &mut [[i64; 3]]) -> Result<()>,
    whole: Option<IntWhole>,
) -> Result<Run> {
    let l = h.levels();
    let sizes: Vec<usize> = (0..=l).map(|j| h.num_vertices(j)).collect();
    // Quantization: the bounding box into [0, 2^QUANT_BITS).
    let first = h.positions.first().copied().unwrap_or(DVec3::ZERO);
    let (lo, hi) = h
        .positions
        .iter()
        .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let extent = (hi - lo).max_element();
    let s = if extent > 0.0 {
        ((1u64 << QUANT_BITS) - 1) as f64 / extent
    } else {
        1.0
    };
    let quant: Vec<[i64; 3]> = h
        .positions
        .iter()
        .map(|p| {
            let q = ((*p - lo) * s).round();
            [q.x as i64, q.y as i64, q.z as i64]
        })
        .collect();
    let to_f = |q: &[i64; 3]| DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64) / s;
    let mut data = quant.clone();
    let mut lowpass = vec![Vec::new(); l + 1];
    for j in (0..l).rev() {
        analyze(j, &mut data[..sizes[j + 1]])?;
        lowpass[j] = data[..sizes[j]].to_vec();
    }
    lowpass[l] = quant.clone();
    let detail_norms = (0..l)
        .map(|j| {
            data[sizes[j]..sizes[j + 1]]
                .iter()
                .map(|d| to_f(d).length())
                .collect()
        })
        .collect();
    for j in 0..l {
        synthesize(j, &mut data[..sizes[j + 1]])?;
    }
    let timing = match whole {
        // The same results as the level steps (tested with the transforms).
        Some((forward, inverse)) => time_in_place(&quant, runs, plan_ms, forward, inverse)?,
        None => time_in_place(
            &quant,
            runs,
            plan_ms,
            |d| {
                (0..l)
                    .rev()
                    .try_for_each(|j| analyze(j, &mut d[..sizes[j + 1]]))
            },
            |d| (0..l).try_for_each(|j| synthesize(j, &mut d[..sizes[j + 1]])),
        )?,
    };
    let mut approximations = Vec::with_capacity(l + 1);
    for (j, low) in lowpass.iter().enumerate() {
        let mut a = low.clone();
        a.resize(sizes[l], [0; 3]);
        for k in j..l {
            synthesize(k, &mut a[..sizes[k + 1]])?;
        }
        approximations.push(a.iter().map(to_f).collect());
    }
    Ok(Run {
        approximations,
        detail_norms,
        reconstructed: data.iter().map(to_f).collect(),
        reference: quant.iter().map(to_f).collect(),
        timing,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;
    use crate::subdivision::subdivide;

    fn sub(m: &Mesh, scheme: Scheme, levels: u32) -> Mesh {
        subdivide(
            m,
            &SubdivideOptions {
                scheme,
                levels,
                ..SubdivideOptions::default()
            },
        )
        .unwrap()
    }

    /// A wavelet whose zero-detail synthesis is the scheme that built the mesh has zero
    /// details and zero approximation error at every level.
    #[test]
    fn own_subdivision_has_no_details() {
        let ico = generate::icosahedron();
        let cases = [
            (sub(&ico, Scheme::Midpoint, 3), WaveletKind::Midpoint, 1e-12),
            (
                sub(&ico, Scheme::Butterfly, 3),
                WaveletKind::Butterfly,
                1e-12,
            ),
            (sub(&ico, Scheme::Loop, 3), WaveletKind::Loop, 1e-7),
            (
                sub(&generate::cube(), Scheme::Bilinear, 3),
                WaveletKind::Linear,
                1e-12,
            ),
            (
                sub(&generate::cube(), Scheme::Bicubic, 3),
                WaveletKind::Cubic,
                1e-12,
            ),
        ];
        for (m, kind, tol) in cases {
            let r = analyze_report(&m, kind, DetailFrame::Global).unwrap();
            assert_eq!(r.num_levels, 3, "{}", kind.name());
            assert_eq!(r.levels.len(), 4);
            assert_eq!(r.levels[3].vertices, m.num_vertices());
            for l in &r.levels {
                assert!(
                    l.max_error < tol,
                    "{} level {}: {}",
                    kind.name(),
                    l.level,
                    l.max_error
                );
                assert!(
                    l.max_detail < tol,
                    "{} level {}: {}",
                    kind.name(),
                    l.level,
                    l.max_detail
                );
            }
            assert!(r.reconstruction_max_error < tol);
        }
    }

    #[test]
    fn noisy_mesh_errors_decrease_and_reconstruct() {
        let mut m = sub(&generate::cube(), Scheme::CatmullClark, 3);
        for (i, p) in m.positions.iter_mut().enumerate() {
            *p += 0.01
                * DVec3::new(
                    (i as f64).sin(),
                    (1.7 * i as f64).cos(),
                    (0.3 * i as f64).sin(),
                );
        }
        for kind in [
            WaveletKind::Linear,
            WaveletKind::Cubic,
            WaveletKind::CubicInt,
            WaveletKind::QuinticInt,
        ] {
            let r = analyze_report(&m, kind, DetailFrame::Global).unwrap();
            assert_eq!(r.base_vertices, 8);
            assert_eq!(r.base_faces, 6);
            assert_eq!(r.levels[3].l2_error, 0.0);
            assert!(
                r.levels[0].l2_error > r.levels[2].l2_error,
                "{}",
                kind.name()
            );
            assert!(r.levels[2].mean_detail > 0.0);
            if kind.name().ends_with("-int") {
                assert_eq!(r.reconstruction_max_error, 0.0);
                assert_eq!(r.quantization_bits, Some(QUANT_BITS));
            } else {
                assert!(r.reconstruction_max_error < 1e-12);
            }
        }
    }

    #[test]
    fn mismatch_names_the_fitting_wavelets() {
        let quad = sub(&generate::cube(), Scheme::CatmullClark, 2);
        let e = analyze_report(&quad, WaveletKind::Loop, DetailFrame::Global).unwrap_err();
        assert!(e.to_string().contains("linear, cubic"), "{e}");
        let tri = sub(&generate::icosahedron(), Scheme::Loop, 2);
        let e = analyze_report(&tri, WaveletKind::Cubic, DetailFrame::Global).unwrap_err();
        assert!(e.to_string().contains("midpoint, midpoint-lifted"), "{e}");
        let e = analyze_report(
            &generate::icosahedron(),
            WaveletKind::Loop,
            DetailFrame::Global,
        )
        .unwrap_err();
        assert!(e.to_string().contains("coarsening step 1"), "{e}");
    }
}

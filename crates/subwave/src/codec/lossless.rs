//! Lossless coding of semi-regular meshes: integer wavelets coded level by level with
//! context-modelled adaptive binary coding of the integer details.
//!
//! Sources: Maret 2003 §4.5 (wavelet coding of subdivision surfaces, the MPEG-4 AFX
//! framework this mode extends) and Bertram et al. §4.3 (integer lifting of B-spline wavelets
//! on quad hierarchies, for lossless coding); the triangle transforms are the integer
//! midpoint / butterfly liftings of [`crate::wavelet::triangle_int`] (Calderbank et al. 1998).
//! The context modelling follows the usual lossless-image practice (CALIC / JPEG-LS style:
//! the expected magnitude of a residual is estimated from already decoded neighbours).
//!
//! # Stream
//! The positions are quantized on the stream's grid (`2^bits − 1` steps over the longest side
//! of the bounding box, [`super::quantize::Grid`]). The base mesh is coded first by the
//! base-mesh coder's integer API ([`super::basemesh::encode_integers`]: valence-driven
//! connectivity, parallelogram prediction), which renumbers the base; the hierarchy is
//! re-indexed to that order. Then one chunk per level `j = 0..L` (container kind
//! [`super::container::ChunkKind::Level`], id `j`) holds the residuals of the odd vertices of
//! level `j + 1` (`V_j..V_{j+1}` in contract order):
//!
//! ```text
//! predictor u8      triangles: the mode below (chosen per level by the encoder); quads: 0
//! range-coder data  per vertex, per component x, y, z: zero flag, sign, |d| − 1
//!                   (mode 6: per vertex the on-line flag, then k: zero flag, sign,
//!                   |k| − 1; or, off its line, the three components as above)
//! ```
//!
//! **Triangle hierarchies** use pure prediction (no update step: the level-`j` vertices keep
//! their exact finest positions, so every level chunk decodes to an exact coarser mesh):
//! `d = x − ⌊P + ½⌋` with `P` one of (mode byte) 0 midpoint, 1 butterfly (the stencils of
//! [`crate::subdivision`]), 2 their mean, or, in **reference streams**, 3 the reference
//! surface `R`, 4 `R` plus the midpoint interpolation of the residual field `x − R` of the
//! level-`j` vertices, 5 the same with butterfly; or 6, the **normal lines** of
//! [`super::normal_line`] (format version 9): per vertex a flag, then for a vertex on its
//! line (`x = ⌊P + k·N + ½⌋`, `P` the butterfly prediction, `N` the unit normal of the
//! predicted surface) the integer `k`, else `d` against the butterfly `P` as mode 1 codes it.
//! The encoder codes each level with every mode and keeps the smallest.
//!
//! A normal remesh snapped to the grid ([`super::normal_line::snap_to_lines`], what
//! `subwave encode --lossless` makes of an irregular input) has most of its vertices on their
//! lines, so one integer places each: measured at 12 bits against Draco on the same remesh
//! (`scripts/lossless_vs_draco.py`), stanford-bunny at 5 levels 0.675× (mode 6 on the
//! unsnapped normal remesh) → 0.395× (snapped), rocker-arm and cheburashka at 4 levels
//! 0.42× and 0.41×.
//!
//! A **reference stream** (flag `F_REFERENCE` of [`super::progressive`]) targets meshes that
//! are (close to) subdivision surfaces. Interpolating predictors predict a Loop surface
//! poorly, and even an exactly butterfly-subdivided mesh leaves rounding noise when the
//! prediction starts from the *quantized* coarse positions. The encoder fits control points
//! `X_0` of the base mesh by least squares (`argmin ‖S^L X_0 − y‖²` for `S` = Loop or
//! butterfly, CGLS over the stencil tables, `fit_control_points`), rounds them to `2^-k`
//! grid steps (`k` from `REFERENCE_BITS`), and codes them in the base chunk (tag byte
//! `k | scheme << 4`, scheme 0 Loop, 1 butterfly, then the base-mesh integer stream). Both
//! sides compute `R = S^L X_0` with the same f64 code (`reference_surface`); on an exactly
//! subdivided input the residuals are then rounding differences, mostly zero, which the
//! phase contexts (below) code in a fraction of a bit. Level chunk 0 starts with the
//! residuals of the base vertices against `⌊R + ½⌋`. The encoder codes the plain stream and
//! each (scheme, k) reference stream and keeps the smallest.
//!
//! **Quad hierarchies** use Bertram's integer B-spline lifting (the stream's wavelet) and
//! code its details level by level with the same contexts.
//!
//! Each level chunk decodes after the base and the coarser levels only, so any prefix of the
//! stream decodes to the levels it holds exactly (a cut level up to the first missing byte);
//! the missing residuals are zero.
//!
//! # Contexts
//! A line level (mode 6) codes its flag in contexts of the coded neighbours (how many are
//! off their line, up to 2; whether any is on it), and `k` as a zero flag and a magnitude in
//! contexts of the class of the neighbours' mean `|k|` (this level's weighted 2:1 against
//! coarser ones), and a sign in contexts of the sign of their sum; the vertices off their
//! line code their residual vectors as below, with models of their own.
//!
//! For odd vertex `v` and component `c`, with `N(v)` its neighbours in the level-`j + 1`
//! mesh: the **expected magnitude** is the mean `|d_c|` of the neighbours already coded at
//! this level (`V_j ≤ w < v`), weighted 2:1 with the mean over those coded at coarser levels
//! (`V_0 ≤ w < V_j`), averaged with the largest `|d|` of the components of `v` already coded.
//! Its bit length selects the class (24 classes). The zero flag is coded in contexts of
//! (component, class, phase), the sign in contexts of (component, sign of the same-level
//! neighbours' sum, phase), the magnitude with an adaptive Elias-gamma model ([`UInt`]) per
//! (component, class); every level starts with fresh models. The **phase** of a triangle
//! prediction is where the unrounded `P` falls between two rounding ties (8 bins of
//! `P + ½ − ⌊P + ½⌋`): on exactly subdivided input the residual is a rounding difference,
//! whose zero probability and sign depend on it. Quad details use one phase.
//!
//! # Determinism
//! Predictions are evaluated in `f64` in stencil order (IEEE 754, no fused multiply-adds),
//! identically in the encoder and the decoder of one build. The butterfly's extraordinary
//! and Loop's masks have real weights computed with `cos`, whose last bit may differ between
//! C libraries: streams are exact between machines whose `libm` agrees (as for
//! [`crate::wavelet::triangle_int`]).
//!
//! # Decoder safety
//! Every count comes from the validated header ([`super::progressive`]); the base chunk's
//! counts are checked against it; decoded coordinates are bounded by [`MAX_COORD`] after
//! every level (a corrupt stream is an error, never an overflow).

use glam::DVec3;
use rayon::prelude::*;

use super::basemesh;
use super::container::{ChunkEntry, ChunkKind, Container};
use super::normal_line;
use super::quantize::Grid;
use super::rangecoder::{CountedBit, Decoder, Encoder, UInt};
use crate::hierarchy::Hierarchy;
use crate::mesh::Mesh;
use crate::subdivision::refine::Split;
use crate::subdivision::stencil::StencilTable;
use crate::subdivision::{Refinement, Scheme, SubdivideOptions};
use crate::topology::Topology;
use crate::wavelet::bertram::{BSplineWavelet, Degree};
use crate::wavelet::triangle_int::MAX_COORD;
use crate::{Error, Result};

/// Triangle level predictor: midpoint.
const MODE_MIDPOINT: u8 = 0;
/// Triangle level predictor: butterfly.
const MODE_BUTTERFLY: u8 = 1;
/// Triangle level predictor: the mean of midpoint and butterfly.
const MODE_HALF: u8 = 2;
/// Reference streams: the reference surface.
const MODE_REF: u8 = 3;
/// Reference streams: the reference plus the midpoint interpolation of the residual field.
const MODE_REF_MIDPOINT: u8 = 4;
/// Reference streams: the reference plus the butterfly interpolation of the residual field.
const MODE_REF_BUTTERFLY: u8 = 5;
/// Triangle level predictor: the normal lines of [`super::normal_line`] (butterfly, then one
/// integer step along the predicted normal per vertex on its line).
const MODE_LINE: u8 = 6;
/// What a vertex's residual is, for the contexts of line levels: coded at a level of
/// another predictor (or not coded).
const KIND_VECTOR: u8 = 0;
/// A vertex of a line level on its line (its residual is `[k, 0, 0]`).
const KIND_ON_LINE: u8 = 1;
/// A vertex of a line level off its line (its residual is the vector).
const KIND_OFF_LINE: u8 = 2;
/// Contexts of the on-line flag.
const LINE_FLAG_CONTEXTS: usize = 6;
/// Magnitude classes.
const CLASSES: usize = 24;
/// Phase bins of a prediction (where it falls between two rounding ties).
const PHASES: usize = 8;
/// Extra bits of the reference control points over the grid, tried by the encoder per
/// scheme of [`REFERENCE_SCHEMES`]: each extra bit costs about 3 bits per base vertex and
/// shrinks the rounding noise of the reference. Measured at 12 bits (base + levels, KB):
/// Loop-subdivided spot (Loop reference) k = 2: 19.3, 3: 18.1, 4: 16.8, 5: 16.3, 6: 16.3;
/// butterfly-subdivided rocker arm (butterfly reference) k = 1: 51.5, 2: 47.0, 3: 47.0,
/// 4: 48.1, 5: 49.9.
const REFERENCE_BITS: [[u8; 2]; 2] = [[4, 6], [2, 4]];
/// Largest extra precision a decoder accepts.
const MAX_REFERENCE_BITS: u8 = 8;

/// `⌊y⌋` for `|y| < 2^62`, exact (no libm call).
#[inline]
pub(crate) fn floor_i64(y: f64) -> i64 {
    let t = y as i64;
    if (t as f64) > y {
        t - 1
    } else {
        t
    }
}

/// The rounded prediction and its phase bin.
#[inline]
fn round_phase(p: f64) -> (i64, u8) {
    let r = floor_i64(p + 0.5);
    let f = (p + 0.5) - r as f64;
    (r, ((f * PHASES as f64) as u8).min(PHASES as u8 - 1))
}

/// The adaptive models of one level.
struct Models {
    zero: Vec<CountedBit>,
    sign: Vec<CountedBit>,
    mags: Vec<UInt<CountedBit>>,
}

impl Models {
    fn new() -> Self {
        Models {
            zero: vec![CountedBit::default(); 3 * CLASSES * PHASES],
            sign: vec![CountedBit::default(); 3 * 3 * PHASES],
            mags: vec![UInt::new(); 3 * CLASSES],
        }
    }
}

/// Bit length of `x`.
#[inline]
fn bitlen(x: u64) -> usize {
    (64 - x.leading_zeros()) as usize
}

/// The neighbourhood of a vertex being coded: expected magnitudes ×16 per component from
/// the neighbours already coded (`None`: none), and the sign class of the same-level
/// neighbours' sum.
struct Context {
    expect: Option<[u64; 3]>,
    sign: [usize; 3],
}

/// Where a level's vertices are and which neighbours count.
#[derive(Clone, Copy)]
struct Span<'a> {
    /// The mesh the vertices live in (level `j + 1`).
    topo: &'a Topology,
    /// Vertices below `first_coded` have no residual (not coded, or coded elsewhere).
    first_coded: usize,
    /// First vertex of the level (`V_j`).
    first: usize,
}

fn context(s: Span, v: usize, res: &[[i64; 3]]) -> Context {
    let (mut ss, mut sc) = ([0u64; 3], [0u64; 3]);
    let (mut ns, mut nc) = (0u64, 0u64);
    let mut sg = [0i64; 3];
    for &e in s.topo.vertex_edges(v) {
        let w = s.topo.other_vertex(e as usize, v as u32) as usize;
        if w >= v || w < s.first_coded {
            continue;
        }
        let r = res[w];
        if w >= s.first {
            ns += 1;
            for c in 0..3 {
                ss[c] += r[c].unsigned_abs();
                sg[c] += r[c];
            }
        } else {
            nc += 1;
            for c in 0..3 {
                sc[c] += r[c].unsigned_abs();
            }
        }
    }
    let expect = match (ns, nc) {
        (0, 0) => None,
        (n, 0) => Some(ss.map(|s| 16 * s / n)),
        (0, n) => Some(sc.map(|s| 16 * s / n)),
        (a, b) => Some([0, 1, 2].map(|c| 16 * (2 * ss[c] * b + sc[c] * a) / (3 * a * b))),
    };
    Context {
        expect,
        sign: sg.map(|s| (s.signum() + 1) as usize),
    }
}

/// The magnitude class of component `c` given the neighbourhood and the components of the
/// same vertex already coded.
#[inline]
fn class(ctx: &Context, c: usize, own: &[i64; 3]) -> usize {
    let mine = own[..c].iter().map(|x| x.unsigned_abs()).max();
    let e = match (ctx.expect, mine) {
        (None, None) => return 0,
        (Some(e), None) => e[c],
        (None, Some(m)) => 16 * m,
        (Some(e), Some(m)) => (e[c] + 16 * m) / 2,
    };
    (1 + bitlen(e)).min(CLASSES - 1)
}

/// Codes the residuals `details` of vertices `s.first..` (with their phases).
fn encode_level(
    s: Span,
    details: &[[i64; 3]],
    phases: &[[u8; 3]],
    res: &mut [[i64; 3]],
    enc: &mut Encoder,
) {
    let mut m = Models::new();
    for (i, d) in details.iter().enumerate() {
        let v = s.first + i;
        encode_vertex(&mut m, s, v, d, &phases[i], res, enc);
        res[v] = *d;
    }
}

/// Codes the residual vector `d` of vertex `v` (phases `ph`) in the contexts of its coded
/// neighbours.
fn encode_vertex(
    m: &mut Models,
    s: Span,
    v: usize,
    d: &[i64; 3],
    ph: &[u8; 3],
    res: &[[i64; 3]],
    enc: &mut Encoder,
) {
    let ctx = context(s, v, res);
    for c in 0..3 {
        let k = class(&ctx, c, d);
        let ph = ph[c] as usize;
        let x = d[c];
        enc.bit(&mut m.zero[(c * CLASSES + k) * PHASES + ph], x == 0);
        if x != 0 {
            enc.bit(&mut m.sign[(c * 3 + ctx.sign[c]) * PHASES + ph], x < 0);
            m.mags[c * CLASSES + k].encode(enc, (x.unsigned_abs() - 1) as u32);
        }
    }
}

/// Decodes the residual vector of vertex `v` (phases `ph`), as [`encode_vertex`] coded it.
fn decode_vertex(
    m: &mut Models,
    s: Span,
    v: usize,
    ph: &[u8; 3],
    res: &[[i64; 3]],
    dec: &mut Decoder,
) -> [i64; 3] {
    let ctx = context(s, v, res);
    let mut d = [0i64; 3];
    for c in 0..3 {
        let k = class(&ctx, c, &d);
        let ph = ph[c] as usize;
        if !dec.bit(&mut m.zero[(c * CLASSES + k) * PHASES + ph]) {
            let neg = dec.bit(&mut m.sign[(c * 3 + ctx.sign[c]) * PHASES + ph]);
            let a = m.mags[c * CLASSES + k].decode(dec) as i64 + 1;
            d[c] = if neg { -a } else { a };
        }
    }
    d
}

/// Decodes the residuals of vertices `s.first..s.first + phases.len()` into `res`; returns
/// how many vertices decoded before the data ran out.
fn decode_level(s: Span, phases: &[[u8; 3]], res: &mut [[i64; 3]], dec: &mut Decoder) -> usize {
    let mut m = Models::new();
    for (i, ph) in phases.iter().enumerate() {
        let v = s.first + i;
        let d = decode_vertex(&mut m, s, v, ph, res, dec);
        if dec.truncated() {
            return i;
        }
        res[v] = d;
    }
    phases.len()
}

/// Bytes of a level coded on its own (the encoder's choice of predictor).
fn level_cost(s: Span, details: &[[i64; 3]], phases: &[[u8; 3]], res: &[[i64; 3]]) -> usize {
    let mut scratch = res.to_vec();
    let mut e = Encoder::new();
    encode_level(s, details, phases, &mut scratch, &mut e);
    e.finish().len()
}

/// A vertex of a line level as the encoder codes it: on its line (`d = [k, 0, 0]`, `k` its
/// step) or off it (`d` the residual against the rounded butterfly prediction, with phases).
#[derive(Clone, Copy, Debug)]
struct LineResidual {
    on_line: bool,
    d: [i64; 3],
    phase: [u8; 3],
}

/// The adaptive models of a line level.
struct LineModels {
    /// On-line flag, per [`LineContext::flag`].
    flag: [CountedBit; LINE_FLAG_CONTEXTS],
    /// Step: zero flag per class, sign per sign class, magnitude − 1 per class.
    zero: Vec<CountedBit>,
    sign: [CountedBit; 3],
    mags: Vec<UInt<CountedBit>>,
    /// The residual vectors of the vertices off their line.
    off: Models,
}

impl LineModels {
    fn new() -> Self {
        LineModels {
            flag: [CountedBit::default(); LINE_FLAG_CONTEXTS],
            zero: vec![CountedBit::default(); CLASSES],
            sign: [CountedBit::default(); 3],
            mags: vec![UInt::new(); CLASSES],
            off: Models::new(),
        }
    }
}

/// The contexts of a vertex of a line level, from its coded neighbours.
struct LineContext {
    /// `2 · min(neighbours off their line, 2) + (any neighbour on its line)`.
    flag: usize,
    /// Magnitude class of the expected step: the neighbours' mean `|k|` (×16), those of this
    /// level weighted 2:1 against coarser ones, as [`context`] does.
    class: usize,
    /// Sign of the sum of the neighbours' steps (0 negative, 1 zero, 2 positive).
    sign: usize,
}

fn line_context(s: Span, v: usize, res: &[[i64; 3]], kinds: &[u8]) -> LineContext {
    let (mut off, mut ns, mut nc, mut ss, mut sc, mut sg) = (0usize, 0u64, 0u64, 0u64, 0u64, 0i64);
    for &e in s.topo.vertex_edges(v) {
        let w = s.topo.other_vertex(e as usize, v as u32) as usize;
        if w >= v || w < s.first_coded {
            continue;
        }
        match kinds[w] {
            KIND_OFF_LINE => off += 1,
            KIND_ON_LINE => {
                let k = res[w][0];
                sg += k;
                if w >= s.first {
                    ns += 1;
                    ss += k.unsigned_abs();
                } else {
                    nc += 1;
                    sc += k.unsigned_abs();
                }
            }
            _ => {}
        }
    }
    let expect = match (ns, nc) {
        (0, 0) => None,
        (a, b) => Some(16 * (2 * ss + sc) / (2 * a + b)),
    };
    LineContext {
        flag: 2 * off.min(2) + usize::from(ns + nc > 0),
        class: expect.map_or(0, |e| (1 + bitlen(e)).min(CLASSES - 1)),
        sign: (sg.signum() + 1) as usize,
    }
}

/// Codes the vertices `s.first..` of a line level.
fn encode_line_level(
    s: Span,
    items: &[LineResidual],
    res: &mut [[i64; 3]],
    kinds: &mut [u8],
    enc: &mut Encoder,
) {
    let mut m = LineModels::new();
    for (i, it) in items.iter().enumerate() {
        let v = s.first + i;
        let c = line_context(s, v, res, kinds);
        enc.bit(&mut m.flag[c.flag], it.on_line);
        if it.on_line {
            let k = it.d[0];
            enc.bit(&mut m.zero[c.class], k == 0);
            if k != 0 {
                enc.bit(&mut m.sign[c.sign], k < 0);
                m.mags[c.class].encode(enc, (k.unsigned_abs() - 1) as u32);
            }
            kinds[v] = KIND_ON_LINE;
        } else {
            encode_vertex(&mut m.off, s, v, &it.d, &it.phase, res, enc);
            kinds[v] = KIND_OFF_LINE;
        }
        res[v] = it.d;
    }
}

/// Decodes the vertices `s.first..s.first + lines.len()` of a line level (their lines
/// `(P, N)`) into `data` (grid points) and `res`/`kinds` (contexts); returns how many
/// decoded before the data ran out.
fn decode_line_level(
    s: Span,
    lines: &[(DVec3, DVec3)],
    res: &mut [[i64; 3]],
    kinds: &mut [u8],
    data: &mut [[i64; 3]],
    dec: &mut Decoder,
) -> usize {
    let mut m = LineModels::new();
    for (i, &(p, n)) in lines.iter().enumerate() {
        let v = s.first + i;
        let c = line_context(s, v, res, kinds);
        let (d, x, kind) = if dec.bit(&mut m.flag[c.flag]) {
            let k = if dec.bit(&mut m.zero[c.class]) {
                0
            } else {
                let neg = dec.bit(&mut m.sign[c.sign]);
                let a = m.mags[c.class].decode(dec) as i64 + 1;
                if neg {
                    -a
                } else {
                    a
                }
            };
            ([k, 0, 0], normal_line::point(p, n, k), KIND_ON_LINE)
        } else {
            let r = [p.x, p.y, p.z].map(round_phase);
            let d = decode_vertex(&mut m.off, s, v, &r.map(|x| x.1), res, dec);
            let x = [0, 1, 2].map(|c| r[c].0.saturating_add(d[c]));
            (d, x, KIND_OFF_LINE)
        };
        if dec.truncated() {
            return i;
        }
        res[v] = d;
        kinds[v] = kind;
        data[v] = x;
    }
    lines.len()
}

/// The residuals of a line level's vertices `q` (grid points) on their lines.
fn line_residuals(lines: &[(DVec3, DVec3)], q: &[[i64; 3]]) -> Vec<LineResidual> {
    lines
        .par_iter()
        .with_min_len(4096)
        .zip(q)
        .map(|(&(p, n), &x)| match normal_line::step(p, n, x) {
            Some(k) => LineResidual {
                on_line: true,
                d: [k, 0, 0],
                phase: [0; 3],
            },
            None => {
                let r = [p.x, p.y, p.z].map(round_phase);
                LineResidual {
                    on_line: false,
                    d: [0, 1, 2].map(|c| x[c] - r[c].0),
                    phase: r.map(|x| x.1),
                }
            }
        })
        .collect()
}

/// The stencil tables of an interpolating or approximating scheme on `h`'s base, checked
/// against the hierarchy, and the subdivided base positions.
pub(crate) fn scheme_tables(h: &Hierarchy, base: &Mesh, scheme: Scheme) -> Result<Refinement> {
    let o = SubdivideOptions {
        scheme,
        levels: h.levels() as u32,
        ..Default::default()
    };
    let r = Refinement::build(base, &o, true)?;
    let ok = r.stencils.len() == h.levels()
        && r.stencils.iter().enumerate().all(|(j, t)| {
            t.num_sources as usize == h.num_vertices(j)
                && t.len() == h.num_vertices(j + 1)
                && t.child_sources == 0
                && t.indices.iter().all(|&k| k < t.num_sources)
        });
    if !ok {
        return Err(Error::InvalidArgument(format!(
            "the {scheme:?} tables do not match the hierarchy"
        )));
    }
    Ok(r)
}

/// `Σ w · x[k]` over row `r` of `t`.
#[inline]
pub(crate) fn apply_int(t: &StencilTable, r: usize, x: &[[i64; 3]]) -> [f64; 3] {
    let (a, b) = (t.offsets[r] as usize, t.offsets[r + 1] as usize);
    let mut acc = [0.0f64; 3];
    for (&k, &w) in t.indices[a..b].iter().zip(&t.weights[a..b]) {
        let y = x[k as usize];
        for q in 0..3 {
            acc[q] += w * y[q] as f64;
        }
    }
    acc
}

/// `Σ w · x[k]` over row `r` of `t`, for reals.
#[inline]
fn apply_f(t: &StencilTable, r: usize, x: &[DVec3]) -> [f64; 3] {
    let (a, b) = (t.offsets[r] as usize, t.offsets[r + 1] as usize);
    let mut acc = [0.0f64; 3];
    for (&k, &w) in t.indices[a..b].iter().zip(&t.weights[a..b]) {
        let y = x[k as usize];
        for q in 0..3 {
            acc[q] += w * y[q];
        }
    }
    acc
}

/// The predictors of a triangle hierarchy.
struct TriPredictors {
    /// Midpoint tables (built only if a level uses them).
    mid: Option<Vec<StencilTable>>,
    /// Butterfly tables (likewise).
    bfly: Option<Vec<StencilTable>>,
    /// Vertices per level (`V_0..=V_L`).
    sizes: Vec<usize>,
    /// The reference surface at the finest level, in grid units (reference streams).
    reference: Option<Vec<DVec3>>,
}

impl TriPredictors {
    /// The predictors of `h`, with the midpoint and butterfly tables if asked for.
    fn new(h: &Hierarchy, base: &Mesh, mid: bool, bfly: bool) -> Result<Self> {
        let tables = |on: bool, scheme| -> Result<Option<Vec<StencilTable>>> {
            Ok(if on {
                Some(scheme_tables(h, base, scheme)?.stencils)
            } else {
                None
            })
        };
        Ok(TriPredictors {
            mid: tables(mid, Scheme::Midpoint)?,
            bfly: tables(bfly, Scheme::Butterfly)?,
            sizes: (0..=h.levels()).map(|j| h.num_vertices(j)).collect(),
            reference: None,
        })
    }

    /// Whether `mode` needs the midpoint and the butterfly tables.
    fn needs(mode: u8) -> (bool, bool) {
        match mode {
            MODE_MIDPOINT | MODE_REF_MIDPOINT => (true, false),
            MODE_BUTTERFLY | MODE_REF_BUTTERFLY | MODE_LINE => (false, true),
            MODE_HALF => (true, true),
            _ => (false, false),
        }
    }

    fn modes(&self) -> &'static [u8] {
        if self.reference.is_some() {
            &[
                MODE_MIDPOINT,
                MODE_BUTTERFLY,
                MODE_HALF,
                MODE_REF,
                MODE_REF_MIDPOINT,
                MODE_REF_BUTTERFLY,
                MODE_LINE,
            ]
        } else {
            &[MODE_MIDPOINT, MODE_BUTTERFLY, MODE_HALF, MODE_LINE]
        }
    }

    /// The normal lines of level `j`'s odd vertices ([`normal_line::lines`]) from the exact
    /// values `even` of the level-`j` vertices of `h`; `None` without the butterfly tables.
    fn lines(&self, h: &Hierarchy, j: usize, even: &[[i64; 3]]) -> Option<Vec<(DVec3, DVec3)>> {
        let t = self.bfly.as_ref()?.get(j)?;
        Some(normal_line::lines(
            t,
            h.topology(j),
            h.topology(j + 1),
            even,
        ))
    }

    /// Rounded predictions and phases of level `j`'s odd vertices (`V_j..V_{j+1}`) from the
    /// exact values `even` of the level-`j` vertices. `mode` must be one of
    /// [`TriPredictors::modes`].
    ///
    /// A mode whose tables were not built predicts the reference (or zero): never for a
    /// stream the encoder wrote, since the decoder builds the tables its levels name.
    fn predict(&self, mode: u8, j: usize, even: &[[i64; 3]]) -> Vec<([i64; 3], [u8; 3])> {
        let mid = self.mid.as_ref().and_then(|t| t.get(j));
        let bfly = self.bfly.as_ref().and_then(|t| t.get(j));
        let vj = even.len();
        let n = self.sizes.get(j + 1).copied().unwrap_or(vj).max(vj);
        let empty = Vec::new();
        let reference = self.reference.as_ref().unwrap_or(&empty);
        (vj..n)
            .into_par_iter()
            .with_min_len(4096)
            .map(|v| {
                let p = match (mode, mid, bfly) {
                    (MODE_MIDPOINT, Some(mid), _) => apply_int(mid, v, even),
                    (MODE_BUTTERFLY, _, Some(bfly)) => apply_int(bfly, v, even),
                    (MODE_HALF, Some(mid), Some(bfly)) => {
                        let (a, b) = (apply_int(mid, v, even), apply_int(bfly, v, even));
                        [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]))
                    }
                    _ => {
                        let r = reference.get(v).copied().unwrap_or_default();
                        let t = match mode {
                            MODE_REF_MIDPOINT => mid,
                            MODE_REF_BUTTERFLY => bfly,
                            _ => None,
                        };
                        match t {
                            None => r.to_array(),
                            Some(t) => {
                                let a = apply_int(t, v, even);
                                let b = apply_f(t, v, &reference[..vj.min(reference.len())]);
                                [0, 1, 2].map(|c| r[c] + (a[c] - b[c]))
                            }
                        }
                    }
                };
                let (x, y, z) = (round_phase(p[0]), round_phase(p[1]), round_phase(p[2]));
                ([x.0, y.0, z.0], [x.1, y.1, z.1])
            })
            .collect()
    }

    /// Rounded reference and phases of the base vertices (reference streams).
    fn predict_base(&self, v0: usize) -> Vec<([i64; 3], [u8; 3])> {
        let r = self.reference.as_deref().unwrap_or(&[]);
        r[..v0.min(r.len())]
            .iter()
            .map(|p| {
                let (x, y, z) = (round_phase(p.x), round_phase(p.y), round_phase(p.z));
                ([x.0, y.0, z.0], [x.1, y.1, z.1])
            })
            .collect()
    }
}

/// The schemes of reference surfaces (the high nibble of the tag byte).
const REFERENCE_SCHEMES: [Scheme; 2] = [Scheme::Loop, Scheme::Butterfly];

/// The scheme and extra bits of a reference tag byte (`k | scheme << 4`), if valid.
fn reference_tag(tag: u8) -> Option<(Scheme, u8)> {
    let k = tag & 15;
    let s = REFERENCE_SCHEMES.get((tag >> 4) as usize)?;
    (k <= MAX_REFERENCE_BITS).then_some((*s, k))
}

/// The reference surface of control points `x0` (integers in units of `2^-k` grid steps):
/// `L` levels of the tag's scheme on `base`'s faces, in grid units. Deterministic: the same
/// function runs in the encoder and the decoder.
fn reference_surface(h: &Hierarchy, base: &Mesh, x0: &[[i64; 3]], tag: u8) -> Result<Vec<DVec3>> {
    let (scheme, k) = reference_tag(tag)
        .ok_or_else(|| Error::InvalidArgument(format!("bad reference tag {tag}")))?;
    let mut m = base.clone();
    m.positions = x0
        .iter()
        .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect();
    let r = scheme_tables(h, &m, scheme)?;
    let s = 1.0 / (1u64 << k) as f64;
    Ok(r.positions.iter().map(|p| *p * s).collect())
}

/// Least-squares control points of a subdivision surface (the scheme of `tables`) through
/// the finest positions `y` (grid units): `argmin ‖S_{L−1} ⋯ S_0 x − y‖²` by conjugate gradients on the normal equations
/// (CGLS), per component, from the base samples.
fn fit_control_points(tables: &[StencilTable], y: &[DVec3], v0: usize) -> Vec<DVec3> {
    let apply = |x: &[DVec3]| -> Vec<DVec3> {
        let mut cur = x.to_vec();
        for t in tables {
            cur = (0..t.len())
                .into_par_iter()
                .with_min_len(4096)
                .map(|r| DVec3::from_array(apply_f(t, r, &cur)))
                .collect();
        }
        cur
    };
    let apply_t = |z: &[DVec3]| -> Vec<DVec3> {
        let mut cur = z.to_vec();
        for t in tables.iter().rev() {
            let mut out = vec![DVec3::ZERO; t.num_sources as usize];
            for (r, &zr) in cur.iter().enumerate().take(t.len()) {
                let (a, b) = (t.offsets[r] as usize, t.offsets[r + 1] as usize);
                for (&k, &w) in t.indices[a..b].iter().zip(&t.weights[a..b]) {
                    out[k as usize] += w * zr;
                }
            }
            cur = out;
        }
        cur
    };
    let dot = |a: &[DVec3], b: &[DVec3]| -> DVec3 { a.iter().zip(b).map(|(x, y)| *x * *y).sum() };
    let mut x = y[..v0].to_vec();
    let ax = apply(&x);
    let mut r: Vec<DVec3> = y.iter().zip(&ax).map(|(a, b)| *a - *b).collect();
    let mut s = apply_t(&r);
    let mut p = s.clone();
    let mut gamma = dot(&s, &s);
    let tol = gamma * 1e-20;
    for _ in 0..400 {
        if gamma.cmple(tol).all() {
            break;
        }
        let q = apply(&p);
        let qq = dot(&q, &q);
        let alpha = DVec3::select(qq.cmpgt(DVec3::ZERO), gamma / qq, DVec3::ZERO);
        for (xi, pi) in x.iter_mut().zip(&p) {
            *xi += alpha * *pi;
        }
        for (ri, qi) in r.iter_mut().zip(&q) {
            *ri -= alpha * *qi;
        }
        s = apply_t(&r);
        let g2 = dot(&s, &s);
        let beta = DVec3::select(gamma.cmpgt(DVec3::ZERO), g2 / gamma, DVec3::ZERO);
        for (pi, si) in p.iter_mut().zip(&s) {
            *pi = *si + beta * *pi;
        }
        gamma = g2;
    }
    x
}

/// What [`encode`] produces.
pub(crate) struct Encoded {
    /// The base chunk.
    pub base: Vec<u8>,
    /// One chunk per level.
    pub levels: Vec<Vec<u8>>,
    /// The hierarchy in the stream's order (base renumbered by the base-mesh coder).
    pub hierarchy: Hierarchy,
    /// Bit length − 1 of the largest residual per component (−1: all zero), for the header.
    pub top: [i32; 3],
    /// Whether the stream has a reference surface (flag of the header).
    pub reference: bool,
}

/// The base integers in the original base order, coded by the base-mesh coder (whose order,
/// from the faces only, is the re-indexed one).
fn base_chunk(original_base: &Mesh, vertex_map: &[u32], q: &[[i64; 3]]) -> Result<Vec<u8>> {
    let mut q_orig = vec![[0i64; 3]; q.len()];
    for (i, &v) in vertex_map.iter().enumerate() {
        q_orig[v as usize] = q[i];
    }
    let enc = basemesh::encode_integers(original_base, &q_orig)?;
    if enc.vertex_map != vertex_map {
        return Err(Error::InvalidArgument(
            "the base-mesh coder's order changed between two runs".into(),
        ));
    }
    Ok(enc.bytes)
}

fn update_top(top: &mut [i32; 3], d: &[[i64; 3]]) -> Result<()> {
    for d in d {
        for c in 0..3 {
            if d[c].unsigned_abs() >= 1 << 31 {
                return Err(Error::InvalidArgument(
                    "an integer residual exceeds 2^31; use fewer bits".into(),
                ));
            }
            top[c] = top[c].max(bitlen(d[c].unsigned_abs()) as i32 - 1);
        }
    }
    Ok(())
}

/// Encodes hierarchy `reindexed` (already in the base coder's order; `vertex_map` maps its
/// base vertices to `original_base`'s, whose faces the base coder traverses) on `grid`.
/// Triangle hierarchies try the plain interpolating stream and reference streams and keep
/// the smallest.
///
/// # Errors
/// [`Error::InvalidArgument`] if a quantized coordinate exceeds [`MAX_COORD`] or a residual
/// `2^31`; errors of the transforms and of [`basemesh::encode_integers`].
pub(crate) fn encode(
    reindexed: Hierarchy,
    original_base: &Mesh,
    vertex_map: &[u32],
    grid: &Grid,
    degree: Degree,
) -> Result<Encoded> {
    let nh = reindexed;
    let q: Vec<[i64; 3]> = nh
        .positions
        .iter()
        .map(|&p| grid.quantize(p).map(i64::from))
        .collect();
    if let Some(i) = q.iter().position(|x| x.iter().any(|c| c.abs() > MAX_COORD)) {
        return Err(Error::InvalidArgument(format!(
            "vertex {i}: quantized coordinate beyond ±2^40"
        )));
    }
    let mut base_mesh = original_base.clone();
    base_mesh.edge_tags.clear();
    base_mesh.vertex_tags.clear();
    if nh.split != Split::Triangles {
        let (base, levels, top) = encode_quad(&nh, &base_mesh, vertex_map, q, degree)?;
        return Ok(Encoded {
            base,
            levels,
            hierarchy: nh,
            top,
            reference: false,
        });
    }
    let mut new_base = nh.base.clone();
    new_base.edge_tags.clear();
    new_base.vertex_tags.clear();
    let mut pred = TriPredictors::new(&nh, &new_base, true, true)?;
    let mut best = encode_tri(&nh, &base_mesh, vertex_map, &q, &pred, None)?;
    // Reference streams: control points of the least-squares Loop or butterfly surface.
    let y: Vec<DVec3> = nh
        .positions
        .iter()
        .map(|&p| (p - grid.origin) / grid.step)
        .collect();
    let size = |e: &(Vec<u8>, Vec<Vec<u8>>, [i32; 3], bool)| {
        e.0.len() + e.1.iter().map(Vec::len).sum::<usize>()
    };
    for (si, &scheme) in REFERENCE_SCHEMES.iter().enumerate() {
        let Ok(tables) = scheme_tables(&nh, &new_base, scheme) else {
            continue;
        };
        let x0 = fit_control_points(&tables.stencils, &y, nh.num_vertices(0));
        for k in REFERENCE_BITS[si] {
            let s = (1u64 << k) as f64;
            let xi: Vec<[i64; 3]> = x0
                .iter()
                .map(|p| {
                    let m = (*p * s).round();
                    [m.x, m.y, m.z].map(|c| c.clamp(-(MAX_COORD as f64), MAX_COORD as f64) as i64)
                })
                .collect();
            let tag = k | (si as u8) << 4;
            pred.reference = Some(reference_surface(&nh, &new_base, &xi, tag)?);
            let r = encode_tri(&nh, &base_mesh, vertex_map, &q, &pred, Some((tag, &xi)))?;
            if size(&r) < size(&best) {
                best = r;
            }
        }
    }
    let (base, levels, top, reference) = best;
    Ok(Encoded {
        base,
        levels,
        hierarchy: nh,
        top,
        reference,
    })
}

/// A triangle stream: plain (base = the finest positions of the base vertices) or with a
/// reference surface (`reference`: extra bits `k` and the control points; base chunk =
/// `k` then the control points; level 0 starts with the base vertices' residuals).
#[allow(clippy::type_complexity)]
fn encode_tri(
    nh: &Hierarchy,
    base_mesh: &Mesh,
    vertex_map: &[u32],
    q: &[[i64; 3]],
    pred: &TriPredictors,
    reference: Option<(u8, &[[i64; 3]])>,
) -> Result<(Vec<u8>, Vec<Vec<u8>>, [i32; 3], bool)> {
    let l = nh.levels();
    let v0 = nh.num_vertices(0);
    let mut top = [-1i32; 3];
    let mut res = vec![[0i64; 3]; q.len()];
    let mut levels = Vec::with_capacity(l);
    let base = match reference {
        None => base_chunk(base_mesh, vertex_map, &q[..v0])?,
        Some((k, x0)) => {
            let mut b = vec![k];
            b.extend_from_slice(&base_chunk(base_mesh, vertex_map, x0)?);
            b
        }
    };
    let first_coded = if reference.is_some() { 0 } else { v0 };
    let mut kinds = vec![KIND_VECTOR; q.len()];
    for j in 0..l {
        let (vj, n) = (nh.num_vertices(j), nh.num_vertices(j + 1));
        let mut e = Encoder::new();
        if j == 0 && reference.is_some() {
            let p = pred.predict_base(v0);
            let d: Vec<[i64; 3]> = (0..v0)
                .map(|v| [0, 1, 2].map(|c| q[v][c] - p[v].0[c]))
                .collect();
            let ph: Vec<[u8; 3]> = p.iter().map(|x| x.1).collect();
            update_top(&mut top, &d)?;
            let s = Span {
                topo: nh.topology(0),
                first_coded: 0,
                first: 0,
            };
            encode_level(s, &d, &ph, &mut res, &mut e);
        }
        let span = Span {
            topo: nh.topology(j + 1),
            first_coded,
            first: vj,
        };
        let mut best: Option<(usize, u8, Vec<[i64; 3]>, Vec<[u8; 3]>)> = None;
        let mut line: Option<(usize, Vec<LineResidual>)> = None;
        for &m in pred.modes() {
            if m == MODE_LINE {
                let Some(lines) = pred.lines(nh, j, &q[..vj]) else {
                    continue;
                };
                let items = line_residuals(&lines, &q[vj..n]);
                let (mut r, mut k) = (res.clone(), kinds.clone());
                let mut scratch = Encoder::new();
                encode_line_level(span, &items, &mut r, &mut k, &mut scratch);
                line = Some((scratch.finish().len(), items));
                continue;
            }
            let p = pred.predict(m, j, &q[..vj]);
            let d: Vec<[i64; 3]> = (vj..n)
                .map(|v| [0, 1, 2].map(|c| q[v][c] - p[v - vj].0[c]))
                .collect();
            let ph: Vec<[u8; 3]> = p.iter().map(|x| x.1).collect();
            let c = level_cost(span, &d, &ph, &res);
            if best.as_ref().is_none_or(|b| c < b.0) {
                best = Some((c, m, d, ph));
            }
        }
        let Some((cost, m, d, ph)) = best else {
            return Err(Error::InvalidArgument("no predictor".into()));
        };
        let m = match line {
            Some((c, items)) if c < cost => {
                let d: Vec<[i64; 3]> = items.iter().map(|x| x.d).collect();
                update_top(&mut top, &d)?;
                encode_line_level(span, &items, &mut res, &mut kinds, &mut e);
                MODE_LINE
            }
            _ => {
                update_top(&mut top, &d)?;
                encode_level(span, &d, &ph, &mut res, &mut e);
                m
            }
        };
        let mut chunk = vec![m];
        chunk.extend_from_slice(&e.finish());
        levels.push(chunk);
    }
    Ok((base, levels, top, reference.is_some()))
}

/// A quad stream: Bertram's integer lifting, then the details level by level.
#[allow(clippy::type_complexity)]
fn encode_quad(
    nh: &Hierarchy,
    base_mesh: &Mesh,
    vertex_map: &[u32],
    mut data: Vec<[i64; 3]>,
    degree: Degree,
) -> Result<(Vec<u8>, Vec<Vec<u8>>, [i32; 3])> {
    let l = nh.levels();
    let v0 = nh.num_vertices(0);
    let w = BSplineWavelet::new(degree);
    w.analyze_int(&nh.topologies[..l], &mut data)?;
    let mut top = [-1i32; 3];
    update_top(&mut top, &data[v0..])?;
    let base = base_chunk(base_mesh, vertex_map, &data[..v0])?;
    let mut res = vec![[0i64; 3]; data.len()];
    let mut levels = Vec::with_capacity(l);
    for j in 0..l {
        let (vj, n) = (nh.num_vertices(j), nh.num_vertices(j + 1));
        let span = Span {
            topo: nh.topology(j + 1),
            first_coded: v0,
            first: vj,
        };
        let mut e = Encoder::new();
        encode_level(span, &data[vj..n], &vec![[0; 3]; n - vj], &mut res, &mut e);
        let mut chunk = vec![0u8];
        chunk.extend_from_slice(&e.finish());
        levels.push(chunk);
    }
    Ok((base, levels, top))
}

/// What [`decode`] returns.
pub(crate) struct DecodedLevels {
    /// The finest mesh (positions dequantized).
    pub mesh: Mesh,
    /// Bytes of the stream used.
    pub bytes_used: usize,
    /// Levels decoded completely.
    pub levels_complete: u32,
    /// Whether the whole stream was decoded.
    pub complete: bool,
}

fn derr(offset: usize, message: impl Into<String>) -> Error {
    Error::Decode {
        offset,
        message: message.into(),
    }
}

/// The level chunk `j` of a stream (index `j + 1`): its bytes (possibly a prefix, possibly
/// empty) and whether it is whole.
fn level_chunk<'a>(c: &Container, bytes: &'a [u8], j: usize) -> Result<(&'a [u8], bool, usize)> {
    let i = j + 1;
    let e: &ChunkEntry = c
        .chunks
        .get(i)
        .ok_or_else(|| derr(c.header_len, format!("level {j} has no chunk")))?;
    if e.kind != ChunkKind::Level || e.id as usize != j {
        return Err(derr(
            c.header_len,
            format!("{} is not level {j}", e.name(i)),
        ));
    }
    let (chunk, whole) = c.chunk(bytes, i)?;
    Ok((chunk, whole, e.offset as usize))
}

fn check_coords(data: &[[i64; 3]], what: &str) -> Result<()> {
    if data.iter().any(|x| x.iter().any(|c| c.abs() > MAX_COORD)) {
        return Err(derr(
            0,
            format!("{what} decodes to coordinates beyond ±2^40 (corrupt stream)"),
        ));
    }
    Ok(())
}

/// Decodes the chunks of a lossless stream whose header and index `c` are validated
/// (`bytes` may be a prefix): the base, then the level chunks in order. `reference`: the
/// stream has a reference surface (triangles).
///
/// # Errors
/// [`Error::Decode`] for a base chunk that is incomplete, corrupt or does not match the
/// header, a chunk that is not the expected level, an unknown predictor, coordinates
/// beyond [`MAX_COORD`]; a complete chunk failing its CRC (named).
pub(crate) fn decode(
    c: &Container,
    split: Split,
    degree: Degree,
    reference: bool,
    bytes: &[u8],
) -> Result<DecodedLevels> {
    let h = &c.header;
    let entry0 = &c.chunks[0];
    let off = entry0.offset as usize;
    let data0 = c.base_chunk(bytes)?;
    let name0 = entry0.name(0);
    let (k, data0) = if reference {
        match data0.split_first() {
            Some((&k, rest)) if reference_tag(k).is_some() && split == Split::Triangles => {
                (k, rest)
            }
            _ => return Err(derr(off, format!("{name0}: bad reference precision"))),
        }
    } else {
        (0, data0)
    };
    let (mut base, base_q) =
        basemesh::decode_integers(data0).map_err(|e| derr(off, format!("{name0}: {e}")))?;
    c.check_base_counts(
        base.num_vertices(),
        base.num_faces(),
        base.face_indices.len(),
    )?;
    check_coords(&base_q, "the base mesh chunk")?;
    base.edge_tags.clear();
    base.vertex_tags.clear();
    let hier = Hierarchy::new(&base, h.levels as u32, split, None)
        .map_err(|e| derr(off, format!("{name0}: {e}")))?;
    let l = hier.levels();
    let v0 = hier.num_vertices(0);
    let nfine = hier.num_vertices(l);
    let mut data = vec![[0i64; 3]; nfine];
    let mut res = vec![[0i64; 3]; nfine];
    let mut used = off + entry0.len as usize;
    let mut levels_complete = 0u32;
    let mut decoding = true;
    if split == Split::Triangles {
        // Build only the tables the present levels name (and midpoint for the levels a
        // prefix lacks, in plain streams).
        let (mut need_mid, mut need_bfly) = (!reference, false);
        for j in 0..l {
            if let Ok((chunk, _, _)) = level_chunk(c, bytes, j) {
                if let Some(&m) = chunk.first() {
                    let (a, b) = TriPredictors::needs(m);
                    need_mid |= a;
                    need_bfly |= b;
                }
            }
        }
        let mut pred = TriPredictors::new(&hier, &base, need_mid, need_bfly)
            .map_err(|e| derr(off, e.to_string()))?;
        if reference {
            pred.reference = Some(
                reference_surface(&hier, &base, &base_q, k)
                    .map_err(|e| derr(off, e.to_string()))?,
            );
            let p = pred.predict_base(v0);
            for v in 0..v0 {
                data[v] = p[v].0;
            }
        } else {
            data[..v0].copy_from_slice(&base_q);
        }
        let first_coded = if reference { 0 } else { v0 };
        let mut kinds = vec![KIND_VECTOR; nfine];
        for j in 0..l {
            let (vj, n) = (hier.num_vertices(j), hier.num_vertices(j + 1));
            let mut mode = if reference { MODE_REF } else { MODE_MIDPOINT };
            let mut got = 0;
            let mut chunk_info = None;
            if decoding {
                let (chunk, whole, at) = level_chunk(c, bytes, j)?;
                match chunk.split_first() {
                    Some((&m, rest)) if pred.modes().contains(&m) => {
                        mode = m;
                        chunk_info = Some((rest, whole, at, chunk.len()));
                    }
                    Some((&m, _)) => {
                        return Err(derr(at, format!("level {j}: unknown predictor {m}")));
                    }
                    None => decoding = false,
                }
            }
            let mut dec_opt =
                chunk_info.map(|(rest, whole, at, len)| (Decoder::new(rest), whole, at, len));
            if j == 0 && reference {
                if let Some((dec, _, _, _)) = dec_opt.as_mut() {
                    let p = pred.predict_base(v0);
                    let ph: Vec<[u8; 3]> = p.iter().map(|x| x.1).collect();
                    let s = Span {
                        topo: hier.topology(0),
                        first_coded: 0,
                        first: 0,
                    };
                    let g = decode_level(s, &ph, &mut res, dec);
                    for v in 0..g {
                        data[v] = [0, 1, 2].map(|c| p[v].0[c].saturating_add(res[v][c]));
                    }
                    check_coords(&data[..v0], "the base residuals")?;
                    if g < v0 {
                        dec_opt = None;
                        decoding = false;
                    }
                }
            }
            let lines = if mode == MODE_LINE {
                let l = pred.lines(&hier, j, &data[..vj]);
                Some(l.ok_or_else(|| derr(off, "the butterfly tables are missing"))?)
            } else {
                None
            };
            let p = match lines {
                Some(_) => Vec::new(),
                None => pred.predict(mode, j, &data[..vj]),
            };
            if let Some((dec, whole, at, len)) = dec_opt.as_mut() {
                let s = Span {
                    topo: hier.topology(j + 1),
                    first_coded,
                    first: vj,
                };
                got = match &lines {
                    Some(l) => decode_line_level(s, l, &mut res, &mut kinds, &mut data, dec),
                    None => {
                        let ph: Vec<[u8; 3]> = p.iter().map(|x| x.1).collect();
                        decode_level(s, &ph, &mut res, dec)
                    }
                };
                used = *at + *len;
                if got == n - vj && *whole {
                    levels_complete += 1;
                } else {
                    decoding = false;
                }
            }
            match &lines {
                // Line levels wrote their decoded points; the rest get the prediction.
                Some(l) => {
                    for v in vj + got..n {
                        data[v] = normal_line::point(l[v - vj].0, l[v - vj].1, 0);
                    }
                }
                None => {
                    for v in vj..n {
                        let r = if v - vj < got { res[v] } else { [0; 3] };
                        data[v] = [0, 1, 2].map(|c| p[v - vj].0[c].saturating_add(r[c]));
                    }
                }
            }
            check_coords(&data[vj..n], &format!("level {j}"))?;
        }
    } else {
        data[..v0].copy_from_slice(&base_q);
        let w = BSplineWavelet::new(degree);
        for j in 0..l {
            let (vj, n) = (hier.num_vertices(j), hier.num_vertices(j + 1));
            if decoding {
                let (chunk, whole, at) = level_chunk(c, bytes, j)?;
                if let Some((_, rest)) = chunk.split_first() {
                    let s = Span {
                        topo: hier.topology(j + 1),
                        first_coded: v0,
                        first: vj,
                    };
                    let mut dec = Decoder::new(rest);
                    let got = decode_level(s, &vec![[0; 3]; n - vj], &mut res, &mut dec);
                    data[vj..vj + got].copy_from_slice(&res[vj..vj + got]);
                    used = at + chunk.len();
                    if got == n - vj && whole {
                        levels_complete += 1;
                    } else {
                        decoding = false;
                    }
                } else {
                    decoding = false;
                }
            }
            w.synthesize_level_int(&hier.topologies[j], &mut data[..n])
                .map_err(|e| derr(0, format!("integer synthesis of level {j}: {e}")))?;
            check_coords(&data[..n], &format!("level {j}"))?;
        }
    }
    let grid = Grid {
        origin: h.grid_origin,
        step: h.grid_step,
    };
    let positions: Vec<DVec3> = data.iter().map(|&q| grid.dequantize(q)).collect();
    Ok(DecodedLevels {
        mesh: hier.level_mesh(l, positions),
        bytes_used: used.min(bytes.len()),
        levels_complete,
        complete: levels_complete as usize == l,
    })
}

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
//! [`super::container::ChunkKind::Level`], id `j`) holds the details of the odd vertices of
//! level `j + 1` (`V_j..V_{j+1}` in contract order):
//!
//! ```text
//! predictor u8      triangles: 0 midpoint, 1 butterfly (chosen per level by the encoder);
//!                   quads: 0 (the stream's B-spline wavelet)
//! range-coder data  per odd vertex, per component x, y, z: zero flag, sign, |d| − 1
//! ```
//!
//! Each level chunk decodes after the base and the coarser levels only, so any prefix of the
//! stream decodes to the levels it holds exactly (a cut level up to the first missing byte),
//! synthesized to the finest connectivity with zero finer details.
//!
//! # Contexts
//! For odd vertex `v` and component `c`, with `N(v)` its neighbours in the level-`j + 1`
//! mesh: the **expected magnitude** is the mean `|d_c|` of the neighbours already coded at
//! this level (`V_j ≤ w < v`), weighted 2:1 with the mean over those coded at coarser levels
//! (`V_0 ≤ w < V_j`), averaged with the largest `|d|` of the components of `v` already coded.
//! Its bit length selects the class (24 classes). The zero flag is coded in contexts of
//! (level, component, class, phase), the sign in contexts of (level, component, sign of the
//! same-level neighbours' sum, phase), the magnitude with an adaptive Elias-gamma model
//! ([`UInt`]) per (level, component, class). The **phase** is, for unlifted triangle
//! transforms (pure interpolating prediction), where the unrounded prediction falls between
//! two rounding ties ([`IntTriangleWavelet::prediction_phases`]): on exactly subdivided
//! input the detail is the rounding difference, whose zero probability and sign depend on
//! it. Lifted and quad transforms use one phase.
//!
//! # Decoder safety
//! Every count comes from the validated header ([`super::progressive`]); the base chunk's
//! counts are checked against it; decoded coordinates are bounded by [`MAX_COORD`] after
//! every level (a corrupt stream is an error, never an overflow).

use glam::DVec3;

use super::basemesh;
use super::container::{ChunkEntry, ChunkKind, Container};
use super::quantize::Grid;
use super::rangecoder::{Bit, Decoder, Encoder, UInt};
use crate::hierarchy::Hierarchy;
use crate::mesh::Mesh;
use crate::subdivision::refine::Split;
use crate::subdivision::{Scheme, SubdivideOptions};
use crate::topology::Topology;
use crate::wavelet::bertram::{BSplineWavelet, Degree};
use crate::wavelet::triangle_int::{IntTriangleWavelet, MAX_COORD};
use crate::{Error, Result};

/// Prediction of a triangle level: midpoint.
const PRED_MIDPOINT: u8 = 0;
/// Prediction of a triangle level: butterfly.
const PRED_BUTTERFLY: u8 = 1;
/// Magnitude classes.
const CLASSES: usize = 24;
/// Phase bins ([`IntTriangleWavelet::prediction_phases`]).
const PHASES: usize = 8;

/// The integer transform of a lossless stream, applied level by level.
pub(crate) enum Transform<'h> {
    /// Triangle hierarchies: midpoint and butterfly (chosen per level), lifted or not.
    Tri {
        h: &'h Hierarchy,
        lifted: bool,
        mid: Option<IntTriangleWavelet<'h>>,
        bfly: Option<IntTriangleWavelet<'h>>,
    },
    /// Quad hierarchies: Bertram's integer B-spline lifting.
    Quad(BSplineWavelet, &'h [Topology]),
}

impl<'h> Transform<'h> {
    /// The transform of `h`: B-spline of `degree` on quad hierarchies, else the triangle
    /// wavelets (built when first needed).
    pub(crate) fn new(h: &'h Hierarchy, degree: Degree, lifted: bool) -> Self {
        if h.split == Split::Triangles {
            Transform::Tri {
                h,
                lifted,
                mid: None,
                bfly: None,
            }
        } else {
            Transform::Quad(BSplineWavelet::new(degree), &h.topologies[..h.levels()])
        }
    }

    /// Whether the transform has prediction phases (unlifted triangles).
    fn phased(&self) -> bool {
        matches!(self, Transform::Tri { lifted: false, .. })
    }

    /// The predictors a level may use.
    fn candidates(&self) -> &'static [u8] {
        match self {
            Transform::Tri { .. } => &[PRED_MIDPOINT, PRED_BUTTERFLY],
            Transform::Quad(..) => &[0],
        }
    }

    fn tri(&mut self, pred: u8) -> Result<&IntTriangleWavelet<'h>> {
        let Transform::Tri {
            h,
            lifted,
            mid,
            bfly,
        } = self
        else {
            return Err(Error::InvalidArgument("not a triangle transform".into()));
        };
        let (slot, scheme) = match pred {
            PRED_MIDPOINT => (mid, Scheme::Midpoint),
            PRED_BUTTERFLY => (bfly, Scheme::Butterfly),
            p => return Err(Error::InvalidArgument(format!("unknown predictor {p}"))),
        };
        if slot.is_none() {
            let opts = SubdivideOptions {
                scheme,
                ..Default::default()
            };
            *slot = Some(IntTriangleWavelet::from_scheme(h, &opts, *lifted)?);
        }
        slot.as_ref()
            .ok_or_else(|| Error::InvalidArgument("triangle wavelet".into()))
    }

    /// One analysis step of level `j` (on `V_{j+1}` values).
    fn forward_level(&mut self, pred: u8, j: usize, data: &mut [[i64; 3]]) -> Result<()> {
        match self {
            Transform::Quad(w, levels) => w.analyze_level_int(&levels[j], data),
            Transform::Tri { .. } => {
                self.tri(pred)?.forward_level(j, data);
                Ok(())
            }
        }
    }

    /// One synthesis step of level `j` (on `V_{j+1}` values).
    fn inverse_level(&mut self, pred: u8, j: usize, data: &mut [[i64; 3]]) -> Result<()> {
        match self {
            Transform::Quad(w, levels) => w.synthesize_level_int(&levels[j], data),
            Transform::Tri { .. } => {
                self.tri(pred)?.inverse_level(j, data);
                Ok(())
            }
        }
    }

    /// Prediction phases of level `j`'s odd vertices from the even values (unlifted
    /// triangles), else all zero.
    fn phases(&mut self, pred: u8, j: usize, even: &[[i64; 3]], n: usize) -> Result<Vec<[u8; 3]>> {
        if self.phased() {
            Ok(self.tri(pred)?.prediction_phases(j, even))
        } else {
            Ok(vec![[0; 3]; n])
        }
    }
}

/// The adaptive models of one level.
struct Models {
    zero: Vec<Bit>,
    sign: Vec<Bit>,
    mags: Vec<UInt>,
}

impl Models {
    fn new() -> Self {
        Models {
            zero: vec![Bit::new(); 3 * CLASSES * PHASES],
            sign: vec![Bit::new(); 3 * 3 * PHASES],
            mags: vec![UInt::new(); 3 * CLASSES],
        }
    }
}

/// Bit length of `x`.
#[inline]
fn bitlen(x: u64) -> usize {
    (64 - x.leading_zeros()) as usize
}

/// The neighbourhood statistics of odd vertex `v` of level `j + 1`: per component the sum of
/// `|d|` and count of same-level and coarser-level coded neighbours, and the sign of the
/// same-level neighbours' sum.
struct Context {
    /// Expected magnitude ×16 per component from the neighbours (`None`: no neighbour).
    expect: Option<[u64; 3]>,
    sign: [usize; 3],
}

fn context(fine: &Topology, v: usize, v0: usize, vj: usize, res: &[[i64; 3]]) -> Context {
    let (mut ss, mut sc) = ([0u64; 3], [0u64; 3]);
    let (mut ns, mut nc) = (0u64, 0u64);
    let mut sg = [0i64; 3];
    for &e in fine.vertex_edges(v) {
        let w = fine.other_vertex(e as usize, v as u32) as usize;
        if w >= v || w < v0 {
            continue;
        }
        let r = res[w];
        if w >= vj {
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

/// Codes the details `d` (odd vertices `V_j..V_{j+1}`) of level `j`.
fn encode_level(
    fine: &Topology,
    v0: usize,
    vj: usize,
    details: &[[i64; 3]],
    phases: &[[u8; 3]],
    res: &mut [[i64; 3]],
    enc: &mut Encoder,
) {
    let mut m = Models::new();
    for (i, d) in details.iter().enumerate() {
        let v = vj + i;
        let ctx = context(fine, v, v0, vj, res);
        for c in 0..3 {
            let k = class(&ctx, c, d);
            let ph = phases[i][c] as usize;
            let x = d[c];
            enc.bit(&mut m.zero[(c * CLASSES + k) * PHASES + ph], x == 0);
            if x != 0 {
                enc.bit(&mut m.sign[(c * 3 + ctx.sign[c]) * PHASES + ph], x < 0);
                m.mags[c * CLASSES + k].encode(enc, (x.unsigned_abs() - 1) as u32);
            }
        }
        res[v] = *d;
    }
}

/// Decodes level `j`'s details into `res[V_j..]` (and returns how many vertices decoded
/// before the data ran out).
fn decode_level(
    fine: &Topology,
    v0: usize,
    vj: usize,
    phases: &[[u8; 3]],
    res: &mut [[i64; 3]],
    dec: &mut Decoder,
) -> usize {
    let mut m = Models::new();
    for (i, ph) in phases.iter().enumerate() {
        let v = vj + i;
        let ctx = context(fine, v, v0, vj, res);
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
        if dec.truncated() {
            return i;
        }
        res[v] = d;
    }
    phases.len()
}

/// A cost estimate of a level's details (bits of an Elias-gamma code), for the choice of
/// predictor.
fn cost(details: &[[i64; 3]]) -> u64 {
    details
        .iter()
        .flat_map(|d| d.iter())
        .map(|&x| 2 * bitlen(x.unsigned_abs()) as u64 + 1)
        .sum()
}

/// What [`encode`] produces.
pub(crate) struct Encoded {
    /// The base chunk (a [`basemesh`] integer stream).
    pub base: Vec<u8>,
    /// One chunk per level.
    pub levels: Vec<Vec<u8>>,
    /// The hierarchy in the stream's order (base renumbered by the base-mesh coder).
    pub hierarchy: Hierarchy,
    /// Bit length − 1 of the largest detail per component (−1: all zero), for the header.
    pub top: [i32; 3],
}

/// Encodes hierarchy `h` (already re-indexed to the base coder's order, `reindexed`) on
/// `grid`. `plain` is the base coder's vertex map of `h.base` (decoded vertex `i` is base
/// vertex `vertex_map[i]` of the original hierarchy), `original_base` that base's faces.
///
/// # Errors
/// [`Error::InvalidArgument`] if a quantized coordinate exceeds [`MAX_COORD`] or a detail
/// `2^31`; errors of the transforms and of [`basemesh::encode_integers`].
pub(crate) fn encode(
    reindexed: Hierarchy,
    original_base: &Mesh,
    vertex_map: &[u32],
    grid: &Grid,
    degree: Degree,
    lifted: bool,
) -> Result<Encoded> {
    let nh = reindexed;
    let l = nh.levels();
    let v0 = nh.num_vertices(0);
    let mut data: Vec<[i64; 3]> = nh
        .positions
        .iter()
        .map(|&p| grid.quantize(p).map(i64::from))
        .collect();
    if let Some(i) = data
        .iter()
        .position(|x| x.iter().any(|c| c.abs() > MAX_COORD))
    {
        return Err(Error::InvalidArgument(format!(
            "vertex {i}: quantized coordinate beyond ±2^40"
        )));
    }
    let mut t = Transform::new(&nh, degree, lifted);
    let mut preds = vec![0u8; l];
    let mut phases: Vec<Vec<[u8; 3]>> = vec![Vec::new(); l];
    for j in (0..l).rev() {
        let (vj, n) = (nh.num_vertices(j), nh.num_vertices(j + 1));
        let mut best: Option<(u64, u8, Vec<[i64; 3]>)> = None;
        for &p in t.candidates() {
            let mut tmp = data[..n].to_vec();
            t.forward_level(p, j, &mut tmp)?;
            let c = cost(&tmp[vj..]);
            if best.as_ref().is_none_or(|b| c < b.0) {
                best = Some((c, p, tmp));
            }
        }
        let Some((_, p, tmp)) = best else {
            return Err(Error::InvalidArgument("no predictor".into()));
        };
        // Phases from the even values before this level's analysis (unlifted: unchanged).
        phases[j] = t.phases(p, j, &data[..vj], n - vj)?;
        data[..n].copy_from_slice(&tmp);
        preds[j] = p;
    }
    let mut top = [-1i32; 3];
    for d in &data[v0..] {
        for c in 0..3 {
            if d[c].unsigned_abs() >= 1 << 31 {
                return Err(Error::InvalidArgument(
                    "an integer detail exceeds 2^31; use fewer bits".into(),
                ));
            }
            top[c] = top[c].max(bitlen(d[c].unsigned_abs()) as i32 - 1);
        }
    }
    // Base chunk: the base integers in the original base order, coded by the base-mesh
    // coder, whose order (faces only) is the re-indexed one.
    let mut q_orig = vec![[0i64; 3]; v0];
    for (i, &v) in vertex_map.iter().enumerate() {
        q_orig[v as usize] = data[i];
    }
    let mut base_mesh = original_base.clone();
    base_mesh.edge_tags.clear();
    base_mesh.vertex_tags.clear();
    let enc = basemesh::encode_integers(&base_mesh, &q_orig)?;
    if enc.vertex_map != vertex_map {
        return Err(Error::InvalidArgument(
            "the base-mesh coder's order changed between two runs".into(),
        ));
    }
    let mut res = vec![[0i64; 3]; data.len()];
    let mut levels = Vec::with_capacity(l);
    for j in 0..l {
        let (vj, n) = (nh.num_vertices(j), nh.num_vertices(j + 1));
        let mut e = Encoder::new();
        encode_level(
            nh.topology(j + 1),
            v0,
            vj,
            &data[vj..n],
            &phases[j],
            &mut res,
            &mut e,
        );
        let mut chunk = vec![preds[j]];
        chunk.extend_from_slice(&e.finish());
        levels.push(chunk);
    }
    Ok(Encoded {
        base: enc.bytes,
        levels,
        hierarchy: nh,
        top,
    })
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

/// Decodes the chunks of a lossless stream whose header and index `c` are validated
/// (`bytes` may be a prefix): the base, then the level chunks in order.
///
/// # Errors
/// [`Error::Decode`] for a base chunk that is incomplete, corrupt or does not match the
/// header, a chunk that is not the expected level, an unknown predictor, coordinates
/// beyond [`MAX_COORD`]; a complete chunk failing its CRC (named).
pub(crate) fn decode(
    c: &Container,
    split: Split,
    degree: Degree,
    lifted: bool,
    bytes: &[u8],
) -> Result<DecodedLevels> {
    let h = &c.header;
    let entry0 = &c.chunks[0];
    let off = entry0.offset as usize;
    let (data0, whole) = c.chunk(bytes, 0)?;
    if !whole {
        return Err(derr(
            bytes.len(),
            format!(
                "stream truncated in the base mesh chunk (the first {} bytes are needed)",
                entry0.offset + entry0.len as u64
            ),
        ));
    }
    let (mut base, base_q) = basemesh::decode_integers(data0)
        .map_err(|e| derr(off, format!("{}: {e}", entry0.name(0))))?;
    if base.num_vertices() != h.base_vertices as usize
        || base.num_faces() != h.base_faces as usize
        || base.face_indices.len() != h.base_corners as usize
    {
        return Err(derr(
            off,
            "the base mesh chunk does not match the header's base counts",
        ));
    }
    if base_q.iter().any(|x| x.iter().any(|c| c.abs() > MAX_COORD)) {
        return Err(derr(off, "base mesh chunk: coordinates beyond ±2^40"));
    }
    base.edge_tags.clear();
    base.vertex_tags.clear();
    let hier = Hierarchy::new(&base, h.levels as u32, split, None)
        .map_err(|e| derr(off, format!("base mesh chunk: {e}")))?;
    let l = hier.levels();
    let v0 = hier.num_vertices(0);
    let nfine = hier.num_vertices(l);
    let mut data = vec![[0i64; 3]; nfine];
    data[..v0].copy_from_slice(&base_q);
    let mut res = vec![[0i64; 3]; nfine];
    let mut t = Transform::new(&hier, degree, lifted);
    let mut used = off + data0.len();
    let mut levels_complete = 0u32;
    let mut decoding = true;
    for j in 0..l {
        let (vj, n) = (hier.num_vertices(j), hier.num_vertices(j + 1));
        let i = j + 1;
        let mut pred = 0u8;
        if decoding {
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
            if let Some((&p, rest)) = chunk.split_first() {
                if !t.candidates().contains(&p) {
                    return Err(derr(
                        e.offset as usize,
                        format!("{}: unknown predictor {p}", e.name(i)),
                    ));
                }
                pred = p;
                let phases = t.phases(p, j, &data[..vj], n - vj)?;
                let mut dec = Decoder::new(rest);
                let got = decode_level(hier.topology(j + 1), v0, vj, &phases, &mut res, &mut dec);
                data[vj..vj + got].copy_from_slice(&res[vj..vj + got]);
                used = e.offset as usize + chunk.len();
                if got == n - vj && whole {
                    levels_complete += 1;
                } else {
                    decoding = false;
                }
            } else {
                decoding = false;
            }
        }
        // Without a chunk the level keeps zero details; its predictor is then the first
        // candidate (the decoded mesh is an approximation anyway).
        t.inverse_level(pred, j, &mut data[..n])
            .map_err(|e| derr(0, format!("integer synthesis of level {j}: {e}")))?;
        if data[..n]
            .iter()
            .any(|x| x.iter().any(|c| c.abs() > MAX_COORD))
        {
            return Err(derr(
                0,
                format!("level {j} decodes to coordinates beyond ±2^40 (corrupt stream)"),
            ));
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

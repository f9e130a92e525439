//! Direct streams: an irregular mesh coded as it is — the single-rate base-mesh coder at a
//! coarse precision, then one refinement chunk per further bit of precision — for inputs
//! that a remesh does not serve.
//!
//! A remesh pays where the input is densely sampled: its semi-regular connectivity costs
//! nothing and its wavelet coefficients are small (stanford-bunny, 35k vertices: 0.21× Draco's
//! bytes at 69 dB). A low-poly mesh (a few thousand vertices or fewer, flat facets meeting at
//! sharp edges) is the opposite case: the remesh must sample every facet finely to follow its
//! edges, and its stream ends up many times larger than the input coded directly. Measured
//! 2026-12-06 (`subwave eval`, bytes over Draco 1.5's at equal PSNR): cow (2.9k vertices) 1.1×
//! at 64 dB to 14× at the remesh's top (84.5 dB, 112 KB); beetle (1.2k) 2× at 64 dB to 35×;
//! suzanne (507) 4.6× at 66 dB, topping out at 70 dB with 32 KB where Draco reaches 101 dB
//! with 2 KB.
//!
//! A direct stream codes the mesh itself, progressively in precision (the "successive
//! refinement of positions" of single-rate coders; Maret 2003 §4.5 codes base meshes this
//! way at a fixed precision):
//!
//! 1. positions quantized on a grid of `2^B − 1` steps over the longest side of the bounding
//!    box ([`Grid`], `B` = header `bits`);
//! 2. the base chunk: the length (`u32`, little endian) of a base-mesh stream of the faces
//!    and the coarse integers `q >> (B − b₀)` (`b₀` = header `base_bits`) by the base-mesh
//!    coder's integer API ([`basemesh::encode_integers`]: valence-driven connectivity,
//!    parallelogram prediction, crease flags), which renumbers the vertices and may rotate
//!    faces; that stream; then, range coded, per quad one bit (rotate by one corner or not:
//!    a rotation by two keeps a quad's diagonal) and per larger polygon its rotation, which
//!    give every polygon its input's fan triangulation back (a non-planar polygon's surface,
//!    as viewers and the distance triangulate it, depends on its first corner);
//! 3. `B − b₀` plane chunks (kind [`ChunkKind::Plane`], id `p`): bit `B − b₀ − 1 − p` of every
//!    coordinate, vertex by vertex in the decoded order, each a binary decision of the range
//!    coder in a context of where the mean of the vertex's neighbours (their positions at the
//!    start of the plane) falls in the vertex's current interval (eight bins) — on a smooth dense
//!    mesh the neighbours predict the top planes' bits well; on a coarse one the contexts
//!    learn that they do not and cost about one bit.
//!
//! Header: `levels` 0, flags `F_BASEMESH | F_DIRECT` of [`super::progressive`], `top` −1.
//! Any prefix holding the header, the index and the base chunk decodes: every vertex at the
//! precision of the planes it has, the unknown low bits at mid-interval. The full stream
//! reproduces the `B`-bit grid positions exactly (a lossless stream of the input at `B`
//! bits).
//!
//! # Decoder safety
//! The base chunk's counts must match the header's (which [`super::progressive`] bounds by
//! the stream size before anything is allocated), its inner length must fit in it, rotations
//! must be smaller than their polygon's corner count, coarse integers must lie in
//! `0..2^b₀`, `8 ≤ b₀ ≤ B ≤ 30`; a cut plane decodes up to the last vertex whose three bits
//! it holds.

use glam::DVec3;
use rayon::prelude::*;

use super::basemesh;
use super::container::{ChunkKind, Container};
use super::quantize::Grid;
use super::rangecoder::{Bit, Decoder, Encoder, UInt};
use crate::distance::{psnr, rms_to, sample_surface, sampled_rms_to, ClosestPoint};
use crate::mesh::Mesh;
use crate::{Error, Result};

/// Default precision `B` of a direct stream (bits per coordinate over the longest side of
/// the bounding box): about 100 dB from the input, Draco's finest usual setting.
pub const DEFAULT_BITS: u32 = 14;
/// Precision `b₀` of a direct stream's base chunk (the first decodable prefix, about 64 dB
/// from the input).
pub const COARSE_BITS: u32 = 8;
/// Area samples per surface of [`compare`]'s distances.
pub const COMPARE_SAMPLES: usize = 10_000;

/// Neighbour-prediction bins of a refinement bit ([`bin`]).
const BINS: usize = 8;
/// Plane classes of the contexts: the first plane, the second, the rest.
const PLANE_CLASSES: usize = 3;

/// Options of [`encode`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DirectOptions {
    /// Precision `B` of the full stream (`coarse_bits..=30`).
    pub bits: u32,
    /// Precision `b₀` of the base chunk (`8..=bits`).
    pub coarse_bits: u32,
    /// Vertices of the mesh the stream stands for (header, for rates); `None`: the mesh's.
    pub input_vertices: Option<u32>,
}

impl Default for DirectOptions {
    fn default() -> Self {
        DirectOptions {
            bits: DEFAULT_BITS,
            coarse_bits: COARSE_BITS,
            input_vertices: None,
        }
    }
}

/// What a decoder needs of a direct stream's header (parsed by [`super::progressive`]).
pub(crate) struct Params {
    /// `B`.
    pub bits: u32,
    /// `b₀`.
    pub coarse_bits: u32,
}

/// The context bin of the next bit of a coordinate whose interval is `[lo, lo + 2^r)`
/// (fine-grid units, `r ≥ 1` bits unknown), given the neighbours' prediction `pred`: which
/// quarter of the interval `pred` falls in, or whether it is within half an interval below
/// or above it, or further (a non-finite prediction counts as the second quarter).
#[inline]
fn bin(pred: f64, lo: u64, r: u32) -> usize {
    let u = (pred - lo as f64) / (1u64 << r) as f64;
    if !u.is_finite() {
        return 3;
    }
    match u {
        u if u < -0.5 => 0,
        u if u < 0.0 => 1,
        u if u < 0.25 => 2,
        u if u < 0.5 => 3,
        u if u < 0.75 => 4,
        u if u < 1.0 => 5,
        u if u < 1.5 => 6,
        _ => 7,
    }
}

/// The vertex neighbours of `mesh` (consecutive corners of its faces), as CSR offsets and
/// indices, each neighbour once.
fn neighbours(mesh: &Mesh) -> (Vec<u32>, Vec<u32>) {
    let n = mesh.num_vertices();
    let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(2 * mesh.face_indices.len());
    for f in mesh.faces() {
        for (i, &a) in f.iter().enumerate() {
            let b = f[(i + 1) % f.len()];
            if a != b {
                pairs.push((a, b));
                pairs.push((b, a));
            }
        }
    }
    pairs.par_sort_unstable();
    pairs.dedup();
    let mut off = vec![0u32; n + 1];
    for &(a, _) in &pairs {
        off[a as usize + 1] += 1;
    }
    for i in 0..n {
        off[i + 1] += off[i];
    }
    (off, pairs.into_iter().map(|(_, b)| b).collect())
}

/// The refinement state shared by the encoder and the decoder: per vertex and coordinate the
/// known high bits (`known[v] >> r` with `r` = `rem[v]` bits still unknown).
struct Refiner {
    off: Vec<u32>,
    adj: Vec<u32>,
    /// Known high bits, shifted into place (the unknown low bits zero).
    known: Vec<[u64; 3]>,
    /// Unknown low bits per vertex.
    rem: Vec<u32>,
    models: Vec<Bit>,
}

impl Refiner {
    fn new(mesh: &Mesh, coarse: &[[u64; 3]], shift: u32) -> Refiner {
        let (off, adj) = neighbours(mesh);
        Refiner {
            off,
            adj,
            known: coarse.iter().map(|q| q.map(|x| x << shift)).collect(),
            rem: vec![shift; coarse.len()],
            models: vec![Bit::new(); BINS * PLANE_CLASSES * 3],
        }
    }

    /// Mid-interval positions in fine-grid units.
    fn estimates(&self) -> Vec<DVec3> {
        self.known
            .par_iter()
            .zip(&self.rem)
            .map(|(k, &r)| {
                let half = ((1u64 << r) - 1) as f64 / 2.0;
                DVec3::new(k[0] as f64 + half, k[1] as f64 + half, k[2] as f64 + half)
            })
            .collect()
    }

    /// Neighbour means of `est` (a vertex without neighbours predicts itself).
    fn predictions(&self, est: &[DVec3]) -> Vec<DVec3> {
        (0..est.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|v| {
                let ns = &self.adj[self.off[v] as usize..self.off[v + 1] as usize];
                if ns.is_empty() {
                    return est[v];
                }
                ns.iter().map(|&w| est[w as usize]).sum::<DVec3>() / ns.len() as f64
            })
            .collect()
    }

    fn context(&self, plane: u32, c: usize, pred: f64, lo: u64, r: u32) -> usize {
        let class = (plane as usize).min(PLANE_CLASSES - 1);
        (class * 3 + c) * BINS + bin(pred, lo, r)
    }
}

/// Encodes `mesh` as a direct stream (see the module documentation).
///
/// `mesh` must be what the base-mesh coder takes: a consistently oriented 2-manifold
/// (boundaries allowed) without unreferenced vertices; [`codable`] repairs one that is not.
///
/// # Errors
/// [`Error::InvalidArgument`] for `opts` out of range, a non-finite coordinate or a mesh
/// without faces; the base-mesh coder's [`Error::Mesh`] for a mesh it cannot code.
pub fn encode(mesh: &Mesh, opts: &DirectOptions) -> Result<Vec<u8>> {
    if !(8..=30).contains(&opts.coarse_bits) || !(opts.coarse_bits..=30).contains(&opts.bits) {
        return Err(Error::InvalidArgument(format!(
            "direct stream precision: need 8 ≤ coarse bits ({}) ≤ bits ({}) ≤ 30",
            opts.coarse_bits, opts.bits
        )));
    }
    if mesh.num_faces() == 0 {
        return Err(Error::InvalidArgument(
            "the mesh has no faces: nothing to code".to_string(),
        ));
    }
    if let Some(v) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::InvalidArgument(format!(
            "vertex {v} has a non-finite coordinate"
        )));
    }
    let bb = super::progressive::bbox(&mesh.positions);
    let grid = Grid::new(bb[0], bb[1], opts.bits);
    let shift = opts.bits - opts.coarse_bits;
    // On the grid of the box's minimum corner every coordinate is in 0..2^B.
    let q: Vec<[u64; 3]> = mesh
        .positions
        .iter()
        .map(|&p| grid.quantize(p).map(|x| x.max(0) as u64))
        .collect();
    let coarse: Vec<[i64; 3]> = q.iter().map(|x| x.map(|c| (c >> shift) as i64)).collect();
    let mut enc = basemesh::encode_integers(mesh, &coarse)?;
    // The decoder's vertex order.
    let q: Vec<[u64; 3]> = enc.vertex_map.iter().map(|&v| q[v as usize]).collect();
    let coarse: Vec<[u64; 3]> = q.iter().map(|x| x.map(|c| c >> shift)).collect();
    // The base chunk: the base-mesh stream's length (u32, little endian), the stream, then
    // the rotations that give each decoded polygon its input's fan triangulation back (the
    // base-mesh coder may rotate faces; a non-planar polygon's fan from its first corner,
    // which viewers and the distance use, depends on that corner): per quad one bit (a
    // rotation by two corners keeps its diagonal), per larger polygon the rotation that
    // brings its input's first corner back.
    let mut to_decoded = vec![0u32; mesh.num_vertices()];
    for (i, &v) in enc.vertex_map.iter().enumerate() {
        to_decoded[v as usize] = i as u32;
    }
    let mut rot = Encoder::new();
    let mut rot_model: UInt = UInt::new();
    let mut quad_model = Bit::new();
    let mut faces = Vec::with_capacity(enc.decoded.face_indices.len());
    for (i, f) in enc.decoded.faces().enumerate() {
        let first = to_decoded[mesh.face(enc.face_map[i] as usize)[0] as usize];
        let mut r = f.iter().position(|&v| v == first).unwrap_or(0);
        match f.len() {
            3 => r = 0,
            4 => {
                r %= 2;
                rot.bit(&mut quad_model, r == 1);
            }
            _ => rot_model.encode(&mut rot, r as u32),
        }
        faces.extend(f[r..].iter().chain(&f[..r]).copied());
    }
    enc.decoded.face_indices = faces;
    let mut base = (enc.bytes.len() as u32).to_le_bytes().to_vec();
    base.extend_from_slice(&enc.bytes);
    base.extend_from_slice(&rot.finish());
    let mut chunks = vec![(ChunkKind::Base, 0u32, base, Vec::new())];
    let mut r = Refiner::new(&enc.decoded, &coarse, shift);
    for plane in 0..shift {
        let est = r.estimates();
        let pred = r.predictions(&est);
        let mut e = Encoder::new();
        for (v, x) in q.iter().enumerate() {
            let rv = r.rem[v];
            for c in 0..3 {
                let bit = (x[c] >> (rv - 1)) & 1 == 1;
                let ctx = r.context(plane, c, pred[v][c], r.known[v][c], rv);
                e.bit(&mut r.models[ctx], bit);
                r.known[v][c] |= u64::from(bit) << (rv - 1);
            }
            r.rem[v] = rv - 1;
        }
        chunks.push((ChunkKind::Plane, plane, e.finish(), Vec::new()));
    }
    let split = if mesh.faces().all(|f| f.len() == 3) {
        0
    } else {
        1
    };
    super::progressive::write_direct(
        &enc.decoded,
        split,
        opts,
        bb,
        &grid,
        mesh.num_vertices(),
        &chunks,
    )
}

/// A decoded direct stream: the mesh, the bytes used, the complete planes and whether the
/// whole stream was decoded.
pub(crate) struct DecodedDirect {
    pub mesh: Mesh,
    pub bytes_used: usize,
    pub planes_complete: u32,
    pub planes: u32,
    pub complete: bool,
}

fn derr(offset: usize, msg: impl Into<String>) -> Error {
    Error::Decode {
        offset,
        message: msg.into(),
    }
}

/// Decodes the direct stream `bytes` (a prefix, possibly) whose container `c` the caller
/// parsed.
pub(crate) fn decode(c: &Container, params: &Params, bytes: &[u8]) -> Result<DecodedDirect> {
    let h = &c.header;
    let (bits, b0) = (params.bits, params.coarse_bits);
    if !(8..=30).contains(&b0) || !(b0..=30).contains(&bits) || h.levels != 0 {
        return Err(derr(
            14,
            format!("direct stream: bad precision (base {b0} bits, full {bits} bits) or levels"),
        ));
    }
    let shift = bits - b0;
    let e0 = &c.chunks[0];
    let off = e0.offset as usize;
    let data0 = c.base_chunk(bytes)?;
    let name0 = e0.name(0);
    let (len, rest) = match data0.split_first_chunk::<4>() {
        Some((l, rest)) if u32::from_le_bytes(*l) as usize <= rest.len() => {
            (u32::from_le_bytes(*l) as usize, rest)
        }
        _ => {
            return Err(derr(
                off,
                format!("{name0}: the base-mesh stream's length is out of the chunk"),
            ))
        }
    };
    let (mut mesh, coarse) =
        basemesh::decode_integers(&rest[..len]).map_err(|e| derr(off, format!("{name0}: {e}")))?;
    // The polygons' rotations (see `encode`).
    let mut d = Decoder::new(&rest[len..]);
    let mut rot_model: UInt = UInt::new();
    let mut quad_model = Bit::new();
    let mut faces = Vec::with_capacity(mesh.face_indices.len());
    for f in mesh.faces() {
        let r = match f.len() {
            3 => 0,
            4 => usize::from(d.bit(&mut quad_model)),
            _ => rot_model.decode(&mut d) as usize,
        };
        if r >= f.len() || d.truncated() {
            return Err(derr(off, format!("{name0}: bad polygon rotations")));
        }
        faces.extend(f[r..].iter().chain(&f[..r]).copied());
    }
    mesh.face_indices = faces;
    c.check_base_counts(
        mesh.num_vertices(),
        mesh.num_faces(),
        mesh.face_indices.len(),
    )?;
    if coarse
        .iter()
        .flatten()
        .any(|&x| !(0..1i64 << b0).contains(&x))
    {
        return Err(derr(
            off,
            format!("{name0}: a coarse coordinate is outside the {b0}-bit grid"),
        ));
    }
    let coarse: Vec<[u64; 3]> = coarse.iter().map(|x| x.map(|c| c as u64)).collect();
    let mut r = Refiner::new(&mesh, &coarse, shift);
    let mut used = off + e0.len as usize;
    let mut planes_complete = 0;
    for plane in 0..shift {
        let i = plane as usize + 1;
        let Some(e) = c.chunks.get(i) else {
            return Err(derr(c.header_len, format!("plane {plane} has no chunk")));
        };
        if e.kind != ChunkKind::Plane || e.id != plane {
            return Err(derr(
                c.header_len,
                format!("{} is not refinement plane {plane}", e.name(i)),
            ));
        }
        let (data, whole) = c.chunk(bytes, i)?;
        if data.is_empty() && !whole {
            break;
        }
        used = e.offset as usize + data.len();
        let est = r.estimates();
        let pred = r.predictions(&est);
        let mut d = Decoder::new(data);
        let mut cut = false;
        for (v, pv) in pred.iter().enumerate() {
            let rv = r.rem[v];
            let mut k = r.known[v];
            for c in 0..3 {
                let ctx = r.context(plane, c, pv[c], k[c], rv);
                let bit = d.bit(&mut r.models[ctx]);
                k[c] |= u64::from(bit) << (rv - 1);
            }
            if d.truncated() {
                cut = true;
                break;
            }
            r.known[v] = k;
            r.rem[v] = rv - 1;
        }
        if cut || !whole {
            break;
        }
        planes_complete += 1;
    }
    let grid = Grid {
        origin: h.grid_origin,
        step: h.grid_step,
    };
    mesh.positions = r
        .estimates()
        .into_iter()
        .map(|x| grid.origin + x * grid.step)
        .collect();
    Ok(DecodedDirect {
        mesh,
        bytes_used: used.min(bytes.len()),
        planes_complete,
        planes: shift,
        complete: planes_complete == shift,
    })
}

/// `mesh` as the base-mesh coder takes it: itself if it is a consistently oriented manifold,
/// else repaired as `subwave compress-base --repair` does (non-manifold vertices and edges
/// split, faces re-oriented; the result is triangulated and loses crease and corner tags),
/// with what the repair did.
///
/// # Errors
/// The repair's errors (a mesh without faces, bad indices).
pub fn codable(mesh: &Mesh) -> Result<(Mesh, Option<crate::remesh::RepairReport>)> {
    let mut m = mesh.clone();
    m.remove_unreferenced();
    let topo = crate::topology::Topology::build(&m);
    if m.check_indices().is_ok() && crate::validate::require_manifold(&topo).is_ok() {
        return Ok((m, None));
    }
    let (pos, tris, report) = crate::remesh::repair::prepare(&m, true)?;
    let mut out = Mesh::from_triangles(pos, &tris);
    out.remove_unreferenced();
    Ok((out, Some(report)))
}

/// Where [`compare`] measured a wavelet stream and a direct stream of the same input: at
/// the direct stream's first decodable prefix (header and base chunk, about 64 dB from the
/// input), two refinement planes later (about 76 dB) and four (about 88 dB), each stream cut
/// at the same byte count — in that order, until one stream is closer at most of them.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// The byte budgets measured.
    pub bytes: Vec<usize>,
    /// PSNR (dB against the input) of the wavelet stream's prefixes (−∞ for a prefix that
    /// ends before its base chunk does: no mesh).
    pub wavelet_psnr: Vec<f64>,
    /// PSNR of the direct stream's prefixes.
    pub direct_psnr: Vec<f64>,
    /// Budgets planned (some are not measured once the majority is decided).
    pub planned: usize,
}

impl Comparison {
    /// Whether the direct stream is closer to the input at most of the planned budgets: then
    /// it serves the input better over the range of qualities a client asks for (measured
    /// 2026-12-06 on the corpus: suzanne, cow, beetle, teapot and spot; the remesh for
    /// stanford-bunny, fandisk, rocker-arm, cheburashka and woody).
    pub fn prefer_direct(&self) -> bool {
        self.direct_wins() * 2 > self.planned
    }

    fn direct_wins(&self) -> usize {
        self.direct_psnr
            .iter()
            .zip(&self.wavelet_psnr)
            .filter(|(d, w)| d > w)
            .count()
    }
}

/// The input side of [`compare`]'s distances, built once: its BVH, area samples and
/// diagonal.
struct Target {
    closest: ClosestPoint,
    samples: Vec<DVec3>,
    diagonal: f64,
}

impl Target {
    fn new(input: &Mesh) -> Result<Target> {
        let tris = crate::distance::triangles(input, "the input")?;
        let samples = sample_surface(&input.positions, &tris, COMPARE_SAMPLES);
        Ok(Target {
            closest: ClosestPoint::new(input)?,
            samples,
            diagonal: input.diagonal(),
        })
    }

    /// PSNR of `m` against the input (the larger one-sided RMS of area samples, as
    /// [`crate::distance::distance`] measures it).
    fn psnr(&self, m: &Mesh) -> Result<f64> {
        let (to_input, from_input) = rayon::join(
            || sampled_rms_to(m, &self.closest, COMPARE_SAMPLES),
            || -> Result<f64> { Ok(rms_to(&self.samples, &ClosestPoint::new(m)?)) },
        );
        Ok(psnr(self.diagonal, to_input?.max(from_input?)))
    }
}

/// Measures the wavelet stream `wavelet` and the direct stream `direct` of `input` against
/// it at the budgets of [`Comparison`] (with [`COMPARE_SAMPLES`] area samples per surface).
///
/// # Errors
/// A stream that does not decode, or a decoded mesh without faces.
pub fn compare(input: &Mesh, wavelet: &[u8], direct: &[u8]) -> Result<Comparison> {
    measure(input, wavelet, direct, &[0, 2, 4], |c| {
        let wins = c.direct_wins();
        2 * wins > c.planned || 2 * (c.bytes.len() - wins) >= c.planned
    })
}

/// Whether the direct stream `direct` of `input` is closer to it than the wavelet stream
/// `wavelet` at both of the first two budgets of [`Comparison`] (about 64 and 76 dB): then
/// a remesh with more levels, which costs more bytes at low rates and gains near its top,
/// would not win either, and `subwave encode` need not build it
/// ([`super::prepare::prepare_screened`]). Also returns the comparison.
///
/// # Errors
/// As [`compare`].
pub fn screen(input: &Mesh, wavelet: &[u8], direct: &[u8]) -> Result<(bool, Comparison)> {
    let c = measure(input, wavelet, direct, &[0, 2], |c| {
        c.direct_wins() < c.bytes.len()
    })?;
    Ok((c.direct_wins() == c.planned && c.planned > 0, c))
}

/// The budgets at the ends of the direct stream's chunks `chunks` (those it has), measured in
/// order until `decided`.
fn measure(
    input: &Mesh,
    wavelet: &[u8],
    direct: &[u8],
    chunks: &[usize],
    decided: impl Fn(&Comparison) -> bool,
) -> Result<Comparison> {
    let ends = |stream: &[u8]| -> Result<Vec<usize>> {
        Ok(super::container::read(stream)?
            .chunks
            .iter()
            .map(|e| (e.offset + e.len as u64) as usize)
            .collect())
    };
    let direct_ends = ends(direct)?;
    // A prefix that ends before a stream's base chunk does not decode: no mesh at all.
    let wavelet_first = ends(wavelet)?[0];
    let budgets: Vec<usize> = chunks
        .iter()
        .filter_map(|&i| direct_ends.get(i).copied())
        .collect();
    let target = Target::new(input)?;
    let psnr_at = |stream: &[u8], b: usize| -> Result<f64> {
        let opts = super::progressive::DecodeOptions {
            max_bytes: Some(b),
            trees: None,
        };
        target.psnr(&super::progressive::decode(stream, &opts)?.mesh)
    };
    let mut c = Comparison {
        bytes: Vec::new(),
        wavelet_psnr: Vec::new(),
        direct_psnr: Vec::new(),
        planned: budgets.len(),
    };
    for &b in &budgets {
        let (w, d) = rayon::join(
            || {
                if b < wavelet_first {
                    Ok(f64::NEG_INFINITY)
                } else {
                    psnr_at(wavelet, b)
                }
            },
            || psnr_at(direct, b),
        );
        c.bytes.push(b);
        c.wavelet_psnr.push(w?);
        c.direct_psnr.push(d?);
        if decided(&c) {
            break;
        }
    }
    Ok(c)
}

/// The direct stream of `input` ([`codable`], then [`encode`] with `opts`) and its
/// [`Comparison`] with the wavelet stream `wavelet` of the same input: what `subwave encode`
/// and `subwave eval` weigh when the input was remeshed (the direct stream replaces the
/// wavelet one where [`Comparison::prefer_direct`]). Also returns what the repair did, if
/// the input needed one.
///
/// # Errors
/// As [`codable`], [`encode`] and [`compare`].
pub fn encode_and_compare(
    input: &Mesh,
    wavelet: &[u8],
    opts: &DirectOptions,
) -> Result<(Vec<u8>, Comparison, Option<crate::remesh::RepairReport>)> {
    let (mesh, repair) = codable(input)?;
    let bytes = encode(&mesh, opts)?;
    let comparison = compare(input, wavelet, &bytes)?;
    Ok((bytes, comparison, repair))
}

//! Base-mesh coding: a single-rate lossless (up to position quantization) coder of polygon
//! meshes with boundaries, holes, several components, crease and corner tags.
//!
//! The base mesh of a wavelet decomposition, the control mesh of a CAD fit (Lavoué et al.
//! §VII.1) and any irregular mesh coded on its own go through this coder. It has three parts,
//! one file each:
//!
//! - [`connectivity`]: a valence-driven cut-border traversal (Touma–Gotsman 1998's conquest
//!   of an *active list* around a *focus* vertex, with Alliez–Desbrun 2001's observation that
//!   the information is the vertex degrees, here coded as per-face "the focus / the gate's
//!   other end is now complete" decisions in contexts of the number of faces already around
//!   the vertex) generalised to polygons as in Isenburg–Snoeyink's Face Fixer (the face across
//!   the gate is described by its degree and by how it attaches to the border). Boundaries are
//!   closed by one dummy vertex per hole (Touma–Gotsman §3), so holes cost a few bits.
//! - [`positions`]: uniform quantization over the bounding cube and (multi-)parallelogram
//!   prediction (Touma–Gotsman §4, Cohen-Or et al.'s multi-way averaging), residuals
//!   entropy coded in contexts of the predictor kind and the neighbourhood's residual size.
//! - [`creases`]: the crease flags of the edges as a run-length coded binary vector and the
//!   corner tags likewise (Lavoué et al. §VII.1), with their sharpness values.
//!
//! All entropy coding uses the adaptive binary range coder of [`crate::codec::rangecoder`],
//! with contexts that adapt fast while young ([`crate::codec::rangecoder::CountedBit`]): a
//! base mesh has hundreds of contexts and often only a few hundred vertices.
//!
//! # Bitstream (version 2)
//!
//! Version 2 codes exactly the symbols of version 1 with `CountedBit` contexts instead of
//! fixed-rate ones (connectivity of the corpus meshes 1–20% smaller: beetle 3,536 → 3,328
//! bits, suzanne 1,128 → 904).
//!
//! ```text
//! "SWBM" version:u8 position_bits:u8
//! varint vertices, isolated, faces, corners, holes, augmented_faces, components
//! f64 LE bbox_min.x, bbox_min.y, bbox_min.z, cube_side
//! varint connectivity_len, positions_len, creases_len
//! connectivity chunk, positions chunk, creases chunk (each a range-coder stream)
//! ```
//!
//! # What the decoder returns
//!
//! The codec renumbers vertices and faces (the traversal order). [`Encoded::vertex_map`] and
//! [`Encoded::face_map`] give, for each decoded vertex and face, the input one. Preserved
//! exactly: the faces (each possibly cyclically rotated, never reversed), hence orientation,
//! boundaries and components; every vertex, including those no face uses (they come last, in
//! Morton order of their quantized positions); the crease and corner tags, canonicalised:
//! one edge tag per tagged edge (the last tag of an edge wins, as in [`crate::Topology`]), in
//! decoded edge order (first appearance) with the edge's vertices in their first traversal
//! direction; one vertex tag per tagged vertex in vertex order; tags of sharpness ≤ 0 (or
//! NaN) and edge tags whose vertices share no edge are dropped. Colours, texture coordinates and face-varying data are not
//! coded. Positions are quantized: see [`Quantization`].

pub mod connectivity;
pub mod creases;
pub mod positions;
#[cfg(test)]
mod tests;

use glam::DVec3;

use crate::codec::rangecoder::{Decoder, Encoder};
use crate::mesh::Mesh;
use crate::topology::Topology;
use crate::{Error, Result};

/// Bitstream magic.
const MAGIC: &[u8; 4] = b"SWBM";
/// Bitstream version written by [`encode`]; [`decode`] accepts only this one.
pub const VERSION: u8 = 2;

/// Elements a decoder accepts per byte of stream: a bound on declared counts, checked before
/// anything is allocated. Every vertex costs at least three adaptive binary decisions of at
/// least 0.011 bit each (the range coder's most skewed probability is 4065/4096), every face
/// at least one: a stream of `n` bytes cannot code more than ≈ 250·n vertices or 750·n faces.
const MAX_VERTICES_PER_BYTE: u64 = 256;
/// See [`MAX_VERTICES_PER_BYTE`].
const MAX_FACES_PER_BYTE: u64 = 1024;
/// Corners per byte (a d-gon of new vertices costs at least d decisions).
const MAX_CORNERS_PER_BYTE: u64 = 4096;

/// Options of [`encode`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BaseMeshOptions {
    /// Quantization bits per coordinate, `8..=30` (default 14): positions are snapped to a
    /// grid of `2^position_bits` steps along the longest side of the bounding box.
    pub position_bits: u32,
}

impl Default for BaseMeshOptions {
    fn default() -> Self {
        BaseMeshOptions { position_bits: 14 }
    }
}

/// The position quantization of a stream: decoded position = `min + q · step` per axis, with
/// `step = side / (2^bits − 1)` where `side` is the longest side of the bounding box of all
/// vertices (a cube grid, the same step on every axis); `q` in `0..2^bits`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quantization {
    /// Bits per coordinate.
    pub bits: u32,
    /// Minimum corner of the bounding box.
    pub min: DVec3,
    /// Longest side of the bounding box (0 when all vertices coincide or there are none).
    pub side: f64,
}

impl Quantization {
    /// The grid step (`side / (2^bits − 1)`).
    pub fn step(&self) -> f64 {
        self.side / (((1u64 << self.bits) - 1) as f64)
    }

    /// The grid point of `p` (rounded, clamped to `0..2^bits`).
    pub fn quantize(&self, p: DVec3) -> [u32; 3] {
        let step = self.step();
        let max = ((1u64 << self.bits) - 1) as f64;
        let q = |x: f64, lo: f64| -> u32 {
            if step > 0.0 {
                ((x - lo) / step).round().clamp(0.0, max) as u32
            } else {
                0
            }
        };
        [q(p.x, self.min.x), q(p.y, self.min.y), q(p.z, self.min.z)]
    }

    /// The position of grid point `q`.
    pub fn dequantize(&self, q: [u32; 3]) -> DVec3 {
        let step = self.step();
        self.min + DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64) * step
    }
}

/// Sizes of the parts of a stream, in bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Stats {
    /// The connectivity chunk.
    pub connectivity_bits: u64,
    /// The positions chunk.
    pub position_bits: u64,
    /// The crease and corner tags chunk.
    pub crease_bits: u64,
    /// The fixed header (magic, version, counts, bounding box, chunk lengths).
    pub header_bits: u64,
    /// Vertices coded (including unreferenced ones).
    pub vertices: u64,
    /// Faces coded.
    pub faces: u64,
}

/// The result of [`encode_with_info`].
#[derive(Clone, Debug)]
pub struct Encoded {
    /// The stream.
    pub bytes: Vec<u8>,
    /// Sizes of its parts.
    pub stats: Stats,
    /// Decoded vertex `i` is input vertex `vertex_map[i]`.
    pub vertex_map: Vec<u32>,
    /// Decoded face `i` is input face `face_map[i]` (possibly cyclically rotated).
    pub face_map: Vec<u32>,
    /// Exactly what [`decode`] returns for `bytes`.
    pub decoded: Mesh,
    /// The quantized positions of `decoded`, in decoded order.
    pub quantized: Vec<[u32; 3]>,
    /// The quantization.
    pub quantization: Quantization,
}

/// Encodes `mesh`.
///
/// # Errors
/// [`Error::InvalidArgument`] if `opts.position_bits` is outside `8..=30`;
/// [`Error::Mesh`] if the mesh breaks [`Mesh::check_indices`] or is not a consistently
/// oriented 2-manifold ([`crate::validate::require_manifold`]'s errors), or has more than
/// `2^31` corners.
pub fn encode(mesh: &Mesh, opts: &BaseMeshOptions) -> Result<Vec<u8>> {
    Ok(encode_with_info(mesh, opts)?.bytes)
}

/// Encodes `mesh` and returns the stream with its sizes, the vertex and face maps and the
/// decoded mesh. Same errors as [`encode`].
pub fn encode_with_info(mesh: &Mesh, opts: &BaseMeshOptions) -> Result<Encoded> {
    if !(8..=30).contains(&opts.position_bits) {
        return Err(Error::InvalidArgument(format!(
            "position bits must be in 8..=30, got {}",
            opts.position_bits
        )));
    }
    encode_on_grid(mesh, quantization_of(mesh, opts.position_bits))
}

/// Largest magnitude of an integer position accepted by [`encode_integers`] (`2^52`, so that
/// every value and grid offset is exact in `f64`).
pub const MAX_INTEGER: i64 = 1 << 52;

/// Encodes a mesh whose positions are already integers (`q[v]` for vertex `v`; the mesh's
/// own positions are ignored), exactly: [`decode_integers`] returns the same integers (in
/// the decoded vertex order, [`Encoded::vertex_map`]). The integers are coded as grid points
/// of step 1 from their per-axis minimum, with the same connectivity coder and
/// parallelogram prediction as [`encode`]; the decoded vertex and face order depends only on
/// the faces, so it is the order [`encode`] gives for the same faces.
///
/// # Errors
/// [`Error::InvalidArgument`] if `q.len()` is not the vertex count, a value exceeds
/// [`MAX_INTEGER`] in magnitude or the values span more than `2^30 − 1` on an axis; otherwise
/// as [`encode`].
pub fn encode_integers(mesh: &Mesh, q: &[[i64; 3]]) -> Result<Encoded> {
    if q.len() != mesh.num_vertices() {
        return Err(Error::InvalidArgument(format!(
            "{} integer positions for {} vertices",
            q.len(),
            mesh.num_vertices()
        )));
    }
    if let Some(v) = q
        .iter()
        .position(|p| p.iter().any(|x| x.abs() > MAX_INTEGER))
    {
        return Err(Error::InvalidArgument(format!(
            "vertex {v}: integer position {:?} beyond ±2^52",
            q[v]
        )));
    }
    let mut lo = [0i64; 3];
    let mut span = 0i64;
    for c in 0..3 {
        let (a, b) = q
            .iter()
            .fold((i64::MAX, i64::MIN), |(a, b), p| (a.min(p[c]), b.max(p[c])));
        if !q.is_empty() {
            lo[c] = a;
            span = span.max(b - a);
        }
    }
    let bits = (64 - span.leading_zeros()).max(8);
    if bits > 30 {
        return Err(Error::InvalidArgument(format!(
            "integer positions span {span} on an axis; the base-mesh coder takes at most 2^30 − 1"
        )));
    }
    let quantization = Quantization {
        bits,
        min: DVec3::new(lo[0] as f64, lo[1] as f64, lo[2] as f64),
        side: ((1u64 << bits) - 1) as f64,
    };
    let mut m = mesh.clone();
    m.positions = q
        .iter()
        .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect();
    encode_on_grid(&m, quantization)
}

/// Decodes a stream written by [`encode_integers`]: the mesh (positions are the integers as
/// `f64`) and the integer positions in decoded vertex order.
///
/// # Errors
/// As [`decode`]; [`Error::Decode`] if the stream's grid is not the unit integer grid of
/// [`encode_integers`].
pub fn decode_integers(bytes: &[u8]) -> Result<(Mesh, Vec<[i64; 3]>)> {
    let (mesh, quantized, qz) = decode_quantized(bytes)?;
    let lo = [qz.min.x, qz.min.y, qz.min.z];
    if qz.side != ((1u64 << qz.bits) - 1) as f64
        || lo
            .iter()
            .any(|&x| x.fract() != 0.0 || x.abs() > MAX_INTEGER as f64)
    {
        return Err(Error::Decode {
            offset: 0,
            message: "not an integer-position base-mesh stream (its grid is not the unit grid)"
                .into(),
        });
    }
    let lo = lo.map(|x| x as i64);
    let q = quantized
        .iter()
        .map(|p| [0, 1, 2].map(|c| lo[c] + p[c] as i64))
        .collect();
    Ok((mesh, q))
}

/// [`encode_with_info`] on a given grid.
fn encode_on_grid(mesh: &Mesh, quantization: Quantization) -> Result<Encoded> {
    mesh.check_indices()?;
    if mesh.face_indices.len() >= (1 << 31) {
        return Err(Error::InvalidArgument(
            "the base-mesh coder takes at most 2^31 face corners".into(),
        ));
    }
    let topo = Topology::build(mesh);
    crate::validate::require_manifold(&topo)?;

    // Connectivity.
    let mut enc = Encoder::new();
    let conn = connectivity::encode(mesh, &mut enc)?;
    let conn_bytes = enc.finish();

    // Vertex order: referenced vertices in traversal order, then the unreferenced ones.
    let mut vertex_map = conn.vertex_map.clone();
    let mut seen = vec![false; mesh.num_vertices()];
    for &v in &vertex_map {
        seen[v as usize] = true;
    }
    let nref = vertex_map.len();
    vertex_map.extend((0..mesh.num_vertices() as u32).filter(|&v| !seen[v as usize]));

    // Positions.
    // Unreferenced vertices in Morton order of their grid points (ties in input order), so
    // that each is close to the previous one (their predictor).
    vertex_map[nref..]
        .sort_by_cached_key(|&v| morton(quantization.quantize(mesh.positions[v as usize])));
    let quantized: Vec<[u32; 3]> = vertex_map
        .iter()
        .map(|&v| quantization.quantize(mesh.positions[v as usize]))
        .collect();
    let mut enc = Encoder::new();
    positions::encode(
        &quantized,
        nref,
        &conn.face_offsets,
        &conn.face_indices,
        quantization.bits,
        &mut enc,
    );
    let pos_bytes = enc.finish();

    // Decoded mesh (without tags yet).
    let mut decoded = Mesh {
        positions: quantized
            .iter()
            .map(|&q| quantization.dequantize(q))
            .collect(),
        face_offsets: conn.face_offsets.clone(),
        face_indices: conn.face_indices.clone(),
        ..Mesh::new()
    };

    // Creases.
    let mut inverse = vec![0u32; mesh.num_vertices()];
    for (i, &v) in vertex_map.iter().enumerate() {
        inverse[v as usize] = i as u32;
    }
    let mut enc = Encoder::new();
    let (edge_tags, vertex_tags) = creases::encode(mesh, &inverse, &decoded, &mut enc);
    let crease_bytes = enc.finish();
    decoded.edge_tags = edge_tags;
    decoded.vertex_tags = vertex_tags;

    // Assemble.
    let header = Header {
        position_bits: quantization.bits,
        vertices: mesh.num_vertices() as u64,
        isolated: (mesh.num_vertices() - nref) as u64,
        faces: mesh.num_faces() as u64,
        corners: mesh.face_indices.len() as u64,
        holes: conn.holes as u64,
        augmented_faces: conn.augmented_faces as u64,
        components: conn.components as u64,
        quantization,
        chunk_lens: [
            conn_bytes.len() as u64,
            pos_bytes.len() as u64,
            crease_bytes.len() as u64,
        ],
    };
    let mut bytes = header.write();
    let header_len = bytes.len();
    bytes.extend_from_slice(&conn_bytes);
    bytes.extend_from_slice(&pos_bytes);
    bytes.extend_from_slice(&crease_bytes);

    Ok(Encoded {
        stats: Stats {
            connectivity_bits: 8 * conn_bytes.len() as u64,
            position_bits: 8 * pos_bytes.len() as u64,
            crease_bits: 8 * crease_bytes.len() as u64,
            header_bits: 8 * header_len as u64,
            vertices: mesh.num_vertices() as u64,
            faces: mesh.num_faces() as u64,
        },
        bytes,
        vertex_map,
        face_map: conn.face_map,
        decoded,
        quantized,
        quantization,
    })
}

/// Decodes a stream written by [`encode`].
///
/// # Errors
/// [`Error::Decode`] naming the field or chunk for a truncated, corrupt or unsupported
/// stream. Never panics; declared counts are checked against the stream size before anything
/// is allocated.
pub fn decode(bytes: &[u8]) -> Result<Mesh> {
    Ok(decode_quantized(bytes)?.0)
}

/// Decodes a stream and also returns the quantized positions (the exact integers the encoder
/// coded, in decoded vertex order) and the quantization. Same errors as [`decode`].
pub fn decode_quantized(bytes: &[u8]) -> Result<(Mesh, Vec<[u32; 3]>, Quantization)> {
    let (h, mut at) = Header::read(bytes)?;
    let chunk = |at: usize, len: u64, name: &str| -> Result<&[u8]> {
        let end = (at as u64)
            .checked_add(len)
            .filter(|&e| e <= bytes.len() as u64);
        match end {
            Some(e) => Ok(&bytes[at..e as usize]),
            None => Err(Error::Decode {
                offset: at,
                message: format!("{name} chunk of {len} bytes runs past the end of the stream"),
            }),
        }
    };
    let conn_data = chunk(at, h.chunk_lens[0], "connectivity")?;
    let conn_at = at;
    at += conn_data.len();
    let pos_data = chunk(at, h.chunk_lens[1], "positions")?;
    let pos_at = at;
    at += pos_data.len();
    let crease_data = chunk(at, h.chunk_lens[2], "creases")?;
    let crease_at = at;

    let nref = h.vertices - h.isolated;
    let mut dec = Decoder::new(conn_data);
    let conn = connectivity::decode(
        &mut dec,
        &connectivity::Declared {
            vertices: nref,
            faces: h.faces,
            corners: h.corners,
            holes: h.holes,
            augmented_faces: h.augmented_faces,
            components: h.components,
        },
    )
    .map_err(|e| e.at(conn_at, "connectivity"))?;

    let mut dec = Decoder::new(pos_data);
    let quantized = positions::decode(
        h.vertices as usize,
        nref as usize,
        &conn.face_offsets,
        &conn.face_indices,
        h.position_bits,
        &mut dec,
    )
    .map_err(|e| e.at(pos_at, "positions"))?;

    let q = h.quantization;
    let mut mesh = Mesh {
        positions: quantized.iter().map(|&p| q.dequantize(p)).collect(),
        face_offsets: conn.face_offsets,
        face_indices: conn.face_indices,
        ..Mesh::new()
    };
    let mut dec = Decoder::new(crease_data);
    let (edge_tags, vertex_tags) =
        creases::decode(&mesh, &mut dec).map_err(|e| e.at(crease_at, "creases"))?;
    mesh.edge_tags = edge_tags;
    mesh.vertex_tags = vertex_tags;
    mesh.check_indices().map_err(|e| Error::Decode {
        offset: conn_at,
        message: format!("connectivity chunk decodes to an invalid mesh: {e}"),
    })?;
    Ok((mesh, quantized, q))
}

/// The Morton (Z-order) code of a grid point (30 bits per axis interleaved).
fn morton(q: [u32; 3]) -> u128 {
    let mut m = 0u128;
    for bit in (0..30).rev() {
        for &x in &q {
            m = (m << 1) | ((x >> bit) & 1) as u128;
        }
    }
    m
}

/// The quantization of `mesh`'s vertices with `bits` bits.
fn quantization_of(mesh: &Mesh, bits: u32) -> Quantization {
    let (lo, hi) = mesh.bounding_box().unwrap_or((DVec3::ZERO, DVec3::ZERO));
    let side = (hi - lo).max_element();
    Quantization {
        bits,
        min: lo,
        side: if side.is_finite() { side } else { 0.0 },
    }
}

/// A decoding error inside a chunk, before it is placed in the stream.
#[derive(Debug)]
pub(crate) struct ChunkError {
    /// Byte offset inside the chunk.
    pub offset: usize,
    /// The field.
    pub message: String,
}

impl ChunkError {
    pub(crate) fn new(dec: &Decoder, message: impl Into<String>) -> Self {
        ChunkError {
            offset: dec.position(),
            message: message.into(),
        }
    }

    fn at(self, base: usize, chunk: &str) -> Error {
        Error::Decode {
            offset: base + self.offset,
            message: format!("{chunk} chunk: {}", self.message),
        }
    }
}

/// The fixed header.
struct Header {
    position_bits: u32,
    vertices: u64,
    isolated: u64,
    faces: u64,
    corners: u64,
    holes: u64,
    augmented_faces: u64,
    components: u64,
    quantization: Quantization,
    chunk_lens: [u64; 3],
}

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// A cursor over the header bytes that names the field on error.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn err(&self, message: String) -> Error {
        Error::Decode {
            offset: self.at,
            message,
        }
    }

    fn bytes(&mut self, n: usize, field: &str) -> Result<&[u8]> {
        match self.bytes.get(self.at..self.at + n) {
            Some(s) => {
                self.at += n;
                Ok(s)
            }
            None => Err(self.err(format!("header field `{field}`: the stream ends early"))),
        }
    }

    fn varint(&mut self, field: &str) -> Result<u64> {
        let mut v = 0u64;
        for i in 0..10 {
            let b = *self.bytes(1, field)?.first().unwrap_or(&0);
            if i == 9 && b > 1 {
                break;
            }
            v |= ((b & 0x7F) as u64) << (7 * i);
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(self.err(format!("header field `{field}`: malformed varint")))
    }

    fn f64(&mut self, field: &str) -> Result<f64> {
        let b = self.bytes(8, field)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        let x = f64::from_le_bytes(a);
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(format!("header field `{field}` is not finite")))
        }
    }
}

impl Header {
    fn write(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(64);
        out.extend_from_slice(MAGIC);
        out.push(VERSION);
        out.push(self.position_bits as u8);
        for v in [
            self.vertices,
            self.isolated,
            self.faces,
            self.corners,
            self.holes,
            self.augmented_faces,
            self.components,
        ] {
            put_varint(&mut out, v);
        }
        let q = &self.quantization;
        for x in [q.min.x, q.min.y, q.min.z, q.side] {
            out.extend_from_slice(&x.to_le_bytes());
        }
        for &l in &self.chunk_lens {
            put_varint(&mut out, l);
        }
        out
    }

    fn read(bytes: &[u8]) -> Result<(Header, usize)> {
        let mut r = Reader { bytes, at: 0 };
        if r.bytes(4, "magic")? != MAGIC {
            return Err(Error::Decode {
                offset: 0,
                message: "not a subwave base-mesh stream (bad magic)".into(),
            });
        }
        let version = r.bytes(1, "version")?[0];
        if version != VERSION {
            return Err(Error::Decode {
                offset: 4,
                message: format!(
                    "unsupported base-mesh stream version {version} (this decoder reads {VERSION})"
                ),
            });
        }
        let position_bits = r.bytes(1, "position_bits")?[0] as u32;
        if !(8..=30).contains(&position_bits) {
            return Err(r.err(format!(
                "header field `position_bits` = {position_bits} is outside 8..=30"
            )));
        }
        let n = bytes.len() as u64;
        let mut field = |name: &str, limit: u64| -> Result<u64> {
            let v = r.varint(name)?;
            if v > limit {
                Err(r.err(format!(
                    "header field `{name}` = {v} is more than a {n}-byte stream can hold ({limit})"
                )))
            } else {
                Ok(v)
            }
        };
        let u32max = u32::MAX as u64 / 2;
        let vertices = field("vertices", (MAX_VERTICES_PER_BYTE * n + 64).min(u32max))?;
        let isolated = field("isolated", vertices)?;
        let faces = field("faces", (MAX_FACES_PER_BYTE * n + 64).min(u32max))?;
        let corners = field("corners", (MAX_CORNERS_PER_BYTE * n + 256).min(u32max))?;
        let holes = field("holes", vertices)?;
        let augmented_faces = field("augmented_faces", (MAX_FACES_PER_BYTE * n + 64).min(u32max))?;
        let components = field("components", faces)?;
        if corners < 3 * faces || augmented_faces < faces {
            return Err(r.err(format!(
                "header counts are inconsistent: {faces} faces, {corners} corners, {augmented_faces} augmented faces"
            )));
        }
        let min = DVec3::new(
            r.f64("bbox_min.x")?,
            r.f64("bbox_min.y")?,
            r.f64("bbox_min.z")?,
        );
        let side = r.f64("cube_side")?;
        if side < 0.0 {
            return Err(r.err("header field `cube_side` is negative".into()));
        }
        let mut chunk_lens = [0u64; 3];
        for (l, name) in
            chunk_lens
                .iter_mut()
                .zip(["connectivity_len", "positions_len", "creases_len"])
        {
            *l = r.varint(name)?;
        }
        let at = r.at;
        Ok((
            Header {
                position_bits,
                vertices,
                isolated,
                faces,
                corners,
                holes,
                augmented_faces,
                components,
                quantization: Quantization {
                    bits: position_bits,
                    min,
                    side,
                },
                chunk_lens,
            },
            at,
        ))
    }
}

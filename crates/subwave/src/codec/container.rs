//! The `.swv` stream container: a versioned header, a chunk index with byte offsets and a
//! CRC-32 per chunk, then the chunks (base mesh, then coefficient data).
//!
//! Maret 2003 §4.5.1 (view-dependent AFX streams: per-tree bit planes with their sizes) and
//! §4.5.3 (the proposed extension: each bit plane of the whole forest contiguous, with its
//! size). The index gives every chunk's absolute offset and length, so that an HTTP range
//! request can fetch any chunk, and its checksum, so that a damaged chunk is reported by
//! name instead of being decoded into garbage.
//!
//! # Layout (all integers little-endian)
//! ```text
//! magic     "SWAV"                       4 bytes
//! version   u16                          (VERSION)
//! hlen      u32                          bytes of the header including the index and its CRC
//! fields    Header::write                fixed size (HEADER_FIELDS bytes)
//! nchunks   varint
//! per chunk kind u8, id varint, len varint, crc u32, nmarks varint, marks (varints of the
//!           differences between successive marks, the first from 0)
//! hcrc      u32                          CRC-32 of every header byte before it
//! chunks    ...                          contiguous, in index order
//! ```
//! `varint` is LEB128 (7 bits per byte, low first, at most 5 bytes for a `u32`). Chunks
//! follow the header without gaps, so the index stores lengths and [`read`] derives each
//! chunk's absolute byte offset ([`ChunkEntry::offset`]: `hlen` plus the lengths before it)
//! — a client that has the header knows every chunk's byte range without a second request.
//! (Version 5 stored the offsets and fixed-width fields: 23 bytes per entry instead of
//! about 8, 245 bytes more for a 16-plane stream.)
//!
//! `marks` are, for a per-tree chunk, the byte length of the prefix of the chunk that holds
//! bit planes `top..=p` (one mark per plane): a client fetches `[offset, offset + mark)`.
//!
//! A reader validates every count against the bytes it has before allocating: the number
//! of chunks against the header length, chunk extents against `u64` overflow, and (in
//! [`super::progressive`]) the decoded mesh size against the stream size.

use glam::DVec3;

use crate::{Error, Result};

/// The magic bytes.
pub const MAGIC: [u8; 4] = *b"SWAV";
/// The format version (bumped on every format change; the golden-bytes test pins it).
pub const VERSION: u16 = 10;
/// Bytes of the fixed header fields.
pub const HEADER_FIELDS: usize = 16 + 8 * 13 + 4 * 4;
/// Fewest bytes of a chunk index entry (kind, one-byte id, length and mark count, CRC).
const ENTRY_MIN: usize = 1 + 1 + 1 + 4 + 1;

/// What a chunk holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChunkKind {
    /// The base mesh.
    Base,
    /// One bit plane of the whole forest (embedded layout); `id` is the plane.
    Plane,
    /// All bit planes of one tree (trees layout); `id` is the tree.
    Tree,
    /// The details of one level (lossless streams); `id` is the level `j` (details of the
    /// odd vertices of level `j + 1`).
    Level,
}

impl ChunkKind {
    fn code(self) -> u8 {
        match self {
            ChunkKind::Base => 0,
            ChunkKind::Plane => 1,
            ChunkKind::Tree => 2,
            ChunkKind::Level => 3,
        }
    }

    fn from_code(c: u8) -> Option<ChunkKind> {
        match c {
            0 => Some(ChunkKind::Base),
            1 => Some(ChunkKind::Plane),
            2 => Some(ChunkKind::Tree),
            3 => Some(ChunkKind::Level),
            _ => None,
        }
    }
}

/// One entry of the chunk index.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChunkEntry {
    /// What the chunk holds.
    pub kind: ChunkKind,
    /// Plane (for [`ChunkKind::Plane`]) or tree (for [`ChunkKind::Tree`]); 0 for the base.
    pub id: u32,
    /// Absolute byte offset in the stream.
    pub offset: u64,
    /// Length in bytes.
    pub len: u32,
    /// CRC-32 (IEEE) of the chunk's bytes.
    pub crc: u32,
    /// Per-plane prefix lengths (per-tree chunks), else empty.
    pub marks: Vec<u32>,
}

impl ChunkEntry {
    /// A human name for error messages ("chunk 3 (bit plane 11)").
    pub fn name(&self, index: usize) -> String {
        match self.kind {
            ChunkKind::Base => format!("chunk {index} (base mesh)"),
            ChunkKind::Plane => format!("chunk {index} (bit plane {})", self.id),
            ChunkKind::Tree => format!("chunk {index} (tree {})", self.id),
            ChunkKind::Level => format!("chunk {index} (level {})", self.id),
        }
    }
}

/// The fixed header fields (their meaning is defined by [`super::progressive`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Wavelet id.
    pub wavelet: u8,
    /// Flag bits.
    pub flags: u8,
    /// Split: 0 triangles, 1 polygons (quads).
    pub split: u8,
    /// Layout: 0 embedded, 1 trees.
    pub layout: u8,
    /// Subdivision levels.
    pub levels: u8,
    /// Bits `N` of the coefficient quantization (eq. 4.8) or of the lossless grid.
    pub bits: u8,
    /// Bits of the base-mesh grid.
    pub base_bits: u8,
    /// Level weight of the lossy details, in quarters of the exponent `α`: the details of
    /// level `j` were multiplied by `2^(−α·j)` before quantization (0 in lossless streams;
    /// see [`super::progressive::EncodeOptions::level_exponent`]). Version 7.
    pub level_weight: u8,
    /// Top bit plane per component (−1: all zero).
    pub top: [i8; 3],
    /// Tangential shift `k` of lossy local-frame details: their two tangential components
    /// were multiplied by `2^(−k)` (on top of the level weight) before quantization (0 with
    /// global frames and in lossless streams; see
    /// [`super::progressive::EncodeOptions::tangent_shift`]). Version 7.
    pub tangent_shift: u8,
    /// Vertices of the mesh the stream stands for (the input before remeshing), for rates
    /// in bits per input vertex.
    pub input_vertices: u32,
    /// Bounding box of the encoded finest positions.
    pub bbox: [DVec3; 2],
    /// Coefficient steps per component (eq. 4.8).
    pub steps: [f64; 3],
    /// Origin of the position grid (base mesh; lossless positions).
    pub grid_origin: DVec3,
    /// Step of the position grid.
    pub grid_step: f64,
    /// Base vertices.
    pub base_vertices: u32,
    /// Base faces.
    pub base_faces: u32,
    /// Base face corners (sum of arities).
    pub base_corners: u32,
    /// Trees of the forest.
    pub num_trees: u32,
}

/// A parsed container.
#[derive(Clone, Debug, PartialEq)]
pub struct Container {
    /// The header fields.
    pub header: Header,
    /// Bytes of the header and index.
    pub header_len: usize,
    /// The chunk index, in stream order.
    pub chunks: Vec<ChunkEntry>,
}

/// Whether `data`'s CRC-32 is `crc`. Under `cfg(fuzzing)` (set by `cargo fuzz`) every checksum
/// matches, so that the fuzzer's mutations reach the decoders behind the checksums instead of
/// stopping at them.
pub(crate) fn crc_matches(data: &[u8], crc: u32) -> bool {
    cfg!(fuzzing) || crc32(data) == crc
}

/// CRC-32 (IEEE 802.3, reflected, polynomial `0xEDB88320`), as zlib's `crc32`: slicing by
/// 8 (eight table lookups per 8 bytes, independent of each other, instead of a chain of one
/// lookup per byte).
pub fn crc32(data: &[u8]) -> u32 {
    static TABLES: std::sync::OnceLock<[[u32; 256]; 8]> = std::sync::OnceLock::new();
    let t = TABLES.get_or_init(|| {
        let mut t = [[0u32; 256]; 8];
        for (i, x) in t[0].iter_mut().enumerate() {
            let mut c = i as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
            *x = c;
        }
        for k in 1..8 {
            let (done, rest) = t.split_at_mut(k);
            for (x, &p) in rest[0].iter_mut().zip(&done[k - 1]) {
                *x = (p >> 8) ^ done[0][(p & 0xFF) as usize];
            }
        }
        t
    });
    let mut c = !0u32;
    let mut chunks = data.chunks_exact(8);
    for b in &mut chunks {
        let lo = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) ^ c;
        let hi = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
        c = t[7][(lo & 0xFF) as usize]
            ^ t[6][((lo >> 8) & 0xFF) as usize]
            ^ t[5][((lo >> 16) & 0xFF) as usize]
            ^ t[4][(lo >> 24) as usize]
            ^ t[3][(hi & 0xFF) as usize]
            ^ t[2][((hi >> 8) & 0xFF) as usize]
            ^ t[1][((hi >> 16) & 0xFF) as usize]
            ^ t[0][(hi >> 24) as usize];
    }
    for &b in chunks.remainder() {
        c = t[0][((c ^ b as u32) & 0xFF) as usize] ^ (c >> 8);
    }
    !c
}

fn put_varint(out: &mut Vec<u8>, mut v: u32) {
    while v >= 0x80 {
        out.push((v as u8 & 0x7F) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn put_f64(out: &mut Vec<u8>, x: f64) {
    out.extend_from_slice(&x.to_le_bytes());
}

impl Header {
    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&[
            self.wavelet,
            self.flags,
            self.split,
            self.layout,
            self.levels,
            self.bits,
            self.base_bits,
            self.level_weight,
        ]);
        out.extend(self.top.iter().map(|&t| t as u8));
        out.push(self.tangent_shift);
        out.extend_from_slice(&self.input_vertices.to_le_bytes());
        for p in self.bbox {
            for c in 0..3 {
                put_f64(out, p[c]);
            }
        }
        for s in self.steps {
            put_f64(out, s);
        }
        for c in 0..3 {
            put_f64(out, self.grid_origin[c]);
        }
        put_f64(out, self.grid_step);
        for v in [
            self.base_vertices,
            self.base_faces,
            self.base_corners,
            self.num_trees,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }

    fn read(r: &mut Reader) -> Result<Header> {
        let b = r.bytes(16)?;
        let mut f = || r.f64();
        let bbox = [DVec3::new(f()?, f()?, f()?), DVec3::new(f()?, f()?, f()?)];
        let steps = [f()?, f()?, f()?];
        let grid_origin = DVec3::new(f()?, f()?, f()?);
        let grid_step = f()?;
        let h = Header {
            wavelet: b[0],
            flags: b[1],
            split: b[2],
            layout: b[3],
            levels: b[4],
            bits: b[5],
            base_bits: b[6],
            level_weight: b[7],
            top: [b[8] as i8, b[9] as i8, b[10] as i8],
            tangent_shift: b[11],
            input_vertices: u32::from_le_bytes([b[12], b[13], b[14], b[15]]),
            bbox,
            steps,
            grid_origin,
            grid_step,
            base_vertices: r.u32()?,
            base_faces: r.u32()?,
            base_corners: r.u32()?,
            num_trees: r.u32()?,
        };
        let finite = h.bbox.iter().all(|p| p.is_finite())
            && h.steps.iter().all(|s| s.is_finite() && *s > 0.0)
            && h.grid_origin.is_finite()
            && h.grid_step.is_finite()
            && h.grid_step > 0.0;
        if !finite {
            return Err(Error::Decode {
                offset: 10,
                message: "header: non-finite or non-positive box, step or grid".into(),
            });
        }
        Ok(h)
    }
}

/// Writes a container: `header`, then `chunks` (kind, id, bytes, marks) in order.
///
/// # Errors
/// [`Error::InvalidArgument`] if a chunk exceeds 4 GiB or has more than 65,535 marks.
pub fn write(header: &Header, chunks: &[(ChunkKind, u32, Vec<u8>, Vec<u32>)]) -> Result<Vec<u8>> {
    let mut head = Vec::new();
    head.extend_from_slice(&MAGIC);
    head.extend_from_slice(&VERSION.to_le_bytes());
    head.extend_from_slice(&[0; 4]); // hlen, patched below
    header.write(&mut head);
    if chunks.len() > u32::MAX as usize {
        return Err(Error::InvalidArgument("more than 2^32 chunks".into()));
    }
    put_varint(&mut head, chunks.len() as u32);
    for (kind, id, data, marks) in chunks {
        if data.len() > u32::MAX as usize || marks.len() > u16::MAX as usize {
            return Err(Error::InvalidArgument(
                "a chunk is larger than 4 GiB or has too many planes".into(),
            ));
        }
        head.push(kind.code());
        put_varint(&mut head, *id);
        put_varint(&mut head, data.len() as u32);
        head.extend_from_slice(&crc32(data).to_le_bytes());
        put_varint(&mut head, marks.len() as u32);
        let mut prev = 0u32;
        for &m in marks {
            if m < prev || m > data.len() as u32 {
                return Err(Error::InvalidArgument(
                    "chunk marks must increase and stay within the chunk".into(),
                ));
            }
            put_varint(&mut head, m - prev);
            prev = m;
        }
    }
    let hl = u32::try_from(head.len() + 4)
        .map_err(|_| Error::InvalidArgument("the chunk index exceeds 4 GiB".into()))?;
    head[6..10].copy_from_slice(&hl.to_le_bytes());
    let c = crc32(&head);
    head.extend_from_slice(&c.to_le_bytes());
    for (_, _, data, _) in chunks {
        head.extend_from_slice(data);
    }
    Ok(head)
}

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn bytes(&mut self, n: usize) -> Result<&'a [u8]> {
        match self.data.get(self.pos..self.pos.saturating_add(n)) {
            Some(b) => {
                self.pos += n;
                Ok(b)
            }
            None => Err(Error::Decode {
                offset: self.pos,
                message: format!(
                    "stream truncated in the header ({} bytes; the header needs more)",
                    self.data.len()
                ),
            }),
        }
    }
    fn u16(&mut self) -> Result<u16> {
        let b = self.bytes(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }
    fn u32(&mut self) -> Result<u32> {
        let b = self.bytes(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn varint(&mut self) -> Result<u32> {
        let mut v = 0u64;
        for i in 0..5 {
            let b = self.bytes(1)?[0];
            v |= ((b & 0x7F) as u64) << (7 * i);
            if b & 0x80 == 0 {
                return u32::try_from(v).map_err(|_| Error::Decode {
                    offset: self.pos,
                    message: "chunk index: a number overflows 32 bits".into(),
                });
            }
        }
        Err(Error::Decode {
            offset: self.pos,
            message: "chunk index: a number is longer than 5 bytes".into(),
        })
    }
    fn u64(&mut self) -> Result<u64> {
        let b = self.bytes(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_bits(self.u64()?))
    }
}

/// Parses the header and chunk index of `bytes` (a whole stream or a prefix holding at
/// least the header), checking magic, version, header CRC and the index's consistency.
///
/// # Errors
/// [`Error::Decode`] naming the field: bad magic, unsupported version, a prefix shorter than
/// the header, a header CRC mismatch, an index inconsistent with the header length (counts
/// that do not fit, overlong numbers, marks beyond their chunk, trailing bytes).
pub fn read(bytes: &[u8]) -> Result<Container> {
    let mut r = Reader {
        data: bytes,
        pos: 0,
    };
    if r.bytes(4)? != MAGIC {
        return Err(Error::Decode {
            offset: 0,
            message: "not a subwave stream (magic is not \"SWAV\")".into(),
        });
    }
    let version = r.u16()?;
    if version != VERSION {
        return Err(Error::Decode {
            offset: 4,
            message: format!(
                "stream version {version} is not supported (this build reads version {VERSION})"
            ),
        });
    }
    let hlen = r.u32()? as usize;
    if hlen < 10 + HEADER_FIELDS + 1 + 4 {
        return Err(Error::Decode {
            offset: 6,
            message: format!("header length {hlen} is too small"),
        });
    }
    if bytes.len() < hlen {
        return Err(Error::Decode {
            offset: bytes.len(),
            message: format!(
                "stream truncated in the header ({} bytes; the header and chunk index need {hlen})",
                bytes.len()
            ),
        });
    }
    let stored = u32::from_le_bytes([
        bytes[hlen - 4],
        bytes[hlen - 3],
        bytes[hlen - 2],
        bytes[hlen - 1],
    ]);
    if !crc_matches(&bytes[..hlen - 4], stored) {
        return Err(Error::Decode {
            offset: 0,
            message: "header and chunk index fail their checksum".into(),
        });
    }
    let mut r = Reader {
        data: &bytes[..hlen - 4],
        pos: 10,
    };
    let header = Header::read(&mut r)?;
    let at = r.pos;
    let n = r.varint()? as usize;
    if n > (r.data.len() - r.pos) / ENTRY_MIN {
        return Err(Error::Decode {
            offset: at,
            message: format!("chunk index: {n} chunks do not fit in the header"),
        });
    }
    let mut chunks = Vec::with_capacity(n);
    let mut expected = hlen as u64;
    for i in 0..n {
        let at = r.pos;
        let kind = r.bytes(1)?[0];
        let kind = ChunkKind::from_code(kind).ok_or_else(|| Error::Decode {
            offset: at,
            message: format!("chunk index entry {i}: unknown chunk kind {kind}"),
        })?;
        let id = r.varint()?;
        let len = r.varint()?;
        let crc = r.u32()?;
        let nm = r.varint()? as usize;
        if nm > r.data.len() - r.pos {
            return Err(Error::Decode {
                offset: at,
                message: format!("chunk index entry {i}: {nm} marks do not fit in the header"),
            });
        }
        let mut marks = Vec::with_capacity(nm);
        let mut prev = 0u32;
        for _ in 0..nm {
            let m = prev.saturating_add(r.varint()?);
            prev = m;
            if m > len {
                return Err(Error::Decode {
                    offset: at,
                    message: format!(
                        "chunk index entry {i}: plane marks are not increasing within the chunk"
                    ),
                });
            }
            marks.push(m);
        }
        let offset = expected;
        expected = offset + len as u64;
        chunks.push(ChunkEntry {
            kind,
            id,
            offset,
            len,
            crc,
            marks,
        });
    }
    if r.pos != r.data.len() {
        return Err(Error::Decode {
            offset: r.pos,
            message: "chunk index: trailing bytes in the header".into(),
        });
    }
    Ok(Container {
        header,
        header_len: hlen,
        chunks,
    })
}

impl Container {
    /// Total stream length the index declares.
    pub fn total_len(&self) -> u64 {
        self.chunks
            .last()
            .map_or(self.header_len as u64, |c| c.offset + c.len as u64)
    }

    /// The base mesh chunk (chunk 0) of `bytes`, whole and checked: a decoder needs all of it.
    ///
    /// # Errors
    /// [`Error::Decode`] saying how many bytes are needed if `bytes` ends inside it; naming it
    /// if it fails its checksum.
    pub fn base_chunk<'a>(&self, bytes: &'a [u8]) -> Result<&'a [u8]> {
        let (data, whole) = self.chunk(bytes, 0)?;
        if !whole {
            let e = &self.chunks[0];
            return Err(Error::Decode {
                offset: bytes.len(),
                message: format!(
                    "stream truncated in the base mesh chunk (the first {} bytes are needed)",
                    e.offset + e.len as u64
                ),
            });
        }
        Ok(data)
    }

    /// Checks a decoded base mesh's counts (`vertices`, `faces`, face `corners`) against
    /// the header's.
    ///
    /// # Errors
    /// [`Error::Decode`] at the base chunk if any differs.
    pub fn check_base_counts(&self, vertices: usize, faces: usize, corners: usize) -> Result<()> {
        let h = &self.header;
        if vertices != h.base_vertices as usize
            || faces != h.base_faces as usize
            || corners != h.base_corners as usize
        {
            return Err(Error::Decode {
                offset: self.chunks[0].offset as usize,
                message: "the base mesh chunk does not match the header's base counts".into(),
            });
        }
        Ok(())
    }

    /// The bytes of chunk `i` present in `bytes` (all of them, a prefix, or none) and whether
    /// the chunk is complete. A complete chunk is checked against its CRC.
    ///
    /// # Errors
    /// [`Error::Decode`] naming the chunk if it is complete and fails its checksum.
    pub fn chunk<'a>(&self, bytes: &'a [u8], i: usize) -> Result<(&'a [u8], bool)> {
        let c = &self.chunks[i];
        let start = (c.offset.min(bytes.len() as u64)) as usize;
        let end = ((c.offset + c.len as u64).min(bytes.len() as u64)) as usize;
        let data = &bytes[start..end];
        let complete = data.len() == c.len as usize;
        if complete && !crc_matches(data, c.crc) {
            return Err(Error::Decode {
                offset: start,
                message: format!("{} fails its checksum (corrupt data)", c.name(i)),
            });
        }
        Ok((data, complete))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> Header {
        Header {
            wavelet: 1,
            flags: 2,
            split: 0,
            layout: 0,
            levels: 3,
            bits: 12,
            base_bits: 16,
            level_weight: 0,
            top: [11, 9, -1],
            tangent_shift: 0,
            input_vertices: 42,
            bbox: [DVec3::ZERO, DVec3::ONE],
            steps: [0.5, 0.25, 1.0],
            grid_origin: DVec3::ZERO,
            grid_step: 1e-3,
            base_vertices: 12,
            base_faces: 20,
            base_corners: 60,
            num_trees: 30,
        }
    }

    #[test]
    fn crc32_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        // Slicing by 8 equals the bytewise definition at every length and alignment.
        let bytewise = |d: &[u8]| {
            let mut c = !0u32;
            for &b in d {
                c ^= b as u32;
                for _ in 0..8 {
                    c = if c & 1 != 0 {
                        0xEDB8_8320 ^ (c >> 1)
                    } else {
                        c >> 1
                    };
                }
            }
            !c
        };
        let data: Vec<u8> = (0..300u32)
            .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
            .collect();
        for start in 0..9 {
            for end in start..data.len() {
                assert_eq!(crc32(&data[start..end]), bytewise(&data[start..end]));
            }
        }
    }

    #[test]
    fn write_read_round_trip_and_corruption() {
        let chunks = vec![
            (ChunkKind::Base, 0, vec![1, 2, 3], vec![]),
            (ChunkKind::Tree, 5, vec![4, 5, 6, 7], vec![2, 4]),
        ];
        let s = write(&header(), &chunks).unwrap();
        let c = read(&s).unwrap();
        assert_eq!(c.header, header());
        assert_eq!(c.chunks.len(), 2);
        assert_eq!(c.chunks[1].marks, vec![2, 4]);
        assert_eq!(c.total_len(), s.len() as u64);
        assert_eq!(c.chunk(&s, 1).unwrap(), (&[4u8, 5, 6, 7][..], true));
        assert_eq!(
            c.chunk(&s[..s.len() - 1], 1).unwrap(),
            (&[4u8, 5, 6][..], false)
        );
        let mut bad = s.clone();
        let n = bad.len();
        bad[n - 2] ^= 1;
        let e = c.chunk(&bad, 1).unwrap_err().to_string();
        assert!(e.contains("chunk 1 (tree 5) fails its checksum"), "{e}");
        let mut bad = s.clone();
        bad[20] ^= 1;
        assert!(read(&bad).unwrap_err().to_string().contains("checksum"));
        for cut in 0..c.header_len {
            assert!(read(&s[..cut]).is_err());
        }
        // Offsets are derived from the lengths; an entry costs 8 bytes plus its marks.
        assert_eq!(c.chunks[0].offset, c.header_len as u64);
        assert_eq!(c.chunks[1].offset, c.header_len as u64 + 3);
        assert_eq!(c.header_len, 10 + HEADER_FIELDS + 1 + 8 + 8 + 2 + 4);
    }

    #[test]
    fn malformed_index_numbers_are_errors() {
        let s = write(&header(), &[(ChunkKind::Base, 0, vec![1, 2, 3], vec![])]).unwrap();
        let at = 10 + HEADER_FIELDS;
        // Rewrites the index bytes after `at` and fixes the header CRC, so that only the
        // index itself is wrong.
        let patch = |index: &[u8]| {
            let mut b = s[..at].to_vec();
            b.extend_from_slice(index);
            let hl = (b.len() + 4) as u32;
            b[6..10].copy_from_slice(&hl.to_le_bytes());
            let c = crc32(&b);
            b.extend_from_slice(&c.to_le_bytes());
            read(&b).unwrap_err().to_string()
        };
        let e = patch(&[0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x01]);
        assert!(e.contains("longer than 5 bytes"), "{e}");
        let e = patch(&[0xFF, 0xFF, 0xFF, 0xFF, 0x7F]);
        assert!(e.contains("overflows"), "{e}");
        let e = patch(&[100, 0, 0, 3, 0, 0, 0, 0, 0]);
        assert!(e.contains("do not fit"), "{e}");
        let e = patch(&[1, 9, 0, 3, 0, 0, 0, 0, 0]);
        assert!(e.contains("unknown chunk kind"), "{e}");
        let e = patch(&[1, 0, 0, 3, 0, 0, 0, 0, 1, 4]);
        assert!(e.contains("marks"), "{e}");
        let e = patch(&[1, 0, 0, 3, 0, 0, 0, 0, 0, 0]);
        assert!(e.contains("trailing"), "{e}");
    }
}

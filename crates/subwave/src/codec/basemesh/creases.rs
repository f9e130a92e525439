//! Crease and corner tags: run-length coded flags (Lavoué et al., *Compression of CAD meshes
//! by subdivision inversion*, §VII.1: "flags on the edges (sharp or not) are represented by
//! an n-sized binary vector, encoded by a run length algorithm").
//!
//! The edges of the decoded mesh are numbered in order of first appearance (the
//! [`crate::Topology`] convention), so the flag vector follows the connectivity traversal and
//! crease lines give short runs. The vector is coded as its number of ones, then the lengths
//! of the runs of zeros before each one (adaptive Elias-gamma, [`UInt`]); then each tag's
//! sharpness: "same as the previous tag" (an adaptive bit; the first is compared with
//! [`SHARPNESS_INFINITE`]) or the 64 bits of the `f64`. Corner (vertex) tags are coded the
//! same way over the vertex order.

use std::collections::{BTreeMap, HashMap};

use crate::codec::rangecoder::{CountedBit, Decoder, Encoder, UInt};
use crate::mesh::{EdgeTag, Mesh, VertexTag, SHARPNESS_INFINITE};

use super::connectivity::corners_by_edge;
use super::ChunkError;

/// The edges of `mesh` in order of first appearance, each in its first traversal direction.
pub(crate) fn edge_list(mesh: &Mesh) -> Vec<[u32; 2]> {
    let idx = &mesh.face_indices;
    // Corner -> next corner in its face.
    let mut next = vec![0u32; idx.len()];
    for w in mesh.face_offsets.windows(2) {
        let (a, b) = (w[0] as usize, w[1] as usize);
        for (c, nx) in next.iter_mut().enumerate().take(b).skip(a) {
            *nx = if c + 1 == b { a as u32 } else { c as u32 + 1 };
        }
    }
    let order = corners_by_edge(idx, &next);
    let key = |c: u32| {
        let (a, b) = (idx[c as usize], idx[next[c as usize] as usize]);
        (a.min(b), a.max(b))
    };
    // Mark the first corner (in corner order) of each edge; buckets are sorted by corner
    // within equal keys, so that is the first of each run.
    let mut first = vec![false; idx.len()];
    let mut i = 0;
    while i < order.len() {
        first[order[i] as usize] = true;
        let k = key(order[i]);
        let mut j = i + 1;
        while j < order.len() && key(order[j]) == k {
            j += 1;
        }
        i = j;
    }
    (0..idx.len())
        .filter(|&c| first[c])
        .map(|c| [idx[c], idx[next[c] as usize]])
        .collect()
}

struct Models {
    count: UInt<CountedBit>,
    gap: UInt<CountedBit>,
    same: CountedBit,
}

impl Models {
    fn new() -> Self {
        Models {
            count: UInt::new(),
            gap: UInt::new(),
            same: CountedBit::default(),
        }
    }
}

/// Codes a sorted list of tagged ids with their sharpness.
fn encode_flags(m: &mut Models, enc: &mut Encoder, tags: &[(u32, f64)]) {
    m.count.encode(enc, tags.len() as u32);
    let mut next = 0u32;
    let mut prev_s = SHARPNESS_INFINITE;
    for &(id, s) in tags {
        m.gap.encode(enc, id - next);
        next = id + 1;
        let same = s.to_bits() == prev_s.to_bits();
        enc.bit(&mut m.same, same);
        if !same {
            let b = s.to_bits();
            enc.raw((b >> 32) as u32, 32);
            enc.raw(b as u32, 32);
        }
        prev_s = s;
    }
}

/// Decodes the tags after their `count` (decoded by the caller), `n` the number of ids.
fn decode_flags(
    m: &mut Models,
    dec: &mut Decoder,
    count: usize,
    n: usize,
    what: &str,
) -> std::result::Result<Vec<(u32, f64)>, ChunkError> {
    if count > n {
        return Err(ChunkError::new(
            dec,
            format!("{count} {what} tags but only {n} {what}s"),
        ));
    }
    let mut out = Vec::with_capacity(count);
    let mut next = 0u64;
    let mut prev_s = SHARPNESS_INFINITE;
    for _ in 0..count {
        let id = next + m.gap.decode(dec) as u64;
        if id >= n as u64 {
            return Err(ChunkError::new(
                dec,
                format!("{what} tag beyond the last {what}"),
            ));
        }
        next = id + 1;
        let s = if dec.bit(&mut m.same) {
            prev_s
        } else {
            let hi = dec.raw(32) as u64;
            let lo = dec.raw(32) as u64;
            f64::from_bits(hi << 32 | lo)
        };
        if dec.truncated() {
            return Err(ChunkError::new(
                dec,
                format!("the stream ends early ({what} tags)"),
            ));
        }
        // Only positive sharpness is coded: anything else is corrupt.
        if s.is_nan() || s <= 0.0 {
            return Err(ChunkError::new(
                dec,
                format!("{what} tag sharpness {s} is not positive"),
            ));
        }
        prev_s = s;
        out.push((id as u32, s));
    }
    Ok(out)
}

/// Encodes the tags of `mesh` (input ids) for the decoded mesh `decoded` (`inverse[v]` is the
/// decoded id of input vertex `v`). Returns the tags as the decoder will produce them.
pub(crate) fn encode(
    mesh: &Mesh,
    inverse: &[u32],
    decoded: &Mesh,
    enc: &mut Encoder,
) -> (Vec<EdgeTag>, Vec<VertexTag>) {
    let mut m = Models::new();
    // Edge tags.
    let mut edge_tags = Vec::new();
    let mut coded: Vec<(u32, f64)> = Vec::new();
    if !mesh.edge_tags.is_empty() {
        let edges = edge_list(decoded);
        let lookup: HashMap<(u32, u32), u32> = edges
            .iter()
            .enumerate()
            .map(|(e, &[a, b])| ((a.min(b), a.max(b)), e as u32))
            .collect();
        let mut sharp: BTreeMap<u32, f64> = BTreeMap::new();
        for t in &mesh.edge_tags {
            let (a, b) = (
                inverse[t.vertices[0] as usize],
                inverse[t.vertices[1] as usize],
            );
            if let Some(&e) = lookup.get(&(a.min(b), a.max(b))) {
                sharp.insert(e, t.sharpness);
            }
        }
        coded = sharp.into_iter().filter(|&(_, s)| s > 0.0).collect();
        edge_tags = coded
            .iter()
            .map(|&(e, s)| EdgeTag {
                vertices: edges[e as usize],
                sharpness: s,
            })
            .collect();
    }
    encode_flags(&mut m, enc, &coded);
    // Vertex tags.
    let mut sharp: BTreeMap<u32, f64> = BTreeMap::new();
    for t in &mesh.vertex_tags {
        sharp.insert(inverse[t.vertex as usize], t.sharpness);
    }
    let coded: Vec<(u32, f64)> = sharp.into_iter().filter(|&(_, s)| s > 0.0).collect();
    encode_flags(&mut m, enc, &coded);
    let vertex_tags = coded
        .iter()
        .map(|&(v, s)| VertexTag {
            vertex: v,
            sharpness: s,
        })
        .collect();
    (edge_tags, vertex_tags)
}

/// Decodes the tags of `mesh` (its faces and vertices already decoded).
pub(crate) fn decode(
    mesh: &Mesh,
    dec: &mut Decoder,
) -> std::result::Result<(Vec<EdgeTag>, Vec<VertexTag>), ChunkError> {
    let mut m = Models::new();
    let mut edge_tags = Vec::new();
    // The edge list is only needed when there are edge tags.
    let count = m.count.decode(dec) as usize;
    if count > 0 {
        let edges = edge_list(mesh);
        for (e, s) in decode_flags(&mut m, dec, count, edges.len(), "edge")? {
            edge_tags.push(EdgeTag {
                vertices: edges[e as usize],
                sharpness: s,
            });
        }
    }
    let count = m.count.decode(dec) as usize;
    let vertex_tags = decode_flags(&mut m, dec, count, mesh.num_vertices(), "vertex")?
        .into_iter()
        .map(|(v, s)| VertexTag {
            vertex: v,
            sharpness: s,
        })
        .collect();
    Ok((edge_tags, vertex_tags))
}

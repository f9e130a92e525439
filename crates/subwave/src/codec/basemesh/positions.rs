//! Vertex positions: uniform quantization and parallelogram prediction.
//!
//! Positions are quantized on a cube grid over the bounding box ([`super::Quantization`]) and
//! coded in decoded vertex order (the connectivity traversal's order), each predicted from
//! vertices already decoded and its residual entropy coded:
//!
//! - **parallelogram rule** (Touma & Gotsman, *Triangle Mesh Compression*, GI 1998, §4):
//!   for a triangle `(w, a, b)` whose neighbour across `ab` is `(b, a, c)` with `a, b, c`
//!   known, `w ≈ a + b − c`; for a quadrilateral `(w, a, c, b)` with `a, b, c` known, the same
//!   rule inside the face (Isenburg & Alliez's polygonal parallelogram prediction);
//! - **multi-way averaging** (Cohen-Or, Cohen & Irony, *Multi-way geometry encoding*, 2002):
//!   every available parallelogram is predicted and the predictions averaged;
//! - otherwise the average of the known neighbours, else the previous vertex.
//!
//! Residuals are coded per axis as a magnitude (adaptive Elias-gamma, [`UInt`]) and a raw
//! sign bit, in contexts of the axis and of the expected magnitude: the
//! average bit length of the residuals of the known neighbours, averaged with that of the
//! axes of the same vertex already coded (flat regions code small residuals cheaply, detailed
//! ones do not pollute their statistics).

use crate::codec::rangecoder::{CountedBit, Decoder, Encoder, UInt};

use super::connectivity::HalfEdges;
use super::ChunkError;

const NONE: u32 = u32::MAX;

/// Magnitude classes of the neighbourhood's residuals.
const MAGS: usize = 14;

/// Prediction tables over the decoded faces.
struct Predictor {
    he: HalfEdges,
    indices: Vec<u32>,
    /// Corners of each vertex (CSR).
    vc_offsets: Vec<u32>,
    vc: Vec<u32>,
}

impl Predictor {
    fn new(nref: usize, offsets: &[u32], indices: &[u32]) -> Self {
        let he = HalfEdges::build(offsets, indices);
        let mut vc_offsets = vec![0u32; nref + 1];
        for &v in indices {
            vc_offsets[v as usize + 1] += 1;
        }
        for i in 0..nref {
            vc_offsets[i + 1] += vc_offsets[i];
        }
        let mut fill = vc_offsets.clone();
        let mut vc = vec![0u32; indices.len()];
        for (c, &v) in indices.iter().enumerate() {
            vc[fill[v as usize] as usize] = c as u32;
            fill[v as usize] += 1;
        }
        Predictor {
            he,
            indices: indices.to_vec(),
            vc_offsets,
            vc,
        }
    }

    /// The prediction of vertex `w` from vertices `< w` and the magnitude class of
    /// the known neighbours' residuals.
    fn predict(&self, w: u32, q: &[[u32; 3]], res_mag: &[u8], maxq: i64) -> ([i64; 3], usize) {
        let known = |v: u32| v < w;
        let he = &self.he;
        let vert = |c: u32| self.indices[c as usize];
        let mut sum = [0i64; 3];
        let mut n = 0i64;
        let mut nsum = [0i64; 3];
        let mut nn = 0i64;
        let mut mag_sum = 0u32;
        let mut mag_n = 0u32;
        let corners = &self.vc
            [self.vc_offsets[w as usize] as usize..self.vc_offsets[w as usize + 1] as usize];
        for &c in corners {
            let cn = he.next[c as usize];
            let cp = he.prev[c as usize];
            let (a, b) = (vert(cn), vert(cp));
            for x in [a, b] {
                if known(x) {
                    let p = q[x as usize];
                    for i in 0..3 {
                        nsum[i] += p[i] as i64;
                    }
                    nn += 1;
                    mag_sum += res_mag[x as usize] as u32;
                    mag_n += 1;
                }
            }
            if !(known(a) && known(b)) {
                continue;
            }
            let nnext = he.next[cn as usize];
            let opposite = if nnext == cp {
                // Triangle (w, a, b): the vertex across edge a→b.
                let t = he.twin[cn as usize];
                if t == NONE {
                    NONE
                } else {
                    let t2 = he.next[he.next[t as usize] as usize];
                    // Only a triangle on the other side.
                    if he.next[t2 as usize] == t {
                        vert(t2)
                    } else {
                        NONE
                    }
                }
            } else if he.next[nnext as usize] == cp {
                // Quad (w, a, c, b).
                vert(nnext)
            } else {
                NONE
            };
            if opposite != NONE && known(opposite) {
                let (pa, pb, pc) = (q[a as usize], q[b as usize], q[opposite as usize]);
                for i in 0..3 {
                    sum[i] += pa[i] as i64 + pb[i] as i64 - pc[i] as i64;
                }
                n += 1;
            }
        }
        let mag = (mag_sum + mag_n / 2)
            .checked_div(mag_n)
            .map_or(MAGS - 1, |x| x.min(MAGS as u32 - 1) as usize);
        let avg = |s: [i64; 3], n: i64| s.map(|x| (2 * x + n).div_euclid(2 * n).clamp(0, maxq));
        if n > 0 {
            (avg(sum, n), mag)
        } else if nn > 0 {
            (avg(nsum, nn), mag)
        } else if w > 0 {
            (q[w as usize - 1].map(|x| x as i64), mag)
        } else {
            ([maxq / 2 + 1; 3].map(|x| x.min(maxq)), mag)
        }
    }
}

/// Size of a residual vector: the bit length of its largest component.
fn mag_class(r: [i64; 3]) -> u8 {
    let m = r.iter().map(|x| x.unsigned_abs()).max().unwrap_or(0);
    (64 - m.leading_zeros()) as u8
}

/// The residual models: one adaptive magnitude model per context (expected magnitude × axis;
/// the axis matters for flat or extruded models, whose residuals along one axis are all
/// zero); signs are raw bits (they are equiprobable). Small meshes have too few residuals to
/// train many contexts: the magnitude classes are merged below [`FULL_CONTEXTS`] vertices
/// and dropped below [`SOME_CONTEXTS`].
struct Models {
    mags: Vec<UInt<CountedBit>>,
    /// `None`: one class; `Some(s)`: class = expected bit length >> s.
    shift: Option<u32>,
}

/// Referenced vertices from which every magnitude class has its own context.
const FULL_CONTEXTS: usize = 16_384;
/// Referenced vertices from which magnitude classes (merged by two) are used at all.
const SOME_CONTEXTS: usize = 1_024;

impl Models {
    fn new(nref: usize) -> Self {
        Models {
            mags: vec![UInt::new(); MAGS * 3],
            shift: if nref >= FULL_CONTEXTS {
                Some(0)
            } else if nref >= SOME_CONTEXTS {
                Some(1)
            } else {
                None
            },
        }
    }

    /// The model of `axis`: the expected magnitude is the neighbours' residual size `nb`
    /// (a bit length), averaged with the size of the axes of this vertex already coded.
    fn model(&mut self, nb: usize, axis: usize, r: &[i64; 3]) -> &mut UInt<CountedBit> {
        let Some(shift) = self.shift else {
            return &mut self.mags[axis];
        };
        let e = if axis == 0 {
            nb
        } else {
            let m = r[..axis]
                .iter()
                .map(|x| x.unsigned_abs())
                .max()
                .unwrap_or(0);
            let own = 64 - m.leading_zeros() as usize;
            (nb + own).div_ceil(2)
        };
        &mut self.mags[(e >> shift).min(MAGS - 1) * 3 + axis]
    }

    fn encode(&mut self, enc: &mut Encoder, nb: usize, r: &mut [i64; 3], axis: usize, v: i64) {
        r[axis] = v;
        let m = self.model(nb, axis, r);
        m.encode(enc, v.unsigned_abs() as u32);
        if v != 0 {
            enc.raw((v < 0) as u32, 1);
        }
    }

    fn decode(&mut self, dec: &mut Decoder, nb: usize, r: &mut [i64; 3], axis: usize) -> i64 {
        let m = self.model(nb, axis, r);
        let a = m.decode(dec) as i64;
        let v = if a != 0 && dec.raw(1) != 0 { -a } else { a };
        r[axis] = v;
        v
    }
}

/// Encodes the quantized positions `q` (decoded order; the first `nref` are referenced by
/// the faces, in decoded ids).
pub(crate) fn encode(
    q: &[[u32; 3]],
    nref: usize,
    offsets: &[u32],
    indices: &[u32],
    bits: u32,
    enc: &mut Encoder,
) {
    let maxq = (1i64 << bits) - 1;
    let pred = Predictor::new(nref, offsets, indices);
    let mut m = Models::new(nref);
    let mut res_mag = vec![0u8; q.len()];
    for w in 0..q.len() {
        let (p, mag) = if w < nref {
            pred.predict(w as u32, q, &res_mag, maxq)
        } else {
            let p = if w > 0 {
                q[w - 1].map(|x| x as i64)
            } else {
                [maxq / 2; 3]
            };
            (p, MAGS - 1)
        };
        let mut r = [0i64; 3];
        for i in 0..3 {
            m.encode(enc, mag, &mut r, i, q[w][i] as i64 - p[i]);
        }
        res_mag[w] = mag_class(r);
    }
}

/// Decodes `nv` quantized positions (the first `nref` referenced by the faces).
pub(crate) fn decode(
    nv: usize,
    nref: usize,
    offsets: &[u32],
    indices: &[u32],
    bits: u32,
    dec: &mut Decoder,
) -> std::result::Result<Vec<[u32; 3]>, ChunkError> {
    let maxq = (1i64 << bits) - 1;
    if indices.iter().any(|&v| v as usize >= nref) {
        return Err(ChunkError::new(
            dec,
            "face index beyond the referenced vertices",
        ));
    }
    let pred = Predictor::new(nref, offsets, indices);
    let mut m = Models::new(nref);
    let mut res_mag = vec![0u8; nv];
    let mut q: Vec<[u32; 3]> = Vec::with_capacity(nv);
    for w in 0..nv {
        let (p, mag) = if w < nref {
            pred.predict(w as u32, &q, &res_mag, maxq)
        } else {
            let p = if w > 0 {
                q[w - 1].map(|x| x as i64)
            } else {
                [maxq / 2; 3]
            };
            (p, MAGS - 1)
        };
        let mut r = [0i64; 3];
        let mut x = [0u32; 3];
        for i in 0..3 {
            m.decode(dec, mag, &mut r, i);
            let v = p[i] + r[i];
            if !(0..=maxq).contains(&v) {
                return Err(ChunkError::new(
                    dec,
                    format!("vertex {w}: coordinate {i} outside the quantization grid"),
                ));
            }
            x[i] = v as u32;
        }
        if dec.truncated() {
            return Err(ChunkError::new(
                dec,
                format!("the stream ends early (vertex {w})"),
            ));
        }
        res_mag[w] = mag_class(r);
        q.push(x);
    }
    Ok(q)
}

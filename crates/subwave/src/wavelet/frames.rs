//! Local frames for detail vectors (Maret 2003 §4.4.3, Fig. 4.8; Khodakovsky et al. PGC).
//!
//! Detail vectors of wavelet analyses are strongly correlated with the surface normal. A
//! detail is therefore expressed in a local frame `(x̂, ŷ, ẑ)` with `x̂` the normal, as in
//! Maret: the local `x` coordinate carries most of the energy on smooth surfaces.
//!
//! The frame of an odd (new) vertex is computed from the **predicted** fine level (the coarse
//! level subdivided with zero details), which a decoder has before it reads the details, so
//! encoder and decoder compute bit-identical frames:
//! - normal: the normalised sum of the Newell normals (area-weighted) of the predicted fine
//!   faces around the vertex;
//! - first tangent: the parent edge's direction (predicted positions of its two ends; for the
//!   face point of a polygon split, the parent face's first edge), made orthogonal to the
//!   normal; second tangent: normal × first tangent.
//!
//! Degenerate configurations fall back deterministically (normal `+z` if the faces have no
//! area; any orthonormal tangent if the edge is parallel to the normal), so every frame is
//! orthonormal and the change of coordinates is exactly invertible up to rounding.

use glam::DVec3;
use rayon::prelude::*;

use crate::topology::Topology;

/// An orthonormal frame: `normal`, `tangent`, `bitangent = normal × tangent`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Unit normal (local `x`, Maret Fig. 4.8).
    pub normal: DVec3,
    /// Unit tangent (local `y`).
    pub tangent: DVec3,
    /// Unit bitangent (local `z`).
    pub bitangent: DVec3,
}

impl Frame {
    /// The frame with the given normal direction and first tangent direction (made
    /// orthonormal; see the module documentation for the fallbacks).
    ///
    /// Bit for bit `glam`'s `try_normalize` of the normal, then of the tangent's part
    /// orthogonal to it (each squared length computed once; inlined into the callers' loops
    /// so that the square roots and divisions of consecutive frames overlap).
    #[inline(always)]
    pub fn new(normal: DVec3, tangent: DVec3) -> Frame {
        // `try_normalize`: `x * (1 / sqrt(x·x))` when that reciprocal is finite and positive.
        let rn = 1.0 / normal.dot(normal).sqrt();
        let n = if rn.is_finite() && rn > 0.0 {
            normal * rn
        } else {
            DVec3::Z
        };
        let t = tangent - tangent.dot(n) * n;
        let tt = t.dot(t);
        let t = if tt > 1e-24 * tangent.dot(tangent) {
            let rt = 1.0 / tt.sqrt();
            if rt.is_finite() && rt > 0.0 {
                t * rt
            } else {
                n.any_orthonormal_vector()
            }
        } else {
            n.any_orthonormal_vector()
        };
        Frame {
            normal: n,
            tangent: t,
            bitangent: n.cross(t),
        }
    }

    /// Global vector → local coordinates `(normal, tangent, bitangent)`.
    #[inline]
    pub fn to_local(&self, d: DVec3) -> DVec3 {
        DVec3::new(
            d.dot(self.normal),
            d.dot(self.tangent),
            d.dot(self.bitangent),
        )
    }

    /// Local coordinates → global vector.
    #[inline]
    pub fn to_global(&self, l: DVec3) -> DVec3 {
        l.x * self.normal + l.y * self.tangent + l.z * self.bitangent
    }
}

/// Newell normal (twice the area vector) of face `f` of `topo` at positions `p`.
fn face_normal(topo: &Topology, f: usize, p: &[DVec3]) -> DVec3 {
    let fv = topo.face_vertices(f);
    let mut n = DVec3::ZERO;
    for i in 0..fv.len() {
        let j = if i + 1 == fv.len() { 0 } else { i + 1 };
        n += p[fv[i] as usize].cross(p[fv[j] as usize]);
    }
    n
}

/// The frames of the odd vertices `V_c..V_f` of a fine level, from its predicted positions.
///
/// `coarse` is the parent level's topology (it names each odd vertex's parent edge or face),
/// `fine` the child level's, `predicted` the child level's predicted positions (`V_f`
/// values). Frame `i` belongs to fine vertex `V_c + i`.
///
/// # Panics
/// If `predicted.len()` is not `fine`'s vertex count.
pub fn odd_vertex_frames(coarse: &Topology, fine: &Topology, predicted: &[DVec3]) -> Vec<Frame> {
    assert_eq!(
        predicted.len(),
        fine.num_vertices as usize,
        "predicted positions"
    );
    let nc = coarse.num_vertices as usize;
    let ne = coarse.num_edges();
    let nf = fine.num_vertices as usize;
    (nc..nf)
        .into_par_iter()
        .with_min_len(4096)
        .map(|o| {
            let n: DVec3 = fine
                .vertex_faces(o)
                .iter()
                .map(|&f| face_normal(fine, f as usize, predicted))
                .sum();
            let (a, b) = if o < nc + ne {
                let [a, b] = coarse.edge_vertices[o - nc];
                (a, b)
            } else {
                let fv = coarse.face_vertices(o - nc - ne);
                (fv[0], fv[1])
            };
            Frame::new(n, predicted[b as usize] - predicted[a as usize])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_invert() {
        let cases = [
            (DVec3::new(0.0, 0.0, 2.0), DVec3::new(1.0, 1.0, 0.0)),
            (DVec3::new(1.0, 2.0, 3.0), DVec3::new(-1.0, 0.5, 0.2)),
            (DVec3::ZERO, DVec3::X),
            (DVec3::Y, DVec3::Y),
            (DVec3::Y, DVec3::ZERO),
        ];
        for (n, t) in cases {
            let f = Frame::new(n, t);
            for (a, b) in [
                (f.normal, f.tangent),
                (f.normal, f.bitangent),
                (f.tangent, f.bitangent),
            ] {
                assert!(a.dot(b).abs() < 1e-15);
            }
            for v in [f.normal, f.tangent, f.bitangent] {
                assert!((v.length() - 1.0).abs() < 1e-15);
            }
            // Right-handed, normal along the given normal.
            assert!((f.normal.cross(f.tangent) - f.bitangent).length() < 1e-15);
            if n != DVec3::ZERO {
                assert!((f.normal - n.normalize()).length() < 1e-15);
            }
            let d = DVec3::new(0.3, -1.7, 2.9);
            assert!((f.to_global(f.to_local(d)) - d).length() < 1e-14);
            assert!((f.to_local(d).x - d.dot(f.normal)).abs() < 1e-15);
        }
    }
}

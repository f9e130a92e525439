//! Face-varying data (texture coordinates with seams) through refinement, linearly.
//!
//! Face-varying values belong to face corners, so a texture seam is an edge whose two faces
//! index different values. They are interpolated linearly on each face, OpenSubdiv's
//! `FVAR_LINEAR_ALL`: a child corner at a parent corner keeps its value, a child corner at an
//! edge point takes the mean of the edge's two corner values in that face, a face point the mean
//! of the face's corner values. Values are shared between faces exactly where the parent values
//! were (same pair of value indices across an edge), so seams stay seams and nothing else is
//! duplicated. Child faces follow the ordering contract of [`super::refine`].

use std::collections::HashMap;

use super::refine::Split;
use crate::mesh::FaceVarying;

/// Refines face-varying data `levels` times along with faces `face_offsets` (the level-0
/// faces; `fv.indices` has one entry per face corner).
///
/// Returns the finest level's data, one index per corner of the finest faces in the order of
/// [`super::refine`]'s face contract (for [`Split::QuadTri`], triangles split 1-to-4 and quads
/// around a face point).
///
/// # Panics
/// If `fv.indices.len()` differs from the corner count of `face_offsets`, or `split` is
/// `Triangles` and a face is not a triangle (callers check both: [`crate::Mesh::check_indices`]
/// and the scheme's arity check).
pub fn refine_linear(
    fv: &FaceVarying,
    face_offsets: &[u32],
    split: Split,
    levels: u32,
) -> FaceVarying {
    assert_eq!(
        fv.indices.len(),
        *face_offsets.last().unwrap_or(&0) as usize,
        "one face-varying index per corner"
    );
    let mut coords = fv.coords.clone();
    let mut indices = fv.indices.clone();
    let mut offsets = face_offsets.to_vec();
    for _ in 0..levels {
        let mut mids: HashMap<(u32, u32), u32> = HashMap::new();
        let mut mid = |coords: &mut Vec<[f64; 2]>, a: u32, b: u32| -> u32 {
            let key = (a.min(b), a.max(b));
            if a == b {
                return a;
            }
            *mids.entry(key).or_insert_with(|| {
                let (p, q) = (coords[a as usize], coords[b as usize]);
                coords.push([0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]);
                coords.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(4 * indices.len());
        let mut next_offsets = vec![0u32];
        for w in offsets.windows(2) {
            let u = &indices[w[0] as usize..w[1] as usize];
            let n = u.len();
            let polygon = match split {
                Split::Triangles => false,
                Split::Polygons => true,
                Split::QuadTri => n != 3,
            };
            match polygon {
                false => {
                    assert_eq!(n, 3, "triangle split of a face with {n} corners");
                    let m01 = mid(&mut coords, u[0], u[1]);
                    let m12 = mid(&mut coords, u[1], u[2]);
                    let m20 = mid(&mut coords, u[2], u[0]);
                    for child in [
                        [u[0], m01, m20],
                        [u[1], m12, m01],
                        [u[2], m20, m12],
                        [m01, m12, m20],
                    ] {
                        next.extend_from_slice(&child);
                        next_offsets.push(next.len() as u32);
                    }
                }
                true => {
                    let mut c = [0.0; 2];
                    for &i in u {
                        c[0] += coords[i as usize][0];
                        c[1] += coords[i as usize][1];
                    }
                    coords.push([c[0] / n as f64, c[1] / n as f64]);
                    let center = coords.len() as u32 - 1;
                    let m: Vec<u32> = (0..n)
                        .map(|i| mid(&mut coords, u[i], u[(i + 1) % n]))
                        .collect();
                    for i in 0..n {
                        next.extend_from_slice(&[u[i], m[i], center, m[(i + n - 1) % n]]);
                        next_offsets.push(next.len() as u32);
                    }
                }
            }
        }
        indices = next;
        offsets = next_offsets;
    }
    FaceVarying { coords, indices }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles sharing an edge, with a seam on it (the second face indexes its own copies
    /// of the shared corners' values).
    fn seam() -> (FaceVarying, Vec<u32>) {
        let fv = FaceVarying {
            coords: vec![
                [0.0, 0.0],
                [1.0, 0.0],
                [0.0, 1.0],
                [1.0, 0.0],
                [0.0, 1.0],
                [1.0, 1.0],
            ],
            indices: vec![0, 1, 2, 3, 5, 4],
        };
        (fv, vec![0, 3, 6])
    }

    #[test]
    fn triangles_interpolate_linearly_and_keep_seams() {
        let (fv, offsets) = seam();
        let r = refine_linear(&fv, &offsets, Split::Triangles, 1);
        assert_eq!(r.indices.len(), 2 * 4 * 3);
        // First face's children: (u0 m01 m20), ...
        let c = |k: usize| r.coords[r.indices[k] as usize];
        assert_eq!(c(0), [0.0, 0.0]);
        assert_eq!(c(1), [0.5, 0.0]);
        assert_eq!(c(2), [0.0, 0.5]);
        // The seam edge (1,2) / (3,4) gets two distinct midpoints with the same value.
        let mid_a = r.indices[4]; // child 1 of face 0: (u1, m12, m01)
        let mid_b = r.indices[12 + 2]; // child 0 of face 1: (u3, m35, m43)
        assert_eq!(r.coords[mid_a as usize], [0.5, 0.5]);
        assert_eq!(r.coords[mid_b as usize], [0.5, 0.5]);
        assert_ne!(mid_a, mid_b);
        // 6 coords + 3 midpoints per face (none shared across the seam).
        assert_eq!(r.coords.len(), 6 + 6);
    }

    #[test]
    fn shared_values_are_shared_and_quads_get_centres() {
        let fv = FaceVarying {
            coords: vec![
                [0.0, 0.0],
                [1.0, 0.0],
                [1.0, 1.0],
                [0.0, 1.0],
                [2.0, 0.0],
                [2.0, 1.0],
            ],
            indices: vec![0, 1, 2, 3, 1, 4, 5, 2],
        };
        let r = refine_linear(&fv, &[0, 4, 8], Split::Polygons, 2);
        // Level 1: 6 + 2 centres + 7 edge midpoints (edge 1-2 shared) = 15 coords.
        let l1 = refine_linear(&fv, &[0, 4, 8], Split::Polygons, 1);
        assert_eq!(l1.coords.len(), 15);
        assert_eq!(l1.coords[l1.indices[2] as usize], [0.5, 0.5]);
        assert_eq!(r.indices.len(), 2 * 16 * 4);
        // Every value stays inside the two unit squares' span.
        assert!(r
            .coords
            .iter()
            .all(|c| (0.0..=2.0).contains(&c[0]) && (0.0..=1.0).contains(&c[1])));
    }
}

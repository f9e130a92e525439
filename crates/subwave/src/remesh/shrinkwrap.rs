//! Shrink-wrapping: the remeshing fallback when the parameterization fails.
//!
//! Kobbelt, Vorsatz, Labsik & Seidel, "A shrink wrapping approach to remeshing polygonal
//! surfaces" (Eurographics 1999), as Bertram et al. §5.3 used it to obtain semi-regular
//! meshes: a coarse mesh of the right topology (here the simplified base domain, whose
//! vertices are input vertices) is refined level by level; after each split the new vertices
//! (edge midpoints, face centroids) are projected onto the closest point of the input, and a
//! few rounds of tangential relaxation with re-projection ([`super::resample::relax`]) spread
//! them evenly. No parameterization is needed, so it works whatever the tracking did, but
//! closest-point projection can fold the mesh where the coarse mesh is far from the input
//! (deep concavities); it is therefore the fallback, reported as such.

use glam::DVec3;
use rayon::prelude::*;

use super::resample::{relax, Projector};
use crate::hierarchy::Hierarchy;
use crate::subdivision::refine::Split;

/// Finest positions of `h` by shrink-wrapping from its base positions; `fixed_base` says
/// which base vertices must not move (boundary and feature corners); `iterations` rounds of
/// relaxation per level.
pub fn shrinkwrap(
    h: &Hierarchy,
    fixed_base: &[bool],
    proj: &Projector,
    iterations: u32,
    progress: &mut dyn FnMut(f64),
) -> Vec<DVec3> {
    let levels = h.levels();
    let mut pos: Vec<DVec3> = h.base.positions.clone();
    for l in 0..levels {
        let t = &h.topologies[l];
        let nv = pos.len();
        let mut next = pos.clone();
        next.extend(
            t.edge_vertices
                .iter()
                .map(|&[a, b]| 0.5 * (pos[a as usize] + pos[b as usize])),
        );
        if h.split == Split::Polygons {
            next.extend((0..t.num_faces()).map(|f| {
                let fv = t.face_vertices(f);
                fv.iter().map(|&v| pos[v as usize]).sum::<DVec3>() / fv.len() as f64
            }));
        }
        let mut hints = vec![u32::MAX; next.len()];
        next[nv..]
            .par_iter_mut()
            .zip(&mut hints[nv..])
            .for_each(|(p, h)| (*p, *h) = proj.closest(*p));
        let mut fixed = vec![false; next.len()];
        fixed[..fixed_base.len()].copy_from_slice(fixed_base);
        relax(
            &mut next,
            &mut hints,
            &h.topologies[l + 1],
            &fixed,
            proj,
            iterations,
            0.5,
        );
        pos = next;
        progress((l + 1) as f64 / levels as f64);
    }
    pos
}

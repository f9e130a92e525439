//! Coarse-to-fine relaxation of the resampling parameters in the base domain.
//!
//! Lee et al., "MAPS" (SIGGRAPH 1998), §4 ("Remeshing"): the dyadic points of the base
//! domain, mapped through the parameterization, sample the input unevenly where the
//! parameterization compresses it. The simplification flattens every removed vertex's star,
//! so a protrusion that the base mesh cuts off (the bunny's ear tips, 1 cm past the nearest
//! base vertex) has a small image, and the dyadic points undersample it five-fold: at 5
//! levels, 0.1% of the bunny's input faces held 35% of the squared distance to the remesh,
//! all at the ear tips. MAPS smooths the parameterization in the parameter domain; here
//! the *samples* are smoothed there, level by level, before the remesh is built:
//!
//! 1. level 0 is the base vertices; the vertices of level `l` are those of level `l − 1`
//!    plus one per edge: its dyadic point moved by the mean displacement of its edge's ends
//!    (from their dyadic points to their relaxed ones), all in the frame of its base
//!    triangle ([`ParamMap::to_frame`]), which is the midpoint of the relaxed ends measured
//!    from the dyadic midpoint (the parallelogram unfoldings disagree around base vertices
//!    of valence other than six; measuring from the dyadic midpoint cancels that, and
//!    unmoved ends give the dyadic point exactly). A vertex on a boundary or feature base
//!    edge keeps its dyadic parameter, so it stays on the input's curve;
//! 2. a few Jacobi steps ([`schedule`]) move every other vertex of level `l` to the
//!    centroid of its star's faces in the parameter domain, each face weighted by the area
//!    of its image on the input: faces that are large on the surface pull the vertex
//!    towards them, so the samples spread evenly over the surface, at the scale of level
//!    `l` first (few vertices, long steps) and finer at each level after.
//!
//! A move is kept only if no face of the star turns over in the parameter domain nor on the
//! surface (normal within 84° of its old one, and not against the input triangle the vertex
//! lands on), the new point lies in the image of an input triangle, and it crosses no
//! boundary or feature base edge; simultaneous moves of neighbours that turn a face over
//! are undone. Vertices of boundary and feature chains, and base vertices, never move.
//!
//! Measured at 5 levels over 200 base faces: bunny 79.6 → 81.0 dB, Hausdorff 0.51% → 0.34%
//! of the diagonal; cow 65.0 → 73.6 dB, teapot 82.0 → 85.8 dB; but the repairs after it do
//! not always end with fewer flipped faces (cow 44 → 53), so [`super::remesh`] keeps the
//! dyadic sampling where that one ends with fewer.

use glam::DVec3;
use rayon::prelude::*;

use super::param::ParamMap;
use super::resample::level_params;
use super::simplify::{PairSet, Param};
use crate::hierarchy::Hierarchy;
use crate::topology::Topology;

/// How far outside every input triangle's image (smallest barycentric coordinate) a moved
/// parameter may land.
const INSIDE: f64 = -1e-9;

/// Vertices with more faces around them than this do not move.
const MAX_STAR: usize = 16;

/// The steps at level `l` of `levels`, with `faces` faces, for a budget of `n`
/// ([`super::RemeshOptions`]'s `param_relax_iterations`): none on the first two levels
/// (their few vertices span whole base triangles; relaxing them measured worse on the
/// bunny), `n` on the levels in between up to 65,536 faces and `⌈n / 3⌉` on larger ones,
/// `⌈n / 6⌉` on the finest (the most vertices, the shortest moves), none on levels over
/// 262,144 faces. Bunny at 6 levels: `n` steps on level 5 took 4.3 s (88.8 dB, 23 flipped
/// faces), `⌈n / 3⌉` 0.9 s (89.4 dB, 16 flipped).
pub fn schedule(n: u32, l: usize, levels: usize, faces: usize) -> u32 {
    if (l < 3 && l < levels) || faces > 1 << 18 {
        0
    } else if l < levels && faces <= 1 << 16 {
        n
    } else if l < levels {
        n.div_ceil(3)
    } else {
        n.div_ceil(6)
    }
}

/// Twice the signed area of the triangle of frame points `a`, `b`, `c` (coordinates 1 and
/// 2 of the barycentric frame).
fn orient(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    (b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1])
}

/// Dyadic parameter `d` moved by the mean displacement of its edge's ends (from their
/// dyadic parameters to their relaxed ones), all in the frame of `d`'s base triangle:
/// the midpoint of the relaxed ends, measured from where the dyadic midpoint is (so that
/// unmoved ends give `d` exactly, and the unfoldings' disagreement around base vertices
/// cancels). `None` when an end is outside `d`'s chart or the point leaves it.
fn shifted(map: &ParamMap, d: &Param, ends: [(&Param, &Param); 2]) -> Option<Param> {
    let t = d.face;
    let mut c = d.bary;
    for (old, new) in ends {
        let (o, n) = (map.to_frame(t, old)?, map.to_frame(t, new)?);
        for k in 0..3 {
            c[k] += 0.5 * (n[k] - o[k]);
        }
    }
    if c == d.bary {
        return Some(*d);
    }
    map.relocate(t, c)
}

/// The parameters of the vertices of level `levels` of `h` (a hierarchy of triangle splits
/// over the base triangles of `map`), relaxed coarse to fine as the module documentation
/// describes, with `iterations(l)` Jacobi steps at level `l`. `chains` are the boundary and
/// feature base edges (sorted vertex pairs). Without steps, the result is
/// [`level_params`]'s dyadic parameters.
///
/// The result has one parameter per vertex of level `levels`, in the ordering contract.
pub fn relaxed_params(
    h: &Hierarchy,
    levels: usize,
    map: &ParamMap,
    chains: &PairSet,
    iterations: impl Fn(usize) -> u32,
) -> Vec<Param> {
    let base_tris = map.base_triangles();
    let mut params = level_params(h, 0, false);
    for l in 1..=levels {
        let prev = &h.topologies[l - 1];
        let topo = &h.topologies[l];
        let dyadic = level_params(h, l, false);
        let nprev = prev.num_vertices as usize;
        let fixed: Vec<bool> = dyadic
            .par_iter()
            .map(|p| p.is_pinned(base_tris[p.face as usize], chains))
            .collect();
        let mut next: Vec<Param> = Vec::with_capacity(dyadic.len());
        next.extend_from_slice(&params);
        next.par_extend((0..prev.num_edges()).into_par_iter().map(|e| {
            let v = nprev + e;
            let [a, b] = prev.edge_vertices[e];
            let (a, b) = (a as usize, b as usize);
            if fixed[v] || (params[a] == dyadic[a] && params[b] == dyadic[b]) {
                return dyadic[v];
            }
            shifted(
                map,
                &dyadic[v],
                [(&dyadic[a], &params[a]), (&dyadic[b], &params[b])],
            )
            .filter(|m| map.locate(m).inside >= INSIDE)
            .unwrap_or(dyadic[v])
        }));
        let steps = iterations(l);
        if steps > 0 {
            let mut images: Vec<DVec3> = next
                .par_iter()
                .map(|p| map.point(&map.locate(p)).unwrap_or(DVec3::NAN))
                .collect();
            // Vertices by base triangle, so that each thread's point locations stay in a
            // few triangles' images (a visiting order only: the steps are Jacobi steps).
            let mut order: Vec<u32> = (0..next.len() as u32).collect();
            order.par_sort_by_key(|&v| next[v as usize].face);
            for _ in 0..steps {
                step(&mut next, &mut images, topo, map, &fixed, chains, &order);
            }
        }
        params = next;
    }
    params
}

/// Whether a face whose corner images went from `old` to `new` stayed upright on the
/// surface: its normal keeps within about 84° of the old one (as [`super::resample::relax`]
/// guards its moves).
fn upright(old: [DVec3; 3], new: [DVec3; 3]) -> bool {
    let n0 = (old[1] - old[0]).cross(old[2] - old[0]);
    let n1 = (new[1] - new[0]).cross(new[2] - new[0]);
    n1.dot(n0) > 0.1 * n1.length() * n0.length()
}

/// One Jacobi step of the area-weighted parameter relaxation over `topo`'s vertices,
/// visited in `order` (a permutation of them; the result does not depend on it).
/// `images[v]` is the input point of `params[v]` (updated with the moves).
fn step(
    params: &mut [Param],
    images: &mut [DVec3],
    topo: &Topology,
    map: &ParamMap,
    fixed: &[bool],
    chains: &PairSet,
    order: &[u32],
) {
    let base_tris = map.base_triangles();
    let cur: &[Param] = params;
    let moves: Vec<Option<(Param, DVec3)>> = order
        .par_iter()
        .map(|&v| {
            let v = v as usize;
            if fixed[v] {
                return None;
            }
            let p = cur[v];
            let t = p.face;
            let faces = topo.vertex_faces(v);
            if faces.is_empty() {
                return None;
            }
            let corners = |f: u32| {
                let fv = topo.face_vertices(f as usize);
                [fv[0] as usize, fv[1] as usize, fv[2] as usize]
            };
            // The star's corners in `t`'s frame, once per face (at most 16 faces).
            let mut frames = [[[0.0; 3]; 3]; MAX_STAR];
            if faces.len() > MAX_STAR {
                return None;
            }
            let mut acc = [0.0; 3];
            let mut wsum = 0.0;
            for (i, &f) in faces.iter().enumerate() {
                let c = corners(f);
                let x = c.map(|w| images[w]);
                let a = (x[1] - x[0]).cross(x[2] - x[0]).length();
                if !a.is_finite() {
                    return None;
                }
                for (j, &w) in c.iter().enumerate() {
                    let b = if w == v {
                        p.bary
                    } else {
                        map.to_frame(t, &cur[w])?
                    };
                    frames[i][j] = b;
                    for k in 0..3 {
                        acc[k] += a * b[k] / 3.0;
                    }
                }
                if orient(frames[i][0], frames[i][1], frames[i][2]) <= 0.0 {
                    return None;
                }
                wsum += a;
            }
            if wsum <= 0.0 {
                return None;
            }
            let target = acc.map(|x| x / wsum);
            // The star must not turn over in `t`'s frame.
            for (i, &f) in faces.iter().enumerate() {
                let c = corners(f);
                let mut new = frames[i];
                for (j, &w) in c.iter().enumerate() {
                    if w == v {
                        new[j] = target;
                    }
                }
                if orient(new[0], new[1], new[2]) <= 0.0 {
                    return None;
                }
            }
            // No crossing of a chain base edge of `t`.
            let tv = base_tris[t as usize];
            for k in 0..3 {
                if target[k] < 0.0 {
                    let (a, b) = (tv[(k + 1) % 3], tv[(k + 2) % 3]);
                    if chains.contains(&(a.min(b), a.max(b))) {
                        return None;
                    }
                }
            }
            let np = map.relocate(t, target)?;
            if np.bary.iter().any(|&x| x <= 0.0) || np.bary.contains(&1.0) {
                return None;
            }
            let l = map.locate(&np);
            if l.inside < INSIDE {
                return None;
            }
            let x = map.point(&l)?;
            // Nor on the surface, nor against the input where the vertex lands.
            let n_in = map.input_normal(l.tri);
            for &f in faces {
                let c = corners(f);
                let old = c.map(|w| images[w]);
                let new = c.map(|w| if w == v { x } else { images[w] });
                let n = (new[1] - new[0]).cross(new[2] - new[0]);
                if !upright(old, new) || n.dot(n_in) <= 0.0 {
                    return None;
                }
            }
            Some((np, x))
        })
        .collect();
    let mut next: Vec<Param> = params.to_vec();
    let mut next_images = images.to_vec();
    for (&v, m) in order.iter().zip(&moves) {
        if let Some((p, x)) = m {
            next[v as usize] = *p;
            next_images[v as usize] = *x;
        }
    }
    // Simultaneous moves of neighbours can still turn a face over: undo the moves of its
    // corners (a few rounds; undone vertices are back where every face was upright).
    for _ in 0..4 {
        let undo: Vec<u32> = (0..topo.num_faces())
            .into_par_iter()
            .filter_map(|f| {
                let fv = topo.face_vertices(f);
                let c = [fv[0] as usize, fv[1] as usize, fv[2] as usize];
                if !c.iter().any(|&w| next[w] != params[w]) {
                    return None;
                }
                let t = next[c[0]].face;
                let frame = |k: usize| map.to_frame(t, &next[c[k]]);
                let ok = matches!(
                    (frame(0), frame(1), frame(2)),
                    (Some(a), Some(b), Some(d)) if orient(a, b, d) > 0.0
                ) && upright(c.map(|w| images[w]), c.map(|w| next_images[w]));
                (!ok).then_some(f as u32)
            })
            .collect();
        if undo.is_empty() {
            break;
        }
        for f in undo {
            for &w in topo.face_vertices(f as usize) {
                next[w as usize] = params[w as usize];
                next_images[w as usize] = images[w as usize];
            }
        }
    }
    params.copy_from_slice(&next);
    images.copy_from_slice(&next_images);
}

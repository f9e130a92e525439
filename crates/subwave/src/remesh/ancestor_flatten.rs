//! Last resort for the folds a remesh keeps: re-subdivide the nearest unfolded ancestor.
//!
//! A semi-regular remesh is a hierarchy: every finest-level triangle `f` of an `L`-level
//! remesh descends from triangle `f >> 2(L − m)` of level `m` (the children of triangle `k`
//! are `4k..4k+3`, Maret eq. 5.7), and every vertex created at level `l + 1` sits on an edge
//! of level `l` (the ordering contract of [`crate::subdivision::refine`]). Lee et al. (MAPS,
//! SIGGRAPH 1998, §4) resolve a fold of the resampling by smoothing the parameterization
//! around it; [`super::fold_repair`] does the same on the surface, vertex by vertex and disc
//! by disc. Where that fails (thin parts of the input, coincident or folded-back sheets of
//! non-manifold inputs), this pass replaces the fold's *subtree* by a plain subdivision of
//! its ancestors. At each level `m = L − 1, L − 2, …, 0` it tries three sets of level-`m`
//! triangles: the fold's ancestor `A`, `A` with the triangles sharing an edge with it, and
//! `A` with those sharing a corner. Every vertex created after level `m` strictly inside a
//! set (all its faces descend from the set, so the set's outline stays where it is) is put
//! back at the midpoint of its parent edge, coarse to fine (midpoint subdivision, Maret
//! §3.2), either projected onto the input after each midpoint (a fresh resampling of the
//! subtrees, tried first) or left on the planes of the set's triangles (whose faces keep
//! their normals and angles); third, the set's inside is re-embedded by Tutte's embedding
//! spanned by its outline in a flattening of the input under it (as the fold repair
//! re-embeds discs), and the few faces that leaves bad are repaired with only the inside
//! free ([`repair_folds`]). The third kind is for a region the resampling crushed along a
//! line, whose coarse ancestors are slivers too: a re-subdivision keeps their shape, and the
//! fold repair's discs of rings and circles do not reach past the crushed strip (the
//! bunny's last flipped face at 6 levels, in a strip of level-4 triangles 8% of the
//! diagonal long and 1.2% wide, is opened by re-embedding its level-2 ancestor: 1 → 0).
//! The first candidate that leaves no bad face among all faces around the moved vertices
//! is kept; otherwise the one that removes the most, if any
//! removes one; otherwise nothing changes. Each change is measured over every face it can
//! alter, so the number of bad faces only goes down.
//!
//! The connectivity is untouched; base vertices (level 0) never move. A flat subtree stands
//! off a curved input by the chordal error of `A`, so the finest ancestors are tried first,
//! and faces whose centroid ends farther from the input than the fold repair's tolerance
//! count against a candidate as bad faces do.
//!
//! Measured at 5 levels over 200 base faces (`subwave remesh --levels 5 --base-faces 200
//! --repair`, 2026-12-04), flipped + degenerate faces before → after: cheburashka 1 → 0
//! (77.9 → 79.5 dB), suzanne 11 → 7, teapot 29 + 1 → 6 (84.5 → 86.8 dB), beetle 151 + 42 →
//! 82 + 14 (77.8 → 79.7 dB); cow's 19 stay (its folds are on its thin tail, in level-3 and
//! level-4 triangles next to a base vertex, where every re-subdivision turns more faces
//! over).
//!
//! With the re-embedded kind (2026-12-05, 5 levels): the cow over 200 base faces ends
//! clean (9.7 s for the default search instead of 16.5 s over 800), the beetle keeps 3
//! flipped faces instead of 5; at 4 levels every corpus mesh ends clean.
//!
//! [`patch_folds`] tries the same ancestor sets with the region's positions taken from
//! another sampling of the same hierarchy (the remesher's relaxed and dyadic samplings,
//! where both keep folds, in different places). Measured 2026-12-05 (`--base-faces 200`,
//! `--repair`): beetle at 5 levels 6 → 5 flipped faces; the bunny at 6 levels keeps its 2
//! and the cow at 4 levels (800 base faces) its 2: the other sampling's subtrees meet the
//! outline 6 to 112 bad faces worse (both are clean since the re-embedded kind).

use std::collections::{HashMap, HashSet};

use glam::DVec3;
use rayon::prelude::*;

use super::flatten::{flat_reembed, Patch};
use super::fold_repair::{face_state, faces_around, repair_folds, FaceState};
use super::resample::Projector;
use crate::topology::Topology;

/// What [`flatten_folds`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AncestorFlatten {
    /// Subtrees re-subdivided (or re-embedded, or taken from another sampling).
    pub subtrees: usize,
    /// Of them, left on their ancestor's plane (not projected onto the input).
    pub flat: usize,
    /// Vertices moved (with repeats).
    pub moved: usize,
    /// Flipped faces left (normal against the input's at the closest input point).
    pub flipped_after: usize,
    /// Degenerate faces left (as [`super::quality::Quality::degenerate`]).
    pub degenerate_after: usize,
}

/// Whether a face state is bad here: flipped or touching the flip threshold, or degenerate.
fn is_bad(s: &FaceState) -> bool {
    s.0 <= 0.0 || s.2
}

/// Whether a face state counts against a candidate: bad, or its centroid farther than
/// `off` from the input.
fn counts_against(s: &FaceState, off: f64) -> bool {
    is_bad(s) || s.3 > off
}

/// Re-subdivides the ancestors of the finest level's flipped and degenerate faces, as the
/// module documentation describes, at most `passes` passes over the bad faces.
///
/// `topologies` are the hierarchy's levels `0..=L` of triangle splits (`topologies[l]` has
/// `V_l` vertices, the first `V_{l−1}` being level `l − 1`'s, then one per edge of level
/// `l − 1` in edge order); `pos` and `hints` (an input triangle near each vertex, updated
/// for the moved ones) have `V_L` entries; `proj` is the input.
///
/// # Panics
/// If the sizes disagree with `topologies`, or a level is not a 1-to-4 triangle split of
/// the previous one.
pub fn flatten_folds(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topologies: &[Topology],
    proj: &Projector,
    passes: u32,
    off_surface: f64,
) -> AncestorFlatten {
    folds_pass(pos, hints, topologies, proj, passes, off_surface, None)
}

/// Like [`flatten_folds`], but each candidate takes the region's positions (and hints) from
/// `other`, another sampling of the same hierarchy over the same input, instead of
/// re-subdividing it: where two samplings fold in different places, a fold is patched with
/// the other's subtree where that subtree meets the kept outline without more bad faces
/// (measured in the module documentation).
///
/// # Panics
/// As [`flatten_folds`], or if `other`'s sizes differ from `pos`'.
pub fn patch_folds(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topologies: &[Topology],
    proj: &Projector,
    passes: u32,
    off_surface: f64,
    other: (&[DVec3], &[u32]),
) -> AncestorFlatten {
    assert_eq!(other.0.len(), pos.len(), "other positions per vertex");
    assert_eq!(other.1.len(), pos.len(), "other hints per vertex");
    folds_pass(
        pos,
        hints,
        topologies,
        proj,
        passes,
        off_surface,
        Some(other),
    )
}

/// [`flatten_folds`] (`other` `None`) or [`patch_folds`].
fn folds_pass(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topologies: &[Topology],
    proj: &Projector,
    passes: u32,
    off_surface: f64,
    other: Option<(&[DVec3], &[u32])>,
) -> AncestorFlatten {
    let levels = topologies.len() - 1;
    let topo = &topologies[levels];
    assert_eq!(
        pos.len(),
        topo.num_vertices as usize,
        "positions per vertex"
    );
    assert_eq!(hints.len(), pos.len(), "hints per vertex");
    for l in 1..=levels {
        assert_eq!(
            topologies[l].num_faces(),
            4 * topologies[l - 1].num_faces(),
            "level {l} is not a 1-to-4 split"
        );
    }
    let mut state: Vec<FaceState> = (0..topo.num_faces())
        .into_par_iter()
        .map(|f| face_state(topo.face_vertices(f), pos, hints, proj))
        .collect();
    let mut out = AncestorFlatten::default();
    // Level of each vertex: the first level that has it.
    let starts: Vec<usize> = topologies.iter().map(|t| t.num_vertices as usize).collect();
    let level_of = |w: usize| starts.partition_point(|&s| s <= w);
    for _ in 0..passes {
        let bad: Vec<u32> = (0..state.len() as u32)
            .filter(|&f| is_bad(&state[f as usize]))
            .collect();
        let mut progress = false;
        // Candidates (level, ancestor set) that removed nothing, until a change is made.
        let mut failed = HashSet::new();
        for f in bad {
            if !is_bad(&state[f as usize]) {
                continue; // fixed by an earlier subtree
            }
            if let Some((flat, moved)) = fix_face(
                f as usize,
                pos,
                hints,
                &mut state,
                topologies,
                proj,
                &level_of,
                off_surface,
                &mut failed,
                other,
            ) {
                out.subtrees += 1;
                out.flat += flat as usize;
                out.moved += moved;
                progress = true;
            }
        }
        if !progress {
            break;
        }
    }
    out.flipped_after = state.iter().filter(|s| s.0 < 0.0).count();
    out.degenerate_after = state.iter().filter(|s| s.2).count();
    out
}

/// Largest number of finest faces under one candidate's ancestors.
const MAX_REGION_FACES: usize = 1 << 12;

/// The vertices a candidate re-subdivides: those created after level `m` all of whose
/// finest faces descend from the level-`m` faces `set` (sorted); so every face around a
/// moved vertex is inside the set's subtrees, and the set's outline stays where it is.
fn region_of(set: &[u32], m: usize, topologies: &[Topology]) -> Vec<u32> {
    let levels = topologies.len() - 1;
    let topo = &topologies[levels];
    let shift = 2 * (levels - m);
    let per = 1usize << shift;
    let first = topologies[m].num_vertices as usize;
    let mut region: Vec<u32> = set
        .iter()
        .flat_map(|&a| a as usize * per..(a as usize + 1) * per)
        .flat_map(|g| topo.face_vertices(g).iter().copied())
        .filter(|&w| w as usize >= first)
        .collect();
    region.sort_unstable();
    region.dedup();
    region.retain(|&w| {
        topo.vertex_faces(w as usize)
            .iter()
            .all(|&g| set.binary_search(&(g >> shift)).is_ok())
    });
    region
}

/// The candidate ancestor sets of finest face `f` at level `m`, smallest first: its
/// ancestor `A`, `A` with the faces sharing an edge with it, and with those sharing a
/// corner (each sorted; repeats and oversized sets left out).
fn ancestor_sets(f: usize, m: usize, topologies: &[Topology]) -> Vec<Vec<u32>> {
    let levels = topologies.len() - 1;
    let coarse = &topologies[m];
    let a = (f >> (2 * (levels - m))) as u32;
    let corners = coarse.face_vertices(a as usize);
    let around = faces_around(corners, coarse);
    let edge_neighbours: Vec<u32> = around
        .iter()
        .copied()
        .filter(|&g| {
            let gv = coarse.face_vertices(g as usize);
            g == a || gv.iter().filter(|v| corners.contains(v)).count() >= 2
        })
        .collect();
    let mut sets: Vec<Vec<u32>> = Vec::with_capacity(3);
    for set in [vec![a], edge_neighbours, around] {
        if set.len() << (2 * (levels - m)) > MAX_REGION_FACES {
            continue;
        }
        if sets.last() != Some(&set) {
            sets.push(set);
        }
    }
    sets
}

/// Tries the ancestors of finest face `f`, finest first (see the module documentation);
/// keeps the best change, if any, and returns whether it is flat and how many vertices
/// moved.
#[allow(clippy::too_many_arguments)]
fn fix_face(
    f: usize,
    pos: &mut [DVec3],
    hints: &mut [u32],
    state: &mut [FaceState],
    topologies: &[Topology],
    proj: &Projector,
    level_of: &dyn Fn(usize) -> usize,
    off: f64,
    failed: &mut HashSet<(usize, Vec<u32>)>,
    other: Option<(&[DVec3], &[u32])>,
) -> Option<(bool, usize)> {
    let levels = topologies.len() - 1;
    let topo = &topologies[levels];
    // (bad faces removed, candidate) of the best candidate so far.
    let mut best: Option<(usize, Candidate)> = None;
    'levels: for m in (0..levels).rev() {
        for set in ancestor_sets(f, m, topologies) {
            let key = (m, set);
            if failed.contains(&key) {
                continue;
            }
            let set = &key.1;
            let region = region_of(set, m, topologies);
            if region.is_empty() {
                continue;
            }
            let touched = faces_around(&region, topo);
            let before = touched
                .iter()
                .filter(|&&g| counts_against(&state[g as usize], off))
                .count();
            if !touched.iter().any(|&g| is_bad(&state[g as usize])) {
                continue; // the fold is not under this set
            }
            let mut helped = false;
            let kinds: &[Kind] = if other.is_some() {
                &[Kind::Other]
            } else {
                &[Kind::Projected, Kind::Flat, Kind::Reembedded]
            };
            for &kind in kinds {
                let c = match (kind, other) {
                    (Kind::Other, Some(o)) => taken_from(&region, o),
                    (Kind::Reembedded, _) => {
                        match reembedded(&region, &touched, pos, hints, topo, proj) {
                            Some(c) => c,
                            None => continue,
                        }
                    }
                    _ => resubdivide(
                        &region,
                        pos,
                        hints,
                        topologies,
                        proj,
                        level_of,
                        kind == Kind::Flat,
                    ),
                };
                let mut c = c;
                let mut after = count_bad(&c, &touched, pos, hints, topo, proj, off);
                if kind == Kind::Reembedded && after > 0 {
                    // The few faces a re-embedding leaves bad (slivers where the input
                    // bends under the flattening), repaired inside the region.
                    let p = polished(&c, &touched, pos, hints, topo, proj, off);
                    let a = count_bad(&p, &touched, pos, hints, topo, proj, off);
                    if a < after {
                        (c, after) = (p, a);
                    }
                }
                tracing::trace!(
                    f,
                    m,
                    set = set.len(),
                    ?kind,
                    before,
                    after,
                    "ancestor candidate"
                );
                helped |= after < before;
                if after < before && best.as_ref().is_none_or(|b| before - after > b.0) {
                    best = Some((before - after, c));
                }
                if after == 0 {
                    break 'levels;
                }
            }
            if !helped {
                failed.insert(key);
            }
        }
    }
    let (_, c) = best?;
    failed.clear();
    c.apply(pos, hints);
    for &g in &faces_around(&c.region, topo) {
        state[g as usize] = face_state(topo.face_vertices(g as usize), pos, hints, proj);
    }
    Some((c.flat, c.region.len()))
}

/// A re-subdivision of a region: its vertices (sorted), their places in it, and their new
/// positions and hints.
struct Candidate {
    region: Vec<u32>,
    index: HashMap<u32, usize>,
    pos: Vec<DVec3>,
    hints: Vec<u32>,
    flat: bool,
}

impl Candidate {
    /// The candidate moving the `region` vertices (sorted) to `pos` and `hints` (one each).
    fn new(region: &[u32], pos: Vec<DVec3>, hints: Vec<u32>, flat: bool) -> Candidate {
        Candidate {
            region: region.to_vec(),
            index: region.iter().enumerate().map(|(k, &w)| (w, k)).collect(),
            pos,
            hints,
            flat,
        }
    }

    /// Writes the candidate's positions and hints into `pos` and `hints`.
    fn apply(&self, pos: &mut [DVec3], hints: &mut [u32]) {
        for (k, &w) in self.region.iter().enumerate() {
            pos[w as usize] = self.pos[k];
            hints[w as usize] = self.hints[k];
        }
    }

    /// The position and hint of vertex `v`: new if it is in the region, else from `pos`
    /// and `hints`.
    fn at(&self, v: u32, pos: &[DVec3], hints: &[u32]) -> (DVec3, u32) {
        self.index
            .get(&v)
            .map_or((pos[v as usize], hints[v as usize]), |&k| {
                (self.pos[k], self.hints[k])
            })
    }
}

/// The kinds of candidate of [`fix_face`].
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Kind {
    /// Midpoints projected onto the input ([`resubdivide`]).
    Projected,
    /// Midpoints on the ancestors' planes ([`resubdivide`]).
    Flat,
    /// The region re-embedded in a flattening of the input under it, its outline fixed
    /// ([`reembedded`]).
    Reembedded,
    /// The region taken from another sampling ([`taken_from`]).
    Other,
}

/// The `region` vertices re-embedded by Tutte's embedding spanned by the set's outline in a
/// flattening of the input under the faces `touched` around them ([`flat_reembed`]): where
/// the region is crushed along a line (all its faces slivers, the outline well shaped), a
/// midpoint re-subdivision keeps its shape and the discs of [`super::fold_repair`] do not
/// reach past it; `None` where the input under it is not a disc or the embedding folds.
fn reembedded(
    region: &[u32],
    touched: &[u32],
    pos: &[DVec3],
    hints: &[u32],
    topo: &Topology,
    proj: &Projector,
) -> Option<Candidate> {
    let mut verts: Vec<u32> = touched
        .iter()
        .flat_map(|&g| topo.face_vertices(g as usize).iter().copied())
        .collect();
    verts.sort_unstable();
    verts.dedup();
    let patch = Patch::under(pos, hints, &verts, proj)?;
    let moves = flat_reembed(&patch, pos, hints, topo, region, &[], touched, proj).ok()?;
    Some(Candidate::new(
        region,
        moves.iter().map(|m| m.0).collect(),
        moves.iter().map(|m| m.1).collect(),
        false,
    ))
}

/// Candidate `c` with the bad faces it leaves among `touched` repaired by
/// [`repair_folds`], only its region's vertices free (run on `pos` and `hints` in place,
/// which are then put back as they were).
fn polished(
    c: &Candidate,
    touched: &[u32],
    pos: &mut [DVec3],
    hints: &mut [u32],
    topo: &Topology,
    proj: &Projector,
    off: f64,
) -> Candidate {
    let saved = taken_from(&c.region, (pos, hints));
    c.apply(pos, hints);
    let mut fixed = vec![true; pos.len()];
    for &w in &c.region {
        fixed[w as usize] = false;
    }
    let suspects: Vec<u32> = touched
        .iter()
        .copied()
        .filter(|&g| {
            counts_against(
                &face_state(topo.face_vertices(g as usize), pos, hints, proj),
                off,
            )
        })
        .collect();
    repair_folds(
        pos,
        hints,
        topo,
        &fixed,
        &[],
        proj,
        POLISH_ROUNDS,
        Some(&suspects),
        f64::INFINITY,
    );
    // Only the region's vertices moved (the others are fixed): putting them back restores
    // every position and hint.
    let out = taken_from(&c.region, (pos, hints));
    saved.apply(pos, hints);
    out
}

/// Rounds of [`repair_folds`]' vertex moves in [`polished`].
const POLISH_ROUNDS: u32 = 12;

/// The `region` vertices at their positions (and hints) in `other`.
fn taken_from(region: &[u32], other: (&[DVec3], &[u32])) -> Candidate {
    Candidate::new(
        region,
        region.iter().map(|&w| other.0[w as usize]).collect(),
        region.iter().map(|&w| other.1[w as usize]).collect(),
        false,
    )
}

/// New positions and hints of the `region` vertices (sorted ascending, all created after
/// their ancestor's level): each at the midpoint of its parent edge's ends (their new
/// positions when they are in the region), projected onto the input unless `flat`.
fn resubdivide(
    region: &[u32],
    pos: &[DVec3],
    hints: &[u32],
    topologies: &[Topology],
    proj: &Projector,
    level_of: &dyn Fn(usize) -> usize,
    flat: bool,
) -> Candidate {
    let mut c = Candidate::new(
        region,
        Vec::with_capacity(region.len()),
        Vec::with_capacity(region.len()),
        flat,
    );
    for &w in region {
        let w = w as usize;
        let l = level_of(w); // w is a vertex of level l, created on an edge of level l − 1
        let parent = &topologies[l - 1];
        let e = w - parent.num_vertices as usize;
        let ends = parent.edge_vertices[e];
        let (pa, ha) = c.at(ends[0], pos, hints);
        let (pb, hb) = c.at(ends[1], pos, hints);
        let mid = 0.5 * (pa + pb);
        let (q, t) = proj.closest_near(mid, &[hints[w], ha, hb]);
        c.pos.push(if flat { mid } else { q });
        c.hints.push(t);
    }
    c
}

/// Faces among `touched` that are bad or farther than `off` from the input, with the
/// candidate's vertices at their new positions.
fn count_bad(
    c: &Candidate,
    touched: &[u32],
    pos: &[DVec3],
    hints: &[u32],
    topo: &Topology,
    proj: &Projector,
    off: f64,
) -> usize {
    touched
        .par_iter()
        .with_min_len(64)
        .filter(|&&g| {
            let fv = topo.face_vertices(g as usize);
            let mut local_pos = [DVec3::ZERO; 3];
            let mut local_hints = [u32::MAX; 3];
            for (i, &v) in fv.iter().take(3).enumerate() {
                (local_pos[i], local_hints[i]) = c.at(v, pos, hints);
            }
            counts_against(&face_state(&[0, 1, 2], &local_pos, &local_hints, proj), off)
        })
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;
    use crate::hierarchy::Hierarchy;
    use crate::mesh::Mesh;
    use crate::subdivision::{subdivide, Scheme, SubdivideOptions};

    /// The hierarchy of an icosahedron split `levels` times by midpoints, and its finest mesh.
    fn midpoint_icosahedron(levels: u32) -> (Hierarchy, Mesh) {
        let opts = SubdivideOptions {
            scheme: Scheme::Midpoint,
            levels,
            ..Default::default()
        };
        let fine = subdivide(&generate::icosphere(0), &opts).unwrap();
        (Hierarchy::detect(&fine, None).unwrap().0, fine)
    }

    /// The closest-point index of triangle mesh `m`.
    fn projector(m: &Mesh) -> Projector {
        let tris: Vec<[u32; 3]> = (0..m.num_faces())
            .map(|f| {
                let v = m.face(f);
                [v[0], v[1], v[2]]
            })
            .collect();
        Projector::new(&m.positions, &tris).unwrap()
    }

    /// The hierarchy of a 3-level midpoint subdivision of an icosahedron, a finer icosphere
    /// as the input, and the hierarchy's vertices projected onto it with their hints.
    fn on_the_sphere() -> (Hierarchy, Projector, Vec<DVec3>, Vec<u32>) {
        let (h, _) = midpoint_icosahedron(3);
        let proj = projector(&generate::icosphere(4));
        let pos: Vec<DVec3> = h
            .positions
            .iter()
            .map(|p| proj.closest(p.normalize()).0)
            .collect();
        let hints: Vec<u32> = pos.iter().map(|&p| proj.closest(p).1).collect();
        (h, proj, pos, hints)
    }

    /// A 3-level midpoint subdivision of an icosphere projected onto the unit sphere, with a
    /// fold made by pushing one finest vertex across its neighbours: the pass removes the
    /// fold, moves no base vertex, and leaves no bad face.
    #[test]
    fn removes_a_fold_and_keeps_the_base() {
        let (h, proj, mut pos, mut hints) = on_the_sphere();
        let topo = &h.topologies[3];
        // Fold: a finest vertex pushed far across its one-ring.
        let v = topo.num_vertices as usize - 7;
        let ring: Vec<u32> = topo
            .vertex_faces(v)
            .iter()
            .flat_map(|&f| topo.face_vertices(f as usize).iter().copied())
            .filter(|&w| w as usize != v)
            .collect();
        let c = ring.iter().map(|&w| pos[w as usize]).sum::<DVec3>() / ring.len() as f64;
        let far = pos[ring[0] as usize];
        pos[v] = proj.closest(c + 2.5 * (far - c)).0;
        hints[v] = proj.closest(pos[v]).1;
        let bad_before = (0..topo.num_faces())
            .filter(|&f| is_bad(&face_state(topo.face_vertices(f), &pos, &hints, &proj)))
            .count();
        assert!(bad_before > 0, "the test must start with a fold");
        let nb = h.topologies[0].num_vertices as usize;
        let base_before = pos[..nb].to_vec();
        let r = flatten_folds(&mut pos, &mut hints, &h.topologies, &proj, 2, f64::INFINITY);
        assert_eq!((r.flipped_after, r.degenerate_after), (0, 0), "{r:?}");
        assert!(r.subtrees >= 1 && r.moved >= 1, "{r:?}");
        assert_eq!(&pos[..nb], &base_before[..]);
        let bad_after = (0..topo.num_faces())
            .filter(|&f| is_bad(&face_state(topo.face_vertices(f), &pos, &hints, &proj)))
            .count();
        assert_eq!(bad_after, 0);
        // The fold's vertex went back near its ring.
        assert!(pos[v].distance(c) < far.distance(c), "{:?}", pos[v]);
    }

    /// Two samplings of the same hierarchy, each with a fold where the other has none: the
    /// first's fold is patched with the other's subtree, and nothing else moves.
    #[test]
    fn patches_a_fold_from_another_sampling() {
        let (h, _) = midpoint_icosahedron(3);
        let proj = projector(&generate::icosphere(4));
        let clean: Vec<DVec3> = h
            .positions
            .iter()
            .map(|p| proj.closest(p.normalize()).0)
            .collect();
        let topo = &h.topologies[3];
        let fold = |v: usize| {
            let mut pos = clean.clone();
            let ring: Vec<u32> = topo
                .vertex_faces(v)
                .iter()
                .flat_map(|&f| topo.face_vertices(f as usize).iter().copied())
                .filter(|&w| w as usize != v)
                .collect();
            let c = ring.iter().map(|&w| pos[w as usize]).sum::<DVec3>() / ring.len() as f64;
            pos[v] = proj.closest(c + 2.5 * (pos[ring[0] as usize] - c)).0;
            let hints: Vec<u32> = pos.iter().map(|&p| proj.closest(p).1).collect();
            (pos, hints)
        };
        let n = topo.num_vertices as usize;
        let bad = |pos: &[DVec3], hints: &[u32]| {
            (0..topo.num_faces())
                .filter(|&f| is_bad(&face_state(topo.face_vertices(f), pos, hints, &proj)))
                .count()
        };
        let (mut pos, mut hints) = fold(n - 7);
        let (other_pos, other_hints) = fold(n / 2);
        assert!(bad(&pos, &hints) > 0 && bad(&other_pos, &other_hints) > 0);
        let before = pos.clone();
        let r = patch_folds(
            &mut pos,
            &mut hints,
            &h.topologies,
            &proj,
            2,
            f64::INFINITY,
            (&other_pos, &other_hints),
        );
        assert_eq!((r.flipped_after, r.degenerate_after), (0, 0), "{r:?}");
        assert_eq!(bad(&pos, &hints), 0);
        // Only vertices of the patched subtree moved, each to the other sampling's place.
        for v in 0..n {
            assert!(pos[v] == before[v] || pos[v] == other_pos[v], "vertex {v}");
        }
        assert_eq!(
            pos[n / 2],
            before[n / 2],
            "the other's fold is not brought in"
        );
    }

    /// A region crushed along a line (every vertex inside an ancestor set pressed onto a
    /// thin strip through its centre, as a resampling can leave it; its outline well
    /// shaped): the re-embedding spanned by the outline in a flattening of the input
    /// leaves no bad face around it, and puts every vertex on the input.
    #[test]
    fn a_crushed_region_is_reembedded_from_its_outline() {
        let (h, proj, mut pos, mut hints) = on_the_sphere();
        let topo = &h.topologies[3];
        let f = topo.num_faces() / 3;
        let set = ancestor_sets(f, 1, &h.topologies)[1].clone();
        let region = region_of(&set, 1, &h.topologies);
        assert!(region.len() > 10, "{}", region.len());
        let c = region.iter().map(|&w| pos[w as usize]).sum::<DVec3>() / region.len() as f64;
        let along = (pos[region[0] as usize] - c).normalize();
        for &w in &region {
            // Squeezed to 2% across the strip.
            let d = pos[w as usize] - c;
            let q = c + along * d.dot(along) + (d - along * d.dot(along)) * 0.02;
            (pos[w as usize], hints[w as usize]) = proj.closest(q.normalize());
        }
        let touched = faces_around(&region, topo);
        let bad = |c: &Candidate| count_bad(c, &touched, &pos, &hints, topo, &proj, f64::INFINITY);
        let unchanged = taken_from(&region, (&pos, &hints));
        assert!(bad(&unchanged) > 0, "the crush must leave bad faces");
        let c = reembedded(&region, &touched, &pos, &hints, topo, &proj).unwrap();
        assert_eq!(bad(&c), 0);
        for (k, &p) in c.pos.iter().enumerate() {
            assert!(
                (p.length() - 1.0).abs() < 0.02,
                "vertex {} off the input",
                c.region[k]
            );
            assert!(proj.closest(p).0.distance(p) < 1e-9);
        }
    }

    /// Nothing to do on a clean remesh: positions unchanged, counts zero.
    #[test]
    fn leaves_a_clean_mesh_alone() {
        let (h, fine) = midpoint_icosahedron(2);
        let proj = projector(&fine);
        let mut pos = h.positions.clone();
        let mut hints: Vec<u32> = pos.iter().map(|&p| proj.closest(p).1).collect();
        let r = flatten_folds(&mut pos, &mut hints, &h.topologies, &proj, 2, f64::INFINITY);
        assert_eq!(r, AncestorFlatten::default());
        assert_eq!(pos, h.positions);
    }
}

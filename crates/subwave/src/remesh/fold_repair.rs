//! Final repair of flipped and degenerate faces of a remesh, in 3D on the finest level.
//!
//! After the resampling through the MAPS parameterization (Lee et al. 1998, §4) and the
//! relaxation and untangling of [`super::resample`], a few faces can still be turned over
//! against the input (where the parameterization folds or misses, next to boundary and
//! feature chains whose vertices are pinned) or be slivers. Lee et al. §4 smooth such
//! regions in the parameter domain; here the repair works on the surface, as the untangling
//! of Kobbelt et al. 1999 ("shrink-wrapping", §4 relaxation restricted to the tangent plane):
//! every free vertex of a bad face is moved into the *kernel* of its star — the region of the
//! input's tangent plane from which every face around it turns counterclockwise around the
//! input normal — at the kernel's Chebyshev centre (the point farthest from the lines of the
//! opposite edges, a tiny linear program), then projected onto the input. A move is kept only
//! if it lowers the number of flipped faces around the vertex (or keeps it and raises their
//! smallest angle), does not pull the faces off the input, stays on the sheet (short
//! projection) and stays within one ring of where the repair found the vertex, so the
//! sampling (and the distortion) changes only locally. Only positions change: the
//! subdivision connectivity is untouched; pinned vertices (on boundary and feature chains)
//! stay on their curves.
//!
//! Where the input turns sharply within one star (a hole rim that rolls over), the kernel in
//! one tangent plane can be empty although a fold-free position exists on the surface; the
//! last stage searches each remaining bad face's free vertices over points of the input
//! towards their ring (its centroid, neighbours and midpoints of consecutive neighbours),
//! measured exactly as the final counts are and kept under the same guards (bunny at 5
//! levels: its last flipped face of 204,800; suzanne 29 to 11, cow 45 to 19).
//!
//! Faces whose centroid lies farther than a tolerance off the input are repaired too (with
//! the same disc re-embeddings): where the parameterization's images overlap, a patch of
//! faces can be stretched across the input, each face neither flipped nor thin but
//! bridging a region of the surface it does not follow (beetle at 5 levels: 86% of the
//! squared distance in two base triangles, 63.0 dB instead of 77.0 dB).

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use super::flatten::{chebyshev_centre, flat_reembed, Patch, RimRun};
use super::quality::{min_angle, DEGENERATE_DEGREES};
use super::resample::{face_hints, face_normal, face_region, flips_around, Projector};
use crate::topology::Topology;

/// Faces with a smaller angle than this (degrees) are repaired (above
/// [`DEGENERATE_DEGREES`], so that repaired faces clear the degenerate threshold).
const BAD_ANGLE: f64 = 2.0;

/// What [`repair_folds`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FoldRepair {
    /// Flipped faces (normal opposing the input's) before the repair.
    pub flipped_before: usize,
    /// Degenerate faces (as [`super::quality::Quality::degenerate`]) before the repair.
    pub degenerate_before: usize,
    /// Flipped faces after the repair.
    pub flipped_after: usize,
    /// Degenerate faces after the repair.
    pub degenerate_after: usize,
    /// Vertex moves made.
    pub moves: usize,
}

/// Whether face `f` is bad: its normal makes a non-acute angle with the input normal at the
/// closest input point of its centroid, it has an angle below `min_degrees`, or its
/// centroid is farther than `off` from the input.
fn bad_face(
    fv: &[u32],
    pos: &[DVec3],
    hints: &[u32],
    proj: &Projector,
    min_degrees: f64,
    off: f64,
) -> bool {
    let (sign, dist) = flip_sign(fv, pos, hints, proj);
    sign <= 0.0 || dist > off || min_angle(fv, pos) < min_degrees
}

/// The dot product of face `fv`'s normal with the input normal at the closest input point
/// of its centroid, and the centroid's distance to that point.
fn flip_sign(fv: &[u32], pos: &[DVec3], hints: &[u32], proj: &Projector) -> (f64, f64) {
    let n = face_normal(fv, pos);
    let c = fv.iter().map(|&v| pos[v as usize]).sum::<DVec3>() / fv.len() as f64;
    let (q, tri) = proj.closest_near(c, &face_hints(fv, hints));
    (n.dot(proj.normals[tri as usize]), q.distance(c))
}

/// A face's flip sign (as [`flip_sign`]), smallest angle (degrees), whether it is
/// degenerate (as [`super::quality::Quality::degenerate`]), and its centroid's distance
/// to the input.
pub(super) type FaceState = (f64, f64, bool, f64);

pub(super) fn face_state(fv: &[u32], pos: &[DVec3], hints: &[u32], proj: &Projector) -> FaceState {
    let angle = min_angle(fv, pos);
    let degenerate = angle < DEGENERATE_DEGREES || face_normal(fv, pos).length_squared() == 0.0;
    let (sign, dist) = flip_sign(fv, pos, hints, proj);
    (sign, angle, degenerate, dist)
}

/// The faces around the vertices of `region` (sorted, distinct): every face a move of them
/// can change.
pub(super) fn faces_around(region: &[u32], topo: &Topology) -> Vec<u32> {
    let mut faces: Vec<u32> = region
        .iter()
        .flat_map(|&w| topo.vertex_faces(w as usize).iter().copied())
        .collect();
    faces.sort_unstable();
    faces.dedup();
    faces
}

/// Re-measures the faces around the vertices that moved since `last` was taken, and takes
/// `last` again.
fn refresh(
    state: &mut [FaceState],
    last: &mut [DVec3],
    topo: &Topology,
    pos: &[DVec3],
    hints: &[u32],
    proj: &Projector,
) {
    let mut faces: Vec<u32> = (0..pos.len())
        .filter(|&v| pos[v] != last[v])
        .flat_map(|v| topo.vertex_faces(v).iter().copied())
        .collect();
    faces.sort_unstable();
    faces.dedup();
    measure(state, &faces, topo, pos, hints, proj);
    last.copy_from_slice(pos);
}

/// Measures `faces` (distinct) into `state`.
fn measure(
    state: &mut [FaceState],
    faces: &[u32],
    topo: &Topology,
    pos: &[DVec3],
    hints: &[u32],
    proj: &Projector,
) {
    let updates: Vec<FaceState> = faces
        .par_iter()
        .map(|&f| face_state(topo.face_vertices(f as usize), pos, hints, proj))
        .collect();
    for (&f, u) in faces.iter().zip(updates) {
        state[f as usize] = u;
    }
}

/// The bad faces of `state` (as [`bad_face`] with [`BAD_ANGLE`] and `off`).
fn bad_of(state: &[FaceState], off: f64) -> Vec<u32> {
    (0..state.len() as u32)
        .filter(|&f| {
            let s = state[f as usize];
            s.0 <= 0.0 || s.1 < BAD_ANGLE || s.3 > off
        })
        .collect()
}

/// Counts of flipped (normal opposing the input's) and degenerate faces of `state`.
fn counts(state: &[FaceState]) -> (usize, usize) {
    (
        state.iter().filter(|s| s.0 < 0.0).count(),
        state.iter().filter(|s| s.2).count(),
    )
}

/// Repairs flipped and degenerate faces of a level (see the module documentation): at most
/// `rounds` Gauss-Seidel rounds over the free vertices of the bad faces, the region growing
/// by one ring per round (up to three). `hints[v]` is an input triangle near vertex `v`
/// (updated as vertices move); `fixed` vertices do not move, except those marked in
/// `slides` (remesh boundary vertices on the input's boundary, or an empty slice for none),
/// which a disc's re-embedding may slide along the input's boundary between boundary
/// vertices that stay. `suspects`: the only faces that can be flipped or have an angle
/// below 2° (as [`super::resample::untangle_bad`] returns them), or `None` to measure
/// every face. Faces whose centroid is farther than `off_surface` from the input are bad
/// as well (every face is measured for that; `f64::INFINITY` for none).
///
/// Preconditions: `pos`, `hints` and `fixed` have `topo.num_vertices` entries, `slides`
/// as many or none; the vertices lie on the input behind `proj`.
#[allow(clippy::too_many_arguments)]
pub fn repair_folds(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topo: &Topology,
    fixed: &[bool],
    slides: &[bool],
    proj: &Projector,
    rounds: u32,
    suspects: Option<&[u32]>,
    off_surface: f64,
) -> FoldRepair {
    let t0 = std::time::Instant::now();
    let off = off_surface;
    let mut state: Vec<FaceState> = match suspects {
        None => (0..topo.num_faces())
            .into_par_iter()
            .map(|f| face_state(topo.face_vertices(f), pos, hints, proj))
            .collect(),
        Some(faces) => {
            let mut state = vec![(1.0, 60.0, false, 0.0); topo.num_faces()];
            let mut faces = faces.to_vec();
            if off.is_finite() {
                // Faces off the input are not among the suspects: every face's centroid.
                faces.par_extend((0..topo.num_faces() as u32).into_par_iter().filter(|&f| {
                    let fv = topo.face_vertices(f as usize);
                    flip_sign(fv, pos, hints, proj).1 > off
                }));
                faces.sort_unstable();
                faces.dedup();
            }
            measure(&mut state, &faces, topo, pos, hints, proj);
            state
        }
    };
    let mut last = pos.to_vec();
    let (flipped_before, degenerate_before) = counts(&state);
    let mut out = FoldRepair {
        flipped_before,
        degenerate_before,
        ..FoldRepair::default()
    };
    let mut origin: Vec<Option<(DVec3, f64)>> = vec![None; pos.len()];
    let bad = bad_of(&state, off);
    tracing::debug!(
        ms = t0.elapsed().as_secs_f64() * 1e3,
        "fold repair: measured"
    );
    let bad = vertex_rounds(
        pos,
        hints,
        topo,
        fixed,
        proj,
        rounds,
        bad,
        &mut origin,
        &mut out.moves,
        off,
    );
    // Folds no single vertex can open: re-embed a growing disc around each connected group
    // of bad faces, then polish the discs' new faces vertex by vertex.
    // Repeated while it helps (at most three times).
    let mut bad = bad;
    let mut failed = std::collections::HashMap::new();
    for _ in 0..3 {
        if bad.is_empty() {
            break;
        }
        tracing::debug!(
            ms = t0.elapsed().as_secs_f64() * 1e3,
            bad = bad.len(),
            "fold repair: vertex rounds"
        );
        let moved = reembed(
            pos,
            hints,
            topo,
            fixed,
            slides,
            proj,
            &bad,
            &mut failed,
            off,
        );
        tracing::debug!(
            ms = t0.elapsed().as_secs_f64() * 1e3,
            moved,
            "fold repair: re-embedded"
        );
        if moved == 0 {
            break;
        }
        out.moves += moved;
        refresh(&mut state, &mut last, topo, pos, hints, proj);
        let again = bad_of(&state, off);
        let again = vertex_rounds(
            pos,
            hints,
            topo,
            fixed,
            proj,
            rounds,
            again,
            &mut origin,
            &mut out.moves,
            off,
        );
        let progress = again.len() < bad.len();
        bad = again;
        if !progress {
            break;
        }
    }
    // What neither the kernel moves nor the re-embeddings opened: single-vertex moves
    // searched over sample points of each star.
    if !bad.is_empty() {
        let before = bad.len();
        bad = search_rounds(
            pos,
            hints,
            topo,
            fixed,
            proj,
            bad,
            &mut origin,
            &mut out.moves,
            off,
        );
        tracing::debug!(
            ms = t0.elapsed().as_secs_f64() * 1e3,
            before,
            after = bad.len(),
            "fold repair: star search"
        );
    }
    refresh(&mut state, &mut last, topo, pos, hints, proj);
    let (flipped_after, degenerate_after) = counts(&state);
    tracing::debug!(ms = t0.elapsed().as_secs_f64() * 1e3, "fold repair: done");
    out.flipped_after = flipped_after;
    out.degenerate_after = degenerate_after;
    out
}

/// Gauss-Seidel rounds of single-vertex moves into the kernel of their stars over the free
/// vertices of the `bad` faces (the region growing by one ring per round, up to three; at
/// most `rounds` rounds, fewer once a round at full radius no longer lowers their number). `origin[v]` is
/// where vertex `v` was, and its ring's mean edge length, when the repair first met it.
/// Returns the bad faces left (faces off the input by more than `off` count as bad).
#[allow(clippy::too_many_arguments)]
fn vertex_rounds(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topo: &Topology,
    fixed: &[bool],
    proj: &Projector,
    rounds: u32,
    mut bad: Vec<u32>,
    origin: &mut [Option<(DVec3, f64)>],
    moves: &mut usize,
    off: f64,
) -> Vec<u32> {
    let mut prev = usize::MAX;
    for round in 0..rounds {
        if bad.is_empty() {
            break;
        }
        let mut round_moves = 0;
        let verts = free_region(topo, fixed, &bad, round.min(3) as usize);
        for &v in &verts {
            let Some(guard) = Guard::of(v, topo, pos, hints, proj, &mut origin[v]) else {
                continue;
            };
            let p0 = pos[v];
            let n = proj.smooth_normal(hints[v]);
            let Some((k, _, _)) = kernel_centre(v, p0, n, topo, pos).filter(|k| k.1 > 0.0) else {
                continue;
            };
            let targets = [1.0, 0.5, 0.25].map(|t| p0.lerp(k, t));
            if move_to_best(v, &targets, &guard, topo, pos, hints, proj) {
                *moves += 1;
                round_moves += 1;
            }
        }
        bad = still_bad(&verts, &bad, topo, pos, hints, proj, off);
        tracing::debug!(round, bad = bad.len(), region = verts.len(), "fold repair");
        // At full radius, stop once a round no longer lowers the count.
        if round >= 3 && (round_moves == 0 || bad.len() >= prev) {
            break;
        }
        prev = bad.len();
    }
    bad
}

/// What a single-vertex move must beat and keep to (see [`move_to_best`]).
struct Guard {
    /// [`flips_around`] of the vertex where it is.
    now: (usize, f64, f64),
    /// Where the repair first met the vertex, and its ring's mean edge length then.
    origin: (DVec3, f64),
    /// Its ring's mean edge length now.
    reach: f64,
}

impl Guard {
    /// The guard of vertex `v`, or `None` if no face around it is flipped or has an angle
    /// below [`BAD_ANGLE`]. `origin` is where the repair first met `v` (set now if unset).
    fn of(
        v: usize,
        topo: &Topology,
        pos: &[DVec3],
        hints: &[u32],
        proj: &Projector,
        origin: &mut Option<(DVec3, f64)>,
    ) -> Option<Guard> {
        let now = flips_around(v, pos[v], hints[v], topo, pos, hints, proj);
        if now.0 == 0 && now.1 >= BAD_ANGLE {
            return None;
        }
        let reach = mean_edge(topo, pos, v);
        let origin = *origin.get_or_insert((pos[v], reach));
        Some(Guard { now, origin, reach })
    }
}

/// Moves vertex `v` to the best of `targets` projected onto the input, if one qualifies:
/// fewer flipped faces around it than `guard.now` (or as many and a larger smallest
/// angle), a projection shorter than a quarter of `guard.reach`, within the first ring
/// length of the origin, and its faces no farther off the input than now (or than 5% of
/// the reach); the first of equals wins. Updates `hints[v]`; returns whether it moved.
#[allow(clippy::too_many_arguments)]
fn move_to_best(
    v: usize,
    targets: &[DVec3],
    guard: &Guard,
    topo: &Topology,
    pos: &mut [DVec3],
    hints: &mut [u32],
    proj: &Projector,
) -> bool {
    let (o, reach0) = guard.origin;
    let mut best: Option<(DVec3, u32, (usize, f64, f64))> = None;
    for &target in targets {
        let (q, tri) = proj.closest_near(target, &[hints[v]]);
        if q.distance(target) > 0.25 * guard.reach || q.distance(o) > reach0 {
            continue;
        }
        let new = flips_around(v, q, tri, topo, pos, hints, proj);
        if new.2 > guard.now.2.max(0.05 * guard.reach) {
            continue;
        }
        let cur = best.map_or(guard.now, |b| b.2);
        if new.0 < cur.0 || (new.0 == cur.0 && new.1 > cur.1) {
            best = Some((q, tri, new));
        }
    }
    let Some((q, tri, _)) = best else {
        return false;
    };
    pos[v] = q;
    hints[v] = tri;
    true
}

/// The mean length of the edges around vertex `v`.
fn mean_edge(topo: &Topology, pos: &[DVec3], v: usize) -> f64 {
    let edges = topo.vertex_edges(v);
    edges
        .iter()
        .map(|&e| pos[topo.other_vertex(e as usize, v as u32) as usize].distance(pos[v]))
        .sum::<f64>()
        / edges.len().max(1) as f64
}

/// The free (not `fixed`, not isolated) vertices within `rings` rings of the `bad` faces,
/// in index order.
fn free_region(topo: &Topology, fixed: &[bool], bad: &[u32], rings: usize) -> Vec<usize> {
    let n = fixed.len();
    let region = face_region(topo, n, bad.iter().map(|&f| f as usize), rings);
    (0..n)
        .filter(|&v| region[v] && !fixed[v] && !topo.vertex_edges(v).is_empty())
        .collect()
}

/// The faces among `bad` and those around `verts` that are bad now (as [`bad_face`] with
/// [`BAD_ANGLE`] and `off`), sorted.
fn still_bad(
    verts: &[usize],
    bad: &[u32],
    topo: &Topology,
    pos: &[DVec3],
    hints: &[u32],
    proj: &Projector,
    off: f64,
) -> Vec<u32> {
    let mut faces: Vec<u32> = verts
        .iter()
        .flat_map(|&v| topo.vertex_faces(v).iter().copied())
        .collect();
    faces.extend_from_slice(bad);
    faces.sort_unstable();
    faces.dedup();
    faces
        .into_par_iter()
        .filter(|&f| {
            bad_face(
                topo.face_vertices(f as usize),
                pos,
                hints,
                proj,
                BAD_ANGLE,
                off,
            )
        })
        .collect()
}

/// Rounds of [`search_rounds`] at most.
const SEARCH_ROUNDS: usize = 4;

/// Fractions of the way from a vertex (or its ring's centroid) to each sample point of its
/// ring tried by [`search_rounds`] (with 0.8 too, bad faces left at 5 levels: suzanne
/// 14 → 11, cow 23 → 19, beetle 203 → 193; PSNR not lower on any corpus mesh).
const SEARCH_STEPS: [f64; 4] = [0.2, 0.4, 0.6, 0.8];

/// Last-resort single-vertex moves for the `bad` faces left by the kernel moves and the
/// re-embeddings. The kernel of [`vertex_rounds`] lives in one tangent plane, which fails
/// where the input turns sharply within a star (a hole rim that rolls over: the bunny's last
/// flipped face at 5 levels stood across one, perpendicular to the surface). Here each free
/// vertex of a bad face tries points on the input towards its ring's centroid, its
/// neighbours and the midpoints of consecutive neighbours (from the vertex and from the
/// centroid, [`SEARCH_STEPS`] of the way), each measured by the faces of its star exactly
/// as the final counts measure them; the best is kept under the same guards as the kernel
/// moves (fewer flipped faces, or as many and a larger smallest angle; a short projection;
/// within a ring of where the repair first met the vertex; faces not pulled off the input).
/// The region grows by one ring per round. Returns the bad faces left.
#[allow(clippy::too_many_arguments)]
fn search_rounds(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topo: &Topology,
    fixed: &[bool],
    proj: &Projector,
    mut bad: Vec<u32>,
    origin: &mut [Option<(DVec3, f64)>],
    moves: &mut usize,
    off: f64,
) -> Vec<u32> {
    let mut targets = Vec::new();
    for round in 0..SEARCH_ROUNDS {
        if bad.is_empty() {
            break;
        }
        let verts = free_region(topo, fixed, &bad, round.min(3));
        let mut round_moves = 0;
        for &v in &verts {
            let Some(guard) = Guard::of(v, topo, pos, hints, proj, &mut origin[v]) else {
                continue;
            };
            let p0 = pos[v];
            let ring: Vec<DVec3> = topo
                .vertex_edges(v)
                .iter()
                .map(|&e| pos[topo.other_vertex(e as usize, v as u32) as usize])
                .collect();
            let centroid = ring.iter().sum::<DVec3>() / ring.len() as f64;
            targets.clear();
            targets.push(centroid);
            for (i, &u) in ring.iter().enumerate() {
                let mid = (u + ring[(i + 1) % ring.len()]) * 0.5;
                for &t in &SEARCH_STEPS {
                    for from in [p0, centroid] {
                        targets.push(from.lerp(u, t));
                        targets.push(from.lerp(mid, t));
                    }
                }
            }
            for t in SEARCH_STEPS {
                targets.push(p0.lerp(centroid, t));
            }
            if move_to_best(v, &targets, &guard, topo, pos, hints, proj) {
                *moves += 1;
                round_moves += 1;
            }
        }
        bad = still_bad(&verts, &bad, topo, pos, hints, proj, off);
        tracing::debug!(
            round,
            bad = bad.len(),
            moves = round_moves,
            "fold repair: star search"
        );
    }
    bad
}

/// Rings around a group of bad faces at most for the membrane of [`reembed`].
const MEMBRANE_RINGS: usize = 6;

/// A flat re-embedding of a disc grown along a fold (see [`reembed`]) is refused if it
/// moves a vertex farther than this many mean edge lengths of the disc: a large disc
/// re-embedded by Tutte's uniform weights redistributes its vertices and can cut off a
/// protrusion of the input under it (cow at 5 levels without this bound: 74.8 → 44.8 dB).
const MAX_SHIFT: f64 = 3.0;

/// Discs with more free vertices than this are not re-embedded by rings (the cow's discs
/// grown along folds passed 3,000 vertices in 228 attempts, which took 6.4 s and kept 12
/// re-embeddings; with the cap, the corpus's flipped and degenerate counts at 5 levels are
/// unchanged and the cow's remesh takes 4.7 s instead of 11.4).
const MAX_DISC: usize = 3000;

/// The rings around a group of bad faces tried by [`reembed`]; the flat re-embedding tries
/// them all (folds collapsed onto a sharp input edge reach farther than a membrane can
/// follow).
const RINGS: &[usize] = &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16];

/// Circles of [`reembed`]'s last attempt at most, each [`CIRCLE_GROWTH`] times the last.
const CIRCLES: i32 = 10;

/// Growth of the radius from one circle to the next.
const CIRCLE_GROWTH: f64 = 1.5;

/// Sweeps of the membrane solve in [`reembed`].
const MEMBRANE_SWEEPS: usize = 60;

/// The input point to which a repaired vertex goes: the local closest point (walking from
/// its input triangle `hint`, so it stays on its sheet), else the closest one.
fn project(proj: &Projector, p: DVec3, hint: u32) -> (DVec3, u32) {
    proj.closest_local(p, hint)
        .unwrap_or_else(|| proj.closest_near(p, &[hint]))
}

/// The input triangle vertex `v` of `free` had before the re-embedding.
fn saved_hint(free: &[u32], saved: &[(DVec3, u32)], v: u32) -> u32 {
    free.iter()
        .position(|&w| w == v)
        .map_or(u32::MAX, |i| saved[i].1)
}

/// Re-embeds the neighbourhood of each connected group of `bad` faces, trying in turn
/// until the group is repaired, for `k` in [`RINGS`]:
/// - the free vertices within `k` rings take the membrane (uniform Laplacian, Gauss-Seidel)
///   spanned by the ring around them, which projected onto the input's tangent plane is
///   Tutte's barycentric embedding (fold-free for a convex ring, Floater 1997), and are
///   projected onto the input (`k` up to [`MEMBRANE_RINGS`]);
/// - the same disc re-embedded in a flattening of the input ([`flat_reembed`]).
///
/// A fold can run out of every disc of rings: a pleat along a line whose faces overlap in
/// the flattening beyond the few that are turned over, so the disc's boundary crosses
/// itself there and no embedding inside it exists (rocker-arm at 5 levels: the flat
/// re-embeddings of 1 to 16 rings all stayed folded at the boundary). Once a flat
/// re-embedding fails, the vertices of the faces it left turned over join the group's as
/// seeds of the next discs, so the disc grows along the fold (rocker-arm: 4 flipped faces
/// to none); such discs are capped at [`MAX_DISC`] free vertices, and their re-embedding
/// must move no vertex farther than [`MAX_SHIFT`] mean edge lengths.
///
/// Then, the disc being every remesh vertex of the flattening inside a circle around the
/// group (growing by [`CIRCLE_GROWTH`], at most [`CIRCLES`] times), whose boundary is
/// nearly convex even where the remesh is crushed in the flattening, re-embedded there,
/// with the disc's `slides` vertices sliding along the input's boundary ([`RimRun`]).
/// (Sliding in the discs of rings as well repairs no more faces on the corpus.)
/// A re-embedding is kept only if it lowers
/// the number of bad faces of the disc without pulling faces off the input. Returns the
/// number of vertices moved. Groups in `failed` whose corners are where they were when they
/// failed are skipped; groups that fail are added with their corners' positions. Faces off
/// the input by more than `off` count as bad.
#[allow(clippy::too_many_arguments)]
fn reembed(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topo: &Topology,
    fixed: &[bool],
    slides: &[bool],
    proj: &Projector,
    bad: &[u32],
    failed: &mut std::collections::HashMap<Vec<u32>, Vec<DVec3>>,
    off: f64,
) -> usize {
    let nv = pos.len();
    // Groups of bad faces sharing vertices (union-find over the faces' vertices).
    let mut parent: Vec<u32> = (0..nv as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for &f in bad {
        let fv = topo.face_vertices(f as usize);
        for w in fv.windows(2) {
            let (a, b) = (find(&mut parent, w[0]), find(&mut parent, w[1]));
            parent[a as usize] = b;
        }
    }
    let mut groups: std::collections::BTreeMap<u32, Vec<u32>> = Default::default();
    for &f in bad {
        let r = find(&mut parent, topo.face_vertices(f as usize)[0]);
        groups.entry(r).or_default().push(f);
    }
    let mut moved = 0;
    let mut in_region = vec![false; nv];
    for faces in groups.values() {
        // A group that could not be repaired before, and whose vertices have not moved
        // since, is skipped.
        let corners: Vec<DVec3> = faces
            .iter()
            .flat_map(|&f| {
                topo.face_vertices(f as usize)
                    .iter()
                    .map(|&v| pos[v as usize])
            })
            .collect();
        if failed.get(faces) == Some(&corners) {
            continue;
        }
        let mut repaired = false;
        // The disc: the group's and the `extra` vertices grown by k rings.
        let mut grow = |k: usize, extra: &[u32]| {
            let mut verts: Vec<u32> = faces
                .iter()
                .flat_map(|&f| topo.face_vertices(f as usize).iter().copied())
                .chain(extra.iter().copied())
                .collect();
            verts.sort_unstable();
            verts.dedup();
            for &v in &verts {
                in_region[v as usize] = true;
            }
            for _ in 0..k {
                let mut next = verts.clone();
                for &v in &verts {
                    for &e in topo.vertex_edges(v as usize) {
                        let w = topo.other_vertex(e as usize, v);
                        if !in_region[w as usize] {
                            in_region[w as usize] = true;
                            next.push(w);
                        }
                    }
                }
                verts = next;
            }
            for &v in &verts {
                in_region[v as usize] = false;
            }
            verts
        };
        // The input under the largest disc, flattened once for every disc; where that is
        // not a topological disc (it reaches across a boundary or onto another part of the
        // input), the input under a smaller one (teapot at 5 levels: 40 flipped faces to
        // 36, 82.0 to 84.5 dB; discs outside the patch are not re-embedded flat).
        let widest = RINGS.last().map_or(0, |&k| k + 1);
        let patch = [widest, 9, 5, 3]
            .into_iter()
            .find_map(|k| Patch::under(pos, hints, &grow(k, &[]), proj));
        let score = |pos: &[DVec3], hints: &[u32], disc_faces: &[u32]| {
            let mut nbad = 0;
            let mut dev = 0.0f64;
            let mut len = 0.0;
            for &f in disc_faces {
                let fv = topo.face_vertices(f as usize);
                if bad_face(fv, pos, hints, proj, BAD_ANGLE, off) {
                    nbad += 1;
                }
                let c = fv.iter().map(|&v| pos[v as usize]).sum::<DVec3>() / fv.len() as f64;
                let (q, _) = proj.closest_near(c, &face_hints(fv, hints));
                dev = dev.max(q.distance(c));
                len += pos[fv[0] as usize].distance(pos[fv[1] as usize]);
            }
            (nbad, dev, len / disc_faces.len().max(1) as f64)
        };
        let save = |movable: &[u32], pos: &[DVec3], hints: &[u32]| -> Vec<(DVec3, u32)> {
            movable
                .iter()
                .map(|&v| (pos[v as usize], hints[v as usize]))
                .collect()
        };
        // A re-embedding of the `movable` vertices (`saved`: where they were) is kept if
        // it lowers the bad faces around them without pulling faces off the input;
        // otherwise they are restored.
        let keep = |pos: &mut [DVec3],
                    hints: &mut [u32],
                    movable: &[u32],
                    saved: &[(DVec3, u32)],
                    faces: &[u32],
                    before: (usize, f64, f64)| {
            let after = score(pos, hints, faces);
            let better = after.0 < before.0 && after.1 <= before.1.max(0.05 * before.2);
            if !better {
                for (&v, &(p, t)) in movable.iter().zip(saved) {
                    pos[v as usize] = p;
                    hints[v as usize] = t;
                }
            }
            better
        };
        // Vertices of faces a flat re-embedding left turned over: where the fold runs out of
        // the disc (a pleat along a line), the next discs grow from them too.
        let mut extra: Vec<u32> = Vec::new();
        for &k in RINGS {
            let with_extra = !extra.is_empty();
            let verts = grow(k, &extra);
            let free: Vec<u32> = verts
                .iter()
                .copied()
                .filter(|&v| !fixed[v as usize] && !topo.vertex_edges(v as usize).is_empty())
                .collect();
            if free.is_empty() || free.len() > MAX_DISC {
                continue;
            }
            let disc_faces = faces_around(&free, topo);
            // The disc's score as it is (the flat re-embedding needs it only if it succeeds).
            let mut before = (k <= MEMBRANE_RINGS).then(|| score(pos, hints, &disc_faces));
            let saved = save(&free, pos, hints);
            if let Some(before) = before {
                for _ in 0..MEMBRANE_SWEEPS {
                    for &v in &free {
                        let edges = topo.vertex_edges(v as usize);
                        let c = edges
                            .iter()
                            .map(|&e| pos[topo.other_vertex(e as usize, v) as usize])
                            .sum::<DVec3>()
                            / edges.len() as f64;
                        pos[v as usize] = c;
                    }
                }
                // Lift along the disc's normal onto the input (the membrane is a height field over
                // the tangent plane; a closest point would pull it onto creases).
                let normal = free
                    .iter()
                    .map(|&v| proj.smooth_normal(saved_hint(&free, &saved, v)))
                    .sum::<DVec3>()
                    .normalize_or_zero();
                let reach = 2.0 * before.2;
                for &v in &free {
                    let p = pos[v as usize];
                    let up = proj.cast_ray(p, normal, reach);
                    let down = proj.cast_ray(p, -normal, reach);
                    let hit = match (up, down) {
                        (Some(a), Some(b)) => Some(if a.0 <= b.0 {
                            (p + normal * a.0, a.1)
                        } else {
                            (p - normal * b.0, b.1)
                        }),
                        (Some(a), None) => Some((p + normal * a.0, a.1)),
                        (None, Some(b)) => Some((p - normal * b.0, b.1)),
                        (None, None) => None,
                    };
                    let (q, t) = match hit {
                        Some(h) if normal != DVec3::ZERO => h,
                        _ => project(proj, p, hints[v as usize]),
                    };
                    pos[v as usize] = q;
                    hints[v as usize] = t;
                }
                if keep(pos, hints, &free, &saved, &disc_faces, before) {
                    moved += free.len();
                    repaired = true;
                    break;
                }
            }
            // Where the input bends within the disc, a membrane lifted along one normal
            // cannot open the fold: Tutte's embedding in a flattening of the input can.
            let tf = std::time::Instant::now();
            let fr = patch
                .as_ref()
                .map(|pt| flat_reembed(pt, pos, hints, topo, &free, &[], &disc_faces, proj));
            tracing::trace!(
                k,
                free = free.len(),
                ok = matches!(fr, Some(Ok(_))),
                ms = tf.elapsed().as_secs_f64() * 1e3,
                "flat attempt"
            );
            if let Some(Err(folded)) = &fr {
                extra.extend_from_slice(folded);
                extra.sort_unstable();
                extra.dedup();
            }
            if let Some(Ok(moves)) = fr {
                let before = *before.get_or_insert_with(|| score(pos, hints, &disc_faces));
                let far = free
                    .iter()
                    .zip(&moves)
                    .any(|(&v, m)| m.0.distance(pos[v as usize]) > MAX_SHIFT * before.2);
                if with_extra && far {
                    continue;
                }
                for (&v, &(p, t)) in free.iter().zip(&moves) {
                    pos[v as usize] = p;
                    hints[v as usize] = t;
                }
                if keep(pos, hints, &free, &saved, &disc_faces, before) {
                    moved += free.len();
                    repaired = true;
                    break;
                }
            }
        }
        // Where the remesh around the group is crushed in the flattening (a fold wider than
        // the discs of rings), the disc is every remesh vertex in a growing circle of the
        // flattening: its boundary is then nearly convex, and Tutte's embedding spanned by
        // it does not fold.
        if let (false, Some(pt)) = (repaired, patch.as_ref()) {
            let candidates = grow(widest, &[]);
            let flat: Vec<Option<DVec2>> = candidates
                .iter()
                .map(|&v| pt.flat_vertex(proj, pos[v as usize], hints[v as usize]))
                .collect();
            let group: Vec<DVec2> = faces
                .iter()
                .flat_map(|&f| topo.face_vertices(f as usize))
                .filter_map(|&v| {
                    let i = candidates.iter().position(|&w| w == v)?;
                    flat[i]
                })
                .collect();
            if !group.is_empty() {
                let c = group.iter().copied().sum::<DVec2>() / group.len() as f64;
                let r0 = group.iter().map(|p| p.distance(c)).fold(0.0, f64::max);
                let mut last = 0;
                for j in 1..=CIRCLES {
                    let rho = (r0.max(1e-3) * CIRCLE_GROWTH.powi(j)).min(2.0);
                    let inside: Vec<u32> = candidates
                        .iter()
                        .zip(&flat)
                        .filter(|(_, p)| p.is_some_and(|p| p.distance(c) < rho))
                        .map(|(&v, _)| v)
                        .collect();
                    if inside.len() == last {
                        continue;
                    }
                    last = inside.len();
                    let free: Vec<u32> = inside
                        .iter()
                        .copied()
                        .filter(|&v| {
                            !fixed[v as usize] && !topo.vertex_edges(v as usize).is_empty()
                        })
                        .collect();
                    let runs = rim_runs(&inside, topo, slides);
                    let mut movable = free.clone();
                    movable.extend(runs.iter().flat_map(|r| r.verts.iter().copied()));
                    if free.is_empty() {
                        continue;
                    }
                    let disc_faces = faces_around(&movable, topo);
                    let Ok(moves) =
                        flat_reembed(pt, pos, hints, topo, &free, &runs, &disc_faces, proj)
                    else {
                        continue;
                    };
                    let before = score(pos, hints, &disc_faces);
                    let saved = save(&movable, pos, hints);
                    for (&v, &(p, t)) in movable.iter().zip(&moves) {
                        pos[v as usize] = p;
                        hints[v as usize] = t;
                    }
                    if keep(pos, hints, &movable, &saved, &disc_faces, before) {
                        moved += movable.len();
                        repaired = true;
                        break;
                    }
                    if rho >= 2.0 {
                        break;
                    }
                }
            }
        }
        if !repaired {
            failed.insert(faces.clone(), corners);
        }
    }
    moved
}

/// The chains of `slides` vertices among `verts` along the remesh boundary, each between
/// the boundary vertices (not sliding, or outside `verts`) before and after it; closed
/// chains (a whole hole's rim) and vertices without exactly two boundary edges stay.
fn rim_runs(verts: &[u32], topo: &Topology, slides: &[bool]) -> Vec<RimRun> {
    if slides.is_empty() {
        return Vec::new();
    }
    let bnext = |v: u32| -> Option<[u32; 2]> {
        let mut out = [u32::MAX; 2];
        let mut n = 0;
        for &e in topo.vertex_edges(v as usize) {
            if topo.is_boundary_edge(e as usize) {
                if n == 2 {
                    return None;
                }
                out[n] = topo.other_vertex(e as usize, v);
                n += 1;
            }
        }
        (n == 2).then_some(out)
    };
    let in_disc: std::collections::HashSet<u32> = verts
        .iter()
        .copied()
        .filter(|&v| slides.get(v as usize) == Some(&true) && bnext(v).is_some())
        .collect();
    let mut done: std::collections::HashSet<u32> = Default::default();
    let mut runs = Vec::new();
    for &v in verts {
        if !in_disc.contains(&v) || done.contains(&v) {
            continue;
        }
        // Back to the chain's start, then forward to its end.
        let walk = |from: u32, prev: u32| -> (Vec<u32>, u32) {
            let mut chain = vec![from];
            let (mut cur, mut prev) = (from, prev);
            while let Some(nb) = bnext(cur) {
                let nxt = if nb[0] == prev { nb[1] } else { nb[0] };
                if !in_disc.contains(&nxt) || nxt == from {
                    return (chain, nxt);
                }
                chain.push(nxt);
                prev = cur;
                cur = nxt;
            }
            (chain, u32::MAX)
        };
        let Some(nb) = bnext(v) else { continue };
        let (back, a) = walk(v, nb[1]);
        let (fwd, b) = walk(v, nb[0]);
        done.extend(back.iter().chain(&fwd).copied());
        if a == v || b == v || a == u32::MAX || b == u32::MAX || a == b {
            continue; // closed, or no anchor
        }
        let mut chain: Vec<u32> = back.into_iter().rev().collect();
        chain.extend_from_slice(&fwd[1..]);
        runs.push(RimRun {
            anchors: [a, b],
            verts: chain,
        });
    }
    runs
}

/// The centre of the kernel of vertex `v`'s star in the plane through `p` with unit normal
/// `n`: the point maximizing the smallest signed distance `r` to the lines of the edges of the
/// faces around `v` that are not incident to it (each face turns counterclockwise around `n`
/// when `v` is on the positive side of them), found by enumerating the vertices of that
/// linear program in `(x, y, r)` (a few edges; bounded by a box twice the ring's radius).
/// Returns the point in 3D, `r` (negative: the kernel is empty and the point violates the
/// constraints least) and the same margin for `p` itself; `None` for a zero normal or a vertex without faces.
pub fn kernel_centre(
    v: usize,
    p: DVec3,
    n: DVec3,
    topo: &Topology,
    pos: &[DVec3],
) -> Option<(DVec3, f64, f64)> {
    if n == DVec3::ZERO {
        return None;
    }
    let (e1, e2) = n.any_orthonormal_pair();
    let to2 = |q: DVec3| {
        let d = q - p;
        [d.dot(e1), d.dot(e2)]
    };
    // Constraints u·x − r ≥ c with unit u.
    let mut cons: Vec<([f64; 2], f64)> = Vec::with_capacity(16);
    let mut radius = 0.0f64;
    let mut centre = [0.0f64; 2];
    let mut nring = 0.0;
    for &f in topo.vertex_faces(v) {
        let fv = topo.face_vertices(f as usize);
        let m = fv.len();
        let Some(k) = fv.iter().position(|&w| w as usize == v) else {
            continue;
        };
        for i in 1..m - 1 {
            let a = to2(pos[fv[(k + i) % m] as usize]);
            let b = to2(pos[fv[(k + i + 1) % m] as usize]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let l = (d[0] * d[0] + d[1] * d[1]).sqrt();
            if l <= 0.0 {
                continue;
            }
            let u = [-d[1] / l, d[0] / l];
            cons.push((u, u[0] * a[0] + u[1] * a[1]));
        }
        let a = to2(pos[fv[(k + 1) % m] as usize]);
        radius = radius.max((a[0] * a[0] + a[1] * a[1]).sqrt());
        centre[0] += a[0];
        centre[1] += a[1];
        nring += 1.0;
    }
    if cons.len() < 3 || radius <= 0.0 {
        return None;
    }
    let centre = DVec2::new(centre[0] / nring, centre[1] / nring);
    // The margin of `p` itself (the origin of the plane).
    let margin = cons.iter().map(|c| -c.1).fold(f64::INFINITY, f64::min);
    let mut cons: Vec<(DVec2, f64)> = cons
        .into_iter()
        .map(|(u, c)| (DVec2::new(u[0], u[1]), c))
        .collect();
    let best = chebyshev_centre(&mut cons, centre, radius);
    best.map(|(x, r)| (p + e1 * x.x + e2 * x.y, r, margin))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::icosphere;

    /// The bad faces of `pos` among all faces (as [`bad_face`] with [`BAD_ANGLE`]).
    fn all_bad(topo: &Topology, pos: &[DVec3], hints: &[u32], proj: &Projector) -> Vec<u32> {
        (0..topo.num_faces() as u32)
            .filter(|&f| {
                let fv = topo.face_vertices(f as usize);
                bad_face(fv, pos, hints, proj, BAD_ANGLE, f64::INFINITY)
            })
            .collect()
    }

    /// A 3-level icosphere's mesh on a 5-level icosphere (the input), its vertices on the
    /// input, with those in `pushed` moved past their first neighbour (onto the input), so
    /// that their stars fold.
    struct Folded {
        proj: Projector,
        topo: Topology,
        pos: Vec<DVec3>,
        hints: Vec<u32>,
    }

    impl Folded {
        fn new(pushed: &[usize]) -> Folded {
            let input = icosphere(5);
            let tris: Vec<[u32; 3]> = input.faces().map(|f| [f[0], f[1], f[2]]).collect();
            let proj = Projector::new(&input.positions, &tris).unwrap();
            let coarse = icosphere(3);
            let topo = Topology::build(&coarse);
            let (mut pos, mut hints): (Vec<DVec3>, Vec<u32>) =
                coarse.positions.iter().map(|&p| proj.closest(p)).unzip();
            assert!(all_bad(&topo, &pos, &hints, &proj).is_empty());
            for &v in pushed {
                let w = topo.other_vertex(topo.vertex_edges(v)[0] as usize, v as u32) as usize;
                (pos[v], hints[v]) = proj.closest(pos[w] + 0.3 * (pos[w] - pos[v]));
            }
            Folded {
                proj,
                topo,
                pos,
                hints,
            }
        }

        fn bad(&self) -> Vec<u32> {
            all_bad(&self.topo, &self.pos, &self.hints, &self.proj)
        }

        /// [`search_rounds`] from the bad faces; the faces left and the moves made.
        fn search(&mut self, fixed: &[bool]) -> (Vec<u32>, usize) {
            let bad = self.bad();
            let mut origin = vec![None; self.pos.len()];
            let mut moves = 0;
            let left = search_rounds(
                &mut self.pos,
                &mut self.hints,
                &self.topo,
                fixed,
                &self.proj,
                bad,
                &mut origin,
                &mut moves,
                f64::INFINITY,
            );
            (left, moves)
        }
    }

    /// The star search alone (no kernel move, no re-embedding) opens folds made by pushing
    /// vertices of a sphere's mesh past a neighbour: each pushed vertex is walked back onto
    /// the input, towards its ring, until no face of its star is turned over or thin; every
    /// other vertex stays, and every vertex stays on the input.
    #[test]
    fn star_search_opens_pushed_folds() {
        let pushed: Vec<usize> = (0..642).step_by(101).collect();
        let mut c = Folded::new(&pushed);
        assert!(
            c.bad().len() >= 2 * pushed.len(),
            "{} bad faces",
            c.bad().len()
        );
        let before = c.pos.clone();
        let (left, moves) = c.search(&vec![false; before.len()]);
        assert!(left.is_empty(), "{} bad faces left", left.len());
        assert!(c.bad().is_empty());
        assert!(moves >= pushed.len(), "{moves} moves");
        for (v, (&p, &b)) in c.pos.iter().zip(&before).enumerate() {
            assert!(c.proj.closest(p).0.distance(p) < 1e-9, "vertex {v}");
            let near = pushed.iter().any(|&u| {
                u == v
                    || c.topo
                        .vertex_edges(u)
                        .iter()
                        .any(|&e| c.topo.other_vertex(e as usize, u as u32) as usize == v)
            });
            if !near {
                assert_eq!(p, b, "vertex {v} moved");
            }
        }
    }

    /// With a fixed pushed vertex the search cannot open its fold by moving it; it leaves
    /// the fold (or opens it by moving the ring) and never moves the fixed vertex; the faces
    /// it reports are exactly the bad ones.
    #[test]
    fn star_search_keeps_fixed_vertices() {
        let v = 7;
        let mut c = Folded::new(&[v]);
        let q = c.pos[v];
        let mut fixed = vec![false; c.pos.len()];
        fixed[v] = true;
        let (left, _) = c.search(&fixed);
        assert_eq!(c.pos[v], q);
        assert_eq!(left, c.bad());
    }
}

//! Re-embedding a folded disc of a remesh in a flattening of the input surface under it.
//!
//! MAPS (Lee et al. 1998, §4) smooths resampled points in the parameter domain, where a
//! fold-free embedding exists. The repairs of [`super::fold_repair`] move vertices in the
//! input's tangent plane (one vertex into the kernel of its star, or a disc as a membrane
//! lifted along one normal), which cannot open a fold where the input bends within it — the
//! bunny's bottom plate between its holes and its sides is a strip narrower than a level-5
//! face, and most of the bunny's last flipped faces lie on it. Here the input triangles
//! under a disc of the remesh are flattened by Tutte's barycentric embedding (Tutte 1963;
//! Floater 1997, Theorem 1: uniform weights with the boundary on a convex polygon embed a
//! triangulated disc without folds), the disc's free vertices take Tutte's embedding spanned
//! by the disc's other vertices in that plane (where the disc's boundary is not convex and
//! Tutte's embedding folds, vertices move into the kernels of their stars, exactly as in
//! the plane; where that gets stuck — free vertices that must move together — all of them
//! minimize the regularized shape energy of [`super::untangle_energy`] from Tutte's
//! embedding), and each goes back to the input point with the same flat coordinates (it
//! lies on the input by construction). The simultaneous untangling, measured on the bunny
//! at 6 levels over 200 base faces: of about 1,000 flat re-embeddings, 580 stayed folded
//! in the plane before it and 52 after; the flipped faces left went from 2 to 1 (the last
//! one went with [`super::ancestor_flatten`]'s re-embedded ancestors), and the cow's at 4
//! levels from 2 to none. Only positions change; the caller keeps the result
//! only if it lowers the number of bad faces. On the corpus at 5 levels this halves the
//! flipped faces left on the bunny (81 to 32) and leaves 1 of spot's 29.
//!
//! Next to a hole, the remesh's boundary vertices crowd on the input's boundary where the
//! interior needs room; pinned, they keep the fold. [`RimRun`]s let them slide along the
//! input's boundary: between two boundary vertices that stay, they are spaced evenly by
//! arc length on the patch's boundary loop, which runs along the input's boundary there
//! (with the discs chosen as circles of the flattening in [`super::fold_repair`], the
//! bunny's flipped faces at 5 levels go from 32 to 2).

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::resample::{closest_on_triangle, Projector};
use super::untangle_energy;
use crate::topology::Topology;

/// Rings of input triangles added around the triangles under the disc, so that the
/// flattening's distortion at its circular boundary stays away from the disc.
const PATCH_RINGS: usize = 2;

/// Rings of input triangles at most around the triangles under the disc, while they do not
/// form a topological disc (gaps between the seeds).
const MAX_PATCH_RINGS: usize = 8;

/// The largest input patch flattened (triangles); bigger ones are not folds to repair
/// locally.
const MAX_PATCH_TRIANGLES: usize = 20_000;

/// Conjugate-gradient iterations at most per coordinate of a Tutte solve.
const CG_ITERATIONS: usize = 2_000;

/// New positions and input triangles for the `free` vertices of a remesh disc whose faces
/// are `disc_faces` (every face around a free vertex or a sliding one), from Tutte's
/// embedding in `patch`, a flattening of the input under the disc (see the module
/// documentation), untangled vertex by vertex where the disc's boundary is not convex;
/// then for the vertices of `runs`, in their order.
///
/// The vertices of each run of `runs` (remesh vertices on the input's boundary, pinned
/// otherwise) slide along the input's boundary between their anchors, evenly spaced by
/// arc length: the boundary of a disc whose vertices crowd on the input's boundary
/// (next to a hole, where the input is a narrow strip) then leaves the interior room to
/// unfold.
///
/// Preconditions: `pos` and `hints` have `topo.num_vertices` entries, the vertices lie on
/// the input behind `proj`, and `hints[v]` is an input triangle near vertex `v`; runs do
/// not share vertices with `free` or each other.
/// Returns `Err` when a vertex of the disc lies outside the patch or a run's anchors are
/// not joined by the input's boundary inside the patch (with no vertices), or when the flat
/// embedding of the disc still folds after the untangling (with the vertices of the faces
/// still turned over, among them disc boundary vertices that would have to move: where a
/// fold runs out of the disc, the caller grows the disc over them).
#[allow(clippy::too_many_arguments)]
pub(super) fn flat_reembed(
    patch: &Patch,
    pos: &[DVec3],
    hints: &[u32],
    topo: &Topology,
    free: &[u32],
    runs: &[RimRun],
    disc_faces: &[u32],
    proj: &Projector,
) -> Result<Vec<(DVec3, u32)>, Vec<u32>> {
    // The disc's vertices, free ones first, then the sliding ones.
    let mut local: HashMap<u32, u32> = HashMap::new();
    let mut verts: Vec<u32> = Vec::new();
    let sliding = runs.iter().flat_map(|r| r.verts.iter());
    for &v in free.iter().chain(sliding).chain(
        disc_faces
            .iter()
            .flat_map(|&f| topo.face_vertices(f as usize)),
    ) {
        local.entry(v).or_insert_with(|| {
            verts.push(v);
            verts.len() as u32 - 1
        });
    }
    let flat = |v: u32| patch.flat_vertex(proj, pos[v as usize], hints[v as usize]);
    // Flat coordinates of the disc's vertices: the fixed ones where they lie, the sliding
    // ones evenly along the boundary between their anchors, the free ones from Tutte's
    // embedding spanned by them.
    let nfree = free.len();
    let nslide: usize = runs.iter().map(|r| r.verts.len()).sum();
    let mut known: Vec<Option<DVec2>> = vec![None; verts.len()];
    let mut next = nfree;
    let none = Vec::new;
    for run in runs {
        let a = (flat(run.anchors[0]).and_then(|p| patch.rim_param(p))).ok_or_else(none)?;
        let b = (flat(run.anchors[1]).and_then(|p| patch.rim_param(p))).ok_or_else(none)?;
        let total = patch.rim_arc[patch.rim.len()];
        // Both ways round the loop; the one along the input's boundary (the shorter if
        // both are).
        let fwd = (b - a).rem_euclid(total);
        let delta = [fwd, fwd - total]
            .into_iter()
            .filter(|&d| patch.rim_is_open(a, d))
            .min_by(|x, y| x.abs().total_cmp(&y.abs()))
            .ok_or_else(none)?;
        let n = run.verts.len() as f64;
        for j in 0..run.verts.len() {
            known[next] = Some(patch.rim_point(a + delta * (j as f64 + 1.0) / (n + 1.0)));
            next += 1;
        }
    }
    for i in nfree + nslide..verts.len() {
        known[i] = Some(flat(verts[i]).ok_or_else(none)?);
    }
    let mut start = vec![0u32; verts.len() + 1];
    let mut adj: Vec<u32> = Vec::new();
    for (i, &v) in verts.iter().enumerate() {
        if i < nfree {
            for &e in topo.vertex_edges(v as usize) {
                let w = topo.other_vertex(e as usize, v);
                adj.push(*local.get(&w).ok_or_else(none)?);
            }
        }
        start[i + 1] = adj.len() as u32;
    }
    let Some(uv) = tutte(&start, &adj, &known) else {
        tracing::trace!("flat: disc tutte failed");
        return Err(none());
    };
    // Tutte's embedding folds next to reflex corners of the disc's boundary: move the
    // free vertices of folded faces into the kernels of their stars, as
    // [`super::fold_repair`] does in the tangent plane, here in the exact plane.
    let faces: Vec<Vec<u32>> = disc_faces
        .iter()
        .map(|&f| {
            topo.face_vertices(f as usize)
                .iter()
                .map(|v| local[v])
                .collect()
        })
        .collect();
    let mut uv = uv;
    let tutte_uv = uv.clone();
    // Where one node at a time gets stuck, all of them at once from Tutte's embedding.
    if !untangle_flat(&mut uv, nfree, &faces) && {
        uv.copy_from_slice(&tutte_uv);
        let t = std::time::Instant::now();
        let ok = untangle_energy::untangle(&mut uv, nfree, &faces, ENERGY_SWEEPS);
        tracing::trace!(
            nfree,
            ok,
            ms = t.elapsed().as_secs_f64() * 1e3,
            "energy untangle"
        );
        !ok
    } {
        tracing::trace!(free = nfree, "flat: the disc stays folded in the plane");
        let mut folded: Vec<u32> = faces
            .iter()
            .filter(|fv| !turns_ccw(&uv, fv))
            .flat_map(|fv| fv.iter().map(|&i| verts[i as usize]))
            .collect();
        folded.sort_unstable();
        folded.dedup();
        return Err(folded);
    }
    (0..nfree + nslide)
        .map(|i| patch.lift(proj, uv[i]))
        .collect::<Option<Vec<_>>>()
        .ok_or_else(none)
}

/// Whether flat polygon `fv` (node indices into `uv`) turns counterclockwise.
fn turns_ccw(uv: &[DVec2], fv: &[u32]) -> bool {
    let m = fv.len();
    (0..m)
        .map(|i| uv[fv[i] as usize].perp_dot(uv[fv[(i + 1) % m] as usize]))
        .sum::<f64>()
        > 0.0
}

/// Twice the signed area of a polygon.
fn polygon_area(p: &[DVec2]) -> f64 {
    (0..p.len())
        .map(|i| p[i].perp_dot(p[(i + 1) % p.len()]))
        .sum()
}

/// Input triangles flattened onto the plane (a topological disc of the input under a disc
/// of the remesh, see [`Patch::under`]).
pub(super) struct Patch {
    /// The input triangles.
    tris: Vec<u32>,
    /// Local vertex indices of each triangle's corners.
    corners: Vec<[u32; 3]>,
    /// Flat coordinates of each local vertex.
    uv: Vec<DVec2>,
    /// Local index of each input triangle of the patch.
    index: HashMap<u32, u32>,
    /// Cells per side of the grid over `[-1, 1]²` that buckets the flat triangles.
    cells: usize,
    /// The triangles overlapping each grid cell (CSR: `bucket[bucket_start[c]..bucket_start[c + 1]]`).
    bucket_start: Vec<u32>,
    bucket: Vec<u32>,
    /// The patch's boundary loop (local vertex indices, counterclockwise in the plane).
    rim: Vec<u32>,
    /// Arc length along `rim` at each of its vertices (`rim.len() + 1` entries, in 3D).
    rim_arc: Vec<f64>,
    /// Whether the loop's edge `i` (`rim[i]` to `rim[i + 1]`) is on the input's boundary
    /// (rather than cut out of the input by the patch).
    rim_open: Vec<bool>,
}

/// A chain of remesh vertices on the input's boundary that may slide along it: `verts` in
/// their order along the remesh boundary, between the two `anchors` that stay (see
/// [`flat_reembed`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct RimRun {
    /// The boundary vertices before the first and after the last of `verts`.
    pub anchors: [u32; 2],
    /// The sliding vertices, from `anchors[0]` to `anchors[1]`.
    pub verts: Vec<u32>,
}

impl Patch {
    /// The input under the remesh vertices `verts` (the triangles they lie on, grown as
    /// [`Patch::flatten`] does), flattened; `None` if they do not form one disc.
    pub(super) fn under(
        pos: &[DVec3],
        hints: &[u32],
        verts: &[u32],
        proj: &Projector,
    ) -> Option<Patch> {
        // The input triangle each vertex lies on (a hint may be a neighbour of it).
        let seeds: Vec<u32> = verts
            .iter()
            .map(|&v| proj.closest_near(pos[v as usize], &[hints[v as usize]]).1)
            .collect();
        if seeds.iter().any(|&t| t as usize >= proj.num_triangles()) {
            return None;
        }
        Patch::flatten(proj, &seeds)
    }

    /// The `seeds` input triangles grown by [`PATCH_RINGS`] rings, and by more (up to
    /// [`MAX_PATCH_RINGS`]) until they form a topological disc, flattened by Tutte's
    /// embedding with the boundary on the unit circle (by arc length); `None` if they do
    /// not become one disc or grow too large.
    fn flatten(proj: &Projector, seeds: &[u32]) -> Option<Patch> {
        let mut tris: Vec<u32> = seeds.to_vec();
        tris.sort_unstable();
        tris.dedup();
        for ring in 0..MAX_PATCH_RINGS {
            let mut grown = tris.clone();
            for &t in &tris {
                for v in proj.triangle(t) {
                    grown.extend_from_slice(proj.fan(v));
                }
            }
            grown.sort_unstable();
            grown.dedup();
            tris = grown;
            if tris.len() > MAX_PATCH_TRIANGLES {
                return None;
            }
            if ring + 1 >= PATCH_RINGS {
                if let Some(patch) = Patch::flatten_disc(proj, &tris) {
                    return Some(patch);
                }
            }
        }
        None
    }

    /// Input triangles `tris` (sorted, distinct) flattened as [`Patch::flatten`] does;
    /// `None` if they are not one topological disc.
    fn flatten_disc(proj: &Projector, tris: &[u32]) -> Option<Patch> {
        let tris = tris.to_vec();
        let index: HashMap<u32, u32> = tris
            .iter()
            .enumerate()
            .map(|(i, &t)| (t, i as u32))
            .collect();
        let mut vlocal: HashMap<u32, u32> = HashMap::new();
        let mut vglobal: Vec<u32> = Vec::new();
        let corners: Vec<[u32; 3]> = tris
            .iter()
            .map(|&t| {
                proj.triangle(t).map(|v| {
                    *vlocal.entry(v).or_insert_with(|| {
                        vglobal.push(v);
                        vglobal.len() as u32 - 1
                    })
                })
            })
            .collect();
        let nv = vglobal.len();
        // Half-edges, sorted (deterministic order); a boundary half-edge has no twin.
        let mut half: Vec<(u32, u32)> = corners
            .iter()
            .flat_map(|c| (0..3).map(move |k| (c[k], c[(k + 1) % 3])))
            .collect();
        half.sort_unstable();
        if half.windows(2).any(|w| w[0] == w[1]) {
            return None;
        }
        let has = |a: u32, b: u32| half.binary_search(&(a, b)).is_ok();
        let mut next = vec![u32::MAX; nv];
        let mut nboundary = 0;
        let mut nedges = 0;
        for &(a, b) in &half {
            if has(b, a) {
                nedges += 1; // once per direction: halved below
            } else {
                if next[a as usize] != u32::MAX {
                    return None; // two boundary edges leave `a`: pinched
                }
                next[a as usize] = b;
                nboundary += 1;
                nedges += 2;
            }
        }
        let nedges = nedges / 2;
        // One disc: V − E + F = 1 and one boundary loop through every boundary edge.
        if nv as i64 - nedges as i64 + corners.len() as i64 != 1 || nboundary < 3 {
            return None;
        }
        let first = next.iter().position(|&n| n != u32::MAX)? as u32;
        let mut lp = vec![first];
        let mut cur = next[first as usize];
        while cur != first {
            if lp.len() > nboundary {
                return None;
            }
            lp.push(cur);
            cur = *next.get(cur as usize)?;
            if cur == u32::MAX {
                return None;
            }
        }
        if lp.len() != nboundary {
            return None;
        }
        // The boundary onto the unit circle by arc length, in the loop's order.
        let p3 = |i: u32| proj.vertex(vglobal[i as usize]);
        let mut arc = vec![0.0f64; lp.len() + 1];
        for i in 0..lp.len() {
            arc[i + 1] = arc[i] + p3(lp[i]).distance(p3(lp[(i + 1) % lp.len()]));
        }
        let total = arc[lp.len()];
        if total <= 0.0 || !total.is_finite() {
            return None;
        }
        let mut known: Vec<Option<DVec2>> = vec![None; nv];
        for (i, &v) in lp.iter().enumerate() {
            let a = std::f64::consts::TAU * arc[i] / total;
            known[v as usize] = Some(DVec2::new(a.cos(), a.sin()));
        }
        // Vertex adjacency (each undirected edge from both ends).
        let mut start = vec![0u32; nv + 1];
        for &(a, b) in &half {
            start[a as usize + 1] += 1;
            if !has(b, a) {
                start[b as usize + 1] += 1;
            }
        }
        for i in 0..nv {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut adj = vec![0u32; start[nv] as usize];
        for &(a, b) in &half {
            adj[fill[a as usize] as usize] = b;
            fill[a as usize] += 1;
            if !has(b, a) {
                adj[fill[b as usize] as usize] = a;
                fill[b as usize] += 1;
            }
        }
        let mut uv = tutte(&start, &adj, &known)?;
        let area: f64 = corners
            .iter()
            .map(|c| polygon_area(&c.map(|i| uv[i as usize])))
            .sum();
        // Mirrored if need be, so that the input's faces turn counterclockwise.
        if area < 0.0 {
            for p in &mut uv {
                p.y = -p.y;
            }
            // The loop then runs clockwise: reversed, so that it runs counterclockwise.
            lp.reverse();
        }
        let mut rim_arc = vec![0.0f64; lp.len() + 1];
        for i in 0..lp.len() {
            rim_arc[i + 1] = rim_arc[i] + p3(lp[i]).distance(p3(lp[(i + 1) % lp.len()]));
        }
        // An edge of the loop is on the input's boundary when one input triangle has it.
        let rim_open: Vec<bool> = (0..lp.len())
            .map(|i| {
                let (a, b) = (
                    vglobal[lp[i] as usize],
                    vglobal[lp[(i + 1) % lp.len()] as usize],
                );
                proj.fan(a)
                    .iter()
                    .filter(|&&t| proj.triangle(t).contains(&b))
                    .count()
                    == 1
            })
            .collect();
        // Buckets of the flat triangles for point location.
        let cells = ((corners.len() as f64).sqrt().ceil() as usize).clamp(1, 256);
        let cell_of =
            |x: f64| (((x + 1.0) * 0.5 * cells as f64).floor().max(0.0) as usize).min(cells - 1);
        let ranges: Vec<[usize; 4]> = corners
            .iter()
            .map(|c| {
                let p = c.map(|i| uv[i as usize]);
                let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
                [cell_of(lo.x), cell_of(hi.x), cell_of(lo.y), cell_of(hi.y)]
            })
            .collect();
        let mut bucket_start = vec![0u32; cells * cells + 1];
        for r in &ranges {
            for y in r[2]..=r[3] {
                for x in r[0]..=r[1] {
                    bucket_start[y * cells + x + 1] += 1;
                }
            }
        }
        for i in 0..cells * cells {
            bucket_start[i + 1] += bucket_start[i];
        }
        let mut fill = bucket_start.clone();
        let mut bucket = vec![0u32; bucket_start[cells * cells] as usize];
        for (t, r) in ranges.iter().enumerate() {
            for y in r[2]..=r[3] {
                for x in r[0]..=r[1] {
                    bucket[fill[y * cells + x] as usize] = t as u32;
                    fill[y * cells + x] += 1;
                }
            }
        }
        Some(Patch {
            tris,
            corners,
            uv,
            index,
            cells,
            bucket_start,
            bucket,
            rim: lp,
            rim_arc,
            rim_open,
        })
    }

    /// Arc-length parameter along the patch's boundary loop of flat point `x`, which must
    /// lie on the loop (within `1e-9`); `None` otherwise.
    fn rim_param(&self, x: DVec2) -> Option<f64> {
        let n = self.rim.len();
        let mut best: Option<(f64, f64)> = None;
        for i in 0..n {
            let a = self.uv[self.rim[i] as usize];
            let b = self.uv[self.rim[(i + 1) % n] as usize];
            let d = b - a;
            let l2 = d.length_squared();
            let t = if l2 > 0.0 {
                ((x - a).dot(d) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let dist = x.distance(a + d * t);
            if best.is_none_or(|bst| dist < bst.0) {
                best = Some((
                    dist,
                    self.rim_arc[i] + t * (self.rim_arc[i + 1] - self.rim_arc[i]),
                ));
            }
        }
        best.filter(|b| b.0 <= 1e-9).map(|b| b.1)
    }

    /// The flat point at arc-length parameter `s` (any real: taken modulo the loop's
    /// length) along the patch's boundary loop.
    fn rim_point(&self, s: f64) -> DVec2 {
        let n = self.rim.len();
        let total = self.rim_arc[n];
        let s = s.rem_euclid(total);
        let i = (self.rim_arc.partition_point(|&a| a <= s) - 1).min(n - 1);
        let (a, b) = (self.rim_arc[i], self.rim_arc[i + 1]);
        let t = if b > a { (s - a) / (b - a) } else { 0.0 };
        let (pa, pb) = (
            self.uv[self.rim[i] as usize],
            self.uv[self.rim[(i + 1) % n] as usize],
        );
        pa + (pb - pa) * t
    }

    /// Whether the loop between parameters `a` and `a + delta` (`delta` of either sign,
    /// `|delta|` below the loop's length) runs only along the input's boundary.
    fn rim_is_open(&self, a: f64, delta: f64) -> bool {
        let n = self.rim.len();
        let total = self.rim_arc[n];
        let (lo, hi) = if delta >= 0.0 {
            (a, a + delta)
        } else {
            (a + delta, a)
        };
        let lo = lo.rem_euclid(total);
        let hi = lo + (hi - lo);
        // Edges overlapping (lo, hi) with positive length, on the loop and its copy shifted
        // by one turn.
        (0..n).all(|i| {
            let overlaps = |shift: f64| {
                let (s, e) = (self.rim_arc[i] + shift, self.rim_arc[i + 1] + shift);
                s.max(lo) < e.min(hi)
            };
            self.rim_open[i] || !(overlaps(0.0) || overlaps(total))
        })
    }
    /// Flat coordinates of the input point `p` near input triangle `hint` (`None` if the
    /// input triangle it lies on is not in the patch).
    pub(super) fn flat_vertex(&self, proj: &Projector, p: DVec3, hint: u32) -> Option<DVec2> {
        let (_, t) = proj.closest_near(p, &[hint]);
        self.flat_of(proj, p, t)
    }

    /// Flat coordinates of input point `p` on input triangle `t` (`None` if `t` is not in
    /// the patch).
    fn flat_of(&self, proj: &Projector, p: DVec3, t: u32) -> Option<DVec2> {
        let i = *self.index.get(&t)? as usize;
        let [a, b, c] = proj.triangle(t).map(|v| proj.vertex(v));
        let q = closest_on_triangle(p, a, b, c);
        let w = barycentric3(q, a, b, c)?;
        let [ua, ub, uc] = self.corners[i].map(|k| self.uv[k as usize]);
        Some(ua * w[0] + ub * w[1] + uc * w[2])
    }

    /// The input point with flat coordinates `x` and its triangle (`None` outside the
    /// patch).
    fn lift(&self, proj: &Projector, x: DVec2) -> Option<(DVec3, u32)> {
        if !(x.x.abs() <= 1.0 && x.y.abs() <= 1.0) {
            return None;
        }
        let cell_of = |v: f64| {
            (((v + 1.0) * 0.5 * self.cells as f64).floor().max(0.0) as usize).min(self.cells - 1)
        };
        let c = cell_of(x.y) * self.cells + cell_of(x.x);
        let mut best: Option<(f64, usize, [f64; 3])> = None;
        for &i in &self.bucket[self.bucket_start[c] as usize..self.bucket_start[c + 1] as usize] {
            let i = i as usize;
            let [a, b, cc] = self.corners[i].map(|k| self.uv[k as usize]);
            let d = (b - a).perp_dot(cc - a);
            if d == 0.0 {
                continue;
            }
            let w1 = (x - a).perp_dot(cc - a) / d;
            let w2 = (b - a).perp_dot(x - a) / d;
            let w = [1.0 - w1 - w2, w1, w2];
            let m = w[0].min(w[1]).min(w[2]);
            if best.is_none_or(|bst| m > bst.0) {
                best = Some((m, i, w));
            }
        }
        let (m, i, w) = best?;
        if m < -1e-9 {
            return None;
        }
        let w = w.map(|x| x.max(0.0));
        let s = w[0] + w[1] + w[2];
        let t = self.tris[i];
        let [a, b, c] = proj.triangle(t).map(|v| proj.vertex(v));
        Some(((a * w[0] + b * w[1] + c * w[2]) / s, t))
    }
}

/// Sweeps of [`untangle_energy::untangle`] at most, where [`untangle_flat`] fails.
const ENERGY_SWEEPS: usize = 200;

/// Sweeps of [`untangle_flat`] at most.
const UNTANGLE_SWEEPS: usize = 64;

/// Moves the first `nfree` nodes of the flat polygons `faces` (local node indices into
/// `uv`), as long as one of their faces does not turn counterclockwise, to the centre of
/// the kernel of their star (the point farthest inside every half-plane left of the edges
/// opposite the node), in Gauss-Seidel sweeps. Returns whether every face turns
/// counterclockwise in the end.
fn untangle_flat(uv: &mut [DVec2], nfree: usize, faces: &[Vec<u32>]) -> bool {
    let mut star: Vec<Vec<u32>> = vec![Vec::new(); nfree];
    for (f, fv) in faces.iter().enumerate() {
        for &v in fv {
            if (v as usize) < nfree {
                star[v as usize].push(f as u32);
            }
        }
    }
    let ccw = |uv: &[DVec2], f: usize| turns_ccw(uv, &faces[f]);
    for _ in 0..UNTANGLE_SWEEPS {
        let mut bad = false;
        let mut moved = false;
        for v in 0..nfree {
            if star[v].iter().all(|&f| ccw(uv, f as usize)) {
                continue;
            }
            bad = true;
            let mut cons: Vec<(DVec2, f64)> = Vec::with_capacity(16);
            let mut radius = 0.0f64;
            for &f in &star[v] {
                let fv = &faces[f as usize];
                let m = fv.len();
                let Some(k) = fv.iter().position(|&w| w as usize == v) else {
                    continue;
                };
                for i in 1..m - 1 {
                    let a = uv[fv[(k + i) % m] as usize];
                    let b = uv[fv[(k + i + 1) % m] as usize];
                    let d = b - a;
                    let l = d.length();
                    if l > 0.0 {
                        let u = d.perp() / l;
                        cons.push((u, u.dot(a)));
                    }
                    radius = radius.max(a.distance(uv[v]));
                }
            }
            if let Some((x, r)) = chebyshev_centre(&mut cons, uv[v], radius) {
                if r > 0.0 {
                    uv[v] = x;
                    moved = true;
                }
            }
        }
        if !bad {
            return true;
        }
        if !moved {
            return false;
        }
    }
    (0..faces.len()).all(|f| ccw(uv, f))
}

/// The point `x` maximizing `r` subject to `u·x − r ≥ c` for the constraints `cons` (unit
/// `u`) and a box `2 radius` around `centre` (appended to `cons`), by enumerating the
/// vertices of the linear program in `(x, y, r)` (a few constraints): the Chebyshev centre
/// of the kernel of a star (`r < 0`: the kernel is empty, `x` violates the constraints
/// least). `None` for fewer than two constraints or a zero radius.
pub(super) fn chebyshev_centre(
    cons: &mut Vec<(DVec2, f64)>,
    centre: DVec2,
    radius: f64,
) -> Option<(DVec2, f64)> {
    if cons.len() < 2 || radius <= 0.0 {
        return None;
    }
    let big = 2.0 * radius;
    for u in [DVec2::X, -DVec2::X, DVec2::Y, -DVec2::Y] {
        cons.push((u, u.dot(centre) - big));
    }
    let det3 = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let n = cons.len();
    let tol = 1e-12 * radius;
    let mut best: Option<(DVec2, f64)> = None;
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                let rows = [cons[i], cons[j], cons[k]];
                let a = rows.map(|(u, _)| [u.x, u.y, -1.0]);
                let det = det3(a);
                if det.abs() < 1e-12 {
                    continue;
                }
                let c = rows.map(|(_, c)| c);
                let col = |j: usize| {
                    let mut m = a;
                    for r in 0..3 {
                        m[r][j] = c[r];
                    }
                    det3(m) / det
                };
                let (x, r) = (DVec2::new(col(0), col(1)), col(2));
                if best.is_some_and(|b| r <= b.1) {
                    continue;
                }
                if cons.iter().all(|(u, c)| u.dot(x) - r >= c - tol) {
                    best = Some((x, r));
                }
            }
        }
    }
    best
}

/// Barycentric coordinates of `q` (in the plane of `abc`) in triangle `abc`; `None` for a
/// degenerate triangle.
fn barycentric3(q: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<[f64; 3]> {
    let (e0, e1, d) = (b - a, c - a, q - a);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (d.dot(e0), d.dot(e1));
    let den = d00 * d11 - d01 * d01;
    if den <= 0.0 || !den.is_finite() {
        return None;
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    Some([1.0 - v - w, v, w])
}

/// Tutte's barycentric embedding: every node `i` with `known[i] == None` at the mean of its
/// neighbours `adj[start[i]..start[i + 1]]`, the others where `known` puts them (uniform
/// Laplace system, conjugate gradients per coordinate). `None` if a group of unknown
/// nodes touches no known node (the system is singular) or the solve does not converge.
fn tutte(start: &[u32], adj: &[u32], known: &[Option<DVec2>]) -> Option<Vec<DVec2>> {
    let n = known.len();
    let mut unknown = vec![u32::MAX; n];
    let mut order: Vec<u32> = Vec::new();
    for i in 0..n {
        if known[i].is_none() {
            unknown[i] = order.len() as u32;
            order.push(i as u32);
        }
    }
    let m = order.len();
    let mut out: Vec<DVec2> = known.iter().map(|k| k.unwrap_or(DVec2::ZERO)).collect();
    if m == 0 {
        return Some(out);
    }
    // Every unknown node must reach a known one.
    let mut reached = vec![false; n];
    let mut stack: Vec<u32> = Vec::new();
    for i in 0..n {
        if known[i].is_some() {
            continue;
        }
        if adj[start[i] as usize..start[i + 1] as usize]
            .iter()
            .any(|&j| known[j as usize].is_some())
        {
            reached[i] = true;
            stack.push(i as u32);
        }
    }
    while let Some(i) = stack.pop() {
        for &j in &adj[start[i as usize] as usize..start[i as usize + 1] as usize] {
            if known[j as usize].is_none() && !reached[j as usize] {
                reached[j as usize] = true;
                stack.push(j);
            }
        }
    }
    if order.iter().any(|&i| !reached[i as usize]) {
        return None;
    }
    let apply = |x: &[f64], y: &mut [f64]| {
        for (r, &i) in order.iter().enumerate() {
            let nb = &adj[start[i as usize] as usize..start[i as usize + 1] as usize];
            let mut s = nb.len() as f64 * x[r];
            for &j in nb {
                let u = unknown[j as usize];
                if u != u32::MAX {
                    s -= x[u as usize];
                }
            }
            y[r] = s;
        }
    };
    for axis in 0..2 {
        let b: Vec<f64> = order
            .iter()
            .map(|&i| {
                adj[start[i as usize] as usize..start[i as usize + 1] as usize]
                    .iter()
                    .filter_map(|&j| known[j as usize].map(|p| p[axis]))
                    .sum()
            })
            .collect();
        let x = conjugate_gradient(&apply, &b)?;
        for (r, &i) in order.iter().enumerate() {
            out[i as usize][axis] = x[r];
        }
    }
    Some(out)
}

/// Solves `A x = b` for a symmetric positive definite `A` given as `apply(x, A x)`; `None`
/// if [`CG_ITERATIONS`] do not reduce the residual below `1e-10 ‖b‖` (they stop at
/// `1e-13 ‖b‖`).
fn conjugate_gradient(apply: &impl Fn(&[f64], &mut [f64]), b: &[f64]) -> Option<Vec<f64>> {
    let m = b.len();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut x = vec![0.0; m];
    let mut r = b.to_vec();
    let mut p = r.clone();
    let mut ap = vec![0.0; m];
    let mut rr = dot(&r, &r);
    let tol = 1e-26 * rr.max(f64::MIN_POSITIVE);
    for _ in 0..CG_ITERATIONS {
        if rr <= tol {
            return Some(x);
        }
        apply(&p, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() {
            return None;
        }
        let alpha = rr / pap;
        for i in 0..m {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        let rr_new = dot(&r, &r);
        let beta = rr_new / rr;
        rr = rr_new;
        for i in 0..m {
            p[i] = r[i] + beta * p[i];
        }
    }
    // Not converged to 1e-13: accept 1e-10 (a flat embedding needs no more).
    (rr <= 1e6 * tol).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tutte_puts_a_free_node_at_its_neighbours_mean() {
        // A square of known corners around one free centre.
        let known = vec![
            None,
            Some(DVec2::new(0.0, 0.0)),
            Some(DVec2::new(2.0, 0.0)),
            Some(DVec2::new(2.0, 2.0)),
            Some(DVec2::new(0.0, 2.0)),
        ];
        let start = vec![0, 4, 4, 4, 4, 4];
        let adj = vec![1, 2, 3, 4];
        let uv = tutte(&start, &adj, &known).unwrap();
        assert!((uv[0] - DVec2::new(1.0, 1.0)).length() < 1e-12);
        // An unknown node with no path to a known one is refused.
        let known = vec![None, None];
        let start = vec![0, 1, 2];
        let adj = vec![1, 0];
        assert!(tutte(&start, &adj, &known).is_none());
    }

    #[test]
    fn a_folded_grid_disc_is_unfolded_on_a_bent_surface() {
        // Input: a strip bent by 90° (an L-shaped cross-section), finely triangulated.
        let n = 12;
        let mut pos = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let s = i as f64 / n as f64 * 2.0;
                let y = j as f64 / n as f64;
                // x along the floor until s = 1, then up the wall.
                let p = if s <= 1.0 {
                    DVec3::new(s, y, 0.0)
                } else {
                    DVec3::new(1.0, y, s - 1.0)
                };
                pos.push(p);
            }
        }
        let mut tris = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let a = (j * (n + 1) + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32 + 2, a + n as u32 + 1);
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
        let proj = Projector::new(&pos, &tris).unwrap();
        // The remesh: the same grid, coarser, with one interior vertex dragged across its
        // neighbours (a fold), lying on the input.
        let m = 4;
        let mut rpos = Vec::new();
        for j in 0..=m {
            for i in 0..=m {
                rpos.push(pos[(j * 3) * (n + 1) + i * 3]);
            }
        }
        let mut faces = Vec::new();
        for j in 0..m {
            for i in 0..m {
                let a = (j * (m + 1) + i) as u32;
                let (b, c, d) = (a + 1, a + m as u32 + 2, a + m as u32 + 1);
                faces.push([a, b, c]);
                faces.push([a, c, d]);
            }
        }
        let centre = 2 * (m + 1) + 2;
        rpos[centre] = pos[(2 * 3) * (n + 1) + 3 * 3 + 2]; // past its right neighbour
        let mesh = crate::Mesh::from_triangles(rpos.clone(), &faces);
        let topo = Topology::build(&mesh);
        let hints: Vec<u32> = rpos.iter().map(|&p| proj.closest(p).1).collect();
        let area = |p: &[DVec3], f: &[u32]| {
            let [a, b, c] = [0, 1, 2].map(|k| p[f[k] as usize]);
            (b - a).cross(c - a)
        };
        let disc: Vec<u32> = topo.vertex_faces(centre).to_vec();
        let n_at = |p: DVec3| proj.normals[proj.closest(p).1 as usize];
        let folded = disc
            .iter()
            .filter(|&&f| {
                let fv = topo.face_vertices(f as usize);
                let c = fv.iter().map(|&v| rpos[v as usize]).sum::<DVec3>() / 3.0;
                area(&rpos, fv).dot(n_at(c)) <= 0.0
            })
            .count();
        assert!(folded > 0, "the test fold must fold");
        let all: Vec<u32> = (0..rpos.len() as u32).collect();
        let patch = Patch::under(&rpos, &hints, &all, &proj).unwrap();
        let moved = flat_reembed(
            &patch,
            &rpos,
            &hints,
            &topo,
            &[centre as u32],
            &[],
            &disc,
            &proj,
        )
        .unwrap();
        rpos[centre] = moved[0].0;
        for &f in &disc {
            let fv = topo.face_vertices(f as usize);
            let c = fv.iter().map(|&v| rpos[v as usize]).sum::<DVec3>() / 3.0;
            assert!(area(&rpos, fv).dot(n_at(c)) > 0.0, "face {f} still folded");
            // On the input.
            assert!(proj.closest(moved[0].0).0.distance(moved[0].0) < 1e-12);
        }
    }

    /// A disc of the bunny's 6-level remesh (node coordinates in the flattening of the
    /// input under it, as [`flat_reembed`] met it, the Tutte embedding of its two free
    /// nodes 0 and 1): Tutte's embedding folds next to a reflex corner of the disc's
    /// boundary, moving one node at a time into its star's kernel gets stuck, and the
    /// simultaneous untangling ([`untangle_energy`]) opens it without moving the boundary.
    #[test]
    fn a_disc_the_kernel_moves_leave_folded_is_untangled() {
        let faces: Vec<Vec<u32>> = [
            [3, 2, 5],
            [6, 7, 2],
            [2, 7, 5],
            [3, 0, 4],
            [8, 1, 0],
            [9, 4, 1],
            [0, 1, 4],
            [8, 10, 1],
            [9, 1, 11],
            [10, 11, 1],
            [3, 5, 0],
            [8, 0, 12],
            [5, 12, 0],
        ]
        .iter()
        .map(|f: &[u32; 3]| f.to_vec())
        .collect();
        let tutte_uv: Vec<DVec2> = [
            (0.35359006652626035, -0.8553519372101298),
            (0.3505711951485235, -0.8877064798968564),
            (0.4216125611891625, -0.9055020606808092),
            (0.3960210640008774, -0.9176036644522261),
            (0.36965391529447345, -0.9281609419793025),
            (0.3743221699170275, -0.8388646848641454),
            (0.4460885199719704, -0.8911794140880924),
            (0.37657682872719955, -0.8063041813909304),
            (0.3307466898801583, -0.8107583280501613),
            (0.34328676658806884, -0.9387182195063787),
            (0.37093021681526, -0.8832629951844331),
            (0.33521951578692005, -0.9099864574507321),
            (0.3002253649165021, -0.749017524018087),
        ]
        .iter()
        .map(|&(x, y)| DVec2::new(x, y))
        .collect();
        let folded = |uv: &[DVec2]| faces.iter().filter(|f| !turns_ccw(uv, f)).count();
        assert!(folded(&tutte_uv) > 0, "Tutte's embedding must fold here");
        let mut uv = tutte_uv.clone();
        assert!(
            !untangle_flat(&mut uv, 2, &faces),
            "the kernel moves must get stuck"
        );
        let mut uv = tutte_uv.clone();
        assert!(untangle_energy::untangle(&mut uv, 2, &faces, ENERGY_SWEEPS));
        assert_eq!(folded(&uv), 0);
        assert_eq!(&uv[2..], &tutte_uv[2..], "the disc's boundary stays");
    }
}

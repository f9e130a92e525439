//! Topology-preserving simplification to a base domain, with the MAPS parameterization of every
//! removed vertex tracked over the simplified triangles.
//!
//! - **Error metric**: Garland & Heckbert's quadric error metric (QEM, SIGGRAPH 1997, §5:
//!   area-weighted plane quadrics, and constraint planes perpendicular to boundary and feature
//!   edges), on *half-edge* collapses `u → v`, so that base vertices are input vertices. A
//!   length term `β·A_u·|u−v|²` (A_u: quadric area of `u`) favours short edges on flat
//!   regions, giving the evenly sized base triangles MAPS asks for (Lee et al. 1998, §3.2
//!   "priority by area and curvature").
//! - **Topology is preserved**: the link condition (Dey et al. 1999, as MAPS §3.1 requires of
//!   its vertex removals), boundary vertices move only along boundary edges, feature ("crease")
//!   vertices only along their feature chain, corners (feature valence ≠ 0, 2) never; no
//!   collapse folds a face (normals must stay within 78°); no closed component goes below four
//!   faces; each component keeps its share of the face budget (area-proportional), so
//!   components are simplified independently.
//! - **Parameterization** (MAPS §3.3, "tracking the parameterization"): every removed input
//!   vertex keeps a position `(face, barycentric)` over the current mesh. When a collapse
//!   changes the star of `u`, the points that lived in that star (and `u` itself) are
//!   located in the new star's triangles in the plane the old star is flattened into (MAPS
//!   §3.2 flattens with the conformal `z^a`; here a polar map that keeps the radii, which
//!   does not squeeze the neighbourhood of sharp tips, see `State::flatten`). A collapse
//!   whose new star folds in that plane is not made (MAPS §3.2 rejects such retriangulations
//!   too), so every point of the star lands in one new triangle: the re-attachment is one to
//!   one and the tracked parameterization stays an embedding. Chain points (boundary and
//!   feature vertices) stay on chain edges: they go to the closest point of the new star's
//!   chain edges *in that plane* (where a boundary is straight through `u`), so they keep
//!   their order along the chain and their place beside the points around them (the
//!   closest point in space, used before, sheared the two against each other and folded
//!   the parameterization along every boundary). Flattening each side of a feature curve
//!   into a half disc, to make it straight as well, was tried: it distorts uneven sides and
//!   doubled fandisk's Hausdorff distance at 3 levels. Only points outside every new
//!   triangle by rounding are re-attached to the closest point of the new star's triangles
//!   in space (the projection variant, as in Guskov et al.'s normal meshes, 2000).

#![allow(clippy::needless_range_loop)] // parallel arrays indexed by vertex and face

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;

use crate::topology::UnionFind;

/// A multiplicative hasher for the integer-pair keys of the edge sets (FxHash's mixing).
#[derive(Default, Clone, Copy)]
pub struct PairHasher(u64);

impl Hasher for PairHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u32(&mut self, x: u32) {
        self.write_u64(x as u64);
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// A hash set of vertex pairs with [`PairHasher`].
pub type PairSet = std::collections::HashSet<(u32, u32), BuildHasherDefault<PairHasher>>;

/// A point of the parameter domain: a triangle of the base mesh and barycentric
/// coordinates in it (summing to 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Param {
    /// Base triangle.
    pub face: u32,
    /// Barycentric coordinates with respect to its corners, in corner order.
    pub bary: [f64; 3],
}

impl Param {
    /// The base edge of triangle `tri` (this parameter's base triangle) that the point lies
    /// on, if `is_edge` accepts it (as a sorted vertex pair), with the point's position
    /// along it from its smaller vertex to its larger (0 to 1). `None` for a base vertex or
    /// a point on no accepted edge.
    pub fn on_edge(
        &self,
        tri: [u32; 3],
        is_edge: impl Fn((u32, u32)) -> bool,
    ) -> Option<((u32, u32), f64)> {
        if self.bary.contains(&1.0) {
            return None;
        }
        (0..3).find_map(|k| {
            let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let key = (a.min(b), a.max(b));
            (self.bary[k] == 0.0 && is_edge(key)).then(|| {
                let sa = self.bary[(k + 1) % 3];
                (key, if a < b { 1.0 - sa } else { sa })
            })
        })
    }

    /// Whether the point is a base vertex or lies on one of the `chains` base edges (of its
    /// base triangle `tri`): the points the remesher keeps on the input's curves.
    pub fn is_pinned(&self, tri: [u32; 3], chains: &PairSet) -> bool {
        self.bary.contains(&1.0) || self.on_edge(tri, |e| chains.contains(&e)).is_some()
    }
}

/// The result of [`simplify`].
#[derive(Clone, Debug)]
pub struct Simplified {
    /// Base vertex positions (input vertices kept).
    pub positions: Vec<DVec3>,
    /// Base triangles.
    pub triangles: Vec<[u32; 3]>,
    /// For each base vertex, its input vertex.
    pub input_vertex: Vec<u32>,
    /// The parameter of each input vertex.
    pub params: Vec<Param>,
    /// Base edges (vertex pairs, sorted) that are boundary or feature edges.
    pub chain_edges: PairSet,
}

#[derive(Clone, Copy, Default)]
struct Quadric {
    // Symmetric 4x4: a2 ab ac ad b2 bc bd c2 cd d2, and the area weight.
    q: [f64; 10],
    area: f64,
}

impl Quadric {
    fn plane(n: DVec3, d: f64, w: f64) -> Quadric {
        let (a, b, c) = (n.x, n.y, n.z);
        Quadric {
            q: [
                w * a * a,
                w * a * b,
                w * a * c,
                w * a * d,
                w * b * b,
                w * b * c,
                w * b * d,
                w * c * c,
                w * c * d,
                w * d * d,
            ],
            area: 0.0,
        }
    }
    fn add(&mut self, o: &Quadric) {
        for i in 0..10 {
            self.q[i] += o.q[i];
        }
        self.area += o.area;
    }
    fn eval(&self, p: DVec3) -> f64 {
        let q = &self.q;
        let (x, y, z) = (p.x, p.y, p.z);
        q[0] * x * x
            + 2.0 * q[1] * x * y
            + 2.0 * q[2] * x * z
            + 2.0 * q[3] * x
            + q[4] * y * y
            + 2.0 * q[5] * y * z
            + 2.0 * q[6] * y
            + q[7] * z * z
            + 2.0 * q[8] * z
            + q[9]
    }
}

#[derive(PartialEq)]
struct Entry {
    cost: f64,
    u: u32,
    v: u32,
    stamp: u32,
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        // Min-heap on cost.
        other.cost.total_cmp(&self.cost).then(other.u.cmp(&self.u))
    }
}

fn key(a: u32, b: u32) -> (u32, u32) {
    if a < b {
        (a, b)
    } else {
        (b, a)
    }
}

/// Closest point of triangle `abc` to `p`, as barycentric coordinates (Ericson, Real-Time
/// Collision Detection §5.1.5).
pub fn closest_bary(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = 1.0 / (va + vb + vc);
    if !denom.is_finite() {
        return [1.0 / 3.0; 3];
    }
    let v = vb * denom;
    let w = vc * denom;
    [1.0 - v - w, v, w]
}

/// Barycentric coordinates of `p` in the planar triangle `c` (either orientation).
fn bary_2d(c: [[f64; 2]; 3], p: [f64; 2]) -> [f64; 3] {
    let [a, b, cc] = c;
    let det = (b[0] - a[0]) * (cc[1] - a[1]) - (cc[0] - a[0]) * (b[1] - a[1]);
    if det == 0.0 {
        return [-1.0; 3];
    }
    let l1 = ((p[0] - a[0]) * (cc[1] - a[1]) - (cc[0] - a[0]) * (p[1] - a[1])) / det;
    let l2 = ((b[0] - a[0]) * (p[1] - a[1]) - (p[0] - a[0]) * (b[1] - a[1])) / det;
    [1.0 - l1 - l2, l1, l2]
}

/// Closest point of segment `ab` to `p` as the parameter `t` (`a + t (b − a)`).
fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let d = b - a;
    let l2 = d.length_squared();
    if l2 <= 0.0 {
        0.0
    } else {
        ((p - a).dot(d) / l2).clamp(0.0, 1.0)
    }
}

struct State<'a> {
    pos: &'a [DVec3],
    faces: Vec<[u32; 3]>,
    face_alive: Vec<bool>,
    vfaces: Vec<Vec<u32>>,
    alive: Vec<bool>,
    quadric: Vec<Quadric>,
    chain: PairSet,
    chain_deg: Vec<u8>,
    comp: Vec<u32>,
    comp_faces: Vec<usize>,
    comp_target: Vec<usize>,
    comp_closed: Vec<bool>,
    stamp: Vec<u32>,
    // Parameterization tracking.
    face_points: Vec<Vec<u32>>,
    params: Vec<Param>,
    chain_point: Vec<bool>,
    pinned: Vec<bool>,
    beta: f64,
    /// Points re-attached by closest point in space rather than in the flattened star.
    projected: usize,
}

/// Twice the smallest area a re-attachment triangle may have in the flattened star (whose
/// radius is 1).
const PLANAR_MIN_DET: f64 = 1e-9;

fn normal(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    (b - a).cross(c - a)
}

impl State<'_> {
    fn neighbors(&self, u: u32, out: &mut Vec<u32>) {
        out.clear();
        for &f in &self.vfaces[u as usize] {
            for &w in &self.faces[f as usize] {
                if w != u && !out.contains(&w) {
                    out.push(w);
                }
            }
        }
    }

    fn recount_chain(&mut self, u: u32) {
        // Chain edges only ever join chain points (a collapse moves a chain edge only along
        // a chain edge, into a chain point).
        if !self.chain_point[u as usize] {
            self.chain_deg[u as usize] = 0;
            return;
        }
        let mut n = Vec::new();
        self.neighbors(u, &mut n);
        self.chain_deg[u as usize] = n
            .iter()
            .filter(|&&w| self.chain.contains(&key(u, w)))
            .count()
            .min(255) as u8;
    }

    /// Whether collapsing `u` into `v` keeps topology, chains and orientation.
    fn valid(&self, u: u32, v: u32, nu: &[u32], scratch: &mut Vec<u32>) -> bool {
        let (ui, vi) = (u as usize, v as usize);
        if !self.alive[ui] || !self.alive[vi] || self.pinned[ui] {
            return false;
        }
        let on_chain = self.chain.contains(&key(u, v));
        match self.chain_deg[ui] {
            0 => {}
            2 => {
                if !on_chain {
                    return false;
                }
                // The chain must not shrink below three edges (a triangle loop).
                let other = nu
                    .iter()
                    .copied()
                    .find(|&w| w != v && self.chain.contains(&key(u, w)));
                if let Some(w) = other {
                    if self.chain.contains(&key(v, w)) {
                        return false;
                    }
                }
            }
            _ => return false,
        }
        // Faces on the edge uv and their opposite vertices.
        let mut shared = 0usize;
        let mut opposite = [u32::MAX; 2];
        for &f in &self.vfaces[ui] {
            let t = &self.faces[f as usize];
            if t.contains(&v) {
                if shared < 2 {
                    opposite[shared] = t.iter().copied().find(|&w| w != u && w != v).unwrap();
                }
                shared += 1;
            }
        }
        // u must keep a face (its points are re-attached there).
        if shared == 0 || shared > 2 || self.vfaces[ui].len() <= shared {
            return false;
        }
        // Boundary vertices that are joined by an interior edge would pinch: they are both
        // chain vertices then, caught above unless `u` is not on a chain; check boundary of v.
        // Link condition: common neighbours are exactly the opposite vertices.
        self.neighbors(v, scratch);
        let mut common = 0usize;
        for &w in nu {
            if w != v && scratch.contains(&w) {
                if !opposite[..shared].contains(&w) {
                    return false;
                }
                common += 1;
            }
        }
        if common != shared {
            return false;
        }
        // Closed components keep at least four faces; every component its budget.
        let c = self.comp[ui] as usize;
        let after = self.comp_faces[c].saturating_sub(shared);
        if after < self.comp_target[c] || (self.comp_closed[c] && after < 4) || after < 1 {
            return false;
        }
        // No new face may duplicate an existing one (a "pillow" of two faces on the same
        // three vertices).
        for &f in &self.vfaces[ui] {
            let t = self.faces[f as usize];
            if t.contains(&v) {
                continue;
            }
            let others: Vec<u32> = t.iter().copied().filter(|&w| w != u).collect();
            if self.vfaces[vi].iter().any(|&g| {
                let tg = &self.faces[g as usize];
                tg.contains(&others[0]) && tg.contains(&others[1])
            }) {
                return false;
            }
        }
        // No face flips or degenerates.
        let pv = self.pos[vi];
        for &f in &self.vfaces[ui] {
            let t = self.faces[f as usize];
            if t.contains(&v) {
                continue;
            }
            let [a, b, cc] = t.map(|w| self.pos[w as usize]);
            let n0 = normal(a, b, cc);
            let r = t.map(|w| if w == u { pv } else { self.pos[w as usize] });
            let n1 = normal(r[0], r[1], r[2]);
            let (l0, l1) = (n0.length(), n1.length());
            if l1 <= 1e-300 || n0.dot(n1) < 0.2 * l0 * l1 {
                return false;
            }
        }
        // The new fan around `v` must not fold in the plane the old star is flattened
        // into, or the points of the star cannot be re-attached one to one (MAPS §3.2).
        self.planar_fan_ok(u, v)
    }

    /// Whether the triangles around `v` after collapsing `u` into it keep their orientation
    /// in the flattening of `u`'s star ([`State::flatten`]).
    fn planar_fan_ok(&self, u: u32, v: u32) -> bool {
        let faces = &self.vfaces[u as usize];
        let Some(flat) = self.flatten(u, faces) else {
            return false;
        };
        let at = |w: u32| flat.iter().find(|x| x.0 == w).map(|x| x.1);
        let Some(pv) = at(v) else { return false };
        for &f in faces {
            let t = self.faces[f as usize];
            if t.contains(&v) {
                continue;
            }
            let mut c = [[0.0; 2]; 3];
            for k in 0..3 {
                c[k] = if t[k] == u {
                    pv
                } else {
                    match at(t[k]) {
                        Some(x) => x,
                        None => return false,
                    }
                };
            }
            let det = (c[1][0] - c[0][0]) * (c[2][1] - c[0][1])
                - (c[2][0] - c[0][0]) * (c[1][1] - c[0][1]);
            if det <= PLANAR_MIN_DET {
                return false;
            }
        }
        true
    }

    fn cost(&self, u: u32, v: u32) -> f64 {
        let mut q = self.quadric[u as usize];
        q.add(&self.quadric[v as usize]);
        let pv = self.pos[v as usize];
        let d2 = (self.pos[u as usize] - pv).length_squared();
        q.eval(pv).max(0.0) + self.beta * self.quadric[u as usize].area * d2
    }

    /// The best valid collapse out of `u`, if any.
    fn best(&self, u: u32, nu: &mut Vec<u32>, scratch: &mut Vec<u32>) -> Option<(f64, u32)> {
        self.neighbors(u, nu);
        let mut best: Option<(f64, u32)> = None;
        for i in 0..nu.len() {
            let v = nu[i];
            if !self.valid(u, v, nu, scratch) {
                continue;
            }
            let c = self.cost(u, v);
            if best.is_none_or(|(bc, _)| c < bc) {
                best = Some((c, v));
            }
        }
        best
    }

    /// The cheapest collapse out of `u` among those the chain rules allow, without the
    /// (costlier) topological and geometric checks, which run when it leaves the queue.
    fn best_unchecked(&self, u: u32, nu: &mut Vec<u32>) -> Option<(f64, u32)> {
        let ui = u as usize;
        if !self.alive[ui] || self.pinned[ui] || self.chain_deg[ui] > 2 || self.chain_deg[ui] == 1 {
            return None;
        }
        self.neighbors(u, nu);
        let mut best: Option<(f64, u32)> = None;
        for &v in nu.iter() {
            if self.chain_deg[ui] == 2 && !self.chain.contains(&key(u, v)) {
                continue;
            }
            let c = self.cost(u, v);
            if best.is_none_or(|(bc, _)| c < bc) {
                best = Some((c, v));
            }
        }
        best
    }

    /// Re-attaches point `p` (an input vertex) to the closest of `faces`.
    fn attach(&mut self, p: u32, faces: &[u32]) {
        let x = self.pos[p as usize];
        let mut best = (
            f64::INFINITY,
            Param {
                face: u32::MAX,
                bary: [1.0 / 3.0; 3],
            },
        );
        if self.chain_point[p as usize] {
            for &f in faces {
                let t = self.faces[f as usize];
                for i in 0..3 {
                    let (a, b) = (t[i], t[(i + 1) % 3]);
                    if !self.chain.contains(&key(a, b)) {
                        continue;
                    }
                    let (pa, pb) = (self.pos[a as usize], self.pos[b as usize]);
                    let s = closest_on_segment(x, pa, pb);
                    let d = (pa + s * (pb - pa)).distance_squared(x);
                    if d < best.0 {
                        let mut bary = [0.0; 3];
                        bary[i] = 1.0 - s;
                        bary[(i + 1) % 3] = s;
                        best = (d, Param { face: f, bary });
                    }
                }
            }
        }
        if best.1.face == u32::MAX {
            for &f in faces {
                let t = self.faces[f as usize];
                let [a, b, c] = t.map(|w| self.pos[w as usize]);
                let bary = closest_bary(x, a, b, c);
                let q = a * bary[0] + b * bary[1] + c * bary[2];
                let d = q.distance_squared(x);
                if d < best.0 {
                    best = (d, Param { face: f, bary });
                }
            }
        }
        self.params[p as usize] = best.1;
        if best.1.face != u32::MAX {
            self.face_points[best.1.face as usize].push(p);
        }
    }

    /// The star of `u` flattened as in MAPS §3.2: `u` at the origin, each ring vertex at
    /// angle (cumulative 3D angle) · `2π / Θ` (`π / Θ` on a boundary) and radius `r / r_max`.
    /// MAPS's conformal map `z^(2π / Θ)` raises the radius to that power too; at a cone
    /// vertex with a small angle sum (the tip of an ear, `Θ ≈ π`) that squeezes the points
    /// near it towards it, and the collapses compound the squeeze, so the tips got a few
    /// long resampled triangles cutting them off (the bunny's ear tips held 70% of the
    /// squared distance at 6 levels). The polar map with the radius kept bounds the area
    /// distortion by the angle factor alone. `None` if the ring is not one fan.
    fn flatten(&self, u: u32, faces: &[u32]) -> Option<Vec<(u32, [f64; 2])>> {
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(faces.len());
        for &f in faces {
            let t = self.faces[f as usize];
            let k = t.iter().position(|&w| w == u)?;
            pairs.push((t[(k + 1) % 3], t[(k + 2) % 3]));
        }
        let start = pairs
            .iter()
            .find(|(a, _)| !pairs.iter().any(|(_, b)| b == a))
            .map(|p| p.0);
        let boundary = start.is_some();
        let mut ring = vec![start.unwrap_or(pairs[0].0)];
        loop {
            let cur = *ring.last().unwrap();
            let Some(&(_, b)) = pairs.iter().find(|(a, _)| *a == cur) else {
                break;
            };
            if b == ring[0] {
                break;
            }
            ring.push(b);
            if ring.len() > pairs.len() + 1 {
                return None;
            }
        }
        let expected = if boundary {
            pairs.len() + 1
        } else {
            pairs.len()
        };
        if ring.len() != expected {
            return None;
        }
        let pu = self.pos[u as usize];
        let d: Vec<DVec3> = ring.iter().map(|&w| self.pos[w as usize] - pu).collect();
        let n = ring.len();
        let steps = if boundary { n - 1 } else { n };
        let angles: Vec<f64> = (0..steps)
            .map(|i| d[i].angle_between(d[(i + 1) % n]))
            .collect();
        let total: f64 = angles.iter().sum();
        if total.partial_cmp(&0.0) != Some(Ordering::Greater) {
            return None;
        }
        let a = if boundary {
            std::f64::consts::PI
        } else {
            2.0 * std::f64::consts::PI
        } / total;
        let rmax = d.iter().map(|x| x.length()).fold(0.0, f64::max);
        if rmax <= 0.0 {
            return None;
        }
        let mut out = Vec::with_capacity(n);
        let mut phi = 0.0f64;
        for i in 0..n {
            let r = d[i].length() / rmax;
            out.push((ring[i], [r * phi.cos(), r * phi.sin()]));
            if i < steps {
                phi += a * angles[i];
            }
        }
        Some(out)
    }

    fn collapse(&mut self, u: u32, v: u32) {
        let (ui, vi) = (u as usize, v as usize);
        let mut nu = Vec::new();
        self.neighbors(u, &mut nu);
        // The flattening of u's star (before its chain edges move to v).
        let flat = self.flatten(u, &self.vfaces[ui]);
        // Chain bookkeeping: u's chain edges move to v.
        for &w in &nu {
            if w != v && self.chain.remove(&key(u, w)) {
                self.chain.insert(key(v, w));
            }
        }
        self.chain.remove(&key(u, v));
        // Points to re-attach.
        let mut points = vec![u];
        let old_faces = std::mem::take(&mut self.vfaces[ui]);
        // Old parameters of the points, as planar positions in the flattened star, with
        // their index in `points` (u, then the points of the old faces in order).
        let mut planar: Vec<(u32, [f64; 2], usize)> = Vec::new();
        if let Some(flat) = &flat {
            let at = |w: u32| flat.iter().find(|x| x.0 == w).map(|x| x.1);
            planar.push((u, [0.0, 0.0], 0));
            let mut index = 1;
            for &f in &old_faces {
                let t = self.faces[f as usize];
                let c = t.map(|w| at(w).unwrap_or([0.0, 0.0]));
                for &p in &self.face_points[f as usize] {
                    index += 1;
                    let b = self.params[p as usize].bary;
                    planar.push((
                        p,
                        [
                            b[0] * c[0][0] + b[1] * c[1][0] + b[2] * c[2][0],
                            b[0] * c[0][1] + b[1] * c[1][1] + b[2] * c[2][1],
                        ],
                        index - 1,
                    ));
                }
            }
        }
        let mut new_faces = Vec::with_capacity(old_faces.len());
        for &f in &old_faces {
            points.append(&mut self.face_points[f as usize]);
            let t = &mut self.faces[f as usize];
            if t.contains(&v) {
                self.face_alive[f as usize] = false;
                let t = *t;
                for w in t {
                    if w != u {
                        self.vfaces[w as usize].retain(|&g| g != f);
                    }
                }
            } else {
                for w in t.iter_mut() {
                    if *w == u {
                        *w = v;
                    }
                }
                self.vfaces[vi].push(f);
                new_faces.push(f);
            }
        }
        let c = self.comp[ui] as usize;
        self.comp_faces[c] -= old_faces.len() - new_faces.len();
        self.alive[ui] = false;
        let qu = self.quadric[ui];
        self.quadric[vi].add(&qu);
        // Planar re-attachment (MAPS §3.3): locate each point's flattened position in the
        // new fan around v; chain points, and points outside every new planar triangle (or
        // all points, if the new fan folds in the plane), by closest point in space.
        let mut done = vec![false; points.len()];
        if let Some(flat) = &flat {
            let at = |w: u32| {
                flat.iter()
                    .find(|x| x.0 == w)
                    .map(|x| x.1)
                    .unwrap_or([0.0, 0.0])
            };
            let tris: Vec<(u32, [[f64; 2]; 3])> = new_faces
                .iter()
                .map(|&f| (f, self.faces[f as usize].map(at)))
                .collect();
            let folds = tris.iter().any(|(_, c)| {
                (c[1][0] - c[0][0]) * (c[2][1] - c[0][1])
                    - (c[2][0] - c[0][0]) * (c[1][1] - c[0][1])
                    <= 0.0
            });
            if !folds {
                for &(p, xy, i) in &planar {
                    if self.chain_point[p as usize] {
                        // Chain points to the closest chain edge of the new fan in the plane
                        // (the chain is straight there), so they keep their order along it
                        // and their side of the points around them.
                        let mut best = (f64::INFINITY, u32::MAX, [0.0; 3]);
                        for &(f, c) in &tris {
                            let t = self.faces[f as usize];
                            for k in 0..3 {
                                let (a, b) = (t[k], t[(k + 1) % 3]);
                                if !self.chain.contains(&key(a, b)) {
                                    continue;
                                }
                                let (pa, pb) = (c[k], c[(k + 1) % 3]);
                                let d = [pb[0] - pa[0], pb[1] - pa[1]];
                                let l2 = d[0] * d[0] + d[1] * d[1];
                                let s = if l2 > 0.0 {
                                    (((xy[0] - pa[0]) * d[0] + (xy[1] - pa[1]) * d[1]) / l2)
                                        .clamp(0.0, 1.0)
                                } else {
                                    0.0
                                };
                                let q = [pa[0] + s * d[0], pa[1] + s * d[1]];
                                let dist = (q[0] - xy[0]).powi(2) + (q[1] - xy[1]).powi(2);
                                if dist < best.0 {
                                    let mut bary = [0.0; 3];
                                    bary[k] = 1.0 - s;
                                    bary[(k + 1) % 3] = s;
                                    best = (dist, f, bary);
                                }
                            }
                        }
                        if best.1 != u32::MAX {
                            self.params[p as usize] = Param {
                                face: best.1,
                                bary: best.2,
                            };
                            self.face_points[best.1 as usize].push(p);
                            done[i] = true;
                        }
                        continue;
                    }
                    let mut best = (f64::NEG_INFINITY, 0u32, [0.0; 3]);
                    for &(f, c) in &tris {
                        let l = bary_2d(c, xy);
                        let m = l[0].min(l[1]).min(l[2]);
                        if m > best.0 {
                            best = (m, f, l);
                        }
                    }
                    if best.0 >= -1e-9 {
                        let l = best.2.map(|x| x.max(0.0));
                        let sum = l[0] + l[1] + l[2];
                        self.params[p as usize] = Param {
                            face: best.1,
                            bary: l.map(|x| x / sum),
                        };
                        self.face_points[best.1 as usize].push(p);
                        done[i] = true;
                    }
                }
            }
        }
        for (i, p) in points.into_iter().enumerate() {
            if !done[i] {
                if !self.chain_point[p as usize] {
                    self.projected += 1;
                }
                self.attach(p, &new_faces);
            }
        }
        self.recount_chain(v);
        for &w in &nu {
            self.recount_chain(w);
        }
    }
}

/// Simplifies the oriented manifold triangle mesh `(pos, tris)` to about `target` faces
/// (see the module documentation). `chain_edges` are the input's feature edges (sorted
/// vertex pairs); boundary edges are added to them. Chain vertices where the chain turns by
/// more than `corner_angle` degrees are kept. `progress` receives the fraction done.
///
/// Preconditions: `tris` index `pos`, form an oriented 2-manifold without degenerate faces.
pub fn simplify(
    pos: &[DVec3],
    tris: &[[u32; 3]],
    chain_edges: &PairSet,
    target: usize,
    corner_angle: Option<f64>,
    progress: &mut dyn FnMut(f64),
) -> Simplified {
    let nv = pos.len();
    let nf = tris.len();
    // Components, areas, boundary edges.
    let mut uf = UnionFind::new(nv);
    for t in tris {
        uf.union(t[0], t[1]);
        uf.union(t[1], t[2]);
    }
    let mut comp_of_root = vec![u32::MAX; nv];
    let mut comp = vec![0u32; nv];
    let mut ncomp = 0usize;
    for v in 0..nv {
        let r = uf.find(v as u32) as usize;
        if comp_of_root[r] == u32::MAX {
            comp_of_root[r] = ncomp as u32;
            ncomp += 1;
        }
        comp[v] = comp_of_root[r];
    }
    let mut comp_faces = vec![0usize; ncomp];
    let mut comp_area = vec![0.0f64; ncomp];
    let mut edge_count: std::collections::HashMap<(u32, u32), u32, BuildHasherDefault<PairHasher>> =
        Default::default();
    let mut quadric = vec![Quadric::default(); nv];
    let mut vfaces: Vec<Vec<u32>> = vec![Vec::new(); nv];
    let mut total_area = 0.0;
    for (f, t) in tris.iter().enumerate() {
        let [a, b, c] = t.map(|i| pos[i as usize]);
        let n = normal(a, b, c);
        let area = 0.5 * n.length();
        let c0 = comp[t[0] as usize] as usize;
        comp_faces[c0] += 1;
        comp_area[c0] += area;
        total_area += area;
        let nn = n.normalize_or_zero();
        let mut q = Quadric::plane(nn, -nn.dot(a), area);
        q.area = area / 3.0;
        for &i in t {
            quadric[i as usize].add(&q);
            vfaces[i as usize].push(f as u32);
        }
        for i in 0..3 {
            *edge_count.entry(key(t[i], t[(i + 1) % 3])).or_default() += 1;
        }
    }
    let mut chain: PairSet = chain_edges.clone();
    let mut comp_closed = vec![true; ncomp];
    for (&k, &n) in &edge_count {
        if n == 1 {
            chain.insert(k);
            comp_closed[comp[k.0 as usize] as usize] = false;
        }
    }
    // Constraint planes along chain edges (perpendicular to each adjacent face).
    for (f, t) in tris.iter().enumerate() {
        let _ = f;
        let [a, b, c] = t.map(|i| pos[i as usize]);
        let n = normal(a, b, c).normalize_or_zero();
        for i in 0..3 {
            let (i0, i1) = (t[i], t[(i + 1) % 3]);
            if !chain.contains(&key(i0, i1)) {
                continue;
            }
            let (p0, p1) = (pos[i0 as usize], pos[i1 as usize]);
            let e = p1 - p0;
            let m = e.cross(n).normalize_or_zero();
            let q = Quadric::plane(m, -m.dot(p0), 10.0 * e.length_squared());
            quadric[i0 as usize].add(&q);
            quadric[i1 as usize].add(&q);
        }
    }
    let comp_target: Vec<usize> = (0..ncomp)
        .map(|c| {
            let share = if total_area > 0.0 {
                comp_area[c] / total_area
            } else {
                comp_faces[c] as f64 / nf.max(1) as f64
            };
            ((target as f64 * share).round() as usize).max(if comp_closed[c] { 4 } else { 1 })
        })
        .collect();
    let mut chain_point = vec![false; nv];
    for &(a, b) in &chain {
        chain_point[a as usize] = true;
        chain_point[b as usize] = true;
    }
    let mut st = State {
        pos,
        faces: tris.to_vec(),
        face_alive: vec![true; nf],
        vfaces,
        alive: vec![true; nv],
        quadric,
        chain,
        chain_deg: vec![0; nv],
        comp,
        comp_faces,
        comp_target,
        comp_closed,
        stamp: vec![0; nv],
        face_points: vec![Vec::new(); nf],
        params: vec![
            Param {
                face: u32::MAX,
                bary: [1.0, 0.0, 0.0]
            };
            nv
        ],
        chain_point,
        pinned: vec![false; nv],
        beta: 0.05,
        projected: 0,
    };
    for v in 0..nv as u32 {
        st.recount_chain(v);
    }
    // Chain vertices where the chain turns by more than `corner_angle` are corners (never
    // removed).
    for v in 0..nv as u32 {
        let Some(corner_angle) = corner_angle else {
            break;
        };
        if st.chain_deg[v as usize] != 2 {
            continue;
        }
        let mut n = Vec::new();
        st.neighbors(v, &mut n);
        let ends: Vec<u32> = n
            .into_iter()
            .filter(|&w| st.chain.contains(&key(v, w)))
            .collect();
        let p = pos[v as usize];
        let d0 = (p - pos[ends[0] as usize]).normalize_or_zero();
        let d1 = (pos[ends[1] as usize] - p).normalize_or_zero();
        if d0.dot(d1) < corner_angle.to_radians().cos() {
            st.pinned[v as usize] = true;
        }
    }
    let mut heap = BinaryHeap::with_capacity(nv);
    let (mut nu, mut scratch) = (Vec::new(), Vec::new());
    for u in 0..nv as u32 {
        if let Some((cost, v)) = st.best_unchecked(u, &mut nu) {
            heap.push(Entry {
                cost,
                u,
                v,
                stamp: 0,
            });
        }
    }
    let total_removable = nv.saturating_sub(target / 2 + 2).max(1);
    let mut removed = 0usize;
    let mut touched = Vec::new();
    while let Some(Entry { u, v, stamp, .. }) = heap.pop() {
        let ui = u as usize;
        if !st.alive[ui] || stamp != st.stamp[ui] {
            continue;
        }
        st.neighbors(u, &mut nu);
        if !st.valid(u, v, &nu, &mut scratch) {
            st.stamp[ui] += 1;
            if let Some((cost, v)) = st.best(u, &mut nu, &mut scratch) {
                heap.push(Entry {
                    cost,
                    u,
                    v,
                    stamp: st.stamp[ui],
                });
            }
            continue;
        }
        st.collapse(u, v);
        removed += 1;
        if removed & 1023 == 0 {
            progress((removed as f64 / total_removable as f64).min(1.0));
        }
        // Re-evaluate v and its ring (and the ring's ring, whose link may have changed).
        st.neighbors(v, &mut touched);
        touched.push(v);
        let ring = touched.clone();
        for &w in &ring {
            let wi = w as usize;
            st.stamp[wi] += 1;
            if let Some((cost, t)) = st.best_unchecked(w, &mut nu) {
                heap.push(Entry {
                    cost,
                    u: w,
                    v: t,
                    stamp: st.stamp[wi],
                });
            }
        }
    }
    tracing::debug!(removed, projected = st.projected, "simplification");
    // Compact.
    let mut vmap = vec![u32::MAX; nv];
    let mut positions = Vec::new();
    let mut input_vertex = Vec::new();
    for v in 0..nv {
        if st.alive[v] && !st.vfaces[v].is_empty() {
            vmap[v] = positions.len() as u32;
            positions.push(pos[v]);
            input_vertex.push(v as u32);
        }
    }
    let mut fmap = vec![u32::MAX; nf];
    let mut triangles = Vec::new();
    for f in 0..nf {
        if st.face_alive[f] {
            fmap[f] = triangles.len() as u32;
            triangles.push(st.faces[f].map(|w| vmap[w as usize]));
        }
    }
    let mut params = st.params;
    for (v, p) in params.iter_mut().enumerate() {
        if st.alive[v] {
            // A base vertex: a corner of any face around it.
            let f = st.vfaces[v][0];
            let corner = st.faces[f as usize]
                .iter()
                .position(|&w| w as usize == v)
                .unwrap();
            let mut bary = [0.0; 3];
            bary[corner] = 1.0;
            *p = Param {
                face: fmap[f as usize],
                bary,
            };
        } else {
            p.face = fmap[p.face as usize];
        }
    }
    let chain_edges = st
        .chain
        .iter()
        .map(|&(a, b)| key(vmap[a as usize], vmap[b as usize]))
        .collect();
    progress(1.0);
    Simplified {
        positions,
        triangles,
        input_vertex,
        params,
        chain_edges,
    }
}

//! Resampling a base domain at subdivision connectivity through the parameterization, and the
//! final relaxation on the input surface.
//!
//! Lee et al. 1998 (MAPS) §4 "remeshing": the base domain is split `L` times (1-to-4 triangle
//! split, Maret eq. 5.7; or, for Bertram et al.'s quad hierarchies (§4.1 Fig. 7), each base
//! triangle into three quads and then 1-to-4 quad splits), every new vertex gets the
//! parameter of the midpoint of its parent edge (face point: of its parent face) in the base
//! triangle it lies in, and is mapped onto the input through [`super::param::ParamMap`], so
//! every vertex of every level lies on the input surface.
//!
//! Then, as MAPS's "smoothing in the parameter domain" is meant to give well-shaped
//! triangles, [`relax`] moves finest-level vertices tangentially (Laplacian with the normal
//! component removed, Jacobi iterations) and re-projects each onto the closest point of the
//! input (BVH), guarded against jumping to another sheet: the projection is accepted only if
//! the input normal there agrees with the remesh normal and it moved less than half the
//! local edge length (Kobbelt et al. 1999's "shrink-wrapping" relaxation, restricted to the
//! tangent plane). Base vertices and vertices on boundary and feature base edges stay on their
//! curves (fixed), so boundaries stay boundaries and creases stay sharp.

use glam::DVec3;
use parry3d_f64::query::{PointQueryWithLocation, Ray, RayCast};
use parry3d_f64::shape::TriMesh;
use rayon::prelude::*;

use super::simplify::Param;
use crate::hierarchy::Hierarchy;
use crate::topology::Topology;
use crate::{Error, Result};

/// Closest points on the input with the triangle hit.
pub struct Projector {
    shape: TriMesh,
    pos: Vec<DVec3>,
    tris: Vec<[u32; 3]>,
    /// Triangles around each input vertex (CSR: `fan[fan_start[v]..fan_start[v + 1]]`).
    fan_start: Vec<u32>,
    fan: Vec<u32>,
    /// Unit normal of each input triangle.
    pub normals: Vec<DVec3>,
    /// [`SHEET_TOLERANCE`] times the input's bounding-box diagonal: how much closer another
    /// part of the input must be than the hinted sheet for [`Projector::closest_near`] to
    /// leave that sheet.
    sheet_tolerance: f64,
}

/// Where two sheets of the input lie closer together than this fraction of its bounding-box
/// diagonal, [`Projector::closest_near`] keeps to the hinted one.
///
/// Models with coincident, oppositely oriented sheets (a panel modelled by its two sides,
/// overlapping coplanar triangles: 47 of the beetle's edges are on more than two faces and
/// the repair cuts them apart) give points on one sheet a closest point on the other about
/// as often as on their own, with the opposite normal. Measured on the beetle's 5-level
/// remesh: of the 486 faces whose normal opposes the input's at the closest point of their
/// centroid, 143 have an input triangle facing their way within 1e-5 of the diagonal and
/// 254 within 1e-4 (elsewhere few do: suzanne 11 of 37, cow 6 of 44, none of the bunny's,
/// rocker-arm's, cheburashka's or teapot's). Keeping to the
/// sheet a point was sampled from moves it at most this far from the true closest point
/// (80 dB of PSNR if every point did).
pub const SHEET_TOLERANCE: f64 = 1e-4;

impl Projector {
    /// A BVH over the input triangles.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if parry cannot index the triangles.
    pub fn new(pos: &[DVec3], tris: &[[u32; 3]]) -> Result<Projector> {
        let normals = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| pos[i as usize]);
                (b - a).cross(c - a).normalize_or_zero()
            })
            .collect();
        let vertices = pos
            .iter()
            .map(|p| parry3d_f64::math::Vector::new(p.x, p.y, p.z))
            .collect();
        let shape = TriMesh::new(vertices, tris.to_vec())
            .map_err(|e| Error::InvalidArgument(format!("cannot index the triangles: {e:?}")))?;
        let mut fan_start = vec![0u32; pos.len() + 1];
        for t in tris {
            for &i in t {
                fan_start[i as usize + 1] += 1;
            }
        }
        for i in 0..pos.len() {
            fan_start[i + 1] += fan_start[i];
        }
        let mut fill = fan_start.clone();
        let mut fan = vec![0u32; 3 * tris.len()];
        for (k, t) in tris.iter().enumerate() {
            for &i in t {
                fan[fill[i as usize] as usize] = k as u32;
                fill[i as usize] += 1;
            }
        }
        Ok(Projector {
            shape,
            pos: pos.to_vec(),
            tris: tris.to_vec(),
            fan_start,
            fan,
            normals,
            sheet_tolerance: SHEET_TOLERANCE * crate::mesh::diagonal_of(pos),
        })
    }

    /// A *local* closest input point to `p`: starting from input triangle `start`, walks
    /// to the neighbouring triangle across the edge or vertex where the current closest point
    /// lies as long as that gets closer, so it stays on the sheet of the input around
    /// `start` (a local minimum of the distance over the surface, which is the global one
    /// unless another part of the input comes closer). `None` if `start` is not an input
    /// triangle or the walk does not settle within 64 steps.
    pub fn closest_local(&self, p: DVec3, start: u32) -> Option<(DVec3, u32)> {
        let tri = |t: u32| -> Option<(DVec3, f64, Region)> {
            let [a, b, c] = self.tris.get(t as usize)?.map(|i| self.pos[i as usize]);
            let (q, r) = closest_on_triangle_region(p, a, b, c);
            Some((q, q.distance_squared(p), r))
        };
        let mut cur = start;
        let (mut q, mut d2, mut region) = tri(cur)?;
        if !d2.is_finite() {
            return None;
        }
        for _ in 0..64 {
            let t = self.tris[cur as usize];
            // The corners whose fans are searched, and a vertex the next triangle must have.
            let (corners, n, other) = match region {
                Region::Face => return Some((q, cur)),
                Region::Vertex(k) => ([k, 0, 0], 1, None),
                Region::Edge(i, j) => ([i, 0, 0], 1, Some(t[j])),
                Region::Degenerate => ([0, 1, 2], 3, None),
            };
            let mut next: Option<(u32, DVec3, f64, Region)> = None;
            for &k in &corners[..n] {
                let v = t[k] as usize;
                for &u in &self.fan[self.fan_start[v] as usize..self.fan_start[v + 1] as usize] {
                    if u == cur || other.is_some_and(|w| !self.tris[u as usize].contains(&w)) {
                        continue;
                    }
                    let (qu, du, ru) = tri(u)?;
                    if du < next.map_or(d2, |n| n.2) {
                        next = Some((u, qu, du, ru));
                    }
                }
            }
            match next {
                Some((u, qu, du, ru)) if du < d2 => {
                    (cur, q, d2, region) = (u, qu, du, ru);
                }
                _ => return Some((q, cur)),
            }
        }
        None
    }

    /// The input's normal around triangle `t`: the area-weighted mean of the normals of the
    /// input triangles sharing a vertex with it (unit; zero if they cancel or `t` is not an
    /// input triangle).
    pub fn smooth_normal(&self, t: u32) -> DVec3 {
        let Some(tv) = self.tris.get(t as usize) else {
            return DVec3::ZERO;
        };
        let mut n = DVec3::ZERO;
        let mut seen: [u32; 64] = [u32::MAX; 64];
        let mut count = 0;
        for &v in tv {
            let v = v as usize;
            for &u in &self.fan[self.fan_start[v] as usize..self.fan_start[v + 1] as usize] {
                if seen[..count].contains(&u) {
                    continue;
                }
                if count < seen.len() {
                    seen[count] = u;
                    count += 1;
                }
                let [a, b, c] = self.tris[u as usize].map(|i| self.pos[i as usize]);
                n += (b - a).cross(c - a);
            }
        }
        n.normalize_or_zero()
    }

    /// The closest point of input triangle `t` to `p` and its squared distance (`None` if
    /// `t` is not an input triangle).
    fn on_triangle(&self, p: DVec3, t: u32) -> Option<(DVec3, f64)> {
        let [a, b, c] = self.tris.get(t as usize)?.map(|i| self.pos[i as usize]);
        let q = closest_on_triangle(p, a, b, c);
        Some((q, q.distance_squared(p)))
    }

    /// The closest input point to `p` and its triangle, like [`Projector::closest`], using
    /// input triangles `hints` known to be near `p` (any of them; `u32::MAX` or out-of-range
    /// entries are ignored): the nearest of them bounds the BVH search, which then only
    /// visits the few nodes closer than it. The same point as [`Projector::closest`] up to
    /// rounding, except that the hinted sheet is kept (the local closest point reached by
    /// walking from the nearest hint, [`Projector::closest_local`]) when another part of
    /// the input is closer by less than [`SHEET_TOLERANCE`] of the input's diagonal: on
    /// coincident sheets of opposite orientation, a point keeps the sheet it came from. So
    /// the BVH is not searched at all when that local point is within the tolerance.
    pub fn closest_near(&self, p: DVec3, hints: &[u32]) -> (DVec3, u32) {
        let mut best: Option<(DVec3, f64, u32)> = None;
        for &t in hints {
            if best.is_some_and(|b| b.2 == t) {
                continue;
            }
            if let Some((q, d2)) = self.on_triangle(p, t) {
                if best.is_none_or(|b| d2 < b.1) {
                    best = Some((q, d2, t));
                }
            }
        }
        let Some((mut q, mut d2, mut t)) = best else {
            return self.closest(p);
        };
        // Walk on the surface to a local minimum: a tight bound for the search.
        if let Some((qw, tw)) = self.closest_local(p, t) {
            let dw = qw.distance_squared(p);
            if dw < d2 {
                (q, d2, t) = (qw, dw, tw);
            }
        }
        if !d2.is_finite() {
            return self.closest(p);
        }
        // Only a part of the input closer by more than the tolerance leaves the sheet: none
        // can be when the sheet is that close (most queries, from points just moved along
        // the surface), and the search need not look farther than that.
        let reach = d2.sqrt() - self.sheet_tolerance;
        if reach <= 0.0 {
            return (q, t);
        }
        match self.search(p, reach * reach) {
            Some((qs, ds, ts)) if d2.sqrt() - ds.sqrt() > self.sheet_tolerance => (qs, ts),
            _ => (q, t),
        }
    }

    /// The input triangle closest to `p` among those closer than `sqrt(max_d2)` (BVH
    /// best-first search on squared distances), with the point and its squared distance.
    fn search(&self, p: DVec3, max_d2: f64) -> Option<(DVec3, f64, u32)> {
        self.shape
            .bvh()
            .find_best(
                max_d2,
                |node, _| {
                    let (mn, mx) = (node.mins(), node.maxs());
                    let dx = (mn.x - p.x).max(p.x - mx.x).max(0.0);
                    let dy = (mn.y - p.y).max(p.y - mx.y).max(0.0);
                    let dz = (mn.z - p.z).max(p.z - mx.z).max(0.0);
                    dx * dx + dy * dy + dz * dz
                },
                |prim, _| {
                    let (q, d2) = self.on_triangle(p, prim)?;
                    Some((d2, q))
                },
            )
            .map(|(t, (d2, q))| (q, d2, t))
    }

    /// The corners of input triangle `t` (panics if `t` is out of range).
    pub(crate) fn triangle(&self, t: u32) -> [u32; 3] {
        self.tris[t as usize]
    }

    /// The position of input vertex `v` (panics if `v` is out of range).
    pub(crate) fn vertex(&self, v: u32) -> DVec3 {
        self.pos[v as usize]
    }

    /// The input triangles around input vertex `v` (panics if `v` is out of range).
    pub(crate) fn fan(&self, v: u32) -> &[u32] {
        &self.fan[self.fan_start[v as usize] as usize..self.fan_start[v as usize + 1] as usize]
    }

    /// The number of input triangles.
    pub(crate) fn num_triangles(&self) -> usize {
        self.tris.len()
    }

    /// The closest input point to `p` and its triangle.
    pub fn closest(&self, p: DVec3) -> (DVec3, u32) {
        let (proj, (tri, _)) = self.shape.project_local_point_and_get_location(
            parry3d_f64::math::Vector::new(p.x, p.y, p.z),
            false,
        );
        (DVec3::new(proj.point.x, proj.point.y, proj.point.z), tri)
    }

    /// The first input triangle hit by the ray `p + t d`, `0 ≤ t ≤ max_t` (`d` need not be
    /// unit; `t` is in multiples of it), as `(t, triangle)`; either side of a triangle counts.
    pub fn cast_ray(&self, p: DVec3, d: DVec3, max_t: f64) -> Option<(f64, u32)> {
        let ray = Ray::new(
            parry3d_f64::math::Vector::new(p.x, p.y, p.z),
            parry3d_f64::math::Vector::new(d.x, d.y, d.z),
        );
        self.shape
            .cast_local_ray_and_get_normal(&ray, max_t, false)
            .map(|hit| (hit.time_of_impact, hit.subshape))
    }
}

/// Where on a triangle its closest point to a query lies (corner indices 0, 1, 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Region {
    Face,
    Vertex(usize),
    Edge(usize, usize),
    Degenerate,
}

/// The closest point of triangle `abc` to `p` (Ericson, "Real-Time Collision Detection",
/// §5.1.5: Voronoi regions of the vertices, edges and face).
pub fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    closest_on_triangle_region(p, a, b, c).0
}

/// [`closest_on_triangle`] and the Voronoi region the point lies in.
fn closest_on_triangle_region(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, Region) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Region::Vertex(0));
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Region::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + v * ab, Region::Edge(0, 1));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Region::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + w * ac, Region::Edge(0, 2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + w * (c - b), Region::Edge(1, 2));
    }
    let denom = va + vb + vc;
    if denom == 0.0 || !denom.is_finite() {
        // Degenerate triangle: the nearest of its vertices and edges.
        let seg = |x: DVec3, y: DVec3| {
            let d = y - x;
            let l = d.length_squared();
            let t = if l > 0.0 {
                ((p - x).dot(d) / l).clamp(0.0, 1.0)
            } else {
                0.0
            };
            x + t * d
        };
        let q = [seg(a, b), seg(b, c), seg(c, a)]
            .into_iter()
            .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
            .unwrap_or(a);
        return (q, Region::Degenerate);
    }
    let inv = 1.0 / denom;
    (a + ab * (vb * inv) + ac * (vc * inv), Region::Face)
}

/// Corners of the children of a triangle with corner parameters `c` (Maret eq. 5.7 order).
fn tri_children(c: [[f64; 3]; 3], child: usize) -> [[f64; 3]; 3] {
    let mid = |a: [f64; 3], b: [f64; 3]| {
        [
            0.5 * (a[0] + b[0]),
            0.5 * (a[1] + b[1]),
            0.5 * (a[2] + b[2]),
        ]
    };
    let (m01, m12, m20) = (mid(c[0], c[1]), mid(c[1], c[2]), mid(c[2], c[0]));
    match child {
        0 => [c[0], m01, m20],
        1 => [c[1], m12, m01],
        2 => [c[2], m20, m12],
        _ => [m01, m12, m20],
    }
}

/// Child `i` of a quad `(p0..p3)`: `(p_i, m_i, centre, m_{i-1})`.
fn quad_child(c: [[f64; 3]; 4], i: usize) -> [[f64; 3]; 4] {
    let mid = |a: [f64; 3], b: [f64; 3]| {
        [
            0.5 * (a[0] + b[0]),
            0.5 * (a[1] + b[1]),
            0.5 * (a[2] + b[2]),
        ]
    };
    let centre = [
        0.25 * (c[0][0] + c[1][0] + c[2][0] + c[3][0]),
        0.25 * (c[0][1] + c[1][1] + c[2][1] + c[3][1]),
        0.25 * (c[0][2] + c[1][2] + c[2][2] + c[3][2]),
    ];
    [
        c[i],
        mid(c[i], c[(i + 1) % 4]),
        centre,
        mid(c[(i + 3) % 4], c[i]),
    ]
}

const E: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// The parameter of every vertex of level `level` of `h`, a hierarchy over the base
/// triangles (`quads == false`) or over the quads made of them (three per base triangle,
/// `(v_i, m_i, c, m_{i-1})`, `quads == true`).
pub fn level_params(h: &Hierarchy, level: usize, quads: bool) -> Vec<Param> {
    let topo = &h.topologies[level];
    let nv = topo.num_vertices as usize;
    let mut out = vec![
        Param {
            face: u32::MAX,
            bary: [0.0; 3],
        };
        nv
    ];
    let shift = 2 * level;
    for k in 0..topo.num_faces() {
        let fv = topo.face_vertices(k);
        if !quads {
            let mut c = E;
            let t = k >> shift;
            for l in (0..level).rev() {
                c = tri_children(c, (k >> (2 * l)) & 3);
            }
            for (j, &v) in fv.iter().enumerate() {
                if out[v as usize].face == u32::MAX {
                    out[v as usize] = Param {
                        face: t as u32,
                        bary: c[j],
                    };
                }
            }
        } else {
            let q = k >> shift;
            let (t, i) = (q / 3, q % 3);
            let mid = |a: [f64; 3], b: [f64; 3]| {
                [
                    0.5 * (a[0] + b[0]),
                    0.5 * (a[1] + b[1]),
                    0.5 * (a[2] + b[2]),
                ]
            };
            let mut c = [
                E[i],
                mid(E[i], E[(i + 1) % 3]),
                [1.0 / 3.0; 3],
                mid(E[(i + 2) % 3], E[i]),
            ];
            for l in (0..level).rev() {
                c = quad_child(c, (k >> (2 * l)) & 3);
            }
            for (j, &v) in fv.iter().enumerate() {
                if out[v as usize].face == u32::MAX {
                    out[v as usize] = Param {
                        face: t as u32,
                        bary: c[j],
                    };
                }
            }
        }
    }
    out
}

/// Area-weighted normals of a level's vertices.
pub fn vertex_normals(topo: &Topology, pos: &[DVec3]) -> Vec<DVec3> {
    (0..topo.num_vertices as usize)
        .into_par_iter()
        .map(|v| {
            let mut n = DVec3::ZERO;
            for &f in topo.vertex_faces(v) {
                n += face_normal(topo.face_vertices(f as usize), pos);
            }
            n.normalize_or_zero()
        })
        .collect()
}

/// Twice the area vector of a polygon (Newell).
pub fn face_normal(fv: &[u32], pos: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    let o = pos[fv[0] as usize];
    for i in 1..fv.len().saturating_sub(1) {
        n += (pos[fv[i] as usize] - o).cross(pos[fv[i + 1] as usize] - o);
    }
    n
}

/// Input triangles near the vertices of a face (the hints of its vertices, for
/// [`Projector::closest_near`]).
pub(super) fn face_hints(fv: &[u32], hints: &[u32]) -> [u32; 4] {
    let mut h = [u32::MAX; 4];
    for (i, &v) in fv.iter().take(4).enumerate() {
        h[i] = hints.get(v as usize).copied().unwrap_or(u32::MAX);
    }
    h
}

/// Tangential relaxation with guarded re-projection (see the module documentation);
/// `fixed` vertices do not move. `hints[v]` is an input triangle near vertex `v`
/// (`u32::MAX`: unknown; same length as `pos`), updated to the triangle each moved vertex
/// lands on. Returns the number of rejected projections in the last iteration.
pub fn relax(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topo: &Topology,
    fixed: &[bool],
    proj: &Projector,
    iterations: u32,
    step: f64,
) -> usize {
    let mut rejected = 0;
    for _ in 0..iterations {
        let normals = vertex_normals(topo, pos);
        let cur: &[DVec3] = pos;
        let hint: &[u32] = hints;
        let next: Vec<(DVec3, u32, bool)> = (0..cur.len())
            .into_par_iter()
            .map(|v| {
                let p = cur[v];
                if fixed[v] {
                    return (p, hint[v], true);
                }
                let edges = topo.vertex_edges(v);
                if edges.is_empty() {
                    return (p, hint[v], true);
                }
                let mut c = DVec3::ZERO;
                let mut len = 0.0;
                for &e in edges {
                    let w = topo.other_vertex(e as usize, v as u32) as usize;
                    c += cur[w];
                    len += cur[w].distance(p);
                }
                let k = edges.len() as f64;
                c /= k;
                len /= k;
                let n = normals[v];
                let d = c - p;
                let t = d - d.dot(n) * n;
                let moved = p + step * t;
                let (q, tri) = proj.closest_near(moved, &[hint[v]]);
                let mut ok =
                    proj.normals[tri as usize].dot(n) > 0.3 && q.distance(moved) < 0.5 * len;
                // No incident face may turn over (its normal stays within 90° of the old one
                // and of the input's).
                if ok {
                    for &f in topo.vertex_faces(v) {
                        let fv = topo.face_vertices(f as usize);
                        let old = face_normal(fv, cur);
                        let k = fv.iter().position(|&w| w as usize == v).unwrap_or(0);
                        let mut pts = [DVec3::ZERO; 4];
                        for (i, &w) in fv.iter().enumerate().take(4) {
                            pts[i] = if i == k { q } else { cur[w as usize] };
                        }
                        let m = fv.len().min(4);
                        let mut nn = DVec3::ZERO;
                        for i in 1..m - 1 {
                            nn += (pts[i] - pts[0]).cross(pts[i + 1] - pts[0]);
                        }
                        if nn.dot(old) <= 0.1 * nn.length() * old.length() || nn.dot(n) <= 0.0 {
                            ok = false;
                            break;
                        }
                    }
                }
                if ok {
                    (q, tri, true)
                } else {
                    (p, hint[v], false)
                }
            })
            .collect();
        rejected = 0;
        for (v, (p, tri, ok)) in next.into_iter().enumerate() {
            pos[v] = p;
            hints[v] = tri;
            if !ok {
                rejected += 1;
            }
        }
    }
    rejected
}

/// Whether each face of a level is flipped against the input (its normal opposes the input
/// normal at the closest input point of its centroid) or has zero area; `hints` as in
/// [`relax`].
pub fn flipped_faces(topo: &Topology, pos: &[DVec3], hints: &[u32], proj: &Projector) -> Vec<bool> {
    (0..topo.num_faces())
        .into_par_iter()
        .map(|f| {
            let fv = topo.face_vertices(f);
            let n = face_normal(fv, pos);
            let c = fv.iter().map(|&v| pos[v as usize]).sum::<DVec3>() / fv.len() as f64;
            let (_, tri) = proj.closest_near(c, &face_hints(fv, hints));
            n.dot(proj.normals[tri as usize]) <= 0.0
        })
        .collect()
}

/// Number of faces around `v` that are flipped against the input when `v` is at `p` (near
/// input triangle `hint`), the smallest angle of those faces (degrees), and the largest
/// distance of their centroids to the input.
pub(super) fn flips_around(
    v: usize,
    p: DVec3,
    hint: u32,
    topo: &Topology,
    pos: &[DVec3],
    hints: &[u32],
    proj: &Projector,
) -> (usize, f64, f64) {
    let mut count = 0;
    let mut min_angle = 180.0f64;
    let mut dev = 0.0f64;
    for &f in topo.vertex_faces(v) {
        let fv = topo.face_vertices(f as usize);
        let m = fv.len();
        let q = |i: usize| {
            if fv[i] as usize == v {
                p
            } else {
                pos[fv[i] as usize]
            }
        };
        let mut n = DVec3::ZERO;
        let mut c = DVec3::ZERO;
        for i in 0..m {
            c += q(i);
            if i >= 1 && i + 1 < m {
                n += (q(i) - q(0)).cross(q(i + 1) - q(0));
            }
        }
        let mut fh = face_hints(fv, hints);
        if let Some(k) = fv.iter().take(4).position(|&w| w as usize == v) {
            fh[k] = hint;
        }
        let c = c / m as f64;
        let (cq, tri) = proj.closest_near(c, &fh);
        dev = dev.max(cq.distance(c));
        if n.dot(proj.normals[tri as usize]) <= 0.0 {
            count += 1;
        }
        // The smallest angle has the largest cosine (one `acos` per face).
        let mut max_cos = f64::NEG_INFINITY;
        for i in 0..m {
            let a = q((i + 1) % m) - q(i);
            let b = q((i + m - 1) % m) - q(i);
            let (la, lb) = (a.length(), b.length());
            if la > 0.0 && lb > 0.0 {
                max_cos = max_cos.max((a.dot(b) / (la * lb)).clamp(-1.0, 1.0));
            } else {
                max_cos = f64::INFINITY;
            }
        }
        let ang = if max_cos == f64::INFINITY {
            0.0
        } else if max_cos == f64::NEG_INFINITY {
            180.0
        } else {
            max_cos.acos().to_degrees()
        };
        min_angle = min_angle.min(ang);
    }
    (count, min_angle, dev)
}

/// Whether a face is flipped against the input or has an angle below `min_degrees`.
fn bad_face(fv: &[u32], pos: &[DVec3], hints: &[u32], proj: &Projector, min_degrees: f64) -> bool {
    let n = face_normal(fv, pos);
    let c = fv.iter().map(|&v| pos[v as usize]).sum::<DVec3>() / fv.len() as f64;
    let (_, tri) = proj.closest_near(c, &face_hints(fv, hints));
    n.dot(proj.normals[tri as usize]) <= 0.0 || super::quality::min_angle(fv, pos) < min_degrees
}

/// Untangling: each free vertex of a flipped face, or of a face with an angle below 2°, tries
/// the closest input point of the centroid of its neighbours (a full Laplacian step, which
/// opens a fold) and of points between it and its current position, and takes the first that
/// lowers the number of flipped faces around it (or keeps it and raises their smallest
/// angle); vertices stay on the input. Gauss-Seidel over the bad region, at most `rounds`
/// rounds, each widening the region by one ring (up to three). `hints` as in [`relax`].
/// Returns the number of flipped faces left.
pub fn untangle(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topo: &Topology,
    fixed: &[bool],
    proj: &Projector,
    rounds: u32,
) -> usize {
    untangle_counts(pos, hints, topo, fixed, proj, rounds).0
}

/// [`untangle`], returning the faces left whose normal makes a non-acute angle with the
/// input normal (`≤ 0`: flipped or zero area, as [`flipped_faces`]) and those whose normal
/// opposes it (`< 0`: [`super::quality::Quality::flipped`]).
pub fn untangle_counts(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topo: &Topology,
    fixed: &[bool],
    proj: &Projector,
    rounds: u32,
) -> (usize, usize) {
    let bad = untangle_bad(pos, hints, topo, fixed, proj, rounds);
    // A face that is not bad is not flipped; only the bad ones need the flip test.
    let cur: &[DVec3] = pos;
    let hint: &[u32] = hints;
    bad.par_iter()
        .map(|&f| {
            let fv = topo.face_vertices(f as usize);
            let n = face_normal(fv, cur);
            let c = fv.iter().map(|&v| cur[v as usize]).sum::<DVec3>() / fv.len() as f64;
            let (_, tri) = proj.closest_near(c, &face_hints(fv, hint));
            let d = n.dot(proj.normals[tri as usize]);
            (usize::from(d <= 0.0), usize::from(d < 0.0))
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Flags of the `nv` vertices of `faces` and of the `rings` rings of vertices around them.
pub(crate) fn face_region(
    topo: &Topology,
    nv: usize,
    faces: impl IntoIterator<Item = usize>,
    rings: usize,
) -> Vec<bool> {
    let mut region = vec![false; nv];
    for f in faces {
        for &v in topo.face_vertices(f) {
            region[v as usize] = true;
        }
    }
    for _ in 0..rings {
        let grown = region.clone();
        for (v, &r) in grown.iter().enumerate() {
            if r {
                for &e in topo.vertex_edges(v) {
                    region[topo.other_vertex(e as usize, v as u32) as usize] = true;
                }
            }
        }
    }
    region
}

/// [`untangle`], returning the faces left that are flipped (normal at a non-acute angle with
/// the input's, as [`flipped_faces`]) or have an angle below 2°, in increasing order; every
/// other face is neither flipped nor degenerate.
pub fn untangle_bad(
    pos: &mut [DVec3],
    hints: &mut [u32],
    topo: &Topology,
    fixed: &[bool],
    proj: &Projector,
    rounds: u32,
) -> Vec<u32> {
    const BAD_ANGLE: f64 = 2.0;
    let mut flipped: Vec<bool> = (0..topo.num_faces())
        .into_par_iter()
        .map(|f| bad_face(topo.face_vertices(f), pos, hints, proj, BAD_ANGLE))
        .collect();
    let mut count = flipped.iter().filter(|&&f| f).count();
    for radius in 1..=rounds {
        if count == 0 {
            break;
        }
        let seeds = flipped.iter().enumerate().filter(|x| *x.1).map(|x| x.0);
        let region = face_region(topo, pos.len(), seeds, radius.min(3) as usize - 1);
        for v in 0..pos.len() {
            if !region[v] || fixed[v] {
                continue;
            }
            let edges = topo.vertex_edges(v);
            if edges.is_empty() {
                continue;
            }
            let c = edges
                .iter()
                .map(|&e| pos[topo.other_vertex(e as usize, v as u32) as usize])
                .sum::<DVec3>()
                / edges.len() as f64;
            let now = flips_around(v, pos[v], hints[v], topo, pos, hints, proj);
            if now.0 == 0 && now.1 >= BAD_ANGLE {
                continue;
            }
            let p0 = pos[v];
            for t in [1.0, 0.5, 0.25] {
                let (q, tri) = proj.closest_near(p0.lerp(c, t), &[hints[v]]);
                let new = flips_around(v, q, tri, topo, pos, hints, proj);
                if new.0 < now.0 || (new.0 == now.0 && new.1 > now.1) {
                    pos[v] = q;
                    hints[v] = tri;
                    break;
                }
            }
        }
        // Re-test only the faces around the region.
        let mut faces: Vec<u32> = Vec::new();
        for (v, &r) in region.iter().enumerate() {
            if r {
                faces.extend_from_slice(topo.vertex_faces(v));
            }
        }
        faces.sort_unstable();
        faces.dedup();
        let cur: &[DVec3] = pos;
        let hint: &[u32] = hints;
        let updates: Vec<(u32, bool)> = faces
            .par_iter()
            .map(|&f| {
                (
                    f,
                    bad_face(topo.face_vertices(f as usize), cur, hint, proj, BAD_ANGLE),
                )
            })
            .collect();
        for (f, flip) in updates {
            flipped[f as usize] = flip;
        }
        count = flipped.iter().filter(|&&f| f).count();
    }
    (0..flipped.len() as u32)
        .filter(|&f| flipped[f as usize])
        .collect()
}

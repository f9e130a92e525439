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
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::TriMesh;
use rayon::prelude::*;

use super::simplify::Param;
use crate::hierarchy::Hierarchy;
use crate::topology::Topology;
use crate::{Error, Result};

/// Closest points on the input with the triangle hit.
pub struct Projector {
    shape: TriMesh,
    /// Unit normal of each input triangle.
    pub normals: Vec<DVec3>,
}

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
        Ok(Projector { shape, normals })
    }

    /// The closest input point to `p` and its triangle.
    pub fn closest(&self, p: DVec3) -> (DVec3, u32) {
        let (proj, (tri, _)) = self.shape.project_local_point_and_get_location(
            parry3d_f64::math::Vector::new(p.x, p.y, p.z),
            false,
        );
        (DVec3::new(proj.point.x, proj.point.y, proj.point.z), tri)
    }
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

/// Tangential relaxation with guarded re-projection (see the module documentation);
/// `fixed` vertices do not move. Returns the number of rejected projections in the last
/// iteration.
pub fn relax(
    pos: &mut [DVec3],
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
        let next: Vec<(DVec3, bool)> = (0..cur.len())
            .into_par_iter()
            .map(|v| {
                let p = cur[v];
                if fixed[v] {
                    return (p, true);
                }
                let edges = topo.vertex_edges(v);
                if edges.is_empty() {
                    return (p, true);
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
                let (q, tri) = proj.closest(moved);
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
                    (q, true)
                } else {
                    (p, false)
                }
            })
            .collect();
        rejected = 0;
        for (v, (p, ok)) in next.into_iter().enumerate() {
            pos[v] = p;
            if !ok {
                rejected += 1;
            }
        }
    }
    rejected
}

/// Whether each face of a level is flipped against the input (its normal opposes the input
/// normal at the closest input point of its centroid) or has zero area.
pub fn flipped_faces(topo: &Topology, pos: &[DVec3], proj: &Projector) -> Vec<bool> {
    (0..topo.num_faces())
        .into_par_iter()
        .map(|f| {
            let fv = topo.face_vertices(f);
            let n = face_normal(fv, pos);
            let c = fv.iter().map(|&v| pos[v as usize]).sum::<DVec3>() / fv.len() as f64;
            let (_, tri) = proj.closest(c);
            n.dot(proj.normals[tri as usize]) <= 0.0
        })
        .collect()
}

/// Number of faces around `v` that are flipped against the input when `v` is at `p`, and
/// the smallest angle of those faces (degrees).
fn flips_around(
    v: usize,
    p: DVec3,
    topo: &Topology,
    pos: &[DVec3],
    proj: &Projector,
) -> (usize, f64) {
    let mut count = 0;
    let mut min_angle = 180.0f64;
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
        let (_, tri) = proj.closest(c / m as f64);
        if n.dot(proj.normals[tri as usize]) <= 0.0 {
            count += 1;
        }
        for i in 0..m {
            let a = q((i + 1) % m) - q(i);
            let b = q((i + m - 1) % m) - q(i);
            let (la, lb) = (a.length(), b.length());
            let ang = if la > 0.0 && lb > 0.0 {
                (a.dot(b) / (la * lb)).clamp(-1.0, 1.0).acos().to_degrees()
            } else {
                0.0
            };
            min_angle = min_angle.min(ang);
        }
    }
    (count, min_angle)
}

/// Whether a face is flipped against the input or has an angle below `min_degrees`.
fn bad_face(fv: &[u32], pos: &[DVec3], proj: &Projector, min_degrees: f64) -> bool {
    let n = face_normal(fv, pos);
    let c = fv.iter().map(|&v| pos[v as usize]).sum::<DVec3>() / fv.len() as f64;
    let (_, tri) = proj.closest(c);
    n.dot(proj.normals[tri as usize]) <= 0.0 || super::quality::min_angle(fv, pos) < min_degrees
}

/// Untangling: each free vertex of a flipped face, or of a face with an angle below 2°, tries
/// the closest input point of the centroid of its neighbours (a full Laplacian step, which
/// opens a fold) and of points between it and its current position, and takes the first that
/// lowers the number of flipped faces around it (or keeps it and raises their smallest
/// angle); vertices stay on the input. Gauss-Seidel over the bad region, at most `rounds`
/// rounds, each widening the region by one ring (up to three). Returns the number of flipped
/// faces left.
pub fn untangle(
    pos: &mut [DVec3],
    topo: &Topology,
    fixed: &[bool],
    proj: &Projector,
    rounds: u32,
) -> usize {
    const BAD_ANGLE: f64 = 2.0;
    let mut flipped: Vec<bool> = (0..topo.num_faces())
        .into_par_iter()
        .map(|f| bad_face(topo.face_vertices(f), pos, proj, BAD_ANGLE))
        .collect();
    let mut count = flipped.iter().filter(|&&f| f).count();
    for radius in 1..=rounds {
        if count == 0 {
            break;
        }
        let mut region = vec![false; pos.len()];
        for (f, &flip) in flipped.iter().enumerate() {
            if flip {
                for &v in topo.face_vertices(f) {
                    region[v as usize] = true;
                }
            }
        }
        for _ in 1..radius.min(3) {
            let grown = region.clone();
            for (v, &r) in grown.iter().enumerate() {
                if r {
                    for &e in topo.vertex_edges(v) {
                        region[topo.other_vertex(e as usize, v as u32) as usize] = true;
                    }
                }
            }
        }
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
            let now = flips_around(v, pos[v], topo, pos, proj);
            if now.0 == 0 && now.1 >= BAD_ANGLE {
                continue;
            }
            let p0 = pos[v];
            for t in [1.0, 0.5, 0.25] {
                let (q, _) = proj.closest(p0.lerp(c, t));
                let new = flips_around(v, q, topo, pos, proj);
                if new.0 < now.0 || (new.0 == now.0 && new.1 > now.1) {
                    pos[v] = q;
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
        let updates: Vec<(u32, bool)> = faces
            .par_iter()
            .map(|&f| {
                (
                    f,
                    bad_face(topo.face_vertices(f as usize), cur, proj, BAD_ANGLE),
                )
            })
            .collect();
        for (f, flip) in updates {
            flipped[f as usize] = flip;
        }
        count = flipped.iter().filter(|&&f| f).count();
    }
    flipped_faces(topo, pos, proj)
        .iter()
        .filter(|&&f| f)
        .count()
}

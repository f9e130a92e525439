//! Topological refinement: a child level's tables built directly from the parent's.
//!
//! This is the `Vtr::Refinement` of OpenSubdiv: no hashing, no search; child edges are
//! numbered in one scan of the parent faces, in the order in which they first appear in the
//! child face list, so that a refined level satisfies the same conventions as a level built
//! from scratch by [`Topology::build`] (tested).
//!
//! # Ordering contract
//! The wavelet transforms and the AFX offspring forest (Maret §5.3.4, Algorithms 5-7) rely on
//! it:
//! - **Vertices**: the parent's `V` vertices keep their indices; then one vertex per parent
//!   edge, in edge order (`V + e`); then, for polygon splits, one vertex per parent face, in
//!   face order (`V + E + f`).
//! - **Triangle split (1-to-4)**: triangle `k = (v0, v1, v2)` with edge points `v3, v4, v5` on
//!   edges `v0v1, v1v2, v2v0` has children `4k..4k+3` = `(v0 v3 v5), (v1 v4 v3), (v2 v5 v4),
//!   (v3 v4 v5)` (Maret eq. 5.7).
//! - **Polygon split (1-to-n quads)**: face `k` of arity `n` with corners `v_i`, edge points
//!   `m_i` on edges `v_i v_{i+1}` and face point `c` has children `offset_k + i =
//!   (v_i, m_i, c, m_{i-1})`, `offset_k` being the number of corners of the faces before `k`
//!   (so the children of quad `k` of a quad mesh are `4k..4k+3`). This is OpenSubdiv's order.
//! - **Quad/triangle split** ([`Split::QuadTri`], Stam & Loop 2003; Lavoué et al. §III.2):
//!   on a mesh of triangles and quads, the parent's vertices keep their indices, then one
//!   vertex per parent edge in edge order (`V + e`), then one face point per parent *quad* in
//!   face order (`V + E + q`, `q` counting the quads before it; triangles get none). Every
//!   parent face has four children, stored in parent face order (children of face `k` are
//!   `4k..4k+3`): a triangle's in the triangle-split order above (Maret eq. 5.7), a quad's in
//!   the polygon-split order `(v_i, m_i, c, m_{i-1})`.
//! - **Edges** of the child level: order of first appearance in the child face list.
//! - **√3 split** (not a [`Split`]: [`super::sqrt3`] refines itself): parent vertices keep
//!   their indices, then one centroid per split face in face order (`V + f` on closed meshes),
//!   then two trisection points per sharp edge on trisection steps; children `3f..3f+2` of
//!   face `f` lie along its edges `v_i v_{i+1}`, see [`super::sqrt3`]'s ordering contract.

use crate::par::Filler;
use crate::topology::{Topology, VertexFaces, VertexKind};

/// How a scheme splits faces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Split {
    /// Each triangle into four (Loop, butterfly, midpoint).
    Triangles,
    /// Each n-gon into n quads around a face point (Catmull-Clark, bilinear, B-splines).
    Polygons,
    /// Triangles 1-to-4 by edge points, quads 1-to-4 around a face point (quad/triangle
    /// subdivision of Stam & Loop 2003); faces of other arities are not allowed.
    QuadTri,
}

/// Number of quads among `parent`'s faces (the face points of a [`Split::QuadTri`]).
pub fn num_quads(parent: &Topology) -> usize {
    parent
        .face_offsets
        .windows(2)
        .filter(|w| w[1] - w[0] == 4)
        .count()
}

/// The child level's faces and edges, before the derived tables are built.
pub struct ChildEdges {
    /// Child face offsets.
    pub face_offsets: Vec<u32>,
    /// Child face vertices.
    pub face_vertices: Vec<u32>,
    /// Child face edges.
    pub face_edges: Vec<u32>,
    /// Child edge ends (first-traversal direction).
    pub edge_vertices: Vec<[u32; 2]>,
    /// For each parent edge, its two child halves: at `edge_vertices[e][0]` and at `[1]`.
    pub edge_halves: Vec<[u32; 2]>,
}

/// Number of child vertices of a split of `parent`.
pub fn child_vertex_count(parent: &Topology, split: Split) -> usize {
    let base = parent.num_vertices as usize + parent.num_edges();
    match split {
        Split::Triangles => base,
        Split::Polygons => base + parent.num_faces(),
        Split::QuadTri => base + num_quads(parent),
    }
}

/// Parent faces per parallel work item.
const FACE_CHUNK: usize = 4096;

/// Offsets `0, arity, 2 arity, ..., n arity` of `n` faces of one arity.
fn uniform_offsets(n: usize, arity: u32) -> Vec<u32> {
    crate::par::par_vec(n + 1, 1 << 16, || (), |_, i| arity * i as u32)
}

/// Child faces only (no edges): enough for the last level of a refinement, whose topology
/// nobody queries. Returns `(face_offsets, face_vertices)`.
pub fn child_faces(parent: &Topology, split: Split) -> (Vec<u32>, Vec<u32>) {
    let nv = parent.num_vertices;
    let ne = parent.num_edges() as u32;
    let nf = parent.num_faces();
    match split {
        Split::Triangles => {
            let fv = crate::par::par_vec(
                nf,
                FACE_CHUNK,
                || (),
                |_, f| {
                    let v = parent.face_vertices(f);
                    let e = parent.face_edges(f);
                    let (v3, v4, v5) = (nv + e[0], nv + e[1], nv + e[2]);
                    [v[0], v3, v5, v[1], v4, v3, v[2], v5, v4, v3, v4, v5]
                },
            );
            (uniform_offsets(4 * nf, 3), fv.into_flattened())
        }
        Split::Polygons if parent.face_arity == 4 => {
            // A quad mesh (every level after the first of Catmull-Clark): fixed-size records.
            let fv = crate::par::par_vec(
                nf,
                FACE_CHUNK,
                || (),
                |_, f| {
                    let v = parent.face_vertices(f);
                    let e = parent.face_edges(f);
                    let c = nv + ne + f as u32;
                    let m = [nv + e[0], nv + e[1], nv + e[2], nv + e[3]];
                    [
                        v[0], m[0], c, m[3], v[1], m[1], c, m[0], v[2], m[2], c, m[1], v[3], m[3],
                        c, m[2],
                    ]
                },
            );
            (uniform_offsets(4 * nf, 4), fv.into_flattened())
        }
        Split::Polygons => {
            let nc = parent.face_vertices.len();
            // Face f's children take 4 · (its corners) slots: parts of face chunks.
            let jobs = (0..nf)
                .step_by(FACE_CHUNK)
                .map(|lo| {
                    let hi = (lo + FACE_CHUNK).min(nf);
                    let len = 4 * (parent.face_offsets[hi] - parent.face_offsets[lo]) as usize;
                    (lo..hi, len)
                })
                .collect();
            let fv = crate::par::par_parts(jobs, |faces, out| {
                for f in faces {
                    let v = parent.face_vertices(f);
                    let e = parent.face_edges(f);
                    let c = nv + ne + f as u32;
                    let n = v.len();
                    for i in 0..n {
                        let prev = if i == 0 { n - 1 } else { i - 1 };
                        out.extend(&[v[i], nv + e[i], c, nv + e[prev]]);
                    }
                }
            });
            (uniform_offsets(nc, 4), fv)
        }
        Split::QuadTri => {
            let mut offsets = Vec::with_capacity(4 * nf + 1);
            let mut fv = Vec::with_capacity(4 * parent.face_vertices.len());
            offsets.push(0u32);
            let mut q = nv + ne;
            for f in 0..nf {
                let v = parent.face_vertices(f);
                let e = parent.face_edges(f);
                if v.len() == 3 {
                    let (v3, v4, v5) = (nv + e[0], nv + e[1], nv + e[2]);
                    for t in [[v[0], v3, v5], [v[1], v4, v3], [v[2], v5, v4], [v3, v4, v5]] {
                        fv.extend_from_slice(&t);
                        offsets.push(fv.len() as u32);
                    }
                } else {
                    let n = v.len();
                    for i in 0..n {
                        let prev = if i == 0 { n - 1 } else { i - 1 };
                        fv.extend_from_slice(&[v[i], nv + e[i], q, nv + e[prev]]);
                        offsets.push(fv.len() as u32);
                    }
                    q += 1;
                }
            }
            (offsets, fv)
        }
    }
}

/// The child edges of a split as they are numbered: a buffer of the exact count plus one
/// slot, written without branches (whether a half is new follows the mesh, not a pattern a
/// branch predictor learns). Each candidate is written at `len`, which then advances only for
/// a new edge, so every slot below `len` holds an edge (and an out-of-range slot is a
/// bounds-check panic).
///
/// Whether a half is new needs no lookup: the parent's edges are numbered by first appearance,
/// so the face being scanned is the first of its edge `e` exactly when `e` is at least
/// `seen`, one past the largest edge of the faces before it; that first face creates both
/// halves of `e`, and traverses `e` as `edge_vertices[e]` (the parent is consistently
/// oriented), so its outgoing half at a corner is the half at end 0, a later face's the half
/// at end 1.
struct ChildEdgeList<'a> {
    slots: &'a mut [std::mem::MaybeUninit<[u32; 2]>],
    len: usize,
    /// Per parent edge, its child halves at `edge_vertices[e][0]` and `[1]` (`u32::MAX` until
    /// created).
    halves: &'a mut [[u32; 2]],
    /// One past the largest parent edge of the faces scanned before the current one.
    seen: u32,
}

impl ChildEdgeList<'_> {
    /// The child half of parent edge `e` at the current corner (the corner's outgoing edge if
    /// `out`, else its incoming one), created by the edge's first face with the direction
    /// `dir`.
    #[inline(always)]
    fn half(&mut self, e: u32, out: bool, dir: [u32; 2]) -> u32 {
        let fresh = e >= self.seen;
        let end = usize::from(fresh != out);
        let h = &mut self.halves[e as usize][end];
        self.slots[self.len].write(dir);
        let id = if fresh { self.len as u32 } else { *h };
        *h = id;
        self.len += usize::from(fresh);
        id
    }

    /// A new interior edge with direction `dir`.
    #[inline(always)]
    fn interior(&mut self, dir: [u32; 2]) -> u32 {
        self.slots[self.len].write(dir);
        self.len += 1;
        (self.len - 1) as u32
    }

    /// The edges of the four children of triangle `v` (edges `e`), in child order (Maret eq.
    /// 5.7): child 4f (v0 m0 m2), 4f+1 (v1 m1 m0), 4f+2 (v2 m2 m1), 4f+3 (m0 m1 m2).
    #[inline(always)]
    fn triangle(&mut self, v: &[u32], e: &[u32], nv: u32) -> [u32; 12] {
        let m = [nv + e[0], nv + e[1], nv + e[2]];
        let h00 = self.half(e[0], true, [v[0], m[0]]);
        let ia = self.interior([m[0], m[2]]);
        let h20 = self.half(e[2], false, [m[2], v[0]]);
        let h11 = self.half(e[1], true, [v[1], m[1]]);
        let ib = self.interior([m[1], m[0]]);
        let h01 = self.half(e[0], false, [m[0], v[1]]);
        let h22 = self.half(e[2], true, [v[2], m[2]]);
        let ic = self.interior([m[2], m[1]]);
        let h12 = self.half(e[1], false, [m[1], v[2]]);
        [h00, ia, h20, h11, ib, h01, h22, ic, h12, ib, ic, ia]
    }

    /// The edges of the children `(v_i, m_i, c, m_{i-1})` of polygon `v` (edges `e`) around
    /// face point `c`, onto `out` (four per child).
    #[inline(always)]
    fn polygon(&mut self, v: &[u32], e: &[u32], nv: u32, c: u32, out: &mut Filler<u32>) {
        let n = v.len();
        let mut first_interior = 0u32;
        let mut prev_interior = 0u32;
        for i in 0..n {
            let ip = if i == 0 { n - 1 } else { i - 1 };
            let (mi, mp) = (nv + e[i], nv + e[ip]);
            let h_out = self.half(e[i], true, [v[i], mi]);
            let int_i = if i == n - 1 {
                first_interior
            } else {
                self.interior([mi, c])
            };
            let int_p = if i == 0 {
                // Interior edge n-1 first appears here, traversed c -> m_{n-1}.
                first_interior = self.interior([c, mp]);
                first_interior
            } else {
                prev_interior
            };
            let h_in = self.half(e[ip], false, [mp, v[i]]);
            out.extend(&[h_out, int_i, int_p, h_in]);
            prev_interior = int_i;
        }
    }
}

/// Child faces and edges of a split, numbered per the ordering contract.
///
/// Preconditions: `parent` is a consistently oriented manifold (checked by
/// [`crate::validate::require_manifold`] at level 0; splitting preserves it) whose edges are
/// numbered by first appearance with the ends in the direction of their first traversal (as
/// [`Topology::build`] and this refiner number them), and for [`Split::Triangles`] every face
/// is a triangle, for [`Split::QuadTri`] a triangle or a quad. A parent violating them gives
/// wrong tables or a panic (an index out of range), never undefined behaviour.
pub fn child_edges(parent: &Topology, split: Split) -> ChildEdges {
    let (face_offsets, face_vertices) = child_faces(parent, split);
    let nv = parent.num_vertices;
    let ne = parent.num_edges();
    let nf = parent.num_faces();
    // Every parent edge has two halves, and every split makes one interior edge per parent
    // corner (a triangle's three inner edges, an n-gon's n spokes): the exact count.
    let count = 2 * ne + parent.face_vertices.len();
    let mut edge_store: Vec<[u32; 2]> = Vec::with_capacity(count + 1);
    let mut halves = vec![[u32::MAX; 2]; ne];
    let mut edges = ChildEdgeList {
        slots: edge_store.spare_capacity_mut(),
        len: 0,
        halves: &mut halves,
        seen: 0,
    };
    let ne32 = ne as u32;
    // The child faces' edges in face order, one serial part (edges are numbered in scan order).
    let face_edges = crate::par::filled_vec(face_vertices.len(), |out| {
        // Quad/triangle: the face point of the next quad.
        let mut q = nv + ne32;
        for f in 0..nf {
            let v = parent.face_vertices(f);
            let e = parent.face_edges(f);
            match split {
                Split::Triangles => out.extend(&edges.triangle(v, e, nv)),
                Split::Polygons => edges.polygon(v, e, nv, nv + ne32 + f as u32, out),
                Split::QuadTri => {
                    // Children of face f are 4f..4f+3, starting at this corner of the list.
                    debug_assert_eq!(out.len(), face_offsets[4 * f] as usize);
                    if v.len() == 3 {
                        out.extend(&edges.triangle(v, e, nv));
                    } else {
                        edges.polygon(v, e, nv, q, out);
                        q += 1;
                    }
                }
            }
            edges.seen = edges.seen.max(e.iter().max().map_or(0, |&x| x + 1));
        }
    });
    let len = edges.len;
    debug_assert_eq!(len, count, "child edge count");
    // SAFETY: slots `0..len` were written (slot `k` when `len` was `k`, before it advanced)
    // and lie within the capacity (`slots` is the spare capacity of the empty vector).
    unsafe { edge_store.set_len(len) };
    ChildEdges {
        face_offsets,
        face_vertices,
        face_edges,
        edge_vertices: edge_store,
        edge_halves: halves,
    }
}

/// Builds the child level's full topology (without ring ordering unless `order_rings`).
pub fn refine_topology(
    parent: &Topology,
    split: Split,
    order_rings: bool,
) -> (Topology, Vec<[u32; 2]>) {
    refine_topology_with(parent, split, order_rings, true)
}

/// [`refine_topology`]; without `vertex_faces`, a lean level whose vertex-face relation
/// keeps only its offsets (see [`Topology::from_edges_counted`]; `order_rings` must then be
/// false).
pub(crate) fn refine_topology_with(
    parent: &Topology,
    split: Split,
    order_rings: bool,
    vertex_faces: bool,
) -> (Topology, Vec<[u32; 2]>) {
    let nv = child_vertex_count(parent, split);
    let c = child_edges(parent, split);
    let offsets = child_offsets(parent, split, &c);
    let table = match (&offsets, vertex_faces) {
        (_, false) => VertexFaces::Lean,
        (Some([vf, _, _]), true) if split == Split::Polygons => {
            let (faces, corners) = polygon_child_vertex_faces(parent, vf);
            VertexFaces::Given(faces, corners)
        }
        _ => VertexFaces::Sort,
    };
    let topo = Topology::from_edges_counted(
        nv,
        c.face_offsets,
        c.face_vertices,
        c.face_edges,
        c.edge_vertices,
        order_rings,
        offsets,
        table,
    );
    (topo, c.edge_halves)
}

/// The child level's vertex faces and corners of a polygon split, in parallel chunks of child
/// vertices from the parent's tables (each child vertex writes its own range of the layout
/// `vf` of [`child_offsets`]), in the scan order of a counting sort: ascending child faces.
/// By the ordering contract, child `offset_f + i` of parent face `f` is `(v_i, m_i, c,
/// m_{i-1})`: a parent vertex is corner 0 of one child per parent face; the edge point of
/// the edge at corner `i` of `f` is corner 1 of child `i` and corner 3 of child `i + 1`
/// (mod n); a face point is corner 2 of each of its face's children.
fn polygon_child_vertex_faces(parent: &Topology, vf: &[u32]) -> (Vec<u32>, Vec<u16>) {
    /// Child vertices per parallel work item.
    const CHUNK: usize = 4096;
    let nv = parent.num_vertices as usize;
    let ne = parent.num_edges();
    let n_child = vf.len() - 2;
    // Child vertex k's faces start at vf[k + 1].
    let jobs = (0..n_child)
        .step_by(CHUNK)
        .map(|k0| {
            let k1 = (k0 + CHUNK).min(n_child);
            (k0..k1, (vf[k1 + 1] - vf[k0 + 1]) as usize)
        })
        .collect();
    let (faces, corners) = crate::par::par_parts2(jobs, |range, fs, cs| {
        for k in range {
            if k < nv {
                let start = fs.len();
                for (&f, &i) in parent
                    .vertex_faces(k)
                    .iter()
                    .zip(parent.vertex_face_corners(k))
                {
                    fs.push(parent.face_offsets[f as usize] + u32::from(i));
                    cs.push(0);
                }
                // Ordered 1-rings (a level-0 parent) are not in face order.
                if parent.rings_ordered {
                    fs.written_from(start).sort_unstable();
                }
            } else if k < nv + ne {
                let e = (k - nv) as u32;
                for &f in parent.edge_faces(k - nv) {
                    let o = parent.face_offsets[f as usize];
                    let fe = parent.face_edges(f as usize);
                    let i = fe.iter().position(|&x| x == e).unwrap_or(0);
                    if i + 1 < fe.len() {
                        fs.extend(&[o + i as u32, o + i as u32 + 1]);
                        cs.extend(&[1, 3]);
                    } else {
                        fs.extend(&[o, o + i as u32]);
                        cs.extend(&[3, 1]);
                    }
                }
            } else {
                let f = k - nv - ne;
                let o = parent.face_offsets[f];
                for i in 0..parent.face_vertices(f).len() as u32 {
                    fs.push(o + i);
                    cs.push(2);
                }
            }
        }
    });
    (faces, corners)
}

/// The child level's vertex-face, vertex-edge and edge-face offsets, from the parent's counts
/// (in the layout of [`Topology::from_edges_counted`]), for the triangle and polygon splits of
/// a manifold parent; `None` for [`Split::QuadTri`] (counted by [`Topology::from_edges`]).
///
/// A parent vertex keeps one child face per parent face (its corner child) and one child edge
/// per parent edge (its half). An edge point has, per incident face, three child faces and two
/// interior edges (triangles) or two child faces and one interior edge (polygons), plus the
/// edge's two halves. A face point has one child face and one interior edge per corner. A
/// half of a parent edge lies in one child face per face of the edge, an interior edge in two.
fn child_offsets(parent: &Topology, split: Split, c: &ChildEdges) -> Option<[Vec<u32>; 3]> {
    let (faces_per_face, edges_per_face) = match split {
        Split::Triangles => (3, 2),
        Split::Polygons => (2, 1),
        Split::QuadTri => return None,
    };
    let nv = parent.num_vertices as usize;
    let ne = parent.num_edges();
    let n_child = child_vertex_count(parent, split);
    // The three tables are independent: built in parallel.
    let edge_faces = |e: usize| parent.edge_face_offsets[e + 1] - parent.edge_face_offsets[e];
    let vf = || {
        prefix(n_child, |v| {
            if v < nv {
                parent.vertex_face_offsets[v + 1] - parent.vertex_face_offsets[v]
            } else if v < nv + ne {
                faces_per_face * edge_faces(v - nv)
            } else {
                parent.face_vertices(v - nv - ne).len() as u32
            }
        })
    };
    let ve = || {
        prefix(n_child, |v| {
            if v < nv {
                parent.vertex_edge_offsets[v + 1] - parent.vertex_edge_offsets[v]
            } else if v < nv + ne {
                2 + edges_per_face * edge_faces(v - nv)
            } else {
                parent.face_vertices(v - nv - ne).len() as u32
            }
        })
    };
    let ef = || child_edge_face_offsets(parent, c);
    let (vf, (ve, ef)) = rayon::join(vf, || rayon::join(ve, ef));
    Some([vf, ve, ef])
}

/// A prefix sum of `n` counts in the layout of [`child_offsets`]: a leading 0, then the
/// `n + 1` offsets.
fn prefix(n: usize, count: impl Fn(usize) -> u32) -> Vec<u32> {
    let mut off = Vec::with_capacity(n + 2);
    off.push(0u32);
    off.push(0u32);
    let mut acc = 0u32;
    off.extend((0..n).map(|k| {
        acc += count(k);
        acc
    }));
    off
}

/// The child level's edge-face offsets (the layout of [`child_offsets`]): two faces per child
/// edge, but the halves of a parent edge lie in as many child faces as it has faces.
fn child_edge_face_offsets(parent: &Topology, c: &ChildEdges) -> Vec<u32> {
    let mut counts = vec![2u8; c.edge_vertices.len()];
    for (e, h) in c.edge_halves.iter().enumerate() {
        let n = parent.edge_face_offsets[e + 1] - parent.edge_face_offsets[e];
        if n != 2 {
            for &x in h {
                counts[x as usize] = n.min(255) as u8;
            }
        }
    }
    prefix(counts.len(), |e| u32::from(counts[e]))
}

/// The child level of a polygon split without vertex relations ([`VertexFaces::Without`]):
/// faces, edges, edge faces and kinds, zero sharpness. The refiner builds it for the last
/// level it evaluates, whose vertices' relations `super::stencil::level_apply_from_coarser`
/// reads from `parent` instead: the vertex-face and vertex-edge tables are the largest part
/// of a level's tables, and their counting sort the longest serial pass of its build.
/// Returns the level and the halves of `parent`'s edges, as [`refine_topology`] does.
///
/// Preconditions: those of [`child_edges`] for [`Split::Polygons`].
pub(crate) fn refine_topology_without_vertex_relations(
    parent: &Topology,
) -> (Topology, Vec<[u32; 2]>) {
    let split = Split::Polygons;
    let nv = child_vertex_count(parent, split);
    let c = child_edges(parent, split);
    let ef = child_edge_face_offsets(parent, &c);
    let mut topo = Topology::from_edges_counted(
        nv,
        c.face_offsets,
        c.face_vertices,
        c.face_edges,
        c.edge_vertices,
        false,
        Some([Vec::new(), Vec::new(), ef]),
        VertexFaces::Without,
    );
    // Without vertex relations every vertex is taken to have edges: an isolated parent
    // vertex stays isolated.
    for (v, k) in parent.vertex_kinds.iter().enumerate() {
        if *k == VertexKind::Isolated {
            topo.vertex_kinds[v] = VertexKind::Isolated;
        }
    }
    (topo, c.edge_halves)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;
    use crate::mesh::Mesh;

    fn check_same(parent_mesh: &Mesh, split: Split) {
        let parent = Topology::build(parent_mesh);
        let (child, _) = refine_topology(&parent, split, true);
        let mesh = Mesh {
            positions: vec![glam::DVec3::ZERO; child.num_vertices as usize],
            face_offsets: child.face_offsets.clone(),
            face_indices: child.face_vertices.clone(),
            ..Mesh::new()
        };
        let direct = Topology::build(&mesh);
        assert_eq!(child.face_edges, direct.face_edges);
        assert_eq!(child.edge_vertices, direct.edge_vertices);
        assert_eq!(child.edge_faces, direct.edge_faces);
        assert_eq!(child.vertex_faces, direct.vertex_faces);
        assert_eq!(child.vertex_edges, direct.vertex_edges);
        assert_eq!(child.vertex_kinds, direct.vertex_kinds);
        // Twice more: the child of a child.
        let (grand, _) = refine_topology(&child, split, false);
        let mesh = Mesh {
            positions: vec![glam::DVec3::ZERO; grand.num_vertices as usize],
            face_offsets: grand.face_offsets.clone(),
            face_indices: grand.face_vertices.clone(),
            ..Mesh::new()
        };
        let direct = Topology::build(&mesh);
        assert_eq!(grand.edge_vertices, direct.edge_vertices);
        assert_eq!(grand.face_edges, direct.face_edges);
        assert_eq!(grand.edge_face_offsets, direct.edge_face_offsets);
        assert_eq!(grand.edge_faces, direct.edge_faces);
        assert_eq!(grand.vertex_face_offsets, direct.vertex_face_offsets);
        assert_eq!(grand.vertex_edge_offsets, direct.vertex_edge_offsets);
        // Unordered 1-rings: the scan order of `from_edges`.
        let scan = Topology::from_edges(
            grand.num_vertices as usize,
            grand.face_offsets.clone(),
            grand.face_vertices.clone(),
            grand.face_edges.clone(),
            grand.edge_vertices.clone(),
            false,
        );
        assert_eq!(grand.vertex_faces, scan.vertex_faces);
        assert_eq!(grand.vertex_face_corners, scan.vertex_face_corners);
        assert_eq!(grand.vertex_edges, scan.vertex_edges);
        assert_eq!(grand.vertex_kinds, scan.vertex_kinds);
        // A lean child: the same tables but the vertex faces, which its vertices gather from
        // their edges exactly as the scan order has them.
        let (lean, _) = refine_topology_with(&child, split, false, false);
        assert!(grand.has_vertex_faces() && !lean.has_vertex_faces());
        assert!(lean.vertex_faces.is_empty() && lean.vertex_face_corners.is_empty());
        assert_eq!(lean.vertex_face_offsets, grand.vertex_face_offsets);
        assert_eq!(lean.vertex_edges, grand.vertex_edges);
        assert_eq!(lean.edge_faces, grand.edge_faces);
        assert_eq!(lean.vertex_kinds, grand.vertex_kinds);
        let (mut faces, mut corners) = (Vec::new(), Vec::new());
        for v in 0..lean.num_vertices as usize {
            lean.vertex_faces_from_edges(v, &mut faces, &mut corners);
            assert_eq!(faces, scan.vertex_faces(v), "vertex {v}");
            assert_eq!(corners, scan.vertex_face_corners(v), "vertex {v}");
        }
    }

    #[test]
    fn triangle_split_matches_build() {
        check_same(&generate::icosahedron(), Split::Triangles);
        check_same(&generate::disk(5), Split::Triangles);
        check_same(&generate::torus(1.0, 0.4, 5, 4, true), Split::Triangles);
    }

    #[test]
    fn polygon_split_matches_build() {
        check_same(&generate::cube(), Split::Polygons);
        check_same(&generate::pyramid(), Split::Polygons);
        check_same(&generate::grid(3, 2, false), Split::Polygons);
        check_same(&generate::torus(1.0, 0.4, 5, 4, false), Split::Polygons);
    }

    /// A closed mixed mesh: the cube with its top and front faces split into two triangles.
    pub(crate) fn mixed_cube() -> Mesh {
        let c = generate::cube();
        let mut faces: Vec<Vec<u32>> = Vec::new();
        for (k, f) in c.faces().enumerate() {
            if k == 1 || k == 2 {
                faces.push(vec![f[0], f[1], f[2]]);
                faces.push(vec![f[0], f[2], f[3]]);
            } else {
                faces.push(f.to_vec());
            }
        }
        Mesh::from_faces(c.positions.clone(), faces)
    }

    #[test]
    fn quad_tri_split_matches_build() {
        check_same(&mixed_cube(), Split::QuadTri);
        check_same(&generate::icosahedron(), Split::QuadTri);
        check_same(&generate::cube(), Split::QuadTri);
        check_same(&generate::grid(3, 2, false), Split::QuadTri);
        check_same(&generate::disk(5), Split::QuadTri);
    }

    #[test]
    fn quad_tri_split_ordering() {
        let m = mixed_cube();
        let parent = Topology::build(&m);
        let (nv, ne) = (parent.num_vertices, parent.num_edges() as u32);
        let (off, fv) = child_faces(&parent, Split::QuadTri);
        assert_eq!(off.len(), 4 * parent.num_faces() + 1);
        assert_eq!(
            child_vertex_count(&parent, Split::QuadTri),
            (nv + ne) as usize + 4
        );
        let mut q = nv + ne;
        for f in 0..parent.num_faces() {
            let v = parent.face_vertices(f);
            let e = parent.face_edges(f);
            let kids: Vec<&[u32]> = (4 * f..4 * f + 4)
                .map(|c| &fv[off[c] as usize..off[c + 1] as usize])
                .collect();
            if v.len() == 3 {
                let (v3, v4, v5) = (nv + e[0], nv + e[1], nv + e[2]);
                assert_eq!(kids[0], &[v[0], v3, v5]);
                assert_eq!(kids[1], &[v[1], v4, v3]);
                assert_eq!(kids[2], &[v[2], v5, v4]);
                assert_eq!(kids[3], &[v3, v4, v5]);
            } else {
                for i in 0..4 {
                    let p = (i + 3) % 4;
                    assert_eq!(kids[i], &[v[i], nv + e[i], q, nv + e[p]]);
                }
                q += 1;
            }
        }
    }

    #[test]
    fn maret_eq_5_7_children() {
        let m = generate::tetrahedron();
        let parent = Topology::build(&m);
        let (_, fv) = child_faces(&parent, Split::Triangles);
        let v = parent.face_vertices(0);
        let e = parent.face_edges(0);
        let (v3, v4, v5) = (4 + e[0], 4 + e[1], 4 + e[2]);
        assert_eq!(
            &fv[..12],
            &[v[0], v3, v5, v[1], v4, v3, v[2], v5, v4, v3, v4, v5]
        );
    }
}

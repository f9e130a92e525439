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
//! - **Edges** of the child level: order of first appearance in the child face list.
//! - **√3 split** (not a [`Split`]: [`super::sqrt3`] refines itself): parent vertices keep
//!   their indices, then one centroid per split face in face order (`V + f` on closed meshes),
//!   then two trisection points per sharp edge on trisection steps; children `3f..3f+2` of
//!   face `f` lie along its edges `v_i v_{i+1}`, see [`super::sqrt3`]'s ordering contract.

use rayon::prelude::*;

use crate::topology::Topology;

/// How a scheme splits faces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Split {
    /// Each triangle into four (Loop, butterfly, midpoint).
    Triangles,
    /// Each n-gon into n quads around a face point (Catmull-Clark, bilinear, B-splines).
    Polygons,
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
    }
}

/// Parent faces per parallel work item.
const FACE_CHUNK: usize = 4096;

/// Offsets `0, arity, 2 arity, ..., n arity` of `n` faces of one arity.
fn uniform_offsets(n: usize, arity: u32) -> Vec<u32> {
    let mut offsets = Vec::with_capacity(n + 1);
    (0..n as u32 + 1)
        .into_par_iter()
        .map(|i| arity * i)
        .collect_into_vec(&mut offsets);
    offsets
}

/// Child faces only (no edges): enough for the last level of a refinement, whose topology
/// nobody queries. Returns `(face_offsets, face_vertices)`.
pub fn child_faces(parent: &Topology, split: Split) -> (Vec<u32>, Vec<u32>) {
    let nv = parent.num_vertices;
    let ne = parent.num_edges() as u32;
    let nf = parent.num_faces();
    match split {
        Split::Triangles => {
            let mut fv = vec![0u32; 12 * nf];
            fv.par_chunks_mut(12 * FACE_CHUNK)
                .enumerate()
                .for_each(|(c, out)| {
                    for (k, o) in out.chunks_exact_mut(12).enumerate() {
                        let f = c * FACE_CHUNK + k;
                        let v = parent.face_vertices(f);
                        let e = parent.face_edges(f);
                        let (v3, v4, v5) = (nv + e[0], nv + e[1], nv + e[2]);
                        o.copy_from_slice(&[v[0], v3, v5, v[1], v4, v3, v[2], v5, v4, v3, v4, v5]);
                    }
                });
            (uniform_offsets(4 * nf, 3), fv)
        }
        Split::Polygons => {
            let nc = parent.face_vertices.len();
            let mut fv = vec![0u32; 4 * nc];
            // Face f's children start at 4 · face_offsets[f]: split the output at face chunks.
            let mut parts = Vec::with_capacity(nf.div_ceil(FACE_CHUNK));
            let mut rest = fv.as_mut_slice();
            for lo in (0..nf).step_by(FACE_CHUNK) {
                let hi = (lo + FACE_CHUNK).min(nf);
                let len = 4 * (parent.face_offsets[hi] - parent.face_offsets[lo]) as usize;
                let (head, tail) = rest.split_at_mut(len);
                parts.push((lo..hi, head));
                rest = tail;
            }
            parts.into_par_iter().for_each(|(faces, out)| {
                let mut k = 0;
                for f in faces {
                    let v = parent.face_vertices(f);
                    let e = parent.face_edges(f);
                    let c = nv + ne + f as u32;
                    let n = v.len();
                    for i in 0..n {
                        let prev = if i == 0 { n - 1 } else { i - 1 };
                        out[k..k + 4].copy_from_slice(&[v[i], nv + e[i], c, nv + e[prev]]);
                        k += 4;
                    }
                }
            });
            (uniform_offsets(nc, 4), fv)
        }
    }
}

/// Child faces and edges of a split, numbered per the ordering contract.
///
/// Preconditions: `parent` is a consistently oriented manifold (checked by
/// [`crate::validate::require_manifold`] at level 0; splitting preserves it), and for
/// [`Split::Triangles`] every face is a triangle.
pub fn child_edges(parent: &Topology, split: Split) -> ChildEdges {
    let (face_offsets, face_vertices) = child_faces(parent, split);
    let nv = parent.num_vertices;
    let ne = parent.num_edges();
    let nf = parent.num_faces();
    let mut face_edges = vec![0u32; face_vertices.len()];
    let mut edge_vertices: Vec<[u32; 2]> = Vec::with_capacity(face_vertices.len() / 2 + 2);
    let mut halves = vec![[u32::MAX; 2]; ne];
    // The child half of parent edge `e` at its end `w`, created on first sight with the given
    // direction.
    let mut half = |edge_vertices: &mut Vec<[u32; 2]>, e: u32, w: u32, dir: [u32; 2]| -> u32 {
        let end = usize::from(parent.edge_vertices[e as usize][0] != w);
        let h = &mut halves[e as usize][end];
        if *h == u32::MAX {
            *h = edge_vertices.len() as u32;
            edge_vertices.push(dir);
        }
        *h
    };
    let new_edge = |edge_vertices: &mut Vec<[u32; 2]>, dir: [u32; 2]| -> u32 {
        edge_vertices.push(dir);
        (edge_vertices.len() - 1) as u32
    };
    match split {
        Split::Triangles => {
            for f in 0..nf {
                let v = parent.face_vertices(f);
                let e = parent.face_edges(f);
                let m = [nv + e[0], nv + e[1], nv + e[2]];
                let c = 12 * f;
                // Child 4f: (v0 m0 m2); 4f+1: (v1 m1 m0); 4f+2: (v2 m2 m1); 4f+3: (m0 m1 m2).
                let h00 = half(&mut edge_vertices, e[0], v[0], [v[0], m[0]]);
                let ia = new_edge(&mut edge_vertices, [m[0], m[2]]);
                let h20 = half(&mut edge_vertices, e[2], v[0], [m[2], v[0]]);
                let h11 = half(&mut edge_vertices, e[1], v[1], [v[1], m[1]]);
                let ib = new_edge(&mut edge_vertices, [m[1], m[0]]);
                let h01 = half(&mut edge_vertices, e[0], v[1], [m[0], v[1]]);
                let h22 = half(&mut edge_vertices, e[2], v[2], [v[2], m[2]]);
                let ic = new_edge(&mut edge_vertices, [m[2], m[1]]);
                let h12 = half(&mut edge_vertices, e[1], v[2], [m[1], v[2]]);
                face_edges[c..c + 12]
                    .copy_from_slice(&[h00, ia, h20, h11, ib, h01, h22, ic, h12, ib, ic, ia]);
            }
        }
        Split::Polygons => {
            let ne32 = ne as u32;
            for f in 0..nf {
                let v = parent.face_vertices(f);
                let e = parent.face_edges(f);
                let n = v.len();
                let cpt = nv + ne32 + f as u32;
                let base = 4 * parent.face_offsets[f] as usize;
                let mut first_interior = 0u32;
                let mut prev_interior = 0u32;
                for i in 0..n {
                    let ip = if i == 0 { n - 1 } else { i - 1 };
                    let (mi, mp) = (nv + e[i], nv + e[ip]);
                    // Child i: (v_i, m_i, c, m_{i-1}).
                    let h_out = half(&mut edge_vertices, e[i], v[i], [v[i], mi]);
                    let int_i = if i == n - 1 {
                        first_interior
                    } else {
                        new_edge(&mut edge_vertices, [mi, cpt])
                    };
                    let int_p = if i == 0 {
                        // Interior edge n-1 first appears here, traversed c -> m_{n-1}.
                        let id = new_edge(&mut edge_vertices, [cpt, mp]);
                        first_interior = id;
                        id
                    } else {
                        prev_interior
                    };
                    let h_in = half(&mut edge_vertices, e[ip], v[i], [mp, v[i]]);
                    let c = base + 4 * i;
                    face_edges[c..c + 4].copy_from_slice(&[h_out, int_i, int_p, h_in]);
                    prev_interior = int_i;
                }
            }
        }
    }
    ChildEdges {
        face_offsets,
        face_vertices,
        face_edges,
        edge_vertices,
        edge_halves: halves,
    }
}

/// Builds the child level's full topology (without ring ordering unless `order_rings`).
pub fn refine_topology(
    parent: &Topology,
    split: Split,
    order_rings: bool,
) -> (Topology, Vec<[u32; 2]>) {
    let nv = child_vertex_count(parent, split);
    let c = child_edges(parent, split);
    let topo = Topology::from_edges(
        nv,
        c.face_offsets,
        c.face_vertices,
        c.face_edges,
        c.edge_vertices,
        order_rings,
    );
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

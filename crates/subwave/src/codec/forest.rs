//! The offspring forest over which SPIHT orders the wavelet coefficients.
//!
//! # Triangle hierarchies: the MPEG-4 AFX edge-offspring forest
//! Maret 2003 §3.3 (Fig. 3.7: an interior edge has four offspring, a boundary edge three),
//! §5.3.4 ("Offsprings Trees Construction", Figs. 5.6-5.8, Algorithms 6-7). Coefficients are
//! one per edge of each level (the detail of the odd vertex `V_j + e` of level-`j` edge `e`,
//! the flat layout of [`crate::wavelet::triangle`]); node `n` of the forest is the
//! coefficient at flat index `V_0 + n`. The trees are rooted at the base edges, **in the
//! order of their first appearance in the coordinate index** `P^0` (which is the crate's edge
//! order, so root `t` is base edge `t`).
//!
//! For a level-`j` triangle `(a, b, c)` with odd vertices `m_ab, m_bc, m_ca`, the children
//! (Maret eq. 5.7) are `(a m_ab m_ca), (b m_bc m_ab), (c m_ca m_bc), (m_ab m_bc m_ca)`. For
//! its edge `a→b` (and likewise `b→c`, `c→a`) we name, as Algorithms 6-7 do with the vertex
//! labels of Fig. 5.8 (numbered by first appearance of the level-`j+1` edges of the four
//! children, eq. 5.8):
//! - `v6` = child edge `(a, m_ab)` (first edge of child 0),
//! - `v11` = child edge `(m_ab, b)` (last edge of child 1),
//! - `v13` = the interior edge `(m_bc, m_ca)` "parallel" to `a→b` (of child 3).
//!
//! Every level-`j` edge carries an orientation tag, `PL` or `AR` (§5.3.4: P(arallel) /
//! A(nti-parallel) for offspring `0, 1`; L(eft) / R(ight) for `2, 3`; only `PL` and `AR` occur).
//! Triangles are visited in coordinate-index order; on the edge's first triangle its offspring
//! list is created, on its second (if any) the second interior edge is inserted:
//! - base level (Algorithm 6): first triangle: the edge's tag is `PL`, `O = (v11 PL, v6 PL,
//!   v13 PL)`; second triangle: append `v13 AR`;
//! - finer levels (Algorithm 7): first triangle: `O = (v11 PL, v6 PL, v13 PL)` if the edge is
//!   `PL`, else `O = (v6 AR, v11 AR, ⋆, v13 AR)` (slot 2 reserved); second triangle: if `PL`
//!   slot 3 `= v13 AR`, else slot 2 `= v13 PL`.
//!
//! A child's tag is the one written beside it; a reserved slot that stays empty (boundary
//! edge) is dropped. The figures 5.7-5.8 are not in the text we have; `v6/v11/v13` follow from
//! the vertex numbering of eqs. 5.7-5.8 as described above, and every edge of level `j + 1` is
//! the offspring of exactly one edge of level `j` (checked by the tests).
//!
//! # Quad hierarchies (Bertram et al., Catmull-Clark connectivity): vertex/face forest
//! Coefficients of level `j` are the edge vertices (one per level-`j` edge) then the face
//! vertices (one per level-`j` face), the layout of [`crate::wavelet::bertram`]. Offspring,
//! with the child quad of face `f` at corner `i` being `(v_i, m_i, c, m_{i-1})`:
//! - edge `e = v_i v_{i+1}` (Fig. 3.7 c-d): its two halves `(v_i m_i)`, `(m_i v_{i+1})`
//!   (in the direction of its first face), then the interior edge `(m_i c)` of each adjacent
//!   face in face order (4 offspring, 3 on a boundary);
//! - face `f`: the face vertices of its child quads, in corner order (n offspring for an
//!   n-gon).
//!
//! Roots: the base edges in edge order, then the base faces in face order.

use crate::hierarchy::Hierarchy;
use crate::subdivision::refine::Split;
use crate::{Error, Result};

/// "No node".
const NONE: u32 = u32::MAX;

/// An offspring forest over the detail coefficients of a hierarchy (node `n` = flat index
/// `V_0 + n`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Forest {
    /// Number of nodes (`V_L − V_0`).
    pub num_nodes: usize,
    /// Number of trees; the roots are nodes `0..num_trees` in tree order.
    pub num_trees: usize,
    /// Offspring of node `n`: `children[offsets[n]..offsets[n + 1]]`, in coding order.
    pub offsets: Vec<u32>,
    /// Concatenated offspring lists.
    pub children: Vec<u32>,
    /// Level `j` of each node (its coefficient belongs to level `j → j + 1`).
    pub level: Vec<u8>,
    /// Levels `L` of the hierarchy: nodes of level `j < L − 1` have offspring (every
    /// edge and face is split), those of level `j < L − 2` grandchildren.
    pub levels: usize,
}

impl Forest {
    /// The forest of hierarchy `h`: the AFX edge forest for [`Split::Triangles`], the
    /// vertex/face forest for [`Split::Polygons`].
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a [`Split::QuadTri`] hierarchy or more than 255 levels.
    pub fn new(h: &Hierarchy) -> Result<Forest> {
        if h.levels() > 255 {
            return Err(Error::InvalidArgument("at most 255 levels".into()));
        }
        match h.split {
            Split::Triangles => Ok(triangle_forest(h)),
            Split::Polygons => Ok(quad_forest(h)),
            Split::QuadTri => Err(Error::InvalidArgument(
                "the codec supports triangle (1-to-4) and Catmull-Clark quad hierarchies, not quad/triangle splits".into(),
            )),
        }
    }

    /// Offspring of node `n`.
    #[inline]
    pub fn offspring(&self, n: usize) -> &[u32] {
        &self.children[self.offsets[n] as usize..self.offsets[n + 1] as usize]
    }

    /// The tree of every node (its root).
    pub fn tree_of(&self) -> Vec<u32> {
        let mut tree = vec![0u32; self.num_nodes];
        for (t, x) in tree.iter_mut().enumerate().take(self.num_trees) {
            *x = t as u32;
        }
        // Parents precede their offspring in node order (level by level).
        for n in 0..self.num_nodes {
            let t = tree[n];
            for &c in self.offspring(n) {
                tree[c as usize] = t;
            }
        }
        tree
    }
}

/// Builds the CSR arrays from per-level fixed slots (`slots[n]` up to 4 children, `NONE` for
/// empty), with one more level of leaves.
fn from_slots(num_nodes: usize, num_trees: usize, slots: &[[u32; 4]], level: Vec<u8>) -> Forest {
    let mut offsets = Vec::with_capacity(num_nodes + 1);
    let mut children = Vec::with_capacity(slots.len() * 4);
    offsets.push(0u32);
    for n in 0..num_nodes {
        if let Some(s) = slots.get(n) {
            children.extend(s.iter().copied().filter(|&c| c != NONE));
        }
        offsets.push(children.len() as u32);
    }
    let levels = level.iter().map(|&l| l as usize + 1).max().unwrap_or(0);
    Forest {
        num_nodes,
        num_trees,
        offsets,
        children,
        level,
        levels,
    }
}

fn levels_of(h: &Hierarchy) -> Vec<u8> {
    let v0 = h.num_vertices(0);
    let mut level = vec![0u8; h.num_vertices(h.levels()) - v0];
    for j in 0..h.levels() {
        level[h.num_vertices(j) - v0..h.num_vertices(j + 1) - v0].fill(j as u8);
    }
    level
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Orient {
    Pl,
    Ar,
}

fn triangle_forest(h: &Hierarchy) -> Forest {
    let l = h.levels();
    let v0 = h.num_vertices(0);
    let num_nodes = h.num_vertices(l) - v0;
    let num_trees = if l == 0 { 0 } else { h.topology(0).num_edges() };
    // Slots of nodes that have offspring (levels 0..L-2).
    let parents = if l >= 2 {
        h.num_vertices(l - 1) - v0
    } else {
        0
    };
    let mut slots = vec![[NONE; 4]; parents];
    // Orientation tags of the current level's edges.
    let mut orient: Vec<Orient> =
        vec![Orient::Pl; if l > 0 { h.topology(0).num_edges() } else { 0 }];
    for j in 0..l.saturating_sub(1) {
        let t = h.topology(j);
        let tc = h.topology(j + 1);
        let base_p = h.num_vertices(j) - v0;
        let base_c = h.num_vertices(j + 1) - v0;
        let mut seen = vec![false; t.num_edges()];
        let mut next = vec![Orient::Pl; tc.num_edges()];
        for k in 0..t.num_faces() {
            let fe = t.face_edges(k);
            let ce = |child: usize, i: usize| tc.face_edges(4 * k + child)[i];
            for (i, &e) in fe.iter().enumerate().take(3) {
                let e = e as usize;
                // (v6, v11, v13) of edge i of triangle k, as level-(j+1) edges.
                let (v6, v11, v13) = match i {
                    0 => (ce(0, 0), ce(1, 2), ce(3, 1)),
                    1 => (ce(1, 0), ce(2, 2), ce(3, 2)),
                    _ => (ce(2, 0), ce(0, 2), ce(3, 0)),
                };
                let node = |x: u32| (base_c + x as usize) as u32;
                let s = &mut slots[base_p + e];
                let first = !seen[e];
                seen[e] = true;
                let o = orient[e];
                match (first, o) {
                    (true, Orient::Pl) => {
                        *s = [node(v11), node(v6), node(v13), NONE];
                        next[v11 as usize] = Orient::Pl;
                        next[v6 as usize] = Orient::Pl;
                        next[v13 as usize] = Orient::Pl;
                    }
                    (true, Orient::Ar) => {
                        *s = [node(v6), node(v11), NONE, node(v13)];
                        next[v6 as usize] = Orient::Ar;
                        next[v11 as usize] = Orient::Ar;
                        next[v13 as usize] = Orient::Ar;
                    }
                    (false, Orient::Pl) => {
                        s[3] = node(v13);
                        next[v13 as usize] = Orient::Ar;
                    }
                    (false, Orient::Ar) => {
                        s[2] = node(v13);
                        next[v13 as usize] = Orient::Pl;
                    }
                }
            }
        }
        orient = next;
    }
    from_slots(num_nodes, num_trees, &slots, levels_of(h))
}

fn quad_forest(h: &Hierarchy) -> Forest {
    let l = h.levels();
    let v0 = h.num_vertices(0);
    let num_nodes = h.num_vertices(l) - v0;
    let num_trees = if l == 0 {
        0
    } else {
        h.topology(0).num_edges() + h.topology(0).num_faces()
    };
    let parents = if l >= 2 {
        h.num_vertices(l - 1) - v0
    } else {
        0
    };
    let mut slots = vec![[NONE; 4]; parents];
    let mut face_children: Vec<Vec<u32>> = Vec::new(); // base faces (any arity)
    for j in 0..l.saturating_sub(1) {
        let t = h.topology(j);
        let tc = h.topology(j + 1);
        let base_p = h.num_vertices(j) - v0;
        let base_c = h.num_vertices(j + 1) - v0;
        let ne_c = tc.num_edges();
        let ne = t.num_edges();
        let mut filled = vec![0u8; ne];
        let mut first_child = 0usize;
        for f in 0..t.num_faces() {
            let fe = t.face_edges(f);
            let n = fe.len();
            let q = |i: usize| first_child + i; // child quad at corner i
            let mut kids = Vec::with_capacity(n);
            for (i, &e) in fe.iter().enumerate() {
                let e = e as usize;
                let s = &mut slots[base_p + e];
                let interior = tc.face_edges(q(i))[1];
                if filled[e] == 0 {
                    let half_a = tc.face_edges(q(i))[0];
                    let half_b = tc.face_edges(q((i + 1) % n))[3];
                    s[0] = (base_c + half_a as usize) as u32;
                    s[1] = (base_c + half_b as usize) as u32;
                    s[2] = (base_c + interior as usize) as u32;
                    filled[e] = 3;
                } else if filled[e] == 3 {
                    s[3] = (base_c + interior as usize) as u32;
                    filled[e] = 4;
                }
                kids.push((base_c + ne_c + q(i)) as u32);
            }
            if n <= 4 {
                let s = &mut slots[base_p + ne + f];
                s[..n].copy_from_slice(&kids);
            } else {
                // Only base faces can have more than four corners.
                face_children.resize(f + 1, Vec::new());
                face_children[f] = kids;
            }
            first_child += n;
        }
    }
    // General CSR (faces of more than four corners at level 0).
    let mut offsets = Vec::with_capacity(num_nodes + 1);
    let mut children = Vec::new();
    offsets.push(0u32);
    let ne0 = if l > 0 { h.topology(0).num_edges() } else { 0 };
    for n in 0..num_nodes {
        if let Some(s) = slots.get(n) {
            let f = n.wrapping_sub(ne0);
            match face_children.get(f) {
                Some(k) if n >= ne0 && !k.is_empty() => children.extend_from_slice(k),
                _ => children.extend(s.iter().copied().filter(|&c| c != NONE)),
            }
        }
        offsets.push(children.len() as u32);
    }
    Forest {
        num_nodes,
        num_trees,
        offsets,
        children,
        level: levels_of(h),
        levels: h.levels(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;

    fn check_partition(f: &Forest, h: &Hierarchy) {
        let v0 = h.num_vertices(0);
        let mut parent_count = vec![0u32; f.num_nodes];
        for n in 0..f.num_nodes {
            for &c in f.offspring(n) {
                parent_count[c as usize] += 1;
                assert_eq!(f.level[c as usize], f.level[n] + 1);
            }
        }
        let roots = h.num_vertices(1) - v0;
        for (n, &p) in parent_count.iter().enumerate() {
            assert_eq!(p, u32::from(n >= roots), "node {n}");
        }
    }

    #[test]
    fn triangle_forest_partitions_every_level() {
        let base = generate::icosahedron();
        let h = Hierarchy::new(&base, 3, Split::Triangles, None).unwrap();
        let f = Forest::new(&h).unwrap();
        assert_eq!(f.num_trees, 30);
        check_partition(&f, &h);
        // Closed mesh: every non-leaf has four offspring.
        for n in 0..h.num_vertices(2) - 12 {
            assert_eq!(f.offspring(n).len(), 4);
        }
        let tree = f.tree_of();
        let mut sizes = vec![0usize; 30];
        for t in tree {
            sizes[t as usize] += 1;
        }
        assert!(sizes.iter().all(|&s| s == 1 + 4 + 16));
    }

    #[test]
    fn triangle_forest_with_boundary() {
        let base = generate::triangle_grid(3);
        let h = Hierarchy::new(&base, 3, Split::Triangles, None).unwrap();
        let f = Forest::new(&h).unwrap();
        check_partition(&f, &h);
        let t0 = h.topology(0);
        for e in 0..t0.num_edges() {
            let want = if t0.is_boundary_edge(e) { 3 } else { 4 };
            assert_eq!(f.offspring(e).len(), want, "edge {e}");
        }
    }

    #[test]
    fn first_level_order_follows_algorithm_6() {
        // One triangle: edge 0 = (0,1) has offspring (v11, v6, v13) = ((m,1), (0,m), interior).
        let base = generate::triangle_grid(1);
        let h = Hierarchy::new(&base, 2, Split::Triangles, None).unwrap();
        let f = Forest::new(&h).unwrap();
        let t1 = h.topology(1);
        let v1 = h.num_vertices(1) - h.num_vertices(0);
        let f0 = &h.topology(0).face_vertices(0);
        let (a, b) = (f0[0], f0[1]);
        let m = h.num_vertices(0) as u32 + h.topology(0).face_edges(0)[0];
        let o: Vec<[u32; 2]> = f
            .offspring(h.topology(0).face_edges(0)[0] as usize)
            .iter()
            .map(|&c| t1.edge_vertices[c as usize - v1])
            .collect();
        let has =
            |e: [u32; 2], x: u32, y: u32| (e[0] == x && e[1] == y) || (e[0] == y && e[1] == x);
        assert!(has(o[0], m, b));
        assert!(has(o[1], a, m));
        assert!(!o[2].contains(&a) && !o[2].contains(&b) && !o[2].contains(&m));
    }

    #[test]
    fn quad_forest_partitions_every_level() {
        let base = generate::cube();
        let h = Hierarchy::new(&base, 3, Split::Polygons, None).unwrap();
        let f = Forest::new(&h).unwrap();
        assert_eq!(f.num_trees, 12 + 6);
        check_partition(&f, &h);
        let grid = generate::grid(2, 2, false);
        let h = Hierarchy::new(&grid, 3, Split::Polygons, None).unwrap();
        check_partition(&Forest::new(&h).unwrap(), &h);
    }
}

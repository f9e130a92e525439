//! Stencil tables: each child vertex as a weighted sum of parent vertices.
//!
//! OpenSubdiv's `Far::StencilTable` layout (sizes as offsets, indices, weights), one table per
//! level. Refinement computes child positions by applying the level's table, so re-evaluating
//! cached tables after the control points move (Maret §5.1.1, animation) gives bit-identical
//! results to refining from scratch. Any per-vertex data (colours, texture coordinates as
//! vertex-varying data) interpolates through the same tables.

use glam::DVec3;
use rayon::prelude::*;

use super::refine::Split;
use super::rules::{child_edge_sharpness, decrement, Creasing, EdgeMask, EdgeNeighborhood, Rule, Rules, Sector, VertexMask, VertexNeighborhood};
use crate::topology::Topology;

/// Child vertices per parallel work item.
const CHUNK: usize = 4096;

/// Per-vertex data that stencils can interpolate.
pub trait Interpolate: Copy + Send + Sync {
    /// The additive identity.
    fn zero() -> Self;
    /// `self += w · x`.
    fn add_scaled(&mut self, x: &Self, w: f64);
}

impl Interpolate for DVec3 {
    #[inline]
    fn zero() -> Self {
        DVec3::ZERO
    }
    #[inline]
    fn add_scaled(&mut self, x: &Self, w: f64) {
        *self += w * *x;
    }
}

impl<const N: usize> Interpolate for [f64; N] {
    #[inline]
    fn zero() -> Self {
        [0.0; N]
    }
    #[inline]
    fn add_scaled(&mut self, x: &Self, w: f64) {
        for (a, b) in self.iter_mut().zip(x) {
            *a += w * b;
        }
    }
}

impl<const N: usize> Interpolate for [f32; N] {
    #[inline]
    fn zero() -> Self {
        [0.0; N]
    }
    #[inline]
    fn add_scaled(&mut self, x: &Self, w: f64) {
        for (a, b) in self.iter_mut().zip(x) {
            *a = (*a as f64 + w * *b as f64) as f32;
        }
    }
}

/// One level's stencils: child vertex `j` is `Σ weights[k] · parent[indices[k]]` for `k` in
/// `offsets[j]..offsets[j + 1]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StencilTable {
    /// Number of parent vertices the indices refer to.
    pub num_sources: u32,
    /// Start of each child's stencil (length: children + 1).
    pub offsets: Vec<u32>,
    /// Parent vertex indices.
    pub indices: Vec<u32>,
    /// Weights, parallel to `indices`.
    pub weights: Vec<f64>,
}

impl StencilTable {
    /// Number of child vertices.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// True if the table has no stencils.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Interpolates `src` (one value per parent vertex) into a new vector of child values,
    /// in parallel.
    ///
    /// # Panics
    /// If `src.len() != self.num_sources`.
    pub fn apply<T: Interpolate>(&self, src: &[T]) -> Vec<T> {
        let mut dst = vec![T::zero(); self.len()];
        self.apply_into(src, &mut dst);
        dst
    }

    /// Like [`StencilTable::apply`], into a caller-owned buffer of `self.len()` values.
    pub fn apply_into<T: Interpolate>(&self, src: &[T], dst: &mut [T]) {
        assert_eq!(src.len(), self.num_sources as usize, "stencil source size");
        assert_eq!(dst.len(), self.len(), "stencil destination size");
        dst.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            let base = c * CHUNK;
            for (j, o) in out.iter_mut().enumerate() {
                let (a, b) = (self.offsets[base + j] as usize, self.offsets[base + j + 1] as usize);
                let mut acc = T::zero();
                for k in a..b {
                    acc.add_scaled(&src[self.indices[k] as usize], self.weights[k]);
                }
                *o = acc;
            }
        });
    }

    /// Bytes of memory held by the table.
    pub fn memory_bytes(&self) -> usize {
        4 * self.offsets.len() + 4 * self.indices.len() + 8 * self.weights.len()
    }
}

/// A stencil being assembled: merges repeated indices.
#[derive(Default)]
struct Builder {
    idx: Vec<u32>,
    w: Vec<f64>,
}

impl Builder {
    #[inline]
    fn add(&mut self, i: u32, w: f64) {
        if w == 0.0 {
            return;
        }
        if let Some(k) = self.idx.iter().position(|&x| x == i) {
            self.w[k] += w;
        } else {
            self.idx.push(i);
            self.w.push(w);
        }
    }

    fn add_centroid(&mut self, topo: &Topology, f: usize, w: f64) {
        let fv = topo.face_vertices(f);
        let wf = w / fv.len() as f64;
        for &v in fv {
            self.add(v, wf);
        }
    }
}

/// Everything a level's stencil construction needs besides the parent topology.
pub struct LevelContext<'a> {
    /// The scheme's rules.
    pub rules: &'a dyn Rules,
    /// How semi-sharp creases relax.
    pub creasing: Creasing,
    /// Parent positions (for sector angles of Biermann et al.'s corner rule).
    pub positions: &'a [DVec3],
}

/// The sector of end `v` of edge `e` (faces joined through smooth edges), for Biermann et
/// al.'s rules; `None` if `v`'s rule is not crease or corner.
fn sector(topo: &Topology, e: u32, v: u32, positions: &[DVec3]) -> Option<Sector> {
    let edges = topo.vertex_edges(v as usize);
    let sharp: Vec<f64> = edges.iter().map(|&x| topo.edge_sharpness[x as usize]).collect();
    let rule = Rule::classify(topo.vertex_sharpness[v as usize], &sharp);
    if !matches!(rule, Rule::Crease | Rule::Corner) {
        return None;
    }
    // Flood the faces around v from e's faces across smooth edges incident to v.
    let faces = topo.vertex_faces(v as usize);
    let corners = topo.vertex_face_corners(v as usize);
    let mut in_sector = vec![false; faces.len()];
    let mut stack: Vec<usize> = Vec::new();
    for &f in topo.edge_faces(e as usize) {
        if let Some(k) = faces.iter().position(|&x| x == f) {
            in_sector[k] = true;
            stack.push(k);
        }
    }
    let face_edges_at = |k: usize| {
        let f = faces[k] as usize;
        let fe = topo.face_edges(f);
        let i = corners[k] as usize;
        [fe[i], fe[(i + fe.len() - 1) % fe.len()]]
    };
    while let Some(k) = stack.pop() {
        for x in face_edges_at(k) {
            if topo.edge_sharpness[x as usize] > 0.0 {
                continue;
            }
            for (k2, done) in in_sector.iter_mut().enumerate() {
                if !*done && face_edges_at(k2).contains(&x) {
                    *done = true;
                    stack.push(k2);
                }
            }
        }
    }
    let mut count = 0;
    let mut angle = 0.0;
    let p = positions[v as usize];
    for (k, &inside) in in_sector.iter().enumerate() {
        if inside {
            count += 1;
            let fv = topo.face_vertices(faces[k] as usize);
            let i = corners[k] as usize;
            let a = positions[fv[(i + 1) % fv.len()] as usize] - p;
            let b = positions[fv[(i + fv.len() - 1) % fv.len()] as usize] - p;
            angle += a.angle_between(b);
        }
    }
    Some(Sector { rule, faces: count, angle })
}

/// Builds the stencils of one refinement level: vertex points, then edge points, then (for
/// polygon splits) face points, per the ordering contract of [`super::refine`].
pub fn level_stencils(topo: &Topology, ctx: &LevelContext) -> StencilTable {
    let nv = topo.num_vertices as usize;
    let ne = topo.num_edges();
    let nf = topo.num_faces();
    let split = ctx.rules.split();
    let n_child = nv + ne + if split == Split::Polygons { nf } else { 0 };
    let needs_sectors = ctx.rules.needs_sectors();

    let chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f64>)> = (0..n_child.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let (lo, hi) = (c * CHUNK, ((c + 1) * CHUNK).min(n_child));
            let mut sizes = Vec::with_capacity(hi - lo);
            let mut idx = Vec::with_capacity(8 * (hi - lo));
            let mut wts = Vec::with_capacity(8 * (hi - lo));
            let mut b = Builder::default();
            let (mut vm, mut vs) = (VertexMask::default(), VertexMask::default());
            let (mut em, mut es) = (EdgeMask::default(), EdgeMask::default());
            let mut sharp = Vec::new();
            let mut child_sharp = Vec::new();
            for j in lo..hi {
                b.idx.clear();
                b.w.clear();
                if j < nv {
                    let v = j;
                    let edges = topo.vertex_edges(v);
                    let faces = topo.vertex_faces(v);
                    sharp.clear();
                    sharp.extend(edges.iter().map(|&e| topo.edge_sharpness[e as usize]));
                    child_sharp.clear();
                    child_sharp.extend(sharp.iter().map(|&s| child_edge_sharpness(ctx.creasing, s, &sharp)));
                    let vsharp = topo.vertex_sharpness[v];
                    let n = VertexNeighborhood {
                        num_faces: faces.len(),
                        edge_sharpness: &sharp,
                        vertex_sharpness: vsharp,
                        child_edge_sharpness: &child_sharp,
                        child_vertex_sharpness: decrement(vsharp),
                    };
                    if edges.is_empty() {
                        b.add(v as u32, 1.0);
                    } else {
                        ctx.rules.vertex_mask(&n, &mut vm, &mut vs);
                        b.add(v as u32, vm.vertex);
                        for (i, &e) in edges.iter().enumerate() {
                            b.add(topo.other_vertex(e as usize, v as u32), vm.edges[i]);
                        }
                        for (i, &f) in faces.iter().enumerate() {
                            b.add_centroid(topo, f as usize, vm.faces[i]);
                        }
                    }
                } else if j < nv + ne {
                    let e = j - nv;
                    let [a, bb] = topo.edge_vertices[e];
                    let faces = topo.edge_faces(e);
                    let ends = if needs_sectors && topo.edge_sharpness[e] <= 0.0 {
                        [sector(topo, e as u32, a, ctx.positions), sector(topo, e as u32, bb, ctx.positions)]
                    } else {
                        [None, None]
                    };
                    let n = EdgeNeighborhood {
                        sharpness: topo.edge_sharpness[e],
                        num_faces: faces.len(),
                        face_arity: faces.first().map_or(0, |&f| topo.face_vertices(f as usize).len()),
                        ends,
                    };
                    ctx.rules.edge_mask(&n, &mut em, &mut es);
                    b.add(a, em.ends[0]);
                    b.add(bb, em.ends[1]);
                    for (i, &f) in faces.iter().enumerate() {
                        match split {
                            Split::Triangles => {
                                let opp = topo.face_vertices(f as usize).iter().copied().find(|&x| x != a && x != bb);
                                if let Some(o) = opp {
                                    b.add(o, em.faces[i]);
                                }
                            }
                            Split::Polygons => b.add_centroid(topo, f as usize, em.faces[i]),
                        }
                    }
                } else {
                    b.add_centroid(topo, j - nv - ne, 1.0);
                }
                sizes.push(b.idx.len() as u32);
                idx.extend_from_slice(&b.idx);
                wts.extend_from_slice(&b.w);
            }
            (sizes, idx, wts)
        })
        .collect();

    let total: usize = chunks.iter().map(|c| c.1.len()).sum();
    let mut table = StencilTable {
        num_sources: nv as u32,
        offsets: Vec::with_capacity(n_child + 1),
        indices: Vec::with_capacity(total),
        weights: Vec::with_capacity(total),
    };
    table.offsets.push(0);
    let mut acc = 0u32;
    for (sizes, idx, w) in chunks {
        for s in sizes {
            acc += s;
            table.offsets.push(acc);
        }
        table.indices.extend_from_slice(&idx);
        table.weights.extend_from_slice(&w);
    }
    table
}

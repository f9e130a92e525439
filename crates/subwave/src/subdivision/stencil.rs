//! Stencil tables: each child vertex as a weighted sum of parent vertices (and, for polygon
//! splits, of the child face points).
//!
//! OpenSubdiv's `Far::StencilTable` layout (sizes as offsets, indices, weights), one table per
//! level. Polygon splits (Catmull-Clark, bilinear) weigh each face through its child face
//! point, as OpenSubdiv's `Sdc` masks do for Catmull-Clark (`AreFaceWeightsForFacePoints`):
//! the face points come first, from parent vertices, and the edge and vertex points refer to
//! them ([`StencilTable::child_sources`]), so that a smooth edge point is four terms instead
//! of six and a vertex point reads no face corners. Measured on the bunny's third
//! Catmull-Clark level (2 cores): positions 71 → 55 ms, the whole refinement 121 → 111 ms. One generator turns each child's mask into (index, weight) pairs: [`level_stencils`]
//! stores them in a table, [`level_apply`] sums them at once without storing them (the path of
//! [`super::subdivide`]). Both sum the same weights in the same order, so re-evaluating cached
//! tables after the control points move (Maret §5.1.1, animation) gives bit-identical results
//! to refining from scratch. Any per-vertex data (colours, texture coordinates as
//! vertex-varying data) interpolates through the same tables.
//!
//! Masks of the common configurations (smooth interior vertices by valence, smooth edges
//! between two faces by arity) are asked of the rules once per level and reused; for those,
//! [`level_apply`] sums the very (index, weight) sequence the generator would build, with the
//! weights merged in the same order, without building it (Loop's 1-rings, Catmull-Clark's
//! quads; degenerate neighbourhoods where the generator would merge more fall back to it).
//! Quad/triangle splits ([`Split::QuadTri`]) ask every mask of the rules with the arities of
//! the incident faces ([`Rules::vertex_mask_with_arities`], [`Rules::edge_mask_with_arities`]).

use glam::DVec3;
use rayon::prelude::*;

use super::refine::Split;
use super::rules::{
    child_edge_sharpness, decrement, Creasing, EdgeMask, EdgeNeighborhood, EndRing, Rule, Rules,
    Sector, VertexMask, VertexNeighborhood,
};
use crate::par::{prefetch, Tail};
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

/// One level's stencils: child vertex `j` is `Σ weights[k] · source[indices[k]]` for `k` in
/// `offsets[j]..offsets[j + 1]`, where source `i < num_sources` is parent vertex `i` and
/// source `num_sources + i` is child `len() - child_sources + i`.
///
/// The last `child_sources` children are evaluated first, from parent vertices only; the
/// others may refer to them. Polygon splits ([`Split::Polygons`]: Catmull-Clark, bilinear)
/// use this for their face points, as OpenSubdiv's refinement does (`Sdc` masks whose face
/// weights apply to the child face points): an edge or vertex point weighs a face's point,
/// not the face's corners, which is fewer terms and the same surface. Other tables have
/// `child_sources == 0` (every index a parent vertex).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StencilTable {
    /// Number of parent vertices the indices below it refer to.
    pub num_sources: u32,
    /// Number of trailing children that other stencils may refer to (index `num_sources + i`
    /// for the `i`-th of them); 0 if every index is a parent vertex.
    pub child_sources: u32,
    /// Start of each child's stencil (length: children + 1).
    pub offsets: Vec<u32>,
    /// Source indices (parent vertices, then the trailing children).
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
    /// in parallel: the trailing [`StencilTable::child_sources`] first, then the others.
    ///
    /// # Panics
    /// If `src.len() != self.num_sources`, or if `child_sources > len()`.
    pub fn apply<T: Interpolate>(&self, src: &[T]) -> Vec<T> {
        assert_eq!(src.len(), self.num_sources as usize, "stencil source size");
        let n = self.len();
        let late = self.child_sources as usize;
        if late == 0 {
            return crate::par::par_vec(n, CHUNK, || (), |_, j| self.eval(j, src, &[]));
        }
        crate::par::par_vec_tail_first(
            n,
            late,
            CHUNK,
            || (),
            |_, k| self.eval(n - late + k, src, &[]),
            |_, j, tail| self.eval(j, src, tail),
        )
    }

    /// Child `j`'s value: its stencil applied to `src` (parent values) and `tail` (the
    /// trailing children's values), summed in stencil order.
    #[inline]
    fn eval<T: Interpolate>(&self, j: usize, src: &[T], tail: &[T]) -> T {
        let (a, b) = (self.offsets[j] as usize, self.offsets[j + 1] as usize);
        let mut acc = T::zero();
        for (&i, &w) in self.indices[a..b].iter().zip(&self.weights[a..b]) {
            acc.add_scaled(source(src, tail, i), w);
        }
        acc
    }

    /// Like [`StencilTable::apply`], into a caller-owned buffer of `self.len()` values.
    ///
    /// # Panics
    /// As [`StencilTable::apply`], or if `dst.len() != self.len()`.
    pub fn apply_into<T: Interpolate>(&self, src: &[T], dst: &mut [T]) {
        assert_eq!(src.len(), self.num_sources as usize, "stencil source size");
        assert_eq!(dst.len(), self.len(), "stencil destination size");
        assert!(
            self.child_sources as usize <= self.len(),
            "{} child sources of {} children",
            self.child_sources,
            self.len()
        );
        let head = self.len() - self.child_sources as usize;
        let (h, t) = dst.split_at_mut(head);
        t.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            let base = head + c * CHUNK;
            for (j, o) in out.iter_mut().enumerate() {
                *o = self.eval(base + j, src, &[]);
            }
        });
        let t = &*t;
        h.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            let base = c * CHUNK;
            for (j, o) in out.iter_mut().enumerate() {
                *o = self.eval(base + j, src, t);
            }
        });
    }

    /// Bytes of memory held by the table.
    pub fn memory_bytes(&self) -> usize {
        4 * self.offsets.len() + 4 * self.indices.len() + 8 * self.weights.len()
    }
}

/// Stencil source `i`: parent value `src[i]`, or past the parents the trailing child
/// `tail[i - src.len()]` ([`StencilTable::child_sources`]).
#[inline(always)]
fn source<'a, T>(src: &'a [T], tail: &'a [T], i: u32) -> &'a T {
    let i = i as usize;
    if i < src.len() {
        &src[i]
    } else {
        &tail[i - src.len()]
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
    fn clear(&mut self) {
        self.idx.clear();
        self.w.clear();
    }

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

    /// [`Builder::add`] for an index known not to be in the stencil yet (same result, no
    /// search).
    #[inline]
    fn add_new(&mut self, i: u32, w: f64) {
        debug_assert!(!self.idx.contains(&i));
        if w != 0.0 {
            self.idx.push(i);
            self.w.push(w);
        }
    }

    fn add_centroid(&mut self, topo: &Topology, f: usize, w: f64) {
        if w == 0.0 {
            // Every term would be zero and skipped.
            return;
        }
        let fv = topo.face_vertices(f);
        let wf = w / fv.len() as f64;
        for &v in fv {
            self.add(v, wf);
        }
    }

    /// `Σ w · source[i]` (parent values `src`, then the trailing children's `tail`), summed
    /// in stencil order (as [`StencilTable::apply_into`] does).
    #[inline]
    fn eval<T: Interpolate>(&self, src: &[T], tail: &[T]) -> T {
        let mut acc = T::zero();
        for (&i, &w) in self.idx.iter().zip(&self.w) {
            acc.add_scaled(source(src, tail, i), w);
        }
        acc
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
    /// The parent's [`vertex_features`] if the caller has them (the refiner derives them
    /// with the child topology, off the critical path), else `None` (computed here). Must
    /// equal `vertex_features(topo)`.
    pub features: Option<&'a [u8]>,
}

/// Per vertex of `topo`: 255 if the vertex has nonzero corner sharpness, else the number of
/// incident edges with nonzero sharpness (saturating at 255); 0 means the vertex is smooth
/// (no sector and no crease rule needed).
pub fn vertex_features(topo: &Topology) -> Vec<u8> {
    let mut features: Vec<u8> = topo
        .vertex_sharpness
        .iter()
        .map(|&s| if s != 0.0 { u8::MAX } else { 0 })
        .collect();
    for (ev, &s) in topo.edge_vertices.iter().zip(&topo.edge_sharpness) {
        if s != 0.0 {
            for &v in ev {
                features[v as usize] = features[v as usize].saturating_add(1);
            }
        }
    }
    features
}

/// The sector of end `v` of edge `e` (faces joined through smooth edges), for Biermann et
/// al.'s rules; `None` if `v`'s rule is not crease or corner.
fn sector(topo: &Topology, e: u32, v: u32, positions: &[DVec3]) -> Option<Sector> {
    let edges = topo.vertex_edges(v as usize);
    let sharp: Vec<f64> = edges
        .iter()
        .map(|&x| topo.edge_sharpness[x as usize])
        .collect();
    let rule = Rule::classify(topo.vertex_sharpness[v as usize], &sharp);
    if !matches!(rule, Rule::Crease | Rule::Corner) {
        return None;
    }
    // Flood the faces around v from e's faces across smooth edges incident to v.
    let (mut gathered, mut gathered_corners) = (Vec::new(), Vec::new());
    let (faces, corners) = if topo.has_vertex_faces() {
        (
            topo.vertex_faces(v as usize),
            topo.vertex_face_corners(v as usize),
        )
    } else {
        topo.vertex_faces_from_edges(v as usize, &mut gathered, &mut gathered_corners);
        (&gathered[..], &gathered_corners[..])
    };
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
    Some(Sector {
        rule,
        faces: count,
        angle,
    })
}

/// Largest valence whose smooth vertex mask is cached per level.
const CACHED_VALENCE: usize = 32;
/// Largest face arity whose smooth edge mask is cached per level.
const CACHED_ARITY: usize = 8;

/// Masks of the common configurations, computed once per level by the rules themselves (so
/// they are the very masks the general path would compute): a smooth interior vertex (no
/// sharp incident edge, no corner sharpness) by valence, and a smooth edge between two faces
/// whose ends are neither crease nor corner vertices, by face arity.
struct MaskCache {
    smooth_vertex: Vec<VertexMask>,
    smooth_edge: Vec<EdgeMask>,
}

impl MaskCache {
    fn new(rules: &dyn Rules) -> MaskCache {
        let zeros = [0.0; CACHED_VALENCE];
        let (mut vs, mut es) = (VertexMask::default(), EdgeMask::default());
        let smooth_vertex = (0..CACHED_VALENCE)
            .map(|n| {
                let mut m = VertexMask::default();
                rules.vertex_mask(&VertexNeighborhood::smooth(n, &zeros), &mut m, &mut vs);
                m
            })
            .collect();
        let smooth_edge = (0..CACHED_ARITY)
            .map(|a| {
                let n = EdgeNeighborhood {
                    sharpness: 0.0,
                    num_faces: 2,
                    face_arity: a,
                    ends: [None, None],
                    child_sharpness: [0.0; 2],
                };
                let mut m = EdgeMask::default();
                rules.edge_mask(&n, &mut m, &mut es);
                m
            })
            .collect();
        MaskCache {
            smooth_vertex,
            smooth_edge,
        }
    }
}

/// Direct-evaluation recipes of the common configurations for [`level_apply`]: the very
/// (index, weight) sequences [`Level::stencil`] would build for them, with the weights merged
/// in the same order, evaluated without building the stencil. Each recipe applies only where
/// the [`Builder`] would merge nothing beyond what the recipe accounts for (checked per child,
/// falling back to the general path), so the result is bit-identical.
struct Fast {
    /// Per valence: a smooth interior vertex whose mask weighs no face (Loop, butterfly,
    /// midpoint, bilinear): `(vertex, edges)`; zero weights are skipped as
    /// [`Builder::add_new`] does.
    ring_vertex: Vec<Option<(f64, Vec<f64>)>>,
    /// Per valence, for a polygon split: a smooth interior vertex with uniform nonzero edge and
    /// face weights (Catmull-Clark): the weights of the vertex, of each ring vertex and of
    /// each child face point.
    face_point_vertex: Vec<Option<[f64; 3]>>,
    /// A smooth edge between two triangles: ends and opposite vertices' weights.
    tri_edge: [f64; 4],
    /// Per face arity, for a polygon split: a smooth edge between two faces: the weights of
    /// its ends and of its two faces' points (zero weights are skipped as
    /// [`Builder::add_new`] does).
    face_point_edge: Vec<[f64; 4]>,
}

impl Fast {
    fn new(cache: &MaskCache) -> Fast {
        let ring_vertex = cache
            .smooth_vertex
            .iter()
            .map(|m| {
                m.faces
                    .iter()
                    .all(|&w| w == 0.0)
                    .then(|| (m.vertex, m.edges.clone()))
            })
            .collect();
        let face_point_vertex = cache
            .smooth_vertex
            .iter()
            .map(|m| {
                let (we, wf) = (*m.edges.first()?, *m.faces.first()?);
                let uniform = m.edges.iter().all(|&w| w == we) && m.faces.iter().all(|&w| w == wf);
                (uniform && m.vertex != 0.0 && we != 0.0 && wf != 0.0).then_some([m.vertex, we, wf])
            })
            .collect();
        let e3 = &cache.smooth_edge[3.min(CACHED_ARITY - 1)];
        let f3 = |i: usize| e3.faces.get(i).copied().unwrap_or(0.0);
        let tri_edge = [e3.ends[0], e3.ends[1], f3(0), f3(1)];
        let face_point_edge = cache
            .smooth_edge
            .iter()
            .map(|m| {
                let f = |i: usize| m.faces.get(i).copied().unwrap_or(0.0);
                [m.ends[0], m.ends[1], f(0), f(1)]
            })
            .collect();
        Fast {
            ring_vertex,
            face_point_vertex,
            tri_edge,
            face_point_edge,
        }
    }
}

/// Per-thread scratch space of [`Level::stencil`].
#[derive(Default)]
struct Scratch {
    b: Builder,
    vm: VertexMask,
    vs: VertexMask,
    em: EdgeMask,
    es: EdgeMask,
    sharp: Vec<f64>,
    child_sharp: Vec<f64>,
    /// Per edge end (rules that need rings): rotated ring sharpness and ring vertices.
    ring_sharp: [Vec<f64>; 2],
    ring_verts: [Vec<u32>; 2],

    arities: Vec<u32>,
    /// A vertex's faces and corners, gathered on a lean level (no vertex-face table).
    faces: Vec<u32>,
    corners: Vec<u16>,
    /// A vertex's edges (or a crease end's), gathered on a level without vertex relations
    /// ([`Coarser`]).
    edges: Vec<u32>,
    /// Sorting space of a gathered vertex's faces and corners.
    pairs: Vec<(u32, u16)>,
}

/// The coarser level of a polygon split's level built without vertex relations
/// ([`crate::topology::Topology::has_vertex_edges`] false): the level refined into it and the
/// halves of its edges ([`super::refine::ChildEdges::edge_halves`]), from which each vertex's
/// relations follow by the ordering contract of [`super::refine`]. A child face `offset_F +
/// i` of coarser face `F` is `(v_i, m_i, c, m_{i-1})` with edges `(v_i m_i, m_i c, c m_{i-1},
/// m_{i-1} v_i)`: its second edge is the spoke at `m_i`.
#[derive(Clone, Copy)]
pub(crate) struct Coarser<'a> {
    /// The coarser level (rings not ordered: its vertex faces ascend).
    pub(crate) topo: &'a Topology,
    /// Per coarser edge, its child halves at its ends 0 and 1.
    pub(crate) halves: &'a [[u32; 2]],
}

/// One level's stencil generator: the single place that turns masks into (index, weight)
/// pairs, shared by the table builder ([`level_stencils`]) and the direct evaluation
/// ([`level_apply`]), so that both sum the same weights in the same order.
struct Level<'a> {
    topo: &'a Topology,
    ctx: &'a LevelContext<'a>,
    cache: MaskCache,
    split: Split,
    /// [`Split::QuadTri`]: the parent quads, whose face points follow the edge points.
    quads: Vec<u32>,
    needs_sectors: bool,
    needs_rings: bool,
    /// [`vertex_features`] of `topo`.
    features: std::borrow::Cow<'a, [u8]>,
    /// `topo` has its vertex-face table (else it is a lean level: see
    /// [`Topology::from_edges_counted`]).
    vertex_faces: bool,
    fast: Fast,
    nv: usize,
    ne: usize,
    n_child: usize,
    /// Set when `topo` has no vertex relations: they are read from the coarser level.
    coarser: Option<Coarser<'a>>,
}

impl<'a> Level<'a> {
    fn new(topo: &'a Topology, ctx: &'a LevelContext<'a>, coarser: Option<Coarser<'a>>) -> Self {
        assert_eq!(
            coarser.is_some(),
            !topo.has_vertex_edges(),
            "a level without vertex relations needs its coarser level, and only it"
        );
        if let Some(c) = &coarser {
            assert!(
                !c.topo.rings_ordered && ctx.rules.split() == Split::Polygons,
                "the coarser level of a polygon split, with its vertex faces in face order"
            );
        }
        let nv = topo.num_vertices as usize;
        let ne = topo.num_edges();
        let split = ctx.rules.split();
        let n_child = super::refine::child_vertex_count(topo, split);
        let quads = if split == Split::QuadTri {
            (0..topo.num_faces() as u32)
                .filter(|&f| topo.face_vertices(f as usize).len() == 4)
                .collect()
        } else {
            Vec::new()
        };
        let features = match ctx.features {
            Some(f) => {
                debug_assert!(
                    f == vertex_features(topo),
                    "features given for another level"
                );
                std::borrow::Cow::Borrowed(f)
            }
            None => std::borrow::Cow::Owned(vertex_features(topo)),
        };
        let cache = MaskCache::new(ctx.rules);
        Level {
            topo,
            quads,
            features,
            vertex_faces: topo.has_vertex_faces(),
            ctx,
            fast: Fast::new(&cache),
            cache,
            split,
            needs_sectors: ctx.rules.needs_sectors(),
            needs_rings: ctx.rules.needs_rings(),
            nv,
            ne,
            n_child,
            coarser,
        }
    }

    /// The edges of vertex `v` (ascending) into `edges`, and its faces (ascending) with its
    /// corner in each into `pairs`, on a level without vertex relations, from the coarser
    /// level `c` (see [`Coarser`]): what the counting sorts of
    /// [`Topology::from_edges_counted`] would have listed.
    fn gather(&self, c: &Coarser, v: usize, edges: &mut Vec<u32>, pairs: &mut Vec<(u32, u16)>) {
        let (p, topo) = (c.topo, self.topo);
        let (nvp, nep) = (p.num_vertices as usize, p.num_edges());
        edges.clear();
        pairs.clear();
        let spoke = |child: u32| topo.face_edges(child as usize)[1];
        if v < nvp {
            // A coarser vertex: one half per coarser edge, one corner child per coarser face.
            for &e in p.vertex_edges(v) {
                let end = usize::from(p.edge_vertices[e as usize][0] != v as u32);
                edges.push(c.halves[e as usize][end]);
            }
            for (&f, &k) in p.vertex_faces(v).iter().zip(p.vertex_face_corners(v)) {
                pairs.push((p.face_offsets[f as usize] + u32::from(k), 0));
            }
        } else if v < nvp + nep {
            // An edge point: the two halves, and per coarser face the spoke of the child at
            // the edge's corner, which with the next child holds the point (corners 1, 3).
            let e = v - nvp;
            edges.extend_from_slice(&c.halves[e]);
            for &f in p.edge_faces(e) {
                let fe = p.face_edges(f as usize);
                let i = fe.iter().position(|&x| x as usize == e).unwrap_or(0);
                let o = p.face_offsets[f as usize];
                let next = if i + 1 == fe.len() { 0 } else { i + 1 };
                edges.push(spoke(o + i as u32));
                pairs.push((o + i as u32, 1));
                pairs.push((o + next as u32, 3));
            }
        } else {
            // A face point: the spokes of the face's children, corner 2 of each.
            let f = v - nvp - nep;
            let o = p.face_offsets[f];
            for k in 0..p.face_vertices(f).len() as u32 {
                edges.push(spoke(o + k));
                pairs.push((o + k, 2));
            }
        }
        edges.sort_unstable();
        pairs.sort_unstable();
    }

    /// Vertex child `v`'s value on a level without vertex relations, by the coarser level's
    /// recipe of a smooth interior Catmull-Clark vertex (the vertex, its ring in ascending
    /// edge order, the points of its faces in ascending order: the sequence
    /// [`Level::stencil`] builds from the gathered relations), or `None`.
    #[inline(always)]
    fn coarser_vertex<T: Interpolate>(
        &self,
        c: &Coarser,
        v: usize,
        src: &[T],
        tail: &[T],
    ) -> Option<T> {
        if self.features[v] != 0 || tail.is_empty() {
            return None;
        }
        let p = c.topo;
        let (nvp, nep) = (p.num_vertices as usize, p.num_edges());
        let mut acc = T::zero();
        if v < nvp {
            let edges = p.vertex_edges(v);
            let faces = p.vertex_faces(v);
            let n = edges.len();
            if n == 0 || n != faces.len() || n >= CACHED_VALENCE {
                return None;
            }
            let [wv, wr, wf] = self.fast.face_point_vertex[n]?;
            let mut ring = [(0u32, 0u32); CACHED_VALENCE];
            for (r, &e) in ring.iter_mut().zip(edges) {
                let end = usize::from(p.edge_vertices[e as usize][0] != v as u32);
                *r = (c.halves[e as usize][end], nvp as u32 + e);
            }
            let ring = &mut ring[..n];
            // Insertion sort: rings are short and nearly sorted.
            for i in 1..n {
                let mut k = i;
                while k > 0 && ring[k - 1].0 > ring[k].0 {
                    ring.swap(k - 1, k);
                    k -= 1;
                }
            }
            acc.add_scaled(&src[v], wv);
            for &(_, r) in ring.iter() {
                acc.add_scaled(&src[r as usize], wr);
            }
            for (&f, &k) in faces.iter().zip(p.vertex_face_corners(v)) {
                acc.add_scaled(&tail[first_corner(p, f as usize) + k as usize], wf);
            }
        } else if v < nvp + nep {
            let e = v - nvp;
            let ef = p.edge_faces(e);
            if ef.len() != 2 {
                return None;
            }
            let [wv, wr, wf] = self.fast.face_point_vertex[4]?;
            let [a, b] = p.edge_vertices[e];
            let [ha, hb] = c.halves[e];
            let (f0, f1) = (ef[0] as usize, ef[1] as usize);
            let (c0, c1) = (nvp + nep + f0, nvp + nep + f1);
            // The halves and the first face's spoke are numbered in that face's scan: the half
            // at end 0 first unless the edge closes the face (then its spoke comes first and
            // the half at end 1 before the one at end 0); the second face's spoke comes last.
            let ring = if ha < hb {
                [a as usize, c0, b as usize, c1]
            } else {
                [c0, b as usize, a as usize, c1]
            };
            let children = |f: usize| {
                let fe = p.face_edges(f);
                let e = e as u32;
                let i = if let [x0, x1, x2, x3] = *fe {
                    // A quad (every level after the first): its edges are distinct.
                    debug_assert!([x0, x1, x2, x3].contains(&e));
                    usize::from(x1 == e) + 2 * usize::from(x2 == e) + 3 * usize::from(x3 == e)
                } else {
                    fe.iter().position(|&x| x == e).unwrap_or(0)
                };
                let o = first_corner(p, f);
                if i + 1 == fe.len() {
                    [o, o + i]
                } else {
                    [o + i, o + i + 1]
                }
            };
            let ([x0, x1], [y0, y1]) = (children(f0), children(f1));
            acc.add_scaled(&src[v], wv);
            for r in ring {
                acc.add_scaled(&src[r], wr);
            }
            for f in [x0, x1, y0, y1] {
                acc.add_scaled(&tail[f], wf);
            }
        } else {
            let f = v - nvp - nep;
            let fe = p.face_edges(f);
            let n = fe.len();
            if !(3..CACHED_VALENCE).contains(&n) {
                return None;
            }
            let [wv, wr, wf] = self.fast.face_point_vertex[n]?;
            let o = first_corner(p, f);
            // Spokes in scan order: at m_0, at m_{n-1} (the first face's closing spoke), then
            // at m_1 .. m_{n-2}.
            acc.add_scaled(&src[v], wv);
            acc.add_scaled(&src[nvp + fe[0] as usize], wr);
            acc.add_scaled(&src[nvp + fe[n - 1] as usize], wr);
            for &x in &fe[1..n - 1] {
                acc.add_scaled(&src[nvp + x as usize], wr);
            }
            for k in 0..n {
                acc.add_scaled(&tail[o + k], wf);
            }
        }
        Some(acc)
    }

    /// Number of trailing children the other stencils refer to ([`StencilTable::child_sources`]):
    /// the face points of a polygon split, none for the other splits.
    fn child_sources(&self) -> usize {
        if self.split == Split::Polygons {
            self.n_child - self.nv - self.ne
        } else {
            0
        }
    }

    /// Adds face `f` weighed `w` to a stencil: its child face point (source `nv + f`) for a
    /// polygon split, else its centroid over its corners (a quad/triangle split's triangles
    /// have no face point; its quads' face points are not sources, keeping one rule).
    #[inline]
    fn add_face(&self, b: &mut Builder, f: u32, w: f64) {
        if self.split == Split::Polygons {
            // Distinct faces have distinct points, and no point is a parent vertex.
            b.add_new(self.nv as u32 + f, w);
        } else {
            b.add_centroid(self.topo, f as usize, w);
        }
    }

    /// True if `v` is certainly neither a crease nor a corner vertex (no sector needed): no
    /// corner sharpness and fewer than two sharp edges.
    #[inline]
    fn no_sector(&self, v: u32) -> bool {
        self.features[v as usize] < 2
    }

    /// The stencil of child vertex `j`, into `s.b`: vertex points, then edge points, then
    /// (polygon splits) face points, per the ordering contract of [`super::refine`].
    fn stencil(&self, j: usize, s: &mut Scratch) {
        let topo = self.topo;
        let (nv, ne) = (self.nv, self.ne);
        s.b.clear();
        if j < nv {
            let v = j;
            let (edges, faces) = if let Some(c) = &self.coarser {
                self.gather(c, v, &mut s.edges, &mut s.pairs);
                s.faces.clear();
                s.faces.extend(s.pairs.iter().map(|&(f, _)| f));
                (&s.edges[..], &s.faces[..])
            } else if self.vertex_faces {
                (topo.vertex_edges(v), topo.vertex_faces(v))
            } else {
                topo.vertex_faces_from_edges(v, &mut s.faces, &mut s.corners);
                (topo.vertex_edges(v), &s.faces[..])
            };
            if edges.is_empty() {
                s.b.add(v as u32, 1.0);
                return;
            }
            let vsharp = topo.vertex_sharpness[v];
            let mixed = self.split == Split::QuadTri;
            let smooth = self.features[v] == 0
                && edges.len() == faces.len()
                && edges.len() < CACHED_VALENCE
                && !mixed;
            let mask = if smooth {
                &self.cache.smooth_vertex[edges.len()]
            } else {
                s.sharp.clear();
                s.sharp
                    .extend(edges.iter().map(|&e| topo.edge_sharpness[e as usize]));
                s.child_sharp.clear();
                s.child_sharp.extend(
                    s.sharp
                        .iter()
                        .map(|&x| child_edge_sharpness(self.ctx.creasing, x, &s.sharp)),
                );
                let n = VertexNeighborhood {
                    num_faces: faces.len(),
                    edge_sharpness: &s.sharp,
                    vertex_sharpness: vsharp,
                    child_edge_sharpness: &s.child_sharp,
                    child_vertex_sharpness: decrement(vsharp),
                };
                if mixed {
                    s.arities.clear();
                    s.arities.extend(
                        faces
                            .iter()
                            .map(|&f| topo.face_vertices(f as usize).len() as u32),
                    );
                    self.ctx
                        .rules
                        .vertex_mask_with_arities(&n, &s.arities, &mut s.vm, &mut s.vs);
                } else {
                    self.ctx.rules.vertex_mask(&n, &mut s.vm, &mut s.vs);
                }
                &s.vm
            };
            // The vertex and its neighbours are distinct (no two edges join the same vertices);
            // face centroids may repeat them.
            s.b.add_new(v as u32, mask.vertex);
            for (i, &e) in edges.iter().enumerate() {
                s.b.add_new(topo.other_vertex(e as usize, v as u32), mask.edges[i]);
            }
            for (i, &f) in faces.iter().enumerate() {
                self.add_face(&mut s.b, f, mask.faces[i]);
            }
        } else if j < nv + ne {
            let e = j - nv;
            let [a, b] = topo.edge_vertices[e];
            let faces = topo.edge_faces(e);
            let sharpness = topo.edge_sharpness[e];
            let face_arity = faces
                .first()
                .map_or(0, |&f| topo.face_vertices(f as usize).len());
            if self.needs_rings {
                self.ring_edge_stencil(e, s);
                return;
            }

            let mixed = self.split == Split::QuadTri;
            let cached = sharpness == 0.0
                && !mixed
                && faces.len() == 2
                && face_arity < CACHED_ARITY
                && (!self.needs_sectors || self.no_sector(a) && self.no_sector(b));
            let mask = if cached {
                &self.cache.smooth_edge[face_arity]
            } else {
                let ends = if self.needs_sectors && sharpness <= 0.0 {
                    let p = self.ctx.positions;
                    [sector(topo, e as u32, a, p), sector(topo, e as u32, b, p)]
                } else {
                    [None, None]
                };
                let child_sharpness = if sharpness > 0.0 && self.ctx.creasing == Creasing::Chaikin {
                    [a, b].map(|w| {
                        let ends = match &self.coarser {
                            Some(c) => {
                                self.gather(c, w as usize, &mut s.edges, &mut s.pairs);
                                &s.edges[..]
                            }
                            None => topo.vertex_edges(w as usize),
                        };
                        s.sharp.clear();
                        s.sharp
                            .extend(ends.iter().map(|&x| topo.edge_sharpness[x as usize]));
                        child_edge_sharpness(self.ctx.creasing, sharpness, &s.sharp)
                    })
                } else {
                    [decrement(sharpness); 2]
                };
                let n = EdgeNeighborhood {
                    sharpness,
                    num_faces: faces.len(),
                    face_arity,
                    ends,
                    child_sharpness,
                };
                if mixed {
                    s.arities.clear();
                    s.arities.extend(
                        faces
                            .iter()
                            .map(|&f| topo.face_vertices(f as usize).len() as u32),
                    );
                    self.ctx
                        .rules
                        .edge_mask_with_arities(&n, &s.arities, &mut s.em, &mut s.es);
                } else {
                    self.ctx.rules.edge_mask(&n, &mut s.em, &mut s.es);
                }
                &s.em
            };
            s.b.add_new(a, mask.ends[0]);
            s.b.add_new(b, mask.ends[1]);
            for (i, &f) in faces.iter().enumerate() {
                // Triangles weigh their vertex opposite the edge, polygons their centroid.
                let opposite = match self.split {
                    Split::Triangles => true,
                    Split::Polygons => false,
                    Split::QuadTri => topo.face_vertices(f as usize).len() == 3,
                };
                if opposite {
                    let opp = topo
                        .face_vertices(f as usize)
                        .iter()
                        .copied()
                        .find(|&x| x != a && x != b);
                    if let Some(o) = opp {
                        s.b.add(o, mask.faces[i]);
                    }
                } else {
                    self.add_face(&mut s.b, f, mask.faces[i]);
                }
            }
        } else {
            // A face's vertices are distinct.
            let f = if self.split == Split::QuadTri {
                self.quads[j - nv - ne] as usize
            } else {
                j - nv - ne
            };
            let fv = topo.face_vertices(f);
            let wf = 1.0 / fv.len() as f64;
            for &v in fv {
                s.b.add_new(v, wf);
            }
        }
    }
}

/// The end of edge `e` other than `v`, which must be one of its ends (as
/// [`Topology::other_vertex`], without a branch: the fast paths' ring edges are unpredictable).
#[inline(always)]
fn other_end(topo: &Topology, e: usize, v: u32) -> u32 {
    let [a, b] = topo.edge_vertices[e];
    debug_assert!(a == v || b == v, "vertex {v} is not an end of edge {e}");
    a ^ b ^ v
}

/// The first corner of face `f` in `face_vertices` / `face_edges` (no table read on a level
/// of one face arity).
#[inline(always)]
fn first_corner(topo: &Topology, f: usize) -> usize {
    match topo.face_arity as usize {
        0 => topo.face_offsets[f] as usize,
        a => a * f,
    }
}

impl Level<'_> {
    /// Prefetches for [`level_apply_from_coarser`]'s vertex points (see [`Level::prefetch`]):
    /// the coarser tables that locate the sources of vertex child `far`, the sources of
    /// vertex child `near` (children past the vertex points are ignored).
    #[inline(always)]
    fn prefetch_coarser<T>(&self, c: &Coarser, far: usize, near: usize, src: &[T], tail: &[T]) {
        let p = c.topo;
        let (nvp, nep) = (p.num_vertices as usize, p.num_edges());
        if far < nvp {
            for &e in p.vertex_edges(far) {
                prefetch(c.halves.get(e as usize));
                prefetch(p.edge_vertices.get(e as usize));
            }
        } else if far < nvp + nep {
            let e = far - nvp;
            prefetch(c.halves.get(e));
            for &f in p.edge_faces(e) {
                prefetch(p.face_edges.get(first_corner(p, f as usize)));
            }
        }
        if near < nvp {
            for &e in p.vertex_edges(near) {
                prefetch(src.get(nvp + e as usize));
            }
            for (&f, &k) in p.vertex_faces(near).iter().zip(p.vertex_face_corners(near)) {
                prefetch(tail.get(first_corner(p, f as usize) + k as usize));
            }
        } else if near < nvp + nep {
            let e = near - nvp;
            let [a, b] = p.edge_vertices[e];
            prefetch(src.get(a as usize));
            prefetch(src.get(b as usize));
            for &f in p.edge_faces(e) {
                prefetch(src.get(nvp + nep + f as usize));
                let o = first_corner(p, f as usize);
                prefetch(tail.get(o));
                prefetch(tail.get(o + 2));
            }
        } else if near < self.nv {
            let f = near - nvp - nep;
            for &x in p.face_edges(f) {
                prefetch(src.get(nvp + x as usize));
            }
        }
    }

    /// Prefetches (a hint, no effect on results) for [`level_apply`]: the table entries that
    /// locate the sources of vertex or edge child `far` (its ring edges' ends, its edge's
    /// faces' corners), and the source values of child `near`, from the parent's `src` and the
    /// trailing children's `tail`. Children past the vertex and edge points are ignored.
    #[inline(always)]
    fn prefetch<T>(&self, far: usize, near: usize, src: &[T], tail: &[T]) {
        let topo = self.topo;
        let (nv, ne) = (self.nv, self.ne);
        let lean = self.coarser.as_ref();
        if let Some(c) = lean {
            // No vertex relations here: the vertex children's come from the coarser level.
            self.prefetch_coarser(c, far, near, src, tail);
        }
        if far < nv {
            if lean.is_none() {
                for &e in topo.vertex_edges(far) {
                    prefetch(topo.edge_vertices.get(e as usize));
                }
            }
        } else if far < nv + ne && self.split == Split::Triangles {
            for &f in topo.edge_faces(far - nv) {
                prefetch(topo.face_vertices.get(3 * f as usize));
            }
        }
        if near < nv {
            if lean.is_none() {
                for &e in topo.vertex_edges(near) {
                    let [a, b] = topo.edge_vertices[e as usize];
                    prefetch(src.get((a ^ b ^ near as u32) as usize));
                }
                if self.vertex_faces && !tail.is_empty() {
                    for &f in topo.vertex_faces(near) {
                        prefetch(tail.get(f as usize));
                    }
                }
            }
        } else if near < nv + ne {
            let e = near - nv;
            let [a, b] = topo.edge_vertices[e];
            prefetch(src.get(a as usize));
            prefetch(src.get(b as usize));
            for &f in topo.edge_faces(e) {
                if self.split == Split::Triangles {
                    if let Some(fv) = topo.face_vertices.get(3 * f as usize..3 * f as usize + 3) {
                        let o = fv[0] ^ fv[1] ^ fv[2] ^ a ^ b;
                        prefetch(src.get(o as usize));
                    }
                } else {
                    prefetch(tail.get(f as usize));
                }
            }
        }
    }

    /// Prefetches the corners' values of face point `j` (a child past the vertex and edge
    /// points; others are ignored) for [`level_apply`].
    #[inline(always)]
    fn prefetch_face<T>(&self, j: usize, src: &[T]) {
        if let Some(f) = j.checked_sub(self.nv + self.ne) {
            if f < self.topo.num_faces() {
                for &v in self.topo.face_vertices(f) {
                    prefetch(src.get(v as usize));
                }
            }
        }
    }

    /// Child `j`'s value by a [`Fast`] recipe, bit-identical to evaluating
    /// [`Level::stencil`] on the parent values `src` and the trailing children's values
    /// `tail` ([`Level::child_sources`]; empty while they are computed); `None` where no
    /// recipe applies.
    #[inline(always)]
    fn fast_value<T: Interpolate>(&self, j: usize, src: &[T], tail: &[T]) -> Option<T> {
        let topo = self.topo;
        let (nv, ne) = (self.nv, self.ne);
        if j < nv {
            if let Some(c) = &self.coarser {
                return self.coarser_vertex(c, j, src, tail);
            }
        }
        let mut acc = T::zero();
        if j < nv {
            let v = j;
            if self.features[v] != 0 || self.split == Split::QuadTri {
                return None;
            }
            let (ea, eb) = (
                topo.vertex_edge_offsets[v] as usize,
                topo.vertex_edge_offsets[v + 1] as usize,
            );
            let (fa, fb) = (
                topo.vertex_face_offsets[v] as usize,
                topo.vertex_face_offsets[v + 1] as usize,
            );
            let n = eb - ea;
            if n == 0 || n != fb - fa || n >= CACHED_VALENCE {
                return None;
            }
            let edges = &topo.vertex_edges[ea..eb];
            if let Some((wv, we)) = &self.fast.ring_vertex[n] {
                if *wv != 0.0 {
                    acc.add_scaled(&src[v], *wv);
                }
                for (&e, &w) in edges.iter().zip(we) {
                    if w != 0.0 {
                        let r = other_end(topo, e as usize, v as u32);
                        acc.add_scaled(&src[r as usize], w);
                    }
                }
                return Some(acc);
            }
            // (Reading the ring from the faces, the next corner in each, instead of through the
            // edges was measured 3 ms slower on the bunny's third Catmull-Clark level.)
            // The vertex, its ring (distinct: no two edges join the same vertices), then the
            // points of its faces.
            let [wv, wr, wf] = self.fast.face_point_vertex[n]?;
            if self.split != Split::Polygons || !self.vertex_faces {
                return None;
            }
            acc.add_scaled(&src[v], wv);
            for &e in edges {
                let r = other_end(topo, e as usize, v as u32);
                acc.add_scaled(&src[r as usize], wr);
            }
            for &f in &topo.vertex_faces[fa..fb] {
                acc.add_scaled(&tail[f as usize], wf);
            }
            Some(acc)
        } else if j < nv + ne {
            let e = j - nv;
            let (fa, fb) = (
                topo.edge_face_offsets[e] as usize,
                topo.edge_face_offsets[e + 1] as usize,
            );
            if fb - fa != 2 || topo.edge_sharpness[e] != 0.0 || self.needs_rings {
                return None;
            }
            let [a, b] = topo.edge_vertices[e];
            if self.needs_sectors && !(self.no_sector(a) && self.no_sector(b)) {
                return None;
            }
            let (f0, f1) = (
                topo.edge_faces[fa] as usize,
                topo.edge_faces[fa + 1] as usize,
            );
            match self.split {
                Split::Polygons => {
                    let arity = topo.face_vertices(f0).len();
                    let [wa, wb, w0, w1] = *self.fast.face_point_edge.get(arity)?;
                    for (x, w) in [(&src[a as usize], wa), (&src[b as usize], wb)] {
                        if w != 0.0 {
                            acc.add_scaled(x, w);
                        }
                    }
                    for (f, w) in [(f0, w0), (f1, w1)] {
                        if w != 0.0 {
                            acc.add_scaled(&tail[f], w);
                        }
                    }
                    Some(acc)
                }
                Split::Triangles => {
                    // The corner opposite edge `e = ab` in triangle `f`: its three distinct
                    // corners sum to `a + b + opposite` (wrapping arithmetic is exact on `u32`).
                    let opposite = |f: usize| {
                        let fv = &topo.face_vertices[3 * f..3 * f + 3];
                        fv[0]
                            .wrapping_add(fv[1])
                            .wrapping_add(fv[2])
                            .wrapping_sub(a)
                            .wrapping_sub(b)
                    };
                    if topo.face_arity != 3 {
                        return None;
                    }
                    let [wa, wb, w0, w1] = self.fast.tri_edge;
                    let (o0, o1) = (opposite(f0), opposite(f1));
                    if o0 == o1 && w0 != 0.0 && w1 != 0.0 {
                        return None;
                    }
                    for (x, w) in [(a, wa), (b, wb), (o0, w0), (o1, w1)] {
                        if w != 0.0 {
                            acc.add_scaled(&src[x as usize], w);
                        }
                    }
                    Some(acc)
                }
                Split::QuadTri => None,
            }
        } else if self.split != Split::QuadTri {
            let fv = topo.face_vertices(j - nv - ne);
            let wf = 1.0 / fv.len() as f64;
            for &v in fv {
                acc.add_scaled(&src[v as usize], wf);
            }
            Some(acc)
        } else {
            None
        }
    }

    /// The stencil of the edge point of `e` for rules that see the ends' ordered 1-rings
    /// ([`Rules::needs_rings`]): ends, opposite vertices, then each end's ring weights.
    fn ring_edge_stencil(&self, e: usize, s: &mut Scratch) {
        let topo = self.topo;
        debug_assert!(topo.rings_ordered, "rules need ordered 1-rings");
        let ends = topo.edge_vertices[e];
        let faces = topo.edge_faces(e);
        for (k, &v) in ends.iter().enumerate() {
            let edges = topo.vertex_edges(v as usize);
            let at = edges.iter().position(|&x| x as usize == e).unwrap_or(0);
            let n = edges.len();
            s.ring_sharp[k].clear();
            s.ring_verts[k].clear();
            for j in 0..n {
                let x = edges[(at + j) % n] as usize;
                s.ring_sharp[k].push(topo.edge_sharpness[x]);
                s.ring_verts[k].push(topo.other_vertex(x, v));
            }
        }
        let n = EdgeNeighborhood {
            sharpness: topo.edge_sharpness[e],
            num_faces: faces.len(),
            face_arity: faces
                .first()
                .map_or(0, |&f| topo.face_vertices(f as usize).len()),
            ends: [None, None],
            child_sharpness: [decrement(topo.edge_sharpness[e]); 2],
        };
        let rings = [0, 1].map(|k| EndRing {
            sharpness: &s.ring_sharp[k],
            vertex_sharpness: topo.vertex_sharpness[ends[k] as usize],
            num_faces: (topo.vertex_face_offsets[ends[k] as usize + 1]
                - topo.vertex_face_offsets[ends[k] as usize]) as usize,
        });
        self.ctx
            .rules
            .edge_mask_with_rings(&n, &rings, &mut s.em, &mut s.es);
        let m = &s.em;
        s.b.add_new(ends[0], m.ends[0]);
        s.b.add_new(ends[1], m.ends[1]);
        for (i, &f) in faces.iter().enumerate() {
            let w = m.faces.get(i).copied().unwrap_or(0.0);
            match self.split {
                Split::Triangles => {
                    let opp = topo
                        .face_vertices(f as usize)
                        .iter()
                        .copied()
                        .find(|&x| x != ends[0] && x != ends[1]);
                    if let Some(o) = opp {
                        s.b.add(o, w);
                    }
                }
                Split::Polygons | Split::QuadTri => self.add_face(&mut s.b, f, w),
            }
        }
        for k in 0..2 {
            for (&v, &w) in s.ring_verts[k].iter().zip(&m.rings[k]) {
                s.b.add(v, w);
            }
        }
    }
}

/// Builds the stencils of one refinement level: vertex points, then edge points, then (for
/// polygon splits) face points, per the ordering contract of [`super::refine`].
///
/// Two passes over the children, in parallel: the first computes every stencil for its size
/// only (the offsets), the second computes it again into its place in the table, allocated
/// once at its exact size. Computing each stencil twice costs less than buffering the table
/// per chunk and copying it, which doubled the memory the build touched: on this 2-core VM a
/// first-touched page costs more than computing a stencil (the bunny's three Catmull-Clark
/// levels: the build spent 85% of its time in the kernel zeroing fresh pages).
pub fn level_stencils(topo: &Topology, ctx: &LevelContext) -> StencilTable {
    let level = Level::new(topo, ctx, None);
    let n_child = level.n_child;
    let mut offsets = vec![0u32; n_child + 1];
    offsets[1..]
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each_init(Scratch::default, |s, (c, sizes)| {
            for (k, size) in sizes.iter_mut().enumerate() {
                level.stencil(c * CHUNK + k, s);
                *size = s.b.idx.len() as u32;
            }
        });
    for j in 0..n_child {
        offsets[j + 1] += offsets[j];
    }
    let total = offsets[n_child] as usize;
    let mut indices = vec![0u32; total];
    let mut weights = vec![0.0f64; total];
    // Each chunk's slice of the table, cut at its children's offsets.
    let mut parts = Vec::with_capacity(n_child.div_ceil(CHUNK));
    let (mut idx_rest, mut w_rest) = (&mut indices[..], &mut weights[..]);
    for lo in (0..n_child).step_by(CHUNK) {
        let hi = (lo + CHUNK).min(n_child);
        let len = (offsets[hi] - offsets[lo]) as usize;
        let (i, ir) = std::mem::take(&mut idx_rest).split_at_mut(len);
        let (w, wr) = std::mem::take(&mut w_rest).split_at_mut(len);
        parts.push((lo..hi, i, w));
        (idx_rest, w_rest) = (ir, wr);
    }
    parts
        .into_par_iter()
        .for_each_init(Scratch::default, |s, (children, idx, w)| {
            let mut at = 0;
            for j in children {
                level.stencil(j, s);
                let n = s.b.idx.len();
                debug_assert_eq!(n as u32, offsets[j + 1] - offsets[j], "stencil {j}");
                idx[at..at + n].copy_from_slice(&s.b.idx);
                w[at..at + n].copy_from_slice(&s.b.w);
                at += n;
            }
        });
    StencilTable {
        num_sources: level.nv as u32,
        child_sources: level.child_sources() as u32,
        offsets,
        indices,
        weights,
    }
}

/// The child level's values computed directly from the parent's `src`, without storing the
/// stencils: bit-identical to `level_stencils(topo, ctx).apply(src)` (same stencils, summed
/// in the same order).
///
/// # Panics
/// If `src.len()` is not the parent's vertex count.
pub fn level_apply<T: Interpolate>(topo: &Topology, ctx: &LevelContext, src: &[T]) -> Vec<T> {
    apply(topo, ctx, src, None, None)
}

/// [`level_apply`] on a level of a polygon split built without vertex relations
/// ([`super::refine::refine_topology_without_vertex_relations`]), whose vertices' relations
/// are read from the `coarser` level; bit-identical to [`level_apply`] on the same level with
/// its relations. `early`, if given, are the values computed already
/// ([`grandchild_points`] of the coarser level: the face points, perhaps with a range of
/// vertex points), which it finishes.
///
/// # Panics
/// If `src.len()` is not `topo`'s vertex count, if `topo` has vertex relations, if the rules
/// do not split polygons or the coarser level's rings are ordered (its vertex faces must be in
/// face order, as the refiner leaves them past level 0), or if `early` was sized for
/// another level.
pub(crate) fn level_apply_from_coarser<T: Interpolate>(
    topo: &Topology,
    ctx: &LevelContext,
    src: &[T],
    coarser: Coarser,
    early: Option<Tail<T>>,
) -> Vec<T> {
    apply(topo, ctx, src, Some(coarser), early)
}

/// The face points of the level after the child of `parent`, a quad mesh refined by a polygon
/// split (whose face points are centroids), from `child` (the child level's values) and
/// `parent`'s tables alone, before the child's topology exists: the tail of the grandchild
/// level's values, for [`level_apply_from_coarser`] (the child being the level without vertex
/// relations, whose coarser level is `parent`) to finish. Bit-identical to the face points it
/// would compute: by the ordering contract of [`super::refine`], child face `4k + i` of
/// parent quad `k` is `(v_i, m_i, c, m_{i-1})`, and its face point sums a quarter of each
/// corner in that order, from zero. With them, where `rules` have the smooth recipe
/// ([`has_coarser_recipes`]), the grandchild points of the child's face points (the range
/// `V + E..V + E + F` of the grandchild level; smooth valence-4 vertices whose spokes and
/// faces follow from the contract, summed as `Level::coarser_vertex` sums them). `None`
/// unless `rules` split polygons and `parent` is a quad mesh.
///
/// `subdivide` computes them with the child's values, while the child's topology (the longer
/// task of that level) is still being built. The bunny's third Catmull-Clark level, medians of
/// 21 runs in four alternations: the face points, 77.1–78.0 → 72.1–73.1 ms (level 1 → 2
/// unchanged at 24–25 ms, its values 14 → 19 ms; level 2 → 3 34 → 31–32 ms); the vertex
/// points of the child's face points besides, 75.1–76.4 → 72.2–73.6 ms.
///
/// # Panics
/// If `child.len()` is not the child level's vertex count (`parent`'s vertices, edges and
/// faces).
pub(crate) fn grandchild_points<T: Interpolate>(
    parent: &Topology,
    rules: &dyn Rules,
    child: &[T],
) -> Option<Tail<T>> {
    if parent.face_arity != 4 || rules.split() != Split::Polygons {
        return None;
    }
    let (nv, ne, nf) = (
        parent.num_vertices as usize,
        parent.num_edges(),
        parent.num_faces(),
    );
    assert_eq!(child.len(), nv + ne + nf, "child level size");
    // The grandchild level's size: the child's vertices, then one point per child edge (two
    // halves per parent edge, a spoke per parent corner) and per child face (one per corner).
    let nfc = 4 * nf;
    let n = child.len() + 2 * ne + nfc + nfc;
    let fe = &parent.face_edges;
    let fv = &parent.face_vertices;
    let mut t = crate::par::par_tail(
        n,
        nfc,
        CHUNK,
        || (),
        |_, g| {
            let (k, i) = (g / 4, g % 4);
            let prev = 4 * k + (i + 3) % 4;
            if let Some(&v) = fv.get(g + PREFETCH_NEAR) {
                prefetch(child.get(v as usize));
                prefetch(child.get(nv + fe[g + PREFETCH_NEAR] as usize));
            }
            let corners = [
                fv[g] as usize,
                nv + fe[g] as usize,
                nv + ne + k,
                nv + fe[prev] as usize,
            ];
            let mut acc = T::zero();
            for c in corners {
                acc.add_scaled(&child[c], 0.25);
            }
            acc
        },
    );
    // The vertex points of the child's face points, smooth valence-4 vertices: the recipe of
    // `Level::coarser_vertex` (the vertex, its spokes in scan order m_0, m_3, m_1, m_2, its
    // four faces' points).
    if let Some([wv, wr, wf]) = Fast::new(&MaskCache::new(rules)).face_point_vertex[4] {
        let first = nv + ne;
        t.fill_range(
            first..first + nf,
            CHUNK,
            || (),
            |_, v, faces| {
                let k = v - first;
                let e = &fe[4 * k..4 * k + 4];
                let mut acc = T::zero();
                acc.add_scaled(&child[v], wv);
                for x in [e[0], e[3], e[1], e[2]] {
                    acc.add_scaled(&child[nv + x as usize], wr);
                }
                for f in &faces[4 * k..4 * k + 4] {
                    acc.add_scaled(f, wf);
                }
                acc
            },
        );
    }
    Some(t)
}

/// Whether `rules` have the smooth-vertex recipe that [`level_apply_from_coarser`] reads
/// from the coarser level (uniform nonzero ring and face weights, as Catmull-Clark's), so
/// that a level without vertex relations evaluates its vertex points without the general
/// path.
pub(crate) fn has_coarser_recipes(rules: &dyn Rules) -> bool {
    let fast = Fast::new(&MaskCache::new(rules));
    (3..CACHED_VALENCE.min(9)).all(|n| fast.face_point_vertex[n].is_some())
}

/// [`level_apply`], with the coarser level of a level without vertex relations.
fn apply<T: Interpolate>(
    topo: &Topology,
    ctx: &LevelContext,
    src: &[T],
    coarser: Option<Coarser>,
    early: Option<Tail<T>>,
) -> Vec<T> {
    assert_eq!(src.len(), topo.num_vertices as usize, "stencil source size");
    let level = Level::new(topo, ctx, coarser);
    let value = |s: &mut Scratch, j: usize, tail: &[T]| {
        level.fast_value(j, src, tail).unwrap_or_else(|| {
            level.stencil(j, s);
            s.b.eval(src, tail)
        })
    };
    // The fast paths' time goes into chains of dependent loads (a vertex's edges, their ends,
    // the ends' values) that miss the cache at the finest levels. Each child first prefetches
    // the values of the child PREFETCH_NEAR places ahead and the tables of the one
    // PREFETCH_FAR ahead (whose values it then finds in cache PREFETCH_NEAR places later):
    // the bunny's third Catmull-Clark level, 50 → 36–40 ms.
    let prefetching = level.split != Split::QuadTri;
    let (n, late) = (level.n_child, level.child_sources());
    let head = |s: &mut Scratch, j: usize, tail: &[T]| {
        if prefetching {
            level.prefetch(j + PREFETCH_FAR, j + PREFETCH_NEAR, src, tail);
        }
        value(s, j, tail)
    };
    if let Some(t) = early {
        assert_eq!((t.len(), t.late()), (n, late), "points computed early");
        return crate::par::par_head(t, CHUNK, Scratch::default, head);
    }
    if late == 0 {
        return crate::par::par_vec(n, CHUNK, Scratch::default, |s, j| head(s, j, &[]));
    }
    crate::par::par_vec_tail_first(
        n,
        late,
        CHUNK,
        Scratch::default,
        |s, k| {
            let j = n - late + k;
            if prefetching {
                level.prefetch_face(j + PREFETCH_NEAR, src);
            }
            value(s, j, &[])
        },
        head,
    )
}

/// How many children ahead [`level_apply`] prefetches the values a child reads.
const PREFETCH_NEAR: usize = 8;
/// How many children ahead [`level_apply`] prefetches the table entries that locate them.
const PREFETCH_FAR: usize = 16;

#[cfg(test)]
mod tests {
    use super::super::{subdivide, BoundaryMode, Refinement, Scheme, SubdivideOptions};
    use super::*;
    use crate::generate;
    use crate::mesh::{EdgeTag, Mesh, VertexTag, SHARPNESS_INFINITE};

    /// `m` with pseudo-random semi-sharp and infinitely sharp creases and a corner.
    fn tagged(mut m: Mesh, seed: u64) -> Mesh {
        let t = Topology::build(&m);
        let mut x = seed;
        for e in 0..t.num_edges() {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            if (x >> 60) < 5 {
                let s = if (x >> 56) & 1 == 0 {
                    ((x >> 40) % 40) as f64 / 8.0
                } else {
                    SHARPNESS_INFINITE
                };
                m.edge_tags.push(EdgeTag {
                    vertices: t.edge_vertices[e],
                    sharpness: s,
                });
            }
        }
        m.vertex_tags.push(VertexTag {
            vertex: 1,
            sharpness: 1.5,
        });
        m
    }

    /// Degenerate closed meshes where the direct path's recipes must fall back to the general
    /// path (repeated opposite vertices, diagonals that are ring vertices, valence 2): still
    /// bit-identical to the tables.
    #[test]
    fn direct_evaluation_falls_back_on_degenerate_meshes() {
        let p = vec![
            glam::DVec3::new(0.0, 0.0, 0.0),
            glam::DVec3::new(1.0, 0.1, 0.0),
            glam::DVec3::new(1.2, 1.0, 0.3),
            glam::DVec3::new(-0.1, 0.9, 0.2),
        ];
        let pillows = [
            (
                Mesh::from_faces(p.clone(), vec![vec![0, 1, 2], vec![0, 2, 1]]),
                Scheme::Loop,
            ),
            (
                Mesh::from_faces(p.clone(), vec![vec![0, 1, 2, 3], vec![3, 2, 1, 0]]),
                Scheme::CatmullClark,
            ),
            (
                Mesh::from_faces(p, vec![vec![0, 1, 2, 3], vec![3, 2, 1, 0]]),
                Scheme::Bilinear,
            ),
        ];
        // One level: deeper levels of these meshes have repeated edges, outside the
        // refiner's preconditions.
        for (m, scheme) in pillows {
            let o = SubdivideOptions {
                scheme,
                levels: 1,
                ..Default::default()
            };
            let table = Refinement::build(&m, &o, true).unwrap();
            let direct = subdivide(&m, &o).unwrap();
            assert_eq!(table.positions, direct.positions, "{o:?}");
        }
    }

    /// A level built without vertex relations (the last level `subdivide` evaluates) gathers
    /// from its coarser level exactly the relations the counting sorts list, and evaluates bit
    /// for bit as the same level with them: on closed and open meshes, quads and mixed
    /// polygons, with semi-sharp and infinitely sharp creases and corners, both creasings.
    #[test]
    fn a_level_without_vertex_relations_reads_them_from_the_coarser_level() {
        let meshes = [
            generate::torus(1.0, 0.4, 6, 5, true),
            generate::disk(6),
            generate::icosphere(1),
            generate::grid(3, 3, false),
            generate::pyramid(),
        ];
        let mut recipes = 0;
        for (k, m) in meshes.into_iter().enumerate() {
            for seed in 0..3u64 {
                let m = if seed == 0 {
                    m.clone()
                } else {
                    tagged(m.clone(), 7 * seed + k as u64)
                };
                for creasing in [Creasing::Uniform, Creasing::Chaikin] {
                    let o = SubdivideOptions {
                        scheme: Scheme::CatmullClark,
                        levels: 3,
                        boundary: BoundaryMode::OpenSubdiv,
                        creasing,
                        ..Default::default()
                    };
                    let r = Refinement::build(&m, &o, true).unwrap();
                    let (coarse, full) = (&r.topologies[1], &r.topologies[2]);
                    let (mut lite, halves) =
                        super::super::refine::refine_topology_without_vertex_relations(coarse);
                    super::super::child_sharpness(coarse, &mut lite, &halves, creasing);
                    assert!(!lite.has_vertex_edges() && full.has_vertex_edges());
                    assert_eq!(lite.edge_sharpness, full.edge_sharpness);
                    assert_eq!(lite.vertex_sharpness, full.vertex_sharpness);
                    assert_eq!(lite.vertex_kinds, full.vertex_kinds);
                    let c = Coarser {
                        topo: coarse,
                        halves: &halves,
                    };
                    let p2 = &r.evaluate_levels(&m.positions).unwrap()[1];
                    let rules = super::super::catmull_clark::CatmullClarkRules;
                    let ctx = LevelContext {
                        rules: &rules,
                        creasing,
                        positions: p2,
                        features: None,
                    };
                    let level = Level::new(&lite, &ctx, Some(c));
                    let (mut edges, mut pairs) = (Vec::new(), Vec::new());
                    for v in 0..full.num_vertices as usize {
                        level.gather(&c, v, &mut edges, &mut pairs);
                        assert_eq!(edges, full.vertex_edges(v), "{k} {seed} vertex {v}");
                        let faces: Vec<u32> = pairs.iter().map(|p| p.0).collect();
                        let corners: Vec<u16> = pairs.iter().map(|p| p.1).collect();
                        assert_eq!(faces, full.vertex_faces(v), "{k} {seed} vertex {v}");
                        assert_eq!(corners, full.vertex_face_corners(v), "{k} {seed} {v}");
                    }
                    let want = level_apply(full, &ctx, p2);
                    let got = level_apply_from_coarser(&lite, &ctx, p2, c, None);
                    assert_eq!(got, want, "{k} {seed} {creasing:?}");
                    // The face points computed from the coarser level, before this one's
                    // tables, are this level's, and finish into the same values.
                    let early = grandchild_points(coarse, &rules, p2).expect("a quad mesh");
                    let faces = &want[full.num_vertices as usize + full.num_edges()..];
                    assert_eq!(early.computed(), faces, "{k} {seed} {creasing:?}");
                    let got = level_apply_from_coarser(&lite, &ctx, p2, c, Some(early));
                    assert_eq!(got, want, "{k} {seed} {creasing:?}");
                    // The recipe, not only the general path, is what ran on smooth vertices.
                    let tail = &want[full.num_vertices as usize + full.num_edges()..];
                    recipes += (0..full.num_vertices as usize)
                        .filter(|&v| level.coarser_vertex(&c, v, p2, tail).is_some())
                        .count();
                }
            }
        }
        assert!(recipes > 1000, "{recipes} vertices by the coarser recipe");
    }

    /// The direct path ([`level_apply`], used by `subdivide`) matches the stencil tables bit
    /// for bit, through every rule (creases, corners, semi-sharp transitions, Biermann et
    /// al.'s sectors, centroids).
    #[test]
    fn direct_evaluation_matches_tables() {
        let meshes = [
            generate::torus(1.0, 0.4, 6, 5, true),
            generate::disk(6),
            generate::icosphere(1),
            generate::torus(1.0, 0.4, 6, 5, false),
            generate::grid(3, 3, false),
            generate::pyramid(),
        ];
        for (k, m) in meshes.into_iter().enumerate() {
            for seed in 0..4u64 {
                let m = if seed == 0 {
                    m.clone()
                } else {
                    tagged(m.clone(), seed + k as u64)
                };
                let schemes: &[Scheme] = if m.is_triangle_mesh() {
                    &[
                        Scheme::Loop,
                        Scheme::Midpoint,
                        Scheme::CatmullClark,
                        Scheme::Butterfly,
                        Scheme::ButterflyOriginal,
                    ]
                } else {
                    &[Scheme::CatmullClark, Scheme::Bilinear]
                };
                for &scheme in schemes {
                    for boundary in [
                        BoundaryMode::Crease,
                        BoundaryMode::OpenSubdiv,
                        BoundaryMode::OpenSubdivCorners,
                    ] {
                        for creasing in [Creasing::Uniform, Creasing::Chaikin] {
                            let o = SubdivideOptions {
                                scheme,
                                levels: 3,
                                boundary,
                                creasing,
                                ..Default::default()
                            };
                            let table = Refinement::build(&m, &o, true).unwrap();
                            let direct = subdivide(&m, &o).unwrap();
                            assert_eq!(table.positions, direct.positions, "{k} {seed} {o:?}");
                            assert_eq!(table.evaluate(&m.positions).unwrap(), direct.positions);
                            assert_eq!(table.face_vertices, direct.face_indices);
                            assert_eq!(table.edge_tags, direct.edge_tags);
                        }
                    }
                }
            }
        }
    }

    /// Polygon splits weigh the child face points (OpenSubdiv's face-point masks): a
    /// Catmull-Clark table's face points come last and refer to parent vertices only, a
    /// smooth edge point is its two ends and its two faces' points, and `apply_into` equals
    /// `apply`; other splits' tables refer to parent vertices only.
    #[test]
    fn polygon_tables_refer_to_their_face_points() {
        let m = generate::torus(1.0, 0.4, 6, 5, false);
        let o = SubdivideOptions {
            scheme: Scheme::CatmullClark,
            levels: 2,
            ..Default::default()
        };
        let r = Refinement::build(&m, &o, true).unwrap();
        let t = &r.stencils[0];
        let topo = Topology::build(&m);
        let (nv, ne, nf) = (topo.num_vertices, topo.num_edges() as u32, topo.num_faces());
        assert_eq!(t.num_sources, nv);
        assert_eq!(t.child_sources as usize, nf);
        assert_eq!(t.len(), (nv + ne) as usize + nf);
        for j in 0..t.len() {
            let (a, b) = (t.offsets[j] as usize, t.offsets[j + 1] as usize);
            let sum: f64 = t.weights[a..b].iter().sum();
            assert!((sum - 1.0).abs() < 1e-12, "child {j}: weights sum to {sum}");
            let late = j >= (nv + ne) as usize;
            assert!(
                t.indices[a..b].iter().all(|&i| i < nv || !late),
                "face point {j} refers to a child"
            );
        }
        // A smooth edge between two quads: ends, then the two face points.
        let e = 0usize;
        let j = nv as usize + e;
        let (a, b) = (t.offsets[j] as usize, t.offsets[j + 1] as usize);
        let want: Vec<u32> = topo.edge_vertices[e]
            .into_iter()
            .chain(topo.edge_faces(e).iter().map(|&f| nv + f))
            .collect();
        assert_eq!(&t.indices[a..b], &want[..]);
        assert_eq!(&t.weights[a..b], &[0.25; 4]);
        let direct = t.apply(&m.positions);
        let mut into = vec![glam::DVec3::ZERO; t.len()];
        t.apply_into(&m.positions, &mut into);
        assert_eq!(direct, into);
        let loop_tables = Refinement::build(
            &generate::icosphere(1),
            &SubdivideOptions {
                scheme: Scheme::Loop,
                levels: 2,
                ..Default::default()
            },
            true,
        )
        .unwrap();
        assert!(loop_tables.stencils.iter().all(|t| t.child_sources == 0));
    }
}

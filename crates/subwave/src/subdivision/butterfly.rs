//! The modified butterfly scheme: interpolating 1-to-4 subdivision of triangle meshes.
//!
//! Zorin, Schröder & Sweldens 1996 ("Interpolating subdivision for meshes with arbitrary
//! topology"), the "modified butterfly" that MPEG-4 AFX adopts (Maret 2003 §3.6: "Butterfly
//! follow the modified butterfly introduced in \[25\], with support of crease, dart and corner
//! tags"; its stencils are built from the ordered 1-rings of both ends of an edge, Maret §5.3.2
//! Fig. 5.5). Old vertices keep their positions (the vertex mask is the identity); the point of
//! an edge `(v, w)` is:
//!
//! - both ends **regular** (valence 6): the 8-point butterfly of Dyn, Levin & Gregory 1990,
//!   `1/2 (v + w) + 1/8 (o0 + o1) − 1/16 (four wings)`, the wings being the ring vertices two
//!   steps from the edge around `v` and around `w`;
//! - one end **extraordinary** (valence `k ≠ 6`): only that end's 1-ring, `3/4 v + Σ s_j r_j`
//!   with `r_0 = w` and `s_j` of Zorin et al. (`k = 3`: `5/12, −1/12, −1/12`; `k = 4`:
//!   `3/8, 0, −1/8, 0`; `k ≥ 5`: `(1/4 + cos(2πj/k) + 1/2 cos(4πj/k))/k`);
//! - both ends extraordinary: the average of the two one-sided masks.
//!
//! # Creases, boundaries and corners (Maret §3.5 tags)
//! Boundary edges arrive infinitely sharp (see [`super::rules`]), so boundaries are creases.
//!
//! - A **crease edge** uses the 4-point rule along the crease curve, `−1/16, 9/16, 9/16,
//!   −1/16` (Dyn, Levin & Gregory 1987; Zorin et al.'s boundary rule). The curve continues
//!   through an end that has exactly two sharp edges and no corner sharpness; elsewhere (a
//!   corner, a dart's tip, a junction of creases) the missing curve neighbour is replaced by
//!   the linear extrapolation `2 v − w` (the curve ends there), which gives `7/16, 10/16,
//!   −1/16`, and the midpoint when both neighbours are missing.
//! - A **smooth edge with an end on a crease or corner** (two or more sharp edges there) sees
//!   that end's *sector*, the `k` faces between the two sharp edges that enclose the edge,
//!   with ring vertices `p_0..p_k` (`p_0`, `p_k` on the sharp edges). The sector is completed
//!   to a virtual interior vertex of valence `2k` by its point reflection through the vertex,
//!   `p_{k+j} = 2 v − p_j` (`0 < j < k`), and the interior rules above apply to the virtual
//!   ring (weights on reflected points fold back onto `v` and `p_j`). A regular crease vertex
//!   (`k = 3`, valence 4 on a boundary) is thus regular (virtual valence 6): on a half-plane of
//!   the regular triangle grid the reflected points are the missing lattice points, so the
//!   butterfly stencil is reproduced exactly and linear functions are reproduced, as the
//!   4-point rule does along the crease. Extraordinary sectors use Zorin's weights for
//!   valence `2k`.
//!
//! This is our construction, in the spirit of Zorin et al.'s boundary treatment (the tangent
//! plane of the one-sided rule is built from the symmetric completion of the sector, as
//! Biermann, Levin & Zorin 2000 do with `θ_k = π/k` for Loop): the exact boundary masks of
//! Zorin's thesis (1998) and course notes (SIGGRAPH 2000, Maret's ref. \[25\]) could not be
//! consulted here and are not claimed to be reproduced. Semi-sharp edges blend the crease and
//! smooth masks by their sharpness, as the other schemes do ([`super::rules`]).
//!
//! # MeshLab
//! MeshLab's "Butterfly Subdivision Surfaces" filter (vcg `MidPointButterfly`, vcglib
//! `complex/algorithms/refine.h`) is *not* the modified butterfly: it applies the original
//! 8-point stencil at every interior edge, whatever the valences ([`ButterflyVariant::Original`],
//! `--scheme butterfly-original`), and the 4-point rule on boundary edges (neighbours along the
//! boundary loop, ignoring tags). Next to a boundary its wing search stays inside the edge's own
//! face when the wing's face is missing, so a missing wing is replaced by the vertex of the
//! edge's face on that side (the stencil still sums to 1, but linear functions are no longer
//! reproduced; ours reflects the sector instead). Measured with `scripts/crosscheck-meshlab.sh`
//! and `scripts/butterfly_vs_meshlab.py` (distances over the bounding-box diagonal; MeshLab's
//! OBJ keeps 9 digits):
//! - original variant vs MeshLab, 2 levels, closed meshes (cheburashka, fandisk, rocker-arm):
//!   at most 6.6e-9, every vertex;
//! - modified (this scheme) vs MeshLab, 1 level: at most 6.6e-9 on edges whose ends both have
//!   valence 6 (and, on woody, on boundary edges); up to 8.2e-3 on edges with an
//!   extraordinary end (rocker-arm), where MeshLab's points match the original 8-point rule
//!   recomputed independently to 6.6e-9; on woody (open), up to 5.8e-3 on interior edges next
//!   to the boundary, where MeshLab's points match the 8-point rule with its wing fallback.

use std::f64::consts::TAU;

use super::refine::Split;
use super::rules::{
    decrement, EdgeMask, EdgeNeighborhood, EndRing, Rules, VertexMask, VertexNeighborhood,
};
use super::stencil::StencilTable;
use crate::mesh::SHARPNESS_INFINITE;
use crate::topology::Topology;

/// "No vertex / edge".
const NONE: u32 = u32::MAX;

/// Which butterfly.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ButterflyVariant {
    /// Zorin, Schröder & Sweldens' modified butterfly (the AFX scheme).
    #[default]
    Modified,
    /// The original 8-point butterfly of Dyn, Levin & Gregory 1990 at every smooth edge,
    /// whatever the valences (Maret §5.3 notes AFX stencils for butterfly "modified or not";
    /// MeshLab's butterfly). The wings are the ring vertices two steps from the edge around
    /// each end (at a valence-3 end, the other opposite vertex); creases as in the modified
    /// scheme.
    Original,
}

/// The butterfly's rules.
#[derive(Clone, Copy, Debug, Default)]
pub struct ButterflyRules {
    /// Modified (default) or original.
    pub variant: ButterflyVariant,
}

/// Zorin et al.'s weight `s_j` of the `j`-th ring vertex (counter-clockwise from the other
/// end of the edge) for an extraordinary vertex of valence `k` (the vertex itself weighs
/// `3/4`; the weights sum to `1/4`). `k = 6` gives `s_j` of the one-sided form of the regular
/// stencil, which the scheme does not use (regular ends take the 8-point butterfly).
pub fn extraordinary_weight(k: usize, j: usize) -> f64 {
    match k {
        3 => [5.0 / 12.0, -1.0 / 12.0, -1.0 / 12.0][j % 3],
        4 => [0.375, 0.0, -0.125, 0.0][j % 4],
        _ => {
            let (kf, jf) = (k as f64, (j % k.max(1)) as f64);
            (0.25 + (TAU * jf / kf).cos() + 0.5 * (2.0 * TAU * jf / kf).cos()) / kf
        }
    }
}

/// How an end's (possibly virtual) ring maps to its real ring.
#[derive(Clone, Copy, Debug, PartialEq)]
enum VirtualRing {
    /// A smooth end: the ring itself (`valence` vertices).
    Full { valence: usize },
    /// An end on a crease or corner: the sector of `faces` faces holding the edge, the edge
    /// being its `back`-th ring vertex from the sector's first sharp edge; virtual valence
    /// `2 faces`.
    Sector {
        faces: usize,
        back: usize,
        valence: usize,
    },
}

impl VirtualRing {
    /// The virtual ring of an end (see the module documentation).
    fn of(ring: &EndRing) -> VirtualRing {
        let n = ring.valence();
        let sharp = |j: usize| ring.sharpness[j] > 0.0;
        if (1..n).filter(|&j| sharp(j)).count() < 2 {
            return VirtualRing::Full { valence: n };
        }
        let fwd = (1..n).find(|&j| sharp(j)).unwrap_or(n);
        let bwd = (1..n).rev().find(|&j| sharp(j)).unwrap_or(0);
        let back = n - bwd;
        VirtualRing::Sector {
            faces: fwd + back,
            back,
            valence: n,
        }
    }

    /// Virtual valence.
    fn len(self) -> usize {
        match self {
            VirtualRing::Full { valence } => valence,
            VirtualRing::Sector { faces, .. } => 2 * faces,
        }
    }

    /// Adds `w` on the virtual ring vertex `o` steps counter-clockwise from the edge, folding
    /// reflected vertices (`2 v − p`) onto the end `*end` and the real ring `ring`.
    fn add(self, o: usize, w: f64, end: &mut f64, ring: &mut [f64]) {
        match self {
            VirtualRing::Full { valence } => ring[o % valence] += w,
            VirtualRing::Sector {
                faces,
                back,
                valence,
            } => {
                let t = (back + o) % (2 * faces);
                let real = |s: usize| (s + valence - back % valence) % valence;
                if t <= faces {
                    ring[real(t)] += w;
                } else {
                    *end += 2.0 * w;
                    ring[real(t - faces)] -= w;
                }
            }
        }
    }
}

impl ButterflyRules {
    /// The crease mask: the 4-point rule along the crease curve (see the module docs).
    fn crease_mask(rings: &[EndRing; 2], num_faces: usize, m: &mut EdgeMask) {
        m.clear_with_rings(num_faces, [rings[0].valence(), rings[1].valence()]);
        m.ends = [9.0 / 16.0, 9.0 / 16.0];
        for (k, r) in rings.iter().enumerate() {
            let mut others = (1..r.valence()).filter(|&j| r.sharpness[j] > 0.0);
            match (r.vertex_sharpness > 0.0, others.next(), others.next()) {
                (false, Some(j), None) => m.rings[k][j] -= 1.0 / 16.0,
                _ => {
                    // Curve end: the neighbour beyond `ends[k]` is `2 ends[k] − ends[1 − k]`.
                    m.ends[k] -= 2.0 / 16.0;
                    m.ends[1 - k] += 1.0 / 16.0;
                }
            }
        }
    }

    /// The smooth mask of an edge between two faces (see the module docs).
    fn smooth_mask(&self, rings: &[EndRing; 2], num_faces: usize, m: &mut EdgeMask) {
        m.clear_with_rings(num_faces, [rings[0].valence(), rings[1].valence()]);
        let virt = [VirtualRing::of(&rings[0]), VirtualRing::of(&rings[1])];
        let regular = match self.variant {
            ButterflyVariant::Modified => virt.map(|v| v.len() == 6),
            ButterflyVariant::Original => [true, true],
        };
        if virt.iter().any(|v| v.len() < 3) {
            // Degenerate ring (not a manifold triangle mesh): the midpoint.
            m.ends = [0.5, 0.5];
            return;
        }
        let mut ends = [0.0; 2];
        if regular == [true, true] {
            // Opposite vertices one step, wings two steps from the edge (both ways).
            for k in 0..2 {
                let n = virt[k].len();
                ends[k] += 0.5;
                if k == 0 {
                    virt[0].add(1, 0.125, &mut ends[0], &mut m.rings[0]);
                    virt[0].add(n - 1, 0.125, &mut ends[0], &mut m.rings[0]);
                }
                virt[k].add(2, -1.0 / 16.0, &mut ends[k], &mut m.rings[k]);
                virt[k].add(n - 2, -1.0 / 16.0, &mut ends[k], &mut m.rings[k]);
            }
        } else {
            let c = if regular.contains(&true) { 1.0 } else { 0.5 };
            for k in 0..2 {
                if regular[k] {
                    continue;
                }
                let n = virt[k].len();
                ends[k] += c * 0.75;
                for j in 0..n {
                    let w = c * extraordinary_weight(n, j);
                    virt[k].add(j, w, &mut ends[k], &mut m.rings[k]);
                }
            }
        }
        m.ends = ends;
    }
}

impl Rules for ButterflyRules {
    fn name(&self) -> &'static str {
        match self.variant {
            ButterflyVariant::Modified => "butterfly",
            ButterflyVariant::Original => "butterfly-original",
        }
    }

    fn split(&self) -> Split {
        Split::Triangles
    }

    fn needs_rings(&self) -> bool {
        true
    }

    /// Interpolating: old vertices stay.
    fn vertex_mask(&self, n: &VertexNeighborhood, mask: &mut VertexMask, _: &mut VertexMask) {
        mask.clear(n.valence(), n.num_faces);
        mask.vertex = 1.0;
    }

    /// Without rings (not used by the refiner, which asks for rings): the midpoint.
    fn edge_mask(&self, n: &EdgeNeighborhood, mask: &mut EdgeMask, _: &mut EdgeMask) {
        mask.set_crease(n.num_faces);
    }

    fn edge_mask_with_rings(
        &self,
        n: &EdgeNeighborhood,
        rings: &[EndRing; 2],
        mask: &mut EdgeMask,
        scratch: &mut EdgeMask,
    ) {
        let s = n.sharpness;
        if n.num_faces != 2 || s >= 1.0 {
            Self::crease_mask(rings, n.num_faces, mask);
            return;
        }
        self.smooth_mask(rings, n.num_faces, mask);
        if s > 0.0 {
            Self::crease_mask(rings, n.num_faces, scratch);
            mask.blend(1.0 - s, scratch, s);
        }
    }
}

/// The stencil table of one level of modified butterfly refinement of an **untagged**
/// triangle mesh (boundary edges as creases, the refiner's defaults), built straight from the
/// level's topology: bit for bit the table that [`super::Refinement::build`] keeps for that
/// level with `Scheme::Butterfly` and default options (same rows, indices in the same order,
/// same weights), without refining positions or re-ordering the 1-rings of the whole level.
///
/// Interior edges whose ends are both interior vertices of valence 6 get the 8-point stencil
/// directly (Dyn, Levin & Gregory, in the refiner's order: the ends, the first end's ring
/// `r_1, r_2, r_{4}, r_5`, the second end's wings `r_2, r_4`); every other edge goes through
/// [`ButterflyRules`] with its ends' counter-clockwise rings walked locally, as the refiner
/// does with its ordered rings.
///
/// Contract: `topo` is a level of a consistently oriented 2-manifold triangle mesh (as every
/// level of a [`crate::hierarchy::Hierarchy`] is); its edge and vertex sharpness are ignored
/// (the mesh must carry no crease or corner tags for the equality above to hold).
pub fn untagged_level_table(topo: &Topology) -> StencilTable {
    let nv = topo.num_vertices as usize;
    let ne = topo.num_edges();
    // Interior vertices of valence 6 (no boundary edge: as many faces as edges).
    let regular: Vec<bool> = (0..nv)
        .map(|v| {
            let k = topo.valence(v);
            k == 6 && topo.vertex_faces(v).len() == k
        })
        .collect();
    // Room for 8 entries per edge, and for the longer general stencils (at most the ends,
    // the opposite vertices and both rings: `k_a + k_b + 4` entries) on the edges of the
    // other vertices, so that the tables are not reallocated (copied) while they grow.
    let extra: usize = (0..nv)
        .filter(|&v| !regular[v])
        .map(|v| {
            let k = topo.valence(v);
            k * (k + 2)
        })
        .sum();
    let mut offsets = Vec::with_capacity(nv + ne + 1);
    offsets.extend(0..=nv as u32);
    let mut indices = Vec::with_capacity(nv + 8 * ne + extra);
    indices.extend(0..nv as u32);
    let mut weights = Vec::with_capacity(nv + 8 * ne + extra);
    weights.resize(nv, 1.0);
    // Per edge and side: the opposite vertex and the next and previous edges of the face
    // on that side (side 0: the face traversing the edge in its stored direction, the
    // first; side 1: the other).
    let mut side = vec![[[NONE; 3]; 2]; ne];
    for f in 0..topo.num_faces() {
        let (fv, fe) = (topo.face_vertices(f), topo.face_edges(f));
        if fv.len() != 3 {
            continue;
        }
        for i in 0..3 {
            let x = fe[i] as usize;
            let slot = (topo.edge_vertices[x][0] != fv[i]) as usize;
            side[x][slot] = [fv[(i + 2) % 3], fe[(i + 1) % 3], fe[(i + 2) % 3]];
        }
    }
    // The vertex across edge `x` from the face that traverses it from `u`.
    let wing = |x: u32, u: u32| -> u32 {
        let x = x as usize;
        let s = (topo.edge_vertices[x][0] != u) as usize;
        side[x][1 - s][0]
    };
    let mut scratch = RingScratch::default();
    const W: f64 = -1.0 / 16.0;
    for (e, &[l, r]) in side.iter().enumerate() {
        let [a, b] = topo.edge_vertices[e];
        let mut fast = None;
        if regular[a as usize] && regular[b as usize] && l[0] != NONE && r[0] != NONE {
            let ring = [
                l[0],
                wing(l[2], l[0]),
                wing(r[1], a),
                r[0],
                wing(r[2], r[0]),
                wing(l[1], b),
            ];
            let all = [a, b, ring[0], ring[1], ring[2], ring[3], ring[4], ring[5]];
            // Eight distinct vertices, none missing (all pairs compared without early
            // exits: 28 comparisons the compiler keeps branch-free).
            let mut ok = ring.iter().fold(true, |ok, &x| ok & (x != NONE));
            for i in 1..8 {
                for j in 0..i {
                    ok &= all[i] != all[j];
                }
            }
            if ok {
                fast = Some(all);
            }
        }
        match fast {
            Some(all) => {
                indices.extend_from_slice(&all);
                weights.extend_from_slice(&[0.5, 0.5, 0.125, W, W, 0.125, W, W]);
            }
            None => {
                general_stencil(topo, e, &mut scratch);
                indices.extend_from_slice(&scratch.idx);
                weights.extend_from_slice(&scratch.w);
            }
        }
        offsets.push(indices.len() as u32);
    }
    StencilTable {
        num_sources: nv as u32,
        child_sources: 0,
        offsets,
        indices,
        weights,
    }
}

/// Scratch space of [`general_stencil`].
#[derive(Default)]
struct RingScratch {
    idx: Vec<u32>,
    w: Vec<f64>,
    edges: Vec<u32>,
    used: Vec<bool>,
    ring_sharp: [Vec<f64>; 2],
    ring_verts: [Vec<u32>; 2],
    m: EdgeMask,
    s: EdgeMask,
    /// Masks of interior edges between interior ends, by valences (`ka · CACHED + kb`):
    /// they depend on nothing else.
    interior: Vec<Option<EdgeMask>>,
    /// The ordered edges of each vertex met so far ([`ordered_edges`], computed once per
    /// vertex instead of once per edge end): `ring_store[start..start + len]` for
    /// `rings[v] = [start, len]` (`start = NONE` if not computed yet).
    rings: Vec<[u32; 2]>,
    ring_store: Vec<u32>,
    /// Parallel to `ring_store`: the other end of each edge, and its sharpness (boundary
    /// edges infinitely sharp).
    ring_other: Vec<u32>,
    ring_edge_sharp: Vec<f64>,
}

/// The sharpness [`general_stencil`] gives edge `x` of an untagged level: infinite on the
/// boundary, 0 inside.
#[inline]
fn boundary_sharpness(topo: &Topology, x: u32) -> f64 {
    if topo.is_boundary_edge(x as usize) {
        SHARPNESS_INFINITE
    } else {
        0.0
    }
}

/// Valences below this have their interior masks cached.
const CACHED: usize = 24;

impl RingScratch {
    /// The range of `ring_store` holding vertex `v`'s [`ordered_edges`].
    fn ring(&mut self, topo: &Topology, v: usize) -> std::ops::Range<usize> {
        if self.rings.is_empty() {
            self.rings = vec![[NONE, 0]; topo.num_vertices as usize];
        }
        let [start, len] = self.rings[v];
        if start != NONE {
            return start as usize..start as usize + len as usize;
        }
        ordered_edges(topo, v, &mut self.edges, &mut self.used);
        let start = self.ring_store.len();
        self.ring_store.extend_from_slice(&self.edges);
        for &x in &self.edges {
            self.ring_other
                .push(topo.other_vertex(x as usize, v as u32));
            self.ring_edge_sharp.push(boundary_sharpness(topo, x));
        }
        self.rings[v] = [start as u32, self.edges.len() as u32];
        start..self.ring_store.len()
    }

    /// Adds `w · x` to the stencil, merging a repeated index (the refiner's builder).
    #[inline]
    fn add(&mut self, x: u32, w: f64) {
        if w == 0.0 {
            return;
        }
        if let Some(k) = self.idx.iter().position(|&y| y == x) {
            self.w[k] += w;
        } else {
            self.idx.push(x);
            self.w.push(w);
        }
    }
}

/// The edges around `v` in the refiner's counter-clockwise order (the ordered 1-ring of
/// [`Topology`]: from the corner whose outgoing edge is a boundary edge on a boundary), into
/// `edges`.
fn ordered_edges(topo: &Topology, v: usize, edges: &mut Vec<u32>, used: &mut Vec<bool>) {
    let faces = topo.vertex_faces(v);
    let corners = topo.vertex_face_corners(v);
    let n = faces.len();
    edges.clear();
    if n == 0 {
        return;
    }
    // Outgoing and incoming edge of corner k.
    let out_in = |k: usize| {
        let fe = topo.face_edges(faces[k] as usize);
        let i = corners[k] as usize;
        (fe[i], fe[(i + fe.len() - 1) % fe.len()])
    };
    let start = (0..n)
        .find(|&k| topo.is_boundary_edge(out_in(k).0 as usize))
        .unwrap_or(0);
    let boundary = topo.is_boundary_edge(out_in(start).0 as usize);
    used.clear();
    used.resize(n, false);
    let mut k = start;
    let (entry, mut exit) = out_in(k);
    edges.push(entry);
    loop {
        used[k] = true;
        edges.push(exit);
        match (0..n).find(|&k2| k2 != k && out_in(k2).0 == exit) {
            Some(k2) if !used[k2] => {
                k = k2;
                exit = out_in(k2).1;
            }
            _ => break,
        }
    }
    if !boundary {
        edges.pop();
    }
}

/// The stencil of edge `e` through [`ButterflyRules`] (the refiner's ring path), into
/// `s.idx`, `s.w`.
fn general_stencil(topo: &Topology, e: usize, s: &mut RingScratch) {
    let ends = topo.edge_vertices[e];
    let faces = topo.edge_faces(e);
    for (k, &v) in ends.iter().enumerate() {
        // The ring from edge `e` on: edges `(at + j) % n`, `j = 0..n`.
        let range = s.ring(topo, v as usize);
        let at = s.ring_store[range.clone()]
            .iter()
            .position(|&x| x as usize == e)
            .unwrap_or(0);
        let (sharp, other) = (&s.ring_edge_sharp[range.clone()], &s.ring_other[range]);
        s.ring_sharp[k].clear();
        s.ring_sharp[k].extend_from_slice(&sharp[at..]);
        s.ring_sharp[k].extend_from_slice(&sharp[..at]);
        s.ring_verts[k].clear();
        s.ring_verts[k].extend_from_slice(&other[at..]);
        s.ring_verts[k].extend_from_slice(&other[..at]);
    }
    let sharpness = boundary_sharpness(topo, e as u32);
    let n = EdgeNeighborhood {
        sharpness,
        num_faces: faces.len(),
        face_arity: faces
            .first()
            .map_or(0, |&f| topo.face_vertices(f as usize).len()),
        ends: [None, None],
        child_sharpness: [decrement(sharpness); 2],
    };
    let rings = [0, 1].map(|k| EndRing {
        sharpness: &s.ring_sharp[k],
        vertex_sharpness: 0.0,
        num_faces: topo.vertex_faces(ends[k] as usize).len(),
    });
    let (ka, kb) = (rings[0].valence(), rings[1].valence());
    let interior = sharpness == 0.0
        && faces.len() == 2
        && ka < CACHED
        && kb < CACHED
        && rings.iter().all(|r| r.num_faces == r.valence())
        && s.ring_sharp.iter().flatten().all(|&x| x == 0.0);
    let slot = ka * CACHED + kb;
    let cached = if interior {
        if s.interior.is_empty() {
            s.interior.resize(CACHED * CACHED, None);
        }
        s.interior[slot].take()
    } else {
        None
    };
    let m = match cached {
        Some(m) => m,
        None => {
            ButterflyRules::default().edge_mask_with_rings(&n, &rings, &mut s.m, &mut s.s);
            std::mem::take(&mut s.m)
        }
    };
    s.idx.clear();
    s.w.clear();
    for (&v, &w) in ends.iter().zip(&m.ends) {
        if w != 0.0 {
            s.idx.push(v);
            s.w.push(w);
        }
    }
    for (i, &f) in faces.iter().enumerate() {
        let w = m.faces.get(i).copied().unwrap_or(0.0);
        let opp = topo
            .face_vertices(f as usize)
            .iter()
            .copied()
            .find(|&x| x != ends[0] && x != ends[1]);
        if let Some(o) = opp {
            s.add(o, w);
        }
    }
    for k in 0..2 {
        for j in 0..s.ring_verts[k].len() {
            let (v, w) = (
                s.ring_verts[k][j],
                m.rings[k].get(j).copied().unwrap_or(0.0),
            );
            s.add(v, w);
        }
    }
    if interior {
        s.interior[slot] = Some(m);
    } else {
        s.m = m;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::SHARPNESS_INFINITE;

    const INF: f64 = SHARPNESS_INFINITE;

    fn mask(sharpness: f64, rings: [(&[f64], f64, usize); 2]) -> EdgeMask {
        let n = EdgeNeighborhood {
            sharpness,
            num_faces: if sharpness >= INF { 1 } else { 2 },
            face_arity: 3,
            ends: [None, None],
            child_sharpness: [0.0; 2],
        };
        let rings = rings.map(|(s, vs, f)| EndRing {
            sharpness: s,
            vertex_sharpness: vs,
            num_faces: f,
        });
        let (mut m, mut s) = (EdgeMask::default(), EdgeMask::default());
        ButterflyRules::default().edge_mask_with_rings(&n, &rings, &mut m, &mut s);
        m
    }

    #[test]
    fn zorin_weights() {
        for k in 3..=12 {
            let sum: f64 = (0..k).map(|j| extraordinary_weight(k, j)).sum();
            assert!((0.75 + sum - 1.0).abs() < 1e-14, "k = {k}");
        }
        // k = 5 from the formula: s_0 = (1/4 + 1 + 1/2)/5 = 0.35.
        assert!((extraordinary_weight(5, 0) - 0.35).abs() < 1e-15);
        assert_eq!(extraordinary_weight(4, 2), -0.125);
        // k = 6 (unused by the scheme, regular ends take the butterfly): s_3 from the formula.
        assert!((extraordinary_weight(6, 3) - (0.25 - 1.0 + 0.5) / 6.0).abs() < 1e-15);
    }

    #[test]
    fn regular_butterfly() {
        let z = [0.0; 6];
        let m = mask(0.0, [(&z, 0.0, 6), (&z, 0.0, 6)]);
        assert_eq!(m.ends, [0.5, 0.5]);
        assert_eq!(m.rings[0], vec![0.0, 0.125, -0.0625, 0.0, -0.0625, 0.125]);
        assert_eq!(m.rings[1], vec![0.0, 0.0, -0.0625, 0.0, -0.0625, 0.0]);
        assert_eq!(m.sum(), 1.0);
    }

    #[test]
    fn extraordinary_ends() {
        let z = [0.0; 12];
        for k in (3..=12).filter(|&k| k != 6) {
            // One extraordinary end: its ring only.
            let m = mask(0.0, [(&z[..k], 0.0, k), (&z[..6], 0.0, 6)]);
            assert_eq!(m.ends, [0.75, 0.0]);
            assert!((m.sum() - 1.0).abs() < 1e-14);
            assert!(m.rings[1].iter().all(|&w| w == 0.0));
            for j in 0..k {
                assert_eq!(m.rings[0][j], extraordinary_weight(k, j));
            }
            // Both extraordinary: the average.
            let m2 = mask(0.0, [(&z[..k], 0.0, k), (&z[..5], 0.0, 5)]);
            assert!((m2.ends[0] - 0.375).abs() < 1e-15 && (m2.ends[1] - 0.375).abs() < 1e-15);
            assert!((m2.sum() - 1.0).abs() < 1e-14);
            assert!((m2.rings[0][1] - 0.5 * extraordinary_weight(k, 1)).abs() < 1e-15);
        }
    }

    #[test]
    fn boundary_and_crease_masks_sum_to_one() {
        // A boundary vertex of valence v + 1 (v faces), ring from the edge: boundary edges at
        // ring positions `a` and `b`.
        for faces in 2..=10usize {
            let n = faces + 1;
            for pos in 1..faces {
                // The edge is the `pos`-th edge of the fan from its leading boundary edge.
                let mut s = vec![0.0; n];
                s[(n - pos) % n] = INF;
                s[(n - pos + faces) % n] = INF;
                for other in [3, 5, 6, 7] {
                    let z = [0.0; 12];
                    let m = mask(0.0, [(&s, 0.0, faces), (&z[..other], 0.0, other)]);
                    assert!((m.sum() - 1.0).abs() < 1e-14, "{faces} {pos} {other}");
                    let m = mask(0.5, [(&s, 0.0, faces), (&z[..other], 0.0, other)]);
                    assert!((m.sum() - 1.0).abs() < 1e-14);
                }
            }
        }
        // Crease edges: both neighbours along the crease, one, none (corner), dart tip.
        let s4 = [INF, 0.0, INF, 0.0];
        let m = mask(INF, [(&s4, 0.0, 3), (&s4, 0.0, 3)]);
        assert_eq!(m.ends, [9.0 / 16.0, 9.0 / 16.0]);
        assert_eq!(m.rings[0], vec![0.0, 0.0, -1.0 / 16.0, 0.0]);
        assert_eq!(m.sum(), 1.0);
        let m = mask(INF, [(&s4, 1.0, 3), (&s4, 0.0, 3)]);
        assert_eq!(m.ends, [7.0 / 16.0, 10.0 / 16.0]);
        assert_eq!(m.sum(), 1.0);
        let m = mask(INF, [(&s4, 1.0, 3), (&s4, 1.0, 3)]);
        assert_eq!(m.ends, [0.5, 0.5]);
        let dart = [INF, 0.0, 0.0, 0.0, 0.0];
        let m = mask(INF, [(&dart, 0.0, 5), (&s4, 0.0, 3)]);
        assert_eq!(m.ends, [7.0 / 16.0, 10.0 / 16.0]);
        assert_eq!(m.sum(), 1.0);
    }

    #[test]
    fn regular_boundary_vertex_gives_the_butterfly_with_a_reflected_wing() {
        // Half-plane of the regular grid: boundary vertex 0 with ring a, b, b − a, −a (a, −a
        // on the boundary), the edge to b. Ring rotated from b: b, b − a, −a, a.
        let s = [0.0, 0.0, INF, INF];
        let z = [0.0; 6];
        let m = mask(0.0, [(&s, 0.0, 3), (&z, 0.0, 6)]);
        // Virtual wings around 0: two steps from b, i.e. −a (real) and a − b = 2·0 − (b − a).
        // End 0: 1/2 − 2/16; b − a: 1/8 + 1/16; a: 1/8; −a: −1/16.
        assert_eq!(m.ends, [0.5 - 0.125, 0.5]);
        assert_eq!(m.rings[0], vec![0.0, 0.125 + 0.0625, -0.0625, 0.125]);
        assert_eq!(m.sum(), 1.0);
    }

    #[test]
    fn original_is_the_8_point_rule_at_any_valence() {
        let r = ButterflyRules {
            variant: ButterflyVariant::Original,
        };
        let z = [0.0; 7];
        let n = EdgeNeighborhood {
            sharpness: 0.0,
            num_faces: 2,
            face_arity: 3,
            ends: [None, None],
            child_sharpness: [0.0; 2],
        };
        let ring = |k: usize| EndRing {
            sharpness: &z[..k],
            vertex_sharpness: 0.0,
            num_faces: k,
        };
        let (mut m, mut s) = (EdgeMask::default(), EdgeMask::default());
        r.edge_mask_with_rings(&n, &[ring(5), ring(3)], &mut m, &mut s);
        assert_eq!(m.ends, [0.5, 0.5]);
        assert_eq!(m.rings[0], vec![0.0, 0.125, -0.0625, -0.0625, 0.125]);
        // Valence 3: the wings two steps away are the opposite vertices.
        assert_eq!(m.rings[1], vec![0.0, -0.0625, -0.0625]);
        assert_eq!(m.sum(), 1.0);
    }

    #[test]
    fn vertices_stay() {
        let z = [0.0; 7];
        let (mut m, mut s) = (VertexMask::default(), VertexMask::default());
        ButterflyRules::default().vertex_mask(&VertexNeighborhood::smooth(7, &z), &mut m, &mut s);
        assert_eq!(m.vertex, 1.0);
        assert_eq!(m.sum(), 1.0);
    }
}

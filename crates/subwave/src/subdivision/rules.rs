//! Masks and local neighbourhoods: the interface between scheme rules and the refiner.
//!
//! A scheme's rules (one file per scheme) are pure functions from a [`VertexNeighborhood`] or
//! [`EdgeNeighborhood`] — valence, face count, sharpness, tags, sector size and angle — to a
//! mask, as OpenSubdiv's `Sdc` separates rules from `Vtr` tables. The refiner translates a
//! mask's local weights to parent vertex indices:
//!
//! - vertex masks: `vertex` weighs the vertex itself, `edges[i]` the far end of the `i`-th
//!   incident edge, `faces[i]` the centroid of the `i`-th incident face (polygon schemes);
//! - edge masks: `ends[0]`, `ends[1]` weigh the edge's ends (in the edge's stored direction),
//!   `faces[i]` the vertex opposite the edge in the `i`-th incident triangle (triangle schemes)
//!   or the centroid of the `i`-th incident face (polygon schemes); the quad/triangle split
//!   mixes both per face: opposite vertex of a triangle, centroid of a quad.
//!
//! Sharpness follows OpenSubdiv (`Sdc::Crease`): 0 smooth, `>= SHARPNESS_INFINITE` infinitely
//! sharp, in between semi-sharp. Boundary edges arrive as infinitely sharp, so that "boundary
//! edges count as creases" (Maret §3.5) needs no special case in the rules.

use crate::mesh::SHARPNESS_INFINITE;

/// The rule a vertex follows (Maret §3.5 tags; OpenSubdiv's `Sdc::Crease::Rule`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// No sharp incident edge.
    Smooth,
    /// One sharp incident edge.
    Dart,
    /// Two sharp incident edges.
    Crease,
    /// More than two sharp incident edges, or a sharp vertex.
    Corner,
}

impl Rule {
    /// The rule of a vertex from its corner sharpness and incident edge sharpness.
    pub fn classify(vertex_sharpness: f64, edge_sharpness: &[f64]) -> Rule {
        if vertex_sharpness > 0.0 {
            return Rule::Corner;
        }
        match edge_sharpness.iter().filter(|&&s| s > 0.0).count() {
            0 => Rule::Smooth,
            1 => Rule::Dart,
            2 => Rule::Crease,
            _ => Rule::Corner,
        }
    }
}

/// How semi-sharp creases relax from one level to the next (OpenSubdiv's `CreasingMethod`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Creasing {
    /// Sharpness decreases by one per level.
    #[default]
    Uniform,
    /// Chaikin's rule: a child's sharpness blends its parent's with the neighbouring creases'
    /// (`3/4 s + 1/4 average of the others`) before decreasing by one.
    Chaikin,
}

/// True if the sharpness is infinite.
#[inline]
pub fn is_infinite(s: f64) -> bool {
    s >= SHARPNESS_INFINITE
}

/// Sharpness after one level of uniform creasing.
#[inline]
pub fn decrement(s: f64) -> f64 {
    if is_infinite(s) {
        SHARPNESS_INFINITE
    } else if s > 1.0 {
        s - 1.0
    } else {
        0.0
    }
}

/// Sharpness of the child half of an edge at one of its ends (`Sdc::Crease::
/// SubdivideEdgeSharpnessAtVertex`). `incident` lists the sharpness of every edge at that end,
/// including this edge.
pub fn child_edge_sharpness(creasing: Creasing, s: f64, incident: &[f64]) -> f64 {
    if creasing == Creasing::Uniform || incident.len() < 2 || s <= 0.0 || is_infinite(s) {
        return decrement(s);
    }
    let (mut sum, mut count) = (0.0, 0usize);
    for &x in incident {
        if x > 0.0 && !is_infinite(x) {
            sum += x;
            count += 1;
        }
    }
    let mut c = s;
    if count > 1 {
        let avg_others = (sum - s) / (count - 1) as f64;
        c = 0.75 * s + 0.25 * avg_others;
    }
    c -= 1.0;
    if c > 0.0 {
        c
    } else {
        0.0
    }
}

/// The weight of the parent rule when a vertex's rule changes between levels
/// (`Sdc::Crease::ComputeFractionalWeightAtVertex`): the mean parent sharpness of the features
/// that become smooth, clamped to 1.
pub fn fractional_weight(
    parent_vertex: f64,
    child_vertex: f64,
    parent_edges: &[f64],
    child_edges: &[f64],
) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    if parent_vertex > 0.0 && child_vertex <= 0.0 {
        sum += parent_vertex;
        count += 1;
    }
    for (&p, &c) in parent_edges.iter().zip(child_edges) {
        if p > 0.0 && c <= 0.0 {
            sum += p;
            count += 1;
        }
    }
    if count == 0 {
        0.0
    } else {
        (sum / count as f64).min(1.0)
    }
}

/// Everything a vertex rule may look at.
#[derive(Clone, Copy, Debug)]
pub struct VertexNeighborhood<'a> {
    /// Number of incident faces.
    pub num_faces: usize,
    /// Sharpness of each incident edge at this level (boundary edges infinite).
    pub edge_sharpness: &'a [f64],
    /// Corner sharpness at this level.
    pub vertex_sharpness: f64,
    /// Sharpness of the incident edges' child halves at this vertex (next level).
    pub child_edge_sharpness: &'a [f64],
    /// Corner sharpness at the next level.
    pub child_vertex_sharpness: f64,
}

impl VertexNeighborhood<'_> {
    /// Number of incident edges (the valence).
    #[inline]
    pub fn valence(&self) -> usize {
        self.edge_sharpness.len()
    }

    /// The neighbourhood of a smooth interior vertex of valence `n` (for tests and tables).
    pub fn smooth(n: usize, zeros: &[f64]) -> VertexNeighborhood<'_> {
        VertexNeighborhood {
            num_faces: n,
            edge_sharpness: &zeros[..n],
            vertex_sharpness: 0.0,
            child_edge_sharpness: &zeros[..n],
            child_vertex_sharpness: 0.0,
        }
    }
}

/// Geometry of the sector on one side of an edge end that is a crease or corner vertex
/// (Biermann, Levin & Zorin 2000): the number of faces `k` of the sector and its angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sector {
    /// The end vertex's rule.
    pub rule: Rule,
    /// Faces in the sector that contains the edge.
    pub faces: usize,
    /// Sum of the sector's face angles at the vertex, radians.
    pub angle: f64,
}

/// Everything an edge rule may look at.
#[derive(Clone, Copy, Debug)]
pub struct EdgeNeighborhood {
    /// Sharpness of the edge (boundary edges infinite).
    pub sharpness: f64,
    /// Number of incident faces (1 on a boundary).
    pub num_faces: usize,
    /// Arity of the incident faces, when all are equal (3 for triangle schemes).
    pub face_arity: usize,
    /// The sector of each end (for the rules of Biermann et al.; `None` when not computed).
    pub ends: [Option<Sector>; 2],
    /// Sharpness of the edge's two child halves at the next level (at `ends[0]`, `ends[1]`),
    /// by the creasing rule; both equal `sharpness` when the edge is smooth or infinitely sharp.
    pub child_sharpness: [f64; 2],
}

/// A vertex-point mask in local terms (see the module documentation).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexMask {
    /// Weight of the vertex itself.
    pub vertex: f64,
    /// Weight of the far end of each incident edge.
    pub edges: Vec<f64>,
    /// Weight of each incident face's centroid.
    pub faces: Vec<f64>,
}

impl VertexMask {
    /// Resets to zero weights for `edges` edges and `faces` faces.
    pub fn clear(&mut self, edges: usize, faces: usize) {
        self.vertex = 0.0;
        self.edges.clear();
        self.edges.resize(edges, 0.0);
        self.faces.clear();
        self.faces.resize(faces, 0.0);
    }

    /// `self = a·self + b·other` (other has the same shape).
    pub fn blend(&mut self, a: f64, other: &VertexMask, b: f64) {
        self.vertex = a * self.vertex + b * other.vertex;
        for (x, y) in self.edges.iter_mut().zip(&other.edges) {
            *x = a * *x + b * *y;
        }
        for (x, y) in self.faces.iter_mut().zip(&other.faces) {
            *x = a * *x + b * *y;
        }
    }

    /// Sum of all weights (1 for an affine-invariant rule).
    pub fn sum(&self) -> f64 {
        self.vertex + self.edges.iter().sum::<f64>() + self.faces.iter().sum::<f64>()
    }

    /// The crease rule (Maret Fig. 3.9b): `3/4` the vertex, `1/8` each sharp edge's far end.
    pub fn set_crease(&mut self, n: &VertexNeighborhood, sharp: impl Fn(usize) -> bool) {
        self.clear(n.valence(), n.num_faces);
        self.vertex = 0.75;
        for i in 0..n.valence() {
            if sharp(i) {
                self.edges[i] = 0.125;
            }
        }
    }

    /// The corner rule: the vertex does not move.
    pub fn set_corner(&mut self, n: &VertexNeighborhood) {
        self.clear(n.valence(), n.num_faces);
        self.vertex = 1.0;
    }
}

/// One end of an edge seen through its ordered 1-ring (Maret §2.3 eq. 2.3, Algorithm 4),
/// for rules that reach beyond the edge's faces (the butterfly, Maret §5.3.2 Fig. 5.5).
///
/// The ring is rotated to start at the edge itself: entry `j` is the `j`-th incident edge
/// counter-clockwise from the edge, whose far end is the ring's `j`-th vertex (entry 0 is
/// the edge, its far end the edge's other end). Consecutive entries share a face, except
/// across the gap of a boundary vertex, which lies between its two boundary edges (both
/// infinitely sharp, see the module documentation).
#[derive(Clone, Copy, Debug)]
pub struct EndRing<'a> {
    /// Sharpness of the incident edges in rotated ring order (entry 0: the edge itself).
    pub sharpness: &'a [f64],
    /// Corner sharpness of the end vertex.
    pub vertex_sharpness: f64,
    /// Number of faces around the end (one less than the valence on a boundary).
    pub num_faces: usize,
}

impl EndRing<'_> {
    /// Number of incident edges (the valence).
    #[inline]
    pub fn valence(&self) -> usize {
        self.sharpness.len()
    }
}

/// An edge-point mask in local terms (see the module documentation).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EdgeMask {
    /// Weights of the two ends.
    pub ends: [f64; 2],
    /// Weight of each incident face's opposite vertex (triangles) or centroid (polygons).
    pub faces: Vec<f64>,
    /// Weights over each end's ordered 1-ring, rotated to start at the other end (see
    /// [`EndRing`]); empty unless the scheme asks for rings ([`Rules::needs_rings`]).
    pub rings: [Vec<f64>; 2],
}

impl EdgeMask {
    /// Resets to zero weights for `faces` faces (and no ring weights).
    pub fn clear(&mut self, faces: usize) {
        self.ends = [0.0; 2];
        self.faces.clear();
        self.faces.resize(faces, 0.0);
        self.rings[0].clear();
        self.rings[1].clear();
    }

    /// Resets to zero weights for `faces` faces and rings of the given valences.
    pub fn clear_with_rings(&mut self, faces: usize, valences: [usize; 2]) {
        self.clear(faces);
        self.rings[0].resize(valences[0], 0.0);
        self.rings[1].resize(valences[1], 0.0);
    }

    /// The crease rule: the midpoint.
    pub fn set_crease(&mut self, faces: usize) {
        self.clear(faces);
        self.ends = [0.5, 0.5];
    }

    /// `self = a·self + b·other`.
    pub fn blend(&mut self, a: f64, other: &EdgeMask, b: f64) {
        self.ends = [
            a * self.ends[0] + b * other.ends[0],
            a * self.ends[1] + b * other.ends[1],
        ];
        for (x, y) in self.faces.iter_mut().zip(&other.faces) {
            *x = a * *x + b * *y;
        }
        for (r, o) in self.rings.iter_mut().zip(&other.rings) {
            for (x, y) in r.iter_mut().zip(o) {
                *x = a * *x + b * *y;
            }
        }
    }

    /// Sum of all weights.
    pub fn sum(&self) -> f64 {
        self.ends[0]
            + self.ends[1]
            + self.faces.iter().sum::<f64>()
            + self.rings[0].iter().sum::<f64>()
            + self.rings[1].iter().sum::<f64>()
    }
}

/// The rules of a scheme that splits faces 1-to-4 (triangles) or 1-to-n (polygons).
pub trait Rules: Sync {
    /// The scheme's name, as on the command line.
    fn name(&self) -> &'static str;
    /// How faces are split.
    fn split(&self) -> super::refine::Split;
    /// Whether edge masks need [`EdgeNeighborhood::ends`] sectors.
    fn needs_sectors(&self) -> bool {
        false
    }
    /// The mask of the vertex point of a parent vertex.
    fn vertex_mask(&self, n: &VertexNeighborhood, mask: &mut VertexMask, scratch: &mut VertexMask);
    /// The mask of the edge point of a parent edge.
    fn edge_mask(&self, n: &EdgeNeighborhood, mask: &mut EdgeMask, scratch: &mut EdgeMask);
    /// Whether edge masks need the ends' ordered 1-rings ([`Rules::edge_mask_with_rings`]);
    /// the refiner then orders the rings of every level.
    fn needs_rings(&self) -> bool {
        false
    }
    /// The mask of the edge point of a parent edge, seeing the ordered 1-rings of its ends
    /// (`rings[i]` for `ends[i]`); may fill [`EdgeMask::rings`]. Called instead of
    /// [`Rules::edge_mask`] when [`Rules::needs_rings`]; by default the same.
    fn edge_mask_with_rings(
        &self,
        n: &EdgeNeighborhood,
        rings: &[EndRing; 2],
        mask: &mut EdgeMask,
        scratch: &mut EdgeMask,
    ) {
        let _ = rings;
        self.edge_mask(n, mask, scratch);
    }
    /// The vertex mask when the rule depends on the arity of each incident face (the refiner
    /// calls it instead of [`Rules::vertex_mask`] for [`super::refine::Split::QuadTri`]):
    /// `face_arities[i]` is the arity of the `i`-th incident face. Defaults to
    /// [`Rules::vertex_mask`].
    fn vertex_mask_with_arities(
        &self,
        n: &VertexNeighborhood,
        face_arities: &[u32],
        mask: &mut VertexMask,
        scratch: &mut VertexMask,
    ) {
        let _ = face_arities;
        self.vertex_mask(n, mask, scratch);
    }
    /// The edge mask when the rule depends on the arity of each incident face (called instead
    /// of [`Rules::edge_mask`] for [`super::refine::Split::QuadTri`]; `faces[i]` of the mask
    /// then weighs the opposite vertex of a triangle, the centroid of a quad). Defaults to
    /// [`Rules::edge_mask`].
    fn edge_mask_with_arities(
        &self,
        n: &EdgeNeighborhood,
        face_arities: &[u32],
        mask: &mut EdgeMask,
        scratch: &mut EdgeMask,
    ) {
        let _ = face_arities;
        self.edge_mask(n, mask, scratch);
    }
}

/// Applies OpenSubdiv's semi-sharp vertex transition: computes the parent rule's mask with
/// `rule_mask`, and, when the rule at the next level differs, blends it with the child rule's
/// mask by [`fractional_weight`].
pub fn vertex_mask_with_transition(
    n: &VertexNeighborhood,
    mask: &mut VertexMask,
    scratch: &mut VertexMask,
    rule_mask: impl Fn(Rule, &VertexNeighborhood, &mut VertexMask),
) {
    let parent = Rule::classify(n.vertex_sharpness, n.edge_sharpness);
    rule_mask(parent, n, mask);
    if parent == Rule::Smooth || parent == Rule::Dart {
        return;
    }
    let child = Rule::classify(n.child_vertex_sharpness, n.child_edge_sharpness);
    if child == parent {
        return;
    }
    let w = fractional_weight(
        n.vertex_sharpness,
        n.child_vertex_sharpness,
        n.edge_sharpness,
        n.child_edge_sharpness,
    );
    // The child rule's mask uses the child's sharp edges (for a crease rule).
    let child_n = VertexNeighborhood {
        edge_sharpness: n.child_edge_sharpness,
        vertex_sharpness: n.child_vertex_sharpness,
        ..*n
    };
    rule_mask(child, &child_n, scratch);
    mask.blend(w, scratch, 1.0 - w);
}

/// Applies OpenSubdiv's semi-sharp edge rule (`Sdc::Scheme::ComputeEdgeVertexMask` with the
/// child rule known, as `Far::PrimvarRefiner` calls it): a sharp edge whose two child halves
/// stay sharp gives the crease mask; otherwise (the child vertex becomes a dart or smooth) the
/// smooth mask from `smooth` is blended with the crease mask by the parent sharpness `s`:
/// `s · crease + (1 - s) · smooth`.
///
/// With uniform creasing both halves stay sharp exactly when `s > 1`, so the blend weight is
/// at most 1. With Chaikin creasing a half can decay to zero while `s` lies in `(1, 4/3)`;
/// OpenSubdiv then uses `s` unclamped (a slight extrapolation), and so do we, to reproduce it.
pub fn edge_mask_with_sharpness(
    n: &EdgeNeighborhood,
    mask: &mut EdgeMask,
    scratch: &mut EdgeMask,
    smooth: impl Fn(&EdgeNeighborhood, &mut EdgeMask),
) {
    let s = n.sharpness;
    if s > 0.0 && n.child_sharpness[0] > 0.0 && n.child_sharpness[1] > 0.0 {
        mask.set_crease(n.num_faces);
        return;
    }
    smooth(n, mask);
    if s > 0.0 {
        scratch.set_crease(n.num_faces);
        mask.blend(1.0 - s, scratch, s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classify() {
        assert_eq!(Rule::classify(0.0, &[0.0, 0.0, 0.0]), Rule::Smooth);
        assert_eq!(Rule::classify(0.0, &[0.0, 2.0, 0.0]), Rule::Dart);
        assert_eq!(Rule::classify(0.0, &[1.0, 2.0, 0.0]), Rule::Crease);
        assert_eq!(Rule::classify(0.0, &[1.0, 2.0, 0.5]), Rule::Corner);
        assert_eq!(Rule::classify(3.0, &[0.0; 3]), Rule::Corner);
    }

    #[test]
    fn creasing() {
        assert_eq!(decrement(2.5), 1.5);
        assert_eq!(decrement(0.5), 0.0);
        assert_eq!(decrement(10.0), 10.0);
        // Chaikin: 3/4 of 2 + 1/4 of 4, minus 1.
        assert_eq!(
            child_edge_sharpness(Creasing::Chaikin, 2.0, &[2.0, 4.0, 0.0]),
            1.5
        );
        assert_eq!(
            child_edge_sharpness(Creasing::Uniform, 2.0, &[2.0, 4.0, 0.0]),
            1.0
        );
        assert_eq!(fractional_weight(0.0, 0.0, &[0.5, 0.0], &[0.0, 0.0]), 0.5);
        assert_eq!(fractional_weight(0.0, 0.0, &[3.0, 1.0], &[2.0, 0.0]), 1.0);
    }
}

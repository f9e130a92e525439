//! Limit positions, tangents and normals of Loop and Catmull-Clark surfaces.
//!
//! Maret 2003 §3.4 (eqs. 3.4–3.6): writing one subdivision step around a vertex as a local
//! subdivision matrix `S` acting on the vertex and its 1-ring, `P^k = S^k P^0` converges to
//! the limit point `l · P^0`, `l` being the left eigenvector of `S` for the eigenvalue 1
//! (normalised to sum 1); the left eigenvectors of the subdominant eigenvalue pair give two
//! tangents of the limit surface, whose cross product is the limit normal. The masks here are
//! those eigenvectors, in OpenSubdiv's closed forms (`Sdc::Scheme<SCHEME_LOOP>` and
//! `Sdc::Scheme<SCHEME_CATMARK>`, `assign{Smooth,Crease,Corner}Limit{,Tangent}Mask(s)` in
//! `opensubdiv/sdc/loopScheme.h` and `catmarkScheme.h`, OpenSubdiv 3.x), with their tangent
//! scalings:
//!
//! - **Loop, smooth** (valence `n`): position `(1 − nχ) v + χ Σ r_j`, `χ = 1/(n + 3/(8β))`,
//!   `β` of [`LoopWeights`] (Loop's eq. 3.7 or Warren's eq. 3.8; for `n = 6` both give
//!   `χ = 1/12`); tangents `Σ cos(2πj/n) r_j` and `Σ sin(2πj/n) r_j` (the eigenvalue
//!   `3/8 + 1/4 cos(2π/n)` of every β).
//! - **Catmull-Clark, smooth** (valence `n`, quads): position
//!   `(n² v + 4 Σ e_j + Σ f_j) / (n(n + 5))`, `e_j` the 1-ring, `f_j` the vertex opposite `v` in
//!   the `j`-th quad; tangents `Σ 4 cos(θj) e_j + Σ (cos θj + cos θ(j+1)) / (4λ − 1) f_j`,
//!   `θ = 2π/n`, `λ = 5/16 + 1/16 (cos θ + cos(θ/2) √(2(9 + cos θ)))` the subdominant
//!   eigenvalue, and its rotation by one step. OpenSubdiv treats valence 2 as a corner.
//! - **Crease** (both schemes; boundaries are creases, Maret §3.5): the crease is a uniform
//!   cubic B-spline curve, limit `2/3 v + 1/6 (r_a + r_b)` over the two sharp edges; tangent
//!   along the crease `r_a − r_b` (scaled), across it the formulas of Biermann, Levin & Zorin
//!   2000 as OpenSubdiv writes them.
//! - **Corner**: the vertex; tangents along its first two edges.
//!
//! # Semi-sharp features
//! As OpenSubdiv's `Far::PrimvarRefiner::Limit`, the mask follows the vertex's rule *at the
//! finest level* ([`Rule::classify`] on that level's sharpness): any edge sharpness left > 0
//! counts as sharp, so a vertex on a crease that would relax after further levels is
//! projected onto the crease curve. The limit is therefore exact when every sharpness of the
//! finest level is 0 or infinite — refine at least `ceil(max sharpness)` levels (with uniform
//! creasing) for exact limits.
//!
//! # Where the masks are approximate (as in OpenSubdiv)
//! - **Darts** take the smooth masks although their sharp edge is refined with the crease
//!   rule;
//! - with [`super::BoundaryMode::Crease`] (Biermann et al.'s modified Loop edge rules next to
//!   creases), smooth vertices next to a crease vertex whose sector does not have 3 faces take
//!   the standard Loop masks, although their edge to the crease vertex is refined with the
//!   modified rule;
//! - crease cross-tangents of irregular crease vertices use Biermann et al.'s formulas (exact
//!   for their modified rules).
//!
//! Positions elsewhere are exact: limit positions are invariant under further refinement
//! (tested to 1e-12).

use glam::DVec3;
use rayon::prelude::*;

use super::loop_scheme::{LoopRules, LoopWeights};
use super::refine::{self, Split};
use super::rules::{Rule, VertexMask};
use super::stencil::StencilTable;
use super::{Refinement, Scheme, SubdivideOptions};
use crate::mesh::{Mesh, SHARPNESS_INFINITE};
use crate::topology::Topology;
use crate::{Error, Result};

/// Which limit masks apply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LimitScheme {
    /// Loop, with the β of its smooth vertex rule.
    Loop(LoopWeights),
    /// Catmull-Clark (the finest level must be a quad mesh).
    CatmullClark,
}

impl LimitScheme {
    /// The limit masks of `opts.scheme`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a scheme without limit masks here (midpoint, bilinear:
    /// their limit is the refined mesh itself).
    pub fn from_options(opts: &SubdivideOptions) -> Result<LimitScheme> {
        match opts.scheme {
            Scheme::Loop => Ok(LimitScheme::Loop(opts.loop_weights)),
            Scheme::CatmullClark => Ok(LimitScheme::CatmullClark),
            other => Err(Error::InvalidArgument(format!(
                "limit positions are implemented for loop and catmull-clark, not {}",
                other.name()
            ))),
        }
    }
}

/// What a limit mask depends on: counts, the vertex's rule and, for a crease, its two sharp
/// edges.
///
/// Masks are in local terms as in [`super::rules`], with one difference: `faces[i]` weighs
/// the vertex *opposite* the centre in the `i`-th incident face (the quad's diagonal vertex;
/// OpenSubdiv's `SetFaceWeightsForFaceCenters(false)`), not the face centroid. Edges and faces
/// are in 1-ring order (face `i` between edges `i` and `i + 1`, counter-clockwise; a boundary
/// vertex starts at its leading boundary edge), which orients the tangents so that
/// `tangent1 × tangent2` points to the side the faces are counter-clockwise from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LimitNeighborhood {
    /// Number of incident edges.
    pub num_edges: usize,
    /// Number of incident faces.
    pub num_faces: usize,
    /// The vertex's rule at this (the finest) level.
    pub rule: Rule,
    /// For [`Rule::Crease`]: the first and the last sharp edge in ring order
    /// (`Sdc::Crease::GetSharpEdgePairOfCrease`).
    pub crease_ends: [usize; 2],
}

impl LimitNeighborhood {
    /// The neighbourhood of a smooth interior vertex of valence `n`.
    pub fn smooth(n: usize) -> LimitNeighborhood {
        LimitNeighborhood {
            num_edges: n,
            num_faces: n,
            rule: Rule::Smooth,
            crease_ends: [0, 0],
        }
    }

    /// The neighbourhood from incident edge sharpness (in ring order), vertex sharpness and
    /// face count.
    pub fn from_sharpness(
        edge_sharpness: &[f64],
        vertex_sharpness: f64,
        num_faces: usize,
    ) -> LimitNeighborhood {
        let rule = Rule::classify(vertex_sharpness, edge_sharpness);
        let mut crease_ends = [0, 0];
        if rule == Rule::Crease {
            crease_ends[0] = edge_sharpness.iter().position(|&s| s > 0.0).unwrap_or(0);
            crease_ends[1] = edge_sharpness.iter().rposition(|&s| s > 0.0).unwrap_or(0);
        }
        LimitNeighborhood {
            num_edges: edge_sharpness.len(),
            num_faces,
            rule,
            crease_ends,
        }
    }
}

/// Loop's smooth limit position mask for valence `n`: `χ = 1/(n + 3/(8β))` per neighbour,
/// `1 − nχ` for the vertex (`1/12` and `1/2` for `n = 6`).
pub fn loop_smooth_limit(weights: LoopWeights, n: usize, mask: &mut VertexMask) {
    mask.clear(n, n);
    let chi = if n == 6 {
        1.0 / 12.0
    } else {
        let beta = LoopRules {
            weights,
            ..Default::default()
        }
        .beta(n);
        1.0 / (n as f64 + 3.0 / (8.0 * beta))
    };
    mask.edges.iter_mut().for_each(|w| *w = chi);
    mask.vertex = if n == 6 { 0.5 } else { 1.0 - n as f64 * chi };
}

/// Loop's smooth limit tangent masks for valence `n`: `cos(2πj/n)` and `sin(2πj/n)` on the
/// 1-ring (exact `±1/2`, `±√3/2` for `n = 6`).
pub fn loop_smooth_limit_tangents(n: usize, t1: &mut VertexMask, t2: &mut VertexMask) {
    t1.clear(n, n);
    t2.clear(n, n);
    if n == 6 {
        let r = 0.5 * 3f64.sqrt();
        t1.edges.copy_from_slice(&[1.0, 0.5, -0.5, -1.0, -0.5, 0.5]);
        t2.edges.copy_from_slice(&[0.0, r, r, 0.0, -r, -r]);
        return;
    }
    let a = std::f64::consts::TAU / n as f64;
    for j in 0..n {
        t1.edges[j] = (a * j as f64).cos();
        t2.edges[j] = (a * j as f64).sin();
    }
}

/// Catmull-Clark's smooth limit position mask for valence `n`:
/// `(n² v + 4 Σ e_j + Σ f_j) / (n(n + 5))` (`4/9, 1/9, 1/36` for `n = 4`); valence 2 is a
/// corner, as in OpenSubdiv.
pub fn catmark_smooth_limit(n: usize, mask: &mut VertexMask) {
    if n == 2 {
        corner_limit(n, n, mask);
        return;
    }
    mask.clear(n, n);
    let (v, e, f) = if n == 4 {
        (4.0 / 9.0, 1.0 / 9.0, 1.0 / 36.0)
    } else {
        let nf = n as f64;
        let f = 1.0 / (nf * (nf + 5.0));
        (1.0 - nf * 5.0 * f, 4.0 * f, f)
    };
    mask.vertex = v;
    mask.edges.iter_mut().for_each(|w| *w = e);
    mask.faces.iter_mut().for_each(|w| *w = f);
}

/// Catmull-Clark's smooth limit tangent masks for valence `n`
/// (`assignSmoothLimitTangentMasks`); valence 2 takes the corner tangents.
pub fn catmark_smooth_limit_tangents(n: usize, t1: &mut VertexMask, t2: &mut VertexMask) {
    if n == 2 {
        corner_limit_tangents(n, n, 1.0, t1, t2);
        return;
    }
    t1.clear(n, n);
    t2.clear(n, n);
    if n == 4 {
        t1.edges.copy_from_slice(&[4.0, 0.0, -4.0, 0.0]);
        t1.faces.copy_from_slice(&[1.0, -1.0, -1.0, 1.0]);
        t2.edges.copy_from_slice(&[0.0, 4.0, 0.0, -4.0]);
        t2.faces.copy_from_slice(&[1.0, 1.0, -1.0, -1.0]);
        return;
    }
    let theta = std::f64::consts::TAU / n as f64;
    let (c, ch) = (theta.cos(), (0.5 * theta).cos());
    let lambda = 5.0 / 16.0 + (c + ch * (2.0 * (9.0 + c)).sqrt()) / 16.0;
    let fscale = 1.0 / (4.0 * lambda - 1.0);
    for j in 0..n {
        let (ci, ci1) = ((j as f64 * theta).cos(), ((j + 1) as f64 * theta).cos());
        t1.edges[j] = 4.0 * ci;
        t1.faces[j] = fscale * (ci + ci1);
    }
    // The second tangent is the first rotated by one step around the vertex.
    for j in 0..n {
        let p = (j + n - 1) % n;
        t2.edges[j] = t1.edges[p];
        t2.faces[j] = t1.faces[p];
    }
}

/// The crease limit position mask (both schemes): `2/3 v + 1/6 (r_a + r_b)`, the uniform cubic
/// B-spline along the crease.
pub fn crease_limit(
    num_edges: usize,
    num_faces: usize,
    crease_ends: [usize; 2],
    mask: &mut VertexMask,
) {
    mask.clear(num_edges, num_faces);
    mask.vertex = 2.0 / 3.0;
    mask.edges[crease_ends[0]] = 1.0 / 6.0;
    mask.edges[crease_ends[1]] = 1.0 / 6.0;
}

/// The corner limit position mask: the vertex itself.
pub fn corner_limit(num_edges: usize, num_faces: usize, mask: &mut VertexMask) {
    mask.clear(num_edges, num_faces);
    mask.vertex = 1.0;
}

/// Corner tangents: `scale (r_0 − v)` and `scale (r_1 − v)` (`scale` 3 for Loop, 1 for
/// Catmull-Clark, as OpenSubdiv).
pub fn corner_limit_tangents(
    num_edges: usize,
    num_faces: usize,
    scale: f64,
    t1: &mut VertexMask,
    t2: &mut VertexMask,
) {
    t1.clear(num_edges, num_faces);
    t2.clear(num_edges, num_faces);
    t1.vertex = -scale;
    t2.vertex = -scale;
    if num_edges > 0 {
        t1.edges[0] = scale;
    }
    if num_edges > 1 {
        t2.edges[1] = scale;
    }
}

/// Loop's crease limit tangents (`Scheme<SCHEME_LOOP>::assignCreaseLimitTangentMasks`): along
/// the crease `3/2 (r_a − r_b)`; across it, into the faces between `r_a` and `r_b`
/// counter-clockwise, by the number `k − 1` of interior edges there: `k = 1`: `3 (r_a + r_b) −
/// 6 v`; `k = 2`: `3 (r_1 − v)`; `k = 3` (regular): `√3 (r_1 + r_2 − v) − √3/2 (r_a + r_b)`;
/// `k > 3`: `−3 sin θ (r_a + r_b) + 6 (1 − cos θ) Σ sin(iθ) r_i`, `θ = π/k`.
pub fn loop_crease_limit_tangents(
    num_edges: usize,
    crease_ends: [usize; 2],
    t1: &mut VertexMask,
    t2: &mut VertexMask,
) {
    let [a, b] = crease_ends;
    t1.clear(num_edges, 0);
    t2.clear(num_edges, 0);
    t1.edges[a] = 1.5;
    t1.edges[b] = -1.5;
    let interior = b.saturating_sub(a + 1);
    match interior {
        0 => {
            t2.vertex = -6.0;
            t2.edges[a] = 3.0;
            t2.edges[b] = 3.0;
        }
        1 => {
            t2.vertex = -3.0;
            t2.edges[a + 1] = 3.0;
        }
        2 => {
            let r3 = 3f64.sqrt();
            t2.vertex = -r3;
            t2.edges[a] = -0.5 * r3;
            t2.edges[b] = -0.5 * r3;
            t2.edges[a + 1] = r3;
            t2.edges[a + 2] = r3;
        }
        _ => {
            let theta = std::f64::consts::PI / (interior + 1) as f64;
            let c = -3.0 * theta.sin();
            t2.edges[a] = c;
            t2.edges[b] = c;
            let e = -6.0 * (theta.cos() - 1.0);
            for i in 1..=interior {
                t2.edges[a + i] = e * (i as f64 * theta).sin();
            }
        }
    }
}

/// Catmull-Clark's crease limit tangents (`Scheme<SCHEME_CATMARK>::
/// assignCreaseLimitTangentMasks`): along the crease `1/2 (r_a − r_b)`; across it the uniform
/// B-spline cross tangent for one interior edge, Biermann et al.'s formula for more, and
/// `3 (r_a + r_b) − 6 v` for a single face.
pub fn catmark_crease_limit_tangents(
    num_edges: usize,
    num_faces: usize,
    crease_ends: [usize; 2],
    t1: &mut VertexMask,
    t2: &mut VertexMask,
) {
    let [a, b] = crease_ends;
    t1.clear(num_edges, num_faces);
    t2.clear(num_edges, num_faces);
    t1.edges[a] = 0.5;
    t1.edges[b] = -0.5;
    let interior = b.saturating_sub(a + 1);
    match interior {
        0 => {
            t2.vertex = -6.0;
            t2.edges[a] = 3.0;
            t2.edges[b] = 3.0;
        }
        1 => {
            t2.vertex = -4.0 / 6.0;
            t2.edges[a] = -1.0 / 6.0;
            t2.edges[a + 1] = 4.0 / 6.0;
            t2.edges[b] = -1.0 / 6.0;
            t2.faces[a] = 1.0 / 6.0;
            t2.faces[a + 1] = 1.0 / 6.0;
        }
        _ => {
            let k = (interior + 1) as f64;
            let theta = std::f64::consts::PI / k;
            let (c, s) = (theta.cos(), theta.sin());
            let denom = 1.0 / (k * (3.0 + c));
            let r = (c + 1.0) / s;
            t2.vertex = 4.0 * r * (c - 1.0) * denom;
            let cw = -r * (1.0 + 2.0 * c) * denom;
            t2.edges[a] = cw;
            t2.edges[b] = cw;
            t2.faces[a] = s * denom;
            for i in 1..=interior {
                let (si, si1) = ((i as f64 * theta).sin(), ((i + 1) as f64 * theta).sin());
                t2.edges[a + i] = 4.0 * si * denom;
                t2.faces[a + i] = (si + si1) * denom;
            }
        }
    }
}

/// The position and tangent masks of a vertex (`Sdc::Scheme::ComputeVertexLimitMask`):
/// smooth and dart vertices take the smooth masks, creases the crease masks, corners the
/// corner masks.
pub fn limit_masks(
    scheme: LimitScheme,
    n: &LimitNeighborhood,
    pos: &mut VertexMask,
    t1: &mut VertexMask,
    t2: &mut VertexMask,
) {
    let (ne, nf) = (n.num_edges, n.num_faces);
    match (n.rule, scheme) {
        (Rule::Smooth | Rule::Dart, LimitScheme::Loop(w)) => {
            loop_smooth_limit(w, nf, pos);
            loop_smooth_limit_tangents(nf, t1, t2);
        }
        (Rule::Smooth | Rule::Dart, LimitScheme::CatmullClark) => {
            catmark_smooth_limit(nf, pos);
            catmark_smooth_limit_tangents(nf, t1, t2);
        }
        (Rule::Crease, LimitScheme::Loop(_)) => {
            crease_limit(ne, nf, n.crease_ends, pos);
            loop_crease_limit_tangents(ne, n.crease_ends, t1, t2);
        }
        (Rule::Crease, LimitScheme::CatmullClark) => {
            crease_limit(ne, nf, n.crease_ends, pos);
            catmark_crease_limit_tangents(ne, nf, n.crease_ends, t1, t2);
        }
        (Rule::Corner, LimitScheme::Loop(_)) => {
            corner_limit(ne, nf, pos);
            corner_limit_tangents(ne, nf, 3.0, t1, t2);
        }
        (Rule::Corner, LimitScheme::CatmullClark) => {
            corner_limit(ne, nf, pos);
            corner_limit_tangents(ne, nf, 1.0, t1, t2);
        }
    }
}

/// Limit stencils of a level: each vertex's limit position and two limit tangents as weights
/// of that level's vertices (OpenSubdiv's `Far::LimitStencilTable` at the vertices). Evaluate
/// them on moving control points with [`StencilTable::apply`] (composed with the refinement's
/// tables, [`Refinement::evaluate`], for animation, Maret §5.1.1).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LimitStencils {
    /// Limit positions.
    pub position: StencilTable,
    /// First limit tangents (along the first edge, or along the crease).
    pub tangent1: StencilTable,
    /// Second limit tangents (`tangent1 × tangent2` is the outward normal).
    pub tangent2: StencilTable,
}

/// A level's vertices at the limit, with tangents and unit normals.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LimitSurface {
    /// Limit positions.
    pub positions: Vec<DVec3>,
    /// First limit tangents.
    pub tangents1: Vec<DVec3>,
    /// Second limit tangents.
    pub tangents2: Vec<DVec3>,
    /// Unit normals `normalize(tangent1 × tangent2)` (zero where the tangents are parallel,
    /// and at isolated vertices).
    pub normals: Vec<DVec3>,
}

/// Vertices per parallel work item.
const CHUNK: usize = 4096;

/// One chunk's three stencils, in the flat layout.
#[derive(Default)]
struct Part {
    sizes: [Vec<u32>; 3],
    indices: [Vec<u32>; 3],
    weights: [Vec<f64>; 3],
}

impl LimitStencils {
    /// The limit stencils of every vertex of `topo`, a level whose rings are ordered
    /// ([`Topology::build`] or a refinement with ring ordering) and whose sharpness is set as
    /// the refiner sets it (boundary edges infinitely sharp; see
    /// [`Refinement::finest_topology`]). Isolated vertices keep their position and get zero
    /// tangents.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if the rings are not ordered, a vertex is not manifold, or,
    /// for Catmull-Clark, a face is not a quad (refine at least one level first), or, for
    /// Loop, not a triangle; the message names the element.
    pub fn build(topo: &Topology, scheme: LimitScheme) -> Result<LimitStencils> {
        if !topo.rings_ordered {
            return Err(Error::InvalidArgument(
                "limit stencils need ordered 1-rings (build the topology with Topology::build)"
                    .into(),
            ));
        }
        build_tables(topo, scheme, true)
    }

    /// The limit position stencils only ([`LimitStencils::position`]); the position masks are
    /// symmetric, so `topo`'s 1-rings need not be ordered.
    ///
    /// # Errors
    /// As [`LimitStencils::build`], except for the ring order.
    pub fn positions(topo: &Topology, scheme: LimitScheme) -> Result<StencilTable> {
        Ok(build_tables(topo, scheme, false)?.position)
    }

    /// The limit surface of the level's `positions`.
    ///
    /// # Panics
    /// If `positions` does not have one entry per vertex of the level.
    pub fn evaluate(&self, positions: &[DVec3]) -> LimitSurface {
        let p = self.position.apply(positions);
        let t1 = self.tangent1.apply(positions);
        let t2 = self.tangent2.apply(positions);
        let normals = t1
            .par_iter()
            .zip(&t2)
            .map(|(a, b)| a.cross(*b).normalize_or_zero())
            .collect();
        LimitSurface {
            positions: p,
            tangents1: t1,
            tangents2: t2,
            normals,
        }
    }
}

/// The three limit stencil tables of `topo` (the tangent tables empty unless `tangents`).
fn build_tables(topo: &Topology, scheme: LimitScheme, tangents: bool) -> Result<LimitStencils> {
    let arity = match scheme {
        LimitScheme::Loop(_) => 3,
        LimitScheme::CatmullClark => 4,
    };
    if let Some(f) = (0..topo.num_faces()).find(|&f| topo.face_vertices(f).len() != arity) {
        return Err(Error::InvalidArgument(format!(
            "face {f} has {} vertices: {} limit masks need {}{}",
            topo.face_vertices(f).len(),
            if arity == 3 { "loop" } else { "catmull-clark" },
            if arity == 3 { "triangles" } else { "quads" },
            if arity == 4 {
                " (refine at least one level first)"
            } else {
                ""
            }
        )));
    }
    use crate::topology::VertexKind;
    if let Some(v) = topo
        .vertex_kinds
        .iter()
        .position(|k| matches!(k, VertexKind::NonManifold | VertexKind::Irregular))
    {
        return Err(Error::InvalidArgument(format!(
            "vertex {v} is not manifold: its limit is undefined"
        )));
    }
    let nv = topo.num_vertices as usize;
    let parts: Vec<Part> = (0..nv.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut part = Part::default();
            let mut masks: [VertexMask; 3] = Default::default();
            let mut sharp = Vec::new();
            let mut ring = Vec::new();
            let mut opposite = Vec::new();
            for v in c * CHUNK..((c + 1) * CHUNK).min(nv) {
                let edges = topo.vertex_edges(v);
                if edges.is_empty() {
                    for k in 0..if tangents { 3 } else { 1 } {
                        part.sizes[k].push(u32::from(k == 0));
                    }
                    part.indices[0].push(v as u32);
                    part.weights[0].push(1.0);
                    continue;
                }
                sharp.clear();
                sharp.extend(edges.iter().map(|&e| topo.edge_sharpness[e as usize]));
                let faces = topo.vertex_faces(v);
                let n = LimitNeighborhood::from_sharpness(
                    &sharp,
                    topo.vertex_sharpness[v],
                    faces.len(),
                );
                let [pos, t1, t2] = &mut masks;
                limit_masks(scheme, &n, pos, t1, t2);
                let masks = &masks[..if tangents { 3 } else { 1 }];
                ring.clear();
                ring.extend(topo.ring(v));
                opposite.clear();
                for (&f, &i) in faces.iter().zip(topo.vertex_face_corners(v)) {
                    let fv = topo.face_vertices(f as usize);
                    opposite.push(fv[(i as usize + 2) % fv.len()]);
                }
                for (k, m) in masks.iter().enumerate() {
                    let start = part.indices[k].len();
                    let (idx, w) = (&mut part.indices[k], &mut part.weights[k]);
                    let mut add = |i: u32, x: f64| {
                        if x == 0.0 {
                            return;
                        }
                        if let Some(p) = idx[start..].iter().position(|&y| y == i) {
                            w[start + p] += x;
                        } else {
                            idx.push(i);
                            w.push(x);
                        }
                    };
                    // Small weights first, as OpenSubdiv sums them.
                    for (&o, &x) in opposite.iter().zip(&m.faces) {
                        add(o, x);
                    }
                    for (&r, &x) in ring.iter().zip(&m.edges) {
                        add(r, x);
                    }
                    add(v as u32, m.vertex);
                    part.sizes[k].push((idx.len() - start) as u32);
                }
            }
            part
        })
        .collect();
    let table = |k: usize| {
        let total: usize = parts.iter().map(|p| p.indices[k].len()).sum();
        let mut t = StencilTable {
            num_sources: nv as u32,
            child_sources: 0,
            offsets: Vec::with_capacity(nv + 1),
            indices: Vec::with_capacity(total),
            weights: Vec::with_capacity(total),
        };
        t.offsets.push(0);
        for p in &parts {
            for &s in &p.sizes[k] {
                let last = *t.offsets.last().unwrap_or(&0);
                t.offsets.push(last + s);
            }
            t.indices.extend_from_slice(&p.indices[k]);
            t.weights.extend_from_slice(&p.weights[k]);
        }
        t
    };
    Ok(LimitStencils {
        position: table(0),
        tangent1: if tangents {
            table(1)
        } else {
            StencilTable::default()
        },
        tangent2: if tangents {
            table(2)
        } else {
            StencilTable::default()
        },
    })
}

impl Refinement {
    /// The finest level's topology, with ordered 1-rings and the sharpness the refiner would
    /// use at that level: the carried crease and corner tags, boundary edges infinitely sharp
    /// (for `levels = 0`, the level-0 topology as refined, with `--sharp-angle` creases and
    /// OpenSubdiv boundary corners).
    pub fn finest_topology(&self) -> Topology {
        if let [t] = self.topologies.as_slice() {
            if t.num_vertices as usize == self.positions.len()
                && t.face_vertices.len() == self.face_vertices.len()
                && t.rings_ordered
            {
                // levels = 0: the finest level is level 0, kept as refined.
                return t.clone();
            }
        }
        let mesh = Mesh {
            positions: vec![DVec3::ZERO; self.positions.len()],
            face_offsets: self.face_offsets.clone(),
            face_indices: self.face_vertices.clone(),
            edge_tags: self.edge_tags.clone(),
            vertex_tags: self.vertex_tags.clone(),
            ..Mesh::new()
        };
        let mut topo = Topology::build(&mesh);
        for e in 0..topo.num_edges() {
            if topo.is_boundary_edge(e) {
                topo.edge_sharpness[e] = SHARPNESS_INFINITE;
            }
        }
        topo
    }

    /// Limit stencils of the finest level (see [`LimitStencils::build`]).
    ///
    /// # Errors
    /// As [`LimitStencils::build`].
    pub fn limit_stencils(&self, scheme: LimitScheme) -> Result<LimitStencils> {
        LimitStencils::build(&self.finest_topology(), scheme)
    }

    /// The finest level's vertices projected to the limit surface, with limit normals.
    ///
    /// # Errors
    /// As [`LimitStencils::build`].
    pub fn limit(&self, scheme: LimitScheme) -> Result<LimitSurface> {
        Ok(self.limit_stencils(scheme)?.evaluate(&self.positions))
    }
}

/// The finest level's topology, refined from the last level kept in `r` (no edge matching;
/// the same tables as [`Refinement::finest_topology`], by the ordering contract of
/// [`super::refine`]), 1-rings ordered if `order_rings`.
fn finest_topology_from_parent(
    r: &Refinement,
    opts: &SubdivideOptions,
    order_rings: bool,
) -> Topology {
    let levels = opts.levels as usize;
    if levels == 0 || r.topologies.len() != levels {
        return r.finest_topology();
    }
    let parent = &r.topologies[levels - 1];
    let split = if opts.scheme == Scheme::Loop {
        Split::Triangles
    } else {
        Split::Polygons
    };
    let (mut child, halves) = refine::refine_topology(parent, split, order_rings);
    super::child_sharpness(parent, &mut child, &halves, opts.creasing);
    child
}

/// The finest level of `mesh` refined by `opts` as a mesh whose positions are `limit(r,
/// topology)`, with colours and texture coordinates refined.
fn subdivide_with(
    mesh: &Mesh,
    opts: &SubdivideOptions,
    order_rings: bool,
    limit: impl FnOnce(&Refinement, &Topology) -> Result<Vec<DVec3>>,
) -> Result<Mesh> {
    let carry = mesh.colors.is_some() || mesh.uvs.is_some();
    let r = Refinement::build_with(mesh, opts, carry, true)?;
    let topo = finest_topology_from_parent(&r, opts, order_rings);
    let positions = limit(&r, &topo)?;
    drop(topo);
    let mut out = Mesh::new();
    if opts.levels == 0 {
        out.colors.clone_from(&mesh.colors);
        out.uvs.clone_from(&mesh.uvs);
    } else if carry {
        if let Some(c) = &mesh.colors {
            out.colors = Some(r.evaluate(c)?);
        }
        if let Some(t) = &mesh.uvs {
            out.uvs = Some(r.evaluate(t)?);
        }
    }
    out.positions = positions;
    out.face_offsets = r.face_offsets;
    out.face_indices = r.face_vertices;
    out.edge_tags = r.edge_tags;
    out.vertex_tags = r.vertex_tags;
    Ok(out)
}

/// [`super::subdivide`], with the finest level's vertices moved to their limit positions
/// (Maret §3.4); also returns the limit surface (positions, tangents, unit normals — the
/// [`Mesh`] type has no normal attribute). Colours and texture coordinates keep their refined
/// (not limit) values.
///
/// # Errors
/// As [`Refinement::build`]; [`Error::InvalidArgument`] for a scheme without limit masks
/// (midpoint, bilinear) and for Catmull-Clark with 0 levels on a mesh that is not all quads.
pub fn subdivide_limit(mesh: &Mesh, opts: &SubdivideOptions) -> Result<(Mesh, LimitSurface)> {
    let scheme = LimitScheme::from_options(opts)?;
    let mut surface = LimitSurface::default();
    let out = subdivide_with(mesh, opts, true, |r, topo| {
        surface = LimitStencils::build(topo, scheme)?.evaluate(&r.positions);
        Ok(surface.positions.clone())
    })?;
    Ok((out, surface))
}

/// [`subdivide_limit`] without tangents and normals (faster: the finest level's 1-rings need
/// no ordering).
///
/// # Errors
/// As [`subdivide_limit`].
pub fn subdivide_limit_positions(mesh: &Mesh, opts: &SubdivideOptions) -> Result<Mesh> {
    let scheme = LimitScheme::from_options(opts)?;
    subdivide_with(mesh, opts, false, |r, topo| {
        Ok(LimitStencils::positions(topo, scheme)?.apply(&r.positions))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::subdivision::rules::{Rules, VertexNeighborhood};

    /// A dense matrix as rows.
    type Mat = Vec<Vec<f64>>;

    /// `x · S` for a row vector `x`.
    fn left_mul(x: &[f64], s: &Mat) -> Vec<f64> {
        (0..s[0].len())
            .map(|c| x.iter().zip(s).map(|(a, row)| a * row[c]).sum())
            .collect()
    }

    /// Loop's local subdivision matrix (Maret eq. 3.4) on `(v, r_0..r_{n-1})`, from the
    /// scheme's own refinement rules.
    fn loop_matrix(weights: LoopWeights, n: usize) -> Mat {
        let rules = LoopRules {
            weights,
            ..Default::default()
        };
        let zeros = [0.0; 32];
        let (mut m, mut s) = (VertexMask::default(), VertexMask::default());
        rules.vertex_mask(&VertexNeighborhood::smooth(n, &zeros), &mut m, &mut s);
        let mut rows = vec![vec![0.0; n + 1]; n + 1];
        rows[0][0] = m.vertex;
        rows[0][1..].copy_from_slice(&m.edges);
        for j in 0..n {
            // Edge point of edge j: 3/8 (v + r_j) + 1/8 (r_{j-1} + r_{j+1}).
            let r = &mut rows[j + 1];
            r[0] += 0.375;
            r[1 + j] += 0.375;
            r[1 + (j + n - 1) % n] += 0.125;
            r[1 + (j + 1) % n] += 0.125;
        }
        rows
    }

    /// Catmull-Clark's local subdivision matrix on `(v, e_0..e_{n-1}, f_0..f_{n-1})` of a
    /// quad fan (face `j` is `v, e_j, f_j, e_{j+1}`).
    fn catmark_matrix(n: usize) -> Mat {
        let dim = 2 * n + 1;
        let (e, f) = (|j: usize| 1 + j % n, |j: usize| 1 + n + j % n);
        // Face point c_j as a row.
        let centroid = |j: usize| {
            let mut r = vec![0.0; dim];
            for k in [0, e(j), f(j), e(j + 1)] {
                r[k] += 0.25;
            }
            r
        };
        let nf = n as f64;
        let mut rows = vec![vec![0.0; dim]; dim];
        rows[0][0] = (nf - 2.0) / nf;
        for j in 0..n {
            rows[0][e(j)] += 1.0 / (nf * nf);
            for (k, w) in centroid(j).into_iter().enumerate() {
                rows[0][k] += w / (nf * nf) * nf / nf;
            }
        }
        for j in 0..n {
            let (cp, c) = (centroid(j + n - 1), centroid(j));
            let r = &mut rows[e(j)];
            r[0] += 0.25;
            r[e(j)] += 0.25;
            for k in 0..dim {
                r[k] += 0.25 * (cp[k] + c[k]);
            }
            rows[f(j)] = centroid(j);
        }
        rows
    }

    fn assert_eigen(x: &[f64], s: &Mat, lambda: f64, what: &str) {
        let y = left_mul(x, s);
        for (a, b) in y.iter().zip(x) {
            assert!(
                (a - lambda * b).abs() < 1e-13,
                "{what}: {y:?} vs {lambda} {x:?}"
            );
        }
    }

    fn flat(m: &VertexMask) -> Vec<f64> {
        let mut x = vec![m.vertex];
        x.extend(&m.edges);
        x.extend(&m.faces);
        x
    }

    #[test]
    fn maret_regular_loop_matrix() {
        // Maret eq. 3.4: the regular matrix, 1/16 (10, 1, ...; 6, 6, 2, 0, ...).
        let s = loop_matrix(LoopWeights::Loop, 6);
        assert!((s[0][0] - 10.0 / 16.0).abs() < 1e-15 && (s[0][1] - 1.0 / 16.0).abs() < 1e-15);
        assert_eq!(s[1][..4], [6.0 / 16.0, 6.0 / 16.0, 2.0 / 16.0, 0.0]);
        let mut m = VertexMask::default();
        loop_smooth_limit(LoopWeights::Loop, 6, &mut m);
        assert_eq!(m.vertex, 0.5);
        assert_eq!(m.edges, vec![1.0 / 12.0; 6]);
    }

    #[test]
    fn loop_masks_are_left_eigenvectors() {
        for weights in [LoopWeights::Loop, LoopWeights::Warren] {
            for n in 3..13 {
                let s = loop_matrix(weights, n);
                let (mut p, mut t1, mut t2) = Default::default();
                limit_masks(
                    LimitScheme::Loop(weights),
                    &LimitNeighborhood::smooth(n),
                    &mut p,
                    &mut t1,
                    &mut t2,
                );
                let x = flat(&p);
                assert!((p.sum() - 1.0).abs() < 1e-14);
                assert_eigen(&x[..n + 1], &s, 1.0, "loop position");
                let lambda = 0.375 + 0.25 * (std::f64::consts::TAU / n as f64).cos();
                for t in [&t1, &t2] {
                    assert!(t.sum().abs() < 1e-13, "tangent sum {n}");
                    assert_eigen(&flat(t)[..n + 1], &s, lambda, "loop tangent");
                }
            }
        }
    }

    #[test]
    fn catmark_masks_are_left_eigenvectors() {
        for n in 3..13 {
            let s = catmark_matrix(n);
            // Each row of the local matrix is affine.
            for row in &s {
                assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-14);
            }
            let (mut p, mut t1, mut t2) = Default::default();
            limit_masks(
                LimitScheme::CatmullClark,
                &LimitNeighborhood::smooth(n),
                &mut p,
                &mut t1,
                &mut t2,
            );
            assert!((p.sum() - 1.0).abs() < 1e-14);
            assert_eigen(&flat(&p), &s, 1.0, "catmark position");
            // The subdominant eigenvalue, from the power of the tangent mask itself.
            let x = flat(&t1);
            let y = left_mul(&x, &s);
            let k = (0..x.len())
                .max_by(|&a, &b| x[a].abs().total_cmp(&x[b].abs()))
                .unwrap();
            let lambda = y[k] / x[k];
            let theta = std::f64::consts::TAU / n as f64;
            let expect = 5.0 / 16.0
                + (theta.cos() + (0.5 * theta).cos() * (2.0 * (9.0 + theta.cos())).sqrt()) / 16.0;
            assert!(
                (lambda - expect).abs() < 1e-13,
                "n = {n}: {lambda} vs {expect}"
            );
            for t in [&t1, &t2] {
                assert!(t.sum().abs() < 1e-13);
                assert_eigen(&flat(t), &s, expect, "catmark tangent");
            }
        }
        // The regular case: (1, 4, 1) ⊗ (1, 4, 1) / 36.
        let mut m = VertexMask::default();
        catmark_smooth_limit(4, &mut m);
        assert_eq!(
            (m.vertex, m.edges[0], m.faces[0]),
            (16.0 / 36.0, 4.0 / 36.0, 1.0 / 36.0)
        );
    }

    /// Local matrix of a boundary vertex with `k` faces (`k + 1` edges, the first and last
    /// sharp), Loop's unmodified rules, on `(v, r_0..r_k)`.
    fn loop_crease_matrix(k: usize) -> Mat {
        let dim = k + 2;
        let mut rows = vec![vec![0.0; dim]; dim];
        rows[0][0] = 0.75;
        rows[0][1] = 0.125;
        rows[0][k + 1] = 0.125;
        for j in 0..=k {
            let r = &mut rows[j + 1];
            if j == 0 || j == k {
                r[0] = 0.5;
                r[j + 1] = 0.5;
            } else {
                r[0] = 0.375;
                r[j + 1] = 0.375;
                r[j] = 0.125;
                r[j + 2] = 0.125;
            }
        }
        rows
    }

    #[test]
    fn crease_and_corner_masks() {
        for k in 1..8 {
            let n = LimitNeighborhood {
                num_edges: k + 1,
                num_faces: k,
                rule: Rule::Crease,
                crease_ends: [0, k],
            };
            for scheme in [
                LimitScheme::Loop(LoopWeights::Loop),
                LimitScheme::CatmullClark,
            ] {
                let (mut p, mut t1, mut t2) = Default::default();
                limit_masks(scheme, &n, &mut p, &mut t1, &mut t2);
                assert!((p.sum() - 1.0).abs() < 1e-15);
                assert_eq!(
                    (p.vertex, p.edges[0], p.edges[k]),
                    (2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0)
                );
                assert!(
                    t1.sum().abs() < 1e-14 && t2.sum().abs() < 1e-13,
                    "{scheme:?} {k}"
                );
                // The cross tangent points into the faces (positive on interior edges).
                if k > 1 {
                    assert!(t2.edges[1..k].iter().all(|&w| w > 0.0), "{scheme:?} {k}");
                }
            }
            // The crease curve: (1/6, 2/3, 1/6) is the limit of (1/8, 3/4, 1/8), (1/2, 1/2),
            // and the regular (k = 3) Loop cross tangent is an eigenvector of the fan.
            let s = loop_crease_matrix(k);
            let (mut p, mut t1, mut t2) = Default::default();
            limit_masks(
                LimitScheme::Loop(LoopWeights::Loop),
                &n,
                &mut p,
                &mut t1,
                &mut t2,
            );
            assert_eigen(&flat(&p)[..k + 2], &s, 1.0, "crease position");
            assert_eigen(&flat(&t1)[..k + 2], &s, 0.5, "crease tangent");
            if k == 3 {
                assert_eigen(&flat(&t2)[..k + 2], &s, 0.5, "regular cross tangent");
            }
        }
        let n = LimitNeighborhood::from_sharpness(&[0.0, 10.0, 0.0, 2.0, 0.5], 0.0, 5);
        assert_eq!(n.rule, Rule::Corner);
        let (mut p, mut t1, mut t2) = Default::default();
        limit_masks(LimitScheme::CatmullClark, &n, &mut p, &mut t1, &mut t2);
        assert_eq!((p.vertex, p.sum()), (1.0, 1.0));
        assert_eq!((t1.sum(), t2.sum()), (0.0, 0.0));
        let n = LimitNeighborhood::from_sharpness(&[0.0, 10.0, 0.0, 0.5, 0.0], 0.0, 5);
        assert_eq!((n.rule, n.crease_ends), (Rule::Crease, [1, 3]));
    }
}

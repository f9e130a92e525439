//! Quad/triangle subdivision (Stam & Loop 2003, "Quad/triangle subdivision", Computer Graphics
//! Forum 22(1)), the scheme of Lavoué, Dupont & Baskurt's CAD compression (§III.2, Figs. 3-4),
//! with the sharp-edge rules of Hoppe et al. 1994 (Lavoué §V.1, eqs. 2-3).
//!
//! Stam and Loop describe one step as a *linear subdivision* — edges split at their midpoints,
//! triangles 1-to-4, quads 1-to-4 around their centroid ([`Split::QuadTri`]) — followed by a
//! *smoothing* of every vertex of the linearly subdivided mesh by a mask over itself and its
//! direct neighbours (Lavoué Fig. 4): Loop's mask (Fig. 4a) around a vertex surrounded only by
//! triangles, Catmull-Clark's (Fig. 4b) around one surrounded only by quads, and otherwise the
//! quad/triangle mask (Fig. 4c)
//!
//! ```text
//! p' = α p + β Σ (edge neighbours) + γ Σ (opposite corners of incident quads),
//! α = 1 / (1 + n_e/2 + n_q/4),  β = α/2,  γ = α/4,
//! ```
//!
//! with `n_e` edges and `n_q` quads around the vertex. This module composes the two steps into
//! masks over the *parent* vertices, so that the refiner, stencil tables and cached
//! re-evaluation work unchanged:
//!
//! - **face point** of a quad: its centroid (all four faces around it in the linear mesh are
//!   quads, Catmull-Clark's mask of valence 4 leaves it at the centroid);
//! - **edge points** (their linear-mesh neighbourhood only holds children of the edge's two
//!   faces): triangle–triangle `3/8 (v0 + v1) + 1/8 (o0 + o1)` (Loop), quad–quad
//!   `1/4 (v0 + v1) + 1/4 (c0 + c1)` (Catmull-Clark, `c` face points), and the mixed
//!   quad–triangle edge `3/8 (v0 + v1) + 1/8 o + 1/16 (y + z)` (`o` the triangle's opposite
//!   vertex, `y, z` the quad's other two corners), written as `5/16 (v0 + v1) + 1/8 o + 1/4 c`;
//! - **vertex points**: Loop's rule `(1 − nβ) v + β Σ r_j` among triangles only,
//!   Catmull-Clark's `(n − 2)/n v + 1/n² Σ r_j + 1/n² Σ c_f` among quads only, and among both
//!   the composition of the mask above: `(α + n_e β/2) v + β/2 Σ r_j + γ Σ_quads c_q`.
//!
//! On a triangle mesh the scheme is therefore Loop (with Hoppe's crease rules, the crate's
//! Loop under [`super::BoundaryMode::OpenSubdiv`]), on a quad mesh Catmull-Clark (tested to
//! 1e-12 against both).
//!
//! **Sharp edges and boundaries** (Lavoué §III.2 and §V.1: "the rules defined by Hoppe et
//! al. for sharp or boundary edges"): an edge point on a sharp edge is the midpoint, a vertex
//! with two sharp edges moves to `1/8 (P_{i−1} + 6 P_i + P_{i+1})` over its sharp neighbours
//! (eq. 2: the cubic B-spline curve rule, as [`super::curves`] refines crease curves), a
//! corner (three or more sharp edges, or a corner tag) stays (eq. 3); a dart (one sharp edge)
//! takes the smooth rule. Boundary edges are sharp. Semi-sharp creases blend the rules as in
//! OpenSubdiv, like the crate's other schemes.
//!
//! Not implemented: the optional correction of the mixed mask at low-valence vertices that
//! Stam & Loop propose to tune eigenvalues (Lavoué uses the masks of Fig. 4 as they are).

use super::loop_scheme::{LoopBoundary, LoopRules, LoopWeights};
use super::refine::Split;
use super::rules::{
    edge_mask_with_sharpness, vertex_mask_with_transition, EdgeMask, EdgeNeighborhood, Rule, Rules,
    VertexMask, VertexNeighborhood,
};
use crate::mesh::Mesh;
use crate::MeshError;

/// The quad/triangle scheme's rules.
#[derive(Clone, Copy, Debug, Default)]
pub struct QuadTriRules {
    /// β of Loop's vertex rule around vertices surrounded only by triangles.
    pub weights: LoopWeights,
}

/// Checks that every face is a triangle or a quad, the faces the scheme takes.
///
/// # Errors
/// [`MeshError::UnsupportedFaces`] listing the other faces and suggesting Catmull-Clark.
pub fn require_triangles_and_quads(mesh: &Mesh) -> Result<(), MeshError> {
    let faces: Vec<u32> = (0..mesh.num_faces())
        .filter(|&f| !matches!(mesh.face_arity(f), 3 | 4))
        .map(|f| f as u32)
        .collect();
    if faces.is_empty() {
        Ok(())
    } else {
        Err(MeshError::UnsupportedFaces {
            scheme: "quad-tri",
            needs: "triangles and quads",
            faces,
            hint: "use catmull-clark (any polygons)",
        })
    }
}

/// Weights `(α, β, γ)` of the mixed smoothing mask of Stam & Loop (Lavoué Fig. 4c) for a
/// vertex of the linearly subdivided mesh with `n_e` edges and `n_q` quads around it.
pub fn mixed_smoothing_weights(n_e: usize, n_q: usize) -> (f64, f64, f64) {
    let alpha = 1.0 / (1.0 + 0.5 * n_e as f64 + 0.25 * n_q as f64);
    (alpha, 0.5 * alpha, 0.25 * alpha)
}

impl QuadTriRules {
    /// The mask of a vertex following `rule`, `arities[i]` being the arity of its `i`-th face.
    fn rule_mask(&self, rule: Rule, n: &VertexNeighborhood, arities: &[u32], m: &mut VertexMask) {
        match rule {
            Rule::Smooth | Rule::Dart => {
                let k = n.valence();
                m.clear(k, n.num_faces);
                let quads = arities.iter().filter(|&&a| a == 4).count();
                let kf = k as f64;
                if quads == 0 {
                    // Loop (Fig. 4a composed with the linear split).
                    let b = LoopRules {
                        weights: self.weights,
                        boundary: LoopBoundary::OpenSubdiv,
                    }
                    .beta(k);
                    m.vertex = 1.0 - kf * b;
                    m.edges.iter_mut().for_each(|w| *w = b);
                } else if quads == arities.len() {
                    // Catmull-Clark (Fig. 4b).
                    m.vertex = (kf - 2.0) / kf;
                    let w = 1.0 / (kf * kf);
                    m.edges.iter_mut().for_each(|x| *x = w);
                    m.faces.iter_mut().for_each(|x| *x = w);
                } else {
                    // Fig. 4c: edge neighbours of the linear mesh are the midpoints
                    // (v + r_j)/2, the opposite corners of its quads the face points c_q.
                    let (alpha, beta, gamma) = mixed_smoothing_weights(k, quads);
                    m.vertex = alpha + 0.5 * beta * kf;
                    m.edges.iter_mut().for_each(|w| *w = 0.5 * beta);
                    for (w, &a) in m.faces.iter_mut().zip(arities) {
                        if a == 4 {
                            *w = gamma;
                        }
                    }
                }
            }
            Rule::Crease => m.set_crease(n, |i| n.edge_sharpness[i] > 0.0),
            Rule::Corner => m.set_corner(n),
        }
    }

    /// The smooth edge mask for faces of the given arities (see the module documentation).
    fn smooth_edge(n: &EdgeNeighborhood, arities: &[u32], m: &mut EdgeMask) {
        m.clear(n.num_faces);
        if n.num_faces != 2 {
            // A boundary edge that is not sharp (never produced by the refiner, which
            // sharpens boundaries): fall back to the midpoint.
            m.ends = [0.5, 0.5];
            return;
        }
        // Each face contributes half of its side of the mask: a triangle 3/16 per end and
        // 1/8 its opposite vertex, a quad 1/8 per end and 1/4 its centroid.
        for (w, &a) in m.faces.iter_mut().zip(arities) {
            let (end, face) = if a == 3 {
                (3.0 / 16.0, 0.125)
            } else {
                (0.125, 0.25)
            };
            m.ends[0] += end;
            m.ends[1] += end;
            *w = face;
        }
    }
}

impl Rules for QuadTriRules {
    fn name(&self) -> &'static str {
        "quad-tri"
    }

    fn split(&self) -> Split {
        Split::QuadTri
    }

    /// Without face arities, the faces are taken to be triangles (the refiner calls
    /// [`Rules::vertex_mask_with_arities`]).
    fn vertex_mask(&self, n: &VertexNeighborhood, mask: &mut VertexMask, scratch: &mut VertexMask) {
        let tris = vec![3u32; n.num_faces];
        self.vertex_mask_with_arities(n, &tris, mask, scratch);
    }

    /// Without face arities, every face has [`EdgeNeighborhood::face_arity`].
    fn edge_mask(&self, n: &EdgeNeighborhood, mask: &mut EdgeMask, scratch: &mut EdgeMask) {
        let arities = vec![n.face_arity as u32; n.num_faces];
        self.edge_mask_with_arities(n, &arities, mask, scratch);
    }

    fn vertex_mask_with_arities(
        &self,
        n: &VertexNeighborhood,
        face_arities: &[u32],
        mask: &mut VertexMask,
        scratch: &mut VertexMask,
    ) {
        vertex_mask_with_transition(n, mask, scratch, |r, n, m| {
            self.rule_mask(r, n, face_arities, m)
        });
    }

    fn edge_mask_with_arities(
        &self,
        n: &EdgeNeighborhood,
        face_arities: &[u32],
        mask: &mut EdgeMask,
        scratch: &mut EdgeMask,
    ) {
        edge_mask_with_sharpness(n, mask, scratch, |n, m| {
            Self::smooth_edge(n, face_arities, m)
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mixed edge rule composed by hand from the linear split and Fig. 4c: the edge point
    /// of a quad–triangle edge has 5 edges and 2 quads around it in the linear mesh.
    #[test]
    fn mixed_edge_rule_from_smoothing_mask() {
        let (a, b, g) = mixed_smoothing_weights(5, 2);
        assert_eq!((a, b, g), (0.25, 0.125, 0.0625));
        // Quad (v0, v1, z, y), triangle (v1, v0, o). Neighbours of m = (v0+v1)/2: v0, v1,
        // (v0+o)/2, (v1+o)/2, c = (v0+v1+y+z)/4; quad corners (v0+y)/2, (v1+z)/2.
        // Coefficients over (v0, v1, o, y, z):
        let m = [0.5, 0.5, 0.0, 0.0, 0.0];
        let nbrs = [
            [1.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0, 0.0],
            [0.5, 0.0, 0.5, 0.0, 0.0],
            [0.0, 0.5, 0.5, 0.0, 0.0],
            [0.25, 0.25, 0.0, 0.25, 0.25],
        ];
        let diag = [[0.5, 0.0, 0.0, 0.5, 0.0], [0.0, 0.5, 0.0, 0.0, 0.5]];
        let mut w = [0.0; 5];
        for i in 0..5 {
            w[i] = a * m[i]
                + b * nbrs.iter().map(|x| x[i]).sum::<f64>()
                + g * diag.iter().map(|x| x[i]).sum::<f64>();
        }
        assert_eq!(w, [0.375, 0.375, 0.125, 0.0625, 0.0625]);
        // The mask the rules give, expanded (centroid weight spread over its corners).
        let n = EdgeNeighborhood {
            sharpness: 0.0,
            num_faces: 2,
            face_arity: 4,
            ends: [None, None],
            child_sharpness: [0.0; 2],
        };
        let (mut em, mut es) = (EdgeMask::default(), EdgeMask::default());
        QuadTriRules::default().edge_mask_with_arities(&n, &[4, 3], &mut em, &mut es);
        let c = em.faces[0] / 4.0;
        assert_eq!(
            [em.ends[0] + c, em.ends[1] + c, em.faces[1], c, c],
            [0.375, 0.375, 0.125, 0.0625, 0.0625]
        );
    }

    #[test]
    fn masks_are_affine() {
        let zeros = [0.0; 8];
        let (mut m, mut s) = (VertexMask::default(), VertexMask::default());
        for k in 3..8 {
            for q in 0..=k {
                let ar: Vec<u32> = (0..k).map(|i| if i < q { 4 } else { 3 }).collect();
                QuadTriRules::default().vertex_mask_with_arities(
                    &VertexNeighborhood::smooth(k, &zeros),
                    &ar,
                    &mut m,
                    &mut s,
                );
                // Centroid weights count once each (a centroid's weights sum to 1).
                assert!((m.sum() - 1.0).abs() < 1e-15, "{k} {q} {m:?}");
            }
        }
    }
}

//! Loop subdivision with piecewise-smooth tags.
//!
//! Loop 1987; tags and rules of Maret 2003 §3.5 (Fig. 3.9): smooth and dart vertices take the
//! smooth rule `(1 − nβ) v + β Σ r_j` with β of Loop (Maret eq. 3.7,
//! `β = (5/8 − (3/8 + 1/4 cos(2π/n))²)/n`) or Warren (eq. 3.8, `3/(8n)`, `3/16` for `n = 3`);
//! crease vertices `3/4 v + 1/8 (r_a + r_b)` over their two crease neighbours; corners stay.
//! Smooth edges `3/8 (v0 + v1) + 1/8 (o0 + o1)`; crease edges their midpoint.
//!
//! With [`LoopBoundary::Biermann`] (the default, "boundary as crease"), a smooth edge with an
//! end `v0` on a crease or corner uses the rule of Biermann, Levin & Zorin 2000 that keeps the
//! limit surface smooth next to extraordinary crease vertices: `(3/4 − γ) v0 + γ v1 + 1/8
//! (o0 + o1)` with `γ = 1/2 − 1/4 cos θ_k`, `θ_k = π/k` on a crease and `α/k` at a corner, `k`
//! faces in the end's sector and `α` its angle (for a regular crease vertex, `k = 3`, this is
//! the smooth rule). When both ends are on creases, the two one-sided masks are averaged.
//! With [`LoopBoundary::OpenSubdiv`], edges keep the smooth rule, as OpenSubdiv's Loop does,
//! and semi-sharp creases follow OpenSubdiv's transitions.

use super::refine::Split;
use super::rules::{
    edge_mask_with_sharpness, vertex_mask_with_transition, EdgeMask, EdgeNeighborhood, Rule, Rules,
    VertexMask, VertexNeighborhood,
};

/// Which β the smooth vertex rule uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LoopWeights {
    /// Loop's original β (Maret eq. 3.7); OpenSubdiv's choice.
    #[default]
    Loop,
    /// Warren's simplified β (Maret eq. 3.8).
    Warren,
}

/// Edge rules next to creases and boundaries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LoopBoundary {
    /// Biermann, Levin & Zorin 2000 modified rules next to crease and corner vertices.
    #[default]
    Biermann,
    /// OpenSubdiv's rules (unmodified smooth edge rule).
    OpenSubdiv,
}

/// The Loop scheme's rules.
#[derive(Clone, Copy, Debug, Default)]
pub struct LoopRules {
    /// β of the smooth vertex rule.
    pub weights: LoopWeights,
    /// Edge rules next to creases.
    pub boundary: LoopBoundary,
}

impl LoopRules {
    /// β for an interior vertex of valence `n`.
    pub fn beta(&self, n: usize) -> f64 {
        let nf = n as f64;
        match self.weights {
            LoopWeights::Loop => {
                let c = 0.375 + 0.25 * (std::f64::consts::TAU / nf).cos();
                (0.625 - c * c) / nf
            }
            LoopWeights::Warren => {
                if n == 3 {
                    3.0 / 16.0
                } else {
                    3.0 / (8.0 * nf)
                }
            }
        }
    }

    fn rule_mask(&self, rule: Rule, n: &VertexNeighborhood, m: &mut VertexMask) {
        match rule {
            Rule::Smooth | Rule::Dart => {
                let k = n.valence();
                m.clear(k, n.num_faces);
                let b = self.beta(k);
                m.vertex = 1.0 - k as f64 * b;
                m.edges.iter_mut().for_each(|w| *w = b);
            }
            Rule::Crease => m.set_crease(n, |i| n.edge_sharpness[i] > 0.0),
            Rule::Corner => m.set_corner(n),
        }
    }

    /// γ(θ) of Biermann et al. for the crease end of an edge.
    fn gamma(sector: &super::rules::Sector) -> Option<f64> {
        let k = sector.faces.max(1) as f64;
        let theta = match sector.rule {
            Rule::Crease => std::f64::consts::PI / k,
            Rule::Corner => sector.angle / k,
            _ => return None,
        };
        Some(0.5 - 0.25 * theta.cos())
    }
}

impl Rules for LoopRules {
    fn name(&self) -> &'static str {
        "loop"
    }

    fn split(&self) -> Split {
        Split::Triangles
    }

    fn needs_sectors(&self) -> bool {
        self.boundary == LoopBoundary::Biermann
    }

    fn vertex_mask(&self, n: &VertexNeighborhood, mask: &mut VertexMask, scratch: &mut VertexMask) {
        vertex_mask_with_transition(n, mask, scratch, |r, n, m| self.rule_mask(r, n, m));
    }

    fn edge_mask(&self, n: &EdgeNeighborhood, mask: &mut EdgeMask, scratch: &mut EdgeMask) {
        edge_mask_with_sharpness(n, mask, scratch, |n, m| {
            m.clear(n.num_faces);
            m.ends = [0.375, 0.375];
            m.faces.iter_mut().for_each(|w| *w = 0.125);
            if self.boundary != LoopBoundary::Biermann || n.num_faces != 2 {
                return;
            }
            let g = [
                n.ends[0].as_ref().and_then(Self::gamma),
                n.ends[1].as_ref().and_then(Self::gamma),
            ];
            let one_sided = |g: f64, crease_end: usize| {
                let mut e = [0.0; 2];
                e[crease_end] = 0.75 - g;
                e[1 - crease_end] = g;
                e
            };
            m.ends = match g {
                [Some(a), Some(b)] => {
                    let (x, y) = (one_sided(a, 0), one_sided(b, 1));
                    [0.5 * (x[0] + y[0]), 0.5 * (x[1] + y[1])]
                }
                [Some(a), None] => one_sided(a, 0),
                [None, Some(b)] => one_sided(b, 1),
                [None, None] => m.ends,
            };
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::subdivision::rules::Sector;

    #[test]
    fn regular_weights() {
        let r = LoopRules::default();
        // Valence 6: β = 1/16.
        assert!((r.beta(6) - 1.0 / 16.0).abs() < 1e-15);
        let w = LoopRules {
            weights: LoopWeights::Warren,
            ..r
        };
        assert_eq!(w.beta(3), 3.0 / 16.0);
        assert_eq!(w.beta(6), 1.0 / 16.0);
        let zeros = [0.0; 16];
        for n in 3..12 {
            let (mut m, mut s) = (VertexMask::default(), VertexMask::default());
            r.vertex_mask(&VertexNeighborhood::smooth(n, &zeros), &mut m, &mut s);
            assert!((m.sum() - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn crease_and_corner_vertices() {
        let r = LoopRules::default();
        let sharp = [10.0, 0.0, 0.0, 10.0, 0.0];
        let n = VertexNeighborhood {
            num_faces: 5,
            edge_sharpness: &sharp,
            vertex_sharpness: 0.0,
            child_edge_sharpness: &sharp,
            child_vertex_sharpness: 0.0,
        };
        let (mut m, mut s) = (VertexMask::default(), VertexMask::default());
        r.vertex_mask(&n, &mut m, &mut s);
        assert_eq!(m.vertex, 0.75);
        assert_eq!(m.edges, vec![0.125, 0.0, 0.0, 0.125, 0.0]);
        let n = VertexNeighborhood {
            vertex_sharpness: 10.0,
            child_vertex_sharpness: 10.0,
            ..n
        };
        r.vertex_mask(&n, &mut m, &mut s);
        assert_eq!(m.vertex, 1.0);
    }

    #[test]
    fn biermann_edge_rule() {
        let r = LoopRules::default();
        let (mut m, mut s) = (EdgeMask::default(), EdgeMask::default());
        let sector = |faces| {
            Some(Sector {
                rule: Rule::Crease,
                faces,
                angle: std::f64::consts::PI,
            })
        };
        // A regular crease vertex (k = 3) gives the smooth rule.
        let n = EdgeNeighborhood {
            sharpness: 0.0,
            num_faces: 2,
            face_arity: 3,
            ends: [sector(3), None],
            child_sharpness: [0.0; 2],
        };
        r.edge_mask(&n, &mut m, &mut s);
        assert!((m.ends[0] - 0.375).abs() < 1e-15 && (m.ends[1] - 0.375).abs() < 1e-15);
        // k = 1: θ = π, γ = 3/4: the crease end gets 0.
        let n = EdgeNeighborhood {
            ends: [None, sector(1)],
            ..n
        };
        r.edge_mask(&n, &mut m, &mut s);
        assert!((m.ends[1]).abs() < 1e-15 && (m.ends[0] - 0.75).abs() < 1e-15);
        assert!((m.sum() - 1.0).abs() < 1e-15);
        // Crease edges: the midpoint.
        let n = EdgeNeighborhood {
            sharpness: 10.0,
            child_sharpness: [10.0; 2],
            ..n
        };
        r.edge_mask(&n, &mut m, &mut s);
        assert_eq!(m.ends, [0.5, 0.5]);
        // Semi-sharp 0.25: a quarter crease, three quarters smooth.
        let n = EdgeNeighborhood {
            sharpness: 0.25,
            ends: [None, None],
            child_sharpness: [0.0; 2],
            ..n
        };
        r.edge_mask(&n, &mut m, &mut s);
        assert!((m.ends[0] - (0.25 * 0.5 + 0.75 * 0.375)).abs() < 1e-15);
        // Chaikin: a 0.8 edge whose halves stay sharp is a full crease (OpenSubdiv's rule)...
        let n = EdgeNeighborhood {
            sharpness: 0.8,
            child_sharpness: [0.35, 0.1],
            ..n
        };
        r.edge_mask(&n, &mut m, &mut s);
        assert_eq!(m.ends, [0.5, 0.5]);
        // ... and a 1.2 edge with one half decayed blends by 1.2, unclamped.
        let n = EdgeNeighborhood {
            sharpness: 1.2,
            child_sharpness: [0.0, 0.1],
            ..n
        };
        r.edge_mask(&n, &mut m, &mut s);
        assert!((m.ends[0] - (1.2 * 0.5 - 0.2 * 0.375)).abs() < 1e-15);
        assert!((m.sum() - 1.0).abs() < 1e-14);
    }
}

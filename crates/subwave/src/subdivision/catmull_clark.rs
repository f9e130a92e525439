//! Catmull-Clark subdivision on polygon meshes with boundaries, sharp and semi-sharp creases.
//!
//! Catmull & Clark 1978; sharp creases and corners of Hoppe et al. 1994; semi-sharp creases as
//! in OpenSubdiv (DeRose, Kass & Truong 1998, uniform and Chaikin creasing). Face points are
//! centroids. A smooth edge point is `1/4 (v0 + v1 + f0 + f1)` (f: face points); a smooth
//! vertex of valence `n` moves to `(n − 2)/n v + 1/n² Σ r_j + 1/n² Σ f_j`; crease vertices
//! to `3/4 v + 1/8 (r_a + r_b)`; corners stay. These are OpenSubdiv's `Sdc::Scheme<CATMARK>`
//! masks, so results match OpenSubdiv's (tested against it through `subwave-osd`).

use super::refine::Split;
use super::rules::{
    edge_mask_with_sharpness, vertex_mask_with_transition, EdgeMask, EdgeNeighborhood, Rule, Rules,
    VertexMask, VertexNeighborhood,
};

/// The Catmull-Clark scheme's rules.
#[derive(Clone, Copy, Debug, Default)]
pub struct CatmullClarkRules;

fn rule_mask(rule: Rule, n: &VertexNeighborhood, m: &mut VertexMask) {
    match rule {
        Rule::Smooth | Rule::Dart => {
            let k = n.valence();
            m.clear(k, n.num_faces);
            let kf = k as f64;
            m.vertex = (kf - 2.0) / kf;
            let w = 1.0 / (kf * kf);
            m.edges.iter_mut().for_each(|x| *x = w);
            m.faces.iter_mut().for_each(|x| *x = w);
        }
        Rule::Crease => m.set_crease(n, |i| n.edge_sharpness[i] > 0.0),
        Rule::Corner => m.set_corner(n),
    }
}

impl Rules for CatmullClarkRules {
    fn name(&self) -> &'static str {
        "catmull-clark"
    }

    fn split(&self) -> Split {
        Split::Polygons
    }

    fn vertex_mask(&self, n: &VertexNeighborhood, mask: &mut VertexMask, scratch: &mut VertexMask) {
        vertex_mask_with_transition(n, mask, scratch, rule_mask);
    }

    fn edge_mask(&self, n: &EdgeNeighborhood, mask: &mut EdgeMask, scratch: &mut EdgeMask) {
        edge_mask_with_sharpness(n, mask, scratch, |n, m| {
            m.clear(n.num_faces);
            if n.num_faces < 2 {
                // A boundary edge that is not sharp (never produced by the refiner, which
                // sharpens boundaries): fall back to the midpoint.
                m.ends = [0.5, 0.5];
                return;
            }
            m.ends = [0.25, 0.25];
            let w = 0.5 / n.num_faces as f64;
            m.faces.iter_mut().for_each(|x| *x = w);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_vertex() {
        let zeros = [0.0; 8];
        let (mut m, mut s) = (VertexMask::default(), VertexMask::default());
        CatmullClarkRules.vertex_mask(&VertexNeighborhood::smooth(4, &zeros), &mut m, &mut s);
        assert_eq!(m.vertex, 0.5);
        assert_eq!(m.edges, vec![1.0 / 16.0; 4]);
        assert_eq!(m.faces, vec![1.0 / 16.0; 4]);
        assert!((m.sum() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn semi_sharp_vertex_transition() {
        // Two edges of sharpness 0.5 become smooth: half crease rule, half smooth rule.
        let p = [0.5, 0.0, 0.5, 0.0];
        let c = [0.0; 4];
        let n = VertexNeighborhood {
            num_faces: 4,
            edge_sharpness: &p,
            vertex_sharpness: 0.0,
            child_edge_sharpness: &c,
            child_vertex_sharpness: 0.0,
        };
        let (mut m, mut s) = (VertexMask::default(), VertexMask::default());
        CatmullClarkRules.vertex_mask(&n, &mut m, &mut s);
        assert!((m.vertex - (0.5 * 0.75 + 0.5 * 0.5)).abs() < 1e-15);
        assert!((m.edges[0] - (0.5 * 0.125 + 0.5 / 16.0)).abs() < 1e-15);
        assert!((m.edges[1] - 0.5 / 16.0).abs() < 1e-15);
        assert!((m.sum() - 1.0).abs() < 1e-15);
    }
}

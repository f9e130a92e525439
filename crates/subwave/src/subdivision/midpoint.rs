//! Midpoint subdivision: linear 1-to-4 splitting of triangles, bilinear splitting of polygons.
//!
//! The interpolating, polynomial-reproducing-of-degree-one scheme (Maret §3.3, the "midpoint"
//! scheme of MPEG-4 AFX): vertices stay, edge points are midpoints, and for polygon meshes face
//! points are centroids (OpenSubdiv's `SCHEME_BILINEAR`). Tags have no effect.

use super::refine::Split;
use super::rules::{EdgeMask, EdgeNeighborhood, Rules, VertexMask, VertexNeighborhood};

/// The midpoint (linear / bilinear) scheme's rules.
#[derive(Clone, Copy, Debug)]
pub struct MidpointRules {
    /// Triangles 1-to-4, or polygons 1-to-n quads.
    pub split: Split,
}

impl Rules for MidpointRules {
    fn name(&self) -> &'static str {
        match self.split {
            Split::Triangles => "midpoint",
            Split::Polygons => "bilinear",
            // The linear step of quad/triangle subdivision (Stam & Loop 2003).
            Split::QuadTri => "midpoint",
        }
    }

    fn split(&self) -> Split {
        self.split
    }

    fn vertex_mask(&self, n: &VertexNeighborhood, mask: &mut VertexMask, _: &mut VertexMask) {
        mask.set_corner(n);
    }

    fn edge_mask(&self, n: &EdgeNeighborhood, mask: &mut EdgeMask, _: &mut EdgeMask) {
        mask.set_crease(n.num_faces);
    }
}

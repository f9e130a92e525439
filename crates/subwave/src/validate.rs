//! Mesh statistics (`subwave info`) and the structural checks that algorithms require.
//!
//! [`report`] describes a mesh without judging it; [`require_manifold`] turns the problems a
//! subdivision or coding algorithm cannot take into a typed [`MeshError`] that lists the
//! offending elements (Maret §2.3.6: subdivision needs a 2-manifold with ordered 1-rings).

use std::collections::BTreeMap;

use serde::Serialize;

use crate::mesh::Mesh;
use crate::topology::{Topology, UnionFind, VertexKind, VertexTag};
use crate::MeshError;
use glam::DVec3;

/// Counts and measures of a mesh: the content of `subwave info`.
///
/// `vertices` counts every vertex of the file; the topological counts (Euler characteristic,
/// valences, bounding box) are over referenced vertices.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct MeshReport {
    /// All vertices, referenced or not.
    pub vertices: usize,
    /// Vertices used by at least one face.
    pub referenced_vertices: usize,
    /// Vertices no face uses.
    pub unreferenced_vertices: usize,
    /// Number of faces.
    pub faces: usize,
    /// Number of faces of each arity (3 = triangles, 4 = quads, ...).
    pub faces_by_arity: BTreeMap<usize, usize>,
    /// Number of edges.
    pub edges: usize,
    /// Edges with exactly one face.
    pub boundary_edges: usize,
    /// Connected sets of boundary edges.
    pub boundary_loops: usize,
    /// Connected components of faces (sharing vertices).
    pub components: usize,
    /// V − E + F over referenced vertices.
    pub euler_characteristic: i64,
    /// Total genus when the mesh is a consistently oriented 2-manifold.
    pub genus: Option<u64>,
    /// Edges with more than two faces.
    pub non_manifold_edges: usize,
    /// Vertices whose faces form several fans.
    pub non_manifold_vertices: usize,
    /// Interior edges traversed in the same direction by both faces.
    pub inconsistent_orientation_edges: usize,
    /// Vertices at the ends of boundary edges that lie exactly on other boundary edges
    /// (duplicated seams, [`weld_seams`]), which `remesh --repair` welds.
    pub seam_vertices: usize,
    /// T-junctions of slits between boundary chains, which `remesh --repair` stitches
    /// ([`crate::remesh::stitch::stitch_slits`]).
    pub slit_vertices: usize,
    /// Edges with a positive crease sharpness tag.
    pub crease_edges: usize,
    /// Vertex tags of Maret §3.5 (boundary edges count as creases).
    pub tags: TagCounts,
    /// Number of referenced vertices of each valence.
    pub valence_histogram: BTreeMap<usize, usize>,
    /// Minimum corner of the bounding box of referenced vertices.
    pub bbox_min: [f64; 3],
    /// Maximum corner of the bounding box of referenced vertices.
    pub bbox_max: [f64; 3],
    /// Length of the bounding-box diagonal.
    pub bbox_diagonal: f64,
}

/// Number of vertices with each tag.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq, Eq)]
pub struct TagCounts {
    /// Smooth vertices.
    pub smooth: usize,
    /// Darts (one incident crease edge).
    pub dart: usize,
    /// Crease vertices (two incident crease edges).
    pub crease: usize,
    /// Corners (three or more crease edges, or tagged).
    pub corner: usize,
}

/// Computes the report of `mesh`, whose topology is `topo` (built from the same mesh).
pub fn report(mesh: &Mesh, topo: &Topology) -> MeshReport {
    let mut faces_by_arity = BTreeMap::new();
    for f in 0..mesh.num_faces() {
        *faces_by_arity.entry(mesh.face_arity(f)).or_insert(0) += 1;
    }
    let referenced: Vec<u32> = (0..topo.num_vertices)
        .filter(|&v| topo.vertex_kinds[v as usize] != VertexKind::Isolated)
        .collect();
    let mut valence_histogram = BTreeMap::new();
    let mut tags = TagCounts::default();
    for &v in &referenced {
        *valence_histogram
            .entry(topo.valence(v as usize))
            .or_insert(0) += 1;
        match topo.vertex_tag(v as usize) {
            VertexTag::Smooth => tags.smooth += 1,
            VertexTag::Dart => tags.dart += 1,
            VertexTag::Crease => tags.crease += 1,
            VertexTag::Corner => tags.corner += 1,
        }
    }
    let (lo, hi) = mesh
        .bounding_box_of(referenced.iter().copied())
        .unwrap_or((glam::DVec3::ZERO, glam::DVec3::ZERO));
    let boundary_edges = (0..topo.num_edges())
        .filter(|&e| topo.is_boundary_edge(e))
        .count();
    let triangles = mesh.triangulate().0;
    MeshReport {
        vertices: mesh.num_vertices(),
        referenced_vertices: referenced.len(),
        unreferenced_vertices: mesh.num_vertices() - referenced.len(),
        faces: mesh.num_faces(),
        faces_by_arity,
        edges: topo.num_edges(),
        boundary_edges,
        boundary_loops: topo.boundary_loops().1,
        components: topo.face_components().1,
        euler_characteristic: topo.euler_characteristic(),
        genus: topo.genus(),
        non_manifold_edges: topo.non_manifold_edges().len(),
        non_manifold_vertices: topo.non_manifold_vertices().len(),
        inconsistent_orientation_edges: topo.inconsistent_edges.len(),
        seam_vertices: weld_seams(&mesh.positions, &triangles).1,
        slit_vertices: crate::remesh::stitch::stitch_slits(
            &mesh.positions,
            &triangles,
            crate::remesh::stitch::SLIT_TOLERANCE * mesh.diagonal(),
        )
        .1,
        crease_edges: topo.edge_sharpness.iter().filter(|&&s| s > 0.0).count(),
        tags,
        valence_histogram,
        bbox_min: lo.to_array(),
        bbox_max: hi.to_array(),
        bbox_diagonal: (hi - lo).length(),
    }
}

/// Duplicated seams of the triangles `tris` over `positions`: for every vertex, the vertex
/// it is welded into (itself if none), and the number of vertices welded into another.
///
/// Precondition: the indices of `tris` are below `positions.len()`. For the weld to keep
/// every triangle valid, no triangle may have two vertices at the same place (remove
/// degenerate triangles first, as [`crate::remesh::repair::prepare`] does); the count of a
/// mesh that has such triangles ([`report`]) includes their coincident boundary ends.
///
/// A boundary edge (on one triangle) is a seam edge when another boundary edge has its ends at
/// exactly the same two positions (bit for bit, `-0.0` as `0.0`, either direction); the
/// coincident ends of such edges are welded into the smallest index among them. Vertices
/// that coincide without a coincident edge (parts touching at a point) are left apart.
pub fn weld_seams(positions: &[DVec3], tris: &[[u32; 3]]) -> (Vec<u32>, usize) {
    use std::collections::HashMap;
    let n = positions.len();
    let key = |v: u32| {
        positions[v as usize]
            .to_array()
            .map(|x| (x + 0.0).to_bits())
    };
    // Undirected edges and the number of triangles on each.
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for fv in tris {
        for i in 0..3 {
            let (a, b) = (fv[i], fv[(i + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    // Boundary edges grouped by their ends' positions (ordered so either direction matches).
    // A place: the bits of a position.
    type Place = [u64; 3];
    let mut by_place: HashMap<(Place, Place), Vec<(u32, u32)>> = HashMap::new();
    for (&(a, b), &count) in &edges {
        if count != 1 {
            continue;
        }
        let (ka, kb) = (key(a), key(b));
        let (p, q) = if ka <= kb {
            ((a, b), (ka, kb))
        } else {
            ((b, a), (kb, ka))
        };
        by_place.entry(q).or_default().push(p);
    }
    let mut uf = UnionFind::new(n);
    for group in by_place.values() {
        if let Some((&(a0, b0), rest)) = group.split_first() {
            for &(a, b) in rest {
                uf.union(a0, a);
                uf.union(b0, b);
            }
        }
    }
    let mut smallest = vec![u32::MAX; n];
    for v in 0..n as u32 {
        let r = uf.find(v) as usize;
        smallest[r] = smallest[r].min(v);
    }
    let root: Vec<u32> = (0..n as u32)
        .map(|v| smallest[uf.find(v) as usize])
        .collect();
    let welded = root
        .iter()
        .enumerate()
        .filter(|&(v, &r)| r as usize != v)
        .count();
    (root, welded)
}

/// Checks that the mesh is a consistently oriented 2-manifold (possibly with boundaries).
///
/// # Errors
/// The first problem found, in this order, listing every offending element:
/// [`MeshError::NonManifoldEdges`], [`MeshError::NonManifoldVertices`],
/// [`MeshError::InconsistentOrientation`].
pub fn require_manifold(topo: &Topology) -> Result<(), MeshError> {
    let edges = topo.non_manifold_edges();
    if !edges.is_empty() {
        return Err(MeshError::NonManifoldEdges {
            edges: edges
                .iter()
                .map(|&e| topo.edge_vertices[e as usize])
                .collect(),
        });
    }
    let vertices = topo.non_manifold_vertices();
    if !vertices.is_empty() {
        return Err(MeshError::NonManifoldVertices { vertices });
    }
    if !topo.inconsistent_edges.is_empty() {
        return Err(MeshError::InconsistentOrientation {
            edges: topo
                .inconsistent_edges
                .iter()
                .map(|&e| topo.edge_vertices[e as usize])
                .collect(),
        });
    }
    // A single fan whose orientation flips inside it is caught above (its edges are
    // inconsistent); any other irregular vertex touches a non-manifold edge.
    debug_assert!(topo.is_manifold());
    Ok(())
}

/// Checks that every face has the arity a scheme needs.
///
/// # Errors
/// [`MeshError::UnsupportedFaces`] listing the faces of another arity, with `hint` saying
/// which scheme to use instead.
pub fn require_arity(
    mesh: &Mesh,
    arity: usize,
    scheme: &'static str,
    needs: &'static str,
    hint: &'static str,
) -> Result<(), MeshError> {
    let faces: Vec<u32> = (0..mesh.num_faces())
        .filter(|&f| mesh.face_arity(f) != arity)
        .map(|f| f as u32)
        .collect();
    if faces.is_empty() {
        Ok(())
    } else {
        Err(MeshError::UnsupportedFaces {
            scheme,
            needs,
            faces,
            hint,
        })
    }
}

//! The polygon mesh: positions, flat faces, crease/corner tags and optional attributes.
//!
//! Faces of any arity are stored flat, as in OpenSubdiv's `Vtr` tables and Maret §2.3.1's
//! "coordinate index": `face_offsets[f]..face_offsets[f + 1]` indexes `face_indices`, which holds
//! `u32` vertex indices in counter-clockwise order. The topology (edges, 1-rings, boundary loops)
//! is derived from these arrays by [`crate::topology::Topology::build`].

use glam::DVec3;

/// Sharpness at or above which a crease or corner is infinitely sharp (OpenSubdiv's
/// `Sdc::Crease::SHARPNESS_INFINITE`).
pub const SHARPNESS_INFINITE: f64 = 10.0;

/// A sharpness tag on the edge between two vertices (OBJ `t crease 2/1 a b s`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeTag {
    /// The two end vertices, in any order.
    pub vertices: [u32; 2],
    /// Crease sharpness: 0 smooth, `>= SHARPNESS_INFINITE` infinitely sharp, between them a
    /// semi-sharp crease that relaxes after that many subdivision levels.
    pub sharpness: f64,
}

/// A sharpness tag on a vertex (OBJ `t corner 1/1 v s`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexTag {
    /// The tagged vertex.
    pub vertex: u32,
    /// Corner sharpness, with the same scale as [`EdgeTag::sharpness`].
    pub sharpness: f64,
}

/// Face-varying texture coordinates: one index into `coords` per face corner.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaceVarying {
    /// The distinct texture coordinates.
    pub coords: Vec<[f64; 2]>,
    /// One index into `coords` per entry of [`Mesh::face_indices`].
    pub indices: Vec<u32>,
}

/// A polygon mesh with `f64` positions and faces of any arity stored flat.
///
/// Invariants that [`Mesh::check_indices`] verifies (readers and generators uphold them; code
/// that builds a mesh by hand should call it): `face_offsets` starts at 0, is non-decreasing and
/// ends at `face_indices.len()`; every index is `< positions.len()`; optional per-vertex arrays
/// have `positions.len()` entries; face-varying indices have `face_indices.len()` entries.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Start of each face in `face_indices`, plus a final entry equal to its length.
    pub face_offsets: Vec<u32>,
    /// Vertex indices of all faces, concatenated.
    pub face_indices: Vec<u32>,
    /// Crease tags on edges.
    pub edge_tags: Vec<EdgeTag>,
    /// Corner tags on vertices.
    pub vertex_tags: Vec<VertexTag>,
    /// Optional per-vertex colours (linear RGB in 0..1).
    pub colors: Option<Vec<[f32; 3]>>,
    /// Optional per-vertex texture coordinates.
    pub uvs: Option<Vec<[f64; 2]>>,
    /// Optional face-varying texture coordinates (OBJ `vt` with seams).
    pub face_uvs: Option<FaceVarying>,
}

impl Mesh {
    /// An empty mesh (no vertices, no faces).
    pub fn new() -> Self {
        Mesh {
            face_offsets: vec![0],
            ..Default::default()
        }
    }

    /// A mesh from positions and a list of faces (each a slice of vertex indices).
    ///
    /// Indices are not checked; call [`Mesh::check_indices`] on untrusted data.
    pub fn from_faces<F: AsRef<[u32]>>(
        positions: Vec<DVec3>,
        faces: impl IntoIterator<Item = F>,
    ) -> Self {
        let mut m = Mesh {
            positions,
            ..Mesh::new()
        };
        for f in faces {
            m.push_face(f.as_ref());
        }
        m
    }

    /// A mesh of triangles from positions and `[u32; 3]` faces.
    pub fn from_triangles(positions: Vec<DVec3>, triangles: &[[u32; 3]]) -> Self {
        let mut face_offsets = Vec::with_capacity(triangles.len() + 1);
        face_offsets.extend((0..=triangles.len() as u32).map(|i| 3 * i));
        Mesh {
            positions,
            face_offsets,
            face_indices: triangles.iter().flatten().copied().collect(),
            ..Default::default()
        }
    }

    /// Appends a face (vertex indices in counter-clockwise order) and returns its index.
    pub fn push_face(&mut self, vertices: &[u32]) -> u32 {
        if self.face_offsets.is_empty() {
            self.face_offsets.push(0);
        }
        self.face_indices.extend_from_slice(vertices);
        self.face_offsets.push(self.face_indices.len() as u32);
        (self.face_offsets.len() - 2) as u32
    }

    /// Number of vertices (including vertices no face references).
    #[inline]
    pub fn num_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of faces.
    #[inline]
    pub fn num_faces(&self) -> usize {
        self.face_offsets.len().saturating_sub(1)
    }

    /// The vertex indices of face `f`. Panics if `f >= num_faces()`.
    #[inline]
    pub fn face(&self, f: usize) -> &[u32] {
        &self.face_indices[self.face_offsets[f] as usize..self.face_offsets[f + 1] as usize]
    }

    /// Iterates over the faces as slices of vertex indices.
    pub fn faces(&self) -> impl ExactSizeIterator<Item = &[u32]> + '_ {
        self.face_offsets
            .windows(2)
            .map(move |w| &self.face_indices[w[0] as usize..w[1] as usize])
    }

    /// Arity of face `f`.
    #[inline]
    pub fn face_arity(&self, f: usize) -> usize {
        (self.face_offsets[f + 1] - self.face_offsets[f]) as usize
    }

    /// True if every face is a triangle.
    pub fn is_triangle_mesh(&self) -> bool {
        self.face_offsets.windows(2).all(|w| w[1] - w[0] == 3)
    }

    /// True if every face is a quadrilateral.
    pub fn is_quad_mesh(&self) -> bool {
        self.face_offsets.windows(2).all(|w| w[1] - w[0] == 4)
    }

    /// Axis-aligned bounding box `(min, max)` of the given vertices, or `None` if empty.
    pub fn bounding_box_of(
        &self,
        vertices: impl IntoIterator<Item = u32>,
    ) -> Option<(DVec3, DVec3)> {
        let mut it = vertices.into_iter();
        let first = self.positions[it.next()? as usize];
        Some(it.fold((first, first), |(lo, hi), v| {
            let p = self.positions[v as usize];
            (lo.min(p), hi.max(p))
        }))
    }

    /// Bounding box of all vertices, or `None` if the mesh has none.
    pub fn bounding_box(&self) -> Option<(DVec3, DVec3)> {
        self.bounding_box_of(0..self.positions.len() as u32)
    }

    /// Length of the bounding-box diagonal (0 for an empty mesh).
    pub fn diagonal(&self) -> f64 {
        diagonal_of(&self.positions)
    }

    /// For each vertex, whether any face references it.
    pub fn referenced(&self) -> Vec<bool> {
        let mut used = vec![false; self.positions.len()];
        for &v in &self.face_indices {
            if let Some(u) = used.get_mut(v as usize) {
                *u = true;
            }
        }
        used
    }

    /// Checks the structural invariants listed on [`Mesh`].
    ///
    /// # Errors
    /// [`crate::MeshError`] naming the first offending face, corner or array.
    pub fn check_indices(&self) -> Result<(), crate::MeshError> {
        use crate::MeshError;
        let nv = self.positions.len();
        if self.face_offsets.first().copied().unwrap_or(0) != 0
            || self.face_offsets.last().copied().unwrap_or(0) as usize != self.face_indices.len()
        {
            return Err(MeshError::BadOffsets);
        }
        for f in 0..self.num_faces() {
            let (a, b) = (self.face_offsets[f], self.face_offsets[f + 1]);
            if b < a {
                return Err(MeshError::BadOffsets);
            }
            if b - a < 3 {
                return Err(MeshError::FaceTooSmall {
                    face: f as u32,
                    arity: (b - a) as usize,
                });
            }
            let fv = self.face(f);
            if let Some(&v) = fv.iter().find(|&&v| v as usize >= nv) {
                return Err(MeshError::IndexOutOfRange {
                    face: f as u32,
                    index: v,
                    vertices: nv,
                });
            }
            if let Some(v) = repeated_vertex(fv) {
                return Err(MeshError::RepeatedVertex {
                    face: f as u32,
                    vertex: v,
                });
            }
        }
        for (v, p) in self.positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(MeshError::NonFinite { vertex: v as u32 });
            }
        }
        let per_vertex = |name: &'static str, len: usize| {
            if len != nv {
                Err(MeshError::AttributeLength {
                    name,
                    len,
                    expected: nv,
                })
            } else {
                Ok(())
            }
        };
        if let Some(c) = &self.colors {
            per_vertex("colors", c.len())?;
        }
        if let Some(t) = &self.uvs {
            per_vertex("uvs", t.len())?;
        }
        if let Some(fv) = &self.face_uvs {
            if fv.indices.len() != self.face_indices.len() {
                return Err(MeshError::AttributeLength {
                    name: "face_uvs",
                    len: fv.indices.len(),
                    expected: self.face_indices.len(),
                });
            }
            if let Some(&bad) = fv.indices.iter().find(|&&i| i as usize >= fv.coords.len()) {
                return Err(MeshError::AttributeIndex {
                    name: "face_uvs",
                    index: bad,
                    len: fv.coords.len(),
                });
            }
        }
        for t in &self.edge_tags {
            for &v in &t.vertices {
                if v as usize >= nv {
                    return Err(MeshError::TagOutOfRange {
                        vertex: v,
                        vertices: nv,
                    });
                }
            }
        }
        for t in &self.vertex_tags {
            if t.vertex as usize >= nv {
                return Err(MeshError::TagOutOfRange {
                    vertex: t.vertex,
                    vertices: nv,
                });
            }
        }
        Ok(())
    }

    /// Removes vertices that no face references, renumbering faces and tags; returns the
    /// old→new map (`u32::MAX` for removed vertices).
    pub fn remove_unreferenced(&mut self) -> Vec<u32> {
        let used = self.referenced();
        let mut map = vec![u32::MAX; self.positions.len()];
        let mut next = 0u32;
        for (v, &u) in used.iter().enumerate() {
            if u {
                map[v] = next;
                next += 1;
            }
        }
        if next as usize == self.positions.len() {
            return map;
        }
        let keep = |v: usize| used[v];
        self.positions = (0..self.positions.len())
            .filter(|&v| keep(v))
            .map(|v| self.positions[v])
            .collect();
        if let Some(c) = &mut self.colors {
            *c = (0..c.len()).filter(|&v| keep(v)).map(|v| c[v]).collect();
        }
        if let Some(t) = &mut self.uvs {
            *t = (0..t.len()).filter(|&v| keep(v)).map(|v| t[v]).collect();
        }
        for v in &mut self.face_indices {
            *v = map[*v as usize];
        }
        self.edge_tags
            .retain(|t| t.vertices.iter().all(|&v| keep(v as usize)));
        for t in &mut self.edge_tags {
            t.vertices = t.vertices.map(|v| map[v as usize]);
        }
        self.vertex_tags.retain(|t| keep(t.vertex as usize));
        for t in &mut self.vertex_tags {
            t.vertex = map[t.vertex as usize];
        }
        map
    }

    /// Splits every face into triangles (fan from its first vertex), in face order.
    /// Returns the triangles and, for each, the index of the face it came from.
    pub fn triangulate(&self) -> (Vec<[u32; 3]>, Vec<u32>) {
        let mut tris = Vec::with_capacity(self.face_indices.len());
        let mut from = Vec::with_capacity(self.face_indices.len());
        for (f, fv) in self.faces().enumerate() {
            for i in 1..fv.len().saturating_sub(1) {
                tris.push([fv[0], fv[i], fv[i + 1]]);
                from.push(f as u32);
            }
        }
        (tris, from)
    }

    /// Area-weighted vertex normals (unit length; zero for isolated vertices).
    pub fn vertex_normals(&self) -> Vec<DVec3> {
        let mut n = vec![DVec3::ZERO; self.positions.len()];
        for fv in self.faces() {
            // Newell's method: robust for non-planar polygons.
            let mut fnrm = DVec3::ZERO;
            for i in 0..fv.len() {
                let a = self.positions[fv[i] as usize];
                let b = self.positions[fv[(i + 1) % fv.len()] as usize];
                fnrm += a.cross(b);
            }
            for &v in fv {
                n[v as usize] += fnrm;
            }
        }
        for x in &mut n {
            *x = x.normalize_or_zero();
        }
        n
    }
}

/// The first vertex that a face visits twice, if any: a quadratic scan for small faces, a sort
/// for large ones (so that hostile input with huge polygons stays linearithmic).
fn repeated_vertex(fv: &[u32]) -> Option<u32> {
    if fv.len() <= 16 {
        (1..fv.len())
            .find(|&i| fv[..i].contains(&fv[i]))
            .map(|i| fv[i])
    } else {
        let mut sorted = fv.to_vec();
        sorted.sort_unstable();
        sorted.windows(2).find(|w| w[0] == w[1]).map(|w| w[0])
    }
}

/// Length of the bounding-box diagonal of `points` (0 if there are none).
pub fn diagonal_of(points: &[DVec3]) -> f64 {
    let Some(&first) = points.first() else {
        return 0.0;
    };
    let (lo, hi) = points
        .iter()
        .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    (hi - lo).length()
}

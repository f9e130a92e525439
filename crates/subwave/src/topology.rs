//! Mesh topology as flat `u32` tables: edges, ordered 1-rings, boundary loops, components, tags.
//!
//! Implements the mesh model of Maret 2003 §2.3 (1-rings eq. 2.3, valence and crease degree
//! §2.3.3, interior/boundary edges §2.3.4, manifoldness §2.3.6), the ordered 1-ring
//! construction of Algorithm 4, and the vertex tags of §3.5 (a vertex incident to one crease
//! edge is a *dart*, to two a *crease* vertex, to more a *corner*; boundary edges count as
//! creases).
//!
//! The tables follow OpenSubdiv's `Vtr::Level`: every relation is a pair of arrays
//! (`*_offsets` of length `n + 1`, and the concatenated members), so that building is linear in
//! the mesh size and no per-element allocation happens.
//!
//! **Edge order.** Edges are numbered in order of first appearance when the faces are scanned in
//! order, each face from its first corner: edge `face_edges[c]` joins corner `c` to the next
//! corner of the same face. The plain-subdivision ordering contract and the AFX offspring forest
//! (trees in order of first appearance of base edges) rely on this order.
//!
//! **1-ring order.** For a manifold vertex, `vertex_faces` and `vertex_edges` are ordered
//! counter-clockwise (for counter-clockwise faces): `e0, f0, e1, f1, ...` where face `f_i` lies
//! between edges `e_i` and `e_{i+1}`, `e_i` being the *outgoing* edge of `f_i` at the vertex.
//! A boundary vertex starts at its leading boundary edge and has one more edge than faces
//! (OpenSubdiv's convention; Maret's ordered 1-ring `R_i` is the sequence of the edges' other
//! ends, [`Topology::ring`]). A non-manifold vertex keeps its faces and edges in scan order.

use rayon::prelude::*;

use crate::mesh::Mesh;

/// Classification of a vertex's neighbourhood.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum VertexKind {
    /// No face uses the vertex.
    #[default]
    Isolated,
    /// A closed fan of faces: the 1-ring is a cycle.
    Interior,
    /// An open fan: the 1-ring starts and ends on boundary edges.
    Boundary,
    /// The incident faces form several edge-connected fans (a pinched vertex).
    NonManifold,
    /// One fan, but an incident edge is non-manifold or the orientation flips around the
    /// vertex, so the 1-ring cannot be ordered consistently.
    Irregular,
}

/// Vertex tag of Maret §3.5 (Fig. 3.9), from the number of incident crease edges.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum VertexTag {
    /// No incident crease edge.
    #[default]
    Smooth,
    /// Exactly one incident crease edge: the end of a crease line.
    Dart,
    /// Exactly two incident crease edges: on a crease line.
    Crease,
    /// More than two incident crease edges, or tagged as a corner.
    Corner,
}

/// How [`Topology::from_edges_counted`] obtains the vertex-face relation.
pub(crate) enum VertexFaces {
    /// A counting sort of the corners by vertex (faces in scan order).
    Sort,
    /// Only the offsets: a lean level (see [`Topology::from_edges_counted`]).
    Lean,
    /// Faces and corners built by the caller, exactly as [`VertexFaces::Sort`] would order
    /// them, laid out by the vertex-face offsets the caller also gives (else sorted).
    Given(Vec<u32>, Vec<u16>),
    /// No vertex relation at all, neither faces nor edges (not even their offsets): a level
    /// whose consumer gathers each vertex's relations from the coarser level (see
    /// [`Topology::has_vertex_edges`]).
    Without,
}

/// Flat topology tables of a polygon mesh. See the module documentation for the conventions.
#[derive(Clone, Debug, Default)]
pub struct Topology {
    /// Number of vertices (including isolated ones).
    pub num_vertices: u32,
    /// Start of each face's corners in `face_vertices` / `face_edges` (length `F + 1`).
    pub face_offsets: Vec<u32>,
    /// Vertex of each face corner (a copy of the mesh's `face_indices`).
    pub face_vertices: Vec<u32>,
    /// Edge from each face corner to the next corner of the same face.
    pub face_edges: Vec<u32>,
    /// End vertices of each edge, in the direction the first face traversed it.
    pub edge_vertices: Vec<[u32; 2]>,
    /// Start of each edge's faces in `edge_faces` (length `E + 1`).
    pub edge_face_offsets: Vec<u32>,
    /// Faces of each edge, in face order.
    pub edge_faces: Vec<u32>,
    /// Start of each vertex's faces in `vertex_faces` / `vertex_face_corners` (length `V + 1`).
    pub vertex_face_offsets: Vec<u32>,
    /// Faces around each vertex (ordered for manifold vertices).
    pub vertex_faces: Vec<u32>,
    /// Local index of the vertex within each face of `vertex_faces`.
    pub vertex_face_corners: Vec<u16>,
    /// Start of each vertex's edges in `vertex_edges` (length `V + 1`).
    pub vertex_edge_offsets: Vec<u32>,
    /// Edges around each vertex (ordered for manifold vertices).
    pub vertex_edges: Vec<u32>,
    /// Classification of each vertex.
    pub vertex_kinds: Vec<VertexKind>,
    /// Crease sharpness of each edge (0 smooth; from the mesh's edge tags).
    pub edge_sharpness: Vec<f64>,
    /// Corner sharpness of each vertex (0 unless tagged).
    pub vertex_sharpness: Vec<f64>,
    /// Indices into the mesh's `edge_tags` of tags whose two vertices share no edge.
    pub unmatched_edge_tags: Vec<u32>,
    /// Edges whose two faces traverse them in the same direction.
    pub inconsistent_edges: Vec<u32>,
    /// Whether `vertex_faces` / `vertex_edges` are in 1-ring order (see the module docs);
    /// refined levels skip the ordering unless a scheme needs it.
    pub rings_ordered: bool,
    /// The number of corners of every face when all faces have the same (every refined level
    /// of a triangle or polygon split), else 0. [`Topology::face_vertices`] and
    /// [`Topology::face_edges`] then skip `face_offsets` (one memory access less per face).
    /// Whoever edits the face tables of a built topology must reset it to 0.
    pub face_arity: u32,
}

/// The common arity of all faces given by `offsets`, or 0 if they differ (or there are none).
fn uniform_arity(offsets: &[u32]) -> u32 {
    let Some(w) = offsets.windows(2).next() else {
        return 0;
    };
    let a = w[1] - w[0];
    if offsets.windows(2).all(|w| w[1] - w[0] == a) {
        a
    } else {
        0
    }
}

impl Topology {
    /// Builds the tables of `mesh` in time linear in its size (times the largest valence for
    /// edge matching).
    ///
    /// Preconditions: `mesh.check_indices()` holds (indices in range, no face with fewer than 3
    /// or repeated vertices). Non-manifold edges and vertices are allowed and classified.
    /// Panics only if the preconditions are violated (indices out of range).
    pub fn build(mesh: &Mesh) -> Self {
        let nv = mesh.num_vertices();
        let nf = mesh.num_faces();
        let fo = &mesh.face_offsets;
        let fvs = &mesh.face_indices;
        let nc = fvs.len();

        // --- Edges, by bucketing half-edges on their smaller vertex (counting sort). ---
        let mut bucket_off = vec![0u32; nv + 1];
        for f in 0..nf {
            let (a, b) = (fo[f] as usize, fo[f + 1] as usize);
            for c in a..b {
                let n = if c + 1 == b { a } else { c + 1 };
                let lo = fvs[c].min(fvs[n]);
                bucket_off[lo as usize + 1] += 1;
            }
        }
        for i in 0..nv {
            bucket_off[i + 1] += bucket_off[i];
        }
        // Each bucket holds (other vertex, edge id) pairs of the edges found so far.
        let mut bucket_fill = vec![0u32; nv];
        let mut bucket: Vec<(u32, u32)> = vec![(0, 0); nc];
        let mut face_edges = vec![0u32; nc];
        let mut edge_vertices: Vec<[u32; 2]> = Vec::with_capacity(nc / 2 + 8);
        let mut edge_face_count: Vec<u32> = Vec::with_capacity(nc / 2 + 8);
        let mut inconsistent = Vec::new();
        for f in 0..nf {
            let (a, b) = (fo[f] as usize, fo[f + 1] as usize);
            for c in a..b {
                let n = if c + 1 == b { a } else { c + 1 };
                let (u, v) = (fvs[c], fvs[n]);
                let (lo, hi) = if u < v { (u, v) } else { (v, u) };
                let start = bucket_off[lo as usize] as usize;
                let fill = bucket_fill[lo as usize] as usize;
                let found = bucket[start..start + fill]
                    .iter()
                    .find(|e| e.0 == hi)
                    .map(|e| e.1);
                let e = match found {
                    Some(e) => {
                        let ef = &mut edge_face_count[e as usize];
                        *ef += 1;
                        // Second face traversing the edge in the same direction as the first.
                        if *ef == 2 && edge_vertices[e as usize][0] == u {
                            inconsistent.push(e);
                        }
                        e
                    }
                    None => {
                        let e = edge_vertices.len() as u32;
                        edge_vertices.push([u, v]);
                        edge_face_count.push(1);
                        bucket[start + fill] = (hi, e);
                        bucket_fill[lo as usize] += 1;
                        e
                    }
                };
                face_edges[c] = e;
            }
        }
        drop(bucket);
        drop(bucket_fill);
        drop(bucket_off);
        let mut topo =
            Self::from_edges(nv, fo.clone(), fvs.clone(), face_edges, edge_vertices, true);
        topo.inconsistent_edges = inconsistent;
        topo.apply_tags(mesh);
        topo
    }

    /// Builds the remaining tables from faces and their edges (edge-faces, vertex-faces,
    /// vertex-edges), for a refiner that numbers child edges itself.
    ///
    /// Preconditions: `face_edges[c]` joins corner `c` to the next corner of its face,
    /// `edge_vertices` lists each edge's ends in the direction of its first traversal, and
    /// edges are numbered in order of first appearance. With `order_rings`, 1-rings are ordered
    /// and vertices classified as [`Topology::build`] does; without, 1-rings stay in scan order
    /// and vertices are classified `Boundary` if an incident edge has one face, else `Interior`
    /// (the refiner knows the mesh is manifold). Sharpness tables are zero.
    pub fn from_edges(
        nv: usize,
        face_offsets: Vec<u32>,
        face_vertices: Vec<u32>,
        face_edges: Vec<u32>,
        edge_vertices: Vec<[u32; 2]>,
        order_rings: bool,
    ) -> Self {
        Self::from_edges_counted(
            nv,
            face_offsets,
            face_vertices,
            face_edges,
            edge_vertices,
            order_rings,
            None,
            VertexFaces::Sort,
        )
    }

    /// [`Topology::from_edges`] with the offsets of the three relations known in advance
    /// (a refiner derives them from the parent level), skipping their counting passes:
    /// `offsets` are the vertex-face, vertex-edge and edge-face offsets, each as a leading 0
    /// followed by the `n + 1` offsets (the layout of [`Topology::counting_offsets`]). The
    /// tables are those of [`Topology::from_edges`] when the offsets are right.
    ///
    /// With [`VertexFaces::Lean`], the vertex-face relation keeps only its offsets (the face
    /// count of each vertex): `vertex_faces` and `vertex_face_corners` stay empty, so that
    /// [`Topology::has_vertex_faces`] is false and [`Topology::vertex_faces`] panics, and a
    /// consumer that needs a vertex's faces gathers them with
    /// [`Topology::vertex_faces_from_edges`]. The refiner builds such lean levels when it
    /// drops them after use and its fast paths read only the counts (a vertex-face scatter is
    /// the largest of the three counting sorts). Panics if `order_rings` is asked of a lean
    /// level. With [`VertexFaces::Given`], the caller's table is taken as it is (a refiner
    /// builds it in parallel from the parent); with [`VertexFaces::Sort`] it is sorted here.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn from_edges_counted(
        nv: usize,
        face_offsets: Vec<u32>,
        face_vertices: Vec<u32>,
        face_edges: Vec<u32>,
        edge_vertices: Vec<[u32; 2]>,
        order_rings: bool,
        offsets: Option<[Vec<u32>; 3]>,
        vertex_faces: VertexFaces,
    ) -> Self {
        assert!(
            !matches!(vertex_faces, VertexFaces::Lean | VertexFaces::Without) || !order_rings,
            "ordering rings needs the vertex-face table"
        );
        let without = matches!(vertex_faces, VertexFaces::Without);
        let ne = edge_vertices.len();
        // Offsets whose sizes or totals disagree with the tables are counted instead.
        let fits = |o: &Vec<u32>, n: usize, total: usize| {
            o.len() == n + 2 && o.last().is_some_and(|&t| t as usize == total)
        };
        let [vf, ve, ef] = offsets.map_or([None, None, None], |o| o.map(Some));
        let vf = vf.filter(|o| fits(o, nv, face_vertices.len()));
        let ve = ve.filter(|o| fits(o, nv, 2 * ne));
        let ef = ef.filter(|o| fits(o, ne, face_edges.len()));
        // A given table must fit the corners and come with its offsets.
        let vertex_faces = match vertex_faces {
            VertexFaces::Given(f, c)
                if vf.is_none() || f.len() != face_vertices.len() || c.len() != f.len() =>
            {
                VertexFaces::Sort
            }
            x => x,
        };
        // The three relations are independent counting sorts: build them in parallel. (Writing
        // the edge-face and vertex-edge relations inside the refiner's serial edge-numbering
        // scan instead was measured slower: the bunny's third Catmull-Clark level's scan went
        // from 9 to 38 ms and `subdivide` from 86 to 106 ms; the scattered writes cost the
        // same wherever they are made, and here they run on two cores.)
        let (
            (edge_face_offsets, edge_faces),
            (
                (vertex_face_offsets, vertex_faces, vertex_face_corners),
                (vertex_edge_offsets, vertex_edges),
            ),
        ) = rayon::join(
            || Self::edge_face_table(ne, &face_offsets, &face_edges, ef),
            || {
                rayon::join(
                    || {
                        let (faces, corners) = match vertex_faces {
                            VertexFaces::Sort => {
                                return Self::vertex_face_table(
                                    nv,
                                    &face_offsets,
                                    &face_vertices,
                                    vf,
                                )
                            }
                            VertexFaces::Lean => (Vec::new(), Vec::new()),
                            VertexFaces::Given(f, c) => (f, c),
                            VertexFaces::Without => return (Vec::new(), Vec::new(), Vec::new()),
                        };
                        let mut off = vf.unwrap_or_else(|| {
                            Self::counting_offsets(nv, face_vertices.iter().copied())
                        });
                        // The counting layout's leading 0 dropped: the start of each
                        // vertex's faces, then the total.
                        off.remove(0);
                        (off, faces, corners)
                    },
                    || {
                        if without {
                            (Vec::new(), Vec::new())
                        } else {
                            Self::vertex_edge_table(nv, &edge_vertices, ve)
                        }
                    },
                )
            },
        );
        let vertex_kinds = if order_rings {
            // Set for every vertex by `order_rings`.
            vec![VertexKind::Isolated; nv]
        } else {
            // Every vertex with an edge is interior, unless an incident edge has one face.
            // Both scans in parallel chunks (refined levels have millions of elements, on the
            // refiner's critical path); boundary edges are few, marked from their list.
            const CHUNK: usize = 1 << 16;
            let mut kinds: Vec<VertexKind> = crate::par::par_vec(
                nv,
                CHUNK,
                || (),
                |_, v| {
                    // Without vertex relations (a refined level), every vertex has edges.
                    if without || vertex_edge_offsets[v + 1] > vertex_edge_offsets[v] {
                        VertexKind::Interior
                    } else {
                        VertexKind::Isolated
                    }
                },
            );
            let boundary: Vec<usize> = edge_face_offsets
                .par_windows(2)
                .with_min_len(CHUNK)
                .enumerate()
                .filter(|(_, w)| w[1] - w[0] == 1)
                .map(|(e, _)| e)
                .collect();
            for e in boundary {
                for &v in &edge_vertices[e] {
                    kinds[v as usize] = VertexKind::Boundary;
                }
            }
            kinds
        };
        let mut topo = Topology {
            num_vertices: nv as u32,
            face_offsets,
            face_vertices,
            face_edges,
            edge_vertices,
            edge_face_offsets,
            edge_faces,
            vertex_face_offsets,
            vertex_faces,
            vertex_face_corners,
            vertex_edge_offsets,
            vertex_edges,
            vertex_kinds,
            edge_sharpness: vec![0.0; ne],
            vertex_sharpness: vec![0.0; nv],
            unmatched_edge_tags: Vec::new(),
            inconsistent_edges: Vec::new(),
            rings_ordered: order_rings,
            face_arity: 0,
        };
        if topo.face_offsets.is_empty() {
            topo.face_offsets.push(0);
        }
        topo.face_arity = uniform_arity(&topo.face_offsets);
        if order_rings {
            topo.order_rings();
        }
        topo
    }

    /// Offsets of a counting sort of items by key (`n` keys), from the items' keys:
    /// `offsets[k + 1]` is the start of key `k` (offsets has `n + 2` entries), ready for
    /// [`Topology::counting_slot`].
    fn counting_offsets(n: usize, keys: impl Iterator<Item = u32>) -> Vec<u32> {
        let mut off = vec![0u32; n + 2];
        for k in keys {
            off[k as usize + 2] += 1;
        }
        for i in 2..n + 2 {
            off[i] += off[i - 1];
        }
        off
    }

    /// The next slot of key `k` in a counting sort; after every item is placed, `offsets`
    /// without its last entry is the usual `n + 1` offsets table.
    #[inline]
    fn counting_slot(off: &mut [u32], k: u32) -> usize {
        let s = &mut off[k as usize + 1];
        *s += 1;
        (*s - 1) as usize
    }

    /// Edge -> faces, in face order (a stable counting sort of the corners by edge).
    fn edge_face_table(
        ne: usize,
        fo: &[u32],
        face_edges: &[u32],
        known: Option<Vec<u32>>,
    ) -> (Vec<u32>, Vec<u32>) {
        let mut off = match known {
            Some(k) => k,
            None => Self::counting_offsets(ne, face_edges.iter().copied()),
        };
        let mut edge_faces = vec![0u32; face_edges.len()];
        for (f, w) in fo.windows(2).enumerate() {
            for &e in &face_edges[w[0] as usize..w[1] as usize] {
                edge_faces[Self::counting_slot(&mut off, e)] = f as u32;
            }
        }
        off.pop();
        debug_assert_eq!(off.last().map_or(0, |&x| x as usize), edge_faces.len());
        (off, edge_faces)
    }

    /// Vertex -> faces and corners, in face order (scan order).
    fn vertex_face_table(
        nv: usize,
        fo: &[u32],
        fvs: &[u32],
        known: Option<Vec<u32>>,
    ) -> (Vec<u32>, Vec<u32>, Vec<u16>) {
        let mut off = match known {
            Some(k) => k,
            None => Self::counting_offsets(nv, fvs.iter().copied()),
        };
        let mut vertex_faces = vec![0u32; fvs.len()];
        let mut vertex_face_corners = vec![0u16; fvs.len()];
        for (f, w) in fo.windows(2).enumerate() {
            for (i, &v) in fvs[w[0] as usize..w[1] as usize].iter().enumerate() {
                let slot = Self::counting_slot(&mut off, v);
                vertex_faces[slot] = f as u32;
                vertex_face_corners[slot] = i.min(u16::MAX as usize) as u16;
            }
        }
        off.pop();
        debug_assert_eq!(off.last().map_or(0, |&x| x as usize), vertex_faces.len());
        (off, vertex_faces, vertex_face_corners)
    }

    /// Vertex -> edges, in edge order (scan order).
    fn vertex_edge_table(
        nv: usize,
        edge_vertices: &[[u32; 2]],
        known: Option<Vec<u32>>,
    ) -> (Vec<u32>, Vec<u32>) {
        let mut off = match known {
            Some(k) => k,
            None => Self::counting_offsets(nv, edge_vertices.iter().flatten().copied()),
        };
        let mut vertex_edges = vec![0u32; 2 * edge_vertices.len()];
        for (e, ev) in edge_vertices.iter().enumerate() {
            for &v in ev {
                vertex_edges[Self::counting_slot(&mut off, v)] = e as u32;
            }
        }
        off.pop();
        debug_assert_eq!(off.last().map_or(0, |&x| x as usize), vertex_edges.len());
        (off, vertex_edges)
    }

    /// Orders each vertex's faces and edges counter-clockwise (Maret Algorithm 4) and
    /// classifies the vertex. Vertices are independent (each rewrites only its own ranges of
    /// `vertex_faces`, `vertex_face_corners` and `vertex_edges`): chunks of them run in
    /// parallel.
    fn order_rings(&mut self) {
        /// Vertices per parallel work item.
        const CHUNK: usize = 2048;
        let nv = self.num_vertices as usize;
        let Topology {
            face_offsets,
            face_edges,
            edge_face_offsets,
            vertex_face_offsets,
            vertex_faces,
            vertex_face_corners,
            vertex_edge_offsets,
            vertex_edges,
            vertex_kinds,
            ..
        } = self;
        let tables = RingTables {
            face_offsets,
            face_edges,
            edge_face_offsets,
        };
        // Each chunk's disjoint slices of the vertex tables.
        let mut jobs = Vec::with_capacity(nv.div_ceil(CHUNK));
        let (mut faces, mut corners, mut edges, mut kinds) = (
            &mut vertex_faces[..],
            &mut vertex_face_corners[..],
            &mut vertex_edges[..],
            &mut vertex_kinds[..nv],
        );
        for v0 in (0..nv).step_by(CHUNK) {
            let v1 = (v0 + CHUNK).min(nv);
            let nf = (vertex_face_offsets[v1] - vertex_face_offsets[v0]) as usize;
            let ne = (vertex_edge_offsets[v1] - vertex_edge_offsets[v0]) as usize;
            let (f, fr) = std::mem::take(&mut faces).split_at_mut(nf);
            let (c, cr) = std::mem::take(&mut corners).split_at_mut(nf);
            let (e, er) = std::mem::take(&mut edges).split_at_mut(ne);
            let (k, kr) = std::mem::take(&mut kinds).split_at_mut(v1 - v0);
            (faces, corners, edges, kinds) = (fr, cr, er, kr);
            jobs.push((v0, f, c, e, k));
        }
        let (vfo, veo) = (&vertex_face_offsets[..], &vertex_edge_offsets[..]);
        jobs.into_par_iter()
            .for_each(|(v0, faces, corners, edges, kinds)| {
                let mut scratch = RingScratch::default();
                let (fbase, ebase) = (vfo[v0] as usize, veo[v0] as usize);
                for (j, kind) in kinds.iter_mut().enumerate() {
                    let v = v0 + j;
                    let fr = vfo[v] as usize - fbase..vfo[v + 1] as usize - fbase;
                    let er = veo[v] as usize - ebase..veo[v + 1] as usize - ebase;
                    *kind = tables.order_ring(
                        &mut faces[fr.clone()],
                        &mut corners[fr],
                        &mut edges[er],
                        &mut scratch,
                    );
                }
            });
    }

    fn apply_tags(&mut self, mesh: &Mesh) {
        for (t, tag) in mesh.edge_tags.iter().enumerate() {
            match self.find_edge(tag.vertices[0], tag.vertices[1]) {
                Some(e) => self.edge_sharpness[e as usize] = tag.sharpness.max(0.0),
                None => self.unmatched_edge_tags.push(t as u32),
            }
        }
        for tag in &mesh.vertex_tags {
            if let Some(s) = self.vertex_sharpness.get_mut(tag.vertex as usize) {
                *s = tag.sharpness.max(0.0);
            }
        }
    }

    /// Number of faces.
    #[inline]
    pub fn num_faces(&self) -> usize {
        self.face_offsets.len() - 1
    }

    /// Number of edges.
    #[inline]
    pub fn num_edges(&self) -> usize {
        self.edge_vertices.len()
    }

    /// Vertices of face `f`.
    #[inline]
    pub fn face_vertices(&self, f: usize) -> &[u32] {
        &self.face_vertices[self.face_range(f)]
    }

    /// The corners of face `f` in `face_vertices` / `face_edges`.
    #[inline]
    fn face_range(&self, f: usize) -> std::ops::Range<usize> {
        let a = self.face_arity as usize;
        if a != 0 {
            debug_assert!(f < self.num_faces());
            f * a..f * a + a
        } else {
            self.face_offsets[f] as usize..self.face_offsets[f + 1] as usize
        }
    }

    /// Edges of face `f` (edge `i` joins corner `i` to corner `i + 1`).
    #[inline]
    pub fn face_edges(&self, f: usize) -> &[u32] {
        &self.face_edges[self.face_range(f)]
    }

    /// Faces of edge `e` (one for a boundary edge, two for an interior one, more if
    /// non-manifold).
    #[inline]
    pub fn edge_faces(&self, e: usize) -> &[u32] {
        &self.edge_faces[self.edge_face_offsets[e] as usize..self.edge_face_offsets[e + 1] as usize]
    }

    /// Faces around vertex `v` (counter-clockwise for manifold vertices).
    #[inline]
    pub fn vertex_faces(&self, v: usize) -> &[u32] {
        &self.vertex_faces
            [self.vertex_face_offsets[v] as usize..self.vertex_face_offsets[v + 1] as usize]
    }

    /// False on a lean refined level, whose vertex-face relation holds only its offsets (the
    /// refiner builds such levels for its own use and drops them); true on every topology
    /// the library hands out.
    #[inline]
    pub fn has_vertex_faces(&self) -> bool {
        self.vertex_faces.len() == self.face_vertices.len()
    }

    /// False on a refined level built without vertex relations (the refiner builds such a
    /// level for its own use, gathers them from the coarser level, and drops it): its
    /// [`Topology::vertex_edges`], [`Topology::vertex_faces`] and their offsets are empty.
    /// True on every topology the library hands out.
    #[inline]
    pub fn has_vertex_edges(&self) -> bool {
        !self.vertex_edge_offsets.is_empty() || self.num_vertices == 0
    }

    /// The faces around `v` in face order with `v`'s corner in each, into `faces` and
    /// `corners` (cleared first), gathered from the faces of `v`'s edges: what
    /// [`Topology::vertex_faces`] and [`Topology::vertex_face_corners`] hold when rings are not
    /// ordered, for levels built without them. Linear in the faces of `v`'s edges (times the
    /// valence for the corners).
    pub fn vertex_faces_from_edges(&self, v: usize, faces: &mut Vec<u32>, corners: &mut Vec<u16>) {
        faces.clear();
        corners.clear();
        for &e in self.vertex_edges(v) {
            faces.extend_from_slice(self.edge_faces(e as usize));
        }
        faces.sort_unstable();
        faces.dedup();
        corners.extend(faces.iter().map(|&f| {
            let i = self
                .face_vertices(f as usize)
                .iter()
                .position(|&x| x as usize == v);
            i.map_or(0, |i| i.min(u16::MAX as usize) as u16)
        }));
    }

    /// Local index of `v` in each face of [`Topology::vertex_faces`].
    #[inline]
    pub fn vertex_face_corners(&self, v: usize) -> &[u16] {
        &self.vertex_face_corners
            [self.vertex_face_offsets[v] as usize..self.vertex_face_offsets[v + 1] as usize]
    }

    /// Edges around vertex `v` (counter-clockwise for manifold vertices, starting at the
    /// leading boundary edge on a boundary).
    #[inline]
    pub fn vertex_edges(&self, v: usize) -> &[u32] {
        &self.vertex_edges
            [self.vertex_edge_offsets[v] as usize..self.vertex_edge_offsets[v + 1] as usize]
    }

    /// The other end of edge `e` seen from `v`.
    #[inline]
    pub fn other_vertex(&self, e: usize, v: u32) -> u32 {
        let [a, b] = self.edge_vertices[e];
        if a == v {
            b
        } else {
            a
        }
    }

    /// Maret's ordered 1-ring `R_v` (eq. 2.3, Algorithm 4): the neighbours of `v` in the
    /// order of [`Topology::vertex_edges`].
    pub fn ring(&self, v: usize) -> impl ExactSizeIterator<Item = u32> + '_ {
        self.vertex_edges(v)
            .iter()
            .map(move |&e| self.other_vertex(e as usize, v as u32))
    }

    /// Valence of `v`: the number of incident edges (Maret §2.3.3).
    #[inline]
    pub fn valence(&self, v: usize) -> usize {
        (self.vertex_edge_offsets[v + 1] - self.vertex_edge_offsets[v]) as usize
    }

    /// True if edge `e` has exactly one face.
    #[inline]
    pub fn is_boundary_edge(&self, e: usize) -> bool {
        self.edge_face_offsets[e + 1] - self.edge_face_offsets[e] == 1
    }

    /// True if edge `e` has more than two faces.
    #[inline]
    pub fn is_non_manifold_edge(&self, e: usize) -> bool {
        self.edge_face_offsets[e + 1] - self.edge_face_offsets[e] > 2
    }

    /// True if edge `e` is a crease: tagged with positive sharpness, or on the boundary
    /// (boundary edges count as creases, Maret §3.5).
    #[inline]
    pub fn is_crease_edge(&self, e: usize) -> bool {
        self.edge_sharpness[e] > 0.0 || self.is_boundary_edge(e)
    }

    /// The edge joining `a` and `b`, if any (a scan of `a`'s edges).
    pub fn find_edge(&self, a: u32, b: u32) -> Option<u32> {
        if a as usize >= self.num_vertices as usize || b as usize >= self.num_vertices as usize {
            return None;
        }
        self.vertex_edges(a as usize)
            .iter()
            .copied()
            .find(|&e| self.other_vertex(e as usize, a) == b)
    }

    /// True if every vertex is interior, boundary or isolated and no edge is non-manifold
    /// or inconsistently oriented.
    pub fn is_manifold(&self) -> bool {
        self.vertex_kinds.iter().all(|k| {
            matches!(
                k,
                VertexKind::Interior | VertexKind::Boundary | VertexKind::Isolated
            )
        }) && self.inconsistent_edges.is_empty()
            && (0..self.num_edges()).all(|e| !self.is_non_manifold_edge(e))
    }

    /// Maret §3.5 tag of vertex `v`: counts incident crease edges (boundary edges included);
    /// a vertex with positive corner sharpness is a corner.
    pub fn vertex_tag(&self, v: usize) -> VertexTag {
        if self.vertex_sharpness[v] > 0.0 {
            return VertexTag::Corner;
        }
        let creases = self
            .vertex_edges(v)
            .iter()
            .filter(|&&e| self.is_crease_edge(e as usize))
            .count();
        match creases {
            0 => VertexTag::Smooth,
            1 => VertexTag::Dart,
            2 => VertexTag::Crease,
            _ => VertexTag::Corner,
        }
    }

    /// Tags of all vertices (see [`Topology::vertex_tag`]).
    pub fn vertex_tags(&self) -> Vec<VertexTag> {
        (0..self.num_vertices as usize)
            .map(|v| self.vertex_tag(v))
            .collect()
    }

    /// Edges with more than two faces, as vertex pairs.
    pub fn non_manifold_edges(&self) -> Vec<u32> {
        (0..self.num_edges() as u32)
            .filter(|&e| self.is_non_manifold_edge(e as usize))
            .collect()
    }

    /// Vertices whose faces form several fans.
    pub fn non_manifold_vertices(&self) -> Vec<u32> {
        (0..self.num_vertices)
            .filter(|&v| self.vertex_kinds[v as usize] == VertexKind::NonManifold)
            .collect()
    }

    /// Boundary loops: connected sets of boundary edges (joined at shared vertices). Returns
    /// the component index of every boundary edge (`u32::MAX` for others) and the count.
    pub fn boundary_loops(&self) -> (Vec<u32>, usize) {
        let mut uf = UnionFind::new(self.num_vertices as usize);
        let ne = self.num_edges();
        for e in 0..ne {
            if self.is_boundary_edge(e) {
                let [a, b] = self.edge_vertices[e];
                uf.union(a, b);
            }
        }
        let mut label = vec![u32::MAX; self.num_vertices as usize];
        let mut count = 0u32;
        let mut out = vec![u32::MAX; ne];
        for (e, o) in out.iter_mut().enumerate() {
            if self.is_boundary_edge(e) {
                let r = uf.find(self.edge_vertices[e][0]) as usize;
                if label[r] == u32::MAX {
                    label[r] = count;
                    count += 1;
                }
                *o = label[r];
            }
        }
        (out, count as usize)
    }

    /// Connected components of faces (faces sharing a vertex are connected). Returns each
    /// face's component and the count.
    pub fn face_components(&self) -> (Vec<u32>, usize) {
        let mut uf = UnionFind::new(self.num_vertices as usize);
        for f in 0..self.num_faces() {
            let fv = self.face_vertices(f);
            for w in fv.windows(2) {
                uf.union(w[0], w[1]);
            }
        }
        let mut label = vec![u32::MAX; self.num_vertices as usize];
        let mut count = 0u32;
        let comp = (0..self.num_faces())
            .map(|f| {
                let r = uf.find(self.face_vertices(f)[0]) as usize;
                if label[r] == u32::MAX {
                    label[r] = count;
                    count += 1;
                }
                label[r]
            })
            .collect();
        (comp, count as usize)
    }

    /// Number of referenced vertices (those with at least one face).
    pub fn num_referenced_vertices(&self) -> usize {
        self.vertex_kinds
            .iter()
            .filter(|&&k| k != VertexKind::Isolated)
            .count()
    }

    /// Euler characteristic χ = V − E + F over referenced vertices.
    pub fn euler_characteristic(&self) -> i64 {
        self.num_referenced_vertices() as i64 - self.num_edges() as i64 + self.num_faces() as i64
    }

    /// Total genus, summing `(2 − χ_c − b_c) / 2` over components `c` (b_c: boundary loops);
    /// `None` if the mesh is not a consistently oriented 2-manifold.
    pub fn genus(&self) -> Option<u64> {
        if !self.is_manifold() {
            return None;
        }
        let (fcomp, ncomp) = self.face_components();
        let mut chi = vec![0i64; ncomp];
        let mut vcomp = vec![u32::MAX; self.num_vertices as usize];
        for (f, &c) in fcomp.iter().enumerate() {
            chi[c as usize] += 1;
            for &v in self.face_vertices(f) {
                vcomp[v as usize] = c;
            }
        }
        for &c in &vcomp {
            if c != u32::MAX {
                chi[c as usize] += 1;
            }
        }
        let mut edge_comp = vec![0u32; self.num_edges()];
        for e in 0..self.num_edges() {
            let c = fcomp[self.edge_faces(e)[0] as usize];
            edge_comp[e] = c;
            chi[c as usize] -= 1;
        }
        let (loops, _) = self.boundary_loops();
        let mut seen = std::collections::HashSet::new();
        let mut b = vec![0i64; ncomp];
        for e in 0..self.num_edges() {
            if loops[e] != u32::MAX && seen.insert(loops[e]) {
                b[edge_comp[e] as usize] += 1;
            }
        }
        let mut g = 0i64;
        for c in 0..ncomp {
            let twice = 2 - chi[c] - b[c];
            if twice < 0 || twice % 2 != 0 {
                return None;
            }
            g += twice / 2;
        }
        Some(g as u64)
    }
}

/// A union-find over `u32` elements with path halving and union by size.
#[derive(Clone, Debug)]
pub struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    /// `n` singleton sets.
    pub fn new(n: usize) -> Self {
        UnionFind {
            parent: (0..n as u32).collect(),
            size: vec![1; n],
        }
    }

    /// The representative of `x`'s set.
    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let p = self.parent[x as usize];
            self.parent[x as usize] = self.parent[p as usize];
            x = p;
        }
        x
    }

    /// Merges the sets of `a` and `b`; returns false if they were already one set.
    pub fn union(&mut self, a: u32, b: u32) -> bool {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return false;
        }
        if self.size[a as usize] < self.size[b as usize] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b as usize] = a;
        self.size[a as usize] += self.size[b as usize];
        true
    }
}

/// The face and edge tables [`Topology::order_rings`] reads.
struct RingTables<'a> {
    face_offsets: &'a [u32],
    face_edges: &'a [u32],
    edge_face_offsets: &'a [u32],
}

/// Reused buffers of [`RingTables::order_ring`].
#[derive(Default)]
struct RingScratch {
    /// Outgoing and incoming edge of each incident corner.
    out_in: Vec<(u32, u32)>,
    fan_of: Vec<u32>,
    stack: Vec<usize>,
    used: Vec<bool>,
    faces: Vec<u32>,
    corners: Vec<u16>,
    edges: Vec<u32>,
}

impl RingTables<'_> {
    /// Number of faces of edge `e`.
    #[inline]
    fn nfaces(&self, e: u32) -> u32 {
        self.edge_face_offsets[e as usize + 1] - self.edge_face_offsets[e as usize]
    }

    /// Number of edge-connected fans among the corners `oi` (outgoing and incoming edge of
    /// each; through any shared edge, manifold or not).
    fn fans(oi: &[(u32, u32)], fan_of: &mut Vec<u32>, stack: &mut Vec<usize>) -> u32 {
        let n = oi.len();
        fan_of.clear();
        fan_of.resize(n, u32::MAX);
        let mut fans = 0u32;
        for k0 in 0..n {
            if fan_of[k0] != u32::MAX {
                continue;
            }
            fan_of[k0] = fans;
            stack.clear();
            stack.push(k0);
            while let Some(k) = stack.pop() {
                let (o, i) = oi[k];
                for (k2, fan) in fan_of.iter_mut().enumerate() {
                    if *fan == u32::MAX {
                        let (o2, i2) = oi[k2];
                        if o2 == o || o2 == i || i2 == o || i2 == i {
                            *fan = fans;
                            stack.push(k2);
                        }
                    }
                }
            }
            fans += 1;
        }
        fans
    }

    /// Orders one vertex's incident `faces` (with their `corners`) and `edges` in place when
    /// they form one manifold fan, and returns the vertex's kind.
    fn order_ring(
        &self,
        faces: &mut [u32],
        corners: &mut [u16],
        edges: &mut [u32],
        s: &mut RingScratch,
    ) -> VertexKind {
        let n = faces.len();
        if n == 0 {
            return VertexKind::Isolated;
        }
        // Per incident corner: outgoing and incoming edge.
        s.out_in.clear();
        s.out_in
            .extend(faces.iter().zip(corners.iter()).map(|(&f, &i)| {
                let (f, i) = (f as usize, i as usize);
                let (a, b) = (
                    self.face_offsets[f] as usize,
                    self.face_offsets[f + 1] as usize,
                );
                let prev = if i == 0 { b - 1 } else { a + i - 1 };
                (self.face_edges[a + i], self.face_edges[prev])
            }));
        let oi = &s.out_in;
        // Walk the fan from a start corner. A walk that covers every corner proves there is
        // one edge-connected fan, so the fans are counted (quadratic in the valence) only when
        // it does not: a vertex is non-manifold if it has several fans, else irregular if the
        // walk stops short, an incident edge is non-manifold or the orientation flips.
        // The start corner: on a boundary, the one whose outgoing edge is a boundary edge.
        let mut start = 0usize;
        let mut boundary = false;
        let mut start_flipped = false;
        for (k, &(o, i)) in oi.iter().enumerate() {
            if self.nfaces(o) == 1 {
                start = k;
                boundary = true;
                start_flipped = false;
                break;
            }
            if self.nfaces(i) == 1 && !boundary {
                // Only an incoming boundary edge so far: orientation flips somewhere.
                start = k;
                boundary = true;
                start_flipped = true;
            }
        }
        s.faces.clear();
        s.corners.clear();
        s.edges.clear();
        s.used.clear();
        s.used.resize(n, false);
        let mut k = start;
        let (o, i) = oi[k];
        let (entry, mut exit) = if start_flipped { (i, o) } else { (o, i) };
        let mut consistent = !start_flipped;
        s.edges.push(entry);
        loop {
            s.used[k] = true;
            s.faces.push(faces[k]);
            s.corners.push(corners[k]);
            s.edges.push(exit);
            // The other corner sharing `exit`.
            let mut next = None;
            for (k2, &(o2, i2)) in oi.iter().enumerate() {
                if k2 != k {
                    if o2 == exit {
                        next = Some((k2, i2, false));
                        break;
                    }
                    if i2 == exit {
                        next = Some((k2, o2, true));
                        break;
                    }
                }
            }
            match next {
                Some((k2, e_out, flipped)) if !s.used[k2] => {
                    if flipped {
                        consistent = false;
                    }
                    k = k2;
                    exit = e_out;
                }
                _ => break,
            }
        }
        if !boundary {
            // Closed fan: the last exit edge is the first entry edge; drop the duplicate.
            s.edges.pop();
        }
        let complete = s.faces.len() == n && s.edges.len() == edges.len();
        if !complete {
            return if Self::fans(oi, &mut s.fan_of, &mut s.stack) > 1 {
                VertexKind::NonManifold
            } else {
                VertexKind::Irregular
            };
        }
        if edges.iter().any(|&e| self.nfaces(e) > 2) {
            return VertexKind::Irregular;
        }
        faces.copy_from_slice(&s.faces);
        corners.copy_from_slice(&s.corners);
        edges.copy_from_slice(&s.edges);
        if !consistent {
            VertexKind::Irregular
        } else if boundary {
            VertexKind::Boundary
        } else {
            VertexKind::Interior
        }
    }
}

#[cfg(test)]
mod arity_tests {
    use super::*;
    use crate::generate;

    /// The uniform-arity shortcut gives the same face corners as the offsets.
    #[test]
    fn uniform_arity_shortcut() {
        for (m, want) in [
            (generate::icosahedron(), 3),
            (generate::cube(), 4),
            (generate::pyramid(), 0),
        ] {
            let t = Topology::build(&m);
            assert_eq!(t.face_arity, want);
            let mut generic = t.clone();
            generic.face_arity = 0;
            for f in 0..t.num_faces() {
                assert_eq!(t.face_vertices(f), generic.face_vertices(f));
                assert_eq!(t.face_edges(f), generic.face_edges(f));
            }
        }
        assert_eq!(uniform_arity(&[0]), 0);
        assert_eq!(uniform_arity(&[0, 3, 6, 10]), 0);
        assert_eq!(uniform_arity(&[0, 4, 8]), 4);
    }
}

#[cfg(test)]
mod ring_tests {
    use super::*;
    use crate::generate;
    use glam::DVec3;

    fn kinds(faces: Vec<Vec<u32>>) -> Vec<VertexKind> {
        let n = faces.iter().flatten().max().map_or(0, |&v| v + 1) as usize;
        let m = Mesh::from_faces(vec![DVec3::ZERO; n], faces);
        Topology::build(&m).vertex_kinds
    }

    /// Each ordered ring alternates edges and faces: face `f_i` lies between edges `e_i` and
    /// `e_{i+1}`, and `e_i` is its outgoing edge at the vertex.
    fn check_rings(t: &Topology) {
        for v in 0..t.num_vertices as usize {
            let (fs, es) = (t.vertex_faces(v), t.vertex_edges(v));
            let kind = t.vertex_kinds[v];
            match kind {
                VertexKind::Interior => assert_eq!(es.len(), fs.len()),
                VertexKind::Boundary => assert_eq!(es.len(), fs.len() + 1),
                other => panic!("vertex {v} is {other:?}"),
            }
            for (i, (&f, &c)) in fs.iter().zip(t.vertex_face_corners(v)).enumerate() {
                let fe = t.face_edges(f as usize);
                let n = fe.len();
                let c = c as usize;
                assert_eq!(t.face_vertices(f as usize)[c] as usize, v);
                assert_eq!(fe[c], es[i], "outgoing edge of face {i} at vertex {v}");
                assert_eq!(fe[(c + n - 1) % n], es[(i + 1) % es.len()], "vertex {v}");
            }
        }
    }

    #[test]
    fn manifold_rings_are_ordered() {
        for m in [
            generate::icosahedron(),
            generate::cube(),
            generate::disk(5),
            generate::grid(3, 2, false),
            generate::torus(1.0, 0.4, 5, 4, true),
        ] {
            check_rings(&Topology::build(&m));
        }
    }

    #[test]
    fn pinched_vertex_is_non_manifold() {
        // Two triangles touching at vertex 0 only.
        let k = kinds(vec![vec![0, 1, 2], vec![0, 3, 4]]);
        assert_eq!(k[0], VertexKind::NonManifold);
        assert!(k[1..].iter().all(|&x| x == VertexKind::Boundary));
        // Two fans, one of them around a non-manifold edge: still non-manifold.
        let k = kinds(vec![
            vec![0, 1, 2],
            vec![1, 0, 3],
            vec![0, 1, 4],
            vec![0, 5, 6],
        ]);
        assert_eq!(k[0], VertexKind::NonManifold);
        assert_eq!(k[1], VertexKind::Irregular);
    }

    #[test]
    fn non_manifold_edge_and_flipped_orientation_are_irregular() {
        // Three triangles on edge 0-1.
        let k = kinds(vec![vec![0, 1, 2], vec![1, 0, 3], vec![0, 1, 4]]);
        assert_eq!(&k[..2], &[VertexKind::Irregular, VertexKind::Irregular]);
        assert!(k[2..].iter().all(|&x| x == VertexKind::Boundary));
        // Two triangles traversing edge 0-1 the same way.
        let k = kinds(vec![vec![0, 1, 2], vec![0, 1, 3]]);
        assert_eq!(&k[..2], &[VertexKind::Irregular, VertexKind::Irregular]);
        // A closed fan with one face flipped.
        let k = kinds(vec![
            vec![0, 1, 2],
            vec![0, 2, 3],
            vec![0, 4, 3],
            vec![0, 4, 1],
        ]);
        assert_eq!(k[0], VertexKind::Irregular);
    }
}

//! Semi-regular meshes: a base mesh and `L` levels of subdivision connectivity.
//!
//! Maret 2003 §4.2.3 ("Decimation in Meshes", Fig. 4.4): a mesh has *subdivision
//! connectivity* if its graph is that of a base mesh split `L` times; wavelet analysis then
//! decimates it level by level (the even vertices are kept, the odd ones, one per coarse
//! edge, are removed). A [`Hierarchy`] stores such a mesh with its connectivity made
//! implicit by the ordering contract of [`crate::subdivision::refine`]: the vertices of level
//! `j` are the first `V_j` vertices of level `j + 1` (then one vertex per level-`j` edge, in
//! edge order), and triangle `k`'s children are `4k..4k+3` in Maret eq. 5.7 order (polygon
//! splits: OpenSubdiv's order). Only the finest positions are stored; level `j`'s
//! connectivity is its [`Topology`].
//!
//! [`Hierarchy::detect`] recovers the structure from a triangle mesh given in any vertex and
//! face order (the inverse of the 1-to-4 split, applied repeatedly as in Fig. 4.4) and
//! renumbers it into the contract, returning the permutation ([`Renumbering`]). All-quad
//! meshes are detected as Catmull-Clark (1-to-4 quad) splits instead (`hierarchy/quad.rs`,
//! Bertram et al. §4.1 Fig. 7), giving a [`Split::Polygons`] hierarchy.
//!
//! # Detection (one coarsening step)
//! In a 1-to-4 split, every child triangle is either a *central* triangle (three odd
//! vertices) or a *corner* triangle (one even vertex, two odd ones), the even vertices form an
//! independent set, and an interior odd vertex has valence 6 (4 on a boundary). Labelling one
//! triangle fixes its edge-neighbours' labels (across a corner's odd-odd edge lies a central
//! triangle; across its even-odd edges, corners with the same even vertex; across a central
//! triangle's edges, corners whose even vertex is opposite the edge), so each edge-connected
//! component is labelled by a breadth-first propagation from one seed triangle. The seed is a
//! triangle at a vertex that cannot be odd (interior valence ≠ 6, boundary valence ≠ 4);
//! in a fully regular component the four labellings of its first triangle are tried in turn.
//! Each central triangle and its three neighbours then form a group; the group's corners give
//! the coarse triangle, and each odd vertex its coarse edge. After the last step the contract
//! hierarchy is rebuilt from the coarsest mesh and checked to reproduce every input triangle
//! (with its orientation), so an accepted detection is exact.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;

use crate::mesh::Mesh;
use crate::subdivision::refine::{child_faces, child_vertex_count, refine_topology, Split};
use crate::subdivision::MAX_FACES;
use crate::topology::{Topology, VertexKind};
use crate::validate::{require_arity, require_manifold};
use crate::{Error, Result};

mod quad;

/// A semi-regular mesh: base mesh, per-level topology, finest positions.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    /// How each level splits its faces.
    pub split: Split,
    /// The base mesh (level 0): its faces and tags; its positions are the finest-level
    /// positions of the base vertices (`positions[..V_0]`).
    pub base: Mesh,
    /// Topology of levels `0..=L` (`topologies[j]` has `V_j` vertices). Level 0 carries the
    /// base mesh's tags; finer levels carry no sharpness. 1-rings are ordered at level 0
    /// only.
    pub topologies: Vec<Topology>,
    /// Positions of the finest level `L`, in contract order.
    pub positions: Vec<DVec3>,
}

/// Maps a detected hierarchy back to the input mesh's numbering.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Renumbering {
    /// For each hierarchy vertex (finest level, contract order), its input vertex.
    pub vertices: Vec<u32>,
    /// For each finest-level hierarchy face, its input face (the hierarchy's triangle may be
    /// a cyclic rotation of the input's; the orientation is the same).
    pub faces: Vec<u32>,
}

impl Renumbering {
    /// Per-vertex values in hierarchy order, moved back to input order.
    pub fn to_input<T: Copy + Default>(&self, values: &[T]) -> Vec<T> {
        let mut out = vec![T::default(); values.len()];
        for (new, &old) in self.vertices.iter().enumerate() {
            out[old as usize] = values[new];
        }
        out
    }

    /// Per-vertex values in input order, moved to hierarchy order.
    pub fn from_input<T: Copy>(&self, values: &[T]) -> Vec<T> {
        self.vertices
            .iter()
            .map(|&old| values[old as usize])
            .collect()
    }
}

impl Hierarchy {
    /// The hierarchy of `base` split `levels` times (`split` says how), with the given finest
    /// positions, or, if `None`, the linear ones (midpoints of edges, centroids of faces:
    /// midpoint / bilinear subdivision).
    ///
    /// # Errors
    /// [`Error::Mesh`] if `base` has bad indices, is not a consistently oriented manifold, or
    /// (for [`Split::Triangles`]) has non-triangles; [`Error::InvalidArgument`] if the result
    /// would exceed [`MAX_FACES`] faces or `positions` has the wrong length.
    pub fn new(
        base: &Mesh,
        levels: u32,
        split: Split,
        positions: Option<Vec<DVec3>>,
    ) -> Result<Hierarchy> {
        let topologies = Self::checked_topologies(base, levels, split, false)?;
        let n_fine = topologies.last().unwrap().num_vertices as usize;
        let positions = match positions {
            Some(p) => {
                if p.len() != n_fine {
                    return Err(Error::InvalidArgument(format!(
                        "{} finest positions given, level {levels} has {n_fine} vertices",
                        p.len()
                    )));
                }
                p
            }
            None => {
                let mut p = base.positions.clone();
                for t in &topologies[..levels as usize] {
                    p = linear_refine(t, split, &p);
                }
                p
            }
        };
        let mut base = base.clone();
        let nb = base.positions.len();
        base.positions.copy_from_slice(&positions[..nb]);
        Ok(Hierarchy {
            split,
            base,
            topologies,
            positions,
        })
    }

    /// The connectivity of [`Hierarchy::new`] for a decoder, without positions: `positions`
    /// is **empty** (and `base.positions` are `base`'s), levels `0..L` have their full
    /// topology, and the finest level `L` only its faces (`num_vertices`, `face_offsets`,
    /// `face_vertices`, `face_arity`; its edge and vertex tables are empty). This is what a
    /// synthesis reads: level `j`'s transform, the offspring forest and the local frames use
    /// the topologies of levels `j < L` and the finest faces (the decoder of
    /// [`crate::codec::progressive`]).
    ///
    /// # Errors
    /// As [`Hierarchy::new`].
    pub(crate) fn skeleton(base: &Mesh, levels: u32, split: Split) -> Result<Hierarchy> {
        let topologies = Self::checked_topologies(base, levels, split, true)?;
        Ok(Hierarchy {
            split,
            base: base.clone(),
            topologies,
            positions: Vec::new(),
        })
    }

    /// [`Hierarchy::skeleton`] without the finest level's faces: level `L` is only its vertex
    /// count and face arity (a decoder builds its faces apart, [`child_faces`] of level
    /// `L − 1`, in parallel with the work that needs the coarse levels only).
    ///
    /// # Errors
    /// As [`Hierarchy::new`].
    pub(crate) fn skeleton_without_finest_faces(
        base: &Mesh,
        levels: u32,
        split: Split,
    ) -> Result<Hierarchy> {
        if levels == 0 {
            return Self::skeleton(base, 0, split);
        }
        // The checks of `levels` levels first (the face limit), then the coarse levels.
        let faces_out = match split {
            Split::Triangles | Split::QuadTri => {
                (base.num_faces() as u64).saturating_mul(4u64.saturating_pow(levels))
            }
            Split::Polygons => (base.face_indices.len() as u64)
                .saturating_mul(4u64.saturating_pow(levels.saturating_sub(1))),
        };
        if faces_out > MAX_FACES {
            return Err(Error::InvalidArgument(format!(
                "{levels} levels on {} faces would make {faces_out} faces, more than the {MAX_FACES} supported; use fewer levels",
                base.num_faces()
            )));
        }
        let mut topologies = Self::checked_topologies(base, levels - 1, split, false)?;
        let parent = topologies.last().unwrap();
        let finest = Topology {
            num_vertices: child_vertex_count(parent, split) as u32,
            face_arity: match split {
                _ if parent.num_faces() == 0 => 0,
                Split::Triangles => 3,
                Split::Polygons => 4,
                Split::QuadTri => 0,
            },
            ..Topology::default()
        };
        topologies.push(finest);
        Ok(Hierarchy {
            split,
            base: base.clone(),
            topologies,
            positions: Vec::new(),
        })
    }

    /// The level topologies of `base` split `levels` times, after the checks of
    /// [`Hierarchy::new`]; with `faces_only_finest`, the finest level holds its faces only
    /// (see [`Hierarchy::skeleton`]).
    fn checked_topologies(
        base: &Mesh,
        levels: u32,
        split: Split,
        faces_only_finest: bool,
    ) -> Result<Vec<Topology>> {
        base.check_indices()?;
        if split == Split::Triangles {
            require_arity(
                base,
                3,
                "triangle hierarchy",
                "triangles",
                "use Split::Polygons (quads) for polygon meshes",
            )?;
        }
        let faces_out = match split {
            Split::Triangles | Split::QuadTri => {
                (base.num_faces() as u64).saturating_mul(4u64.saturating_pow(levels))
            }
            Split::Polygons => (base.face_indices.len() as u64)
                .saturating_mul(4u64.saturating_pow(levels.saturating_sub(1))),
        };
        if levels > 0 && faces_out > MAX_FACES {
            return Err(Error::InvalidArgument(format!(
                "{levels} levels on {} faces would make {faces_out} faces, more than the {MAX_FACES} supported; use fewer levels",
                base.num_faces()
            )));
        }
        let t0 = Topology::build(base);
        require_manifold(&t0)?;
        let mut topologies = Vec::with_capacity(levels as usize + 1);
        topologies.push(t0);
        for l in 0..levels {
            let parent = topologies.last().unwrap();
            let child = if faces_only_finest && l + 1 == levels {
                let (face_offsets, face_vertices) = child_faces(parent, split);
                Topology {
                    num_vertices: child_vertex_count(parent, split) as u32,
                    face_arity: if split == Split::QuadTri {
                        0
                    } else {
                        face_offsets.get(1).copied().unwrap_or(0)
                    },
                    face_offsets,
                    face_vertices,
                    ..Topology::default()
                }
            } else {
                refine_topology(parent, split, false).0
            };
            topologies.push(child);
        }
        Ok(topologies)
    }

    /// Number of subdivision levels `L` (0 for a base mesh alone).
    pub fn levels(&self) -> usize {
        self.topologies.len() - 1
    }

    /// Number of vertices `V_j` of level `j` (`0..=L`).
    pub fn num_vertices(&self, level: usize) -> usize {
        self.topologies[level].num_vertices as usize
    }

    /// The topology of level `j` (`0..=L`).
    pub fn topology(&self, level: usize) -> &Topology {
        &self.topologies[level]
    }

    /// Level `j`'s vertices sampled at the finest level (`positions[..V_j]`): the "lazy"
    /// coarse positions.
    pub fn level_samples(&self, level: usize) -> &[DVec3] {
        &self.positions[..self.num_vertices(level)]
    }

    /// The finest level as a mesh (contract order).
    pub fn finest_mesh(&self) -> Mesh {
        let t = self.topologies.last().unwrap();
        Mesh {
            positions: self.positions.clone(),
            face_offsets: t.face_offsets.clone(),
            face_indices: t.face_vertices.clone(),
            ..Mesh::new()
        }
    }

    /// The mesh of level `j` with the given positions (one per level-`j` vertex).
    ///
    /// # Panics
    /// If `positions.len() != V_j`.
    pub fn level_mesh(&self, level: usize, positions: Vec<DVec3>) -> Mesh {
        let t = &self.topologies[level];
        assert_eq!(positions.len(), t.num_vertices as usize, "level positions");
        Mesh {
            positions,
            face_offsets: t.face_offsets.clone(),
            face_indices: t.face_vertices.clone(),
            ..Mesh::new()
        }
    }

    /// Detects subdivision connectivity (1-to-4 triangle splits, or for an all-quad mesh
    /// Catmull-Clark 1-to-4 quad splits giving a [`Split::Polygons`] hierarchy with an
    /// all-quad base, see `hierarchy/quad.rs`) in `mesh`, whose vertices and faces may be in
    /// any order, and renumbers it into the ordering contract.
    ///
    /// With `levels = Some(L)`, exactly `L` coarsening steps are required; with `None`, as
    /// many as the mesh allows (at least one). Unreferenced vertices become isolated base
    /// vertices. Tags and attributes are not carried.
    ///
    /// # Errors
    /// [`Error::Mesh`] if the mesh has bad indices, non-triangles, or is not a consistently
    /// oriented manifold; [`Error::Hierarchy`] naming the coarsening step and the triangle
    /// that is not part of a 1-to-4 group (e.g. "coarsening step 2: triangle (input vertices
    /// 3, 17, 40) is not part of a 1-to-4 group: ...").
    pub fn detect(mesh: &Mesh, levels: Option<u32>) -> Result<(Hierarchy, Renumbering)> {
        mesh.check_indices()?;
        if mesh.num_faces() > 0 && mesh.is_quad_mesh() {
            return quad::detect_quads(mesh, levels);
        }
        require_arity(
            mesh,
            3,
            "subdivision-connectivity detection (triangles; all-quad meshes are detected as Catmull-Clark splits)",
            "triangles",
            "triangulate the mesh first (it then has no 1-to-4 structure unless it was built by one)",
        )?;
        let nv = mesh.num_vertices();
        let input: Vec<[u32; 3]> = mesh.faces().map(|f| [f[0], f[1], f[2]]).collect();
        let mut faces = input.clone();
        // Per step (finest first): coarse edge (sorted input ids) -> odd input vertex.
        let mut steps: Vec<OddVertices> = Vec::new();
        loop {
            let step = steps.len() + 1;
            if levels.is_some_and(|l| step > l as usize) {
                break;
            }
            match coarsen(nv, &faces, step) {
                Ok((coarse, odd)) => {
                    faces = coarse;
                    steps.push(odd);
                }
                Err(e) => {
                    if levels.is_none() && step > 1 && matches!(e, Error::Hierarchy(_)) {
                        break;
                    }
                    return Err(e);
                }
            }
        }
        let l = steps.len();
        // Base vertices: every input vertex never odd, in input order.
        let mut is_odd = vec![false; nv];
        for s in &steps {
            for &o in s.values() {
                is_odd[o as usize] = true;
            }
        }
        let mut to_input: Vec<u32> = (0..nv as u32).filter(|&v| !is_odd[v as usize]).collect();
        let mut new_of = vec![u32::MAX; nv];
        for (n, &o) in to_input.iter().enumerate() {
            new_of[o as usize] = n as u32;
        }
        let base_tris: Vec<[u32; 3]> = faces
            .iter()
            .map(|t| t.map(|v| new_of[v as usize]))
            .collect();
        let base_pos = to_input
            .iter()
            .map(|&o| mesh.positions[o as usize])
            .collect();
        let base = Mesh::from_triangles(base_pos, &base_tris);
        let t0 = Topology::build(&base);
        require_manifold(&t0)?;
        let mut topologies = vec![t0];
        for j in 0..l {
            let parent = &topologies[j];
            let odd = &steps[l - 1 - j];
            for (e, &[a, b]) in parent.edge_vertices.iter().enumerate() {
                let (ia, ib) = (to_input[a as usize], to_input[b as usize]);
                let Some(&o) = odd.get(&key(ia, ib)) else {
                    return Err(Error::Hierarchy(format!(
                        "level {j}: edge {e} (input vertices {ia}, {ib}) has no odd vertex at level {}",
                        j + 1
                    )));
                };
                if new_of[o as usize] != u32::MAX {
                    return Err(Error::Hierarchy(format!(
                        "level {}: input vertex {o} is the odd vertex of two edges",
                        j + 1
                    )));
                }
                new_of[o as usize] = to_input.len() as u32;
                to_input.push(o);
            }
            let (child, _) = refine_topology(parent, Split::Triangles, false);
            debug_assert_eq!(child.num_vertices as usize, to_input.len());
            topologies.push(child);
        }
        if to_input.len() != nv {
            return Err(Error::Hierarchy(format!(
                "{} of the {nv} vertices are not in the rebuilt hierarchy",
                nv - to_input.len()
            )));
        }
        // Every rebuilt finest triangle must be an input triangle, with its orientation.
        let mut by_key: IntMap<[u32; 3], u32> = int_map(input.len());
        for (f, t) in input.iter().enumerate() {
            by_key.insert(rotate_min(*t), f as u32);
        }
        let finest = topologies.last().unwrap();
        let mut face_map = Vec::with_capacity(finest.num_faces());
        let mut used = vec![false; input.len()];
        for f in 0..finest.num_faces() {
            let v = finest.face_vertices(f);
            let t = [
                to_input[v[0] as usize],
                to_input[v[1] as usize],
                to_input[v[2] as usize],
            ];
            match by_key.get(&rotate_min(t)) {
                Some(&g) if !used[g as usize] => {
                    used[g as usize] = true;
                    face_map.push(g);
                }
                _ => {
                    return Err(Error::Hierarchy(format!(
                        "the rebuilt level {l} triangle {f} (input vertices {}, {}, {}) is not an input triangle with that orientation",
                        t[0], t[1], t[2]
                    )))
                }
            }
        }
        if face_map.len() != input.len() {
            return Err(Error::Hierarchy(format!(
                "the rebuilt hierarchy has {} finest triangles, the input {}",
                face_map.len(),
                input.len()
            )));
        }
        let positions = to_input
            .iter()
            .map(|&o| mesh.positions[o as usize])
            .collect();
        Ok((
            Hierarchy {
                split: Split::Triangles,
                base,
                topologies,
                positions,
            },
            Renumbering {
                vertices: to_input,
                faces: face_map,
            },
        ))
    }
}

/// Linear refinement of `p` over `t`: vertices stay, edge points are midpoints and (polygon
/// splits) face points centroids: midpoint / bilinear subdivision.
fn linear_refine(t: &Topology, split: Split, p: &[DVec3]) -> Vec<DVec3> {
    let mut out = p.to_vec();
    out.extend(
        t.edge_vertices
            .iter()
            .map(|&[a, b]| 0.5 * (p[a as usize] + p[b as usize])),
    );
    if split == Split::Polygons {
        out.extend((0..t.num_faces()).map(|f| {
            let fv = t.face_vertices(f);
            fv.iter().map(|&v| p[v as usize]).sum::<DVec3>() / fv.len() as f64
        }));
    }
    out
}

/// A multiplicative hasher for integer keys (FxHash's mixing): the maps here hold millions
/// of integer keys, for which SipHash's DoS resistance is not needed.
#[derive(Default)]
struct IntHasher(u64);

impl Hasher for IntHasher {
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    #[inline]
    fn write_u32(&mut self, x: u32) {
        self.write_u64(x as u64);
    }
    #[inline]
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    #[inline]
    fn write_usize(&mut self, x: usize) {
        self.write_u64(x as u64);
    }
}

/// A hash map with [`IntHasher`].
type IntMap<K, V> = HashMap<K, V, BuildHasherDefault<IntHasher>>;

fn int_map<K, V>(capacity: usize) -> IntMap<K, V> {
    IntMap::with_capacity_and_hasher(capacity, Default::default())
}

/// Sorted-pair key of an edge.
#[inline]
fn key(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    (lo as u64) << 32 | hi as u64
}

/// The cyclic rotation of `t` starting at its smallest vertex.
fn rotate_min(t: [u32; 3]) -> [u32; 3] {
    let i = (0..3).min_by_key(|&i| t[i]).unwrap();
    [t[i], t[(i + 1) % 3], t[(i + 2) % 3]]
}

const UNSET: u8 = u8::MAX;
const CENTRAL: u8 = 3;
const EVEN: u8 = 1;
const ODD: u8 = 2;

/// A failed labelling: the triangle where it failed and why.
pub(crate) struct Conflict {
    pub(crate) face: u32,
    pub(crate) reason: &'static str,
}

/// One coarsening step's labelling of faces and vertices, as [`label_components`] drives it.
pub(crate) trait Labelling {
    /// Starts a hypothesis (forgets which labels the previous one set).
    fn begin(&mut self);
    /// Propagates `label` of face `seed` over its edge-connected component.
    fn propagate(&mut self, seed: u32, label: u8) -> std::result::Result<(), Conflict>;
    /// Clears the labels set since [`Labelling::begin`].
    fn reset(&mut self);
}

/// Labels every edge-connected component of `topo` (see [`first_labelling`]): `pinned(v)` is
/// true for vertices whose label is forced (they fix the seed), `noun` names the faces and
/// `name` a face in messages, `fail` turns a conflict into the error to return.
pub(crate) fn label_components(
    topo: &Topology,
    step: usize,
    noun: &str,
    name: &dyn Fn(u32) -> String,
    pinned: &dyn Fn(u32) -> bool,
    labels: &mut impl Labelling,
    fail: &dyn Fn(Conflict) -> Error,
) -> Result<()> {
    for members in edge_components(topo) {
        let start = members[0];
        if members.len() % 4 != 0 {
            return Err(Error::Hierarchy(format!(
                "coarsening step {step}: the part of the mesh around {} has {} {noun}, not a multiple of 4",
                name(start),
                members.len()
            )));
        }
        let forced = members.iter().find_map(|&f| {
            topo.face_vertices(f as usize)
                .iter()
                .position(|&v| pinned(v))
                .map(|i| (f, i as u8))
        });
        first_labelling(start, forced, |seed, l| {
            labels.begin();
            let r = labels.propagate(seed, l);
            if r.is_err() {
                labels.reset();
            }
            r
        })
        .map_err(fail)?;
    }
    Ok(())
}

impl Labelling for Labels<'_> {
    fn begin(&mut self) {
        self.touched_faces.clear();
        self.touched_verts.clear();
    }
    fn propagate(&mut self, seed: u32, label: u8) -> std::result::Result<(), Conflict> {
        self.propagate_from(seed, label)
    }
    fn reset(&mut self) {
        self.clear_touched();
    }
}

/// The edge-connected components of `topo`'s faces (faces sharing an edge), each listed from
/// its smallest face, in order of that face.
pub(crate) fn edge_components(topo: &Topology) -> Vec<Vec<u32>> {
    let nf = topo.num_faces();
    let mut seen = vec![false; nf];
    let mut stack = Vec::new();
    let mut out = Vec::new();
    for start in 0..nf as u32 {
        if seen[start as usize] {
            continue;
        }
        seen[start as usize] = true;
        stack.push(start);
        let mut members = vec![start];
        while let Some(f) = stack.pop() {
            for &e in topo.face_edges(f as usize) {
                for &g in topo.edge_faces(e as usize) {
                    if !seen[g as usize] {
                        seen[g as usize] = true;
                        stack.push(g);
                        members.push(g);
                    }
                }
            }
        }
        out.push(members);
    }
    out
}

/// Labels one component from a seed: the `forced` (face, label) if a vertex pins it, else each
/// of the four labels of `start` in turn. `attempt` propagates one hypothesis (undoing its
/// partial labels when it fails); the first success wins, otherwise the first failure is
/// returned.
pub(crate) fn first_labelling<E>(
    start: u32,
    forced: Option<(u32, u8)>,
    mut attempt: impl FnMut(u32, u8) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    let hypotheses: Vec<(u32, u8)> = match forced {
        Some(h) => vec![h],
        None => (0..4).map(|l| (start, l)).collect(),
    };
    let mut first_err = None;
    for (seed, l) in hypotheses {
        match attempt(seed, l) {
            Ok(()) => return Ok(()),
            Err(e) => {
                first_err.get_or_insert(e);
            }
        }
    }
    Err(first_err.expect("at least one hypothesis"))
}

/// Labelling state of one coarsening step.
struct Labels<'a> {
    topo: &'a Topology,
    face: Vec<u8>,
    vert: Vec<u8>,
    touched_faces: Vec<u32>,
    touched_verts: Vec<u32>,
}

impl Labels<'_> {
    /// Labels face `g` (`CENTRAL`, or the corner of its even vertex).
    fn assign(&mut self, g: u32, label: u8, queue: &mut Vec<u32>) -> Result<(), Conflict> {
        let cur = self.face[g as usize];
        if cur == label {
            return Ok(());
        }
        if cur != UNSET {
            return Err(Conflict {
                face: g,
                reason: "its neighbours disagree on which of its vertices is even",
            });
        }
        self.face[g as usize] = label;
        self.touched_faces.push(g);
        for (i, &v) in self.topo.face_vertices(g as usize).iter().enumerate() {
            let want = if label == i as u8 { EVEN } else { ODD };
            let cur = self.vert[v as usize];
            if cur == UNSET {
                self.vert[v as usize] = want;
                self.touched_verts.push(v);
            } else if cur != want {
                return Err(Conflict {
                    face: g,
                    reason: if want == EVEN {
                        "its would-be even vertex is odd in a neighbouring group"
                    } else {
                        "its would-be odd vertex is even in a neighbouring group"
                    },
                });
            }
        }
        queue.push(g);
        Ok(())
    }

    /// Propagates the labelling from `seed` over its edge-connected component.
    fn propagate_from(&mut self, seed: u32, label: u8) -> std::result::Result<(), Conflict> {
        let topo = self.topo;
        let mut queue = Vec::new();
        self.assign(seed, label, &mut queue)?;
        while let Some(f) = queue.pop() {
            let l = self.face[f as usize];
            let fv = topo.face_vertices(f as usize);
            let fe = topo.face_edges(f as usize);
            for i in 0..3 {
                // Edge i joins corners i and i + 1; the corner opposite is i + 2.
                let even_edge = l != CENTRAL && (l as usize == i || l as usize == (i + 1) % 3);
                let faces = topo.edge_faces(fe[i] as usize);
                let Some(&g) = faces.iter().find(|&&g| g != f) else {
                    if !even_edge {
                        return Err(Conflict {
                            face: f,
                            reason: if l == CENTRAL {
                                "it would be a central triangle, but has a boundary edge"
                            } else {
                                "the central triangle of its group would lie across a boundary edge"
                            },
                        });
                    }
                    continue;
                };
                let gv = topo.face_vertices(g as usize);
                let corner_of = |x: u32| gv.iter().position(|&y| y == x).unwrap() as u8;
                let gl = if l == CENTRAL {
                    // g's even vertex is the one not on the shared edge.
                    let (a, b) = (fv[i], fv[(i + 1) % 3]);
                    gv.iter().position(|&y| y != a && y != b).unwrap() as u8
                } else if even_edge {
                    corner_of(fv[l as usize])
                } else {
                    CENTRAL
                };
                self.assign(g, gl, &mut queue)?;
            }
        }
        Ok(())
    }

    fn clear_touched(&mut self) {
        for f in self.touched_faces.drain(..) {
            self.face[f as usize] = UNSET;
        }
        for v in self.touched_verts.drain(..) {
            self.vert[v as usize] = UNSET;
        }
    }
}

/// Per coarse edge (sorted-pair key of its input vertex ids), its odd input vertex.
type OddVertices = IntMap<u64, u32>;

/// One coarsening step (the inverse of one 1-to-4 split, Maret Fig. 4.4): the coarse
/// triangles (input vertex ids) and, per coarse edge, its odd vertex.
fn coarsen(nv: usize, faces: &[[u32; 3]], step: usize) -> Result<(Vec<[u32; 3]>, OddVertices)> {
    let mesh = Mesh::from_triangles(vec![DVec3::ZERO; nv], faces);
    let topo = Topology::build(&mesh);
    require_manifold(&topo)?;
    let name = |f: u32| {
        let v = topo.face_vertices(f as usize);
        if step == 1 {
            format!("triangle {f} (vertices {}, {}, {})", v[0], v[1], v[2])
        } else {
            format!(
                "coarse triangle (input vertices {}, {}, {})",
                v[0], v[1], v[2]
            )
        }
    };
    let fail = |c: Conflict| {
        Error::Hierarchy(format!(
            "coarsening step {step}: {} is not part of a 1-to-4 group: {}",
            name(c.face),
            c.reason
        ))
    };
    let nf = topo.num_faces();
    if nf == 0 {
        return Err(Error::Hierarchy(format!(
            "coarsening step {step}: the mesh has no triangles"
        )));
    }
    // A vertex that cannot be odd: odd vertices have valence 6 inside, 4 on a boundary.
    let forced_even = |v: u32| match topo.vertex_kinds[v as usize] {
        VertexKind::Interior => topo.valence(v as usize) != 6,
        VertexKind::Boundary => topo.valence(v as usize) != 4,
        _ => false,
    };
    let mut labels = Labels {
        topo: &topo,
        face: vec![UNSET; nf],
        vert: vec![UNSET; nv],
        touched_faces: Vec::new(),
        touched_verts: Vec::new(),
    };
    // Edge-connected components, each labelled from one seed.
    label_components(
        &topo,
        step,
        "triangles",
        &name,
        &forced_even,
        &mut labels,
        &fail,
    )?;
    // Groups: each central triangle with its three corner neighbours.
    let mut coarse = Vec::with_capacity(nf / 4);
    let mut odd: OddVertices = int_map(nf / 2);
    let mut odd_edge = vec![u64::MAX; nv];
    let mut grouped = vec![false; nf];
    for c in 0..nf as u32 {
        if labels.face[c as usize] != CENTRAL {
            continue;
        }
        let cv = topo.face_vertices(c as usize);
        let ce = topo.face_edges(c as usize);
        // Across edge i of the central triangle (v3 v4 v5) lies the corner of v1, v2, v0
        // for i = 0, 1, 2 (Maret eq. 5.7).
        let mut even = [0u32; 3];
        for i in 0..3 {
            let g = *topo
                .edge_faces(ce[i] as usize)
                .iter()
                .find(|&&g| g != c)
                .expect("central triangles have no boundary edge");
            if std::mem::replace(&mut grouped[g as usize], true) {
                return Err(fail(Conflict {
                    face: g,
                    reason: "it touches two central triangles",
                }));
            }
            let gl = labels.face[g as usize] as usize;
            even[(i + 1) % 3] = topo.face_vertices(g as usize)[gl];
        }
        grouped[c as usize] = true;
        if even[0] == even[1] || even[1] == even[2] || even[2] == even[0] {
            return Err(fail(Conflict {
                face: c,
                reason: "its group would make a degenerate coarse triangle",
            }));
        }
        coarse.push(even);
        for i in 0..3 {
            let (o, k) = (cv[i], key(even[i], even[(i + 1) % 3]));
            let oe = &mut odd_edge[o as usize];
            if *oe == u64::MAX {
                *oe = k;
            }
            if *odd.entry(k).or_insert(o) != o || *oe != k {
                return Err(fail(Conflict {
                    face: c,
                    reason: "an odd vertex would lie on two coarse edges (or a coarse edge carry two odd vertices)",
                }));
            }
        }
    }
    if let Some(f) = grouped.iter().position(|&g| !g) {
        return Err(fail(Conflict {
            face: f as u32,
            reason: "no central triangle is adjacent to it",
        }));
    }
    Ok((coarse, odd))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;

    /// The skeleton without the finest faces equals the skeleton but for those faces, which
    /// are `child_faces` of its level `L − 1`; the face limit is checked the same way.
    #[test]
    fn skeleton_without_finest_faces_equals_the_skeleton() {
        let cases = [
            (generate::icosahedron(), Split::Triangles),
            (generate::grid(3, 2, true), Split::Triangles),
            (generate::cube(), Split::Polygons),
        ];
        for (base, split) in cases {
            for levels in 0..4 {
                let s = Hierarchy::skeleton(&base, levels, split).unwrap();
                let d = Hierarchy::skeleton_without_finest_faces(&base, levels, split).unwrap();
                let l = levels as usize;
                // (Topology has no PartialEq: its Debug form lists every table.)
                let coarse = |h: &Hierarchy| format!("{:?}", &h.topologies[..l]);
                assert_eq!(coarse(&s), coarse(&d), "{split:?} {levels}");
                let (sf, df) = (&s.topologies[l], &d.topologies[l]);
                assert_eq!(
                    (sf.num_vertices, sf.face_arity),
                    (df.num_vertices, df.face_arity)
                );
                if levels > 0 {
                    assert!(df.face_vertices.is_empty());
                    let (o, v) = child_faces(&d.topologies[l - 1], split);
                    assert_eq!((&o, &v), (&sf.face_offsets, &sf.face_vertices));
                }
            }
        }
        let too_many = Hierarchy::skeleton_without_finest_faces(
            &generate::icosahedron(),
            14,
            Split::Triangles,
        );
        assert!(matches!(too_many, Err(Error::InvalidArgument(_))));
    }

    /// A tiny deterministic generator (SplitMix64).
    pub(crate) struct Rng(pub u64);
    impl Rng {
        pub fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
            z ^ (z >> 31)
        }
        pub fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
        pub fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// `m` with vertices and faces randomly permuted and face corners randomly rotated.
    fn shuffle(m: &Mesh, rng: &mut Rng) -> (Mesh, Vec<u32>) {
        let n = m.num_vertices();
        let mut perm: Vec<u32> = (0..n as u32).collect(); // old -> new
        for i in (1..n).rev() {
            perm.swap(i, rng.below(i + 1));
        }
        let mut pos = vec![DVec3::ZERO; n];
        for (old, &new) in perm.iter().enumerate() {
            pos[new as usize] = m.positions[old];
        }
        let mut tris: Vec<[u32; 3]> = m
            .faces()
            .map(|f| {
                let r = rng.below(3);
                [f[r], f[(r + 1) % 3], f[(r + 2) % 3]].map(|v| perm[v as usize])
            })
            .collect();
        for i in (1..tris.len()).rev() {
            tris.swap(i, rng.below(i + 1));
        }
        (Mesh::from_triangles(pos, &tris), perm)
    }

    fn merged(a: &Mesh, b: &Mesh, shift: DVec3) -> Mesh {
        let mut m = a.clone();
        let off = a.num_vertices() as u32;
        m.positions.extend(b.positions.iter().map(|&p| p + shift));
        for f in b.faces() {
            let g: Vec<u32> = f.iter().map(|&v| v + off).collect();
            m.push_face(&g);
        }
        m
    }

    #[test]
    fn new_matches_refinement_counts() {
        let h = Hierarchy::new(&generate::icosahedron(), 3, Split::Triangles, None).unwrap();
        assert_eq!(h.levels(), 3);
        assert_eq!(h.num_vertices(0), 12);
        assert_eq!(h.num_vertices(1), 42);
        assert_eq!(h.num_vertices(3), 642);
        assert_eq!(h.topology(3).num_faces(), 20 * 64);
        // Linear positions: the midpoint subdivision of the crate.
        let mut m = generate::icosahedron();
        for _ in 0..3 {
            m = generate::midpoint_split(&m);
        }
        assert_eq!(h.positions, m.positions);
        assert_eq!(h.finest_mesh().face_indices, m.face_indices);
        let q = Hierarchy::new(&generate::cube(), 2, Split::Polygons, None).unwrap();
        assert_eq!(q.topology(2).num_faces(), 6 * 16);
    }

    /// `same_base`: the base vertices must be the original ones (false for fully regular
    /// meshes such as a (6, 6, 6) torus, which have several valid coarsenings).
    fn roundtrip(base: &Mesh, levels: u32, seed: u64, same_base: bool) {
        let mut rng = Rng(seed);
        // Non-linear finest positions so that positions really have to be mapped.
        let lin = Hierarchy::new(base, levels, Split::Triangles, None).unwrap();
        let pos: Vec<DVec3> = lin
            .positions
            .iter()
            .map(|&p| p + 0.01 * DVec3::new(rng.unit(), rng.unit(), rng.unit()))
            .collect();
        let h = Hierarchy::new(base, levels, Split::Triangles, Some(pos)).unwrap();
        let (shuffled, perm) = shuffle(&h.finest_mesh(), &mut rng);
        let (d, r) = Hierarchy::detect(&shuffled, Some(levels)).unwrap();
        assert_eq!(d.levels(), levels as usize);
        assert_eq!(d.base.num_vertices(), base.num_vertices());
        assert_eq!(d.base.num_faces(), base.num_faces());
        for j in 0..=levels as usize {
            assert_eq!(d.num_vertices(j), h.num_vertices(j));
        }
        // Positions and faces map back exactly.
        assert_eq!(r.to_input(&d.positions), shuffled.positions);
        for (f, &g) in r.faces.iter().enumerate() {
            let a = d.topology(levels as usize).face_vertices(f);
            let b = shuffled.face(g as usize);
            let a = rotate_min([a[0], a[1], a[2]].map(|v| r.vertices[v as usize]));
            assert_eq!(a, rotate_min([b[0], b[1], b[2]]));
        }
        // Base vertices are original base vertices (up to order).
        if !same_base {
            return;
        }
        let mut got: Vec<u32> = r.vertices[..base.num_vertices()].to_vec();
        let mut want: Vec<u32> = perm[..base.num_vertices()].to_vec();
        got.sort_unstable();
        want.sort_unstable();
        assert_eq!(got, want);
        // Unbounded detection finds the same number of levels.
        let (d2, _) = Hierarchy::detect(&shuffled, None).unwrap();
        assert_eq!(d2.levels(), levels as usize);
    }

    #[test]
    fn detect_after_shuffle() {
        roundtrip(&generate::icosahedron(), 3, 1, true);
        roundtrip(&generate::tetrahedron(), 3, 2, true);
        roundtrip(&generate::disk(5), 3, 3, true);
        roundtrip(&generate::grid(3, 2, true), 3, 4, true);
        roundtrip(&generate::torus(1.0, 0.4, 5, 4, true), 2, 5, false);
        let two = merged(
            &generate::icosahedron(),
            &generate::grid(2, 2, true),
            DVec3::new(5.0, 0.0, 0.0),
        );
        roundtrip(&two, 3, 6, true);
        // An isolated vertex stays a base vertex.
        let mut iso = generate::disk(4);
        iso.positions.push(DVec3::new(9.0, 9.0, 9.0));
        roundtrip(&iso, 2, 7, true);
    }

    #[test]
    fn detect_errors() {
        // The icosahedron is not a split of anything.
        let e = Hierarchy::detect(&generate::icosahedron(), None).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("coarsening step 1"), "{msg}");
        // Two levels, three asked.
        let h = Hierarchy::new(&generate::icosahedron(), 2, Split::Triangles, None).unwrap();
        let e = Hierarchy::detect(&h.finest_mesh(), Some(3)).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("coarsening step 3") && msg.contains("1-to-4 group"),
            "{msg}"
        );
        // A flipped edge breaks the structure locally.
        let mut m = h.finest_mesh();
        let t = Topology::build(&m);
        let e = (0..t.num_edges())
            .find(|&e| {
                let [a, b] = t.edge_vertices[e];
                a >= 12 && b >= 12 && t.edge_faces(e).len() == 2
            })
            .unwrap();
        let [a, b] = t.edge_vertices[e];
        let [f, g] = [t.edge_faces(e)[0], t.edge_faces(e)[1]];
        let opp = |f: u32| {
            *m.face(f as usize)
                .iter()
                .find(|&&x| x != a && x != b)
                .unwrap()
        };
        let (c, d) = (opp(f), opp(g));
        // Face f is (a, b, c) up to rotation; replace f, g by (c, d, b)/(d, c, a) keeping
        // orientation: f traverses a->b.
        let fv = m.face(f as usize).to_vec();
        let i = fv.iter().position(|&x| x == a).unwrap();
        let (a, b) = if fv[(i + 1) % 3] == b { (a, b) } else { (b, a) };
        let s = m.face_offsets[f as usize] as usize;
        m.face_indices[s..s + 3].copy_from_slice(&[a, d, c]);
        let s = m.face_offsets[g as usize] as usize;
        m.face_indices[s..s + 3].copy_from_slice(&[d, b, c]);
        let e = Hierarchy::detect(&m, Some(1)).unwrap_err();
        assert!(e.to_string().contains("1-to-4 group"), "{e}");
        // The cube is no Catmull-Clark split; mixed meshes are refused.
        let e = Hierarchy::detect(&generate::cube(), None).unwrap_err();
        assert!(e.to_string().contains("coarsening step 1"), "{e}");
        let e = Hierarchy::detect(&generate::pyramid(), None).unwrap_err();
        assert!(e.to_string().contains("triangles"), "{e}");
    }
}

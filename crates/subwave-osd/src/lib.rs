//! Cross-check harness: runs Pixar's OpenSubdiv (3.7, through the `opensubdiv-petite` crate) on
//! a subwave [`Mesh`], so that subwave's own subdivision can be compared against it in tests
//! and benchmarks. Test-only (`publish = false`).
//!
//! # API
//! - [`refine`] / [`refine_timed`]: uniform refinement in OpenSubdiv's own vertex and face order
//!   (what OpenSubdiv users see), with timings of the topology, primvar and stencil phases.
//! - [`refine_ordered`] / [`refine_ordered_levels`]: the same result permuted into subwave's
//!   ordering contract, level by level, so that a test can compare vertex by vertex and face by
//!   face (the mapping is computed from OpenSubdiv's parent/child tables, not by geometry, and is
//!   checked face by face while it is built).
//! - [`max_vertex_set_distance`]: an order-independent comparison (nearest neighbours through a
//!   k-d tree).
//!
//! # Precision
//! `opensubdiv-petite` instantiates OpenSubdiv's `PrimvarRefiner`, `StencilTable` and
//! `Osd::CpuEvaluator` for `float` only, and the subdivision weights themselves are computed in
//! `float` (`Far::PrimvarRefinerReal<float>`), so an `f64` evaluation is not possible through
//! this crate. The harness translates the mesh so that its bounding-box centre is at the origin
//! before converting to `f32` (subdivision is affine invariant) and translates back in `f64`; the
//! remaining error is a few `f32` ulps of the mesh's size per level, so compare with a tolerance
//! of about `1e-5 * mesh.diagonal()`. (Measured against subwave's `f64` refinement: about `1e-7`
//! on unit-size meshes at level 3, `2e-8` on the Stanford bunny, diagonal 0.25, at level 3.)
//!
//! # OpenSubdiv's vertex order in uniform refinement (facts, from `Vtr::Refinement::
//! populateParentChildIndices` and `Far::TopologyRefiner::UniformOptions` in OpenSubdiv 3.7)
//! - `UniformOptions::orderVerticesFromFacesFirst` is `false` by default **in C++**. Then the
//!   child vertices of level `i + 1` are: first the children of the `V` parent *vertices*
//!   (child `v` of parent vertex `v`, same index), then the children of the `F` parent *faces*
//!   (in face order, `V + f`), then the children of the `E` parent *edges* (in OpenSubdiv's edge
//!   order, `V + F + e`). Loop has no face children, so it is `V` then `E`.
//! - With `orderVerticesFromFacesFirst = true` the blocks are faces, edges, vertices. **Beware:**
//!   `opensubdiv_petite::far::UniformRefinementOptions::default()` sets it to `true` (unlike
//!   C++); this harness always sets it to `false` explicitly.
//! - Child **faces** come in parent-face order: face `f`'s children are consecutive, child `j`
//!   being the one at corner `j` of `f` (for triangles, children 0..2 at the corners and 3 in
//!   the middle). Their corner order differs from subwave's: a non-quad's child `j` is
//!   `(v_j, m_j, c, m_{j-1})` like subwave, but a quad's child `j` is rotated so that *its*
//!   corner `j` is `v_j`; the triangle children are `(v0 m0 m2), (m0 v1 m1), (m2 m1 v2),
//!   (m1 m2 m0)` against subwave's `(v0 m0 m2), (v1 m1 m0), (v2 m2 m1), (m0 m1 m2)`.
//! - **Edges** at level 0 (built by `Vtr::Level::completeTopologyFromFaceVertices`) are numbered
//!   by first appearance while scanning faces and their corners in order (edge `c` of a face
//!   joins corners `c` and `c + 1`) -- the same as subwave's contract for a manifold mesh. At
//!   refined levels OpenSubdiv numbers first all child edges interior to parent faces (by parent
//!   face), then the two halves of each parent edge (by parent edge), which is *not*
//!   first-appearance order.
//!
//! So at level 1 (from a manifold level 0) subwave's order is OpenSubdiv's with the face and
//! edge blocks swapped (`V`, `E`, `F` instead of `V`, `F`, `E`); from level 2 on the edge-vertex
//! block is permuted as well. [`refine_ordered_levels`] builds the full permutation: vertex
//! children through `TopologyLevel::vertex_child_vertex`, edge children through the OpenSubdiv
//! edge at the matching corner of the matching face (`face_edges`, `edge_child_vertex`), face
//! children through `face_child_vertex`, and child faces through `face_child_faces` with the
//! corner rotation found and verified per face.
//!
//! # Build requirements
//! `opensubdiv-petite-sys` compiles OpenSubdiv's C++ with CMake and generates bindings with
//! bindgen: Debian packages `cmake` and `libclang-dev` (plus a C++ compiler).

#![warn(missing_docs)]

use std::collections::HashMap;
use std::time::Instant;

use glam::DVec3;
use opensubdiv_petite::far::{self, TopologyLevel};
use opensubdiv_petite::{osd, Index};
use subwave::mesh::Mesh;

/// OpenSubdiv's subdivision schemes (`Sdc::SchemeType`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OsdScheme {
    /// `SCHEME_CATMARK`: any polygons, 1-to-n quad split.
    CatmullClark,
    /// `SCHEME_LOOP`: triangles only, 1-to-4 split.
    Loop,
    /// `SCHEME_BILINEAR`: any polygons, 1-to-n quad split (triangles become 3 quads), face and
    /// edge points at centroids, vertices unmoved.
    Bilinear,
}

/// Boundary interpolation (`Sdc::Options::VtxBoundaryInterpolation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OsdBoundary {
    /// `VTX_BOUNDARY_NONE`: "no boundary interpolation, except where boundary edges were
    /// explicitly sharpened". In fact OpenSubdiv's `TopologyRefinerFactory` makes every boundary
    /// edge infinitely sharp whatever this option; `NONE` only tags the faces around boundary
    /// vertices as holes, which matters for patch tables and limit evaluation but not for
    /// uniform refinement: [`refine`] gives the same faces and positions as with `EdgeOnly`.
    None,
    /// `VTX_BOUNDARY_EDGE_ONLY`: boundary edges are infinitely sharp creases.
    EdgeOnly,
    /// `VTX_BOUNDARY_EDGE_AND_CORNER`: as `EdgeOnly`, and boundary vertices with one incident
    /// face are infinitely sharp corners.
    EdgeAndCorner,
}

/// Creasing method for semi-sharp creases (`Sdc::Options::CreasingMethod`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OsdCreasing {
    /// `CREASE_UNIFORM`: child edges get the parent's sharpness minus one.
    Uniform,
    /// `CREASE_CHAIKIN`: child sharpness blends the sharpness of neighbouring crease edges.
    Chaikin,
}

/// Options of [`refine`] and friends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OsdOptions {
    /// Subdivision scheme.
    pub scheme: OsdScheme,
    /// Boundary interpolation.
    pub boundary: OsdBoundary,
    /// Creasing method.
    pub creasing: OsdCreasing,
    /// Number of uniform refinement levels (0..=10; OpenSubdiv stores it in 4 bits).
    pub levels: u32,
}

impl Default for OsdOptions {
    /// Catmull-Clark, `EdgeOnly` boundaries, uniform creasing, one level.
    fn default() -> Self {
        OsdOptions {
            scheme: OsdScheme::CatmullClark,
            boundary: OsdBoundary::EdgeOnly,
            creasing: OsdCreasing::Uniform,
            levels: 1,
        }
    }
}

/// Largest number of levels accepted by [`refine`] (OpenSubdiv's limit is 15; 10 levels of
/// Catmull-Clark already multiply the face count by a million).
pub const MAX_LEVELS: u32 = 10;

/// Wall-clock timings of the phases of [`refine_timed`], in milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OsdTimings {
    /// `TopologyRefinerFactory::Create` (from a `TopologyDescriptor`) plus `RefineUniform`.
    pub topology_ms: f64,
    /// `PrimvarRefiner` creation plus `Interpolate` of the positions through every level.
    pub positions_ms: f64,
    /// `StencilTableFactory::Create` for the finest level only (factorized, no intermediate
    /// levels), from the already refined topology. `None` when `levels == 0`.
    pub stencil_build_ms: Option<f64>,
    /// Cached re-evaluation: upload of the control points into an `Osd::CpuVertexBuffer` and
    /// `Osd::CpuEvaluator::EvalStencils` (buffers allocated beforehand). `None` when
    /// `levels == 0`.
    pub stencil_eval_ms: Option<f64>,
}

/// The refined hierarchy: the refiner (topology of every level) and positions of every level,
/// relative to `center`.
struct Hierarchy {
    refiner: far::TopologyRefiner,
    /// `positions[l]` holds `3 * V_l` floats.
    positions: Vec<Vec<f32>>,
    center: DVec3,
    timings: OsdTimings,
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn check_input(mesh: &Mesh, opts: &OsdOptions) -> Result<(), String> {
    mesh.check_indices()
        .map_err(|e| format!("invalid mesh: {e}"))?;
    if mesh.num_faces() == 0 || mesh.positions.is_empty() {
        return Err("OpenSubdiv needs at least one face".into());
    }
    if opts.levels > MAX_LEVELS {
        return Err(format!(
            "{} levels requested, at most {MAX_LEVELS} supported",
            opts.levels
        ));
    }
    if let Some(f) = (0..mesh.num_faces()).find(|&f| mesh.face_arity(f) < 3) {
        return Err(format!(
            "face {f} has {} vertices; OpenSubdiv needs at least 3",
            mesh.face_arity(f)
        ));
    }
    if opts.scheme == OsdScheme::Loop {
        if let Some(f) = (0..mesh.num_faces()).find(|&f| mesh.face_arity(f) != 3) {
            return Err(format!(
                "Loop needs triangles, face {f} has {} vertices",
                mesh.face_arity(f)
            ));
        }
    }
    let nv = mesh.positions.len();
    if let Some(t) = mesh
        .edge_tags
        .iter()
        .find(|t| t.vertices.iter().any(|&v| v as usize >= nv))
    {
        return Err(format!(
            "crease tag {:?} names a vertex out of range",
            t.vertices
        ));
    }
    if let Some(t) = mesh.vertex_tags.iter().find(|t| t.vertex as usize >= nv) {
        return Err(format!("corner tag names vertex {} out of range", t.vertex));
    }
    if i32::try_from(mesh.face_indices.len()).is_err() {
        return Err("mesh too large for OpenSubdiv's i32 indices".into());
    }
    Ok(())
}

/// Refines `mesh` and interpolates positions through all levels; with `stencils`, also builds
/// and evaluates a stencil table and checks that it agrees with the primvar result.
fn build(mesh: &Mesh, opts: &OsdOptions, stencils: bool) -> Result<Hierarchy, String> {
    check_input(mesh, opts)?;
    let levels = opts.levels as usize;
    let center = mesh
        .bounding_box()
        .map_or(DVec3::ZERO, |(lo, hi)| 0.5 * (lo + hi));
    let coarse: Vec<f32> = mesh
        .positions
        .iter()
        .flat_map(|p| (*p - center).as_vec3().to_array())
        .collect();
    let arities: Vec<u32> = mesh.face_offsets.windows(2).map(|w| w[1] - w[0]).collect();
    let crease_pairs: Vec<u32> = mesh.edge_tags.iter().flat_map(|t| t.vertices).collect();
    let crease_sharpness: Vec<f32> = mesh.edge_tags.iter().map(|t| t.sharpness as f32).collect();
    let corner_vertices: Vec<u32> = mesh.vertex_tags.iter().map(|t| t.vertex).collect();
    let corner_sharpness: Vec<f32> = mesh
        .vertex_tags
        .iter()
        .map(|t| t.sharpness as f32)
        .collect();

    let t = Instant::now();
    let mut descriptor =
        far::TopologyDescriptor::new(mesh.positions.len(), &arities, &mesh.face_indices)
            .map_err(|e| format!("TopologyDescriptor: {e}"))?;
    if !crease_pairs.is_empty() {
        descriptor.creases(&crease_pairs, &crease_sharpness);
    }
    if !corner_vertices.is_empty() {
        descriptor.corners(&corner_vertices, &corner_sharpness);
    }
    let refiner_options = far::TopologyRefinerOptions {
        scheme: match opts.scheme {
            OsdScheme::CatmullClark => far::Scheme::CatmullClark,
            OsdScheme::Loop => far::Scheme::Loop,
            OsdScheme::Bilinear => far::Scheme::Bilinear,
        },
        boundary_interpolation: match opts.boundary {
            OsdBoundary::None => None,
            OsdBoundary::EdgeOnly => Some(far::BoundaryInterpolation::EdgeOnly),
            OsdBoundary::EdgeAndCorner => Some(far::BoundaryInterpolation::EdgeAndCorner),
        },
        creasing_method: match opts.creasing {
            OsdCreasing::Uniform => far::CreasingMethod::Uniform,
            OsdCreasing::Chaikin => far::CreasingMethod::Chaikin,
        },
        ..Default::default()
    };
    let mut refiner = far::TopologyRefiner::new(descriptor, refiner_options)
        .map_err(|e| format!("TopologyRefiner: {e}"))?;
    if levels > 0 {
        refiner.refine_uniform(far::UniformRefinementOptions {
            refinement_level: levels,
            order_vertices_from_faces_first: false,
            full_topology_in_last_level: false,
        });
    }
    let mut timings = OsdTimings {
        topology_ms: ms_since(t),
        ..Default::default()
    };
    if refiner.max_level() != levels {
        return Err(format!(
            "OpenSubdiv refined to level {} instead of {levels}",
            refiner.max_level()
        ));
    }

    let t = Instant::now();
    let mut positions = vec![coarse];
    if levels > 0 {
        let primvar =
            far::PrimvarRefiner::new(&refiner).map_err(|e| format!("PrimvarRefiner: {e}"))?;
        for level in 1..=levels {
            let next = primvar
                .interpolate(level, 3, &positions[level - 1])
                .ok_or_else(|| format!("PrimvarRefiner::interpolate failed at level {level}"))?;
            positions.push(next);
        }
    }
    timings.positions_ms = ms_since(t);

    if stencils && levels > 0 {
        let t = Instant::now();
        let table = far::StencilTable::new(
            &refiner,
            far::StencilTableOptions {
                generate_offsets: true,
                generate_intermediate_levels: false,
                max_level: levels,
                ..Default::default()
            },
        )
        .map_err(|e| format!("StencilTable: {e}"))?;
        timings.stencil_build_ms = Some(ms_since(t));

        let n_coarse = mesh.positions.len();
        let n_fine = table.len();
        let mut src = osd::CpuVertexBuffer::new(3, n_coarse).map_err(|e| e.to_string())?;
        let mut dst = osd::CpuVertexBuffer::new(3, n_fine).map_err(|e| e.to_string())?;
        let desc = osd::BufferDescriptor::new(0, 3, 3).map_err(|e| e.to_string())?;
        let t = Instant::now();
        src.update_data(&positions[0], 0, n_coarse)
            .map_err(|e| e.to_string())?;
        osd::cpu_evaluator::evaluate_stencils(&src, desc, &mut dst, desc, &table)
            .map_err(|e| e.to_string())?;
        timings.stencil_eval_ms = Some(ms_since(t));

        let evaluated = dst.bind_cpu_buffer().map_err(|e| e.to_string())?;
        let finest = &positions[levels];
        if evaluated.len() != finest.len() {
            return Err(format!(
                "stencil table has {n_fine} stencils, the finest level {} vertices",
                finest.len() / 3
            ));
        }
        let scale = mesh.diagonal().max(f64::MIN_POSITIVE);
        let worst = evaluated
            .iter()
            .zip(finest)
            .map(|(a, b)| f64::from((a - b).abs()))
            .fold(0.0, f64::max);
        if worst > 1e-4 * scale {
            return Err(format!(
                "stencil evaluation differs from primvar refinement by {worst}"
            ));
        }
    }
    Ok(Hierarchy {
        refiner,
        positions,
        center,
        timings,
    })
}

fn level(refiner: &far::TopologyRefiner, l: usize) -> Result<TopologyLevel<'_>, String> {
    refiner
        .level(l)
        .ok_or_else(|| format!("OpenSubdiv has no level {l}"))
}

fn to_positions(flat: &[f32], center: DVec3) -> Vec<DVec3> {
    flat.chunks_exact(3)
        .map(|p| center + DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
        .collect()
}

/// The finest level in OpenSubdiv's own order.
fn finest_mesh(h: &Hierarchy) -> Result<Mesh, String> {
    let last = h.positions.len() - 1;
    let lvl = level(&h.refiner, last)?;
    let mut m = Mesh::new();
    m.positions = to_positions(&h.positions[last], h.center);
    m.face_indices.reserve(lvl.face_vertex_count());
    m.face_offsets.reserve(lvl.face_count());
    for f in 0..lvl.face_count() {
        let fv = lvl
            .face_vertices(Index::from(f))
            .ok_or_else(|| format!("OpenSubdiv face {f} at level {last} has no vertices"))?;
        m.push_face(index_slice_as_u32(fv));
    }
    Ok(m)
}

fn index_slice_as_u32(ix: &[Index]) -> &[u32] {
    // SAFETY: `Index` is `#[repr(transparent)]` over `u32`.
    unsafe { std::slice::from_raw_parts(ix.as_ptr().cast::<u32>(), ix.len()) }
}

/// Uniformly refines `mesh` `opts.levels` times with OpenSubdiv, its crease tags
/// ([`Mesh::edge_tags`]) and corner tags ([`Mesh::vertex_tags`]) passed as OpenSubdiv sharpness,
/// and returns the finest level in **OpenSubdiv's** vertex and face order (see the crate docs).
///
/// Positions are OpenSubdiv's `f32` results converted to `f64` (see "Precision" in the crate
/// docs). The result carries no tags or attributes. `levels == 0` returns the input geometry
/// after the `f32` round trip.
///
/// # Errors
/// A message if the mesh violates [`Mesh::check_indices`], has no face, has a face with fewer
/// than 3 vertices, is not all triangles for Loop, has out-of-range tags, if `levels >
/// MAX_LEVELS`, or if OpenSubdiv fails.
pub fn refine(mesh: &Mesh, opts: &OsdOptions) -> Result<Mesh, String> {
    finest_mesh(&build(mesh, opts, false)?)
}

/// [`refine`] with timings of its phases; also builds the finest level's stencil table and
/// re-evaluates the positions with it (checking that both agree).
///
/// # Errors
/// As [`refine`], or if the stencil evaluation disagrees with the primvar refinement.
pub fn refine_timed(mesh: &Mesh, opts: &OsdOptions) -> Result<(Mesh, OsdTimings), String> {
    let h = build(mesh, opts, true)?;
    Ok((finest_mesh(&h)?, h.timings))
}

/// One level of [`refine_ordered_levels`].
#[derive(Clone, Debug)]
pub struct OrderedLevel {
    /// The level's vertices and faces in subwave's ordering contract.
    pub mesh: Mesh,
    /// For each subwave vertex index of this level, OpenSubdiv's vertex index at the same level.
    pub subwave_to_osd: Vec<u32>,
}

/// Subwave's edges of a face list: for each corner, the index of the edge from it to the next
/// corner, numbered by first appearance; returns `(face_edges, edge_count)`.
fn first_appearance_edges(offsets: &[u32], indices: &[u32]) -> (Vec<u32>, usize) {
    let mut ids: HashMap<(u32, u32), u32> = HashMap::with_capacity(indices.len() / 2 + 1);
    let mut face_edges = Vec::with_capacity(indices.len());
    for w in offsets.windows(2) {
        let f = &indices[w[0] as usize..w[1] as usize];
        for (c, &a) in f.iter().enumerate() {
            let b = f[(c + 1) % f.len()];
            let key = (a.min(b), a.max(b));
            let next = ids.len() as u32;
            face_edges.push(*ids.entry(key).or_insert(next));
        }
    }
    (face_edges, ids.len())
}

/// Uniformly refines `mesh` with OpenSubdiv and returns **every** level `0..=opts.levels`
/// permuted into subwave's ordering contract (`subwave::subdivision::refine`):
/// - vertices: level `i`'s vertices keep their indices, then one vertex per edge in edge order
///   (first appearance scanning faces and corners, edge `c` joining corners `c` and `c + 1`),
///   then, for the quad schemes (Catmull-Clark, bilinear), one per face in face order;
/// - faces: triangle `k = (v0 v1 v2)` with edge points `m0 m1 m2` has children `4k..4k+3` =
///   `(v0 m0 m2), (v1 m1 m0), (v2 m2 m1), (m0 m1 m2)`; a face with corners `v_i`, edge points
///   `m_i` and face point `c` has children `(v_i, m_i, c, m_{i-1})`, consecutive.
///
/// The permutation comes from OpenSubdiv's parent/child tables, and each child face is checked to
/// be a rotation of the OpenSubdiv face it maps to, so a successful result is exact (no
/// geometric matching). Compare positions with a tolerance (see "Precision" in the crate docs).
///
/// # Errors
/// As [`refine`]; also if the mesh's edges are non-manifold or inconsistently oriented in a way
/// that breaks the correspondence (a message names the level and face).
pub fn refine_ordered_levels(mesh: &Mesh, opts: &OsdOptions) -> Result<Vec<OrderedLevel>, String> {
    let h = build(mesh, opts, false)?;
    let quads = opts.scheme != OsdScheme::Loop;
    // Level 0: OpenSubdiv keeps the input order.
    let mut offsets = mesh.face_offsets.clone();
    let mut indices = mesh.face_indices.clone();
    let mut to_osd: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    // For each subwave face: (OpenSubdiv face, r) with subwave corner i at OpenSubdiv corner
    // (i + r) % n.
    let mut face_map: Vec<(u32, u32)> = (0..mesh.num_faces() as u32).map(|f| (f, 0)).collect();
    let mut out = Vec::with_capacity(h.positions.len());
    for l in 0..h.positions.len() {
        let osd_pos = &h.positions[l];
        let positions = to_osd
            .iter()
            .map(|&o| {
                let p = &osd_pos[3 * o as usize..3 * o as usize + 3];
                h.center + DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
            })
            .collect();
        if l + 1 == h.positions.len() {
            out.push(OrderedLevel {
                mesh: Mesh {
                    positions,
                    face_offsets: offsets,
                    face_indices: indices,
                    ..Mesh::new()
                },
                subwave_to_osd: to_osd,
            });
            break;
        }
        let parent = level(&h.refiner, l)?;
        let child = level(&h.refiner, l + 1)?;
        let nv = to_osd.len();
        let nf = offsets.len() - 1;
        let (face_edges, ne) = first_appearance_edges(&offsets, &indices);
        let nchild = nv + ne + if quads { nf } else { 0 };
        if nchild != child.vertex_count() {
            return Err(format!(
                "level {}: subwave's contract gives {nchild} vertices, OpenSubdiv has {}",
                l + 1,
                child.vertex_count()
            ));
        }
        let mut next_to_osd = vec![u32::MAX; nchild];
        for (v, &o) in to_osd.iter().enumerate() {
            next_to_osd[v] = parent.vertex_child_vertex(Index(o)).0;
        }
        let mut next_offsets = Vec::with_capacity(if quads { indices.len() } else { 4 * nf } + 1);
        next_offsets.push(0u32);
        let mut next_indices = Vec::with_capacity(4 * if quads { indices.len() } else { 3 * nf });
        let mut next_face_map = Vec::with_capacity(next_offsets.capacity());
        for f in 0..nf {
            let (a, b) = (offsets[f] as usize, offsets[f + 1] as usize);
            let fv = &indices[a..b];
            let fe = &face_edges[a..b];
            let n = fv.len();
            let (of, r) = face_map[f];
            let osd_fv = parent.face_vertices(Index(of)).unwrap_or(&[]);
            let osd_fe = parent.face_edges(Index(of)).unwrap_or(&[]);
            let osd_children = parent.face_child_faces(Index(of)).unwrap_or(&[]);
            let expected_children = if quads { n } else { 4 };
            if osd_fv.len() != n || osd_fe.len() != n || osd_children.len() != expected_children {
                return Err(format!(
                    "level {l}: face {f} does not match OpenSubdiv face {of}"
                ));
            }
            let osd_corner = |i: usize| (i + r as usize) % n;
            // Edge points.
            for i in 0..n {
                let e = nv + fe[i] as usize;
                let oe = osd_fe[osd_corner(i)];
                let ends = parent.edge_vertices(oe).unwrap_or(&[]);
                let (pa, pb) = (to_osd[fv[i] as usize], to_osd[fv[(i + 1) % n] as usize]);
                if !(ends.len() == 2
                    && ((ends[0].0 == pa && ends[1].0 == pb)
                        || (ends[0].0 == pb && ends[1].0 == pa)))
                {
                    return Err(format!(
                        "level {l}: edge {i} of face {f} does not match OpenSubdiv edge {}",
                        oe.0
                    ));
                }
                let c = parent.edge_child_vertex(oe).0;
                if next_to_osd[e] != u32::MAX && next_to_osd[e] != c {
                    return Err(format!(
                        "level {l}: edge {} has two OpenSubdiv children",
                        fe[i]
                    ));
                }
                next_to_osd[e] = c;
            }
            let m = |i: usize| (nv + fe[i % n] as usize) as u32;
            if quads {
                let cpt = (nv + ne + f) as u32;
                next_to_osd[cpt as usize] = parent.face_child_vertex(Index(of)).0;
                for i in 0..n {
                    next_indices.extend_from_slice(&[fv[i], m(i), cpt, m(i + n - 1)]);
                    next_offsets.push(next_indices.len() as u32);
                    next_face_map.push(osd_children[osd_corner(i)].0);
                }
            } else {
                let children = [
                    [fv[0], m(0), m(2)],
                    [fv[1], m(1), m(0)],
                    [fv[2], m(2), m(1)],
                    [m(0), m(1), m(2)],
                ];
                for (i, tri) in children.iter().enumerate() {
                    next_indices.extend_from_slice(tri);
                    next_offsets.push(next_indices.len() as u32);
                    next_face_map.push(osd_children[if i < 3 { osd_corner(i) } else { 3 }].0);
                }
            }
        }
        // Every child vertex found, once.
        let mut seen = vec![false; nchild];
        for (s, &o) in next_to_osd.iter().enumerate() {
            if o as usize >= nchild || std::mem::replace(&mut seen[o as usize], true) {
                return Err(format!(
                    "level {}: vertex {s} has no unique OpenSubdiv counterpart",
                    l + 1
                ));
            }
        }
        // Child faces: find and verify each one's rotation against OpenSubdiv's.
        let mut rotated = Vec::with_capacity(next_face_map.len());
        for (k, &of) in next_face_map.iter().enumerate() {
            let sub = &next_indices[next_offsets[k] as usize..next_offsets[k + 1] as usize];
            let osd_fv = child.face_vertices(Index(of)).unwrap_or(&[]);
            let n = sub.len();
            let first = next_to_osd[sub[0] as usize];
            let r = osd_fv.iter().position(|o| o.0 == first);
            let ok = osd_fv.len() == n
                && r.is_some_and(|r| {
                    (0..n).all(|i| osd_fv[(i + r) % n].0 == next_to_osd[sub[i] as usize])
                });
            match (ok, r) {
                (true, Some(r)) => rotated.push((of, r as u32)),
                _ => {
                    return Err(format!(
                    "level {}: child face {k} {sub:?} is not a rotation of OpenSubdiv face {of}",
                    l + 1
                ))
                }
            }
        }
        out.push(OrderedLevel {
            mesh: Mesh {
                positions,
                face_offsets: std::mem::replace(&mut offsets, next_offsets),
                face_indices: std::mem::replace(&mut indices, next_indices),
                ..Mesh::new()
            },
            subwave_to_osd: std::mem::replace(&mut to_osd, next_to_osd),
        });
        face_map = rotated;
    }
    Ok(out)
}

/// The finest level of [`refine_ordered_levels`]: OpenSubdiv's result with vertices and faces
/// in subwave's ordering contract, comparable to subwave's own refinement vertex by vertex.
///
/// # Errors
/// As [`refine_ordered_levels`].
pub fn refine_ordered(mesh: &Mesh, opts: &OsdOptions) -> Result<Mesh, String> {
    let mut levels = refine_ordered_levels(mesh, opts)?;
    Ok(levels.pop().expect("at least level 0").mesh)
}

/// Largest distance between the vertices of `a` and `b` at the same index (`f64::INFINITY` if
/// the vertex counts differ). For results of [`refine_ordered`].
pub fn max_vertex_distance(a: &Mesh, b: &Mesh) -> f64 {
    if a.positions.len() != b.positions.len() {
        return f64::INFINITY;
    }
    a.positions
        .iter()
        .zip(&b.positions)
        .map(|(p, q)| p.distance(*q))
        .fold(0.0, f64::max)
}

/// A static 3-d tree over points: a balanced implicit tree (median at the middle of each range).
struct KdTree {
    points: Vec<DVec3>,
}

impl KdTree {
    fn new(mut points: Vec<DVec3>) -> Self {
        fn build(p: &mut [DVec3], depth: usize) {
            if p.len() <= 1 {
                return;
            }
            let axis = depth % 3;
            let mid = p.len() / 2;
            p.select_nth_unstable_by(mid, |a, b| a[axis].total_cmp(&b[axis]));
            let (lo, hi) = p.split_at_mut(mid);
            build(lo, depth + 1);
            build(&mut hi[1..], depth + 1);
        }
        build(&mut points, 0);
        KdTree { points }
    }

    /// Squared distance from `q` to the nearest point (infinite for an empty tree).
    fn nearest_sq(&self, q: DVec3) -> f64 {
        fn go(p: &[DVec3], depth: usize, q: DVec3, best: &mut f64) {
            if p.is_empty() {
                return;
            }
            let mid = p.len() / 2;
            let d2 = p[mid].distance_squared(q);
            if d2 < *best {
                *best = d2;
            }
            let axis = depth % 3;
            let diff = q[axis] - p[mid][axis];
            let (near, far) = if diff < 0.0 {
                (&p[..mid], &p[mid + 1..])
            } else {
                (&p[mid + 1..], &p[..mid])
            };
            go(near, depth + 1, q, best);
            if diff * diff < *best {
                go(far, depth + 1, q, best);
            }
        }
        let mut best = f64::INFINITY;
        go(&self.points, 0, q, &mut best);
        best
    }
}

fn directed_distance(from: &[DVec3], to: &KdTree) -> f64 {
    from.iter()
        .map(|&q| to.nearest_sq(q))
        .fold(0.0, f64::max)
        .sqrt()
}

/// Order-independent comparison: the symmetric Hausdorff distance between the vertex sets of `a`
/// and `b` (for every vertex of either mesh, the distance to the nearest vertex of the other;
/// the maximum), found with a k-d tree in `O(n log n)`.
///
/// Returns `f64::INFINITY` if the face counts or the vertex counts differ (different
/// topologies), 0 for two empty meshes. Use it to compare subwave's result with [`refine`]'s.
pub fn max_vertex_set_distance(a: &Mesh, b: &Mesh) -> f64 {
    if a.num_faces() != b.num_faces() || a.positions.len() != b.positions.len() {
        return f64::INFINITY;
    }
    if a.positions.is_empty() {
        return 0.0;
    }
    let ta = KdTree::new(a.positions.clone());
    let tb = KdTree::new(b.positions.clone());
    directed_distance(&a.positions, &tb).max(directed_distance(&b.positions, &ta))
}

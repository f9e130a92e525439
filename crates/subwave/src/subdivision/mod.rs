//! Plain subdivision surfaces: scheme rules, a generic refiner and stencil tables.
//!
//! The layers follow OpenSubdiv:
//! - **rules** ([`rules`], one file per scheme: [`loop_scheme`], [`catmull_clark`],
//!   [`butterfly`], [`midpoint`], [`quad_tri`]; [`sqrt3`] has its own 1-to-3 split, flips and
//!   stencils): pure masks from a local neighbourhood (valence, sharpness, tags, sector);
//! - **refinement** ([`refine`]): each child level's flat tables built directly from the
//!   parent's, following the ordering contract documented there;
//! - **stencils** ([`stencil`]): each level's child vertices as weighted sums of parent
//!   vertices; refinement evaluates them (directly, or through tables that [`Refinement`]
//!   keeps for cached re-evaluation of moving control points, Maret §5.1.1, bit-identically).
//!
//! Tags follow Maret §3.5: edge sharpness from the mesh's crease tags (and `--sharp-angle`),
//! boundary edges infinitely sharp, vertex rules smooth / dart / crease / corner from the
//! number of sharp incident edges or a corner tag.

pub mod butterfly;
pub mod catmull_clark;
pub mod curves;
pub mod face_varying;

pub mod limit;
pub mod loop_scheme;
pub mod midpoint;
pub mod profile;
pub mod quad_tri;
pub mod refine;
pub mod rules;
pub mod sqrt3;
pub mod stencil;

use glam::DVec3;

use crate::mesh::{EdgeTag, Mesh, VertexTag, SHARPNESS_INFINITE};
use crate::topology::Topology;
use crate::validate::{require_arity, require_manifold};
use crate::{Error, Result};
use butterfly::{ButterflyRules, ButterflyVariant};
use catmull_clark::CatmullClarkRules;
use loop_scheme::{LoopBoundary, LoopRules, LoopWeights};
use midpoint::MidpointRules;
use refine::Split;
use rules::{child_edge_sharpness, decrement, Creasing, Rules};
use stencil::{level_apply, level_stencils, Interpolate, LevelContext, StencilTable};

/// The subdivision schemes implemented so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheme {
    /// Loop (triangles), piecewise smooth.
    Loop,
    /// Midpoint: linear 1-to-4 on triangle meshes, bilinear on polygon meshes.
    Midpoint,
    /// Catmull-Clark (any polygons), sharp and semi-sharp creases.
    CatmullClark,
    /// Bilinear (any polygons, 1-to-n quads, face points at centroids).
    Bilinear,
    /// Modified butterfly (triangles), interpolating, with crease tags.
    Butterfly,
    /// The original 8-point butterfly everywhere (triangles; MeshLab's butterfly).
    ButterflyOriginal,

    /// Kobbelt's √3 (triangles): 1-to-3 split, relaxation, edge flips; boundaries trisected
    /// every second step ([`sqrt3`]).
    Sqrt3,

    /// Quad/triangle subdivision of Stam & Loop 2003 (triangles and quads; Loop on triangle
    /// regions, Catmull-Clark on quad regions), sharp and semi-sharp creases.
    QuadTri,

    /// Generalized bicubic B-splines (MLCA): Bertram et al.'s cubic wavelet synthesis with
    /// zero details ([`crate::wavelet::bertram`]); Catmull-Clark at regular vertices.
    Bicubic,
    /// Generalized biquintic B-splines: Bertram et al.'s quintic wavelet synthesis with zero
    /// details ([`crate::wavelet::bertram`]).
    Biquintic,
}

impl Scheme {
    /// The scheme's command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Scheme::Loop => "loop",
            Scheme::Midpoint => "midpoint",
            Scheme::CatmullClark => "catmull-clark",
            Scheme::Bilinear => "bilinear",
            Scheme::Butterfly => "butterfly",
            Scheme::ButterflyOriginal => "butterfly-original",

            Scheme::Sqrt3 => "sqrt3",

            Scheme::QuadTri => "quad-tri",

            Scheme::Bicubic => "bicubic",
            Scheme::Biquintic => "biquintic",
        }
    }

    /// The B-spline degree of the schemes computed by wavelet synthesis
    /// ([`crate::wavelet::bertram`]), `None` for stencil-based schemes.
    pub fn bspline_degree(self) -> Option<crate::wavelet::bertram::Degree> {
        use crate::wavelet::bertram::Degree;
        match self {
            Scheme::Bicubic => Some(Degree::Cubic),
            Scheme::Biquintic => Some(Degree::Quintic),
            _ => None,
        }
    }
}

/// How boundary edges and vertices are treated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BoundaryMode {
    /// Boundary edges are creases (Maret §3.5), with Biermann et al.'s modified Loop edge rules
    /// next to creases.
    #[default]
    Crease,
    /// OpenSubdiv's `VTX_BOUNDARY_EDGE_ONLY`: boundary edges infinitely sharp, OpenSubdiv's
    /// unmodified rules elsewhere.
    OpenSubdiv,
    /// OpenSubdiv's `VTX_BOUNDARY_EDGE_AND_CORNER`: as `OpenSubdiv`, and boundary vertices with
    /// a single face are corners.
    OpenSubdivCorners,
    /// OpenSubdiv's `VTX_BOUNDARY_NONE`: no boundary interpolation. For the smooth schemes
    /// (Loop, Catmull-Clark), every face incident to a boundary vertex whose boundary edges are
    /// not explicitly tagged infinitely sharp is a hole: it still supports its interior
    /// neighbours (refinement is that of `OpenSubdiv`) but produces no surface, so the result
    /// shrinks by a ring of faces at each such boundary. [`subdivide`] drops the holes'
    /// descendants and the vertices only they use; [`Refinement::base_holes`] lists them. For
    /// the linear schemes it equals `OpenSubdiv`, as in OpenSubdiv.
    None,
}

/// Options of [`subdivide`] and [`Refinement::build`].
#[derive(Clone, Copy, Debug)]
pub struct SubdivideOptions {
    /// The scheme.
    pub scheme: Scheme,
    /// Number of refinement levels (0 returns the input).
    pub levels: u32,
    /// Boundary treatment.
    pub boundary: BoundaryMode,
    /// How semi-sharp creases relax.
    pub creasing: Creasing,
    /// β of Loop's smooth vertex rule.
    pub loop_weights: LoopWeights,
    /// Edges whose dihedral angle exceeds this many degrees become infinitely sharp creases.
    pub sharp_angle: Option<f64>,
}

impl Default for SubdivideOptions {
    fn default() -> Self {
        SubdivideOptions {
            scheme: Scheme::Loop,
            levels: 1,
            boundary: BoundaryMode::Crease,
            creasing: Creasing::Uniform,
            loop_weights: LoopWeights::Loop,
            sharp_angle: None,
        }
    }
}

/// Largest number of child faces [`Refinement::build`] accepts (2^31): more would overflow
/// `u32` indices.
pub const MAX_FACES: u64 = 1 << 31;

fn rules_for(opts: &SubdivideOptions, mesh: &Mesh) -> Box<dyn Rules> {
    match opts.scheme {
        Scheme::Loop => Box::new(LoopRules {
            weights: opts.loop_weights,
            boundary: if opts.boundary == BoundaryMode::Crease {
                LoopBoundary::Biermann
            } else {
                LoopBoundary::OpenSubdiv
            },
        }),
        Scheme::Midpoint => Box::new(MidpointRules {
            split: if mesh.is_triangle_mesh() {
                Split::Triangles
            } else {
                Split::Polygons
            },
        }),
        // The B-spline schemes refine like bilinear; their positions come from the wavelet
        // synthesis (`Refinement::build_with`).
        Scheme::Bilinear | Scheme::Bicubic | Scheme::Biquintic => Box::new(MidpointRules {
            split: Split::Polygons,
        }),
        Scheme::CatmullClark => Box::new(CatmullClarkRules),
        Scheme::Butterfly => Box::new(ButterflyRules::default()),
        Scheme::ButterflyOriginal => Box::new(ButterflyRules {
            variant: ButterflyVariant::Original,
        }),

        // √3 has its own split and stencils: `Refinement::build_with` hands it to `sqrt3`.
        Scheme::Sqrt3 => unreachable!("sqrt3 is refined by subdivision::sqrt3"),

        Scheme::QuadTri => Box::new(quad_tri::QuadTriRules {
            weights: opts.loop_weights,
        }),
    }
}

/// Edges of `topo` whose dihedral angle (between face normals) exceeds `degrees`.
pub fn sharp_edges_by_angle(mesh: &Mesh, topo: &Topology, degrees: f64) -> Vec<u32> {
    let normal = |f: usize| {
        let fv = topo.face_vertices(f);
        let mut n = DVec3::ZERO;
        for i in 0..fv.len() {
            n += mesh.positions[fv[i] as usize]
                .cross(mesh.positions[fv[(i + 1) % fv.len()] as usize]);
        }
        n.normalize_or_zero()
    };
    let cos_limit = degrees.to_radians().cos();
    (0..topo.num_edges() as u32)
        .filter(|&e| {
            let f = topo.edge_faces(e as usize);
            f.len() == 2 && normal(f[0] as usize).dot(normal(f[1] as usize)) < cos_limit
        })
        .collect()
}

/// A refinement hierarchy: the topology of every level but the last, the faces of the last,
/// and, if kept, one stencil table per level for cached re-evaluation.
#[derive(Clone, Debug)]
pub struct Refinement {
    /// Topology of levels `0..levels` (the last level's topology is not built).
    pub topologies: Vec<Topology>,
    /// Face offsets of the finest level.
    pub face_offsets: Vec<u32>,
    /// Face vertices of the finest level.
    pub face_vertices: Vec<u32>,
    /// One table per level (`stencils[i]` maps level `i` to level `i + 1`); empty if not kept.
    pub stencils: Vec<StencilTable>,
    /// Positions of the finest level.
    pub positions: Vec<DVec3>,
    /// Crease tags of the finest level (sharp interior edges; boundaries are implicit).
    pub edge_tags: Vec<EdgeTag>,
    /// Corner tags of the finest level.
    pub vertex_tags: Vec<VertexTag>,
    /// Base faces that are holes ([`BoundaryMode::None`]), increasing; empty otherwise.
    pub base_holes: Vec<u32>,
    /// Number of levels refined.
    pub levels: u32,
    /// How faces were split at each level; `None` for √3 ([`sqrt3`]: children `3f..3f+2`
    /// of face `f`, so `3^L` consecutive descendants per base face).
    pub split: Option<Split>,
}

impl Refinement {
    /// Refines `mesh` `opts.levels` times, keeping the stencil tables if `keep_stencils`.
    ///
    /// # Errors
    /// - [`Error::Mesh`] if the mesh violates [`Mesh::check_indices`], is not a consistently
    ///   oriented manifold (the error lists the edges or vertices), or has faces the scheme
    ///   cannot take (Loop on quads, quad-tri on other polygons: the error names them and
    ///   suggests Catmull-Clark);
    /// - [`Error::InvalidArgument`] if the result would exceed [`MAX_FACES`] faces.
    pub fn build(mesh: &Mesh, opts: &SubdivideOptions, keep_stencils: bool) -> Result<Refinement> {
        Self::build_with(mesh, opts, keep_stencils, true)
    }

    /// [`Refinement::build`], dropping each level's topology once refined unless
    /// `keep_topologies` ([`Refinement::topologies`] is then empty). Without stencils, child
    /// values are computed directly ([`stencil::level_apply`]), bit-identical to applying the
    /// tables.
    fn build_with(
        mesh: &Mesh,
        opts: &SubdivideOptions,
        keep_stencils: bool,
        keep_topologies: bool,
    ) -> Result<Refinement> {
        if opts.scheme == Scheme::Sqrt3 {
            mesh.check_indices()?;
            return sqrt3::build(mesh, opts, keep_stencils, keep_topologies);
        }
        if let Some(degree) = opts.scheme.bspline_degree() {
            mesh.check_indices()?;
            return bspline_refinement(mesh, opts, degree, keep_stencils, keep_topologies);
        }
        let Prepared {
            rules,
            split,
            mut topo,
            base_holes,
        } = prepare(mesh, opts)?;
        let mut positions = mesh.positions.clone();
        let mut topologies = Vec::with_capacity(opts.levels as usize);
        let mut stencils = Vec::new();
        let (mut face_offsets, mut face_vertices) = (Vec::new(), Vec::new());
        let (mut edge_tags, mut vertex_tags) = (mesh.edge_tags.clone(), mesh.vertex_tags.clone());
        if opts.levels == 0 {
            (face_offsets, face_vertices) = (topo.face_offsets.clone(), topo.face_vertices.clone());
        }
        // Whether the finest level can have tags at all (see `finest_tags`).
        let tagged = has_interior_tags(&topo);
        // The current level's `stencil::vertex_features`, once derived with it.
        let mut features: Option<Vec<u8>> = None;
        /// What a level hands to the next: its child topology with its features (and, for a
        /// child without vertex relations, the halves of the parent's edges), or the finest
        /// level's faces.
        enum Next {
            Child(Box<Topology>, Vec<u8>, Option<Vec<[u32; 2]>>),
            Finest((Vec<u32>, Vec<u32>), (Vec<EdgeTag>, Vec<VertexTag>)),
        }
        // The last level evaluated (the parent of the finest) is built without vertex
        // relations where its vertices' rings can be read from the level before it instead
        // (`stencil::level_apply_from_coarser`): Catmull-Clark-like polygon splits of 3 or more
        // levels whose tables are not kept (their stencil tables and topologies are public)
        // and whose input has no interior tags (`finest_tags` reads that level's vertex
        // edges). That level's vertex-face and vertex-edge tables are the largest of a
        // refinement's, and their counting sort its longest serial pass: the bunny's third
        // Catmull-Clark level, 85-88 → 81-83 ms in alternated runs (level 1 → 2 34 → 26 ms;
        // level 2 → 3 34 → 37-39 ms, its vertex points' reads being less local), peak memory
        // 437 → 405 MB.
        let lite = split == Split::Polygons
            && !keep_stencils
            && !keep_topologies
            && !tagged
            && !rules.needs_rings()
            && stencil::has_coarser_recipes(rules.as_ref());
        // The level before a level without vertex relations, and the halves of its edges.
        let mut coarser: Option<(Topology, Vec<[u32; 2]>)> = None;
        // Points of the level after a level without vertex relations computed with that
        // level's values (its face points and their face points' vertex points,
        // `stencil::grandchild_points`).
        let mut early = None;
        for level in 0..opts.levels {
            // Whether this level's child is built without vertex relations.
            let lite_child = level + 2 == opts.levels && lite && !topo.rings_ordered;
            let pending = early.take();
            let ctx = LevelContext {
                rules: rules.as_ref(),
                creasing: opts.creasing,
                positions: &positions,
                features: features.as_deref(),
            };
            let values = || {
                if keep_stencils {
                    let table = level_stencils(&topo, &ctx);
                    (table.apply(&positions), Some(table), None)
                } else if let Some((c, halves)) = &coarser {
                    let c = stencil::Coarser { topo: c, halves };
                    let v = stencil::level_apply_from_coarser(&topo, &ctx, &positions, c, pending);
                    (v, None, None)
                } else {
                    let v = level_apply(&topo, &ctx, &positions);
                    // The next level's face points (and the vertex points of this level's
                    // face points) need only this level's tables: computed here, they leave
                    // the next level less to do while this one waits for its child's topology
                    // (the longer of the two).
                    let next = if lite_child {
                        stencil::grandchild_points(&topo, rules.as_ref(), &v)
                    } else {
                        None
                    };
                    (v, None, next)
                }
            };
            let child = || {
                if lite_child {
                    let (mut child, halves) =
                        refine::refine_topology_without_vertex_relations(&topo);
                    child_sharpness(&topo, &mut child, &halves, opts.creasing);
                    let features = child_features(&topo, &child, &halves);
                    Next::Child(Box::new(child), features, Some(halves))
                } else if level + 1 < opts.levels {
                    let (mut child, halves) = refine::refine_topology_with(
                        &topo,
                        split,
                        rules.needs_rings(),
                        keep_topologies || !lean_levels(split, rules.as_ref()),
                    );
                    child_sharpness(&topo, &mut child, &halves, opts.creasing);
                    let features = child_features(&topo, &child, &halves);
                    Next::Child(Box::new(child), features, None)
                } else {
                    Next::Finest(
                        refine::child_faces(&topo, split),
                        finest_tags(&topo, opts.creasing, tagged),
                    )
                }
            };
            // The child values and the child topology depend only on the parent: overlap them,
            // unless the (large) stencil tables are kept, to bound the peak memory.
            let ((next_positions, table, next_early), next) = if keep_stencils {
                let values = values();
                (values, child())
            } else {
                rayon::join(values, child)
            };
            positions = next_positions;
            early = next_early;
            stencils.extend(table);
            let parent = match next {
                Next::Child(child, child_features, halves) => {
                    features = Some(child_features);
                    let parent = std::mem::replace(&mut topo, *child);
                    match halves {
                        Some(halves) => {
                            coarser = Some((parent, halves));
                            None
                        }
                        None => Some(parent),
                    }
                }
                Next::Finest(faces, tags) => {
                    ((face_offsets, face_vertices), (edge_tags, vertex_tags)) = (faces, tags);
                    Some(std::mem::take(&mut topo))
                }
            };
            if keep_topologies {
                topologies.extend(parent);
            }
        }
        if opts.levels == 0 && keep_topologies {
            topologies.push(topo);
        }
        Ok(Refinement {
            topologies,
            face_offsets,
            face_vertices,
            stencils,
            positions,
            edge_tags,
            vertex_tags,
            base_holes,
            levels: opts.levels,
            split: Some(split),
        })
    }

    /// The finest-level faces that descend from base face `face` of `base` (the level-0
    /// topology), by the ordering contract of [`refine`]: `4^L` consecutive triangles per base
    /// triangle; `4^(L-1)` consecutive quads per base corner for polygon splits.
    pub fn descendants(&self, base: &Topology, face: u32) -> std::ops::Range<usize> {
        let f = face as usize;
        match (self.levels, self.split) {
            (0, _) => f..f + 1,
            (l, None) => {
                let n = 3usize.pow(l);
                f * n..(f + 1) * n
            }
            (l, Some(Split::Triangles | Split::QuadTri)) => {
                let n = 4usize.pow(l);
                f * n..(f + 1) * n
            }
            (l, Some(Split::Polygons)) => {
                let n = 4usize.pow(l - 1);
                base.face_offsets[f] as usize * n..base.face_offsets[f + 1] as usize * n
            }
        }
    }

    /// Re-evaluates the finest level from new control values (one per level-0 vertex) with
    /// the cached stencils, bit-identical to refining them from scratch.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if the stencils were not kept or `control` has the wrong
    /// length.
    pub fn evaluate<T: Interpolate>(&self, control: &[T]) -> Result<Vec<T>> {
        let mut levels = self.evaluate_levels(control)?;
        Ok(levels.pop().unwrap_or_else(|| control.to_vec()))
    }

    /// Like [`Refinement::evaluate`], returning every level `1..=levels`.
    ///
    /// # Errors
    /// As [`Refinement::evaluate`].
    pub fn evaluate_levels<T: Interpolate>(&self, control: &[T]) -> Result<Vec<Vec<T>>> {
        let levels = self.levels as usize;
        if self.stencils.len() != levels {
            return Err(Error::InvalidArgument(
                "stencils were not kept: build the refinement with keep_stencils".into(),
            ));
        }
        let sources = self
            .stencils
            .first()
            .map_or(self.positions.len(), |t| t.num_sources as usize);
        if control.len() != sources {
            return Err(Error::InvalidArgument(format!(
                "{} control values given, the mesh has {sources} vertices",
                control.len(),
            )));
        }
        let mut out: Vec<Vec<T>> = Vec::with_capacity(levels);
        for t in &self.stencils {
            let next = t.apply(out.last().map_or(control, |v| v.as_slice()));
            out.push(next);
        }
        Ok(out)
    }

    /// The finest level as a mesh (positions and faces).
    pub fn to_mesh(&self) -> Mesh {
        Mesh {
            positions: self.positions.clone(),
            face_offsets: self.face_offsets.clone(),
            face_indices: self.face_vertices.clone(),
            ..Mesh::new()
        }
    }
}

/// Whether the refiner may build the levels it drops after use lean (without their
/// vertex-face table, see [`Topology::from_edges_counted`]): on triangle splits whose rules
/// need no ordered rings, the fast paths of [`stencil`] read only each vertex's face count,
/// and the few vertices that take the general path gather their faces from their edges.
pub(crate) fn lean_levels(split: Split, rules: &dyn Rules) -> bool {
    split == Split::Triangles && !rules.needs_rings()
}

/// A level-0 topology ready to refine: the scheme's rules, its split, the topology with the
/// sharpness the refiner uses (tags, `--sharp-angle` creases, boundaries and boundary corners),
/// and the holes of [`BoundaryMode::None`].
pub(crate) struct Prepared {
    pub(crate) rules: Box<dyn Rules>,
    pub(crate) split: Split,
    pub(crate) topo: Topology,
    pub(crate) base_holes: Vec<u32>,
}

/// The number of faces that `opts.levels` levels of `opts.scheme` make of `mesh` (saturating
/// at `u64::MAX`): `F · 4^L` for triangle and quad/triangle splits, `C · 4^(L−1)` for polygon
/// splits (`C` corners: each n-gon becomes n quads), `F · 3^L` for √3; `F` for no levels.
/// [`subdivide`] refuses more than [`MAX_FACES`]; callers can also check the memory the
/// result needs before they start.
pub fn output_faces(mesh: &Mesh, opts: &SubdivideOptions) -> u64 {
    let f = mesh.num_faces() as u64;
    if opts.levels == 0 {
        return f;
    }
    if opts.scheme == Scheme::Sqrt3 {
        return f.saturating_mul(3u64.saturating_pow(opts.levels));
    }
    match rules_for(opts, mesh).split() {
        Split::Triangles | Split::QuadTri => f.saturating_mul(4u64.saturating_pow(opts.levels)),
        Split::Polygons => {
            (mesh.face_indices.len() as u64).saturating_mul(4u64.saturating_pow(opts.levels - 1))
        }
    }
}

/// Checks `mesh` for `opts` and prepares its level-0 topology (see [`Refinement::build`] for
/// the errors).
pub(crate) fn prepare(mesh: &Mesh, opts: &SubdivideOptions) -> Result<Prepared> {
    mesh.check_indices()?;
    if opts.scheme == Scheme::Loop {
        require_arity(
            mesh,
            3,
            "loop",
            "triangles",
            "use catmull-clark or bilinear (any polygons)",
        )?;
    }
    if matches!(opts.scheme, Scheme::Butterfly | Scheme::ButterflyOriginal) {
        require_arity(
            mesh,
            3,
            opts.scheme.name(),
            "triangles",
            "use catmull-clark or bilinear (any polygons)",
        )?;
    }
    if opts.scheme == Scheme::QuadTri {
        quad_tri::require_triangles_and_quads(mesh)?;
    }
    let rules = rules_for(opts, mesh);
    let split = rules.split();
    let faces_out = output_faces(mesh, opts);
    if opts.levels > 0 && faces_out > MAX_FACES {
        return Err(Error::InvalidArgument(format!(
            "{} levels of {} on {} faces would make {} faces, more than the {} supported; use fewer levels",
            opts.levels,
            opts.scheme.name(),
            mesh.num_faces(),
            faces_out,
            MAX_FACES
        )));
    }
    let mut topo = Topology::build(mesh);
    require_manifold(&topo)?;
    if let Some(deg) = opts.sharp_angle {
        for e in sharp_edges_by_angle(mesh, &topo, deg) {
            topo.edge_sharpness[e as usize] = SHARPNESS_INFINITE;
        }
    }
    let base_holes = if opts.boundary == BoundaryMode::None
        && matches!(opts.scheme, Scheme::Loop | Scheme::CatmullClark)
    {
        boundary_holes(&topo)
    } else {
        Vec::new()
    };
    for e in 0..topo.num_edges() {
        if topo.is_boundary_edge(e) {
            topo.edge_sharpness[e] = SHARPNESS_INFINITE;
        }
    }
    if opts.boundary == BoundaryMode::OpenSubdivCorners {
        for v in 0..topo.num_vertices as usize {
            if topo.vertex_faces(v).len() == 1 {
                topo.vertex_sharpness[v] = SHARPNESS_INFINITE;
            }
        }
    }
    Ok(Prepared {
        rules,
        split,
        topo,
        base_holes,
    })
}

/// [`Refinement`] of the B-spline schemes: bilinear topology, positions from the wavelet
/// synthesis with zero details. No stencil tables (the synthesis is a sequence of lifts).
fn bspline_refinement(
    mesh: &Mesh,
    opts: &SubdivideOptions,
    degree: crate::wavelet::bertram::Degree,
    keep_stencils: bool,
    keep_topologies: bool,
) -> Result<Refinement> {
    if keep_stencils {
        return Err(Error::InvalidArgument(format!(
            "{} is computed by wavelet lifting and has no stencil tables",
            opts.scheme.name()
        )));
    }
    let bilinear = SubdivideOptions {
        scheme: Scheme::Bilinear,
        ..*opts
    };
    let mut r = Refinement::build_with(mesh, &bilinear, false, true)?;
    if opts.levels > 0 {
        let w = crate::wavelet::bertram::BSplineWavelet::new(degree);
        r.positions = w.subdivide(&r.topologies, &mesh.positions)?;
    }
    if !keep_topologies {
        r.topologies.clear();
    }
    Ok(r)
}

/// Faces that are holes under [`BoundaryMode::None`] (OpenSubdiv's
/// `TopologyRefinerFactoryBase::prepareComponentTagsAndSharpness`): those incident to a
/// boundary vertex with a boundary edge not tagged infinitely sharp. Call before boundary edges
/// are sharpened.
fn boundary_holes(topo: &Topology) -> Vec<u32> {
    let mut hole = vec![false; topo.num_faces()];
    for v in 0..topo.num_vertices as usize {
        let edges = topo.vertex_edges(v);
        if edges.len() == topo.vertex_faces(v).len() {
            continue;
        }
        let exclude = edges.iter().any(|&e| {
            topo.is_boundary_edge(e as usize)
                && !rules::is_infinite(topo.edge_sharpness[e as usize])
        });
        if exclude {
            for &f in topo.vertex_faces(v) {
                hole[f as usize] = true;
            }
        }
    }
    (0..topo.num_faces() as u32)
        .filter(|&f| hole[f as usize])
        .collect()
}

/// Sets the child level's sharpness from the parent's: each edge's halves by the creasing
/// rule at their end, corners decremented; new edges and vertices are smooth.
fn child_sharpness(
    parent: &Topology,
    child: &mut Topology,
    halves: &[[u32; 2]],
    creasing: Creasing,
) {
    let mut incident = Vec::new();
    for (e, h) in halves.iter().enumerate() {
        let s = parent.edge_sharpness[e];
        if s <= 0.0 {
            continue;
        }
        for (end, &half) in h.iter().enumerate() {
            let w = parent.edge_vertices[e][end] as usize;
            incident.clear();
            incident.extend(
                parent
                    .vertex_edges(w)
                    .iter()
                    .map(|&x| parent.edge_sharpness[x as usize]),
            );
            child.edge_sharpness[half as usize] = child_edge_sharpness(creasing, s, &incident);
        }
    }
    for v in 0..parent.num_vertices as usize {
        child.vertex_sharpness[v] = decrement(parent.vertex_sharpness[v]);
    }
}

/// [`stencil::vertex_features`] of a `child` whose sharpness [`child_sharpness`] set, from
/// the parent (linear in the parent's edges and vertices, not the child's): only the halves
/// of the parent's sharp edges can be sharp, only the parent's vertices corners.
fn child_features(parent: &Topology, child: &Topology, halves: &[[u32; 2]]) -> Vec<u8> {
    let mut features = vec![0u8; child.num_vertices as usize];
    for (f, &s) in features
        .iter_mut()
        .zip(&child.vertex_sharpness[..parent.num_vertices as usize])
    {
        if s != 0.0 {
            *f = u8::MAX;
        }
    }
    for (e, h) in halves.iter().enumerate() {
        if parent.edge_sharpness[e] == 0.0 {
            continue;
        }
        for &half in h {
            if child.edge_sharpness[half as usize] != 0.0 {
                for &v in &child.edge_vertices[half as usize] {
                    features[v as usize] = features[v as usize].saturating_add(1);
                }
            }
        }
    }
    features
}

/// Whether `topo` has an interior edge or a vertex with positive sharpness (what
/// [`finest_tags`] turns into tags; boundary edges are sharp without being tags).
pub(crate) fn has_interior_tags(topo: &Topology) -> bool {
    topo.vertex_sharpness.iter().any(|&s| s > 0.0)
        || (0..topo.num_edges()).any(|e| topo.edge_sharpness[e] > 0.0 && !topo.is_boundary_edge(e))
}

/// Tags of the level refined from `parent`: the halves of its sharp interior edges (child
/// edge `(w, V + e)`, sharpness by the creasing rule) and its decremented corners.
///
/// `tagged` is [`has_interior_tags`] of level 0. Creases only soften from level to level,
/// and new edges and vertices are smooth: without sharp interior edges or sharp vertices at
/// level 0 no level has tags, and the scan of `parent` (millions of edges at the finest
/// levels) is skipped.
fn finest_tags(
    parent: &Topology,
    creasing: Creasing,
    tagged: bool,
) -> (Vec<EdgeTag>, Vec<VertexTag>) {
    if !tagged {
        return Default::default();
    }
    let nv = parent.num_vertices;
    let mut edges = Vec::new();
    let mut incident = Vec::new();
    for e in 0..parent.num_edges() {
        let s = parent.edge_sharpness[e];
        if s <= 0.0 || parent.is_boundary_edge(e) {
            continue;
        }
        for &w in &parent.edge_vertices[e] {
            incident.clear();
            incident.extend(
                parent
                    .vertex_edges(w as usize)
                    .iter()
                    .map(|&x| parent.edge_sharpness[x as usize]),
            );
            let c = child_edge_sharpness(creasing, s, &incident);
            if c > 0.0 {
                edges.push(EdgeTag {
                    vertices: [w, nv + e as u32],
                    sharpness: c,
                });
            }
        }
    }
    let vertices = (0..nv)
        .filter_map(|v| {
            let s = decrement(parent.vertex_sharpness[v as usize]);
            (s > 0.0).then_some(VertexTag {
                vertex: v,
                sharpness: s,
            })
        })
        .collect();
    (edges, vertices)
}

/// Subdivides `mesh` and returns the finest level, with per-vertex colours and texture
/// coordinates interpolated as vertex-varying data, face-varying texture coordinates
/// interpolated linearly per face ([`face_varying`]) and crease tags carried to the new edges.
///
/// # Errors
/// As [`Refinement::build`].
pub fn subdivide(mesh: &Mesh, opts: &SubdivideOptions) -> Result<Mesh> {
    if let Some(degree) = opts.scheme.bspline_degree() {
        return crate::wavelet::bertram::subdivide_mesh(mesh, opts, degree);
    }
    let carry = mesh.colors.is_some() || mesh.uvs.is_some();
    let r = Refinement::build_with(mesh, opts, carry, carry)?;
    let holes: Vec<_> = if r.base_holes.is_empty() {
        Vec::new()
    } else {
        let base = Topology::build(mesh);
        r.base_holes
            .iter()
            .map(|&f| r.descendants(&base, f))
            .collect()
    };
    let mut out = Mesh::new();
    if carry {
        if let Some(c) = &mesh.colors {
            out.colors = Some(r.evaluate(c)?);
        }
        if let Some(t) = &mesh.uvs {
            out.uvs = Some(r.evaluate(t)?);
        }
    }
    out.positions = r.positions;
    out.face_offsets = r.face_offsets;
    out.face_indices = r.face_vertices;
    out.edge_tags = r.edge_tags;
    out.vertex_tags = r.vertex_tags;
    if let Some(fv) = &mesh.face_uvs {
        if let Some(split) = r.split {
            out.face_uvs = Some(face_varying::refine_linear(
                fv,
                &mesh.face_offsets,
                split,
                r.levels,
            ));
        } else {
            tracing::warn!(
                "{}: face-varying texture coordinates are not refined by this scheme; dropped",
                opts.scheme.name()
            );
        }
    }
    if !holes.is_empty() {
        drop_faces(&mut out, &holes);
    }
    Ok(out)
}

/// Removes the faces in `ranges` and the vertices only they used.
fn drop_faces(mesh: &mut Mesh, ranges: &[std::ops::Range<usize>]) {
    let mut keep = vec![true; mesh.num_faces()];
    for r in ranges {
        keep[r.clone()].iter_mut().for_each(|k| *k = false);
    }
    let (mut offsets, mut indices, mut uv) = (vec![0u32], Vec::new(), Vec::new());
    for f in (0..keep.len()).filter(|&f| keep[f]) {
        let (a, b) = (
            mesh.face_offsets[f] as usize,
            mesh.face_offsets[f + 1] as usize,
        );
        indices.extend_from_slice(&mesh.face_indices[a..b]);
        if let Some(fv) = &mesh.face_uvs {
            uv.extend_from_slice(&fv.indices[a..b]);
        }
        offsets.push(indices.len() as u32);
    }
    mesh.face_offsets = offsets;
    mesh.face_indices = indices;
    if let Some(fv) = &mut mesh.face_uvs {
        fv.indices = uv;
    }
    mesh.remove_unreferenced();
}

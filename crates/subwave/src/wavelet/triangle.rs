//! Wavelets on triangle hierarchies (1-to-4 splits): midpoint (lazy or lifted), any
//! interpolating scheme's prediction, and Loop as in Khodakovsky, Schröder & Sweldens,
//! *Progressive Geometry Compression* (PGC, SIGGRAPH 2000).
//!
//! Maret 2003 §4.2.3 ("Computation of details coefficients") and §4.5 (the MPEG-4 AFX
//! wavelet subdivision surface node: Loop, butterfly and midpoint wavelets, the last two
//! lifted or not, details in global or local coordinates, §4.4.3). One level `j → j + 1` of
//! a [`Hierarchy`] at a time, on flat `Vec<DVec3>`:
//! - the **fine** signal has `V_{j+1}` values in contract order (even vertices `0..V_j`, then
//!   one odd vertex per level-`j` edge);
//! - the **coarse** signal has `V_j` values;
//! - the **details** have `E_j = V_{j+1} − V_j` values, detail `e` belonging to odd vertex
//!   `V_j + e`, i.e. to level-`j` edge `e` (PGC's edge-based detail hierarchy).
//!
//! # Transforms
//! Each level's prediction `S_j` is a [`StencilTable`] mapping level `j` to level `j + 1`
//! (the stencil tables of [`crate::subdivision`]).
//! - **Interpolating** schemes (even rows of `S_j` are the identity; [`Kind::Interpolating`]):
//!   analysis `d = x_odd − S_j(x_even)_odd`, then, if lifted, the update `c = x_even + U d`;
//!   synthesis `x_even = c − U d`, `x_odd = S_j(x_even)_odd + d`. Midpoint is the lazy
//!   wavelet with linear prediction ([`TriangleWavelet::midpoint`]); any other interpolating
//!   scheme plugs in through [`TriangleWavelet::interpolating`] with its level stencil tables.
//!   **Butterfly hook**: [`TriangleWavelet::from_scheme`] builds the tables of any scheme of
//!   [`crate::subdivision`] with [`Refinement::build`] and accepts it if it is interpolating;
//!   once `Scheme::Butterfly` is merged, `from_scheme(h, &opts, lifted)` with
//!   `opts.scheme = Scheme::Butterfly` gives the unlifted and lifted butterfly wavelets
//!   (`tests::butterfly_hook_with_a_plugged_table` runs the path with a hand-made
//!   interpolating table, `tests::from_scheme_midpoint` with the crate's midpoint rules).
//! - **Loop** ([`Kind::Loop`], PGC): synthesis is Loop subdivision of the coarse level plus
//!   details at the odd vertices only, `x = S_j c + (0, d)`. Analysis solves the sparse system
//!   "Loop vertex rule applied to the coarse level = even vertices of the fine level"
//!   (`A c = x_even`, `A` the even rows of `S_j`: `V_j × V_j`, ~7 nonzeros per row, well
//!   conditioned) by BiCGSTAB with Jacobi preconditioning, started from `x_even` and after
//!   removing the centroid (rows sum to 1); then `d = x_odd − (S_j c)_odd`. There is no finite
//!   lifting for Loop analysis (Maret §4.2.3), hence the solve.
//!
//! # The update (lifting) step
//! `c_v = x_v + Σ_{e ∋ v} s_{v,e} d_e` with `s_{v,e} = 3 φ_e / (8 f_v)`, `φ_e` the number of
//! faces of edge `e` (1 or 2) and `f_v` the number of level-`j` faces at `v` (`1/8` at a
//! regular interior vertex). It makes the coarse signal keep the *integral* of the
//! piecewise-linear surface in the topological metric (every level-`j` triangle of area
//! `4^{-j}`): `I_j(x) = 4^{-j} Σ_v f_v x_v`. Derivation: substituting `x_o = (x_a + x_b)/2 +
//! d_o` in `I_{j+1}` (odd vertices have `3 φ_e` fine faces, even vertices keep `f_v`, and
//! `Σ_{e ∋ v} φ_e = 2 f_v`) gives `I_{j+1}(x) = 4^{-j} (Σ_v f_v x_v + Σ_e 3 φ_e d_e / 4)`,
//! and `Σ_v f_v Σ_e s_{v,e} d_e = Σ_e d_e (3 φ_e/8 + 3 φ_e/8)` matches the second term. So
//! the base mesh keeps the first moment (centroid) of the fine surface in this metric, the
//! property of the 1D lifted linear wavelet (`c_i = x_{2i} + (d_{i−1} + d_i)/4`). For
//! butterfly the same update applies: its prediction weights have the same column sums as
//! midpoint's in regular regions (`6·1/2 + 6·1/8 − 12·1/16 = 3`).
//!
//! # Local frames
//! With [`DetailFrame::Local`], details are stored as `(normal, tangent, bitangent)`
//! coordinates ([`super::frames`]) of the frame at each odd vertex of the **predicted**
//! surface `S_j c` (for the lifted wavelets, `S_j` of the updated coarse signal), which a
//! decoder has before it reads the details.
//!
//! # Position-dependent masks
//! Loop's tables come from [`Refinement::build`] on the hierarchy's base mesh (boundaries and
//! tagged edges as creases, per the [`SubdivideOptions`]). The only masks that depend on
//! positions are Biermann et al.'s edge rules next to *corner* vertices (a corner tag, or
//! three or more crease edges) with `BoundaryMode::Crease`: they use the corner's sector
//! angle, evaluated once from the hierarchy's base positions (the finest samples of the base
//! vertices) and their Loop refinements. A codec must then give the decoder the same angles
//! (or the same base positions); meshes without such corners (any untagged mesh, with or
//! without boundary) have no position-dependent mask.

use glam::DVec3;
use rayon::prelude::*;

use super::frames::{odd_vertex_frames, Frame};
use crate::hierarchy::Hierarchy;
use crate::subdivision::butterfly;
use crate::subdivision::refine::Split;
use crate::subdivision::stencil::StencilTable;
use crate::subdivision::{Refinement, Scheme, SubdivideOptions};
use crate::topology::Topology;
use crate::{Error, Result};

/// Coordinates of the detail vectors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DetailFrame {
    /// Global `x, y, z`.
    #[default]
    Global,
    /// Local `(normal, tangent, bitangent)` of the predicted surface (Maret §4.4.3).
    Local,
}

/// The kind of transform.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Interpolating prediction (odd vertices only), with or without the update step.
    Interpolating {
        /// Whether the update (lifting) step is applied.
        lifted: bool,
    },
    /// Loop (PGC): approximating prediction, analysis by a sparse solve.
    Loop,
}

/// Options of the Loop analysis solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverOptions {
    /// Stop when the residual's max norm is at most this times the right-hand side's (after
    /// removing its centroid).
    pub tolerance: f64,
    /// Iteration limit (an error beyond it).
    pub max_iterations: usize,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            tolerance: 1e-15,
            max_iterations: 500,
        }
    }
}

/// A full decomposition: base positions and the details of every level (`details[j]` has
/// `E_j` values, for level `j → j + 1`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Decomposition {
    /// Level-0 positions (`V_0` values).
    pub base: Vec<DVec3>,
    /// Details per level, coarsest first.
    pub details: Vec<Vec<DVec3>>,
}

/// A wavelet transform on a triangle [`Hierarchy`].
#[derive(Clone, Debug)]
pub struct TriangleWavelet<'h> {
    h: &'h Hierarchy,
    tables: Vec<StencilTable>,
    /// Per level, the most common odd-row stencil ([`RowPattern`]).
    patterns: Vec<RowPattern>,
    /// The update step's plan (lifted wavelets; empty otherwise).
    update_plan: UpdatePlan,
    kind: Kind,
    frame: DetailFrame,
    solver: SolverOptions,
}

fn require_triangles(h: &Hierarchy) -> Result<()> {
    if h.split != Split::Triangles {
        return Err(Error::InvalidArgument(
            "triangle wavelets need a triangle (1-to-4) hierarchy; use the quad wavelets for polygon splits".into(),
        ));
    }
    Ok(())
}

impl Decomposition {
    /// The flat layout `[base | details of level 0 | details of level 1 | …]`: the finest
    /// level's vertex order, each coarse level a prefix (the in-place layout of the quad
    /// wavelets in [`super`]).
    pub fn to_flat(&self) -> Vec<DVec3> {
        let mut out = self.base.clone();
        for d in &self.details {
            out.extend_from_slice(d);
        }
        out
    }

    /// The inverse of [`Decomposition::to_flat`] for hierarchy `h` (`V_L` values).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `flat` does not have `V_L` values.
    pub fn from_flat(h: &Hierarchy, flat: &[DVec3]) -> Result<Decomposition> {
        let l = h.levels();
        if flat.len() != h.num_vertices(l) {
            return Err(Error::InvalidArgument(format!(
                "{} values given, the finest level has {} vertices",
                flat.len(),
                h.num_vertices(l)
            )));
        }
        Ok(Decomposition {
            base: flat[..h.num_vertices(0)].to_vec(),
            details: (0..l)
                .map(|j| flat[h.num_vertices(j)..h.num_vertices(j + 1)].to_vec())
                .collect(),
        })
    }
}

impl<'h> TriangleWavelet<'h> {
    /// The midpoint wavelet: linear prediction (odd vertex − midpoint of its parent edge),
    /// with the update step of the module documentation if `lifted`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `h` is not a triangle hierarchy.
    pub fn midpoint(h: &'h Hierarchy, lifted: bool) -> Result<Self> {
        require_triangles(h)?;
        let tables = (0..h.levels())
            .map(|j| {
                let t = h.topology(j);
                let nv = t.num_vertices;
                let ne = t.num_edges() as u32;
                let mut offsets: Vec<u32> = (0..=nv).collect();
                offsets.extend((1..=ne).map(|e| nv + 2 * e));
                let mut indices: Vec<u32> = (0..nv).collect();
                indices.extend(t.edge_vertices.iter().flatten());
                let mut weights = vec![1.0; nv as usize];
                weights.resize((nv + 2 * ne) as usize, 0.5);
                StencilTable {
                    num_sources: nv,
                    child_sources: 0,
                    offsets,
                    indices,
                    weights,
                }
            })
            .collect();
        Self::interpolating(h, tables, lifted)
    }

    /// The wavelet of an interpolating scheme given by its level stencil tables
    /// (`tables[j]` maps level `j` to level `j + 1`; even rows must be the identity). This is
    /// the hook for butterfly: pass `Refinement::build(&h.base, &opts, true)?.stencils`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `h` is not a triangle hierarchy, the number or sizes of
    /// the tables do not match the hierarchy, a table refers to its own children
    /// ([`StencilTable::child_sources`] not 0), or an even row is not the identity (naming
    /// the level and vertex).
    pub fn interpolating(
        h: &'h Hierarchy,
        tables: Vec<StencilTable>,
        lifted: bool,
    ) -> Result<Self> {
        require_triangles(h)?;
        check_tables(h, &tables)?;
        for (j, t) in tables.iter().enumerate() {
            for v in 0..t.num_sources as usize {
                let (a, b) = (t.offsets[v] as usize, t.offsets[v + 1] as usize);
                if b != a + 1 || t.indices[a] as usize != v || t.weights[a] != 1.0 {
                    return Err(Error::InvalidArgument(format!(
                        "level {j}: the stencil of even vertex {v} is not the identity; the scheme is not interpolating (use TriangleWavelet::loop_pgc for approximating schemes)"
                    )));
                }
            }
        }
        Ok(TriangleWavelet {
            h,
            patterns: tables.iter().map(RowPattern::new).collect(),
            tables,
            update_plan: if lifted {
                UpdatePlan::new(h)
            } else {
                UpdatePlan::default()
            },
            kind: Kind::Interpolating { lifted },
            frame: DetailFrame::Global,
            solver: SolverOptions::default(),
        })
    }

    /// The wavelet of an interpolating scheme of [`crate::subdivision`], its tables built by
    /// [`Refinement::build`] on the hierarchy's base mesh (`opts.levels` is ignored). With
    /// `Scheme::Midpoint` this is [`TriangleWavelet::midpoint`]; with the butterfly scheme
    /// (once merged) it gives the unlifted and lifted butterfly wavelets of MPEG-4 AFX.
    ///
    /// # Errors
    /// As [`Refinement::build`]; as [`TriangleWavelet::interpolating`] (in particular if the
    /// scheme is not interpolating).
    pub fn from_scheme(h: &'h Hierarchy, opts: &SubdivideOptions, lifted: bool) -> Result<Self> {
        require_triangles(h)?;
        let o = SubdivideOptions {
            levels: h.levels() as u32,
            ..*opts
        };
        let r = Refinement::build(&h.base, &o, true)?;
        Self::interpolating(h, r.stencils, lifted)
    }

    /// The modified butterfly wavelet with the refiner's default options (boundaries as
    /// creases): [`TriangleWavelet::from_scheme`] with `Scheme::Butterfly`, bit for bit, but
    /// for a hierarchy without crease or corner tags the prediction tables are built straight
    /// from the hierarchy's level topologies
    /// ([`crate::subdivision::butterfly::untagged_level_table`]) instead of refining the base
    /// mesh again.
    ///
    /// # Errors
    /// As [`TriangleWavelet::from_scheme`].
    pub fn butterfly(h: &'h Hierarchy, lifted: bool) -> Result<Self> {
        require_triangles(h)?;
        let untagged = h.topologies.iter().all(|t| {
            t.edge_sharpness.iter().all(|&s| s == 0.0)
                && t.vertex_sharpness.iter().all(|&s| s == 0.0)
        });
        if !untagged || h.topologies.is_empty() {
            let opts = SubdivideOptions {
                scheme: Scheme::Butterfly,
                ..Default::default()
            };
            return Self::from_scheme(h, &opts, lifted);
        }
        let tables = h.topologies[..h.levels()]
            .par_iter()
            .map(butterfly::untagged_level_table)
            .collect();
        Self::interpolating(h, tables, lifted)
    }

    /// The Loop wavelet of PGC. `opts` gives the boundary mode, creasing and β of the Loop
    /// tables (its `scheme` and `levels` are ignored).
    ///
    /// # Errors
    /// As [`Refinement::build`] on the base mesh; [`Error::InvalidArgument`] if `h` is not a
    /// triangle hierarchy.
    pub fn loop_pgc(h: &'h Hierarchy, opts: &SubdivideOptions) -> Result<Self> {
        require_triangles(h)?;
        let o = SubdivideOptions {
            scheme: Scheme::Loop,
            levels: h.levels() as u32,
            ..*opts
        };
        let r = Refinement::build(&h.base, &o, true)?;
        check_tables(h, &r.stencils)?;
        Ok(TriangleWavelet {
            h,
            tables: r.stencils,
            patterns: Vec::new(),
            update_plan: UpdatePlan::default(),
            kind: Kind::Loop,
            frame: DetailFrame::Global,
            solver: SolverOptions::default(),
        })
    }

    /// The same transform with details in the given coordinates.
    pub fn with_frame(mut self, frame: DetailFrame) -> Self {
        self.frame = frame;
        self
    }

    /// The same transform with other solver options (Loop analysis).
    pub fn with_solver(mut self, solver: SolverOptions) -> Self {
        self.solver = solver;
        self
    }

    /// The kind of transform.
    pub fn kind(&self) -> Kind {
        self.kind
    }

    /// The hierarchy.
    pub fn hierarchy(&self) -> &'h Hierarchy {
        self.h
    }

    /// The prediction tables (`tables[j]`: level `j` → `j + 1`).
    pub fn tables(&self) -> &[StencilTable] {
        &self.tables
    }

    /// The prediction tables and their row patterns, by value.
    pub(crate) fn into_parts(self) -> (Vec<StencilTable>, Vec<RowPattern>) {
        (self.tables, self.patterns)
    }

    fn check_level(&self, level: usize) -> Result<()> {
        if level >= self.tables.len() {
            return Err(Error::InvalidArgument(format!(
                "level {level} does not exist: the hierarchy has {} levels (0..{})",
                self.tables.len(),
                self.tables.len()
            )));
        }
        Ok(())
    }

    fn check_len(what: &str, level: usize, got: usize, want: usize) -> Result<()> {
        if got != want {
            return Err(Error::InvalidArgument(format!(
                "level {level}: {got} {what} values given, {want} expected"
            )));
        }
        Ok(())
    }

    /// The predicted fine level `S_j c` (synthesis with zero details; for the lifted
    /// wavelets, of the given coarse signal as the even vertices).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a bad level or length.
    pub fn predict(&self, level: usize, coarse: &[DVec3]) -> Result<Vec<DVec3>> {
        self.check_level(level)?;
        Self::check_len("coarse", level, coarse.len(), self.h.num_vertices(level))?;
        Ok(self.tables[level].apply(coarse))
    }

    /// The frames of level `level`'s odd vertices on the predicted surface `predicted`.
    fn frames(&self, level: usize, predicted: &[DVec3]) -> Vec<Frame> {
        let fine = self.h.topology(level + 1);
        if fine.rings_ordered && !fine.vertex_face_offsets.is_empty() {
            return odd_vertex_frames(self.h.topology(level), fine, predicted);
        }
        // Unordered fine level (every level a hierarchy builds): the same frames from the
        // coarse topology.
        let nc = self.h.num_vertices(level);
        let (even, odd) = predicted.split_at(nc);
        let t = self.h.topology(level);
        (0..odd.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|e| coarse_frame(t, even, odd, e))
            .collect()
    }

    /// `c += ±U d` (the update step), in place.
    fn update(&self, level: usize, coarse: &mut [DVec3], details: &[DVec3], sign: f64) {
        let t = self.h.topology(level);
        self.update_plan
            .for_each(t, level, coarse, |x, f, edges, phi| {
                let mut acc = DVec3::ZERO;
                for (k, &e) in edges.iter().enumerate() {
                    acc += edge_face_count(t, phi, k, e) as f64 * details[e as usize];
                }
                *x += sign * 3.0 / (8.0 * f as f64) * acc;
            });
    }

    /// One analysis step: level `level + 1`'s signal (`V_{j+1}` values) into the coarse
    /// signal (`V_j`) and the details (`E_j`, in the transform's frame).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a bad level or length, or if the Loop solve does not
    /// converge.
    pub fn analyze_level(&self, level: usize, fine: &[DVec3]) -> Result<(Vec<DVec3>, Vec<DVec3>)> {
        self.check_level(level)?;
        Self::check_len("fine", level, fine.len(), self.h.num_vertices(level + 1))?;
        let nc = self.h.num_vertices(level);
        let table = &self.tables[level];
        let (even, odd) = fine.split_at(nc);
        let (coarse, mut details, predicted) = match self.kind {
            Kind::Loop => {
                let coarse = solve_even_rows(table, even, &self.solver).map_err(|(it, r)| {
                    Error::InvalidArgument(format!(
                        "level {level}: the Loop analysis solve did not converge in {it} iterations (relative residual {r:.3e})"
                    ))
                })?;
                let predicted = table.apply(&coarse);
                let details = sub(odd, &predicted[nc..]);
                (coarse, details, Some(predicted))
            }
            Kind::Interpolating { lifted } => {
                let predicted = table.apply(even);
                let details = sub(odd, &predicted[nc..]);
                if lifted {
                    let mut coarse = even.to_vec();
                    self.update(level, &mut coarse, &details, 1.0);
                    (coarse, details, None)
                } else {
                    (even.to_vec(), details, Some(predicted))
                }
            }
        };
        if self.frame == DetailFrame::Local {
            let predicted = match predicted {
                Some(p) => p,
                None => table.apply(&coarse),
            };
            let frames = self.frames(level, &predicted);
            details
                .par_iter_mut()
                .zip(&frames)
                .for_each(|(d, f)| *d = f.to_local(*d));
        }
        Ok((coarse, details))
    }

    /// One synthesis step: the coarse signal (`V_j`) and details (`E_j`, in the transform's
    /// frame) into level `level + 1`'s signal.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a bad level or length.
    pub fn synthesize_level(
        &self,
        level: usize,
        coarse: &[DVec3],
        details: &[DVec3],
    ) -> Result<Vec<DVec3>> {
        self.check_level(level)?;
        let nc = self.h.num_vertices(level);
        Self::check_len("coarse", level, coarse.len(), nc)?;
        Self::check_len(
            "detail",
            level,
            details.len(),
            self.h.num_vertices(level + 1) - nc,
        )?;
        let table = &self.tables[level];
        let lifted = self.kind == Kind::Interpolating { lifted: true };
        let global: Vec<DVec3>;
        let mut predicted = None;
        let details = if self.frame == DetailFrame::Local {
            let p = table.apply(coarse);
            let frames = self.frames(level, &p);
            global = details
                .par_iter()
                .zip(&frames)
                .map(|(d, f)| f.to_global(*d))
                .collect();
            predicted = Some(p);
            &global[..]
        } else {
            details
        };
        let mut fine = if lifted {
            let mut even = coarse.to_vec();
            self.update(level, &mut even, details, -1.0);
            table.apply(&even)
        } else {
            predicted.unwrap_or_else(|| table.apply(coarse))
        };
        fine[nc..]
            .par_iter_mut()
            .zip(details)
            .for_each(|(x, d)| *x += *d);
        Ok(fine)
    }

    /// Full analysis in place: `data` holds the finest level (`V_L` values) on entry and the
    /// flat layout of [`Decomposition::to_flat`] (`[base | details 0 | … | details L−1]`) on
    /// return, bit for bit equal to [`TriangleWavelet::decompose`] followed by `to_flat`.
    ///
    /// For interpolating wavelets with global details this is the lifting scheme proper: per
    /// level one pass over the odd vertices (prediction) and, if lifted, one over the even
    /// vertices (update), with no allocation. Loop and local frames go through
    /// [`TriangleWavelet::analyze_level`] (a solve or the frames need the predicted level).
    ///
    /// # Errors
    /// As [`TriangleWavelet::analyze_level`]; a wrong length.
    pub fn decompose_in_place(&self, data: &mut [DVec3]) -> Result<()> {
        let l = self.tables.len();
        Self::check_len("finest", l, data.len(), self.h.num_vertices(l))?;
        for j in (0..l).rev() {
            let n = self.h.num_vertices(j + 1);
            let nc = self.h.num_vertices(j);
            match (self.kind, self.frame) {
                (Kind::Interpolating { lifted }, DetailFrame::Global) => {
                    let (even, odd) = data[..n].split_at_mut(nc);
                    self.predict_odd(j, even, odd, -1.0);
                    if lifted {
                        self.update(j, even, odd, 1.0);
                    }
                }
                _ => {
                    let (c, d) = self.analyze_level(j, &data[..n])?;
                    data[..nc].copy_from_slice(&c);
                    data[nc..n].copy_from_slice(&d);
                }
            }
        }
        Ok(())
    }

    /// Full synthesis in place: the inverse of [`TriangleWavelet::decompose_in_place`]
    /// (`data` in the flat layout on entry, the finest level on return), bit for bit equal to
    /// [`TriangleWavelet::reconstruct`] of the same decomposition.
    ///
    /// # Errors
    /// As [`TriangleWavelet::synthesize_level`]; a wrong length.
    pub fn reconstruct_in_place(&self, data: &mut [DVec3]) -> Result<()> {
        self.reconstruct_in_place_with(data, &mut SynthesisScratch::default())
    }

    /// [`TriangleWavelet::reconstruct_in_place`] with its scratch memory in `scratch` (any
    /// history; same result), e.g. one from [`SynthesisScratch::prepared`] whose pages were
    /// touched off the critical path.
    ///
    /// # Errors
    /// As [`TriangleWavelet::reconstruct_in_place`].
    pub fn reconstruct_in_place_with(
        &self,
        data: &mut [DVec3],
        scratch: &mut SynthesisScratch,
    ) -> Result<()> {
        let l = self.tables.len();
        Self::check_len("flat", l, data.len(), self.h.num_vertices(l))?;
        let SynthesisScratch { pred, normals } = scratch;
        for j in 0..l {
            let n = self.h.num_vertices(j + 1);
            let nc = self.h.num_vertices(j);
            match (self.kind, self.frame) {
                (Kind::Interpolating { lifted }, DetailFrame::Global) => {
                    let (even, odd) = data[..n].split_at_mut(nc);
                    if lifted {
                        self.update(j, even, odd, -1.0);
                    }
                    self.predict_odd(j, even, odd, 1.0);
                }
                (Kind::Interpolating { lifted }, DetailFrame::Local)
                    if !self.h.topology(j + 1).rings_ordered =>
                {
                    let (even, odd) = data[..n].split_at_mut(nc);
                    let scratch = (&mut *pred, &mut *normals);
                    self.synthesize_local_in_place(j, even, odd, scratch, lifted);
                }
                _ => {
                    let (c, d) = data[..n].split_at(nc);
                    let fine = self.synthesize_level(j, c, d)?;
                    data[..n].copy_from_slice(&fine);
                }
            }
        }
        Ok(())
    }

    /// One synthesis step of an interpolating wavelet with local frames, in place, bit for
    /// bit [`TriangleWavelet::synthesize_level`]: `even` holds the coarse signal, `odd` the
    /// details in local coordinates on entry; both hold level `level + 1` on return. `pred`
    /// and `normals` are scratch space (the predicted odd vertices, the normals of the
    /// predicted fine faces). Needs an unordered fine level (the
    /// frames are computed from the coarse topology, [`coarse_frame`]).
    fn synthesize_local_in_place(
        &self,
        level: usize,
        even: &mut [DVec3],
        odd: &mut [DVec3],
        (pred, normals): (&mut Vec<DVec3>, &mut Vec<[DVec3; 4]>),
        lifted: bool,
    ) {
        let t = self.h.topology(level);
        let table = &self.tables[level];
        let nc = even.len();
        {
            let even = &*even;
            // The predicted odd vertices (`StencilTable::apply`'s sums, written once).
            pred.clear();
            pred.par_extend(
                (nc..nc + odd.len())
                    .into_par_iter()
                    .with_min_len(ODD_CHUNK)
                    .map(|r| {
                        let (a, b) = (table.offsets[r] as usize, table.offsets[r + 1] as usize);
                        let mut acc = DVec3::ZERO;
                        for (&k, &w) in table.indices[a..b].iter().zip(&table.weights[a..b]) {
                            acc += w * even[k as usize];
                        }
                        acc
                    }),
            );
        }
        {
            let (even, pred) = (&*even, &pred[..]);
            // The predicted fine faces' normals, once per face.
            normals.clear();
            normals.par_extend(
                (0..t.num_faces())
                    .into_par_iter()
                    .with_min_len(ODD_CHUNK / 2)
                    .map(|f| child_normals(t, even, pred, f)),
            );
            let normals = &normals[..];
            odd.par_chunks_mut(ODD_CHUNK)
                .enumerate()
                .for_each(|(c, out)| {
                    for (i, d) in out.iter_mut().enumerate() {
                        let e = c * ODD_CHUNK + i;
                        let f = frame_of_edge(t, even, pred, e, |f, c| normals[f][c]);
                        *d = f.to_global(*d);
                    }
                });
        }
        if lifted {
            self.update(level, even, odd, -1.0);
            self.predict_odd(level, even, odd, 1.0);
        } else {
            odd.par_chunks_mut(ODD_CHUNK)
                .zip(pred.par_chunks(ODD_CHUNK))
                .for_each(|(o, p)| o.iter_mut().zip(p).for_each(|(x, p)| *x = *p + *x));
        }
        // The even rows of the table are the identity, applied as `0 + 1 · x` (which turns a
        // −0 into +0, as the allocating synthesis does).
        even.par_chunks_mut(ODD_CHUNK)
            .for_each(|c| c.iter_mut().for_each(|x| *x = DVec3::ZERO + *x));
    }

    /// `odd[e] = sign · odd[e] + (S_j even)_{odd e}` for `sign = 1` (synthesis), or
    /// `odd[e] − (S_j even)_{odd e}` for `sign = −1` (analysis), in place: the odd rows of
    /// level `level`'s table, summed in stencil order as [`StencilTable::apply`] does.
    fn predict_odd(&self, level: usize, even: &[DVec3], odd: &mut [DVec3], sign: f64) {
        let t = &self.tables[level];
        let nc = even.len();
        let pat = self.patterns.get(level).filter(|p| p.rows.len() == t.len());
        odd.par_chunks_mut(ODD_CHUNK)
            .enumerate()
            .for_each(|(c, out)| {
                let first = nc + c * ODD_CHUNK;
                for (i, x) in out.iter_mut().enumerate() {
                    let r = first + i;
                    let (a, b) = (t.offsets[r] as usize, t.offsets[r + 1] as usize);
                    let idx = &t.indices[a..b];
                    let acc = match pat.filter(|p| p.rows[r]) {
                        Some(p) => p.dot(idx, even),
                        None => {
                            let mut acc = DVec3::ZERO;
                            for (&k, &w) in idx.iter().zip(&t.weights[a..b]) {
                                acc += w * even[k as usize];
                            }
                            acc
                        }
                    };
                    if sign > 0.0 {
                        *x += acc;
                    } else {
                        *x -= acc;
                    }
                }
            });
    }

    /// Full analysis of finest-level positions (`V_L` values) down to the base.
    ///
    /// # Errors
    /// As [`TriangleWavelet::analyze_level`].
    pub fn decompose(&self, finest: &[DVec3]) -> Result<Decomposition> {
        let l = self.tables.len();
        Self::check_len("finest", l, finest.len(), self.h.num_vertices(l))?;
        let mut details = vec![Vec::new(); l];
        let mut signal = finest.to_vec();
        for j in (0..l).rev() {
            let (c, d) = self.analyze_level(j, &signal)?;
            details[j] = d;
            signal = c;
        }
        Ok(Decomposition {
            base: signal,
            details,
        })
    }

    /// Full synthesis: the finest level from a decomposition. Missing finer levels of
    /// details (`details.len() < L`) stop the synthesis at level `details.len()`.
    ///
    /// # Errors
    /// As [`TriangleWavelet::synthesize_level`]; more detail levels than the hierarchy has.
    pub fn reconstruct(&self, d: &Decomposition) -> Result<Vec<DVec3>> {
        if d.details.len() > self.tables.len() {
            return Err(Error::InvalidArgument(format!(
                "{} detail levels given, the hierarchy has {}",
                d.details.len(),
                self.tables.len()
            )));
        }
        let mut signal = d.base.clone();
        for (j, det) in d.details.iter().enumerate() {
            signal = self.synthesize_level(j, &signal, det)?;
        }
        Ok(signal)
    }
}

/// The predicted position of vertex `v` of level `j + 1`: `even` (the coarse vertices, as the
/// identity rows of the prediction give them, `0 + x`) then `odd`.
#[inline]
fn predicted(even: &[DVec3], odd: &[DVec3], v: u32) -> DVec3 {
    let nc = even.len();
    if (v as usize) < nc {
        DVec3::ZERO + even[v as usize]
    } else {
        odd[v as usize - nc]
    }
}

/// The Newell normals (as [`odd_vertex_frames`] sums them) of the four children (Maret eq.
/// 5.7) of level-`j` triangle `f`, on the predicted level `j + 1` (`even`, `odd`).
#[inline]
fn child_normals(t: &Topology, even: &[DVec3], odd: &[DVec3], f: usize) -> [DVec3; 4] {
    let fv = t.face_vertices(f);
    let fe = t.face_edges(f);
    // Children (v0 m0 m2), (v1 m1 m0), (v2 m2 m1), (m0 m1 m2), with `m_i` the odd vertex
    // `V_j + fe[i]`: the corners are even and the edge points odd, so [`predicted`]'s
    // test is known here (same values: `0 + x` for the even ones).
    let p = |v: u32| DVec3::ZERO + even[v as usize];
    let q = |e: u32| odd[e as usize];
    let (p0, p1, p2) = (p(fv[0]), p(fv[1]), p(fv[2]));
    let (q0, q1, q2) = (q(fe[0]), q(fe[1]), q(fe[2]));
    let newell = |a: DVec3, b: DVec3, c: DVec3| {
        let mut n = DVec3::ZERO;
        n += a.cross(b);
        n += b.cross(c);
        n += c.cross(a);
        n
    };
    [
        newell(p0, q0, q2),
        newell(p1, q1, q0),
        newell(p2, q2, q1),
        newell(q0, q1, q2),
    ]
}

/// The local frame of the odd vertex of level-`j` edge `e` ([`odd_vertex_frames`]) from the
/// coarse topology `t` alone, with `normal(f, c)` the normal of child `c` of triangle `f`
/// ([`child_normals`]): the fine faces around the odd vertex are the children of `e`'s faces
/// that hold it, summed in fine face order (the order of an unordered fine topology's
/// `vertex_faces`).
#[inline]
fn frame_of_edge(
    t: &Topology,
    even: &[DVec3],
    odd: &[DVec3],
    e: usize,
    normal: impl Fn(usize, usize) -> DVec3,
) -> Frame {
    let mut faces = [0u32; 2];
    let ef = t.edge_faces(e);
    let k = ef.len().min(2);
    faces[..k].copy_from_slice(&ef[..k]);
    if k == 2 && faces[0] > faces[1] {
        faces.swap(0, 1);
    }
    let mut n = DVec3::ZERO;
    for &f in &faces[..k] {
        let which = match t
            .face_edges(f as usize)
            .iter()
            .position(|&x| x as usize == e)
        {
            Some(0) => [0, 1, 3],
            Some(1) => [1, 2, 3],
            _ => [0, 2, 3],
        };
        for c in which {
            n += normal(f as usize, c);
        }
    }
    let [a, b] = t.edge_vertices[e];
    Frame::new(n, predicted(even, odd, b) - predicted(even, odd, a))
}

/// [`frame_of_edge`] computing the child normals on the way.
fn coarse_frame(t: &Topology, even: &[DVec3], odd: &[DVec3], e: usize) -> Frame {
    frame_of_edge(t, even, odd, e, |f, c| child_normals(t, even, odd, f)[c])
}

fn check_tables(h: &Hierarchy, tables: &[StencilTable]) -> Result<()> {
    if tables.len() != h.levels() {
        return Err(Error::InvalidArgument(format!(
            "{} stencil tables given, the hierarchy has {} levels",
            tables.len(),
            h.levels()
        )));
    }
    for (j, t) in tables.iter().enumerate() {
        if t.child_sources != 0 {
            return Err(Error::InvalidArgument(format!(
                "level {j}: the stencil table refers to {} of its own children (a polygon \
                 split's face points); the triangle wavelets take tables over the coarse \
                 vertices only",
                t.child_sources
            )));
        }
        if t.num_sources as usize != h.num_vertices(j) || t.len() != h.num_vertices(j + 1) {
            return Err(Error::InvalidArgument(format!(
                "level {j}: the stencil table maps {} to {} vertices, the hierarchy {} to {}",
                t.num_sources,
                t.len(),
                h.num_vertices(j),
                h.num_vertices(j + 1)
            )));
        }
    }
    Ok(())
}

fn sub(a: &[DVec3], b: &[DVec3]) -> Vec<DVec3> {
    a.par_iter().zip(b).map(|(x, y)| *x - *y).collect()
}

/// Odd vertices per parallel work item of the in-place prediction.
const ODD_CHUNK: usize = 8192;

/// Coarse vertices per parallel work item of the update step.
const UPDATE_CHUNK: usize = 4096;

/// The plan of the update step of the lifted triangle wavelets (built once per hierarchy):
/// per level, the face count `φ_e` of the edge of each (vertex, edge) incidence, aligned with
/// [`Topology::vertex_edges`], so the update reads it sequentially instead of looking up two
/// edge-face offsets per edge. A level whose array is missing (an edge with more than 255
/// faces, or no plan built) falls back to those lookups; the result is the same.
#[derive(Clone, Debug, Default)]
pub(crate) struct UpdatePlan {
    phi: Vec<Vec<u8>>,
}

impl UpdatePlan {
    /// The plan of every level of `h`.
    pub(crate) fn new(h: &Hierarchy) -> Self {
        let phi = (0..h.levels())
            .map(|j| {
                let t = h.topology(j);
                if (0..t.num_edges()).any(|e| t.edge_faces(e).len() > u8::MAX as usize) {
                    return Vec::new();
                }
                t.vertex_edges
                    .par_iter()
                    .with_min_len(UPDATE_CHUNK)
                    .map(|&e| t.edge_faces(e as usize).len() as u8)
                    .collect()
            })
            .collect();
        UpdatePlan { phi }
    }

    /// Runs `f(x, f_v, edges, phi)` in parallel for each coarse vertex `v` of level `level`
    /// (topology `t`) that has faces: `x` its value in `coarse`, `f_v` its face count,
    /// `edges` its [`Topology::vertex_edges`] and `phi` their face counts if the level has a
    /// plan ([`edge_face_count`] reads them either way).
    #[inline]
    pub(crate) fn for_each<T: Send>(
        &self,
        t: &Topology,
        level: usize,
        coarse: &mut [T],
        f: impl Fn(&mut T, usize, &[u32], Option<&[u8]>) + Sync,
    ) {
        let phi = self
            .phi
            .get(level)
            .filter(|p| p.len() == t.vertex_edges.len());
        coarse
            .par_chunks_mut(UPDATE_CHUNK)
            .enumerate()
            .for_each(|(c, out)| {
                let v0 = c * UPDATE_CHUNK;
                let fo = &t.vertex_face_offsets[v0..=v0 + out.len()];
                let eo = &t.vertex_edge_offsets[v0..=v0 + out.len()];
                for (i, x) in out.iter_mut().enumerate() {
                    let nf = (fo[i + 1] - fo[i]) as usize;
                    if nf == 0 {
                        continue;
                    }
                    let (a, b) = (eo[i] as usize, eo[i + 1] as usize);
                    f(x, nf, &t.vertex_edges[a..b], phi.map(|p| &p[a..b]))
                }
            });
    }
}

/// `φ_e` of the `k`-th edge `e` of a vertex in [`UpdatePlan::for_each`].
#[inline(always)]
pub(crate) fn edge_face_count(t: &Topology, phi: Option<&[u8]>, k: usize, e: u32) -> u32 {
    match phi {
        Some(p) => p[k] as u32,
        None => t.edge_faces(e as usize).len() as u32,
    }
}

/// The most common odd-row stencil of a level table (the regular butterfly mask, the
/// midpoint's two halves; built once per hierarchy): the prediction of a flagged row reads its
/// weights from the pattern — the same values in the same order, so the same result bit for
/// bit — instead of streaming them from the table.
#[derive(Clone, Debug, Default)]
pub(crate) struct RowPattern {
    /// The pattern's weights (at most [`RowPattern::MAX`]; empty: no pattern).
    pub(crate) weights: Vec<f64>,
    /// Per table row: whether its weights are the pattern's (even rows: false).
    pub(crate) rows: Vec<bool>,
}

impl RowPattern {
    /// Longest pattern.
    const MAX: usize = 12;

    /// The pattern of `t`'s odd rows: the most frequent weight row among 64 samples.
    pub(crate) fn new(t: &StencilTable) -> Self {
        let nc = t.num_sources as usize;
        let n = t.len();
        if n <= nc {
            return RowPattern::default();
        }
        let row = |r: usize| &t.weights[t.offsets[r] as usize..t.offsets[r + 1] as usize];
        let same = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
        };
        let samples: Vec<&[f64]> = (0..64).map(|i| row(nc + i * (n - nc) / 64)).collect();
        let Some(best) = samples
            .iter()
            .max_by_key(|s| samples.iter().filter(|x| same(x, s)).count())
            .filter(|s| s.len() <= Self::MAX)
        else {
            return RowPattern::default();
        };
        RowPattern {
            weights: best.to_vec(),
            rows: (0..n)
                .into_par_iter()
                .with_min_len(ODD_CHUNK)
                .map(|r| r >= nc && same(row(r), best))
                .collect(),
        }
    }

    /// `Σ w_i x[idx_i]` in order, `w` the pattern (`idx` as long as the pattern).
    #[inline]
    pub(crate) fn dot(&self, idx: &[u32], x: &[DVec3]) -> DVec3 {
        #[inline(always)]
        fn fixed<const M: usize>(w: &[f64; M], idx: &[u32; M], x: &[DVec3]) -> DVec3 {
            let mut acc = DVec3::ZERO;
            for i in 0..M {
                acc += w[i] * x[idx[i] as usize];
            }
            acc
        }
        let w = &self.weights[..];
        if let (Ok(w), Ok(idx)) = (w.try_into(), idx.try_into()) {
            return fixed::<2>(w, idx, x);
        }
        if let (Ok(w), Ok(idx)) = (w.try_into(), idx.try_into()) {
            return fixed::<8>(w, idx, x);
        }
        let mut acc = DVec3::ZERO;
        for (&k, &w) in idx.iter().zip(w) {
            acc += w * x[k as usize];
        }
        acc
    }
}

/// Rows per parallel work item of the solver.
const ROWS: usize = 4096;

/// The square system of the even rows of a level table (`n = num_sources` rows).
struct EvenRows<'a> {
    t: &'a StencilTable,
    inv_diag: Vec<f64>,
}

impl EvenRows<'_> {
    fn new(t: &StencilTable) -> EvenRows<'_> {
        let n = t.num_sources as usize;
        let inv_diag = (0..n)
            .into_par_iter()
            .map(|v| {
                let (a, b) = (t.offsets[v] as usize, t.offsets[v + 1] as usize);
                let d: f64 = (a..b)
                    .filter(|&k| t.indices[k] as usize == v)
                    .map(|k| t.weights[k])
                    .sum();
                if d != 0.0 {
                    1.0 / d
                } else {
                    1.0
                }
            })
            .collect();
        EvenRows { t, inv_diag }
    }

    /// `y = A x`.
    fn mul(&self, x: &[DVec3], y: &mut [DVec3]) {
        let t = self.t;
        y.par_chunks_mut(ROWS).enumerate().for_each(|(c, out)| {
            for (i, o) in out.iter_mut().enumerate() {
                let r = c * ROWS + i;
                let (a, b) = (t.offsets[r] as usize, t.offsets[r + 1] as usize);
                let mut acc = DVec3::ZERO;
                for k in a..b {
                    acc += t.weights[k] * x[t.indices[k] as usize];
                }
                *o = acc;
            }
        });
    }

    /// `y = M⁻¹ x` (Jacobi).
    fn precondition(&self, x: &[DVec3], y: &mut [DVec3]) {
        y.par_iter_mut()
            .with_min_len(ROWS)
            .zip(x)
            .zip(&self.inv_diag)
            .for_each(|((y, x), d)| *y = *d * *x);
    }
}

/// Componentwise dot products of two 3-vector signals, summed in an order that does not
/// depend on the threads' scheduling (fixed chunks of [`ROWS`], then their sums in order;
/// rayon's `sum` associates as the work happens to be split, which changes the last bits
/// from run to run under load).
fn dot3(a: &[DVec3], b: &[DVec3]) -> DVec3 {
    let parts: Vec<DVec3> = a
        .par_chunks(ROWS)
        .zip(b.par_chunks(ROWS))
        .map(|(a, b)| a.iter().zip(b).map(|(x, y)| *x * *y).sum::<DVec3>())
        .collect();
    parts.into_iter().sum()
}

/// The sum of a 3-vector signal, in an order independent of scheduling (as [`dot3`]).
fn sum3(a: &[DVec3]) -> DVec3 {
    let parts: Vec<DVec3> = a
        .par_chunks(ROWS)
        .map(|a| a.iter().sum::<DVec3>())
        .collect();
    parts.into_iter().sum()
}

/// Componentwise max norm.
fn max3(a: &[DVec3]) -> DVec3 {
    a.par_iter()
        .with_min_len(ROWS)
        .map(|x| x.abs())
        .reduce(|| DVec3::ZERO, |a, b| a.max(b))
}

/// Componentwise `a / b`, 0 where `b` is 0 (a converged component stays frozen).
fn div3(a: DVec3, b: DVec3) -> DVec3 {
    let d = |x: f64, y: f64| if y != 0.0 { x / y } else { 0.0 };
    DVec3::new(d(a.x, b.x), d(a.y, b.y), d(a.z, b.z))
}

/// Solves `A c = b` for the even rows `A` of `t` (three right-hand sides, the coordinates,
/// by one BiCGSTAB with componentwise scalars and Jacobi preconditioning), from `c = b`.
/// Returns `Err((iterations, relative residual))` without convergence.
fn solve_even_rows(
    t: &StencilTable,
    b: &[DVec3],
    opts: &SolverOptions,
) -> std::result::Result<Vec<DVec3>, (usize, f64)> {
    let n = b.len();
    if n == 0 {
        return Ok(Vec::new());
    }
    let a = EvenRows::new(t);
    // Rows sum to 1: solve for c − m with b − m (scale-independent tolerance).
    let m = sum3(b) / n as f64;
    let b: Vec<DVec3> = b.par_iter().map(|x| *x - m).collect();
    let scale = max3(&b).max(DVec3::splat(f64::MIN_POSITIVE));
    let tol = opts.tolerance * scale;
    let mut x = b.clone();
    let mut r = vec![DVec3::ZERO; n];
    let (mut p, mut v) = (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n]);
    let (mut y, mut z, mut s, mut tt) = (
        vec![DVec3::ZERO; n],
        vec![DVec3::ZERO; n],
        vec![DVec3::ZERO; n],
        vec![DVec3::ZERO; n],
    );
    let residual = |x: &[DVec3], r: &mut [DVec3]| {
        a.mul(x, r);
        r.par_iter_mut()
            .with_min_len(ROWS)
            .zip(&b)
            .for_each(|(r, b)| *r = *b - *r);
    };
    let rel = |r: DVec3| (r / scale).max_element();
    let mut it = 0;
    // Restarts from the true residual guard against drift of the recursive one.
    for _restart in 0..4 {
        residual(&x, &mut r);
        if max3(&r).cmple(tol).all() {
            return Ok(x.into_par_iter().map(|c| c + m).collect());
        }
        let r0 = r.clone();
        let (mut rho, mut alpha, mut omega) = (DVec3::ONE, DVec3::ONE, DVec3::ONE);
        p.iter_mut().for_each(|q| *q = DVec3::ZERO);
        v.iter_mut().for_each(|q| *q = DVec3::ZERO);
        while it < opts.max_iterations {
            it += 1;
            let rho_new = dot3(&r0, &r);
            let beta = div3(rho_new, rho) * div3(alpha, omega);
            p.par_iter_mut()
                .with_min_len(ROWS)
                .zip(&r)
                .zip(&v)
                .for_each(|((p, r), v)| *p = *r + beta * (*p - omega * *v));
            a.precondition(&p, &mut y);
            a.mul(&y, &mut v);
            alpha = div3(rho_new, dot3(&r0, &v));
            s.par_iter_mut()
                .with_min_len(ROWS)
                .zip(&r)
                .zip(&v)
                .for_each(|((s, r), v)| *s = *r - alpha * *v);
            if max3(&s).cmple(tol).all() {
                x.par_iter_mut()
                    .with_min_len(ROWS)
                    .zip(&y)
                    .for_each(|(x, y)| *x += alpha * *y);
                break;
            }
            a.precondition(&s, &mut z);
            a.mul(&z, &mut tt);
            omega = div3(dot3(&tt, &s), dot3(&tt, &tt));
            x.par_iter_mut()
                .with_min_len(ROWS)
                .zip(&y)
                .zip(&z)
                .for_each(|((x, y), z)| *x += alpha * *y + omega * *z);
            r.par_iter_mut()
                .with_min_len(ROWS)
                .zip(&s)
                .zip(&tt)
                .for_each(|((r, s), t)| *r = *s - omega * *t);
            rho = rho_new;
            if max3(&r).cmple(tol).all() {
                break;
            }
        }
        tracing::debug!(iterations = it, "Loop analysis solve");
        if std::env::var_os("SUBWAVE_SOLVER_TRACE").is_some() {
            eprintln!("BiCGSTAB: {it} iterations, n = {n}");
        }
        if it >= opts.max_iterations {
            break;
        }
    }
    residual(&x, &mut r);
    let res = max3(&r);
    if res.cmple(tol).all() {
        Ok(x.into_par_iter().map(|c| c + m).collect())
    } else {
        Err((it, rel(res)))
    }
}

/// Scratch memory of a local-frame synthesis ([`TriangleWavelet::reconstruct_in_place_with`]):
/// the predicted odd vertices and the predicted fine faces' normals of a level. Its
/// contents never carry over from one synthesis to the next.
#[derive(Clone, Debug, Default)]
pub struct SynthesisScratch {
    pred: Vec<DVec3>,
    normals: Vec<[DVec3; 4]>,
}

impl SynthesisScratch {
    /// Scratch sized for the finest synthesis step of `w` (empty unless `w` is an
    /// interpolating wavelet with local frames, the only synthesis that uses it), every page
    /// written once, so that a synthesis run later does not fault its memory in: a decoder
    /// prepares it beside its coefficient decoding.
    pub fn prepared(w: &TriangleWavelet) -> SynthesisScratch {
        let l = w.tables.len();
        let mut s = SynthesisScratch::default();
        if l == 0
            || !matches!(
                (w.kind, w.frame),
                (Kind::Interpolating { .. }, DetailFrame::Local)
            )
        {
            return s;
        }
        let odd = w.h.num_vertices(l) - w.h.num_vertices(l - 1);
        let faces = w.h.topology(l - 1).num_faces();
        s.pred.resize(odd, DVec3::ZERO);
        s.normals.resize(faces, [DVec3::ZERO; 4]);
        s.pred.clear();
        s.normals.clear();
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;
    use crate::mesh::Mesh;
    use crate::subdivision::subdivide;

    struct Rng(u64);
    impl Rng {
        fn unit(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
        fn vec(&mut self) -> DVec3 {
            DVec3::new(self.unit(), self.unit(), self.unit())
        }
    }

    /// The hierarchy of `base` split `levels` times with finest positions `project`ed from a
    /// smooth parameterisation: the Loop subdivision of `base` (the linear one would have
    /// kinks across the base edges, which wavelets see as O(h) tangential details).
    fn smooth(base: &Mesh, levels: u32, project: impl Fn(DVec3) -> DVec3) -> Hierarchy {
        let opts = SubdivideOptions {
            scheme: Scheme::Loop,
            levels,
            ..Default::default()
        };
        let fine = subdivide(base, &opts).unwrap();
        let p = fine.positions.into_iter().map(project).collect();
        Hierarchy::new(base, levels, Split::Triangles, Some(p)).unwrap()
    }

    /// Unit sphere over an icosahedron.
    fn sphere(levels: u32) -> Hierarchy {
        smooth(&generate::icosahedron(), levels, |p| p.normalize())
    }

    /// Torus (radii 1, 0.4) over a coarse triangulated torus.
    fn torus(levels: u32) -> Hierarchy {
        let (rr, r) = (1.0, 0.4);
        smooth(&generate::torus(rr, r, 12, 8, true), levels, |p| {
            let q = DVec3::new(p.x, p.y, 0.0).normalize() * rr;
            q + (p - q).normalize() * r
        })
    }

    /// A height field over a triangulated grid (with boundary), over the grid's linear
    /// parameterisation (smooth: the grid is planar).
    fn hills(levels: u32) -> Hierarchy {
        let base = generate::grid(3, 3, true);
        let lin = Hierarchy::new(&base, levels, Split::Triangles, None).unwrap();
        let p = lin
            .positions
            .iter()
            .map(|&p| DVec3::new(p.x, p.y, 0.4 * (1.3 * p.x).sin() * (0.9 * p.y).cos()))
            .collect();
        Hierarchy::new(&base, levels, Split::Triangles, Some(p)).unwrap()
    }

    /// [`hills`] over the Loop parameterisation of the grid.
    fn hills_loop(levels: u32) -> Hierarchy {
        smooth(&generate::grid(3, 3, true), levels, |p| {
            DVec3::new(p.x, p.y, 0.4 * (1.3 * p.x).sin() * (0.9 * p.y).cos())
        })
    }

    fn with_noise(h: &Hierarchy, amp: f64, seed: u64) -> Hierarchy {
        let mut rng = Rng(seed);
        let p = h.positions.iter().map(|&p| p + amp * rng.vec()).collect();
        Hierarchy::new(&h.base, h.levels() as u32, Split::Triangles, Some(p)).unwrap()
    }

    fn max_dist(a: &[DVec3], b: &[DVec3]) -> f64 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .map(|(x, y)| x.distance(*y))
            .fold(0.0, f64::max)
    }

    fn diag(p: &[DVec3]) -> f64 {
        let (lo, hi) = p
            .iter()
            .fold((DVec3::MAX, DVec3::MIN), |(l, h), &x| (l.min(x), h.max(x)));
        lo.distance(hi)
    }

    fn wavelets(h: &Hierarchy) -> Vec<(&'static str, TriangleWavelet<'_>)> {
        let mut out = Vec::new();
        for frame in [DetailFrame::Global, DetailFrame::Local] {
            let tag = |g: &'static str, l: &'static str| {
                if frame == DetailFrame::Global {
                    g
                } else {
                    l
                }
            };
            out.push((
                tag("midpoint", "midpoint/local"),
                TriangleWavelet::midpoint(h, false)
                    .unwrap()
                    .with_frame(frame),
            ));
            out.push((
                tag("midpoint-lifted", "midpoint-lifted/local"),
                TriangleWavelet::midpoint(h, true)
                    .unwrap()
                    .with_frame(frame),
            ));
            out.push((
                tag("loop", "loop/local"),
                TriangleWavelet::loop_pgc(h, &SubdivideOptions::default())
                    .unwrap()
                    .with_frame(frame),
            ));
        }
        out
    }

    /// The in-place transforms equal the allocating ones bit for bit (all kinds, both
    /// frames, with boundary), and invert each other.
    #[test]
    fn in_place_equals_allocating() {
        let meshes = [
            ("sphere", with_noise(&sphere(3), 0.02, 11)),
            ("hills", with_noise(&hills(3), 0.02, 12)),
        ];
        for (name, h) in &meshes {
            let mut all = wavelets(h);
            all.push((
                "butterfly-lifted",
                TriangleWavelet::from_scheme(
                    h,
                    &SubdivideOptions {
                        scheme: Scheme::Butterfly,
                        ..Default::default()
                    },
                    true,
                )
                .unwrap(),
            ));
            for (wname, w) in all {
                let flat = w.decompose(&h.positions).unwrap().to_flat();
                let mut data = h.positions.clone();
                w.decompose_in_place(&mut data).unwrap();
                assert!(
                    data.iter()
                        .zip(&flat)
                        .all(|(a, b)| a.to_array() == b.to_array()),
                    "{name} {wname}: in-place analysis differs"
                );
                let d = Decomposition::from_flat(h, &flat).unwrap();
                let back = w.reconstruct(&d).unwrap();
                w.reconstruct_in_place(&mut data).unwrap();
                assert!(
                    data.iter()
                        .zip(&back)
                        .all(|(a, b)| a.to_array() == b.to_array()),
                    "{name} {wname}: in-place synthesis differs"
                );
                let tol = 1e-12 * diag(&h.positions);
                assert!(max_dist(&data, &h.positions) <= tol, "{name} {wname}");
            }
            let w = TriangleWavelet::midpoint(h, true).unwrap();
            assert!(w.decompose_in_place(&mut [DVec3::ZERO; 5]).is_err());
        }
    }

    #[test]
    fn perfect_reconstruction() {
        let meshes = [
            ("sphere", with_noise(&sphere(4), 0.02, 1)),
            ("torus", with_noise(&torus(3), 0.02, 2)),
            ("hills", with_noise(&hills(3), 0.02, 3)),
        ];
        for (name, h) in &meshes {
            let tol = 1e-12 * diag(&h.positions);
            for (wname, w) in wavelets(h) {
                let d = w.decompose(&h.positions).unwrap();
                assert_eq!(d.base.len(), h.num_vertices(0));
                let back = w.reconstruct(&d).unwrap();
                let err = max_dist(&back, &h.positions);
                println!("{name} {wname}: reconstruction error {err:.2e} (bound {tol:.2e})");
                assert!(err <= tol, "{name} {wname}: {err}");
            }
        }
    }

    #[test]
    fn zero_details_is_plain_subdivision() {
        let bases: [Mesh; 3] = [
            generate::icosahedron(),
            generate::torus(1.0, 0.4, 6, 4, true),
            generate::grid(3, 3, true),
        ];
        for (k, base) in bases.iter().enumerate() {
            let mut base = base.clone();
            let mut rng = Rng(10 + k as u64);
            for p in &mut base.positions {
                *p += 0.1 * rng.vec();
            }
            let levels = 3;
            let h = Hierarchy::new(&base, levels, Split::Triangles, None).unwrap();
            let tol = 1e-12 * diag(&base.positions);
            for (scheme, w) in [
                (
                    Scheme::Midpoint,
                    TriangleWavelet::midpoint(&h, false).unwrap(),
                ),
                (
                    Scheme::Midpoint,
                    TriangleWavelet::midpoint(&h, true).unwrap(),
                ),
                (
                    Scheme::Loop,
                    TriangleWavelet::loop_pgc(&h, &SubdivideOptions::default()).unwrap(),
                ),
            ] {
                for frame in [DetailFrame::Global, DetailFrame::Local] {
                    let w = w.clone().with_frame(frame);
                    let d = Decomposition {
                        base: base.positions.clone(),
                        details: (0..levels as usize)
                            .map(|j| vec![DVec3::ZERO; h.topology(j).num_edges()])
                            .collect(),
                    };
                    let got = w.reconstruct(&d).unwrap();
                    let opts = SubdivideOptions {
                        scheme,
                        levels,
                        ..Default::default()
                    };
                    let want = subdivide(&base, &opts).unwrap();
                    assert_eq!(want.face_indices, h.finest_mesh().face_indices);
                    let err = max_dist(&got, &want.positions);
                    assert!(err <= tol, "mesh {k} {scheme:?} {:?}: {err}", w.kind());
                }
            }
        }
    }

    /// Loop analysis of a Loop-subdivided mesh recovers its control mesh with zero details
    /// (an independent check of the solve against the crate's refiner).
    #[test]
    fn loop_analysis_inverts_loop_subdivision() {
        for base in [generate::icosahedron(), generate::grid(3, 2, true)] {
            let mut base = base;
            let mut rng = Rng(99);
            for p in &mut base.positions {
                *p += 0.2 * rng.vec();
            }
            let opts = SubdivideOptions {
                scheme: Scheme::Loop,
                levels: 3,
                ..Default::default()
            };
            let fine = subdivide(&base, &opts).unwrap();
            let h = Hierarchy::new(&base, 3, Split::Triangles, Some(fine.positions)).unwrap();
            let w = TriangleWavelet::loop_pgc(&h, &opts).unwrap();
            let d = w.decompose(&h.positions).unwrap();
            let tol = 1e-12 * diag(&base.positions);
            assert!(max_dist(&d.base, &base.positions) <= tol);
            for det in &d.details {
                assert!(det.iter().all(|x| x.length() <= tol));
            }
        }
    }

    /// The lifted midpoint analysis keeps the topological integral `Σ_v f_v x_v 4^{-j}`.
    #[test]
    fn lifting_preserves_the_integral() {
        for h in [
            with_noise(&sphere(3), 0.05, 4),
            with_noise(&hills(3), 0.05, 5),
        ] {
            let w = TriangleWavelet::midpoint(&h, true).unwrap();
            let integral = |j: usize, x: &[DVec3]| {
                let t = h.topology(j);
                let s: DVec3 = (0..x.len())
                    .map(|v| t.vertex_faces(v).len() as f64 * x[v])
                    .sum();
                s / 4f64.powi(j as i32)
            };
            let mut x = h.positions.clone();
            let i_fine = integral(h.levels(), &x);
            for j in (0..h.levels()).rev() {
                let (c, _) = w.analyze_level(j, &x).unwrap();
                assert!((integral(j, &c) - i_fine).length() < 1e-9 * i_fine.length().max(1.0));
                x = c;
            }
            // The unlifted (lazy) midpoint wavelet does not keep it.
            let lazy = TriangleWavelet::midpoint(&h, false).unwrap();
            let (c, _) = lazy.analyze_level(h.levels() - 1, &h.positions).unwrap();
            assert!((integral(h.levels() - 1, &c) - i_fine).length() > 1e-6);
        }
    }

    fn mean_len(d: &[DVec3]) -> f64 {
        d.iter().map(|x| x.length()).sum::<f64>() / d.len() as f64
    }

    #[test]
    fn energy_compaction_on_a_smooth_surface() {
        let h = sphere(4);
        for (name, w) in wavelets(&h) {
            let d = w.decompose(&h.positions).unwrap();
            let means: Vec<f64> = d.details.iter().map(|x| mean_len(x)).collect();
            let ratio = means[0] / means[3];
            let shown: Vec<String> = means.iter().map(|m| format!("{m:.3e}")).collect();
            println!(
                "sphere {name}: mean |detail| per level {shown:?}, coarsest/finest {ratio:.1}"
            );
            assert!(ratio >= 10.0, "{name}: {ratio}");
        }
    }

    /// On smooth surfaces the normal carries most of the detail energy. "Smooth" is relative
    /// to the scheme's parameterisation: sphere and torus are sampled over the Loop
    /// parameterisation of their base mesh (smooth everywhere: closed), the height field over
    /// the grid's linear parameterisation for the interpolating wavelets and over its Loop
    /// parameterisation for Loop (Loop with crease boundaries rounds the square's corners,
    /// so linear samples there are tangential details for Loop, and the converse for
    /// midpoint: measured 4% and 48% normal energy for the mismatched pairs).
    #[test]
    fn local_frames_concentrate_energy_in_the_normal() {
        let (sphere, torus, hills, hills_loop) = (sphere(4), torus(3), hills(3), hills_loop(3));
        for (mname, h) in [
            ("sphere", &sphere),
            ("torus", &torus),
            ("hills", &hills),
            ("hills", &hills_loop),
        ] {
            for (name, w) in wavelets(h) {
                let is_loop = w.kind() == Kind::Loop;
                if !name.ends_with("/local")
                    || std::ptr::eq(h, &hills) && is_loop
                    || std::ptr::eq(h, &hills_loop) && !is_loop
                {
                    continue;
                }
                let d = w.decompose(&h.positions).unwrap();
                let share = |det: &[DVec3]| {
                    let n: f64 = det.iter().map(|x| x.x * x.x).sum();
                    let t: f64 = det.iter().map(|x| x.length_squared()).sum();
                    (n, t)
                };
                let levels: Vec<String> = d
                    .details
                    .iter()
                    .map(|x| {
                        let (n, t) = share(x);
                        format!("{:.3}", n / t)
                    })
                    .collect();
                let (n, t) = share(&d.details.concat());
                let ratio = n / t;
                println!(
                    "{mname} {name}: normal share of detail energy {ratio:.4} (per level {levels:?})"
                );
                assert!(ratio > 0.5, "{mname} {name}: {ratio}");
            }
        }
    }

    /// The interpolating hook with a plugged table (midpoint weights perturbed into a
    /// 4-point rule over the edge's two faces, a stand-in for butterfly): perfect
    /// reconstruction lifted and unlifted, and non-interpolating tables are refused.
    #[test]
    fn butterfly_hook_with_a_plugged_table() {
        let h = with_noise(&sphere(3), 0.02, 7);
        let tables: Vec<StencilTable> = (0..h.levels())
            .map(|j| {
                let t = h.topology(j);
                let nv = t.num_vertices;
                let mut tab = StencilTable {
                    num_sources: nv,
                    child_sources: 0,
                    offsets: vec![0],
                    ..Default::default()
                };
                for v in 0..nv {
                    tab.indices.push(v);
                    tab.weights.push(1.0);
                    tab.offsets.push(tab.indices.len() as u32);
                }
                for e in 0..t.num_edges() {
                    let [a, b] = t.edge_vertices[e];
                    tab.indices.extend([a, b]);
                    tab.weights.extend([0.5, 0.5]);
                    for &f in t.edge_faces(e) {
                        let o = *t
                            .face_vertices(f as usize)
                            .iter()
                            .find(|&&x| x != a && x != b)
                            .unwrap();
                        tab.indices.extend([o, a, b]);
                        tab.weights.extend([0.125, -0.0625, -0.0625]);
                    }
                    tab.offsets.push(tab.indices.len() as u32);
                }
                tab
            })
            .collect();
        let tol = 1e-12 * diag(&h.positions);
        for lifted in [false, true] {
            let w = TriangleWavelet::interpolating(&h, tables.clone(), lifted)
                .unwrap()
                .with_frame(DetailFrame::Local);
            let d = w.decompose(&h.positions).unwrap();
            assert!(max_dist(&w.reconstruct(&d).unwrap(), &h.positions) <= tol);
        }
        let lp = TriangleWavelet::loop_pgc(&h, &SubdivideOptions::default()).unwrap();
        let e = TriangleWavelet::interpolating(&h, lp.tables().to_vec(), false).unwrap_err();
        assert!(e.to_string().contains("not interpolating"), "{e}");
        // A table that refers to its own children (a polygon split's) is refused.
        let mut own = tables.clone();
        own[0].child_sources = 1;
        let e = TriangleWavelet::interpolating(&h, own, false).unwrap_err();
        assert!(e.to_string().contains("its own children"), "{e}");
    }

    #[test]
    fn from_scheme_midpoint() {
        let h = with_noise(&hills(2), 0.01, 12);
        let opts = SubdivideOptions {
            scheme: Scheme::Midpoint,
            ..Default::default()
        };
        for lifted in [false, true] {
            let a = TriangleWavelet::from_scheme(&h, &opts, lifted).unwrap();
            let b = TriangleWavelet::midpoint(&h, lifted).unwrap();
            assert_eq!(a.tables(), b.tables());
            let d = a.decompose(&h.positions).unwrap();
            assert_eq!(d, b.decompose(&h.positions).unwrap());
            // The flat layout round-trips.
            let flat = d.to_flat();
            assert_eq!(flat.len(), h.positions.len());
            assert_eq!(Decomposition::from_flat(&h, &flat).unwrap(), d);
        }
        let e = TriangleWavelet::from_scheme(&h, &SubdivideOptions::default(), false).unwrap_err();
        assert!(e.to_string().contains("not interpolating"), "{e}");
    }

    #[test]
    fn detected_hierarchy_runs_the_wavelets() {
        // Shuffled input → detect → analyse → synthesise → map back.
        let h = with_noise(&sphere(3), 0.01, 8);
        let m = h.finest_mesh();
        let n = m.num_vertices();
        let perm: Vec<u32> = (0..n as u32).map(|i| (i * 7919 + 13) % n as u32).collect();
        let mut pos = vec![DVec3::ZERO; n];
        for (old, &new) in perm.iter().enumerate() {
            pos[new as usize] = m.positions[old];
        }
        let mut tris: Vec<[u32; 3]> = m
            .faces()
            .map(|f| [f[1], f[2], f[0]].map(|v| perm[v as usize]))
            .collect();
        tris.reverse();
        let shuffled = Mesh::from_triangles(pos, &tris);
        let (d, r) = Hierarchy::detect(&shuffled, None).unwrap();
        assert_eq!(d.levels(), 3);
        let w = TriangleWavelet::loop_pgc(&d, &SubdivideOptions::default()).unwrap();
        let dec = w.decompose(&d.positions).unwrap();
        let back = r.to_input(&w.reconstruct(&dec).unwrap());
        assert!(max_dist(&back, &shuffled.positions) <= 1e-12 * diag(&back));
    }

    /// Timing of the finest Loop analysis level near a million vertices (run with
    /// `cargo test --release -p subwave --lib loop_analysis_timing -- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn loop_analysis_timing() {
        let t0 = std::time::Instant::now();
        let h = with_noise(&sphere(8), 1e-4, 11);
        let w = TriangleWavelet::loop_pgc(&h, &SubdivideOptions::default()).unwrap();
        println!(
            "setup ({} vertices): {:.2} s",
            h.positions.len(),
            t0.elapsed().as_secs_f64()
        );
        let l = h.levels() - 1;
        let t = std::time::Instant::now();
        let (c, d) = w.analyze_level(l, &h.positions).unwrap();
        println!(
            "Loop analysis, finest level: {:.3} s",
            t.elapsed().as_secs_f64()
        );
        let t = std::time::Instant::now();
        let back = w.synthesize_level(l, &c, &d).unwrap();
        println!(
            "Loop synthesis, finest level: {:.3} s",
            t.elapsed().as_secs_f64()
        );
        assert!(max_dist(&back, &h.positions) < 1e-12 * 2.0);
        let t = std::time::Instant::now();
        let dec = w.decompose(&h.positions).unwrap();
        println!(
            "Loop full decomposition: {:.3} s",
            t.elapsed().as_secs_f64()
        );
        let m = TriangleWavelet::midpoint(&h, true).unwrap();
        let t = std::time::Instant::now();
        let _ = m.decompose(&h.positions).unwrap();
        println!(
            "lifted midpoint full decomposition: {:.3} s",
            t.elapsed().as_secs_f64()
        );
        let t = std::time::Instant::now();
        let (dh, _) = Hierarchy::detect(&h.finest_mesh(), None).unwrap();
        println!(
            "detection ({} levels): {:.2} s",
            dh.levels(),
            t.elapsed().as_secs_f64()
        );
        drop(dec);
    }

    #[test]
    fn bad_arguments_are_errors() {
        let h = sphere(2);
        let w = TriangleWavelet::midpoint(&h, true).unwrap();
        assert!(w.analyze_level(2, &h.positions).is_err());
        assert!(w.analyze_level(1, &h.positions[..10]).is_err());
        assert!(w.synthesize_level(0, &h.positions[..12], &[]).is_err());
        let q = Hierarchy::new(&generate::cube(), 1, Split::Polygons, None).unwrap();
        assert!(TriangleWavelet::midpoint(&q, false).is_err());
    }
}

/// Butterfly wavelets (unlifted and lifted) through the interpolating-scheme hook.
#[cfg(test)]
mod butterfly_wavelets {
    use super::*;
    use crate::generate;
    /// The in-place synthesis with local frames (frames from the coarse topology, on a
    /// hierarchy whose finest level holds faces only, as the decoder builds it) equals,
    /// bit for bit, the per-level synthesis of the full hierarchy with the frames of the
    /// fine topology (`odd_vertex_frames`), the refiner's tables and `StencilTable::apply`,
    /// including the signs of zeros.
    #[test]
    fn in_place_local_synthesis_equals_the_reference() {
        let opts = SubdivideOptions {
            scheme: Scheme::Butterfly,
            ..Default::default()
        };
        let mut state = 5u64;
        let mut unit = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for base in [
            generate::icosahedron(),
            generate::grid(3, 2, true),
            generate::torus(1.0, 0.4, 6, 5, true),
            generate::disk(7),
        ] {
            let full = Hierarchy::new(&base, 3, Split::Triangles, None).unwrap();
            let skeleton = Hierarchy::skeleton(&base, 3, Split::Triangles).unwrap();
            assert!(skeleton.positions.is_empty());
            for j in 0..3 {
                let (a, b) = (full.topology(j), skeleton.topology(j));
                assert_eq!(a.face_edges, b.face_edges);
                assert_eq!(a.vertex_faces, b.vertex_faces);
                assert_eq!(a.vertex_edges, b.vertex_edges);
            }
            assert_eq!(
                full.topology(3).face_vertices,
                skeleton.topology(3).face_vertices
            );
            assert_eq!(full.num_vertices(3), skeleton.num_vertices(3));
            let n = full.num_vertices(3);
            let mut flat: Vec<DVec3> = (0..n).map(|_| DVec3::new(unit(), unit(), unit())).collect();
            // Zeros of both signs, in coarse positions and details.
            flat[1] = DVec3::new(-0.0, 0.0, -0.0);
            flat[n - 1] = DVec3::new(-0.0, -0.0, 0.0);
            flat[n / 2] = DVec3::ZERO;
            for lifted in [false, true] {
                for midpoint in [false, true] {
                    let (slow, fast) = if midpoint {
                        (
                            TriangleWavelet::midpoint(&full, lifted).unwrap(),
                            TriangleWavelet::midpoint(&skeleton, lifted).unwrap(),
                        )
                    } else {
                        (
                            TriangleWavelet::from_scheme(&full, &opts, lifted).unwrap(),
                            TriangleWavelet::butterfly(&skeleton, lifted).unwrap(),
                        )
                    };
                    let fast = fast.with_frame(DetailFrame::Local);
                    // Reference: level by level on the full hierarchy.
                    let mut signal = flat[..full.num_vertices(0)].to_vec();
                    for j in 0..3 {
                        let nc = full.num_vertices(j);
                        let details = &flat[nc..full.num_vertices(j + 1)];
                        let table = &slow.tables()[j];
                        let p = table.apply(&signal);
                        let frames = odd_vertex_frames(full.topology(j), full.topology(j + 1), &p);
                        let global: Vec<DVec3> = details
                            .iter()
                            .zip(&frames)
                            .map(|(d, f)| f.to_global(*d))
                            .collect();
                        let mut fine = if lifted {
                            let mut even = signal.clone();
                            slow.update(j, &mut even, &global, -1.0);
                            table.apply(&even)
                        } else {
                            p
                        };
                        for (x, d) in fine[nc..].iter_mut().zip(&global) {
                            *x += *d;
                        }
                        signal = fine;
                    }
                    let mut data = flat.clone();
                    fast.reconstruct_in_place(&mut data).unwrap();
                    let bits = |v: &[DVec3]| -> Vec<[u64; 3]> {
                        v.iter()
                            .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
                            .collect()
                    };
                    assert!(
                        bits(&data) == bits(&signal),
                        "lifted {lifted}, midpoint {midpoint}: the syntheses differ"
                    );
                    // The same with prepared scratch memory, and with scratch memory that
                    // holds another synthesis' leftovers.
                    let mut scratch = SynthesisScratch::prepared(&fast);
                    for _ in 0..2 {
                        let mut again = flat.clone();
                        fast.reconstruct_in_place_with(&mut again, &mut scratch)
                            .unwrap();
                        assert!(bits(&again) == bits(&signal), "scratch changes the result");
                    }
                }
            }
        }
    }

    /// The butterfly tables built from the hierarchy's topologies equal the refiner's, bit
    /// for bit, on closed and open meshes with valences 3 to 8 and more, tiny meshes whose
    /// stencils repeat vertices, and a hierarchy in another vertex order.
    #[test]
    fn butterfly_tables_equal_the_refiners() {
        let tri = |m: crate::mesh::Mesh| {
            crate::mesh::Mesh::from_triangles(m.positions.clone(), &m.triangulate().0)
        };
        let bases = [
            generate::tetrahedron(),
            generate::icosahedron(),
            generate::grid(3, 2, true),
            generate::grid(1, 1, true),
            generate::torus(1.0, 0.4, 8, 6, true),
            generate::torus(1.0, 0.4, 3, 3, true),
            generate::triangle_grid(3),
            generate::disk(7),
            generate::disk(3),
            tri(generate::cube()),
            tri(generate::pyramid()),
        ];
        let opts = SubdivideOptions {
            scheme: Scheme::Butterfly,
            ..Default::default()
        };
        for (i, base) in bases.iter().enumerate() {
            let h = Hierarchy::new(base, 3, Split::Triangles, None).unwrap();
            let fast = TriangleWavelet::butterfly(&h, true).unwrap();
            let slow = TriangleWavelet::from_scheme(&h, &opts, true).unwrap();
            assert_eq!(fast.tables().len(), 3);
            for (j, (a, b)) in fast.tables().iter().zip(slow.tables()).enumerate() {
                assert!(a == b, "mesh {i}, level {j}: the tables differ");
            }
        }
        // A detected hierarchy (its own vertex order).
        let fine = crate::subdivision::subdivide(
            &generate::icosahedron(),
            &SubdivideOptions {
                scheme: Scheme::Midpoint,
                levels: 2,
                ..Default::default()
            },
        )
        .unwrap();
        let (h, _) = Hierarchy::detect(&fine, None).unwrap();
        let fast = TriangleWavelet::butterfly(&h, false).unwrap();
        let slow = TriangleWavelet::from_scheme(&h, &opts, false).unwrap();
        assert!(fast.tables() == slow.tables());
    }

    #[test]
    fn butterfly_wavelets_reconstruct_and_equal_butterfly_subdivision() {
        for base in [
            generate::icosahedron(),
            generate::grid(3, 3, true),
            generate::torus(1.0, 0.4, 8, 6, true),
        ] {
            let lin = Hierarchy::new(&base, 3, Split::Triangles, None).unwrap();
            let p: Vec<DVec3> = lin
                .positions
                .iter()
                .enumerate()
                .map(|(i, &p)| {
                    p + 0.01
                        * DVec3::new(
                            (i as f64).sin(),
                            (i as f64 * 1.7).cos(),
                            (i as f64 * 0.3).sin(),
                        )
                })
                .collect();
            let h = Hierarchy::new(&base, 3, Split::Triangles, Some(p)).unwrap();
            let opts = SubdivideOptions {
                scheme: Scheme::Butterfly,
                ..Default::default()
            };
            for lifted in [false, true] {
                for frame in [DetailFrame::Global, DetailFrame::Local] {
                    let w = TriangleWavelet::from_scheme(&h, &opts, lifted)
                        .unwrap()
                        .with_frame(frame);
                    let d = w.decompose(&h.positions).unwrap();
                    let back = w.reconstruct(&d).unwrap();
                    let err = back
                        .iter()
                        .zip(&h.positions)
                        .map(|(a, b)| a.distance(*b))
                        .fold(0.0, f64::max);
                    // zero details = butterfly subdivision
                    let z = Decomposition {
                        base: d.base.clone(),
                        details: d
                            .details
                            .iter()
                            .map(|x| vec![DVec3::ZERO; x.len()])
                            .collect(),
                    };
                    let mut bm = h.base.clone();
                    bm.positions = d.base.clone();
                    let want =
                        crate::subdivision::subdivide(&bm, &SubdivideOptions { levels: 3, ..opts })
                            .unwrap();
                    let zerr = w
                        .clone()
                        .with_frame(DetailFrame::Global)
                        .reconstruct(&z)
                        .unwrap()
                        .iter()
                        .zip(&want.positions)
                        .map(|(a, b)| a.distance(*b))
                        .fold(0.0, f64::max);
                    println!("butterfly lifted={lifted} {frame:?}: recon {err:.2e}, zero-detail vs subdivide {zerr:.2e}");
                    assert!(err < 1e-12 && zerr < 1e-12);
                }
            }
        }
    }
}

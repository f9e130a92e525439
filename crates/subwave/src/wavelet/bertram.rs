//! Generalized B-spline subdivision-surface wavelets (Bertram, Duchaineau, Hamann & Joy,
//! "Generalized B-spline Subdivision-surface Wavelets for Geometry Compression").
//!
//! # The construction
//! The one-dimensional linear, cubic and quintic B-spline wavelets of §3.3 are sequences of
//! *s-lift* and *w-lift* operations (eqs. 3.9, 3.10; parameters in Table 1). §4.2 generalizes
//! each operation to a mesh with Catmull-Clark connectivity (§4.1, Fig. 7): the fine level's
//! vertices are `v` (one per coarse vertex, the scaling coefficients), `e` (one per coarse
//! edge) and `f` (one per coarse face) — the wavelet coefficients. With the averaging
//! operators of §4.1 (Fig. 8: `f̄_v` the mean of the `f` vertices of the faces around `v`,
//! `ē_v` of the `e` vertices of its edges, `v̄_f`/`ē_f` of a face's corners/edges, `v̄_e` the
//! midpoint of an edge, `f̄_e` the mean of its one or two faces' `f` vertices):
//!
//! ```text
//! s-lift(a, b):  v ← b² v + 4a² f̄_v + 4ab ē_v;   then  e ← b e + 2a f̄_e      (4.5)
//! w-lift(a, b):  f ← b² f + 4a² v̄_f + 4ab ē_f;   then  e ← b e + 2a v̄_e      (4.6)
//! ```
//!
//! (each right-hand side reads the values before the operation; on a rectilinear grid this is
//! exactly the tensor product of the 1-D lift applied to the rows, then the columns, eqs.
//! 4.3/4.4 — tested). The averages divide by the actual number of neighbours, so the total
//! weight of each update is independent of the valence (§4.2): extraordinary vertices and
//! non-quad base faces need no special rule. The analysis (DWT) applies Table 1's lifts in
//! order; the synthesis undoes each vertex modification exactly, in reverse order (§4.2, last
//! paragraph) — on interior vertices that is the lift `(−a/b, 1/b)` of Table 1's lower half.
//! With zero details the synthesis is a stationary subdivision scheme (§4.2, §5.1): bilinear
//! for the linear wavelet, the MLCA scheme for the cubic one (eq. 4.7; equal to Catmull-Clark
//! at valence 4), biquintic B-splines on regular grids for the quintic one.
//!
//! # Boundaries
//! The paper treats only closed meshes; its averaging operators are nonetheless defined on a
//! boundary (the mean over the neighbours that exist), and [`Boundary::Averages`] (the
//! default) uses them unchanged: a boundary edge's `f̄_e` is its single face's `f` vertex.
//! [`Boundary::Symmetric`] changes one operator so that a rectilinear grid *with boundary*
//! reproduces the tensor product of the 1-D transform with whole-sample symmetric extension at
//! the ends (the usual boundary of symmetric biorthogonal wavelets): at a boundary vertex with
//! interior edges, `ē_v` is half the mean over its boundary edges plus half the mean over its
//! interior edges. Both are exactly invertible; neither makes the boundary curve a B-spline
//! curve of the boundary vertices alone (the interior pulls on it, as in a mirrored grid).
//!
//! # Integer transform (§4.3)
//! Eqs. 4.8–4.11: each update adds the rounded (`[x]` = nearest integer, ties up) average term,
//! so the inverse subtracts the very same integer. The last s-lift of the cubic (quintic)
//! construction has `a` and `b` divided by 2 (4) so that every `b` is 1 ([`IntLift`],
//! [`Degree::integer_lifts`]): coarse coefficients shrink by 4 (16) per level, details stay
//! integers, and the inverse is exact for any integer input. Arithmetic is in `i128`; a
//! coefficient that does not fit the coordinate type is an error, never a wrap.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::floor_div_const_small;

use crate::mesh::Mesh;
use crate::subdivision::stencil::Interpolate;
use crate::subdivision::{Refinement, Scheme, SubdivideOptions};
use crate::topology::Topology;
use crate::{Error, Result};

/// Elements per parallel work item.
const MIN_LEN: usize = 2048;

/// Polynomial degree of the B-spline scaling functions (§3.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Degree {
    /// Linear B-splines (§3.3.1): two lifts; synthesis with zero details is bilinear
    /// subdivision.
    Linear,
    /// Cubic B-splines (§3.3.2): three lifts; synthesis with zero details is MLCA (eq. 4.7).
    Cubic,
    /// Quintic B-splines (§3.3.2): four lifts; unstable as a low-pass filter (§5.2).
    Quintic,
}

/// Which coefficients a lifting operation modifies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LiftKind {
    /// s-lift (eqs. 3.9, 4.5): modifies the scaling (`v`) coefficients from the `e`/`f`
    /// details, then the `e` coefficients from the `f` ones.
    S,
    /// w-lift (eqs. 3.10, 4.6): modifies the `f` coefficients from the `v`/`e` ones, then the
    /// `e` coefficients from the `v` ones.
    W,
}

/// A floating-point lifting operation `s-lift(a, b)` or `w-lift(a, b)` (Table 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lift {
    /// s- or w-lift.
    pub kind: LiftKind,
    /// Weight of the neighbours.
    pub a: f64,
    /// Weight of the coefficient itself (non-zero).
    pub b: f64,
}

/// An integer lifting operation (eqs. 4.8, 4.9) with `a = a_num / a_den` and integer `b`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IntLift {
    /// s- or w-lift.
    pub kind: LiftKind,
    /// Numerator of `a`.
    pub a_num: i64,
    /// Denominator of `a` (positive).
    pub a_den: i64,
    /// Integer weight of the coefficient itself (1 in every table here, §4.3).
    pub b: i64,
}

const fn lift(kind: LiftKind, a: f64, b: f64) -> Lift {
    Lift { kind, a, b }
}

const fn ilift(kind: LiftKind, a_num: i64, a_den: i64) -> IntLift {
    IntLift {
        kind,
        a_num,
        a_den,
        b: 1,
    }
}

use LiftKind::{S, W};

const LINEAR: [Lift; 2] = [lift(W, -0.5, 1.0), lift(S, 0.25, 1.0)];
const CUBIC: [Lift; 3] = [lift(S, -0.25, 1.0), lift(W, -1.0, 1.0), lift(S, 0.375, 2.0)];
const QUINTIC: [Lift; 4] = [
    lift(W, -1.0 / 6.0, 1.0),
    lift(S, -0.5625, 1.0),
    lift(W, -4.0 / 3.0, 1.0),
    lift(S, 0.625, 4.0),
];
const INT_LINEAR: [IntLift; 2] = [ilift(W, -1, 2), ilift(S, 1, 4)];
const INT_CUBIC: [IntLift; 3] = [ilift(S, -1, 4), ilift(W, -1, 1), ilift(S, 3, 16)];
const INT_QUINTIC: [IntLift; 4] = [
    ilift(W, -1, 6),
    ilift(S, -9, 16),
    ilift(W, -4, 3),
    ilift(S, 5, 32),
];

impl Degree {
    /// All degrees, ascending.
    pub const ALL: [Degree; 3] = [Degree::Linear, Degree::Cubic, Degree::Quintic];

    /// Lower-case name (`linear`, `cubic`, `quintic`).
    pub fn name(self) -> &'static str {
        match self {
            Degree::Linear => "linear",
            Degree::Cubic => "cubic",
            Degree::Quintic => "quintic",
        }
    }

    /// The analysis (DWT) lifts in order of computation: Table 1, upper half.
    pub fn analysis_lifts(self) -> &'static [Lift] {
        match self {
            Degree::Linear => &LINEAR,
            Degree::Cubic => &CUBIC,
            Degree::Quintic => &QUINTIC,
        }
    }

    /// The synthesis (inverse DWT) lifts in order of computation, `(−a/b, 1/b)` of the analysis
    /// lifts in reverse order: Table 1, lower half. (The implementation inverts each vertex
    /// modification exactly instead, which equals these lifts away from boundaries.)
    pub fn synthesis_lifts(self) -> Vec<Lift> {
        self.analysis_lifts()
            .iter()
            .rev()
            .map(|l| lift(l.kind, -l.a / l.b, 1.0 / l.b))
            .collect()
    }

    /// The integer analysis lifts of §4.3: Table 1 with `a` and `b` of the last s-lift divided
    /// by 2 (cubic) or 4 (quintic), so that every `b` is 1.
    pub fn integer_lifts(self) -> &'static [IntLift] {
        match self {
            Degree::Linear => &INT_LINEAR,
            Degree::Cubic => &INT_CUBIC,
            Degree::Quintic => &INT_QUINTIC,
        }
    }
}

/// Boundary treatment (the paper covers closed meshes only; see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Boundary {
    /// The §4.1 averaging operators unchanged: means over the neighbours that exist.
    #[default]
    Averages,
    /// As `Averages`, except that `ē_v` at a boundary vertex weighs its boundary edges and its
    /// interior edges one half each: a rectilinear grid with boundary then reproduces the
    /// tensor product of the 1-D transform with symmetric extension.
    Symmetric,
}

/// Integer coordinate types of the integer transform (`i32`, `i64`).
pub trait IntCoord: Copy + Send + Sync + Into<i128> + TryFrom<i128> {
    /// Type name for error messages.
    const NAME: &'static str;
}

impl IntCoord for i32 {
    const NAME: &'static str = "i32";
}

impl IntCoord for i64 {
    const NAME: &'static str = "i64";
}

/// A generalized B-spline wavelet transform: degree and boundary rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BSplineWavelet {
    /// Degree of the B-splines.
    pub degree: Degree,
    /// Boundary treatment.
    pub boundary: Boundary,
}

impl BSplineWavelet {
    /// The transform of `degree` with the default boundary rule ([`Boundary::Averages`]).
    pub fn new(degree: Degree) -> Self {
        BSplineWavelet {
            degree,
            boundary: Boundary::default(),
        }
    }

    /// One analysis step (§4.2, Table 1): `data` holds the level refined from `coarse`
    /// (`V + E + F` entries, ordering contract of [`crate::subdivision::refine`]); afterwards
    /// the first `V` entries are the coarse positions and the others the detail coefficients of
    /// the edge and face vertices.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `data` does not have `V + E + F` entries.
    pub fn analyze_level<T: Interpolate>(&self, coarse: &Topology, data: &mut [T]) -> Result<()> {
        check_len(coarse, data.len())?;
        let ctx = Ctx::new(coarse, self.boundary);
        for l in self.degree.analysis_lifts() {
            ctx.lift(*l, data);
        }
        Ok(())
    }

    /// One synthesis step, the exact inverse of [`BSplineWavelet::analyze_level`]: each vertex
    /// modification undone in reverse order (eqs. 4.5/4.6 solved for the old value).
    ///
    /// # Errors
    /// As [`BSplineWavelet::analyze_level`].
    pub fn synthesize_level<T: Interpolate>(
        &self,
        coarse: &Topology,
        data: &mut [T],
    ) -> Result<()> {
        check_len(coarse, data.len())?;
        let ctx = Ctx::new(coarse, self.boundary);
        for l in self.degree.analysis_lifts().iter().rev() {
            ctx.unlift(*l, data);
        }
        Ok(())
    }

    /// The full analysis of a hierarchy, in place: `levels[j]` is the topology of level `j`
    /// (as [`Refinement::topologies`] of a polygon split), `data` the finest level
    /// (`levels.len()` splits of `levels[0]`). Afterwards `data` is `[base | details of level
    /// 0 | details of level 1 | …]` (see [`detail_range`]).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if the levels are not successive polygon splits or `data`
    /// has the wrong length.
    pub fn analyze<T: Interpolate>(&self, levels: &[Topology], data: &mut [T]) -> Result<()> {
        let sizes = level_sizes(levels)?;
        check_total(&sizes, data.len())?;
        for (j, topo) in levels.iter().enumerate().rev() {
            self.analyze_level(topo, &mut data[..sizes[j + 1]])?;
        }
        Ok(())
    }

    /// The full synthesis, inverse of [`BSplineWavelet::analyze`].
    ///
    /// # Errors
    /// As [`BSplineWavelet::analyze`].
    pub fn synthesize<T: Interpolate>(&self, levels: &[Topology], data: &mut [T]) -> Result<()> {
        let sizes = level_sizes(levels)?;
        check_total(&sizes, data.len())?;
        for (j, topo) in levels.iter().enumerate() {
            self.synthesize_level(topo, &mut data[..sizes[j + 1]])?;
        }
        Ok(())
    }

    /// Subdivision: the synthesis of `base` (one value per vertex of `levels[0]`) with all
    /// details zero (§4.2, §5.1), returning the finest level.
    ///
    /// # Errors
    /// As [`BSplineWavelet::analyze`], or if `base` has the wrong length.
    pub fn subdivide<T: Interpolate>(&self, levels: &[Topology], base: &[T]) -> Result<Vec<T>> {
        let sizes = level_sizes(levels)?;
        if base.len() != sizes[0] {
            return Err(Error::InvalidArgument(format!(
                "{} base values given, the base mesh has {} vertices",
                base.len(),
                sizes[0]
            )));
        }
        let mut data = Vec::with_capacity(*sizes.last().unwrap_or(&0));
        data.extend_from_slice(base);
        data.resize(*sizes.last().unwrap_or(&0), T::zero());
        self.synthesize(levels, &mut data)?;
        Ok(data)
    }

    /// One integer analysis step (eqs. 4.8, 4.9 with the §4.3 rescaling): as
    /// [`BSplineWavelet::analyze_level`] on integer coordinates.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `data` has the wrong length or a coefficient overflows
    /// `I` (the message names the vertex).
    pub fn analyze_level_int<I: IntCoord>(
        &self,
        coarse: &Topology,
        data: &mut [[I; 3]],
    ) -> Result<()> {
        self.analyze_level_int_with(coarse, data, false).map(|_| ())
    }

    /// [`BSplineWavelet::analyze_level_int`], skipping the scan if every value of `data` is
    /// known to lie within [`FAST_BOUND`] (`known_small`); returns whether the coarse part
    /// left in `data[..V]` does.
    fn analyze_level_int_with<I: IntCoord>(
        &self,
        coarse: &Topology,
        data: &mut [[I; 3]],
        known_small: bool,
    ) -> Result<bool> {
        check_len(coarse, data.len())?;
        let ctx = Ctx::new(coarse, self.boundary);
        let mut small = if known_small {
            Small::ALL
        } else {
            Small::scan(coarse, data, false)
        };
        for l in self.degree.integer_lifts() {
            ctx.int_lift_tracked(*l, data, false, &mut small)?;
        }
        Ok(small.v)
    }

    /// One integer synthesis step (eqs. 4.10, 4.11), the exact inverse of
    /// [`BSplineWavelet::analyze_level_int`].
    ///
    /// # Errors
    /// As [`BSplineWavelet::analyze_level_int`].
    pub fn synthesize_level_int<I: IntCoord>(
        &self,
        coarse: &Topology,
        data: &mut [[I; 3]],
    ) -> Result<()> {
        self.synthesize_level_int_with(coarse, data, false)
            .map(|_| ())
    }

    /// [`BSplineWavelet::synthesize_level_int`], scanning only the details if the coarse part
    /// `data[..V]` is known to lie within [`FAST_BOUND`] (`coarse_small`); returns whether all
    /// of `data` does afterwards.
    fn synthesize_level_int_with<I: IntCoord>(
        &self,
        coarse: &Topology,
        data: &mut [[I; 3]],
        coarse_small: bool,
    ) -> Result<bool> {
        check_len(coarse, data.len())?;
        let ctx = Ctx::new(coarse, self.boundary);
        let mut small = Small::scan(coarse, data, coarse_small);
        for l in self.degree.integer_lifts().iter().rev() {
            ctx.int_lift_tracked(*l, data, true, &mut small)?;
        }
        Ok(small.v && small.e && small.f)
    }

    /// The full integer analysis of a hierarchy, in place (layout as
    /// [`BSplineWavelet::analyze`]).
    ///
    /// # Errors
    /// As [`BSplineWavelet::analyze`] and [`BSplineWavelet::analyze_level_int`].
    pub fn analyze_int<I: IntCoord>(&self, levels: &[Topology], data: &mut [[I; 3]]) -> Result<()> {
        let sizes = level_sizes(levels)?;
        check_total(&sizes, data.len())?;
        // Each coarser level is the coarse part the finer one left: its smallness is known.
        let mut small = false;
        for (j, topo) in levels.iter().enumerate().rev() {
            small = self.analyze_level_int_with(topo, &mut data[..sizes[j + 1]], small)?;
        }
        Ok(())
    }

    /// The full integer synthesis, inverse of [`BSplineWavelet::analyze_int`].
    ///
    /// # Errors
    /// As [`BSplineWavelet::analyze_int`].
    pub fn synthesize_int<I: IntCoord>(
        &self,
        levels: &[Topology],
        data: &mut [[I; 3]],
    ) -> Result<()> {
        let sizes = level_sizes(levels)?;
        check_total(&sizes, data.len())?;
        // Each finer level's coarse part is what the coarser one produced: only the details
        // need a scan.
        let mut small = false;
        for (j, topo) in levels.iter().enumerate() {
            small = self.synthesize_level_int_with(topo, &mut data[..sizes[j + 1]], small)?;
        }
        Ok(())
    }
}

/// Number of vertices of each level: `sizes[0]` of the base, `sizes[j + 1] = V_j + E_j + F_j`
/// of the level refined from `levels[j]`.
///
/// # Errors
/// [`Error::InvalidArgument`] if `levels` is empty or `levels[j + 1]` is not the polygon split
/// of `levels[j]` (by vertex count).
pub fn level_sizes(levels: &[Topology]) -> Result<Vec<usize>> {
    let Some(first) = levels.first() else {
        return Err(Error::InvalidArgument(
            "a wavelet hierarchy needs at least one level".into(),
        ));
    };
    let mut sizes = vec![first.num_vertices as usize];
    for (j, t) in levels.iter().enumerate() {
        if t.num_vertices as usize != sizes[j] {
            return Err(Error::InvalidArgument(format!(
                "level {j} has {} vertices, expected {} (the polygon split of level {})",
                t.num_vertices,
                sizes[j],
                j.saturating_sub(1)
            )));
        }
        sizes.push(fine_count(t));
    }
    Ok(sizes)
}

/// Index range of the detail coefficients of level `j` (the `e` and `f` vertices of the level
/// refined from `levels[j]`) in the layout left by [`BSplineWavelet::analyze`]; `j ==
/// levels.len()` is not valid. `0..V_0` holds the base mesh.
///
/// # Errors
/// As [`level_sizes`], or [`Error::InvalidArgument`] if `j >= levels.len()`.
pub fn detail_range(levels: &[Topology], j: usize) -> Result<Range<usize>> {
    let sizes = level_sizes(levels)?;
    if j >= levels.len() {
        return Err(Error::InvalidArgument(format!(
            "level {j} has no details: the hierarchy has {} levels",
            levels.len()
        )));
    }
    Ok(sizes[j]..sizes[j + 1])
}

/// The topology hierarchy of `levels` polygon splits (Catmull-Clark connectivity, §4.1) of
/// `mesh`, with the bilinearly refined positions: [`Refinement::build`] with
/// [`Scheme::Bilinear`]; its `topologies` feed the transforms.
///
/// # Errors
/// As [`Refinement::build`].
pub fn quad_hierarchy(mesh: &Mesh, levels: u32) -> Result<Refinement> {
    let opts = SubdivideOptions {
        scheme: Scheme::Bilinear,
        levels,
        ..SubdivideOptions::default()
    };
    Refinement::build(mesh, &opts, false)
}

/// Plain subdivision with the synthesis of `degree` and zero details (§4.2, §5.1): the
/// [`Scheme::Bicubic`] and [`Scheme::Biquintic`] paths of
/// [`crate::subdivision::subdivide`]. Vertex colours and texture coordinates are subdivided
/// the same way; crease tags have no effect on these schemes (they are carried to the new
/// edges as for bilinear subdivision).
///
/// # Errors
/// As [`Refinement::build`].
pub fn subdivide_mesh(mesh: &Mesh, opts: &SubdivideOptions, degree: Degree) -> Result<Mesh> {
    let r = Refinement::build(
        mesh,
        &SubdivideOptions {
            scheme: Scheme::Bilinear,
            ..*opts
        },
        false,
    )?;
    let mut out = r.to_mesh();
    out.edge_tags = r.edge_tags;
    out.vertex_tags = r.vertex_tags;
    if opts.levels == 0 {
        out.colors.clone_from(&mesh.colors);
        out.uvs.clone_from(&mesh.uvs);
        return Ok(out);
    }
    let w = BSplineWavelet::new(degree);
    out.positions = w.subdivide(&r.topologies, &mesh.positions)?;
    if let Some(c) = &mesh.colors {
        out.colors = Some(w.subdivide(&r.topologies, c)?);
    }
    if let Some(t) = &mesh.uvs {
        out.uvs = Some(w.subdivide(&r.topologies, t)?);
    }
    Ok(out)
}

fn fine_count(t: &Topology) -> usize {
    t.num_vertices as usize + t.num_edges() + t.num_faces()
}

fn check_len(coarse: &Topology, len: usize) -> Result<()> {
    let n = fine_count(coarse);
    if len != n {
        return Err(Error::InvalidArgument(format!(
            "{len} values given, the refined level has {n} vertices ({} + {} edges + {} faces)",
            coarse.num_vertices,
            coarse.num_edges(),
            coarse.num_faces()
        )));
    }
    Ok(())
}

fn check_total(sizes: &[usize], len: usize) -> Result<()> {
    let n = *sizes.last().unwrap_or(&0);
    if len != n {
        return Err(Error::InvalidArgument(format!(
            "{len} values given, the finest level of the hierarchy has {n} vertices"
        )));
    }
    Ok(())
}

/// The coarse topology of one level and the boundary rule: the §4.1 averaging operators.
struct Ctx<'a> {
    t: &'a Topology,
    symmetric: bool,
    /// Integer lifts try `i64` arithmetic first (false: `i128` only, the reference in tests).
    int64: bool,
}

/// `Σ w_i x_i / den` as integer weights: `ē_v` under the boundary rule.
#[derive(Clone, Copy)]
struct EdgeWeights {
    boundary: i64,
    interior: i64,
    den: i64,
}

/// `c0 x + c1 y`.
#[inline]
fn combo2<T: Interpolate>(x: &T, c0: f64, y: &T, c1: f64) -> T {
    let mut r = T::zero();
    r.add_scaled(x, c0);
    r.add_scaled(y, c1);
    r
}

/// `c0 x + c1 y + c2 z`.
#[inline]
fn combo3<T: Interpolate>(x: &T, c0: f64, y: &T, c1: f64, z: &T, c2: f64) -> T {
    let mut r = T::zero();
    r.add_scaled(x, c0);
    r.add_scaled(y, c1);
    r.add_scaled(z, c2);
    r
}

/// `Σ data[idx]` (zero if `idx` is empty).
#[inline]
fn sum<T: Interpolate>(idx: &[u32], data: &[T]) -> T {
    let mut y = T::zero();
    for &i in idx {
        y.add_scaled(&data[i as usize], 1.0);
    }
    y
}

/// `1 / n` for the neighbour counts of the §4.1 averages (a table for the common ones: no
/// division in the inner loops); 1 for `n = 0` (the sum is then zero).
#[inline]
fn recip(n: usize) -> f64 {
    const R: [f64; 9] = [
        1.0,
        1.0,
        1.0 / 2.0,
        1.0 / 3.0,
        1.0 / 4.0,
        1.0 / 5.0,
        1.0 / 6.0,
        1.0 / 7.0,
        1.0 / 8.0,
    ];
    match R.get(n) {
        Some(r) => *r,
        None => 1.0 / n as f64,
    }
}

/// Exact sum of `data[idx]` and the count (1 if empty, the sum being 0).
#[inline]
fn isum<I: IntCoord>(idx: &[u32], data: &[[I; 3]]) -> ([i128; 3], i128) {
    let mut s = [0i128; 3];
    for &i in idx {
        let x = data[i as usize];
        for k in 0..3 {
            s[k] += x[k].into();
        }
    }
    (s, idx.len().max(1) as i128)
}

/// `[n / d]`: nearest integer, ties towards +∞ (`d > 0`).
#[inline]
fn round_div(n: i128, d: i128) -> i128 {
    (2 * n + d).div_euclid(2 * d)
}

/// [`round_div`] in `i64`, `None` on overflow (`d > 0`). `⌊x / (2^k c)⌋ = ⌊⌊x / 2^k⌋ / c⌋`:
/// a shift, then a division by the odd part `c` of `2d`, by a constant for the common
/// denominators (valence 3–6 and Table 1's `a`).
#[inline]
fn round_div64(n: i64, d: i64) -> Option<i64> {
    let x = n.checked_mul(2)?.checked_add(d)?;
    let den = d.checked_mul(2)?;
    let k = den.trailing_zeros();
    let (y, c) = (x >> k, den >> k);
    Some(match c {
        1 => y,
        3 => y.div_euclid(3),
        5 => y.div_euclid(5),
        9 => y.div_euclid(9),
        15 => y.div_euclid(15),
        25 => y.div_euclid(25),
        27 => y.div_euclid(27),
        45 => y.div_euclid(45),
        81 => y.div_euclid(81),
        _ => y.div_euclid(c),
    })
}

/// `x` as `i64` (`None` if it does not fit).
#[inline]
fn to64<I: IntCoord>(x: I) -> Option<i64> {
    let y: i128 = x.into();
    i64::try_from(y).ok()
}

/// [`isum`] in `i64`, `None` on overflow.
#[inline]
fn isum64<I: IntCoord>(idx: &[u32], data: &[[I; 3]]) -> Option<([i64; 3], i64)> {
    let mut s = [0i64; 3];
    for &i in idx {
        let x = data[i as usize];
        for k in 0..3 {
            s[k] = s[k].checked_add(to64(x[k])?)?;
        }
    }
    Some((s, idx.len().max(1) as i64))
}

/// Runs `f(i, &mut out[i])` over `out` in parallel.
#[inline]
fn par_update<T: Send, F: Fn(usize, &mut T) + Sync + Send>(out: &mut [T], f: F) {
    // Chunks with a plain sequential loop inside: no per-element work-splitting overhead.
    out.par_chunks_mut(MIN_LEN)
        .enumerate()
        .for_each(|(c, chunk)| {
            let base = c * MIN_LEN;
            for (k, x) in chunk.iter_mut().enumerate() {
                f(base + k, x);
            }
        });
}

/// Runs `f(first, chunk)` over `out` in parallel chunks, `first` the index of the chunk's first
/// element.
#[inline]
fn par_chunks<T: Send, F: Fn(usize, &mut [T]) + Sync + Send>(out: &mut [T], f: F) {
    out.par_chunks_mut(MIN_LEN)
        .enumerate()
        .for_each(|(c, chunk)| f(c * MIN_LEN, chunk));
}

/// The weight `a = P / Q` of an integer lift, for [`Ctx::int_lift_w`].
trait LiftWeight: Copy + Send + Sync {
    /// Whether `P` and `Q` are Table 1's (compile-time constants with the bounds that
    /// [`FAST_BOUND`] assumes); false: the general path only.
    const FAST: bool;
    /// Numerator.
    const P: i64;
    /// Denominator (positive).
    const Q: i64;
}

/// Compile-time `a = P / Q`.
#[derive(Clone, Copy)]
struct ConstWeight<const P: i64, const Q: i64>;

impl<const P: i64, const Q: i64> LiftWeight for ConstWeight<P, Q> {
    const FAST: bool = true;
    const P: i64 = P;
    const Q: i64 = Q;
}

/// A weight known at run time only (the general path).
#[derive(Clone, Copy)]
struct DynWeight;

impl LiftWeight for DynWeight {
    const FAST: bool = false;
    const P: i64 = 0;
    const Q: i64 = 1;
}

/// Inputs of the regular formulas lie in `[−2^FAST_BOUND, 2^FAST_BOUND)`: then with `|P| ≤ 9`,
/// `Q ≤ 32` no intermediate exceeds `2^58` (`2|P|(|P| + Q) · 4 · 2^45 < 2^57`) and the
/// updated value fits `i64`.
const FAST_BOUND: u32 = 45;

/// `c` as `i64`.
#[inline(always)]
fn coord<I: IntCoord>(c: I) -> i64 {
    let y: i128 = c.into();
    y as i64
}

/// Which parts of a level's data lie within `[−2^FAST_BOUND, 2^FAST_BOUND)`.
#[derive(Clone, Copy, Debug)]
struct Small {
    v: bool,
    e: bool,
    f: bool,
}

impl Small {
    /// Every part small.
    const ALL: Small = Small {
        v: true,
        e: true,
        f: true,
    };

    /// Scans the level's data (`V + E + F` entries of the level refined from `t`), all but
    /// the `V` coarse entries if they are known to be small (`v_small`).
    fn scan<I: IntCoord>(t: &Topology, data: &[[I; 3]], v_small: bool) -> Small {
        let nv = t.num_vertices as usize;
        let ne = t.num_edges();
        let all = |x: &[[I; 3]]| x.par_chunks(1 << 14).all(all_small);
        Small {
            v: v_small || all(&data[..nv]),
            e: all(&data[nv..nv + ne]),
            f: all(&data[nv + ne..]),
        }
    }
}

/// Whether every value of `x` lies in `[−2^FAST_BOUND, 2^FAST_BOUND)`.
#[inline]
fn all_small<I: IntCoord>(x: &[[I; 3]]) -> bool {
    let mut chk = 0u64;
    for y in x {
        for &c in y {
            chk |= (coord(c) as u64).wrapping_add(1 << FAST_BOUND);
        }
    }
    chk >> (FAST_BOUND + 1) == 0
}

/// Runs `f(first, chunk)` over `out` in parallel chunks (as [`par_chunks`]); true iff every
/// value left in `out` is small ([`all_small`]).
#[inline]
fn par_chunks_small<I: IntCoord, F: Fn(usize, &mut [[I; 3]]) + Sync + Send>(
    out: &mut [[I; 3]],
    f: F,
) -> bool {
    let big = std::sync::atomic::AtomicBool::new(false);
    out.par_chunks_mut(MIN_LEN)
        .enumerate()
        .for_each(|(c, chunk)| {
            f(c * MIN_LEN, chunk);
            if !all_small(chunk) {
                big.store(true, Ordering::Relaxed);
            }
        });
    !big.load(Ordering::Relaxed)
}

/// `x ± [p(p sx + q sy) / q²]` (`+` forward, `−` inverse): the rounded term of the
/// two-neighbour-class update of [`Ctx::int_lift`] when both classes have four members
/// (`dx = dy = 4`: `[(4p² sx dy + 4pq sy dx) / (q² dx dy)]`, the same rational). `None` if a
/// result does not fit `I`: the caller takes the general path, which reports the overflow.
/// Precondition: `x` and every value read lie within [`FAST_BOUND`].
#[inline(always)]
fn regular_term2<I: IntCoord, W: LiftWeight>(
    x: &[I; 3],
    ix: &[u32],
    xs: &[[I; 3]],
    iy: &[u32],
    ys: &[[I; 3]],
    inverse: bool,
) -> Option<[I; 3]> {
    let (mut sx, mut sy) = ([0i64; 3], [0i64; 3]);
    for &i in &ix[..4] {
        let y = xs[i as usize];
        for k in 0..3 {
            sx[k] += coord(y[k]);
        }
    }
    for &i in &iy[..4] {
        let y = ys[i as usize];
        for k in 0..3 {
            sy[k] += coord(y[k]);
        }
    }
    let (p, q) = (W::P, W::Q);
    let mut out = *x;
    for k in 0..3 {
        let n = 2 * p * (p * sx[k] + q * sy[k]) + q * q;
        let r = floor_div_const2::<W>(n);
        let c = coord(x[k]);
        let z = if inverse { c - r } else { c + r };
        out[k] = I::try_from(z as i128).ok()?;
    }
    Some(out)
}

/// `⌊n / (2Q²)⌋` of `W`.
#[inline(always)]
fn floor_div_const2<W: LiftWeight>(n: i64) -> i64 {
    // Table 1's denominators 2Q²: 2, 8, 32, 72, 18, 512, 2048.
    match 2 * W::Q * W::Q {
        2 => floor_div_const_small::<2>(n),
        8 => floor_div_const_small::<8>(n),
        18 => floor_div_const_small::<18>(n),
        32 => floor_div_const_small::<32>(n),
        72 => floor_div_const_small::<72>(n),
        512 => floor_div_const_small::<512>(n),
        2048 => floor_div_const_small::<2048>(n),
        d => n.div_euclid(d),
    }
}

/// `⌊n / (2Q)⌋` of `W`.
#[inline(always)]
fn floor_div_const1<W: LiftWeight>(n: i64) -> i64 {
    // Table 1's denominators 2Q: 2, 4, 6, 8, 12, 32, 64.
    match 2 * W::Q {
        2 => floor_div_const_small::<2>(n),
        4 => floor_div_const_small::<4>(n),
        6 => floor_div_const_small::<6>(n),
        8 => floor_div_const_small::<8>(n),
        12 => floor_div_const_small::<12>(n),
        32 => floor_div_const_small::<32>(n),
        64 => floor_div_const_small::<64>(n),
        d => n.div_euclid(d),
    }
}

/// `x ± [2a s̄]` for an edge with one or two neighbours `idx` in `src` (`s̄` their mean:
/// `[2p s / (q d)]`, [`Ctx::int_lift`]'s one-class term); `None` for another count or a
/// result that does not fit `I`. Precondition as [`regular_term2`].
#[inline(always)]
fn regular_term1<I: IntCoord, W: LiftWeight>(
    x: &[I; 3],
    idx: &[u32],
    src: &[[I; 3]],
    inverse: bool,
) -> Option<[I; 3]> {
    let (p, q) = (W::P, W::Q);
    // `[2p s / (q d)] = ⌊(2 m s + q) / (2q)⌋` with `m = 2p / d`.
    let mut s = [0i64; 3];
    let m = match *idx {
        [a, b] => {
            let (ya, yb) = (src[a as usize], src[b as usize]);
            for k in 0..3 {
                s[k] = coord(ya[k]) + coord(yb[k]);
            }
            p
        }
        [a] => {
            let y = src[a as usize];
            for k in 0..3 {
                s[k] = coord(y[k]);
            }
            2 * p
        }
        _ => return None,
    };
    let mut out = *x;
    for k in 0..3 {
        let r = floor_div_const1::<W>(2 * m * s[k] + q);
        let c = coord(x[k]);
        let z = if inverse { c - r } else { c + r };
        out[k] = I::try_from(z as i128).ok()?;
    }
    Some(out)
}

/// Splits a level's data into its `v`, `e` and `f` parts.
fn split3<'d, T>(t: &Topology, data: &'d mut [T]) -> (&'d mut [T], &'d mut [T], &'d mut [T]) {
    let (v, rest) = data.split_at_mut(t.num_vertices as usize);
    let (e, f) = rest.split_at_mut(t.num_edges());
    (v, e, f)
}

/// Records the smallest index whose coefficient overflowed.
struct Overflow(AtomicUsize);

impl Overflow {
    fn new() -> Self {
        Overflow(AtomicUsize::new(usize::MAX))
    }
    fn set(&self, i: usize) {
        self.0.fetch_min(i, Ordering::Relaxed);
    }
    fn check<I: IntCoord>(&self, what: &str) -> Result<()> {
        match self.0.load(Ordering::Relaxed) {
            usize::MAX => Ok(()),
            i => Err(Error::InvalidArgument(format!(
                "integer wavelet transform: the coefficient of {what} vertex {i} does not fit \
                 in {} (use i64 or smaller coordinates)",
                I::NAME
            ))),
        }
    }
}

/// Converts `x` to `[I; 3]`, recording `i` in `o` on overflow.
#[inline]
fn store<I: IntCoord>(x: [i128; 3], out: &mut [I; 3], o: &Overflow, i: usize) {
    for k in 0..3 {
        match I::try_from(x[k]) {
            Ok(y) => out[k] = y,
            Err(_) => o.set(i),
        }
    }
}

impl<'a> Ctx<'a> {
    fn new(t: &'a Topology, boundary: Boundary) -> Self {
        Ctx {
            t,
            symmetric: boundary == Boundary::Symmetric,
            int64: true,
        }
    }

    /// Weights of `ē_v` for vertex `v` (§4.1; [`Boundary::Symmetric`] at boundary vertices).
    #[inline]
    fn edge_weights(&self, v: usize) -> EdgeWeights {
        let edges = self.t.vertex_edges(v);
        let n = edges.len() as i64;
        if self.symmetric {
            let nb = edges
                .iter()
                .filter(|&&e| self.t.is_boundary_edge(e as usize))
                .count() as i64;
            if nb > 0 && nb < n {
                let ni = n - nb;
                return EdgeWeights {
                    boundary: ni,
                    interior: nb,
                    den: 2 * nb * ni,
                };
            }
        }
        EdgeWeights {
            boundary: 1,
            interior: 1,
            den: n.max(1),
        }
    }

    /// `ē_v` in floating point.
    #[inline]
    fn e_bar_v<T: Interpolate>(&self, v: usize, e: &[T]) -> T {
        let w = self.edge_weights(v);
        let (wb, wi) = (
            w.boundary as f64 / w.den as f64,
            w.interior as f64 / w.den as f64,
        );
        let mut y = T::zero();
        for &x in self.t.vertex_edges(v) {
            let k = if self.symmetric && self.t.is_boundary_edge(x as usize) {
                wb
            } else {
                wi
            };
            y.add_scaled(&e[x as usize], k);
        }
        y
    }

    /// [`Ctx::e_bar_v_int`] in `i64`, `None` on overflow.
    #[inline]
    fn e_bar_v_int64<I: IntCoord>(&self, v: usize, e: &[[I; 3]]) -> Option<([i64; 3], i64)> {
        if !self.symmetric {
            return isum64(self.t.vertex_edges(v), e);
        }
        let w = self.edge_weights(v);
        let mut s = [0i64; 3];
        for &x in self.t.vertex_edges(v) {
            let k = if self.t.is_boundary_edge(x as usize) {
                w.boundary
            } else {
                w.interior
            };
            let c = e[x as usize];
            for j in 0..3 {
                s[j] = s[j].checked_add(k.checked_mul(to64(c[j])?)?)?;
            }
        }
        Some((s, w.den))
    }

    /// `ē_v` as an exact weighted sum and its denominator.
    #[inline]
    fn e_bar_v_int<I: IntCoord>(&self, v: usize, e: &[[I; 3]]) -> ([i128; 3], i128) {
        let w = self.edge_weights(v);
        let mut s = [0i128; 3];
        for &x in self.t.vertex_edges(v) {
            let k = if self.symmetric && self.t.is_boundary_edge(x as usize) {
                w.boundary
            } else {
                w.interior
            } as i128;
            let c = e[x as usize];
            for j in 0..3 {
                s[j] += k * c[j].into();
            }
        }
        (s, w.den as i128)
    }

    /// `Σ data[idx]` and the weight `w / n` of its mean (`w` if `idx` is empty, the sum
    /// being zero): the means of §4.1 scaled by a lift weight without a multiplication per
    /// neighbour.
    #[inline]
    fn scaled_sum<T: Interpolate>(idx: &[u32], data: &[T], w: f64) -> (T, f64) {
        (sum(idx, data), w * recip(idx.len()))
    }

    /// Vertex update `x ← c0 x + cf f̄_v + ce ē_v`.
    #[inline]
    fn vertex_pass<T: Interpolate>(
        &self,
        v: &mut [T],
        e: &[T],
        f: &[T],
        c0: f64,
        cf: f64,
        ce: f64,
    ) {
        let t = self.t;
        par_chunks(v, |v0, out| {
            // The chunk's adjacency offsets, sliced once.
            let fo = &t.vertex_face_offsets[v0..=v0 + out.len()];
            let eo = &t.vertex_edge_offsets[v0..=v0 + out.len()];
            for (k, x) in out.iter_mut().enumerate() {
                let faces = &t.vertex_faces[fo[k] as usize..fo[k + 1] as usize];
                let (fs, wf) = Self::scaled_sum(faces, f, cf);
                let (es, we) = if self.symmetric {
                    (self.e_bar_v(v0 + k, e), ce)
                } else {
                    let edges = &t.vertex_edges[eo[k] as usize..eo[k + 1] as usize];
                    Self::scaled_sum(edges, e, ce)
                };
                *x = combo3(x, c0, &fs, wf, &es, we);
            }
        });
    }

    /// Face update `x ← c0 x + cv v̄_f + ce ē_f`.
    #[inline]
    fn face_pass<T: Interpolate>(&self, f: &mut [T], v: &[T], e: &[T], c0: f64, cv: f64, ce: f64) {
        let t = self.t;
        let nf = t.num_faces();
        if t.face_arity == 4 && t.face_vertices.len() == 4 * nf && t.face_edges.len() == 4 * nf {
            // All quads (every level after the first split): the corners in fixed fours.
            let (wv, we) = (cv * recip(4), ce * recip(4));
            par_chunks(f, |f0, out| {
                let r = 4 * f0..4 * (f0 + out.len());
                let fv = t.face_vertices[r.clone()].chunks_exact(4);
                let fe = t.face_edges[r].chunks_exact(4);
                for ((x, cv), ce) in out.iter_mut().zip(fv).zip(fe) {
                    let vs = sum(cv, v);
                    let es = sum(ce, e);
                    *x = combo3(x, c0, &vs, wv, &es, we);
                }
            });
            return;
        }
        par_update(f, |i, x| {
            let (vs, wv) = Self::scaled_sum(t.face_vertices(i), v, cv);
            let (es, we) = Self::scaled_sum(t.face_edges(i), e, ce);
            *x = combo3(x, c0, &vs, wv, &es, we);
        });
    }

    /// Edge update `x ← c0 x + c1 s̄_e` with `s̄_e` the mean over the edge's faces (`src` =
    /// f) or its two vertices (`src` = v).
    #[inline]
    fn edge_pass<T: Interpolate>(
        &self,
        e: &mut [T],
        src: &[T],
        from_faces: bool,
        c0: f64,
        c1: f64,
    ) {
        let t = self.t;
        if from_faces {
            par_chunks(e, |e0, out| {
                let o = &t.edge_face_offsets[e0..=e0 + out.len()];
                for (k, x) in out.iter_mut().enumerate() {
                    let faces = &t.edge_faces[o[k] as usize..o[k + 1] as usize];
                    let (s, w) = Self::scaled_sum(faces, src, c1);
                    *x = combo2(x, c0, &s, w);
                }
            });
        } else {
            let h = 0.5 * c1;
            par_chunks(e, |e0, out| {
                let ev = &t.edge_vertices[e0..e0 + out.len()];
                for (x, &[p, q]) in out.iter_mut().zip(ev) {
                    let mut s = src[p as usize];
                    s.add_scaled(&src[q as usize], 1.0);
                    *x = combo2(x, c0, &s, h);
                }
            });
        }
    }

    fn lift<T: Interpolate>(&self, l: Lift, data: &mut [T]) {
        let (v, e, f) = split3(self.t, data);
        let (a, b) = (l.a, l.b);
        let (kk, kb, b2) = (4.0 * a * a, 4.0 * a * b, b * b);
        match l.kind {
            S => {
                // v ← b² v + 4a² f̄_v + 4ab ē_v (eq. 4.5), reading the old e.
                self.vertex_pass(v, e, f, b2, kk, kb);
                // e ← b e + 2a f̄_e.
                self.edge_pass(e, f, true, b, 2.0 * a);
            }
            W => {
                // f ← b² f + 4a² v̄_f + 4ab ē_f (eq. 4.6), reading the old e.
                self.face_pass(f, v, e, b2, kk, kb);
                // e ← b e + 2a v̄_e.
                self.edge_pass(e, v, false, b, 2.0 * a);
            }
        }
    }

    fn unlift<T: Interpolate>(&self, l: Lift, data: &mut [T]) {
        let (v, e, f) = split3(self.t, data);
        let (a, b) = (l.a, l.b);
        let (kk, kb, b2) = (4.0 * a * a, 4.0 * a * b, b * b);
        match l.kind {
            S => {
                self.edge_pass(e, f, true, 1.0 / b, -2.0 * a / b);
                self.vertex_pass(v, e, f, 1.0 / b2, -kk / b2, -kb / b2);
            }
            W => {
                self.edge_pass(e, v, false, 1.0 / b, -2.0 * a / b);
                self.face_pass(f, v, e, 1.0 / b2, -kk / b2, -kb / b2);
            }
        }
    }

    /// Integer lift (eqs. 4.8, 4.9) or, if `inverse`, its inverse (eqs. 4.10, 4.11).
    #[cfg(test)]
    fn int_lift<I: IntCoord>(&self, l: IntLift, data: &mut [[I; 3]], inverse: bool) -> Result<()> {
        let mut small = Small::scan(self.t, data, false);
        self.int_lift_tracked(l, data, inverse, &mut small)
    }

    /// [`Ctx::int_lift`] with `small` telling which parts of `data` lie within
    /// [`FAST_BOUND`] on entry, updated on return.
    fn int_lift_tracked<I: IntCoord>(
        &self,
        l: IntLift,
        data: &mut [[I; 3]],
        inverse: bool,
        small: &mut Small,
    ) -> Result<()> {
        // The lifts of Table 1 with their weights as compile-time constants (the regular
        // elements' divisions become shifts and multiplications); any other lift at run time.
        macro_rules! dispatch {
            ($(($p:literal, $q:literal)),*) => {
                match (l.a_num, l.a_den, l.b) {
                    $(($p, $q, 1) => self.int_lift_w(ConstWeight::<{ $p }, { $q }>, l, data, inverse, small),)*
                    _ => self.int_lift_w(DynWeight, l, data, inverse, small),
                }
            };
        }
        dispatch!(
            (-1, 2),
            (1, 4),
            (-1, 4),
            (-1, 1),
            (3, 16),
            (-1, 6),
            (-9, 16),
            (-4, 3),
            (5, 32)
        )
    }

    /// [`Ctx::int_lift`] with the weight `a = P/Q` of `W` if [`LiftWeight::FAST`] (then equal
    /// to `l.a_num / l.a_den`, and `l.b == 1`): in a pass whose inputs are all below
    /// [`FAST_BOUND`] in magnitude (`small`), regular elements (valence-4 vertices, quads,
    /// edges with one or two faces) take exact `i64` formulas with constant divisors; every
    /// other element the general path. Each pass records whether its outputs are small.
    fn int_lift_w<I: IntCoord, W: LiftWeight>(
        &self,
        _w: W,
        l: IntLift,
        data: &mut [[I; 3]],
        inverse: bool,
        small: &mut Small,
    ) -> Result<()> {
        let t = self.t;
        let nv = t.num_vertices as usize;
        let ne = t.num_edges();
        let (v, e, f) = split3(t, data);
        let (p, q, b) = (l.a_num as i128, l.a_den as i128, l.b as i128);
        debug_assert!(q > 0 && b != 0);
        let o = Overflow::new();
        // The rounded term of the two-neighbour-class update `4a² x̄ + 4ab ȳ`, `x̄ = sx/dx`,
        // `ȳ = sy/dy`: [(4p² sx dy + 4pqb sy dx) / (q² dx dy)].
        let term2 = |sx: [i128; 3], dx: i128, sy: [i128; 3], dy: i128| -> [i128; 3] {
            let den = q * q * dx * dy;
            std::array::from_fn(|k| {
                round_div(4 * p * p * sx[k] * dy + 4 * p * q * b * sy[k] * dx, den)
            })
        };
        // [2a x̄] with x̄ = sx/dx.
        let term1 = |sx: [i128; 3], dx: i128| -> [i128; 3] {
            std::array::from_fn(|k| round_div(2 * p * sx[k], q * dx))
        };
        // Forward: y = b^m x + r. Inverse: x = (y − r) / b^m (exact for b = ±1; a remainder
        // means `y` was not produced by the forward lift: reported as an overflow).
        let apply = |x: &mut [I; 3], r: [i128; 3], bm: i128, i: usize| {
            let y: [i128; 3] = std::array::from_fn(|k| {
                let c: i128 = x[k].into();
                if inverse {
                    let d = c - r[k];
                    if d % bm != 0 {
                        o.set(i);
                    }
                    d / bm
                } else {
                    bm * c + r[k]
                }
            });
            store(y, x, &o, i);
        };
        // The same in `i64` (every table here has `b = 1`), `None` on overflow: the caller
        // then takes the `i128` path, which gives the same result or reports the overflow.
        let fast = self.int64 && b == 1 && i64::try_from(p).is_ok() && i64::try_from(q).is_ok();
        let (p64, q64) = (p as i64, q as i64);
        let term2_64 = |sx: [i64; 3], dx: i64, sy: [i64; 3], dy: i64| -> Option<[i64; 3]> {
            let den = q64.checked_mul(q64)?.checked_mul(dx)?.checked_mul(dy)?;
            let cx = p64.checked_mul(4 * p64)?.checked_mul(dy)?;
            let cy = p64.checked_mul(4 * q64)?.checked_mul(dx)?;
            let mut r = [0i64; 3];
            for k in 0..3 {
                let n = sx[k].checked_mul(cx)?.checked_add(sy[k].checked_mul(cy)?)?;
                r[k] = round_div64(n, den)?;
            }
            Some(r)
        };
        let term1_64 = |sx: [i64; 3], dx: i64| -> Option<[i64; 3]> {
            let den = q64.checked_mul(dx)?;
            let c = p64.checked_mul(2)?;
            let mut r = [0i64; 3];
            for k in 0..3 {
                r[k] = round_div64(sx[k].checked_mul(c)?, den)?;
            }
            Some(r)
        };
        // `x ± r` for `b = 1`; false (and `x` untouched) if it does not fit.
        let apply64 = |x: &mut [I; 3], r: [i64; 3]| -> bool {
            let mut y = [x[0]; 3];
            for k in 0..3 {
                let Some(c) = to64(x[k]) else { return false };
                let z = if inverse {
                    c.checked_sub(r[k])
                } else {
                    c.checked_add(r[k])
                };
                match z.and_then(|z| I::try_from(z as i128).ok()) {
                    Some(z) => y[k] = z,
                    None => return false,
                }
            }
            *x = y;
            true
        };
        let vertex_pass = |v: &mut [[I; 3]], e: &[[I; 3]], f: &[[I; 3]], regular: bool| {
            let general = |i: usize, x: &mut [I; 3]| {
                if fast {
                    let r = isum64(t.vertex_faces(i), f).and_then(|(sf, df)| {
                        let (se, de) = self.e_bar_v_int64(i, e)?;
                        term2_64(sf, df, se, de)
                    });
                    if r.is_some_and(|r| apply64(x, r)) {
                        return;
                    }
                }
                let (sf, df) = isum(t.vertex_faces(i), f);
                let (se, de) = self.e_bar_v_int(i, e);
                apply(x, term2(sf, df, se, de), b * b, i);
            };
            // The general path through a `dyn` call: rare (irregular elements), and kept out
            // of the regular loop's code.
            let general: &(dyn Fn(usize, &mut [I; 3]) + Sync) = &general;
            par_chunks_small(v, |v0, out| {
                let fo = &t.vertex_face_offsets[v0..=v0 + out.len()];
                let eo = &t.vertex_edge_offsets[v0..=v0 + out.len()];
                for (k, x) in out.iter_mut().enumerate() {
                    let (fa, ea) = (fo[k] as usize, eo[k] as usize);
                    if regular && fo[k + 1] as usize == fa + 4 && eo[k + 1] as usize == ea + 4 {
                        let fi = &t.vertex_faces[fa..fa + 4];
                        let ei = &t.vertex_edges[ea..ea + 4];
                        if let Some(y) = regular_term2::<I, W>(x, fi, f, ei, e, inverse) {
                            *x = y;
                            continue;
                        }
                    }
                    general(v0 + k, x);
                }
            })
        };
        let face_pass = |f: &mut [[I; 3]], v: &[[I; 3]], e: &[[I; 3]], regular: bool| {
            let general = |i: usize, x: &mut [I; 3]| {
                if fast {
                    let r = isum64(t.face_vertices(i), v).and_then(|(sv, dv)| {
                        let (se, de) = isum64(t.face_edges(i), e)?;
                        term2_64(sv, dv, se, de)
                    });
                    if r.is_some_and(|r| apply64(x, r)) {
                        return;
                    }
                }
                let (sv, dv) = isum(t.face_vertices(i), v);
                let (se, de) = isum(t.face_edges(i), e);
                apply(x, term2(sv, dv, se, de), b * b, nv + ne + i);
            };
            // The general path through a `dyn` call: rare (irregular elements), and kept out
            // of the regular loop's code.
            let general: &(dyn Fn(usize, &mut [I; 3]) + Sync) = &general;
            par_chunks_small(f, |f0, out| {
                for (k, x) in out.iter_mut().enumerate() {
                    let i = f0 + k;
                    let (fv, fe) = (t.face_vertices(i), t.face_edges(i));
                    if regular && fv.len() == 4 && fe.len() == 4 {
                        if let Some(y) = regular_term2::<I, W>(x, fv, v, fe, e, inverse) {
                            *x = y;
                            continue;
                        }
                    }
                    general(i, x);
                }
            })
        };
        let edge_pass = |e: &mut [[I; 3]], src: &[[I; 3]], from_faces: bool, regular: bool| {
            let general = |i: usize, x: &mut [I; 3]| {
                let idx: &[u32] = if from_faces {
                    t.edge_faces(i)
                } else {
                    &t.edge_vertices[i]
                };
                if fast {
                    let r = isum64(idx, src).and_then(|(s, d)| term1_64(s, d));
                    if r.is_some_and(|r| apply64(x, r)) {
                        return;
                    }
                }
                let (s, d) = isum(idx, src);
                apply(x, term1(s, d), b, nv + i);
            };
            // The general path through a `dyn` call: rare (irregular elements), and kept out
            // of the regular loop's code.
            let general: &(dyn Fn(usize, &mut [I; 3]) + Sync) = &general;
            if from_faces {
                par_chunks_small(e, |e0, out| {
                    let o = &t.edge_face_offsets[e0..=e0 + out.len()];
                    for (k, x) in out.iter_mut().enumerate() {
                        let idx = &t.edge_faces[o[k] as usize..o[k + 1] as usize];
                        // The regular formula only on small inputs (its bound).
                        match regular.then(|| regular_term1::<I, W>(x, idx, src, inverse)) {
                            Some(Some(y)) => *x = y,
                            _ => general(e0 + k, x),
                        }
                    }
                })
            } else {
                par_chunks_small(e, |e0, out| {
                    let ev = &t.edge_vertices[e0..e0 + out.len()];
                    for (k, (x, idx)) in out.iter_mut().zip(ev).enumerate() {
                        match regular.then(|| regular_term1::<I, W>(x, idx, src, inverse)) {
                            Some(Some(y)) => *x = y,
                            _ => general(e0 + k, x),
                        }
                    }
                })
            }
        };
        // The regular formulas need every input of the pass within `FAST_BOUND`.
        let ok = |a: bool, b: bool, c: bool| W::FAST && fast && !self.symmetric && a && b && c;
        let s = small;
        match (l.kind, inverse) {
            (S, false) => {
                s.v = vertex_pass(v, e, f, ok(s.v, s.e, s.f));
                s.e = edge_pass(e, f, true, ok(s.e, s.f, true));
            }
            (S, true) => {
                s.e = edge_pass(e, f, true, ok(s.e, s.f, true));
                s.v = vertex_pass(v, e, f, ok(s.v, s.e, s.f));
            }
            (W, false) => {
                s.f = face_pass(f, v, e, ok(s.f, s.v, s.e));
                s.e = edge_pass(e, v, false, ok(s.e, s.v, true));
            }
            (W, true) => {
                s.e = edge_pass(e, v, false, ok(s.e, s.v, true));
                s.f = face_pass(f, v, e, ok(s.f, s.v, s.e));
            }
        }
        o.check::<I>("refined")
    }
}

#[cfg(test)]
mod tests;

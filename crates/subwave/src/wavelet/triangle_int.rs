//! Integer-to-integer wavelets on triangle hierarchies: the lifted midpoint and butterfly
//! wavelets of [`super::triangle`] with every lifting step rounded (Calderbank, Daubechies,
//! Sweldens & Yeo, *Wavelet transforms that map integers to integers*, 1998), for the lossless
//! mode of the codec (issue "progressive geometry codec", deliverable 5; Maret §4.5 describes
//! the float transforms, Bertram et al. §4.3 the same idea on quad hierarchies).
//!
//! # Transform
//! Per level `j → j + 1`, in place on `[even (V_j) | odd (E_j)]` integer coordinates (the
//! ordering contract of [`crate::subdivision::refine`]), as the float transform of
//! [`super::triangle`] with each step rounded:
//! - prediction: `d_e = x_e − ⌊P_e(x_even) + ½⌋`, `P_e` the odd row of the scheme's level
//!   stencil table (midpoint: `(x_a + x_b)/2`; butterfly: the modified butterfly masks);
//! - update (lifted only): `c_v = x_v + ⌊3 Σ_{e∋v} φ_e d_e / (8 f_v) + ½⌋` with `φ_e` the
//!   faces of edge `e` and `f_v` those of vertex `v` (the integral-preserving update of
//!   [`super::triangle`]), computed exactly in integers.
//!
//! Synthesis undoes the steps in reverse order with the same rounded terms, so analysis followed
//! by synthesis is the identity on integers, whatever the rounding: each step adds to one part a
//! function of the other part only.
//!
//! # Determinism
//! `P_e` has real weights (butterfly's extraordinary masks are not dyadic). It is evaluated in
//! `f64` in stencil order, which IEEE 754 makes deterministic on every machine (Rust never
//! contracts to fused multiply-adds), and exact for midpoint and the regular butterfly mask.
//! Coordinates are limited to `|x| ≤ 2^40` ([`MAX_COORD`]) so that every product and sum is far
//! from `f64`'s 53-bit limit and no detail can overflow `i64`.

use rayon::prelude::*;

use super::floor_div_const;
use super::triangle::{edge_face_count, RowPattern, TriangleWavelet, UpdatePlan};
use crate::hierarchy::Hierarchy;
use crate::subdivision::refine::Split;
use crate::subdivision::stencil::StencilTable;
use crate::subdivision::{Refinement, Scheme, SubdivideOptions};
use crate::{Error, Result};

/// Largest coordinate magnitude accepted by the integer transforms (`2^40`). Coefficients of a
/// transform of such coordinates stay below `2^44` in magnitude.
pub const MAX_COORD: i64 = 1 << 40;

/// Values per parallel work item.
const CHUNK: usize = 8192;

/// An integer-to-integer wavelet on a triangle [`Hierarchy`]: interpolating prediction
/// (midpoint or butterfly), with or without the update step.
#[derive(Clone, Debug)]
pub struct IntTriangleWavelet<'h> {
    h: &'h Hierarchy,
    tables: Vec<StencilTable>,
    /// Per level, the table's weights as sixteenths ([`DyadicRows`]).
    dyadic: Vec<DyadicRows>,
    update_plan: UpdatePlan,
    lifted: bool,
}

/// A level table's weights as sixteenths `k = 16 w` (built once per hierarchy): rows whose
/// weights all are such (with `Σ |k| ≤ 32`) are predicted in exact `i64` arithmetic,
/// `⌊(Σ k y + 8) / 16⌋`, when every source lies within `2^47` in magnitude — the value
/// the `f64` evaluation gives then, since every product and partial sum is a multiple of
/// 1/16 below `2^49` (exact in `f64`). The regular butterfly mask (8, 8, 2, 2, −1 ×4) and
/// midpoint (8, 8) are such rows; the extraordinary butterfly masks are not.
#[derive(Clone, Debug, Default)]
struct DyadicRows {
    /// `16 w`, parallel to the table's weights (meaningful in dyadic rows only).
    k: Vec<i8>,
    /// Per row: whether it is dyadic.
    ok: Vec<bool>,
    /// The level's most common odd row ([`RowPattern`]) in sixteenths, if it is dyadic, and
    /// per row whether the row is that pattern.
    pattern: Option<(Vec<i64>, Vec<bool>)>,
}

impl DyadicRows {
    /// The rows of `t`, whose row pattern is `p`.
    fn new(t: &StencilTable, p: RowPattern) -> Self {
        let k: Vec<i8> = t
            .weights
            .par_iter()
            .with_min_len(CHUNK)
            .map(|&w| {
                let k = w * 16.0;
                if k.fract() == 0.0 && k.abs() <= 16.0 {
                    k as i8
                } else {
                    i8::MIN
                }
            })
            .collect();
        let ok = (0..t.len())
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|r| {
                let ks = &k[t.offsets[r] as usize..t.offsets[r + 1] as usize];
                ks.iter().all(|&k| k != i8::MIN)
                    && ks.iter().map(|&k| (k as i32).abs()).sum::<i32>() <= 32
            })
            .collect();
        let pk: Vec<i64> = p.weights.iter().map(|&w| (w * 16.0) as i64).collect();
        let dyadic_pattern = !pk.is_empty()
            && p.weights
                .iter()
                .zip(&pk)
                .all(|(&w, &k)| w * 16.0 == k as f64)
            && pk.iter().all(|k| k.abs() <= 16)
            && pk.iter().map(|k| k.abs()).sum::<i64>() <= 32;
        DyadicRows {
            k,
            ok,
            pattern: dyadic_pattern.then_some((pk, p.rows)),
        }
    }
}

/// `Σ k_i y[idx_i]` for a row of `M` entries (`None` if `k` or `idx` is not that long).
#[inline(always)]
fn idot<const M: usize>(k: &[i64], idx: &[u32], y: &[[i64; 3]]) -> Option<[i64; 3]> {
    let (Ok(k), Ok(idx)) = (<&[i64; M]>::try_from(k), <&[u32; M]>::try_from(idx)) else {
        return None;
    };
    let mut acc = [0i64; 3];
    for i in 0..M {
        let v = y[idx[i] as usize];
        for q in 0..3 {
            acc[q] += k[i] * v[q];
        }
    }
    Some(acc)
}

/// Sources of the dyadic prediction lie in `[−2^DYADIC_BOUND, 2^DYADIC_BOUND)`.
const DYADIC_BOUND: u32 = 47;

/// Whether every value of `x` lies in `[−2^DYADIC_BOUND, 2^DYADIC_BOUND)`.
fn all_small(x: &[[i64; 3]]) -> bool {
    x.par_chunks(1 << 14).all(|c| {
        let mut chk = 0u64;
        for y in c {
            for &v in y {
                chk |= (v as u64).wrapping_add(1 << DYADIC_BOUND);
            }
        }
        chk >> (DYADIC_BOUND + 1) == 0
    })
}

impl<'h> IntTriangleWavelet<'h> {
    /// The integer midpoint wavelet (prediction `⌊(x_a + x_b)/2 + ½⌋`), lifted if `lifted`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `h` is not a triangle (1-to-4) hierarchy.
    pub fn midpoint(h: &'h Hierarchy, lifted: bool) -> Result<Self> {
        Self::from_scheme(
            h,
            &SubdivideOptions {
                scheme: Scheme::Midpoint,
                ..Default::default()
            },
            lifted,
        )
    }

    /// The integer wavelet of an interpolating scheme of [`crate::subdivision`] (midpoint or
    /// butterfly), its tables built on the hierarchy's base mesh (`opts.levels` is ignored).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if `h` is not a triangle hierarchy or the scheme is not
    /// interpolating; as [`Refinement::build`].
    pub fn from_scheme(h: &'h Hierarchy, opts: &SubdivideOptions, lifted: bool) -> Result<Self> {
        if h.split != Split::Triangles {
            return Err(Error::InvalidArgument(
                "integer triangle wavelets need a triangle (1-to-4) hierarchy; use Bertram's integer wavelets for quad hierarchies".into(),
            ));
        }
        let o = SubdivideOptions {
            levels: h.levels() as u32,
            ..*opts
        };
        // Midpoint and butterfly with the default options on an untagged hierarchy: the same
        // tables, bit for bit, built from the hierarchy's level topologies (no refinement of
        // the base mesh; [`TriangleWavelet::butterfly`]).
        let d = SubdivideOptions::default();
        let untagged = h.topologies.iter().all(|t| {
            t.edge_sharpness.iter().all(|&s| s == 0.0)
                && t.vertex_sharpness.iter().all(|&s| s == 0.0)
        });
        let defaults = opts.boundary == d.boundary
            && opts.creasing == d.creasing
            && opts.loop_weights == d.loop_weights
            && opts.sharp_angle.is_none();
        let (stencils, patterns) = match opts.scheme {
            Scheme::Midpoint if defaults && untagged && h.levels() > 0 => {
                TriangleWavelet::midpoint(h, false)?.into_parts()
            }
            Scheme::Butterfly if defaults && untagged && h.levels() > 0 => {
                TriangleWavelet::butterfly(h, false)?.into_parts()
            }
            _ => (Refinement::build(&h.base, &o, true)?.stencils, Vec::new()),
        };
        for (j, t) in stencils.iter().enumerate() {
            if t.num_sources as usize != h.num_vertices(j) || t.len() != h.num_vertices(j + 1) {
                return Err(Error::InvalidArgument(format!(
                    "level {j}: the scheme's table does not match the hierarchy"
                )));
            }
            for v in 0..t.num_sources as usize {
                let (a, b) = (t.offsets[v] as usize, t.offsets[v + 1] as usize);
                if b != a + 1 || t.indices[a] as usize != v || t.weights[a] != 1.0 {
                    return Err(Error::InvalidArgument(format!(
                        "level {j}: the {:?} scheme is not interpolating (even vertex {v} moves); integer wavelets take midpoint or butterfly",
                        opts.scheme
                    )));
                }
            }
        }
        Ok(Self::with_tables(h, stencils, patterns, lifted))
    }

    /// The wavelet of checked `tables`, with its plans; `patterns` are the tables' row
    /// patterns if already built (else built here).
    fn with_tables(
        h: &'h Hierarchy,
        tables: Vec<StencilTable>,
        mut patterns: Vec<RowPattern>,
        lifted: bool,
    ) -> Self {
        if patterns.len() != tables.len() {
            patterns = tables.iter().map(RowPattern::new).collect();
        }
        IntTriangleWavelet {
            h,
            dyadic: tables
                .iter()
                .zip(patterns)
                .map(|(t, p)| DyadicRows::new(t, p))
                .collect(),
            tables,
            update_plan: if lifted {
                UpdatePlan::new(h)
            } else {
                UpdatePlan::default()
            },
            lifted,
        }
    }

    /// The hierarchy.
    pub fn hierarchy(&self) -> &'h Hierarchy {
        self.h
    }

    fn check(&self, data: &[[i64; 3]]) -> Result<()> {
        let l = self.tables.len();
        let n = self.h.num_vertices(l);
        if data.len() != n {
            return Err(Error::InvalidArgument(format!(
                "{} integer values given, the finest level has {n} vertices",
                data.len()
            )));
        }
        Ok(())
    }

    /// Full analysis in place: `data` holds the finest level's integer coordinates on entry
    /// and `[base | details 0 | … | details L−1]` on return.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a wrong length or a coordinate beyond [`MAX_COORD`]
    /// (naming the vertex).
    pub fn forward(&self, data: &mut [[i64; 3]]) -> Result<()> {
        self.check(data)?;
        if let Some(i) = data
            .par_iter()
            .position_first(|x| x.iter().any(|c| c.abs() > MAX_COORD))
        {
            return Err(Error::InvalidArgument(format!(
                "vertex {i}: coordinate {:?} beyond ±2^40; quantize to fewer bits",
                data[i]
            )));
        }
        for j in (0..self.tables.len()).rev() {
            self.forward_level(j, &mut data[..self.h.num_vertices(j + 1)]);
        }
        Ok(())
    }

    /// One analysis step on level `level + 1`'s values (`V_{j+1}` entries, no range check:
    /// [`IntTriangleWavelet::forward`] checks the whole hierarchy).
    ///
    /// # Panics
    /// If `data` does not have `V_{j+1}` entries or `level` does not exist.
    pub fn forward_level(&self, level: usize, data: &mut [[i64; 3]]) {
        assert_eq!(data.len(), self.h.num_vertices(level + 1), "level size");
        let (even, odd) = data.split_at_mut(self.h.num_vertices(level));
        self.predict(level, even, odd, -1);
        if self.lifted {
            self.update(level, even, odd, 1);
        }
    }

    /// One synthesis step, the inverse of [`IntTriangleWavelet::forward_level`].
    ///
    /// # Panics
    /// If `data` does not have `V_{j+1}` entries or `level` does not exist.
    pub fn inverse_level(&self, level: usize, data: &mut [[i64; 3]]) {
        assert_eq!(data.len(), self.h.num_vertices(level + 1), "level size");
        let (even, odd) = data.split_at_mut(self.h.num_vertices(level));
        if self.lifted {
            self.update(level, even, odd, -1);
        }
        self.predict(level, even, odd, 1);
    }

    /// Full synthesis in place, the exact inverse of [`IntTriangleWavelet::forward`].
    /// Truncated data (finer details zero) gives the integer version of the plain scheme.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a wrong length or a value beyond `2^50` in magnitude
    /// (not produced by [`IntTriangleWavelet::forward`]; it could overflow).
    pub fn inverse(&self, data: &mut [[i64; 3]]) -> Result<()> {
        self.check(data)?;
        if let Some(i) = data
            .par_iter()
            .position_first(|x| x.iter().any(|c| c.abs() > 1 << 50))
        {
            return Err(Error::InvalidArgument(format!(
                "coefficient {i}: {:?} beyond ±2^50, not produced by the forward transform",
                data[i]
            )));
        }
        for j in 0..self.tables.len() {
            self.inverse_level(j, &mut data[..self.h.num_vertices(j + 1)]);
        }
        Ok(())
    }

    /// `odd[e] += sign · ⌊P_e(even) + ½⌋`.
    fn predict(&self, level: usize, even: &[[i64; 3]], odd: &mut [[i64; 3]], sign: i64) {
        let t = &self.tables[level];
        let nc = even.len();
        let dyadic = self.dyadic.get(level).filter(|d| {
            d.k.len() == t.weights.len()
                && d.ok.len() == t.len()
                && d.pattern.as_ref().is_none_or(|p| p.1.len() == t.len())
                && all_small(even)
        });
        odd.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            let first = nc + c * CHUNK;
            for (i, x) in out.iter_mut().enumerate() {
                let r = first + i;
                let (a, b) = (t.offsets[r] as usize, t.offsets[r + 1] as usize);
                let pattern = dyadic.and_then(|d| d.pattern.as_ref()).filter(|p| p.1[r]);
                if let Some((pk, _)) = pattern {
                    let idx = &t.indices[a..b];
                    if let Some(acc) = idot::<8>(pk, idx, even).or_else(|| idot::<2>(pk, idx, even))
                    {
                        for q in 0..3 {
                            x[q] += sign * ((acc[q] + 8) >> 4);
                        }
                        continue;
                    }
                }
                if let Some(d) = dyadic.filter(|d| d.ok[r]) {
                    let mut acc = [0i64; 3];
                    for (&k, &w) in t.indices[a..b].iter().zip(&d.k[a..b]) {
                        let y = even[k as usize];
                        for q in 0..3 {
                            acc[q] += w as i64 * y[q];
                        }
                    }
                    for q in 0..3 {
                        x[q] += sign * ((acc[q] + 8) >> 4);
                    }
                    continue;
                }
                let mut acc = [0.0f64; 3];
                for (&k, &w) in t.indices[a..b].iter().zip(&t.weights[a..b]) {
                    let y = even[k as usize];
                    for q in 0..3 {
                        acc[q] += w * y[q] as f64;
                    }
                }
                for q in 0..3 {
                    x[q] += sign * floor_i64(acc[q] + 0.5);
                }
            }
        });
    }

    /// `even[v] += sign · ⌊3 Σ φ_e d_e / (8 f_v) + ½⌋`, exactly.
    fn update(&self, level: usize, even: &mut [[i64; 3]], odd: &[[i64; 3]], sign: i64) {
        let t = self.h.topology(level);
        self.update_plan
            .for_each(t, level, even, |x, nf, edges, phi| {
                let f = nf as i64;
                let mut s = [0i64; 3];
                for (k, &e) in edges.iter().enumerate() {
                    let phi = edge_face_count(t, phi, k, e) as i64;
                    let d = odd[e as usize];
                    for q in 0..3 {
                        s[q] += phi * d[q];
                    }
                }
                // ⌊3s/(8f) + ½⌋ = ⌊(6s + 8f) / (16f)⌋; the common face counts divide by
                // constants (multiplications after compilation).
                let r = |n: i64| match f {
                    6 => floor_div_const::<96>(n + 48),
                    3 => floor_div_const::<48>(n + 24),
                    _ => (n + 8 * f).div_euclid(16 * f),
                };
                for q in 0..3 {
                    x[q] += sign * r(6 * s[q]);
                }
            });
    }
}

/// `⌊y⌋` for `|y| < 2^62` without a libm call (the baseline x86-64 target has no rounding
/// instruction); exact, so encoder and decoder agree.
#[inline]
fn floor_i64(y: f64) -> i64 {
    let t = y as i64; // towards zero
    if (t as f64) > y {
        t - 1
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::generate;
    use crate::subdivision::subdivide;
    use crate::wavelet::triangle::TriangleWavelet;

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
    }

    /// A Loop-smooth sphere (or grid with boundary) hierarchy, quantized to `bits`.
    fn quantized(base: &crate::mesh::Mesh, levels: u32, bits: u32) -> (Hierarchy, Vec<[i64; 3]>) {
        let opts = SubdivideOptions {
            scheme: Scheme::Loop,
            levels,
            ..Default::default()
        };
        let p: Vec<DVec3> = subdivide(base, &opts)
            .unwrap()
            .positions
            .into_iter()
            .map(|p| {
                if base.num_faces() == 20 {
                    p.normalize()
                } else {
                    p
                }
            })
            .collect();
        let h = Hierarchy::new(base, levels, Split::Triangles, Some(p)).unwrap();
        let s = ((1i64 << bits) - 1) as f64 / 2.0;
        let q = h
            .positions
            .iter()
            .map(|p| ((*p + 1.0) * s).round().to_array().map(|c| c as i64))
            .collect();
        (h, q)
    }

    fn schemes(h: &Hierarchy) -> Vec<(&'static str, IntTriangleWavelet<'_>)> {
        let bf = SubdivideOptions {
            scheme: Scheme::Butterfly,
            ..Default::default()
        };
        vec![
            ("midpoint", IntTriangleWavelet::midpoint(h, false).unwrap()),
            (
                "midpoint-lifted",
                IntTriangleWavelet::midpoint(h, true).unwrap(),
            ),
            (
                "butterfly",
                IntTriangleWavelet::from_scheme(h, &bf, false).unwrap(),
            ),
            (
                "butterfly-lifted",
                IntTriangleWavelet::from_scheme(h, &bf, true).unwrap(),
            ),
        ]
    }

    /// The tables built from the level topologies (default options, untagged hierarchy) give
    /// the transform of the tables of a refinement of the base mesh, bit for bit.
    #[test]
    fn topology_tables_match_the_refinement() {
        for (h, q) in [
            quantized(&generate::icosahedron(), 3, 16),
            quantized(&generate::grid(3, 2, true), 3, 20),
        ] {
            for (name, w) in schemes(&h) {
                let scheme = if name.starts_with("midpoint") {
                    Scheme::Midpoint
                } else {
                    Scheme::Butterfly
                };
                let o = SubdivideOptions {
                    scheme,
                    levels: h.levels() as u32,
                    ..Default::default()
                };
                let mut r = IntTriangleWavelet::with_tables(
                    &h,
                    Refinement::build(&h.base, &o, true).unwrap().stencils,
                    Vec::new(),
                    w.lifted,
                );
                // The update's fallback (no plan: edge-face lookups).
                r.update_plan = UpdatePlan::default();
                let (mut a, mut b) = (q.clone(), q.clone());
                w.forward(&mut a).unwrap();
                r.forward(&mut b).unwrap();
                assert_eq!(a, b, "{name}");
                if scheme == Scheme::Butterfly {
                    assert_eq!(w.tables, r.tables, "{name}");
                }
            }
        }
    }

    /// The exact `i64` evaluation of dyadic rows gives the `f64` evaluation's values, on
    /// smooth data, on random data and beyond `2^47` (where the `f64` path is taken).
    #[test]
    fn dyadic_rows_match_f64() {
        let meshes = [
            quantized(&generate::icosahedron(), 4, 16),
            quantized(&generate::grid(3, 2, true), 3, 20),
        ];
        for (h, q) in &meshes {
            let mut rng = Rng(9);
            let random: Vec<[i64; 3]> = q
                .iter()
                .map(|_| [0; 3].map(|_: i64| (rng.next() % (1 << 41)) as i64 - (1 << 40)))
                .collect();
            let huge: Vec<[i64; 3]> = q.iter().map(|c| c.map(|x| x << 32)).collect();
            for (name, w) in schemes(h) {
                assert!(w.dyadic.iter().all(|d| d.ok.iter().any(|&ok| ok)), "{name}");
                let mut plain = w.clone();
                plain.dyadic.clear();
                for input in [q, &random, &huge] {
                    let (mut a, mut b) = (input.clone(), input.clone());
                    (0..h.levels()).rev().for_each(|j| {
                        w.forward_level(j, &mut a[..h.num_vertices(j + 1)]);
                        plain.forward_level(j, &mut b[..h.num_vertices(j + 1)]);
                    });
                    assert_eq!(a, b, "{name} forward");
                    (0..h.levels()).for_each(|j| {
                        w.inverse_level(j, &mut a[..h.num_vertices(j + 1)]);
                        plain.inverse_level(j, &mut b[..h.num_vertices(j + 1)]);
                    });
                    assert_eq!(a, b, "{name} inverse");
                    assert_eq!(&a, input, "{name} lossless");
                }
            }
        }
    }

    #[test]
    fn lossless_on_smooth_and_random_data() {
        let meshes = [
            quantized(&generate::icosahedron(), 4, 16),
            quantized(&generate::grid(3, 2, true), 3, 20),
        ];
        for (h, q) in &meshes {
            let mut rng = Rng(5);
            let random: Vec<[i64; 3]> = q
                .iter()
                .map(|_| [0; 3].map(|_: i64| (rng.next() % (1 << 30)) as i64 - (1 << 29)))
                .collect();
            for (name, w) in schemes(h) {
                for input in [q, &random] {
                    let mut d = input.clone();
                    w.forward(&mut d).unwrap();
                    assert_ne!(&d, input, "{name}: the transform did something");
                    w.inverse(&mut d).unwrap();
                    assert_eq!(&d, input, "{name}: not lossless");
                }
            }
        }
    }

    /// The integer transform follows the float one: coarse values and details within a few
    /// units of rounding per level, and smooth data compacts its energy.
    #[test]
    fn close_to_the_float_transform_and_compacts() {
        let (h, q) = quantized(&generate::icosahedron(), 4, 16);
        let qh = Hierarchy::new(
            &h.base,
            h.levels() as u32,
            Split::Triangles,
            Some(
                q.iter()
                    .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64))
                    .collect(),
            ),
        )
        .unwrap();
        for lifted in [false, true] {
            let w = IntTriangleWavelet::midpoint(&h, lifted).unwrap();
            let mut d = q.clone();
            w.forward(&mut d).unwrap();
            let wf = TriangleWavelet::midpoint(&qh, lifted).unwrap();
            let f = wf.decompose(&qh.positions).unwrap().to_flat();
            let worst = d
                .iter()
                .zip(&f)
                .map(|(a, b)| {
                    (DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64) - *b)
                        .abs()
                        .max_element()
                })
                .fold(0.0, f64::max);
            assert!(worst <= 4.0, "lifted {lifted}: {worst}");
            let mean = |j: usize| {
                let r = h.num_vertices(j)..h.num_vertices(j + 1);
                d[r.clone()]
                    .iter()
                    .map(|x| ((x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) as f64).sqrt())
                    .sum::<f64>()
                    / r.len() as f64
            };
            assert!(mean(3) * 10.0 < mean(0), "{} vs {}", mean(0), mean(3));
        }
    }

    /// Zero details synthesize the (rounded) plain scheme: within half a unit per level of the
    /// float midpoint subdivision of the base.
    #[test]
    fn zero_details_is_rounded_subdivision() {
        let (h, q) = quantized(&generate::icosahedron(), 3, 16);
        let w = IntTriangleWavelet::midpoint(&h, false).unwrap();
        let mut d = q.clone();
        w.forward(&mut d).unwrap();
        let nb = h.num_vertices(0);
        d[nb..].iter_mut().for_each(|x| *x = [0; 3]);
        w.inverse(&mut d).unwrap();
        let base: Vec<DVec3> = q[..nb]
            .iter()
            .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64))
            .collect();
        let mut m = h.base.clone();
        m.positions = base;
        let plain = subdivide(
            &m,
            &SubdivideOptions {
                scheme: Scheme::Midpoint,
                levels: 3,
                ..Default::default()
            },
        )
        .unwrap();
        for (a, b) in d.iter().zip(&plain.positions) {
            let a = DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64);
            assert!((a - *b).abs().max_element() <= 1.5, "{a} vs {b}");
        }
    }

    #[test]
    fn floor_without_libm() {
        for y in [
            -2.5,
            -2.0,
            -1.5,
            -0.5,
            -0.0,
            0.0,
            0.49,
            0.5,
            1.0,
            7.99,
            -7.01,
            1e15 + 0.5,
        ] {
            assert_eq!(floor_i64(y), y.floor() as i64, "{y}");
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let (h, q) = quantized(&generate::icosahedron(), 2, 16);
        let w = IntTriangleWavelet::midpoint(&h, true).unwrap();
        assert!(w.forward(&mut q[..5].to_vec()).is_err());
        let mut big = q.clone();
        big[7][1] = MAX_COORD + 1;
        let e = w.forward(&mut big).unwrap_err().to_string();
        assert!(e.contains("vertex 7"), "{e}");
        let mut huge = q.clone();
        huge[3][0] = 1 << 52;
        assert!(w.inverse(&mut huge).is_err());
        let loop_opts = SubdivideOptions::default();
        assert!(IntTriangleWavelet::from_scheme(&h, &loop_opts, true).is_err());
    }
}

//! Wavelet transforms on meshes with subdivision connectivity
//! ([`crate::hierarchy::Hierarchy`]).
//!
//! - [`triangle`]: triangle hierarchies, Maret 2003 §4.2.3 (computation of details coefficients)
//!   and §4.4.3 (details in local frames): midpoint lifted or not, any interpolating scheme's
//!   prediction (butterfly), Loop as in Khodakovsky–Schröder–Sweldens PGC;
//! - [`triangle_int`]: integer-to-integer lifted midpoint and butterfly wavelets (lossless
//!   mode of the codec);
//! - [`frames`]: the local frames of detail vectors;
//! - [`report`]: per-level errors, detail statistics, reconstruction error and timings of
//!   any of these wavelets on a detected semi-regular mesh (`subwave wavelet`);
//! - [`stability`]: Bertram et al.'s noise experiment (§5.2, Fig. 17) as a report
//!   (`subwave stability`);
//! - [`bertram`]: Bertram, Duchaineau, Hamann & Joy's generalized (lifted, biorthogonal)
//!   B-spline wavelets on Catmull-Clark quad hierarchies — linear, cubic and quintic — in
//!   floating point and as an exact integer-to-integer transform (§3–4.3 of the paper). With
//!   zero details the synthesis is plain subdivision (bilinear, bicubic "MLCA", biquintic),
//!   which [`crate::subdivision::Scheme::Bicubic`] and
//!   [`crate::subdivision::Scheme::Biquintic`] use.
//!
//! Coefficient layout (shared by every transform here): a level's data is a flat slice in the
//! refiner's vertex order ([`crate::subdivision::refine`], ordering contract): the coarse
//! level's `V` vertices, then one entry per coarse edge, then (quad hierarchies) one per coarse
//! face. Analysis replaces the first `V` entries by the coarse positions and the rest by detail
//! coefficients; since each coarse level is a prefix of the finer one, analysing every level
//! leaves `[base mesh | details of level 0 | details of level 1 | …]`.

pub mod bertram;
pub mod frames;
pub mod report;
pub mod stability;
pub mod triangle;
pub mod triangle_int;

/// `⌊n / D⌋` for a compile-time `D > 0`: a shift for the power-of-two part, a division by the
/// odd part `c` (a multiplication after compilation).
///
/// The odd division is unsigned: for `|m| < 2^58`, `⌊m / c⌋ = (m + c·2^58) / c − 2^58` with
/// `m + c·2^58 ≥ 0`, one multiply-high and no remainder fix-up (`div_euclid` computes the
/// quotient, the remainder and a correction; measured 10% of the quintic integer lifts).
/// Shared by the integer lifts of [`bertram`] and [`triangle_int`].
/// Larger `|m|`, which the regular formulas never produce (their intermediates stay below
/// `2^58`, see `bertram::FAST_BOUND`), take `div_euclid`.
#[inline(always)]
pub(crate) fn floor_div_const<const D: i64>(n: i64) -> i64 {
    let k = D.trailing_zeros();
    let m = n >> k;
    if m.unsigned_abs() < 1 << 58 {
        floor_div_const_small::<D>(n)
    } else {
        m.div_euclid(D >> k)
    }
}

/// [`floor_div_const`] for `|n >> k| < 2^58` (`2^k` the power-of-two part of `D`;
/// debug-asserted), which the regular formulas' intermediates satisfy
/// (`bertram::FAST_BOUND`): no range check before the multiply-high.
#[inline(always)]
pub(crate) fn floor_div_const_small<const D: i64>(n: i64) -> i64 {
    let k = D.trailing_zeros();
    let c = D >> k;
    let m = n >> k;
    debug_assert!(
        m.unsigned_abs() < 1 << 58,
        "{n} / {D} outside the fast bound"
    );
    if c == 1 {
        m
    } else if c < 32 {
        let bias = c << 58;
        (((m + bias) as u64) / c as u64) as i64 - (1 << 58)
    } else {
        m.div_euclid(c)
    }
}

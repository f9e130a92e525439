//! Quantization of wavelet coefficients and positions.
//!
//! Maret 2003 §4.4.1 ("Binary Representation of Coefficients"): with `d_max` the largest
//! coefficient magnitude (eq. 4.7), each coefficient becomes the integer
//! `c = ⌊(2^N − 1) · |d| / d_max⌋` with a sign (eqs. 4.8-4.9), i.e. a dead-zone uniform
//! quantizer of step `Δ = d_max / (2^N − 1)`. AFX quantizes each component (x, y, z)
//! separately ([`ComponentMode::Independent`]: one `d_max` per component); Maret's proposed
//! extension (§4.5.2-4.5.3) aligns the least significant bits of the three components
//! ([`ComponentMode::Aligned`]: one `Δ` for all, so that a bit plane has the same weight in
//! the squared error whatever the component, which matters with local frames where the normal
//! component dominates).
//!
//! Decoding (eqs. 4.11-4.12) reconstructs a coefficient known to lie in the integer interval
//! `[lo, lo + 2^w)` at the middle of the corresponding real interval,
//! `(lo + 2^w / 2) · Δ` ([`reconstruct`]); a coefficient not yet significant is 0. (Maret's
//! 4.11 takes the middle of the integer end points, `3·2^{n−2} + ½`; ours is the middle of the
//! real interval covered by the dead-zone quantizer, which is what minimises the squared error
//! for a uniform density.)
//!
//! Positions (base mesh, lossless mode) are quantized on a uniform grid over the bounding box
//! ([`Grid`]).

use glam::DVec3;

/// How the three components of a detail vector share quantization steps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ComponentMode {
    /// One step per component, from its own `d_max` (MPEG-4 AFX).
    Independent,
    /// One step for all components (least significant bits aligned, Maret §4.5.3).
    #[default]
    Aligned,
}

/// Largest number of magnitude bit planes (`N` of eq. 4.8).
pub const MAX_PLANES: u32 = 30;

/// Per-component quantization steps (eq. 4.8) for `bits` = `N` bit planes.
///
/// Components whose coefficients are all zero get step 1. `bits` is clamped to
/// `1..=MAX_PLANES`.
pub fn steps(details: &[DVec3], bits: u32, mode: ComponentMode) -> [f64; 3] {
    let bits = bits.clamp(1, MAX_PLANES);
    let mut dmax = [0.0f64; 3];
    for d in details {
        for (c, m) in dmax.iter_mut().enumerate() {
            *m = m.max(d[c].abs());
        }
    }
    if mode == ComponentMode::Aligned {
        let m = dmax[0].max(dmax[1]).max(dmax[2]);
        dmax = [m; 3];
    }
    let levels = ((1u64 << bits) - 1) as f64;
    dmax.map(|m| {
        if m > 0.0 && m.is_finite() {
            m / levels
        } else {
            1.0
        }
    })
}

/// The quantized magnitude `⌊|d| / Δ⌋` (eq. 4.8), clamped to `2^MAX_PLANES − 1`, and the
/// sign (`true` for negative).
#[inline]
pub fn quantize(d: f64, step: f64) -> (u32, bool) {
    let q = (d.abs() / step).floor();
    let q = if q.is_finite() {
        q.min(((1u64 << MAX_PLANES) - 1) as f64) as u32
    } else {
        0
    };
    (q, d < 0.0)
}

/// The mid-interval reconstruction (eqs. 4.11-4.12) of a magnitude known to lie in
/// `[lo, lo + 2^w)`, with its sign, times the step.
#[inline]
pub fn reconstruct(lo: u32, w: u32, negative: bool, step: f64) -> f64 {
    let m = (lo as f64 + (1u64 << w) as f64 * 0.5) * step;
    if negative {
        -m
    } else {
        m
    }
}

/// A uniform grid over a box: `x = origin + q · step` per component.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// Grid origin (the box's minimum corner).
    pub origin: DVec3,
    /// Grid step (the same for the three axes).
    pub step: f64,
}

impl Grid {
    /// A grid with `2^bits` steps along the box's longest side (`bits` clamped to 1..=30).
    pub fn new(min: DVec3, max: DVec3, bits: u32) -> Grid {
        let bits = bits.clamp(1, 30);
        let extent = (max - min).max_element();
        let step = if extent > 0.0 && extent.is_finite() {
            extent / ((1u64 << bits) - 1) as f64
        } else {
            1.0
        };
        Grid { origin: min, step }
    }

    /// The nearest grid point's integer coordinates (saturating at `±2^31`).
    #[inline]
    pub fn quantize(&self, p: DVec3) -> [i32; 3] {
        let q = ((p - self.origin) / self.step).round();
        [0, 1, 2].map(|c| {
            let v = q[c];
            if v.is_finite() {
                v.clamp(i32::MIN as f64, i32::MAX as f64) as i32
            } else {
                0
            }
        })
    }

    /// The position of integer coordinates.
    #[inline]
    pub fn dequantize(&self, q: [i64; 3]) -> DVec3 {
        self.origin + DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64) * self.step
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_follow_eq_4_8() {
        let d = [DVec3::new(1.0, -0.5, 0.25), DVec3::new(-2.0, 0.1, 0.0)];
        let s = steps(&d, 4, ComponentMode::Independent);
        assert_eq!(s, [2.0 / 15.0, 0.5 / 15.0, 0.25 / 15.0]);
        let s = steps(&d, 4, ComponentMode::Aligned);
        assert_eq!(s, [2.0 / 15.0; 3]);
        // The largest coefficient maps to 2^N - 1.
        assert_eq!(quantize(-2.0, 2.0 / 15.0), (15, true));
        assert_eq!(quantize(0.1, 2.0 / 15.0), (0, false));
    }

    #[test]
    fn reconstruction_is_mid_interval() {
        assert_eq!(reconstruct(8, 3, false, 1.0), 12.0);
        assert_eq!(reconstruct(5, 0, true, 2.0), -11.0);
    }

    #[test]
    fn grid_round_trip() {
        let g = Grid::new(DVec3::ZERO, DVec3::new(2.0, 1.0, 1.0), 10);
        let p = DVec3::new(1.3, 0.2, 0.9);
        let q = g.quantize(p);
        let back = g.dequantize(q.map(i64::from));
        assert!((back - p).abs().max_element() <= g.step / 2.0 + 1e-12);
    }
}

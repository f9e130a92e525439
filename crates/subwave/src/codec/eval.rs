//! Rate–distortion evaluation of progressive streams (`subwave eval`, the demo).
//!
//! A progressive stream is cut at several byte budgets; each prefix is decoded and compared
//! with the *input* mesh by the Metro-style distance of [`crate::distance`] (RMS both ways,
//! Hausdorff, PSNR = 20 log10(input diagonal / larger one-sided RMS), the convention of the
//! progressive geometry compression literature and of `../shared/peers/README.md`). Rates
//! are in bits per *input* vertex, so that a remeshed stream is charged for the input it
//! stands for, as Draco's points are (`../shared/peers/draco_rd.py`).

use rayon::prelude::*;
use serde::Serialize;

use crate::distance::distance;
use crate::mesh::Mesh;
use crate::{Error, Result};

/// One point of a rate–distortion curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RdPoint {
    /// Bytes of the stream prefix.
    pub bytes: usize,
    /// Bits per input vertex: `8 · bytes / V_input`.
    pub bpv: f64,
    /// Symmetric RMS surface distance (the larger one-sided RMS).
    pub rms: f64,
    /// Hausdorff distance.
    pub max: f64,
    /// PSNR in dB against the input's bounding-box diagonal.
    pub psnr: f64,
}

/// `count` byte budgets spaced geometrically from `min` to `full` (both included), strictly
/// increasing (duplicates after rounding are dropped, so fewer may come back when
/// `full - min` is small).
///
/// # Errors
/// [`Error::InvalidArgument`] if `min == 0`, `min > full` or `count < 2`.
pub fn budgets(min: usize, full: usize, count: usize) -> Result<Vec<usize>> {
    if min == 0 || min > full || count < 2 {
        return Err(Error::InvalidArgument(format!(
            "budgets: need 0 < min ≤ full and count ≥ 2 (min {min}, full {full}, count {count})"
        )));
    }
    let ratio = (full as f64 / min as f64).powf(1.0 / (count - 1) as f64);
    let mut out: Vec<usize> = (0..count)
        .map(|i| {
            if i + 1 == count {
                full
            } else {
                ((min as f64) * ratio.powi(i as i32)).round() as usize
            }
        })
        .collect();
    out.dedup();
    Ok(out)
}

/// Decodes `decode(b)` for each budget `b` and measures it against `input` with `samples`
/// area samples per surface. `decode` returns the mesh a `b`-byte prefix decodes to and the
/// bytes it actually used (≤ `b`; a point reports the budget, the bytes a client fetched).
/// Points are evaluated in parallel; their order is that of `budgets`.
///
/// # Errors
/// The first error of `decode` or of the distance (e.g. a decoded mesh without faces).
pub fn rate_distortion<F>(
    input: &Mesh,
    budgets: &[usize],
    samples: usize,
    decode: F,
) -> Result<Vec<RdPoint>>
where
    F: Fn(usize) -> Result<Mesh> + Sync,
{
    let vertices = input.referenced().iter().filter(|&&u| u).count().max(1) as f64;
    budgets
        .par_iter()
        .map(|&bytes| {
            let mesh = decode(bytes)?;
            let d = distance(input, &mesh, samples)?;
            Ok(RdPoint {
                bytes,
                bpv: 8.0 * bytes as f64 / vertices,
                rms: d.rms,
                max: d.max,
                psnr: d.psnr,
            })
        })
        .collect()
}

/// The rate (bits per vertex) at which a curve reaches `psnr`, interpolated linearly in
/// PSNR between the two points around it (points sorted by rate; PSNR assumed to increase
/// with rate). `None` if the curve never reaches `psnr` or starts above it.
pub fn bpv_at_psnr(points: &[RdPoint], psnr: f64) -> Option<f64> {
    points.windows(2).find_map(|w| {
        let (a, b) = (w[0], w[1]);
        if a.psnr <= psnr && psnr <= b.psnr && b.psnr > a.psnr {
            let t = (psnr - a.psnr) / (b.psnr - a.psnr);
            Some(a.bpv + t * (b.bpv - a.bpv))
        } else if a.psnr == psnr {
            Some(a.bpv)
        } else {
            None
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;

    #[test]
    fn budgets_are_geometric_and_end_at_full() {
        let b = budgets(100, 10_000, 5).unwrap();
        assert_eq!(b, vec![100, 316, 1000, 3162, 10_000]);
        assert_eq!(budgets(5, 7, 8).unwrap(), vec![5, 6, 7]);
        assert!(budgets(0, 7, 8).is_err() && budgets(9, 7, 8).is_err());
        assert!(budgets(1, 7, 1).is_err());
    }

    #[test]
    fn coarser_prefixes_are_further_from_the_input() {
        // "Decoding" b bytes gives the sphere shrunk by 1/b: distance falls with the budget.
        let input = generate::icosphere(3);
        let pts = rate_distortion(&input, &[10, 100, 1000], 20_000, |b| {
            let mut m = input.clone();
            for p in &mut m.positions {
                *p *= 1.0 - 1.0 / b as f64;
            }
            Ok(m)
        })
        .unwrap();
        assert_eq!(
            pts.iter().map(|p| p.bytes).collect::<Vec<_>>(),
            [10, 100, 1000]
        );
        assert!(
            pts[0].psnr < pts[1].psnr && pts[1].psnr < pts[2].psnr,
            "{pts:?}"
        );
        assert!((pts[2].rms - 1e-3).abs() < 2e-4, "{pts:?}");
        let v = input.num_vertices() as f64;
        assert!((pts[1].bpv - 800.0 / v).abs() < 1e-12);
        let mid = bpv_at_psnr(&pts, (pts[0].psnr + pts[1].psnr) / 2.0).unwrap();
        assert!((mid - (pts[0].bpv + pts[1].bpv) / 2.0).abs() < 1e-9);
        assert_eq!(bpv_at_psnr(&pts, pts[2].psnr + 1.0), None);
    }

    #[test]
    fn decode_errors_propagate() {
        let input = generate::cube();
        let e = rate_distortion(&input, &[1], 100, |_| {
            Err(Error::InvalidArgument("boom".into()))
        })
        .unwrap_err();
        assert!(e.to_string().contains("boom"));
    }
}

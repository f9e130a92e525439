//! Bertram et al.'s stability experiment (*Generalized B-spline subdivision-surface wavelets
//! for geometry compression*, §5.2, Fig. 17), as a report: `subwave stability`.
//!
//! A base mesh is subdivided `L` times with zero details by the wavelet's own synthesis
//! (bilinear, MLCA bicubic or biquintic: [`BSplineWavelet::subdivide`]), white noise is added
//! to the finest level, and both the clean and the noisy meshes are low-passed level by level
//! with the analysis ([`BSplineWavelet::analyze_level`]). The clean mesh low-passes to itself
//! (zero details), so the difference at each level is the noise that the low-pass filter lets
//! through. A stable filter shrinks it (linear), an unstable one amplifies it (quintic: the
//! paper's "noise increases dramatically with each level").
//!
//! # Measure
//! Per level `j` (finest first): `rms_noise` is the RMS of the vertex distances between the
//! noisy and clean low-pass levels (model units), `relative` divides it by the mean edge length
//! of the clean level `j` — the amplitude one sees relative to the mesh, which is how Fig. 17
//! shows it — and `gain` is `rms_noise` of level `j` over that of the finest level.
//!
//! # Noise
//! Each coordinate of each finest vertex gets an independent uniform value in
//! `[−a, a)` with `a = noise · (mean finest edge length)`, from a fixed-seed splitmix64
//! generator (reproducible runs).

use glam::DVec3;
use serde::Serialize;

use super::bertram::{level_sizes, quad_hierarchy, BSplineWavelet, Degree};
use crate::mesh::Mesh;
use crate::subdivision::refine::{refine_topology, Split};
use crate::topology::Topology;
use crate::{Error, Result};

/// Noise of one low-pass level.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StabilityLevel {
    /// Level (`L` is the finest, where the noise was added).
    pub level: usize,
    /// Vertices of the level.
    pub vertices: usize,
    /// RMS vertex distance between the noisy and clean low-pass levels (model units).
    pub rms_noise: f64,
    /// `rms_noise` divided by the level's mean edge length.
    pub relative: f64,
    /// `rms_noise` over the finest level's.
    pub gain: f64,
}

/// The experiment for one degree.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StabilityRun {
    /// `linear`, `cubic` or `quintic`.
    pub degree: &'static str,
    /// Levels, finest first.
    pub levels: Vec<StabilityLevel>,
}

/// The experiment for several degrees on one base mesh.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StabilityReport {
    /// Subdivision levels.
    pub levels: u32,
    /// Noise amplitude relative to the finest mean edge length.
    pub noise: f64,
    /// One run per degree.
    pub runs: Vec<StabilityRun>,
}

/// splitmix64, uniform in `[−1, 1)`.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

fn rms(a: &[DVec3], b: &[DVec3]) -> f64 {
    if a.is_empty() {
        return 0.0;
    }
    (a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum::<f64>()
        / a.len() as f64)
        .sqrt()
}

fn mean_edge(t: &Topology, p: &[DVec3]) -> f64 {
    if t.num_edges() == 0 {
        return 0.0;
    }
    t.edge_vertices
        .iter()
        .map(|[a, b]| (p[*a as usize] - p[*b as usize]).length())
        .sum::<f64>()
        / t.num_edges() as f64
}

/// Runs the §5.2 experiment on `base` (any polygon mesh; a non-quad mesh gets one
/// Catmull-Clark topology step first, as [`quad_hierarchy`] does) for each of `degrees`:
/// `levels` subdivision levels, uniform noise of amplitude `noise` times the finest mean edge
/// length, generator seed `seed`.
///
/// # Errors
/// As [`quad_hierarchy`] (invalid or non-manifold base mesh); [`Error::InvalidArgument`] for
/// zero levels, or a negative or non-finite noise.
pub fn stability(
    base: &Mesh,
    degrees: &[Degree],
    levels: u32,
    noise: f64,
    seed: u64,
) -> Result<StabilityReport> {
    if levels == 0 {
        return Err(Error::InvalidArgument(
            "the stability experiment needs at least one level (--levels 1 or more)".into(),
        ));
    }
    if !noise.is_finite() || noise < 0.0 {
        return Err(Error::InvalidArgument(format!(
            "noise {noise} must be a finite non-negative number"
        )));
    }
    let r = quad_hierarchy(base, levels)?;
    let topos = &r.topologies;
    let l = topos.len();
    let sizes = level_sizes(topos)?;
    let finest = refine_topology(&topos[l - 1], Split::Polygons, false).0;
    let mut runs = Vec::new();
    for &degree in degrees {
        let w = BSplineWavelet::new(degree);
        let mut clean = w.subdivide(topos, &base.positions)?;
        let amp = noise * mean_edge(&finest, &clean);
        let mut rng = Rng(seed);
        let mut noisy: Vec<DVec3> = clean
            .iter()
            .map(|p| *p + amp * DVec3::new(rng.unit(), rng.unit(), rng.unit()))
            .collect();
        let first = rms(&noisy, &clean);
        let level = |j: usize, n: f64, t: &Topology, p: &[DVec3]| StabilityLevel {
            level: j,
            vertices: p.len(),
            rms_noise: n,
            relative: n / mean_edge(t, p),
            gain: if first > 0.0 { n / first } else { 0.0 },
        };
        let mut out = vec![level(l, first, &finest, &clean)];
        for j in (0..l).rev() {
            w.analyze_level(&topos[j], &mut noisy[..sizes[j + 1]])?;
            w.analyze_level(&topos[j], &mut clean[..sizes[j + 1]])?;
            let n = rms(&noisy[..sizes[j]], &clean[..sizes[j]]);
            out.push(level(j, n, &topos[j], &clean[..sizes[j]]));
        }
        runs.push(StabilityRun {
            degree: degree.name(),
            levels: out,
        });
    }
    Ok(StabilityReport {
        levels,
        noise,
        runs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;

    /// The paper's observations (§5.2) as thresholds: linear removes the noise, cubic keeps
    /// its relative amplitude roughly constant, quintic amplifies it at every level.
    #[test]
    fn linear_smooths_cubic_holds_quintic_explodes() {
        let r = stability(&generate::cube(), &Degree::ALL, 5, 0.2, 9).unwrap();
        let rel = |i: usize| -> Vec<f64> { r.runs[i].levels.iter().map(|l| l.relative).collect() };
        let (lin, cub, qui) = (rel(0), rel(1), rel(2));
        assert!(lin[3] < 0.1 * lin[0], "{lin:?}");
        assert!(cub[3] < cub[0] && cub[3] > 0.25 * cub[0], "{cub:?}");
        assert!(qui[3] > 10.0 * qui[0], "{qui:?}");
        assert!(lin.windows(2).all(|w| w[1] < w[0]), "{lin:?}");
        assert!(qui.windows(2).all(|w| w[1] > w[0]), "{qui:?}");
        assert_eq!(r.runs[0].levels.len(), 6);
        assert_eq!(r.runs[0].levels[0].level, 5);
        assert!((r.runs[2].levels[0].gain - 1.0).abs() < 1e-12);
    }

    /// A triangle base mesh goes through one Catmull-Clark step; zero noise gives zero.
    #[test]
    fn triangle_base_and_zero_noise() {
        let r = stability(&generate::icosahedron(), &[Degree::Cubic], 3, 0.0, 1).unwrap();
        assert!(r.runs[0].levels.iter().all(|l| l.rms_noise == 0.0));
        assert!(stability(&generate::cube(), &[Degree::Cubic], 0, 0.1, 1).is_err());
        assert!(stability(&generate::cube(), &[Degree::Cubic], 2, -1.0, 1).is_err());
    }
}

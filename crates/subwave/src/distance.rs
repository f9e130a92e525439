//! Metro-style surface distance between two meshes: dense sampling of each surface and
//! closest-point queries on the other, RMS both ways, Hausdorff distance and PSNR.
//!
//! Cignoni, Rocchini & Scopigno, "Metro: measuring error on simplified surfaces" (1998), as
//! the progressive geometry compression literature uses it (Maret 2003 §4.6 reports PSNR; Bertram
//! §5 and Table 5 report L2 and maximum errors). The conventions are those of
//! `../shared/peers/README.md` and `metro.py`:
//! - a one-sided distance samples surface A uniformly by area and measures each sample's
//!   distance to the closest point of surface B; its RMS is `sqrt(mean d²)`, its maximum the
//!   one-sided Hausdorff distance;
//! - `rms` is the larger of the two one-sided RMS values, `max` the symmetric Hausdorff distance
//!   (the larger maximum), and `psnr = 20 log10(diag(A) / rms)` dB with `diag(A)` the bounding-box
//!   diagonal of the first mesh.
//!
//! Sampling is deterministic: samples go to triangles in proportion to their area (error
//! diffusion over the triangle list, so every triangle larger than the sample spacing gets
//! one), at low-discrepancy points (the R2 sequence) mapped uniformly onto each triangle. The
//! RMS and mean are over these area samples only (as `metro.py`, which samples faces only);
//! the maximum also takes every vertex, so that the Hausdorff distance sees the extremities
//! (where a smoothed or decimated surface is usually farthest away), and is therefore at least
//! the face-sampled maximum that MeshLab reports. Closest points come from parry3d's BVH over
//! the other mesh's triangles, queried in parallel.

use glam::DVec3;
use parry3d_f64::math::Vector as PVec;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::TriMesh;
use rayon::prelude::*;

use crate::mesh::Mesh;
use crate::{Error, Result};

/// Default number of area samples per surface (as `metro.py`).
pub const DEFAULT_SAMPLES: usize = 200_000;

/// One direction of the distance: samples of one surface against the other.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct OneSided {
    /// Root mean square of the sample distances.
    pub rms: f64,
    /// Mean sample distance.
    pub mean: f64,
    /// Largest distance over the area samples and the vertices (one-sided Hausdorff).
    pub max: f64,
    /// Where [`OneSided::max`] is measured: the sample or vertex of the measured surface
    /// farthest from the other (the place a remesh misses most, say).
    pub farthest: [f64; 3],
    /// Number of area samples (the vertices come on top).
    pub samples: usize,
}

/// The symmetric distance between meshes A and B (JSON keys of `subwave distance --json`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Distance {
    /// Larger of the two one-sided RMS distances.
    pub rms: f64,
    /// Symmetric Hausdorff distance.
    pub max: f64,
    /// `20 log10(diagonal / rms)` in dB (infinite when `rms` is 0).
    pub psnr: f64,
    /// RMS from A's samples to B.
    pub rms_ab: f64,
    /// RMS from B's samples to A.
    pub rms_ba: f64,
    /// A's bounding-box diagonal.
    pub diagonal: f64,
    /// A sampled against B.
    pub ab: OneSided,
    /// B sampled against A.
    pub ba: OneSided,
}

/// The triangles of a mesh (polygons fanned), checked non-empty; `which` names the mesh in
/// the error.
///
/// # Errors
/// [`Error::InvalidArgument`] for a mesh without faces; [`Mesh::check_indices`]'s errors.
pub fn triangles(mesh: &Mesh, which: &str) -> Result<Vec<[u32; 3]>> {
    mesh.check_indices()?;
    let (tris, _) = mesh.triangulate();
    if tris.is_empty() {
        return Err(Error::InvalidArgument(format!(
            "mesh {which} has no faces: a surface distance needs triangles or polygons"
        )));
    }
    Ok(tris)
}

/// A BVH over a mesh's triangles for closest-point queries.
pub struct ClosestPoint {
    shape: TriMesh,
}

impl ClosestPoint {
    /// Builds the BVH over `mesh`'s faces (polygons are fanned into triangles).
    ///
    /// # Errors
    /// [`Error::Mesh`] if the mesh's indices are invalid, [`Error::InvalidArgument`] if it has
    /// no face.
    pub fn new(mesh: &Mesh) -> Result<ClosestPoint> {
        let tris = triangles(mesh, "B")?;
        Self::from_triangles(&mesh.positions, tris)
    }

    fn from_triangles(positions: &[DVec3], tris: Vec<[u32; 3]>) -> Result<ClosestPoint> {
        let vertices = positions.iter().map(|p| PVec::new(p.x, p.y, p.z)).collect();
        let shape = TriMesh::new(vertices, tris)
            .map_err(|e| Error::InvalidArgument(format!("cannot index the triangles: {e:?}")))?;
        Ok(ClosestPoint { shape })
    }

    /// The closest point of the surface to `p`.
    pub fn closest(&self, p: DVec3) -> DVec3 {
        let q = self
            .shape
            .project_local_point(PVec::new(p.x, p.y, p.z), false)
            .point;
        DVec3::new(q.x, q.y, q.z)
    }

    /// The distance from `p` to the surface.
    pub fn distance(&self, p: DVec3) -> f64 {
        self.closest(p).distance(p)
    }
}

/// The vertices that some triangle uses.
pub fn used_vertices(positions: &[DVec3], tris: &[[u32; 3]]) -> Vec<DVec3> {
    let mut used = vec![false; positions.len()];
    for t in tris {
        for &i in t {
            used[i as usize] = true;
        }
    }
    (0..positions.len())
        .filter(|&i| used[i])
        .map(|i| positions[i])
        .collect()
}

/// About `count` area-weighted, deterministic sample points on a triangle set (see the module
/// documentation).
pub fn sample_surface(positions: &[DVec3], tris: &[[u32; 3]], count: usize) -> Vec<DVec3> {
    let area = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        0.5 * (b - a).cross(c - a).length()
    };
    let total: f64 = tris.iter().map(area).sum();
    let mut out = Vec::new();
    if total <= 0.0 || count == 0 {
        return out;
    }
    // R2 sequence (Roberts 2018): the plastic number's reciprocal powers.
    const G: f64 = 1.324_717_957_244_746;
    let (a1, a2) = (1.0 / G, 1.0 / (G * G));
    let per_area = count as f64 / total;
    let mut carry = 0.0;
    let mut k = 0u64;
    out.reserve(count + tris.len());
    for t in tris {
        let want = area(t) * per_area + carry;
        let n = want.floor();
        carry = want - n;
        let [a, b, c] = t.map(|i| positions[i as usize]);
        for _ in 0..n as u64 {
            k += 1;
            let u = (0.5 + a1 * k as f64).fract();
            let v = (0.5 + a2 * k as f64).fract();
            // Uniform on the triangle: fold the unit square.
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            out.push(a + u * (b - a) + v * (c - a));
        }
    }
    out
}

/// Area samples and vertices of one surface measured against a BVH of the other.
fn one_sided(samples: &[DVec3], vertices: &[DVec3], target: &ClosestPoint) -> OneSided {
    // The larger distance, and of equal ones the first point (a deterministic reduction).
    let farther = |x: (f64, usize), y: (f64, usize)| {
        if y.0 > x.0 || (y.0 == x.0 && y.1 < x.1) {
            y
        } else {
            x
        }
    };
    let (vmax, vat) = vertices
        .par_iter()
        .enumerate()
        .map(|(i, &p)| (target.distance(p), i))
        .reduce(|| (0.0, usize::MAX), farther);
    let (sum, sum2, (max, at)) = samples
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            let d = target.distance(p);
            (d, d * d, (d, i))
        })
        .reduce(
            || (0.0, 0.0, (0.0f64, usize::MAX)),
            |x, y| (x.0 + y.0, x.1 + y.1, farther(x.2, y.2)),
        );
    let n = samples.len().max(1) as f64;
    let farthest = if vmax > max {
        vertices[vat]
    } else {
        samples
            .get(at)
            .or(vertices.get(vat))
            .copied()
            .unwrap_or_default()
    };
    OneSided {
        rms: (sum2 / n).sqrt(),
        mean: sum / n,
        max: max.max(vmax),
        farthest: farthest.to_array(),
        samples: samples.len(),
    }
}

/// The symmetric Metro-style distance between `a` and `b` with `samples` area samples per
/// surface (see the module documentation; [`DEFAULT_SAMPLES`] matches `metro.py`).
///
/// # Errors
/// [`Error::Mesh`] if a mesh's indices are invalid; [`Error::InvalidArgument`] if a mesh has no
/// face.
pub fn distance(a: &Mesh, b: &Mesh, samples: usize) -> Result<Distance> {
    let ta = triangles(a, "A")?;
    let tb = triangles(b, "B")?;
    let sa = sample_surface(&a.positions, &ta, samples);
    let sb = sample_surface(&b.positions, &tb, samples);
    let (ta_v, tb_v) = (ta.clone(), tb.clone());
    let (qa, qb) = rayon::join(
        || ClosestPoint::from_triangles(&a.positions, ta),
        || ClosestPoint::from_triangles(&b.positions, tb),
    );
    let (qa, qb) = (qa?, qb?);
    let ab = one_sided(&sa, &used_vertices(&a.positions, &ta_v), &qb);
    let ba = one_sided(&sb, &used_vertices(&b.positions, &tb_v), &qa);
    let rms = ab.rms.max(ba.rms);
    let diagonal = a.diagonal();
    Ok(Distance {
        rms,
        max: ab.max.max(ba.max),
        psnr: psnr(diagonal, rms),
        rms_ab: ab.rms,
        rms_ba: ba.rms,
        diagonal,
        ab,
        ba,
    })
}

/// The one-sided RMS distance from `samples` area samples of `a` to the surface `target`
/// (no vertex queries, no Hausdorff distance): what [`distance`] reports as `rms_ab` when
/// `target` indexes `b`, for callers that already hold `b`'s BVH.
///
/// # Errors
/// As [`distance`] for `a`.
pub fn sampled_rms_to(a: &Mesh, target: &ClosestPoint, samples: usize) -> Result<f64> {
    let ta = triangles(a, "A")?;
    let s = sample_surface(&a.positions, &ta, samples);
    Ok(rms_to(&s, target))
}

/// The RMS distance from `points` to the surface `target`, summed in fixed chunks so that
/// the result does not depend on the threads' scheduling (0 for no points).
pub fn rms_to(points: &[DVec3], target: &ClosestPoint) -> f64 {
    let parts: Vec<f64> = points
        .par_chunks(4096)
        .map(|c| c.iter().map(|&p| target.distance(p).powi(2)).sum())
        .collect();
    (parts.into_iter().sum::<f64>() / points.len().max(1) as f64).sqrt()
}

/// `20 log10(diagonal / rms)` dB; infinite for `rms == 0`.
pub fn psnr(diagonal: f64, rms: f64) -> f64 {
    if rms > 0.0 {
        20.0 * (diagonal / rms).log10()
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;

    #[test]
    fn identical_meshes_are_at_distance_zero() {
        let m = generate::torus(1.0, 0.3, 12, 8, true);
        let d = distance(&m, &m, 20_000).unwrap();
        assert!(d.max < 1e-12 && d.rms < 1e-12, "{d:?}");
        assert!(d.psnr > 250.0, "{d:?}");
    }

    #[test]
    fn parallel_planes_are_at_their_offset() {
        let a = generate::grid(4, 4, true);
        let mut b = a.clone();
        for p in &mut b.positions {
            p.z += 0.25;
        }
        let d = distance(&a, &b, 10_000).unwrap();
        assert!(
            (d.rms - 0.25).abs() < 1e-12 && (d.max - 0.25).abs() < 1e-12,
            "{d:?}"
        );
        let diag = a.diagonal();
        assert!((d.psnr - 20.0 * (diag / 0.25).log10()).abs() < 1e-9);
    }

    #[test]
    fn spheres_differ_by_their_radii() {
        // A fine icosphere against the same scaled by 1.01: every point is ~0.01 away.
        let a = generate::icosphere(4);
        let mut b = a.clone();
        for p in &mut b.positions {
            *p *= 1.01;
        }
        let d = distance(&a, &b, 50_000).unwrap();
        // Flat triangles sit inside the sphere: distances are 0.01 up to the chord sag.
        assert!((d.rms - 0.01).abs() < 1e-3 && d.max < 0.0105, "{d:?}");
        assert!(d.ab.samples.abs_diff(50_000) <= 1, "{}", d.ab.samples);
    }

    #[test]
    fn one_sided_distances_differ_for_a_subset() {
        // B is half of A: A's samples on the missing half are far, B's are all on A.
        let a = generate::grid(4, 4, true);
        let mut b = generate::grid(2, 4, true);
        for p in &mut b.positions {
            p.z += 0.0;
        }
        let d = distance(&a, &b, 20_000).unwrap();
        assert!(d.rms_ba < 1e-12, "{d:?}");
        assert!(d.rms_ab > 0.5 && (d.max - 2.0).abs() < 1e-9, "{d:?}");
        // The sampled estimate is the larger one-sided RMS of the same samples, both ways.
        let (qa, qb) = (
            ClosestPoint::new(&a).unwrap(),
            ClosestPoint::new(&b).unwrap(),
        );
        let r = sampled_rms_to(&a, &qb, 20_000).unwrap();
        assert!(
            (r - d.rms_ab).abs() <= 1e-12 * d.rms_ab,
            "{r} vs {}",
            d.rms_ab
        );
        assert!(sampled_rms_to(&b, &qa, 20_000).unwrap() < 1e-12);
        // The farthest point of A is where A is 2 away from B, on A.
        let far = DVec3::from_array(d.ab.farthest);
        assert!((qb.distance(far) - 2.0).abs() < 1e-9, "{far}");
        assert!(qa.distance(far) < 1e-12, "{far}");
    }

    #[test]
    fn samples_are_uniform_by_area() {
        // Two triangles of areas 1 and 3: samples split 1:3.
        let p = [
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(16.0, 0.0, 0.0),
            DVec3::new(10.0, 1.0, 0.0),
        ];
        let s = sample_surface(&p, &[[0, 1, 2], [3, 4, 5]], 4000);
        let left = s.iter().filter(|q| q.x < 5.0).count();
        let right = s.iter().filter(|q| q.x >= 5.0).count();
        assert_eq!((left, right), (1000, 3000));
        // All inside their triangles (z = 0, x within the span).
        assert!(s.iter().all(|q| q.z == 0.0 && q.y >= 0.0 && q.y <= 1.0));
    }

    #[test]
    fn empty_meshes_are_errors() {
        let a = generate::cube();
        let e = distance(&a, &Mesh::new(), 100).unwrap_err().to_string();
        assert!(e.contains("mesh B has no faces"), "{e}");
    }
}

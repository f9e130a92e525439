//! Subdivision curves for creases and patch boundaries (Lavoué, Dupont & Baskurt, "High rate
//! compression of CAD meshes based on subdivision inversion", §V.1, eqs. 2-4).
//!
//! A control polygon (open polyline or closed polygon) is refined by Hoppe et al.'s rules for
//! sharp and boundary edges: a new point at the midpoint of every segment, and every control
//! point moved to
//!
//! ```text
//! P_i' = 1/8 (P_{i−1} + 6 P_i + P_{i+1})      (eq. 2, uniform cubic B-spline)
//! P_i' = P_i                                  (eq. 3, corners and the ends of open curves)
//! ```
//!
//! so the curve is a uniform cubic B-spline except next to corners and ends, which it
//! interpolates. The limit position of a control point is
//!
//! ```text
//! P_i^∞ = 1/6 (P_{i−1} + 4 P_i + P_{i+1})     (eq. 4; corners and ends stay)
//! ```
//!
//! These are exactly the crease rules of [`super::quad_tri`] (and of the crate's Loop and
//! Catmull-Clark): a crease of a mesh refines as this curve (tested).
//!
//! Both operators are linear in the control points, so they are also offered as
//! [`StencilTable`]s ([`SubdivisionCurve::refine_table`], [`SubdivisionCurve::limit_table`],
//! and composed over several levels, [`SubdivisionCurve::sample_table`]): the fitting of
//! §V.2.2 expresses sample points of a finer level as such linear combinations of the control
//! points.
//!
//! Point order of a refined curve: `P_0', E_0, P_1', E_1, …` along the curve (`E_i` on segment
//! `P_i P_{i+1}`), so control point `i` becomes point `2i` and a corner `c` becomes corner
//! `2c`; an open curve of `n` points refines to `2n − 1`, a closed one to `2n`.

use glam::DVec3;

use super::stencil::StencilTable;
use crate::{Error, Result};

/// A subdivision curve's control polygon: points along the curve, whether the last joins the
/// first, and the indices of its corners (sharp points that stay, eq. 3).
#[derive(Clone, Debug, PartialEq)]
pub struct SubdivisionCurve {
    /// Control points, in curve order.
    pub points: Vec<DVec3>,
    /// True for a closed polygon (segment `P_{n−1} P_0` exists).
    pub closed: bool,
    /// Corner indices (sorted, distinct). The ends of an open curve are always fixed and need
    /// not be listed.
    pub corners: Vec<u32>,
}

impl SubdivisionCurve {
    /// A control polygon with the given corners.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] if an open curve has fewer than 2 points, a closed one fewer
    /// than 3, or a corner index is out of range.
    pub fn new(points: Vec<DVec3>, closed: bool, mut corners: Vec<u32>) -> Result<Self> {
        let min = if closed { 3 } else { 2 };
        if points.len() < min {
            return Err(Error::InvalidArgument(format!(
                "a {} subdivision curve needs at least {min} control points, got {}",
                if closed { "closed" } else { "open" },
                points.len()
            )));
        }
        if let Some(&c) = corners.iter().find(|&&c| c as usize >= points.len()) {
            return Err(Error::InvalidArgument(format!(
                "corner {c} is out of range: the curve has {} control points",
                points.len()
            )));
        }
        corners.sort_unstable();
        corners.dedup();
        Ok(SubdivisionCurve {
            points,
            closed,
            corners,
        })
    }

    /// An open polyline without inner corners (its two ends are fixed).
    ///
    /// # Errors
    /// As [`SubdivisionCurve::new`].
    pub fn open(points: Vec<DVec3>) -> Result<Self> {
        Self::new(points, false, Vec::new())
    }

    /// A closed polygon without corners (a uniform cubic B-spline curve).
    ///
    /// # Errors
    /// As [`SubdivisionCurve::new`].
    pub fn closed(points: Vec<DVec3>) -> Result<Self> {
        Self::new(points, true, Vec::new())
    }

    /// Number of control points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True if the curve has no control points (never for a curve built by `new`).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// True if control point `i` stays put (eq. 3): a corner, or an end of an open curve.
    pub fn is_fixed(&self, i: usize) -> bool {
        (!self.closed && (i == 0 || i + 1 == self.points.len()))
            || self.corners.binary_search(&(i as u32)).is_ok()
    }

    /// The neighbours `(i − 1, i + 1)` of an inner or closed-curve point.
    fn neighbours(&self, i: usize) -> (usize, usize) {
        let n = self.points.len();
        ((i + n - 1) % n, (i + 1) % n)
    }

    /// Number of segments.
    fn num_segments(&self) -> usize {
        if self.closed {
            self.points.len()
        } else {
            self.points.len() - 1
        }
    }

    /// One refinement step (eqs. 2-3) as a stencil table from this curve's points to the
    /// refined curve's (in the refined point order of the module documentation).
    pub fn refine_table(&self) -> StencilTable {
        let n = self.points.len();
        let segs = self.num_segments();
        let mut t = StencilTable {
            num_sources: n as u32,
            child_sources: 0,
            offsets: vec![0],
            indices: Vec::with_capacity(5 * n),
            weights: Vec::with_capacity(5 * n),
        };
        let push = |t: &mut StencilTable, terms: &[(usize, f64)]| {
            for &(i, w) in terms {
                t.indices.push(i as u32);
                t.weights.push(w);
            }
            t.offsets.push(t.indices.len() as u32);
        };
        for i in 0..n {
            if self.is_fixed(i) {
                push(&mut t, &[(i, 1.0)]);
            } else {
                let (a, b) = self.neighbours(i);
                push(&mut t, &[(a, 0.125), (i, 0.75), (b, 0.125)]);
            }
            if i < segs {
                push(&mut t, &[(i, 0.5), ((i + 1) % n, 0.5)]);
            }
        }
        t
    }

    /// Limit positions (eq. 4) as a stencil table from the control points.
    pub fn limit_table(&self) -> StencilTable {
        let n = self.points.len();
        let mut t = StencilTable {
            num_sources: n as u32,
            child_sources: 0,
            offsets: vec![0],
            indices: Vec::with_capacity(3 * n),
            weights: Vec::with_capacity(3 * n),
        };
        for i in 0..n {
            if self.is_fixed(i) {
                t.indices.push(i as u32);
                t.weights.push(1.0);
            } else {
                let (a, b) = self.neighbours(i);
                t.indices.extend([a as u32, i as u32, b as u32]);
                t.weights.extend([1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0]);
            }
            t.offsets.push(t.indices.len() as u32);
        }
        t
    }

    /// The points of level `levels` (their limit positions if `limit`) as a stencil table
    /// over this curve's control points: the linear map from control points to sample points
    /// that the least-squares fitting of §V.2.2 needs (`levels = 0` with `limit` gives eq. 4).
    pub fn sample_table(&self, levels: u32, limit: bool) -> StencilTable {
        let mut c = self.clone();
        let mut acc = identity(self.points.len());
        for _ in 0..levels {
            acc = compose(&acc, &c.refine_table());
            c = SubdivisionCurve {
                points: vec![DVec3::ZERO; 2 * c.len() - usize::from(!c.closed)],
                closed: c.closed,
                corners: c.corners.iter().map(|&k| 2 * k).collect(),
            };
        }
        if limit {
            acc = compose(&acc, &c.limit_table());
        }
        acc
    }

    /// The curve after one refinement step (eqs. 2-3): corners `c` become `2c`.
    pub fn subdivide(&self) -> SubdivisionCurve {
        SubdivisionCurve {
            points: self.refine_table().apply(&self.points),
            closed: self.closed,
            corners: self.corners.iter().map(|&c| 2 * c).collect(),
        }
    }

    /// The curve after `levels` refinement steps.
    pub fn subdivide_levels(&self, levels: u32) -> SubdivisionCurve {
        let mut c = self.clone();
        for _ in 0..levels {
            c = c.subdivide();
        }
        c
    }

    /// The limit position of every control point (eq. 4).
    pub fn limit_positions(&self) -> Vec<DVec3> {
        self.limit_table().apply(&self.points)
    }
}

/// The identity table on `n` points.
fn identity(n: usize) -> StencilTable {
    StencilTable {
        num_sources: n as u32,
        child_sources: 0,
        offsets: (0..=n as u32).collect(),
        indices: (0..n as u32).collect(),
        weights: vec![1.0; n],
    }
}

/// `then ∘ first`: the table mapping `first`'s sources to `then`'s outputs (repeated
/// sources merged, in order of first appearance).
fn compose(first: &StencilTable, then: &StencilTable) -> StencilTable {
    let mut out = StencilTable {
        num_sources: first.num_sources,
        child_sources: 0,
        offsets: vec![0],
        indices: Vec::new(),
        weights: Vec::new(),
    };
    for j in 0..then.len() {
        let row = out.indices.len();
        for k in then.offsets[j] as usize..then.offsets[j + 1] as usize {
            let (mid, w) = (then.indices[k] as usize, then.weights[k]);
            for m in first.offsets[mid] as usize..first.offsets[mid + 1] as usize {
                let (src, v) = (first.indices[m], first.weights[m]);
                match out.indices[row..].iter().position(|&x| x == src) {
                    Some(p) => out.weights[row + p] += w * v,
                    None => {
                        out.indices.push(src);
                        out.weights.push(w * v);
                    }
                }
            }
        }
        out.offsets.push(out.indices.len() as u32);
    }
    out
}

/// The uniform cubic B-spline segment of control points `p[0..4]` at `u ∈ [0, 1]`: the limit
/// curve of [`SubdivisionCurve`] away from corners and ends (for tests and fitting).
pub fn cubic_bspline_point(p: [DVec3; 4], u: f64) -> DVec3 {
    let (u2, u3) = (u * u, u * u * u);
    let v = 1.0 - u;
    (v * v * v * p[0]
        + (3.0 * u3 - 6.0 * u2 + 4.0) * p[1]
        + (-3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0) * p[2]
        + u3 * p[3])
        / 6.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn polygon(n: usize, r: f64) -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                let a = TAU * i as f64 / n as f64;
                DVec3::new(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect()
    }

    fn max_dist(a: &[DVec3], b: &[DVec3]) -> f64 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .map(|(x, y)| x.distance(*y))
            .fold(0.0, f64::max)
    }

    #[test]
    fn rejects_bad_input() {
        assert!(SubdivisionCurve::open(vec![DVec3::ZERO]).is_err());
        assert!(SubdivisionCurve::closed(vec![DVec3::ZERO, DVec3::X]).is_err());
        let e = SubdivisionCurve::new(polygon(4, 1.0), true, vec![7]).unwrap_err();
        assert!(e.to_string().contains("corner 7"), "{e}");
    }

    #[test]
    fn counts_and_rules() {
        let p = vec![
            DVec3::ZERO,
            DVec3::new(1.0, 2.0, 0.0),
            DVec3::new(3.0, 2.0, 1.0),
            DVec3::new(4.0, 0.0, 0.0),
        ];
        let open = SubdivisionCurve::open(p.clone()).unwrap().subdivide();
        assert_eq!(open.len(), 7);
        assert_eq!(open.points[0], p[0]);
        assert_eq!(open.points[6], p[3]);
        assert_eq!(open.points[1], 0.5 * (p[0] + p[1]));
        let want = (p[0] + 6.0 * p[1] + p[2]) / 8.0;
        assert!(open.points[2].distance(want) < 1e-15);
        let closed = SubdivisionCurve::closed(p.clone()).unwrap().subdivide();
        assert_eq!(closed.len(), 8);
        let want = (p[3] + 6.0 * p[0] + p[1]) / 8.0;
        assert!(closed.points[0].distance(want) < 1e-15);
        assert_eq!(closed.points[7], 0.5 * (p[3] + p[0]));
        // A corner stays and keeps being a corner.
        let c = SubdivisionCurve::new(p.clone(), true, vec![2]).unwrap();
        let c2 = c.subdivide_levels(2);
        assert_eq!(c2.corners, vec![8]);
        assert_eq!(c2.points[8], p[2]);
    }

    /// Away from corners the curve is the uniform cubic B-spline: the limit positions of the
    /// points of level `k` are the spline at parameters `i / 2^k`.
    #[test]
    fn closed_curve_is_the_cubic_bspline() {
        let p = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.5, 0.3),
            DVec3::new(3.0, 2.0, -0.2),
            DVec3::new(1.5, 3.5, 0.1),
            DVec3::new(-0.5, 2.0, 0.6),
        ];
        let n = p.len();
        let c = SubdivisionCurve::closed(p.clone()).unwrap();
        for k in 0..5u32 {
            let ck = c.subdivide_levels(k);
            let limit = ck.limit_positions();
            let s = 1usize << k;
            for (j, l) in limit.iter().enumerate() {
                // Point j of level k sits at parameter j / 2^k: segment i = j / s of the
                // spline whose segment i runs between control points i and i + 1.
                let (i, u) = (j / s, (j % s) as f64 / s as f64);
                let q = [p[(i + n - 1) % n], p[i], p[(i + 1) % n], p[(i + 2) % n]];
                assert!(l.distance(cubic_bspline_point(q, u)) < 1e-13, "{k} {j}");
            }
        }
    }

    /// A regular polygon converges to a smooth closed curve: at every level the turning angle
    /// is the same at every point, 2π / (number of points), and the points approach the
    /// spline's (limit) positions.
    #[test]
    fn regular_polygon_converges_smoothly() {
        let n = 6;
        let c = SubdivisionCurve::closed(polygon(n, 1.0)).unwrap();
        let mut prev_gap = f64::INFINITY;
        for k in 1..8 {
            let ck = c.subdivide_levels(k);
            let m = ck.len();
            assert_eq!(m, n << k);
            let mut max_turn: f64 = 0.0;
            for i in 0..m {
                let a = ck.points[(i + m - 1) % m];
                let b = ck.points[i];
                let d = ck.points[(i + 1) % m];
                max_turn = max_turn.max((b - a).angle_between(d - b));
            }
            // Uniform turning (up to the two point kinds' slight difference), vanishing.
            assert!(max_turn < 1.2 * TAU / m as f64, "{k}: {max_turn}");
            // Distance of the level's points to their limit positions shrinks by ~4 a level.
            let gap = max_dist(&ck.points, &ck.limit_positions());
            assert!(gap < prev_gap / 3.5, "{k}: {gap} vs {prev_gap}");
            prev_gap = gap;
        }
        // The limit radius of a control point: (2 cos(2π/n) + 4) / 6.
        let l = c.limit_positions();
        let r = (2.0 * (TAU / n as f64).cos() + 4.0) / 6.0;
        assert!(l.iter().all(|p| (p.length() - r).abs() < 1e-14));
    }

    /// The limit position of a point does not change under refinement (eq. 4 is the left
    /// eigenvector of eq. 2), next to corners and ends too.
    #[test]
    fn limit_positions_are_invariant() {
        let p = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(2.0, -0.5, 0.4),
            DVec3::new(3.0, 1.5, 0.2),
            DVec3::new(4.0, 0.0, -0.3),
            DVec3::new(5.0, 0.7, 0.0),
        ];
        for c in [
            SubdivisionCurve::open(p.clone()).unwrap(),
            SubdivisionCurve::closed(p.clone()).unwrap(),
            SubdivisionCurve::new(p.clone(), true, vec![1, 4]).unwrap(),
            SubdivisionCurve::new(p.clone(), false, vec![2]).unwrap(),
        ] {
            let l0 = c.limit_positions();
            for k in 1..5u32 {
                let ck = c.subdivide_levels(k);
                let lk = ck.limit_positions();
                for (i, x) in l0.iter().enumerate() {
                    assert!(x.distance(lk[i << k]) < 1e-13, "{c:?} level {k} point {i}");
                }
            }
            // Fixed points never move.
            let c5 = c.subdivide_levels(5);
            for (i, (&p, &l)) in c.points.iter().zip(&l0).enumerate() {
                if c.is_fixed(i) {
                    assert_eq!(c5.points[i << 5], p);
                    assert_eq!(l, p);
                }
            }
        }
    }

    #[test]
    fn sample_tables_match_refinement() {
        let p = polygon(5, 1.5);
        for (closed, corners) in [(true, vec![]), (true, vec![2]), (false, vec![3])] {
            let c = SubdivisionCurve::new(p.clone(), closed, corners).unwrap();
            for levels in 0..4 {
                let ck = c.subdivide_levels(levels);
                let t = c.sample_table(levels, false);
                assert!(max_dist(&t.apply(&c.points), &ck.points) < 1e-14);
                let t = c.sample_table(levels, true);
                assert!(max_dist(&t.apply(&c.points), &ck.limit_positions()) < 1e-14);
                // Rows are affine combinations.
                for j in 0..t.len() {
                    let w: f64 = t.weights[t.offsets[j] as usize..t.offsets[j + 1] as usize]
                        .iter()
                        .sum();
                    assert!((w - 1.0).abs() < 1e-14);
                }
            }
        }
    }

    #[test]
    fn affine_invariance() {
        let m = glam::DMat3::from_cols(
            DVec3::new(1.2, 0.3, -0.1),
            DVec3::new(-0.4, 0.9, 0.2),
            DVec3::new(0.1, 0.5, 1.7),
        );
        let f = |x: DVec3| m * x + DVec3::new(3.0, -2.0, 0.5);
        let p = polygon(7, 2.0);
        for closed in [false, true] {
            let c = SubdivisionCurve::new(p.clone(), closed, vec![3]).unwrap();
            let img =
                SubdivisionCurve::new(p.iter().map(|&x| f(x)).collect(), closed, vec![3]).unwrap();
            let a: Vec<DVec3> = c.subdivide_levels(3).points.into_iter().map(f).collect();
            assert!(max_dist(&a, &img.subdivide_levels(3).points) < 1e-12);
            let a: Vec<DVec3> = c.limit_positions().into_iter().map(f).collect();
            assert!(max_dist(&a, &img.limit_positions()) < 1e-12);
        }
    }
}

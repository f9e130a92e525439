//! Simultaneous untangling and smoothing of a planar mesh.
//!
//! Escobar, Rodríguez, Montenegro, Montero & González-Yuste, "Simultaneous untangling and
//! smoothing of tetrahedral meshes", Computer Methods in Applied Mechanics and Engineering
//! 192 (2003) — here in the plane, for triangles. The shape energy of a triangle
//! `(x, a, b)` is its condition number `η = ‖S‖² / (2σ)` (`S` the Jacobian of the map from an
//! equilateral triangle, `σ = det S`), up to a constant `l / σ`: the sum of its squared edge
//! lengths over its doubled signed area. `l / σ` is a barrier that keeps a valid mesh valid,
//! but it is undefined where `σ ≤ 0`. Escobar et al. replace `σ` by
//! `h(σ) = (σ + √(σ² + 4δ²)) / 2`, positive for every `σ`, increasing, and `≈ δ² / |σ|` for
//! inverted triangles, whose energy is then large and falls as they turn over: the
//! minimization of `Σ l / h(σ)` moves the nodes of inverted triangles until they are valid
//! *and* smooths the valid ones, at once, instead of untangling first and smoothing after.
//! `δ` follows the worst triangle (`δ² = ε(ε − σ_min)` while `σ_min < ε`, else
//! 0, with `σ` normalized by the mean squared edge length), so that the modified energy is
//! the plain one once the mesh is valid.
//!
//! Used by [`super::flatten`] where Tutte's embedding of a remesh disc folds next to reflex
//! corners of the disc's boundary and moving one node at a time into the kernel of its star
//! gets stuck: nodes that must move together (a fold across several free vertices whose
//! stars' kernels are each empty) move together here, since each node's step lowers the
//! energy of its neighbours' triangles too. The minimization is node by node (Gauss-Seidel,
//! over the free nodes within [`ACTIVE_RINGS`] rings of a triangle below `ε`: the rest of a
//! disc is valid and stays where Tutte's embedding put it), each step a Newton step on the
//! node's star (2 × 2, exact gradient and Hessian) or, where the Hessian is not positive
//! definite, a gradient step, with a backtracking line search.

use glam::DVec2;

/// `ε` of the regularization (`δ² = ε(ε − σ_min)`, `δ` chosen from the worst triangle as Escobar et al. do), in units of the
/// mean squared edge length.
const EPSILON: f64 = 1e-3;

/// The untangling gives up after this many sweeps in a row that do not raise the worst
/// triangle's normalized `σ` by [`STALL_GAIN`].
const STALL_SWEEPS: usize = 8;

/// See [`STALL_SWEEPS`] (a valid equilateral triangle has `σ ≈ 0.87`).
const STALL_GAIN: f64 = 1e-4;

/// Rings of nodes around the triangles below `ε` that each sweep moves.
const ACTIVE_RINGS: usize = 8;

/// Sweeps (every active node once) after the mesh is valid, smoothing it with `δ = 0`.
const POLISH_SWEEPS: usize = 2;

/// The corner triangles of polygon `fv`, counterclockwise: the polygon itself for a
/// triangle; each corner with its two neighbours for a larger polygon (a valid convex
/// polygon has every one of them counterclockwise).
fn corner_triangles(fv: &[u32]) -> Vec<[u32; 3]> {
    let m = fv.len();
    if m == 3 {
        return vec![[fv[0], fv[1], fv[2]]];
    }
    (0..m)
        .map(|k| [fv[(k + m - 1) % m], fv[k], fv[(k + 1) % m]])
        .collect()
}

/// The energy `l / h(σ)` of triangle `(x, a, b)` (counterclockwise when valid); `None`
/// where `h(σ) ≤ 0` (`δ = 0` and the triangle not valid).
fn energy(x: DVec2, a: DVec2, b: DVec2, delta2: f64) -> Option<f64> {
    let (p, q) = (a - x, b - x);
    let sigma = p.perp_dot(q);
    let l = p.length_squared() + q.length_squared() + (a - b).length_squared();
    let h = 0.5 * (sigma + (sigma * sigma + 4.0 * delta2).sqrt());
    (h > 0.0 && h.is_finite()).then(|| l / h)
}

/// [`energy`] with its gradient and Hessian in `x` (`[∂xx, ∂xy, ∂yy]`): with `s = ∇σ`
/// (constant: `σ` is linear in `x`), `∇h = h′ s`, `∇²h = h″ s sᵀ`, `h′ = h / r`,
/// `h″ = 2δ² / r³` (`r = √(σ² + 4δ²)`), `∇l = 2(2x − a − b)` and `∇²l = 4I`.
fn energy_derivatives(x: DVec2, a: DVec2, b: DVec2, delta2: f64) -> Option<(f64, DVec2, [f64; 3])> {
    let (p, q) = (a - x, b - x);
    let sigma = p.perp_dot(q);
    let l = p.length_squared() + q.length_squared() + (a - b).length_squared();
    let r = (sigma * sigma + 4.0 * delta2).sqrt();
    let h = 0.5 * (sigma + r);
    if !(h > 0.0 && h.is_finite() && r > 0.0) {
        return None;
    }
    let s = DVec2::new(a.y - b.y, b.x - a.x);
    let dl = -2.0 * (p + q);
    let dh = s * (h / r);
    let d2h = 2.0 * delta2 / (r * r * r);
    let (h2, h3) = (h * h, h * h * h);
    let g = dl / h - dh * (l / h2);
    // ∇²e = ∇²l / h − (∇l ∇hᵀ + ∇h ∇lᵀ) / h² − l ∇²h / h² + 2 l ∇h ∇hᵀ / h³.
    let hess = |i: usize, j: usize| {
        let id = if i == j { 4.0 } else { 0.0 };
        id / h - (dl[i] * dh[j] + dh[i] * dl[j]) / h2 - l * d2h * s[i] * s[j] / h2
            + 2.0 * l * dh[i] * dh[j] / h3
    };
    Some((l / h, g, [hess(0, 0), hess(0, 1), hess(1, 1)]))
}

/// The energy of a node's star (`star`: the other corners of its triangles) at `x`.
fn star_energy(x: DVec2, star: &[(u32, u32)], uv: &[DVec2], delta2: f64) -> Option<f64> {
    star.iter()
        .map(|&(a, b)| energy(x, uv[a as usize], uv[b as usize], delta2))
        .sum()
}

/// The energy of a node's star at `x`, its gradient and Hessian.
fn star_derivatives(
    x: DVec2,
    star: &[(u32, u32)],
    uv: &[DVec2],
    delta2: f64,
) -> Option<(f64, DVec2, [f64; 3])> {
    let mut e = 0.0;
    let mut g = DVec2::ZERO;
    let mut hs = [0.0; 3];
    for &(a, b) in star {
        let (ei, gi, hi) = energy_derivatives(x, uv[a as usize], uv[b as usize], delta2)?;
        e += ei;
        g += gi;
        for k in 0..3 {
            hs[k] += hi[k];
        }
    }
    Some((e, g, hs))
}

/// Moves the first `nfree` nodes of the planar polygons `faces` (indices into `uv`) to
/// minimize Escobar et al.'s regularized shape energy (see the module documentation), at
/// most `sweeps` Gauss-Seidel sweeps; stops when every polygon turns counterclockwise
/// (after [`POLISH_SWEEPS`] smoothing sweeps that keep them so). Returns whether every
/// polygon turns counterclockwise in the end; nodes not in `0..nfree` never move.
///
/// Preconditions: every index in `faces` is below `uv.len()`; `nfree ≤ uv.len()`.
pub(super) fn untangle(uv: &mut [DVec2], nfree: usize, faces: &[Vec<u32>], sweeps: usize) -> bool {
    let tris: Vec<[u32; 3]> = faces.iter().flat_map(|f| corner_triangles(f)).collect();
    if tris.is_empty() {
        return true;
    }
    // Each free node's star: the other two corners of its triangles, in counterclockwise
    // order after it.
    let mut star: Vec<Vec<(u32, u32)>> = vec![Vec::new(); nfree];
    for t in &tris {
        for k in 0..3 {
            let v = t[k] as usize;
            if v < nfree {
                star[v].push((t[(k + 1) % 3], t[(k + 2) % 3]));
            }
        }
    }
    // Normalized coordinates: the mean squared edge length becomes 1.
    let mean_l2 = tris
        .iter()
        .map(|t| {
            (0..3)
                .map(|k| uv[t[k] as usize].distance_squared(uv[t[(k + 1) % 3] as usize]))
                .sum::<f64>()
        })
        .sum::<f64>()
        / (3 * tris.len()) as f64;
    if !(mean_l2 > 0.0 && mean_l2.is_finite()) {
        return false;
    }
    let scale = mean_l2.sqrt();
    let origin = uv[tris[0][0] as usize];
    let mut x: Vec<DVec2> = uv.iter().map(|&p| (p - origin) / scale).collect();
    let sigma_of = |x: &[DVec2], t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| x[i as usize]);
        (b - a).perp_dot(c - a)
    };
    let valid = |x: &[DVec2]| {
        faces.iter().all(|fv| {
            let m = fv.len();
            (0..m)
                .map(|i| x[fv[i] as usize].perp_dot(x[fv[(i + 1) % m] as usize]))
                .sum::<f64>()
                > 0.0
        }) && tris.iter().all(|t| sigma_of(x, t) > 0.0)
    };
    let mut polish = 0;
    let mut best_min = f64::NEG_INFINITY;
    let mut stalled = 0;
    // The nodes swept: those within [`ACTIVE_RINGS`] rings of a triangle below `ε` (the
    // rest of the disc is valid and stays where it is).
    let mut active: Vec<u32> = Vec::new();
    let mut mark = vec![false; nfree];
    let mut used = 0;
    for _ in 0..sweeps {
        used += 1;
        let sigma: Vec<f64> = tris.iter().map(|t| sigma_of(&x, t)).collect();
        let sigma_min = sigma.iter().copied().fold(f64::INFINITY, f64::min);
        if sigma_min > 0.0 && valid(&x) {
            if polish == POLISH_SWEEPS {
                break;
            }
            polish += 1;
        } else {
            for &v in &active {
                mark[v as usize] = false;
            }
            active.clear();
            for (t, &sg) in tris.iter().zip(&sigma) {
                if sg < EPSILON {
                    for &v in t {
                        if (v as usize) < nfree && !mark[v as usize] {
                            mark[v as usize] = true;
                            active.push(v);
                        }
                    }
                }
            }
            let mut from = 0;
            for _ in 0..ACTIVE_RINGS {
                let to = active.len();
                for i in from..to {
                    let v = active[i] as usize;
                    for &(a, b) in &star[v] {
                        for w in [a, b] {
                            if (w as usize) < nfree && !mark[w as usize] {
                                mark[w as usize] = true;
                                active.push(w);
                            }
                        }
                    }
                }
                from = to;
            }
            active.sort_unstable();
            // No progress on the worst triangle for a while: give up.
            if sigma_min > best_min + STALL_GAIN {
                best_min = sigma_min;
                stalled = 0;
            } else {
                stalled += 1;
                if stalled > STALL_SWEEPS {
                    break;
                }
            }
        }
        let delta2 = if sigma_min < EPSILON {
            EPSILON * (EPSILON - sigma_min)
        } else {
            0.0
        };
        for &v in &active {
            step(&mut x, v as usize, &star[v as usize], delta2);
        }
    }
    let ok = valid(&x);
    tracing::trace!(used, ok, "energy sweeps");
    for i in 0..nfree {
        uv[i] = origin + x[i] * scale;
    }
    ok
}

/// One line-searched Newton (or gradient) step of node `v` on its star's energy.
fn step(x: &mut [DVec2], v: usize, star: &[(u32, u32)], delta2: f64) {
    let p = x[v];
    let Some((e0, g, [hxx, hxy, hyy])) = star_derivatives(p, star, x, delta2) else {
        return;
    };
    let gn = g.length();
    if gn < 1e-14 || !gn.is_finite() {
        return;
    }
    let gradient_step = -g / gn * 0.5; // half a mean edge
    let det = hxx * hyy - hxy * hxy;
    let newton = -DVec2::new(hyy * g.x - hxy * g.y, hxx * g.y - hxy * g.x) / det;
    let dir = if hxx > 0.0 && det > 0.0 && newton.is_finite() && newton.length() < 4.0 {
        newton
    } else {
        gradient_step
    };
    let slope = g.dot(dir);
    let mut t = 1.0;
    for _ in 0..30 {
        let q = p + dir * t;
        if star_energy(q, star, x, delta2).is_some_and(|e| e <= e0 + 1e-4 * t * slope) {
            x[v] = q;
            return;
        }
        t *= 0.5;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ccw(uv: &[DVec2], f: &[u32]) -> bool {
        let [a, b, c] = [0, 1, 2].map(|k| uv[f[k] as usize]);
        (b - a).perp_dot(c - a) > 0.0
    }

    /// The analytic gradient and Hessian agree with central differences of the energy, for
    /// valid and inverted triangles, with and without the regularization.
    #[test]
    fn derivatives_match_finite_differences() {
        let (a, b) = (DVec2::new(1.0, 0.2), DVec2::new(0.3, 1.1));
        for (x, delta2) in [
            (DVec2::new(0.1, -0.2), 0.0),
            (DVec2::new(0.1, -0.2), 1e-3),
            (DVec2::new(1.5, 1.4), 1e-3), // inverted
        ] {
            let (e, g, h) = energy_derivatives(x, a, b, delta2).unwrap();
            assert_eq!(energy(x, a, b, delta2), Some(e));
            let s = 1e-5;
            let fd = |d: DVec2| {
                (energy(x + d, a, b, delta2).unwrap() - energy(x - d, a, b, delta2).unwrap())
                    / (2.0 * s)
            };
            let gfd = DVec2::new(fd(DVec2::X * s), fd(DVec2::Y * s));
            assert!((g - gfd).length() < 1e-5 * (1.0 + g.length()), "{g} {gfd}");
            let gd = |d: DVec2| {
                (energy_derivatives(x + d, a, b, delta2).unwrap().1
                    - energy_derivatives(x - d, a, b, delta2).unwrap().1)
                    / (2.0 * s)
            };
            let (hx, hy) = (gd(DVec2::X * s), gd(DVec2::Y * s));
            let scale = 1.0 + h.iter().map(|v| v.abs()).fold(0.0, f64::max);
            for (got, want) in [(h[0], hx.x), (h[1], hx.y), (h[1], hy.x), (h[2], hy.y)] {
                assert!((got - want).abs() < 1e-4 * scale, "{h:?} {hx} {hy}");
            }
        }
        // δ = 0 and an inverted triangle: undefined, not a wrong number.
        assert_eq!(energy(DVec2::new(1.5, 1.4), a, b, 0.0), None);
    }

    /// Two free nodes inside an octagon, dragged across each other (each one's star
    /// contains the other): untangled, every triangle counterclockwise, boundary untouched.
    #[test]
    fn untangles_two_crossed_nodes_and_keeps_the_boundary() {
        // Boundary: an octagon; interior: nodes 0 and 1, a strip of triangles between them.
        let n = 8;
        let mut uv = vec![DVec2::new(0.5, 0.0), DVec2::new(-0.5, 0.0)];
        for k in 0..n {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            uv.push(DVec2::new(2.0 * a.cos(), 1.5 * a.sin()));
        }
        // Boundary nodes 2..10: 2 (angle 0) .. 6 (angle π). Node 0 sees 8,9,2,3,4; node 1
        // sees 4,5,6,7,8.
        let b = |k: usize| (2 + k % n) as u32;
        let mut faces: Vec<Vec<u32>> = Vec::new();
        for k in [6usize, 7, 0, 1] {
            faces.push(vec![0, b(k), b(k + 1)]);
        }
        for k in 2..6 {
            faces.push(vec![1, b(k), b(k + 1)]);
        }
        faces.push(vec![0, b(2), 1]);
        faces.push(vec![1, b(6), 0]);
        assert!(faces.iter().all(|f| ccw(&uv, f)), "the start must be valid");
        // Cross them over: 0 far left, 1 far right.
        uv[0] = DVec2::new(-1.6, 0.3);
        uv[1] = DVec2::new(1.6, -0.3);
        let bad = faces.iter().filter(|f| !ccw(&uv, f)).count();
        assert!(bad >= 2, "the test must fold faces ({bad})");
        let boundary: Vec<DVec2> = uv[2..].to_vec();
        assert!(untangle(&mut uv, 2, &faces, 200));
        for f in &faces {
            assert!(ccw(&uv, f), "face {f:?} still folded: {uv:?}");
        }
        assert_eq!(&uv[2..], &boundary[..]);
    }

    /// A valid mesh stays valid (the barrier holds once `δ = 0`), and a free node already
    /// at its best place moves little.
    #[test]
    fn a_valid_mesh_stays_valid() {
        let mut uv = vec![DVec2::ZERO];
        for k in 0..6 {
            let a = std::f64::consts::TAU * k as f64 / 6.0;
            uv.push(DVec2::new(a.cos(), a.sin()));
        }
        let faces: Vec<Vec<u32>> = (0..6u32).map(|k| vec![0, 1 + k, 1 + (k + 1) % 6]).collect();
        assert!(untangle(&mut uv, 1, &faces, 50));
        assert!(uv[0].length() < 1e-6, "{:?}", uv[0]);
    }

    /// A node that cannot be placed (its boundary ring is turned clockwise, so that no
    /// position makes its triangles counterclockwise) is reported, not hidden.
    #[test]
    fn reports_an_impossible_disc() {
        let mut uv = vec![DVec2::new(0.1, 0.0)];
        for k in 0..6 {
            let a = -std::f64::consts::TAU * k as f64 / 6.0;
            uv.push(DVec2::new(a.cos(), a.sin()));
        }
        let faces: Vec<Vec<u32>> = (0..6u32).map(|k| vec![0, 1 + k, 1 + (k + 1) % 6]).collect();
        assert!(!untangle(&mut uv, 1, &faces, 100));
        assert!(uv[0].is_finite());
    }
}

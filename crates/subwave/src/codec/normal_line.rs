//! Normal lines on the lossless grid: the lossless coder's line predictor, and a normal
//! remesh snapped onto it.
//!
//! Guskov, Vidimče, Sweldens & Schröder, "Normal Meshes" (SIGGRAPH 2000) §3, and
//! Khodakovsky & Guskov, "Compression of Normal Meshes" (2002): every odd vertex of a normal
//! mesh lies on the line through its butterfly prediction along the predicted surface's
//! normal, so one scalar places it. Lossy coding gets this from the local frames (Maret 2003
//! §4.5.2, Fig. 4.8): the two tangential components of a detail are zero. Lossless coding of
//! *quantized* positions does not: the decoder's line runs through the quantized coarser
//! level, and the grid point stored for a vertex lies up to a cell off that line, so its
//! residual has three nonzero components (the bunny's normal remesh at 12 bits, lossless:
//! 0.74× Draco's bytes, where a subdivided mesh costs 0.3×).
//!
//! This module closes the gap from both ends:
//! - `lines` computes the line of every odd vertex of a level from the exact (integer)
//!   coarser level, exactly as the lossless decoder does: `P` the butterfly prediction (the
//!   stencil table in `f64`, in stencil order) and `N` the unit normal of the codec's local
//!   frame on the predicted surface ([`odd_vertex_frames`]). `point` is the grid point
//!   `⌊P + k·N + ½⌋` of step `k`, `step` the step of a grid point on its line, if it is on
//!   it. The lossless coder's line predictor (mode 6 of [`super::lossless`]) codes `k` for
//!   the vertices on their line and the residual vector for the others.
//! - [`snap_to_lines`] puts a triangle hierarchy on the lossless grid level by level, coarse
//!   to fine: each odd vertex within [`SnapOptions::reach`] cells of its line (the vertices a
//!   normal re-sampling pierced, [`crate::remesh::normal`]) goes to the grid point of its
//!   line nearest to it, every other vertex to its nearest grid point. The result is the
//!   remesh quantized on the grid, each vertex at most `reach + 1.5` cells from where it was,
//!   and the lossless coder places most vertices with one integer.
//!
//! # Determinism
//! The lines are `f64` sums in a fixed order with no fused multiply-adds, so one build
//! computes the same grid points in the encoder, the decoder and [`snap_to_lines`]. The
//! snap only raises the share of vertices on their line: a vertex that the encoder's
//! hierarchy (re-indexed by the base-mesh coder, so summed in another order) finds off its
//! line by a last-bit difference is coded as a residual, never wrongly.

use glam::DVec3;
use rayon::prelude::*;

use super::lossless::{apply_int, floor_i64, scheme_tables};
use super::quantize::Grid;
use crate::hierarchy::Hierarchy;
use crate::subdivision::refine::Split;
use crate::subdivision::stencil::StencilTable;
use crate::subdivision::Scheme;
use crate::topology::Topology;
use crate::wavelet::frames::odd_vertex_frames;
use crate::{Error, Result};

/// The normal lines `(P, N)` of the odd vertices `V_j..V_{j+1}` of level `j + 1`, in grid
/// units, from the exact values `even` of the level-`j` vertices: `P` the butterfly
/// prediction (row `v` of `bfly`, the butterfly stencil table of step `j`), `N` the unit
/// normal of the local frame on the predicted level-`j + 1` surface.
///
/// # Panics
/// If `bfly` does not have a row per vertex of `fine` with sources below `even.len()`, or
/// `even.len()` is not `coarse`'s vertex count (the lossless coder checks its tables
/// against the hierarchy before calling this).
pub(crate) fn lines(
    bfly: &StencilTable,
    coarse: &Topology,
    fine: &Topology,
    even: &[[i64; 3]],
) -> Vec<(DVec3, DVec3)> {
    let nc = even.len();
    let nf = fine.num_vertices as usize;
    assert_eq!(nc, coarse.num_vertices as usize, "coarse vertices");
    assert_eq!(bfly.len(), nf, "butterfly rows");
    let mut predicted: Vec<DVec3> = Vec::with_capacity(nf);
    predicted.extend(
        even.iter()
            .map(|x| DVec3::new(x[0] as f64, x[1] as f64, x[2] as f64)),
    );
    predicted.par_extend(
        (nc..nf)
            .into_par_iter()
            .with_min_len(4096)
            .map(|v| DVec3::from_array(apply_int(bfly, v, even))),
    );
    let frames = odd_vertex_frames(coarse, fine, &predicted);
    frames
        .iter()
        .zip(&predicted[nc..])
        .map(|(f, &p)| (p, f.normal))
        .collect()
}

/// The grid point `⌊P + k·N + ½⌋` of step `k` on the line `(p, n)` (saturating: a corrupt
/// step gives a far point, which the decoder's coordinate bound refuses).
#[inline]
pub(crate) fn point(p: DVec3, n: DVec3, k: i64) -> [i64; 3] {
    let k = k as f64;
    [
        floor_i64(p.x + k * n.x + 0.5),
        floor_i64(p.y + k * n.y + 0.5),
        floor_i64(p.z + k * n.z + 0.5),
    ]
}

/// The step `k` with [`point`]`(p, n, k) == x`, searched around the projection of `x` on
/// the line (`k` nearest to it first, then up to two steps either way); `None` if `x` is
/// not on the line.
pub(crate) fn step(p: DVec3, n: DVec3, x: [i64; 3]) -> Option<i64> {
    let t = (DVec3::new(x[0] as f64, x[1] as f64, x[2] as f64) - p).dot(n);
    if t.is_nan() || t.abs() >= (1u64 << 40) as f64 {
        return None;
    }
    let k0 = floor_i64(t + 0.5);
    [0, -1, 1, -2, 2]
        .into_iter()
        .map(|o| k0 + o)
        .find(|&k| point(p, n, k) == x)
}

/// Options of [`snap_to_lines`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SnapOptions {
    /// Bits of the grid (`2^bits − 1` steps over the longest side of the bounding box, the
    /// lossless coder's grid at the same bits; 1..=24).
    pub bits: u32,
    /// An odd vertex goes onto its line if it is at most this many grid steps from it
    /// (default 4). A normal re-sampling's vertex lies on the line through the unquantized
    /// coarser level, which the grid moves by up to a cell, and its normal turns with it: the
    /// farther the vertex is along its line, the farther it is from the decoder's. Measured
    /// at 12 bits (bytes, reach 2 → 4 → 8; PSNR of the decoded remesh against the input):
    /// stanford-bunny 35,559 → 35,147 → 35,066 (83.19 → 83.16 → 83.05 dB), spot 5,898 →
    /// 5,689 → 5,496 (71.23 → 71.19 → 71.15 dB), teapot 5,236 → 5,028 → 4,919, cow 15,697 →
    /// 15,342 → 15,100, suzanne 3,663 → 3,575 → 3,464 (the last three within 0.02 dB up to
    /// 4; the cow 0.16 dB farther at 8); rocker-arm 12,509 → 12,419 at 4 (78.39 → 78.37 dB).
    pub reach: f64,
}

impl Default for SnapOptions {
    fn default() -> Self {
        SnapOptions {
            bits: 12,
            reach: 4.0,
        }
    }
}

/// What [`snap_to_lines`] did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SnapStats {
    /// For each refinement step `j → j + 1`: the odd vertices of level `j + 1`.
    pub odd: Vec<usize>,
    /// For each step: the odd vertices on their normal line (where the lossless coder finds
    /// them: those put there, and any rounded one that happens to be on it).
    pub on_line: Vec<usize>,
    /// The grid step (model units).
    pub grid_step: f64,
    /// The mean distance a vertex moved, in grid steps.
    pub mean_move: f64,
    /// The largest distance a vertex moved, in grid steps.
    pub max_move: f64,
    /// Vertices put back on their rounded grid points because their move turned a finest
    /// face over (or made it degenerate) that rounding alone keeps.
    pub reverted: usize,
}

impl SnapStats {
    /// The share of the odd vertices put on their line (1 if there are none).
    pub fn on_line_fraction(&self) -> f64 {
        crate::remesh::normal::share(&self.on_line, &self.odd)
    }
}

/// Puts the triangle hierarchy `h` on the lossless grid of `opts.bits` bits (its bounding
/// box's), its odd vertices on the lossless coder's normal lines where they are within
/// `opts.reach` grid steps of them (see the module documentation); the connectivity is
/// unchanged. One vertex on each face of the bounding box is only rounded and no vertex
/// leaves the box, so that the snapped hierarchy has the same box, and a lossless encoder at
/// `opts.bits` bits (of the hierarchy or of the mesh written from it) finds the same grid.
///
/// # Errors
/// [`Error::InvalidArgument`] for a quad hierarchy, bits out of `1..=24`, a negative or
/// non-finite reach, or a non-finite position.
pub fn snap_to_lines(h: &mut Hierarchy, opts: &SnapOptions) -> Result<SnapStats> {
    if h.split != Split::Triangles {
        return Err(Error::InvalidArgument(
            "snapping to normal lines needs a triangle hierarchy (not --quads)".into(),
        ));
    }
    if !(1..=24).contains(&opts.bits) {
        return Err(Error::InvalidArgument(format!(
            "grid bits {} out of range 1..=24",
            opts.bits
        )));
    }
    if !(opts.reach >= 0.0 && opts.reach.is_finite()) {
        return Err(Error::InvalidArgument(format!(
            "snap reach {} must be a finite number of grid steps ≥ 0",
            opts.reach
        )));
    }
    if let Some(v) = h.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::InvalidArgument(format!(
            "vertex {v} has a non-finite coordinate"
        )));
    }
    let [lo, hi] = super::progressive::bbox(&h.positions);
    let grid = Grid::new(lo, hi, opts.bits);
    let top = ((hi - lo) / grid.step).round();
    let top = [top.x as i64, top.y as i64, top.z as i64];
    let x: Vec<DVec3> = h
        .positions
        .iter()
        .map(|&p| (p - grid.origin) / grid.step)
        .collect();
    let mut q: Vec<[i64; 3]> = h
        .positions
        .iter()
        .map(|&p| grid.quantize(p).map(i64::from))
        .collect();
    // One vertex on each face of the box stays rounded (the first with the face's
    // coordinate), and no vertex leaves the box: the box, and so the grid, stay.
    let mut anchors = Vec::with_capacity(6);
    for c in 0..3 {
        for side in [0, top[c]] {
            if let Some(v) = q.iter().position(|g| g[c] == side) {
                anchors.push(v);
            }
        }
    }
    let rounded = q.clone();
    let mut base = h.base.clone();
    base.edge_tags.clear();
    base.vertex_tags.clear();
    let tables = scheme_tables(h, &base, Scheme::Butterfly)?.stencils;
    let mut stats = SnapStats {
        grid_step: grid.step,
        ..SnapStats::default()
    };
    let reach = opts.reach;
    for (j, table) in tables.iter().enumerate() {
        let (vj, n) = (h.num_vertices(j), h.num_vertices(j + 1));
        let l = lines(table, h.topology(j), h.topology(j + 1), &q[..vj]);
        let on_line = q[vj..n]
            .par_iter_mut()
            .with_min_len(1024)
            .zip(&x[vj..n])
            .zip(&l)
            .enumerate()
            .map(|(i, ((qv, &xv), &(p, nrm)))| {
                let t = (xv - p).dot(nrm);
                let off = (xv - p - t * nrm).length();
                if !anchors.contains(&(vj + i)) && off <= reach {
                    let c = point(p, nrm, floor_i64(t + 0.5));
                    if (0..3).all(|i| (0..=top[i]).contains(&c[i])) {
                        *qv = c;
                        return 1;
                    }
                }
                // A rounded point can be on its line too (the coder finds it there).
                usize::from(step(p, nrm, *qv).is_some())
            })
            .sum::<usize>();
        stats.odd.push(n - vj);
        stats.on_line.push(on_line);
    }
    stats.reverted = revert_turned_faces(h, &x, &rounded, &mut q);
    // A revert moves a vertex off its line and the lines of its descendants: count again.
    stats
        .on_line
        .truncate(if stats.reverted > 0 { 0 } else { tables.len() });
    for (j, table) in tables.iter().enumerate().skip(stats.on_line.len()) {
        let (vj, n) = (h.num_vertices(j), h.num_vertices(j + 1));
        let l = lines(table, h.topology(j), h.topology(j + 1), &q[..vj]);
        stats.on_line.push(
            (vj..n)
                .into_par_iter()
                .with_min_len(4096)
                .filter(|&v| step(l[v - vj].0, l[v - vj].1, q[v]).is_some())
                .count(),
        );
    }
    let moved: Vec<f64> = q
        .iter()
        .zip(&x)
        .map(|(g, xv)| (DVec3::new(g[0] as f64, g[1] as f64, g[2] as f64) - *xv).length())
        .collect();
    stats.mean_move = moved.iter().sum::<f64>() / moved.len().max(1) as f64;
    stats.max_move = moved.iter().copied().fold(0.0, f64::max);
    h.positions = q.iter().map(|&g| grid.dequantize(g)).collect();
    Ok(stats)
}

/// Rounds of [`revert_turned_faces`].
const REVERT_ROUNDS: usize = 4;

/// The finest faces of `h` that the snap turned over or made degenerate (grid points `q`)
/// where the rounded grid points `rounded` keep their orientation before the snap (`x`):
/// their moved vertices go back to `rounded`, for up to [`REVERT_ROUNDS`] rounds (a revert
/// can turn a neighbour). The points of finer vertices stay where they are: they leave their
/// lines, which the lossless coder then codes as residuals. Returns the vertices reverted.
fn revert_turned_faces(
    h: &Hierarchy,
    x: &[DVec3],
    rounded: &[[i64; 3]],
    q: &mut [[i64; 3]],
) -> usize {
    let g = |p: [i64; 3]| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
    let normal = |fv: &[u32], at: &dyn Fn(usize) -> DVec3| {
        let (a, b, c) = (at(fv[0] as usize), at(fv[1] as usize), at(fv[2] as usize));
        (b - a).cross(c - a)
    };
    let topo = h.topology(h.levels());
    let mut reverted = 0;
    for _ in 0..REVERT_ROUNDS {
        let qs: &[[i64; 3]] = q;
        let bad: Vec<u32> = (0..topo.num_faces())
            .into_par_iter()
            .with_min_len(4096)
            .flat_map_iter(|f| {
                let fv = topo.face_vertices(f);
                let bad = fv.len() == 3 && {
                    let before = normal(fv, &|v| x[v]);
                    let turned = |n: DVec3| n.dot(before) <= 0.0;
                    turned(normal(fv, &|v| g(qs[v]))) && !turned(normal(fv, &|v| g(rounded[v])))
                };
                let fv = if bad { fv } else { &[] };
                fv.iter()
                    .copied()
                    .filter(|&v| qs[v as usize] != rounded[v as usize])
            })
            .collect();
        if bad.is_empty() {
            break;
        }
        for v in bad {
            let v = v as usize;
            if q[v] != rounded[v] {
                q[v] = rounded[v];
                reverted += 1;
            }
        }
    }
    reverted
}

/// [`snap_to_lines`] on the triangle remesh `r` of `input`, after its normal re-sampling
/// ([`crate::remesh::normal::resample_remesh`]): updates `r.hierarchy`, `r.mesh` (positions
/// only) and re-measures `r.quality` against `input` (a move of a few grid steps can fold a
/// sliver face: the count says so, with a warning in `r.warnings`).
///
/// # Errors
/// As [`snap_to_lines`]; [`Error::InvalidArgument`] if `input` has no triangles or names a
/// vertex that does not exist.
pub fn snap_remesh(
    r: &mut crate::remesh::Remeshed,
    input: &crate::mesh::Mesh,
    opts: &SnapOptions,
) -> Result<SnapStats> {
    let stats = snap_to_lines(&mut r.hierarchy, opts)?;
    r.mesh.positions.clone_from(&r.hierarchy.positions);
    let surface =
        crate::remesh::normal::NormalSurface::new(&input.positions, &input.triangulate().0)?;
    let flipped = r.quality.flipped;
    r.quality = crate::remesh::quality::measure(&r.mesh, surface.projector());
    if r.quality.flipped > flipped {
        r.warnings.push(format!(
            "{} face(s) flipped after the snap to the {}-bit grid",
            r.quality.flipped - flipped,
            opts.bits
        ));
    }
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::progressive::{decode, encode, DecodeOptions, EncodeOptions, Wavelet};
    use crate::generate;

    /// A normal mesh of a bumpy sphere over an icosahedron: level by level, every odd vertex
    /// on the bumpy surface along its line (computed from the coarser level at a precision of
    /// 10⁻⁶, far finer than the 12-bit grid of the tests).
    fn bumpy(levels: usize) -> Hierarchy {
        let radius = |u: DVec3| 1.0 + 0.05 * (5.0 * u.x).sin() * (4.0 * u.y).cos();
        let base = generate::icosahedron();
        let h = Hierarchy::new(&base, levels as u32, Split::Triangles, None).unwrap();
        let mut pos = h.positions.clone();
        for p in &mut pos[..h.num_vertices(0)] {
            *p = p.normalize() * radius(p.normalize());
        }
        let tables = scheme_tables(&h, &h.base, Scheme::Butterfly)
            .unwrap()
            .stencils;
        for (j, t) in tables.iter().enumerate() {
            let (vj, n) = (h.num_vertices(j), h.num_vertices(j + 1));
            let even: Vec<[i64; 3]> = pos[..vj]
                .iter()
                .map(|p| (*p * 1e6).round().to_array().map(|c| c as i64))
                .collect();
            let l = lines(t, h.topology(j), h.topology(j + 1), &even);
            for v in vj..n {
                let (p, nrm) = (l[v - vj].0 / 1e6, l[v - vj].1);
                let mut t = 0.0;
                for _ in 0..30 {
                    let x = p + t * nrm;
                    let u = x.normalize();
                    t += (radius(u) - x.length()) / nrm.dot(u);
                }
                pos[v] = p + t * nrm;
            }
        }
        Hierarchy::new(&base, levels as u32, Split::Triangles, Some(pos)).unwrap()
    }

    #[test]
    fn a_point_is_found_on_its_line() {
        let (p, n) = (DVec3::new(10.3, -4.2, 7.9), DVec3::new(0.6, 0.0, 0.8));
        for k in -40..40 {
            let x = point(p, n, k);
            let s = step(p, n, x).expect("on its line");
            assert_eq!(point(p, n, s), x);
        }
        assert_eq!(step(p, n, [10, 3, 8]), None);
    }

    #[test]
    fn snapped_vertices_are_on_the_lines_the_lossless_coder_finds() {
        let mut h = bumpy(4);
        let before = h.positions.clone();
        let s = snap_to_lines(&mut h, &SnapOptions::default()).unwrap();
        assert!(s.on_line_fraction() > 0.9, "{s:?}");
        let bound = SnapOptions::default().reach + 1.5;
        assert!(s.max_move <= bound, "{s:?}");
        let step_len = s.grid_step;
        for (a, b) in before.iter().zip(&h.positions) {
            assert!(a.distance(*b) <= bound * step_len);
        }
        // Recompute the lines from the snapped grid points, as a decoder would.
        let grid = {
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(-f64::INFINITY));
            for p in &h.positions {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            Grid::new(lo, hi, 12)
        };
        let q: Vec<[i64; 3]> = h
            .positions
            .iter()
            .map(|&p| grid.quantize(p).map(i64::from))
            .collect();
        let tables = scheme_tables(&h, &h.base, Scheme::Butterfly)
            .unwrap()
            .stencils;
        let mut on = 0;
        for (j, t) in tables.iter().enumerate() {
            let (vj, n) = (h.num_vertices(j), h.num_vertices(j + 1));
            let l = lines(t, h.topology(j), h.topology(j + 1), &q[..vj]);
            on += (vj..n)
                .filter(|&v| step(l[v - vj].0, l[v - vj].1, q[v]).is_some())
                .count();
        }
        assert_eq!(on, s.on_line.iter().sum::<usize>());
    }

    #[test]
    fn a_snapped_remesh_codes_smaller_losslessly_and_exactly() {
        let mut h = bumpy(4);
        let opts = EncodeOptions {
            lossless: true,
            bits: 12,
            wavelet: Wavelet::Butterfly,
            ..Default::default()
        };
        let plain = encode(&h, &opts).unwrap();
        snap_to_lines(&mut h, &SnapOptions::default()).unwrap();
        let snapped = encode(&h, &opts).unwrap();
        assert!(
            (snapped.len() as f64) < 0.8 * plain.len() as f64,
            "{} vs {}",
            snapped.len(),
            plain.len()
        );
        let d = decode(&snapped, &DecodeOptions::default()).unwrap();
        assert!(d.complete);
        let mut a: Vec<[u64; 3]> = d
            .mesh
            .positions
            .iter()
            .map(|p| p.to_array().map(f64::to_bits))
            .collect();
        let mut b: Vec<[u64; 3]> = h
            .positions
            .iter()
            .map(|p| p.to_array().map(f64::to_bits))
            .collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(
            a, b,
            "the decoded positions are the snapped ones, bit for bit"
        );
    }

    #[test]
    fn refuses_quads_and_bad_options() {
        let mut q = Hierarchy::new(&generate::cube(), 1, Split::Polygons, None).unwrap();
        assert!(snap_to_lines(&mut q, &SnapOptions::default()).is_err());
        let mut h = bumpy(1);
        for o in [
            SnapOptions {
                bits: 0,
                ..Default::default()
            },
            SnapOptions {
                bits: 25,
                ..Default::default()
            },
            SnapOptions {
                reach: f64::NAN,
                ..Default::default()
            },
            SnapOptions {
                reach: -1.0,
                ..Default::default()
            },
        ] {
            assert!(snap_to_lines(&mut h, &o).is_err(), "{o:?}");
        }
        h.positions[0].x = f64::INFINITY;
        assert!(snap_to_lines(&mut h, &SnapOptions::default()).is_err());
    }
}

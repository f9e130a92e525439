//! The MAPS parameterization as a map from the base domain onto the input surface.
//!
//! Lee, Sweldens, Schröder, Cowsar & Dobkin, "MAPS: Multiresolution Adaptive
//! Parameterization of Surfaces" (SIGGRAPH 1998), §3.4 ("point location"): after the
//! simplification of [`super::simplify`], every input vertex has a parameter
//! `(base triangle, barycentric coordinates)`, so every input triangle has an image in the
//! base domain. A point of the base domain is mapped onto the input surface by finding the
//! input triangle whose image contains it and interpolating the input positions with the
//! barycentric coordinates of the point in that image (piecewise linear, so the image lies on
//! the input surface).
//!
//! Input triangles whose corners lie in different base triangles straddle base edges or
//! vertices; MAPS flattens the neighbourhood with a conformal map. Here each base triangle `t`
//! has an affine *chart* of the base triangles sharing a vertex with it: each neighbour is
//! unfolded across the shared edge as a parallelogram (the corner opposite the edge goes to
//! `a + b − c`), composing unfoldings along the shortest edge path (breadth first). Corners
//! that are base vertices of `t` map to `t`'s corners exactly. Each input triangle is
//! registered in the frames of its corners' base triangles (and of the base triangles around
//! a base-vertex corner), and each frame has a uniform grid over its barycentric square for
//! point location.

use glam::DVec3;
use rayon::prelude::*;

use super::simplify::Param;
use crate::mesh::Mesh;
use crate::topology::Topology;

type Mat = [[f64; 3]; 3]; // columns: the frame coordinates of a neighbour's corners

fn mul(m: &Mat, b: [f64; 3]) -> [f64; 3] {
    let mut r = [0.0; 3];
    for (j, col) in m.iter().enumerate() {
        for i in 0..3 {
            r[i] += col[i] * b[j];
        }
    }
    r
}

/// A registered input triangle in one base frame.
#[derive(Clone, Copy)]
struct Entry {
    tri: u32,
    /// Frame coordinates (x, y) = (b1, b2) of its three corners.
    xy: [[f64; 2]; 3],
}

/// The inverse parameterization: base domain → input surface.
pub struct ParamMap<'a> {
    input_pos: &'a [DVec3],
    input_tris: &'a [[u32; 3]],
    base_tris: Vec<[u32; 3]>,
    charts: Vec<Vec<(u32, Mat)>>,
    entries: Vec<Vec<Entry>>,
    grid_res: Vec<u32>,
    grid_offsets: Vec<Vec<u32>>,
    grid_members: Vec<Vec<u32>>,
    /// Input triangles that could not be registered in any frame.
    pub unregistered: usize,
}

/// Where a base-domain point landed.
#[derive(Clone, Copy, Debug)]
pub struct Located {
    /// The input triangle.
    pub tri: u32,
    /// Barycentric coordinates in it (clamped to the triangle).
    pub lambda: [f64; 3],
    /// The smallest unclamped coordinate: ≥ 0 (up to rounding) when the point was inside the
    /// triangle's image, negative when the nearest image was taken.
    pub inside: f64,
}

impl<'a> ParamMap<'a> {
    /// Builds charts (spread around the base vertices marked in `spread`, see `spread_fans`;
    /// empty: none), registrations and grids.
    ///
    /// Preconditions: `base` is a manifold triangle mesh; every `params[i].face` indexes it.
    pub fn new(
        base: &Mesh,
        input_pos: &'a [DVec3],
        input_tris: &'a [[u32; 3]],
        params: &[Param],
        spread: &[bool],
    ) -> ParamMap<'a> {
        let topo = Topology::build(base);
        let nb = base.num_faces();
        let base_tris: Vec<[u32; 3]> = base.faces().map(|f| [f[0], f[1], f[2]]).collect();
        let charts: Vec<Vec<(u32, Mat)>> = (0..nb)
            .into_par_iter()
            .map(|t| build_chart(&topo, &base_tris, t, spread))
            .collect();
        // Registration.
        let mut entries: Vec<Vec<Entry>> = vec![Vec::new(); nb];
        let mut unregistered = 0;
        let mut frames: Vec<u32> = Vec::with_capacity(16);
        let to_frame = |t: usize, p: &Param| -> Option<[f64; 3]> {
            if p.face as usize == t {
                return Some(p.bary);
            }
            // A base vertex that is a corner of t.
            if let Some(k) = p.bary.iter().position(|&x| x == 1.0) {
                let w = base_tris[p.face as usize][k];
                if let Some(c) = base_tris[t].iter().position(|&x| x == w) {
                    let mut b = [0.0; 3];
                    b[c] = 1.0;
                    return Some(b);
                }
            }
            charts[t]
                .iter()
                .find(|(f, _)| *f == p.face)
                .map(|(_, m)| mul(m, p.bary))
        };
        for (ti, tri) in input_tris.iter().enumerate() {
            frames.clear();
            for &v in tri {
                let p = &params[v as usize];
                if !frames.contains(&p.face) {
                    frames.push(p.face);
                }
                if let Some(k) = p.bary.iter().position(|&x| x == 1.0) {
                    let w = base_tris[p.face as usize][k];
                    for &f in topo.vertex_faces(w as usize) {
                        if !frames.contains(&f) {
                            frames.push(f);
                        }
                    }
                }
            }
            let mut any = false;
            for &t in &frames {
                let t = t as usize;
                let b: Option<Vec<[f64; 3]>> = tri
                    .iter()
                    .map(|&v| to_frame(t, &params[v as usize]))
                    .collect();
                let Some(b) = b else { continue };
                let xy = [[b[0][1], b[0][2]], [b[1][1], b[1][2]], [b[2][1], b[2][2]]];
                let area = (xy[1][0] - xy[0][0]) * (xy[2][1] - xy[0][1])
                    - (xy[2][0] - xy[0][0]) * (xy[1][1] - xy[0][1]);
                if area.abs() < 1e-24 {
                    continue;
                }
                // Skip frames the image does not reach.
                let (minx, maxx) = min_max(xy.map(|p| p[0]));
                let (miny, maxy) = min_max(xy.map(|p| p[1]));
                if maxx < 0.0 || maxy < 0.0 || minx + miny > 1.0 || minx > 1.0 || miny > 1.0 {
                    continue;
                }
                entries[t].push(Entry { tri: ti as u32, xy });
                any = true;
            }
            if !any {
                unregistered += 1;
            }
        }
        // Grids.
        let grids: Vec<(u32, Vec<u32>, Vec<u32>)> =
            entries.par_iter().map(|e| build_grid(e)).collect();
        let mut grid_res = Vec::with_capacity(nb);
        let mut grid_offsets = Vec::with_capacity(nb);
        let mut grid_members = Vec::with_capacity(nb);
        for (g, o, m) in grids {
            grid_res.push(g);
            grid_offsets.push(o);
            grid_members.push(m);
        }
        ParamMap {
            input_pos,
            input_tris,
            base_tris,
            charts,
            entries,
            grid_res,
            grid_offsets,
            grid_members,
            unregistered,
        }
    }

    /// The base triangles.
    pub fn base_triangles(&self) -> &[[u32; 3]] {
        &self.base_tris
    }

    /// `p` expressed in base triangle `t`'s frame, if `p.face` is in `t`'s chart.
    pub fn to_frame(&self, t: u32, p: &Param) -> Option<[f64; 3]> {
        if p.face == t {
            return Some(p.bary);
        }
        self.charts[t as usize]
            .iter()
            .find(|(f, _)| *f == p.face)
            .map(|(_, m)| mul(m, p.bary))
    }

    /// The parameter of the point with coordinates `c` in `t`'s frame: in `t` if all of `c`
    /// is non-negative, else in the triangle of `t`'s chart that contains it (edge
    /// neighbours first); `None` if none does.
    pub fn relocate(&self, t: u32, c: [f64; 3]) -> Option<Param> {
        relocate(&self.charts, t, c)
    }

    /// The chart of `t`: its neighbours and the matrices taking their barycentric
    /// coordinates to `t`'s frame.
    pub fn chart(&self, t: u32) -> impl Iterator<Item = (u32, [[f64; 3]; 3])> + '_ {
        self.charts[t as usize].iter().copied()
    }

    /// Locates a base-domain point on the input: the input triangle whose image in the
    /// frame of the point's base triangle contains it, or the nearest image there
    /// ([`Located::inside`] negative).
    pub fn locate(&self, p: &Param) -> Located {
        let t = p.face as usize;
        let (x, y) = (p.bary[1], p.bary[2]);
        let g = self.grid_res[t];
        let mut best: Option<(f64, Entry, [f64; 3])> = None;
        let consider = |best: &mut Option<(f64, Entry, [f64; 3])>, e: &Entry| {
            let l = bary2(e.xy, x, y);
            let m = l[0].min(l[1]).min(l[2]);
            if best.as_ref().is_none_or(|(bm, _, _)| m > *bm) {
                *best = Some((m, *e, l));
            }
        };
        if g > 0 {
            let cx = ((x * g as f64).floor() as i64).clamp(0, g as i64 - 1) as usize;
            let cy = ((y * g as f64).floor() as i64).clamp(0, g as i64 - 1) as usize;
            let c = cy * g as usize + cx;
            let o = &self.grid_offsets[t];
            for &i in &self.grid_members[t][o[c] as usize..o[c + 1] as usize] {
                consider(&mut best, &self.entries[t][i as usize]);
            }
        }
        if best.as_ref().is_none_or(|(m, _, _)| *m < -1e-9) {
            for e in &self.entries[t] {
                consider(&mut best, e);
            }
        }
        Self::located(best)
    }

    /// The point in the frames of the base triangles of its triangle's chart, among the
    /// images registered there: where a base vertex's unfoldings disagree (the
    /// parallelogram charts do not close up around a vertex of valence other than six), an
    /// image that straddles base triangles can reach into `p.face` in a neighbour's frame
    /// although it does not in `p.face`'s own, leaving a gap there. The nearest image over
    /// those frames (`None` for a point whose chart holds no images).
    pub fn locate_around(&self, p: &Param) -> Option<Located> {
        let t = p.face as usize;
        let mut best: Option<(f64, Entry, [f64; 3])> = None;
        for &(n, _) in &self.charts[t] {
            let Some(m) = self.charts[n as usize]
                .iter()
                .find(|(f, _)| *f as usize == t)
                .map(|x| x.1)
            else {
                continue;
            };
            let b = mul(&m, p.bary);
            for e in &self.entries[n as usize] {
                let l = bary2(e.xy, b[1], b[2]);
                let mm = l[0].min(l[1]).min(l[2]);
                if best.as_ref().is_none_or(|(bm, _, _)| mm > *bm) {
                    best = Some((mm, *e, l));
                }
            }
        }
        best.is_some().then(|| Self::located(best))
    }

    /// The located point of the best entry (clamped and normalized coordinates).
    fn located(best: Option<(f64, Entry, [f64; 3])>) -> Located {
        match best {
            Some((m, e, l)) => {
                let mut l = l.map(|v| v.max(0.0));
                let s = l[0] + l[1] + l[2];
                if s > 0.0 {
                    l = l.map(|v| v / s);
                } else {
                    l = [1.0 / 3.0; 3];
                }
                Located {
                    tri: e.tri,
                    lambda: l,
                    inside: m,
                }
            }
            None => Located {
                tri: u32::MAX,
                lambda: [1.0 / 3.0; 3],
                inside: f64::NEG_INFINITY,
            },
        }
    }

    /// The (unnormalized) normal of input triangle `tri`.
    pub fn input_normal(&self, tri: u32) -> DVec3 {
        let t = self.input_tris[tri as usize];
        let p = |k: usize| self.input_pos[t[k] as usize];
        (p(1) - p(0)).cross(p(2) - p(0))
    }

    /// The input-surface point of a located parameter (`None` if nothing was found).
    pub fn point(&self, l: &Located) -> Option<DVec3> {
        if l.tri == u32::MAX {
            return None;
        }
        let t = self.input_tris[l.tri as usize];
        Some(
            self.input_pos[t[0] as usize] * l.lambda[0]
                + self.input_pos[t[1] as usize] * l.lambda[1]
                + self.input_pos[t[2] as usize] * l.lambda[2],
        )
    }
}

fn min_max(v: [f64; 3]) -> (f64, f64) {
    (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]))
}

/// Barycentric coordinates of `(x, y)` in the 2D triangle `xy` (either orientation).
fn bary2(xy: [[f64; 2]; 3], x: f64, y: f64) -> [f64; 3] {
    let [a, b, c] = xy;
    let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    let l1 = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (y - a[1])) / det;
    let l2 = ((b[0] - a[0]) * (y - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
    [1.0 - l1 - l2, l1, l2]
}

/// A uniform grid over the unit square of a base triangle's frame for [`ParamMap::locate`]:
/// its resolution, the offsets of each cell's members, and the members (indices of the
/// entries whose bounding boxes meet the cell).
fn build_grid(entries: &[Entry]) -> (u32, Vec<u32>, Vec<u32>) {
    if entries.is_empty() {
        return (0, vec![0], Vec::new());
    }
    // Four cells per image: a point's cell holds ~6 images on the bunny at 5 levels (13 with
    // one cell per two images, 23M candidate tests in the sampling relaxation instead of
    // 11M), for no more peak memory.
    let g = ((entries.len() as f64 * 4.0).sqrt().ceil() as u32).clamp(1, 256);
    let gf = g as f64;
    let cells = (g * g) as usize;
    let range = |e: &Entry| {
        let (minx, maxx) = min_max(e.xy.map(|p| p[0]));
        let (miny, maxy) = min_max(e.xy.map(|p| p[1]));
        let c = |v: f64| ((v * gf).floor() as i64).clamp(0, g as i64 - 1) as usize;
        (c(minx), c(maxx), c(miny), c(maxy))
    };
    let mut counts = vec![0u32; cells + 1];
    for e in entries {
        let (x0, x1, y0, y1) = range(e);
        for cy in y0..=y1 {
            for cx in x0..=x1 {
                counts[cy * g as usize + cx + 1] += 1;
            }
        }
    }
    for i in 0..cells {
        counts[i + 1] += counts[i];
    }
    let mut fill = counts.clone();
    let mut members = vec![0u32; counts[cells] as usize];
    for (i, e) in entries.iter().enumerate() {
        let (x0, x1, y0, y1) = range(e);
        for cy in y0..=y1 {
            for cx in x0..=x1 {
                let c = cy * g as usize + cx;
                members[fill[c] as usize] = i as u32;
                fill[c] += 1;
            }
        }
    }
    (g, counts, members)
}

/// The chart of base triangle `t`: every triangle sharing a vertex with it, reached by
/// edge-adjacent unfoldings (breadth first), with its corners' coordinates in `t`'s frame.
///
/// The parallelogram unfolding gives every triangle 60° at each corner, so the triangles
/// around a base vertex of valence `n` span `n · 60°` rather than a turn: an input triangle
/// with a corner at a base vertex that spans three of its triangles has a flat or inverted
/// image, and nearly all the images left folded after [`untangle_params`] are such (5
/// levels: suzanne 26 of 34, cow 10 of 12, fandisk 9 of 9). Two remedies were measured
/// and not kept: images around a base vertex in its own star flattening (folded images
/// 34 → 9 on suzanne, but the charts then disagree on the base edges between images taken
/// in different charts: suzanne's flipped faces 44 → 261), and isometric unfoldings (each
/// triangle's true shape; bunny 10 → 4, rocker-arm 4 → 0 flipped faces, but cow 51 → 151 and
/// teapot 40 → 144, where slivers of the base unfold wildly). A third is kept: around the
/// base vertices marked in `spread` ([`untangle_spreading_fans`] marks those of valence
/// over six at the corners of images the untangling leaves folded, and keeps the result
/// only if fewer are left), the triangles that share no edge with `t` are re-placed so that the fan
/// closes (`spread_fans`). Spreading every fan of valence over six was measured too (5
/// levels: suzanne 7 → 0 flipped faces, but teapot 6 → 8, beetle 96 → 124 bad faces).
fn build_chart(topo: &Topology, tris: &[[u32; 3]], t: usize, spread: &[bool]) -> Vec<(u32, Mat)> {
    let tv = tris[t];
    let near = |f: usize| tris[f].iter().any(|v| tv.contains(v));
    let mut out: Vec<(u32, Mat)> = Vec::new();
    let identity: Mat = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut queue: Vec<(u32, Mat)> = vec![(t as u32, identity)];
    let mut seen: Vec<u32> = vec![t as u32];
    let mut head = 0;
    while head < queue.len() {
        let (s, ms) = queue[head];
        head += 1;
        let st = tris[s as usize];
        for &e in topo.face_edges(s as usize) {
            let ef = topo.edge_faces(e as usize);
            for &n in ef {
                if n == s || seen.contains(&n) || !near(n as usize) {
                    continue;
                }
                seen.push(n);
                let [a, b] = topo.edge_vertices[e as usize];
                let ia = st.iter().position(|&x| x == a).unwrap();
                let ib = st.iter().position(|&x| x == b).unwrap();
                let ic = 3 - ia - ib;
                let ca = ms[ia];
                let cb = ms[ib];
                let cc = ms[ic];
                let d = [
                    ca[0] + cb[0] - cc[0],
                    ca[1] + cb[1] - cc[1],
                    ca[2] + cb[2] - cc[2],
                ];
                let nt = tris[n as usize];
                let mut m: Mat = [[0.0; 3]; 3];
                for (k, &w) in nt.iter().enumerate() {
                    m[k] = if w == a {
                        ca
                    } else if w == b {
                        cb
                    } else {
                        d
                    };
                }
                // Shared base vertices of t map to t's corners exactly.
                for (k, &w) in nt.iter().enumerate() {
                    if let Some(c) = tv.iter().position(|&x| x == w) {
                        let mut u = [0.0; 3];
                        u[c] = 1.0;
                        m[k] = u;
                    }
                }
                queue.push((n, m));
                out.push((n, m));
            }
        }
    }
    if !spread.is_empty() {
        spread_fans(topo, tris, t, spread, &mut out);
    }
    out
}

/// The valence whose fan the parallelogram unfoldings close exactly (6 · 60°); fans of
/// higher valence overlap.
const CLOSED_VALENCE: usize = 6;

/// Re-places, in `t`'s chart, the triangles around each interior corner `w` of `t` of
/// valence `k > 6` that share no edge with `t`: the parallelogram unfoldings give each of
/// them 60° at `w`, so going both ways round `w` they overlap past 360°. With `w` at the
/// origin of `t`'s frame taken as equilateral (`t`'s edges from `w` at 0° and 60°, its two
/// edge neighbours' far corners at 120° and 300°, as the unfolding puts them), the spokes in
/// between are spread evenly over the 180° left, so the fan closes up without overlap. Only
/// the corners marked in `spread` (indexed by base vertex) are re-placed; boundary
/// vertices, whose fans do not close, are left as unfolded.
fn spread_fans(
    topo: &Topology,
    tris: &[[u32; 3]],
    t: usize,
    spread: &[bool],
    out: &mut [(u32, Mat)],
) {
    let tv = tris[t];
    for cw in 0..3 {
        let w = tv[cw];
        let k = topo.vertex_faces(w as usize).len();
        if k <= CLOSED_VALENCE || !spread.get(w as usize).copied().unwrap_or(false) {
            continue;
        }
        // Walk around w counterclockwise from t: each face's corner before w (`prev`)
        // starts the next face's edge from w.
        let (xa, xb) = (tv[(cw + 1) % 3], tv[(cw + 2) % 3]);
        let mut spokes = vec![xa, xb];
        let mut faces = vec![t as u32];
        let mut f = t;
        let mut prev = xb;
        let closed = loop {
            let Some(e) = topo.find_edge(w, prev) else {
                break false;
            };
            let ef = topo.edge_faces(e as usize);
            if ef.len() != 2 {
                break false;
            }
            let g = if ef[0] as usize == f { ef[1] } else { ef[0] } as usize;
            if g == t {
                break true;
            }
            if faces.len() > k {
                break false;
            }
            let gv = tris[g];
            let Some(i) = gv.iter().position(|&x| x == w) else {
                break false;
            };
            if gv[(i + 1) % 3] != prev {
                break false;
            }
            prev = gv[(i + 2) % 3];
            faces.push(g as u32);
            spokes.push(prev);
            f = g;
        };
        // spokes: s_0 = xa, s_1 = xb, ..., s_{k-1}, then back to xa.
        if !closed || faces.len() != k || spokes.len() != k + 1 || spokes[k] != xa {
            continue;
        }
        // Spoke j's angle (degrees): 0, 60, then 120 .. 300 evenly.
        let angle = |j: usize| -> f64 {
            match j {
                0 => 0.0,
                1 => 60.0,
                _ => 120.0 + (j - 2) as f64 * 180.0 / (k - 3) as f64,
            }
        };
        let at = |j: usize| -> [f64; 3] {
            let th = angle(j).to_radians();
            let beta = 2.0 * th.sin() / 3f64.sqrt();
            let alpha = th.cos() - th.sin() / 3f64.sqrt();
            let mut b = [0.0; 3];
            b[cw] = 1.0 - alpha - beta;
            b[(cw + 1) % 3] = alpha;
            b[(cw + 2) % 3] = beta;
            b
        };
        // Faces 2..k-1 (face j spans spokes j and j+1) share no edge with t.
        for j in 2..k - 1 {
            let g = faces[j];
            let gv = tris[g as usize];
            let mut m: Mat = [[0.0; 3]; 3];
            for (c, &x) in gv.iter().enumerate() {
                m[c] = if x == w {
                    let mut u = [0.0; 3];
                    u[cw] = 1.0;
                    u
                } else if x == spokes[j] {
                    at(j)
                } else {
                    at(j + 1)
                };
            }
            if let Some(slot) = out.iter_mut().find(|(n, _)| *n == g) {
                slot.1 = m;
            }
        }
    }
}

/// `p` in base triangle `t`'s frame: directly, as a base vertex that is a corner of `t`, or
/// through `t`'s chart.
fn frame_of(
    charts: &[Vec<(u32, Mat)>],
    base_tris: &[[u32; 3]],
    t: u32,
    p: &Param,
) -> Option<[f64; 3]> {
    if p.face == t {
        return Some(p.bary);
    }
    if let Some(k) = p.bary.iter().position(|&x| x == 1.0) {
        let w = base_tris[p.face as usize][k];
        if let Some(c) = base_tris[t as usize].iter().position(|&x| x == w) {
            let mut b = [0.0; 3];
            b[c] = 1.0;
            return Some(b);
        }
    }
    charts[t as usize]
        .iter()
        .find(|(f, _)| *f == p.face)
        .map(|(_, m)| mul(m, p.bary))
}

/// The coordinates `x` with `m · x = c` (Cramer's rule); `None` if `m` is singular.
fn solve(m: &Mat, c: [f64; 3]) -> Option<[f64; 3]> {
    let det3 = |a: [f64; 3], b: [f64; 3], d: [f64; 3]| {
        a[0] * (b[1] * d[2] - b[2] * d[1]) - b[0] * (a[1] * d[2] - a[2] * d[1])
            + d[0] * (a[1] * b[2] - a[2] * b[1])
    };
    let det = det3(m[0], m[1], m[2]);
    if det.abs() < 1e-300 {
        return None;
    }
    Some([
        det3(c, m[1], m[2]) / det,
        det3(m[0], c, m[2]) / det,
        det3(m[0], m[1], c) / det,
    ])
}

/// The parameter of the point with coordinates `c` in `t`'s frame: in `t` if inside, else in
/// the chart triangle containing it (edge neighbours first, as the chart is ordered breadth
/// first). `None` if no triangle of the chart contains it.
fn relocate(charts: &[Vec<(u32, Mat)>], t: u32, c: [f64; 3]) -> Option<Param> {
    let norm = |x: [f64; 3]| {
        let x = x.map(|v| v.max(0.0));
        let s = x[0] + x[1] + x[2];
        x.map(|v| v / s)
    };
    if c.iter().all(|&v| v >= 0.0) {
        return Some(Param {
            face: t,
            bary: norm(c),
        });
    }
    for (f, m) in &charts[t as usize] {
        if let Some(x) = solve(m, c) {
            if x.iter().all(|&v| v >= -1e-12) {
                return Some(Param {
                    face: *f,
                    bary: norm(x),
                });
            }
        }
    }
    None
}

/// Twice the signed area of input triangle `tri`'s image in the base domain (in the frame of
/// one of its corners' base triangles); `None` if no frame holds all three corners.
fn image_area(
    charts: &[Vec<(u32, Mat)>],
    base_tris: &[[u32; 3]],
    params: &[Param],
    tri: [u32; 3],
) -> Option<f64> {
    for &v in &tri {
        let t = params[v as usize].face;
        let b: Option<Vec<[f64; 3]>> = tri
            .iter()
            .map(|&w| frame_of(charts, base_tris, t, &params[w as usize]))
            .collect();
        if let Some(b) = b {
            return Some(
                (b[1][1] - b[0][1]) * (b[2][2] - b[0][2])
                    - (b[2][1] - b[0][1]) * (b[1][2] - b[0][2]),
            );
        }
    }
    None
}

/// The parameter of chain point `v` (on a base edge, not a base vertex) moved along its
/// base edge to the mean of the edge parameters of its two neighbours `nb` on that edge's
/// line (points of the same edge or its end vertices); `None` unless there are exactly two.
fn slide_on_edge(
    charts: &[Vec<(u32, Mat)>],
    base_tris: &[[u32; 3]],
    params: &[Param],
    nb: &[u32],
    v: usize,
) -> Option<Param> {
    let p = params[v];
    let k = p.bary.iter().position(|&x| x == 0.0)?;
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    let mut along = [0.0f64; 2];
    let mut n = 0;
    for &w in nb {
        let q = params[w as usize];
        let on_edge = q.bary.contains(&1.0) || q.bary.contains(&0.0);
        if !on_edge {
            continue;
        }
        let Some(b) = frame_of(charts, base_tris, p.face, &q) else {
            continue;
        };
        if b[k].abs() > 1e-12 || b[i] < -1e-12 || b[j] < -1e-12 {
            continue;
        }
        if n == 2 {
            return None;
        }
        along[n] = b[j];
        n += 1;
    }
    if n != 2 {
        return None;
    }
    let s = (0.5 * (along[0] + along[1])).clamp(0.0, 1.0);
    if s <= 0.0 || s >= 1.0 {
        return None;
    }
    let mut bary = [0.0; 3];
    bary[i] = 1.0 - s;
    bary[j] = s;
    Some(Param { face: p.face, bary })
}

/// Gauss-Seidel sweeps of [`untangle_params`] per round.
const TUTTE_SWEEPS: usize = 30;

/// Untangles the parameterization (the images of the input triangles in the base domain must
/// not overlap, or a base-domain point has several images and [`ParamMap::locate`] may pick
/// the wrong one, far from its neighbours'): every input triangle whose image is inverted,
/// degenerate, or spread over base triangles no chart holds together is *bad*; the free
/// vertices of the bad triangles and their rings (growing by one ring per round, up to
/// `rounds` rounds) are moved towards the average of their neighbours' parameters (Tutte's
/// barycentric embedding, Gauss-Seidel, in the chart of the vertex's base triangle or of a
/// neighbour's), which embeds a disc with a convex boundary without folds (Floater 1997); as
/// the regions' boundaries need not be convex, a move is kept only if it does not add bad
/// triangles around the vertex, so the count never grows. `fixed` vertices keep their
/// parameters, except those on a base edge (boundary and feature points on their chains),
/// which slide along it to the mean of their two neighbours on it (in 1D, kept only if
/// that lowers the bad triangles around them); base vertices stay. The images left bad
/// are nearly all at base vertices (see `build_chart`).
///
/// Charts are spread around the base vertices marked in `spread` (see `spread_fans`; empty:
/// none). Returns the number of bad input triangles before and after, and the base
/// vertices at the corners of those left.
///
/// Preconditions: as [`ParamMap::new`]; `fixed.len() == params.len()`.
pub fn untangle_params(
    base: &Mesh,
    input_tris: &[[u32; 3]],
    params: &mut [Param],
    fixed: &[bool],
    rounds: u32,
    spread: &[bool],
) -> Untangled {
    let topo = Topology::build(base);
    let base_tris: Vec<[u32; 3]> = base.faces().map(|f| [f[0], f[1], f[2]]).collect();
    let charts: Vec<Vec<(u32, Mat)>> = (0..base.num_faces())
        .into_par_iter()
        .map(|t| build_chart(&topo, &base_tris, t, spread))
        .collect();
    let nv = params.len();
    let is_bad = |params: &[Param], tri: [u32; 3]| {
        image_area(&charts, &base_tris, params, tri).is_none_or(|a| a <= 1e-18)
    };
    let bad: Vec<bool> = input_tris.par_iter().map(|&t| is_bad(params, t)).collect();
    let before = bad.iter().filter(|&&b| b).count();
    if before == 0 {
        return Untangled::default();
    }
    // Vertex → faces and vertex → neighbours of the input.
    let mut vf: Vec<Vec<u32>> = vec![Vec::new(); nv];
    let mut nb: Vec<Vec<u32>> = vec![Vec::new(); nv];
    for (f, t) in input_tris.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3]);
            vf[a].push(f as u32);
            if !nb[a].contains(&b) {
                nb[a].push(b);
            }
            if !nb[b as usize].contains(&t[k]) {
                nb[b as usize].push(t[k]);
            }
        }
    }
    let mut bad_faces: Vec<u32> = (0..input_tris.len() as u32)
        .filter(|&f| bad[f as usize])
        .collect();
    let mut after = before;
    for round in 0..rounds {
        if bad_faces.is_empty() {
            break;
        }
        let mut region = vec![false; nv];
        for &f in &bad_faces {
            for &v in &input_tris[f as usize] {
                region[v as usize] = true;
            }
        }
        for _ in 0..(round + 1).min(6) {
            let grown = region.clone();
            for (v, &r) in grown.iter().enumerate() {
                if r {
                    for &w in &nb[v] {
                        region[w as usize] = true;
                    }
                }
            }
        }
        let verts: Vec<usize> = (0..nv).filter(|&v| region[v] && !fixed[v]).collect();
        // Fixed points on a base edge (not base vertices): the chain points.
        let chain_verts: Vec<usize> = (0..nv)
            .filter(|&v| {
                let b = params[v].bary;
                region[v] && fixed[v] && !b.contains(&1.0) && b.contains(&0.0)
            })
            .collect();
        let mut stuck = 0;
        for _ in 0..TUTTE_SWEEPS {
            for &v in &verts {
                if nb[v].is_empty() {
                    continue;
                }
                // The frame: the vertex's base triangle, or (if it sits in a base triangle
                // far from its neighbours') a neighbour's.
                let frames = std::iter::once(params[v].face)
                    .chain(nb[v].iter().map(|&w| params[w as usize].face));
                let mut avg = None;
                for t in frames {
                    let mut c = [0.0; 3];
                    let mut ok = true;
                    for &w in &nb[v] {
                        match frame_of(&charts, &base_tris, t, &params[w as usize]) {
                            Some(b) => {
                                for k in 0..3 {
                                    c[k] += b[k];
                                }
                            }
                            None => {
                                ok = false;
                                break;
                            }
                        }
                    }
                    if ok {
                        avg = Some((t, c));
                        break;
                    }
                }
                let Some((t, c)) = avg else {
                    stuck += 1;
                    continue;
                };
                let n = nb[v].len() as f64;
                match relocate(&charts, t, c.map(|x| x / n)) {
                    Some(p) => {
                        // Only moves that do not add bad triangles around the vertex.
                        let count = |params: &[Param]| {
                            vf[v]
                                .iter()
                                .filter(|&&f| is_bad(params, input_tris[f as usize]))
                                .count()
                        };
                        let now = count(params);
                        let old = params[v];
                        params[v] = p;
                        if count(params) > now {
                            params[v] = old;
                        }
                    }
                    None => stuck += 1,
                }
            }
            // Chain points slide along their base edge, to the mean of their two
            // neighbours on the same edge (Tutte's embedding of the chain, in 1D).
            for &v in &chain_verts {
                let Some(p) = slide_on_edge(&charts, &base_tris, params, &nb[v], v) else {
                    continue;
                };
                let count = |params: &[Param]| {
                    vf[v]
                        .iter()
                        .filter(|&&f| is_bad(params, input_tris[f as usize]))
                        .count()
                };
                let now = count(params);
                let old = params[v];
                params[v] = p;
                if count(params) >= now {
                    params[v] = old;
                }
            }
        }
        let mut faces: Vec<u32> = verts
            .iter()
            .chain(&chain_verts)
            .flat_map(|&v| vf[v].iter().copied())
            .collect();
        faces.extend_from_slice(&bad_faces);
        faces.sort_unstable();
        faces.dedup();
        let cur: &[Param] = params;
        bad_faces = faces
            .par_iter()
            .copied()
            .filter(|&f| is_bad(cur, input_tris[f as usize]))
            .collect();
        after = bad_faces.len();
        tracing::debug!(
            round,
            bad = after,
            region = verts.len(),
            stuck,
            "parameter untangling"
        );
    }
    if tracing::enabled!(tracing::Level::DEBUG) {
        let at_base_vertex = bad_faces
            .iter()
            .filter(|&&f| {
                input_tris[f as usize]
                    .iter()
                    .any(|&v| params[v as usize].bary.contains(&1.0))
            })
            .count();
        let at_chain = bad_faces
            .iter()
            .filter(|&&f| {
                input_tris[f as usize].iter().any(|&v| {
                    let b = params[v as usize].bary;
                    fixed[v as usize] && !b.contains(&1.0)
                })
            })
            .count();
        tracing::debug!(
            after,
            at_base_vertex,
            at_chain,
            "folded input-triangle images left"
        );
    }
    // Faces outside the regions did not change. The base vertices that are corners of the
    // images left bad.
    let mut at_base: Vec<u32> = bad_faces
        .iter()
        .flat_map(|&f| input_tris[f as usize])
        .filter_map(|v| {
            let p = &params[v as usize];
            let k = p.bary.iter().position(|&x| x == 1.0)?;
            Some(base_tris[p.face as usize][k])
        })
        .collect();
    at_base.sort_unstable();
    at_base.dedup();
    Untangled {
        before,
        after,
        at_base,
    }
}

/// [`untangle_params`] from the tracked parameters `params`, then, where it leaves images
/// folded at base vertices of valence over six (whose parallelogram charts overlap), again
/// from the same parameters with those vertices' fans spread (`spread_fans`), keeping the
/// second result if it leaves fewer bad images. Returns what the kept untangling left and
/// the spread mask to build the [`ParamMap`] with (empty: the first was kept).
///
/// Preconditions: as [`untangle_params`].
pub fn untangle_spreading_fans(
    base: &Mesh,
    input_tris: &[[u32; 3]],
    params: &mut [Param],
    fixed: &[bool],
    rounds: u32,
) -> (Untangled, Vec<bool>) {
    let raw = params.to_vec();
    let first = untangle_params(base, input_tris, params, fixed, rounds, &[]);
    tracing::debug!(?first, "folded input-triangle images");
    let topo = Topology::build(base);
    let mut spread = vec![false; base.positions.len()];
    for &w in &first.at_base {
        spread[w as usize] = topo.vertex_faces(w as usize).len() > CLOSED_VALENCE;
    }
    if !spread.contains(&true) {
        return (first, Vec::new());
    }
    let mut again = raw;
    let second = untangle_params(base, input_tris, &mut again, fixed, rounds, &spread);
    tracing::debug!(?second, "folded input-triangle images with spread fans");
    if second.after < first.after {
        params.copy_from_slice(&again);
        (second, spread)
    } else {
        (first, Vec::new())
    }
}

/// What [`untangle_params`] left.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Untangled {
    /// Bad input triangles (images inverted, degenerate or in no chart) before.
    pub before: usize,
    /// Bad input triangles after.
    pub after: usize,
    /// Base vertices that are a corner of a bad image after, increasing.
    pub at_base: Vec<u32>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bipyramid over an `n`-gon: apices 0 (valence `n`) and 1, equator `2..2 + n`.
    fn bipyramid(n: u32) -> (Mesh, Vec<[u32; 3]>) {
        let mut pos = vec![DVec3::Z, -DVec3::Z];
        for i in 0..n {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            pos.push(DVec3::new(a.cos(), a.sin(), 0.0));
        }
        let tris: Vec<[u32; 3]> = (0..n)
            .flat_map(|i| {
                let (a, b) = (2 + i, 2 + (i + 1) % n);
                [[0, a, b], [1, b, a]]
            })
            .collect();
        (Mesh::from_triangles(pos, &tris), tris)
    }

    /// Points of `t`'s frame strictly inside two or more of the triangles around base
    /// vertex `w` as `t`'s chart places them.
    fn overlaps(chart: &[(u32, Mat)], tris: &[[u32; 3]], t: usize, w: u32) -> usize {
        let identity: Mat = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let placed: Vec<[[f64; 2]; 3]> = std::iter::once(&(t as u32, identity))
            .chain(chart)
            .filter(|(f, _)| tris[*f as usize].contains(&w))
            .map(|(_, m)| m.map(|c| [c[1], c[2]]))
            .collect();
        assert_eq!(placed.len(), 8, "the fan of the apex");
        let mut n = 0;
        for i in 0..=120 {
            for j in 0..=120 {
                let (x, y) = (-3.0 + 0.05 * i as f64, -3.0 + 0.05 * j as f64);
                let inside = placed
                    .iter()
                    .filter(|xy| bary2(**xy, x, y).iter().all(|&l| l > 1e-9))
                    .count();
                n += usize::from(inside > 1);
            }
        }
        n
    }

    /// Around a vertex of valence 8, the parallelogram unfoldings overlap (8 · 60° > 360°);
    /// spread fans close up without overlap, keep `t`'s edge neighbours where the
    /// unfolding puts them, and keep every placed triangle's orientation.
    #[test]
    fn spread_fans_close_around_high_valence_vertices() {
        let (base, tris) = bipyramid(8);
        let topo = Topology::build(&base);
        let unfolded = build_chart(&topo, &tris, 0, &[]);
        assert!(overlaps(&unfolded, &tris, 0, 0) > 0);
        let mut spread = vec![false; base.positions.len()];
        spread[0] = true;
        let fans = build_chart(&topo, &tris, 0, &spread);
        assert_eq!(overlaps(&fans, &tris, 0, 0), 0);
        assert_eq!(fans.len(), unfolded.len());
        for ((f, a), (g, b)) in unfolded.iter().zip(&fans) {
            assert_eq!(f, g);
            let edge_neighbour = tris[*f as usize]
                .iter()
                .filter(|v| tris[0].contains(v))
                .count()
                == 2;
            if edge_neighbour || !tris[*f as usize].contains(&0) {
                assert_eq!(a, b, "face {f}");
            }
            let xy = b.map(|c| [c[1], c[2]]);
            let area = (xy[1][0] - xy[0][0]) * (xy[2][1] - xy[0][1])
                - (xy[2][0] - xy[0][0]) * (xy[1][1] - xy[0][1]);
            assert!(area > 0.0, "face {f} turned over");
        }
        // No marked vertex of valence over six: the unfolded chart.
        spread[0] = false;
        spread[2] = true;
        assert_eq!(build_chart(&topo, &tris, 0, &spread), unfolded);
    }
}

//! Meshes that tests, benchmarks and the demo build themselves.
//!
//! Regular solids, spheres, tori, grids and disks; deliberately broken meshes for the error
//! paths (a bowtie, a fin, a flipped face); and the embedded default input of `subwave demo`:
//! Bertram et al.'s "five blobs" (Bertram §5.1, Fig. 13), an isosurface of a sum of Gaussians
//! obtained by subdividing a coarse base mesh and projecting every vertex onto the surface.

use glam::DVec3;

use crate::mesh::Mesh;
use crate::topology::Topology;

/// A regular tetrahedron (4 vertices, 4 outward-oriented triangles) inscribed in the unit sphere.
pub fn tetrahedron() -> Mesh {
    let s = 1.0 / 3f64.sqrt();
    let p = vec![
        DVec3::new(s, s, s),
        DVec3::new(s, -s, -s),
        DVec3::new(-s, s, -s),
        DVec3::new(-s, -s, s),
    ];
    Mesh::from_triangles(p, &[[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
}

/// The cube `[-1, 1]^3` as 6 outward-oriented quads (8 vertices).
pub fn cube() -> Mesh {
    let p = (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 != 0 { 1.0 } else { -1.0 },
                if i & 2 != 0 { 1.0 } else { -1.0 },
                if i & 4 != 0 { 1.0 } else { -1.0 },
            )
        })
        .collect();
    let faces: [[u32; 4]; 6] = [
        [0, 2, 3, 1], // z = -1
        [4, 5, 7, 6], // z = +1
        [0, 1, 5, 4], // y = -1
        [2, 6, 7, 3], // y = +1
        [0, 4, 6, 2], // x = -1
        [1, 3, 7, 5], // x = +1
    ];
    Mesh::from_faces(p, faces)
}

/// The regular icosahedron inscribed in the unit sphere (12 vertices, 20 triangles).
pub fn icosahedron() -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let raw = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let p = raw
        .iter()
        .map(|a| DVec3::from_array(*a).normalize())
        .collect();
    let f: [[u32; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    Mesh::from_triangles(p, &f)
}

/// Splits every triangle 1-to-4 at edge midpoints, following the ordering contract: old
/// vertices keep their indices, then one new vertex per edge in edge order; the children of
/// triangle `k` are `4k..4k+3` as in Maret eq. 5.7 (`v0 v3 v5 / v1 v4 v3 / v2 v5 v4 / v3 v4 v5`,
/// where `v3, v4, v5` are the midpoints of edges `v0v1, v1v2, v2v0`).
///
/// Precondition: a triangle mesh. Attributes and tags are not carried.
pub fn midpoint_split(mesh: &Mesh) -> Mesh {
    let topo = Topology::build(mesh);
    let nv = mesh.num_vertices() as u32;
    let mut positions = mesh.positions.clone();
    positions.extend(
        topo.edge_vertices
            .iter()
            .map(|&[a, b]| 0.5 * (mesh.positions[a as usize] + mesh.positions[b as usize])),
    );
    let mut tris = Vec::with_capacity(4 * mesh.num_faces());
    for f in 0..mesh.num_faces() {
        let v = topo.face_vertices(f);
        let e = topo.face_edges(f);
        let (v3, v4, v5) = (nv + e[0], nv + e[1], nv + e[2]);
        tris.push([v[0], v3, v5]);
        tris.push([v[1], v4, v3]);
        tris.push([v[2], v5, v4]);
        tris.push([v3, v4, v5]);
    }
    Mesh::from_triangles(positions, &tris)
}

/// An icosphere: the icosahedron split `levels` times with vertices on the unit sphere
/// (`10·4^levels + 2` vertices).
pub fn icosphere(levels: u32) -> Mesh {
    let mut m = icosahedron();
    for _ in 0..levels {
        m = midpoint_split(&m);
        for p in &mut m.positions {
            *p = p.normalize();
        }
    }
    m
}

/// A torus around the z axis with major radius `r_major` and minor radius `r_minor`,
/// `nu × nv` quads (`nu, nv >= 3`), or `2·nu·nv` triangles if `triangles`.
pub fn torus(r_major: f64, r_minor: f64, nu: u32, nv: u32, triangles: bool) -> Mesh {
    let (nu, nv) = (nu.max(3), nv.max(3));
    let mut p = Vec::with_capacity((nu * nv) as usize);
    for i in 0..nu {
        let u = i as f64 / nu as f64 * std::f64::consts::TAU;
        for j in 0..nv {
            let v = j as f64 / nv as f64 * std::f64::consts::TAU;
            let r = r_major + r_minor * v.cos();
            p.push(DVec3::new(r * u.cos(), r * u.sin(), r_minor * v.sin()));
        }
    }
    let id = |i: u32, j: u32| (i % nu) * nv + (j % nv);
    let mut m = Mesh {
        positions: p,
        ..Mesh::new()
    };
    for i in 0..nu {
        for j in 0..nv {
            let q = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            if triangles {
                m.push_face(&[q[0], q[1], q[2]]);
                m.push_face(&[q[0], q[2], q[3]]);
            } else {
                m.push_face(&q);
            }
        }
    }
    m
}

/// A planar `nx × ny` grid of unit quads in the z = 0 plane (open, one boundary loop), or of
/// triangles (each quad split along its diagonal) if `triangles`.
pub fn grid(nx: u32, ny: u32, triangles: bool) -> Mesh {
    let (nx, ny) = (nx.max(1), ny.max(1));
    let mut p = Vec::with_capacity(((nx + 1) * (ny + 1)) as usize);
    for j in 0..=ny {
        for i in 0..=nx {
            p.push(DVec3::new(i as f64, j as f64, 0.0));
        }
    }
    let id = |i: u32, j: u32| j * (nx + 1) + i;
    let mut m = Mesh {
        positions: p,
        ..Mesh::new()
    };
    for j in 0..ny {
        for i in 0..nx {
            let q = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            if triangles {
                m.push_face(&[q[0], q[1], q[2]]);
                m.push_face(&[q[0], q[2], q[3]]);
            } else {
                m.push_face(&q);
            }
        }
    }
    m
}

/// A regular triangle grid (every interior vertex of valence 6) of `n × n` parallelogram cells
/// in the z = 0 plane, each split into two triangles.
pub fn triangle_grid(n: u32) -> Mesh {
    let n = n.max(1);
    let mut m = grid(n, n, true);
    for p in &mut m.positions {
        *p = DVec3::new(p.x + 0.5 * p.y, p.y * 3f64.sqrt() / 2.0, 0.0);
    }
    m
}

/// An open disk: a fan of `n >= 3` triangles around a centre vertex (one boundary loop).
pub fn disk(n: u32) -> Mesh {
    let n = n.max(3);
    let mut p = vec![DVec3::ZERO];
    p.extend((0..n).map(|i| {
        let a = i as f64 / n as f64 * std::f64::consts::TAU;
        DVec3::new(a.cos(), a.sin(), 0.0)
    }));
    let tris: Vec<[u32; 3]> = (0..n).map(|i| [0, 1 + i, 1 + (i + 1) % n]).collect();
    Mesh::from_triangles(p, &tris)
}

/// A closed mixed mesh: a square pyramid (one quad base, four triangles).
pub fn pyramid() -> Mesh {
    let p = vec![
        DVec3::new(-1.0, -1.0, 0.0),
        DVec3::new(1.0, -1.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(-1.0, 1.0, 0.0),
        DVec3::new(0.0, 0.0, 1.0),
    ];
    Mesh::from_faces(
        p,
        [
            &[3u32, 2, 1, 0][..],
            &[0, 1, 4],
            &[1, 2, 4],
            &[2, 3, 4],
            &[3, 0, 4],
        ],
    )
}

/// Two triangles sharing only a vertex (a bowtie): vertex 0 is non-manifold.
pub fn bowtie() -> Mesh {
    let p = vec![
        DVec3::ZERO,
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(-1.0, 0.0, 0.0),
        DVec3::new(-1.0, -1.0, 0.0),
    ];
    Mesh::from_triangles(p, &[[0, 1, 2], [0, 3, 4]])
}

/// Three triangles sharing the edge 0–1 (a fin): the edge is non-manifold.
pub fn fin() -> Mesh {
    let p = vec![
        DVec3::ZERO,
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.5, 1.0, 0.0),
        DVec3::new(0.5, -1.0, 0.0),
        DVec3::new(0.5, 0.0, 1.0),
    ];
    Mesh::from_triangles(p, &[[0, 1, 2], [1, 0, 3], [0, 1, 4]])
}

/// The tetrahedron with its last face reversed: inconsistent orientation on three edges.
pub fn flipped_tetrahedron() -> Mesh {
    let mut m = tetrahedron();
    let n = m.face_indices.len();
    m.face_indices.swap(n - 1, n - 2);
    m
}

/// The scalar field of the five blobs: a sum of five isotropic Gaussians.
#[derive(Clone, Copy, Debug)]
pub struct Blobs {
    /// Centres of the Gaussians.
    pub centers: [DVec3; 5],
    /// Standard deviation of each Gaussian.
    pub sigma: f64,
    /// Iso-value of the surface.
    pub iso: f64,
}

impl Default for Blobs {
    fn default() -> Self {
        Blobs {
            centers: [
                DVec3::new(0.0, 0.0, 0.35),
                DVec3::new(0.85, 0.0, -0.1),
                DVec3::new(-0.45, 0.75, -0.1),
                DVec3::new(-0.45, -0.75, -0.1),
                DVec3::new(0.0, 0.0, -0.75),
            ],
            sigma: 0.42,
            iso: 0.5,
        }
    }
}

impl Blobs {
    /// Field value and gradient at `p`.
    pub fn eval(&self, p: DVec3) -> (f64, DVec3) {
        let k = 1.0 / (2.0 * self.sigma * self.sigma);
        let mut f = 0.0;
        let mut g = DVec3::ZERO;
        for c in &self.centers {
            let d = p - *c;
            let w = (-k * d.length_squared()).exp();
            f += w;
            g += -2.0 * k * w * d;
        }
        (f, g)
    }

    /// Projects `p` onto the isosurface along the ray from the origin through `p` (the
    /// outermost crossing, found by marching and bisection), then polishes with Newton steps
    /// along the gradient (Bertram §5.1). Returns `p` unchanged if the ray misses the surface.
    pub fn project(&self, p: DVec3) -> DVec3 {
        let dir = p.normalize_or_zero();
        if dir == DVec3::ZERO {
            return p;
        }
        let r_max = 4.0;
        let steps = 200;
        let mut outside = r_max;
        let mut inside = None;
        for s in (0..steps).rev() {
            let r = r_max * s as f64 / steps as f64;
            if self.eval(dir * r).0 >= self.iso {
                inside = Some(r);
                break;
            }
            outside = r;
        }
        let Some(mut lo) = inside else { return p };
        let mut hi = outside;
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if self.eval(dir * mid).0 >= self.iso {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let mut q = dir * (0.5 * (lo + hi));
        for _ in 0..3 {
            let (f, g) = self.eval(q);
            let gg = g.length_squared();
            if gg < 1e-300 {
                break;
            }
            let step = (f - self.iso) / gg * g;
            if step.length() > 1e-3 {
                break;
            }
            q -= step;
        }
        q
    }
}

/// Bertram et al.'s "five blobs" (Bertram §5.1): an icosahedron subdivided `levels` times by
/// midpoint splitting, every vertex projected onto the isosurface of [`Blobs::default`] after
/// each step. The result has subdivision connectivity over the 20-triangle base mesh, in the
/// plain-subdivision vertex and face order (`10·4^levels + 2` vertices).
pub fn five_blobs(levels: u32) -> Mesh {
    let blobs = Blobs::default();
    let mut m = icosahedron();
    for p in &mut m.positions {
        *p = blobs.project(*p);
    }
    for _ in 0..levels {
        m = midpoint_split(&m);
        for p in &mut m.positions {
            *p = blobs.project(*p);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validate::report;

    fn rep(m: &Mesh) -> crate::validate::MeshReport {
        m.check_indices().unwrap();
        report(m, &Topology::build(m))
    }

    #[test]
    fn closed_solids() {
        for (m, v, e, f, g) in [
            (tetrahedron(), 4, 6, 4, 0),
            (cube(), 8, 12, 6, 0),
            (icosahedron(), 12, 30, 20, 0),
            (icosphere(2), 162, 480, 320, 0),
            (torus(1.0, 0.3, 8, 6, false), 48, 96, 48, 1),
            (torus(1.0, 0.3, 8, 6, true), 48, 144, 96, 1),
            (pyramid(), 5, 8, 5, 0),
            (five_blobs(2), 162, 480, 320, 0),
        ] {
            let r = rep(&m);
            assert_eq!((r.vertices, r.edges, r.faces), (v, e, f));
            assert_eq!(r.boundary_edges, 0);
            assert_eq!(r.genus, Some(g));
            assert_eq!(r.components, 1);
            assert_eq!(r.euler_characteristic, 2 - 2 * g as i64);
            assert_eq!(r.inconsistent_orientation_edges, 0);
        }
    }

    #[test]
    fn outward_orientation() {
        for m in [
            tetrahedron(),
            cube(),
            icosahedron(),
            pyramid(),
            five_blobs(1),
        ] {
            let n = m.vertex_normals();
            let c = m.positions.iter().sum::<DVec3>() / m.num_vertices() as f64;
            let out = m
                .positions
                .iter()
                .zip(&n)
                .filter(|(p, n)| (**p - c).dot(**n) > 0.0)
                .count();
            assert_eq!(out, m.num_vertices());
        }
    }

    #[test]
    fn open_meshes() {
        let r = rep(&grid(3, 2, false));
        assert_eq!(
            (
                r.vertices,
                r.faces,
                r.edges,
                r.boundary_edges,
                r.boundary_loops
            ),
            (12, 6, 17, 10, 1)
        );
        assert_eq!(r.genus, Some(0));
        let r = rep(&disk(6));
        assert_eq!(
            (r.boundary_edges, r.boundary_loops, r.euler_characteristic),
            (6, 1, 1)
        );
        let r = rep(&triangle_grid(4));
        assert_eq!(r.valence_histogram.get(&6), Some(&9));
    }

    #[test]
    fn broken_meshes() {
        let r = rep(&bowtie());
        assert_eq!(
            (r.non_manifold_vertices, r.non_manifold_edges, r.components),
            (1, 0, 1)
        );
        let r = rep(&fin());
        assert_eq!((r.non_manifold_vertices, r.non_manifold_edges), (0, 1));
        let r = rep(&flipped_tetrahedron());
        assert_eq!(r.inconsistent_orientation_edges, 3);
        assert_eq!(r.genus, None);
    }

    #[test]
    fn five_blobs_on_isosurface() {
        let b = Blobs::default();
        let m = five_blobs(3);
        for p in &m.positions {
            assert!((b.eval(*p).0 - b.iso).abs() < 1e-9);
        }
        // No folded triangles: every face normal points away from the origin.
        for f in m.faces() {
            let (a, bb, c) = (
                m.positions[f[0] as usize],
                m.positions[f[1] as usize],
                m.positions[f[2] as usize],
            );
            assert!((bb - a).cross(c - a).dot(a + bb + c) > 0.0);
        }
    }
}

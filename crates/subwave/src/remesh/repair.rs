//! Input preparation for remeshing: triangulation, removal of unreferenced vertices and
//! degenerate faces, and the repair of non-manifold edges and vertices.
//!
//! Maret 2003 §2.3 (Algorithm 4) defines the 2-manifold the subdivision and wavelet layers
//! need: every edge on one or two consistently oriented faces, the faces around every vertex
//! one fan. A remesher (Lee et al. 1998, MAPS §2) starts from such a mesh. [`prepare`] with `repair` set makes one
//! by *cutting*: faces are glued to each other only across edges that are on exactly two
//! faces, after orienting each glued component consistently (breadth-first, flipping faces
//! as Maret §2.3.1's orientation test requires); every vertex is then split into one copy per
//! fan of the faces glued around it. Non-manifold edges thus become boundary edges of each
//! sheet, pinched vertices become several vertices, and non-orientable gluings are cut.
//!
//! Before that, the repair closes *duplicated seams*: a boundary edge whose two ends lie
//! exactly where the ends of another boundary edge lie (a model tessellated patch by patch,
//! as Newell's teapot, stores each patch's rim apart) is glued to it by welding the
//! coincident ends ([`weld_seams`]). Only edges are matched, so parts that merely touch at a
//! vertex stay apart; a weld that makes an edge non-manifold (three coincident rims) is cut
//! again by the repair above.
//!
//! After the weld, it stitches *slits* ([`super::stitch::stitch_slits`]): a boundary edge
//! is split at the T-junction vertices of another boundary chain lying a hair away, where
//! every new piece then meets a boundary edge traversed the other way (the crack closes).
//!
//! After the weld and before the cut, it drops *pocket lids* ([`pocket_lids`]): a
//! triangle each of whose edges is on exactly three faces, on one side of which a small
//! patch of faces closes a pocket over the same three edges while a larger surface goes on
//! on the other. Modellers glue a part (a mirror, a headlight) onto a body by adding its
//! sides over a triangle of the body and leaving that triangle in place; it is then inside
//! the solid, and cutting its edges would leave three sheets meeting there, which the
//! remesher folds (the beetle has nine such lids).

use std::collections::VecDeque;

use glam::DVec3;

use super::stitch::SLIT_TOLERANCE;
use crate::mesh::Mesh;
use crate::topology::{Topology, UnionFind};
use crate::validate::require_manifold;
pub use crate::validate::weld_seams;
use crate::{MeshError, Result};

/// What [`prepare`] changed in the input.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct RepairReport {
    /// Faces removed because they repeat a vertex or have (nearly) zero area.
    pub degenerate_faces: usize,
    /// Faces removed because an earlier face has the same three vertices (in either
    /// orientation).
    pub duplicate_faces: usize,
    /// Vertices no face used (dropped).
    pub unreferenced_vertices: usize,
    /// Non-manifold edges cut (only with repair).
    pub non_manifold_edges: usize,
    /// Non-manifold vertices split (only with repair).
    pub non_manifold_vertices: usize,
    /// Faces flipped to make orientations consistent (only with repair).
    pub flipped_faces: usize,
    /// Vertices added by splitting.
    pub added_vertices: usize,
    /// Vertices welded into a coincident one to close duplicated seams (only with repair).
    pub welded_vertices: usize,
    /// Faces removed as the lids of pockets glued onto the surface (only with repair,
    /// [`pocket_lids`]).
    pub lid_faces: usize,
    /// T-vertices at which boundary edges were split to close slits between boundary
    /// chains (only with repair, [`super::stitch::stitch_slits`]).
    pub stitched_vertices: usize,
    /// Without repair: vertices that the repair would weld (the ends of boundary edges that
    /// coincide with other boundary edges), left apart; 0 with repair.
    pub seam_vertices: usize,
}

impl RepairReport {
    /// What the manifold repair changed in the surface (cut edges, split vertices, flipped
    /// faces), as one clause for a warning; `None` if it changed nothing. Removed degenerate
    /// and duplicate faces and dropped vertices are not part of it ([`RepairReport::warnings`]
    /// lists them apart: they are removed with or without repair).
    pub fn repair_summary(&self) -> Option<String> {
        let s = counted(&[
            (
                self.welded_vertices,
                "welded",
                "vertex(es) into coincident ones to close duplicated seams",
            ),
            (
                self.stitched_vertices,
                "stitched",
                "T-junction(s) closing slits between boundaries",
            ),
            (
                self.lid_faces,
                "removed",
                "face(s) closing a pocket glued onto the surface along their edges (inside the solid)",
            ),
            (
                self.non_manifold_edges,
                "cut",
                "non-manifold edge(s) into boundary edges",
            ),
            (
                self.non_manifold_vertices,
                "split",
                "non-manifold vertex(es)",
            ),
            (
                self.flipped_faces,
                "flipped",
                "face(s) to orient their component consistently",
            ),
        ])
        .join(", ");
        if s.is_empty() {
            None
        } else if self.added_vertices > 0 {
            Some(format!("{s}; {} vertices added", self.added_vertices))
        } else {
            Some(s)
        }
    }

    /// One warning per kind of change to the input (the remesher's report): degenerate and
    /// duplicate faces removed, vertices on no kept face dropped, then the repair
    /// ([`RepairReport::repair_summary`]), or without repair the duplicated seams it would
    /// have closed.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = counted(&[
            (
                self.degenerate_faces,
                "removed",
                "degenerate face(s) (a repeated vertex or zero area)",
            ),
            (
                self.duplicate_faces,
                "removed",
                "duplicate face(s) (the three vertices of an earlier face)",
            ),
            (
                self.unreferenced_vertices,
                "dropped",
                "vertex(es) that no kept face uses (a remesh samples the surface only)",
            ),
        ]);
        w.extend(
            self.repair_summary()
                .map(|s| format!("repaired the input into a manifold: {s}")),
        );
        if self.seam_vertices > 0 {
            w.push(format!(
                "{} vertex(es) end boundary edges that coincide with other boundary edges \
                 (duplicated seams, kept open as boundaries): --repair welds them",
                self.seam_vertices
            ));
        }
        w
    }
}

/// `"{verb} {n} {what}"` for each entry with a positive count.
fn counted(entries: &[(usize, &str, &str)]) -> Vec<String> {
    entries
        .iter()
        .filter(|e| e.0 > 0)
        .map(|(n, verb, what)| format!("{verb} {n} {what}"))
        .collect()
}

/// The triangles of `mesh` ready for remeshing: polygons fanned (a quad along a diagonal
/// that is not already an edge), degenerate triangles (a repeated vertex, area below
/// `1e-14 · diagonal²`, or the vertex set of an earlier triangle) and unreferenced vertices
/// removed and, if `repair`, duplicated seams welded, slits stitched, pocket lids removed and
/// non-manifold edges and vertices cut (see the module documentation).
///
/// Returns the positions, the triangles and the report.
///
/// # Errors
/// [`MeshError`] variants of [`Mesh::check_indices`] for bad indices;
/// [`MeshError::NonManifold`] naming the non-manifold edges and vertices (and
/// [`MeshError::InconsistentOrientation`]) when `repair` is false and the input is not an
/// oriented 2-manifold.
pub fn prepare(mesh: &Mesh, repair: bool) -> Result<(Vec<DVec3>, Vec<[u32; 3]>, RepairReport)> {
    check_indices_allow_repeats(mesh)?;
    let mut report = RepairReport::default();
    let diag = mesh.diagonal();
    let min_area2 = (1e-14 * diag * diag).powi(2);
    let tris = triangulate(mesh);
    let mut kept = Vec::with_capacity(tris.len());
    let mut seen = std::collections::HashSet::with_capacity(tris.len());
    for t in tris {
        // A second face on the same three vertices (either orientation) is degenerate too.
        let mut sorted = t;
        sorted.sort_unstable();
        if !seen.insert(sorted) {
            report.duplicate_faces += 1;
            continue;
        }
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let degenerate = t[0] == t[1]
            || t[1] == t[2]
            || t[0] == t[2]
            || (b - a).cross(c - a).length_squared() * 0.25 <= min_area2;
        if degenerate {
            report.degenerate_faces += 1;
        } else {
            kept.push(t);
        }
    }
    // Duplicated seams: welded with repair (faces that then repeat a kept one are dropped as
    // duplicates), reported without.
    let (root, seam_vertices) = weld_seams(&mesh.positions, &kept);
    if seam_vertices > 0 && repair {
        report.welded_vertices = seam_vertices;
        seen.clear();
        kept.retain_mut(|t| {
            *t = t.map(|i| root[i as usize]);
            let mut sorted = *t;
            sorted.sort_unstable();
            let fresh = seen.insert(sorted);
            if !fresh {
                report.duplicate_faces += 1;
            }
            fresh
        });
    } else {
        report.seam_vertices = seam_vertices;
    }
    // Slits between boundary chains, with T-junctions: closed with repair.
    if repair {
        let (stitched, inserted) =
            super::stitch::stitch_slits(&mesh.positions, &kept, SLIT_TOLERANCE * diag);
        if inserted > 0 {
            report.stitched_vertices = inserted;
            kept = stitched;
        }
    }
    // Drop unreferenced vertices.
    let mut map = vec![u32::MAX; mesh.positions.len()];
    let mut positions = Vec::new();
    let mut original = Vec::new();
    for t in &mut kept {
        for i in t.iter_mut() {
            if map[*i as usize] == u32::MAX {
                map[*i as usize] = positions.len() as u32;
                positions.push(mesh.positions[*i as usize]);
                original.push(*i);
            }
            *i = map[*i as usize];
        }
    }
    // Welded vertices are on no face now; they are counted apart.
    report.unreferenced_vertices = mesh.positions.len() - positions.len() - report.welded_vertices;
    let mut m = Mesh::from_triangles(positions, &kept);
    let mut topo = Topology::build(&m);
    let mut nm_edges = topo.non_manifold_edges();
    if repair && !nm_edges.is_empty() {
        let lids = pocket_lids(&topo);
        if !lids.is_empty() {
            // A lid's vertices stay on the faces around its edges: none becomes unreferenced.
            report.lid_faces = lids.len();
            let mut f = 0;
            kept.retain(|_| {
                f += 1;
                lids.binary_search(&(f as u32 - 1)).is_err()
            });
            m = Mesh::from_triangles(std::mem::take(&mut m.positions), &kept);
            topo = Topology::build(&m);
            nm_edges = topo.non_manifold_edges();
        }
    }
    let nm_vertices = topo.non_manifold_vertices();
    if !repair {
        if !nm_edges.is_empty() || !nm_vertices.is_empty() {
            return Err(MeshError::NonManifold {
                // Named in the input's numbering.
                edges: nm_edges
                    .iter()
                    .map(|&e| topo.edge_vertices[e as usize].map(|v| original[v as usize]))
                    .collect(),
                vertices: nm_vertices.iter().map(|&v| original[v as usize]).collect(),
            }
            .into());
        }
        require_manifold(&topo)?;
        let Mesh { positions, .. } = m;
        return Ok((positions, kept, report));
    }
    report.non_manifold_edges = nm_edges.len();
    report.non_manifold_vertices = nm_vertices.len();
    let (positions, tris, flipped, added) = cut_to_manifold(&m.positions, &kept, &topo);
    report.flipped_faces = flipped;
    report.added_vertices = added;
    Ok((positions, tris, report))
}

/// Largest pocket (in faces) whose lid [`pocket_lids`] removes, and the number of
/// faces the surface on the lid's other side must exceed: a part glued onto a body is a
/// few faces (the beetle's are 3 or 1).
pub const MAX_POCKET_FACES: usize = 64;

/// The *lids of pockets* among the faces of `topo` (sorted face indices): a triangle `t`
/// each of whose three edges is on exactly three faces (not counting lids found before),
/// such that
/// - a patch of at most [`MAX_POCKET_FACES`] other triangles, connected across edges on two
///   triangles, is bounded by exactly `t`'s three edges (the pocket: with `t` a closed
///   surface), and
/// - the third triangle on each edge belongs to a surface that reaches more than
///   [`MAX_POCKET_FACES`] triangles across edges on two triangles (the body the pocket is
///   glued onto; fins standing on `t`'s edges, or a small body, keep `t`, and their edges
///   are cut as any non-manifold edge).
///
/// Without `t` each of its edges is on two faces, and the pocket's sides continue the
/// body's surface. Faces are tested in index order, each test seeing the lids found before
/// it as removed.
///
/// Preconditions: `topo` is of triangles, none repeating a vertex and no two on the same
/// vertex set (as [`prepare`] makes them).
pub fn pocket_lids(topo: &Topology) -> Vec<u32> {
    let mut g = Gluing {
        topo,
        removed: vec![false; topo.num_faces()],
        live: (0..topo.num_edges())
            .map(|e| topo.edge_faces(e).len() as u32)
            .collect(),
    };
    let mut lids = Vec::new();
    for t in 0..topo.num_faces() {
        let te = topo.face_edges(t);
        if te.len() != 3 || te.iter().any(|&e| g.live[e as usize] != 3) {
            continue;
        }
        let mut tb = te.to_vec();
        tb.sort_unstable();
        // The pocket: grown from a face on t's first edge. The body: the other face there.
        let others: Vec<usize> = topo
            .edge_faces(te[0] as usize)
            .iter()
            .map(|&f| f as usize)
            .filter(|&f| f != t && !g.removed[f])
            .collect();
        debug_assert_eq!(others.len(), 2, "three live faces on the edge");
        let is_lid = (0..2).any(|i| {
            let (pocket, body) = (others[i], others[1 - i]);
            match g.patch(pocket, MAX_POCKET_FACES) {
                Patch::Closed { faces, border } if border == tb && !faces.contains(&body) => {
                    matches!(g.patch(body, MAX_POCKET_FACES), Patch::Large)
                }
                _ => false,
            }
        });
        if is_lid {
            g.removed[t] = true;
            for &e in te {
                g.live[e as usize] -= 1;
            }
            lids.push(t as u32);
        }
    }
    lids
}

/// The faces of [`pocket_lids`]'s topology, with the lids found so far removed.
struct Gluing<'a> {
    topo: &'a Topology,
    removed: Vec<bool>,
    /// Faces left on each edge.
    live: Vec<u32>,
}

/// What a patch grown across edges on two faces is ([`Gluing::patch`]).
enum Patch {
    /// It stops within the limit at edges on three or more faces, each reached once
    /// (`border`, sorted).
    Closed { faces: Vec<usize>, border: Vec<u32> },
    /// It stops within the limit, but at a boundary edge (one face) or at an edge on three
    /// or more faces reached twice.
    Open,
    /// It has more faces than the limit.
    Large,
}

impl Gluing<'_> {
    /// The patch grown breadth-first from face `seed` across edges on two live faces, up to
    /// `limit` faces.
    fn patch(&self, seed: usize, limit: usize) -> Patch {
        let mut faces = vec![seed];
        let mut border = Vec::new();
        let mut open = false;
        let mut i = 0;
        while i < faces.len() {
            let f = faces[i];
            i += 1;
            for &e in self.topo.face_edges(f) {
                match self.live[e as usize] {
                    0 | 1 => open = true,
                    2 => {
                        for &h in self.topo.edge_faces(e as usize) {
                            let h = h as usize;
                            if h != f && !self.removed[h] && !faces.contains(&h) {
                                if faces.len() == limit {
                                    return Patch::Large;
                                }
                                faces.push(h);
                            }
                        }
                    }
                    _ => border.push(e),
                }
            }
        }
        border.sort_unstable();
        let n = border.len();
        border.dedup();
        if !open && border.len() == n {
            Patch::Closed { faces, border }
        } else {
            // A boundary edge, or an edge reached twice: not a disc bounded by single edges.
            Patch::Open
        }
    }
}

/// The triangles of `mesh`'s faces: polygons fanned from their first corner, except that a
/// quad whose diagonal from its first corner is already an edge of the mesh (or another
/// quad's diagonal) is split along its other diagonal. Fanning such a quad makes that edge
/// non-manifold: Suzanne's two quads `(70 196 138 137)` and `(70 137 138 197)` around the
/// valence-2 vertex 137 both fanned into triangle `70 138 137`.
fn triangulate(mesh: &Mesh) -> Vec<[u32; 3]> {
    if mesh.faces().all(|fv| fv.len() == 3) {
        return mesh.triangulate().0;
    }
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let mut edges: std::collections::HashSet<(u32, u32)> = std::collections::HashSet::new();
    for fv in mesh.faces() {
        for i in 0..fv.len() {
            edges.insert(key(fv[i], fv[(i + 1) % fv.len()]));
        }
    }
    let mut tris = Vec::with_capacity(mesh.face_indices.len());
    for fv in mesh.faces() {
        if fv.len() == 4 {
            let d02 = key(fv[0], fv[2]);
            let d13 = key(fv[1], fv[3]);
            if edges.contains(&d02) && !edges.contains(&d13) {
                edges.insert(d13);
                tris.push([fv[0], fv[1], fv[3]]);
                tris.push([fv[1], fv[2], fv[3]]);
                continue;
            }
            edges.insert(d02);
        }
        for i in 1..fv.len().saturating_sub(1) {
            tris.push([fv[0], fv[i], fv[i + 1]]);
        }
    }
    tris
}

/// Like [`Mesh::check_indices`] but lets faces repeat a vertex (they are removed as
/// degenerate).
fn check_indices_allow_repeats(mesh: &Mesh) -> Result<()> {
    match mesh.check_indices() {
        Err(MeshError::RepeatedVertex { .. }) => {
            let n = mesh.positions.len();
            for (f, fv) in mesh.faces().enumerate() {
                if fv.len() < 3 {
                    return Err(MeshError::FaceTooSmall {
                        face: f as u32,
                        arity: fv.len(),
                    }
                    .into());
                }
                if let Some(&index) = fv.iter().find(|&&i| i as usize >= n) {
                    return Err(MeshError::IndexOutOfRange {
                        face: f as u32,
                        index,
                        vertices: n,
                    }
                    .into());
                }
            }
            if let Some(v) = mesh.positions.iter().position(|p| !p.is_finite()) {
                return Err(MeshError::NonFinite { vertex: v as u32 }.into());
            }
            Ok(())
        }
        r => Ok(r?),
    }
}

/// Orients each component through its two-face edges, cuts every other edge, and splits
/// vertices per fan. Returns positions, triangles, flipped face count, added vertex count.
fn cut_to_manifold(
    positions: &[DVec3],
    tris: &[[u32; 3]],
    topo: &Topology,
) -> (Vec<DVec3>, Vec<[u32; 3]>, usize, usize) {
    let nf = tris.len();
    let mut out: Vec<[u32; 3]> = tris.to_vec();
    let mut visited = vec![false; nf];
    let mut flipped = 0;
    // Orientation by breadth-first propagation across two-face edges.
    let directed = |t: &[u32; 3], a: u32, b: u32| (0..3).any(|i| t[i] == a && t[(i + 1) % 3] == b);
    let mut queue = VecDeque::new();
    for seed in 0..nf {
        if visited[seed] {
            continue;
        }
        visited[seed] = true;
        queue.push_back(seed);
        while let Some(f) = queue.pop_front() {
            for &e in topo.face_edges(f) {
                let ef = topo.edge_faces(e as usize);
                if ef.len() != 2 {
                    continue;
                }
                let g = if ef[0] as usize == f { ef[1] } else { ef[0] } as usize;
                if g == f || visited[g] {
                    continue;
                }
                visited[g] = true;
                let [a, b] = topo.edge_vertices[e as usize];
                // Consistent: f and g traverse the edge in opposite directions.
                let f_ab = directed(&out[f], a, b);
                let g_ab = directed(&out[g], a, b);
                if f_ab == g_ab {
                    out[g].swap(1, 2);
                    flipped += 1;
                }
                queue.push_back(g);
            }
        }
    }
    // Glue corners across consistent two-face edges.
    let mut uf = UnionFind::new(3 * nf);
    let corner = |f: usize, v: u32, out: &[[u32; 3]]| -> u32 {
        let i = out[f].iter().position(|&x| x == v).expect("vertex of face");
        (3 * f + i) as u32
    };
    for e in 0..topo.num_edges() {
        let ef = topo.edge_faces(e);
        if ef.len() != 2 || ef[0] == ef[1] {
            continue;
        }
        let (f, g) = (ef[0] as usize, ef[1] as usize);
        let [a, b] = topo.edge_vertices[e];
        if directed(&out[f], a, b) == directed(&out[g], a, b) {
            continue; // non-orientable gluing: cut
        }
        uf.union(corner(f, a, &out), corner(g, a, &out));
        uf.union(corner(f, b, &out), corner(g, b, &out));
    }
    // One new vertex per (original vertex, corner class).
    let mut class_vertex = vec![u32::MAX; 3 * nf];
    let mut new_positions = Vec::with_capacity(positions.len());
    let mut used_original = vec![false; positions.len()];
    let mut added = 0;
    let mut result = vec![[0u32; 3]; nf];
    for f in 0..nf {
        for i in 0..3 {
            let root = uf.find((3 * f + i) as u32) as usize;
            if class_vertex[root] == u32::MAX {
                let v = out[f][i] as usize;
                class_vertex[root] = new_positions.len() as u32;
                new_positions.push(positions[v]);
                if used_original[v] {
                    added += 1;
                }
                used_original[v] = true;
            }
            result[f][i] = class_vertex[root];
        }
    }
    (new_positions, result, flipped, added)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate;

    #[test]
    fn bowtie_is_rejected_then_split() {
        let m = generate::bowtie();
        let err = prepare(&m, false).unwrap_err().to_string();
        assert!(err.contains("non-manifold"), "{err}");
        let (p, t, r) = prepare(&m, true).unwrap();
        let fixed = Mesh::from_triangles(p, &t);
        let topo = Topology::build(&fixed);
        assert!(require_manifold(&topo).is_ok());
        assert_eq!(r.added_vertices, 1);
        assert_eq!(r.non_manifold_vertices, 1);
    }

    #[test]
    fn fin_edge_is_cut() {
        let m = generate::fin();
        let err = prepare(&m, false).unwrap_err().to_string();
        assert!(err.contains("edge"), "{err}");
        let (p, t, r) = prepare(&m, true).unwrap();
        let topo = Topology::build(&Mesh::from_triangles(p, &t));
        assert!(require_manifold(&topo).is_ok());
        assert_eq!(r.non_manifold_edges, 1);
    }

    #[test]
    fn degenerate_faces_are_dropped() {
        let mut m = generate::icosahedron();
        let n = m.num_faces();
        m.positions.push(m.positions[0]);
        let extra = (m.positions.len() - 1) as u32;
        m.push_face(&[0, 1, 0]);
        m.push_face(&[0, extra, 1]);
        // A face on the vertices of an earlier one, reversed: a duplicate.
        let f0 = m.face(0).to_vec();
        m.push_face(&[f0[2], f0[1], f0[0]]);
        let (p, t, r) = prepare(&m, false).unwrap();
        assert_eq!(t.len(), n);
        assert_eq!((r.degenerate_faces, r.duplicate_faces), (2, 1));
        assert_eq!(r.unreferenced_vertices, 1);
        assert_eq!(p.len(), 12);
        assert_eq!(r.repair_summary(), None, "nothing cut, split or flipped");
        assert_eq!(
            r.warnings(),
            [
                "removed 2 degenerate face(s) (a repeated vertex or zero area)",
                "removed 1 duplicate face(s) (the three vertices of an earlier face)",
                "dropped 1 vertex(es) that no kept face uses (a remesh samples the surface only)",
            ]
        );
    }

    fn boundary_edges(topo: &Topology) -> usize {
        (0..topo.num_edges())
            .filter(|&e| topo.is_boundary_edge(e))
            .count()
    }

    /// Two squares stored apart along a shared side (a duplicated seam) are welded into one
    /// sheet with repair and reported without; parts touching at one point stay apart.
    #[test]
    fn duplicated_seams_are_welded() {
        let p = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        // Left square 0 1 2 3, right square 4 5 6 7 whose left side (4, 7) lies on (1, 2);
        // the right square's corner 6 also touches a third triangle's corner 8 at a point.
        let positions = vec![
            p(0.0, 0.0),
            p(1.0, 0.0),
            p(1.0, 1.0),
            p(0.0, 1.0),
            p(1.0, 0.0),
            p(2.0, 0.0),
            p(2.0, 1.0),
            p(1.0, 1.0),
            p(2.0, 1.0),
            p(3.0, 1.0),
            p(3.0, 2.0),
        ];
        let faces = vec![
            vec![0, 1, 2],
            vec![0, 2, 3],
            vec![4, 5, 6],
            vec![4, 6, 7],
            vec![8, 9, 10],
        ];
        let m = Mesh::from_faces(positions, faces);
        let (pos, tris, r) = prepare(&m, false).unwrap();
        assert_eq!((pos.len(), r.seam_vertices, r.welded_vertices), (11, 2, 0));
        assert!(
            r.warnings()
                .iter()
                .any(|w| w.starts_with("2 vertex(es) end boundary edges")
                    && w.ends_with("--repair welds them")),
            "{:?}",
            r.warnings()
        );
        let topo = Topology::build(&Mesh::from_triangles(pos, &tris));
        assert_eq!(boundary_edges(&topo), 11);
        let (pos, tris, r) = prepare(&m, true).unwrap();
        assert_eq!((pos.len(), r.seam_vertices, r.welded_vertices), (9, 0, 2));
        assert_eq!(r.unreferenced_vertices, 0);
        assert_eq!(r.added_vertices, 0, "the touching corner is not welded");
        let topo = Topology::build(&Mesh::from_triangles(pos, &tris));
        assert!(require_manifold(&topo).is_ok());
        assert_eq!(boundary_edges(&topo), 9, "the seam is an interior edge");
        assert_eq!(
            r.repair_summary().as_deref(),
            Some("welded 2 vertex(es) into coincident ones to close duplicated seams")
        );
        // -0.0 and 0.0 are the same place.
        let mut m2 = m.clone();
        m2.positions[4].y = -0.0;
        assert_eq!(weld_seams(&m2.positions, &m2.triangulate().0).1, 2);
    }

    /// A sphere of `levels` midpoint splits of the icosahedron with a pyramid glued onto
    /// face 0 whose base (face 0) was left in place, its sides traversing the base's edges
    /// as face 0 does (`reversed`: the other way); `fins`: instead of the pyramid, a single
    /// triangle on each edge of face 0.
    fn glued_pocket(levels: u32, reversed: bool, fins: bool) -> Mesh {
        let mut m = generate::icosphere(levels);
        let [a, b, c]: [u32; 3] = m.face(0).try_into().unwrap();
        let [pa, pb, pc] = [a, b, c].map(|v| m.positions[v as usize]);
        let n = (pb - pa).cross(pc - pa).normalize();
        let centre = (pa + pb + pc) / 3.0;
        let edges = [(a, b), (b, c), (c, a)];
        for (i, &(u, w)) in edges.iter().enumerate() {
            let apex = if fins {
                // A fin standing on its edge, leaning away from face 0.
                let mid = (m.positions[u as usize] + m.positions[w as usize]) / 2.0;
                mid + 0.3 * n + 0.2 * (mid - centre) + 0.01 * i as f64 * DVec3::X
            } else {
                centre + 0.2 * n
            };
            let k = if fins || i == 0 {
                m.positions.push(apex);
                (m.positions.len() - 1) as u32
            } else {
                (m.positions.len() - 1) as u32
            };
            if reversed {
                m.push_face(&[w, u, k]);
            } else {
                m.push_face(&[u, w, k]);
            }
        }
        m
    }

    /// A pocket's lid (a face whose three edges each carry the pocket's side and the body)
    /// is removed, so nothing is cut; with the sides the other way round they are flipped
    /// too. Three fins on a face's edges close no pocket, and on a body of fewer than
    /// `MAX_POCKET_FACES` faces the pocket is not told from the body: the edges are cut.
    #[test]
    fn pocket_lids_are_removed() {
        for reversed in [false, true] {
            let m = glued_pocket(2, reversed, false);
            assert_eq!(Topology::build(&m).non_manifold_edges().len(), 3);
            let (p, t, r) = prepare(&m, true).unwrap();
            assert_eq!(r.lid_faces, 1, "reversed {reversed}");
            assert_eq!(t.len(), 322);
            assert_eq!((r.non_manifold_edges, r.added_vertices), (0, 0));
            assert_eq!(r.flipped_faces, if reversed { 3 } else { 0 });
            let out = Mesh::from_triangles(p, &t);
            let topo = Topology::build(&out);
            assert!(require_manifold(&topo).is_ok());
            assert_eq!(boundary_edges(&topo), 0, "a closed surface");
            assert!(r
                .repair_summary()
                .unwrap()
                .starts_with("removed 1 face(s) closing a pocket glued onto the surface"));
            // Without repair, the lid's edges are named as non-manifold.
            assert!(prepare(&m, false).is_err());
        }
        for (levels, fins, faces) in [(2, true, 323), (0, true, 23), (0, false, 23)] {
            let m = glued_pocket(levels, false, fins);
            let (p, t, r) = prepare(&m, true).unwrap();
            assert_eq!(
                (r.lid_faces, r.non_manifold_edges, t.len()),
                (0, 3, faces),
                "levels {levels} fins {fins}"
            );
            assert!(require_manifold(&Topology::build(&Mesh::from_triangles(p, &t))).is_ok());
        }
        let m = glued_pocket(2, false, false);
        assert_eq!(pocket_lids(&Topology::build(&m)), [0]);
        let (p, t, _) = prepare(&m, true).unwrap();
        let repaired = Topology::build(&Mesh::from_triangles(p, &t));
        assert!(pocket_lids(&repaired).is_empty(), "nothing left to remove");
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]

        /// A glued pocket with random triangles added among the vertices around its lid
        /// (more pockets, fins, lids over lids), and random soups over few vertices: the
        /// repair never panics and always ends with an oriented 2-manifold, and each lid it
        /// removes turns exactly its three edges manifold.
        #[test]
        fn repair_of_random_gluings_is_manifold(
            extra in proptest::collection::vec([0usize..16, 0usize..16, 0usize..16], 0..24),
            reversed in proptest::bool::ANY,
            soup in proptest::bool::ANY,
        ) {
            let mut m = if soup {
                let p = (0..16).map(|i| DVec3::new(i as f64, (i * i % 7) as f64, (i % 3) as f64));
                Mesh::from_faces(p.collect(), Vec::<Vec<u32>>::new())
            } else {
                glued_pocket(2, reversed, false)
            };
            // The vertices of the first faces (the lid's among them) and the apex.
            let mut around: Vec<u32> = Vec::new();
            for f in 0..m.num_faces() {
                for &v in m.face(f) {
                    if !around.contains(&v) && around.len() < 15 {
                        around.push(v);
                    }
                }
            }
            around.push((m.positions.len() - 1) as u32);
            if soup {
                around = (0..16).collect();
            }
            for t in &extra {
                let [a, b, c] = t.map(|i| around[i.min(around.len() - 1)]);
                m.push_face(&[a, b, c]);
            }
            if m.num_faces() == 0 {
                return Ok(());
            }
            let (p, t, r) = prepare(&m, true).unwrap();
            if !t.is_empty() {
                let topo = Topology::build(&Mesh::from_triangles(p, &t));
                proptest::prop_assert!(require_manifold(&topo).is_ok(), "{:?}", r);
            }
            let mut kept: Vec<[u32; 3]> = Vec::new();
            let mut seen = std::collections::HashSet::new();
            for t in m.triangulate().0 {
                let mut s = t;
                s.sort_unstable();
                if s[0] != s[1] && s[1] != s[2] && seen.insert(s) {
                    kept.push(t);
                }
            }
            let nm = |tris: &[[u32; 3]]| {
                let mut count = std::collections::HashMap::new();
                for t in tris {
                    for i in 0..3 {
                        let (a, b) = (t[i], t[(i + 1) % 3]);
                        *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
                    }
                }
                count.values().filter(|&&c| c > 2).count()
            };
            let before = nm(&kept);
            let n = kept.len();
            let lids = pocket_lids(&Topology::build(&Mesh::from_triangles(m.positions.clone(), &kept)));
            let removed = lids.len();
            let mut f = 0;
            kept.retain(|_| {
                f += 1;
                !lids.contains(&(f as u32 - 1))
            });
            proptest::prop_assert_eq!(kept.len() + removed, n);
            proptest::prop_assert_eq!(nm(&kept) + 3 * removed, before);
        }
    }

    /// The repair's summary names what it changed.
    #[test]
    fn repair_summary_names_the_changes() {
        // Two triangles traversing their shared edge in the same direction.
        let p = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 1.0)];
        let m = Mesh::from_faces(p, vec![vec![0, 1, 2], vec![0, 1, 3]]);
        assert!(prepare(&m, false).is_err());
        let (_, _, r) = prepare(&m, true).unwrap();
        assert_eq!(
            r.repair_summary().as_deref(),
            Some("flipped 1 face(s) to orient their component consistently")
        );
        let (_, _, r) = prepare(&generate::fin(), true).unwrap();
        let s = r.repair_summary().unwrap();
        assert!(
            s.starts_with("cut 1 non-manifold edge(s) into boundary edges"),
            "{s}"
        );
    }
}

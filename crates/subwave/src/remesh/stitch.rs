//! Stitching of *slits*: cracks between two boundary chains of a mesh that follow each other
//! a hair apart, with T-junctions (vertices of one side that the other side's edges pass).
//!
//! Modellers join panels whose rims were tessellated apart: one rim is a long edge, the other
//! the same curve through more vertices, and between them a slit of a fraction of a
//! millimetre (the beetle of the corpus: a boundary loop 47–53–376–389 after the repair,
//! whose sides are 0.05–0.09% of the diagonal apart). A remesher parameterizes such a slit as
//! a hole whose two sides are crushed together, and folds faces along it at fine levels.
//! Barequet & Kumar ("Repairing CAD models", IEEE Visualization 1997) close such cracks by
//! matching the boundary chains and splitting edges at the other side's vertices; this is
//! the T-junction part of it: a boundary edge `ab` is split at the boundary vertices
//! `v_1..v_k` of another part of the boundary that lie within a tolerance of it (their
//! projection strictly inside the segment), its face `abc` becoming the fan `a v_1 c, …,
//! v_k b c`, but only where *every* new sub-edge then meets a boundary edge traversed the
//! other way (an existing one or a sub-edge of another split): the slit closes completely
//! and the mesh stays an oriented manifold there. Nothing moves: the split face bends by the
//! slit's width. A split that would not close, that would make a sliver or turn a new face
//! against the split one, or that meets a second split on the same face, is not made.

use std::collections::HashMap;

use glam::DVec3;

/// Largest distance, relative to the mesh's bounding-box diagonal, between a T-vertex and
/// the boundary edge it splits: the beetle's slit is 0.05–0.09% of its diagonal wide.
pub const SLIT_TOLERANCE: f64 = 2e-3;

/// A T-vertex's projection must lie this far (as a fraction of the edge) inside the edge.
const END_MARGIN: f64 = 0.01;

/// Splits the boundary edges of `tris` at the T-vertices of slits (module documentation)
/// and returns the new triangles and the number of T-vertices inserted (0: `tris`
/// unchanged). Faces keep their order; a split face's fan takes its place.
///
/// Preconditions: indices of `tris` below `positions.len()`; no triangle repeats a vertex.
/// `tolerance` is absolute (callers scale [`SLIT_TOLERANCE`] by the diagonal).
pub fn stitch_slits(
    positions: &[DVec3],
    tris: &[[u32; 3]],
    tolerance: f64,
) -> (Vec<[u32; 3]>, usize) {
    if tolerance.is_nan() || tolerance <= 0.0 {
        return (tris.to_vec(), 0);
    }
    // Face sides (undirected edge key, face side `3 f + i`), sorted: an edge's faces are
    // its run of equal keys, a boundary edge a run of one.
    let key2 = |a: u32, b: u32| (u64::from(a.min(b)) << 32) | u64::from(a.max(b));
    let mut sides: Vec<(u64, u32)> = tris
        .iter()
        .enumerate()
        .flat_map(|(f, t)| (0..3).map(move |i| (key2(t[i], t[(i + 1) % 3]), (3 * f + i) as u32)))
        .collect();
    sides.sort_unstable();
    let faces_on = |a: u32, b: u32| {
        let k = key2(a, b);
        let lo = sides.partition_point(|x| x.0 < k);
        sides[lo..].iter().take_while(|x| x.0 == k).count()
    };
    // Boundary edges (a, b) as their face traverses them, with the face and its third corner,
    // in face order.
    let mut boundary: Vec<(u32, u32, usize, u32)> = Vec::new();
    for (j, &(k, side)) in sides.iter().enumerate() {
        let single =
            (j == 0 || sides[j - 1].0 != k) && !matches!(sides.get(j + 1), Some(x) if x.0 == k);
        if single {
            let (f, i) = (side as usize / 3, side as usize % 3);
            let t = tris[f];
            boundary.push((t[i], t[(i + 1) % 3], f, t[(i + 2) % 3]));
        }
    }
    boundary.sort_unstable_by_key(|e| (e.2, e.0));
    if boundary.is_empty() {
        return (tris.to_vec(), 0);
    }
    let mut corners: Vec<u32> = boundary.iter().flat_map(|e| [e.0, e.1]).collect();
    corners.sort_unstable();
    corners.dedup();
    // Boundary vertices in a uniform grid of cells at least the mean boundary edge long.
    let mean = boundary
        .iter()
        .map(|e| positions[e.0 as usize].distance(positions[e.1 as usize]))
        .sum::<f64>()
        / boundary.len() as f64;
    let cell = mean.max(tolerance).max(f64::MIN_POSITIVE);
    let key = |p: DVec3| (p / cell).floor().as_ivec3().to_array();
    let mut grid: HashMap<[i32; 3], Vec<u32>> = HashMap::new();
    for &v in &corners {
        grid.entry(key(positions[v as usize])).or_default().push(v);
    }
    // Each boundary edge's T-vertices, ordered along it.
    let mut chains: Vec<Vec<u32>> = vec![Vec::new(); boundary.len()];
    for (k, &(a, b, _, _)) in boundary.iter().enumerate() {
        let (pa, pb) = (positions[a as usize], positions[b as usize]);
        let d = pb - pa;
        let len2 = d.length_squared();
        if len2 <= 0.0 {
            continue;
        }
        let lo = key(pa.min(pb) - DVec3::splat(tolerance));
        let hi = key(pa.max(pb) + DVec3::splat(tolerance));
        // Cells the edge's box covers: a few, as cells are a mean edge long; a very long edge
        // is skipped rather than scanned cell by cell.
        let cells = (0..3)
            .map(|i| (hi[i] as i64 - lo[i] as i64 + 1) as u64)
            .product::<u64>();
        if cells > 4096 {
            continue;
        }
        let mut found: Vec<(f64, u32)> = Vec::new();
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    for &v in grid.get(&[x, y, z]).map_or(&[][..], |c| c.as_slice()) {
                        if v == a || v == b {
                            continue;
                        }
                        let p = positions[v as usize];
                        let t = (p - pa).dot(d) / len2;
                        if t <= END_MARGIN || t >= 1.0 - END_MARGIN {
                            continue;
                        }
                        if p.distance(pa + t * d) <= tolerance {
                            found.push((t, v));
                        }
                    }
                }
            }
        }
        found.sort_by(|x, y| x.0.total_cmp(&y.0));
        chains[k] = found.into_iter().map(|(_, v)| v).collect();
    }
    // Accept splits whose sub-edges all meet a boundary edge the other way, among the
    // boundary edges as the accepted splits leave them; a rejection can undo a partner's
    // match, so until nothing changes.
    let mut accepted: Vec<bool> = chains.iter().map(|c| !c.is_empty()).collect();
    // A face with two candidate splits is left alone.
    let mut per_face: HashMap<usize, usize> = HashMap::new();
    for (k, e) in boundary.iter().enumerate() {
        if accepted[k] {
            *per_face.entry(e.2).or_insert(0) += 1;
        }
    }
    for (k, e) in boundary.iter().enumerate() {
        if accepted[k] && per_face[&e.2] > 1 {
            accepted[k] = false;
        }
    }
    let path = |k: usize| {
        let (a, b, _, _) = boundary[k];
        std::iter::once(a)
            .chain(chains[k].iter().copied())
            .chain(std::iter::once(b))
            .collect::<Vec<u32>>()
    };
    // Geometric checks of each candidate fan: no sliver, no face turned against the split one.
    for k in 0..boundary.len() {
        if !accepted[k] {
            continue;
        }
        let (a, b, _, c) = boundary[k];
        let pc = positions[c as usize];
        let n = (positions[b as usize] - positions[a as usize]).cross(pc - positions[a as usize]);
        let p = path(k);
        accepted[k] = p.windows(2).all(|w| {
            let (x, y) = (positions[w[0] as usize], positions[w[1] as usize]);
            let m = (y - x).cross(pc - x);
            m.dot(n) > 0.0 && super::quality::min_angle(&[0, 1, 2], &[x, y, pc]) >= 1.0
        }) && !p.contains(&c);
    }
    loop {
        // Directed boundary edges as the accepted splits leave them, with multiplicities.
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for (k, e) in boundary.iter().enumerate() {
            if accepted[k] {
                for w in path(k).windows(2) {
                    *directed.entry((w[0], w[1])).or_insert(0) += 1;
                }
            } else {
                *directed.entry((e.0, e.1)).or_insert(0) += 1;
            }
        }
        // A piece closes if it and its reverse are each one boundary edge, and no interior
        // edge joins its ends already.
        let closes = |w: &[u32]| {
            directed.get(&(w[0], w[1])) == Some(&1)
                && directed.get(&(w[1], w[0])) == Some(&1)
                && faces_on(w[0], w[1]) <= 1
        };
        let mut changed = false;
        for (k, a) in accepted.iter_mut().enumerate() {
            if *a && !path(k).windows(2).all(closes) {
                *a = false;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    let mut fans: HashMap<usize, Vec<[u32; 3]>> = HashMap::new();
    let mut inserted = 0;
    for k in (0..boundary.len()).filter(|&k| accepted[k]) {
        let (_, _, f, c) = boundary[k];
        let p = path(k);
        inserted += p.len() - 2;
        fans.insert(f, p.windows(2).map(|w| [w[0], w[1], c]).collect());
    }
    if inserted == 0 {
        return (tris.to_vec(), 0);
    }
    let mut out = Vec::with_capacity(tris.len() + inserted);
    for (f, t) in tris.iter().enumerate() {
        match fans.get(&f) {
            Some(fan) => out.extend_from_slice(fan),
            None => out.push(*t),
        }
    }
    (out, inserted)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;
    use crate::topology::Topology;

    /// Two panels in the plane z = 0: below, a rectangle whose top rim is one edge from
    /// (3, 1) to (0, 1); above, a panel whose bottom rim runs from (0, 1) through two
    /// vertices `gap` higher to (3, 1) (shared ends): a slit with two T-junctions. With
    /// `flip_above` the upper panel's faces are reversed.
    fn panels(gap: f64, flip_above: bool) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let p = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        let positions = vec![
            p(0.0, 0.0),
            p(3.0, 0.0),
            p(3.0, 1.0),
            p(0.0, 1.0),
            p(1.0, 1.0 + gap),
            p(2.0, 1.0 + gap),
            p(0.0, 2.0),
            p(3.0, 2.0),
        ];
        let mut tris = vec![[0, 1, 2], [0, 2, 3]];
        let above = [[3, 4, 6], [4, 7, 6], [4, 5, 7], [5, 2, 7]];
        tris.extend(
            above
                .iter()
                .map(|&[a, b, c]| if flip_above { [a, c, b] } else { [a, b, c] }),
        );
        (positions, tris)
    }

    fn boundary_edges(positions: &[DVec3], tris: &[[u32; 3]]) -> usize {
        let m = Mesh::from_triangles(positions.to_vec(), tris);
        let t = Topology::build(&m);
        (0..t.num_edges())
            .filter(|&e| t.is_boundary_edge(e))
            .count()
    }

    #[test]
    fn a_slit_with_t_junctions_closes() {
        let (positions, tris) = panels(1e-3, false);
        assert_eq!(boundary_edges(&positions, &tris), 10);
        let (out, inserted) = stitch_slits(&positions, &tris, 2e-3);
        assert_eq!(inserted, 2);
        // The long edge's face became a fan of three, in its place.
        assert_eq!(out.len(), tris.len() + 2);
        assert_eq!(out[0], tris[0]);
        assert_eq!(&out[4..], &tris[2..]);
        let m = Mesh::from_triangles(positions.clone(), &out);
        let t = Topology::build(&m);
        assert!(t.is_manifold() && t.inconsistent_edges.is_empty());
        // One disc: the slit's six boundary edges are interior now.
        assert_eq!(boundary_edges(&positions, &out), 6);
        assert_eq!(t.boundary_loops().1, 1);
    }

    /// The remesher's input preparation stitches with `--repair`; without, the slit's ends
    /// (two fans each) make the input non-manifold, named in the error.
    #[test]
    fn the_repair_stitches_slits() {
        let (positions, tris) = panels(1e-3, false);
        let faces: Vec<Vec<u32>> = tris.iter().map(|t| t.to_vec()).collect();
        let mesh = Mesh::from_faces(positions, faces);
        match super::super::repair::prepare(&mesh, false) {
            Err(crate::Error::Mesh(crate::MeshError::NonManifold { edges, vertices })) => {
                assert_eq!((edges, vertices), (vec![], vec![2, 3]));
            }
            other => panic!("expected a non-manifold error, got {other:?}"),
        }
        let (_, kept, r) = super::super::repair::prepare(&mesh, true).unwrap();
        assert_eq!((kept.len(), r.stitched_vertices), (8, 2));
        assert_eq!((r.non_manifold_vertices, r.added_vertices), (0, 0));
        let summary = r.repair_summary().unwrap();
        assert!(summary.starts_with("stitched 2 T-junction(s)"), "{summary}");
    }

    #[test]
    fn a_gap_wider_than_the_tolerance_stays_open() {
        let (positions, tris) = panels(1e-2, false);
        let (out, inserted) = stitch_slits(&positions, &tris, 2e-3);
        assert_eq!((inserted, out), (0, tris));
    }

    #[test]
    fn sides_traversed_the_same_way_are_not_glued() {
        // Gluing would make the orientation inconsistent.
        let (positions, tris) = panels(1e-3, true);
        let (out, inserted) = stitch_slits(&positions, &tris, 2e-3);
        assert_eq!((inserted, out), (0, tris));
    }

    #[test]
    fn a_split_that_would_not_close_the_slit_is_not_made() {
        // The second T-vertex moved off the rim: splitting at the first alone leaves a
        // sub-edge without a partner.
        let (mut positions, tris) = panels(1e-3, false);
        positions[5].y = 1.5;
        let (out, inserted) = stitch_slits(&positions, &tris, 2e-3);
        assert_eq!((inserted, out), (0, tris));
    }

    #[test]
    fn closed_meshes_and_empty_input_are_unchanged() {
        let m = crate::generate::icosphere(1);
        let tris: Vec<[u32; 3]> = (0..m.num_faces())
            .map(|f| {
                let v = m.face(f);
                [v[0], v[1], v[2]]
            })
            .collect();
        assert_eq!(stitch_slits(&m.positions, &tris, 1.0), (tris, 0));
        assert_eq!(stitch_slits(&[], &[], 1.0), (Vec::new(), 0));
    }
}

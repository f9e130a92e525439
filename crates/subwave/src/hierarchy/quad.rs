//! Detection of Catmull-Clark connectivity (1-to-4 quad splits, [`Split::Polygons`] on an
//! all-quad base) in a quad mesh given in any vertex and face order.
//!
//! Bertram et al. §4.1 (Fig. 7): a level refined from a quad mesh has one `v` vertex per
//! coarse vertex, one `e` vertex per coarse edge and one `f` vertex per coarse face, and each
//! child quad reads `(v, e, f, e)` around its boundary (refiner order `(v_i, m_i, c,
//! m_{i−1})`, [`crate::subdivision::refine`]). So an `f` vertex is interior with valence 4,
//! an `e` vertex has valence 4 inside and 3 on a boundary, and a vertex of any other valence
//! (or a boundary vertex of valence ≠ 3) must be a `v` vertex.
//!
//! # One coarsening step
//! Labelling one quad (which corner is its `v` vertex) fixes the labels of its four corners,
//! and across each edge the neighbour's two other corners: the corner opposite a `v` vertex
//! is an `f` vertex and vice versa, the one opposite an `e` vertex an `e` vertex. Each
//! edge-connected component is labelled by a breadth-first propagation from one seed quad:
//! the quad at a vertex that must be a `v` vertex, with that corner `v`; in a fully regular
//! component (every vertex of valence 4, e.g. a torus grid) the four corners of its first
//! quad are tried in turn. The four quads around each `f` vertex, chained by their shared
//! `e` vertices, give the coarse quad (their `v` corners) and the odd vertex of each coarse
//! edge and face. After the last step the contract hierarchy is rebuilt from the coarsest
//! mesh and checked to reproduce every input quad with its orientation, so an accepted
//! detection is exact.
//!
//! Limitation: the base mesh must be all quads (a polygon base, whose first level is all
//! quads with face points of valence ≠ 4, is detected down to level 1 only).

use glam::DVec3;

use super::{
    int_map, key, label_components, Conflict, Hierarchy, IntMap, Labelling, OddVertices,
    Renumbering,
};
use crate::mesh::Mesh;
use crate::subdivision::refine::{refine_topology, Split};
use crate::topology::{Topology, VertexKind};
use crate::validate::require_manifold;
use crate::{Error, Result};

const UNSET: u8 = u8::MAX;
const V: u8 = 0;
const E: u8 = 1;
const F: u8 = 2;

/// The cyclic rotation of quad `q` starting at its smallest vertex.
pub(super) fn rotate_min4(q: [u32; 4]) -> [u32; 4] {
    let i = (0..4).min_by_key(|&i| q[i]).unwrap();
    [q[i], q[(i + 1) % 4], q[(i + 2) % 4], q[(i + 3) % 4]]
}

/// Odd vertices of one coarsening step: per coarse edge (sorted-pair key) its `e` vertex, per
/// coarse quad ([`rotate_min4`] of its input ids) its `f` vertex.
struct QuadStep {
    edges: OddVertices,
    faces: IntMap<[u32; 4], u32>,
}

/// Labelling state of one coarsening step.
struct Labels<'a> {
    topo: &'a Topology,
    /// Per quad, the corner of its `v` vertex.
    face: Vec<u8>,
    /// Per vertex, `V`, `E` or `F`.
    vert: Vec<u8>,
    touched_faces: Vec<u32>,
    touched_verts: Vec<u32>,
}

impl Labels<'_> {
    fn allowed(&self, v: u32, label: u8) -> bool {
        let val = self.topo.valence(v as usize);
        match (label, self.topo.vertex_kinds[v as usize]) {
            (V, _) => true,
            (E, VertexKind::Interior) | (F, VertexKind::Interior) => val == 4,
            (E, VertexKind::Boundary) => val == 3,
            _ => false,
        }
    }

    fn assign(
        &mut self,
        g: u32,
        corner: u8,
        queue: &mut Vec<u32>,
    ) -> Result<(), (u32, &'static str)> {
        let cur = self.face[g as usize];
        if cur == corner {
            return Ok(());
        }
        if cur != UNSET {
            return Err((
                g,
                "its neighbours disagree on which of its corners is an old vertex",
            ));
        }
        self.face[g as usize] = corner;
        self.touched_faces.push(g);
        for (i, &v) in self.topo.face_vertices(g as usize).iter().enumerate() {
            let want = [V, E, F, E][(i + 4 - corner as usize) % 4];
            let cur = self.vert[v as usize];
            if cur == UNSET {
                if !self.allowed(v, want) {
                    return Err((
                        g,
                        if want == F {
                            "its face point would be a vertex that is not interior of valence 4"
                        } else {
                            "its edge points would include a vertex of valence other than 4 (3 on a boundary)"
                        },
                    ));
                }
                self.vert[v as usize] = want;
                self.touched_verts.push(v);
            } else if cur != want {
                return Err((
                    g,
                    "its corners cannot read (old vertex, edge point, face point, edge point)",
                ));
            }
        }
        queue.push(g);
        Ok(())
    }

    fn propagate_from(&mut self, seed: u32, corner: u8) -> Result<(), (u32, &'static str)> {
        let mut queue = Vec::new();
        self.assign(seed, corner, &mut queue)?;
        while let Some(f) = queue.pop() {
            for &e in self.topo.face_edges(f as usize) {
                for &g in self.topo.edge_faces(e as usize) {
                    if g == f || self.face[g as usize] != UNSET {
                        // Labelled neighbours are checked through their shared vertices.
                        continue;
                    }
                    let gv = self.topo.face_vertices(g as usize);
                    let [a, b] = self.topo.edge_vertices[e as usize];
                    let mut c = None;
                    for x in [a, b] {
                        let p = gv.iter().position(|&y| y == x).unwrap() as u8;
                        match self.vert[x as usize] {
                            V => c = Some(p),
                            F => c = Some((p + 2) % 4),
                            _ => {}
                        }
                    }
                    let Some(c) = c else {
                        return Err((g, "both ends of an edge it shares would be edge points"));
                    };
                    self.assign(g, c, &mut queue)?;
                }
            }
        }
        Ok(())
    }

    fn clear_touched(&mut self) {
        for f in self.touched_faces.drain(..) {
            self.face[f as usize] = UNSET;
        }
        for v in self.touched_verts.drain(..) {
            self.vert[v as usize] = UNSET;
        }
    }
}

impl Labelling for Labels<'_> {
    fn begin(&mut self) {
        self.touched_faces.clear();
        self.touched_verts.clear();
    }
    fn propagate(&mut self, seed: u32, label: u8) -> std::result::Result<(), Conflict> {
        self.propagate_from(seed, label)
            .map_err(|(face, reason)| Conflict { face, reason })
    }
    fn reset(&mut self) {
        self.clear_touched();
    }
}

/// One coarsening step: the inverse of one Catmull-Clark split of a quad mesh.
fn coarsen(nv: usize, faces: &[[u32; 4]], step: usize) -> Result<(Vec<[u32; 4]>, QuadStep)> {
    let mesh = Mesh::from_faces(vec![DVec3::ZERO; nv], faces);
    let topo = Topology::build(&mesh);
    require_manifold(&topo)?;
    let name = |f: u32| {
        let v = topo.face_vertices(f as usize);
        let what = if step == 1 {
            format!("quad {f} (vertices")
        } else {
            "coarse quad (input vertices".into()
        };
        format!("{what} {}, {}, {}, {})", v[0], v[1], v[2], v[3])
    };
    let fail = |f: u32, reason: &str| {
        Error::Hierarchy(format!(
            "coarsening step {step}: {} is not part of a 1-to-4 quad group (Catmull-Clark split): {reason}",
            name(f)
        ))
    };
    let nf = topo.num_faces();
    if nf == 0 {
        return Err(Error::Hierarchy(format!(
            "coarsening step {step}: the mesh has no quads"
        )));
    }
    let forced_v = |v: u32| match topo.vertex_kinds[v as usize] {
        VertexKind::Interior => topo.valence(v as usize) != 4,
        VertexKind::Boundary => topo.valence(v as usize) != 3,
        _ => false,
    };
    let mut labels = Labels {
        topo: &topo,
        face: vec![UNSET; nf],
        vert: vec![UNSET; nv],
        touched_faces: Vec::new(),
        touched_verts: Vec::new(),
    };
    label_components(
        &topo,
        step,
        "quads",
        &name,
        &forced_v,
        &mut labels,
        &|c: Conflict| fail(c.face, c.reason),
    )?;
    // Groups: the four quads around each face point, chained by their shared edge points.
    let mut coarse = Vec::with_capacity(nf / 4);
    let mut out = QuadStep {
        edges: int_map(nf / 2),
        faces: int_map(nf / 4),
    };
    let mut odd_edge = vec![u64::MAX; nv];
    for c in 0..nv as u32 {
        if labels.vert[c as usize] != F {
            continue;
        }
        let around = topo.vertex_faces(c as usize);
        let first = around[0];
        // Child (v_i, m_i, c, m_{i-1}) read from quad q with c at corner k.
        let child = |q: u32| {
            let qv = topo.face_vertices(q as usize);
            let k = qv.iter().position(|&x| x == c).unwrap();
            (qv[(k + 2) % 4], qv[(k + 3) % 4], qv[(k + 1) % 4])
        };
        let mut vs = [0u32; 4];
        let mut ms = [0u32; 4];
        let mut q = first;
        for i in 0..4 {
            let (v, m, _) = child(q);
            vs[i] = v;
            ms[i] = m;
            if i < 3 {
                let Some(&next) = around.iter().find(|&&g| child(g).2 == m) else {
                    return Err(fail(q, "the quads around its face point do not close up"));
                };
                q = next;
            }
        }
        if ms[3] != child(first).2 {
            return Err(fail(
                first,
                "the quads around its face point do not close up",
            ));
        }
        if (0..4).any(|i| (i + 1..4).any(|j| vs[i] == vs[j] || ms[i] == ms[j])) {
            return Err(fail(first, "its group would make a degenerate coarse quad"));
        }
        coarse.push(vs);
        out.faces.insert(rotate_min4(vs), c);
        for i in 0..4 {
            let (o, k) = (ms[i], key(vs[i], vs[(i + 1) % 4]));
            let oe = &mut odd_edge[o as usize];
            if *oe == u64::MAX {
                *oe = k;
            }
            if *out.edges.entry(k).or_insert(o) != o || *oe != k {
                return Err(fail(
                    first,
                    "an edge point would lie on two coarse edges (or a coarse edge carry two edge points)",
                ));
            }
        }
    }
    if coarse.len() * 4 != nf {
        return Err(Error::Hierarchy(format!(
            "coarsening step {step}: {} face points group {} of the {nf} quads",
            coarse.len(),
            4 * coarse.len()
        )));
    }
    Ok((coarse, out))
}

/// [`Hierarchy::detect`] for all-quad meshes (the caller checked the indices and arity).
pub(super) fn detect_quads(mesh: &Mesh, levels: Option<u32>) -> Result<(Hierarchy, Renumbering)> {
    let nv = mesh.num_vertices();
    let input: Vec<[u32; 4]> = mesh.faces().map(|f| [f[0], f[1], f[2], f[3]]).collect();
    let mut faces = input.clone();
    let mut steps: Vec<QuadStep> = Vec::new();
    loop {
        let step = steps.len() + 1;
        if levels.is_some_and(|l| step > l as usize) {
            break;
        }
        match coarsen(nv, &faces, step) {
            Ok((c, odd)) => {
                faces = c;
                steps.push(odd);
            }
            Err(e) => {
                if levels.is_none() && step > 1 && matches!(e, Error::Hierarchy(_)) {
                    break;
                }
                return Err(e);
            }
        }
    }
    let l = steps.len();
    let mut is_odd = vec![false; nv];
    for s in &steps {
        for &o in s.edges.values().chain(s.faces.values()) {
            is_odd[o as usize] = true;
        }
    }
    let mut to_input: Vec<u32> = (0..nv as u32).filter(|&v| !is_odd[v as usize]).collect();
    let mut new_of = vec![u32::MAX; nv];
    for (n, &o) in to_input.iter().enumerate() {
        new_of[o as usize] = n as u32;
    }
    let base_pos = to_input
        .iter()
        .map(|&o| mesh.positions[o as usize])
        .collect();
    let base = Mesh::from_faces(
        base_pos,
        faces.iter().map(|q| q.map(|v| new_of[v as usize])),
    );
    let t0 = Topology::build(&base);
    require_manifold(&t0)?;
    let mut topologies = vec![t0];
    let mut claim = |o: u32, to_input: &mut Vec<u32>, level: usize| -> Result<()> {
        if new_of[o as usize] != u32::MAX {
            return Err(Error::Hierarchy(format!(
                "level {level}: input vertex {o} is the edge or face point of two coarse elements"
            )));
        }
        new_of[o as usize] = to_input.len() as u32;
        to_input.push(o);
        Ok(())
    };
    for j in 0..l {
        let parent = &topologies[j];
        let odd = &steps[l - 1 - j];
        for (e, &[a, b]) in parent.edge_vertices.iter().enumerate() {
            let (ia, ib) = (to_input[a as usize], to_input[b as usize]);
            let Some(&o) = odd.edges.get(&key(ia, ib)) else {
                return Err(Error::Hierarchy(format!(
                    "level {j}: edge {e} (input vertices {ia}, {ib}) has no edge point at level {}",
                    j + 1
                )));
            };
            claim(o, &mut to_input, j + 1)?;
        }
        for f in 0..parent.num_faces() {
            let fv = parent.face_vertices(f);
            let q = [fv[0], fv[1], fv[2], fv[3]].map(|v| to_input[v as usize]);
            let Some(&o) = odd.faces.get(&rotate_min4(q)) else {
                return Err(Error::Hierarchy(format!(
                    "level {j}: quad {f} (input vertices {}, {}, {}, {}) has no face point at level {}",
                    q[0], q[1], q[2], q[3],
                    j + 1
                )));
            };
            claim(o, &mut to_input, j + 1)?;
        }
        let (child, _) = refine_topology(parent, Split::Polygons, false);
        debug_assert_eq!(child.num_vertices as usize, to_input.len());
        topologies.push(child);
    }
    if to_input.len() != nv {
        return Err(Error::Hierarchy(format!(
            "{} of the {nv} vertices are not in the rebuilt hierarchy",
            nv - to_input.len()
        )));
    }
    let mut by_key: IntMap<[u32; 4], u32> = int_map(input.len());
    for (f, q) in input.iter().enumerate() {
        by_key.insert(rotate_min4(*q), f as u32);
    }
    let finest = topologies.last().unwrap();
    let mut face_map = Vec::with_capacity(finest.num_faces());
    let mut used = vec![false; input.len()];
    for f in 0..finest.num_faces() {
        let v = finest.face_vertices(f);
        let q = [v[0], v[1], v[2], v[3]].map(|x| to_input[x as usize]);
        match by_key.get(&rotate_min4(q)) {
            Some(&g) if !used[g as usize] => {
                used[g as usize] = true;
                face_map.push(g);
            }
            _ => {
                return Err(Error::Hierarchy(format!(
                    "the rebuilt level {l} quad {f} (input vertices {}, {}, {}, {}) is not an input quad with that orientation",
                    q[0], q[1], q[2], q[3]
                )))
            }
        }
    }
    if face_map.len() != input.len() {
        return Err(Error::Hierarchy(format!(
            "the rebuilt hierarchy has {} finest quads, the input {}",
            face_map.len(),
            input.len()
        )));
    }
    let positions: Vec<DVec3> = to_input
        .iter()
        .map(|&o| mesh.positions[o as usize])
        .collect();
    let mut base = base;
    let nb = base.positions.len();
    base.positions.copy_from_slice(&positions[..nb]);
    Ok((
        Hierarchy {
            split: Split::Polygons,
            base,
            topologies,
            positions,
        },
        Renumbering {
            vertices: to_input,
            faces: face_map,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::super::tests::Rng;
    use super::*;
    use crate::generate;

    /// `m` with vertices and faces randomly permuted and face corners randomly rotated.
    fn shuffle(m: &Mesh, rng: &mut Rng) -> (Mesh, Vec<u32>) {
        let n = m.num_vertices();
        let mut perm: Vec<u32> = (0..n as u32).collect(); // old -> new
        for i in (1..n).rev() {
            perm.swap(i, rng.below(i + 1));
        }
        let mut pos = vec![DVec3::ZERO; n];
        for (old, &new) in perm.iter().enumerate() {
            pos[new as usize] = m.positions[old];
        }
        let mut faces: Vec<Vec<u32>> = m
            .faces()
            .map(|f| {
                let r = rng.below(f.len());
                (0..f.len())
                    .map(|i| perm[f[(i + r) % f.len()] as usize])
                    .collect()
            })
            .collect();
        for i in (1..faces.len()).rev() {
            faces.swap(i, rng.below(i + 1));
        }
        (Mesh::from_faces(pos, faces), perm)
    }

    fn roundtrip(base: &Mesh, levels: u32, seed: u64, same_base: bool) {
        let mut rng = Rng(seed);
        let lin = Hierarchy::new(base, levels, Split::Polygons, None).unwrap();
        let pos: Vec<DVec3> = lin
            .positions
            .iter()
            .map(|&p| p + 0.01 * DVec3::new(rng.unit(), rng.unit(), rng.unit()))
            .collect();
        let h = Hierarchy::new(base, levels, Split::Polygons, Some(pos)).unwrap();
        let (shuffled, perm) = shuffle(&h.finest_mesh(), &mut rng);
        let (d, r) = Hierarchy::detect(&shuffled, Some(levels)).unwrap();
        assert_eq!(d.split, Split::Polygons);
        assert_eq!(d.levels(), levels as usize);
        assert_eq!(d.base.num_vertices(), base.num_vertices());
        assert_eq!(d.base.num_faces(), base.num_faces());
        for j in 0..=levels as usize {
            assert_eq!(d.num_vertices(j), h.num_vertices(j));
            assert_eq!(d.topology(j).num_faces(), h.topology(j).num_faces());
        }
        // Positions map back exactly; faces are input faces with their orientation.
        assert_eq!(r.to_input(&d.positions), shuffled.positions);
        for (f, &g) in r.faces.iter().enumerate() {
            let a = d.topology(levels as usize).face_vertices(f);
            let b = shuffled.face(g as usize);
            let a = rotate_min4([a[0], a[1], a[2], a[3]].map(|v| r.vertices[v as usize]));
            assert_eq!(a, rotate_min4([b[0], b[1], b[2], b[3]]));
        }
        if !same_base {
            return;
        }
        let mut got: Vec<u32> = r.vertices[..base.num_vertices()].to_vec();
        let mut want: Vec<u32> = perm[..base.num_vertices()].to_vec();
        got.sort_unstable();
        want.sort_unstable();
        assert_eq!(got, want);
        // The edge and face points of level 1 are the original ones (as sets).
        let n1 = h.num_vertices(1);
        let mut got: Vec<u32> = r.vertices[base.num_vertices()..n1].to_vec();
        let mut want: Vec<u32> = perm[base.num_vertices()..n1].to_vec();
        got.sort_unstable();
        want.sort_unstable();
        assert_eq!(got, want);
        let (d2, _) = Hierarchy::detect(&shuffled, None).unwrap();
        assert_eq!(d2.levels(), levels as usize);
    }

    #[test]
    fn detect_quads_after_shuffle() {
        roundtrip(&generate::cube(), 3, 11, true);
        roundtrip(&generate::cube(), 2, 12, true);
        roundtrip(&generate::grid(3, 2, false), 3, 13, true);
        roundtrip(&generate::grid(1, 1, false), 2, 14, true);
        // A (5, 4) torus is fully regular: several valid coarsenings.
        roundtrip(&generate::torus(1.0, 0.4, 5, 4, false), 2, 15, false);
        roundtrip(&generate::torus(1.0, 0.4, 3, 3, false), 3, 16, false);
    }

    #[test]
    fn detect_quads_errors() {
        // A cube is a split of nothing.
        let e = Hierarchy::detect(&generate::cube(), Some(1)).unwrap_err();
        assert!(e.to_string().contains("coarsening step 1"), "{e}");
        // Two levels, three asked.
        let h = Hierarchy::new(&generate::cube(), 2, Split::Polygons, None).unwrap();
        let e = Hierarchy::detect(&h.finest_mesh(), Some(3)).unwrap_err();
        assert!(e.to_string().contains("coarsening step 3"), "{e}");
        // Rotating the diagonal structure of one quad pair breaks the grouping.
        let mut m = h.finest_mesh();
        // Re-triangulating nothing: swap two corners' roles by rotating a quad's start is
        // harmless (same cycle), so instead reverse one quad (orientation flip).
        let s = m.face_offsets[5] as usize;
        m.face_indices[s..s + 4].reverse();
        assert!(Hierarchy::detect(&m, Some(1)).is_err());
    }
}

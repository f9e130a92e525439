//! Connectivity of a polygon mesh by a valence-driven cut-border traversal.
//!
//! The algorithm is Touma & Gotsman's (*Triangle Mesh Compression*, Graphics Interface 1998):
//! a border ("active list") separates the processed faces from the others; a *focus* vertex
//! on it is conquered face by face until all its faces are processed, then the focus moves on
//! along the border; a face that touches the border elsewhere splits the border (`split`,
//! with an offset) or, on a handle, merges two borders (`merge`, with a border index and an
//! offset). Holes are closed by one dummy vertex each (TG §3: a triangle fan from a new vertex
//! onto every boundary loop); dummy vertices and their faces are dropped by the decoder.
//!
//! Polygons are handled as in Isenburg & Snoeyink's Face Fixer (*Face Fixer: Compressing
//! Polygon Meshes with Properties*, SIGGRAPH 2000), the connectivity coder Lavoué et al.
//! §VII.1 use for CAD control meshes: each face across the gate (the border edge entering the
//! focus) is described by its degree and by how its boundary attaches to the border. Its
//! edges after the gate are `e_0 .. e_k` (`k = degree − 2`); the last `f` of them follow the
//! border forward from the focus (Face Fixer's "right" attachments; `f = k + 1` closes the
//! border), the first `b` follow it backward from the gate's other end ("left"), and the
//! vertices between them are new or (rarely) elsewhere on a border.
//!
//! The entropy coding follows Alliez & Desbrun (*Valence-Driven Connectivity Encoding for 3D
//! Meshes*, Eurographics 2001): the information of a manifold traversal is essentially the
//! vertex valences. Here the valence of the focus is coded incrementally: "the focus is
//! complete after this face" (`f ≥ 1`) is an adaptive binary decision in the context of the
//! number of faces already around the focus (and the face degree, and whether the vertex is
//! a dummy), so the product of these decisions over a vertex is the probability of its
//! valence; the same for the gate's other end (`b ≥ 1`). Face degrees are coded in the context
//! of the previous degree (Face Fixer's degree coding), and skipped for triangle meshes.
//!
//! Encoder and decoder share the border data structure (`Border::apply`) and the symbol
//! flow (`code_face`, generic over the direction), so they cannot diverge.

use crate::codec::rangecoder::{CountedBit, Decoder, Encoder, UInt};
use crate::mesh::Mesh;
use crate::{Error, Result};

use super::ChunkError;

const NONE: u32 = u32::MAX;

/// Half-edge adjacency of a face table: for each corner `c` (the half-edge from its vertex to
/// the next corner's vertex), the next and previous corners of its face, its face and its
/// twin (the corner of the opposite half-edge, [`NONE`] on a boundary or a non-manifold edge).
pub(crate) struct HalfEdges {
    /// Next corner in the same face.
    pub next: Vec<u32>,
    /// Previous corner in the same face.
    pub prev: Vec<u32>,
    /// Face of each corner.
    pub face: Vec<u32>,
    /// Opposite half-edge, or `NONE`.
    pub twin: Vec<u32>,
}

impl HalfEdges {
    /// Builds the tables in `O(n log n)` (a sort of the corners by edge), whatever the input:
    /// an edge with other than one half-edge in each direction gets no twins.
    pub(crate) fn build(offsets: &[u32], indices: &[u32]) -> Self {
        let n = indices.len();
        let mut next = vec![0u32; n];
        let mut prev = vec![0u32; n];
        let mut face = vec![0u32; n];
        for (f, w) in offsets.windows(2).enumerate() {
            let (a, b) = (w[0] as usize, w[1] as usize);
            for c in a..b {
                next[c] = if c + 1 == b { a as u32 } else { c as u32 + 1 };
                prev[c] = if c == a { b as u32 - 1 } else { c as u32 - 1 };
                face[c] = f as u32;
            }
        }
        let order = corners_by_edge(indices, &next);
        let key = |c: u32| {
            let (a, b) = (indices[c as usize], indices[next[c as usize] as usize]);
            (a.min(b), a.max(b))
        };
        let mut twin = vec![NONE; n];
        let mut i = 0;
        while i < n {
            let k = key(order[i]);
            let mut j = i + 1;
            while j < n && key(order[j]) == k {
                j += 1;
            }
            if j - i == 2 {
                let (c, d) = (order[i] as usize, order[i + 1] as usize);
                if indices[c] != indices[d] {
                    twin[c] = d as u32;
                    twin[d] = c as u32;
                }
            }
            i = j;
        }
        HalfEdges {
            next,
            prev,
            face,
            twin,
        }
    }
}

/// The corners (half-edges) ordered so that those of the same undirected edge are
/// contiguous: a counting sort on the smaller vertex, then a sort of each (small) bucket on
/// the larger one. `O(n)` for bounded valences, `O(n log n)` whatever the input.
pub(crate) fn corners_by_edge(indices: &[u32], next: &[u32]) -> Vec<u32> {
    let n = indices.len();
    let nv = indices.iter().max().map_or(0, |&m| m as usize + 1);
    let lo = |c: usize| indices[c].min(indices[next[c] as usize]);
    let hi = |c: u32| {
        let c = c as usize;
        indices[c].max(indices[next[c] as usize])
    };
    let mut off = vec![0u32; nv + 1];
    for c in 0..n {
        off[lo(c) as usize + 1] += 1;
    }
    for v in 0..nv {
        off[v + 1] += off[v];
    }
    let mut fill = off.clone();
    let mut order = vec![0u32; n];
    for c in 0..n {
        let l = lo(c) as usize;
        order[fill[l] as usize] = c as u32;
        fill[l] += 1;
    }
    for v in 0..nv {
        let bucket = &mut order[off[v] as usize..off[v + 1] as usize];
        if bucket.len() > 1 {
            bucket.sort_unstable_by_key(|&c| (hi(c), c));
        }
    }
    order
}

/// The cut border: cyclic doubly linked lists of vertex occurrences ("nodes"). The border
/// edge from node `n` to `next[n]` has its processed face on the left (the face traverses
/// `vert[n] → vert[next[n]]`) and an unprocessed face on the right.
#[derive(Default)]
struct Border {
    vert: Vec<u32>,
    next: Vec<u32>,
    prev: Vec<u32>,
    lp: Vec<u32>,
    alive: Vec<bool>,
    /// Per loop: a live node, the length, and whether it is alive.
    loops: Vec<LoopInfo>,
    /// Live loops, in creation order (the traversal continues with the last one).
    active: Vec<u32>,
}

#[derive(Clone, Copy)]
struct LoopInfo {
    head: u32,
    len: u32,
}

/// A vertex of the face after the back and forward runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mid {
    /// A new vertex (its decoded id).
    New(u32),
    /// A vertex already on a border, by node.
    Node(u32),
}

/// What [`Border::apply`] did.
struct Applied {
    /// The face's vertices: focus, gate's other end, then the rest in face order.
    face: Vec<u32>,
    /// For each edge of the face after the back run and before the forward run, in face
    /// order: the node whose outgoing border edge it is (`None` if it closed against an
    /// existing border edge).
    outgoing: Vec<Option<u32>>,
    /// The next focus, or `None` when the loop closed.
    focus: Option<u32>,
}

impl Border {
    fn new_node(&mut self, v: u32, lp: u32) -> u32 {
        let n = self.vert.len() as u32;
        self.vert.push(v);
        self.next.push(n);
        self.prev.push(n);
        self.lp.push(lp);
        self.alive.push(true);
        n
    }

    /// Starts a loop with the vertices of a face (in face order); returns its nodes.
    fn start_loop(&mut self, verts: &[u32]) -> Vec<u32> {
        let id = self.loops.len() as u32;
        let nodes: Vec<u32> = verts.iter().map(|&v| self.new_node(v, id)).collect();
        let n = nodes.len();
        for i in 0..n {
            self.next[nodes[i] as usize] = nodes[(i + 1) % n];
            self.prev[nodes[i] as usize] = nodes[(i + n - 1) % n];
        }
        self.loops.push(LoopInfo {
            head: nodes[0],
            len: n as u32,
        });
        self.active.push(id);
        nodes
    }

    fn len_of(&self, node: u32) -> u32 {
        self.loops[self.lp[node as usize] as usize].len
    }

    fn kill_loop(&mut self, id: u32) {
        if let Some(i) = self.active.iter().position(|&l| l == id) {
            self.active.remove(i);
        }
    }

    /// Relabels the loop through `start` as `id` (walks at most `limit` nodes).
    fn relabel(&mut self, start: u32, id: u32) {
        let mut n = start;
        loop {
            self.lp[n as usize] = id;
            n = self.next[n as usize];
            if n == start {
                break;
            }
        }
    }

    /// Processes the face across the border edge entering `h` (see the module docs for `f`,
    /// `b`, `closure` and `mids`). Errors name what is inconsistent (only corrupt streams).
    fn apply(
        &mut self,
        h: u32,
        d: u32,
        f: u32,
        b: u32,
        closure: bool,
        mids: &[Mid],
    ) -> std::result::Result<Applied, &'static str> {
        let k = d - 2;
        let hu = h as usize;
        let g = self.prev[hu];
        let l = self.len_of(h);
        let mut face = Vec::with_capacity(d as usize);
        face.push(self.vert[hu]);
        face.push(self.vert[g as usize]);
        if closure {
            if l != d {
                return Err("a closing face's degree differs from its border's length");
            }
            let mut n = g;
            for _ in 0..k {
                n = self.prev[n as usize];
                face.push(self.vert[n as usize]);
            }
            let id = self.lp[hu];
            let mut n = h;
            for _ in 0..d {
                self.alive[n as usize] = false;
                n = self.next[n as usize];
            }
            self.kill_loop(id);
            return Ok(Applied {
                face,
                outgoing: Vec::new(),
                focus: None,
            });
        }
        if b + f > k || b + f + 2 > l || mids.len() as u32 != k - b - f {
            return Err("face runs are longer than the border");
        }
        // Back run.
        let mut bn = g;
        for _ in 0..b {
            self.alive[bn as usize] = false;
            bn = self.prev[bn as usize];
            face.push(self.vert[bn as usize]);
        }
        // Forward run.
        let mut fw = h;
        let mut fwd_verts = Vec::with_capacity(f as usize);
        for _ in 0..f {
            self.alive[fw as usize] = false;
            fw = self.next[fw as usize];
            fwd_verts.push(self.vert[fw as usize]);
        }
        let id = self.lp[hu];
        self.loops[id as usize].len -= b + f;
        self.next[bn as usize] = fw;
        self.prev[fw as usize] = bn;
        self.loops[id as usize].head = bn;
        let mut cur = bn;
        let mut outgoing = Vec::with_capacity(mids.len() + 1);
        outgoing.push(Some(cur));
        for &m in mids {
            match m {
                Mid::New(v) => {
                    let lid = self.lp[cur as usize];
                    let n = self.new_node(v, lid);
                    let nx = self.next[cur as usize];
                    self.next[cur as usize] = n;
                    self.prev[n as usize] = cur;
                    self.next[n as usize] = nx;
                    self.prev[nx as usize] = n;
                    self.loops[lid as usize].len += 1;
                    face.push(v);
                    cur = n;
                }
                Mid::Node(q) => {
                    let qu = q as usize;
                    let nx = self.next[cur as usize];
                    if !self.alive.get(qu).copied().unwrap_or(false) || q == cur || q == nx {
                        return Err("a face vertex refers to an unusable border node");
                    }
                    face.push(self.vert[qu]);
                    let lc = self.lp[cur as usize];
                    let lq = self.lp[qu];
                    if self.next[qu] == cur {
                        // The new edge cur→q is the twin of the border edge q→cur: both
                        // disappear, and so does `cur`'s gap (its node).
                        self.alive[cur as usize] = false;
                        self.next[qu] = nx;
                        self.prev[nx as usize] = q;
                        self.loops[lc as usize].len -= 1;
                        self.loops[lc as usize].head = q;
                        if let Some(last) = outgoing.last_mut() {
                            *last = None;
                        }
                        cur = q;
                        outgoing.push(Some(cur));
                        continue;
                    }
                    let q2 = self.new_node(self.vert[qu], lc);
                    let pq = self.prev[qu];
                    self.next[pq as usize] = q2;
                    self.prev[q2 as usize] = pq;
                    self.next[q2 as usize] = nx;
                    self.prev[nx as usize] = q2;
                    self.next[cur as usize] = q;
                    self.prev[qu] = cur;
                    if lc == lq {
                        // Split: q2's loop keeps the id, cur's loop gets a new one. Count
                        // both by walking them in lockstep; relabel the shorter.
                        let total = self.loops[lc as usize].len + 1;
                        let (mut a, mut c) = (q2, q);
                        let mut n = 1u32;
                        let short_is_q2 = loop {
                            a = self.next[a as usize];
                            c = self.next[c as usize];
                            if a == q2 {
                                break true;
                            }
                            if c == q {
                                break false;
                            }
                            n += 1;
                        };
                        let new_id = self.loops.len() as u32;
                        let (short, short_start) = if short_is_q2 { (n, q2) } else { (n, q) };
                        self.relabel(short_start, new_id);
                        self.loops.push(LoopInfo {
                            head: short_start,
                            len: short,
                        });
                        self.loops[lc as usize].len = total - short;
                        self.loops[lc as usize].head = if short_is_q2 { q } else { q2 };
                        self.active.push(new_id);
                    } else {
                        // Merge: one loop through both; relabel the shorter.
                        let (lc_len, lq_len) =
                            (self.loops[lc as usize].len, self.loops[lq as usize].len);
                        let (keep, drop) = if lc_len >= lq_len { (lc, lq) } else { (lq, lc) };
                        self.relabel(q2, keep);
                        self.loops[keep as usize].len = lc_len + lq_len + 1;
                        self.loops[keep as usize].head = q2;
                        self.kill_loop(drop);
                    }
                    cur = q2;
                }
            }
            outgoing.push(Some(cur));
        }
        face.extend(fwd_verts.iter().rev());
        Ok(Applied {
            face,
            outgoing,
            focus: Some(fw),
        })
    }
}

/// The two directions of the coder, so that one function describes the symbol flow.
trait BitIo {
    /// Codes (or decodes) a bit; returns the bit.
    fn bit(&mut self, ctx: &mut CountedBit, value: bool) -> bool;
    /// Codes (or decodes) an integer; returns it.
    fn uint(&mut self, model: &mut UInt<CountedBit>, value: u32) -> u32;
}

impl BitIo for Encoder {
    #[inline]
    fn bit(&mut self, ctx: &mut CountedBit, value: bool) -> bool {
        Encoder::bit(self, ctx, value);
        value
    }
    #[inline]
    fn uint(&mut self, model: &mut UInt<CountedBit>, value: u32) -> u32 {
        model.encode(self, value);
        value
    }
}

impl BitIo for Decoder<'_> {
    #[inline]
    fn bit(&mut self, ctx: &mut CountedBit, _: bool) -> bool {
        Decoder::bit(self, ctx)
    }
    #[inline]
    fn uint(&mut self, model: &mut UInt<CountedBit>, _: u32) -> u32 {
        model.decode(self)
    }
}

/// Faces counted in the "faces so far around a vertex" contexts.
const CNT_CAP: usize = 15;

/// The adaptive models.
struct Models {
    degree_same: [CountedBit; 3],
    degree: [UInt<CountedBit>; 3],
    fwd_first: Vec<CountedBit>,
    back_first: Vec<CountedBit>,
    fwd_more: [CountedBit; 12],
    back_more: [CountedBit; 12],
    closure: [CountedBit; 3],
    existing: [CountedBit; 3],
    dummy: CountedBit,
    same_loop: CountedBit,
    offset: UInt<CountedBit>,
    loop_index: UInt<CountedBit>,
}

impl Models {
    fn new() -> Self {
        Models {
            degree_same: [CountedBit::default(); 3],
            degree: [UInt::new(), UInt::new(), UInt::new()],
            fwd_first: vec![CountedBit::default(); 3 * 3 * 2 * (CNT_CAP + 1)],
            back_first: vec![CountedBit::default(); 3 * 3 * 2 * (CNT_CAP + 1)],
            fwd_more: [CountedBit::default(); 12],
            back_more: [CountedBit::default(); 12],
            closure: [CountedBit::default(); 3],
            existing: [CountedBit::default(); 3],
            dummy: CountedBit::default(),
            same_loop: CountedBit::default(),
            offset: UInt::new(),
            loop_index: UInt::new(),
        }
    }
}

fn degree_class(d: u32) -> usize {
    match d {
        3 => 0,
        4 => 1,
        _ => 2,
    }
}

/// The traversal state both directions share.
struct State {
    border: Border,
    /// Faces processed around each vertex (decoded ids).
    cnt: Vec<u32>,
    /// Whether each vertex (decoded id) is a dummy.
    dummy: Vec<bool>,
    /// Whether every face is a triangle (no degrees coded).
    all_triangles: bool,
    prev_degree: u32,
    /// Dummy vertices still to come.
    holes_left: u64,
    /// Valence (faces) of the last vertex completed.
    last_valence: u32,
    /// Whether `last_valence` is a context (meshes of [`VALENCE_CONTEXT_VERTICES`] or more).
    valence_context: bool,
}

/// Vertices (with the dummies) from which the last valence is a context.
pub(crate) const VALENCE_CONTEXT_VERTICES: u64 = 16_384;

/// The encoder's knowledge of a face.
#[derive(Default)]
struct Truth {
    d: u32,
    f: u32,
    b: u32,
    closure: bool,
    mids: Vec<TruthMid>,
}

#[derive(Clone, Copy)]
enum TruthMid {
    New { dummy: bool },
    Same { steps: u32 },
    Other { index: u32, steps: u32 },
}

/// The coded description of a face, with node references resolved.
struct Op {
    d: u32,
    f: u32,
    b: u32,
    closure: bool,
    /// `Ok(dummy)` for a new vertex, `Err(node)` for a border node.
    mids: Vec<std::result::Result<bool, u32>>,
}

/// Codes a face degree (the start face of a component, or a face across the gate).
fn code_degree<I: BitIo>(
    io: &mut I,
    m: &mut Models,
    st: &mut State,
    d: u32,
) -> std::result::Result<u32, &'static str> {
    if st.all_triangles {
        return Ok(3);
    }
    let c = degree_class(st.prev_degree);
    let d = if io.bit(&mut m.degree_same[c], d == st.prev_degree) {
        st.prev_degree
    } else {
        let x = io.uint(&mut m.degree[c], d.wrapping_sub(3));
        let d = x.checked_add(3).ok_or("face degree overflows")?;
        if d == st.prev_degree {
            return Err("face degree coded as different from the previous one but equal");
        }
        d
    };
    st.prev_degree = d;
    Ok(d)
}

/// The symbol flow of one face across the gate entering `h`: the same code encodes (from
/// `truth`) and decodes (ignoring it).
fn code_face<I: BitIo>(
    io: &mut I,
    m: &mut Models,
    st: &mut State,
    h: u32,
    truth: &Truth,
    max_degree: u64,
) -> std::result::Result<Op, &'static str> {
    let br = &st.border;
    let g = br.prev[h as usize];
    let (v, u) = (br.vert[h as usize], br.vert[g as usize]);
    let l = br.len_of(h);
    let (dv, du) = (st.dummy[v as usize], st.dummy[u as usize]);
    let d = if dv || du {
        3
    } else {
        code_degree(io, m, st, truth.d)?
    };
    if d < 3 || d as u64 > max_degree {
        return Err("face degree out of range");
    }
    let k = d - 2;
    let c = degree_class(d);
    // Large meshes: also in the context of the last completed vertex's valence (≤ 5, 6, ≥ 7;
    // Touma–Gotsman's observation that valences are locally correlated).
    let lv = if st.valence_context {
        (st.last_valence.clamp(5, 7) - 5) as usize
    } else {
        0
    };
    // Forward run (and closure).
    let mut f = 0u32;
    let mut closure = false;
    loop {
        if f == k {
            if l == d && io.bit(&mut m.closure[c], truth.closure) {
                closure = true;
            }
            break;
        }
        if f + 3 > l {
            break;
        }
        let ctx = if f == 0 {
            let cnt = (st.cnt[v as usize] as usize).min(CNT_CAP);
            &mut m.fwd_first[((lv * 3 + c) * 2 + dv as usize) * (CNT_CAP + 1) + cnt]
        } else {
            &mut m.fwd_more[c * 4 + (f as usize).min(3)]
        };
        if io.bit(ctx, truth.f > f) {
            if f == 0 && !dv {
                st.last_valence = st.cnt[v as usize] + 1;
            }
            f += 1;
        } else {
            break;
        }
    }
    if closure {
        return Ok(Op {
            d,
            f: k + 1,
            b: 0,
            closure,
            mids: Vec::new(),
        });
    }
    // Back run.
    let mut b = 0u32;
    while b < k - f && b + f + 3 <= l {
        let ctx = if b == 0 {
            let cnt = (st.cnt[u as usize] as usize).min(CNT_CAP);
            &mut m.back_first[((lv * 3 + c) * 2 + du as usize) * (CNT_CAP + 1) + cnt]
        } else {
            &mut m.back_more[c * 4 + (b as usize).min(3)]
        };
        if io.bit(ctx, truth.b > b) {
            if b == 0 && !du {
                st.last_valence = st.cnt[u as usize] + 1;
            }
            b += 1;
        } else {
            break;
        }
    }
    // Middle vertices.
    let nm = k - f - b;
    let mut mids = Vec::with_capacity(nm as usize);
    for i in 0..nm as usize {
        let t = truth
            .mids
            .get(i)
            .copied()
            .unwrap_or(TruthMid::New { dummy: false });
        let existing = io.bit(&mut m.existing[c], !matches!(t, TruthMid::New { .. }));
        if !existing {
            let dummy = if st.holes_left > 0 && !dv && !du {
                io.bit(&mut m.dummy, matches!(t, TruthMid::New { dummy: true }))
            } else {
                false
            };
            if dummy {
                st.holes_left -= 1;
            }
            mids.push(Ok(dummy));
            continue;
        }
        let br = &st.border;
        let same = io.bit(&mut m.same_loop, matches!(t, TruthMid::Same { .. }));
        let node = if same {
            let steps = match t {
                TruthMid::Same { steps } => steps,
                _ => 0,
            };
            let s = io.uint(&mut m.offset, steps.wrapping_sub(1)) as u64 + 1;
            if s >= l as u64 {
                return Err("split offset beyond the border's length");
            }
            let mut n = h;
            for _ in 0..s {
                n = br.next[n as usize];
            }
            n
        } else {
            let (index, steps) = match t {
                TruthMid::Other { index, steps } => (index, steps),
                _ => (0, 0),
            };
            let i = io.uint(&mut m.loop_index, index) as usize;
            let Some(&lid) = br.active.get(i) else {
                return Err("merge refers to a border that does not exist");
            };
            if lid == br.lp[h as usize] {
                return Err("merge refers to the current border");
            }
            let info = br.loops[lid as usize];
            let s = io.uint(&mut m.offset, steps);
            if s >= info.len {
                return Err("merge offset beyond the border's length");
            }
            let mut n = info.head;
            for _ in 0..s {
                n = br.next[n as usize];
            }
            n
        };
        mids.push(Err(node));
    }
    Ok(Op {
        d,
        f,
        b,
        closure,
        mids,
    })
}

/// What the encoder produces besides the bits.
pub(crate) struct EncodedConnectivity {
    /// Decoded referenced vertex `i` is input vertex `vertex_map[i]`.
    pub vertex_map: Vec<u32>,
    /// Decoded face `i` is input face `face_map[i]`.
    pub face_map: Vec<u32>,
    /// Decoded faces.
    pub face_offsets: Vec<u32>,
    /// Decoded faces.
    pub face_indices: Vec<u32>,
    /// Boundary loops (dummy vertices).
    pub holes: usize,
    /// Faces including the dummy fans.
    pub augmented_faces: usize,
    /// Connected components.
    pub components: usize,
}

/// Counts the decoder checks the stream against.
pub(crate) struct Declared {
    /// Referenced vertices.
    pub vertices: u64,
    /// Faces.
    pub faces: u64,
    /// Face corners.
    pub corners: u64,
    /// Holes (dummy vertices).
    pub holes: u64,
    /// Faces including dummy fans.
    pub augmented_faces: u64,
    /// Components.
    pub components: u64,
}

/// The decoded connectivity.
pub(crate) struct DecodedConnectivity {
    /// Faces, decoded vertex ids.
    pub face_offsets: Vec<u32>,
    /// Faces, decoded vertex ids.
    pub face_indices: Vec<u32>,
}

/// Output tables in decoded ids, shared by both directions.
struct Output {
    offsets: Vec<u32>,
    indices: Vec<u32>,
    next_vertex: u32,
}

impl Output {
    fn push_face(&mut self, face: &[u32]) {
        self.indices.extend_from_slice(face);
        self.offsets.push(self.indices.len() as u32);
    }
}

/// Drops dummy vertices and their faces: returns the real faces (renumbered) and, for each
/// kept augmented face, its augmented index.
fn strip_dummies(out: &Output, dummy: &[bool]) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let mut rank = vec![NONE; dummy.len()];
    let mut n = 0u32;
    for (v, &d) in dummy.iter().enumerate() {
        if !d {
            rank[v] = n;
            n += 1;
        }
    }
    let mut offsets = vec![0u32];
    let mut indices = Vec::with_capacity(out.indices.len());
    let mut kept = Vec::new();
    for (f, w) in out.offsets.windows(2).enumerate() {
        let fv = &out.indices[w[0] as usize..w[1] as usize];
        if fv.iter().all(|&v| !dummy[v as usize]) {
            indices.extend(fv.iter().map(|&v| rank[v as usize]));
            offsets.push(indices.len() as u32);
            kept.push(f as u32);
        }
    }
    (offsets, indices, kept)
}

/// Encodes the connectivity of `mesh` (a consistently oriented 2-manifold: the caller has
/// checked it) into `enc`.
pub(crate) fn encode(mesh: &Mesh, enc: &mut Encoder) -> Result<EncodedConnectivity> {
    let internal = |what: &str| {
        Error::InvalidArgument(format!(
            "base-mesh connectivity encoder: {what} (is the mesh a 2-manifold?)"
        ))
    };
    let nv = mesh.num_vertices();
    let nf = mesh.num_faces();
    // Close the holes: one dummy vertex per boundary loop, a triangle fan onto it.
    let real = HalfEdges::build(&mesh.face_offsets, &mesh.face_indices);
    let mut hole_out = vec![NONE; nv];
    let mut boundary_starts = Vec::new();
    for c in 0..mesh.face_indices.len() {
        if real.twin[c] == NONE {
            let a = mesh.face_indices[c];
            let b = mesh.face_indices[real.next[c] as usize];
            hole_out[b as usize] = a;
            boundary_starts.push(b);
        }
    }
    let mut aug_offsets = mesh.face_offsets.clone();
    let mut aug_indices = mesh.face_indices.clone();
    let mut holes = 0u32;
    let mut in_hole = vec![false; nv];
    for &s in &boundary_starts {
        if in_hole[s as usize] {
            continue;
        }
        let dv = nv as u32 + holes;
        holes += 1;
        let mut p = s;
        loop {
            in_hole[p as usize] = true;
            let q = hole_out[p as usize];
            if q == NONE {
                return Err(internal("open boundary loop"));
            }
            aug_indices.extend_from_slice(&[p, q, dv]);
            aug_offsets.push(aug_indices.len() as u32);
            p = q;
            if p == s {
                break;
            }
            if in_hole[p as usize] {
                return Err(internal("boundary loops touch"));
            }
        }
    }
    let naug_v = nv + holes as usize;
    let naug_f = aug_offsets.len() - 1;
    let he = HalfEdges::build(&aug_offsets, &aug_indices);
    if he.twin.contains(&NONE) {
        return Err(internal(
            "an edge without its opposite half-edge after closing holes",
        ));
    }

    let mut st = State {
        border: Border::default(),
        cnt: Vec::with_capacity(naug_v),
        dummy: Vec::with_capacity(naug_v),
        all_triangles: mesh.is_triangle_mesh(),
        prev_degree: 3,
        holes_left: holes as u64,
        last_valence: 6,
        // Referenced vertices and dummies: what the decoder knows.
        valence_context: (mesh.referenced().iter().filter(|&&r| r).count() + holes as usize) as u64
            >= VALENCE_CONTEXT_VERTICES,
    };
    let mut m = Models::new();
    enc.bit(&mut CountedBit::default(), st.all_triangles);
    let mut out = Output {
        offsets: vec![0],
        indices: Vec::with_capacity(aug_indices.len()),
        next_vertex: 0,
    };
    let mut dec_id = vec![NONE; naug_v];
    let mut order: Vec<u32> = Vec::with_capacity(naug_v);
    let mut aug_face_order: Vec<u32> = Vec::with_capacity(naug_f);
    let mut processed = vec![false; naug_f];
    let mut node_out_corner: Vec<u32> = Vec::new();
    let mut node_of_corner = vec![NONE; aug_indices.len()];
    let mut components = 0usize;
    let max_degree = u64::MAX;

    let new_vertex = |st: &mut State,
                      out: &mut Output,
                      dec_id: &mut Vec<u32>,
                      order: &mut Vec<u32>,
                      input: u32,
                      dummy: bool|
     -> u32 {
        let id = out.next_vertex;
        out.next_vertex += 1;
        dec_id[input as usize] = id;
        order.push(input);
        st.cnt.push(0);
        st.dummy.push(dummy);
        id
    };

    for start in 0..nf {
        if processed[start] {
            continue;
        }
        components += 1;
        let (a, b) = (aug_offsets[start] as usize, aug_offsets[start + 1] as usize);
        code_degree(enc, &mut m, &mut st, (b - a) as u32).map_err(internal)?;
        let mut verts = Vec::with_capacity(b - a);
        for &x in &aug_indices[a..b] {
            verts.push(new_vertex(
                &mut st,
                &mut out,
                &mut dec_id,
                &mut order,
                x,
                false,
            ));
        }
        let nodes = st.border.start_loop(&verts);
        node_out_corner.resize(st.border.vert.len(), NONE);
        for (i, c) in (a..b).enumerate() {
            node_out_corner[nodes[i] as usize] = c as u32;
            node_of_corner[c] = nodes[i];
            st.cnt[verts[i] as usize] += 1;
        }
        processed[start] = true;
        out.push_face(&verts);
        aug_face_order.push(start as u32);
        let mut focus = Some(nodes[1]);
        while let Some(h) = focus {
            let br = &st.border;
            let g = br.prev[h as usize];
            let cg = node_out_corner[g as usize];
            let ct = he.twin[cg as usize];
            let gf = he.face[ct as usize] as usize;
            if processed[gf] {
                return Err(internal("gate face already processed"));
            }
            // Corners of the face from the focus: v, u, w1..wk.
            let mut cs = Vec::with_capacity(8);
            let mut c = ct;
            loop {
                cs.push(c);
                c = he.next[c as usize];
                if c == ct {
                    break;
                }
            }
            let d = cs.len() as u32;
            let k = d - 2;
            let matched = |c: u32| processed[he.face[he.twin[c as usize] as usize] as usize];
            // e_j is corner cs[1 + j].
            let mut t = Truth {
                d,
                ..Truth::default()
            };
            let mut n = h;
            while t.f <= k && matched(cs[(1 + k - t.f) as usize]) {
                if node_of_corner[he.twin[cs[(1 + k - t.f) as usize] as usize] as usize] != n {
                    return Err(internal("forward run leaves the border"));
                }
                n = br.next[n as usize];
                t.f += 1;
            }
            if t.f == k + 1 {
                t.closure = true;
            } else {
                let mut n = br.prev[h as usize];
                while t.b < k - t.f && matched(cs[(1 + t.b) as usize]) {
                    let tw = he.twin[cs[(1 + t.b) as usize] as usize];
                    if br.next[node_of_corner[tw as usize] as usize] != n {
                        return Err(internal("back run leaves the border"));
                    }
                    n = br.prev[n as usize];
                    t.b += 1;
                }
                for j in (t.b + 1)..=(k - t.f) {
                    let cw = cs[(1 + j) as usize];
                    let w = aug_indices[cw as usize];
                    if dec_id[w as usize] == NONE {
                        t.mids.push(TruthMid::New {
                            dummy: w as usize >= nv,
                        });
                        continue;
                    }
                    // Rotate around w through unprocessed faces to its border occurrence.
                    let mut c = cw;
                    let mut q = NONE;
                    for _ in 0..aug_indices.len() {
                        let tw = he.twin[c as usize];
                        if processed[he.face[tw as usize] as usize] {
                            q = br.next[node_of_corner[tw as usize] as usize];
                            break;
                        }
                        c = he.next[tw as usize];
                    }
                    if q == NONE || !br.alive[q as usize] {
                        return Err(internal("split vertex not on the border"));
                    }
                    if br.lp[q as usize] == br.lp[h as usize] {
                        let mut s = 0u32;
                        let mut n = h;
                        while n != q {
                            n = br.next[n as usize];
                            s += 1;
                        }
                        t.mids.push(TruthMid::Same { steps: s });
                    } else {
                        let lid = br.lp[q as usize];
                        let index = br.active.iter().position(|&x| x == lid).unwrap_or(0) as u32;
                        let mut s = 0u32;
                        let mut n = br.loops[lid as usize].head;
                        while n != q {
                            n = br.next[n as usize];
                            s += 1;
                        }
                        t.mids.push(TruthMid::Other { index, steps: s });
                    }
                }
            }
            let op = code_face(enc, &mut m, &mut st, h, &t, max_degree).map_err(internal)?;
            if op.f != t.f || op.b != t.b || op.closure != t.closure || op.d != t.d {
                return Err(internal("face description not codable"));
            }
            let mut mids = Vec::with_capacity(op.mids.len());
            for (i, mm) in op.mids.iter().enumerate() {
                match *mm {
                    Ok(dummy) => {
                        let w = aug_indices[cs[(2 + op.b as usize) + i] as usize];
                        let id = new_vertex(&mut st, &mut out, &mut dec_id, &mut order, w, dummy);
                        mids.push(Mid::New(id));
                    }
                    Err(node) => mids.push(Mid::Node(node)),
                }
            }
            let ap = st
                .border
                .apply(h, op.d, op.f, op.b, op.closure, &mids)
                .map_err(internal)?;
            for (i, &node) in ap.outgoing.iter().enumerate() {
                let Some(node) = node else { continue };
                let c = cs[(1 + op.b as usize) + i];
                node_out_corner.resize(st.border.vert.len(), NONE);
                node_out_corner[node as usize] = c;
                node_of_corner[c as usize] = node;
            }
            // Nodes created by splits/merges that are not on `outgoing` keep their corner:
            // the copy q2 continues the path (on `outgoing`); the original q keeps its
            // outgoing edge, but q2 took q's place for the incoming one, which is fine since
            // node_of_corner maps edges by their start node.
            for &x in &ap.face {
                st.cnt[x as usize] += 1;
            }
            debug_assert!(
                ap.face
                    .iter()
                    .zip(&cs)
                    .all(|(&x, &c)| order[x as usize] == aug_indices[c as usize]),
                "face {:?} vs {:?} op f={} b={} closure={}",
                ap.face
                    .iter()
                    .map(|&x| order[x as usize])
                    .collect::<Vec<_>>(),
                cs.iter()
                    .map(|&c| aug_indices[c as usize])
                    .collect::<Vec<_>>(),
                op.f,
                op.b,
                op.closure
            );
            processed[gf] = true;
            out.push_face(&ap.face);
            aug_face_order.push(gf as u32);
            focus = ap.focus.or_else(|| {
                st.border
                    .active
                    .last()
                    .map(|&l| st.border.loops[l as usize].head)
            });
        }
    }
    let (face_offsets, face_indices, kept) = strip_dummies(&out, &st.dummy);
    let vertex_map: Vec<u32> = order
        .iter()
        .copied()
        .filter(|&v| (v as usize) < nv)
        .collect();
    let face_map = kept.iter().map(|&f| aug_face_order[f as usize]).collect();
    Ok(EncodedConnectivity {
        vertex_map,
        face_map,
        face_offsets,
        face_indices,
        holes: holes as usize,
        augmented_faces: naug_f,
        components,
    })
}

/// Decodes the connectivity chunk.
pub(crate) fn decode(
    dec: &mut Decoder,
    declared: &Declared,
) -> std::result::Result<DecodedConnectivity, ChunkError> {
    let aug_vertices = declared.vertices + declared.holes;
    let aug_corners = declared.corners + 3 * (declared.augmented_faces - declared.faces);
    let cap = |n: u64| n.min(1 << 20) as usize;
    let mut st = State {
        border: Border::default(),
        cnt: Vec::with_capacity(cap(aug_vertices)),
        dummy: Vec::with_capacity(cap(aug_vertices)),
        all_triangles: false,
        prev_degree: 3,
        holes_left: declared.holes,
        last_valence: 6,
        valence_context: aug_vertices >= VALENCE_CONTEXT_VERTICES,
    };
    let mut m = Models::new();
    st.all_triangles = dec.bit(&mut CountedBit::default());
    let mut out = Output {
        offsets: Vec::with_capacity(cap(declared.augmented_faces + 1)),
        indices: Vec::with_capacity(cap(aug_corners)),
        next_vertex: 0,
    };
    out.offsets.push(0);
    let truth = Truth::default();
    let err = |dec: &Decoder, what: &str| ChunkError::new(dec, what);
    for _ in 0..declared.components {
        let left = aug_corners - out.indices.len() as u64;
        let d = code_degree(dec, &mut m, &mut st, 0).map_err(|e| err(dec, e))?;
        if d < 3 || d as u64 > left || out.next_vertex as u64 + d as u64 > aug_vertices {
            return Err(err(dec, "component start face: degree out of range"));
        }
        let verts: Vec<u32> = (out.next_vertex..out.next_vertex + d).collect();
        out.next_vertex += d;
        st.cnt.extend(std::iter::repeat_n(1, d as usize));
        st.dummy.extend(std::iter::repeat_n(false, d as usize));
        let nodes = st.border.start_loop(&verts);
        out.push_face(&verts);
        let mut focus = Some(nodes[1]);
        while let Some(h) = focus {
            if dec.truncated() {
                return Err(err(dec, "the stream ends early"));
            }
            if out.offsets.len() as u64 > declared.augmented_faces {
                return Err(err(dec, "more faces than the header declares"));
            }
            let left = aug_corners - out.indices.len() as u64;
            let op = code_face(dec, &mut m, &mut st, h, &truth, left).map_err(|e| err(dec, e))?;
            let mut mids = Vec::with_capacity(op.mids.len());
            for mm in &op.mids {
                match *mm {
                    Ok(dummy) => {
                        if out.next_vertex as u64 >= aug_vertices {
                            return Err(err(dec, "more vertices than the header declares"));
                        }
                        let id = out.next_vertex;
                        out.next_vertex += 1;
                        st.cnt.push(0);
                        st.dummy.push(dummy);
                        mids.push(Mid::New(id));
                    }
                    Err(node) => mids.push(Mid::Node(node)),
                }
            }
            let ap = st
                .border
                .apply(h, op.d, op.f, op.b, op.closure, &mids)
                .map_err(|e| err(dec, e))?;
            for &x in &ap.face {
                st.cnt[x as usize] += 1;
            }
            out.push_face(&ap.face);
            focus = ap.focus.or_else(|| {
                st.border
                    .active
                    .last()
                    .map(|&l| st.border.loops[l as usize].head)
            });
        }
    }
    if dec.truncated() {
        return Err(err(dec, "the stream ends early"));
    }
    let nfaces = out.offsets.len() as u64 - 1;
    if out.next_vertex as u64 != aug_vertices
        || nfaces != declared.augmented_faces
        || st.holes_left != 0
    {
        return Err(err(
            dec,
            "decoded vertex, face or hole counts differ from the header's",
        ));
    }
    let (face_offsets, face_indices, _) = strip_dummies(&out, &st.dummy);
    if face_offsets.len() as u64 - 1 != declared.faces
        || face_indices.len() as u64 != declared.corners
    {
        return Err(err(
            dec,
            "decoded face or corner counts differ from the header's",
        ));
    }
    Ok(DecodedConnectivity {
        face_offsets,
        face_indices,
    })
}

//! SPIHT (Set Partitioning In Hierarchical Trees) over an offspring [`Forest`].
//!
//! Maret 2003 §4.4.2, Algorithm 1 (after Said & Pearlman 1996): three ordered lists, LIC
//! (insignificant coefficients), LIS (insignificant sets: type A = the descendants `D(c)`,
//! type B = `L(c) = D(c) − O(c)`) and LSC (significant coefficients); per bit plane `n` a
//! sorting pass (significance `S_n` of LIC entries, then of LIS sets, splitting significant
//! sets) and a refinement pass (bit `n` of every coefficient of the LSC *except those that
//! became significant in this plane's sorting pass*, whose bit is known to be 1).
//!
//! The lists hold *entries* `3·node + component`: the three components are coded by the same
//! passes (the AFX stream of §4.4.2 interleaves them the same way), each with its own top
//! plane (`top[c]`, the highest plane in which component `c` has a set bit; entries of
//! component `c` are skipped in the planes above it). With
//! [`ComponentMode::Independent`](super::quantize::ComponentMode) steps this is AFX's
//! independent per-component SPIHT; with aligned steps the planes follow the squared error
//! across components (§4.5.3).
//!
//! Type-A entries are only made for nodes with offspring and type-B entries only when
//! `L(c)` is not empty (line 22 of Algorithm 1), so no bit is spent on empty sets.
//!
//! # Entropy coding
//! Every decision goes through the adaptive binary range coder
//! ([`super::rangecoder`]). With `contexts = true` (the default of the codec) significance,
//! sign and refinement bits use adaptive contexts ("context-adaptive arithmetic coding" of
//! Maret §4.5): significance per component, level of the node, kind of test (LIC
//! coefficient, offspring of a just-split set, type-A set, type-B set) and whether a
//! component of the same node was significant in an earlier plane; signs and refinement bits per component
//! and level. With `contexts = false` every bit is coded raw (probability ½), i.e. the plain
//! SPIHT bit stream.
//!
//! # Prefixes
//! The decoder stops at the first decision that needs a byte the stream does not have
//! ([`Decoder::truncated`]); every coefficient then holds what the exact decisions before it
//! said (its interval `[lo, lo + 2^w)` and sign, or insignificant).

use super::forest::Forest;
use super::rangecoder::{Bit, Decoder, Encoder};

/// The type-B flag of an LIS entry.
const TYPE_B: u32 = 1 << 31;
/// Levels with their own contexts (deeper levels share the last).
const CTX_LEVELS: usize = 12;
/// "Not significant" in [`Coefficients::width`].
pub const INSIGNIFICANT: u8 = u8::MAX;

/// Largest number of forest nodes the coder accepts (entries `3·node + c` and the type-B
/// flag must fit in `u32`).
pub const MAX_NODES: usize = (1 << 29) - 1;

/// The adaptive contexts of one SPIHT stream.
#[derive(Clone, Debug)]
struct Contexts {
    on: bool,
    /// [kind][other component significant][component][level]
    sig: Vec<Bit>,
    /// [component][level]
    sign: Vec<Bit>,
    /// [component][level]
    refine: Vec<Bit>,
}

/// Kinds of significance test.
#[derive(Clone, Copy)]
enum Test {
    Lic = 0,
    Offspring = 1,
    SetA = 2,
    SetB = 3,
}

impl Contexts {
    fn new(on: bool) -> Self {
        Contexts {
            on,
            sig: vec![Bit::new(); 4 * 2 * 3 * CTX_LEVELS],
            sign: vec![Bit::new(); 3 * CTX_LEVELS],
            refine: vec![Bit::new(); 3 * CTX_LEVELS],
        }
    }

    #[inline]
    fn sig_index(test: Test, other: bool, c: usize, level: u8) -> usize {
        let l = (level as usize).min(CTX_LEVELS - 1);
        (((test as usize) * 2 + other as usize) * 3 + c) * CTX_LEVELS + l
    }

    #[inline]
    fn cl(c: usize, level: u8) -> usize {
        c * CTX_LEVELS + (level as usize).min(CTX_LEVELS - 1)
    }
}

/// The quantized coefficients an encoder codes: magnitudes and signs per entry
/// (`3·node + component`), with the maxima over descendant sets.
#[derive(Clone, Debug)]
pub struct Magnitudes {
    mag: Vec<u32>,
    neg: Vec<bool>,
    /// max over `D(c)` per entry.
    dmax: Vec<u32>,
    /// max over `L(c)` per entry.
    lmax: Vec<u32>,
    /// Top plane per component (−1: all zero).
    pub top: [i32; 3],
}

impl Magnitudes {
    /// Magnitudes `mag` and signs `neg` (`neg[i]` true for negative) of entries
    /// `3·node + c` of `forest`.
    ///
    /// # Panics
    /// If the lengths are not `3 · forest.num_nodes`.
    pub fn new(forest: &Forest, mag: Vec<u32>, neg: Vec<bool>) -> Magnitudes {
        assert_eq!(mag.len(), 3 * forest.num_nodes);
        assert_eq!(neg.len(), mag.len());
        let mut dmax = vec![0u32; mag.len()];
        let mut lmax = vec![0u32; mag.len()];
        for n in (0..forest.num_nodes).rev() {
            for c in 0..3 {
                let mut d = 0u32;
                let mut l = 0u32;
                for &k in forest.offspring(n) {
                    let k = 3 * k as usize + c;
                    d = d.max(mag[k]).max(dmax[k]);
                    l = l.max(dmax[k]);
                }
                dmax[3 * n + c] = d;
                lmax[3 * n + c] = l;
            }
        }
        let mut top = [-1i32; 3];
        for (i, &m) in mag.iter().enumerate() {
            if m > 0 {
                let t = 31 - m.leading_zeros() as i32;
                let c = i % 3;
                top[c] = top[c].max(t);
            }
        }
        Magnitudes {
            mag,
            neg,
            dmax,
            lmax,
            top,
        }
    }
}

/// The number of bit planes of a stream with top planes `top` (0 if every coefficient is
/// zero).
pub fn num_planes(top: [i32; 3]) -> u32 {
    (top.iter().copied().max().unwrap_or(-1) + 1).max(0) as u32
}

/// The shared list state of an encoder or decoder.
#[derive(Clone, Debug)]
struct Lists {
    lic: Vec<u32>,
    lis: Vec<u32>,
    lsc: Vec<u32>,
    /// The plane of the next pass.
    plane: i32,
    top: [i32; 3],
    ctx: Contexts,
}

impl Lists {
    fn new(forest: &Forest, roots: &[u32], top: [i32; 3], contexts: bool) -> Lists {
        let lists = (
            Vec::with_capacity(roots.len() * 3),
            Vec::with_capacity(roots.len() * 3),
            Vec::new(),
        );
        Lists::in_memory(forest, roots, top, contexts, lists)
    }

    /// [`Lists::new`] in the memory of the (cleared) vectors `lists` (LIC, LIS, LSC).
    fn in_memory(
        forest: &Forest,
        roots: &[u32],
        top: [i32; 3],
        contexts: bool,
        (mut lic, mut lis, mut lsc): (Vec<u32>, Vec<u32>, Vec<u32>),
    ) -> Lists {
        lic.clear();
        lis.clear();
        lsc.clear();
        for &r in roots {
            for c in 0..3u32 {
                lic.push(3 * r + c);
                if !forest.offspring(r as usize).is_empty() {
                    lis.push(3 * r + c);
                }
            }
        }
        Lists {
            lic,
            lis,
            lsc,
            plane: top.iter().copied().max().unwrap_or(-1),
            top,
            ctx: Contexts::new(contexts),
        }
    }
}

/// Whether `L(n)` is not empty (some offspring has offspring).
#[inline]
fn has_grandchildren(forest: &Forest, n: usize) -> bool {
    forest.level[n] as usize + 2 < forest.levels
}

/// SPIHT encoder state over one set of roots (the whole forest, or one tree).
#[derive(Clone, Debug)]
pub struct SpihtEncoder<'a> {
    forest: &'a Forest,
    m: &'a Magnitudes,
    lists: Lists,
}

impl<'a> SpihtEncoder<'a> {
    /// An encoder of the trees rooted at `roots` (node ids `< forest.num_trees`).
    pub fn new(forest: &'a Forest, m: &'a Magnitudes, roots: &[u32], contexts: bool) -> Self {
        SpihtEncoder {
            forest,
            m,
            lists: Lists::new(forest, roots, m.top, contexts),
        }
    }

    /// The plane the next [`SpihtEncoder::code_plane`] codes (−1 when done).
    pub fn plane(&self) -> i32 {
        self.lists.plane
    }

    #[inline]
    fn put_sig(&mut self, enc: &mut Encoder, test: Test, e: usize, bit: bool) {
        let ctx = &mut self.lists.ctx;
        if ctx.on {
            let level = self.forest.level[e / 3];
            // Some component of the node significant in an earlier plane.
            let b = e - e % 3;
            let thr2 = 2u64 << self.lists.plane;
            let other = self.m.mag[b..b + 3].iter().any(|&x| x as u64 >= thr2);
            enc.bit(
                &mut ctx.sig[Contexts::sig_index(test, other, e % 3, level)],
                bit,
            );
        } else {
            enc.raw(bit as u32, 1);
        }
    }

    #[inline]
    fn put_sign(&mut self, enc: &mut Encoder, e: usize) {
        let bit = self.m.neg[e];
        let ctx = &mut self.lists.ctx;
        if ctx.on {
            let level = self.forest.level[e / 3];
            enc.bit(&mut ctx.sign[Contexts::cl(e % 3, level)], bit);
        } else {
            enc.raw(bit as u32, 1);
        }
    }

    /// Codes the sorting and refinement passes of the current plane; returns `false` (and
    /// codes nothing) when every plane is done.
    pub fn code_plane(&mut self, enc: &mut Encoder) -> bool {
        let n = self.lists.plane;
        if n < 0 {
            return false;
        }
        let thr = 1u32 << n;
        let top = self.lists.top;
        let lsc_before = self.lists.lsc.len();
        // LIC.
        let lic = std::mem::take(&mut self.lists.lic);
        let mut keep = Vec::with_capacity(lic.len());
        for &e in &lic {
            let e = e as usize;
            if top[e % 3] < n {
                keep.push(e as u32);
                continue;
            }
            let s = self.m.mag[e] >= thr;
            self.put_sig(enc, Test::Lic, e, s);
            if s {
                self.put_sign(enc, e);
                self.lists.lsc.push(e as u32);
            } else {
                keep.push(e as u32);
            }
        }
        self.lists.lic = keep;
        // LIS (entries appended during the pass are processed in the same pass).
        let mut i = 0;
        let mut out: Vec<u32> = Vec::with_capacity(self.lists.lis.len());
        while i < self.lists.lis.len() {
            let entry = self.lists.lis[i];
            i += 1;
            let e = (entry & !TYPE_B) as usize;
            let (node, c) = (e / 3, e % 3);
            if top[c] < n {
                out.push(entry);
                continue;
            }
            if entry & TYPE_B == 0 {
                let s = self.m.dmax[e] >= thr;
                self.put_sig(enc, Test::SetA, e, s);
                if s {
                    for &k in self.forest.offspring(node) {
                        let ke = 3 * k as usize + c;
                        let sk = self.m.mag[ke] >= thr;
                        self.put_sig(enc, Test::Offspring, ke, sk);
                        if sk {
                            self.put_sign(enc, ke);
                            self.lists.lsc.push(ke as u32);
                        } else {
                            self.lists.lic.push(ke as u32);
                        }
                    }
                    if has_grandchildren(self.forest, node) {
                        self.lists.lis.push(e as u32 | TYPE_B);
                    }
                } else {
                    out.push(entry);
                }
            } else {
                let s = self.m.lmax[e] >= thr;
                self.put_sig(enc, Test::SetB, e, s);
                if s {
                    for &k in self.forest.offspring(node) {
                        self.lists.lis.push(3 * k + c as u32);
                    }
                } else {
                    out.push(entry);
                }
            }
        }
        self.lists.lis = out;
        // Refinement.
        let ctx = &mut self.lists.ctx;
        for &e in &self.lists.lsc[..lsc_before] {
            let e = e as usize;
            let bit = (self.m.mag[e] >> n) & 1 != 0;
            if ctx.on {
                let level = self.forest.level[e / 3];
                enc.bit(&mut ctx.refine[Contexts::cl(e % 3, level)], bit);
            } else {
                enc.raw(bit as u32, 1);
            }
        }
        self.lists.plane -= 1;
        true
    }
}

/// The decoder's knowledge of every coefficient entry: magnitude interval `[lo, lo + 2^w)`
/// (`w = INSIGNIFICANT` while not significant) and sign.
#[derive(Clone, Debug, Default)]
pub struct Coefficients {
    /// Lower end of the magnitude interval.
    pub lo: Vec<u32>,
    /// log2 of the interval width, or [`INSIGNIFICANT`].
    pub width: Vec<u8>,
    /// Sign (true: negative).
    pub neg: Vec<bool>,
    /// Per node: 1 + the plane in which its first component became significant, 0 while
    /// none is (the significance contexts' "other component significant in an earlier
    /// plane", one byte instead of three widths).
    first: Vec<u8>,
}

impl Coefficients {
    /// All entries of `forest` insignificant.
    pub fn new(forest: &Forest) -> Self {
        let n = 3 * forest.num_nodes;
        Coefficients {
            lo: vec![0; n],
            width: vec![INSIGNIFICANT; n],
            neg: vec![false; n],
            first: vec![0; forest.num_nodes],
        }
    }

    /// [`Coefficients::new`] in this value's memory: every entry of `forest` insignificant.
    pub fn reset(&mut self, forest: &Forest) {
        let n = 3 * forest.num_nodes;
        self.lo.clear();
        self.lo.resize(n, 0);
        self.width.clear();
        self.width.resize(n, INSIGNIFICANT);
        self.neg.clear();
        self.neg.resize(n, false);
        self.first.clear();
        self.first.resize(forest.num_nodes, 0);
    }

    /// Resets the entries of the nodes in `nodes` to insignificant (removing a tree).
    pub fn clear_nodes(&mut self, nodes: impl Iterator<Item = usize>) {
        for n in nodes {
            for e in 3 * n..3 * n + 3 {
                self.lo[e] = 0;
                self.width[e] = INSIGNIFICANT;
                self.neg[e] = false;
            }
            self.first[n] = 0;
        }
    }
}

/// SPIHT decoder state over one set of roots.
#[derive(Clone, Debug)]
pub struct SpihtDecoder<'a> {
    forest: &'a Forest,
    lists: Lists,
    /// The refinement context of each LSC entry (parallel to `lists.lsc`).
    lsc_ctx: Vec<u8>,
}

/// The list memory of a [`SpihtDecoder`], handed from one decoder to the next
/// ([`SpihtDecoder::in_memory`], [`SpihtDecoder::into_memory`]) so that repeated decodes do
/// not allocate (and fault in) their lists again.
#[derive(Clone, Debug, Default)]
pub struct SpihtMemory {
    lic: Vec<u32>,
    lis: Vec<u32>,
    lsc: Vec<u32>,
    lsc_ctx: Vec<u8>,
}

impl<'a> SpihtDecoder<'a> {
    /// A decoder of the trees rooted at `roots`, with the stream's top planes.
    pub fn new(forest: &'a Forest, roots: &[u32], top: [i32; 3], contexts: bool) -> Self {
        Self::in_memory(forest, roots, top, contexts, SpihtMemory::default())
    }

    /// [`SpihtDecoder::new`] with its lists in `memory` (whatever they held is dropped;
    /// their capacity is kept).
    pub fn in_memory(
        forest: &'a Forest,
        roots: &[u32],
        top: [i32; 3],
        contexts: bool,
        memory: SpihtMemory,
    ) -> Self {
        let SpihtMemory {
            lic,
            lis,
            lsc,
            mut lsc_ctx,
        } = memory;
        let mut lists = Lists::in_memory(forest, roots, top, contexts, (lic, lis, lsc));
        lsc_ctx.clear();
        if roots.len() == forest.num_trees {
            // The whole forest: reserve the lists' largest sizes once (address space only;
            // no copies while they grow).
            let n = 3 * forest.num_nodes;
            lists.lic.reserve(n);
            lists.lis.reserve(n);
            lists.lsc.reserve(n);
            lsc_ctx.reserve(n);
        }
        SpihtDecoder {
            forest,
            lists,
            lsc_ctx,
        }
    }

    /// The plane the next [`SpihtDecoder::decode_plane`] decodes (−1 when done).
    pub fn plane(&self) -> i32 {
        self.lists.plane
    }

    /// The decoder's list memory, for the next decoder ([`SpihtDecoder::in_memory`]).
    pub fn into_memory(self) -> SpihtMemory {
        SpihtMemory {
            lic: self.lists.lic,
            lis: self.lists.lis,
            lsc: self.lists.lsc,
            lsc_ctx: self.lsc_ctx,
        }
    }

    /// Decodes the current plane into `out`. Returns `false` if the stream ended before the
    /// plane was complete (the state is then that of the exact decisions decoded; decoding
    /// must not continue) or if every plane is done.
    ///
    /// # Panics
    /// If `out` was not made for this decoder's forest ([`Coefficients::new`]).
    pub fn decode_plane(&mut self, dec: &mut Decoder, out: &mut Coefficients) -> bool {
        assert_eq!(
            out.lo.len(),
            3 * self.forest.num_nodes,
            "coefficients of another forest"
        );
        if self.lists.ctx.on {
            self.decode_passes::<true>(dec, out)
        } else {
            self.decode_passes::<false>(dec, out)
        }
    }

    /// [`SpihtDecoder::decode_plane`] with contexts on (`ON`) or raw bits: the passes of
    /// Algorithm 1 in the encoder's order, with the per-decision work kept small (one
    /// division per entry, branch-free range decoding and refinement).
    #[inline(never)]
    fn decode_passes<const ON: bool>(&mut self, dec: &mut Decoder, out: &mut Coefficients) -> bool {
        // The coder's state in locals (registers) for the whole pass, written back on return:
        // through `dec`, every decision would store and reload it.
        let mut d = *dec;
        let done = self.decode_passes_with::<ON>(&mut d, out);
        *dec = d;
        done
    }

    #[inline(always)]
    fn decode_passes_with<const ON: bool>(
        &mut self,
        dec: &mut Decoder,
        out: &mut Coefficients,
    ) -> bool {
        let n = self.lists.plane;
        if n < 0 {
            return false;
        }
        let thr = 1u32 << n;
        let nb = n as u8;
        let top = self.lists.top;
        let active = [top[0] >= n, top[1] >= n, top[2] >= n];
        let forest = self.forest;
        let levels = &forest.level[..];
        let l = &mut self.lists;
        let lsc_ctx = &mut self.lsc_ctx;
        let lsc_before = l.lsc.len();
        let Contexts {
            sig, sign, refine, ..
        } = &mut l.ctx;
        let (sig, sign, refine) = (&mut sig[..], &mut sign[..], &mut refine[..]);
        let Coefficients {
            lo,
            width,
            neg,
            first,
        } = out;
        let (lo, width, neg, first) = (&mut lo[..], &mut width[..], &mut neg[..], &mut first[..]);
        // One decision with context `ctx` (raw bit without contexts); stops the pass at the
        // first decision that needs a missing byte.
        macro_rules! decide {
            ($ctx:expr) => {{
                let b = if ON { dec.bit($ctx) } else { dec.raw(1) != 0 };
                if dec.truncated() {
                    return false;
                }
                b
            }};
        }
        // A node with a component significant in an earlier plane has `first > n + 1`
        // (entries found significant in this plane set `first = n + 1`).
        let earlier = nb + 1;
        // The context row of node `node`'s significance tests: some component significant in
        // an earlier plane, and the level.
        let sig_row = |first: &[u8], node: usize| -> (usize, usize) {
            (
                (first[node] > earlier) as usize,
                (levels[node] as usize).min(CTX_LEVELS - 1),
            )
        };
        let sig_at = |test: Test, other: usize, c: usize, lv: usize| {
            (((test as usize) * 2 + other) * 3 + c) * CTX_LEVELS + lv
        };
        // Entry `e` of node `node` became significant with sign `s`.
        macro_rules! significant {
            ($e:expr, $node:expr, $s:expr, $ci:expr) => {{
                let (e, node) = ($e, $node);
                lo[e] = thr;
                width[e] = nb;
                neg[e] = $s;
                first[node] = first[node].max(earlier);
                l.lsc.push(e as u32);
                lsc_ctx.push($ci as u8);
            }};
        }
        // LIC.
        let mut kept = 0;
        for idx in 0..l.lic.len() {
            let e = l.lic[idx] as usize;
            let node = e / 3;
            let c = e - 3 * node;
            if active[c] {
                let (other, lv) = sig_row(first, node);
                if decide!(&mut sig[sig_at(Test::Lic, other, c, lv)]) {
                    let ci = c * CTX_LEVELS + lv;
                    let s = decide!(&mut sign[ci]);
                    significant!(e, node, s, ci);
                    continue;
                }
            }
            l.lic[kept] = e as u32;
            kept += 1;
        }
        l.lic.truncate(kept);
        // LIS (entries appended during the pass are processed in the same pass).
        let mut i = 0;
        let mut kept = 0;
        while i < l.lis.len() {
            let entry = l.lis[i];
            i += 1;
            let e = (entry & !TYPE_B) as usize;
            let node = e / 3;
            let c = e - 3 * node;
            let mut keep = true;
            if active[c] {
                let (other, lv) = sig_row(first, node);
                if entry & TYPE_B == 0 {
                    if decide!(&mut sig[sig_at(Test::SetA, other, c, lv)]) {
                        for &k in forest.offspring(node) {
                            let k = k as usize;
                            let ke = 3 * k + c;
                            let (other, lv) = sig_row(first, k);
                            if decide!(&mut sig[sig_at(Test::Offspring, other, c, lv)]) {
                                let ci = c * CTX_LEVELS + lv;
                                let s = decide!(&mut sign[ci]);
                                significant!(ke, k, s, ci);
                            } else {
                                l.lic.push(ke as u32);
                            }
                        }
                        if has_grandchildren(forest, node) {
                            l.lis.push(e as u32 | TYPE_B);
                        }
                        keep = false;
                    }
                } else if decide!(&mut sig[sig_at(Test::SetB, other, c, lv)]) {
                    for &k in forest.offspring(node) {
                        l.lis.push(3 * k + c as u32);
                    }
                    keep = false;
                }
            }
            if keep {
                l.lis[kept] = entry;
                kept += 1;
            }
        }
        l.lis.drain(kept..i);
        // Refinement.
        for (&e, &ci) in l.lsc[..lsc_before].iter().zip(&lsc_ctx[..lsc_before]) {
            let e = e as usize;
            let bit = decide!(&mut refine[ci as usize]);
            lo[e] += thr & (bit as u32).wrapping_neg();
            width[e] = nb;
        }
        l.plane -= 1;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    macro_rules! get {
        ($dec:expr, $e:expr) => {{
            let b = $e;
            if $dec.truncated() {
                return false;
            }
            b
        }};
    }

    /// The straightforward decoder this module had before [`SpihtDecoder::decode_passes`] (kept to
    /// check that the fast one decodes every prefix to the same state).
    impl SpihtDecoder<'_> {
        /// Decodes the current plane into `out`. Returns `false` if the stream ended before the
        /// plane was complete (the state is then that of the exact decisions decoded; decoding
        /// must not continue) or if every plane is done.
        fn decode_plane_reference(&mut self, dec: &mut Decoder, out: &mut Coefficients) -> bool {
            let n = self.lists.plane;
            if n < 0 {
                return false;
            }
            let thr = 1u32 << n;
            let top = self.lists.top;
            let forest = self.forest;
            let lsc_before = self.lists.lsc.len();
            let l = &mut self.lists;
            let on = l.ctx.on;
            // Some component of the node significant in an earlier plane (width > n; entries
            // found significant in this plane have width n, refinement comes after sorting).
            let other = |out: &Coefficients, e: usize| {
                let b = e - e % 3;
                out.width[b..b + 3]
                    .iter()
                    .any(|&w| w != INSIGNIFICANT && w as i32 > n)
            };
            macro_rules! sig {
            ($test:expr, $e:expr) => {{
                let e: usize = $e;
                if on {
                    let idx = Contexts::sig_index($test, other(out, e), e % 3, forest.level[e / 3]);
                    get!(dec, dec.bit(&mut l.ctx.sig[idx]))
                } else {
                    get!(dec, dec.raw(1) != 0)
                }
            }};
        }
            macro_rules! sign {
            ($e:expr) => {{
                let e: usize = $e;
                if on {
                    let idx = Contexts::cl(e % 3, forest.level[e / 3]);
                    get!(dec, dec.bit(&mut l.ctx.sign[idx]))
                } else {
                    get!(dec, dec.raw(1) != 0)
                }
            }};
        }
            // LIC.
            let mut idx = 0;
            let mut kept = 0;
            while idx < l.lic.len() {
                let e = l.lic[idx] as usize;
                idx += 1;
                if top[e % 3] >= n {
                    let s = sig!(Test::Lic, e);
                    if s {
                        let neg = sign!(e);
                        out.lo[e] = thr;
                        out.width[e] = n as u8;
                        out.neg[e] = neg;
                        l.lsc.push(e as u32);
                        continue;
                    }
                }
                l.lic[kept] = e as u32;
                kept += 1;
            }
            l.lic.truncate(kept);
            // LIS.
            let mut i = 0;
            let mut kept = 0;
            while i < l.lis.len() {
                let entry = l.lis[i];
                i += 1;
                let e = (entry & !TYPE_B) as usize;
                let (node, c) = (e / 3, e % 3);
                let mut keep = true;
                if top[c] >= n {
                    if entry & TYPE_B == 0 {
                        if sig!(Test::SetA, e) {
                            for &k in forest.offspring(node) {
                                let ke = 3 * k as usize + c;
                                if sig!(Test::Offspring, ke) {
                                    let neg = sign!(ke);
                                    out.lo[ke] = thr;
                                    out.width[ke] = n as u8;
                                    out.neg[ke] = neg;
                                    l.lsc.push(ke as u32);
                                } else {
                                    l.lic.push(ke as u32);
                                }
                            }
                            if has_grandchildren(forest, node) {
                                l.lis.push(e as u32 | TYPE_B);
                            }
                            keep = false;
                        }
                    } else if sig!(Test::SetB, e) {
                        for &k in forest.offspring(node) {
                            l.lis.push(3 * k + c as u32);
                        }
                        keep = false;
                    }
                }
                if keep {
                    l.lis[kept] = entry;
                    kept += 1;
                }
            }
            l.lis.drain(kept..i);
            // Refinement.
            for &e in &l.lsc[..lsc_before] {
                let e = e as usize;
                let bit = if on {
                    let idx = Contexts::cl(e % 3, forest.level[e / 3]);
                    get!(dec, dec.bit(&mut l.ctx.refine[idx]))
                } else {
                    get!(dec, dec.raw(1) != 0)
                };
                if bit {
                    out.lo[e] += thr;
                }
                out.width[e] = n as u8;
            }
            l.plane -= 1;
            true
        }
    }

    use crate::generate;
    use crate::hierarchy::Hierarchy;
    use crate::subdivision::refine::Split;

    fn sample(forest: &Forest, seed: u64) -> Magnitudes {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 33) as u32
        };
        let mut mag = Vec::new();
        let mut neg = Vec::new();
        for n in 0..forest.num_nodes {
            for c in 0..3 {
                let scale = 1u32 << (14 - 2 * forest.level[n] as u32 - c as u32);
                mag.push(next() % scale);
                neg.push(next() & 1 == 1);
            }
        }
        Magnitudes::new(forest, mag, neg)
    }

    fn round_trip(contexts: bool) {
        let h = Hierarchy::new(&generate::icosahedron(), 4, Split::Triangles, None).unwrap();
        let f = Forest::new(&h).unwrap();
        let m = sample(&f, 7);
        let roots: Vec<u32> = (0..f.num_trees as u32).collect();
        let mut e = SpihtEncoder::new(&f, &m, &roots, contexts);
        let mut enc = Encoder::new();
        while e.code_plane(&mut enc) {}
        let bytes = enc.finish();
        let mut d = SpihtDecoder::new(&f, &roots, m.top, contexts);
        let mut dec = Decoder::new(&bytes);
        let mut out = Coefficients::new(&f);
        while d.decode_plane(&mut dec, &mut out) {}
        assert_eq!(d.plane(), -1);
        for i in 0..m.mag.len() {
            if m.mag[i] == 0 {
                assert_eq!(out.width[i], INSIGNIFICANT);
            } else {
                assert_eq!(
                    (out.lo[i], out.width[i], out.neg[i]),
                    (m.mag[i], 0, m.neg[i])
                );
            }
        }
        // Prefixes: every known interval contains the true magnitude.
        for cut in [0, 1, 5, bytes.len() / 3, bytes.len() - 1] {
            let mut d = SpihtDecoder::new(&f, &roots, m.top, contexts);
            let mut dec = Decoder::new(&bytes[..cut]);
            let mut out = Coefficients::new(&f);
            while d.decode_plane(&mut dec, &mut out) {}
            for i in 0..m.mag.len() {
                if out.width[i] != INSIGNIFICANT {
                    let w = 1u32 << out.width[i];
                    assert!(out.lo[i] <= m.mag[i] && m.mag[i] < out.lo[i] + w);
                    assert_eq!(out.neg[i], m.neg[i]);
                }
            }
        }
    }

    /// The fast decoder equals the reference decoder on every prefix of several streams
    /// (same coefficients, same planes, same stop), with and without contexts, over whole
    /// forests and single trees, on a closed and an open hierarchy.
    #[test]
    fn fast_decoder_equals_reference_on_every_prefix() {
        let meshes = [generate::icosahedron(), generate::grid(3, 2, true)];
        for (mi, base) in meshes.iter().enumerate() {
            let h = Hierarchy::new(base, 4, Split::Triangles, None).unwrap();
            let f = Forest::new(&h).unwrap();
            let m = sample(&f, 11 + mi as u64);
            let all: Vec<u32> = (0..f.num_trees as u32).collect();
            for roots in [all, vec![1]] {
                for contexts in [true, false] {
                    let mut e = SpihtEncoder::new(&f, &m, &roots, contexts);
                    let mut enc = Encoder::new();
                    while e.code_plane(&mut enc) {}
                    let bytes = enc.finish();
                    let step = (bytes.len() / 97).max(1);
                    let cuts = (0..=bytes.len()).step_by(step).chain([bytes.len()]);
                    for cut in cuts {
                        let run = |fast: bool| {
                            let mut d = SpihtDecoder::new(&f, &roots, m.top, contexts);
                            let mut dec = Decoder::new(&bytes[..cut]);
                            let mut out = Coefficients::new(&f);
                            let mut planes = 0;
                            while if fast {
                                d.decode_plane(&mut dec, &mut out)
                            } else {
                                d.decode_plane_reference(&mut dec, &mut out)
                            } {
                                planes += 1;
                            }
                            (
                                out.lo,
                                out.width,
                                out.neg,
                                planes,
                                d.plane(),
                                dec.position(),
                            )
                        };
                        assert!(
                            run(true) == run(false),
                            "mesh {mi}, contexts {contexts}, cut {cut}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn lossless_round_trip_with_contexts() {
        round_trip(true);
    }

    #[test]
    fn lossless_round_trip_raw_bits() {
        round_trip(false);
    }
}

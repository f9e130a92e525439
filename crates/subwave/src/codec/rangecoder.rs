//! Adaptive binary range coder (the carry-propagating "LZMA-style" coder of G. N. N. Martin,
//! *Range encoding: an algorithm for removing redundancy from a digitised message*, 1979,
//! with Subbotin-style byte output), with adaptive binary contexts, raw (equiprobable) bits,
//! bit-tree symbols and an adaptive Elias-gamma integer model built on them.
//!
//! This is the entropy coder of every subwave bitstream: the base-mesh coder
//! ([`crate::codec`]), the SPIHT significance, sign and refinement bits (Maret 2003 §4.5,
//! "context-adaptive arithmetic coding") and the container's headers. It is written here
//! rather than taken from `constriction` because the codec needs two things that crate's
//! stream coders do not offer directly: adaptive binary contexts updated after every bit at
//! ~1 ns per bit (constriction's models are fixed distributions that would have to be rebuilt
//! per bit), and **exact prefix semantics** for embedded streams: every decision of the
//! decoder depends only on the bytes it has read, so when a stream is cut at any byte the
//! decoder reports [`Decoder::truncated`] at the first symbol that needs a missing byte, and
//! every symbol before it equals what the full stream decodes to.
//!
//! Contract: the decoder never panics and never reads out of bounds, whatever the bytes
//! (missing bytes read as zero and set [`Decoder::truncated`]).

/// Bits of precision of a probability.
const PROB_BITS: u32 = 12;
/// The probability scale (`1 << PROB_BITS`).
const PROB_ONE: u16 = 1 << PROB_BITS;
/// Adaptation speed: each coded bit moves the probability by 1/32 of the distance.
const ADAPT_SHIFT: u32 = 5;
/// The range is renormalised when it falls below this.
const TOP: u32 = 1 << 24;

/// An adaptive binary probability model: what [`Encoder::bit`] and [`Decoder::bit`] code
/// with. Implementations: [`Bit`] (a fixed adaptation rate, the fastest to decode) and
/// [`CountedBit`] (a rate that starts fast, for models that code few bits). The trait is
/// sealed: the coder's termination and the decoders' allocation bounds rely on the
/// probability range of these two.
pub trait BitModel: sealed::Sealed + Copy + Default {
    /// The probability that the next bit is 0, in 1/4096: in `1..=4095`, whatever bits
    /// were coded.
    fn p0(&self) -> u32;
    /// Updates the model after coding `bit`.
    fn update(&mut self, bit: bool);
}

mod sealed {
    /// Implemented by the crate's bit models only.
    pub trait Sealed {}
    impl Sealed for super::Bit {}
    impl Sealed for super::CountedBit {}
}

/// Moves `p` (the probability of a 0, in 1/4096) by `1/2^shift` of the distance to 0 (after
/// a 1) or to 4096 (after a 0), without a branch on `bit`.
#[inline(always)]
fn adapt(p: u32, bit: bool, shift: u32) -> u16 {
    let m = (bit as u32).wrapping_neg();
    let up = p + ((PROB_ONE as u32 - p) >> shift);
    let down = p - (p >> shift);
    ((up & !m) | (down & m)) as u16
}

/// An adaptive binary context: the probability that the next bit is 0, in 1/4096, moved by
/// 1/32 of the distance after each bit. Its probability stays in `31..=4065`, so a bit costs
/// at least 0.011 bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bit(u16);

impl Default for Bit {
    fn default() -> Self {
        Bit(PROB_ONE / 2)
    }
}

impl Bit {
    /// A context with P(0) = 1/2.
    pub fn new() -> Self {
        Self::default()
    }
}

impl BitModel for Bit {
    #[inline(always)]
    fn p0(&self) -> u32 {
        self.0 as u32
    }

    #[inline(always)]
    fn update(&mut self, bit: bool) {
        self.0 = adapt(self.0 as u32, bit, ADAPT_SHIFT);
    }
}

/// Adaptation shifts of a [`CountedBit`] by the number of bits it has coded: 1/2 of the
/// distance after its first bit, then 1/4 (2 bits), 1/8 (4 bits), 1/16 (8 bits) and from
/// the 16th bit on [`Bit`]'s 1/32. This approximates the frequency count of a
/// Krichevsky–Trofimov estimator (the rate 1/(n + 2) after `n` bits) while the context is
/// young, where a fixed slow rate pays for its start at P = 1/2 on every context.
#[rustfmt::skip]
const COUNTED_RATE: [u8; 16] = [1, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, ADAPT_SHIFT as u8];

/// An adaptive binary context whose adaptation rate starts fast and slows down to [`Bit`]'s
/// (by 1/2 of the distance after its first bit, then 1/4 for two bits, 1/8 for four, 1/16
/// for eight, and 1/32 from its 16th bit on): for models with many contexts that each see
/// few bits, as in the base-mesh and lossless coders (the base mesh of the beetle codes 6%
/// fewer connectivity bits with it). Its probability stays in `31..=4065`, as [`Bit`]'s: a
/// monotone run reaches at most `4096 − 200` before the last rate applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CountedBit {
    p: u16,
    seen: u16,
}

impl Default for CountedBit {
    fn default() -> Self {
        CountedBit {
            p: PROB_ONE / 2,
            seen: 0,
        }
    }
}

impl BitModel for CountedBit {
    #[inline(always)]
    fn p0(&self) -> u32 {
        self.p as u32
    }

    #[inline(always)]
    fn update(&mut self, bit: bool) {
        let shift = COUNTED_RATE[self.seen as usize] as u32;
        self.p = adapt(self.p as u32, bit, shift);
        self.seen = (self.seen + 1).min(COUNTED_RATE.len() as u16 - 1);
    }
}

/// The range encoder. Bytes go to an internal `Vec<u8>`; [`Encoder::finish`] returns them.
#[derive(Debug)]
pub struct Encoder {
    low: u64,
    range: u32,
    cache: u8,
    cache_size: u64,
    out: Vec<u8>,
}

impl Default for Encoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Encoder {
    /// An empty encoder.
    pub fn new() -> Self {
        Encoder {
            low: 0,
            range: u32::MAX,
            cache: 0,
            cache_size: 1,
            out: Vec::new(),
        }
    }

    #[inline]
    fn shift_low(&mut self) {
        if (self.low as u32) < 0xFF00_0000 || (self.low >> 32) != 0 {
            let carry = (self.low >> 32) as u8;
            let mut temp = self.cache;
            loop {
                self.out.push(temp.wrapping_add(carry));
                temp = 0xFF;
                self.cache_size -= 1;
                if self.cache_size == 0 {
                    break;
                }
            }
            self.cache = ((self.low >> 24) & 0xFF) as u8;
        }
        self.cache_size += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    #[inline]
    fn normalize(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    /// Codes `bit` with the adaptive context `ctx` (then updates the context).
    #[inline]
    pub fn bit<M: BitModel>(&mut self, ctx: &mut M, bit: bool) {
        let bound = (self.range >> PROB_BITS) * ctx.p0();
        if bit {
            self.low += bound as u64;
            self.range -= bound;
        } else {
            self.range = bound;
        }
        ctx.update(bit);
        self.normalize();
    }

    /// Codes the `n` low bits of `value` (most significant first) with probability 1/2 each.
    /// `n` ≤ 32.
    #[inline]
    pub fn raw(&mut self, value: u32, n: u32) {
        debug_assert!(n <= 32);
        for i in (0..n).rev() {
            self.range >>= 1;
            if (value >> i) & 1 != 0 {
                self.low += self.range as u64;
            }
            self.normalize();
        }
    }

    /// Bytes written so far, excluding the up to 5 bytes still held in the coder's state.
    pub fn bytes_so_far(&self) -> usize {
        self.out.len()
    }

    /// An upper bound of the size the stream would have if it were finished now.
    pub fn size_bound(&self) -> usize {
        self.out.len() + self.cache_size as usize + 4
    }

    /// Flushes the coder's state and returns the bytes.
    pub fn finish(mut self) -> Vec<u8> {
        for _ in 0..5 {
            self.shift_low();
        }
        // The first byte is always 0 (the initial cache); drop it: the decoder assumes it.
        self.out.remove(0);
        self.out
    }
}

/// The range decoder over a byte slice. Safe on any bytes: reading beyond the end yields
/// zeros and sets [`Decoder::truncated`].
#[derive(Clone, Copy, Debug)]
pub struct Decoder<'a> {
    data: &'a [u8],
    pos: usize,
    code: u32,
    range: u32,
    truncated: bool,
}

impl<'a> Decoder<'a> {
    /// A decoder reading `data` (the output of [`Encoder::finish`], or a prefix of it).
    pub fn new(data: &'a [u8]) -> Self {
        let mut d = Decoder {
            data,
            pos: 0,
            code: 0,
            range: u32::MAX,
            truncated: false,
        };
        for _ in 0..4 {
            d.code = (d.code << 8) | d.next_byte() as u32;
        }
        d
    }

    #[inline]
    fn next_byte(&mut self) -> u8 {
        match self.data.get(self.pos) {
            Some(&b) => {
                self.pos += 1;
                b
            }
            None => {
                self.truncated = true;
                0
            }
        }
    }

    /// Brings `range` back to at least [`TOP`]. Every decision leaves `range ≥ 31 · 2^12`
    /// (a context's probability stays in `[31, 4065]` / 4096, a raw bit halves a range of at
    /// least `2^24`), so one byte is all it ever needs: that step is branch-free (the need
    /// for a byte is data-dependent and unpredictable), the loop after it never runs.
    #[inline(always)]
    fn normalize(&mut self) {
        let need = self.range < TOP;
        let byte = self.data.get(self.pos).copied();
        self.truncated |= need & byte.is_none();
        let shift = 8 * need as u32;
        let mask = (need as u32).wrapping_neg();
        self.range <<= shift;
        self.code = (self.code << shift) | (byte.unwrap_or(0) as u32 & mask);
        self.pos += (need & byte.is_some()) as usize;
        while self.range < TOP {
            self.range <<= 8;
            self.code = (self.code << 8) | self.next_byte() as u32;
        }
    }

    /// True once a decoded symbol needed a byte beyond the end of the data: that symbol and
    /// every later one are unreliable; every symbol decoded before it is exact.
    #[inline]
    pub fn truncated(&self) -> bool {
        self.truncated
    }

    /// Bytes consumed so far.
    pub fn position(&self) -> usize {
        self.pos
    }

    /// Decodes a bit with the adaptive context `ctx` (mirrors [`Encoder::bit`]).
    #[inline(always)]
    pub fn bit<M: BitModel>(&mut self, ctx: &mut M) -> bool {
        // Normalising before the decision (not after) makes `truncated` flag exactly the
        // first decision that depends on a missing byte.
        self.normalize();
        // Branch-free (the decision is data-dependent and often unpredictable): the same
        // arithmetic as the encoder's, selected by masks.
        let bound = (self.range >> PROB_BITS) * ctx.p0();
        let bit = self.code >= bound;
        let m = (bit as u32).wrapping_neg();
        self.code -= bound & m;
        self.range = (bound & !m) | (self.range.wrapping_sub(bound) & m);
        ctx.update(bit);
        bit
    }

    /// Decodes `n` ≤ 32 raw bits (mirrors [`Encoder::raw`]).
    #[inline]
    pub fn raw(&mut self, n: u32) -> u32 {
        let mut v = 0u32;
        for _ in 0..n {
            self.normalize();
            self.range >>= 1;
            let bit = self.code >= self.range;
            if bit {
                self.code -= self.range;
            }
            v = (v << 1) | bit as u32;
        }
        v
    }
}

// The encoder normalises after each symbol and the decoder before: both keep the same
// (range, low/code) state sequence, since normalisation only depends on `range`.

/// Adaptive model of `BITS`-bit symbols as a binary tree of contexts (MSB first).
#[derive(Clone, Debug)]
pub struct BitTree<M: BitModel = Bit> {
    bits: u32,
    ctx: Vec<M>,
}

impl<M: BitModel> BitTree<M> {
    /// A model of `bits`-bit symbols (`bits` ≤ 16).
    pub fn new(bits: u32) -> Self {
        assert!(bits <= 16, "BitTree supports at most 16-bit symbols");
        BitTree {
            bits,
            ctx: vec![M::default(); 1usize << bits],
        }
    }

    /// Codes `symbol` (< 2^bits).
    pub fn encode(&mut self, enc: &mut Encoder, symbol: u32) {
        let mut node = 1usize;
        for i in (0..self.bits).rev() {
            let b = (symbol >> i) & 1 != 0;
            enc.bit(&mut self.ctx[node], b);
            node = (node << 1) | b as usize;
        }
    }

    /// Decodes a symbol.
    pub fn decode(&mut self, dec: &mut Decoder) -> u32 {
        let mut node = 1usize;
        for _ in 0..self.bits {
            let b = dec.bit(&mut self.ctx[node]);
            node = (node << 1) | b as usize;
        }
        (node - (1usize << self.bits)) as u32
    }
}

/// Adaptive model of unsigned integers (Elias-gamma layout): the bit length `n` of `v + 1`
/// in unary with adaptive contexts, then the `n - 1` bits below the leading one, the first
/// [`UInt::ADAPTIVE_MANTISSA`] of them with contexts per length, the rest raw.
#[derive(Clone, Debug)]
pub struct UInt<M: BitModel = Bit> {
    length: [M; 33],
    mantissa: Vec<M>,
}

impl<M: BitModel> Default for UInt<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: BitModel> UInt<M> {
    /// Mantissa bits coded with adaptive contexts (the rest are raw).
    pub const ADAPTIVE_MANTISSA: u32 = 2;

    /// A fresh model.
    pub fn new() -> Self {
        UInt {
            length: [M::default(); 33],
            mantissa: vec![M::default(); 34 << Self::ADAPTIVE_MANTISSA],
        }
    }

    /// Codes `v` (any `u32`).
    pub fn encode(&mut self, enc: &mut Encoder, v: u32) {
        let x = v as u64 + 1;
        let n = 64 - x.leading_zeros(); // 1..=33
        for i in 1..n {
            enc.bit(&mut self.length[i as usize - 1], true);
        }
        if n < 33 {
            enc.bit(&mut self.length[n as usize - 1], false);
        }
        let mut node = 1usize;
        for i in (0..n - 1).rev() {
            let b = (x >> i) & 1 != 0;
            let k = n - 1 - i; // 1-based position below the leading one
            if k <= Self::ADAPTIVE_MANTISSA {
                let idx = ((n as usize) << Self::ADAPTIVE_MANTISSA) + node - 1;
                enc.bit(&mut self.mantissa[idx], b);
                node = (node << 1) | b as usize;
            } else {
                enc.raw(b as u32, 1);
            }
        }
    }

    /// Decodes a value. On corrupt data the result is some `u32` (never a panic).
    pub fn decode(&mut self, dec: &mut Decoder) -> u32 {
        let mut n = 1u32;
        while n < 33 && dec.bit(&mut self.length[n as usize - 1]) {
            n += 1;
        }
        let mut x: u64 = 1;
        let mut node = 1usize;
        for k in 1..n {
            let b = if k <= Self::ADAPTIVE_MANTISSA {
                let idx = ((n as usize) << Self::ADAPTIVE_MANTISSA) + node - 1;
                let b = dec.bit(&mut self.mantissa[idx]);
                node = (node << 1) | b as usize;
                b
            } else {
                dec.raw(1) != 0
            };
            x = (x << 1) | b as u64;
        }
        (x - 1).min(u32::MAX as u64) as u32
    }
}

/// Adaptive model of signed integers: zero flag, sign, then magnitude − 1 with [`UInt`].
#[derive(Clone, Debug, Default)]
pub struct SInt<M: BitModel = Bit> {
    zero: M,
    sign: M,
    magnitude: UInt<M>,
}

impl<M: BitModel> SInt<M> {
    /// A fresh model.
    pub fn new() -> Self {
        Self::default()
    }

    /// Codes `v` (|v| < 2^32).
    pub fn encode(&mut self, enc: &mut Encoder, v: i64) {
        debug_assert!(v.unsigned_abs() <= u32::MAX as u64 + 1);
        enc.bit(&mut self.zero, v == 0);
        if v != 0 {
            enc.bit(&mut self.sign, v < 0);
            self.magnitude
                .encode(enc, (v.unsigned_abs() - 1).min(u32::MAX as u64) as u32);
        }
    }

    /// Decodes a value.
    pub fn decode(&mut self, dec: &mut Decoder) -> i64 {
        if dec.bit(&mut self.zero) {
            return 0;
        }
        let neg = dec.bit(&mut self.sign);
        let m = self.magnitude.decode(dec) as i64 + 1;
        if neg {
            -m
        } else {
            m
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> u32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 33) as u32
        }
    }

    #[derive(Debug, PartialEq, Clone, Copy)]
    enum Sym {
        Bit(usize, bool),
        Raw(u32, u32),
        Tree(u32),
        U(u32),
        S(i64),
    }

    fn script(seed: u64, n: usize) -> Vec<Sym> {
        let mut r = Lcg(seed);
        (0..n)
            .map(|_| match r.next() % 5 {
                0 => Sym::Bit((r.next() % 3) as usize, r.next() % 10 < 2),
                1 => {
                    let k = r.next() % 33;
                    let v = if k == 32 {
                        r.next()
                    } else {
                        r.next() & ((1u32 << k) - 1)
                    };
                    Sym::Raw(v, k)
                }
                2 => Sym::Tree(r.next() % 64),
                3 => Sym::U(if r.next().is_multiple_of(4) {
                    r.next()
                } else {
                    r.next() % 20
                }),
                _ => Sym::S((r.next() % 200) as i64 - 100),
            })
            .collect()
    }

    struct Models<M: BitModel> {
        bits: [M; 3],
        tree: BitTree<M>,
        u: UInt<M>,
        s: SInt<M>,
    }

    fn models<M: BitModel>() -> Models<M> {
        Models {
            bits: [M::default(); 3],
            tree: BitTree::new(6),
            u: UInt::new(),
            s: SInt::new(),
        }
    }

    fn encode<M: BitModel>(syms: &[Sym]) -> Vec<u8> {
        let mut m = models::<M>();
        let mut e = Encoder::new();
        for s in syms {
            match *s {
                Sym::Bit(c, b) => e.bit(&mut m.bits[c], b),
                Sym::Raw(v, k) => e.raw(v, k),
                Sym::Tree(v) => m.tree.encode(&mut e, v),
                Sym::U(v) => m.u.encode(&mut e, v),
                Sym::S(v) => m.s.encode(&mut e, v),
            }
        }
        e.finish()
    }

    /// Decodes following `syms`' kinds; returns how many symbols decoded before truncation.
    fn decode<M: BitModel>(bytes: &[u8], syms: &[Sym]) -> Vec<Sym> {
        let mut m = models::<M>();
        let mut d = Decoder::new(bytes);
        let mut out = Vec::new();
        for s in syms {
            let got = match *s {
                Sym::Bit(c, _) => Sym::Bit(c, d.bit(&mut m.bits[c])),
                Sym::Raw(_, k) => Sym::Raw(d.raw(k), k),
                Sym::Tree(_) => Sym::Tree(m.tree.decode(&mut d)),
                Sym::U(_) => Sym::U(m.u.decode(&mut d)),
                Sym::S(_) => Sym::S(m.s.decode(&mut d)),
            };
            if d.truncated() {
                break;
            }
            out.push(got);
        }
        out
    }

    fn roundtrip_mixed_symbols_with<M: BitModel>() {
        for seed in 0..20 {
            let syms = script(seed, 2000);
            let bytes = encode::<M>(&syms);
            assert_eq!(decode::<M>(&bytes, &syms), syms, "seed {seed}");
        }
    }

    #[test]
    fn roundtrip_mixed_symbols() {
        roundtrip_mixed_symbols_with::<Bit>();
        roundtrip_mixed_symbols_with::<CountedBit>();
    }

    fn every_prefix_with<M: BitModel>() {
        let syms = script(7, 600);
        let bytes = encode::<M>(&syms);
        let mut last = 0;
        for cut in 0..=bytes.len() {
            let got = decode::<M>(&bytes[..cut], &syms);
            assert_eq!(&got[..], &syms[..got.len()], "cut {cut}");
            assert!(got.len() >= last, "monotone in the prefix length");
            last = got.len();
        }
        assert_eq!(last, syms.len());
    }

    #[test]
    fn every_prefix_decodes_a_correct_prefix_of_symbols() {
        every_prefix_with::<Bit>();
        every_prefix_with::<CountedBit>();
    }

    /// A [`CountedBit`] stays within [`Bit`]'s probability range (31..=4065), which the
    /// decoders' allocation bounds rely on (a decision costs at least 0.011 bits): runs of
    /// one value from a fresh context (the extremes, since an update is monotone in the
    /// probability) and random sequences.
    #[test]
    fn counted_bit_probabilities_stay_within_bits_range() {
        for value in [false, true] {
            let mut c = CountedBit::default();
            let mut b = Bit::new();
            for _ in 0..10_000 {
                c.update(value);
                b.update(value);
                assert!((31..=4065).contains(&c.p0()), "{}", c.p0());
            }
            assert_eq!(c.p0(), b.p0(), "both saturate at the same probability");
        }
        let mut r = Lcg(5);
        for _ in 0..200 {
            let mut c = CountedBit::default();
            let skew = r.next() % 64;
            for _ in 0..500 {
                c.update(r.next() % 64 < skew);
                assert!((31..=4065).contains(&c.p0()));
            }
        }
    }

    /// Many young contexts of a skewed source: the counted contexts learn the skew in a few
    /// bits, the fixed-rate ones pay for their start at 1/2 (the case of the base-mesh coder).
    #[test]
    fn young_counted_contexts_cost_less_than_fixed_rate_ones() {
        fn bytes<M: BitModel>() -> usize {
            let mut r = Lcg(9);
            let mut ctx = [M::default(); 64];
            let mut e = Encoder::new();
            for _ in 0..24 {
                for (i, c) in ctx.iter_mut().enumerate() {
                    // Contexts of P(1) = 10% and 90%.
                    e.bit(c, r.next().is_multiple_of(10) != (i % 2 == 0));
                }
            }
            e.finish().len()
        }
        let (fixed, counted) = (bytes::<Bit>(), bytes::<CountedBit>());
        assert!(
            (counted as f64) < 0.85 * fixed as f64,
            "{counted} bytes counted, {fixed} fixed"
        );
    }

    #[test]
    fn skewed_bits_compress() {
        let mut e = Encoder::new();
        let mut c = Bit::new();
        let mut r = Lcg(3);
        for _ in 0..100_000 {
            e.bit(&mut c, r.next().is_multiple_of(100));
        }
        let n = e.finish().len();
        // Entropy of p = 0.01 is 0.081 bit: 1010 bytes; allow 15% adaptation overhead.
        assert!(n < 1160, "{n} bytes");
    }

    /// Contexts driven to their extreme probabilities (31 and 4065 / 4096), then decisions
    /// against them (the smallest ranges a decision leaves: the one-byte normalisation's
    /// bound), raw bits between: every prefix decodes a correct prefix of the decisions, and
    /// the decoder never reads past the data.
    #[test]
    fn extreme_probabilities_on_every_prefix() {
        let mut syms = Vec::new();
        for round in 0..6 {
            syms.extend(std::iter::repeat_n(Sym::Bit(0, true), 400));
            syms.extend(std::iter::repeat_n(Sym::Bit(1, false), 400));
            // Surprises against both saturated contexts.
            for k in 0..40 {
                syms.push(Sym::Bit(0, k % 3 != round % 3));
                syms.push(Sym::Bit(1, k % 4 == round % 4));
                if k % 7 == 0 {
                    syms.push(Sym::Raw(k, 9));
                }
            }
        }
        let bytes = encode::<Bit>(&syms);
        assert_eq!(decode::<Bit>(&bytes, &syms), syms);
        let mut last = 0;
        for cut in 0..=bytes.len() {
            let got = decode::<Bit>(&bytes[..cut], &syms);
            assert_eq!(&got[..], &syms[..got.len()], "cut {cut}");
            assert!(got.len() >= last);
            last = got.len();
        }
        // Reading beyond the end never advances the position past it.
        let mut m = models::<Bit>();
        let mut d = Decoder::new(&bytes[..bytes.len() / 2]);
        for _ in 0..syms.len() {
            d.bit(&mut m.bits[0]);
            assert!(d.position() <= bytes.len() / 2);
        }
        assert!(d.truncated());
    }

    #[test]
    fn garbage_never_panics() {
        let mut r = Lcg(11);
        for _ in 0..200 {
            let len = (r.next() % 64) as usize;
            let bytes: Vec<u8> = (0..len).map(|_| r.next() as u8).collect();
            let syms = script(r.next() as u64, 300);
            let _ = decode::<Bit>(&bytes, &syms);
            let _ = decode::<CountedBit>(&bytes, &syms);
        }
    }

    #[test]
    fn extreme_integers_roundtrip() {
        let vals = [0u32, 1, 2, 3, 255, 65535, u32::MAX - 1, u32::MAX];
        let mut u: UInt = UInt::new();
        let mut s: SInt = SInt::new();
        let mut e = Encoder::new();
        for &v in &vals {
            u.encode(&mut e, v);
            s.encode(&mut e, v as i64);
            s.encode(&mut e, -(v as i64));
        }
        let bytes = e.finish();
        let mut u: UInt = UInt::new();
        let mut s: SInt = SInt::new();
        let mut d = Decoder::new(&bytes);
        for &v in &vals {
            assert_eq!(u.decode(&mut d), v);
            assert_eq!(s.decode(&mut d), v as i64);
            assert_eq!(s.decode(&mut d), -(v as i64));
        }
        assert!(!d.truncated());
    }
}

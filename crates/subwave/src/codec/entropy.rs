//! Coder efficiency: the bytes SPIHT spends on a stream's detail coefficients against the
//! empirical entropy of those coefficients, bit plane by bit plane.
//!
//! A SPIHT stream cut at the end of bit plane `k` tells the decoder every coefficient's
//! magnitude down to bit `k` and its sign (Maret 2003 §4.4.2, Algorithm 1; the decoder then
//! reconstructs mid-interval, eqs. 4.11-4.12). That is the dead-zone quantization
//! `q = sign · ⌊|c| / 2^k⌋` of every coefficient `c` (in units of the finest step). Its
//! empirical entropy bounds what a coder that sees each coefficient alone can spend:
//! - **order 0**: `Σ −log2 P(q)` with `P` the frequency of `q` among the coefficients of the
//!   same level and component (the classes SPIHT's contexts separate, [`super::spiht`]);
//! - **given the parent**: the same within classes that also split by the parent's
//!   `min(|q_parent|, 4)` in the offspring forest ([`super::forest`]), or "root": what the
//!   zerotree structure of SPIHT can exploit beyond order 0.
//!
//! Both are empirical (the frequencies are taken from the coefficients themselves, with no
//! cost for describing them), so an adaptive coder cannot quite reach them. Measured on the
//! default stream of the Stanford bunny (5 levels, 102,653 vertices), SPIHT spends 1.4–3%
//! more than the order-0 bound up to the end of each of its last six bit planes (which hold
//! 90% of its bytes), and the parent lowers the bound by 3–4%: the bytes of such a stream
//! are set by the coefficients (the remesh and its wavelet), not by how they are entropy
//! coded. `subwave bench entropy` prints the table.

use std::collections::HashMap;

use super::forest::Forest;
use super::spiht::INSIGNIFICANT;
use crate::Result;

/// One bit plane of a stream against the entropy of its quantization.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneEntropy {
    /// The bit plane `k` (the coefficients are known down to bit `k` after it).
    pub plane: u32,
    /// Bytes of the coefficient chunks up to and including this plane's (the base mesh and
    /// the header not counted).
    pub bytes: u64,
    /// Order-0 empirical entropy of the coefficients quantized to this plane, per level
    /// and component, in bytes.
    pub order0_bytes: f64,
    /// The same given the parent's quantized magnitude (`min(|q|, 4)`, or root), in bytes.
    pub parent_bytes: f64,
}

/// The efficiency report of a stream: the number of coefficient entries (three per forest
/// node) and one [`PlaneEntropy`] per bit plane, from the top plane down.
#[derive(Clone, Debug, PartialEq)]
pub struct CoderEfficiency {
    /// Coefficient entries (`3 ·` forest nodes).
    pub coefficients: usize,
    /// Per bit plane, in coding order.
    pub planes: Vec<PlaneEntropy>,
}

/// Decodes the whole embedded wavelet stream `stream` and weighs each of its bit planes
/// against the entropy of the quantization it completes (module docs).
///
/// # Errors
/// [`crate::Error::Decode`] for a damaged or truncated stream (as
/// [`super::progressive::decode`]), [`crate::Error::InvalidArgument`] for a direct, per-tree
/// or lossless stream (the message says how to encode one this reads: `--direct never`,
/// `--layout embedded`, without `--lossless`).
pub fn coder_efficiency(stream: &[u8]) -> Result<CoderEfficiency> {
    let (forest, coefs, chunks) = super::progressive::embedded_coefficients(stream)?;
    // Signed magnitudes (0 where insignificant) and the class of each entry.
    let values: Vec<i64> = (0..coefs.lo.len())
        .map(|e| {
            if coefs.width[e] == INSIGNIFICANT {
                0
            } else if coefs.neg[e] {
                -(coefs.lo[e] as i64)
            } else {
                coefs.lo[e] as i64
            }
        })
        .collect();
    let parent_of = parents(&forest);
    let class: Vec<u32> = (0..values.len())
        .map(|e| 3 * forest.level[e / 3] as u32 + (e % 3) as u32)
        .collect();
    let mut planes = Vec::with_capacity(chunks.len());
    let mut bytes = 0u64;
    for (plane, len) in chunks {
        bytes += len;
        let q = |e: usize| {
            let v = values[e];
            v.signum() * (v.unsigned_abs() >> plane) as i64
        };
        let mut order0: HashMap<(u32, i64), u64> = HashMap::new();
        let mut parent: HashMap<(u32, u8, i64), u64> = HashMap::new();
        for (e, &cl) in class.iter().enumerate() {
            let v = q(e);
            *order0.entry((cl, v)).or_default() += 1;
            let p = match parent_of[e / 3] {
                ROOT => 5,
                p => q(3 * p as usize + e % 3).unsigned_abs().min(4) as u8,
            };
            *parent.entry((cl, p, v)).or_default() += 1;
        }
        planes.push(PlaneEntropy {
            plane,
            bytes,
            order0_bytes: entropy_bits(order0.into_iter().map(|((c, _), n)| (c as u64, n))) / 8.0,
            parent_bytes: entropy_bits(
                parent
                    .into_iter()
                    .map(|((c, p, _), n)| (((c as u64) << 8) | p as u64, n)),
            ) / 8.0,
        });
    }
    Ok(CoderEfficiency {
        coefficients: values.len(),
        planes,
    })
}

/// "No parent" in [`parents`].
const ROOT: u32 = u32::MAX;

/// The node whose offspring each node of `forest` is ([`ROOT`] for the roots).
fn parents(forest: &Forest) -> Vec<u32> {
    let mut parent = vec![ROOT; forest.num_nodes];
    for n in 0..forest.num_nodes {
        for &c in forest.offspring(n) {
            parent[c as usize] = n as u32;
        }
    }
    parent
}

/// `Σ_classes (N log2 N − Σ_values n log2 n)`: the empirical entropy in bits of values counted
/// `(class, count)` per (class, value).
fn entropy_bits(counts: impl Iterator<Item = (u64, u64)>) -> f64 {
    let mut totals: HashMap<u64, u64> = HashMap::new();
    let mut sum = 0.0;
    for (class, n) in counts {
        *totals.entry(class).or_default() += n;
        sum -= n as f64 * (n as f64).log2();
    }
    for n in totals.into_values() {
        sum += n as f64 * (n as f64).log2();
    }
    sum.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entropy_of_counts() {
        // Two classes: {a, a, b, b} (2 bits) and {c} (0 bits).
        let bits = entropy_bits([(0, 2), (0, 2), (1, 1)].into_iter());
        assert!((bits - 4.0).abs() < 1e-9, "{bits}");
        assert_eq!(entropy_bits(std::iter::empty()), 0.0);
    }
}

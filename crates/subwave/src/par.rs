//! Parallel construction of large vectors without a per-element collect.
//!
//! rayon's `collect_into_vec` over an indexed iterator pays its bookkeeping (split, consumer,
//! initialised-length tracking) for every element; for the cheap elements of refinement (a
//! Loop vertex is a dozen multiply-adds) it costs as much as the work. [`par_vec`] instead
//! gives each task a chunk of the vector's spare capacity and a plain loop, and touches every
//! page of the new buffer from the thread that computes it (first-touch page faults are
//! spread over the cores, not taken by one serial fill).

use rayon::prelude::*;

/// `(0..n).map(|j| f(&mut state, j))` as a vector, computed in parallel chunks of `chunk`
/// elements, each task with its own `state` from `init` (scratch buffers). The elements are
/// in index order whatever the scheduling.
///
/// # Panics
/// If `chunk` is 0, or if `f` panics (the panic propagates; nothing is leaked but the
/// elements already computed, which are not dropped).
pub(crate) fn par_vec<T, S>(
    n: usize,
    chunk: usize,
    init: impl Fn() -> S + Sync + Send,
    f: impl Fn(&mut S, usize) -> T + Sync + Send,
) -> Vec<T>
where
    T: Send,
{
    assert!(chunk > 0, "par_vec: chunk must be positive");
    let mut out = Vec::with_capacity(n);
    out.spare_capacity_mut()[..n]
        .par_chunks_mut(chunk)
        .enumerate()
        .for_each_init(init, |s, (c, slots)| {
            let first = c * chunk;
            for (k, slot) in slots.iter_mut().enumerate() {
                slot.write(f(s, first + k));
            }
        });
    // SAFETY: the chunks cover the first `n` slots and the loop wrote each of them; a panic
    // above propagates before this line, leaving the vector empty.
    unsafe { out.set_len(n) };
    out
}

#[cfg(test)]
mod tests {
    use super::par_vec;

    #[test]
    fn par_vec_equals_the_serial_map() {
        for (n, chunk) in [(0, 1), (1, 1), (5, 2), (4096, 4096), (100_003, 1000)] {
            let v = par_vec(n, chunk, Vec::<u64>::new, |s, j| {
                s.push(j as u64); // per-task state is usable
                (j as u64) * 3 + 1
            });
            assert_eq!(v, (0..n as u64).map(|j| j * 3 + 1).collect::<Vec<_>>());
        }
        let strings = par_vec(10_000, 7, || (), |_, j| j.to_string());
        assert!(strings.iter().enumerate().all(|(j, s)| *s == j.to_string()));
    }

    #[test]
    #[should_panic(expected = "element 77")]
    fn a_panic_propagates() {
        par_vec(
            1000,
            10,
            || (),
            |_, j| {
                assert!(j != 77, "element 77");
                j
            },
        );
    }
}

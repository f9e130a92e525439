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
    par_fill(&mut out.spare_capacity_mut()[..n], chunk, init, f);
    // SAFETY: `par_fill` wrote each of the first `n` slots; a panic in it propagates before
    // this line, leaving the vector empty.
    unsafe { out.set_len(n) };
    out
}

/// Writes `f(&mut state, k)` into slot `k` of `slots`, in parallel chunks of `chunk` slots,
/// each task with its own `state` from `init`. Every slot is written when it returns.
///
/// # Panics
/// If `chunk` is 0, or if `f` panics (the panic propagates; slots already written are not
/// dropped).
pub(crate) fn par_fill<T, S>(
    slots: &mut [std::mem::MaybeUninit<T>],
    chunk: usize,
    init: impl Fn() -> S + Sync + Send,
    f: impl Fn(&mut S, usize) -> T + Sync + Send,
) where
    T: Send,
{
    assert!(chunk > 0, "par_fill: chunk must be positive");
    slots
        .par_chunks_mut(chunk)
        .enumerate()
        .for_each_init(init, |s, (c, slots)| {
            let first = c * chunk;
            for (k, slot) in slots.iter_mut().enumerate() {
                slot.write(f(s, first + k));
            }
        });
}

/// `(0..n).map(..)` as a vector whose last `late` elements are computed first
/// (`tail(&mut state, k)` for element `n - late + k`) and whose other elements may read them
/// (`head(&mut state, j, tail)`), in parallel chunks of `chunk` elements.
///
/// # Panics
/// If `late > n`, if `chunk` is 0, or if a closure panics (the panic propagates; nothing is
/// leaked but the elements already computed, which are not dropped).
pub(crate) fn par_vec_tail_first<T, S>(
    n: usize,
    late: usize,
    chunk: usize,
    init: impl Fn() -> S + Sync + Send,
    tail: impl Fn(&mut S, usize) -> T + Sync + Send,
    head: impl Fn(&mut S, usize, &[T]) -> T + Sync + Send,
) -> Vec<T>
where
    T: Send + Sync,
{
    assert!(late <= n, "par_vec_tail_first: {late} late elements of {n}");
    let mut out = Vec::with_capacity(n);
    let (h, t) = out.spare_capacity_mut()[..n].split_at_mut(n - late);
    par_fill(t, chunk, &init, tail);
    // SAFETY: `par_fill` wrote every slot of `t` (a panic propagates before this line), and
    // `MaybeUninit<T>` has the layout of `T`.
    let t: &[T] = unsafe { std::slice::from_raw_parts(t.as_ptr().cast::<T>(), t.len()) };
    par_fill(h, chunk, &init, |s, j| head(s, j, t));
    // SAFETY: both fills wrote their slots, which cover the first `n`.
    unsafe { out.set_len(n) };
    out
}

/// Hints the processor to fetch `x`'s cache line (nothing where `x` is `None`, or off x86-64).
#[inline(always)]
pub(crate) fn prefetch<T>(x: Option<&T>) {
    #[cfg(target_arch = "x86_64")]
    if let Some(x) = x {
        // SAFETY: a prefetch reads nothing architecturally and cannot fault; `x` is a valid
        // reference anyway.
        unsafe {
            use core::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            _mm_prefetch::<_MM_HINT_T0>(std::ptr::from_ref(x).cast::<i8>());
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
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
    fn tail_first_reads_the_tail() {
        for (n, late, chunk) in [(0, 0, 1), (5, 0, 2), (5, 5, 2), (10_003, 1_000, 97)] {
            let v = super::par_vec_tail_first(
                n,
                late,
                chunk,
                || (),
                |_, k| 2 * (n - late + k) as u64,
                |_, j, tail: &[u64]| {
                    assert_eq!(tail.len(), late);
                    j as u64 + tail.first().copied().unwrap_or(0)
                },
            );
            let first = if late > 0 { 2 * (n - late) as u64 } else { 0 };
            let want: Vec<u64> = (0..n)
                .map(|j| {
                    if j >= n - late {
                        2 * j as u64
                    } else {
                        j as u64 + first
                    }
                })
                .collect();
            assert_eq!(v, want, "{n} {late} {chunk}");
        }
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

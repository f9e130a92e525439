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
/// (`head(&mut state, j, tail)`), in parallel chunks of `chunk` elements: [`par_tail`], then
/// [`par_head`].
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
    par_head(par_tail(n, late, chunk, &init, tail), chunk, init, head)
}

/// A vector of `n` elements of which only the last `late` ([`par_tail`]) and possibly a
/// range before them ([`Tail::fill_range`]) are computed yet; [`par_head`] computes the
/// others. Dropped before that, it drops the computed elements and frees its buffer.
pub(crate) struct Tail<T> {
    /// Capacity at least `n`, length 0; slots `n - late..n` and `done` are initialised.
    buf: Vec<T>,
    n: usize,
    late: usize,
    /// Slots before the tail computed already (empty if none).
    done: std::ops::Range<usize>,
}

impl<T> Tail<T> {
    /// The length of the finished vector.
    pub(crate) fn len(&self) -> usize {
        self.n
    }

    /// The number of tail elements, computed by [`par_tail`].
    pub(crate) fn late(&self) -> usize {
        self.late
    }

    /// Computes the elements `range` before the tail (once) as `f(&mut state, j, tail)`,
    /// `tail` being the elements `n - late..n`, in parallel chunks of `chunk`.
    ///
    /// # Panics
    /// If a range was computed already, if `range` reaches into the tail, if `chunk` is 0, or
    /// if `f` panics (the elements of `range` computed before it are then not dropped).
    pub(crate) fn fill_range<S>(
        &mut self,
        range: std::ops::Range<usize>,
        chunk: usize,
        init: impl Fn() -> S + Sync + Send,
        f: impl Fn(&mut S, usize, &[T]) -> T + Sync + Send,
    ) where
        T: Send + Sync,
    {
        assert!(
            self.done.is_empty() && range.start <= range.end && range.end <= self.n - self.late,
            "fill_range: {range:?} of {} elements before a tail of {}, {:?} done",
            self.n,
            self.late,
            self.done
        );
        let (h, t) = self.buf.spare_capacity_mut()[..self.n].split_at_mut(self.n - self.late);
        // SAFETY: `par_tail` wrote every slot of `t`, and `MaybeUninit<T>` has the layout of
        // `T`.
        let t: &[T] = unsafe { std::slice::from_raw_parts(t.as_ptr().cast::<T>(), t.len()) };
        let start = range.start;
        par_fill(&mut h[range.clone()], chunk, init, |s, k| {
            f(s, start + k, t)
        });
        self.done = range;
    }

    /// The computed elements, `n - late..n` of the finished vector.
    #[cfg(test)]
    pub(crate) fn computed(&self) -> &[T] {
        // SAFETY: the buffer's capacity is at least `n`, and `par_tail` wrote every slot of
        // `n - late..n` before returning the `Tail`.
        unsafe { std::slice::from_raw_parts(self.buf.as_ptr().add(self.n - self.late), self.late) }
    }
}

impl<T> Drop for Tail<T> {
    fn drop(&mut self) {
        // SAFETY: the slots `n - late..n` and `done` of the buffer's capacity are initialised
        // (`par_tail`, `fill_range`) and dropped once, here; `par_head` takes the buffer out
        // without running this.
        unsafe {
            let base = self.buf.as_mut_ptr();
            let tail = base.add(self.n - self.late);
            std::ptr::drop_in_place(std::ptr::slice_from_raw_parts_mut(tail, self.late));
            let done = base.add(self.done.start);
            std::ptr::drop_in_place(std::ptr::slice_from_raw_parts_mut(done, self.done.len()));
        }
    }
}

/// The last `late` of `n` elements (`tail(&mut state, k)` for element `n - late + k`),
/// computed in parallel chunks of `chunk`, in a buffer of `n` for [`par_head`] to finish.
///
/// # Panics
/// If `late > n`, if `chunk` is 0, or if `tail` panics.
pub(crate) fn par_tail<T, S>(
    n: usize,
    late: usize,
    chunk: usize,
    init: impl Fn() -> S + Sync + Send,
    tail: impl Fn(&mut S, usize) -> T + Sync + Send,
) -> Tail<T>
where
    T: Send,
{
    assert!(late <= n, "par_tail: {late} late elements of {n}");
    let mut buf = Vec::with_capacity(n);
    par_fill(
        &mut buf.spare_capacity_mut()[n - late..n],
        chunk,
        init,
        tail,
    );
    Tail {
        buf,
        n,
        late,
        done: 0..0,
    }
}

/// Finishes `t` ([`par_tail`]): element `j < n - late` outside the range computed already
/// ([`Tail::fill_range`]) is `head(&mut state, j, tail)`, `tail` being the elements
/// `n - late..n`; in parallel chunks of `chunk`.
///
/// # Panics
/// If `chunk` is 0, or if `head` panics.
pub(crate) fn par_head<T, S>(
    t: Tail<T>,
    chunk: usize,
    init: impl Fn() -> S + Sync + Send,
    head: impl Fn(&mut S, usize, &[T]) -> T + Sync + Send,
) -> Vec<T>
where
    T: Send + Sync,
{
    // Taken apart without `Tail`'s drop: the elements move into the finished vector.
    let mut t = std::mem::ManuallyDrop::new(t);
    let (mut buf, n, late, done) = (std::mem::take(&mut t.buf), t.n, t.late, t.done.clone());
    let (h, t) = buf.spare_capacity_mut()[..n].split_at_mut(n - late);
    // SAFETY: `par_tail` wrote every slot of `t`, and `MaybeUninit<T>` has the layout of `T`.
    let t: &[T] = unsafe { std::slice::from_raw_parts(t.as_ptr().cast::<T>(), t.len()) };
    let (before, rest) = h.split_at_mut(done.start);
    par_fill(before, chunk, &init, |s, j| head(s, j, t));
    let after = &mut rest[done.len()..];
    par_fill(after, chunk, &init, |s, k| head(s, done.end + k, t));
    // SAFETY: the fills wrote the slots around `done`, written before, and the tail: the
    // first `n`.
    unsafe { buf.set_len(n) };
    buf
}

/// Uninitialised slots written front to back: the writer of one part of a vector built by
/// [`par_parts`] or [`par_parts2`], which check that every part is written full.
pub(crate) struct Filler<'a, T> {
    slots: &'a mut [std::mem::MaybeUninit<T>],
    len: usize,
}

impl<T: Copy> Filler<'_, T> {
    /// Writes the next slot (a bounds-check panic past the part's end).
    #[inline(always)]
    pub(crate) fn push(&mut self, x: T) {
        self.slots[self.len].write(x);
        self.len += 1;
    }

    /// Writes the next `xs.len()` slots.
    #[inline(always)]
    pub(crate) fn extend(&mut self, xs: &[T]) {
        let dst = &mut self.slots[self.len..self.len + xs.len()];
        for (d, &x) in dst.iter_mut().zip(xs) {
            d.write(x);
        }
        self.len += xs.len();
    }

    /// How many slots are written.
    #[inline(always)]
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The written slots from `from` on (empty if `from` is past them).
    pub(crate) fn written_from(&mut self, from: usize) -> &mut [T] {
        let from = from.min(self.len);
        let w = &mut self.slots[from..self.len];
        // SAFETY: slots below `len` were written (by `push` or `extend`), and
        // `MaybeUninit<T>` has the layout of `T`.
        unsafe { std::slice::from_raw_parts_mut(w.as_mut_ptr().cast::<T>(), w.len()) }
    }

    fn is_full(&self) -> bool {
        self.len == self.slots.len()
    }
}

/// Cuts the spare capacity of `v` (empty, with capacity for the sum of the parts' lengths)
/// into consecutive fillers of the jobs' lengths.
fn fillers<'a, T, J>(v: &'a mut Vec<T>, jobs: Vec<(J, usize)>) -> Vec<(J, Filler<'a, T>)> {
    let mut rest = v.spare_capacity_mut();
    jobs.into_iter()
        .map(|(job, len)| {
            let (slots, tail) = std::mem::take(&mut rest).split_at_mut(len);
            rest = tail;
            (job, Filler { slots, len: 0 })
        })
        .collect()
}

/// A vector of the jobs' lengths' sum, its consecutive parts (one per job, of the job's
/// length) written in parallel by `fill`, without zeroing the buffer first (a large zeroed
/// allocation costs a `memset` when the allocator reuses memory).
///
/// # Panics
/// If `fill` panics, or leaves a part not written full (nothing is returned then).
pub(crate) fn par_parts<T, J>(
    jobs: Vec<(J, usize)>,
    fill: impl Fn(J, &mut Filler<T>) + Sync + Send,
) -> Vec<T>
where
    T: Copy + Send,
    J: Send,
{
    let n = jobs.iter().map(|j| j.1).sum();
    let mut out = Vec::with_capacity(n);
    let full = fillers(&mut out, jobs)
        .into_par_iter()
        .map(|(job, mut f)| {
            fill(job, &mut f);
            f.is_full()
        })
        .all(|x| x);
    assert!(full, "par_parts: a part was not written full");
    // SAFETY: the fillers cover the first `n` slots, and each was written full (checked).
    unsafe { out.set_len(n) };
    out
}

/// A vector of `n` elements written front to back by `fill` (serially), without zeroing
/// the buffer first.
///
/// # Panics
/// If `fill` panics, or writes fewer or more than `n` elements.
pub(crate) fn filled_vec<T: Copy>(n: usize, fill: impl FnOnce(&mut Filler<T>)) -> Vec<T> {
    let mut out = Vec::with_capacity(n);
    let mut f = Filler {
        slots: &mut out.spare_capacity_mut()[..n],
        len: 0,
    };
    fill(&mut f);
    assert!(f.is_full(), "filled_vec: {} of {n} elements written", f.len);
    // SAFETY: the filler's slots are the first `n`, all written (checked).
    unsafe { out.set_len(n) };
    out
}

/// [`par_parts`] with two vectors of the same lengths, written side by side.
///
/// # Panics
/// As [`par_parts`].
pub(crate) fn par_parts2<A, B, J>(
    jobs: Vec<(J, usize)>,
    fill: impl Fn(J, &mut Filler<A>, &mut Filler<B>) + Sync + Send,
) -> (Vec<A>, Vec<B>)
where
    A: Copy + Send,
    B: Copy + Send,
    J: Send,
{
    let n = jobs.iter().map(|j| j.1).sum();
    let lens: Vec<usize> = jobs.iter().map(|j| j.1).collect();
    let (mut a, mut b) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let fa = fillers(&mut a, jobs);
    let fb = fillers(&mut b, lens.into_iter().map(|l| ((), l)).collect());
    let full = fa
        .into_par_iter()
        .zip(fb)
        .map(|((job, mut x), (_, mut y))| {
            fill(job, &mut x, &mut y);
            x.is_full() && y.is_full()
        })
        .all(|x| x);
    assert!(full, "par_parts2: a part was not written full");
    // SAFETY: the fillers of each vector cover its first `n` slots, and each was written full
    // (checked).
    unsafe {
        a.set_len(n);
        b.set_len(n);
    }
    (a, b)
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

    /// A tail computed apart ([`super::par_tail`]), and a range before it
    /// ([`super::Tail::fill_range`]), are what [`super::par_head`] reads and keeps; a `Tail`
    /// dropped unfinished drops the elements it computed.
    #[test]
    fn a_tail_finishes_later() {
        let t = super::par_tail(10_000, 3_000, 64, || (), |_, k| (7_000 + k) as u64 * 2);
        assert_eq!((t.len(), t.late()), (10_000, 3_000));
        assert_eq!(t.computed()[..2], [14_000, 14_002]);
        let v = super::par_head(t, 64, || (), |_, j, tail: &[u64]| j as u64 + tail[0]);
        let want: Vec<u64> = (0..10_000u64)
            .map(|j| if j < 7_000 { j + 14_000 } else { 2 * j })
            .collect();
        assert_eq!(v, want);
        // A range before the tail, computed apart, is kept.
        let mut t = super::par_tail(10_000, 3_000, 64, || (), |_, k| (7_000 + k) as u64 * 2);
        t.fill_range(
            100..5_000,
            64,
            || (),
            |_, j, tail: &[u64]| j as u64 + tail[1],
        );
        let v = super::par_head(t, 64, || (), |_, j, _: &[u64]| j as u64);
        let want: Vec<u64> = (0..10_000u64)
            .map(|j| match j {
                100..5_000 => j + 14_002,
                7_000.. => 2 * j,
                _ => j,
            })
            .collect();
        assert_eq!(v, want);
        // Unfinished, its computed elements are dropped (each `Arc` clone released).
        let rc = std::sync::Arc::new(());
        let mut t = super::par_tail(100, 10, 8, || (), |_, _| rc.clone());
        t.fill_range(
            20..25,
            8,
            || (),
            |_, _, _: &[std::sync::Arc<()>]| rc.clone(),
        );
        assert_eq!(std::sync::Arc::strong_count(&rc), 16);
        drop(t);
        assert_eq!(std::sync::Arc::strong_count(&rc), 1);
    }

    #[test]
    fn parts_are_written_in_order() {
        let jobs: Vec<(usize, usize)> = [3, 0, 5, 1].into_iter().enumerate().collect();
        let v = super::par_parts(jobs.clone(), |j, f| {
            for k in 0..[3, 0, 5, 1][j] {
                f.push(10 * j + k);
            }
            f.written_from(0).reverse();
        });
        assert_eq!(v, [2, 1, 0, 24, 23, 22, 21, 20, 30]);
        let (a, b) = super::par_parts2(jobs, |j, x, y| {
            let n = [3, 0, 5, 1][j];
            x.extend(&vec![j as u8; n]);
            (0..n).for_each(|k| y.push(k as u16));
            assert_eq!(x.len(), y.len());
        });
        assert_eq!(a, [0, 0, 0, 2, 2, 2, 2, 2, 3]);
        assert_eq!(b, [0, 1, 2, 0, 1, 2, 3, 4, 0]);
    }

    #[test]
    fn filled_vec_writes_front_to_back() {
        assert_eq!(super::filled_vec(3, |f| f.extend(&[1u8, 2, 3])), [1, 2, 3]);
        assert!(super::filled_vec::<u8>(0, |_| ()).is_empty());
        let r = std::panic::catch_unwind(|| super::filled_vec(3, |f| f.push(1u8)));
        assert!(r.is_err(), "a short fill panics");
    }

    #[test]
    #[should_panic(expected = "not written full")]
    fn a_part_left_short_panics() {
        super::par_parts(vec![((), 4)], |_, f| f.push(1u32));
    }

    #[test]
    #[should_panic(expected = "out of range")]
    fn a_part_written_past_its_end_panics() {
        super::par_parts(vec![((), 1), ((), 1)], |_, f| f.extend(&[1u32, 2]));
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

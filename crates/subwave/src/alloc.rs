//! A global allocator that backs large allocations with transparent huge pages.
//!
//! Refinement, stencil evaluation and decoding write buffers of tens to hundreds of megabytes
//! that nothing has touched before (the bunny's third Loop level alone is 2.2 M positions and
//! 4.4 M triangles). The first write to each 4 KiB page of such a buffer is a page fault that
//! the kernel serves by zeroing the page; on a virtual machine it can also exit to the host.
//! Measured here (2-core VM, `/sys/kernel/mm/transparent_hugepage/enabled` = `madvise`),
//! first-touching 400 MiB took 450–520 ms in 4 KiB pages and 50–90 ms once the range was
//! advised `MADV_HUGEPAGE` (one fault per 2 MiB): most of the time of a plain subdivision of
//! the bunny can go into page faults.
//!
//! [`HugePages`] wraps [mimalloc](https://github.com/microsoft/mimalloc) (which keeps freed
//! memory for reuse instead of returning it to the kernel at once, as glibc does with large
//! blocks, so repeated refinements — an animation re-subdividing every frame, a benchmark's
//! runs — fault far fewer pages; [`HugePages`] has it keep freed memory for good,
//! [`PURGE_DELAY_MS`]) and advises every allocation of at least
//! [`HUGE_THRESHOLD`] bytes as `MADV_HUGEPAGE` before it is returned, so that its first
//! touch faults in 2 MiB pages where the kernel allows it (`madvise` or `always` mode). It
//! changes no result, only where the memory comes from; elsewhere than Linux it is mimalloc
//! alone. Measured on the bunny's third Loop level (median of 15 runs, three alternations):
//! glibc with the advice 206–226 ms, mimalloc alone 200–208 ms, mimalloc with the advice
//! 157–182 ms. Binaries opt in (a library cannot choose the global allocator):
//!
//! ```
//! #[global_allocator]
//! static ALLOC: subwave::alloc::HugePages = subwave::alloc::HugePages;
//! ```
//!
//! Huge pages only pay where a buffer is written through: on this VM a huge-page fault can
//! cost milliseconds, so the `subwave` executable turns them off ([`disable_huge_pages`])
//! for every command but refinement (remeshing the bunny: 1.2–1.9 s of kernel time less).
//!
//! The cost of a first touch depends on how the VM's host backs the memory, and it changes
//! from day to day. Measured again on 2026-12-05 (400 MiB touched once per page, a C program
//! beside this crate): 4 KiB pages 126–132 ms every time, huge pages 47–2,822 ms (nine runs:
//! 2,613, 52, 238, 92, 211, 773, 2,822, 47, 211). A one-shot `subwave subdivide` of the
//! bunny's third Catmull-Clark level took 0.28–2.02 s (median 0.45 s of 8) with huge pages
//! and 0.33–0.36 s without (run under `prctl(PR_SET_THP_DISABLE)`), while repeated
//! refinements, which fault nothing once warm, were faster with them (`vs_opensubdiv`
//! medians 92 against 101 ms: fewer TLB misses). Refinement keeps them for now; a one-shot
//! command on such a host may do better without.
//!
//! The `subwave` executable, the benchmarks and the OpenSubdiv comparison use it (the
//! comparison's C++ side keeps glibc's allocator; glibc's tunable
//! `GLIBC_TUNABLES=glibc.malloc.hugetlb=1` gives it the huge-page advice too).

use std::alloc::{GlobalAlloc, Layout};
use std::sync::atomic::{AtomicBool, Ordering};

use mimalloc::MiMalloc as Inner;

/// mimalloc's purge delay as [`HugePages`] sets it before its first allocation: how long
/// freed memory stays committed in the process for reuse before mimalloc returns it to the
/// kernel, in milliseconds; −1 (this value) never returns it (mimalloc's default is 1,000).
///
/// A refinement frees hundreds of megabytes that the next one needs again; memory returned
/// to the kernel in between is faulted in again, page by page. Measured on the 2-core VM of
/// the issues (2026-12-04, bunny, third Catmull-Clark level, each refinement 0.5–4 s after
/// the last with OpenSubdiv's refinement in between): with mimalloc's default, 3,000–5,000
/// page faults in many refinements and medians of 113–127 ms (`vs_opensubdiv`'s alternating
/// rounds); with a delay of 10 s, still 3,000–3,800 faults in some (mimalloc also purges
/// outside the delay); never purging, none, and 98–105 ms. Back-to-back refinements fault
/// almost nothing either way, and the peak resident memory is the same (the bunny's encode:
/// 205–220 MB both ways): freed memory is reused, not added to. The cost: a process keeps
/// its high-water mark of memory until it exits.
pub const PURGE_DELAY_MS: i64 = -1;

/// mimalloc's `mi_option_purge_delay`: the sixteenth entry of its option enumeration
/// (`mimalloc.h`, versions 2 and 3), which `libmimalloc-sys` does not name.
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Whether [`configure`] ran.
static CONFIGURED: AtomicBool = AtomicBool::new(false);

/// Sets mimalloc's options once ([`PURGE_DELAY_MS`]); cheap after the first call.
#[inline]
fn configure() {
    if !CONFIGURED.load(Ordering::Relaxed) && !CONFIGURED.swap(true, Ordering::AcqRel) {
        // SAFETY: `mi_option_set` stores an integer option; the swap makes this the only
        // call, and the option is read by mimalloc only when it purges.
        unsafe {
            libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, PURGE_DELAY_MS as _);
        }
    }
}

/// Allocations of at least this many bytes (4 MiB) are advised to use huge pages.
pub const HUGE_THRESHOLD: usize = 4 << 20;

/// mimalloc, with allocations of [`HUGE_THRESHOLD`] bytes or more advised
/// `MADV_HUGEPAGE` (see the module documentation).
#[derive(Clone, Copy, Debug, Default)]
pub struct HugePages;

/// Advises the 2 MiB-aligned interior of `[ptr, ptr + size)` as huge-page memory (a hint: an
/// error is ignored, the memory then stays in small pages).
#[inline]
fn advise(ptr: *mut u8, size: usize) {
    #[cfg(target_os = "linux")]
    if !ptr.is_null() && size >= HUGE_THRESHOLD {
        const HUGE: usize = 2 << 20;
        let start = (ptr as usize).next_multiple_of(HUGE);
        let end = (ptr as usize + size) & !(HUGE - 1);
        if end > start {
            // SAFETY: `[start, end)` lies inside the allocation just made, which this
            // process owns; MADV_HUGEPAGE changes no contents and no mapping, only how
            // future faults in the range are served.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, size);
}

/// Turns transparent huge pages off for the whole process (Linux
/// `prctl(PR_SET_THP_DISABLE)`; no effect elsewhere): from then on every page fault maps a
/// 4 KiB page, whatever [`HugePages`] or mimalloc advise.
///
/// For workloads of many medium-sized, partly touched or short-lived buffers, where a huge
/// page is zeroed for a few kilobytes of use. Measured on the 2-core VM of
/// the issues (2026-12-04, `encode` of stanford-bunny, three alternations): with huge pages
/// 140–154 of them were faulted (by mimalloc's own arenas as much as by the advice) for
/// 1.2–1.9 s of kernel time and 2.97–3.74 s in all; without, 0.16–0.20 s and 2.29–2.50 s. A
/// large refinement, which writes every byte of its buffers, keeps them (`subdivide` of the
/// bunny's third Loop level was 10–15% faster with them).
///
/// # Errors
/// The `prctl` error (Linux before 3.15); the process then keeps huge pages.
pub fn disable_huge_pages() -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: PR_SET_THP_DISABLE takes one integer argument and changes only the
        // kernel's paging policy for this process; the unused arguments are 0 as required.
        let r = unsafe { libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0) };
        if r != 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    Ok(())
}

// SAFETY: every method forwards to mimalloc with the same arguments and returns its result;
// `advise` only gives the kernel a hint about memory mimalloc has just handed out.
unsafe impl GlobalAlloc for HugePages {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        configure();
        let p = Inner.alloc(layout);
        advise(p, layout.size());
        p
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        configure();
        let p = Inner.alloc_zeroed(layout);
        advise(p, layout.size());
        p
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        Inner.dealloc(ptr, layout)
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = Inner.realloc(ptr, layout, new_size);
        if new_size > layout.size() {
            advise(p, new_size);
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_pages_can_be_disabled() {
        // Process-wide, but only a paging policy: the other tests' results do not change.
        disable_huge_pages().expect("prctl(PR_SET_THP_DISABLE)");
        #[cfg(target_os = "linux")]
        {
            // SAFETY: PR_GET_THP_DISABLE takes no argument and reads the flag.
            let flag = unsafe { libc::prctl(libc::PR_GET_THP_DISABLE, 0, 0, 0, 0) };
            assert_eq!(flag, 1, "huge pages are disabled for the process");
        }
        let v = vec![1u8; 3 * HUGE_THRESHOLD];
        assert!(v.iter().all(|&b| b == 1), "allocations still work");
    }

    // The test tells mimalloc's default from the setting.
    const _: () = assert!(PURGE_DELAY_MS != 1000);

    /// Option 15 is mimalloc's purge delay (default 1,000 ms, unless an earlier test's
    /// allocation already set it), and an allocation through [`HugePages`] sets it.
    #[test]
    // `c_long` is `i64` here but `i32` on Windows.
    #[allow(clippy::useless_conversion)]
    fn the_first_allocation_sets_the_purge_delay() {
        if std::env::var_os("MIMALLOC_PURGE_DELAY").is_some() {
            return;
        }
        // SAFETY: reading an option has no precondition.
        let before = i64::from(unsafe { libmimalloc_sys::mi_option_get(MI_OPTION_PURGE_DELAY) });
        assert!(
            before == 1000 || (before == PURGE_DELAY_MS && CONFIGURED.load(Ordering::Relaxed)),
            "option 15 is {before}: not mimalloc's purge delay"
        );
        let layout = Layout::from_size_align(64, 8).unwrap();
        // SAFETY: a valid layout, freed with the same layout.
        unsafe {
            let p = HugePages.alloc(layout);
            assert!(!p.is_null());
            HugePages.dealloc(p, layout);
            assert_eq!(
                i64::from(libmimalloc_sys::mi_option_get(MI_OPTION_PURGE_DELAY)),
                PURGE_DELAY_MS
            );
        }
    }

    #[test]
    fn large_and_small_allocations_work() {
        let a = HugePages;
        for size in [
            1usize,
            4096,
            HUGE_THRESHOLD - 1,
            HUGE_THRESHOLD,
            3 * HUGE_THRESHOLD + 7,
        ] {
            let layout = Layout::from_size_align(size, 64).unwrap();
            unsafe {
                let p = a.alloc_zeroed(layout);
                assert!(!p.is_null());
                assert_eq!(*p, 0);
                assert_eq!(*p.add(size - 1), 0);
                *p.add(size - 1) = 7;
                let q = a.realloc(p, layout, 2 * size);
                assert!(!q.is_null());
                assert_eq!(*q.add(size - 1), 7, "realloc keeps the contents");
                a.dealloc(q, Layout::from_size_align(2 * size, 64).unwrap());
            }
        }
    }
}

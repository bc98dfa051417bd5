//! A worker thread's malloc heap on transparent huge pages.
//!
//! Each analysis thread allocates its channels' state, histories and decoded blocks from its
//! own glibc arena: about 2 MB of fresh memory per thread in a 64-channel × 10 s run, all of it
//! page faults on 4 kB pages (~500 per thread, 1.2 µs each on the 2-core VM this was measured
//! on: ~1 ms of the run's ~19 ms of CPU). On one 2 MB page it is one fault.
//!
//! glibc maps a thread arena's heap as one region of `HEAP_MAX_BYTES` aligned to its own size
//! (the address of any chunk of it, rounded down, is the heap's start) and grows it in place.
//! The advice covers that region; its first 2 MB, where the arena's header was already
//! written on small pages, is collapsed into a huge page at once (`MADV_COLLAPSE`, Linux ≥ 6.1:
//! 0.09 ms against 0.6 ms of faults). Where the assumption does not hold (another allocator, an
//! older kernel, huge pages off) the calls land on memory of this process or are refused: they
//! change only how pages are backed, never what they hold.

/// glibc's `HEAP_MAX_SIZE` on 64-bit targets: 2 × `DEFAULT_MMAP_THRESHOLD_MAX` (32 MiB).
#[cfg(all(target_os = "linux", target_env = "gnu", target_pointer_width = "64"))]
const HEAP_MAX_BYTES: usize = 64 << 20;

#[cfg(all(target_os = "linux", target_env = "gnu", target_pointer_width = "64"))]
use crate::frontend::decay_arena::HUGE_PAGE_BYTES;

/// Bytes of the allocation whose address locates the arena's heap: above glibc's per-thread
/// cache (at most 1032 bytes, which may hold chunks of other arenas freed by this thread) and
/// below its mapping threshold (at least 128 KiB), so it comes from this thread's arena.
#[cfg(all(target_os = "linux", target_env = "gnu", target_pointer_width = "64"))]
const PROBE_BYTES: usize = 4096;

/// Fresh heap memory a thread expects to use (its decoded blocks) from which the first 2 MB
/// is collapsed at once: below, its few pages fault in cheaper than a collapse (128 pages ×
/// 1.2 µs against 0.09 ms).
#[cfg(all(target_os = "linux", target_env = "gnu", target_pointer_width = "64"))]
const COLLAPSE_FROM_BYTES: usize = 512 << 10;

/// Asks for huge pages on the heap of the calling thread's malloc arena, expecting to use
/// `expected_bytes` of it: call it first thing in a thread, and again with more bytes once the
/// thread knows it will use them (the reader, when its blocks turn out to be its own buffers).
/// Performance only: nothing changes where it does not apply.
pub(super) fn advise_huge_pages(expected_bytes: usize) {
    #[cfg(not(all(target_os = "linux", target_env = "gnu", target_pointer_width = "64")))]
    let _ = expected_bytes;
    #[cfg(all(target_os = "linux", target_env = "gnu", target_pointer_width = "64"))]
    {
        let probe: Vec<u8> = Vec::with_capacity(PROBE_BYTES);
        let heap = probe.as_ptr() as usize & !(HEAP_MAX_BYTES - 1);
        // SAFETY: advice only (no memory is freed, moved or changed in content); on a range
        // that is not wholly mapped the kernel advises the mapped parts or refuses.
        unsafe {
            let heap = heap as *mut libc::c_void;
            if libc::madvise(heap, HEAP_MAX_BYTES, libc::MADV_HUGEPAGE) == 0
                && expected_bytes >= COLLAPSE_FROM_BYTES
            {
                libc::madvise(heap, HUGE_PAGE_BYTES, libc::MADV_COLLAPSE);
            }
        }
    }
}

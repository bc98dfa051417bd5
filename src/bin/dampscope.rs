//! The `dampscope` binary: a thin shell around [`dampscope::cli`].

fn main() {
    // Rust ignores SIGPIPE, so a closed pipe (`dampscope demo | head -1`) made every print
    // panic. Restore the default action: the process ends quietly, like any Unix filter.
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any thread exists; SIG_DFL is a valid action
    // for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: called before any thread exists; M_TOP_PAD takes any non-negative byte count.
    unsafe {
        libc::mallopt(libc::M_TOP_PAD, MALLOC_TOP_PAD_BYTES);
        libc::mallopt(libc::M_MMAP_THRESHOLD, MALLOC_MMAP_THRESHOLD_BYTES);
    }
    std::process::exit(dampscope::cli::main_exit_code());
}

/// Bytes glibc adds whenever a heap grows (its default: 128 KiB). Each worker thread's heap
/// grows as decays accumulate; at the default step a 64-channel × 10 s run made ~390 `mprotect`
/// calls, each taking the address-space lock that the other thread's page faults need (4 % of
/// the CPU, ~1 ms of an 18 ms run). Growing 16 MiB at a time leaves ~15 calls and costs no
/// memory: the pages are only reserved until touched.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MALLOC_TOP_PAD_BYTES: libc::c_int = 16 << 20;

/// Smallest allocation glibc maps on its own instead of taking from a heap (its default: 128
/// KiB, rising to the largest freed). A reader's blocks are 1 MiB buffers: mapped apart, each
/// one is 256 page faults and an unmapping; from the thread's heap, on its huge pages
/// (`pipeline/thread_heap.rs`), they are a fraction of one.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MALLOC_MMAP_THRESHOLD_BYTES: libc::c_int = 4 << 20;

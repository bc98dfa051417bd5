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
    keep_freed_memory();
    std::process::exit(dampscope::cli::main_exit_code());
}

/// Largest allocation glibc serves from its heap instead of a fresh mapping of its own, bytes.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const HEAP_ALLOCATION_LIMIT_BYTES: libc::c_int = 64 << 20;

/// Lets glibc reuse freed buffers instead of unmapping them. By default every allocation over
/// 128 kB (a decay's frame history, a block of a 64-channel stream) gets pages of its own,
/// returned on free and faulted in anew on the next one: page faults were 15–20 % of a run's
/// time. Memory is bounded as before (what is freed is reused, not grown).
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: called before any thread exists; both are documented mallopt parameters.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, HEAP_ALLOCATION_LIMIT_BYTES);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 4 * HEAP_ALLOCATION_LIMIT_BYTES);
    }
}

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
    std::process::exit(dampscope::cli::main_exit_code());
}

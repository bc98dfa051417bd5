//! Standard input from a pipe, read in larger gulps.
//!
//! A pipe holds 64 KiB by default: a writer such as `cat` fills it, the reader empties it, and
//! each side sleeps while the other works — 160 round trips for a 10 MB recording, and blocks of
//! at most 64 KiB (256 frames of 64 channels, too few for a frame pair of the STFT). Linux lets
//! either end enlarge the pipe up to `/proc/sys/fs/pipe-max-size` (1 MiB by default).

use std::fs::File;

/// Bytes asked for a pipe's buffer: the size of a reader block (`frames::MAX_BLOCK_BYTES`).
#[cfg(target_os = "linux")]
const PIPE_BYTES: libc::c_int = 1 << 20;

/// Enlarges the buffer of `file` when it is a pipe; anything else, or a refusal (a smaller
/// system limit), leaves it as it is.
pub(crate) fn widen(file: &File) {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        use std::os::unix::fs::FileTypeExt;
        if file.metadata().is_ok_and(|m| m.file_type().is_fifo()) {
            // SAFETY: F_SETPIPE_SZ on an open descriptor that `file` owns; it only resizes the
            // pipe's buffer, and failure is an error code.
            unsafe {
                libc::fcntl(file.as_raw_fd(), libc::F_SETPIPE_SZ, PIPE_BYTES);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = file;
}

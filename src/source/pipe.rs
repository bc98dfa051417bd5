//! Standard input from a pipe, read in larger gulps, and watched for a writer's pauses.
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

/// How long a stream may pause, ms, before the frames it sent are handed out in a block not
/// yet full (`FrameReader::wake_on_pause`). A writer that keeps up never waits this long
/// between writes (a recorder writes every few ms, `cat` continuously), so its blocks are the
/// file's; one that stops and waits for rows is answered within this.
pub const STREAM_PAUSE_MS: i32 = 250;

/// Whether bytes, the end or an error arrive on descriptor `fd` within `ms` milliseconds
/// (`poll`; an interrupted wait is resumed). Without `poll`, always.
pub(crate) fn arrives_within(fd: i32, ms: i32) -> bool {
    #[cfg(unix)]
    {
        let mut watch = libc::pollfd {
            fd,
            events: libc::POLLIN,
            revents: 0,
        };
        loop {
            // SAFETY: one pollfd, valid for the call; the caller keeps `fd` open.
            let n = unsafe { libc::poll(&mut watch, 1, ms) };
            if n >= 0 || std::io::Error::last_os_error().kind() != std::io::ErrorKind::Interrupted {
                // Readable, closed (POLLHUP) or an error: the read tells which.
                return n != 0;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (fd, ms);
        true
    }
}

/// A reader that, while its flag is set, answers a read that would wait longer than
/// [`STREAM_PAUSE_MS`] for the writer with `WouldBlock` instead of waiting: a line-by-line
/// source ([`super::csv::CsvSource`]) sets the flag once a block holds rows, and hands them out
/// when its writer pauses.
pub(crate) struct PausingReader<R> {
    inner: R,
    fd: i32,
    armed: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl<R> PausingReader<R> {
    /// `inner`, whose bytes arrive on descriptor `fd`, and the flag its reader sets.
    pub(crate) fn new(inner: R, fd: i32) -> (Self, std::sync::Arc<std::sync::atomic::AtomicBool>) {
        let armed = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        (
            PausingReader {
                inner,
                fd,
                armed: armed.clone(),
            },
            armed,
        )
    }
}

impl<R: std::io::Read> std::io::Read for PausingReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.armed.load(std::sync::atomic::Ordering::Relaxed)
            && !arrives_within(self.fd, STREAM_PAUSE_MS)
        {
            return Err(std::io::ErrorKind::WouldBlock.into());
        }
        self.inner.read(buf)
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;
    use std::os::fd::{AsRawFd, FromRawFd};

    /// A pipe grows to 1 MiB (or the system's limit, if lower).
    #[test]
    fn a_pipe_is_widened() {
        let mut fds = [0; 2];
        // SAFETY: `pipe` writes two new descriptors into `fds`, owned by the files below.
        assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
        // SAFETY: both descriptors are fresh and owned by nothing else.
        let (read_end, _write_end) =
            unsafe { (File::from_raw_fd(fds[0]), File::from_raw_fd(fds[1])) };
        // SAFETY: F_GETPIPE_SZ only reads the pipe's size.
        let size = |f: &File| unsafe { libc::fcntl(f.as_raw_fd(), libc::F_GETPIPE_SZ) };
        let before = size(&read_end);
        widen(&read_end);
        let limit: libc::c_int = std::fs::read_to_string("/proc/sys/fs/pipe-max-size")
            .ok()
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or(PIPE_BYTES);
        assert_eq!(size(&read_end), PIPE_BYTES.min(limit).max(before));
    }
}

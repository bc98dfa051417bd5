//! A regular file (or standard input redirected from one) read through the page cache's own
//! pages instead of `read` copies.
//!
//! Reading a 64-channel raw stream, the kernel's copy of each page into the reader's buffer was
//! a tenth of a whole 48 kHz run. Mapped, the decoder reads the page cache directly and the copy
//! is gone. Only regular files are mapped: a pipe or a terminal is read as a stream, as before.
//!
//! The one hazard of a mapping is a file that shrinks while it is read (another program
//! truncating it): the pages past its new end raise `SIGBUS`. That is why mapping is chosen only
//! for the raw decoder, whose input is a recording at rest, and why [`NO_MAP_ENV`] turns it off.

use std::fs::File;

/// Set this environment variable (to anything) to read every input as a stream, unmapped.
pub const NO_MAP_ENV: &str = "DAMPSCOPE_NO_MMAP";

/// The bytes of a file from a starting offset to its end (as long as the file was when mapped),
/// mapped read-only.
pub(crate) struct MappedBytes {
    /// Start of the mapping (page-aligned), and its length in bytes.
    base: *mut std::ffi::c_void,
    map_len: usize,
    /// Where the wanted bytes start within the mapping (the offset's distance from its page).
    skip: usize,
}

// SAFETY: the mapping is read-only and private to this value; the bytes it exposes are plain
// memory that any thread may read, and it is unmapped exactly once, on drop.
unsafe impl Send for MappedBytes {}
unsafe impl Sync for MappedBytes {}

impl MappedBytes {
    /// The file's bytes from its current read position on, when it is a regular file with at
    /// least one byte left and mapping is allowed; `None` otherwise (read it as a stream).
    #[cfg(unix)]
    pub(crate) fn rest_of(file: &File) -> Option<Self> {
        use std::os::fd::AsRawFd;
        if std::env::var_os(NO_MAP_ENV).is_some() {
            return None;
        }
        let meta = file.metadata().ok()?;
        if !meta.file_type().is_file() {
            return None;
        }
        let fd = file.as_raw_fd();
        // SAFETY: `fd` is an open descriptor owned by `file`; lseek with offset 0 and SEEK_CUR
        // only reports the position.
        let offset = unsafe { libc::lseek(fd, 0, libc::SEEK_CUR) };
        let size = meta.len();
        if offset < 0 || offset as u64 >= size {
            return None;
        }
        // SAFETY: sysconf has no preconditions.
        let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
        let page = if page > 0 { page as u64 } else { 4096 };
        let start = offset as u64 / page * page;
        let map_len = usize::try_from(size - start).ok()?;
        // SAFETY: a fresh private read-only mapping of an open regular file, at a page-aligned
        // offset, of a positive length within the file; failure is reported as MAP_FAILED.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                map_len,
                libc::PROT_READ,
                libc::MAP_PRIVATE,
                fd,
                start as libc::off_t,
            )
        };
        if base == libc::MAP_FAILED {
            return None;
        }
        Some(MappedBytes {
            base,
            map_len,
            skip: (offset as u64 - start) as usize,
        })
    }

    /// Without memory mapping: always a stream.
    #[cfg(not(unix))]
    pub(crate) fn rest_of(_file: &File) -> Option<Self> {
        None
    }

    /// The mapped bytes.
    pub(crate) fn bytes(&self) -> &[u8] {
        // SAFETY: `base` maps `map_len` readable bytes for the life of `self`, `skip < map_len`.
        unsafe {
            std::slice::from_raw_parts(
                (self.base as *const u8).add(self.skip),
                self.map_len - self.skip,
            )
        }
    }
}

impl Drop for MappedBytes {
    fn drop(&mut self) {
        #[cfg(unix)]
        // SAFETY: `base`/`map_len` are exactly what mmap returned; nothing borrows the bytes
        // past `self`'s life.
        unsafe {
            libc::munmap(self.base, self.map_len);
        }
    }
}

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
use std::sync::Arc;

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
    /// The system's page size, bytes.
    page_bytes: usize,
    /// Whole-page ranges (offsets in the mapping) released and not yet unmapped, and how many
    /// bytes of them make a batch.
    released: std::sync::Mutex<Vec<std::ops::Range<usize>>>,
    release_batch_bytes: usize,
}

// SAFETY: the mapping is read-only and private to this value; the bytes it exposes are plain
// memory that any thread may read, and it is unmapped exactly once, on drop.
unsafe impl Send for MappedBytes {}
unsafe impl Sync for MappedBytes {}

impl MappedBytes {
    /// The file's bytes from its current read position on, when it is a regular file with at
    /// least one byte left and mapping is allowed; `None` otherwise (read it as a stream). The
    /// position is then moved to the file's end, where reading the rest would have left it: a
    /// command after dampscope on the same standard input (`{ dampscope analyze - …; cat; } <
    /// file`) sees what it would see after any reader, not the same bytes again.
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
        // SAFETY: as above; the new position is the file's size, a valid offset.
        unsafe { libc::lseek(fd, size as libc::off_t, libc::SEEK_SET) };
        Some(MappedBytes {
            base,
            map_len,
            skip: (offset as u64 - start) as usize,
            page_bytes: page as usize,
            released: Default::default(),
            release_batch_bytes: RELEASE_BATCH_BYTES,
        })
    }

    /// Without memory mapping: always a stream.
    #[cfg(not(unix))]
    pub(crate) fn rest_of(_file: &File) -> Option<Self> {
        None
    }

    /// Bytes mapped (from the offset on).
    pub(crate) fn len(&self) -> usize {
        self.map_len - self.skip
    }

    /// The mapped bytes `range` (within [`MappedBytes::len`]). Never ask for bytes a dropped
    /// [`MappedRange`] covered: its whole pages are gone (the reader hands each range out once
    /// and never reads it again; the blocks read theirs only while they hold them).
    pub(crate) fn slice(&self, range: std::ops::Range<usize>) -> &[u8] {
        assert!(range.start <= range.end && range.end <= self.len());
        // SAFETY: `base` maps `map_len` readable bytes for the life of `self`, less the pages
        // of ranges released ([`MappedRange`]), which are never sliced again; `range` lies
        // within the mapping (checked above).
        unsafe {
            std::slice::from_raw_parts(
                (self.base as *const u8).add(self.skip + range.start),
                range.len(),
            )
        }
    }

    /// Gives back the whole pages inside `range` (its partial pages at either end stay: a
    /// neighbouring range may hold them): unmapped once [`RELEASE_BATCH_BYTES`] have gathered,
    /// adjacent ranges in one call (each call interrupts the other cores to flush their TLBs).
    ///
    /// # Safety
    /// No reference into `range` may be alive, and `range` is never sliced again.
    unsafe fn release(&self, range: std::ops::Range<usize>) {
        #[cfg(unix)]
        {
            let page = self.page_bytes;
            let start = (self.skip + range.start).div_ceil(page) * page;
            let end = (self.skip + range.end) / page * page;
            if end <= start {
                return;
            }
            let mut released = self.released.lock().unwrap_or_else(|e| e.into_inner());
            released.push(start..end);
            let total: usize = released.iter().map(|r| r.len()).sum();
            if total < self.release_batch_bytes {
                return;
            }
            released.sort_unstable_by_key(|r| r.start);
            let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
            for r in released.drain(..) {
                match runs.last_mut() {
                    Some(last) if last.end == r.start => last.end = r.end,
                    _ => runs.push(r),
                }
            }
            for run in runs {
                // SAFETY: whole pages of our own mapping that nothing references any more
                // (caller's contract); a failure leaves them mapped until the whole goes.
                unsafe {
                    libc::munmap((self.base as *mut u8).add(run.start).cast(), run.len());
                }
            }
        }
    }
}

/// Bytes of released pages gathered before they are unmapped (see [`MappedRange`]).
const RELEASE_BATCH_BYTES: usize = 8 << 20;

/// A range of a mapped file handed to one reader (a block of frames); its whole pages are
/// given back when the range is dropped (unmapped with others, [`RELEASE_BATCH_BYTES`] at a
/// time).
///
/// Why: a mapped page costs the kernel work twice, when it is mapped and when it is unmapped.
/// Unmapped all at once, at the end of the input, that second half came after the last block
/// and before the finishing, on the critical path: 4.3 ms for a 123 MB input. Released as the
/// blocks go, mostly by the reading thread as it recycles them, it overlaps the analysis.
pub(crate) struct MappedRange {
    map: Arc<MappedBytes>,
    range: std::ops::Range<usize>,
}

impl MappedRange {
    /// `range` of `map`, to be given out once (each byte of the file to one range).
    pub(crate) fn new(map: Arc<MappedBytes>, range: std::ops::Range<usize>) -> Self {
        assert!(range.end <= map.len());
        MappedRange { map, range }
    }

    /// Its bytes.
    pub(crate) fn bytes(&self) -> &[u8] {
        self.map.slice(self.range.clone())
    }
}

impl Drop for MappedRange {
    fn drop(&mut self) {
        // SAFETY: the range was given out once ([`MappedRange::new`]), and its bytes are only
        // borrowed through `&self`, so none is referenced once it is dropped.
        unsafe { self.map.release(self.range.clone()) }
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

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::io::Write;

    /// Whether the page holding `p` is mapped in this process (`mincore` refuses unmapped
    /// addresses).
    fn is_mapped(p: *const u8, page: usize) -> bool {
        let start = (p as usize / page * page) as *mut libc::c_void;
        let mut v = 0u8;
        // SAFETY: mincore only inspects the address range and writes one byte for one page.
        unsafe { libc::mincore(start, page, &mut v) == 0 }
    }

    /// The mapping starts at the file's read position and leaves it at the end, as a reader
    /// of the rest would.
    #[test]
    fn mapping_the_rest_consumes_it_like_a_reader() {
        use std::io::{Read, Seek};
        let path = std::env::temp_dir().join(format!("dampscope-rest-{}", std::process::id()));
        let bytes: Vec<u8> = (0..10_000).map(|i| (i % 253) as u8).collect();
        std::fs::File::create(&path)
            .unwrap()
            .write_all(&bytes)
            .unwrap();
        let mut file = std::fs::File::open(&path).unwrap();
        file.read_exact(&mut [0u8; 4100]).unwrap();
        let map = Arc::new(MappedBytes::rest_of(&file).unwrap());
        assert_eq!(map.len(), 10_000 - 4100);
        assert_eq!(map.slice(0..map.len()), &bytes[4100..]);
        assert_eq!(file.stream_position().unwrap(), 10_000);
        assert_eq!(file.read(&mut [0u8; 16]).unwrap(), 0);
        // Nothing left: read as a stream (which reads nothing).
        assert!(MappedBytes::rest_of(&file).is_none());
        std::fs::remove_file(&path).ok();
    }

    /// A dropped range gives back exactly its whole pages: the pages it shares with its
    /// neighbours and the neighbours' own stay mapped and read the file's bytes; given back in
    /// batches, they go once a batch has gathered.
    #[test]
    fn a_dropped_range_unmaps_its_whole_pages_only() {
        let path = std::env::temp_dir().join(format!("dampscope-release-{}", std::process::id()));
        let bytes: Vec<u8> = (0..6 * 4096 + 100).map(|i| (i % 251) as u8).collect();
        std::fs::File::create(&path)
            .unwrap()
            .write_all(&bytes)
            .unwrap();
        let mut map = MappedBytes::rest_of(&std::fs::File::open(&path).unwrap()).unwrap();
        // Every release unmapped at once (no batch to gather).
        map.release_batch_bytes = 0;
        let map = Arc::new(map);
        let page = map.page_bytes;
        let (a, b, c) = (
            0..page + 100,
            page + 100..4 * page + 7,
            4 * page + 7..map.len(),
        );
        let first = MappedRange::new(map.clone(), a.clone());
        let middle = MappedRange::new(map.clone(), b.clone());
        let last = MappedRange::new(map.clone(), c.clone());
        assert_eq!(middle.bytes(), &bytes[b.clone()]);
        let inside = map.slice(2 * page..2 * page + 1).as_ptr();
        let shared = [
            map.slice(page..page + 1).as_ptr(),
            map.slice(4 * page..4 * page + 1).as_ptr(),
        ];
        drop(middle);
        // Pages 2 and 3 were wholly the middle range's; pages 1 and 4 are shared.
        assert!(!is_mapped(inside, page));
        assert!(shared.iter().all(|&p| is_mapped(p, page)));
        assert_eq!(first.bytes(), &bytes[a]);
        assert_eq!(last.bytes(), &bytes[c]);
        drop((first, last, map));
        // In batches: released pages stay mapped until two pages' worth have gathered, then
        // go together.
        let mut map = MappedBytes::rest_of(&std::fs::File::open(&path).unwrap()).unwrap();
        map.release_batch_bytes = 2 * page;
        let map = Arc::new(map);
        let (one, two) = (0..2 * page, 2 * page..4 * page - 1);
        let first_page = map.slice(0..1).as_ptr();
        let third_page = map.slice(2 * page..2 * page + 1).as_ptr();
        drop(MappedRange::new(map.clone(), two));
        assert!(
            is_mapped(third_page, page),
            "one page gathered, none unmapped"
        );
        drop(MappedRange::new(map.clone(), one));
        assert!(!is_mapped(first_page, page) && !is_mapped(third_page, page));
        std::fs::remove_file(&path).ok();
    }
}

//! Shared machinery of the binary sources (WAV data chunk, raw samples): read whole interleaved
//! frames block by block from any reader, decode them, and report a short stream only after
//! every complete frame has been delivered.

use std::io::{self, Read};

use std::sync::Arc;

#[path = "frames_decode.rs"]
mod decode;
#[path = "frames_edges.rs"]
mod edges;
#[cfg(target_arch = "x86_64")]
#[path = "frames_f32_avx2.rs"]
mod f32_avx2;
use decode::{deinterleave, TILE_FRAMES};
pub(crate) use decode::{deinterleave_with, Codec, FrameLayout};

use super::encoded::EncodedFrames;
use super::mapped::MappedBytes;
use super::pipe::STREAM_PAUSE_MS;
use super::{Block, SourceError};

/// Upper bound on the bytes read by one `read_block` call unless the source is allowed more
/// ([`super::Source::allow_block_bytes`]): 1 MiB, 4096 frames of 64 f32 channels. Each channel
/// then gets 4096 samples per block, so that the analyzer can show the STFT the samples ahead
/// of each 1024-sample chunk it feeds (frame pairs in one transform,
/// [`crate::frontend::FrontEnd::process_ahead`]): whole 64-channel run at 4096 Hz 12.7 → 12.3
/// ms (median of 30). An earlier pipeline, which copied and decoded every block on one thread,
/// lost a tenth of a short run faulting 1 MiB blocks in; now the decoded blocks are reused per
/// worker (+350 page faults per run, CPU unchanged: 35.0 against 35.4 ms for octave bands).
const MAX_BLOCK_BYTES: usize = 1 << 20;

/// Reads until `buf` holds `want` bytes or the reader ends; returns the number of bytes read.
pub(crate) fn read_up_to<R: Read>(r: &mut R, buf: &mut Vec<u8>, want: usize) -> io::Result<usize> {
    buf.clear();
    buf.resize(want, 0);
    let mut n = 0;
    while n < want {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    buf.truncate(n);
    Ok(n)
}

/// Streams interleaved frames of a fixed codec and channel count.
pub(crate) struct FrameReader<R> {
    reader: R,
    codec: Codec,
    channels: usize,
    /// Multiplier applied to every decoded value.
    scale: f64,
    /// Data bytes announced by a header, if any (None: read to the end of the stream).
    announced_bytes: Option<u64>,
    /// Bytes consumed from the reader.
    bytes_read: u64,
    frames_read: u64,
    pending: Option<SourceError>,
    done: bool,
    /// Bytes read and not yet handed out: between calls, only the start of a partial frame.
    read: BufferedFrames,
    what: String,
    /// The input as a mapped file, and how many of its bytes were decoded: then `reader` and
    /// `read` are unused and blocks are decoded straight from the mapping.
    mapped: Option<(Arc<MappedBytes>, usize)>,
    /// The most bytes one read returns, mapped or streamed ([`MAX_BLOCK_BYTES`] unless
    /// allowed more).
    block_bytes: usize,
    /// The descriptor a stream arrives on, watched while a block fills: a writer that pauses
    /// for [`STREAM_PAUSE_MS`] gets the frames it sent analysed ([`FrameReader::wake_on_pause`]).
    pause_fd: Option<i32>,
    /// The last read returned early: the writer paused ([`FrameReader::paused`]).
    paused: bool,
    /// A pause was told and nothing arrived since (a pause is told once).
    pause_told: bool,
}

/// Where the whole frames of one read are: in the reader's buffer, or a range of the mapping.
enum FrameBytes<'a> {
    Buffered(&'a mut BufferedFrames),
    Mapped(&'a Arc<MappedBytes>, std::ops::Range<usize>),
}

impl FrameBytes<'_> {
    fn bytes(&self) -> &[u8] {
        match self {
            FrameBytes::Buffered(b) => b.whole_frames(),
            FrameBytes::Mapped(m, range) => m.slice(range.clone()),
        }
    }
}

/// A stream reader's buffer: `whole` bytes of whole frames, then the start of a partial frame,
/// `have` bytes in all.
struct BufferedFrames {
    buf: Vec<u8>,
    whole: usize,
    have: usize,
}

impl BufferedFrames {
    fn whole_frames(&self) -> &[u8] {
        &self.buf[..self.whole]
    }

    /// Leaves the whole frames at the start of `into` without copying them (the two buffers
    /// trade places, `into`'s old bytes are lost) and the partial frame at the start of the
    /// reader's new buffer, so that `whole` = 0; returns the whole frames' byte count. A block
    /// copy saved per read, and neither buffer is shortened: the next read into either fills
    /// initialized room instead of zeroing it again (megabytes a read at high rates).
    fn move_whole_into(&mut self, into: &mut Vec<u8>) -> usize {
        std::mem::swap(&mut self.buf, into);
        let partial = self.have - self.whole;
        if self.buf.len() < partial {
            self.buf.resize(partial, 0);
        }
        self.buf[..partial].copy_from_slice(&into[self.whole..self.have]);
        let whole = self.whole;
        (self.whole, self.have) = (0, partial);
        whole
    }

    /// Moves the partial frame to the start (after the whole frames were used in place).
    fn keep_partial(&mut self) {
        self.buf.copy_within(self.whole..self.have, 0);
        (self.whole, self.have) = (0, self.have - self.whole);
    }
}

impl<R: Read> FrameReader<R> {
    /// A reader of `channels` interleaved channels; `announced_bytes` limits the data length.
    pub(crate) fn new(
        reader: R,
        codec: Codec,
        channels: usize,
        scale: f64,
        announced_bytes: Option<u64>,
        what: String,
    ) -> Self {
        Self {
            reader,
            codec,
            channels,
            scale,
            announced_bytes,
            bytes_read: 0,
            read: BufferedFrames {
                buf: Vec::new(),
                whole: 0,
                have: 0,
            },
            frames_read: 0,
            pending: None,
            done: false,
            what,
            mapped: None,
            block_bytes: MAX_BLOCK_BYTES,
            pause_fd: None,
            paused: false,
            pause_told: false,
        }
    }

    /// Hands out a partly filled block when nothing more arrives on `fd` (the descriptor
    /// `reader` reads, unbuffered) for [`STREAM_PAUSE_MS`]: a stream's blocks are filled whole
    /// so that they are a mapped file's, but a writer that waits for rows before it sends more
    /// must not wait forever, nor a paused recorder's last frames until it resumes.
    pub(crate) fn wake_on_pause(&mut self, fd: i32) {
        self.pause_fd = Some(fd);
    }

    /// Whether bytes (or the end) arrive on the watched descriptor within [`STREAM_PAUSE_MS`];
    /// always, without one.
    fn arrives_soon(&self) -> bool {
        self.pause_fd
            .is_none_or(|fd| super::pipe::arrives_within(fd, STREAM_PAUSE_MS))
    }

    /// The last read stopped at the writer's pause ([`super::Source::paused`]).
    pub(crate) fn paused(&self) -> bool {
        self.paused
    }

    /// Lets one read return up to `bytes` (never less than
    /// [`MAX_BLOCK_BYTES`]; see [`super::Source::allow_block_bytes`]).
    pub(crate) fn allow_block_bytes(&mut self, bytes: usize) {
        self.block_bytes = bytes.max(MAX_BLOCK_BYTES);
    }

    /// This reader decoding from `mapped` bytes (the same input, mapped) instead of reading.
    pub(crate) fn decoding_from(mut self, mapped: MappedBytes) -> Self {
        self.mapped = Some((Arc::new(mapped), 0));
        self
    }

    /// Whole sample frames the mapped input holds in all (at most what a header announced);
    /// `None` when the input is read as a stream.
    pub(crate) fn mapped_frames(&self) -> Option<u64> {
        let (mapped, _) = self.mapped.as_ref()?;
        let frame_bytes = (self.channels * self.codec.bytes()).max(1) as u64;
        let bytes = mapped.len() as u64;
        Some(self.announced_bytes.map_or(bytes, |a| a.min(bytes)) / frame_bytes)
    }

    /// Whether the input is decoded from a mapped file.
    #[cfg(test)]
    pub(crate) fn is_mapped(&self) -> bool {
        self.mapped.is_some()
    }

    /// Replaces the multiplier applied to every decoded value.
    pub(crate) fn set_scale(&mut self, scale: f64) {
        self.scale = scale;
    }

    /// What each stored value is multiplied by.
    pub(crate) fn scale(&self) -> f64 {
        self.scale
    }

    /// The name of the input, for error messages.
    pub(crate) fn what(&self) -> &str {
        &self.what
    }

    fn frame_bytes(&self) -> usize {
        self.channels * self.codec.bytes()
    }

    /// The truncation error once the stream ended; `whole` frames of this call not yet counted.
    fn truncation(&self, partial: usize, whole: usize) -> SourceError {
        let frames = self.frames_read + whole as u64;
        let fb = self.frame_bytes() as u64;
        match self.announced_bytes {
            Some(n) => SourceError::Truncated {
                what: self.what.clone(),
                expected: format!("{n} data bytes ({} frames) announced by the header", n / fb),
                got: format!("{} bytes ({} whole frames)", self.bytes_read, frames),
            },
            None => SourceError::Truncated {
                what: self.what.clone(),
                expected: format!(
                    "a whole number of {fb}-byte frames ({} channels x {} bytes)",
                    self.channels,
                    self.codec.bytes()
                ),
                got: format!(
                    "{} bytes: {} whole frames and {partial} stray bytes",
                    self.bytes_read, frames
                ),
            },
        }
    }

    /// The [`super::Source::read_block`] contract: up to `max_frames` frames into `block`,
    /// `Ok(false)` at the end, every complete frame before a `Truncated` error, `Empty` when the
    /// stream held no frame at all.
    pub(crate) fn read_block(
        &mut self,
        max_frames: usize,
        block: &mut Block,
    ) -> Result<bool, SourceError> {
        block.channels.resize_with(self.channels, Vec::new);
        for ch in &mut block.channels {
            ch.clear();
        }
        block.known_finite.clear();
        let (codec, scale) = (self.codec, self.scale);
        self.next_frames(max_frames, |frames| {
            deinterleave(
                codec,
                frames.bytes(),
                scale,
                &mut block.channels,
                &mut block.known_finite,
            )
        })
    }

    /// [`FrameReader::read_block`] with the frames left encoded in `out`, for the thread that
    /// analyses them to decode (a mapped file's frames are not even copied).
    pub(crate) fn read_encoded_block(
        &mut self,
        max_frames: usize,
        out: &mut EncodedFrames,
    ) -> Result<bool, SourceError> {
        out.reset(self.codec, self.scale, self.channels);
        self.next_frames(max_frames, |frames| match frames {
            FrameBytes::Buffered(frames) => out.set_moved(|into| frames.move_whole_into(into)),
            FrameBytes::Mapped(map, range) => out.set_mapped(map.clone(), range),
        })
    }

    /// The state machine of both reads: up to `max_frames` whole frames handed to `take`,
    /// `Ok(false)` at the end, every complete frame before a `Truncated` error.
    fn next_frames(
        &mut self,
        max_frames: usize,
        take: impl FnOnce(FrameBytes<'_>),
    ) -> Result<bool, SourceError> {
        if let Some(e) = self.pending.take() {
            return Err(e);
        }
        if self.done {
            return Ok(false);
        }
        let fb = self.frame_bytes();
        // At most `block_bytes` per call (but at least one frame): memory stays bounded
        // whatever the caller asks; fewer frames than asked is within the contract.
        let cap_frames = (self.block_bytes / fb).max(1);
        let frames = max_frames.clamp(1, cap_frames);
        if self.mapped.is_some() {
            return self.next_mapped_frames(frames, take);
        }
        let mut want = frames.saturating_mul(fb);
        if let Some(n) = self.announced_bytes {
            want = want.min(self.read.have + (n - self.bytes_read) as usize);
        }
        if self.read.buf.len() < want {
            self.read.buf.resize(want, 0);
        }
        // A stream's block is filled as a mapped file's is (up to `want` bytes, or the end),
        // not cut where a read happened to return: the same blocks whatever the writer's
        // timing, so the same frames are paired (the same bits out as from the file) and a
        // fast writer's blocks are long enough to pair frames at all. A live stream waits
        // for one block of signal (4096 frames, or four look-ahead spans), a paused one
        // [`STREAM_PAUSE_MS`] at most.
        let mut eof = false;
        self.paused = false;
        while self.read.have < want {
            // With a frame in hand, or none and the pause not yet told (the frames sent may
            // have filled whole blocks): a writer that waits for its rows gets them.
            if (self.read.have >= fb || !self.pause_told) && !self.arrives_soon() {
                self.paused = true;
                self.pause_told = true;
                break;
            }
            let read = &mut self.read;
            match self.reader.read(&mut read.buf[read.have..want]) {
                Ok(0) => {
                    eof = true;
                    break;
                }
                Ok(k) => {
                    read.have += k;
                    self.bytes_read += k as u64;
                    self.pause_told = false;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    return Err(SourceError::Io {
                        what: self.what.clone(),
                        source: e,
                    })
                }
            }
        }
        let read = &self.read;
        let whole = read.have / fb;
        let partial = read.have % fb;
        let announced_done = self.announced_bytes.is_some_and(|n| self.bytes_read == n);
        if eof || announced_done {
            self.done = true;
            if partial > 0 || (eof && self.announced_bytes.is_some()) {
                self.pending = Some(self.truncation(partial, whole));
            }
        }
        let read = &mut self.read;
        read.whole = whole * fb;
        take(FrameBytes::Buffered(read));
        if read.whole > 0 {
            read.keep_partial();
        }
        self.frames_read += whole as u64;
        let tells_pause = self.paused && !self.done; // with an empty block, if need be
        if whole == 0 && !tells_pause {
            return super::end_of_input(&mut self.pending, self.frames_read, &self.what);
        }
        Ok(true)
    }

    /// [`FrameReader::next_frames`] from the mapped file: up to `frames` frames taken in place,
    /// with the same end, truncation and empty-input reports as the stream.
    fn next_mapped_frames(
        &mut self,
        frames: usize,
        take: impl FnOnce(FrameBytes<'_>),
    ) -> Result<bool, SourceError> {
        let fb = self.frame_bytes();
        let Some((mapped, used)) = &mut self.mapped else {
            return Ok(false);
        };
        let all = mapped.len();
        let end = self.announced_bytes.map_or(all, |n| all.min(n as usize));
        let rest = end - *used;
        let whole = (rest / fb).min(frames);
        take(FrameBytes::Mapped(mapped, *used..*used + whole * fb));
        *used += whole * fb;
        self.bytes_read = *used as u64;
        if end - *used < fb {
            // The last whole frame is out: what is left is a partial frame, or a file shorter
            // than its header announced.
            self.done = true;
            let partial = end - *used;
            let short = self.announced_bytes.is_some_and(|n| (end as u64) < n);
            if partial > 0 || short {
                self.bytes_read = end as u64;
                self.pending = Some(self.truncation(partial, whole));
            }
        }
        self.frames_read += whole as u64;
        if whole == 0 {
            return super::end_of_input(&mut self.pending, self.frames_read, &self.what);
        }
        Ok(true)
    }
}

#[cfg(test)]
#[path = "frames_tests.rs"]
mod tests;

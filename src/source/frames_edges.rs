//! A stream's edges: its first bytes, looked at before any frame is decoded (a WAV header in
//! input declared raw), and what follows the frames a header announced, to tell a trailing
//! chunk from a second file appended to the first (`cat a.wav b.wav |`).

use std::io::Read;

use super::FrameReader;

/// The most bytes skipped to reach the bytes looked at: trailing chunks longer than this are
/// not read through (the look is then not taken).
const MAX_SKIP_BYTES: u64 = 16 << 20;

impl<R: Read> FrameReader<R> {
    /// Reads the stream's first `n` bytes (fewer at its end), to be looked at before any frame
    /// is decoded; they stay in the buffer, the first frames' bytes. Call it before any read.
    pub(crate) fn first_bytes(&mut self, n: usize) -> std::io::Result<&[u8]> {
        let mut first = std::mem::take(&mut self.read.buf);
        super::read_up_to(&mut self.reader, &mut first, n)?;
        (self.read.have, self.read.whole) = (first.len(), 0);
        self.bytes_read = first.len() as u64;
        self.read.buf = first;
        Ok(&self.read.buf[..self.read.have])
    }

    /// Up to `max` bytes of the input that come `skip` bytes after the frames handed out: a
    /// mapped file's, or a stream's as they arrive. A watched stream that pauses for
    /// [`STREAM_PAUSE_MS`](crate::source::STREAM_PAUSE_MS) is taken to have nothing more, so
    /// that a writer keeping its end open is not waited for; an unwatched reader is read until
    /// it ends or gives the bytes. Fewer at the end of the input, none when `skip` exceeds
    /// [`MAX_SKIP_BYTES`]; a failed read ends the look. Call it once the frames are all out.
    pub(crate) fn bytes_past(&mut self, skip: u64, max: usize) -> Vec<u8> {
        if skip > MAX_SKIP_BYTES {
            return Vec::new();
        }
        let mut to_skip = skip as usize;
        if let Some((mapped, used)) = &self.mapped {
            let start = used.saturating_add(to_skip).min(mapped.len());
            let end = start.saturating_add(max).min(mapped.len());
            return mapped.slice(start..end).to_vec();
        }
        let mut past = Vec::with_capacity(max);
        let mut chunk = [0u8; 4096];
        while past.len() < max && self.arrives_soon() {
            let room = match to_skip {
                0 => max - past.len(),
                n => n,
            };
            let room = room.min(chunk.len());
            match self.reader.read(&mut chunk[..room]) {
                Ok(0) => break,
                Ok(k) if to_skip > 0 => to_skip -= k,
                Ok(k) => past.extend_from_slice(&chunk[..k]),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(_) => break,
            }
        }
        past
    }
}

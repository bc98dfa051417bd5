//! Blocks of interleaved frames still in their stored encoding (raw samples, a WAV data chunk),
//! handed over undecoded so that each analysis thread decodes only its own channels.
//!
//! Why: decoding on the reading thread wrote every sample as an f64 (twice the bytes of an f32)
//! into memory that another core then read back — the first pass over each block there (the
//! new-hit watch's scan) was 6–8 % of a 48 kHz run, the decode itself 9–10 %, on a third
//! thread competing for two cores. Decoded where it is analysed, a block's samples are still
//! in that core's cache when the analysis reads them; a mapped file's frames are not even
//! copied.

use std::ops::Range;
use std::sync::Arc;

use super::frames::{deinterleave_with, Codec, FrameLayout};
use super::mapped::{MappedBytes, MappedRange};
use super::Block;
use crate::frontend::simd::Isa;

/// Whole interleaved frames of one block, in the codec they were stored in.
pub struct EncodedFrames {
    bytes: EncodedBytes,
    codec: Codec,
    scale: f64,
    channels: usize,
    /// Instruction set of the decoder (detected once per block buffer, not per block).
    isa: Isa,
}

impl Default for EncodedFrames {
    fn default() -> Self {
        EncodedFrames {
            bytes: EncodedBytes::Copied(Vec::new(), 0),
            codec: Codec::F32,
            scale: 1.0,
            channels: 0,
            isa: Isa::detect(),
        }
    }
}

/// The frames' bytes: a copy (read from a stream), or a range of a mapped file.
enum EncodedBytes {
    /// A buffer and how many of its first bytes are this block's (the rest is room, kept
    /// initialized so that a reader can fill it without zeroing it first).
    Copied(Vec<u8>, usize),
    /// A block's range of a mapped file, unmapped when the block lets go of it.
    Mapped(MappedRange),
}

impl EncodedFrames {
    /// Empties the block for frames of `channels` channels in `codec`, each value times `scale`
    /// (a copy buffer is kept for reuse).
    pub(crate) fn reset(&mut self, codec: Codec, scale: f64, channels: usize) {
        self.codec = codec;
        self.scale = scale;
        self.channels = channels;
        match &mut self.bytes {
            EncodedBytes::Copied(_, len) => *len = 0,
            other => *other = EncodedBytes::Copied(Vec::new(), 0),
        }
    }

    /// The frames are the first bytes of the buffer `fill` is given (this block's copy buffer,
    /// whatever it held), as many as it returns: a reader hands its own buffer over instead of
    /// copying it, and the room after them stays for the next read.
    pub(crate) fn set_moved(&mut self, fill: impl FnOnce(&mut Vec<u8>) -> usize) {
        if !matches!(self.bytes, EncodedBytes::Copied(..)) {
            self.bytes = EncodedBytes::Copied(Vec::new(), 0);
        }
        if let EncodedBytes::Copied(v, len) = &mut self.bytes {
            *len = fill(v);
        }
    }

    /// The frames are `range` of the mapped file `map` (whole frames).
    pub(crate) fn set_mapped(&mut self, map: Arc<MappedBytes>, range: Range<usize>) {
        self.bytes = EncodedBytes::Mapped(MappedRange::new(map, range));
    }

    fn bytes(&self) -> &[u8] {
        match &self.bytes {
            EncodedBytes::Copied(v, len) => &v[..*len],
            EncodedBytes::Mapped(range) => range.bytes(),
        }
    }

    /// Whether the frames are a copy in this block's own buffer (not a mapped file's pages).
    pub(crate) fn is_copy(&self) -> bool {
        matches!(self.bytes, EncodedBytes::Copied(..))
    }

    /// Channels per frame.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Sample frames held.
    pub fn frames(&self) -> usize {
        let frame_bytes = self.channels * self.codec.bytes();
        self.bytes().len().checked_div(frame_bytes).unwrap_or(0)
    }

    /// Decodes channels `range` (clamped to the frame) into `out`: `out.channels[i]` is
    /// channel `range.start + i`, with the finiteness flags the decoder learns on the way, as
    /// the source's own [`super::Source::read_block`] would give them.
    pub fn decode_into(&self, range: Range<usize>, out: &mut Block) {
        let end = range.end.min(self.channels);
        let start = range.start.min(end);
        out.channels.resize_with(end - start, Vec::new);
        let layout = FrameLayout {
            frame_channels: self.channels,
            first: start,
        };
        deinterleave_with(
            self.isa,
            self.codec,
            self.bytes(),
            layout,
            self.scale,
            &mut out.channels,
            &mut out.known_finite,
        );
    }
}

//! Decoding whole interleaved frames into per-channel samples: the sample codecs and the
//! tiled de-interleaving (with its AVX2 path for f32).

#[cfg(target_arch = "x86_64")]
use super::f32_avx2;
use crate::frontend::simd::Isa;

/// How one sample is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Codec {
    /// Unsigned 8-bit integer, offset 128 (WAV 8-bit PCM).
    U8,
    /// Signed little-endian integer of 2, 3 or 4 bytes.
    Int(usize),
    /// Little-endian IEEE float, 4 bytes.
    F32,
    /// Little-endian IEEE float, 8 bytes.
    F64,
}

impl Codec {
    /// Bytes per sample.
    pub(crate) fn bytes(self) -> usize {
        match self {
            Codec::U8 => 1,
            Codec::Int(b) => b,
            Codec::F32 => 4,
            Codec::F64 => 8,
        }
    }

    /// Whether the samples are integers (scaled by the source's integer scale).
    pub(crate) fn is_int(self) -> bool {
        matches!(self, Codec::U8 | Codec::Int(_))
    }

    /// The factor that maps integer counts to [-1, 1): 2^-(bits-1). 1 for floats.
    pub(crate) fn full_scale(self) -> f64 {
        match self {
            Codec::U8 => 1.0 / 128.0,
            Codec::Int(b) => 1.0 / f64::powi(2.0, 8 * b as i32 - 1),
            Codec::F32 | Codec::F64 => 1.0,
        }
    }

    /// Decodes one sample from exactly `self.bytes()` bytes (integers as raw counts): the
    /// obviously correct decoder that [`deinterleave`] is tested against.
    #[cfg(test)]
    pub(super) fn decode(self, b: &[u8]) -> f64 {
        match self {
            Codec::U8 => f64::from(b[0]) - 128.0,
            Codec::Int(2) => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Codec::Int(3) => f64::from(i32::from_le_bytes([0, b[0], b[1], b[2]]) >> 8),
            Codec::Int(_) => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Codec::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Codec::F64 => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        }
    }
}

/// Frames per tile of [`deinterleave`]: a tile's bytes (at most 64 frames × the frame) stay in
/// the first-level cache while each channel's samples are picked out of it.
pub(super) const TILE_FRAMES: usize = 64;

/// Decodes whole interleaved frames into one vector per channel (each replaced by the frame
/// count of samples). The codec is resolved once, outside the loops, and the frames are taken in tiles,
/// so that each channel's writes are sequential and its reads stay in the cache.
///
/// `known_finite` is cleared and, where the decoder learns it on the way, filled with one flag
/// per channel: every decoded sample of that channel is finite (see [`Block::known_finite`]).
pub(super) fn deinterleave(
    codec: Codec,
    bytes: &[u8],
    scale: f64,
    channels: &mut [Vec<f64>],
    known_finite: &mut Vec<bool>,
) {
    let layout = FrameLayout::whole(channels.len());
    deinterleave_with(
        Isa::detect(),
        codec,
        bytes,
        layout,
        scale,
        channels,
        known_finite,
    )
}

/// Which channels of each stored frame a decode takes: `channels.len()` of them from
/// `first` on, in frames of `frame_channels`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct FrameLayout {
    /// Channels per stored frame.
    pub(crate) frame_channels: usize,
    /// The first channel decoded.
    pub(crate) first: usize,
}

impl FrameLayout {
    /// Every channel of frames of `channels`.
    pub(crate) fn whole(channels: usize) -> Self {
        FrameLayout {
            frame_channels: channels,
            first: 0,
        }
    }
}

/// [`deinterleave`] with the instruction set given, of the channels `layout.first ..
/// layout.first + channels.len()` of frames of `layout.frame_channels` (which must hold them).
pub(crate) fn deinterleave_with(
    isa: Isa,
    codec: Codec,
    bytes: &[u8],
    layout: FrameLayout,
    scale: f64,
    channels: &mut [Vec<f64>],
    known_finite: &mut Vec<bool>,
) {
    #[inline(always)]
    fn run<const B: usize>(
        bytes: &[u8],
        layout: FrameLayout,
        scale: f64,
        channels: &mut [Vec<f64>],
        decode: impl Fn([u8; B]) -> f64,
    ) {
        let fb = layout.frame_channels * B;
        let frames = bytes.len() / fb.max(1);
        for ch in channels.iter_mut() {
            ch.clear();
            ch.reserve(frames);
        }
        for t0 in (0..frames).step_by(TILE_FRAMES) {
            let t1 = (t0 + TILE_FRAMES).min(frames);
            let tile = &bytes[t0 * fb..t1 * fb];
            for (c, ch) in channels.iter_mut().enumerate() {
                let at = (layout.first + c) * B;
                // An exact-size iterator: no zero fill, no capacity check per sample.
                ch.extend(tile.chunks_exact(fb).map(|frame| {
                    let mut raw = [0u8; B];
                    raw.copy_from_slice(&frame[at..at + B]);
                    decode(raw) * scale
                }));
            }
        }
    }
    known_finite.clear();
    debug_assert!(layout.first + channels.len() <= layout.frame_channels);
    // A finite value times a scale of magnitude at most 1 stays finite (it cannot overflow).
    let scale_keeps_finite = scale.is_finite() && scale.abs() <= 1.0;
    #[cfg(target_arch = "x86_64")]
    if codec == Codec::F32
        && !channels.is_empty()
        && channels.len().is_multiple_of(8)
        && isa != Isa::Generic
    {
        // SAFETY: `Isa::detect` found AVX2 on this CPU; the channel count is a multiple of 8
        // and the channels lie in the frame.
        let finite = unsafe { f32_avx2::f32_by_eights_avx2(bytes, layout, scale, channels) };
        if scale_keeps_finite {
            *known_finite = finite;
        }
        return;
    }
    if codec.is_int() && scale_keeps_finite {
        // Integers are finite, and so are their scaled values.
        known_finite.resize(channels.len(), true);
    }
    match codec {
        Codec::U8 => run::<1>(bytes, layout, scale, channels, |b| f64::from(b[0]) - 128.0),
        Codec::Int(2) => run::<2>(bytes, layout, scale, channels, |b| {
            f64::from(i16::from_le_bytes(b))
        }),
        Codec::Int(3) => run::<3>(bytes, layout, scale, channels, |b| {
            f64::from(i32::from_le_bytes([0, b[0], b[1], b[2]]) >> 8)
        }),
        Codec::Int(_) => run::<4>(bytes, layout, scale, channels, |b| {
            f64::from(i32::from_le_bytes(b))
        }),
        Codec::F32 => run::<4>(bytes, layout, scale, channels, |b| {
            f64::from(f32::from_le_bytes(b))
        }),
        Codec::F64 => run::<8>(bytes, layout, scale, channels, f64::from_le_bytes),
    }
}

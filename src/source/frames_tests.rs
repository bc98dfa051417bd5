//! Unit tests of the frame decoder: every codec against sample-by-sample decoding, and the
//! finiteness flags of the f32 kernel.

use super::*;
use crate::frontend::simd::Isa;

/// The tiled, per-codec decoder against one sample at a time, for every codec, channel
/// counts around the tile and the 8-channel groups, and frame counts that leave a partial
/// tile or a partial group of eight frames.
#[test]
fn deinterleave_matches_sample_by_sample_decoding() {
    let codecs = [
        Codec::U8,
        Codec::Int(2),
        Codec::Int(3),
        Codec::Int(4),
        Codec::F32,
        Codec::F64,
    ];
    for codec in codecs {
        // 8, 16 and 64 channels take the transposing f32 kernel where the CPU has AVX2.
        for n_ch in [1, 3, 8, 16, 64] {
            for frames in [0, 1, 7, 9, 63, 64, 65, 200] {
                let sb = codec.bytes();
                let mut bytes = vec![0u8; frames * n_ch * sb];
                for (i, b) in bytes.iter_mut().enumerate() {
                    *b = (i * 7919 % 251) as u8;
                }
                if codec == Codec::F32 || codec == Codec::F64 {
                    // Finite floats: a value per sample with a small exponent.
                    for s in bytes.chunks_exact_mut(sb) {
                        let v = (s[0] as f64 - 100.0) / 7.0;
                        if sb == 4 {
                            s.copy_from_slice(&(v as f32).to_le_bytes());
                        } else {
                            s.copy_from_slice(&v.to_le_bytes());
                        }
                    }
                }
                for isa in Isa::available() {
                    // Blocks are decoded into recycled vectors: start from stale ones.
                    let mut got = vec![vec![-1.0; 5]; n_ch];
                    let mut finite = vec![false; 3];
                    deinterleave_with(
                        isa,
                        codec,
                        &bytes,
                        FrameLayout::whole(n_ch),
                        0.5,
                        &mut got,
                        &mut finite,
                    );
                    assert!(finite.is_empty() || finite == vec![true; n_ch]);
                    // A run of the channels (as a worker decodes its share): the same
                    // values, the same flags. Runs of 8 take the f32 kernel, off the
                    // frame's groups of eight too.
                    for (first, count) in [(0, n_ch), (1, n_ch - 1), (n_ch / 2, n_ch / 2)]
                        .into_iter()
                        .chain((n_ch >= 16).then_some((3, 8)))
                        .chain((n_ch >= 16).then_some((8, 8)))
                    {
                        let layout = FrameLayout {
                            frame_channels: n_ch,
                            first,
                        };
                        let mut part = vec![vec![-1.0; 2]; count];
                        let mut part_finite = Vec::new();
                        deinterleave_with(
                            isa,
                            codec,
                            &bytes,
                            layout,
                            0.5,
                            &mut part,
                            &mut part_finite,
                        );
                        for (c, ch) in part.iter().enumerate() {
                            assert_eq!(ch.len(), frames);
                            for (i, v) in ch.iter().enumerate() {
                                let at = (i * n_ch + first + c) * sb;
                                let want = codec.decode(&bytes[at..at + sb]) * 0.5;
                                assert_eq!(
                                    v.to_bits(),
                                    want.to_bits(),
                                    "{isa:?} {codec:?} {first}+{count} of {n_ch} #{i}"
                                );
                            }
                        }
                        assert!(part_finite.is_empty() || part_finite == vec![true; count]);
                        if isa != Isa::Generic && codec == Codec::F32 && count % 8 == 0 && count > 0
                        {
                            assert_eq!(part_finite.len(), count, "the f32 kernel flags");
                        }
                    }
                    for (c, ch) in got.iter().enumerate() {
                        assert_eq!(ch.len(), frames);
                        for (i, v) in ch.iter().enumerate() {
                            let at = (i * n_ch + c) * sb;
                            let want = codec.decode(&bytes[at..at + sb]) * 0.5;
                            assert_eq!(
                                v.to_bits(),
                                want.to_bits(),
                                "{isa:?} {codec:?} {n_ch} ch #{i}"
                            );
                        }
                    }
                }
            }
        }
    }
}

/// The per-channel finiteness flags the decoder returns are never wrong: a NaN or ±∞ at any
/// frame (in the groups of eight, in the tail) of any channel clears that channel's flag
/// only, and a scale that could overflow gives no flags at all.
#[test]
fn known_finite_flags_name_exactly_the_channels_with_non_finite_values() {
    for isa in Isa::available() {
        for n_ch in [8usize, 16, 64, 3] {
            for frames in [1usize, 8, 9, 64, 65, 200] {
                for (bad_ch, bad_frame, bad) in [
                    (0, 0, f32::NAN),
                    (n_ch - 1, frames - 1, f32::INFINITY),
                    (n_ch / 2, frames / 2, f32::NEG_INFINITY),
                ] {
                    let mut values = vec![0.25f32; frames * n_ch];
                    values[bad_frame * n_ch + bad_ch] = bad;
                    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
                    let mut got = vec![Vec::new(); n_ch];
                    let mut finite = Vec::new();
                    let whole = FrameLayout::whole(n_ch);
                    deinterleave_with(isa, Codec::F32, &bytes, whole, 1.0, &mut got, &mut finite);
                    if !finite.is_empty() {
                        for (c, f) in finite.iter().enumerate() {
                            assert_eq!(*f, c != bad_ch, "{isa:?} {n_ch} ch {frames} frames");
                        }
                    }
                    // Where the fast kernel runs, the flags must be there.
                    if isa != Isa::Generic && n_ch % 8 == 0 {
                        assert_eq!(finite.len(), n_ch);
                    }
                    deinterleave_with(isa, Codec::F32, &bytes, whole, 1e300, &mut got, &mut finite);
                    assert!(finite.is_empty(), "a scale of 1e300 can overflow");
                }
            }
        }
    }
}

//! The AVX2 decoder of 32-bit float frames in groups of eight channels (see
//! [`super::deinterleave_with`]).

use super::{FrameLayout, TILE_FRAMES};

/// [`super::deinterleave_with`] of 32-bit floats when the channels come in groups of eight (the common
/// 8/16/32/64-channel arrays): per group, eight frames at a time are loaded as eight vectors,
/// transposed in registers, widened to f64 and stored, four samples per instruction. The
/// scalar path picks one sample per channel per frame and was a tenth of a whole 48 kHz run.
/// The same conversion and product as the scalar path: identical bits.
///
/// Returns per channel whether every input value was finite: the exponent bits of the eight
/// loaded vectors are compared on the way (an AND, a compare and an OR per vector), which
/// spares the analysis its own pass over the decoded samples.
///
/// # Safety
/// The CPU must have AVX2, `channels.len()` must be a multiple of 8, and the channels must lie
/// in the frame (`layout.first + channels.len() <= layout.frame_channels`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn f32_by_eights_avx2(
    bytes: &[u8],
    layout: FrameLayout,
    scale: f64,
    channels: &mut [Vec<f64>],
) -> Vec<bool> {
    use std::arch::x86_64::*;
    let n_ch = channels.len();
    let (stride, first) = (layout.frame_channels, layout.first);
    debug_assert!(n_ch > 0 && n_ch.is_multiple_of(8) && first + n_ch <= stride);
    let frames = bytes.len() / (4 * stride);
    let whole = frames / 8 * 8;
    for ch in channels.iter_mut() {
        ch.clear();
        ch.reserve(frames);
    }
    let src = bytes.as_ptr();
    let factor = _mm256_set1_pd(scale);
    // An f32 is not finite exactly when its exponent bits are all ones.
    let exponent = _mm256_set1_epi32(0x7f80_0000);
    // Per group of eight channels, bit j set: channel 8g + j held a non-finite value.
    let mut non_finite = vec![0u8; n_ch / 8];
    for t0 in (0..whole).step_by(TILE_FRAMES) {
        let t1 = (t0 + TILE_FRAMES).min(whole);
        for (g, group) in channels.chunks_exact_mut(8).enumerate() {
            let out: [*mut f64; 8] = std::array::from_fn(|j| group[j].as_mut_ptr());
            let mut bad = _mm256_setzero_si256();
            for f in (t0..t1).step_by(8) {
                // r[i] = channels first+8g .. first+8g+8 of frame f + i (in bounds: f + 8 <=
                // frames, first + 8g + 8 <= stride).
                let r: [__m256; 8] = std::array::from_fn(|i| {
                    _mm256_loadu_ps(src.add(((f + i) * stride + first + 8 * g) * 4) as *const f32)
                });
                for v in &r {
                    let e = _mm256_and_si256(_mm256_castps_si256(*v), exponent);
                    bad = _mm256_or_si256(bad, _mm256_cmpeq_epi32(e, exponent));
                }
                let c = transpose_8x8(r);
                for (j, &v) in c.iter().enumerate() {
                    let lo = _mm256_cvtps_pd(_mm256_castps256_ps128(v));
                    let hi = _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(v));
                    // In bounds: `reserve(frames)` above, f + 8 <= frames.
                    _mm256_storeu_pd(out[j].add(f), _mm256_mul_pd(lo, factor));
                    _mm256_storeu_pd(out[j].add(f + 4), _mm256_mul_pd(hi, factor));
                }
            }
            non_finite[g] |= _mm256_movemask_ps(_mm256_castsi256_ps(bad)) as u8;
        }
    }
    let mut finite = Vec::with_capacity(n_ch);
    for (c, ch) in channels.iter_mut().enumerate() {
        // The first `whole` samples were written above.
        ch.set_len(whole);
        let mut tail_finite = true;
        ch.extend((whole..frames).map(|f| {
            let at = (f * stride + first + c) * 4;
            let mut raw = [0u8; 4];
            raw.copy_from_slice(&bytes[at..at + 4]);
            let v = f32::from_le_bytes(raw);
            tail_finite &= v.is_finite();
            f64::from(v) * scale
        }));
        finite.push(tail_finite && non_finite[c / 8] & (1 << (c % 8)) == 0);
    }
    finite
}

/// The transpose of an 8 × 8 matrix of f32 held as eight row vectors.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn transpose_8x8(r: [std::arch::x86_64::__m256; 8]) -> [std::arch::x86_64::__m256; 8] {
    use std::arch::x86_64::*;
    let t0 = _mm256_unpacklo_ps(r[0], r[1]);
    let t1 = _mm256_unpackhi_ps(r[0], r[1]);
    let t2 = _mm256_unpacklo_ps(r[2], r[3]);
    let t3 = _mm256_unpackhi_ps(r[2], r[3]);
    let t4 = _mm256_unpacklo_ps(r[4], r[5]);
    let t5 = _mm256_unpackhi_ps(r[4], r[5]);
    let t6 = _mm256_unpacklo_ps(r[6], r[7]);
    let t7 = _mm256_unpackhi_ps(r[6], r[7]);
    let u0 = _mm256_shuffle_ps::<0x44>(t0, t2);
    let u1 = _mm256_shuffle_ps::<0xEE>(t0, t2);
    let u2 = _mm256_shuffle_ps::<0x44>(t1, t3);
    let u3 = _mm256_shuffle_ps::<0xEE>(t1, t3);
    let u4 = _mm256_shuffle_ps::<0x44>(t4, t6);
    let u5 = _mm256_shuffle_ps::<0xEE>(t4, t6);
    let u6 = _mm256_shuffle_ps::<0x44>(t5, t7);
    let u7 = _mm256_shuffle_ps::<0xEE>(t5, t7);
    [
        _mm256_permute2f128_ps::<0x20>(u0, u4),
        _mm256_permute2f128_ps::<0x20>(u1, u5),
        _mm256_permute2f128_ps::<0x20>(u2, u6),
        _mm256_permute2f128_ps::<0x20>(u3, u7),
        _mm256_permute2f128_ps::<0x31>(u0, u4),
        _mm256_permute2f128_ps::<0x31>(u1, u5),
        _mm256_permute2f128_ps::<0x31>(u2, u6),
        _mm256_permute2f128_ps::<0x31>(u3, u7),
    ]
}

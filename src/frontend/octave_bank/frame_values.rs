//! A reversed or forward octave bank's frame from the kernel's frame sums: the mean energy per
//! sample, and the cosine of the band's frequency from sums smoothed over a few periods (see
//! [`super::OctaveBankFrontEnd`]); the reversed bank converts a chunk of frames at a time in
//! vector lanes ([`frames_from_sums`]).

use super::kernel::FrameSums;
use crate::decay::CountDivisor;
use crate::frontend::simd::Isa;

/// One band's frame from its sums: the mean energy per sample, and the cosine of its frequency
/// (cos 2πf/fs from the smoothed sums `sm`, updated here; NaN where unknown).
#[inline(always)]
pub(super) fn frame_values(
    sm: &mut [f64; 2],
    alpha: f64,
    sums: &FrameSums,
    scale: CountDivisor,
) -> (f64, f64) {
    let (mean, [cross, power]) = smoothed_values(sm, alpha, sums, scale);
    (mean, cosine_of(cross, power))
}

/// The first half of [`frame_values`]: the mean energy, and the smoothed sums `sm` updated and
/// returned (Σ y[n−1]·(y[n] + y[n−2]), Σ y[n−1]²).
#[inline(always)]
fn smoothed_values(
    sm: &mut [f64; 2],
    alpha: f64,
    &[energy, cross, power]: &FrameSums,
    scale: CountDivisor,
) -> (f64, [f64; 2]) {
    sm[0] = alpha * sm[0] + cross;
    sm[1] = alpha * sm[1] + power;
    (scale.divide(energy), *sm)
}

/// The second half of [`frame_values`]: cos 2πf/fs from the smoothed sums, NaN where the
/// power is not positive.
#[inline(always)]
fn cosine_of(cross: f64, power: f64) -> f64 {
    let cosine = (0.5 * cross / power).clamp(-1.0, 1.0);
    if power > 0.0 {
        cosine
    } else {
        f64::NAN
    }
}

/// Where [`frames_from_sums`] writes: band-major arrays of `n_frames` frames per band.
pub(super) struct BandFrames<'a> {
    /// Mean energies, band b's frame k at `b · n_frames + k`.
    pub(super) energy: &'a mut [f64],
    /// Frequency cosines, laid out alike.
    pub(super) cosine: &'a mut [f64],
    pub(super) n_frames: usize,
}

/// One chunk of a reversed decay for [`frames_from_sums`]: `sums` holds frames in processing
/// order (`smooth.len()` bands each), frame j being frame `k_end − 1 − j` of the band-major
/// arrays; the smoothed sums `smooth` (per band, with factors `alpha`) carry over from chunk
/// to chunk.
pub(super) struct Chunk<'a> {
    pub(super) sums: &'a [FrameSums],
    pub(super) smooth: &'a mut [[f64; 2]],
    pub(super) alpha: &'a [f64],
    pub(super) scale: CountDivisor,
    pub(super) k_end: usize,
}

/// [`frame_values`] for every band and frame of a chunk, into `out`: bit for bit one
/// `frame_values` per band and frame; here up to eight bands advance in vector lanes, their
/// smoothed sums in registers (band by band through memory, with a division per band and
/// frame, this was 6–7 % of an octave-bank run at 4096 Hz).
pub(super) fn frames_from_sums(isa: Isa, chunk: Chunk<'_>, out: &mut BandFrames<'_>) {
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn wide(chunk: Chunk<'_>, out: &mut BandFrames<'_>) {
        in_lanes::<8>(chunk, out)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn narrow(chunk: Chunk<'_>, out: &mut BandFrames<'_>) {
        in_lanes::<4>(chunk, out)
    }
    match isa {
        // SAFETY (both): `Isa::detect` found the feature on this CPU. No fused operations:
        // the same results as the portable path.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { wide(chunk, out) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2Fma => unsafe { narrow(chunk, out) },
        Isa::Generic => in_lanes::<4>(chunk, out),
    }
}

/// [`frames_from_sums`] with `L` bands per group of lanes (a group's bands over every frame of
/// the chunk, then the next group).
#[inline(always)]
fn in_lanes<const L: usize>(chunk: Chunk<'_>, out: &mut BandFrames<'_>) {
    let Chunk {
        sums,
        smooth,
        alpha,
        scale,
        k_end,
    } = chunk;
    let nb = smooth.len();
    if nb == 0 {
        return;
    }
    let n = out.n_frames;
    for first in (0..nb).step_by(L) {
        let m = (nb - first).min(L);
        // Lanes past the bands stay zero (their values are never written).
        let (mut sm0, mut sm1, mut a) = ([0.0; L], [0.0; L], [0.0; L]);
        for l in 0..m {
            [sm0[l], sm1[l]] = smooth[first + l];
            a[l] = alpha[first + l];
        }
        for (j, frame) in sums.chunks_exact(nb).enumerate() {
            let k = k_end - 1 - j;
            let (mut energy, mut cross, mut power) = ([0.0; L], [0.0; L], [0.0; L]);
            for (l, s) in frame[first..first + m].iter().enumerate() {
                [energy[l], cross[l], power[l]] = *s;
            }
            let mut cosine = [0.0; L];
            for l in 0..L {
                sm0[l] = a[l] * sm0[l] + cross[l];
                sm1[l] = a[l] * sm1[l] + power[l];
                energy[l] = scale.divide(energy[l]);
                cosine[l] = cosine_of(sm0[l], sm1[l]);
            }
            for l in 0..m {
                out.energy[(first + l) * n + k] = energy[l];
                out.cosine[(first + l) * n + k] = cosine[l];
            }
        }
        for l in 0..m {
            smooth[first + l] = [sm0[l], sm1[l]];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chunk through the lanes gives each band and frame's scalar `frame_values`, bit for bit,
    /// on every instruction set of this CPU: 1 to 19 bands (groups of four and eight and what
    /// is left), chunks carrying their smoothed sums over, and powers zero, negative or NaN,
    /// ratios beyond ±1 (clamped), NaN sums.
    #[test]
    fn chunks_in_lanes_are_the_scalar_frames() {
        let special = |i: usize| match i % 23 {
            0 => [1.0, 3.0, 0.0],
            1 => [2.0, -5.0, -1.0],
            2 => [f64::NAN, 0.5, f64::NAN],
            3 => [0.0, 50.0, 1.0],
            4 => [1e-300, f64::NAN, 1e-300],
            _ => {
                let x = i as f64 * 0.731;
                [x.cos().abs(), x.sin() * 2.0, 0.5 + (x * 1.3).cos().abs()]
            }
        };
        for nb in 1..=19 {
            for scale in [CountDivisor::new(8), CountDivisor::new(7)] {
                let alpha: Vec<f64> = (0..nb).map(|b| 0.5 + 0.02 * b as f64).collect();
                let n_frames = 70;
                let sums: Vec<FrameSums> = (0..n_frames * nb).map(special).collect();
                // The scalar form: frame by frame from the last, as the bank processes them.
                let mut sm = vec![[0.25, 0.5]; nb];
                let (mut energy, mut cosine) = (vec![0.0; nb * n_frames], vec![0.0; nb * n_frames]);
                for j in 0..n_frames {
                    let k = n_frames - 1 - j;
                    for b in 0..nb {
                        let (e, c) = frame_values(&mut sm[b], alpha[b], &sums[j * nb + b], scale);
                        energy[b * n_frames + k] = e;
                        cosine[b * n_frames + k] = c;
                    }
                }
                for isa in Isa::available() {
                    let mut smooth = vec![[0.25, 0.5]; nb];
                    let (mut e, mut c) = (vec![0.0; nb * n_frames], vec![0.0; nb * n_frames]);
                    let mut out = BandFrames {
                        energy: &mut e,
                        cosine: &mut c,
                        n_frames,
                    };
                    // Chunks of 1, 29 and 40 frames.
                    let mut k_end = n_frames;
                    for len in [1, 29, 40] {
                        let j0 = n_frames - k_end;
                        let chunk = &sums[j0 * nb..(j0 + len) * nb];
                        let chunk = Chunk {
                            sums: chunk,
                            smooth: &mut smooth,
                            alpha: &alpha,
                            scale,
                            k_end,
                        };
                        frames_from_sums(isa, chunk, &mut out);
                        k_end -= len;
                    }
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&e), bits(&energy), "{isa:?} {nb} bands");
                    assert_eq!(bits(&c), bits(&cosine), "{isa:?} {nb} bands");
                    let flat = |v: &[[f64; 2]]| bits(&v.concat());
                    assert_eq!(flat(&smooth), flat(&sm), "{isa:?} {nb} bands");
                }
            }
        }
        // What the clamp and the NaN rule give.
        assert_eq!(cosine_of(5.0, 1.0), 1.0);
        assert_eq!(cosine_of(-5.0, 1.0), -1.0);
        assert!(cosine_of(1.0, 0.0).is_nan() && cosine_of(1.0, -2.0).is_nan());
        assert_eq!(cosine_of(0.6, 1.0), 0.3);
    }
}

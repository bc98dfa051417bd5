//! A reversed or forward octave bank's frame from the kernel's frame sums: the mean energy per
//! sample, and the cosine of the band's frequency from sums smoothed over a few periods (see
//! [`super::OctaveBankFrontEnd`]). The reversed bank takes the two halves apart, so that the
//! cosines of a chunk of frames are computed in vector lanes.

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
pub(super) fn smoothed_values(
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

/// [`cosine_of`] over a run of frames: `cross[i]` becomes the cosine from itself and
/// `power[i]` (`power` at least as long). In vector lanes: a division per band and frame, one
/// at a time, was most of the cost of turning a reversed decay's frame sums into frames.
pub(super) fn cosines_in_place(isa: Isa, cross: &mut [f64], power: &[f64]) {
    #[inline(always)]
    fn run(cross: &mut [f64], power: &[f64]) {
        for (c, &p) in cross.iter_mut().zip(power) {
            *c = cosine_of(*c, p);
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn run_avx512(cross: &mut [f64], power: &[f64]) {
        run(cross, power)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(cross: &mut [f64], power: &[f64]) {
        run(cross, power)
    }
    match isa {
        // SAFETY (both): `Isa::detect` found the feature on this CPU. No fused operations:
        // the same results as the portable path.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { run_avx512(cross, power) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2Fma => unsafe { run_avx2(cross, power) },
        Isa::Generic => run(cross, power),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lanes give each frame's scalar cosine, bit for bit, on every instruction set of
    /// this CPU: powers zero, negative, NaN, tiny; ratios beyond ±1 (clamped), NaN sums.
    #[test]
    fn cosines_in_lanes_are_the_scalar_ones() {
        let specials = [0.0, -0.0, -1.0, f64::NAN, 1e-300, f64::INFINITY, 2.0];
        let mut cross = Vec::new();
        let mut power = Vec::new();
        for (i, &p) in specials.iter().enumerate() {
            for (j, &c) in [0.3, -5.0, 5.0, f64::NAN, 1e-310, -0.0, f64::NEG_INFINITY]
                .iter()
                .enumerate()
            {
                cross.push(c * (1.0 + (i * 7 + j) as f64 * 1e-3));
                power.push(p);
            }
        }
        for k in 0..1000 {
            let x = k as f64 * 0.731;
            cross.push(x.sin() * (1.0 + (k % 3) as f64));
            power.push(0.5 + (x * 1.3).cos().abs());
        }
        let scalar: Vec<u64> = cross
            .iter()
            .zip(&power)
            .map(|(&c, &p)| cosine_of(c, p).to_bits())
            .collect();
        for isa in Isa::available() {
            // Runs of every length end to end (vector bodies and remainders).
            let mut lanes = cross.clone();
            let mut at = 0;
            for len in (0..).map(|n| n % 19) {
                let end = (at + len).min(lanes.len());
                cosines_in_place(isa, &mut lanes[at..end], &power[at..]);
                at = end;
                if at == lanes.len() {
                    break;
                }
            }
            let got: Vec<u64> = lanes.iter().map(|c| c.to_bits()).collect();
            assert_eq!(got, scalar, "{isa:?}");
        }
        // What the clamp and the NaN rule give.
        assert_eq!(cosine_of(5.0, 1.0), 1.0);
        assert_eq!(cosine_of(-5.0, 1.0), -1.0);
        assert!(cosine_of(1.0, 0.0).is_nan() && cosine_of(1.0, -2.0).is_nan());
        assert_eq!(cosine_of(0.6, 1.0), 0.3);
    }
}

//! arccos of many values at once, four per vector instruction.
//!
//! The octave bank turns every band's every frame into a frequency, f = acos(c)·fs/2π: at
//! 4096 Hz with 2 ms frames that is 3000 arccosines per second of signal and channel, and libm's
//! one-at-a-time `acos` was a seventh of the bank's whole run. This is the same algorithm as
//! fdlibm's `acos` (the classic rational approximation of asin on [0, 0.5] and the half-angle
//! reduction above), written without branches so that a vector of lanes takes each path and keeps
//! its own: within one unit in the last place of the correctly rounded arccosine (libm's is
//! too; the two may differ in that last place), NaN for NaN.

use super::simd::Isa;

// fdlibm's constants with its published digits (each parses to the f64 fdlibm intends).
const PIO2_HI: f64 = std::f64::consts::FRAC_PI_2;
#[allow(clippy::excessive_precision)]
const PIO2_LO: f64 = 6.123_233_995_736_766_036e-17;
const PI: f64 = std::f64::consts::PI;
#[allow(clippy::excessive_precision)]
const PS: [f64; 6] = [
    1.666_666_666_666_666_574e-1,
    -3.255_658_186_224_009_154e-1,
    2.012_125_321_348_629_259e-1,
    -4.005_553_450_067_941_140e-2,
    7.915_349_942_898_145_322e-4,
    3.479_331_075_960_211_676e-5,
];
#[allow(clippy::excessive_precision)]
const QS: [f64; 4] = [
    -2.403_394_911_734_414_219,
    2.020_945_760_233_505_695,
    -6.882_839_716_054_532_930e-1,
    7.703_815_055_590_193_528e-2,
];

/// asin(√z)/√z − 1 over √z², i.e. the rational part r(z) = p(z)/q(z) of fdlibm's asin.
#[inline(always)]
fn rational(z: f64) -> f64 {
    let p = z * (PS[0] + z * (PS[1] + z * (PS[2] + z * (PS[3] + z * (PS[4] + z * PS[5])))));
    let q = 1.0 + z * (QS[0] + z * (QS[1] + z * (QS[2] + z * QS[3])));
    p / q
}

/// arccos of one value, every path computed and the right one selected (so that it vectorizes).
#[inline(always)]
fn acos_one(x: f64) -> f64 {
    let ax = x.abs();
    // |x| < 0.5: π/2 − asin(x).
    let z_mid = x * x;
    let mid = PIO2_HI - (x - (PIO2_LO - x * rational(z_mid)));
    // |x| ≥ 0.5: 2·asin(√((1 − |x|)/2)), reflected for negative x.
    let z = (1.0 - ax) * 0.5;
    let s = z.sqrt();
    let r = rational(z);
    let negative = PI - 2.0 * (s + (r * s - PIO2_LO));
    // For x > 0, fdlibm splits √z into a 26-bit head and a correction for the last bits.
    let head = f64::from_bits(s.to_bits() & 0xffff_ffff_0000_0000);
    // (At x = 1, z = s = 0: no correction, where the quotient would be 0/0.)
    let c = if s > 0.0 {
        (z - head * head) / (s + head)
    } else {
        0.0
    };
    let positive = 2.0 * (head + (r * s + c));
    if ax < 0.5 {
        mid
    } else if x < 0.0 {
        negative
    } else {
        positive
    }
}

/// acos(value) · scale for one value, bit for bit what [`acos_scaled_in_place`] gives it.
#[inline]
pub(crate) fn acos_scaled(value: f64, scale: f64) -> f64 {
    acos_one(value) * scale
}

/// `values[i] = acos(values[i]) · scale` for every i (inputs in [−1, 1]; NaN stays NaN).
pub(crate) fn acos_scaled_in_place(isa: Isa, values: &mut [f64], scale: f64) {
    #[inline(always)]
    fn run(values: &mut [f64], scale: f64) {
        for v in values.iter_mut() {
            *v = acos_one(*v) * scale;
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(values: &mut [f64], scale: f64) {
        run(values, scale)
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU (no fused operations: the same results
        // as the portable path).
        Isa::Avx2Fma | Isa::Avx512 => unsafe { run_avx2(values, scale) },
        Isa::Generic => run(values, scale),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units of the last place between two finite f64 of the same sign.
    fn ulps(a: f64, b: f64) -> u64 {
        a.to_bits().abs_diff(b.to_bits())
    }

    /// Against libm's `acos` on a dense sweep of [−1, 1], the branch points ±0.5, the ends, tiny
    /// values and NaN, on every instruction set of this CPU: within one unit in the last place,
    /// and the same bits on every instruction set.
    #[test]
    fn lane_acos_is_within_one_ulp_of_libm() {
        let mut xs: Vec<f64> = (0..=400_000)
            .map(|i| -1.0 + 2.0 * i as f64 / 400_000.0)
            .collect();
        for edge in [
            -1.0f64,
            -0.5,
            -0.0,
            0.0,
            0.5,
            1.0,
            1e-300,
            -1e-20,
            0.999_999_999_999,
        ] {
            xs.extend([edge, f64::from_bits(edge.to_bits() + 1)]);
        }
        xs.retain(|x| x.abs() <= 1.0);
        let mut by_isa = Vec::new();
        for isa in Isa::available() {
            let mut got = xs.clone();
            acos_scaled_in_place(isa, &mut got, 1.0);
            let worst = xs
                .iter()
                .zip(&got)
                .map(|(x, g)| ulps(x.acos(), *g))
                .max()
                .unwrap_or(0);
            assert!(worst <= 1, "{isa:?}: {worst} ulp");
            by_isa.push(got);
        }
        for other in &by_isa[1..] {
            assert!(other
                .iter()
                .zip(&by_isa[0])
                .all(|(a, b)| a.to_bits() == b.to_bits()));
        }
        let mut nan = [f64::NAN, 0.3];
        acos_scaled_in_place(Isa::detect(), &mut nan, 2.0);
        assert!(nan[0].is_nan());
        assert_eq!(nan[1], 2.0 * acos_one(0.3));
    }
}

//! atan2 of many pairs at once, four or eight per vector instruction.
//!
//! The Goyder bank turns every band's every frame into a frequency from the phase of its lag
//! product, f = f_h + atan2(im, re)·fs/2π: libm's one-at-a-time `atan2` was 30 % of a
//! 64-channel Goyder run at 4096 Hz. This is fdlibm's `atan` (an odd polynomial in 11 terms
//! after reduction to one of five intervals) and its `atan2` quadrant rules, written without
//! branches so that a vector of lanes takes each path and keeps its own. The reduction is
//! selected before its one division, so each lane computes exactly fdlibm's expression: within
//! one unit in the last place of libm's result over the test's sweep (libm's is correctly
//! rounded or nearly; the two may differ in that last place), NaN for NaN.

use super::simd::Isa;

// fdlibm's constants with its published digits (each parses to the f64 fdlibm intends).
#[allow(clippy::excessive_precision)]
const ATAN_HI: [f64; 4] = [
    4.636_476_090_008_060_935_15e-01,
    std::f64::consts::FRAC_PI_4, // fdlibm's 7.85398163397448278999e-01, the same f64
    9.827_937_232_473_290_540_82e-01,
    std::f64::consts::FRAC_PI_2, // fdlibm's 1.57079632679489655800e+00, the same f64
];
#[allow(clippy::excessive_precision)]
const ATAN_LO: [f64; 4] = [
    2.269_877_745_296_168_709_24e-17,
    3.061_616_997_868_383_017_93e-17,
    1.390_331_103_123_099_845_16e-17,
    6.123_233_995_736_766_035_87e-17,
];
#[allow(clippy::excessive_precision)]
const AT: [f64; 11] = [
    3.333_333_333_333_293_180_27e-01,
    -1.999_999_999_987_648_324_76e-01,
    1.428_571_427_250_346_637_11e-01,
    -1.111_111_040_546_235_578_80e-01,
    9.090_887_133_436_506_561_96e-02,
    -7.691_876_205_044_829_994_95e-02,
    6.661_073_137_387_531_206_69e-02,
    -5.833_570_133_790_573_486_45e-02,
    4.976_877_994_615_932_360_17e-02,
    -3.653_157_274_421_691_552_70e-02,
    1.628_582_011_536_578_236_23e-02,
];
const PI: f64 = std::f64::consts::PI;
const PI_O_2: f64 = std::f64::consts::FRAC_PI_2;
#[allow(clippy::excessive_precision)]
const PI_LO: f64 = 1.224_646_799_147_353_177_2e-16;

/// atan(a) for a ≥ 0 (or +∞), every reduction's numerator and denominator selected first.
#[inline(always)]
fn atan_nonnegative(a: f64) -> f64 {
    // fdlibm's intervals: [0, 7/16) none; [7/16, 11/16) → (2a − 1)/(2 + a), atan(1/2);
    // [11/16, 19/16) → (a − 1)/(a + 1), atan(1); [19/16, 39/16) → (a − 1.5)/(1 + 1.5a),
    // atan(3/2); beyond → −1/a, atan(∞).
    let (num, den, id) = if a < 0.6875 {
        (2.0 * a - 1.0, 2.0 + a, 0)
    } else if a < 1.1875 {
        (a - 1.0, a + 1.0, 1)
    } else if a < 2.4375 {
        (a - 1.5, 1.0 + 1.5 * a, 2)
    } else {
        (-1.0, a, 3)
    };
    let reduced = num / den;
    let small = a < 0.4375;
    let x = if small { a } else { reduced };
    let z = x * x;
    let w = z * z;
    let s1 = z * (AT[0] + w * (AT[2] + w * (AT[4] + w * (AT[6] + w * (AT[8] + w * AT[10])))));
    let s2 = w * (AT[1] + w * (AT[3] + w * (AT[5] + w * (AT[7] + w * AT[9]))));
    if small {
        x - x * (s1 + s2)
    } else {
        ATAN_HI[id] - ((x * (s1 + s2) - ATAN_LO[id]) - x)
    }
}

/// atan2(y, x) for finite or infinite y, x not both zero (fdlibm's quadrant rules; ±0 for
/// y = ±0 with x > 0, ±π with x < 0).
#[inline(always)]
fn atan2_one(y: f64, x: f64) -> f64 {
    let (ay, ax) = (y.abs(), x.abs());
    // The exponent difference decides where |y/x| is beyond the polynomial's reach.
    let k = ((ay.to_bits() >> 52) as i64) - ((ax.to_bits() >> 52) as i64);
    let z = if k > 60 {
        PI_O_2 + 0.5 * PI_LO
    } else if x < 0.0 && k < -60 {
        0.0
    } else {
        atan_nonnegative(ay / ax)
    };
    let quadrant = if x.is_sign_negative() {
        PI - (z - PI_LO)
    } else {
        z
    };
    let angle = if y == 0.0 && !x.is_sign_negative() {
        0.0
    } else if y == 0.0 {
        PI
    } else {
        quadrant
    };
    let signed = if y.is_sign_negative() { -angle } else { angle };
    if x.is_nan() || y.is_nan() {
        f64::NAN
    } else {
        signed
    }
}

/// The frame frequency of a lag product `re + j·im` in a band heterodyned by `f_h_hz`:
/// `f_h_hz + atan2(im, re)·fs_hz/2π`, NaN where both are zero (no signal), bit for bit what
/// [`frame_frequencies_in_place`] gives it.
#[inline(always)]
pub(crate) fn frame_frequency(re: f64, im: f64, f_h_hz: f64, fs_hz: f64) -> f64 {
    let f = f_h_hz + atan2_one(im, re) * fs_hz / (2.0 * PI);
    if re == 0.0 && im == 0.0 {
        f64::NAN
    } else {
        f
    }
}

/// `re[i] = frame_frequency(re[i], im[i], f_h_hz, fs_hz)` for every i (`im` as long as `re`).
pub(crate) fn frame_frequencies_in_place(
    isa: Isa,
    re: &mut [f64],
    im: &[f64],
    f_h_hz: f64,
    fs_hz: f64,
) {
    #[inline(always)]
    fn run(re: &mut [f64], im: &[f64], f_h_hz: f64, fs_hz: f64) {
        for (r, &i) in re.iter_mut().zip(im) {
            *r = frame_frequency(*r, i, f_h_hz, fs_hz);
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(re: &mut [f64], im: &[f64], f_h_hz: f64, fs_hz: f64) {
        run(re, im, f_h_hz, fs_hz)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn run_avx512(re: &mut [f64], im: &[f64], f_h_hz: f64, fs_hz: f64) {
        run(re, im, f_h_hz, fs_hz)
    }
    assert_eq!(re.len(), im.len(), "one imaginary part per real part");
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU (no fused operations: the same results
        // as the portable path).
        Isa::Avx2Fma => unsafe { run_avx2(re, im, f_h_hz, fs_hz) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX-512F on this CPU (no fused operations either).
        Isa::Avx512 => unsafe { run_avx512(re, im, f_h_hz, fs_hz) },
        Isa::Generic => run(re, im, f_h_hz, fs_hz),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units of the last place between two finite f64 of the same sign.
    fn ulps(a: f64, b: f64) -> u64 {
        a.to_bits().abs_diff(b.to_bits())
    }

    /// Against libm's `atan2` on a dense sweep of angles at several magnitudes, the reduction
    /// boundaries, both axes and signed zeros, huge and tiny ratios, infinities, NaN: within one
    /// unit in the last place; and the frame frequencies vectorised over whole runs have the
    /// scalar form's bits on every instruction set of this CPU.
    #[test]
    fn lane_atan2_is_within_one_ulp_of_libm() {
        let mut pairs: Vec<(f64, f64)> = Vec::new();
        for i in 0..200_000 {
            let t = -PI + 2.0 * PI * i as f64 / 200_000.0;
            for r in [1.0, 3.7e-9, 2.5e12] {
                pairs.push((r * t.sin(), r * t.cos()));
            }
        }
        for ratio in [0.4375f64, 0.6875, 1.1875, 2.4375] {
            for step in [-1i64, 0, 1] {
                let a = f64::from_bits(ratio.to_bits().wrapping_add(step as u64));
                for (sy, sx) in [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
                    pairs.push((sy * a, sx * 1.0));
                    pairs.push((sy * a * 3.0, sx * 3.0));
                }
            }
        }
        for (y, x) in [
            (0.0, 1.0),
            (-0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (1.0, -0.0),
            (1e300, 1e-300),
            (1e-300, 1e300),
            (-1e-300, -1e300),
            (1e-300, -1e300),
            (1e-20, -1.0),
            (f64::INFINITY, 1.0),
            (1.0, f64::INFINITY),
            (1.0, f64::NEG_INFINITY),
            (-1.0, f64::NEG_INFINITY),
            (f64::MIN_POSITIVE, 1.0),
            (f64::NAN, 1.0),
            (1.0, f64::NAN),
        ] {
            pairs.push((y, x));
        }
        for &(y, x) in &pairs {
            let (want, got) = (y.atan2(x), atan2_one(y, x));
            if want.is_nan() {
                assert!(got.is_nan(), "atan2({y:e}, {x:e}) = {got:e}");
                continue;
            }
            assert!(
                want.is_sign_negative() == got.is_sign_negative() && ulps(want, got) <= 1,
                "atan2({y:e}, {x:e}) = {want:e}, got {got:e}"
            );
        }
        // Every instruction set, vectorised over whole runs, gives the scalar form's bits.
        let mut re: Vec<f64> = pairs.iter().map(|p| p.1).collect();
        let im: Vec<f64> = pairs.iter().map(|p| p.0).collect();
        let scalar: Vec<u64> = re
            .iter()
            .zip(&im)
            .map(|(&r, &i)| frame_frequency(r, i, 1000.0, 4096.0).to_bits())
            .collect();
        let original = re.clone();
        for isa in Isa::available() {
            re.copy_from_slice(&original);
            frame_frequencies_in_place(isa, &mut re, &im, 1000.0, 4096.0);
            let bits: Vec<u64> = re.iter().map(|v| v.to_bits()).collect();
            assert!(bits == scalar, "{isa:?}");
        }
    }

    /// No signal (both parts zero) has no frequency; NaN stays NaN; otherwise the heterodyne
    /// frequency plus the phase step in Hz, as the scalar form gives it.
    #[test]
    fn frame_frequencies_are_the_heterodyne_plus_the_phase_step() {
        let (f_h, fs) = (1000.0f64, 4096.0f64);
        let mut re: [f64; 5] = [0.0, f64::NAN, 1.0, 0.5, -2.0];
        let im: [f64; 5] = [0.0, 1.0, 0.0, 0.5, 1e-3];
        let want: Vec<f64> = re
            .iter()
            .zip(&im)
            .map(|(&r, &i)| f_h + i.atan2(r) * fs / (2.0 * PI))
            .collect();
        frame_frequencies_in_place(Isa::detect(), &mut re, &im, f_h, fs);
        assert!(re[0].is_nan() && re[1].is_nan());
        assert_eq!(re[2], f_h);
        for (g, w) in re[3..].iter().zip(&want[3..]) {
            assert!((g - w).abs() <= 1e-12 * w.abs(), "{g} vs {w}");
        }
        assert_eq!(re[4], frame_frequency(-2.0, 1e-3, f_h, fs));
    }
}

//! The prime-factor FFT against the DFT by its definition, and the lengths it plans.

use super::*;

/// The oracle: the DFT by its definition, angles reduced exactly (jk mod N; the N roots of
/// unity tabulated once).
fn naive_dft(z: &[Complex<f64>]) -> Vec<Complex<f64>> {
    let n = z.len();
    let roots: Vec<Complex<f64>> = (0..n)
        .map(|m| {
            let angle = -2.0 * std::f64::consts::PI * m as f64 / n as f64;
            Complex::new(angle.cos(), angle.sin())
        })
        .collect();
    (0..n)
        .map(|k| {
            z.iter()
                .enumerate()
                .fold(Complex::new(0.0, 0.0), |acc, (j, &v)| {
                    acc + v * roots[(j * k) % n]
                })
        })
        .collect()
}

/// Lengths of the register kernels' factors only: two to four axes, every factor size, last
/// steps of one to eight lines.
const REGISTER_LENGTHS: [usize; 15] = [
    15,
    21,
    35,
    45,
    63,
    99,
    117,
    143,
    315,
    429,
    585,
    819,
    1001,
    1155,
    5 * 7 * 11,
];

/// Every planned length against the definition on every instruction set of this CPU, to
/// 1e-13 of the spectrum's largest bin: two to four factors, every factor size, last
/// steps of one to eight lines, frames shorter than N (zero padding), one frame or two.
#[test]
fn transforms_equal_the_dft_by_definition() {
    let lengths: Vec<usize> = REGISTER_LENGTHS
        .into_iter()
        .chain([
            // Wide factors (primes above 13): first, last and middle axes, with small ones
            // and each other, tails of every K_BLOCK remainder (H = 8 … 14, 56,
            // 128), the 200 ms windows at 16384 Hz (29 · 113) and 65536 Hz (3 · 17 · 257);
            // for Rader's, p − 1 = 2 · 4 · 5, 4 · 13, 2 · 4 · 4 · 3 and 4 · 4 · 4 · 3 too.
            3 * 41,
            5 * 53,
            3 * 97,
            5 * 193,
            3 * 17,
            17 * 19,
            5 * 23,
            3 * 5 * 29,
            9 * 31,
            5 * 17 * 19,
            17 * 29,
            29 * 113,
            3 * 17 * 257,
        ])
        .collect();
    // Each wide prime by the direct sum, and by Rader's wherever it applies.
    let plans = [usize::MAX, 0].iter().flat_map(|&rader_min| {
        lengths.iter().map(move |&n| {
            PrimeFactorFft::with_rader_from(n, rader_min).unwrap_or_else(|| panic!("{n} planned"))
        })
    });
    let plans: Vec<PrimeFactorFft> = plans.collect();
    for isa in Isa::available() {
        for plan in &plans {
            let n = plan.n;
            let len = n - n / 5;
            let a: Vec<f64> = (0..len)
                .map(|j| (0.37 * j as f64).sin() + ((j * 7919) % 101) as f64 * 1e-2)
                .collect();
            let b: Vec<f64> = (0..len).map(|j| (0.11 * j as f64).cos() - 0.3).collect();
            let window: Vec<f64> = (0..len).map(|j| 1.0 + (j % 3) as f64).collect();
            for two in [true, false] {
                let input = FramePair {
                    a: &a,
                    b: two.then_some(&b[..]),
                    window: &window,
                };
                let z: Vec<Complex<f64>> = (0..n)
                    .map(|j| match j < len {
                        true => Complex::new(a[j] * window[j], b[j] * window[j] * f64::from(two)),
                        false => Complex::new(0.0, 0.0),
                    })
                    .collect();
                let mut got = Vec::new();
                plan.transform(isa, &input, &mut SplitBuffer::default(), &mut got);
                let expected = naive_dft(&z);
                let scale = expected.iter().fold(0.0f64, |m, c| m.max(c.norm()));
                assert_eq!(got.len(), n);
                for (k, (g, e)) in got.iter().zip(&expected).enumerate() {
                    assert!(
                        (g - e).norm() <= 1e-13 * scale,
                        "{isa:?} N {n} two {two} bin {k}: {g} vs {e}"
                    );
                }
            }
        }
    }
}

/// Lengths the lane kernels cannot take are left to rustfft: even ones, single prime
/// powers, powers of small primes beyond the register kernels' (rustfft's own are fast),
/// and factors past the wide stages' limit.
#[test]
fn only_odd_products_of_coprime_factors_the_stages_take_are_planned() {
    for n in [
        1,
        2,
        9,
        13,
        25,
        27,
        113,
        25 * 3,
        49 * 3,
        200,
        201 * 2,
        818,
        820,
        3 * 263,
        17 * 263,
    ] {
        assert!(PrimeFactorFft::new(n).is_none(), "{n}");
    }
    assert_eq!(prime_powers(819), vec![9, 7, 13]);
    for n in [819, 3 * 17, 3 * 31, 201, 29 * 113, 3 * 17 * 257] {
        assert_eq!(PrimeFactorFft::new(n).map(|p| p.n), Some(n));
    }
}

/// A frame pair's powers straight from the last stage ([`super::pair_powers`]) are the
/// unpacked powers of the spectrum ([`super::super::kernels::unpack_pair_powers`]) bit for
/// bit, on every instruction set: every register factor last, wide ones last by the direct sum
/// and by Rader's, one to many vectors of line pairs (the last one part-filled), frames
/// shorter than N (zero padding) and frames of N.
#[test]
fn pair_powers_from_the_last_stage_equal_the_unpacked_spectrum_bit_for_bit() {
    let lengths = REGISTER_LENGTHS.into_iter().chain([
        3 * 5 * 29,
        9 * 31,
        3 * 41,
        5 * 193,
        17 * 29,
        29 * 113,
        3 * 17 * 257,
    ]);
    for n in lengths {
        let plan = PrimeFactorFft::new(n).unwrap_or_else(|| panic!("{n} planned"));
        // The pairs must plan (else the test would compare the slow path with itself).
        assert!(plan.pair_powers.is_some(), "N {n}");
        for len in [n, n - n / 5] {
            let a: Vec<f64> = (0..len)
                .map(|j| (0.37 * j as f64).sin() + ((j * 7919) % 101) as f64 * 1e-2)
                .collect();
            let b: Vec<f64> = (0..len).map(|j| (0.11 * j as f64).cos() - 0.3).collect();
            let window: Vec<f64> = (0..len).map(|j| 0.5 + (j % 3) as f64).collect();
            let input = FramePair {
                a: &a,
                b: Some(&b),
                window: &window,
            };
            for isa in Isa::available() {
                let mut spectrum = Vec::new();
                plan.transform(isa, &input, &mut SplitBuffer::default(), &mut spectrum);
                let bins = n / 2 + 1;
                let (mut want_a, mut want_b) = (vec![0.0; bins], vec![0.0; bins]);
                super::super::kernels::unpack_pair_powers(isa, &spectrum, &mut want_a, &mut want_b);
                // Start from values no bin holds, so that a bin left unwritten shows.
                let (mut got_a, mut got_b) = (vec![-1.0; bins], vec![-1.0; bins]);
                let mut work = SplitBuffer::default();
                plan.pair_powers(
                    isa,
                    &input,
                    &mut work,
                    &mut Vec::new(),
                    (&mut got_a, &mut got_b),
                );
                for k in 0..bins {
                    assert_eq!(
                        (got_a[k].to_bits(), got_b[k].to_bits()),
                        (want_a[k].to_bits(), want_b[k].to_bits()),
                        "{isa:?} N {n} frames of {len}: bin {k} {} {} vs {} {}",
                        got_a[k],
                        got_b[k],
                        want_a[k],
                        want_b[k]
                    );
                }
            }
        }
    }
}

/// A real frame of 2M points through the transform of its M sample pairs: its powers straight
/// from the last stage ([`PrimeFactorFft::half_powers`] with tables) equal the spectrum's
/// post-processing by [`super::super::kernels::half_spectrum_powers`] bit for bit, on every
/// instruction set, for every register-factor length M and wide last stages of both kinds
/// (the tables must exist for each: else
/// the test would compare the slow path with itself), frames of 2M samples and shorter.
#[test]
fn half_powers_from_the_last_stage_equal_the_post_processed_spectrum_bit_for_bit() {
    use super::super::kernels::half_spectrum_powers;
    use super::super::tables::shared_half_twiddles;
    let lengths = REGISTER_LENGTHS.into_iter().chain([
        // Wide last stages: direct sums (29, 31, 41) and Rader's (113 at 32768 Hz, 193, 257).
        3 * 5 * 29,
        9 * 31,
        3 * 41,
        5 * 193,
        29 * 113,
        3 * 17 * 257,
    ]);
    for m in lengths {
        let plan = PrimeFactorFft::new(m).expect("planned");
        let twiddles = shared_half_twiddles(2 * m);
        let tables = plan.half_power_tables(&twiddles);
        assert!(tables.is_some(), "no half-power tables for M = {m}");
        for frame in [2 * m, 2 * m - 1, m + 3] {
            let x: Vec<f64> = (0..frame)
                .map(|i| ((i * 7919 % 1013) as f64 - 500.0) * 1e-3 + (i as f64 * 0.37).sin())
                .collect();
            let window: Vec<f64> = (0..frame)
                .map(|i| 0.5 - 0.5 * (i as f64 * 0.02).cos())
                .collect();
            for isa in Isa::available() {
                let (mut work, mut spectrum) = (SplitBuffer::default(), Vec::new());
                plan.transform_interleaved(isa, (&x, &window), &mut work, &mut spectrum);
                let mut expected = vec![0.0; m + 1];
                half_spectrum_powers(isa, &spectrum, &twiddles, &mut expected);
                let mut got = vec![f64::NAN; m + 1];
                let (mut work, mut spectrum) = (SplitBuffer::default(), Vec::new());
                plan.half_powers(
                    isa,
                    (&x, &window),
                    (tables.as_ref(), &twiddles),
                    &mut work,
                    &mut spectrum,
                    &mut got,
                );
                for (k, (g, e)) in got.iter().zip(&expected).enumerate() {
                    assert_eq!(
                        g.to_bits(),
                        e.to_bits(),
                        "{isa:?} M {m} frame {frame} bin {k}: {g} vs {e}"
                    );
                }
            }
        }
    }
}

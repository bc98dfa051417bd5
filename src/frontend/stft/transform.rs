//! One frame (or a pair of frames) in, its power spectrum out: the transform the STFT runs
//! per hop, chosen by the parity of the FFT length.
//!
//! - **Even length N = 2M**: the frame's samples, taken two by two as complex numbers, go
//!   through one complex FFT of M; realfft's post-processing turns that into the real
//!   spectrum, here fused with |X_k|² ([`super::kernels::half_spectrum_powers`]). realfft
//!   itself would write the spectrum and the power pass read it back: that pass and the
//!   post-processing were 11 % of a whole 48 kHz run; the fused one reads the half spectrum once
//!   and writes only the powers. Same arithmetic, same bits.
//! - **Odd length**: realfft's real transform costs a whole complex FFT of N, so two successive
//!   frames share one (one as the real part, one as the imaginary part) whenever both are in
//!   hand; a lone frame takes realfft's. Where the length is a product of small coprime factors
//!   (819 = 9 · 7 · 13 at 4096 Hz) and the CPU has AVX-512, both take the prime-factor FFT of
//!   [`super::prime_factor`] instead (a quarter faster than rustfft's plan of 819, windowing
//!   included).

use std::sync::Arc;

use realfft::RealToComplex;
use rustfft::num_complex::Complex;
use rustfft::Fft;

use super::kernels::{
    half_spectrum_powers, power_spectrum, unpack_pair_powers, window_and_zero_pad,
    window_into_pairs, window_pair,
};
use super::prime_factor::{FramePair, HalfPowerTables, PrimeFactorFft, SplitBuffer};
use super::tables::{shared_complex_plan, shared_half_twiddles, shared_plan, shared_prime_factor};
use crate::frontend::simd::Isa;

/// The FFT plans of one FFT length (shared by every front end of that length).
#[derive(Clone)]
pub(super) enum Transform {
    /// N = 2M: the complex FFT of M, and realfft's post-processing twiddles (halved).
    Even {
        half: Arc<dyn Fft<f64>>,
        twiddles: Arc<[Complex<f64>]>,
    },
    /// N odd: realfft's transform for a lone frame, the complex one of N for a pair.
    Odd {
        real: Arc<dyn RealToComplex<f64>>,
        pair: Arc<dyn Fft<f64>>,
    },
    /// N odd, where it applies ([`shared_prime_factor`]): the prime-factor FFT for both (no
    /// rustfft plan is made: planning them was 0.1 ms of every run's start).
    PrimeFactor(Arc<PrimeFactorFft>),
    /// N = 2M with the prime-factor FFT applying to M: as `Even`, its complex FFT of M taken
    /// by the prime-factor FFT (M = 819 at 8192 Hz, 3277 at 32768 Hz).
    EvenPrimeFactor {
        half: Arc<PrimeFactorFft>,
        twiddles: Arc<[Complex<f64>]>,
        /// The post-processing in the last stage's lanes, where the plan allows it.
        tables: Option<Arc<HalfPowerTables>>,
    },
}

impl Transform {
    /// The plans for an FFT of `nfft` points (≥ 2).
    pub(super) fn new(nfft: usize) -> Transform {
        if nfft.is_multiple_of(2) {
            let twiddles = shared_half_twiddles(nfft);
            match shared_prime_factor(nfft / 2) {
                Some(half) => Transform::EvenPrimeFactor {
                    tables: half.half_power_tables(&twiddles).map(Arc::new),
                    half,
                    twiddles,
                },
                None => Transform::Even {
                    half: shared_complex_plan(nfft / 2),
                    twiddles,
                },
            }
        } else if let Some(plan) = shared_prime_factor(nfft) {
            Transform::PrimeFactor(plan)
        } else {
            Transform::Odd {
                real: shared_plan(nfft),
                pair: shared_complex_plan(nfft),
            }
        }
    }

    /// Whether two successive frames are best transformed together ([`Transform::pair_powers`]).
    pub(super) fn pairs_frames(&self) -> bool {
        matches!(self, Transform::Odd { .. } | Transform::PrimeFactor(_))
    }

    /// `buffers.power` (N/2 + 1 bins) = the power spectrum of `x · window`, zero-padded to N.
    pub(super) fn frame_power(
        &self,
        isa: Isa,
        x: &[f64],
        window: &[f64],
        buffers: &mut FrameBuffers,
    ) {
        match self {
            Transform::Even { half, twiddles } => {
                buffers.fit_even(half.as_ref());
                let FrameBuffers {
                    half_in,
                    spectrum,
                    scratch,
                    power,
                    ..
                } = buffers;
                window_into_pairs(isa, half_in, x, window);
                // Lengths are fixed at construction, so the FFT cannot fail.
                half.process_outofplace_with_scratch(half_in, spectrum, scratch);
                half_spectrum_powers(isa, spectrum, twiddles, power);
            }
            Transform::EvenPrimeFactor {
                half,
                twiddles,
                tables,
            } => {
                sized(&mut buffers.power, half.len() + 1, 0.0);
                sized(&mut buffers.power_b, half.len() + 1, 0.0);
                half.half_powers(
                    isa,
                    (x, window),
                    (tables.as_deref(), twiddles),
                    &mut buffers.split,
                    &mut buffers.pair,
                    &mut buffers.power,
                );
            }
            Transform::PrimeFactor(plan) => {
                prime_factor_spectrum(plan, isa, (x, None), window, buffers);
                let bins = buffers.power.len();
                power_spectrum(isa, &mut buffers.power, &buffers.pair[..bins]);
            }
            Transform::Odd { real, .. } => {
                buffers.fit_odd(real.as_ref(), None);
                let FrameBuffers {
                    fft_in,
                    spectrum,
                    scratch,
                    power,
                    ..
                } = buffers;
                window_and_zero_pad(isa, fft_in, x, window);
                let _ = real.process_with_scratch(fft_in, spectrum, scratch);
                power_spectrum(isa, power, spectrum);
            }
        }
    }

    /// `buffers.power` and `buffers.power_b` = the power spectra of `a · window` and
    /// `b · window` (odd lengths; an even one takes them one by one).
    pub(super) fn pair_powers(
        &self,
        isa: Isa,
        a: &[f64],
        b: &[f64],
        window: &[f64],
        buffers: &mut FrameBuffers,
    ) {
        match self {
            Transform::PrimeFactor(plan) => {
                let bins = plan.len() / 2 + 1;
                sized(&mut buffers.power, bins, 0.0);
                sized(&mut buffers.power_b, bins, 0.0);
                let input = FramePair {
                    a,
                    b: Some(b),
                    window,
                };
                let powers = (&mut buffers.power[..], &mut buffers.power_b[..]);
                plan.pair_powers(isa, &input, &mut buffers.split, &mut buffers.pair, powers);
            }
            Transform::Odd { real, pair } => {
                buffers.fit_odd(real.as_ref(), Some(pair.as_ref()));
                window_pair(&mut buffers.pair, a, b, window);
                pair.process_with_scratch(&mut buffers.pair, &mut buffers.pair_scratch);
                unpack_pair_powers(isa, &buffers.pair, &mut buffers.power, &mut buffers.power_b);
            }
            Transform::Even { .. } | Transform::EvenPrimeFactor { .. } => {
                self.frame_power(isa, b, window, buffers);
                std::mem::swap(&mut buffers.power, &mut buffers.power_b);
                self.frame_power(isa, a, window, buffers);
            }
        }
    }
}

/// `buffers.pair` = the prime-factor FFT of a · window + i b · window (b none: zero), the
/// powers sized for its bins.
fn prime_factor_spectrum(
    plan: &PrimeFactorFft,
    isa: Isa,
    (a, b): (&[f64], Option<&[f64]>),
    window: &[f64],
    buffers: &mut FrameBuffers,
) {
    let bins = plan.len() / 2 + 1;
    sized(&mut buffers.power, bins, 0.0);
    sized(&mut buffers.power_b, bins, 0.0);
    let input = FramePair { a, b, window };
    plan.transform(isa, &input, &mut buffers.split, &mut buffers.pair);
}

/// The buffers of one frame's transform (windowed frame, spectrum, FFT scratch, power). No frame
/// keeps them, so one set per thread serves every channel that thread analyses and stays in the
/// cache; one set per channel made the 48 kHz path memory-bound.
#[derive(Default)]
pub(super) struct FrameBuffers {
    /// Even lengths: the windowed frame as M sample pairs.
    half_in: Vec<Complex<f64>>,
    /// Odd lengths: the windowed frame for realfft.
    fft_in: Vec<f64>,
    /// The half spectrum (even) or realfft's spectrum (odd).
    spectrum: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
    /// The frame's power spectrum (the first frame's, for a pair).
    pub(super) power: Vec<f64>,
    /// A frame pair's packed input and transform (in place), its scratch, and the second
    /// frame's power spectrum.
    pair: Vec<Complex<f64>>,
    pair_scratch: Vec<Complex<f64>>,
    pub(super) power_b: Vec<f64>,
    /// The prime-factor FFT's working arrays (its spectrum goes to `pair`).
    split: SplitBuffer,
}

impl FrameBuffers {
    /// Sizes the buffers for the half-length complex FFT `half` (a no-op when they fit). Every
    /// buffer this transform uses is checked: a thread may run transforms of other lengths and
    /// parities in between, and they share `spectrum`, `scratch` and the powers.
    fn fit_even(&mut self, half: &dyn Fft<f64>) {
        let (m, zero) = (half.len(), Complex::new(0.0, 0.0));
        sized(&mut self.half_in, m, zero);
        sized(&mut self.spectrum, m, zero);
        sized(&mut self.scratch, half.get_outofplace_scratch_len(), zero);
        sized(&mut self.power, m + 1, 0.0);
        sized(&mut self.power_b, m + 1, 0.0);
    }

    /// Sizes the buffers for `real` and, with frame pairs, for `pair` (a no-op when they fit;
    /// every buffer checked, as in [`FrameBuffers::fit_even`]).
    fn fit_odd(&mut self, real: &dyn RealToComplex<f64>, pair: Option<&dyn Fft<f64>>) {
        let (bins, zero) = (real.complex_len(), Complex::new(0.0, 0.0));
        sized(&mut self.fft_in, real.len(), 0.0);
        sized(&mut self.spectrum, bins, zero);
        sized(&mut self.scratch, real.get_scratch_len(), zero);
        sized(&mut self.power, bins, 0.0);
        sized(&mut self.power_b, bins, 0.0);
        if let Some(pair) = pair {
            sized(&mut self.pair, pair.len(), zero);
            sized(&mut self.pair_scratch, pair.get_inplace_scratch_len(), zero);
        }
    }
}

/// `v` with `len` elements (refilled with `fill` when its length was different).
fn sized<T: Clone>(v: &mut Vec<T>, len: usize, fill: T) {
    if v.len() != len {
        v.clear();
        v.resize(len, fill);
    }
}

thread_local! {
    static FRAME_BUFFERS: std::cell::RefCell<FrameBuffers> = Default::default();
}

/// Runs `f` with this thread's frame buffers.
pub(super) fn with_frame_buffers<R>(f: impl FnOnce(&mut FrameBuffers) -> R) -> R {
    crate::frontend::with_thread_scratch(&FRAME_BUFFERS, f)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle: realfft's r2c of `frame · window` (zero beyond, to `nfft` points), then the
    /// power of each bin.
    fn realfft_powers(frame: &[f64], window: &[f64], nfft: usize) -> Vec<f64> {
        let real = realfft::RealFftPlanner::<f64>::new().plan_fft_forward(nfft);
        let mut input = real.make_input_vec();
        for ((d, &v), &g) in input.iter_mut().zip(frame).zip(window) {
            *d = v * g;
        }
        let mut out = real.make_output_vec();
        real.process(&mut input, &mut out).unwrap();
        out.iter().map(|c| c.norm_sqr()).collect()
    }

    /// The even-length path with rustfft's plan of M, whatever the CPU would pick.
    fn rustfft_even(nfft: usize) -> Transform {
        Transform::Even {
            half: shared_complex_plan(nfft / 2),
            twiddles: shared_half_twiddles(nfft),
        }
    }

    /// The fused even-length path gives realfft's transform followed by |X|², bit for bit,
    /// for lengths 2M with M even and odd, with and without zero padding, on every
    /// instruction set of this CPU (with rustfft's plan of M, as realfft has it).
    #[test]
    fn even_lengths_give_realffts_powers_bit_for_bit() {
        for isa in Isa::available() {
            for (w, nfft) in [
                (4, 4),
                (6, 6),
                (10, 10),
                (9, 18),
                (200, 200),
                (201, 402),
                (9600, 9600),
            ] {
                let x: Vec<f64> = (0..w)
                    .map(|i| ((i * 7919 % 1013) as f64 - 500.0) * 1e-3 + (i as f64 * 0.37).sin())
                    .collect();
                let window: Vec<f64> = (0..w)
                    .map(|i| 0.5 + 0.5 * (i as f64 * 0.01).cos())
                    .collect();
                let mut buffers = FrameBuffers::default();
                rustfft_even(nfft).frame_power(isa, &x, &window, &mut buffers);
                let expected = realfft_powers(&x, &window, nfft);
                assert_eq!(buffers.power.len(), expected.len(), "{isa:?} N {nfft}");
                for (k, (a, b)) in buffers.power.iter().zip(&expected).enumerate() {
                    assert_eq!(
                        a.to_bits(),
                        b.to_bits(),
                        "{isa:?} N {nfft} bin {k}: {a} vs {b}"
                    );
                }
            }
        }
    }

    /// Even lengths whose half the prime-factor FFT takes (M = 15, 201 = 3 · 67, 819 at 8192
    /// Hz, 3277 = 29 · 113 at 32768 Hz), forced on whatever this CPU has: realfft's powers to
    /// 1e-12 of the largest, frames of N samples, odd-length ones and zero-padded ones.
    #[test]
    fn even_lengths_through_the_prime_factor_fft_give_realffts_powers() {
        for (w, nfft) in [
            (30usize, 30usize),
            (29, 30),
            (402, 402),
            (300, 402),
            (1638, 1638),
            (1637, 1638),
            (6554, 6554),
        ] {
            let x: Vec<f64> = (0..w)
                .map(|i| ((i * 7919 % 1013) as f64 - 500.0) * 1e-3 + (i as f64 * 0.37).sin())
                .collect();
            let window: Vec<f64> = (0..w)
                .map(|i| 0.5 - 0.5 * (i as f64 * 0.02).cos())
                .collect();
            let expected = realfft_powers(&x, &window, nfft);
            let scale = expected.iter().fold(0.0f64, |m, &p| m.max(p));
            let half = Arc::new(PrimeFactorFft::new(nfft / 2).expect("planned"));
            let twiddles = shared_half_twiddles(nfft);
            let forced = Transform::EvenPrimeFactor {
                tables: half.half_power_tables(&twiddles).map(Arc::new),
                half,
                twiddles,
            };
            for isa in Isa::available() {
                let mut buffers = FrameBuffers::default();
                forced.frame_power(isa, &x, &window, &mut buffers);
                assert_eq!(buffers.power.len(), expected.len(), "{isa:?} N {nfft}");
                for (k, (g, e)) in buffers.power.iter().zip(&expected).enumerate() {
                    assert!(
                        (g - e).abs() <= 1e-12 * scale,
                        "{isa:?} N {nfft} w {w} bin {k}: {g} vs {e}"
                    );
                }
            }
        }
    }

    /// A pair of frames gives each frame's own power spectrum, for odd lengths (one complex
    /// FFT for both: equal to rounding) and even ones (one after the other: the same bits).
    #[test]
    fn a_pair_gives_each_frames_own_powers() {
        for nfft in [201usize, 200] {
            let x: Vec<f64> = (0..2 * nfft)
                .map(|i| (i as f64 * 0.21).sin() + 0.1)
                .collect();
            let window = vec![1.0; nfft];
            let (a, b) = (&x[..nfft], &x[nfft / 2..nfft / 2 + nfft]);
            let transform = Transform::new(nfft);
            let mut buffers = FrameBuffers::default();
            transform.pair_powers(Isa::detect(), a, b, &window, &mut buffers);
            let (pa, pb) = (buffers.power.clone(), buffers.power_b.clone());
            for (frame, got) in [(a, &pa), (b, &pb)] {
                transform.frame_power(Isa::detect(), frame, &window, &mut buffers);
                assert_eq!(got.len(), buffers.power.len());
                let scale = buffers.power.iter().fold(0.0f64, |m, &p| m.max(p));
                for (g, e) in got.iter().zip(&buffers.power) {
                    assert!((g - e).abs() <= 1e-12 * scale, "N {nfft}: {g} vs {e}");
                    if nfft % 2 == 0 {
                        assert_eq!(g.to_bits(), e.to_bits());
                    }
                }
            }
        }
    }

    /// One thread's buffers serve transforms of any length and parity in turn (as a thread
    /// analysing channels of different settings does): each gives the powers it gives on
    /// fresh buffers. 200 → 201 → 200 once panicked in rustfft: the even length's input buffer
    /// still fitted, so its spectrum buffer, resized by the odd one, was not checked.
    #[test]
    fn shared_buffers_serve_every_length_in_turn() {
        // 819, 315, 63, 45, 3277 (29 · 113, with wide stages and their scratch) and the half of
        // 1638 take the prime-factor FFT on AVX-512 CPUs, whose padding positions are left as
        // they are: 63 (9 · 7) and 45 (9 · 5) both pad to 9 · 8 positions, and 45 has padding
        // where 63 leaves data.
        let lengths = [
            200usize, 201, 819, 200, 63, 45, 199, 9, 315, 819, 10, 402, 201, 1638, 200, 1638, 3277,
            819,
        ];
        let x: Vec<f64> = (0..3278).map(|i| (i as f64 * 0.13).cos() + 0.05).collect();
        let window = vec![1.0; 3278];
        let mut shared = FrameBuffers::default();
        for &n in &lengths {
            let transform = Transform::new(n);
            transform.frame_power(Isa::detect(), &x[..n], &window[..n], &mut shared);
            let mut fresh = FrameBuffers::default();
            transform.frame_power(Isa::detect(), &x[..n], &window[..n], &mut fresh);
            assert_eq!(shared.power, fresh.power, "N {n} after other lengths");
            assert_eq!(shared.power.len(), n / 2 + 1, "N {n}");
            if transform.pairs_frames() {
                let (a, b) = (&x[..n], &x[1..n + 1]);
                transform.pair_powers(Isa::detect(), a, b, &window[..n], &mut shared);
                transform.pair_powers(Isa::detect(), a, b, &window[..n], &mut fresh);
                assert_eq!(
                    (&shared.power, &shared.power_b),
                    (&fresh.power, &fresh.power_b)
                );
            }
        }
    }

    /// Frames of 819 samples (9 · 7 · 13, a 200 ms window at 4096 Hz) through the prime-factor
    /// FFT, forced on whatever this CPU has, alone and in pairs, zero-padded or not: realfft's
    /// powers to 1e-12 of the largest; with its lone frames through realfft and its pairs
    /// through rustfft the same plan must agree too (the transform the CPU picks).
    #[test]
    fn prime_factor_frames_give_realffts_powers() {
        for (w, nfft) in [(819usize, 819usize), (273, 819), (63, 63)] {
            let x: Vec<f64> = (0..w + 5)
                .map(|i| ((i * 7919 % 1013) as f64 - 500.0) * 1e-3 + (i as f64 * 0.37).sin())
                .collect();
            let window: Vec<f64> = (0..w)
                .map(|i| 0.5 - 0.5 * (i as f64 * 0.02).cos())
                .collect();
            let (a, b) = (&x[..w], &x[5..w + 5]);
            let oracle = |frame: &[f64]| realfft_powers(frame, &window, nfft);
            let forced = Transform::PrimeFactor(Arc::new(PrimeFactorFft::new(nfft).unwrap()));
            for transform in [forced, Transform::new(nfft)] {
                for isa in Isa::available() {
                    let mut buffers = FrameBuffers::default();
                    transform.pair_powers(isa, a, b, &window, &mut buffers);
                    let (pa, pb) = (buffers.power.clone(), buffers.power_b.clone());
                    transform.frame_power(isa, b, &window, &mut buffers);
                    for (got, frame) in [(&pa, a), (&pb, b), (&buffers.power, b)] {
                        let expected = oracle(frame);
                        let scale = expected.iter().fold(0.0f64, |m, &p| m.max(p));
                        assert_eq!(got.len(), expected.len());
                        for (k, (g, e)) in got.iter().zip(&expected).enumerate() {
                            assert!(
                                (g - e).abs() <= 1e-12 * scale,
                                "{isa:?} N {nfft} w {w} bin {k}: {g} vs {e}"
                            );
                        }
                    }
                }
            }
        }
    }
}

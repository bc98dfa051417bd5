//! Decay estimation: one band's energy sequence → reverberation times and damping ratios.
//!
//! The estimator is online ([`schroeder::OnlineSchroeder`]): every frame costs O(1) work and the
//! memory is the frame sequence itself (a few floats per frame at the front end's frame rate).
//! A provisional estimate can be asked for at any time; the final one at the end of the decay.
//! Line fits on the Schroeder curve live in [`regression`], the damping conversions in
//! [`damping`], and the figures that describe one decay in [`estimate`].

pub mod damping;
pub mod estimate;
pub mod flags;
pub mod frequency;
pub mod leakage;
pub mod lundeby;
pub mod oracle;
pub mod quantization;
pub mod range;
pub mod regression;
pub mod restarts;
pub mod schroeder;
pub mod settings;
mod side_by_side;

pub use estimate::{DecayEstimate, Flag};
pub use frequency::FrequencyCoding;
pub use range::EvaluationRange;
pub use schroeder::OnlineSchroeder;

/// Consumes one band's energy sequence, frame by frame, and estimates its decay.
///
/// The seam between the front end's frames and the estimate: the pipeline drives one estimator
/// per band through this trait only ([`crate::pipeline::analyze_decay_with`] takes any). Two
/// implementations: [`OnlineSchroeder`] (O(1) per frame, compensated sums) and the plain offline
/// oracle [`oracle::BatchSchroeder`] that the tests hold it to.
pub trait DecayEstimator: Send {
    /// Adds the next frame: its band energy (≥ 0) and the frequency present in it (Hz, or NaN).
    fn push_frame(&mut self, energy: f64, frequency_hz: f64);

    /// Adds frames in order: frame k's energy and frequency are `energy[k]` and
    /// `frequency[k]`, the frequency coded by `coding` (a buffered bank's frames of one band).
    /// The same as one [`DecayEstimator::push_frame`] per frame with the frequency decoded; an
    /// estimator may keep the values coded and decode those it reads.
    fn push_frames(&mut self, energy: &[f64], frequency: &[f64], coding: FrequencyCoding) {
        for (&e, &f) in energy.iter().zip(frequency) {
            self.push_frame(e, coding.to_hz(f));
        }
    }

    /// Several bands' [`DecayEstimator::push_frames`] at once: `energy[j]` and `frequency[j]`
    /// to `estimators[j]`. The same as one call per band; an estimator may interleave the
    /// bands' work (their running sums are chains that a band alone waits on).
    fn push_frames_each(
        estimators: &mut [Self],
        energy: &[&[f64]],
        frequency: &[&[f64]],
        coding: FrequencyCoding,
    ) where
        Self: Sized,
    {
        for ((est, e), f) in estimators.iter_mut().zip(energy).zip(frequency) {
            est.push_frames(e, f, coding);
        }
    }

    /// The estimate from the frames seen so far (the Schroeder curve truncated at the last frame).
    fn provisional(&self) -> DecayEstimate;

    /// [`DecayEstimator::provisional`] of the estimators where `wanted`, `None` elsewhere; an
    /// estimator may interleave the bands' work, as in [`DecayEstimator::push_frames_each`].
    fn provisional_each(estimators: &[Self], wanted: &[bool]) -> Vec<Option<DecayEstimate>>
    where
        Self: Sized,
    {
        estimators
            .iter()
            .zip(wanted)
            .map(|(e, &w)| w.then(|| e.provisional()))
            .collect()
    }

    /// Number of frames consumed so far.
    fn frames(&self) -> usize;

    /// Forgets everything, ready for a new decay.
    fn reset(&mut self);

    /// Makes room for `frames` more frames at once (a buffered front end emits a whole decay):
    /// the history then grows once instead of by repeated doubling and copying.
    fn reserve_frames(&mut self, _frames: usize) {}

    /// Forgets everything and gives the frame history's memory back (a decay of a multichannel
    /// run is done: the next channel's decay reuses the memory instead of faulting in new
    /// pages).
    fn release(&mut self) {
        self.reset();
    }

    /// Total energy of the frames so far (the leakage test compares bands by it).
    fn total_energy(&self) -> f64;

    /// How far below the decay curve's start the fit reaches (the evaluation range's lower
    /// limit, dB > 0; 35 for T30): the leakage test holds what slower bands leak into this one
    /// to that depth. `None`: only total energies are compared.
    fn fit_depth_db(&self) -> Option<f64> {
        None
    }

    /// The frame energies the estimate uses: from the band's own start (its energy within
    /// [`schroeder::DECAY_START_LEVEL_DB`] of its peak) on. The test for merged hits reads it.
    fn decay_energies(&self) -> &[f64];
}

/// The largest of `values` and 0, NaN ignored: the value `fold(0.0, f64::max)` gives (the sign
/// of a zero aside), from [`max_ignoring_nan`]. A band's peak frame energy is looked up several
/// times per estimate, over 5000 frames per band at 2 ms frames.
pub(crate) fn peak_or_zero(values: &[f64]) -> f64 {
    let m = max_ignoring_nan(values);
    if m > 0.0 {
        m
    } else {
        0.0
    }
}

/// The largest of `values`, NaN ignored; −∞ when there is none. In independent lanes, each a
/// comparison (`f64::max` costs four more instructions per value for its NaN rule, and a single
/// fold waits on every comparison before the next); NaN compares false, so it never wins. The
/// lanes fill the CPU's widest vectors (generic code compiled to two-value SSE2 maxima was 2 %
/// of an octave-bank run). Which lane a value lands in changes nothing but the sign of a zero
/// maximum.
pub(crate) fn max_ignoring_nan(values: &[f64]) -> f64 {
    use crate::frontend::simd::Isa;
    match Isa::detect() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX-512F on this CPU.
        Isa::Avx512 => unsafe { max_avx512(values) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU.
        Isa::Avx2Fma => unsafe { max_avx2(values) },
        Isa::Generic => max_in_lanes::<8>(values),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn max_avx512(values: &[f64]) -> f64 {
    // Four registers of eight: the comparisons' latency hidden behind each other.
    max_in_lanes::<32>(values)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn max_avx2(values: &[f64]) -> f64 {
    max_in_lanes::<16>(values)
}

/// [`max_ignoring_nan`] with `LANES` running maxima.
#[inline(always)]
fn max_in_lanes<const LANES: usize>(values: &[f64]) -> f64 {
    let larger = |m: f64, v: f64| if v > m { v } else { m };
    let mut lanes = [f64::NEG_INFINITY; LANES];
    let chunks = values.chunks_exact(LANES);
    let rest = chunks.remainder();
    for chunk in chunks {
        for (m, &v) in lanes.iter_mut().zip(chunk) {
            *m = larger(*m, v);
        }
    }
    rest.iter()
        .chain(&lanes)
        .fold(f64::NEG_INFINITY, |m, &v| larger(m, v))
}

/// Division by a count, as a multiply where that gives the same bits: dividing by a power of
/// two is multiplying by its inverse (both round the same exact quotient). A division per value
/// was half the cost of turning frame sums into mean energies (one per band and 2 ms frame) and
/// of Lundeby's block means.
#[derive(Clone, Copy, Debug)]
pub(crate) enum CountDivisor {
    /// Multiply by this inverse of a power of two.
    Times(f64),
    /// Divide by the count.
    Over(f64),
}

impl CountDivisor {
    /// Division by `count`.
    pub(crate) fn new(count: usize) -> Self {
        if count.is_power_of_two() {
            CountDivisor::Times(1.0 / count as f64)
        } else {
            CountDivisor::Over(count as f64)
        }
    }

    /// `x / count`, bit for bit.
    #[inline(always)]
    pub(crate) fn divide(self, x: f64) -> f64 {
        match self {
            CountDivisor::Times(inverse) => x * inverse,
            CountDivisor::Over(count) => x / count,
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn peak_in_lanes_is_the_plain_fold() {
        let odd = [f64::NAN, -1.0, 0.0, 3.5, f64::INFINITY, 1e-300, 7.0];
        for n in 0..40 {
            for at in 0..n {
                let mut v: Vec<f64> = (0..n).map(|k| odd[(k * 5 + at) % odd.len()]).collect();
                v[at] = 1e3 * (at as f64 + 1.0);
                let plain = v.iter().cloned().fold(0.0, f64::max);
                assert_eq!(super::peak_or_zero(&v), plain, "{v:?}");
                let finite: Vec<f64> = v.iter().map(|x| x.min(1e9)).collect();
                let plain = finite.iter().cloned().fold(0.0, f64::max);
                assert_eq!(super::peak_or_zero(&finite), plain, "{finite:?}");
            }
        }
        assert_eq!(super::peak_or_zero(&[]), 0.0);
        assert_eq!(super::peak_or_zero(&[f64::NAN, -2.0]), 0.0);
        assert_eq!(super::max_ignoring_nan(&[]), f64::NEG_INFINITY);
        assert_eq!(super::max_ignoring_nan(&[f64::NAN; 11]), f64::NEG_INFINITY);
        assert_eq!(super::max_ignoring_nan(&[f64::NAN, -2.0, -3.0]), -2.0);
        // Every lane width (and the one this CPU dispatches to), 0–100 values, the maximum at
        // every position, against a fold of the non-NaN values.
        let widths: [fn(&[f64]) -> f64; 4] = [
            super::max_in_lanes::<8>,
            super::max_in_lanes::<16>,
            super::max_in_lanes::<32>,
            super::max_ignoring_nan,
        ];
        for n in 0..=100usize {
            for at in (0..n).step_by(7) {
                let mut v: Vec<f64> = (0..n)
                    .map(|k| odd[(k * 3 + n) % odd.len()].min(5.0) - 10.0)
                    .collect();
                v[at] = 2.0 + at as f64;
                let want = v
                    .iter()
                    .filter(|x| !x.is_nan())
                    .fold(f64::NEG_INFINITY, |m, &x| m.max(x));
                for (i, max) in widths.iter().enumerate() {
                    assert_eq!(max(&v), want, "width {i}, {n} values, max at {at}");
                }
            }
        }
    }
}

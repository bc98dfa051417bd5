//! Online backward-integrated Schroeder curve.
//!
//! EDC(t_k) = Σ_{m ≥ k} e_m. Frames arrive one by one and the total E_total is kept as they come
//! (in double-double form, value + Neumaier compensation); the curve itself is summed backwards
//! over the stored frame energies when it is asked for, which is exact to rounding deep into the
//! decay (a forward form E_total − S_{k−1} cancels catastrophically there: at −60 dB the result
//! is 10⁻⁶ E_total) and keeps 16 bytes per frame (energy and frequency) instead of 32 with
//! stored prefix sums: 100 000 bands of one decay fit in the memory budget.

use super::estimate::{estimate_from_coded_curve, DecayEstimate, EstimateSettings};
use super::{DecayEstimator, FrequencyCoding};

/// A band's decay starts where its energy first comes within this many dB of its peak: ISO
/// 3382-1's start of an impulse response, applied per band as pyrato's `time_shift` does. The
/// frames before it (a band filter ringing up, a window sliding in, a later band's share of the
/// first arrival) are kept but not fitted: a forward-filtered living-room RIR read its EDT at
/// 2 kHz 16 % short from the broadband onset.
pub const DECAY_START_LEVEL_DB: f64 = 20.0;

/// A compensated running sum (Neumaier): `hi + lo` is the sum to about twice f64 precision.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompensatedSum {
    /// Leading part of the sum.
    pub hi: f64,
    /// Rounding error accumulated so far.
    pub lo: f64,
}

impl CompensatedSum {
    /// Adds `x` to the sum.
    #[inline]
    pub fn add(&mut self, x: f64) {
        let t = self.hi + x;
        if self.hi.abs() >= x.abs() {
            self.lo += (self.hi - t) + x;
        } else {
            self.lo += (x - t) + self.hi;
        }
        self.hi = t;
    }

    /// The sum as one f64.
    #[inline]
    pub fn value(&self) -> f64 {
        self.hi + self.lo
    }

    /// `self − other` with the compensation terms kept apart until the end.
    #[inline]
    pub fn minus(&self, other: &CompensatedSum) -> f64 {
        (self.hi - other.hi) + (self.lo - other.lo)
    }
}

/// Online Schroeder integrator for one band of one channel.
///
/// `push_frame` is O(1); the memory is the frame sequence (energy and frequency per frame). The
/// curve (O(frames)), and estimates from it, are available at any time.
#[derive(Clone, Debug)]
pub struct OnlineSchroeder {
    frame_period_s: f64,
    f_center_hz: f64,
    settings: EstimateSettings,
    energies: Vec<f64>,
    /// Per frame, the frequency present, coded as `coding` says.
    frequencies: Vec<f64>,
    coding: FrequencyCoding,
    running: CompensatedSum,
    /// The band's share of the input's rounding noise per frame (0: none known).
    floor_energy: f64,
}

impl OnlineSchroeder {
    /// A new integrator for frames `frame_period_s` apart in a band centred at `f_center_hz`.
    pub fn new(frame_period_s: f64, f_center_hz: f64, settings: EstimateSettings) -> Self {
        OnlineSchroeder {
            frame_period_s,
            f_center_hz,
            settings,
            energies: Vec::new(),
            frequencies: Vec::new(),
            coding: FrequencyCoding::Hz,
            running: CompensatedSum::default(),
            floor_energy: 0.0,
        }
    }

    /// The same integrator, told the band's share of the input's rounding noise per frame
    /// ([`super::quantization::floor_energy`]): its estimates treat it as the noise floor where
    /// the record shows no higher one. It stays through resets.
    pub fn with_floor_energy(mut self, floor_energy: f64) -> Self {
        self.floor_energy = super::quantization::kept_floor(floor_energy);
        self
    }

    /// EDC at frame `k` (k < frames): Σ_{m ≥ k} e_m, summed backwards with compensation.
    pub fn edc_at(&self, k: usize) -> f64 {
        let mut acc = CompensatedSum::default();
        self.energies[k..].iter().rev().for_each(|&e| acc.add(e));
        acc.value()
    }

    /// The whole (unnormalised) energy decay curve so far, summed backwards with compensation.
    pub fn edc(&self) -> Vec<f64> {
        let mut edc = vec![0.0; self.energies.len()];
        let mut acc = CompensatedSum::default();
        for (k, &e) in self.energies.iter().enumerate().rev() {
            acc.add(e);
            edc[k] = acc.value();
        }
        edc
    }

    /// The frame energies so far.
    pub fn energies(&self) -> &[f64] {
        &self.energies
    }

    /// The per-frame dominant frequencies so far (Hz, NaN where unknown), decoded here if the
    /// front end handed them over coded.
    pub fn frequencies_hz(&self) -> std::borrow::Cow<'_, [f64]> {
        self.coding.decode(&self.frequencies)
    }

    /// Appends frames' kept energies (see `kept_energy`) and their frequencies, without the
    /// running sum; returns the index of the first frame appended.
    fn keep_frames(&mut self, energy: &[f64], frequency: &[f64], coding: FrequencyCoding) -> usize {
        // From an iterator of known length: a push per frame kept the length in memory, and
        // zeroing the room first wrote it twice (a buffered bank hands over 5000 frames per
        // band and decay at 2 ms frames).
        let n = energy.len().min(frequency.len());
        let start = self.energies.len();
        let energies = &mut self.energies;
        crate::frontend::simd::in_wide_vectors(|| {
            energies.extend(energy[..n].iter().map(|&x| kept_energy(x)))
        });
        self.store_frequencies(&frequency[..n], coding);
        start
    }

    /// Appends frames' frequencies: kept as coded (an estimate decodes only the frames it reads)
    /// unless the frames held are coded otherwise, then all in Hz.
    fn store_frequencies(&mut self, frequency: &[f64], coding: FrequencyCoding) {
        if self.frequencies.is_empty() {
            self.coding = coding;
        }
        if coding == self.coding {
            self.frequencies.extend_from_slice(frequency);
        } else {
            self.decode_frequencies();
            let from = self.frequencies.len();
            self.frequencies.extend_from_slice(frequency);
            coding.decode_in_place(&mut self.frequencies[from..]);
        }
    }

    /// Turns the frequencies held into Hz (before frames of another coding join them).
    fn decode_frequencies(&mut self) {
        self.coding.decode_in_place(&mut self.frequencies);
        self.coding = FrequencyCoding::Hz;
    }

    /// Time between frames in seconds.
    pub fn frame_period_s(&self) -> f64 {
        self.frame_period_s
    }

    /// The first frame of the decay proper: the first whose energy comes within
    /// [`DECAY_START_LEVEL_DB`] of the band's peak (0 for a band without energy).
    pub fn start_frame(&self) -> usize {
        decay_start_frame(&self.energies)
    }

    /// The estimate from the frames seen so far, from the band's own start on.
    pub fn estimate(&self) -> DecayEstimate {
        self.estimate_from_edc(&self.edc())
    }

    /// [`OnlineSchroeder::estimate`] with the curve given ([`OnlineSchroeder::edc`]'s).
    fn estimate_from_edc(&self, edc: &[f64]) -> DecayEstimate {
        let start = self.start_frame();
        estimate_from_coded_curve(
            &edc[start..],
            &self.energies[start..],
            &self.frequencies[start..],
            self.coding,
            self.frame_period_s,
            self.f_center_hz,
            &self.settings,
            self.floor_energy,
        )
    }
}

/// A frame energy as the history keeps it: non-finite and negative values count as 0.
#[inline]
fn kept_energy(energy: f64) -> f64 {
    if energy.is_finite() && energy > 0.0 {
        energy
    } else {
        0.0
    }
}

impl DecayEstimator for OnlineSchroeder {
    fn push_frame(&mut self, energy: f64, frequency_hz: f64) {
        if self.coding != FrequencyCoding::Hz {
            self.decode_frequencies();
        }
        let e = kept_energy(energy);
        self.energies.push(e);
        self.frequencies.push(frequency_hz);
        self.running.add(e);
    }

    fn push_frames(&mut self, energy: &[f64], frequency: &[f64], coding: FrequencyCoding) {
        let start = self.keep_frames(energy, frequency, coding);
        let mut running = self.running;
        self.energies[start..].iter().for_each(|&e| running.add(e));
        self.running = running;
    }

    fn push_frames_each(
        estimators: &mut [Self],
        energy: &[&[f64]],
        frequency: &[&[f64]],
        coding: FrequencyCoding,
    ) {
        let starts: Vec<usize> = estimators
            .iter_mut()
            .zip(energy.iter().zip(frequency))
            .map(|(est, (e, f))| est.keep_frames(e, f, coding))
            .collect();
        // The running sums four bands at a time.
        let mut sums: Vec<CompensatedSum> = estimators.iter().map(|e| e.running).collect();
        let kept: Vec<&[f64]> = estimators
            .iter()
            .zip(&starts)
            .map(|(e, &s)| &e.energies[s..])
            .collect();
        super::side_by_side::add_each(&mut sums, &kept);
        for (est, sum) in estimators.iter_mut().zip(sums) {
            est.running = sum;
        }
    }

    fn provisional_each(estimators: &[Self], wanted: &[bool]) -> Vec<Option<DecayEstimate>> {
        // The curves four bands at a time, then each band's estimate from its own.
        let chosen: Vec<&OnlineSchroeder> = estimators
            .iter()
            .zip(wanted)
            .filter_map(|(e, &w)| w.then_some(e))
            .collect();
        let energies: Vec<&[f64]> = chosen.iter().map(|e| e.energies.as_slice()).collect();
        let mut curves = super::side_by_side::backward_integrals(&energies).into_iter();
        estimators
            .iter()
            .zip(wanted)
            .map(|(e, &w)| {
                w.then(|| {
                    let edc = curves.next().expect("a curve per wanted band");
                    e.estimate_from_edc(&edc)
                })
            })
            .collect()
    }

    fn provisional(&self) -> DecayEstimate {
        self.estimate()
    }

    fn frames(&self) -> usize {
        self.energies.len()
    }

    fn reset(&mut self) {
        self.energies.clear();
        self.frequencies.clear();
        self.coding = FrequencyCoding::Hz;
        self.running = CompensatedSum::default();
    }

    fn reserve_frames(&mut self, frames: usize) {
        reserve_history(&mut self.energies, frames);
        reserve_history(&mut self.frequencies, frames);
    }

    fn release(&mut self) {
        give_back_history(std::mem::take(&mut self.energies));
        give_back_history(std::mem::take(&mut self.frequencies));
        self.coding = FrequencyCoding::Hz;
        self.running = CompensatedSum::default();
    }

    fn fit_depth_db(&self) -> Option<f64> {
        Some(-self.settings.range.limits_db().1)
    }

    fn total_energy(&self) -> f64 {
        self.running.value()
    }

    fn decay_energies(&self) -> &[f64] {
        &self.energies[self.start_frame()..]
    }
}

thread_local! {
    /// Frame histories that finished decays gave back on this thread, for the next decay of any
    /// channel: the memory stays with the process and its pages stay mapped (freeing them let
    /// the allocator return them, and a stream of short decays faulted them in again each time).
    static SPARE_HISTORIES: std::cell::RefCell<Vec<Vec<f64>>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// Histories one thread keeps for reuse at most (more are freed).
const SPARE_HISTORIES_MAX: usize = 1024;

/// Keeps `history`'s memory for the next decay on this thread ([`reserve_history`]).
pub(crate) fn give_back_history(mut history: Vec<f64>) {
    if history.capacity() == 0 {
        return;
    }
    history.clear();
    let _ = SPARE_HISTORIES.try_with(|spare| {
        if let Ok(mut spare) = spare.try_borrow_mut() {
            if spare.len() < SPARE_HISTORIES_MAX {
                spare.push(history);
            }
        }
    });
}

/// Makes room in `history` for `additional` more values, in memory given back earlier on this
/// thread where a spare is large enough (then the values held so far move into it and its own
/// memory goes to the pool); a history without memory takes the last spare in any case. Fresh
/// memory only when no spare fits: growing a short history into new memory while the pool held
/// large ones made each decay fault in new pages.
pub(crate) fn reserve_history(history: &mut Vec<f64>, additional: usize) {
    let need = history.len() + additional;
    if history.capacity() >= need && history.capacity() > 0 {
        return;
    }
    let spare = SPARE_HISTORIES
        .try_with(|spare| {
            let mut spare = spare.try_borrow_mut().ok()?;
            let fit = spare.iter().rposition(|s| s.capacity() >= need);
            match fit {
                Some(i) => Some(spare.swap_remove(i)),
                None if history.capacity() == 0 => spare.pop(),
                None => None,
            }
        })
        .ok()
        .flatten();
    if let Some(mut spare) = spare {
        spare.extend_from_slice(history);
        give_back_history(std::mem::replace(history, spare));
    }
    history.reserve(additional);
}

/// A per-decay curve in memory from this thread's pool of histories ([`reserve_history`]),
/// given back when dropped. A fresh vector per band and decay came from `mmap` once it was
/// above the allocator's threshold (a Goyder bank's 0.25 ms frames: 320 kB per 10 s band) and
/// faulted its pages in again for every decay.
pub(crate) struct PooledCurve(Vec<f64>);

impl PooledCurve {
    /// `len` zeros.
    pub(crate) fn zeros(len: usize) -> Self {
        let mut v = Vec::new();
        reserve_history(&mut v, len);
        v.resize(len, 0.0);
        PooledCurve(v)
    }

    /// Empty, with room for `capacity` values.
    pub(crate) fn with_capacity(capacity: usize) -> Self {
        let mut v = Vec::new();
        reserve_history(&mut v, capacity);
        PooledCurve(v)
    }
}

impl std::ops::Deref for PooledCurve {
    type Target = Vec<f64>;
    fn deref(&self) -> &Vec<f64> {
        &self.0
    }
}

impl std::ops::DerefMut for PooledCurve {
    fn deref_mut(&mut self) -> &mut Vec<f64> {
        &mut self.0
    }
}

impl Drop for PooledCurve {
    fn drop(&mut self) {
        give_back_history(std::mem::take(&mut self.0));
    }
}

/// The first frame of a band's decay proper: the first whose energy comes within
/// [`DECAY_START_LEVEL_DB`] of the band's peak (0 for a band without energy).
pub fn decay_start_frame(energies: &[f64]) -> usize {
    let peak = super::peak_or_zero(energies);
    let level = peak * 10f64.powf(-DECAY_START_LEVEL_DB / 10.0);
    if peak > 0.0 {
        energies.iter().position(|&e| e >= level).unwrap_or(0)
    } else {
        0
    }
}

/// The offline oracle: `EDC[k] = Σ_{m ≥ k} e[m]`, summed backwards from the end as written in the
/// definition (pyrato's `flip(cumsum(flip(e)))`). Slow to update, obviously correct.
pub fn backward_integrate(energies: &[f64]) -> Vec<f64> {
    let mut edc = vec![0.0; energies.len()];
    let mut acc = 0.0;
    for k in (0..energies.len()).rev() {
        acc += energies[k];
        edc[k] = acc;
    }
    edc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compensated_sum_keeps_small_terms() {
        let mut s = CompensatedSum::default();
        s.add(1.0);
        for _ in 0..10 {
            s.add(1e-17);
        }
        assert!((s.minus(&CompensatedSum { hi: 1.0, lo: 0.0 }) - 1e-16).abs() < 1e-30);
    }

    #[test]
    fn bands_side_by_side_are_each_band_alone() {
        // Bands of different lengths (one empty), pushed and estimated together or alone.
        let fs = 4096.0;
        let coding = FrequencyCoding::Cosine { sample_rate_hz: fs };
        let bands: Vec<(Vec<f64>, Vec<f64>)> = (0..6)
            .map(|b| {
                let n = [700, 650, 0, 1200, 90, 700][b];
                let rate = 0.02 * (b + 1) as f64;
                let e = (0..n)
                    .map(|k| (-(k as f64) * rate).exp() + 1e-7 * ((k * 7 + b) % 5) as f64)
                    .collect();
                let c = (0..n)
                    .map(|k| (0.3 + 0.001 * (k % 9) as f64).cos())
                    .collect();
                (e, c)
            })
            .collect();
        let settings = EstimateSettings::default();
        let fresh: Vec<OnlineSchroeder> = (0..6)
            .map(|b| OnlineSchroeder::new(0.002, 125.0 * (1 << b) as f64, settings))
            .collect();
        let (mut together, mut alone) = (fresh.clone(), fresh);
        // Some frames already held.
        for est in together.iter_mut().chain(alone.iter_mut()) {
            est.push_frame(0.25, 90.0);
        }
        let energy: Vec<&[f64]> = bands.iter().map(|b| b.0.as_slice()).collect();
        let cosines: Vec<&[f64]> = bands.iter().map(|b| b.1.as_slice()).collect();
        OnlineSchroeder::push_frames_each(&mut together, &energy, &cosines, coding);
        for (est, (e, c)) in alone.iter_mut().zip(&bands) {
            est.push_frames(e, c, coding);
        }
        let wanted = [true, true, true, false, true, true];
        let each = OnlineSchroeder::provisional_each(&together, &wanted);
        for (b, (t, a)) in together.iter().zip(&alone).enumerate() {
            assert_eq!(
                t.total_energy().to_bits(),
                a.total_energy().to_bits(),
                "band {b}"
            );
            assert_eq!(t.energies(), a.energies(), "band {b}");
            match &each[b] {
                Some(est) => assert_eq!(format!("{est:?}"), format!("{:?}", a.provisional())),
                None => assert!(!wanted[b]),
            }
        }
        assert!(each[0].as_ref().is_some_and(|e| e.t60_s.is_some()));
    }

    #[test]
    fn frames_in_bulk_are_pushed_as_one_by_one() {
        // Odd values (negative, NaN, infinite, zero) among them.
        let mut energy: Vec<f64> = (0..500)
            .map(|k| (-(k as f64) * 0.01).exp() * (1.0 + 0.3 * (k as f64 * 0.7).sin()))
            .collect();
        energy[10] = -1.0;
        energy[31] = f64::INFINITY;
        energy[44] = 0.0;
        energy[97] = f64::NAN;
        let freqs: Vec<f64> = (0..energy.len())
            .map(|i| {
                if i % 50 == 3 {
                    f64::NAN
                } else {
                    100.0 + i as f64
                }
            })
            .collect();
        // The same frequencies as cosines of 2πf/fs.
        let fs = 4096.0;
        let cosines: Vec<f64> = freqs
            .iter()
            .map(|f| (2.0 * std::f64::consts::PI * f / fs).cos())
            .collect();
        let cosine = FrequencyCoding::Cosine { sample_rate_hz: fs };
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for count in [0, 1, 2, 499, 500] {
            for coded in [false, true] {
                let settings = EstimateSettings::default();
                let mut one_by_one = OnlineSchroeder::new(0.002, 100.0, settings);
                let mut bulk = one_by_one.clone();
                // A frame before the bulk (held in Hz), or none (the bulk's coding is kept).
                if !coded {
                    one_by_one.push_frame(0.5, 80.0);
                    bulk.push_frame(0.5, 80.0);
                }
                let (values, coding) = if coded {
                    (&cosines, cosine)
                } else {
                    (&freqs, FrequencyCoding::Hz)
                };
                for k in 0..count {
                    one_by_one.push_frame(energy[k], coding.to_hz(values[k]));
                }
                bulk.push_frames(&energy[..count], &values[..count], coding);
                // Coded frames after Hz ones and the other way round.
                one_by_one.push_frames(&energy[..3], &values[..3], coding);
                bulk.push_frames(&energy[..3], &values[..3], coding);
                for (e, v) in [(0.25, 300.0), (0.125, 301.0)] {
                    one_by_one.push_frame(e, v);
                }
                bulk.push_frame(0.25, 300.0);
                bulk.push_frames(&[0.125], &[301.0], FrequencyCoding::Hz);
                let what = format!("{count} frames, coded {coded}");
                assert_eq!(one_by_one.energies(), bulk.energies(), "{what}");
                assert_eq!(
                    bits(&one_by_one.frequencies_hz()),
                    bits(&bulk.frequencies_hz()),
                    "{what}"
                );
                assert_eq!(
                    one_by_one.total_energy().to_bits(),
                    bulk.total_energy().to_bits()
                );
                assert_eq!(
                    format!("{:?}", one_by_one.estimate()),
                    format!("{:?}", bulk.estimate()),
                    "{what}"
                );
            }
        }
        // Kept coded until read: an estimate from cosines is the one from their frequencies.
        let mut hz = OnlineSchroeder::new(0.002, 100.0, EstimateSettings::default());
        let mut coded = hz.clone();
        let decay: Vec<f64> = (0..500).map(|k| (-(k as f64) * 0.02).exp()).collect();
        let decoded: Vec<f64> = cosines.iter().map(|&c| cosine.to_hz(c)).collect();
        hz.push_frames(&decay, &decoded, FrequencyCoding::Hz);
        coded.push_frames(&decay, &cosines, cosine);
        assert_eq!(coded.coding, cosine);
        let (a, b) = (hz.estimate(), coded.estimate());
        assert!(a.f_dominant_hz.is_some());
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }
}

//! One decay's bands together: the per-band estimators with the end-of-decay test, and the tests
//! across bands (resolution, leakage, restarts) that decide which bands give a number.

use crate::decay::estimate::EstimateSettings;
use crate::decay::leakage::{flag_leakage, BandLevel, LeakageModel};
use crate::decay::restarts::first_restart;
use crate::decay::{DecayEstimate, DecayEstimator, Flag, FrequencyCoding, OnlineSchroeder};
use crate::frontend::{Band, Frame, FrontEnd};

/// Estimates every band of one decay, given from its onset, in one go (no threads), with the
/// online Schroeder estimator.
pub fn analyze_decay(
    samples: &[f64],
    front_end: &mut dyn FrontEnd,
    settings: &EstimateSettings,
) -> Vec<DecayEstimate> {
    analyze_decay_with(samples, front_end, |band, frame_period_s| {
        OnlineSchroeder::new(frame_period_s, band.center_hz, *settings)
    })
}

/// [`analyze_decay`] with any [`DecayEstimator`]: `new_estimator(band, frame_period_s)` makes
/// one per band. The cross-band tests (resolution, leakage, merged hits) are the same.
pub fn analyze_decay_with<E: DecayEstimator>(
    samples: &[f64],
    front_end: &mut dyn FrontEnd,
    new_estimator: impl Fn(&Band, f64) -> E,
) -> Vec<DecayEstimate> {
    front_end.reset();
    let period = front_end.resolution().frame_period_s;
    let estimators = front_end
        .bands()
        .iter()
        .map(|b| new_estimator(b, period))
        .collect();
    let mut trackers = BandTrackers::new(estimators, f64::INFINITY, None);
    front_end.process(samples, &mut |f: Frame<'_>| trackers.push(f));
    front_end.finish(&mut |f: Frame<'_>| trackers.push(f));
    let cut_short = front_end.decay_cut_short();
    let mut estimates: Vec<DecayEstimate> = trackers
        .estimators
        .iter()
        .map(|e| e.provisional())
        .collect();
    judge_bands(front_end, &trackers.estimators, &mut estimates);
    if cut_short {
        estimates
            .iter_mut()
            .for_each(|e| e.flags.push(Flag::DecayTooLong));
    }
    estimates
}

/// A front end as the leakage test's model of its bands.
struct FrontEndLeakage<'a>(&'a dyn FrontEnd);

impl LeakageModel for FrontEndLeakage<'_> {
    fn mode_gain(&self, b: usize, f_hz: f64, sigma_per_s: f64) -> f64 {
        self.0.mode_gain(b, f_hz, sigma_per_s)
    }
    fn mode_gain_bound(&self, b: usize, f_hz: f64, sigma_per_s: f64) -> f64 {
        self.0.mode_gain_bound(b, f_hz, sigma_per_s)
    }
    fn flat_gain(&self, b: usize, lo_hz: f64, hi_hz: f64) -> f64 {
        self.0.flat_gain(b, lo_hz, hi_hz)
    }
    fn tolerance_hz(&self) -> f64 {
        self.0.frequency_tolerance_hz()
    }
}

/// The tests across the bands of one decay: a band narrower than the front end resolves gives
/// no number ([`Flag::BelowResolution`]), nor does a decay as fast as the band filter's own
/// ringing ([`Flag::FilterLimited`]), nor a band whose decay is another band's
/// ([`Flag::Leakage`], see [`crate::decay::leakage`]) or holds a new hit ([`Flag::MergedHits`]).
pub(super) fn judge_bands<E: DecayEstimator>(
    front_end: &dyn FrontEnd,
    estimators: &[E],
    estimates: &mut [DecayEstimate],
) {
    let resolution = front_end.resolution();
    let resolution_hz = resolution.frequency_resolution_hz;
    let rise_frames = (resolution.time_resolution_s / resolution.frame_period_s).ceil() as usize;
    let levels: Vec<BandLevel> = front_end
        .bands()
        .iter()
        .zip(estimators)
        .map(|(b, e)| BandLevel {
            lo_hz: b.lo_hz,
            hi_hz: b.hi_hz,
            center_hz: b.center_hz,
            energy: e.total_energy(),
            fit_depth_db: e.fit_depth_db(),
        })
        .collect();
    // Decided on the decay times as fitted: a band whose decay the leakage test withholds may
    // be filter-limited too (an empty band's onset ringing under a slower mode's skirt), and
    // says so.
    let filter_limited: Vec<bool> = (estimates.iter().enumerate())
        .map(|(b, est)| {
            est.t60_s
                .is_some_and(|t60| t60 < front_end.shortest_t60_s(b))
        })
        .collect();
    flag_leakage(estimates, &levels, &FrontEndLeakage(front_end));
    for (b, (est, band)) in estimates.iter_mut().zip(front_end.bands()).enumerate() {
        if band.width_hz() < resolution_hz * (1.0 - 1e-9) && !est.has(Flag::NoEnergy) {
            est.withhold(Flag::BelowResolution);
        }
        if filter_limited[b] {
            est.withhold(Flag::FilterLimited);
        }
    }
    for (est, e) in estimates.iter_mut().zip(estimators) {
        if first_restart(e.decay_energies(), rise_frames).is_some() {
            est.withhold(Flag::MergedHits);
        }
    }
}

/// When a decay may end on its noise floor ([`crate::pipeline::Segmentation::floor_min_s`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct FloorEnd {
    /// Frames a decay holds at least before it may end on its floor.
    pub(super) min_frames: usize,
    /// Energy ratio (≤ 1) that the last quarter must reach against the one before.
    pub(super) flat_factor: f64,
}

impl FloorEnd {
    /// The floor test for frames of `frame_period_s`; `None` when `floor_min_s` is infinite.
    pub(super) fn new(floor_min_s: f64, floor_flat_db: f64, frame_period_s: f64) -> Option<Self> {
        let frames = floor_min_s / frame_period_s;
        (frames.is_finite() && frame_period_s > 0.0).then(|| FloorEnd {
            min_frames: (frames.ceil() as usize).max(8),
            flat_factor: 10f64.powf(-floor_flat_db / 10.0),
        })
    }
}

/// Per-band estimators plus the end-of-decay tests.
pub(super) struct BandTrackers<E: DecayEstimator = OnlineSchroeder> {
    pub(super) estimators: Vec<E>,
    peak: Vec<f64>,
    end_factor: f64,
    floor: Option<FloorEnd>,
    /// Per band, the running sum of its frame energies (`[0]` = 0; empty, without memory,
    /// between decays): quarter means in O(1).
    cumulative: Vec<Vec<f64>>,
    frames: usize,
    pub(super) ended: bool,
}

impl<E: DecayEstimator> BandTrackers<E> {
    /// Trackers over one estimator per band; a decay ends when every band fell `end_drop_db`,
    /// or (with `floor`) has sat on its floor for the last half of a decay old enough.
    pub(super) fn new(estimators: Vec<E>, end_drop_db: f64, floor: Option<FloorEnd>) -> Self {
        BandTrackers {
            peak: vec![0.0; estimators.len()],
            cumulative: vec![Vec::new(); if floor.is_some() { estimators.len() } else { 0 }],
            estimators,
            end_factor: 10f64.powf(-end_drop_db / 10.0),
            floor,
            frames: 0,
            ended: false,
        }
    }

    /// Makes room for `frames` more frames in every band's history.
    pub(super) fn reserve(&mut self, frames: usize) {
        self.estimators
            .iter_mut()
            .for_each(|e| e.reserve_frames(frames));
        self.cumulative
            .iter_mut()
            .for_each(|c| crate::decay::schroeder::reserve_history(c, frames));
    }

    /// Empties a running sum to its leading 0, in memory given back earlier on this thread if
    /// it has none of its own (the histories' pool: taking fresh memory for the sums while
    /// giving theirs to the pool made every decay fault in new pages).
    fn restart_sum(c: &mut Vec<f64>) {
        c.clear();
        crate::decay::schroeder::reserve_history(c, 0);
        c.push(0.0);
    }

    /// Adds one frame to every band's running sum; a band no longer `active` (buffered banks:
    /// past its own end) repeats its last frame, which leaves the floor test neutral.
    fn add_to_sums(&mut self, energy: &[f64], active: impl Fn(usize) -> bool) {
        for (b, (c, &e)) in self.cumulative.iter_mut().zip(energy).enumerate() {
            if c.is_empty() {
                Self::restart_sum(c);
            }
            let frame = [e];
            super::end_scan::extend_sum(c, if active(b) { &frame } else { &[] }, 1);
        }
    }

    /// Like [`BandTrackers::reset`], and gives the histories' memory back to this thread: a long
    /// decay's frames are megabytes per channel, reused by the next decay of any channel.
    pub(super) fn release(&mut self) {
        self.reset();
        self.estimators.iter_mut().for_each(|e| e.release());
        for c in &mut self.cumulative {
            // Empty, without memory, until the next decay's reset takes some from the pool.
            crate::decay::schroeder::give_back_history(std::mem::take(c));
        }
    }

    pub(super) fn reset(&mut self) {
        self.estimators.iter_mut().for_each(|e| {
            e.reset();
            // A released history takes memory given back earlier on this thread.
            e.reserve_frames(0);
        });
        self.peak.iter_mut().for_each(|p| *p = 0.0);
        self.cumulative.iter_mut().for_each(Self::restart_sum);
        self.frames = 0;
        self.ended = false;
    }

    /// A whole decay's frames ([`crate::frontend::FrameSink::frames`]), the same as one
    /// [`BandTrackers::push`] per frame: first the end tests, frame by frame, to find where the
    /// decay ends; then each band's estimator takes its frames up to there in one run (a call
    /// per frame and band, across all bands, was a fifth of a buffered bank's run at 2 ms
    /// frames).
    pub(super) fn push_all(
        &mut self,
        energy: &[f64],
        frequency: &[f64],
        coding: FrequencyCoding,
        band_frames: &[usize],
    ) {
        let nb = band_frames.len();
        if nb == 0 || self.ended {
            return;
        }
        debug_assert_eq!(nb, self.estimators.len());
        let n_frames = energy.len() / nb;
        // Band by band, over every frame: which frames are low in every active band (against
        // the band's running peak), and the running sums (cut back to the frames taken). Frame
        // by frame across the bands, the peaks and sums went through memory at every step.
        let mut all_low = vec![true; n_frames];
        let mut peaks = self.peak.clone();
        let band = |b: usize| &energy[b * n_frames..b * n_frames + band_frames[b].min(n_frames)];
        for (b, peak) in peaks.iter_mut().enumerate() {
            *peak = super::end_scan::mark_low(&mut all_low, band(b), *peak, self.end_factor);
        }
        let mut first_entry = vec![0; self.cumulative.len()];
        for (c, first) in self.cumulative.iter_mut().zip(&mut first_entry) {
            if c.is_empty() {
                Self::restart_sum(c);
            }
            *first = c.len();
        }
        let actives: Vec<&[f64]> = (0..self.cumulative.len()).map(band).collect();
        super::end_scan::extend_sums(&mut self.cumulative, &actives, n_frames);
        // Frame by frame: where the decay ends.
        let mut taken = n_frames;
        for (k, &low) in all_low.iter().enumerate() {
            self.frames += 1;
            self.ended = (low && self.end_factor > 0.0) || self.on_floor();
            if self.ended {
                taken = k + 1;
                break;
            }
        }
        for (c, first) in self.cumulative.iter_mut().zip(first_entry) {
            c.truncate(first + taken);
        }
        // The peaks as far as the frames taken.
        if taken == n_frames {
            self.peak = peaks;
        } else {
            for (b, peak) in self.peak.iter_mut().enumerate() {
                let at = b * n_frames;
                let count = taken.min(band_frames[b]);
                *peak = energy[at..at + count].iter().fold(*peak, |p, &e| p.max(e));
            }
        }
        let (energies, frequencies): (Vec<&[f64]>, Vec<&[f64]>) = band_frames
            .iter()
            .enumerate()
            .map(|(b, &ends)| {
                let (at, count) = (b * n_frames, taken.min(ends));
                (&energy[at..at + count], &frequency[at..at + count])
            })
            .unzip();
        E::push_frames_each(&mut self.estimators, &energies, &frequencies, coding);
    }

    pub(super) fn push(&mut self, frame: Frame<'_>) {
        if self.ended {
            return;
        }
        let mut all_low = true;
        for (k, est) in self.estimators.iter_mut().enumerate() {
            if frame.active.is_some_and(|a| !a[k]) {
                continue;
            }
            let e = frame.energy[k];
            est.push_frame(e, frame.frequency_hz[k]);
            self.peak[k] = self.peak[k].max(e);
            all_low &= e <= self.peak[k] * self.end_factor;
        }
        self.frames += 1;
        self.add_to_sums(frame.energy, |b| frame.active.is_none_or(|a| a[b]));
        self.ended = (all_low && self.end_factor > 0.0) || self.on_floor();
    }

    /// True when the decay is old enough and every band's last quarter is not lower than the
    /// quarter before by more than the floor's flatness (its last half is a floor).
    fn on_floor(&self) -> bool {
        let Some(floor) = self.floor else {
            return false;
        };
        let n = self.frames;
        if n < floor.min_frames {
            return false;
        }
        let q = n / 4;
        self.cumulative.iter().all(|c| {
            let (a, b, z) = (c[n - 2 * q], c[n - q], c[n]);
            z - b >= (b - a) * floor.flat_factor
        })
    }
}

/// The trackers take a front end's frames directly, and make room when told how many come.
impl<E: DecayEstimator> crate::frontend::FrameSink for BandTrackers<E> {
    fn frame(&mut self, frame: Frame<'_>) {
        self.push(frame);
    }

    fn frames(
        &mut self,
        energy: &[f64],
        frequency: &[f64],
        coding: FrequencyCoding,
        band_frames: &[usize],
    ) {
        self.push_all(energy, frequency, coding, band_frames);
    }

    fn expect_frames(&mut self, frames: usize) {
        self.reserve(frames);
    }
}

/// [`BandTrackers`] as a sink that adds the time spent in them to a clock (profiled runs).
pub(super) struct TimedTrackers<'a> {
    pub(super) trackers: &'a mut BandTrackers,
    pub(super) seconds: &'a mut f64,
}

impl crate::frontend::FrameSink for TimedTrackers<'_> {
    fn frame(&mut self, frame: Frame<'_>) {
        let t0 = std::time::Instant::now();
        self.trackers.push(frame);
        *self.seconds += t0.elapsed().as_secs_f64();
    }

    fn expect_frames(&mut self, frames: usize) {
        self.trackers.reserve(frames);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frontend::FrameSink;

    /// Bands of the trackers under test: a group of four side by side and two more.
    const NB: usize = 6;

    fn trackers(end_drop_db: f64, floor: Option<FloorEnd>) -> BandTrackers {
        let settings = EstimateSettings::default();
        BandTrackers::new(
            (0..NB)
                .map(|b| OnlineSchroeder::new(0.002, 100.0 * (b + 1) as f64, settings))
                .collect(),
            end_drop_db,
            floor,
        )
    }

    /// Everything the trackers hold, as bits.
    fn state(t: &BandTrackers) -> Vec<u64> {
        let mut out = vec![t.frames as u64, t.ended as u64];
        for (e, p) in t.estimators.iter().zip(&t.peak) {
            out.push(p.to_bits());
            out.push(e.total_energy().to_bits());
            out.extend(e.decay_energies().iter().map(|v| v.to_bits()));
            out.extend(e.frequencies_hz().iter().map(|v| v.to_bits()));
        }
        for c in &t.cumulative {
            out.extend(c.iter().map(|v| v.to_bits()));
        }
        out
    }

    /// The bulk path against one push per frame (the default of `FrameSink::frames`, which
    /// also reads the frames band by band): decays
    /// that end by their drop, on their floor or not at all, bands that stop early, NaN and
    /// negative energies, and trackers that already hold frames.
    #[test]
    fn a_whole_decay_at_once_equals_its_frames_one_by_one() {
        let n = 1000;
        let mut energy = Vec::new();
        let mut freq = Vec::new();
        for k in 0..n {
            for b in 0..NB {
                let decay = (-(k as f64) * 0.05 * (b + 1) as f64).exp();
                let noise = 1e-6 * (1.0 + ((k * 31 + b * 7) % 13) as f64);
                // A NaN and a negative energy late in the bands that stop early (a NaN in
                // the running sums would keep the floor test from ever passing).
                energy.push(match (k, b) {
                    (200, 1) => f64::NAN,
                    (80, 2) => -1.0,
                    _ => decay + noise,
                });
                freq.push(100.0 * (b + 1) as f64 + (k % 5) as f64);
            }
        }
        let floors = [None, FloorEnd::new(0.3, 3.0, 0.002)];
        let (mut cases, mut ended_early) = (0, 0);
        for (end_drop_db, floor) in [
            (f64::INFINITY, floors[0]),
            (30.0, floors[0]),
            (f64::INFINITY, floors[1]),
            (200.0, floors[1]),
        ] {
            for band_frames in [
                [n, n, n, n, n, n],
                [n, 150, 60, n, 700, 999],
                [n, 250, 90, 400, n, 10],
                [0, n, 3, n, 1, n],
            ] {
                for (already, coding) in [
                    (0usize, FrequencyCoding::Hz),
                    (5, FrequencyCoding::Hz),
                    (
                        0,
                        FrequencyCoding::Cosine {
                            sample_rate_hz: 4096.0,
                        },
                    ),
                    (
                        5,
                        FrequencyCoding::Cosine {
                            sample_rate_hz: 4096.0,
                        },
                    ),
                ] {
                    let (mut bulk, mut single) =
                        (trackers(end_drop_db, floor), trackers(end_drop_db, floor));
                    // Some frames pushed one by one before the bulk.
                    for k in 0..already {
                        let f = Frame {
                            energy: &energy[NB * k..NB * (k + 1)],
                            frequency_hz: &freq[NB * k..NB * (k + 1)],
                            active: None,
                        };
                        bulk.push(f);
                        single.push(Frame { ..f });
                    }
                    // The rest, band by band (the layout of `FrameSink::frames`).
                    let band_major = |v: &[f64]| -> Vec<f64> {
                        (0..NB)
                            .flat_map(|b| (already..n).map(move |k| v[NB * k + b]))
                            .collect()
                    };
                    // The bulk's frequencies coded as a buffered bank may hand them over.
                    let coded: Vec<f64> = match coding {
                        FrequencyCoding::Hz => band_major(&freq),
                        FrequencyCoding::Cosine { sample_rate_hz } => band_major(&freq)
                            .iter()
                            .map(|f| (2.0 * std::f64::consts::PI * f / sample_rate_hz).cos())
                            .collect(),
                    };
                    let (e, f) = (&band_major(&energy), &coded);
                    let ends: Vec<usize> = band_frames
                        .iter()
                        .map(|&x: &usize| x.saturating_sub(already))
                        .collect();
                    FrameSink::frames(&mut bulk, e, f, coding, &ends);
                    // The trait's default: one frame at a time.
                    let mut one_by_one = |frame: Frame<'_>| single.push(frame);
                    FrameSink::frames(&mut one_by_one, e, f, coding, &ends);
                    assert_eq!(
                        state(&bulk),
                        state(&single),
                        "drop {end_drop_db} floor {:?} bands {band_frames:?} after {already} \
                         {coding:?}",
                        floor.is_some()
                    );
                    cases += 1;
                    ended_early += (bulk.ended && bulk.frames < n) as usize;
                }
            }
        }
        // Both ends occur: by the drop, and on the floor.
        assert!(ended_early >= 8, "{ended_early} of {cases} ended early");
    }
}

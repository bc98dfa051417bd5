//! One decay's bands together: the per-band estimators with the end-of-decay test, and the tests
//! across bands (resolution, leakage, restarts) that decide which bands give a number.

use crate::decay::estimate::EstimateSettings;
use crate::decay::leakage::{flag_leakage, BandLevel, LeakageModel};
use crate::decay::restarts::first_restart;
use crate::decay::{DecayEstimate, DecayEstimator, Flag, OnlineSchroeder};
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
    let mut trackers = BandTrackers::new(estimators, f64::INFINITY);
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
    fn flat_gain(&self, b: usize, lo_hz: f64, hi_hz: f64) -> f64 {
        self.0.flat_gain(b, lo_hz, hi_hz)
    }
    fn tolerance_hz(&self) -> f64 {
        self.0.frequency_tolerance_hz()
    }
}

/// The tests across the bands of one decay: a band narrower than the front end resolves gives
/// no number ([`Flag::BelowResolution`]), nor does a band whose decay is another band's
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
        })
        .collect();
    flag_leakage(estimates, &levels, &FrontEndLeakage(front_end));
    for (est, band) in estimates.iter_mut().zip(front_end.bands()) {
        if band.width_hz() < resolution_hz * (1.0 - 1e-9) && !est.has(Flag::NoEnergy) {
            est.withhold(Flag::BelowResolution);
        }
    }
    for (est, e) in estimates.iter_mut().zip(estimators) {
        if first_restart(e.decay_energies(), rise_frames).is_some() {
            est.withhold(Flag::MergedHits);
        }
    }
}

/// Per-band estimators plus the end-of-decay test.
pub(super) struct BandTrackers<E: DecayEstimator = OnlineSchroeder> {
    pub(super) estimators: Vec<E>,
    peak: Vec<f64>,
    end_factor: f64,
    pub(super) ended: bool,
}

impl<E: DecayEstimator> BandTrackers<E> {
    /// Trackers over one estimator per band; a decay ends when every band fell `end_drop_db`.
    pub(super) fn new(estimators: Vec<E>, end_drop_db: f64) -> Self {
        BandTrackers {
            peak: vec![0.0; estimators.len()],
            estimators,
            end_factor: 10f64.powf(-end_drop_db / 10.0),
            ended: false,
        }
    }

    pub(super) fn reset(&mut self) {
        self.estimators.iter_mut().for_each(|e| e.reset());
        self.peak.iter_mut().for_each(|p| *p = 0.0);
        self.ended = false;
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
        self.ended = all_low && self.end_factor > 0.0;
    }
}

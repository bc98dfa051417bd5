//! The slow, obviously correct decay estimator: keeps every frame and, when asked, sums the
//! Schroeder curve backwards from the end exactly as its definition is written
//! ([`super::schroeder::backward_integrate`]). It is the oracle the online estimator is held to,
//! frame by frame and through the whole chain ([`crate::pipeline::analyze_decay_with`]).

use super::estimate::{estimate_from_coded_curve, EstimateSettings};
use super::schroeder::{backward_integrate, decay_start_frame};
use super::{DecayEstimate, DecayEstimator, FrequencyCoding};

/// Offline Schroeder estimator for one band: O(frames) per estimate, no running sums.
#[derive(Clone, Debug)]
pub struct BatchSchroeder {
    frame_period_s: f64,
    f_center_hz: f64,
    settings: EstimateSettings,
    energies: Vec<f64>,
    frequencies_hz: Vec<f64>,
    floor_energy: f64,
}

impl BatchSchroeder {
    /// A new estimator for frames `frame_period_s` apart in a band centred at `f_center_hz`.
    pub fn new(frame_period_s: f64, f_center_hz: f64, settings: EstimateSettings) -> Self {
        BatchSchroeder {
            frame_period_s,
            f_center_hz,
            settings,
            energies: Vec::new(),
            frequencies_hz: Vec::new(),
            floor_energy: 0.0,
        }
    }

    /// As [`super::OnlineSchroeder::with_floor_energy`].
    pub fn with_floor_energy(mut self, floor_energy: f64) -> Self {
        self.floor_energy = super::quantization::kept_floor(floor_energy);
        self
    }
}

impl DecayEstimator for BatchSchroeder {
    fn push_frame(&mut self, energy: f64, frequency_hz: f64) {
        // Energies that cannot be (negative, NaN, infinite) count as none, as online.
        self.energies.push(if energy.is_finite() && energy > 0.0 {
            energy
        } else {
            0.0
        });
        self.frequencies_hz.push(frequency_hz);
    }

    fn provisional(&self) -> DecayEstimate {
        let start = decay_start_frame(&self.energies);
        let edc = backward_integrate(&self.energies[start..]);
        estimate_from_coded_curve(
            &edc,
            &self.energies[start..],
            &self.frequencies_hz[start..],
            FrequencyCoding::Hz,
            self.frame_period_s,
            self.f_center_hz,
            &self.settings,
            self.floor_energy,
        )
    }

    fn frames(&self) -> usize {
        self.energies.len()
    }

    fn reset(&mut self) {
        self.energies.clear();
        self.frequencies_hz.clear();
    }

    fn fit_depth_db(&self) -> Option<f64> {
        Some(-self.settings.range.limits_db().1)
    }

    fn total_energy(&self) -> f64 {
        self.energies.iter().sum()
    }

    fn decay_energies(&self) -> &[f64] {
        &self.energies[decay_start_frame(&self.energies)..]
    }
}

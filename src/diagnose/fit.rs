//! The fit of a model to the recordings, as FORMATS.md §5 reports it before and after the
//! update: the RMS differences of the paired modes' damping ratios and frequencies, and the
//! FRF error of the report's eq. 4.8, ε = Σ|H_model − H_measured| / Σ|H_measured| over the
//! frequencies of a band and every sensor, averaged over the third-octave bands of the range.
//!
//! The measured FRF is the DFT of each recorded impulse response (Δt Σ h e^{−jωt}, acceleration
//! per unit force); the model's is its reduced model (modes to twice the range plus residual
//! vectors) solved at the same frequencies, at the recordings' sensors and excitation point.
//! A record shorter than its slowest decay leaks in the DFT; that floor is the same before and
//! after, so the comparison stands, but ε does not reach zero on such data even for a perfect
//! model.

use faer::c64;
use realfft::RealFftPlanner;

use super::evidence::{Evidence, ModelView};
use crate::frontend::iec_bands::{iec_band, OctaveFraction};
use crate::modal::Recordings;
use crate::sim::assembly::sensors_at;
use crate::sim::error::SimError;
use crate::sim::model::SensorPosition;
use crate::sim::reduced::{BasisOptions, ReducedModel, ReducedSolve};

/// The fit of a model to the recordings.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FitMeasures {
    /// Mean over bands of the report's eq. 4.8 (`null` when it cannot be computed).
    pub frf_error: Option<f64>,
    /// RMS over the paired modes of the damping ratio difference.
    pub damping_rms: f64,
    /// RMS over the paired modes of the damped frequency difference, Hz.
    pub frequency_rms_hz: f64,
}

/// Before and after the update.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FitBeforeAfter {
    /// The model as given.
    pub before: FitMeasures,
    /// The updated model.
    pub after: FitMeasures,
}

/// The measures of `evidence` with an FRF error.
pub fn measures(evidence: &Evidence, frf_error: Option<f64>) -> FitMeasures {
    FitMeasures {
        frf_error,
        damping_rms: evidence.damping_rms().unwrap_or(f64::NAN),
        frequency_rms_hz: evidence.frequency_rms_hz().unwrap_or(f64::NAN),
    }
}

/// The recordings' FRFs on the DFT grid within the bands, ready for eq. 4.8.
#[derive(Clone, Debug)]
pub struct MeasuredFrf {
    /// The third-octave bands, (lo, hi) in Hz.
    pub bands: Vec<(f64, f64)>,
    /// The DFT frequencies inside the bands, Hz.
    pub frequencies_hz: Vec<f64>,
    /// Per channel, the accelerance at `frequencies_hz`, (m/s²)/N.
    pub channels: Vec<Vec<c64>>,
}

impl MeasuredFrf {
    /// The FRFs of `rec` in the whole third-octave bands between `lo_hz` and `hi_hz`; `None`
    /// when no whole band fits or the record is empty.
    pub fn of(rec: &Recordings, lo_hz: f64, hi_hz: f64) -> Option<Self> {
        let n = rec.channels.iter().map(Vec::len).max()?;
        if n < 8 || hi_hz.partial_cmp(&lo_hz) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let bands: Vec<(f64, f64)> = (-40..=13)
            .map(|x| iec_band(OctaveFraction::Third, x))
            .filter(|b| b.lo_hz >= lo_hz && b.hi_hz <= hi_hz.min(0.5 * rec.fs_hz))
            .map(|b| (b.lo_hz, b.hi_hz))
            .collect();
        if bands.is_empty() {
            return None;
        }
        let df = rec.fs_hz / n as f64;
        let bins: Vec<usize> = (0..=n / 2)
            .filter(|&k| {
                let f = k as f64 * df;
                bands.iter().any(|b| f >= b.0 && f < b.1)
            })
            .collect();
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
        let dt = 1.0 / rec.fs_hz;
        let channels = rec
            .channels
            .iter()
            .map(|x| {
                let mut buf = vec![0.0; n];
                buf[..x.len()].copy_from_slice(x);
                let mut spec = fft.make_output_vec();
                fft.process(&mut buf, &mut spec)
                    .expect("buffer lengths come from the plan");
                bins.iter()
                    .map(|&k| c64::new(spec[k].re * dt, spec[k].im * dt))
                    .collect()
            })
            .collect();
        Some(Self {
            bands,
            frequencies_hz: bins.iter().map(|&k| k as f64 * df).collect(),
            channels,
        })
    }

    /// Eq. 4.8 averaged over the bands, for model accelerances `model` (per channel, at
    /// `frequencies_hz`). `None` when no band has measured energy.
    pub fn error(&self, model: &[Vec<c64>]) -> Option<f64> {
        let mut per_band = Vec::new();
        for &(lo, hi) in &self.bands {
            let (mut num, mut den) = (0.0, 0.0);
            for (k, f) in self.frequencies_hz.iter().enumerate() {
                if *f < lo || *f >= hi {
                    continue;
                }
                for (m, h) in self.channels.iter().zip(model) {
                    num += (h[k] - m[k]).norm();
                    den += m[k].norm();
                }
            }
            if den > 0.0 {
                per_band.push(num / den);
            }
        }
        (!per_band.is_empty()).then(|| per_band.iter().sum::<f64>() / per_band.len() as f64)
    }
}

/// The accelerance of `view`'s model at `sensors` for a unit z force at `excitation` (x, y in
/// m), at `frequencies_hz`: one vector per sensor.
pub fn model_accelerance(
    view: &ModelView,
    sensors: &[SensorPosition],
    excitation: (f64, f64),
    frequencies_hz: &[f64],
) -> Result<Vec<Vec<c64>>, SimError> {
    let mut system = view.system.clone();
    system.sensors = sensors_at(&view.model, sensors)?;
    let at = sensors_at(
        &view.model,
        &[SensorPosition {
            id: "excitation".into(),
            x_m: excitation.0,
            y_m: excitation.1,
        }],
    )?;
    system.force = vec![0.0; system.n_free];
    for &(d, w) in &at[0].weights {
        system.force[d] += w;
    }
    let reduced = ReducedModel::build(
        &system,
        &view.basis.frequencies_hz,
        view.basis.shapes.as_ref(),
        BasisOptions::default(),
    )?;
    let frf = reduced.frf(frequencies_hz, ReducedSolve::Auto)?;
    Ok((0..frf.n_sensors()).map(|s| frf.accelerance(s)).collect())
}

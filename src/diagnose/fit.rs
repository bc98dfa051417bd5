//! The fit of a model to the recordings, as FORMATS.md §5 reports it before and after the
//! update: the RMS differences of the paired modes' damping ratios and frequencies, and the
//! FRF error of the report's eq. 4.8, ε = Σ|H_model − H_measured| / Σ|H_measured| over the
//! frequencies of a band and every sensor, averaged over the third-octave bands of the range.
//!
//! The measured FRF is the DFT of each recorded impulse response (Δt Σ h e^{−jωt}, acceleration
//! per unit force). A record shorter than its slowest decays (3 s against a T60 of 9 s at
//! 5 Hz) is a truncated response, and its DFT leaks; the model is processed the same way: its
//! reduced model (modes to twice the range plus residual vectors, at the recordings' sensors
//! and excitation point) gives the accelerance on a grid four records long, band-limited with
//! a half-cosine taper above the range, the inverse FFT gives its impulse response, which is
//! cut to the record's length and transformed like the recordings. (A recording made by a
//! simulator with a period equal to the record — an FFT of the FRF on the record's own grid,
//! as `dampscope simulate` does — is periodic instead, and keeps a floor of ε even for a right
//! model.) Which processing the recordings had is not stated in a recording set, so both are
//! tried against the model as given and the one that fits it better is kept for the updated
//! model too. Measurement noise leaves a floor of ε either way.

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
    /// The same after a global calibration (an offset and trends in f and f² of ln f fitted
    /// away): what is left beyond the model form a calibration absorbs, Hz.
    pub frequency_rms_calibrated_hz: f64,
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
        frequency_rms_calibrated_hz: calibrated_rms_hz(evidence),
    }
}

/// RMS of f_model × (ln f ratio − its fit by 1, f, f²) over the pairs, Hz.
fn calibrated_rms_hz(evidence: &Evidence) -> f64 {
    let f: Vec<f64> = evidence
        .pairs
        .iter()
        .map(|p| evidence.model[p.model].damped_frequency_hz)
        .collect();
    let y: Vec<f64> = evidence
        .pairs
        .iter()
        .map(|p| p.frequency_rel.ln_1p())
        .collect();
    residual_rms_hz(&f, &y, &[])
}

/// RMS of fₖ × (yₖ − its fit by 1, f, f² and those `patterns` that have one value per mode),
/// Hz; NaN without modes.
pub(super) fn residual_rms_hz(f_hz: &[f64], y: &[f64], patterns: &[Vec<f64>]) -> f64 {
    if f_hz.is_empty() {
        return f64::NAN;
    }
    let r = super::nuisance::Nuisance::new(f_hz, patterns).residual(y);
    (r.iter()
        .zip(f_hz)
        .map(|(r, f)| (r * f).powi(2))
        .sum::<f64>()
        / f_hz.len() as f64)
        .sqrt()
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
    /// The record length the DFT was taken over, samples.
    pub samples: usize,
}

impl MeasuredFrf {
    /// The accelerances of `rec` in the whole third-octave bands between `lo_hz` and `hi_hz`,
    /// its responses differentiated `derivatives` times (× jω each: 1 for velocities, 2 for
    /// displacements); `None` when no whole band fits or the record is empty.
    pub fn of(rec: &Recordings, derivatives: u32, lo_hz: f64, hi_hz: f64) -> Option<Self> {
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
        // Per bin, dt (the DFT as a Fourier integral) times (jω)^derivatives.
        let factors: Vec<c64> = bins
            .iter()
            .map(|&k| {
                let jw = c64::new(0.0, 2.0 * std::f64::consts::PI * k as f64 * df);
                c64::new(dt, 0.0) * jw.powi(derivatives as i32)
            })
            .collect();
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
                    .zip(&factors)
                    .map(|(&k, factor)| c64::new(spec[k].re, spec[k].im) * factor)
                    .collect()
            })
            .collect();
        Some(Self {
            bands,
            frequencies_hz: bins.iter().map(|&k| k as f64 * df).collect(),
            channels,
            samples: n,
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

/// Records this many times the recording's length make the model's impulse response before
/// it is cut (its decays below the record's end fall 4× further than the record's own).
pub const MODEL_PERIOD_RECORDS: usize = 4;

/// The model's accelerance processed as a recording of `samples` at `fs_hz` would be (see the
/// module doc): per sensor, at the DFT bins `frequencies_hz` of that record length.
pub fn model_recorded_accelerance(
    view: &ModelView,
    sensors: &[SensorPosition],
    excitation: (f64, f64),
    samples: usize,
    fs_hz: f64,
    frequencies_hz: &[f64],
) -> Result<Vec<Vec<c64>>, SimError> {
    let top = frequencies_hz.iter().copied().fold(0.0, f64::max);
    let long = MODEL_PERIOD_RECORDS * samples;
    let df = fs_hz / long as f64;
    let (taper_from, cut) = (1.2 * top, (1.5 * top).min(0.5 * fs_hz));
    let n_grid = ((cut / df).floor() as usize).max(2);
    let grid: Vec<f64> = (0..n_grid).map(|k| k as f64 * df).collect();
    let h = model_accelerance(view, sensors, excitation, &grid)?;
    let inverse = RealFftPlanner::<f64>::new().plan_fft_inverse(long);
    let forward = RealFftPlanner::<f64>::new().plan_fft_forward(samples);
    let bins: Vec<usize> = frequencies_hz
        .iter()
        .map(|f| (f / (fs_hz / samples as f64)).round() as usize)
        .collect();
    let dt = 1.0 / fs_hz;
    Ok(h.iter()
        .map(|hs| {
            let mut spec = inverse.make_input_vec();
            for (k, v) in hs.iter().enumerate() {
                let f = grid[k];
                let w = if f <= taper_from {
                    1.0
                } else {
                    0.5 * (1.0
                        + (std::f64::consts::PI * (f - taper_from) / (cut - taper_from)).cos())
                };
                // h(t) = (1/(long Δt)) Σ H e^{jωt} ⇔ the inverse real FFT of H/Δt, scaled 1/long.
                spec[k] = realfft::num_complex::Complex::new(v.re * w / dt, v.im * w / dt);
            }
            spec[0].im = 0.0;
            let mut ir = inverse.make_output_vec();
            inverse
                .process(&mut spec, &mut ir)
                .expect("buffer lengths come from the plan");
            let mut cut_ir: Vec<f64> = ir[..samples].iter().map(|v| v / long as f64).collect();
            let mut out = forward.make_output_vec();
            forward
                .process(&mut cut_ir, &mut out)
                .expect("buffer lengths come from the plan");
            bins.iter()
                .map(|&b| c64::new(out[b].re * dt, out[b].im * dt))
                .collect()
        })
        .collect())
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

/// Sensors shown in the FRF overlays.
const OVERLAY_SENSORS: usize = 3;

/// Measured and modelled accelerances at a few sensors, for the figures.
#[derive(Clone, Debug)]
pub struct FrfOverlay {
    /// Frequencies, Hz.
    pub frequencies_hz: Vec<f64>,
    /// Sensor ids shown.
    pub sensors: Vec<String>,
    /// Per shown sensor: measured, model before, model after, (m/s²)/N.
    pub curves: Vec<[Vec<c64>; 3]>,
}

/// How the recordings' impulse responses relate to the structure's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum RecordProcessing {
    /// Cut from a longer response (a measurement).
    Truncated,
    /// One period of a response wrapped around (an inverse FFT on the record's own grid).
    Periodic,
}

/// Eq. 4.8 before and after, the processing assumed, and the overlays.
#[derive(Clone, Debug)]
pub struct FrfComparison {
    /// ε of the model as given.
    pub before: Option<f64>,
    /// ε of the updated model.
    pub after: Option<f64>,
    /// The processing that fitted the model as given better.
    pub processing: RecordProcessing,
    /// FRFs at the driving point, the farthest sensor and one between.
    pub overlay: Option<FrfOverlay>,
}

/// The models' accelerance as the recordings were processed.
fn as_recorded(
    view: &ModelView,
    sensors: &[SensorPosition],
    excitation: (f64, f64),
    measured: &MeasuredFrf,
    fs_hz: f64,
    how: RecordProcessing,
) -> Result<Vec<Vec<c64>>, SimError> {
    match how {
        RecordProcessing::Periodic => {
            model_accelerance(view, sensors, excitation, &measured.frequencies_hz)
        }
        RecordProcessing::Truncated => model_recorded_accelerance(
            view,
            sensors,
            excitation,
            measured.samples,
            fs_hz,
            &measured.frequencies_hz,
        ),
    }
}

/// The FRF error (eq. 4.8) of `before` and `after` against `rec` in the whole third-octave
/// bands of `range_hz`, excited at `excitation` (x, y in m); `None` when no band fits.
pub fn compare_frfs(
    rec: &Recordings,
    derivatives: Option<u32>,
    sensors: &[SensorPosition],
    excitation: (f64, f64),
    range_hz: (f64, f64),
    before: &ModelView,
    after: &ModelView,
) -> Result<Option<FrfComparison>, SimError> {
    let Some(measured) = derivatives.and_then(|p| MeasuredFrf::of(rec, p, range_hz.0, range_hz.1))
    else {
        return Ok(None);
    };
    let mut best: Option<(f64, RecordProcessing, Vec<Vec<c64>>)> = None;
    for how in [RecordProcessing::Truncated, RecordProcessing::Periodic] {
        let h = as_recorded(before, sensors, excitation, &measured, rec.fs_hz, how)?;
        let e = measured.error(&h).unwrap_or(f64::INFINITY);
        if best.as_ref().is_none_or(|b| e < b.0) {
            best = Some((e, how, h));
        }
    }
    let (e0, how, h0) = best.expect("two processings tried");
    let h1 = as_recorded(after, sensors, excitation, &measured, rec.fs_hz, how)?;
    let mut by_distance: Vec<usize> = (0..sensors.len()).collect();
    let d = |s: &SensorPosition| (s.x_m - excitation.0).hypot(s.y_m - excitation.1);
    by_distance.sort_by(|&a, &b| d(&sensors[a]).total_cmp(&d(&sensors[b])));
    let shown: Vec<usize> = if by_distance.len() >= OVERLAY_SENSORS {
        vec![
            by_distance[0],
            by_distance[by_distance.len() / 2],
            by_distance[by_distance.len() - 1],
        ]
    } else {
        by_distance
    };
    let overlay = FrfOverlay {
        frequencies_hz: measured.frequencies_hz.clone(),
        sensors: shown.iter().map(|&s| sensors[s].id.clone()).collect(),
        curves: shown
            .iter()
            .map(|&s| [measured.channels[s].clone(), h0[s].clone(), h1[s].clone()])
            .collect(),
    };
    Ok(Some(FrfComparison {
        before: e0.is_finite().then_some(e0),
        after: measured.error(&h1),
        processing: how,
        overlay: Some(overlay),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A displacement impulse response differentiated twice (× (jω)²) is the accelerance the
    /// model gives: one mode of a unit-mass oscillator (f 40 Hz, ζ 2 %) at 8192 Hz, 8 s (fine
    /// enough that the sampled response does not alias into the band by 1 %),
    /// within 1 % of −ω² / (ωₙ² − ω² + 2jζωₙω) in every bin of the bands; read as acceleration
    /// (no differentiation) it is off by orders of magnitude.
    #[test]
    fn displacement_recordings_become_accelerances() {
        let (fs, f_n, zeta) = (8192.0, 40.0, 0.02);
        let w_n = 2.0 * std::f64::consts::PI * f_n;
        let (sigma, w_d) = (zeta * w_n, w_n * (1.0 - zeta * zeta).sqrt());
        let x: Vec<f64> = (0..(8.0 * fs) as usize)
            .map(|i| {
                let t = i as f64 / fs;
                (-sigma * t).exp() * (w_d * t).sin() / w_d
            })
            .collect();
        let rec = Recordings {
            fs_hz: fs,
            names: vec!["s".into()],
            channels: vec![x],
        };
        let measured = MeasuredFrf::of(&rec, 2, 20.0, 100.0).unwrap();
        let analytic: Vec<c64> = measured
            .frequencies_hz
            .iter()
            .map(|&f| {
                let w = 2.0 * std::f64::consts::PI * f;
                c64::new(-w * w, 0.0) / c64::new(w_n * w_n - w * w, 2.0 * zeta * w_n * w)
            })
            .collect();
        assert!(!analytic.is_empty());
        for (m, a) in measured.channels[0].iter().zip(&analytic) {
            assert!((m - a).norm() < 0.01 * a.norm(), "{m} vs {a}");
        }
        let error = measured.error(std::slice::from_ref(&analytic)).unwrap();
        assert!(error < 0.01, "{error}");
        let undifferentiated = MeasuredFrf::of(&rec, 0, 20.0, 100.0).unwrap();
        assert!(undifferentiated.error(&[analytic]).unwrap() > 0.9);
    }
}

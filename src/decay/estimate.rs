//! From a Schroeder curve to reverberation times, damping ratios, quality figures and flags.
//!
//! A number is only reported when the curve supports it: the curve must reach the lower limit of
//! the evaluation range and at least [`EstimateSettings::min_points`] frames must lie in it;
//! otherwise the estimate is empty and a [`Flag`] says why.

use super::damping::damping_ratio;
use super::lundeby::{compensated_edc, lundeby, FirstRegressionEnd, LundebySettings};
use super::range::EvaluationRange;
use super::regression::{fit_line, LineFit};

/// Why an estimate is missing, or what to be careful about when reading it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Flag {
    /// The band received no energy.
    NoEnergy,
    /// The record ends before the decay curve reaches the lower limit of the range.
    TooShort,
    /// The curve reaches the range, but fewer than the minimum number of frames fall inside it:
    /// the front end's frame rate is too low for this decay (use a shorter window or a filter bank).
    TooFewFrames,
    /// A noise floor sits less than 10 dB below the lower limit of the range (ISO 3382 rule).
    NoiseLimited,
    /// The fitted line does not fall.
    NoDecay,
    /// |T30/T20 − 1| exceeds the curvature limit: not a single exponential (beating, several
    /// modes, or noise).
    NonlinearDecay,
    /// The record ends less than 10 dB below the lower limit, so the end of the curve bends down.
    TruncationBias,
    /// The channel contained NaN or infinite samples; nothing from it is reported.
    NonFiniteInput,
    /// The input ended in the middle of a sample frame or before the length its header announced.
    InputTruncated,
    /// The frequency carrying the band's energy lies outside the band: the decay measured is
    /// leakage of a neighbouring mode (the report's nodal-line effect, section 3.2).
    OffBandDominant,
    /// A noise floor was found; the curve was truncated at Lundeby's intersection time and its
    /// tail compensated (ISO 3382 practice).
    NoiseCompensated,
    /// The band lies (partly) above the Nyquist frequency or outside what the front end resolves.
    BandOutOfRange,
    /// The decay outlasted the buffering front end's limit (`max_decay_s`): only its first
    /// part was analysed.
    DecayTooLong,
    /// The analysis of this channel stopped on an internal error (a bug, reported on stderr);
    /// the other channels were analysed.
    InternalError,
}

impl Flag {
    /// The flag as it appears in tables.
    pub fn as_str(&self) -> &'static str {
        match self {
            Flag::NoEnergy => "no_energy",
            Flag::TooShort => "too_short",
            Flag::TooFewFrames => "too_few_frames",
            Flag::NoiseLimited => "noise_limited",
            Flag::NoDecay => "no_decay",
            Flag::NonlinearDecay => "nonlinear_decay",
            Flag::TruncationBias => "truncation_bias",
            Flag::NonFiniteInput => "non_finite_input",
            Flag::InputTruncated => "input_truncated",
            Flag::BandOutOfRange => "band_out_of_range",
            Flag::NoiseCompensated => "noise_compensated",
            Flag::OffBandDominant => "off_band_dominant",
            Flag::DecayTooLong => "decay_too_long",
            Flag::InternalError => "internal_error",
        }
    }
}

/// How estimates are made from a decay curve.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EstimateSettings {
    /// The range whose fit gives `t60_s` and the damping ratios.
    pub range: EvaluationRange,
    /// Fewest frames inside the range for a fit (3 by default).
    pub min_points: usize,
    /// |C| = |100 (T30/T20 − 1)| above this, in %, raises [`Flag::NonlinearDecay`] (10 by default).
    pub curvature_limit_pct: f64,
    /// A noise floor less than this many dB below the range's lower limit raises
    /// [`Flag::NoiseLimited`] and withholds the number (10 by default, the ISO 3382-1 rule:
    /// 35 dB of peak-to-noise for T20, 45 dB for T30). Lower it to get noise-compensated
    /// values closer to the floor, at the risk of their bias.
    pub noise_margin_db: f64,
}

impl Default for EstimateSettings {
    fn default() -> Self {
        EstimateSettings {
            range: EvaluationRange::T30,
            min_points: 3,
            curvature_limit_pct: 10.0,
            noise_margin_db: 10.0,
        }
    }
}

/// Everything dampscope reports about one decay in one band. Missing values are `None`.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DecayEstimate {
    /// Early decay time (0…−10 dB, ×6) in seconds.
    pub edt_s: Option<f64>,
    /// T20 (−5…−25 dB, ×3) in seconds.
    pub t20_s: Option<f64>,
    /// T30 (−5…−35 dB, ×2) in seconds.
    pub t30_s: Option<f64>,
    /// Reverberation time from the chosen range, in seconds.
    pub t60_s: Option<f64>,
    /// D = 1.0994 / (T60 · f_center) (report eq. 2.14), a fraction.
    pub damping_ratio: Option<f64>,
    /// D · f_center / f_dominant (report eq. 3.2), a fraction.
    pub damping_ratio_corrected: Option<f64>,
    /// Energy-weighted frequency present in the band during the fitted part, Hz.
    pub f_dominant_hz: Option<f64>,
    /// r² of the chosen range's fit.
    pub r2: Option<f64>,
    /// Frames in the chosen range's fit.
    pub n_points: usize,
    /// Peak band energy over the mean of the last 10 % of frames, dB.
    pub dynamic_range_db: Option<f64>,
    /// C = 100 (T30/T20 − 1), %.
    pub curvature_pct: Option<f64>,
    /// Why something is missing or suspect.
    pub flags: Vec<Flag>,
}

impl DecayEstimate {
    /// An estimate that holds nothing but one flag.
    pub fn failed(flag: Flag) -> Self {
        DecayEstimate {
            flags: vec![flag],
            ..Default::default()
        }
    }

    /// True when `flag` was raised.
    pub fn has(&self, flag: Flag) -> bool {
        self.flags.contains(&flag)
    }
}

/// A fit over one range, or why there is none.
struct RangeFit {
    fit: LineFit,
    first: usize,
    end: usize,
    tail_margin_db: f64,
}

fn fit_range(
    levels_db: &[f64],
    times_s: &[f64],
    range: EvaluationRange,
    noise: Option<f64>,
    settings: &EstimateSettings,
) -> Result<RangeFit, Flag> {
    let min_points = settings.min_points;
    let (upper, lower) = range.limits_db();
    if let Some(pnr_db) = noise {
        if pnr_db < -lower + settings.noise_margin_db {
            return Err(Flag::NoiseLimited);
        }
    }
    let last = *levels_db.last().ok_or(Flag::NoEnergy)?;
    if last > lower {
        return Err(if noise.is_some() {
            Flag::NoiseLimited
        } else {
            Flag::TooShort
        });
    }
    let first = levels_db
        .iter()
        .position(|&l| l <= upper)
        .ok_or(Flag::TooShort)?;
    let end = levels_db
        .iter()
        .position(|&l| l < lower)
        .unwrap_or(levels_db.len());
    if end <= first || end - first < min_points {
        return Err(Flag::TooFewFrames);
    }
    let fit = fit_line(&times_s[first..end], &levels_db[first..end]).ok_or(Flag::TooFewFrames)?;
    if fit.t60_s().is_none() {
        return Err(Flag::NoDecay);
    }
    Ok(RangeFit {
        fit,
        first,
        end,
        tail_margin_db: lower - last,
    })
}

/// Noise floor check on the band energies: `Some(peak-to-noise ratio in dB)` when the last 10 %
/// of the frames no longer decay (less than 3 dB below the 10 % before them).
fn noise_floor_pnr_db(energies: &[f64]) -> Option<f64> {
    let n = energies.len();
    if n < 20 {
        return None;
    }
    let tenth = (n / 10).max(2);
    let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
    let tail = mean(&energies[n - tenth..]);
    let before = mean(&energies[n - 2 * tenth..n - tenth]);
    let peak = energies.iter().cloned().fold(0.0, f64::max);
    if tail <= 0.0 || peak <= 0.0 {
        return None;
    }
    let pnr = 10.0 * (peak / tail).log10();
    (before < 2.0 * tail && pnr < 150.0).then_some(pnr)
}

/// The Schroeder curve of `energies` minus the noise energy, truncated at Lundeby's
/// intersection time, with the tail beyond it added back (METHODS.md §2.2). `None` when Lundeby's method fails.
fn noise_compensated_curve(
    energies: &[f64],
    frame_period_s: f64,
    f_center_hz: f64,
) -> Option<Vec<f64>> {
    let settings = LundebySettings {
        // pyrato's per-band block length (800/f + 10) ms, at least one frame.
        initial_block_s: ((800.0 / f_center_hz.max(1.0) + 10.0) * 1e-3).max(frame_period_s),
        first_regression_end: FirstRegressionEnd::FirstBelow,
        ..Default::default()
    };
    let found = lundeby(energies, 1.0 / frame_period_s, &settings).ok()?;
    let curve: Vec<f64> = compensated_edc(energies, 1.0 / frame_period_s, &found, true)
        .into_iter()
        .map_while(|v| v)
        .collect();
    (curve.len() >= 2).then_some(curve)
}

/// Estimates a decay from its (unnormalised) Schroeder curve `edc`, the frame energies and the
/// per-frame frequencies, with frames `frame_period_s` apart in a band centred on `f_center_hz`.
pub fn estimate_from_curve(
    edc: &[f64],
    energies: &[f64],
    frequencies_hz: &[f64],
    frame_period_s: f64,
    f_center_hz: f64,
    settings: &EstimateSettings,
) -> DecayEstimate {
    if edc.is_empty() || edc[0] <= 0.0 || !edc[0].is_finite() {
        return DecayEstimate::failed(Flag::NoEnergy);
    }
    let noise = noise_floor_pnr_db(energies);
    // With a noise floor, truncate at Lundeby's intersection time and add the missing tail.
    let mut noise_compensated = false;
    let curve: Vec<f64> = match noise {
        Some(_) => match noise_compensated_curve(energies, frame_period_s, f_center_hz) {
            Some(c) => {
                noise_compensated = true;
                c
            }
            // A noise floor that Lundeby cannot place: no trustworthy curve.
            None => return DecayEstimate::failed(Flag::NoiseLimited),
        },
        None => edc.to_vec(),
    };
    if curve.is_empty() || curve[0] <= 0.0 {
        return DecayEstimate::failed(Flag::NoiseLimited);
    }
    let levels_db: Vec<f64> = curve
        .iter()
        .map(|&e| 10.0 * (e.max(f64::MIN_POSITIVE) / curve[0]).log10())
        .collect();
    let times_s: Vec<f64> = (0..curve.len())
        .map(|k| k as f64 * frame_period_s)
        .collect();
    let fit_of = |r| fit_range(&levels_db, &times_s, r, noise, settings);
    let t_of = |r| fit_of(r).ok().and_then(|f| f.fit.t60_s());

    let mut est = DecayEstimate {
        edt_s: t_of(EvaluationRange::Edt),
        t20_s: t_of(EvaluationRange::T20),
        t30_s: t_of(EvaluationRange::T30),
        ..Default::default()
    };
    let peak = energies.iter().cloned().fold(0.0, f64::max);
    if energies.len() >= 2 && peak > 0.0 {
        let tenth = (energies.len() / 10).max(1);
        let tail = energies[energies.len() - tenth..].iter().sum::<f64>() / tenth as f64;
        if tail > 0.0 {
            est.dynamic_range_db = Some(10.0 * (peak / tail).log10());
        }
    }

    let (w_first, w_end) = match fit_of(settings.range) {
        Ok(rf) => {
            let t60 = rf
                .fit
                .t60_s()
                .expect("fit_range returns falling lines only");
            est.t60_s = Some(t60);
            est.damping_ratio = Some(damping_ratio(t60, f_center_hz));
            est.r2 = Some(rf.fit.r2);
            est.n_points = rf.fit.n_points;
            if rf.tail_margin_db < 10.0 {
                est.flags.push(Flag::TruncationBias);
            }
            (rf.first, rf.end)
        }
        Err(flag) => {
            est.flags.push(flag);
            (0, energies.len())
        }
    };

    // Frequency present in the band: energy-weighted over the fitted frames.
    let (mut wsum, mut fsum) = (0.0, 0.0);
    for k in w_first..w_end.min(frequencies_hz.len()) {
        let f = frequencies_hz[k];
        if f.is_finite() && f > 0.0 {
            wsum += energies[k];
            fsum += energies[k] * f;
        }
    }
    if wsum > 0.0 {
        let f_dom = fsum / wsum;
        est.f_dominant_hz = Some(f_dom);
        if let Some(t60) = est.t60_s {
            est.damping_ratio_corrected = Some(damping_ratio(t60, f_dom));
        }
    }

    if noise_compensated {
        est.flags.push(Flag::NoiseCompensated);
    }
    if let (Some(t20), Some(t30)) = (est.t20_s, est.t30_s) {
        let c = 100.0 * (t30 / t20 - 1.0);
        est.curvature_pct = Some(c);
        if c.abs() > settings.curvature_limit_pct {
            est.flags.push(Flag::NonlinearDecay);
        }
    }
    est
}

//! From a Schroeder curve to reverberation times, damping ratios, quality figures and flags.
//!
//! A number is only reported when the curve supports it: a noise floor must lie
//! [`EstimateSettings::noise_margin_db`] below the lower limit of the evaluation range, a record
//! that ends while the decay still falls must end below that limit (the band energy, not the
//! backward integral, which always plunges at the end), the curve must reach it and at least
//! [`EstimateSettings::min_points`] frames must lie in it; otherwise the estimate is empty and a
//! [`Flag`] says why. The check runs for every number (EDT, T20, T30) on its own range.

use super::damping::damping_ratio;
use super::lundeby::{compensated_curve_into, lundeby, FirstRegressionEnd, LundebySettings};
use super::range::EvaluationRange;
use super::regression::{fit_line, LineFit};
use super::schroeder::PooledCurve;
use super::FrequencyCoding;

pub use super::flags::Flag;

pub use super::settings::*;

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

    /// Withholds every decay time and damping ratio and raises `flag` (once): the curve does
    /// not describe a decay of this band. Quality figures and `f_dominant` stay, to show why.
    pub fn withhold(&mut self, flag: Flag) {
        self.edt_s = None;
        self.t20_s = None;
        self.t30_s = None;
        self.t60_s = None;
        self.damping_ratio = None;
        self.damping_ratio_corrected = None;
        if !self.has(flag) {
            self.flags.push(flag);
        }
    }

    /// Why the estimate has no damping ratio: the first flag that withholds one (not a
    /// qualifying flag such as `noise_compensated` that happened to be raised first), or
    /// `None` when the number stands.
    pub fn missing_reason(&self) -> Option<&'static str> {
        if self.damping_ratio.is_some() {
            return None;
        }
        Some(Flag::missing_reason(&self.flags))
    }

    /// True when the estimate carries a reverberation time (no flag withheld it).
    pub fn has_number(&self) -> bool {
        self.t60_s.is_some()
    }
}

/// A fit over one range, or why there is none.
struct RangeFit {
    fit: LineFit,
    first: usize,
    end: usize,
    tail_margin_db: f64,
}

/// What a band's peak must clear its undithered rounding noise by, beyond a range's depth, dB:
/// the noise margin plus [`super::quantization::UNDITHERED_EXTRA_MARGIN_DB`].
fn quantization_margin_db(settings: &EstimateSettings) -> f64 {
    settings.noise_margin_db + super::quantization::UNDITHERED_EXTRA_MARGIN_DB
}

fn fit_range(
    levels_db: &[f64],
    last_db: f64,
    times_s: &[f64],
    range: EvaluationRange,
    floor: Floor,
    quantization_db: Option<f64>,
    settings: &EstimateSettings,
) -> Result<RangeFit, Flag> {
    let min_points = settings.min_points;
    let (upper, lower) = match range {
        EvaluationRange::Edt => settings.edt_limits_db,
        r => r.limits_db(),
    };
    let noise = match floor {
        Floor::Noise(pnr_db) => Some(pnr_db),
        _ => None,
    };
    match floor {
        Floor::Noise(db) if db < -lower + settings.noise_margin_db => {
            return Err(Flag::NoiseLimited)
        }
        Floor::RecordEnd(db) if db < -lower => return Err(Flag::TooShort),
        _ => {}
    }
    if levels_db.is_empty() {
        return Err(Flag::NoEnergy);
    }
    if quantization_db.is_some_and(|q| q < -lower + quantization_margin_db(settings)) {
        return Err(Flag::QuantizationLimited);
    }
    if last_db > lower {
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
        tail_margin_db: match floor {
            Floor::RecordEnd(db) => db + lower,
            _ => lower - last_db,
        },
    })
}

/// What the decay ends in, as dB below the peak frame energy: the range check of every reported
/// number compares it with the range's lower limit plus [`EstimateSettings::noise_margin_db`].
#[derive(Clone, Copy, Debug)]
enum Floor {
    /// A noise floor (the record end no longer decays).
    Noise(f64),
    /// The record ends while the decay still falls, at this level (mean of its last tenth): a
    /// truncated or short record, whose backward integral plunges at the end and would
    /// otherwise let a 7.5 dB decay give an EDT (issue 15). A number needs the end below the
    /// range's lower limit; less than 10 dB below it raises [`Flag::TruncationBias`].
    RecordEnd(f64),
    /// Too few frames to tell.
    Unknown,
}

/// Noise floor check on the band energies: `Some(peak-to-noise ratio in dB)` when the end of the
/// record no longer decays: the last 10 % of the frames less than 3 dB below the 10 % before
/// them, or the last 20 % less than 3 dB below the 20 % before them. Band energies of noise
/// fluctuate (a few STFT bins per frame: nearly exponentially distributed), so the mean of a
/// tenth of a short record is noisy; the longer pair catches the floors the shorter misses
/// (measured: STFT band of 5 Hz, 12 s at 35 dB PSNR, 2 of 16 noise seeds missed by the tenths
/// alone and their numbers withheld as `poor_fit`), and a decay still falling is farther below
/// over a fifth than over a tenth, so it is no likelier to be taken for noise.
fn noise_floor_pnr_db(energies: &[f64], figures: &EndFigures) -> Option<f64> {
    let n = energies.len();
    if n < 20 {
        return None;
    }
    let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
    // The last tenth's mean is `figures.tenth_mean` (n ≥ 20: a tenth is at least 2 frames).
    let tail_of = |part: usize| {
        if part == n / 10 {
            figures.tenth_mean
        } else {
            mean(&energies[n - part..])
        }
    };
    let flat = |part: usize| {
        let tail = tail_of(part);
        let before = mean(&energies[n - 2 * part..n - part]);
        tail > 0.0 && before < 2.0 * tail
    };
    let (tail, peak) = (figures.tenth_mean, figures.peak);
    if tail <= 0.0 || peak <= 0.0 {
        return None;
    }
    let pnr = 10.0 * (peak / tail).log10();
    ((flat(n / 10) || flat(n / 5)) && pnr < 150.0).then_some(pnr)
}

/// What the noise-floor test and the dynamic range both read from a band's frames: its peak
/// (NaN ignored, at least 0) and the mean of its last tenth (at least one frame). Each was
/// computed in both (a scan and an in-order sum over 500 of 5000 frames, twice per band).
struct EndFigures {
    peak: f64,
    /// NaN without frames.
    tenth_mean: f64,
}

impl EndFigures {
    fn of(energies: &[f64]) -> EndFigures {
        let tenth = (energies.len() / 10).max(1).min(energies.len());
        let last = &energies[energies.len() - tenth..];
        EndFigures {
            peak: super::peak_or_zero(energies),
            tenth_mean: last.iter().sum::<f64>() / tenth as f64,
        }
    }
}

/// Peak frame energy over the mean of the last tenth of the frames, in dB (`None` when there are
/// fewer than two frames or no energy at the end).
fn peak_to_tail_db(energies: &[f64], figures: &EndFigures) -> Option<f64> {
    let (peak, tail) = (figures.peak, figures.tenth_mean);
    if energies.len() < 2 || peak <= 0.0 {
        return None;
    }
    (tail > 0.0).then(|| 10.0 * (peak / tail).log10())
}

/// Time, s, at which the Schroeder curve `edc` first falls 10 dB below its start (the whole
/// record when it never does).
fn ten_db_time_s(edc: &[f64], frame_period_s: f64) -> f64 {
    let start = edc.first().copied().unwrap_or(0.0);
    edc.iter()
        .position(|&e| e <= 0.1 * start)
        .unwrap_or(edc.len()) as f64
        * frame_period_s
}

/// The Schroeder curve of `energies` (plain: `edc`) minus the noise energy, truncated at Lundeby's
/// intersection time, with the tail beyond it added back (METHODS.md §2.2). `None` when Lundeby's method fails.
fn noise_compensated_curve(
    edc: &[f64],
    energies: &[f64],
    frame_period_s: f64,
    f_center_hz: f64,
    compensation: NoiseCompensation,
) -> Option<PooledCurve> {
    // pyrato's per-band block length (800/f + 10) ms, at least one frame; the robust variant
    // caps it at a fifth of the time the curve takes to fall 10 dB (Lundeby's own 5 blocks per
    // 10 dB): a 4 kHz structural mode with T60 = 25 ms fell 26 dB within pyrato's 10 ms block
    // and was refused as noise-limited with 70 dB of range.
    let pyrato_block_s = (800.0 / f_center_hz.max(1.0) + 10.0) * 1e-3;
    let block_s = match compensation {
        NoiseCompensation::Pyrato => pyrato_block_s,
        NoiseCompensation::Robust => pyrato_block_s.min(0.2 * ten_db_time_s(edc, frame_period_s)),
    };
    let settings = LundebySettings {
        initial_block_s: block_s.max(frame_period_s),
        first_regression_end: match compensation {
            NoiseCompensation::Robust => FirstRegressionEnd::FirstBelow,
            NoiseCompensation::Pyrato => FirstRegressionEnd::LastAbove,
        },
        ..Default::default()
    };
    let mut found = lundeby(energies, 1.0 / frame_period_s, &settings).ok()?;
    if compensation == NoiseCompensation::Pyrato {
        let tenth = &energies[energies.len() - (energies.len() / 10).max(1)..];
        found.noise_energy = tenth.iter().sum::<f64>() / tenth.len() as f64;
    }
    let mut curve = PooledCurve::with_capacity(energies.len());
    compensated_curve_into(energies, 1.0 / frame_period_s, &found, true, &mut curve);
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
    estimate_from_coded_curve(
        edc,
        energies,
        frequencies_hz,
        FrequencyCoding::Hz,
        frame_period_s,
        f_center_hz,
        settings,
        0.0,
    )
}

/// [`estimate_from_curve`] with the per-frame frequencies coded by `coding`: only the fitted
/// frames' are decoded; and with the band's share of the input's rounding noise,
/// `floor_energy` per frame (0: float input), which every range must clear by its depth plus
/// the margins unless the record's own floor dithers it ([`super::quantization`]).
#[allow(clippy::too_many_arguments)]
pub fn estimate_from_coded_curve(
    edc: &[f64],
    energies: &[f64],
    frequencies: &[f64],
    coding: FrequencyCoding,
    frame_period_s: f64,
    f_center_hz: f64,
    settings: &EstimateSettings,
    floor_energy: f64,
) -> DecayEstimate {
    if edc.is_empty() || edc[0] <= 0.0 || !edc[0].is_finite() {
        return DecayEstimate::failed(Flag::NoEnergy);
    }
    // Digital silence at the end — exact zeros, as in a record zero-padded after it was cut, or
    // a quiet integer recording rounded to 0 — is not a decay that reached −∞ dB: the record
    // ends at its last frame with energy, and the range checks see that end (a 0.5 s response
    // padded to 3 s gave D +20 % where the same 0.5 s unpadded gives `too_short`).
    let live = energies
        .iter()
        .rposition(|&e| e != 0.0)
        .map_or(0, |k| k + 1);
    let energies = &energies[..live];
    let edc = &edc[..live.min(edc.len())];
    let frequencies = &frequencies[..live.min(frequencies.len())];
    let figures = EndFigures::of(energies);
    let noise = noise_floor_pnr_db(energies, &figures);
    let quantization_db =
        super::quantization::undithered_clearance_db(figures.peak, floor_energy, noise);
    // With a noise floor, truncate at Lundeby's intersection time and add the missing tail.
    let mut noise_compensated = false;
    let compensated = match noise {
        Some(_) => match noise_compensated_curve(
            edc,
            energies,
            frame_period_s,
            f_center_hz,
            settings.noise_compensation,
        ) {
            Some(c) => {
                noise_compensated = true;
                Some(c)
            }
            // A noise floor that Lundeby cannot place: no trustworthy curve.
            None => return DecayEstimate::failed(Flag::NoiseLimited),
        },
        None => None,
    };
    // The compensated curve, or the Schroeder curve as given.
    let curve: &[f64] = compensated.as_deref().map_or(edc, |c| c.as_slice());
    if curve.is_empty() || curve[0] <= 0.0 {
        return DecayEstimate::failed(Flag::NoiseLimited);
    }
    let level_db = |e: f64| 10.0 * (e.max(f64::MIN_POSITIVE) / curve[0]).log10();
    // The levels down to the first below the deepest limit of any fit, and the last one: no
    // fit looks further (a 10 s decay at 2 ms frames is mostly tail, and its logarithms were
    // 5 % of an octave-bank run).
    let deepest_db = [
        settings.edt_limits_db.1,
        EvaluationRange::T20.limits_db().1,
        EvaluationRange::T30.limits_db().1,
        settings.range.limits_db().1,
    ]
    .into_iter()
    .fold(f64::INFINITY, |a, b| {
        if b.is_nan() {
            f64::NEG_INFINITY
        } else {
            a.min(b)
        }
    });
    let mut levels_db = Vec::with_capacity(curve.len());
    for &e in curve {
        let l = level_db(e);
        levels_db.push(l);
        if l < deepest_db {
            break;
        }
    }
    let last_db = level_db(curve[curve.len() - 1]);
    let times_s: Vec<f64> = (0..levels_db.len())
        .map(|k| k as f64 * frame_period_s)
        .collect();
    let dynamic_range_db = peak_to_tail_db(energies, &figures);
    let floor = match (noise, dynamic_range_db) {
        (Some(pnr_db), _) => Floor::Noise(pnr_db),
        (None, Some(db)) => Floor::RecordEnd(db),
        (None, None) => Floor::Unknown,
    };
    let fit_of = |r| {
        fit_range(
            &levels_db,
            last_db,
            &times_s,
            r,
            floor,
            quantization_db,
            settings,
        )
    };
    let t_of = |r| fit_of(r).ok().and_then(|f| f.fit.t60_s());

    let mut est = DecayEstimate {
        edt_s: t_of(EvaluationRange::Edt),
        t20_s: t_of(EvaluationRange::T20),
        t30_s: t_of(EvaluationRange::T30),
        dynamic_range_db,
        ..Default::default()
    };

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
    for k in w_first..w_end.min(frequencies.len()) {
        let f = coding.to_hz(frequencies[k]);
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
    let poor_r2 = est.r2.is_some_and(|r2| r2 < settings.min_r2);
    let poor_c = est
        .curvature_pct
        .is_some_and(|c| c.abs() > settings.max_curvature_pct);
    if est.t60_s.is_some() && (poor_r2 || poor_c) {
        est.withhold(Flag::PoorFit);
    }
    est
}

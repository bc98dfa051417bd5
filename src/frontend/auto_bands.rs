//! Mode-centred band layouts (`--bands auto`): one band per mode, edges halfway to the neighbours.
//!
//! A band that holds several modes yields only an energy-weighted mean damping D_eq; a band
//! centred on one mode and reaching halfway to each neighbour measures that mode's damping (with
//! the Goyder filter bank, whose reversed filtering keeps the decay rate even when B·T60 ≈ 1).
//! Mode frequencies come from the spectral peaks of the decay itself ([`auto_bands`]) or from a
//! model ([`bands_around_modes`]).

use realfft::RealFftPlanner;

use super::Band;
use crate::error::{Error, Result};

/// How spectral peaks are picked for `--bands auto`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AutoBandSettings {
    /// Lowest peak frequency considered, Hz.
    pub f_min_hz: f64,
    /// Highest peak frequency considered, Hz (clamped to Nyquist).
    pub f_max_hz: f64,
    /// Peaks more than this far below the largest one in the range are ignored, dB (30).
    pub threshold_db: f64,
    /// Widest band, Hz: each half-width is capped at half of this (default 100 Hz).
    pub max_width_hz: f64,
    /// Peaks closer than this keep only the larger one, Hz (default 1 Hz).
    pub min_spacing_hz: f64,
    /// FFT length = next power of two ≥ the decay length, times this (default 4).
    pub zero_pad: usize,
    /// Most peaks kept (the largest; default 64).
    pub max_peaks: usize,
    /// Narrowest band, Hz (0 by default): a buffering bank drops `cut_factor / B` seconds at
    /// the end of each band, so bands on a short record must be wide (see
    /// [`min_width_for_record_hz`]). Overrides `max_width_hz` where larger.
    pub min_width_hz: f64,
}

/// Narrowest band whose transient cut (`cut_factor / B` s) takes at most a quarter of a record
/// of `record_s` seconds: a 0.1 s shock record needs 120 Hz bands with the banks' cut factor 3.
pub fn min_width_for_record_hz(record_s: f64, cut_factor: f64) -> f64 {
    if record_s > 0.0 {
        4.0 * cut_factor / record_s
    } else {
        0.0
    }
}

impl Default for AutoBandSettings {
    fn default() -> Self {
        AutoBandSettings {
            f_min_hz: 0.0,
            f_max_hz: f64::INFINITY,
            threshold_db: 30.0,
            max_width_hz: 100.0,
            min_spacing_hz: 1.0,
            zero_pad: 4,
            max_peaks: 64,
            min_width_hz: 0.0,
        }
    }
}

/// Bands centred on `freqs_hz` (sorted and deduplicated here): each band reaches halfway to the
/// neighbouring modes, the outermost ones as far out as inward, and no half-width exceeds
/// `max_width_hz / 2`. `center_hz` and `nominal_hz` are the mode frequency. Non-finite or
/// non-positive frequencies are an error.
pub fn bands_around_modes(freqs_hz: &[f64], max_width_hz: f64) -> Result<Vec<Band>> {
    if !(max_width_hz.is_finite() && max_width_hz > 0.0) {
        return Err(Error::setting(
            "max band width",
            format!("expected a positive width in Hz, got {max_width_hz}"),
        ));
    }
    if let Some(bad) = freqs_hz.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
        return Err(Error::setting(
            "mode frequencies",
            format!("expected positive finite frequencies in Hz, got {bad}"),
        ));
    }
    let mut f: Vec<f64> = freqs_hz.to_vec();
    f.sort_by(f64::total_cmp);
    f.dedup();
    let cap = 0.5 * max_width_hz;
    let n = f.len();
    Ok((0..n)
        .map(|i| {
            let below = (i > 0).then(|| 0.5 * (f[i] - f[i - 1]));
            let above = (i + 1 < n).then(|| 0.5 * (f[i + 1] - f[i]));
            let lo_half = below.or(above).unwrap_or(cap).min(cap).min(f[i]);
            let hi_half = above.or(below).unwrap_or(cap).min(cap);
            Band {
                lo_hz: f[i] - lo_half,
                hi_hz: f[i] + hi_half,
                center_hz: f[i],
                nominal_hz: f[i],
            }
        })
        .collect())
}

/// A peak must stand this many dB above the higher of its two bases (the lowest points between
/// it and the nearest higher peak on each side, or the range's ends) of the smoothed spectrum to
/// count as a mode: the ripples of one broad peak, or of a short record's truncation, do not.
pub const PEAK_PROMINENCE_DB: f64 = 10.0;

/// The power spectrum is smoothed over this many times 1/T (T the longest record): the
/// sidelobes of a record cut at T repeat every 1/T Hz.
pub const SMOOTHING_RECORDS: f64 = 2.0;

/// Peak frequencies (Hz, ascending) of one decay; see [`spectral_peaks_multi`].
pub fn spectral_peaks(samples: &[f64], fs_hz: f64, s: &AutoBandSettings) -> Result<Vec<f64>> {
    Ok(spectral_peaks_multi(&[samples], fs_hz, s)?
        .into_iter()
        .map(|p| p.f_hz)
        .collect())
}

/// A mode found in a spectrum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpectralPeak {
    /// Peak frequency, Hz (parabolic interpolation).
    pub f_hz: f64,
    /// Peak level of the smoothed spectrum, dB (relative).
    pub level_db: f64,
    /// Width where the smoothed spectrum is 3 dB down on both sides, Hz: about 2·D·f for a
    /// lightly damped mode (plus the smoothing, 2/T).
    pub half_power_hz: f64,
}

/// Frame period, s, that gives a decay in any of `bands` at least ten frames over its first
/// 10 dB, when each band is [`HALF_POWER_WIDTHS_PER_BAND`] half-power widths of its mode:
/// T60 ≈ 2.2 / Δf_3dB = 8.8 / B, so 10 dB take 1.47 / B s; 0.15 / B_max. The buffering banks'
/// 2 ms frames gave a 4 kHz impact mode (T20 of 15 ms) fewer than three frames.
pub fn frame_period_for_bands_s(bands: &[Band]) -> f64 {
    let widest = bands.iter().map(|b| b.width_hz()).fold(0.0, f64::max);
    if widest > 0.0 {
        0.15 / widest
    } else {
        f64::INFINITY
    }
}

/// Auto bands end at most this fraction of the Nyquist frequency.
pub const NYQUIST_MARGIN: f64 = 0.99;

/// A band centred on a mode must be at least this many half-power widths wide: a band-pass
/// narrower than the mode's own peak rings longer than the mode decays and measures itself
/// (a 50 Hz band on a 4.2 kHz mode with D = 1 %, half-power width 83 Hz, read the band
/// filter's envelope, not the mode's).
pub const HALF_POWER_WIDTHS_PER_BAND: f64 = 4.0;

/// Peak frequencies (Hz, ascending) of the power spectrum summed over `channels` (each from its
/// onset, each normalised to unit energy so that one loud sensor does not decide alone),
/// zero-padded, smoothed over [`SMOOTHING_RECORDS`] / T: local maxima within the range and
/// threshold whose prominence is at least [`PEAK_PROMINENCE_DB`], refined by parabolic
/// interpolation. Of two peaks closer than the larger one's half-power (−3 dB) width — about
/// 2·D·f, the spacing below which two modes are one peak — and closer than `min_spacing_hz`,
/// only the larger is kept.
pub fn spectral_peaks_multi(
    channels: &[&[f64]],
    fs_hz: f64,
    s: &AutoBandSettings,
) -> Result<Vec<SpectralPeak>> {
    if !(fs_hz.is_finite() && fs_hz > 0.0) {
        return Err(Error::setting(
            "fs",
            format!("expected a positive sample rate in Hz, got {fs_hz}"),
        ));
    }
    let longest = channels.iter().map(|c| c.len()).max().unwrap_or(0);
    if longest < 4 || channels.iter().any(|c| c.iter().any(|x| !x.is_finite())) {
        return Err(Error::setting(
            "auto_bands",
            format!("expected at least 4 finite samples to find modes, got {longest} samples"),
        ));
    }
    if !(s.zero_pad >= 1 && s.zero_pad <= 64 && s.threshold_db >= 0.0 && s.min_spacing_hz >= 0.0) {
        return Err(Error::setting(
            "auto_bands",
            "expected zero_pad 1…64, threshold_db >= 0 and min_spacing_hz >= 0",
        ));
    }
    let n_fft = longest.next_power_of_two() * s.zero_pad;
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n_fft);
    let mut power = vec![0.0; n_fft / 2 + 1];
    for samples in channels {
        let energy: f64 = samples.iter().map(|x| x * x).sum();
        if energy.is_nan() || energy <= 0.0 {
            continue;
        }
        let mut input = fft.make_input_vec();
        input[..samples.len()].copy_from_slice(samples);
        let mut spectrum = fft.make_output_vec();
        fft.process(&mut input, &mut spectrum)
            .map_err(|e| Error::setting("auto_bands", format!("FFT failed: {e}")))?;
        for (p, c) in power.iter_mut().zip(&spectrum) {
            *p += c.norm_sqr() / energy;
        }
    }
    let bin_hz = fs_hz / n_fft as f64;
    let half = (SMOOTHING_RECORDS * fs_hz / longest as f64 / bin_hz / 2.0).round() as usize;
    let db = smoothed_db(&power, half);
    let k_lo = ((s.f_min_hz / bin_hz).ceil().max(1.0) as usize).min(db.len() - 1);
    let k_hi = ((s.f_max_hz / bin_hz).floor().min((db.len() - 2) as f64)) as usize;
    if k_hi <= k_lo {
        return Ok(Vec::new());
    }
    let range = &db[k_lo..=k_hi];
    let top = range.iter().cloned().fold(f64::MIN, f64::max);
    let mut peaks: Vec<SpectralPeak> = (1..range.len() - 1)
        .filter(|&i| range[i] > range[i - 1] && range[i] >= range[i + 1])
        .filter(|&i| range[i] >= top - s.threshold_db)
        .filter(|&i| prominence_db(range, i) >= PEAK_PROMINENCE_DB)
        .map(|i| {
            let (a, b, c) = (range[i - 1], range[i], range[i + 1]);
            let den = a - 2.0 * b + c;
            let p = if den < 0.0 { 0.5 * (a - c) / den } else { 0.0 };
            let f = (k_lo as f64 + i as f64 + p) * bin_hz;
            SpectralPeak {
                f_hz: f,
                level_db: b - 0.25 * (a - c) * p,
                half_power_hz: half_power_width(range, i) * bin_hz,
            }
        })
        .collect();
    // Largest first; drop peaks within a larger one's half-power width or min spacing.
    peaks.sort_by(|x, y| y.level_db.total_cmp(&x.level_db));
    let mut kept: Vec<SpectralPeak> = Vec::new();
    for p in peaks {
        if kept.len() >= s.max_peaks {
            break;
        }
        if kept
            .iter()
            .all(|q| (q.f_hz - p.f_hz).abs() >= s.min_spacing_hz.max(q.half_power_hz))
        {
            kept.push(p);
        }
    }
    kept.sort_by(|x, y| x.f_hz.total_cmp(&y.f_hz));
    Ok(kept)
}

/// 10 log10 of `power` averaged over ±`half` bins (fewer at the ends).
fn smoothed_db(power: &[f64], half: usize) -> Vec<f64> {
    let mut prefix = vec![0.0; power.len() + 1];
    for (k, p) in power.iter().enumerate() {
        prefix[k + 1] = prefix[k] + p;
    }
    (0..power.len())
        .map(|k| {
            let (a, b) = (k.saturating_sub(half), (k + half + 1).min(power.len()));
            10.0 * ((prefix[b] - prefix[a]) / (b - a) as f64)
                .max(1e-300)
                .log10()
        })
        .collect()
}

/// Height of peak `i` of `db` above the higher of its two bases (the lowest point between it and
/// the nearest higher value on each side, or the end).
fn prominence_db(db: &[f64], i: usize) -> f64 {
    let base = |it: &mut dyn Iterator<Item = usize>| {
        let mut low = db[i];
        for k in it {
            if db[k] > db[i] {
                break;
            }
            low = low.min(db[k]);
        }
        low
    };
    let left = base(&mut (0..i).rev());
    let right = base(&mut (i + 1..db.len()));
    db[i] - left.max(right)
}

/// Width, in bins, of peak `i` of `db` where it is 3 dB down on both sides.
fn half_power_width(db: &[f64], i: usize) -> f64 {
    let level = db[i] - 3.0;
    let left = (0..i).rev().find(|&k| db[k] < level).unwrap_or(0);
    let right = (i + 1..db.len())
        .find(|&k| db[k] < level)
        .unwrap_or(db.len() - 1);
    (right - left) as f64
}

/// `--bands auto`: bands around the spectral peaks of `channels` (each from its onset; see
/// [`spectral_peaks_multi`] and [`bands_around_modes`]), each at least `min_width_hz` wide so
/// that a buffering bank's transient cut leaves enough of the record, and at least
/// [`HALF_POWER_WIDTHS_PER_BAND`] half-power widths of its peak where the neighbours leave
/// room (both override `max_width_hz`). Errors when no peak is found.
pub fn auto_bands(channels: &[&[f64]], fs_hz: f64, s: &AutoBandSettings) -> Result<Vec<Band>> {
    let found = spectral_peaks_multi(channels, fs_hz, s)?;
    let peaks: Vec<f64> = found.iter().map(|p| p.f_hz).collect();
    if peaks.is_empty() {
        return Err(Error::setting(
            "auto_bands",
            format!(
                "expected at least one spectral peak between {} and {} Hz, found none",
                s.f_min_hz, s.f_max_hz
            ),
        ));
    }
    let nyquist = 0.5 * fs_hz;
    let mut bands = bands_around_modes(&peaks, s.max_width_hz)?;
    // Halfway to the neighbours without the cap: how far a band may grow for its peak.
    let halfway = bands_around_modes(&peaks, fs_hz)?;
    for ((b, p), free) in bands.iter_mut().zip(&found).zip(&halfway) {
        let for_peak = (HALF_POWER_WIDTHS_PER_BAND * p.half_power_hz).min(free.width_hz());
        if for_peak > b.width_hz() {
            let grow = 0.5 * (for_peak - b.width_hz());
            b.lo_hz = (b.lo_hz - grow).max(free.lo_hz);
            b.hi_hz = (b.hi_hz + grow).min(free.hi_hz);
        }
        // The transient cut's minimum overrides the neighbours (the record allows no less).
        let missing = s.min_width_hz - b.width_hz();
        if missing > 0.0 {
            b.lo_hz = (b.lo_hz - 0.5 * missing).max(0.5 * b.lo_hz);
            b.hi_hz += 0.5 * missing;
        }
        // Filter designs need their upper edge below Nyquist.
        b.hi_hz = b.hi_hz.min(NYQUIST_MARGIN * nyquist);
    }
    bands.retain(|b| b.lo_hz < b.hi_hz && b.center_hz < b.hi_hz);
    Ok(bands)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_reach_halfway_and_respect_the_cap() {
        let b = bands_around_modes(&[230.0, 170.0, 200.0], 100.0).unwrap();
        let edges: Vec<(f64, f64)> = b.iter().map(|b| (b.lo_hz, b.hi_hz)).collect();
        assert_eq!(edges, vec![(155.0, 185.0), (185.0, 215.0), (215.0, 245.0)]);
        assert_eq!(b[1].center_hz, 200.0);
        let b = bands_around_modes(&[100.0, 400.0], 40.0).unwrap();
        assert_eq!((b[0].lo_hz, b[0].hi_hz), (80.0, 120.0));
        let b = bands_around_modes(&[50.0], 30.0).unwrap();
        assert_eq!((b[0].lo_hz, b[0].hi_hz), (35.0, 65.0));
        assert!(bands_around_modes(&[f64::NAN], 30.0).is_err());
    }

    #[test]
    fn finds_the_modes_of_a_three_mode_decay() {
        let fs = 4000.0;
        let x: Vec<f64> = (0..8000)
            .map(|i| {
                let t = i as f64 / fs;
                [170.0, 200.0, 230.0]
                    .iter()
                    .map(|&f: &f64| {
                        let w = 2.0 * std::f64::consts::PI * f;
                        (-0.025 * w * t).exp() * (w * t).sin()
                    })
                    .sum()
            })
            .collect();
        let p = spectral_peaks(&x, fs, &AutoBandSettings::default()).unwrap();
        assert_eq!(p.len(), 3, "{p:?}");
        for (got, want) in p.iter().zip([170.0, 200.0, 230.0]) {
            assert!((got - want).abs() < 1.5, "{got} vs {want}");
        }
    }
}

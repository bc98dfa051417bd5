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

/// Peak frequencies (Hz, ascending) of the magnitude spectrum of `samples`: local maxima of the
/// zero-padded FFT within the range and threshold, refined by parabolic interpolation of the
/// dB magnitude over the three bins around each maximum.
pub fn spectral_peaks(samples: &[f64], fs_hz: f64, s: &AutoBandSettings) -> Result<Vec<f64>> {
    if !(fs_hz.is_finite() && fs_hz > 0.0) {
        return Err(Error::setting(
            "fs",
            format!("expected a positive sample rate in Hz, got {fs_hz}"),
        ));
    }
    if samples.len() < 4 || samples.iter().any(|x| !x.is_finite()) {
        return Err(Error::setting(
            "--bands auto",
            format!(
                "expected at least 4 finite samples to find modes, got {} samples",
                samples.len()
            ),
        ));
    }
    if !(s.zero_pad >= 1 && s.zero_pad <= 64 && s.threshold_db >= 0.0 && s.min_spacing_hz >= 0.0) {
        return Err(Error::setting(
            "--bands auto",
            "expected zero_pad 1…64, threshold_db >= 0 and min_spacing_hz >= 0",
        ));
    }
    let n_fft = samples.len().next_power_of_two() * s.zero_pad;
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n_fft);
    let mut input = fft.make_input_vec();
    input[..samples.len()].copy_from_slice(samples);
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut input, &mut spectrum)
        .map_err(|e| Error::setting("--bands auto", format!("FFT failed: {e}")))?;
    let bin_hz = fs_hz / n_fft as f64;
    let db: Vec<f64> = spectrum
        .iter()
        .map(|c| 10.0 * c.norm_sqr().max(1e-300).log10())
        .collect();
    let k_lo = ((s.f_min_hz / bin_hz).ceil().max(1.0) as usize).min(db.len() - 1);
    let k_hi = ((s.f_max_hz / bin_hz).floor().min((db.len() - 2) as f64)) as usize;
    if k_hi <= k_lo {
        return Ok(Vec::new());
    }
    let top = db[k_lo..=k_hi].iter().cloned().fold(f64::MIN, f64::max);
    let mut peaks: Vec<(f64, f64)> = (k_lo..=k_hi)
        .filter(|&k| db[k] > db[k - 1] && db[k] >= db[k + 1] && db[k] >= top - s.threshold_db)
        .map(|k| {
            let (a, b, c) = (db[k - 1], db[k], db[k + 1]);
            let den = a - 2.0 * b + c;
            let p = if den < 0.0 { 0.5 * (a - c) / den } else { 0.0 };
            ((k as f64 + p) * bin_hz, b - 0.25 * (a - c) * p)
        })
        .collect();
    // Largest first; drop peaks too close to a larger one; keep at most max_peaks.
    peaks.sort_by(|x, y| y.1.total_cmp(&x.1));
    let mut kept: Vec<(f64, f64)> = Vec::new();
    for p in peaks {
        if kept.len() >= s.max_peaks {
            break;
        }
        if kept.iter().all(|q| (q.0 - p.0).abs() >= s.min_spacing_hz) {
            kept.push(p);
        }
    }
    let mut f: Vec<f64> = kept.into_iter().map(|p| p.0).collect();
    f.sort_by(f64::total_cmp);
    Ok(f)
}

/// `--bands auto`: bands around the spectral peaks of `samples` (see [`spectral_peaks`] and
/// [`bands_around_modes`]). Errors when no peak is found.
pub fn auto_bands(samples: &[f64], fs_hz: f64, s: &AutoBandSettings) -> Result<Vec<Band>> {
    let peaks = spectral_peaks(samples, fs_hz, s)?;
    if peaks.is_empty() {
        return Err(Error::setting(
            "--bands auto",
            format!(
                "expected at least one spectral peak between {} and {} Hz, found none",
                s.f_min_hz, s.f_max_hz
            ),
        ));
    }
    let nyquist = 0.5 * fs_hz;
    let mut bands = bands_around_modes(&peaks, s.max_width_hz)?;
    for b in &mut bands {
        b.hi_hz = b.hi_hz.min(nyquist);
    }
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

//! Measured frequency response functions (FRFs) turned into impulse responses, the decays the
//! rest of dampscope analyses.
//!
//! The transform is the report's (eq. 3.1, `crate::sim::impulse`): an inverse real FFT over
//! the one-sided grid 0, df, …, fmax gives h(t) at fs = 2·fmax, 1/df seconds long; the
//! imaginary parts of the DC and fmax bins are dropped (a real signal's spectrum is real
//! there). What [`FrfToImpulse`] adds, and [`ImpulseSet::notes`] reports:
//!
//! - **A grid not starting at 0 Hz** (f_min = m·df): the m bins below f_min are set to zero.
//!   Bands below f_min then hold no energy, and the step at f_min rings in h(t) at f_min.
//! - **Band-limit taper** (`taper_fraction`, default 0 = none): a half-cosine over the top
//!   fraction of the band, 1 at its start and 0 at fmax. Default none because the cut at fmax
//!   only rings at fmax = fs/2, above every analysis band (the crate's bands stop at 0.4·fs), and
//!   a taper changes amplitudes inside its range. Use it when the FRF is large at fmax (a mode
//!   or a rising accelerance there), whose ringing would otherwise leak into the top bands.
//!   What it does to D: multiplying H(f) by a smooth W(f) convolves h(t) with a kernel about
//!   1/(taper width) long; a decaying mode keeps its decay rate through a convolution, so D of
//!   modes below the taper is untouched and D of modes inside it changes by less than the
//!   taper's slope across the mode's half-power bandwidth (tested in `uff_format`).
//! - **Exponential window** (`exponential_window_tau_s`): h(t)·e^(−t/τ). It makes a response
//!   that has not died out within 1/df decay before the FFT's wrap-around, at the price of an
//!   added decay rate σ_win = 1/τ: every measured D grows by σ_win/(2πf). The set reports the
//!   total window (this one and one the test system applied, [`FrfSet::exponential_window_tau_s`])
//!   so that the analysis subtracts it ([`ImpulseSet::corrected_damping`], or
//!   `ModalSettings::exponential_window_tau_s`, which `dampscope modal` fills from meta.json).
//!
//! Inputs: CSV ([`parse_frf_csv`]) and universal files ([`measurement_from_uff`], in
//! `crate::uff::import`, re-exported here).

use std::f64::consts::{PI, TAU};

use realfft::num_complex::Complex;

pub use super::frf_csv::{is_frf_csv_header, parse_frf_csv, read_frf_csv};
use super::memory::MemorySource;
use super::{SignalInfo, SourceError};
use crate::sim::impulse::{impulse_response, uniform_grid};
pub use crate::uff::import::{measurement_from_uff, read_frf_uff, UffMeasurement};
use crate::{Error, Result};

/// One measured FRF: a response DOF over a reference DOF.
#[derive(Clone, Debug, PartialEq)]
pub struct FrfChannel {
    /// Channel id (the sensor id a recording set's `sensors.csv` uses).
    pub id: String,
    /// H at each frequency of [`FrfSet::freq_hz`].
    pub values: Vec<Complex<f64>>,
    /// Response node, when the file names one.
    pub response_node: Option<i64>,
    /// Response direction (UFF code: 3 = +Z), when known.
    pub response_dir: Option<i64>,
    /// Reference (excitation) node.
    pub reference_node: Option<i64>,
    /// Reference direction.
    pub reference_dir: Option<i64>,
    /// Measured quantity (`acceleration`, …), informative.
    pub quantity: Option<String>,
    /// Unit of H (`m/s^2/N`, …), informative.
    pub unit: Option<String>,
}

impl FrfChannel {
    /// A channel with only an id and values.
    pub fn new(id: impl Into<String>, values: Vec<Complex<f64>>) -> Self {
        FrfChannel {
            id: id.into(),
            values,
            response_node: None,
            response_dir: None,
            reference_node: None,
            reference_dir: None,
            quantity: None,
            unit: None,
        }
    }
}

/// FRFs on one common, evenly spaced frequency grid.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrfSet {
    /// The frequencies, Hz: f_min + k·df.
    pub freq_hz: Vec<f64>,
    /// One FRF per channel.
    pub channels: Vec<FrfChannel>,
    /// τ of an exponential window e^(−t/τ) the test system already applied to the responses
    /// before computing the FRFs, s (declared by the file; see [`parse_frf_csv`],
    /// [`measurement_from_uff`]). Its decay rate is reported so that D is corrected.
    pub exponential_window_tau_s: Option<f64>,
}

/// How [`FrfSet::impulse_responses`] turns FRFs into impulse responses (module note).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrfToImpulse {
    /// Half-cosine taper over this top fraction of 0…fmax (0 = none, at most 1).
    pub taper_fraction: f64,
    /// Exponential window e^(−t/τ) applied to h(t), τ in s (`None` = none).
    pub exponential_window_tau_s: Option<f64>,
}

/// Impulse responses, one per channel, with what was done to get them.
#[derive(Clone, Debug, PartialEq)]
pub struct ImpulseSet {
    /// Sample rate, Hz (2·fmax for FRFs; 1/Δt for time responses).
    pub sample_rate_hz: f64,
    /// Channel ids.
    pub names: Vec<String>,
    /// One response per channel, equal lengths.
    pub channels: Vec<Vec<f64>>,
    /// τ of the total exponential window on these responses (the test system's and the one
    /// applied here combined: 1/τ = 1/τ₁ + 1/τ₂), s; `None` when there is none.
    pub exponential_window_tau_s: Option<f64>,
    /// What was done, one sentence each (grid, padding, taper, windows, wrap-around).
    pub notes: Vec<String>,
}

impl ImpulseSet {
    /// The decay rate σ_win = 1/τ the windows added, 1/s (0 without a window).
    pub fn window_decay_per_s(&self) -> f64 {
        self.exponential_window_tau_s.map_or(0.0, |t| 1.0 / t)
    }

    /// A damping ratio measured on these responses at `frequency_hz` with the windows' added
    /// damping removed: D − σ_win/(2πf) (use the decay's dominant frequency).
    pub fn corrected_damping(&self, damping_ratio: f64, frequency_hz: f64) -> f64 {
        damping_ratio - self.window_decay_per_s() / (TAU * frequency_hz)
    }

    /// The responses as a [`super::Source`] for the streaming pipeline.
    pub fn into_source(self) -> Result<MemorySource, SourceError> {
        let info = SignalInfo {
            sample_rate_hz: self.sample_rate_hz,
            channel_names: self.names,
        };
        MemorySource::new(info, self.channels)
    }
}

fn setting(name: &str, reason: impl Into<String>) -> Error {
    Error::setting(name, reason)
}

fn check_tau(name: &str, tau: Option<f64>) -> Result<()> {
    match tau {
        Some(t) if !(t.is_finite() && t > 0.0) => {
            Err(setting(name, format!("expected a finite τ > 0 s, got {t}")))
        }
        _ => Ok(()),
    }
}

/// Multiplies `x` (sampled at `fs`) by e^(−t/τ).
pub(crate) fn exponential_window(x: &mut [f64], fs: f64, tau_s: f64) {
    for (i, v) in x.iter_mut().enumerate() {
        *v *= (-(i as f64) / (fs * tau_s)).exp();
    }
}

/// 1/τ of two windows applied one after the other.
pub(crate) fn combined_tau(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    let rate = a.map_or(0.0, |t| 1.0 / t) + b.map_or(0.0, |t| 1.0 / t);
    (rate > 0.0).then(|| 1.0 / rate)
}

impl FrfSet {
    /// Impulse responses of every channel (module note: grid, padding, taper, windows).
    /// Errors: no channels, lengths that differ from the grid, non-finite values, a grid that
    /// is not even or does not start at a multiple of its spacing, options out of range.
    pub fn impulse_responses(&self, options: &FrfToImpulse) -> Result<ImpulseSet> {
        let n = self.freq_hz.len();
        if self.channels.is_empty() || n < 2 {
            return Err(setting(
                "FRF set",
                format!(
                    "expected at least one channel over at least 2 frequencies, got {} over {n}",
                    self.channels.len()
                ),
            ));
        }
        if !(0.0..=1.0).contains(&options.taper_fraction) {
            return Err(setting(
                "taper fraction",
                format!("expected 0 … 1, got {}", options.taper_fraction),
            ));
        }
        check_tau(
            "exponential window time constant",
            options.exponential_window_tau_s,
        )?;
        check_tau(
            "measured FRFs' window time constant",
            self.exponential_window_tau_s,
        )?;
        let (f0, f_last) = (self.freq_hz[0], self.freq_hz[n - 1]);
        let df = (f_last - f0) / (n - 1) as f64;
        let bad_grid = |k: usize, why: String| {
            setting(
                "FRF frequency grid",
                format!("frequency #{} ({} Hz): {why}", k + 1, self.freq_hz[k]),
            )
        };
        if !(df > 0.0 && f0 >= 0.0 && f0.is_finite() && f_last.is_finite()) {
            return Err(bad_grid(
                0,
                format!("expected f_min ≥ 0 and rising, f_max = {f_last}"),
            ));
        }
        if let Some(k) =
            (0..n).find(|&k| (self.freq_hz[k] - (f0 + k as f64 * df)).abs() > 1e-4 * df)
        {
            return Err(bad_grid(
                k,
                format!("expected the even grid f_min + k·{df} Hz"),
            ));
        }
        let m = f0 / df;
        if (m - m.round()).abs() > 1e-4 {
            return Err(bad_grid(
                0,
                format!(
                    "f_min is not a multiple of df = {df} Hz, so zeros cannot pad the grid to 0 Hz"
                ),
            ));
        }
        let pad = m.round() as usize;
        let full = pad + n;
        if full > 1 << 26 {
            return Err(setting(
                "FRF frequency grid",
                format!("{full} bins from 0 Hz: too many"),
            ));
        }
        let grid: Vec<f64> = (0..full).map(|k| k as f64 * df).collect();
        let (df, fmax) =
            uniform_grid(&grid).map_err(|e| setting("FRF frequency grid", e.to_string()))?;
        let fs = 2.0 * fmax;
        let len = 2 * (full - 1);
        let mut notes = vec![format!(
            "inverse real FFT of {full} bins 0…{fmax} Hz (df = {df} Hz): fs = {fs} Hz, \
             {len} samples ({} s); imaginary parts at 0 Hz and fmax dropped",
            1.0 / df
        )];
        if pad > 0 {
            notes.push(format!("{pad} bins below f_min = {f0} Hz set to zero"));
        }
        let taper_start = fmax * (1.0 - options.taper_fraction);
        if options.taper_fraction > 0.0 {
            notes.push(format!(
                "half-cosine taper from {taper_start} Hz to 0 at {fmax} Hz"
            ));
        }
        let window = options.exponential_window_tau_s;
        if let Some(t) = window {
            notes.push(format!(
                "exponential window τ = {t} s applied: adds {} 1/s of decay rate",
                1.0 / t
            ));
        }
        if let Some(t) = self.exponential_window_tau_s {
            notes.push(format!(
                "the FRFs were already windowed (τ = {t} s): adds {} 1/s",
                1.0 / t
            ));
        }
        let mut channels = Vec::with_capacity(self.channels.len());
        for c in &self.channels {
            if c.values.len() != n {
                return Err(setting(
                    &format!("FRF channel {}", c.id),
                    format!(
                        "expected {n} values (one per frequency), got {}",
                        c.values.len()
                    ),
                ));
            }
            if let Some(k) = c
                .values
                .iter()
                .position(|z| !(z.re.is_finite() && z.im.is_finite()))
            {
                return Err(setting(
                    &format!("FRF channel {}", c.id),
                    format!("value #{} at {} Hz is not finite", k + 1, self.freq_hz[k]),
                ));
            }
            let mut h = vec![Complex::new(0.0, 0.0); pad];
            h.extend_from_slice(&c.values);
            if options.taper_fraction > 0.0 {
                for (k, z) in h.iter_mut().enumerate() {
                    let f = k as f64 * df;
                    if f > taper_start {
                        *z *= 0.5 * (1.0 + (PI * (f - taper_start) / (fmax - taper_start)).cos());
                    }
                }
            }
            let mut x = impulse_response(&h, fmax)
                .map_err(|e| setting(&format!("FRF channel {}", c.id), e.to_string()))?;
            if let Some(t) = window {
                exponential_window(&mut x, fs, t);
            }
            if let Some(note) = wraparound(&c.id, &x) {
                notes.push(note);
            }
            channels.push(x);
        }
        Ok(ImpulseSet {
            sample_rate_hz: fs,
            names: self.channels.iter().map(|c| c.id.clone()).collect(),
            channels,
            exponential_window_tau_s: combined_tau(self.exponential_window_tau_s, window),
            notes,
        })
    }
}

/// A note when the last tenth of a response holds more than −40 dB of its peak: it has not
/// died out within 1/df, and the circular IFFT folded its tail onto its start.
fn wraparound(id: &str, x: &[f64]) -> Option<String> {
    let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let tail = x[x.len() - x.len() / 10..]
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    (peak > 0.0 && tail > 0.01 * peak).then(|| {
        format!(
            "channel {id}: the response is still at {:.0} dB of its peak in its last tenth \
             (wrap-around); an exponential window would end it",
            20.0 * (tail / peak).log10()
        )
    })
}

pub(crate) fn malformed(what: &str, format: &'static str, detail: String) -> Error {
    Error::Source(SourceError::Malformed {
        what: what.to_string(),
        format,
        detail,
    })
}

/// Reads the `exponential_window_tau_s` a text declares as `exponential_window_tau_s=0.5` (or
/// `: 0.5`), e.g. in a CSV comment or a UFF ID line.
pub(crate) fn declared_tau(text: &str) -> Option<std::result::Result<f64, String>> {
    let key = "exponential_window_tau_s";
    let rest = &text[text.find(key)? + key.len()..];
    let rest = rest
        .trim_start()
        .trim_start_matches(['=', ':'])
        .trim_start();
    let num: String = rest
        .chars()
        .take_while(|c| c.is_ascii_digit() || "+-.eE".contains(*c))
        .collect();
    Some(
        num.parse::<f64>()
            .ok()
            .filter(|t| t.is_finite() && *t > 0.0)
            .ok_or(num),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_in_all_three_forms_and_a_declared_window() {
        let text = "# exponential_window_tau_s = 0.25\nfreq_hz, a_re, a_im, b_db, b_deg, c_mag, c_deg\n0, 1, 0, 0, 90, 2, 180\n1, 0.5, -0.5, 20, -90, 3, 0\n";
        let s = parse_frf_csv(text, "t.csv").unwrap();
        assert_eq!(s.freq_hz, vec![0.0, 1.0]);
        assert_eq!(s.exponential_window_tau_s, Some(0.25));
        let ids: Vec<&str> = s.channels.iter().map(|c| c.id.as_str()).collect();
        assert_eq!(ids, ["a", "b", "c"]);
        assert_eq!(s.channels[0].values[1], Complex::new(0.5, -0.5));
        let b = s.channels[1].values[1];
        assert!((b - Complex::new(0.0, -10.0)).norm() < 1e-12, "{b}");
        let c = s.channels[2].values[0];
        assert!((c - Complex::new(-2.0, 0.0)).norm() < 1e-12, "{c}");
    }

    #[test]
    fn csv_errors_name_column_and_row() {
        let e = parse_frf_csv("f,a_re,a_im\n0,1,0\n1,x,0\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("column 2") && e.contains("row 2") && e.contains("\"x\""),
            "{e}"
        );
        let e = parse_frf_csv("time,a_re,a_im\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("column 1"), "{e}");
        let e = parse_frf_csv("f,a_re,a_deg\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("sensor \"a\""), "{e}");
        let e = parse_frf_csv("f,a_re,a_im,a_re\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("column 4"), "{e}");
        let e = parse_frf_csv("f,a_phase\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("suffix"), "{e}");
        let e = parse_frf_csv("# exponential_window_tau_s=-1\nf,a_re,a_im\n", "t")
            .unwrap_err()
            .to_string();
        assert!(e.contains("exponential_window_tau_s"), "{e}");
    }

    fn one_mode(freq_hz: &[f64]) -> FrfSet {
        let (fn_hz, zeta) = (50.0, 0.02);
        let values = freq_hz
            .iter()
            .map(|&f| {
                Complex::new(1.0, 0.0) / Complex::new(fn_hz * fn_hz - f * f, 2.0 * zeta * f * fn_hz)
            })
            .collect();
        FrfSet {
            freq_hz: freq_hz.to_vec(),
            channels: vec![FrfChannel::new("s", values)],
            exponential_window_tau_s: None,
        }
    }

    #[test]
    fn a_grid_above_0_hz_is_zero_padded_and_equals_the_padded_grid() {
        let df = 0.5;
        let full: Vec<f64> = (0..801).map(|k| k as f64 * df).collect();
        let mut padded = one_mode(&full);
        let cut = one_mode(&full[20..]);
        padded.channels[0].values[..20]
            .iter_mut()
            .for_each(|z| *z = Complex::new(0.0, 0.0));
        let a = padded.impulse_responses(&FrfToImpulse::default()).unwrap();
        let b = cut.impulse_responses(&FrfToImpulse::default()).unwrap();
        assert_eq!(a.channels, b.channels);
        assert_eq!(b.sample_rate_hz, 800.0);
        assert!(
            b.notes
                .iter()
                .any(|n| n.contains("20 bins below f_min = 10 Hz")),
            "{:?}",
            b.notes
        );
        let odd = one_mode(&full[20..].iter().map(|f| f + 0.2).collect::<Vec<_>>());
        let e = odd
            .impulse_responses(&FrfToImpulse::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a multiple"), "{e}");
    }

    #[test]
    fn windows_combine_and_the_correction_removes_their_rate() {
        let full: Vec<f64> = (0..801).map(|k| k as f64 * 0.5).collect();
        let mut s = one_mode(&full);
        s.exponential_window_tau_s = Some(0.5);
        let plain = one_mode(&full)
            .impulse_responses(&FrfToImpulse::default())
            .unwrap();
        let opts = FrfToImpulse {
            exponential_window_tau_s: Some(0.5),
            ..Default::default()
        };
        let w = s.impulse_responses(&opts).unwrap();
        assert_eq!(w.exponential_window_tau_s, Some(0.25));
        assert_eq!(w.window_decay_per_s(), 4.0);
        let i = 400;
        let expect = plain.channels[0][i] * (-(i as f64) / (800.0 * 0.5)).exp();
        assert!(
            (w.channels[0][i] - expect).abs() < 1e-15,
            "{} vs {expect}",
            w.channels[0][i]
        );
        assert!((w.corrected_damping(0.03, 50.0) - (0.03 - 4.0 / (TAU * 50.0))).abs() < 1e-15);
        let bad = FrfToImpulse {
            taper_fraction: 1.5,
            ..Default::default()
        };
        assert!(s.impulse_responses(&bad).is_err());
    }
}

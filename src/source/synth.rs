//! Synthetic decays: the report's eq. 4.5, a sum of exponentially decaying sines
//!
//! ```text
//! x(t) = Σ_i A_i · exp(−D_i · 2π f_i · t) · sin(2π f_i t − ψ_i)
//! ```
//!
//! sampled at t = n / fs, n = 0 … N−1 with N = round(duration · fs), optionally plus seeded white
//! Gaussian noise. The SNR is a peak SNR (as pyrato's `psnr`): noise rms
//! σ = max_n |x(n / fs)| · 10^(−snr_db / 20), where the maximum is the exact maximum of the clean
//! sampled signal over the whole duration. It is found by a streaming pre-pass that stops as soon
//! as the envelope bound Σ|A_i| exp(−D_i 2π f_i t) falls below the running maximum (no later
//! sample can exceed it), so it is cheap for decays and needs no memory.

use std::str::FromStr;

use super::noise::GaussianNoise;
use super::{Block, SignalInfo, Source, SourceError};

/// One decaying sine of eq. 4.5.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Mode {
    /// Frequency f_i in Hz.
    pub frequency_hz: f64,
    /// Critical damping ratio D_i (0.025 = 2.5 %).
    pub damping_ratio: f64,
    /// Amplitude A_i.
    pub amplitude: f64,
    /// Phase ψ_i in degrees (subtracted: sin(2π f t − ψ)).
    pub phase_deg: f64,
}

impl Mode {
    /// A mode at `frequency_hz` with damping ratio `damping_ratio`, amplitude and phase ψ (deg).
    pub fn new(frequency_hz: f64, damping_ratio: f64, amplitude: f64, phase_deg: f64) -> Self {
        Mode {
            frequency_hz,
            damping_ratio,
            amplitude,
            phase_deg,
        }
    }

    /// Value of this mode at time `t_s` seconds.
    pub fn value(&self, t_s: f64) -> f64 {
        let w = std::f64::consts::TAU * self.frequency_hz;
        self.amplitude
            * (-self.damping_ratio * w * t_s).exp()
            * (w * t_s - self.phase_deg.to_radians()).sin()
    }

    /// Upper bound of |value| at and after `t_s`: the envelope |A| exp(−D 2π f t).
    fn envelope(&self, t_s: f64) -> f64 {
        self.amplitude.abs()
            * (-self.damping_ratio * std::f64::consts::TAU * self.frequency_hz * t_s).exp()
    }
}

impl FromStr for Mode {
    type Err = String;

    /// Parses `F:D[:A[:PSI]]` (Hz, ratio, amplitude, degrees; A = 1 and ψ = 0 by default).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parts: Vec<&str> = s.split(':').map(str::trim).collect();
        if !(2..=4).contains(&parts.len()) {
            return Err(format!(
                "mode: expected F:D[:A[:PSI]] (e.g. 200:0.025 or 230:0.025:1:0), got {s:?}"
            ));
        }
        let names = [
            "frequency F (Hz)",
            "damping ratio D",
            "amplitude A",
            "phase PSI (deg)",
        ];
        let mut v = [0.0, 0.0, 1.0, 0.0];
        for (k, p) in parts.iter().enumerate() {
            v[k] = p
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    format!(
                        "mode {s:?}: {} must be a finite number, got {p:?}",
                        names[k]
                    )
                })?;
        }
        let m = Mode {
            frequency_hz: v[0],
            damping_ratio: v[1],
            amplitude: v[2],
            phase_deg: v[3],
        };
        m.check().map_err(|e| format!("mode {s:?}: {e}"))?;
        Ok(m)
    }
}

impl Mode {
    fn check(&self) -> Result<(), String> {
        if !(self.frequency_hz.is_finite() && self.frequency_hz > 0.0) {
            return Err(format!(
                "frequency must be > 0 Hz, got {}",
                self.frequency_hz
            ));
        }
        if !(self.damping_ratio.is_finite() && self.damping_ratio >= 0.0) {
            return Err(format!(
                "damping ratio must be >= 0, got {}",
                self.damping_ratio
            ));
        }
        if !self.amplitude.is_finite() || !self.phase_deg.is_finite() {
            return Err(format!(
                "amplitude and phase must be finite, got {} and {}",
                self.amplitude, self.phase_deg
            ));
        }
        Ok(())
    }
}

/// Everything that defines a synthetic decay.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SynthSpec {
    /// The decaying sines.
    pub modes: Vec<Mode>,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Length, seconds (N = round(duration · fs) samples).
    pub duration_s: f64,
    /// Peak SNR of the added white noise in dB; `None` = no noise.
    pub snr_db: Option<f64>,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl SynthSpec {
    /// Number of samples: round(duration · fs).
    pub fn n_samples(&self) -> u64 {
        let n = (self.duration_s * self.sample_rate_hz).round();
        if n.is_finite() && n > 0.0 {
            n as u64
        } else {
            0
        }
    }

    /// Checks that the spec describes a real signal; a `Setting` error says what is wrong.
    pub fn validate(&self) -> Result<(), SourceError> {
        let err = |detail: String| SourceError::Setting {
            what: "synth".into(),
            detail,
        };
        if self.modes.is_empty() {
            return Err(err("expected at least one mode, got none".into()));
        }
        for (k, m) in self.modes.iter().enumerate() {
            m.check().map_err(|e| err(format!("mode {}: {e}", k + 1)))?;
        }
        if !(self.sample_rate_hz.is_finite() && self.sample_rate_hz > 0.0) {
            return Err(err(format!(
                "sample rate must be > 0 Hz, got {}",
                self.sample_rate_hz
            )));
        }
        if !(self.duration_s.is_finite() && self.duration_s > 0.0) || self.n_samples() == 0 {
            return Err(err(format!(
                "duration must give at least one sample, got {} s at {} Hz",
                self.duration_s, self.sample_rate_hz
            )));
        }
        if let Some(snr) = self.snr_db {
            if !snr.is_finite() {
                return Err(err(format!("SNR must be finite dB, got {snr}")));
            }
        }
        Ok(())
    }

    /// Clean (noise-free) sample n.
    pub fn clean_sample(&self, n: u64) -> f64 {
        let t = n as f64 / self.sample_rate_hz;
        self.modes.iter().map(|m| m.value(t)).sum()
    }

    /// Exact max |x| of the clean sampled signal (see the module documentation).
    pub fn peak(&self) -> f64 {
        let mut peak = 0f64;
        for n in 0..self.n_samples() {
            let t = n as f64 / self.sample_rate_hz;
            // Check the bound every 64 samples: it only decreases with t.
            if n % 64 == 0 && self.modes.iter().map(|m| m.envelope(t)).sum::<f64>() <= peak {
                break;
            }
            peak = peak.max(self.clean_sample(n).abs());
        }
        peak
    }

    /// Noise rms for the requested peak SNR (0 without noise): max|x| · 10^(−snr/20).
    pub fn noise_rms(&self) -> f64 {
        self.snr_db
            .map_or(0.0, |snr| self.peak() * 10f64.powf(-snr / 20.0))
    }
}

/// The whole signal at once (tests and small demos). Call [`SynthSpec::validate`] first on user
/// input; an invalid spec yields no samples or non-finite ones, never a panic.
pub fn synthesize(spec: &SynthSpec) -> Vec<f64> {
    let mut src = SynthSource::unchecked(spec.clone());
    let mut out = Vec::with_capacity(spec.n_samples().min(1 << 26) as usize);
    let mut block = Block::default();
    while let Ok(true) = src.read_block(1 << 16, &mut block) {
        out.extend_from_slice(&block.channels[0]);
    }
    out
}

/// Eq. 4.5 without noise, `duration_s` at `fs_hz`: the decay every synthetic study starts from.
pub fn decaying_sines(modes: &[Mode], fs_hz: f64, duration_s: f64) -> Vec<f64> {
    synthesize(&SynthSpec {
        modes: modes.to_vec(),
        sample_rate_hz: fs_hz,
        duration_s,
        snr_db: None,
        seed: 0,
    })
}

/// A one-channel [`Source`] (`ch0`) generating eq. 4.5 block by block.
pub struct SynthSource {
    spec: SynthSpec,
    info: SignalInfo,
    next: u64,
    total: u64,
    noise_rms: f64,
    noise: GaussianNoise,
}

impl SynthSource {
    /// A source for `spec`, validated first.
    pub fn new(spec: SynthSpec) -> Result<Self, SourceError> {
        spec.validate()?;
        Ok(Self::unchecked(spec))
    }

    fn unchecked(spec: SynthSpec) -> Self {
        Self {
            info: SignalInfo {
                sample_rate_hz: spec.sample_rate_hz,
                channel_names: vec!["ch0".into()],
            },
            next: 0,
            total: spec.n_samples(),
            noise_rms: spec.noise_rms(),
            noise: GaussianNoise::new(spec.seed),
            spec,
        }
    }

    /// Total number of samples this source yields.
    pub fn n_samples(&self) -> u64 {
        self.total
    }

    /// The noise rms actually used (0 without noise).
    pub fn noise_rms(&self) -> f64 {
        self.noise_rms
    }
}

impl Source for SynthSource {
    fn info(&self) -> &SignalInfo {
        &self.info
    }

    fn read_block(&mut self, max_frames: usize, block: &mut Block) -> Result<bool, SourceError> {
        block.channels.resize_with(1, Vec::new);
        let ch = &mut block.channels[0];
        ch.clear();
        let n = (self.total - self.next).min(max_frames.max(1) as u64);
        if n == 0 {
            return Ok(false);
        }
        ch.reserve(n as usize);
        for k in self.next..self.next + n {
            let mut x = self.spec.clean_sample(k);
            if self.noise_rms > 0.0 {
                x += self.noise_rms * self.noise.next_gaussian();
            }
            ch.push(x);
        }
        self.next += n;
        Ok(true)
    }
}

//! Multichannel modal identification: every mode's frequency, damping and shape from all sensors
//! at once (issue 8).
//!
//! Per-channel decay fits need a clean decay at every sensor; a joint fit does not, because the
//! channels' energies add. The chain, per sub-band of the analysis range:
//!
//! ```text
//! channels ──▶ baseband (heterodyne, reversed low-pass, decimate) ──▶ compress channels (SVD)
//!          ──▶ block-Hankel SVD, shift invariance at every order ──▶ stabilisation diagram
//!          ──▶ clusters of stable poles = modes ──▶ residues on all channels (shapes, MPC)
//! ```
//!
//! The entry point is [`identify`]; it returns plain data ([`ModalResult`]).

pub mod baseband;
pub mod refine;
pub mod shapes;
pub mod stabilise;
pub mod subspace;

use faer::c64;

pub use baseband::SubBandPlan;
use baseband::{plan_subbands, to_baseband, SubBand};
use stabilise::{classify, select_modes, PoleClass, StabilityCriteria};
use subspace::{compress, poles_by_order, HankelPlan};

/// Default sub-band layout (see [`SubBandPlan`]): 10–40 Hz wide, 40 % of the lower edge, guards
/// of a quarter of the width.
pub const DEFAULT_SUBBANDS: SubBandPlan = SubBandPlan {
    min_width_hz: 10.0,
    max_width_hz: 40.0,
    relative_width: 0.4,
    guard_fraction: 0.25,
};
/// Default highest model order (complex poles per sub-band).
pub const DEFAULT_MAX_ORDER: usize = 40;
/// Default lowest model order of the sweep.
pub const DEFAULT_MIN_ORDER: usize = 2;
/// Default number of principal components the channels are compressed to.
pub const DEFAULT_COMPRESSED_CHANNELS: usize = 32;

/// Multichannel recordings of one test: impulse responses or free decays, one per sensor, all
/// starting at the same instant.
#[derive(Clone, Debug)]
pub struct Recordings {
    /// Sample rate, Hz.
    pub fs_hz: f64,
    /// Channel names (sensor ids).
    pub names: Vec<String>,
    /// Samples, one vector per channel, equal lengths.
    pub channels: Vec<Vec<f64>>,
}

impl Recordings {
    /// Reads every sample of `source` (at most `max_frames` per channel) into recordings.
    pub fn from_source(
        source: &mut dyn crate::source::Source,
        max_frames: usize,
    ) -> Result<Self, crate::source::SourceError> {
        let info = source.info().clone();
        let channels = crate::source::memory::read_all(source, max_frames)?;
        Ok(Recordings {
            fs_hz: info.sample_rate_hz,
            names: info.channel_names,
            channels,
        })
    }

    /// Adds white Gaussian noise to every channel at `snr_db` **on mean signal power**: the
    /// noise variance is the mean over channels of each channel's power over the whole record,
    /// divided by 10^(snr/10) (far harsher on decays than a peak SNR). Seeded; channel `k` gets
    /// its own stream.
    pub fn add_noise_mean_power(&mut self, snr_db: f64, seed: u64) {
        let n = self.channels.first().map_or(0, Vec::len).max(1) as f64;
        let power = self
            .channels
            .iter()
            .map(|x| x.iter().map(|v| v * v).sum::<f64>() / n)
            .sum::<f64>()
            / self.channels.len().max(1) as f64;
        let sigma = (power / 10f64.powf(snr_db / 10.0)).sqrt();
        for (k, x) in self.channels.iter_mut().enumerate() {
            let mut g = crate::source::noise::GaussianNoise::new(
                seed.wrapping_mul(0x9E37_79B9_7F4A_7C15)
                    .wrapping_add(k as u64),
            );
            for v in x.iter_mut() {
                *v += sigma * g.next_gaussian();
            }
        }
    }

    /// The channels' summed power spectrum, (f in Hz, dB), for the stabilisation diagram's
    /// background.
    pub fn mean_power_spectrum_db(&self) -> Vec<(f64, f64)> {
        use realfft::RealFftPlanner;
        let n = self.channels.first().map_or(0, Vec::len);
        if n < 2 {
            return Vec::new();
        }
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
        let mut power = vec![0.0; n / 2 + 1];
        let mut spectrum = fft.make_output_vec();
        let mut input = fft.make_input_vec();
        for x in &self.channels {
            input.copy_from_slice(x);
            if fft.process(&mut input, &mut spectrum).is_ok() {
                for (p, s) in power.iter_mut().zip(&spectrum) {
                    *p += s.norm_sqr();
                }
            }
        }
        power
            .iter()
            .enumerate()
            .map(|(k, p)| {
                (
                    k as f64 * self.fs_hz / n as f64,
                    10.0 * p.max(1e-300).log10(),
                )
            })
            .collect()
    }
}

/// How [`identify`] works.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ModalSettings {
    /// Lowest frequency of interest, Hz.
    pub fmin_hz: f64,
    /// Highest frequency of interest, Hz.
    pub fmax_hz: f64,
    /// How the range is cut into sub-bands ([`DEFAULT_SUBBANDS`]).
    pub subbands: SubBandPlan,
    /// Lowest model order swept ([`DEFAULT_MIN_ORDER`]).
    pub min_order: usize,
    /// Highest model order swept ([`DEFAULT_MAX_ORDER`]).
    pub max_order: usize,
    /// Principal components kept of the channels ([`DEFAULT_COMPRESSED_CHANNELS`]).
    pub compressed_channels: usize,
    /// Analysis start, s after the record's start (`None`: the sample after the peak of the
    /// summed squared channels, i.e. after the impact).
    pub start_s: Option<f64>,
    /// Stability and clustering criteria.
    pub stability: StabilityCriteria,
}

impl ModalSettings {
    /// Defaults for the range `fmin_hz..fmax_hz`.
    pub fn new(fmin_hz: f64, fmax_hz: f64) -> Self {
        ModalSettings {
            fmin_hz,
            fmax_hz,
            subbands: DEFAULT_SUBBANDS,
            min_order: DEFAULT_MIN_ORDER,
            max_order: DEFAULT_MAX_ORDER,
            compressed_channels: DEFAULT_COMPRESSED_CHANNELS,
            start_s: None,
            stability: StabilityCriteria::default(),
        }
    }
}

/// One identified mode.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Mode {
    /// Damped natural frequency, Hz (median over the stable orders).
    pub frequency_hz: f64,
    /// Damping ratio (median over the stable orders).
    pub damping_ratio: f64,
    /// Standard deviation of the frequency over the stable orders, Hz.
    pub frequency_std_hz: f64,
    /// Standard deviation of the damping ratio over the stable orders.
    pub damping_std: f64,
    /// Modal phase collinearity of the shape (1: a real normal mode).
    pub mpc: f64,
    /// Orders at which the mode was stable.
    pub n_stable: usize,
    /// Complex shape per channel, largest component 1 + 0j.
    #[serde(skip)]
    pub shape: Vec<c64>,
}

/// One pole of the stabilisation diagram.
#[derive(Clone, Copy, Debug)]
pub struct DiagramPole {
    /// Model order.
    pub order: usize,
    /// Frequency, Hz.
    pub f_hz: f64,
    /// Damping ratio.
    pub damping_ratio: f64,
    /// Its class.
    pub class: PoleClass,
}

/// A sub-band that gave nothing, and why (the others are unaffected).
#[derive(Clone, Debug)]
pub struct SkippedBand {
    /// The band.
    pub band: SubBand,
    /// Why.
    pub reason: String,
}

/// Everything [`identify`] found.
#[derive(Clone, Debug)]
pub struct ModalResult {
    /// Modes by ascending frequency.
    pub modes: Vec<Mode>,
    /// The stabilisation diagram (every pole of every order in every sub-band, accepted range).
    pub diagram: Vec<DiagramPole>,
    /// Sub-bands that gave no poles.
    pub skipped: Vec<SkippedBand>,
    /// Channel names, the order of every shape.
    pub names: Vec<String>,
}

/// Why identification cannot run at all.
#[derive(Debug, thiserror::Error)]
pub enum ModalError {
    /// No channels or no samples.
    #[error("no samples to analyse ({channels} channels, {samples} samples)")]
    Empty {
        /// Channels given.
        channels: usize,
        /// Samples per channel.
        samples: usize,
    },
    /// Channels of different lengths.
    #[error("channel {channel} holds {got} samples, expected {expected}")]
    Ragged {
        /// The offending channel.
        channel: usize,
        /// Length of channel 0.
        expected: usize,
        /// Its length.
        got: usize,
    },
    /// The frequency range is empty or beyond the Nyquist frequency.
    #[error("frequency range {fmin_hz}..{fmax_hz} Hz: expected 0 ≤ fmin < fmax < {nyquist_hz} Hz (Nyquist)")]
    Range {
        /// Requested lower limit.
        fmin_hz: f64,
        /// Requested upper limit.
        fmax_hz: f64,
        /// Half the sample rate.
        nyquist_hz: f64,
    },
    /// A setting out of its domain.
    #[error("{name}: expected {expected}, got {got}")]
    Setting {
        /// The setting.
        name: &'static str,
        /// Its domain.
        expected: &'static str,
        /// The value given.
        got: String,
    },
}

fn validate(rec: &Recordings, s: &ModalSettings) -> Result<usize, ModalError> {
    let n = rec.channels.first().map_or(0, Vec::len);
    if rec.channels.is_empty() || n == 0 {
        return Err(ModalError::Empty {
            channels: rec.channels.len(),
            samples: n,
        });
    }
    if let Some((c, x)) = rec.channels.iter().enumerate().find(|(_, x)| x.len() != n) {
        return Err(ModalError::Ragged {
            channel: c,
            expected: n,
            got: x.len(),
        });
    }
    let nyquist_hz = rec.fs_hz / 2.0;
    let guard = s.subbands.guard_fraction * s.subbands.max_width_hz;
    if !(s.fmin_hz >= 0.0 && s.fmin_hz < s.fmax_hz && s.fmax_hz + guard < nyquist_hz) {
        return Err(ModalError::Range {
            fmin_hz: s.fmin_hz,
            fmax_hz: s.fmax_hz,
            nyquist_hz,
        });
    }
    let setting = |name, expected, got: String| ModalError::Setting {
        name,
        expected,
        got,
    };
    let b = &s.subbands;
    if !(b.min_width_hz > 0.0 && b.max_width_hz >= b.min_width_hz && b.max_width_hz.is_finite()) {
        return Err(setting(
            "sub-band widths",
            "0 < min ≤ max Hz",
            format!("{}..{}", b.min_width_hz, b.max_width_hz),
        ));
    }
    if !(b.relative_width >= 0.0 && b.relative_width.is_finite()) {
        return Err(setting(
            "relative sub-band width",
            "≥ 0",
            b.relative_width.to_string(),
        ));
    }
    if !(0.0..=2.0).contains(&b.guard_fraction) {
        return Err(setting(
            "guard fraction",
            "0 … 2",
            b.guard_fraction.to_string(),
        ));
    }
    if s.min_order < 1 || s.max_order < s.min_order + 2 || s.max_order > 400 {
        return Err(setting(
            "model orders",
            "1 ≤ min, min + 2 ≤ max ≤ 400",
            format!("{}..{}", s.min_order, s.max_order),
        ));
    }
    if s.compressed_channels == 0 {
        return Err(setting("compressed channels", "≥ 1", "0".into()));
    }
    Ok(n)
}

/// Sample index where the analysis starts: `start_s`, or the sample after the peak of the
/// summed squared channels.
fn start_index(rec: &Recordings, s: &ModalSettings, n: usize) -> usize {
    if let Some(t) = s.start_s {
        return ((t.max(0.0) * rec.fs_hz).round() as usize).min(n);
    }
    let mut best = (0, 0.0);
    for t in 0..n {
        let e: f64 = rec.channels.iter().map(|x| x[t] * x[t]).sum();
        if e > best.1 {
            best = (t, e);
        }
    }
    (best.0 + 1).min(n)
}

/// Identifies the modes of `rec` in `settings.fmin_hz..fmax_hz` from all channels at once.
pub fn identify(rec: &Recordings, settings: &ModalSettings) -> Result<ModalResult, ModalError> {
    let n = validate(rec, settings)?;
    let start = start_index(rec, settings, n);
    let plan = HankelPlan::new(
        rec.channels.len(),
        settings.max_order,
        settings.compressed_channels,
    );
    let mut result = ModalResult {
        modes: Vec::new(),
        diagram: Vec::new(),
        skipped: Vec::new(),
        names: rec.names.clone(),
    };
    for sub in plan_subbands(settings.fmin_hz, settings.fmax_hz, &settings.subbands) {
        let guard = sub.guard_hz;
        let band = to_baseband(&rec.channels, rec.fs_hz, &sub, start);
        let compressed = compress(band.data.as_ref(), plan.compressed_channels);
        let Some(by_order) = compressed.as_ref().and_then(|y| {
            poles_by_order(
                &band,
                y.as_ref(),
                &plan,
                settings.min_order..=settings.max_order,
            )
        }) else {
            result.skipped.push(SkippedBand {
                band: sub,
                reason: format!(
                    "{} decimated samples are too few for {} block rows, or a factorisation failed",
                    band.data.ncols(),
                    plan.block_rows
                ),
            });
            continue;
        };
        // Modes are selected over the whole analysed range (their exponentials all enter the
        // residue fit) and kept where the sub-band accepts them.
        let (lo, hi) = (sub.lo_hz - guard, sub.hi_hz + guard);
        let classes = classify(&by_order, lo, hi, &settings.stability);
        for (poles, class) in by_order.iter().zip(&classes) {
            for (p, k) in poles.iter().zip(class) {
                if p.f_hz >= sub.lo_hz && p.f_hz < sub.hi_hz {
                    result.diagram.push(DiagramPole {
                        order: p.order,
                        f_hz: p.f_hz,
                        damping_ratio: p.damping_ratio,
                        class: *k,
                    });
                }
            }
        }
        let clusters = select_modes(&by_order, &classes, &settings.stability);
        let z0: Vec<c64> = clusters.iter().map(|c| c.representative().z).collect();
        let z = match &compressed {
            Some(y) if !z0.is_empty() => refine::refine_poles(y.as_ref(), &z0),
            _ => z0,
        };
        let residues = shapes::residues(band.data.as_ref(), &z);
        for (r, cl) in clusters.iter().enumerate() {
            let (f, d) = band.frequency_and_damping(z[r]);
            if !(f >= sub.lo_hz && f < sub.hi_hz && d > 0.0) {
                continue;
            }
            let shape = residues
                .as_ref()
                .map(|a| shapes::normalised(&(0..a.ncols()).map(|c| a[(r, c)]).collect::<Vec<_>>()))
                .unwrap_or_default();
            result.modes.push(Mode {
                frequency_hz: f,
                damping_ratio: d,
                frequency_std_hz: cl.std(|p| p.f_hz),
                damping_std: cl.std(|p| p.damping_ratio),
                mpc: shapes::mpc(&shape),
                n_stable: cl.poles.len(),
                shape,
            });
        }
    }
    result
        .modes
        .sort_by(|a, b| a.frequency_hz.total_cmp(&b.frequency_hz));
    Ok(result)
}

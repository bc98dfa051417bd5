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

pub mod band;
pub mod baseband;
pub mod model_shapes;
pub mod recordings;
pub mod refine;
pub mod shapes;
pub mod stabilise;
pub mod subspace;

use faer::c64;

pub use baseband::SubBandPlan;
use baseband::{plan_subbands, to_baseband, SubBand};
pub use recordings::Recordings;
use stabilise::{PoleClass, StabilityCriteria};
use subspace::HankelPlan;

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
    /// Time constant τ of an exponential window e^(−t/τ) applied to the recordings before
    /// they reached dampscope (impact testing's force/response window), s: its decay rate 1/τ
    /// is subtracted from every pole, which would otherwise read too much damping.
    pub exponential_window_tau_s: Option<f64>,
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
            exponential_window_tau_s: None,
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
    /// Standard uncertainty of the frequency, Hz: the spread over the stable orders and the
    /// sensor jackknife combined (root sum of squares).
    pub frequency_std_hz: f64,
    /// Standard uncertainty of the damping ratio, combined like `frequency_std_hz`.
    pub damping_std: f64,
    /// Standard deviation of the frequency over the stable orders, Hz.
    pub frequency_order_std_hz: f64,
    /// Standard deviation of the damping ratio over the stable orders.
    pub damping_order_std: f64,
    /// Jackknife standard error of the frequency over sensor groups, Hz
    /// ([`band::JACKKNIFE_GROUPS`] groups, each left out in turn).
    pub frequency_sensor_std_hz: f64,
    /// Jackknife standard error of the damping ratio over sensor groups.
    pub damping_sensor_std: f64,
    /// Modal phase collinearity of the shape (1: a real normal mode).
    pub mpc: f64,
    /// Orders at which the mode was stable.
    pub n_stable: usize,
    /// Modal signal-to-noise ratio, dB: the mode's energy on all channels over the noise
    /// energy a free exponential absorbs from noise alone (see [`shapes::ResidueFit`]).
    pub modal_snr_db: f64,
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

impl ModalResult {
    /// The mode that carries most of channel `channel`'s energy inside `lo_hz..hi_hz`, and how
    /// many modes the band holds: `None` when no mode lies in the band. A mode's energy at a
    /// channel is its modal SNR (energy over all channels) times the channel's share of the
    /// shape's squared norm. This is the mode a decay fit of that channel's band mostly sees.
    pub fn dominant_mode(&self, lo_hz: f64, hi_hz: f64, channel: usize) -> Option<(&Mode, usize)> {
        let in_band: Vec<&Mode> = self
            .modes
            .iter()
            .filter(|m| m.frequency_hz >= lo_hz && m.frequency_hz < hi_hz)
            .collect();
        let energy_at = |m: &Mode| {
            let total: f64 = m.shape.iter().map(|x| x.norm_sqr()).sum();
            let here = m.shape.get(channel).map_or(0.0, |x| x.norm_sqr());
            let share = if total > 0.0 { here / total } else { 0.0 };
            10f64.powf(m.modal_snr_db / 10.0) * share
        };
        let best = in_band
            .iter()
            .copied()
            .max_by(|a, b| energy_at(a).total_cmp(&energy_at(b)))?;
        Some((best, in_band.len()))
    }
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
    /// The frequency range is empty, or its top plus the sub-bands' guard reaches the Nyquist
    /// frequency (a short record widens the sub-bands, and their guard with them).
    #[error("frequency range {fmin_hz}..{fmax_hz} Hz: expected 0 ≤ fmin < fmax and fmax + {guard_hz:.1} Hz (the guard of sub-bands up to {width_hz:.1} Hz wide; short records widen them, this one is {record_s:.3} s) below {nyquist_hz} Hz (Nyquist): lower --fmax or give a longer record")]
    Range {
        /// Requested lower limit.
        fmin_hz: f64,
        /// Requested upper limit.
        fmax_hz: f64,
        /// Half the sample rate.
        nyquist_hz: f64,
        /// The widest sub-band's guard above fmax, Hz.
        guard_hz: f64,
        /// The widest sub-band, Hz.
        width_hz: f64,
        /// The record's length, s.
        record_s: f64,
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

/// `fmin..fmax` is ordered and `fmax` plus the widest sub-band's guard stays below Nyquist.
fn check_range(rec: &Recordings, s: &ModalSettings, plan: &SubBandPlan) -> Result<(), ModalError> {
    let nyquist_hz = rec.fs_hz / 2.0;
    let guard = plan.guard_fraction * plan.max_width_hz;
    if !(s.fmin_hz >= 0.0 && s.fmin_hz < s.fmax_hz && s.fmax_hz + guard < nyquist_hz) {
        return Err(ModalError::Range {
            fmin_hz: s.fmin_hz,
            fmax_hz: s.fmax_hz,
            nyquist_hz,
            guard_hz: guard,
            width_hz: plan.max_width_hz,
            record_s: rec.channels.first().map_or(0, Vec::len) as f64 / rec.fs_hz,
        });
    }
    Ok(())
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
    check_range(rec, s, &s.subbands)?;
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
    if let Some(t) = s.exponential_window_tau_s {
        if !(t > 0.0 && t.is_finite()) {
            return Err(setting(
                "exponential window time constant",
                "a finite τ > 0 s",
                t.to_string(),
            ));
        }
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
    identify_with_progress(rec, settings, &mut |_, _| {})
}

/// [`identify`], calling `progress(done, total)` after each sub-band (for a progress bar).
pub fn identify_with_progress(
    rec: &Recordings,
    settings: &ModalSettings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ModalResult, ModalError> {
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
    let record_s = (n - start) as f64 / rec.fs_hz;
    let subbands = settings.subbands.fitted_to_record(record_s);
    // A short record widens the sub-bands, and with them the guard above fmax.
    check_range(rec, settings, &subbands)?;
    let plan_of_bands = plan_subbands(settings.fmin_hz, settings.fmax_hz, &subbands);
    let total = plan_of_bands.len();
    for (done, sub) in plan_of_bands.into_iter().enumerate() {
        let mut band = to_baseband(&rec.channels, rec.fs_hz, &sub, start);
        band.window_decay_per_s = settings.exponential_window_tau_s.map_or(0.0, |t| 1.0 / t);
        match band::identify_band(&band, &sub, &plan, settings) {
            Ok((modes, diagram)) => {
                result.modes.extend(modes);
                result.diagram.extend(diagram);
            }
            Err(reason) => result.skipped.push(SkippedBand { band: sub, reason }),
        }
        progress(done + 1, total);
    }
    result
        .modes
        .sort_by(|a, b| a.frequency_hz.total_cmp(&b.frequency_hz));
    Ok(result)
}

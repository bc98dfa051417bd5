//! Several front ends side by side on the same decays (`dampscope compare`), and beside them
//! the multichannel modal identification ([`crate::modal::identify`]) over the bands' range.
//!
//! Offline: the whole input is in memory; each channel's decay starts at its onset (the first
//! sample within `onset_level_db` of the peak) and runs to the end of the input. Per channel
//! and band, one row per front end and, when asked, one `modal` row: the mode that carries
//! most of that channel's energy in the band.

use crate::decay::estimate::EstimateSettings;
use crate::decay::DecayEstimate;
use crate::error::Result;
use crate::frontend::{Band, FrontEnd};
use crate::modal::{identify, ModalResult, ModalSettings, Recordings};
use crate::pipeline::analyze_decay;
use crate::pipeline::segment::onset::find_onset;
use crate::pipeline::segment::DEFAULT_ONSET_LEVEL_DB;
use crate::plan::{BandLayout, FrontEndKind, FrontEndSpec};

/// The `front_end` name of the multichannel modal estimate.
pub const MODAL_FRONT_END: &str = "modal";

/// What to compare.
#[derive(Clone, Debug, PartialEq)]
pub struct ComparePlan {
    /// Bands (resolved per channel on its decay, so `auto` follows each channel's peaks).
    pub bands: BandLayout,
    /// Front-end settings shared by every kind compared.
    pub front_end: FrontEndSpec,
    /// The front ends, in column order.
    pub kinds: Vec<FrontEndKind>,
    /// Also the multichannel modal estimate.
    pub modal: bool,
    /// How each decay is estimated.
    pub estimate: EstimateSettings,
    /// Decay onset: first sample within this many dB of the peak.
    pub onset_level_db: f64,
}

impl Default for ComparePlan {
    /// STFT and Goyder bank on the report's bands.
    fn default() -> Self {
        ComparePlan {
            bands: BandLayout::default(),
            front_end: FrontEndSpec::default(),
            kinds: vec![FrontEndKind::Stft, FrontEndKind::Goyder],
            modal: false,
            estimate: EstimateSettings::default(),
            onset_level_db: DEFAULT_ONSET_LEVEL_DB,
        }
    }
}

/// One channel, band and front end (or the modal estimate).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CompareRow {
    /// Channel (sensor id).
    pub channel: String,
    /// The band as `LO-HI` in Hz (two decimals).
    pub band_hz: String,
    /// The band's nominal frequency, Hz.
    pub nominal_hz: f64,
    /// `stft`, `goyder`, `octave` or `modal`.
    pub front_end: &'static str,
    /// Damping ratio in % (frequency-corrected where known; the mode's for `modal`).
    pub d_pct: Option<f64>,
    /// Reverberation time, s (`modal`: 1.1 / (D f)).
    pub t60_s: Option<f64>,
    /// r² of the decay fit.
    pub r2: Option<f64>,
    /// Frames in the fit (`modal`: the stable poles).
    pub n_points: usize,
    /// Frame period, ms.
    pub frame_ms: Option<f64>,
    /// Time resolution, ms.
    pub t_res_ms: Option<f64>,
    /// Frequency resolution, Hz.
    pub f_res_hz: Option<f64>,
    /// Flags, `;`-separated (`modal`: `no_mode`, `several_modes`, `outside_modal_range`,
    /// `modal_failed`).
    pub flags: String,
    /// The modal estimate's standard deviation of D, %.
    pub d_std_pct: Option<f64>,
    /// The decay's dominant frequency, or the mode's, Hz.
    pub f_hz: Option<f64>,
}

/// The rows, and what the user should know about them.
#[derive(Clone, Debug, Default)]
pub struct Comparison {
    /// Rows by channel, band, then front end.
    pub rows: Vec<CompareRow>,
    /// Silent channels, dropped bands, a failed modal identification.
    pub warnings: Vec<String>,
}

fn band_label(band: &Band) -> String {
    format!("{:.2}-{:.2}", band.lo_hz, band.hi_hz)
}

fn decay_row(channel: &str, band: &Band, fe: &dyn FrontEnd, e: &DecayEstimate) -> CompareRow {
    let r = fe.resolution();
    CompareRow {
        channel: channel.to_string(),
        band_hz: band_label(band),
        nominal_hz: band.nominal_hz,
        front_end: fe.name(),
        d_pct: e
            .damping_ratio_corrected
            .or(e.damping_ratio)
            .map(|d| 100.0 * d),
        t60_s: e.t60_s,
        r2: e.r2,
        n_points: e.n_points,
        frame_ms: Some(r.frame_period_s * 1e3),
        t_res_ms: Some(r.time_resolution_s * 1e3),
        f_res_hz: Some(r.frequency_resolution_hz),
        flags: e
            .flags
            .iter()
            .map(|f| f.as_str())
            .collect::<Vec<_>>()
            .join(";"),
        d_std_pct: None,
        f_hz: e.f_dominant_hz,
    }
}

/// The multichannel identification behind the `modal` rows.
enum ModalOutcome {
    /// Identified up to `fmax_hz`.
    Done { result: ModalResult, fmax_hz: f64 },
    /// Identification could not run (reason in the warnings).
    Failed,
}

fn modal_row(channel: &str, index: usize, band: &Band, modal: &ModalOutcome) -> CompareRow {
    let mut row = CompareRow {
        channel: channel.to_string(),
        band_hz: band_label(band),
        nominal_hz: band.nominal_hz,
        front_end: MODAL_FRONT_END,
        d_pct: None,
        t60_s: None,
        r2: None,
        n_points: 0,
        frame_ms: None,
        t_res_ms: None,
        f_res_hz: None,
        flags: String::new(),
        d_std_pct: None,
        f_hz: None,
    };
    let found = match modal {
        ModalOutcome::Failed => Err("modal_failed"),
        ModalOutcome::Done { fmax_hz, .. } if band.hi_hz > *fmax_hz => Err("outside_modal_range"),
        ModalOutcome::Done { result, .. } => result
            .dominant_mode(band.lo_hz, band.hi_hz, index)
            .ok_or("no_mode"),
    };
    match found {
        Ok((m, count)) => {
            row.d_pct = Some(100.0 * m.damping_ratio);
            row.t60_s = Some(1.1 / (m.damping_ratio * m.frequency_hz));
            row.n_points = m.n_stable;
            row.flags = if count > 1 { "several_modes" } else { "" }.to_string();
            row.d_std_pct = Some(100.0 * m.damping_std);
            row.f_hz = Some(m.frequency_hz);
        }
        Err(flag) => row.flags = flag.to_string(),
    }
    row
}

/// Identifies the modes of all channels over the bands' range (clamped below the highest
/// frequency the sample rate allows).
fn identify_for_bands(
    rec: &Recordings,
    bands: &[Band],
    exponential_window_tau_s: Option<f64>,
    warnings: &mut Vec<String>,
) -> ModalOutcome {
    let lo = bands.iter().map(|b| b.lo_hz).fold(f64::INFINITY, f64::min);
    let hi = bands.iter().map(|b| b.hi_hz).fold(0.0, f64::max);
    let sub = crate::modal::DEFAULT_SUBBANDS;
    let fmax_hz = hi.min(0.5 * rec.fs_hz - sub.guard_fraction * sub.max_width_hz - 1.0);
    let settings = ModalSettings {
        exponential_window_tau_s,
        ..ModalSettings::new(lo.max(0.0), fmax_hz)
    };
    match identify(rec, &settings) {
        Ok(result) => ModalOutcome::Done { result, fmax_hz },
        Err(e) => {
            warnings.push(format!("modal identification failed: {e}"));
            ModalOutcome::Failed
        }
    }
}

/// Runs every front end of `plan` (and the modal identification) on every channel of `rec`.
/// `exponential_window_tau_s`: the recording set's exponential window, if any (the modal
/// estimate removes its added damping).
pub fn compare(
    rec: &Recordings,
    exponential_window_tau_s: Option<f64>,
    plan: &ComparePlan,
) -> Result<Comparison> {
    plan.bands.validate()?;
    plan.estimate.validate()?;
    let mut out = Comparison::default();
    // Per channel: its index, its decay (from the onset) and its bands.
    let mut channels = Vec::new();
    for (index, (name, x)) in rec.names.iter().zip(&rec.channels).enumerate() {
        let Some(onset) = find_onset(x, plan.onset_level_db) else {
            out.warnings
                .push(format!("channel {name} is silent; skipped"));
            continue;
        };
        let decay = &x[onset..];
        let resolved = plan.bands.resolve(rec.fs_hz, Some(&[decay]))?;
        out.warnings.extend(resolved.warnings);
        channels.push((index, decay, resolved.bands));
    }
    let modal = plan.modal.then(|| {
        let all: Vec<Band> = channels.iter().flat_map(|c| c.2.clone()).collect();
        identify_for_bands(rec, &all, exponential_window_tau_s, &mut out.warnings)
    });
    for (index, decay, bands) in &channels {
        let name = &rec.names[*index];
        let mut per_fe = Vec::new();
        for kind in &plan.kinds {
            let mut fe = plan.front_end.with_kind(*kind).build(rec.fs_hz, bands)?;
            let est = analyze_decay(decay, fe.as_mut(), &plan.estimate);
            per_fe.push((fe, est));
        }
        for (b, band) in bands.iter().enumerate() {
            for (fe, est) in &per_fe {
                out.rows.push(decay_row(name, band, fe.as_ref(), &est[b]));
            }
            if let Some(m) = &modal {
                out.rows.push(modal_row(name, *index, band, m));
            }
        }
    }
    Ok(out)
}

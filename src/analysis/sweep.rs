//! The built-in front-end study (`dampscope compare --sweep`): synthetic decays with known
//! damping through every front end, error against the truth.
//!
//! Cases: single modes and close pairs (two modes 1.2 % apart, as plate modes 7/8, equal
//! amplitude, 90° apart, the same D, so the truth is still D) on a grid of frequencies and
//! damping ratios. Front ends: STFT with 200 ms and 50 ms Hann windows (50 % overlap), the
//! Goyder bank (reversed, order 4, 1 ms frames) and the third-octave bank (reversed) — each
//! on a band around the mode (STFT and Goyder: width max(10 Hz, 10 % of f); octave: the
//! third-octave band centred on f). The fit range is T30; the reported D is the
//! frequency-corrected one (D·f_center/f_dominant where the front end knows f_dominant).

use std::fmt::Write as _;
use std::path::Path;

use crate::decay::estimate::EstimateSettings;
use crate::decay::{DecayEstimate, EvaluationRange};
use crate::error::{Error, Result};
use crate::frontend::iec_bands::OCTAVE_RATIO_G;
use crate::frontend::stft::StftSettings;
use crate::frontend::{Band, FilterDirection, FrontEnd};
use crate::pipeline::analyze_decay;
use crate::plan::{FrontEndKind, FrontEndSpec};
use crate::source::synth::{decaying_sines, Mode};

/// What the sweep covers.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepConfig {
    /// Mode frequencies, Hz.
    pub freqs_hz: Vec<f64>,
    /// Damping ratios (fractions, e.g. 0.01 = 1 %).
    pub dampings: Vec<f64>,
    /// Sample rate of the synthetic decays, Hz.
    pub fs_hz: f64,
    /// Also run close pairs (beating).
    pub pairs: bool,
    /// Longest synthetic decay, s (cases are shortened to this).
    pub max_duration_s: f64,
}

impl Default for SweepConfig {
    /// The full study: f from 20 to 2000 Hz (8 values), D from 0.2 % to 5 % (6 values).
    fn default() -> Self {
        SweepConfig {
            freqs_hz: vec![20.0, 40.0, 80.0, 160.0, 315.0, 630.0, 1250.0, 2000.0],
            dampings: vec![0.002, 0.005, 0.01, 0.02, 0.03, 0.05],
            fs_hz: 6000.0,
            pairs: true,
            max_duration_s: 40.0,
        }
    }
}

impl SweepConfig {
    /// A small grid for tests (2 frequencies × 2 dampings).
    pub fn reduced() -> Self {
        SweepConfig {
            freqs_hz: vec![100.0, 800.0],
            dampings: vec![0.005, 0.02],
            ..Default::default()
        }
    }
}

/// The front ends of the study, in column order of the figure.
pub const SWEEP_FRONT_ENDS: [&str; 4] = ["stft-200ms", "stft-50ms", "goyder", "octave-third"];

/// One case through one front end.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SweepRow {
    /// `single` or `pair`.
    pub case: &'static str,
    /// Mode frequency (the lower one for pairs), Hz.
    pub f_hz: f64,
    /// True damping ratio (fraction).
    pub d_true: f64,
    /// True reverberation time, s.
    pub t60_true_s: f64,
    /// Front end label (see [`SWEEP_FRONT_ENDS`]).
    pub front_end: &'static str,
    /// Band width × true T60 (the BT product).
    pub bt: f64,
    /// Estimated damping ratio (frequency-corrected where available), if any.
    pub d_est: Option<f64>,
    /// Relative error d_est/d_true − 1, if an estimate exists.
    pub rel_err: Option<f64>,
    /// Flags raised, `;`-separated.
    pub flags: String,
}

/// The front end of a sweep column and the band it analyses around a mode at `f` Hz.
fn build(label: &str, fs: f64, f: f64) -> Result<(Box<dyn FrontEnd>, Band)> {
    let w = (0.1 * f).max(10.0);
    let around = Band {
        center_hz: f,
        nominal_hz: f,
        ..Band::new((f - 0.5 * w).max(0.5), f + 0.5 * w)?
    };
    let (spec, band) = match label {
        "stft-200ms" => (FrontEndSpec::default(), around),
        "stft-50ms" => (
            FrontEndSpec {
                stft: StftSettings {
                    window_ms: 50.0,
                    ..Default::default()
                },
                ..Default::default()
            },
            around,
        ),
        "goyder" => (
            FrontEndSpec::default().with_kind(FrontEndKind::Goyder),
            around,
        ),
        _ => {
            let half = OCTAVE_RATIO_G.powf(1.0 / 6.0);
            let third = Band {
                lo_hz: f / half,
                hi_hz: f * half,
                center_hz: f,
                nominal_hz: f,
            };
            let spec = FrontEndSpec {
                kind: FrontEndKind::Octave,
                direction: FilterDirection::Reversed,
                frame_period_ms: Some(1.0),
                ..Default::default()
            };
            (spec, third)
        }
    };
    Ok((spec.build(fs, &[band])?, band))
}

fn run_case(cfg: &SweepConfig, pair: bool, f: f64, d: f64) -> Result<Vec<SweepRow>> {
    let t60 = 1.0994 / (f * d);
    let mut modes = vec![Mode::new(f, d, 1.0, 0.0)];
    if pair {
        modes.push(Mode::new(f * 1.012, d, 1.0, 90.0));
    }
    let duration = (0.9 * t60 + 3.0 / (0.1 * f).max(10.0) + 0.3).min(cfg.max_duration_s);
    let x = decaying_sines(&modes, cfg.fs_hz, duration);
    let settings = EstimateSettings {
        range: EvaluationRange::T30,
        ..Default::default()
    };
    SWEEP_FRONT_ENDS
        .iter()
        .map(|&label| {
            let (mut fe, band) = build(label, cfg.fs_hz, f)?;
            let est: DecayEstimate = analyze_decay(&x, fe.as_mut(), &settings)
                .pop()
                .unwrap_or_default();
            let d_est = est.damping_ratio_corrected.or(est.damping_ratio);
            Ok(SweepRow {
                case: if pair { "pair" } else { "single" },
                f_hz: f,
                d_true: d,
                t60_true_s: t60,
                front_end: label,
                bt: band.width_hz() * t60,
                d_est,
                rel_err: d_est.map(|e| e / d - 1.0),
                flags: est
                    .flags
                    .iter()
                    .map(|f| f.as_str())
                    .collect::<Vec<_>>()
                    .join(";"),
            })
        })
        .collect()
}

/// Runs every case of `cfg` through every front end, in parallel over the available cores.
/// Rows come back in a fixed order (case, f, D, front end).
pub fn run_sweep(cfg: &SweepConfig) -> Result<Vec<SweepRow>> {
    let nyq = 0.5 * cfg.fs_hz;
    if let Some(f) = cfg
        .freqs_hz
        .iter()
        .find(|f| !(**f > 0.0 && **f * 1.15 < nyq))
    {
        return Err(Error::setting(
            "sweep",
            format!("expected frequencies above 0 and below 0.87 × Nyquist ({nyq} Hz), got {f}"),
        ));
    }
    if let Some(d) = cfg.dampings.iter().find(|d| !(**d > 0.0 && **d < 0.5)) {
        return Err(Error::setting(
            "sweep",
            format!("expected damping ratios in (0, 0.5), got {d}"),
        ));
    }
    let mut cases = Vec::new();
    for pair in [false, true] {
        if pair && !cfg.pairs {
            continue;
        }
        for &f in &cfg.freqs_hz {
            for &d in &cfg.dampings {
                cases.push((pair, f, d));
            }
        }
    }
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(cases.len().max(1));
    let results: Vec<Result<Vec<SweepRow>>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let cases = &cases;
                scope.spawn(move || {
                    (t..cases.len())
                        .step_by(threads)
                        .map(|i| (i, run_case(cfg, cases[i].0, cases[i].1, cases[i].2)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        let mut all: Vec<(usize, Result<Vec<SweepRow>>)> = handles
            .into_iter()
            .flat_map(|h| {
                h.join().unwrap_or_else(|_| {
                    vec![(
                        usize::MAX,
                        Err(Error::setting("sweep", "a worker thread panicked")),
                    )]
                })
            })
            .collect();
        all.sort_by_key(|(i, _)| *i);
        all.into_iter().map(|(_, r)| r).collect()
    });
    let mut rows = Vec::new();
    for r in results {
        rows.extend(r?);
    }
    Ok(rows)
}

/// Runs the sweep and writes `sweep.csv` and `sweep.png` into `dir` (created if missing).
pub fn sweep_to_dir(cfg: &SweepConfig, dir: &Path) -> Result<Vec<SweepRow>> {
    std::fs::create_dir_all(dir)?;
    let rows = run_sweep(cfg)?;
    crate::output::write_csv_file(&dir.join("sweep.csv"), &rows)?;
    crate::plot::sweep_heatmap(&rows, &dir.join("sweep.png"))?;
    Ok(rows)
}

/// Per front end and case: cases with an estimate, within 2 % and 5 %, and the median |error|.
pub fn sweep_summary(rows: &[SweepRow]) -> String {
    let mut out =
        String::from("case    front_end     estimates  within_2%  within_5%  median_|err|_%\n");
    for case in ["single", "pair"] {
        for fe in SWEEP_FRONT_ENDS {
            let sel: Vec<&SweepRow> = rows
                .iter()
                .filter(|r| r.case == case && r.front_end == fe)
                .collect();
            if sel.is_empty() {
                continue;
            }
            let mut errs: Vec<f64> = sel.iter().filter_map(|r| r.rel_err.map(f64::abs)).collect();
            errs.sort_by(f64::total_cmp);
            let within = |t: f64| errs.iter().filter(|e| **e < t).count();
            let median = errs
                .get(errs.len() / 2)
                .map_or("-".into(), |m| format!("{:.2}", m * 100.0));
            let _ = writeln!(
                out,
                "{case:<7} {fe:<13} {:>4}/{:<4}  {:>9}  {:>9}  {median:>14}",
                errs.len(),
                sel.len(),
                within(0.02),
                within(0.05)
            );
        }
    }
    out
}

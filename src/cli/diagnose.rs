//! `dampscope diagnose RECORDINGS --model M.toml --out DIR`: what physics the model lacks
//! ([`crate::diagnose::procedure::diagnose`]), the model updated with it, and the fit before
//! and after.
//!
//! Writes `diagnosis.json` (FORMATS.md §5), `updated-model.toml`, `modes.csv` (every paired
//! mode: measured and model f and D, MAC) and `report.md`, and prints the findings.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context;

use crate::diagnose::procedure::{diagnose, DiagnoseSettings, Diagnosis, DEFAULT_DIAGNOSE_FMAX_HZ};
use crate::modal::model_shapes::sensor_positions;
use crate::modal::Recordings;
use crate::sim::model::{Model, SensorSpec};
use crate::source::recording_set::open_recording_set;

/// Most samples per channel read.
const MAX_DIAGNOSE_SAMPLES: usize = 1 << 24;

/// Options of `dampscope diagnose`.
#[derive(Debug, clap::Args)]
pub struct DiagnoseArgs {
    /// The recordings: a recording-set directory (sensor positions are needed).
    pub input: PathBuf,
    /// The model to check (TOML).
    #[arg(long, value_name = "PATH")]
    pub model: PathBuf,
    /// Modes up to this frequency are identified and compared, Hz.
    #[arg(long, default_value_t = DEFAULT_DIAGNOSE_FMAX_HZ, value_name = "HZ")]
    pub fmax: f64,
    /// Add white noise at this SNR on mean signal power, dB (for robustness studies).
    #[arg(long, value_name = "DB")]
    pub add_noise_db: Option<f64>,
    /// Seed of --add-noise-db.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

#[derive(serde::Serialize)]
struct DiagnosisJson<'a> {
    findings: &'a [crate::diagnose::procedure::Finding],
    fit: crate::diagnose::procedure::FitBeforeAfter,
    updated_model: &'a str,
}

#[derive(serde::Serialize)]
struct ModeRow {
    model_mode: usize,
    frequency_hz: f64,
    model_frequency_hz: f64,
    damping_ratio: f64,
    damping_std: f64,
    model_damping_ratio: f64,
    mac: f64,
}

/// Runs `dampscope diagnose`.
pub fn run(args: &DiagnoseArgs) -> anyhow::Result<()> {
    let mut set = open_recording_set(&args.input)
        .with_context(|| format!("recording set {}", args.input.display()))?;
    let sensors = sensor_positions(&set.sensors);
    let mut rec = Recordings::from_source(set.source.as_mut(), MAX_DIAGNOSE_SAMPLES)
        .with_context(|| format!("reading {}", args.input.display()))?;
    if let Some(snr) = args.add_noise_db {
        rec.add_noise_mean_power(snr, args.seed);
    }
    let model =
        Model::load(&args.model).with_context(|| format!("model {}", args.model.display()))?;
    let settings = DiagnoseSettings {
        fmax_hz: args.fmax,
        ..DiagnoseSettings::default()
    };
    let d = diagnose(&rec, &sensors, &model, &settings)?;
    print!("{}", summary(&d));
    write_outputs(args, &d)
}

/// The findings and the fit, in plain words.
pub fn summary(d: &Diagnosis) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{} modes identified, {} paired with the model (model form: frequencies {:+.2} % in the median, scatter {:.2} %)",
        d.modes.len(),
        d.evidence.pairs.len(),
        d.evidence
            .calibration
            .map_or(0.0, |c| 100.0 * c.log_frequency_ratio.exp_m1()),
        d.evidence
            .calibration
            .map_or(0.0, |c| 100.0 * c.frequency_sigma_rel),
    );
    if d.findings.is_empty() {
        let _ = writeln!(out, "verdict: no missing physics");
    }
    for f in &d.findings {
        let _ = writeln!(
            out,
            "finding: {} (confidence {:.2}): {}",
            f.kind, f.confidence, f.summary
        );
    }
    let (b, a) = (d.fit.before, d.fit.after);
    let _ = writeln!(
        out,
        "fit: damping RMS {:.5} → {:.5}, frequency RMS {:.3} → {:.3} Hz",
        b.damping_rms, a.damping_rms, b.frequency_rms_hz, a.frequency_rms_hz
    );
    out
}

fn write_outputs(args: &DiagnoseArgs, d: &Diagnosis) -> anyhow::Result<()> {
    let out = &args.out;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let json = DiagnosisJson {
        findings: &d.findings,
        fit: d.fit,
        updated_model: "updated-model.toml",
    };
    let path = out.join("diagnosis.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json)?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    // The updated model must load from the output directory: a sensor file is made absolute.
    let mut updated = d.updated_model.clone();
    if let (SensorSpec::File { file }, Some(base)) =
        (&mut updated.output.sensors, &d.updated_model.base_dir)
    {
        if file.is_relative() {
            *file = std::path::absolute(base.join(&*file))?;
        }
    }
    let path = out.join("updated-model.toml");
    std::fs::write(
        &path,
        toml::to_string(&updated).context("cannot write the updated model as TOML")?,
    )
    .with_context(|| format!("cannot write {}", path.display()))?;
    let rows: Vec<ModeRow> = d
        .evidence
        .pairs
        .iter()
        .map(|p| {
            let (m, q) = (&d.modes[p.measured], &d.evidence.model[p.model]);
            ModeRow {
                model_mode: q.mode,
                frequency_hz: m.frequency_hz,
                model_frequency_hz: q.damped_frequency_hz,
                damping_ratio: m.damping_ratio,
                damping_std: m.damping_std,
                model_damping_ratio: q.damping_ratio,
                mac: p.mac,
            }
        })
        .collect();
    super::write_csv(&out.join("modes.csv"), &rows)?;
    let report = format!(
        "# Diagnosis of {} against {}\n\n{}\n\
         Modal damping maps are dominated by beating and nodal lines; this diagnosis uses each \
         mode's damping and frequency identified from all sensors at once, paired with the \
         model's modes by shape, so a region shows in the modes that strain it.\n",
        args.input.display(),
        args.model.display(),
        summary(d)
            .lines()
            .map(|l| format!("- {l}\n"))
            .collect::<String>()
    );
    let path = out.join("report.md");
    std::fs::write(&path, report).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

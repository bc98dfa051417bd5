//! `dampscope diagnose RECORDINGS --model M.toml --out DIR`: what physics the model lacks
//! ([`crate::diagnose::procedure::diagnose`]), the model updated with it, and the fit before
//! and after.
//!
//! Writes `diagnosis.json` (FORMATS.md §5), `updated-model.toml`, `modes.csv` (every paired
//! mode: measured and model f and D, MAC) and `report.md`, and prints the findings.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context;

use crate::diagnose::procedure::{
    diagnose_with_progress, DiagnoseSettings, DEFAULT_DIAGNOSE_FMAX_HZ,
};
use crate::diagnose::report::{why_maps_miss, Diagnosis};
use crate::diagnose::score::DEFAULT_MODEL_FORM_SIGMA;
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
    /// How far a correct model's frequencies may differ from the structure's, mode by mode,
    /// beyond a calibrated offset and trends, % (another mesh or plate theory: ~0.1 %).
    #[arg(long, default_value_t = 100.0 * DEFAULT_MODEL_FORM_SIGMA, value_name = "PERCENT")]
    pub model_form_percent: f64,
    /// Print how long each stage took (stderr).
    #[arg(long)]
    pub timings: bool,
}

#[derive(serde::Serialize)]
struct DiagnosisJson<'a> {
    findings: &'a [crate::diagnose::report::Finding],
    fit: crate::diagnose::fit::FitBeforeAfter,
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
    updated_frequency_hz: Option<f64>,
    updated_damping_ratio: Option<f64>,
    updated_mac: Option<f64>,
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
        excitation_m: set.excitation.first().map(|e| (e.x_m, e.y_m)),
        model_form_sigma: 0.01 * args.model_form_percent,
        ..DiagnoseSettings::default()
    };
    let bar = indicatif::ProgressBar::new_spinner();
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let start = std::time::Instant::now();
    let mut last = (start, String::from("reading"));
    let mut stages: Vec<(String, f64)> = Vec::new();
    let d = diagnose_with_progress(&rec, &sensors, &model, &settings, &mut |stage| {
        let now = std::time::Instant::now();
        stages.push((std::mem::take(&mut last.1), (now - last.0).as_secs_f64()));
        last = (now, stage.to_string());
        bar.set_message(stage.to_string())
    });
    stages.push((last.1, last.0.elapsed().as_secs_f64()));
    bar.finish_and_clear();
    if args.timings {
        for (stage, s) in &stages {
            eprintln!("{s:8.2} s  {stage}");
        }
        eprintln!("{:8.2} s  in all", start.elapsed().as_secs_f64());
    }
    let d = d?;
    print!("{}", d.summary());
    write_outputs(args, &d)
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
            let after = d
                .evidence_after
                .pairs
                .iter()
                .find(|a| a.measured == p.measured)
                .map(|a| (&d.evidence_after.model[a.model], a.mac));
            ModeRow {
                updated_frequency_hz: after.map(|a| a.0.damped_frequency_hz),
                updated_damping_ratio: after.map(|a| a.0.damping_ratio),
                updated_mac: after.map(|a| a.1),
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
    write_figures(out, &updated, d)?;
    let report = report_markdown(args, d);
    let path = out.join("report.md");
    std::fs::write(&path, report).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// `report.md`: the summary, each finding with why a damping map alone would miss it, and the
/// families' scores.
fn report_markdown(args: &DiagnoseArgs, d: &Diagnosis) -> String {
    let mut out = format!(
        "# Diagnosis of {} against {}\n\n",
        args.input.display(),
        args.model.display()
    );
    for l in d.summary().lines() {
        let _ = writeln!(out, "- {l}");
    }
    for f in &d.findings {
        let _ = writeln!(out, "\n## {}\n\n{}\n", f.kind, f.summary);
        if let Some(r) = &f.runner_up {
            let _ = writeln!(
                out,
                "The next best explanation, {}, fits worse by ΔBIC = {:.1}{}.\n",
                r.kind,
                r.delta_bic,
                if r.delta_bic >= 10.0 {
                    " (decisive)"
                } else {
                    ": not decisive, keep it in mind"
                }
            );
        }
        let (sizes, mirrors): (Vec<_>, Vec<_>) =
            f.images.iter().partition(|i| !i.parameters.is_empty());
        if !mirrors.is_empty() {
            let _ = writeln!(
                out,
                "{} mirror image(s) of it fit the evidence as well and could not be ruled out by \
                 the mode shapes; they are listed in diagnosis.json.\n",
                mirrors.len()
            );
        }
        for i in sizes {
            let size = ["loss_factor", "peak_loss_factor", "youngs_modulus"]
                .iter()
                .find_map(|k| i.parameters.get(*k).map(|v| (k, v)));
            let (Some(r), Some((name, value))) = (&i.region, size) else {
                continue;
            };
            let _ = writeln!(
                out,
                "Another size fits the damping about as well (its area trades against its loss; \
                 the mode shapes chose the one above): x {:.2}–{:.2} m, y {:.2}–{:.2} m with \
                 {name} {value:.3}.\n",
                r.x[0], r.x[1], r.y[0], r.y[1]
            );
        }
        let why = why_maps_miss(&f.kind);
        if !why.is_empty() {
            let _ = writeln!(out, "{why}\n");
        }
    }
    let _ = writeln!(
        out,
        "\n## How each kind scored\n\nBIC gain over \"no change\" of each kind's best \
         explanation (a finding needs ≥ 6 after paying for its parameters and the places \
         searched):\n\n| round | kind | BIC gain |\n|---|---|---|"
    );
    for s in &d.families {
        let _ = writeln!(out, "| {} | {} | {:.1} |", s.round + 1, s.kind, s.bic_gain);
    }
    out
}

/// The figures: mode errors before/after, the shape residual map with the findings drawn, and
/// FRF overlays (when the FRF error could be computed).
fn write_figures(out: &std::path::Path, model: &Model, d: &Diagnosis) -> anyhow::Result<()> {
    crate::plot::mode_errors(d, &out.join("mode-errors.png"))?;
    let residual = d.shape_residual();
    if d.sensor_positions.len() == residual.len() && !residual.is_empty() {
        let at: Vec<(f64, f64)> = d.sensor_positions.iter().map(|s| (s.x_m, s.y_m)).collect();
        crate::plot::residual_map(
            "Shape residual against the model as given (larger: worse), findings in green",
            (model.plate.lx, model.plate.ly),
            &at,
            &residual,
            &d.findings,
            &out.join("residual-map.png"),
        )?;
    }
    if d.frf.is_some() {
        crate::plot::frf_overlay(d, &out.join("frf-overlay.png"))?;
    }
    Ok(())
}

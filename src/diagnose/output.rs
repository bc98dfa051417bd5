//! The files of a diagnosis (FORMATS.md §5): `diagnosis.json`, `updated-model.toml` (loads
//! in `simulate`: a relative sensor file is made absolute), `modes.csv` (every paired mode:
//! measured and model f and D, MAC, and the updated model's), `report.md` in plain words, and
//! the figures (`mode-errors.png`, `residual-map.png`, `frf-overlay.png`).

use std::fmt::Write as _;
use std::path::Path;

use super::report::{why_maps_miss, Diagnosis};
use crate::error::{Error, Result};
use crate::output::write_csv_file;
use crate::sim::model::{Model, SensorSpec};

/// The name `diagnosis.json` gives the updated model.
pub const UPDATED_MODEL_FILE: &str = "updated-model.toml";

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

/// Writes every file of `d` into `out` (created if missing). `recordings` and `model` name
/// what was compared, for the report's title. A file that cannot be written is an error
/// naming it; those written before it stay.
pub fn write_diagnosis(out: &Path, d: &Diagnosis, recordings: &Path, model: &Path) -> Result<()> {
    let failed = |path: &Path| {
        let path = path.display().to_string();
        move |e: std::io::Error| Error::Output(format!("{path}: {e}"))
    };
    std::fs::create_dir_all(out).map_err(failed(out))?;
    let json = DiagnosisJson {
        findings: &d.findings,
        fit: d.fit,
        updated_model: UPDATED_MODEL_FILE,
    };
    let path = out.join("diagnosis.json");
    let text = serde_json::to_string_pretty(&json)
        .map_err(|e| Error::Output(format!("{}: {e}", path.display())))?;
    crate::output::write_text_file(&path, &text)?;
    // The updated model must load from the output directory: a sensor file is made absolute.
    let mut updated = d.updated_model.clone();
    if let (SensorSpec::File { file }, Some(base)) =
        (&mut updated.output.sensors, &d.updated_model.base_dir)
    {
        if file.is_relative() {
            *file = std::path::absolute(base.join(&*file)).map_err(failed(file))?;
        }
    }
    let path = out.join(UPDATED_MODEL_FILE);
    let text = toml::to_string(&updated).map_err(|e| {
        Error::Output(format!(
            "{}: the updated model as TOML: {e}",
            path.display()
        ))
    })?;
    crate::output::write_text_file(&path, &text)?;
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
    write_csv_file(&out.join("modes.csv"), &rows)?;
    write_figures(out, &updated, d)?;
    let path = out.join("report.md");
    crate::output::write_text_file(&path, &report_markdown(d, recordings, model))?;
    Ok(())
}

/// `report.md`: the summary, each finding with why a damping map alone would miss it, and the
/// families' scores.
pub fn report_markdown(d: &Diagnosis, recordings: &Path, model: &Path) -> String {
    let mut out = format!(
        "# Diagnosis of {} against {}\n\n",
        recordings.display(),
        model.display()
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
         searched; a row rejected as not borne out gives the gain through the re-solved \
         model; a row rejected because a kept finding's own kind explains it gives what it \
         adds on top of that):\n\n| round | kind | BIC gain |\n|---|---|---|"
    );
    for s in &d.families {
        let _ = writeln!(out, "| {} | {} | {:.1} |", s.round + 1, s.kind, s.bic_gain);
    }
    out
}

/// The figures: mode errors before/after, the shape residual map with the findings drawn, and
/// FRF overlays (when the FRF error could be computed).
pub fn write_figures(out: &Path, model: &Model, d: &Diagnosis) -> Result<()> {
    // Mode errors need a mode paired before and after; without one there is nothing to draw,
    // and the report and the other figures are still written.
    let paired_both = d.evidence.pairs.iter().any(|p| {
        d.evidence_after
            .pairs
            .iter()
            .any(|a| a.measured == p.measured)
    });
    if paired_both {
        crate::plot::mode_errors(d, &out.join("mode-errors.png"))?;
    }
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

//! `dampscope diagnose RECORDINGS --model M.toml --out DIR`: where and how the model's damping
//! differs from the recordings (see [`crate::diagnose`]), the model updated with the best
//! hypothesis, and the fit before and after.
//!
//! Writes `modes.csv` (per mode: recorded, simulated and updated D), `hypotheses.csv`,
//! `updated.toml` (the model with the hypothesis applied) and prints the verdict.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{bail, Context};

use super::analyze::{make_front_end, FrontEndChoice};
use super::bands_arg::BandArgs;
use super::compare::DirectionArg;
use super::write_csv;
use crate::diagnose::{
    cell_energy_fractions, cell_grid, fit_hypotheses, indistinguishable, per_mode_damping,
    updated_model, Cell, Hypothesis, ModeDamping,
};
use crate::frontend::auto_bands::bands_around_modes;
use crate::frontend::Band;
use crate::pipeline::{self, AnalysisConfig, FrontEndFactory, ResultRow};
use crate::sim::assembly::assemble;
use crate::sim::eigen::{lowest_modes, ModeRequest};
use crate::sim::model::{Model, SensorSpec};
use crate::sim::simulate::{simulate, SimulateOptions};
use crate::sim::truncation::modal_stiffness;
use crate::source::memory::MemorySource;
use crate::source::recording_set::open_recording_set;
use crate::source::{SignalInfo, Source};

/// Options of `dampscope diagnose`.
#[derive(Debug, clap::Args)]
pub struct DiagnoseArgs {
    /// The recordings: a recording-set directory (sensor positions are needed).
    pub input: PathBuf,
    /// The model to check (TOML); it is simulated at the recordings' sensors and sample rate.
    #[arg(long, value_name = "PATH")]
    pub model: PathBuf,
    /// Modes of the model up to this frequency are compared, Hz.
    #[arg(long, default_value_t = 80.0)]
    pub fmax_modes_hz: f64,
    /// Widest mode-centred band, Hz.
    #[arg(long, default_value_t = 20.0)]
    pub max_band_hz: f64,
    /// Candidate cells for local loss, NXxNY over the plate (aligned with the mesh is best).
    #[arg(long, default_value = "4x6")]
    pub cells: String,
    /// Relative model-form uncertainty of the simulated per-mode damping (0.01 = 1 %).
    #[arg(long, default_value_t = 0.01)]
    pub model_form: f64,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

fn parse_cells(s: &str) -> anyhow::Result<(usize, usize)> {
    let (a, b) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("invalid --cells {s:?}: expected NXxNY, e.g. 4x6"))?;
    let (nx, ny): (usize, usize) = (
        a.trim()
            .parse()
            .with_context(|| format!("invalid --cells {s:?}"))?,
        b.trim()
            .parse()
            .with_context(|| format!("invalid --cells {s:?}"))?,
    );
    if nx == 0 || ny == 0 {
        bail!("invalid --cells {s:?}: expected at least 1x1");
    }
    Ok((nx, ny))
}

/// Mode-centred Goyder analysis (T20) of `source` in `bands`.
fn analyze_modes(source: Box<dyn Source>, bands: &[Band]) -> anyhow::Result<Vec<ResultRow>> {
    let fs = source.info().sample_rate_hz;
    let band_args = BandArgs {
        range: "t20".into(),
        ..BandArgs::default()
    };
    let config = AnalysisConfig {
        estimate: band_args.estimate()?,
        ..AnalysisConfig::default()
    };
    make_front_end(
        FrontEndChoice::Goyder,
        &band_args,
        DirectionArg::Reversed,
        fs,
        bands,
    )?;
    let bands = bands.to_vec();
    let factory: FrontEndFactory = Arc::new(move || {
        make_front_end(
            FrontEndChoice::Goyder,
            &band_args,
            DirectionArg::Reversed,
            fs,
            &bands,
        )
    });
    let mut rows = Vec::new();
    pipeline::run(source, &factory, &config, |r| {
        rows.extend_from_slice(r);
        Ok(())
    })?;
    Ok(rows)
}

/// Simulates `model` and analyses its responses like the recordings.
fn simulated_modes(model: &Model, bands: &[Band]) -> anyhow::Result<Vec<ModeDamping>> {
    let sim = simulate(model, &SimulateOptions::default())?;
    let info = SignalInfo {
        sample_rate_hz: sim.fs_hz,
        channel_names: sim.sensors.iter().map(|s| s.id.clone()).collect(),
    };
    let source = Box::new(MemorySource::new(info, sim.impulse_responses)?);
    Ok(per_mode_damping(&analyze_modes(source, bands)?, bands))
}

fn pct(v: Option<f64>) -> String {
    v.map_or("—".into(), |v| format!("{:.3}", 100.0 * v))
}

fn describe(h: &Hypothesis, cells: &[Cell], fractions: &faer::Mat<f64>) -> String {
    let span = |c: &Cell| {
        format!(
            "x {:.3}–{:.3} m, y {:.3}–{:.3} m",
            c.x_m[0], c.x_m[1], c.y_m[0], c.y_m[1]
        )
    };
    match h {
        Hypothesis::NoChange => "no change: the model's damping explains the recordings".into(),
        Hypothesis::GlobalLoss { delta_g } => {
            format!(
                "global loss factor {delta_g:+.4} (D {:+.3} %)",
                50.0 * delta_g
            )
        }
        Hypothesis::LocalLoss { cells: used } => {
            let parts: Vec<String> = used
                .iter()
                .map(|&(r, g)| {
                    let twins = indistinguishable(fractions, r, 0.02);
                    let also = if twins.is_empty() {
                        String::new()
                    } else {
                        let t: Vec<String> = twins.iter().map(|&q| span(&cells[q])).collect();
                        format!(
                            " (or, indistinguishable by modal damping: {})",
                            t.join(", ")
                        )
                    };
                    format!("{}: Δg {g:.4}{also}", span(&cells[r]))
                })
                .collect();
            format!("extra loss in {} cell(s): {}", used.len(), parts.join("; "))
        }
    }
}

/// Runs `diagnose`.
pub fn run(args: &DiagnoseArgs) -> anyhow::Result<()> {
    let (nx, ny) = parse_cells(&args.cells)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let set = open_recording_set(&args.input)?;
    let fs = set.source.info().sample_rate_hz;
    let mut model = Model::load(&args.model)?;
    // Simulate at the recordings' sensors and time step.
    let sensors_csv: PathBuf = std::fs::canonicalize(args.input.join("sensors.csv"))
        .with_context(|| format!("{}: no sensors.csv", args.input.display()))?;
    model.output.sensors = SensorSpec::File { file: sensors_csv };
    model.output.fmax = 0.5 * fs;
    let sys = assemble(&model)?;
    let modes = lowest_modes(&sys, ModeRequest::BelowHz(args.fmax_modes_hz))?;
    let keep: Vec<usize> = (0..modes.frequencies_hz.len())
        .filter(|&i| modes.frequencies_hz[i] > 0.5)
        .collect();
    if keep.len() < 2 {
        bail!(
            "only {} mode(s) below {} Hz: raise --fmax-modes-hz",
            keep.len(),
            args.fmax_modes_hz
        );
    }
    let freqs: Vec<f64> = keep.iter().map(|&i| modes.frequencies_hz[i]).collect();
    let bands = bands_around_modes(&freqs, args.max_band_hz)?;
    eprintln!(
        "dampscope: analysing {} modes below {} Hz in the recordings and the model",
        bands.len(),
        args.fmax_modes_hz
    );
    let recorded = per_mode_damping(&analyze_modes(set.source, &bands)?, &bands);
    let simulated = simulated_modes(&model, &bands)?;

    let cells = cell_grid(model.plate.lx, model.plate.ly, nx, ny);
    let all_fractions = cell_energy_fractions(&model, &modes, &cells)?;
    // Modes measured on both sides.
    let used: Vec<usize> = (0..bands.len())
        .filter(|&k| recorded[k].median_d.is_some() && simulated[k].median_d.is_some())
        .collect();
    if used.len() < 2 {
        bail!(
            "only {} mode(s) measured in both recordings and model",
            used.len()
        );
    }
    let residual: Vec<f64> = used
        .iter()
        .map(|&k| recorded[k].median_d.unwrap_or(0.0) - simulated[k].median_d.unwrap_or(0.0))
        .collect();
    // The estimator checks itself on the model: where its per-mode D on the simulated
    // responses misses the model's own modal D (modal strain energy), that mode's difference
    // is trusted less by as much (close modes and nodal lines bias decay estimates).
    let bias: Vec<f64> = used
        .iter()
        .map(|&k| {
            let i = keep[k];
            let m = modal_stiffness(&sys, modes.frequencies_hz[i], modes.shapes.as_ref(), i);
            simulated[k].median_d.unwrap_or(0.0) - 0.5 * m.im / m.re
        })
        .collect();
    let sigma: Vec<f64> = used
        .iter()
        .zip(&bias)
        .map(|(&k, b)| {
            let (r, s) = (recorded[k], simulated[k]);
            let se = r.std_error.unwrap_or(0.0).powi(2) + s.std_error.unwrap_or(0.0).powi(2);
            let floor = (args.model_form * s.median_d.unwrap_or(0.0)).powi(2);
            (se + floor + b * b).sqrt().max(1e-9)
        })
        .collect();
    let fractions = faer::Mat::from_fn(used.len(), cells.len(), |i, r| {
        all_fractions[(keep[used[i]], r)]
    });
    let fits = fit_hypotheses(&residual, &sigma, &fractions);
    let best = fits[0].hypothesis.clone();
    let updated = updated_model(&model, &cells, &best);
    let after = if best == Hypothesis::NoChange {
        simulated.clone()
    } else {
        simulated_modes(&updated, &bands)?
    };
    write_outputs(
        &args.out, &bands, &recorded, &simulated, &after, &fits, &updated,
    )?;

    let rms = |sim: &[ModeDamping]| -> f64 {
        let v: Vec<f64> = used
            .iter()
            .map(|&k| recorded[k].median_d.unwrap_or(0.0) - sim[k].median_d.unwrap_or(f64::NAN))
            .collect();
        (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
    };
    println!(
        "{:>9} {:>9} {:>9} {:>9}",
        "mode Hz", "D rec %", "D model %", "D upd %"
    );
    for k in 0..bands.len() {
        println!(
            "{:>9.2} {:>9} {:>9} {:>9}",
            bands[k].center_hz,
            pct(recorded[k].median_d),
            pct(simulated[k].median_d),
            pct(after[k].median_d)
        );
    }
    println!(
        "{:<12} {:>10} {:>3} {:>10}",
        "hypothesis", "chi2", "k", "BIC"
    );
    for f in &fits {
        let name = match f.hypothesis {
            Hypothesis::NoChange => "none",
            Hypothesis::GlobalLoss { .. } => "global loss",
            Hypothesis::LocalLoss { .. } => "local loss",
        };
        println!(
            "{name:<12} {:>10.2} {:>3} {:>10.2}",
            f.chi2, f.n_params, f.bic
        );
    }
    println!("verdict: {}", describe(&best, &cells, &fractions));
    println!(
        "fit over {} modes: rms(D_rec − D_model) {:.4} % before, {:.4} % after the update",
        used.len(),
        100.0 * rms(&simulated),
        100.0 * rms(&after)
    );
    println!(
        "wrote {}/modes.csv, hypotheses.csv, updated.toml",
        args.out.display()
    );
    Ok(())
}

fn write_outputs(
    out: &Path,
    bands: &[Band],
    recorded: &[ModeDamping],
    simulated: &[ModeDamping],
    after: &[ModeDamping],
    fits: &[crate::diagnose::Fit],
    updated: &Model,
) -> anyhow::Result<()> {
    #[derive(serde::Serialize)]
    struct Row {
        mode_hz: f64,
        d_recorded: Option<f64>,
        d_model: Option<f64>,
        d_updated: Option<f64>,
        n_recorded: usize,
    }
    write_csv(
        &out.join("modes.csv"),
        (0..bands.len()).map(|k| Row {
            mode_hz: bands[k].center_hz,
            d_recorded: recorded[k].median_d,
            d_model: simulated[k].median_d,
            d_updated: after[k].median_d,
            n_recorded: recorded[k].n,
        }),
    )?;
    #[derive(serde::Serialize)]
    struct FitRow {
        hypothesis: String,
        chi2: f64,
        n_params: usize,
        bic: f64,
    }
    let fit_rows: Vec<FitRow> = fits
        .iter()
        .map(|f| -> anyhow::Result<FitRow> {
            Ok(FitRow {
                hypothesis: serde_json::to_string(&f.hypothesis)?,
                chi2: f.chi2,
                n_params: f.n_params,
                bic: f.bic,
            })
        })
        .collect::<anyhow::Result<_>>()?;
    write_csv(&out.join("hypotheses.csv"), fit_rows)?;
    let toml = toml::to_string(updated).context("cannot write the updated model as TOML")?;
    std::fs::write(out.join("updated.toml"), toml)
        .with_context(|| format!("cannot write {}", out.join("updated.toml").display()))?;
    Ok(())
}

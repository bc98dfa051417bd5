//! `dampscope diagnose RECORDINGS --model M.toml --out DIR`: where and how the model's damping
//! differs from the recordings (see [`crate::diagnose`]), the model updated with the best
//! hypothesis, and the fit before and after.
//!
//! Writes `modes.csv` (per mode: recorded, simulated and updated D), `hypotheses.csv`,
//! `updated.toml` (the model with the hypothesis applied) and prints the verdict.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{bail, Context};

use super::analyze::MAX_WHOLE_SAMPLES;
use super::analyze::{make_front_end, FrontEndChoice};
use super::bands_arg::BandArgs;
use super::compare::DirectionArg;
use super::write_csv;
use crate::diagnose::{
    cell_energy_fractions, cell_grid, cell_images, fit_hypotheses, indistinguishable,
    per_mode_damping, updated_model, Cell, Hypothesis, ModeDamping,
};
use crate::frontend::auto_bands::bands_around_modes;
use crate::frontend::Band;
use crate::pipeline::{self, AnalysisConfig, FrontEndFactory, ResultRow};
use crate::sim::assembly::assemble;
use crate::sim::eigen::{lowest_modes, ModeRequest, Modes};
use crate::sim::model::{Model, SensorSpec};
use crate::sim::simulate::{simulate_system, SimulateOptions};
use crate::sim::truncation::modal_stiffness;
use crate::source::memory::{read_all, MemorySource};
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

/// Impulse responses of `model` at its sensors. Loss factors do not change the undamped
/// modes, so every variant of one mesh reuses `modes` (modes below 1.5 fmax).
fn impulse_responses(model: &Model, modes: &Modes) -> anyhow::Result<Vec<Vec<f64>>> {
    let sys = assemble(model)?;
    let r = simulate_system(
        &sys,
        Some(modes),
        model.output.fmax,
        model.output.df,
        &SimulateOptions::default(),
    )?;
    Ok(r.impulse_responses)
}

/// Analyses impulse responses like the recordings: per-mode damping.
fn measured_modes(
    irs: &[Vec<f64>],
    fs_hz: f64,
    names: &[String],
    bands: &[Band],
) -> anyhow::Result<Vec<ModeDamping>> {
    let info = SignalInfo {
        sample_rate_hz: fs_hz,
        channel_names: names.to_vec(),
    };
    let source = Box::new(MemorySource::new(info, irs.to_vec())?);
    Ok(per_mode_damping(&analyze_modes(source, bands)?, bands))
}

/// Time-response misfit Σ (x_rec − x_sim)² / Σ x_rec² over all channels (common length).
fn misfit(recorded: &[Vec<f64>], simulated: &[Vec<f64>]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (r, s) in recorded.iter().zip(simulated) {
        for (a, b) in r.iter().zip(s) {
            num += (a - b) * (a - b);
            den += a * a;
        }
    }
    if den > 0.0 {
        num / den
    } else {
        f64::INFINITY
    }
}

fn pct(v: Option<f64>) -> String {
    v.map_or("—".into(), |v| format!("{:.3}", 100.0 * v))
}

fn describe(
    h: &Hypothesis,
    cells: &[Cell],
    fractions: &faer::Mat<f64>,
    settled: &[usize],
) -> String {
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
                    let also = if twins.is_empty() || settled.contains(&r) {
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
    // One eigen-solve serves both the simulations (modes below 1.5 fmax) and the comparison
    // (modes below --fmax-modes-hz).
    let fast_modes = lowest_modes(
        &sys,
        ModeRequest::BelowHz(args.fmax_modes_hz.max(1.5 * model.output.fmax)),
    )?;
    let n_compared = fast_modes
        .frequencies_hz
        .iter()
        .filter(|f| **f < args.fmax_modes_hz)
        .count();
    let modes = Modes {
        frequencies_hz: fast_modes.frequencies_hz[..n_compared].to_vec(),
        shapes: fast_modes.shapes.subcols(0, n_compared).to_owned(),
    };
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
    let names: Vec<String> = set.sensors.iter().map(|s| s.id.clone()).collect();
    let base_irs = impulse_responses(&model, &fast_modes)?;
    let simulated = measured_modes(&base_irs, fs, &names, &bands)?;

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
    let mut best = fits[0].hypothesis.clone();
    let mut tie_break = None;
    let mut settled_cells: Vec<usize> = Vec::new();
    let after = match &best {
        Hypothesis::NoChange => simulated.clone(),
        Hypothesis::LocalLoss { cells: found } => {
            // Mirror images are indistinguishable by modal damping; the time responses at the
            // sensors (the excitation is off-centre) can still tell them apart. Each cell
            // (largest Δg first) takes the image that fits the time responses best; then every
            // single-cell swap of the result is checked to say whether the choice is clear.
            let mut recordings = open_recording_set(&args.input)?;
            let rec = read_all(recordings.source.as_mut(), MAX_WHOLE_SAMPLES)?;
            let rho0 = misfit(&rec, &base_irs);
            let (lx, ly) = (model.plate.lx, model.plate.ly);
            let gmax = found.iter().map(|p| p.1).fold(0.0, f64::max);
            let mut set: Vec<(usize, f64)> = found
                .iter()
                .copied()
                .filter(|p| p.1 >= 0.05 * gmax)
                .collect();
            set.sort_by(|a, b| b.1.total_cmp(&a.1));
            let mut cache: Vec<(Vec<usize>, f64)> = Vec::new();
            let mut rho_of = |set: &[(usize, f64)]| -> anyhow::Result<f64> {
                let mut key: Vec<usize> = set.iter().map(|p| p.0).collect();
                key.sort_unstable();
                if let Some((_, rho)) = cache.iter().find(|(k, _)| *k == key) {
                    return Ok(*rho);
                }
                let h = Hypothesis::LocalLoss {
                    cells: set.to_vec(),
                };
                let rho = misfit(
                    &rec,
                    &impulse_responses(&updated_model(&model, &cells, &h), &fast_modes)?,
                );
                cache.push((key, rho));
                Ok(rho)
            };
            let mut best_rho = rho_of(&set)?;
            for k in 0..set.len() {
                for q in cell_images(&cells, set[k].0, &fractions, lx, ly) {
                    if set.iter().any(|p| p.0 == q) {
                        continue;
                    }
                    let mut cand = set.clone();
                    cand[k].0 = q;
                    let rho = rho_of(&cand)?;
                    if rho < best_rho {
                        (best_rho, set) = (rho, cand);
                    }
                }
            }
            // Verification, per cell: its image is settled when every other image of it fits
            // worse by at least a quarter of what the cell itself contributes to the fit.
            let mut settled = Vec::with_capacity(set.len());
            for k in 0..set.len() {
                let mut runner_up = f64::INFINITY;
                for q in cell_images(&cells, set[k].0, &fractions, lx, ly) {
                    if set.iter().any(|p| p.0 == q) {
                        continue;
                    }
                    let mut cand = set.clone();
                    cand[k].0 = q;
                    runner_up = runner_up.min(rho_of(&cand)?);
                }
                let without: Vec<(usize, f64)> = set
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != k)
                    .map(|(_, p)| *p)
                    .collect();
                let effect = if without.is_empty() {
                    rho0
                } else {
                    rho_of(&without)?
                } - best_rho;
                let ok = runner_up.is_infinite()
                    || (effect > 0.0 && runner_up - best_rho >= 0.25 * effect);
                settled.push((set[k].0, ok));
            }
            let resolved = settled.iter().all(|p| p.1);
            let mut tried: Vec<(f64, Hypothesis)> = cache
                .iter()
                .map(|(k, rho)| {
                    let c = k.iter().map(|&r| (r, 0.0)).collect();
                    (*rho, Hypothesis::LocalLoss { cells: c })
                })
                .collect();
            tried.sort_by(|p, q| p.0.total_cmp(&q.0));
            tie_break = Some((rho0, tried, resolved));
            settled_cells = settled.iter().filter(|p| p.1).map(|p| p.0).collect();
            best = Hypothesis::LocalLoss { cells: set };
            let irs = impulse_responses(&updated_model(&model, &cells, &best), &fast_modes)?;
            measured_modes(&irs, fs, &names, &bands)?
        }
        Hypothesis::GlobalLoss { .. } => {
            let irs = impulse_responses(&updated_model(&model, &cells, &best), &fast_modes)?;
            measured_modes(&irs, fs, &names, &bands)?
        }
    };
    let updated = updated_model(&model, &cells, &best);
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
    if let Some((rho0, tried, resolved)) = &tie_break {
        if tried.len() > 1 {
            println!(
                "mirror images: time-response misfit Σ(x_rec − x_sim)²/Σx_rec² (model as given: {rho0:.3e})"
            );
            for (rho, h) in tried {
                if let Hypothesis::LocalLoss { cells: c } = h {
                    let where_: Vec<String> = c
                        .iter()
                        .map(|&(r, _)| {
                            let k = cells[r];
                            format!(
                                "x {:.2}–{:.2} y {:.2}–{:.2}",
                                k.x_m[0], k.x_m[1], k.y_m[0], k.y_m[1]
                            )
                        })
                        .collect();
                    println!("  {rho:.3e}  {}", where_.join(", "));
                }
            }
            println!(
                "{}",
                if *resolved {
                    "mirror ambiguity resolved by the time responses"
                } else {
                    "mirror ambiguity resolved only in part: cells still listed with their images are not settled"
                }
            );
        }
    }
    println!(
        "verdict: {}",
        describe(&best, &cells, &fractions, &settled_cells)
    );
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

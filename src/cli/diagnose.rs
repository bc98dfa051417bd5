//! `dampscope diagnose RECORDINGS --model M.toml --out DIR`: what physics the model lacks
//! ([`crate::diagnose::procedure::diagnose`]), the model updated with it, and the fit before
//! and after.
//!
//! Prints the findings; the files ([`crate::diagnose::output::write_diagnosis`]) go to `--out`.

use std::path::PathBuf;

use anyhow::Context;

use crate::diagnose::output::write_diagnosis;
use crate::diagnose::procedure::{
    diagnose_with_progress, DiagnoseSettings, DEFAULT_DIAGNOSE_FMAX_HZ, MODEL_RANGE_FACTOR,
};
use crate::diagnose::score::DEFAULT_MODEL_FORM_SIGMA;
use crate::modal::model_shapes::sensor_positions;
use crate::modal::Recordings;
use crate::sim::model::Model;
use crate::source::recording_set::open_recording_set;

/// Most samples per channel read.
const MAX_DIAGNOSE_SAMPLES: usize = 1 << 24;

/// Name the physics the model lacks (mass, stiffness, edge support, loss, damping law, noise), where and how much; update the model, show the fit.
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

/// Runs `dampscope diagnose`.
pub fn run(args: &DiagnoseArgs) -> anyhow::Result<()> {
    let mut set = open_recording_set(&args.input)
        .with_context(|| format!("recording set {}", args.input.display()))?;
    super::warn_all(&set.warnings);
    let sensors = sensor_positions(&set.sensors)
        .with_context(|| format!("recording set {}", args.input.display()))?;
    let mut rec = Recordings::from_source(set.source.as_mut(), MAX_DIAGNOSE_SAMPLES)
        .with_context(|| format!("reading {}", args.input.display()))?;
    if let Some(snr) = args.add_noise_db {
        rec.add_noise_mean_power(snr, args.seed);
    }
    let model =
        Model::load(&args.model).with_context(|| format!("model {}", args.model.display()))?;
    super::warn_all(&crate::sim::resolution::model_warnings(&model, args.fmax));
    super::warn_all(
        crate::diagnose::nuisance::pattern_warning(&model, MODEL_RANGE_FACTOR * args.fmax)
            .as_slice(),
    );
    let settings = DiagnoseSettings {
        fmax_hz: args.fmax,
        excitation_m: set.excitation.first().map(|e| (e.x_m, e.y_m)),
        model_form_sigma: 0.01 * args.model_form_percent,
        // A window the responses carry (FRFs from an impact test) is not the structure's loss.
        exponential_window_tau_s: set.meta.exponential_window_tau_s,
        derivatives_to_acceleration: set.meta.derivatives_to_acceleration().ok(),
        ..DiagnoseSettings::default()
    };
    if let Err(why) = set.meta.derivatives_to_acceleration() {
        super::warn_all(&[format!(
            "{why}: no FRF error is computed; the modes' frequencies, damping and shapes are \
             compared as usual"
        )]);
    }
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
    write_diagnosis(&args.out, &d, &args.input, &args.model)
        .with_context(|| format!("writing the diagnosis into {}", args.out.display()))
}

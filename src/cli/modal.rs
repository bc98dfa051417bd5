//! `dampscope modal INPUT --fmax HZ --out DIR`: multichannel modal identification
//! ([`crate::modal::identify`]); this module only parses, calls and writes.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;

use super::args::InputFormatArgs;
use crate::modal::model_shapes::{
    match_model, model_modes_at, sensor_positions, ModelMatch, MODEL_FMAX_FACTOR,
};
use crate::modal::{identify_with_progress, ModalResult, ModalSettings, Recordings};
use crate::source::open::open_input;

/// Most samples per channel `modal` reads (the identification holds the whole record).
pub const MAX_MODAL_SAMPLES: usize = 1 << 26;

/// Modal identification from all channels at once: modes.csv, shapes.csv, stabilisation.png.
#[derive(Debug, Clone, clap::Args)]
pub struct ModalArgs {
    /// A recording set directory, a .wav/.csv file, or `-` for standard input.
    pub input: String,
    /// How to read raw or headerless input.
    #[command(flatten)]
    pub input_format: InputFormatArgs,
    /// Lowest frequency of interest, Hz.
    #[arg(long, default_value_t = 0.5, value_name = "HZ")]
    pub fmin: f64,
    /// Highest frequency of interest, Hz.
    #[arg(long, value_name = "HZ")]
    pub fmax: f64,
    /// Write modes.csv, shapes.csv, stabilisation.png and a shape figure per mode here.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Narrowest sub-band, Hz (sub-bands are 40 % of their lower edge wide, within these limits).
    #[arg(long, default_value_t = crate::modal::DEFAULT_SUBBANDS.min_width_hz, value_name = "HZ")]
    pub min_band_width: f64,
    /// Widest sub-band, Hz.
    #[arg(long, default_value_t = crate::modal::DEFAULT_SUBBANDS.max_width_hz, value_name = "HZ")]
    pub max_band_width: f64,
    /// Highest model order swept per sub-band.
    #[arg(long, default_value_t = crate::modal::DEFAULT_MAX_ORDER, value_name = "N")]
    pub max_order: usize,
    /// Analysis start in s (default: the sample after the peak of the summed squared channels).
    #[arg(long, value_name = "S")]
    pub start_s: Option<f64>,
    /// Add white noise at this SNR on mean signal power, dB (for robustness studies).
    #[arg(long, value_name = "DB")]
    pub add_noise_db: Option<f64>,
    /// Seed of --add-noise-db.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Time constant τ of an exponential window e^(−t/τ) already applied to the responses, s
    /// (default: `exponential_window_tau_s` of the recording set's meta.json, if any); its
    /// decay rate is subtracted from every pole.
    #[arg(long, value_name = "S")]
    pub exponential_window_s: Option<f64>,
    /// Plate model (TOML) whose mode shapes, read at the recording set's sensor positions, are
    /// paired with the identified ones by MAC (columns model_mode, model_frequency_hz,
    /// mac_model of modes.csv).
    #[arg(long, value_name = "PATH")]
    pub model: Option<PathBuf>,
    /// Print read / identify / write times on stderr.
    #[arg(long)]
    pub timings: bool,
}

#[derive(serde::Serialize)]
struct ModeRow {
    mode: usize,
    frequency_hz: f64,
    damping_ratio: f64,
    frequency_std_hz: f64,
    damping_std: f64,
    mpc: f64,
    n_stable: usize,
    modal_snr_db: f64,
    frequency_order_std_hz: f64,
    damping_order_std: f64,
    frequency_sensor_std_hz: f64,
    damping_sensor_std: f64,
    model_mode: Option<usize>,
    model_frequency_hz: Option<f64>,
    mac_model: Option<f64>,
}

#[derive(serde::Serialize)]
struct ShapeRow<'a> {
    mode: usize,
    sensor: &'a str,
    x: Option<f64>,
    y: Option<f64>,
    re: f64,
    im: f64,
    magnitude: f64,
    phase_deg: f64,
}

fn mode_rows<'a>(
    result: &'a ModalResult,
    matches: &'a [Option<ModelMatch>],
) -> impl Iterator<Item = ModeRow> + 'a {
    result.modes.iter().enumerate().map(|(k, m)| {
        let hit = matches.get(k).copied().flatten();
        ModeRow {
            mode: k + 1,
            frequency_hz: m.frequency_hz,
            damping_ratio: m.damping_ratio,
            frequency_std_hz: m.frequency_std_hz,
            damping_std: m.damping_std,
            mpc: m.mpc,
            n_stable: m.n_stable,
            modal_snr_db: m.modal_snr_db,
            frequency_order_std_hz: m.frequency_order_std_hz,
            damping_order_std: m.damping_order_std,
            frequency_sensor_std_hz: m.frequency_sensor_std_hz,
            damping_sensor_std: m.damping_sensor_std,
            model_mode: hit.map(|h| h.model_mode),
            model_frequency_hz: hit.map(|h| h.model_frequency_hz),
            mac_model: hit.map(|h| h.mac),
        }
    })
}

fn write_outputs(
    args: &ModalArgs,
    rec: &Recordings,
    result: &ModalResult,
    matches: &[Option<ModelMatch>],
    positions: Option<&[(f64, f64)]>,
) -> anyhow::Result<()> {
    let dir = &args.out;
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    crate::output::write_csv_file(&dir.join("modes.csv"), mode_rows(result, matches))?;
    let mut rows = Vec::new();
    for (k, m) in result.modes.iter().enumerate() {
        for (c, v) in m.shape.iter().enumerate() {
            rows.push(ShapeRow {
                mode: k + 1,
                sensor: &result.names[c],
                x: positions.map(|p| p[c].0),
                y: positions.map(|p| p[c].1),
                re: v.re,
                im: v.im,
                magnitude: v.norm(),
                phase_deg: v.arg().to_degrees(),
            });
        }
    }
    crate::output::write_csv_file(&dir.join("shapes.csv"), rows)?;
    // The same modes as a universal file (nodes 2411 + one dataset 55 per mode): they open in
    // the modal software labs use. Positions 0 where the input gave none.
    let sensors: Vec<crate::source::Sensor> = result
        .names
        .iter()
        .enumerate()
        .map(|(c, id)| crate::source::Sensor {
            id: id.clone(),
            x_m: positions.map_or(0.0, |p| p[c].0),
            y_m: positions.map_or(0.0, |p| p[c].1),
            z_m: None,
            dir: "z".into(),
        })
        .collect();
    let shapes: Vec<crate::output::uff::ModeShapeRecord> = result
        .modes
        .iter()
        .map(|m| crate::output::uff::ModeShapeRecord {
            frequency_hz: m.frequency_hz,
            damping_ratio: m.damping_ratio,
            shape: m.shape.clone(),
        })
        .collect();
    crate::output::uff::write_mode_shapes_uff(&dir.join("modes.uff"), &shapes, &sensors)?;
    crate::plot::stabilisation_diagram(
        result,
        &rec.mean_power_spectrum_db(),
        (args.fmin, args.fmax),
        &dir.join("stabilisation.png"),
    )?;
    if let Some(p) = positions {
        for (k, m) in result.modes.iter().enumerate() {
            let re: Vec<f64> = m.shape.iter().map(|v| v.re).collect();
            let versus_model = matches
                .get(k)
                .copied()
                .flatten()
                .map(|h| {
                    format!(
                        ", MAC {:.3} with model mode {} ({:.2} Hz)",
                        h.mac, h.model_mode, h.model_frequency_hz
                    )
                })
                .unwrap_or_default();
            crate::plot::mode_shape(
                &format!(
                    "mode {}: {:.2} Hz, D = {:.2} %, MPC {:.2}{versus_model}",
                    k + 1,
                    m.frequency_hz,
                    100.0 * m.damping_ratio,
                    m.mpc
                ),
                p,
                &re,
                &dir.join(format!("shape-{:02}.png", k + 1)),
            )?;
        }
    }
    Ok(())
}

/// A sub-band progress bar on stderr, drawn only when stderr is a terminal.
fn progress_bar() -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed:>4} [{bar:30}] sub-band {pos}/{len}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar
}

/// Runs `dampscope modal`.
pub fn run(args: &ModalArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let mut opened = open_input(&args.input, &args.input_format.options())?;
    super::warn_all(&opened.warnings);
    let mut rec = Recordings::from_source(opened.source.as_mut(), MAX_MODAL_SAMPLES)
        .with_context(|| format!("reading {}", args.input))?;
    if let Some(snr) = args.add_noise_db {
        rec.add_noise_mean_power(snr, args.seed);
    }
    let positions: Option<Vec<(f64, f64)>> = opened
        .sensors
        .as_ref()
        .map(|s| s.iter().map(|s| (s.x_m, s.y_m)).collect());
    let t_read = t0.elapsed().as_secs_f64();
    let settings = ModalSettings {
        subbands: crate::modal::SubBandPlan {
            min_width_hz: args.min_band_width,
            max_width_hz: args.max_band_width,
            ..crate::modal::DEFAULT_SUBBANDS
        },
        max_order: args.max_order,
        start_s: args.start_s,
        exponential_window_tau_s: args.exponential_window_s.or(opened
            .meta
            .as_ref()
            .and_then(|m| m.exponential_window_tau_s)),
        ..ModalSettings::new(args.fmin, args.fmax)
    };
    let bar = progress_bar();
    let result = identify_with_progress(&rec, &settings, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    let t_identify = t0.elapsed().as_secs_f64() - t_read;
    for s in &result.skipped {
        eprintln!(
            "dampscope: sub-band {:.1}–{:.1} Hz gave no poles: {}",
            s.band.lo_hz, s.band.hi_hz, s.reason
        );
    }
    let matches = match &args.model {
        Some(path) => {
            let Some(sensors) = &opened.sensors else {
                anyhow::bail!(
                    "--model needs the sensors' positions: give a recording set (sensors.csv) as INPUT"
                );
            };
            let model = crate::sim::model::Model::load(path)
                .with_context(|| format!("model {}", path.display()))?;
            let positions = sensor_positions(sensors).context("sensors.csv")?;
            let model_modes = model_modes_at(&model, &positions, MODEL_FMAX_FACTOR * args.fmax)
                .with_context(|| format!("modes of the model {}", path.display()))?;
            match_model(&result.modes, &model_modes)
        }
        None => Vec::new(),
    };
    let t_model = t0.elapsed().as_secs_f64() - t_read - t_identify;
    println!("mode,frequency_hz,damping_ratio,frequency_std_hz,damping_std,mpc,n_stable,modal_snr_db,mac_model");
    for row in mode_rows(&result, &matches) {
        println!(
            "{},{:.4},{:.6},{:.4},{:.6},{:.3},{},{:.1},{}",
            row.mode,
            row.frequency_hz,
            row.damping_ratio,
            row.frequency_std_hz,
            row.damping_std,
            row.mpc,
            row.n_stable,
            row.modal_snr_db,
            row.mac_model.map_or(String::new(), |m| format!("{m:.4}"))
        );
    }
    write_outputs(args, &rec, &result, &matches, positions.as_deref())?;
    if args.timings {
        eprintln!(
            "timings: read {:.2} s, identify {:.2} s ({} channels × {} samples), model {:.2} s, write {:.2} s",
            t_read,
            t_identify,
            rec.channels.len(),
            rec.channels.first().map_or(0, Vec::len),
            t_model,
            t0.elapsed().as_secs_f64() - t_read - t_identify - t_model
        );
    }
    Ok(())
}

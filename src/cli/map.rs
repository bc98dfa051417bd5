//! `dampscope map INPUT --out DIR`: local damping maps over the sensors and the global
//! equivalent damping per band (report sections 3 and 4.2, eq. 4.3).
//!
//! Writes to DIR: `results.csv` (the full analysis table, as `analyze` writes it),
//! `global.csv` (per band: sensors, estimates, mean/median/spread of D, missing by reason),
//! `sensors_needed.csv` (the mean from every k-th sensor, section 4.2.1) and one PNG map per
//! band (`map_<lo>-<hi>Hz.png`). Prints the global table.

use std::path::PathBuf;

use anyhow::Context;

use super::analyze::{exit_code_of, prepare};
use super::args::InputFormatArgs;
use super::args::PipelineArgs;
use crate::analysis::maps::{band_maps, BandMap, GlobalDamping, MapError, SubsetMean};
use crate::output::atomic::AtomicFile;
use crate::output::write_csv_file;
use crate::output::{TableFormat, TableWriter};
use crate::pipeline::{self, ResultRow};
use crate::source::open::open_input;
use crate::source::recording_set::read_sensors;

/// Local damping maps over the sensors and the global damping per band (recording set).
#[derive(Debug, clap::Args)]
pub struct MapArgs {
    /// A recording-set directory (sensor positions from its sensors.csv), or any other input
    /// with --sensors.
    pub input: String,
    /// How to read raw or headerless input.
    #[command(flatten)]
    pub input_format: InputFormatArgs,
    /// Sensor positions (a sensors.csv as in a recording set: `id,x,y[,z,dir]`); wins over the
    /// recording set's own.
    #[arg(long, value_name = "FILE")]
    pub sensors: Option<PathBuf>,
    /// Front end, bands, range, decay detection (as for analyze).
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Which decay of each channel to map (0: the first).
    #[arg(long, default_value_t = 0)]
    pub decay: usize,
    /// Largest step k of the every-k-th-sensor study.
    #[arg(long, default_value_t = 20)]
    pub max_step: usize,
    /// Draw at most this many band maps (the tables always hold every band).
    #[arg(long, default_value_t = 40)]
    pub max_figures: usize,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// One row of sensors_needed.csv.
#[derive(serde::Serialize)]
struct NeededRow {
    f_lo_hz: f64,
    f_hi_hz: f64,
    step: usize,
    n_nodes: usize,
    n_estimated: usize,
    mean_d: Option<f64>,
    rel_change: Option<f64>,
}

impl NeededRow {
    fn new(band: &crate::frontend::Band, s: SubsetMean) -> Self {
        NeededRow {
            f_lo_hz: band.lo_hz,
            f_hi_hz: band.hi_hz,
            step: s.step,
            n_nodes: s.n_nodes,
            n_estimated: s.n_estimated,
            mean_d: s.mean_d,
            rel_change: s.rel_change,
        }
    }
}

fn percent(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |v| format!("{:.3}", 100.0 * v))
}

/// The global table as printed.
pub fn global_table(globals: &[GlobalDamping]) -> String {
    let mut s = format!(
        "{:>16} {:>11} {:>8} {:>8} {:>8} {:>9}  {}\n",
        "band Hz", "estimated", "mean D%", "median", "std", "mean Dc%", "missing"
    );
    for g in globals {
        s.push_str(&format!(
            "{:>16} {:>11} {:>8} {:>8} {:>8} {:>9}  {}\n",
            format!("{:.1}–{:.1}", g.f_lo_hz, g.f_hi_hz),
            format!("{}/{}", g.n_estimated, g.n_nodes),
            percent(g.mean_d),
            percent(g.median_d),
            percent(g.std_d),
            percent(g.mean_d_corrected),
            g.missing
        ));
    }
    s
}

/// Runs `map`; returns the exit code (0, or 3 when part of the input was damaged).
pub fn run(args: &MapArgs) -> anyhow::Result<i32> {
    let opened = open_input(&args.input, &args.input_format.options())?;
    super::warn_all(&opened.warnings);
    let sensors = match (&args.sensors, opened.sensors) {
        (Some(path), _) => read_sensors(path)?,
        (None, Some(s)) => s,
        (None, None) => return Err(MapError::NoSensors.into()),
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let window_tau_s = opened
        .meta
        .as_ref()
        .and_then(|m| m.exponential_window_tau_s);
    let run = prepare(&args.pipeline, opened.source, window_tau_s)?;
    let results = args.out.join("results.csv");
    let mut file = AtomicFile::create(&results)?;
    let mut writer = TableWriter::new(&mut file, TableFormat::Csv);
    let mut rows: Vec<ResultRow> = Vec::new();
    let ran = writer.write_header().and_then(|_| {
        pipeline::run(run.source, &run.factory, &run.config, |r| {
            rows.extend_from_slice(r);
            writer.write_rows(r)
        })
    });
    // Renamed into place also after an error: it holds every complete decay's rows.
    file.commit()?;
    let summary = ran?;
    let code = exit_code_of(&summary);
    let maps: Vec<BandMap> = band_maps(&rows, &sensors, args.decay)?;
    let globals: Vec<GlobalDamping> = maps.iter().map(BandMap::global).collect();
    write_csv_file(&args.out.join("global.csv"), &globals)?;
    write_csv_file(
        &args.out.join("sensors_needed.csv"),
        maps.iter().flat_map(|m| {
            m.sensors_needed(args.max_step)
                .into_iter()
                .map(|s| NeededRow::new(&m.band, s))
        }),
    )?;
    for m in maps.iter().take(args.max_figures) {
        let png = args
            .out
            .join(format!("map_{:.1}-{:.1}Hz.png", m.band.lo_hz, m.band.hi_hz));
        crate::plot::damping_map(m, &png)?;
    }
    if maps.len() > args.max_figures {
        eprintln!(
            "dampscope: warning: {} bands, maps drawn for the first {} (--max-figures)",
            maps.len(),
            args.max_figures
        );
    }
    print!("{}", global_table(&globals));
    println!(
        "wrote {}/results.csv, global.csv, sensors_needed.csv and {} map(s)",
        args.out.display(),
        maps.len().min(args.max_figures)
    );
    Ok(code)
}

//! `dampscope compare INPUT`: the same decays through several front ends, side by side; and
//! `dampscope compare --sweep`: the built-in study on synthetic decays with known damping.
//!
//! Compare is offline: the whole input is read into memory (at most
//! [`MAX_COMPARE_SAMPLES`] samples per channel), each channel's decay starts at its onset
//! (first sample within `--onset-level-db` of the peak) and runs to the end of the input.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;

use super::analyze::{make_front_end, FrontEndChoice};
use super::bands_arg::{BandArgs, InputFormatArgs};
use crate::analysis::sweep::{run_sweep, write_csv, SweepConfig, SweepRow, SWEEP_FRONT_ENDS};
use crate::decay::DecayEstimate;
use crate::error::{Error, Result};
use crate::frontend::goyder::FilterDirection;
use crate::frontend::onset::find_onset;
use crate::frontend::{Band, FrontEnd};
use crate::pipeline::analyze_decay;
use crate::source::stdin::open_input;
use crate::source::Block;

/// Most samples per channel that `compare` reads (2^27 ≈ 50 min at 44.1 kHz, 1 GiB as f64).
pub const MAX_COMPARE_SAMPLES: usize = 1 << 27;

/// Options of `dampscope compare`.
#[derive(Debug, clap::Args)]
pub struct CompareArgs {
    /// A .wav or .csv file, a recording-set directory, or `-` (not needed with --sweep).
    pub input: Option<String>,
    /// How to read raw or headerless input.
    #[command(flatten)]
    pub input_format: InputFormatArgs,
    /// Bands, STFT window and evaluation range (as for analyze). `--bands` also takes
    /// `auto` (one band per spectral peak of each channel's decay), `octave`, `third-octave`.
    #[command(flatten)]
    pub bands: BandArgs,
    /// Front ends to compare, comma-separated: stft, goyder, octave.
    #[arg(long, value_delimiter = ',', default_value = "stft,goyder")]
    pub front_ends: Vec<String>,
    /// Time direction of the Goyder and octave filters.
    #[arg(long, value_enum, default_value_t = DirectionArg::Reversed)]
    pub filter_direction: DirectionArg,
    /// Decay onset: first sample within this many dB of the peak.
    #[arg(long, default_value_t = 20.0)]
    pub onset_level_db: f64,
    /// Run the built-in sweep on synthetic decays instead of reading INPUT.
    #[arg(long)]
    pub sweep: bool,
    /// With --sweep: a reduced grid (2 frequencies × 2 dampings) for a quick look.
    #[arg(long)]
    pub sweep_reduced: bool,
    /// Directory for compare.csv, or for sweep.csv and sweep.png (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// `--filter-direction`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DirectionArg {
    /// Causal, in recording order.
    Forward,
    /// On the time-reversed decay (the decay rate is preserved).
    Reversed,
}

impl From<DirectionArg> for FilterDirection {
    fn from(d: DirectionArg) -> Self {
        match d {
            DirectionArg::Forward => FilterDirection::Forward,
            DirectionArg::Reversed => FilterDirection::Reversed,
        }
    }
}

impl From<FilterDirection> for DirectionArg {
    fn from(d: FilterDirection) -> Self {
        match d {
            FilterDirection::Forward => DirectionArg::Forward,
            FilterDirection::Reversed => DirectionArg::Reversed,
        }
    }
}

/// Resolves the band options for one decay (see [`BandArgs::resolve_with`]).
pub fn resolve_bands(
    args: &BandArgs,
    decay: &[f64],
    fs_hz: f64,
) -> Result<(Vec<Band>, Vec<String>)> {
    args.resolve_with(fs_hz, Some(&[decay]))
}

/// Builds the named front end.
pub fn build_front_end(
    name: &str,
    args: &CompareArgs,
    fs_hz: f64,
    bands: &[Band],
) -> Result<Box<dyn FrontEnd>> {
    let choice = match name.trim() {
        "stft" => FrontEndChoice::Stft,
        "goyder" => FrontEndChoice::Goyder,
        "octave" => FrontEndChoice::Octave,
        other => {
            return Err(Error::setting(
                "--front-ends",
                format!("expected stft, goyder or octave, got '{other}'"),
            ))
        }
    };
    make_front_end(choice, &args.bands, args.filter_direction, fs_hz, bands)
}

fn fmt_opt(v: Option<f64>, scale: f64, digits: usize) -> String {
    v.map_or("-".into(), |x| format!("{:.*}", digits, x * scale))
}

/// One table line for one channel, band and front end.
fn table_line(channel: &str, band: &Band, fe: &dyn FrontEnd, e: &DecayEstimate) -> Vec<String> {
    let r = fe.resolution();
    vec![
        channel.to_string(),
        format!("{:.2}-{:.2}", band.lo_hz, band.hi_hz),
        format!("{}", band.nominal_hz),
        fe.name().to_string(),
        fmt_opt(e.damping_ratio_corrected.or(e.damping_ratio), 100.0, 4),
        fmt_opt(e.t60_s, 1.0, 4),
        fmt_opt(e.r2, 1.0, 5),
        e.n_points.to_string(),
        format!("{:.3}", r.frame_period_s * 1e3),
        format!("{:.3}", r.time_resolution_s * 1e3),
        format!("{:.3}", r.frequency_resolution_hz),
        e.flags
            .iter()
            .map(|f| f.as_str())
            .collect::<Vec<_>>()
            .join(";"),
    ]
}

const HEADER: [&str; 12] = [
    "channel",
    "band_hz",
    "nominal_hz",
    "front_end",
    "d_pct",
    "t60_s",
    "r2",
    "n_points",
    "frame_ms",
    "t_res_ms",
    "f_res_hz",
    "flags",
];

fn read_all(args: &CompareArgs, input: &str) -> anyhow::Result<(f64, Vec<String>, Vec<Vec<f64>>)> {
    let opts = args.input_format.options();
    let mut opened = open_input(input, &opts)?;
    let info = opened.source.info().clone();
    let mut data: Vec<Vec<f64>> = vec![Vec::new(); info.channels()];
    let mut block = Block::default();
    while opened.source.read_block(1 << 16, &mut block)? {
        for (d, c) in data.iter_mut().zip(&block.channels) {
            d.extend_from_slice(c);
        }
        anyhow::ensure!(
            data.first().map_or(0, Vec::len) <= MAX_COMPARE_SAMPLES,
            "input {input} is longer than {MAX_COMPARE_SAMPLES} samples per channel, the most compare reads"
        );
    }
    Ok((info.sample_rate_hz, info.channel_names, data))
}

/// Runs `compare` (or the sweep with `--sweep`).
pub fn run(args: &CompareArgs) -> anyhow::Result<()> {
    if args.sweep || args.sweep_reduced {
        let dir = args.out.clone().unwrap_or_else(|| PathBuf::from("."));
        let cfg = if args.sweep_reduced {
            SweepConfig::reduced()
        } else {
            SweepConfig::default()
        };
        let rows = sweep_to_dir(&cfg, &dir)?;
        print!("{}", sweep_summary(&rows));
        println!(
            "wrote {} and {}",
            dir.join("sweep.csv").display(),
            dir.join("sweep.png").display()
        );
        return Ok(());
    }
    let input = args
        .input
        .as_deref()
        .context("compare needs INPUT (a file, a directory or -), or --sweep")?;
    let (fs, names, data) = read_all(args, input)?;
    let mut table: Vec<Vec<String>> = Vec::new();
    for (name, x) in names.iter().zip(&data) {
        let Some(onset) = find_onset(x, args.onset_level_db) else {
            eprintln!("dampscope: warning: channel {name} is silent; skipped");
            continue;
        };
        let decay = &x[onset..];
        let (bands, warnings) = resolve_bands(&args.bands, decay, fs)?;
        for w in warnings {
            eprintln!("dampscope: warning: {w}");
        }
        let settings = args.bands.estimate()?;
        let mut per_fe = Vec::new();
        for fe_name in &args.front_ends {
            let mut fe = build_front_end(fe_name, args, fs, &bands)?;
            let est = analyze_decay(decay, fe.as_mut(), &settings);
            per_fe.push((fe, est));
        }
        for (b, band) in bands.iter().enumerate() {
            for (fe, est) in &per_fe {
                table.push(table_line(name, band, fe.as_ref(), &est[b]));
            }
        }
    }
    print!("{}", aligned(&table));
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let path = dir.join("compare.csv");
        let mut w = csv::Writer::from_path(&path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        w.write_record(HEADER)?;
        for row in &table {
            w.write_record(row)?;
        }
        w.flush()?;
    }
    Ok(())
}

fn aligned(table: &[Vec<String>]) -> String {
    let mut widths: Vec<usize> = HEADER.iter().map(|h| h.len()).collect();
    for row in table {
        for (w, c) in widths.iter_mut().zip(row) {
            *w = (*w).max(c.chars().count());
        }
    }
    let mut out = String::new();
    let header: Vec<String> = HEADER.iter().map(|h| h.to_string()).collect();
    for row in std::iter::once(&header).chain(table) {
        for (c, w) in row.iter().zip(&widths) {
            let _ = write!(out, "{c:<w$}  ");
        }
        out.truncate(out.trim_end().len());
        out.push('\n');
    }
    out
}

/// Runs the sweep and writes `sweep.csv` and `sweep.png` into `dir` (created if missing).
pub fn sweep_to_dir(cfg: &SweepConfig, dir: &Path) -> Result<Vec<SweepRow>> {
    std::fs::create_dir_all(dir)?;
    let rows = run_sweep(cfg)?;
    write_csv(&rows, &dir.join("sweep.csv"))?;
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

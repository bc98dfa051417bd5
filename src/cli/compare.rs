//! `dampscope compare INPUT`: the same decays through several front ends, side by side
//! ([`crate::analysis::compare`]); and `dampscope compare --sweep`: the built-in study on
//! synthetic decays with known damping ([`crate::analysis::sweep`]).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context;

use super::args::{BandArgs, InputFormatArgs};
use crate::analysis::compare::{compare, ComparePlan, CompareRow, MODAL_FRONT_END};
use crate::analysis::sweep::{sweep_summary, sweep_to_dir, SweepConfig};
use crate::modal::Recordings;
use crate::pipeline::segment::DEFAULT_ONSET_LEVEL_DB;
use crate::plan::FrontEndKind;
use crate::source::memory::MAX_WHOLE_SAMPLES;
use crate::source::open::open_input;

/// One entry of `--front-ends`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CompareColumn {
    /// A front end's decay estimate.
    FrontEnd(FrontEndKind),
    /// The multichannel modal estimate.
    Modal,
}

fn parse_column(text: &str) -> Result<CompareColumn, String> {
    if text.trim() == MODAL_FRONT_END {
        return Ok(CompareColumn::Modal);
    }
    text.parse()
        .map(CompareColumn::FrontEnd)
        .map_err(|_| format!("expected stft, goyder, octave or modal, got '{text}'"))
}

/// Run STFT, Goyder bank and octave bank side by side on one input, or the built-in sweep.
#[derive(Debug, clap::Args)]
pub struct CompareArgs {
    /// A .wav or .csv file, a recording-set directory, or `-` (not needed with --sweep).
    pub input: Option<String>,
    /// How to read raw or headerless input.
    #[command(flatten)]
    pub input_format: InputFormatArgs,
    /// Bands, STFT window, filter banks and evaluation range (as for analyze). `--bands` also
    /// takes `auto` (one band per spectral peak of each channel's decay), `octave`,
    /// `third-octave`.
    #[command(flatten)]
    pub bands: BandArgs,
    /// Front ends to compare, comma-separated: stft, goyder, octave, and `modal` (the
    /// multichannel identification of `dampscope modal` over the bands' range: per channel and
    /// band, the mode that carries most of that channel's energy in the band).
    #[arg(long, value_delimiter = ',', default_value = "stft,goyder", value_parser = parse_column)]
    pub front_ends: Vec<CompareColumn>,
    /// Decay onset: first sample within this many dB of the peak.
    #[arg(long, default_value_t = DEFAULT_ONSET_LEVEL_DB)]
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

impl CompareArgs {
    /// The comparison these options describe.
    pub fn plan(&self) -> ComparePlan {
        ComparePlan {
            bands: self.bands.layout(),
            front_end: self.bands.front_end(FrontEndKind::Stft),
            kinds: self
                .front_ends
                .iter()
                .filter_map(|c| match c {
                    CompareColumn::FrontEnd(k) => Some(*k),
                    CompareColumn::Modal => None,
                })
                .collect(),
            modal: self.front_ends.contains(&CompareColumn::Modal),
            estimate: self.bands.estimate(),
            onset_level_db: self.onset_level_db,
        }
    }
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
    let mut opened = open_input(input, &args.input_format.options())?;
    super::warn_all(&opened.warnings);
    let rec = Recordings::from_source(opened.source.as_mut(), MAX_WHOLE_SAMPLES)?;
    let tau = opened.meta.and_then(|m| m.exponential_window_tau_s);
    let comparison = compare(&rec, tau, &args.plan())?;
    super::warn_all(&comparison.warnings);
    print!("{}", aligned(&comparison.rows));
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        crate::output::write_csv_file(&dir.join("compare.csv"), &comparison.rows)?;
    }
    Ok(())
}

/// The rows as an aligned text table (D and T60 to 4 decimals, resolutions to 3).
fn aligned(rows: &[CompareRow]) -> String {
    let num = |v: Option<f64>, digits: usize| v.map_or("-".into(), |x| format!("{x:.digits$}"));
    let header = [
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
        "d_std_pct",
        "f_hz",
    ];
    let mut table: Vec<Vec<String>> = vec![header.iter().map(|h| h.to_string()).collect()];
    for r in rows {
        table.push(vec![
            r.channel.clone(),
            r.band_hz.clone(),
            format!("{}", r.nominal_hz),
            r.front_end.to_string(),
            num(r.d_pct, 4),
            num(r.t60_s, 4),
            num(r.r2, 5),
            r.n_points.to_string(),
            num(r.frame_ms, 3),
            num(r.t_res_ms, 3),
            num(r.f_res_hz, 3),
            r.flags.clone(),
            num(r.d_std_pct, 4),
            num(r.f_hz, 3),
        ]);
    }
    let mut widths = vec![0; header.len()];
    for row in &table {
        for (w, c) in widths.iter_mut().zip(row) {
            *w = (*w).max(c.chars().count());
        }
    }
    let mut out = String::new();
    for row in &table {
        for (c, w) in row.iter().zip(&widths) {
            let _ = write!(out, "{c:<w$}  ");
        }
        out.truncate(out.trim_end().len());
        out.push('\n');
    }
    out
}

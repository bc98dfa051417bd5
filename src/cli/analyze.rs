//! `dampscope analyze INPUT`: decay times and damping ratios per band and channel.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::sync::Arc;

use anyhow::Context;

use super::bands_arg::BandArgs;
use super::{EXIT_OK, EXIT_PARTIAL};
use crate::frontend::stft::StftFrontEnd;
use crate::frontend::FrontEnd;
use crate::output::{TableFormat, TableWriter};
use crate::pipeline::{self, AnalysisConfig, FrontEndFactory};
use crate::source::raw::RawFormat;
use crate::source::stdin::{open_input, InputOptions};

/// Which time-frequency front end turns samples into band energies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FrontEndChoice {
    /// Short-time Fourier transform (Hann window).
    Stft,
}

/// Options of `dampscope analyze`.
#[derive(Debug, clap::Args)]
pub struct AnalyzeArgs {
    /// A .wav or .csv file, a recording-set directory, or `-` for standard input
    /// (WAV or CSV detected; raw samples with --raw).
    pub input: String,
    /// Standard input holds raw little-endian interleaved samples of this type.
    #[arg(long, value_name = "f32|f64")]
    pub raw: Option<RawFormat>,
    /// Sample rate in Hz (raw input, or CSV without a time column).
    #[arg(long = "fs", value_name = "HZ")]
    pub fs_hz: Option<f64>,
    /// Number of channels (required for raw input; checked for other inputs).
    #[arg(long)]
    pub channels: Option<usize>,
    /// Front end.
    #[arg(long, value_enum, default_value_t = FrontEndChoice::Stft)]
    pub front_end: FrontEndChoice,
    /// Bands, windows and evaluation range.
    #[command(flatten)]
    pub bands: BandArgs,
    /// Output table format.
    #[arg(long, value_enum, default_value_t = TableFormat::Csv)]
    pub format: TableFormat,
    /// Write the table here instead of standard output.
    #[arg(long, value_name = "FILE")]
    pub out: Option<std::path::PathBuf>,
    /// Decay onset: first sample within this many dB of the peak.
    #[arg(long, default_value_t = 20.0)]
    pub onset_level_db: f64,
    /// End a decay after this many seconds (bounds memory on endless streams).
    #[arg(long, value_name = "S")]
    pub max_decay_s: Option<f64>,
    /// End a decay when every band has fallen this many dB below its peak.
    #[arg(long, default_value_t = 100.0)]
    pub end_drop_db: f64,
    /// After a decay ends, a sample within this many dB of its peak starts the next one.
    #[arg(long, default_value_t = 20.0)]
    pub retrigger_db: f64,
}

/// Builds the front-end factory for the chosen front end.
pub fn front_end_factory(
    choice: FrontEndChoice,
    bands_args: &BandArgs,
    sample_rate_hz: f64,
) -> anyhow::Result<FrontEndFactory> {
    let bands = bands_args.resolve(sample_rate_hz)?;
    let stft = bands_args.stft();
    // Build one now so that bad settings fail before any thread starts.
    match choice {
        FrontEndChoice::Stft => {
            StftFrontEnd::new(stft, sample_rate_hz, &bands)?;
            Ok(Arc::new(move || {
                Ok(Box::new(StftFrontEnd::new(stft, sample_rate_hz, &bands)?) as Box<dyn FrontEnd>)
            }))
        }
    }
}

/// Runs `analyze`; returns the exit code (0, or 3 when part of the input was damaged).
pub fn run(args: &AnalyzeArgs) -> anyhow::Result<i32> {
    let opts = InputOptions {
        raw: args.raw,
        fs_hz: args.fs_hz,
        channels: args.channels,
    };
    let opened = open_input(&args.input, &opts)?;
    let info = opened.source.info().clone();
    let factory = front_end_factory(args.front_end, &args.bands, info.sample_rate_hz)?;
    if let Some(s) = args.max_decay_s {
        anyhow::ensure!(
            s > 0.0,
            "invalid setting --max-decay-s: expected > 0, got {s}"
        );
    }
    let config = AnalysisConfig {
        estimate: args.bands.estimate()?,
        onset_level_db: args.onset_level_db,
        max_decay_s: args.max_decay_s,
        end_drop_db: args.end_drop_db,
        retrigger_db: args.retrigger_db,
        ..Default::default()
    };
    let out: Box<dyn Write> = match &args.out {
        Some(p) => Box::new(BufWriter::new(
            File::create(p).with_context(|| format!("cannot create {}", p.display()))?,
        )),
        None => Box::new(std::io::stdout().lock()),
    };
    let mut writer = TableWriter::new(out, args.format);
    writer.write_header()?;
    let summary = pipeline::run(opened.source, &factory, &config, |rows| {
        writer.write_rows(rows)
    })?;
    let mut code = EXIT_OK;
    if let Some(e) = &summary.input_error {
        eprintln!(
            "dampscope: warning: {e}; results up to that point were written (flag input_truncated)"
        );
        code = EXIT_PARTIAL;
    }
    if !summary.non_finite_channels.is_empty() {
        eprintln!(
            "dampscope: warning: NaN or infinite samples in channel(s) {}: no estimates for them (flag non_finite_input)",
            summary.non_finite_channels.join(", ")
        );
        code = EXIT_PARTIAL;
    }
    Ok(code)
}

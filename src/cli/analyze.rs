//! `dampscope analyze INPUT`: decay times and damping ratios per band and channel.

use std::io::Write;

use super::args::{InputFormatArgs, PipelineArgs};
use super::{EXIT_OK, EXIT_PARTIAL};
use crate::analysis::spread::Spread;
use crate::output::atomic::AtomicFile;
use crate::output::{write_csv_file, TableFormat, TableWriter};
use crate::pipeline;
use crate::plan::PreparedRun;
use crate::source::open::open_input;
use crate::source::Source;

/// Estimate decay times and damping ratios per band and channel (file, directory or `-`).
#[derive(Debug, clap::Args)]
pub struct AnalyzeArgs {
    /// A .wav or .csv file, a recording-set directory, or `-` for standard input
    /// (WAV or CSV detected; raw samples with --raw).
    pub input: String,
    /// How to read raw or headerless input.
    #[command(flatten)]
    pub input_format: InputFormatArgs,
    /// Front end, bands, range, decay detection.
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Output table format.
    #[arg(long, value_enum, default_value_t = TableFormat::Csv)]
    pub format: TableFormat,
    /// Write the table here instead of standard output.
    #[arg(long, value_name = "FILE")]
    pub out: Option<std::path::PathBuf>,
    /// Also write, per channel and band, the decays combined with their spread (count, missing
    /// by reason, median/quartiles/min/max of D and T60, flagged share) to this CSV when the
    /// run ends (as `dampscope summarize` gives from the table).
    #[arg(long, value_name = "FILE")]
    pub summary: Option<std::path::PathBuf>,
}

/// Prepares the plan of `args` on `source`; prints its warnings to stderr.
/// `window_tau_s`: an exponential window the responses carry (FRF input, or declared by the
/// recording set); its damping is removed from every estimate.
pub fn prepare(
    args: &PipelineArgs,
    source: Box<dyn Source>,
    window_tau_s: Option<f64>,
) -> anyhow::Result<PreparedRun> {
    let mut run = args.plan().prepare(source)?;
    run.config.exponential_window_tau_s = window_tau_s;
    super::warn_all(&run.warnings);
    Ok(run)
}

/// Warns about damaged input or non-finite channels; returns the exit code (0, or 3 when
/// part of the input was damaged).
pub fn exit_code_of(summary: &pipeline::RunSummary) -> i32 {
    let mut code = EXIT_OK;
    if let Some(e) = &summary.input_error {
        let said = if e.cuts_decays_short() {
            "results up to that point were written (flag input_truncated)"
        } else {
            "the results written are those of what was read"
        };
        eprintln!("dampscope: warning: {e}; {said}");
        code = EXIT_PARTIAL;
    }
    if !summary.internal_error_channels.is_empty() {
        eprintln!(
            "dampscope: error: internal error in channel(s) {} (a bug; please report it with the input): their rows say internal_error, the other channels were analysed",
            summary.internal_error_channels.join(", ")
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
    code
}

/// Runs `analyze`; returns the exit code (0, or 3 when part of the input was damaged).
pub fn run(args: &AnalyzeArgs) -> anyhow::Result<i32> {
    let opened = open_input(&args.input, &args.input_format.options())?;
    super::warn_all(&opened.warnings);
    let window_tau_s = opened
        .meta
        .as_ref()
        .and_then(|m| m.exponential_window_tau_s);
    let run = prepare(&args.pipeline, opened.source, window_tau_s)?;
    // A results file is written under a temporary name and renamed into place when the run
    // ends, also when it ends on an error (it then holds every complete decay's rows, as the
    // exit code says); a killed run leaves no file under the final name.
    let mut file = match &args.out {
        Some(p) => Some(AtomicFile::create(p)?),
        None => None,
    };
    let out: Box<dyn Write + '_> = match &mut file {
        Some(f) => Box::new(f),
        None => Box::new(std::io::stdout().lock()),
    };
    let mut writer = TableWriter::new(out, args.format);
    let mut spread = args.summary.as_ref().map(|_| Spread::new());
    let ran = writer.write_header().and_then(|_| {
        pipeline::run(run.source, &run.factory, &run.config, |rows| {
            if let Some(s) = &mut spread {
                rows.iter().for_each(|r| s.add_row(r));
            }
            writer.write_rows(rows)
        })
    });
    drop(writer);
    if let Some(f) = file {
        f.commit()?;
    }
    // The spread of what was analysed, also after an input error (like the table).
    if let (Some(path), Some(s)) = (&args.summary, &spread) {
        write_csv_file(path, s.rows())?;
    }
    let summary = ran?;
    Ok(exit_code_of(&summary))
}

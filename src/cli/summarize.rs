//! `dampscope summarize RESULTS.csv`: the decays of a results table (as `analyze` writes it,
//! from a file or `-` for standard input) combined per channel and band with their spread
//! ([`crate::analysis::spread::summarize_table`]); CSV on standard output or `--out`.

use std::path::PathBuf;

use anyhow::Context;

use crate::analysis::spread::summarize_table;
use crate::output::write_csv_file;

/// Combine the decays of an analyze results table per channel and band: count, missing by reason, median/quartiles/min/max of D and T60.
#[derive(Debug, clap::Args)]
pub struct SummarizeArgs {
    /// A results table written by `dampscope analyze` (CSV), or `-` for standard input.
    pub input: String,
    /// Write the summary here instead of standard output.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// Runs `dampscope summarize`.
pub fn run(args: &SummarizeArgs) -> anyhow::Result<()> {
    let rows = if args.input == "-" {
        summarize_table(std::io::stdin().lock(), "standard input")?
    } else {
        let f = std::fs::File::open(&args.input)
            .with_context(|| format!("cannot read {}", args.input))?;
        summarize_table(std::io::BufReader::new(f), &args.input)?
    };
    match &args.out {
        Some(path) => write_csv_file(path, &rows)?,
        None => {
            let mut w = csv::Writer::from_writer(std::io::stdout().lock());
            for r in &rows {
                w.serialize(r)?;
            }
            w.flush()?;
        }
    }
    Ok(())
}

//! `dampscope bench`: throughput of the whole analysis per front end ([`crate::analysis::bench`]).

use std::io::IsTerminal;

use super::args::BandArgs;
use crate::analysis::bench::{
    bench, BenchInput, BenchPlan, BenchRow, DEFAULT_BENCH_CHANNELS, DEFAULT_BENCH_FS_HZ,
    DEFAULT_BENCH_REPEAT, DEFAULT_BENCH_SECONDS,
};
use crate::frontend::iec_bands::OctaveFraction;
use crate::pipeline::AnalysisConfig;
use crate::plan::{BandSpec, FrontEndKind};
use crate::source::memory::{read_all, MAX_WHOLE_SAMPLES};
use crate::source::open::{open_input, InputOptions};
use crate::source::raw::RawFormat;

/// How the bench prints its rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchFormat {
    /// An aligned table for reading.
    Table,
    /// One JSON object per row.
    Jsonl,
}

/// Time the whole analysis per front end on synthetic (or given) multichannel decays.
#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    /// Time this input (a file, recording set or `-`; read whole, then fed as raw f32 like the
    /// synthetic one) instead of the synthetic decays.
    pub input: Option<String>,
    /// With INPUT on standard input: raw little-endian samples of this type.
    #[arg(long, value_name = "f32|f64")]
    pub raw: Option<RawFormat>,
    /// Channels of the synthetic input (of a raw INPUT: its channel count).
    #[arg(long, value_name = "N")]
    pub channels: Option<usize>,
    /// Sample rates of the synthetic input, Hz, comma-separated (of a raw INPUT: its one rate).
    #[arg(long = "fs", value_delimiter = ',', value_name = "HZ")]
    pub fs_hz: Vec<f64>,
    /// Seconds of synthetic signal per channel.
    #[arg(long, default_value_t = DEFAULT_BENCH_SECONDS)]
    pub seconds: f64,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub threads: Option<usize>,
    /// Front ends to time, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "stft,octave,goyder")]
    pub front_ends: Vec<FrontEndKind>,
    /// Timed runs per front end (the fastest counts; one more, profiled, gives the stage shares).
    #[arg(long, default_value_t = DEFAULT_BENCH_REPEAT,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub repeat: usize,
    /// Output format.
    #[arg(long, value_enum, default_value_t = BenchFormat::Table)]
    pub format: BenchFormat,
    /// Bands, front-end settings and evaluation range (as for analyze). Without --band or
    /// --bands: IEC octave bands, as the Python peers use.
    #[command(flatten)]
    pub bands: BandArgs,
}

impl BenchArgs {
    /// The bench these options describe.
    pub fn plan(&self) -> BenchPlan {
        let mut bands = self.bands.layout();
        if bands.specs.is_empty() {
            bands.specs.push(BandSpec::Iec(OctaveFraction::Octave));
        }
        BenchPlan {
            front_ends: self.front_ends.clone(),
            front_end: self.bands.front_end(FrontEndKind::Stft),
            bands,
            config: AnalysisConfig {
                estimate: self.bands.estimate(),
                ..Default::default()
            },
            threads: self.threads,
            repeat: self.repeat,
        }
    }

    fn inputs(&self) -> anyhow::Result<Vec<BenchInput>> {
        let Some(path) = &self.input else {
            let rates: &[f64] = if self.fs_hz.is_empty() {
                &DEFAULT_BENCH_FS_HZ
            } else {
                &self.fs_hz
            };
            let channels = self.channels.unwrap_or(DEFAULT_BENCH_CHANNELS);
            return rates
                .iter()
                .map(|&fs| Ok(BenchInput::synthetic(channels, fs, self.seconds)?))
                .collect();
        };
        if self.fs_hz.len() > 1 {
            anyhow::bail!(
                "--fs: an input has one sample rate, got {} values",
                self.fs_hz.len()
            );
        }
        let options = InputOptions {
            raw: self.raw,
            fs_hz: self.fs_hz.first().copied(),
            channels: self.channels,
            ..Default::default()
        };
        let mut opened = open_input(path, &options)?;
        super::warn_all(&opened.warnings);
        let info = opened.source.info().clone();
        let data = read_all(opened.source.as_mut(), MAX_WHOLE_SAMPLES)?;
        let mut bytes = Vec::new();
        crate::output::raw::append_interleaved_f32_le(&data, &mut bytes);
        Ok(vec![BenchInput {
            bytes: bytes.into(),
            format: RawFormat::F32,
            fs_hz: info.sample_rate_hz,
            channels: data.len(),
        }])
    }
}

fn mega(x: f64) -> String {
    format!("{:.1}", x * 1e-6)
}

/// A duration with at most three decimals and no trailing zeros (10, 0.1, 0.894).
fn short(x: f64) -> String {
    let s = format!("{x:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn pct(x: f64) -> String {
    format!("{:.0}", 100.0 * x)
}

/// The aligned text line of a row.
pub fn table_line(r: &BenchRow) -> String {
    let stages = r.stages.map_or("-".to_string(), |s| {
        format!(
            "{}/{}/{}/{}/{}",
            pct(s.read),
            pct(s.segment),
            pct(s.front_end),
            pct(s.estimator),
            pct(s.output)
        )
    });
    format!(
        "{:>7} {:<7} {:>5} {:>4}×{:<6} {:>3} {:>8.4} {:>9} {:>9} {:>9} {:>9} {:>8} {:>16} {:>9}",
        r.fs_hz,
        r.front_end,
        r.bands,
        r.channels,
        format!("{}s", short(r.seconds)),
        r.threads,
        r.wall_s,
        mega(r.samples_per_s),
        mega(r.samples_per_s_per_channel),
        mega(r.samples_per_s_per_thread),
        format!("{:.0}", r.realtime_factor),
        mega(r.bytes_per_s),
        stages,
        r.fft_bound_samples_per_s.map_or("-".to_string(), mega),
    )
}

/// Header of [`table_line`].
pub const TABLE_HEADER: &str = "     fs front   bands  ch×s        thr   wall_s  Msmp/s  Msmp/s/ch Msmp/s/th  x_realtm     MB/s  %rd/sg/fe/es/out fft_bound";

/// Runs the bench and prints its rows as they are measured.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let plan = args.plan();
    let inputs = args.inputs()?;
    let steps = (inputs.len() * (1 + plan.front_ends.len())) as u64;
    let bar = if std::io::stderr().is_terminal() {
        indicatif::ProgressBar::new(steps)
    } else {
        indicatif::ProgressBar::hidden()
    };
    if args.format == BenchFormat::Table {
        println!("{TABLE_HEADER}");
    }
    for input in &inputs {
        bench(input, &plan, |row| {
            let line = match args.format {
                BenchFormat::Table => table_line(row),
                BenchFormat::Jsonl => serde_json::to_string(row).unwrap_or_default(),
            };
            bar.suspend(|| println!("{line}"));
            bar.inc(1);
        })?;
    }
    bar.finish_and_clear();
    Ok(())
}

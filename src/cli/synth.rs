//! `dampscope synth`: writes synthetic decays (report eq. 4.5) as WAV, raw f32 or CSV, to a file
//! or standard output, generated block by block so that `dampscope synth … | dampscope analyze -`
//! streams.

use std::io::{self, BufWriter, Write};

use anyhow::{bail, Context};

use crate::output::atomic::AtomicFile;
use crate::output::WavStreamWriter;
use crate::source::{Block, Mode, Source, SynthSource, SynthSpec};

/// Output format of `synth`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SynthFormat {
    /// 32-bit float WAV.
    Wav,
    /// Raw little-endian f32 samples (one channel).
    RawF32,
    /// CSV text: a `# fs=` comment, a `time,x` header, one row per sample.
    Csv,
}

/// Write decaying sines (report eq. 4.5) as WAV, raw f32 or CSV (stdout or --out).
#[derive(Clone, Debug, clap::Args)]
pub struct SynthArgs {
    /// A decaying sine `F:D[:A[:PSI]]`: frequency in Hz, damping ratio, amplitude (default 1),
    /// phase in degrees (default 0). Repeat for several modes.
    #[arg(long = "mode", value_name = "F:D[:A[:PSI]]", required = true)]
    pub modes: Vec<Mode>,
    /// Sample rate in Hz (a whole number for WAV).
    #[arg(long = "fs", value_name = "HZ", default_value_t = 4000.0)]
    pub fs_hz: f64,
    /// Length in seconds.
    #[arg(long = "seconds", value_name = "S", default_value_t = 4.0)]
    pub seconds: f64,
    /// Add white Gaussian noise at this peak SNR in dB (noise rms = max|x| · 10^(−SNR/20)).
    #[arg(long = "snr-db", value_name = "DB")]
    pub snr_db: Option<f64>,
    /// Seed of the noise generator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output file (default: standard output).
    #[arg(long, value_name = "FILE")]
    pub out: Option<String>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = SynthFormat::Wav)]
    pub format: SynthFormat,
}

impl SynthArgs {
    /// The signal these options describe.
    pub fn spec(&self) -> SynthSpec {
        SynthSpec {
            modes: self.modes.clone(),
            sample_rate_hz: self.fs_hz,
            duration_s: self.seconds,
            snr_db: self.snr_db,
            seed: self.seed,
        }
    }
}

/// Frames generated per block.
const BLOCK_FRAMES: usize = 8192;

/// Streams the whole signal of `src` in `format` to `out`.
fn write_signal(
    mut src: SynthSource,
    format: SynthFormat,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    let fs = src.info().sample_rate_hz;
    let n = src.n_samples();
    let mut block = Block::default();
    match format {
        SynthFormat::Wav => {
            if fs.fract() != 0.0 || fs > f64::from(u32::MAX) {
                bail!("invalid setting --fs: a WAV header needs a whole number of Hz, got {fs}");
            }
            let mut w = WavStreamWriter::new(&mut *out, fs as u32, 1, n)?;
            while src.read_block(BLOCK_FRAMES, &mut block)? {
                w.write_block(&block)?;
            }
            w.finish()?;
        }
        SynthFormat::RawF32 => {
            let mut buf = Vec::with_capacity(BLOCK_FRAMES * 4);
            while src.read_block(BLOCK_FRAMES, &mut block)? {
                buf.clear();
                crate::output::raw::append_interleaved_f32_le(&block.channels, &mut buf);
                out.write_all(&buf)?;
            }
        }
        SynthFormat::Csv => {
            writeln!(out, "# fs={fs}")?;
            writeln!(out, "time,x")?;
            let mut k = 0u64;
            while src.read_block(BLOCK_FRAMES, &mut block)? {
                for v in &block.channels[0] {
                    writeln!(out, "{},{v}", k as f64 / fs)?;
                    k += 1;
                }
            }
        }
    }
    out.flush()?;
    Ok(())
}

/// Runs `synth`: validates the options, then writes the signal to `--out` or standard output.
pub fn run(args: &SynthArgs) -> anyhow::Result<()> {
    let src = SynthSource::new(args.spec())?;
    match &args.out {
        Some(path) => {
            // Whole or not at all: a killed run leaves no half signal under the final name.
            let mut w = AtomicFile::create(std::path::Path::new(path))?;
            write_signal(src, args.format, &mut w).with_context(|| format!("writing {path}"))?;
            w.commit().with_context(|| format!("writing {path}"))
        }
        None => {
            let stdout = io::stdout();
            let mut w = BufWriter::new(stdout.lock());
            write_signal(src, args.format, &mut w).context("writing standard output")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::{open_stream, synthesize, InputOptions, RawFormat};
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        synth: SynthArgs,
    }

    fn bytes(args: &[&str]) -> (SynthArgs, Vec<u8>) {
        let a = Cli::try_parse_from(std::iter::once("synth").chain(args.iter().copied()))
            .unwrap()
            .synth;
        let mut out = Vec::new();
        write_signal(SynthSource::new(a.spec()).unwrap(), a.format, &mut out).unwrap();
        (a, out)
    }

    fn read_back(b: Vec<u8>, opts: &InputOptions) -> (f64, Vec<f64>) {
        let mut src = open_stream(std::io::Cursor::new(b), "test", opts).unwrap();
        let fs = src.info().sample_rate_hz;
        let mut block = Block::default();
        let mut x = Vec::new();
        while src.read_block(1000, &mut block).unwrap() {
            x.extend_from_slice(&block.channels[0]);
        }
        (fs, x)
    }

    #[test]
    fn every_format_reads_back() {
        let common = [
            "--mode",
            "200:0.025",
            "--mode",
            "230:0.025:1:0",
            "--seconds",
            "0.5",
            "--snr-db",
            "60",
        ];
        let (a, wav) = bytes(&[&common[..], &["--format", "wav"]].concat());
        assert_eq!(a.fs_hz, 4000.0);
        let want = synthesize(&a.spec());
        let want32: Vec<f64> = want.iter().map(|&v| f64::from(v as f32)).collect();
        assert_eq!(
            read_back(wav, &InputOptions::default()),
            (4000.0, want32.clone())
        );
        let (_, raw) = bytes(&[&common[..], &["--format", "raw-f32"]].concat());
        let opts = InputOptions {
            raw: Some(RawFormat::F32),
            fs_hz: Some(4000.0),
            channels: Some(1),
            ..Default::default()
        };
        assert_eq!(read_back(raw, &opts), (4000.0, want32));
        let (_, csv) = bytes(&[&common[..], &["--format", "csv"]].concat());
        assert_eq!(read_back(csv, &InputOptions::default()), (4000.0, want));
    }

    #[test]
    fn bad_options_are_errors() {
        assert!(
            Cli::try_parse_from(["synth"]).is_err(),
            "--mode is required"
        );
        assert!(Cli::try_parse_from(["synth", "--mode", "200"]).is_err());
        assert!(Cli::try_parse_from(["synth", "--mode", "200:0.1", "--format", "mp3"]).is_err());
        let a = Cli::try_parse_from(["synth", "--mode", "200:0.1", "--fs", "4000.5"]).unwrap();
        let src = SynthSource::new(a.synth.spec()).unwrap();
        assert!(write_signal(src, SynthFormat::Wav, &mut Vec::new()).is_err());
        let a = Cli::try_parse_from(["synth", "--mode", "200:0.1", "--seconds=-1"]).unwrap();
        assert!(run(&a.synth).is_err());
    }
}

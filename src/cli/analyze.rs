//! `dampscope analyze INPUT`: decay times and damping ratios per band and channel.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::sync::Arc;

use anyhow::Context;

use super::bands_arg::{BandArgs, InputFormatArgs};
use super::compare::DirectionArg;
use super::{EXIT_OK, EXIT_PARTIAL};
use crate::frontend::auto_bands::frame_period_for_bands_s;
use crate::frontend::bands::Band;
use crate::frontend::goyder::{GoyderFrontEnd, GoyderSettings};
use crate::frontend::octave_bank::{OctaveBankFrontEnd, OctaveBankSettings};
use crate::frontend::onset::find_onset;
use crate::frontend::stft::StftFrontEnd;
use crate::frontend::FrontEnd;
use crate::output::{TableFormat, TableWriter};
use crate::pipeline::{self, AnalysisConfig, FrontEndFactory};
use crate::source::memory::{read_all, MemorySource};
use crate::source::stdin::open_input;
use crate::source::Source;

/// Which time-frequency front end turns samples into band energies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FrontEndChoice {
    /// Short-time Fourier transform (Hann window).
    Stft,
    /// Goyder-style bank: narrow complex band-pass filters run on the time-reversed decay.
    Goyder,
    /// IEC 61260 Butterworth band-pass bank (biquads), forward or time-reversed.
    Octave,
}

/// Builds one front end of `choice` for `bands`.
pub fn make_front_end(
    choice: FrontEndChoice,
    band_args: &BandArgs,
    direction: DirectionArg,
    sample_rate_hz: f64,
    bands: &[Band],
) -> crate::error::Result<Box<dyn FrontEnd>> {
    Ok(match choice {
        FrontEndChoice::Stft => {
            Box::new(StftFrontEnd::new(band_args.stft(), sample_rate_hz, bands)?)
        }
        FrontEndChoice::Goyder => Box::new(GoyderFrontEnd::new(
            GoyderSettings {
                direction: direction.into(),
                order: band_args
                    .filter_order
                    .unwrap_or(GoyderSettings::default().order),
                frame_period_ms: band_args
                    .frame_ms
                    .unwrap_or(GoyderSettings::default().frame_period_ms),
                ..Default::default()
            },
            sample_rate_hz,
            bands,
        )?),
        FrontEndChoice::Octave => Box::new(OctaveBankFrontEnd::new(
            OctaveBankSettings {
                direction: direction.into(),
                order: band_args
                    .filter_order
                    .unwrap_or(OctaveBankSettings::default().order),
                frame_period_ms: band_args
                    .frame_ms
                    .unwrap_or(OctaveBankSettings::default().frame_period_ms),
                ..Default::default()
            },
            sample_rate_hz,
            bands,
        )?),
    })
}

/// Named settings of another tool ([`crate::presets`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PresetArg {
    /// pyrato's Chu + Lundeby reverberation times: octave bank forward at order 14, 0.1 ms
    /// frames, EDT over −0.1…−10.1 dB, numbers down to the noise and whatever the curvature.
    Pyrato,
}

/// The analysis options shared by `analyze` and `map`: front end, bands, evaluation range and
/// how decays are found in the stream.
#[derive(Debug, Clone, clap::Args)]
pub struct PipelineArgs {
    /// Front end.
    #[arg(long, value_enum, default_value_t = FrontEndChoice::Stft)]
    pub front_end: FrontEndChoice,
    /// Filter direction of the filter banks (reversed preserves the decay rate).
    #[arg(long, value_enum, default_value_t = DirectionArg::Reversed)]
    pub filter_direction: DirectionArg,
    /// Bands, windows and evaluation range.
    #[command(flatten)]
    pub bands: BandArgs,
    /// Decay onset: first sample within this many dB of the peak.
    #[arg(long, default_value_t = pipeline::DEFAULT_ONSET_LEVEL_DB)]
    pub onset_level_db: f64,
    /// End a decay after this many seconds (bounds memory on endless streams).
    #[arg(long, value_name = "S")]
    pub max_decay_s: Option<f64>,
    /// End a decay when every band has fallen this many dB below its peak.
    #[arg(long, default_value_t = pipeline::DEFAULT_END_DROP_DB)]
    pub end_drop_db: f64,
    /// After a decay ends, a sample within this many dB of its peak starts the next one.
    #[arg(long, default_value_t = pipeline::DEFAULT_RETRIGGER_DB)]
    pub retrigger_db: f64,
    /// During a decay, a sample that rises this many dB above the signal before it (and is
    /// within --retrigger-db of the peak) is a new hit and starts a new decay; `inf` never splits.
    #[arg(long, default_value_t = pipeline::DEFAULT_RETRIGGER_JUMP_DB, value_name = "DB")]
    pub retrigger_jump_db: f64,
    /// Reproduce another tool: `pyrato` sets --front-end octave --filter-direction forward
    /// --filter-order 14 --frame-ms 0.1 --noise-margin-db 0 --min-r2 0 --max-curvature-pct inf
    /// and pyrato's EDT limits (these options are then ignored).
    #[arg(long, value_enum)]
    pub preset: Option<PresetArg>,
}

impl PipelineArgs {
    /// The options with the preset's settings in place of the ones it overrides.
    pub fn with_preset(&self) -> PipelineArgs {
        let mut args = self.clone();
        if let Some(PresetArg::Pyrato) = self.preset {
            use crate::presets::pyrato;
            args.front_end = FrontEndChoice::Octave;
            args.filter_direction = pyrato::DIRECTION.into();
            args.bands.filter_order = Some(pyrato::FILTER_ORDER);
            args.bands.frame_ms = Some(pyrato::FRAME_PERIOD_MS);
        }
        args
    }

    /// The estimate settings of these options (the preset's when one is given).
    pub fn estimate(&self) -> crate::error::Result<crate::decay::estimate::EstimateSettings> {
        let given = self.bands.estimate()?;
        Ok(match self.preset {
            Some(PresetArg::Pyrato) => {
                crate::presets::pyrato::estimate(given.range, given.min_points)
            }
            None => given,
        })
    }
}

/// Options of `dampscope analyze`.
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
}

/// Builds the front-end factory for the chosen front end and bands.
pub fn front_end_factory(
    choice: FrontEndChoice,
    band_args: &BandArgs,
    direction: DirectionArg,
    sample_rate_hz: f64,
    bands: Vec<Band>,
) -> anyhow::Result<FrontEndFactory> {
    // Build one now so that bad settings fail before any thread starts.
    make_front_end(choice, band_args, direction, sample_rate_hz, &bands)?;
    let band_args = band_args.clone();
    Ok(Arc::new(move || {
        make_front_end(choice, &band_args, direction, sample_rate_hz, &bands)
    }))
}

/// The most samples per channel read whole for `--bands auto` (2^27: 45 min at 48 kHz).
pub const MAX_WHOLE_SAMPLES: usize = 1 << 27;

/// Everything `pipeline::run` needs, checked before any thread starts.
pub struct PreparedRun {
    /// The samples (read whole for `--bands auto`).
    pub source: Box<dyn Source>,
    /// One front end per channel.
    pub factory: FrontEndFactory,
    /// Decay detection and estimate settings.
    pub config: AnalysisConfig,
}

/// Resolves bands (reading the input whole for `--bands auto`), front end and settings;
/// prints band warnings to stderr.
pub fn prepare(args: &PipelineArgs, mut source: Box<dyn Source>) -> anyhow::Result<PreparedRun> {
    let mut args = args.with_preset();
    let info = source.info().clone();
    let fs = info.sample_rate_hz;
    let (source, bands, warnings): (Box<dyn Source>, _, _) = if args.bands.needs_samples() {
        // Mode-centred bands need the spectrum first: read the input whole (bounded).
        let data = read_all(source.as_mut(), MAX_WHOLE_SAMPLES)?;
        let decays: Vec<&[f64]> = data
            .iter()
            .map(|c| &c[find_onset(c, args.onset_level_db).unwrap_or(0)..])
            .collect();
        let (bands, warnings) = args.bands.resolve_with(fs, Some(&decays))?;
        if args.bands.frame_ms.is_none() {
            // Mode-centred bands on a fast structural decay need frames finer than the banks'
            // default; the finest any bank uses by default otherwise.
            let fine_ms = 1e3 * frame_period_for_bands_s(&bands);
            let default_ms = match args.front_end {
                FrontEndChoice::Goyder => GoyderSettings::default().frame_period_ms,
                _ => OctaveBankSettings::default().frame_period_ms,
            };
            if fine_ms < default_ms {
                args.bands.frame_ms = Some(fine_ms);
            }
        }
        (
            Box::new(MemorySource::new(info.clone(), data)?),
            bands,
            warnings,
        )
    } else {
        let (bands, warnings) = args.bands.resolve_with(fs, None)?;
        (source, bands, warnings)
    };
    for w in warnings {
        eprintln!("dampscope: warning: {w}");
    }
    if let Some(frames) = source.duration_frames() {
        let window = args.bands.window_ms * 1e-3 * fs;
        if args.front_end == FrontEndChoice::Stft && window > frames as f64 {
            anyhow::bail!(
                "invalid setting --window-ms: expected at most the input's length ({:.3} s), got {} ms",
                frames as f64 / fs,
                args.bands.window_ms
            );
        }
    }
    let factory = front_end_factory(
        args.front_end,
        &args.bands,
        args.filter_direction,
        fs,
        bands,
    )?;
    if let Some(s) = args.max_decay_s {
        anyhow::ensure!(
            s > 0.0,
            "invalid setting --max-decay-s: expected > 0, got {s}"
        );
    }
    anyhow::ensure!(
        args.retrigger_jump_db > 0.0,
        "invalid setting --retrigger-jump-db: expected > 0 dB, got {}",
        args.retrigger_jump_db
    );
    let config = AnalysisConfig {
        estimate: args.estimate()?,
        onset_level_db: args.onset_level_db,
        max_decay_s: args.max_decay_s,
        end_drop_db: args.end_drop_db,
        retrigger_db: args.retrigger_db,
        retrigger_jump_db: args.retrigger_jump_db,
        ..Default::default()
    };
    Ok(PreparedRun {
        source,
        factory,
        config,
    })
}

/// Warns about damaged input or non-finite channels; returns the exit code (0, or 3 when
/// part of the input was damaged).
pub fn exit_code_of(summary: &pipeline::RunSummary) -> i32 {
    let mut code = EXIT_OK;
    if let Some(e) = &summary.input_error {
        eprintln!(
            "dampscope: warning: {e}; results up to that point were written (flag input_truncated)"
        );
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
    let run = prepare(&args.pipeline, opened.source)?;
    let out: Box<dyn Write> = match &args.out {
        Some(p) => Box::new(BufWriter::new(
            File::create(p).with_context(|| format!("cannot create {}", p.display()))?,
        )),
        None => Box::new(std::io::stdout().lock()),
    };
    let mut writer = TableWriter::new(out, args.format);
    writer.write_header()?;
    let summary = pipeline::run(run.source, &run.factory, &run.config, |rows| {
        writer.write_rows(rows)
    })?;
    Ok(exit_code_of(&summary))
}

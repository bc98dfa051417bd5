//! Options shared by several subcommands, and their conversion into the library's plans
//! ([`crate::plan`]): clap parses, these structs say how flags map to settings, nothing more.
//! Every default comes from the library constant that the setting's own `Default` uses.

use crate::decay::estimate::{
    EstimateSettings, DEFAULT_MAX_CURVATURE_PCT, DEFAULT_MIN_POINTS, DEFAULT_MIN_R2,
    DEFAULT_NOISE_MARGIN_DB, DEFAULT_RANGE,
};
use crate::decay::EvaluationRange;
use crate::frontend::bands::parse_band;
use crate::frontend::stft::{StftSettings, DEFAULT_OVERLAP, DEFAULT_WINDOW_MS, DEFAULT_ZERO_PAD};
use crate::frontend::{Band, FilterDirection};
use crate::pipeline::segment::{
    Segmentation, DEFAULT_END_DROP_DB, DEFAULT_FLOOR_FLAT_DB, DEFAULT_FLOOR_MIN_S,
    DEFAULT_ONSET_LEVEL_DB, DEFAULT_RETRIGGER_DB, DEFAULT_RETRIGGER_JUMP_DB,
};
use crate::plan::bands::DEFAULT_MAX_BAND_HZ;
use crate::plan::{AnalysisPlan, BandLayout, BandSpec, FrontEndKind, FrontEndSpec};
use crate::source::open::InputOptions;
use crate::source::raw::RawFormat;

/// `--front-end`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FrontEndChoice {
    /// Short-time Fourier transform (Hann window).
    Stft,
    /// Goyder-style bank: narrow complex band-pass filters run on the time-reversed decay.
    Goyder,
    /// IEC 61260 Butterworth band-pass bank (biquads), forward or time-reversed.
    Octave,
}

impl From<FrontEndChoice> for FrontEndKind {
    fn from(c: FrontEndChoice) -> Self {
        match c {
            FrontEndChoice::Stft => FrontEndKind::Stft,
            FrontEndChoice::Goyder => FrontEndKind::Goyder,
            FrontEndChoice::Octave => FrontEndKind::Octave,
        }
    }
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

/// The reason of a library error, without the field's name (clap names the flag itself).
fn reason(e: crate::error::Error) -> String {
    match e {
        crate::error::Error::InvalidSetting { reason, .. } => reason,
        other => other.to_string(),
    }
}

/// A frequency option, Hz: a finite number above 0 (`--fmax 0` reached the model's own check
/// and was reported as a fault of `--model`).
pub(crate) fn parse_positive_hz(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(f) if f.is_finite() && f > 0.0 => Ok(f),
        Ok(f) => Err(format!("expected a frequency > 0 Hz, got {f}")),
        Err(e) => Err(format!("expected a frequency in Hz, got {text:?} ({e})")),
    }
}

fn parse_band_arg(text: &str) -> Result<Band, String> {
    parse_band(text).map_err(reason)
}

fn parse_bands_arg(text: &str) -> Result<BandSpec, String> {
    text.parse().map_err(reason)
}

fn parse_range_arg(text: &str) -> Result<EvaluationRange, String> {
    text.parse()
        .map_err(|e: crate::decay::range::RangeParseError| e.to_string())
}

/// Options that choose the bands, the front ends' settings and the estimate.
#[derive(Debug, Clone, clap::Args)]
pub struct BandArgs {
    /// One band LO:HI in Hz (repeatable).
    #[arg(long = "band", value_name = "LO:HI", value_parser = parse_band_arg)]
    pub band: Vec<Band>,
    /// Consecutive bands LO:HI:WIDTH in Hz, or a layout: `octave`, `third-octave` (IEC 61260-1
    /// base-10, nominal labels), `auto` (mode-centred: one band per spectral peak of the decay,
    /// edges halfway to the neighbours) or `model` (one band per mode of --model). Repeatable.
    /// Without --band and --bands: the report's layout, 50 Hz wide bands centred on 50, 100,
    /// 150, … Hz up to 0.4 fs (at most 2 kHz), i.e. `25:TOP:50`.
    #[arg(
        long = "bands",
        value_name = "LO:HI:WIDTH|octave|third-octave|auto|model",
        value_parser = parse_bands_arg
    )]
    pub bands: Vec<BandSpec>,
    /// Plate model (TOML) whose modes centre the bands of `--bands model`.
    #[arg(long, value_name = "M.toml")]
    pub model: Option<std::path::PathBuf>,
    /// Widest mode-centred band (`auto`, `model`), Hz.
    #[arg(long, default_value_t = DEFAULT_MAX_BAND_HZ)]
    pub max_band_hz: f64,
    /// STFT window length in ms.
    #[arg(long, default_value_t = DEFAULT_WINDOW_MS)]
    pub window_ms: f64,
    /// STFT overlap, 0 ≤ overlap < 1.
    #[arg(long, default_value_t = DEFAULT_OVERLAP)]
    pub overlap: f64,
    /// STFT zero-padding factor (FFT length = window × factor).
    #[arg(long, default_value_t = DEFAULT_ZERO_PAD)]
    pub zero_pad: usize,
    /// Order of the filter banks' low-pass prototype (octave: 1…16, default 3; Goyder: even,
    /// 2…8, default 4). pyfar/pyrato use 14.
    #[arg(long, value_name = "N")]
    pub filter_order: Option<usize>,
    /// Frame period of the filter banks in ms (octave: 2, Goyder: 1 by default). pyrato reads
    /// its decay curves at sample resolution; 0.1 ms comes within 0.4 % of it on EDT.
    #[arg(long, value_name = "MS")]
    pub frame_ms: Option<f64>,
    /// Time direction of the filter banks (reversed preserves the decay rate).
    #[arg(long, value_enum, default_value_t = FilterDirection::default().into())]
    pub filter_direction: DirectionArg,
    /// Evaluation range: edt, t20, t30, drop:N (−5…−(5+N) dB) or from:A:B (−A…−B dB).
    #[arg(long, default_value_t = DEFAULT_RANGE, value_parser = parse_range_arg)]
    pub range: EvaluationRange,
    /// Fewest frames in the evaluation range for a number to be reported.
    #[arg(long, default_value_t = DEFAULT_MIN_POINTS)]
    pub min_points: usize,
    /// How far (dB) a noise floor must lie below the range's lower limit for a number to be
    /// reported: 10 per ISO 3382-1; 0 reports noise-compensated values the way pyrato does.
    #[arg(long, default_value_t = DEFAULT_NOISE_MARGIN_DB)]
    pub noise_margin_db: f64,
    /// |C| = |100 (T30/T20 − 1)| above this (%) withholds the number as `poor_fit`; `inf` keeps
    /// every number (flagged `nonlinear_decay` above 10 %), as pyrato does.
    #[arg(long, default_value_t = DEFAULT_MAX_CURVATURE_PCT, value_name = "PCT")]
    pub max_curvature_pct: f64,
    /// Fits with a lower r² give no number (`poor_fit`); 0 keeps every fit.
    #[arg(long, default_value_t = DEFAULT_MIN_R2, value_name = "R2")]
    pub min_r2: f64,
}

impl BandArgs {
    /// The band layout given.
    pub fn layout(&self) -> BandLayout {
        BandLayout {
            specs: self
                .band
                .iter()
                .map(|b| BandSpec::Band(*b))
                .chain(self.bands.iter().cloned())
                .collect(),
            max_band_hz: self.max_band_hz,
            model: self.model.clone(),
        }
    }

    /// The front-end settings given, for `kind`.
    pub fn front_end(&self, kind: FrontEndKind) -> FrontEndSpec {
        FrontEndSpec {
            kind,
            stft: StftSettings {
                window_ms: self.window_ms,
                overlap: self.overlap,
                zero_pad: self.zero_pad,
            },
            direction: self.filter_direction.into(),
            filter_order: self.filter_order,
            frame_period_ms: self.frame_ms,
        }
    }

    /// The estimate settings given (checked where the plan is validated).
    pub fn estimate(&self) -> EstimateSettings {
        EstimateSettings {
            range: self.range,
            min_points: self.min_points,
            noise_margin_db: self.noise_margin_db,
            max_curvature_pct: self.max_curvature_pct,
            min_r2: self.min_r2,
            ..Default::default()
        }
    }
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
    /// Bands, windows and evaluation range.
    #[command(flatten)]
    pub bands: BandArgs,
    /// Decay onset: first sample within this many dB of the peak.
    #[arg(long, default_value_t = DEFAULT_ONSET_LEVEL_DB)]
    pub onset_level_db: f64,
    /// End a decay after this many seconds (bounds memory on endless streams).
    #[arg(long, value_name = "S")]
    pub max_decay_s: Option<f64>,
    /// End a decay when every band has fallen this many dB below its peak.
    #[arg(long, default_value_t = DEFAULT_END_DROP_DB)]
    pub end_drop_db: f64,
    /// After a decay ends, a sample within this many dB of its peak starts the next one.
    #[arg(long, default_value_t = DEFAULT_RETRIGGER_DB)]
    pub retrigger_db: f64,
    /// During a decay, a sample that rises this many dB above the signal before it (and is
    /// within --retrigger-db of the peak) is a new hit and starts a new decay; `inf` never splits.
    #[arg(long, default_value_t = DEFAULT_RETRIGGER_JUMP_DB, value_name = "DB")]
    pub retrigger_jump_db: f64,
    /// A decay also ends once it is this old (s) and every band has sat on its noise floor for
    /// the last half of it; `inf` never (then only the drop, a new hit or --max-decay-s end it).
    #[arg(long, default_value_t = DEFAULT_FLOOR_MIN_S, value_name = "S")]
    pub floor_min_s: f64,
    /// A band is on its floor when its last quarter is at most this many dB below the quarter
    /// before.
    #[arg(long, default_value_t = DEFAULT_FLOOR_FLAT_DB, value_name = "DB")]
    pub floor_flat_db: f64,
    /// End every open decay when the writer pauses (nothing on standard input or a named pipe
    /// for 0.25 s), as if the input ended there: for a client that sends one record at a time
    /// and waits for its rows. The rows are those of the same bytes in a file that ends at the
    /// pause.
    #[arg(long)]
    pub pause_ends_decays: bool,
    /// Reproduce another tool: `pyrato` sets --front-end octave --filter-direction forward
    /// --filter-order 14 --frame-ms 0.1 --noise-margin-db 0 --min-r2 0 --max-curvature-pct inf
    /// and pyrato's EDT limits (these options are then ignored).
    #[arg(long, value_enum)]
    pub preset: Option<PresetArg>,
}

impl PipelineArgs {
    /// The analysis plan these options describe (the preset's settings in place of the ones it
    /// overrides). Validated by [`AnalysisPlan::prepare`].
    pub fn plan(&self) -> AnalysisPlan {
        let mut plan = AnalysisPlan {
            bands: self.bands.layout(),
            front_end: self.bands.front_end(self.front_end.into()),
            config: crate::pipeline::AnalysisConfig {
                estimate: self.bands.estimate(),
                segmentation: Segmentation {
                    onset_level_db: self.onset_level_db,
                    max_decay_s: self.max_decay_s,
                    end_drop_db: self.end_drop_db,
                    retrigger_db: self.retrigger_db,
                    retrigger_jump_db: self.retrigger_jump_db,
                    floor_min_s: self.floor_min_s,
                    floor_flat_db: self.floor_flat_db,
                    pause_ends_decays: self.pause_ends_decays,
                    ..Default::default()
                },
                ..Default::default()
            },
        };
        if let Some(PresetArg::Pyrato) = self.preset {
            crate::presets::pyrato::apply(&mut plan);
        }
        plan
    }
}

/// Options that say how to read raw or headerless input (shared by the commands that read).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct InputFormatArgs {
    /// Standard input holds raw little-endian interleaved samples of this type.
    #[arg(long, value_name = "f32|f64")]
    pub raw: Option<RawFormat>,
    /// Sample rate in Hz (raw input, or CSV without a time column).
    #[arg(long = "fs", value_name = "HZ")]
    pub fs_hz: Option<f64>,
    /// Number of channels (required for raw input; checked for other inputs).
    #[arg(long)]
    pub channels: Option<usize>,
    /// FRF input: half-cosine taper over this top fraction of 0…fmax before the inverse FFT
    /// (0 = none).
    #[arg(long, default_value_t = 0.0, value_name = "FRACTION")]
    pub frf_taper: f64,
    /// FRF input: exponential window e^(−t/τ) on the impulse responses, τ in s; its added
    /// damping 1/(2πfτ) is removed from every D again (flag exponential_window_removed).
    #[arg(long, value_name = "TAU_S")]
    pub frf_window_s: Option<f64>,
}

impl InputFormatArgs {
    /// The options as the source layer takes them.
    pub fn options(&self) -> InputOptions {
        InputOptions {
            raw: self.raw,
            fs_hz: self.fs_hz,
            channels: self.channels,
            frf: crate::source::frf::FrfToImpulse {
                taper_fraction: self.frf_taper,
                exponential_window_tau_s: self.frf_window_s,
            },
        }
    }
}

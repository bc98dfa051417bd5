//! Band and front-end options shared by `analyze` and `compare`.

use crate::decay::estimate::EstimateSettings;
use crate::decay::EvaluationRange;
use crate::error::{Error, Result};
use crate::frontend::auto_bands::{
    auto_bands, bands_around_modes, min_width_for_record_hz, AutoBandSettings,
};
use crate::frontend::bands::{default_bands, parse_band, parse_band_range, Band};
use crate::frontend::iec_bands::{iec_bands, OctaveFraction};
use crate::frontend::stft::StftSettings;
use crate::source::raw::RawFormat;
use crate::source::stdin::InputOptions;

/// Options that choose the bands and the STFT settings.
#[derive(Debug, Clone, clap::Args)]
pub struct BandArgs {
    /// One band LO:HI in Hz (repeatable).
    #[arg(long = "band", value_name = "LO:HI")]
    pub band: Vec<String>,
    /// Consecutive bands LO:HI:WIDTH in Hz, or a layout: `octave`, `third-octave` (IEC 61260-1
    /// base-10, nominal labels), `auto` (mode-centred: one band per spectral peak of the decay,
    /// edges halfway to the neighbours) or `model` (one band per mode of --model). Repeatable.
    /// Without --band and --bands: the report's layout, 50 Hz wide bands centred on 50, 100,
    /// 150, … Hz up to 0.4 fs (at most 2 kHz), i.e. `25:TOP:50`.
    #[arg(
        long = "bands",
        value_name = "LO:HI:WIDTH|octave|third-octave|auto|model"
    )]
    pub bands: Vec<String>,
    /// Plate model (TOML) whose modes centre the bands of `--bands model`.
    #[arg(long, value_name = "M.toml")]
    pub model: Option<std::path::PathBuf>,
    /// Widest mode-centred band (`auto`, `model`), Hz.
    #[arg(long, default_value_t = 50.0)]
    pub max_band_hz: f64,
    /// STFT window length in ms.
    #[arg(long, default_value_t = 200.0)]
    pub window_ms: f64,
    /// STFT overlap, 0 ≤ overlap < 1.
    #[arg(long, default_value_t = 0.5)]
    pub overlap: f64,
    /// STFT zero-padding factor (FFT length = window × factor).
    #[arg(long, default_value_t = 1)]
    pub zero_pad: usize,
    /// Order of the filter banks' low-pass prototype (octave: 1…16, default
    /// `OctaveBankSettings::default().order`; Goyder: even, 2…8, default 4). pyfar/pyrato use 14.
    #[arg(long, value_name = "N")]
    pub filter_order: Option<usize>,
    /// Frame period of the filter banks in ms (octave: 2, Goyder: 1 by default). pyrato reads
    /// its decay curves at sample resolution; 0.1 ms comes within 0.4 % of it on EDT.
    #[arg(long, value_name = "MS")]
    pub frame_ms: Option<f64>,
    /// Evaluation range: edt, t20, t30, drop:N (−5…−(5+N) dB) or from:A:B (−A…−B dB).
    #[arg(long, default_value = "t30")]
    pub range: String,
    /// Fewest frames in the evaluation range for a number to be reported.
    #[arg(long, default_value_t = 3)]
    pub min_points: usize,
    /// How far (dB) a noise floor must lie below the range's lower limit for a number to be
    /// reported: 10 per ISO 3382-1; 0 reports noise-compensated values the way pyrato does.
    #[arg(long, default_value_t = 10.0)]
    pub noise_margin_db: f64,
    /// |C| = |100 (T30/T20 − 1)| above this (%) withholds the number as `poor_fit`; `inf` keeps
    /// every number (flagged `nonlinear_decay` above 10 %), as pyrato does.
    #[arg(long, default_value_t = crate::decay::estimate::DEFAULT_MAX_CURVATURE_PCT, value_name = "PCT")]
    pub max_curvature_pct: f64,
    /// Fits with a lower r² give no number (`poor_fit`); 0 keeps every fit.
    #[arg(long, default_value_t = crate::decay::estimate::DEFAULT_MIN_R2, value_name = "R2")]
    pub min_r2: f64,
}

impl Default for BandArgs {
    fn default() -> Self {
        BandArgs {
            band: Vec::new(),
            bands: Vec::new(),
            model: None,
            max_band_hz: 50.0,
            window_ms: 200.0,
            overlap: 0.5,
            zero_pad: 1,
            filter_order: None,
            frame_ms: None,
            range: "t30".into(),
            min_points: 3,
            noise_margin_db: 10.0,
            max_curvature_pct: crate::decay::estimate::DEFAULT_MAX_CURVATURE_PCT,
            min_r2: crate::decay::estimate::DEFAULT_MIN_R2,
        }
    }
}

impl BandArgs {
    /// The STFT settings given.
    pub fn stft(&self) -> StftSettings {
        StftSettings {
            window_ms: self.window_ms,
            overlap: self.overlap,
            zero_pad: self.zero_pad,
        }
    }

    /// The estimate settings given.
    pub fn estimate(&self) -> Result<EstimateSettings> {
        let range: EvaluationRange =
            self.range
                .parse()
                .map_err(|e: crate::decay::range::RangeParseError| {
                    Error::setting("--range", e.to_string())
                })?;
        if self.min_points < 2 {
            return Err(Error::setting(
                "--min-points",
                format!("expected >= 2, got {}", self.min_points),
            ));
        }
        if !(self.noise_margin_db.is_finite() && self.noise_margin_db >= 0.0) {
            return Err(Error::setting(
                "--noise-margin-db",
                format!("expected a finite value >= 0, got {}", self.noise_margin_db),
            ));
        }
        if self.max_curvature_pct.is_nan() || self.max_curvature_pct < 0.0 {
            return Err(Error::setting(
                "--max-curvature-pct",
                format!(
                    "expected a value >= 0 (or inf), got {}",
                    self.max_curvature_pct
                ),
            ));
        }
        if !(0.0..=1.0).contains(&self.min_r2) {
            return Err(Error::setting(
                "--min-r2",
                format!("expected 0 <= r2 <= 1, got {}", self.min_r2),
            ));
        }
        Ok(EstimateSettings {
            range,
            min_points: self.min_points,
            noise_margin_db: self.noise_margin_db,
            max_curvature_pct: self.max_curvature_pct,
            min_r2: self.min_r2,
            ..Default::default()
        })
    }

    /// True when the bands can only be chosen after seeing the decay (`--bands auto`).
    pub fn needs_samples(&self) -> bool {
        self.bands.iter().any(|b| b.trim() == "auto")
    }

    /// The bands given, in order, or the default layout when none are given. `decays` (every
    /// channel from its onset) are needed for `--bands auto`. Returns the bands and warnings to
    /// show the user.
    pub fn resolve_with(
        &self,
        sample_rate_hz: f64,
        decays: Option<&[&[f64]]>,
    ) -> Result<(Vec<Band>, Vec<String>)> {
        let mut out = Vec::new();
        let mut warnings = Vec::new();
        for b in &self.band {
            out.push(parse_band(b)?);
        }
        for spec in &self.bands {
            let key = spec.trim();
            if key == "auto" {
                let decays = decays.ok_or_else(|| {
                    Error::setting(
                        "--bands",
                        "auto needs the decay's samples (read whole first)",
                    )
                })?;
                let longest = decays.iter().map(|d| d.len()).max().unwrap_or(0);
                let s = AutoBandSettings {
                    f_max_hz: 0.5 * sample_rate_hz,
                    max_width_hz: self.max_band_hz,
                    min_width_hz: min_width_for_record_hz(
                        longest as f64 / sample_rate_hz,
                        crate::frontend::BANK_CUT_FACTOR,
                    ),
                    ..Default::default()
                };
                out.extend(auto_bands(decays, sample_rate_hz, &s)?);
            } else if key == "model" {
                out.extend(self.model_bands(sample_rate_hz)?);
            } else if let Some(fraction) = OctaveFraction::from_keyword(key) {
                let (b, w) = iec_bands(fraction, 20.0, sample_rate_hz)?;
                out.extend(b);
                warnings.extend(w);
            } else {
                out.extend(parse_band_range(spec)?);
            }
        }
        if out.is_empty() {
            out = default_bands(sample_rate_hz)?;
        }
        Ok((out, warnings))
    }

    /// Bands around the modes of `--model` below 0.45 fs.
    fn model_bands(&self, sample_rate_hz: f64) -> Result<Vec<Band>> {
        let path = self
            .model
            .as_ref()
            .ok_or_else(|| Error::setting("--bands model", "needs --model M.toml"))?;
        let sim_err = |e: crate::sim::SimError| Error::setting("--model", e.to_string());
        let model = crate::sim::model::Model::load(path).map_err(sim_err)?;
        let system = crate::sim::assembly::assemble(&model).map_err(sim_err)?;
        let modes = crate::sim::eigen::lowest_modes(
            &system,
            crate::sim::eigen::ModeRequest::BelowHz(0.45 * sample_rate_hz),
        )
        .map_err(sim_err)?;
        bands_around_modes(&modes.frequencies_hz, self.max_band_hz)
    }

    /// The bands given (without `auto`), or the default layout when none are given.
    pub fn resolve(&self, sample_rate_hz: f64) -> Result<Vec<Band>> {
        self.resolve_with(sample_rate_hz, None).map(|(b, _)| b)
    }
}

/// Options that say how to read raw or headerless input (shared by `analyze` and `compare`).
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
}

impl InputFormatArgs {
    /// The options as the source layer takes them.
    pub fn options(&self) -> InputOptions {
        InputOptions {
            raw: self.raw,
            fs_hz: self.fs_hz,
            channels: self.channels,
        }
    }
}

//! Band and front-end options shared by `analyze` and `compare`.

use crate::decay::estimate::EstimateSettings;
use crate::decay::EvaluationRange;
use crate::error::{Error, Result};
use crate::frontend::bands::{parse_band, parse_band_range, Band};
use crate::frontend::stft::StftSettings;

/// Options that choose the bands and the STFT settings.
#[derive(Debug, Clone, clap::Args)]
pub struct BandArgs {
    /// One band LO:HI in Hz (repeatable).
    #[arg(long = "band", value_name = "LO:HI")]
    pub band: Vec<String>,
    /// Consecutive bands LO:HI:WIDTH in Hz (repeatable).
    #[arg(long = "bands", value_name = "LO:HI:WIDTH")]
    pub bands: Vec<String>,
    /// STFT window length in ms.
    #[arg(long, default_value_t = 200.0)]
    pub window_ms: f64,
    /// STFT overlap, 0 ≤ overlap < 1.
    #[arg(long, default_value_t = 0.5)]
    pub overlap: f64,
    /// STFT zero-padding factor (FFT length = window × factor).
    #[arg(long, default_value_t = 1)]
    pub zero_pad: usize,
    /// Evaluation range: edt, t20, t30 or drop:N (−5…−(5+N) dB).
    #[arg(long, default_value = "t30")]
    pub range: String,
    /// Fewest frames in the evaluation range for a number to be reported.
    #[arg(long, default_value_t = 3)]
    pub min_points: usize,
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
        Ok(EstimateSettings {
            range,
            min_points: self.min_points,
            ..Default::default()
        })
    }

    /// The bands given, in order, or the default layout when none are given.
    pub fn resolve(&self, sample_rate_hz: f64) -> Result<Vec<Band>> {
        let mut out = Vec::new();
        for b in &self.band {
            out.push(parse_band(b)?);
        }
        for spec in &self.bands {
            out.extend(parse_band_range(spec)?);
        }
        if out.is_empty() {
            out = default_bands(sample_rate_hz)?;
        }
        Ok(out)
    }
}

/// The default layout: consecutive 50 Hz bands from 25 Hz up to 0.4 fs (at most 2 kHz)... kept
/// simple until standard octave layouts land.
pub fn default_bands(sample_rate_hz: f64) -> Result<Vec<Band>> {
    let top = (0.4 * sample_rate_hz).min(2025.0);
    parse_band_range(&format!("25:{top}:50"))
}

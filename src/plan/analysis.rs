//! An analysis as a plan: bands, front end, estimate and segmentation settings, validated once;
//! [`AnalysisPlan::prepare`] turns it and a source into what [`crate::pipeline::run`] needs.

use crate::error::{Error, Result};
use crate::frontend::auto_bands::frame_period_for_bands_s;
use crate::frontend::Band;
use crate::pipeline::segment::onset::find_onset;
use crate::pipeline::{AnalysisConfig, FrontEndFactory};
use crate::source::memory::{read_all, MemorySource, MAX_WHOLE_SAMPLES};
use crate::source::Source;

use super::bands::BandLayout;
use super::front_end::{FrontEndKind, FrontEndSpec};

/// What to analyse and how.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AnalysisPlan {
    /// Which bands.
    pub bands: BandLayout,
    /// Which front end, with its settings.
    pub front_end: FrontEndSpec,
    /// Estimate and segmentation settings.
    pub config: AnalysisConfig,
}

/// Everything [`crate::pipeline::run`] needs, checked before any thread starts.
pub struct PreparedRun {
    /// The samples (read whole for mode-centred bands).
    pub source: Box<dyn Source>,
    /// The bands, resolved.
    pub bands: Vec<Band>,
    /// One front end per channel.
    pub factory: FrontEndFactory,
    /// Decay detection and estimate settings.
    pub config: AnalysisConfig,
    /// What the user should know (bands dropped above Nyquist, …).
    pub warnings: Vec<String>,
}

impl AnalysisPlan {
    /// Checks every setting that does not depend on the input; errors name the field.
    pub fn validate(&self) -> Result<()> {
        self.bands.validate()?;
        self.config.validate()
    }

    /// Resolves the bands (reading the input whole, at most [`MAX_WHOLE_SAMPLES`] per channel,
    /// when they are centred on the decays' spectral peaks), builds the front-end factory and
    /// checks the settings against the input.
    pub fn prepare(&self, mut source: Box<dyn Source>) -> Result<PreparedRun> {
        self.validate()?;
        let info = source.info().clone();
        let quantization_step = source.quantization_step();
        let fs = info.sample_rate_hz;
        let mut front_end = self.front_end;
        let (source, resolved): (Box<dyn Source>, _) = if self.bands.needs_samples() {
            // Mode-centred bands need the spectrum first: read the input whole (bounded).
            let data = read_all(source.as_mut(), MAX_WHOLE_SAMPLES)?;
            let level = self.config.segmentation.onset_level_db;
            let decays: Vec<&[f64]> = data
                .iter()
                .map(|c| &c[find_onset(c, level).unwrap_or(0)..])
                .collect();
            let resolved = self.bands.resolve(fs, Some(&decays))?;
            if front_end.frame_period_ms.is_none() {
                // Mode-centred bands on a fast structural decay need frames finer than the
                // banks' default.
                let fine_ms = 1e3 * frame_period_for_bands_s(&resolved.bands);
                if fine_ms < front_end.frame_period_ms() && front_end.kind != FrontEndKind::Stft {
                    front_end.frame_period_ms = Some(fine_ms);
                }
            }
            (Box::new(MemorySource::new(info.clone(), data)?), resolved)
        } else {
            (source, self.bands.resolve(fs, None)?)
        };
        if let Some(frames) = source.duration_frames() {
            let window = front_end.stft.window_ms * 1e-3 * fs;
            if front_end.kind == FrontEndKind::Stft && window > frames as f64 {
                return Err(Error::setting(
                    "window_ms",
                    format!(
                        "expected at most the input's length ({:.3} s), got {} ms",
                        frames as f64 / fs,
                        front_end.stft.window_ms
                    ),
                ));
            }
        }
        let factory = front_end.factory(fs, resolved.bands.clone())?;
        Ok(PreparedRun {
            source,
            bands: resolved.bands,
            factory,
            config: AnalysisConfig {
                quantization_step,
                ..self.config
            },
            warnings: resolved.warnings,
        })
    }
}

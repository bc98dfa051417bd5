//! Which bands to analyse: the band grammar of the command line and of settings files, and its
//! resolution into [`Band`]s once the sample rate (and, for mode-centred layouts, the decay or
//! the model) is known.
//!
//! Layouts, in the order given (several may be combined): one band `LO:HI`; consecutive bands
//! `LO:HI:WIDTH`; `octave` / `third-octave` (IEC 61260-1 base-10, nominal labels); `auto` (one
//! band per spectral peak of the decays, edges halfway to the neighbours); `model` (one band per
//! mode of a plate model). Without any: the report's layout, 50 Hz bands centred on 50, 100, …
//! ([`crate::frontend::bands::default_bands`]).

use std::path::PathBuf;
use std::str::FromStr;

use crate::error::{Error, Result};
use crate::frontend::auto_bands::{
    auto_bands, bands_around_modes, min_width_for_record_hz, AutoBandSettings,
};
use crate::frontend::bands::{default_bands, parse_band, parse_band_range};
use crate::frontend::iec_bands::{iec_bands, OctaveFraction};
use crate::frontend::{Band, BANK_CUT_FACTOR};

/// Default of [`BandLayout::max_band_hz`]: the widest mode-centred band, Hz (the report's
/// band width).
pub const DEFAULT_MAX_BAND_HZ: f64 = 50.0;

/// Lowest band edge of the IEC layouts, Hz.
pub const IEC_LOWEST_HZ: f64 = 20.0;

/// Modes of `model` layouts are taken below this fraction of the sample rate.
pub const MODEL_MODES_BELOW_FRACTION_OF_FS: f64 = 0.45;

/// One entry of a band layout.
#[derive(Clone, Debug, PartialEq)]
pub enum BandSpec {
    /// One band, `LO:HI`.
    Band(Band),
    /// Consecutive bands, `LO:HI:WIDTH`.
    Consecutive(Vec<Band>),
    /// IEC 61260-1 octave or third-octave bands up to the Nyquist frequency.
    Iec(OctaveFraction),
    /// One band per spectral peak of the decays (needs their samples).
    Auto,
    /// One band per mode of the layout's model.
    Model,
}

impl FromStr for BandSpec {
    type Err = Error;

    /// `LO:HI`, `LO:HI:WIDTH`, `octave`, `third-octave`, `auto` or `model`.
    fn from_str(text: &str) -> Result<Self> {
        let key = text.trim();
        Ok(match key {
            "auto" => BandSpec::Auto,
            "model" => BandSpec::Model,
            _ => match OctaveFraction::from_keyword(key) {
                Some(fraction) => BandSpec::Iec(fraction),
                None if key.split(':').count() == 2 => BandSpec::Band(parse_band(key)?),
                None => BandSpec::Consecutive(parse_band_range(key)?),
            },
        })
    }
}

/// A band layout: what [`BandLayout::resolve`] turns into bands.
#[derive(Clone, Debug, PartialEq)]
pub struct BandLayout {
    /// The entries, in order; none: the default layout.
    pub specs: Vec<BandSpec>,
    /// Widest mode-centred band (`auto`, `model`), Hz.
    pub max_band_hz: f64,
    /// The plate model whose modes centre a `model` layout.
    pub model: Option<PathBuf>,
}

impl Default for BandLayout {
    /// The report's layout.
    fn default() -> Self {
        BandLayout {
            specs: Vec::new(),
            max_band_hz: DEFAULT_MAX_BAND_HZ,
            model: None,
        }
    }
}

/// Bands with the warnings their resolution raised (IEC bands dropped above Nyquist, …).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ResolvedBands {
    /// The bands, in layout order.
    pub bands: Vec<Band>,
    /// What the user should know about them.
    pub warnings: Vec<String>,
}

impl BandLayout {
    /// A layout of explicit bands.
    pub fn of_bands(bands: &[Band]) -> BandLayout {
        BandLayout {
            specs: bands.iter().map(|b| BandSpec::Band(*b)).collect(),
            ..Default::default()
        }
    }

    /// True when the bands can only be chosen after seeing the decays (`auto`).
    pub fn needs_samples(&self) -> bool {
        self.specs.contains(&BandSpec::Auto)
    }

    /// Checks what can be checked before any input is seen.
    pub fn validate(&self) -> Result<()> {
        if !(self.max_band_hz.is_finite() && self.max_band_hz > 0.0) {
            return Err(Error::setting(
                "max_band_hz",
                format!("expected a positive width in Hz, got {}", self.max_band_hz),
            ));
        }
        if self.specs.contains(&BandSpec::Model) && self.model.is_none() {
            return Err(Error::setting("bands", "model needs a model file (model)"));
        }
        Ok(())
    }

    /// The bands at `fs_hz`. `decays` (every channel from its onset) are needed for `auto`.
    pub fn resolve(&self, fs_hz: f64, decays: Option<&[&[f64]]>) -> Result<ResolvedBands> {
        self.validate()?;
        let mut out = ResolvedBands::default();
        for spec in &self.specs {
            match spec {
                BandSpec::Band(b) => out.bands.push(*b),
                BandSpec::Consecutive(bands) => out.bands.extend_from_slice(bands),
                BandSpec::Iec(fraction) => {
                    let (bands, warnings) = iec_bands(*fraction, IEC_LOWEST_HZ, fs_hz)?;
                    out.bands.extend(bands);
                    out.warnings.extend(warnings);
                }
                BandSpec::Auto => {
                    let decays = decays.ok_or_else(|| {
                        Error::setting(
                            "auto_bands",
                            "needs the decays' samples (read the input whole first)",
                        )
                    })?;
                    let longest = decays.iter().map(|d| d.len()).max().unwrap_or(0);
                    let settings = AutoBandSettings {
                        f_max_hz: 0.5 * fs_hz,
                        max_width_hz: self.max_band_hz,
                        min_width_hz: min_width_for_record_hz(
                            longest as f64 / fs_hz,
                            BANK_CUT_FACTOR,
                        ),
                        ..Default::default()
                    };
                    out.bands.extend(auto_bands(decays, fs_hz, &settings)?);
                }
                BandSpec::Model => out.bands.extend(self.model_bands(fs_hz)?),
            }
        }
        if out.bands.is_empty() {
            out.bands = default_bands(fs_hz)?;
        }
        Ok(out)
    }

    /// Bands around the modes of the layout's model below
    /// [`MODEL_MODES_BELOW_FRACTION_OF_FS`] × fs.
    fn model_bands(&self, fs_hz: f64) -> Result<Vec<Band>> {
        let path = self
            .model
            .as_deref()
            .ok_or_else(|| Error::setting("bands", "model needs a model file (model)"))?;
        let sim_err = |e: crate::sim::SimError| Error::setting("model", e.to_string());
        let model = crate::sim::model::Model::load(path).map_err(sim_err)?;
        let modes = crate::sim::eigen::model_modes(
            &model,
            crate::sim::eigen::ModeRequest::BelowHz(MODEL_MODES_BELOW_FRACTION_OF_FS * fs_hz),
        )
        .map_err(sim_err)?;
        bands_around_modes(&modes.frequencies_hz, self.max_band_hz)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grammar_reads_every_layout() {
        assert_eq!("auto".parse::<BandSpec>().unwrap(), BandSpec::Auto);
        assert_eq!("model".parse::<BandSpec>().unwrap(), BandSpec::Model);
        assert!(matches!("third-octave".parse(), Ok(BandSpec::Iec(_))));
        assert_eq!(
            "380:420".parse::<BandSpec>().unwrap(),
            BandSpec::Band(Band::new(380.0, 420.0).unwrap())
        );
        match "25:125:50".parse::<BandSpec>().unwrap() {
            BandSpec::Consecutive(b) => assert_eq!(b.len(), 2),
            other => panic!("{other:?}"),
        }
        assert!("25:x:50".parse::<BandSpec>().is_err());
    }

    #[test]
    fn empty_layout_is_the_reports_and_auto_needs_samples() {
        let layout = BandLayout::default();
        let r = layout.resolve(4000.0, None).unwrap();
        assert_eq!(r.bands, default_bands(4000.0).unwrap());
        let auto = BandLayout {
            specs: vec![BandSpec::Auto],
            ..Default::default()
        };
        assert!(auto.needs_samples());
        assert!(auto.resolve(4000.0, None).is_err());
        let model = BandLayout {
            specs: vec![BandSpec::Model],
            ..Default::default()
        };
        assert!(model.validate().is_err());
    }
}

//! Band definitions and the command-line forms `LO:HI` and `LO:HI:WIDTH`.

use crate::error::{Error, Result};

/// A frequency band in Hz.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Band {
    /// Lower edge, Hz.
    pub lo_hz: f64,
    /// Upper edge, Hz.
    pub hi_hz: f64,
    /// Centre used for D = 1.0994 / (T60 f_center), Hz (arithmetic for plain bands, exact
    /// geometric midband for IEC octave bands, the mode for mode-centred bands).
    pub center_hz: f64,
    /// Label frequency for tables, Hz (the IEC nominal frequency for octave bands, else the centre).
    pub nominal_hz: f64,
}

impl Band {
    /// A band from `lo_hz` to `hi_hz` with its arithmetic centre (as the report's 150–250 Hz → 200 Hz).
    pub fn new(lo_hz: f64, hi_hz: f64) -> Result<Self> {
        if !(lo_hz.is_finite() && hi_hz.is_finite() && lo_hz >= 0.0 && hi_hz > lo_hz) {
            return Err(Error::setting(
                "band",
                format!("expected 0 <= LO < HI, got {lo_hz}:{hi_hz}"),
            ));
        }
        let c = 0.5 * (lo_hz + hi_hz);
        Ok(Band {
            lo_hz,
            hi_hz,
            center_hz: c,
            nominal_hz: c,
        })
    }

    /// Bandwidth in Hz.
    pub fn width_hz(&self) -> f64 {
        self.hi_hz - self.lo_hz
    }
}

fn parse_numbers(text: &str, what: &str, count: usize) -> Result<Vec<f64>> {
    let parts: Vec<&str> = text.split(':').collect();
    if parts.len() != count {
        return Err(Error::setting(
            what,
            format!("expected {count} numbers separated by ':', got '{text}'"),
        ));
    }
    parts
        .iter()
        .map(|p| {
            p.trim()
                .parse::<f64>()
                .map_err(|_| Error::setting(what, format!("'{p}' in '{text}' is not a number")))
        })
        .collect()
}

/// Parses `LO:HI` (Hz) into one band.
pub fn parse_band(text: &str) -> Result<Band> {
    let v = parse_numbers(text, "band", 2)?;
    Band::new(v[0], v[1])
}

/// Parses `LO:HI:WIDTH` (Hz) into consecutive bands of `WIDTH` from `LO` up to `HI`
/// (the last band ends at or below `HI`).
pub fn parse_band_range(text: &str) -> Result<Vec<Band>> {
    let v = parse_numbers(text, "bands", 3)?;
    let (lo, hi, width) = (v[0], v[1], v[2]);
    if !(width > 0.0 && hi > lo && lo >= 0.0 && (hi - lo).is_finite()) {
        return Err(Error::setting(
            "bands",
            format!("expected 0 <= LO < HI and WIDTH > 0, got '{text}'"),
        ));
    }
    let n = ((hi - lo) / width + 1e-9).floor() as usize;
    if n == 0 || n > 100_000 {
        return Err(Error::setting(
            "bands",
            format!("'{text}' gives {n} bands; expected 1 to 100000"),
        ));
    }
    (0..n)
        .map(|i| Band::new(lo + i as f64 * width, lo + (i + 1) as f64 * width))
        .collect()
}

/// The default layout: the report's chapter 4 bands, 50 Hz wide, centred on 50, 100, 150, … Hz,
/// up to 0.4 fs (at most 2 kHz).
/// Below 187.5 Hz (0.4 fs < 75 Hz) it holds no band: an error that says so and names the
/// choices, not the layout's internal `LO:HI:WIDTH` text.
pub fn default_bands(sample_rate_hz: f64) -> Result<Vec<Band>> {
    let top = (DEFAULT_BANDS_TOP_FRACTION_OF_FS * sample_rate_hz).min(DEFAULT_BANDS_TOP_HZ);
    if !(top >= 75.0 && sample_rate_hz.is_finite()) {
        return Err(Error::setting(
            "bands",
            format!(
                "the default layout (50 Hz bands centred on 50, 100, … Hz up to 0.4 fs) holds \
                 no band at {} Hz, where 0.4 fs is {} Hz; expected a sample \
                 rate of at least 187.5 Hz, or bands chosen with --band LO:HI, --bands \
                 LO:HI:WIDTH, octave, third-octave or auto",
                crate::error::shown(sample_rate_hz),
                crate::error::shown(top)
            ),
        ));
    }
    parse_band_range(&format!("25:{top}:50"))
}

/// The default layout reaches up to this fraction of the sample rate.
pub const DEFAULT_BANDS_TOP_FRACTION_OF_FS: f64 = 0.4;
/// The default layout ends at the latest at this band edge, Hz (the band centred on 2 kHz).
pub const DEFAULT_BANDS_TOP_HZ: f64 = 2025.0;

#[cfg(test)]
mod tests {
    use super::*;

    /// The default layout's first band (25–75 Hz) needs 0.4 fs ≥ 75 Hz; below, the error
    /// names the rate and the choices instead of the layout's text.
    #[test]
    fn the_default_layout_at_low_rates_says_why_it_is_empty() {
        assert_eq!(default_bands(187.5).unwrap().len(), 1);
        for fs in [100.0, 187.0, 0.0, f64::NAN] {
            let e = default_bands(fs).unwrap_err().to_string();
            assert!(
                e.contains("holds no band") && e.contains("--bands"),
                "{fs}: {e}"
            );
            assert!(!e.contains("25:"), "{fs}: {e}");
        }
        // Found by the contract probe: `--fs 1e-300` printed three hundred zeros.
        let e = default_bands(1e-300).unwrap_err().to_string();
        assert!(e.contains("at 1e-300 Hz, where 0.4 fs is 4e-301 Hz"), "{e}");
    }

    #[test]
    fn parses_bands() {
        let b = parse_band("150:250").unwrap();
        assert_eq!((b.lo_hz, b.hi_hz, b.center_hz), (150.0, 250.0, 200.0));
        let bs = parse_band_range("50:550:50").unwrap();
        assert_eq!(bs.len(), 10);
        assert_eq!(bs[9].hi_hz, 550.0);
        assert!(parse_band("250:150").is_err());
        assert!(parse_band("a:b").is_err());
        assert!(parse_band_range("0:100:0").is_err());
    }
}

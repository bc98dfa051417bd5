//! IEC 61260-1 octave and third-octave bands (base-10 system).
//!
//! Exact midband frequencies f_m = 1000 · G^(x/b) Hz with G = 10^(3/10) and b = 1 (octave) or
//! 3 (third octave); edges f_m · G^(±1/(2b)). Bands carry the exact midband as `center_hz` (used
//! for D = 1.0994/(T60 f)) and the IEC nominal label (31.5, 63, 125, … Hz) as `nominal_hz`.

use super::Band;
use crate::error::{Error, Result};

/// The octave ratio of the base-10 system, G = 10^(3/10).
pub const OCTAVE_RATIO_G: f64 = 1.995_262_314_968_879_5;

/// Lowest nominal frequency generated, Hz (IEC lists bands from 10 Hz).
const LOWEST_NOMINAL_HZ: f64 = 10.0;
/// Highest nominal frequency generated, Hz.
const HIGHEST_NOMINAL_HZ: f64 = 20_000.0;

/// Which fractional-octave layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum OctaveFraction {
    /// Full octaves (b = 1).
    Octave,
    /// One-third octaves (b = 3).
    Third,
}

impl OctaveFraction {
    /// Bands per octave, b.
    pub fn bands_per_octave(self) -> i32 {
        match self {
            OctaveFraction::Octave => 1,
            OctaveFraction::Third => 3,
        }
    }

    /// Parses `octave` or `third-octave` (the `--bands` keywords); `None` for anything else.
    pub fn from_keyword(text: &str) -> Option<Self> {
        match text.trim() {
            "octave" => Some(OctaveFraction::Octave),
            "third-octave" | "third" | "1/3-octave" => Some(OctaveFraction::Third),
            _ => None,
        }
    }
}

/// The IEC nominal label of the third-octave band with index `x` (x = 0 is 1000 Hz): the R10
/// preferred numbers 1, 1.25, 1.6, 2, 2.5, 3.15, 4, 5, 6.3, 8 times a power of ten.
pub fn nominal_third_octave_hz(x: i32) -> f64 {
    const R10: [f64; 10] = [1.0, 1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0];
    let decade = x.div_euclid(10);
    let step = x.rem_euclid(10) as usize;
    // Round to kill the floating noise of powi (e.g. 31.499999…).
    let v = R10[step] * 10f64.powi(decade + 3);
    (v * 1000.0).round() / 1000.0
}

/// The band with index `x` in layout `fraction` (x = 0 is the 1000 Hz band).
pub fn iec_band(fraction: OctaveFraction, x: i32) -> Band {
    let b = fraction.bands_per_octave();
    let fm = 1000.0 * OCTAVE_RATIO_G.powf(x as f64 / b as f64);
    let half = OCTAVE_RATIO_G.powf(1.0 / (2.0 * b as f64));
    // Octave band x sits on third-octave index 3x, whose label it shares.
    let nominal = nominal_third_octave_hz(x * (3 / b));
    Band {
        lo_hz: fm / half,
        hi_hz: fm * half,
        center_hz: fm,
        nominal_hz: nominal,
    }
}

/// IEC bands from the first one whose nominal frequency is ≥ `f_min_hz` up to the Nyquist
/// frequency of `fs_hz` (and at most the 20 kHz band).
///
/// Returns the bands and warnings (not printed): the first band that straddles Nyquist (lower
/// edge below, upper edge above) is dropped and named in a warning. Errors on a non-finite or
/// non-positive `fs_hz` or a non-finite `f_min_hz`.
pub fn iec_bands(
    fraction: OctaveFraction,
    f_min_hz: f64,
    fs_hz: f64,
) -> Result<(Vec<Band>, Vec<String>)> {
    if !(fs_hz.is_finite() && fs_hz > 0.0) {
        return Err(Error::setting(
            "fs",
            format!("expected a positive sample rate in Hz, got {fs_hz}"),
        ));
    }
    if !f_min_hz.is_finite() {
        return Err(Error::setting(
            "bands",
            format!("expected a finite lowest band frequency in Hz, got {f_min_hz}"),
        ));
    }
    let nyquist = 0.5 * fs_hz;
    let b = fraction.bands_per_octave();
    let mut bands = Vec::new();
    let mut warnings = Vec::new();
    // Third-octave index −20 is 10 Hz; step b/… so octave indices cover the same span.
    let (first, last) = match fraction {
        OctaveFraction::Octave => (-6, 4),
        OctaveFraction::Third => (-20, 13),
    };
    for x in first..=last {
        let band = iec_band(fraction, x);
        if band.nominal_hz < LOWEST_NOMINAL_HZ
            || band.nominal_hz > HIGHEST_NOMINAL_HZ
            || band.nominal_hz < f_min_hz * (1.0 - 1e-9)
        {
            continue;
        }
        if band.hi_hz > nyquist {
            if band.lo_hz < nyquist {
                warnings.push(format!(
                    "{} band {} Hz dropped: its upper edge {:.1} Hz is above the Nyquist frequency {:.1} Hz",
                    if b == 1 { "octave" } else { "third-octave" },
                    band.nominal_hz,
                    band.hi_hz,
                    nyquist
                ));
            }
            break;
        }
        bands.push(band);
    }
    Ok((bands, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_midbands_edges_and_labels() {
        let (bands, w) = iec_bands(OctaveFraction::Octave, 31.5, 48_000.0).unwrap();
        let labels: Vec<f64> = bands.iter().map(|b| b.nominal_hz).collect();
        assert_eq!(
            labels,
            vec![31.5, 63.0, 125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0, 16000.0]
        );
        assert!(w.is_empty(), "{w:?}");
        let k1 = bands.iter().find(|b| b.nominal_hz == 1000.0).unwrap();
        assert!((k1.center_hz - 1000.0).abs() < 1e-9);
        // Edges of the 1 kHz octave: 1000 · G^(∓1/2) = 707.946, 1412.538 Hz.
        assert!(
            (k1.lo_hz - 707.945_784_384_137_9).abs() < 1e-6,
            "{}",
            k1.lo_hz
        );
        assert!(
            (k1.hi_hz - 1_412.537_544_622_754).abs() < 1e-6,
            "{}",
            k1.hi_hz
        );
        let b125 = bands.iter().find(|b| b.nominal_hz == 125.0).unwrap();
        assert!((b125.center_hz - 125.892_541_179_416_7).abs() < 1e-9);
    }

    #[test]
    fn third_octaves_and_nyquist_warning() {
        let (bands, w) = iec_bands(OctaveFraction::Third, 25.0, 3000.0).unwrap();
        let labels: Vec<f64> = bands.iter().map(|b| b.nominal_hz).collect();
        assert_eq!(
            labels,
            vec![
                25.0, 31.5, 40.0, 50.0, 63.0, 80.0, 100.0, 125.0, 160.0, 200.0, 250.0, 315.0,
                400.0, 500.0, 630.0, 800.0, 1000.0, 1250.0
            ]
        );
        // 1600 Hz band: 1425…1778 Hz straddles Nyquist (1500 Hz) → dropped with a warning.
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("1600"), "{w:?}");
        // At fs = 2000 Hz the 1000 Hz third (edge 1122 Hz) straddles Nyquist: warned.
        let (bands, w) = iec_bands(OctaveFraction::Third, 25.0, 2000.0).unwrap();
        assert_eq!(bands.last().unwrap().nominal_hz, 800.0);
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("1000"), "{w:?}");
        // Adjacent thirds share edges.
        for p in bands.windows(2) {
            assert!((p[0].hi_hz - p[1].lo_hz).abs() < 1e-9);
        }
    }

    #[test]
    fn bad_sample_rate_is_an_error() {
        assert!(iec_bands(OctaveFraction::Octave, 31.5, 0.0).is_err());
        assert!(iec_bands(OctaveFraction::Octave, f64::NAN, 1000.0).is_err());
    }
}

//! How estimates are made from a decay curve: the settings of [`super::estimate`] and their
//! defaults (re-exported there).

#[cfg(doc)]
use super::flags::Flag;
use super::range::EvaluationRange;

/// How estimates are made from a decay curve.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EstimateSettings {
    /// The range whose fit gives `t60_s` and the damping ratios.
    pub range: EvaluationRange,
    /// Fewest frames inside the range for a fit (3 by default).
    pub min_points: usize,
    /// |C| = |100 (T30/T20 − 1)| above this, in %, raises [`Flag::NonlinearDecay`] (10 by default).
    pub curvature_limit_pct: f64,
    /// A noise floor less than this many dB below the range's lower limit raises
    /// [`Flag::NoiseLimited`] and withholds the number (10 by default, the ISO 3382-1 rule:
    /// 35 dB of peak-to-noise for T20, 45 dB for T30). Lower it to get noise-compensated
    /// values closer to the floor, at the risk of their bias.
    pub noise_margin_db: f64,
    /// Fits with a lower r² give no number ([`Flag::PoorFit`]; [`DEFAULT_MIN_R2`] by default).
    pub min_r2: f64,
    /// |C| above this, in %, gives no number ([`Flag::PoorFit`]; [`DEFAULT_MAX_CURVATURE_PCT`]
    /// by default). Between `curvature_limit_pct` and this the number stands, flagged
    /// [`Flag::NonlinearDecay`] (the report's beating maps live there).
    pub max_curvature_pct: f64,
    /// Upper and lower limit of the EDT fit in dB ((0, −10) by default, ISO 3382-1; pyrato
    /// fits −0.1 … −10.1 dB, see [`crate::presets::pyrato`]).
    pub edt_limits_db: (f64, f64),
    /// How Lundeby's method and the Chu noise subtraction are run.
    pub noise_compensation: NoiseCompensation,
}

/// Variants of the Chu + Lundeby noise compensation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum NoiseCompensation {
    /// Lundeby's first regression ends at the first block below noise + 10 dB (robust for band
    /// energies at a frame rate, whose noise blocks fluctuate by ±10 dB) and Lundeby's final
    /// noise estimate is subtracted. The default.
    Robust,
    /// As pyrato: the first regression ends at the last block above noise + 10 dB, and the
    /// noise subtracted and used for the tail correction is the mean of the last 10 % of the
    /// decay (`noise_level='auto'`). Needs fine frames: at 0.1 ms the robust rule's first
    /// regression stopped at an early dip of a forward order-14 125 Hz band (t_i 1.56 s
    /// instead of pyrato's 1.89 s, T30 −1.2 %).
    Pyrato,
}

/// Default of [`EstimateSettings::min_r2`]: below it the line misses the Schroeder curve badly
/// (hits merged into one decay fit with r² 0.63–0.75). Measured for the choice: two beating
/// modes (plate modes 7 + 8, METHODS.md §1, whose T20 over the relative phase is the report's
/// beating result, flagged `nonlinear_decay`) fit with r² ≥ 0.86; the full plate model at 55 Hz
/// over the 33 × 49 grid ≥ 0.80, 99 % of its sensors ≥ 0.96; a single mode ≥ 0.997.
pub const DEFAULT_MIN_R2: f64 = 0.8;

/// Default of [`EstimateSettings::max_curvature_pct`], %: the full plate model at 55 Hz reaches
/// |C| = 36 % on its worst sensor (a nodal line crossing beating modes); 50 % is beyond any
/// curve that one decay rate describes.
pub const DEFAULT_MAX_CURVATURE_PCT: f64 = 50.0;

/// Default of [`EstimateSettings::curvature_limit_pct`], % (ISO 3382-1's 10 % for C).
pub const DEFAULT_CURVATURE_LIMIT_PCT: f64 = 10.0;

/// Default of [`EstimateSettings::noise_margin_db`], dB (ISO 3382-1).
pub const DEFAULT_NOISE_MARGIN_DB: f64 = 10.0;

/// Default of [`EstimateSettings::min_points`].
pub const DEFAULT_MIN_POINTS: usize = 3;

/// A band whose energy is not at least this far above what the stronger bands of the same
/// decay leak into it is flagged [`Flag::Leakage`], dB: above it the band's own content holds
/// at least three quarters of its energy. A band in the skirt of a strong mode sits near 0 dB
/// (its energy *is* the leakage); a third-octave band of a room with an order-3 bank receives
/// about −10 dB from an equally strong neighbour, so a stricter margin would refuse ordinary
/// diffuse bands (measured on `ir_sportscentre_omni.wav`: 63 Hz at 9.4 dB).
pub const LEAKAGE_MARGIN_DB: f64 = 6.0;

/// A band more than this many dB below the strongest band of the same decay is flagged
/// [`Flag::Leakage`]: no measurement chain has that dynamic range (a float32 sample holds 144 dB),
/// so what such a band holds is rounding noise of the strong bands, which decays with them.
pub const NUMERICAL_FLOOR_DB: f64 = 100.0;

/// Default of [`EstimateSettings::range`]: T30 (−5 … −35 dB), the report's range.
pub const DEFAULT_RANGE: EvaluationRange = EvaluationRange::T30;

impl EstimateSettings {
    /// Checks the settings; an error names the field and says what was expected.
    pub fn validate(&self) -> crate::error::Result<()> {
        use crate::error::Error;
        if self.min_points < 2 {
            return Err(Error::setting(
                "min_points",
                format!("expected >= 2, got {}", self.min_points),
            ));
        }
        if !(self.noise_margin_db.is_finite() && self.noise_margin_db >= 0.0) {
            return Err(Error::setting(
                "noise_margin_db",
                format!("expected a finite value >= 0, got {}", self.noise_margin_db),
            ));
        }
        if self.max_curvature_pct.is_nan() || self.max_curvature_pct < 0.0 {
            return Err(Error::setting(
                "max_curvature_pct",
                format!(
                    "expected a value >= 0 (or inf), got {}",
                    self.max_curvature_pct
                ),
            ));
        }
        if !(0.0..=1.0).contains(&self.min_r2) {
            return Err(Error::setting(
                "min_r2",
                format!("expected 0 <= r2 <= 1, got {}", self.min_r2),
            ));
        }
        Ok(())
    }
}

impl Default for EstimateSettings {
    fn default() -> Self {
        EstimateSettings {
            range: DEFAULT_RANGE,
            min_points: DEFAULT_MIN_POINTS,
            curvature_limit_pct: DEFAULT_CURVATURE_LIMIT_PCT,
            noise_margin_db: DEFAULT_NOISE_MARGIN_DB,
            min_r2: DEFAULT_MIN_R2,
            max_curvature_pct: DEFAULT_MAX_CURVATURE_PCT,
            edt_limits_db: EvaluationRange::Edt.limits_db(),
            noise_compensation: NoiseCompensation::Robust,
        }
    }
}

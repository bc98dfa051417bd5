//! Band definitions.

/// A frequency band in Hz.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Band {
    /// Lower edge, Hz.
    pub lo_hz: f64,
    /// Upper edge, Hz.
    pub hi_hz: f64,
    /// Centre used for D = 1.0994 / (T60 f_center), Hz.
    pub center_hz: f64,
}

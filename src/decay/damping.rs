//! Conversions between decay time and damping.

/// `D · f · T60` for a single exponentially decaying mode: ln(10⁶)/(4π) = 3·ln(10)/(2π) ≈ 1.0994.
///
/// The report's eq. 2.14 rounds it to 1.1 (a 0.05 % difference); dampscope uses the exact value.
pub const DAMPING_T60_PRODUCT: f64 = 3.0 * std::f64::consts::LN_10 / (2.0 * std::f64::consts::PI);

/// Critical damping ratio D (fraction, not %) of a decay with reverberation time `t60_s` at
/// frequency `frequency_hz` (report eq. 2.14).
pub fn damping_ratio(t60_s: f64, frequency_hz: f64) -> f64 {
    DAMPING_T60_PRODUCT / (t60_s * frequency_hz)
}

/// Reverberation time T60 in seconds of a mode with damping ratio `damping_ratio` at
/// `frequency_hz` (report eq. 4.4).
pub fn t60_from_damping(damping_ratio: f64, frequency_hz: f64) -> f64 {
    DAMPING_T60_PRODUCT / (damping_ratio * frequency_hz)
}

/// Corrects a damping ratio computed with the band centre for the frequency actually present
/// (report eq. 3.2): D_real = D_calc · f_center / f_real. Exact, since both equal σ/(2π f_real).
pub fn corrected_damping_ratio(damping_ratio: f64, f_center_hz: f64, f_dominant_hz: f64) -> f64 {
    damping_ratio * f_center_hz / f_dominant_hz
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn energy_of_a_mode_falls_60_db_in_t60() {
        let (d, f) = (0.025, 55.0);
        let t60 = t60_from_damping(d, f);
        // Energy envelope e^{-2 D ω t}: level after t60 must be −60 dB.
        let level_db = 10.0
            * (-2.0 * d * 2.0 * std::f64::consts::PI * f * t60)
                .exp()
                .log10();
        assert!((level_db + 60.0).abs() < 1e-9, "{level_db}");
        assert!((damping_ratio(t60, f) - d).abs() < 1e-15);
    }
}

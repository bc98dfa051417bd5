//! Conversions between decay time and damping.

use super::estimate::{DecayEstimate, Flag};

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

/// Decay time (any of EDT, T20, T30, T60, all scaled to 60 dB) with an exponential window's
/// decay rate 1/τ removed: the window e^(−t/τ) adds 1/τ to the amplitude decay rate
/// σ = 3 ln 10 / T. `None` when nothing is left (the window accounts for all the decay).
pub fn t60_without_window(t60_s: f64, tau_s: f64) -> Option<f64> {
    let sigma = 3.0 * std::f64::consts::LN_10 / t60_s - 1.0 / tau_s;
    (sigma > 0.0 && sigma.is_finite()).then(|| 3.0 * std::f64::consts::LN_10 / sigma)
}

/// Removes an exponential window's damping from an estimate of a band centred at
/// `f_center_hz`: every decay time through [`t60_without_window`], both damping ratios again
/// from the corrected T60, and flag `exponential_window_removed`. When the window accounts for
/// all the decay the numbers are withheld (`no_decay`).
pub fn remove_exponential_window(est: &mut DecayEstimate, tau_s: f64, f_center_hz: f64) {
    if est.t60_s.is_none() && est.edt_s.is_none() {
        return;
    }
    for t in [&mut est.edt_s, &mut est.t20_s, &mut est.t30_s] {
        *t = t.and_then(|v| t60_without_window(v, tau_s));
    }
    est.flags.push(Flag::ExponentialWindowRemoved);
    let Some(t60) = est.t60_s.map(|v| t60_without_window(v, tau_s)) else {
        return;
    };
    match t60 {
        Some(t60) => {
            est.t60_s = Some(t60);
            est.damping_ratio = Some(damping_ratio(t60, f_center_hz));
            est.damping_ratio_corrected = est
                .f_dominant_hz
                .filter(|f| *f > 0.0)
                .map(|f| damping_ratio(t60, f));
        }
        None => est.withhold(Flag::NoDecay),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_adds_a_known_damping_that_is_removed_again() {
        // D = 2 % at 50 Hz under a window of τ = 0.5 s: measured D = 2 % + 1/(2π·50·0.5).
        let (d, f, tau) = (0.02, 50.0, 0.5);
        let d_win = d + 1.0 / (2.0 * std::f64::consts::PI * f * tau);
        let mut est = DecayEstimate {
            t60_s: Some(t60_from_damping(d_win, f)),
            t30_s: Some(t60_from_damping(d_win, f)),
            damping_ratio: Some(d_win),
            f_dominant_hz: Some(f),
            ..Default::default()
        };
        remove_exponential_window(&mut est, tau, f);
        assert!((est.damping_ratio.unwrap() / d - 1.0).abs() < 1e-12);
        assert!((est.damping_ratio_corrected.unwrap() / d - 1.0).abs() < 1e-12);
        assert!((est.t30_s.unwrap() / t60_from_damping(d, f) - 1.0).abs() < 1e-12);
        assert!(est.has(Flag::ExponentialWindowRemoved));
        // A window faster than the decay leaves nothing: withheld, not negative.
        let mut est = DecayEstimate {
            t60_s: Some(2.0),
            damping_ratio: Some(0.01),
            ..Default::default()
        };
        remove_exponential_window(&mut est, 0.1, f);
        assert!(est.damping_ratio.is_none() && est.has(Flag::NoDecay));
    }

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

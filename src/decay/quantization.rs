//! The quantization floor: what an integer recording cannot hold.
//!
//! Rounding to a step Δ adds noise of Δ² / 12 per sample. Dithered — by a dither signal or by
//! the sensor's own noise of a few counts — that noise is white, independent of the signal,
//! and shows in the band energies as a floor that Lundeby's method finds. Undithered, as
//! synthetic exports and quiet recordings of a quiet chain are, it is a distortion of the loud
//! modes: a weak or fast band sees, after its own decay, the rounding error of the strong modes,
//! which decays with *them*, then exact zeros once everything is below half a step. Its curve
//! shows no floor and seems to decay over 80–120 dB, and the fit reads the strong modes'
//! decay: a 16-bit recording peaking at −48 dBFS gave D 95 % low, unflagged, in a band whose
//! mode peaked 14 dB above its share of Δ² / 12.
//!
//! The floor is known without looking: Δ² / 12 times what the band receives from white noise of
//! unit variance ([`crate::frontend::FrontEnd::white_noise_energy`]). Unless the record shows a
//! floor at least [`DITHERED_ABOVE_DB`] above it, each decay time (EDT, T20, T30) stands only
//! if the band's peak frame energy clears the rounding noise by the range's depth plus the
//! noise margin plus [`UNDITHERED_EXTRA_MARGIN_DB`]; otherwise it is missing, and the reported
//! number is withheld with [`super::Flag::QuantizationLimited`]
//! ([`super::estimate::estimate_from_coded_curve`]).

/// Energy per frame of a band from rounding to `step` (noise of step² / 12 per sample), given
/// the band's white-noise energy per frame for unit variance.
pub fn floor_energy(step: f64, white_noise_energy: f64) -> f64 {
    step * step / 12.0 * white_noise_energy
}

/// `floor_energy` as an estimator keeps it: 0 (no floor) unless finite and positive.
pub(crate) fn kept_floor(floor_energy: f64) -> f64 {
    if floor_energy.is_finite() && floor_energy > 0.0 {
        floor_energy
    } else {
        0.0
    }
}

/// A measured noise floor at least this far above the rounding noise dithers it, dB: noise of
/// more than Δ² / 6 per sample (σ ≳ 0.4 Δ) spreads each sample over several steps, and what
/// rounding adds is then part of the floor that the estimate measures and compensates.
pub const DITHERED_ABOVE_DB: f64 = 3.0;

/// The margin an undithered rounding floor needs beyond the noise margin, dB. Its error is not
/// an additive floor that Lundeby's method can place and subtract, but a distortion of the
/// decay: measured on 8- and 16-bit undithered WAVs of four random modes (4096–16384 Hz, 3
/// and 5 s, T60 0.3–2.5 s, peaks −70…0 dBFS, 50 Hz STFT bands), T30 numbers were within 5 %
/// of the truth once the peak cleared the floor by 55 dB, and off by up to 21 % between 45 and
/// 55 dB (the 10 dB margin of a measured floor); the same decays as float WAVs within 0.5 %.
pub const UNDITHERED_EXTRA_MARGIN_DB: f64 = 10.0;

/// How far (dB) a band's `peak_energy` lies above its undithered rounding noise of
/// `floor_energy` per frame: `None` without a known floor (float input), without energy, or
/// when the record's own floor (`measured_floor_db` below the peak) dithers it.
pub fn undithered_clearance_db(
    peak_energy: f64,
    floor_energy: f64,
    measured_floor_db: Option<f64>,
) -> Option<f64> {
    (floor_energy > 0.0 && peak_energy > 0.0)
        .then(|| 10.0 * (peak_energy / floor_energy).log10())
        .filter(|&q| measured_floor_db.is_none_or(|pnr| pnr > q - DITHERED_ABOVE_DB))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decay::estimate::{estimate_from_coded_curve, EstimateSettings};
    use crate::decay::{Flag, FrequencyCoding};

    /// A 1 s T60 decay at 10 ms frames, 3 s, peak 1, noiseless: its estimate with a rounding
    /// floor `clearance_db` below the peak.
    fn estimate_with_floor(
        clearance_db: f64,
        range: crate::decay::range::EvaluationRange,
    ) -> crate::decay::DecayEstimate {
        let energies: Vec<f64> = (0..300)
            .map(|k| 10f64.powf(-6.0 * k as f64 * 0.01))
            .collect();
        let mut edc = energies.clone();
        for k in (0..edc.len() - 1).rev() {
            edc[k] += edc[k + 1];
        }
        let frequencies = vec![100.0; energies.len()];
        let settings = EstimateSettings {
            range,
            ..Default::default()
        };
        let floor = 10f64.powf(-clearance_db / 10.0);
        estimate_from_coded_curve(
            &edc,
            &energies,
            &frequencies,
            FrequencyCoding::Hz,
            0.01,
            100.0,
            &settings,
            floor,
        )
    }

    /// T30 needs its 35 dB plus 10 + 10 dB of clearance, T20 25 + 20, EDT 10 + 20: at 50 dB
    /// the T30 number is withheld as `quantization_limited` and T20 and EDT stand; at 56 dB
    /// all stand, as without a floor.
    #[test]
    fn each_range_needs_its_depth_plus_both_margins_above_the_floor() {
        use crate::decay::range::EvaluationRange::{T20, T30};
        let clear = estimate_with_floor(56.0, T30);
        let none = estimate_with_floor(f64::INFINITY, T30);
        assert_eq!(clear, none);
        assert!((clear.t60_s.unwrap() - 1.0).abs() < 0.01, "{clear:?}");

        let limited = estimate_with_floor(50.0, T30);
        assert_eq!(limited.t30_s, None);
        assert_eq!(limited.damping_ratio, None);
        assert!(
            limited.t20_s.is_some() && limited.edt_s.is_some(),
            "{limited:?}"
        );
        assert_eq!(limited.missing_reason(), Some("quantization_limited"));

        let t20 = estimate_with_floor(50.0, T20);
        assert!(
            t20.damping_ratio.is_some() && !t20.has(Flag::QuantizationLimited),
            "{t20:?}"
        );
        let t20 = estimate_with_floor(40.0, T20);
        assert!(
            t20.has(Flag::QuantizationLimited) && t20.edt_s.is_some(),
            "{t20:?}"
        );
        assert!(estimate_with_floor(29.0, T20).edt_s.is_none());
    }

    /// A measured floor 3 dB or more above the rounding noise dithers it (no extra margin, no
    /// flag); closer, or none, leaves the clearance to be checked.
    #[test]
    fn a_measured_floor_above_the_rounding_noise_dithers_it() {
        assert_eq!(undithered_clearance_db(1.0, 1e-5, Some(46.9)), None);
        assert_eq!(undithered_clearance_db(1.0, 1e-5, Some(47.1)), Some(50.0));
        assert_eq!(undithered_clearance_db(1.0, 1e-5, None), Some(50.0));
        assert_eq!(undithered_clearance_db(1.0, 0.0, None), None);
        assert_eq!(undithered_clearance_db(0.0, 1e-5, None), None);
    }
}

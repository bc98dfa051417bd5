//! Identified modes against a finite-element model: the model's mode shapes read at the
//! recording's sensor positions, and each identified mode paired with the model mode its shape
//! resembles most (MAC). Shapes, not frequencies, make the pairing: a model that is off in
//! stiffness still pairs the right modes, and a close pair is told apart.

use faer::c64;

use super::Mode;
use crate::sim::assembly::{assemble, sensors_at};
use crate::sim::eigen::{lowest_modes, ModeRequest};
use crate::sim::error::SimError;
use crate::sim::model::{Model, SensorPosition};

/// Model modes are computed up to this multiple of the analysis range's upper limit, so that a
/// stiffer structure's modes near the limit still find their partner.
pub const MODEL_FMAX_FACTOR: f64 = 1.3;

/// Where a recording set's sensors are, as the model reads positions. The model's responses
/// are out-of-plane (z) displacements, the same through the thickness of a bending plate; a
/// sensor measuring another direction (`dir` of FORMATS.md §1: `x`, `y`, or `-z`, whose sign is
/// flipped) would be compared with them silently, so it is an error naming the sensor.
pub fn sensor_positions(
    sensors: &[crate::source::recording_set::Sensor],
) -> Result<Vec<SensorPosition>, SimError> {
    sensors
        .iter()
        .enumerate()
        .map(|(row, s)| {
            let dir = s.dir.trim().to_ascii_lowercase();
            if !matches!(dir.as_str(), "z" | "+z" | "") {
                return Err(crate::sim::error::invalid(
                    format!("sensors.csv row {} (id {}).dir", row + 1, s.id),
                    format!(
                        "expected z (the model's responses are out-of-plane), got {:?}{}",
                        s.dir,
                        if dir == "-z" {
                            ": negate the channel and give dir z"
                        } else {
                            ": leave in-plane sensors out of the set"
                        }
                    ),
                ));
            }
            Ok(SensorPosition {
                id: s.id.clone(),
                x_m: s.x_m,
                y_m: s.y_m,
            })
        })
        .collect()
}

/// One mode of the model, its shape at the sensors.
#[derive(Clone, Debug)]
pub struct ModelMode {
    /// Natural frequency, Hz.
    pub frequency_hz: f64,
    /// Out-of-plane displacement at each sensor (mass-normalised modal amplitude).
    pub shape: Vec<f64>,
}

/// The model's modes below `fmax_hz` read at `positions`.
pub fn model_modes_at(
    model: &Model,
    positions: &[SensorPosition],
    fmax_hz: f64,
) -> Result<Vec<ModelMode>, SimError> {
    let system = assemble(model)?;
    let sensors = sensors_at(model, positions)?;
    let modes = lowest_modes(&system, ModeRequest::BelowHz(fmax_hz))?;
    Ok(modes
        .frequencies_hz
        .iter()
        .enumerate()
        .map(|(i, &f)| ModelMode {
            frequency_hz: f,
            shape: shape_at(&sensors, modes.shapes.as_ref(), i),
        })
        .collect())
}

/// Column `col` of `shapes` (n_free × modes) read at each sensor (its interpolation weights).
pub fn shape_at(
    sensors: &[crate::sim::system::SensorWeights],
    shapes: faer::MatRef<'_, f64>,
    col: usize,
) -> Vec<f64> {
    sensors
        .iter()
        .map(|s| s.weights.iter().map(|&(d, w)| w * shapes[(d, col)]).sum())
        .collect()
}

/// An identified mode's partner in the model.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ModelMatch {
    /// The model mode, 1-based in ascending frequency.
    pub model_mode: usize,
    /// Its frequency, Hz.
    pub model_frequency_hz: f64,
    /// MAC between the identified (complex) and the model (real) shape.
    pub mac: f64,
}

/// MAC |φᴴψ|² / (|φ|²|ψ|²) of a complex identified shape and a real model shape.
pub fn mac_complex_real(identified: &[c64], model: &[f64]) -> f64 {
    let mut dot = c64::new(0.0, 0.0);
    let (mut na, mut nb) = (0.0, 0.0);
    for (a, &b) in identified.iter().zip(model) {
        dot += a.conj() * b;
        na += a.norm_sqr();
        nb += b * b;
    }
    if na > 0.0 && nb > 0.0 {
        dot.norm_sqr() / (na * nb)
    } else {
        0.0
    }
}

/// Each identified mode's model partner: the model mode of highest MAC (`None` when the mode
/// has no shape or the model no modes).
pub fn match_model(modes: &[Mode], model: &[ModelMode]) -> Vec<Option<ModelMatch>> {
    modes
        .iter()
        .map(|m| {
            model
                .iter()
                .enumerate()
                .map(|(i, mm)| ModelMatch {
                    model_mode: i + 1,
                    model_frequency_hz: mm.frequency_hz,
                    mac: mac_complex_real(&m.shape, &mm.shape),
                })
                .filter(|x| x.mac.is_finite() && !m.shape.is_empty())
                .max_by(|a, b| a.mac.total_cmp(&b.mac))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mac_ignores_scale_and_phase_and_sees_orthogonality() {
        let real = [1.0, -2.0, 0.5];
        let rotated: Vec<c64> = real
            .iter()
            .map(|&v| c64::from_polar(3.0 * v, 0.9))
            .collect();
        assert!((mac_complex_real(&rotated, &real) - 1.0).abs() < 1e-12);
        let other = [2.0, 1.0, 0.0];
        assert!(mac_complex_real(&rotated, &other) < 1e-12);
    }

    /// Found by the contract probe: a sensor measuring x was compared with the model's z
    /// responses without a word. z (any case, `+z`) passes; x, y and −z are refused by row and id.
    #[test]
    fn sensors_measuring_another_direction_are_refused() {
        let sensor = |id: &str, dir: &str| crate::source::recording_set::Sensor {
            id: id.into(),
            x_m: 0.5,
            y_m: 0.5,
            z_m: None,
            dir: dir.into(),
        };
        let ok = [sensor("a", "z"), sensor("b", " Z"), sensor("c", "+z")];
        assert_eq!(sensor_positions(&ok).unwrap().len(), 3);
        let x = sensor_positions(&[sensor("a", "z"), sensor("b", "x")]).unwrap_err();
        assert!(
            x.to_string()
                .starts_with("sensors.csv row 2 (id b).dir: expected z"),
            "{x}"
        );
        let minus = sensor_positions(&[sensor("m", "-z")])
            .unwrap_err()
            .to_string();
        assert!(minus.contains("negate the channel"), "{minus}");
    }
}

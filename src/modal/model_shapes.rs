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

/// The MAC of a complex identified shape with the span of several real model shapes: the
/// share of |φ|² that the span holds, |Qᵀφ|² / |φ|² with Q an orthonormal basis of the span
/// (Gram–Schmidt). With one shape it is [`mac_complex_real`]; with modes so close that their
/// mixing is not to be trusted it scores the pair as a whole (shapes that are linearly
/// dependent on the earlier ones add nothing).
pub fn subspace_mac(identified: &[c64], span: &[&[f64]]) -> f64 {
    let total: f64 = identified.iter().map(|a| a.norm_sqr()).sum();
    if total <= 0.0 {
        return 0.0;
    }
    let mut basis: Vec<Vec<f64>> = Vec::with_capacity(span.len());
    let mut held = 0.0;
    for shape in span {
        let mut q: Vec<f64> = shape.to_vec();
        let scale = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        for b in &basis {
            let d: f64 = q.iter().zip(b).map(|(x, y)| x * y).sum();
            q.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
        }
        let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        // A shape (nearly) in the span of the earlier ones adds no direction (NaN neither).
        if norm.is_nan() || norm <= 1e-9 * scale {
            continue;
        }
        q.iter_mut().for_each(|x| *x /= norm);
        let dot = identified
            .iter()
            .zip(&q)
            .fold(c64::new(0.0, 0.0), |acc, (a, &b)| acc + a.conj() * b);
        held += dot.norm_sqr();
        basis.push(q);
    }
    (held / total).min(1.0)
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

    /// The slow oracle: the least-squares projection of φ on the span, solved by the normal
    /// equations of the (linearly independent) shapes.
    fn projected_share(phi: &[c64], span: &[&[f64]]) -> f64 {
        let n = span.len();
        let gram = nalgebra::DMatrix::from_fn(n, n, |i, j| {
            span[i].iter().zip(span[j]).map(|(a, b)| a * b).sum::<f64>()
        });
        let inverse = gram.try_inverse().unwrap();
        let parts: [fn(&c64) -> f64; 2] = [|z| z.re, |z| z.im];
        let mut held = 0.0;
        for part in parts {
            let rhs = nalgebra::DVector::from_fn(n, |i, _| {
                span[i]
                    .iter()
                    .zip(phi)
                    .map(|(a, z)| a * part(z))
                    .sum::<f64>()
            });
            held += rhs.dot(&(&inverse * &rhs));
        }
        held / phi.iter().map(|z| z.norm_sqr()).sum::<f64>()
    }

    #[test]
    fn the_subspace_mac_is_the_share_of_the_shape_in_the_span() {
        let a = [1.0, 0.5, -0.3, 0.2, 0.0];
        let b = [0.1, -0.8, 0.4, 0.9, 0.3];
        let c = [0.7, 0.2, 0.1, -0.5, 1.0];
        let phi: Vec<c64> = (0..5)
            .map(|i| {
                c64::new(
                    0.6 * a[i] - 0.9 * b[i] + 0.05 * c[i],
                    0.1 * c[i] - 0.2 * a[i],
                )
            })
            .collect();
        // One shape: the ordinary MAC.
        let one = subspace_mac(&phi, &[&a]);
        assert!((one - mac_complex_real(&phi, &a)).abs() < 1e-12, "{one}");
        // Two and three shapes: the share the projection holds, as the normal equations give it.
        for span in [vec![&a[..], &b[..]], vec![&a[..], &b[..], &c[..]]] {
            let (fast, slow) = (subspace_mac(&phi, &span), projected_share(&phi, &span));
            assert!((fast - slow).abs() < 1e-12, "{fast} against {slow}");
        }
        // The two shapes φ's real part is made of hold it nearly whole, each alone far less.
        let both = subspace_mac(&phi, &[&a, &b]);
        assert!(both > 0.95 && mac_complex_real(&phi, &a) < 0.5, "{both}");
        // A shape in the span of the earlier ones adds nothing.
        let dependent: Vec<f64> = a.iter().zip(&b).map(|(x, y)| 2.0 * x - y).collect();
        let with = subspace_mac(&phi, &[&a, &b, &dependent]);
        assert!((with - both).abs() < 1e-12, "{with} against {both}");
        assert_eq!(subspace_mac(&[c64::new(0.0, 0.0); 5], &[&a]), 0.0);
    }
}

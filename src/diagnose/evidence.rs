//! The evidence a diagnosis stands on: the recordings' identified modes (frequency, damping,
//! complex shape; `crate::modal`) paired with the model's damped poles and its shapes read at
//! the same sensors. Shapes make the pairing (a mass or a soft edge moves frequencies and can
//! swap the order of modes); each pair gives Δf/f and ΔD. A global stiffness calibration (the
//! median frequency ratio) and the paired modes' robust scatter around it measure how far the
//! user's model differs from the structure in form alone (mesh, plate theory), so that physics
//! is only claimed for differences beyond that.

use crate::modal::model_shapes::{mac_complex_real, shape_at};
use crate::modal::Mode;
use crate::sim::assembly::{assemble, sensors_at};
use crate::sim::eigen::{lowest_modes, ModeRequest};
use crate::sim::error::SimError;
use crate::sim::model::{Model, SensorPosition};
use crate::sim::poles::{damped_poles_from_modes, POLE_BASIS_FACTOR};

/// A pair's shapes must have at least this MAC (a mode's partner in a model with a concealed
/// mass keeps MAC > 0.9; two different modes of a plate stay below 0.5 at 99 sensors).
pub const MIN_PAIR_MAC: f64 = 0.6;
/// A pair's frequencies may differ by at most this fraction (a soft edge lowers frequencies by
/// up to ~10 %).
pub const MAX_PAIR_FREQUENCY_REL: f64 = 0.15;
/// Scale from the median absolute deviation to a normal standard deviation.
const MAD_TO_SIGMA: f64 = 1.4826;

/// One mode of the model at the sensors, with its damped pole.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelPole {
    /// 1-based number among the model's modes.
    pub mode: usize,
    /// Undamped natural frequency, Hz.
    pub frequency_hz: f64,
    /// Damped frequency, Hz (what the identification measures).
    pub damped_frequency_hz: f64,
    /// Damping ratio of the pole.
    pub damping_ratio: f64,
    /// Out-of-plane displacement at each sensor (mass-normalised).
    pub shape: Vec<f64>,
}

/// A model solved once for a diagnosis: its undamped modes (to [`POLE_BASIS_FACTOR`] × the
/// range, the basis of its damped poles) and everything read from them.
pub struct ModelView {
    /// The model.
    pub model: Model,
    /// Its assembled system.
    pub system: crate::sim::FeSystem,
    /// Its undamped modes, mass-normalised, to twice the range.
    pub basis: crate::sim::eigen::Modes,
    /// How many of them lie below the range's upper limit.
    pub count: usize,
    /// The range's upper limit, Hz.
    pub fmax_hz: f64,
}

impl ModelView {
    /// Assembles and solves `model` for the modes below `fmax_hz`.
    pub fn new(model: &Model, fmax_hz: f64) -> Result<Self, SimError> {
        let system = assemble(model)?;
        let basis = lowest_modes(&system, ModeRequest::BelowHz(POLE_BASIS_FACTOR * fmax_hz))?;
        let count = basis
            .frequencies_hz
            .iter()
            .filter(|&&f| f < fmax_hz)
            .count();
        Ok(Self {
            model: model.clone(),
            system,
            basis,
            count,
            fmax_hz,
        })
    }

    /// A view of `model`, which differs from this one's in loss only (loss factors, patches
    /// that change nothing but the loss factor, Rayleigh damping): the undamped modes are the
    /// same, so they are reused instead of solved again.
    pub fn with_loss_change(&self, model: &Model) -> Result<Self, SimError> {
        Ok(Self {
            model: model.clone(),
            system: assemble(model)?,
            basis: self.basis.clone(),
            count: self.count,
            fmax_hz: self.fmax_hz,
        })
    }

    /// The modes below the range read at `positions`: one vector per mode, one value per
    /// position (mass-normalised out-of-plane displacement, m/√kg).
    pub fn shapes_at(&self, positions: &[SensorPosition]) -> Result<Vec<Vec<f64>>, SimError> {
        let sensors = sensors_at(&self.model, positions)?;
        Ok((0..self.count)
            .map(|i| shape_at(&sensors, self.basis.shapes.as_ref(), i))
            .collect())
    }

    /// The complex shapes of the damped modes below the range at `positions` (one vector per
    /// mode, unnormalised): with non-proportional damping their quadrature part shows where
    /// the loss is.
    pub fn complex_shapes_at(
        &self,
        positions: &[SensorPosition],
    ) -> Result<Vec<Vec<faer::c64>>, SimError> {
        let mut system = self.system.clone();
        system.sensors = sensors_at(&self.model, positions)?;
        let reduced = crate::sim::reduced::ReducedModel::build(
            &system,
            &self.basis.frequencies_hz,
            self.basis.shapes.as_ref(),
            crate::sim::reduced::BasisOptions::default(),
        )?;
        Ok(reduced
            .damped_modes()?
            .into_iter()
            .take(self.count)
            .map(|m| m.2)
            .collect())
    }

    /// The damped poles below the range with their shapes at `positions`. Errors as the
    /// simulator's (an SLS region: its poles depend on frequency).
    pub fn poles_at(&self, positions: &[SensorPosition]) -> Result<Vec<ModelPole>, SimError> {
        let poles = damped_poles_from_modes(&self.system, &self.basis, self.count)?;
        let shapes = self.shapes_at(positions)?;
        Ok(shapes
            .into_iter()
            .enumerate()
            .map(|(i, shape)| ModelPole {
                mode: i + 1,
                frequency_hz: self.basis.frequencies_hz[i],
                damped_frequency_hz: poles[i].damped_frequency_hz,
                damping_ratio: poles[i].damping_ratio,
                shape,
            })
            .collect())
    }
}

/// The model's damped poles with undamped natural frequency below `fmax_hz`, their shapes at
/// `positions` ([`ModelView::poles_at`] of a fresh view).
pub fn model_poles_at(
    model: &Model,
    positions: &[SensorPosition],
    fmax_hz: f64,
) -> Result<Vec<ModelPole>, SimError> {
    ModelView::new(model, fmax_hz)?.poles_at(positions)
}

/// A measured mode and its model partner.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ModePair {
    /// Index into the measured modes.
    pub measured: usize,
    /// Index into the model poles.
    pub model: usize,
    /// MAC of the two shapes.
    pub mac: f64,
    /// Measured over model damped frequency, minus 1.
    pub frequency_rel: f64,
    /// Measured minus model damping ratio.
    pub damping_diff: f64,
    /// The measured damping ratio's standard deviation.
    pub damping_std: f64,
}

/// One-to-one pairs of measured modes and model poles: among all couples with MAC ≥
/// [`MIN_PAIR_MAC`] and frequencies within [`MAX_PAIR_FREQUENCY_REL`], the highest MAC is
/// paired first. Returns the pairs (by measured frequency) and the indices left unpaired
/// (measured, model).
pub fn pair_modes(
    measured: &[Mode],
    model: &[ModelPole],
) -> (Vec<ModePair>, Vec<usize>, Vec<usize>) {
    let mut couples = Vec::new();
    for (i, m) in measured.iter().enumerate() {
        for (j, p) in model.iter().enumerate() {
            let rel = m.frequency_hz / p.damped_frequency_hz - 1.0;
            if rel.abs() > MAX_PAIR_FREQUENCY_REL {
                continue;
            }
            let mac = mac_complex_real(&m.shape, &p.shape);
            if mac >= MIN_PAIR_MAC {
                couples.push((mac, i, j, rel));
            }
        }
    }
    couples.sort_by(|a, b| b.0.total_cmp(&a.0));
    let (mut used_m, mut used_p) = (vec![false; measured.len()], vec![false; model.len()]);
    let mut pairs = Vec::new();
    for (mac, i, j, rel) in couples {
        if used_m[i] || used_p[j] {
            continue;
        }
        used_m[i] = true;
        used_p[j] = true;
        pairs.push(ModePair {
            measured: i,
            model: j,
            mac,
            frequency_rel: rel,
            damping_diff: measured[i].damping_ratio - model[j].damping_ratio,
            damping_std: measured[i].damping_std,
        });
    }
    pairs.sort_by_key(|p| p.measured);
    let unpaired = |used: &[bool]| (0..used.len()).filter(|&k| !used[k]).collect();
    (pairs, unpaired(&used_m), unpaired(&used_p))
}

/// The model-form part of the frequency differences: a global stiffness calibration and the
/// scatter left around it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Calibration {
    /// Median of ln(f_measured / f_model) over the pairs: the model's frequencies times
    /// e^this (its stiffness times e^(2·this)) match the structure's in the median.
    pub log_frequency_ratio: f64,
    /// Robust standard deviation (1.4826 · MAD) of the pairs' ln frequency ratios around the
    /// median: the model-form scatter no physics is claimed within.
    pub frequency_sigma_rel: f64,
}

/// [`Calibration`] of `pairs`; `None` without pairs.
pub fn calibrate(pairs: &[ModePair]) -> Option<Calibration> {
    let mut logs: Vec<f64> = pairs.iter().map(|p| p.frequency_rel.ln_1p()).collect();
    let centre = median(&mut logs)?;
    let mut dev: Vec<f64> = logs.iter().map(|l| (l - centre).abs()).collect();
    Some(Calibration {
        log_frequency_ratio: centre,
        frequency_sigma_rel: MAD_TO_SIGMA * median(&mut dev)?,
    })
}

fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// Everything measured against the model.
#[derive(Clone, Debug)]
pub struct Evidence {
    /// The model's poles in the analysed range (and a margin above it).
    pub model: Vec<ModelPole>,
    /// Measured–model pairs.
    pub pairs: Vec<ModePair>,
    /// Measured modes without a model partner (indices).
    pub unpaired_measured: Vec<usize>,
    /// Model poles without a measured partner (indices).
    pub unpaired_model: Vec<usize>,
    /// The model-form calibration (`None` when nothing paired).
    pub calibration: Option<Calibration>,
}

impl Evidence {
    /// Pairs `measured` with `model` and calibrates.
    pub fn gather(measured: &[Mode], model: Vec<ModelPole>) -> Self {
        let (pairs, unpaired_measured, unpaired_model) = pair_modes(measured, &model);
        let calibration = calibrate(&pairs);
        Self {
            model,
            pairs,
            unpaired_measured,
            unpaired_model,
            calibration,
        }
    }

    /// The pairs whose model mode lies among `view`'s modes below its range (the rest were
    /// paired with modes beyond it, which have no strain-energy shares or shapes in `view`).
    pub fn pairs_within(&self, view: &ModelView) -> Vec<&ModePair> {
        self.pairs.iter().filter(|p| p.model < view.count).collect()
    }

    /// RMS over the pairs of the damping ratio difference (`None` without pairs).
    pub fn damping_rms(&self) -> Option<f64> {
        rms(self.pairs.iter().map(|p| p.damping_diff))
    }

    /// RMS over the pairs of the damped frequency difference, Hz (`None` without pairs).
    pub fn frequency_rms_hz(&self) -> Option<f64> {
        rms(self.pairs.iter().map(|p| {
            let f = self.model[p.model].damped_frequency_hz;
            f * p.frequency_rel
        }))
    }
}

fn rms(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (mut sum, mut n) = (0.0, 0usize);
    for v in values {
        sum += v * v;
        n += 1;
    }
    (n > 0).then(|| (sum / n as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::c64;

    fn mode(f: f64, d: f64, shape: &[f64]) -> Mode {
        Mode {
            frequency_hz: f,
            damping_ratio: d,
            frequency_std_hz: 0.0,
            damping_std: 0.001,
            frequency_order_std_hz: 0.0,
            damping_order_std: 0.0,
            frequency_sensor_std_hz: 0.0,
            damping_sensor_std: 0.0,
            mpc: 1.0,
            n_stable: 10,
            modal_snr_db: 30.0,
            shape: shape.iter().map(|&v| c64::new(v, 0.0)).collect(),
        }
    }

    fn pole(mode: usize, f: f64, shape: &[f64]) -> ModelPole {
        ModelPole {
            mode,
            frequency_hz: f,
            damped_frequency_hz: f,
            damping_ratio: 0.02,
            shape: shape.to_vec(),
        }
    }

    /// A mass swaps the order of two close modes: the shapes, not the order, pair them; a
    /// measured mode unlike every model shape and a model mode never seen stay unpaired.
    #[test]
    fn shapes_pair_swapped_modes_and_leave_strangers_alone() {
        let (a, b, c) = (
            [1.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, 1.0, 0.0],
            [1.0, 1.0, -1.0, -1.0],
        );
        let measured = [
            mode(10.0, 0.03, &b),
            mode(10.4, 0.02, &a),
            mode(30.0, 0.02, &[1.0, -1.0, 1.0, -1.0]),
        ];
        let model = [pole(1, 10.2, &a), pole(2, 10.5, &b), pole(3, 20.0, &c)];
        let (pairs, extra, missing) = pair_modes(&measured, &model);
        assert_eq!(pairs.len(), 2);
        assert_eq!((pairs[0].measured, pairs[0].model), (0, 1));
        assert_eq!((pairs[1].measured, pairs[1].model), (1, 0));
        assert!((pairs[0].damping_diff - 0.01).abs() < 1e-12);
        assert!((pairs[0].frequency_rel - (10.0 / 10.5 - 1.0)).abs() < 1e-12);
        assert_eq!(extra, vec![2]);
        assert_eq!(missing, vec![2]);
    }

    /// A uniform 1 % stiffness error is calibrated away; one mode moved by a mass stands out
    /// of the scatter.
    #[test]
    fn calibration_takes_the_median_and_a_robust_scatter() {
        let rel = [0.005, 0.0051, 0.0049, 0.0050, 0.0052, -0.02];
        let pairs: Vec<ModePair> = rel
            .iter()
            .enumerate()
            .map(|(k, &r)| ModePair {
                measured: k,
                model: k,
                mac: 1.0,
                frequency_rel: r,
                damping_diff: 0.0,
                damping_std: 0.0,
            })
            .collect();
        let c = calibrate(&pairs).unwrap();
        assert!((c.log_frequency_ratio - 0.00505f64.ln_1p()).abs() < 1e-4);
        assert!(c.frequency_sigma_rel < 2e-4, "{c:?}");
        assert!(((-0.02f64).ln_1p() - c.log_frequency_ratio).abs() > 50.0 * c.frequency_sigma_rel);
        assert!(calibrate(&[]).is_none());
    }
}

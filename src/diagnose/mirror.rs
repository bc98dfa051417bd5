//! Mirror images of a lossy region. On a plate symmetric about its centre lines a rectangle
//! and its mirror images strain every mode alike, so modal damping cannot tell them apart. The
//! mode shapes can: non-proportional damping makes them complex, and their quadrature part
//! (the component 90° out of phase with the real shape) sits near the loss. Each candidate is
//! applied to the model, its damped modes are solved at the sensors, and their quadrature
//! patterns are correlated with the measured ones; the candidate that correlates best wins.

use faer::c64;

use super::damping::{apply, DampingHypothesis};
use super::evidence::{Evidence, ModelView};
use crate::modal::Mode;
use crate::sim::error::SimError;
use crate::sim::model::SensorPosition;

/// The quadrature part of `shape` relative to the real `reference`: `shape` rotated so that its
/// projection on `reference` is real and positive, then its imaginary part.
fn quadrature(shape: &[c64], reference: &[f64]) -> Vec<f64> {
    let a: c64 = shape
        .iter()
        .zip(reference)
        .fold(c64::new(0.0, 0.0), |acc, (s, r)| acc + s * r);
    if a.norm() == 0.0 {
        return vec![0.0; shape.len()];
    }
    let rot = a.conj() / a.norm();
    shape.iter().map(|s| (s * rot).im).collect()
}

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let (ab, aa, bb) = a
        .iter()
        .zip(b)
        .fold((0.0, 0.0, 0.0), |(ab, aa, bb), (x, y)| {
            (ab + x * y, aa + x * x, bb + y * y)
        });
    if aa > 0.0 && bb > 0.0 {
        ab / (aa * bb).sqrt()
    } else {
        0.0
    }
}

/// How well the damped modes of `model` match the measured shapes' quadrature parts: the
/// correlation per paired mode, weighted by how complex the model's mode is (a nearly real
/// mode says nothing about where the loss is).
fn quadrature_match(
    measured: &[Mode],
    evidence: &Evidence,
    view: &ModelView,
    sensors: &[SensorPosition],
) -> Result<f64, SimError> {
    let shapes = view.complex_shapes_at(sensors)?;
    let (mut num, mut den) = (0.0, 0.0);
    for p in &evidence.pairs {
        let Some(chi) = shapes.get(p.model) else {
            continue;
        };
        let reference = &evidence.model[p.model].shape;
        let q_model = quadrature(chi, reference);
        let q_meas = quadrature(&measured[p.measured].shape, reference);
        let total: f64 = chi.iter().map(|x| x.norm_sqr()).sum();
        let weight = if total > 0.0 {
            q_model.iter().map(|x| x * x).sum::<f64>() / total
        } else {
            0.0
        };
        num += weight * correlation(&q_meas, &q_model);
        den += weight;
    }
    Ok(if den > 0.0 { num / den } else { 0.0 })
}

/// The region hypothesis (fitted against `base`) with its rectangle replaced by the candidate (itself or an image)
/// whose complex shapes match the measured ones best; the others become its images. Also the
/// scores, per candidate in the order (first, images…). Other hypotheses pass unchanged.
pub fn resolve_images(
    measured: &[Mode],
    evidence: &Evidence,
    base: &ModelView,
    sensors: &[SensorPosition],
    hypothesis: &DampingHypothesis,
) -> Result<(DampingHypothesis, Vec<f64>), SimError> {
    let DampingHypothesis::Region {
        x_m,
        y_m,
        delta_g,
        images,
    } = hypothesis
    else {
        return Ok((hypothesis.clone(), Vec::new()));
    };
    if images.is_empty() {
        return Ok((hypothesis.clone(), Vec::new()));
    }
    let candidates: Vec<([f64; 2], [f64; 2])> = std::iter::once((*x_m, *y_m))
        .chain(images.iter().copied())
        .collect();
    let mut scores = Vec::with_capacity(candidates.len());
    for &(x, y) in &candidates {
        let h = DampingHypothesis::Region {
            x_m: x,
            y_m: y,
            delta_g: *delta_g,
            images: Vec::new(),
        };
        let view = base.with_loss_change(&apply(&base.model, &h))?;
        scores.push(quadrature_match(measured, evidence, &view, sensors)?);
    }
    let best = (0..scores.len())
        .max_by(|&a, &b| scores[a].total_cmp(&scores[b]))
        .expect("candidates are not empty");
    let (x, y) = candidates[best];
    Ok((
        DampingHypothesis::Region {
            x_m: x,
            y_m: y,
            delta_g: *delta_g,
            images: candidates
                .iter()
                .enumerate()
                .filter(|&(k, _)| k != best)
                .map(|(_, c)| *c)
                .collect(),
        },
        scores,
    ))
}

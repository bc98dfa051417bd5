//! Mirror images of a finding. On a plate symmetric about its centre lines a change and its
//! mirror images move the modes' frequencies and damping alike, so modal frequencies and
//! damping cannot tell them apart. The mode shapes can:
//!
//! - a loss (a lossy or viscoelastic region) makes the shapes complex, their quadrature part
//!   (the component 90° out of phase with the real shape) sitting near the loss: each image is
//!   applied to the model, its damped modes are solved at the sensors, and their quadrature
//!   patterns are correlated with the measured ones; the best correlation wins;
//! - a mass or a stiffness change bends the real shapes towards or away from itself: each image
//!   is applied, the model solved again, and the image whose shapes pair best with the measured
//!   ones (least Σ(1 − MAC), an unpaired mode counting 1) wins; model modes the change mixes
//!   strongly ([`MIXING_SPACING_PER_SHIFT`]) are scored as one subspace.
//!
//! The winner is settled when it beats the runner-up by a margin; otherwise the images stay in
//! the finding.

use faer::c64;

use super::evidence::{Evidence, ModelPole, ModelView};
use super::hypothesis::Hypothesis;
use super::refine::view_of;
use super::score::{Candidate, Prediction};
use super::workers::parallel_map;
use crate::modal::model_shapes::{shape_at, subspace_mac};
use crate::modal::Mode;
use crate::sim::assembly::{assemble, sensors_at};
use crate::sim::eigen::{lowest_modes, ModeRequest};
use crate::sim::error::SimError;
use crate::sim::model::SensorPosition;

/// A loss's image is ruled out when the best quadrature correlation beats the runner-up's by
/// this much (0.45–0.53 measured on the damped-patch cases; noise on a wrong image's
/// correlation is ~0.1).
pub const MIN_QUADRATURE_MARGIN: f64 = 0.2;
/// A mass's or stiffness change's image is ruled out when the runner-up's shape misfit
/// Σ(1 − MAC) exceeds the best one's by this much.
pub const MIN_SHAPE_MISFIT_MARGIN: f64 = 0.02;
/// Model modes closer than this many times the finding's largest relative frequency shift are
/// scored as one subspace when the shapes choose among a mass's or stiffness change's mirror
/// images. A change that moves a mode by δ couples it to a neighbour by up to about δ (a point
/// mass's coupling is the geometric mean of the two modes' shifts), and at a spacing of 2δ the
/// two are mixed by 22.5° or more (tan 2θ = 2δ / spacing). Mirror images differ in the sign of
/// that coupling, which the pair's order or spacing in another plate theory flips as well, so
/// the shapes' choice must not hang on it: on Kirchhoff recordings of a 2.63 kg mass (largest
/// shift 1.2 %), one mode of a pair 2.4 % apart (MAC 0.62 at the true place, 0.88 at the mirror
/// image) outweighed all the others and chose the mirror image.
pub const MIXING_SPACING_PER_SHIFT: f64 = 2.0;
/// Two changes of one kind are the same size (mirror images of each other) within this
/// relative difference of every parameter (the scan's images fit alike to 1e-3).
const SAME_SIZE_REL: f64 = 1e-3;
/// Most sizes of a lossy region handed on for the re-solved damping to choose among (the
/// shapes' favourites): the true one was among the shapes' first two on every set tried
/// (Kirchhoff and FE recordings of a damped patch and of a viscoelastic layer).
pub const MAX_SIZES: usize = 2;

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

/// How well the damped modes of `view` match the measured shapes' quadrature parts: the
/// correlation per paired mode, weighted by how complex the model's mode is (a nearly real
/// mode says nothing about where the loss is).
pub(crate) fn quadrature_match(
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

/// How well a place's re-solved shapes pair with the measured ones (lower is better); for a loss
/// both fields hold minus its quadrature correlation.
#[derive(Clone, Copy, Debug)]
struct ShapeMisfit {
    /// Σ(1 − MAC), each measured mode against its partner alone, an unpaired one counting 1.
    modes_alone: f64,
    /// The same with each measured mode's MAC taken with the span of its partner and the model
    /// modes within the mixing window of the partner's frequency ([`subspace_mac`]).
    mixed_as_one: f64,
}

/// The measured modes against `model` re-solved to `fmax_hz` (undamped shapes), with the
/// mixing window `mixing_window_rel` ([`ShapeMisfit`]).
fn shape_misfit(
    measured: &[Mode],
    model: &crate::sim::model::Model,
    sensors: &[SensorPosition],
    (fmax_hz, mixing_window_rel): (f64, f64),
) -> Result<ShapeMisfit, SimError> {
    let system = assemble(model)?;
    let modes = lowest_modes(&system, ModeRequest::BelowHz(fmax_hz))?;
    let at = sensors_at(model, sensors)?;
    let poles: Vec<ModelPole> = (0..modes.frequencies_hz.len())
        .map(|i| ModelPole {
            mode: i + 1,
            frequency_hz: modes.frequencies_hz[i],
            damped_frequency_hz: modes.frequencies_hz[i],
            damping_ratio: 0.0,
            shape: shape_at(&at, modes.shapes.as_ref(), i),
        })
        .collect();
    let e = Evidence::gather(measured, poles);
    let unpaired = (measured.len() - e.pairs.len()) as f64;
    let mixed: f64 = e
        .pairs
        .iter()
        .map(|p| {
            let partner = &e.model[p.model];
            let near = |q: &ModelPole| {
                (q.frequency_hz / partner.frequency_hz - 1.0).abs() <= mixing_window_rel
            };
            let span: Vec<&[f64]> = std::iter::once(partner)
                .chain(
                    e.model
                        .iter()
                        .enumerate()
                        .filter(|&(k, q)| k != p.model && near(q))
                        .map(|(_, q)| q),
                )
                .map(|q| &q.shape[..])
                .collect();
            1.0 - subspace_mac(&measured[p.measured].shape, &span)
        })
        .sum();
    Ok(ShapeMisfit {
        modes_alone: e.pairs.iter().map(|p| 1.0 - p.mac).sum::<f64>() + unpaired,
        mixed_as_one: mixed + unpaired,
    })
}

/// Whether `a` and `b` are one change at two places (the same kind and size: the scan's
/// mirror images), not a rival of another size.
fn same_change(a: &Hypothesis, b: &Hypothesis) -> bool {
    let same = |x: f64, y: f64| (x - y).abs() <= SAME_SIZE_REL * x.abs().max(y.abs());
    let dims = |r: &super::regions::Region| (r.x[1] - r.x[0], r.y[1] - r.y[0]);
    match (a, b) {
        (Hypothesis::AddedMass { mass_kg: p, .. }, Hypothesis::AddedMass { mass_kg: q, .. }) => {
            same(*p, *q)
        }
        (
            Hypothesis::StiffnessChange {
                region: r,
                youngs_factor: p,
            },
            Hypothesis::StiffnessChange {
                region: s,
                youngs_factor: q,
            },
        ) => {
            let ((w, h), (v, g)) = (dims(r), dims(s));
            same(*p, *q) && same(w, v) && same(h, g)
        }
        (
            Hypothesis::BoundaryCompliance {
                stiffness_per_length: p,
                was_pinned: i,
                ..
            },
            Hypothesis::BoundaryCompliance {
                stiffness_per_length: q,
                was_pinned: j,
                ..
            },
        ) => i == j && same(*p, *q),
        _ => false,
    }
}

/// The winner among `all` by their `measures`, how far each falls behind it, and each one's
/// score (higher is better).
/// - A loss: the best quadrature correlation (no two losses count as one change here).
/// - A mass or stiffness change: first the change with the least misfit, modes alone, against
///   rivals of another size (their couplings differ in strength, which the shapes show whatever
///   the model form); then, among that change's mirror images, the least misfit with strongly
///   mixed modes as one ([`MIXING_SPACING_PER_SHIFT`]).
fn choose(all: &[Hypothesis], measures: &[ShapeMisfit]) -> (usize, Vec<f64>, Vec<f64>) {
    let n = all.len();
    let least = |keep: &dyn Fn(usize) -> bool, by: &dyn Fn(usize) -> f64| {
        (0..n)
            .filter(|&k| keep(k))
            .min_by(|&a, &b| by(a).total_cmp(&by(b)))
            .expect("the kept are not empty")
    };
    let alone = |k: usize| measures[k].modes_alone;
    let mixed = |k: usize| measures[k].mixed_as_one;
    let change = least(&|_| true, &alone);
    let imaged = |k: usize| k == change || same_change(&all[k], &all[change]);
    // Exact ties (the images of a symmetric set) go to the better misfit modes alone.
    let top = least(&imaged, &|k| mixed(k) + 1e-9 * alone(k));
    let misfit = |k: usize| if imaged(k) { mixed(k) } else { alone(k) };
    let deficit = (0..n)
        .map(|k| {
            if imaged(k) {
                mixed(k) - mixed(top)
            } else {
                alone(k) - alone(change)
            }
        })
        .collect();
    (top, deficit, (0..n).map(|k| -misfit(k)).collect())
}

/// The largest change of ln f that `prediction` makes on any pair.
fn largest_shift(prediction: &Prediction) -> f64 {
    prediction
        .log_frequency
        .iter()
        .fold(0.0, |m: f64, a| m.max(a.abs()))
}

/// The outcome of [`resolve_images`].
#[derive(Clone, Debug)]
pub struct Resolved {
    /// The place that fits the shapes best.
    pub hypothesis: Hypothesis,
    /// For a loss: the sizes at the winner's place that the shapes could not rule out (the
    /// winner first), each with its quadrature correlation, for the re-solved damping to
    /// choose among; empty otherwise.
    pub sizes: Vec<(Hypothesis, f64)>,
    /// The others that could not be ruled out (empty when settled).
    pub images: Vec<Hypothesis>,
    /// Score per candidate, in the order (candidate, its images…, its alternatives…):
    /// quadrature correlation for a loss (higher is better), shape misfit for a mass or
    /// stiffness (lower is better).
    pub scores: Vec<f64>,
    /// Whether the winner beat every candidate at another place (less than half of the
    /// smaller in the other) by the kind's margin.
    pub settled: bool,
}

/// Where a candidate sits, for telling images apart: its region, or a small square around its
/// point.
fn place(h: &Hypothesis) -> Option<super::regions::Region> {
    h.region().or(match h {
        Hypothesis::AddedMass { x_m, y_m, .. } => Some(super::regions::Region {
            x: [x_m - 0.05, x_m + 0.05],
            y: [y_m - 0.05, y_m + 0.05],
        }),
        _ => None,
    })
}

/// The candidate's image or alternative (itself included) that the shapes support, against
/// `base` (the view the candidate was scored on; `evidence` gathered against it). For a loss
/// the alternatives (other sizes the damping could not tell apart) compete too.
pub fn resolve_images(
    measured: &[Mode],
    evidence: &Evidence,
    base: &ModelView,
    sensors: &[SensorPosition],
    candidate: &Candidate,
) -> Result<Resolved, SimError> {
    let loss = matches!(
        candidate.hypothesis,
        Hypothesis::LocalizedDamping { .. } | Hypothesis::ViscoelasticDamping { .. }
    );
    let mut all: Vec<Hypothesis> = std::iter::once(candidate.hypothesis.clone())
        .chain(candidate.images.iter().cloned())
        .collect();
    if loss {
        all.extend(candidate.alternatives.iter().cloned());
    }
    if all.len() == 1 {
        return Ok(Resolved {
            hypothesis: all[0].clone(),
            sizes: Vec::new(),
            images: Vec::new(),
            scores: Vec::new(),
            settled: true,
        });
    }
    let mixing_window_rel = MIXING_SPACING_PER_SHIFT * largest_shift(&candidate.prediction);
    let measures = parallel_map(all.iter().collect(), |h: &Hypothesis| {
        // A loss is placed by its loss alone: a viscoelastic layer's mass would make every
        // candidate a full re-solve (16 of them: 40 s of a 58 s diagnosis), and where the
        // quadrature parts point does not depend on it.
        let placing = match h {
            Hypothesis::ViscoelasticDamping { .. } if loss => h.with_density_factor(1.0),
            _ => h.clone(),
        };
        let h = &placing;
        let model = h.apply(&base.model);
        if loss {
            let q = quadrature_match(measured, evidence, &view_of(base, &model, h)?, sensors)?;
            Ok(ShapeMisfit {
                modes_alone: -q,
                mixed_as_one: -q,
            })
        } else {
            let m = (base.fmax_hz, mixing_window_rel);
            shape_misfit(measured, &model, sensors, m)
        }
    })?;
    // Higher is better in `scores`; `deficit` is how far each falls behind the winner.
    let (top, deficit, mut scores) = choose(&all, &measures);
    let margin = if loss {
        MIN_QUADRATURE_MARGIN
    } else {
        MIN_SHAPE_MISFIT_MARGIN
    };
    // The shapes choose the place; among sizes at that place (half of the smaller in the
    // other) they cannot choose (±1 cell scored 0.73–0.76 on a g = 50 % patch; a layer
    // twice as wide with half the loss scored above the true one), so those the shapes do
    // not rule out are handed on as `sizes`, for the re-solved damping to settle.
    let top_place = place(&all[top]);
    let same_place = |k: usize| match (&top_place, place(&all[k])) {
        (Some(a), Some(b)) => a.containment(&b) >= 0.5,
        _ => k == top,
    };
    let within = |k: usize| deficit[k] < margin;
    let sizes: Vec<usize> = (0..all.len())
        .filter(|&k| same_place(k) && within(k))
        .collect();
    // Of rectangles of one width and height (a size and its mirror image both at the place,
    // overlapping) only the shapes' favourite is handed on: the damping cannot tell them
    // apart, and each costs its re-solves.
    let dims = |k: usize| place(&all[k]).map(|r| (r.x[1] - r.x[0], r.y[1] - r.y[0]));
    let same_dims = |a: usize, b: usize| match (dims(a), dims(b)) {
        (Some(p), Some(q)) => (p.0 - q.0).abs() < 1e-9 && (p.1 - q.1).abs() < 1e-9,
        _ => false,
    };
    let mut sizes: Vec<usize> = sizes
        .iter()
        .copied()
        .filter(|&k| {
            !sizes
                .iter()
                .any(|&j| j != k && same_dims(j, k) && (scores[j], k) > (scores[k], j))
        })
        .collect();
    // The first in the candidate's order stands in for them all; the shapes' favourites are
    // handed on, at most MAX_SIZES (each costs four re-solves).
    let best = sizes.first().copied().unwrap_or(top);
    sizes.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]));
    sizes.truncate(MAX_SIZES);
    let rivals: Vec<usize> = (0..all.len())
        .filter(|&k| !same_place(k) && within(k))
        .collect();
    if !loss {
        scores.iter_mut().for_each(|s| *s = -*s);
    }
    Ok(Resolved {
        hypothesis: all[best].clone(),
        sizes: if loss {
            sizes.iter().map(|&k| (all[k].clone(), scores[k])).collect()
        } else {
            Vec::new()
        },
        settled: rivals.is_empty(),
        images: rivals.iter().map(|&k| all[k].clone()).collect(),
        scores,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mass(x_m: f64, y_m: f64, mass_kg: f64) -> Hypothesis {
        Hypothesis::AddedMass { x_m, y_m, mass_kg }
    }

    fn misfit(modes_alone: f64, mixed_as_one: f64) -> ShapeMisfit {
        ShapeMisfit {
            modes_alone,
            mixed_as_one,
        }
    }

    /// The misfits measured on the two cases that set the rule. Mirror images (one size) go by
    /// the misfit with mixed modes as one: the true place (0.821 modes alone, 0.125 mixed) beats
    /// the image that one close pair favoured (0.668, 0.213).
    #[test]
    fn mirror_images_are_chosen_with_mixed_modes_as_one() {
        let all = [mass(1.612, 1.04, 3.48), mass(0.388, 1.04, 3.48)];
        let (top, deficit, scores) = choose(&all, &[misfit(0.668, 0.213), misfit(0.821, 0.125)]);
        assert_eq!(top, 1);
        assert!((deficit[0] - 0.088).abs() < 1e-12, "{deficit:?}");
        assert_eq!(scores, vec![-0.213, -0.125]);
    }

    /// Rivals of another size go by the misfit modes alone: a 47 kg mass at a pinned edge and
    /// its image (0.356 alone, 0.049 mixed) lose to 2.2 kg 0.1 m in (0.139, 0.078), as the
    /// shapes showed before any mixing was set aside.
    #[test]
    fn a_rival_of_another_size_is_compared_mode_by_mode() {
        let all = [
            mass(0.525, 0.025, 47.4),
            mass(0.475, 0.025, 47.4),
            mass(0.47, 0.12, 2.2),
        ];
        let measures = [
            misfit(0.356, 0.049),
            misfit(0.356, 0.049),
            misfit(0.139, 0.078),
        ];
        let (top, deficit, _) = choose(&all, &measures);
        assert_eq!(top, 2);
        assert!(deficit[0] > MIN_SHAPE_MISFIT_MARGIN, "{deficit:?}");
        assert!(same_change(&all[0], &all[1]) && !same_change(&all[0], &all[2]));
    }
}

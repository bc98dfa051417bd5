//! A finding's size re-fitted through the re-solved model. The scans use first-order
//! sensitivities (a mass's −½mφ², a region's ½FΔg), which under-estimate effects large enough
//! to change the mode shapes (a 2 kg mass, a g = 50 % patch). One Gauss–Newton step: the model
//! with the finding is solved again, its remaining misfit on the same pairs is projected on the
//! first-order sensitivity, and the size moves by that much (within its physical bounds).

use super::evidence::{Evidence, ModelView};
use super::hypothesis::{sls_with_peak, Hypothesis};
use super::score::{Candidate, Prediction, Scorer};
use crate::modal::Mode;
use crate::sim::error::SimError;
use crate::sim::model::{Model, SensorPosition};

/// The size a refinement moves, and its bounds.
impl Hypothesis {
    /// The size the refinement moves (mass, stiffness factor − 1, Δg, peak loss); `None` for
    /// kinds fitted exactly by their scan (the edge spring, the damping law).
    pub fn amplitude(&self) -> Option<f64> {
        match self {
            Hypothesis::AddedMass { mass_kg, .. } => Some(*mass_kg),
            Hypothesis::StiffnessChange { youngs_factor, .. } => Some(youngs_factor - 1.0),
            Hypothesis::LocalizedDamping { delta_g, .. } => Some(*delta_g),
            Hypothesis::ViscoelasticDamping { peak_loss, .. } => Some(*peak_loss),
            _ => None,
        }
    }

    /// The same change with another size, clamped to what is physical.
    pub fn with_amplitude(&self, a: f64) -> Hypothesis {
        let mut h = self.clone();
        match &mut h {
            Hypothesis::AddedMass { mass_kg, .. } => *mass_kg = a.max(0.0),
            Hypothesis::StiffnessChange { youngs_factor, .. } => {
                let (lo, hi) = super::stiffness::STIFFNESS_FACTOR_RANGE;
                *youngs_factor = 1.0 + a.clamp(lo, hi);
            }
            Hypothesis::LocalizedDamping { delta_g, .. } => {
                *delta_g = a.clamp(0.0, super::damping::MAX_REGION_DELTA_G)
            }
            Hypothesis::ViscoelasticDamping {
                sls,
                peak_loss,
                peak_hz,
                ..
            } => {
                *peak_loss = a.clamp(0.0, super::viscoelastic::MAX_PEAK_LOSS);
                *sls = sls_with_peak(sls.e_inf, *peak_loss, *peak_hz);
            }
            _ => {}
        }
        h
    }
}

/// Whether `h` applied to `model` leaves its undamped modes alone (a viscoelastic region
/// without added mass whose relaxed modulus is the plate's counts as such).
pub fn changes_loss_only(model: &Model, h: &Hypothesis) -> bool {
    match h {
        Hypothesis::ViscoelasticDamping {
            sls,
            density_factor,
            ..
        } => *density_factor == 1.0 && sls.e_inf == model.material.youngs_modulus,
        other => other.is_loss_only(),
    }
}

/// A view of `model`, which is `base`'s model with `h` applied: the undamped modes are reused
/// when `h` changes the loss only (a viscoelastic region without added mass whose relaxed
/// modulus is the plate's counts as such), else solved again.
pub fn view_of(base: &ModelView, model: &Model, h: &Hypothesis) -> Result<ModelView, SimError> {
    if changes_loss_only(&base.model, h) {
        base.with_loss_change(model)
    } else {
        ModelView::new(model, base.fmax_hz)
    }
}

/// `candidate` (scored by `scorer` against `base`) with its size refined through the re-solved
/// model: up to [`REFINE_SOLVES`] solves, secant steps along the first-order sensitivity.
pub fn refine(
    measured: &[Mode],
    sensors: &[SensorPosition],
    base: &ModelView,
    scorer: &Scorer,
    candidate: &Candidate,
) -> Result<Hypothesis, SimError> {
    let h = &candidate.hypothesis;
    let Some(amp) = h.amplitude().filter(|a| *a != 0.0) else {
        return Ok(h.clone());
    };
    let n = scorer.n();
    let unit_a: Vec<f64> = candidate
        .prediction
        .log_frequency
        .iter()
        .map(|v| v / amp)
        .collect();
    let unit_b: Vec<f64> = candidate
        .prediction
        .damping
        .iter()
        .map(|v| v / amp)
        .collect();
    let sigma2 = (scorer.rss_frequency(&candidate.prediction.log_frequency) / n as f64).max(1e-300);
    let w = &scorer.damping_weight;
    // The size change the misfit left by `h` (solved) asks for, to first order.
    let step = |h: &Hypothesis| -> Result<Option<f64>, SimError> {
        let after = evidence_with(measured, sensors, base, h)?;
        let (mut y, mut r, mut sa, mut sb) =
            (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for (k, p) in scorer.pairs.iter().enumerate() {
            if let Some(q) = after.pairs.iter().find(|q| q.measured == p.measured) {
                y[k] = q.frequency_rel.ln_1p();
                r[k] = q.damping_diff;
                sa[k] = unit_a[k];
                sb[k] = unit_b[k];
            }
        }
        let (py, pa) = (scorer.nuisance.residual(&y), scorer.nuisance.residual(&sa));
        let mut num: f64 = (0..n).map(|k| pa[k] * py[k]).sum::<f64>() / sigma2;
        let mut den: f64 = (0..n).map(|k| pa[k] * pa[k]).sum::<f64>() / sigma2;
        num += (0..n).map(|k| w[k] * w[k] * sb[k] * r[k]).sum::<f64>();
        den += (0..n).map(|k| w[k] * w[k] * sb[k] * sb[k]).sum::<f64>();
        Ok((den > 0.0 && num.is_finite()).then(|| num / den))
    };
    // Secant iteration on the size: the first-order sensitivity gives the direction, the
    // re-solved model how far (a g = 50 % patch's damping is not linear in g).
    let (mut a0, mut g0) = (
        amp,
        match step(h)? {
            Some(g) => g,
            None => return Ok(h.clone()),
        },
    );
    let mut current = h.with_amplitude(a0 + g0);
    for _ in 1..REFINE_SOLVES {
        let a1 = current.amplitude().unwrap_or(a0);
        if (a1 - a0).abs() <= REFINE_TOLERANCE * a0.abs().max(1e-12) {
            break;
        }
        let Some(g1) = step(&current)? else { break };
        if g1.abs() <= REFINE_TOLERANCE * a1.abs().max(1e-12) || g1 == g0 {
            break;
        }
        let next = a1 - g1 * (a1 - a0) / (g1 - g0);
        (a0, g0) = (a1, g1);
        current = h.with_amplitude(next);
    }
    Ok(current)
}

/// The score ([`Scorer::bic`]) of `h` through the re-solved model rather than its
/// first-order prediction: what `h` explains of each pair is the evidence before less the
/// evidence after applying it (a pair the solved model loses explains nothing). `params` and
/// `locations` as the candidate's. Used to choose among sizes of a lossy region, whose
/// first-order damping trades the region's area for its loss.
pub fn solved_bic(
    measured: &[Mode],
    sensors: &[SensorPosition],
    base: &ModelView,
    scorer: &Scorer,
    h: &Hypothesis,
    params: f64,
    locations: f64,
) -> Result<f64, SimError> {
    let after = evidence_with(measured, sensors, base, h)?;
    Ok(bic_of_update(scorer, &after, params, locations))
}

/// `measured` against `base`'s model with `h` applied (solved again unless `h` changes the loss
/// only).
fn evidence_with(
    measured: &[Mode],
    sensors: &[SensorPosition],
    base: &ModelView,
    h: &Hypothesis,
) -> Result<Evidence, SimError> {
    let model = h.apply(&base.model);
    let view = view_of(base, &model, h)?;
    Ok(Evidence::gather(measured, view.poles_at(sensors)?))
}

/// [`solved_bic`] of an update whose evidence (the model with the change, against the same
/// measured modes) is `after`.
pub fn bic_of_update(scorer: &Scorer, after: &Evidence, params: f64, locations: f64) -> f64 {
    let mut explained = Prediction::none(scorer.n());
    for (k, effect) in effect_on_pairs(scorer, after).into_iter().enumerate() {
        if let Some((a, b)) = effect {
            explained.log_frequency[k] = a;
            explained.damping[k] = b;
        }
    }
    scorer.bic(&explained, params, locations)
}

/// What `h` does to each of `scorer`'s pairs through the re-solved model: the evidence before
/// (ln f ratio, ΔD) less the evidence after applying it; `None` for a pair the solved model
/// no longer pairs.
fn solved_effect(
    measured: &[Mode],
    sensors: &[SensorPosition],
    base: &ModelView,
    scorer: &Scorer,
    h: &Hypothesis,
) -> Result<Vec<Option<(f64, f64)>>, SimError> {
    let after = evidence_with(measured, sensors, base, h)?;
    Ok(effect_on_pairs(scorer, &after))
}

/// The evidence of `scorer`'s pairs less the evidence `after` an update, per pair; `None` for a
/// pair `after` no longer pairs.
fn effect_on_pairs(scorer: &Scorer, after: &Evidence) -> Vec<Option<(f64, f64)>> {
    scorer
        .pairs
        .iter()
        .enumerate()
        .map(|(k, p)| {
            after
                .pairs
                .iter()
                .find(|q| q.measured == p.measured)
                .map(|q| {
                    (
                        scorer.log_frequency[k] - q.frequency_rel.ln_1p(),
                        scorer.damping[k] - q.damping_diff,
                    )
                })
        })
        .collect()
}

/// Most re-solves of one refinement.
pub const REFINE_SOLVES: usize = 3;
/// A refinement stops when the size moves by less than this fraction.
pub const REFINE_TOLERANCE: f64 = 0.01;

/// Which place of `c` (the candidate or one of its images) lies nearest to `h`'s: a re-scan
/// must not jump to a mirror image that was ruled out already.
fn nearest_place(c: &Candidate, h: &Hypothesis) -> Hypothesis {
    let place = |x: &Hypothesis| -> (f64, f64) {
        match x {
            Hypothesis::AddedMass { x_m, y_m, .. } => (*x_m, *y_m),
            other => other.region().map_or((0.0, 0.0), |r| r.centre()),
        }
    };
    let at = place(h);
    std::iter::once(&c.hypothesis)
        .chain(&c.images)
        .min_by(|a, b| {
            let (pa, pb) = (place(a), place(b));
            ((pa.0 - at.0).hypot(pa.1 - at.1)).total_cmp(&(pb.0 - at.0).hypot(pb.1 - at.1))
        })
        .cloned()
        .unwrap_or_else(|| c.hypothesis.clone())
}

/// Place and size refitted together: the scans are linear in the size at the model's own
/// sensitivities, and an effect large enough to bend the modes (a region 40 % softer) is then
/// placed too large and too weak. Each pass solves the model with the current finding, takes
/// the part of its effect the first-order prediction missed out of the evidence, scans the
/// family again (`rescan`, on the corrected evidence) and refines the size through the
/// re-solved model — a fixed-point iteration of the nonlinear fit, [`REFIT_PASSES`] times.
/// Returns the finding and the candidate whose prediction is its first-order sensitivity.
pub fn refit(
    measured: &[Mode],
    sensors: &[SensorPosition],
    base: &ModelView,
    scorer: &Scorer,
    start: (Hypothesis, Candidate),
    rescan: &dyn Fn(&Scorer) -> Result<Option<Candidate>, SimError>,
) -> Result<(Hypothesis, Candidate), SimError> {
    let (mut h, mut cand) = start;
    for _ in 0..REFIT_PASSES {
        let (Some(amp), Some(scan_amp)) = (h.amplitude(), cand.hypothesis.amplitude()) else {
            break;
        };
        if scan_amp == 0.0 {
            break;
        }
        let scale = amp / scan_amp;
        let mut corrected = scorer.clone();
        let effects = solved_effect(measured, sensors, base, scorer, &h)?;
        for (k, effect) in effects.into_iter().enumerate() {
            // The nonlinear part = the exact effect − the linear one.
            let Some((exact_a, exact_b)) = effect else {
                continue;
            };
            corrected.log_frequency[k] -= exact_a - scale * cand.prediction.log_frequency[k];
            corrected.damping[k] -= exact_b - scale * cand.prediction.damping[k];
        }
        let Some(next) = rescan(&corrected)? else {
            break;
        };
        let mut c = next.clone();
        c.hypothesis = nearest_place(&next, &h);
        c.images.clear();
        h = refine(measured, sensors, base, scorer, &c)?;
        cand = c;
    }
    Ok((h, cand))
}

/// Passes of [`refit`].
pub const REFIT_PASSES: usize = 2;

/// A kept finding `h` resized on later evidence: its first-order sensitivity (the prediction
/// of `scanned`, made on `from`'s pairs) scaled by the size change δ that scores best on
/// `scorer` (golden section over δ within ± the current size), one parameter at no new place.
/// A later finding must beat this as well as "no change": what the first finding's size left
/// over is not new physics (a viscoelastic layer's loss found 20 % too high otherwise reads as
/// a soft edge, which lowers damping). `None` for kinds without a size.
pub fn resize_candidate(
    h: &Hypothesis,
    scanned: &Candidate,
    from: &Scorer,
    scorer: &Scorer,
) -> Option<Candidate> {
    let amp = h.amplitude().filter(|a| *a != 0.0)?;
    let scan_amp = scanned.hypothesis.amplitude().filter(|a| *a != 0.0)?;
    let unit = scanned.prediction.realigned(from, scorer, 1.0 / scan_amp);
    let at = |d: f64| -> (f64, super::score::Prediction) {
        let p = super::score::Prediction {
            log_frequency: unit.log_frequency.iter().map(|v| v * d).collect(),
            damping: unit.damping.iter().map(|v| v * d).collect(),
        };
        (scorer.bic(&p, 1.0, 1.0), p)
    };
    let (mut a, mut b) = (-amp.abs(), amp.abs());
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..40 {
        let (c, d) = (b - phi * (b - a), a + phi * (b - a));
        if at(c).0 < at(d).0 {
            b = d;
        } else {
            a = c;
        }
    }
    let delta = 0.5 * (a + b);
    let (_, prediction) = at(delta);
    Some(scorer.candidate(h.with_amplitude(amp + delta), prediction, 1.0, 1.0))
}

//! One round's candidates: every family's best explanation against a view of the model, and
//! the settling of the chosen one's size among what its scan could not tell apart. Called by
//! [`super::procedure`] once per round.

use super::evidence::ModelView;
use super::hypothesis::Hypothesis;
use super::procedure::MIN_BIC_GAIN;
use super::refine::{self, refine};
use super::regions::ModeShares;
use super::score::{Candidate, Prediction, Scorer};
use super::workers::parallel_map;
use super::{boundary, damping, mass, stiffness, viscoelastic};
use crate::modal::Mode;
use crate::sim::error::SimError;
use crate::sim::model::SensorPosition;

/// Whether a kind may still be found after `found` (one loss explanation at a time; no kind
/// twice).
pub(super) fn allowed(kind: &str, found: &[Hypothesis]) -> bool {
    let loss = |k: &str| {
        matches!(
            k,
            "localized_damping" | "viscoelastic_damping" | "damping_law"
        )
    };
    found
        .iter()
        .all(|h| h.kind() != kind && !(loss(h.kind()) && loss(kind)))
}

/// Every family's best candidate against `view`.
pub(super) fn candidates(
    measured: &[Mode],
    scorer: &Scorer,
    view: &ModelView,
    sensors: &[SensorPosition],
    found: &[Hypothesis],
    edges: &mut boundary::EdgeCache,
    shares: &ModeShares,
) -> Result<Vec<Candidate>, SimError> {
    let mut out = Vec::new();
    if allowed("added_mass", found) {
        out.extend(mass::scan_point_mass(scorer, view)?);
    }
    if allowed("stiffness_change", found) {
        out.push(stiffness::scan_stiffness(scorer, shares));
    }
    if allowed("localized_damping", found) {
        out.push(damping::scan_localized_damping(scorer, shares));
    }
    if allowed("viscoelastic_damping", found) {
        out.push(viscoelastic::scan_viscoelastic(
            scorer,
            shares,
            view.model.material.youngs_modulus,
        ));
    }
    if allowed("damping_law", found) {
        out.extend(damping::fit_damping_laws(scorer, view)?);
    }
    if allowed("boundary_compliance", found) {
        out.extend(boundary::scan_boundary(
            measured, scorer, view, sensors, edges,
        )?);
    }
    Ok(out)
}

/// The family of `h` scanned again on `scorer` (for [`refine::refit`]); `None` for the kinds
/// their scan fits exactly.
pub(super) fn rescan(
    h: &Hypothesis,
    scorer: &Scorer,
    view: &ModelView,
    shares: &ModeShares,
) -> Result<Option<Candidate>, SimError> {
    Ok(match h {
        Hypothesis::AddedMass { .. } => mass::scan_point_mass(scorer, view)?,
        Hypothesis::StiffnessChange { .. } => Some(stiffness::scan_stiffness(scorer, shares)),
        Hypothesis::LocalizedDamping { .. } => {
            Some(damping::scan_localized_damping(scorer, shares))
        }
        Hypothesis::ViscoelasticDamping { .. } => Some(viscoelastic::scan_viscoelastic(
            scorer,
            shares,
            view.model.material.youngs_modulus,
        )),
        _ => None,
    })
}

/// The first-order prediction of `h` on `scorer`'s pairs (for a place the shapes chose among
/// a candidate's images and alternatives); `None` for kinds whose candidate already holds it.
pub(super) fn first_order(
    h: &Hypothesis,
    scorer: &Scorer,
    view: &ModelView,
    shares: &ModeShares,
) -> Result<Option<Prediction>, SimError> {
    Ok(match h {
        Hypothesis::AddedMass { .. } => Some(mass::predict(h, scorer, view)?),
        Hypothesis::StiffnessChange { .. } => Some(stiffness::predict(h, scorer, shares)),
        Hypothesis::LocalizedDamping { .. } => Some(damping::predict(h, scorer, shares)),
        Hypothesis::ViscoelasticDamping { .. } => Some(viscoelastic::predict(h, scorer, shares)),
        _ => None,
    })
}

/// The candidate `best` moved to the place the shapes chose (`chosen`), and its size refined
/// through the re-solved model. When the shapes left several sizes of a lossy region
/// (`sizes`, each with its quadrature correlation), each is refined and scored through its
/// re-solved model: the first-order damping trades area for loss, the solved one less so (a
/// g = 50 % patch: the true rectangle by 14 in BIC over ±1 cell). Sizes within
/// [`SIZE_BIC_TIE`] of the best are not told apart by the damping (a viscoelastic layer and
/// one twice as wide with half the loss: 1.1); among them the shapes' favourite is kept, and
/// the others (refined) are returned, best shape first, to be reported.
pub(super) fn settle_size(
    modes: &[Mode],
    sensors: &[SensorPosition],
    view: &ModelView,
    (scorer, shares): (&Scorer, &ModeShares),
    best: &Candidate,
    sizes: &[(Hypothesis, f64)],
    chosen: &Hypothesis,
) -> Result<(Candidate, Hypothesis, Vec<Hypothesis>), SimError> {
    let at = |h: &Hypothesis| -> Result<Candidate, SimError> {
        let mut c = best.clone();
        c.hypothesis = h.clone();
        c.prediction = first_order(h, scorer, view, shares)?.unwrap_or(c.prediction);
        Ok(c)
    };
    if sizes.len() < 2 {
        let c = at(chosen)?;
        let refined = refine(modes, sensors, view, scorer, &c)?;
        return Ok((c, refined, Vec::new()));
    }
    // Sizes are ranked by their loss alone (a layer's mass would make every refinement a full
    // re-solve: 72 s instead of 45 for a diagnosis); the kept one is refined with its mass.
    let settled = parallel_map(sizes.iter().collect(), |(h, shape_score)| {
        let c = at(&h.with_density_factor(1.0))?;
        let refined = refine(modes, sensors, view, scorer, &c)?;
        let bic = refine::solved_bic(
            modes,
            sensors,
            view,
            scorer,
            &refined,
            c.params,
            c.locations,
        )?;
        let sized = refined
            .amplitude()
            .map_or(h.clone(), |a| h.with_amplitude(a));
        Ok((sized, bic, *shape_score))
    })?;
    let least = settled.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
    let mut tied: Vec<_> = settled
        .into_iter()
        .filter(|s| s.1 - least < SIZE_BIC_TIE)
        .collect();
    tied.sort_by(|a, b| b.2.total_cmp(&a.2));
    let mut tied = tied.into_iter().map(|t| t.0);
    let kept = tied.next().expect("the least BIC is among the sizes");
    let c = at(&kept)?;
    let refined = refine(modes, sensors, view, scorer, &c)?;
    Ok((c, refined, tied.collect()))
}

/// Sizes of a lossy region whose re-solved BICs differ by less than this are a tie for the
/// damping — the evidence a finding itself must show ([`MIN_BIC_GAIN`], "strong") — and the
/// shapes decide; the other tied sizes are reported with the finding, with their loss. (On
/// FE recordings of a g = 50 % patch the solved damping preferred a rectangle two cells
/// narrower by 4, on Kirchhoff recordings the true one by 14: below "strong" it is noise.)
pub const SIZE_BIC_TIE: f64 = MIN_BIC_GAIN;

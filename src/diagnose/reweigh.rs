//! A kept finding's size weighed again against the model that has another finding too.
//!
//! The diagnosis finds its changes one after the other: the first is sized against the model
//! without the second, where it may have absorbed part of the second's effect (a damped patch
//! sized without the mass that reshapes its modes; a mass sized without the patch that raises
//! the damped frequencies). [`reweigh_first`] refits the first change's size through the
//! re-solved model that has the second, the scorer calibrated there.

use super::evidence::{Evidence, ModelView};
use super::hypothesis::Hypothesis;
use super::nuisance::model_form_patterns;
use super::refine::{refine, view_of};
use super::score::{Candidate, Scorer};
use crate::modal::Mode;
use crate::sim::error::SimError;
use crate::sim::model::{Model, SensorPosition};

/// A first finding as the procedure keeps it: the refined change, the scan's candidate it came
/// from (its prediction is the first-order sensitivity) and the scorer of the round it was
/// found in.
pub struct FirstFinding<'a> {
    /// The change as refined and applied.
    pub hypothesis: &'a Hypothesis,
    /// The scan's candidate it came from.
    pub candidate: &'a Candidate,
    /// The scorer of its round.
    pub scorer: &'a Scorer,
}

/// `first`'s size refitted against `model` (the model without any finding) with `second`
/// applied; also that model's view and the recordings' evidence against it. `base` is the view of `model`, `original` the recordings'
/// evidence against it without its patches' own losses (for the damping's model form,
/// [`Scorer::with_damping_form_of`]).
/// `None` when `first` has no size to refit or too few pairs remain to score; a size of 0
/// means the first finding explains nothing beside the second.
pub fn reweigh_first(
    modes: &[Mode],
    sensors: &[SensorPosition],
    (base, model, original): (&ModelView, &Model, &Evidence),
    first: &FirstFinding<'_>,
    second: &Hypothesis,
    model_form_sigma: f64,
) -> Result<Option<(Hypothesis, ModelView, Evidence)>, SimError> {
    let Some(amp) = first.hypothesis.amplitude() else {
        return Ok(None);
    };
    let with_second = second.apply(model);
    let base2 = view_of(base, &with_second, second)?;
    let ev2 = Evidence::gather(modes, base2.poles_at(sensors)?);
    let patterns = model_form_patterns(&base2, sensors, &ev2, model_form_sigma)?;
    let Some(scorer2) = Scorer::new(modes, &ev2, &base2, &patterns, model_form_sigma)
        .map(|s| s.with_damping_form_of(original))
    else {
        return Ok(None);
    };
    let scan_amp = first.candidate.hypothesis.amplitude().unwrap_or(amp);
    let mut c = first.candidate.clone();
    let scale = if scan_amp != 0.0 { amp / scan_amp } else { 1.0 };
    c.prediction = c.prediction.realigned(first.scorer, &scorer2, scale);
    c.hypothesis = first.hypothesis.clone();
    let reweighed = refine(modes, sensors, &base2, &scorer2, &c)?;
    Ok(Some((reweighed, base2, ev2)))
}

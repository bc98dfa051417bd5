//! The diagnosis as one procedure. Identify the recordings' modes; pair them with the model's;
//! score every family's best explanation ([`super::score`]); keep the best if it beats "no
//! change" by [`MIN_BIC_GAIN`]; settle its mirror images by the shapes, refine its size
//! through the re-solved model, apply it, and search again against the updated model (up to
//! [`MAX_FINDINGS`]). The first finding is then weighed again against the model that has the
//! second. The fit is measured before and after; the noise floor is reported apart.

use super::boundary;
use super::candidates::{candidates, rescan, settle_size};
use super::evidence::{Evidence, ModelView};
use super::fit::{compare_frfs, measures, FitBeforeAfter};
use super::fit_compare::fits_worse;
use super::hypothesis::Hypothesis;
use super::mass::place_between_grid_points;
use super::mirror::resolve_images;
use super::noise::{channel_snr_db, median_snr_db, REPORT_BELOW_SNR_DB};
use super::nuisance::model_form_patterns;
use super::refine::{self, bic_of_update, view_of};
use super::regions::ModeShares;
use super::report::{
    Diagnosis, FamilyScore, Finding, RunnerUp, REJECTED_FITS_WORSE, REJECTED_KEPT_KIND_EXPLAINS,
    REJECTED_NOT_BORNE_OUT, REJECTED_NO_SIZE,
};
use super::reweigh::{reweigh_first, FirstFinding};
use super::score::{Candidate, Prediction, Scorer, DEFAULT_MODEL_FORM_SIGMA};
use crate::modal::{identify, ModalError, ModalSettings, Recordings};
use crate::sim::error::SimError;
use crate::sim::model::{Model, SensorPosition};

/// Default highest frequency of the modes compared, Hz (about 15 modes of the reference plate:
/// enough to place a region; the frequency evidence needs fewer).
pub const DEFAULT_DIAGNOSE_FMAX_HZ: f64 = 160.0;
/// Default lowest frequency, Hz.
pub const DEFAULT_DIAGNOSE_FMIN_HZ: f64 = 0.5;
/// The model's modes are solved to this multiple of the range (a stiffer structure's modes near
/// the limit still find their partner).
pub const MODEL_RANGE_FACTOR: f64 = 1.3;
/// A finding must beat "no change" by this much BIC: "strong" evidence on Kass and Raftery's
/// scale of 2 ln(Bayes factor) (6–10), on top of the price of its parameters and of the
/// locations searched; not a value fitted to any test case.
pub const MIN_BIC_GAIN: f64 = 6.0;
/// Most findings of missing physics in one diagnosis.
pub const MAX_FINDINGS: usize = 2;
/// Least pairs to diagnose at all.
pub const MIN_PAIRS: usize = 4;

/// Settings of [`diagnose`].
#[derive(Clone, Debug)]
pub struct DiagnoseSettings {
    /// Modes from `fmin_hz` to `fmax_hz` are identified and compared.
    pub fmin_hz: f64,
    /// See `fmin_hz`.
    pub fmax_hz: f64,
    /// Where the recordings were excited (x, y in m: a recording set's `excitation.csv`), for
    /// the FRF error; `None`: the model's excitation.
    pub excitation_m: Option<(f64, f64)>,
    /// How far a correct model's ln f may differ from the structure's, mode by mode, beyond
    /// the calibrated offset and trends (see [`super::score`]).
    pub model_form_sigma: f64,
    /// τ of an exponential window e^(−t/τ) the recordings carry (impact testing; declared by
    /// a recording set's meta.json or its FRF file), s: its decay rate is removed from every
    /// identified pole ([`ModalSettings::exponential_window_tau_s`]), which would otherwise
    /// read as loss the model lacks. The FRF error still compares the responses as recorded
    /// (windowed) with the model's. `None`: no window.
    pub exponential_window_tau_s: Option<f64>,
    /// How many times the recordings must be differentiated to be accelerations, for the FRF
    /// error (0: acceleration, the default; 1: velocity; 2: displacement: a recording set's
    /// [`crate::source::RecordingMeta::derivatives_to_acceleration`]); `None`: they are not
    /// impulse responses of a known quantity (free decays), and no FRF error is computed.
    pub derivatives_to_acceleration: Option<u32>,
}

impl Default for DiagnoseSettings {
    fn default() -> Self {
        Self {
            fmin_hz: DEFAULT_DIAGNOSE_FMIN_HZ,
            fmax_hz: DEFAULT_DIAGNOSE_FMAX_HZ,
            excitation_m: None,
            model_form_sigma: DEFAULT_MODEL_FORM_SIGMA,
            exponential_window_tau_s: None,
            derivatives_to_acceleration: Some(0),
        }
    }
}

/// Why a diagnosis cannot run.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// The recordings cannot be identified.
    #[error("modal identification of the recordings: {0}")]
    Modal(#[from] ModalError),
    /// The model cannot be solved.
    #[error("the model: {0}")]
    Model(#[from] SimError),
    /// A recording set's sensor lies outside the model's plate (the model's mesh would move it
    /// onto the nearest edge: a silent mislabel, or positions in other units).
    #[error("sensor {id} at ({x_m}, {y_m}) m: expected a position on the model's plate, 0..{lx_m} × 0..{ly_m} m (positions in metres, plate coordinates: docs/FORMATS.md §1)")]
    SensorOffPlate {
        /// The sensor's id.
        id: String,
        /// Its position, m.
        x_m: f64,
        /// Its position, m.
        y_m: f64,
        /// The plate's length along x, m.
        lx_m: f64,
        /// The plate's length along y, m.
        ly_m: f64,
    },
    /// Too little evidence.
    #[error("expected at least {expected} modes paired with the model, got {got}")]
    TooFewPairs {
        /// Needed.
        expected: usize,
        /// Found.
        got: usize,
    },
}

/// Diagnoses `rec` (its channels at `sensors`) against `model`.
pub fn diagnose(
    rec: &Recordings,
    sensors: &[SensorPosition],
    model: &Model,
    settings: &DiagnoseSettings,
) -> Result<Diagnosis, DiagnoseError> {
    diagnose_with_progress(rec, sensors, model, settings, &mut |_| {})
}

/// `model` with every patch's own loss factor taken back to the plate's (`None`: no patch has
/// one). A loss change only: the undamped modes stay. Viscoelastic patches are left as they are
/// (their storage modulus depends on frequency: removing them would change the modes).
fn without_patch_losses(model: &Model) -> Option<Model> {
    let lossy = |p: &crate::sim::model::Patch| {
        p.sls.is_none()
            && p.loss_factor
                .is_some_and(|g| g != model.material.loss_factor)
    };
    model.patches.iter().any(lossy).then(|| {
        let mut plain = model.clone();
        for p in plain.patches.iter_mut().filter(|p| lossy(p)) {
            p.loss_factor = None;
        }
        plain
    })
}

/// One kept finding: the refined change, the candidate it came from (its prediction is the
/// sensitivity), and the scorer of its round.
struct Kept {
    hypothesis: Hypothesis,
    candidate: Candidate,
    scorer: Scorer,
    finding: Finding,
}

impl Kept {
    /// This finding with its size refitted to `reweighed`; its evidence, images and
    /// confidence stay those of its round.
    fn resize(&mut self, reweighed: Hypothesis, model: &Model) {
        let old = &self.finding;
        self.finding = Finding {
            images: old.images.clone(),
            confidence: old.confidence,
            bic_gain: old.bic_gain,
            runner_up: old.runner_up.clone(),
            ..Finding::of(&reweighed, &[], model)
        };
        self.hypothesis = reweighed;
    }
}

/// [`diagnose`], telling `progress` what it is doing.
pub fn diagnose_with_progress(
    rec: &Recordings,
    sensors: &[SensorPosition],
    model: &Model,
    settings: &DiagnoseSettings,
    progress: &mut dyn FnMut(&str),
) -> Result<Diagnosis, DiagnoseError> {
    let (lx_m, ly_m) = (model.plate.lx, model.plate.ly);
    let slack_m = 1e-6 * lx_m.max(ly_m);
    let on_plate = |v: f64, l: f64| (-slack_m..=l + slack_m).contains(&v);
    if let Some(s) = sensors
        .iter()
        .find(|s| !(on_plate(s.x_m, lx_m) && on_plate(s.y_m, ly_m)))
    {
        return Err(DiagnoseError::SensorOffPlate {
            id: s.id.clone(),
            x_m: s.x_m,
            y_m: s.y_m,
            lx_m,
            ly_m,
        });
    }
    // Every candidate model shares the mesh: keep its factorisations for the run.
    let _factors = crate::sim::reuse::scope();
    progress("identifying the recordings' modes");
    let modal = ModalSettings {
        exponential_window_tau_s: settings.exponential_window_tau_s,
        ..ModalSettings::new(settings.fmin_hz, settings.fmax_hz)
    };
    let modes = identify(rec, &modal)?.modes;
    progress("solving the model");
    let base = ModelView::new(model, MODEL_RANGE_FACTOR * settings.fmax_hz)?;
    let evidence = Evidence::gather(&modes, base.poles_at(sensors)?);
    if evidence.pairs.len() < MIN_PAIRS {
        return Err(DiagnoseError::TooFewPairs {
            expected: MIN_PAIRS,
            got: evidence.pairs.len(),
        });
    }
    // The damping's model form is that of all the damping regions predict, also of those the
    // model has already (see `with_damping_form_of`).
    let form_reference = match without_patch_losses(model) {
        Some(plain) => Evidence::gather(&modes, base.with_loss_change(&plain)?.poles_at(sensors)?),
        None => evidence.clone(),
    };
    let mut families = Vec::new();
    let mut kept: Vec<Kept> = Vec::new();
    let mut edges = boundary::EdgeCache::default();
    let (mut view, mut ev) = (base.with_loss_change(model)?, evidence.clone());
    for round in 0..MAX_FINDINGS {
        let patterns = model_form_patterns(&view, sensors, &ev, settings.model_form_sigma)?;
        let Some(scorer) = Scorer::new(&modes, &ev, &view, &patterns, settings.model_form_sigma)
            .map(|s| s.with_damping_form_of(&form_reference))
        else {
            break;
        };
        progress(&format!(
            "round {}: scoring every kind of missing physics",
            round + 1
        ));
        let found: Vec<Hypothesis> = kept.iter().map(|k| k.hypothesis.clone()).collect();
        let shares = ModeShares::of(&view)?;
        let cands = candidates(&modes, &scorer, &view, sensors, &found, &mut edges, &shares)?;
        let none = scorer.none_bic();
        for c in &cands {
            families.push(FamilyScore {
                round,
                kind: c.hypothesis.kind().into(),
                bic_gain: none - c.bic,
            });
        }
        // What the kept findings' sizes left over competes with new physics.
        let resize = kept
            .iter()
            .enumerate()
            .filter_map(|(i, k)| {
                refine::resize_candidate(&k.hypothesis, &k.candidate, &k.scorer, &scorer)
                    .map(|c| (i, c))
            })
            .min_by(|a, b| a.1.bic.total_cmp(&b.1.bic));
        // A kept finding a little off its place or size leaves a residual that its own kind,
        // scanned again, explains: a new finding must pay on top of that correction too (found:
        // a mass 0.04 m off its place left a stiffer strip along a free edge, +9.9, where a
        // second mass beside the first explained more).
        // (Scanned only when the round's best beats "no change": most last rounds do not.)
        let best = cands.iter().min_by(|a, b| a.bic.total_cmp(&b.bic)).cloned();
        let corrections = match &best {
            Some(b) if none - b.bic >= MIN_BIC_GAIN => kept
                .iter()
                .map(|k| rescan(&k.hypothesis, &scorer, &view, &shares))
                .collect::<Result<Vec<_>, _>>()?,
            _ => Vec::new(),
        };
        // What `b` adds to the BIC on top of `r`, their first-order predictions summed.
        let gain_on_top = |r: &Candidate, b: &Candidate| {
            let joint = Prediction {
                log_frequency: (0..scorer.n())
                    .map(|k| r.prediction.log_frequency[k] + b.prediction.log_frequency[k])
                    .collect(),
                damping: (0..scorer.n())
                    .map(|k| r.prediction.damping[k] + b.prediction.damping[k])
                    .collect(),
            };
            r.bic - scorer.bic(&joint, r.params + b.params, b.locations)
        };
        // The least `best` adds on top of a kept finding's correction, when below the bar.
        let explained = best.as_ref().and_then(|b| {
            corrections
                .iter()
                .flatten()
                .map(|r| gain_on_top(r, b))
                .filter(|&g| g < MIN_BIC_GAIN)
                .min_by(f64::total_cmp)
        });
        // A new finding must pay against "no change" and, when a kept finding's size could
        // explain what is left, on top of that resized finding too, and on top of every kept
        // finding's correction.
        let pays = best.as_ref().is_some_and(|b| {
            none - b.bic >= MIN_BIC_GAIN
                && resize
                    .as_ref()
                    .is_none_or(|(_, r)| gain_on_top(r, b) >= MIN_BIC_GAIN)
                && explained.is_none()
        });
        if !pays {
            if let (Some(b), Some(gain)) = (&best, explained) {
                if none - b.bic >= MIN_BIC_GAIN {
                    families.push(FamilyScore {
                        round,
                        kind: format!("{}{REJECTED_KEPT_KIND_EXPLAINS}", b.hypothesis.kind()),
                        bic_gain: gain,
                    });
                }
            }
            if let Some((i, r)) = resize.filter(|r| none - r.1.bic >= MIN_BIC_GAIN) {
                progress(&format!(
                    "round {}: resizing the {}",
                    round + 1,
                    r.hypothesis.kind()
                ));
                families.push(FamilyScore {
                    round,
                    kind: format!("{} (resized)", r.hypothesis.kind()),
                    bic_gain: none - r.bic,
                });
                kept[i].resize(r.hypothesis.clone(), model);
                let updated = kept
                    .iter()
                    .fold(model.clone(), |m, k| k.hypothesis.apply(&m));
                view = ModelView::new(&updated, base.fmax_hz)?;
                ev = Evidence::gather(&modes, view.poles_at(sensors)?);
            }
            break;
        }
        let best = best.expect("a paying candidate exists");
        let weights: f64 = std::iter::once(none)
            .chain(cands.iter().map(|c| c.bic))
            .map(|b| (-(b - best.bic) / 2.0).exp())
            .sum();
        let runner_up = cands
            .iter()
            .filter(|c| c.hypothesis.kind() != best.hypothesis.kind())
            .min_by(|a, b| a.bic.total_cmp(&b.bic))
            .map(|c| RunnerUp {
                kind: c.hypothesis.kind().into(),
                delta_bic: c.bic - best.bic,
            });
        progress(&format!(
            "round {}: {} found; settling images and size",
            round + 1,
            best.hypothesis.kind()
        ));
        let resolved = resolve_images(&modes, &ev, &view, sensors, &best)?;
        let (chosen, refined, other_sizes) = settle_size(
            &modes,
            sensors,
            &view,
            (&scorer, &shares),
            &best,
            &resolved.sizes,
            &resolved.hypothesis,
        )?;
        // Place and size refitted together for a stiffness change, whose first-order scan
        // places a strong change too large and too weak; a mass is placed between the grid's
        // points (a loss region's place was chosen by the shapes among what the damping
        // allows: it stays).
        let (refined, chosen) = match refined {
            Hypothesis::StiffnessChange { .. } => {
                let rescan = |s: &Scorer| rescan(&chosen.hypothesis, s, &view, &shares);
                let start = (refined, chosen.clone());
                refine::refit(&modes, sensors, &view, &scorer, start, &rescan)?
            }
            Hypothesis::AddedMass { .. } => {
                place_between_grid_points(&modes, sensors, &view, &scorer, (refined, chosen))?
            }
            _ => (refined, chosen),
        };
        let unsettled: Vec<Hypothesis> = resolved
            .images
            .iter()
            .chain(&other_sizes)
            .cloned()
            .collect();
        let mut finding = Finding::of(&refined, &unsettled, &view.model);
        finding.confidence = 1.0 / weights;
        finding.bic_gain = Some(none - best.bic);
        finding.runner_up = runner_up;
        if !refine::changes_loss_only(&view.model, &refined) {
            edges.clear();
        }
        let next = refined.apply(&view.model);
        let next_view = view_of(&view, &next, &refined)?;
        let next_ev = Evidence::gather(&modes, next_view.poles_at(sensors)?);
        // The first-order scan chose it; the re-solved model may not bear it out. A size refitted
        // to no change is no finding (found on a coarse model of a thin plate: "added_mass"
        // 0.00 kg, BIC gain 7.3, the fit unchanged); an update that fits worse is not returned
        // (a stiffer region of a small plate: "stiffness_change" over the whole plate,
        // frequency RMS 2.4 → 9.0 Hz).
        // Nor is one whose re-solved effect does not beat "no change" by the bar its scan
        // cleared (found: every stiffer region named beside a mass in the probes of a small
        // plate scored −4 to −22 through its re-solved model, each true mass +12 to +52).
        let solved_gain = none - bic_of_update(&scorer, &next_ev, chosen.params, chosen.locations);
        let rejected = if refined.amplitude() == Some(0.0) {
            Some(REJECTED_NO_SIZE)
        } else if solved_gain < MIN_BIC_GAIN {
            Some(REJECTED_NOT_BORNE_OUT)
        } else if fits_worse(&ev, &next_ev, &patterns) {
            Some(REJECTED_FITS_WORSE)
        } else {
            None
        };
        if let Some(why) = rejected {
            progress(&format!("round {}: {}{why}", round + 1, refined.kind()));
            families.push(FamilyScore {
                round,
                kind: format!("{}{why}", refined.kind()),
                // Not borne out: the gain that rejected it, not its scan's.
                bic_gain: if why == REJECTED_NOT_BORNE_OUT {
                    solved_gain
                } else {
                    none - best.bic
                },
            });
            break;
        }
        view = next_view;
        ev = next_ev;
        kept.push(Kept {
            hypothesis: refined,
            candidate: chosen,
            scorer,
            finding,
        });
    }
    if kept.len() == 2 {
        progress("weighing the first finding against the model with the second");
        let (first, second) = (&kept[0], &kept[1]);
        let first_found = FirstFinding {
            hypothesis: &first.hypothesis,
            candidate: &first.candidate,
            scorer: &first.scorer,
        };
        let beside = reweigh_first(
            &modes,
            sensors,
            (&base, model, &form_reference),
            &first_found,
            &second.hypothesis,
            settings.model_form_sigma,
        )?;
        if let Some((reweighed, base2, ev2)) = beside {
            if reweighed.amplitude() == Some(0.0) {
                // Beside the second finding the first explains nothing: it is dropped.
                families.push(FamilyScore {
                    round: MAX_FINDINGS - 1,
                    kind: format!("{}{REJECTED_NO_SIZE}", reweighed.kind()),
                    bic_gain: first.finding.bic_gain.unwrap_or(f64::NAN),
                });
                ev = ev2;
                view = base2;
                kept.remove(0);
            } else {
                let updated = second.hypothesis.apply(&reweighed.apply(model));
                view = ModelView::new(&updated, base.fmax_hz)?;
                ev = Evidence::gather(&modes, view.poles_at(sensors)?);
                kept[0].resize(reweighed, model);
            }
        }
    }
    let mut findings: Vec<Finding> = kept.iter().map(|k| k.finding.clone()).collect();
    findings.sort_by(|a, b| b.confidence.total_cmp(&a.confidence));
    let snr = channel_snr_db(rec);
    if let Some(median) = median_snr_db(&snr).filter(|m| *m < REPORT_BELOW_SNR_DB) {
        findings.push(Finding::noise_floor(median, snr));
    }
    progress("FRFs before and after");
    let lowest = evidence
        .pairs
        .iter()
        .map(|p| modes[p.measured].frequency_hz)
        .fold(f64::INFINITY, f64::min);
    let ex = &base.model.excitation;
    let frf = compare_frfs(
        rec,
        settings.derivatives_to_acceleration,
        sensors,
        settings.excitation_m.unwrap_or((ex.x, ex.y)),
        (0.8 * lowest, settings.fmax_hz),
        &base,
        &view,
    )?;
    let (frf_before, frf_after) = frf.as_ref().map_or((None, None), |c| (c.before, c.after));
    Ok(Diagnosis {
        findings,
        fit: FitBeforeAfter {
            before: measures(&evidence, frf_before),
            after: measures(&ev, frf_after),
        },
        updated_model: view.model.clone(),
        evidence,
        evidence_after: ev,
        modes,
        families,
        frf: frf.and_then(|c| c.overlay),
        sensor_positions: sensors.to_vec(),
    })
}

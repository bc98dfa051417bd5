//! The diagnosis as one procedure: identify the recordings' modes, pair them with the model's,
//! fit each family of missing physics that the evidence can show today (`added_mass` from the
//! frequencies, missing loss from the damping), keep what pays for its parameters, update the
//! model, and measure the fit before and after. The result serialises as FORMATS.md §5's
//! `diagnosis.json`.

use std::collections::BTreeMap;

use super::damping::{self, DampingHypothesis};
use super::evidence::{Evidence, ModelView};
use super::mass::{self, add_mass};
use super::mirror;
use crate::modal::{identify, ModalError, ModalSettings, Recordings};
use crate::sim::error::SimError;
use crate::sim::model::{Model, SensorPosition};

/// Default highest frequency of the modes compared, Hz (about 15 modes of the reference plate:
/// enough to place a region; the frequency evidence needs fewer).
pub const DEFAULT_DIAGNOSE_FMAX_HZ: f64 = 160.0;
/// The model's modes are solved to this multiple of the range (a stiffer structure's modes near
/// the limit still find their partner).
pub const MODEL_RANGE_FACTOR: f64 = 1.3;

/// Settings of [`diagnose`].
#[derive(Clone, Debug)]
pub struct DiagnoseSettings {
    /// Modes from `fmin_hz` to `fmax_hz` are identified and compared.
    pub fmin_hz: f64,
    /// See `fmin_hz`.
    pub fmax_hz: f64,
}

impl Default for DiagnoseSettings {
    fn default() -> Self {
        Self {
            fmin_hz: 0.5,
            fmax_hz: DEFAULT_DIAGNOSE_FMAX_HZ,
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
    /// Too little evidence.
    #[error("expected at least {expected} modes paired with the model, got {got}")]
    TooFewPairs {
        /// Needed.
        expected: usize,
        /// Found.
        got: usize,
    },
}

/// Where a finding sits.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Region {
    /// [x_min, x_max], m.
    pub x: [f64; 2],
    /// [y_min, y_max], m.
    pub y: [f64; 2],
}

/// A point on the plate.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Point {
    /// m.
    pub x: f64,
    /// m.
    pub y: f64,
}

/// One piece of missing physics (FORMATS.md §5).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Finding {
    /// `localized_damping`, `added_mass`, `damping_law`, `noise_floor`, ….
    pub kind: String,
    /// What, where and how much, in plain words.
    pub summary: String,
    /// The region, for region kinds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub region: Option<Region>,
    /// The point, for point kinds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub point: Option<Point>,
    /// The damping law, for `damping_law` (`"rayleigh"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub law: Option<String>,
    /// Other rectangles the evidence cannot tell from `region` (the plate's mirror images).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub images: Vec<Region>,
    /// Fitted parameters by name (`loss_factor`, `mass_kg`, `alpha`, `beta`, `delta_g`, …).
    pub parameters: BTreeMap<String, f64>,
    /// Posterior probability against "no change" from the BIC gain, 1/(1 + e^(−gain/2)).
    pub confidence: f64,
}

/// The fit of a model to the recordings.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FitMeasures {
    /// Mean over bands of the report's eq. 4.8 (not computed yet: `null`).
    pub frf_error: Option<f64>,
    /// RMS over the paired modes of the damping ratio difference.
    pub damping_rms: f64,
    /// RMS over the paired modes of the damped frequency difference, Hz.
    pub frequency_rms_hz: f64,
}

/// Before and after the update.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FitBeforeAfter {
    /// The model as given.
    pub before: FitMeasures,
    /// The updated model.
    pub after: FitMeasures,
}

/// Everything [`diagnose`] concludes.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// The findings, strongest first (empty: no missing physics).
    pub findings: Vec<Finding>,
    /// Fit before and after.
    pub fit: FitBeforeAfter,
    /// The model with every finding applied.
    pub updated_model: Model,
    /// Modes identified, paired, and the model-form calibration (for the report).
    pub evidence: Evidence,
    /// The identified modes.
    pub modes: Vec<crate::modal::Mode>,
}

/// A region's mirror images are ruled out when the best candidate's quadrature correlation
/// beats the runner-up's by this much (0.45–0.53 measured on the damped-patch cases; noise on
/// a wrong image's correlation is ~0.1).
pub const MIN_IMAGE_MARGIN: f64 = 0.2;

/// The best score minus the second best (0 with fewer than two).
fn image_margin(scores: &[f64]) -> f64 {
    let mut s = scores.to_vec();
    s.sort_by(|a, b| b.total_cmp(a));
    if s.len() < 2 {
        0.0
    } else {
        s[0] - s[1]
    }
}

/// Least pairs for any hypothesis.
const MIN_PAIRS: usize = 4;

fn confidence(gain: f64) -> f64 {
    1.0 / (1.0 + (-0.5 * gain).exp())
}

fn measures(e: &Evidence) -> FitMeasures {
    FitMeasures {
        frf_error: None,
        damping_rms: e.damping_rms().unwrap_or(f64::NAN),
        frequency_rms_hz: e.frequency_rms_hz().unwrap_or(f64::NAN),
    }
}

/// Diagnoses `rec` (its channels at `sensors`) against `model`.
pub fn diagnose(
    rec: &Recordings,
    sensors: &[SensorPosition],
    model: &Model,
    settings: &DiagnoseSettings,
) -> Result<Diagnosis, DiagnoseError> {
    let modes = identify(rec, &ModalSettings::new(settings.fmin_hz, settings.fmax_hz))?.modes;
    let view = ModelView::new(model, MODEL_RANGE_FACTOR * settings.fmax_hz)?;
    let evidence = Evidence::gather(&modes, view.poles_at(sensors)?);
    if evidence.pairs.len() < MIN_PAIRS {
        return Err(DiagnoseError::TooFewPairs {
            expected: MIN_PAIRS,
            got: evidence.pairs.len(),
        });
    }
    let mut findings = Vec::new();
    let mass_fit =
        mass::fit_point_mass(&modes, &evidence, &view, sensors)?.filter(|m| m.is_finding());
    let mut loss: Option<DampingHypothesis> = None;
    let fits = damping::fit_damping(&evidence, &view)?;
    let none_bic = fits
        .iter()
        .find(|f| f.hypothesis == DampingHypothesis::NoChange)
        .map_or(f64::INFINITY, |f| f.bic);
    if let Some(best) = fits.first() {
        let gain = none_bic - best.bic;
        if best.hypothesis != DampingHypothesis::NoChange && gain >= damping::MIN_BIC_GAIN {
            let (hypothesis, scores) =
                mirror::resolve_images(&modes, &evidence, &view, sensors, &best.hypothesis)?;
            let settled = image_margin(&scores) >= MIN_IMAGE_MARGIN;
            let hypothesis = match hypothesis {
                DampingHypothesis::Region {
                    x_m, y_m, delta_g, ..
                } if settled => DampingHypothesis::Region {
                    x_m,
                    y_m,
                    delta_g,
                    images: Vec::new(),
                },
                h => h,
            };
            let mut finding = damping_finding(&hypothesis, model, confidence(gain));
            if settled {
                finding.summary.push_str(
                    " Its mirror images, which strain the modes alike, are ruled out by the \
                     complex mode shapes (the loss puts their out-of-phase part near itself).",
                );
            }
            findings.push(finding);
            loss = Some(hypothesis);
        }
    }
    let mut updated = loss
        .as_ref()
        .map_or_else(|| model.clone(), |h| damping::apply(model, h));
    if let Some(m) = mass_fit {
        // With a loss found too, the mass is weighed again against the model that has it: a
        // lossy patch raises the damped frequencies and hid part of the mass's drop.
        let mass_kg = match &loss {
            Some(_) => mass::refit_mass_at(
                &modes,
                &evidence,
                &view.with_loss_change(&updated)?,
                sensors,
                (m.x_m, m.y_m),
                m.mass_kg,
            )?,
            None => m.mass_kg,
        };
        updated = add_mass(&updated, m.x_m, m.y_m, mass_kg);
        findings.push(Finding {
            kind: "added_mass".into(),
            summary: format!(
                "A mass of {mass_kg:.2} kg that the model lacks sits near ({:.2}, {:.2}) m: it \
                 lowers the modes with an antinode there and leaves those with a nodal line \
                 through it.",
                m.x_m, m.y_m
            ),
            region: None,
            point: Some(Point { x: m.x_m, y: m.y_m }),
            law: None,
            images: Vec::new(),
            parameters: BTreeMap::from([("mass_kg".to_string(), mass_kg)]),
            confidence: confidence(m.bic_gain),
        });
    }
    let after_view = ModelView::new(&updated, MODEL_RANGE_FACTOR * settings.fmax_hz)?;
    let after = Evidence::gather(&modes, after_view.poles_at(sensors)?);
    findings.sort_by(|a, b| b.confidence.total_cmp(&a.confidence));
    Ok(Diagnosis {
        findings,
        fit: FitBeforeAfter {
            before: measures(&evidence),
            after: measures(&after),
        },
        updated_model: updated,
        evidence,
        modes,
    })
}

fn damping_finding(h: &DampingHypothesis, model: &Model, confidence: f64) -> Finding {
    let g0 = model.material.loss_factor;
    let mut f = Finding {
        kind: String::new(),
        summary: String::new(),
        region: None,
        point: None,
        law: None,
        images: Vec::new(),
        parameters: BTreeMap::new(),
        confidence,
    };
    match h {
        DampingHypothesis::Region {
            x_m,
            y_m,
            delta_g,
            images,
        } => {
            f.kind = "localized_damping".into();
            f.region = Some(Region { x: *x_m, y: *y_m });
            f.images = images
                .iter()
                .map(|(x, y)| Region { x: *x, y: *y })
                .collect();
            f.parameters.insert("loss_factor".into(), g0 + delta_g);
            f.parameters.insert("delta_g".into(), *delta_g);
            f.summary = format!(
                "The region x {:.2}–{:.2} m, y {:.2}–{:.2} m dissipates more than modelled: loss \
                 factor {:.3} instead of {g0:.3}. Each mode's extra damping follows its share of \
                 strain energy there{}.",
                x_m[0],
                x_m[1],
                y_m[0],
                y_m[1],
                g0 + delta_g,
                if images.is_empty() {
                    String::new()
                } else {
                    format!(
                        "; its {} mirror image(s) strain the modes alike and cannot be ruled out \
                         from modal damping",
                        images.len()
                    )
                }
            );
        }
        DampingHypothesis::GlobalLoss { delta_g } => {
            f.kind = "localized_damping".into();
            f.region = Some(Region {
                x: [0.0, model.plate.lx],
                y: [0.0, model.plate.ly],
            });
            f.parameters.insert("loss_factor".into(), g0 + delta_g);
            f.parameters.insert("delta_g".into(), *delta_g);
            f.summary = format!(
                "The whole plate's loss factor is {:.4}, not {g0:.4}: every mode's damping differs \
                 by the same amount.",
                g0 + delta_g
            );
        }
        DampingHypothesis::Rayleigh { alpha, beta } => {
            f.kind = "damping_law".into();
            f.law = Some("rayleigh".into());
            f.parameters.insert("alpha".into(), *alpha);
            f.parameters.insert("beta".into(), *beta);
            f.summary = format!(
                "The damping follows a Rayleigh law the model lacks: α = {alpha:.3} 1/s, \
                 β = {beta:.3e} s (extra damping ratio α/(2ω) + βω/2)."
            );
        }
        DampingHypothesis::NoChange => {}
    }
    f
}

//! One score for every hypothesis: how well its predicted changes explain the paired modes'
//! frequencies and damping, paid for by its parameters and by the places it was free to look.
//!
//! For the pairs k = 1…n (measured mode ↔ model mode below the view's range) the evidence is
//! y_k = ln(f_measured / f_model) and r_k = D_measured − D_model with the identification's σ_k.
//! A hypothesis predicts a_k (its change of ln f) and b_k (its change of D). Then
//!
//! ```text
//! BIC = n ln(RSS_f / n) + Σ ((r_k − b_k)/σ_k)² + (p + p_nuisance) ln n + ln N_locations
//! RSS_f = |P⊥(y − a)|²   (the model-form nuisance profiled out, no lower than the
//!                         identification's own frequency variance)
//! ```
//!
//! The frequency noise is profiled (model form sets it, not the identification), the damping
//! noise is the identification's. `ln N_locations` is the price of having scanned N places
//! (points, rectangles, edges): plain BIC under-penalises a search over many locations.
//!
//! RSS_f is floored at the model-form scatter, (n − p_nuisance) σ_form²: two correct models of
//! one plate (3-D hexahedra and a Kirchhoff plate, scripts/kirchhoff_sim.py) still differ mode
//! by mode by 0.11 % RMS around the nuisance fit, a few modes further off (near the corners of
//! pinned and free edges), which a point mass there would happily explain. A hypothesis gets
//! no credit for fitting the frequencies closer than that; a concealed effect moves some modes
//! far beyond it and keeps its credit. σ_form is the user's statement of how good the model is
//! ([`DEFAULT_MODEL_FORM_SIGMA`] by default); above it, the scatter is profiled from the data.

use super::evidence::{Evidence, ModePair, ModelView};
use super::hypothesis::Hypothesis;
use super::nuisance::Nuisance;
use crate::modal::Mode;

/// Smallest σ of a mode's damping ratio (an identification's order spread can be ~0).
pub const MIN_SIGMA_D: f64 = 1e-5;
/// The model-form part of a damping difference, relative: two correct plate models (the
/// 3-D hexahedra and a Kirchhoff plate) give a region's extra damping per mode to 2–5 %
/// (measured on the viscoelastic-layer and damped-patch sets), so σ_k² = σ_identified² +
/// (this × r_k)².
pub const DAMPING_FORM_REL: f64 = 0.05;
/// How far two correct models of one plate differ in ln f, mode by mode, around the nuisance
/// fit (0.11 % measured between the 32 × 48 × 2 hexahedra and a Kirchhoff plate; 0.1 %).
pub const DEFAULT_MODEL_FORM_SIGMA: f64 = 1e-3;
/// Least pairs a hypothesis is scored on.
pub const MIN_SCORED_PAIRS: usize = 4;

/// 1/σ of a pair's damping difference: the identification's σ and the model-form part of
/// `extra_damping` (the damping the model lacks or a finding added, D), in quadrature.
fn damping_weight(pair: &ModePair, extra_damping: f64) -> f64 {
    let form = DAMPING_FORM_REL * extra_damping;
    1.0 / (pair.damping_std.max(MIN_SIGMA_D).powi(2) + form * form).sqrt()
}

/// What a hypothesis predicts for each scored pair (same order as [`Scorer::pairs`]).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Prediction {
    /// Change of ln f per pair.
    pub log_frequency: Vec<f64>,
    /// Change of the damping ratio per pair.
    pub damping: Vec<f64>,
}

impl Prediction {
    /// This prediction, made for `from`'s pairs, on `to`'s pairs (matched by measured mode; a
    /// pair `from` lacks predicts no change), times `scale`.
    pub fn realigned(&self, from: &Scorer, to: &Scorer, scale: f64) -> Prediction {
        let mut p = Prediction::none(to.n());
        for (k, pair) in to.pairs.iter().enumerate() {
            if let Some(j) = from.pairs.iter().position(|q| q.measured == pair.measured) {
                p.log_frequency[k] = scale * self.log_frequency[j];
                p.damping[k] = scale * self.damping[j];
            }
        }
        p
    }

    /// No change on `n` pairs.
    pub fn none(n: usize) -> Self {
        Self {
            log_frequency: vec![0.0; n],
            damping: vec![0.0; n],
        }
    }
}

/// A hypothesis with its prediction and score.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// The change to the model.
    pub hypothesis: Hypothesis,
    /// What it predicts.
    pub prediction: Prediction,
    /// Free continuous parameters (the location's coordinates included).
    pub params: f64,
    /// How many places were scanned to find it (1: none).
    pub locations: f64,
    /// Its [`Scorer::bic`].
    pub bic: f64,
    /// The same change elsewhere, explaining the evidence as well (the plate's mirror
    /// images): settled later by the shapes, or reported.
    pub images: Vec<Hypothesis>,
    /// Other places and sizes the scanned evidence cannot tell from this one (for a lossy
    /// region: a larger region with less loss), for the mode shapes to settle.
    pub alternatives: Vec<Hypothesis>,
}

/// The evidence in the form every hypothesis is scored on.
#[derive(Clone, Debug)]
pub struct Scorer {
    /// The scored pairs (model mode below the view's range).
    pub pairs: Vec<ModePair>,
    /// ln(f_measured / f_model damped) per pair.
    pub log_frequency: Vec<f64>,
    /// D_measured − D_model per pair.
    pub damping: Vec<f64>,
    /// 1/σ_D per pair.
    pub damping_weight: Vec<f64>,
    /// Undamped model frequency per pair, Hz.
    pub model_frequency_hz: Vec<f64>,
    /// The model-form nuisance over the pairs.
    pub nuisance: Nuisance,
    /// The least RSS_f can be: the identification's Σ (σ_f/f)², or the model-form scatter
    /// (see the module doc) if larger.
    pub rss_floor: f64,
}

impl Scorer {
    /// The scorer of `evidence` (gathered from `measured` against `view`), with the model's
    /// discretisation `pattern` per view mode (empty: none; see
    /// [`super::nuisance::discretisation_pattern`]); `None` with fewer than
    /// [`MIN_SCORED_PAIRS`] pairs. `form_sigma`: the model-form scatter of ln f (see the
    /// module doc).
    pub fn new(
        measured: &[Mode],
        evidence: &Evidence,
        view: &ModelView,
        patterns: &[Vec<f64>],
        form_sigma: f64,
    ) -> Option<Self> {
        let pairs: Vec<ModePair> = evidence.pairs_within(view).into_iter().copied().collect();
        if pairs.len() < MIN_SCORED_PAIRS {
            return None;
        }
        let model_frequency_hz: Vec<f64> = pairs
            .iter()
            .map(|p| view.basis.frequencies_hz[p.model])
            .collect();
        let identification_floor = pairs
            .iter()
            .map(|p| {
                let m = &measured[p.measured];
                (m.frequency_std_hz / m.frequency_hz).powi(2)
            })
            .sum::<f64>()
            .max(1e-300);
        let log_frequency: Vec<f64> = pairs.iter().map(|p| p.frequency_rel.ln_1p()).collect();
        let per_pair: Vec<Vec<f64>> = patterns
            .iter()
            .filter(|pattern| pattern.len() >= view.count)
            .map(|pattern| pairs.iter().map(|p| pattern[p.model]).collect())
            .collect();
        let nuisance = Nuisance::new(&model_frequency_hz, &per_pair);
        let dof = (pairs.len() as f64 - nuisance.params()).max(1.0);
        let rss_floor = identification_floor.max(dof * form_sigma * form_sigma);
        Some(Self {
            log_frequency,
            damping: pairs.iter().map(|p| p.damping_diff).collect(),
            damping_weight: pairs
                .iter()
                .map(|p| damping_weight(p, p.damping_diff))
                .collect(),
            nuisance,
            model_frequency_hz,
            rss_floor,
            pairs,
        })
    }

    /// This scorer with the damping's model-form part taken from `original` (the recordings
    /// against the model before any finding, its own lossy patches taken back to the plate's
    /// loss) where that is larger: once a lossy region is in the model, found or given, the
    /// extra damping it predicts per mode carries the same relative model-form error
    /// ([`DAMPING_FORM_REL`]) as when it was missing, although the difference left is small.
    /// Found on Kirchhoff recordings of a mass beside a g = 50 % patch: with the patch in the
    /// model the identification's σ_D alone (down to 8e-5) made the small damping changes by
    /// which the mass reshapes the patch's modes cost 40 in BIC, and the mass was rejected;
    /// with a model that had the patch already, the difference left was taken for an elastic
    /// edge (tests `diagnose_kirchhoff_two_effects`).
    pub fn with_damping_form_of(mut self, original: &Evidence) -> Self {
        for (k, p) in self.pairs.iter().enumerate() {
            let before = original
                .pairs
                .iter()
                .find(|q| q.measured == p.measured)
                .map_or(0.0, |q| q.damping_diff);
            self.damping_weight[k] = damping_weight(p, before.abs().max(p.damping_diff.abs()));
        }
        self
    }

    /// Number of scored pairs.
    pub fn n(&self) -> usize {
        self.pairs.len()
    }

    /// |P⊥(y − a)|², floored at the identification's frequency variance.
    pub fn rss_frequency(&self, a: &[f64]) -> f64 {
        let d: Vec<f64> = self
            .log_frequency
            .iter()
            .zip(a)
            .map(|(y, a)| y - a)
            .collect();
        let r = self.nuisance.residual(&d);
        r.iter().map(|x| x * x).sum::<f64>().max(self.rss_floor)
    }

    /// Σ ((r_k − b_k)/σ_k)².
    pub fn chi2_damping(&self, b: &[f64]) -> f64 {
        (0..self.n())
            .map(|k| ((self.damping[k] - b[k]) * self.damping_weight[k]).powi(2))
            .sum()
    }

    /// The frequency part of the BIC for a residual sum of squares (see the module doc).
    pub fn frequency_term(&self, rss: f64) -> f64 {
        let n = self.n() as f64;
        n * (rss.max(self.rss_floor) / n).ln()
    }

    /// ln n: what one parameter costs.
    pub fn ln_n(&self) -> f64 {
        (self.n() as f64).ln()
    }

    /// The BIC of a prediction with `params` free parameters found among `locations` places.
    pub fn bic(&self, prediction: &Prediction, params: f64, locations: f64) -> f64 {
        self.frequency_term(self.rss_frequency(&prediction.log_frequency))
            + self.chi2_damping(&prediction.damping)
            + (params + self.nuisance.params()) * self.ln_n()
            + locations.max(1.0).ln()
    }

    /// The BIC of "no change" (the nuisance only).
    pub fn none_bic(&self) -> f64 {
        self.bic(&Prediction::none(self.n()), 0.0, 1.0)
    }

    /// A scored candidate.
    pub fn candidate(
        &self,
        hypothesis: Hypothesis,
        prediction: Prediction,
        params: f64,
        locations: f64,
    ) -> Candidate {
        let bic = self.bic(&prediction, params, locations);
        Candidate {
            hypothesis,
            prediction,
            params,
            locations,
            bic,
            images: Vec::new(),
            alternatives: Vec::new(),
        }
    }
}

//! Loss the model lacks or gets wrong, from the damping evidence: per paired mode
//! r_k = D_measured − D_model with the identification's σ_k. Two families:
//!
//! - `localized_damping`: extra loss Δg ≥ 0 in a rectangle. By modal strain energy it raises
//!   mode k's damping ratio by ½ F_k Δg (F_k: the share of the mode's strain energy in the
//!   rectangle), so a region shows in the modes that strain it and not in the others —
//!   whatever a local damping map, dominated by beating and nodal lines, shows. Every rectangle
//!   of the cell grid is tried; five parameters among all rectangles.
//! - `damping_law`: the plate's damping law replaced by a loss factor g' and Rayleigh damping
//!   C = αM + βK₀ (all ≥ 0): ΔD_k = ½(g' − g₀)F_plate,k + (α − α₀)/(2ω_k) + (β − β₀)ω_k/2,
//!   F_plate the strain share of the regions that take the plate's loss. Fitted by
//!   non-negative least squares, once with g' alone (one parameter: the plate's loss factor is
//!   another) and once with all three (a frequency-dependent law).

use faer::Mat;

use super::evidence::ModelView;
use super::hypothesis::Hypothesis;
use super::nnls;
use super::regions::{ModeShares, RectangleTable};
use super::score::{Candidate, Prediction, Scorer};
use crate::sim::error::SimError;

/// Rectangles whose χ² on the damping is within this of the best one's are alternatives for
/// the mode shapes to choose from: a χ² difference below 10 is not decisive on Kass and
/// Raftery's scale of 2 ln(Bayes factor). (A region twice as large with half the loss strains
/// the low modes nearly alike: measured Δχ² 2–7 on the viscoelastic-layer sets.)
pub const ALTERNATIVE_CHI2: f64 = 10.0;
/// The largest extra loss factor a region is given.
pub const MAX_REGION_DELTA_G: f64 = 5.0;

/// The best lossy rectangle for the scorer's pairs, with its images.
pub fn scan_localized_damping(scorer: &Scorer, shares: &ModeShares) -> Candidate {
    let modes: Vec<usize> = scorer.pairs.iter().map(|p| p.model).collect();
    let table = RectangleTable::new(
        shares.grid.clone(),
        &ModeShares::rows(&shares.strain, &modes, 0.5),
    );
    let n = scorer.n();
    let best = table.scan_with(
        &vec![1.0; n],
        &scorer.damping,
        &scorer.damping_weight,
        (0.0, MAX_REGION_DELTA_G),
        Some(ALTERNATIVE_CHI2),
    );
    let prediction = Prediction {
        log_frequency: vec![0.0; n],
        damping: table
            .sum_over(&best.region)
            .iter()
            .map(|s| s * best.amplitude)
            .collect(),
    };
    let hypothesis = |region, delta_g| Hypothesis::LocalizedDamping { region, delta_g };
    let mut c = scorer.candidate(
        hypothesis(best.region, best.amplitude),
        prediction,
        5.0,
        shares.grid.rectangle_count(),
    );
    c.images = best.images.iter().map(|&(r, g)| hypothesis(r, g)).collect();
    c.alternatives = best
        .alternatives
        .iter()
        .map(|&(r, g)| hypothesis(r, g))
        .collect();
    c
}

/// The first-order prediction of a `localized_damping` hypothesis on the scorer's pairs.
pub fn predict(h: &Hypothesis, scorer: &Scorer, shares: &ModeShares) -> Prediction {
    let Hypothesis::LocalizedDamping { region, delta_g } = *h else {
        return Prediction::none(scorer.n());
    };
    let modes: Vec<usize> = scorer.pairs.iter().map(|p| p.model).collect();
    let table = RectangleTable::new(
        shares.grid.clone(),
        &ModeShares::rows(&shares.strain, &modes, 0.5),
    );
    Prediction {
        log_frequency: vec![0.0; scorer.n()],
        damping: table
            .sum_over(&region)
            .iter()
            .map(|s| s * delta_g)
            .collect(),
    }
}

/// Per scored pair, the share of the mode's strain energy in the regions that take the plate's
/// loss factor (the plate and the patches without a loss factor of their own).
fn plate_loss_share(scorer: &Scorer, view: &ModelView) -> Vec<f64> {
    let sys = &view.system;
    let inherits = |name: &str| -> bool {
        name == "plate"
            || name
                .strip_prefix("patch ")
                .and_then(|p| p.parse::<usize>().ok())
                .and_then(|p| view.model.patches.get(p))
                .is_some_and(|p| p.loss_factor.is_none() && p.sls.is_none())
    };
    let phi = view.basis.shapes.as_ref();
    scorer
        .pairs
        .iter()
        .map(|p| {
            let (mut inherited, mut total) = (0.0, 0.0);
            for term in &sys.stiffness_terms {
                let (sym, val) = term.matrix.parts();
                let mut e = 0.0;
                for j in 0..sys.n_free {
                    for idx in sym.col_range(j) {
                        e += phi[(sym.row_idx()[idx], p.model)] * val[idx] * phi[(j, p.model)];
                    }
                }
                total += e;
                if inherits(&term.name) {
                    inherited += e;
                }
            }
            if total > 0.0 {
                inherited / total
            } else {
                0.0
            }
        })
        .collect()
}

/// The two damping-law candidates (loss factor alone; loss factor and Rayleigh α, β).
pub fn fit_damping_laws(scorer: &Scorer, view: &ModelView) -> Result<Vec<Candidate>, SimError> {
    let n = scorer.n();
    let share = plate_loss_share(scorer, view);
    let g0 = view.model.material.loss_factor;
    let (a0, b0) = view
        .model
        .damping
        .as_ref()
        .map_or((0.0, 0.0), |d| (d.rayleigh.alpha, d.rayleigh.beta));
    let omega: Vec<f64> = scorer
        .model_frequency_hz
        .iter()
        .map(|f| 2.0 * std::f64::consts::PI * f)
        .collect();
    let w = &scorer.damping_weight;
    let target: Vec<f64> = (0..n)
        .map(|k| {
            scorer.damping[k] + 0.5 * g0 * share[k] + a0 / (2.0 * omega[k]) + 0.5 * b0 * omega[k]
        })
        .collect();
    let columns = |k: usize| [0.5 * share[k], 0.5 / omega[k], 0.5 * omega[k]];
    let mut out = Vec::new();
    for free in [1usize, 3] {
        let a = Mat::from_fn(n, free, |k, c| w[k] * columns(k)[c]);
        let b: Vec<f64> = (0..n).map(|k| w[k] * target[k]).collect();
        let x = nnls::nnls(&a, &b);
        let (g, alpha, beta) = if free == 1 {
            (x[0], a0, b0)
        } else {
            (x[0], x[1], x[2])
        };
        let damping = (0..n)
            .map(|k| {
                0.5 * (g - g0) * share[k]
                    + (alpha - a0) / (2.0 * omega[k])
                    + 0.5 * (beta - b0) * omega[k]
            })
            .collect();
        out.push(scorer.candidate(
            Hypothesis::DampingLaw {
                loss_factor: g,
                alpha,
                beta,
            },
            Prediction {
                log_frequency: vec![0.0; n],
                damping,
            },
            free as f64,
            1.0,
        ));
    }
    Ok(out)
}

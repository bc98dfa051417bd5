//! `stiffness_change`: a region whose Young's modulus (or, equivalently for bending, thickness³)
//! differs from the model's. Stiffening a region by a factor 1 + κ raises mode i's ω² by the
//! share F_i of its strain energy there times κ, so Δln f_i ≈ ½ F_i κ, either sign, and leaves
//! its damping ratio alone (the region keeps the plate's loss factor). Every rectangle of the
//! cell grid is tried with the model-form nuisance profiled out of both the evidence and the
//! sensitivities; the best is scored with five parameters (four edges, κ) among all rectangles.

use faer::Mat;

use super::hypothesis::Hypothesis;
use super::regions::{ModeShares, RectangleTable};
use super::score::{Candidate, Prediction, Scorer};

/// The range of κ = E_region/E_plate − 1 searched: a region may be much softer (a crack, a
/// thinner part) or up to five times stiffer.
pub const STIFFNESS_FACTOR_RANGE: (f64, f64) = (-0.8, 4.0);

/// The best stiffness change for the scorer's pairs, with its images.
pub fn scan_stiffness(scorer: &Scorer, shares: &ModeShares) -> Candidate {
    let modes: Vec<usize> = scorer.pairs.iter().map(|p| p.model).collect();
    let raw = ModeShares::rows(&shares.strain, &modes, 0.5);
    // The nuisance is linear: residualising each cell's column residualises every sum of cells.
    let mut residualised = Mat::<f64>::zeros(raw.nrows(), raw.ncols());
    for c in 0..raw.ncols() {
        let col: Vec<f64> = (0..raw.nrows()).map(|k| raw[(k, c)]).collect();
        for (k, v) in scorer.nuisance.residual(&col).into_iter().enumerate() {
            residualised[(k, c)] = v;
        }
    }
    let table = RectangleTable::new(shares.grid.clone(), &residualised);
    let n = scorer.n();
    let target = scorer.nuisance.residual(&scorer.log_frequency);
    let best = table.scan(
        &vec![1.0; n],
        &target,
        &vec![1.0; n],
        STIFFNESS_FACTOR_RANGE,
    );
    let raw_table = RectangleTable::new(shares.grid.clone(), &raw);
    let kappa = best.amplitude;
    let prediction = Prediction {
        log_frequency: raw_table
            .sum_over(&best.region)
            .iter()
            .map(|s| s * kappa)
            .collect(),
        damping: vec![0.0; n],
    };
    let hypothesis = |region, kappa: f64| Hypothesis::StiffnessChange {
        region,
        youngs_factor: 1.0 + kappa,
    };
    let mut c = scorer.candidate(
        hypothesis(best.region, kappa),
        prediction,
        5.0,
        shares.grid.rectangle_count(),
    );
    c.images = best.images.iter().map(|&(r, k)| hypothesis(r, k)).collect();
    c
}

/// The first-order prediction of a `stiffness_change` hypothesis on the scorer's pairs.
pub fn predict(h: &Hypothesis, scorer: &Scorer, shares: &ModeShares) -> Prediction {
    let Hypothesis::StiffnessChange {
        region,
        youngs_factor,
    } = *h
    else {
        return Prediction::none(scorer.n());
    };
    let modes: Vec<usize> = scorer.pairs.iter().map(|p| p.model).collect();
    let table = RectangleTable::new(
        shares.grid.clone(),
        &ModeShares::rows(&shares.strain, &modes, 0.5),
    );
    Prediction {
        log_frequency: table
            .sum_over(&region)
            .iter()
            .map(|s| s * (youngs_factor - 1.0))
            .collect(),
        damping: vec![0.0; scorer.n()],
    }
}

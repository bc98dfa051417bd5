//! `viscoelastic_damping`: a region whose loss depends on frequency — a viscoelastic layer or
//! insert, modelled as a standard linear solid (FORMATS.md §3 `sls`). Its loss factor follows a
//! Debye bell, L(f) = η_peak · 2(f/f₀)/(1 + (f/f₀)²) for a moderate peak, so mode k's damping
//! rises by ½ F_k η(f_k): the modes that strain the region near f₀ gain the most, those far
//! above or below it little. A real solid cannot lose without stiffening (Kramers–Kronig): the
//! same law raises the region's storage modulus across f₀, Δln f_k = ½ F_k (E'(f_k)/E − 1). A
//! damping layer also adds mass (Δln f_k = −½ G_k μ, G_k the kinetic share, μ = Δρ/ρ), which
//! is kept only if the frequencies ask for it (it must pay for its parameter).
//!
//! Search: for each f₀ on a log grid, every rectangle with the Debye bell as a per-mode
//! weight (one scan of the damping evidence per f₀); the best (rectangle, f₀, η_peak) becomes
//! an SLS with e_inf the plate's modulus, scored on both frequencies and damping with six
//! parameters (seven with the mass) among rectangles × f₀ values.

use super::hypothesis::{sls_loss, sls_with_peak, Hypothesis};
use super::regions::{ModeShares, RectangleTable};
use super::score::{Candidate, Prediction, Scorer};

/// Peak frequencies tried, as a log grid from a third of the lowest paired mode to three
/// times the highest.
pub const PEAK_GRID_POINTS: usize = 36;
/// The largest peak loss factor a region is given.
pub const MAX_PEAK_LOSS: f64 = 3.0;

/// The Debye bell 2x/(1 + x²), 1 at x = 1.
fn bell(f_hz: f64, peak_hz: f64) -> f64 {
    let x = f_hz / peak_hz;
    2.0 * x / (1.0 + x * x)
}

/// The best viscoelastic region for the scorer's pairs (with and without added mass, the
/// better of the two), with its images.
pub fn scan_viscoelastic(
    scorer: &Scorer,
    shares: &ModeShares,
    youngs_modulus_pa: f64,
) -> Candidate {
    let modes: Vec<usize> = scorer.pairs.iter().map(|p| p.model).collect();
    let strain = RectangleTable::new(
        shares.grid.clone(),
        &ModeShares::rows(&shares.strain, &modes, 0.5),
    );
    let kinetic = RectangleTable::new(
        shares.grid.clone(),
        &ModeShares::rows(&shares.kinetic, &modes, 0.5),
    );
    let f = &scorer.model_frequency_hz;
    let (lo, hi) = (
        f.iter().copied().fold(f64::INFINITY, f64::min) / 3.0,
        f.iter().copied().fold(0.0, f64::max) * 3.0,
    );
    let mut best: Option<(super::regions::ScanResult, f64)> = None;
    for g in 0..PEAK_GRID_POINTS {
        let peak = lo * (hi / lo).powf(g as f64 / (PEAK_GRID_POINTS - 1) as f64);
        let scale: Vec<f64> = f.iter().map(|&fk| bell(fk, peak)).collect();
        let r = strain.scan(
            &scale,
            &scorer.damping,
            &scorer.damping_weight,
            (0.0, MAX_PEAK_LOSS),
        );
        if best.as_ref().is_none_or(|b| r.misfit < b.0.misfit) {
            best = Some((r, peak));
        }
    }
    let (_, peak_hz) = best.expect("the peak grid is not empty");
    // Again at the best peak, keeping the alternatives the damping cannot tell apart.
    let scale: Vec<f64> = f.iter().map(|&fk| bell(fk, peak_hz)).collect();
    let scan = strain.scan_with(
        &scale,
        &scorer.damping,
        &scorer.damping_weight,
        (0.0, MAX_PEAK_LOSS),
        Some(super::damping::ALTERNATIVE_CHI2),
    );
    let locations = shares.grid.rectangle_count() * PEAK_GRID_POINTS as f64;
    let build = |region, peak_loss: f64| -> (Hypothesis, Prediction, f64) {
        let s = strain.sum_over(&region);
        let sls = sls_with_peak(youngs_modulus_pa, peak_loss, peak_hz);
        let stiffening: Vec<f64> = (0..f.len())
            .map(|k| {
                let (re, _) = sls.modulus(2.0 * std::f64::consts::PI * f[k]);
                s[k] * (re / youngs_modulus_pa - 1.0)
            })
            .collect();
        let damping = (0..f.len()).map(|k| s[k] * sls_loss(&sls, f[k])).collect();
        // The layer's mass, if the frequencies left after the stiffening ask for it.
        let g = kinetic.sum_over(&region);
        let rest: Vec<f64> = (0..f.len())
            .map(|k| scorer.log_frequency[k] - stiffening[k])
            .collect();
        let a: Vec<f64> = g.iter().map(|v| -v).collect();
        let (mu, _) = scorer.nuisance.fit(&rest, &a, true);
        let with_mass = Prediction {
            log_frequency: (0..f.len()).map(|k| stiffening[k] + mu * a[k]).collect(),
            damping,
        };
        let h = |mu: f64| Hypothesis::ViscoelasticDamping {
            region,
            sls,
            peak_loss,
            peak_hz,
            density_factor: 1.0 + mu,
        };
        let no_mass = Prediction {
            log_frequency: stiffening,
            damping: with_mass.damping.clone(),
        };
        let (b0, b1) = (
            scorer.bic(&no_mass, 6.0, locations),
            scorer.bic(&with_mass, 7.0, locations),
        );
        if mu > 0.0 && b1 < b0 {
            (h(mu), with_mass, 7.0)
        } else {
            (h(0.0), no_mass, 6.0)
        }
    };
    let (hypothesis, prediction, params) = build(scan.region, scan.amplitude);
    let mut c = scorer.candidate(hypothesis, prediction, params, locations);
    c.images = scan
        .images
        .iter()
        .map(|&(r, eta)| build(r, eta).0)
        .collect();
    c.alternatives = scan
        .alternatives
        .iter()
        .map(|&(r, eta)| build(r, eta).0)
        .collect();
    c
}

/// The first-order prediction of a `viscoelastic_damping` hypothesis on the scorer's pairs:
/// its loss and stiffening from the region's strain shares, its added mass from the kinetic.
pub fn predict(h: &Hypothesis, scorer: &Scorer, shares: &ModeShares) -> Prediction {
    let Hypothesis::ViscoelasticDamping {
        region,
        sls,
        density_factor,
        ..
    } = *h
    else {
        return Prediction::none(scorer.n());
    };
    let modes: Vec<usize> = scorer.pairs.iter().map(|p| p.model).collect();
    let table = |m| RectangleTable::new(shares.grid.clone(), &ModeShares::rows(m, &modes, 0.5));
    let (s, g) = (
        table(&shares.strain).sum_over(&region),
        table(&shares.kinetic).sum_over(&region),
    );
    let f = &scorer.model_frequency_hz;
    Prediction {
        log_frequency: (0..f.len())
            .map(|k| {
                let (re, _) = sls.modulus(2.0 * std::f64::consts::PI * f[k]);
                s[k] * (re / sls.e_inf - 1.0) - g[k] * (density_factor - 1.0)
            })
            .collect(),
        damping: (0..f.len()).map(|k| s[k] * sls_loss(&sls, f[k])).collect(),
    }
}

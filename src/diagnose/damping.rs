//! Loss the model lacks, from the damping evidence: per paired mode r_i = D_measured − D_model
//! with the identification's uncertainty σ_i. By modal strain energy an extra loss factor Δg
//! in a region changes mode i's damping ratio by ½ F_i Δg (F_i: the share of the mode's strain
//! energy in the region), so a region shows in the modes that strain it and not in the others —
//! whatever a local damping map, dominated by beating and nodal lines, shows. Three families
//! compete with "no change" by the Bayesian information criterion χ² + k ln n:
//!
//! - `localized_damping`: any rectangle on the element grid (every one is tried: prefix sums
//!   of per-element energy shares make each fit O(modes)) with Δg ≥ 0; k = 5;
//! - a global loss change Δg (any sign, floored at −g so no loss goes negative); k = 1;
//! - `damping_law`: Rayleigh, r_i = α/(2ω_i) + βω_i/2 with α, β ≥ 0; k = 2.
//!
//! A rectangle and its mirror images strain the modes alike on a symmetric plate; all of them
//! are reported.

use faer::Mat;

use super::evidence::{Evidence, ModelView};
use super::{cell_energy_fractions, cell_grid, nnls};
use crate::sim::error::SimError;
use crate::sim::model::{Model, Patch};

/// A hypothesis is reported when it beats "no change" by this much BIC: "strong" evidence on
/// Kass and Raftery's scale of 2 ln(Bayes factor).
pub const MIN_BIC_GAIN: f64 = 6.0;
/// Smallest σ of a mode's damping ratio (an identification's order spread can be ~0).
const MIN_SIGMA_D: f64 = 1e-5;
/// Rectangles whose χ² is within this fraction of the best are its images.
const IMAGE_CHI2_REL: f64 = 1e-6;

/// What the damping evidence says.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum DampingHypothesis {
    /// The model's damping is right.
    NoChange,
    /// The loss factor of the whole plate differs by `delta_g`.
    GlobalLoss {
        /// Added loss factor.
        delta_g: f64,
    },
    /// Extra loss `delta_g` in a rectangle (and, indistinguishably, in its images).
    Region {
        /// [x_min, x_max], m.
        x_m: [f64; 2],
        /// [y_min, y_max], m.
        y_m: [f64; 2],
        /// Added loss factor in the rectangle.
        delta_g: f64,
        /// Rectangles the evidence cannot tell from this one, ([x], [y]) in m.
        images: Vec<([f64; 2], [f64; 2])>,
    },
    /// Rayleigh damping C = αM + βK added.
    Rayleigh {
        /// α, 1/s.
        alpha: f64,
        /// β, s.
        beta: f64,
    },
}

/// A hypothesis with its fit.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct DampingFit {
    /// The hypothesis.
    pub hypothesis: DampingHypothesis,
    /// Σ ((r_i − predicted_i)/σ_i)².
    pub chi2: f64,
    /// χ² + k ln n.
    pub bic: f64,
}

/// Every family's best fit to the damping evidence, best (lowest BIC) first; empty without
/// pairs. `view` is the model the evidence was gathered against (its element grid gives the
/// rectangles).
pub fn fit_damping(evidence: &Evidence, view: &ModelView) -> Result<Vec<DampingFit>, SimError> {
    let pairs = evidence.pairs_within(view);
    let n = pairs.len();
    if n == 0 {
        return Ok(Vec::new());
    }
    let r: Vec<f64> = pairs.iter().map(|p| p.damping_diff).collect();
    let w: Vec<f64> = pairs
        .iter()
        .map(|p| 1.0 / p.damping_std.max(MIN_SIGMA_D))
        .collect();
    let ln_n = (n as f64).ln();
    let chi2 = |pred: &dyn Fn(usize) -> f64| -> f64 {
        (0..n).map(|i| ((r[i] - pred(i)) * w[i]).powi(2)).sum()
    };
    let mut fits = vec![DampingFit {
        hypothesis: DampingHypothesis::NoChange,
        chi2: chi2(&|_| 0.0),
        bic: chi2(&|_| 0.0),
    }];
    // Global: ΔD_i = ½Δg.
    let half = scalar_fit(&r, &w, &vec![0.5; n], f64::NEG_INFINITY);
    let g0 = view.model.material.loss_factor;
    let delta_g = half.max(-g0);
    let c = chi2(&|_| 0.5 * delta_g);
    fits.push(DampingFit {
        hypothesis: DampingHypothesis::GlobalLoss { delta_g },
        chi2: c,
        bic: c + ln_n,
    });
    // Rayleigh: ΔD_i = α/(2ω_i) + βω_i/2, α, β ≥ 0.
    let omega: Vec<f64> = pairs
        .iter()
        .map(|p| 2.0 * std::f64::consts::PI * evidence.model[p.model].frequency_hz)
        .collect();
    let a = Mat::from_fn(n, 2, |i, k| {
        w[i] * if k == 0 {
            0.5 / omega[i]
        } else {
            0.5 * omega[i]
        }
    });
    let b: Vec<f64> = (0..n).map(|i| r[i] * w[i]).collect();
    let ab = nnls::nnls(&a, &b);
    let c = chi2(&|i| ab[0] * 0.5 / omega[i] + ab[1] * 0.5 * omega[i]);
    fits.push(DampingFit {
        hypothesis: DampingHypothesis::Rayleigh {
            alpha: ab[0],
            beta: ab[1],
        },
        chi2: c,
        bic: c + 2.0 * ln_n,
    });
    // Regions: every rectangle of the element grid.
    let model_modes: Vec<usize> = pairs.iter().map(|p| p.model).collect();
    fits.push(best_region(&view.model, view, &model_modes, &r, &w, ln_n)?);
    fits.sort_by(|p, q| p.bic.total_cmp(&q.bic));
    Ok(fits)
}

/// argmin_x Σ w²(r − a x)² with x ≥ `floor`.
fn scalar_fit(r: &[f64], w: &[f64], a: &[f64], floor: f64) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..r.len() {
        num += w[i] * w[i] * a[i] * r[i];
        den += w[i] * w[i] * a[i] * a[i];
    }
    if den > 0.0 {
        (num / den).max(floor)
    } else {
        0.0
    }
}

/// The rectangle (on the model's element grid, through the thickness) whose extra loss best
/// explains `r`, with its images.
fn best_region(
    model: &Model,
    view: &ModelView,
    modes: &[usize],
    r: &[f64],
    w: &[f64],
    ln_n: f64,
) -> Result<DampingFit, SimError> {
    let (nx, ny) = (model.mesh.nx, model.mesh.ny);
    let (lx, ly) = (model.plate.lx, model.plate.ly);
    let cells = cell_grid(lx, ly, nx, ny);
    let basis = crate::sim::eigen::Modes {
        frequencies_hz: view.basis.frequencies_hz[..view.count].to_vec(),
        shapes: view.basis.shapes.subcols(0, view.count).to_owned(),
    };
    let f = cell_energy_fractions(model, &basis, &cells)?;
    // prefix[k][(j, i)]: mode modes[k]'s share in cells [0, i) × [0, j).
    let prefix: Vec<Mat<f64>> = modes
        .iter()
        .map(|&m| {
            let mut p = Mat::<f64>::zeros(ny + 1, nx + 1);
            for j in 0..ny {
                for i in 0..nx {
                    p[(j + 1, i + 1)] =
                        f[(m, j * nx + i)] + p[(j, i + 1)] + p[(j + 1, i)] - p[(j, i)];
                }
            }
            p
        })
        .collect();
    let n = r.len();
    let mut share = vec![0.0; n];
    let mut found: Vec<(f64, [usize; 4], f64)> = Vec::new();
    let mut best = f64::INFINITY;
    for i0 in 0..nx {
        for i1 in i0 + 1..=nx {
            for j0 in 0..ny {
                for j1 in j0 + 1..=ny {
                    for (k, p) in prefix.iter().enumerate() {
                        share[k] = 0.5 * (p[(j1, i1)] - p[(j0, i1)] - p[(j1, i0)] + p[(j0, i0)]);
                    }
                    let dg = scalar_fit(r, w, &share, 0.0);
                    let c: f64 = (0..n)
                        .map(|k| ((r[k] - share[k] * dg) * w[k]).powi(2))
                        .sum();
                    if c <= best * (1.0 + IMAGE_CHI2_REL) {
                        if c < best {
                            best = c;
                            found.retain(|e| e.0 <= best * (1.0 + IMAGE_CHI2_REL));
                        }
                        found.push((c, [i0, i1, j0, j1], dg));
                    }
                }
            }
        }
    }
    found.retain(|e| e.0 <= best * (1.0 + IMAGE_CHI2_REL));
    let span = |e: &[usize; 4]| {
        (
            [lx * e[0] as f64 / nx as f64, lx * e[1] as f64 / nx as f64],
            [ly * e[2] as f64 / ny as f64, ly * e[3] as f64 / ny as f64],
        )
    };
    let (c, first, dg) = found[0];
    let (x_m, y_m) = span(&first);
    Ok(DampingFit {
        hypothesis: DampingHypothesis::Region {
            x_m,
            y_m,
            delta_g: dg,
            images: found[1..].iter().map(|e| span(&e.1)).collect(),
        },
        chi2: c,
        bic: c + 5.0 * ln_n,
    })
}

/// `base` with the damping hypothesis applied (a patch of the base loss plus Δg, appended so it
/// takes precedence; a global change on the plate; Rayleigh damping added to any present).
pub fn apply(base: &Model, hypothesis: &DampingHypothesis) -> Model {
    let mut m = base.clone();
    match hypothesis {
        DampingHypothesis::NoChange => {}
        DampingHypothesis::GlobalLoss { delta_g } => {
            m.material.loss_factor = (m.material.loss_factor + delta_g).max(0.0);
        }
        DampingHypothesis::Region {
            x_m, y_m, delta_g, ..
        } => m.patches.push(Patch {
            x: *x_m,
            y: *y_m,
            youngs_modulus: None,
            poisson: None,
            density: None,
            loss_factor: Some(base.material.loss_factor + delta_g),
            sls: None,
        }),
        DampingHypothesis::Rayleigh { alpha, beta } => {
            let (a0, b0) = m
                .damping
                .as_ref()
                .map_or((0.0, 0.0), |d| (d.rayleigh.alpha, d.rayleigh.beta));
            m.damping = Some(crate::sim::model::Damping {
                rayleigh: crate::sim::model::Rayleigh {
                    alpha: a0 + alpha,
                    beta: b0 + beta,
                },
            });
        }
    }
    m
}

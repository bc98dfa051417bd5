//! Mismatch diagnosis, first hypothesis family: missing or wrong *loss* (DESIGN.md §4).
//!
//! Recordings and the model's simulation are analysed by the same chain in mode-centred Goyder
//! bands (one per model mode), so that the estimator's own bias (beating, nodal lines) cancels
//! in the difference r_i = D_rec,i − D_sim,i (per mode: the median over the sensors). By modal
//! strain energy, an extra loss factor Δg_r in a region r changes mode i's damping ratio by
//! ΔD_i = ½ Σ_r F_ir Δg_r, with F_ir = φ_iᵀ K_r φ_i / φ_iᵀ K φ_i the share of the mode's strain
//! energy in r. Three hypotheses are fitted to the weighted residuals:
//!
//! - no change (0 parameters);
//! - a different global loss factor (1 parameter, any sign);
//! - extra loss in some cells of a grid over the plate (Δg_r ≥ 0 by non-negative least squares;
//!   as many parameters as cells used) — a damping patch, even one that the local damping map
//!   does not show (report section 3.3).
//!
//! The weights are σ_i² = se_rec² + se_sim² + (model_form · D_sim)²: the medians' standard errors
//! plus a floor for small model-form differences between the simulator that made the recordings
//! and this one. The hypothesis with the lowest BIC = χ² + k ln n wins, so clean data matching
//! the model gives "no change" rather than invented physics.

pub mod damping;
pub mod evidence;
pub mod mass;
pub mod nnls;

use faer::Mat;

use crate::frontend::Band;
use crate::pipeline::ResultRow;
use crate::sim::assembly::assemble;
use crate::sim::eigen::Modes;
use crate::sim::error::SimError;
use crate::sim::model::{Model, Patch};

/// The damping of one mode measured over the sensors.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ModeDamping {
    /// Median of the frequency-corrected local damping ratios (fraction).
    pub median_d: Option<f64>,
    /// Its standard error, 1.2533 · std / √n.
    pub std_error: Option<f64>,
    /// Sensors with an estimate (a band flagged `leakage` has none).
    pub n: usize,
}

/// Per band (mode): the median corrected damping ratio over the channels' first decays,
/// leaving out estimates whose energy came from a neighbouring mode.
pub fn per_mode_damping(rows: &[ResultRow], bands: &[Band]) -> Vec<ModeDamping> {
    bands
        .iter()
        .map(|band| {
            let mut d: Vec<f64> = rows
                .iter()
                .filter(|r| r.band == *band && r.decay == 0)
                .filter_map(|r| r.estimate.damping_ratio_corrected)
                .collect();
            d.sort_by(f64::total_cmp);
            let n = d.len();
            if n < 3 {
                return ModeDamping {
                    median_d: None,
                    std_error: None,
                    n,
                };
            }
            let median = if n % 2 == 1 {
                d[n / 2]
            } else {
                0.5 * (d[n / 2 - 1] + d[n / 2])
            };
            let mean = d.iter().sum::<f64>() / n as f64;
            let var = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            ModeDamping {
                median_d: Some(median),
                std_error: Some(1.2533 * var.sqrt() / (n as f64).sqrt()),
                n,
            }
        })
        .collect()
}

/// A candidate region: a rectangle through the thickness.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Cell {
    /// [x_min, x_max], m.
    pub x_m: [f64; 2],
    /// [y_min, y_max], m.
    pub y_m: [f64; 2],
}

/// An nx × ny grid of cells over the plate 0…lx × 0…ly.
pub fn cell_grid(lx_m: f64, ly_m: f64, nx: usize, ny: usize) -> Vec<Cell> {
    let mut cells = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            cells.push(Cell {
                x_m: [
                    lx_m * i as f64 / nx as f64,
                    lx_m * (i + 1) as f64 / nx as f64,
                ],
                y_m: [
                    ly_m * j as f64 / ny as f64,
                    ly_m * (j + 1) as f64 / ny as f64,
                ],
            });
        }
    }
    cells
}

/// F_ir: the share of mode i's strain energy in cell r (n_modes × n_cells). The cells are
/// assembled as regions of a copy of `model` (before its own patches, which keep their
/// material); `modes` must be the model's (same mesh, hence the same dofs).
pub fn cell_energy_fractions(
    model: &Model,
    modes: &Modes,
    cells: &[Cell],
) -> Result<Mat<f64>, SimError> {
    let mut split = model.clone();
    let own = std::mem::take(&mut split.patches);
    split.patches = cells
        .iter()
        .map(|c| Patch {
            x: c.x_m,
            y: c.y_m,
            youngs_modulus: None,
            poisson: None,
            density: None,
            loss_factor: None,
            sls: None,
        })
        .chain(own)
        .collect();
    let sys = assemble(&split)?;
    let phi = modes.shapes.as_ref();
    let n_modes = modes.frequencies_hz.len();
    let mut energy = Mat::<f64>::zeros(n_modes, sys.stiffness_terms.len());
    for (t, term) in sys.stiffness_terms.iter().enumerate() {
        let (sym, val) = term.matrix.parts();
        for i in 0..n_modes {
            let mut e = 0.0;
            for j in 0..sys.n_free {
                for idx in sym.col_range(j) {
                    e += phi[(sym.row_idx()[idx], i)] * val[idx] * phi[(j, i)];
                }
            }
            energy[(i, t)] = e;
        }
    }
    // Cell r is the region named "patch r" (an empty plate region may have no term).
    let column: Vec<Option<usize>> = (0..cells.len())
        .map(|r| {
            let name = format!("patch {r}");
            sys.stiffness_terms.iter().position(|t| t.name == name)
        })
        .collect();
    Ok(Mat::from_fn(n_modes, cells.len(), |i, r| {
        let total: f64 = (0..energy.ncols()).map(|t| energy[(i, t)]).sum();
        column[r].map_or(0.0, |t| energy[(i, t)] / total)
    }))
}

/// A hypothesis about the missing loss, with its fitted parameters.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum Hypothesis {
    /// The model's damping is right.
    NoChange,
    /// The loss factor of the whole plate differs by `delta_g`.
    GlobalLoss {
        /// Added loss factor (may be negative).
        delta_g: f64,
    },
    /// Extra loss factor in some cells: (cell index, Δg ≥ 0).
    LocalLoss {
        /// The cells with extra loss and how much.
        cells: Vec<(usize, f64)>,
    },
}

/// A fitted hypothesis and how well it explains the residuals.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Fit {
    /// The hypothesis.
    pub hypothesis: Hypothesis,
    /// Weighted residual sum of squares Σ ((r_i − predicted_i) / σ_i)².
    pub chi2: f64,
    /// Fitted parameters.
    pub n_params: usize,
    /// χ² + k ln n: the lower, the better.
    pub bic: f64,
}

/// Fits the three hypotheses to `residual_d` (D_rec − D_sim per mode) with uncertainties
/// `sigma_d`, given the cell energy fractions (modes × cells); sorted by BIC, best first.
pub fn fit_hypotheses(residual_d: &[f64], sigma_d: &[f64], fractions: &Mat<f64>) -> Vec<Fit> {
    let n = residual_d.len();
    let w: Vec<f64> = sigma_d.iter().map(|s| 1.0 / s).collect();
    let chi2 = |pred: &dyn Fn(usize) -> f64| -> f64 {
        (0..n)
            .map(|i| ((residual_d[i] - pred(i)) * w[i]).powi(2))
            .sum()
    };
    let ln_n = (n.max(1) as f64).ln();
    let mut fits = Vec::new();
    let c0 = chi2(&|_| 0.0);
    fits.push(Fit {
        hypothesis: Hypothesis::NoChange,
        chi2: c0,
        n_params: 0,
        bic: c0,
    });
    // Global: ΔD_i = ½ Δg for every mode; weighted least squares in one parameter.
    let sw: f64 = w.iter().map(|v| v * v).sum();
    if sw > 0.0 {
        let half_dg: f64 = (0..n).map(|i| residual_d[i] * w[i] * w[i]).sum::<f64>() / sw;
        let c = chi2(&|_| half_dg);
        fits.push(Fit {
            hypothesis: Hypothesis::GlobalLoss {
                delta_g: 2.0 * half_dg,
            },
            chi2: c,
            n_params: 1,
            bic: c + ln_n,
        });
    }
    // Local: ΔD_i = ½ Σ_r F_ir Δg_r, Δg ≥ 0.
    let nc = fractions.ncols();
    let a = Mat::from_fn(n, nc, |i, r| 0.5 * fractions[(i, r)] * w[i]);
    let b: Vec<f64> = (0..n).map(|i| residual_d[i] * w[i]).collect();
    let dg = nnls::nnls(&a, &b);
    let used: Vec<(usize, f64)> = dg
        .iter()
        .enumerate()
        .filter(|(_, v)| **v > 0.0)
        .map(|(r, v)| (r, *v))
        .collect();
    if !used.is_empty() {
        let c = chi2(&|i| used.iter().map(|&(r, g)| 0.5 * fractions[(i, r)] * g).sum());
        fits.push(Fit {
            n_params: used.len(),
            bic: c + used.len() as f64 * ln_n,
            hypothesis: Hypothesis::LocalLoss { cells: used },
            chi2: c,
        });
    }
    fits.sort_by(|p, q| p.bic.total_cmp(&q.bic));
    fits
}

/// The cells that per-mode damping cannot tell apart from cell `r`: their strain-energy shares
/// (columns of `fractions`, modes × cells) match r's within `rel_tol` of r's largest share for
/// every mode. On a symmetric plate these are r's mirror images: modal damping alone cannot
/// say on which side of a symmetry line the loss sits.
pub fn indistinguishable(fractions: &Mat<f64>, r: usize, rel_tol: f64) -> Vec<usize> {
    let n = fractions.nrows();
    let scale = (0..n).map(|i| fractions[(i, r)].abs()).fold(0.0, f64::max);
    (0..fractions.ncols())
        .filter(|&q| q != r)
        .filter(|&q| {
            (0..n).all(|i| (fractions[(i, q)] - fractions[(i, r)]).abs() <= rel_tol * scale)
        })
        .collect()
}

/// The mirror images of cell `r` (x → lx − x, y → ly − y, both) that exist in `cells` and
/// that modal damping cannot tell from `r` ([`indistinguishable`]); `r` itself excluded.
pub fn cell_images(
    cells: &[Cell],
    r: usize,
    fractions: &Mat<f64>,
    lx_m: f64,
    ly_m: f64,
) -> Vec<usize> {
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * (1.0 + a.abs());
    let twins = indistinguishable(fractions, r, 0.02);
    let c = cells[r];
    let mut out = Vec::new();
    for (mx, my) in [(true, false), (false, true), (true, true)] {
        let x = if mx {
            [lx_m - c.x_m[1], lx_m - c.x_m[0]]
        } else {
            c.x_m
        };
        let y = if my {
            [ly_m - c.y_m[1], ly_m - c.y_m[0]]
        } else {
            c.y_m
        };
        if let Some(q) = cells.iter().position(|k| {
            same(k.x_m[0], x[0])
                && same(k.x_m[1], x[1])
                && same(k.y_m[0], y[0])
                && same(k.y_m[1], y[1])
        }) {
            if q != r && twins.contains(&q) && !out.contains(&q) {
                out.push(q);
            }
        }
    }
    out
}

/// `base` with the hypothesis applied: a global loss change on the plate and every patch, or
/// one patch per cell with the plate's loss factor plus the cell's Δg (appended last, so they
/// take precedence over existing patches there).
pub fn updated_model(base: &Model, cells: &[Cell], hypothesis: &Hypothesis) -> Model {
    let mut m = base.clone();
    match hypothesis {
        Hypothesis::NoChange => {}
        Hypothesis::GlobalLoss { delta_g } => {
            m.material.loss_factor = (m.material.loss_factor + delta_g).max(0.0);
            for p in &mut m.patches {
                if let Some(g) = &mut p.loss_factor {
                    *g = (*g + delta_g).max(0.0);
                }
            }
        }
        Hypothesis::LocalLoss { cells: used } => {
            for &(r, dg) in used {
                m.patches.push(Patch {
                    x: cells[r].x_m,
                    y: cells[r].y_m,
                    youngs_modulus: None,
                    poisson: None,
                    density: None,
                    loss_factor: Some(base.material.loss_factor + dg),
                    sls: None,
                });
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hypotheses_pick_what_made_the_residuals() {
        // 8 modes, 4 cells with distinct energy shares.
        let f = Mat::from_fn(8, 4, |i, r| {
            let raw = [(i * 3 + r * 5) % 7, (i + 2 * r) % 4][(i + r) % 2] as f64 + 0.2;
            raw / 10.0
        });
        let sigma = vec![1e-4; 8];
        // Cell 2 has Δg = 0.05.
        let local: Vec<f64> = (0..8).map(|i| 0.5 * f[(i, 2)] * 0.05).collect();
        let fits = fit_hypotheses(&local, &sigma, &f);
        match &fits[0].hypothesis {
            Hypothesis::LocalLoss { cells } => {
                assert_eq!(cells.len(), 1, "{cells:?}");
                assert_eq!(cells[0].0, 2);
                assert!((cells[0].1 - 0.05).abs() < 1e-9);
            }
            h => panic!("{h:?}"),
        }
        // A global change of +0.004 in g: ΔD = 0.002 everywhere.
        let fits = fit_hypotheses(&[0.002; 8], &sigma, &f);
        match fits[0].hypothesis {
            Hypothesis::GlobalLoss { delta_g } => assert!((delta_g - 0.004).abs() < 1e-12),
            ref h => panic!("{h:?}"),
        }
        // Residuals at the noise level: nothing is invented.
        let noise = [1e-5, -2e-5, 0.5e-5, 1e-5, -1e-5, 0.0, 2e-5, -0.5e-5];
        assert_eq!(
            fit_hypotheses(&noise, &sigma, &f)[0].hypothesis,
            Hypothesis::NoChange
        );
    }

    #[test]
    fn mirror_cells_are_indistinguishable() {
        // Cells 0 and 3 share their energy shares (mirror images); cell 1 differs by 5 %.
        let f = Mat::from_fn(3, 4, |i, r| match r {
            0 | 3 => 0.1 * (i + 1) as f64,
            1 => 0.1 * (i + 1) as f64 * if i == 2 { 1.05 } else { 1.0 },
            _ => 0.02,
        });
        assert_eq!(indistinguishable(&f, 0, 0.02), vec![3]);
        assert_eq!(indistinguishable(&f, 3, 0.02), vec![0]);
        assert!(indistinguishable(&f, 2, 0.02).is_empty());
    }

    #[test]
    fn images_of_one_cell() {
        let cells = cell_grid(2.0, 3.0, 4, 6);
        let f = Mat::from_fn(3, cells.len(), |i, r| {
            let c = cells[r];
            let (dx, dy) = (
                (c.x_m[0] + c.x_m[1] - 2.0).abs(),
                (c.y_m[0] + c.y_m[1] - 3.0).abs(),
            );
            0.01 * (1.0 + i as f64) * (1.0 + dx) * (2.0 + dy * dy)
        });
        let mut im = cell_images(&cells, 18, &f, 2.0, 3.0);
        im.sort_unstable();
        // x 1.0–1.5, y 2.0–2.5 → x 0.5–1.0 (17), y 0.5–1.0 (6), both (5).
        assert_eq!(im, vec![5, 6, 17]);
    }

    #[test]
    fn cell_grid_covers_the_plate() {
        let c = cell_grid(2.0, 3.0, 4, 6);
        assert_eq!(c.len(), 24);
        assert_eq!(c[0].x_m, [0.0, 0.5]);
        assert_eq!(c[23].y_m, [2.5, 3.0]);
    }
}

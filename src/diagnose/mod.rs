//! Mismatch diagnosis (DESIGN.md §4): when recordings and the model differ, what physics the
//! model left out, where, how much, and the fit before and after adding it.
//!
//! The data flow, one file each: [`evidence`] (the recordings' modes identified from all
//! sensors at once, paired by shape with the model's damped poles, and the model-form
//! calibration), the hypothesis families ([`mass`]: a point mass from the frequencies;
//! [`damping`]: a lossy rectangle, a global loss change or a Rayleigh law from the damping),
//! and [`procedure`], which runs them, keeps what pays for its parameters in the Bayesian
//! information criterion, and updates the model. The cell grid and the strain-energy shares
//! below serve the damping family; [`nnls`] its non-negative fits.

pub mod damping;
pub mod evidence;
pub mod mass;
pub mod mirror;
pub mod nnls;
pub mod procedure;

use faer::Mat;

use crate::sim::assembly::assemble;
use crate::sim::eigen::Modes;
use crate::sim::error::SimError;
use crate::sim::model::{Model, Patch};

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_grid_covers_the_plate() {
        let c = cell_grid(2.0, 3.0, 4, 6);
        assert_eq!(c.len(), 24);
        assert_eq!(c[0].x_m, [0.0, 0.5]);
        assert_eq!(c[23].y_m, [2.5, 3.0]);
    }
}

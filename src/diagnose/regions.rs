//! Rectangles on the plate, and the search over all of them.
//!
//! A region's effect on mode i follows the share of the mode's strain energy (a stiffness or
//! loss change) or kinetic energy (a density change) inside it. The plate is cut into a grid of
//! cells on element boundaries (at most [`MAX_CELLS_PER_SIDE`] a side); per-cell shares summed
//! in prefix tables give any rectangle's share in O(modes), so every rectangle of the grid can
//! be tried: no preset cell layout decides where a finding may lie.

use faer::Mat;

use super::evidence::ModelView;
use crate::sim::assembly::assemble;
use crate::sim::eigen::Modes;
use crate::sim::error::SimError;
use crate::sim::model::{Model, Patch, SensorPosition};

/// The cell grid has at most this many cells along a side (cells group whole elements).
pub const MAX_CELLS_PER_SIDE: usize = 48;
/// Rectangles whose misfit is within this fraction of the best one's are its images.
pub const IMAGE_MISFIT_REL: f64 = 1e-6;

/// A rectangle through the thickness, m.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Region {
    /// [x_min, x_max], m.
    pub x: [f64; 2],
    /// [y_min, y_max], m.
    pub y: [f64; 2],
}

impl Region {
    /// Centre (x, y), m.
    pub fn centre(&self) -> (f64, f64) {
        (0.5 * (self.x[0] + self.x[1]), 0.5 * (self.y[0] + self.y[1]))
    }

    /// A patch over this region that overrides nothing (to be filled in by the caller).
    pub fn patch(&self) -> Patch {
        Patch {
            x: self.x,
            y: self.y,
            youngs_modulus: None,
            poisson: None,
            density: None,
            loss_factor: None,
            sls: None,
        }
    }
}

/// The grid of cells over a model's plate, on its element boundaries.
#[derive(Clone, Debug)]
pub struct CellGrid {
    /// Cell boundaries along x, m (nx + 1 values).
    pub x_m: Vec<f64>,
    /// Cell boundaries along y, m (ny + 1 values).
    pub y_m: Vec<f64>,
}

impl CellGrid {
    /// The cells of `model`: its elements, grouped when a side has more than
    /// [`MAX_CELLS_PER_SIDE`].
    pub fn of(model: &Model) -> Self {
        let edges = |n_el: usize, len: f64| -> Vec<f64> {
            let n = n_el.min(MAX_CELLS_PER_SIDE);
            (0..=n)
                .map(|i| len * ((i * n_el) as f64 / n as f64).round() / n_el as f64)
                .collect()
        };
        Self {
            x_m: edges(model.mesh.nx, model.plate.lx),
            y_m: edges(model.mesh.ny, model.plate.ly),
        }
    }

    /// Cells along x.
    pub fn nx(&self) -> usize {
        self.x_m.len() - 1
    }

    /// Cells along y.
    pub fn ny(&self) -> usize {
        self.y_m.len() - 1
    }

    /// The cells, row by row (x fastest).
    pub fn cells(&self) -> Vec<Region> {
        let mut out = Vec::with_capacity(self.nx() * self.ny());
        for j in 0..self.ny() {
            for i in 0..self.nx() {
                out.push(self.span([i, i + 1, j, j + 1]));
            }
        }
        out
    }

    /// The rectangle of cells [i0, i1) × [j0, j1).
    pub fn span(&self, e: [usize; 4]) -> Region {
        Region {
            x: [self.x_m[e[0]], self.x_m[e[1]]],
            y: [self.y_m[e[2]], self.y_m[e[3]]],
        }
    }

    /// Number of rectangles on the grid.
    pub fn rectangle_count(&self) -> f64 {
        let (nx, ny) = (self.nx() as f64, self.ny() as f64);
        0.25 * nx * (nx + 1.0) * ny * (ny + 1.0)
    }
}

/// Strain-energy shares F_ir of mode i in cell r (modes × cells). The cells are assembled as
/// regions of a copy of `model` (before its own patches, which keep their material); `modes`
/// must be the model's (same mesh, hence the same dofs).
pub fn strain_shares(model: &Model, modes: &Modes, cells: &[Region]) -> Result<Mat<f64>, SimError> {
    let mut split = model.clone();
    let own = std::mem::take(&mut split.patches);
    split.patches = cells.iter().map(Region::patch).chain(own).collect();
    let sys = assemble(&split)?;
    let phi = modes.shapes.as_ref();
    let n_modes = modes.frequencies_hz.len();
    let mut energy = Mat::<f64>::zeros(n_modes, sys.stiffness_terms.len());
    for (t, term) in sys.stiffness_terms.iter().enumerate() {
        let (sym, val) = term.matrix.parts();
        // A cell's term has entries in its own few columns only: visit those, not every dof
        // per mode (the same additions in the same order).
        let filled: Vec<usize> = (0..sys.n_free)
            .filter(|&j| !sym.col_range(j).is_empty())
            .collect();
        for i in 0..n_modes {
            let shape = phi.col(i);
            let mut e = 0.0;
            for &j in &filled {
                for idx in sym.col_range(j) {
                    e += shape[sym.row_idx()[idx]] * val[idx] * shape[j];
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

/// Out-of-plane kinetic-energy shares G_ir = ρh ∫_cell w_i² (mass-normalised w, the plate's
/// own density and thickness) by 2 × 2 Gauss points per cell, from `shapes_at` (which reads the
/// modes at positions). What a density change in a region does to the modes, to first order.
pub fn kinetic_shares(
    model: &Model,
    cells: &[Region],
    shapes_at: impl Fn(&[SensorPosition]) -> Result<Vec<Vec<f64>>, SimError>,
) -> Result<Mat<f64>, SimError> {
    let g = 0.5 / 3f64.sqrt();
    let mut points = Vec::with_capacity(4 * cells.len());
    for c in cells {
        let (xc, yc) = c.centre();
        let (hx, hy) = (c.x[1] - c.x[0], c.y[1] - c.y[0]);
        for (sx, sy) in [(-g, -g), (g, -g), (-g, g), (g, g)] {
            points.push(SensorPosition {
                id: String::new(),
                x_m: xc + sx * hx,
                y_m: yc + sy * hy,
            });
        }
    }
    let w = shapes_at(&points)?;
    let rho_h = model.material.density * model.plate.thickness;
    Ok(Mat::from_fn(w.len(), cells.len(), |i, r| {
        let c = &cells[r];
        let area = (c.x[1] - c.x[0]) * (c.y[1] - c.y[0]);
        let mean_sq: f64 = (0..4).map(|q| w[i][4 * r + q].powi(2)).sum::<f64>() / 4.0;
        rho_h * area * mean_sq
    }))
}

/// Per-cell energy shares of a view's modes, computed once per diagnosis round.
#[derive(Clone, Debug)]
pub struct ModeShares {
    /// The cells.
    pub grid: CellGrid,
    /// Strain-energy shares, view modes × cells.
    pub strain: Mat<f64>,
    /// Out-of-plane kinetic-energy shares, view modes × cells.
    pub kinetic: Mat<f64>,
}

impl ModeShares {
    /// The shares of `view`'s modes below its range.
    pub fn of(view: &ModelView) -> Result<Self, SimError> {
        let grid = CellGrid::of(&view.model);
        let cells = grid.cells();
        let modes = Modes {
            frequencies_hz: view.basis.frequencies_hz[..view.count].to_vec(),
            shapes: view.basis.shapes.subcols(0, view.count).to_owned(),
        };
        let strain = strain_shares(&view.model, &modes, &cells)?;
        let kinetic = kinetic_shares(&view.model, &cells, |p| view.shapes_at(p))?;
        Ok(Self {
            grid,
            strain,
            kinetic,
        })
    }

    /// `factor` × the rows of `shares` for the given model modes (one row per pair).
    pub fn rows(shares: &Mat<f64>, model_modes: &[usize], factor: f64) -> Mat<f64> {
        Mat::from_fn(model_modes.len(), shares.ncols(), |k, c| {
            factor * shares[(model_modes[k], c)]
        })
    }
}

/// Prefix sums of per-cell values for each scored pair: any rectangle's value per pair in
/// O(pairs).
#[derive(Clone, Debug)]
pub struct RectangleTable {
    /// The grid.
    pub grid: CellGrid,
    prefix: Vec<Mat<f64>>,
}

/// The best rectangle of a [`RectangleTable::scan`].
#[derive(Clone, Debug, PartialEq)]
pub struct ScanResult {
    /// Weighted residual sum of squares.
    pub misfit: f64,
    /// The rectangle.
    pub region: Region,
    /// Its fitted amplitude.
    pub amplitude: f64,
    /// Rectangles of the same misfit (the plate's mirror images), with their amplitudes.
    pub images: Vec<(Region, f64)>,
    /// Other rectangles, unlike the best one (overlap below [`ALTERNATIVE_MAX_OVERLAP`]) and
    /// unlike each other, that fit within the scan's tolerance: what the evidence scanned
    /// cannot tell from the best (a larger region with less loss), for other evidence to
    /// settle. Empty unless asked for.
    pub alternatives: Vec<(Region, f64)>,
}

/// Alternatives overlap the best rectangle and each other by less than this (intersection
/// over union).
pub const ALTERNATIVE_MAX_OVERLAP: f64 = 0.8;
/// Most alternatives a scan returns.
pub const MAX_ALTERNATIVES: usize = 12;

impl Region {
    /// Intersection over union with `other` (0: apart, 1: the same rectangle).
    pub fn overlap(&self, other: &Region) -> f64 {
        let ix = (self.x[1].min(other.x[1]) - self.x[0].max(other.x[0])).max(0.0);
        let iy = (self.y[1].min(other.y[1]) - self.y[0].max(other.y[0])).max(0.0);
        let inter = ix * iy;
        let area = |r: &Region| (r.x[1] - r.x[0]) * (r.y[1] - r.y[0]);
        let union = area(self) + area(other) - inter;
        if union > 0.0 {
            inter / union
        } else {
            0.0
        }
    }

    /// The share of the smaller of the two rectangles that lies in the other (1: one holds
    /// the other; 0: apart): a region and a narrower one inside it sit at the same place
    /// though their [`Region::overlap`] is small.
    pub fn containment(&self, other: &Region) -> f64 {
        let ix = (self.x[1].min(other.x[1]) - self.x[0].max(other.x[0])).max(0.0);
        let iy = (self.y[1].min(other.y[1]) - self.y[0].max(other.y[0])).max(0.0);
        let area = |r: &Region| (r.x[1] - r.x[0]) * (r.y[1] - r.y[0]);
        let smaller = area(self).min(area(other));
        if smaller > 0.0 {
            ix * iy / smaller
        } else {
            0.0
        }
    }
}

impl RectangleTable {
    /// The table of `values` (pairs × cells of `grid`, row by row).
    pub fn new(grid: CellGrid, values: &Mat<f64>) -> Self {
        let (nx, ny) = (grid.nx(), grid.ny());
        let prefix = (0..values.nrows())
            .map(|k| {
                let mut p = Mat::<f64>::zeros(ny + 1, nx + 1);
                for j in 0..ny {
                    for i in 0..nx {
                        p[(j + 1, i + 1)] =
                            values[(k, j * nx + i)] + p[(j, i + 1)] + p[(j + 1, i)] - p[(j, i)];
                    }
                }
                p
            })
            .collect();
        Self { grid, prefix }
    }

    /// The summed value of the cells [i0, i1) × [j0, j1) for each pair.
    pub fn sum(&self, e: [usize; 4]) -> Vec<f64> {
        self.prefix
            .iter()
            .map(|p| p[(e[3], e[1])] - p[(e[2], e[1])] - p[(e[3], e[0])] + p[(e[2], e[0])])
            .collect()
    }

    /// The summed value over the cells whose centres lie in `region`, per pair.
    pub fn sum_over(&self, region: &Region) -> Vec<f64> {
        let index = |edges: &[f64], v: f64| {
            edges
                .windows(2)
                .take_while(|w| 0.5 * (w[0] + w[1]) < v)
                .count()
        };
        let e = [
            index(&self.grid.x_m, region.x[0]),
            index(&self.grid.x_m, region.x[1]),
            index(&self.grid.y_m, region.y[0]),
            index(&self.grid.y_m, region.y[1]),
        ];
        if e[1] <= e[0] || e[3] <= e[2] {
            return vec![0.0; self.prefix.len()];
        }
        self.sum(e)
    }

    /// Every rectangle: the amplitude x in [lo, hi] minimising Σ_k w_k² (t_k − s_k c_k x)²
    /// (s_k the rectangle's summed value, c_k = `scale[k]`), and the rectangle of least misfit
    /// with its images.
    pub fn scan(
        &self,
        scale: &[f64],
        target: &[f64],
        weight: &[f64],
        bounds: (f64, f64),
    ) -> ScanResult {
        self.scan_with(scale, target, weight, bounds, None)
    }

    /// [`Self::scan`], also keeping the best rectangle of each class of place and size (centre
    /// on a grid of two cells, width and height in steps of 40 %) and returning, as
    /// alternatives, those within `tolerance` of the best misfit, diverse by overlap.
    pub fn scan_with(
        &self,
        scale: &[f64],
        target: &[f64],
        weight: &[f64],
        bounds: (f64, f64),
        tolerance: Option<f64>,
    ) -> ScanResult {
        let mut classes: std::collections::HashMap<[i64; 4], (f64, [usize; 4], f64)> =
            std::collections::HashMap::new();
        let class_of = |e: &[usize; 4]| -> [i64; 4] {
            let step = 1.4f64.ln();
            [
                (e[0] + e[1]) as i64 / 4,
                (e[2] + e[3]) as i64 / 4,
                (((e[1] - e[0]) as f64).ln() / step).round() as i64,
                (((e[3] - e[2]) as f64).ln() / step).round() as i64,
            ]
        };
        let (nx, ny) = (self.grid.nx(), self.grid.ny());
        let n = target.len();
        let tw: Vec<f64> = (0..n).map(|k| target[k] * weight[k]).collect();
        let tt: f64 = tw.iter().map(|v| v * v).sum();
        let cw: Vec<f64> = (0..n).map(|k| scale[k] * weight[k]).collect();
        let mut found: Vec<(f64, [usize; 4], f64)> = Vec::new();
        let mut best = f64::INFINITY;
        let mut s = vec![0.0; n];
        for i0 in 0..nx {
            for i1 in i0 + 1..=nx {
                for j0 in 0..ny {
                    for j1 in j0 + 1..=ny {
                        let (mut st, mut ss) = (0.0, 0.0);
                        for (k, p) in self.prefix.iter().enumerate() {
                            s[k] = (p[(j1, i1)] - p[(j0, i1)] - p[(j1, i0)] + p[(j0, i0)]) * cw[k];
                            st += s[k] * tw[k];
                            ss += s[k] * s[k];
                        }
                        let x = if ss > 0.0 {
                            (st / ss).clamp(bounds.0, bounds.1)
                        } else {
                            0.0
                        };
                        let misfit = (tt - 2.0 * x * st + x * x * ss).max(0.0);
                        if tolerance.is_some() {
                            let e = [i0, i1, j0, j1];
                            let slot = classes.entry(class_of(&e)).or_insert((f64::INFINITY, e, x));
                            if misfit < slot.0 {
                                *slot = (misfit, e, x);
                            }
                        }
                        let tol = IMAGE_MISFIT_REL * best.max(1e-300);
                        // A rectangle held at zero change is "no change", not an image: when
                        // no change fits (the data ask for the opposite sign) every rectangle
                        // would tie, and 10⁶ images were carried on (a soft edge's lower
                        // damping made the loss scans take 30 s each).
                        let no_change = x == 0.0 && !found.is_empty();
                        if misfit <= best + tol && !no_change {
                            if misfit < best {
                                best = misfit;
                                let keep = best + IMAGE_MISFIT_REL * best.max(1e-300);
                                found.retain(|e| e.0 <= keep);
                            }
                            found.push((misfit, [i0, i1, j0, j1], x));
                        }
                    }
                }
            }
        }
        let keep = best + IMAGE_MISFIT_REL * best.max(1e-300);
        found.retain(|e| e.0 <= keep);
        let (misfit, first, amplitude) = found[0];
        let images: Vec<(Region, f64)> = found[1..]
            .iter()
            .map(|e| (self.grid.span(e.1), e.2))
            .collect();
        let mut alternatives: Vec<(Region, f64)> = Vec::new();
        if let Some(tol) = tolerance {
            let mut near: Vec<(f64, [usize; 4], f64)> = classes
                .into_values()
                .filter(|c| c.0 <= misfit + tol && c.2 != 0.0)
                .collect();
            near.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut taken: Vec<Region> = std::iter::once(self.grid.span(first))
                .chain(images.iter().map(|i| i.0))
                .collect();
            for (_, e, x) in near {
                if alternatives.len() == MAX_ALTERNATIVES {
                    break;
                }
                let r = self.grid.span(e);
                if taken
                    .iter()
                    .all(|t| t.overlap(&r) < ALTERNATIVE_MAX_OVERLAP)
                {
                    taken.push(r);
                    alternatives.push((r, x));
                }
            }
        }
        ScanResult {
            misfit,
            region: self.grid.span(first),
            amplitude,
            images,
            alternatives,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scan finds the rectangle that made the data, with its amplitude, against a slow
    /// oracle (every rectangle's sum recomputed cell by cell).
    #[test]
    fn the_scan_finds_the_rectangle_that_made_the_data() {
        let grid = CellGrid {
            x_m: (0..=5).map(|i| 0.4 * i as f64).collect(),
            y_m: (0..=6).map(|j| 0.5 * j as f64).collect(),
        };
        let n_pairs = 7;
        // Irregular cell values: a periodic pattern (c mod 11) gave two rectangles equal sums.
        let values = Mat::from_fn(n_pairs, 30, |k, c| {
            (1.0 + ((k + 1) as f64 * 1.7 + (c + 2) as f64 * 0.93).sin().powi(2))
                * (1.0 + 0.05 * k as f64)
        });
        let table = RectangleTable::new(grid.clone(), &values);
        let truth = [1usize, 3, 2, 5];
        let oracle = |e: [usize; 4]| -> Vec<f64> {
            (0..n_pairs)
                .map(|k| {
                    let mut s = 0.0;
                    for j in e[2]..e[3] {
                        for i in e[0]..e[1] {
                            s += values[(k, j * 5 + i)];
                        }
                    }
                    s
                })
                .collect()
        };
        // Prefix sums add in another order than the oracle: equal to rounding, not bit for bit.
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        assert!(close(&table.sum(truth), &oracle(truth)));
        let target: Vec<f64> = oracle(truth).iter().map(|s| 0.3 * s).collect();
        let r = table.scan(
            &vec![1.0; n_pairs],
            &target,
            &vec![1.0; n_pairs],
            (0.0, 10.0),
        );
        assert_eq!(r.region, grid.span(truth));
        assert!(
            (r.amplitude - 0.3).abs() < 1e-12 && r.misfit < 1e-20,
            "{r:?}"
        );
        assert!(close(&table.sum_over(&grid.span(truth)), &oracle(truth)));
        assert_eq!(grid.rectangle_count(), 15.0 * 21.0);
    }

    /// Data that ask for a negative change where only positive ones are allowed: the best is
    /// "no change" and no rectangle is its image (all 315 tied at zero amplitude, and every
    /// one was carried on as an image: the soft-edge set's 30 s loss scans).
    #[test]
    fn regression_no_change_has_no_images() {
        let grid = CellGrid {
            x_m: (0..=5).map(|i| 0.4 * i as f64).collect(),
            y_m: (0..=6).map(|j| 0.5 * j as f64).collect(),
        };
        let values = Mat::from_fn(4, 30, |k, c| 1.0 + ((k + c) as f64).sin().powi(2));
        let table = RectangleTable::new(grid, &values);
        let target = vec![-1.0; 4];
        let r = table.scan_with(&[1.0; 4], &target, &[1.0; 4], (0.0, 10.0), Some(1e9));
        assert_eq!(r.amplitude, 0.0);
        assert!(r.images.is_empty(), "{} images", r.images.len());
        assert!(r.alternatives.is_empty(), "{:?}", r.alternatives);
    }

    #[test]
    fn cells_group_elements_on_a_fine_mesh() {
        let mut model = Model::reference_plate();
        model.mesh.nx = 96;
        model.mesh.ny = 144;
        let g = CellGrid::of(&model);
        assert_eq!((g.nx(), g.ny()), (48, 48));
        assert!((g.x_m[1] - 2.0 / 48.0).abs() < 1e-12);
        assert!((g.y_m[1] - 3.0 * 3.0 / 144.0).abs() < 1e-12);
        assert_eq!(
            CellGrid::of(&Model::reference_plate()).cells().len(),
            32 * 48
        );
    }
}

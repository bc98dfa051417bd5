//! `boundary_compliance`: an edge held by springs of finite stiffness k per metre — a pinned
//! edge that gives, or a free edge that is held. A soft support lowers every mode that moves
//! the edge, by up to several percent, and, storing energy without loss, lowers the modes'
//! damping too: D_k ≈ ½ g U_plate / (U_plate + U_spring). Both channels of evidence see it.
//!
//! The frequencies are not linear in k (from pinned at k → ∞ to free at k = 0), so each edge is
//! solved at both limits and the model is reduced to the union of the two mode sets
//! (M-orthonormalised): K̂(k) = K̂_rest + k K̂_edge. In that basis every k costs one small dense
//! eigen-solve, so k is searched on a log grid and refined, per edge. The reduced solution is
//! checked against re-solving the full model (tests/suite/diagnose_boundary.rs). Each mode of the
//! reduced model is paired with the measured modes by shape, like the model's own; a mode's
//! damping comes from its strain-energy shares (modal strain energy), and the nominal model is
//! solved in the same basis so that the basis's own error cancels.

use faer::linalg::solvers::Solve;
use faer::sparse::SparseColMat;
use faer::{Mat, MatRef, Side};

use super::evidence::{pair_modes, ModelPole, ModelView};
use super::hypothesis::Hypothesis;
use super::score::{Candidate, Prediction, Scorer};
use super::workers::parallel_map;
use crate::modal::model_shapes::shape_at;
use crate::modal::Mode;
use crate::sim::assembly::{assemble, dof_embedding, edge_spring_matrix, sensors_at};
use crate::sim::eigen::{lowest_modes, reference_stiffness, sparse_combination, ModeRequest};
use crate::sim::error::SimError;
use crate::sim::model::{Edge, Model, SensorPosition};
use crate::sim::reduced::m_orthonormalise;

/// The "pinned" limit of the basis: a spring this stiff per metre of edge, N/m², holds the
/// edge's modes below 200 Hz to within 0.01 % of pinned on the reference plate.
pub const RIGID_EDGE_STIFFNESS: f64 = 1e12;
/// Searched range of log10 k (k in N/m²).
pub const LOG10_STIFFNESS_RANGE: (f64, f64) = (3.0, 12.0);
/// Shift of the attachment vectors' solve, Hz.
pub const ATTACHMENT_SHIFT_HZ: f64 = 1.0;
/// Load patterns along an edge (cosines with 0 … this − 1 half-waves).
pub const EDGE_LOAD_PATTERNS: usize = 16;
/// Points along the edge the patterns are applied at (finer than any mesh's nodes there).
const EDGE_LOAD_POINTS: usize = 256;
/// Krylov blocks of attachment vectors.
pub const ATTACHMENT_BLOCKS: usize = 2;
/// Step of the coarse log10 k grid.
const LOG10_STEP: f64 = 0.25;

/// A model matrix (symmetric) times the columns of `b`.
fn spmm(a: &SparseColMat<usize, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    crate::sim::spmm::symmetric_times_dense(a, b)
}

/// One edge's spring-supported model, reduced to the modes of both limits.
pub struct EdgeBasis {
    /// The edge.
    pub edge: Edge,
    /// Whether the model pins it.
    pub was_pinned: bool,
    /// The model's own spring stiffness on the edge (∞ for pinned, 0 for free), N/m².
    pub nominal_stiffness: f64,
    k_rest: Mat<f64>,
    k_edge: Mat<f64>,
    loss: Mat<f64>,
    rayleigh: (f64, f64),
    at_sensors: Mat<f64>,
}

/// A solution of the reduced model: per mode, undamped frequency (Hz), damping ratio (modal
/// strain energy) and shape at the sensors.
pub type EdgeModes = Vec<(f64, f64, Vec<f64>)>;

impl EdgeBasis {
    /// Reduces `view`'s model with `edge` released and held by springs. The basis is the
    /// view's own modes (to twice its range; pinned if the model pins the edge, free if it
    /// leaves it free; embedded in the released model's dofs) and the edge's attachment
    /// vectors K⁻¹B (the static response of the released plate to a load at each edge dof) —
    /// a Craig–Bampton basis when the edge was pinned, its dual when it was free — unless
    /// `attachments` holds them already (they depend only on the undamped system). Shapes are
    /// read at `sensors`. Returns the basis and the attachment vectors, for reuse.
    pub fn new(
        view: &ModelView,
        edge: Edge,
        sensors: &[SensorPosition],
        attachments: Option<Mat<f64>>,
    ) -> Result<(Self, Mat<f64>), SimError> {
        let model = &view.model;
        let was_pinned = model.supports.pinned_edges.iter().any(|e| e == edge.name());
        let nominal_stiffness = if was_pinned {
            f64::INFINITY
        } else {
            model
                .edge_springs
                .iter()
                .filter(|s| s.edge == edge.name())
                .map(|s| s.stiffness_per_length)
                .sum()
        };
        let mut free = model.clone();
        free.supports.pinned_edges.retain(|e| e != edge.name());
        free.edge_springs.retain(|s| s.edge != edge.name());
        let sys0 = assemble(&free)?;
        let n = sys0.n_free;
        let unit = edge_spring_matrix(&free, edge, 1.0, n)?;
        let embed = dof_embedding(model, &free, view.system.n_free)?;
        let own = &view.basis.shapes;
        // The view's modes embedded: the released dofs are zero there, and the mass on the
        // others is the same, so they stay M-orthonormal.
        let mut modes = Mat::<f64>::zeros(n, own.ncols());
        for (i, to) in embed.iter().enumerate() {
            if let Some(t) = to {
                for j in 0..own.ncols() {
                    modes[(*t, j)] = own[(i, j)];
                }
            }
        }
        let extra = match attachments {
            Some(m) => m,
            None => {
                let loads = edge_load_patterns(&free, edge, n)?;
                attachment_vectors(&sys0, &loads, modes.as_ref())?
            }
        };
        let basis = Mat::from_fn(n, modes.ncols() + extra.ncols(), |i, j| {
            if j < modes.ncols() {
                modes[(i, j)]
            } else {
                extra[(i, j - modes.ncols())]
            }
        });
        let size = basis.ncols();
        let project = |a: &SparseColMat<usize, f64>| -> Mat<f64> {
            basis.transpose() * spmm(a, basis.as_ref())
        };
        let mut k_rest = Mat::<f64>::zeros(size, size);
        let mut loss = Mat::<f64>::zeros(size, size);
        for t in &sys0.stiffness_terms {
            let p = project(&t.matrix);
            loss += &p * faer::Scale(t.loss_factor);
            k_rest += &p;
        }
        let k_edge = project(&unit);
        let weights = sensors_at(&free, sensors)?;
        let at_sensors = Mat::from_fn(sensors.len(), size, |s, j| {
            weights[s]
                .weights
                .iter()
                .map(|&(d, wt)| wt * basis[(d, j)])
                .sum()
        });
        Ok((
            Self {
                edge,
                was_pinned,
                nominal_stiffness,
                k_rest,
                k_edge,
                loss,
                rayleigh: sys0.rayleigh.unwrap_or((0.0, 0.0)),
                at_sensors,
            },
            extra,
        ))
    }

    /// The modes below `fmax_hz` with springs of `k` N/m² (∞: the rigid limit).
    pub fn modes(&self, k: f64, fmax_hz: f64) -> Result<EdgeModes, SimError> {
        let k = k.min(RIGID_EDGE_STIFFNESS);
        let a = &self.k_rest + &self.k_edge * faer::Scale(k);
        let evd = a
            .self_adjoint_eigen(Side::Lower)
            .map_err(|e| SimError::Eigen(format!("reduced edge model: {e:?}")))?;
        let (s, u) = (evd.S().column_vector(), evd.U());
        let two_pi = 2.0 * std::f64::consts::PI;
        let mut out: EdgeModes = Vec::new();
        for j in 0..s.nrows() {
            let lam = s[j].max(0.0);
            let f = lam.sqrt() / two_pi;
            if f >= fmax_hz {
                continue;
            }
            let q = u.col(j);
            let lq = &self.loss * q;
            let num: f64 = (0..q.nrows()).map(|i| q[i] * lq[i]).sum();
            let omega = two_pi * f;
            let (alpha, beta) = self.rayleigh;
            let d = if lam > 0.0 {
                0.5 * num / lam + alpha / (2.0 * omega) + 0.5 * beta * omega
            } else {
                0.0
            };
            let shape = (0..self.at_sensors.nrows())
                .map(|r| (0..q.nrows()).map(|i| self.at_sensors[(r, i)] * q[i]).sum())
                .collect();
            out.push((f, d, shape));
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(out)
    }
}

/// Line loads along `edge`'s mid-plane line shaped cos(mπs/L), m = 0 … [`EDGE_LOAD_PATTERNS`]
/// − 1 (s along the edge, L its length): what a support exerts on the modes of the range,
/// which have far fewer half-waves along an edge than it has nodes. Columns over the free dofs
/// of `model` (system size `n`).
fn edge_load_patterns(model: &Model, edge: Edge, n: usize) -> Result<Mat<f64>, SimError> {
    let (lx, ly) = (model.plate.lx, model.plate.ly);
    let len = match edge {
        Edge::Y0 | Edge::Y1 => lx,
        Edge::X0 | Edge::X1 => ly,
    };
    let points: Vec<SensorPosition> = (0..=EDGE_LOAD_POINTS)
        .map(|p| {
            let s = len * p as f64 / EDGE_LOAD_POINTS as f64;
            let (x_m, y_m) = match edge {
                Edge::Y0 => (s, 0.0),
                Edge::Y1 => (s, ly),
                Edge::X0 => (0.0, s),
                Edge::X1 => (lx, s),
            };
            SensorPosition {
                id: String::new(),
                x_m,
                y_m,
            }
        })
        .collect();
    let weights = sensors_at(model, &points)?;
    let mut b = Mat::<f64>::zeros(n, EDGE_LOAD_PATTERNS);
    for (p, w) in weights.iter().enumerate() {
        let s = p as f64 / EDGE_LOAD_POINTS as f64;
        for m in 0..EDGE_LOAD_PATTERNS {
            let c = (m as f64 * std::f64::consts::PI * s).cos();
            for &(d, wt) in &w.weights {
                b[(d, m)] += c * wt;
            }
        }
    }
    Ok(b)
}

/// The attachment vectors of a released or held edge, M-orthonormal to `modes` (the view's,
/// embedded) and among themselves: a block Krylov sequence X₁ = (K + σM)⁻¹B, X_{j+1} =
/// (K + σM)⁻¹M X_j, each block orthonormalised against everything before it (twice, as
/// `sim::reduced` does) before the next is formed. B holds the edge's `loads`; K is the
/// reference stiffness and σ = (2π · [`ATTACHMENT_SHIFT_HZ`])², which keeps the solve regular
/// when the released plate is a mechanism (one pinned line left is a hinge). The first block
/// is the static (Craig–Bampton) correction, the next ones carry it into dynamics.
fn attachment_vectors(
    sys: &crate::sim::FeSystem,
    loads: &Mat<f64>,
    modes: MatRef<'_, f64>,
) -> Result<Mat<f64>, SimError> {
    let n = sys.n_free;
    let k = reference_stiffness(sys)?;
    let sigma = (2.0 * std::f64::consts::PI * ATTACHMENT_SHIFT_HZ).powi(2);
    let shifted = sparse_combination(n, &[(1.0, &k), (sigma, &sys.mass)], "K + σM")?;
    let llt = crate::sim::reuse::cholesky(&shifted)
        .map_err(|e| SimError::Eigen(format!("released plate's stiffness: {e:?}")))?;
    let mut basis = modes.to_owned();
    let mut m_basis = spmm(&sys.mass, basis.as_ref());
    let first = basis.ncols();
    let mut x = llt.solve(loads.as_ref());
    for _ in 0..ATTACHMENT_BLOCKS {
        let cand: Vec<Vec<f64>> = (0..x.ncols())
            .map(|j| x.col(j).iter().copied().collect())
            .collect();
        let q = m_orthonormalise(&sys.mass, basis.as_ref(), m_basis.as_ref(), cand)
            .map_err(|e| SimError::Eigen(format!("edge attachment vectors: {e}")))?;
        if q.is_empty() {
            break;
        }
        let block = Mat::from_fn(n, q.len(), |i, j| q[j][i]);
        let m_block = spmm(&sys.mass, block.as_ref());
        x = llt.solve(m_block.as_ref());
        let old = basis.ncols();
        let grown = Mat::from_fn(n, old + q.len(), |i, j| {
            if j < old {
                basis[(i, j)]
            } else {
                block[(i, j - old)]
            }
        });
        let grown_m = Mat::from_fn(n, old + q.len(), |i, j| {
            if j < old {
                m_basis[(i, j)]
            } else {
                m_block[(i, j - old)]
            }
        });
        basis = grown;
        m_basis = grown_m;
    }
    Ok(basis.subcols(first, basis.ncols() - first).to_owned())
}

/// Per scored pair, the partner among `modes` of its measured mode (by shape), as (f, D).
fn partners(measured: &[Mode], scorer: &Scorer, modes: &EdgeModes) -> Vec<Option<(f64, f64)>> {
    let poles: Vec<ModelPole> = modes
        .iter()
        .enumerate()
        .map(|(j, (f, d, shape))| ModelPole {
            mode: j + 1,
            frequency_hz: *f,
            damped_frequency_hz: *f,
            damping_ratio: *d,
            shape: shape.clone(),
        })
        .collect();
    let (pairs, _, _) = pair_modes(measured, &poles);
    scorer
        .pairs
        .iter()
        .map(|sp| {
            pairs
                .iter()
                .find(|p| p.measured == sp.measured)
                .map(|p| (poles[p.model].frequency_hz, poles[p.model].damping_ratio))
        })
        .collect()
}

/// What springs of `k` predict against the nominal support, both solved in `basis`.
fn predict(
    measured: &[Mode],
    scorer: &Scorer,
    basis: &EdgeBasis,
    nominal: &[Option<(f64, f64)>],
    k: f64,
    fmax_hz: f64,
) -> Result<Prediction, SimError> {
    let hyp = partners(measured, scorer, &basis.modes(k, fmax_hz)?);
    let mut p = Prediction::none(scorer.n());
    for (i, (h, n)) in hyp.iter().zip(nominal).enumerate() {
        if let (Some(h), Some(n)) = (h, n) {
            p.log_frequency[i] = (h.0 / n.0).ln();
            p.damping[i] = h.1 - n.1;
        }
    }
    Ok(p)
}

/// The attachment vectors of each edge, kept between rounds of a diagnosis while the undamped
/// system stays the same (findings that change the loss only).
#[derive(Default)]
pub struct EdgeCache {
    modes: Vec<(Edge, Mat<f64>)>,
}

impl EdgeCache {
    /// Forgets everything (the undamped system changed).
    pub fn clear(&mut self) {
        self.modes.clear();
    }
}

/// The best spring support for each edge of the plate, the best of them as a candidate.
pub fn scan_boundary(
    measured: &[Mode],
    scorer: &Scorer,
    view: &ModelView,
    sensors: &[SensorPosition],
    cache: &mut EdgeCache,
) -> Result<Option<Candidate>, SimError> {
    let fmax = view.fmax_hz;
    let edges = [Edge::X0, Edge::X1, Edge::Y0, Edge::Y1];
    let jobs: Vec<(Edge, Option<Mat<f64>>)> = edges
        .iter()
        .map(|&edge| {
            let cached = cache
                .modes
                .iter()
                .position(|(e, _)| *e == edge)
                .map(|i| cache.modes.swap_remove(i).1);
            (edge, cached)
        })
        .collect();
    let results = parallel_map(jobs, |(edge, cached)| {
        let (basis, other) = EdgeBasis::new(view, edge, sensors, cached)?;
        let best = best_stiffness(measured, scorer, &basis, fmax, edges.len())?;
        Ok((edge, other, best))
    })?;
    let mut best: Option<Candidate> = None;
    for (edge, other, candidate) in results {
        cache.modes.push((edge, other));
        if best.as_ref().is_none_or(|c| candidate.bic < c.bic) {
            best = Some(candidate);
        }
    }
    Ok(best)
}

/// The spring stiffness of `basis`'s edge that scores best: a log grid, then golden-section
/// refinement within one grid step of the grid's best.
fn best_stiffness(
    measured: &[Mode],
    scorer: &Scorer,
    basis: &EdgeBasis,
    fmax: f64,
    locations: usize,
) -> Result<Candidate, SimError> {
    let nominal = partners(
        measured,
        scorer,
        &basis.modes(basis.nominal_stiffness, fmax)?,
    );
    let score = |log_k: f64| -> Result<(f64, Prediction), SimError> {
        let p = predict(measured, scorer, basis, &nominal, 10f64.powf(log_k), fmax)?;
        Ok((scorer.bic(&p, 1.0, locations as f64), p))
    };
    let (lo, hi) = LOG10_STIFFNESS_RANGE;
    let steps = ((hi - lo) / LOG10_STEP).round() as usize;
    let mut grid_best = (f64::INFINITY, lo);
    for s in 0..=steps {
        let log_k = lo + s as f64 * LOG10_STEP;
        let (bic, _) = score(log_k)?;
        if bic < grid_best.0 {
            grid_best = (bic, log_k);
        }
    }
    let (mut a, mut b) = (grid_best.1 - LOG10_STEP, grid_best.1 + LOG10_STEP);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..12 {
        let (c, d) = (b - phi * (b - a), a + phi * (b - a));
        if score(c)?.0 < score(d)?.0 {
            b = d;
        } else {
            a = c;
        }
    }
    let refined = 0.5 * (a + b);
    let (bic, prediction) = score(refined)?;
    let (prediction, log_k) = if bic <= grid_best.0 {
        (prediction, refined)
    } else {
        (score(grid_best.1)?.1, grid_best.1)
    };
    Ok(scorer.candidate(
        Hypothesis::BoundaryCompliance {
            edge: basis.edge,
            stiffness_per_length: 10f64.powf(log_k),
            was_pinned: basis.was_pinned,
        },
        prediction,
        1.0,
        locations as f64,
    ))
}

/// The modes of `model` below `fmax_hz` at `sensors`, solved in full (the oracle of
/// [`EdgeBasis::modes`]): (undamped frequency, shape).
pub fn full_modes(
    model: &Model,
    fmax_hz: f64,
    sensors: &[SensorPosition],
) -> Result<Vec<(f64, Vec<f64>)>, SimError> {
    let sys = assemble(model)?;
    let modes = lowest_modes(&sys, ModeRequest::BelowHz(fmax_hz))?;
    let at = sensors_at(model, sensors)?;
    Ok((0..modes.frequencies_hz.len())
        .map(|i| {
            (
                modes.frequencies_hz[i],
                shape_at(&at, modes.shapes.as_ref(), i),
            )
        })
        .collect())
}

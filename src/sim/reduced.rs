//! The fast FRF method: Ritz–Galerkin projection onto the undamped modes plus static residual
//! vectors, with the exact regional damping and SLS patch moduli in that basis.
//!
//! Basis V = [Φ | R], M-orthonormalised, where Φ are the undamped modes (mass-normalised, up to
//! a cut-off well above the analysed fmax) and R holds
//!
//! - the static residual K₀⁻¹ f (the quasi-static contribution of every truncated mode), and
//! - for each region r whose stiffness factor differs from the first region's (a patch with
//!   another loss factor, or an SLS region): K₀⁻¹ K_r K₀⁻¹ f and K₀⁻¹ K_r φ_i for the modes
//!   below the analysed fmax — the static (first-order) part of how the region's different
//!   complex, possibly frequency-dependent stiffness couples the kept modes to truncated ones.
//!
//! With modes only (no residual vectors) a damped patch misses ~65 % per band on a lattice test (see
//! tests/suite/sim_frf.rs); with them fast vs direct is < 1 % per 50 Hz band.
//!
//! M, every K_r and C are projected once (dense m × m). Per frequency the small complex system
//! (Σ_r s_r(ω) K̂_r + jω Ĉ − ω² M̂) q = Vᵀ f is solved and mapped to the sensors with (S V) q.
//!
//! When no region is viscoelastic and there is no Rayleigh damping, the reduced dynamic stiffness
//! is K̂_c − ω² M̂ with a constant complex K̂_c: it is diagonalised once (complex eigenvectors)
//! and every frequency costs O(m) per sensor. Otherwise (SLS regions, Rayleigh damping) the
//! state-space form linear in s is diagonalised once ([`super::state_space`]), with a dense LU
//! per frequency (frequencies split over two threads) as the fallback and the oracle.

use faer::c64;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::sparse::SparseColMat;
use faer::{Accum, Mat, MatRef, Par, Side};

pub(crate) use super::basis::{m_orthonormalise, m_orthonormalise_columns};
use super::eigen::{reference_stiffness, sparse_combination};
use super::factored::{FactoredFrf, FrfSolve};
use super::frf::{parallel_rows, validate_frequencies, validate_system, Frf, FrfError};
use super::system::FeSystem;
use std::sync::Arc;

/// How the reduced system is solved per frequency.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ReducedSolve {
    /// Diagonalise when possible (no SLS region, no Rayleigh damping); else the state-space
    /// eigen-solve ([`super::state_space`]) when it costs less than an LU per frequency and
    /// reproduces it at check frequencies; else LU per frequency.
    #[default]
    Auto,
    /// Always a dense complex LU per frequency (the general path, and the oracle of the
    /// others).
    PerFrequencyLu,
    /// Always the state-space eigen-solve; an error if it does not reproduce the LU at the
    /// check frequencies (for tests and benches of that path).
    StateSpace,
}

/// Which residual vectors enrich the modal basis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BasisOptions {
    /// Add the static residual K₀⁻¹ f.
    pub static_residual: bool,
    /// Add K₀⁻¹ K_r K₀⁻¹ f for every perturbing region r (see [`perturbing_regions`]).
    pub region_residuals: bool,
    /// For every perturbing region r, add K₀⁻¹ K_r φ_i for the modes below this frequency, Hz:
    /// the static part of how the region's different (complex, possibly frequency-dependent)
    /// stiffness factor changes those mode shapes — first-order perturbation through the
    /// truncated modes. Without them a damped or viscoelastic patch couples the kept modes to
    /// truncated ones that the basis cannot represent.
    pub mode_residuals_below_hz: f64,
}

impl Default for BasisOptions {
    fn default() -> Self {
        Self {
            static_residual: true,
            region_residuals: true,
            mode_residuals_below_hz: f64::INFINITY,
        }
    }
}

/// Checks a mode set against the system: `shapes` is n_free × m, one frequency per column.
pub fn validate_modes(
    sys: &FeSystem,
    frequencies_hz: &[f64],
    shapes: MatRef<'_, f64>,
) -> Result<(), FrfError> {
    if shapes.nrows() != sys.n_free || shapes.ncols() != frequencies_hz.len() {
        return Err(FrfError::Dimension {
            what: "mode shapes".into(),
            expected: format!("{} × {} (n_free × modes)", sys.n_free, frequencies_hz.len()),
            got: format!("{} × {}", shapes.nrows(), shapes.ncols()),
        });
    }
    for (i, f) in frequencies_hz.iter().enumerate() {
        if !f.is_finite() || *f < 0.0 {
            return Err(FrfError::Invalid {
                what: format!("mode {} frequency", i + 1),
                message: format!("expected finite ≥ 0 Hz, got {f}"),
            });
        }
    }
    Ok(())
}

/// The regions that perturb the first one: with K(ω) = s₁(ω) K₀ + Σ_{r≥2} (s_r − s₁) K_r, a
/// region with the same loss factor as region 0 and no SLS (while region 0 has none either)
/// contributes nothing, and region 0 itself is redundant (K₀⁻¹ K₀ x = x).
pub fn perturbing_regions(sys: &FeSystem) -> Vec<usize> {
    let Some(first) = sys.stiffness_terms.first() else {
        return Vec::new();
    };
    (1..sys.stiffness_terms.len())
        .filter(|&r| {
            let t = &sys.stiffness_terms[r];
            t.sls.is_some() || first.sls.is_some() || t.loss_factor != first.loss_factor
        })
        .collect()
}

/// Sum of every stiffness term, K₀ (each region at its reference modulus).
pub(crate) fn k0(sys: &FeSystem) -> Result<SparseColMat<usize, f64>, FrfError> {
    reference_stiffness(sys).map_err(|e| FrfError::Factorisation {
        what: "K0 assembly".into(),
        message: e.to_string(),
    })
}

/// Sparse × dense product of a symmetric model matrix, real ([`super::spmm::symmetric_times_dense`]).
pub(super) fn spmm(a: &SparseColMat<usize, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    super::spmm::symmetric_times_dense(a, b)
}

/// Static solve with K₀ (sparse Cholesky). If K₀ is singular (a free structure) the shifted
/// K₀ + σM with σ = (2π · 1 Hz)² is used instead: the vectors are still good Ritz vectors.
pub(super) fn static_solver(sys: &FeSystem) -> Result<Arc<Llt<usize, f64>>, FrfError> {
    let k = k0(sys)?;
    match super::reuse::cholesky_reused(&k) {
        Ok(l) => Ok(l),
        Err(_) => {
            let sigma = (2.0 * std::f64::consts::PI).powi(2);
            let ks = sparse_combination(sys.n_free, &[(1.0, &k), (sigma, &sys.mass)], "K0 + σM")
                .map_err(|e| FrfError::Factorisation {
                    what: "K0 + σM assembly".into(),
                    message: e.to_string(),
                })?;
            super::reuse::cholesky_reused(&ks).map_err(|e| FrfError::Factorisation {
                what: "K0 (and K0 + σM) Cholesky for the static residual".into(),
                message: format!("{e:?}"),
            })
        }
    }
}

/// The static displacement K₀⁻¹ f over the free dofs (K₀ + σM for a free structure, see
/// `static_solver`): with the modes' own static part removed, the residual flexibility of the
/// truncated modes.
pub fn static_displacement(sys: &FeSystem) -> Result<Vec<f64>, FrfError> {
    let llt = static_solver(sys)?;
    let f = Mat::from_fn(sys.n_free, 1, |i, _| sys.force[i]);
    Ok(llt.solve(f.as_ref()).col(0).iter().copied().collect())
}

/// A copy of a stiffness term without its matrix (a 0 × 0 placeholder): only its frequency
/// factor s_r(ω) is needed once the matrix has been projected.
pub(crate) fn factor_only(
    t: &super::system::StiffnessTerm,
) -> Result<super::system::StiffnessTerm, FrfError> {
    Ok(super::system::StiffnessTerm {
        name: t.name.clone(),
        matrix: SparseColMat::try_new_from_triplets(0, 0, &[]).map_err(|e| {
            FrfError::Factorisation {
                what: "empty placeholder matrix".into(),
                message: format!("{e:?}"),
            }
        })?,
        loss_factor: t.loss_factor,
        sls: t.sls,
        reference_modulus_pa: t.reference_modulus_pa,
    })
}

/// Solves A q = b by a dense partial-pivoting LU in place, single-threaded (the callers already
/// run one frequency per thread; nested parallelism would oversubscribe the cores).
pub(crate) fn lu_solve_sequential(a: &mut Mat<c64>, b: MatRef<'_, c64>) -> Vec<c64> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::lu::partial_pivoting::{factor, solve};
    let m = a.nrows();
    let mut perm = vec![0usize; m];
    let mut perm_inv = vec![0usize; m];
    let mut mem = MemBuffer::new(
        factor::lu_in_place_scratch::<usize, c64>(m, m, Par::Seq, Default::default())
            .or(solve::solve_in_place_scratch::<usize, c64>(m, 1, Par::Seq)),
    );
    let (_, p) = factor::lu_in_place(
        a.as_mut(),
        &mut perm,
        &mut perm_inv,
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    );
    let mut x = b.to_owned();
    solve::solve_in_place_with_conj(
        a.as_ref(),
        a.as_ref(),
        p,
        faer::Conj::No,
        x.as_mut(),
        Par::Seq,
        MemStack::new(&mut mem),
    );
    x.col(0).iter().copied().collect()
}

/// Modal responses (frequency × basis vector) and sensor weights (sensor × basis vector).
pub(super) type FrfFactors = (Mat<c64>, Mat<c64>);

/// The reduced (projected) model: everything the per-frequency solve needs.
pub struct ReducedModel {
    /// Basis size m (modes + residual vectors).
    pub size: usize,
    /// How many columns of the basis are modes (the rest are residual vectors).
    pub n_modes: usize,
    pub(super) m_hat: Mat<f64>,
    pub(super) k_hat: Vec<Mat<f64>>,
    pub(super) factors: Vec<super::system::StiffnessTerm>,
    pub(super) rayleigh: (f64, f64),
    pub(super) b: Vec<f64>,
    pub(super) sv: Mat<f64>,
    sensor_ids: Vec<String>,
}

impl ReducedModel {
    /// Projects `sys` onto [modes | residual vectors]. `shapes` are mass-normalised undamped
    /// modes (n_free × m), `frequencies_hz` their frequencies.
    pub fn build(
        sys: &FeSystem,
        frequencies_hz: &[f64],
        shapes: MatRef<'_, f64>,
        opts: BasisOptions,
    ) -> Result<Self, FrfError> {
        validate_system(sys)?;
        validate_modes(sys, frequencies_hz, shapes)?;
        let n = sys.n_free;
        let m_phi = spmm(&sys.mass, shapes);
        let mut cand = Vec::new();
        let regions = perturbing_regions(sys);
        if opts.static_residual || !regions.is_empty() {
            let llt = static_solver(sys)?;
            let f = Mat::from_fn(n, 1, |i, _| sys.force[i]);
            let r0 = llt.solve(f.as_ref());
            if opts.static_residual {
                cand.push(r0.col(0).iter().copied().collect::<Vec<f64>>());
            }
            let sel: Vec<usize> = (0..shapes.ncols())
                .filter(|&i| frequencies_hz[i] <= opts.mode_residuals_below_hz)
                .collect();
            for &r in &regions {
                let t = &sys.stiffness_terms[r];
                if opts.region_residuals {
                    let v = llt.solve(spmm(&t.matrix, r0.as_ref()).as_ref());
                    cand.push(v.col(0).iter().copied().collect());
                }
                if !sel.is_empty() {
                    let phi = Mat::from_fn(n, sel.len(), |i, j| shapes[(i, sel[j])]);
                    let v = llt.solve(spmm(&t.matrix, phi.as_ref()).as_ref());
                    for j in 0..sel.len() {
                        cand.push(v.col(j).iter().copied().collect());
                    }
                }
            }
        }
        let extra = m_orthonormalise(&sys.mass, shapes, m_phi.as_ref(), cand)?;
        let m = shapes.ncols() + extra.len();
        let v = Mat::from_fn(n, m, |i, j| {
            if j < shapes.ncols() {
                shapes[(i, j)]
            } else {
                extra[j - shapes.ncols()][i]
            }
        });
        Self::from_basis(sys, v, shapes.ncols())
    }

    /// Projects `sys` onto the M-orthonormal basis `v` (n_free × m) whose first `n_modes`
    /// columns are modes: M̂, every K̂_r, the load and the sensor rows.
    pub(super) fn from_basis(
        sys: &FeSystem,
        v: Mat<f64>,
        n_modes: usize,
    ) -> Result<Self, FrfError> {
        let (n, m) = (sys.n_free, v.ncols());
        let par = faer::get_global_parallelism();
        let project = |a: &SparseColMat<usize, f64>| -> Mat<f64> {
            let av = spmm(a, v.as_ref());
            let mut out = Mat::<f64>::zeros(m, m);
            faer::linalg::matmul::matmul(
                out.as_mut(),
                Accum::Replace,
                v.transpose(),
                av.as_ref(),
                1.0,
                par,
            );
            out
        };
        let m_hat = project(&sys.mass);
        let k_hat: Vec<Mat<f64>> = sys
            .stiffness_terms
            .iter()
            .map(|t| project(&t.matrix))
            .collect();
        let b: Vec<f64> = (0..m)
            .map(|j| (0..n).map(|i| v[(i, j)] * sys.force[i]).sum())
            .collect();
        let sv = Mat::from_fn(sys.sensors.len(), m, |s, j| {
            sys.sensors[s]
                .weights
                .iter()
                .map(|&(d, w)| w * v[(d, j)])
                .sum()
        });
        Ok(Self {
            size: m,
            n_modes,
            m_hat,
            k_hat,
            factors: sys
                .stiffness_terms
                .iter()
                .map(factor_only)
                .collect::<Result<_, _>>()?,
            rayleigh: sys.rayleigh.unwrap_or((0.0, 0.0)),
            b,
            sv,
            sensor_ids: sys.sensors.iter().map(|s| s.id.clone()).collect(),
        })
    }

    /// Whether one eigen-solve of the state matrix (size ≤ 3m, ~10 N³ operations) costs less
    /// than a dense LU (~m³) at each of `n_frequencies`.
    fn state_space_pays(&self, n_frequencies: usize) -> bool {
        let m = self.size as f64;
        let n = if self.factors.iter().any(|t| t.sls.is_some()) {
            3.0 * m
        } else {
            2.0 * m
        };
        10.0 * n.powi(3) < n_frequencies as f64 * m.powi(3)
    }

    fn frequency_independent(&self) -> bool {
        self.factors.iter().all(|t| t.sls.is_none()) && self.rayleigh == (0.0, 0.0)
    }

    /// Reduced dynamic stiffness at ω.
    fn dynamic_stiffness(&self, omega: f64) -> Mat<c64> {
        let m = self.size;
        let (alpha, beta) = self.rayleigh;
        let mut a = Mat::<c64>::from_fn(m, m, |i, j| {
            c64::new(-omega * omega, omega * alpha) * self.m_hat[(i, j)]
        });
        for (t, k) in self.factors.iter().zip(&self.k_hat) {
            let (sr, si) = t.factor(omega);
            let s = c64::new(sr, si + omega * beta);
            for j in 0..m {
                for i in 0..m {
                    a[(i, j)] += s * k[(i, j)];
                }
            }
        }
        a
    }

    /// Reduced coordinates q(ω) for every frequency (m × n_freq), by LU per frequency.
    pub(super) fn q_by_lu(&self, freqs_hz: &[f64]) -> Result<Mat<c64>, FrfError> {
        let b = Mat::<c64>::from_fn(self.size, 1, |i, _| c64::new(self.b[i], 0.0));
        let rows = parallel_rows(freqs_hz, 2, |f| {
            let mut a = self.dynamic_stiffness(2.0 * std::f64::consts::PI * f);
            let q = lu_solve_sequential(&mut a, b.as_ref());
            if q.iter().any(|z| !z.re.is_finite() || !z.im.is_finite()) {
                return Err(FrfError::Factorisation {
                    what: format!("reduced dynamic stiffness at {f} Hz"),
                    message: "singular (non-finite solution)".into(),
                });
            }
            Ok(q)
        })?;
        Ok(Mat::from_fn(self.size, freqs_hz.len(), |i, k| rows[k][i]))
    }

    /// Receptance at every sensor and frequency.
    pub fn frf(&self, freqs_hz: &[f64], how: ReducedSolve) -> Result<Frf, FrfError> {
        Ok(self.factored_frf(freqs_hz, how)?.to_frf())
    }

    /// Receptance as modal responses × sensor weights, for streaming many sensors.
    pub fn factored_frf(
        &self,
        freqs_hz: &[f64],
        how: ReducedSolve,
    ) -> Result<FactoredFrf, FrfError> {
        validate_frequencies(freqs_hz)?;
        let diagonalised = match how {
            ReducedSolve::Auto if self.frequency_independent() => self
                .frf_diagonalised(freqs_hz)?
                .map(|parts| (parts, FrfSolve::Modal)),
            ReducedSolve::Auto if self.state_space_pays(freqs_hz.len()) => {
                self.frf_state_space(freqs_hz)?
            }
            ReducedSolve::StateSpace => {
                Some(
                    self.frf_state_space(freqs_hz)?
                        .ok_or_else(|| FrfError::Factorisation {
                            what: "state-space eigen-decomposition".into(),
                            message: "it does not reproduce the dense LU at the check frequencies"
                                .into(),
                        })?,
                )
            }
            _ => None,
        };
        let ((modal, weights), solve) = match diagonalised {
            Some(done) => done,
            None => (self.frf_lu(freqs_hz)?, FrfSolve::PerFrequencyLu),
        };
        Ok(FactoredFrf {
            frequencies_hz: freqs_hz.to_vec(),
            sensor_ids: self.sensor_ids.clone(),
            modal,
            weights,
            solve,
        })
    }

    /// Reduced coordinates by LU per frequency (n_freq × m) and the sensor rows of the basis.
    fn frf_lu(&self, freqs_hz: &[f64]) -> Result<FrfFactors, FrfError> {
        let q = self.q_by_lu(freqs_hz)?;
        let svc = Mat::<c64>::from_fn(self.sv.nrows(), self.sv.ncols(), |i, j| {
            c64::new(self.sv[(i, j)], 0.0)
        });
        Ok((q.transpose().to_owned(), svc))
    }

    /// K̂_c = Σ_r (1 + j g_r) K̂_r, the reduced stiffness of a frequency-independent model.
    pub(super) fn constant_stiffness(&self) -> Mat<c64> {
        let m = self.size;
        let mut kc = Mat::<c64>::zeros(m, m);
        for (t, k) in self.factors.iter().zip(&self.k_hat) {
            let (sr, si) = t.factor(0.0);
            let s = c64::new(sr, si);
            for j in 0..m {
                for i in 0..m {
                    kc[(i, j)] += s * k[(i, j)];
                }
            }
        }
        kc
    }

    /// The constant-K̂_c path: K̂_c − ω²M̂ with M̂ = L Lᵀ; L⁻¹ K̂_c L⁻ᵀ = X Λ X⁻¹, so
    /// q(ω) = L⁻ᵀ X (Λ − ω²)⁻¹ X⁻¹ L⁻¹ b, returned as (Λ − ω²)⁻¹ X⁻¹ L⁻¹ b per frequency and
    /// the sensor rows S V L⁻ᵀ X. Returns `None` when the eigenvectors are too
    /// ill-conditioned to trust (the caller then falls back to LU per frequency).
    fn frf_diagonalised(&self, freqs_hz: &[f64]) -> Result<Option<FrfFactors>, FrfError> {
        let m = self.size;
        let llt = match self.m_hat.llt(Side::Lower) {
            Ok(l) => l,
            Err(_) => return Ok(None),
        };
        let l = llt.L();
        let kc = self.constant_stiffness();
        let lc = Mat::<c64>::from_fn(m, m, |i, j| c64::new(l[(i, j)], 0.0));
        // T = L⁻¹ K̂_c L⁻ᵀ
        let lc_lu = lc.partial_piv_lu();
        let y = lc_lu.solve(kc.as_ref()); // L⁻¹ K̂_c
        let t = lc_lu.solve(y.transpose()).transpose().to_owned(); // (L⁻¹ (L⁻¹K̂_c)ᵀ)ᵀ
        let evd = match t.eigen() {
            Ok(e) => e,
            Err(_) => return Ok(None),
        };
        let x = evd.U().to_owned();
        let lam: Vec<c64> = evd.S().column_vector().iter().copied().collect();
        // Trust check: the eigen-residual and the solve of X must be accurate.
        let tx = &t * &x;
        let mut res: f64 = 0.0;
        let mut scale: f64 = 0.0;
        for j in 0..m {
            for i in 0..m {
                res = res.max((tx[(i, j)] - x[(i, j)] * lam[j]).norm());
                scale = scale.max(t[(i, j)].norm());
            }
        }
        let x_lu = x.partial_piv_lu();
        let bc = Mat::<c64>::from_fn(m, 1, |i, _| c64::new(self.b[i], 0.0));
        let y = x_lu.solve(lc_lu.solve(bc.as_ref()));
        let back = &x * &y;
        let lb = lc_lu.solve(bc.as_ref());
        let mut yres: f64 = 0.0;
        let mut ynorm: f64 = 0.0;
        for i in 0..m {
            yres = yres.max((back[(i, 0)] - lb[(i, 0)]).norm());
            ynorm = ynorm.max(lb[(i, 0)].norm());
        }
        let trusted = res <= 1e-9 * scale && yres <= 1e-9 * ynorm; // false for NaN too
        if !trusted {
            return Ok(None);
        }
        // P = (S V) L⁻ᵀ X  (n_sensors × m)
        let svc = Mat::<c64>::from_fn(self.sv.nrows(), m, |i, j| c64::new(self.sv[(i, j)], 0.0));
        let lt_inv_x = lc_lu.solve_transpose(x.as_ref());
        let p = &svc * &lt_inv_x;
        let r = Mat::<c64>::from_fn(freqs_hz.len(), m, |k, i| {
            let w = 2.0 * std::f64::consts::PI * freqs_hz[k];
            y[(i, 0)] / (lam[i] - c64::new(w * w, 0.0))
        });
        Ok(Some((r, p)))
    }
}

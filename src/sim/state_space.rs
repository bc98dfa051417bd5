//! The reduced model in state-space form, linear in s: one eigen-solve replaces the dense LU
//! per frequency for models whose damping depends on frequency (viscoelastic regions, Rayleigh).
//!
//! A standard linear solid region r adds c_r·sτ_r/(1 + sτ_r)·K̂_r to the relaxed stiffness K̂_c
//! (c_r = (1 + j g_r) e/e_ref, τ_r = η/e). With K̂_r = U_r Σ_r U_rᵀ (its numerical range,
//! [`RANK_TOLERANCE`]) and internal variables y_r = sτ_r/(1 + sτ_r)·U_rᵀ q, i.e.
//! ẏ_r = U_rᵀ q̇ − y_r/τ_r, the equation s²M̂q + sĈq + K̂_c q + Σ_r c_r U_r Σ_r y_r = b is
//! first-order in the state x = (q, q̇, y_1, …):
//!
//! ```text
//! A = [[ 0,          I,          0            ],
//!      [ −M̂⁻¹K̂_c,   −M̂⁻¹Ĉ,     −M̂⁻¹c_r U_rΣ_r ],
//!      [ 0,          U_rᵀ,       −I/τ_r       ]]
//! ```
//!
//! of size N = 2m + Σ rank K̂_r (only the range of K̂_r needs internal variables; the full
//! z_r = sτ/(1 + sτ) q would add m per region). With A = X Λ X⁻¹ and g = X⁻¹(0, M̂⁻¹b, 0),
//! q(jω) = Σ_k X_q,k g_k / (jω − λ_k): the resolvent, exact, evaluated for all frequencies as
//! one matrix product. It is trusted only if it reproduces the dense LU at a few frequencies
//! ([`TRUST_FREQUENCIES`], [`TRUST_TOLERANCE`]); otherwise the caller falls back to the LU.
//!
//! The displacement-like states are scaled by s₀ = 2π × the top frequency (x = (s₀q, q̇, s₀y),
//! a similarity: the eigenvalues do not change). Unscaled, the velocities are ~s₀ times the
//! displacements, the eigenvector matrix is that much worse conditioned, and on the soft
//! polymer patch (1104 states) the responses matched the LU only to 2e-6: the check rejected
//! them and every frequency went to the LU after the eigen-solve had been paid. Scaled, they
//! match to 1e-10.

use faer::c64;
use faer::linalg::solvers::Solve;
use faer::{Accum, Mat, Side};

use super::factored::FrfSolve;
use super::frf::FrfError;
use super::reduced::{FrfFactors, ReducedModel};

/// Eigenvalues of K̂_r below this fraction of its largest are outside its range (no internal
/// variable): the coupling they would carry is below round-off of the largest.
pub const RANK_TOLERANCE: f64 = 1e-12;

/// Frequencies at which the state-space responses are checked against the dense LU.
pub const TRUST_FREQUENCIES: usize = 7;

/// Largest relative difference ‖q_ss − q_lu‖/‖q_lu‖ at a check frequency for the state-space
/// responses to be used (an ill-conditioned eigenvector matrix shows up far above it).
pub const TRUST_TOLERANCE: f64 = 1e-6;

/// Frequencies per block of the resolvent product (bounds its scratch memory).
const FREQUENCY_BLOCK: usize = 1024;

/// The state-space form of a reduced model: ẋ = A x + B u.
pub struct StateForm {
    /// The state matrix A, N × N.
    pub matrix: Mat<c64>,
    /// The input B = (0, M̂⁻¹b, 0), N × 1.
    pub input: Mat<c64>,
    /// Number of generalised coordinates m (the first m states are q).
    pub coordinates: usize,
}

/// The state scale s₀ for responses at `freqs_hz`: the top of the band (at least 1 rad/s).
fn state_scale_rad_s(freqs_hz: &[f64]) -> f64 {
    let top = freqs_hz.iter().fold(0.0f64, |a, &f| a.max(f));
    (2.0 * std::f64::consts::PI * top).max(1.0)
}

/// `a` as complex.
fn complex(a: &Mat<f64>) -> Mat<c64> {
    Mat::from_fn(a.nrows(), a.ncols(), |i, j| c64::new(a[(i, j)], 0.0))
}

/// An SLS region's internal-variable block: τ, U_r (m × k) and c_r U_r Σ_r (m × k).
struct Relaxation {
    tau_s: f64,
    range: Mat<f64>,
    coupling: Mat<c64>,
}

impl ReducedModel {
    /// The internal-variable blocks of the SLS regions (see the module documentation).
    fn relaxations(&self) -> Result<Vec<Relaxation>, FrfError> {
        let mut out = Vec::new();
        for (t, k) in self.factors.iter().zip(&self.k_hat) {
            let Some(sls) = t.sls else { continue };
            if !(sls.e > 0.0 && sls.eta > 0.0 && t.reference_modulus_pa > 0.0) {
                return Err(FrfError::Invalid {
                    what: format!("viscoelastic region {}", t.name),
                    message: format!(
                        "expected e > 0, eta > 0 and a positive reference modulus, got e = {}, \
                         eta = {}, reference {}",
                        sls.e, sls.eta, t.reference_modulus_pa
                    ),
                });
            }
            let sym = Mat::from_fn(k.nrows(), k.ncols(), |i, j| 0.5 * (k[(i, j)] + k[(j, i)]));
            let evd = sym
                .self_adjoint_eigen(Side::Lower)
                .map_err(|e| FrfError::Factorisation {
                    what: format!("range of the reduced stiffness of {}", t.name),
                    message: format!("{e:?}"),
                })?;
            let lam: Vec<f64> = evd.S().column_vector().iter().copied().collect();
            let largest = lam.iter().fold(0.0f64, |a, l| a.max(l.abs()));
            let keep: Vec<usize> = (0..lam.len())
                .filter(|&i| lam[i].abs() > RANK_TOLERANCE * largest)
                .collect();
            let u = evd.U();
            let range = Mat::from_fn(k.nrows(), keep.len(), |i, c| u[(i, keep[c])]);
            let coef = c64::new(1.0, t.loss_factor) * (sls.e / t.reference_modulus_pa);
            let coupling = Mat::from_fn(k.nrows(), keep.len(), |i, c| {
                coef * (range[(i, c)] * lam[keep[c]])
            });
            out.push(Relaxation {
                tau_s: sls.eta / sls.e,
                range,
                coupling,
            });
        }
        Ok(out)
    }

    /// The state-space form of s²M̂ + sĈ + K̂(s) (see the module documentation), with the
    /// displacement-like states scaled by `scale_rad_s` (x = (s₀q, q̇, s₀y)): a similarity
    /// that leaves the eigenvalues alone and balances the blocks for frequencies near s₀.
    pub fn state_form_scaled(&self, scale_rad_s: f64) -> Result<StateForm, FrfError> {
        let s0 = scale_rad_s;
        let m = self.size;
        let (alpha, beta) = self.rayleigh;
        let mut c = Mat::<c64>::from_fn(m, m, |i, j| c64::new(alpha * self.m_hat[(i, j)], 0.0));
        if beta != 0.0 {
            for k in &self.k_hat {
                c += Mat::<c64>::from_fn(m, m, |i, j| c64::new(beta * k[(i, j)], 0.0));
            }
        }
        let lu = complex(&self.m_hat).partial_piv_lu();
        let mk = lu.solve(self.constant_stiffness());
        let mc = lu.solve(c);
        let relax = self.relaxations()?;
        let n = 2 * m + relax.iter().map(|r| r.range.ncols()).sum::<usize>();
        let mut a = Mat::<c64>::zeros(n, n);
        for i in 0..m {
            a[(i, m + i)] = c64::new(s0, 0.0);
        }
        a.as_mut()
            .submatrix_mut(m, 0, m, m)
            .copy_from(&(faer::Scale(c64::new(-1.0 / s0, 0.0)) * &mk));
        a.as_mut().submatrix_mut(m, m, m, m).copy_from(&(-&mc));
        let mut at = 2 * m;
        for r in &relax {
            let k = r.range.ncols();
            let mcoup = lu.solve(&r.coupling);
            a.as_mut()
                .submatrix_mut(m, at, m, k)
                .copy_from(&(faer::Scale(c64::new(-1.0 / s0, 0.0)) * &mcoup));
            a.as_mut()
                .submatrix_mut(at, m, k, m)
                .copy_from(&complex(&(r.range.transpose() * s0)));
            for i in 0..k {
                a[(at + i, at + i)] = c64::new(-1.0 / r.tau_s, 0.0);
            }
            at += k;
        }
        let b = Mat::<c64>::from_fn(m, 1, |i, _| c64::new(self.b[i], 0.0));
        let mb = lu.solve(b);
        let input = Mat::<c64>::from_fn(n, 1, |i, _| {
            if (m..2 * m).contains(&i) {
                mb[(i - m, 0)]
            } else {
                c64::new(0.0, 0.0)
            }
        });
        Ok(StateForm {
            matrix: a,
            input,
            coordinates: m,
        })
    }

    /// The unscaled state-space form (s₀ = 1 rad/s).
    pub fn state_form(&self) -> Result<StateForm, FrfError> {
        self.state_form_scaled(1.0)
    }

    /// Reduced coordinates at every frequency (frequency × m) by the eigen-decomposition of
    /// the state matrix, with the sensor rows of the basis; `None` when the decomposition does
    /// not reproduce the dense LU at the check frequencies (the caller then uses the LU).
    pub(super) fn frf_state_space(
        &self,
        freqs_hz: &[f64],
    ) -> Result<Option<(FrfFactors, FrfSolve)>, FrfError> {
        let scale = state_scale_rad_s(freqs_hz);
        let form = self.state_form_scaled(scale)?;
        let m = form.coordinates;
        let evd = match form.matrix.eigen() {
            Ok(e) => e,
            Err(_) => return Ok(None),
        };
        drop(form.matrix);
        let x = evd.U().to_owned();
        let lam: Vec<c64> = evd.S().column_vector().iter().copied().collect();
        drop(evd);
        let g = x.partial_piv_lu().solve(&form.input);
        // X_q scaled by g: q(jω) = Σ_k xg[:, k] / (jω − λ_k)
        let xg_t = Mat::<c64>::from_fn(lam.len(), m, |k, i| x[(i, k)] * g[(k, 0)] / scale);
        drop(x);
        let nf = freqs_hz.len();
        let mut q = Mat::<c64>::zeros(nf, m);
        let par = faer::get_global_parallelism();
        for start in (0..nf).step_by(FREQUENCY_BLOCK) {
            let len = FREQUENCY_BLOCK.min(nf - start);
            let r = Mat::<c64>::from_fn(len, lam.len(), |f, k| {
                let s = c64::new(0.0, 2.0 * std::f64::consts::PI * freqs_hz[start + f]);
                c64::new(1.0, 0.0) / (s - lam[k])
            });
            faer::linalg::matmul::matmul(
                q.as_mut().submatrix_mut(start, 0, len, m),
                Accum::Replace,
                r.as_ref(),
                xg_t.as_ref(),
                c64::new(1.0, 0.0),
                par,
            );
        }
        if !self.agrees_with_lu(freqs_hz, &q)? {
            return Ok(None);
        }
        let solve = FrfSolve::StateSpace { states: lam.len() };
        Ok(Some(((q, complex(&self.sv)), solve)))
    }

    /// Whether `q` (frequency × m) matches the dense LU at [`TRUST_FREQUENCIES`] frequencies
    /// spread over the band, to [`TRUST_TOLERANCE`].
    fn agrees_with_lu(&self, freqs_hz: &[f64], q: &Mat<c64>) -> Result<bool, FrfError> {
        let nf = freqs_hz.len();
        let picks: Vec<usize> = (0..TRUST_FREQUENCIES)
            .map(|i| ((2 * i + 1) * nf / (2 * TRUST_FREQUENCIES)).min(nf - 1))
            .collect();
        let check: Vec<f64> = picks.iter().map(|&k| freqs_hz[k]).collect();
        let lu = self.q_by_lu(&check)?;
        for (c, &k) in picks.iter().enumerate() {
            let (mut num, mut den) = (0.0f64, 0.0f64);
            for i in 0..self.size {
                num += (q[(k, i)] - lu[(i, c)]).norm_sqr();
                den += lu[(i, c)].norm_sqr();
            }
            if num.is_nan() || num > TRUST_TOLERANCE * TRUST_TOLERANCE * den {
                return Ok(false);
            }
        }
        Ok(true)
    }
}

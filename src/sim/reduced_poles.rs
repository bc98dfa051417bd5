//! The damped modes of a reduced model: its poles and its complex mode shapes at the sensors,
//! from the state-space form of s²M̂ + sĈ + K̂_c. With non-proportional damping (a lossy patch)
//! the shapes are complex, their quadrature part concentrated where the loss is: what tells a
//! patch from its mirror image on a symmetric plate, where the poles alone cannot.

use faer::c64;
use faer::linalg::solvers::Solve;
use faer::Mat;

use super::frf::FrfError;
use super::reduced::ReducedModel;

/// A pole with Re s up to this fraction of |s| above zero is an undamped mode (an undamped
/// model's poles sit on the imaginary axis to rounding); it is kept with D = 0. The
/// non-physical root of a hysteretic mode has Im s < 0 and is left out by the sign of Im s.
const UNDAMPED_TOLERANCE: f64 = 1e-9;

/// One damped mode: damped frequency Im s / 2π in Hz, damping ratio −Re s / |s|, and the
/// complex displacement at each sensor (unnormalised).
pub type DampedMode = (f64, f64, Vec<c64>);

impl ReducedModel {
    /// The state matrix [[0, I], [−M̂⁻¹K̂_c, −M̂⁻¹Ĉ]] (Ĉ = αM̂ + βK̂₀); errors for an SLS region.
    fn state_matrix(&self) -> Result<Mat<c64>, FrfError> {
        if self.factors.iter().any(|t| t.sls.is_some()) {
            return Err(FrfError::Invalid {
                what: "damped poles".into(),
                message:
                    "expected loss factors and Rayleigh damping only, got a viscoelastic region"
                        .into(),
            });
        }
        let m = self.size;
        let (alpha, beta) = self.rayleigh;
        let mc = Mat::<c64>::from_fn(m, m, |i, j| c64::new(self.m_hat[(i, j)], 0.0));
        let mut c = Mat::<c64>::from_fn(m, m, |i, j| c64::new(alpha * self.m_hat[(i, j)], 0.0));
        for k in &self.k_hat {
            c += Mat::<c64>::from_fn(m, m, |i, j| c64::new(beta * k[(i, j)], 0.0));
        }
        let lu = mc.partial_piv_lu();
        let (mk, mcv) = (lu.solve(self.constant_stiffness()), lu.solve(c));
        Ok(Mat::<c64>::from_fn(2 * m, 2 * m, |i, j| {
            match (i < m, j < m) {
                (true, true) => c64::new(0.0, 0.0),
                (true, false) => c64::new(if j - m == i { 1.0 } else { 0.0 }, 0.0),
                (false, true) => -mk[(i - m, j)],
                (false, false) => -mcv[(i - m, j - m)],
            }
        }))
    }

    /// The damped poles of the model (loss factors and Rayleigh damping; no SLS region), the
    /// truth against which identified modes are judged when damping is non-proportional (a
    /// damped patch) or frequency-dependent (Rayleigh): the eigenvalues s of the state-space
    /// form with Im s > 0 and Re s ≤ 0, each as the damped frequency Im s / 2π in Hz and the
    /// damping ratio −Re s / |s|, by frequency. A free response is Σ e^{st}, so these are what
    /// a time-domain fit sees. The basis's residual vectors add poles far above its modes; keep
    /// only those below the modes' range.
    pub fn damped_poles(&self) -> Result<Vec<(f64, f64)>, FrfError> {
        let s = self
            .state_matrix()?
            .eigenvalues()
            .map_err(|e| FrfError::Factorisation {
                what: "state-space eigenvalues".into(),
                message: format!("{e:?}"),
            })?;
        let mut poles: Vec<(f64, f64)> = s
            .iter()
            .filter(|s| s.im > 0.0 && s.re <= UNDAMPED_TOLERANCE * s.norm())
            .map(|s| {
                let s = c64::new(s.re, s.im);
                (
                    s.im / (2.0 * std::f64::consts::PI),
                    (-s.re / s.norm()).max(0.0),
                )
            })
            .collect();
        poles.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(poles)
    }

    /// [`Self::damped_poles`] with each mode's complex shape at the model's sensors (the
    /// displacement half of the state eigenvector through the sensor rows of the basis).
    pub fn damped_modes(&self) -> Result<Vec<DampedMode>, FrfError> {
        let evd = self
            .state_matrix()?
            .eigen()
            .map_err(|e| FrfError::Factorisation {
                what: "state-space eigenvectors".into(),
                message: format!("{e:?}"),
            })?;
        let (u, s) = (evd.U(), evd.S().column_vector());
        let m = self.size;
        let mut modes: Vec<DampedMode> = (0..s.nrows())
            .filter(|&k| s[k].im > 0.0 && s[k].re <= UNDAMPED_TOLERANCE * s[k].norm())
            .map(|k| {
                let sk = c64::new(s[k].re, s[k].im);
                let shape = (0..self.sv.nrows())
                    .map(|r| {
                        (0..m).fold(c64::new(0.0, 0.0), |acc, j| {
                            acc + u[(j, k)] * self.sv[(r, j)]
                        })
                    })
                    .collect();
                (
                    sk.im / (2.0 * std::f64::consts::PI),
                    -sk.re / sk.norm(),
                    shape,
                )
            })
            .collect();
        modes.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(modes)
    }
}

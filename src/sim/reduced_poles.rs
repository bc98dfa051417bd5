//! The damped modes of a reduced model: its poles and its complex mode shapes at the sensors,
//! from the state-space form of s²M̂ + sĈ + K̂_c. With non-proportional damping (a lossy patch)
//! the shapes are complex, their quadrature part concentrated where the loss is: what tells a
//! patch from its mirror image on a symmetric plate, where the poles alone cannot.

use faer::c64;

use super::frf::FrfError;
use super::reduced::ReducedModel;

/// A pole with Re s up to this fraction of |s| above zero is an undamped mode (an undamped
/// model's poles sit on the imaginary axis to rounding); it is kept with D = 0. The
/// non-physical root of a hysteretic mode has Im s < 0 and is left out by the sign of Im s.
const UNDAMPED_TOLERANCE: f64 = 1e-9;

/// One damped mode: damped frequency Im s / 2π in Hz, damping ratio −Re s / |s|, and the
/// complex displacement at each sensor (unnormalised).
pub type DampedMode = (f64, f64, Vec<c64>);

/// A root with a damping ratio above this is a relaxation of a viscoelastic region's internal
/// variable, not a vibration mode.
const MAX_MODE_DAMPING_RATIO: f64 = 0.9;

/// Whether state eigenvalue `s` is a damped vibration mode (see [`UNDAMPED_TOLERANCE`] and
/// [`MAX_MODE_DAMPING_RATIO`]).
fn is_mode(s: c64) -> bool {
    s.im > 0.0 && s.re <= UNDAMPED_TOLERANCE * s.norm() && -s.re < MAX_MODE_DAMPING_RATIO * s.norm()
}

impl ReducedModel {
    /// The damped poles of the model (loss factors, Rayleigh damping, SLS regions), the
    /// truth against which identified modes are judged when damping is non-proportional (a
    /// damped patch) or frequency-dependent (Rayleigh): the eigenvalues s of the state-space
    /// form with Im s > 0 and Re s ≤ 0, each as the damped frequency Im s / 2π in Hz and the
    /// damping ratio −Re s / |s|, by frequency. A free response is Σ e^{st}, so these are what
    /// a time-domain fit sees. The basis's residual vectors add poles far above its modes; keep
    /// only those below the modes' range.
    pub fn damped_poles(&self) -> Result<Vec<(f64, f64)>, FrfError> {
        let s = self
            .state_form()?
            .matrix
            .eigenvalues()
            .map_err(|e| FrfError::Factorisation {
                what: "state-space eigenvalues".into(),
                message: format!("{e:?}"),
            })?;
        let mut poles: Vec<(f64, f64)> = s
            .iter()
            .filter(|&&s| is_mode(c64::new(s.re, s.im)))
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
            .state_form()?
            .matrix
            .eigen()
            .map_err(|e| FrfError::Factorisation {
                what: "state-space eigenvectors".into(),
                message: format!("{e:?}"),
            })?;
        let (u, s) = (evd.U(), evd.S().column_vector());
        let m = self.size;
        let mut modes: Vec<DampedMode> = (0..s.nrows())
            .filter(|&k| is_mode(c64::new(s[k].re, s[k].im)))
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

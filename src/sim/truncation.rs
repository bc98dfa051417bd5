//! Modal truncation to chosen modes (report eq. 2.7 / 4.6) for the single-mode studies:
//!
//! ```text
//! H_s(ω) = Σ_{i ∈ kept} φ_i(s) φ_iᵀ f / (k_i − ω² + jω(α + β ω_i²))
//! ```
//!
//! with φ_i mass-normalised undamped modes, φ_i(s) the sensor's weighted sum and the complex
//! modal stiffness k_i either
//!
//! - from the modal strain energy: k_i = Σ_r s_r(ω_i) φ_iᵀ K_r φ_i, i.e. ω_i²(1 + j g_i) with
//!   g_i = Σ_r g_r E_ri / Σ_r E_ri for structural regions (the plate loss factor for a
//!   homogeneous plate; SLS regions evaluated at ω_i), or
//! - from given modal damping ratios D_i: k_i = ω_i²(1 + j 2 D_i) (report eqs. 4.6–4.7).

use faer::{c64, Mat, MatRef};

use super::factored::FactoredFrf;
use super::frf::{validate_frequencies, validate_system, Frf, FrfError};
use super::reduced::validate_modes;
use super::system::FeSystem;

/// Where the modal damping of the kept modes comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum ModalDamping {
    /// Modal strain energy of each region with its loss factor / SLS modulus at ω_i.
    StrainEnergy,
    /// Given critical damping ratios D_i, one per kept mode (g_i = 2 D_i).
    Ratios(Vec<f64>),
}

/// Converts 1-based mode numbers to column indices, checking them against the mode count.
pub fn mode_columns(keep_1based: &[usize], n_modes: usize) -> Result<Vec<usize>, FrfError> {
    if keep_1based.is_empty() {
        return Err(FrfError::Invalid {
            what: "kept modes".into(),
            message: "expected at least one mode number, got none".into(),
        });
    }
    keep_1based
        .iter()
        .map(|&k| {
            if k == 0 || k > n_modes {
                Err(FrfError::Invalid {
                    what: "kept modes".into(),
                    message: format!("expected mode numbers 1..={n_modes} (1-based), got {k}"),
                })
            } else {
                Ok(k - 1)
            }
        })
        .collect()
}

/// Complex modal stiffness k_i = Σ_r s_r(ω_i) φ_iᵀ K_r φ_i of one mode (column `col`), N/m per
/// unit modal mass; its loss factor is Im/Re.
pub fn modal_stiffness(
    sys: &FeSystem,
    frequency_hz: f64,
    shape: MatRef<'_, f64>,
    col: usize,
) -> c64 {
    let omega = 2.0 * std::f64::consts::PI * frequency_hz;
    let phi = shape.col(col);
    let mut k = c64::new(0.0, 0.0);
    for t in &sys.stiffness_terms {
        let (sym, val) = t.matrix.parts();
        let mut e = 0.0;
        for j in 0..sys.n_free {
            for idx in sym.col_range(j) {
                e += phi[sym.row_idx()[idx]] * val[idx] * phi[j];
            }
        }
        let (sr, si) = t.factor(omega);
        k += c64::new(sr, si) * e;
    }
    k
}

/// The truncated-modal FRF at every sensor for the 1-based mode numbers `keep_1based`.
pub fn truncated_frf(
    sys: &FeSystem,
    frequencies_hz_modes: &[f64],
    shapes: MatRef<'_, f64>,
    keep_1based: &[usize],
    damping: &ModalDamping,
    freqs_hz: &[f64],
) -> Result<Frf, FrfError> {
    truncated_factored_frf(
        sys,
        frequencies_hz_modes,
        shapes,
        keep_1based,
        damping,
        freqs_hz,
    )
    .map(|f| f.to_frf())
}

/// [`truncated_frf`] as modal responses × sensor weights (one basis vector per kept mode).
pub fn truncated_factored_frf(
    sys: &FeSystem,
    frequencies_hz_modes: &[f64],
    shapes: MatRef<'_, f64>,
    keep_1based: &[usize],
    damping: &ModalDamping,
    freqs_hz: &[f64],
) -> Result<FactoredFrf, FrfError> {
    validate_system(sys)?;
    validate_modes(sys, frequencies_hz_modes, shapes)?;
    validate_frequencies(freqs_hz)?;
    let cols = mode_columns(keep_1based, shapes.ncols())?;
    if let ModalDamping::Ratios(d) = damping {
        if d.len() != cols.len() {
            return Err(FrfError::Dimension {
                what: "modal damping ratios".into(),
                expected: format!("{} (one per kept mode)", cols.len()),
                got: format!("{}", d.len()),
            });
        }
        if let Some(bad) = d.iter().find(|x| !x.is_finite() || **x < 0.0) {
            return Err(FrfError::Invalid {
                what: "modal damping ratios".into(),
                message: format!("expected finite ≥ 0, got {bad}"),
            });
        }
    }
    let (alpha, beta) = sys.rayleigh.unwrap_or((0.0, 0.0));
    // Per kept mode: complex stiffness, viscous coefficient, participation φᵀf, sensor values.
    let mut modes = Vec::with_capacity(cols.len());
    for (n, &c) in cols.iter().enumerate() {
        let wi = 2.0 * std::f64::consts::PI * frequencies_hz_modes[c];
        let k = match damping {
            ModalDamping::StrainEnergy => modal_stiffness(sys, frequencies_hz_modes[c], shapes, c),
            ModalDamping::Ratios(d) => c64::new(wi * wi, 2.0 * d[n] * wi * wi),
        };
        let visc = alpha + beta * wi * wi;
        let part: f64 = (0..sys.n_free).map(|i| shapes[(i, c)] * sys.force[i]).sum();
        let at_sensors: Vec<f64> = sys
            .sensors
            .iter()
            .map(|s| s.weights.iter().map(|&(d, w)| w * shapes[(d, c)]).sum())
            .collect();
        modes.push((k, visc, part, at_sensors));
    }
    let modal = Mat::<c64>::from_fn(freqs_hz.len(), modes.len(), |kf, i| {
        let w = 2.0 * std::f64::consts::PI * freqs_hz[kf];
        let (k, visc, part, _) = &modes[i];
        c64::new(*part, 0.0) / (*k + c64::new(-w * w, w * visc))
    });
    let weights = Mat::<c64>::from_fn(sys.sensors.len(), modes.len(), |s, i| {
        c64::new(modes[i].3[s], 0.0)
    });
    Ok(FactoredFrf {
        frequencies_hz: freqs_hz.to_vec(),
        sensor_ids: sys.sensors.iter().map(|s| s.id.clone()).collect(),
        modal,
        weights,
        solve: super::factored::FrfSolve::Modal,
    })
}

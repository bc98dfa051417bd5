//! FRF re-synthesis from the global damping per band (report section 4.2.2, eqs. 4.6–4.8).
//!
//! The identified global equivalent damping ratios D(f_n) of the bands are interpolated to each
//! natural frequency f_i of the undamped model and applied as modal structural damping
//! g_i = 2 D(f_i):
//!
//! ```text
//! H_est(Ω) = Σ_i φ_i φ_iᵀ f / (ω_i²(1 + j g_i) − Ω²)                    (eqs. 4.6, 4.7)
//! ε_band   = Σ_{f ∈ band} |H_est − H_orig| / Σ_{f ∈ band} |H_orig|        (eq. 4.8)
//! ```
//!
//! Modes above the kept ones still contribute their static flexibility, which matters most at
//! the driving point; with `static_displacement` given, the residual
//! R_s = (u_static(s) − Σ_i φ_i(s) φ_iᵀ f / ω_i²) / (1 + j g_top) is added to every sensor, with
//! g_top = 2 D at the highest kept mode (the truncated modes get the damping of the top band),
//! so that ε measures the damping and not the modal truncation.
//!
//! Beside the per-band error, each mode's damping ratio from its modal strain energy
//! (D_i = η_i / 2, η_i = Im k_i / Re k_i, the "numerical damping ratios" of the report's
//! Fig. 4.10) is compared with the one the bands assign to it.

use faer::c64;

use crate::sim::eigen::Modes;
use crate::sim::frf::{Frf, FrfError};
use crate::sim::system::FeSystem;
use crate::sim::truncation::{modal_stiffness, truncated_frf, ModalDamping};

/// The global damping ratio identified in one band.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BandDamping {
    /// Lower band edge, Hz.
    pub f_lo_hz: f64,
    /// Upper band edge, Hz.
    pub f_hi_hz: f64,
    /// Band centre, Hz (where the ratio is placed for interpolation).
    pub f_center_hz: f64,
    /// Global equivalent damping ratio (fraction).
    pub damping_ratio: f64,
}

/// The damping ratio at `f_hz`: linear between band centres, constant beyond the first and
/// last. `bands` must be non-empty; they are used in order of their centres.
pub fn damping_at(bands: &[BandDamping], f_hz: f64) -> f64 {
    let mut b: Vec<&BandDamping> = bands.iter().collect();
    b.sort_by(|p, q| p.f_center_hz.total_cmp(&q.f_center_hz));
    let (first, last) = (b[0], b[b.len() - 1]);
    if f_hz <= first.f_center_hz {
        return first.damping_ratio;
    }
    if f_hz >= last.f_center_hz {
        return last.damping_ratio;
    }
    let k = b.partition_point(|p| p.f_center_hz <= f_hz);
    let (p, q) = (b[k - 1], b[k]);
    let t = (f_hz - p.f_center_hz) / (q.f_center_hz - p.f_center_hz);
    p.damping_ratio + t * (q.damping_ratio - p.damping_ratio)
}

/// Eq. 4.8 over the frequencies in [lo, hi] and the given sensors' FRF columns: Σ|est − orig| /
/// Σ|orig|. `None` when no frequency falls in the band or the original is zero there.
pub fn band_error(est: &Frf, orig: &Frf, sensors: &[usize], lo_hz: f64, hi_hz: f64) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for (k, f) in orig.frequencies_hz.iter().enumerate() {
        if *f < lo_hz || *f > hi_hz {
            continue;
        }
        for &s in sensors {
            let (e, o) = (
                est.receptance_m_per_n[(k, s)],
                orig.receptance_m_per_n[(k, s)],
            );
            num += (e - o).norm();
            den += o.norm();
        }
    }
    (den > 0.0).then_some(num / den)
}

/// One mode of the re-synthesis.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ModeDamping {
    /// Mode number, from 1.
    pub mode: usize,
    /// Natural frequency, Hz.
    pub frequency_hz: f64,
    /// Damping ratio from the model's modal strain energy (η_i / 2).
    pub d_model: f64,
    /// Damping ratio assigned from the bands.
    pub d_assigned: f64,
}

/// One band of the re-synthesis.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BandResult {
    /// Lower band edge, Hz.
    pub f_lo_hz: f64,
    /// Upper band edge, Hz.
    pub f_hi_hz: f64,
    /// Identified global damping ratio.
    pub d_global: f64,
    /// Modes with a natural frequency in the band.
    pub n_modes: usize,
    /// Mean model damping ratio of those modes.
    pub d_model_mean: Option<f64>,
    /// Eq. 4.8 at the driving-point sensor.
    pub eps_driving_point: Option<f64>,
    /// Eq. 4.8 over every sensor but the driving point.
    pub eps_all_sensors: Option<f64>,
}

/// The outcome of [`resynthesize`].
#[derive(Clone, Debug)]
pub struct Resynthesis {
    /// The estimated FRF (eq. 4.6) at every sensor.
    pub estimated: Frf,
    /// Per mode: model vs assigned damping.
    pub modes: Vec<ModeDamping>,
    /// Per band: damping and errors.
    pub bands: Vec<BandResult>,
}

/// Re-synthesises the FRF of `sys` from `bands` over `modes` (all of them, undamped shapes) and
/// compares it with `original` (same frequencies and sensors) per band; `driving_point` is the
/// sensor column of the driving point; `static_displacement` (K₀⁻¹ f over the free dofs)
/// adds the truncated modes' residual flexibility, `None` keeps eq. 4.6 as it stands.
pub fn resynthesize(
    sys: &FeSystem,
    modes: &Modes,
    bands: &[BandDamping],
    original: &Frf,
    driving_point: usize,
    static_displacement: Option<&[f64]>,
) -> Result<Resynthesis, FrfError> {
    if bands.is_empty() {
        return Err(FrfError::Invalid {
            what: "global damping".into(),
            message: "expected at least one band with a damping ratio, got none".into(),
        });
    }
    if driving_point >= original.n_sensors() {
        return Err(FrfError::Invalid {
            what: "driving point".into(),
            message: format!(
                "expected a sensor index below {}, got {driving_point}",
                original.n_sensors()
            ),
        });
    }
    let n = modes.frequencies_hz.len();
    let assigned: Vec<f64> = modes
        .frequencies_hz
        .iter()
        .map(|&f| damping_at(bands, f))
        .collect();
    let keep: Vec<usize> = (1..=n).collect();
    let mut estimated = truncated_frf(
        sys,
        &modes.frequencies_hz,
        modes.shapes.as_ref(),
        &keep,
        &ModalDamping::Ratios(assigned.clone()),
        &original.frequencies_hz,
    )?;
    if let Some(u) = static_displacement {
        if u.len() != sys.n_free {
            return Err(FrfError::Dimension {
                what: "static displacement".into(),
                expected: format!("{} (free dofs)", sys.n_free),
                got: u.len().to_string(),
            });
        }
        let phi = modes.shapes.as_ref();
        let d_top = assigned.last().copied().unwrap_or(0.0);
        let part: Vec<f64> = (0..n)
            .map(|i| (0..sys.n_free).map(|d| phi[(d, i)] * sys.force[d]).sum())
            .collect();
        for (s, sensor) in sys.sensors.iter().enumerate() {
            let at = |col: &dyn Fn(usize) -> f64| -> f64 {
                sensor.weights.iter().map(|&(d, w)| w * col(d)).sum()
            };
            let mut r = at(&|d| u[d]);
            for i in 0..n {
                let w = 2.0 * std::f64::consts::PI * modes.frequencies_hz[i];
                if w > 0.0 {
                    r -= at(&|d| phi[(d, i)]) * part[i] / (w * w);
                }
            }
            let residual = c64::new(r, 0.0) / c64::new(1.0, 2.0 * d_top);
            for k in 0..estimated.frequencies_hz.len() {
                estimated.receptance_m_per_n[(k, s)] += residual;
            }
        }
    }
    let mode_rows: Vec<ModeDamping> = (0..n)
        .map(|i| {
            let f = modes.frequencies_hz[i];
            let k: c64 = modal_stiffness(sys, f, modes.shapes.as_ref(), i);
            ModeDamping {
                mode: i + 1,
                frequency_hz: f,
                d_model: 0.5 * k.im / k.re,
                d_assigned: assigned[i],
            }
        })
        .collect();
    let all: Vec<usize> = (0..original.n_sensors())
        .filter(|&s| s != driving_point)
        .collect();
    let band_rows = bands
        .iter()
        .map(|b| {
            let inside: Vec<f64> = mode_rows
                .iter()
                .filter(|m| m.frequency_hz >= b.f_lo_hz && m.frequency_hz < b.f_hi_hz)
                .map(|m| m.d_model)
                .collect();
            BandResult {
                f_lo_hz: b.f_lo_hz,
                f_hi_hz: b.f_hi_hz,
                d_global: b.damping_ratio,
                n_modes: inside.len(),
                d_model_mean: (!inside.is_empty())
                    .then(|| inside.iter().sum::<f64>() / inside.len() as f64),
                eps_driving_point: band_error(
                    &estimated,
                    original,
                    &[driving_point],
                    b.f_lo_hz,
                    b.f_hi_hz,
                ),
                eps_all_sensors: band_error(&estimated, original, &all, b.f_lo_hz, b.f_hi_hz),
            }
        })
        .collect();
    Ok(Resynthesis {
        estimated,
        modes: mode_rows,
        bands: band_rows,
    })
}

/// Default of the mode cut-off of [`resynthesize_model`]: modes below 3 × fmax carry the
/// re-synthesis (the rest enter as a static residual, which misses their dynamic amplification
/// 1/(1 − (f/f_i)²): 3 keeps that below 12.5 % of an already small residual).
pub const DEFAULT_MODE_CUTOFF_FACTOR: f64 = 3.0;

/// A model's FRF re-synthesised from the global damping per band, with what it was compared to.
pub struct ModelResynthesis {
    /// Per band and per mode results, and the re-synthesised FRF.
    pub result: Resynthesis,
    /// The model's own FRF (sensors, then the driving point as the last column).
    pub original: Frf,
    /// Column of the driving point in both FRFs.
    pub driving_point: usize,
    /// Modes below this frequency carried the re-synthesis, Hz.
    pub cutoff_hz: f64,
    /// How many modes that was.
    pub n_modes: usize,
}

/// The whole procedure of `dampscope resynth` (report section 4.2.2): adds the driving point as
/// a virtual sensor (the displacement at the load, weighted like the load), computes the
/// model's FRF up to its fmax, and re-synthesises it with each band's global damping on the
/// modes below `mode_cutoff_factor` × fmax (the others as a static residual unless
/// `with_residual` is false, eq. 4.6 exactly as the report writes it).
pub fn resynthesize_model(
    model: &crate::sim::model::Model,
    bands: &[BandDamping],
    mode_cutoff_factor: f64,
    with_residual: bool,
) -> crate::error::Result<ModelResynthesis> {
    use crate::error::Error;
    use crate::sim::eigen::{lowest_modes, ModeRequest};
    let failed = |e: &dyn std::fmt::Display| Error::setting("model", e.to_string());
    if !(mode_cutoff_factor.is_finite() && mode_cutoff_factor >= 1.0) {
        return Err(Error::setting(
            "mode_cutoff_factor",
            format!("expected >= 1, got {mode_cutoff_factor}"),
        ));
    }
    let mut sys = crate::sim::assembly::assemble(model).map_err(|e| failed(&e))?;
    let total: f64 = sys.force.iter().sum();
    if total == 0.0 {
        return Err(Error::setting(
            "model",
            "the load vector sums to zero: no driving point",
        ));
    }
    let weights: Vec<(usize, f64)> = sys
        .force
        .iter()
        .enumerate()
        .filter(|(_, f)| **f != 0.0)
        .map(|(d, f)| (d, f / total))
        .collect();
    sys.sensors.push(crate::sim::system::SensorWeights {
        id: "driving_point".into(),
        x_m: model.excitation.x,
        y_m: model.excitation.y,
        weights,
    });
    let driving_point = sys.sensors.len() - 1;
    let fmax = model.output.fmax;
    let cutoff_hz = mode_cutoff_factor * fmax;
    let modes = lowest_modes(&sys, ModeRequest::BelowHz(cutoff_hz)).map_err(|e| failed(&e))?;
    let original = crate::sim::simulate::simulate_system(
        &sys,
        Some(&modes),
        fmax,
        model.output.df,
        &crate::sim::simulate::SimulateOptions::default(),
    )
    .map_err(|e| failed(&e))?
    .frf;
    let u_static = if with_residual {
        Some(crate::sim::reduced::static_displacement(&sys).map_err(|e| failed(&e))?)
    } else {
        None
    };
    let result = resynthesize(
        &sys,
        &modes,
        bands,
        &original,
        driving_point,
        u_static.as_deref(),
    )
    .map_err(|e| failed(&e))?;
    Ok(ModelResynthesis {
        result,
        original,
        driving_point,
        cutoff_hz,
        n_modes: modes.frequencies_hz.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    fn band(lo: f64, hi: f64, d: f64) -> BandDamping {
        BandDamping {
            f_lo_hz: lo,
            f_hi_hz: hi,
            f_center_hz: 0.5 * (lo + hi),
            damping_ratio: d,
        }
    }

    #[test]
    fn interpolation_between_centres_and_flat_outside() {
        let b = [band(150.0, 250.0, 0.03), band(50.0, 150.0, 0.01)];
        assert_eq!(damping_at(&b, 10.0), 0.01);
        assert_eq!(damping_at(&b, 100.0), 0.01);
        assert!((damping_at(&b, 150.0) - 0.02).abs() < 1e-15);
        assert!((damping_at(&b, 175.0) - 0.025).abs() < 1e-15);
        assert_eq!(damping_at(&b, 200.0), 0.03);
        assert_eq!(damping_at(&b, 1e4), 0.03);
        assert_eq!(damping_at(&[band(0.0, 10.0, 0.02)], 3.0), 0.02);
    }

    #[test]
    fn band_error_is_eq_4_8() {
        let frf = |v: [f64; 4]| Frf {
            frequencies_hz: vec![10.0, 20.0, 30.0, 40.0],
            sensor_ids: vec!["a".into()],
            receptance_m_per_n: Mat::from_fn(4, 1, |k, _| c64::new(v[k], 0.0)),
        };
        let orig = frf([1.0, 2.0, 4.0, 8.0]);
        let est = frf([1.0, 3.0, 2.0, 0.0]);
        // 20–30 Hz: (|3 − 2| + |2 − 4|) / (2 + 4) = 0.5.
        assert_eq!(band_error(&est, &orig, &[0], 15.0, 30.0), Some(0.5));
        assert_eq!(band_error(&est, &orig, &[0], 10.0, 10.0), Some(0.0));
        assert_eq!(band_error(&est, &orig, &[0], 50.0, 60.0), None);
    }
}

//! `added_mass`: a point mass the model lacks, found from the frequency evidence. A mass m at
//! point q lowers mode i's frequency by Δf_i/f_i ≈ −½ m φ_i(q)² (φ mass-normalised), so modes
//! with an antinode at q drop and modes with a nodal line through q do not. Over a grid of
//! candidate points, ln(f_measured/f_model) = c₀ + c₁f² + m·(−½φ_i(q)²) is fitted by least
//! squares (c₀ and c₁ absorb the model-form offset and a mesh's f² drift; m ≥ 0); the best point is kept when it pays for its
//! three parameters (m, x, y) in the Bayesian information criterion with the noise level
//! profiled from the residual (n ln(RSS/n) + k ln n; RSS no lower than the identification's
//! own frequency variance). Points with the same fit (the plate's mirror images) are told apart
//! by re-solving the model with the mass at each and comparing the shapes.

use super::evidence::{Evidence, ModelView};
use crate::modal::Mode;
use crate::sim::error::SimError;
use crate::sim::model::{Model, PointMass, SensorPosition};

/// Spacing of the candidate points, m.
pub const MASS_GRID_SPACING_M: f64 = 0.05;
/// Candidate points whose residual is within this fraction of the best one's are images of it
/// (the same φ² by symmetry).
const IMAGE_RSS_REL: f64 = 1e-3;

/// A mass is reported when its BIC gain reaches this: "strong" evidence on Kass and Raftery's
/// scale of 2 ln(Bayes factor) (6–10), not a value fitted to any test case.
pub const MIN_BIC_GAIN: f64 = 6.0;

/// The best point-mass hypothesis.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MassFit {
    /// Position, m.
    pub x_m: f64,
    /// Position, m.
    pub y_m: f64,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Residual sum of squares of ln f without the mass (offset only).
    pub rss_none: f64,
    /// Residual sum of squares with it.
    pub rss: f64,
    /// BIC(no mass) − BIC(mass): positive when the mass pays for its parameters.
    pub bic_gain: f64,
    /// How many mirror images the frequencies could not tell apart (1: none).
    pub images: usize,
}

/// The model-form nuisance the frequencies are fitted with: an offset (a global stiffness or
/// density error) and a trend in f² (a coarser mesh's discretisation error grows as (kh)², so
/// its frequencies drift from the structure's with frequency). A mass is local: its pattern
/// over the modes follows φ², not f. The columns 1 and (f/f_max)², orthonormalised.
struct Nuisance {
    basis: Vec<Vec<f64>>,
}

impl Nuisance {
    fn new(frequencies_hz: &[f64]) -> Self {
        let fmax = frequencies_hz.iter().copied().fold(1e-300, f64::max);
        let columns = [
            vec![1.0; frequencies_hz.len()],
            frequencies_hz.iter().map(|f| (f / fmax).powi(2)).collect(),
        ];
        let mut basis: Vec<Vec<f64>> = Vec::new();
        for c in columns {
            let mut v = c;
            for b in &basis {
                let d = dot(&v, b);
                v.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
            }
            let norm = dot(&v, &v).sqrt();
            if norm > 1e-12 {
                basis.push(v.iter().map(|x| x / norm).collect());
            }
        }
        Self { basis }
    }

    /// Parameters the nuisance spends.
    fn params(&self) -> f64 {
        self.basis.len() as f64
    }

    /// `v` with its nuisance part removed.
    fn residual(&self, v: &[f64]) -> Vec<f64> {
        let mut r = v.to_vec();
        for b in &self.basis {
            let d = dot(&r, b);
            r.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
        }
        r
    }

    /// Least squares of y = nuisance + m a with m ≥ 0 (or any sign): (m, rss).
    fn fit(&self, y: &[f64], a: &[f64], non_negative: bool) -> (f64, f64) {
        let (yr, ar) = (self.residual(y), self.residual(a));
        let (ay, aa) = (dot(&ar, &yr), dot(&ar, &ar));
        let mut m = if aa > 0.0 { ay / aa } else { 0.0 };
        if non_negative {
            m = m.max(0.0);
        }
        (m, dot(&yr, &yr) - 2.0 * m * ay + m * m * aa)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl MassFit {
    /// Whether the mass pays for its parameters ([`MIN_BIC_GAIN`]).
    pub fn is_finding(&self) -> bool {
        self.mass_kg > 0.0 && self.bic_gain >= MIN_BIC_GAIN
    }
}

/// The candidate points: a grid of `spacing_m` over the plate, symmetric about its centre.
fn grid(lx_m: f64, ly_m: f64, spacing_m: f64) -> Vec<SensorPosition> {
    let (nx, ny) = (
        (lx_m / spacing_m).round() as usize,
        (ly_m / spacing_m).round() as usize,
    );
    let mut out = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            out.push(SensorPosition {
                id: format!("q{i}_{j}"),
                x_m: lx_m * (i as f64 + 0.5) / nx as f64,
                y_m: ly_m * (j as f64 + 0.5) / ny as f64,
            });
        }
    }
    out
}

/// Fits a point mass to the frequency evidence (`evidence` built from `measured` against
/// `view`'s poles at the `sensors`). `None` with fewer than four pairs. The images are
/// resolved by re-solving the model with the mass at each (one eigen-solve per image).
pub fn fit_point_mass(
    measured: &[Mode],
    evidence: &Evidence,
    view: &ModelView,
    sensors: &[SensorPosition],
) -> Result<Option<MassFit>, SimError> {
    let pairs = evidence.pairs_within(view);
    let n = pairs.len();
    if n < 4 {
        return Ok(None);
    }
    let y: Vec<f64> = pairs.iter().map(|p| p.frequency_rel.ln_1p()).collect();
    let noise: f64 = pairs
        .iter()
        .map(|p| {
            (measured[p.measured].frequency_std_hz / measured[p.measured].frequency_hz).powi(2)
        })
        .sum();
    let nuisance = Nuisance::new(
        &pairs
            .iter()
            .map(|p| view.basis.frequencies_hz[p.model])
            .collect::<Vec<_>>(),
    );
    let rss_none = nuisance.fit(&y, &vec![0.0; n], true).1;
    let plate = &view.model.plate;
    let points = grid(plate.lx, plate.ly, MASS_GRID_SPACING_M);
    let phi = view.shapes_at(&points)?;
    let fits: Vec<(usize, f64, f64)> = (0..points.len())
        .map(|q| {
            let a: Vec<f64> = pairs
                .iter()
                .map(|p| -0.5 * phi[p.model][q].powi(2))
                .collect();
            let (m, rss) = nuisance.fit(&y, &a, true);
            (q, m, rss)
        })
        .collect();
    let best = fits
        .iter()
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .copied()
        .expect("the grid is not empty");
    let k0 = nuisance.params();
    let bic = |rss: f64, k: f64| n as f64 * (rss.max(noise) / n as f64).ln() + k * (n as f64).ln();
    let images: Vec<(usize, f64, f64)> = fits
        .iter()
        .filter(|f| f.1 > 0.0 && f.2 <= best.2 * (1.0 + IMAGE_RSS_REL) + 1e-300)
        .copied()
        .collect();
    let chosen = if images.len() > 1 {
        closest_shapes(measured, view, sensors, &points, &images)?
    } else {
        best
    };
    let (x_m, y_m) = (points[chosen.0].x_m, points[chosen.0].y_m);
    let mass_kg = refit_mass_at(measured, evidence, view, sensors, (x_m, y_m), chosen.1)?;
    Ok(Some(MassFit {
        x_m,
        y_m,
        mass_kg,
        rss_none,
        rss: chosen.2,
        bic_gain: bic(rss_none, k0) - bic(chosen.2, k0 + 3.0),
        images: images.len(),
    }))
}

/// One Gauss–Newton step on a mass of `mass_kg` at `point` through the re-solved model
/// (`view`'s model plus the mass): the first-order sensitivity underestimates a mass whose own
/// shape change matters. `view` may hold other findings already (a lossy patch moves the
/// damped frequencies too); `evidence` must pair the same modes. Returns the stepped mass, ≥ 0.
pub fn refit_mass_at(
    measured: &[Mode],
    evidence: &Evidence,
    view: &ModelView,
    sensors: &[SensorPosition],
    point: (f64, f64),
    mass_kg: f64,
) -> Result<f64, SimError> {
    let pairs = evidence.pairs_within(view);
    if pairs.is_empty() {
        return Ok(mass_kg);
    }
    let nuisance = Nuisance::new(
        &pairs
            .iter()
            .map(|p| view.basis.frequencies_hz[p.model])
            .collect::<Vec<_>>(),
    );
    let at = [SensorPosition {
        id: "mass".into(),
        x_m: point.0,
        y_m: point.1,
    }];
    let phi = view.shapes_at(&at)?;
    let a: Vec<f64> = pairs
        .iter()
        .map(|p| -0.5 * phi[p.model][0].powi(2))
        .collect();
    let updated = with_mass(view, point.0, point.1, mass_kg)?.poles_at(sensors)?;
    let after: Vec<f64> = pairs
        .iter()
        .map(|p| {
            let f = measured[p.measured].frequency_hz;
            (f / updated[p.model].damped_frequency_hz).ln()
        })
        .collect();
    Ok((mass_kg + nuisance.fit(&after, &a, false).0).max(0.0))
}

/// Among equally good candidate points, the one whose re-solved model's shapes fit the
/// measured shapes best (the sum over pairs of 1 − MAC).
fn closest_shapes(
    measured: &[Mode],
    view: &ModelView,
    sensors: &[SensorPosition],
    points: &[SensorPosition],
    candidates: &[(usize, f64, f64)],
) -> Result<(usize, f64, f64), SimError> {
    let mut best: Option<((usize, f64, f64), f64)> = None;
    for &cand in candidates {
        // Undamped shapes suffice to compare (no damped poles, no basis beyond the range).
        let model = add_mass(&view.model, points[cand.0].x_m, points[cand.0].y_m, cand.1);
        let system = crate::sim::assembly::assemble(&model)?;
        let modes = crate::sim::eigen::lowest_modes(
            &system,
            crate::sim::eigen::ModeRequest::BelowHz(view.fmax_hz),
        )?;
        let at = crate::sim::assembly::sensors_at(&model, sensors)?;
        let poles: Vec<super::evidence::ModelPole> = (0..modes.frequencies_hz.len())
            .map(|i| super::evidence::ModelPole {
                mode: i + 1,
                frequency_hz: modes.frequencies_hz[i],
                damped_frequency_hz: modes.frequencies_hz[i],
                damping_ratio: 0.0,
                shape: crate::modal::model_shapes::shape_at(&at, modes.shapes.as_ref(), i),
            })
            .collect();
        let e = Evidence::gather(measured, poles);
        let misfit: f64 = e.pairs.iter().map(|p| 1.0 - p.mac).sum::<f64>()
            + (measured.len() - e.pairs.len()) as f64;
        if best.is_none_or(|b| misfit < b.1) {
            best = Some((cand, misfit));
        }
    }
    Ok(best.expect("candidates are not empty").0)
}

/// `model` with a point mass added.
pub fn add_mass(model: &Model, x_m: f64, y_m: f64, mass_kg: f64) -> Model {
    let mut m = model.clone();
    m.point_masses.push(PointMass {
        x: x_m,
        y: y_m,
        mass: mass_kg,
    });
    m
}

/// `view`'s model with a point mass added, solved over the same range.
pub fn with_mass(
    view: &ModelView,
    x_m: f64,
    y_m: f64,
    mass_kg: f64,
) -> Result<ModelView, SimError> {
    ModelView::new(&add_mass(&view.model, x_m, y_m, mass_kg), view.fmax_hz)
}

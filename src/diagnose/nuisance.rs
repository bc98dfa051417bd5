//! The model-form nuisance every frequency fit carries: the user's model is not the structure's
//! twin, and a correct model of another discretisation or plate theory differs from it by
//!
//! - an offset (a global stiffness or density error: every ln f moves alike);
//! - drifts in f and f² (a plate's shear and rotary inertia and a mesh's discretisation error
//!   grow as (kh)², and k² ∝ f for bending waves);
//! - the model's own discretisation pattern: hexahedra err by direction (a mode bending along
//!   x errs unlike one bending along y), so the error is not a function of f alone. The model
//!   solved on another mesh shows that pattern (Richardson: the error goes as h², so f_2h − f_h
//!   and f_h − f_h/2 are both proportional to the model's own error), see
//!   [`discretisation_pattern`]. A mesh half as fine is cheap, but its pattern is the model's
//!   only while its elements still resolve the waves ([`RICHARDSON_MIN_ELEMENTS_PER_WAVELENGTH`]);
//!   a coarse model is solved on a mesh twice as fine instead. Found on a 1 × 1.5 m plate on
//!   12 × 18 × 2 against recordings of a 36 × 54 × 2 one: the 6 × 9 mesh's pattern explained
//!   almost nothing of the right model's mismatch (residual 0.43 → 0.40 % RMS around the other
//!   columns, several modes unpaired), and a false stiffer region or point mass was named in
//!   six of six recordings; the 24 × 36 mesh's pattern leaves 0.07 %.
//!
//! Measured against an independent Kirchhoff plate (scripts/kirchhoff_sim.py), the 32 × 48 × 2
//! model's 18 modes below 160 Hz differ by 0.19 % RMS around an offset, 0.17 % around 1, f,
//! f², and 0.11 % with the pattern too. Physics is only claimed for the part of
//! ln(f_measured / f_model) that these columns cannot explain. A point mass, a stiffer region
//! or a soft edge are local: their patterns over the modes follow φ², a region's strain energy
//! or the edge's motion.

use super::evidence::{pair_modes, ModelPole, ModelView};
use crate::modal::model_shapes::shape_at;
use crate::modal::Mode;
use crate::sim::assembly::{assemble, sensors_at};
use crate::sim::eigen::{lowest_modes, ModeRequest};
use crate::sim::error::SimError;
use crate::sim::model::{Model, SensorPosition};
use crate::sim::resolution::elements_per_wavelength;

/// Fewest elements per bending wavelength, at the view's highest frequency, that a mesh half
/// as fine as the model's must keep for its modes to show the model's pattern. Below it the
/// error no longer goes as h²: the reference plate against its 64 × 96 mesh errs +2.2 % at 7.4
/// elements per wavelength and +3.5 % at 6.0 (h² predicts ×1.52, measured ×1.59), +4.9 % at 4.7
/// (h² predicts 5.5 %) and +5.8 % at 4.1 (6.7 %); [`crate::sim::resolution`] has the figures.
pub const RICHARDSON_MIN_ELEMENTS_PER_WAVELENGTH: f64 = 6.0;

/// The mesh whose modes show a model's discretisation pattern.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PatternMesh {
    /// Half as many elements along x and along y (cheap; needs a fine model).
    HalfAsFine,
    /// Twice as many along x and along y (four times the unknowns; for a coarse model).
    TwiceAsFine,
}

impl PatternMesh {
    /// Which mesh shows `model`'s pattern up to `fmax_hz`: the mesh half as fine while it keeps
    /// [`RICHARDSON_MIN_ELEMENTS_PER_WAVELENGTH`], else the mesh twice as fine if its system
    /// fits the memory budget; `None` when neither can.
    pub fn for_model(model: &Model, fmax_hz: f64) -> Option<Self> {
        let coarser = Self::HalfAsFine.mesh_of(model);
        if model.mesh.nx >= 8
            && model.mesh.ny >= 8
            && elements_per_wavelength(&coarser, fmax_hz)
                .is_some_and(|n| n >= RICHARDSON_MIN_ELEMENTS_PER_WAVELENGTH)
        {
            return Some(Self::HalfAsFine);
        }
        crate::sim::limits::check_system_fits(&Self::TwiceAsFine.mesh_of(model))
            .is_ok()
            .then_some(Self::TwiceAsFine)
    }

    /// `model` on this mesh.
    pub fn mesh_of(self, model: &Model) -> Model {
        let mut other = model.clone();
        match self {
            Self::HalfAsFine => {
                other.mesh.nx /= 2;
                other.mesh.ny /= 2;
            }
            Self::TwiceAsFine => {
                other.mesh.nx *= 2;
                other.mesh.ny *= 2;
            }
        }
        other
    }
}

/// What a user should hear when no mesh can show `model`'s discretisation pattern up to
/// `fmax_hz` (the view's range): without it, the mesh's own direction-dependent error is left
/// for the physics to explain; `None` when a mesh can.
pub fn pattern_warning(model: &Model, fmax_hz: f64) -> Option<String> {
    PatternMesh::for_model(model, fmax_hz).is_none().then(|| {
        format!(
            "the model's discretisation error cannot be profiled up to {fmax_hz:.0} Hz: the mesh \
             half as fine has fewer than {RICHARDSON_MIN_ELEMENTS_PER_WAVELENGTH:.0} elements \
             per bending wavelength and the mesh twice as fine does not fit the memory budget; \
             a finding may be the mesh's own error (raise --max-memory or lower --fmax)"
        )
    })
}

/// The model's discretisation pattern per mode of `view` (below its range): ln(f_coarser /
/// f_finer) between the view's model and the model on the [`PatternMesh::for_model`] mesh,
/// modes paired by shape at `sensors`; 0 for a mode without a partner. Empty when no mesh can
/// show it.
pub fn discretisation_pattern(
    view: &ModelView,
    sensors: &[SensorPosition],
) -> Result<Vec<f64>, SimError> {
    match PatternMesh::for_model(&view.model, view.fmax_hz) {
        Some(mesh) => discretisation_pattern_on(view, sensors, mesh),
        None => Ok(Vec::new()),
    }
}

/// [`discretisation_pattern`] from the model on `mesh`, whichever it is.
pub fn discretisation_pattern_on(
    view: &ModelView,
    sensors: &[SensorPosition],
    mesh: PatternMesh,
) -> Result<Vec<f64>, SimError> {
    let other = mesh.mesh_of(&view.model);
    let sys = assemble(&other)?;
    let modes = lowest_modes(&sys, ModeRequest::BelowHz(1.25 * view.fmax_hz))?;
    let at = sensors_at(&other, sensors)?;
    let own = view.shapes_at(sensors)?;
    // The view's modes as "measured" modes, the other mesh's as the model: the pairing by
    // shape handles swapped orders.
    let as_measured: Vec<Mode> = own
        .iter()
        .enumerate()
        .map(|(i, shape)| Mode {
            frequency_hz: view.basis.frequencies_hz[i],
            damping_ratio: 0.0,
            frequency_std_hz: 0.0,
            damping_std: 0.0,
            frequency_order_std_hz: 0.0,
            damping_order_std: 0.0,
            frequency_sensor_std_hz: 0.0,
            damping_sensor_std: 0.0,
            mpc: 1.0,
            n_stable: 0,
            modal_snr_db: 0.0,
            shape: shape.iter().map(|&v| faer::c64::new(v, 0.0)).collect(),
        })
        .collect();
    let poles: Vec<ModelPole> = (0..modes.frequencies_hz.len())
        .map(|j| ModelPole {
            mode: j + 1,
            frequency_hz: modes.frequencies_hz[j],
            damped_frequency_hz: modes.frequencies_hz[j],
            damping_ratio: 0.0,
            shape: shape_at(&at, modes.shapes.as_ref(), j),
        })
        .collect();
    let (pairs, _, _) = pair_modes(&as_measured, &poles);
    let mut out = vec![0.0; own.len()];
    // frequency_rel is f_view / f_other − 1: the coarser mesh's frequency over the finer's.
    let sign = match mesh {
        PatternMesh::HalfAsFine => -1.0,
        PatternMesh::TwiceAsFine => 1.0,
    };
    for p in pairs {
        out[p.measured] = sign * p.frequency_rel.ln_1p();
    }
    Ok(out)
}

/// The model-form patterns per mode of `view` (below its range) that every frequency fit
/// profiles out: the discretisation pattern ([`discretisation_pattern`], when a mesh can show
/// it), and the twist at free edges ([`free_edge_twist_pattern`]) when it earns its place on
/// `evidence`: its column must lower the "no change" BIC (frequency residual floored at
/// `form_sigma`, as the scorer floors it) by [`super::procedure::MIN_BIC_GAIN`], the bar a
/// finding clears. Recordings of a thin-plate (Kirchhoff) model of the same plate differ from
/// the solid model in the modes that twist at free edges (1 × 1.5 × 0.02 m, free edges x0 and
/// x1: 0.38–1.09 % there, 0.06–0.24 % elsewhere; 0.27 % RMS around 1, f and f², 0.05 % with this
/// column), and without it a point mass of 0.86 kg was named in six of six such recordings of
/// the right model; kept always, the column also took part of real masses' signatures and
/// left false stiffer regions beside them (4 of 12 recordings of the solid model against 1).
pub fn model_form_patterns(
    view: &ModelView,
    sensors: &[SensorPosition],
    evidence: &super::evidence::Evidence,
    form_sigma: f64,
) -> Result<Vec<Vec<f64>>, SimError> {
    let mut patterns = vec![discretisation_pattern(view, sensors)?];
    patterns.retain(|p| p.len() == view.count && p.iter().any(|&v| v != 0.0));
    let twist = free_edge_twist_pattern(view)?;
    if twist.iter().any(|&v| v != 0.0)
        && twist_earns_its_place(view, evidence, &patterns, &twist, form_sigma)
    {
        patterns.push(twist);
    }
    Ok(patterns)
}

/// Whether adding `twist` to the nuisance columns `patterns` lowers the BIC of "no change" on
/// `evidence` by [`super::procedure::MIN_BIC_GAIN`].
fn twist_earns_its_place(
    view: &ModelView,
    evidence: &super::evidence::Evidence,
    patterns: &[Vec<f64>],
    twist: &[f64],
    form_sigma: f64,
) -> bool {
    let pairs = evidence.pairs_within(view);
    let n = pairs.len() as f64;
    let f_hz: Vec<f64> = pairs
        .iter()
        .map(|p| view.basis.frequencies_hz[p.model])
        .collect();
    let y: Vec<f64> = pairs.iter().map(|p| p.frequency_rel.ln_1p()).collect();
    let per_pair = |pattern: &[f64]| pairs.iter().map(|p| pattern[p.model]).collect::<Vec<f64>>();
    let without: Vec<Vec<f64>> = patterns.iter().map(|p| per_pair(p)).collect();
    let mut with = without.clone();
    with.push(per_pair(twist));
    let bic = |columns: &[Vec<f64>]| {
        let nuisance = Nuisance::new(&f_hz, columns);
        let r = nuisance.residual(&y);
        let floor = (n - nuisance.params()).max(1.0) * form_sigma * form_sigma;
        let rss = dot(&r, &r).max(floor).max(1e-300);
        n * (rss / n).ln() + nuisance.params() * n.ln()
    };
    n > 6.0 && bic(&without) - bic(&with) >= super::procedure::MIN_BIC_GAIN
}

/// The twist at the model's free edges per mode of `view` (below its range), relative: Σ over
/// the elements along every edge that is not pinned of (∂²w/∂x∂y)² times the element's length
/// along the edge, over the mode's stiffness ω² (shapes mass-normalised), scaled to a largest
/// value of 1. A thin-plate (Kirchhoff) model carries the twisting moment to a free edge, a
/// solid's or a thick plate's falls to zero within a layer about a thickness wide, so the two
/// differ in the modes that twist there, to first order in thickness over width.
pub fn free_edge_twist_pattern(view: &ModelView) -> Result<Vec<f64>, SimError> {
    use crate::sim::model::Edge;
    let model = &view.model;
    let (nx, ny) = (model.mesh.nx, model.mesh.ny);
    let (dx, dy) = (model.plate.lx / nx as f64, model.plate.ly / ny as f64);
    let pinned = model.pinned_edges()?;
    // Corners (x0, y0, x1, y1) of the elements along each free edge, and their lengths along it.
    let mut elements: Vec<[f64; 4]> = Vec::new();
    let mut lengths: Vec<f64> = Vec::new();
    for edge in [Edge::X0, Edge::X1, Edge::Y0, Edge::Y1] {
        if pinned.contains(&edge) {
            continue;
        }
        let (columns, rows, length) = match edge {
            Edge::X0 => (0..1, 0..ny, dy),
            Edge::X1 => (nx - 1..nx, 0..ny, dy),
            Edge::Y0 => (0..nx, 0..1, dx),
            Edge::Y1 => (0..nx, ny - 1..ny, dx),
        };
        for i in columns {
            for j in rows.clone() {
                let (x0, y0) = (i as f64 * dx, j as f64 * dy);
                elements.push([x0, y0, x0 + dx, y0 + dy]);
                lengths.push(length);
            }
        }
    }
    let points: Vec<SensorPosition> = elements
        .iter()
        .flat_map(|&[x0, y0, x1, y1]| [(x0, y0), (x1, y0), (x0, y1), (x1, y1)])
        .enumerate()
        .map(|(k, (x_m, y_m))| SensorPosition {
            id: format!("e{k}"),
            x_m,
            y_m,
        })
        .collect();
    if points.is_empty() {
        return Ok(vec![0.0; view.count]);
    }
    let shapes = view.shapes_at(&points)?;
    let mut out: Vec<f64> = shapes
        .iter()
        .enumerate()
        .map(|(n, w)| {
            let twist: f64 = w
                .chunks_exact(4)
                .zip(&lengths)
                .map(|(c, length)| ((c[3] - c[2] - c[1] + c[0]) / (dx * dy)).powi(2) * length)
                .sum();
            let omega = 2.0 * std::f64::consts::PI * view.basis.frequencies_hz[n];
            twist / (omega * omega).max(1e-300)
        })
        .collect();
    let top = out.iter().copied().fold(0.0, f64::max);
    if top > 0.0 {
        out.iter_mut().for_each(|v| *v /= top);
    }
    Ok(out)
}

/// The nuisance columns 1, f/f_max, (f/f_max)² and the model-form patterns over the paired
/// modes, orthonormalised, and least squares with them profiled out.
#[derive(Clone, Debug)]
pub struct Nuisance {
    basis: Vec<Vec<f64>>,
}

impl Nuisance {
    /// The nuisance over modes of undamped frequencies `frequencies_hz` (one per pair), with
    /// the model-form `patterns` (each one value per pair; others are left out).
    pub fn new(frequencies_hz: &[f64], patterns: &[Vec<f64>]) -> Self {
        let fmax = frequencies_hz.iter().copied().fold(1e-300, f64::max);
        let mut columns = vec![
            vec![1.0; frequencies_hz.len()],
            frequencies_hz.iter().map(|f| f / fmax).collect(),
            frequencies_hz.iter().map(|f| (f / fmax).powi(2)).collect(),
        ];
        columns.extend(
            patterns
                .iter()
                .filter(|p| p.len() == frequencies_hz.len())
                .cloned(),
        );
        let mut basis: Vec<Vec<f64>> = Vec::new();
        for c in columns {
            let original = dot(&c, &c).sqrt();
            let mut v = c;
            for _ in 0..2 {
                for b in &basis {
                    let d = dot(&v, b);
                    v.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
                }
            }
            // A column (nearly) in the span of the others adds nothing.
            let norm = dot(&v, &v).sqrt();
            if norm > 1e-6 * original {
                basis.push(v.iter().map(|x| x / norm).collect());
            }
        }
        Self { basis }
    }

    /// Parameters the nuisance spends.
    pub fn params(&self) -> f64 {
        self.basis.len() as f64
    }

    /// `v` with its nuisance part removed (the projection onto the nuisance's complement).
    pub fn residual(&self, v: &[f64]) -> Vec<f64> {
        let mut r = v.to_vec();
        for b in &self.basis {
            let d = dot(&r, b);
            r.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
        }
        r
    }

    /// Least squares of y = nuisance + m·a, m ≥ 0 when `non_negative`: (m, residual sum of
    /// squares).
    pub fn fit(&self, y: &[f64], a: &[f64], non_negative: bool) -> (f64, f64) {
        let (yr, ar) = (self.residual(y), self.residual(a));
        let (ay, aa) = (dot(&ar, &yr), dot(&ar, &ar));
        let mut m = if aa > 0.0 { ay / aa } else { 0.0 };
        if non_negative {
            m = m.max(0.0);
        }
        (m, (dot(&yr, &yr) - 2.0 * m * ay + m * m * aa).max(0.0))
    }
}

/// Σ aᵢbᵢ.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The small plate of `regression_coarse_model` (1 × 1.5 × 0.02 m, pinned on y0 and y1) on
    /// `nx` × `ny` × 2.
    fn small_plate(nx: usize, ny: usize) -> Model {
        let mut m = Model::reference_plate();
        (m.plate.lx, m.plate.ly) = (1.0, 1.5);
        (m.mesh.nx, m.mesh.ny) = (nx, ny);
        m
    }

    /// The reference plate keeps the cheap mesh over the diagnoses' usual range; the small
    /// plate's 12 × 18 model at 520 Hz (the probe's view) needs the finer one; a model whose
    /// finer mesh cannot fit gets no pattern.
    #[test]
    fn the_pattern_mesh_follows_the_waves() {
        let reference = Model::reference_plate();
        let pick = PatternMesh::for_model;
        assert_eq!(pick(&reference, 208.0), Some(PatternMesh::HalfAsFine));
        assert_eq!(pick(&reference, 400.0), Some(PatternMesh::TwiceAsFine));
        assert_eq!(
            pick(&small_plate(12, 18), 520.0),
            Some(PatternMesh::TwiceAsFine)
        );
        assert_eq!(
            pick(&small_plate(6, 8), 50.0),
            Some(PatternMesh::TwiceAsFine)
        );
        // 1 mm elements whose mesh half as fine still fails at 10 MHz, and whose mesh twice
        // as fine would need far more memory than any budget.
        let mut huge = reference;
        (huge.mesh.nx, huge.mesh.ny) = (2000, 3000);
        assert_eq!(pick(&huge, 1.0e7), None);
        assert!(pattern_warning(&huge, 1.0e7).is_some_and(|w| w.contains("--max-memory")));
        assert_eq!(pattern_warning(&Model::reference_plate(), 208.0), None);
    }

    /// Where both meshes show it, the pattern from the mesh half as fine and the one from the
    /// mesh twice as fine agree mode by mode in sign (the coarser mesh is the stiffer: a sign
    /// slip between the two would flip the finer one) and differ by the convergence rate:
    /// 2ᵖ for an error ∝ hᵖ, 4 for h². Measured 4.4–9.7 (p 2.1–3.3) on the small plate on
    /// 16 × 24 × 2, its 5 modes below 150 Hz (≥ 9 elements per wavelength even on 8 × 12).
    #[test]
    fn both_meshes_show_the_same_pattern() {
        let view = ModelView::new(&small_plate(16, 24), 150.0).unwrap();
        let sensors: Vec<SensorPosition> = (0..30)
            .map(|k| SensorPosition {
                id: format!("s{k}"),
                x_m: 0.07 + 0.86 * ((k % 5) as f64 + 0.3) / 5.0,
                y_m: 0.07 + 1.36 * ((k / 5) as f64 + 0.6) / 6.0,
            })
            .collect();
        let coarse = discretisation_pattern_on(&view, &sensors, PatternMesh::HalfAsFine).unwrap();
        let fine = discretisation_pattern_on(&view, &sensors, PatternMesh::TwiceAsFine).unwrap();
        assert!(coarse.len() >= 5, "{coarse:?}");
        for (c, f) in coarse.iter().zip(&fine) {
            assert!(
                *f > 0.0 && (3.0..12.0).contains(&(c / f)),
                "{coarse:?} {fine:?}"
            );
        }
    }

    /// On the small plate (pinned on y0 and y1, free along x0 and x1) the modes that bend
    /// along y only (1, 3 and 6 of the 12 × 18 model) hardly twist at the free edges, the ones
    /// with a nodal line along y (2 and 7) twist the most; a plate pinned on all four edges has
    /// no free edge and no pattern.
    #[test]
    fn the_twist_pattern_marks_the_modes_that_twist_at_free_edges() {
        let view = ModelView::new(&small_plate(12, 18), 400.0).unwrap();
        let q = free_edge_twist_pattern(&view).unwrap();
        assert_eq!(q.len(), view.count);
        for bending in [0, 2, 5] {
            assert!(q[bending] < 0.15, "{q:?}");
        }
        for twisting in [1, 6] {
            assert!(q[twisting] > 0.9, "{q:?}");
        }
        let mut pinned = small_plate(12, 18);
        pinned.supports.pinned_edges = ["x0", "x1", "y0", "y1"].map(String::from).to_vec();
        let view = ModelView::new(&pinned, 300.0).unwrap();
        assert!(free_edge_twist_pattern(&view)
            .unwrap()
            .iter()
            .all(|&v| v == 0.0));
    }

    /// An offset and an f² drift are explained away entirely; a pattern unlike both is not.
    #[test]
    fn offset_and_drift_are_profiled_out() {
        let f = [5.0, 11.0, 21.0, 30.0, 36.0, 48.0];
        let nuisance = Nuisance::new(&f, &[]);
        let y: Vec<f64> = f.iter().map(|f| 0.003 - 1e-6 * f * f).collect();
        let r = nuisance.residual(&y);
        assert!(dot(&r, &r) < 1e-20, "{r:?}");
        let a = [0.0, -0.01, 0.0, -0.01, 0.0, 0.0];
        let with: Vec<f64> = y.iter().zip(&a).map(|(y, a)| y + 0.5 * a).collect();
        let (m, rss) = nuisance.fit(&with, &a, true);
        assert!((m - 0.5).abs() < 1e-9 && rss < 1e-20, "{m} {rss}");
        assert_eq!(nuisance.fit(&with, &a.map(|v| -v), true).0, 0.0);
    }
}

//! Sizes of a simulation, estimated from the model alone, before anything is allocated.
//!
//! Why: a model is a few lines of TOML, and `nx = 5000, ny = 5000` asks for a system of 225
//! million dofs whose matrices alone would take terabytes. Every model is sized when it is
//! validated (so on loading, before the mesh is built) and refused, naming the sizes, the
//! estimate and the limit, when it would not fit in the process memory budget
//! ([`crate::budget`], `--max-memory`).

use super::model::{Model, SensorSpec};
use super::SimError;

/// Couplings per dof in the sparse stiffness and mass (27 neighbouring nodes × 3 directions).
const COUPLINGS_PER_DOF: f64 = 81.0;
/// Most basis vectors the Lanczos mode solver keeps.
const MAX_BASIS_VECTORS: f64 = 2000.0;
/// Sensors counted for a sensor file, which is read later.
const SENSORS_OF_A_FILE: usize = 1000;
/// Sustained floating-point rate the time estimate assumes, flop/s (this 2-core class of
/// machine on faer's kernels: the reference plate at 0–2 kHz is estimated at 26 s and took
/// 30.5 s on 2026-11-25).
pub const ASSUMED_FLOPS_PER_S: f64 = 5e9;
/// The fast method's modes reach this multiple of fmax ([`super::simulate::SimulateOptions`]).
const MODE_CUTOFF_FACTOR: f64 = 1.5;

/// What a model asks of the machine, counted from its mesh and output settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelSize {
    /// Unknowns of the assembled system (3 per node, before the supports remove some).
    pub dofs: f64,
    /// Nonzeros of the stiffness (the mass has as many).
    pub matrix_nonzeros: f64,
    /// Entries of the shift-invert factor (banded bound: 9 (nz + 1)(min(nx, ny) + 1) per dof).
    pub factor_entries: f64,
    /// Vectors of the Lanczos basis (at most `MAX_BASIS_VECTORS`).
    pub basis_vectors: f64,
    /// Sensors (a sensor file counts as `SENSORS_OF_A_FILE`).
    pub sensors: usize,
    /// Frequency lines 0 … fmax at df.
    pub frequency_lines: f64,
    /// Bending modes of the plate below 1.5 fmax, from the Kirchhoff modal density
    /// n = A/(4π)·√(ρh/D)·ω (patches, supports and in-plane modes not counted).
    pub plate_modes: f64,
}

impl ModelSize {
    /// The sizes of `model`.
    pub fn of(model: &Model) -> Self {
        let m = &model.mesh;
        let (nx, ny, nz) = (m.nx as f64, m.ny as f64, m.nz as f64);
        let dofs = 3.0 * (nx + 1.0) * (ny + 1.0) * (nz + 1.0);
        ModelSize {
            dofs,
            matrix_nonzeros: dofs * COUPLINGS_PER_DOF,
            factor_entries: dofs * 9.0 * (nz + 1.0) * (nx.min(ny) + 1.0),
            basis_vectors: dofs.min(MAX_BASIS_VECTORS),
            sensors: sensor_count(model).unwrap_or(SENSORS_OF_A_FILE),
            frequency_lines: (model.output.fmax / model.output.df).max(1.0) + 1.0,
            plate_modes: plate_modes_below(model, MODE_CUTOFF_FACTOR * model.output.fmax).min(dofs),
        }
    }

    /// Rough wall time of a fast simulation, s, at [`ASSUMED_FLOPS_PER_S`]: the banded
    /// factor (dofs × bandwidth²), Lanczos steps (2 per mode + 60, each two solves with the
    /// factor and a re-orthogonalisation against the steps so far) and the FRF products
    /// (lines × sensors × basis, complex; basis ≈ modes + their residual vectors). An order of
    /// magnitude, said before anything is allocated; soft viscoelastic patches add local
    /// modes it does not count.
    pub fn estimated_seconds(&self) -> f64 {
        let bandwidth = self.factor_entries / self.dofs.max(1.0);
        let factor = self.dofs * bandwidth * bandwidth;
        let steps = 2.0 * self.plate_modes + 60.0;
        let lanczos = steps * (4.0 * self.factor_entries + 4.0 * self.dofs * steps);
        let frf = self.frequency_lines * self.sensors as f64 * 2.0 * self.plate_modes * 8.0;
        (factor + lanczos + frf) / ASSUMED_FLOPS_PER_S
    }

    /// Bytes of the model's system: stiffness and mass (value + index per nonzero), the factor
    /// and the Lanczos basis.
    pub fn system_bytes(&self) -> f64 {
        self.matrix_nonzeros * 12.0 * 2.0
            + self.factor_entries * 8.0
            + self.dofs * self.basis_vectors * 8.0
    }

    /// Bytes of the outputs when every sensor's FRF (complex) and impulse response are held,
    /// twice over while the recording set is written.
    pub fn held_output_bytes(&self) -> f64 {
        self.sensors as f64 * (self.frequency_lines * 16.0 + 2.0 * self.frequency_lines * 8.0) * 2.0
    }

    /// One line for messages: `225.0 M dofs, 18.2 G nonzeros, factor 1.0e13 entries, about
    /// 3e9 s of work`.
    pub fn describe(&self) -> String {
        format!(
            "{} dofs, {} matrix nonzeros, factor fill {:.1e} entries, about {} of work",
            count(self.dofs),
            count(self.matrix_nonzeros),
            self.factor_entries,
            duration(self.estimated_seconds())
        )
    }
}

/// Sensors of a grid model (`None` for a sensor file, read later).
pub fn sensor_count(model: &Model) -> Option<usize> {
    match &model.output.sensors {
        SensorSpec::Grid { nx, ny } => Some(nx.saturating_mul(*ny)),
        SensorSpec::File { .. } => None,
    }
}

/// Bending modes of the model's plate below `f_hz` (Kirchhoff modal density, see
/// [`ModelSize::plate_modes`]); 0 for non-physical inputs (the model's validation reports
/// them).
fn plate_modes_below(model: &Model, f_hz: f64) -> f64 {
    let (p, m) = (&model.plate, &model.material);
    let h = p.thickness;
    let d = m.youngs_modulus * h.powi(3) / (12.0 * (1.0 - m.poisson * m.poisson));
    let n = p.lx * p.ly / (4.0 * std::f64::consts::PI)
        * (m.density * h / d).sqrt()
        * 2.0
        * std::f64::consts::PI
        * f_hz;
    if n.is_finite() {
        n.max(0.0)
    } else {
        0.0
    }
}

/// Seconds in a readable unit: `12 s`, `3.4 min`, `2.1 h`, `5.0e3 days`.
pub fn duration(seconds: f64) -> String {
    match seconds {
        s if !s.is_finite() => "an unbounded time".into(),
        s if s < 120.0 => format!("{s:.0} s"),
        s if s < 7200.0 => format!("{:.1} min", s / 60.0),
        s if s < 172_800.0 => format!("{:.1} h", s / 3600.0),
        s => format!("{:.1e} days", s / 86_400.0),
    }
}

/// `1234567` → `1.2 M`.
fn count(n: f64) -> String {
    match n {
        n if n >= 1e9 => format!("{:.1} G", n / 1e9),
        n if n >= 1e6 => format!("{:.1} M", n / 1e6),
        n if n >= 1e3 => format!("{:.1} k", n / 1e3),
        n => format!("{n:.0}"),
    }
}

/// Refuses `what` (e.g. "simulating", "the modes of") on `model` when `estimate_bytes` exceeds
/// the process memory budget; the message names the mesh, its sizes, the estimate and the limit.
pub fn check_budget(model: &Model, what: &str, estimate_bytes: f64) -> Result<(), SimError> {
    let size = ModelSize::of(model);
    crate::budget::check(
        &format!(
            "{what} a {}×{}×{} mesh with {} sensors ({})",
            model.mesh.nx,
            model.mesh.ny,
            model.mesh.nz,
            sensor_count(model).map_or("listed".into(), |n| n.to_string()),
            size.describe()
        ),
        estimate_bytes,
    )
    .map_err(|e| SimError::InvalidValue {
        key: "model size".into(),
        message: e.to_string(),
    })
}

/// Refuses a model whose system alone (no outputs) would not fit: checked by
/// [`Model::validate`], so on loading, before the mesh is built.
pub fn check_system_fits(model: &Model) -> Result<(), SimError> {
    check_budget(model, "assembling", ModelSize::of(model).system_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_time_estimate_grows_with_the_mesh_and_the_band() {
        let reference = Model::reference_plate();
        let base = ModelSize::of(&reference).estimated_seconds();
        assert!(base > 1.0 && base < 600.0, "{base}");
        let mut finer = reference.clone();
        finer.mesh.nx *= 2;
        finer.mesh.ny *= 2;
        assert!(ModelSize::of(&finer).estimated_seconds() > 4.0 * base);
        let mut wider = reference.clone();
        wider.output.fmax *= 2.0;
        assert!(ModelSize::of(&wider).estimated_seconds() > 1.5 * base);
        let mut huge = reference;
        huge.mesh.nx = 5000;
        huge.mesh.ny = 5000;
        let text = ModelSize::of(&huge).describe();
        assert!(text.contains("days of work"), "{text}");
    }
}

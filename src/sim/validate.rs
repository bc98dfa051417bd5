//! Validation of a [`Model`]: every impossible value is a [`SimError::InvalidValue`] naming its
//! TOML key, e.g. `plate.thickness: must be > 0, got -0.02`.

use super::error::{invalid, SimError};
use super::model::{Edge, Model, Patch, RegionMaterial, SensorSpec};

impl Model {
    /// Checks every value; the first impossible one is returned as an error naming its key.
    pub fn validate(&self) -> Result<(), SimError> {
        positive("plate.lx", self.plate.lx)?;
        positive("plate.ly", self.plate.ly)?;
        positive("plate.thickness", self.plate.thickness)?;
        for (key, n) in [
            ("mesh.nx", self.mesh.nx),
            ("mesh.ny", self.mesh.ny),
            ("mesh.nz", self.mesh.nz),
        ] {
            if n == 0 {
                return Err(invalid(key, "must be ≥ 1 element, got 0"));
            }
        }
        validate_material("material", &self.material_of_plate())?;
        for (i, name) in self.supports.pinned_edges.iter().enumerate() {
            Edge::parse(name, &format!("supports.pinned_edges[{i}]"))?;
        }
        let ex = &self.excitation;
        self.inside("excitation", ex.x, ex.y)?;
        if !matches!(ex.dir.as_str(), "x" | "y" | "z") {
            return Err(invalid(
                "excitation.dir",
                format!("expected \"x\", \"y\" or \"z\", got {:?}", ex.dir),
            ));
        }
        finite("excitation.force", ex.force)?;
        positive("output.fmax", self.output.fmax)?;
        positive("output.df", self.output.df)?;
        if self.output.df >= self.output.fmax {
            return Err(invalid(
                "output.df",
                format!(
                    "must be < output.fmax = {}, got {}",
                    self.output.fmax, self.output.df
                ),
            ));
        }
        if let SensorSpec::Grid { nx, ny } = self.output.sensors {
            if nx == 0 || ny == 0 {
                return Err(invalid(
                    "output.sensors",
                    format!("grid needs nx, ny ≥ 1, got nx = {nx}, ny = {ny}"),
                ));
            }
        }
        for (i, p) in self.patches.iter().enumerate() {
            self.validate_patch(i, p)?;
        }
        for (i, m) in self.point_masses.iter().enumerate() {
            let key = format!("point_mass[{i}]");
            self.inside(&key, m.x, m.y)?;
            non_negative(&format!("{key}.mass"), m.mass)?;
        }
        for (i, s) in self.edge_springs.iter().enumerate() {
            let key = format!("edge_spring[{i}]");
            Edge::parse(&s.edge, &format!("{key}.edge"))?;
            non_negative(
                &format!("{key}.stiffness_per_length"),
                s.stiffness_per_length,
            )?;
        }
        if let Some(d) = &self.damping {
            non_negative("damping.rayleigh.alpha", d.rayleigh.alpha)?;
            non_negative("damping.rayleigh.beta", d.rayleigh.beta)?;
        }
        // Last: a model of valid values may still be too large for this machine; refused here,
        // before the mesh or any matrix is allocated.
        super::limits::check_system_fits(self)
    }

    fn validate_patch(&self, i: usize, p: &Patch) -> Result<(), SimError> {
        let key = format!("patch[{i}]");
        for (axis, range, len) in [("x", p.x, self.plate.lx), ("y", p.y, self.plate.ly)] {
            let k = format!("{key}.{axis}");
            if !(range[0].is_finite() && range[1].is_finite() && range[0] < range[1]) {
                return Err(invalid(
                    k,
                    format!("expected [min, max] with min < max, got {range:?}"),
                ));
            }
            if range[0] < 0.0 || range[1] > len {
                return Err(invalid(
                    k,
                    format!("must lie inside the plate [0, {len}], got {range:?}"),
                ));
            }
        }
        if let Some(s) = &p.sls {
            if let Some(e) = p
                .youngs_modulus
                .filter(|&e| (e - s.e_inf).abs() > 1e-9 * s.e_inf)
            {
                // The law is the modulus (e_inf at rest, e_inf + e fast): a different one would
                // be dropped without a word. The same value (as the example writes it) is
                // redundant, not wrong.
                return Err(invalid(
                    format!("{key}.youngs_modulus"),
                    format!(
                        "an sls patch takes its modulus from its law (e_inf = {} Pa at rest); \
                         give youngs_modulus equal to e_inf or none, got youngs_modulus = {e}",
                        s.e_inf
                    ),
                ));
            }
            positive(&format!("{key}.sls.e"), s.e)?;
            positive(&format!("{key}.sls.e_inf"), s.e_inf)?;
            positive(&format!("{key}.sls.eta"), s.eta)?;
        }
        validate_material(&key, &self.material_of_patch(p))?;
        Ok(())
    }

    pub(crate) fn inside(&self, key: &str, x: f64, y: f64) -> Result<(), SimError> {
        let (lx, ly) = (self.plate.lx, self.plate.ly);
        if !(x.is_finite() && y.is_finite() && (0.0..=lx).contains(&x) && (0.0..=ly).contains(&y)) {
            return Err(invalid(
                key,
                format!("position must lie on the plate [0, {lx}] × [0, {ly}] m, got ({x}, {y})"),
            ));
        }
        Ok(())
    }
}

fn validate_material(key: &str, m: &RegionMaterial) -> Result<(), SimError> {
    positive(&format!("{key}.youngs_modulus"), m.youngs_modulus)?;
    positive(&format!("{key}.density"), m.density)?;
    let nu = m.poisson;
    if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
        return Err(invalid(
            format!("{key}.poisson"),
            format!("must be in (-1, 0.5), got {nu}"),
        ));
    }
    non_negative(&format!("{key}.loss_factor"), m.loss_factor)
}

fn positive(key: &str, v: f64) -> Result<(), SimError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(key, format!("must be > 0, got {v}")))
    }
}

fn non_negative(key: &str, v: f64) -> Result<(), SimError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(key, format!("must be ≥ 0, got {v}")))
    }
}

fn finite(key: &str, v: f64) -> Result<(), SimError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(invalid(key, format!("must be finite, got {v}")))
    }
}

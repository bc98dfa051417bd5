//! Whether a mesh resolves the bending waves up to the highest frequency asked of it.
//!
//! A structured mesh of C3D8I bricks is stiff for waves only a few elements long: its modes come
//! out high, the more so the higher they are, and nothing in the results says so. The report's
//! reference plate (2 × 3 × 0.02 m aluminium, pinned on two edges) on its 32 × 48 mesh, against
//! the same plate on 64 × 96, measured here mode by mode: +2.2 % at 7.4 elements per bending
//! wavelength (mode 100, 929 Hz), +3.5 % at 6.0 (1387 Hz), +4.9 % at 4.7 (2264 Hz), +5.8 % at 4.1
//! (3026 Hz). The reference model's fmax of 2 kHz sits at 5.0.

use super::model::{Model, RegionMaterial};

/// Fewest elements per bending wavelength at fmax before a warning: below it the highest modes
/// are more than about 6 % high (module documentation).
pub const MIN_ELEMENTS_PER_WAVELENGTH: f64 = 4.0;

/// Kirchhoff bending wavelength of a plate of `thickness_m` in `material` at `f_hz`, m:
/// λ = 2π (D / (ρ h ω²))^¼ with D = E h³ / (12 (1 − ν²)).
pub fn bending_wavelength_m(material: &RegionMaterial, thickness_m: f64, f_hz: f64) -> f64 {
    let h = thickness_m;
    let d = material.youngs_modulus * h.powi(3) / (12.0 * (1.0 - material.poisson.powi(2)));
    let omega = 2.0 * std::f64::consts::PI * f_hz;
    2.0 * std::f64::consts::PI * (d / (material.density * h * omega * omega)).powf(0.25)
}

/// The warning for a (validated) `model` whose elements are too coarse for bending waves at
/// `fmax_hz` in the plate or any patch (each at its own material; an SLS patch at its relaxed
/// modulus, where its waves are shortest); `None` when every region has at least
/// [`MIN_ELEMENTS_PER_WAVELENGTH`].
pub fn resolution_warning(model: &Model, fmax_hz: f64) -> Option<String> {
    let (name, element_m, wavelength_m) = shortest_wave(model, fmax_hz)?;
    let per_wavelength = wavelength_m / element_m;
    (per_wavelength < MIN_ELEMENTS_PER_WAVELENGTH).then(|| {
        let fine_hz = fmax_hz * (per_wavelength / MIN_ELEMENTS_PER_WAVELENGTH).powi(2);
        format!(
            "{per_wavelength:.1} elements per bending wavelength at {fmax_hz:.0} Hz in {name} \
             (elements {:.1} mm, wavelength {:.1} mm), below {MIN_ELEMENTS_PER_WAVELENGTH:.0}: \
             modes with waves that short come out high (more than ~6 %), and so does the \
             response built on them; refine the mesh in plane or keep below {fine_hz:.0} Hz",
            1e3 * element_m,
            1e3 * wavelength_m
        )
    })
}

/// Elements per bending wavelength at `fmax_hz` in the region of `model` whose waves are
/// shortest (the plate or a patch); `None` for a frequency that is not positive and finite.
pub fn elements_per_wavelength(model: &Model, fmax_hz: f64) -> Option<f64> {
    shortest_wave(model, fmax_hz).map(|(_, element_m, wavelength_m)| wavelength_m / element_m)
}

/// The region with the shortest bending waves at `fmax_hz`: its name, the mesh's longest
/// element side and the wavelength, m.
fn shortest_wave(model: &Model, fmax_hz: f64) -> Option<(String, f64, f64)> {
    if !(fmax_hz.is_finite() && fmax_hz > 0.0) {
        return None;
    }
    let element_m =
        (model.plate.lx / model.mesh.nx as f64).max(model.plate.ly / model.mesh.ny as f64);
    let regions = std::iter::once(("the plate".to_string(), model.material_of_plate())).chain(
        model
            .patches
            .iter()
            .enumerate()
            .map(|(p, patch)| (format!("patch[{p}]"), model.material_of_patch(patch))),
    );
    let (name, wavelength_m) = regions
        .map(|(name, m)| {
            (
                name,
                bending_wavelength_m(&m, model.plate.thickness, fmax_hz),
            )
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    Some((name, element_m, wavelength_m))
}

/// What a user should hear about `model` before its modes up to `fmax_hz` are computed: the
/// mesh's warnings ([`super::mesh::Mesh::warnings`]) and [`resolution_warning`].
pub fn model_warnings(model: &Model, fmax_hz: f64) -> Vec<String> {
    let mut warnings = super::mesh::Mesh::new(model).warnings;
    warnings.extend(resolution_warning(model, fmax_hz));
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::model::REFERENCE_PLATE_TOML;

    fn reference(nx: usize, ny: usize, fmax_hz: f64) -> Model {
        let text = REFERENCE_PLATE_TOML
            .replace("nx = 32", &format!("nx = {nx}"))
            .replace("ny = 48", &format!("ny = {ny}"))
            .replace("fmax = 2000.0", &format!("fmax = {fmax_hz:.1}"));
        Model::from_toml_str(&text).unwrap()
    }

    /// The reference plate has 5.0 elements per wavelength at its 2 kHz (no warning), 3.9 at
    /// 3.3 kHz, and a 16 × 24 mesh 2.5 at 2 kHz (warnings that name the frequency to keep to).
    #[test]
    fn coarse_meshes_at_high_fmax_are_warned_about() {
        let model = reference(32, 48, 2000.0);
        let lambda = bending_wavelength_m(&model.material_of_plate(), 0.02, 2000.0);
        assert!((lambda / 0.0625 - 5.0).abs() < 0.05, "{lambda}");
        assert_eq!(resolution_warning(&model, 2000.0), None);
        let w = resolution_warning(&model, 3300.0).expect("3.9 per wavelength");
        assert!(w.starts_with("3.9 elements per bending wavelength"), "{w}");
        let w = resolution_warning(&reference(16, 24, 2000.0), 2000.0).expect("2.5");
        assert!(w.contains("keep below 78"), "{w}");
    }

    /// A soft patch has shorter waves than the plate: it is the region named.
    #[test]
    fn the_softest_region_sets_the_wavelength() {
        let text = format!(
            "{}\n[[patch]]\nx = [0.5, 1.0]\ny = [0.5, 1.0]\nyoungs_modulus = 7.0e8\n",
            REFERENCE_PLATE_TOML
        );
        let model = Model::from_toml_str(&text).unwrap();
        let w = resolution_warning(&model, 500.0).expect("a soft patch");
        assert!(w.contains("in patch[0]"), "{w}");
    }
}

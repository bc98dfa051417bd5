//! `added_mass` from the frequency evidence (issue 9): a 2 kg mass concealed on a 324 kg plate
//! recorded on a finer mesh (48 × 72 × 2, 99 off-node sensors, 50 dB on mean power) than the
//! diagnosing model (32 × 48 × 2); a right model and a damped patch must not give a mass.

use dampscope::diagnose::evidence::{Evidence, ModelView};
use dampscope::diagnose::mass::{fit_point_mass, with_mass, MassFit};
use dampscope::modal::model_shapes::sensor_positions;
use dampscope::modal::{identify, ModalSettings, Recordings};
use dampscope::sim::model::Model;
use dampscope::source::recording_set::open_recording_set;

const MODEL: &str = "examples/plate-homogeneous.toml";
/// Where tests/data/diagnose/plate-48x72-mass.toml puts the mass (drawn from a fixed seed).
const TRUE_MASS: (f64, f64, f64) = (0.941, 1.196, 2.0);

/// The mass fit on `set` at 50 dB (seed 1), modes below 80 Hz, with the frequency RMS of the
/// model before and of the model with the found mass after.
fn fit(set: &str) -> (MassFit, f64, f64) {
    let mut opened = open_recording_set(std::path::Path::new(set)).expect("test data");
    let sensors = sensor_positions(&opened.sensors);
    let mut rec = Recordings::from_source(opened.source.as_mut(), 1 << 20).unwrap();
    rec.add_noise_mean_power(50.0, 1);
    let modes = identify(&rec, &ModalSettings::new(0.5, 80.0))
        .unwrap()
        .modes;
    let model = Model::load(std::path::Path::new(MODEL)).unwrap();
    let view = ModelView::new(&model, 1.3 * 80.0).unwrap();
    let before = Evidence::gather(&modes, view.poles_at(&sensors).unwrap());
    let found = fit_point_mass(&modes, &before, &view, &sensors)
        .unwrap()
        .expect("enough pairs");
    let updated = with_mass(&view, found.x_m, found.y_m, found.mass_kg).unwrap();
    let after = Evidence::gather(&modes, updated.poles_at(&sensors).unwrap());
    eprintln!(
        "{set}: {found:?}, frequency RMS {:?} → {:?} Hz",
        before.frequency_rms_hz(),
        after.frequency_rms_hz()
    );
    (
        found,
        before.frequency_rms_hz().unwrap(),
        after.frequency_rms_hz().unwrap(),
    )
}

/// Found where it is (of the four mirror images the frequencies cannot tell apart, the shapes
/// pick the right one), its mass within 30 % (1.72 kg measured), and the frequency RMS at
/// least halved by adding it.
#[test]
fn a_concealed_2_kg_mass_is_found_weighed_and_fixes_the_frequencies() {
    let (found, before, after) = fit("tests/data/diagnose/plate-48x72-mass");
    assert!(found.is_finding(), "{found:?}");
    let (x, y, m) = TRUE_MASS;
    let off = (found.x_m - x).hypot(found.y_m - y);
    assert!(off < 0.25, "{found:?}: {off:.3} m from ({x}, {y})");
    assert!((found.mass_kg / m - 1.0).abs() < 0.3, "{found:?}");
    assert!(
        after <= 0.5 * before,
        "frequency RMS {before} Hz → {after} Hz"
    );
}

/// A right model of another mesh: no mass pays for its parameters.
#[test]
fn a_right_model_gets_no_mass() {
    let (found, _, _) = fit("tests/data/modal/plate-48x72-homogeneous");
    assert!(!found.is_finding(), "{found:?}");
}

/// A damped patch also moves the damped frequencies (by up to 0.3 % here), but not as a mass
/// does: no mass is reported.
#[test]
fn a_damped_patch_is_not_a_mass() {
    let (found, _, _) = fit("tests/data/modal/plate-48x72-damped-patch");
    assert!(!found.is_finding(), "{found:?}");
}

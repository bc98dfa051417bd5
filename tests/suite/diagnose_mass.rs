//! `added_mass` from the frequency evidence (issue 9): a 2 kg mass concealed on a 324 kg plate
//! recorded on a finer mesh (48 × 72 × 2, 99 off-node sensors, 50 dB on mean power) than the
//! diagnosing model (32 × 48 × 2); a right model must not give a mass. The scan alone, on the
//! modes below 120 Hz (the whole procedure is tested by `diagnose_cli`).

use crate::common;

use dampscope::diagnose::evidence::{Evidence, ModelView};
use dampscope::diagnose::hypothesis::Hypothesis;
use dampscope::diagnose::mass::scan_point_mass;
use dampscope::diagnose::nuisance::model_form_patterns;
use dampscope::diagnose::procedure::MIN_BIC_GAIN;
use dampscope::diagnose::score::{Candidate, Scorer, DEFAULT_MODEL_FORM_SIGMA};
use dampscope::modal::{identify, ModalSettings};
use dampscope::sim::model::Model;

const MODEL: &str = "examples/plate-homogeneous.toml";
/// Modes identified up to here.
const FMAX_HZ: f64 = 120.0;
/// Where tests/data/diagnose/plate-48x72-mass.toml puts the mass (drawn from a fixed seed).
const TRUE_MASS: (f64, f64, f64) = (0.941, 1.196, 2.0);

/// The best point mass on `set` at 50 dB (seed 1) and its BIC gain over "no change".
fn scan(set: &str) -> (Candidate, f64) {
    let (rec, sensors) = common::noisy_set(set, 50.0, 1);
    let modes = identify(&rec, &ModalSettings::new(0.5, FMAX_HZ))
        .unwrap()
        .modes;
    let model = Model::load(std::path::Path::new(MODEL)).unwrap();
    let view = ModelView::new(&model, 1.3 * FMAX_HZ).unwrap();
    let evidence = Evidence::gather(&modes, view.poles_at(&sensors).unwrap());
    let scorer = Scorer::new(
        &modes,
        &evidence,
        &view,
        &model_form_patterns(&view, &sensors, &evidence, DEFAULT_MODEL_FORM_SIGMA).unwrap(),
        DEFAULT_MODEL_FORM_SIGMA,
    )
    .unwrap();
    let c = scan_point_mass(&scorer, &view).unwrap().expect("a point");
    let gain = scorer.none_bic() - c.bic;
    eprintln!(
        "{set}: {:?} ({} images), gain {gain:.1}",
        c.hypothesis,
        c.images.len()
    );
    (c, gain)
}

/// The true point is the one found or one of its mirror images (0.05 m grid), the first-order
/// mass within 30 % (1.79 kg measured), and it pays for its parameters and the 2400 points
/// searched.
#[test]
fn a_concealed_2_kg_mass_is_found_and_weighed() {
    let (c, gain) = scan("tests/data/diagnose/plate-48x72-mass");
    assert!(gain >= MIN_BIC_GAIN, "{gain}");
    let (tx, ty, tm) = TRUE_MASS;
    let off = std::iter::once(&c.hypothesis)
        .chain(&c.images)
        .map(|h| match h {
            Hypothesis::AddedMass { x_m, y_m, .. } => (x_m - tx).hypot(y_m - ty),
            other => panic!("{other:?}"),
        })
        .fold(f64::INFINITY, f64::min);
    assert!(off < 0.25, "{off}");
    let Hypothesis::AddedMass { mass_kg, .. } = c.hypothesis else {
        unreachable!()
    };
    assert!((mass_kg / tm - 1.0).abs() < 0.3, "{mass_kg}");
}

/// A right model of another mesh: no mass pays for its parameters.
#[test]
fn a_right_model_gets_no_mass() {
    let (_, gain) = scan("tests/data/modal/plate-48x72-homogeneous");
    assert!(gain < MIN_BIC_GAIN, "{gain}");
}

//! Missing loss from the damping evidence (issue 9): a concealed damped patch (the report's
//! patch with g = 50 % on a g = 5 % plate) recorded on a finer mesh (48 × 72 × 2, 99 off-node
//! sensors, 50 dB on mean power) than the diagnosing model (32 × 48 × 2). The modes below
//! 160 Hz (15 of them) fix the rectangle up to the plate's mirror symmetry.

use dampscope::diagnose::damping::{apply, fit_damping, DampingHypothesis, MIN_BIC_GAIN};
use dampscope::diagnose::evidence::{Evidence, ModelView};
use dampscope::modal::model_shapes::sensor_positions;
use dampscope::modal::{identify, ModalSettings, Recordings};
use dampscope::sim::model::Model;
use dampscope::source::recording_set::open_recording_set;

const MODEL: &str = "examples/plate-homogeneous.toml";
const FMAX_HZ: f64 = 160.0;
/// tests/data/modal/plate-48x72-damped-patch.toml: the patch and its extra loss factor.
const PATCH_CENTRE_M: (f64, f64) = (1.375, 2.1875);
const PATCH_DELTA_G: f64 = 0.45;

/// The diagnosing model, solved once.
fn model_view() -> ModelView {
    let model = Model::load(std::path::Path::new(MODEL)).unwrap();
    ModelView::new(&model, 1.3 * FMAX_HZ).unwrap()
}

/// The best damping hypothesis on `set` (50 dB, `seed`) against `view`, its BIC gain over "no change", and
/// the damping RMS before and after the model is updated with it.
fn diagnose(set: &str, seed: u64, view: &ModelView) -> (DampingHypothesis, f64, f64, f64) {
    let mut opened = open_recording_set(std::path::Path::new(set)).expect("test data");
    let sensors = sensor_positions(&opened.sensors);
    let mut rec = Recordings::from_source(opened.source.as_mut(), 1 << 20).unwrap();
    rec.add_noise_mean_power(50.0, seed);
    let modes = identify(&rec, &ModalSettings::new(0.5, FMAX_HZ))
        .unwrap()
        .modes;
    let before = Evidence::gather(&modes, view.poles_at(&sensors).unwrap());
    let fits = fit_damping(&before, view).unwrap();
    let none = fits
        .iter()
        .find(|f| f.hypothesis == DampingHypothesis::NoChange)
        .unwrap()
        .bic;
    let best = fits[0].clone();
    let updated = ModelView::new(&apply(&view.model, &best.hypothesis), 1.3 * FMAX_HZ).unwrap();
    let after = Evidence::gather(&modes, updated.poles_at(&sensors).unwrap());
    eprintln!(
        "{set} seed {seed}: {:?}, gain {:.1}, damping RMS {:?} → {:?}",
        best.hypothesis,
        none - best.bic,
        before.damping_rms(),
        after.damping_rms()
    );
    (
        best.hypothesis,
        none - best.bic,
        before.damping_rms().unwrap(),
        after.damping_rms().unwrap(),
    )
}

/// Three noise seeds: a region wins by far; the true patch is the rectangle found or one of its
/// mirror images (centre within 0.3 m); Δg within 30 % (0.42, 0.57, 0.42 measured); the
/// updated model halves the damping RMS at least (10×, measured).
#[test]
fn a_concealed_damped_patch_is_located_and_sized() {
    let view = model_view();
    for seed in 1..=3 {
        let (h, gain, before, after) =
            diagnose("tests/data/modal/plate-48x72-damped-patch", seed, &view);
        assert!(gain >= MIN_BIC_GAIN, "seed {seed}: {h:?}");
        let DampingHypothesis::Region {
            x_m,
            y_m,
            delta_g,
            images,
        } = h
        else {
            panic!("seed {seed}: {h:?}");
        };
        let centre = |x: [f64; 2], y: [f64; 2]| (0.5 * (x[0] + x[1]), 0.5 * (y[0] + y[1]));
        let (px, py) = PATCH_CENTRE_M;
        let off = std::iter::once((x_m, y_m))
            .chain(images.iter().copied())
            .map(|(x, y)| {
                let (cx, cy) = centre(x, y);
                (cx - px).hypot(cy - py)
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            off < 0.3,
            "seed {seed}: nearest image {off:.3} m from the patch"
        );
        assert!(
            (delta_g / PATCH_DELTA_G - 1.0).abs() < 0.3,
            "seed {seed}: Δg {delta_g}"
        );
        assert!(after <= 0.5 * before, "seed {seed}: {before} → {after}");
    }
}

/// A right model, and a model whose only fault is a missing mass: no loss is invented.
#[test]
fn no_loss_is_invented_for_a_right_model_or_a_missing_mass() {
    let view = model_view();
    for set in [
        "tests/data/modal/plate-48x72-homogeneous",
        "tests/data/diagnose/plate-48x72-mass",
    ] {
        let (h, gain, _, _) = diagnose(set, 1, &view);
        assert!(
            h == DampingHypothesis::NoChange || gain < MIN_BIC_GAIN,
            "{set}: {h:?} gains {gain}"
        );
    }
}

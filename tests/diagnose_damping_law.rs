//! `damping_law` (issue 9): a plate whose damping is a Rayleigh law (α = 9.4 1/s, β = 2.32e-5 s;
//! D from 14 % at 5 Hz to 1.5 % at 85 Hz), recorded on the 48 × 72 × 2 mesh (99 off-node
//! sensors, 50 dB on mean power), diagnosed against the 32 × 48 × 2 model with no damping at
//! all. Also the regression that found it: an undamped model's poles sit on the imaginary axis
//! and were all dropped (no pairs, "expected at least 4 modes paired, got 0").

mod common;

use dampscope::diagnose::procedure::{diagnose, DiagnoseSettings};
use dampscope::sim::model::Model;

/// Measured: α = 9.409 1/s, β = 2.316e-5 s; damping RMS 0.0445 → 0.0019.
#[test]
fn a_rayleigh_law_is_named_and_its_coefficients_found() {
    let (rec, sensors) = common::noisy_set("tests/data/diagnose/plate-48x72-rayleigh", 50.0, 1);
    let text = std::fs::read_to_string("examples/plate-homogeneous.toml")
        .unwrap()
        .replace("loss_factor = 0.05", "loss_factor = 0.0");
    let mut undamped: Model = toml::from_str(&text).unwrap();
    undamped.base_dir = Some(std::path::PathBuf::from("examples"));
    let settings = DiagnoseSettings {
        fmax_hz: 130.0,
        ..DiagnoseSettings::default()
    };
    let d = diagnose(&rec, &sensors, &undamped, &settings).unwrap();
    assert!(d.evidence.pairs.len() >= 12, "{}", d.evidence.pairs.len());
    assert_eq!(d.findings.len(), 1, "{:?}", d.findings);
    let f = &d.findings[0];
    assert_eq!(f.kind, "damping_law");
    assert_eq!(f.law.as_deref(), Some("rayleigh"));
    let (alpha, beta) = (f.parameters["alpha"], f.parameters["beta"]);
    assert!((alpha / 9.4 - 1.0).abs() < 0.3, "α {alpha}");
    assert!((beta / 2.32e-5 - 1.0).abs() < 0.3, "β {beta}");
    assert!(
        d.fit.after.damping_rms <= 0.5 * d.fit.before.damping_rms,
        "{:?}",
        d.fit
    );
}

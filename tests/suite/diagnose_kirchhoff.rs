//! `diagnose` on recordings from another simulator (issue 9): a Kirchhoff thin-plate
//! Rayleigh–Ritz model (`scripts/kirchhoff_sim.py`), not the FE plate dampscope diagnoses
//! with. Nothing is changed in the control: its frequencies differ from the model's by the
//! plate theory and mesh (−0.01 % in the median, 0.2 % scatter), and that must not be read as
//! missing physics, whatever the noise.

use crate::common;

fn control(seed: u64) {
    let d = common::diagnose_set(
        "tests/data/diagnose/plate-48x72-kirchhoff-control",
        50.0,
        seed,
        100.0,
    );
    assert!(d.evidence.pairs.len() >= 10, "{}", d.evidence.pairs.len());
    assert!(
        common::physics(&d).is_empty(),
        "seed {seed}: {:?}",
        d.findings
    );
    assert!(
        d.findings.iter().any(|f| f.kind == "noise_floor"),
        "50 dB on mean power is reported: {:?}",
        d.findings
    );
}

/// Two noise seeds; measured 13 s each in release, only `noise_floor` (49.3 dB) found.
#[test]
fn the_control_from_another_simulator_gets_no_physics() {
    control(1);
    control(2);
}

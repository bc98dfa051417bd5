//! `stiffness_change` end to end (issue 9): a region x 0.938–1.480, y 0.476–1.139 m whose
//! Young's modulus is 57.5 % of the plate's (4.025e10 Pa) in the recordings (48 × 72 × 2
//! mesh, 99 off-node sensors, 50 dB on mean power), against the nominal 32 × 48 × 2 model:
//! the modes that bend the region drop, the others hardly; the damping is unchanged.

use crate::common;

/// Measured (modes to 100 Hz, seed 1): x 0.62–1.44, y 0.44–1.12 m (centre 0.29 m from the
/// truth's — the region's width and its softness trade off on 12 modes), E 5.058e10 Pa
/// (+26 % of the truth's, i.e. −28 % instead of −42.5 %), frequency RMS 1.076 → 0.224 Hz.
/// The tolerances are the issue's: place within 0.3 m, size within 30 %.
#[test]
fn a_soft_region_is_named_placed_and_sized() {
    let d = common::diagnose_set(
        "tests/data/diagnose/plate-48x72-soft-region",
        50.0,
        1,
        100.0,
    );
    let physics = common::physics(&d);
    assert_eq!(physics.len(), 1, "{:?}", d.findings);
    let f = physics[0];
    assert_eq!(f.kind, "stiffness_change", "{f:?}");
    let off = common::region_offset_m(f, 0.5 * (0.938 + 1.480), 0.5 * (0.476 + 1.139));
    assert!(off < 0.3, "{off} m: {f:?}");
    let e = f.parameters["youngs_modulus"];
    assert!(common::rel_err(e, 4.025e10) < 0.3, "{e}");
    assert!(
        d.fit.after.frequency_rms_hz <= 0.5 * d.fit.before.frequency_rms_hz,
        "{:?}",
        d.fit
    );
}

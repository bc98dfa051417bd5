//! A damped patch under a 35 dB noise floor (issue 9): the g = 50 % patch x 1.125–1.625,
//! y 1.875–2.5 m (48 × 72 × 2 mesh, 99 off-node sensors) with white noise 35 dB below the
//! mean signal power — far harsher than 35 dB below the peak. The patch is still named,
//! placed and sized, and the noise is reported as what it is (`noise_floor`), not as damping.

use crate::common;

/// Measured (modes to 160 Hz, seed 1): x 1.12–1.69, y 1.94–2.50 m, g 0.468, noise floor
/// 31.5 dB in the median channel (3.5 dB under the 35 dB added: not examined), damping RMS
/// 0.01148 → 0.00114, 44 s in release.
#[test]
fn a_damped_patch_is_found_under_a_35_db_floor_and_the_floor_named() {
    let d = common::diagnose_set("tests/data/modal/plate-48x72-damped-patch", 35.0, 1, 160.0);
    let physics = common::physics(&d);
    assert_eq!(physics.len(), 1, "{:?}", d.findings);
    let f = physics[0];
    assert_eq!(f.kind, "localized_damping", "{f:?}");
    let off = common::region_offset_m(f, 1.375, 2.1875);
    assert!(off < 0.3, "{off} m: {f:?}");
    let g = f.parameters["loss_factor"];
    assert!(common::rel_err(g, 0.5) < 0.3, "{g}");
    let floor = d
        .findings
        .iter()
        .find(|f| f.kind == "noise_floor")
        .expect("a noise_floor finding");
    let snr = floor.snr_db.expect("its SNR");
    assert!((25.0..45.0).contains(&snr), "{snr} dB");
    assert!(
        d.fit.after.damping_rms <= 0.5 * d.fit.before.damping_rms,
        "{:?}",
        d.fit
    );
}

//! `viscoelastic_damping` end to end (issue 9): a damping layer x 1.005–1.482, y 1.836–2.510 m
//! whose loss factor peaks at 0.178 near 53.8 Hz (standard linear solid) and which adds 11.5 %
//! density there, in the recordings (48 × 72 × 2 mesh, 99 off-node sensors, 50 dB on mean
//! power), against the nominal 32 × 48 × 2 model. A frequency-independent damped patch
//! explains the damping of the modes near the peak but not the fall-off on both sides.

use crate::common;

/// Measured (modes to 100 Hz, seed 1): x 0.94–1.56, y 1.81–2.50 m (centre 0.02 m off), peak
/// 0.137 at 58 Hz, damping RMS 0.00424 → 0.00049, 55 s in release.
#[test]
fn a_viscoelastic_layer_is_named_with_its_peak() {
    let d = common::diagnose_set(
        "tests/data/diagnose/plate-48x72-viscoelastic-layer",
        50.0,
        1,
        100.0,
    );
    let f = common::assert_viscoelastic_layer(&d);
    let peak_hz = f.parameters["peak_frequency_hz"];
    assert!(common::rel_err(peak_hz, 53.8) < 0.3, "{peak_hz}");
}

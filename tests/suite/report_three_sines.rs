//! The report's Table 4.1 case: three decaying sines (170/200/230 Hz, D 2.5 %, A 1, ψ 0) in one
//! 150–250 Hz band. The report finds D_eq,ref = 2.16 %: below 2.5 % because of beating.

use crate::common::{decaying_sines, stft_estimate};
use dampscope::decay::EvaluationRange;

fn three_sines(fs: f64) -> Vec<f64> {
    decaying_sines(
        &[
            (170.0, 0.025, 1.0, 0.0),
            (200.0, 0.025, 1.0, 0.0),
            (230.0, 0.025, 1.0, 0.0),
        ],
        fs,
        2.0,
    )
}

#[test]
fn three_sine_equivalent_damping_table() {
    let fs = 4000.0;
    let x = three_sines(fs);
    for window_ms in [10.0, 20.0, 50.0] {
        for range in [EvaluationRange::T20, EvaluationRange::T30] {
            let est = stft_estimate(&x, fs, window_ms, 150.0, 250.0, range);
            eprintln!(
                "window {window_ms} ms, {range}: D_eq = {:?} (corrected {:?}), n = {}, flags {:?}",
                est.damping_ratio.map(|d| 100.0 * d),
                est.damping_ratio_corrected.map(|d| 100.0 * d),
                est.n_points,
                est.flags
            );
        }
    }
}

#[test]
fn report_setting_10_ms_window_20_db_drop_reproduces_2_16_percent() {
    // Chapter 4: a 100 Hz wide band is analysed with a 10 ms window (Δf = 100 Hz, eq. 2.13),
    // 50 % overlap, a 20 dB drop (−5…−25 dB), D from the band centre (200 Hz).
    let fs = 4000.0;
    let est = stft_estimate(
        &three_sines(fs),
        fs,
        10.0,
        150.0,
        250.0,
        EvaluationRange::T20,
    );
    let d_eq_pct = 100.0 * est.damping_ratio.unwrap();
    assert!(
        (d_eq_pct / 2.16 - 1.0).abs() < 0.005,
        "D_eq = {d_eq_pct} %, report 2.16 %"
    );
    // Beating pulls it below every mode's 2.5 %, as the report says.
    assert!(d_eq_pct < 2.5);
}

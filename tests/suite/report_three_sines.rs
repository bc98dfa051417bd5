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

/// Every window that leaves the decay enough frames reads D_eq below each mode's 2.5 % (the
/// beating of three equal modes pulls the band's decay down, as the report says) but within
/// 20 % of it, unflagged; a 50 ms window leaves 3–5 frames in the range and its number carries
/// a flag. Measured: 2.16/2.25 % (10 ms, T20/T30), 2.15/2.29 % (20 ms), 1.93/2.35 % flagged
/// `nonlinear_decay` (50 ms).
#[test]
fn three_sine_equivalent_damping_table() {
    let fs = 4000.0;
    let x = three_sines(fs);
    for window_ms in [10.0, 20.0, 50.0] {
        for range in [EvaluationRange::T20, EvaluationRange::T30] {
            let est = stft_estimate(&x, fs, window_ms, 150.0, 250.0, range);
            let d_pct = 100.0 * est.damping_ratio.expect("a clean decay gives a number");
            if window_ms <= 20.0 {
                assert!(
                    (2.0..2.5).contains(&d_pct) && est.flags.is_empty(),
                    "{window_ms} ms {range}: D_eq {d_pct} %, flags {:?}",
                    est.flags
                );
            } else {
                assert!(
                    !est.flags.is_empty(),
                    "{window_ms} ms {range}: {} frames, D_eq {d_pct} % unflagged",
                    est.n_points
                );
            }
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

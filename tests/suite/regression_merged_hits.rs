//! Found probing the defaults as a new user would: hits every 4 s over a −60 dB noise floor
//! became one decay per channel (the 100 dB end-drop is never reached over a noise floor) with
//! T60 ≈ 100 s, D ≈ 0.003 %, r² 0.63–0.75 and no flag. Now a new hit during a decay starts a new
//! decay, and a fit that bad, whatever its cause, gives no number (`poor_fit`).

use crate::common::{add_at, analyse_stft, gaussian_noise, rel_err, test_hit};
use dampscope::decay::{EvaluationRange, Flag};
use dampscope::pipeline::{AnalysisConfig, ResultRow};

const FS: f64 = 4000.0;
/// (f_hz, D) of the two modes every hit excites: T60 0.92 s and 0.73 s.
const MODES: [(f64, f64); 2] = [(120.0, 0.01), (300.0, 0.005)];

/// Hits of different strengths and phases at `times_s`, over white noise 60 dB below the
/// strongest peak.
fn hit_stream(times_s: &[f64], seconds: f64, seed: u64) -> Vec<f64> {
    let n = (seconds * FS) as usize;
    let mut x = gaussian_noise(n, 1e-3, seed);
    for (k, &t0) in times_s.iter().enumerate() {
        let hit = test_hit(&MODES, k, FS, seconds - t0);
        add_at(&mut x, (t0 * FS) as usize, &hit, 1.0);
    }
    x
}

fn analyse(x: Vec<f64>, config: &AnalysisConfig) -> Vec<ResultRow> {
    analyse_stft(x, FS, &[(100.0, 140.0), (280.0, 320.0)], config)
}

fn check_every_hit(rows: &[ResultRow], times_s: &[f64], range: EvaluationRange) {
    let decays = rows.iter().map(|r| r.decay).max().unwrap() + 1;
    assert_eq!(decays, times_s.len(), "one decay per hit");
    for r in rows {
        let onset = r.onset_s.unwrap();
        let t0 = times_s[r.decay];
        assert!(
            (onset - t0).abs() < 0.01,
            "decay {} starts at {onset} s, hit at {t0} s",
            r.decay
        );
        let want = MODES
            .iter()
            .find(|m| r.band.lo_hz < m.0 && m.0 < r.band.hi_hz)
            .unwrap()
            .1;
        let d = r
            .estimate
            .damping_ratio
            .unwrap_or_else(|| panic!("decay {} {:?}: no number", r.decay, r.estimate.flags));
        assert!(
            rel_err(d, want) < 0.03,
            "decay {} band {:?} ({range:?}): D {d} against {want}",
            r.decay,
            r.band
        );
    }
}

#[test]
fn hits_every_4_s_over_a_noise_floor_are_one_decay_each() {
    let times: Vec<f64> = (0..5).map(|k| 4.0 * k as f64).collect();
    for seed in [1, 2, 3] {
        let rows = analyse(hit_stream(&times, 20.0, seed), &AnalysisConfig::default());
        check_every_hit(&rows, &times, EvaluationRange::T30);
    }
}

#[test]
fn a_hit_before_the_last_decay_reached_the_floor_starts_a_new_decay() {
    // 0.8 s apart: the previous decay is still 40–50 dB above the floor.
    let times: Vec<f64> = (0..5).map(|k| 0.8 * k as f64).collect();
    let mut config = AnalysisConfig::default();
    config.estimate.range = EvaluationRange::T20;
    let rows = analyse(hit_stream(&times, 5.0, 7), &config);
    check_every_hit(&rows, &times, EvaluationRange::T20);
}

#[test]
fn merged_hits_give_no_number_when_splitting_is_off() {
    let times: Vec<f64> = (0..5).map(|k| 4.0 * k as f64).collect();
    let config = AnalysisConfig {
        segmentation: dampscope::pipeline::Segmentation {
            retrigger_jump_db: f64::INFINITY,
            ..Default::default()
        },
        ..Default::default()
    };
    let rows = analyse(hit_stream(&times, 20.0, 1), &config);
    assert_eq!(rows.len(), 2, "one merged decay, two bands");
    for r in &rows {
        assert!(
            r.estimate.damping_ratio.is_none()
                && r.estimate.edt_s.is_none()
                && r.estimate.has(Flag::MergedHits),
            "{:?}",
            r.estimate
        );
    }
}

//! Found on structural impact records (issue 15): two hits in one record were merged (flagged only
//! `nonlinear_decay`) or, with the buffering banks and a finite `--end-drop-db`, the second was
//! silently dropped. Now a record with two hits 0.3 s apart gives two decays with the same values
//! as each hit recorded alone, with every front end, default detection settings and a finite
//! `--end-drop-db`.

use std::collections::HashMap;

use crate::common::{decaying_sines, fresh_dir, gaussian_noise, run_dampscope};

const FS: u32 = 8000;
/// (f_hz, D): T60 0.14 s and 0.11 s, so a hit has fallen 130 dB 0.3 s later.
const MODES: [(f64, f64); 2] = [(400.0, 0.02), (1000.0, 0.01)];
const SECONDS: f64 = 0.8;

/// A record holding the hits (start s, amplitude) over white noise 100 dB below a unit hit.
fn record(hits: &[(f64, f64)], seed: u64) -> Vec<f64> {
    let n = (SECONDS * FS as f64) as usize;
    let mut x = gaussian_noise(n, 1e-5, seed);
    for &(t0, a) in hits {
        let modes: Vec<(f64, f64, f64, f64)> =
            MODES.iter().map(|&(f, d)| (f, d, a, 30.0)).collect();
        let start = (t0 * FS as f64) as usize;
        let hit = decaying_sines(&modes, FS as f64, SECONDS - t0);
        for (i, v) in hit.into_iter().enumerate().take(n - start) {
            x[start + i] += v;
        }
    }
    x
}

/// Rows of `analyze` as maps column → value.
fn analyze(path: &std::path::Path, extra: &[&str]) -> Vec<HashMap<String, String>> {
    let mut args = vec!["analyze", path.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = run_dampscope(&args, b"");
    assert!(
        o.status.code() == Some(0) || o.status.code() == Some(3),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = String::from_utf8(o.stdout).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(String::from))
                .collect()
        })
        .collect()
}

/// (f_center, D) of every band on a mode of the decay that starts within 10 ms of `onset_s`.
fn mode_rows(rows: &[HashMap<String, String>], onset_s: f64) -> Vec<(f64, Option<f64>)> {
    rows.iter()
        .filter(|r| (r["onset_s"].parse::<f64>().unwrap() - onset_s).abs() < 0.01)
        .filter(|r| {
            let (lo, hi): (f64, f64) = (r["f_lo"].parse().unwrap(), r["f_hi"].parse().unwrap());
            MODES.iter().any(|m| lo < m.0 && m.0 < hi)
        })
        .map(|r| {
            (
                r["f_center"].parse().unwrap(),
                r["damping_ratio"].parse().ok(),
            )
        })
        .collect()
}

#[test]
fn two_hits_0_3_s_apart_are_two_decays_equal_to_each_hit_alone() {
    let dir = fresh_dir("two-hits");
    let both = dir.join("both.wav");
    let first = dir.join("first.wav");
    let second = dir.join("second.wav");
    crate::common::write_float_wav(&both, &record(&[(0.05, 1.0), (0.35, 0.7)], 1), FS);
    crate::common::write_float_wav(&first, &record(&[(0.05, 1.0)], 1), FS);
    crate::common::write_float_wav(&second, &record(&[(0.35, 0.7)], 1), FS);
    for front_end in [
        &["--front-end", "stft", "--window-ms", "20"][..],
        &["--front-end", "goyder"][..],
        &["--front-end", "octave"][..],
        // A finite end drop ends the first decay before the second hit in the buffering banks;
        // the second hit once vanished there.
        &["--front-end", "goyder", "--end-drop-db", "60"][..],
        &["--front-end", "octave", "--end-drop-db", "60"][..],
    ] {
        let rows = analyze(&both, front_end);
        let decays: std::collections::BTreeSet<&str> =
            rows.iter().map(|r| r["onset_s"].as_str()).collect();
        assert_eq!(decays.len(), 2, "{front_end:?}: decays at {decays:?} s");
        // (A record of the second hit alone also holds a noise-only "decay" before it, with
        // no number; the hit's decay is the one at its onset.)
        for (decay, onset_s, alone) in [(0, 0.05, &first), (1, 0.35, &second)] {
            let got = mode_rows(&rows, onset_s);
            let want = mode_rows(&analyze(alone, front_end), onset_s);
            assert_eq!(got.len(), MODES.len(), "{front_end:?} decay {decay}");
            assert_eq!(want.len(), MODES.len(), "{front_end:?} hit {decay} alone");
            let mut numbers = 0;
            for ((f, d), (_, w)) in got.iter().zip(&want) {
                match (d, w) {
                    (Some(d), Some(w)) => {
                        numbers += 1;
                        assert!(
                            (d / w - 1.0).abs() < 0.02,
                            "{front_end:?} decay {decay} band {f} Hz: D {d} with the other hit, {w} alone"
                        );
                    }
                    (None, None) => {}
                    _ => panic!(
                        "{front_end:?} decay {decay} band {f} Hz: {d:?} with the other hit, {w:?} alone"
                    ),
                }
            }
            assert!(
                numbers >= 1,
                "{front_end:?} decay {decay}: no number at all"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

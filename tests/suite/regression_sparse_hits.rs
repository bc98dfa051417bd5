//! Found probing a monitoring stream (issue 12): a hit, then minutes of sensor noise. Over a
//! noise floor the 100 dB end-drop is never reached, so the decay stayed open — no row until
//! the next hit or the end of the input, and memory growing with the stream. Now a decay also
//! ends once every band has sat on its floor for the last half of it (and it is at least
//! `floor_min_s` old): its row comes while the input still arrives, with the same damping.

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::common::{analyse_stft, decaying_sines, gaussian_noise, rel_err};
use dampscope::decay::Flag;
use dampscope::pipeline::{AnalysisConfig, ResultRow, Segmentation};

const FS: f64 = 4096.0;
/// (f_hz, D) of the two modes every hit excites: T60 0.93 s and 1.22 s.
const MODES: [(f64, f64); 2] = [(118.0, 0.01), (452.0, 0.002)];

/// Hits at `times_s` over white noise `noise_db` below a unit-amplitude hit, `seconds` long.
fn sparse_hits(times_s: &[f64], seconds: f64, noise_db: f64, seed: u64) -> Vec<f64> {
    let n = (seconds * FS) as usize;
    let mut x = gaussian_noise(n, 10f64.powf(-noise_db / 20.0), seed);
    for (k, &t0) in times_s.iter().enumerate() {
        let a = [1.0, 0.6, 0.85][k % 3];
        let modes: Vec<(f64, f64, f64, f64)> = MODES
            .iter()
            .enumerate()
            .map(|(m, &(f, d))| (f, d, a, 41.0 * (k + 2 * m) as f64))
            .collect();
        let start = (t0 * FS) as usize;
        let hit = decaying_sines(&modes, FS, 10.0);
        for (i, v) in hit.into_iter().enumerate().take(n - start) {
            x[start + i] += v;
        }
    }
    x
}

fn analyse(x: Vec<f64>, config: &AnalysisConfig) -> Vec<ResultRow> {
    analyse_stft(x, FS, &[(100.0, 140.0), (430.0, 470.0)], config)
}

#[test]
fn sparse_hits_end_on_their_floor_with_the_damping_of_whole_records() {
    let times = [0.0, 50.0, 100.0];
    for seed in [1, 2, 3] {
        let x = sparse_hits(&times, 160.0, 60.0, seed);
        let rows = analyse(x.clone(), &AnalysisConfig::default());
        for r in &rows {
            let t0 = times[r.decay];
            assert!((r.onset_s.unwrap() - t0).abs() < 0.01, "{r:?}");
            let want = MODES
                .iter()
                .find(|m| r.band.lo_hz < m.0 && m.0 < r.band.hi_hz)
                .unwrap()
                .1;
            let d = r
                .estimate
                .damping_ratio
                .unwrap_or_else(|| panic!("seed {seed} decay {}: {:?}", r.decay, r.estimate.flags));
            assert!(rel_err(d, want) < 0.03, "seed {seed}: {d} vs {want}");
            assert!(!r.estimate.has(Flag::DecayTooLong));
        }
        // The same numbers as each hit analysed alone as a whole 40 s record (no floor end):
        // ending on the floor cuts nothing the estimate needs.
        let whole = AnalysisConfig {
            segmentation: Segmentation {
                floor_min_s: f64::INFINITY,
                ..Default::default()
            },
            ..Default::default()
        };
        for (k, &t0) in times.iter().enumerate() {
            let start = (t0 * FS) as usize;
            let alone = analyse(x[start..start + (40.0 * FS) as usize].to_vec(), &whole);
            for (a, b) in alone.iter().zip(rows.iter().filter(|r| r.decay == k)) {
                let (da, db) = (
                    a.estimate.damping_ratio.unwrap(),
                    b.estimate.damping_ratio.unwrap(),
                );
                assert!(
                    rel_err(db, da) < 0.01,
                    "seed {seed} hit {k}: {db} vs alone {da}"
                );
            }
        }
    }
}

#[test]
fn a_lone_hit_gives_its_row_while_the_stream_goes_on() {
    let x = sparse_hits(&[0.0], 40.0, 80.0, 7);
    let bytes: Vec<u8> = x.iter().flat_map(|v| (*v as f32).to_le_bytes()).collect();
    let mut child = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args([
            "analyze",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4096",
            "--channels",
            "1",
        ])
        .args(["--band", "100:140"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().skip(1) {
            let _ = tx.send(line.unwrap());
        }
    });
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(&bytes).unwrap();
    stdin.flush().unwrap();
    // The input stays open (a monitoring stream): the row must come anyway.
    let start = Instant::now();
    let row = rx.recv_timeout(Duration::from_secs(30));
    let waited = start.elapsed();
    drop(stdin);
    let _ = child.wait();
    let row = row.unwrap_or_else(|_| panic!("no row after {waited:?} while the stream was open"));
    let cells: Vec<&str> = row.split(',').collect();
    let d: f64 = cells[13]
        .parse()
        .unwrap_or_else(|_| panic!("no number: {row}"));
    assert!(rel_err(d, 0.01) < 0.03, "{row}");
}

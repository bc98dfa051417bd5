//! `dampscope map` end to end on recording sets with known local damping: the map holds each
//! sensor's truth, the global mean is the mean of the truths (eq. 4.3), a sensor that does not
//! move is counted as missing, never filled in; inputs without sensor positions are refused.

use std::path::Path;

use crate::common::{csv_rows, decaying_sines, fresh_dir, rel_err};
use dampscope::output::{write_recording_set, write_wav_f32};
use dampscope::source::{DecayKind, RecordingMeta, Sensor};

fn map(args: &[&str]) -> std::process::Output {
    crate::common::TestCommand::new(["map"].iter().chain(args)).output()
}

/// 4 × 3 sensors, 100 Hz decays with D rising along x (1 … 2.5 %), one sensor still.
fn known_set(dir: &Path) -> (Vec<Sensor>, Vec<Option<f64>>) {
    let fs = 2000.0;
    let mut sensors = Vec::new();
    let mut truth = Vec::new();
    let mut chans = Vec::new();
    for j in 0..3 {
        for i in 0..4 {
            let id = format!("n{}", sensors.len());
            sensors.push(Sensor {
                id,
                x_m: 0.5 * i as f64,
                y_m: 0.5 * j as f64,
                z_m: None,
                dir: "z".into(),
            });
            if (i, j) == (3, 2) {
                truth.push(None);
                chans.push(vec![0.0; 6000]);
            } else {
                let d = 0.01 + 0.005 * i as f64;
                truth.push(Some(d));
                chans.push(decaying_sines(&[(100.0, d, 1.0 + j as f64, 0.0)], fs, 3.0));
            }
        }
    }
    let meta = RecordingMeta {
        exponential_window_tau_s: None,
        kind: DecayKind::FreeDecay,
        ..Default::default()
    };
    write_recording_set(dir, &meta, &sensors, &[], fs, &chans).unwrap();
    (sensors, truth)
}

#[test]
fn map_of_a_set_with_known_local_damping() {
    let set = fresh_dir("maps-set");
    let (sensors, truth) = known_set(&set);
    let out = set.join("out");
    let o = map(&[
        set.to_str().unwrap(),
        "--band",
        "90:110",
        "--range",
        "t30",
        "--window-ms",
        "50",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let printed = String::from_utf8_lossy(&o.stdout);
    assert!(printed.contains("11/12"), "{printed}");

    // Every sensor's row carries its own truth (D uses f_center = 100 Hz = f).
    let rows = csv_rows(&out.join("results.csv"));
    for (s, t) in sensors.iter().zip(&truth) {
        let r = rows.iter().find(|r| r["channel"] == s.id);
        match t {
            Some(d) => {
                let got: f64 = r.unwrap()["damping_ratio"].parse().unwrap();
                assert!(rel_err(got, *d) < 0.01, "{}: {got} vs {d}", s.id);
            }
            None => assert!(
                r.is_none_or(|r| r["damping_ratio"].is_empty()),
                "{}: a still sensor must have no estimate",
                s.id
            ),
        }
    }
    let g = csv_rows(&out.join("global.csv"));
    assert_eq!(g.len(), 1);
    let known: Vec<f64> = truth.iter().flatten().copied().collect();
    let want = known.iter().sum::<f64>() / known.len() as f64;
    let mean: f64 = g[0]["mean_d"].parse().unwrap();
    assert!(rel_err(mean, want) < 0.01, "mean {mean} vs {want}");
    assert_eq!(g[0]["n_nodes"], "12");
    assert_eq!(g[0]["n_estimated"], "11");
    assert_eq!(
        g[0]["missing"].matches(':').count(),
        1,
        "{:?}",
        g[0]["missing"]
    );
    let std: f64 = g[0]["std_d"].parse().unwrap();
    assert!(std > 0.004, "the spread of the truths must show: {std}");

    // Every 2nd sensor: 0, 2, 4, … → x = 0 and 1 m only (D 1 % and 2 %).
    let needed = csv_rows(&out.join("sensors_needed.csv"));
    let k2 = needed.iter().find(|r| r["step"] == "2").unwrap();
    let m2: f64 = k2["mean_d"].parse().unwrap();
    assert!(rel_err(m2, 0.015) < 0.01, "k = 2: {m2}");

    let png = std::fs::read(out.join("map_90.0-110.0Hz.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG") && png.len() > 5000);
    let _ = std::fs::remove_dir_all(&set);
}

#[test]
fn sensor_positions_from_a_file_or_an_error() {
    let dir = fresh_dir("maps-wav");
    let fs = 2000.0;
    let chans: Vec<Vec<f64>> = [0.01, 0.02]
        .iter()
        .map(|d| decaying_sines(&[(100.0, *d, 1.0, 0.0)], fs, 3.0))
        .collect();
    let wav = dir.join("two.wav");
    let mut bytes = Vec::new();
    write_wav_f32(&mut bytes, fs as u32, &chans).unwrap();
    std::fs::write(&wav, bytes).unwrap();
    let out = dir.join("out");
    let args = |extra: &[&str]| {
        let mut a = vec![wav.to_str().unwrap(), "--band", "90:110", "--out"];
        a.push(out.to_str().unwrap());
        a.extend_from_slice(extra);
        a.iter().map(|s| s.to_string()).collect::<Vec<String>>()
    };
    let run = |a: Vec<String>| map(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let o = run(args(&[]));
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("no sensors"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // WAV channels are named ch0, ch1.
    let sensors = dir.join("sensors.csv");
    std::fs::write(&sensors, "id,x,y\nch0,0,0\nch1,1,0\n").unwrap();
    let o = run(args(&["--sensors", sensors.to_str().unwrap()]));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let g = csv_rows(&out.join("global.csv"));
    let mean: f64 = g[0]["mean_d"].parse().unwrap();
    assert!(rel_err(mean, 0.015) < 0.01, "{mean}");
    // Channels without a position are an error, not a silent drop.
    std::fs::write(&sensors, "id,x,y\nch0,0,0\n").unwrap();
    let o = run(args(&["--sensors", sensors.to_str().unwrap()]));
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no sensor position"));
    let _ = std::fs::remove_dir_all(&dir);
}

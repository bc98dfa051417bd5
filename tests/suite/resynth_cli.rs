//! `dampscope resynth`: the global damping per band applied to the undamped modes (report
//! eqs. 4.6–4.8), end to end through the binary.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::common::{csv_rows, fresh_dir};

fn dampscope(args: &[&str]) -> String {
    crate::common::TestCommand::new(args).ok()
}

fn num(r: &HashMap<String, String>, k: &str) -> f64 {
    r[k].parse().unwrap_or_else(|_| panic!("{k} = {:?}", r[k]))
}

/// The reference plate with `patch` appended, 0–`fmax` Hz, a coarse sensor grid.
fn model(dir: &Path, fmax: f64, patch: &str) -> PathBuf {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/plate-homogeneous.toml"
    ))
    .unwrap()
    .replace("fmax = 2000.0", &format!("fmax = {fmax}"))
    .replace(
        "sensors = { nx = 33, ny = 49 }",
        "sensors = { nx = 17, ny = 25 }",
    );
    let p = dir.join("model.toml");
    std::fs::write(&p, format!("{text}\n{patch}")).unwrap();
    p
}

fn global_csv(dir: &Path, d: f64) -> PathBuf {
    let p = dir.join(format!("global-{d}.csv"));
    let mut s = String::from("f_lo_hz,f_hi_hz,f_center_hz,n_nodes,n_estimated,mean_d\n");
    for k in 0..4 {
        let lo = 25.0 + 50.0 * k as f64;
        s.push_str(&format!("{lo},{},{},10,10,{d}\n", lo + 50.0, lo + 25.0));
    }
    // A band without an estimate is skipped, not invented.
    s.push_str("225,275,250,10,0,\n");
    std::fs::write(&p, s).unwrap();
    p
}

/// Homogeneous plate, g = 5 %: every mode's modal-strain-energy D is 2.5 %, so the bands' true
/// 2.5 % must give the model's own FRF back (ε < 1 %), and a 20 % low D must show in ε.
#[test]
fn the_true_damping_gives_the_model_back_and_a_wrong_one_does_not() {
    let dir = fresh_dir("resynth-homogeneous");
    let m = model(&dir, 250.0, "");
    let run = |d: f64, extra: &[&str]| {
        let out = dir.join(format!("out-{d}-{}", extra.len()));
        let g = global_csv(&dir, d);
        let mut args = vec!["resynth", "--model", m.to_str().unwrap(), "--global"];
        args.push(g.to_str().unwrap());
        args.extend_from_slice(&["--out", out.to_str().unwrap()]);
        args.extend_from_slice(extra);
        dampscope(&args);
        out
    };
    let good = run(0.025, &[]);
    let modes = csv_rows(&good.join("modes.csv"));
    assert!(modes.len() > 20, "{} modes", modes.len());
    for m in &modes {
        assert!((num(m, "d_model") - 0.025).abs() < 1e-9, "{m:?}");
    }
    let bands = csv_rows(&good.join("resynth.csv"));
    assert_eq!(bands.len(), 4, "the band without a mean is skipped");
    for b in &bands {
        // Measured 0.03–0.7 % (rising towards fmax: the static residual of the modes above
        // 3 fmax misses their dynamic amplification); with 1.5 fmax it was 1.4–4.1 %.
        assert!(num(b, "eps_driving_point") < 0.01, "{b:?}");
        assert!(num(b, "eps_all_sensors") < 0.01, "{b:?}");
    }
    let low = csv_rows(&run(0.02, &[]).join("resynth.csv"));
    for b in &low {
        assert!(
            num(b, "eps_all_sensors") > 0.05,
            "D 20 % low must show: {b:?}"
        );
    }
    // Without the residual flexibility the driving point carries the modal truncation error.
    let bare = csv_rows(&run(0.025, &["--no-residual"]).join("resynth.csv"));
    let worst = |rs: &[HashMap<String, String>]| {
        rs.iter()
            .map(|b| num(b, "eps_driving_point"))
            .fold(0.0, f64::max)
    };
    assert!(
        worst(&bare) > 3.0 * worst(&bands),
        "{} vs {}",
        worst(&bare),
        worst(&bands)
    );
    assert!(std::fs::read(good.join("resynth.png"))
        .unwrap()
        .starts_with(b"\x89PNG"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Report section 4.2.2 end to end: the plate with a g = 10 % patch, 50 Hz bands from 25 to
/// 425 Hz (20 ms Hann; the report's ninth band, 425–475 Hz, sits too close to Nyquist at
/// fmax = 500 Hz), simulate → map → resynth on a 17 × 25 sensor grid (every other node).
/// The report: the global D lies below the modes' numerical D in every band (Fig. 4.10), and
/// the re-synthesised FRF is off by up to 25 %, less at higher frequencies (Fig. 4.12).
/// Since nodes whose band energy is a neighbour's leakage (a 20 ms window spreads each mode
/// ±100 Hz) give no number, the global D holds the report's shortfall where it is large
/// (1.55, 1.97, 2.20, 2.33 % against 2.6 % below 225 Hz) and comes within a few per cent of the
/// modes above (2.43–2.73 %; the 350 Hz band reads 4 % high: the kept nodes are those where
/// the band's upper modes dominate, and D = 1.1/(T60 f_c) uses the centre frequency).
/// Measured: driving-point ε 20 % at 50 Hz, 1.4–3.2 % from 250 Hz on.
#[test]
fn report_patch_plate_global_damping_and_resynthesis() {
    let dir = fresh_dir("resynth-patch");
    let m = model(
        &dir,
        500.0,
        "[[patch]]\nx = [1.125, 1.625]\ny = [1.875, 2.5]\nloss_factor = 0.10\n",
    );
    let (set, map, out) = (dir.join("set"), dir.join("map"), dir.join("out"));
    let s = |p: &Path| p.to_str().unwrap().to_string();
    dampscope(&["simulate", "--model", &s(&m), "--out", &s(&set)]);
    dampscope(&[
        "map",
        &s(&set),
        "--bands",
        "25:425:50",
        "--window-ms",
        "20",
        "--max-figures",
        "1",
        "--out",
        &s(&map),
    ]);
    dampscope(&[
        "resynth",
        "--model",
        &s(&m),
        "--global",
        &s(&map.join("global.csv")),
        "--out",
        &s(&out),
    ]);
    let bands = csv_rows(&out.join("resynth.csv"));
    assert_eq!(bands.len(), 8);
    for (k, b) in bands.iter().enumerate() {
        let (g, model) = (num(b, "d_global"), num(b, "d_model_mean"));
        if k < 4 {
            assert!(
                g < 0.95 * model,
                "global {g} must lie below the modes' {model}"
            );
        } else {
            assert!(
                (g / model - 1.0).abs() < 0.08,
                "global {g} against the modes' {model}"
            );
        }
        assert!(num(b, "eps_driving_point") < 0.30, "{b:?}");
    }
    let eps: Vec<f64> = bands.iter().map(|b| num(b, "eps_driving_point")).collect();
    let high = eps[4..].iter().sum::<f64>() / 4.0;
    assert!(eps[0] > 2.0 * high, "error falls with frequency: {eps:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

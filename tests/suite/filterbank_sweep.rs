//! Issue 4 acceptance: the reduced sweep writes its CSV and PNG, and `compare` runs on a file.

use std::path::PathBuf;

use clap::Parser;
use dampscope::analysis::sweep::{sweep_to_dir, SweepConfig};
use dampscope::cli::compare::{run, CompareArgs};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dampscope-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn reduced_sweep_writes_csv_and_png_with_expected_physics() {
    let dir = temp_dir("sweep");
    let rows = sweep_to_dir(&SweepConfig::reduced(), &dir).unwrap();
    // 2 f × 2 D × (single, pair) × 4 front ends.
    assert_eq!(rows.len(), 32);
    let png = std::fs::read(dir.join("sweep.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert!(png.len() > 10_000, "a real figure, {} bytes", png.len());
    let csv = std::fs::read_to_string(dir.join("sweep.csv")).unwrap();
    assert_eq!(csv.lines().count(), 33);
    assert!(csv.starts_with("case,f_hz,d_true,t60_true_s,front_end,bt,d_est,rel_err,flags"));
    for r in rows.iter().filter(|r| r.case == "single") {
        if r.front_end == "goyder" {
            let e = r.rel_err.expect("Goyder always estimates single modes");
            assert!(e.abs() < 0.02, "{r:?}");
        }
    }
    // 800 Hz, D = 2 %: T60 = 69 ms, far too short for 100 ms hops.
    let fast = rows
        .iter()
        .find(|r| {
            r.case == "single" && r.front_end == "stft-200ms" && r.f_hz == 800.0 && r.d_true == 0.02
        })
        .unwrap();
    assert_eq!(fast.d_est, None, "{fast:?}");
    assert!(fast.flags.contains("too_few_frames"), "{fast:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[derive(Parser)]
struct Wrapper {
    #[command(flatten)]
    args: CompareArgs,
}

#[test]
fn compare_reads_a_csv_and_writes_a_side_by_side_table() {
    let dir = temp_dir("compare");
    std::fs::create_dir_all(&dir).unwrap();
    let fs = 4000.0;
    let mut text = String::from("# fs=4000\n");
    for i in 0..8000 {
        let t = i as f64 / fs;
        let w = 2.0 * std::f64::consts::PI * 400.0;
        text.push_str(&format!("{}\n", (-0.01 * w * t).exp() * (w * t).sin()));
    }
    let input = dir.join("decay.csv");
    std::fs::write(&input, text).unwrap();
    let w = Wrapper::try_parse_from([
        "compare",
        input.to_str().unwrap(),
        "--band",
        "380:420",
        "--front-ends",
        "stft,goyder,octave",
        "--out",
        dir.to_str().unwrap(),
    ])
    .unwrap();
    run(&w.args).unwrap();
    let out = std::fs::read_to_string(dir.join("compare.csv")).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 4, "{out}");
    assert!(
        lines[1].contains(",stft,") && lines[1].contains("too_few_frames"),
        "{out}"
    );
    let goyder: Vec<&str> = lines[2].split(',').collect();
    assert_eq!(goyder[3], "goyder");
    let d: f64 = goyder[4].parse().unwrap();
    assert!((d - 1.0).abs() < 0.02, "D = {d} %");
    let bad = Wrapper::try_parse_from(["compare", input.to_str().unwrap(), "--front-ends", "fft"]);
    assert!(bad.is_err(), "an unknown front end is a usage error");
    let _ = std::fs::remove_dir_all(&dir);
}

//! Issue 3 acceptance, end to end through the binary: the reference plate reduced to mode 7
//! (g = 5 %, report section 3.2, Fig. 3.6) streamed from `dampscope simulate --stdout` into
//! `dampscope analyze -` in the report's 55 Hz band (52.5–57.5 Hz, 200 ms Hann, 30 dB drop).
//! The report finds 2.6 % uncorrected; the corrected value must be within 2 % of 2.5 %.

use std::process::{Command, Stdio};

#[test]
fn plate_mode_7_alone_gives_2_5_percent_through_simulate_and_analyze() {
    let dir = std::env::temp_dir().join(format!("dampscope-m7-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/plate-homogeneous.toml"
    ))
    .unwrap()
    .replace(
        "sensors = { nx = 33, ny = 49 }",
        "sensors = { nx = 5, ny = 4 }",
    );
    let path = dir.join("m7.toml");
    std::fs::write(&path, model).unwrap();

    let exe = env!("CARGO_BIN_EXE_dampscope");
    let mut sim = Command::new(exe)
        .args([
            "simulate",
            "--model",
            path.to_str().unwrap(),
            "--keep-modes",
            "7",
            "--stdout",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let analyze = Command::new(exe)
        .args(["analyze", "-", "--band", "52.5:57.5", "--range", "t30"])
        .stdin(sim.stdout.take().unwrap())
        .output()
        .unwrap();
    assert!(sim.wait().unwrap().success());
    assert!(
        analyze.status.success(),
        "{}",
        String::from_utf8_lossy(&analyze.stderr)
    );
    let rows = dampscope::output::read_table(&String::from_utf8(analyze.stdout).unwrap()).unwrap();
    let mut measured = 0;
    for r in &rows {
        if r["flags"].contains("no_energy") {
            // Sensors on the pinned edges do not move.
            continue;
        }
        let d: f64 = r["damping_ratio"].parse().unwrap();
        let dc: f64 = r["damping_ratio_corrected"].parse().unwrap();
        assert!(
            (d - 0.026).abs() < 0.0005,
            "uncorrected {d} (report: 2.6 %)"
        );
        assert!((dc / 0.025 - 1.0).abs() < 0.02, "corrected {dc}");
        measured += 1;
    }
    assert_eq!(measured, 10, "the 10 sensors off the pinned edges");
    let _ = std::fs::remove_dir_all(&dir);
}

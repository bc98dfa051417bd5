//! `dampscope modes` end to end (through `cli::modes::run`), and the example model files.

use dampscope::cli::modes::{run, ModesArgs};
use dampscope::sim::model::Model;

#[test]
fn modes_cli_writes_csv_of_the_lowest_modes() {
    let dir = std::env::temp_dir().join(format!("dampscope-modes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("coarse.toml");
    let text = dampscope::sim::model::REFERENCE_PLATE_TOML
        .replace("nx = 32", "nx = 8")
        .replace("ny = 48", "ny = 12");
    std::fs::write(&model, text).unwrap();
    let out = dir.join("modes.csv");
    run(&ModesArgs {
        model: Some(model),
        count: Some(5),
        fmax: None,
        out: Some(out.clone()),
        timings: true,
    })
    .unwrap();
    let csv = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "mode,frequency_hz");
    assert_eq!(lines.len(), 6);
    let f1: f64 = lines[1].split(',').nth(1).unwrap().parse().unwrap();
    // 8 × 12 × 2 mesh: within 2 % of the Levy value 5.230 Hz.
    assert!((f1 - 5.230).abs() / 5.230 < 0.02, "{f1}");
}

#[test]
fn every_example_model_parses_and_validates() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let model = Model::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            dampscope::sim::assembly::assemble(&model)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            n += 1;
        }
    }
    assert!(n >= 3, "expected the three example models, found {n}");
}

/// The full speed run of the acceptance (all modes below 2 kHz of the reference mesh) with
/// `--timings`; run with `cargo test --test sim_modes_cli -- --ignored --nocapture`.
#[test]
#[ignore = "speed run (reference mesh, ~220 modes); timed by benches/modes.rs and --timings"]
fn reference_plate_modes_below_2khz_with_timings() {
    let out = std::env::temp_dir().join(format!("dampscope-modes2k-{}.csv", std::process::id()));
    run(&ModesArgs {
        model: None,
        count: None,
        fmax: Some(2000.0),
        out: Some(out.clone()),
        timings: true,
    })
    .unwrap();
    let csv = std::fs::read_to_string(&out).unwrap();
    let n = csv.lines().count() - 1;
    eprintln!("{n} modes below 2 kHz");
    assert!((150..300).contains(&n), "{n}");
}

//! `dampscope modes` end to end (through `cli::modes::run`), and the example model files.

use dampscope::cli::modes::{run, ModesArgs};
use dampscope::sim::model::Model;

#[test]
fn modes_cli_writes_csv_of_the_lowest_modes() {
    let dir = crate::common::fresh_dir("modes");
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
        damping: false,
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

/// `--damping` on a homogeneous plate (g = 5 %): every pole has D = sin(atan(0.05)/2) and the
/// damped frequency f·Re√(1 + 0.05j); with a patch of g = 50 % the poles' D differ from mode to
/// mode and all lie between the plate's and the patch's.
#[test]
fn modes_cli_damping_gives_each_pole() {
    let dir = crate::common::fresh_dir("poles");
    let coarse = dampscope::sim::model::REFERENCE_PLATE_TOML
        .replace("nx = 32", "nx = 8")
        .replace("ny = 48", "ny = 12");
    let patched =
        format!("{coarse}\n[[patch]]\nx = [1.0, 1.5]\ny = [1.75, 2.5]\nloss_factor = 0.5\n");
    let mut spread = Vec::new();
    for (name, text) in [("plain", coarse), ("patched", patched)] {
        let model = dir.join(format!("{name}.toml"));
        std::fs::write(&model, text).unwrap();
        let out = dir.join(format!("{name}.csv"));
        run(&ModesArgs {
            model: Some(model),
            count: Some(8),
            fmax: None,
            out: Some(out.clone()),
            timings: false,
            damping: true,
        })
        .unwrap();
        let csv = std::fs::read_to_string(&out).unwrap();
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(
            lines[0],
            "mode,frequency_hz,damped_frequency_hz,damping_ratio"
        );
        assert_eq!(lines.len(), 9, "{csv}");
        let d: Vec<f64> = lines[1..]
            .iter()
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
                if name == "plain" {
                    assert!((v[3] / 0.0249766 - 1.0).abs() < 1e-4, "{l}");
                    assert!((v[2] / (v[1] * 1.000312) - 1.0).abs() < 1e-5, "{l}");
                }
                v[3]
            })
            .collect();
        spread.push(d);
    }
    let patched = &spread[1];
    assert!(
        patched.iter().all(|&d| d > 0.025 && d < 0.25),
        "{patched:?}"
    );
    let (lo, hi) = patched
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &d| (a.min(d), b.max(d)));
    assert!(hi > 1.1 * lo, "{patched:?}");
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
        damping: false,
    })
    .unwrap();
    let csv = std::fs::read_to_string(&out).unwrap();
    let n = csv.lines().count() - 1;
    eprintln!("{n} modes below 2 kHz");
    assert!((150..300).contains(&n), "{n}");
}

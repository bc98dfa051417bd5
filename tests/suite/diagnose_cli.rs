//! `dampscope diagnose` (issue 9) on recordings made unlike the diagnosing model (48 × 72 × 2
//! mesh, 99 off-node sensors, 50 dB on mean power) against the reference model (32 × 48 × 2):
//! a concealed 2 kg mass is named, placed and weighed, the outputs follow FORMATS.md §5, and
//! the updated model loads and carries the mass; a right model gets no finding. The mass
//! case compares the modes to 160 Hz: below ~120 Hz the coarse model's own frequency error
//! (0.1–0.3 %, growing with f) is as large as the mass's effect, and the raw frequency RMS
//! cannot halve (0.273 → 0.143 Hz at 120 Hz, 0.673 → 0.286 Hz at 160 Hz, measured).

use crate::common;

use dampscope::diagnose::procedure::{diagnose, DiagnoseSettings};
use dampscope::modal::model_shapes::sensor_positions;
use dampscope::modal::Recordings;
use dampscope::sim::model::Model;
use dampscope::source::recording_set::open_recording_set;

const MODEL: &str = "examples/plate-homogeneous.toml";
/// Where tests/data/diagnose/plate-48x72-mass.toml puts the mass.
const TRUE_MASS: (f64, f64, f64) = (0.941, 1.196, 2.0);

#[test]
fn the_command_names_places_and_weighs_a_concealed_mass() {
    let dir = common::fresh_dir("diagnose-mass");
    let out = common::run_dampscope(
        &[
            "diagnose",
            "tests/data/diagnose/plate-48x72-mass",
            "--model",
            MODEL,
            "--add-noise-db",
            "50",
            "--fmax",
            "160",
            "--out",
            dir.to_str().unwrap(),
        ],
        b"",
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("finding: added_mass"), "{stdout}");
    // diagnosis.json as FORMATS.md §5 has it.
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("diagnosis.json")).unwrap())
            .unwrap();
    check_schema(&json);
    let all = json["findings"].as_array().unwrap();
    // The noise added at 50 dB is reported apart (measured 48.8 dB on the median channel).
    let noise: Vec<_> = all.iter().filter(|f| f["kind"] == "noise_floor").collect();
    assert_eq!(noise.len(), 1, "{json}");
    let snr = noise[0]["snr_db"].as_f64().unwrap();
    assert!((snr - 50.0).abs() < 3.0, "{json}");
    let findings: Vec<_> = all.iter().filter(|f| f["kind"] != "noise_floor").collect();
    assert_eq!(findings.len(), 1, "{json}");
    let f = findings[0];
    assert_eq!(f["kind"], "added_mass");
    assert!(f["summary"].as_str().unwrap().contains("kg"));
    let (x, y) = (
        f["point"]["x"].as_f64().unwrap(),
        f["point"]["y"].as_f64().unwrap(),
    );
    let (tx, ty, tm) = TRUE_MASS;
    assert!((x - tx).hypot(y - ty) < 0.25, "{json}");
    let m = f["parameters"]["mass_kg"].as_f64().unwrap();
    assert!((m / tm - 1.0).abs() < 0.3, "{json}");
    let c = f["confidence"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&c) && c > 0.9, "{json}");
    for when in ["before", "after"] {
        let fit = &json["fit"][when];
        assert!(fit["damping_rms"].as_f64().unwrap() >= 0.0, "{json}");
        assert!(fit["frequency_rms_hz"].as_f64().unwrap() >= 0.0, "{json}");
        assert!(fit["frf_error"].as_f64().unwrap() > 0.0, "{json}");
    }
    // The mass brings the FRFs closer too (eq. 4.8: 0.117 → 0.084 measured).
    let frf = |w: &str| json["fit"][w]["frf_error"].as_f64().unwrap();
    assert!(frf("after") < 0.9 * frf("before"), "{json}");
    let before = json["fit"]["before"]["frequency_rms_hz"].as_f64().unwrap();
    let after = json["fit"]["after"]["frequency_rms_hz"].as_f64().unwrap();
    assert!(after <= 0.5 * before, "{before} → {after}");
    assert_eq!(json["updated_model"], "updated-model.toml");
    // The updated model loads from the output directory and holds the mass.
    let updated = Model::load(&dir.join("updated-model.toml")).unwrap();
    assert_eq!(updated.point_masses.len(), 1);
    assert!((updated.point_masses[0].mass - m).abs() < 1e-9);
    dampscope::sim::assembly::assemble(&updated).unwrap();
    let modes = common::csv_rows(&dir.join("modes.csv"));
    assert!(modes.len() >= 10, "{}", modes.len());
    assert!(std::fs::read_to_string(dir.join("report.md"))
        .unwrap()
        .contains("added_mass"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The procedure on a right model of another mesh: no finding, the fit unchanged.
#[test]
fn a_right_model_gets_no_finding() {
    let mut set = open_recording_set(std::path::Path::new(
        "tests/data/modal/plate-48x72-homogeneous",
    ))
    .unwrap();
    let sensors = sensor_positions(&set.sensors).unwrap();
    let mut rec = Recordings::from_source(set.source.as_mut(), 1 << 20).unwrap();
    rec.add_noise_mean_power(50.0, 2);
    let model = Model::load(std::path::Path::new(MODEL)).unwrap();
    let settings = DiagnoseSettings {
        fmax_hz: 80.0,
        ..DiagnoseSettings::default()
    };
    let d = diagnose(&rec, &sensors, &model, &settings).unwrap();
    assert!(d.is_clean(), "{:?}", d.findings);
    assert_eq!(d.fit.before, d.fit.after);
    assert_eq!(d.evidence.pairs.len(), 8);
}

/// `diagnosis.json` against docs/diagnosis.schema.json (the FORMATS.md §5 contract as a JSON
/// Schema); panics with the validator's message.
fn check_schema(json: &serde_json::Value) {
    if let Err(e) = validate(json) {
        panic!("diagnosis.json does not follow the schema: {e}\n{json:#}");
    }
}

fn validate(json: &serde_json::Value) -> Result<(), String> {
    let schema: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string("docs/diagnosis.schema.json").expect("the schema is in docs/"),
    )
    .expect("the schema is JSON");
    let url = schema["$id"].as_str().unwrap().to_string();
    let mut schemas = boon::Schemas::new();
    let mut compiler = boon::Compiler::new();
    compiler.add_resource(&url, schema).unwrap();
    let index = compiler
        .compile(&url, &mut schemas)
        .map_err(|e| format!("schema: {e}"))?;
    schemas.validate(json, index).map_err(|e| e.to_string())
}

/// The schema check itself can fail: a NaN fit (written as null), an unknown kind, a region
/// kind without its region and a confidence above 1 are each refused.
#[test]
fn the_schema_refuses_broken_diagnoses() {
    let good = serde_json::json!({
        "findings": [{
            "kind": "localized_damping", "summary": "s", "region": { "x": [0.1, 0.5], "y": [1.0, 1.5] },
            "parameters": { "loss_factor": 0.1 }, "confidence": 0.9
        }],
        "fit": {
            "before": { "frf_error": null, "damping_rms": 0.01, "frequency_rms_hz": 0.2 },
            "after": { "frf_error": 0.1, "damping_rms": 0.001, "frequency_rms_hz": 0.2 }
        },
        "updated_model": "updated-model.toml"
    });
    validate(&good).unwrap();
    let broken = |path: &[&str], value: serde_json::Value| {
        let mut j = good.clone();
        let mut at = &mut j;
        for p in &path[..path.len() - 1] {
            at = match p.parse::<usize>() {
                Ok(i) => &mut at[i],
                Err(_) => &mut at[*p],
            };
        }
        at[path[path.len() - 1]] = value;
        j
    };
    for (path, value) in [
        (vec!["fit", "after", "damping_rms"], serde_json::Value::Null),
        (
            vec!["findings", "0", "kind"],
            serde_json::json!("cosmic_rays"),
        ),
        (vec!["findings", "0", "confidence"], serde_json::json!(1.5)),
    ] {
        let j = broken(&path, value);
        assert!(validate(&j).is_err(), "{path:?} passed: {j}");
    }
    let mut no_region = good.clone();
    no_region["findings"][0]
        .as_object_mut()
        .unwrap()
        .remove("region");
    assert!(validate(&no_region).is_err());
}

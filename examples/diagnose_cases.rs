//! Diagnoses the concealed-physics recording sets of `tests/data` against the nominal model
//! and prints one line per set: what was found, where, how much, and the fit before and after.
//!
//! ```text
//! cargo run --release --example diagnose_cases                # every set, 50 dB, 100 Hz
//! cargo run --release --example diagnose_cases -- soft-edge   # the sets whose name contains it
//! ```
//!
//! The sets were recorded on another mesh (48 × 72 × 2, sensors between the nodes) or by
//! another simulator (Kirchhoff thin plate); white noise at 50 dB on mean signal power is
//! added here (35 dB for the `-35db` case).

use dampscope::diagnose::procedure::{diagnose, DiagnoseSettings};
use dampscope::modal::model_shapes::sensor_positions;
use dampscope::modal::Recordings;
use dampscope::sim::model::Model;
use dampscope::source::recording_set::open_recording_set;
use std::path::Path;

/// (name, set directory, SNR on mean power in dB, modes up to Hz).
const CASES: &[(&str, &str, f64, f64)] = &[
    (
        "control (FE)",
        "tests/data/modal/plate-48x72-homogeneous",
        50.0,
        100.0,
    ),
    (
        "control (Kirchhoff)",
        "tests/data/diagnose/plate-48x72-kirchhoff-control",
        50.0,
        100.0,
    ),
    ("mass", "tests/data/diagnose/plate-48x72-mass", 50.0, 120.0),
    (
        "soft-edge",
        "tests/data/diagnose/plate-48x72-soft-edge",
        50.0,
        100.0,
    ),
    (
        "soft-region",
        "tests/data/diagnose/plate-48x72-soft-region",
        50.0,
        100.0,
    ),
    (
        "damped-patch",
        "tests/data/modal/plate-48x72-damped-patch",
        50.0,
        160.0,
    ),
    (
        "damped-patch-35db",
        "tests/data/modal/plate-48x72-damped-patch",
        35.0,
        160.0,
    ),
    (
        "viscoelastic-layer",
        "tests/data/diagnose/plate-48x72-viscoelastic-layer",
        50.0,
        100.0,
    ),
    (
        "viscoelastic-layer (Kirchhoff)",
        "tests/data/diagnose/plate-48x72-kirchhoff-viscoelastic",
        50.0,
        100.0,
    ),
    (
        "rayleigh",
        "tests/data/diagnose/plate-48x72-rayleigh",
        50.0,
        100.0,
    ),
    (
        "mass-and-patch",
        "tests/data/diagnose/plate-48x72-mass-and-patch",
        50.0,
        130.0,
    ),
];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let filter = std::env::args().nth(1).unwrap_or_default();
    let model = Model::load(Path::new("examples/plate-homogeneous.toml"))?;
    for &(name, dir, snr_db, fmax_hz) in CASES.iter().filter(|c| c.0.contains(&filter)) {
        let mut set = open_recording_set(Path::new(dir))?;
        let sensors = sensor_positions(&set.sensors)?;
        let mut rec = Recordings::from_source(set.source.as_mut(), 1 << 20)?;
        rec.add_noise_mean_power(snr_db, 1);
        let settings = DiagnoseSettings {
            fmax_hz,
            ..DiagnoseSettings::default()
        };
        let started = std::time::Instant::now();
        let d = diagnose(&rec, &sensors, &model, &settings)?;
        let found: Vec<String> = d
            .findings
            .iter()
            .filter(|f| f.kind != "noise_floor")
            .map(|f| {
                let place = match (&f.region, &f.point, &f.edge) {
                    (Some(r), _, _) => format!(
                        " x {:.2}–{:.2} y {:.2}–{:.2} m",
                        r.x[0], r.x[1], r.y[0], r.y[1]
                    ),
                    (_, Some(p), _) => format!(" at ({:.2}, {:.2}) m", p.x, p.y),
                    (_, _, Some(e)) => format!(" edge {e}"),
                    _ => String::new(),
                };
                let params: Vec<String> = f
                    .parameters
                    .iter()
                    .map(|(k, v)| format!("{k} {v:.4}"))
                    .collect();
                format!("{}{place} [{}]", f.kind, params.join(", "))
            })
            .collect();
        println!(
            "{name}: {} | damping RMS {:.5} → {:.5}, frequency RMS {:.3} → {:.3} Hz | {:.0} s",
            if found.is_empty() {
                "no physics missing".to_string()
            } else {
                found.join("; ")
            },
            d.fit.before.damping_rms,
            d.fit.after.damping_rms,
            d.fit.before.frequency_rms_hz,
            d.fit.after.frequency_rms_hz,
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

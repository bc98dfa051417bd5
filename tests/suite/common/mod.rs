//! Helpers shared by the integration tests.
#![allow(dead_code)]

use dampscope::decay::estimate::EstimateSettings;
use dampscope::decay::{DecayEstimate, EvaluationRange};
use dampscope::frontend::bands::Band;
use dampscope::frontend::stft::{StftFrontEnd, StftSettings};
use dampscope::pipeline::analyze_decay;

/// The report's eq. 4.5 (the library's [`dampscope::source::synth::decaying_sines`]), modes as
/// (f_hz, D, A, ψ_deg).
pub fn decaying_sines(modes: &[(f64, f64, f64, f64)], fs: f64, seconds: f64) -> Vec<f64> {
    let modes: Vec<dampscope::source::synth::Mode> = modes
        .iter()
        .map(|&(f, d, a, psi)| dampscope::source::synth::Mode::new(f, d, a, psi))
        .collect();
    dampscope::source::synth::decaying_sines(&modes, fs, seconds)
}

/// Analyses `x` (starting at its onset) with an STFT of `window_ms` in one band.
pub fn stft_estimate(
    x: &[f64],
    fs: f64,
    window_ms: f64,
    lo: f64,
    hi: f64,
    range: EvaluationRange,
) -> DecayEstimate {
    let band = Band::new(lo, hi).unwrap();
    let mut fe = StftFrontEnd::new(
        StftSettings {
            window_ms,
            ..Default::default()
        },
        fs,
        &[band],
    )
    .unwrap();
    let settings = EstimateSettings {
        range,
        ..Default::default()
    };
    analyze_decay(x, &mut fe, &settings).remove(0)
}

/// Relative error |got/want − 1|.
pub fn rel_err(got: f64, want: f64) -> f64 {
    (got / want - 1.0).abs()
}

/// Deterministic white Gaussian noise (splitmix64 + Box–Muller) of standard deviation `sigma`.
pub fn gaussian_noise(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
    let mut state = seed;
    let mut next = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (u1, u2) = (next().max(1e-300), next());
            sigma * (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
        })
        .collect()
}

/// The rows of a CSV file with a header, each as column name → text.
pub fn csv_rows(path: &std::path::Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let header: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    r.records()
        .map(|rec| {
            let rec = rec.unwrap();
            header
                .iter()
                .cloned()
                .zip(rec.iter().map(String::from))
                .collect()
        })
        .collect()
}

/// A fresh, empty temporary directory `dampscope-<name>-<pid>` (removed first if left over).
pub fn fresh_dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("dampscope-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the real binary with `args`, `stdin` piped in (written from a thread, so a large input
/// cannot dead-lock against the output), and returns its output.
pub fn run_dampscope(args: &[&str], stdin: &[u8]) -> std::process::Output {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary runs");
    let mut input = child.stdin.take().unwrap();
    let data = stdin.to_vec();
    let writer = std::thread::spawn(move || {
        let _ = input.write_all(&data);
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    out
}

/// A stored recording set read whole, with white noise added at `snr_db` on mean signal power
/// (`seed`), and its sensor positions as the model reads them.
pub fn noisy_set(
    dir: &str,
    snr_db: f64,
    seed: u64,
) -> (
    dampscope::modal::Recordings,
    Vec<dampscope::sim::model::SensorPosition>,
) {
    let mut set = dampscope::source::recording_set::open_recording_set(std::path::Path::new(dir))
        .unwrap_or_else(|e| panic!("{dir}: {e}"));
    let sensors = dampscope::modal::model_shapes::sensor_positions(&set.sensors);
    let mut rec = dampscope::modal::Recordings::from_source(set.source.as_mut(), 1 << 20)
        .unwrap_or_else(|e| panic!("{dir}: {e}"));
    rec.add_noise_mean_power(snr_db, seed);
    (rec, sensors)
}

/// `diagnose` of recording set `dir` (noise added at `snr_db` on mean power, `seed`) against
/// the nominal model examples/plate-homogeneous.toml, modes to `fmax_hz`.
pub fn diagnose_set(
    dir: &str,
    snr_db: f64,
    seed: u64,
    fmax_hz: f64,
) -> dampscope::diagnose::report::Diagnosis {
    use dampscope::diagnose::procedure::{diagnose, DiagnoseSettings};
    let (rec, sensors) = noisy_set(dir, snr_db, seed);
    let model =
        dampscope::sim::model::Model::load(std::path::Path::new("examples/plate-homogeneous.toml"))
            .unwrap();
    let settings = DiagnoseSettings {
        fmax_hz,
        ..DiagnoseSettings::default()
    };
    diagnose(&rec, &sensors, &model, &settings).unwrap_or_else(|e| panic!("{dir}: {e}"))
}

/// The findings of `d` that name physics (not the noise floor).
pub fn physics(
    d: &dampscope::diagnose::report::Diagnosis,
) -> Vec<&dampscope::diagnose::report::Finding> {
    d.findings
        .iter()
        .filter(|f| f.kind != "noise_floor")
        .collect()
}

/// Distance from the centre of `f`'s region to (x, y), m.
pub fn region_offset_m(f: &dampscope::diagnose::report::Finding, x: f64, y: f64) -> f64 {
    let r = f.region.as_ref().expect("a region");
    (0.5 * (r.x[0] + r.x[1]) - x).hypot(0.5 * (r.y[0] + r.y[1]) - y)
}

/// The viscoelastic layer of the `diagnose/*viscoelastic*` sets (x 1.005–1.482, y 1.836–2.510 m,
/// peak loss factor 0.178): `d` names it alone, its centre within 0.3 m, its peak within 30 %,
/// and the damping RMS at least halved. Returns the finding for further checks.
pub fn assert_viscoelastic_layer(
    d: &dampscope::diagnose::report::Diagnosis,
) -> &dampscope::diagnose::report::Finding {
    let physics = physics(d);
    assert_eq!(physics.len(), 1, "{:?}", d.findings);
    let f = physics[0];
    assert_eq!(f.kind, "viscoelastic_damping", "{f:?}");
    let off = region_offset_m(f, 0.5 * (1.005 + 1.482), 0.5 * (1.836 + 2.510));
    assert!(off < 0.3, "{off} m: {f:?}");
    let peak = f.parameters["peak_loss_factor"];
    assert!(rel_err(peak, 0.178) < 0.3, "{peak}");
    assert!(
        d.fit.after.damping_rms <= 0.5 * d.fit.before.damping_rms,
        "{:?}",
        d.fit
    );
    f
}

//! Helpers shared by the integration tests.
#![allow(dead_code)]

use dampscope::decay::estimate::EstimateSettings;
use dampscope::decay::{DecayEstimate, EvaluationRange};
use dampscope::frontend::bands::Band;
use dampscope::frontend::stft::{StftFrontEnd, StftSettings};
use dampscope::pipeline::analyze_decay;

/// The path of a file under `tests/data` (the reference data the oracles read, kept in the
/// repository); a missing file fails the test, it never skips it.
pub fn data(rel: &str) -> String {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(rel);
    assert!(p.exists(), "missing test data {}", p.display());
    p.to_string_lossy().into_owned()
}

/// The report's eq. 4.5 (the library's [`dampscope::source::synth::decaying_sines`]), modes as
/// (f_hz, D, A, ψ_deg).
pub fn decaying_sines(modes: &[(f64, f64, f64, f64)], fs: f64, seconds: f64) -> Vec<f64> {
    let modes: Vec<dampscope::source::synth::Mode> = modes
        .iter()
        .map(|&(f, d, a, psi)| dampscope::source::synth::Mode::new(f, d, a, psi))
        .collect();
    dampscope::source::synth::decaying_sines(&modes, fs, seconds)
}

/// Hit `k` of the hit-stream tests: `modes` as (f_hz, D), each at the strength
/// [1, 0.5, 0.8, 0.3, 0.9][k mod 5] and phase 37°·(k + mode index), `seconds` long.
pub fn test_hit(modes: &[(f64, f64)], k: usize, fs: f64, seconds: f64) -> Vec<f64> {
    let a = [1.0, 0.5, 0.8, 0.3, 0.9][k % 5];
    let modes: Vec<(f64, f64, f64, f64)> = modes
        .iter()
        .enumerate()
        .map(|(m, &(f, d))| (f, d, a, 37.0 * (k + m) as f64))
        .collect();
    decaying_sines(&modes, fs, seconds)
}

/// Adds `gain × hit` into `x` from sample `start` on, cut at the end of `x`.
pub fn add_at(x: &mut [f64], start: usize, hit: &[f64], gain: f64) {
    let n = x.len();
    for (i, v) in hit.iter().enumerate().take(n.saturating_sub(start)) {
        x[start + i] += gain * v;
    }
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

/// White Gaussian noise of standard deviation `sigma`: the library's own generator
/// ([`dampscope::source::noise::GaussianNoise`]), seeded.
pub fn gaussian_noise(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
    let mut g = dampscope::source::noise::GaussianNoise::new(seed);
    (0..n).map(|_| sigma * g.next_gaussian()).collect()
}

/// `x` as a mono 32-bit float WAV at `path`, `fs_hz` samples per second.
pub fn write_float_wav(path: &std::path::Path, x: &[f64], fs_hz: u32) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: fs_hz,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for &v in x {
        w.write_sample(v as f32).unwrap();
    }
    w.finalize().unwrap();
}

/// The rows of a CSV file with a header, each as column name → text.
pub fn csv_rows(path: &std::path::Path) -> Vec<std::collections::HashMap<String, String>> {
    let r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    rows_of(r)
}

/// The rows of `dampscope ARGS` (with `stdin` piped in), which must exit 0, each as column
/// name → text.
pub fn analyze_rows(args: &[&str], stdin: &[u8]) -> Vec<std::collections::HashMap<String, String>> {
    let o = run_dampscope(args, stdin);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{args:?}: {e}");
    rows_of(csv::Reader::from_reader(o.stdout.as_slice()))
}

fn rows_of<R: std::io::Read>(
    mut r: csv::Reader<R>,
) -> Vec<std::collections::HashMap<String, String>> {
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

/// `dampscope simulate --model MODEL --out SET EXTRA…`, which must succeed.
pub fn simulate_set(model: &std::path::Path, set: &std::path::Path, extra: &[&str]) {
    let (model, set) = (model.to_str().unwrap(), set.to_str().unwrap());
    TestCommand::new(
        ["simulate", "--model", model, "--out", set]
            .iter()
            .chain(extra),
    )
    .ok();
}

/// A fresh, empty temporary directory `dampscope-<name>-<pid>` (removed first if left over).
pub fn fresh_dir(name: &str) -> ScratchDir {
    let d = std::env::temp_dir().join(format!("dampscope-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    ScratchDir(d)
}

/// A test's temporary directory ([`fresh_dir`]): removed when dropped, unless the test is
/// failing (then it stays, to be looked at). Before, every run of the suite left about 30 MB of
/// directories in the temporary folder.
#[derive(Debug)]
pub struct ScratchDir(std::path::PathBuf);

impl std::ops::Deref for ScratchDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::path::Path> for ScratchDir {
    fn as_ref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// The real `dampscope` binary as a test runs it (in the manner of ripgrep's `TestCommand`):
/// arguments, optional standard input (written from a thread, so a large input cannot
/// dead-lock against the output), and assertions on the outcome that print stderr.
pub struct TestCommand {
    cmd: std::process::Command,
    stdin: Option<Vec<u8>>,
}

impl TestCommand {
    /// `dampscope ARGS…`.
    pub fn new<S: AsRef<std::ffi::OsStr>>(args: impl IntoIterator<Item = S>) -> Self {
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_dampscope"));
        cmd.args(args);
        TestCommand { cmd, stdin: None }
    }

    /// One more argument.
    pub fn arg(mut self, a: impl AsRef<std::ffi::OsStr>) -> Self {
        self.cmd.arg(a);
        self
    }

    /// More arguments.
    pub fn args<S: AsRef<std::ffi::OsStr>>(mut self, a: impl IntoIterator<Item = S>) -> Self {
        self.cmd.args(a);
        self
    }

    /// Pipes `bytes` to standard input.
    pub fn stdin(mut self, bytes: &[u8]) -> Self {
        self.stdin = Some(bytes.to_vec());
        self
    }

    /// Runs to the end; the whole output, whatever the exit code.
    pub fn output(mut self) -> std::process::Output {
        use std::io::Write;
        use std::process::Stdio;
        let piped = self.stdin.is_some();
        let mut child = self
            .cmd
            .stdin(if piped { Stdio::piped() } else { Stdio::null() })
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the dampscope binary runs");
        let writer = self.stdin.take().map(|data| {
            let mut input = child.stdin.take().unwrap();
            std::thread::spawn(move || {
                let _ = input.write_all(&data);
            })
        });
        let out = child.wait_with_output().unwrap();
        if let Some(w) = writer {
            w.join().unwrap();
        }
        out
    }

    /// Runs, asserts success (showing the command and stderr otherwise) and returns stdout.
    pub fn ok(self) -> String {
        let shown = format!("{:?}", self.cmd);
        let out = self.output();
        assert!(
            out.status.success(),
            "{shown}: exit {:?}: {}",
            out.status.code(),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    }
}

/// Runs the real binary with `args` and `stdin` piped in; returns its output.
pub fn run_dampscope(args: &[&str], stdin: &[u8]) -> std::process::Output {
    TestCommand::new(args).stdin(stdin).output()
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
    let sensors = dampscope::modal::model_shapes::sensor_positions(&set.sensors).unwrap();
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

/// Runs one channel `x` at `fs` through the whole streaming pipeline with a default STFT over
/// `bands` (lo, hi in Hz) and `config`; the rows in the order they came.
pub fn analyse_stft(
    x: Vec<f64>,
    fs: f64,
    bands: &[(f64, f64)],
    config: &dampscope::pipeline::AnalysisConfig,
) -> Vec<dampscope::pipeline::ResultRow> {
    use dampscope::frontend::FrontEnd;
    let info = dampscope::source::SignalInfo {
        sample_rate_hz: fs,
        channel_names: vec!["a".into()],
    };
    let source = dampscope::source::memory::MemorySource::new(info, vec![x]).unwrap();
    let bands: Vec<Band> = bands
        .iter()
        .map(|&(lo, hi)| Band::new(lo, hi).unwrap())
        .collect();
    let factory: dampscope::pipeline::FrontEndFactory = std::sync::Arc::new(move || {
        Ok(Box::new(StftFrontEnd::new(StftSettings::default(), fs, &bands)?) as Box<dyn FrontEnd>)
    });
    let mut rows = Vec::new();
    dampscope::pipeline::run(Box::new(source), &factory, config, |r| {
        rows.extend_from_slice(r);
        Ok(())
    })
    .unwrap();
    rows
}

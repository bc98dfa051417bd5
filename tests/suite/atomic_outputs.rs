//! Killed runs leave no partial file under a final name (issue 12): every output goes to a hidden
//! `.NAME.partial-…` file and is renamed into place once complete. Each test kills the real
//! binary with SIGKILL while it is writing, after checking that it *was* writing (a temporary
//! file with content exists), and then finds no file under a final name.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::fresh_dir;

/// The hidden temporary files in `dir` (names holding `.partial-`) and their sizes.
fn partial_files(dir: &Path) -> Vec<(PathBuf, u64)> {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok())
                .filter(|e| e.file_name().to_string_lossy().contains(".partial-"))
                .map(|e| (e.path(), e.metadata().map_or(0, |m| m.len())))
                .collect()
        })
        .unwrap_or_default()
}

/// Waits (up to `limit`) until a temporary file in `dir` holds more than `min_bytes`.
fn wait_for_partial(child: &mut Child, dir: &Path, min_bytes: u64, limit: Duration) {
    let start = Instant::now();
    loop {
        if partial_files(dir).iter().any(|(_, n)| *n > min_bytes) {
            return;
        }
        if let Ok(Some(status)) = child.try_wait() {
            panic!("the run ended ({status}) before it was seen writing");
        }
        assert!(
            start.elapsed() < limit,
            "no temporary file with > {min_bytes} bytes in {} after {limit:?}",
            dir.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn kill(mut child: Child) {
    child.kill().expect("kill");
    let _ = child.wait();
}

#[test]
fn a_killed_analyze_leaves_no_results_file() {
    let dir = fresh_dir("atomic-analyze");
    let results = dir.join("results.csv");
    let mut child = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args([
            "analyze",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4096",
            "--channels",
            "2",
        ])
        .arg("--out")
        .arg(&results)
        .args(["--max-decay-s", "1"])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Hits every second on two channels, fed while the test watches: rows are written as each
    // decay ends (the results file grows while the run goes on).
    let mut stdin = child.stdin.take().unwrap();
    let fs = 4096.0;
    let mut bytes = Vec::new();
    for i in 0..(6 * 4096) {
        let t = (i % 4096) as f64 / fs;
        let v = ((-20.0 * t).exp() * (2.0 * std::f64::consts::PI * 300.0 * t).sin()) as f32;
        bytes.extend_from_slice(&v.to_le_bytes());
        bytes.extend_from_slice(&(0.5 * v).to_le_bytes());
    }
    stdin.write_all(&bytes).unwrap();
    stdin.flush().unwrap();
    wait_for_partial(&mut child, &dir, 400, Duration::from_secs(30));
    kill(child);
    drop(stdin);
    assert!(!results.exists(), "a killed run left {}", results.display());
    assert!(!partial_files(&dir).is_empty());
}

#[test]
fn a_killed_simulation_leaves_no_recording_set() {
    let dir = fresh_dir("atomic-simulate");
    let set = dir.join("set");
    // The reference plate on a 16 × 24 mesh to 1 kHz: modes in seconds, still 1617 sensors ×
    // 8000 samples (52 MB) to stream. (The full mesh to 2 kHz took over the 40 s below to
    // start writing while the heavy diagnose tests ran beside it.)
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/plate-homogeneous.toml"),
    )
    .unwrap()
    .replace("nx = 32", "nx = 16")
    .replace("ny = 48", "ny = 24")
    .replace("fmax = 2000.0", "fmax = 1000.0");
    let model = dir.join("lighter.toml");
    std::fs::write(&model, text).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args(["simulate", "--model"])
        .arg(&model)
        .arg("--out")
        .arg(&set)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // The responses are streamed to disk as they are computed.
    let start = Instant::now();
    while !set.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(40),
            "no output directory"
        );
        assert!(child.try_wait().unwrap().is_none(), "simulate ended early");
        std::thread::sleep(Duration::from_millis(20));
    }
    wait_for_partial(&mut child, &set, 1 << 20, Duration::from_secs(40));
    kill(child);
    for name in ["responses.wav", "responses.csv", "sensors.csv", "meta.json"] {
        assert!(!set.join(name).exists(), "a killed run left {name}");
    }
    let opened = dampscope::source::open_recording_set(&set);
    assert!(
        opened.is_err(),
        "a killed run left a readable recording set"
    );
}

#[test]
fn a_finished_simulation_replaces_an_old_set_whole() {
    let dir = fresh_dir("atomic-replace");
    let set = dir.join("set");
    // An old set of another shape, with a responses file of the other kind.
    std::fs::create_dir_all(&set).unwrap();
    std::fs::write(set.join("responses.csv"), "time,a\n0,1\n").unwrap();
    std::fs::write(set.join("sensors.csv"), "id,x,y\na,0,0\n").unwrap();
    std::fs::write(set.join("notes.txt"), "kept").unwrap();
    // The reference plate on a coarse mesh, 0–200 Hz, 3 × 3 sensors.
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/plate-homogeneous.toml"),
    )
    .unwrap()
    .replace("nx = 32", "nx = 8")
    .replace("ny = 48", "ny = 12")
    .replace("fmax = 2000.0", "fmax = 200.0")
    .replace("df = 0.25", "df = 2.0")
    .replace(
        "sensors = { nx = 33, ny = 49 }",
        "sensors = { nx = 3, ny = 3 }",
    );
    let model = dir.join("small.toml");
    std::fs::write(&model, text).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args(["simulate", "--model"])
        .arg(&model)
        .arg("--out")
        .arg(&set)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!set.join("responses.csv").exists(), "stale responses kept");
    assert_eq!(
        std::fs::read_to_string(set.join("notes.txt")).unwrap(),
        "kept"
    );
    assert!(partial_files(&set).is_empty(), "temporary files left");
    let opened = dampscope::source::open_recording_set(&set).unwrap();
    assert_eq!(opened.sensors.len(), 9);
}

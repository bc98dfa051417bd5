//! Found probing inputs as a new user would: contradictions were accepted silently. A recording
//! set whose meta.json said fs = 8000 while its CSV time column said 4000 was analysed at 8000
//! (every number changes); `analyze` labelled four channels "E1" when sensor ids repeated; one
//! empty CSV cell in one channel stopped all channels at that row; 0 bytes of raw f32 on
//! standard input exited 3 with 31 `no_energy` rows. Each is now an error with a message, or
//! (the empty cell) a missing sample of that channel only.

use crate::common::run_dampscope as dampscope;

use std::path::Path;
use std::process::Output;

use crate::common::{decaying_sines, fresh_dir};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Two channels of a 55 Hz decay as CSV text with a time column at `fs` (times printed with
/// `decimals` decimals), optionally an empty cell in channel E2 at row 1000.
fn csv_text(fs: f64, decimals: usize, header: &str, empty_cell: bool) -> String {
    let x = decaying_sines(&[(55.0, 0.025, 1.0, 0.0)], fs, 3.0);
    let mut s = format!("{header}\n");
    for (i, v) in x.iter().enumerate() {
        let t = i as f64 / fs;
        if empty_cell && i == 1000 {
            s.push_str(&format!("{t:.decimals$},{v:e},\n"));
        } else {
            s.push_str(&format!("{t:.decimals$},{v:e},{:e}\n", 0.5 * v));
        }
    }
    s
}

fn recording_set(dir: &Path, meta_fs: f64, responses: &str) {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("responses.csv"), responses).unwrap();
    std::fs::write(dir.join("sensors.csv"), "id,x,y\nE1,0.1,0.2\nE2,0.3,0.4\n").unwrap();
    std::fs::write(dir.join("meta.json"), format!("{{\"fs\": {meta_fs}}}")).unwrap();
}

#[test]
fn meta_fs_contradicting_the_csv_time_column_is_an_error() {
    let dir = fresh_dir("contra-csv");
    let set = dir.join("set");
    recording_set(&set, 8000.0, &csv_text(4000.0, 6, "time,E1,E2", false));
    let o = dampscope(&["analyze", set.to_str().unwrap()], b"");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("contradictory") && e.contains("8000") && e.contains("4000"),
        "{e}"
    );
    // The same set with the right fs is analysed.
    std::fs::write(set.join("meta.json"), "{\"fs\": 4000}").unwrap();
    let o = dampscope(&["analyze", set.to_str().unwrap()], b"");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_coarsely_printed_time_column_agrees_with_its_rate() {
    // 3 kHz with times printed to the microsecond: steps of 333 and 334 µs. Not a contradiction.
    let dir = fresh_dir("contra-coarse");
    let set = dir.join("set");
    recording_set(&set, 3000.0, &csv_text(3000.0, 6, "time,E1,E2", false));
    let o = dampscope(&["analyze", set.to_str().unwrap()], b"");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // Without meta.json the rate comes from the mean step, not from the first two times.
    std::fs::remove_file(set.join("meta.json")).unwrap();
    let o = dampscope(&["analyze", set.to_str().unwrap()], b"");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    let row = text
        .lines()
        .find(|l| l.contains(",25.000000,75.000000,"))
        .unwrap();
    let d: f64 = row.split(',').nth(14).unwrap().parse().unwrap();
    assert!((d / 0.025 - 1.0).abs() < 0.02, "{row}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// FORMATS.md §1: "The WAV header's sample rate is the truth for the sample rate." A set whose
/// meta.json disagreed (8000.04 Hz: the exact rate of a clock a WAV header cannot hold; or the
/// rate of a responses.csv the WAV overrides) was refused; it is read at the header's rate, and
/// the disagreement is said, not passed over.
#[test]
fn meta_fs_contradicting_the_wav_header_gives_way_to_the_header_with_a_warning() {
    let dir = fresh_dir("contra-wav");
    let set = dir.join("set");
    std::fs::create_dir_all(&set).unwrap();
    let o = dampscope(
        &[
            "synth",
            "--mode",
            "55:0.025",
            "--fs",
            "4000",
            "--seconds",
            "2",
        ],
        b"",
    );
    std::fs::write(set.join("responses.wav"), &o.stdout).unwrap();
    std::fs::write(set.join("sensors.csv"), "id,x,y\nE1,0.1,0.2\n").unwrap();
    std::fs::write(set.join("meta.json"), "{\"fs\": 8000}").unwrap();
    let o = dampscope(&["analyze", set.to_str().unwrap()], b"");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("warning") && e.contains("4000 Hz") && e.contains("fs = 8000"),
        "{e}"
    );
    // Read at the header's 4000 Hz: the 55 Hz mode's D is its 2.5 % (at 8000 Hz it would be
    // at 110 Hz with half the decay time).
    let text = String::from_utf8_lossy(&o.stdout);
    let row = text
        .lines()
        .find(|l| l.contains(",52.500000,57.500000,") || l.contains(",50.000000,60.000000,"))
        .or_else(|| {
            text.lines()
                .find(|l| l.contains("E1,") && !l.contains(",,,,"))
        })
        .unwrap_or_else(|| panic!("no row near 55 Hz in\n{text}"));
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = header
        .iter()
        .position(|h| *h == "damping_ratio_corrected")
        .unwrap();
    let d: f64 = row.split(',').nth(col).unwrap().parse().unwrap();
    assert!((d / 0.025 - 1.0).abs() < 0.05, "{row}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn repeated_sensor_ids_are_an_error_everywhere() {
    let text = csv_text(4000.0, 6, "time,E1,E1", false);
    let o = dampscope(&["analyze", "-"], text.as_bytes());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("unique"), "{}", stderr(&o));
    let dir = fresh_dir("contra-ids");
    let set = dir.join("set");
    recording_set(&set, 4000.0, &csv_text(4000.0, 6, "time,E1,E2", false));
    std::fs::write(set.join("sensors.csv"), "id,x,y\nE1,0.1,0.2\nE1,0.3,0.4\n").unwrap();
    for cmd in ["analyze", "map"] {
        let out = dir.join(cmd);
        let o = dampscope(
            &[cmd, set.to_str().unwrap(), "--out", out.to_str().unwrap()],
            b"",
        );
        assert_eq!(o.status.code(), Some(1), "{cmd}: {}", stderr(&o));
        assert!(stderr(&o).contains("unique"), "{cmd}: {}", stderr(&o));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_empty_cell_stops_only_its_own_channel() {
    let text = csv_text(4000.0, 6, "time,E1,E2", true);
    let o = dampscope(&["analyze", "-"], text.as_bytes());
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    let band = ",25.000000,75.000000,";
    let e1 = out
        .lines()
        .find(|l| l.starts_with("E1,") && l.contains(band))
        .unwrap();
    let e2 = out
        .lines()
        .find(|l| l.starts_with("E2,") && l.contains(band))
        .unwrap();
    let d: f64 = e1.split(',').nth(14).unwrap().parse().expect(e1);
    assert!((d / 0.025 - 1.0).abs() < 0.02, "{e1}");
    assert!(e2.contains("non_finite_input"), "{e2}");
}

#[test]
fn empty_raw_standard_input_exits_1() {
    let o = dampscope(
        &[
            "analyze",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4000",
            "--channels",
            "1",
        ],
        b"",
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("no samples"), "{}", stderr(&o));
    let rows = String::from_utf8_lossy(&o.stdout).lines().count();
    assert!(rows <= 1, "no result rows, got {rows} lines");
}

/// Found on pyrato's reference RIRs (issue 15): a CSV laid out one channel per row, 2 × 16384,
/// was read as 16 384 channels of two samples without a word. A headerless CSV with fewer rows
/// than columns is now refused naming both counts; the same data one channel per column, and a
/// headed CSV with more channels than samples (a large sensor grid), are read.
#[test]
fn a_transposed_headerless_csv_is_refused() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/pyrato/analytic_rir_psnr50_2D.csv"
    );
    let o = dampscope(&["analyze", path, "--fs", "3000"], b"");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("2 rows of 16384 columns") && stderr(&o).contains("transposed"),
        "{}",
        stderr(&o)
    );
    let text = std::fs::read_to_string(path).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
    let columns: String = (0..rows[0].len())
        .map(|k| format!("{},{}\n", rows[0][k], rows[1][k]))
        .collect();
    let o = dampscope(
        &["analyze", "-", "--fs", "3000", "--band", "100:200"],
        columns.as_bytes(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(String::from_utf8_lossy(&o.stdout).lines().count(), 3);
    let wide = format!(
        "time,{}\n0,{}\n0.001,{}\n",
        (0..50)
            .map(|k| format!("s{k}"))
            .collect::<Vec<_>>()
            .join(","),
        vec!["1"; 50].join(","),
        vec!["0.5"; 50].join(",")
    );
    let o = dampscope(&["analyze", "-", "--band", "100:200"], wide.as_bytes());
    assert!(!stderr(&o).contains("transposed"), "{}", stderr(&o));
    assert_eq!(String::from_utf8_lossy(&o.stdout).lines().count(), 51);
}

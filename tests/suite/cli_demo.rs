//! The README's front door: `dampscope demo` runs without input files and prints the report's
//! reference numbers (Table 4.1's D_eq = 2.16 %, the plate maps' 2.6 % and 2.7 %).

use std::process::Command;

/// The number in column `col` (whitespace-separated) of the first line starting with `start`.
fn value(out: &str, start: &str, col_from_end: usize) -> f64 {
    let line = out
        .lines()
        .find(|l| l.starts_with(start))
        .unwrap_or_else(|| panic!("no line starting with {start:?} in\n{out}"));
    let cols: Vec<&str> = line.split_whitespace().collect();
    cols[cols.len() - col_from_end]
        .parse()
        .unwrap_or_else(|_| panic!("{line}"))
}

#[test]
fn demo_runs_and_reproduces_the_report() {
    let out = crate::common::TestCommand::new(["demo"]).ok();
    // "three sines …  10ms  150–250  t20  2.500  2.164  2.245  D_eq,ref = 2.16"
    let line = out.lines().find(|l| l.starts_with("three sines")).unwrap();
    let cols: Vec<&str> = line.split_whitespace().collect();
    let i = cols.iter().position(|c| *c == "t20").unwrap();
    let d_eq: f64 = cols[i + 2].parse().unwrap();
    assert!((d_eq - 2.16).abs() < 0.005, "{line}");
    // Plate rows: "mode 7 only (eq. 2.7)  1551  2.579  2.496  2.6 (Fig. 3.6)".
    let m7 = value(&out, "mode 7 only", 5);
    let m78 = value(&out, "modes 7 + 8", 5);
    assert!((m7 - 2.6).abs() < 0.05, "mode 7: {m7}");
    assert!((m78 - 2.7).abs() < 0.05, "modes 7 + 8: {m78}");
    assert!(!out.contains("NaN"), "{out}");
}

/// Found with `dampscope map … | head -2`: a closed standard output made the next print
/// panic (exit 101 with a backtrace). The binary now ends quietly on SIGPIPE like any filter.
#[cfg(unix)]
#[test]
fn closed_pipe_ends_quietly_not_with_a_panic() {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .arg("demo")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 16];
    child.stdout.take().unwrap().read_exact(&mut first).unwrap();
    // The read end is dropped here: the demo's later prints hit a closed pipe.
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_ne!(out.status.code(), Some(101), "{stderr}");
}

//! Streaming for real: a long raw stream of repeated decays is piped into `dampscope analyze -`
//! in small chunks. Results must appear while the input is still arriving, and the process's
//! memory must not grow with the length of the stream.

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

fn vm_hwm_kib(pid: u32) -> Option<u64> {
    dampscope::budget::peak_memory_kib_of(&pid.to_string())
}

#[test]
fn long_piped_stream_gives_results_early_and_bounded_memory() {
    let fs = 4000.0;
    let decay_s = 2.0;
    let decays = 600; // 20 minutes of signal, 4.8 M samples
    let per = (fs * decay_s) as usize;
    let one: Vec<u8> = (0..per)
        .flat_map(|i| {
            let t = i as f64 / fs;
            let w = 2.0 * std::f64::consts::PI * 55.0;
            let x = (-(0.025 * w) * t).exp() * (w * t).sin();
            (x as f32).to_le_bytes()
        })
        .collect();

    let mut child = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args([
            "analyze",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4000",
            "--channels",
            "1",
        ])
        .args(["--band", "52.5:57.5", "--range", "t20"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary runs");
    let pid = child.id();
    let rows = Arc::new(AtomicUsize::new(0));
    let good = Arc::new(AtomicUsize::new(0));
    let stdout = child.stdout.take().unwrap();
    let (r2, g2) = (rows.clone(), good.clone());
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().skip(1) {
            let line = line.unwrap();
            r2.fetch_add(1, Ordering::SeqCst);
            // damping_ratio_corrected is column 15 (0-based 14).
            let cells: Vec<&str> = line.split(',').collect();
            if let Ok(d) = cells[14].parse::<f64>() {
                if (d / 0.025 - 1.0).abs() < 0.03 {
                    g2.fetch_add(1, Ordering::SeqCst);
                }
            }
        }
    });
    let mut stdin = child.stdin.take().unwrap();
    let mut hwm_early = 0;
    for k in 0..decays {
        for chunk in one.chunks(1000) {
            stdin.write_all(chunk).unwrap();
        }
        if k == decays / 4 {
            hwm_early = vm_hwm_kib(pid).unwrap_or(0);
        }
    }
    stdin.flush().unwrap();
    std::thread::sleep(std::time::Duration::from_millis(300));
    let rows_before_close = rows.load(Ordering::SeqCst);
    let hwm_late = vm_hwm_kib(pid).unwrap_or(0);
    drop(stdin);
    let status = child.wait().unwrap();
    reader.join().unwrap();
    assert!(status.success(), "exit {status:?}");
    assert!(
        rows_before_close >= decays - 2,
        "only {rows_before_close} rows before the input was closed"
    );
    assert_eq!(rows.load(Ordering::SeqCst), decays);
    assert!(good.load(Ordering::SeqCst) >= decays - 1, "estimates off");
    eprintln!("VmHWM after 1/4 of the input: {hwm_early} KiB, at the end: {hwm_late} KiB; rows before close: {rows_before_close}");
    // Peak memory after 4× more input may not have grown by more than 2 MiB.
    assert!(hwm_early > 0, "could not read VmHWM");
    assert!(
        hwm_late <= hwm_early + 2048,
        "peak memory grew from {hwm_early} KiB to {hwm_late} KiB"
    );
}

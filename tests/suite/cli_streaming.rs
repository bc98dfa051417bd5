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

/// The sample rate of the one-channel streams, Hz.
const FS_HZ: f64 = 4000.0;

/// `frames` samples of a 55 Hz decay with a damping ratio of 0.025 at [`FS_HZ`], raw f32.
fn decay_55_hz_f32(frames: usize) -> Vec<u8> {
    (0..frames)
        .flat_map(|i| {
            let t = i as f64 / FS_HZ;
            let w = 2.0 * std::f64::consts::PI * 55.0;
            let x = (-(0.025 * w) * t).exp() * (w * t).sin();
            (x as f32).to_le_bytes()
        })
        .collect()
}

/// `dampscope analyze -` of one raw f32 channel at [`FS_HZ`], the band around 55 Hz, and
/// `extra` arguments; standard input and output piped.
fn analyze_one_channel(extra: &[&str]) -> std::process::Child {
    let raw = ["--raw", "f32", "--fs", "4000", "--channels", "1"];
    analyze_piped(&[&raw[..], extra].concat())
}

/// `dampscope analyze -` of the band around 55 Hz with `args`; standard input and output piped.
fn analyze_piped(args: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args(["analyze", "-", "--band", "52.5:57.5"])
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("binary runs")
}

/// The data rows of a child's standard output (its header skipped), each sent as it comes.
pub(crate) fn data_rows(
    stdout: std::process::ChildStdout,
) -> (
    std::sync::mpsc::Receiver<String>,
    std::thread::JoinHandle<()>,
) {
    let (tx, rx) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().skip(1) {
            if tx.send(line.unwrap()).is_err() {
                break;
            }
        }
    });
    (rx, reader)
}

#[test]
fn long_piped_stream_gives_results_early_and_bounded_memory() {
    let decay_s = 2.0;
    let decays = 600; // 20 minutes of signal, 4.8 M samples
    let one = decay_55_hz_f32((FS_HZ * decay_s) as usize);
    let mut child = analyze_one_channel(&["--range", "t20"]);
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

/// A slow writer's pipe gives the file's rows, bit for bit. The STFT pairs two frames in one
/// transform when both are in a block, and a pair rounds differently from two lone frames; the
/// stream's blocks were cut where its reads returned, so a writer that sent 16 KB at a time
/// (fewer frames than a hop at 16384 Hz) got no pairs, other bits than the file, and other bits
/// on every run. Now a stream fills its blocks as a mapped file's are.
#[test]
fn a_slow_writers_pipe_gives_the_files_rows_bit_for_bit() {
    let (fs, channels, seconds) = (16384.0, 4usize, 4.0);
    let n = (fs * seconds) as usize;
    let bytes: Vec<u8> = (0..n)
        .flat_map(|i| {
            let t = i as f64 / fs;
            (0..channels).map(move |c| {
                let f = 200.0 + 200.0 * c as f64;
                let w = 2.0 * std::f64::consts::PI * f;
                let x = (-(0.002 * w) * t).exp() * (w * t + c as f64).sin();
                // A deterministic floor far below the decay, so that every band has a tail.
                let floor = 1e-5 * (((i * 7919 + c * 104_729) % 2001) as f64 / 1000.0 - 1.0);
                x + floor
            })
        })
        .flat_map(|x| (x as f32).to_le_bytes())
        .collect();
    let path = std::env::temp_dir().join(format!("dampscope-slow-{}.f32", std::process::id()));
    std::fs::write(&path, &bytes).unwrap();
    let args = [
        "analyze",
        "--raw",
        "f32",
        "--fs",
        "16384",
        "--channels",
        "4",
        "--front-end",
        "stft",
        "--bands",
        "octave",
        "--format",
        "jsonl",
    ];
    let by_path = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args(args)
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        by_path.status.success(),
        "{}",
        String::from_utf8_lossy(&by_path.stderr)
    );
    let rows = String::from_utf8(by_path.stdout.clone()).unwrap();
    assert!(
        rows.lines()
            .filter(|l| l.contains("\"damping_ratio\":0"))
            .count()
            >= channels,
        "too few estimates to compare:\n{rows}"
    );
    let mut child = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args(args)
        .arg("-")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || {
        for chunk in bytes.chunks(16 * 1024) {
            stdin.write_all(chunk).unwrap();
            stdin.flush().unwrap();
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    });
    let piped = child.wait_with_output().unwrap();
    writer.join().unwrap();
    assert!(
        piped.status.success(),
        "{}",
        String::from_utf8_lossy(&piped.stderr)
    );
    assert_eq!(String::from_utf8(piped.stdout).unwrap(), rows);
    std::fs::remove_file(&path).ok();
}

/// A writer that sends one short decay and waits for its row before sending more gets it: a
/// stream's block is filled whole only while bytes keep coming; after a pause of
/// `STREAM_PAUSE_MS` the frames that arrived are analysed. 3000 frames at 4000 Hz (less than
/// a 4096-frame block) whose decay ends after 0.5 s; the row must come while the input is still
/// open (a reader that waited for the whole block would never give it).
#[test]
fn a_writer_that_waits_for_its_row_gets_it() {
    let child = analyze_one_channel(&["--max-decay-s", "0.5"]);
    let (row, waited) = first_row_with_the_input_open(child, &decay_55_hz_f32(3000));
    assert!(row.starts_with("ch0,0,"), "{row}");
    eprintln!("row after {waited:?}");
}

/// Writes `bytes` to `child`'s standard input and keeps it open until the first data row
/// arrives (10 s at most); returns that row and how long it took, after the child exited 0.
fn first_row_with_the_input_open(
    mut child: std::process::Child,
    bytes: &[u8],
) -> (String, std::time::Duration) {
    let (rx, reader) = data_rows(child.stdout.take().unwrap());
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(bytes).unwrap();
    stdin.flush().unwrap();
    let started = std::time::Instant::now();
    let row = rx.recv_timeout(std::time::Duration::from_secs(10));
    let waited = started.elapsed();
    drop(stdin);
    let status = child.wait().unwrap();
    reader.join().unwrap();
    assert!(status.success(), "exit {status:?}");
    (row.expect("no row while the input was open"), waited)
}

/// The same as CSV text with a time column. Found probing streams: a CSV stream was not
/// watched, so a writer that waits got nothing — not even the header — until it closed: the
/// rate's read-ahead (up to 4096 rows) and each block (4096 rows) waited for rows that were
/// not coming.
#[test]
fn a_csv_writer_that_waits_for_its_row_gets_it() {
    let samples: Vec<f32> = decay_55_hz_f32(3000)
        .chunks(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let mut text = String::from("time,ch0\n");
    for (i, x) in samples.iter().enumerate() {
        text.push_str(&format!("{:.6},{x:e}\n", i as f64 / FS_HZ));
    }
    let child = analyze_piped(&["--max-decay-s", "0.5"]);
    let (row, _) = first_row_with_the_input_open(child, text.as_bytes());
    assert!(row.starts_with("ch0,0,"), "{row}");
}

/// The same through a named pipe given by path, as a WAV stream of unknown length (detected
/// like standard input, its descriptor watched the same way). Found a bug: the check for an
/// FRF CSV opened the path a second time and read its first lines, so a named pipe or a
/// process substitution (`dampscope analyze <(tool)`) lost its first 8 KB, and its WAV header
/// with them ("no samples", or "not a recognised input").
#[cfg(unix)]
#[test]
fn a_named_pipe_keeps_its_first_bytes_and_answers_a_writer_that_waits() {
    use std::os::unix::ffi::OsStrExt;
    let path = std::env::temp_dir().join(format!("dampscope-fifo-{}", std::process::id()));
    let c_path = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo only creates the node.
    assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0);
    let mut child = Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .arg("analyze")
        .arg(&path)
        .args(["--band", "52.5:57.5", "--max-decay-s", "0.5"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("binary runs");
    let (rx, reader) = data_rows(child.stdout.take().unwrap());
    // Opening the write end waits for the reader to open the pipe.
    let mut fifo = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    // A float WAV header whose RIFF and data lengths are unknown (0xFFFFFFFF), then the data.
    let mut wav = b"RIFF\xff\xff\xff\xffWAVEfmt ".to_vec();
    wav.extend(16u32.to_le_bytes());
    wav.extend(3u16.to_le_bytes()); // IEEE float
    wav.extend(1u16.to_le_bytes());
    wav.extend(4000u32.to_le_bytes());
    wav.extend(16000u32.to_le_bytes());
    wav.extend(4u16.to_le_bytes());
    wav.extend(32u16.to_le_bytes());
    wav.extend(b"data\xff\xff\xff\xff");
    wav.extend(decay_55_hz_f32(3000));
    fifo.write_all(&wav).unwrap();
    fifo.flush().unwrap();
    let row = rx.recv_timeout(std::time::Duration::from_secs(10));
    drop(fifo);
    let status = child.wait().unwrap();
    reader.join().unwrap();
    std::fs::remove_file(&path).ok();
    assert!(status.success(), "exit {status:?}");
    let row = row.expect("no row while the pipe was open");
    assert!(row.starts_with("ch0,0,"), "{row}");
}

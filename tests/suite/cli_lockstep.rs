//! A client that sends one record and waits for its rows (`--pause-ends-decays`). Found probing
//! with records unlike the clean decays of the streaming tests: several modes per channel,
//! noise 50 dB under the mean signal power, 3 s records. With noise no band falls the 100 dB
//! that ends a decay, and a record is far shorter than the floor test's 20 s, so a writer that
//! waited got its rows only with the next record or when it closed the input; and a record of
//! whole blocks (12288 frames = 3 × 4096) never even reported the pause, because the reader
//! waited for a first byte of the next block.

use std::io::Write;
use std::process::{Command, Stdio};
use std::time::Duration;

use super::cli_streaming::data_rows;

const FS_HZ: f64 = 4096.0;
const CHANNELS: usize = 4;

/// One record: per channel four modes (60–1000 Hz, damping ratios 0.4–2 %), white noise 50 dB
/// under the channel's mean power (Box–Muller from a fixed LCG), interleaved raw f32.
fn noisy_record(frames: usize, seed: u64) -> Vec<u8> {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut channels: Vec<Vec<f64>> = Vec::new();
    for c in 0..CHANNELS {
        let mut x = vec![0.0; frames];
        let modes: [(f64, f64); 4] = [
            (60.0, 0.02),
            (180.0, 0.008),
            (420.0, 0.004),
            (1000.0, 0.006),
        ];
        for (m, &(f_hz, zeta)) in modes.iter().enumerate() {
            let f = f_hz * (1.0 + 0.03 * c as f64);
            let (w, phase) = (std::f64::consts::TAU * f, uniform() * std::f64::consts::TAU);
            let amp = 0.4 + 0.15 * ((c + m) % 4) as f64;
            for (i, v) in x.iter_mut().enumerate() {
                let t = i as f64 / FS_HZ;
                *v += amp * (-zeta * w * t).exp() * (w * t + phase).sin();
            }
        }
        let power = x.iter().map(|v| v * v).sum::<f64>() / frames as f64;
        let sigma = (power * 1e-5).sqrt();
        for v in x.iter_mut() {
            let (u1, u2) = (uniform(), uniform());
            *v += sigma * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        }
        channels.push(x);
    }
    (0..frames)
        .flat_map(|i| channels.iter().map(move |x| x[i] as f32))
        .flat_map(f32::to_le_bytes)
        .collect()
}

/// `dampscope analyze INPUT` of the raw f32 records, octave bands, and `extra` arguments.
fn analyze(input: &str, extra: &[&str]) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_dampscope"));
    cmd.args(["analyze", input, "--raw", "f32", "--fs", "4096"])
        .args(["--channels", &CHANNELS.to_string(), "--bands", "octave"])
        .args(extra);
    cmd
}

/// The data rows of a finished run's standard output (it must have succeeded).
fn rows_of(out: std::process::Output) -> Vec<String> {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    text.lines().skip(1).map(str::to_string).collect()
}

/// The data rows of `bytes` analysed as a file `name` by `command(path)`.
fn file_rows(bytes: &[u8], name: &str, command: impl Fn(&str) -> Command) -> Vec<String> {
    let path = std::env::temp_dir().join(format!("dampscope-{}-{name}", std::process::id()));
    std::fs::write(&path, bytes).unwrap();
    let out = command(path.to_str().unwrap()).output().unwrap();
    std::fs::remove_file(&path).ok();
    rows_of(out)
}

/// Runs `command` (reading standard input), sends each record keeping the input open, and
/// collects the rows that arrive within `wait` of it (at most `rows_per_record`); then closes
/// the input. Returns the rows per record and those that came only when the input closed.
fn lockstep(
    mut command: Command,
    records: &[Vec<u8>],
    rows_per_record: usize,
    wait: Duration,
) -> (Vec<Vec<String>>, Vec<String>) {
    let mut child = command
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("binary runs");
    let (rx, reader) = data_rows(child.stdout.take().unwrap());
    let mut stdin = child.stdin.take().unwrap();
    let mut per_record = Vec::new();
    for record in records {
        stdin.write_all(record).unwrap();
        stdin.flush().unwrap();
        let deadline = std::time::Instant::now() + wait;
        let mut rows = Vec::new();
        while rows.len() < rows_per_record {
            let Some(left) = deadline.checked_duration_since(std::time::Instant::now()) else {
                break;
            };
            match rx.recv_timeout(left) {
                Ok(row) => rows.push(row),
                Err(_) => break,
            }
        }
        per_record.push(rows);
    }
    drop(stdin);
    let status = child.wait().unwrap();
    reader.join().unwrap();
    assert!(status.success(), "exit {status:?}");
    (per_record, rx.try_iter().collect())
}

/// With `--pause-ends-decays` each record's rows come while the input is still open: the
/// first record's are those of the same bytes in a file, bit for bit; the second (12288
/// frames, whole blocks: the pause comes with an empty block) gets its rows too, its onset at
/// the record's start. Without the option the first record's rows wait for the second.
#[test]
fn a_writer_that_waits_gets_each_noisy_records_rows() {
    let first = noisy_record(12000, 1);
    let second = noisy_record(3 * 4096, 2);
    let expected_first = file_rows(&first, "lockstep-first.f32", |path| analyze(path, &[]));
    let per_record = expected_first.len();
    assert!(per_record >= CHANNELS * 5, "{per_record} rows");
    let records = [first, second];
    let (got, after_close) = lockstep(
        analyze("-", &["--pause-ends-decays"]),
        &records,
        per_record,
        Duration::from_secs(5),
    );
    assert_eq!(
        got[0], expected_first,
        "the first record's rows differ from the file's"
    );
    assert_eq!(got[1].len(), per_record, "second record: {:?}", got[1]);
    for row in &got[1] {
        let onset_s: f64 = row.split(',').nth(2).unwrap().parse().unwrap();
        assert!((onset_s - 12000.0 / FS_HZ).abs() < 0.05, "{row}");
    }
    assert!(
        after_close.is_empty(),
        "rows only at the close: {after_close:?}"
    );
    // The default leaves a decay open at a pause: its rows come with the next record.
    let (got, _) = lockstep(analyze("-", &[]), &records[..1], 1, Duration::from_secs(1));
    assert!(
        got[0].is_empty(),
        "rows at a pause without the option: {:?}",
        got[0]
    );
}

/// Without the option a writer that stalls in the middle of a record (0.6 s, then the rest)
/// gets the file's rows bit for bit: the pause is reported (an empty block when the stall
/// falls on a block boundary) and changes nothing.
#[test]
fn a_stalled_writer_without_the_option_gets_the_files_rows() {
    let record = noisy_record(3 * 4096, 3);
    let expected = file_rows(&record, "stall.f32", |path| analyze(path, &[]));
    for stall_frames in [4096, 6000] {
        let (before, after) = record.split_at(stall_frames * CHANNELS * 4);
        let parts = [before.to_vec(), after.to_vec()];
        let wait = Duration::from_millis(600);
        let (got, at_close) = lockstep(analyze("-", &[]), &parts, usize::MAX, wait);
        let rows: Vec<String> = got.concat().into_iter().chain(at_close).collect();
        assert_eq!(rows, expected, "stall after {stall_frames} frames");
    }
}

/// The same for CSV text: a record of 4096 rows (one whole CSV block, so the pause is told
/// with an empty block) gets its rows while the input is open, those of the same text in a
/// file.
#[test]
fn a_csv_writer_that_waits_gets_its_records_rows() {
    let record = noisy_record(4096, 4);
    let mut text = String::from("a,b,c,d\n");
    for frame in record.chunks(CHANNELS * 4) {
        let cells: Vec<String> = frame
            .chunks(4)
            .map(|b| format!("{:e}", f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect();
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    let csv = |input: &str, extra: &[&str]| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_dampscope"));
        cmd.args(["analyze", input, "--fs", "4096", "--bands", "octave"])
            .args(extra);
        cmd
    };
    let expected = file_rows(text.as_bytes(), "lockstep.csv", |path| csv(path, &[]));
    let (got, _) = lockstep(
        csv("-", &["--pause-ends-decays"]),
        &[text.into_bytes()],
        expected.len(),
        Duration::from_secs(5),
    );
    assert_eq!(got[0], expected, "rows while the input was open");
}

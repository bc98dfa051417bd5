//! `dampscope synth … | dampscope analyze -` and friends, through the real binary.

use crate::common::run_dampscope as dampscope;

use std::process::Output;

fn synth(format: &str) -> Vec<u8> {
    let out = dampscope(
        &[
            "synth",
            "--mode",
            "55:0.025",
            "--fs",
            "4000",
            "--seconds",
            "4",
            "--format",
            format,
        ],
        b"",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// Column `name` of the first data row of a results CSV.
fn cell(csv_text: &str, name: &str) -> String {
    let rows = dampscope::output::read_table(csv_text).unwrap();
    rows[0].get(name).cloned().unwrap_or_default()
}

/// Analyses `input` from standard input in the 55 Hz band; D_corrected must be 2.5 % ± 2 %.
fn assert_stdin_gives_2_5_percent(input: &[u8]) {
    let out = dampscope(&["analyze", "-", "--band", "52.5:57.5"], input);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let d: f64 = cell(&text, "damping_ratio_corrected").parse().unwrap();
    assert!((d / 0.025 - 1.0).abs() < 0.02, "D = {d}");
}

fn assert_clean(out: &Output) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "panic: {err}");
}

#[test]
fn wav_piped_from_synth_is_analysed() {
    let wav = synth("wav");
    assert_eq!(&wav[..4], b"RIFF");
    assert_stdin_gives_2_5_percent(&wav);
}

#[test]
fn raw_f32_piped_from_synth_is_analysed() {
    let raw = synth("raw-f32");
    let out = dampscope(
        &[
            "analyze",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4000",
            "--channels",
            "1",
            "--band",
            "52.5:57.5",
            "--format",
            "jsonl",
        ],
        &raw,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = String::from_utf8(out.stdout).unwrap();
    let v: serde_json::Value = serde_json::from_str(line.lines().next().unwrap()).unwrap();
    let d = v["damping_ratio_corrected"].as_f64().unwrap();
    assert!((d / 0.025 - 1.0).abs() < 0.02, "D = {d}");
}

#[test]
fn csv_input_is_analysed() {
    let csv = synth("csv");
    assert_stdin_gives_2_5_percent(&csv);
}

#[test]
fn garbage_input_is_a_clear_error() {
    let out = dampscope(
        &["analyze", "-"],
        &[0u8, 159, 146, 150, 1, 2, 3, 255, 0, 0, 7],
    );
    assert_clean(&out);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("error"), "{err}");
}

#[test]
fn empty_input_is_a_clear_error() {
    let out = dampscope(&["analyze", "-"], b"");
    assert_clean(&out);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no samples"));
}

#[test]
fn truncated_wav_flushes_partial_results_and_exits_3() {
    let wav = synth("wav");
    // Cut after ~1 s, while the decay (100 dB down only after ~1.3 s) is still running.
    let cut = &wav[..wav.len() / 4 + 1];
    let out = dampscope(&["analyze", "-", "--band", "52.5:57.5"], cut);
    assert_clean(&out);
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(cell(&text, "flags").contains("input_truncated"), "{text}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("truncated"));
}

#[test]
fn truncated_raw_frame_is_reported() {
    let mut raw = synth("raw-f32");
    raw.truncate(raw.len() - 2);
    let out = dampscope(
        &[
            "analyze",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4000",
            "--channels",
            "1",
            "--band",
            "52.5:57.5",
        ],
        &raw,
    );
    assert_clean(&out);
    assert_eq!(out.status.code(), Some(3));
}

#[test]
fn nan_channel_is_flagged_and_the_other_channel_still_analysed() {
    // Two channels: ch0 a clean decay, ch1 holds a NaN.
    let fs = 4000.0;
    let mut text = String::from("time,a,b\n");
    for i in 0..16000 {
        let t = i as f64 / fs;
        let w = 2.0 * std::f64::consts::PI * 55.0;
        let x = (-(0.025 * w) * t).exp() * (w * t).sin();
        let y = if i == 100 { f64::NAN } else { x };
        text.push_str(&format!("{t},{x},{y}\n"));
    }
    let out = dampscope(&["analyze", "-", "--band", "52.5:57.5"], text.as_bytes());
    assert_clean(&out);
    assert_eq!(out.status.code(), Some(3));
    let rows = dampscope::output::read_table(&String::from_utf8(out.stdout).unwrap()).unwrap();
    let a = rows.iter().find(|r| r["channel"] == "a").unwrap();
    let b = rows.iter().find(|r| r["channel"] == "b").unwrap();
    assert!(!a["damping_ratio"].is_empty());
    assert!(b["damping_ratio"].is_empty());
    assert!(b["flags"].contains("non_finite_input"));
    assert!(String::from_utf8_lossy(&out.stderr).contains("NaN"));
}

/// Raw f32 from 16 channels takes the decoder that checks finiteness while it converts (groups
/// of eight channels): a NaN in one channel's second block and an infinity in another's first
/// eight frames flag exactly those two channels, and the 14 others are analysed.
#[test]
fn non_finite_samples_found_by_the_decoder_flag_only_their_channels() {
    let (fs, n_ch, frames) = (4000.0, 16usize, 16000usize);
    let w = 2.0 * std::f64::consts::PI * 55.0;
    let mut raw = Vec::with_capacity(frames * n_ch * 4);
    for i in 0..frames {
        let t = i as f64 / fs;
        let x = ((-(0.025 * w) * t).exp() * (w * t).sin()) as f32;
        for c in 0..n_ch {
            let v = match (c, i) {
                (5, 5000) => f32::NAN,
                (12, 3) => f32::INFINITY,
                _ => x,
            };
            raw.extend_from_slice(&v.to_le_bytes());
        }
    }
    let out = dampscope(
        &[
            "analyze",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4000",
            "--channels",
            "16",
            "--band",
            "52.5:57.5",
        ],
        &raw,
    );
    assert_clean(&out);
    assert_eq!(out.status.code(), Some(3));
    let rows = dampscope::output::read_table(&String::from_utf8(out.stdout).unwrap()).unwrap();
    for c in 0..n_ch {
        let name = format!("ch{c}");
        let row = rows.iter().find(|r| r["channel"] == name).unwrap();
        if c == 5 || c == 12 {
            assert!(row["flags"].contains("non_finite_input"), "{name}: {row:?}");
            assert!(row["damping_ratio"].is_empty(), "{name}");
        } else {
            assert!(
                !row["flags"].contains("non_finite_input"),
                "{name}: {row:?}"
            );
            let d: f64 = row["damping_ratio"].parse().unwrap();
            assert!((d - 0.025).abs() < 0.0025, "{name}: D {d}");
        }
    }
}

/// Standard input redirected from a file is decoded from the mapped file, a pipe is read as a
/// stream: the same rows, exit code and error for a whole raw file (8 channels, two hits) and for
/// one that ends inside a frame; a file named on the command line likewise.
#[test]
fn raw_input_from_a_file_gives_what_the_same_bytes_piped_give() {
    let fs = 4000.0;
    let w = 2.0 * std::f64::consts::PI * 55.0;
    let mut raw = Vec::new();
    for i in 0..40000usize {
        let t = (i % 20000) as f64 / fs;
        let x = ((-(0.025 * w) * t).exp() * (w * t).sin()) as f32;
        for c in 0..8 {
            raw.extend_from_slice(&(x * (1.0 + c as f32)).to_le_bytes());
        }
    }
    let dir = crate::common::fresh_dir("mapped-stdin");
    let args = [
        "analyze",
        "-",
        "--raw",
        "f32",
        "--fs",
        "4000",
        "--channels",
        "8",
        "--band",
        "52.5:57.5",
    ];
    for stray in [0usize, 5] {
        let mut bytes = raw.clone();
        bytes.extend(std::iter::repeat_n(1u8, stray));
        let path = dir.join(format!("x{stray}.f32"));
        std::fs::write(&path, &bytes).unwrap();
        let piped = dampscope(&args, &bytes);
        let from_file = std::process::Command::new(env!("CARGO_BIN_EXE_dampscope"))
            .args(args)
            .stdin(std::fs::File::open(&path).unwrap())
            .output()
            .unwrap();
        let mut named = args.to_vec();
        named[1] = path.to_str().unwrap();
        let named = std::process::Command::new(env!("CARGO_BIN_EXE_dampscope"))
            .args(&named)
            .output()
            .unwrap();
        assert_eq!(piped.status.code(), Some(if stray == 0 { 0 } else { 3 }));
        let rows = String::from_utf8(piped.stdout.clone()).unwrap();
        assert_eq!(rows.lines().count(), 1 + 2 * 8, "{rows}");
        for other in [&from_file, &named] {
            assert_eq!(other.status.code(), piped.status.code());
            assert_eq!(other.stdout, piped.stdout);
        }
        assert_eq!(from_file.stderr, piped.stderr);
        if stray > 0 {
            assert!(String::from_utf8_lossy(&from_file.stderr).contains("5 stray bytes"));
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn recording_set_directory_is_analysed() {
    let dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/recording-set-example");
    assert!(dir.is_dir(), "reference data missing: {}", dir.display());
    let out = dampscope(
        &[
            "analyze",
            dir.to_str().unwrap(),
            "--window-ms",
            "50",
            "--bands",
            "0:200:20",
            "--range",
            "t20",
        ],
        b"",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows = dampscope::output::read_table(&String::from_utf8(out.stdout).unwrap()).unwrap();
    let channels: std::collections::BTreeSet<_> =
        rows.iter().map(|r| r["channel"].clone()).collect();
    assert_eq!(channels.len(), 4, "{channels:?}");
}

/// The library names a bad setting by its field (`overlap`, `window_ms`, `bands`); the command
/// line says which flag set it, and nothing in the library's own message names a flag.
#[test]
fn a_bad_setting_is_named_by_its_flag() {
    let wav = synth("wav");
    for (flag, value) in [
        ("--overlap", "1.5"),
        ("--window-ms", "0.1"),
        ("--min-points", "1"),
    ] {
        let out = dampscope(&["analyze", "-", flag, value], &wav);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(
            err.contains(&format!("invalid setting {flag}:")),
            "{flag}: {err}"
        );
    }
    // A band layout is checked as the command line is parsed: a usage error naming the flag.
    let out = dampscope(&["analyze", "-", "--bands", "5:1:1"], &wav);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("'--bands") && err.contains("expected 0 <= LO < HI"),
        "{err}"
    );
    let settings = dampscope::frontend::stft::StftSettings {
        overlap: 1.5,
        ..Default::default()
    };
    let bands = [dampscope::frontend::Band::new(100.0, 200.0).unwrap()];
    let e = dampscope::frontend::stft::StftFrontEnd::new(settings, 4000.0, &bands)
        .err()
        .expect("overlap 1.5 is refused");
    assert!(!e.to_string().contains("--"), "{e}");
}

/// A WAV redirected to standard input from a file (`analyze - < rec.wav`: opened as the file,
/// its samples decoded from the mapping) gives the rows of the same file by path and of the same
/// bytes through a pipe, and so it does without mapping (`DAMPSCOPE_NO_MMAP`).
#[test]
fn a_wav_redirected_to_standard_input_reads_as_the_file() {
    let wav = synth("wav");
    let path = std::env::temp_dir().join(format!("dampscope-stdin-{}.wav", std::process::id()));
    std::fs::write(&path, &wav).unwrap();
    let args = ["analyze", "--band", "52.5:57.5", "--format", "jsonl"];
    let by_path = dampscope(&[&args[..], &[path.to_str().unwrap()]].concat(), b"");
    let piped = dampscope(&[&args[..], &["-"]].concat(), &wav);
    let redirected = |map: bool| {
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_dampscope"));
        cmd.args(args).arg("-");
        cmd.stdin(std::fs::File::open(&path).unwrap());
        if !map {
            cmd.env(dampscope::source::mapped::NO_MAP_ENV, "1");
        }
        cmd.output().unwrap()
    };
    for out in [&by_path, &piped] {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    assert!(!by_path.stdout.is_empty());
    assert_eq!(by_path.stdout, piped.stdout);
    for map in [true, false] {
        let out = redirected(map);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(out.stdout, by_path.stdout, "mapped: {map}");
    }
    std::fs::remove_file(&path).ok();
}

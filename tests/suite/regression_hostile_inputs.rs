//! Hostile input as a new user might give it (issue 12's probe): none may abort the process.
//! Each case must end with a typed message and a meaningful exit code (1 error, 2 usage, 3
//! partial), never a signal (an allocation failure aborts with SIGABRT, exit 134). The one case
//! the probe found aborting — a 5000 × 5000 mesh (`memory allocation of 1306800000000 bytes
//! failed`) — is refused now when the model is loaded, in well under a second, naming the
//! sizes, the estimate and the limit.

use std::time::{Duration, Instant};

use crate::common::{fresh_dir, run_dampscope as dampscope};

/// Runs `args` with `stdin`; asserts a clean ending with one of `codes` and `words` on stderr.
fn clean_failure(args: &[&str], stdin: &[u8], codes: &[i32], words: &[&str]) -> Duration {
    let t0 = Instant::now();
    let o = dampscope(args, stdin);
    let took = t0.elapsed();
    let e = String::from_utf8_lossy(&o.stderr);
    let code = o.status.code();
    assert!(
        code.is_some_and(|c| codes.contains(&c)),
        "{args:?}: exit {:?} (a signal if None), want one of {codes:?}\n{e}",
        o.status
    );
    assert!(!e.contains("panicked"), "{args:?} panicked:\n{e}");
    for w in words {
        assert!(e.contains(w), "{args:?}: stderr should contain {w:?}:\n{e}");
    }
    took
}

/// A WAV header (PCM 16-bit, 4000 Hz) with the given channel count and claimed data size, then
/// `data`.
fn wav_header(channels: u16, claimed_data_bytes: u32, data: &[u8]) -> Vec<u8> {
    pcm_wav(channels, 2, 4000, claimed_data_bytes, data)
}

/// A PCM WAV header of `bytes_per_sample`-byte samples at `fs` Hz claiming
/// `claimed_data_bytes`, then `data`.
fn pcm_wav(
    channels: u16,
    bytes_per_sample: u16,
    fs: u32,
    claimed_data_bytes: u32,
    data: &[u8],
) -> Vec<u8> {
    let frame = u32::from(channels) * u32::from(bytes_per_sample);
    let mut w = Vec::new();
    w.extend_from_slice(b"RIFF");
    w.extend_from_slice(&claimed_data_bytes.saturating_add(36).to_le_bytes());
    w.extend_from_slice(b"WAVEfmt ");
    w.extend_from_slice(&16u32.to_le_bytes());
    w.extend_from_slice(&1u16.to_le_bytes());
    w.extend_from_slice(&channels.to_le_bytes());
    w.extend_from_slice(&fs.to_le_bytes());
    w.extend_from_slice(&(fs * frame).to_le_bytes());
    w.extend_from_slice(&frame.min(u16::MAX as u32).to_le_bytes()[..2]);
    w.extend_from_slice(&(8 * bytes_per_sample).to_le_bytes());
    w.extend_from_slice(b"data");
    w.extend_from_slice(&claimed_data_bytes.to_le_bytes());
    w.extend_from_slice(data);
    w
}

#[test]
fn a_5000_by_5000_mesh_is_refused_in_under_a_second_by_every_command() {
    let dir = fresh_dir("hostile-mesh");
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/plate-homogeneous.toml"),
    )
    .unwrap()
    .replace("nx = 32", "nx = 5000")
    .replace("ny = 48", "ny = 5000");
    let model = dir.join("huge.toml");
    std::fs::write(&model, text).unwrap();
    let m = model.to_str().unwrap();
    let out = dir.join("out");
    let o = out.to_str().unwrap();
    let words = ["5000×5000×2 mesh", "225.1 M dofs", "more than the limit"];
    for args in [
        vec!["modes", "--model", m],
        vec!["simulate", "--model", m, "--out", o],
        vec!["--max-memory", "64G", "simulate", "--model", m, "--out", o],
        vec![
            "analyze",
            "--model",
            m,
            "--bands",
            "model",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4096",
            "--channels",
            "1",
        ],
    ] {
        let took = clean_failure(&args, &[0u8; 4096], &[1], &words);
        assert!(took < Duration::from_secs(1), "{args:?} took {took:?}");
    }
    assert!(!out.exists(), "nothing written");
}

#[test]
fn broken_inputs_end_with_a_message_not_a_signal() {
    let mut random = Vec::new();
    let mut x = 0x9e3779b97f4a7c15u64;
    for _ in 0..5000 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        random.push(x as u8);
    }
    let nan_csv = b"time,a\n0,0.5\n0.001,NaN\n0.002,0.25\n".to_vec();
    let cases: Vec<(&str, Vec<&str>, Vec<u8>)> = vec![
        ("empty", vec!["analyze", "-"], Vec::new()),
        ("random bytes", vec!["analyze", "-"], random.clone()),
        (
            "random raw f32 without a rate",
            vec!["analyze", "-", "--raw", "f32"],
            random.clone(),
        ),
        (
            "ragged csv",
            vec!["analyze", "-", "--fs", "1000"],
            b"a,b\n1,2\n3\n4,5,6\n".to_vec(),
        ),
        (
            "truncated wav",
            vec!["analyze", "-"],
            wav_header(2, 8000, &[0u8; 100]),
        ),
        (
            "a header claiming 2^31 bytes",
            vec!["analyze", "-"],
            wav_header(1, 1 << 31, &[0u8; 64]),
        ),
        ("zero channels", vec!["analyze", "-"], wav_header(0, 0, &[])),
        (
            "65535 channels",
            vec!["analyze", "-"],
            wav_header(65535, 65535 * 2 * 4, &[0u8; 4096]),
        ),
        ("NaN samples", vec!["analyze", "-", "--fs", "1000"], nan_csv),
        (
            "an absurd window",
            vec![
                "analyze",
                "-",
                "--raw",
                "f32",
                "--fs",
                "4096",
                "--window-ms",
                "1e12",
            ],
            vec![0u8; 4096],
        ),
        (
            "two million bands",
            vec![
                "analyze",
                "-",
                "--raw",
                "f32",
                "--fs",
                "4096",
                "--bands",
                "1:2000001:1",
            ],
            vec![0u8; 4096],
        ),
        (
            "a zero sample rate",
            vec!["analyze", "-", "--raw", "f32", "--fs", "0"],
            vec![0u8; 64],
        ),
    ];
    for (what, args, stdin) in cases {
        let o = dampscope(&args, &stdin);
        let e = String::from_utf8_lossy(&o.stderr);
        let code = o.status.code();
        assert!(
            matches!(code, Some(0..=3)),
            "{what}: exit {:?} (None = killed by a signal)\n{e}",
            o.status
        );
        assert!(!e.contains("panicked"), "{what} panicked:\n{e}");
        if code != Some(0) {
            assert!(
                e.starts_with("dampscope: ") || e.starts_with("error: "),
                "{what}: {e}"
            );
        }
    }
}

/// An FRF CSV piped to standard input was read as time series (its `f`, `h1_re`, `h1_im`
/// columns as three channels, rows out with a given `--fs`); FRF input is read whole from a
/// file, so a stream that starts like one is refused, saying so (exit 1), a comment line first
/// or not.
#[test]
fn an_frf_csv_on_standard_input_is_refused_not_read_as_time_series() {
    for text in [
        "f,h1_re,h1_im\n0,1,0\n1,0.5,0.1\n2,0.2,0.1\n",
        "# measured 2026-11-27\n\nfreq_hz,a_db,a_deg\n0,0,0\n1,-3,10\n",
    ] {
        let out =
            crate::common::TestCommand::new(["analyze", "-", "--fs", "1000", "--band", "10:50"])
                .stdin(text.as_bytes())
                .output();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("FRF CSV"), "{err}");
        assert!(
            out.stdout.is_empty(),
            "{}",
            String::from_utf8_lossy(&out.stdout)
        );
    }
    // A time series whose column merely starts with f is still read.
    let out = crate::common::TestCommand::new(["analyze", "-", "--fs", "1000", "--band", "10:50"])
        .stdin(b"force,x\n0,1\n1,0.5\n2,0.25\n")
        .output();
    assert!(!String::from_utf8_lossy(&out.stderr).contains("FRF CSV"));
}

/// Found piping WAV streams as recorders write them to a pipe: arecord's header says 0x80000000
/// data bytes and SoX's 0x7FFFF000 rounded down to whole frames. Read as lengths, a stream that
/// ended normally was flagged `input_truncated` (exit 3), and a 24-bit stereo one refused (0x80000000
/// is not a multiple of 6 bytes). They are "unknown length", as 0 and 0xFFFFFFFF are.
#[test]
fn recorders_unknown_length_placeholders_are_read_to_the_end() {
    let fs = 4000u32;
    let decay = crate::common::decaying_sines(&[(200.0, 0.01, 0.5, 0.0)], f64::from(fs), 2.0);
    for (bytes_per_sample, placeholder) in [
        (2u16, 0x8000_0000u32),
        (3, 0x8000_0000),
        (2, 0x7FFF_F000),
        (3, 0x7FFF_F000 - 0x7FFF_F000 % 6),
    ] {
        let channels = 2u16;
        let full_scale = f64::from(1u32 << (8 * bytes_per_sample - 1));
        let mut data = Vec::new();
        for v in &decay {
            let q = (v * full_scale).round() as i32;
            for _ in 0..channels {
                data.extend_from_slice(&q.to_le_bytes()[..bytes_per_sample as usize]);
            }
        }
        let w = pcm_wav(channels, bytes_per_sample, fs, placeholder, &data);
        let o = dampscope(&["analyze", "-"], &w);
        let out = String::from_utf8_lossy(&o.stdout);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{bytes_per_sample} bytes, {placeholder:#x}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(!out.contains("input_truncated"), "{out}");
        let row = out
            .lines()
            .find(|l| l.starts_with("ch0,") && l.contains(",175.000000,225.000000,"))
            .unwrap();
        assert!(row.contains(",0.010"), "{placeholder:#x}: {row}");
    }
}

/// Found by the contract probe: a WAV file declared raw (`--raw f32`) had its header read as
/// samples and its rate and channel count replaced by the options', giving rows and exit 0.
/// Given by path or redirected to standard input, it is now refused, saying to drop `--raw`.
#[test]
fn a_wav_file_declared_raw_is_refused_not_read_as_samples() {
    let dir = fresh_dir("raw-wav");
    let data: Vec<u8> = (0..8000i16)
        .map(|i| ((f64::from(i) * 0.3).sin() * 1e4) as i16)
        .flat_map(|s| s.to_le_bytes())
        .collect();
    let path = dir.join("rec.wav");
    std::fs::write(&path, wav_header(1, data.len() as u32, &data)).unwrap();
    let p = path.to_str().unwrap();
    let raw = ["--raw", "f32", "--fs", "4000", "--channels", "1"];
    let mut by_path = vec!["analyze", p];
    by_path.extend(raw);
    clean_failure(&by_path, b"", &[1, 2], &["drop --raw"]);
    let mut redirected = vec!["analyze", "-"];
    redirected.extend(raw);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_dampscope"))
        .args(&redirected)
        .stdin(std::fs::File::open(&path).unwrap())
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        matches!(o.status.code(), Some(1 | 2)),
        "{:?}\n{e}",
        o.status
    );
    assert!(e.contains("drop --raw"), "{e}");
    // Piped (`cat rec.wav | dampscope analyze - --raw f32 …`): the header was read as samples.
    let wav = std::fs::read(&path).unwrap();
    clean_failure(&redirected, &wav, &[1, 2], &["drop --raw"]);
}

/// Found by the contract probe: `cat a.wav b.wav | dampscope analyze -` analysed the first
/// file, left the second unread and exited 0 without a word. Now the run says so and exits 3;
/// the rows are the first file's alone, bit for bit, none flagged; also when the first file's
/// RIFF size counts its own 8-byte header. A trailing chunk inside the first file's RIFF chunk,
/// or bytes after it that are no WAV header, change nothing.
#[test]
fn a_second_wav_file_after_the_first_is_reported_not_ignored() {
    let dir = fresh_dir("concatenated-wav");
    let pcm = |f_hz: f64| -> Vec<u8> {
        (0..12000)
            .map(|i| {
                let t = f64::from(i) / 4000.0;
                ((-4.0 * t).exp() * (2.0 * std::f64::consts::PI * f_hz * t).sin() * 2e4) as i16
            })
            .flat_map(|s| s.to_le_bytes())
            .collect()
    };
    let (a, b) = (pcm(300.0), pcm(700.0));
    let first = wav_header(1, a.len() as u32, &a);
    let second = wav_header(1, b.len() as u32, &b);
    // The first file with a LIST chunk after its data, counted in its RIFF size.
    let mut listed = first.clone();
    listed.extend_from_slice(b"LIST\x05\x00\x00\x00abcde\x00");
    let riff = u32::from_le_bytes(listed[4..8].try_into().unwrap()) + 14;
    listed[4..8].copy_from_slice(&riff.to_le_bytes());
    // A writer that counts the RIFF chunk's 8-byte header in its size.
    let mut overcounted = first.clone();
    let riff = u32::from_le_bytes(overcounted[4..8].try_into().unwrap()) + 8;
    overcounted[4..8].copy_from_slice(&riff.to_le_bytes());
    let analyze = |name: &str, bytes: &[u8]| {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let p = path.to_str().unwrap().to_string();
        let by_path = dampscope(&["analyze", &p, "--bands", "octave"], b"");
        let redirected = std::process::Command::new(env!("CARGO_BIN_EXE_dampscope"))
            .args(["analyze", "-", "--bands", "octave"])
            .stdin(std::fs::File::open(&path).unwrap())
            .output()
            .unwrap();
        let piped = dampscope(&["analyze", "-", "--bands", "octave"], bytes);
        [by_path, redirected, piped]
    };
    let alone = analyze("a.wav", &first)[0].clone();
    assert_eq!(alone.status.code(), Some(0));
    let rows = String::from_utf8_lossy(&alone.stdout).to_string();
    // The first file's decay has a damping ratio (column 13) in some band.
    let damping = |l: &str| {
        l.split(',')
            .nth(13)
            .is_some_and(|d| d.parse::<f64>().is_ok())
    };
    assert!(rows.lines().skip(1).any(damping), "{rows}");
    for (name, bytes, another) in [
        ("ab.wav", [first.clone(), second.clone()].concat(), true),
        (
            "listed-b.wav",
            [listed.clone(), second.clone()].concat(),
            true,
        ),
        (
            "overcounted-b.wav",
            [overcounted, second.clone()].concat(),
            true,
        ),
        ("listed.wav", listed.clone(), false),
        (
            "junk.wav",
            [first.clone(), b"not a header at all".to_vec()].concat(),
            false,
        ),
    ] {
        for (how, o) in ["path", "redirected", "piped"]
            .iter()
            .zip(analyze(name, &bytes))
        {
            let e = String::from_utf8_lossy(&o.stderr);
            let want = if another { 3 } else { 0 };
            assert_eq!(o.status.code(), Some(want), "{name} {how}: {e}");
            assert_eq!(
                e.contains("another WAV file follows"),
                another,
                "{name} {how}: {e}"
            );
            assert_eq!(String::from_utf8_lossy(&o.stdout), rows, "{name} {how}");
        }
    }
}

/// Found by the contract probe: `resynth --fmax 0` was reported as "invalid setting --model:
/// output.fmax" (the option is copied into the model before its check). It is now a usage error
/// that names `--fmax`.
#[test]
fn resynth_with_no_frequency_range_names_its_option() {
    let dir = fresh_dir("resynth-fmax");
    let global = dir.join("global.csv");
    std::fs::write(
        &global,
        "f_lo_hz,f_hi_hz,f_center_hz,mean_d\n25,75,50,0.01\n",
    )
    .unwrap();
    let out = dir.join("out");
    for fmax in ["--fmax=0", "--fmax=-5", "--fmax=nan"] {
        clean_failure(
            &[
                "resynth",
                "--global",
                global.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                fmax,
            ],
            b"",
            &[2],
            &["--fmax", "expected a frequency > 0 Hz"],
        );
    }
}

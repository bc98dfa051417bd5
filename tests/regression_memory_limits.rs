//! Found probing limits on a 24 GB machine: a 2.6 MB WAV declaring 65 535 channels took 3.1 GB,
//! `--channels 1e9` with 400 bytes of input > 8 GB before the first frame, `--window-ms 2.5e7`
//! on a 2 s file 2.7 GB, a 500 × 500 mesh > 8 GB in 5 s, a 200 × 300 sensor grid in `simulate`
//! > 8 GB. Each is now refused before allocating, naming the estimate and the limit.

mod common;

use common::run_dampscope as dampscope;

use std::process::Output;

use common::fresh_dir;

fn refused(o: &Output, words: &[&str]) {
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    for w in words {
        assert!(e.contains(w), "{e} should contain {w}");
    }
}

/// An 8-bit PCM WAV header declaring `channels` channels, with `frames` frames of silence.
fn wide_wav(channels: u16, frames: usize) -> Vec<u8> {
    let data = channels as usize * frames;
    let mut w = Vec::new();
    w.extend_from_slice(b"RIFF");
    w.extend_from_slice(&(36 + data as u32).to_le_bytes());
    w.extend_from_slice(b"WAVEfmt ");
    w.extend_from_slice(&16u32.to_le_bytes());
    w.extend_from_slice(&1u16.to_le_bytes());
    w.extend_from_slice(&channels.to_le_bytes());
    w.extend_from_slice(&4000u32.to_le_bytes());
    w.extend_from_slice(&(4000 * channels as u32).to_le_bytes());
    w.extend_from_slice(&channels.to_le_bytes());
    w.extend_from_slice(&8u16.to_le_bytes());
    w.extend_from_slice(b"data");
    w.extend_from_slice(&(data as u32).to_le_bytes());
    w.resize(44 + data, 0x80);
    w
}

#[test]
fn a_wav_declaring_65535_channels_is_refused_before_allocating() {
    let o = dampscope(
        &["--max-memory", "200M", "analyze", "-", "--window-ms", "5"],
        &wide_wav(65535, 40),
    );
    refused(&o, &["memory", "65535 channels", "200.0 MB"]);
}

#[test]
fn a_billion_raw_channels_are_refused() {
    let o = dampscope(
        &[
            "--max-memory",
            "200M",
            "analyze",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4000",
            "--channels",
            "1000000000",
        ],
        &[0u8; 400],
    );
    refused(&o, &["memory", "1000000000 raw channels"]);
}

#[test]
fn a_window_longer_than_the_input_is_refused() {
    let dir = fresh_dir("mem-window");
    let wav = dir.join("s.wav");
    let w = wav.to_str().unwrap();
    let o = dampscope(
        &["synth", "--mode", "55:0.025", "--seconds", "2", "--out", w],
        b"",
    );
    assert!(o.status.success());
    let o = dampscope(&["analyze", w, "--window-ms", "2.5e7"], b"");
    refused(&o, &["--window-ms", "input's length"]);
    // On a stream of unknown length (raw samples), the memory budget refuses it.
    let raw: Vec<u8> = (0..8000)
        .flat_map(|i| (i as f32).sin().to_le_bytes())
        .collect();
    let o = dampscope(
        &[
            "--max-memory",
            "200M",
            "analyze",
            "-",
            "--raw",
            "f32",
            "--fs",
            "4000",
            "--channels",
            "1",
            "--window-ms",
            "2.5e7",
        ],
        &raw,
    );
    refused(&o, &["memory", "STFT window"]);
    let _ = std::fs::remove_dir_all(&dir);
}

fn model_with(dir: &std::path::Path, from: &str, to: &str) -> std::path::PathBuf {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/plate-homogeneous.toml"
    ))
    .unwrap();
    assert!(text.contains(from));
    let p = dir.join("model.toml");
    std::fs::write(&p, text.replace(from, to)).unwrap();
    p
}

#[test]
fn a_500_by_500_mesh_and_a_200_by_300_sensor_grid_are_refused() {
    let dir = fresh_dir("mem-sim");
    for (from, to, what) in [
        ("nx = 32\nny = 48", "nx = 500\nny = 500", "500×500×"),
        (
            "sensors = { nx = 33, ny = 49 }",
            "sensors = { nx = 200, ny = 300 }",
            "60000 sensors",
        ),
    ] {
        let m = model_with(&dir, from, to);
        let out = dir.join("set");
        let o = dampscope(
            &[
                "--max-memory",
                "4G",
                "simulate",
                "--model",
                m.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            b"",
        );
        refused(&o, &["memory", what]);
        assert!(!out.exists(), "nothing written");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

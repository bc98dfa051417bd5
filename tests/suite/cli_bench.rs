//! `dampscope bench`: every front end timed on the synthetic multichannel decays, and what it
//! times is the real analysis — whatever the thread count or profiling, the rows are the same.

use dampscope::analysis::bench::BenchInput;
use dampscope::pipeline::{run_with, AnalysisConfig, ResultRow, RunOptions};
use dampscope::plan::{BandLayout, BandSpec, FrontEndKind, FrontEndSpec};

#[test]
fn bench_prints_one_row_per_front_end_with_stage_shares() {
    let out = crate::common::TestCommand::new([
        "bench",
        "--channels",
        "3",
        "--seconds",
        "2",
        "--fs",
        "4096",
        "--repeat",
        "1",
        "--format",
        "jsonl",
    ])
    .ok();
    let rows: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["front_end"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["ingest", "stft", "octave", "goyder"], "{out}");
    for r in &rows {
        assert_eq!(r["channels"], 3, "{r}");
        assert!((r["seconds"].as_f64().unwrap() - 2.0).abs() < 1e-9, "{r}");
        let total = r["samples_per_s"].as_f64().unwrap();
        let per_channel = r["samples_per_s_per_channel"].as_f64().unwrap();
        assert!(
            total > 0.0 && (total / per_channel - 3.0).abs() < 1e-9,
            "{r}"
        );
        let name = r["front_end"].as_str().unwrap();
        assert_eq!(
            r["fft_bound_samples_per_s"].is_number(),
            name == "stft",
            "{r}"
        );
        if name == "ingest" {
            assert!(r["stages"].is_null(), "{r}");
            continue;
        }
        // IEC octave bands up to Nyquist at 4096 Hz: 31.5 … 1000 Hz.
        assert_eq!(r["bands"], 6, "{r}");
        let s = &r["stages"];
        let sum: f64 = ["read", "segment", "front_end", "estimator", "output"]
            .iter()
            .map(|k| s[k].as_f64().unwrap())
            .sum();
        assert!(
            (sum - 1.0).abs() < 1e-9 && s["front_end"].as_f64().unwrap() > 0.0,
            "{r}"
        );
    }
}

fn rows(input: &BenchInput, kind: FrontEndKind, options: RunOptions) -> Vec<ResultRow> {
    let bands = BandLayout {
        specs: vec!["octave".parse::<BandSpec>().unwrap()],
        ..Default::default()
    }
    .resolve(input.fs_hz, None)
    .unwrap()
    .bands;
    let factory = FrontEndSpec::default()
        .with_kind(kind)
        .factory(input.fs_hz, bands)
        .unwrap();
    let mut out = Vec::new();
    run_with(
        input.source().unwrap(),
        &factory,
        &AnalysisConfig::default(),
        options,
        |r| {
            out.extend_from_slice(r);
            Ok(())
        },
    )
    .unwrap();
    out
}

#[test]
fn threads_and_profiling_do_not_change_the_results() {
    let input = BenchInput::synthetic(5, 4096.0, 3.0).unwrap();
    let mut with_number = 0;
    for kind in FrontEndKind::ALL {
        let one = rows(
            &input,
            kind,
            RunOptions {
                threads: Some(1),
                ..Default::default()
            },
        );
        let two = rows(
            &input,
            kind,
            RunOptions {
                threads: Some(2),
                profile_stages: true,
                ..Default::default()
            },
        );
        assert_eq!(one.len(), 5 * 6, "{kind:?}");
        assert_eq!(one, two, "{kind:?}");
        with_number += one.iter().filter(|r| r.estimate.t60_s.is_some()).count();
    }
    // The peers' modes (ζ up to 5 %) fall 80 dB within tens of ms: the 200 ms STFT resolves
    // none, the banks' 1–2 ms frames some; the comparison above covers numbers, not only flags.
    assert!(with_number >= 3, "{with_number} of 90 bands with a T60");
}

/// Zero threads or zero timed runs is a usage error (exit 2, naming the flag), not a run
/// with one thread or one whose table times nothing.
#[test]
fn zero_threads_or_runs_are_refused() {
    for flag in ["--threads", "--repeat"] {
        let out =
            crate::common::TestCommand::new(["bench", "--seconds", "0.01", flag, "0"]).output();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag}: {err}");
        assert!(err.contains(flag), "{flag}: {err}");
        assert!(out.stdout.is_empty(), "{flag}");
    }
}

//! Lab formats end to end (issue 12): the simulated plate written as FRFs in a universal file
//! (`simulate --format uff`) and read back through the inverse FFT gives the same damping per
//! band as its impulse responses in a WAV; an exponential window asked for on the FRF input is
//! removed from D again; `modal --out` writes its modes as dataset 55 that read back.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::common::{csv_rows, fresh_dir, TestCommand};

/// The reference plate on a coarse mesh, 0–400 Hz, 4 × 4 sensors (between the mesh's nodes).
fn small_model(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/plate-homogeneous.toml"),
    )
    .unwrap()
    .replace("nx = 32", "nx = 12")
    .replace("ny = 48", "ny = 18")
    .replace("fmax = 2000.0", "fmax = 400.0")
    .replace(
        "sensors = { nx = 33, ny = 49 }",
        "sensors = { nx = 4, ny = 4 }",
    );
    let model = dir.join("small.toml");
    std::fs::write(&model, text).unwrap();
    model
}

/// `analyze INPUT --bands model` rows keyed by (channel, band centre).
fn damping_by_band(input: &Path, model: &Path, extra: &[&str]) -> HashMap<(String, String), f64> {
    let out = input.with_extension("results.csv");
    TestCommand::new(["analyze"])
        .arg(input)
        .args(["--bands", "model", "--model"])
        .arg(model)
        .args(extra)
        .arg("--out")
        .arg(&out)
        .ok();
    csv_rows(&out)
        .into_iter()
        .filter_map(|r| {
            let d: f64 = r["damping_ratio"].parse().ok()?;
            Some(((r["channel"].clone(), r["f_center"].clone()), d))
        })
        .collect()
}

#[test]
fn the_plate_through_uff_58_gives_the_damping_it_gives_through_wav() {
    let dir = fresh_dir("cli-uff");
    let model = small_model(&dir);
    let (wav_set, uff_set) = (dir.join("wav"), dir.join("uff"));
    TestCommand::new(["simulate", "--model"])
        .arg(&model)
        .arg("--out")
        .arg(&wav_set)
        .ok();
    TestCommand::new(["simulate", "--format", "uff", "--model"])
        .arg(&model)
        .arg("--out")
        .arg(&uff_set)
        .ok();
    assert!(uff_set.join("responses.uff").exists() && !uff_set.join("responses.wav").exists());
    let via_wav = damping_by_band(&wav_set, &model, &[]);
    let via_uff = damping_by_band(&uff_set, &model, &[]);
    assert!(via_wav.len() >= 16, "{} numbers", via_wav.len());
    let mut compared = 0;
    for (key, d_wav) in &via_wav {
        let Some(d_uff) = via_uff.get(key) else {
            panic!("{key:?}: a number through WAV, none through UFF");
        };
        assert!(
            (d_uff / d_wav - 1.0).abs() < 1e-3,
            "{key:?}: D {d_uff} through UFF, {d_wav} through WAV"
        );
        compared += 1;
    }
    assert_eq!(compared, via_uff.len(), "the same bands give numbers");

    // An exponential window on the FRF input, τ = 2 s on a 4 s record: it adds 1/(2π f τ) to D
    // (up to a third of D in the lowest bands); removed again, D is back within 2 % wherever
    // the band's energy is its own mode's (dominant frequency within 3 % of its centre: a band
    // carrying another mode's skirt is a multi-exponential, and the window reweights it) and
    // the 200 ms STFT window holds at least 6 periods (≥ 30 Hz). Measured below 30 Hz: +4…6 %
    // at 11.9 Hz, where the window adds 30 % to D; above, at most 1.6 % (a single-mode FRF is
    // corrected to 1e-4: `uff_format`; the plate's bands hold several modes).
    let tau_s = 2.0;
    let windowed = damping_by_band(&uff_set, &model, &["--frf-window-s", "2"]);
    let dominant: HashMap<(String, String), f64> = csv_rows(&uff_set.with_extension("results.csv"))
        .into_iter()
        .filter_map(|r| {
            let f: f64 = r["f_dominant"].parse().ok()?;
            Some(((r["channel"].clone(), r["f_center"].clone()), f))
        })
        .collect();
    let (mut checked, mut largest_share) = (0, 0.0f64);
    for (key, d) in &windowed {
        let (Some(d0), Some(f_dom)) = (via_uff.get(key), dominant.get(key)) else {
            continue;
        };
        let f_center: f64 = key.1.parse().unwrap();
        if (f_dom / f_center - 1.0).abs() > 0.03 || f_center < 30.0 {
            continue;
        }
        let added = 1.0 / (std::f64::consts::TAU * f_center * tau_s);
        largest_share = largest_share.max(added / d0);
        assert!(
            (d / d0 - 1.0).abs() < 0.02,
            "{key:?}: {d} windowed, {d0} not"
        );
        checked += 1;
    }
    assert!(checked >= 8, "{checked} bands checked");
    assert!(
        largest_share > 0.1,
        "the window was too weak to test: {largest_share}"
    );
    let rows = csv_rows(&uff_set.with_extension("results.csv"));
    assert!(rows.iter().all(
        |r| r["flags"].contains("exponential_window_removed") || r["damping_ratio"].is_empty()
    ));

    // Modal identification writes its modes as a universal file too.
    let modal_out = dir.join("modal");
    TestCommand::new(["modal"])
        .arg(&wav_set)
        .args(["--fmin", "10", "--fmax", "150", "--out"])
        .arg(&modal_out)
        .ok();
    let modes = csv_rows(&modal_out.join("modes.csv"));
    let uff = dampscope::uff::read_uff(modal_out.join("modes.uff")).unwrap();
    let shapes: Vec<_> = uff.mode_shapes().collect();
    assert_eq!(shapes.len(), modes.len());
    assert!(!modes.is_empty());
    for (s, m) in shapes.iter().zip(&modes) {
        let f: f64 = m["frequency_hz"].parse().unwrap();
        let d: f64 = m["damping_ratio"].parse().unwrap();
        let (fu, du) = (
            s.analysis.frequency_hz().unwrap(),
            s.analysis.damping_ratio().unwrap(),
        );
        assert!((fu / f - 1.0).abs() < 1e-5, "{fu} vs {f}");
        assert!((du / d - 1.0).abs() < 1e-4, "{du} vs {d}");
    }
    assert_eq!(uff.nodes().count(), 16);
}

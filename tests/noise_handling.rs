//! Decays that end in a noise floor: Lundeby truncation and compensation.

mod common;

use common::{decaying_sines, gaussian_noise, rel_err, stft_estimate};
use dampscope::decay::{EvaluationRange, Flag};

fn noisy(f: f64, d: f64, psnr_db: f64, seconds: f64, fs: f64) -> Vec<f64> {
    let x = decaying_sines(&[(f, d, 1.0, 0.0)], fs, seconds);
    let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let noise = gaussian_noise(x.len(), peak * 10f64.powf(-psnr_db / 20.0), 7);
    x.iter().zip(noise).map(|(a, b)| a + b).collect()
}

#[test]
fn noise_floor_is_found_and_compensated() {
    let fs = 4000.0;
    for (f, d) in [(55.0, 0.025), (100.0, 0.01)] {
        let x = noisy(f, d, 35.0, 12.0, fs);
        let est = stft_estimate(&x, fs, 200.0, f - 2.5, f + 2.5, EvaluationRange::T20);
        eprintln!("{f} Hz: {:?}", est);
        assert!(est.has(Flag::NoiseCompensated), "{:?}", est.flags);
        let dc = est.damping_ratio_corrected.expect("estimate");
        assert!(rel_err(dc, d) < 0.03, "{f} Hz: D = {dc}");
    }
}

#[test]
fn too_little_dynamic_range_is_noise_limited_not_a_number() {
    let fs = 4000.0;
    // 5 dB of broadband PSNR leaves a band peak-to-noise ratio far below the 45 dB T30 needs.
    let x = noisy(55.0, 0.025, 5.0, 12.0, fs);
    let est = stft_estimate(&x, fs, 200.0, 52.5, 57.5, EvaluationRange::T30);
    assert_eq!(est.t60_s, None, "{:?}", est);
    assert!(est.has(Flag::NoiseLimited), "{:?}", est.flags);
}

/// A 4.2 kHz structural mode (D = 1 %, T60 = 26 ms) 70 dB above white noise, through a wide
/// reversed octave-bank band at 0.1 ms frames (what `--bands auto` now gives on the PCB impact
/// record): a number within 3 %. (It also passes with pyrato's unscaled Lundeby block; the
/// scaled block is not yet pinned by a test that fails without it.)
#[test]
fn a_fast_structural_decay_in_noise_gets_a_number() {
    use dampscope::decay::estimate::EstimateSettings;
    use dampscope::frontend::octave_bank::{OctaveBankFrontEnd, OctaveBankSettings};
    use dampscope::frontend::Band;
    let (fs, f, d) = (51_200.0, 4166.0, 0.01);
    let x = noisy(f, d, 70.0, 0.5, fs);
    let band = Band::new(3606.0, 4727.0).unwrap();
    let s = OctaveBankSettings {
        frame_period_ms: 0.1,
        ..Default::default()
    };
    let mut fe = OctaveBankFrontEnd::new(s, fs, &[band]).unwrap();
    let settings = EstimateSettings {
        range: EvaluationRange::T20,
        ..Default::default()
    };
    let est = dampscope::pipeline::analyze_decay(&x, &mut fe, &settings).remove(0);
    let dc = est
        .damping_ratio_corrected
        .unwrap_or_else(|| panic!("no number: {:?}", est.flags));
    assert!(rel_err(dc, d) < 0.03, "D = {dc}, flags {:?}", est.flags);
}

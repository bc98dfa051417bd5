//! Decays that end in a noise floor: Lundeby truncation and compensation.

use crate::common::{decaying_sines, gaussian_noise, rel_err, stft_estimate};
use dampscope::decay::{EvaluationRange, Flag};

fn noisy(f: f64, d: f64, psnr_db: f64, seconds: f64, fs: f64) -> Vec<f64> {
    let x = decaying_sines(&[(f, d, 1.0, 0.0)], fs, seconds);
    let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let noise = gaussian_noise(x.len(), peak * 10f64.powf(-psnr_db / 20.0), 7);
    x.iter().zip(noise).map(|(a, b)| a + b).collect()
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

/// Fast structural modes (T60 = 13–26 ms: 4.2 kHz with D = 1 % and 2 %, 8 kHz with D = 1 %)
/// 60–70 dB above white noise, through a reversed octave-bank band at 0.1 ms frames (what
/// `--bands auto` gives on the PCB impact record) and through the Goyder bank: a number within 3 %.
/// With pyrato's unscaled Lundeby block (800/f + 10 ms, as long as the whole decay) the
/// 13 ms decays were all refused as `noise_limited` (measured: 4.2 kHz/2 % and 8 kHz/1 %, both
/// banks, both noise levels); the block scaled to a fifth of the curve's 10 dB time gets them.
#[test]
fn a_fast_structural_decay_in_noise_gets_a_number() {
    use dampscope::decay::estimate::EstimateSettings;
    use dampscope::frontend::goyder::{GoyderFrontEnd, GoyderSettings};
    use dampscope::frontend::octave_bank::{OctaveBankFrontEnd, OctaveBankSettings};
    use dampscope::frontend::{Band, FrontEnd};
    let fs = 51_200.0;
    for (f, d) in [(4166.0, 0.01), (4166.0, 0.02), (8000.0, 0.01)] {
        for psnr_db in [60.0, 70.0] {
            let x = noisy(f, d, psnr_db, 0.5, fs);
            let band = Band::new(f / 1.2, f * 1.2).unwrap();
            let octave = OctaveBankSettings {
                frame_period_ms: 0.1,
                ..Default::default()
            };
            let front_ends: [Box<dyn FrontEnd>; 2] = [
                Box::new(OctaveBankFrontEnd::new(octave, fs, &[band]).unwrap()),
                Box::new(GoyderFrontEnd::new(GoyderSettings::default(), fs, &[band]).unwrap()),
            ];
            for mut fe in front_ends {
                let settings = EstimateSettings {
                    range: EvaluationRange::T20,
                    ..Default::default()
                };
                let est = dampscope::pipeline::analyze_decay(&x, fe.as_mut(), &settings).remove(0);
                let case = format!("{f} Hz, D {d}, {psnr_db} dB, {}", fe.name());
                let dc = est
                    .damping_ratio_corrected
                    .unwrap_or_else(|| panic!("{case}: no number: {:?}", est.flags));
                assert!(
                    rel_err(dc, d) < 0.03,
                    "{case}: D = {dc}, flags {:?}",
                    est.flags
                );
            }
        }
    }
}

/// A clean decay cut off after 7.5 dB (a 125 Hz mode with T60 = 4.9 s recorded for 0.6 s, no
/// noise floor to detect): its backward integral still plunges to −∞ at the record's end, which
/// gave an EDT of 4.86 s on a measured clap before the range check ran on every number. Now EDT,
/// T20 and T30 all need the band energy to end below their lower limit: nothing is reported.
/// The same mode recorded for 3 s (37 dB) gets its EDT and T20 back.
#[test]
fn a_decay_cut_off_above_the_range_gives_no_number() {
    let fs = 4000.0;
    let (f, t60) = (125.0, 4.86);
    let d = 1.1 / (t60 * f);
    let short = decaying_sines(&[(f, d, 1.0, 0.0)], fs, 0.6);
    for range in [
        EvaluationRange::Edt,
        EvaluationRange::T20,
        EvaluationRange::T30,
    ] {
        let est = stft_estimate(&short, fs, 100.0, f - 20.0, f + 20.0, range);
        assert_eq!(est.t60_s, None, "{range:?}: {est:?}");
        assert!(est.has(Flag::TooShort), "{range:?}: {:?}", est.flags);
        assert_eq!(est.edt_s, None, "{range:?}: EDT {:?}", est.edt_s);
    }
    let long = decaying_sines(&[(f, d, 1.0, 0.0)], fs, 3.0);
    let est = stft_estimate(&long, fs, 100.0, f - 20.0, f + 20.0, EvaluationRange::T20);
    // (EDT reads 5 % short: the first 10 dB take 0.8 s, of which the 100 ms window's ramp-up
    // is a part; this test is about the range check, not about that.)
    let edt = est.edt_s.expect("EDT of a 37 dB decay");
    assert!(rel_err(edt, t60) < 0.1, "EDT {edt} s, want {t60}");
    let t20 = est
        .t60_s
        .unwrap_or_else(|| panic!("T20 of a 37 dB decay: {est:?}"));
    assert!(rel_err(t20, t60) < 0.03, "T20 {t20} s, want {t60}");
}

/// Regression: the noise floor was taken for a decay still falling on 2 of 16 noise
/// realizations (the last tenth of a 12 s record is 12 fluctuating STFT frames), so the raw
/// Schroeder curve with its noise tail was fitted and the number withheld as `poor_fit`
/// (C = 2700–7000 %). Every seed must now be compensated; each estimate within 4 % (the spread
/// over realizations at this noise level: −2.9 … +3.1 % measured) and their mean within 1 %.
#[test]
fn a_noise_floor_is_found_whatever_the_noise_realization() {
    let fs = 4000.0;
    for (f, d) in [(55.0, 0.025), (100.0, 0.01)] {
        let mut sum = 0.0;
        for seed in 1..=8u64 {
            let x0 = decaying_sines(&[(f, d, 1.0, 0.0)], fs, 12.0);
            let peak = x0.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let noise = gaussian_noise(x0.len(), peak * 10f64.powf(-35.0 / 20.0), seed);
            let x: Vec<f64> = x0.iter().zip(noise).map(|(a, b)| a + b).collect();
            let est = stft_estimate(&x, fs, 200.0, f - 2.5, f + 2.5, EvaluationRange::T20);
            assert!(
                est.has(Flag::NoiseCompensated),
                "seed {seed}, {f} Hz: {est:?}"
            );
            let dc = est.damping_ratio_corrected.expect("estimate");
            assert!(rel_err(dc, d) < 0.04, "seed {seed}, {f} Hz: D = {dc}");
            sum += dc;
        }
        assert!(
            rel_err(sum / 8.0, d) < 0.01,
            "{f} Hz: mean D = {}",
            sum / 8.0
        );
    }
}

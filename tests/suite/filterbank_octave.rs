//! Issue 4 acceptance: the IEC octave bank on pyrato's analytic room impulse responses
//! (`tests/data/pyrato/`, copied from shared/reference/pyrato_tests; a missing file fails).

use std::path::PathBuf;

use crate::common::{decaying_sines, rel_err};
use dampscope::decay::estimate::EstimateSettings;
use dampscope::decay::{DecayEstimate, EvaluationRange, Flag};
use dampscope::frontend::iec_bands::{iec_bands, OctaveFraction};
use dampscope::frontend::octave_bank::{
    butterworth_bandpass, OctaveBankFrontEnd, OctaveBankSettings,
};
use dampscope::frontend::FilterDirection;
use dampscope::frontend::{Band, FrontEnd};
use dampscope::pipeline::analyze_decay;

fn reference(name: &str) -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/pyrato")
        .join(name);
    std::fs::read_to_string(&p)
        .unwrap_or_else(|e| panic!("reference file {} not readable ({e})", p.display()))
}

fn numbers(line: &str) -> Vec<f64> {
    line.split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| {
            s.trim()
                .parse::<f64>()
                .expect("a number in the reference CSV")
        })
        .collect()
}

fn octave(
    x: &[f64],
    fs: f64,
    direction: FilterDirection,
    range: EvaluationRange,
) -> Vec<(Band, DecayEstimate)> {
    let (bands, _) = iec_bands(OctaveFraction::Octave, 63.0, fs).unwrap();
    let s = OctaveBankSettings {
        direction,
        ..Default::default()
    };
    let mut fe = OctaveBankFrontEnd::new(s, fs, &bands).unwrap();
    let settings = EstimateSettings {
        range,
        ..Default::default()
    };
    let est = analyze_decay(x, &mut fe, &settings);
    bands.into_iter().zip(est).collect()
}

/// `analytic_rir_rigid_walls.csv`: 44.1 kHz, T60 = 1 s by construction for every mode, no
/// noise. The room (0.8 × 0.5 × 0.3 m, c = 343.9 m/s) has its first mode at 215 Hz and the
/// modal sum stops at 1 kHz, so only the 250, 500 and 1000 Hz octaves hold modes: they are
/// within 3 %. The 63, 125 and 2000–8000 Hz octaves hold nothing but the filter skirts of the
/// modes around 215 Hz and 0.9 kHz (their band signals oscillate at those frequencies): they
/// are flagged `leakage` and give no number. (Before the leakage test they reported 1 s, right
/// by accident, because every mode of this room decays at the same rate.)
#[test]
fn rigid_walls_rir_t20_t30_within_3_percent_where_modes_are_and_leakage_elsewhere() {
    let text = reference("analytic_rir_rigid_walls.csv");
    let x: Vec<f64> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| l.trim().parse::<f64>().expect("one number per line"))
        .collect();
    assert_eq!(x.len(), 65536);
    for direction in [FilterDirection::Reversed, FilterDirection::Forward] {
        for range in [EvaluationRange::T20, EvaluationRange::T30] {
            let rows = octave(&x, 44_100.0, direction, range);
            assert_eq!(rows.len(), 8, "63 Hz … 8 kHz");
            for (band, e) in rows {
                let modal = (250.0..=1000.0).contains(&band.nominal_hz);
                if modal {
                    let t = e.t60_s.unwrap_or(f64::NAN);
                    assert!(
                        rel_err(t, 1.0) < 0.03,
                        "{direction:?} {range:?} {} Hz: T = {t}, flags {:?}",
                        band.nominal_hz,
                        e.flags
                    );
                } else {
                    let f = e.f_dominant_hz.unwrap_or(f64::NAN);
                    assert!(
                        e.has(Flag::Leakage) && e.t60_s.is_none(),
                        "{direction:?} {range:?} {} Hz: {:?}",
                        band.nominal_hz,
                        e
                    );
                    // What the band holds oscillates at the modes next to it.
                    assert!(
                        (200.0..1200.0).contains(&f),
                        "{} Hz band: f_dominant {f}",
                        band.nominal_hz
                    );
                }
            }
        }
    }
}

/// `analytic_rir_psnr50_2D.csv`: fs 3000 Hz, T60 = 1 s and 2 s plus white noise. In spite of the
/// file's name the noise has σ = 0.00999 (Lundeby's noise energy 9.99e-5 in the reference, and
/// the residual against the regenerated noise-free RIR, `scripts/pyrato_octave_psnr.py`), i.e.
/// a broadband peak-SNR of 40 dB. Per octave band the peak-to-noise ratio is only 31–37 dB,
/// below the 45 dB that ISO 3382 asks for T30: no honest T30 exists and the chain must say so
/// rather than report a noise-lengthened value (≈ 20–24 s without compensation). T20 (35 dB
/// needed) is reachable with the estimator's noise compensation in the 1 kHz octave, which holds
/// most of the room's modes (the analytic RIR stops at 1 kHz and the 1 m³ room's modal density
/// grows with f²); the 63–250 Hz octaves hold only a few modes and are noise-limited.
///
/// 500 Hz passes the ISO check but is 3.8 % / 1.5 % off (1.038 s, 1.969 s): the noise
/// realisation, not the bank — on the noise-free RIR every octave is within 0.1 % — and pyrato
/// 1.1.0 itself (Chu + Lundeby on pyfar's octave filters, same script) gives 1.027 s / 1.977 s
/// there, 1.080 s at 125 Hz and 0.970 s at 250 Hz. So 500 Hz is only pinned within 5 %.
/// With `noise_margin_db` 5 the 125 and 250 Hz octaves got numbers, flagged, up to 11 % off:
/// why the ISO margin is the default. Since the leakage test also holds a band's curve at its
/// fit's end against what the other bands leak then (test 4 of `decay::leakage`), the 250 Hz
/// octave, which holds the room's first few modes, is withheld as `leakage`: at −25 dB its
/// curve is within 6 dB of what the 500 Hz and 1 kHz octaves' modes leak into it as tones.
#[test]
fn noisy_rir_t30_noise_limited_t20_at_1_khz_within_3_percent() {
    let text = reference("analytic_rir_psnr50_2D.csv");
    let rows: Vec<Vec<f64>> = text.lines().map(numbers).collect();
    assert_eq!(rows.len(), 2);
    for (x, t60) in rows.iter().zip([1.0, 2.0]) {
        assert_eq!(x.len(), 16384);
        for (band, e) in octave(x, 3000.0, FilterDirection::Reversed, EvaluationRange::T30) {
            assert!(
                e.has(Flag::NoiseLimited) && e.t60_s.is_none(),
                "{} Hz: {:?} {:?}",
                band.nominal_hz,
                e.t60_s,
                e.flags
            );
        }
        let t20 = octave(x, 3000.0, FilterDirection::Reversed, EvaluationRange::T20);
        let (band, e) = t20.iter().find(|(b, _)| b.nominal_hz == 1000.0).unwrap();
        let t = e.t60_s.unwrap_or(f64::NAN);
        assert!(
            rel_err(t, t60) < 0.03,
            "{} Hz T20 = {t} vs {t60}, {:?}",
            band.nominal_hz,
            e.flags
        );
        for (band, e) in t20.iter().filter(|(b, _)| b.nominal_hz <= 250.0) {
            assert!(
                e.has(Flag::NoiseLimited),
                "{} Hz: {:?}",
                band.nominal_hz,
                e.flags
            );
        }
        let (_, e) = t20.iter().find(|(b, _)| b.nominal_hz == 500.0).unwrap();
        let t = e.t60_s.unwrap_or(f64::NAN);
        assert!(rel_err(t, t60) < 0.05, "500 Hz T20 = {t} vs {t60}");
        // A smaller noise margin trades the refusal for flagged, biased numbers.
        let (bands, _) = iec_bands(OctaveFraction::Octave, 63.0, 3000.0).unwrap();
        let mut fe =
            OctaveBankFrontEnd::new(OctaveBankSettings::default(), 3000.0, &bands).unwrap();
        let relaxed = EstimateSettings {
            range: EvaluationRange::T20,
            noise_margin_db: 5.0,
            ..Default::default()
        };
        for (band, e) in bands.iter().zip(analyze_decay(x, &mut fe, &relaxed)) {
            if band.nominal_hz == 250.0 {
                assert!(e.t60_s.is_none() && e.has(Flag::Leakage), "{:?}", e.flags);
            }
            if band.nominal_hz == 125.0 {
                let t = e.t60_s.expect("a number with a 5 dB margin");
                assert!(rel_err(t, t60) < 0.15, "{} Hz: {t}", band.nominal_hz);
                assert!(e.has(Flag::NoiseCompensated) && e.has(Flag::TruncationBias));
            }
        }
    }
}

#[test]
fn bandpass_response_matches_butterworth_at_the_edges() {
    fn gain_at(sections: &[biquad::Coefficients<f64>], f: f64, fs: f64) -> f64 {
        let w = 2.0 * std::f64::consts::PI * f / fs;
        sections.iter().fold(1.0, |g, c| {
            let z1 = rustfft::num_complex::Complex::from_polar(1.0, -w);
            let z2 = z1 * z1;
            g * ((c.b0 + z1 * c.b1 + z2 * c.b2) / (1.0 + z1 * c.a1 + z2 * c.a2)).norm()
        })
    }
    // Analytic: |H| = 1 at the (pre-warped) centre, 1/√2 (−3.01 dB) at both exact edges,
    // ≈ −(order·6 dB per octave of the prototype) far away.
    let (lo, hi) = (707.945_784_384_137_9, 1_412.537_544_622_754);
    for fs in [48_000.0, 3000.0] {
        // fs = 3000 Hz: the upper edge sits near Nyquist, the pre-warped band is very wide and the
        // real prototype pole gives two real band-pass poles; the edges must still be at −3 dB.
        let sections = butterworth_bandpass(3, lo, hi, fs).unwrap();
        let gain = |f: f64| gain_at(&sections, f, fs);
        let centre_warped = fs / std::f64::consts::PI
            * (((std::f64::consts::PI * lo / fs).tan() * (std::f64::consts::PI * hi / fs).tan())
                .sqrt())
            .atan();
        assert!(
            (gain(centre_warped) - 1.0).abs() < 1e-9,
            "{}",
            gain(centre_warped)
        );
        assert!((gain(lo) - 0.5f64.sqrt()).abs() < 1e-9, "{}", gain(lo));
        assert!((gain(hi) - 0.5f64.sqrt()).abs() < 1e-9, "{}", gain(hi));
        // 1.5 octaves below the lower edge: ≥ 30 dB down (48 kHz: −41 dB; 3 kHz, warped: −34 dB).
        assert!(gain(250.0) < 0.03, "{}", gain(250.0));
    }
    let fs = 48_000.0;
    assert!(gain_at(&butterworth_bandpass(3, lo, hi, fs).unwrap(), 4000.0, fs) < 0.01);
    assert!(butterworth_bandpass(3, 0.0, 1000.0, fs).is_err());
    assert!(butterworth_bandpass(3, 1000.0, 30_000.0, fs).is_err());
}

#[test]
fn third_octave_reversed_is_exact_where_forward_is_biased() {
    // METHODS §1.1 STFT table, 1/3-octave columns: 100 Hz, ζ = 3 %, T60 0.366 s (B·T60 ≈ 8.5):
    // forward 0.370 s (+1 %), reversed 0.367 s.
    let fs = 4000.0;
    let x = decaying_sines(&[(100.0, 0.03, 1.0, 0.0)], fs, 3.0);
    let (bands, _) = iec_bands(OctaveFraction::Third, 100.0, fs).unwrap();
    let band = bands[0];
    let truth = 1.0994 / (100.0 * 0.03);
    let run = |direction| {
        let s = OctaveBankSettings {
            direction,
            frame_period_ms: 1.0,
            ..Default::default()
        };
        let mut fe = OctaveBankFrontEnd::new(s, fs, &[band]).unwrap();
        let settings = EstimateSettings {
            range: EvaluationRange::T20,
            ..Default::default()
        };
        assert_eq!(fe.name(), "octave");
        analyze_decay(&x, &mut fe, &settings)
            .remove(0)
            .t60_s
            .unwrap()
    };
    let rev = run(FilterDirection::Reversed);
    let fwd = run(FilterDirection::Forward);
    assert!(rel_err(rev, truth) < 0.005, "reversed {rev} vs {truth}");
    assert!(
        fwd / truth - 1.0 > 0.005,
        "forward {fwd} should be biased upward vs {truth}"
    );
}

//! Synthetic decays against eq. 4.5 written independently, noise level vs requested SNR,
//! block-size independence.

use dampscope::source::{synthesize, Block, Mode, Source, SynthSource, SynthSpec};

fn spec(modes: &[(f64, f64, f64, f64)], fs: f64, seconds: f64, snr_db: Option<f64>) -> SynthSpec {
    SynthSpec {
        modes: modes
            .iter()
            .map(|&(f, d, a, p)| Mode {
                frequency_hz: f,
                damping_ratio: d,
                amplitude: a,
                phase_deg: p,
            })
            .collect(),
        sample_rate_hz: fs,
        duration_s: seconds,
        snr_db,
        seed: 1,
    }
}

/// Eq. 4.5 as the imaginary part of a complex exponential: A·Im(exp((−D + i)·ωt − iψ)).
fn oracle(modes: &[(f64, f64, f64, f64)], t: f64) -> f64 {
    modes
        .iter()
        .map(|&(f, d, a, psi)| {
            let w = 2.0 * std::f64::consts::PI * f;
            let re = -d * w * t;
            let im = w * t - psi * std::f64::consts::PI / 180.0;
            a * re.exp() * im.sin()
        })
        .sum()
}

#[test]
fn matches_eq_4_5() {
    let modes = [
        (170.0, 0.025, 1.0, 0.0),
        (200.0, 0.025, 0.5, 30.0),
        (230.0, 0.01, 2.0, -90.0),
    ];
    let x = synthesize(&spec(&modes, 4000.0, 1.5, None));
    assert_eq!(x.len(), 6000);
    for (n, &v) in x.iter().enumerate() {
        let t = n as f64 / 4000.0;
        assert!((v - oracle(&modes, t)).abs() < 1e-12, "sample {n}");
    }
    // Hand-checked values of a 100 Hz mode, A = 3, ψ = 90°, sampled at 400 Hz (quarter periods):
    // t = 0: 3·sin(−π/2) = −3; t = T/4: sin(0) = 0; t = T/2: 3·e^(−D·π)·sin(π/2).
    let x = synthesize(&spec(&[(100.0, 0.02, 3.0, 90.0)], 400.0, 0.01, None));
    assert!((x[0] + 3.0).abs() < 1e-15);
    assert!(x[1].abs() < 1e-12);
    assert!((x[2] - 3.0 * (-0.02 * std::f64::consts::PI).exp()).abs() < 1e-12);
}

#[test]
fn mode_parsing() {
    let m: Mode = "230:0.025:1:45".parse().unwrap();
    assert_eq!(
        (m.frequency_hz, m.damping_ratio, m.amplitude, m.phase_deg),
        (230.0, 0.025, 1.0, 45.0)
    );
    let m: Mode = "55:0.01".parse().unwrap();
    assert_eq!((m.amplitude, m.phase_deg), (1.0, 0.0));
    for bad in [
        "55",
        "55:x",
        "-1:0.1",
        "55:-0.1",
        "55:0.1:1:2:3",
        "nan:0.1",
        "",
    ] {
        assert!(bad.parse::<Mode>().is_err(), "{bad}");
    }
    assert!(SynthSource::new(spec(&[], 1000.0, 1.0, None)).is_err());
    assert!(SynthSource::new(spec(&[(10.0, 0.1, 1.0, 0.0)], 0.0, 1.0, None)).is_err());
    assert!(SynthSource::new(spec(&[(10.0, 0.1, 1.0, 0.0)], 1000.0, 1e-5, None)).is_err());
}

#[test]
fn peak_is_the_exact_maximum() {
    let cases = [
        spec(&[(55.0, 0.025, 1.0, 0.0)], 4000.0, 4.0, None),
        spec(
            &[(56.84, 0.005, 1.0, 0.0), (57.51, 0.005, 1.0, 120.0)],
            4000.0,
            4.0,
            None,
        ),
        spec(
            &[(3.0, 0.0, 1.0, 0.0), (300.0, 0.05, -2.0, 10.0)],
            1000.0,
            2.0,
            None,
        ),
    ];
    for s in cases {
        let brute = synthesize(&s).iter().fold(0f64, |m, v| m.max(v.abs()));
        assert_eq!(s.peak(), brute);
    }
}

#[test]
fn noise_matches_requested_psnr() {
    for (snr, seed) in [(20.0, 1), (50.0, 2), (80.0, 3)] {
        let clean_spec = spec(
            &[(200.0, 0.025, 1.0, 0.0), (230.0, 0.025, 0.7, 0.0)],
            4000.0,
            4.0,
            None,
        );
        let noisy_spec = SynthSpec {
            snr_db: Some(snr),
            seed,
            ..clean_spec.clone()
        };
        let clean = synthesize(&clean_spec);
        let noisy = synthesize(&noisy_spec);
        let peak = clean.iter().fold(0f64, |m, v| m.max(v.abs()));
        let rms = (clean
            .iter()
            .zip(&noisy)
            .map(|(c, n)| (n - c).powi(2))
            .sum::<f64>()
            / clean.len() as f64)
            .sqrt();
        let measured = 20.0 * (peak / rms).log10();
        assert!(
            (measured - snr).abs() < 0.5,
            "requested {snr} dB, measured {measured} dB"
        );
        // Same seed → same noise; another seed → other noise.
        assert_eq!(noisy, synthesize(&noisy_spec));
        assert_ne!(
            noisy,
            synthesize(&SynthSpec {
                seed: seed + 10,
                ..noisy_spec
            })
        );
    }
}

#[test]
fn block_sizes_give_identical_samples() {
    let s = spec(
        &[(55.0, 0.025, 1.0, 0.0), (120.0, 0.01, 0.3, 45.0)],
        4000.0,
        1.0,
        Some(40.0),
    );
    let whole = synthesize(&s);
    for block in [1, 3, 1000, 4000, 100_000] {
        let mut src = SynthSource::new(s.clone()).unwrap();
        let mut got = Vec::new();
        let mut b = Block::default();
        while src.read_block(block, &mut b).unwrap() {
            assert!(b.frames() <= block);
            got.extend_from_slice(&b.channels[0]);
        }
        assert_eq!(got, whole, "block {block}");
    }
}

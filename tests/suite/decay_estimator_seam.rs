//! The `DecayEstimator` seam: the whole per-decay chain (front end, per-band estimators, the
//! cross-band tests) run with the online estimator and with the plain offline oracle
//! ([`BatchSchroeder`]) gives the same estimates, flags included, for every front end.

use dampscope::decay::estimate::EstimateSettings;
use dampscope::decay::oracle::BatchSchroeder;
use dampscope::decay::EvaluationRange;
use dampscope::frontend::Band;
use dampscope::pipeline::{analyze_decay, analyze_decay_with};
use dampscope::plan::{FrontEndKind, FrontEndSpec};
use dampscope::source::synth::{synthesize, Mode, SynthSpec};

fn close(a: Option<f64>, b: Option<f64>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => (a - b).abs() <= 1e-9 * a.abs().max(b.abs()),
        (None, None) => true,
        _ => false,
    }
}

#[test]
fn online_and_oracle_estimators_agree_through_the_chain() {
    let fs = 4000.0;
    // Beating modes, a weak band and noise: every test across bands gets something to do.
    let x = synthesize(&SynthSpec {
        modes: vec![
            Mode::new(120.0, 0.01, 1.0, 0.0),
            Mode::new(123.0, 0.01, 0.7, 40.0),
            Mode::new(300.0, 0.004, 0.05, 0.0),
        ],
        sample_rate_hz: fs,
        duration_s: 3.0,
        snr_db: Some(60.0),
        seed: 3,
    });
    let bands = [
        Band::new(100.0, 150.0).unwrap(),
        Band::new(280.0, 320.0).unwrap(),
        Band::new(600.0, 700.0).unwrap(),
    ];
    for range in [
        EvaluationRange::T20,
        EvaluationRange::T30,
        EvaluationRange::Edt,
    ] {
        let settings = EstimateSettings {
            range,
            ..Default::default()
        };
        for kind in FrontEndKind::ALL {
            let spec = FrontEndSpec::default().with_kind(kind);
            let mut fe = spec.build(fs, &bands).unwrap();
            let online = analyze_decay(&x, fe.as_mut(), &settings);
            let oracle = analyze_decay_with(&x, fe.as_mut(), |band, period| {
                BatchSchroeder::new(period, band.center_hz, settings)
            });
            let mut numbers = 0;
            for (a, b) in online.iter().zip(&oracle) {
                assert_eq!(a.flags, b.flags, "{} {range}", kind.name());
                for (p, q) in [
                    (a.t60_s, b.t60_s),
                    (a.edt_s, b.edt_s),
                    (a.t20_s, b.t20_s),
                    (a.t30_s, b.t30_s),
                    (a.damping_ratio, b.damping_ratio),
                    (a.damping_ratio_corrected, b.damping_ratio_corrected),
                ] {
                    assert!(close(p, q), "{} {range}: {p:?} vs {q:?}", kind.name());
                }
                numbers += usize::from(a.damping_ratio.is_some());
            }
            // EDT (0 … −10 dB) needs finer frames than the STFT's 100 ms on these decays.
            if range != EvaluationRange::Edt {
                assert!(numbers >= 1, "{} {range}: no band estimated", kind.name());
            }
        }
    }
}

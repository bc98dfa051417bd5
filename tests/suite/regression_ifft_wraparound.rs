//! Found on the simulated reference plate: impulse responses made by inverse FFT rise again in
//! their last samples (the wrap-around of the circular convolution). After the real decay had
//! ended, that tail re-triggered a second "decay" too short for a single frame, which produced a
//! row of `no_energy` per band. Such fragments are not decays and are dropped.

use dampscope::frontend::bands::Band;
use dampscope::frontend::stft::{StftFrontEnd, StftSettings};
use dampscope::pipeline::{AnalysisConfig, ChannelAnalyzer};

#[test]
fn a_blip_at_the_very_end_is_not_a_second_decay() {
    let fs = 4000.0;
    let n = 16000;
    let w = 2.0 * std::f64::consts::PI * 55.0;
    let mut x: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            (-(0.025 * w) * t).exp() * (w * t).sin()
        })
        .collect();
    // The wrap-around: a short rise in the last 40 samples, well above the retrigger level.
    for (k, v) in x[n - 40..].iter_mut().enumerate() {
        *v = 0.5 * (k as f64 / 40.0) * (w * k as f64 / fs).cos();
    }
    let fe = StftFrontEnd::new(
        StftSettings::default(),
        fs,
        &[Band::new(52.5, 57.5).unwrap()],
    )
    .unwrap();
    let mut an = ChannelAnalyzer::new("c".into(), fs, Box::new(fe), AnalysisConfig::default());
    let mut rows = Vec::new();
    an.push(&x, &mut rows);
    an.finish(false, &mut rows);
    assert_eq!(rows.len(), 1, "{rows:?}");
    assert!(rows[0].estimate.damping_ratio.is_some());
    assert_eq!(an.fragments(), 1);
}

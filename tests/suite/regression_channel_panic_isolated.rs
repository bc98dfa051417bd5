//! Found while probing `map` with a band above Nyquist: the STFT sliced past its spectrum, the
//! worker thread panicked, and the run ended "successfully" with the rows of every channel of
//! that worker silently missing. A panic in one channel's analysis now stops that channel only:
//! its rows carry `internal_error`, the summary names it, and the other channels are analysed.

use std::sync::Arc;

use crate::common::decaying_sines;
use dampscope::decay::Flag;
use dampscope::frontend::stft::{StftFrontEnd, StftSettings};
use dampscope::frontend::{Band, FrameSink, FrontEnd, Resolution};
use dampscope::pipeline::{run, AnalysisConfig, FrontEndFactory};
use dampscope::source::memory::MemorySource;
use dampscope::source::SignalInfo;

/// An STFT that panics when it meets the sample value 123 (a stand-in for any bug).
struct Booby(StftFrontEnd);

impl FrontEnd for Booby {
    fn bands(&self) -> &[Band] {
        self.0.bands()
    }
    fn resolution(&self) -> Resolution {
        self.0.resolution()
    }
    fn process(&mut self, samples: &[f64], sink: &mut dyn FrameSink) {
        assert!(!samples.contains(&123.0), "planted bug");
        self.0.process(samples, sink)
    }
    fn finish(&mut self, sink: &mut dyn FrameSink) {
        self.0.finish(sink)
    }
    fn reset(&mut self) {
        self.0.reset()
    }
    fn name(&self) -> &'static str {
        "booby"
    }
    fn mode_gain(&self, band: usize, f_hz: f64, sigma_per_s: f64) -> f64 {
        self.0.mode_gain(band, f_hz, sigma_per_s)
    }
}

#[test]
fn a_panicking_channel_is_flagged_and_the_others_go_on() {
    let fs = 2000.0;
    let good = decaying_sines(&[(100.0, 0.01, 1.0, 0.0)], fs, 3.0);
    let mut bad = good.clone();
    bad[3000] = 123.0;
    // Three channels on (at most) two workers: the bad one shares a worker with a good one.
    let names: Vec<String> = ["bad", "good1", "good2"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let info = SignalInfo {
        sample_rate_hz: fs,
        channel_names: names,
    };
    let source = MemorySource::new(info, vec![bad, good.clone(), good]).unwrap();
    let band = Band::new(90.0, 110.0).unwrap();
    let factory: FrontEndFactory = Arc::new(move || {
        Ok(Box::new(Booby(StftFrontEnd::new(
            StftSettings::default(),
            fs,
            &[band],
        )?)) as Box<dyn FrontEnd>)
    });
    let mut rows = Vec::new();
    let summary = run(
        Box::new(source),
        &factory,
        &AnalysisConfig::default(),
        |r| {
            rows.extend_from_slice(r);
            Ok(())
        },
    )
    .unwrap();
    assert_eq!(summary.internal_error_channels, vec!["bad".to_string()]);
    let bad_rows: Vec<_> = rows.iter().filter(|r| r.channel == "bad").collect();
    assert_eq!(bad_rows.len(), 1);
    assert!(bad_rows[0].estimate.has(Flag::InternalError));
    for ch in ["good1", "good2"] {
        let r = rows.iter().find(|r| r.channel == ch).expect(ch);
        let d = r.estimate.damping_ratio.expect("estimated");
        assert!((d - 0.01).abs() < 2e-4, "{ch}: {d}");
    }
}

//! The chain from samples to result rows: per channel, segmentation into decays, the front end,
//! one decay estimator per band; across channels, the threads.
//!
//! - segmentation ([`segment`]), where decays start and end in a stream (onset, new hit, end of decay) and its
//!   settings ([`Segmentation`]);
//! - `channel`: one channel's [`ChannelAnalyzer`], which feeds each decay through its front end
//!   and band estimators; `bands`: one decay's bands together ([`analyze_decay`]);
//! - `threads`: [`run`], reader → workers (channel groups) → rows in stream order;
//! - the result schema ([`schema`]), the [`ResultRow`] each decay, band and channel gives, and the [`RunSummary`].
//!
//! The reader hands each block to every worker over a bounded channel (so memory stays bounded
//! when the analysis is slower than the input). When a decay ends (its band energies fell
//! `end_drop_db` below their peaks, it reached `max_decay_s`, a new hit came, or the input
//! ended) its rows are sent to the caller at once: results appear while the input still arrives.

use std::sync::Arc;

mod bands;
mod block_pool;
mod channel;
mod end_scan;
mod finishing;
mod order;
pub mod schema;
pub mod segment;
mod thread_heap;
mod threads;

pub use bands::{analyze_decay, analyze_decay_with};
pub use channel::ChannelAnalyzer;
pub use schema::{ResultRow, RunSummary, StageTimes};
pub use segment::Segmentation;
pub use threads::{run, run_with, RunOptions};

use crate::decay::estimate::EstimateSettings;
use crate::error::Result;
use crate::frontend::FrontEnd;

/// Builds one front end per channel (front ends are stateful).
pub type FrontEndFactory = Arc<dyn Fn() -> Result<Box<dyn FrontEnd>> + Send + Sync>;

/// How decays are found in a stream and estimated.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AnalysisConfig {
    /// Fit range, minimum points, curvature limit.
    pub estimate: EstimateSettings,
    /// Where decays start and end.
    pub segmentation: Segmentation,
    /// Sample frames per block read from the source.
    pub block_frames: usize,
    /// τ of an exponential window the responses carry (applied to FRF input, or declared by
    /// the recording set), s: its damping is removed from every estimate
    /// ([`crate::decay::damping::remove_exponential_window`]). `None`: no window.
    pub exponential_window_tau_s: Option<f64>,
    /// Step between the input's sample values, in its sample units (integer WAV: one count;
    /// [`crate::source::Source::quantization_step`]); `None` for float input. Its rounding
    /// noise, step² / 12 per sample, is a floor every band's range must clear
    /// ([`crate::decay::quantization`]).
    #[serde(default)]
    pub quantization_step: Option<f64>,
}

/// Default of [`AnalysisConfig::block_frames`].
pub const DEFAULT_BLOCK_FRAMES: usize = 4096;

/// Blocks hold at least this many of the front end's look-ahead spans
/// ([`FrontEnd::lookahead_samples`]): a frame completed in a block finds the samples of the next
/// one in it unless it ends in the last span. The STFT pairs frames this way; at 65536 Hz
/// (frames of 13107 samples, hop 6554) the default block held less than a hop, and no frame
/// was ever paired: 64 ch × 10 s 242 → 139 ms whole process with 4 spans, 146 with 8 (a
/// larger block leaves the cache), resident memory 47 → 68 MB.
pub const LOOKAHEAD_BLOCK_SPANS: usize = 4;

/// Sample frames per block for `front_end`: `configured`, or more where the front end looks
/// further ahead ([`LOOKAHEAD_BLOCK_SPANS`]).
pub fn block_frames_for(configured: usize, front_end: &dyn FrontEnd) -> usize {
    configured
        .max(LOOKAHEAD_BLOCK_SPANS.saturating_mul(front_end.lookahead_samples()))
        .max(1)
}

impl Default for AnalysisConfig {
    fn default() -> Self {
        AnalysisConfig {
            estimate: EstimateSettings::default(),
            segmentation: Segmentation::default(),
            block_frames: DEFAULT_BLOCK_FRAMES,
            exponential_window_tau_s: None,
            quantization_step: None,
        }
    }
}

impl AnalysisConfig {
    /// Checks every setting; an error names the field.
    pub fn validate(&self) -> Result<()> {
        self.estimate.validate()?;
        if let Some(t) = self.exponential_window_tau_s {
            if !(t.is_finite() && t > 0.0) {
                return Err(crate::error::Error::setting(
                    "exponential_window_tau_s",
                    format!("expected a finite τ > 0 s, got {t}"),
                ));
            }
        }
        if let Some(step) = self.quantization_step {
            if !(step.is_finite() && step > 0.0) {
                return Err(crate::error::Error::setting(
                    "quantization_step",
                    format!("expected a finite step > 0, got {step}"),
                ));
            }
        }
        self.segmentation.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frontend::octave_bank::{OctaveBankFrontEnd, OctaveBankSettings};
    use crate::frontend::stft::{StftFrontEnd, StftSettings};
    use crate::frontend::Band;

    /// Blocks grow to four hops where the STFT pairs frames and a hop is long (13107-sample
    /// frames at 65536 Hz, hop 6554: the default block held no pair), and stay as configured
    /// where the default already holds ten hops (4096 Hz), where frames are not paired (the
    /// even 9600-sample frames at 48 kHz) and for a front end that does not look ahead.
    #[test]
    fn blocks_hold_four_lookahead_spans() {
        let bands = [Band::new(700.0, 1400.0).unwrap()];
        let stft = |fs: f64| StftFrontEnd::new(StftSettings::default(), fs, &bands).unwrap();
        let at_65536 = stft(65536.0);
        assert_eq!(at_65536.lookahead_samples(), 6554);
        assert_eq!(block_frames_for(DEFAULT_BLOCK_FRAMES, &at_65536), 4 * 6554);
        assert_eq!(stft(4096.0).lookahead_samples(), 410);
        assert_eq!(block_frames_for(DEFAULT_BLOCK_FRAMES, &stft(4096.0)), 4096);
        assert_eq!(stft(48000.0).lookahead_samples(), 0);
        assert_eq!(block_frames_for(DEFAULT_BLOCK_FRAMES, &stft(48000.0)), 4096);
        let bank = OctaveBankFrontEnd::new(OctaveBankSettings::default(), 65536.0, &bands).unwrap();
        assert_eq!(block_frames_for(DEFAULT_BLOCK_FRAMES, &bank), 4096);
        // A larger configured block is kept; zero is one frame.
        assert_eq!(block_frames_for(50_000, &at_65536), 50_000);
        assert_eq!(block_frames_for(0, &bank), 1);
    }

    /// What a run asked of its source: the most frames per read, and the bytes it allowed.
    #[derive(Default)]
    struct Asked {
        frames: usize,
        allowed: Option<usize>,
    }

    /// A source in memory that notes what it was asked.
    struct Noting {
        inner: crate::source::memory::MemorySource,
        asked: Arc<std::sync::Mutex<Asked>>,
    }

    impl crate::source::Source for Noting {
        fn info(&self) -> &crate::source::SignalInfo {
            self.inner.info()
        }
        fn read_block(
            &mut self,
            max_frames: usize,
            block: &mut crate::source::Block,
        ) -> std::result::Result<bool, crate::source::SourceError> {
            let mut asked = self.asked.lock().unwrap();
            asked.frames = asked.frames.max(max_frames);
            self.inner.read_block(max_frames, block)
        }
        fn allow_block_bytes(&mut self, bytes: usize) {
            self.asked.lock().unwrap().allowed = Some(bytes);
        }
    }

    /// A run reads the blocks its front end wants and lets the source return them: at 65536
    /// Hz four hops (26216 frames, 8 bytes per sample of its 3 channels allowed), at 4096 Hz
    /// the default block, the source's cap left alone.
    #[test]
    fn a_run_asks_its_source_for_the_blocks_its_front_end_wants() {
        for (fs, frames, allowed) in [
            (65536.0, 4 * 6554, Some(4 * 6554 * 3 * 8)),
            (4096.0, DEFAULT_BLOCK_FRAMES, None),
        ] {
            let info = crate::source::SignalInfo {
                sample_rate_hz: fs,
                channel_names: vec!["a".into(), "b".into(), "c".into()],
            };
            let x: Vec<f64> = (0..(fs as usize) / 2)
                .map(|i| (-(i as f64) / fs * 20.0).exp() * (0.3 * i as f64).sin())
                .collect();
            let inner =
                crate::source::memory::MemorySource::new(info, vec![x.clone(), x.clone(), x])
                    .unwrap();
            let asked = Arc::new(std::sync::Mutex::new(Asked::default()));
            let source = Noting {
                inner,
                asked: asked.clone(),
            };
            let bands = [Band::new(700.0, 1400.0).unwrap()];
            let factory: FrontEndFactory = Arc::new(move || {
                Ok(
                    Box::new(StftFrontEnd::new(StftSettings::default(), fs, &bands)?)
                        as Box<dyn FrontEnd>,
                )
            });
            run(
                Box::new(source),
                &factory,
                &AnalysisConfig::default(),
                |_| Ok(()),
            )
            .unwrap();
            let asked = asked.lock().unwrap();
            assert_eq!((asked.frames, asked.allowed), (frames, allowed), "{fs} Hz");
        }
    }
}

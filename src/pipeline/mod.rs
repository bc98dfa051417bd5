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
}

/// Default of [`AnalysisConfig::block_frames`].
pub const DEFAULT_BLOCK_FRAMES: usize = 4096;

impl Default for AnalysisConfig {
    fn default() -> Self {
        AnalysisConfig {
            estimate: EstimateSettings::default(),
            segmentation: Segmentation::default(),
            block_frames: DEFAULT_BLOCK_FRAMES,
            exponential_window_tau_s: None,
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
        self.segmentation.validate()
    }
}

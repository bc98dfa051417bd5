//! The result schema: one row per decay, band and channel, and what a run saw.

use crate::decay::{DecayEstimate, EvaluationRange};
use crate::frontend::Band;
use crate::source::SourceError;

/// One result: a decay in one band of one channel.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ResultRow {
    /// Channel (sensor id).
    pub channel: String,
    /// Where the row sits in the stream, samples from its start: the decay's onset, or where the
    /// channel failed or ended (rows without a decay). Orders the rows; not written out.
    #[serde(skip)]
    pub position_sample: u64,
    /// Index of the decay within the channel's stream, from 0.
    pub decay: usize,
    /// Onset time of the decay from the start of the stream, s (`None` when no decay was found).
    pub onset_s: Option<f64>,
    /// Front end name.
    pub front_end: &'static str,
    /// The band.
    pub band: Band,
    /// The evaluation range that `t60_s` and the damping ratios come from.
    pub range: EvaluationRange,
    /// The estimate.
    pub estimate: DecayEstimate,
}

/// What a run saw.
#[derive(Debug, Default)]
pub struct RunSummary {
    /// Rows produced.
    pub rows: usize,
    /// Channels whose samples contained NaN or infinity.
    pub non_finite_channels: Vec<String>,
    /// The input error that ended the run early, if any (results up to it were delivered).
    pub input_error: Option<SourceError>,
    /// Channels stopped by an internal error (a bug), flagged `internal_error`; the other
    /// channels went on.
    pub internal_error_channels: Vec<String>,
    /// Where the time went, summed over threads ([`StageTimes`]).
    pub stages: StageTimes,
    /// Worker threads the channels were spread over.
    pub threads: usize,
}

/// Thread time per stage of a run, s, summed over the threads that did it.
///
/// `read_s` (the reader thread in its source) and `output_s` (the caller's row sink) are always
/// measured, once per block or batch of rows. The analysis itself is measured per block and
/// channel (`analysis_s`); its split into segmentation, front end and estimator needs a clock per
/// frame and is only made when asked for ([`super::RunOptions::profile_stages`]), otherwise
/// those three are zero.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct StageTimes {
    /// Decoding the input into blocks.
    pub read_s: f64,
    /// The whole per-channel analysis (segmentation + front end + estimator).
    pub analysis_s: f64,
    /// Onset search and new-hit watch (profiled runs only).
    pub segment_s: f64,
    /// The front end: STFT or filter bank (profiled runs only).
    pub front_end_s: f64,
    /// The band estimators: Schroeder integral, fits, judgement (profiled runs only).
    pub estimator_s: f64,
    /// The caller's sink of result rows.
    pub output_s: f64,
}

impl StageTimes {
    /// Adds another thread's (or run's) times.
    pub fn add(&mut self, other: &StageTimes) {
        self.read_s += other.read_s;
        self.analysis_s += other.analysis_s;
        self.segment_s += other.segment_s;
        self.front_end_s += other.front_end_s;
        self.estimator_s += other.estimator_s;
        self.output_s += other.output_s;
    }

    /// All stages together, s.
    pub fn total_s(&self) -> f64 {
        self.read_s + self.analysis_s + self.output_s
    }
}

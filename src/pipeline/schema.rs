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
}

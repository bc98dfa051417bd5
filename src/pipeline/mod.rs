//! Threads and channels: reader → workers (channel groups) → results.
//!
//! The reader thread pulls blocks from the [`Source`] and hands each block to every worker over a
//! bounded channel (so memory stays bounded when the analysis is slower than the input). Each
//! worker owns the [`ChannelAnalyzer`]s of its channels; an analyzer detects decay onsets, feeds
//! the front end, and keeps one online Schroeder estimator per band. When a decay ends (its band
//! energies fell `end_drop_db` below their peaks, it reached `max_decay_s`, or the input ended)
//! its rows are sent to the caller at once: results appear while the input still arrives.

use std::sync::Arc;

use crossbeam_channel::{bounded, Receiver, Sender};

mod bands;
mod channel;
mod order;

use order::RowOrder;

pub use bands::analyze_decay;
pub use channel::ChannelAnalyzer;

use crate::decay::estimate::EstimateSettings;
use crate::decay::{DecayEstimate, EvaluationRange, Flag};
use crate::error::{Error, Result};
use crate::frontend::{Band, FrontEnd};
use crate::source::{Block, Source, SourceError};

/// Builds one front end per channel (front ends are stateful).
pub type FrontEndFactory = Arc<dyn Fn() -> Result<Box<dyn FrontEnd>> + Send + Sync>;

/// How decays are found in a stream and estimated.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AnalysisConfig {
    /// Fit range, minimum points, curvature limit.
    pub estimate: EstimateSettings,
    /// Onset: first sample within this many dB of the peak (20 by default).
    pub onset_level_db: f64,
    /// Onset: the peak is settled after this long without a larger sample, s (0.1 by default).
    pub onset_lookahead_s: f64,
    /// A decay ends after this long, s (`None`: at the end of the input, or by `end_drop_db`).
    pub max_decay_s: Option<f64>,
    /// A decay ends when every band's energy is this far below its peak, dB (100 by default).
    pub end_drop_db: f64,
    /// After a decay, a new one starts at a sample within this many dB of the last peak (20).
    pub retrigger_db: f64,
    /// During a decay, a sample that high and this many dB above the preceding signal (before
    /// its rise) is a new hit: the decay ends there and a new one starts
    /// ([`DEFAULT_RETRIGGER_JUMP_DB`]; infinity never splits).
    #[serde(default = "default_retrigger_jump_db")]
    pub retrigger_jump_db: f64,
    /// Sample frames per block read from the source.
    pub block_frames: usize,
}

/// Default of [`AnalysisConfig::onset_level_db`]: a decay starts at its first sample within
/// 20 dB of its peak.
pub const DEFAULT_ONSET_LEVEL_DB: f64 = 20.0;

/// Default of [`AnalysisConfig::end_drop_db`]: a decay ends once every band fell 100 dB.
pub const DEFAULT_END_DROP_DB: f64 = 100.0;

/// Default of [`AnalysisConfig::retrigger_db`]: a new decay starts within 20 dB of the last peak.
pub const DEFAULT_RETRIGGER_DB: f64 = 20.0;

/// Default of [`AnalysisConfig::retrigger_jump_db`]: 10 dB. A decaying sum of modes cannot rise
/// that fast whatever its beating (see [`crate::frontend::onset::RetriggerWatch`]), and white
/// noise would need a 12σ sample; hits 4 s apart over a −60 dB floor, merged before, are split.
pub const DEFAULT_RETRIGGER_JUMP_DB: f64 = 10.0;

/// Lowest frequency whose rise time (a quarter period) sets the new-hit test's gap, Hz.
pub(crate) const RETRIGGER_MIN_FREQUENCY_HZ: f64 = 5.0;

fn default_retrigger_jump_db() -> f64 {
    DEFAULT_RETRIGGER_JUMP_DB
}

impl Default for AnalysisConfig {
    fn default() -> Self {
        AnalysisConfig {
            estimate: EstimateSettings::default(),
            onset_level_db: DEFAULT_ONSET_LEVEL_DB,
            onset_lookahead_s: 0.1,
            max_decay_s: None,
            end_drop_db: DEFAULT_END_DROP_DB,
            retrigger_db: DEFAULT_RETRIGGER_DB,
            retrigger_jump_db: DEFAULT_RETRIGGER_JUMP_DB,
            block_frames: 4096,
        }
    }
}

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

/// What a worker hands back after each block: finished rows per channel (index into the
/// input's channels) and each of its channels' watermark ([`ChannelAnalyzer::watermark`]).
struct WorkerReport {
    rows: Vec<(usize, Vec<ResultRow>)>,
    watermarks: Vec<(usize, u64)>,
}

/// Blocks alive at once at most: each worker's queue (4), the one it works on, the one read.
const BLOCKS_IN_FLIGHT: f64 = 6.0;

enum ToWorker {
    Block(Arc<Block>),
    End { truncated: bool },
}

/// Runs the whole analysis of `source`, calling `on_rows` with each batch of finished rows as soon
/// as it is ready. Errors from `on_rows` stop the run.
pub fn run(
    mut source: Box<dyn Source>,
    factory: &FrontEndFactory,
    config: &AnalysisConfig,
    mut on_rows: impl FnMut(&[ResultRow]) -> Result<()>,
) -> Result<RunSummary> {
    let info = source.info().clone();
    let n_channels = info.channels();
    if n_channels == 0 {
        return Err(Error::setting("input", "no channels"));
    }
    crate::source::check_unique_names("input", &info.channel_names)?;
    let workers = n_channels.min(
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1),
    );
    let block_frames = config.block_frames.max(1);
    // Memory, before anything proportional to the channel count is allocated: one front end
    // tells its size, the analyzers' buffers are known, and blocks are shared by the workers.
    let first = factory()?;
    // A decay's frame history: the input's length when known, capped by the longest decay.
    let decay_s = source
        .duration_frames()
        .map_or(f64::INFINITY, |n| n as f64 / info.sample_rate_hz)
        .min(config.max_decay_s.unwrap_or(f64::INFINITY));
    let history_frames = if decay_s.is_finite() {
        decay_s / first.resolution().frame_period_s
    } else {
        0.0 // a stream of unknown length: the envelopes grow with it (docs/FORMATS.md §2)
    };
    let per_channel = first.memory_bytes() as f64
        + ChannelAnalyzer::buffer_bytes(
            info.sample_rate_hz,
            first.bands().len(),
            history_frames,
            config,
        );
    let blocks = BLOCKS_IN_FLIGHT * block_frames as f64 * n_channels as f64 * 8.0;
    crate::budget::check(
        &format!("the analysis of {n_channels} channels"),
        per_channel * n_channels as f64 + blocks,
    )?;
    let mut first = Some(first);
    let mut groups: Vec<Vec<(usize, ChannelAnalyzer)>> = (0..workers).map(|_| Vec::new()).collect();
    for (c, name) in info.channel_names.iter().enumerate() {
        let fe = match first.take() {
            Some(fe) => fe,
            None => factory()?,
        };
        let an = ChannelAnalyzer::new(name.clone(), info.sample_rate_hz, fe, *config);
        groups[c % workers].push((c, an));
    }
    let (row_tx, row_rx) = bounded::<WorkerReport>(64);
    std::thread::scope(|scope| -> Result<RunSummary> {
        let mut worker_txs: Vec<Sender<ToWorker>> = Vec::new();
        let mut handles = Vec::new();
        for group in groups {
            let (tx, rx) = bounded::<ToWorker>(4);
            worker_txs.push(tx);
            let row_tx = row_tx.clone();
            handles.push(scope.spawn(move || worker(group, rx, row_tx)));
        }
        drop(row_tx);
        let reader = scope.spawn(move || -> Option<SourceError> {
            let mut failure = None;
            loop {
                let mut block = Block::default();
                match source.read_block(block_frames, &mut block) {
                    Ok(true) => {
                        let b = Arc::new(block);
                        if worker_txs
                            .iter()
                            .any(|tx| tx.send(ToWorker::Block(b.clone())).is_err())
                        {
                            break;
                        }
                    }
                    Ok(false) => break,
                    Err(e) => {
                        failure = Some(e);
                        break;
                    }
                }
            }
            // An input without a single sample frame is an error, not a run of empty rows:
            // the workers stop without finishing their channels.
            if !matches!(failure, Some(SourceError::Empty { .. })) {
                let truncated = failure.is_some();
                for tx in &worker_txs {
                    let _ = tx.send(ToWorker::End { truncated });
                }
            }
            failure
        });
        let mut summary = RunSummary::default();
        let mut result = Ok(());
        let mut order = RowOrder::new(n_channels);
        let mut deliver = |rows: Vec<ResultRow>, summary: &mut RunSummary| {
            if rows.is_empty() {
                return;
            }
            summary.rows += rows.len();
            for r in &rows {
                if r.estimate.has(Flag::NonFiniteInput)
                    && !summary.non_finite_channels.contains(&r.channel)
                {
                    summary.non_finite_channels.push(r.channel.clone());
                }
                if r.estimate.has(Flag::InternalError)
                    && !summary.internal_error_channels.contains(&r.channel)
                {
                    summary.internal_error_channels.push(r.channel.clone());
                }
            }
            if result.is_ok() {
                result = on_rows(&rows);
            }
        };
        for report in row_rx.iter() {
            for (c, rows) in report.rows {
                order.add(c, rows);
            }
            for (c, w) in report.watermarks {
                order.advance(c, w);
            }
            deliver(order.release(), &mut summary);
        }
        deliver(order.drain(), &mut summary);
        summary.input_error = reader.join().unwrap_or(None);
        if let Some(SourceError::Empty { .. }) = summary.input_error {
            for h in handles {
                let _ = h.join();
            }
            return Err(summary
                .input_error
                .take()
                .map(Error::from)
                .unwrap_or_else(|| Error::setting("input", "no samples")));
        }
        for h in handles {
            let _ = h.join();
        }
        result.map(|_| summary)
    })
}

fn worker(
    mut group: Vec<(usize, ChannelAnalyzer)>,
    rx: Receiver<ToWorker>,
    row_tx: Sender<WorkerReport>,
) {
    use std::panic::{catch_unwind, AssertUnwindSafe};
    // A panic in one channel's analysis (a bug) stops that channel only: its rows say
    // `internal_error` and the channels sharing this worker go on.
    let mut crashed = vec![false; group.len()];
    let mut guarded = |i: usize,
                       an: &mut ChannelAnalyzer,
                       f: &dyn Fn(&mut ChannelAnalyzer, &mut Vec<ResultRow>)|
     -> Vec<ResultRow> {
        if crashed[i] {
            return Vec::new();
        }
        let mut local = Vec::new();
        if catch_unwind(AssertUnwindSafe(|| f(an, &mut local))).is_ok() {
            local
        } else {
            crashed[i] = true;
            an.fail_with(Flag::InternalError)
        }
    };
    for msg in rx.iter() {
        let mut report = WorkerReport {
            rows: Vec::new(),
            watermarks: Vec::with_capacity(group.len()),
        };
        for (i, (c, an)) in group.iter_mut().enumerate() {
            let rows = match &msg {
                ToWorker::Block(block) => match block.channels.get(*c) {
                    Some(samples) => guarded(i, an, &|an, o| an.push(samples, o)),
                    None => Vec::new(),
                },
                ToWorker::End { truncated } => {
                    let t = *truncated;
                    let rows = guarded(i, an, &|an, o| an.finish(t, o));
                    // Finished (or crashed): nothing more comes from this channel.
                    report.watermarks.push((*c, u64::MAX));
                    if !rows.is_empty() {
                        report.rows.push((*c, rows));
                    }
                    continue;
                }
            };
            if !rows.is_empty() {
                report.rows.push((*c, rows));
            }
            report.watermarks.push((*c, an.watermark()));
        }
        if row_tx.send(report).is_err() {
            return;
        }
    }
}

//! The threads of a run: a reader hands each block to every worker over bounded channels; each
//! worker owns the [`ChannelAnalyzer`]s of its channels (a panic in one channel stops that
//! channel only); finished rows come back in stream order ([`super::order::RowOrder`]).

use std::sync::Arc;

use crossbeam_channel::{bounded, Receiver, Sender};

use super::order::RowOrder;
use super::schema::StageTimes;
use super::{AnalysisConfig, ChannelAnalyzer, FrontEndFactory, ResultRow, RunSummary};
use crate::decay::Flag;
use crate::error::{Error, Result};
use crate::source::{Block, Source, SourceError};

/// What a worker hands back after each block: finished rows per channel (index into the
/// input's channels) and each of its channels' watermark ([`ChannelAnalyzer::watermark`]).
struct WorkerReport {
    rows: Vec<(usize, Vec<ResultRow>)>,
    watermarks: Vec<(usize, u64)>,
    /// The worker's time on this block (analysis; with its split once its channels finished).
    times: StageTimes,
}

/// How a run uses the machine; the results do not depend on it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunOptions {
    /// Worker threads (None: one per available core); never more than the channels.
    pub threads: Option<usize>,
    /// Split the analysis time into segmentation, front end and estimator
    /// ([`StageTimes`]; costs a clock read per frame).
    pub profile_stages: bool,
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
    source: Box<dyn Source>,
    factory: &FrontEndFactory,
    config: &AnalysisConfig,
    on_rows: impl FnMut(&[ResultRow]) -> Result<()>,
) -> Result<RunSummary> {
    run_with(source, factory, config, RunOptions::default(), on_rows)
}

/// [`run`] with a chosen number of worker threads and, if asked, the analysis time split by stage.
pub fn run_with(
    mut source: Box<dyn Source>,
    factory: &FrontEndFactory,
    config: &AnalysisConfig,
    options: RunOptions,
    mut on_rows: impl FnMut(&[ResultRow]) -> Result<()>,
) -> Result<RunSummary> {
    let info = source.info().clone();
    let n_channels = info.channels();
    if n_channels == 0 {
        return Err(Error::setting("input", "no channels"));
    }
    crate::source::check_unique_names("input", &info.channel_names)?;
    let workers = n_channels.min(
        options
            .threads
            .unwrap_or_else(|| {
                std::thread::available_parallelism()
                    .map(|n| n.get())
                    .unwrap_or(1)
            })
            .max(1),
    );
    let block_frames = config.block_frames.max(1);
    // Memory, before anything proportional to the channel count is allocated: one front end
    // tells its size, the analyzers' buffers are known, and blocks are shared by the workers.
    let first = factory()?;
    // A decay's frame history: the input's length when known, capped by the longest decay.
    let decay_s = source
        .duration_frames()
        .map_or(f64::INFINITY, |n| n as f64 / info.sample_rate_hz)
        .min(config.segmentation.max_decay_s.unwrap_or(f64::INFINITY));
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
        let mut an = ChannelAnalyzer::new(name.clone(), info.sample_rate_hz, fe, *config);
        if options.profile_stages {
            an.profile_stages();
        }
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
        let reader = scope.spawn(move || -> (Option<SourceError>, f64) {
            let mut failure = None;
            let mut read_s = 0.0;
            // Blocks handed out: any one every worker is done with is read into again, so
            // that the hot path allocates nothing once the pipeline is full (a fresh block of
            // a 64-channel stream is megabytes of new pages to fault in).
            let mut pool: Vec<Arc<Block>> = Vec::new();
            loop {
                let mut block = match pool.iter().position(|b| Arc::strong_count(b) == 1) {
                    // Only this thread holds pool handles, so a free block stays free.
                    Some(i) => Arc::try_unwrap(pool.swap_remove(i)).unwrap_or_default(),
                    None => Block::default(),
                };
                // A recycled block's flags belong to its last samples (a source that does not
                // check leaves them empty).
                block.known_finite.clear();
                let t0 = std::time::Instant::now();
                let got = source.read_block(block_frames, &mut block);
                read_s += t0.elapsed().as_secs_f64();
                match got {
                    Ok(true) => {
                        let b = Arc::new(block);
                        if worker_txs
                            .iter()
                            .any(|tx| tx.send(ToWorker::Block(b.clone())).is_err())
                        {
                            break;
                        }
                        pool.push(b);
                        if pool.len() > BLOCKS_IN_FLIGHT as usize {
                            // More alive than the queues can hold: forget one handle (its
                            // memory goes when the workers drop it).
                            pool.remove(0);
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
            (failure, read_s)
        });
        let mut summary = RunSummary {
            threads: workers,
            ..Default::default()
        };
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
                let t0 = std::time::Instant::now();
                result = on_rows(&rows);
                summary.stages.output_s += t0.elapsed().as_secs_f64();
            }
        };
        for report in row_rx.iter() {
            summary.stages.add(&report.times);
            for (c, rows) in report.rows {
                order.add(c, rows);
            }
            for (c, w) in report.watermarks {
                order.advance(c, w);
            }
            deliver(order.release(), &mut summary);
        }
        deliver(order.drain(), &mut summary);
        let (input_error, read_s) = reader.join().unwrap_or((None, 0.0));
        summary.input_error = input_error;
        summary.stages.read_s = read_s;
        // The front end's share is the analysis time not spent in the other two.
        if options.profile_stages {
            let st = &mut summary.stages;
            st.front_end_s = (st.analysis_s - st.segment_s - st.estimator_s).max(0.0);
        }
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
            times: StageTimes::default(),
        };
        let t0 = std::time::Instant::now();
        for (i, (c, an)) in group.iter_mut().enumerate() {
            let rows = match &msg {
                ToWorker::Block(block) => match block.channels.get(*c) {
                    Some(samples) => {
                        let finite = block.is_known_finite(*c);
                        guarded(i, an, &|an, o| an.push_checked(samples, finite, o))
                    }
                    None => Vec::new(),
                },
                ToWorker::End { truncated } => {
                    let t = *truncated;
                    let rows = guarded(i, an, &|an, o| an.finish(t, o));
                    let (segment_s, estimator_s) = an.stage_seconds();
                    report.times.segment_s += segment_s;
                    report.times.estimator_s += estimator_s;
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
        report.times.analysis_s = t0.elapsed().as_secs_f64();
        if row_tx.send(report).is_err() {
            return;
        }
    }
}

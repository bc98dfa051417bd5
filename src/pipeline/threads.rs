//! The threads of a run: a reader hands each block to every worker over bounded channels; each
//! worker builds and owns the [`ChannelAnalyzer`]s of a contiguous run of channels (a panic in one channel
//! stops that channel only) and, where the source leaves blocks encoded, decodes just those
//! channels itself; finished rows come back in stream order ([`super::order::RowOrder`]). At
//! the end of the input, every worker's open channels go to one queue that all workers drain
//! ([`super::finishing`]).

use std::sync::Arc;

use crossbeam_channel::{bounded, Receiver, Sender};

use super::block_pool::{blocks_in_flight, queue_blocks, BlockPool};
use super::finishing::{finish_queued, guarded, FinishJob, FinishQueue};
use super::order::RowOrder;
use super::schema::StageTimes;
use super::{AnalysisConfig, ChannelAnalyzer, FrontEndFactory, ResultRow, RunSummary};
use crate::decay::Flag;
use crate::error::{Error, Result};
use crate::source::encoded::EncodedFrames;
use crate::source::{Block, Source, SourceError};

/// What a worker hands back after each block: finished rows per channel (index into the
/// input's channels) and each of its channels' watermark ([`ChannelAnalyzer::watermark`]).
pub(super) struct WorkerReport {
    pub(super) rows: Vec<(usize, Vec<ResultRow>)>,
    pub(super) watermarks: Vec<(usize, u64)>,
    /// The worker's time on this block (analysis; with its split once its channels finished).
    pub(super) times: StageTimes,
}

/// How a run uses the machine; the results do not depend on it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunOptions {
    /// Worker threads (None: one per available core); never more than the channels.
    pub threads: Option<usize>,
    /// Split the analysis time into segmentation, front end and estimator
    /// ([`StageTimes`]; costs a clock read per frame).
    pub profile_stages: bool,
    /// Buffered decays always from the allocator, never from a worker's huge-page arena
    /// (`frontend/decay_arena.rs`; for comparisons).
    pub plain_decay_buffers: bool,
}

#[derive(Clone)]
enum ToWorker {
    Block(Arc<Block>),
    /// A block left in its stored encoding: each worker decodes its own channels.
    Encoded(Arc<EncodedFrames>),
    End {
        truncated: bool,
    },
    /// The writer paused after the last block: with `pause_ends_decays` every open decay
    /// ends ([`ChannelAnalyzer::pause`]).
    Pause,
}

/// The channels of each of `workers` workers: contiguous runs, as even as the count allows
/// (their sizes differ by at most one). A worker decoding its run of an encoded block reads
/// only its share of each frame.
fn channel_shares(channels: usize, workers: usize) -> Vec<std::ops::Range<usize>> {
    let workers = workers.clamp(1, channels.max(1));
    let (base, extra) = (channels / workers, channels % workers);
    let mut start = 0;
    (0..workers)
        .map(|w| {
            let len = base + usize::from(w < extra);
            start += len;
            start - len..start
        })
        .collect()
}

/// Runs the whole analysis of `source`, calling `on_rows` with each batch of finished rows as soon
/// as it is ready. Errors from `on_rows` stop the run. A front end the factory cannot build fails
/// the run (the settings are checked on one before any thread starts; a factory that fails later,
/// in a worker, may leave other channels' rows delivered before the error).
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
    // Memory, before anything proportional to the channel count is allocated: one front end
    // tells its size, the analyzers' buffers are known, and blocks are shared by the workers.
    let first = factory()?;
    let block_frames = super::block_frames_for(config.block_frames, first.as_ref());
    if block_frames > config.block_frames {
        // Decoded samples are 8 bytes; no stored encoding is wider.
        source.allow_block_bytes(block_frames.saturating_mul(n_channels * 8));
    }
    let input_frames = source
        .expected_frames()
        .and_then(|n| usize::try_from(n).ok());
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
    let queue_blocks = queue_blocks(block_frames, n_channels);
    let in_flight = blocks_in_flight(queue_blocks);
    let blocks = in_flight as f64 * block_frames as f64 * n_channels as f64 * 8.0;
    crate::budget::check(
        &format!("the analysis of {n_channels} channels"),
        per_channel * n_channels as f64 + blocks,
    )?;
    let mut first = Some(first);
    // A front end the factory failed to build (in a worker, see below): the run's error.
    let build_error: std::sync::Mutex<Option<Error>> = std::sync::Mutex::new(None);
    let (row_tx, row_rx) = bounded::<WorkerReport>(64);
    let finishing = FinishQueue::default();
    let shares = channel_shares(n_channels, workers);
    // Workers start their setup once every thread exists: each one's first steps map and
    // advise memory (the address space's write lock), which the calling thread needs to map
    // the next thread's stack; interleaved, the last thread started 0.2 ms late.
    let all_spawned = std::sync::Barrier::new(shares.len() + 1);
    std::thread::scope(|scope| -> Result<RunSummary> {
        let mut worker_txs: Vec<Sender<ToWorker>> = Vec::new();
        let mut handles = Vec::new();
        let finishing = &finishing;
        let (info, build_error) = (&info, &build_error);
        let all_spawned = &all_spawned;
        for range in shares {
            let (tx, rx) = bounded::<ToWorker>(queue_blocks);
            worker_txs.push(tx);
            let row_tx = row_tx.clone();
            // Its decoded blocks: f64 samples of its channels, a block's frames at most.
            let block_bytes = range.len()
                * input_frames.map_or(block_frames, |n| n.min(block_frames))
                * std::mem::size_of::<f64>();
            let input_frames = input_frames.filter(|_| !options.plain_decay_buffers);
            let first = first.take();
            handles.push(scope.spawn(move || {
                all_spawned.wait();
                super::thread_heap::advise_huge_pages(block_bytes);
                // Decay buffers of this worker's channels on huge pages, where the length is
                // known.
                let _arena = crate::frontend::decay_arena::install(range.len(), input_frames);
                // Each worker builds its own channels' analyzers, both at once: built by the
                // caller's thread, their fresh memory's page faults were 0.3 ms with the other
                // core idle (64 octave-bank channels). A failure ends this worker (the reader
                // then stops) and the run returns it.
                match build_analyzers(range.clone(), first, factory, info, config, options) {
                    Ok(analyzers) => {
                        worker(WorkerChannels { range, analyzers }, rx, row_tx, finishing)
                    }
                    Err(e) => {
                        let mut slot = build_error.lock().unwrap_or_else(|e| e.into_inner());
                        slot.get_or_insert(e);
                    }
                }
            }));
        }
        drop(row_tx);
        let reader = scope.spawn(move || -> (Option<SourceError>, f64) {
            // Its blocks come from its heap, on huge pages; the heap's first 2 MB is collapsed
            // once a block turns out to be a buffer of its own (not a mapped file's pages).
            super::thread_heap::advise_huge_pages(0);
            let mut holds_buffers = false;
            let mut failure = None;
            let mut read_s = 0.0;
            let mut blocks: BlockPool<Block> = BlockPool::new(in_flight);
            let mut encoded: BlockPool<EncodedFrames> = BlockPool::new(in_flight);
            // Left encoded while the source can (binary frames), decoded here otherwise.
            let mut defer = true;
            loop {
                let t0 = std::time::Instant::now();
                let (got, message) = if defer {
                    let mut frames = encoded.take();
                    match source.read_encoded_block(block_frames, &mut frames) {
                        Some(got) => {
                            let frames = Arc::new(frames);
                            encoded.keep(frames.clone());
                            (got, ToWorker::Encoded(frames))
                        }
                        None => {
                            defer = false;
                            continue;
                        }
                    }
                } else {
                    let mut block = blocks.take();
                    // A recycled block's flags belong to its last samples (a source that
                    // does not check leaves them empty).
                    block.known_finite.clear();
                    let got = source.read_block(block_frames, &mut block);
                    let block = Arc::new(block);
                    blocks.keep(block.clone());
                    (got, ToWorker::Block(block))
                };
                read_s += t0.elapsed().as_secs_f64();
                let mapped = matches!(&message, ToWorker::Encoded(f) if !f.is_copy());
                if !holds_buffers && matches!(got, Ok(true)) && !mapped {
                    holds_buffers = true;
                    super::thread_heap::advise_huge_pages(usize::MAX);
                }
                match got {
                    Ok(true) => {
                        if !worker_txs.iter().all(|tx| tx.send(message.clone()).is_ok()) {
                            break;
                        }
                        if source.paused()
                            && !worker_txs.iter().all(|tx| tx.send(ToWorker::Pause).is_ok())
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
                let truncated = failure.as_ref().is_some_and(SourceError::cuts_decays_short);
                for tx in &worker_txs {
                    let _ = tx.send(ToWorker::End { truncated });
                }
            }
            (failure, read_s)
        });
        all_spawned.wait();
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
        // Plus the workers' decoding of encoded blocks (added with their reports).
        summary.stages.read_s += read_s;
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
        if let Some(e) = build_error.lock().unwrap_or_else(|e| e.into_inner()).take() {
            return Err(e);
        }
        result.map(|_| summary)
    })
}

/// The analyzers of channels `range`, in order: the first on `first` when given (the front end
/// the run was sized with), the others on front ends from `factory`.
fn build_analyzers(
    range: std::ops::Range<usize>,
    mut first: Option<Box<dyn crate::frontend::FrontEnd>>,
    factory: &FrontEndFactory,
    info: &crate::source::SignalInfo,
    config: &AnalysisConfig,
    options: RunOptions,
) -> Result<Vec<(usize, ChannelAnalyzer)>> {
    let mut analyzers = Vec::with_capacity(range.len());
    for c in range {
        let fe = match first.take() {
            Some(fe) => fe,
            None => factory()?,
        };
        let name = info.channel_names[c].clone();
        let mut an = ChannelAnalyzer::new(name, info.sample_rate_hz, fe, *config);
        if options.profile_stages {
            an.profile_stages();
        }
        analyzers.push((c, an));
    }
    Ok(analyzers)
}

/// What one worker analyses: its run of channels and their analyzers, in channel order.
struct WorkerChannels {
    range: std::ops::Range<usize>,
    analyzers: Vec<(usize, ChannelAnalyzer)>,
}

fn worker(
    group: WorkerChannels,
    rx: Receiver<ToWorker>,
    row_tx: Sender<WorkerReport>,
    finishing: &FinishQueue,
) {
    let WorkerChannels {
        range,
        analyzers: mut group,
    } = group;
    // This worker's channels of the last encoded block, decoded (reused block to block).
    let mut decoded = Block::default();
    let mut crashed = vec![false; group.len()];
    for msg in rx.iter() {
        let t0 = std::time::Instant::now();
        let mut report = WorkerReport {
            rows: Vec::new(),
            watermarks: Vec::with_capacity(group.len()),
            times: StageTimes::default(),
        };
        // Where this worker's channels are in the block it analyses (decoded ones start at 0).
        let (block, offset): (&Block, usize) = match &msg {
            ToWorker::Block(block) => (block, 0),
            ToWorker::Encoded(frames) => {
                frames.decode_into(range.clone(), &mut decoded);
                report.times.read_s += t0.elapsed().as_secs_f64();
                (&decoded, range.start)
            }
            ToWorker::Pause => {
                for (i, (c, an)) in group.iter_mut().enumerate() {
                    let rows = guarded(&mut crashed[i], an, &|an, o| an.pause(o));
                    if !rows.is_empty() {
                        report.rows.push((*c, rows));
                    }
                    report.watermarks.push((*c, an.watermark()));
                }
                report.times.analysis_s = t0.elapsed().as_secs_f64();
                if row_tx.send(report).is_err() {
                    return;
                }
                continue;
            }
            ToWorker::End { truncated } => {
                let jobs = group.drain(..).zip(crashed.drain(..));
                finishing.deposit(jobs.map(|((channel, analyzer), crashed)| FinishJob {
                    channel,
                    analyzer,
                    crashed,
                }));
                if !finish_queued(finishing, *truncated, &row_tx) {
                    return;
                }
                continue;
            }
        };
        for (i, (c, an)) in group.iter_mut().enumerate() {
            if let Some(samples) = block.channels.get(*c - offset) {
                let finite = block.is_known_finite(*c - offset);
                let rows = guarded(&mut crashed[i], an, &|an, o| {
                    an.push_checked(samples, finite, o)
                });
                if !rows.is_empty() {
                    report.rows.push((*c, rows));
                }
            }
            report.watermarks.push((*c, an.watermark()));
        }
        report.times.analysis_s = t0.elapsed().as_secs_f64() - report.times.read_s;
        if row_tx.send(report).is_err() {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::channel_shares;

    /// The shares cover every channel once, in order, in runs whose sizes differ by at most
    /// one; there are never more runs than channels, and 64 channels on 2 workers split into
    /// the two halves (runs of whole groups of eight, for the vector decoder).
    #[test]
    fn channel_shares_are_contiguous_and_even() {
        for channels in 1..40 {
            for workers in 1..6 {
                let shares = channel_shares(channels, workers);
                assert_eq!(shares.len(), workers.min(channels));
                let flat: Vec<usize> = shares.iter().cloned().flatten().collect();
                assert_eq!(flat, (0..channels).collect::<Vec<_>>());
                let sizes: Vec<usize> = shares.iter().map(|r| r.len()).collect();
                let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
                assert!(
                    hi - lo <= 1 && *lo >= 1,
                    "{channels} ch, {workers}: {sizes:?}"
                );
            }
        }
        assert_eq!(channel_shares(64, 2), vec![0..32, 32..64]);
    }

    /// The IEC octave bands below Nyquist at `fs_hz`.
    fn octave_bands(fs_hz: f64) -> Vec<crate::frontend::Band> {
        use crate::plan::{BandLayout, BandSpec};
        BandLayout {
            specs: vec!["octave".parse::<BandSpec>().unwrap()],
            ..Default::default()
        }
        .resolve(fs_hz, None)
        .unwrap()
        .bands
    }

    /// Decay buffers from the workers' huge-page arenas give the rows the allocator's give,
    /// bit for bit, for both buffering banks on one and two workers; and the arenas were used.
    #[test]
    fn decays_in_arenas_give_the_same_rows() {
        use crate::analysis::bench::BenchInput;
        use crate::plan::{FrontEndKind, FrontEndSpec};
        use std::sync::atomic::Ordering;
        // 32 channels × 10 s at 4096 Hz: 2.6 MB of decays per worker of two, enough for one.
        let input = BenchInput::synthetic(32, 4096.0, 10.0).unwrap();
        let bands = octave_bands(input.fs_hz);
        for kind in [FrontEndKind::Octave, FrontEndKind::Goyder] {
            let factory = FrontEndSpec::default()
                .with_kind(kind)
                .factory(input.fs_hz, bands.clone())
                .unwrap();
            let rows = |threads: usize, plain_decay_buffers: bool| {
                let options = super::RunOptions {
                    threads: Some(threads),
                    plain_decay_buffers,
                    ..Default::default()
                };
                let mut out = Vec::new();
                let config = crate::pipeline::AnalysisConfig::default();
                super::run_with(input.source().unwrap(), &factory, &config, options, |r| {
                    out.extend_from_slice(r);
                    Ok(())
                })
                .unwrap();
                out
            };
            let plain = rows(2, true);
            assert_eq!(plain.len(), 32 * bands.len(), "{kind:?}");
            for threads in [1, 2] {
                let before = crate::frontend::decay_arena::SLOTS_TAKEN.load(Ordering::Relaxed);
                assert_eq!(rows(threads, false), plain, "{kind:?}, {threads} threads");
                let taken = crate::frontend::decay_arena::SLOTS_TAKEN.load(Ordering::Relaxed);
                if cfg!(target_os = "linux") {
                    assert!(taken - before >= 32, "{kind:?}: {} slots", taken - before);
                }
            }
        }
    }

    /// The workers build their channels' analyzers: a factory that fails for some channel fails
    /// the run with its own error (no hang, no panic), on one and on two workers, whichever
    /// worker's channel it is; one that never fails gives every channel's rows.
    #[test]
    fn a_front_end_that_cannot_be_built_fails_the_run() {
        use crate::analysis::bench::BenchInput;
        use crate::plan::FrontEndSpec;
        use std::sync::atomic::{AtomicUsize, Ordering};
        use std::sync::Arc;
        let input = BenchInput::synthetic(8, 4096.0, 1.0).unwrap();
        let bands = octave_bands(input.fs_hz);
        let good = FrontEndSpec::default()
            .factory(input.fs_hz, bands.clone())
            .unwrap();
        let config = crate::pipeline::AnalysisConfig::default();
        // Calls: one to size the run, then one per channel but the first.
        for fail_at in [None, Some(2), Some(6), Some(8)] {
            for threads in [1, 2] {
                let calls = Arc::new(AtomicUsize::new(0));
                let (good, counter) = (good.clone(), calls.clone());
                let factory: crate::pipeline::FrontEndFactory = Arc::new(move || {
                    let n = counter.fetch_add(1, Ordering::SeqCst) + 1;
                    if Some(n) == fail_at {
                        Err(crate::error::Error::setting(
                            "front end",
                            format!("call {n} refused"),
                        ))
                    } else {
                        good()
                    }
                });
                let options = super::RunOptions {
                    threads: Some(threads),
                    ..Default::default()
                };
                let mut rows = 0;
                let run =
                    super::run_with(input.source().unwrap(), &factory, &config, options, |r| {
                        rows += r.len();
                        Ok(())
                    });
                match fail_at {
                    None => {
                        run.unwrap();
                        assert_eq!(rows, 8 * bands.len());
                        assert_eq!(calls.load(Ordering::SeqCst), 8);
                    }
                    Some(n) => {
                        let e = run.unwrap_err().to_string();
                        assert!(
                            e.contains(&format!("call {n} refused")),
                            "{threads} threads: {e}"
                        );
                    }
                }
            }
        }
    }
}

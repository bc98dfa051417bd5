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

use crate::decay::estimate::EstimateSettings;
use crate::decay::leakage::{flag_leakage, BandLevel, LeakageModel};
use crate::decay::{DecayEstimate, DecayEstimator, EvaluationRange, Flag, OnlineSchroeder};
use crate::error::{Error, Result};
use crate::frontend::onset::{OnsetDetector, OnsetEvent, OnsetSettings};
use crate::frontend::{Band, Frame, FrontEnd};
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
    /// Sample frames per block read from the source.
    pub block_frames: usize,
}

impl Default for AnalysisConfig {
    fn default() -> Self {
        AnalysisConfig {
            estimate: EstimateSettings::default(),
            onset_level_db: 20.0,
            onset_lookahead_s: 0.1,
            max_decay_s: None,
            end_drop_db: 100.0,
            retrigger_db: 20.0,
            block_frames: 4096,
        }
    }
}

/// One result: a decay in one band of one channel.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ResultRow {
    /// Channel (sensor id).
    pub channel: String,
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

/// Estimates every band of one decay, given from its onset, in one go (no threads).
pub fn analyze_decay(
    samples: &[f64],
    front_end: &mut dyn FrontEnd,
    settings: &EstimateSettings,
) -> Vec<DecayEstimate> {
    front_end.reset();
    let mut trackers = BandTrackers::new(front_end, settings, f64::INFINITY);
    front_end.process(samples, &mut |f: Frame<'_>| trackers.push(f));
    front_end.finish(&mut |f: Frame<'_>| trackers.push(f));
    let cut_short = front_end.decay_cut_short();
    let mut estimates: Vec<DecayEstimate> =
        trackers.estimators.iter().map(|e| e.provisional()).collect();
    judge_bands(front_end, &trackers.estimators, &mut estimates);
    if cut_short {
        estimates
            .iter_mut()
            .for_each(|e| e.flags.push(Flag::DecayTooLong));
    }
    estimates
}

/// A front end as the leakage test's model of its bands.
struct FrontEndLeakage<'a>(&'a dyn FrontEnd);

impl LeakageModel for FrontEndLeakage<'_> {
    fn mode_gain(&self, b: usize, f_hz: f64, sigma_per_s: f64) -> f64 {
        self.0.mode_gain(b, f_hz, sigma_per_s)
    }
    fn flat_gain(&self, b: usize, lo_hz: f64, hi_hz: f64) -> f64 {
        self.0.flat_gain(b, lo_hz, hi_hz)
    }
    fn tolerance_hz(&self) -> f64 {
        self.0.frequency_tolerance_hz()
    }
}

/// The tests across the bands of one decay: a band narrower than the front end resolves gives
/// no number ([`Flag::BelowResolution`]), nor does a band whose decay is another band's
/// ([`Flag::Leakage`], see [`crate::decay::leakage`]).
fn judge_bands(
    front_end: &dyn FrontEnd,
    estimators: &[OnlineSchroeder],
    estimates: &mut [DecayEstimate],
) {
    let resolution_hz = front_end.resolution().frequency_resolution_hz;
    let levels: Vec<BandLevel> = front_end
        .bands()
        .iter()
        .zip(estimators)
        .map(|(b, e)| BandLevel {
            lo_hz: b.lo_hz,
            hi_hz: b.hi_hz,
            center_hz: b.center_hz,
            energy: e.total_energy(),
        })
        .collect();
    flag_leakage(estimates, &levels, &FrontEndLeakage(front_end));
    for (est, band) in estimates.iter_mut().zip(front_end.bands()) {
        if band.width_hz() < resolution_hz * (1.0 - 1e-9) && !est.has(Flag::NoEnergy) {
            est.withhold(Flag::BelowResolution);
        }
    }
}

/// Per-band estimators plus the end-of-decay test.
struct BandTrackers {
    estimators: Vec<OnlineSchroeder>,
    peak: Vec<f64>,
    end_factor: f64,
    ended: bool,
}

impl BandTrackers {
    fn new(fe: &dyn FrontEnd, settings: &EstimateSettings, end_drop_db: f64) -> Self {
        let period = fe.resolution().frame_period_s;
        BandTrackers {
            estimators: fe
                .bands()
                .iter()
                .map(|b| OnlineSchroeder::new(period, b.center_hz, *settings))
                .collect(),
            peak: vec![0.0; fe.bands().len()],
            end_factor: 10f64.powf(-end_drop_db / 10.0),
            ended: false,
        }
    }

    fn reset(&mut self) {
        self.estimators.iter_mut().for_each(|e| e.reset());
        self.peak.iter_mut().for_each(|p| *p = 0.0);
        self.ended = false;
    }

    fn push(&mut self, frame: Frame<'_>) {
        if self.ended {
            return;
        }
        let mut all_low = true;
        for (k, est) in self.estimators.iter_mut().enumerate() {
            if frame.active.is_some_and(|a| !a[k]) {
                continue;
            }
            let e = frame.energy[k];
            est.push_frame(e, frame.frequency_hz[k]);
            self.peak[k] = self.peak[k].max(e);
            all_low &= e <= self.peak[k] * self.end_factor;
        }
        self.ended = all_low && self.end_factor > 0.0;
    }
}

enum State {
    Searching,
    Decaying { onset_index: u64, samples: u64 },
}

/// Finds decays in one channel's stream and estimates each band of each decay.
pub struct ChannelAnalyzer {
    name: String,
    sample_rate_hz: f64,
    config: AnalysisConfig,
    front_end: Box<dyn FrontEnd>,
    trackers: BandTrackers,
    band_in_range: Vec<bool>,
    detector: OnsetDetector,
    state: State,
    decays: usize,
    last_peak: f64,
    failed: bool,
    fragments: usize,
}

/// Samples fed to the front end between end-of-decay checks.
const CHECK_SAMPLES: usize = 1024;

impl ChannelAnalyzer {
    /// An analyzer for channel `name` at `sample_rate_hz` using `front_end`.
    pub fn new(
        name: String,
        sample_rate_hz: f64,
        front_end: Box<dyn FrontEnd>,
        config: AnalysisConfig,
    ) -> Self {
        let nyquist = 0.5 * sample_rate_hz;
        let band_in_range = front_end
            .bands()
            .iter()
            .map(|b| b.hi_hz <= nyquist * (1.0 + 1e-12))
            .collect();
        let lookahead = (config.onset_lookahead_s * sample_rate_hz).round().max(1.0) as usize;
        let onset = OnsetSettings {
            level_db: config.onset_level_db,
            lookahead_samples: lookahead,
            max_buffer_samples: lookahead.saturating_mul(20).max(1 << 16),
        };
        ChannelAnalyzer {
            trackers: BandTrackers::new(&*front_end, &config.estimate, config.end_drop_db),
            name,
            sample_rate_hz,
            front_end,
            band_in_range,
            detector: OnsetDetector::new(onset, 0.0),
            state: State::Searching,
            decays: 0,
            last_peak: 0.0,
            failed: false,
            fragments: 0,
            config,
        }
    }

    fn max_decay_samples(&self) -> u64 {
        self.config.max_decay_s.map_or(u64::MAX, |s| {
            (s * self.sample_rate_hz).round().max(1.0) as u64
        })
    }

    fn feed(&mut self, samples: &[f64]) {
        let trackers = &mut self.trackers;
        self.front_end
            .process(samples, &mut |f: Frame<'_>| trackers.push(f));
    }

    fn rows_for(&self, onset_s: Option<f64>, estimates: Vec<DecayEstimate>) -> Vec<ResultRow> {
        self.front_end
            .bands()
            .iter()
            .zip(estimates)
            .map(|(band, estimate)| ResultRow {
                channel: self.name.clone(),
                decay: self.decays,
                onset_s,
                front_end: self.front_end.name(),
                band: *band,
                range: self.config.estimate.range,
                estimate,
            })
            .collect()
    }

    fn finalize(&mut self, truncated: bool, out: &mut Vec<ResultRow>) {
        let State::Decaying { onset_index, .. } = self.state else {
            return;
        };
        let trackers = &mut self.trackers;
        self.front_end.finish(&mut |f: Frame<'_>| trackers.push(f));
        if self.decays > 0 && self.trackers.estimators.iter().all(|e| e.frames() == 0) {
            // A re-trigger too short for a single frame at the end of the input (e.g. the
            // wrap-around at the end of an impulse response made by inverse FFT) is not a decay.
            self.fragments += 1;
            self.state = State::Searching;
            return;
        }
        let cut_short = self.front_end.decay_cut_short();
        let mut estimates: Vec<DecayEstimate> = self
            .trackers
            .estimators
            .iter()
            .zip(&self.band_in_range)
            .map(|(e, &ok)| {
                if ok {
                    e.provisional()
                } else {
                    DecayEstimate::failed(Flag::BandOutOfRange)
                }
            })
            .collect();
        judge_bands(&*self.front_end, &self.trackers.estimators, &mut estimates);
        for est in &mut estimates {
            if truncated {
                est.flags.push(Flag::InputTruncated);
            }
            if cut_short {
                est.flags.push(Flag::DecayTooLong);
            }
        }
        let onset_s = onset_index as f64 / self.sample_rate_hz;
        out.extend(self.rows_for(Some(onset_s), estimates));
        self.decays += 1;
        self.state = State::Searching;
        self.detector
            .rearm(self.last_peak * 10f64.powf(-self.config.retrigger_db / 20.0));
    }

    fn start_decay(&mut self, onset_index: u64, first: &[f64], peak: f64) {
        self.front_end.reset();
        self.trackers.reset();
        self.last_peak = peak;
        self.state = State::Decaying {
            onset_index,
            samples: 0,
        };
        self.feed_decay(first);
    }

    /// Feeds decay samples; returns how many were consumed before the decay ended.
    fn feed_decay(&mut self, samples: &[f64]) -> usize {
        let max = self.max_decay_samples();
        let mut used = 0;
        while used < samples.len() {
            let State::Decaying { samples: n, .. } = self.state else {
                break;
            };
            let room = (max - n).min(CHECK_SAMPLES as u64) as usize;
            let take = room.min(samples.len() - used);
            if take == 0 {
                break;
            }
            self.feed(&samples[used..used + take]);
            used += take;
            if let State::Decaying { samples: n, .. } = &mut self.state {
                *n += take as u64;
                if *n >= max || self.trackers.ended {
                    break;
                }
            }
        }
        used
    }

    /// Feeds the next samples of the channel; rows of decays that ended are appended to `out`.
    pub fn push(&mut self, samples: &[f64], out: &mut Vec<ResultRow>) {
        if self.failed {
            return;
        }
        if samples.iter().any(|x| !x.is_finite()) {
            self.failed = true;
            let n = self.front_end.bands().len();
            let failed = vec![DecayEstimate::failed(Flag::NonFiniteInput); n];
            out.extend(self.rows_for(None, failed));
            return;
        }
        let mut rest = samples;
        while !rest.is_empty() {
            match self.state {
                State::Searching => match self.detector.push(rest) {
                    OnsetEvent::Pending => return,
                    OnsetEvent::Found {
                        onset_index,
                        samples,
                        consumed,
                        peak,
                    } => {
                        rest = &rest[consumed..];
                        self.start_decay(onset_index, &samples, peak);
                    }
                },
                State::Decaying { .. } => {
                    let used = self.feed_decay(rest);
                    self.detector.advance(used);
                    rest = &rest[used..];
                }
            }
            if let State::Decaying { samples: n, .. } = self.state {
                if n >= self.max_decay_samples() || self.trackers.ended {
                    self.finalize(false, out);
                }
            }
        }
    }

    /// The input ended (`truncated`: it ended early or broken). Flushes the current decay; a
    /// channel in which no decay was ever found gets one row per band flagged `no_energy`.
    pub fn finish(&mut self, truncated: bool, out: &mut Vec<ResultRow>) {
        if self.failed {
            return;
        }
        if let State::Searching = self.state {
            if let OnsetEvent::Found {
                onset_index,
                samples,
                peak,
                ..
            } = self.detector.finish()
            {
                self.start_decay(onset_index, &samples, peak);
            }
        }
        self.finalize(truncated, out);
        if self.decays == 0 {
            let n = self.front_end.bands().len();
            let mut est = DecayEstimate::failed(Flag::NoEnergy);
            if truncated {
                est.flags.push(Flag::InputTruncated);
            }
            out.extend(self.rows_for(None, vec![est; n]));
        }
    }

    /// Re-triggers dropped because they ended before a single frame (not decays).
    pub fn fragments(&self) -> usize {
        self.fragments
    }

    /// True once non-finite samples were seen (nothing more is reported for this channel).
    pub fn failed(&self) -> bool {
        self.failed
    }

    /// One row per band carrying only `flag` (for a channel that cannot go on).
    fn flagged_rows(&self, flag: Flag) -> Vec<ResultRow> {
        let n = self.front_end.bands().len();
        self.rows_for(None, vec![DecayEstimate::failed(flag); n])
    }
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
    let workers = n_channels.min(
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1),
    );
    let mut groups: Vec<Vec<(usize, ChannelAnalyzer)>> = (0..workers).map(|_| Vec::new()).collect();
    for (c, name) in info.channel_names.iter().enumerate() {
        let fe = factory()?;
        let an = ChannelAnalyzer::new(name.clone(), info.sample_rate_hz, fe, *config);
        groups[c % workers].push((c, an));
    }
    let block_frames = config.block_frames.max(1);
    let (row_tx, row_rx) = bounded::<Vec<ResultRow>>(64);
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
            let truncated = failure.is_some();
            for tx in &worker_txs {
                let _ = tx.send(ToWorker::End { truncated });
            }
            failure
        });
        let mut summary = RunSummary::default();
        let mut result = Ok(());
        for rows in row_rx.iter() {
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
        }
        summary.input_error = reader.join().unwrap_or(None);
        for h in handles {
            let _ = h.join();
        }
        result.map(|_| summary)
    })
}

fn worker(
    mut group: Vec<(usize, ChannelAnalyzer)>,
    rx: Receiver<ToWorker>,
    row_tx: Sender<Vec<ResultRow>>,
) {
    use std::panic::{catch_unwind, AssertUnwindSafe};
    let mut out = Vec::new();
    // A panic in one channel's analysis (a bug) stops that channel only: its rows say
    // `internal_error` and the channels sharing this worker go on.
    let mut crashed = vec![false; group.len()];
    let mut guarded =
        |i: usize,
         an: &mut ChannelAnalyzer,
         out: &mut Vec<ResultRow>,
         f: &dyn Fn(&mut ChannelAnalyzer, &mut Vec<ResultRow>)| {
            if crashed[i] {
                return;
            }
            let mut local = Vec::new();
            if catch_unwind(AssertUnwindSafe(|| f(an, &mut local))).is_ok() {
                out.append(&mut local);
            } else {
                crashed[i] = true;
                out.extend(an.flagged_rows(Flag::InternalError));
            }
        };
    for msg in rx.iter() {
        match msg {
            ToWorker::Block(block) => {
                for (i, (c, an)) in group.iter_mut().enumerate() {
                    if let Some(samples) = block.channels.get(*c) {
                        guarded(i, an, &mut out, &|an, o| an.push(samples, o));
                    }
                }
            }
            ToWorker::End { truncated } => {
                for (i, (_, an)) in group.iter_mut().enumerate() {
                    guarded(i, an, &mut out, &|an, o| an.finish(truncated, o));
                }
            }
        }
        if !out.is_empty() && row_tx.send(std::mem::take(&mut out)).is_err() {
            return;
        }
    }
}

//! One channel's stream: decay onsets, new hits, the front end and the band estimators.

use super::bands::{judge_bands, BandTrackers, FloorEnd, TimedTrackers};
use super::segment::double_hit::{is_double_hit, DOUBLE_HIT_HISTORY_SAMPLES};
use super::segment::onset::{OnsetDetector, OnsetEvent, OnsetSettings, RetriggerWatch};
use super::segment::sample_scan::first_non_finite;
use super::segment::RETRIGGER_MIN_FREQUENCY_HZ;
use super::{AnalysisConfig, ResultRow};
use crate::decay::quantization::floor_energy;
use crate::decay::{DecayEstimate, DecayEstimator, Flag};
use crate::frontend::simd::Isa;
use crate::frontend::FrontEnd;

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
    watch: RetriggerWatch,
    retriggered: bool,
    /// The open decay's hit was clipped (its peak held flat over several samples).
    clipped: bool,
    /// The open decay's first samples hold a second impact (a hammer's rebound).
    double_hit: bool,
    state: State,
    decays: usize,
    last_peak: f64,
    failed: bool,
    finished: bool,
    fragments: usize,
    /// Per-stage clocks, when profiling ([`ChannelAnalyzer::profile_stages`]).
    clock: Option<StageClock>,
    /// Instruction set of the whole-block input check.
    isa: Isa,
}

/// Seconds a profiled analyzer spent in segmentation and in its estimators (the front end's
/// share is the rest of its time).
#[derive(Clone, Copy, Debug, Default)]
struct StageClock {
    segment_s: f64,
    estimator_s: f64,
}

/// Runs `f`, adding its duration to `slot` when there is one.
#[inline]
fn timed<T>(slot: Option<&mut f64>, f: impl FnOnce() -> T) -> T {
    match slot {
        Some(s) => {
            let t0 = std::time::Instant::now();
            let out = f();
            *s += t0.elapsed().as_secs_f64();
            out
        }
        None => f(),
    }
}

/// The onset search's lookahead and buffer cap, samples.
fn onset_sizes(lookahead_s: f64, sample_rate_hz: f64) -> (usize, usize) {
    let lookahead = (lookahead_s * sample_rate_hz).round().max(1.0) as usize;
    (lookahead, lookahead.saturating_mul(20).max(1 << 16))
}

/// Consecutive samples at exactly the peak magnitude that mark a clipped hit. A smooth peak
/// cannot repeat its value three times: even at 480 samples per period, neighbouring samples
/// near a peak differ by ~1e-4 of it, a thousand times a 32-bit float's resolution.
const CLIPPED_RUN_SAMPLES: usize = 3;

/// Whether `samples` (a hit from its onset) hold its `peak` magnitude over a run of at least
/// [`CLIPPED_RUN_SAMPLES`] samples: the sensor or converter saturated.
fn is_clipped(samples: &[f64], peak: f64) -> bool {
    if peak.is_nan() || peak <= 0.0 {
        return false;
    }
    let mut run = 0;
    for &x in samples {
        if x.abs() == peak {
            run += 1;
            if run >= CLIPPED_RUN_SAMPLES {
                return true;
            }
        } else {
            run = 0;
        }
    }
    false
}

/// Samples fed to the front end between end-of-decay checks.
const CHECK_SAMPLES: usize = 1024;

/// Bytes of one band's state in a channel besides its frame history: the estimator, the
/// estimate and the result row, and their small heap parts (flags, the channel name).
pub const BAND_STATE_BYTES: usize = std::mem::size_of::<crate::decay::OnlineSchroeder>()
    + std::mem::size_of::<DecayEstimate>()
    + std::mem::size_of::<ResultRow>()
    + 64;

/// Per band of `front_end`, the energy per frame of rounding to `step` (empty without a step,
/// 0 for a band whose front end cannot say).
fn quantization_floor(front_end: &dyn FrontEnd, step: Option<f64>) -> Vec<f64> {
    let Some(step) = step else {
        return Vec::new();
    };
    (0..front_end.bands().len())
        .map(|b| {
            front_end
                .white_noise_energy(b)
                .map_or(0.0, |white| floor_energy(step, white))
        })
        .collect()
}

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
        let (lookahead, cap) = onset_sizes(config.segmentation.onset_lookahead_s, sample_rate_hz);
        let onset = OnsetSettings {
            level_db: config.segmentation.onset_level_db,
            lookahead_samples: lookahead,
            max_buffer_samples: cap,
            // The front end's own pre-roll, and what the double-hit check wants before the
            // onset.
            pre_roll_samples: front_end.pre_roll_samples().max(DOUBLE_HIT_HISTORY_SAMPLES),
        };
        let lowest_hz = front_end
            .bands()
            .iter()
            .map(|b| b.lo_hz)
            .fold(f64::INFINITY, f64::min)
            .max(RETRIGGER_MIN_FREQUENCY_HZ);
        let gap = ((sample_rate_hz / (4.0 * lowest_hz)).ceil() as usize).min(lookahead);
        let floor = quantization_floor(&*front_end, config.quantization_step);
        ChannelAnalyzer {
            trackers: BandTrackers::new(
                front_end
                    .bands()
                    .iter()
                    .enumerate()
                    .map(|(k, b)| {
                        crate::decay::OnlineSchroeder::new(
                            front_end.resolution().frame_period_s,
                            b.center_hz,
                            config.estimate,
                        )
                        .with_floor_energy(floor.get(k).copied().unwrap_or(0.0))
                    })
                    .collect(),
                config.segmentation.end_drop_db,
                FloorEnd::new(
                    config.segmentation.floor_min_s,
                    config.segmentation.floor_flat_db,
                    front_end.resolution().frame_period_s,
                ),
            ),
            name,
            sample_rate_hz,
            front_end,
            band_in_range,
            detector: OnsetDetector::new(onset, 0.0),
            watch: RetriggerWatch::new(lookahead, gap, config.segmentation.retrigger_jump_db),
            retriggered: false,
            clipped: false,
            double_hit: false,
            state: State::Searching,
            decays: 0,
            last_peak: 0.0,
            failed: false,
            finished: false,
            fragments: 0,
            config,
            clock: None,
            isa: Isa::detect(),
        }
    }

    /// Starts measuring the time spent in segmentation and in the estimators (a clock read per
    /// frame: a few per cent slower, so only for profiling).
    pub fn profile_stages(&mut self) {
        self.clock = Some(StageClock::default());
    }

    /// Seconds spent in (segmentation, estimators) since profiling started; zeros without it.
    pub fn stage_seconds(&self) -> (f64, f64) {
        self.clock
            .map_or((0.0, 0.0), |c| (c.segment_s, c.estimator_s))
    }

    /// Bytes one analyzer holds besides its front end, at most: the onset buffer at its cap,
    /// the new-hit watch, the double-hit check's working copy of the decay's first
    /// [`DOUBLE_HIT_WINDOW_S`](super::segment::double_hit::DOUBLE_HIT_WINDOW_S) (25 bytes a
    /// sample, while a decay starts), and per band its estimator's state (frame energies grow
    /// with the decay: 16 bytes per frame and band on top of this).
    ///
    /// Per band: its estimator and result row (about `BAND_STATE_BYTES`) and the decay's frame
    /// history, 16 bytes per frame, doubled for vector growth, over `history_frames` frames
    /// (what a decay can hold: the input's length when known, capped by `max_decay_s`).
    pub fn buffer_bytes(
        sample_rate_hz: f64,
        n_bands: usize,
        history_frames: f64,
        config: &AnalysisConfig,
    ) -> f64 {
        let (lookahead, cap) = onset_sizes(config.segmentation.onset_lookahead_s, sample_rate_hz);
        let double_hit = 25.0 * super::segment::double_hit::DOUBLE_HIT_WINDOW_S * sample_rate_hz;
        (cap * 8 + lookahead * 24) as f64
            + double_hit
            + n_bands as f64 * (BAND_STATE_BYTES as f64 + 32.0 * history_frames)
    }

    fn max_decay_samples(&self) -> u64 {
        self.config.segmentation.max_decay_s.map_or(u64::MAX, |s| {
            (s * self.sample_rate_hz).round().max(1.0) as u64
        })
    }

    /// Feeds decay samples to the front end, with the samples that will follow them (see
    /// [`FrontEnd::process_ahead`]).
    fn feed(&mut self, samples: &[f64], ahead: &[f64]) {
        let trackers = &mut self.trackers;
        match &mut self.clock {
            None => self.front_end.process_ahead(samples, ahead, trackers),
            Some(clock) => self.front_end.process_ahead(
                samples,
                ahead,
                &mut TimedTrackers {
                    trackers,
                    seconds: &mut clock.estimator_s,
                },
            ),
        }
    }

    fn rows_for(
        &self,
        position_sample: u64,
        onset_s: Option<f64>,
        estimates: Vec<DecayEstimate>,
    ) -> Vec<ResultRow> {
        self.front_end
            .bands()
            .iter()
            .zip(estimates)
            .map(|(band, estimate)| ResultRow {
                channel: self.name.clone(),
                position_sample,
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
        match &mut self.clock {
            None => self.front_end.finish(trackers),
            Some(clock) => self.front_end.finish(&mut TimedTrackers {
                trackers,
                seconds: &mut clock.estimator_s,
            }),
        }
        if self.decays > 0 && self.trackers.estimators.iter().all(|e| e.frames() == 0) {
            // A re-trigger too short for a single frame at the end of the input (e.g. the
            // wrap-around at the end of an impulse response made by inverse FFT) is not a decay.
            self.fragments += 1;
            self.state = State::Searching;
            return;
        }
        let cut_short = self.front_end.decay_cut_short();
        let (front_end, estimators, in_range) = (
            &*self.front_end,
            &self.trackers.estimators,
            &self.band_in_range,
        );
        let mut estimates = timed(self.clock.as_mut().map(|c| &mut c.estimator_s), || {
            let mut estimates: Vec<DecayEstimate> =
                DecayEstimator::provisional_each(estimators, in_range)
                    .into_iter()
                    .map(|e| e.unwrap_or_else(|| DecayEstimate::failed(Flag::BandOutOfRange)))
                    .collect();
            judge_bands(front_end, estimators, &mut estimates);
            estimates
        });
        if let Some(tau) = self.config.exponential_window_tau_s {
            for (est, band) in estimates.iter_mut().zip(self.front_end.bands()) {
                crate::decay::damping::remove_exponential_window(est, tau, band.center_hz);
            }
        }
        for est in &mut estimates {
            if self.clipped {
                est.flags.push(Flag::ClippedHit);
            }
            if self.double_hit {
                est.flags.push(Flag::DoubleHit);
            }
            if truncated {
                est.flags.push(Flag::InputTruncated);
            }
            if cut_short {
                est.flags.push(Flag::DecayTooLong);
            }
        }
        let onset_s = onset_index as f64 / self.sample_rate_hz;
        out.extend(self.rows_for(onset_index, Some(onset_s), estimates));
        // The frame histories are done with: their memory goes to the next decay on this thread.
        self.trackers.release();
        self.decays += 1;
        self.state = State::Searching;
        self.detector
            .rearm(self.last_peak * 10f64.powf(-self.config.segmentation.retrigger_db / 20.0));
    }

    fn start_decay(&mut self, onset_index: u64, pre_roll: &[f64], first: &[f64], peak: f64) {
        self.front_end.reset();
        let fe_pre_roll = pre_roll.len().min(self.front_end.pre_roll_samples());
        self.front_end
            .begin_decay(&pre_roll[pre_roll.len() - fe_pre_roll..]);
        self.trackers.reset();
        self.last_peak = peak;
        self.retriggered = false;
        self.clipped = is_clipped(first, peak);
        self.double_hit = is_double_hit(pre_roll, first, self.sample_rate_hz);
        self.watch.restart(
            peak * 10f64.powf(-self.config.segmentation.retrigger_db / 20.0),
            first.len(),
        );
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
            let mut take = room.min(samples.len() - used);
            if take == 0 {
                break;
            }
            let watch = &mut self.watch;
            let scanned = timed(self.clock.as_mut().map(|c| &mut c.segment_s), || {
                watch.scan(&samples[used..used + take])
            });
            if let Some(hit) = scanned {
                take = hit;
                self.retriggered = true;
            }
            // What the next chunks will feed, unless the decay ends first: up to its length cap,
            // nothing past a new hit.
            let ahead = match scanned {
                Some(_) => &[][..],
                None => {
                    let fed = used + take;
                    let left = (max - n).saturating_sub(take as u64);
                    let end = (fed as u64).saturating_add(left).min(samples.len() as u64);
                    &samples[fed..end as usize]
                }
            };
            self.feed(&samples[used..used + take], ahead);
            used += take;
            if let State::Decaying { samples: n, .. } = &mut self.state {
                *n += take as u64;
                if *n >= max || self.trackers.ended || self.retriggered {
                    break;
                }
            }
        }
        used
    }

    /// Feeds the next samples of the channel; rows of decays that ended are appended to `out`.
    pub fn push(&mut self, samples: &[f64], out: &mut Vec<ResultRow>) {
        self.push_checked(samples, false, out)
    }

    /// [`ChannelAnalyzer::push`] of samples the caller may already know to be all finite
    /// (`known_finite`, e.g. [`crate::source::Block::known_finite`]): then they are not scanned
    /// for NaN and infinities again.
    pub fn push_checked(&mut self, samples: &[f64], known_finite: bool, out: &mut Vec<ResultRow>) {
        if self.failed {
            return;
        }
        let bad = if known_finite {
            debug_assert!(samples.iter().all(|v| v.is_finite()));
            None
        } else {
            first_non_finite(self.isa, samples)
        };
        if let Some(bad) = bad {
            // Decays that ended before the bad sample stand, whatever the block size; the open
            // one is dropped and the channel stops there.
            self.push(&samples[..bad], out);
            if self.failed {
                return;
            }
            self.failed = true;
            let n = self.front_end.bands().len();
            let failed = vec![DecayEstimate::failed(Flag::NonFiniteInput); n];
            out.extend(self.rows_for(self.detector.position(), None, failed));
            return;
        }
        let mut rest = samples;
        while !rest.is_empty() {
            match self.state {
                State::Searching => {
                    match timed(self.clock.as_mut().map(|c| &mut c.segment_s), || {
                        self.detector.push(rest)
                    }) {
                        OnsetEvent::Pending => return,
                        OnsetEvent::Found {
                            onset_index,
                            samples,
                            consumed,
                            peak,
                            pre_roll,
                        } => {
                            rest = &rest[consumed..];
                            self.start_decay(onset_index, &pre_roll, &samples, peak);
                        }
                    }
                }
                State::Decaying { .. } => {
                    let used = self.feed_decay(rest);
                    let detector = &mut self.detector;
                    timed(self.clock.as_mut().map(|c| &mut c.segment_s), || {
                        detector.advance(&rest[..used])
                    });
                    rest = &rest[used..];
                }
            }
            if let State::Decaying { samples: n, .. } = self.state {
                if n >= self.max_decay_samples() || self.trackers.ended || self.retriggered {
                    self.finalize(false, out);
                }
            }
        }
    }

    /// The input ended (`truncated`: it ended early or broken). Flushes the current decay; a
    /// channel in which no decay was ever found gets one row per band flagged `no_energy`.
    pub fn finish(&mut self, truncated: bool, out: &mut Vec<ResultRow>) {
        if self.failed || self.finished {
            return;
        }
        self.finished = true;
        self.settle_search();
        self.finalize(truncated, out);
        if self.decays == 0 {
            let n = self.front_end.bands().len();
            let mut est = DecayEstimate::failed(Flag::NoEnergy);
            if truncated {
                est.flags.push(Flag::InputTruncated);
            }
            out.extend(self.rows_for(self.detector.position(), None, vec![est; n]));
        }
    }

    /// Settles an onset search that armed but did not settle (its lookahead not yet complete)
    /// with what it buffered, and starts that decay.
    fn settle_search(&mut self) {
        if let State::Searching = self.state {
            if let OnsetEvent::Found {
                onset_index,
                samples,
                peak,
                pre_roll,
                ..
            } = self.detector.finish()
            {
                self.start_decay(onset_index, &pre_roll, &samples, peak);
            }
        }
    }

    /// The writer paused (nothing arrived for [`crate::source::STREAM_PAUSE_MS`]): with
    /// [`super::Segmentation::pause_ends_decays`], the open decay ends as at the end of the
    /// input (an onset search still settling settles first), its rows appended to `out`; the
    /// channel then goes on with what comes next. Without it, nothing happens.
    pub fn pause(&mut self, out: &mut Vec<ResultRow>) {
        if self.failed || self.finished || !self.config.segmentation.pause_ends_decays {
            return;
        }
        self.settle_search();
        self.finalize(false, out);
    }

    /// The smallest stream position (sample index) that a row this analyzer produces from now on
    /// can carry: the onset of the open decay, where the onset search armed, or how far it has
    /// read; `u64::MAX` once it can produce nothing more.
    pub fn watermark(&self) -> u64 {
        if self.failed || self.finished {
            return u64::MAX;
        }
        match self.state {
            State::Decaying { onset_index, .. } => onset_index,
            State::Searching => self
                .detector
                .armed_at()
                .unwrap_or_else(|| self.detector.position()),
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

    /// Stops the channel: one row per band carrying only `flag` (for a channel that cannot go
    /// on); nothing more comes from it.
    pub(super) fn fail_with(&mut self, flag: Flag) -> Vec<ResultRow> {
        self.failed = true;
        let n = self.front_end.bands().len();
        self.rows_for(
            self.detector.position(),
            None,
            vec![DecayEstimate::failed(flag); n],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::is_clipped;

    #[test]
    fn a_flat_topped_peak_is_clipped_and_a_sampled_sine_is_not() {
        // A sine at 480 samples per period: its peak is smooth.
        let sine: Vec<f64> = (0..2000)
            .map(|i| (std::f64::consts::TAU * i as f64 / 480.0).sin() as f32 as f64)
            .collect();
        let peak = sine.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(!is_clipped(&sine, peak));
        // The same sine saturating at 0.8.
        let clipped: Vec<f64> = sine.iter().map(|x| x.clamp(-0.8, 0.8)).collect();
        assert!(is_clipped(&clipped, 0.8));
    }
}

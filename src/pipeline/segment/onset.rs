//! Decay onset detection: where the first STFT frame (or filter-bank record) starts.
//!
//! The onset is the first sample whose magnitude comes within `level_db` of the peak. In a
//! stream the peak is not known in advance, so [`OnsetDetector`] arms at the first sample above
//! an arming threshold, buffers until `lookahead` samples have passed without a new peak (or the
//! buffer cap is reached), and then reports the onset inside its buffer. Its memory is bounded by
//! the cap.

/// Offline onset: the first index whose |x| ≥ max|x| · 10^(−level_db/20). `None` for silence.
pub fn find_onset(samples: &[f64], level_db: f64) -> Option<usize> {
    let peak = samples
        .iter()
        .filter(|x| x.is_finite())
        .fold(0.0f64, |m, x| m.max(x.abs()));
    if peak <= 0.0 {
        return None;
    }
    let threshold = peak * 10f64.powf(-level_db / 20.0);
    samples.iter().position(|x| x.abs() >= threshold)
}

/// Settings of the streaming onset detector.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OnsetSettings {
    /// The onset is the first sample within this many dB of the peak (20 by default).
    pub level_db: f64,
    /// The peak is settled when this many samples pass without a larger one.
    pub lookahead_samples: usize,
    /// Hard cap on the samples buffered while looking for the peak.
    pub max_buffer_samples: usize,
    /// Samples before the onset handed over with it ([`OnsetEvent::Found::pre_roll`]); 0 for
    /// none. The detector keeps this many of the most recent samples before it armed.
    pub pre_roll_samples: usize,
}

/// What the detector found in a call to [`OnsetDetector::push`].
#[derive(Debug, PartialEq)]
pub enum OnsetEvent {
    /// No onset yet; every sample given was consumed.
    Pending,
    /// An onset at absolute sample index `onset_index`; `samples` holds the decay from the onset
    /// up to and including the last consumed sample; `consumed` samples of the input were used.
    Found {
        /// Index of the onset sample counted from the start of the stream.
        onset_index: u64,
        /// The decay's first samples, starting at the onset.
        samples: Vec<f64>,
        /// How many samples of the last input slice were consumed.
        consumed: usize,
        /// Peak magnitude seen while looking for the onset.
        peak: f64,
        /// Up to [`OnsetSettings::pre_roll_samples`] samples that preceded the onset, oldest
        /// first (fewer at the start of the stream).
        pre_roll: Vec<f64>,
    },
}

/// Streaming onset detector with bounded memory.
#[derive(Clone, Debug)]
pub struct OnsetDetector {
    settings: OnsetSettings,
    arm_threshold: f64,
    /// Absolute index of the next sample to be pushed.
    position: u64,
    armed_at: Option<u64>,
    buffer: Vec<f64>,
    peak: f64,
    peak_offset: usize,
    /// The most recent samples that are not in `buffer` (at most `pre_roll_samples`).
    history: std::collections::VecDeque<f64>,
}

impl OnsetDetector {
    /// A detector that arms at the first sample with |x| > `arm_threshold`.
    pub fn new(settings: OnsetSettings, arm_threshold: f64) -> Self {
        OnsetDetector {
            settings,
            arm_threshold,
            position: 0,
            armed_at: None,
            buffer: Vec::new(),
            peak: 0.0,
            peak_offset: 0,
            history: std::collections::VecDeque::new(),
        }
    }

    /// Keeps `samples` as the most recent history (for the next onset's pre-roll).
    fn remember(&mut self, samples: &[f64]) {
        let cap = self.settings.pre_roll_samples;
        if cap == 0 {
            return;
        }
        let from = samples.len().saturating_sub(cap);
        self.history.extend(&samples[from..]);
        let excess = self.history.len().saturating_sub(cap);
        self.history.drain(..excess);
    }

    /// Restarts the search at the current position with a new arming threshold
    /// (e.g. 20 dB below the previous decay's peak, so its tail does not re-trigger).
    pub fn rearm(&mut self, arm_threshold: f64) {
        self.arm_threshold = arm_threshold;
        self.armed_at = None;
        self.buffer.clear();
        self.peak = 0.0;
        self.peak_offset = 0;
    }

    /// Moves the stream position forward over `samples` that bypassed the detector (a running
    /// decay); they stay in the history from which the next onset's pre-roll is taken.
    pub fn advance(&mut self, samples: &[f64]) {
        self.position += samples.len() as u64;
        self.remember(samples);
    }

    /// Absolute index of the next sample.
    pub fn position(&self) -> u64 {
        self.position
    }

    /// Absolute index of the sample at which the current search armed (an onset found from now
    /// on lies at or after it), or `None` when it has not armed.
    pub fn armed_at(&self) -> Option<u64> {
        self.armed_at
    }

    fn settle(&mut self, consumed: usize) -> OnsetEvent {
        let threshold = self.peak * 10f64.powf(-self.settings.level_db / 20.0);
        let first = self
            .buffer
            .iter()
            .position(|x| x.abs() >= threshold)
            .unwrap_or(0);
        let onset_index = self.armed_at.unwrap_or(self.position) + first as u64;
        let samples = self.buffer.split_off(first);
        let before = std::mem::take(&mut self.buffer);
        self.remember(&before);
        let pre_roll = self.history.drain(..).collect();
        self.remember(&samples);
        let peak = self.peak;
        self.rearm(self.arm_threshold);
        OnsetEvent::Found {
            onset_index,
            samples,
            consumed,
            peak,
            pre_roll,
        }
    }

    /// Feeds samples. Stops consuming at the moment an onset is settled.
    pub fn push(&mut self, samples: &[f64]) -> OnsetEvent {
        for (i, &x) in samples.iter().enumerate() {
            let a = if x.is_finite() { x.abs() } else { 0.0 };
            self.position += 1;
            if self.armed_at.is_none() {
                if a > self.arm_threshold {
                    self.armed_at = Some(self.position - 1);
                } else {
                    self.remember(&[x]);
                    continue;
                }
            }
            self.buffer.push(x);
            if a > self.peak {
                self.peak = a;
                self.peak_offset = self.buffer.len() - 1;
            }
            let since_peak = self.buffer.len() - 1 - self.peak_offset;
            if since_peak >= self.settings.lookahead_samples
                || self.buffer.len() >= self.settings.max_buffer_samples
            {
                return self.settle(i + 1);
            }
        }
        OnsetEvent::Pending
    }

    /// End of input: settles an armed search with what is buffered.
    pub fn finish(&mut self) -> OnsetEvent {
        if self.armed_at.is_some() && !self.buffer.is_empty() {
            self.settle(0)
        } else {
            OnsetEvent::Pending
        }
    }
}

/// Watches a running decay for a new hit: a sample at least `jump` times the largest magnitude
/// of the `window` samples that end (at least) `gap` samples before it, and at least `level`.
///
/// Why this criterion: a hit's response rises from the old level within a quarter period of its
/// lowest mode (the `gap`), so it is compared with what came before the rise. A decaying sum of
/// modes cannot do that whatever its beating, once `window ≥ gap`: rising from a beat null by
/// `jump` takes longer than the gap unless the window still holds the envelope before the null,
/// which (decaying) is higher; a beat shorter than the window puts its earlier, higher maximum
/// in it. Gaussian noise needs a 4σ → 12σ jump at 10 dB. Memory: one entry per block.
#[derive(Clone, Debug)]
pub struct RetriggerWatch {
    /// Samples per block: the window is kept as block maxima, so each sample costs a compare.
    block: usize,
    /// Blocks in the window, and blocks between the window and the current block.
    window_blocks: usize,
    gap_blocks: usize,
    jump: f64,
    level: f64,
    /// No test before this many samples (the decay's own peak and settling are not a new hit).
    grace: u64,
    seen: u64,
    /// Largest magnitude of the current block so far, and its sample count.
    block_max: f64,
    block_fill: usize,
    /// Index of the current block.
    block_index: u64,
    /// The last `gap_blocks` block maxima, not yet in the window.
    /// A ring of `gap_blocks` slots: `delay_len` of them filled, the oldest at `delay_head`.
    delay: Vec<f64>,
    delay_head: usize,
    delay_len: usize,
    /// (block index, maximum) of the window's blocks, maxima strictly decreasing front to back.
    queue: std::collections::VecDeque<(u64, f64)>,
    /// `jump` × the window's maximum (fixed within a block).
    threshold: f64,
    /// Instruction set of the per-piece maximum.
    isa: crate::frontend::simd::Isa,
}

/// `i` modulo `n` for `i < 2n` (a ring index one step past its end), without a division.
#[inline]
fn wrap(i: usize, n: usize) -> usize {
    if i >= n {
        i - n
    } else {
        i
    }
}

impl RetriggerWatch {
    /// A watch comparing each sample with the `window_samples` ending at least `gap_samples`
    /// before it; a rise of `jump_db` (amplitude dB) is a new hit. The window is held in blocks
    /// of an eighth of the gap, so the gap may grow by up to one block.
    pub fn new(window_samples: usize, gap_samples: usize, jump_db: f64) -> Self {
        let block = (gap_samples / 8).max(1);
        RetriggerWatch {
            block,
            window_blocks: window_samples.max(1).div_ceil(block),
            gap_blocks: gap_samples.div_ceil(block),
            jump: 10f64.powf(jump_db / 20.0),
            level: f64::INFINITY,
            grace: 0,
            seen: 0,
            block_max: 0.0,
            block_fill: 0,
            block_index: 0,
            delay: vec![0.0; gap_samples.div_ceil(block)],
            delay_head: 0,
            delay_len: 0,
            queue: std::collections::VecDeque::new(),
            threshold: 0.0,
            isa: crate::frontend::simd::Isa::detect(),
        }
    }

    /// Starts watching a new decay: samples below `level` never count as a hit; the first
    /// `grace_samples` (the decay's onset buffer) are only remembered.
    pub fn restart(&mut self, level: f64, grace_samples: usize) {
        self.level = level;
        let span = (self.window_blocks + self.gap_blocks + 1) * self.block;
        self.grace = grace_samples.max(span) as u64;
        self.seen = 0;
        self.block_max = 0.0;
        self.block_fill = 0;
        self.block_index = 0;
        self.delay_head = 0;
        self.delay_len = 0;
        self.queue.clear();
        self.threshold = 0.0;
    }

    /// Closes the current block: its maximum enters the delay line; the oldest delayed block
    /// enters the window; blocks older than the window leave it.
    fn close_block(&mut self) {
        // The block `gap_blocks` blocks back leaves the delay line (the one just closed when
        // there is no gap).
        let leaving = if self.gap_blocks == 0 {
            Some(self.block_max)
        } else if self.delay_len < self.gap_blocks {
            let slot = wrap(self.delay_head + self.delay_len, self.gap_blocks);
            self.delay[slot] = self.block_max;
            self.delay_len += 1;
            None
        } else {
            let oldest = self.delay[self.delay_head];
            self.delay[self.delay_head] = self.block_max;
            self.delay_head = wrap(self.delay_head + 1, self.gap_blocks);
            Some(oldest)
        };
        if let Some(m) = leaving {
            let k = self.block_index - self.gap_blocks as u64;
            while self.queue.back().is_some_and(|&(_, v)| v <= m) {
                self.queue.pop_back();
            }
            self.queue.push_back((k, m));
        }
        self.block_index += 1;
        let oldest = self
            .block_index
            .saturating_sub((self.gap_blocks + self.window_blocks) as u64);
        while self.queue.front().is_some_and(|&(k, _)| k < oldest) {
            self.queue.pop_front();
        }
        self.threshold = self.jump * self.queue.front().map_or(0.0, |&(_, m)| m);
        self.block_max = 0.0;
        self.block_fill = 0;
    }

    /// Scans `samples`; returns the index of the first one that is a new hit (it and the rest
    /// are not consumed), or `None` when all were consumed.
    pub fn scan(&mut self, samples: &[f64]) -> Option<usize> {
        if !self.jump.is_finite() {
            // Splitting off: nothing to watch.
            return None;
        }
        let mut done = 0;
        while done < samples.len() {
            // Up to the end of the current block, the threshold is fixed: a piece whose largest
            // magnitude is no hit (or that lies in the grace period) is taken whole.
            let take = (self.block - self.block_fill).min(samples.len() - done);
            let piece = &samples[done..done + take];
            // A non-finite sample counts as 0, as in the per-sample test below.
            let piece_max = super::sample_scan::max_abs_finite(self.isa, piece);
            let in_grace = self.seen + (take as u64) <= self.grace;
            if in_grace || piece_max < self.level || piece_max < self.threshold {
                self.block_max = self.block_max.max(piece_max);
                self.seen += take as u64;
                self.block_fill += take;
            } else {
                for (i, &x) in piece.iter().enumerate() {
                    let a = if x.is_finite() { x.abs() } else { 0.0 };
                    if a >= self.level && a >= self.threshold && self.seen >= self.grace {
                        return Some(done + i);
                    }
                    self.block_max = self.block_max.max(a);
                    self.seen += 1;
                    self.block_fill += 1;
                }
            }
            done += take;
            if self.block_fill == self.block {
                self.close_block();
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> OnsetSettings {
        OnsetSettings {
            level_db: 20.0,
            lookahead_samples: 50,
            max_buffer_samples: 10_000,
            pre_roll_samples: 0,
        }
    }

    #[test]
    fn streaming_onset_matches_offline_onset_whatever_the_block_size() {
        let mut x = vec![0.0; 300];
        x.extend((0..2000).map(|i| {
            let t = i as f64 / 1000.0;
            (-3.0 * t).exp() * (2.0 * std::f64::consts::PI * 37.0 * t).sin()
        }));
        let offline = find_onset(&x, 20.0).unwrap();
        for block in [1, 7, 64, 5000] {
            let mut det = OnsetDetector::new(settings(), 0.0);
            let mut found = None;
            for chunk in x.chunks(block) {
                if let OnsetEvent::Found { onset_index, .. } = det.push(chunk) {
                    found = Some(onset_index);
                    break;
                }
            }
            assert_eq!(found, Some(offline as u64), "block {block}");
        }
    }

    fn decaying_pair(f1: f64, f2: f64, fs: f64, seconds: f64) -> Vec<f64> {
        let sigma = 3.0;
        (0..(seconds * fs) as usize)
            .map(|i| {
                let t = i as f64 / fs;
                let w = |f: f64| (2.0 * std::f64::consts::PI * f * t).sin();
                (-sigma * t).exp() * (w(f1) + w(f2))
            })
            .collect()
    }

    #[test]
    fn retrigger_watch_finds_a_second_hit_and_ignores_beating_and_noise() {
        let fs = 4000.0;
        // Equal-amplitude pairs beat with exact nulls; none is a new hit.
        for (f1, f2) in [(50.0, 51.0), (100.0, 105.0), (200.0, 230.0), (57.0, 57.6)] {
            let x = decaying_pair(f1, f2, fs, 3.0);
            let mut w = RetriggerWatch::new(400, 10, 10.0);
            w.restart(0.1 * 2.0, 0);
            assert_eq!(w.scan(&x), None, "{f1}+{f2} Hz beating");
        }
        // A second hit 1.5 s later, 20 dB weaker than the first, is found where it starts.
        let mut x = decaying_pair(100.0, 105.0, fs, 3.0);
        let start = (1.5 * fs) as usize;
        for (k, v) in decaying_pair(100.0, 105.0, fs, 1.5).iter().enumerate() {
            x[start + k] += 0.1 * v;
        }
        let mut w = RetriggerWatch::new(400, 10, 10.0);
        w.restart(0.01, 0);
        let found = w.scan(&x).expect("second hit");
        assert!((start..start + 10).contains(&found), "found at {found}");
        // Block by block gives the same sample.
        let mut w = RetriggerWatch::new(400, 10, 10.0);
        w.restart(0.01, 0);
        let mut at = None;
        for (b, chunk) in x.chunks(333).enumerate() {
            if let Some(i) = w.scan(chunk) {
                at = Some(b * 333 + i);
                break;
            }
        }
        assert_eq!(at, Some(found));
        // White noise alone never triggers.
        let mut state = 12345u64;
        let noise: Vec<f64> = (0..200_000)
            .map(|_| {
                let mut g = 0.0;
                for _ in 0..12 {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    g += (state >> 11) as f64 / (1u64 << 53) as f64;
                }
                g - 6.0
            })
            .collect();
        let mut w = RetriggerWatch::new(400, 10, 10.0);
        w.restart(0.0, 0);
        assert_eq!(w.scan(&noise), None);
    }

    #[test]
    fn silence_has_no_onset() {
        assert_eq!(find_onset(&[0.0; 10], 20.0), None);
        let mut det = OnsetDetector::new(settings(), 0.0);
        assert_eq!(det.push(&[0.0; 10]), OnsetEvent::Pending);
        assert_eq!(det.finish(), OnsetEvent::Pending);
    }
}

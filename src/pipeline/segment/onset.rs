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

use super::sample_scan::block_maxima_into_ring;

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
    /// Blocks closed since the restart (the current block's index).
    block_index: u64,
    /// The maxima of the last `gap_blocks + window_blocks` closed blocks (all a window can
    /// reach), a ring whose next slot is `ring_head`.
    maxima: Vec<f64>,
    ring_head: usize,
    /// (block index, maximum) of the window's blocks, maxima strictly decreasing front to back;
    /// kept up to date block by block only while `live` (rebuilt from `maxima` when the
    /// threshold is next needed: in a decay's quiet tail no sample can be a hit, and only the
    /// block maxima are kept).
    queue: std::collections::VecDeque<(u64, f64)>,
    live: bool,
    /// `jump` × the window's maximum (fixed within a block; valid while `live`).
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
        let window_blocks = window_samples.max(1).div_ceil(block);
        let gap_blocks = gap_samples.div_ceil(block);
        RetriggerWatch {
            block,
            window_blocks,
            gap_blocks,
            jump: 10f64.powf(jump_db / 20.0),
            level: f64::INFINITY,
            grace: 0,
            seen: 0,
            block_max: 0.0,
            block_fill: 0,
            block_index: 0,
            maxima: vec![0.0; gap_blocks + window_blocks],
            ring_head: 0,
            queue: std::collections::VecDeque::new(),
            live: true,
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
        self.ring_head = 0;
        self.queue.clear();
        self.live = true;
        self.threshold = 0.0;
    }

    /// The maximum of closed block `k` (one of the last `maxima.len()` closed).
    fn block_maximum(&self, k: u64) -> f64 {
        let back = (self.block_index - k) as usize;
        debug_assert!(back >= 1 && back <= self.maxima.len());
        self.maxima[wrap(self.ring_head + self.maxima.len() - back, self.maxima.len())]
    }

    /// Closed block `k` enters the window (the earlier blocks it outweighs leave the queue).
    fn enter_window(&mut self, k: u64) {
        let m = self.block_maximum(k);
        while self.queue.back().is_some_and(|&(_, v)| v <= m) {
            self.queue.pop_back();
        }
        self.queue.push_back((k, m));
    }

    /// Closes the current block: its maximum enters the ring; while the window is kept live,
    /// the block `gap_blocks` back enters it and blocks older than the window leave it.
    fn close_block(&mut self) {
        self.maxima[self.ring_head] = self.block_max;
        self.ring_head = wrap(self.ring_head + 1, self.maxima.len());
        self.block_index += 1;
        self.block_max = 0.0;
        self.block_fill = 0;
        if !self.live {
            return;
        }
        let gap = self.gap_blocks as u64;
        if let Some(k) = (self.block_index - 1).checked_sub(gap) {
            self.enter_window(k);
        }
        let oldest = self
            .block_index
            .saturating_sub((self.gap_blocks + self.window_blocks) as u64);
        while self.queue.front().is_some_and(|&(k, _)| k < oldest) {
            self.queue.pop_front();
        }
        self.threshold = self.jump * self.queue.front().map_or(0.0, |&(_, m)| m);
    }

    /// `jump` × the window's maximum for the current block (the window rebuilt if not live).
    fn current_threshold(&mut self) -> f64 {
        if !self.live {
            self.queue.clear();
            let b = self.block_index;
            let window_end = b.saturating_sub(self.gap_blocks as u64);
            let window_start = b.saturating_sub((self.gap_blocks + self.window_blocks) as u64);
            for k in window_start..window_end {
                self.enter_window(k);
            }
            self.threshold = self.jump * self.queue.front().map_or(0.0, |&(_, m)| m);
            self.live = true;
        }
        self.threshold
    }

    /// Takes `samples` of which none can be a hit (all within the grace period, or all below
    /// the level): only the block maxima a later window can reach are kept, and the window is
    /// rebuilt when next needed.
    fn absorb(&mut self, samples: &[f64]) {
        self.live = false;
        let mut rest = samples;
        // The rest of the current block.
        let first = (self.block - self.block_fill).min(rest.len());
        let head = super::sample_scan::max_abs_finite(self.isa, &rest[..first]);
        self.block_max = self.block_max.max(head);
        self.block_fill += first;
        self.seen += first as u64;
        rest = &rest[first..];
        if self.block_fill < self.block {
            // All of it went into the current block.
            return;
        }
        self.close_block();
        // Whole blocks: those older than the ring's reach are counted, not scanned; the others
        // closed as `close_block` closes them while the window is not live (into the ring).
        let n = rest.len() / self.block;
        let skipped = n.saturating_sub(self.maxima.len());
        let (whole, tail) = rest[skipped * self.block..].split_at((n - skipped) * self.block);
        rest = tail;
        self.block_index += n as u64;
        self.seen += (n * self.block) as u64;
        let (isa, head) = (self.isa, self.ring_head);
        self.ring_head = block_maxima_into_ring(isa, whole, self.block, &mut self.maxima, head);
        // The start of the next block.
        self.block_max = super::sample_scan::max_abs_finite(self.isa, rest);
        self.block_fill = rest.len();
        self.seen += rest.len() as u64;
    }

    /// Scans `samples`; returns the index of the first one that is a new hit (it and the rest
    /// are not consumed), or `None` when all were consumed.
    pub fn scan(&mut self, samples: &[f64]) -> Option<usize> {
        if !self.jump.is_finite() {
            // Splitting off: nothing to watch.
            return None;
        }
        // A stretch wholly within the grace period or below the level holds no hit.
        let in_grace = self.seen + samples.len() as u64 <= self.grace;
        if in_grace || super::sample_scan::max_abs_finite(self.isa, samples) < self.level {
            self.absorb(samples);
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
            if in_grace || piece_max < self.level || piece_max < self.current_threshold() {
                self.block_max = self.block_max.max(piece_max);
                self.seen += take as u64;
                self.block_fill += take;
            } else {
                let threshold = self.current_threshold();
                for (i, &x) in piece.iter().enumerate() {
                    let a = if x.is_finite() { x.abs() } else { 0.0 };
                    if a >= self.level && a >= threshold && self.seen >= self.grace {
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

    /// The watch's criterion, directly: sample i (block j = i / block) is a hit when i is past
    /// the grace period and |x_i| is at least the level and `jump` × the largest |x| of blocks
    /// j − gap − window … j − gap − 1 (non-finite samples count as 0).
    fn first_hit_direct(w: &RetriggerWatch, x: &[f64], level: f64, grace: usize) -> Option<usize> {
        let grace = grace.max((w.window_blocks + w.gap_blocks + 1) * w.block);
        let mag = |v: f64| if v.is_finite() { v.abs() } else { 0.0 };
        (0..x.len()).find(|&i| {
            let j = i / w.block;
            let hi = j.saturating_sub(w.gap_blocks) * w.block;
            let lo = j.saturating_sub(w.gap_blocks + w.window_blocks) * w.block;
            let window_max = x[lo..hi.min(x.len())]
                .iter()
                .fold(0.0f64, |m, &v| m.max(mag(v)));
            i >= grace && mag(x[i]) >= level && mag(x[i]) >= w.jump * window_max
        })
    }

    /// The streaming watch (a window kept block by block, quiet stretches only counted) finds
    /// the sample the direct criterion finds, whatever the chunks it is fed in: decaying noise
    /// with bursts of every size and bumps just below the level, levels above and below the
    /// tail, grace periods, short and long gaps.
    #[test]
    fn retrigger_watch_equals_the_direct_criterion() {
        let mut state = 99u64;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut hits = 0;
        for case in 0..80 {
            let n = 3000 + 97 * case;
            let mut x: Vec<f64> = (0..n)
                .map(|i| uniform() * (-(i as f64) / 400.0).exp())
                .collect();
            let (window, gap) = [(400, 10), (40, 3), (100, 0), (9, 80)][case % 4];
            let level = [1e-3, 0.01, 0.05, 0.0][(case / 4) % 4];
            let grace = [0, 100, 1500][case % 3];
            if case % 3 != 0 {
                // A bump just below the level, then a burst of some size after it.
                let bump = 300 + (case * 211) % (n - 900);
                x[bump] = 0.9 * level;
                let at = bump + 20 + (case * 131) % 500;
                let size = [0.02, 0.1, 0.5, 2.0, 1.2 * level, 2.0 * level][case % 6];
                for k in 0..40 {
                    x[at + k] += size * (uniform() + 0.6) * (-(k as f64) / 10.0).exp();
                }
            }
            if case % 7 == 0 {
                x[n / 2] = f64::NAN;
            }
            let direct =
                first_hit_direct(&RetriggerWatch::new(window, gap, 10.0), &x, level, grace);
            hits += usize::from(direct.is_some());
            for chunk in [1, 7, 64, 333, 1024, n] {
                let mut w = RetriggerWatch::new(window, gap, 10.0);
                w.restart(level, grace);
                let mut found = None;
                for (b, piece) in x.chunks(chunk).enumerate() {
                    if let Some(i) = w.scan(piece) {
                        found = Some(b * chunk + i);
                        break;
                    }
                }
                assert_eq!(found, direct, "case {case} chunk {chunk}");
            }
        }
        // Both outcomes are exercised.
        assert!((10..70).contains(&hits), "{hits} of 80 cases hit");
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

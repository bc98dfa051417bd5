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
        }
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

    /// Moves the stream position forward by `n` samples that bypassed the detector.
    pub fn advance(&mut self, n: usize) {
        self.position += n as u64;
    }

    /// Absolute index of the next sample.
    pub fn position(&self) -> u64 {
        self.position
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
        let peak = self.peak;
        self.rearm(self.arm_threshold);
        OnsetEvent::Found {
            onset_index,
            samples,
            consumed,
            peak,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> OnsetSettings {
        OnsetSettings {
            level_db: 20.0,
            lookahead_samples: 50,
            max_buffer_samples: 10_000,
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

    #[test]
    fn silence_has_no_onset() {
        assert_eq!(find_onset(&[0.0; 10], 20.0), None);
        let mut det = OnsetDetector::new(settings(), 0.0);
        assert_eq!(det.push(&[0.0; 10]), OnsetEvent::Pending);
        assert_eq!(det.finish(), OnsetEvent::Pending);
    }
}

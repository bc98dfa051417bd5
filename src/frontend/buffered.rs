//! What the two buffering filter banks (Goyder, octave) share: the time direction of their
//! filters and the buffer that holds a whole decay so that it can be filtered backwards.
//!
//! Filtering the time-reversed decay preserves its decay rate where a causal filter's ringing
//! would smear it (Jacobsen & Rindel 1987); the price is that the whole decay must be held.
//! [`DecayBuffer`] holds it, bounded: samples past its capacity are dropped and the decay is
//! marked as overflowed (`decay_too_long`), so that memory never grows with the input.

/// In which time direction a band filter runs over the decay.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FilterDirection {
    /// Causal filtering in recording order: the filter's ringing smears the early decay
    /// (biased when B·T60 ≲ 16).
    Forward,
    /// Filtering the time-reversed decay and reversing back: the decay rate is preserved.
    /// The default of both banks.
    #[default]
    Reversed,
}

/// Samples a buffer reserves when it first receives some (2 MiB, address space only until
/// written): a decay that grew by doubling was copied at every step, and the copies faulted in
/// twice the memory it ended with (`memmove` and its page faults were 10 % of a 64-channel,
/// 10 s octave-bank run at 4096 Hz).
const RESERVED_SAMPLES: usize = 1 << 18;

/// One decay's samples, held whole (up to a capacity) for filtering backwards.
#[derive(Clone, Debug, Default)]
pub(crate) struct DecayBuffer {
    samples: Vec<f64>,
    capacity: usize,
    overflowed: bool,
}

impl DecayBuffer {
    /// An empty buffer that holds at most `capacity` samples.
    pub(crate) fn new(capacity: usize) -> Self {
        DecayBuffer {
            samples: Vec::new(),
            capacity,
            overflowed: false,
        }
    }

    /// Starts a decay with the last `len` samples before its onset (`pre_roll`, oldest first),
    /// zeros in front where fewer are given (a record that starts at its onset): a backward
    /// filter's output before the onset is what is kept, not the input there.
    pub(crate) fn start_with_pre_roll(&mut self, pre_roll: &[f64], len: usize) {
        self.samples.clear();
        self.reserve_first();
        let from = pre_roll.len().saturating_sub(len);
        let given = pre_roll.len() - from;
        self.samples.resize(len - given, 0.0);
        self.push(&pre_roll[from..]);
    }

    /// Appends samples; those past the capacity are dropped and the decay marked overflowed.
    pub(crate) fn push(&mut self, samples: &[f64]) {
        self.reserve_first();
        let room = self.capacity.saturating_sub(self.samples.len());
        self.samples
            .extend_from_slice(&samples[..samples.len().min(room)]);
        self.overflowed |= samples.len() > room;
    }

    /// Reserves [`RESERVED_SAMPLES`] (at most the capacity) the first time samples come.
    fn reserve_first(&mut self) {
        if self.samples.capacity() == 0 {
            self.samples
                .reserve_exact(self.capacity.min(RESERVED_SAMPLES));
        }
    }

    /// The samples held, oldest first.
    pub(crate) fn samples(&self) -> &[f64] {
        &self.samples
    }

    /// Takes the samples out (to filter them while the bank's own state changes); hand the
    /// allocation back with [`DecayBuffer::give_back`].
    pub(crate) fn take(&mut self) -> Vec<f64> {
        std::mem::take(&mut self.samples)
    }

    /// Returns a taken allocation, emptied, for the next decay.
    pub(crate) fn give_back(&mut self, mut samples: Vec<f64>) {
        samples.clear();
        self.samples = samples;
    }

    /// Empties the buffer for the next decay (its allocation is kept); the overflow mark stays
    /// until [`DecayBuffer::reset`], so that the decay's rows can still be flagged.
    pub(crate) fn clear(&mut self) {
        self.samples.clear();
    }

    /// Empties the buffer and forgets the overflow.
    pub(crate) fn reset(&mut self) {
        self.samples.clear();
        self.overflowed = false;
    }

    /// True when the current decay had more samples than the capacity.
    pub(crate) fn overflowed(&self) -> bool {
        self.overflowed
    }

    /// Bytes the buffer takes when full.
    pub(crate) fn capacity_bytes(&self) -> usize {
        self.capacity.saturating_mul(std::mem::size_of::<f64>())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_at_most_its_capacity_and_says_so() {
        let mut b = DecayBuffer::new(5);
        b.push(&[1.0, 2.0, 3.0]);
        assert!(!b.overflowed());
        b.push(&[4.0, 5.0, 6.0]);
        assert_eq!(b.samples(), &[1.0, 2.0, 3.0, 4.0, 5.0]);
        assert!(b.overflowed());
        b.clear();
        assert!(b.overflowed() && b.samples().is_empty());
        b.reset();
        assert!(!b.overflowed());
    }

    #[test]
    fn pre_roll_is_zero_padded_in_front() {
        let mut b = DecayBuffer::new(10);
        b.start_with_pre_roll(&[7.0], 3);
        assert_eq!(b.samples(), &[0.0, 0.0, 7.0]);
        b.start_with_pre_roll(&[1.0, 2.0, 3.0, 4.0], 3);
        assert_eq!(b.samples(), &[2.0, 3.0, 4.0]);
    }
}

//! What the two buffering filter banks (Goyder, octave) share: the time direction of their
//! filters and the buffer that holds a whole decay so that it can be filtered backwards.
//!
//! Filtering the time-reversed decay preserves its decay rate where a causal filter's ringing
//! would smear it (Jacobsen & Rindel 1987); the price is that the whole decay must be held.
//! `DecayBuffer` holds it, bounded: samples past its capacity are dropped and the decay is
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

/// Samples a buffer reserves when it first receives some (2 MiB of f64, address space only
/// until written), unless it takes a slot of this thread's decay arena
/// ([`super::decay_arena`]): a decay that grew by doubling was copied at every step, and the
/// copies faulted in twice the memory it ended with (`memmove` and its page faults were 10 % of
/// a 64-channel, 10 s octave-bank run at 4096 Hz).
const RESERVED_SAMPLES: usize = 1 << 18;

/// Single-precision samples: from the allocator, or a slot of this thread's decay arena (which
/// moves its samples to the allocator if it fills up).
#[derive(Debug)]
pub(crate) enum F32Buf {
    Heap(Vec<f32>),
    Arena(super::decay_arena::Slot),
}

impl Clone for F32Buf {
    /// A copy from the allocator (a slot is its owner's alone).
    fn clone(&self) -> Self {
        F32Buf::Heap(self.to_vec())
    }
}

impl std::ops::Deref for F32Buf {
    type Target = [f32];
    fn deref(&self) -> &[f32] {
        match self {
            F32Buf::Heap(v) => v,
            F32Buf::Arena(s) => s.as_slice(),
        }
    }
}

impl F32Buf {
    fn clear(&mut self) {
        match self {
            F32Buf::Heap(v) => v.clear(),
            F32Buf::Arena(s) => s.clear(),
        }
    }

    fn capacity(&self) -> usize {
        match self {
            F32Buf::Heap(v) => v.capacity(),
            F32Buf::Arena(s) => s.capacity(),
        }
    }

    /// Appends `xs` rounded to f32.
    fn extend_rounded(&mut self, xs: &[f64]) {
        match self {
            F32Buf::Heap(v) => {
                super::simd::in_wide_vectors(|| v.extend(xs.iter().map(|&x| x as f32)))
            }
            F32Buf::Arena(s) => {
                if !s.try_extend(xs) {
                    let mut v = Vec::with_capacity(2 * (s.as_slice().len() + xs.len()));
                    v.extend_from_slice(s.as_slice());
                    v.extend(xs.iter().map(|&x| x as f32));
                    *self = F32Buf::Heap(v);
                }
            }
        }
    }
}

/// A decay's samples as held: single precision while every sample so far is exactly an f32
/// (recordings in f32, 16- and 24-bit PCM), double otherwise. Half the memory for the usual
/// recordings: the buffers' page faults were a fifth of a 64-channel octave-bank run.
#[derive(Clone, Debug)]
pub(crate) enum DecaySamples {
    /// Every sample is exactly the f32 kept.
    Single(F32Buf),
    /// Samples as given.
    Double(Vec<f64>),
}

impl Default for DecaySamples {
    fn default() -> Self {
        DecaySamples::Single(F32Buf::Heap(Vec::new()))
    }
}

impl DecaySamples {
    /// Samples held.
    pub(crate) fn len(&self) -> usize {
        match self {
            DecaySamples::Single(v) => v.len(),
            DecaySamples::Double(v) => v.len(),
        }
    }

    /// Runs `f` with the samples as f64: the held ones, or (single precision) their values
    /// widened into memory this thread reuses for every decay.
    pub(crate) fn with_f64<R>(&self, f: impl FnOnce(&[f64]) -> R) -> R {
        thread_local! {
            static WIDENED: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        match self {
            DecaySamples::Double(v) => f(v),
            DecaySamples::Single(v) => super::with_thread_scratch(&WIDENED, |out| {
                out.clear();
                out.extend(v.iter().map(|&x| f64::from(x)));
                f(out)
            }),
        }
    }

    fn clear(&mut self) {
        match self {
            DecaySamples::Single(v) => v.clear(),
            DecaySamples::Double(v) => v.clear(),
        }
    }

    fn capacity(&self) -> usize {
        match self {
            DecaySamples::Single(v) => v.capacity(),
            DecaySamples::Double(v) => v.capacity(),
        }
    }

    /// Appends `xs`, in single precision while they are exact, switching to double (for good)
    /// at the first sample that is not.
    fn extend(&mut self, xs: &[f64], reserve: usize) {
        if let DecaySamples::Single(v) = self {
            let exact = extend_while_exact(v, xs);
            if exact == xs.len() {
                return;
            }
            let mut wide = Vec::with_capacity(reserve.max(v.len() + xs.len() - exact));
            wide.extend(v.iter().map(|&x| f64::from(x)));
            *self = DecaySamples::Double(wide);
            return self.extend(&xs[exact..], reserve);
        }
        if let DecaySamples::Double(v) = self {
            v.extend_from_slice(xs);
        }
    }
}

/// Samples checked for exactness at a time (a vectorised pass each).
const EXACT_CHUNK: usize = 64;

/// Appends the samples of `xs` as f32 up to the first one that is not exactly an f32; returns
/// how many were appended.
fn extend_while_exact(v: &mut F32Buf, xs: &[f64]) -> usize {
    let is_exact = |x: f64| f64::from(x as f32) == x;
    let mut done = 0;
    for chunk in xs.chunks(EXACT_CHUNK) {
        // Without a branch per sample, so that the pass vectorises.
        if !chunk.iter().fold(true, |all, &x| all & is_exact(x)) {
            let n = chunk
                .iter()
                .position(|&x| !is_exact(x))
                .unwrap_or(chunk.len());
            v.extend_rounded(&chunk[..n]);
            return done + n;
        }
        v.extend_rounded(chunk);
        done += chunk.len();
    }
    done
}

/// One decay's samples, held whole (up to a capacity) for filtering backwards.
#[derive(Clone, Debug, Default)]
pub(crate) struct DecayBuffer {
    samples: DecaySamples,
    capacity: usize,
    /// Samples a decay holds before the input's own (a pre-roll): sizes an arena slot.
    lead: usize,
    overflowed: bool,
}

impl DecayBuffer {
    /// An empty buffer that holds at most `capacity` samples.
    pub(crate) fn new(capacity: usize) -> Self {
        Self::with_lead(capacity, 0)
    }

    /// [`DecayBuffer::new`] for decays that start with `lead` samples from before the input's
    /// own (see [`DecayBuffer::start_with_pre_roll`]).
    pub(crate) fn with_lead(capacity: usize, lead: usize) -> Self {
        DecayBuffer {
            samples: DecaySamples::default(),
            capacity,
            lead,
            overflowed: false,
        }
    }

    /// Starts a decay with the last `len` samples before its onset (`pre_roll`, oldest first),
    /// zeros in front where fewer are given (a record that starts at its onset): a backward
    /// filter's output before the onset is what is kept, not the input there.
    pub(crate) fn start_with_pre_roll(&mut self, pre_roll: &[f64], len: usize) {
        const ZEROS: [f64; 256] = [0.0; 256];
        self.samples.clear();
        let from = pre_roll.len().saturating_sub(len);
        let mut zeros = len - (pre_roll.len() - from);
        while zeros > 0 {
            let n = zeros.min(ZEROS.len());
            self.push(&ZEROS[..n]);
            zeros -= n;
        }
        self.push(&pre_roll[from..]);
    }

    /// Appends samples; those past the capacity are dropped and the decay marked overflowed.
    pub(crate) fn push(&mut self, samples: &[f64]) {
        let reserve = self.capacity.min(RESERVED_SAMPLES);
        if self.samples.capacity() == 0 {
            // Reserved the first time samples come (see RESERVED_SAMPLES).
            match &mut self.samples {
                DecaySamples::Single(v) => {
                    *v = match super::decay_arena::take_slot(self.lead, self.capacity) {
                        Some(slot) => F32Buf::Arena(slot),
                        None => F32Buf::Heap(Vec::with_capacity(reserve)),
                    }
                }
                DecaySamples::Double(v) => v.reserve_exact(reserve),
            }
        }
        let room = self.capacity.saturating_sub(self.samples.len());
        self.samples
            .extend(&samples[..samples.len().min(room)], reserve);
        self.overflowed |= samples.len() > room;
    }

    /// Samples held.
    pub(crate) fn len(&self) -> usize {
        self.samples.len()
    }

    /// Takes the samples out (to filter them while the bank's own state changes); hand the
    /// allocation back with [`DecayBuffer::give_back`].
    pub(crate) fn take(&mut self) -> DecaySamples {
        std::mem::take(&mut self.samples)
    }

    /// Returns a taken allocation, emptied, for the next decay.
    pub(crate) fn give_back(&mut self, mut samples: DecaySamples) {
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

    /// Bytes the buffer takes when full (in double precision, the most it can take).
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
        assert_eq!(held(&b), &[1.0, 2.0, 3.0, 4.0, 5.0]);
        assert!(b.overflowed());
        b.clear();
        assert!(b.overflowed() && b.len() == 0);
        b.reset();
        assert!(!b.overflowed());
    }

    #[test]
    fn pre_roll_is_zero_padded_in_front() {
        let mut b = DecayBuffer::new(10);
        b.start_with_pre_roll(&[7.0], 3);
        assert_eq!(held(&b), &[0.0, 0.0, 7.0]);
        b.start_with_pre_roll(&[1.0, 2.0, 3.0, 4.0], 3);
        assert_eq!(held(&b), &[2.0, 3.0, 4.0]);
    }

    fn held(b: &DecayBuffer) -> Vec<f64> {
        b.samples.with_f64(|s| s.to_vec())
    }

    /// Samples come back bit for bit whatever they are: single precision holds them while
    /// each is exactly an f32 (f32 recordings, PCM), double from the first that is not, with
    /// the ones before it; a later decay of the same buffer stays in double.
    #[test]
    fn every_sample_comes_back_bit_for_bit() {
        let exact: Vec<f64> = (0..300)
            .map(|i| f64::from((i as f32 * 0.37).sin() * 0.8))
            .chain([
                0.0,
                -0.0,
                f64::from(f32::MAX),
                f64::from(f32::MIN_POSITIVE),
                f64::INFINITY,
            ])
            .collect();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for odd in [0.1, 1e-300, 1e300, f64::NAN, 1.0 + f64::EPSILON] {
            for at in [0, 1, 63, 64, 65, 200, 305] {
                let mut b = DecayBuffer::new(10_000);
                let mut want = exact.clone();
                want.insert(at, odd);
                // In pieces of 7, so that the switch can come in the middle of a push.
                for piece in want.chunks(7) {
                    b.push(piece);
                }
                assert!(
                    matches!(b.samples, DecaySamples::Double(_)),
                    "{odd} at {at}"
                );
                assert_eq!(bits(&held(&b)), bits(&want), "{odd} at {at}");
                b.clear();
                b.push(&exact);
                assert!(matches!(b.samples, DecaySamples::Double(_)));
                assert_eq!(bits(&held(&b)), bits(&exact));
            }
        }
        let mut b = DecayBuffer::new(10_000);
        b.push(&exact);
        assert!(matches!(b.samples, DecaySamples::Single(_)));
        assert_eq!(bits(&held(&b)), bits(&exact));
        // Taken out and given back, it is an empty buffer of the same precision.
        let taken = b.take();
        assert_eq!(taken.with_f64(|s| bits(s)), bits(&exact));
        b.give_back(taken);
        assert_eq!(b.len(), 0);
    }

    /// A decay in an arena slot keeps every sample, in order, when it outgrows its slot (moved
    /// to the allocator) and when a sample that is not an f32 arrives (switched to f64); the
    /// same as without an arena.
    #[test]
    fn a_slot_that_fills_up_or_meets_a_double_loses_nothing() {
        let frames = 600_000;
        let samples: Vec<f64> = (0..frames + 50_000)
            .map(|k| (k % 977) as f64 * 0.25)
            .collect();
        let mut with_double = samples.clone();
        with_double[1000] = 0.1; // not exactly an f32, while in the slot
        for (case, input) in [("outgrows", &samples), ("double", &with_double)] {
            let plain = {
                let mut b = DecayBuffer::with_lead(usize::MAX, 3);
                b.start_with_pre_roll(&[1.0, 2.0], 3);
                input.chunks(4096).for_each(|c| b.push(c));
                held(&b)
            };
            let _arena = super::super::decay_arena::install(1, Some(frames));
            let mut b = DecayBuffer::with_lead(usize::MAX, 3);
            b.start_with_pre_roll(&[1.0, 2.0], 3);
            assert!(
                !cfg!(target_os = "linux")
                    || matches!(b.samples, DecaySamples::Single(F32Buf::Arena(_))),
                "{case}: the decay starts in a slot"
            );
            input.chunks(4096).for_each(|c| b.push(c));
            assert_eq!(held(&b), plain, "{case}");
            assert_eq!(plain.len(), 3 + input.len());
            assert!(
                !matches!(b.samples, DecaySamples::Single(F32Buf::Arena(_))),
                "{case}"
            );
        }
    }
}

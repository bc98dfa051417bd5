//! The blocks between the reader and the workers: how many a worker's queue holds, and the
//! pool that reuses them once every worker is done, so that the hot path allocates nothing
//! once the pipeline is full.

use std::sync::Arc;

/// Bytes of decoded samples (8 a sample) a worker's queue holds: four default blocks of 64
/// channels (4096 frames). Larger blocks (front ends that look further ahead) queue fewer.
const QUEUE_BYTES: usize = 4 * 4096 * 64 * 8;

/// Blocks a worker's queue holds: as many as fit in [`QUEUE_BYTES`], one to four.
pub(super) fn queue_blocks(block_frames: usize, channels: usize) -> usize {
    (QUEUE_BYTES
        / block_frames
            .saturating_mul(channels.saturating_mul(8))
            .max(1))
    .clamp(1, 4)
}

/// Blocks alive at once at most: a worker's queue, the one it works on, the one read.
pub(super) fn blocks_in_flight(queue_blocks: usize) -> usize {
    queue_blocks + 2
}

/// The blocks a reader hands out, each reused once every worker is done with it, so that the
/// hot path allocates nothing once the pipeline is full (a fresh block of a 64-channel stream
/// is megabytes of new pages to fault in).
pub(super) struct BlockPool<T> {
    handed_out: Vec<Arc<T>>,
    /// The most blocks alive at once ([`blocks_in_flight`]).
    in_flight: usize,
}

impl<T: Default> BlockPool<T> {
    pub(super) fn new(in_flight: usize) -> Self {
        BlockPool {
            handed_out: Vec::new(),
            in_flight,
        }
    }

    /// A block no worker holds any more, or a new one.
    pub(super) fn take(&mut self) -> T {
        match self
            .handed_out
            .iter()
            .position(|b| Arc::strong_count(b) == 1)
        {
            // Only the reader holds pool handles, so a free block stays free.
            Some(i) => Arc::try_unwrap(self.handed_out.swap_remove(i)).unwrap_or_default(),
            None => T::default(),
        }
    }

    /// Remembers a block handed out, to reuse once it is free.
    pub(super) fn keep(&mut self, block: Arc<T>) {
        self.handed_out.push(block);
        if self.handed_out.len() > self.in_flight {
            // More alive than the queues can hold: forget one handle (its memory goes when the
            // workers drop it).
            self.handed_out.remove(0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Default blocks of 64 channels queue four deep; the 26 216-frame blocks of a 64-channel
    /// 65536 Hz STFT (13 MB decoded) one, so that a stream's copied blocks stay within the
    /// memory of the mapped run; never none.
    #[test]
    fn large_blocks_queue_fewer() {
        assert_eq!(queue_blocks(4096, 64), 4);
        assert_eq!(queue_blocks(4096, 1), 4);
        assert_eq!(queue_blocks(8192, 64), 2);
        assert_eq!(queue_blocks(4 * 6554, 64), 1);
        assert_eq!(queue_blocks(usize::MAX, usize::MAX), 1);
        assert_eq!(blocks_in_flight(1), 3);
    }
}

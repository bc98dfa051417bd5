//! Rows in a fixed order whatever the thread timing: by stream position (the decay's onset
//! sample), then channel index, then band, released as soon as no channel can still produce a
//! row that sorts before them.
//!
//! Each channel reports a watermark: the smallest position any row it may still produce can
//! carry (the onset of its open decay, where its onset search armed, or how far it has read).
//! Rows below the smallest watermark of all channels are final in order and leave at once, so
//! the latency is that of the slowest channel on the same hit, not the end of the input.

use std::collections::BTreeMap;

use super::ResultRow;

/// The reorder buffer between the workers and the caller.
pub(super) struct RowOrder {
    pending: BTreeMap<(u64, usize), Vec<ResultRow>>,
    watermarks: Vec<u64>,
}

impl RowOrder {
    /// A buffer for `channels` channels, none of which has read anything yet.
    pub(super) fn new(channels: usize) -> Self {
        RowOrder {
            pending: BTreeMap::new(),
            watermarks: vec![0; channels],
        }
    }

    /// Takes channel `channel`'s rows (all with the same position, bands in order).
    pub(super) fn add(&mut self, channel: usize, rows: Vec<ResultRow>) {
        if let Some(first) = rows.first() {
            self.pending
                .entry((first.position_sample, channel))
                .or_default()
                .extend(rows);
        }
    }

    /// Channel `channel` will produce no row below `position` from now on.
    pub(super) fn advance(&mut self, channel: usize, position: u64) {
        self.watermarks[channel] = position;
    }

    /// The rows that can no longer be preceded by another, in order.
    pub(super) fn release(&mut self) -> Vec<ResultRow> {
        let low = self.watermarks.iter().copied().min().unwrap_or(u64::MAX);
        let later = self.pending.split_off(&(low, 0));
        let ready = std::mem::replace(&mut self.pending, later);
        ready.into_values().flatten().collect()
    }

    /// Everything left, in order (all channels finished).
    pub(super) fn drain(&mut self) -> Vec<ResultRow> {
        std::mem::take(&mut self.pending)
            .into_values()
            .flatten()
            .collect()
    }
}

//! Rows in a fixed order whatever the thread timing: by stream position (the decay's onset
//! sample), then channel index, then band, released as soon as no channel can still produce a
//! row that sorts before them.
//!
//! Each channel reports a watermark: the smallest position any row it may still produce can
//! carry (the onset of its open decay, where its onset search armed, or how far it has read).
//! Channel c at watermark w can still give rows sorting from (w, c) on, so the rows sorting
//! below the least such (w, c) of all channels are final in order and leave at once: the
//! latency is that of the slowest lower channel on the same hit, not the end of the input.
//! (With the least watermark alone, rows at one position waited for every channel: at the end
//! of an input whose channels all hold one decay from the start, no row left until the last
//! channel was finished.)

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
        // The least key a row still to come can have.
        let low = self
            .watermarks
            .iter()
            .enumerate()
            .map(|(c, &w)| (w, c))
            .min()
            .unwrap_or((u64::MAX, 0));
        let later = self.pending.split_off(&low);
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

#[cfg(test)]
mod tests {
    use super::RowOrder;
    use crate::pipeline::ResultRow;

    /// A row of `channel` at `position`, told apart by `decay`.
    fn row(channel: usize, position: u64, decay: usize) -> ResultRow {
        ResultRow {
            channel: format!("ch{channel}"),
            position_sample: position,
            decay,
            onset_s: None,
            front_end: "test",
            band: crate::frontend::Band::new(1.0, 2.0).unwrap(),
            range: crate::decay::EvaluationRange::T30,
            estimate: Default::default(),
        }
    }

    fn keys(rows: &[ResultRow]) -> Vec<(u64, String, usize)> {
        rows.iter()
            .map(|r| (r.position_sample, r.channel.clone(), r.decay))
            .collect()
    }

    /// A finished channel's rows leave although a higher channel is still open at the same
    /// position (the end of an input whose channels all hold a decay from sample 0); the
    /// higher channel's rows wait for a lower open one, and an open channel's rows at its own
    /// watermark wait for it.
    #[test]
    fn rows_leave_when_only_higher_keys_can_follow() {
        let mut order = RowOrder::new(3);
        order.add(2, vec![row(2, 0, 0)]);
        order.advance(2, u64::MAX);
        assert!(
            order.release().is_empty(),
            "channels 0 and 1 may still give (0, 0), (0, 1)"
        );
        order.add(0, vec![row(0, 0, 0), row(0, 0, 1)]);
        assert!(order.release().is_empty(), "channel 0 may add to (0, 0)");
        order.advance(0, u64::MAX);
        assert_eq!(keys(&order.release()), keys(&[row(0, 0, 0), row(0, 0, 1)]));
        order.add(1, vec![row(1, 0, 0)]);
        order.advance(1, 100);
        assert_eq!(keys(&order.release()), keys(&[row(1, 0, 0), row(2, 0, 0)]));
        order.add(1, vec![row(1, 100, 1)]);
        assert!(order.release().is_empty());
        assert_eq!(keys(&order.drain()), keys(&[row(1, 100, 1)]));
    }

    /// Whatever the interleaving of three channels' rows and watermarks, the released rows
    /// followed by the drained ones are every row sorted by (position, channel), each
    /// channel's rows in the order given (a pseudo-random schedule, many seeds).
    #[test]
    fn released_rows_are_in_order_for_any_schedule() {
        for seed in 0..300u64 {
            let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
            let mut next = |n: u64| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state % n
            };
            let channels = 3;
            let mut order = RowOrder::new(channels);
            let mut watermark = vec![0u64; channels];
            let mut given: Vec<ResultRow> = Vec::new();
            let mut out: Vec<ResultRow> = Vec::new();
            let mut serial = 0;
            for _ in 0..40 {
                let c = next(channels as u64) as usize;
                if watermark[c] == u64::MAX {
                    continue;
                }
                match next(3) {
                    // Rows at or above the channel's watermark.
                    0 => {
                        let p = watermark[c] + next(3);
                        let rows: Vec<ResultRow> = (0..1 + next(2))
                            .map(|_| {
                                serial += 1;
                                row(c, p, serial)
                            })
                            .collect();
                        given.extend(rows.iter().cloned());
                        order.add(c, rows);
                    }
                    1 => watermark[c] += next(3),
                    _ => watermark[c] = u64::MAX,
                }
                if watermark[c] != u64::MAX {
                    // A channel gives no row below its last row's position.
                    let last = given
                        .iter()
                        .filter(|r| r.channel == format!("ch{c}"))
                        .map(|r| r.position_sample)
                        .max()
                        .unwrap_or(0);
                    watermark[c] = watermark[c].max(last);
                }
                order.advance(c, watermark[c]);
                out.extend(order.release());
            }
            out.extend(order.drain());
            let mut expected = given.clone();
            // A stable sort keeps each channel's rows in the order they were given.
            expected.sort_by_key(|r| {
                let c: usize = r.channel[2..].parse().unwrap();
                (r.position_sample, c)
            });
            assert_eq!(keys(&out), keys(&expected), "seed {seed}");
        }
    }
}

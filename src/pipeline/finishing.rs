//! The end of a run's input: every channel still open is finished (its decay filtered,
//! estimated, its rows made) by whichever worker is free.
//!
//! The buffered banks do most of their work there: each decay is filtered backwards, then
//! estimated. With each worker finishing its own half of the channels, one core sat idle while
//! the other finished (5–16 ms of a 100 ms octave-bank run, 64 channels at 4096 Hz). Rows do not
//! depend on the thread that finishes a channel, and go back in channel order
//! ([`super::order::RowOrder`]).

use crossbeam_channel::Sender;

use super::schema::StageTimes;
use super::threads::WorkerReport;
use super::{ChannelAnalyzer, ResultRow};
use crate::decay::Flag;

/// One channel whose input ended, waiting for a worker to finish it.
pub(super) struct FinishJob {
    pub(super) channel: usize,
    pub(super) analyzer: ChannelAnalyzer,
    /// The channel's analysis panicked before (it only reports what it has).
    pub(super) crashed: bool,
}

/// The channels whose input ended, finished by whichever worker is free (see the module),
/// lowest channel first.
///
/// Rows go out in channel order, so a channel's rows wait for every lower channel's. Taken in
/// the order the workers happened to deposit them (the second half's channels first when its
/// worker reached the end first), half of the rows waited for the last channel and were all
/// written after the workers were done (0.8–1.2 ms with one core idle, 64 channels at
/// 4096 Hz); lowest first, they go out while the others are finished.
#[derive(Default)]
pub(super) struct FinishQueue(std::sync::Mutex<std::collections::VecDeque<FinishJob>>);

impl FinishQueue {
    /// Adds channels to finish.
    pub(super) fn deposit(&self, jobs: impl IntoIterator<Item = FinishJob>) {
        // A poisoned lock (a panic while holding it) still holds valid jobs.
        let mut queue = self.0.lock().unwrap_or_else(|e| e.into_inner());
        queue.extend(jobs);
        queue.make_contiguous().sort_by_key(|job| job.channel);
    }

    /// The lowest channel waiting to be finished, if any.
    pub(super) fn pop(&self) -> Option<FinishJob> {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).pop_front()
    }
}

/// Runs `f` on `an`; a panic (a bug) marks the channel `crashed` and gives its
/// `internal_error` rows, and the channels sharing the worker go on.
pub(super) fn guarded(
    crashed: &mut bool,
    an: &mut ChannelAnalyzer,
    f: &dyn Fn(&mut ChannelAnalyzer, &mut Vec<ResultRow>),
) -> Vec<ResultRow> {
    use std::panic::{catch_unwind, AssertUnwindSafe};
    if *crashed {
        return Vec::new();
    }
    let mut local = Vec::new();
    if catch_unwind(AssertUnwindSafe(|| f(an, &mut local))).is_ok() {
        local
    } else {
        *crashed = true;
        an.fail_with(Flag::InternalError)
    }
}

/// Finishes queued channels until none is left, one report each; false once the rows can no
/// longer be sent (the run stopped).
pub(super) fn finish_queued(
    finishing: &FinishQueue,
    truncated: bool,
    row_tx: &Sender<WorkerReport>,
) -> bool {
    while let Some(mut job) = finishing.pop() {
        let t0 = std::time::Instant::now();
        let rows = guarded(&mut job.crashed, &mut job.analyzer, &|an, o| {
            an.finish(truncated, o)
        });
        let (segment_s, estimator_s) = job.analyzer.stage_seconds();
        let report = WorkerReport {
            rows: if rows.is_empty() {
                Vec::new()
            } else {
                vec![(job.channel, rows)]
            },
            // Finished (or crashed): nothing more comes from this channel.
            watermarks: vec![(job.channel, u64::MAX)],
            times: StageTimes {
                segment_s,
                estimator_s,
                analysis_s: t0.elapsed().as_secs_f64(),
                ..StageTimes::default()
            },
        };
        if row_tx.send(report).is_err() {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    /// Channels queued for their finish are each finished exactly once, whichever of two
    /// threads draining the queue takes them, with the rows the channel gives when finished
    /// alone; a crashed channel gives nothing more.
    #[test]
    fn queued_channels_are_finished_once_with_their_own_rows() {
        use super::{finish_queued, FinishJob, FinishQueue, WorkerReport};
        use crate::frontend::octave_bank::{OctaveBankFrontEnd, OctaveBankSettings};
        use crate::frontend::Band;
        use crate::pipeline::{AnalysisConfig, ChannelAnalyzer};
        let fs = 4096.0;
        let bands = [
            Band::new(44.67, 89.13).unwrap(),
            Band::new(89.13, 177.8).unwrap(),
        ];
        let analyzer = |c: usize| {
            let fe = OctaveBankFrontEnd::new(OctaveBankSettings::default(), fs, &bands).unwrap();
            let mut an = ChannelAnalyzer::new(
                format!("ch{c}"),
                fs,
                Box::new(fe),
                AnalysisConfig::default(),
            );
            // A decaying 60 + 20c Hz tone after a little silence, as long as the channel number
            // says (different work per channel).
            let f = 60.0 + 20.0 * (c % 5) as f64;
            let x: Vec<f64> = (0..4096 * (1 + c % 3))
                .map(|n| {
                    let t = n as f64 / fs;
                    if n < 100 {
                        0.0
                    } else {
                        (-3.0 * t).exp() * (2.0 * std::f64::consts::PI * f * t).sin()
                    }
                })
                .collect();
            let mut rows = Vec::new();
            an.push(&x, &mut rows);
            assert!(rows.is_empty());
            an
        };
        let channels = 9;
        let alone: Vec<_> = (0..channels)
            .map(|c| {
                let mut rows = Vec::new();
                analyzer(c).finish(false, &mut rows);
                rows
            })
            .collect();
        let queue = FinishQueue::default();
        queue.deposit((0..channels).map(|c| FinishJob {
            channel: c,
            analyzer: analyzer(c),
            crashed: c == 4,
        }));
        let (tx, rx) = crossbeam_channel::unbounded::<WorkerReport>();
        std::thread::scope(|scope| {
            for _ in 0..2 {
                let (queue, tx) = (&queue, tx.clone());
                scope.spawn(move || assert!(finish_queued(queue, false, &tx)));
            }
        });
        drop(tx);
        let mut seen = vec![0; channels];
        for report in rx.iter() {
            assert_eq!(report.watermarks.len(), 1);
            let (c, w) = report.watermarks[0];
            assert_eq!(w, u64::MAX);
            seen[c] += 1;
            let rows: Vec<_> = report
                .rows
                .into_iter()
                .flat_map(|(rc, r)| {
                    assert_eq!(rc, c);
                    r
                })
                .collect();
            if c == 4 {
                assert!(rows.is_empty(), "a crashed channel gives nothing more");
            } else {
                assert!(!rows.is_empty());
                assert_eq!(rows, alone[c], "channel {c}");
            }
        }
        assert_eq!(seen, vec![1; channels]);
        assert!(queue.pop().is_none());
    }
}

//! Segmentation: where, in one channel's stream, decays start and end.
//!
//! A decay starts at its onset (the first sample within `onset_level_db` of its peak,
//! [`onset`]); it ends when every band fell `end_drop_db` below its peak, after `max_decay_s`,
//! when a new hit comes (a sample `retrigger_jump_db` above the signal before it), or with the
//! input, or once it has sat on its noise floor long enough to place it (`floor_min_s`). After a
//! decay, a sample within `retrigger_db` of its peak starts the next one.

pub mod double_hit;
pub mod onset;
pub(crate) mod sample_scan;

use crate::error::{Error, Result};

/// How decays are found in a stream.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Segmentation {
    /// Onset: first sample within this many dB of the peak ([`DEFAULT_ONSET_LEVEL_DB`]).
    pub onset_level_db: f64,
    /// Onset: the peak is settled after this long without a larger sample, s
    /// ([`DEFAULT_ONSET_LOOKAHEAD_S`]).
    pub onset_lookahead_s: f64,
    /// A decay ends after this long, s (`None`: at the end of the input, or by `end_drop_db`).
    pub max_decay_s: Option<f64>,
    /// A decay ends when every band's energy is this far below its peak, dB
    /// ([`DEFAULT_END_DROP_DB`]).
    pub end_drop_db: f64,
    /// After a decay, a new one starts at a sample within this many dB of the last peak
    /// ([`DEFAULT_RETRIGGER_DB`]).
    pub retrigger_db: f64,
    /// During a decay, a sample that high and this many dB above the preceding signal (before
    /// its rise) is a new hit: the decay ends there and a new one starts
    /// ([`DEFAULT_RETRIGGER_JUMP_DB`]; infinity never splits).
    pub retrigger_jump_db: f64,
    /// A decay also ends once it is at least this old, s, and every band has sat on a floor
    /// for the last half of it (the level of its last quarter not more than `floor_flat_db`
    /// below that of the quarter before): a noise floor long enough for the estimator to place
    /// it ([`DEFAULT_FLOOR_MIN_S`]; infinity: never). Bounds memory on a stream of sparse hits
    /// over a noise floor, where `end_drop_db` is never reached.
    pub floor_min_s: f64,
    /// How flat a floor is, dB ([`DEFAULT_FLOOR_FLAT_DB`]).
    pub floor_flat_db: f64,
    /// A pause of the writer ends every open decay, as the end of the input would: nothing
    /// arrived on a watched stream (standard input, a named pipe) for
    /// [`crate::source::STREAM_PAUSE_MS`]. For a client that sends one record and waits for its
    /// rows: with noise no band falls `end_drop_db`, and a record is far shorter than
    /// `floor_min_s`, so its decay would stay open until the next hit or the end of the input.
    /// Off by default: a writer that merely stalls would have its decay cut there, and the
    /// rows would depend on the writer's timing.
    #[serde(default)]
    pub pause_ends_decays: bool,
}

/// Default of [`Segmentation::onset_level_db`]: a decay starts at its first sample within
/// 20 dB of its peak.
pub const DEFAULT_ONSET_LEVEL_DB: f64 = 20.0;

/// Default of [`Segmentation::onset_lookahead_s`]: the peak is settled after 0.1 s.
pub const DEFAULT_ONSET_LOOKAHEAD_S: f64 = 0.1;

/// Default of [`Segmentation::end_drop_db`]: a decay ends once every band fell 100 dB.
pub const DEFAULT_END_DROP_DB: f64 = 100.0;

/// Default of [`Segmentation::retrigger_db`]: a new decay starts within 20 dB of the last peak.
pub const DEFAULT_RETRIGGER_DB: f64 = 20.0;

/// Default of [`Segmentation::retrigger_jump_db`]: 10 dB. A decaying sum of modes cannot rise
/// that fast whatever its beating (see [`onset::RetriggerWatch`]), and white noise would need a
/// 12σ sample; hits 4 s apart over a −60 dB floor, merged before, are split.
pub const DEFAULT_RETRIGGER_JUMP_DB: f64 = 10.0;

/// Default of [`Segmentation::floor_min_s`]: 20 s. A decay whose every band is flat over the
/// second half of 20 s has a T60 beyond 15 · 10 s / `floor_flat_db` = 150 s or is on its floor;
/// records shorter than this (every impulse response in the tests) end with the input as before.
pub const DEFAULT_FLOOR_MIN_S: f64 = 20.0;

/// Default of [`Segmentation::floor_flat_db`]: the last quarter of the decay at most 1 dB below
/// the quarter before. A decay falls 15 t / T60 dB between those quarters at age t; noise
/// averaged over a quarter of ≥ 20 s fluctuates by a few tenths of a dB.
pub const DEFAULT_FLOOR_FLAT_DB: f64 = 1.0;

/// Lowest frequency whose rise time (a quarter period) sets the new-hit test's gap, Hz.
pub(crate) const RETRIGGER_MIN_FREQUENCY_HZ: f64 = 5.0;

impl Default for Segmentation {
    fn default() -> Self {
        Segmentation {
            onset_level_db: DEFAULT_ONSET_LEVEL_DB,
            onset_lookahead_s: DEFAULT_ONSET_LOOKAHEAD_S,
            max_decay_s: None,
            end_drop_db: DEFAULT_END_DROP_DB,
            retrigger_db: DEFAULT_RETRIGGER_DB,
            retrigger_jump_db: DEFAULT_RETRIGGER_JUMP_DB,
            floor_min_s: DEFAULT_FLOOR_MIN_S,
            floor_flat_db: DEFAULT_FLOOR_FLAT_DB,
            pause_ends_decays: false,
        }
    }
}

impl Segmentation {
    /// Checks the settings; an error names the field.
    pub fn validate(&self) -> Result<()> {
        if let Some(s) = self.max_decay_s {
            if s.is_nan() || s <= 0.0 {
                return Err(Error::setting(
                    "max_decay_s",
                    format!("expected > 0, got {s}"),
                ));
            }
        }
        if self.floor_min_s.is_nan() || self.floor_min_s <= 0.0 {
            return Err(Error::setting(
                "floor_min_s",
                format!("expected > 0 s (inf: never), got {}", self.floor_min_s),
            ));
        }
        if !(self.floor_flat_db.is_finite() && self.floor_flat_db >= 0.0) {
            return Err(Error::setting(
                "floor_flat_db",
                format!(
                    "expected a finite level >= 0 dB, got {}",
                    self.floor_flat_db
                ),
            ));
        }
        if self.retrigger_jump_db.is_nan() || self.retrigger_jump_db <= 0.0 {
            return Err(Error::setting(
                "retrigger_jump_db",
                format!("expected > 0 dB, got {}", self.retrigger_jump_db),
            ));
        }
        for (name, v) in [
            ("onset_level_db", self.onset_level_db),
            ("end_drop_db", self.end_drop_db),
            ("retrigger_db", self.retrigger_db),
        ] {
            if v.is_nan() || v < 0.0 {
                return Err(Error::setting(name, format!("expected >= 0 dB, got {v}")));
            }
        }
        if !(self.onset_lookahead_s.is_finite() && self.onset_lookahead_s >= 0.0) {
            return Err(Error::setting(
                "onset_lookahead_s",
                format!(
                    "expected a finite time >= 0, got {}",
                    self.onset_lookahead_s
                ),
            ));
        }
        Ok(())
    }
}

//! Front ends: one channel's samples → per band, a sequence of energy values at a frame rate.
//!
//! Every front end is streaming and stateful: [`FrontEnd::process`] may be called with blocks of
//! any size; completed frames are handed to a sink as they become available. One front end
//! instance serves one channel and one decay at a time; [`FrontEnd::reset`] prepares it for the
//! next decay.

pub mod auto_bands;
pub mod bands;
pub mod goyder;
pub mod iec_bands;
pub mod octave_bank;
pub mod onset;
pub mod stft;

pub use bands::Band;

/// How finely a front end resolves time and frequency, for side-by-side comparisons.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Resolution {
    /// Time between successive energy values, in seconds.
    pub frame_period_s: f64,
    /// Length of the time span that one energy value summarises, in seconds
    /// (STFT: the window; filter bank: about 1/B).
    pub time_resolution_s: f64,
    /// Frequency resolution in Hz (STFT: bin spacing; filter bank: bandwidth).
    pub frequency_resolution_hz: f64,
}

/// One frame of output: per band, the energy and the frequency actually present.
///
/// Both slices have one entry per band, in the order of [`FrontEnd::bands`].
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    /// Band energy of this frame (arbitrary but consistent units, e.g. Σ|X|² over the band).
    pub energy: &'a [f64],
    /// Dominant frequency in the band during this frame, in Hz; `NaN` when unknown.
    pub frequency_hz: &'a [f64],
    /// Which bands this frame holds (`None`: all). A filter bank's narrow bands end earlier
    /// than its wide ones (their start-up transient occupies more of the record's end); their
    /// entries past that point are not part of the decay and must be skipped.
    pub active: Option<&'a [bool]>,
}

/// Receives frames from a front end as they are completed.
pub trait FrameSink {
    /// Called once per completed frame, in time order.
    fn frame(&mut self, frame: Frame<'_>);
}

impl<F: FnMut(Frame<'_>)> FrameSink for F {
    fn frame(&mut self, frame: Frame<'_>) {
        self(frame)
    }
}

/// Turns one channel's samples (starting at a decay onset) into band energies per frame.
pub trait FrontEnd: Send {
    /// The bands this front end produces, in output order.
    fn bands(&self) -> &[Band];

    /// Time and frequency resolution of this front end.
    fn resolution(&self) -> Resolution;

    /// Feeds samples of the current decay. Completed frames go to `sink` in time order.
    fn process(&mut self, samples: &[f64], sink: &mut dyn FrameSink);

    /// Ends the current decay: emits whatever frames remain (a filter bank that needs the whole
    /// decay emits everything here).
    fn finish(&mut self, sink: &mut dyn FrameSink);

    /// Forgets the current decay so that the next call to `process` starts a new one.
    fn reset(&mut self);

    /// True when the current decay outlasted what the front end buffers, so that only its
    /// first part was analysed (the rows then carry `decay_too_long`). Streaming front ends
    /// never are.
    fn decay_cut_short(&self) -> bool {
        false
    }

    /// A short name for tables and logs (`stft`, `goyder`, `octave`).
    fn name(&self) -> &'static str;
}

/// Checks the settings that the buffering filter banks (Goyder, octave) share: frame period in ms
/// (> 0), the transient cut factor (≥ 0) and the longest decay buffered in s (1/fs to 1e10/fs).
/// `bank` names the bank in the error.
pub(crate) fn check_bank_settings(
    bank: &str,
    sample_rate_hz: f64,
    frame_period_ms: f64,
    cut_factor: f64,
    max_decay_s: f64,
) -> crate::error::Result<()> {
    use crate::error::Error;
    if !(frame_period_ms.is_finite() && frame_period_ms > 0.0) {
        return Err(Error::setting(
            format!("{bank} frame period"),
            format!("expected a positive number of ms, got {frame_period_ms}"),
        ));
    }
    if !(cut_factor.is_finite() && cut_factor >= 0.0) {
        return Err(Error::setting(
            format!("{bank} cut factor"),
            format!("expected a finite number >= 0, got {cut_factor}"),
        ));
    }
    if !(1.0..1e10).contains(&(max_decay_s * sample_rate_hz)) {
        return Err(Error::setting(
            format!("{bank} max decay"),
            format!("expected 1/fs to 1e10/fs seconds, got {max_decay_s} s"),
        ));
    }
    Ok(())
}

/// Resolution of a filter bank with frames `hop` samples apart: its time resolution is about
/// 1/B and its frequency resolution B for the narrowest band B.
pub(crate) fn bank_resolution(bands: &[Band], hop: usize, sample_rate_hz: f64) -> Resolution {
    let b_min = bands
        .iter()
        .map(|b| b.width_hz())
        .fold(f64::INFINITY, f64::min);
    Resolution {
        frame_period_s: hop as f64 / sample_rate_hz,
        time_resolution_s: 1.0 / b_min,
        frequency_resolution_hz: b_min,
    }
}

/// Appends `samples` to a decay buffer of at most `max_samples`; returns true when some did not
/// fit (the buffering banks then flag the decay as overflowed instead of growing without bound).
pub(crate) fn buffer_bounded(buffer: &mut Vec<f64>, max_samples: usize, samples: &[f64]) -> bool {
    let room = max_samples.saturating_sub(buffer.len());
    buffer.extend_from_slice(&samples[..samples.len().min(room)]);
    samples.len() > room
}

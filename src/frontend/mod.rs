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

    /// A short name for tables and logs (`stft`, `goyder`, `octave`).
    fn name(&self) -> &'static str;
}

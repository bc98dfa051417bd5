//! Sources: where decays come from.
//!
//! A [`Source`] yields blocks of multichannel samples (channel-major) and knows its sample rate
//! and channel names. It never holds a whole recording unless the format forces it, so that
//! standard input can be analysed while it still arrives.

/// Why a source could not deliver samples. Each variant says what was expected and what was found.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// Reading failed at the operating-system level.
    #[error("cannot read {what}: {source}")]
    Io {
        /// What was being read (a path, or "standard input").
        what: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The input is not in any format dampscope reads.
    #[error("{what}: not a recognised input ({detail})")]
    UnrecognisedFormat {
        /// What was being read.
        what: String,
        /// What was expected and what the first bytes looked like.
        detail: String,
    },
    /// The input is in a known format but broken.
    #[error("{what}: malformed {format} input: {detail}")]
    Malformed {
        /// What was being read.
        what: String,
        /// The format (wav, csv, raw, toml, json).
        format: &'static str,
        /// Expected vs found, with a line or byte position where known.
        detail: String,
    },
    /// The input ended before it was complete.
    #[error("{what}: input truncated: expected {expected}, got {got}")]
    Truncated {
        /// What was being read.
        what: String,
        /// What the header or frame size promised.
        expected: String,
        /// What arrived.
        got: String,
    },
    /// The number of channels does not match what another file or option says.
    #[error("{what}: expected {expected} channels, got {got}")]
    ChannelCount {
        /// What was being read.
        what: String,
        /// Channels expected.
        expected: usize,
        /// Channels found.
        got: usize,
    },
    /// A sample rate given as an option disagrees with the one the file's header states.
    #[error("{what}: the header says {header_hz} Hz but the given sample rate is {option_hz} Hz (give none: a WAV or recording set carries its own rate)")]
    SampleRateConflict {
        /// What was being read.
        what: String,
        /// Rate from the header, Hz.
        header_hz: f64,
        /// Rate from the option, Hz.
        option_hz: f64,
    },
    /// The input holds no samples at all.
    #[error("{what}: no samples")]
    Empty {
        /// What was being read.
        what: String,
    },
    /// Input past what one source reads was left unread (a second WAV file after the
    /// first): the decays read are whole, but part of the input was not analysed.
    #[error("{what}: {detail}")]
    LeftUnread {
        /// What was being read.
        what: String,
        /// What was left, and why.
        detail: String,
    },
    /// A required setting is missing or impossible (sample rate, channel count, …).
    #[error("{what}: {detail}")]
    Setting {
        /// What was being read.
        what: String,
        /// What is missing or wrong.
        detail: String,
    },
}

impl SourceError {
    /// Whether the error cut the decays in progress short (their rows get `input_truncated`):
    /// every error but input left unread after the source's end.
    pub fn cuts_decays_short(&self) -> bool {
        !matches!(self, SourceError::LeftUnread { .. })
    }
}

/// Sample rate and channel names of a source.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SignalInfo {
    /// Samples per second per channel.
    pub sample_rate_hz: f64,
    /// One name per channel (sensor ids for a recording set, `ch0`, `ch1`, … otherwise).
    pub channel_names: Vec<String>,
}

impl SignalInfo {
    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.channel_names.len()
    }
}

/// A block of samples, channel-major: `channels[c][i]` is sample i of channel c.
/// All channels hold the same number of samples.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Block {
    /// One vector of samples per channel.
    pub channels: Vec<Vec<f64>>,
    /// Per channel, `true` where the source that decoded this block saw that every one of its
    /// samples is finite (it checked while converting, at no extra pass); empty or `false`:
    /// not known, and the analysis checks the samples itself.
    pub known_finite: Vec<bool>,
}

impl Block {
    /// A block of these channels' samples, nothing known of their finiteness.
    pub fn new(channels: Vec<Vec<f64>>) -> Self {
        Block {
            channels,
            known_finite: Vec::new(),
        }
    }

    /// Number of sample frames (samples per channel) in the block.
    pub fn frames(&self) -> usize {
        self.channels.first().map_or(0, Vec::len)
    }

    /// Whether the source saw that every sample of channel `c` in this block is finite.
    pub fn is_known_finite(&self, c: usize) -> bool {
        self.known_finite.get(c).copied().unwrap_or(false)
    }
}

/// A stream of multichannel samples.
pub trait Source: Send {
    /// Sample rate and channel names.
    fn info(&self) -> &SignalInfo;

    /// Replaces the contents of `block` with up to `max_frames` sample frames.
    /// Returns `Ok(false)` (and an empty block) at the end of the input; a watched stream may
    /// return `Ok(true)` with no frames to tell a pause ([`Source::paused`]).
    fn read_block(&mut self, max_frames: usize, block: &mut Block) -> Result<bool, SourceError>;

    /// [`Source::read_block`] with the frames left in their stored encoding, for sources of
    /// interleaved binary frames (raw samples, WAV): each analysis thread then decodes only its
    /// own channels ([`encoded::EncodedFrames::decode_into`]), with the same values and flags.
    /// `None`: this source only decodes itself (call `read_block`).
    fn read_encoded_block(
        &mut self,
        _max_frames: usize,
        _out: &mut encoded::EncodedFrames,
    ) -> Option<Result<bool, SourceError>> {
        None
    }

    /// Sample frames the input holds in all, when its header or container says so (a WAV's
    /// data chunk, a file in memory); `None` for streams of unknown length.
    fn duration_frames(&self) -> Option<u64> {
        None
    }

    /// The step between two sample values the input can hold, in the units of its samples
    /// (a 16-bit WAV scaled to [−1, 1): 2⁻¹⁵; with a `scale` per count, that scale); `None`
    /// for float samples and text. Rounding to it adds noise of step² / 12 per sample, which
    /// an undithered recording of a quiet decay does not show as a floor
    /// ([`crate::decay::quantization`]).
    fn quantization_step(&self) -> Option<f64> {
        None
    }

    /// Sample frames the input is expected to hold, for laying out memory only (never checked
    /// against anything): [`Source::duration_frames`], or, for a raw file read through a
    /// mapping, its size.
    fn expected_frames(&self) -> Option<u64> {
        self.duration_frames()
    }

    /// Lets one read return up to `bytes` of stored frames. The binary sources cap a read at
    /// 1 MiB (4096 frames of 64 f32 channels), which bounds their memory; the pipeline raises
    /// the cap when its front end looks further ahead than such a block holds
    /// ([`crate::frontend::FrontEnd::lookahead_samples`]). Which frames are read does not
    /// change, only how many come at a time (a stream's read waits for as many); sources
    /// without a cap ignore it.
    fn allow_block_bytes(&mut self, bytes: usize) {
        let _ = bytes;
    }

    /// Whether the last read returned early because the writer paused: nothing arrived on a
    /// watched stream (standard input, a named pipe) for [`STREAM_PAUSE_MS`]. A pause is told
    /// once, with the frames that did arrive, or with an empty block (`Ok(true)`, no frames)
    /// when they had all been handed out. The pipeline passes it on to every channel
    /// ([`crate::pipeline::ChannelAnalyzer::pause`]). Always `false` for files and for sources
    /// that are not watched.
    fn paused(&self) -> bool {
        false
    }
}

// Implementations. Every source keeps the same error contract: all complete frames are delivered
// before a `Truncated` or `Malformed` error (the pipeline flushes partial results), a stream
// without a single frame is `Empty`, and a call may return fewer frames than asked (the binary
// sources do so only at the end, so that a stream's blocks are a mapped file's).
pub mod csv;
pub mod encoded;
mod frames;
pub mod frf;
pub mod frf_csv;
pub mod frf_input;
pub mod mapped;
pub mod memory;
pub mod noise;
pub mod open;
mod pipe;
pub mod raw;
pub mod recording_set;
pub mod synth;
pub mod wav;

pub use csv::CsvSource;
pub use open::{open_input, open_stream, InputOptions, OpenedInput};
pub use pipe::STREAM_PAUSE_MS;
pub use raw::{RawFormat, RawSource};
pub use recording_set::{
    open_recording_set, DecayKind, Excitation, RecordingMeta, RecordingSet, Sensor,
};
pub use synth::{synthesize, Mode, SynthSource, SynthSpec};
pub use wav::{WavHeader, WavSource};

/// What a source says when a read finds no more frames: the error it held back until every
/// complete frame was delivered, `Empty` when there never was a frame, or the normal end.
pub(crate) fn end_of_input(
    pending: &mut Option<SourceError>,
    frames_read: u64,
    what: &str,
) -> Result<bool, SourceError> {
    if let Some(e) = pending.take() {
        return Err(e);
    }
    if frames_read == 0 {
        return Err(SourceError::Empty {
            what: what.to_string(),
        });
    }
    Ok(false)
}

/// Channel names must be unique: a repeated name would merge two sensors' results.
pub fn check_unique_names(what: &str, names: &[String]) -> Result<(), SourceError> {
    let mut seen = std::collections::HashSet::new();
    for (k, n) in names.iter().enumerate() {
        if !seen.insert(n) {
            return Err(SourceError::Setting {
                what: what.to_string(),
                detail: format!(
                    "expected unique channel names, got {n:?} again as channel {}",
                    k + 1
                ),
            });
        }
    }
    Ok(())
}

//! Raw interleaved little-endian float samples (`--raw f32|f64 --fs HZ --channels N`).
//!
//! Raw streams carry no header, so sample rate and channel count come from the caller. A stream
//! that ends inside a frame delivers every whole frame first and then a
//! [`SourceError::Truncated`] with the byte counts.

use std::io::Read;
use std::str::FromStr;

use super::frames::{Codec, FrameReader};
use super::{Block, SignalInfo, Source, SourceError};

/// Sample type of a raw stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RawFormat {
    /// 32-bit IEEE float, little-endian.
    F32,
    /// 64-bit IEEE float, little-endian.
    F64,
}

impl RawFormat {
    /// Bytes per sample.
    pub fn bytes(self) -> usize {
        match self {
            RawFormat::F32 => 4,
            RawFormat::F64 => 8,
        }
    }

    fn codec(self) -> Codec {
        match self {
            RawFormat::F32 => Codec::F32,
            RawFormat::F64 => Codec::F64,
        }
    }
}

impl FromStr for RawFormat {
    type Err = String;

    /// Parses `f32` or `f64` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "f32" => Ok(RawFormat::F32),
            "f64" => Ok(RawFormat::F64),
            other => Err(format!(
                "raw sample format: expected f32 or f64, got {other:?}"
            )),
        }
    }
}

impl std::fmt::Display for RawFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            RawFormat::F32 => "f32",
            RawFormat::F64 => "f64",
        })
    }
}

/// Checks a caller-given sample rate: finite and positive.
pub(crate) fn check_fs(what: &str, fs_hz: f64) -> Result<f64, SourceError> {
    if fs_hz.is_finite() && fs_hz > 0.0 {
        Ok(fs_hz)
    } else {
        Err(SourceError::Setting {
            what: what.to_string(),
            detail: format!("sample rate: expected a finite positive number of Hz, got {fs_hz}"),
        })
    }
}

/// A [`Source`] reading interleaved little-endian floats; channels are named `ch0`, `ch1`, ….
pub struct RawSource<R: Read + Send> {
    info: SignalInfo,
    frames: FrameReader<R>,
}

/// Bytes a channel costs a source before any sample: its name and its place in the decoder.
const RAW_BYTES_PER_CHANNEL: f64 = 64.0;

impl<R: Read + Send> RawSource<R> {
    /// A raw source of `channels` channels at `fs_hz`. Errors (`Setting`) for a non-positive or
    /// non-finite rate or zero channels.
    pub fn new(
        reader: R,
        what: impl Into<String>,
        format: RawFormat,
        fs_hz: f64,
        channels: usize,
    ) -> Result<Self, SourceError> {
        let what = what.into();
        let fs_hz = check_fs(&what, fs_hz)?;
        if channels == 0 {
            return Err(SourceError::Setting {
                what,
                detail: "channel count: expected at least 1, got 0".into(),
            });
        }
        // Names and the decoder's frame buffers, before they exist (`--channels 1e9` with a
        // few bytes of input must not take the machine).
        let estimate = channels as f64 * (RAW_BYTES_PER_CHANNEL + format.bytes() as f64);
        crate::budget::check(&format!("{channels} raw channels"), estimate).map_err(|e| {
            SourceError::Setting {
                what: what.clone(),
                detail: e.to_string(),
            }
        })?;
        Ok(Self {
            info: SignalInfo {
                sample_rate_hz: fs_hz,
                channel_names: (0..channels).map(|k| format!("ch{k}")).collect(),
            },
            frames: FrameReader::new(reader, format.codec(), channels, 1.0, None, what),
        })
    }
}

impl<R: Read + Send> Source for RawSource<R> {
    fn info(&self) -> &SignalInfo {
        &self.info
    }

    fn read_block(&mut self, max_frames: usize, block: &mut Block) -> Result<bool, SourceError> {
        self.frames.read_block(max_frames, block)
    }
}

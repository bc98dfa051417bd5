//! Streaming WAV reader for non-seekable inputs (files, pipes, standard input).
//!
//! hound needs the data chunk length to be exact, so the header is parsed here (the same
//! formats hound reads: 8/16/24/32-bit integer PCM, 32-bit float, WAVE_FORMAT_EXTENSIBLE with a
//! PCM or float sub-format; 64-bit float as well) and the data chunk is streamed in blocks.
//! A data chunk length of 0 or 0xFFFFFFFF, as streaming writers emit when the length is not
//! known yet, means "read to the end of the stream". Limitation: in that case any chunk after
//! the data chunk would be read as samples (streaming writers put nothing after it). Where the
//! length is known, the bytes after the RIFF chunk are looked at once the data is read: a
//! second WAV file there ends the run with [`SourceError::LeftUnread`].

use std::io::{self, Read};

use super::frames::{Codec, FrameReader};
use super::{Block, SignalInfo, Source, SourceError};

/// What a WAV header says about the samples.
#[derive(Clone, Debug, PartialEq)]
pub struct WavHeader {
    /// Samples per second per channel (the truth for the sample rate).
    pub sample_rate_hz: u32,
    /// Number of interleaved channels.
    pub channels: usize,
    /// Whether the samples are integers (scaled to [-1, 1) by default) or floats.
    pub is_float: bool,
    /// Bytes per sample in the data chunk.
    pub bytes_per_sample: usize,
    /// Length of the data chunk in bytes; `None` when unknown (0 or 0xFFFFFFFF in the header).
    pub data_bytes: Option<u64>,
    /// Bytes of the file's RIFF chunk after the data chunk (trailing chunks and the data's pad
    /// byte), as its size field says; `None` when the data's length or the size is unknown.
    pub trailing_bytes: Option<u64>,
}

fn malformed(what: &str, detail: String) -> SourceError {
    SourceError::Malformed {
        what: what.to_string(),
        format: "wav",
        detail,
    }
}

/// Whether a data chunk's length is what a recorder writes when it does not know the length
/// (it streams to a pipe): 0 or 0xFFFFFFFF, SoX's 0x7FFFF000 rounded down to whole frames,
/// arecord's 0x80000000, or any length from 0x7FFFF000 up that is not whole frames. Such data
/// runs to the end of the input; read as a length, a stream that ended normally was flagged
/// truncated (and a 24-bit one refused: 0x80000000 is not a multiple of 6 bytes).
fn is_length_placeholder(len: u32, frame_bytes: u64) -> bool {
    const SOX_UNKNOWN: u64 = 0x7FFF_F000;
    let n = u64::from(len);
    let fb = frame_bytes.max(1);
    let sox = SOX_UNKNOWN - SOX_UNKNOWN % fb;
    len == 0
        || len == u32::MAX
        || n == sox
        || (n >= SOX_UNKNOWN && (n % fb != 0 || n == 0x8000_0000))
}

/// Reads exactly `buf.len()` bytes; a short read is `Truncated` naming `part`.
fn read_exact_or<R: Read>(
    r: &mut R,
    buf: &mut [u8],
    what: &str,
    part: &str,
) -> Result<(), SourceError> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => {
                if n == 0 && part == "RIFF header" {
                    return Err(SourceError::Empty {
                        what: what.to_string(),
                    });
                }
                return Err(SourceError::Truncated {
                    what: what.to_string(),
                    expected: format!("{} bytes of the {part}", buf.len()),
                    got: format!("{n} bytes"),
                });
            }
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => {
                return Err(SourceError::Io {
                    what: what.to_string(),
                    source: e,
                })
            }
        }
    }
    Ok(())
}

fn u16_at(b: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([b[i], b[i + 1]])
}

fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

/// Parses a `fmt ` chunk body into (rate, channels, codec).
fn parse_fmt(b: &[u8], what: &str) -> Result<(u32, usize, Codec), SourceError> {
    if b.len() < 16 {
        return Err(malformed(
            what,
            format!("fmt chunk of at least 16 bytes expected, got {}", b.len()),
        ));
    }
    let mut tag = u16_at(b, 0);
    let channels = usize::from(u16_at(b, 2));
    let rate = u32_at(b, 4);
    let block_align = usize::from(u16_at(b, 12));
    let bits = u16_at(b, 14);
    if tag == 0xFFFE {
        if b.len() < 40 {
            return Err(malformed(
                what,
                format!(
                    "WAVE_FORMAT_EXTENSIBLE fmt chunk of 40 bytes expected, got {}",
                    b.len()
                ),
            ));
        }
        // The sub-format GUID starts with the format tag it stands for.
        tag = u16_at(b, 24);
    }
    if channels == 0 {
        return Err(malformed(what, "at least 1 channel expected, got 0".into()));
    }
    if rate == 0 {
        return Err(malformed(
            what,
            "positive sample rate expected, got 0 Hz".into(),
        ));
    }
    let container = block_align / channels;
    if container == 0 || block_align % channels != 0 {
        return Err(malformed(
            what,
            format!("block align a multiple of {channels} channels expected, got {block_align}"),
        ));
    }
    let codec = match (tag, container) {
        (1, 1) => Codec::U8,
        (1, 2..=4) => Codec::Int(container),
        (3, 4) => Codec::F32,
        (3, 8) => Codec::F64,
        _ => {
            return Err(malformed(
                what,
                format!(
                "integer PCM (tag 1) of 8/16/24/32 bits or float (tag 3) of 32/64 bits expected, \
                     got format tag {tag} with {bits} bits in {container}-byte samples"
            ),
            ))
        }
    };
    Ok((rate, channels, codec))
}

/// Bytes that tell a WAV file: `RIFF`, the chunk's size, `WAVE`.
pub(crate) const WAV_MAGIC_BYTES: usize = 12;

/// Whether `bytes` begin as a WAV file does (`RIFF`, four bytes of size, `WAVE`).
pub(crate) fn starts_like_wav(bytes: &[u8]) -> bool {
    bytes.len() >= WAV_MAGIC_BYTES && bytes.starts_with(b"RIFF") && &bytes[8..12] == b"WAVE"
}

/// Reads a WAV header up to the start of the data chunk, skipping other chunks.
/// Returns the header and the codec of the samples.
fn read_header<R: Read>(r: &mut R, what: &str) -> Result<(WavHeader, Codec), SourceError> {
    let mut riff = [0u8; WAV_MAGIC_BYTES];
    read_exact_or(r, &mut riff, what, "RIFF header")?;
    if !starts_like_wav(&riff) {
        return Err(SourceError::UnrecognisedFormat {
            what: what.to_string(),
            detail: format!(
                "expected a WAV file starting with \"RIFF....WAVE\", got {:?}",
                String::from_utf8_lossy(&riff)
            ),
        });
    }
    let riff_bytes = u64::from(u32_at(&riff, 4));
    // Bytes of the RIFF chunk's body read so far ("WAVE" and the chunks before the data).
    let mut body_read: u64 = 4;
    let mut fmt: Option<(u32, usize, Codec)> = None;
    loop {
        let mut ch = [0u8; 8];
        read_exact_or(r, &mut ch, what, "chunk header before the data chunk")?;
        body_read += 8;
        let id = [ch[0], ch[1], ch[2], ch[3]];
        let len = u32_at(&ch, 4);
        match &id {
            b"fmt " => {
                if len > 65_536 {
                    return Err(malformed(
                        what,
                        format!("fmt chunk of at most 65536 bytes expected, got {len}"),
                    ));
                }
                let mut body = vec![0u8; len as usize + (len as usize & 1)];
                read_exact_or(r, &mut body, what, "fmt chunk")?;
                body_read += body.len() as u64;
                fmt = Some(parse_fmt(&body, what)?);
            }
            b"data" => {
                let (rate, channels, codec) = fmt.ok_or_else(|| {
                    malformed(what, "fmt chunk expected before the data chunk".into())
                })?;
                let fb = (channels * codec.bytes()) as u64;
                let data_bytes = (!is_length_placeholder(len, fb)).then_some(u64::from(len));
                if let Some(n) = data_bytes {
                    if n % fb != 0 {
                        return Err(malformed(
                            what,
                            format!("data chunk length a multiple of the {fb}-byte frame expected, got {n} bytes"),
                        ));
                    }
                }
                let header = WavHeader {
                    sample_rate_hz: rate,
                    channels,
                    is_float: !codec.is_int(),
                    bytes_per_sample: codec.bytes(),
                    data_bytes,
                    // The RIFF chunk's own pad byte, when its size is odd, ends it too.
                    trailing_bytes: data_bytes
                        .and_then(|n| (riff_bytes + (riff_bytes & 1)).checked_sub(body_read + n))
                        .filter(|_| riff_bytes != u64::from(u32::MAX)),
                };
                return Ok((header, codec));
            }
            _ => {
                let skip = u64::from(len) + u64::from(len & 1);
                let skipped =
                    io::copy(&mut r.take(skip), &mut io::sink()).map_err(|e| SourceError::Io {
                        what: what.to_string(),
                        source: e,
                    })?;
                body_read += skipped;
                if skipped < skip {
                    return Err(SourceError::Truncated {
                        what: what.to_string(),
                        expected: format!(
                            "{skip} bytes of chunk {:?} before the data chunk",
                            String::from_utf8_lossy(&id)
                        ),
                        got: format!("{skipped} bytes"),
                    });
                }
            }
        }
    }
}

/// A [`Source`] that streams a WAV from any reader, block by block, without loading it whole.
///
/// Integer samples are scaled to [-1, 1) (divided by 2^(bits-1); 8-bit is unsigned with offset
/// 128) unless [`WavSource::with_int_scale`] gives the physical units per count. Float samples
/// are passed as they are. Channels are named `ch0`, `ch1`, ….
pub struct WavSource<R: Read + Send> {
    header: WavHeader,
    info: SignalInfo,
    frames: FrameReader<R>,
    codec: Codec,
    /// Whether the bytes after the RIFF chunk were looked at ([`WavSource::end_of_data`]).
    looked_past: bool,
}

/// The RIFF chunk's id and size field, which some writers count in its size.
const RIFF_HEADER_BYTES: u64 = 8;

impl WavSource<io::BufReader<std::fs::File>> {
    /// A WAV file: its header read from `file` (which must be at the file's start), its samples
    /// decoded straight from the page cache when the file is a regular one that can be mapped
    /// ([`super::mapped`]), as raw files are; read as a stream otherwise. The same blocks,
    /// flags and errors either way.
    pub fn from_file(
        mut file: std::fs::File,
        what: impl Into<String>,
    ) -> Result<Self, SourceError> {
        let what = what.into();
        // Unbuffered, so that the file's position is the data chunk's first byte.
        let (header, codec) = read_header(&mut file, &what)?;
        let mapped = super::mapped::MappedBytes::rest_of(&file);
        #[cfg(unix)]
        let fd = std::os::fd::AsRawFd::as_raw_fd(&file);
        let mut source = Self::with_header(io::BufReader::new(file), header, codec, what);
        match mapped {
            Some(mapped) => source.frames = source.frames.decoding_from(mapped),
            #[cfg(unix)]
            None => source.frames.wake_on_pause(fd),
            #[cfg(not(unix))]
            None => {}
        }
        Ok(source)
    }
}

impl<R: Read + Send> WavSource<R> {
    /// This source, handing out a block not yet full when nothing arrives on `fd` (the
    /// descriptor its reader reads) for [`super::STREAM_PAUSE_MS`].
    #[cfg(unix)]
    pub(crate) fn waking_on_pause(mut self, fd: i32) -> Self {
        self.frames.wake_on_pause(fd);
        self
    }
}

impl<R: Read + Send> WavSource<R> {
    /// Reads the header from `reader`; `what` names the input in error messages.
    pub fn new(mut reader: R, what: impl Into<String>) -> Result<Self, SourceError> {
        let what = what.into();
        let (header, codec) = read_header(&mut reader, &what)?;
        Ok(Self::with_header(reader, header, codec, what))
    }

    /// The source of a header already read, its samples next in `reader`.
    fn with_header(reader: R, header: WavHeader, codec: Codec, what: String) -> Self {
        let info = SignalInfo {
            sample_rate_hz: f64::from(header.sample_rate_hz),
            channel_names: (0..header.channels).map(|k| format!("ch{k}")).collect(),
        };
        let frames = FrameReader::new(
            reader,
            codec,
            header.channels,
            codec.full_scale(),
            header.data_bytes,
            what,
        );
        Self {
            header,
            info,
            frames,
            codec,
            looked_past: false,
        }
    }

    /// `read` as the source returns it, but at the end of the data an error when another WAV
    /// file follows this one's RIFF chunk (`cat a.wav b.wav |`): one WAV is read per input
    /// (docs/FORMATS.md §2), and the second file's samples were left unread without a word.
    /// Trailing chunks inside the RIFF chunk, and anything after it that is not a WAV header,
    /// end the input as before.
    fn end_of_data(&mut self, read: Result<bool, SourceError>) -> Result<bool, SourceError> {
        if !matches!(read, Ok(false)) || self.looked_past {
            return read;
        }
        self.looked_past = true;
        let Some(trailing) = self.header.trailing_bytes else {
            return read;
        };
        // Writers that count the RIFF chunk's own 8-byte header in its size put the next file
        // 8 bytes before where the size says the chunk ends: both places are looked at.
        let back = trailing.min(RIFF_HEADER_BYTES);
        let next = self
            .frames
            .bytes_past(trailing - back, back as usize + WAV_MAGIC_BYTES);
        let at = [back as usize, 0]
            .into_iter()
            .find(|&k| next.get(k..).is_some_and(starts_like_wav));
        let Some(at) = at else {
            return read;
        };
        let data = self.header.data_bytes.unwrap_or(0);
        let after = trailing - back + at as u64;
        Err(SourceError::LeftUnread {
            what: self.frames.what().to_string(),
            detail: format!(
                "another WAV file follows this one's {data} data bytes, {after} bytes after \
                 them; one WAV file is read per input, so the second one's samples were not \
                 analysed (give the files one at a time)"
            ),
        })
    }

    /// Multiplies integer counts by `scale` instead of mapping them to [-1, 1) (physical units
    /// per count, as a recording set's `meta.json` `scale`). No effect on float WAVs.
    pub fn with_int_scale(mut self, scale: f64) -> Self {
        if self.codec.is_int() {
            self.frames.set_scale(scale);
        }
        self
    }

    /// Replaces the channel names (for example by sensor ids). Errors when the count differs.
    pub fn with_channel_names(mut self, names: Vec<String>) -> Result<Self, SourceError> {
        if names.len() != self.header.channels {
            return Err(SourceError::ChannelCount {
                what: self.frames.what().to_string(),
                expected: names.len(),
                got: self.header.channels,
            });
        }
        self.info.channel_names = names;
        Ok(self)
    }

    /// What the header said.
    pub fn header(&self) -> &WavHeader {
        &self.header
    }
}

impl<R: Read + Send> Source for WavSource<R> {
    fn info(&self) -> &SignalInfo {
        &self.info
    }

    fn duration_frames(&self) -> Option<u64> {
        let frame_bytes = (self.header.channels * self.header.bytes_per_sample) as u64;
        self.header.data_bytes.map(|b| b / frame_bytes.max(1))
    }

    fn quantization_step(&self) -> Option<f64> {
        // One count, in the units the samples are given in (the integer scale).
        self.codec
            .is_int()
            .then(|| self.frames.scale().abs())
            .filter(|s| s.is_finite() && *s > 0.0)
    }

    fn read_block(&mut self, max_frames: usize, block: &mut Block) -> Result<bool, SourceError> {
        let read = self.frames.read_block(max_frames, block);
        self.end_of_data(read)
    }

    fn read_encoded_block(
        &mut self,
        max_frames: usize,
        out: &mut super::encoded::EncodedFrames,
    ) -> Option<Result<bool, SourceError>> {
        let read = self.frames.read_encoded_block(max_frames, out);
        Some(self.end_of_data(read))
    }

    fn allow_block_bytes(&mut self, bytes: usize) {
        self.frames.allow_block_bytes(bytes)
    }

    fn paused(&self) -> bool {
        self.frames.paused()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::raw::tests::{drain, drain_encoded};
    use std::io::Write;

    /// A WAV of `frames` frames of `channels` samples of `bytes` each (1, 2 or 4: u8, i16,
    /// f32), the data chunk announcing `announced` bytes (its true length when `None`), then
    /// `trailer` (a chunk after the data, or stray bytes).
    fn wav(
        channels: u16,
        bytes: u16,
        frames: usize,
        announced: Option<u32>,
        trailer: &[u8],
    ) -> Vec<u8> {
        let data: Vec<u8> = (0..frames * channels as usize)
            .flat_map(|i| match bytes {
                4 if i == 77 => f32::NAN.to_le_bytes().to_vec(),
                4 => ((i % 97) as f32 * 0.01 - 0.4).to_le_bytes().to_vec(),
                2 => (((i * 7919) % 60_000) as i32 - 30_000).to_le_bytes()[..2].to_vec(),
                _ => vec![(i % 251) as u8],
            })
            .collect();
        let format: u16 = if bytes == 4 { 3 } else { 1 };
        let mut out = b"RIFF\0\0\0\0WAVE".to_vec();
        out.extend_from_slice(b"LIST");
        out.extend_from_slice(&4u32.to_le_bytes());
        out.extend_from_slice(b"INFO");
        out.extend_from_slice(b"fmt ");
        out.extend_from_slice(&16u32.to_le_bytes());
        out.extend_from_slice(&format.to_le_bytes());
        out.extend_from_slice(&channels.to_le_bytes());
        out.extend_from_slice(&65536u32.to_le_bytes());
        out.extend_from_slice(&(65536 * u32::from(channels * bytes)).to_le_bytes());
        out.extend_from_slice(&(channels * bytes).to_le_bytes());
        out.extend_from_slice(&(8 * bytes).to_le_bytes());
        out.extend_from_slice(b"data");
        out.extend_from_slice(&announced.unwrap_or(data.len() as u32).to_le_bytes());
        out.extend_from_slice(&data);
        out.extend_from_slice(trailer);
        out
    }

    /// A WAV file decoded from its mapping gives the blocks, flags and errors of the same
    /// bytes read as a stream (also left encoded and decoded as the workers do): float, 16-bit and 8-bit data, a chunk before the format, a chunk
    /// after the data, a data chunk longer than the file, one of unknown length (0) read to
    /// the end with a partial frame there.
    #[test]
    fn a_mapped_wav_reads_as_the_same_bytes_streamed() {
        let dir = std::env::temp_dir().join(format!("dampscope-wav-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let list = b"LIST\x06\0\0\0abcdef";
        // Channels, bytes per sample, frames, announced data bytes, bytes after the data.
        type Case<'a> = (u16, u16, usize, Option<u32>, &'a [u8]);
        let cases: [Case<'_>; 5] = [
            (8, 4, 3000, None, &[]),
            (3, 2, 2001, None, list),
            (5, 1, 999, None, &[]),
            (4, 4, 1500, Some(4 * 4 * 2000), &[]),
            (2, 2, 1000, Some(0), &[1, 2, 3]),
        ];
        for (i, (channels, bytes, frames, announced, trailer)) in cases.into_iter().enumerate() {
            let bytes = wav(channels, bytes, frames, announced, trailer);
            let path = dir.join(format!("{i}.wav"));
            std::fs::File::create(&path)
                .unwrap()
                .write_all(&bytes)
                .unwrap();
            let mapped = || WavSource::from_file(std::fs::File::open(&path).unwrap(), "x").unwrap();
            assert!(mapped().frames.is_mapped(), "case {i}");
            let streamed = || WavSource::new(std::io::Cursor::new(bytes.clone()), "x").unwrap();
            let seen = drain(mapped());
            assert!(seen.len() > 1, "case {i}: {seen:?}");
            assert_eq!(seen, drain(streamed()), "case {i}");
            assert_eq!(seen, drain_encoded(mapped()), "case {i}, encoded");
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}

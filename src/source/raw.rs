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
    /// Frames the caller says the input holds ([`RawSource::expecting_frames`]).
    expected: Option<u64>,
}

/// Bytes a channel costs a source before any sample: its name and its place in the decoder.
const RAW_BYTES_PER_CHANNEL: f64 = 64.0;

/// Refuses, as raw samples, input that begins with a WAV header (`RIFF`…`WAVE`): its header
/// would be read as samples and its rate and channel count replaced by the options'. No raw
/// recording begins with those twelve bytes by chance (they read as f32 12690.1, …, 3428.1).
fn refuse_wav_header(what: &str, first: &[u8]) -> Result<(), SourceError> {
    if super::wav::starts_like_wav(first) {
        return Err(SourceError::UnrecognisedFormat {
            what: what.to_string(),
            detail: "raw samples were declared (--raw), but the input is a WAV file (it starts \
                     with a RIFF…WAVE header); drop --raw, --fs and --channels: the header \
                     gives them"
                .into(),
        });
    }
    Ok(())
}

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
        Self::with_frames(reader, None, what.into(), format, fs_hz, channels)
    }

    /// The file's remaining bytes as a raw source: decoded straight from the page cache when
    /// the file is a regular one that can be mapped ([`super::mapped`]), read as a stream
    /// otherwise. The same blocks, errors and rows either way.
    #[cfg(unix)]
    pub fn from_file(
        file: R,
        what: impl Into<String>,
        format: RawFormat,
        fs_hz: f64,
        channels: usize,
    ) -> Result<Self, SourceError>
    where
        R: std::os::fd::AsFd,
    {
        use std::os::fd::AsRawFd;
        let what: String = what.into();
        let mapped = file.as_fd().try_clone_to_owned().ok().and_then(|fd| {
            let file = std::fs::File::from(fd);
            let mapped = super::mapped::MappedBytes::rest_of(&file);
            if mapped.is_none() {
                super::pipe::widen(&file);
            }
            mapped
        });
        if let Some(m) = &mapped {
            refuse_wav_header(&what, m.slice(0..m.len().min(super::wav::WAV_MAGIC_BYTES)))?;
        }
        let streamed = mapped.is_none();
        let fd = file.as_fd().as_raw_fd();
        let mut source = Self::with_frames(file, mapped, what, format, fs_hz, channels)?;
        if !streamed {
            return Ok(source);
        }
        // A stream's first bytes, read ahead and kept as its first samples (a WAV piped in).
        let what = source.frames.what().to_string();
        let first = source
            .frames
            .first_bytes(super::wav::WAV_MAGIC_BYTES)
            .map_err(|e| SourceError::Io {
                what: what.clone(),
                source: e,
            })?;
        refuse_wav_header(&what, first)?;
        Ok(source.waking_on_pause(fd))
    }

    /// This source, handing out a block not yet full when nothing arrives on `fd` (the
    /// descriptor its reader reads) for [`super::STREAM_PAUSE_MS`].
    #[cfg(unix)]
    pub(crate) fn waking_on_pause(mut self, fd: i32) -> Self {
        self.frames.wake_on_pause(fd);
        self
    }

    /// This source, announcing that its input holds `frames` sample frames (an input in
    /// memory): used to lay out memory only ([`Source::expected_frames`]), never checked.
    pub fn expecting_frames(mut self, frames: u64) -> Self {
        self.expected = Some(frames);
        self
    }

    /// Without memory mapping: [`RawSource::new`].
    #[cfg(not(unix))]
    pub fn from_file(
        file: R,
        what: impl Into<String>,
        format: RawFormat,
        fs_hz: f64,
        channels: usize,
    ) -> Result<Self, SourceError> {
        Self::new(file, what, format, fs_hz, channels)
    }

    fn with_frames(
        reader: R,
        mapped: Option<super::mapped::MappedBytes>,
        what: String,
        format: RawFormat,
        fs_hz: f64,
        channels: usize,
    ) -> Result<Self, SourceError> {
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
            frames: {
                let frames = FrameReader::new(reader, format.codec(), channels, 1.0, None, what);
                match mapped {
                    Some(m) => frames.decoding_from(m),
                    None => frames,
                }
            },
            expected: None,
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

    fn read_encoded_block(
        &mut self,
        max_frames: usize,
        out: &mut super::encoded::EncodedFrames,
    ) -> Option<Result<bool, SourceError>> {
        Some(self.frames.read_encoded_block(max_frames, out))
    }

    fn allow_block_bytes(&mut self, bytes: usize) {
        self.frames.allow_block_bytes(bytes)
    }

    fn paused(&self) -> bool {
        self.frames.paused()
    }

    /// What the caller announced, or a mapped file's size in frames (no header states it, so
    /// it is no duration).
    fn expected_frames(&self) -> Option<u64> {
        self.expected.or_else(|| self.frames.mapped_frames())
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use std::io::{Seek, SeekFrom, Write};

    /// Every block, then the end or the error, as text: what a run sees of a source.
    pub(in crate::source) fn drain(mut source: impl Source) -> Vec<String> {
        let mut seen = Vec::new();
        let mut block = Block::default();
        loop {
            match source.read_block(1000, &mut block) {
                Ok(true) => seen.push(format!("{:?} {:?}", block.channels, block.known_finite)),
                Ok(false) => {
                    seen.push("end".into());
                    return seen;
                }
                Err(e) => {
                    seen.push(format!("error: {e}"));
                    // A source reports once and then ends.
                    if !matches!(source.read_block(1000, &mut block), Ok(false)) {
                        seen.push("not ended after the error".into());
                    }
                    return seen;
                }
            }
        }
    }

    /// [`drain`] through `read_encoded_block`, each block decoded whole as a worker would.
    pub(in crate::source) fn drain_encoded(mut source: impl Source) -> Vec<String> {
        let mut seen = Vec::new();
        let mut frames = crate::source::encoded::EncodedFrames::default();
        let mut block = Block::default();
        loop {
            match source.read_encoded_block(1000, &mut frames) {
                Some(Ok(true)) => {
                    frames.decode_into(0..frames.channels(), &mut block);
                    seen.push(format!("{:?} {:?}", block.channels, block.known_finite));
                }
                Some(Ok(false)) => {
                    seen.push("end".into());
                    return seen;
                }
                Some(Err(e)) => {
                    seen.push(format!("error: {e}"));
                    if !matches!(
                        source.read_encoded_block(1000, &mut frames),
                        Some(Ok(false))
                    ) {
                        seen.push("not ended after the error".into());
                    }
                    return seen;
                }
                None => return vec!["no encoded blocks".into()],
            }
        }
    }

    /// The mapped file gives exactly the blocks, flags and errors of the same bytes read as a
    /// stream: whole files, files ending in a partial frame, a file read from an offset that is
    /// not on a page or a frame boundary, and a file with nothing left. So do both when their
    /// blocks are left encoded and decoded afterwards, as the workers do.
    #[test]
    fn a_mapped_file_reads_as_the_same_bytes_streamed() {
        let dir = std::env::temp_dir().join(format!("dampscope-mapped-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (n_ch, frames, stray, skip) in [
            (8usize, 5000usize, 0usize, 0usize),
            (8, 5000, 3, 0),
            (3, 2001, 5, 0),
            (16, 700, 0, 4097),
            (1, 10, 0, 40),
        ] {
            let mut bytes = Vec::new();
            for i in 0..frames * n_ch {
                let v = if i == 777 {
                    f32::NAN
                } else {
                    (i % 97) as f32 - 48.0
                };
                bytes.extend_from_slice(&v.to_le_bytes());
            }
            bytes.extend(std::iter::repeat_n(7u8, stray));
            let path = dir.join(format!("{n_ch}-{frames}-{stray}-{skip}.f32"));
            std::fs::File::create(&path)
                .unwrap()
                .write_all(&bytes)
                .unwrap();
            let mapped = || {
                let mut file = std::fs::File::open(&path).unwrap();
                file.seek(SeekFrom::Start(skip as u64)).unwrap();
                RawSource::from_file(file, "x", RawFormat::F32, 1000.0, n_ch).unwrap()
            };
            assert!(mapped().frames.is_mapped() || skip >= bytes.len());
            let stream = || {
                let rest = bytes[skip.min(bytes.len())..].to_vec();
                RawSource::new(
                    std::io::Cursor::new(rest),
                    "x",
                    RawFormat::F32,
                    1000.0,
                    n_ch,
                )
                .unwrap()
            };
            let case = format!("{n_ch} ch, {frames} frames, {stray} stray, from {skip}");
            let a = drain(mapped());
            assert_eq!(a, drain(stream()), "{case}");
            assert_eq!(a, drain_encoded(mapped()), "{case}, encoded");
            assert_eq!(a, drain_encoded(stream()), "{case}, encoded stream");
            assert!(!a.is_empty());
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A reader that yields its bytes in pieces of varying length, as a pipe does.
    struct Pieces {
        bytes: std::io::Cursor<Vec<u8>>,
        lengths: std::iter::Cycle<std::vec::IntoIter<usize>>,
    }

    impl std::io::Read for Pieces {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = self.lengths.next().unwrap_or(1).min(buf.len());
            self.bytes.read(&mut buf[..n])
        }
    }

    /// Each channel's samples (as bits) over all blocks, then how the input ended.
    fn samples_of(mut next: impl FnMut(&mut Block) -> Option<Result<bool, SourceError>>) -> String {
        let mut block = Block::default();
        let mut all: Vec<Vec<u64>> = Vec::new();
        let end = loop {
            match next(&mut block) {
                Some(Ok(true)) => {
                    all.resize_with(block.channels.len(), Vec::new);
                    for (a, ch) in all.iter_mut().zip(&block.channels) {
                        a.extend(ch.iter().map(|v| v.to_bits()));
                    }
                }
                Some(Ok(false)) => break "end".to_string(),
                Some(Err(e)) => break format!("error: {e}"),
                None => break "no encoded blocks".to_string(),
            }
        };
        format!("{all:?} {end}")
    }

    /// A stream that arrives in pieces of 1 byte to 64 KiB, cutting frames anywhere, gives the
    /// samples and the end of the same bytes read whole, whether the reader decodes its blocks
    /// or hands them over encoded (its buffer then trades places with the block's each time, and
    /// a partial frame must move with it), with one block buffer reused throughout.
    #[test]
    fn a_stream_in_pieces_reads_as_the_same_bytes_whole() {
        for (n_ch, frames, stray) in [(8usize, 20_000usize, 0usize), (3, 7001, 5), (64, 900, 7)] {
            let mut bytes = Vec::new();
            for i in 0..frames * n_ch {
                bytes.extend_from_slice(&((i % 1013) as f32 * 0.25 - 100.0).to_le_bytes());
            }
            bytes.extend(std::iter::repeat_n(9u8, stray));
            let whole = || {
                let cursor = std::io::Cursor::new(bytes.clone());
                RawSource::new(cursor, "x", RawFormat::F32, 1000.0, n_ch).unwrap()
            };
            let pieces = || {
                let lengths = vec![1usize, 7, 333, 4096, 65_536, 13, 100_003, 2];
                let reader = Pieces {
                    bytes: std::io::Cursor::new(bytes.clone()),
                    lengths: lengths.into_iter().cycle(),
                };
                RawSource::new(reader, "x", RawFormat::F32, 1000.0, n_ch).unwrap()
            };
            let mut source = whole();
            let expected = samples_of(|b| Some(source.read_block(1000, b)));
            let mut source = pieces();
            let decoded = samples_of(|b| Some(source.read_block(1000, b)));
            let mut source = pieces();
            let mut frames_buf = crate::source::encoded::EncodedFrames::default();
            let encoded = samples_of(|b| {
                let got = source.read_encoded_block(4096, &mut frames_buf)?;
                if matches!(got, Ok(true)) {
                    frames_buf.decode_into(0..frames_buf.channels(), b);
                }
                Some(got)
            });
            let case = format!("{n_ch} ch, {frames} frames, {stray} stray");
            assert_eq!(
                expected.contains("stray"),
                stray > 0,
                "{case}: {}",
                &expected[expected.len() - 60..]
            );
            assert_eq!(decoded, expected, "{case}, decoded");
            assert_eq!(encoded, expected, "{case}, encoded");
        }
    }

    /// A read returns at most 1 MiB of frames unless the source is allowed more
    /// ([`Source::allow_block_bytes`]), mapped or streamed. Decoded and encoded, 64 f32
    /// channels (256 bytes a frame) asked for 30 000 frames at a time.
    #[test]
    fn blocks_grow_to_the_bytes_allowed_and_no_further() {
        let (n_ch, frames) = (64usize, 30_000usize);
        let bytes: Vec<u8> = (0..frames * n_ch)
            .flat_map(|i| ((i % 101) as f32).to_le_bytes())
            .collect();
        let path = std::env::temp_dir().join(format!("dampscope-allow-{}.f32", std::process::id()));
        std::fs::File::create(&path)
            .unwrap()
            .write_all(&bytes)
            .unwrap();
        let mapped = || {
            let file = std::fs::File::open(&path).unwrap();
            RawSource::from_file(file, "x", RawFormat::F32, 65536.0, n_ch).unwrap()
        };
        let stream = || {
            let cursor = std::io::Cursor::new(bytes.clone());
            RawSource::new(cursor, "x", RawFormat::F32, 65536.0, n_ch).unwrap()
        };
        fn first_block(mut source: impl Source, allowed: Option<usize>, encoded: bool) -> usize {
            if let Some(b) = allowed {
                source.allow_block_bytes(b);
            }
            if encoded {
                let mut out = crate::source::encoded::EncodedFrames::default();
                assert!(matches!(
                    source.read_encoded_block(30_000, &mut out),
                    Some(Ok(true))
                ));
                out.frames()
            } else {
                let mut block = Block::default();
                assert!(source.read_block(30_000, &mut block).unwrap());
                block.channels[0].len()
            }
        }
        for encoded in [false, true] {
            // 1 MiB: 4096 frames; allowed 8 MiB: all 30 000 asked; a smaller allowance than
            // the default changes nothing.
            assert_eq!(first_block(mapped(), None, encoded), 4096);
            assert_eq!(first_block(mapped(), Some(8 << 20), encoded), 30_000);
            assert_eq!(first_block(mapped(), Some(1000), encoded), 4096);
            assert_eq!(first_block(stream(), None, encoded), 4096);
            assert_eq!(first_block(stream(), Some(8 << 20), encoded), 30_000);
        }
        std::fs::remove_file(&path).ok();
    }

    /// A reader that returns at most `chunk` bytes a call, as a pipe does when the writer
    /// is slower than the reader.
    struct Trickle {
        bytes: Vec<u8>,
        at: usize,
        chunk: usize,
    }

    impl std::io::Read for Trickle {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = buf.len().min(self.chunk).min(self.bytes.len() - self.at);
            buf[..n].copy_from_slice(&self.bytes[self.at..self.at + n]);
            self.at += n;
            Ok(n)
        }
    }

    /// A stream's blocks are the mapped file's, however its reads return: a reader that hands
    /// out 1000 bytes at a time (not a whole number of 12-byte frames) gives the same blocks,
    /// the same frames in each, as the file mapped, decoded and left encoded (the encoded
    /// blocks recycle their buffers, so stale bytes from the last block would show), with the
    /// default cap and a larger one allowed. Blocks cut where the reads returned paired other
    /// frames in the STFT, and piped input gave other bits on every run.
    #[test]
    fn a_trickling_stream_gives_the_mapped_files_blocks() {
        let (n_ch, frames) = (3usize, 100_000usize);
        let bytes: Vec<u8> = (0..frames * n_ch)
            .flat_map(|i| ((i % 997) as f32 - 0.5).to_le_bytes())
            .collect();
        let path =
            std::env::temp_dir().join(format!("dampscope-trickle-{}.f32", std::process::id()));
        std::fs::File::create(&path)
            .unwrap()
            .write_all(&bytes)
            .unwrap();
        fn allow<S: Source>(mut source: S, allowed: Option<usize>) -> S {
            if let Some(b) = allowed {
                source.allow_block_bytes(b);
            }
            source
        }
        fn decoded(mut source: impl Source) -> Vec<Vec<Vec<f64>>> {
            let mut out = Vec::new();
            let mut block = Block::default();
            while source.read_block(90_000, &mut block).unwrap() {
                out.push(block.channels.clone());
            }
            out
        }
        fn encoded(mut source: impl Source) -> Vec<Vec<Vec<f64>>> {
            let mut out = Vec::new();
            let mut frames = crate::source::encoded::EncodedFrames::default();
            while let Some(Ok(true)) = source.read_encoded_block(90_000, &mut frames) {
                let mut block = Block::default();
                frames.decode_into(0..frames.channels(), &mut block);
                out.push(block.channels);
            }
            out
        }
        let stream = |allowed| {
            let trickle = Trickle {
                bytes: bytes.clone(),
                at: 0,
                chunk: 1000,
            };
            allow(
                RawSource::new(trickle, "x", RawFormat::F32, 65536.0, n_ch).unwrap(),
                allowed,
            )
        };
        for allowed in [None, Some(3 << 20)] {
            let file = std::fs::File::open(&path).unwrap();
            let mapped = RawSource::from_file(file, "x", RawFormat::F32, 65536.0, n_ch).unwrap();
            let expected = decoded(allow(mapped, allowed));
            assert!(expected.len() > 1, "{} blocks", expected.len());
            assert_eq!(decoded(stream(allowed)), expected, "decoded, {allowed:?}");
            assert_eq!(encoded(stream(allowed)), expected, "encoded, {allowed:?}");
        }
        std::fs::remove_file(&path).ok();
    }
}

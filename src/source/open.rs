//! Opening an input by name: `-` (standard input, format detected), a `.wav` or `.csv` file, an
//! FRF file (a universal file `.uff`/`.unv`, or a CSV whose header is `f, <id>_re, <id>_im, …`:
//! [`super::frf_input`]), a recording-set directory, or any other file (detected like standard
//! input).
//!
//! Detection looks at the first bytes without losing them: they are read into a small buffer
//! and chained in front of the rest of the stream. `RIFF` → WAV; text → CSV; anything else →
//! [`SourceError::UnrecognisedFormat`] quoting the first bytes. `--raw` skips detection.

use std::fs::File;
use std::io::{BufReader, Cursor, Read};
use std::path::Path;

use super::csv::CsvSource;
use super::frames::read_up_to;
use super::frf::FrfToImpulse;
use super::frf_input::{is_frf_csv, is_uff_path, open_frf_file};
use super::raw::{RawFormat, RawSource};
use super::recording_set::{open_recording_set_with, RecordingMeta, Sensor};
use super::wav::WavSource;
use super::{Source, SourceError};

/// Bytes looked at to detect the format.
const SNIFF_BYTES: usize = 64;

/// How to read an input, from the command line.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InputOptions {
    /// Raw interleaved little-endian samples of this type (no detection).
    pub raw: Option<RawFormat>,
    /// Sample rate in Hz: required for raw input and for CSV without a time column or `# fs=`
    /// comment; wins over a CSV's own rate; must agree with a WAV header's or recording set's
    /// rate (an error otherwise, rather than a silent choice).
    pub fs_hz: Option<f64>,
    /// Channel count: required for raw input; otherwise checked against the input.
    pub channels: Option<usize>,
    /// How FRF inputs (universal files, FRF CSV) become impulse responses: taper and window.
    pub frf: FrfToImpulse,
}

/// An opened input: the samples, plus sensors and metadata when it was a recording set.
pub struct OpenedInput {
    /// The samples.
    pub source: Box<dyn Source>,
    /// Sensor positions (recording sets only).
    pub sensors: Option<Vec<Sensor>>,
    /// Metadata (recording sets only).
    pub meta: Option<RecordingMeta>,
    /// What the input's files said that was read otherwise, for the user (recording sets).
    pub warnings: Vec<String>,
}

impl OpenedInput {
    fn plain(source: Box<dyn Source>) -> Self {
        Self {
            source,
            sensors: None,
            meta: None,
            warnings: Vec::new(),
        }
    }
}

/// Describes the first bytes of an input for an error message: hex and printable ASCII.
fn describe(bytes: &[u8]) -> String {
    let shown = &bytes[..bytes.len().min(16)];
    let hex: Vec<String> = shown.iter().map(|b| format!("{b:02x}")).collect();
    let ascii: String = shown
        .iter()
        .map(|&b| {
            if b.is_ascii_graphic() || b == b' ' {
                b as char
            } else {
                '.'
            }
        })
        .collect();
    format!("first bytes {} ({ascii:?})", hex.join(" "))
}

/// Whether the bytes look like text: UTF-8 (a character cut at the end is fine) without control
/// characters other than tab, CR and LF.
fn looks_like_text(bytes: &[u8]) -> bool {
    let valid = match std::str::from_utf8(bytes) {
        Ok(s) => s,
        Err(e) if e.error_len().is_none() => {
            // Incomplete character at the end of the sniffed bytes: judge the valid part.
            std::str::from_utf8(&bytes[..e.valid_up_to()]).unwrap_or("")
        }
        Err(_) => return false,
    };
    valid
        .chars()
        .all(|c| !c.is_control() || matches!(c, '\t' | '\r' | '\n'))
}

fn check_channels(what: &str, source: &dyn Source, opts: &InputOptions) -> Result<(), SourceError> {
    match opts.channels {
        Some(n) if n != source.info().channels() => Err(SourceError::ChannelCount {
            what: what.to_string(),
            expected: n,
            got: source.info().channels(),
        }),
        _ => Ok(()),
    }
}

/// Errors when `opts.fs_hz` disagrees with the rate of a source that carries its own (WAV,
/// recording set).
fn check_header_rate(
    what: &str,
    source: &dyn Source,
    opts: &InputOptions,
) -> Result<(), SourceError> {
    let header_hz = source.info().sample_rate_hz;
    match opts.fs_hz {
        Some(option_hz) if (option_hz - header_hz).abs() > 1e-9 * header_hz => {
            Err(SourceError::SampleRateConflict {
                what: what.to_string(),
                header_hz,
                option_hz,
            })
        }
        _ => Ok(()),
    }
}

/// The sample rate and channel count a raw input needs from `opts`.
fn raw_settings(
    what: &str,
    format: RawFormat,
    opts: &InputOptions,
) -> Result<(f64, usize), SourceError> {
    let fs = opts.fs_hz.ok_or_else(|| SourceError::Setting {
        what: what.to_string(),
        detail: format!("raw {format} input needs the sample rate (fs_hz), none given"),
    })?;
    let ch = opts.channels.ok_or_else(|| SourceError::Setting {
        what: what.to_string(),
        detail: format!("raw {format} input needs the channel count (channels), none given"),
    })?;
    Ok((fs, ch))
}

fn raw_source<R: Read + Send + 'static>(
    reader: R,
    what: &str,
    format: RawFormat,
    opts: &InputOptions,
) -> Result<Box<dyn Source>, SourceError> {
    let (fs, ch) = raw_settings(what, format, opts)?;
    Ok(Box::new(RawSource::new(reader, what, format, fs, ch)?))
}

/// A raw source of a file or of standard input: decoded from the mapped file when it is a
/// regular one ([`RawSource::from_file`]).
#[cfg(unix)]
fn raw_file_source<R: Read + Send + std::os::fd::AsFd + 'static>(
    file: R,
    what: &str,
    format: RawFormat,
    opts: &InputOptions,
) -> Result<Box<dyn Source>, SourceError> {
    let (fs, ch) = raw_settings(what, format, opts)?;
    Ok(Box::new(RawSource::from_file(file, what, format, fs, ch)?))
}

#[cfg(not(unix))]
fn raw_file_source<R: Read + Send + 'static>(
    file: R,
    what: &str,
    format: RawFormat,
    opts: &InputOptions,
) -> Result<Box<dyn Source>, SourceError> {
    raw_source(file, what, format, opts)
}

/// Standard input redirected from a WAV file (`dampscope analyze - < rec.wav`), opened as that
/// file ([`WavSource::from_file`]: its samples decoded from the mapping); `None` for anything
/// else — a pipe, a terminal, another format — which is then read and detected as a stream.
/// The first bytes are looked at without reading them (`pread`), so nothing is consumed when
/// the answer is no.
#[cfg(unix)]
fn stdin_wav_file(opts: &InputOptions) -> Result<Option<Box<dyn Source>>, SourceError> {
    use std::io::Seek;
    use std::os::fd::AsFd;
    use std::os::unix::fs::FileExt;
    let Ok(fd) = std::io::stdin().as_fd().try_clone_to_owned() else {
        return Ok(None);
    };
    let file = File::from(fd);
    if !file.metadata().is_ok_and(|m| m.file_type().is_file()) {
        return Ok(None);
    }
    let Ok(at) = (&file).stream_position() else {
        return Ok(None);
    };
    let mut magic = [0u8; 4];
    if !matches!(file.read_at(&mut magic, at), Ok(4)) || &magic != b"RIFF" {
        return Ok(None);
    }
    let wav = WavSource::from_file(file, "standard input")?;
    check_header_rate("standard input", &wav, opts)?;
    let source: Box<dyn Source> = Box::new(wav);
    check_channels("standard input", source.as_ref(), opts)?;
    Ok(Some(source))
}

/// Whether the first line of `head` that is neither blank nor a `#` comment is an FRF CSV
/// header ([`super::frf_csv::is_frf_csv_header`]).
fn starts_like_frf_csv(head: &[u8]) -> bool {
    String::from_utf8_lossy(head)
        .lines()
        .find(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
        .is_some_and(super::frf_csv::is_frf_csv_header)
}

/// Opens a stream whose format must be detected (or is raw per `opts`). `what` names it in
/// errors. Generic so that tests can pass a `Cursor` instead of standard input. Binary frames
/// are read in whole blocks (the same as a mapped file's); the reader's pauses are not
/// watched, as they are for standard input ([`super::STREAM_PAUSE_MS`]), so a writer that
/// waits for rows before it sends more should close or keep writing.
///
/// Errors: `Empty` for a stream without a byte, `UnrecognisedFormat` for binary data that is
/// not a WAV, `ChannelCount` when `opts.channels` disagrees, and whatever the format's source
/// reports for its header.
pub fn open_stream<R: Read + Send + 'static>(
    reader: R,
    what: &str,
    opts: &InputOptions,
) -> Result<Box<dyn Source>, SourceError> {
    open_stream_watched(reader, what, opts, None)
}

/// [`open_stream`] of a reader that reads descriptor `pause_fd` (when known): a WAV stream
/// hands out the frames that arrived when the writer pauses
/// ([`super::STREAM_PAUSE_MS`]) instead of waiting for a whole block.
fn open_stream_watched<R: Read + Send + 'static>(
    mut reader: R,
    what: &str,
    opts: &InputOptions,
    pause_fd: Option<i32>,
) -> Result<Box<dyn Source>, SourceError> {
    #[cfg(not(unix))]
    let _ = pause_fd;
    if let Some(format) = opts.raw {
        // Raw standard input and raw files reach `raw_file_source` (their descriptor watched
        // there); only `open_stream`'s readers come here, unwatched.
        return raw_source(reader, what, format, opts);
    }
    let mut head = Vec::with_capacity(SNIFF_BYTES);
    read_up_to(&mut reader, &mut head, SNIFF_BYTES).map_err(|e| SourceError::Io {
        what: what.to_string(),
        source: e,
    })?;
    if head.is_empty() {
        return Err(SourceError::Empty {
            what: what.to_string(),
        });
    }
    let is_wav = head.starts_with(b"RIFF");
    let is_text = !is_wav && looks_like_text(&head);
    if !is_wav && !is_text {
        return Err(SourceError::UnrecognisedFormat {
            what: what.to_string(),
            detail: format!(
                "expected a WAV stream (starting with RIFF), CSV text, or raw samples (declared raw); got {}",
                describe(&head)
            ),
        });
    }
    if is_text && starts_like_frf_csv(&head) {
        return Err(SourceError::UnrecognisedFormat {
            what: what.to_string(),
            detail: "an FRF CSV (frequency and complex-response columns), which is read from a \
                     regular file given by path, not from a stream: its rows would be taken \
                     for time series; save it to a file"
                .into(),
        });
    }
    let source: Box<dyn Source> = if is_wav {
        let stream = BufReader::new(Cursor::new(head).chain(reader));
        let wav = WavSource::new(stream, what)?;
        check_header_rate(what, &wav, opts)?;
        #[cfg(unix)]
        let wav = match pause_fd {
            Some(fd) => wav.waking_on_pause(fd),
            None => wav,
        };
        Box::new(wav)
    } else {
        #[cfg(unix)]
        if let Some(fd) = pause_fd {
            let (watched, armed) = super::pipe::PausingReader::new(reader, fd);
            let stream = BufReader::new(Cursor::new(head).chain(watched));
            let csv = CsvSource::waking_on_pause(stream, what, opts.fs_hz, armed)?;
            check_channels(what, &csv, opts)?;
            return Ok(Box::new(csv));
        }
        let stream = BufReader::new(Cursor::new(head).chain(reader));
        Box::new(CsvSource::new(stream, what, opts.fs_hz)?)
    };
    check_channels(what, source.as_ref(), opts)?;
    Ok(source)
}

/// Opens `path`: `-` is standard input (detected, or raw per `opts`), a directory is a
/// recording set, a `.wav`/`.csv` file is read as such, any other file is detected like
/// standard input.
pub fn open_input(path: &str, opts: &InputOptions) -> Result<OpenedInput, SourceError> {
    if path == "-" {
        if let Some(format) = opts.raw {
            return raw_file_source(std::io::stdin(), "standard input", format, opts)
                .map(OpenedInput::plain);
        }
        #[cfg(unix)]
        if let Some(wav) = stdin_wav_file(opts)? {
            return Ok(OpenedInput::plain(wav));
        }
        #[cfg(unix)]
        let fd = Some(std::os::fd::AsRawFd::as_raw_fd(&std::io::stdin()));
        #[cfg(not(unix))]
        let fd = None;
        return open_stream_watched(std::io::stdin(), "standard input", opts, fd)
            .map(OpenedInput::plain);
    }
    let p = Path::new(path);
    if p.is_dir() {
        let set = open_recording_set_with(p, &opts.frf)?;
        check_channels(path, set.source.as_ref(), opts)?;
        check_header_rate(path, set.source.as_ref(), opts)?;
        return Ok(OpenedInput {
            source: set.source,
            sensors: Some(set.sensors),
            meta: Some(set.meta),
            warnings: set.warnings,
        });
    }
    let file = File::open(p).map_err(|e| SourceError::Io {
        what: path.to_string(),
        source: e,
    })?;
    if opts.raw.is_none() && (is_uff_path(p) || is_frf_csv(p)) {
        let frf = open_frf_file(p, &opts.frf)?;
        for note in &frf.notes {
            eprintln!("dampscope: note: {path}: {note}");
        }
        check_channels(path, frf.source.as_ref(), opts)?;
        check_header_rate(path, frf.source.as_ref(), opts)?;
        return Ok(OpenedInput {
            source: frf.source,
            sensors: frf.sensors,
            meta: Some(frf.meta),
            warnings: Vec::new(),
        });
    }
    let ext = p
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let source: Box<dyn Source> = match (opts.raw, ext.as_deref()) {
        (None, Some("wav")) => {
            let wav = WavSource::from_file(file, path)?;
            check_header_rate(path, &wav, opts)?;
            Box::new(wav)
        }
        (None, Some("csv")) => Box::new(CsvSource::new(BufReader::new(file), path, opts.fs_hz)?),
        (Some(format), _) => raw_file_source(file, path, format, opts)?,
        _ => {
            #[cfg(unix)]
            let fd = Some(std::os::fd::AsRawFd::as_raw_fd(&file));
            #[cfg(not(unix))]
            let fd = None;
            open_stream_watched(file, path, opts, fd)?
        }
    };
    check_channels(path, source.as_ref(), opts)?;
    Ok(OpenedInput::plain(source))
}

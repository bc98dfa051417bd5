//! Writing 32-bit IEEE-float WAV files to writers that cannot seek (standard output, pipes).
//!
//! hound's `WavWriter` needs `Seek` to patch the header lengths at the end. A generator knows its
//! length up front, so the header can be written first with the right lengths and the samples
//! streamed after it. The header is the canonical one for non-PCM data: an 18-byte `fmt ` chunk
//! (format tag 3, `cbSize` 0) followed by a `fact` chunk holding the frame count.

use std::io::{self, Write};

use crate::source::Block;

/// Bytes per sample of the written format (32-bit float).
const BYTES_PER_SAMPLE: u64 = 4;
/// Most channels a 32-bit float WAV can hold: its block size (channels × 4 bytes) is a 16-bit
/// field.
pub const MAX_FLOAT_WAV_CHANNELS: usize = u16::MAX as usize / BYTES_PER_SAMPLE as usize;
/// Bytes of the RIFF payload that are not sample data: "WAVE", fmt chunk (8 + 18), fact chunk
/// (8 + 4) and the data chunk header (8).
const HEADER_OVERHEAD: u64 = 4 + 8 + 18 + 8 + 4 + 8;

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, msg)
}

/// Builds the 58-byte header of a float WAV holding `n_frames` frames of `n_channels` channels.
/// Fails (InvalidInput) when the data would not fit the 32-bit RIFF length fields or when a
/// field is out of range.
fn float_wav_header(sample_rate_hz: u32, n_channels: usize, n_frames: u64) -> io::Result<Vec<u8>> {
    if n_channels == 0 {
        return Err(invalid("WAV needs at least 1 channel, got 0".into()));
    }
    if n_channels > MAX_FLOAT_WAV_CHANNELS {
        return Err(invalid(format!(
            "a 32-bit float WAV holds at most {MAX_FLOAT_WAV_CHANNELS} channels (its 16-bit block size), got {n_channels}"
        )));
    }
    let channels = n_channels as u16;
    if sample_rate_hz == 0 {
        return Err(invalid("WAV sample rate must be positive, got 0 Hz".into()));
    }
    let block_align = u64::from(channels) * BYTES_PER_SAMPLE;
    let data_len = n_frames
        .checked_mul(block_align)
        .filter(|&d| d + HEADER_OVERHEAD <= u64::from(u32::MAX))
        .ok_or_else(|| {
            invalid(format!(
                "WAV data of {n_frames} frames x {n_channels} channels exceeds the 4 GiB RIFF limit"
            ))
        })?;
    let byte_rate = u64::from(sample_rate_hz) * block_align;
    let byte_rate = u32::try_from(byte_rate).map_err(|_| {
        invalid(format!(
            "WAV byte rate {byte_rate} (rate {sample_rate_hz} Hz x {block_align} bytes) exceeds 32 bits"
        ))
    })?;
    // fact chunk: sample frames per channel, 32 bits.
    let fact = u32::try_from(n_frames).unwrap_or(u32::MAX);
    let mut h = Vec::with_capacity(58);
    h.extend_from_slice(b"RIFF");
    h.extend_from_slice(&((data_len + HEADER_OVERHEAD) as u32).to_le_bytes());
    h.extend_from_slice(b"WAVEfmt ");
    h.extend_from_slice(&18u32.to_le_bytes());
    h.extend_from_slice(&3u16.to_le_bytes()); // WAVE_FORMAT_IEEE_FLOAT
    h.extend_from_slice(&channels.to_le_bytes());
    h.extend_from_slice(&sample_rate_hz.to_le_bytes());
    h.extend_from_slice(&byte_rate.to_le_bytes());
    h.extend_from_slice(&(block_align as u16).to_le_bytes());
    h.extend_from_slice(&32u16.to_le_bytes());
    h.extend_from_slice(&0u16.to_le_bytes()); // cbSize
    h.extend_from_slice(b"fact");
    h.extend_from_slice(&4u32.to_le_bytes());
    h.extend_from_slice(&fact.to_le_bytes());
    h.extend_from_slice(b"data");
    h.extend_from_slice(&(data_len as u32).to_le_bytes());
    Ok(h)
}

/// Appends frames `range` of the channel-major `channels` to `buf`, interleaved, as f32 LE.
fn interleave_f32(channels: &[Vec<f64>], start: usize, end: usize, buf: &mut Vec<u8>) {
    for i in start..end {
        for ch in channels {
            buf.extend_from_slice(&(ch[i] as f32).to_le_bytes());
        }
    }
}

/// Writes `channels` (channel-major, all the same length) as a complete 32-bit IEEE-float WAV to
/// `out`, which need not be seekable. Samples are rounded to f32.
///
/// Errors: `InvalidInput` when there are no channels, the channels differ in length, the rate is
/// 0 or the data exceeds the RIFF size limit; otherwise whatever `out` reports.
pub fn write_wav_f32<W: Write>(
    out: W,
    sample_rate_hz: u32,
    channels: &[Vec<f64>],
) -> io::Result<()> {
    let n_frames = channels.first().map_or(0, Vec::len);
    if let Some((k, ch)) = channels
        .iter()
        .enumerate()
        .find(|(_, c)| c.len() != n_frames)
    {
        return Err(invalid(format!(
            "all channels must have the same length: channel 0 has {n_frames} samples, channel {k} has {}",
            ch.len()
        )));
    }
    let block = Block::new(channels.to_vec());
    let mut w = WavStreamWriter::new(out, sample_rate_hz, channels.len(), n_frames as u64)?;
    w.write_block(&block)?;
    w.finish()?.flush()
}

/// Streams a 32-bit IEEE-float WAV of a length announced up front to a non-seekable writer,
/// block by block, so that a generator never holds its whole signal.
///
/// The header is written by [`WavStreamWriter::new`]; [`WavStreamWriter::finish`] checks that
/// exactly the announced number of frames arrived (a WAV whose header lies is worse than none).
#[derive(Debug)]
pub struct WavStreamWriter<W: Write> {
    out: W,
    n_channels: usize,
    n_frames: u64,
    written_frames: u64,
    buf: Vec<u8>,
}

impl<W: Write> WavStreamWriter<W> {
    /// Writes the header for `n_frames` frames of `n_channels` channels at `sample_rate_hz`.
    pub fn new(
        mut out: W,
        sample_rate_hz: u32,
        n_channels: usize,
        n_frames: u64,
    ) -> io::Result<Self> {
        let header = float_wav_header(sample_rate_hz, n_channels, n_frames)?;
        out.write_all(&header)?;
        Ok(Self {
            out,
            n_channels,
            n_frames,
            written_frames: 0,
            buf: Vec::new(),
        })
    }

    /// Appends the frames of `block`. Errors (`InvalidInput`) when the block has the wrong
    /// number of channels, ragged channels, or would exceed the announced frame count.
    pub fn write_block(&mut self, block: &Block) -> io::Result<()> {
        if block.channels.len() != self.n_channels {
            return Err(invalid(format!(
                "block has {} channels, the WAV header announced {}",
                block.channels.len(),
                self.n_channels
            )));
        }
        let frames = block.frames();
        if let Some((k, ch)) = block
            .channels
            .iter()
            .enumerate()
            .find(|(_, c)| c.len() != frames)
        {
            return Err(invalid(format!(
                "ragged block: channel 0 has {frames} samples, channel {k} has {}",
                ch.len()
            )));
        }
        if self.written_frames + frames as u64 > self.n_frames {
            return Err(invalid(format!(
                "WAV header announced {} frames, got at least {}",
                self.n_frames,
                self.written_frames + frames as u64
            )));
        }
        // Convert in chunks of at most CHUNK_BYTES so that a huge block (or thousands of
        // channels) does not double its memory.
        const CHUNK_BYTES: usize = 4 << 20;
        let chunk_frames = (CHUNK_BYTES / (4 * self.n_channels)).max(1);
        let mut start = 0;
        while start < frames {
            let end = (start + chunk_frames).min(frames);
            self.buf.clear();
            interleave_f32(&block.channels, start, end, &mut self.buf);
            self.out.write_all(&self.buf)?;
            start = end;
        }
        self.written_frames += frames as u64;
        Ok(())
    }

    /// Frames written so far.
    pub fn written_frames(&self) -> u64 {
        self.written_frames
    }

    /// Checks that all announced frames were written, flushes and returns the writer.
    /// Errors (`InvalidData`) when fewer frames than announced were written.
    pub fn finish(mut self) -> io::Result<W> {
        if self.written_frames != self.n_frames {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "WAV header announced {} frames, only {} were written",
                    self.n_frames, self.written_frames
                ),
            ));
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hound_reads_what_we_write() {
        let chans = vec![vec![0.5, -0.25, 1.5], vec![1e-3, 2.0, -3.0]];
        let mut bytes = Vec::new();
        write_wav_f32(&mut bytes, 4000, &chans).unwrap();
        assert_eq!(bytes.len(), 58 + 3 * 2 * 4);
        let riff_len = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize;
        assert_eq!(riff_len + 8, bytes.len());
        let mut r = hound::WavReader::new(std::io::Cursor::new(bytes)).unwrap();
        let spec = r.spec();
        assert_eq!(spec.channels, 2);
        assert_eq!(spec.sample_rate, 4000);
        assert_eq!(spec.sample_format, hound::SampleFormat::Float);
        let s: Vec<f32> = r.samples::<f32>().map(|x| x.unwrap()).collect();
        let expect: Vec<f32> = (0..3)
            .flat_map(|i| chans.iter().map(move |c| c[i] as f32))
            .collect();
        assert_eq!(s, expect);
    }

    #[test]
    fn stream_writer_checks_frame_count() {
        let mut w = WavStreamWriter::new(Vec::new(), 100, 1, 3).unwrap();
        w.write_block(&Block::new(vec![vec![1.0, 2.0]])).unwrap();
        assert!(w.write_block(&Block::new(vec![vec![1.0, 2.0]])).is_err());
        assert!(w
            .write_block(&Block::new(vec![vec![1.0], vec![2.0]]))
            .is_err());
        assert!(w.finish().is_err());
    }

    #[test]
    fn bad_arguments_are_errors() {
        assert!(write_wav_f32(Vec::new(), 100, &[]).is_err());
        assert!(write_wav_f32(Vec::new(), 0, &[vec![1.0]]).is_err());
        assert!(write_wav_f32(Vec::new(), 100, &[vec![1.0], vec![]]).is_err());
        assert!(WavStreamWriter::new(Vec::new(), 100, 2, u64::MAX / 2).is_err());
    }

    /// Found writing a 60 000-sensor recording set: the 16-bit block size wrapped and hound
    /// refused the file ("sample bits exceeds size of sample"). The most channels still give a
    /// file hound reads; one more is an error, not a corrupt header.
    #[test]
    fn regression_block_size_of_many_channels_never_wraps() {
        let chans = vec![vec![0.25]; MAX_FLOAT_WAV_CHANNELS];
        let mut bytes = Vec::new();
        write_wav_f32(&mut bytes, 100, &chans).unwrap();
        let r = hound::WavReader::new(std::io::Cursor::new(bytes)).unwrap();
        assert_eq!(r.spec().channels as usize, MAX_FLOAT_WAV_CHANNELS);
        let e = WavStreamWriter::new(Vec::new(), 100, MAX_FLOAT_WAV_CHANNELS + 1, 1).unwrap_err();
        assert!(e.to_string().contains("at most 16383"), "{e}");
    }
}

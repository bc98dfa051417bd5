//! Writes recording sets (FORMATS.md §1): `responses.wav` (or `responses.csv` beyond the WAV's
//! channel limit), `sensors.csv`, `excitation.csv` and `meta.json`, as
//! [`crate::source::recording_set`] reads them back.

use std::io::Write;
use std::path::Path;

use super::atomic::AtomicFile;
use super::wav::{write_wav_f32, WavStreamWriter, MAX_FLOAT_WAV_CHANNELS};
use crate::source::recording_set::{io_err, Excitation, RecordingMeta, Sensor};
use crate::source::{Block, Source, SourceError};

/// Writes a recording set to `dir` (created if needed): `responses.wav` (32-bit float; over
/// [`MAX_FLOAT_WAV_CHANNELS`] sensors `responses.csv` with a time column),
/// `sensors.csv`, `excitation.csv` and `meta.json` (with `fs` set to `sample_rate_hz`).
/// Errors: `ChannelCount` when `channels` and `sensors` differ in number, `Setting` when the rate
/// is not a positive whole number of Hz (a WAV header stores an integer rate).
pub fn write_recording_set(
    dir: &Path,
    meta: &RecordingMeta,
    sensors: &[Sensor],
    excitation: &[Excitation],
    sample_rate_hz: f64,
    channels: &[Vec<f64>],
) -> Result<(), SourceError> {
    if channels.len() > MAX_FLOAT_WAV_CHANNELS {
        let info = crate::source::SignalInfo {
            sample_rate_hz,
            channel_names: sensors.iter().map(|s| s.id.clone()).collect(),
        };
        let mut src = crate::source::memory::MemorySource::new(info, channels.to_vec())?;
        return write_recording_set_streamed(dir, meta, sensors, excitation, &mut src, 4096);
    }
    write_set(
        dir,
        (meta, sensors, excitation),
        sample_rate_hz,
        channels.len(),
        "responses.wav",
        &mut |w| write_wav_f32(w, sample_rate_hz as u32, channels),
    )
}

/// [`write_recording_set`] from a source of known length, block by block: the responses are
/// never held whole (a simulation of any number of sensors goes straight to disk). Errors also
/// when the source's length is unknown or its rate differs from `sample_rate_hz`.
pub fn write_recording_set_streamed(
    dir: &Path,
    meta: &RecordingMeta,
    sensors: &[Sensor],
    excitation: &[Excitation],
    source: &mut dyn Source,
    block_frames: usize,
) -> Result<(), SourceError> {
    let rate = source.info().sample_rate_hz;
    let Some(frames) = source.duration_frames() else {
        return Err(SourceError::Setting {
            what: dir.display().to_string(),
            detail:
                "a recording set is written from a source of known length; this one is a stream"
                    .into(),
        });
    };
    let n_channels = source.info().channels();
    let as_wav = n_channels <= MAX_FLOAT_WAV_CHANNELS;
    let mut failure = None;
    let written = write_set(
        dir,
        (meta, sensors, excitation),
        rate,
        n_channels,
        if as_wav {
            "responses.wav"
        } else {
            "responses.csv"
        },
        &mut |w| {
            let mut sink = if as_wav {
                ResponseSink::Wav(WavStreamWriter::new(w, rate as u32, n_channels, frames)?)
            } else {
                ResponseSink::csv(w, &source.info().channel_names)?
            };
            let mut block = Block::default();
            loop {
                match source.read_block(block_frames.max(1), &mut block) {
                    Ok(true) => sink.write_block(&block, rate)?,
                    Ok(false) => break,
                    Err(e) => {
                        let msg = e.to_string();
                        failure = Some(e);
                        return Err(std::io::Error::other(msg));
                    }
                }
            }
            sink.finish()
        },
    );
    written.map_err(|e| failure.unwrap_or(e))
}

/// [`write_recording_set`] with FRFs in place of time responses: `responses.uff` (dataset 2411
/// nodes and one dataset 58 accelerance per sensor on the grid 0, df, …, fmax), read back by the
/// recording-set reader through the inverse FFT (the FRFs are exactly those whose inverse FFT
/// the impulse responses are).
pub fn write_recording_set_uff(
    dir: &Path,
    meta: &RecordingMeta,
    sensors: &[Sensor],
    excitation: &[Excitation],
    df_hz: f64,
    frfs: &[Vec<rustfft::num_complex::Complex<f64>>],
) -> Result<(), SourceError> {
    let fmax = df_hz * frfs.first().map_or(0, |h| h.len().saturating_sub(1)) as f64;
    write_set(
        dir,
        (meta, sensors, excitation),
        2.0 * fmax,
        frfs.len(),
        "responses.uff",
        &mut |w| super::uff::write_frf_datasets(w, df_hz, frfs, sensors, excitation.first()),
    )
}

/// Where streamed responses go: a float WAV, or (more channels than a WAV holds) a CSV with a
/// time column and the samples as f32 (the WAV's precision).
enum ResponseSink<'a> {
    Wav(WavStreamWriter<&'a mut dyn Write>),
    Csv { out: &'a mut dyn Write, frames: u64 },
}

impl<'a> ResponseSink<'a> {
    fn csv(out: &'a mut dyn Write, names: &[String]) -> std::io::Result<Self> {
        write!(out, "time")?;
        for n in names {
            write!(out, ",{n}")?;
        }
        writeln!(out)?;
        Ok(ResponseSink::Csv { out, frames: 0 })
    }

    fn write_block(&mut self, block: &Block, rate_hz: f64) -> std::io::Result<()> {
        match self {
            ResponseSink::Wav(w) => w.write_block(block),
            ResponseSink::Csv { out, frames } => {
                for t in 0..block.frames() {
                    write!(out, "{}", *frames as f64 / rate_hz)?;
                    for c in &block.channels {
                        write!(out, ",{}", c[t] as f32)?;
                    }
                    writeln!(out)?;
                    *frames += 1;
                }
                Ok(())
            }
        }
    }

    fn finish(self) -> std::io::Result<()> {
        match self {
            ResponseSink::Wav(w) => w.finish().map(|_| ()),
            ResponseSink::Csv { .. } => Ok(()),
        }
    }
}

/// The common part of the two writers: checks, then the WAV (by `write_wav`) and the metadata.
fn write_set(
    dir: &Path,
    (meta, sensors, excitation): (&RecordingMeta, &[Sensor], &[Excitation]),
    sample_rate_hz: f64,
    n_channels: usize,
    responses_name: &str,
    write_responses: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), SourceError> {
    let what = dir.display().to_string();
    if n_channels != sensors.len() {
        return Err(SourceError::ChannelCount {
            what,
            expected: sensors.len(),
            got: n_channels,
        });
    }
    if !(sample_rate_hz >= 1.0 && sample_rate_hz <= f64::from(u32::MAX))
        || sample_rate_hz.fract() != 0.0
    {
        return Err(SourceError::Setting {
            what,
            detail: format!(
                "sample rate: expected a positive whole number of Hz for the WAV header, got {sample_rate_hz}"
            ),
        });
    }
    std::fs::create_dir_all(dir).map_err(|e| io_err(dir, e))?;
    // Every file is written under a temporary name first (the responses, the long part, before
    // the rest). Then the old responses go, the small files are renamed into place, and the
    // responses last: the set is readable (it has a responses file) only once every file in it
    // is new. A run killed on the way leaves hidden `.partial` files and no set, never a set
    // whose responses and sensors disagree.
    let staged = |name: &str, f: &dyn Fn(&mut dyn Write) -> std::io::Result<()>| {
        let path = dir.join(name);
        let mut w = AtomicFile::create(&path).map_err(|e| io_err(&path, e))?;
        f(&mut w).map_err(|e| io_err(&path, e))?;
        Ok::<_, SourceError>(w)
    };
    let responses = {
        let path = dir.join(responses_name);
        let mut w = AtomicFile::create(&path).map_err(|e| io_err(&path, e))?;
        write_responses(&mut w).map_err(|e| io_err(&path, e))?;
        w
    };
    let with_z = sensors.iter().any(|s| s.z_m.is_some());
    let sensors_file = staged("sensors.csv", &|w| {
        let mut table = csv::Writer::from_writer(w);
        let header: &[&str] = if with_z {
            &["id", "x", "y", "z", "dir"]
        } else {
            &["id", "x", "y", "dir"]
        };
        table.write_record(header)?;
        for s in sensors {
            let mut row = vec![s.id.clone(), s.x_m.to_string(), s.y_m.to_string()];
            if with_z {
                row.push(s.z_m.map_or(String::new(), |z| z.to_string()));
            }
            row.push(s.dir.to_string());
            table.write_record(&row)?;
        }
        table.flush()
    })?;
    let excitation_file = staged("excitation.csv", &|w| {
        let mut table = csv::Writer::from_writer(w);
        table.write_record(["x", "y", "dir", "force"])?;
        for e in excitation {
            table.write_record([
                e.x_m.to_string(),
                e.y_m.to_string(),
                e.dir.to_string(),
                e.force_n.to_string(),
            ])?;
        }
        table.flush()
    })?;
    // As given (a window the responses carry stays declared), with the rate written.
    let meta = RecordingMeta {
        fs: Some(sample_rate_hz),
        ..meta.clone()
    };
    let meta_file = staged("meta.json", &|w| {
        serde_json::to_writer_pretty(&mut *w, &meta).map_err(std::io::Error::other)?;
        writeln!(w)
    })?;
    // Old responses of either kind go first (a stale file of the other kind would also be read
    // instead: the WAV wins).
    for stale in [
        "responses.wav",
        "responses.csv",
        "responses.uff",
        "responses.unv",
        "frf.csv",
    ] {
        let path = dir.join(stale);
        if path.exists() {
            std::fs::remove_file(&path).map_err(|e| io_err(&path, e))?;
        }
    }
    for file in [sensors_file, excitation_file, meta_file, responses] {
        let path = file.target().to_path_buf();
        file.commit().map_err(|e| io_err(&path, e))?;
    }
    Ok(())
}

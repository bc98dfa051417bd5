//! Throughput of the whole analysis as a user runs it (`dampscope bench`).
//!
//! The input is what a lab pipes in: interleaved little-endian f32 samples. Unless a file is
//! given, it is made here once, in memory — per channel three decaying modes (frequency
//! 40 Hz … 0.4 fs, damping ratio 0.5 … 5 %) and white noise 80 dB below the peak, the signal of
//! the peers' script (`shared/peers/throughput.py`) — and every repeat decodes it again through
//! [`RawSource`]. So a measurement covers ingest, segmentation, front end, estimators and the
//! row sink (rows formatted as CSV into a sink that discards them), on the threads a real run
//! uses; only the pipe and the process start are left out.
//!
//! Per front end it gives the best wall time of `repeat` runs, and from one more, profiled run
//! ([`RunOptions::profile_stages`]) the share of thread time per stage. For the STFT it also
//! times the FFTs alone — realfft's r2c of the frame length, once per hop, on the same threads —
//! the bound no STFT of these frames can beat. An `ingest` row times the decoding alone.

use std::io::Cursor;
use std::sync::Arc;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::output::raw::append_interleaved_f32_le;
use crate::output::{TableFormat, TableWriter};
use crate::pipeline::{run_with, AnalysisConfig, RunOptions, StageTimes};
use crate::plan::{BandLayout, FrontEndKind, FrontEndSpec};
use crate::source::noise::GaussianNoise;
use crate::source::raw::{RawFormat, RawSource};
use crate::source::synth::{decaying_sines, Mode};
use crate::source::{Block, Source};

/// Default channel count of a bench run (the 64-channel array).
pub const DEFAULT_BENCH_CHANNELS: usize = 64;
/// Default seconds of signal per channel.
pub const DEFAULT_BENCH_SECONDS: f64 = 10.0;
/// Default sample rates, Hz: a structural test and an audio rate.
pub const DEFAULT_BENCH_FS_HZ: [f64; 2] = [4096.0, 48000.0];
/// Default number of timed runs per front end (the best counts).
pub const DEFAULT_BENCH_REPEAT: usize = 3;
/// Seed of the synthetic signal (fixed: every run times the same samples).
pub const BENCH_SEED: u64 = 1;
/// Level of the synthetic signal's noise below its peak, dB.
pub const BENCH_NOISE_DB: f64 = 80.0;

/// What to time.
#[derive(Clone, Debug)]
pub struct BenchPlan {
    /// Front ends to time, in order.
    pub front_ends: Vec<FrontEndKind>,
    /// Their settings (the kind is replaced by each of `front_ends`).
    pub front_end: FrontEndSpec,
    /// Bands (resolved per sample rate).
    pub bands: BandLayout,
    /// Estimate and segmentation settings.
    pub config: AnalysisConfig,
    /// Worker threads (None: one per core).
    pub threads: Option<usize>,
    /// Timed runs per front end; the fastest counts.
    pub repeat: usize,
}

/// The input of a bench: the samples, encoded as they arrive on standard input.
#[derive(Clone, Debug)]
pub struct BenchInput {
    /// Interleaved little-endian samples.
    pub bytes: Arc<[u8]>,
    /// Their sample type.
    pub format: RawFormat,
    /// Sample rate, Hz.
    pub fs_hz: f64,
    /// Channels per frame.
    pub channels: usize,
}

impl BenchInput {
    /// The synthetic decays described in the module docs, `seconds` long per channel.
    pub fn synthetic(channels: usize, fs_hz: f64, seconds: f64) -> Result<BenchInput> {
        if channels == 0
            || !(fs_hz > 0.0 && fs_hz.is_finite())
            || !(seconds > 0.0 && seconds.is_finite())
        {
            return Err(Error::setting(
                "bench input",
                format!(
                    "expected ≥ 1 channel, a positive sample rate and duration, got {channels} channels, {fs_hz} Hz, {seconds} s"
                ),
            ));
        }
        let n = (seconds * fs_hz).round() as usize;
        let bytes = channels as f64 * n as f64 * 4.0;
        // f64 per channel, their f32 encoding, one channel's synthesis in flight.
        crate::budget::check("the bench signal", bytes * 5.0)?;
        let mut rng = GaussianNoise::new(BENCH_SEED);
        let uniform = |rng: &mut GaussianNoise, lo: f64, hi: f64| {
            lo + (hi - lo) * (rng.next_u64() >> 11) as f64 / 2f64.powi(53)
        };
        let noise = 10f64.powf(-BENCH_NOISE_DB / 20.0);
        let signals: Vec<Vec<f64>> = (0..channels)
            .map(|_| {
                let modes: Vec<Mode> = (0..3)
                    .map(|_| {
                        let f = uniform(&mut rng, 40.0, 0.4 * fs_hz);
                        let zeta = uniform(&mut rng, 0.005, 0.05);
                        let amplitude = uniform(&mut rng, 0.3, 1.0);
                        let phase = uniform(&mut rng, 0.0, 2.0 * std::f64::consts::PI);
                        Mode::new(f, zeta, amplitude, phase.to_degrees())
                    })
                    .collect();
                let x = decaying_sines(&modes, fs_hz, seconds);
                let peak = x
                    .iter()
                    .fold(0.0f64, |m, v| m.max(v.abs()))
                    .max(f64::MIN_POSITIVE);
                x.iter()
                    .map(|v| v / peak + noise * rng.next_gaussian())
                    .collect()
            })
            .collect();
        let mut bytes = Vec::new();
        append_interleaved_f32_le(&signals, &mut bytes);
        Ok(BenchInput {
            bytes: bytes.into(),
            format: RawFormat::F32,
            fs_hz,
            channels,
        })
    }

    /// Sample frames (samples per channel).
    pub fn frames(&self) -> usize {
        self.bytes.len() / (self.channels * self.format.bytes()).max(1)
    }

    /// Seconds of signal per channel.
    pub fn seconds(&self) -> f64 {
        self.frames() as f64 / self.fs_hz
    }

    /// A fresh source over the samples.
    pub fn source(&self) -> Result<Box<dyn Source>> {
        let frame_bytes = (self.channels * self.format.bytes()).max(1);
        // In memory, its length is known: the decays are laid out as for a file.
        Ok(Box::new(
            RawSource::new(
                Cursor::new(self.bytes.clone()),
                "bench input",
                self.format,
                self.fs_hz,
                self.channels,
            )?
            .expecting_frames((self.bytes.len() / frame_bytes) as u64),
        ))
    }
}

/// One line of the bench table.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchRow {
    /// Sample rate, Hz.
    pub fs_hz: f64,
    /// Front end name, or `ingest` (decoding alone).
    pub front_end: String,
    /// Bands analysed (0 for ingest).
    pub bands: usize,
    /// Channels.
    pub channels: usize,
    /// Seconds of signal per channel.
    pub seconds: f64,
    /// Worker threads used.
    pub threads: usize,
    /// Best wall time of the repeats, s.
    pub wall_s: f64,
    /// Channel-samples per second, all channels together.
    pub samples_per_s: f64,
    /// Samples per second and channel.
    pub samples_per_s_per_channel: f64,
    /// Samples per second per worker thread.
    pub samples_per_s_per_thread: f64,
    /// Channel-seconds of signal per second of wall time.
    pub realtime_factor: f64,
    /// Input bytes per second.
    pub bytes_per_s: f64,
    /// Share of thread time per stage in the profiled run (0…1; `None` for ingest).
    pub stages: Option<StageShares>,
    /// STFT only: channel-samples per second if the run did nothing but its FFTs.
    pub fft_bound_samples_per_s: Option<f64>,
}

/// Where the thread time of a run went, as fractions of their sum.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct StageShares {
    /// Decoding the input.
    pub read: f64,
    /// Onset search and new-hit watch.
    pub segment: f64,
    /// STFT or filter bank.
    pub front_end: f64,
    /// Band estimators.
    pub estimator: f64,
    /// Formatting the rows.
    pub output: f64,
}

impl StageShares {
    fn of(t: &StageTimes) -> StageShares {
        let total = t.total_s().max(f64::MIN_POSITIVE);
        StageShares {
            read: t.read_s / total,
            segment: t.segment_s / total,
            front_end: t.front_end_s / total,
            estimator: t.estimator_s / total,
            output: t.output_s / total,
        }
    }
}

impl BenchRow {
    fn new(input: &BenchInput, front_end: &str, bands: usize, threads: usize, wall_s: f64) -> Self {
        let frames = input.frames() as f64;
        let total = frames * input.channels as f64;
        let wall = wall_s.max(f64::MIN_POSITIVE);
        BenchRow {
            fs_hz: input.fs_hz,
            front_end: front_end.to_string(),
            bands,
            channels: input.channels,
            seconds: input.seconds(),
            threads,
            wall_s,
            samples_per_s: total / wall,
            samples_per_s_per_channel: frames / wall,
            samples_per_s_per_thread: total / wall / threads.max(1) as f64,
            realtime_factor: input.channels as f64 * input.seconds() / wall,
            bytes_per_s: input.bytes.len() as f64 / wall,
            stages: None,
            fft_bound_samples_per_s: None,
        }
    }
}

/// Times decoding alone: every block read from a fresh source, nothing done with it.
pub fn bench_ingest(input: &BenchInput, repeat: usize) -> Result<BenchRow> {
    let mut best = f64::INFINITY;
    let mut block = Block::default();
    for _ in 0..repeat.max(1) {
        let mut source = input.source()?;
        let t0 = Instant::now();
        while source.read_block(crate::pipeline::DEFAULT_BLOCK_FRAMES, &mut block)? {}
        best = best.min(t0.elapsed().as_secs_f64());
    }
    Ok(BenchRow::new(input, "ingest", 0, 1, best))
}

/// Times the whole analysis of `input` through the front end `kind`.
pub fn bench_front_end(
    input: &BenchInput,
    plan: &BenchPlan,
    kind: FrontEndKind,
) -> Result<BenchRow> {
    let spec = plan.front_end.with_kind(kind);
    let bands = plan.bands.resolve(input.fs_hz, None)?.bands;
    let factory = spec.factory(input.fs_hz, bands.clone())?;
    let once = |profile_stages: bool| -> Result<(f64, crate::pipeline::RunSummary)> {
        let source = input.source()?;
        let mut table = TableWriter::new(std::io::sink(), TableFormat::Csv);
        let options = RunOptions {
            threads: plan.threads,
            profile_stages,
            ..Default::default()
        };
        let t0 = Instant::now();
        table.write_header()?;
        let summary = run_with(source, &factory, &plan.config, options, |rows| {
            table.write_rows(rows)
        })?;
        Ok((t0.elapsed().as_secs_f64(), summary))
    };
    let mut best = f64::INFINITY;
    let mut threads = 1;
    for _ in 0..plan.repeat.max(1) {
        let (wall, summary) = once(false)?;
        best = best.min(wall);
        threads = summary.threads;
    }
    let (_, profiled) = once(true)?;
    let mut row = BenchRow::new(input, kind.name(), bands.len(), threads, best);
    row.stages = Some(StageShares::of(&profiled.stages));
    if kind == FrontEndKind::Stft {
        row.fft_bound_samples_per_s =
            Some(stft_fft_bound(input, &spec, &bands, threads, plan.repeat)?);
    }
    Ok(row)
}

/// Channel-samples per second of an STFT that did nothing but its FFTs: realfft's r2c of the
/// frame length (times the zero padding) once per hop over every channel, on `threads` threads;
/// the best of `repeat` runs. The frame length and hop are those of the STFT front end built for
/// `bands`.
pub fn stft_fft_bound(
    input: &BenchInput,
    spec: &FrontEndSpec,
    bands: &[crate::frontend::Band],
    threads: usize,
    repeat: usize,
) -> Result<f64> {
    // The front end's own frame length and hop, as the STFT path uses them.
    let stft = crate::frontend::stft::StftFrontEnd::new(spec.stft, input.fs_hz, bands)?;
    let (win, hop) = (stft.window_samples(), stft.hop_samples());
    let nfft = win * spec.stft.zero_pad.max(1);
    let frames = input.frames();
    let per_channel = if frames >= win {
        (frames - win) / hop + 1
    } else {
        0
    };
    let ffts = per_channel * input.channels;
    let fft = realfft::RealFftPlanner::<f64>::new().plan_fft_forward(nfft);
    let threads = threads.max(1);
    let mut best = f64::INFINITY;
    for _ in 0..repeat.max(1) {
        best = best.min(time_ffts(&fft, nfft, ffts, threads));
    }
    Ok((frames * input.channels) as f64 / best.max(f64::MIN_POSITIVE))
}

/// Seconds `threads` threads take for `ffts` forward transforms of length `nfft` in all.
fn time_ffts(
    fft: &Arc<dyn realfft::RealToComplex<f64>>,
    nfft: usize,
    ffts: usize,
    threads: usize,
) -> f64 {
    let t0 = Instant::now();
    std::thread::scope(|scope| {
        for t in 0..threads {
            let fft = fft.clone();
            let share = ffts / threads + usize::from(t < ffts % threads);
            scope.spawn(move || {
                // A fixed frame copied in each time (the FFT uses its input as scratch).
                let frame: Vec<f64> = (0..nfft)
                    .map(|i| ((i * 7919) % 1000) as f64 * 1e-3)
                    .collect();
                let mut x = fft.make_input_vec();
                let mut y = fft.make_output_vec();
                let mut scratch = fft.make_scratch_vec();
                for _ in 0..share {
                    x.copy_from_slice(&frame);
                    let _ = fft.process_with_scratch(&mut x, &mut y, &mut scratch);
                    std::hint::black_box(&y);
                }
            });
        }
    });
    t0.elapsed().as_secs_f64()
}

/// Times every front end of `plan` on `input`, and the ingest alone, calling `on_row` with
/// each row as it is measured.
pub fn bench(
    input: &BenchInput,
    plan: &BenchPlan,
    mut on_row: impl FnMut(&BenchRow),
) -> Result<Vec<BenchRow>> {
    plan.config.validate()?;
    let mut rows = vec![bench_ingest(input, plan.repeat)?];
    on_row(&rows[0]);
    for &kind in &plan.front_ends {
        let row = bench_front_end(input, plan, kind)?;
        on_row(&row);
        rows.push(row);
    }
    Ok(rows)
}

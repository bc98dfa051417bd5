//! Throughput of the STFT + online Schroeder path, in samples per second per channel.
//!
//! `analyzer/*`: one channel on one core (ChannelAnalyzer: onset, STFT, one estimator per band).
//! `pipeline/*`: the threaded pipeline (reader → workers → rows) on 1 and 64 channels; criterion's
//! elements/s there is samples per channel × channels, so divide by the channel count.
//! `bench_command/*`: exactly what `dampscope bench` times (the peers' synthetic decays, 64
//! channels × 10 s as raw f32, IEC octave bands, default settings, rows formatted as CSV), per
//! front end: its elements/s is the command's `samples_per_s`, measured by criterion.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use dampscope::frontend::bands::default_bands;
use dampscope::pipeline::{self, AnalysisConfig, ChannelAnalyzer, FrontEndFactory};
use dampscope::source::{Block, SignalInfo, Source, SourceError};
use std::sync::Arc;

fn decay(fs: f64, seconds: f64, seed: usize) -> Vec<f64> {
    let n = (fs * seconds) as usize;
    let f = 55.0 + 13.0 * (seed % 7) as f64;
    (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            (-2.0 * t).exp() * (2.0 * std::f64::consts::PI * f * t).sin()
        })
        .collect()
}

struct Memory {
    info: SignalInfo,
    data: Arc<Vec<Vec<f64>>>,
    pos: usize,
}

impl Source for Memory {
    fn info(&self) -> &SignalInfo {
        &self.info
    }
    fn read_block(&mut self, max: usize, block: &mut Block) -> Result<bool, SourceError> {
        let n = self.data[0].len();
        if self.pos >= n {
            block.channels.clear();
            return Ok(false);
        }
        let end = (self.pos + max).min(n);
        block.channels = self
            .data
            .iter()
            .map(|c| c[self.pos..end].to_vec())
            .collect();
        self.pos = end;
        Ok(true)
    }
}

/// Every sample goes through the STFT: no early end of the decay.
fn no_early_end() -> AnalysisConfig {
    AnalysisConfig {
        segmentation: dampscope::pipeline::Segmentation {
            end_drop_db: f64::INFINITY,
            ..Default::default()
        },
        ..Default::default()
    }
}

fn factory(fs: f64) -> FrontEndFactory {
    dampscope::plan::FrontEndSpec::default()
        .factory(fs, default_bands(fs).unwrap())
        .unwrap()
}

fn analyzer(c: &mut Criterion) {
    let mut g = c.benchmark_group("analyzer");
    g.sample_size(10);
    // 16384 and 65536 Hz: 200 ms frames of 3277 = 29 · 113 and 13107 = 3 · 17 · 257 points,
    // the prime-factor FFT's wide stages and Rader's.
    for fs in [4000.0, 16384.0, 48000.0, 65536.0] {
        let x = decay(fs, 20.0, 0);
        let f = factory(fs);
        g.throughput(Throughput::Elements(x.len() as u64));
        g.bench_with_input(
            BenchmarkId::new("stft200ms_one_channel", fs as u64),
            &x,
            |b, x| {
                b.iter(|| {
                    let mut an = ChannelAnalyzer::new("c".into(), fs, f().unwrap(), no_early_end());
                    let mut rows = Vec::new();
                    for chunk in x.chunks(4096) {
                        an.push(chunk, &mut rows);
                    }
                    an.finish(false, &mut rows);
                    rows.len()
                })
            },
        );
    }
    g.finish();
}

fn pipeline_bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("pipeline");
    g.sample_size(10);
    for (fs, channels, seconds) in [
        (4000.0, 1, 20.0),
        (48000.0, 1, 20.0),
        (4000.0, 64, 5.0),
        (48000.0, 64, 2.0),
    ] {
        let data: Arc<Vec<Vec<f64>>> =
            Arc::new((0..channels).map(|k| decay(fs, seconds, k)).collect());
        let f = factory(fs);
        g.throughput(Throughput::Elements((data[0].len() * channels) as u64));
        let id = format!("{}ch_{}hz", channels, fs as u64);
        g.bench_function(id, |b| {
            b.iter(|| {
                let src = Memory {
                    info: SignalInfo {
                        sample_rate_hz: fs,
                        channel_names: (0..channels).map(|k| format!("ch{k}")).collect(),
                    },
                    data: data.clone(),
                    pos: 0,
                };
                let mut n = 0;
                pipeline::run(Box::new(src), &f, &no_early_end(), |rows| {
                    n += rows.len();
                    Ok(())
                })
                .unwrap();
                n
            })
        });
    }
    g.finish();
}

fn bench_command(c: &mut Criterion) {
    use dampscope::analysis::bench::{BenchInput, DEFAULT_BENCH_CHANNELS, DEFAULT_BENCH_SECONDS};
    use dampscope::output::{TableFormat, TableWriter};
    use dampscope::plan::{BandLayout, FrontEndKind};
    let mut g = c.benchmark_group("bench_command");
    g.sample_size(10);
    for fs in [4096.0, 48000.0] {
        let input =
            BenchInput::synthetic(DEFAULT_BENCH_CHANNELS, fs, DEFAULT_BENCH_SECONDS).unwrap();
        let bands = BandLayout {
            specs: vec!["octave".parse().unwrap()],
            ..Default::default()
        }
        .resolve(fs, None)
        .unwrap()
        .bands;
        g.throughput(Throughput::Elements(
            (input.frames() * DEFAULT_BENCH_CHANNELS) as u64,
        ));
        for kind in FrontEndKind::ALL {
            let factory = dampscope::plan::FrontEndSpec::default()
                .with_kind(kind)
                .factory(fs, bands.clone())
                .unwrap();
            g.bench_function(format!("{}_{}hz", kind.name(), fs as u64), |b| {
                b.iter(|| {
                    let mut table = TableWriter::new(std::io::sink(), TableFormat::Csv);
                    table.write_header().unwrap();
                    pipeline::run(
                        input.source().unwrap(),
                        &factory,
                        &AnalysisConfig::default(),
                        |rows| table.write_rows(rows),
                    )
                    .unwrap()
                    .rows
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, analyzer, pipeline_bench, bench_command);
criterion_main!(benches);

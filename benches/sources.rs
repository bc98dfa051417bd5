//! Decoding throughput of the sources, in sample frames per second (criterion's elements/s).
//!
//! `wav_f32/*` and `raw_f32/*`: 1 and 64 channels from memory; `csv/*`: 4 channels of text;
//! `synth`: one channel of eq. 4.5 with three modes and noise.

use std::io::Cursor;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use dampscope::output::write_wav_f32;
use dampscope::source::{
    Block, CsvSource, Mode, RawFormat, RawSource, Source, SynthSource, SynthSpec, WavSource,
};

const FRAMES: usize = 200_000;

fn signal(channels: usize) -> Vec<Vec<f64>> {
    (0..channels)
        .map(|c| (0..FRAMES).map(|i| ((i + c) as f64 * 0.01).sin()).collect())
        .collect()
}

fn drain(src: &mut dyn Source) -> usize {
    let mut b = Block::default();
    let mut n = 0;
    while let Ok(true) = src.read_block(8192, &mut b) {
        n += b.frames();
    }
    n
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("sources");
    g.sample_size(10);
    g.throughput(Throughput::Elements(FRAMES as u64));
    for ch in [1usize, 64] {
        let mut wav = Vec::new();
        write_wav_f32(&mut wav, 48000, &signal(ch)).expect("in-memory WAV");
        g.bench_with_input(BenchmarkId::new("wav_f32", ch), &wav, |b, wav| {
            b.iter(|| {
                drain(&mut WavSource::new(Cursor::new(wav.as_slice()), "bench").expect("WAV"))
            })
        });
        let raw: Vec<u8> = wav[58..].to_vec();
        g.bench_with_input(BenchmarkId::new("raw_f32", ch), &raw, |b, raw| {
            b.iter(|| {
                let mut s = RawSource::new(
                    Cursor::new(raw.as_slice()),
                    "bench",
                    RawFormat::F32,
                    48000.0,
                    ch,
                )
                .expect("raw");
                drain(&mut s)
            })
        });
    }
    let sig = signal(4);
    let mut text = String::from("time,a,b,c,d\n");
    let rows = sig[0].iter().zip(&sig[1]).zip(&sig[2]).zip(&sig[3]);
    for (i, (((a, b), c), d)) in rows.enumerate() {
        text += &format!("{},{a},{b},{c},{d}\n", i as f64 / 48000.0);
    }
    g.bench_function(BenchmarkId::new("csv", 4), |b| {
        b.iter(|| {
            drain(&mut CsvSource::new(Cursor::new(text.as_bytes()), "bench", None).expect("CSV"))
        })
    });
    let spec = SynthSpec {
        modes: ["170:0.025", "200:0.025", "230:0.025"]
            .iter()
            .map(|m| m.parse::<Mode>().expect("mode"))
            .collect(),
        sample_rate_hz: 48000.0,
        duration_s: FRAMES as f64 / 48000.0,
        snr_db: Some(60.0),
        seed: 1,
    };
    g.bench_function("synth", |b| {
        b.iter(|| drain(&mut SynthSource::new(spec.clone()).expect("synth")))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

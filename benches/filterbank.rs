//! Throughput of the Goyder-style filter bank (reversed filtering of a buffered decay):
//! criterion's elements/s is samples per second per channel; times the band count it is
//! band-samples per second (the aim: ≥ 1e9 per core). `DAMPSCOPE_SIMD=avx2` or `generic` caps
//! the instruction set the kernel picks, to measure the fallbacks.
//!
//! `cargo bench --bench filterbank`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use dampscope::frontend::bands::Band;
use dampscope::frontend::goyder::{GoyderFrontEnd, GoyderSettings};
use dampscope::frontend::iec_bands::{iec_bands, OctaveFraction};
use dampscope::frontend::octave_bank::{OctaveBankFrontEnd, OctaveBankSettings};
use dampscope::frontend::{Frame, FrontEnd};

fn decay(fs: f64, seconds: f64) -> Vec<f64> {
    let n = (fs * seconds) as usize;
    (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            (-3.0 * t).exp() * (2.0 * std::f64::consts::PI * 440.0 * t).sin()
        })
        .collect()
}

fn run(fe: &mut dyn FrontEnd, x: &[f64]) -> f64 {
    let mut s = 0.0;
    fe.reset();
    fe.process(x, &mut |f: Frame<'_>| s += f.energy[0]);
    fe.finish(&mut |f: Frame<'_>| s += f.energy[0]);
    s
}

fn goyder(c: &mut Criterion) {
    let fs = 48_000.0;
    let x = decay(fs, 1.0);
    let mut g = c.benchmark_group("goyder");
    g.throughput(Throughput::Elements(x.len() as u64));
    g.sample_size(10);
    for nb in [1usize, 4, 10, 30, 100] {
        let bands: Vec<Band> = (0..nb)
            .map(|k| Band::new(100.0 + 20.0 * k as f64, 120.0 + 20.0 * k as f64).unwrap())
            .collect();
        let mut fe = GoyderFrontEnd::new(GoyderSettings::default(), fs, &bands).unwrap();
        g.bench_with_input(BenchmarkId::new("bands", nb), &nb, |b, _| {
            b.iter(|| run(&mut fe, &x))
        });
    }
    g.finish();
    let mut g = c.benchmark_group("octave_bank");
    g.throughput(Throughput::Elements(x.len() as u64));
    g.sample_size(10);
    let (bands, _) = iec_bands(OctaveFraction::Third, 25.0, fs).unwrap();
    let mut fe = OctaveBankFrontEnd::new(OctaveBankSettings::default(), fs, &bands).unwrap();
    g.bench_with_input(
        BenchmarkId::new("third_octaves", bands.len()),
        &bands.len(),
        |b, _| b.iter(|| run(&mut fe, &x)),
    );
    g.finish();
}

criterion_group!(benches, goyder);
criterion_main!(benches);

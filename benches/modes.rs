//! Speed of the modal solve of the reference plate (32 × 48 × 2, 42 003 free dofs with the
//! internal incompatible-mode dofs): assembly, the lowest 40 modes, and every mode below 2 kHz
//! (the acceptance run, ~208 modes), with a small sample size.
//! `dampscope modes --fmax 2000 --timings` prints the same run's breakdown and peak memory.

use criterion::{criterion_group, criterion_main, Criterion};
use dampscope::sim::assembly::assemble;
use dampscope::sim::eigen::{lowest_modes, ModeRequest};
use dampscope::sim::model::Model;

fn modes(c: &mut Criterion) {
    let model = Model::reference_plate();
    let mut g = c.benchmark_group("modes");
    g.sample_size(10);
    g.bench_function("assemble reference plate", |b| {
        b.iter(|| assemble(&model).expect("reference plate assembles"))
    });
    let system = assemble(&model).expect("reference plate assembles");
    g.bench_function("lowest 40 modes of the reference plate", |b| {
        b.iter(|| lowest_modes(&system, ModeRequest::Count(40)).expect("modes"))
    });
    g.bench_function("all modes below 2 kHz of the reference plate", |b| {
        b.iter(|| lowest_modes(&system, ModeRequest::BelowHz(2000.0)).expect("modes"))
    });
    g.finish();
}

criterion_group!(benches, modes);
criterion_main!(benches);

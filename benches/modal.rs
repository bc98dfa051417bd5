//! Speed of multichannel modal identification on the test case: 99 off-node sensors of
//! a 48 × 72 × 2 plate, 3 s at 4 kHz, noise 50 dB below the mean signal power; modes below
//! 80 Hz (the acceptance target is ≤ 2 s wall) and below 300 Hz (≤ 10 s). Reading the set is
//! outside the timed part; `dampscope modal … --timings` prints the same breakdown per run.

use criterion::{criterion_group, criterion_main, Criterion};
use dampscope::modal::{identify, ModalSettings, Recordings};
use dampscope::source::recording_set::open_recording_set;

fn modal(c: &mut Criterion) {
    let mut set = open_recording_set(std::path::Path::new(
        "tests/data/modal/plate-48x72-homogeneous",
    ))
    .expect("test data");
    let mut rec = Recordings::from_source(set.source.as_mut(), 1 << 20).expect("read");
    rec.add_noise_mean_power(50.0, 1);
    let mut g = c.benchmark_group("modal");
    g.sample_size(10);
    for fmax_hz in [80.0, 300.0] {
        let settings = ModalSettings::new(0.5, fmax_hz);
        g.bench_function(
            format!("99 channels x 3 s, modes below {fmax_hz} Hz"),
            |b| b.iter(|| identify(&rec, &settings).expect("identify")),
        );
    }
    g.finish();
}

criterion_group!(benches, modal);
criterion_main!(benches);

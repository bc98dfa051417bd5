//! Speed of the FE responses on a reduced problem (16 × 24 × 2 plate, 0–500 Hz at 0.5 Hz,
//! 9 × 13 sensors): fast FRF + impulse responses (eigen-solve included and excluded), and the
//! direct solution at a few frequencies for scale; the same plate with a soft viscoelastic patch
//! and with a damping layer (issue 13: Craig–Bampton basis + state-space FRF). Small sample
//! sizes: the machine is shared.
//!
//! `cargo bench --bench simulate`

use criterion::{criterion_group, criterion_main, Criterion};
use dampscope::sim::assembly::assemble;
use dampscope::sim::eigen::{lowest_modes, ModeRequest};
use dampscope::sim::frf::direct_frf;
use dampscope::sim::model::{Model, Patch, SensorSpec};
use dampscope::sim::simulate::{simulate_system, SimulateOptions};
use dampscope::sim::Sls;

fn model() -> Model {
    let mut m = Model::reference_plate();
    m.mesh.nx = 16;
    m.mesh.ny = 24;
    m.output.fmax = 500.0;
    m.output.df = 0.5;
    m.output.sensors = SensorSpec::Grid { nx: 9, ny: 13 };
    m.material.loss_factor = 0.005;
    m.patches.push(Patch {
        x: [0.5, 1.0],
        y: [1.75, 2.5],
        youngs_modulus: None,
        poisson: None,
        density: None,
        loss_factor: Some(0.1),
        sls: None,
    });
    m
}

fn bench(c: &mut Criterion) {
    let m = model();
    let sys = assemble(&m).expect("model assembles");
    let opts = SimulateOptions::default();
    let modes =
        lowest_modes(&sys, ModeRequest::BelowHz(opts.mode_cutoff_factor * 500.0)).expect("modes");
    let mut g = c.benchmark_group("simulate_16x24x2_0-500Hz");
    g.sample_size(10);
    g.bench_function("fast_with_eigen", |b| {
        b.iter(|| simulate_system(&sys, None, 500.0, 0.5, &opts).expect("simulate"))
    });
    g.bench_function("fast_given_modes", |b| {
        b.iter(|| simulate_system(&sys, Some(&modes), 500.0, 0.5, &opts).expect("simulate"))
    });
    let few: Vec<f64> = (0..20).map(|k| 25.0 * k as f64).collect();
    g.bench_function("direct_20_frequencies", |b| {
        b.iter(|| direct_frf(&sys, &few).expect("direct"))
    });
    g.finish();
    // the patch region of the report's viscoelastic case, soft polymer or damping layer
    let viscoelastic = |soft: bool| {
        let mut v = m.clone();
        v.patches[0] = Patch {
            youngs_modulus: None,
            poisson: soft.then_some(0.4),
            density: Some(if soft { 1000.0 } else { 1.1 * 2700.0 }),
            loss_factor: Some(0.0),
            sls: Some(if soft {
                Sls {
                    e: 4.83e6,
                    e_inf: 1.0e6,
                    eta: 6.37e3,
                }
            } else {
                dampscope::diagnose::hypothesis::sls_with_peak(7.0e10, 0.3, 150.0)
            }),
            ..v.patches[0].clone()
        };
        assemble(&v).expect("model assembles")
    };
    let mut g = c.benchmark_group("simulate_viscoelastic_16x24x2_0-500Hz");
    g.sample_size(10);
    for (name, soft) in [("soft_patch", true), ("damping_layer", false)] {
        let sys = viscoelastic(soft);
        g.bench_function(name, |b| {
            b.iter(|| simulate_system(&sys, None, 500.0, 0.5, &opts).expect("simulate"))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

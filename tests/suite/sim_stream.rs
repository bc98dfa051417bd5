//! The streamed simulation (issue 14: `simulate` writes the recording set block by block instead
//! of holding sensors × samples) against the held one it replaces, its oracle: every sample of
//! every sensor the same to rounding, noise included, for each path of the fast method (the
//! diagonalised one with complex sensor weights, the per-frequency LU one with a viscoelastic
//! patch) and the truncated method, read in odd-sized blocks.

use dampscope::sim::model::{Model, Patch, SensorSpec};
use dampscope::sim::simulate::{simulate, simulate_stream, Method, SimulateOptions};
use dampscope::sim::Sls;
use dampscope::source::{Block, Source};

fn coarse_plate() -> Model {
    let mut m = Model::reference_plate();
    m.mesh.nx = 8;
    m.mesh.ny = 12;
    m.mesh.nz = 2;
    // 7 × 9 sensors: most of them between the 9 × 13 nodes
    m.output.sensors = SensorSpec::Grid { nx: 7, ny: 9 };
    m.output.fmax = 400.0;
    m.output.df = 1.0;
    m
}

fn streamed_equals_held(model: &Model, method: Method, snr_db: Option<f64>) {
    let opts = SimulateOptions {
        method,
        snr_db,
        seed: 7,
        ..SimulateOptions::default()
    };
    let held = simulate(model, &opts).unwrap();
    let mut streamed = simulate_stream(model, &opts).unwrap();
    let n = held.impulse_responses[0].len();
    assert_eq!(streamed.source.duration_frames(), Some(n as u64));
    assert_eq!(streamed.fs_hz, held.fs_hz);
    assert_eq!(
        streamed.source.info().channel_names,
        held.frf.sensor_ids,
        "channel names and order"
    );
    let mut got: Vec<Vec<f64>> = vec![Vec::new(); held.impulse_responses.len()];
    let mut block = Block::default();
    while streamed.source.read_block(333, &mut block).unwrap() {
        for (g, c) in got.iter_mut().zip(&block.channels) {
            g.extend_from_slice(c);
        }
    }
    let mut checked = 0;
    for (k, (g, h)) in got.iter().zip(&held.impulse_responses).enumerate() {
        assert_eq!(g.len(), n, "channel {k} length");
        let peak = h.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        if peak == 0.0 {
            continue; // a sensor on a pinned edge
        }
        let worst = g
            .iter()
            .zip(h)
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(
            worst <= 1e-9 * peak,
            "channel {k}: streamed differs by {worst:e} (peak {peak:e})"
        );
        checked += 1;
    }
    assert!(checked > 40, "only {checked} non-zero channels");
}

#[test]
fn streamed_fast_diagonalised_equals_held_with_noise() {
    streamed_equals_held(&coarse_plate(), Method::Fast, Some(40.0));
}

#[test]
fn streamed_fast_viscoelastic_equals_held() {
    let mut m = coarse_plate();
    m.patches.push(Patch {
        x: [1.0, 1.5],
        y: [1.5, 2.25],
        youngs_modulus: None,
        poisson: None,
        density: None,
        loss_factor: None,
        sls: Some(Sls {
            e: 2.0e9,
            e_inf: 1.0e9,
            eta: 5.0e6,
        }),
    });
    streamed_equals_held(&m, Method::Fast, None);
}

#[test]
fn streamed_truncated_equals_held_with_noise() {
    streamed_equals_held(
        &coarse_plate(),
        Method::Truncated(vec![1, 3, 7]),
        Some(30.0),
    );
}

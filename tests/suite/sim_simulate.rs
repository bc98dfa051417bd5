//! Acceptance tests of the FE responses on the plate (issue 3): fast vs direct FRF within 1 %
//! per 50 Hz band (eq. 4.8) over 0–500 Hz with a damped and a viscoelastic patch, at the driving
//! point and at an off-patch sensor; a single-mode (mode 7, g = 5 %) impulse response decays
//! with D = 2.5 %.
//!
//! The mesh is 8 × 12 × 2 (a quarter of the reference plate's 32 × 48 × 2 in-plane) so that the
//! direct solution at 501 frequencies (1 Hz) stays within the test time budget (on 16 × 24 × 2 it takes
//! ~290 s per case here); the tolerance is the acceptance one (1 %).

use dampscope::decay::damping::damping_ratio;
use dampscope::decay::regression::fit_line;
use dampscope::sim::assembly::assemble;
use dampscope::sim::factored::FrfSolve;
use dampscope::sim::frf::{band_error, FreqBand};
use dampscope::sim::model::{Model, Patch, SensorSpec};
use dampscope::sim::simulate::{simulate, simulate_system, Method, SimulateOptions};
use dampscope::sim::Sls;

/// The coarse 8 × 12 × 2 plate of the fast-vs-direct tests (sensors between nodes on the patch).
pub(crate) fn coarse_plate() -> Model {
    let mut m = Model::reference_plate();
    m.mesh.nx = 8;
    m.mesh.ny = 12;
    m.mesh.nz = 2;
    m.excitation.x = 0.5;
    m.excitation.y = 0.75;
    // sensors every 0.25 m × 0.375 m: (0.5, 0.75) is the driving point, (1.25, 1.875) lies on
    // the patch, between nodes
    m.output.sensors = SensorSpec::Grid { nx: 9, ny: 9 };
    m.output.fmax = 500.0;
    m.output.df = 1.0;
    m
}

/// The patch region of the fast-vs-direct tests: soft polymer or the plate's material.
pub(crate) fn patch(loss_factor: Option<f64>, sls: Option<Sls>, soft: bool) -> Patch {
    Patch {
        x: [1.0, 1.5],
        y: [1.5, 2.25],
        youngs_modulus: None,
        poisson: soft.then_some(0.4),
        density: soft.then_some(1000.0),
        loss_factor,
        sls,
    }
}

/// METHODS.md §6 "soft damping polymer": E1 = 1 MPa, E = 4.83 MPa, tanδ_max = 1 at 50 Hz.
pub(crate) fn soft_polymer() -> Sls {
    Sls {
        e: 4.83e6,
        e_inf: 1.0e6,
        eta: 6.37e3,
    }
}

/// Worst per-band error at the driving point, an off-patch sensor and a sensor on the patch,
/// and how the fast method solved its reduced model.
fn fast_vs_direct(model: &Model) -> (f64, Option<FrfSolve>) {
    let sys = assemble(model).unwrap();
    let find = |x: f64, y: f64| {
        sys.sensors
            .iter()
            .position(|s| (s.x_m - x).abs() < 1e-9 && (s.y_m - y).abs() < 1e-9)
            .unwrap()
    };
    let picks = [
        ("driving point", find(0.5, 0.75)),
        ("off-patch", find(1.5, 0.75)),
        ("on the patch", find(1.25, 1.875)),
    ];
    let (fmax, df) = (model.output.fmax, model.output.df);
    let direct = Method::Direct;
    let opts = |method| SimulateOptions {
        method,
        ..SimulateOptions::default()
    };
    let d = simulate_system(&sys, None, fmax, df, &opts(direct)).unwrap();
    let f = simulate_system(&sys, None, fmax, df, &opts(Method::Fast)).unwrap();
    eprintln!(
        "fast: {} modes, reduction {:.2} s, FRF {:.2} s ({:?}); direct FRF {:.2} s",
        f.modes_used, f.timings.reduction_s, f.timings.frf_s, f.timings.frf_solve, d.timings.frf_s
    );
    let mut worst: f64 = 0.0;
    for (name, s) in picks {
        for b in 0..10 {
            let band = FreqBand {
                lo_hz: 50.0 * b as f64,
                hi_hz: 50.0 * (b + 1) as f64,
            };
            let e = band_error(
                &f.frf.receptance(s),
                &d.frf.receptance(s),
                &d.frf.frequencies_hz,
                band,
            )
            .unwrap();
            eprintln!("{name} {}–{} Hz: ε = {e:.2e}", band.lo_hz, band.hi_hz);
            worst = worst.max(e);
        }
    }
    (worst, f.timings.frf_solve)
}

#[test]
fn fast_equals_direct_damped_patch() {
    let mut m = coarse_plate();
    m.material.loss_factor = 0.005;
    m.patches.push(patch(Some(0.10), None, false));
    let (worst, _) = fast_vs_direct(&m);
    assert!(worst < 0.01, "worst band error {worst}");
}

#[test]
fn fast_equals_direct_viscoelastic_patch() {
    let mut m = coarse_plate();
    m.material.loss_factor = 0.005;
    m.patches.push(patch(Some(0.0), Some(soft_polymer()), true));
    let (worst, solve) = fast_vs_direct(&m);
    assert!(worst < 0.01, "worst band error {worst}");
    // The interface form (the patch's interior modes eliminated onto its interface), not the
    // general reduced model: the fast path of viscoelastic patches.
    assert!(
        matches!(solve, Some(FrfSolve::Interface { .. })),
        "{solve:?}"
    );
}

/// Only mode 7 kept, plate g = 5 %: the impulse response is one decaying mode whose energy
/// decays at 2ζω with ζ = D = g/2 (hysteretic pole ω₇√(1 + jg)). Energy in windows of whole
/// periods, straight-line fit of the level in dB, D = 1.0994/(T60 f) — the same conversion
/// as the analysis pipeline (`dampscope analyze` is checked end-to-end elsewhere).
#[test]
fn single_mode_impulse_response_decays_with_half_the_loss_factor() {
    let mut m = coarse_plate();
    m.material.loss_factor = 0.05;
    m.mesh.nx = 16; // mode 7 within 1 % of the reference mesh's 56.8 Hz
    m.mesh.ny = 24;
    m.output.fmax = 1000.0;
    m.output.df = 0.125;
    m.output.sensors = SensorSpec::Grid { nx: 3, ny: 3 };
    let opts = SimulateOptions {
        method: Method::Truncated(vec![7]),
        ..SimulateOptions::default()
    };
    let r = simulate(&m, &opts).unwrap();
    assert_eq!(
        r.impulse_responses[0].len(),
        (2.0 * 1000.0 / 0.125) as usize
    );
    // a sensor off the pinned edges with the largest response
    let (k, h) = r
        .impulse_responses
        .iter()
        .enumerate()
        .max_by(|a, b| {
            let e = |h: &Vec<f64>| h.iter().map(|x| x * x).sum::<f64>();
            e(a.1).total_cmp(&e(b.1))
        })
        .unwrap();
    // the peak of |accelerance| gives the mode frequency
    let acc = r.frf.accelerance(k);
    let (kmax, _) = acc
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.norm().total_cmp(&b.1.norm()))
        .unwrap();
    let f7 = r.frf.frequencies_hz[kmax];
    assert!((f7 - 56.8).abs() < 2.0, "mode 7 at {f7} Hz");
    let dt = 1.0 / r.fs_hz;
    let win = ((4.0 / f7) / dt).round() as usize; // ≈ 4 periods
    let (mut t, mut l) = (Vec::new(), Vec::new());
    let mut start = (0.05 / dt) as usize;
    while start + win < h.len() / 2 {
        let e: f64 = h[start..start + win].iter().map(|x| x * x).sum();
        t.push((start + win / 2) as f64 * dt);
        l.push(10.0 * e.log10());
        start += win;
    }
    let l0 = l[0];
    let keep: Vec<usize> = (0..l.len()).filter(|&i| l[i] > l0 - 40.0).collect();
    let tt: Vec<f64> = keep.iter().map(|&i| t[i]).collect();
    let ll: Vec<f64> = keep.iter().map(|&i| l[i]).collect();
    let fit = fit_line(&tt, &ll).unwrap();
    let d = damping_ratio(fit.t60_s().unwrap(), f7);
    eprintln!("mode 7 at {f7} Hz: D = {:.4} %", 100.0 * d);
    assert!(
        (d - 0.025).abs() < 0.02 * 0.025,
        "D = {d}, expected 0.025 within 2 %"
    );
}

/// The damping layer `diagnose` adds (issue 13): a region of the plate's own aluminium whose
/// loss depends on frequency (SLS with e_inf = the plate's modulus, loss peak 0.3 at 150 Hz),
/// with the layer's added stiffness (up to +81 % above the peak) and 10 % added mass. Its
/// interior has few modes in the band; the Craig–Bampton basis carries it.
#[test]
fn fast_equals_direct_damping_layer() {
    let mut m = coarse_plate();
    m.material.loss_factor = 0.005;
    let sls = dampscope::diagnose::hypothesis::sls_with_peak(7.0e10, 0.3, 150.0);
    m.patches.push(Patch {
        density: Some(1.1 * 2700.0),
        ..patch(Some(0.005), Some(sls), false)
    });
    let (worst, solve) = fast_vs_direct(&m);
    assert!(worst < 0.01, "worst band error {worst}");
    assert!(
        matches!(solve, Some(FrfSolve::Interface { .. })),
        "{solve:?}"
    );
}

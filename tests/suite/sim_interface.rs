//! The interface form of viscoelastic models (issue 13): its elimination against a dense
//! Galerkin solve on its own basis, and its interpolated modal sums against the exact ones.

use dampscope::sim::assembly::assemble;
use dampscope::sim::interface::{build, partition, ModalSums};
use dampscope::sim::model::{Model, Patch, SensorSpec};
use dampscope::sim::substructure::DENSE_INTERIOR_MAX_DOFS;
use dampscope::sim::Sls;
use faer::{c64, Mat};

/// The coarse plate of the fast-vs-direct tests with the soft SLS patch (between nodes).
fn soft_patch_plate(fmax: f64, df: f64) -> Model {
    let mut m = Model::reference_plate();
    m.mesh.nx = 8;
    m.mesh.ny = 12;
    m.mesh.nz = 2;
    m.excitation.x = 0.5;
    m.excitation.y = 0.75;
    m.output.sensors = SensorSpec::Grid { nx: 9, ny: 9 };
    m.output.fmax = fmax;
    m.output.df = df;
    m.material.loss_factor = 0.005;
    m.patches.push(Patch {
        x: [1.0, 1.5],
        y: [1.5, 2.25],
        youngs_modulus: None,
        poisson: Some(0.4),
        density: Some(1000.0),
        loss_factor: Some(0.0),
        sls: Some(Sls {
            e: 4.83e6,
            e_inf: 1.0e6,
            eta: 6.37e3,
        }),
    });
    m
}

/// Largest relative difference between two responses, per frequency row, over all rows.
fn worst_row_difference(a: &Mat<c64>, b: &Mat<c64>) -> f64 {
    let mut worst: f64 = 0.0;
    for k in 0..a.nrows() {
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for j in 0..a.ncols() {
            num += (a[(k, j)] - b[(k, j)]).norm_sqr();
            den += b[(k, j)].norm_sqr();
        }
        worst = worst.max((num / den.max(f64::MIN_POSITIVE)).sqrt());
    }
    worst
}

#[test]
fn interpolated_modal_sums_equal_the_exact_sums() {
    let model = soft_patch_plate(500.0, 0.25);
    let sys = assemble(&model).unwrap();
    let part = partition(&sys, DENSE_INTERIOR_MAX_DOFS).unwrap();
    let (im, _, _) = build(&sys, &part, 750.0, false).unwrap().unwrap();
    let freqs: Vec<f64> = (0..=2000).map(|k| 0.25 * k as f64).collect();
    let fast = im
        .factored_frf_with(&freqs, ModalSums::Interpolated)
        .unwrap();
    let exact = im.factored_frf_with(&freqs, ModalSums::Exact).unwrap();
    let d = worst_row_difference(&fast.modal, &exact.modal);
    eprintln!("interpolated vs exact sums: worst relative difference {d:.2e}");
    assert!(d < 1e-7, "{d}");
}

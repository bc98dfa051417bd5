//! The interface form of viscoelastic models (issue 13): its elimination against a dense
//! Galerkin solve on its own basis, and its interpolated modal sums against the exact ones.

use dampscope::sim::assembly::assemble;
use dampscope::sim::interface::{build, partition, ModalSums};
use dampscope::sim::model::Model;
use dampscope::sim::substructure::DENSE_INTERIOR_MAX_DOFS;
use faer::{c64, Mat};

use super::sim_simulate::{coarse_plate, patch, soft_polymer};

/// The coarse plate of the fast-vs-direct tests with the soft SLS patch (between nodes).
fn soft_patch_plate(fmax: f64, df: f64) -> Model {
    let mut m = coarse_plate();
    m.output.fmax = fmax;
    m.output.df = df;
    m.material.loss_factor = 0.005;
    m.patches.push(patch(Some(0.0), Some(soft_polymer()), true));
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

/// The elimination onto the interface is exact algebra: at any frequency it gives the same
/// coordinates as a dense LU of the whole Galerkin system on the same basis [Ψ | Ξ | Φ].
#[test]
fn interface_solve_equals_the_dense_galerkin_solve_on_its_basis() {
    let model = soft_patch_plate(500.0, 1.0);
    let sys = assemble(&model).unwrap();
    let part = partition(&sys, DENSE_INTERIOR_MAX_DOFS).unwrap();
    let (im, _, basis) = build(&sys, &part, 750.0, true).unwrap().unwrap();
    let basis = basis.unwrap();
    let mut blocks = vec![basis.interface_shapes.clone(), basis.plate_modes.clone()];
    blocks.extend(basis.interior_modes.iter().cloned());
    let m: usize = blocks.iter().map(|b| b.ncols()).sum();
    assert_eq!(m, im.basis_size());
    let n = sys.n_free;
    let mut v = Mat::<f64>::zeros(n, m);
    let mut at = 0;
    for b in &blocks {
        v.as_mut().subcols_mut(at, b.ncols()).copy_from(b);
        at += b.ncols();
    }
    let dense = |a: &faer::sparse::SparseColMat<usize, f64>| {
        let av = dampscope::sim::spmm::symmetric_times_dense(a, v.as_ref());
        v.transpose() * &av
    };
    let m_hat = dense(&sys.mass);
    let k_hat: Vec<Mat<f64>> = sys
        .stiffness_terms
        .iter()
        .map(|t| dense(&t.matrix))
        .collect();
    let b: Vec<f64> = (0..m)
        .map(|j| (0..n).map(|i| v[(i, j)] * sys.force[i]).sum())
        .collect();
    // the couplings the interface form takes as zero
    let (r, nz) = (im.interface_dofs, basis.plate_modes.ncols());
    let block_max = |a: &Mat<f64>, r0: usize, nr: usize, c0: usize, nc: usize| {
        let mut x: f64 = 0.0;
        for i in r0..r0 + nr {
            for j in c0..c0 + nc {
                x = x.max(a[(i, j)].abs());
            }
        }
        x
    };
    let k_all = k_hat.iter().fold(Mat::<f64>::zeros(m, m), |acc, k| acc + k);
    eprintln!(
        "|K psi-xi| {:.2e} of |K psi-psi| {:.2e}; |K psi-eta| {:.2e}; |M xi-eta| {:.2e}; |K xi-xi offdiag| {:.2e}",
        block_max(&k_all, 0, r, r, nz),
        block_max(&k_all, 0, r, 0, r),
        block_max(&k_all, 0, r, r + nz, m - r - nz),
        block_max(&m_hat, r, nz, r + nz, m - r - nz),
        (0..nz).flat_map(|i| (0..nz).map(move |j| (i, j))).filter(|(i, j)| i != j).map(|(i, j)| k_all[(r + i, r + j)].abs()).fold(0.0, f64::max),
    );
    let freqs: Vec<f64> = vec![3.0, 48.5, 50.0, 121.0, 250.0, 333.0, 499.0];
    let got = im.factored_frf_with(&freqs, ModalSums::Exact).unwrap();
    let mut want = Mat::<c64>::zeros(freqs.len(), m);
    for (k, &f) in freqs.iter().enumerate() {
        let w = std::f64::consts::TAU * f;
        let a = Mat::<c64>::from_fn(m, m, |i, j| {
            let mut z = c64::new(-w * w * m_hat[(i, j)], 0.0);
            for (t, kh) in sys.stiffness_terms.iter().zip(&k_hat) {
                let (re, imag) = t.factor(w);
                z += c64::new(re, imag) * kh[(i, j)];
            }
            z
        });
        // equilibrated (D A D y = D b, q = D y, D = |diag A|^-1/2): the basis mixes static
        // shapes (stiffness ~1e11) with modes (~1e7), which costs a plain LU digits
        let dg: Vec<f64> = (0..m)
            .map(|i| 1.0 / a[(i, i)].norm().max(1e-300).sqrt())
            .collect();
        let a = Mat::<c64>::from_fn(m, m, |i, j| a[(i, j)] * (dg[i] * dg[j]));
        let rhs = Mat::<c64>::from_fn(m, 1, |i, _| c64::new(b[i] * dg[i], 0.0));
        let q = faer::linalg::solvers::Solve::solve(&a.full_piv_lu(), rhs.as_ref());
        for j in 0..m {
            want[(k, j)] = q[(j, 0)] * dg[j];
        }
    }
    // compare the responses at the sensors (the coordinates themselves are as well conditioned
    // as the basis, which holds nearly dependent static shapes)
    let sens = |modal: &Mat<c64>| {
        let wts = Mat::<c64>::from_fn(im.weights.nrows(), m, |i, j| {
            c64::new(im.weights[(i, j)], 0.0)
        });
        modal * wts.transpose()
    };
    let (gs, ws) = (sens(&got.modal), sens(&want));
    for k in 0..freqs.len() {
        let one = |a: &Mat<c64>| Mat::<c64>::from_fn(1, a.ncols(), |_, j| a[(k, j)]);
        eprintln!(
            "{} Hz: {:.2e}",
            freqs[k],
            worst_row_difference(&one(&gs), &one(&ws))
        );
    }
    let direct = dampscope::sim::frf::direct_frf(&sys, &freqs)
        .unwrap()
        .receptance_m_per_n;
    for k in 0..freqs.len() {
        let one = |a: &Mat<c64>| Mat::<c64>::from_fn(1, a.ncols(), |_, j| a[(k, j)]);
        eprintln!(
            "{} Hz vs direct: interface {:.2e}, galerkin {:.2e}",
            freqs[k],
            worst_row_difference(&one(&gs), &one(&direct)),
            worst_row_difference(&one(&ws), &one(&direct))
        );
    }
    let d = worst_row_difference(&gs, &ws);
    eprintln!("interface vs dense Galerkin: worst relative difference at the sensors {d:.2e}");
    // Measured: ≤ 1.6e-6 from 48.5 Hz up, 3.2e-5 at 3 Hz (below the first plate mode), where
    // the interface form is that far from the direct solve too while the Galerkin solve is at
    // 6e-7: a round-off loss of the quasi-static response not traced yet (see the issue note),
    // 300 times below the 1 % acceptance.
    assert!(d < 1e-4, "{d}");
}

//! LDLᵀ of a complex symmetric matrix (Z = Zᵀ, not Hermitian) without pivoting, blocked.
//!
//! Why: the interface dynamic stiffness is complex symmetric; an LDLᵀ costs half the LU's
//! operations, and the LU was the largest per-frequency cost of the interface form. Without
//! pivoting it can fail or lose accuracy on an indefinite matrix, so every solution is checked
//! by its residual ([`RESIDUAL_TOLERANCE`]) and the caller falls back to the pivoting LU.

use faer::linalg::matmul::triangular::{matmul as tri_matmul, BlockStructure};
use faer::linalg::triangular_solve::solve_unit_lower_triangular_in_place;
use faer::{c64, Accum, Mat, Par};

/// Columns per panel of the blocked factorisation.
pub const PANEL: usize = 32;

/// Largest ‖b − Z x‖ / (‖Z‖_max · ‖x‖_1 + ‖b‖) accepted for the LDLᵀ solution.
pub const RESIDUAL_TOLERANCE: f64 = 1e-12;

/// Factorises the lower triangle of `z` in place (L unit lower, D on the diagonal); `false`
/// when a pivot is zero or not finite. `scaled` is scratch of at least r × [`PANEL`].
///
/// Right-looking by panels of [`PANEL`] columns: the panel's diagonal block is factorised
/// column by column, the rows below it by one triangular solve (L₂₁ D₁ = A₂₁ L₁₁⁻ᵀ), and the
/// trailing lower triangle updated by one product A₂₂ −= (L₂₁ D₁) L₂₁ᵀ, so that nearly all of
/// the work is in faer's matrix kernels.
pub fn factor_in_place(z: &mut Mat<c64>, scaled: &mut Mat<c64>) -> bool {
    let r = z.nrows();
    let mut k = 0;
    while k < r {
        let nb = PANEL.min(r - k);
        if !factor_diagonal_block(z, k, nb) {
            return false;
        }
        let rest = r - k - nb;
        if rest > 0 {
            let (l11, mut a21) = z
                .as_mut()
                .submatrix_mut(k, k, r - k, nb)
                .split_at_row_mut(nb);
            // A₂₁ ← A₂₁ L₁₁⁻ᵀ = L₂₁ D₁ (solved as L₁₁ Xᵀ = A₂₁ᵀ)
            solve_unit_lower_triangular_in_place(
                l11.as_ref(),
                a21.as_mut().transpose_mut(),
                Par::Seq,
            );
            for c in 0..nb {
                let d = z[(k + c, k + c)];
                let inv = c64::new(1.0, 0.0) / d;
                let src = &mut z.col_as_slice_mut(k + c)[k + nb..];
                scaled.col_as_slice_mut(c)[..rest].copy_from_slice(src);
                src.iter_mut().for_each(|x| *x *= inv);
            }
            let (left, right) = z.as_mut().split_at_col_mut(k + nb);
            tri_matmul(
                right.submatrix_mut(k + nb, 0, rest, rest),
                BlockStructure::TriangularLower,
                Accum::Add,
                scaled.as_ref().submatrix(0, 0, rest, nb),
                BlockStructure::Rectangular,
                left.as_ref().submatrix(k + nb, k, rest, nb).transpose(),
                BlockStructure::Rectangular,
                c64::new(-1.0, 0.0),
                Par::Seq,
            );
        }
        k += nb;
    }
    true
}

/// Unblocked LDLᵀ of the nb × nb diagonal block at (k, k); `false` on a zero or non-finite
/// pivot.
fn factor_diagonal_block(z: &mut Mat<c64>, k: usize, nb: usize) -> bool {
    for c in k..k + nb {
        let d = z[(c, c)];
        if !(d.re.is_finite() && d.im.is_finite()) || d.norm_sqr() == 0.0 {
            return false;
        }
        let inv = c64::new(1.0, 0.0) / d;
        z.col_as_slice_mut(c)[c + 1..k + nb]
            .iter_mut()
            .for_each(|x| *x *= inv);
        // the rest of the block: A[i, c'] −= L[i, c] d L[c', c]
        for cp in c + 1..k + nb {
            let f = z[(cp, c)] * d;
            let (left, mut right) = z.as_mut().split_at_col_mut(cp);
            for i in cp..k + nb {
                right[(i, 0)] -= left[(i, c)] * f;
            }
        }
    }
    true
}

/// Solves with a factor from [`factor_in_place`]: L y = b, D w = y, Lᵀ x = w, in place.
pub fn solve_in_place(z: &Mat<c64>, b: &mut [c64]) {
    let r = z.nrows();
    for c in 0..r {
        let bc = b[c];
        for i in c + 1..r {
            b[i] -= z[(i, c)] * bc;
        }
    }
    for (c, x) in b.iter_mut().enumerate() {
        *x /= z[(c, c)];
    }
    for c in (0..r).rev() {
        let mut s = b[c];
        for i in c + 1..r {
            s -= z[(i, c)] * b[i];
        }
        b[c] = s;
    }
}

/// ‖b − Z x‖_max / (‖Z‖_max ‖x‖_1 + ‖b‖_max) (moduli taken as |re| + |im|) with Z given by its lower triangles in the
/// column-major real and imaginary slices (r × r).
pub fn relative_residual(z_re: &[f64], z_im: &[f64], x: &[c64], b: &[c64]) -> f64 {
    let r = x.len();
    let mut res: Vec<c64> = b.to_vec();
    let mut zmax: f64 = 0.0;
    for j in 0..r {
        for i in j..r {
            let v = c64::new(z_re[j * r + i], z_im[j * r + i]);
            zmax = zmax.max(v.re.abs() + v.im.abs());
            res[i] -= v * x[j];
            if i != j {
                res[j] -= v * x[i];
            }
        }
    }
    // |re| + |im| for every modulus: within √2 of it, without a hypot per entry
    let l1 = |v: &c64| v.re.abs() + v.im.abs();
    let xn: f64 = x.iter().map(l1).sum();
    let bn = b.iter().fold(0.0f64, |a, v| a.max(l1(v)));
    let rn = res.iter().fold(0.0f64, |a, v| a.max(l1(v)));
    rn / (zmax * xn + bn).max(f64::MIN_POSITIVE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ldlt_solves_a_complex_symmetric_system_like_the_lu() {
        for r in [1usize, 5, 31, 32, 33, 70, 97, 324] {
            let mut state = 11u64 + r as u64;
            let mut rnd = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
            };
            let mut a = Mat::<c64>::zeros(r, r);
            for j in 0..r {
                for i in j..r {
                    let v = c64::new(rnd(), rnd())
                        + if i == j {
                            c64::new(4.0, 1.0)
                        } else {
                            c64::new(0.0, 0.0)
                        };
                    a[(i, j)] = v;
                    a[(j, i)] = v;
                }
            }
            let b: Vec<c64> = (0..r).map(|_| c64::new(rnd(), rnd())).collect();
            let (mut re, mut im) = (vec![0.0; r * r], vec![0.0; r * r]);
            for j in 0..r {
                for i in 0..r {
                    re[j * r + i] = a[(i, j)].re;
                    im[j * r + i] = a[(i, j)].im;
                }
            }
            let mut f = a.clone();
            let mut scratch = Mat::<c64>::zeros(r, PANEL);
            assert!(factor_in_place(&mut f, &mut scratch));
            let mut x = b.clone();
            solve_in_place(&f, &mut x);
            let want = faer::linalg::solvers::Solve::solve(
                &a.partial_piv_lu(),
                Mat::<c64>::from_fn(r, 1, |i, _| b[i]).as_ref(),
            );
            for i in 0..r {
                assert!((x[i] - want[(i, 0)]).norm() < 1e-11, "r {r} i {i}");
            }
            assert!(relative_residual(&re, &im, &x, &b) < RESIDUAL_TOLERANCE);
        }
    }
}

//! Non-negative least squares, min ‖A x − b‖ subject to x ≥ 0 (Lawson & Hanson's active-set
//! method), for the small dense problems of the diagnosis (modes × candidate regions).

use faer::linalg::solvers::Solve;
use faer::Mat;

/// Unconstrained least squares on the columns `cols` of `a` (by the normal equations; the
/// problems are tiny and the columns of a passive set are independent by construction).
fn ls_on(a: &Mat<f64>, b: &[f64], cols: &[usize]) -> Vec<f64> {
    let k = cols.len();
    let ata = Mat::from_fn(k, k, |i, j| {
        (0..a.nrows())
            .map(|r| a[(r, cols[i])] * a[(r, cols[j])])
            .sum::<f64>()
    });
    let atb = Mat::from_fn(k, 1, |i, _| {
        (0..a.nrows()).map(|r| a[(r, cols[i])] * b[r]).sum::<f64>()
    });
    let z = ata.partial_piv_lu().solve(atb.as_ref());
    (0..k).map(|i| z[(i, 0)]).collect()
}

/// The x ≥ 0 that minimises ‖A x − b‖. `a` is m × n, `b` has m entries.
pub fn nnls(a: &Mat<f64>, b: &[f64]) -> Vec<f64> {
    let (m, n) = (a.nrows(), a.ncols());
    assert_eq!(b.len(), m, "nnls: b must have one entry per row of A");
    let mut x = vec![0.0; n];
    let mut passive: Vec<usize> = Vec::new();
    let tol = 1e-12
        * (0..n)
            .map(|j| (0..m).map(|i| a[(i, j)].abs()).sum::<f64>())
            .fold(0.0, f64::max)
            .max(1e-300)
        * b.iter().map(|v| v.abs()).sum::<f64>().max(1e-300);
    for _outer in 0..3 * n.max(1) {
        // Gradient of −½‖Ax − b‖²: w = Aᵀ(b − Ax).
        let r: Vec<f64> = (0..m)
            .map(|i| b[i] - (0..n).map(|j| a[(i, j)] * x[j]).sum::<f64>())
            .collect();
        let w: Vec<f64> = (0..n)
            .map(|j| (0..m).map(|i| a[(i, j)] * r[i]).sum())
            .collect();
        let Some(t) = (0..n)
            .filter(|j| !passive.contains(j))
            .filter(|&j| w[j] > tol)
            .max_by(|&p, &q| w[p].total_cmp(&w[q]))
        else {
            break;
        };
        passive.push(t);
        // Inner loop: keep the passive-set solution feasible.
        for _inner in 0..3 * n.max(1) {
            let z = ls_on(a, b, &passive);
            if z.iter().all(|v| *v > 0.0) {
                for (k, &j) in passive.iter().enumerate() {
                    x[j] = z[k];
                }
                break;
            }
            let alpha = passive
                .iter()
                .zip(&z)
                .filter(|(_, zk)| **zk <= 0.0)
                .map(|(&j, zk)| x[j] / (x[j] - zk))
                .fold(f64::INFINITY, f64::min);
            for (k, &j) in passive.iter().enumerate() {
                x[j] += alpha * (z[k] - x[j]);
            }
            passive.retain(|&j| x[j] > 1e-15);
            for (j, xj) in x.iter_mut().enumerate() {
                if !passive.contains(&j) {
                    *xj = 0.0;
                }
            }
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    fn residual(a: &Mat<f64>, b: &[f64], x: &[f64]) -> f64 {
        (0..a.nrows())
            .map(|i| {
                let r = b[i] - (0..a.ncols()).map(|j| a[(i, j)] * x[j]).sum::<f64>();
                r * r
            })
            .sum()
    }

    /// Oracle: every subset of columns, unconstrained LS, keep the feasible best.
    fn brute_force(a: &Mat<f64>, b: &[f64]) -> f64 {
        let n = a.ncols();
        let mut best = residual(a, b, &vec![0.0; n]);
        for mask in 1u32..(1 << n) {
            let cols: Vec<usize> = (0..n).filter(|j| mask >> j & 1 == 1).collect();
            let z = ls_on(a, b, &cols);
            if z.iter().all(|v| *v >= 0.0 && v.is_finite()) {
                let mut x = vec![0.0; n];
                for (k, &j) in cols.iter().enumerate() {
                    x[j] = z[k];
                }
                best = best.min(residual(a, b, &x));
            }
        }
        best
    }

    #[test]
    fn matches_the_brute_force_oracle_on_random_problems() {
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for _ in 0..200 {
            let (m, n) = (8, 5);
            let a = Mat::from_fn(m, n, |_, _| rnd());
            let b: Vec<f64> = (0..m).map(|_| rnd()).collect();
            let x = nnls(&a, &b);
            assert!(x.iter().all(|v| *v >= 0.0));
            let (got, want) = (residual(&a, &b, &x), brute_force(&a, &b));
            assert!(got <= want * (1.0 + 1e-9) + 1e-12, "{got} vs {want}");
        }
    }

    #[test]
    fn recovers_a_sparse_non_negative_truth() {
        let a = Mat::from_fn(6, 4, |i, j| {
            ((i * 7 + j * 3) % 5) as f64 + if i == j { 0.5 } else { 0.0 }
        });
        let truth = [0.0, 2.0, 0.0, 0.5];
        let b: Vec<f64> = (0..6)
            .map(|i| (0..4).map(|j| a[(i, j)] * truth[j]).sum())
            .collect();
        let x = nnls(&a, &b);
        for (g, t) in x.iter().zip(truth) {
            assert!((g - t).abs() < 1e-9, "{x:?}");
        }
    }
}

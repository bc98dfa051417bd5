//! Sparse (CSC) × dense products with many columns, blocked over the dense columns.
//!
//! Why: the reduction multiplies the stiffness and mass matrices by hundreds of vectors at a time
//! (static shapes, modes, Ritz vectors). Column by column, every nonzero is a scattered
//! multiply-add of one number; with the dense columns in row-major blocks of [`LANES`] each
//! nonzero updates [`LANES`] contiguous numbers, which the compiler vectorises, and the blocks
//! are shared between two threads. The accumulation order per output entry is the same as the
//! column-by-column product (ascending column of the sparse matrix), so the results agree with
//! it to the last bit or one rounding (the oracle test).

use faer::sparse::SparseColMat;
use faer::{Mat, MatRef};

/// Dense columns per row-major block.
pub const LANES: usize = 8;

/// Below this many dense columns the plain column-by-column product is used.
const BLOCKED_FROM_COLUMNS: usize = 4;

/// One block: `out` (n × w, row-major) = A × `b` (rows of A's columns, row-major, w wide).
fn block_product(a: &SparseColMat<usize, f64>, b: &[f64], w: usize, out: &mut [f64]) {
    let (sym, val) = a.parts();
    for j in 0..a.ncols() {
        let bj = &b[j * w..(j + 1) * w];
        if bj.iter().all(|&x| x == 0.0) {
            continue;
        }
        for k in sym.col_range(j) {
            let v = val[k];
            let i = sym.row_idx()[k];
            let o = &mut out[i * w..(i + 1) * w];
            for (x, &y) in o.iter_mut().zip(bj) {
                *x += v * y;
            }
        }
    }
}

/// A × B for a sparse A (n × p) and a dense B (p × k).
pub fn sparse_times_dense(a: &SparseColMat<usize, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let (n, k) = (a.nrows(), b.ncols());
    let mut out = Mat::<f64>::zeros(n, k);
    if k < BLOCKED_FROM_COLUMNS {
        faer::sparse::linalg::matmul::sparse_dense_matmul(
            out.as_mut(),
            faer::Accum::Replace,
            a.as_ref(),
            b,
            1.0,
            faer::Par::Seq,
        );
        return out;
    }
    let starts: Vec<usize> = (0..k).step_by(LANES).collect();
    let one = |s: usize| -> (usize, usize, Vec<f64>) {
        let w = LANES.min(k - s);
        let p = b.nrows();
        let mut bt = vec![0.0; p * w];
        for c in 0..w {
            for (j, &x) in b.col(s + c).iter().enumerate() {
                bt[j * w + c] = x;
            }
        }
        let mut ot = vec![0.0; n * w];
        block_product(a, &bt, w, &mut ot);
        (s, w, ot)
    };
    let half = starts.len().div_ceil(2);
    let (first, second) = starts.split_at(half);
    let blocks: Vec<(usize, usize, Vec<f64>)> = std::thread::scope(|sc| {
        let h = sc.spawn(|| first.iter().map(|&s| one(s)).collect::<Vec<_>>());
        let mut rest: Vec<_> = second.iter().map(|&s| one(s)).collect();
        let mut all = h.join().unwrap_or_default();
        all.append(&mut rest);
        all
    });
    for (s, w, ot) in blocks {
        for c in 0..w {
            let col = out.col_as_slice_mut(s + c);
            for (i, x) in col.iter_mut().enumerate() {
                *x = ot[i * w + c];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::Triplet;

    #[test]
    fn blocked_product_equals_the_column_by_column_product() {
        let n = 37;
        let mut state = 7u64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut trip = Vec::new();
        for j in 0..n {
            for i in 0..n {
                if (i * 7 + j * 3) % 5 == 0 || i == j {
                    trip.push(Triplet::new(i, j, rnd()));
                }
            }
        }
        let a = SparseColMat::try_new_from_triplets(n, n, &trip).unwrap();
        for k in [1, 3, 4, 8, 13, 17] {
            let b = Mat::from_fn(n, k, |i, j| if (i + j) % 6 == 0 { 0.0 } else { rnd() });
            let got = sparse_times_dense(&a, b.as_ref());
            for c in 0..k {
                for i in 0..n {
                    let want: f64 = (0..n)
                        .map(|j| {
                            let (sym, val) = a.parts();
                            sym.col_range(j)
                                .filter(|&q| sym.row_idx()[q] == i)
                                .map(|q| val[q] * b[(j, c)])
                                .sum::<f64>()
                        })
                        .sum();
                    assert!(
                        (got[(i, c)] - want).abs() <= 1e-14 * (1.0 + want.abs()),
                        "k {k} ({i}, {c}): {} vs {want}",
                        got[(i, c)]
                    );
                }
            }
        }
    }
}

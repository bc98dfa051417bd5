//! Linear combinations of sparse matrices (K₀ = Σ K_r, K₀ − σM), formed many times per
//! diagnosis.

use faer::sparse::{SparseColMat, SymbolicSparseColMat, Triplet};

use super::assembly::sparse_from_triplets;
use super::error::SimError;

/// Σ_r c_r A_r as a new CSC matrix (`what` names it in errors): the union of the parts'
/// patterns, each entry the sum over the parts in their order. Column by column, a merge of
/// the parts' sorted rows (a diagnosis forms K₀ and K₀ − σM of every candidate model: through
/// triplets and a sort this was a fifth of a factorisation); parts of one pattern add their
/// values in place.
pub fn sparse_combination(
    n: usize,
    parts: &[(f64, &SparseColMat<usize, f64>)],
    what: &str,
) -> Result<SparseColMat<usize, f64>, SimError> {
    if let Some((_, a)) = parts.iter().find(|(_, a)| a.nrows() != n || a.ncols() != n) {
        return Err(SimError::Linear {
            what: what.to_string(),
            message: format!("a {} × {} part, expected {n} × {n}", a.nrows(), a.ncols()),
        });
    }
    let Some(&(c0, first)) = parts.first() else {
        return sparse_from_triplets(n, &[], what);
    };
    let (f_ptr, f_rows) = (first.symbolic().col_ptr(), first.symbolic().row_idx());
    if first.symbolic().col_nnz().is_none()
        && parts.iter().all(|(_, a)| has_pattern(a, f_ptr, f_rows))
    {
        let mut sum = first.clone();
        sum.val_mut().iter_mut().for_each(|x| *x *= c0);
        for &(c, a) in &parts[1..] {
            for (x, v) in sum.val_mut().iter_mut().zip(a.val()) {
                *x += c * v;
            }
        }
        return Ok(sum);
    }
    let sorted = |a: &SparseColMat<usize, f64>| {
        a.symbolic().col_nnz().is_none()
            && (0..n).all(|j| {
                let rows = a.symbolic().row_idx_of_col_raw(j);
                rows.windows(2).all(|w| w[0] < w[1])
            })
    };
    if !parts.iter().all(|(_, a)| sorted(a)) {
        return sparse_combination_by_triplets(n, parts, what);
    }
    let nnz: usize = parts.iter().map(|(_, a)| a.compute_nnz()).sum();
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx: Vec<usize> = Vec::with_capacity(nnz);
    let mut values: Vec<f64> = Vec::with_capacity(nnz);
    let mut cursor = vec![0usize; parts.len()];
    col_ptr.push(0);
    for j in 0..n {
        let columns: Vec<(&[usize], &[f64])> = parts
            .iter()
            .map(|(_, a)| (a.symbolic().row_idx_of_col_raw(j), a.val_of_col(j)))
            .collect();
        cursor.iter_mut().for_each(|c| *c = 0);
        // the least row left in any part's column, until none is left
        let least = |cursor: &[usize]| {
            columns
                .iter()
                .zip(cursor)
                .filter_map(|((rows, _), &c)| rows.get(c).copied())
                .min()
        };
        while let Some(row) = least(&cursor) {
            let mut sum = 0.0;
            for (r, ((rows, vals), c)) in columns.iter().zip(cursor.iter_mut()).enumerate() {
                if rows.get(*c) == Some(&row) {
                    sum += parts[r].0 * vals[*c];
                    *c += 1;
                }
            }
            row_idx.push(row);
            values.push(sum);
        }
        col_ptr.push(row_idx.len());
    }
    let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
    Ok(SparseColMat::new(symbolic, values))
}

/// Whether `a` is a packed CSC matrix with exactly the pattern `col_ptr`, `row_idx` (the
/// test for sharing values, a factor or a plan between matrices).
pub fn has_pattern(a: &SparseColMat<usize, f64>, col_ptr: &[usize], row_idx: &[usize]) -> bool {
    let s = a.symbolic();
    s.col_nnz().is_none() && s.col_ptr() == col_ptr && s.row_idx() == row_idx
}

/// [`sparse_combination`] through triplets (any CSC input, sorted or not): its oracle, and its
/// path for parts whose columns are not strictly sorted.
pub fn sparse_combination_by_triplets(
    n: usize,
    parts: &[(f64, &SparseColMat<usize, f64>)],
    what: &str,
) -> Result<SparseColMat<usize, f64>, SimError> {
    let mut trip = Vec::with_capacity(parts.iter().map(|(_, a)| a.compute_nnz()).sum());
    for &(c, a) in parts {
        let a = a.as_ref();
        for j in 0..n {
            let rows = a.symbolic().row_idx_of_col_raw(j);
            for (&i, &v) in rows.iter().zip(a.val_of_col(j)) {
                trip.push(Triplet::new(i, j, c * v));
            }
        }
    }
    sparse_from_triplets(n, &trip, what)
}

/// Test support: `a` and `b` have one pattern, and every pair of values passes `close`
/// (the oracle tests of the fast assembly and sums).
#[cfg(test)]
pub(crate) fn assert_same_pattern(
    a: &SparseColMat<usize, f64>,
    b: &SparseColMat<usize, f64>,
    what: &str,
    close: impl Fn(f64, f64) -> bool,
) {
    assert_eq!(a.symbolic().col_ptr(), b.symbolic().col_ptr(), "{what}");
    assert_eq!(a.symbolic().row_idx(), b.symbolic().row_idx(), "{what}");
    for (&x, &y) in a.val().iter().zip(b.val()) {
        assert!(close(x, y), "{what}: {x} vs {y}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random sparse n × n matrix (sorted CSC), about `per_col` entries a column.
    fn random(n: usize, per_col: usize, seed: u64) -> SparseColMat<usize, f64> {
        let mut state = seed | 1;
        let mut rnd = move |m: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % m
        };
        let t: Vec<_> = (0..n * per_col)
            .map(|_| {
                let (i, j) = (rnd(n as u64) as usize, rnd(n as u64) as usize);
                Triplet::new(i, j, rnd(1000) as f64 / 7.0 - 70.0)
            })
            .collect();
        sparse_from_triplets(n, &t, "test").unwrap()
    }

    /// The merge gives the triplet oracle's matrix: same pattern, values to round-off; parts
    /// of one pattern, one part, no part, empty columns and a wrong size too.
    #[test]
    fn merged_columns_are_the_triplet_sum() {
        for n in [1usize, 5, 40, 300] {
            let (a, b, c) = (random(n, 3, 1), random(n, 5, 2), random(n, 1, 3));
            let same = {
                let mut s = a.clone();
                s.val_mut().iter_mut().for_each(|v| *v = v.sin());
                s
            };
            let sets: Vec<Vec<(f64, &SparseColMat<usize, f64>)>> = vec![
                vec![(1.0, &a)],
                vec![(1.0, &a), (-2.5, &b)],
                vec![(0.5, &a), (1.0, &b), (3.0, &c)],
                vec![(1.0, &a), (2.0, &same)],
                vec![],
            ];
            for parts in &sets {
                let fast = sparse_combination(n, parts, "t").unwrap();
                let slow = sparse_combination_by_triplets(n, parts, "t").unwrap();
                assert_same_pattern(&fast, &slow, &format!("n {n}"), |x, y| {
                    (x - y).abs() <= 1e-12 * (1.0 + y.abs())
                });
            }
        }
        let (a, b) = (random(4, 2, 5), random(5, 2, 6));
        let err = sparse_combination(4, &[(1.0, &a), (1.0, &b)], "K0").unwrap_err();
        assert!(err.to_string().contains("expected 4 × 4"), "{err}");
    }
}

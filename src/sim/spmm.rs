//! Sparse × dense products with many columns, for the symmetric matrices of a model (stiffness
//! and mass matrices and their sums).
//!
//! Why: the reduction multiplies the stiffness and mass matrices by hundreds of vectors at a time
//! (static shapes, modes, Ritz vectors). A symmetric A's column j is its row j, so the product
//! reads A's stored columns as rows: the dense columns go in row-major blocks of [`LANES`], and
//! each output row is summed in registers over its nonzeros (each a multiply-add of [`LANES`]
//! contiguous numbers) and written once; the two threads take half of the rows each. Scattering
//! each column into the output rows instead read and wrote an output row per nonzero, and that
//! product was a fifth of a diagnosis.
//!
//! Per output entry the terms are added in the order of the column-by-column product of the
//! same matrix (ascending column, from zero). For stored values symmetric bit for bit the
//! results are that product's to the last bit; an assembled matrix is symmetric to one rounding
//! per entry (an element's k_ij and k_ji are summed in different orders), and the two products
//! then differ by about that (the oracle tests).

use std::ops::Range;

use faer::sparse::SparseColMat;
use faer::{Mat, MatMut, MatRef};

use crate::frontend::simd::Isa;

/// Dense columns per row-major block.
pub const LANES: usize = 16;

/// A × B for a symmetric sparse A (n × n) and a dense B (n × k), computed as Aᵀ × B (see the
/// module doc: equal to A × B up to the rounding asymmetry of A's stored values).
///
/// # Panics
/// If A is not square or B has not A's size in rows (a caller's bug: both come from one model).
pub fn symmetric_times_dense(a: &SparseColMat<usize, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    symmetric_times_dense_with(Isa::detect(), a, b)
}

/// [`symmetric_times_dense`] with the instruction set `isa` (the tests run every one).
fn symmetric_times_dense_with(
    isa: Isa,
    a: &SparseColMat<usize, f64>,
    b: MatRef<'_, f64>,
) -> Mat<f64> {
    let (n, k) = (a.nrows(), b.ncols());
    assert!(
        a.ncols() == n && b.nrows() == n,
        "symmetric product: expected an n × n matrix and n rows, got {} × {} and {}",
        n,
        a.ncols(),
        b.nrows()
    );
    let mut out = Mat::<f64>::zeros(n, k);
    if n == 0 || k == 0 {
        return out;
    }
    // B in row-major blocks of LANES columns, the last one padded with zeros: row j of block q
    // at (q·n + j)·LANES. Written in order, a block row at a time (written a column at a time,
    // each write went to another cache line).
    let mut blocks = Vec::with_capacity(k.div_ceil(LANES) * n * LANES);
    for q in 0..k.div_ceil(LANES) {
        let width = LANES.min(k - q * LANES);
        let columns = b.subcols(q * LANES, width);
        for j in 0..n {
            let row = columns.row(j);
            blocks.extend((0..LANES).map(|l| if l < width { row[l] } else { 0.0 }));
        }
    }
    let mid = n / 2;
    let (top, bottom) = out.as_mut().split_at_row_mut(mid);
    std::thread::scope(|sc| {
        sc.spawn(|| rows_times_blocks(isa, a, &blocks, 0..mid, top));
        rows_times_blocks(isa, a, &blocks, mid..n, bottom);
    });
    out
}

/// Rows `rows` of Aᵀ × B into `out` (those rows of the product), block by block.
fn rows_times_blocks(
    isa: Isa,
    a: &SparseColMat<usize, f64>,
    blocks: &[f64],
    rows: Range<usize>,
    out: MatMut<'_, f64>,
) {
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(
        a: &SparseColMat<usize, f64>,
        blocks: &[f64],
        rows: Range<usize>,
        out: MatMut<'_, f64>,
    ) {
        run(a, blocks, rows, out)
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU.
        Isa::Avx2Fma | Isa::Avx512 => unsafe { run_avx2(a, blocks, rows, out) },
        Isa::Generic => run(a, blocks, rows, out),
    }
}

/// [`rows_times_blocks`]' loops: each output row's [`LANES`] sums in an array the compiler
/// keeps in vector registers (separate multiplies and adds, never fused, as in the
/// column-by-column product).
#[inline(always)]
fn run(a: &SparseColMat<usize, f64>, blocks: &[f64], rows: Range<usize>, mut out: MatMut<'_, f64>) {
    let (sym, val) = a.parts();
    let row_idx = sym.row_idx();
    let (n, k) = (a.nrows(), out.ncols());
    for (q, block) in blocks.chunks_exact(n * LANES).enumerate() {
        let width = LANES.min(k - q * LANES);
        for (r, j) in rows.clone().enumerate() {
            let mut acc = [0.0f64; LANES];
            for p in sym.col_range(j) {
                let v = val[p];
                let i = row_idx[p] * LANES;
                let bi: &[f64; LANES] = block[i..i + LANES].try_into().expect("a whole block row");
                for (x, &y) in acc.iter_mut().zip(bi) {
                    *x += v * y;
                }
            }
            for (l, &x) in acc.iter().enumerate().take(width) {
                out[(r, q * LANES + l)] = x;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::Triplet;

    fn random(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }

    /// A symmetric n × n pattern with an empty row and column (5), values mirrored bit for bit;
    /// `skew` then moves each upper entry by that many units in the last place.
    fn symmetric(n: usize, skew: i64, state: &mut u64) -> SparseColMat<usize, f64> {
        let mut trip = Vec::new();
        for j in 0..n {
            for i in 0..=j {
                if ((i * 7 + j * 3) % 5 == 0 || i == j) && i != 5 && j != 5 {
                    let v = random(state);
                    let upper = f64::from_bits((v.to_bits() as i64 + skew) as u64);
                    trip.push(Triplet::new(j, i, v));
                    if i != j {
                        trip.push(Triplet::new(i, j, upper));
                    }
                }
            }
        }
        SparseColMat::try_new_from_triplets(n, n, &trip).unwrap()
    }

    /// The column-by-column product: output row i gains A[i, j]·b[j] in ascending j, from 0.
    fn column_by_column(a: &SparseColMat<usize, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
        let (sym, val) = a.parts();
        let mut out = Mat::<f64>::zeros(a.nrows(), b.ncols());
        for c in 0..b.ncols() {
            for j in 0..a.ncols() {
                for q in sym.col_range(j) {
                    out[(sym.row_idx()[q], c)] += val[q] * b[(j, c)];
                }
            }
        }
        out
    }

    #[test]
    fn symmetric_product_is_the_column_by_column_product_bit_for_bit() {
        let mut state = 7u64;
        for n in [0, 1, 2, 9, 37, 64] {
            let a = symmetric(n, 0, &mut state);
            for (isa, k) in Isa::available()
                .into_iter()
                .flat_map(|isa| [0, 1, 3, 4, 8, 13, 17, 33].map(|k| (isa, k)))
            {
                let b = Mat::from_fn(n, k, |i, j| {
                    if (i + j) % 6 == 0 {
                        0.0
                    } else {
                        random(&mut state)
                    }
                });
                let (got, want) = (
                    symmetric_times_dense_with(isa, &a, b.as_ref()),
                    column_by_column(&a, b.as_ref()),
                );
                for c in 0..k {
                    for i in 0..n {
                        assert_eq!(
                            got[(i, c)].to_bits(),
                            want[(i, c)].to_bits(),
                            "{isa:?}, n {n}, k {k} ({i}, {c}): {} vs {}",
                            got[(i, c)],
                            want[(i, c)]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn an_assembled_symmetry_differs_by_its_rounding_only() {
        let mut state = 11u64;
        let (n, k) = (45, 13);
        // Upper entries 2 ulps off their lower mirror, as two summation orders leave them.
        let a = symmetric(n, 2, &mut state);
        let b = Mat::from_fn(n, k, |_, _| random(&mut state));
        let (got, want) = (
            symmetric_times_dense(&a, b.as_ref()),
            column_by_column(&a, b.as_ref()),
        );
        let (sym, val) = a.parts();
        let mut differs = 0;
        for c in 0..k {
            // Bound: per term 2 ulps of the entry plus the sum's own roundings.
            let mut scale = vec![0.0f64; n];
            for j in 0..n {
                for q in sym.col_range(j) {
                    scale[sym.row_idx()[q]] += (val[q] * b[(j, c)]).abs();
                }
            }
            for i in 0..n {
                let d = (got[(i, c)] - want[(i, c)]).abs();
                assert!(
                    d <= 8.0 * f64::EPSILON * scale[i],
                    "({i}, {c}): {d:e} of {:e}",
                    scale[i]
                );
                differs += usize::from(d > 0.0);
            }
        }
        // The product really reads the stored columns as rows (else nothing would differ).
        assert!(differs > 0);
    }
}

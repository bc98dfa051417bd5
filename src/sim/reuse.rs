//! Work shared by the many models of one diagnosis: sparse Cholesky factors here, the mesh's
//! assembly plan in [`super::scatter_plan`].
//!
//! A diagnosis solves dozens of candidate models of one mesh: the stiffness and the shifted
//! K₀ − σM of every candidate have the same sparsity pattern, and a loss-only candidate (a
//! damped patch, a viscoelastic layer on the plate's modulus) has the same K₀ as the model it
//! came from, up to the order in which its terms were summed. Factorised from scratch, the
//! static K₀ factor took 470 ms × 30 calls of a run on the reference plate (a sixth of its
//! CPU time), and each Lanczos solve repeated the AMD ordering and symbolic analysis (~150 ms).
//!
//! Inside a [`scope`] (the diagnosis opens one) this module keeps
//! - the **symbolic** factorisation per sparsity pattern ([`cholesky`]): the numeric factor
//!   computed with it is the one `sp_cholesky` computes, bit for bit (same ordering, same
//!   operations);
//! - the **numeric** factor of a matrix ([`cholesky_reused`]), handed again for a matrix with
//!   the same pattern whose values differ by at most [`REUSE_RELATIVE_TOLERANCE`] of the
//!   largest entry: the summation-order round-off of equal stiffness assembled as one term or
//!   as several. Used where the factor only builds basis vectors (the static residuals).
//!
//! Outside a scope nothing is kept (the simulator's one-off solves and the memory-budgeted
//! streaming keep their footprint); the last scope to close empties the caches.

use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{linalg::LltError, SparseColMat};
use faer::Side;

use super::combination::has_pattern;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// Largest difference, relative to the largest |entry|, at which a cached numeric factor is
/// handed out for another matrix: 1e-12, some thousand ulps. Equal stiffness summed in
/// another order differs by a few ulps of its largest contributions (≲ 1e-15 relative);
/// any real change of the model (a 1 % stiffer patch of one element) is ≳ 1e-6.
pub const REUSE_RELATIVE_TOLERANCE: f64 = 1e-12;
/// Sparsity patterns whose symbolic factorisation is kept (most recently used first).
const SYMBOLIC_ENTRIES: usize = 4;
/// Numeric factors kept (each holds the factor and a copy of the matrix's values).
const NUMERIC_ENTRIES: usize = 2;

static OPEN_SCOPES: AtomicUsize = AtomicUsize::new(0);
static CACHE: Mutex<Cache> = Mutex::new(Cache {
    symbolic: Vec::new(),
    numeric: Vec::new(),
});

struct Pattern {
    nrows: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
}

impl Pattern {
    fn of(a: &SparseColMat<usize, f64>) -> Self {
        let s = a.symbolic();
        Self {
            nrows: a.nrows(),
            col_ptr: s.col_ptr().to_vec(),
            row_idx: s.row_idx().to_vec(),
        }
    }

    fn matches(&self, a: &SparseColMat<usize, f64>) -> bool {
        a.nrows() == self.nrows && has_pattern(a, &self.col_ptr, &self.row_idx)
    }
}

struct Numeric {
    pattern: Arc<Pattern>,
    values: Vec<f64>,
    factor: Arc<Llt<usize, f64>>,
}

struct Cache {
    symbolic: Vec<(Arc<Pattern>, SymbolicLlt<usize>)>,
    numeric: Vec<Numeric>,
}

/// While the returned guard lives, factors are kept (see the module doc). Scopes nest and may
/// overlap across threads; the cache empties when the last one closes.
pub fn scope() -> ScopeGuard {
    OPEN_SCOPES.fetch_add(1, Ordering::SeqCst);
    ScopeGuard(())
}

/// Keeps the cache alive; see [`scope`].
pub struct ScopeGuard(());

impl Drop for ScopeGuard {
    fn drop(&mut self) {
        if OPEN_SCOPES.fetch_sub(1, Ordering::SeqCst) == 1 {
            let mut cache = lock();
            cache.symbolic.clear();
            cache.numeric.clear();
            super::scatter_plan::ScatterPlan::forget();
        }
    }
}

/// Whether a [`scope`] is open (work may be kept for the next model).
pub fn active() -> bool {
    OPEN_SCOPES.load(Ordering::SeqCst) > 0
}

fn lock() -> std::sync::MutexGuard<'static, Cache> {
    // A panic while holding the lock leaves only cached factors behind, each complete.
    CACHE.lock().unwrap_or_else(|e| e.into_inner())
}

/// The symbolic factorisation of `a`'s pattern (cached in a scope) and the pattern's key.
fn symbolic_of(
    a: &SparseColMat<usize, f64>,
) -> Result<(Arc<Pattern>, SymbolicLlt<usize>), LltError> {
    if active() {
        let mut cache = lock();
        if let Some(i) = cache.symbolic.iter().position(|(p, _)| p.matches(a)) {
            let hit = cache.symbolic.remove(i);
            cache.symbolic.insert(0, (hit.0.clone(), hit.1.clone()));
            return Ok(hit);
        }
    }
    let symbolic = SymbolicLlt::try_new(a.symbolic(), Side::Lower)?;
    let pattern = Arc::new(Pattern::of(a));
    if active() {
        let mut cache = lock();
        cache
            .symbolic
            .insert(0, (pattern.clone(), symbolic.clone()));
        cache.symbolic.truncate(SYMBOLIC_ENTRIES);
    }
    Ok((pattern, symbolic))
}

/// The lower Cholesky factor of the symmetric positive definite `a`: what
/// `a.sp_cholesky(Side::Lower)` returns, bit for bit, with the symbolic analysis of `a`'s
/// pattern reused inside a [`scope`].
pub fn cholesky(a: &SparseColMat<usize, f64>) -> Result<Llt<usize, f64>, LltError> {
    let (_, symbolic) = symbolic_of(a)?;
    Llt::try_new_with_symbolic(symbolic, a.as_ref(), Side::Lower)
}

/// Whether `values` equal `cached` within [`REUSE_RELATIVE_TOLERANCE`] of `cached`'s largest
/// magnitude (NaN never does).
fn values_match(values: &[f64], cached: &[f64]) -> bool {
    if values.len() != cached.len() {
        return false;
    }
    let scale = cached.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let bound = REUSE_RELATIVE_TOLERANCE * scale;
    values
        .iter()
        .zip(cached)
        .all(|(a, b)| (a - b).abs() <= bound)
}

/// The lower Cholesky factor of `a`, or inside a [`scope`] the factor of an earlier matrix of
/// the same pattern whose values differ from `a`'s by round-off only (see the module doc).
pub fn cholesky_reused(a: &SparseColMat<usize, f64>) -> Result<Arc<Llt<usize, f64>>, LltError> {
    if active() {
        let mut cache = lock();
        if let Some(i) = cache
            .numeric
            .iter()
            .position(|e| e.pattern.matches(a) && values_match(a.val(), &e.values))
        {
            let hit = cache.numeric.remove(i);
            let factor = hit.factor.clone();
            cache.numeric.insert(0, hit);
            return Ok(factor);
        }
    }
    let (pattern, symbolic) = symbolic_of(a)?;
    let factor = Arc::new(Llt::try_new_with_symbolic(
        symbolic,
        a.as_ref(),
        Side::Lower,
    )?);
    if active() {
        let mut cache = lock();
        cache.numeric.insert(
            0,
            Numeric {
                pattern,
                values: a.val().to_vec(),
                factor: factor.clone(),
            },
        );
        cache.numeric.truncate(NUMERIC_ENTRIES);
    }
    Ok(factor)
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::Triplet;
    use faer::Mat;

    /// A 1-D Laplacian plus `shift` on the diagonal (SPD for shift > −λ_min).
    fn laplacian(n: usize, shift: f64) -> SparseColMat<usize, f64> {
        let mut t = Vec::new();
        for i in 0..n {
            t.push(Triplet::new(i, i, 2.0 + shift));
            if i + 1 < n {
                t.push(Triplet::new(i + 1, i, -1.0));
                t.push(Triplet::new(i, i + 1, -1.0));
            }
        }
        SparseColMat::try_new_from_triplets(n, n, &t).unwrap()
    }

    fn solve(l: &Llt<usize, f64>, n: usize) -> Vec<f64> {
        use faer::linalg::solvers::Solve;
        let b = Mat::from_fn(n, 1, |i, _| (i as f64 * 0.37).sin());
        l.solve(b.as_ref()).col(0).iter().copied().collect()
    }

    /// The scoped, symbolic-reusing factor solves exactly as `sp_cholesky`'s; a numeric
    /// factor is handed out again for round-off changes only, and nothing is kept outside
    /// a scope. (One test: the cache is process-wide.)
    #[test]
    fn cached_factors_are_the_fresh_ones_and_only_for_round_off() {
        let n = 200;
        let a = laplacian(n, 0.1);
        let fresh = solve(&a.sp_cholesky(Side::Lower).unwrap(), n);
        {
            let _scope = scope();
            for _ in 0..2 {
                assert_eq!(solve(&cholesky(&a).unwrap(), n), fresh);
            }
            let first = cholesky_reused(&a).unwrap();
            // the same values up to round-off: the same factor
            let mut nudged = a.clone();
            nudged.val_mut()[0] *= 1.0 + 4.0 * f64::EPSILON;
            assert!(Arc::ptr_eq(&first, &cholesky_reused(&nudged).unwrap()));
            // a real change: a new factor, and it solves the new matrix
            let stiffer = laplacian(n, 0.1 + 1e-6);
            let other = cholesky_reused(&stiffer).unwrap();
            assert!(!Arc::ptr_eq(&first, &other));
            assert_eq!(
                solve(&other, n),
                solve(&stiffer.sp_cholesky(Side::Lower).unwrap(), n)
            );
            // NaN never matches
            let mut bad = a.clone();
            bad.val_mut()[3] = f64::NAN;
            assert!(!values_match(bad.val(), a.val()));
        }
        let outside = cholesky_reused(&a).unwrap();
        assert_eq!(solve(&outside, n), fresh);
        // (another test's diagnosis may hold a scope open meanwhile)
        if !active() {
            assert!(lock().numeric.is_empty() && lock().symbolic.is_empty());
        }
    }
}

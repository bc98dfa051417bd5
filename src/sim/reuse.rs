//! Work shared by the many models of one diagnosis: sparse Cholesky factors here, the mesh's
//! assembly plan in `scatter_plan`.
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
//! - the **modes** of an eigenproblem ([`kept_modes`], [`keep_modes`]), handed again for the
//!   same problem: K₀, M, the request and the solver options equal bit for bit, as recognised
//!   by a 128-bit [`fingerprint`]. A diagnosis meets the same problem again when a candidate
//!   it solved becomes the updated model, or a loss-only change leaves K₀ and M as they were
//!   (2 of the 13 Lanczos solves of the mass-and-patch case).
//!
//! Outside a scope nothing is kept (the simulator's one-off solves and the memory-budgeted
//! streaming keep their footprint); the last scope to close empties the caches.

use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{linalg::LltError, SparseColMat};
use faer::Side;

use super::combination::has_pattern;
use super::eigen::{EigenReport, Modes};
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
/// Solved eigenproblems kept at most (each its modes: dofs × modes values).
const MODES_ENTRIES: usize = 4;
/// Bytes of kept mode shapes at most, in all (the oldest go first; a solution larger than this
/// is not kept): 4 × 10 MB on the 42 000-dof plate, while a model of millions of dofs keeps one
/// or none rather than gigabytes.
const MODES_BYTES: usize = 256 << 20;

static OPEN_SCOPES: AtomicUsize = AtomicUsize::new(0);
static CACHE: Mutex<Cache> = Mutex::new(Cache {
    symbolic: Vec::new(),
    numeric: Vec::new(),
    modes: Vec::new(),
});
/// Modes handed out again (for the tests).
#[cfg(test)]
static MODES_HITS: AtomicUsize = AtomicUsize::new(0);

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
    modes: Vec<([u64; 2], Modes, EigenReport)>,
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
            cache.modes.clear();
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

/// A 128-bit fingerprint of `matrices` (shapes, patterns, the bits of every value) and of
/// `settings`: two independent multiply–xorshift lanes over every word, then mixed. Problems
/// that differ anywhere share one only if both 64-bit lanes coincide (by chance ≈ 2⁻¹²⁸; it is
/// not a cryptographic hash, and model matrices are not adversarial); a matrix of 2.4 M entries
/// takes ~20 ms, against ~2 s for the Lanczos solve it can save.
pub fn fingerprint(matrices: &[&SparseColMat<usize, f64>], settings: &[u64]) -> [u64; 2] {
    let mut lanes = Lanes {
        a: 0x243F_6A88_85A3_08D3,
        b: 0x1319_8A2E_0370_7344,
    };
    for m in matrices {
        lanes.add(m.nrows() as u64);
        lanes.add(m.ncols() as u64);
        m.symbolic()
            .col_ptr()
            .iter()
            .for_each(|&p| lanes.add(p as u64));
        m.symbolic()
            .row_idx()
            .iter()
            .for_each(|&i| lanes.add(i as u64));
        m.val().iter().for_each(|v| lanes.add(v.to_bits()));
    }
    settings.iter().for_each(|&w| lanes.add(w));
    [mix(lanes.a), mix(lanes.b ^ lanes.a)]
}

/// The two lanes of [`fingerprint`]: each step is one-to-one in the lane and in the word.
struct Lanes {
    a: u64,
    b: u64,
}

impl Lanes {
    #[inline(always)]
    fn add(&mut self, w: u64) {
        self.a = (self.a ^ w).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        self.a ^= self.a >> 32;
        self.b = self.b.wrapping_add(w).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        self.b = self.b.rotate_left(29);
    }
}

/// SplitMix64's finaliser: every input bit moves every output bit.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Inside a [`scope`]: the modes (and the report of their solve) kept for the problem
/// `key` ([`fingerprint`]), if any.
pub fn kept_modes(key: &[u64; 2]) -> Option<(Modes, EigenReport)> {
    if !active() {
        return None;
    }
    let mut cache = lock();
    let i = cache.modes.iter().position(|(k, _, _)| k == key)?;
    let hit = cache.modes.remove(i);
    let found = (hit.1.clone(), hit.2);
    cache.modes.insert(0, hit);
    #[cfg(test)]
    MODES_HITS.fetch_add(1, Ordering::SeqCst);
    Some(found)
}

/// Inside a [`scope`]: keeps `modes` as the solution of the problem `key` (within
/// `MODES_ENTRIES` and `MODES_BYTES`).
pub fn keep_modes(key: [u64; 2], modes: &Modes, report: &EigenReport) {
    let bytes = |m: &Modes| m.shapes.nrows() * m.shapes.ncols() * std::mem::size_of::<f64>();
    if active() && bytes(modes) <= MODES_BYTES {
        let mut cache = lock();
        cache.modes.insert(0, (key, modes.clone(), *report));
        let sizes: Vec<usize> = cache.modes.iter().map(|(_, m, _)| bytes(m)).collect();
        cache
            .modes
            .truncate(kept_count(&sizes, MODES_ENTRIES, MODES_BYTES));
    }
}

/// How many of the entries of `sizes` (bytes, newest first) stay: at most `max_entries`, and
/// the newest ones whose sizes add up to at most `max_bytes`.
fn kept_count(sizes: &[usize], max_entries: usize, max_bytes: usize) -> usize {
    let mut total = 0;
    sizes
        .iter()
        .take(max_entries)
        .take_while(|&&b| {
            total += b;
            total <= max_bytes
        })
        .count()
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
        solved_modes_are_kept_for_the_same_problem_only();
    }

    #[test]
    fn kept_modes_stay_within_their_count_and_bytes() {
        assert_eq!(kept_count(&[10, 20, 30], 4, 35), 2);
        assert_eq!(kept_count(&[10, 20, 30], 2, 100), 2);
        assert_eq!(kept_count(&[10, 20, 30], 4, 60), 3);
        assert_eq!(kept_count(&[40, 1], 4, 35), 0);
        assert_eq!(kept_count(&[], 4, 35), 0);
    }

    /// Part of the test above (the cache is process-wide): inside a scope the same problem gets
    /// the modes solved before, bit for bit what a solve gives; a 1e-9 stiffer plate, another
    /// request or other options are solved again.
    fn solved_modes_are_kept_for_the_same_problem_only() {
        use crate::sim::eigen::{lowest_modes, lowest_modes_with, EigenOptions, ModeRequest};
        let mut model = crate::sim::model::Model::reference_plate();
        (model.mesh.nx, model.mesh.ny, model.mesh.nz) = (4, 6, 1);
        let system = crate::sim::assembly::assemble(&model).unwrap();
        let request = ModeRequest::BelowHz(300.0);
        let fresh = lowest_modes(&system, request).unwrap();
        let same = |a: &Modes, b: &Modes| {
            a.frequencies_hz == b.frequencies_hz
                && (0..a.shapes.ncols()).all(|j| a.shapes.col(j).iter().eq(b.shapes.col(j).iter()))
        };
        let hits = || MODES_HITS.load(Ordering::SeqCst);
        {
            let _scope = scope();
            let first = lowest_modes(&system, request).unwrap();
            assert!(same(&first, &fresh), "a solve is deterministic");
            let before = hits();
            let again = lowest_modes(&system, request).unwrap();
            assert!(hits() > before && same(&again, &fresh));
            let mut stiffer = model.clone();
            stiffer.material.youngs_modulus *= 1.0 + 1e-9;
            let other = crate::sim::assembly::assemble(&stiffer).unwrap();
            for (system, request, options) in [
                (&other, request, EigenOptions::default()),
                (
                    &system,
                    ModeRequest::BelowHz(250.0),
                    EigenOptions::default(),
                ),
                (
                    &system,
                    ModeRequest::Count(fresh.frequencies_hz.len()),
                    EigenOptions::default(),
                ),
                (
                    &system,
                    request,
                    EigenOptions {
                        seed: 7,
                        ..EigenOptions::default()
                    },
                ),
            ] {
                let before = hits();
                lowest_modes_with(system, request, &options).unwrap();
                assert_eq!(hits(), before, "{request:?} {options:?}");
            }
            let stiffer_modes = lowest_modes(&other, request).unwrap();
            assert_ne!(stiffer_modes.frequencies_hz, fresh.frequencies_hz);
        }
        if !active() {
            assert!(lock().modes.is_empty());
            assert!(kept_modes(&[0, 0]).is_none());
        }
    }
}

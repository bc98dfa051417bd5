//! The lowest modes of K₀ φ = ω² M φ (K₀ = Σ_r K_r at the reference moduli), mass-normalised.
//!
//! Method: shift-invert Lanczos in the M inner product with full re-orthogonalisation, on faer's
//! sparse Cholesky (AMD ordering) of K₀ − σM with σ = −(2π f_shift)² < 0 (so the factor exists
//! even for a free plate with rigid-body modes). The Krylov space grows (no restart, every
//! Lanczos vector kept, which is the simplest form of locking) until the wanted Ritz pairs have
//! converged: the first N, or every Ritz value below fmax plus one converged Ritz value above
//! fmax (so the modes cover fmax with margin). The returned pairs' residuals are checked
//! explicitly by [`check_modes`].

use std::time::Instant;

use faer::linalg::solvers::Solve;
use faer::sparse::SparseColMat;
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};

pub use super::combination::{sparse_combination, sparse_combination_by_triplets};
use super::error::SimError;
use super::spmm::symmetric_times_dense;
use super::system::FeSystem;

/// Which modes to compute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ModeRequest {
    /// The lowest N modes.
    Count(usize),
    /// Every mode with frequency below this, Hz.
    BelowHz(f64),
}

/// Mass-normalised modes, ascending in frequency.
#[derive(Clone, Debug)]
pub struct Modes {
    /// Natural frequencies, Hz (a tiny negative eigenvalue of a rigid-body mode gives 0).
    pub frequencies_hz: Vec<f64>,
    /// Mode shapes over the free dofs, n_free × m, with ΦᵀMΦ = I.
    pub shapes: Mat<f64>,
}

/// Solver settings.
#[derive(Clone, Copy, Debug)]
pub struct EigenOptions {
    /// The shift is σ = −(2π shift_hz)² (negative: K₀ − σM is positive definite).
    pub shift_hz: f64,
    /// Relative Ritz residual |β_m s_mi| / θ_i below which a pair is converged.
    pub tolerance: f64,
    /// Seed of the random start vector.
    pub seed: u64,
}

impl Default for EigenOptions {
    fn default() -> Self {
        EigenOptions {
            shift_hz: 1.0,
            tolerance: 1e-12,
            seed: 0x5eed_d00d,
        }
    }
}

/// How the solve went (for `--timings`).
#[derive(Clone, Copy, Debug, Default)]
pub struct EigenReport {
    /// Forming and factorising K₀ − σM, s.
    pub factorisation_s: f64,
    /// Lanczos iterations, Ritz vectors, s.
    pub lanczos_s: f64,
    /// Lanczos steps (Krylov dimension).
    pub steps: usize,
    /// Of `lanczos_s`: triangular solves with the factor, s.
    pub solve_s: f64,
    /// Of `lanczos_s`: full re-orthogonalisation, s.
    pub reorth_s: f64,
    /// Of `lanczos_s`: eigen-solves of the tridiagonal matrix (convergence checks), s.
    pub tridiagonal_s: f64,
    /// Of `lanczos_s`: Ritz vectors and their Rayleigh–Ritz refinement, s.
    pub ritz_s: f64,
}

/// y = A x for a CSC matrix.
pub fn sparse_matvec(a: &SparseColMat<usize, f64>, x: &[f64], y: &mut [f64]) {
    y.iter_mut().for_each(|v| *v = 0.0);
    let a = a.as_ref();
    for (j, &xj) in x.iter().enumerate() {
        let rows = a.symbolic().row_idx_of_col_raw(j);
        let vals = a.val_of_col(j);
        for (&i, &v) in rows.iter().zip(vals) {
            y[i] += v * xj;
        }
    }
}

/// K₀ = Σ_r K_r of a system.
pub fn reference_stiffness(system: &FeSystem) -> Result<SparseColMat<usize, f64>, SimError> {
    let parts: Vec<_> = system
        .stiffness_terms
        .iter()
        .map(|t| (1.0, &t.matrix))
        .collect();
    sparse_combination(system.n_free, &parts, "K0")
}

/// The lowest modes of a model: assembled, then solved with default [`EigenOptions`] (for
/// callers that need the modes and not the matrices).
pub fn model_modes(model: &super::model::Model, request: ModeRequest) -> Result<Modes, SimError> {
    let system = super::assembly::assemble(model)?;
    lowest_modes(&system, request)
}

/// The lowest modes with default [`EigenOptions`].
pub fn lowest_modes(system: &FeSystem, request: ModeRequest) -> Result<Modes, SimError> {
    lowest_modes_with(system, request, &EigenOptions::default()).map(|(m, _)| m)
}

struct Lanczos {
    n: usize,
    q: Vec<f64>,
    p: Vec<f64>,
    alpha: Vec<f64>,
    beta: Vec<f64>,
}

impl Lanczos {
    fn m(&self) -> usize {
        self.alpha.len()
    }
    fn q_ref(&self, m: usize) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.q[..self.n * m], self.n, m)
    }
    fn p_ref(&self, m: usize) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.p[..self.n * m], self.n, m)
    }
    /// w ← w − Q (Pᵀ w) over the first `m` vectors (one classical Gram–Schmidt pass).
    ///
    /// The rows are split in two halves done on two threads: the pass reads the whole basis
    /// twice and is bound by memory bandwidth, which one core does not saturate. (While the
    /// interface form's static shapes occupy the other core, the helper shares it.)
    fn orthogonalise(&self, w: &mut [f64], m: usize) {
        if m == 0 {
            return;
        }
        let n = self.n;
        let half = if n >= PARALLEL_ROWS_MIN { n / 2 } else { n };
        let (w_top, w_bottom) = w.split_at_mut(half);
        let rows = [(0, half), (half, n - half)];
        let part = |(r0, len): (usize, usize), w: &[f64]| -> Mat<f64> {
            let mut c = Mat::<f64>::zeros(m, 1);
            if len > 0 {
                faer::linalg::matmul::matmul(
                    c.as_mut(),
                    Accum::Replace,
                    self.p_ref(m).subrows(r0, len).transpose(),
                    MatRef::from_column_major_slice(w, len, 1),
                    1.0,
                    Par::Seq,
                );
            }
            c
        };
        let update = |(r0, len): (usize, usize), w: &mut [f64], c: MatRef<'_, f64>| {
            if len > 0 {
                faer::linalg::matmul::matmul(
                    MatMut::from_column_major_slice_mut(w, len, 1),
                    Accum::Add,
                    self.q_ref(m).subrows(r0, len),
                    c,
                    -1.0,
                    Par::Seq,
                );
            }
        };
        let c = if half < n {
            std::thread::scope(|sc| {
                let h = sc.spawn(|| part(rows[1], w_bottom));
                let mut c = part(rows[0], w_top);
                c += h.join().expect("re-orthogonalisation worker");
                c
            })
        } else {
            part(rows[0], w_top)
        };
        if half < n {
            std::thread::scope(|sc| {
                sc.spawn(|| update(rows[1], w_bottom, c.as_ref()));
                update(rows[0], w_top, c.as_ref());
            });
        } else {
            update(rows[0], w_top, c.as_ref());
        }
    }
}

/// Lanczos vectors at least this long are re-orthogonalised on two threads.
const PARALLEL_ROWS_MIN: usize = 20_000;

fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    acc.iter().sum::<f64>() + tail
}

fn random_vector(n: usize, state: &mut u64) -> Vec<f64> {
    (0..n)
        .map(|_| {
            *state ^= *state << 13;
            *state ^= *state >> 7;
            *state ^= *state << 17;
            (*state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect()
}

/// The lowest modes, with options and a report of where the time went.
pub fn lowest_modes_with(
    system: &FeSystem,
    request: ModeRequest,
    options: &EigenOptions,
) -> Result<(Modes, EigenReport), SimError> {
    let n = system.n_free;
    match request {
        ModeRequest::Count(0) => {
            return Err(SimError::Eigen("requested 0 modes, expected ≥ 1".into()))
        }
        ModeRequest::Count(c) if c > n => {
            return Err(SimError::Eigen(format!(
                "requested {c} modes, but the model has only {n} free dofs"
            )))
        }
        ModeRequest::BelowHz(f) if !(f.is_finite() && f > 0.0) => {
            return Err(SimError::Eigen(format!("fmax must be > 0 Hz, got {f}")))
        }
        _ => {}
    }
    let mut report = EigenReport::default();
    let t0 = Instant::now();
    let sigma = -(2.0 * std::f64::consts::PI * options.shift_hz).powi(2);
    let k0 = reference_stiffness(system)?;
    // Inside a diagnosis the same problem comes again (a candidate becoming the update).
    let key = super::reuse::active().then(|| {
        let request_words = match request {
            ModeRequest::Count(c) => [0, c as u64],
            ModeRequest::BelowHz(f) => [1, f.to_bits()],
        };
        let option_words = [
            options.shift_hz.to_bits(),
            options.tolerance.to_bits(),
            options.seed,
        ];
        super::reuse::fingerprint(
            &[&k0, &system.mass],
            &[request_words.as_slice(), &option_words].concat(),
        )
    });
    if let Some(kept) = key.as_ref().and_then(super::reuse::kept_modes) {
        return Ok(kept);
    }
    let a = sparse_combination(n, &[(1.0, &k0), (-sigma, &system.mass)], "K0 - sigma M")?;
    let llt = super::reuse::cholesky(&a).map_err(|e| SimError::Linear {
        what: format!("Cholesky of K0 - sigma M (sigma = {sigma:e})"),
        message: format!("{e:?} (is the mass matrix positive definite?)"),
    })?;
    drop(a);
    report.factorisation_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();

    let theta_cut = match request {
        ModeRequest::BelowHz(f) => Some(1.0 / ((2.0 * std::f64::consts::PI * f).powi(2) - sigma)),
        ModeRequest::Count(_) => None,
    };
    let mut lz = Lanczos {
        n,
        q: Vec::new(),
        p: Vec::new(),
        alpha: Vec::new(),
        beta: Vec::new(),
    };
    let mut rng = options.seed | 1;
    let mut r = vec![0.0; n];
    let mut w = random_vector(n, &mut rng);
    sparse_matvec(&system.mass, &w, &mut r);
    let b0 = dot(&w, &r).sqrt();
    lz.q.extend(w.iter().map(|v| v / b0));
    lz.p.extend(r.iter().map(|v| v / b0));
    let mut next_check = match request {
        ModeRequest::Count(c) => (2 * c + 20).max(40),
        ModeRequest::BelowHz(_) => 60,
    }
    .min(n);
    let (_theta, s, wanted) = loop {
        let j = lz.m();
        w.copy_from_slice(&lz.p[j * n..(j + 1) * n]);
        let ts = Instant::now();
        llt.solve_in_place(MatMut::from_column_major_slice_mut(&mut w, n, 1));
        report.solve_s += ts.elapsed().as_secs_f64();
        if j > 0 {
            let bj = lz.beta[j - 1];
            for (wi, qi) in w.iter_mut().zip(&lz.q[(j - 1) * n..j * n]) {
                *wi -= bj * qi;
            }
        }
        let aj = dot(&lz.p[j * n..(j + 1) * n], &w);
        for (wi, qi) in w.iter_mut().zip(&lz.q[j * n..(j + 1) * n]) {
            *wi -= aj * qi;
        }
        lz.alpha.push(aj);
        let tr = Instant::now();
        lz.orthogonalise(&mut w, j + 1);
        report.reorth_s += tr.elapsed().as_secs_f64();
        sparse_matvec(&system.mass, &w, &mut r);
        let mut bj = dot(&w, &r).max(0.0).sqrt();
        let m = j + 1;
        if m >= next_check || m == n {
            let tt = Instant::now();
            let (theta, s) = tridiagonal_eigen(&lz.alpha, &lz.beta)?;
            report.tridiagonal_s += tt.elapsed().as_secs_f64();
            if let Some(wanted) =
                converged(&theta, &s, bj, request, theta_cut, options.tolerance, n)
            {
                break (theta, s, wanted);
            }
            if m == n {
                return Err(SimError::Eigen(format!(
                    "Lanczos exhausted all {n} dofs without convergence"
                )));
            }
            // every ~6 %: each step late in the run costs a solve and a pass over the whole
            // basis, so overshooting convergence by up to a quarter (m/4, as before) cost more
            // than the extra eigen-solves of the tridiagonal matrix
            next_check = (m + (m / 16).max(10)).min(n);
        }
        if bj <= 1e-10 * aj.abs() {
            // Invariant subspace found: continue with a fresh random direction (β = 0).
            w = random_vector(n, &mut rng);
            lz.orthogonalise(&mut w, m);
            lz.orthogonalise(&mut w, m);
            sparse_matvec(&system.mass, &w, &mut r);
            let nb = dot(&w, &r).sqrt();
            w.iter_mut().for_each(|v| *v /= nb);
            r.iter_mut().for_each(|v| *v /= nb);
            bj = 0.0;
        } else {
            w.iter_mut().for_each(|v| *v /= bj);
            r.iter_mut().for_each(|v| *v /= bj);
        }
        lz.beta.push(bj);
        lz.q.extend_from_slice(&w);
        lz.p.extend_from_slice(&r);
    };
    let m = lz.m();
    report.steps = m;
    let tz = Instant::now();
    // Ritz vectors Φ = Q S[:, wanted] (θ descending = λ ascending).
    let mut sel = Mat::<f64>::zeros(m, wanted);
    for c in 0..wanted {
        let idx = m - 1 - c; // eigenvalues of T ascending
        for i in 0..m {
            sel[(i, c)] = s[(i, idx)];
        }
    }
    let mut shapes = Mat::<f64>::zeros(n, wanted);
    faer::linalg::matmul::matmul(
        shapes.as_mut(),
        Accum::Replace,
        lz.q_ref(m),
        sel.as_ref(),
        1.0,
        faer::get_global_parallelism(),
    );
    drop(lz);
    let (freqs, shapes) = refine(system, &k0, &llt, shapes)?;
    report.ritz_s = tz.elapsed().as_secs_f64();
    report.lanczos_s = t1.elapsed().as_secs_f64();
    let modes = Modes {
        frequencies_hz: freqs,
        shapes,
    };
    if let Some(key) = key {
        super::reuse::keep_modes(key, &modes, &report);
    }
    Ok((modes, report))
}

/// One step of subspace iteration with Rayleigh–Ritz on the converged Ritz vectors:
/// Y = (K₀ − σM)⁻¹ M Φ, then the k × k problem (YᵀK₀Y) z = λ (YᵀMY) z. It damps the vectors'
/// remaining error in the stiff (high-frequency, incompatible-mode) directions by θ_high/θ,
/// gives Rayleigh-quotient eigenvalues and M-orthonormality to round-off.
fn refine(
    system: &FeSystem,
    k0: &SparseColMat<usize, f64>,
    llt: &faer::sparse::linalg::solvers::Llt<usize, f64>,
    phi: Mat<f64>,
) -> Result<(Vec<f64>, Mat<f64>), SimError> {
    let (n, k) = (phi.nrows(), phi.ncols());
    if k == 0 {
        // No mode below the requested frequency: nothing to refine.
        return Ok((Vec::new(), phi));
    }
    let mut y = symmetric_times_dense(&system.mass, phi.as_ref());
    drop(phi);
    llt.solve_in_place(y.as_mut());
    let ky = symmetric_times_dense(k0, y.as_ref());
    let my = symmetric_times_dense(&system.mass, y.as_ref());
    let par = faer::get_global_parallelism();
    let mut kr = Mat::<f64>::zeros(k, k);
    let mut mr = Mat::<f64>::zeros(k, k);
    faer::linalg::matmul::matmul(
        kr.as_mut(),
        Accum::Replace,
        y.transpose(),
        ky.as_ref(),
        1.0,
        par,
    );
    faer::linalg::matmul::matmul(
        mr.as_mut(),
        Accum::Replace,
        y.transpose(),
        my.as_ref(),
        1.0,
        par,
    );
    drop((ky, my));
    let kr = nalgebra::DMatrix::from_fn(k, k, |i, j| 0.5 * (kr[(i, j)] + kr[(j, i)]));
    let mr = nalgebra::DMatrix::from_fn(k, k, |i, j| 0.5 * (mr[(i, j)] + mr[(j, i)]));
    let l = mr
        .cholesky()
        .ok_or_else(|| SimError::Eigen("Rayleigh–Ritz: Y^T M Y is not positive definite".into()))?
        .l();
    let linv_kr = l
        .solve_lower_triangular(&kr)
        .ok_or_else(|| SimError::Eigen("Rayleigh–Ritz: singular Cholesky factor".into()))?;
    let c = l
        .solve_lower_triangular(&linv_kr.transpose())
        .ok_or_else(|| SimError::Eigen("Rayleigh–Ritz: singular Cholesky factor".into()))?;
    let c = 0.5 * (&c + c.transpose());
    let eig = c.symmetric_eigen();
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let z = nalgebra::DMatrix::from_fn(k, k, |i, j| eig.eigenvectors[(i, order[j])]);
    let z = l
        .transpose()
        .solve_upper_triangular(&z)
        .ok_or_else(|| SimError::Eigen("Rayleigh–Ritz: singular Cholesky factor".into()))?;
    let zf = Mat::<f64>::from_fn(k, k, |i, j| z[(i, j)]);
    let mut shapes = Mat::<f64>::zeros(n, k);
    faer::linalg::matmul::matmul(
        shapes.as_mut(),
        Accum::Replace,
        y.as_ref(),
        zf.as_ref(),
        1.0,
        par,
    );
    let freqs = order
        .iter()
        .map(|&i| eig.eigenvalues[i].max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
        .collect();
    Ok((freqs, shapes))
}

/// Eigen-decomposition of the symmetric tridiagonal T (ascending eigenvalues, columns).
fn tridiagonal_eigen(alpha: &[f64], beta: &[f64]) -> Result<(Vec<f64>, Mat<f64>), SimError> {
    let m = alpha.len();
    let t = Mat::<f64>::from_fn(m, m, |i, j| {
        if i == j {
            alpha[i]
        } else if i == j + 1 {
            beta[j]
        } else if j == i + 1 {
            beta[i]
        } else {
            0.0
        }
    });
    let evd = t
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| SimError::Eigen(format!("tridiagonal eigen-solve of size {m}: {e:?}")))?;
    let s = evd.S().column_vector();
    let theta = (0..m).map(|i| s[i]).collect();
    Ok((theta, evd.U().to_owned()))
}

/// Number of wanted Ritz pairs when all of them have converged, else `None`.
fn converged(
    theta: &[f64],
    s: &Mat<f64>,
    beta_m: f64,
    request: ModeRequest,
    theta_cut: Option<f64>,
    tol: f64,
    n: usize,
) -> Option<usize> {
    let m = theta.len();
    let ok = |c: usize| {
        let idx = m - 1 - c;
        (beta_m * s[(m - 1, idx)]).abs() <= tol * theta[idx].abs()
    };
    match (request, theta_cut) {
        (ModeRequest::Count(k), _) => (k <= m && (0..k).all(ok)).then_some(k),
        (ModeRequest::BelowHz(_), Some(cut)) => {
            let k = theta.iter().filter(|&&t| t > cut).count();
            if m == n {
                return Some(k);
            }
            (k < m && (0..=k).all(ok)).then_some(k)
        }
        _ => None,
    }
}

/// Quality of computed modes: (max over modes of ‖K₀φ − λMφ‖ / (‖K₀φ‖ + λ‖Mφ‖),
/// max |ΦᵀMΦ − I|). At an eigenpair ‖K₀φ‖ = λ‖Mφ‖, so the first number is half of
/// ‖K₀φ − λMφ‖/‖K₀φ‖ but stays finite for rigid-body modes.
pub fn check_modes(system: &FeSystem, modes: &Modes) -> Result<(f64, f64), SimError> {
    let k0 = reference_stiffness(system)?;
    let m = modes.shapes.ncols();
    let mphi = symmetric_times_dense(&system.mass, modes.shapes.as_ref());
    let kphi_all = symmetric_times_dense(&k0, modes.shapes.as_ref());
    let mut worst_res: f64 = 0.0;
    for c in 0..m {
        let kphi = kphi_all.col_as_slice(c);
        let lambda = (2.0 * std::f64::consts::PI * modes.frequencies_hz[c]).powi(2);
        let mp = mphi.col_as_slice(c);
        let res: f64 = kphi
            .iter()
            .zip(mp)
            .map(|(k, mv)| (k - lambda * mv).powi(2))
            .sum::<f64>()
            .sqrt();
        let scale = dot(kphi, kphi).sqrt() + lambda * dot(mp, mp).sqrt();
        worst_res = worst_res.max(res / scale.max(f64::MIN_POSITIVE));
    }
    let mut g = Mat::<f64>::zeros(m, m);
    faer::linalg::matmul::matmul(
        g.as_mut(),
        Accum::Replace,
        modes.shapes.transpose(),
        mphi.as_ref(),
        1.0,
        faer::get_global_parallelism(),
    );
    let mut worst_orth: f64 = 0.0;
    for i in 0..m {
        for j in 0..m {
            let e = g[(i, j)] - if i == j { 1.0 } else { 0.0 };
            worst_orth = worst_orth.max(e.abs());
        }
    }
    Ok((worst_res, worst_orth))
}

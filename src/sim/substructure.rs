//! Craig–Bampton reduction of viscoelastic regions: the basis of the fast FRF for models whose
//! stiffness depends on frequency.
//!
//! Why: a region r whose only frequency dependence is a scalar factor s_r(ω) on its stiffness
//! K_r can be condensed exactly, so its local dynamics need not be found as modes of the whole
//! structure (one Lanczos step at a time) nor doubled by a residual vector each. Its *interior*
//! dofs (touched by K_r and by no other stiffness term) satisfy
//! s_r K_r,ii u_i + s_r K_r,ib u_b − ω² (M_ii u_i + M_ib u_b) = 0 (no load there unless the
//! excitation is), so
//!
//! - the static constraint modes Ψ = −K_r,ii⁻¹ K_r,ib do not depend on s_r(ω): they are the
//!   interior parts of the modes of the structure with the interior *massless* (the Lanczos
//!   operator (K₀ − σM)⁻¹M then condenses the interior statically), and
//! - the fixed-interface modes K_r,ii φ = λ M_ii φ diagonalise the interior at every ω.
//!
//! The basis is [modes of the structure with massless interiors | fixed-interface modes of each
//! interior], M-orthonormalised, then the static residuals, then residual vectors compressed to
//! their principal directions ([`RESIDUAL_COMPRESSION`]): the *inertial* residuals K₀⁻¹Mφ of
//! the interior modes and of the in-band modes (the quasi-static response of the plate to the
//! forces a vibrating interior puts on its boundary, and of a truncated interior to its own
//! inertia; without them the coarse test plate misses 5 % per band at 450–500 Hz), and for
//! modes with a noticeable strain-energy share in a stiffening region the first-order residual
//! K₀⁻¹ K_r φ ([`MODE_RESIDUAL_SHARE`]). Fixed-interface modes above the cut-off (at the
//! region's relaxed modulus, the lowest it has) are left out, their static part being in Ψ: the
//! classical Craig–Bampton truncation, which serves a damping layer (the plate's material with
//! a frequency-dependent loss, added stiffness and mass: few interior modes in the band).
//!
//! Limit: a soft patch keeps all its interior modes (the example's has 1047, all below 3 kHz),
//! and they make the state-space eigen-solve of the FRF large (N = 4733 at 0–2 kHz).

use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, MatRef, Side};

use super::eigen::{lowest_modes, ModeRequest, Modes};
use super::frf::FrfError;
use super::reduced::spmm;
use super::system::{FeSystem, StiffnessTerm};
use super::SimError;

/// A mode gets the first-order residual vector K₀⁻¹ K_r φ of an SLS region r when its strain
/// energy share in r times the region's largest relative stiffening over the band exceeds this
/// (the residual then corrects a frequency shift above ~0.01 % of the mode's; on the coarse
/// test plate the soft patch selects none).
pub const MODE_RESIDUAL_SHARE: f64 = 1e-4;

/// Interiors with at most this many dofs get their fixed-interface modes from a dense
/// eigen-solve (larger ones are not substructured).
pub const DENSE_INTERIOR_MAX_DOFS: usize = 4000;

/// Largest relative eigen-residual and M-orthonormality error of the modes with massless
/// interiors for the Craig–Bampton basis to be used.
pub const MODE_CHECK_TOLERANCE: f64 = 1e-6;

/// Residual vectors (their parts outside the modes, scaled to unit M-norm) are kept along the
/// principal directions whose Gram eigenvalue exceeds this fraction of the largest.
pub const RESIDUAL_COMPRESSION: f64 = 1e-8;

/// The dofs that only one frequency-dependent stiffness term touches.
#[derive(Clone, Debug, PartialEq)]
pub struct RegionInterior {
    /// Index of the term in [`FeSystem::stiffness_terms`].
    pub term: usize,
    /// Free dof indices, ascending.
    pub dofs: Vec<usize>,
}

/// The interior of every viscoelastic (SLS) term: the dofs its matrix touches and no other
/// term's matrix does. Empty interiors are left out.
pub fn sls_interiors(sys: &FeSystem) -> Vec<RegionInterior> {
    let n = sys.n_free;
    let touched: Vec<Vec<bool>> = sys
        .stiffness_terms
        .iter()
        .map(|t| {
            let (sym, val) = t.matrix.parts();
            (0..n)
                .map(|j| sym.col_range(j).any(|k| val[k] != 0.0))
                .collect()
        })
        .collect();
    let count: Vec<usize> = (0..n)
        .map(|d| touched.iter().filter(|t| t[d]).count())
        .collect();
    sys.stiffness_terms
        .iter()
        .enumerate()
        .filter(|(_, t)| t.sls.is_some())
        .filter_map(|(r, _)| {
            let dofs: Vec<usize> = (0..n).filter(|&d| touched[r][d] && count[d] == 1).collect();
            (!dofs.is_empty()).then_some(RegionInterior { term: r, dofs })
        })
        .collect()
}

/// `a[dofs, dofs]` as a sparse matrix of size |dofs|.
fn submatrix(
    a: &SparseColMat<usize, f64>,
    dofs: &[usize],
    what: &str,
) -> Result<SparseColMat<usize, f64>, SimError> {
    let mut local = vec![usize::MAX; a.nrows()];
    for (i, &d) in dofs.iter().enumerate() {
        local[d] = i;
    }
    let (sym, val) = a.parts();
    let mut trip = Vec::new();
    for (jl, &j) in dofs.iter().enumerate() {
        for k in sym.col_range(j) {
            let il = local[sym.row_idx()[k]];
            if il != usize::MAX {
                trip.push(Triplet::new(il, jl, val[k]));
            }
        }
    }
    super::assembly::sparse_from_triplets(dofs.len(), &trip, what)
}

/// `sys` with the mass of every interior removed (rows and columns of its dofs): the structure
/// whose modes carry the interiors statically (their parts are Ψ u_b).
pub fn with_massless_interiors(
    sys: &FeSystem,
    interiors: &[RegionInterior],
) -> Result<FeSystem, SimError> {
    let mut inside = vec![false; sys.n_free];
    for r in interiors {
        r.dofs.iter().for_each(|&d| inside[d] = true);
    }
    let (sym, val) = sys.mass.parts();
    let mut trip = Vec::new();
    for j in (0..sys.n_free).filter(|&j| !inside[j]) {
        for k in sym.col_range(j) {
            let i = sym.row_idx()[k];
            if !inside[i] {
                trip.push(Triplet::new(i, j, val[k]));
            }
        }
    }
    Ok(FeSystem {
        mass: super::assembly::sparse_from_triplets(sys.n_free, &trip, "boundary mass")?,
        ..sys.clone()
    })
}

/// The fixed-interface modes of `interior` below `cutoff_hz` at the region's reference modulus,
/// as columns over all free dofs (zero outside the interior), with their frequencies.
pub fn fixed_interface_modes(
    sys: &FeSystem,
    interior: &RegionInterior,
    cutoff_hz: f64,
) -> Result<Modes, SimError> {
    let local = interior_modes(sys, interior, cutoff_hz)?;
    Ok(Modes {
        shapes: on_free_dofs(sys.n_free, interior, &local.shapes),
        frequencies_hz: local.frequencies_hz,
    })
}

/// Columns over an interior's own dofs (row i is `interior.dofs[i]`) as columns over all `n`
/// free dofs, zero outside the interior.
pub fn on_free_dofs(n: usize, interior: &RegionInterior, local: &Mat<f64>) -> Mat<f64> {
    let mut full = Mat::<f64>::zeros(n, local.ncols());
    for c in 0..local.ncols() {
        for (i, &d) in interior.dofs.iter().enumerate() {
            full[(d, c)] = local[(i, c)];
        }
    }
    full
}

/// The fixed-interface modes of `interior` below `cutoff_hz` (`f64::INFINITY`: every mode with
/// mass, see [`MASSLESS_RELATIVE`]) at the region's reference modulus, mass-normalised, as
/// columns over the interior's own dofs (row i is `interior.dofs[i]`).
pub fn interior_modes(
    sys: &FeSystem,
    interior: &RegionInterior,
    cutoff_hz: f64,
) -> Result<Modes, SimError> {
    let term = &sys.stiffness_terms[interior.term];
    let ni = interior.dofs.len();
    if ni > DENSE_INTERIOR_MAX_DOFS {
        return Err(SimError::InvalidValue {
            key: format!("interior of {}", term.name),
            message: format!(
                "expected at most {DENSE_INTERIOR_MAX_DOFS} dofs for the dense eigen-solve, got {ni}"
            ),
        });
    }
    let k = submatrix(&term.matrix, &interior.dofs, "interior stiffness")?;
    let m = submatrix(&sys.mass, &interior.dofs, "interior mass")?;
    let sub = FeSystem {
        n_free: ni,
        mass: m,
        stiffness_terms: vec![StiffnessTerm {
            matrix: k,
            ..term_without_matrix(term)
        }],
        rayleigh: None,
        force: vec![0.0; ni],
        sensors: Vec::new(),
    };
    dense_modes_below(&sub, cutoff_hz)
}

/// Directions of an interior whose inverted eigenvalue μ = 1/λ is below this fraction of the
/// largest carry no mass (the incompatible-mode dofs): on the example's soft patch the 1047
/// modes with mass have μ ≥ 2.5e-6 of the largest, the 960 massless ones ≤ 1e-16.
pub const MASSLESS_RELATIVE: f64 = 1e-12;

/// A term's factor data with an empty matrix placeholder replaced by the caller.
fn term_without_matrix(t: &StiffnessTerm) -> StiffnessTerm {
    StiffnessTerm {
        name: format!("{} interior", t.name),
        matrix: SparseColMat::try_new_from_triplets(0, 0, &[])
            .expect("an empty 0 × 0 matrix is always valid"),
        loss_factor: t.loss_factor,
        sls: t.sls,
        reference_modulus_pa: t.reference_modulus_pa,
    }
}

/// Every mode of a small system below `cutoff_hz` by a dense generalized eigen-solve. The
/// stiffness of an interior is positive definite (its boundary is held) but its mass need not
/// be (the incompatible-mode dofs' 2 × 2 × 2-point mass has rank 8 per element), so the
/// problem is solved inverted: K = L Lᵀ, L⁻¹ M L⁻ᵀ z = μ z, λ = 1/μ, φ = L⁻ᵀ z / √μ; the
/// massless directions (μ ≈ 0) are infinitely high and left out.
fn dense_modes_below(sys: &FeSystem, cutoff_hz: f64) -> Result<Modes, SimError> {
    use faer::linalg::triangular_solve::{
        solve_lower_triangular_in_place, solve_upper_triangular_in_place,
    };
    let n = sys.n_free;
    let dense = |a: &SparseColMat<usize, f64>| {
        let mut d = Mat::<f64>::zeros(n, n);
        let (sym, val) = a.parts();
        for j in 0..n {
            for k in sym.col_range(j) {
                d[(sym.row_idx()[k], j)] += val[k];
            }
        }
        d
    };
    let (k, m) = (dense(&sys.stiffness_terms[0].matrix), dense(&sys.mass));
    let llt = k.llt(Side::Lower).map_err(|e| {
        SimError::Eigen(format!(
            "interior stiffness is not positive definite: {e:?}"
        ))
    })?;
    let l = llt.L().to_owned();
    let par = faer::get_global_parallelism();
    let mut y = m;
    solve_lower_triangular_in_place(l.as_ref(), y.as_mut(), par);
    let mut c = y.transpose().to_owned();
    solve_lower_triangular_in_place(l.as_ref(), c.as_mut(), par);
    let c = Mat::from_fn(n, n, |i, j| 0.5 * (c[(i, j)] + c[(j, i)]));
    let evd = c
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| SimError::Eigen(format!("interior eigen-solve: {e:?}")))?;
    let mu: Vec<f64> = evd.S().column_vector().iter().copied().collect();
    let omega_cut = 2.0 * std::f64::consts::PI * cutoff_hz;
    let largest = mu.iter().fold(0.0f64, |a, &m| a.max(m));
    // μ descending = λ ascending
    let mut keep: Vec<usize> = (0..n)
        .filter(|&i| mu[i] > MASSLESS_RELATIVE * largest && mu[i] * omega_cut * omega_cut >= 1.0)
        .collect();
    keep.sort_by(|&a, &b| mu[b].total_cmp(&mu[a]));
    let z = Mat::from_fn(n, keep.len(), |i, j| {
        evd.U()[(i, keep[j])] / mu[keep[j]].sqrt()
    });
    let mut shapes = z;
    solve_upper_triangular_in_place(l.transpose(), shapes.as_mut(), par);
    Ok(Modes {
        frequencies_hz: keep
            .iter()
            .map(|&i| (1.0 / mu[i]).sqrt() / (2.0 * std::f64::consts::PI))
            .collect(),
        shapes,
    })
}

/// Largest |s_r(ω)/s_r(0) − 1| of a term over 0 … `fmax_hz` (the SLS modulus rises
/// monotonically, so its value at fmax), 0 for a constant term.
pub fn relative_stiffening(t: &StiffnessTerm, fmax_hz: f64) -> f64 {
    let (a, b) = t.factor(2.0 * std::f64::consts::PI * fmax_hz);
    let (a0, b0) = t.factor(0.0);
    let d0 = a0 * a0 + b0 * b0;
    if d0 <= 0.0 {
        return 0.0;
    }
    // (a + jb)/(a0 + j b0) − 1
    let re = (a * a0 + b * b0) / d0 - 1.0;
    let im = (b * a0 - a * b0) / d0;
    re.hypot(im)
}

/// The Craig–Bampton candidate vectors of `sys` for the band 0 … `fmax_hz`: the modes of the
/// structure with massless interiors below `cutoff_hz` (with their frequencies), then the
/// fixed-interface modes of each interior below `cutoff_hz`, then the first-order residuals
/// K₀⁻¹K_r φ of the modes below `fmax_hz` whose share in an SLS region r is large enough
/// ([`MODE_RESIDUAL_SHARE`]). The caller adds the static residuals and M-orthonormalises.
pub struct CraigBamptonVectors {
    /// Modes of the structure with massless interiors, Hz, and their shapes.
    pub boundary_modes: Modes,
    /// Fixed-interface modes of every interior (columns over all free dofs), Hz.
    pub interior_modes: Modes,
    /// Indices into `boundary_modes` of the modes that get the first-order residual, with the
    /// SLS term it is for.
    pub residual_modes: Vec<(usize, usize)>,
    /// The analysed band's upper end, Hz.
    pub fmax_hz: f64,
}

/// Builds [`CraigBamptonVectors`]; `None` when no SLS region has an interior, when an interior
/// is too large for the dense eigen-solve ([`DENSE_INTERIOR_MAX_DOFS`]: shift-invert Lanczos
/// is not reliable on an interior whose mass is singular, as the incompatible-mode dofs make
/// it), or when the modes with massless interiors fail their residual check
/// ([`MODE_CHECK_TOLERANCE`]); the caller then reduces on the modes of the whole structure.
pub fn craig_bampton_vectors(
    sys: &FeSystem,
    fmax_hz: f64,
    cutoff_hz: f64,
) -> Result<Option<CraigBamptonVectors>, SimError> {
    let interiors = sls_interiors(sys);
    if interiors.is_empty() {
        return Ok(None);
    }
    if interiors
        .iter()
        .any(|r| r.dofs.len() > DENSE_INTERIOR_MAX_DOFS)
    {
        return Ok(None);
    }
    let boundary = with_massless_interiors(sys, &interiors)?;
    let boundary_modes = lowest_modes(&boundary, ModeRequest::BelowHz(cutoff_hz))?;
    let (residual, orthogonality) = super::eigen::check_modes(&boundary, &boundary_modes)?;
    let suspect = |x: f64| x.is_nan() || x > MODE_CHECK_TOLERANCE;
    if suspect(residual) || suspect(orthogonality) {
        return Ok(None);
    }
    drop(boundary);
    let mut freqs = Vec::new();
    let mut cols: Vec<Mat<f64>> = Vec::new();
    for r in &interiors {
        let m = fixed_interface_modes(sys, r, cutoff_hz)?;
        freqs.extend(m.frequencies_hz.iter().copied());
        cols.push(m.shapes);
    }
    let total: usize = cols.iter().map(|c| c.ncols()).sum();
    let mut shapes = Mat::<f64>::zeros(sys.n_free, total);
    let mut at = 0;
    for c in &cols {
        shapes
            .as_mut()
            .submatrix_mut(0, at, sys.n_free, c.ncols())
            .copy_from(c);
        at += c.ncols();
    }
    let residual_modes = residual_modes(sys, &boundary_modes, fmax_hz)?;
    Ok(Some(CraigBamptonVectors {
        boundary_modes,
        interior_modes: Modes {
            frequencies_hz: freqs,
            shapes,
        },
        residual_modes,
        fmax_hz,
    }))
}

/// (mode, SLS term) pairs below `fmax_hz` whose strain-energy share φᵀK_rφ/ω² in the term,
/// times the term's stiffening over the band, exceeds [`MODE_RESIDUAL_SHARE`].
fn residual_modes(
    sys: &FeSystem,
    modes: &Modes,
    fmax_hz: f64,
) -> Result<Vec<(usize, usize)>, FrfError> {
    let mut out = Vec::new();
    for (r, t) in sys.stiffness_terms.iter().enumerate() {
        if t.sls.is_none() {
            continue;
        }
        let stiffening = relative_stiffening(t, fmax_hz);
        for (i, &f) in modes.frequencies_hz.iter().enumerate() {
            if f > fmax_hz {
                continue;
            }
            let share = strain_energy(&t.matrix, modes.shapes.col(i).as_mat())
                / (2.0 * std::f64::consts::PI * f.max(1e-3)).powi(2);
            if share * stiffening > MODE_RESIDUAL_SHARE {
                out.push((i, r));
            }
        }
    }
    Ok(out)
}

/// xᵀ A x for one column x.
fn strain_energy(a: &SparseColMat<usize, f64>, x: MatRef<'_, f64>) -> f64 {
    let (sym, val) = a.parts();
    let mut e = 0.0;
    for j in 0..a.ncols() {
        let xj = x[(j, 0)];
        for k in sym.col_range(j) {
            e += x[(sym.row_idx()[k], 0)] * val[k] * xj;
        }
    }
    e
}

impl super::reduced::ReducedModel {
    /// The reduced model on the Craig–Bampton basis of `cb`: its boundary and interior modes
    /// (M-orthonormalised together), then the residual vectors compressed to their principal
    /// directions ([`RESIDUAL_COMPRESSION`]): the static residual K₀⁻¹f, K₀⁻¹K_rK₀⁻¹f for
    /// every region whose factor differs from the plate's, the first-order residuals
    /// K₀⁻¹K_rφ of the selected boundary modes and the inertial residuals K₀⁻¹Mφ of the
    /// interior modes (the plate's quasi-static response to the forces a vibrating interior
    /// puts on its boundary).
    pub fn craig_bampton(sys: &FeSystem, cb: &CraigBamptonVectors) -> Result<Self, FrfError> {
        super::frf::validate_system(sys)?;
        let n = sys.n_free;
        let (nb, ni) = (
            cb.boundary_modes.shapes.ncols(),
            cb.interior_modes.shapes.ncols(),
        );
        let modes = Mat::from_fn(n, nb + ni, |row, col| {
            if col < nb {
                cb.boundary_modes.shapes[(row, col)]
            } else {
                cb.interior_modes.shapes[(row, col - nb)]
            }
        });
        let empty = Mat::<f64>::zeros(n, 0);
        let modes = super::reduced::m_orthonormalise_columns(
            &sys.mass,
            empty.as_ref(),
            empty.as_ref(),
            modes,
        )?;
        let llt = super::reduced::static_solver(sys)?;
        let f = Mat::from_fn(n, 1, |i, _| sys.force[i]);
        let mut statics = faer::linalg::solvers::Solve::solve(&*llt, f.as_ref());
        for &r in &super::reduced::perturbing_regions(sys) {
            let kr0 = spmm(&sys.stiffness_terms[r].matrix, statics.col(0).as_mat());
            let v = faer::linalg::solvers::Solve::solve(&*llt, kr0.as_ref());
            statics = concat(&statics, &v);
        }
        // boundary modes in the band: the interiors' quasi-static response to their inertia
        // (the part of the truncated fixed-interface modes Ψ leaves out)
        let in_band: Vec<usize> = (0..nb)
            .filter(|&i| cb.boundary_modes.frequencies_hz[i] <= cb.fmax_hz)
            .collect();
        let n_loads = cb.residual_modes.len() + ni + in_band.len();
        let mut loads = Mat::<f64>::zeros(n, n_loads);
        for (k, &i) in in_band.iter().enumerate() {
            let phi = cb.boundary_modes.shapes.col(i).as_mat();
            let mphi = spmm(&sys.mass, phi);
            loads
                .as_mut()
                .col_mut(cb.residual_modes.len() + ni + k)
                .copy_from(mphi.col(0));
        }
        for (at, &(i, r)) in cb.residual_modes.iter().enumerate() {
            let phi = cb.boundary_modes.shapes.col(i).as_mat();
            let kphi = spmm(&sys.stiffness_terms[r].matrix, phi);
            loads.as_mut().col_mut(at).copy_from(kphi.col(0));
        }
        let mphi = spmm(&sys.mass, cb.interior_modes.shapes.as_ref());
        loads
            .as_mut()
            .submatrix_mut(0, cb.residual_modes.len(), n, ni)
            .copy_from(&mphi);
        drop(mphi);
        faer::linalg::solvers::Solve::solve_in_place(&*llt, loads.as_mut());
        let orth = |basis: &Mat<f64>, m_basis: &Mat<f64>, cand: Mat<f64>| {
            super::reduced::m_orthonormalise_columns(
                &sys.mass,
                basis.as_ref(),
                m_basis.as_ref(),
                cand,
            )
        };
        let statics = orth(&modes, &spmm(&sys.mass, modes.as_ref()), statics)?;
        let modes = concat(&modes, &statics);
        let m_modes = spmm(&sys.mass, modes.as_ref());
        let compressed = compress(&sys.mass, &modes, &m_modes, loads)?;
        let extra = orth(&modes, &m_modes, compressed)?;
        Self::from_basis(sys, concat(&modes, &extra), nb + ni)
    }
}

/// The columns of `a` then those of `b`.
fn concat(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    Mat::from_fn(a.nrows(), a.ncols() + b.ncols(), |i, j| {
        if j < a.ncols() {
            a[(i, j)]
        } else {
            b[(i, j - a.ncols())]
        }
    })
}

/// The principal directions of the residual vectors `cand` outside the M-orthonormal `basis`
/// (`m_basis` = M × basis):
/// each projected out of the basis (twice), the parts below 1e-10 of their vector dropped as
/// dependent, the rest scaled to unit M-norm, and the directions of their Gram matrix with an
/// eigenvalue below [`RESIDUAL_COMPRESSION`] × the largest left out. Not orthonormal; the
/// caller orthonormalises.
fn compress(
    mass: &SparseColMat<usize, f64>,
    basis: &Mat<f64>,
    m_basis: &Mat<f64>,
    mut c: Mat<f64>,
) -> Result<Mat<f64>, FrfError> {
    let n = c.nrows();
    let m_norms = |c: &Mat<f64>| -> Vec<f64> {
        let mc = spmm(mass, c.as_ref());
        (0..c.ncols())
            .map(|j| {
                (0..n)
                    .map(|i| c[(i, j)] * mc[(i, j)])
                    .sum::<f64>()
                    .max(0.0)
                    .sqrt()
            })
            .collect()
    };
    let before = m_norms(&c);
    for _ in 0..2 {
        let p = m_basis.transpose() * &c;
        c -= basis * &p;
    }
    let after = m_norms(&c);
    let keep: Vec<usize> = (0..c.ncols())
        .filter(|&j| after[j] > 1e-10 * before[j] && after[j].is_finite())
        .collect();
    let c = Mat::from_fn(n, keep.len(), |i, k| c[(i, keep[k])] / after[keep[k]]);
    if c.ncols() == 0 {
        return Ok(c);
    }
    let (lam, u) = super::basis::gram_eigen(mass, &c)?;
    let largest = lam.iter().fold(0.0f64, |a, &l| a.max(l));
    let dirs: Vec<usize> = (0..lam.len())
        .filter(|&k| lam[k] > RESIDUAL_COMPRESSION * largest)
        .collect();
    let w = Mat::from_fn(c.ncols(), dirs.len(), |i, k| u[(i, dirs[k])]);
    Ok(&c * &w)
}

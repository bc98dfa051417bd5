//! M-orthonormal bases: the candidate vectors of a Ritz basis (modes, residual vectors) made
//! M-orthonormal, with numerically dependent directions dropped.

use faer::sparse::SparseColMat;
use faer::{Mat, MatRef, Side};

use super::frf::FrfError;
use super::reduced::spmm;

/// M-orthonormalises the columns of `cand` against `basis` (already M-orthonormal, with
/// `m_basis` = M × basis) and among themselves; drops columns that are numerically dependent.
///
/// Block form, all GEMMs: twice { C ← C − basis (m_basisᵀ C); SVQB: G = Cᵀ M C = U Λ Uᵀ,
/// C ← C U Λ^{−1/2} over the eigenvalues above 1e-14 }, the columns scaled to unit M-norm
/// first so that the threshold is relative to each candidate's size: "twice is enough".
pub(crate) fn m_orthonormalise(
    mass: &SparseColMat<usize, f64>,
    basis: MatRef<'_, f64>,
    m_basis: MatRef<'_, f64>,
    cand: Vec<Vec<f64>>,
) -> Result<Vec<Vec<f64>>, FrfError> {
    let n = basis.nrows();
    if cand.is_empty() {
        return Ok(Vec::new());
    }
    let c = Mat::from_fn(n, cand.len(), |i, j| cand[j][i]);
    drop(cand);
    let c = m_orthonormalise_columns(mass, basis, m_basis, c)?;
    Ok((0..c.ncols())
        .map(|j| c.col(j).iter().copied().collect())
        .collect())
}

/// [`m_orthonormalise`] on the columns of a matrix (no copy into vectors).
pub(crate) fn m_orthonormalise_columns(
    mass: &SparseColMat<usize, f64>,
    basis: MatRef<'_, f64>,
    m_basis: MatRef<'_, f64>,
    mut c: Mat<f64>,
) -> Result<Mat<f64>, FrfError> {
    let n = c.nrows();
    if c.ncols() == 0 {
        return Ok(c);
    }
    // scale each candidate to unit M-norm first so that the dependence threshold is relative
    for pass in 0..2 {
        if pass == 0 {
            let mc = spmm(mass, c.as_ref());
            for j in 0..c.ncols() {
                let nrm = (0..n)
                    .map(|i| c[(i, j)] * mc[(i, j)])
                    .sum::<f64>()
                    .max(0.0)
                    .sqrt();
                let inv = if nrm > 0.0 && nrm.is_finite() {
                    1.0 / nrm
                } else {
                    0.0
                };
                for i in 0..n {
                    c[(i, j)] *= inv;
                }
            }
        }
        if basis.ncols() > 0 {
            let p = m_basis.transpose() * &c;
            c -= basis * &p;
        }
        let (lam, u) = gram_eigen(mass, &c)?;
        // columns had unit M-norm before the projection: an absolute threshold is relative
        let keep: Vec<usize> = (0..lam.len()).filter(|&k| lam[k] > 1e-14).collect();
        let w = Mat::from_fn(c.ncols(), keep.len(), |i, k| {
            u[(i, keep[k])] / lam[keep[k]].sqrt()
        });
        c = &c * &w;
        if c.ncols() == 0 {
            break;
        }
    }
    Ok(c)
}

/// The eigen-decomposition of the Gram matrix CᵀMC of the columns of `c`: eigenvalues
/// (ascending) and eigenvectors (columns).
pub(crate) fn gram_eigen(
    mass: &SparseColMat<usize, f64>,
    c: &Mat<f64>,
) -> Result<(Vec<f64>, Mat<f64>), FrfError> {
    let g = c.transpose() * spmm(mass, c.as_ref());
    let evd = g
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| FrfError::Factorisation {
            what: "Gram matrix of the residual vectors".into(),
            message: format!("{e:?}"),
        })?;
    Ok((
        evd.S().column_vector().iter().copied().collect(),
        evd.U().to_owned(),
    ))
}

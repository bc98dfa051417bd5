//! Poles of one sub-band from all channels at once: a block-Hankel matrix of the (compressed)
//! channels, its SVD, and the shift invariance of the observability matrix (ERA/ESPRIT family,
//! METHODS.md §7), at every model order of the sweep.

use faer::linalg::solvers::SolveLstsq;
use faer::{c64, Mat, MatRef};

use super::baseband::Baseband;

/// One pole at one model order, with its shape in the compressed channel space.
#[derive(Clone, Debug)]
pub struct Pole {
    /// Model order it was found at.
    pub order: usize,
    /// Damped natural frequency, Hz (imaginary part of the pole over 2π).
    pub f_hz: f64,
    /// Damping ratio −Re λ / |λ|.
    pub damping_ratio: f64,
    /// The pole in the decimated z-plane relative to the heterodyne (for residue fits).
    pub z: c64,
    /// Shape over the compressed channels (unit norm).
    pub shape: Vec<c64>,
}

/// How the Hankel matrix is built.
#[derive(Clone, Copy, Debug)]
pub struct HankelPlan {
    /// Channels after compression (principal components of the sub-band's channels).
    pub compressed_channels: usize,
    /// Block rows (time shifts) of the Hankel matrix.
    pub block_rows: usize,
}

impl HankelPlan {
    /// A plan that supports orders up to `max_order` for `channels` channels: at most
    /// `max_compressed` components, and enough block rows that the shifted observability
    /// matrix has at least twice `max_order` rows.
    pub fn new(channels: usize, max_order: usize, max_compressed: usize) -> Self {
        let k = channels.min(max_compressed).max(1);
        let block_rows = (2 * max_order).div_ceil(k) + 1;
        HankelPlan {
            compressed_channels: k,
            block_rows: block_rows.max(2),
        }
    }

    /// Highest model order this plan supports.
    pub fn max_order(&self) -> usize {
        self.compressed_channels * (self.block_rows - 1)
    }
}

/// The compressed channels (k × samples): projection on the k leading left singular vectors.
pub fn compress(data: MatRef<'_, c64>, k: usize) -> Option<Mat<c64>> {
    // (A short record has fewer singular vectors than channels.)
    let k = k.min(data.ncols());
    if data.nrows() <= k {
        return Some(data.to_owned());
    }
    let svd = data.thin_svd().ok()?;
    let u = svd.U().get(.., ..k);
    Some(u.adjoint() * data)
}

/// Poles at every order in `orders` (ascending) from `y`, the band's channels compressed by
/// [`compress`], or `None` when the record is too short for the plan or a factorisation fails.
pub fn poles_by_order(
    band: &Baseband,
    y: MatRef<'_, c64>,
    plan: &HankelPlan,
    orders: std::ops::RangeInclusive<usize>,
) -> Option<Vec<Vec<Pole>>> {
    let (k, m) = (y.nrows(), y.ncols());
    let p = plan.block_rows;
    if m < 2 * p {
        return None;
    }
    let cols = m - p + 1;
    let hankel = Mat::<c64>::from_fn(k * p, cols, |r, j| y[(r % k, r / k + j)]);
    let svd = hankel.thin_svd().ok()?;
    let (u, s) = (svd.U(), svd.S().column_vector());
    let max_order = (*orders.end()).min(plan.max_order()).min(s.nrows());
    let mut out = Vec::new();
    for n in *orders.start()..=max_order {
        let gamma = Mat::<c64>::from_fn(k * p, n, |r, j| u[(r, j)] * s[j].re.sqrt());
        let up = gamma.get(..k * (p - 1), ..);
        let down = gamma.get(k.., ..);
        let a = up.qr().solve_lstsq(down);
        let Ok(evd) = a.eigen() else {
            out.push(Vec::new());
            continue;
        };
        let (vecs, vals) = (evd.U(), evd.S().column_vector());
        let c = gamma.get(..k, ..);
        let mut poles = Vec::with_capacity(n);
        for i in 0..n {
            let mu = vals[i];
            if mu.norm().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                continue;
            }
            let (f_hz, damping_ratio) = band.frequency_and_damping(mu);
            let shape_col = c * vecs.get(.., i);
            let norm = shape_col.norm_l2();
            if norm.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                continue;
            }
            poles.push(Pole {
                order: n,
                f_hz,
                damping_ratio,
                z: mu,
                shape: (0..k).map(|r| shape_col[r] / norm).collect(),
            });
        }
        out.push(poles);
    }
    Some(out)
}

/// Modal assurance criterion |aᴴb|² / (|a|²|b|²) of two complex shapes.
pub fn mac(a: &[c64], b: &[c64]) -> f64 {
    let mut dot = c64::new(0.0, 0.0);
    let (mut na, mut nb) = (0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        dot += x.conj() * y;
        na += x.norm_sqr();
        nb += y.norm_sqr();
    }
    if na > 0.0 && nb > 0.0 {
        dot.norm_sqr() / (na * nb)
    } else {
        0.0
    }
}

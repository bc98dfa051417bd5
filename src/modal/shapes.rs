//! Mode shapes from all channels: with the poles fixed, every channel's baseband signal is a
//! linear combination of the modes' exponentials, so one least-squares factorisation of the
//! Vandermonde matrix gives every channel's complex residues at once (LSFD in the time domain).

use faer::linalg::solvers::SolveLstsq;
use faer::{c64, Mat, MatRef};

/// Complex residues (modes × channels) of `data` (channels × samples) on the poles `z`
/// (decimated z-plane, sample 0 at the analysis start). `None` when the fit fails.
pub fn residues(data: MatRef<'_, c64>, z: &[c64]) -> Option<Mat<c64>> {
    let (m, n) = (data.nrows(), data.ncols());
    if z.is_empty() || n < z.len() {
        return None;
    }
    let mut v = Mat::<c64>::zeros(n, z.len());
    for (r, &zr) in z.iter().enumerate() {
        let mut p = c64::new(1.0, 0.0);
        for t in 0..n {
            v[(t, r)] = p;
            p *= zr;
        }
    }
    let rhs = Mat::<c64>::from_fn(n, m, |t, c| data[(c, t)]);
    let a = v.qr().solve_lstsq(rhs);
    let finite = (0..a.nrows())
        .all(|r| (0..a.ncols()).all(|c| a[(r, c)].re.is_finite() && a[(r, c)].im.is_finite()));
    finite.then_some(a)
}

/// A residue fit on all channels with its noise level and each mode's share of the signal.
pub struct ResidueFit {
    /// Complex residues, modes × channels.
    pub residues: Mat<c64>,
    /// Variance of the fit's residual per complex sample and channel.
    pub noise_variance: f64,
    /// Each mode's modal signal-to-noise ratio, dB: its energy over all channels and samples
    /// divided by the noise energy one free exponential per channel would absorb from noise
    /// alone (channels × `noise_variance`). A pole fitted to noise sits near 0 dB.
    pub modal_snr_db: Vec<f64>,
}

/// [`residues`] with the residual's variance and each mode's modal SNR.
pub fn fit_residues(data: MatRef<'_, c64>, z: &[c64]) -> Option<ResidueFit> {
    let a = residues(data, z)?;
    let (m, n) = (data.nrows(), data.ncols());
    let mut sum = 0.0;
    let mut powers = vec![c64::new(1.0, 0.0); z.len()];
    let mut energy_per_unit = vec![0.0; z.len()];
    for t in 0..n {
        for c in 0..m {
            let mut fit = c64::new(0.0, 0.0);
            for (r, p) in powers.iter().enumerate() {
                fit += a[(r, c)] * p;
            }
            sum += (data[(c, t)] - fit).norm_sqr();
        }
        for ((p, zr), e) in powers.iter_mut().zip(z).zip(&mut energy_per_unit) {
            *e += p.norm_sqr();
            *p *= zr;
        }
    }
    let dof = (m * n).saturating_sub(m * z.len()).max(1) as f64;
    let noise_variance = sum / dof;
    let modal_snr_db = (0..z.len())
        .map(|r| {
            let amp: f64 = (0..m).map(|c| a[(r, c)].norm_sqr()).sum();
            10.0 * (amp * energy_per_unit[r] / (m as f64 * noise_variance).max(1e-300)).log10()
        })
        .collect();
    Some(ResidueFit {
        residues: a,
        noise_variance,
        modal_snr_db,
    })
}

/// The shape scaled so that its largest component is 1 + 0j.
pub fn normalised(shape: &[c64]) -> Vec<c64> {
    let big = shape
        .iter()
        .copied()
        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
        .unwrap_or(c64::new(1.0, 0.0));
    if big.norm() == 0.0 {
        return shape.to_vec();
    }
    shape.iter().map(|x| x / big).collect()
}

/// Modal phase collinearity (1: all components in phase or in antiphase, a real normal mode;
/// 0: phases spread evenly): ((λ₁ − λ₂)/(λ₁ + λ₂))² of the 2 × 2 covariance of the real and
/// imaginary parts.
pub fn mpc(shape: &[c64]) -> f64 {
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for x in shape {
        sxx += x.re * x.re;
        syy += x.im * x.im;
        sxy += x.re * x.im;
    }
    let tr = sxx + syy;
    if tr <= 0.0 {
        return 0.0;
    }
    let disc = ((sxx - syy).powi(2) + 4.0 * sxy * sxy).sqrt();
    (disc / tr).powi(2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn residues_of_an_exact_sum_are_recovered() {
        let z = [c64::from_polar(0.99, 0.3), c64::from_polar(0.98, 0.35)];
        let a = [
            [c64::new(1.0, 0.5), c64::new(-2.0, 0.1)],
            [c64::new(0.3, 0.0), c64::new(0.0, 1.0)],
        ];
        let data = Mat::<c64>::from_fn(2, 200, |c, t| {
            a[c][0] * z[0].powu(t as u32) + a[c][1] * z[1].powu(t as u32)
        });
        let got = residues(data.as_ref(), &z).unwrap();
        for c in 0..2 {
            for r in 0..2 {
                assert!(
                    (got[(r, c)] - a[c][r]).norm() < 1e-9,
                    "{c} {r}: {}",
                    got[(r, c)]
                );
            }
        }
    }

    #[test]
    fn mpc_is_one_for_a_real_shape_and_zero_for_a_circular_one() {
        let real: Vec<c64> = [1.0, -0.5, 0.2]
            .iter()
            .map(|&v| c64::new(v, 0.0) * c64::from_polar(1.0, 0.7))
            .collect();
        assert!((mpc(&real) - 1.0).abs() < 1e-12);
        let circ: Vec<c64> = (0..4)
            .map(|k| c64::from_polar(1.0, k as f64 * std::f64::consts::FRAC_PI_2))
            .collect();
        assert!(mpc(&circ) < 1e-12);
    }
}

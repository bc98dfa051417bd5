//! Pole refinement by variable projection (Golub–Pereyra, METHODS.md §7): with the poles fixed,
//! the residues are linear (a least-squares solve); the poles alone are moved by
//! Levenberg–Marquardt to minimise the residual over all channels. The subspace poles are
//! within a few times the noise bound; this step takes them to the least-squares optimum, which
//! for white noise is the maximum-likelihood estimate.

use faer::{c64, MatRef};

use super::shapes::residues;

/// Most Levenberg–Marquardt iterations.
const MAX_ITERATIONS: usize = 30;
/// Relative decrease of the cost below which the iteration stops.
const TOLERANCE: f64 = 1e-10;

/// Residual (samples × channels, stacked real and imaginary) of the best fit of `y`
/// (channels × samples) with the poles `z`; `None` when the fit fails.
fn residual(y: MatRef<'_, c64>, z: &[c64]) -> Option<Vec<f64>> {
    let a = residues(y, z)?;
    let (k, m) = (y.nrows(), y.ncols());
    let mut out = Vec::with_capacity(2 * k * m);
    let mut powers: Vec<c64> = vec![c64::new(1.0, 0.0); z.len()];
    for t in 0..m {
        for c in 0..k {
            let mut fit = c64::new(0.0, 0.0);
            for (r, p) in powers.iter().enumerate() {
                fit += a[(r, c)] * p;
            }
            let e = y[(c, t)] - fit;
            out.push(e.re);
            out.push(e.im);
        }
        for (p, zr) in powers.iter_mut().zip(z) {
            *p *= zr;
        }
    }
    Some(out)
}

fn poles(params: &[f64]) -> Vec<c64> {
    params
        .chunks(2)
        .map(|p| c64::new(p[0], p[1]).exp())
        .collect()
}

fn cost(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Solves the small dense system `a x = b` (LU with partial pivoting); `None` when the result
/// is not finite (a singular system).
fn solve(a: &[Vec<f64>], b: &[f64]) -> Option<Vec<f64>> {
    use faer::linalg::solvers::Solve;
    let n = b.len();
    let m = faer::Mat::<f64>::from_fn(n, n, |i, j| a[i][j]);
    let rhs = faer::Mat::<f64>::from_fn(n, 1, |i, _| b[i]);
    let x = m.partial_piv_lu().solve(rhs);
    let x: Vec<f64> = (0..n).map(|i| x[(i, 0)]).collect();
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// How far a pole may move, in units of its own decay rate |Re ln z| (its half-power
/// half-bandwidth): a pole of damping D at f may move by ±D·f in frequency and to between 0 and
/// twice its damping. Within that, the subspace estimate is refined; beyond it the fit would be
/// chasing something else (an attenuated mode at the filter's edge, a neighbour's residual).
pub const TRUST_RADIUS_DECAY_RATES: f64 = 1.0;

/// Whether every pole of `params` stays within the trust radius of its start `start`.
fn within_trust(params: &[f64], start: &[f64]) -> bool {
    params.chunks(2).zip(start.chunks(2)).all(|(p, s)| {
        let r = TRUST_RADIUS_DECAY_RATES * s[0].abs();
        (p[0] - s[0]).hypot(p[1] - s[1]) <= r
    })
}

/// The poles `z0` moved to the least-squares optimum of the fit of `y` (channels × samples)
/// within each pole's trust radius ([`TRUST_RADIUS_DECAY_RATES`]); `z0` itself when the
/// refinement cannot improve it.
pub fn refine_poles(y: MatRef<'_, c64>, z0: &[c64]) -> Vec<c64> {
    let mut params: Vec<f64> = z0
        .iter()
        .flat_map(|z| {
            let l = z.ln();
            [l.re, l.im]
        })
        .collect();
    let start = params.clone();
    let Some(mut r) = residual(y, &poles(&params)) else {
        return z0.to_vec();
    };
    let mut c = cost(&r);
    let mut mu = 1e-3;
    let np = params.len();
    for _ in 0..MAX_ITERATIONS {
        // Forward-difference Jacobian of the projected residual.
        let mut jac: Vec<Vec<f64>> = Vec::with_capacity(np);
        for i in 0..np {
            let h = 1e-7 * params[i].abs().max(1e-3);
            let mut p = params.clone();
            p[i] += h;
            let Some(ri) = residual(y, &poles(&p)) else {
                return poles(&params);
            };
            jac.push(ri.iter().zip(&r).map(|(a, b)| (a - b) / h).collect());
        }
        let jtj: Vec<Vec<f64>> = (0..np)
            .map(|i| {
                (0..np)
                    .map(|j| jac[i].iter().zip(&jac[j]).map(|(a, b)| a * b).sum())
                    .collect()
            })
            .collect();
        let jtr: Vec<f64> = (0..np)
            .map(|i| -jac[i].iter().zip(&r).map(|(a, b)| a * b).sum::<f64>())
            .collect();
        let mut improved = false;
        for _ in 0..8 {
            let mut a = jtj.clone();
            for (i, row) in a.iter_mut().enumerate() {
                row[i] += mu * jtj[i][i].max(1e-30);
            }
            let Some(step) = solve(&a, &jtr) else {
                mu *= 4.0;
                continue;
            };
            let trial: Vec<f64> = params.iter().zip(&step).map(|(p, s)| p + s).collect();
            if !within_trust(&trial, &start) {
                mu *= 4.0;
                continue;
            }
            match residual(y, &poles(&trial)) {
                Some(rt) if cost(&rt) < c => {
                    let rel = (c - cost(&rt)) / c;
                    params = trial;
                    c = cost(&rt);
                    r = rt;
                    mu = (mu / 3.0).max(1e-12);
                    improved = rel > TOLERANCE;
                    break;
                }
                _ => mu *= 4.0,
            }
        }
        if !improved {
            break;
        }
    }
    poles(&params)
}

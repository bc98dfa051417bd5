//! What an STFT band receives from a decaying mode: Σ_k w_k (|H(θ_k − ω)|² + |H(θ_k + ω)|²) over
//! the band's bins k, H the DTFT of the periodic Hann window of n samples times e^{−a m}
//! (a mode of angular frequency ω rad/sample decaying at a per sample, seen through one frame).
//!
//! H(φ) = 0.5 S(φ) − 0.25 S(φ − 2π/n) − 0.25 S(φ + 2π/n) with the geometric sum
//! S(φ) = Σ_{m<n} e^{(−a−jφ) m} = (1 − e^{−an} e^{−jφn}) / (1 − e^{−a} e^{−jφ}).
//!
//! Evaluated directly ([`hann_dtft`]) that is nine complex exponentials per bin, and the leakage
//! test asks for it hundreds of times per decay over bands of hundreds of bins. The three sums
//! share their numerator N(φ) = 1 − e^{−an} e^{−jφn} (a shift by 2π/n turns e^{−jφn} by 2π), and
//! with u = e^{−a} e^{−jφ}, c = e^{j2π/n} the sum of the three fractions is one fraction:
//!
//! H(φ) = N(φ) · u (1 − cos(2π/n)) (1 + u) / (2 (1 − u)(1 − uc)(1 − u/c)),
//!
//! so |H|² is a product of squared magnitudes |1 − r e^{−jθ}|² = (1 − r)² + 4 r sin²(θ/2), each
//! from half-angle sines without cancellation. [`band_mode_gain`] steps those sines from bin to
//! bin by one fixed rotation, restarting from exact values every [`RESYNC_BINS`] bins so that no
//! rounding accumulates: per bin a few real products and one division (three complex divisions
//! before, 5 % of a 48 kHz STFT run).

use rustfft::num_complex::Complex;

/// Bins between exact evaluations of the per-bin phasors.
const RESYNC_BINS: usize = 32;

/// |1 − e^{−a} e^{−jφ}|² below this: S is its limit n (the mode sits on the bin, undamped).
const DEGENERATE_DEN_SQR: f64 = 1e-24;

/// Σ_{m<n} e^{c m} = (1 − e^{cn}) / (1 − e^c) (n when c → 0): the direct evaluation.
#[cfg(test)]
fn geometric_sum(c: Complex<f64>, n: f64) -> Complex<f64> {
    let den = Complex::new(1.0, 0.0) - c.exp();
    if den.norm_sqr() < DEGENERATE_DEN_SQR {
        Complex::new(n, 0.0)
    } else {
        (Complex::new(1.0, 0.0) - (c * n).exp()) / den
    }
}

/// DTFT at φ (rad/sample) of the periodic Hann window of length `n` times e^{−a m}: the direct
/// evaluation, the oracle of [`band_mode_gain`].
#[cfg(test)]
fn hann_dtft(phi: f64, a: f64, n: f64) -> Complex<f64> {
    let step = 2.0 * std::f64::consts::PI / n;
    let s = |t: f64| geometric_sum(Complex::new(-a, -t), n);
    0.5 * s(phi) - 0.25 * s(phi - step) - 0.25 * s(phi + step)
}

/// The band's gain, directly: the slow and obviously correct sum.
#[cfg(test)]
fn band_mode_gain_direct(
    first_bin: usize,
    weights: &[f64],
    bin_rad: f64,
    n: usize,
    a: f64,
    omega: f64,
) -> f64 {
    let n = n as f64;
    weights
        .iter()
        .enumerate()
        .filter(|(_, wt)| **wt > 0.0)
        .map(|(i, wt)| {
            let theta = (first_bin + i) as f64 * bin_rad;
            wt * (hann_dtft(theta - omega, a, n).norm_sqr()
                + hann_dtft(theta + omega, a, n).norm_sqr())
        })
        .sum()
}

/// Σ over the band's bins of w (|H(θ − ω)|² + |H(θ + ω)|²), θ = bin · `bin_rad`, for a window of
/// `n` samples and a decay of `a` per sample (see the module docs).
pub(super) fn band_mode_gain(
    first_bin: usize,
    weights: &[f64],
    bin_rad: f64,
    n: usize,
    a: f64,
    omega: f64,
) -> f64 {
    [-omega, omega]
        .iter()
        .map(|&shift| image_gain(first_bin, weights, bin_rad, n, a, shift))
        .sum()
}

/// Σ_k w_k |H(k · bin_rad + shift)|², from the closed form of the module docs: per bin a few
/// real products of half-angle sines and one division. A bin where a denominator vanishes
/// (an undamped mode on the bin or on its neighbour's Hann zero) takes the limit instead
/// ([`degenerate_bin_sqr`]).
fn image_gain(
    first_bin: usize,
    weights: &[f64],
    bin_rad: f64,
    n: usize,
    a: f64,
    shift: f64,
) -> f64 {
    let nf = n as f64;
    let r = (-a).exp();
    let r_n = (-a * nf).exp();
    // (1 − r)² and (1 − rⁿ)² without cancellation for small a.
    let one_minus_r_sqr = (-a).exp_m1().powi(2);
    let one_minus_rn_sqr = (-a * nf).exp_m1().powi(2);
    let step = 2.0 * std::f64::consts::PI / nf;
    let (half_step_sin, half_step_cos) = (0.5 * step).sin_cos();
    // r² sin⁴(s/2) = r² (1 − cos s)² / 4: the numerator's constant.
    let constant = r * r * half_step_sin.powi(4);
    // Per bin, φ/2 and nφ/2 advance by these angles.
    let (bin_sin, bin_cos) = (0.5 * bin_rad).sin_cos();
    let (bin_n_sin, bin_n_cos) = (0.5 * bin_rad * nf).sin_cos();
    // |1 − r e^{−jθ}|² = (1 − r)² + 4 r sin²(θ/2).
    let den = |half_sin: f64| one_minus_r_sqr + 4.0 * r * half_sin * half_sin;
    let mut total = 0.0;
    let (mut sin_half, mut cos_half) = (0.0, 1.0);
    let (mut sin_half_n, mut cos_half_n) = (0.0, 1.0);
    for (i, &wt) in weights.iter().enumerate() {
        if i % RESYNC_BINS == 0 {
            let phi = (first_bin + i) as f64 * bin_rad + shift;
            (sin_half, cos_half) = (0.5 * phi).sin_cos();
            (sin_half_n, cos_half_n) = (0.5 * phi * nf).sin_cos();
        } else {
            (sin_half, cos_half) = (
                sin_half * bin_cos + cos_half * bin_sin,
                cos_half * bin_cos - sin_half * bin_sin,
            );
            (sin_half_n, cos_half_n) = (
                sin_half_n * bin_n_cos + cos_half_n * bin_n_sin,
                cos_half_n * bin_n_cos - sin_half_n * bin_n_sin,
            );
        }
        if wt <= 0.0 {
            continue;
        }
        // Half angles of φ − s and φ + s (the Hann window's two shifted kernels).
        let sin_below = sin_half * half_step_cos - cos_half * half_step_sin;
        let sin_above = sin_half * half_step_cos + cos_half * half_step_sin;
        let (d0, d1, d2) = (den(sin_half), den(sin_below), den(sin_above));
        let h_sqr = if d0.min(d1).min(d2) < DEGENERATE_DEN_SQR {
            let phi = (first_bin + i) as f64 * bin_rad + shift;
            degenerate_bin_sqr(phi, r, r_n, nf, step)
        } else {
            // |N|² = |1 − rⁿ e^{−jnφ}|² and |1 + r e^{−jφ}|² = (1 − r)² + 4 r cos²(φ/2).
            let numerator = (one_minus_rn_sqr + 4.0 * r_n * sin_half_n * sin_half_n)
                * constant
                * (one_minus_r_sqr + 4.0 * r * cos_half * cos_half);
            numerator / (d0 * d1 * d2)
        };
        total += wt * h_sqr;
    }
    total
}

/// |H(φ)|² where one of the three geometric sums' denominators vanishes: each sum evaluated
/// on its own, a vanishing one replaced by its limit n.
fn degenerate_bin_sqr(phi: f64, r: f64, r_n: f64, nf: f64, step: f64) -> f64 {
    let one = Complex::new(1.0, 0.0);
    let numerator = one - r_n * Complex::from_polar(1.0, -phi * nf);
    let sum = |theta: f64| {
        let den = one - r * Complex::from_polar(1.0, -theta);
        if den.norm_sqr() < DEGENERATE_DEN_SQR {
            Complex::new(nf, 0.0)
        } else {
            numerator / den
        }
    };
    (0.5 * sum(phi) - 0.25 * sum(phi - step) - 0.25 * sum(phi + step)).norm_sqr()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the direct sum over bands at the bottom, middle and top of the spectrum, with
    /// and without zero padding, for tones on, between and far from the bins, undamped and
    /// strongly damped.
    #[test]
    fn fast_gain_matches_the_direct_sum() {
        for (n, zero_pad) in [(819usize, 1usize), (800, 1), (9600, 1), (200, 4)] {
            let nfft = n * zero_pad;
            let bin_rad = 2.0 * std::f64::consts::PI / nfft as f64;
            for first_bin in [0usize, 3, nfft / 4, nfft / 2 - 150] {
                let weights: Vec<f64> = (0..150)
                    .map(|i| {
                        if i == 0 {
                            0.5
                        } else if i == 149 {
                            0.25
                        } else {
                            1.0
                        }
                    })
                    .collect();
                for omega_bins in [0.0, 2.0, 7.5, 40.25, 75.0, (nfft / 3) as f64] {
                    let omega = (first_bin as f64 + omega_bins) * bin_rad;
                    for a in [0.0, 1e-5, 3e-3] {
                        let want = band_mode_gain_direct(first_bin, &weights, bin_rad, n, a, omega);
                        let got = band_mode_gain(first_bin, &weights, bin_rad, n, a, omega);
                        assert!(
                            (got - want).abs() <= 1e-9 * want.abs() + 1e-12 * (n * n) as f64,
                            "n {n} pad {zero_pad} bin {first_bin} ω {omega_bins} a {a}: {got} vs {want}"
                        );
                    }
                }
            }
        }
    }
}

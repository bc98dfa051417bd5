//! What an STFT band receives from a decaying mode: Σ_k w_k (|H(θ_k − ω)|² + |H(θ_k + ω)|²) over
//! the band's bins k, H the DTFT of the periodic Hann window of n samples times e^{−a m}
//! (a mode of angular frequency ω rad/sample decaying at a per sample, seen through one frame).
//!
//! H(φ) = 0.5 S(φ) − 0.25 S(φ − 2π/n) − 0.25 S(φ + 2π/n) with the geometric sum
//! S(φ) = Σ_{m<n} e^{(−a−jφ) m} = (1 − e^{−an} e^{−jφn}) / (1 − e^{−a} e^{−jφ}).
//!
//! Evaluated directly ([`hann_dtft`]) that is nine complex exponentials per bin, and the leakage
//! test asks for it hundreds of times per decay over bands of hundreds of bins: it was half of
//! the whole analysis' time. [`band_mode_gain`] uses that the three sums share their numerator
//! (a shift by 2π/n turns e^{−jφn} by 2π) and that successive bins differ by one fixed rotation,
//! so a bin costs a few complex multiplications and three divisions; the rotations restart
//! from exact values every [`RESYNC_BINS`] bins so that no rounding accumulates.

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

/// Σ_k w_k |H(k · bin_rad + shift)|².
fn image_gain(
    first_bin: usize,
    weights: &[f64],
    bin_rad: f64,
    n: usize,
    a: f64,
    shift: f64,
) -> f64 {
    let nf = n as f64;
    let one = Complex::new(1.0, 0.0);
    let decay = (-a).exp();
    let decay_n = (-a * nf).exp();
    let step = 2.0 * std::f64::consts::PI / nf;
    // e^{∓j step}: S(φ ∓ step) has e^{−j(φ∓step)} = e^{−jφ} e^{±j step} in its denominator.
    let (turn_up, turn_down) = (
        Complex::from_polar(1.0, step),
        Complex::from_polar(1.0, -step),
    );
    let bin_turn = Complex::from_polar(1.0, -bin_rad);
    let bin_turn_n = Complex::from_polar(1.0, -bin_rad * nf);
    let mut total = 0.0;
    let (mut rot, mut rot_n) = (one, one);
    for (i, &wt) in weights.iter().enumerate() {
        if i % RESYNC_BINS == 0 {
            let phi = (first_bin + i) as f64 * bin_rad + shift;
            rot = Complex::from_polar(1.0, -phi);
            rot_n = Complex::from_polar(1.0, -phi * nf);
        } else {
            rot *= bin_turn;
            rot_n *= bin_turn_n;
        }
        if wt <= 0.0 {
            continue;
        }
        let numerator = one - decay_n * rot_n;
        let sum = |r: Complex<f64>| {
            let den = one - decay * r;
            if den.norm_sqr() < DEGENERATE_DEN_SQR {
                Complex::new(nf, 0.0)
            } else {
                numerator / den
            }
        };
        let h = 0.5 * sum(rot) - 0.25 * sum(rot * turn_up) - 0.25 * sum(rot * turn_down);
        total += wt * h.norm_sqr();
    }
    total
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

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

use super::simd::Isa;

#[path = "hann_gain_lanes.rs"]
mod lanes;

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

/// The spectrum a band's bins lie on: bins `bin_rad` apart (rad/sample), of a Hann window of
/// `window_len` samples; with the sines and cosines every band sum on it starts from, found once
/// (three per sum were most of a narrow band's cost).
#[derive(Clone, Copy, Debug)]
pub(super) struct HannGrid {
    bin_rad: f64,
    window_len: usize,
    /// The Hann kernel's step 2π/n, rad/sample.
    step: f64,
    /// (sin, cos) of half a bin, of n times that, and of half the step.
    half_bin: (f64, f64),
    half_bin_n: (f64, f64),
    half_step: (f64, f64),
}

impl HannGrid {
    /// Bins `bin_rad` apart (rad/sample) of a Hann window of `window_len` samples.
    pub(super) fn new(bin_rad: f64, window_len: usize) -> Self {
        let nf = window_len as f64;
        let step = 2.0 * std::f64::consts::PI / nf;
        HannGrid {
            bin_rad,
            window_len,
            step,
            half_bin: (0.5 * bin_rad).sin_cos(),
            half_bin_n: (0.5 * bin_rad * nf).sin_cos(),
            half_step: (0.5 * step).sin_cos(),
        }
    }
}

/// Σ over the band's bins of w (|H(θ − ω)|² + |H(θ + ω)|²), θ = bin · `grid.bin_rad`, bins from
/// `first_bin` on, for a decay of `a` per sample (see the module docs).
pub(super) fn band_mode_gain(
    isa: Isa,
    grid: &HannGrid,
    first_bin: usize,
    weights: &[f64],
    a: f64,
    omega: f64,
) -> f64 {
    [-omega, omega]
        .iter()
        .map(|&shift| image_gain(isa, grid, first_bin, weights, a, shift))
        .sum()
}

/// What the closed form needs of a Hann window of `n` samples and a decay of `a` per sample.
struct DecayingHann {
    nf: f64,
    r: f64,
    r_n: f64,
    /// (1 − r)² and (1 − rⁿ)², without cancellation for small a.
    one_minus_r_sqr: f64,
    one_minus_rn_sqr: f64,
    /// s = 2π/n, and sin, cos of s/2.
    step: f64,
    half_step_sin: f64,
    half_step_cos: f64,
}

impl DecayingHann {
    fn new(grid: &HannGrid, a: f64) -> Self {
        let (nf, step) = (grid.window_len as f64, grid.step);
        let (half_step_sin, half_step_cos) = grid.half_step;
        DecayingHann {
            nf,
            r: (-a).exp(),
            r_n: (-a * nf).exp(),
            one_minus_r_sqr: (-a).exp_m1().powi(2),
            one_minus_rn_sqr: (-a * nf).exp_m1().powi(2),
            step,
            half_step_sin,
            half_step_cos,
        }
    }

    /// (1 − r)² + 4 r h²: with h = sin(θ/2), |1 − r e^{−jθ}|²; with h = cos(φ/2), |1 + r e^{−jφ}|².
    fn sqr(&self, h: f64) -> f64 {
        self.one_minus_r_sqr + 4.0 * self.r * h * h
    }

    /// r² sin⁴(s/2) = r² (1 − cos s)² / 4: the numerator's constant.
    fn constant(&self) -> f64 {
        self.r * self.r * self.half_step_sin.powi(4)
    }
}

/// Σ_k w_k |H(k · bin_rad + shift)|², from the closed form of the module docs: per bin a few
/// real products of half-angle sines and one division, several bins at a time where the CPU
/// has vector lanes ([`lanes`]). A bin where a denominator vanishes (an undamped mode on the
/// bin or on its neighbour's Hann zero) takes the limit instead ([`degenerate_bin_sqr`]).
fn image_gain(
    isa: Isa,
    grid: &HannGrid,
    first_bin: usize,
    weights: &[f64],
    a: f64,
    shift: f64,
) -> f64 {
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `isa` was detected on this CPU (AVX-512F with AVX2 and FMA).
        Isa::Avx512 => unsafe { lanes::image_gain_avx512(grid, first_bin, weights, a, shift) },
        _ => image_gain_scalar(grid, first_bin, weights, a, shift),
    }
}

/// [`image_gain`] one bin at a time.
fn image_gain_scalar(
    grid: &HannGrid,
    first_bin: usize,
    weights: &[f64],
    a: f64,
    shift: f64,
) -> f64 {
    let bin_rad = grid.bin_rad;
    let k = DecayingHann::new(grid, a);
    let (nf, r_n) = (k.nf, k.r_n);
    let (half_step_sin, half_step_cos) = (k.half_step_sin, k.half_step_cos);
    let constant = k.constant();
    // Per bin, φ/2 and nφ/2 advance by these angles.
    let ((bin_sin, bin_cos), (bin_n_sin, bin_n_cos)) = (grid.half_bin, grid.half_bin_n);
    let den = |half_sin: f64| k.sqr(half_sin);
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
            degenerate_bin_sqr(phi, &k)
        } else {
            // |N|² = |1 − rⁿ e^{−jnφ}|² and |1 + r e^{−jφ}|² = (1 − r)² + 4 r cos²(φ/2).
            let numerator = (k.one_minus_rn_sqr + 4.0 * r_n * sin_half_n * sin_half_n)
                * constant
                * k.sqr(cos_half);
            numerator / (d0 * d1 * d2)
        };
        total += wt * h_sqr;
    }
    total
}

/// An upper bound of [`band_mode_gain`] at a small fraction of its cost, for the leakage test:
/// a weak band that stands clear of what the strong bands could at most leak into it needs no
/// exact sum. `cumulative[i]` = Σ_{j<i} `weights[j]` (length `weights.len() + 1`).
///
/// Why it holds: |H(φ)|² = |N|² r² sin⁴(s/2) |1 + u|² / (|1 − u|² |1 − uc|² |1 − u/c|²) with
/// |N| ≤ 1 + rⁿ, and on s ≤ |φ| ≤ π − s (φ reduced to (−π, π], s = 2π/n) every factor of the
/// denominator grows with |φ| and |1 + u|² shrinks: |H|² falls off monotonically away from the
/// tone. So the bins are taken in runs of doubling length from the edge nearest the tone, each
/// run bounded by its weight times the bound at its nearest bin. Where an image's bins come
/// within s of the tone or of π, that image's exact sum is taken instead.
pub(super) fn band_mode_gain_bound(
    isa: Isa,
    grid: &HannGrid,
    first_bin: usize,
    weights: &[f64],
    cumulative: &[f64],
    a: f64,
    omega: f64,
) -> f64 {
    debug_assert_eq!(cumulative.len(), weights.len() + 1);
    [-omega, omega]
        .iter()
        .map(|&shift| {
            image_gain_bound(grid, first_bin, weights, cumulative, a, shift)
                .unwrap_or_else(|| image_gain(isa, grid, first_bin, weights, a, shift))
        })
        .sum()
}

/// Relative margin added to a bound for the rounding of both it and the exact sum.
const BOUND_ROUNDING: f64 = 1e-6;

/// The bound of one image, or `None` where the monotone fall-off does not cover its bins.
fn image_gain_bound(
    grid: &HannGrid,
    first_bin: usize,
    weights: &[f64],
    cumulative: &[f64],
    a: f64,
    shift: f64,
) -> Option<f64> {
    let bin_rad = grid.bin_rad;
    use std::f64::consts::{PI, TAU};
    let len = weights.len();
    if len == 0 {
        return Some(0.0);
    }
    let k = DecayingHann::new(grid, a);
    let step = k.step;
    // The bins' angles, reduced so that the first lies in (−π, π].
    let first = (first_bin as f64 * bin_rad + shift).rem_euclid(TAU);
    let first = if first > PI { first - TAU } else { first };
    let last = first + (len - 1) as f64 * bin_rad;
    // Which end is nearest the tone, and |φ| of bin i.
    let rising = first >= step && last <= PI - step;
    let falling = first >= -(PI - step) && last <= -step;
    if !(rising || falling) {
        return None;
    }
    let distance = |i: usize| (first + i as f64 * bin_rad).abs();
    // |N|² ≤ (1 + rⁿ)².
    let constant = (1.0 + k.r_n).powi(2) * k.constant();
    let den = |theta: f64| k.sqr((0.5 * theta).sin());
    let at = |phi: f64| {
        constant * k.sqr((0.5 * phi).cos()) / (den(phi) * den(phi - step) * den(phi + step))
    };
    // Runs of 1, 1, 2, 4, … bins from the near end.
    let mut total = 0.0;
    let (mut done, mut run) = (0usize, 1usize);
    while done < len {
        let take = run.min(len - done);
        let (lo, hi, nearest) = if rising {
            (done, done + take, done)
        } else {
            (len - done - take, len - done, len - done - 1)
        };
        let weight = cumulative[hi] - cumulative[lo];
        if weight > 0.0 {
            total += weight * at(distance(nearest));
        }
        done += take;
        if done > 1 {
            run *= 2;
        }
    }
    Some(total * (1.0 + BOUND_ROUNDING))
}

/// |H(φ)|² where one of the three geometric sums' denominators vanishes: each sum evaluated
/// on its own, a vanishing one replaced by its limit n.
fn degenerate_bin_sqr(phi: f64, k: &DecayingHann) -> f64 {
    let (r, r_n, nf, step) = (k.r, k.r_n, k.nf, k.step);
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
                        for isa in Isa::available() {
                            let grid = HannGrid::new(bin_rad, n);
                            let got = band_mode_gain(isa, &grid, first_bin, &weights, a, omega);
                            assert!(
                                (got - want).abs() <= 1e-9 * want.abs() + 1e-12 * (n * n) as f64,
                                "{isa:?} n {n} pad {zero_pad} bin {first_bin} ω {omega_bins} a {a}: {got} vs {want}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// The bound is never below the exact sum (tones on, near and far from the band, both
    /// images, damped and not, with zero padding), and for a tone ≥ 12 bins off the band and
    /// between bins it is within 20 dB of it: tight enough to spare the exact sums.
    #[test]
    fn gain_bound_is_above_the_exact_sum_and_close_far_away() {
        let mut far_checked = 0;
        for (n, zero_pad) in [(819usize, 1usize), (9600, 1), (200, 4)] {
            let nfft = n * zero_pad;
            let bin_rad = 2.0 * std::f64::consts::PI / nfft as f64;
            for (first_bin, len) in [
                (0usize, 10usize),
                (5, 40),
                (nfft / 8, nfft / 8),
                (nfft / 4, 300.min(nfft / 4)),
            ] {
                let weights: Vec<f64> = (0..len)
                    .map(|i| {
                        if i == 0 {
                            0.0
                        } else if i == len - 1 {
                            0.3
                        } else {
                            1.0
                        }
                    })
                    .collect();
                let mut cumulative = vec![0.0];
                for w in &weights {
                    cumulative.push(cumulative.last().unwrap() + w);
                }
                for tone_bin in [
                    0.0,
                    1.5,
                    3.0,
                    12.25,
                    47.0,
                    47.5,
                    160.5,
                    (nfft / 2) as f64 - 2.0,
                ] {
                    for offset in [-1.0, 1.0] {
                        let bin = first_bin as f64
                            + if offset < 0.0 {
                                -tone_bin
                            } else {
                                len as f64 + tone_bin
                            };
                        if !(0.0..=(nfft / 2) as f64).contains(&bin) {
                            continue;
                        }
                        let omega = bin * bin_rad;
                        for a in [0.0, 1e-5, 3e-3] {
                            let (isa, grid) = (Isa::detect(), HannGrid::new(bin_rad, n));
                            let exact = band_mode_gain(isa, &grid, first_bin, &weights, a, omega);
                            let bound = band_mode_gain_bound(
                                isa,
                                &grid,
                                first_bin,
                                &weights,
                                &cumulative,
                                a,
                                omega,
                            );
                            assert!(bound >= exact, "n {n} pad {zero_pad} band {first_bin}+{len} tone {bin} a {a}: {bound} < {exact}");
                            // Off the bin grid (on it, an undamped tone's N vanishes on every bin).
                            if tone_bin >= 12.0 && tone_bin.fract() != 0.0 && a == 0.0 {
                                assert!(
                                    bound <= 100.0 * exact,
                                    "n {n} band {first_bin}+{len} tone {bin}: {bound} vs {exact}"
                                );
                                far_checked += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(far_checked > 20, "{far_checked}");
    }
}

//! The per-frame loops of the STFT, each compiled for the instruction set found at run time:
//! window, power spectrum, and one band's energy and strongest bin.

use rustfft::num_complex::Complex;

use crate::frontend::simd::Isa;

/// `dst[..x.len()] = x · window`, the rest of `dst` zero (the zero padding).
pub(super) fn window_and_zero_pad(isa: Isa, dst: &mut [f64], x: &[f64], window: &[f64]) {
    #[inline(always)]
    fn run(dst: &mut [f64], x: &[f64], window: &[f64]) {
        let (head, tail) = dst.split_at_mut(x.len());
        for ((d, &x), &w) in head.iter_mut().zip(x).zip(window) {
            *d = x * w;
        }
        tail.iter_mut().for_each(|v| *v = 0.0);
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(dst: &mut [f64], x: &[f64], window: &[f64]) {
        run(dst, x, window)
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU (separate multiplies: same results).
        Isa::Avx2Fma | Isa::Avx512 => unsafe { run_avx2(dst, x, window) },
        Isa::Generic => run(dst, x, window),
    }
}

/// `power[k] = |spectrum[k]|²`.
pub(super) fn power_spectrum(isa: Isa, power: &mut [f64], spectrum: &[Complex<f64>]) {
    #[inline(always)]
    fn run(power: &mut [f64], spectrum: &[Complex<f64>]) {
        for (p, c) in power.iter_mut().zip(spectrum) {
            *p = c.re * c.re + c.im * c.im;
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(power: &mut [f64], spectrum: &[Complex<f64>]) {
        run(power, spectrum)
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU (no fused operations: same results).
        Isa::Avx2Fma | Isa::Avx512 => unsafe { run_avx2(power, spectrum) },
        Isa::Generic => run(power, spectrum),
    }
}

/// `dst[n] = (a[n] + j b[n]) · window[n]` for n < a.len(), zero beyond: two real frames packed
/// into one complex FFT input.
pub(super) fn window_pair(dst: &mut [Complex<f64>], a: &[f64], b: &[f64], window: &[f64]) {
    let (head, tail) = dst.split_at_mut(a.len());
    for (((d, &x), &y), &w) in head.iter_mut().zip(a).zip(b).zip(window) {
        *d = Complex::new(x * w, y * w);
    }
    tail.iter_mut().for_each(|v| *v = Complex::new(0.0, 0.0));
}

/// Bins per step of the unpacking loops below (their fixed-size lane arrays become vectors).
const UNPACK_LANES: usize = 4;

/// The real and imaginary parts of z[k..k+4] and of their mirror images z[n−k], z[n−k−1],
/// z[n−k−2], z[n−k−3] (`zp` points at z as interleaved f64), each in lanes ordered
/// k, k+2, k+1, k+3 (the order the unpacks give): `[a_re, a_im, b_re, b_im]`.
///
/// # Safety
/// AVX2 must be present, and z[k..k+4] and z[n−k−3..=n−k] must lie in z.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn load_mirrored(zp: *const f64, k: usize, n: usize) -> [std::arch::x86_64::__m256d; 4] {
    use std::arch::x86_64::*;
    let a01 = _mm256_loadu_pd(zp.add(2 * k));
    let a23 = _mm256_loadu_pd(zp.add(2 * k + 4));
    // z[n−k−3], z[n−k−2] and z[n−k−1], z[n−k]; halves swapped to n−k, n−k−1 … first.
    let b_lo = _mm256_loadu_pd(zp.add(2 * (n - k - 3)));
    let b_hi = _mm256_loadu_pd(zp.add(2 * (n - k - 1)));
    let (b_hi, b_lo) = (
        _mm256_permute2f128_pd::<1>(b_hi, b_hi),
        _mm256_permute2f128_pd::<1>(b_lo, b_lo),
    );
    [
        _mm256_unpacklo_pd(a01, a23),
        _mm256_unpackhi_pd(a01, a23),
        _mm256_unpacklo_pd(b_hi, b_lo),
        _mm256_unpackhi_pd(b_hi, b_lo),
    ]
}

/// The power spectra of two real frames from the DFT `z` of `a + j b` (length N):
/// A[k] = (Z[k] + conj Z[N−k]) / 2 and B[k] = (Z[k] − conj Z[N−k]) / 2j, for the bins
/// k < `power_a.len()` (≤ N/2 + 1). Bin 0 pairs with itself; the others run in lanes.
pub(super) fn unpack_pair_powers(
    isa: Isa,
    z: &[Complex<f64>],
    power_a: &mut [f64],
    power_b: &mut [f64],
) {
    #[inline(always)]
    fn bin(zk: Complex<f64>, zn: Complex<f64>) -> (f64, f64) {
        let zc = zn.conj();
        (0.25 * (zk + zc).norm_sqr(), 0.25 * (zk - zc).norm_sqr())
    }
    /// Bin 0 and the bins from `from` on.
    #[inline(always)]
    fn run(z: &[Complex<f64>], power_a: &mut [f64], power_b: &mut [f64], from: usize) {
        let (n, bins) = (z.len(), power_a.len().min(power_b.len()));
        if bins == 0 || n == 0 {
            return;
        }
        (power_a[0], power_b[0]) = bin(z[0], z[0]);
        for k in from.max(1)..bins {
            (power_a[k], power_b[k]) = bin(z[k], z[n - k]);
        }
    }
    /// [`run`] with four bins per step in AVX2 registers: the same IEEE operations per lane
    /// (x + (−y) is x − y), none fused, so the same bits.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(z: &[Complex<f64>], power_a: &mut [f64], power_b: &mut [f64]) {
        use std::arch::x86_64::*;
        let (n, bins) = (z.len(), power_a.len().min(power_b.len()));
        if bins > n / 2 + 1 {
            return run(z, power_a, power_b, 1);
        }
        // Steps over k = 1.. while k + 3 < bins.
        let steps = bins.saturating_sub(1) / UNPACK_LANES;
        let zp = z.as_ptr() as *const f64;
        let quarter = _mm256_set1_pd(0.25);
        for step in 0..steps {
            let k = 1 + step * UNPACK_LANES;
            // SAFETY: k + 3 < bins ≤ N/2 + 1, so z[k..k+4] and z[N−k−3..=N−k] lie in z (N−k−3
            // ≥ N − N/2 ≥ 0 as k + 3 ≤ N/2) and the stores in power_a, power_b. Lanes
            // hold bins k, k+2, k+1, k+3 (the unpacks' order).
            let [a_re, a_im, b_re, b_im] = load_mirrored(zp, k, n);
            let (s_re, s_im) = (_mm256_add_pd(a_re, b_re), _mm256_sub_pd(a_im, b_im));
            let (d_re, d_im) = (_mm256_sub_pd(a_re, b_re), _mm256_add_pd(a_im, b_im));
            let pa = _mm256_add_pd(_mm256_mul_pd(s_re, s_re), _mm256_mul_pd(s_im, s_im));
            let pb = _mm256_add_pd(_mm256_mul_pd(d_re, d_re), _mm256_mul_pd(d_im, d_im));
            let pa = _mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_mul_pd(quarter, pa));
            let pb = _mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_mul_pd(quarter, pb));
            _mm256_storeu_pd(power_a.as_mut_ptr().add(k), pa);
            _mm256_storeu_pd(power_b.as_mut_ptr().add(k), pb);
        }
        run(z, power_a, power_b, 1 + steps * UNPACK_LANES)
    }
    debug_assert!(power_a.len() <= z.len() / 2 + 1);
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU (no fused operations: same results).
        Isa::Avx2Fma | Isa::Avx512 => unsafe { run_avx2(z, power_a, power_b) },
        Isa::Generic => run(z, power_a, power_b, 1),
    }
}

/// `dst[n] = (x[2n]·window[2n], x[2n+1]·window[2n+1])` over the samples of `x`, zero beyond:
/// a real frame of even FFT length as the input of the complex FFT of half that length.
pub(super) fn window_into_pairs(isa: Isa, dst: &mut [Complex<f64>], x: &[f64], window: &[f64]) {
    #[inline(always)]
    fn run(dst: &mut [Complex<f64>], x: &[f64], window: &[f64]) {
        let whole = x.len() / 2;
        let (head, tail) = dst.split_at_mut(whole);
        for ((d, x), w) in head
            .iter_mut()
            .zip(x.chunks_exact(2))
            .zip(window.chunks_exact(2))
        {
            *d = Complex::new(x[0] * w[0], x[1] * w[1]);
        }
        tail.iter_mut().for_each(|v| *v = Complex::new(0.0, 0.0));
        if x.len() % 2 == 1 {
            if let Some(d) = tail.first_mut() {
                *d = Complex::new(x[2 * whole] * window[2 * whole], 0.0);
            }
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(dst: &mut [Complex<f64>], x: &[f64], window: &[f64]) {
        run(dst, x, window)
    }
    debug_assert!(x.len() <= 2 * dst.len() && window.len() >= x.len());
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU (separate multiplies: same results).
        Isa::Avx2Fma | Isa::Avx512 => unsafe { run_avx2(dst, x, window) },
        Isa::Generic => run(dst, x, window),
    }
}

/// The power spectrum |X_k|², k = 0..=M, of a real frame of length 2M from the complex FFT
/// `z` (length M) of its sample pairs: realfft's post-processing (`twiddles[k−1]` =
/// e^{−2πik/2M} / 2, as realfft makes them), its operations in its order, each bin squared
/// as soon as it is made. X_k and X_{M−k} come from Z_k and Z_{M−k} together, so bins
/// k and M−k are written in one step; the centre bin (M even) is Z_{M/2} conjugated.
pub(super) fn half_spectrum_powers(
    isa: Isa,
    z: &[Complex<f64>],
    twiddles: &[Complex<f64>],
    power: &mut [f64],
) {
    /// Bins k and M−k from Z_k, Z_{M−k} and the twiddle of k (realfft's formulas).
    #[inline(always)]
    fn bins(a: Complex<f64>, b: Complex<f64>, tw: Complex<f64>) -> (f64, f64) {
        let sum = a + b;
        let diff = a - b;
        let twiddled_real = sum.im * tw.re + diff.re * tw.im;
        let twiddled_im = sum.im * tw.im - diff.re * tw.re;
        let half_sum_re = 0.5 * sum.re;
        let half_diff_im = 0.5 * diff.im;
        let (re, im) = (half_sum_re + twiddled_real, half_diff_im + twiddled_im);
        let (re_rev, im_rev) = (half_sum_re - twiddled_real, twiddled_im - half_diff_im);
        (re * re + im * im, re_rev * re_rev + im_rev * im_rev)
    }
    /// Bins 0, M and the centre, and the pairs from k = `from` on.
    #[inline(always)]
    fn run(z: &[Complex<f64>], twiddles: &[Complex<f64>], power: &mut [f64], from: usize) {
        let m = z.len();
        if m == 0 || power.len() != m + 1 {
            return;
        }
        // Bins 0 and M: the sum and difference of Z_0's parts (imaginary parts zero).
        let (first, last) = (z[0].re + z[0].im, z[0].re - z[0].im);
        power[0] = first * first + 0.0 * 0.0;
        power[m] = last * last + 0.0 * 0.0;
        let pairs = ((m - 1) / 2).min(twiddles.len());
        for k in from..=pairs {
            (power[k], power[m - k]) = bins(z[k], z[m - k], twiddles[k - 1]);
        }
        if m.is_multiple_of(2) {
            let c = z[m / 2];
            power[m / 2] = c.re * c.re + (-c.im) * (-c.im);
        }
    }
    /// [`run`] with four bins k (and four M−k) per step in AVX2 registers: the same IEEE
    /// operations per lane (multiplies and adds, none fused), so the same bits.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(z: &[Complex<f64>], twiddles: &[Complex<f64>], power: &mut [f64]) {
        use std::arch::x86_64::*;
        let m = z.len();
        if m == 0 || power.len() != m + 1 {
            return;
        }
        let pairs = ((m - 1) / 2).min(twiddles.len());
        // The scalar loop does bin 0, M, the centre and what the vector steps leave.
        let steps = pairs / UNPACK_LANES;
        let (zp, tp, pp) = (
            z.as_ptr() as *const f64,
            twiddles.as_ptr() as *const f64,
            power.as_mut_ptr(),
        );
        let half = _mm256_set1_pd(0.5);
        for step in 0..steps {
            let k = 1 + step * UNPACK_LANES;
            // SAFETY: k + 3 ≤ pairs ≤ (M−1)/2, so z[k..k+4] and z[M−k−3..=M−k] lie in z,
            // twiddles[k−1..k+3] in twiddles, and the stores in power (length M + 1).
            // Lanes hold bins in the order k, k+2, k+1, k+3 (the unpacks' order).
            let [a_re, a_im, b_re, b_im] = load_mirrored(zp, k, m);
            let t01 = _mm256_loadu_pd(tp.add(2 * (k - 1)));
            let t23 = _mm256_loadu_pd(tp.add(2 * (k + 1)));
            let (t_re, t_im) = (_mm256_unpacklo_pd(t01, t23), _mm256_unpackhi_pd(t01, t23));
            let (sum_re, sum_im) = (_mm256_add_pd(a_re, b_re), _mm256_add_pd(a_im, b_im));
            let (diff_re, diff_im) = (_mm256_sub_pd(a_re, b_re), _mm256_sub_pd(a_im, b_im));
            let twiddled_real =
                _mm256_add_pd(_mm256_mul_pd(sum_im, t_re), _mm256_mul_pd(diff_re, t_im));
            let twiddled_im =
                _mm256_sub_pd(_mm256_mul_pd(sum_im, t_im), _mm256_mul_pd(diff_re, t_re));
            let half_sum_re = _mm256_mul_pd(half, sum_re);
            let half_diff_im = _mm256_mul_pd(half, diff_im);
            let (re, im) = (
                _mm256_add_pd(half_sum_re, twiddled_real),
                _mm256_add_pd(half_diff_im, twiddled_im),
            );
            let (re_rev, im_rev) = (
                _mm256_sub_pd(half_sum_re, twiddled_real),
                _mm256_sub_pd(twiddled_im, half_diff_im),
            );
            let lo = _mm256_add_pd(_mm256_mul_pd(re, re), _mm256_mul_pd(im, im));
            let hi = _mm256_add_pd(_mm256_mul_pd(re_rev, re_rev), _mm256_mul_pd(im_rev, im_rev));
            // Lanes (k, k+2, k+1, k+3) → k..k+3; (M−k, M−k−2, M−k−1, M−k−3) → M−k−3..=M−k.
            _mm256_storeu_pd(pp.add(k), _mm256_permute4x64_pd::<0b11_01_10_00>(lo));
            _mm256_storeu_pd(
                pp.add(m - k - 3),
                _mm256_permute4x64_pd::<0b00_10_01_11>(hi),
            );
        }
        // The rest, as `run` does it.
        run(z, twiddles, power, 1 + steps * UNPACK_LANES)
    }
    debug_assert_eq!(power.len(), z.len() + 1);
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU (no fused operations: same results).
        Isa::Avx2Fma | Isa::Avx512 => unsafe { run_avx2(z, twiddles, power) },
        Isa::Generic => run(z, twiddles, power, 1),
    }
}

/// Independent partial sums of the band energy (enough to hide the add latency).
const SUM_LANES: usize = 8;

/// One band's energy Σ weights[i]·power[i] and its strongest bin among `weighted` (positions in
/// `power`, first on a tie; `None` when none has positive power). `weighted` must be exactly the
/// bins of positive weight (as [`super::band_weights`] makes them). The sum and the
/// maximum run in one pass of independent lanes, so the sum may differ from the serial sum in
/// the last bits; the maximum is exact, and its first position is found by a short scan of the
/// band's bins (still in the cache). (A serial chain cost one add latency per bin, and separate
/// passes for the sum and the maximum made this the largest per-frame cost after the FFT at
/// 48 kHz.)
pub(super) fn band_energy_and_peak(
    isa: Isa,
    power: &[f64],
    weights: &[f64],
    weighted: std::ops::Range<usize>,
) -> (f64, Option<usize>) {
    #[inline(always)]
    fn run(
        power: &[f64],
        weights: &[f64],
        weighted: std::ops::Range<usize>,
    ) -> (f64, Option<usize>) {
        // The bins outside `weighted` are exactly those of weight 0 (only edge bins): the
        // maximum skips them by their weight, and the sum runs over every bin in the same
        // lanes as a sum alone would.
        let mut energy_lanes = [0.0f64; SUM_LANES];
        let mut max_lanes = [0.0f64; SUM_LANES];
        let p_chunks = power.chunks_exact(SUM_LANES);
        let w_chunks = weights.chunks_exact(SUM_LANES);
        let (p_tail, w_tail) = (p_chunks.remainder(), w_chunks.remainder());
        for (p, w) in p_chunks.zip(w_chunks) {
            for l in 0..SUM_LANES {
                energy_lanes[l] += w[l] * p[l];
                let candidate = if w[l] > 0.0 { p[l] } else { 0.0 };
                max_lanes[l] = if candidate > max_lanes[l] {
                    candidate
                } else {
                    max_lanes[l]
                };
            }
        }
        let tail: f64 = p_tail.iter().zip(w_tail).map(|(p, w)| w * p).sum();
        let energy = energy_lanes.iter().sum::<f64>() + tail;
        let mut best = max_lanes
            .iter()
            .fold(0.0f64, |m, &v| if v > m { v } else { m });
        for (&p, &w) in p_tail.iter().zip(w_tail) {
            if w > 0.0 && p > best {
                best = p;
            }
        }
        // Its first position (the band's bins are in the cache: a short scan).
        let peak = if best > 0.0 {
            power[weighted.clone()]
                .iter()
                .position(|&p| p == best)
                .map(|i| weighted.start + i)
        } else {
            None
        };
        (energy, peak)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(
        power: &[f64],
        weights: &[f64],
        weighted: std::ops::Range<usize>,
    ) -> (f64, Option<usize>) {
        run(power, weights, weighted)
    }
    debug_assert_eq!(power.len(), weights.len());
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU (separate multiplies and adds).
        Isa::Avx2Fma | Isa::Avx512 => unsafe { run_avx2(power, weights, weighted) },
        Isa::Generic => run(power, weights, weighted),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unpacking a frame pair's transform equals the definition A[k] = |Z[k] + conj Z[N−k]|²/4,
    /// B[k] = |Z[k] − conj Z[N−k]|²/4 (index N−k taken mod N), bit for bit, on every
    /// instruction set of this CPU, for odd and even N and bin counts around the lane steps.
    #[test]
    fn pair_unpacking_equals_the_definition_bit_for_bit() {
        for isa in Isa::available() {
            for n in [1usize, 2, 5, 8, 9, 16, 17, 819, 820] {
                let z: Vec<Complex<f64>> = (0..n)
                    .map(|i| Complex::new((i as f64 * 0.7).sin(), (i as f64 * 1.3).cos() - 0.2))
                    .collect();
                for bins in [0, 1, n / 2, n / 2 + 1] {
                    let (mut a, mut b) = (vec![f64::NAN; bins], vec![f64::NAN; bins]);
                    unpack_pair_powers(isa, &z, &mut a, &mut b);
                    for k in 0..bins {
                        let zc = z[(n - k) % n].conj();
                        let (ea, eb) =
                            (0.25 * (z[k] + zc).norm_sqr(), 0.25 * (z[k] - zc).norm_sqr());
                        assert_eq!(a[k].to_bits(), ea.to_bits(), "{isa:?} N {n} bin {k}");
                        assert_eq!(b[k].to_bits(), eb.to_bits(), "{isa:?} N {n} bin {k}");
                    }
                }
            }
        }
    }

    /// Against the serial definition (weighted sum; strongest bin, first on a tie) on every
    /// instruction set of this CPU, with ties within and across lanes, zero bands, edge bins
    /// outside the band, and lengths around the lane count.
    #[test]
    fn band_energy_and_peak_equal_the_serial_definition() {
        for isa in Isa::available() {
            for len in [0usize, 1, 5, 8, 13, 64, 301] {
                for zero in [false, true] {
                    let power: Vec<f64> = (0..len)
                        .map(|i| {
                            if zero {
                                0.0
                            } else {
                                ((i * 37 % 23) as f64).powi(2)
                            }
                        })
                        .collect();
                    // Edge bins outside the band (weight 0) at both ends, a partial one inside.
                    let weighted = len.min(1)..len.saturating_sub(1).max(len.min(1));
                    let weights: Vec<f64> = (0..len)
                        .map(|i| match i {
                            _ if !weighted.contains(&i) => 0.0,
                            1 => 0.25,
                            _ => 1.0,
                        })
                        .collect();
                    let serial_energy: f64 = power.iter().zip(&weights).map(|(p, w)| w * p).sum();
                    let mut serial_peak = (0.0, None);
                    for i in weighted.clone() {
                        if power[i] > serial_peak.0 {
                            serial_peak = (power[i], Some(i));
                        }
                    }
                    let (energy, peak) =
                        band_energy_and_peak(isa, &power, &weights, weighted.clone());
                    assert!(
                        (energy - serial_energy).abs() <= 1e-14 * serial_energy.abs(),
                        "{isa:?} len {len}: {energy} vs {serial_energy}"
                    );
                    assert_eq!(peak, serial_peak.1, "{isa:?} len {len} zero {zero}");
                }
            }
        }
    }
}

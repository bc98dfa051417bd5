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

/// The power spectra of two real frames from the DFT `z` of `a + j b` (length N):
/// A[k] = (Z[k] + conj Z[N−k]) / 2 and B[k] = (Z[k] − conj Z[N−k]) / 2j, for the bins
/// k < `power_a.len()`.
pub(super) fn unpack_pair_powers(z: &[Complex<f64>], power_a: &mut [f64], power_b: &mut [f64]) {
    let n = z.len();
    for (k, (pa, pb)) in power_a.iter_mut().zip(power_b.iter_mut()).enumerate() {
        let zk = z[k];
        let zc = z[(n - k) % n].conj();
        *pa = 0.25 * (zk + zc).norm_sqr();
        *pb = 0.25 * (zk - zc).norm_sqr();
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

//! [`super::image_gain`] eight bins side by side in AVX-512 lanes. Per bin it is a few
//! products and a division; the scalar loop waits on its own rotation recurrence (~8 cycles a
//! bin) while the divider idles. Here lane j takes bins g + j, g + j + 8, … of each group of
//! [`LANE_RESYNC_BINS`] bins g…, its phasors rotated from the group's exact values by an
//! exact rotation of j bins and then stepped eight bins at a time: 15 steps per exact start
//! against the scalar loop's 31 ([`RESYNC_BINS`]), so no more rounding. The leakage test's band sums (its first flat
//! gains above all: 33 band sums each) were 4 % of a 64-channel STFT run and a seventh of a
//! short one. (Written with intrinsics: the same loop on `[f64; 8]` arrays stayed scalar.)

#[cfg(doc)]
use super::RESYNC_BINS;
#[cfg(target_arch = "x86_64")]
use super::{degenerate_bin_sqr, DecayingHann, HannGrid, DEGENERATE_DEN_SQR};

/// Bins side by side.
#[cfg(target_arch = "x86_64")]
const LANES: usize = 8;

/// Bins between exact evaluations of the phasors: 16 bins of each lane (15 steps).
#[cfg(target_arch = "x86_64")]
const LANE_RESYNC_BINS: usize = 16 * LANES;

#[cfg(target_arch = "x86_64")]
/// (sin, cos) of j times the angle of `one` (its sin, cos) for j = 0 … L − 1, by repeated
/// rotation.
fn rotation_powers<const L: usize>(one: (f64, f64)) -> [(f64, f64); L] {
    let mut out = [(0.0, 1.0); L];
    for j in 1..L {
        out[j] = rotate(out[j - 1], one);
    }
    out
}

#[cfg(target_arch = "x86_64")]
/// (sin, cos) of the sum of two angles given as (sin, cos).
fn rotate((s, c): (f64, f64), (ds, dc): (f64, f64)) -> (f64, f64) {
    (s * dc + c * ds, c * dc - s * ds)
}

/// Σ_k w_k |H(k · bin_rad + shift)|² over the band ([`super::image_gain`]), eight bins at a
/// time.
///
/// # Safety
/// The CPU must have AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
pub(super) unsafe fn image_gain_avx512(
    grid: &HannGrid,
    first_bin: usize,
    weights: &[f64],
    a: f64,
    shift: f64,
) -> f64 {
    use std::arch::x86_64::*;
    let bin_rad = grid.bin_rad;
    let k = DecayingHann::new(grid, a);
    let splat = |x: f64| _mm512_set1_pd(x);
    let (c1, c2) = (splat(k.one_minus_r_sqr), splat(4.0 * k.r));
    let (n1, n2) = (splat(k.one_minus_rn_sqr), splat(4.0 * k.r_n));
    let constant = splat(k.constant());
    let (half_step_sin, half_step_cos) = (splat(k.half_step_sin), splat(k.half_step_cos));
    let lane = rotation_powers::<LANES>(grid.half_bin);
    let lane_n = rotation_powers::<LANES>(grid.half_bin_n);
    let columns = |r: &[(f64, f64); LANES]| {
        let (mut s, mut c) = ([0.0; LANES], [0.0; LANES]);
        for (j, &(sj, cj)) in r.iter().enumerate() {
            (s[j], c[j]) = (sj, cj);
        }
        (_mm512_loadu_pd(s.as_ptr()), _mm512_loadu_pd(c.as_ptr()))
    };
    let (lane_sin, lane_cos) = columns(&lane);
    let (lane_n_sin, lane_n_cos) = columns(&lane_n);
    let (step_sin, step_cos) = rotate(lane[LANES - 1], lane[1]);
    let (step_n_sin, step_n_cos) = rotate(lane_n[LANES - 1], lane_n[1]);
    let (step_sin, step_cos) = (splat(step_sin), splat(step_cos));
    let (step_n_sin, step_n_cos) = (splat(step_n_sin), splat(step_n_cos));
    // (s, c) turned by (ds, dc): (s·dc + c·ds, c·dc − s·ds).
    let turn = |s: __m512d, c: __m512d, ds: __m512d, dc: __m512d| {
        (
            _mm512_fmadd_pd(s, dc, _mm512_mul_pd(c, ds)),
            _mm512_fmsub_pd(c, dc, _mm512_mul_pd(s, ds)),
        )
    };
    // (1 − r)² + 4 r h².
    let sqr = |h: __m512d| _mm512_fmadd_pd(c2, _mm512_mul_pd(h, h), c1);
    let (zero, degenerate_below) = (_mm512_setzero_pd(), splat(DEGENERATE_DEN_SQR));
    let mut total = zero;
    let mut degenerate_total = 0.0;
    for (g, group) in weights.chunks(LANE_RESYNC_BINS).enumerate() {
        let bin0 = first_bin + g * LANE_RESYNC_BINS;
        let phi = bin0 as f64 * bin_rad + shift;
        let (s0, c0) = (0.5 * phi).sin_cos();
        let (sn0, cn0) = (0.5 * phi * k.nf).sin_cos();
        let (mut sin_half, mut cos_half) = turn(splat(s0), splat(c0), lane_sin, lane_cos);
        let (mut sin_half_n, mut cos_half_n) = turn(splat(sn0), splat(cn0), lane_n_sin, lane_n_cos);
        for (step, chunk) in group.chunks(LANES).enumerate() {
            if step > 0 {
                (sin_half, cos_half) = turn(sin_half, cos_half, step_sin, step_cos);
                (sin_half_n, cos_half_n) = turn(sin_half_n, cos_half_n, step_n_sin, step_n_cos);
            }
            // Lanes past the band's end weigh nothing (and are not read).
            let present = ((1u32 << chunk.len()) - 1) as __mmask8;
            let w = _mm512_maskz_loadu_pd(present, chunk.as_ptr());
            let below = _mm512_fmsub_pd(
                sin_half,
                half_step_cos,
                _mm512_mul_pd(cos_half, half_step_sin),
            );
            let above = _mm512_fmadd_pd(
                sin_half,
                half_step_cos,
                _mm512_mul_pd(cos_half, half_step_sin),
            );
            let (d0, d1, d2) = (sqr(sin_half), sqr(below), sqr(above));
            let numerator = _mm512_mul_pd(
                _mm512_mul_pd(
                    _mm512_fmadd_pd(n2, _mm512_mul_pd(sin_half_n, sin_half_n), n1),
                    constant,
                ),
                sqr(cos_half),
            );
            let h = _mm512_div_pd(numerator, _mm512_mul_pd(_mm512_mul_pd(d0, d1), d2));
            let d_min = _mm512_min_pd(_mm512_min_pd(d0, d1), d2);
            let weighted = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(w, zero);
            let regular = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(d_min, degenerate_below);
            // Weightless and degenerate bins add nothing here, whatever h is there.
            total = _mm512_mask3_fmadd_pd(w, h, total, weighted & regular);
            let degenerate = weighted & !regular;
            if degenerate != 0 {
                for j in (0..LANES).filter(|&j| degenerate & (1 << j) != 0) {
                    let bin = bin0 + step * LANES + j;
                    degenerate_total +=
                        chunk[j] * degenerate_bin_sqr(bin as f64 * bin_rad + shift, &k);
                }
            }
        }
    }
    _mm512_reduce_add_pd(total) + degenerate_total
}

//! A frame pair's two power spectra straight from the last stage, without the spectrum.
//!
//! Two real frames a, b go through one complex transform as z = a + i b; their powers are
//! |A_k|² = |Z_k + conj Z_{N−k}|² / 4 and |B_k|² = |Z_k − conj Z_{N−k}|² / 4, so every bin needs
//! its mirror N − k. Scattering all N outputs of the last stage to their bins, then reading
//! them back in mirrored pairs ([`super::super::kernels::unpack_pair_powers`]), moved each
//! value twice out of order: about a fifth of an 819-point pair's time (1.85 µs with it, 1.44–
//! 1.58 without on one core of the README's machine), and of a 3277-point pair's (16.0 → 13.2).
//!
//! In the prime-factor layout the mirror is close at hand. Output k of line L of the last
//! stage (L the indices along the other axes) is bin k' with k' ≡ K_a (mod r_a); its mirror
//! N − k' has every index negated: output (R − k) mod R of the line −L. So the lanes take
//! four lines in their lower half and the four lines −L in their upper half; after the
//! R-point DFTs, output k of one half meets output R − k of the other half in the same lane
//! once the halves of that vector are swapped. Outputs 0 … (R − 1)/2 then give every pair of
//! those lines, and the two powers go straight to their bin (the lower of k', N − k').
//! Register factors last run here ([`last`]); wide ones collect their outputs in the lanes
//! first ([`super::wide::last_pair_powers`]).
//!
//! An even real frame of 2M points takes the same route ([`last_half`]): its sample pairs go
//! through the complex transform of M points, and its bins k and M − k are made from Z_k and
//! Z_{M−k} (realfft's post-processing, twiddled), which meet in the same lanes; the tables put
//! each pair in order and give it its twiddle ([`HalfPowerTables`]); wide last stages collect
//! their lanes first ([`super::wide::last_half_powers`]). One 64-channel 10 s run: 8192 Hz
//! (M = 819) 18.3 → 17.0 ms, 32768 Hz (M = 3277 = 29 · 113) 75.2 → 70.1 ms.
//!
//! The powers are the same IEEE operations in the same order as the unpacking's, none fused,
//! so the same bits: which of the two bins is "k" does not matter (x + y and (x − y)² are
//! symmetric in IEEE arithmetic).

use super::lanes::Lanes;
use super::stages::{dft, Line};
use super::wide::LineValues;
use super::{Stage, PAD};

/// Lanes per half vector: the lines and, in the other half, their mirror lines.
const HALF: usize = PAD / 2;

/// Where the last stage's lines go in the lanes, and where its powers go.
#[derive(Debug)]
pub(super) struct PairPowerPlan {
    /// Per vector, its eight lines: lanes 0–3 lines L, lanes 4–7 the lines −L.
    lines: Vec<u32>,
    /// Per vector and output k = 0 … (R − 1)/2, per lane: the bin (≤ N/2) of the pair.
    bins: Vec<u32>,
    /// The same, the lane's own output's bin (`bins` holds the lower of it and its mirror).
    own: Vec<u32>,
}

impl PairPowerPlan {
    /// The plan for a last stage of `r` points over `lines` lines whose output k of line L
    /// is bin `scatter[L · r + k]` of an `n`-point transform; `None` where the mirrors do not
    /// pair as described (they always should: checked, not assumed).
    pub(super) fn new(n: usize, r: usize, lines: usize, scatter: &[u32]) -> Option<PairPowerPlan> {
        if scatter.len() != n || lines * r != n || r.is_multiple_of(2) {
            return None;
        }
        let h = (r - 1) / 2;
        let mut line_of_bin = vec![0u32; n];
        for (at, &bin) in scatter.iter().enumerate() {
            line_of_bin[bin as usize] = (at / r) as u32;
        }
        let bin = |line: usize, k: usize| scatter[line * r + k] as usize;
        let mirror = |line: usize| line_of_bin[(n - bin(line, 0)) % n] as usize;
        let mut pairs = Vec::new();
        for line in 0..lines {
            let other = mirror(line);
            let mirrored = (0..r).all(|k| (bin(line, k) + bin(other, (r - k) % r)) % n == 0);
            if !mirrored {
                return None;
            }
            if line <= other {
                pairs.push((line, other));
            }
        }
        let vectors = pairs.len().div_ceil(HALF);
        let (mut lanes, mut bins, mut own) = (Vec::new(), Vec::new(), Vec::new());
        let mut covered = vec![false; n / 2 + 1];
        for group in 0..vectors {
            // The last vector repeats its last pair in the lanes left over: the same powers to
            // the same bins twice.
            let pick = |l: usize| pairs[(group * HALF + l).min(pairs.len() - 1)];
            let group_lines: Vec<usize> = (0..PAD)
                .map(|l| match l < HALF {
                    true => pick(l).0,
                    false => pick(l - HALF).1,
                })
                .collect();
            lanes.extend(group_lines.iter().map(|&line| line as u32));
            for k in 0..=h {
                for &line in &group_lines {
                    let b = bin(line, k);
                    let low = b.min(n - b) % n;
                    covered[low] = true;
                    bins.push(low as u32);
                    own.push(b as u32);
                }
            }
        }
        covered.iter().all(|&c| c).then_some(PairPowerPlan {
            lines: lanes,
            bins,
            own,
        })
    }

    /// Per vector: its eight lines (lanes 0–3 lines L, lanes 4–7 the lines −L) and, per
    /// output k = 0 … (R − 1)/2 and lane, the bin of the pair.
    pub(super) fn vectors(&self, r: usize) -> impl Iterator<Item = (&[u32], &[u32])> {
        let per_vector = PAD * ((r - 1) / 2 + 1);
        self.lines
            .chunks_exact(PAD)
            .zip(self.bins.chunks_exact(per_vector))
    }
}

/// The last stage of a frame pair's transform (innermost axis, R points, the array as the
/// other stages left it), straight to the powers of both frames: `power_a[k]`, `power_b[k]`
/// for k = 0 … N/2 (as [`super::super::kernels::unpack_pair_powers`] of the spectrum).
/// `V` must have [`PAD`] lanes.
#[inline(always)]
pub(super) unsafe fn last<V: Lanes, const R: usize, const H: usize>(
    stage: &Stage,
    (re, im): (&[f64], &[f64]),
    plan: &PairPowerPlan,
    power_a: &mut [f64],
    power_b: &mut [f64],
) {
    debug_assert_eq!(V::WIDTH, PAD);
    let pad = R.next_multiple_of(PAD);
    for (lines, bins) in plan.vectors(R) {
        let x = Line::<V, R>::from_rows((re, im), &row_starts(lines, pad));
        let y = dft::<V, R, H>(&x, stage);
        powers_to_bins::<V, _>(R, &y, bins, power_a, power_b);
    }
}

/// Where a vector's lines start in the padded array.
#[inline(always)]
pub(super) fn row_starts(lines: &[u32], pad: usize) -> [usize; PAD] {
    let mut starts = [0usize; PAD];
    for (start, &line) in starts.iter_mut().zip(lines) {
        *start = line as usize * pad;
    }
    starts
}

/// The powers of one vector's pairs to their bins: for k = 0 … (r − 1)/2, output k of each
/// lane with output (r − k) mod r of the lane in the other half (`bins`: per k, per lane).
#[inline(always)]
pub(super) unsafe fn powers_to_bins<V: Lanes, Y: LineValues<V>>(
    r: usize,
    y: &Y,
    bins: &[u32],
    power_a: &mut [f64],
    power_b: &mut [f64],
) {
    let quarter = V::splat(0.25);
    for (k, bins) in bins.chunks_exact(PAD).enumerate() {
        let (zk_re, zk_im) = y.value(k);
        let (zn_re, zn_im) = y.value((r - k) % r);
        let (zn_re, zn_im) = (zn_re.swap_halves(), zn_im.swap_halves());
        let (s_re, s_im) = (zk_re.add(zn_re), zk_im.sub(zn_im));
        let (d_re, d_im) = (zk_re.sub(zn_re), zk_im.add(zn_im));
        let pa = quarter.mul(s_re.mul(s_re).add(s_im.mul(s_im))).to_array();
        let pb = quarter.mul(d_re.mul(d_re).add(d_im.mul(d_im))).to_array();
        for (l, &bin) in bins.iter().enumerate() {
            power_a[bin as usize] = pa[l];
            power_b[bin as usize] = pb[l];
        }
    }
}

/// An even real transform's post-processing in a [`PairPowerPlan`]'s lane order: a real frame
/// of 2M points goes through the complex transform of M points (its sample pairs), and its
/// bins k and M − k come from Z_k and Z_{M−k} (realfft's formulas, as
/// [`super::super::kernels::half_spectrum_powers`] runs them), so the same mirror lanes serve.
/// Per vector, output and lane: the sign that orders the two values (+1 where the lane's own
/// output is Z_k of the lower bin k, −1 where it is Z_{M−k}: Z_{M−k} − Z_k = −(Z_k − Z_{M−k})
/// exactly, and the sum does not depend on the order), and the twiddle of the lower bin.
#[derive(Debug)]
pub(in crate::frontend::stft) struct HalfPowerTables {
    sign: Vec<f64>,
    twiddle_re: Vec<f64>,
    twiddle_im: Vec<f64>,
    /// The vector and lane whose output 0 is Z_0 (bins 0 and M, made apart).
    zero: (usize, usize),
}

impl PairPowerPlan {
    /// The tables of a plan of M = `n` points with a last stage of `r` points for a real
    /// transform of 2M points whose post-processing twiddles are `twiddles`
    /// (`twiddles[k − 1]` = e^{−2πik/2M} / 2); `None` where a bin has no twiddle.
    pub(super) fn half_tables(
        &self,
        n: usize,
        r: usize,
        twiddles: &[rustfft::num_complex::Complex<f64>],
    ) -> Option<HalfPowerTables> {
        let per_vector = PAD * ((r - 1) / 2 + 1);
        let mut tables = HalfPowerTables {
            sign: Vec::with_capacity(self.bins.len()),
            twiddle_re: Vec::with_capacity(self.bins.len()),
            twiddle_im: Vec::with_capacity(self.bins.len()),
            zero: (usize::MAX, 0),
        };
        for (i, (&low, &own)) in self.bins.iter().zip(&self.own).enumerate() {
            let (low, own) = (low as usize, own as usize);
            tables.sign.push(if own == low { 1.0 } else { -1.0 });
            let tw = match low {
                0 => rustfft::num_complex::Complex::new(0.0, 0.0),
                _ => *twiddles.get(low - 1)?,
            };
            tables.twiddle_re.push(tw.re);
            tables.twiddle_im.push(tw.im);
            if own == 0 && tables.zero.0 == usize::MAX {
                tables.zero = (i / per_vector, i % PAD);
            }
        }
        (tables.zero.0 != usize::MAX && n % 2 == 1).then_some(tables)
    }
}

/// The last stage of the complex transform of a real frame's sample pairs (M points), straight
/// to the frame's powers `power[k]`, k = 0 … M, as the spectrum and
/// [`super::super::kernels::half_spectrum_powers`] give them, bit for bit (M odd).
#[inline(always)]
pub(super) unsafe fn last_half<V: Lanes, const R: usize, const H: usize>(
    stage: &Stage,
    (re, im): (&[f64], &[f64]),
    (plan, tables): (&PairPowerPlan, &HalfPowerTables),
    power: &mut [f64],
) {
    debug_assert_eq!(V::WIDTH, PAD);
    let pad = R.next_multiple_of(PAD);
    let mut zero = (0.0, 0.0);
    for (v, (lines, bins)) in plan.vectors(R).enumerate() {
        let x = Line::<V, R>::from_rows((re, im), &row_starts(lines, pad));
        let y = dft::<V, R, H>(&x, stage);
        half_powers_to_bins::<V, _>(R, &y, (bins, v), tables, power, &mut zero);
    }
    zero_and_nyquist(zero, power);
}

/// Bins 0 and M: the sum and difference of Z_0's parts, as the post-processing makes them
/// (the pair [`half_powers_to_bins`] wrote for Z_0 used a twiddle it has not).
#[inline(always)]
pub(super) fn zero_and_nyquist(zero: (f64, f64), power: &mut [f64]) {
    let m = power.len() - 1;
    let (first, last) = (zero.0 + zero.1, zero.0 - zero.1);
    power[0] = first * first + 0.0 * 0.0;
    power[m] = last * last + 0.0 * 0.0;
}

/// Vector `v`'s bins k and M − k (see [`HalfPowerTables`]): realfft's post-processing of
/// Z_k and Z_{M−k}, the same IEEE operations in the same order, none fused; Z_0 to `zero`
/// when this vector holds it.
#[inline(always)]
pub(super) unsafe fn half_powers_to_bins<V: Lanes, Y: LineValues<V>>(
    r: usize,
    y: &Y,
    (bins, v): (&[u32], usize),
    tables: &HalfPowerTables,
    power: &mut [f64],
    zero: &mut (f64, f64),
) {
    if v == tables.zero.0 {
        let (z_re, z_im) = y.value(0);
        *zero = (
            z_re.to_array()[tables.zero.1],
            z_im.to_array()[tables.zero.1],
        );
    }
    let at = v * PAD * ((r - 1) / 2 + 1);
    let m = power.len() - 1;
    let half = V::splat(0.5);
    for (k, bins) in bins.chunks_exact(PAD).enumerate() {
        let i = at + k * PAD;
        let (own_re, own_im) = y.value(k);
        let (mirror_re, mirror_im) = y.value((r - k) % r);
        let (mirror_re, mirror_im) = (mirror_re.swap_halves(), mirror_im.swap_halves());
        let sign = V::load(&tables.sign, i);
        let (t_re, t_im) = (
            V::load(&tables.twiddle_re, i),
            V::load(&tables.twiddle_im, i),
        );
        let (sum_re, sum_im) = (own_re.add(mirror_re), own_im.add(mirror_im));
        let diff_re = sign.mul(own_re.sub(mirror_re));
        let diff_im = sign.mul(own_im.sub(mirror_im));
        let twiddled_real = sum_im.mul(t_re).add(diff_re.mul(t_im));
        let twiddled_im = sum_im.mul(t_im).sub(diff_re.mul(t_re));
        let half_sum_re = half.mul(sum_re);
        let half_diff_im = half.mul(diff_im);
        let (out_re, out_im) = (
            half_sum_re.add(twiddled_real),
            half_diff_im.add(twiddled_im),
        );
        let (rev_re, rev_im) = (
            half_sum_re.sub(twiddled_real),
            twiddled_im.sub(half_diff_im),
        );
        let low = out_re.mul(out_re).add(out_im.mul(out_im)).to_array();
        let high = rev_re.mul(rev_re).add(rev_im.mul(rev_im)).to_array();
        for (l, &bin) in bins.iter().enumerate() {
            power[bin as usize] = low[l];
            power[m - bin as usize] = high[l];
        }
    }
}

impl<V: Lanes, const R: usize> LineValues<V> for Line<V, R> {
    #[inline(always)]
    unsafe fn value(&self, j: usize) -> (V, V) {
        (self.re[j], self.im[j])
    }
}

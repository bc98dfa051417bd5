//! Stages for the factors a line of registers cannot hold: prime powers of primes above 13, up
//! to [`super::WIDE_MAX`] (29 and 113 of 3277 = 29 · 113, a 200 ms window at 16384 Hz; 17 and
//! 257 of 13107 at 65536 Hz). rustfft runs such factors as scalar butterflies or through Rader's
//! and Bluestein's algorithms, 9–10 ns a point against 2–3 for lengths of small factors; the
//! direct sum costs r²/4 complex multiply-adds per line, but in AVX-512 lanes at two fused
//! multiply-adds a cycle that is still a fraction of rustfft's time for the smaller primes.
//! From [`super::RADER_MIN`] on, the stage takes Rader's algorithm ([`super::rader`]) instead.
//!
//! Eight lines side by side, as in [`super::stages`], but from memory: one pass forms the sums
//! and differences x_j ± x_{r−j} of every j into a scratch array, then each block of
//! [`K_BLOCK`] outputs runs one pass over them with its accumulators in registers.

use rustfft::num_complex::Complex;

use super::lanes::Lanes;
use super::pair_powers::{
    half_powers_to_bins, powers_to_bins, row_starts, zero_and_nyquist, HalfPowerTables,
    PairPowerPlan,
};
use super::{Stage, PAD};

/// Outputs k computed per pass over a line's sums: four accumulators each, and the four vectors
/// of one j, fill 28 of the 32 AVX-512 registers.
const K_BLOCK: usize = 6;

/// The cosines and sines of [`Stage`] (k, j = 1 … H, row k − 1) regrouped for [`k_block`]: for
/// each block of up to [`K_BLOCK`] rows, for each j, the block's cosines then its sines (block
/// k₀ starts at 2 H k₀), so that one pass reads one stream.
pub(super) fn blocked_table(h: usize, cos: &[f64], sin: &[f64]) -> Vec<f64> {
    let mut table = Vec::with_capacity(2 * h * h);
    for k0 in (0..h).step_by(K_BLOCK) {
        let rows = k0..h.min(k0 + K_BLOCK);
        for j in 0..h {
            table.extend(rows.clone().map(|k| cos[k * h + j]));
            table.extend(rows.clone().map(|k| sin[k * h + j]));
        }
    }
    table
}

/// A wide stage's working memory (one per thread, in the transform's split buffer): the lines
/// transposed into lanes (last stage), and their sums and differences.
#[derive(Default)]
pub(super) struct WideScratch {
    /// Value j of the lanes' lines: real parts at vector j, imaginary parts at vector r + j.
    lines: Vec<f64>,
    /// For j = 1 … H, vectors 4(j−1) … 4(j−1)+3: the real and imaginary parts of x_j + x_{r−j},
    /// then of x_j − x_{r−j}; or Rader's convolution (2(r − 1) vectors, as many).
    pairs: Vec<f64>,
}

impl WideScratch {
    /// [`WideScratch::fit`], then the lines' and the pairs' memory.
    fn fitted(&mut self, r: usize, width: usize) -> (&mut [f64], &mut [f64]) {
        self.fit(r, width);
        (&mut self.lines, &mut self.pairs)
    }

    /// Room for lines of `r` values, `width` lanes.
    fn fit(&mut self, r: usize, width: usize) {
        let h = (r - 1) / 2;
        if self.lines.len() < 2 * r * width {
            self.lines.resize(2 * r * width, 0.0);
        }
        if self.pairs.len() < 4 * h * width {
            self.pairs.resize(4 * h * width, 0.0);
        }
    }
}

/// Any axis but the innermost, in place: the lines of each outer index are `inner` contiguous
/// positions (a multiple of [`PAD`]), a vector at a time; value j of a line is `inner` further.
#[inline(always)]
pub(super) unsafe fn in_place<V: Lanes>(
    stage: &Stage,
    re: &mut [f64],
    im: &mut [f64],
    scratch: &mut WideScratch,
) {
    let (r, inner, w) = (stage.r, stage.inner, V::WIDTH);
    debug_assert!(inner.is_multiple_of(w));
    scratch.fit(r, w);
    for outer in 0..stage.outer {
        let base = outer * r * inner;
        for start in (base..base + inner).step_by(w) {
            let mut lines = Strided {
                re: &mut *re,
                im: &mut *im,
                start,
                inner,
            };
            let x0 = take_lines::<V, _>(stage, &lines, &mut scratch.pairs);
            put_bins::<V, _>(stage, x0, &mut scratch.pairs, &mut lines);
        }
    }
}

/// The innermost axis, padded to a multiple of [`PAD`]: line L is positions L · pad … L · pad +
/// r − 1, and its bin k goes to `spectrum[scatter[L · r + k]]`.
#[inline(always)]
pub(super) unsafe fn last<V: Lanes>(
    stage: &Stage,
    re: &[f64],
    im: &[f64],
    scatter: &[u32],
    spectrum: &mut [Complex<f64>],
    scratch: &mut WideScratch,
) {
    let (r, lines, w) = (stage.r, stage.outer, V::WIDTH);
    let pad = r.next_multiple_of(PAD);
    let (columns, pairs) = scratch.fitted(r, w);
    for start in (0..lines).step_by(w) {
        let lanes = w.min(lines - start);
        // Value j of every lane's line into vector j (real) and r + j (imaginary).
        if lanes == w && w == PAD {
            let starts: [usize; PAD] = std::array::from_fn(|l| (start + l) * pad);
            rows_into_columns::<V>((re, im), &starts, r, columns);
        } else {
            for j in 0..r {
                for l in 0..w {
                    let (v_re, v_im) = match l < lanes {
                        true => (re[(start + l) * pad + j], im[(start + l) * pad + j]),
                        false => (0.0, 0.0),
                    };
                    columns[j * w + l] = v_re;
                    columns[(r + j) * w + l] = v_im;
                }
            }
        }
        let values = Columns { columns, r };
        let mut bins = Scatter {
            spectrum: &mut *spectrum,
            bins: &scatter[start * r..(start + lanes) * r],
            lanes,
            r,
        };
        let x0 = take_lines::<V, _>(stage, &values, pairs);
        put_bins::<V, _>(stage, x0, pairs, &mut bins);
    }
}

/// The innermost axis of a frame pair's transform straight to the two frames' powers, as
/// [`super::pair_powers::last`] for a wide factor: each vector of lines (with their mirror
/// lines) is transformed as in [`last`], its bins collected in the scratch (where the lines
/// were: read by then), then paired. `V` must have [`PAD`] lanes.
#[inline(always)]
pub(super) unsafe fn last_pair_powers<V: Lanes>(
    stage: &Stage,
    (re, im): (&[f64], &[f64]),
    plan: &PairPowerPlan,
    (power_a, power_b): (&mut [f64], &mut [f64]),
    scratch: &mut WideScratch,
) {
    let (r, w) = (stage.r, V::WIDTH);
    debug_assert_eq!(w, PAD);
    let pad = r.next_multiple_of(PAD);
    let (columns, pairs) = scratch.fitted(r, w);
    for (lines, bins) in plan.vectors(r) {
        transform_into_columns::<V>(stage, (re, im), &row_starts(lines, pad), columns, pairs);
        powers_to_bins::<V, _>(r, &Columns { columns, r }, bins, power_a, power_b);
    }
}

/// One vector of lines transformed, its bins collected in `columns` where the lines were
/// (read whole by then), for [`last_pair_powers`] and [`last_half_powers`] to pair.
#[inline(always)]
unsafe fn transform_into_columns<V: Lanes>(
    stage: &Stage,
    (re, im): (&[f64], &[f64]),
    starts: &[usize; PAD],
    columns: &mut [f64],
    pairs: &mut [f64],
) {
    let r = stage.r;
    rows_into_columns::<V>((re, im), starts, r, columns);
    let values = Columns { columns, r };
    // The lines are read whole before the first bin is kept where they were.
    let x0 = take_lines::<V, _>(stage, &values, pairs);
    let mut collected = Collected { columns, r };
    put_bins::<V, _>(stage, x0, pairs, &mut collected);
}

/// The innermost axis of the transform of a real frame's sample pairs straight to the frame's
/// powers, as [`super::pair_powers::last_half`] for a wide factor (the lanes collected as in
/// [`last_pair_powers`]).
#[inline(always)]
pub(super) unsafe fn last_half_powers<V: Lanes>(
    stage: &Stage,
    (re, im): (&[f64], &[f64]),
    (plan, tables): (&PairPowerPlan, &HalfPowerTables),
    power: &mut [f64],
    scratch: &mut WideScratch,
) {
    let (r, w) = (stage.r, V::WIDTH);
    debug_assert_eq!(w, PAD);
    let pad = r.next_multiple_of(PAD);
    let (columns, pairs) = scratch.fitted(r, w);
    let mut zero = (0.0, 0.0);
    for (v, (lines, bins)) in plan.vectors(r).enumerate() {
        transform_into_columns::<V>(stage, (re, im), &row_starts(lines, pad), columns, pairs);
        let values = Columns { columns, r };
        half_powers_to_bins::<V, _>(r, &values, (bins, v), tables, power, &mut zero);
    }
    zero_and_nyquist(zero, power);
}

/// Reads a vector of lines into `pairs`: Rader's transformed convolution input, or the sums and
/// differences of the direct sum ([`pair_up`]); returns x₀ and bin 0.
#[inline(always)]
unsafe fn take_lines<V: Lanes, X: LineValues<V>>(
    stage: &Stage,
    x: &X,
    pairs: &mut [f64],
) -> [(V, V); 2] {
    match &stage.rader {
        Some(rader) => rader.load::<V, _>(x, pairs),
        None => pair_up::<V, _>(stage.r, pairs, x),
    }
}

/// Every bin of the lines [`take_lines`] read, each to `out`.
#[inline(always)]
unsafe fn put_bins<V: Lanes, O: LineBins<V>>(
    stage: &Stage,
    x0: [(V, V); 2],
    pairs: &mut [f64],
    out: &mut O,
) {
    match &stage.rader {
        Some(rader) => rader.finish::<V, _>(x0, pairs, out),
        None => outputs::<V, _>(stage, x0, pairs, out),
    }
}

/// The `r` values of the [`PAD`] lines starting at `starts` into `columns` (value j of every
/// line: real parts at vector j, imaginary parts at vector r + j), transposed in registers.
/// `V` must have [`PAD`] lanes.
#[inline(always)]
unsafe fn rows_into_columns<V: Lanes>(
    (re, im): (&[f64], &[f64]),
    starts: &[usize; PAD],
    r: usize,
    columns: &mut [f64],
) {
    let w = V::WIDTH;
    for chunk in (0..r).step_by(PAD) {
        let (cols_re, cols_im) = (
            V::load_rows(re, starts, chunk),
            V::load_rows(im, starts, chunk),
        );
        for i in 0..PAD.min(r - chunk) {
            cols_re[i].store(columns, (chunk + i) * w);
            cols_im[i].store(columns, (r + chunk + i) * w);
        }
    }
}

/// Where a vector of lines has its values (no closures: one not inlined would run the
/// intrinsics as calls).
pub(super) trait LineValues<V> {
    /// Value j of the lines: real and imaginary parts.
    unsafe fn value(&self, j: usize) -> (V, V);
}

/// Where a vector of lines' bins go.
pub(super) trait LineBins<V> {
    /// Bin k of the lines: real and imaginary parts.
    unsafe fn put(&mut self, k: usize, re: V, im: V);
}

/// Lines along an inner axis, in place: value j at `start + j · inner`.
struct Strided<'a> {
    re: &'a mut [f64],
    im: &'a mut [f64],
    start: usize,
    inner: usize,
}

impl<V: Lanes> LineValues<V> for Strided<'_> {
    #[inline(always)]
    unsafe fn value(&self, j: usize) -> (V, V) {
        let at = self.start + j * self.inner;
        (V::load(self.re, at), V::load(self.im, at))
    }
}

impl<V: Lanes> LineBins<V> for Strided<'_> {
    #[inline(always)]
    unsafe fn put(&mut self, k: usize, re: V, im: V) {
        let at = self.start + k * self.inner;
        re.store(self.re, at);
        im.store(self.im, at);
    }
}

/// Lines transposed into lanes ([`WideScratch::lines`]).
struct Columns<'a> {
    columns: &'a [f64],
    r: usize,
}

impl<V: Lanes> LineValues<V> for Columns<'_> {
    #[inline(always)]
    unsafe fn value(&self, j: usize) -> (V, V) {
        let w = V::WIDTH;
        (
            V::load(self.columns, j * w),
            V::load(self.columns, (self.r + j) * w),
        )
    }
}

/// A vector of lines' bins kept in lanes, laid out as [`Columns`] reads them.
struct Collected<'a> {
    columns: &'a mut [f64],
    r: usize,
}

impl<V: Lanes> LineBins<V> for Collected<'_> {
    #[inline(always)]
    unsafe fn put(&mut self, k: usize, re: V, im: V) {
        let w = V::WIDTH;
        re.store(self.columns, k * w);
        im.store(self.columns, (self.r + k) * w);
    }
}

/// The last stage's bins, lane l's bin k to `spectrum[bins[l · r + k]]`.
struct Scatter<'a> {
    spectrum: &'a mut [Complex<f64>],
    bins: &'a [u32],
    lanes: usize,
    r: usize,
}

impl<V: Lanes> LineBins<V> for Scatter<'_> {
    #[inline(always)]
    unsafe fn put(&mut self, k: usize, re: V, im: V) {
        let (re, im) = (re.to_array(), im.to_array());
        for l in 0..self.lanes {
            self.spectrum[self.bins[l * self.r + k] as usize] = Complex::new(re[l], im[l]);
        }
    }
}

/// Writes the sums and differences of the pairs of values j, r − j of the lines `x` to
/// `pairs`; returns x₀ and the DFT's bin 0, x₀ + Σ sums.
#[inline(always)]
unsafe fn pair_up<V: Lanes, X: LineValues<V>>(r: usize, pairs: &mut [f64], x: &X) -> [(V, V); 2] {
    let w = V::WIDTH;
    let x0 = x.value(0);
    let mut bin0 = x0;
    for j in 1..=(r - 1) / 2 {
        let (p, q) = (x.value(j), x.value(r - j));
        let (sum_re, sum_im) = (p.0.add(q.0), p.1.add(q.1));
        let at = 4 * (j - 1) * w;
        sum_re.store(pairs, at);
        sum_im.store(pairs, at + w);
        p.0.sub(q.0).store(pairs, at + 2 * w);
        p.1.sub(q.1).store(pairs, at + 3 * w);
        bin0 = (bin0.0.add(sum_re), bin0.1.add(sum_im));
    }
    [x0, bin0]
}

/// Every bin of the lines whose pairs [`pair_up`] wrote: bin 0, then for k = 1 … H,
/// X_k = A − iB and X_{r−k} = A + iB with A = x₀ + Σ_j cos(2π jk/r) · sum_j and
/// B = Σ_j sin(2π jk/r) · dif_j, each to `out`.
#[inline(always)]
unsafe fn outputs<V: Lanes, O: LineBins<V>>(
    stage: &Stage,
    [x0, bin0]: [(V, V); 2],
    pairs: &[f64],
    out: &mut O,
) {
    let h = (stage.r - 1) / 2;
    out.put(0, bin0.0, bin0.1);
    let mut k0 = 0;
    while k0 + K_BLOCK <= h {
        k_block::<V, O, K_BLOCK>(stage, x0, pairs, k0, out);
        k0 += K_BLOCK;
    }
    match h - k0 {
        0 => {}
        1 => k_block::<V, O, 1>(stage, x0, pairs, k0, out),
        2 => k_block::<V, O, 2>(stage, x0, pairs, k0, out),
        3 => k_block::<V, O, 3>(stage, x0, pairs, k0, out),
        4 => k_block::<V, O, 4>(stage, x0, pairs, k0, out),
        _ => k_block::<V, O, 5>(stage, x0, pairs, k0, out),
    }
}

/// Bins k0 + 1 … k0 + KB and their mirrors r − k (see [`outputs`]): one pass over the pairs.
#[inline(always)]
unsafe fn k_block<V: Lanes, O: LineBins<V>, const KB: usize>(
    stage: &Stage,
    x0: (V, V),
    pairs: &[f64],
    k0: usize,
    out: &mut O,
) {
    let (r, w) = (stage.r, V::WIDTH);
    let h = (r - 1) / 2;
    let zero = V::splat(0.0);
    let (mut a_re, mut a_im, mut b_re, mut b_im) = ([x0.0; KB], [x0.1; KB], [zero; KB], [zero; KB]);
    let table = &stage.blocked[k0 * 2 * h..(k0 + KB) * 2 * h];
    for (t, p) in table.chunks_exact(2 * KB).zip(pairs.chunks_exact(4 * w)) {
        let (sum_re, sum_im) = (V::load(p, 0), V::load(p, w));
        let (dif_re, dif_im) = (V::load(p, 2 * w), V::load(p, 3 * w));
        for kk in 0..KB {
            let (c, s) = (V::splat(t[kk]), V::splat(t[KB + kk]));
            a_re[kk] = a_re[kk].mul_add(c, sum_re);
            a_im[kk] = a_im[kk].mul_add(c, sum_im);
            b_re[kk] = b_re[kk].mul_add(s, dif_re);
            b_im[kk] = b_im[kk].mul_add(s, dif_im);
        }
    }
    for kk in 0..KB {
        let k = k0 + kk + 1;
        out.put(k, a_re[kk].add(b_im[kk]), a_im[kk].sub(b_re[kk]));
        out.put(r - k, a_re[kk].sub(b_im[kk]), a_im[kk].add(b_re[kk]));
    }
}

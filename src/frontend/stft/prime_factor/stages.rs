//! The two kinds of stage of the prime-factor FFT, each the R-point DFTs of its lines with
//! one line per vector lane ([`Lanes`]). All are `unsafe`: they run inside a function compiled
//! for `V`'s instruction set.

use rustfft::num_complex::Complex;

use super::lanes::Lanes;
use super::{Stage, PAD};

/// R values of a vector of lines, split into real and imaginary parts.
pub(super) struct Line<V, const R: usize> {
    pub(super) re: [V; R],
    pub(super) im: [V; R],
}

impl<V: Lanes, const R: usize> Line<V, R> {
    /// The R values of the lines starting at `starts` (one per lane), transposed in
    /// registers.
    #[inline(always)]
    pub(super) unsafe fn from_rows((re, im): (&[f64], &[f64]), starts: &[usize; PAD]) -> Self {
        let mut x = Self::zero();
        for chunk in (0..R).step_by(PAD) {
            let (cols_re, cols_im) = (
                V::load_rows(re, starts, chunk),
                V::load_rows(im, starts, chunk),
            );
            let end = R.min(chunk + PAD);
            x.re[chunk..end].copy_from_slice(&cols_re[..end - chunk]);
            x.im[chunk..end].copy_from_slice(&cols_im[..end - chunk]);
        }
        x
    }

    /// All values zero.
    #[inline(always)]
    pub(super) unsafe fn zero() -> Self {
        let zero = V::splat(0.0);
        Line {
            re: [zero; R],
            im: [zero; R],
        }
    }
}

/// Any axis but the innermost, in place: for each outer index, its lines are the `inner`
/// contiguous positions (a multiple of [`PAD`]), a vector at a time.
#[inline(always)]
pub(super) unsafe fn in_place<V: Lanes, const R: usize, const H: usize>(
    stage: &Stage,
    re: &mut [f64],
    im: &mut [f64],
) {
    let inner = stage.inner;
    debug_assert!(inner.is_multiple_of(V::WIDTH));
    for outer in 0..stage.outer {
        let base = outer * R * inner;
        for start in (base..base + inner).step_by(V::WIDTH) {
            dft_in_memory::<V, R, H>(stage, re, im, start, inner);
        }
    }
}

/// The R-point DFT of one vector of lines in place: value j at `at + j · stride` of `re` and
/// `im`.
#[inline(always)]
pub(super) unsafe fn dft_in_memory<V: Lanes, const R: usize, const H: usize>(
    stage: &Stage,
    re: &mut [f64],
    im: &mut [f64],
    at: usize,
    stride: usize,
) {
    let mut x = Line::<V, R>::zero();
    for j in 0..R {
        x.re[j] = V::load(re, at + j * stride);
        x.im[j] = V::load(im, at + j * stride);
    }
    let y = dft::<V, R, H>(&x, stage);
    for k in 0..R {
        y.re[k].store(re, at + k * stride);
        y.im[k].store(im, at + k * stride);
    }
}

/// The innermost axis, padded to a multiple of [`PAD`]: line L is positions L · pad … L · pad +
/// R − 1, and its bin k goes to `spectrum[scatter[L · R + k]]`.
#[inline(always)]
pub(super) unsafe fn last<V: Lanes, const R: usize, const H: usize>(
    stage: &Stage,
    re: &[f64],
    im: &[f64],
    scatter: &[u32],
    spectrum: &mut [Complex<f64>],
) {
    let (lines, pad) = (stage.outer, R.next_multiple_of(PAD));
    for start in (0..lines).step_by(V::WIDTH) {
        let lanes = V::WIDTH.min(lines - start);
        let value = |v: &[f64], l: usize, j: usize| {
            if l < lanes {
                v[(start + l) * pad + j]
            } else {
                0.0
            }
        };
        let mut x = Line::<V, R>::zero();
        if lanes == V::WIDTH {
            let starts: [usize; PAD] = std::array::from_fn(|l| (start + l) * pad);
            x = Line::from_rows((re, im), &starts);
        } else {
            for j in 0..R {
                x.re[j] = V::from_fn(|l| value(re, l, j));
                x.im[j] = V::from_fn(|l| value(im, l, j));
            }
        }
        let y = dft::<V, R, H>(&x, stage);
        let bins = &scatter[start * R..(start + lanes) * R];
        for k in 0..R {
            let (y_re, y_im) = (y.re[k].to_array(), y.im[k].to_array());
            for l in 0..lanes {
                spectrum[bins[l * R + k] as usize] = Complex::new(y_re[l], y_im[l]);
            }
        }
    }
}

/// The forward R-point DFT of each lane, X_k = Σ_j x_j e^{−2πi jk/R}, as
/// x₀ + Σ_{j=1}^{H} (x_j + x_{R−j}) cos θ − i (x_j − x_{R−j}) sin θ with θ = 2π jk / R,
/// H = (R − 1)/2.
#[inline(always)]
pub(super) unsafe fn dft<V: Lanes, const R: usize, const H: usize>(
    x: &Line<V, R>,
    stage: &Stage,
) -> Line<V, R> {
    let (cos, sin) = (&stage.cos[..H * H], &stage.sin[..H * H]);
    let zero = V::splat(0.0);
    let (mut sum_re, mut sum_im, mut dif_re, mut dif_im) =
        ([zero; H], [zero; H], [zero; H], [zero; H]);
    let mut y = Line::<V, R> { re: x.re, im: x.im };
    for j in 0..H {
        let (p, q) = (j + 1, R - 1 - j);
        sum_re[j] = x.re[p].add(x.re[q]);
        sum_im[j] = x.im[p].add(x.im[q]);
        dif_re[j] = x.re[p].sub(x.re[q]);
        dif_im[j] = x.im[p].sub(x.im[q]);
        y.re[0] = y.re[0].add(sum_re[j]);
        y.im[0] = y.im[0].add(sum_im[j]);
    }
    // X_k = A − iB, X_{R−k} = A + iB. The real parts need only the real sums and imaginary
    // differences, the imaginary parts the other two: one half after the other, twelve inputs
    // live at a time for R = 13 (all four at once did not fit in the registers).
    let (a, b) = half_sums::<V, H>(x.re[0], &sum_re, &dif_im, cos, sin);
    for k in 0..H {
        // Real parts A_re ± B_im.
        y.re[k + 1] = a[k].add(b[k]);
        y.re[R - 1 - k] = a[k].sub(b[k]);
    }
    let (a, b) = half_sums::<V, H>(x.im[0], &sum_im, &dif_re, cos, sin);
    for k in 0..H {
        // Imaginary parts A_im ∓ B_re.
        y.im[k + 1] = a[k].sub(b[k]);
        y.im[R - 1 - k] = a[k].add(b[k]);
    }
    y
}

/// For k = 1 … H: A_k = x₀ + Σ_j cos(2π jk / R) · sum_j and B_k = Σ_j sin(2π jk / R) · dif_j
/// (one of the real and imaginary halves of [`dft`]).
#[inline(always)]
unsafe fn half_sums<V: Lanes, const H: usize>(
    x0: V,
    sum: &[V; H],
    dif: &[V; H],
    cos: &[f64],
    sin: &[f64],
) -> ([V; H], [V; H]) {
    let (mut a, mut b) = ([x0; H], [V::splat(0.0); H]);
    for k in 0..H {
        for j in 0..H {
            a[k] = a[k].mul_add(V::splat(cos[k * H + j]), sum[j]);
            b[k] = b[k].mul_add(V::splat(sin[k * H + j]), dif[j]);
        }
    }
    (a, b)
}

//! Rader's algorithm for the large prime factors of the wide stages (113 at 16384 Hz, 257 at
//! 65536 Hz), where the direct sum's r²/4 multiply-adds per line outgrow an FFT's.
//!
//! For a prime p with primitive root g, every bin but X₀ is a cyclic convolution of length
//! L = p − 1: with a_q = x_{g^{−q}} and b_n = ω^{g^n} (ω = e^{−2πi/p}),
//! X_{g^m} = x₀ + Σ_q a_q b_{m−q}, and X₀ = x₀ + Σ_q a_q. The convolution runs as
//! conj(DFT(conj(DFT(a) · B))) with B = DFT(b) / L precomputed, both DFTs forward ones of L
//! points in the lanes (eight lines at a time, as every stage): the first by decimation in
//! frequency (natural order in, a permuted order out), the second by decimation in time (that
//! order in, natural order out), so no reordering pass is needed (B is kept in the same
//! order). L = 2^a · m with m one of the register kernels' odd factors (or 1): passes of radix
//! 4 (and one of radix 2 where a is odd) with twiddles, and the m-point DFTs of
//! [`super::stages`]. Radix-2 passes alone took 82 µs for a frame pair of 3 · 17 · 257, the
//! radix-4 ones 63 (the direct sum 98, rustfft 137).

use super::lanes::Lanes;
use super::stages::dft_in_memory;
use super::wide::{LineBins, LineValues};
use super::{prime_powers, smallest_prime, Stage, FACTORS};

/// A planned Rader transform of one prime.
#[derive(Debug)]
pub(super) struct Rader {
    /// Convolution length p − 1 = 2^a · m.
    len: usize,
    /// The odd part m of `len` and its DFT's tables (none: m = 1).
    odd: Option<Stage>,
    /// Input q of the convolution is x at `gather[q]` = g^{−q} mod p.
    gather: Vec<u32>,
    /// Output m of the convolution is bin `scatter[m]` = g^m mod p.
    scatter: Vec<u32>,
    /// The radices of the passes over the power of two of L, outermost first: fours, and a
    /// two first where the power is odd.
    radices: Vec<usize>,
    /// e^{−2πi k/L}, k < L: the passes' twiddles (real, imaginary parts).
    twiddle_re: Vec<f64>,
    twiddle_im: Vec<f64>,
    /// DFT(b) / L in the order the decimation in frequency leaves.
    kernel_re: Vec<f64>,
    kernel_im: Vec<f64>,
}

impl Rader {
    /// The plan for prime `p`, or `None` when p − 1 is not 2^a · m (a ≥ 1) with m one of the
    /// register kernels' factors or 1.
    pub(super) fn new(p: usize) -> Option<Rader> {
        if p < 3 || smallest_prime(p) != p {
            return None;
        }
        let len = p - 1;
        let odd = len >> len.trailing_zeros();
        if odd != 1 && !FACTORS.contains(&odd) {
            return None;
        }
        let g = primitive_root(p);
        let g_inv = power_mod(g, p - 2, p);
        let powers = |base: usize| {
            let mut v = 1usize;
            (0..len)
                .map(|_| {
                    let out = v as u32;
                    v = v * base % p;
                    out
                })
                .collect::<Vec<u32>>()
        };
        let angle = |k: usize, n: usize| -2.0 * std::f64::consts::PI * (k % n) as f64 / n as f64;
        let twos = len.trailing_zeros() as usize;
        let radices = [2]
            .repeat(twos % 2)
            .into_iter()
            .chain([4].repeat(twos / 2))
            .collect();
        let (twiddle_re, twiddle_im) = (0..len)
            .map(|k| angle(k, len))
            .map(|a| (a.cos(), a.sin()))
            .unzip();
        let mut plan = Rader {
            len,
            odd: (odd > 1).then(|| Stage::new(odd, 0, 0, usize::MAX)),
            gather: powers(g_inv),
            scatter: powers(g),
            radices,
            twiddle_re,
            twiddle_im,
            kernel_re: Vec::new(),
            kernel_im: Vec::new(),
        };
        // b_n = ω^{g^n}, transformed by the same passes (one lane), divided by L.
        let (mut re, mut im): (Vec<f64>, Vec<f64>) = plan
            .scatter
            .iter()
            .map(|&e| angle(e as usize, p))
            .map(|a| (a.cos(), a.sin()))
            .unzip();
        // SAFETY: `f64` lanes need no instruction set beyond the baseline.
        unsafe { plan.decimate_in_frequency::<f64>(&mut re, &mut im) };
        plan.kernel_re = re.iter().map(|v| v / len as f64).collect();
        plan.kernel_im = im.iter().map(|v| v / len as f64).collect();
        Some(plan)
    }

    /// Reads a vector of lines into `work` (the convolution's input, transformed); returns
    /// x₀ and bin 0.
    #[inline(always)]
    pub(super) unsafe fn load<V: Lanes, X: LineValues<V>>(
        &self,
        x: &X,
        work: &mut [f64],
    ) -> [(V, V); 2] {
        let (w, len) = (V::WIDTH, self.len);
        let (re, im) = work[..2 * len * w].split_at_mut(len * w);
        let x0 = x.value(0);
        let mut bin0 = x0;
        for (q, &j) in self.gather.iter().enumerate() {
            let (v_re, v_im) = x.value(j as usize);
            v_re.store(re, q * w);
            v_im.store(im, q * w);
            bin0 = (bin0.0.add(v_re), bin0.1.add(v_im));
        }
        self.decimate_in_frequency::<V>(re, im);
        [x0, bin0]
    }

    /// The bins of the lines [`Rader::load`] read, each to `out`.
    #[inline(always)]
    pub(super) unsafe fn finish<V: Lanes, O: LineBins<V>>(
        &self,
        [x0, bin0]: [(V, V); 2],
        work: &mut [f64],
        out: &mut O,
    ) {
        let (w, len) = (V::WIDTH, self.len);
        let (re, im) = work[..2 * len * w].split_at_mut(len * w);
        // conj(A · B).
        for i in 0..len {
            let (a_re, a_im) = (V::load(re, i * w), V::load(im, i * w));
            let (b_re, b_im) = (V::splat(self.kernel_re[i]), V::splat(self.kernel_im[i]));
            let (prod_re, prod_im) = times((a_re, a_im), (b_re, b_im));
            prod_re.store(re, i * w);
            V::splat(0.0).sub(prod_im).store(im, i * w);
        }
        self.decimate_in_time::<V>(re, im);
        out.put(0, bin0.0, bin0.1);
        for (m, &k) in self.scatter.iter().enumerate() {
            let (c_re, c_im) = (V::load(re, m * w), V::load(im, m * w));
            out.put(k as usize, x0.0.add(c_re), x0.1.sub(c_im));
        }
    }

    /// The forward DFT of L points in place, natural order in, the passes' order out: a pass
    /// per radix (outermost first; each a radix-r DFT across the block's r parts, then
    /// twiddles), then the m-point DFTs of the blocks.
    #[inline(always)]
    unsafe fn decimate_in_frequency<V: Lanes>(&self, re: &mut [f64], im: &mut [f64]) {
        let len = self.len;
        assert!(re.len() >= len * V::WIDTH && im.len() >= len * V::WIDTH);
        let v = Vectors::<V>::new(re, im);
        let mut span = len;
        for &r in &self.radices {
            let (q, step) = (span / r, len / span);
            for start in (0..len).step_by(span) {
                for n in 0..q {
                    let i = start + n;
                    if r == 2 {
                        let (x0, x1) = (v.get(i), v.get(i + q));
                        v.put(i, add(x0, x1));
                        v.put(i + q, times(sub(x0, x1), self.twiddle(n * step)));
                    } else {
                        let y = dft4([v.get(i), v.get(i + q), v.get(i + 2 * q), v.get(i + 3 * q)]);
                        v.put(i, y[0]);
                        for (s, &y) in y.iter().enumerate().skip(1) {
                            v.put(i + s * q, times(y, self.twiddle(s * n * step)));
                        }
                    }
                }
            }
            span = q;
        }
        self.odd_blocks::<V>(re, im);
    }

    /// The forward DFT of L points in place, the passes' order in (as
    /// [`Rader::decimate_in_frequency`] leaves it), natural order out: the m-point DFTs of the
    /// blocks, then a pass per radix (innermost first; twiddles, then a radix-r DFT across the
    /// block's r parts).
    #[inline(always)]
    unsafe fn decimate_in_time<V: Lanes>(&self, re: &mut [f64], im: &mut [f64]) {
        let len = self.len;
        assert!(re.len() >= len * V::WIDTH && im.len() >= len * V::WIDTH);
        self.odd_blocks::<V>(re, im);
        let v = Vectors::<V>::new(re, im);
        let mut span = self.odd_len();
        for &r in self.radices.iter().rev() {
            span *= r;
            let (q, step) = (span / r, len / span);
            for start in (0..len).step_by(span) {
                for n in 0..q {
                    let i = start + n;
                    if r == 2 {
                        let (x0, x1) = (v.get(i), times(v.get(i + q), self.twiddle(n * step)));
                        v.put(i, add(x0, x1));
                        v.put(i + q, sub(x0, x1));
                    } else {
                        let mut x = [v.get(i); 4];
                        for (s, x) in x.iter_mut().enumerate().skip(1) {
                            *x = times(v.get(i + s * q), self.twiddle(s * n * step));
                        }
                        for (s, y) in dft4(x).into_iter().enumerate() {
                            v.put(i + s * q, y);
                        }
                    }
                }
            }
        }
    }

    /// Twiddle k, e^{−2πi k/L}, as two vectors.
    #[inline(always)]
    unsafe fn twiddle<V: Lanes>(&self, k: usize) -> (V, V) {
        (
            V::splat(*self.twiddle_re.get_unchecked(k)),
            V::splat(*self.twiddle_im.get_unchecked(k)),
        )
    }

    /// The odd part m of L.
    fn odd_len(&self) -> usize {
        self.odd.as_ref().map_or(1, |stage| stage.r)
    }

    /// The m-point DFT of each block of m vectors, in place.
    #[inline(always)]
    unsafe fn odd_blocks<V: Lanes>(&self, re: &mut [f64], im: &mut [f64]) {
        let Some(odd) = &self.odd else { return };
        let w = V::WIDTH;
        for at in (0..self.len).step_by(odd.r) {
            let at = at * w;
            match odd.r {
                3 => dft_in_memory::<V, 3, 1>(odd, re, im, at, w),
                5 => dft_in_memory::<V, 5, 2>(odd, re, im, at, w),
                7 => dft_in_memory::<V, 7, 3>(odd, re, im, at, w),
                9 => dft_in_memory::<V, 9, 4>(odd, re, im, at, w),
                11 => dft_in_memory::<V, 11, 5>(odd, re, im, at, w),
                13 => dft_in_memory::<V, 13, 6>(odd, re, im, at, w),
                _ => unreachable!("odd parts are checked when planning"),
            }
        }
    }
}

/// The L vectors of complex values of a transform in place, without bounds checks (the passes'
/// indices stay below L, checked once by the caller).
struct Vectors<V> {
    re: *mut f64,
    im: *mut f64,
    lanes: std::marker::PhantomData<V>,
}

impl<V: Lanes> Vectors<V> {
    fn new(re: &mut [f64], im: &mut [f64]) -> Self {
        Vectors {
            re: re.as_mut_ptr(),
            im: im.as_mut_ptr(),
            lanes: std::marker::PhantomData,
        }
    }

    /// Vector i (i < L).
    #[inline(always)]
    unsafe fn get(&self, i: usize) -> (V, V) {
        (
            V::read(self.re.add(i * V::WIDTH)),
            V::read(self.im.add(i * V::WIDTH)),
        )
    }

    /// Vector i (i < L) = `x`.
    #[inline(always)]
    unsafe fn put(&self, i: usize, x: (V, V)) {
        x.0.write(self.re.add(i * V::WIDTH));
        x.1.write(self.im.add(i * V::WIDTH));
    }
}

/// The 4-point DFT (forward) of four vectors of complex values.
#[inline(always)]
unsafe fn dft4<V: Lanes>([x0, x1, x2, x3]: [(V, V); 4]) -> [(V, V); 4] {
    let (a, b, c, d) = (add(x0, x2), sub(x0, x2), add(x1, x3), sub(x1, x3));
    // b ∓ i d.
    let minus_id = (b.0.add(d.1), b.1.sub(d.0));
    let plus_id = (b.0.sub(d.1), b.1.add(d.0));
    [add(a, c), minus_id, sub(a, c), plus_id]
}

/// a + b of two vectors of complex values.
#[inline(always)]
unsafe fn add<V: Lanes>(a: (V, V), b: (V, V)) -> (V, V) {
    (a.0.add(b.0), a.1.add(b.1))
}

/// a − b of two vectors of complex values.
#[inline(always)]
unsafe fn sub<V: Lanes>(a: (V, V), b: (V, V)) -> (V, V) {
    (a.0.sub(b.0), a.1.sub(b.1))
}

/// The complex product a · b of two vectors of complex values.
#[inline(always)]
unsafe fn times<V: Lanes>((a_re, a_im): (V, V), (b_re, b_im): (V, V)) -> (V, V) {
    (
        a_re.mul(b_re).neg_mul_add(a_im, b_im),
        a_re.mul(b_im).mul_add(a_im, b_re),
    )
}

/// The smallest primitive root of the prime `p`.
fn primitive_root(p: usize) -> usize {
    let primes: Vec<usize> = prime_powers(p - 1)
        .into_iter()
        .map(smallest_prime)
        .collect();
    (2..p)
        .find(|&g| primes.iter().all(|&f| power_mod(g, (p - 1) / f, p) != 1))
        .expect("a prime has a primitive root")
}

/// base^exp mod m.
fn power_mod(base: usize, mut exp: usize, m: usize) -> usize {
    let (mut result, mut b) = (1usize, base % m);
    while exp > 0 {
        if exp & 1 == 1 {
            result = result * b % m;
        }
        b = b * b % m;
        exp >>= 1;
    }
    result
}

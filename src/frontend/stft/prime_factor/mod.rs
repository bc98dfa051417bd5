//! Prime-factor (Good–Thomas) FFT for odd lengths made of coprime factors, such as the
//! 819 = 9 · 7 · 13 samples of a 200 ms window at 4096 Hz, or 3277 = 29 · 113 at 16384 Hz.
//!
//! With N = r₀ · r₁ ⋯ r_{S−1}, the factors pairwise coprime, input index
//! j = Σ i_a · N / r_a (mod N) and output index k ≡ K_a (mod r_a) for every a (the Chinese
//! remainder theorem), e^{−2πi jk/N} = Π_a e^{−2πi i_a K_a / r_a}: the DFT of N is an
//! S-dimensional DFT of sizes r_a with no twiddle factors between the stages.
//!
//! The S-dimensional array is kept row-major (axis S−1 innermost, padded to a multiple of
//! [`PAD`] positions). One pass windows the frames and permutes them into it; then each stage
//! computes the r-point DFTs of all N / r lines along one axis, eight lines side by side in the
//! lanes of an AVX-512 register (the direct sum, halved by pairing x_j with x_{r−j}):
//! - every stage but the last runs in place, its lanes along the contiguous inner axes (whole
//!   vectors, thanks to the padding);
//! - the last stage (the innermost axis) transposes eight lines into the lanes in registers and
//!   scatters its outputs straight to their bins (the output permutation is a scatter anyway);
//!   for a pair of real frames on AVX-512 it takes each line with its mirror line and writes
//!   the two frames' powers instead ([`pair_powers`]).
//!
//! Factors up to 13 ([`FACTORS`]) hold a line in registers ([`stages`]); larger ones, primes
//! above 13 (rustfft's slow lengths), run from memory ([`wide`]): by the direct sum, or by
//! Rader's algorithm from [`RADER_MIN`] on ([`rader`]).
//!
//! rustfft's mixed-radix plan of 819 points runs its 13-point butterflies one at a time in
//! scalar code, half of its time: this transform takes 1.6 µs against its 2.2 (windowing
//! included, one core of the AVX-512 machine of the README). With four AVX2 lanes it was no
//! faster than rustfft, so only AVX-512 CPUs use it ([`super::tables::shared_prime_factor`]);
//! the plain `f64` lanes are the portable reference its tests run on any CPU.

use rustfft::num_complex::Complex;

mod lanes;
mod pair_powers;
mod rader;
mod stages;
mod wide;

use crate::frontend::simd::Isa;
use lanes::Lanes;
pub(super) use pair_powers::HalfPowerTables;
use pair_powers::PairPowerPlan;
use wide::WideScratch;

/// The factors (prime powers) a stage holds in registers ([`stages`]).
const FACTORS: [usize; 6] = [3, 5, 7, 9, 11, 13];

/// The largest factor a [`wide`] stage takes: a prime power of a prime above 13 (rustfft's plans
/// of such factors are its slow ones). 257 covers the 200 ms windows of the power-of-two rates up
/// to 131072 Hz (3 · 17 · 257: 63 µs a frame pair by Rader's, against rustfft's 137); larger
/// factors were not measured and stay with rustfft.
const WIDE_MAX: usize = 257;

/// The innermost axis is padded to a multiple of this many positions (eight `f64` fill one
/// AVX-512 register).
const PAD: usize = 8;

/// One stage: the r-point DFTs along one axis.
#[derive(Debug)]
struct Stage {
    r: usize,
    /// cos(2π jk / r) for k, j = 1 … (r−1)/2, row k−1 (the register kernels' stages only).
    cos: Vec<f64>,
    /// sin(2π jk / r), laid out like `cos`.
    sin: Vec<f64>,
    /// The product of the factors before this axis, and of those after it (its stride).
    outer: usize,
    inner: usize,
    /// A wide factor's tables as [`wide`] reads them (empty for the others and Rader's).
    blocked: Vec<f64>,
    /// A wide prime from [`RADER_MIN`] on, where Rader's plan applies.
    rader: Option<Box<rader::Rader>>,
}

/// The smallest wide prime taken by Rader's algorithm ([`rader`]) instead of the direct sum
/// (one core of the README's AVX-512 machine, a frame pair each: 3 · 17 · 257 63 against 98 µs,
/// 29 · 113 15.7 against 16.5; with 17, 29, 41, 73 or 89 by Rader's the lengths tried were
/// 1–13 % slower, with 97 0–9 % faster).
const RADER_MIN: usize = 100;

/// The shortest length given a wide stage ([`PrimeFactorFft::expected_faster`]): below it
/// rustfft's plans were as fast or faster (one core of the AVX-512 machine of the README, a frame
/// pair each: 51, 95, 205, 255 and 345 points 1.1–3× slower through the wide stages; 287, 301,
/// 323 and every length tried from 357 to 16385 faster, by 1.1–2×).
const WIDE_MIN_POINTS: usize = 350;

/// A planned prime-factor FFT of one odd length (forward, unnormalised, as rustfft's).
#[derive(Debug)]
pub(super) struct PrimeFactorFft {
    n: usize,
    /// Positions of the padded array the stages run on.
    positions: usize,
    stages: Vec<Stage>,
    /// For each input index j < N, its position in the padded array. The other positions are
    /// padding: lines of their own in every stage but the last, which never reads them, so
    /// whatever they hold never reaches a bin.
    position_of: Vec<u32>,
    /// Last stage: for its line L and bin k, at `L · r_{S−1} + k`, the output index.
    scatter: Vec<u32>,
    /// A frame pair's powers from the last stage ([`pair_powers`]).
    pair_powers: Option<PairPowerPlan>,
}

/// The input of a transform: one or two real frames, windowed (zero beyond the frames: the
/// zero padding).
pub(super) struct FramePair<'a> {
    /// The frame in the real part.
    pub a: &'a [f64],
    /// The frame in the imaginary part (none: zero), at least as long as `a`'s windowed part.
    pub b: Option<&'a [f64]>,
    /// The window; the frames are windowed up to the shorter of `a` and this.
    pub window: &'a [f64],
}

/// The split real and imaginary parts the stages run on, and the wide stages' scratch (one set
/// per thread).
#[derive(Default)]
pub(super) struct SplitBuffer {
    re: Vec<f64>,
    im: Vec<f64>,
    wide: WideScratch,
}

impl PrimeFactorFft {
    /// The plan for `n` points, or `None` when `n` is even, is a single prime power (no second
    /// axis to take the lanes from), or has a prime-power factor that is neither one of
    /// [`FACTORS`] nor a power of a prime above 13 up to [`WIDE_MAX`].
    pub(super) fn new(n: usize) -> Option<PrimeFactorFft> {
        Self::with_rader_from(n, RADER_MIN)
    }

    /// As [`PrimeFactorFft::new`], the wide primes from `rader_min` on by Rader's algorithm
    /// (where it applies), the others by the direct sum.
    fn with_rader_from(n: usize, rader_min: usize) -> Option<PrimeFactorFft> {
        if n < 15 || n.is_multiple_of(2) || n > u32::MAX as usize / 2 {
            return None;
        }
        let mut factors = prime_powers(n);
        let takes = |f: usize| FACTORS.contains(&f) || (smallest_prime(f) > 13 && f <= WIDE_MAX);
        if factors.len() < 2 || !factors.iter().all(|&f| takes(f)) {
            return None;
        }
        // The innermost axis is padded to a multiple of PAD positions, so that every line of
        // the other stages is a whole number of vectors: it takes the factor that wastes the
        // least (7 of 8), the others go largest first.
        let waste = |r: usize| (r.next_multiple_of(PAD) - r) as f64 / r as f64;
        let last = factors
            .iter()
            .copied()
            .min_by(|&a, &b| waste(a).total_cmp(&waste(b)))
            .expect("two factors");
        factors.retain(|&r| r != last);
        factors.sort_unstable_by(|a, b| b.cmp(a));
        factors.push(last);
        let (axes, pad) = (factors.len(), last.next_multiple_of(PAD));
        // Row-major strides: position p = Σ i_a · stride_a, the innermost axis padded.
        let mut strides = vec![1; axes];
        strides[axes - 2] = pad;
        for a in (0..axes - 2).rev() {
            strides[a] = strides[a + 1] * factors[a + 1];
        }
        let digit = |p: usize, a: usize| {
            if a == axes - 1 {
                p % pad
            } else {
                p / strides[a] % factors[a]
            }
        };
        let mut outer = 1;
        let stages = factors
            .iter()
            .zip(&strides)
            .map(|(&r, &inner)| {
                let stage = Stage::new(r, outer, inner, rader_min);
                outer *= r;
                stage
            })
            .collect();
        // Position p (not padding) holds input index Σ i_a · N / r_a (mod N).
        let positions = strides[0] * factors[0];
        let mut position_of = vec![0u32; n];
        for p in (0..positions).filter(|&p| digit(p, axes - 1) < last) {
            let j: usize = (0..axes).map(|a| digit(p, a) * (n / factors[a])).sum();
            position_of[j % n] = p as u32;
        }
        // Last stage: output bin k (k ≡ K_a mod r_a) ends at Σ K_a · stride_a, which is element
        // p mod pad of line p / pad.
        let mut scatter = vec![0u32; n];
        for k in 0..n {
            let p: usize = (0..axes).map(|a| k % factors[a] * strides[a]).sum();
            scatter[p / pad * last + p % pad] = k as u32;
        }
        let pair_powers = PairPowerPlan::new(n, last, n / last, &scatter);
        Some(PrimeFactorFft {
            n,
            positions,
            stages,
            position_of,
            scatter,
            pair_powers,
        })
    }

    /// Points of the transform.
    pub(super) fn len(&self) -> usize {
        self.n
    }

    /// Whether this plan is expected to beat rustfft's on an AVX-512 CPU (one core of the
    /// README's machine, a frame pair each): with the register kernels only, always (819: 1.6
    /// against 2.2 µs); with a wide factor, from [`WIDE_MIN_POINTS`] points on, and only if the
    /// innermost axis, when wide, has a vector of lines or more (3 · 193: 3 lines in 8 lanes,
    /// 5.9 against 3.0 µs; 5 · 193 5.6 against 5.2).
    pub(super) fn expected_faster(&self) -> bool {
        let wide = |stage: &Stage| !FACTORS.contains(&stage.r);
        let Some(last) = self.stages.last() else {
            return false;
        };
        !self.stages.iter().any(wide)
            || (self.n >= WIDE_MIN_POINTS && (!wide(last) || self.n / last.r >= PAD))
    }

    /// `spectrum` (resized to N) = the DFT of z = a + i b, both windowed ([`FramePair`]).
    pub(super) fn transform(
        &self,
        isa: Isa,
        input: &FramePair<'_>,
        work: &mut SplitBuffer,
        spectrum: &mut Vec<Complex<f64>>,
    ) {
        self.fit(work, spectrum);
        permute_windowed(&self.position_of, input, &mut work.re, &mut work.im);
        self.run_stages(isa, work, spectrum);
    }

    /// `power_a`, `power_b` (N/2 + 1 bins each) = the power spectra of the two windowed frames
    /// of `input` (`b` given), as [`super::kernels::unpack_pair_powers`] gives them from
    /// [`PrimeFactorFft::transform`]'s spectrum, bit for bit: on AVX-512 straight from the last
    /// stage ([`pair_powers`]), elsewhere by those two steps (`spectrum` then holds the DFT).
    pub(super) fn pair_powers(
        &self,
        isa: Isa,
        input: &FramePair<'_>,
        work: &mut SplitBuffer,
        spectrum: &mut Vec<Complex<f64>>,
        (power_a, power_b): (&mut [f64], &mut [f64]),
    ) {
        let bins = self.n / 2 + 1;
        let (power_a, power_b) = (&mut power_a[..bins], &mut power_b[..bins]);
        match (isa, &self.pair_powers, input.b) {
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx512, Some(plan), Some(_)) => {
                self.fit(work, spectrum);
                permute_windowed(&self.position_of, input, &mut work.re, &mut work.im);
                // SAFETY: `Isa::detect` found AVX-512F on this CPU.
                unsafe { self.pair_powers_avx512(work, plan, power_a, power_b) }
            }
            _ => {
                self.transform(isa, input, work, spectrum);
                super::kernels::unpack_pair_powers(isa, spectrum, power_a, power_b);
            }
        }
    }

    /// The stages in AVX-512 lanes, the last one straight to the pair's powers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma")]
    unsafe fn pair_powers_avx512(
        &self,
        work: &mut SplitBuffer,
        plan: &PairPowerPlan,
        power_a: &mut [f64],
        power_b: &mut [f64],
    ) {
        let out = Output::PairPowers(plan, power_a, power_b);
        self.stages::<lanes::F64x8>(work, out)
    }

    /// The tables that let [`PrimeFactorFft::half_powers`] take the powers of a real frame of
    /// 2N points straight from the last stage, for post-processing `twiddles` (realfft's, halved);
    /// `None` where the mirrors do not pair.
    pub(super) fn half_power_tables(&self, twiddles: &[Complex<f64>]) -> Option<HalfPowerTables> {
        let last = self.stages.last()?;
        self.pair_powers
            .as_ref()?
            .half_tables(self.n, last.r, twiddles)
    }

    /// `power` (N + 1 bins) = the power spectrum of the real frame of 2N points `x · window`, as
    /// [`PrimeFactorFft::transform_interleaved`] and [`super::kernels::half_spectrum_powers`]
    /// give it, bit for bit: on AVX-512 with `tables` straight from the last stage (no
    /// spectrum written and read back), elsewhere by those two steps.
    pub(super) fn half_powers(
        &self,
        isa: Isa,
        (x, window): (&[f64], &[f64]),
        (tables, twiddles): (Option<&HalfPowerTables>, &[Complex<f64>]),
        work: &mut SplitBuffer,
        spectrum: &mut Vec<Complex<f64>>,
        power: &mut [f64],
    ) {
        let power = &mut power[..self.n + 1];
        match (isa, &self.pair_powers, tables) {
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx512, Some(plan), Some(tables)) => {
                self.fit(work, spectrum);
                permute_interleaved(&self.position_of, (x, window), &mut work.re, &mut work.im);
                // SAFETY: `Isa::detect` found AVX-512F on this CPU.
                unsafe { self.half_powers_avx512(work, (plan, tables), power) }
            }
            _ => {
                self.transform_interleaved(isa, (x, window), work, spectrum);
                super::kernels::half_spectrum_powers(isa, spectrum, twiddles, power);
            }
        }
    }

    /// The stages in AVX-512 lanes, the last one straight to the real frame's powers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma")]
    unsafe fn half_powers_avx512(
        &self,
        work: &mut SplitBuffer,
        (plan, tables): (&PairPowerPlan, &HalfPowerTables),
        power: &mut [f64],
    ) {
        self.stages::<lanes::F64x8>(work, Output::HalfPowers(plan, tables, power))
    }

    /// `spectrum` (resized to N) = the DFT of z_m = x_{2m} w_{2m} + i x_{2m+1} w_{2m+1}, zero
    /// past the shorter of `x` and `window`: the complex FFT of half the length that an even
    /// real transform of 2N points is made of (see [`super::transform`]).
    pub(super) fn transform_interleaved(
        &self,
        isa: Isa,
        (x, window): (&[f64], &[f64]),
        work: &mut SplitBuffer,
        spectrum: &mut Vec<Complex<f64>>,
    ) {
        self.fit(work, spectrum);
        permute_interleaved(&self.position_of, (x, window), &mut work.re, &mut work.im);
        self.run_stages(isa, work, spectrum);
    }

    /// Sizes the working arrays and the spectrum for this length.
    fn fit(&self, work: &mut SplitBuffer, spectrum: &mut Vec<Complex<f64>>) {
        work.re.resize(self.positions, 0.0);
        work.im.resize(self.positions, 0.0);
        spectrum.resize(self.n, Complex::new(0.0, 0.0));
    }

    /// The stages on the permuted input in `work`, on the CPU's best lanes.
    fn run_stages(&self, isa: Isa, work: &mut SplitBuffer, spectrum: &mut [Complex<f64>]) {
        match isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::detect` found AVX-512F on this CPU.
            Isa::Avx512 => unsafe { self.transform_avx512(work, spectrum) },
            // SAFETY: `f64` lanes need no instruction set beyond the baseline.
            _ => unsafe { self.stages::<f64>(work, Output::Spectrum(spectrum)) },
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma")]
    unsafe fn transform_avx512(&self, work: &mut SplitBuffer, spectrum: &mut [Complex<f64>]) {
        self.stages::<lanes::F64x8>(work, Output::Spectrum(spectrum))
    }

    /// The stages in `V`'s lanes (inlined into each instruction set's copy).
    #[inline(always)]
    unsafe fn stages<V: Lanes>(&self, work: &mut SplitBuffer, output: Output<'_>) {
        let SplitBuffer {
            re,
            im,
            wide: scratch,
        } = work;
        let (last, others) = self.stages.split_last().expect("two stages or more");
        macro_rules! by_factor {
            ($stage:expr, $f:ident ( $($arg:expr),* )) => {
                match $stage.r {
                    3 => stages::$f::<V, 3, 1>($stage, $($arg),*),
                    5 => stages::$f::<V, 5, 2>($stage, $($arg),*),
                    7 => stages::$f::<V, 7, 3>($stage, $($arg),*),
                    9 => stages::$f::<V, 9, 4>($stage, $($arg),*),
                    11 => stages::$f::<V, 11, 5>($stage, $($arg),*),
                    13 => stages::$f::<V, 13, 6>($stage, $($arg),*),
                    // Planning admits only these and the wide ones.
                    _ => wide::$f::<V>($stage, $($arg),*, scratch),
                }
            };
        }
        for stage in others {
            by_factor!(stage, in_place(re, im));
        }
        match output {
            Output::Spectrum(spectrum) => by_factor!(last, last(re, im, &self.scatter, spectrum)),
            Output::PairPowers(plan, a, b) => {
                let v = (&re[..], &im[..]);
                match last.r {
                    3 => pair_powers::last::<V, 3, 1>(last, v, plan, a, b),
                    5 => pair_powers::last::<V, 5, 2>(last, v, plan, a, b),
                    7 => pair_powers::last::<V, 7, 3>(last, v, plan, a, b),
                    9 => pair_powers::last::<V, 9, 4>(last, v, plan, a, b),
                    11 => pair_powers::last::<V, 11, 5>(last, v, plan, a, b),
                    13 => pair_powers::last::<V, 13, 6>(last, v, plan, a, b),
                    _ => wide::last_pair_powers::<V>(last, v, plan, (a, b), scratch),
                }
            }
            Output::HalfPowers(plan, tables, power) => {
                let v = (&re[..], &im[..]);
                let plan = (plan, tables);
                match last.r {
                    3 => pair_powers::last_half::<V, 3, 1>(last, v, plan, power),
                    5 => pair_powers::last_half::<V, 5, 2>(last, v, plan, power),
                    7 => pair_powers::last_half::<V, 7, 3>(last, v, plan, power),
                    9 => pair_powers::last_half::<V, 9, 4>(last, v, plan, power),
                    11 => pair_powers::last_half::<V, 11, 5>(last, v, plan, power),
                    13 => pair_powers::last_half::<V, 13, 6>(last, v, plan, power),
                    _ => wide::last_half_powers::<V>(last, v, plan, power, scratch),
                }
            }
        }
    }
}

/// What the last stage makes: the spectrum, a frame pair's two power spectra, or the power
/// spectrum of the real frame of twice the length whose sample pairs were transformed.
enum Output<'a> {
    Spectrum(&'a mut [Complex<f64>]),
    PairPowers(&'a PairPowerPlan, &'a mut [f64], &'a mut [f64]),
    HalfPowers(&'a PairPowerPlan, &'a HalfPowerTables, &'a mut [f64]),
}

/// The windowed frames, value j to `re[position_of[j]]`, `im[position_of[j]]` (zero at or
/// past the frames' end): windowing and the input permutation in one pass, reading the frames
/// in order (they stream into the cache) and writing out of order (the array is in the cache
/// already). Vector gathers, and reading out of order, were slower. Not inlined: inside the
/// stages' function its pointers were spilled and reloaded for every value.
#[inline(never)]
fn permute_windowed(position_of: &[u32], input: &FramePair<'_>, re: &mut [f64], im: &mut [f64]) {
    let len = input.a.len().min(input.window.len()).min(position_of.len());
    let (a, window) = (&input.a[..len], &input.window[..len]);
    let (head, tail) = position_of.split_at(len);
    match input.b {
        Some(b) => {
            for (((&p, &x), &y), &w) in head.iter().zip(a).zip(&b[..len]).zip(window) {
                (re[p as usize], im[p as usize]) = (x * w, y * w);
            }
        }
        None => {
            for ((&p, &x), &w) in head.iter().zip(a).zip(window) {
                (re[p as usize], im[p as usize]) = (x * w, 0.0);
            }
        }
    }
    for &p in tail {
        (re[p as usize], im[p as usize]) = (0.0, 0.0);
    }
}

/// The pairs of an even frame as complex values, value m (x_{2m} w_{2m}, x_{2m+1} w_{2m+1}) to
/// `re[position_of[m]]`, `im[position_of[m]]`, zero past the frame's end; as
/// [`permute_windowed`].
#[inline(never)]
fn permute_interleaved(
    position_of: &[u32],
    (x, window): (&[f64], &[f64]),
    re: &mut [f64],
    im: &mut [f64],
) {
    let len = x.len().min(window.len()).min(2 * position_of.len());
    let (x, window) = (&x[..len], &window[..len]);
    let (head, tail) = position_of.split_at(len / 2);
    for ((&p, x), w) in head
        .iter()
        .zip(x.chunks_exact(2))
        .zip(window.chunks_exact(2))
    {
        (re[p as usize], im[p as usize]) = (x[0] * w[0], x[1] * w[1]);
    }
    for (i, &p) in tail.iter().enumerate() {
        let j = 2 * (len / 2 + i);
        re[p as usize] = if j < len { x[j] * window[j] } else { 0.0 };
        im[p as usize] = 0.0;
    }
}

/// The smallest prime factor of `n` ≥ 2.
fn smallest_prime(n: usize) -> usize {
    (2..)
        .find(|p| n.is_multiple_of(*p))
        .expect("n ≥ 2 has a prime factor")
}

/// The prime powers whose product is `n`, smallest prime first.
fn prime_powers(mut n: usize) -> Vec<usize> {
    let mut out = Vec::new();
    let mut p = 2;
    while p * p <= n {
        if n.is_multiple_of(p) {
            let mut q = 1;
            while n.is_multiple_of(p) {
                n /= p;
                q *= p;
            }
            out.push(q);
        }
        p += 1;
    }
    if n > 1 {
        out.push(n);
    }
    out
}

impl Stage {
    /// The stage of factor r (Rader's for a wide prime from `rader_min` on).
    fn new(r: usize, outer: usize, inner: usize, rader_min: usize) -> Stage {
        let h = (r - 1) / 2;
        let angle =
            |j: usize, k: usize| 2.0 * std::f64::consts::PI * ((j * k) % r) as f64 / r as f64;
        let table = |f: fn(f64) -> f64| {
            (1..=h)
                .flat_map(|k| (1..=h).map(move |j| f(angle(j, k))))
                .collect::<Vec<f64>>()
        };
        let rader = match FACTORS.contains(&r) || r < rader_min {
            true => None,
            false => rader::Rader::new(r).map(Box::new),
        };
        // Each kind of stage keeps the tables it reads, no more (for 257, 2 · 128² sines and
        // cosines would be most of a plan's making).
        let (mut cos, mut sin, mut blocked) = (Vec::new(), Vec::new(), Vec::new());
        if rader.is_none() {
            (cos, sin) = (table(f64::cos), table(f64::sin));
            if !FACTORS.contains(&r) {
                blocked = wide::blocked_table(h, &cos, &sin);
                (cos, sin) = (Vec::new(), Vec::new());
            }
        }
        Stage {
            r,
            cos,
            sin,
            outer,
            inner,
            blocked,
            rader,
        }
    }
}

#[cfg(test)]
mod tests;

//! What the filter-bank kernels share: bands laid out in lanes of `[f64; L]` that one CPU
//! vector instruction advances together, the arithmetic on such lanes, and the instruction set
//! chosen once at run time (x86-64: AVX2+FMA or AVX-512 when the CPU has them).
//!
//! The helpers are `#[inline(always)]` so that inside a function compiled with
//! `#[target_feature(enable = "avx2,fma")]` each one becomes one vector instruction.

/// `L` bands side by side, one per lane.
pub(crate) type Lanes<const L: usize> = [f64; L];

/// Every lane `x`.
#[inline(always)]
pub(crate) fn splat<const L: usize>(x: f64) -> Lanes<L> {
    [x; L]
}

/// a·b lane by lane.
#[inline(always)]
pub(crate) fn mul<const L: usize>(a: Lanes<L>, b: Lanes<L>) -> Lanes<L> {
    std::array::from_fn(|l| a[l] * b[l])
}

/// a·b + c, fused when `FMA` (only inside functions compiled with the `fma` feature).
#[inline(always)]
pub(crate) fn madd<const FMA: bool, const L: usize>(
    a: Lanes<L>,
    b: Lanes<L>,
    c: Lanes<L>,
) -> Lanes<L> {
    if FMA {
        std::array::from_fn(|l| a[l].mul_add(b[l], c[l]))
    } else {
        std::array::from_fn(|l| a[l] * b[l] + c[l])
    }
}

/// c − a·b, fused when `FMA`.
#[inline(always)]
pub(crate) fn nmadd<const FMA: bool, const L: usize>(
    a: Lanes<L>,
    b: Lanes<L>,
    c: Lanes<L>,
) -> Lanes<L> {
    if FMA {
        std::array::from_fn(|l| (-a[l]).mul_add(b[l], c[l]))
    } else {
        std::array::from_fn(|l| c[l] - a[l] * b[l])
    }
}

/// a + b lane by lane.
#[inline(always)]
pub(crate) fn add<const L: usize>(a: Lanes<L>, b: Lanes<L>) -> Lanes<L> {
    std::array::from_fn(|l| a[l] + b[l])
}

/// Bands per wide group: 8 f64 lanes fill one AVX-512 register (used with AVX-512 only).
pub(crate) const WIDE: usize = 8;
/// Bands per narrow group: 4 f64 lanes fill one AVX2 register. With AVX-512 a narrow group
/// takes a remainder of up to 4 bands (10 bands cost 12 lanes, not 16); otherwise all groups
/// are narrow (wide ones would not fit in the 16 AVX2 registers).
pub(crate) const NARROW: usize = 4;

/// How a bank lays `bands` out in lanes on `isa`: `(wide, narrow)` group counts, the wide
/// groups ([`WIDE`] lanes) first. Fewer than [`WIDE`] lanes are left empty in all.
pub(crate) fn group_counts(isa: Isa, bands: usize) -> (usize, usize) {
    #[cfg(target_arch = "x86_64")]
    let (wide, rest) = match (isa, bands % WIDE) {
        (Isa::Avx512, rem) if rem > NARROW => (bands.div_ceil(WIDE), 0),
        (Isa::Avx512, rem) => (bands / WIDE, rem),
        _ => (0, bands),
    };
    #[cfg(not(target_arch = "x86_64"))]
    let (wide, rest) = {
        let _ = isa;
        (0, bands)
    };
    (wide, rest.div_ceil(NARROW))
}

/// Which instruction set the kernel runs with (detected once).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Isa {
    /// Portable code (fused multiply-add on aarch64 only, where it is always present).
    Generic,
    /// x86-64 AVX2 with FMA.
    #[cfg(target_arch = "x86_64")]
    Avx2Fma,
    /// x86-64 AVX-512F with FMA.
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

impl Isa {
    /// The best instruction set of this CPU, capped by the environment variable
    /// `DAMPSCOPE_SIMD` (`generic` or `avx2`; for benchmarks and bit-reproducible runs across
    /// machines). Found once per process (reading the environment and asking the CPU each time
    /// cost more than the small loops dispatched per call).
    pub(crate) fn detect() -> Isa {
        static ISA: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
        *ISA.get_or_init(|| {
            let cap = std::env::var("DAMPSCOPE_SIMD").unwrap_or_default();
            Isa::available()
                .into_iter()
                .rev()
                .find(|isa| match cap.as_str() {
                    "generic" => *isa == Isa::Generic,
                    #[cfg(target_arch = "x86_64")]
                    "avx2" => *isa != Isa::Avx512,
                    _ => true,
                })
                .unwrap_or(Isa::Generic)
        })
    }

    /// The instruction sets this CPU can run, from the most portable.
    pub(crate) fn available() -> Vec<Isa> {
        #[allow(unused_mut)]
        let mut list = vec![Isa::Generic];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("fma") {
                if std::arch::is_x86_feature_detected!("avx2") {
                    list.push(Isa::Avx2Fma);
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    list.push(Isa::Avx512);
                }
            }
        }
        list
    }
}

/// Runs `f` compiled for this CPU's widest vectors ([`Isa::detect`]): a plain loop over
/// `f64`s inside it is auto-vectorised with AVX-512 or AVX2 instead of the two-value SSE2 of
/// portable x86-64 code (where a NaN or finiteness test on 64-bit values even takes integer
/// shuffles). `f` is inlined into the feature-enabled copy; same arithmetic, same results.
#[inline(always)]
pub(crate) fn in_wide_vectors<R>(f: impl FnOnce() -> R) -> R {
    match Isa::detect() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX-512F on this CPU.
        Isa::Avx512 => unsafe { run_avx512(f) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 and FMA on this CPU.
        Isa::Avx2Fma => unsafe { run_avx2(f) },
        Isa::Generic => f(),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn run_avx512<R>(f: impl FnOnce() -> R) -> R {
    f()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn run_avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}

//! One CPU vector of `f64`, one line of the transform per lane: the few operations the stages
//! need, for AVX-512 (8 lanes) and plain `f64` (1 lane: the portable reference the tests run
//! everywhere).
//!
//! Written with the intrinsics rather than left to the compiler: on `[f64; 8]` arrays it split
//! the AVX-512 work into 256-bit halves and spilled the halves to the stack. (Four AVX2 lanes
//! were tried too: 2.24 µs for 819 points, no faster than rustfft's plan, so AVX2 machines keep
//! rustfft.)

/// A vector of `WIDTH` lines. Every method is `unsafe`: the CPU must have the instruction set of
/// the implementation (the callers run inside a function compiled for it).
pub(super) trait Lanes: Copy {
    /// Lines per vector.
    const WIDTH: usize;
    /// All lanes `x`.
    unsafe fn splat(x: f64) -> Self;
    /// `v[at .. at + WIDTH]`.
    unsafe fn load(v: &[f64], at: usize) -> Self;
    /// Lane l = `f(l)`.
    unsafe fn from_fn(f: impl Fn(usize) -> f64) -> Self;
    /// Eight values of each of `WIDTH` lines, line l at `v[starts[l] + chunk ..]`, as eight
    /// vectors: vector j holds value j of every line (a transpose in registers).
    unsafe fn load_rows(v: &[f64], starts: &[usize; 8], chunk: usize) -> [Self; 8];
    /// `v[at .. at + WIDTH]` = the lanes.
    unsafe fn store(self, v: &mut [f64], at: usize);
    /// The lanes, in the first `WIDTH` places.
    unsafe fn to_array(self) -> [f64; 8];
    /// self + b.
    unsafe fn add(self, b: Self) -> Self;
    /// self − b.
    unsafe fn sub(self, b: Self) -> Self;
    /// c · x + self (fused where the instruction set has it).
    unsafe fn mul_add(self, c: Self, x: Self) -> Self;
    /// The `WIDTH` values at `p`.
    unsafe fn read(p: *const f64) -> Self;
    /// The lanes to the `WIDTH` values at `p`.
    unsafe fn write(self, p: *mut f64);
    /// self · b.
    unsafe fn mul(self, b: Self) -> Self;
    /// self − c · x (fused where the instruction set has it).
    unsafe fn neg_mul_add(self, c: Self, x: Self) -> Self;
    /// Lanes l and l + `WIDTH`/2 exchanged (one lane: itself).
    unsafe fn swap_halves(self) -> Self;
}

/// Portable code: one line at a time, multiply and add separate.
impl Lanes for f64 {
    const WIDTH: usize = 1;
    #[inline(always)]
    unsafe fn splat(x: f64) -> Self {
        x
    }
    #[inline(always)]
    unsafe fn load(v: &[f64], at: usize) -> Self {
        v[at]
    }
    #[inline(always)]
    unsafe fn from_fn(f: impl Fn(usize) -> f64) -> Self {
        f(0)
    }
    #[inline(always)]
    unsafe fn load_rows(v: &[f64], starts: &[usize; 8], chunk: usize) -> [Self; 8] {
        let at = starts[0] + chunk;
        v[at..at + 8].try_into().expect("eight values")
    }
    #[inline(always)]
    unsafe fn store(self, v: &mut [f64], at: usize) {
        v[at] = self;
    }
    #[inline(always)]
    unsafe fn to_array(self) -> [f64; 8] {
        [self, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    }
    #[inline(always)]
    unsafe fn add(self, b: Self) -> Self {
        self + b
    }
    #[inline(always)]
    unsafe fn sub(self, b: Self) -> Self {
        self - b
    }
    #[inline(always)]
    unsafe fn mul_add(self, c: Self, x: Self) -> Self {
        c * x + self
    }
    #[inline(always)]
    unsafe fn read(p: *const f64) -> Self {
        *p
    }
    #[inline(always)]
    unsafe fn write(self, p: *mut f64) {
        *p = self
    }
    #[inline(always)]
    unsafe fn mul(self, b: Self) -> Self {
        self * b
    }
    #[inline(always)]
    unsafe fn neg_mul_add(self, c: Self, x: Self) -> Self {
        self - c * x
    }
    #[inline(always)]
    unsafe fn swap_halves(self) -> Self {
        self
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::Lanes;
    use std::arch::x86_64::*;

    /// AVX-512F: eight lines.
    #[derive(Clone, Copy)]
    pub(in super::super) struct F64x8(__m512d);

    impl Lanes for F64x8 {
        const WIDTH: usize = 8;
        #[inline(always)]
        unsafe fn splat(x: f64) -> Self {
            F64x8(_mm512_set1_pd(x))
        }
        #[inline(always)]
        unsafe fn load(v: &[f64], at: usize) -> Self {
            F64x8(_mm512_loadu_pd(v[at..at + 8].as_ptr()))
        }
        #[inline(always)]
        unsafe fn from_fn(f: impl Fn(usize) -> f64) -> Self {
            F64x8(_mm512_setr_pd(
                f(0),
                f(1),
                f(2),
                f(3),
                f(4),
                f(5),
                f(6),
                f(7),
            ))
        }
        #[inline(always)]
        unsafe fn load_rows(v: &[f64], starts: &[usize; 8], chunk: usize) -> [Self; 8] {
            // No closures here: one not inlined would run the intrinsics as calls.
            let mut row = [_mm512_setzero_pd(); 8];
            for (row, &start) in row.iter_mut().zip(starts) {
                let at = start + chunk;
                *row = _mm512_loadu_pd(v[at..at + 8].as_ptr());
            }
            // Pairs of rows interleaved, then 128-bit lanes picked twice (an 8 × 8 transpose).
            let (t0, t1) = (
                _mm512_unpacklo_pd(row[0], row[1]),
                _mm512_unpackhi_pd(row[0], row[1]),
            );
            let (t2, t3) = (
                _mm512_unpacklo_pd(row[2], row[3]),
                _mm512_unpackhi_pd(row[2], row[3]),
            );
            let (t4, t5) = (
                _mm512_unpacklo_pd(row[4], row[5]),
                _mm512_unpackhi_pd(row[4], row[5]),
            );
            let (t6, t7) = (
                _mm512_unpacklo_pd(row[6], row[7]),
                _mm512_unpackhi_pd(row[6], row[7]),
            );
            // u0: values 0 and 4 of rows 0–3; u1: 1 and 5; u2: 2 and 6; u3: 3 and 7 (u4–u7:
            // rows 4–7).
            let u0 = _mm512_shuffle_f64x2::<0x88>(t0, t2);
            let u1 = _mm512_shuffle_f64x2::<0x88>(t1, t3);
            let u2 = _mm512_shuffle_f64x2::<0xdd>(t0, t2);
            let u3 = _mm512_shuffle_f64x2::<0xdd>(t1, t3);
            let u4 = _mm512_shuffle_f64x2::<0x88>(t4, t6);
            let u5 = _mm512_shuffle_f64x2::<0x88>(t5, t7);
            let u6 = _mm512_shuffle_f64x2::<0xdd>(t4, t6);
            let u7 = _mm512_shuffle_f64x2::<0xdd>(t5, t7);
            [
                F64x8(_mm512_shuffle_f64x2::<0x88>(u0, u4)),
                F64x8(_mm512_shuffle_f64x2::<0x88>(u1, u5)),
                F64x8(_mm512_shuffle_f64x2::<0x88>(u2, u6)),
                F64x8(_mm512_shuffle_f64x2::<0x88>(u3, u7)),
                F64x8(_mm512_shuffle_f64x2::<0xdd>(u0, u4)),
                F64x8(_mm512_shuffle_f64x2::<0xdd>(u1, u5)),
                F64x8(_mm512_shuffle_f64x2::<0xdd>(u2, u6)),
                F64x8(_mm512_shuffle_f64x2::<0xdd>(u3, u7)),
            ]
        }
        #[inline(always)]
        unsafe fn store(self, v: &mut [f64], at: usize) {
            _mm512_storeu_pd(v[at..at + 8].as_mut_ptr(), self.0)
        }
        #[inline(always)]
        unsafe fn to_array(self) -> [f64; 8] {
            let mut out = [0.0; 8];
            _mm512_storeu_pd(out.as_mut_ptr(), self.0);
            out
        }
        #[inline(always)]
        unsafe fn add(self, b: Self) -> Self {
            F64x8(_mm512_add_pd(self.0, b.0))
        }
        #[inline(always)]
        unsafe fn sub(self, b: Self) -> Self {
            F64x8(_mm512_sub_pd(self.0, b.0))
        }
        #[inline(always)]
        unsafe fn mul_add(self, c: Self, x: Self) -> Self {
            F64x8(_mm512_fmadd_pd(c.0, x.0, self.0))
        }
        #[inline(always)]
        unsafe fn read(p: *const f64) -> Self {
            F64x8(_mm512_loadu_pd(p))
        }
        #[inline(always)]
        unsafe fn write(self, p: *mut f64) {
            _mm512_storeu_pd(p, self.0)
        }
        #[inline(always)]
        unsafe fn mul(self, b: Self) -> Self {
            F64x8(_mm512_mul_pd(self.0, b.0))
        }
        #[inline(always)]
        unsafe fn neg_mul_add(self, c: Self, x: Self) -> Self {
            F64x8(_mm512_fnmadd_pd(c.0, x.0, self.0))
        }
        #[inline(always)]
        unsafe fn swap_halves(self) -> Self {
            F64x8(_mm512_shuffle_f64x2::<0b01_00_11_10>(self.0, self.0))
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) use x86::F64x8;

//! The wide groups' run over many frames with their state in AVX-512 registers: the frames are
//! taken inside the loop, where [`super::Kernel::filter_span`] and [`super::Kernel::take_frame`]
//! per frame (4 samples at 4096 Hz with the default 1 ms frames) loaded and stored a group's
//! whole state, and built each frame's rows on the stack, every time.
//!
//! Written with intrinsics: the same loop on the `[f64; 8]` lanes, once the frame take was
//! inside it, lost the compiler's vectorisation (48 kHz 177 → 265 ms). The operations are those
//! of [`super::Group::step`] and [`super::Group::take_sums`] with fused multiply-adds, in the
//! same order, so the frames are the same bits (tested against the spans and takes).

#![cfg(target_arch = "x86_64")]

use std::arch::x86_64::*;

use super::{FrameOut, Group, MAX_SECTIONS};
use crate::frontend::simd::WIDE;

/// A wide group's state in registers (`NS` sections).
struct State<const NS: usize> {
    rot_re: __m512d,
    rot_im: __m512d,
    c1: [__m512d; NS],
    c2: [__m512d; NS],
    osc_re: __m512d,
    osc_im: __m512d,
    y1r: [__m512d; NS],
    y2r: [__m512d; NS],
    y1i: [__m512d; NS],
    y2i: [__m512d; NS],
    pr: __m512d,
    pi: __m512d,
    sums: [__m512d; 6],
}

impl<const NS: usize> State<NS> {
    #[inline(always)]
    unsafe fn load(g: &Group<WIDE>) -> Self {
        let v = |a: &[f64; WIDE]| _mm512_loadu_pd(a.as_ptr());
        let each = |a: &[[f64; WIDE]; MAX_SECTIONS]| -> [__m512d; NS] {
            std::array::from_fn(|k| v(&a[k]))
        };
        State {
            rot_re: v(&g.rot_re),
            rot_im: v(&g.rot_im),
            c1: each(&g.c1),
            c2: each(&g.c2),
            osc_re: v(&g.osc_re),
            osc_im: v(&g.osc_im),
            y1r: each(&g.y1r),
            y2r: each(&g.y2r),
            y1i: each(&g.y1i),
            y2i: each(&g.y2i),
            pr: v(&g.pr),
            pi: v(&g.pi),
            sums: std::array::from_fn(|i| v(&g.sums[i])),
        }
    }

    #[inline(always)]
    unsafe fn store(&self, g: &mut Group<WIDE>) {
        let put = |a: &mut [f64; WIDE], x: __m512d| _mm512_storeu_pd(a.as_mut_ptr(), x);
        put(&mut g.osc_re, self.osc_re);
        put(&mut g.osc_im, self.osc_im);
        for k in 0..NS {
            put(&mut g.y1r[k], self.y1r[k]);
            put(&mut g.y2r[k], self.y2r[k]);
            put(&mut g.y1i[k], self.y1i[k]);
            put(&mut g.y2i[k], self.y2i[k]);
        }
        put(&mut g.pr, self.pr);
        put(&mut g.pi, self.pi);
        for (sum, &x) in g.sums.iter_mut().zip(&self.sums) {
            put(sum, x);
        }
    }

    /// One sample, accumulating: [`super::Group::step`] with fused multiply-adds.
    #[inline(always)]
    unsafe fn step(&mut self, x: f64) {
        let (c, s) = (self.osc_re, self.osc_im);
        let x = _mm512_set1_pd(x);
        let mut ur = _mm512_mul_pd(x, c);
        let mut ui = _mm512_mul_pd(x, s);
        self.osc_re = _mm512_fnmadd_pd(s, self.rot_im, _mm512_mul_pd(c, self.rot_re));
        self.osc_im = _mm512_fmadd_pd(s, self.rot_re, _mm512_mul_pd(c, self.rot_im));
        for k in 0..NS {
            let yr = _mm512_fmadd_pd(
                self.c1[k],
                self.y1r[k],
                _mm512_fmadd_pd(self.c2[k], self.y2r[k], ur),
            );
            let yi = _mm512_fmadd_pd(
                self.c1[k],
                self.y1i[k],
                _mm512_fmadd_pd(self.c2[k], self.y2i[k], ui),
            );
            self.y2r[k] = self.y1r[k];
            self.y1r[k] = yr;
            self.y2i[k] = self.y1i[k];
            self.y1i[k] = yi;
            ur = yr;
            ui = yi;
        }
        let a = &mut self.sums;
        a[0] = _mm512_fmadd_pd(ur, ur, a[0]);
        a[1] = _mm512_fmadd_pd(ui, ui, a[1]);
        a[2] = _mm512_fmadd_pd(ur, self.pr, a[2]);
        a[3] = _mm512_fmadd_pd(ui, self.pi, a[3]);
        a[4] = _mm512_fmadd_pd(ui, self.pr, a[4]);
        a[5] = _mm512_fmadd_pd(ur, self.pi, a[5]);
        self.pr = ur;
        self.pi = ui;
    }

    /// [`super::Group::take_sums`]: the frame's energy and lag product of the first `lanes`
    /// lanes scattered to `out` at `first + l · stride`, the sums cleared.
    #[inline(always)]
    unsafe fn take(
        &mut self,
        (lanes, index): (__mmask8, __m512i),
        hop: f64,
        out: &mut FrameOut<'_>,
        first: usize,
    ) {
        let s = &self.sums;
        let energy = _mm512_div_pd(
            _mm512_mul_pd(_mm512_set1_pd(2.0), _mm512_add_pd(s[0], s[1])),
            _mm512_set1_pd(hop),
        );
        let lag_re = _mm512_add_pd(s[2], s[3]);
        let lag_im = _mm512_sub_pd(s[4], s[5]);
        for (row, v) in [
            (&mut *out.energy, energy),
            (&mut *out.lag_re, lag_re),
            (&mut *out.lag_im, lag_im),
        ] {
            _mm512_mask_i64scatter_pd::<8>(row.as_mut_ptr().add(first), lanes, index, v);
        }
        self.sums = [_mm512_setzero_pd(); 6];
    }
}

/// Runs group `g` over `xs`, samples `start …` of the decay (backwards when `reversed`),
/// accumulating, and takes each frame completed on the way (frame k: samples k·hop … (k+1)·hop
/// − 1) to `out` at `first + k` for its first `bands` lanes: the operations, in their order, of
/// spans cut at every frame boundary with a take after each.
///
/// # Safety
/// The CPU must have AVX-512F and FMA.
#[target_feature(enable = "avx512f,fma")]
pub(super) unsafe fn run_frames<const NS: usize>(
    g: &mut Group<WIDE>,
    (xs, start): (&[f64], usize),
    reversed: bool,
    (bands, hop): (usize, usize),
    out: &mut FrameOut<'_>,
    first: usize,
) {
    let lanes = bands.min(WIDE);
    if lanes == 0 || xs.is_empty() {
        return;
    }
    // Every take of this span writes below `end` in each row (its frames end by the span's).
    let end = first + (lanes - 1) * out.stride + (start + xs.len() - 1) / hop;
    assert!(
        [out.energy.len(), out.lag_re.len(), out.lag_im.len()]
            .iter()
            .all(|&len| len > end),
        "frame rows too short for the span"
    );
    let offsets: [i64; WIDE] = std::array::from_fn(|l| (l * out.stride) as i64);
    let scatter = (
        ((1u16 << lanes) - 1) as __mmask8,
        _mm512_loadu_si512(offsets.as_ptr().cast()),
    );
    let hop_f = hop as f64;
    let mut state = State::<NS>::load(g);
    if reversed {
        let mut end = xs.len();
        while end > 0 {
            // The frame of the next sample down starts at `boundary`.
            let boundary = (start + end - 1) / hop * hop;
            let lo = boundary.max(start) - start;
            for &x in xs[lo..end].iter().rev() {
                state.step(x);
            }
            if boundary >= start {
                state.take(scatter, hop_f, out, first + boundary / hop);
            }
            end = lo;
        }
    } else {
        let mut i = 0;
        while i < xs.len() {
            let next = ((start + i) / hop + 1) * hop;
            let hi = (next - start).min(xs.len());
            for &x in &xs[i..hi] {
                state.step(x);
            }
            if start + hi == next {
                state.take(scatter, hop_f, out, first + next / hop - 1);
            }
            i = hi;
        }
    }
    state.store(g);
}

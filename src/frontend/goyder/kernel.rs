//! The filtering kernel of the Goyder bank: every band's heterodyne and all-pole low-pass,
//! interleaved so that one CPU vector instruction advances 4 or 8 bands (an AVX2 or AVX-512
//! register; [`super::super::simd::group_counts`], but on AVX-512 groups of 8 only) by one
//! sample. On AVX-512 the frames are taken inside the loop, the state in registers
//! ([`in_registers`]).
//!
//! Per band and sample (f_h = band middle, G = the low-pass's DC gain folded into the
//! oscillator's amplitude so the sections need no input multiply):
//!
//! ```text
//! u      = x · G·e^{−j2π f_h m/fs}             (oscillator: rotated by e^{−j2π f_h/fs} per sample)
//! y_k    = u_k + c1_k·y_k[m−1] + c2_k·y_k[m−2]  (k = 1…order/2, real coefficients, complex data)
//! z      = y_last;  ΣE += |z|²;  ΣP += z·conj(z[m−1])
//! ```
//!
//! That is 20 multiply/fused-multiply-add/add instructions per group of lanes and sample, the
//! whole state of a group stays in registers over a span (the loop runs group by group, each
//! over up to one frame of samples), and the bands vectorise without any time dependence
//! being broken. The oscillator is reset exactly every [`RESYNC_SAMPLES`] samples.
//!
//! The low-pass is the bilinear-transform Butterworth's pole set *without* its zeros at
//! Nyquist (an all-pole section costs 2 instead of 5 instructions per path). Its magnitude
//! differs from the bilinear Butterworth by the factor cos²(π f/fs) per section, i.e. by less
//! than 0.01 dB for f < 0.01·fs; the decay slope, which is what the bank measures, does not
//! depend on it.

use super::super::simd::{group_counts, madd, mul, nmadd, splat, Isa, Lanes, NARROW, WIDE};
use super::super::Band;

#[cfg(target_arch = "x86_64")]
mod in_registers;

/// Samples between exact resynchronisations of the heterodyne oscillators.
pub(super) const RESYNC_SAMPLES: usize = 512;

/// Most all-pole sections per band (order 8).
const MAX_SECTIONS: usize = 4;

/// Feedback coefficients `[c1, c2]` of the all-pole sections of an even-`order` Butterworth
/// low-pass with cut-off `fc_hz` (bilinear transform with pre-warping): section k computes
/// `y[m] = u[m] + c1·y[m−1] + c2·y[m−2]` and has the DC gain 1/(1 − c1 − c2).
pub fn butterworth_allpole(order: usize, fc_hz: f64, fs_hz: f64) -> Vec<[f64; 2]> {
    let k = (std::f64::consts::PI * fc_hz / fs_hz).tan();
    (0..order / 2)
        .map(|i| {
            let q = 1.0
                / (2.0 * (std::f64::consts::PI * (2 * i + 1) as f64 / (2 * order) as f64).cos());
            let norm = 1.0 / (1.0 + k / q + k * k);
            [-2.0 * (k * k - 1.0) * norm, -(1.0 - k / q + k * k) * norm]
        })
        .collect()
}

/// A band's heterodyne frequency (its arithmetic middle, Hz) and its low-pass sections.
pub(super) fn band_design(band: &Band, order: usize, fs_hz: f64) -> (f64, Vec<[f64; 2]>) {
    let f_h = 0.5 * (band.lo_hz + band.hi_hz);
    // Bands beyond Nyquist are flagged by the pipeline; keep the design well-defined.
    let fc = (0.5 * band.width_hz()).min(0.45 * fs_hz);
    (f_h, butterworth_allpole(order, fc, fs_hz))
}

/// Coefficients and states of `L` bands. Padding lanes have zero coefficients and a zero
/// oscillator, so they stay exactly zero.
#[derive(Clone, Copy, Debug)]
struct Group<const L: usize> {
    rot_re: Lanes<L>,
    rot_im: Lanes<L>,
    c1: [Lanes<L>; MAX_SECTIONS],
    c2: [Lanes<L>; MAX_SECTIONS],
    osc_re: Lanes<L>,
    osc_im: Lanes<L>,
    y1r: [Lanes<L>; MAX_SECTIONS],
    y2r: [Lanes<L>; MAX_SECTIONS],
    y1i: [Lanes<L>; MAX_SECTIONS],
    y2i: [Lanes<L>; MAX_SECTIONS],
    pr: Lanes<L>,
    pi: Lanes<L>,
    /// Frame sums, each product in its own accumulator so that no dependency chain is longer
    /// than one fused multiply-add: Σur², Σui², Σur·pr, Σui·pi, Σui·pr, Σur·pi.
    sums: [Lanes<L>; 6],
}

impl<const L: usize> Group<L> {
    const ZERO: Self = Group {
        rot_re: [0.0; L],
        rot_im: [0.0; L],
        c1: [[0.0; L]; MAX_SECTIONS],
        c2: [[0.0; L]; MAX_SECTIONS],
        osc_re: [0.0; L],
        osc_im: [0.0; L],
        y1r: [[0.0; L]; MAX_SECTIONS],
        y2r: [[0.0; L]; MAX_SECTIONS],
        y1i: [[0.0; L]; MAX_SECTIONS],
        y2i: [[0.0; L]; MAX_SECTIONS],
        pr: [0.0; L],
        pi: [0.0; L],
        sums: [[0.0; L]; 6],
    };

    /// Zeroes the filter states and frame sums, keeping coefficients and oscillators.
    fn clear(&mut self) {
        *self = Group {
            rot_re: self.rot_re,
            rot_im: self.rot_im,
            c1: self.c1,
            c2: self.c2,
            osc_re: self.osc_re,
            osc_im: self.osc_im,
            ..Self::ZERO
        };
    }

    /// Sets lane `l`'s sections and oscillator rotation.
    fn set_band(&mut self, l: usize, sections: &[[f64; 2]], rot: (f64, f64)) {
        for (k, [c1, c2]) in sections.iter().enumerate() {
            self.c1[k][l] = *c1;
            self.c2[k][l] = *c2;
        }
        (self.rot_re[l], self.rot_im[l]) = rot;
    }

    /// Sets lane `l`'s oscillator.
    fn set_oscillator(&mut self, l: usize, re: f64, im: f64) {
        self.osc_re[l] = re;
        self.osc_im[l] = im;
    }

    /// The frame sums of the group's first `bands` lanes, cleared: lane l's frame energy
    /// 2Σ|z|²/hop and lag product Σ z·conj(z[m−1]) to `out` at `first + l·stride`.
    #[inline(always)]
    fn take_sums(&mut self, bands: usize, hop: usize, out: FrameOut<'_>, first: usize) {
        // Lane by lane from the sums in place: building the three rows as vectors first put
        // them on the stack and read them back a lane at a time, a store-forwarding stall per
        // value (the frame take was 15 % of the bank at 4096 Hz).
        let s = &self.sums;
        #[allow(clippy::needless_range_loop)] // six rows by one lane index: clearer than a zip
        for l in 0..bands.min(L) {
            let at = first + l * out.stride;
            out.energy[at] = 2.0 * (s[0][l] + s[1][l]) / hop as f64;
            out.lag_re[at] = s[2][l] + s[3][l];
            out.lag_im[at] = s[4][l] - s[5][l];
        }
        self.sums = [[0.0; L]; 6];
    }

    /// Runs the group over `xs` (backwards when `reversed`) with its state held in locals.
    #[inline(always)]
    fn run<const NS: usize, const ACC: bool, const FMA: bool>(
        &mut self,
        xs: &[f64],
        reversed: bool,
    ) {
        let mut g = *self;
        if reversed {
            for &x in xs.iter().rev() {
                g.step::<NS, ACC, FMA>(x);
            }
        } else {
            for &x in xs {
                g.step::<NS, ACC, FMA>(x);
            }
        }
        *self = g;
    }

    #[inline(always)]
    fn step<const NS: usize, const ACC: bool, const FMA: bool>(&mut self, x: f64) {
        let (c, s) = (self.osc_re, self.osc_im);
        let x = splat(x);
        let mut ur = mul(x, c);
        let mut ui = mul(x, s);
        self.osc_re = nmadd::<FMA, L>(s, self.rot_im, mul(c, self.rot_re));
        self.osc_im = madd::<FMA, L>(s, self.rot_re, mul(c, self.rot_im));
        for k in 0..NS {
            let yr = madd::<FMA, L>(
                self.c1[k],
                self.y1r[k],
                madd::<FMA, L>(self.c2[k], self.y2r[k], ur),
            );
            let yi = madd::<FMA, L>(
                self.c1[k],
                self.y1i[k],
                madd::<FMA, L>(self.c2[k], self.y2i[k], ui),
            );
            self.y2r[k] = self.y1r[k];
            self.y1r[k] = yr;
            self.y2i[k] = self.y1i[k];
            self.y1i[k] = yi;
            ur = yr;
            ui = yi;
        }
        if ACC {
            let a = &mut self.sums;
            a[0] = madd::<FMA, L>(ur, ur, a[0]);
            a[1] = madd::<FMA, L>(ui, ui, a[1]);
            a[2] = madd::<FMA, L>(ur, self.pr, a[2]);
            a[3] = madd::<FMA, L>(ui, self.pi, a[3]);
            a[4] = madd::<FMA, L>(ui, self.pr, a[4]);
            a[5] = madd::<FMA, L>(ur, self.pi, a[5]);
        }
        self.pr = ur;
        self.pi = ui;
    }
}

/// The interleaved filter state of all bands of one channel: bands `0..WIDE·wide.len()` in
/// wide groups, the rest in narrow groups.
#[derive(Clone, Debug)]
pub(super) struct Kernel {
    freq_hz: Vec<f64>,
    gain: Vec<f64>,
    sections: usize,
    wide: Vec<Group<WIDE>>,
    narrow: Vec<Group<NARROW>>,
    isa: Isa,
}

/// Where a frame's sums go: per band, energy and lag product, band b's frames `stride` apart.
pub(super) struct FrameOut<'a> {
    /// Frame energies, 2Σ|z|²/hop.
    pub(super) energy: &'a mut [f64],
    /// Real parts of the lag products.
    pub(super) lag_re: &'a mut [f64],
    /// Imaginary parts of the lag products.
    pub(super) lag_im: &'a mut [f64],
    /// Distance between band b's and band b + 1's entry of one frame.
    pub(super) stride: usize,
}

impl FrameOut<'_> {
    fn reborrow(&mut self) -> FrameOut<'_> {
        FrameOut {
            energy: self.energy,
            lag_re: self.lag_re,
            lag_im: self.lag_im,
            stride: self.stride,
        }
    }
}

/// Where band `b` lives: a lane of a wide group or of the narrow group.
enum Slot<'a> {
    Wide(&'a mut Group<WIDE>, usize),
    Narrow(&'a mut Group<NARROW>, usize),
}

impl Kernel {
    /// The kernel for `bands` with a Butterworth prototype of even `order` (2…8).
    pub(super) fn new(bands: &[Band], order: usize, fs_hz: f64) -> Self {
        Kernel::with_isa(bands, order, fs_hz, Isa::detect())
    }

    /// The kernel for `bands` on instruction set `isa` (one of [`Isa::available`]).
    pub(super) fn with_isa(bands: &[Band], order: usize, fs_hz: f64, isa: Isa) -> Self {
        let nb = bands.len();
        // On AVX-512, wide groups only (a narrow group's 256-bit instructions cost as much as a
        // wide one's, and the frames then stay in registers: `frames_in_registers`).
        let (n_wide, n_narrow) = match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => (nb.div_ceil(WIDE), 0),
            _ => group_counts(isa, nb),
        };
        let mut kernel = Kernel {
            freq_hz: Vec::with_capacity(nb),
            gain: Vec::with_capacity(nb),
            sections: order / 2,
            wide: vec![Group::ZERO; n_wide],
            narrow: vec![Group::ZERO; n_narrow],
            isa,
        };
        for (b, band) in bands.iter().enumerate() {
            let (f_h, sections) = band_design(band, order, fs_hz);
            let dc_gain: f64 = sections.iter().map(|[c1, c2]| 1.0 - c1 - c2).product();
            let w = -2.0 * std::f64::consts::PI * f_h / fs_hz;
            match kernel.slot(b) {
                Slot::Wide(g, l) => g.set_band(l, &sections, (w.cos(), w.sin())),
                Slot::Narrow(g, l) => g.set_band(l, &sections, (w.cos(), w.sin())),
            }
            kernel.freq_hz.push(f_h);
            kernel.gain.push(dc_gain);
        }
        kernel
    }

    fn slot(&mut self, b: usize) -> Slot<'_> {
        let n_wide = self.wide.len() * WIDE;
        if b < n_wide {
            Slot::Wide(&mut self.wide[b / WIDE], b % WIDE)
        } else {
            let b = b - n_wide;
            Slot::Narrow(&mut self.narrow[b / NARROW], b % NARROW)
        }
    }

    /// Zeroes every filter state and frame sum.
    pub(super) fn clear(&mut self) {
        self.wide.iter_mut().for_each(Group::clear);
        self.narrow.iter_mut().for_each(Group::clear);
    }

    /// Sets the oscillators exactly to G·e^{−j2π f_h m / fs}.
    pub(super) fn resync(&mut self, m: usize, fs_hz: f64) {
        for b in 0..self.freq_hz.len() {
            let cycles = (self.freq_hz[b] * m as f64 / fs_hz).fract();
            let (s, c) = (-2.0 * std::f64::consts::PI * cycles).sin_cos();
            let gain = self.gain[b];
            match self.slot(b) {
                Slot::Wide(g, l) => g.set_oscillator(l, gain * c, gain * s),
                Slot::Narrow(g, l) => g.set_oscillator(l, gain * c, gain * s),
            }
        }
    }

    /// Filters `xs` (in reverse order when `reversed`) through every band; `accumulate` adds
    /// the outputs to the frame sums.
    pub(super) fn filter_span(&mut self, xs: &[f64], reversed: bool, accumulate: bool) {
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::detect` found AVX-512F and FMA on this CPU.
            Isa::Avx512 => unsafe { self.span_avx512(xs, reversed, accumulate) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::detect` found AVX2 and FMA on this CPU.
            Isa::Avx2Fma => unsafe { self.span_avx2(xs, reversed, accumulate) },
            // aarch64 always has fused multiply-add; x86-64 without the feature would call libm.
            Isa::Generic => {
                self.span::<{ cfg!(target_arch = "aarch64") }>(xs, reversed, accumulate)
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma")]
    unsafe fn span_avx512(&mut self, xs: &[f64], reversed: bool, accumulate: bool) {
        self.span::<true>(xs, reversed, accumulate);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn span_avx2(&mut self, xs: &[f64], reversed: bool, accumulate: bool) {
        self.span::<true>(xs, reversed, accumulate);
    }

    #[inline(always)]
    fn span<const FMA: bool>(&mut self, xs: &[f64], reversed: bool, accumulate: bool) {
        match (self.sections, accumulate) {
            (1, true) => self.span_n::<1, true, FMA>(xs, reversed),
            (1, false) => self.span_n::<1, false, FMA>(xs, reversed),
            (2, true) => self.span_n::<2, true, FMA>(xs, reversed),
            (2, false) => self.span_n::<2, false, FMA>(xs, reversed),
            (3, true) => self.span_n::<3, true, FMA>(xs, reversed),
            (3, false) => self.span_n::<3, false, FMA>(xs, reversed),
            (_, true) => self.span_n::<4, true, FMA>(xs, reversed),
            (_, false) => self.span_n::<4, false, FMA>(xs, reversed),
        }
    }

    #[inline(always)]
    fn span_n<const NS: usize, const ACC: bool, const FMA: bool>(
        &mut self,
        xs: &[f64],
        reversed: bool,
    ) {
        for g in &mut self.wide {
            g.run::<NS, ACC, FMA>(xs, reversed);
        }
        for g in &mut self.narrow {
            g.run::<NS, ACC, FMA>(xs, reversed);
        }
    }

    /// Moves one frame's sums (`hop` samples) into `out` at `frame` and clears them: band b's
    /// energy and lag product Σ z·conj(z[m−1]) at `b·out.stride + frame`. The frame's frequency
    /// is `f_h + arg(lag)·fs/2π` ([`crate::frontend::lane_atan2::frame_frequency`] with
    /// [`Kernel::heterodyne_hz`]), taken for whole decays at once.
    pub(super) fn take_frame(&mut self, hop: usize, frame: usize, out: &mut FrameOut<'_>) {
        let (nb, stride) = (self.freq_hz.len(), out.stride);
        let mut band = 0;
        for g in &mut self.wide {
            g.take_sums(nb - band, hop, out.reborrow(), band * stride + frame);
            band += WIDE;
        }
        for g in &mut self.narrow {
            g.take_sums(nb - band, hop, out.reborrow(), band * stride + frame);
            band += NARROW;
        }
    }

    /// Whether [`Kernel::filter_frames`] runs here: AVX-512, and every band in a wide group.
    pub(super) fn frames_in_registers(&self) -> bool {
        #[cfg(target_arch = "x86_64")]
        return self.isa == Isa::Avx512 && self.narrow.is_empty() && !self.wide.is_empty();
        #[cfg(not(target_arch = "x86_64"))]
        false
    }

    /// Filters `xs`, samples `start …` of the decay (in reverse order when `reversed`), through
    /// every band, accumulating, and moves each frame completed on the way to `out` (band b's
    /// frame k at `b · out.stride + k`), each group's state in registers across the frames:
    /// the same bits as [`Kernel::filter_span`] cut at every frame boundary with a
    /// [`Kernel::take_frame`] after each. Only where [`Kernel::frames_in_registers`] (panics
    /// elsewhere: a caller's bug).
    pub(super) fn filter_frames(
        &mut self,
        run: (&[f64], usize),
        reversed: bool,
        hop: usize,
        out: &mut FrameOut<'_>,
    ) {
        assert!(
            self.frames_in_registers(),
            "frames in registers need AVX-512"
        );
        #[cfg(target_arch = "x86_64")]
        {
            let (nb, stride, sections) = (self.freq_hz.len(), out.stride, self.sections);
            for (i, g) in self.wide.iter_mut().enumerate() {
                let (bands, first) = ((nb - i * WIDE, hop), i * WIDE * stride);
                // SAFETY: `Isa::detect` found AVX-512F and FMA on this CPU (checked above).
                unsafe {
                    match sections {
                        1 => in_registers::run_frames::<1>(g, run, reversed, bands, out, first),
                        2 => in_registers::run_frames::<2>(g, run, reversed, bands, out, first),
                        3 => in_registers::run_frames::<3>(g, run, reversed, bands, out, first),
                        _ => in_registers::run_frames::<4>(g, run, reversed, bands, out, first),
                    }
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (run, reversed, hop, out);
    }

    /// Each band's heterodyne frequency f_h, Hz.
    pub(super) fn heterodyne_hz(&self) -> &[f64] {
        &self.freq_hz
    }

    /// The instruction set the kernel runs with.
    pub(super) fn isa(&self) -> Isa {
        self.isa
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frame sums of `bands` over a two-mode decay, in spans of 37 samples with a resync at
    /// every span start, so that each instruction set runs the same bookkeeping.
    fn frames(isa: Isa, bands: &[Band], order: usize) -> Vec<(f64, f64)> {
        let fs = 8000.0;
        let x: Vec<f64> = (0..4000)
            .map(|n| {
                let t = n as f64 / fs;
                (-4.0 * t).exp() * (2.0 * std::f64::consts::PI * 510.0 * t).sin()
                    + 0.3 * (-9.0 * t).exp() * (2.0 * std::f64::consts::PI * 1233.0 * t).cos()
            })
            .collect();
        let mut k = Kernel::with_isa(bands, order, fs, isa);
        k.clear();
        let mut out = Vec::new();
        let nb = bands.len();
        let (mut e, mut re, mut im) = (vec![0.0; nb], vec![0.0; nb], vec![0.0; nb]);
        for (i, span) in x.chunks(37).enumerate() {
            k.resync(i * 37, fs);
            k.filter_span(span, true, i % 5 != 0);
            k.take_frame(
                37,
                0,
                &mut FrameOut {
                    energy: &mut e,
                    lag_re: &mut re,
                    lag_im: &mut im,
                    stride: 1,
                },
            );
            let f = (0..nb).map(|b| {
                crate::frontend::lane_atan2::frame_frequency(re[b], im[b], k.heterodyne_hz()[b], fs)
            });
            out.extend(e.iter().copied().zip(f));
        }
        out
    }

    #[test]
    fn every_instruction_set_matches_the_portable_kernel() {
        for nb in [1, 3, 8, 12, 13, 21] {
            let bands: Vec<Band> = (0..nb)
                .map(|b| Band::new(400.0 + 60.0 * b as f64, 480.0 + 60.0 * b as f64).unwrap())
                .collect();
            for order in [2, 4, 8] {
                let want = frames(Isa::Generic, &bands, order);
                for isa in Isa::available() {
                    let got = frames(isa, &bands, order);
                    assert_eq!(got.len(), want.len());
                    // Fused and separate rounding differ by ~1e-16 per operation; the
                    // order-8 recursion (poles 0.016 from the unit circle) amplifies that to
                    // ~1e-11 (measured); a wrong coefficient or lane would be off by O(1).
                    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                        assert!(
                            (g.0 - w.0).abs() <= 1e-9 * w.0.abs(),
                            "{isa:?} {nb} bands order {order} #{i}: energy {} vs {}",
                            g.0,
                            w.0
                        );
                        let same_f = (g.1.is_nan() && w.1.is_nan()) || (g.1 - w.1).abs() < 1e-9;
                        assert!(same_f, "{isa:?} #{i}: frequency {} vs {}", g.1, w.1);
                    }
                }
            }
        }
    }

    #[test]
    fn lanes_are_laid_out_without_gaps() {
        let band = Band::new(100.0, 120.0).unwrap();
        for isa in Isa::available() {
            for nb in 0..20 {
                let k = Kernel::with_isa(&vec![band; nb], 4, 1000.0, isa);
                let lanes = WIDE * k.wide.len() + NARROW * k.narrow.len();
                assert!(lanes >= nb && lanes < nb + WIDE.max(NARROW), "{isa:?} {nb}");
                if isa == Isa::Generic {
                    assert!(k.wide.is_empty());
                }
            }
        }
    }
}

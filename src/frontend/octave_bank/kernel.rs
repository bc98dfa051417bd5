//! The filtering kernel of the octave bank: every band's biquad cascade, 4 or 8 bands per
//! group (an AVX2 or AVX-512 register; [`group_counts`]) so that one CPU vector instruction
//! advances a group by one sample. Each lane's arithmetic is the same instructions in the same
//! order whatever the group's width, so the outputs do not depend on it.
//!
//! Per band, sample and section k (transposed direct form II, as the `biquad` crate computes
//! it; the band-pass design has b1 = 0):
//!
//! ```text
//! y   = b0·u + s1
//! s1' = s2 − a1·y
//! s2' = b2·u − a2·y            (u = the previous section's y, the input for the first)
//! ```
//!
//! and at the cascade's end the frame sums Σy², Σy[n−1]·(y[n] + y[n−2]) and Σy[n−1]² (the band
//! energy and the three-point frequency relation, see the bank's docs). A group runs over a
//! whole span of samples with its state in locals (registers), writing its frame sums every
//! `hop` samples, then the next group runs over the same span: no time dependence is broken
//! and the span is read once per group from the cache.
//!
//! Cascades are padded to 1, 2, 3, 4, 6, 8 or 16 sections with exact identity sections
//! (b0 = 1, everything else 0), so each common order runs fully unrolled; lanes without a band
//! have zero coefficients and stay exactly zero.

use super::super::simd::{add, group_counts, madd, mul, nmadd, splat, Isa, Lanes, NARROW, WIDE};

/// Most sections a cascade may have (order 16).
const MAX_SECTIONS: usize = 16;

/// Frame sums of one band: Σy², Σy[n−1]·(y[n] + y[n−2]), Σy[n−1]².
pub(super) type FrameSums = [f64; 3];

/// Coefficients and state of `L` bands.
#[derive(Clone, Copy, Debug)]
struct Group<const L: usize> {
    b0: [Lanes<L>; MAX_SECTIONS],
    b2: [Lanes<L>; MAX_SECTIONS],
    a1: [Lanes<L>; MAX_SECTIONS],
    a2: [Lanes<L>; MAX_SECTIONS],
    s1: [Lanes<L>; MAX_SECTIONS],
    s2: [Lanes<L>; MAX_SECTIONS],
    /// The cascade's last two outputs, y[n−1] and y[n−2].
    y1: Lanes<L>,
    y2: Lanes<L>,
    sums: [Lanes<L>; 3],
}

/// A sample the kernel reads: f64, or an f32 (a decay held in single precision) widened
/// exactly as it is read, instead of in a pass of its own over a widened copy.
pub(crate) trait Sample: Copy {
    /// The sample's value.
    fn value(self) -> f64;
}

impl Sample for f64 {
    #[inline(always)]
    fn value(self) -> f64 {
        self
    }
}

impl Sample for f32 {
    #[inline(always)]
    fn value(self) -> f64 {
        f64::from(self)
    }
}

/// What one call filters and where its frame sums go.
struct Span<'a, S> {
    xs: &'a [S],
    reversed: bool,
    /// Samples (in processing order) until the first frame ends, then `hop` per frame;
    /// `usize::MAX` when nothing accumulates.
    first: usize,
    hop: usize,
    n_bands: usize,
}

impl<const L: usize> Group<L> {
    const ZERO: Group<L> = Group {
        b0: [[0.0; L]; MAX_SECTIONS],
        b2: [[0.0; L]; MAX_SECTIONS],
        a1: [[0.0; L]; MAX_SECTIONS],
        a2: [[0.0; L]; MAX_SECTIONS],
        s1: [[0.0; L]; MAX_SECTIONS],
        s2: [[0.0; L]; MAX_SECTIONS],
        y1: [0.0; L],
        y2: [0.0; L],
        sums: [[0.0; L]; 3],
    };

    /// Sets lane `l` to `cascade` (`[b0, b1, b2, a1, a2]` per section, b1 = 0), padded to
    /// `padded` sections with identity sections.
    fn set_band(&mut self, l: usize, cascade: &[[f64; 5]], padded: usize) {
        debug_assert!(
            cascade.iter().all(|c| c[1] == 0.0),
            "band-pass sections have b1 = 0"
        );
        for k in 0..padded {
            let [b0, _, b2, a1, a2] = cascade.get(k).copied().unwrap_or([1.0, 0.0, 0.0, 0.0, 0.0]);
            self.b0[k][l] = b0;
            self.b2[k][l] = b2;
            self.a1[k][l] = a1;
            self.a2[k][l] = a2;
        }
    }

    /// Zeroes the filter states and frame sums, keeping the coefficients.
    fn clear(&mut self) {
        *self = Group {
            b0: self.b0,
            b2: self.b2,
            a1: self.a1,
            a2: self.a2,
            ..Group::ZERO
        };
    }

    #[inline(always)]
    fn step<const NS: usize, const ACC: bool, const FMA: bool>(&mut self, x: f64) {
        let mut u = splat(x);
        for k in 0..NS {
            let y = madd::<FMA, L>(self.b0[k], u, self.s1[k]);
            self.s1[k] = nmadd::<FMA, L>(self.a1[k], y, self.s2[k]);
            self.s2[k] = nmadd::<FMA, L>(self.a2[k], y, mul(self.b2[k], u));
            u = y;
        }
        if ACC {
            self.sums[0] = madd::<FMA, L>(u, u, self.sums[0]);
            self.sums[1] = madd::<FMA, L>(self.y1, add(u, self.y2), self.sums[1]);
            self.sums[2] = madd::<FMA, L>(self.y1, self.y1, self.sums[2]);
        }
        self.y2 = self.y1;
        self.y1 = u;
    }

    /// Runs the group over the span with its state in locals; lane l is band `lane0 + l`.
    #[inline(always)]
    fn run<const NS: usize, const ACC: bool, const FMA: bool>(
        &mut self,
        span: &Span<'_, impl Sample>,
        lane0: usize,
        out: &mut [FrameSums],
    ) {
        let mut g = *self;
        let n = span.xs.len();
        let (mut p, mut boundary, mut frame) = (0usize, span.first, 0usize);
        while p < n {
            let end = boundary.min(n);
            if span.reversed {
                for &x in span.xs[n - end..n - p].iter().rev() {
                    g.step::<NS, ACC, FMA>(x.value());
                }
            } else {
                for &x in &span.xs[p..end] {
                    g.step::<NS, ACC, FMA>(x.value());
                }
            }
            if ACC && end == boundary {
                for l in 0..L.min(span.n_bands.saturating_sub(lane0)) {
                    out[frame * span.n_bands + lane0 + l] =
                        [g.sums[0][l], g.sums[1][l], g.sums[2][l]];
                }
                g.sums = [[0.0; L]; 3];
                frame += 1;
                boundary = boundary.saturating_add(span.hop);
            }
            p = end;
        }
        *self = g;
    }
}

/// The interleaved filter state of every band of one channel: bands `0..WIDE·wide.len()` in
/// wide groups, the rest in narrow groups.
#[derive(Clone, Debug)]
pub(super) struct Kernel {
    wide: Vec<Group<WIDE>>,
    narrow: Vec<Group<NARROW>>,
    /// Sections per cascade after padding (1, 2, 3, 4, 6, 8 or 16).
    padded_sections: usize,
    n_bands: usize,
    isa: Isa,
}

impl Kernel {
    /// The kernel of bands whose cascades are `sections[band]`, each `[b0, b1, b2, a1, a2]`
    /// with b1 = 0 (the band-pass design), all of the same length (1…16).
    pub(super) fn new(sections: &[Vec<[f64; 5]>]) -> Kernel {
        Kernel::with_isa(sections, Isa::detect())
    }

    fn with_isa(sections: &[Vec<[f64; 5]>], isa: Isa) -> Kernel {
        let ns = sections
            .iter()
            .map(Vec::len)
            .max()
            .unwrap_or(1)
            .clamp(1, MAX_SECTIONS);
        let padded_sections = [1, 2, 3, 4, 6, 8, MAX_SECTIONS]
            .into_iter()
            .find(|&p| p >= ns)
            .unwrap_or(MAX_SECTIONS);
        let (n_wide, n_narrow) = group_counts(isa, sections.len());
        let mut wide = vec![Group::ZERO; n_wide];
        let mut narrow = vec![Group::ZERO; n_narrow];
        let first_narrow = n_wide * WIDE;
        for (b, cascade) in sections.iter().enumerate() {
            if b < first_narrow {
                wide[b / WIDE].set_band(b % WIDE, cascade, padded_sections);
            } else {
                let b = b - first_narrow;
                narrow[b / NARROW].set_band(b % NARROW, cascade, padded_sections);
            }
        }
        Kernel {
            wide,
            narrow,
            padded_sections,
            n_bands: sections.len(),
            isa,
        }
    }

    /// Zeroes every filter state and frame sum.
    pub(super) fn clear(&mut self) {
        self.wide.iter_mut().for_each(Group::clear);
        self.narrow.iter_mut().for_each(Group::clear);
    }

    /// Filters `xs` (from its end to its start when `reversed`) through every band.
    ///
    /// With `frames = Some((first, hop))` the outputs are summed; after the first `first`
    /// samples (in processing order, 1 ≤ first ≤ hop) and then every `hop` samples, the frame
    /// sums of every band go to `out` (frame by frame, bands in order) and are cleared. `out`
    /// ends holding exactly this call's frames: what it held is overwritten, its memory reused
    /// without zeroing (zeroing it again for every chunk of a reversed decay was 1.5 % of an
    /// octave-bank run). A partial frame's sums carry over to the next call. With `None` the
    /// filters only run (and `out` ends empty).
    pub(super) fn filter<S: Sample>(
        &mut self,
        xs: &[S],
        reversed: bool,
        frames: Option<(usize, usize)>,
        out: &mut Vec<FrameSums>,
    ) {
        let (first, hop) = frames.map_or((usize::MAX, usize::MAX), |(f, h)| (f.max(1), h.max(1)));
        let n_frames = if first <= xs.len() {
            1 + (xs.len() - first) / hop
        } else {
            0
        };
        // Every entry is written by the run below (one per band and completed frame).
        let needed = n_frames * self.n_bands;
        if out.len() > needed {
            out.truncate(needed);
        } else {
            out.resize(needed, [0.0; 3]);
        }
        let span = Span {
            xs,
            reversed,
            first,
            hop,
            n_bands: self.n_bands,
        };
        let acc = frames.is_some();
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::detect` found AVX2 and FMA on this CPU.
            Isa::Avx2Fma => unsafe { self.filter_avx2(&span, acc, out) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::detect` found AVX-512F and FMA on this CPU.
            Isa::Avx512 => unsafe { self.filter_avx512(&span, acc, out) },
            // aarch64 always has fused multiply-add; x86-64 without the feature would call libm.
            Isa::Generic => self.dispatch::<{ cfg!(target_arch = "aarch64") }, S>(&span, acc, out),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn filter_avx2<S: Sample>(
        &mut self,
        span: &Span<'_, S>,
        acc: bool,
        out: &mut [FrameSums],
    ) {
        self.dispatch::<true, S>(span, acc, out);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma")]
    unsafe fn filter_avx512<S: Sample>(
        &mut self,
        span: &Span<'_, S>,
        acc: bool,
        out: &mut [FrameSums],
    ) {
        self.dispatch::<true, S>(span, acc, out);
    }

    #[inline(always)]
    fn dispatch<const FMA: bool, S: Sample>(
        &mut self,
        span: &Span<'_, S>,
        acc: bool,
        out: &mut [FrameSums],
    ) {
        match (self.padded_sections, acc) {
            (1, true) => self.groups_run::<1, true, FMA>(span, out),
            (1, false) => self.groups_run::<1, false, FMA>(span, out),
            (2, true) => self.groups_run::<2, true, FMA>(span, out),
            (2, false) => self.groups_run::<2, false, FMA>(span, out),
            (3, true) => self.groups_run::<3, true, FMA>(span, out),
            (3, false) => self.groups_run::<3, false, FMA>(span, out),
            (4, true) => self.groups_run::<4, true, FMA>(span, out),
            (4, false) => self.groups_run::<4, false, FMA>(span, out),
            (6, true) => self.groups_run::<6, true, FMA>(span, out),
            (6, false) => self.groups_run::<6, false, FMA>(span, out),
            (8, true) => self.groups_run::<8, true, FMA>(span, out),
            (8, false) => self.groups_run::<8, false, FMA>(span, out),
            (_, true) => self.groups_run::<MAX_SECTIONS, true, FMA>(span, out),
            (_, false) => self.groups_run::<MAX_SECTIONS, false, FMA>(span, out),
        }
    }

    #[inline(always)]
    fn groups_run<const NS: usize, const ACC: bool, const FMA: bool>(
        &mut self,
        span: &Span<'_, impl Sample>,
        out: &mut [FrameSums],
    ) {
        for (i, g) in self.wide.iter_mut().enumerate() {
            g.run::<NS, ACC, FMA>(span, i * WIDE, out);
        }
        let first_narrow = self.wide.len() * WIDE;
        for (i, g) in self.narrow.iter_mut().enumerate() {
            g.run::<NS, ACC, FMA>(span, first_narrow + i * NARROW, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` deterministic samples in [-0.5, 0.5).
    fn samples(n: usize) -> Vec<f64> {
        (0..n)
            .map(|n| ((n * 7919) % 211) as f64 / 211.0 - 0.5)
            .collect()
    }

    /// Frame sums as bits (NaN payloads and signed zeros told apart).
    fn bits(v: &[FrameSums]) -> Vec<u64> {
        v.iter().flatten().map(|x| x.to_bits()).collect()
    }
    use biquad::{Biquad, Coefficients, DirectForm2Transposed};

    /// The obviously correct bank: the `biquad` crate's sections, one band and sample at a
    /// time, the sums as the kernel documents them.
    fn oracle(sections: &[Vec<[f64; 5]>], xs: &[f64], hop: usize) -> Vec<FrameSums> {
        let mut out = vec![[0.0; 3]; (xs.len() / hop) * sections.len()];
        for (b, cascade) in sections.iter().enumerate() {
            let mut filters: Vec<DirectForm2Transposed<f64>> = cascade
                .iter()
                .map(|&[b0, b1, b2, a1, a2]| {
                    DirectForm2Transposed::<f64>::new(Coefficients { a1, a2, b0, b1, b2 })
                })
                .collect();
            let (mut y1, mut y2, mut s) = (0.0, 0.0, [0.0; 3]);
            for (n, &x) in xs.iter().enumerate() {
                let y = filters.iter_mut().fold(x, |u, f| f.run(u));
                s[0] += y * y;
                s[1] += y1 * (y + y2);
                s[2] += y1 * y1;
                (y2, y1) = (y1, y);
                if (n + 1) % hop == 0 {
                    out[((n + 1) / hop - 1) * sections.len() + b] = std::mem::take(&mut s);
                }
            }
        }
        out
    }

    /// `n_bands` octave bands from 30 Hz (third-octave bands when more than 7, so that 13 fit
    /// below 4 kHz).
    fn bank(n_bands: usize, order: usize, fs: f64) -> Vec<Vec<[f64; 5]>> {
        let ratio = if n_bands <= 7 { 2.0 } else { 2f64.cbrt() };
        (0..n_bands)
            .map(|b| {
                let lo = 30.0 * ratio.powi(b as i32);
                super::super::butterworth_bandpass(order, lo, ratio * lo, fs)
                    .unwrap()
                    .iter()
                    .map(|c| [c.b0, c.b1, c.b2, c.a1, c.a2])
                    .collect()
            })
            .collect()
    }

    /// Every instruction set, order and band count against the oracle, the input cut into
    /// uneven calls (frame sums carried across them), forwards.
    #[test]
    fn every_instruction_set_matches_the_biquad_crate() {
        let fs = 8000.0;
        let xs: Vec<f64> = (0..3000)
            .map(|n| {
                let t = n as f64 / fs;
                (-4.0 * t).exp() * (2.0 * std::f64::consts::PI * 95.0 * t).sin()
                    + 0.5 * (-7.0 * t).exp() * (2.0 * std::f64::consts::PI * 410.0 * t).cos()
            })
            .collect();
        let hop = 16;
        // With AVX-512: narrow groups only (1, 4), one wide (5–7), wide and narrow (9), two wide
        // (13, 16).
        for n_bands in [1, 4, 5, 6, 7, 9, 13, 16] {
            for order in [1, 3, 5, 14] {
                let sections = bank(n_bands, order, fs);
                let want = oracle(&sections, &xs, hop);
                for isa in Isa::available() {
                    let mut k = Kernel::with_isa(&sections, isa);
                    let (mut got, mut frames) = (Vec::new(), Vec::new());
                    let mut done = 0;
                    for chunk in xs.chunks(37) {
                        let first = hop - done % hop;
                        k.filter(chunk, false, Some((first, hop)), &mut frames);
                        got.extend_from_slice(&frames);
                        done += chunk.len();
                    }
                    assert_eq!(got.len(), want.len());
                    // Rounding errors scale with the band's level, not with a frame's: each
                    // band's largest frame sets its scale.
                    let scale: Vec<f64> = (0..n_bands)
                        .map(|b| {
                            want.iter()
                                .skip(b)
                                .step_by(n_bands)
                                .fold(0.0f64, |m, w| m.max(w[0] + w[2]))
                        })
                        .collect();
                    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                        for j in 0..3 {
                            // Fused and separate rounding differ by ~1e-16 per operation; the
                            // recursion amplifies that by its poles' closeness to the unit circle.
                            let tol = 1e-9 * scale[i % n_bands] + 1e-300;
                            assert!(
                                (g[j] - w[j]).abs() <= tol,
                                "{isa:?} {n_bands} bands order {order} sum {j} #{i}: {} vs {}",
                                g[j],
                                w[j]
                            );
                        }
                    }
                }
            }
        }
    }

    /// A band's outputs do not depend on the width of the group its lane is in: every
    /// instruction set with fused multiply-add gives the same bits, for every band count (wide
    /// groups, narrow groups, both), and the lanes cover the bands without a gap.
    #[test]
    fn group_width_does_not_change_a_bit() {
        let fused: Vec<Isa> = Isa::available()
            .into_iter()
            .filter(|&isa| isa != Isa::Generic || cfg!(target_arch = "aarch64"))
            .collect();
        let xs = samples(1500);
        for n_bands in 1..=17 {
            let sections = bank(n_bands, 3, 8000.0);
            let mut first: Option<Vec<u64>> = None;
            for &isa in &fused {
                let mut k = Kernel::with_isa(&sections, isa);
                let lanes = WIDE * k.wide.len() + NARROW * k.narrow.len();
                assert!(
                    lanes >= n_bands && lanes < n_bands + WIDE,
                    "{isa:?} {n_bands}"
                );
                let mut out = Vec::new();
                k.filter(&xs, true, Some((7, 16)), &mut out);
                let bits: Vec<u64> = out.iter().flatten().map(|x| x.to_bits()).collect();
                assert_eq!(out.len(), (1 + (1500 - 7) / 16) * n_bands);
                match &first {
                    None => first = Some(bits),
                    Some(f) => assert!(f == &bits, "{isa:?}, {n_bands} bands"),
                }
            }
        }
    }

    /// Backwards over a slice = forwards over its reversal; running without sums moves the
    /// state exactly as with them.
    #[test]
    fn reversed_and_silent_runs_are_the_same_filter() {
        let sections = bank(5, 3, 4000.0);
        let xs = samples(999);
        let rev: Vec<f64> = xs.iter().rev().copied().collect();
        let (mut a, mut b) = (Kernel::new(&sections), Kernel::new(&sections));
        let (mut out_a, mut out_b) = (Vec::new(), Vec::new());
        a.filter(&xs[500..], true, None, &mut out_a);
        a.filter(&xs[..500], true, Some((10, 10)), &mut out_a);
        b.filter(&rev[..499], false, Some((499, 499)), &mut Vec::new());
        b.filter(&rev[499..], false, Some((10, 10)), &mut out_b);
        assert_eq!(out_a.len(), 50 * 5);
        assert_eq!(out_a, out_b);
    }

    /// `out` ends holding exactly the call's frames whatever it held before (longer, shorter,
    /// NaN-filled): every entry is written, none is left over from the vector's past.
    #[test]
    fn frames_replace_what_out_held() {
        let sections = bank(6, 3, 4096.0);
        let xs = samples(1000);
        for isa in Isa::available() {
            let mut fresh = Vec::new();
            Kernel::with_isa(&sections, isa).filter(&xs, true, Some((8, 8)), &mut fresh);
            assert_eq!(fresh.len(), 125 * 6);
            for held in [0usize, 10, 749, 750, 751, 5000] {
                let mut out = vec![[f64::NAN; 3]; held];
                Kernel::with_isa(&sections, isa).filter(&xs, true, Some((8, 8)), &mut out);
                assert_eq!(bits(&out), bits(&fresh), "{isa:?}, {held} held");
            }
            let mut out = vec![[1.0; 3]; 40];
            Kernel::with_isa(&sections, isa).filter(&xs, true, None, &mut out);
            assert!(out.is_empty());
        }
    }

    /// Single-precision samples are read as their exact f64 values: the same sums, bit for
    /// bit, as from the samples widened first, on every instruction set, forwards and back.
    #[test]
    fn single_precision_samples_are_their_widened_values() {
        let sections = bank(6, 3, 4096.0);
        let xs32: Vec<f32> = (0..777)
            .map(|n| ((n * 7919) % 211) as f32 / 211.0 - 0.5)
            .collect();
        let xs64: Vec<f64> = xs32.iter().map(|&x| f64::from(x)).collect();
        for isa in Isa::available() {
            for reversed in [false, true] {
                let (mut a, mut b) = (
                    Kernel::with_isa(&sections, isa),
                    Kernel::with_isa(&sections, isa),
                );
                let (mut out_a, mut out_b) = (Vec::new(), Vec::new());
                a.filter(&xs32, reversed, Some((8, 8)), &mut out_a);
                b.filter(&xs64, reversed, Some((8, 8)), &mut out_b);
                assert!(!out_a.is_empty());
                assert_eq!(bits(&out_a), bits(&out_b), "{isa:?} reversed {reversed}");
            }
        }
    }
}

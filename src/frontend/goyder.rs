//! Goyder-style filter bank: narrow complex band filters run on the decay reversed in time.
//!
//! Per band (METHODS.md §1.1 reconstruction): the decay x[n], n = 0…N−1, is reversed, multiplied
//! by e^{−j2π f_h m/fs} (f_h = arithmetic band middle), low-pass filtered by a Butterworth of
//! order [`GoyderSettings::order`] with cut-off B/2 (B = band width; as cascaded biquads with real
//! coefficients acting on the real and imaginary parts), and reversed back. The result z[n] is
//! the band's analytic signal shifted to 0 Hz. A growing exponential e^{(σ+jω)t} passes the
//! filter with its slope unchanged (only the gain |H(σ+jω)| changes), while the filter's own
//! start-up transient lands at the *end* of the original record; the last
//! `cut_factor / B_min` seconds (B_min = narrowest band) are therefore dropped for all bands.
//!
//! Frames: consecutive blocks of `hop = round(frame_period_ms · fs / 1000)` samples from the
//! onset; frame energy = block mean of 2|z|² (the mean square of the band signal), frame
//! frequency = f_h + arg(Σ z[m]·conj(z[m−1]))·fs/2π over the block (energy-weighted
//! instantaneous frequency). Block means keep the Schroeder sum of the frames equal to the
//! sample-level integral at block boundaries, whatever the envelope's beating.
//!
//! Reversal needs the whole decay: [`FrontEnd::process`] only buffers (at most
//! [`GoyderSettings::max_decay_s`] seconds; later samples are ignored and
//! [`GoyderFrontEnd::overflowed`] turns true) and [`FrontEnd::finish`] filters and emits every
//! frame. The filtering runs all bands interleaved (structure of arrays, bands in the inner
//! loop) so that the compiler vectorises across bands.

use super::{Band, Frame, FrameSink, FrontEnd, Resolution};
use crate::error::{Error, Result};

/// In which time direction a band filter runs over the decay.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FilterDirection {
    /// Causal filtering in recording order: the filter's ringing smears the early decay
    /// (biased when B·T60 ≲ 16).
    Forward,
    /// Filtering the time-reversed decay and reversing back: the decay rate is preserved.
    Reversed,
}

/// Settings of the Goyder-style filter bank.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GoyderSettings {
    /// Order of the Butterworth low-pass prototype (even, 2…8; 4 by default, i.e. an
    /// 8-pole-equivalent band-pass response around the band middle).
    pub order: usize,
    /// Frame period in milliseconds (1 by default: ≥ 20 frames per T60 down to T60 = 20 ms,
    /// i.e. D = 5 % up to 1.1 kHz; use less for faster decays).
    pub frame_period_ms: f64,
    /// Seconds dropped at the end of the decay, times the narrowest band width B_min
    /// (3 by default: the filter transient has fallen by ≳ 30 dB relative to the signal there).
    /// Not applied in [`FilterDirection::Forward`].
    pub cut_factor: f64,
    /// Longest decay buffered, in seconds (60 by default; bounds memory at 8 bytes × fs × this).
    pub max_decay_s: f64,
    /// Time direction of the filtering ([`FilterDirection::Reversed`] by default).
    pub direction: FilterDirection,
}

impl Default for GoyderSettings {
    fn default() -> Self {
        GoyderSettings {
            order: 4,
            frame_period_ms: 1.0,
            cut_factor: 3.0,
            max_decay_s: 60.0,
            direction: FilterDirection::Reversed,
        }
    }
}

/// Samples between exact resynchronisations of the heterodyne oscillators.
const RESYNC_SAMPLES: usize = 512;

/// One low-pass biquad section for every band: coefficients b0, a1, a2 (b1 = 2·b0 and b2 = b0
/// for a Butterworth low-pass) and the states of the real and imaginary paths, each a vector
/// over bands (transposed direct form II).
#[derive(Clone, Debug)]
struct Section {
    b0: Vec<f64>,
    a1: Vec<f64>,
    a2: Vec<f64>,
    s1_re: Vec<f64>,
    s2_re: Vec<f64>,
    s1_im: Vec<f64>,
    s2_im: Vec<f64>,
}

/// Butterworth low-pass of even `order` and cut-off `fc_hz` as biquads, each `[b0, b1, b2, a1, a2]`
/// (bilinear transform with pre-warping; unit gain at 0 Hz).
pub fn butterworth_lowpass(order: usize, fc_hz: f64, fs_hz: f64) -> Vec<[f64; 5]> {
    let k = (std::f64::consts::PI * fc_hz / fs_hz).tan();
    (0..order / 2)
        .map(|i| {
            let q = 1.0
                / (2.0 * (std::f64::consts::PI * (2 * i + 1) as f64 / (2 * order) as f64).cos());
            let norm = 1.0 / (1.0 + k / q + k * k);
            let b0 = k * k * norm;
            [
                b0,
                2.0 * b0,
                b0,
                2.0 * (k * k - 1.0) * norm,
                (1.0 - k / q + k * k) * norm,
            ]
        })
        .collect()
}

/// The interleaved filter state of all bands.
#[derive(Clone, Debug)]
struct Kernel {
    freq_hz: Vec<f64>,
    rot_re: Vec<f64>,
    rot_im: Vec<f64>,
    osc_re: Vec<f64>,
    osc_im: Vec<f64>,
    sections: Vec<Section>,
    prev_re: Vec<f64>,
    prev_im: Vec<f64>,
    acc_e: Vec<f64>,
    acc_pr: Vec<f64>,
    acc_pi: Vec<f64>,
}

impl Kernel {
    fn new(bands: &[Band], order: usize, fs_hz: f64) -> Self {
        let nb = bands.len();
        let mut sections: Vec<Section> = (0..order / 2)
            .map(|_| Section {
                b0: vec![0.0; nb],
                a1: vec![0.0; nb],
                a2: vec![0.0; nb],
                s1_re: vec![0.0; nb],
                s2_re: vec![0.0; nb],
                s1_im: vec![0.0; nb],
                s2_im: vec![0.0; nb],
            })
            .collect();
        let mut freq_hz = Vec::with_capacity(nb);
        let (mut rot_re, mut rot_im) = (Vec::with_capacity(nb), Vec::with_capacity(nb));
        for (b, band) in bands.iter().enumerate() {
            let f_h = 0.5 * (band.lo_hz + band.hi_hz);
            // Bands beyond Nyquist are flagged by the pipeline; keep the design well-defined.
            let fc = (0.5 * band.width_hz()).min(0.45 * fs_hz);
            for (s, c) in butterworth_lowpass(order, fc, fs_hz).iter().enumerate() {
                let sec = &mut sections[s];
                sec.b0[b] = c[0];
                sec.a1[b] = c[3];
                sec.a2[b] = c[4];
            }
            let w = -2.0 * std::f64::consts::PI * f_h / fs_hz;
            rot_re.push(w.cos());
            rot_im.push(w.sin());
            freq_hz.push(f_h);
        }
        Kernel {
            freq_hz,
            rot_re,
            rot_im,
            osc_re: vec![1.0; nb],
            osc_im: vec![0.0; nb],
            sections,
            prev_re: vec![0.0; nb],
            prev_im: vec![0.0; nb],
            acc_e: vec![0.0; nb],
            acc_pr: vec![0.0; nb],
            acc_pi: vec![0.0; nb],
        }
    }

    fn clear(&mut self) {
        for s in &mut self.sections {
            for v in [&mut s.s1_re, &mut s.s2_re, &mut s.s1_im, &mut s.s2_im] {
                v.iter_mut().for_each(|x| *x = 0.0);
            }
        }
        for v in [
            &mut self.prev_re,
            &mut self.prev_im,
            &mut self.acc_e,
            &mut self.acc_pr,
            &mut self.acc_pi,
        ] {
            v.iter_mut().for_each(|x| *x = 0.0);
        }
    }

    /// Sets the oscillators exactly to e^{−j2π f_h m / fs}.
    fn resync(&mut self, m: usize, fs_hz: f64) {
        for b in 0..self.freq_hz.len() {
            let cycles = (self.freq_hz[b] * m as f64 / fs_hz).fract();
            let (s, c) = (-2.0 * std::f64::consts::PI * cycles).sin_cos();
            self.osc_re[b] = c;
            self.osc_im[b] = s;
        }
    }

    /// Filters one input sample through every band; `accumulate` adds it to the frame sums.
    #[inline]
    fn step(&mut self, x: f64, accumulate: bool) {
        match (self.sections.len(), accumulate) {
            (1, true) => self.step_n::<1, true>(x),
            (1, false) => self.step_n::<1, false>(x),
            (2, true) => self.step_n::<2, true>(x),
            (2, false) => self.step_n::<2, false>(x),
            (3, true) => self.step_n::<3, true>(x),
            (3, false) => self.step_n::<3, false>(x),
            (_, true) => self.step_n::<4, true>(x),
            (_, false) => self.step_n::<4, false>(x),
        }
    }

    /// [`Self::step`] for `NS` sections, fused into one loop over the bands (everything of a
    /// band stays in registers; the loop body vectorises across bands). The sections use the
    /// low-pass symmetry b1 = 2·b0, b2 = b0 of [`butterworth_lowpass`].
    #[inline(always)]
    fn step_n<const NS: usize, const ACC: bool>(&mut self, x: f64) {
        let n = self.freq_hz.len();
        let (or, oi) = (&mut self.osc_re[..n], &mut self.osc_im[..n]);
        let (rr, ri) = (&self.rot_re[..n], &self.rot_im[..n]);
        let (pr, pi) = (&mut self.prev_re[..n], &mut self.prev_im[..n]);
        let (ae, apr, api) = (
            &mut self.acc_e[..n],
            &mut self.acc_pr[..n],
            &mut self.acc_pi[..n],
        );
        let mut secs = self.sections.iter_mut();
        let mut b0: [&[f64]; NS] = [&[]; NS];
        let mut a1: [&[f64]; NS] = [&[]; NS];
        let mut a2: [&[f64]; NS] = [&[]; NS];
        let mut s1r: [&mut [f64]; NS] = std::array::from_fn(|_| &mut [][..]);
        let mut s2r: [&mut [f64]; NS] = std::array::from_fn(|_| &mut [][..]);
        let mut s1i: [&mut [f64]; NS] = std::array::from_fn(|_| &mut [][..]);
        let mut s2i: [&mut [f64]; NS] = std::array::from_fn(|_| &mut [][..]);
        for k in 0..NS {
            let Some(sec) = secs.next() else { return };
            b0[k] = &sec.b0[..n];
            a1[k] = &sec.a1[..n];
            a2[k] = &sec.a2[..n];
            s1r[k] = &mut sec.s1_re[..n];
            s2r[k] = &mut sec.s2_re[..n];
            s1i[k] = &mut sec.s1_im[..n];
            s2i[k] = &mut sec.s2_im[..n];
        }
        for b in 0..n {
            let (c, s) = (or[b], oi[b]);
            let (mut ur, mut ui) = (x * c, x * s);
            or[b] = c * rr[b] - s * ri[b];
            oi[b] = c * ri[b] + s * rr[b];
            for k in 0..NS {
                let (tr, ti) = (b0[k][b] * ur, b0[k][b] * ui);
                let yr = tr + s1r[k][b];
                let yi = ti + s1i[k][b];
                s1r[k][b] = 2.0 * tr - a1[k][b] * yr + s2r[k][b];
                s1i[k][b] = 2.0 * ti - a1[k][b] * yi + s2i[k][b];
                s2r[k][b] = tr - a2[k][b] * yr;
                s2i[k][b] = ti - a2[k][b] * yi;
                ur = yr;
                ui = yi;
            }
            if ACC {
                ae[b] += ur * ur + ui * ui;
                apr[b] += ur * pr[b] + ui * pi[b];
                api[b] += ui * pr[b] - ur * pi[b];
            }
            pr[b] = ur;
            pi[b] = ui;
        }
    }

    /// Moves the frame sums into `energy`/`freq` (one frame of `hop` samples) and clears them.
    fn take_frame(&mut self, hop: usize, fs_hz: f64, energy: &mut [f64], freq: &mut [f64]) {
        for b in 0..self.freq_hz.len() {
            energy[b] = 2.0 * self.acc_e[b] / hop as f64;
            let (re, im) = (self.acc_pr[b], self.acc_pi[b]);
            freq[b] = if re == 0.0 && im == 0.0 {
                f64::NAN
            } else {
                self.freq_hz[b] + im.atan2(re) * fs_hz / (2.0 * std::f64::consts::PI)
            };
            self.acc_e[b] = 0.0;
            self.acc_pr[b] = 0.0;
            self.acc_pi[b] = 0.0;
        }
    }
}

/// The Goyder-style filter bank front end (`--front-end goyder`); one instance per channel.
pub struct GoyderFrontEnd {
    bands: Vec<Band>,
    settings: GoyderSettings,
    sample_rate_hz: f64,
    hop: usize,
    cut_samples: usize,
    max_samples: usize,
    buffer: Vec<f64>,
    overflowed: bool,
    kernel: Kernel,
}

impl GoyderFrontEnd {
    /// A filter bank over `bands` at `sample_rate_hz`. Errors on impossible settings (odd or
    /// out-of-range order, non-positive frame period or maximum duration, negative cut factor).
    pub fn new(settings: GoyderSettings, sample_rate_hz: f64, bands: &[Band]) -> Result<Self> {
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(Error::setting(
                "fs",
                format!("expected a positive sample rate in Hz, got {sample_rate_hz}"),
            ));
        }
        if !(2..=8).contains(&settings.order) || !settings.order.is_multiple_of(2) {
            return Err(Error::setting(
                "goyder order",
                format!("expected an even order from 2 to 8, got {}", settings.order),
            ));
        }
        if !(settings.frame_period_ms.is_finite() && settings.frame_period_ms > 0.0) {
            return Err(Error::setting(
                "goyder frame period",
                format!(
                    "expected a positive number of ms, got {}",
                    settings.frame_period_ms
                ),
            ));
        }
        if !(settings.cut_factor.is_finite() && settings.cut_factor >= 0.0) {
            return Err(Error::setting(
                "goyder cut factor",
                format!("expected a finite number >= 0, got {}", settings.cut_factor),
            ));
        }
        let max = settings.max_decay_s * sample_rate_hz;
        if !(1.0..1e10).contains(&max) {
            return Err(Error::setting(
                "goyder max decay",
                format!(
                    "expected 1/fs to 1e10/fs seconds, got {} s",
                    settings.max_decay_s
                ),
            ));
        }
        let hop = (settings.frame_period_ms * 1e-3 * sample_rate_hz)
            .round()
            .max(1.0) as usize;
        let b_min = bands
            .iter()
            .map(|b| b.width_hz())
            .fold(f64::INFINITY, f64::min);
        let cut_samples = match settings.direction {
            FilterDirection::Forward => 0,
            FilterDirection::Reversed if b_min.is_finite() => {
                (settings.cut_factor / b_min * sample_rate_hz).ceil() as usize
            }
            FilterDirection::Reversed => 0,
        };
        Ok(GoyderFrontEnd {
            bands: bands.to_vec(),
            settings,
            sample_rate_hz,
            hop,
            cut_samples,
            max_samples: max as usize,
            buffer: Vec::new(),
            overflowed: false,
            kernel: Kernel::new(bands, settings.order, sample_rate_hz),
        })
    }

    /// True when the current decay was longer than `max_decay_s` and its end was ignored.
    pub fn overflowed(&self) -> bool {
        self.overflowed
    }

    /// Samples dropped at the end of each decay (the filter transient zone), per band set.
    pub fn cut_samples(&self) -> usize {
        self.cut_samples
    }

    /// Samples per frame.
    pub fn hop_samples(&self) -> usize {
        self.hop
    }

    /// The settings this front end was built with.
    pub fn settings(&self) -> &GoyderSettings {
        &self.settings
    }
}

impl FrontEnd for GoyderFrontEnd {
    fn bands(&self) -> &[Band] {
        &self.bands
    }

    fn resolution(&self) -> Resolution {
        let b_min = self
            .bands
            .iter()
            .map(|b| b.width_hz())
            .fold(f64::INFINITY, f64::min);
        Resolution {
            frame_period_s: self.hop as f64 / self.sample_rate_hz,
            time_resolution_s: 1.0 / b_min,
            frequency_resolution_hz: b_min,
        }
    }

    fn process(&mut self, samples: &[f64], _sink: &mut dyn FrameSink) {
        let room = self.max_samples.saturating_sub(self.buffer.len());
        if samples.len() > room {
            self.overflowed = true;
        }
        self.buffer
            .extend_from_slice(&samples[..samples.len().min(room)]);
    }

    fn finish(&mut self, sink: &mut dyn FrameSink) {
        let n_total = self.buffer.len();
        let keep = n_total.saturating_sub(self.cut_samples);
        let hop = self.hop;
        let n_frames = keep / hop;
        let nb = self.bands.len();
        if n_frames == 0 || nb == 0 {
            self.buffer.clear();
            return;
        }
        let used = n_frames * hop;
        let mut energy = vec![0.0; n_frames * nb];
        let mut freq = vec![0.0; n_frames * nb];
        let fs = self.sample_rate_hz;
        let kernel = &mut self.kernel;
        kernel.clear();
        match self.settings.direction {
            FilterDirection::Reversed => {
                for (m, n) in (0..n_total).rev().enumerate() {
                    if m % RESYNC_SAMPLES == 0 {
                        kernel.resync(m, fs);
                    }
                    kernel.step(self.buffer[n], n < used);
                    if n < used && n % hop == 0 {
                        let k = n / hop;
                        let range = k * nb..(k + 1) * nb;
                        kernel.take_frame(hop, fs, &mut energy[range.clone()], &mut freq[range]);
                    }
                }
            }
            FilterDirection::Forward => {
                for n in 0..used {
                    if n % RESYNC_SAMPLES == 0 {
                        kernel.resync(n, fs);
                    }
                    kernel.step(self.buffer[n], true);
                    if (n + 1) % hop == 0 {
                        let k = n / hop;
                        let range = k * nb..(k + 1) * nb;
                        kernel.take_frame(hop, fs, &mut energy[range.clone()], &mut freq[range]);
                    }
                }
            }
        }
        for k in 0..n_frames {
            sink.frame(Frame {
                energy: &energy[k * nb..(k + 1) * nb],
                frequency_hz: &freq[k * nb..(k + 1) * nb],
            });
        }
        self.buffer.clear();
    }

    fn reset(&mut self) {
        self.buffer.clear();
        self.overflowed = false;
        self.kernel.clear();
    }

    fn name(&self) -> &'static str {
        "goyder"
    }
}

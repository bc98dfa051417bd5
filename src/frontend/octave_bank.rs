//! Standard fractional-octave filter bank (`--front-end octave`), as in room acoustics.
//!
//! Per band, a Butterworth band-pass designed at the band's exact edges (analog prototype of
//! order [`OctaveBankSettings::order`], low-pass → band-pass transform, bilinear transform with
//! pre-warped edges; `order` biquad sections from the `biquad` crate, unit gain at the
//! geometric centre). The squared output, block-averaged over `frame_period_ms`, is the band
//! energy of a frame. [`FilterDirection::Forward`] streams; [`FilterDirection::Reversed`]
//! buffers the decay (at most `max_decay_s`), filters it backwards, reverses back and drops the
//! last `cut_factor / B_min` seconds where the filter's start-up transient lands — the standard
//! remedy for bands with a small B·T60 (Jacobsen & Rindel 1987).

use biquad::{Biquad, Coefficients, DirectForm2Transposed};
use rustfft::num_complex::Complex;

use super::goyder::FilterDirection;
use super::{Band, Frame, FrameSink, FrontEnd, Resolution};
use crate::error::{Error, Result};

/// Settings of the octave filter bank.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OctaveBankSettings {
    /// Order of the low-pass prototype; the band-pass has twice as many poles, in `order`
    /// biquad sections (3 by default: IEC 61260 class 1 is met by order ≥ 3).
    pub order: usize,
    /// Frame period (block-average length) in milliseconds (2 by default).
    pub frame_period_ms: f64,
    /// Time direction of the filtering ([`FilterDirection::Reversed`] by default).
    pub direction: FilterDirection,
    /// Reversed only: seconds dropped at the end, times the narrowest band width (3 by default).
    pub cut_factor: f64,
    /// Reversed only: longest decay buffered, s (60 by default; later samples are ignored).
    pub max_decay_s: f64,
}

impl Default for OctaveBankSettings {
    fn default() -> Self {
        OctaveBankSettings {
            order: 3,
            frame_period_ms: 2.0,
            direction: FilterDirection::Reversed,
            cut_factor: 3.0,
            max_decay_s: 60.0,
        }
    }
}

/// Butterworth band-pass from `lo_hz` to `hi_hz` at `fs_hz` as `order` biquads (unit gain at the
/// pre-warped geometric centre). Errors when the band is empty or reaches 0 Hz or Nyquist.
pub fn butterworth_bandpass(
    order: usize,
    lo_hz: f64,
    hi_hz: f64,
    fs_hz: f64,
) -> Result<Vec<Coefficients<f64>>> {
    if !(lo_hz > 0.0 && hi_hz > lo_hz && hi_hz < 0.5 * fs_hz && (1..=10).contains(&order)) {
        return Err(Error::setting(
            "octave band",
            format!(
                "expected 0 < lo < hi < fs/2 = {} Hz and order 1…10, got {lo_hz}…{hi_hz} Hz, order {order}",
                0.5 * fs_hz
            ),
        ));
    }
    let prewarp = |f: f64| 2.0 * fs_hz * (std::f64::consts::PI * f / fs_hz).tan();
    let (w1, w2) = (prewarp(lo_hz), prewarp(hi_hz));
    let (w0, bw) = ((w1 * w2).sqrt(), w2 - w1);
    let two_fs = 2.0 * fs_hz;
    let omega0 = 2.0 * (w0 / two_fs).atan();
    let e1 = Complex::from_polar(1.0, -omega0);
    let e2 = e1 * e1;
    let mut sections = Vec::with_capacity(order);
    for k in 0..order {
        let theta = std::f64::consts::PI * (2 * k + order + 1) as f64 / (2 * order) as f64;
        let p = Complex::from_polar(1.0, theta) * bw;
        let disc = (p * p - 4.0 * w0 * w0).sqrt();
        // The two band-pass poles from a complex prototype pole lie on opposite sides of the
        // real axis (their product w0² is real and positive) and those of its conjugate are their
        // conjugates: keeping the upper-half-plane one per prototype pole gives each conjugate
        // pair once. The real prototype pole (odd orders) gives a pair of its own (conjugate,
        // or both real for very wide bands near Nyquist), which makes one section.
        let roots = [(p + disc) * 0.5, (p - disc) * 0.5];
        let zs: Vec<Complex<f64>> = if p.im.abs() <= 1e-12 * p.norm() {
            roots.iter().map(|s| (two_fs + s) / (two_fs - s)).collect()
        } else {
            let s = if roots[0].im > 0.0 {
                roots[0]
            } else {
                roots[1]
            };
            let z = (two_fs + s) / (two_fs - s);
            vec![z, z.conj()]
        };
        let (a1, a2) = (-(zs[0] + zs[1]).re, (zs[0] * zs[1]).re);
        let h = (Complex::new(1.0, 0.0) - e2) / (1.0 + e1 * a1 + e2 * a2);
        let g = 1.0 / h.norm();
        sections.push(Coefficients {
            a1,
            a2,
            b0: g,
            b1: 0.0,
            b2: -g,
        });
    }
    if sections.len() != order {
        return Err(Error::setting(
            "octave band",
            format!(
                "design of {lo_hz}…{hi_hz} Hz gave {} sections, expected {order}",
                sections.len()
            ),
        ));
    }
    Ok(sections)
}

/// The octave filter bank front end; one instance per channel.
pub struct OctaveBankFrontEnd {
    bands: Vec<Band>,
    settings: OctaveBankSettings,
    sample_rate_hz: f64,
    filters: Vec<Vec<DirectForm2Transposed<f64>>>,
    hop: usize,
    cut_samples: usize,
    max_samples: usize,
    buffer: Vec<f64>,
    overflowed: bool,
    acc: Vec<f64>,
    in_frame: usize,
    energy: Vec<f64>,
    freq: Vec<f64>,
}

impl OctaveBankFrontEnd {
    /// A bank over `bands` at `sample_rate_hz`. Errors on impossible settings or bands (see
    /// [`butterworth_bandpass`]; bands above Nyquist are rejected here, so drop them first, as
    /// [`super::iec_bands::iec_bands`] does).
    pub fn new(settings: OctaveBankSettings, sample_rate_hz: f64, bands: &[Band]) -> Result<Self> {
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(Error::setting(
                "fs",
                format!("expected a positive sample rate in Hz, got {sample_rate_hz}"),
            ));
        }
        super::check_bank_settings(
            "octave",
            sample_rate_hz,
            settings.frame_period_ms,
            settings.cut_factor,
            settings.max_decay_s,
        )?;
        let filters = bands
            .iter()
            .map(|b| {
                Ok(
                    butterworth_bandpass(settings.order, b.lo_hz, b.hi_hz, sample_rate_hz)?
                        .into_iter()
                        .map(DirectForm2Transposed::<f64>::new)
                        .collect(),
                )
            })
            .collect::<Result<Vec<_>>>()?;
        let hop = (settings.frame_period_ms * 1e-3 * sample_rate_hz)
            .round()
            .max(1.0) as usize;
        let b_min = bands
            .iter()
            .map(|b| b.width_hz())
            .fold(f64::INFINITY, f64::min);
        let cut_samples = match settings.direction {
            FilterDirection::Reversed if b_min.is_finite() => {
                (settings.cut_factor / b_min * sample_rate_hz).ceil() as usize
            }
            _ => 0,
        };
        let nb = bands.len();
        Ok(OctaveBankFrontEnd {
            bands: bands.to_vec(),
            settings,
            sample_rate_hz,
            filters,
            hop,
            cut_samples,
            max_samples: (settings.max_decay_s * sample_rate_hz) as usize,
            buffer: Vec::new(),
            overflowed: false,
            acc: vec![0.0; nb],
            in_frame: 0,
            energy: vec![0.0; nb],
            freq: bands.iter().map(|b| b.center_hz).collect(),
        })
    }

    /// True when the current decay was longer than `max_decay_s` (reversed mode) and its end
    /// was ignored.
    pub fn overflowed(&self) -> bool {
        self.overflowed
    }

    fn clear_filters(&mut self) {
        for f in self.filters.iter_mut().flatten() {
            f.reset_state();
        }
        self.acc.iter_mut().for_each(|a| *a = 0.0);
        self.in_frame = 0;
    }

    /// Filters one sample through every band and adds its square to the frame sums.
    fn step(&mut self, x: f64) {
        for (acc, cascade) in self.acc.iter_mut().zip(&mut self.filters) {
            let y = cascade.iter_mut().fold(x, |u, f| f.run(u));
            *acc += y * y;
        }
    }

    fn take_frame(&mut self) {
        let hop = self.hop as f64;
        for (e, a) in self.energy.iter_mut().zip(&mut self.acc) {
            *e = *a / hop;
            *a = 0.0;
        }
    }

    fn emit(&self, sink: &mut dyn FrameSink) {
        sink.frame(Frame {
            energy: &self.energy,
            frequency_hz: &self.freq,
            active: None,
        });
    }
}

impl FrontEnd for OctaveBankFrontEnd {
    fn bands(&self) -> &[Band] {
        &self.bands
    }

    fn resolution(&self) -> Resolution {
        super::bank_resolution(&self.bands, self.hop, self.sample_rate_hz)
    }

    fn process(&mut self, samples: &[f64], sink: &mut dyn FrameSink) {
        match self.settings.direction {
            FilterDirection::Forward => {
                for &x in samples {
                    self.step(x);
                    self.in_frame += 1;
                    if self.in_frame == self.hop {
                        self.take_frame();
                        self.in_frame = 0;
                        self.emit(sink);
                    }
                }
            }
            FilterDirection::Reversed => {
                self.overflowed |=
                    super::buffer_bounded(&mut self.buffer, self.max_samples, samples);
            }
        }
    }

    fn finish(&mut self, sink: &mut dyn FrameSink) {
        if self.settings.direction == FilterDirection::Forward {
            // A partial last frame is dropped (its mean would cover fewer samples).
            self.clear_filters();
            return;
        }
        let buffer = std::mem::take(&mut self.buffer);
        let keep = buffer.len().saturating_sub(self.cut_samples);
        let n_frames = keep / self.hop;
        let used = n_frames * self.hop;
        let nb = self.bands.len();
        let mut frames = vec![0.0; n_frames * nb];
        self.clear_filters();
        for n in (0..buffer.len()).rev() {
            if n >= used {
                // Run the filters through the transient zone without keeping the output.
                for cascade in &mut self.filters {
                    cascade.iter_mut().fold(buffer[n], |u, f| f.run(u));
                }
                continue;
            }
            self.step(buffer[n]);
            if n % self.hop == 0 {
                self.take_frame();
                let k = n / self.hop;
                frames[k * nb..(k + 1) * nb].copy_from_slice(&self.energy);
            }
        }
        for k in 0..n_frames {
            self.energy.copy_from_slice(&frames[k * nb..(k + 1) * nb]);
            self.emit(sink);
        }
        self.clear_filters();
        self.buffer = buffer;
        self.buffer.clear();
    }

    fn reset(&mut self) {
        self.buffer.clear();
        self.overflowed = false;
        self.clear_filters();
    }

    fn decay_cut_short(&self) -> bool {
        self.overflowed
    }

    fn name(&self) -> &'static str {
        "octave"
    }
}

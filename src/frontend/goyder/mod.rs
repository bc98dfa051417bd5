//! Goyder-style filter bank: narrow complex band filters run on the decay reversed in time.
//!
//! Per band (METHODS.md §1.1 reconstruction): the decay `x[n]`, n = 0…N−1, is reversed, multiplied
//! by e^{−j2π f_h m/fs} (f_h = arithmetic band middle), low-pass filtered by a Butterworth of
//! order [`GoyderSettings::order`] with cut-off B/2 (B = band width; as cascaded all-pole
//! sections with real coefficients acting on the real and imaginary parts, see `kernel`), and
//! reversed back. The result `z[n]` is
//! the band's analytic signal shifted to 0 Hz. A growing exponential e^{(σ+jω)t} passes the
//! filter with its slope unchanged (only the gain |H(σ+jω)| changes), while the filter's own
//! start-up transient lands at the *end* of the original record; the last `cut_factor / B`
//! seconds of each band (B its width) are therefore dropped: frames run to the widest band's
//! cut, and each narrower band's frames past its own cut are marked inactive
//! ([`crate::frontend::Frame::active`]), so that one narrow band (two close modes) does not shorten the others.
//!
//! Frames: consecutive blocks of `hop = round(frame_period_ms · fs / 1000)` samples from the
//! onset; frame energy = block mean of 2|z|² (the mean square of the band signal), frame
//! frequency = f_h + `arg(Σ z[m]·conj(z[m−1]))`·fs/2π over the block (energy-weighted
//! instantaneous frequency). Block means keep the Schroeder sum of the frames equal to the
//! sample-level integral at block boundaries, whatever the envelope's beating.
//!
//! Reversal needs the whole decay: [`FrontEnd::process`] only buffers (at most
//! [`GoyderSettings::max_decay_s`] seconds; later samples are ignored and
//! [`GoyderFrontEnd::overflowed`] turns true) and [`FrontEnd::finish`] filters and emits every
//! frame. The filtering runs all bands interleaved (structure of arrays, 8 bands per vector)
//! so that the compiler vectorises across bands, with AVX-512 or AVX2 + FMA chosen at run time.

mod kernel;

pub use kernel::butterworth_allpole;
use kernel::{band_design, FrameOut, Kernel, RESYNC_SAMPLES};

use super::buffered::DecayBuffer;
pub use super::buffered::FilterDirection;
use super::{lane_atan2, Band, FrameSink, FrontEnd, Resolution};
use crate::decay::FrequencyCoding;
use crate::error::{Error, Result};

/// Settings of the Goyder-style filter bank.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GoyderSettings {
    /// Order of the Butterworth low-pass prototype (even, 2…8; 4 by default, i.e. an
    /// 8-pole-equivalent band-pass response around the band middle).
    pub order: usize,
    /// Frame period in milliseconds (1 by default: ≥ 20 frames per T60 down to T60 = 20 ms,
    /// i.e. D = 5 % up to 1.1 kHz; use less for faster decays).
    pub frame_period_ms: f64,
    /// Seconds dropped at the end of the decay, times each band's width B
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
            cut_factor: super::BANK_CUT_FACTOR,
            max_decay_s: 60.0,
            direction: FilterDirection::default(),
        }
    }
}

/// The Goyder-style filter bank front end (`--front-end goyder`); one instance per channel.
#[derive(Clone)]
pub struct GoyderFrontEnd {
    bands: Vec<Band>,
    settings: GoyderSettings,
    sample_rate_hz: f64,
    hop: usize,
    band_cut_samples: Vec<usize>,
    buffer: DecayBuffer,
    kernel: Kernel,
    /// Per band: heterodyne frequency (Hz) and low-pass sections as `[b0, b1, b2, a1, a2]`
    /// with the DC gain in b0 (for [`FrontEnd::mode_gain`]).
    designs: Vec<(f64, Vec<[f64; 5]>)>,
}

/// How the frames of a decay are taken from the kernel.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum FrameTaking {
    /// A span per frame, and a take after it (every instruction set; the oracle).
    BySpans,
    /// The kernel takes the frames inside each span ([`Kernel::filter_frames`]; AVX-512 kernels
    /// of wide groups only, [`Kernel::frames_in_registers`]). The same bits.
    InRegisters,
}

/// The frames of a decay (`buffer`, `n_frames` frames of `hop` samples) through `kernel` into
/// `out`, in spans between events: oscillator resynchronisation (every [`RESYNC_SAMPLES`]
/// processed samples), reversed the start of the kept part, and by spans every frame boundary.
fn filter_decay_frames(
    kernel: &mut Kernel,
    (buffer, n_frames, hop): (&[f64], usize, usize),
    (reversed, taking): (bool, FrameTaking),
    fs: f64,
    out: &mut FrameOut<'_>,
) {
    let (n_total, used) = (buffer.len(), n_frames * hop);
    let by_spans = taking == FrameTaking::BySpans;
    if reversed {
        let (mut n_end, mut m) = (n_total, 0usize);
        while n_end > 0 {
            if m % RESYNC_SAMPLES == 0 {
                kernel.resync(m, fs);
            }
            let cap = n_end.saturating_sub(RESYNC_SAMPLES - m % RESYNC_SAMPLES);
            let lo = match (n_end > used, by_spans) {
                (true, _) => used.max(cap),
                (false, true) => ((n_end - 1) / hop * hop).max(cap),
                (false, false) => cap,
            };
            if n_end > used || by_spans {
                kernel.filter_span(&buffer[lo..n_end], true, n_end <= used);
                if n_end <= used && lo.is_multiple_of(hop) {
                    kernel.take_frame(hop, lo / hop, out);
                }
            } else {
                kernel.filter_frames((&buffer[lo..n_end], lo), true, hop, out);
            }
            (m, n_end) = (m + n_end - lo, lo);
        }
    } else {
        let mut n0 = 0;
        while n0 < used {
            if n0 % RESYNC_SAMPLES == 0 {
                kernel.resync(n0, fs);
            }
            let n1 = used.min(n0 + RESYNC_SAMPLES - n0 % RESYNC_SAMPLES);
            if by_spans {
                let n1 = n1.min((n0 / hop + 1) * hop);
                kernel.filter_span(&buffer[n0..n1], false, true);
                if n1.is_multiple_of(hop) {
                    kernel.take_frame(hop, n1 / hop - 1, out);
                }
                n0 = n1;
            } else {
                kernel.filter_frames((&buffer[n0..n1], n0), false, hop, out);
                n0 = n1;
            }
        }
    }
}

impl GoyderFrontEnd {
    /// The `n_frames` frames of a decay from its samples, in the bank's direction, to `sink`.
    fn filter_decay(&mut self, buffer: &[f64], n_frames: usize, sink: &mut dyn FrameSink) {
        let (n_total, hop, nb) = (buffer.len(), self.hop, self.bands.len());
        thread_local! {
            /// The lag products' imaginary parts of a decay's frames (their real parts go where
            /// the frequencies will be).
            static LAG_IM: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        super::with_band_frame_arrays(n_frames * nb, false, |energy, freq| {
            super::with_thread_scratch(&LAG_IM, |lag_im| {
                lag_im.clear();
                lag_im.resize(n_frames * nb, 0.0);
                self.filter_frames(buffer, n_frames, energy, freq, lag_im);
            });
            // Each band holds the frames before its own transient zone.
            let band_frames: Vec<usize> = self
                .band_cut_samples
                .iter()
                .map(|c| n_total.saturating_sub(*c) / hop)
                .collect();
            super::emit_band_frames(sink, energy, freq, FrequencyCoding::Hz, &band_frames);
        });
    }

    /// Filters the decay in `buffer` into `n_frames` frames, band-major: `energy`, and the
    /// frame frequencies in `freq` (`lag_im` is the scratch of the lag products' imaginary
    /// parts), the phases taken for every frame at once.
    fn filter_frames(
        &mut self,
        buffer: &[f64],
        n_frames: usize,
        energy: &mut [f64],
        freq: &mut [f64],
        lag_im: &mut [f64],
    ) {
        let (hop, fs) = (self.hop, self.sample_rate_hz);
        let reversed = self.settings.direction == FilterDirection::Reversed;
        let kernel = &mut self.kernel;
        kernel.clear();
        // Each frame's bands straight to their runs of frames (the real parts of the lag
        // products where the frequencies will be).
        let mut out = FrameOut {
            energy: &mut *energy,
            lag_re: &mut *freq,
            lag_im: &mut *lag_im,
            stride: n_frames,
        };
        let taking = match kernel.frames_in_registers() {
            true => FrameTaking::InRegisters,
            false => FrameTaking::BySpans,
        };
        filter_decay_frames(
            kernel,
            (buffer, n_frames, hop),
            (reversed, taking),
            fs,
            &mut out,
        );
        let isa = kernel.isa();
        for (b, &f_h) in kernel.heterodyne_hz().iter().enumerate() {
            let run = b * n_frames..(b + 1) * n_frames;
            lane_atan2::frame_frequencies_in_place(
                isa,
                &mut freq[run.clone()],
                &lag_im[run],
                f_h,
                fs,
            );
        }
    }

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
        super::check_bank_settings(
            "goyder",
            sample_rate_hz,
            settings.frame_period_ms,
            settings.cut_factor,
            settings.max_decay_s,
        )?;
        let hop = (settings.frame_period_ms * 1e-3 * sample_rate_hz)
            .round()
            .max(1.0) as usize;
        let band_cut_samples = bands
            .iter()
            .map(|b| match settings.direction {
                FilterDirection::Forward => 0,
                FilterDirection::Reversed => {
                    (settings.cut_factor / b.width_hz() * sample_rate_hz).ceil() as usize
                }
            })
            .collect();
        Ok(GoyderFrontEnd {
            bands: bands.to_vec(),
            settings,
            sample_rate_hz,
            hop,
            band_cut_samples,
            buffer: DecayBuffer::new((settings.max_decay_s * sample_rate_hz) as usize),
            kernel: Kernel::new(bands, settings.order, sample_rate_hz),
            designs: bands
                .iter()
                .map(|b| {
                    let (f_h, sections) = band_design(b, settings.order, sample_rate_hz);
                    let biquads = sections
                        .iter()
                        .map(|&[c1, c2]| [1.0 - c1 - c2, 0.0, 0.0, -c1, -c2])
                        .collect();
                    (f_h, biquads)
                })
                .collect(),
        })
    }

    /// True when the current decay was longer than `max_decay_s` and its end was ignored.
    pub fn overflowed(&self) -> bool {
        self.buffer.overflowed()
    }

    /// Samples dropped at the end of each decay for the widest band (its filter transient
    /// zone): the frames end there. Narrower bands end earlier, see [`Self::band_cut_samples`].
    pub fn cut_samples(&self) -> usize {
        self.band_cut_samples.iter().copied().min().unwrap_or(0)
    }

    /// Samples dropped at the end of each decay, per band (`cut_factor` / band width).
    pub fn band_cut_samples(&self) -> &[usize] {
        &self.band_cut_samples
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
    fn memory_bytes(&self) -> usize {
        // The decay buffer (Goyder always buffers) plus per-band filters and frames.
        self.buffer.capacity_bytes() + self.bands.len() * 512
    }

    fn bands(&self) -> &[Band] {
        &self.bands
    }

    fn resolution(&self) -> Resolution {
        super::bank_resolution(&self.bands, self.hop, self.sample_rate_hz, 0.0)
    }

    fn process(&mut self, samples: &[f64], _sink: &mut dyn FrameSink) {
        self.buffer.push(samples);
    }

    fn finish(&mut self, sink: &mut dyn FrameSink) {
        let n_total = self.buffer.len();
        let keep = n_total.saturating_sub(self.cut_samples());
        let hop = self.hop;
        let n_frames = keep / hop;
        let nb = self.bands.len();
        if n_frames == 0 || nb == 0 {
            self.buffer.clear();
            return;
        }
        let held = self.buffer.take();
        held.with_f64(|buffer| self.filter_decay(buffer, n_frames, sink));
        self.buffer.give_back(held);
    }

    fn reset(&mut self) {
        self.buffer.reset();
        self.kernel.clear();
    }

    fn decay_cut_short(&self) -> bool {
        self.buffer.overflowed()
    }

    fn name(&self) -> &'static str {
        "goyder"
    }

    fn mode_gain(&self, band: usize, f_hz: f64, sigma_per_s: f64) -> f64 {
        // The band shifts f_h to 0 Hz and low-passes: a real mode at ±f arrives at ±f − f_h.
        let (f_h, sections) = &self.designs[band];
        let reversed = self.settings.direction == FilterDirection::Reversed;
        [f_hz - f_h, -f_hz - f_h]
            .iter()
            .map(|&df| {
                let z_inv = super::mode_z_inv(df, sigma_per_s, reversed, self.sample_rate_hz);
                super::cascade_power(sections.iter().copied(), z_inv)
            })
            .sum()
    }

    fn white_noise_energy(&self, band: usize) -> Option<f64> {
        // White real noise shifted by f_h is white complex noise of the same power; a frame is
        // the block mean of 2|z|², z that noise low-passed.
        let (_, sections) = self.designs.get(band)?;
        Some(2.0 * super::gain_memo::impulse_energy(sections))
    }

    fn flat_gain(&self, band: usize, lo_hz: f64, hi_hz: f64) -> f64 {
        // The same few for every channel: once per process (see `gain_memo`).
        let (f_h, sections) = &self.designs[band];
        super::gain_memo::bank_flat_gain(
            super::gain_memo::GOYDER_TAG,
            self.sample_rate_hz,
            self.settings.direction == FilterDirection::Reversed,
            (lo_hz, hi_hz),
            &[*f_h],
            sections,
            |f_hz| self.mode_gain(band, f_hz, 0.0),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frontend::simd::Isa;

    /// White noise gives each band the energy per frame the quantization floor assumes, both
    /// directions, narrow and wide bands.
    #[test]
    fn white_noise_gives_each_band_its_predicted_energy() {
        let fs = 4096.0;
        let bands: Vec<Band> = [(95.0, 105.0), (300.0, 350.0), (1000.0, 1400.0)]
            .iter()
            .map(|&(lo, hi)| Band::new(lo, hi).unwrap())
            .collect();
        for direction in [FilterDirection::Reversed, FilterDirection::Forward] {
            let settings = GoyderSettings {
                direction,
                ..Default::default()
            };
            let mut fe = GoyderFrontEnd::new(settings, fs, &bands).unwrap();
            crate::frontend::test_frames::assert_white_noise_energy(&mut fe, fs, 40.0, 0.08);
        }
    }

    /// The frames taken inside the AVX-512 kernel are those of the spans cut at every frame
    /// boundary, bit for bit: both directions, frames of 1 to 600 samples (across the
    /// resynchronisation spans of 512 or not), one to three wide groups with padding lanes,
    /// every section count, a reversed tail past the kept frames.
    #[test]
    fn frames_in_registers_equal_the_frames_by_spans() {
        if !Isa::available().contains(&Isa::Avx512) {
            return; // Nothing to compare on this CPU: the spans are the only path.
        }
        let fs = 4096.0;
        let x: Vec<f64> = (0..3001)
            .map(|n| {
                let t = n as f64 / fs;
                (-3.0 * t).exp() * (2.0 * std::f64::consts::PI * 180.0 * t).sin()
                    + 0.4 * (-7.0 * t).exp() * (2.0 * std::f64::consts::PI * 611.0 * t).cos()
                    + 1e-3 * ((n * 7919 % 1013) as f64 / 1013.0 - 0.5)
            })
            .collect();
        for nb in [5, 6, 8, 16, 23] {
            let bands: Vec<Band> = (0..nb)
                .map(|b| Band::new(60.0 + 70.0 * b as f64, 110.0 + 70.0 * b as f64).unwrap())
                .collect();
            for order in [2, 4, 6, 8] {
                let kernel = Kernel::with_isa(&bands, order, fs, Isa::Avx512);
                assert!(kernel.frames_in_registers(), "{nb} bands");
                for hop in [1, 4, 37, 48, 512, 600] {
                    for reversed in [true, false] {
                        let n_frames = x.len() / hop - usize::from(reversed);
                        let run = |in_registers: bool| {
                            let mut k = kernel.clone();
                            k.clear();
                            let mut rows = vec![vec![f64::NAN; n_frames * nb]; 3];
                            let [e, re, im] = &mut rows[..] else {
                                unreachable!()
                            };
                            let mut out = FrameOut {
                                energy: e,
                                lag_re: re,
                                lag_im: im,
                                stride: n_frames,
                            };
                            let taking = match in_registers {
                                true => FrameTaking::InRegisters,
                                false => FrameTaking::BySpans,
                            };
                            let frames = (&x[..], n_frames, hop);
                            filter_decay_frames(&mut k, frames, (reversed, taking), fs, &mut out);
                            rows
                        };
                        let (want, got) = (run(false), run(true));
                        for (row, (w, g)) in want.iter().zip(&got).enumerate() {
                            assert!(w.iter().all(|v| !v.is_nan()), "every frame taken");
                            let same = w.iter().zip(g).all(|(a, b)| a.to_bits() == b.to_bits());
                            assert!(
                                same,
                                "{nb} bands order {order} hop {hop} reversed {reversed} row {row}"
                            );
                        }
                    }
                }
            }
        }
    }
}

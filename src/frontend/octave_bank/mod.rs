//! Standard fractional-octave filter bank (`--front-end octave`), as in room acoustics.
//!
//! Per band, a Butterworth band-pass designed at the band's exact edges (analog prototype of
//! order [`OctaveBankSettings::order`], low-pass → band-pass transform, bilinear transform with
//! pre-warped edges; `order` biquad sections from the `biquad` crate, unit gain at the
//! geometric centre). The squared output, block-averaged over `frame_period_ms`, is the band
//! energy of a frame. [`FilterDirection::Forward`] streams; [`FilterDirection::Reversed`]
//! buffers the decay (at most `max_decay_s`), filters it backwards, reverses back and drops, per
//! band, the last `cut_factor / B` seconds where the filter's start-up transient lands — the
//! standard remedy for bands with a small B·T60 (Jacobsen & Rindel 1987). Reversed filtering also
//! smears each band's share of the first arrival to before the onset: the decay therefore starts
//! with a pre-roll of `cut_factor / B_min` seconds (what preceded the onset, zeros where the
//! record has nothing); the estimator starts each band where its energy first comes within
//! 20 dB of its peak ([`crate::decay::schroeder::DECAY_START_LEVEL_DB`], ISO 3382-1's start
//! rule, per band). Without this, 43–78 % of the band energy at 125 Hz–2 kHz of a measured
//! living-room RIR was discarded.

mod frame_values;
mod kernel;

use biquad::Coefficients;
use rustfft::num_complex::Complex;

use frame_values::{frame_values, frames_from_sums, BandFrames, Chunk};
use kernel::{FrameSums, Kernel, Sample};

use super::buffered::{DecayBuffer, DecaySamples, FilterDirection};
use super::simd::Isa;
use super::{Band, Frame, FrameSink, FrontEnd, Resolution};
use crate::decay::{CountDivisor, FrequencyCoding};
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
            direction: FilterDirection::default(),
            cut_factor: super::BANK_CUT_FACTOR,
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
    if !(lo_hz > 0.0 && hi_hz > lo_hz && hi_hz < 0.5 * fs_hz && (1..=16).contains(&order)) {
        return Err(Error::setting(
            "octave band",
            format!(
                "expected 0 < lo < hi < fs/2 = {} Hz and order 1…16, got {lo_hz}…{hi_hz} Hz, order {order}",
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

/// Frames filtered per kernel call in a reversed decay (bounds the scratch of frame sums).
const FRAMES_PER_CHUNK: usize = 1024;

thread_local! {
    /// The kernel's frame sums (scratch), one per thread for every channel it analyses: one
    /// per front end faulted in 150 kB per channel of a reversed bank.
    static FRAME_SUMS: std::cell::RefCell<Vec<FrameSums>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Runs `f` with this thread's frame-sum scratch.
fn with_frame_sums<R>(f: impl FnOnce(&mut Vec<FrameSums>) -> R) -> R {
    super::with_thread_scratch(&FRAME_SUMS, f)
}

/// The octave filter bank front end; one instance per channel.
#[derive(Clone)]
pub struct OctaveBankFrontEnd {
    bands: Vec<Band>,
    settings: OctaveBankSettings,
    sample_rate_hz: f64,
    /// Per band, its sections as `[b0, b1, b2, a1, a2]` (for [`FrontEnd::mode_gain`]).
    sections: Vec<Vec<[f64; 5]>>,
    /// Every band's cascade; per frame it sums Σy², and Σ y[n−1]·(y[n] + y[n−2]) and
    /// Σ y[n−1]²: the band signal's frequency from the three-point relation
    /// y[n] + y[n−2] = 2 cos(2πf/fs) y[n−1], exact sample by sample for a sinusoid, so that a
    /// frame shorter than a period is not biased (a lag product would be).
    kernel: Kernel,
    /// The frequency sums smoothed over about two periods of the band's lower edge, and the
    /// smoothing factor per frame: within one short frame a decaying sinusoid's cross term
    /// (σ/fs · sin ω · Σ y cos) does not cancel, over a few periods it does.
    smooth: Vec<[f64; 2]>,
    smooth_factor: Vec<f64>,
    /// Instruction set of the frames' arccosines.
    isa: Isa,
    hop: usize,
    /// The longest group delay of the bands at their centres, s: how long the bank rings up.
    rise_s: f64,
    /// Per band, the samples dropped at the end of a reversed decay (cut_factor / B).
    band_cut_samples: Vec<usize>,
    /// Samples before the onset a reversed decay starts with (the widest reach, cut_factor / B_min).
    pre_roll: usize,
    max_samples: usize,
    buffer: DecayBuffer,
    /// Samples of the current (forward) frame so far.
    in_frame: usize,
    /// The last frame's band energies, and its frequencies (cosines until converted to Hz).
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
        let designs = bands
            .iter()
            .map(|b| butterworth_bandpass(settings.order, b.lo_hz, b.hi_hz, sample_rate_hz))
            .collect::<Result<Vec<_>>>()?;
        let sections: Vec<Vec<[f64; 5]>> = designs
            .iter()
            .map(|d| d.iter().map(|c| [c.b0, c.b1, c.b2, c.a1, c.a2]).collect())
            .collect();
        let hop = (settings.frame_period_ms * 1e-3 * sample_rate_hz)
            .round()
            .max(1.0) as usize;
        let reversed = settings.direction == FilterDirection::Reversed;
        let band_cut_samples: Vec<usize> = bands
            .iter()
            .map(|b| {
                if reversed {
                    (settings.cut_factor / b.width_hz() * sample_rate_hz).ceil() as usize
                } else {
                    0
                }
            })
            .collect();
        let pre_roll = band_cut_samples.iter().copied().max().unwrap_or(0);
        let rise_s = bands
            .iter()
            .zip(&sections)
            .map(|(b, s): (&Band, &Vec<[f64; 5]>)| {
                super::cascade_group_delay_samples(s.iter().copied(), b.center_hz, sample_rate_hz)
            })
            .fold(0.0, f64::max)
            / sample_rate_hz;
        let nb = bands.len();
        let max_samples = (settings.max_decay_s * sample_rate_hz) as usize;
        Ok(OctaveBankFrontEnd {
            bands: bands.to_vec(),
            settings,
            sample_rate_hz,
            kernel: Kernel::new(&sections),
            sections,
            smooth: vec![[0.0; 2]; nb],
            smooth_factor: bands
                .iter()
                .map(|b| (-(hop as f64) * b.lo_hz / (2.0 * sample_rate_hz)).exp())
                .collect(),
            hop,
            rise_s,
            band_cut_samples,
            pre_roll,
            max_samples,
            buffer: DecayBuffer::with_lead(max_samples + pre_roll, pre_roll),
            in_frame: 0,
            energy: vec![0.0; nb],
            freq: vec![f64::NAN; nb],
            isa: Isa::detect(),
        })
    }

    /// True when the current decay was longer than `max_decay_s` (reversed mode) and its end
    /// was ignored.
    pub fn overflowed(&self) -> bool {
        self.buffer.overflowed()
    }

    fn clear_filters(&mut self) {
        self.kernel.clear();
        self.smooth.iter_mut().for_each(|a| *a = [0.0; 2]);
        self.in_frame = 0;
    }

    /// A whole decay's frames from its samples, filtered from the last to the first, to `sink`.
    fn filter_reversed<S: Sample>(&mut self, buffer: &[S], sink: &mut dyn FrameSink) {
        // Each band keeps the frames before its own transient zone; the widest band the most.
        let band_frames: Vec<usize> = self
            .band_cut_samples
            .iter()
            .map(|c| buffer.len().saturating_sub(*c) / self.hop)
            .collect();
        let n_frames = band_frames.iter().copied().max().unwrap_or(0);
        let used = n_frames * self.hop;
        let nb = self.bands.len();
        let energy_scale = self.energy_scale();
        self.clear_filters();
        // Every band's every frame is written below (the chunks cover frames n_frames..0).
        super::with_band_frame_arrays(n_frames * nb, true, |frames, freqs| {
            with_frame_sums(|sums| {
                // Through the transient zone without keeping the output, then frame by frame
                // from the last to the first, a bounded chunk of frames at a time.
                self.kernel.filter(&buffer[used..], true, None, sums);
                let mut out = BandFrames {
                    energy: frames,
                    cosine: freqs,
                    n_frames,
                };
                let mut k_end = n_frames;
                while k_end > 0 {
                    let k_start = k_end.saturating_sub(FRAMES_PER_CHUNK);
                    let chunk = &buffer[k_start * self.hop..k_end * self.hop];
                    self.kernel
                        .filter(chunk, true, Some((self.hop, self.hop)), sums);
                    // Straight into the band-major arrays.
                    let chunk = Chunk {
                        sums,
                        smooth: &mut self.smooth,
                        alpha: &self.smooth_factor,
                        scale: energy_scale,
                        k_end,
                    };
                    frames_from_sums(self.isa, chunk, &mut out);
                    k_end = k_start;
                }
            });
            // The cosines as they are: an estimate decodes only the frames it fits.
            let coding = FrequencyCoding::Cosine {
                sample_rate_hz: self.sample_rate_hz,
            };
            super::emit_band_frames(sink, frames, freqs, coding, &band_frames);
        });
        self.clear_filters();
    }

    /// Turns one frame's sums (every band) into its energies and the cosines of its frequencies
    /// (cos 2πf/fs, NaN where unknown; [`OctaveBankFrontEnd::cosines_to_hz`] converts them,
    /// many frames at once where it can).
    fn take_frame(&mut self, sums: &[FrameSums]) {
        let energy_scale = self.energy_scale();
        for ((((e, f), sm), &alpha), sum) in self
            .energy
            .iter_mut()
            .zip(&mut self.freq)
            .zip(&mut self.smooth)
            .zip(&self.smooth_factor)
            .zip(sums)
        {
            (*e, *f) = frame_values(sm, alpha, sum, energy_scale);
        }
    }

    /// How a frame's Σy² becomes its mean energy per sample: over the hop.
    fn energy_scale(&self) -> CountDivisor {
        CountDivisor::new(self.hop)
    }

    /// Frequencies in Hz from their cosines ([`OctaveBankFrontEnd::take_frame`]), in place.
    fn cosines_to_hz(isa: Isa, sample_rate_hz: f64, cosines: &mut [f64]) {
        let to_hz = sample_rate_hz / (2.0 * std::f64::consts::PI);
        crate::frontend::lane_acos::acos_scaled_in_place(isa, cosines, to_hz);
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
    fn memory_bytes(&self) -> usize {
        let buffer = match self.settings.direction {
            // The decay buffer with its pre-roll, and the onset detector's pre-roll history.
            FilterDirection::Reversed => (self.max_samples + 2 * self.pre_roll).saturating_mul(8),
            FilterDirection::Forward => 0,
        };
        buffer + self.bands.len() * 512
    }

    fn bands(&self) -> &[Band] {
        &self.bands
    }

    fn resolution(&self) -> Resolution {
        super::bank_resolution(&self.bands, self.hop, self.sample_rate_hz, self.rise_s)
    }

    fn shortest_t60_s(&self, band: usize) -> f64 {
        // Each band's filter is designed on the band's edges (its −3 dB points).
        self.bands
            .get(band)
            .map_or(0.0, |b| super::BT60_MIN / b.width_hz())
    }

    fn process(&mut self, samples: &[f64], sink: &mut dyn FrameSink) {
        match self.settings.direction {
            FilterDirection::Forward => with_frame_sums(|sums| {
                let first = self.hop - self.in_frame;
                self.kernel
                    .filter(samples, false, Some((first, self.hop)), sums);
                for frame in sums.chunks_exact(self.bands.len().max(1)) {
                    self.take_frame(frame);
                    Self::cosines_to_hz(self.isa, self.sample_rate_hz, &mut self.freq);
                    self.emit(sink);
                }
                self.in_frame = (self.in_frame + samples.len()) % self.hop;
            }),
            FilterDirection::Reversed => {
                self.buffer.push(samples);
            }
        }
    }

    fn finish(&mut self, sink: &mut dyn FrameSink) {
        if self.settings.direction == FilterDirection::Forward {
            // A partial last frame is dropped (its mean would cover fewer samples).
            self.clear_filters();
            return;
        }
        let held = self.buffer.take();
        // Read as held: an f32 decay is widened sample by sample inside the kernel.
        match &held {
            DecaySamples::Single(v) => self.filter_reversed(v, sink),
            DecaySamples::Double(v) => self.filter_reversed(v, sink),
        }
        self.buffer.give_back(held);
    }

    fn reset(&mut self) {
        self.buffer.reset();
        self.clear_filters();
    }

    fn decay_cut_short(&self) -> bool {
        self.buffer.overflowed()
    }

    fn pre_roll_samples(&self) -> usize {
        self.pre_roll
    }

    fn begin_decay(&mut self, pre_roll: &[f64]) {
        if self.settings.direction == FilterDirection::Reversed {
            self.buffer.start_with_pre_roll(pre_roll, self.pre_roll);
        }
    }

    fn name(&self) -> &'static str {
        "octave"
    }

    fn mode_gain(&self, band: usize, f_hz: f64, sigma_per_s: f64) -> f64 {
        let reversed = self.settings.direction == FilterDirection::Reversed;
        let z_inv = super::mode_z_inv(f_hz, sigma_per_s, reversed, self.sample_rate_hz);
        super::cascade_power(self.sections[band].iter().copied(), z_inv)
    }

    fn white_noise_energy(&self, band: usize) -> Option<f64> {
        // A frame is the mean square of the band's output.
        Some(super::gain_memo::impulse_energy(self.sections.get(band)?))
    }

    fn flat_gain(&self, band: usize, lo_hz: f64, hi_hz: f64) -> f64 {
        // The same few for every channel: once per process (see `gain_memo`).
        super::gain_memo::bank_flat_gain(
            super::gain_memo::OCTAVE_TAG,
            self.sample_rate_hz,
            self.settings.direction == FilterDirection::Reversed,
            (lo_hz, hi_hz),
            &[],
            &self.sections[band],
            |f_hz| self.mode_gain(band, f_hz, 0.0),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// White noise gives each band the energy per frame the quantization floor assumes: both
    /// directions, orders 2 and 3, IEC octave bands at 8192 Hz.
    #[test]
    fn white_noise_gives_each_band_its_predicted_energy() {
        let fs = 8192.0;
        use crate::frontend::iec_bands::{iec_bands, OctaveFraction};
        let bands = iec_bands(OctaveFraction::Octave, 63.0, fs).unwrap().0;
        for direction in [FilterDirection::Reversed, FilterDirection::Forward] {
            for order in [2, 3] {
                let settings = OctaveBankSettings {
                    order,
                    direction,
                    ..Default::default()
                };
                let mut fe = OctaveBankFrontEnd::new(settings, fs, &bands).unwrap();
                crate::frontend::test_frames::assert_white_noise_energy(&mut fe, fs, 40.0, 0.08);
            }
        }
    }

    /// The frequency each band reports is the frequency of its band signal: a 55 Hz decay
    /// through the 63 Hz octave band reads 55 Hz, and through the 125 Hz band (its skirt) too
    /// when filtered backwards; forwards the filter's own ringing after the onset (near the
    /// band) mixes in, but the energy stays below the band.
    #[test]
    fn band_signal_frequency_is_the_tone_frequency() {
        let fs = 4000.0;
        let x: Vec<f64> = (0..16000)
            .map(|i| {
                let t = i as f64 / fs;
                (-t).exp() * (2.0 * std::f64::consts::PI * 55.0 * t).sin()
            })
            .collect();
        let bands = [
            Band::new(44.67, 89.13).unwrap(),
            Band::new(89.13, 177.8).unwrap(),
        ];
        for direction in [FilterDirection::Forward, FilterDirection::Reversed] {
            let s = OctaveBankSettings {
                direction,
                ..Default::default()
            };
            let mut fe = OctaveBankFrontEnd::new(s, fs, &bands).unwrap();
            let (mut wsum, mut fsum) = ([0.0; 2], [0.0; 2]);
            let mut sink = |f: Frame<'_>| {
                for b in 0..2 {
                    if f.frequency_hz[b].is_finite() {
                        wsum[b] += f.energy[b];
                        fsum[b] += f.energy[b] * f.frequency_hz[b];
                    }
                }
            };
            fe.process(&x, &mut sink);
            fe.finish(&mut sink);
            for b in 0..2 {
                let f = fsum[b] / wsum[b];
                if b == 1 && direction == FilterDirection::Forward {
                    assert!(f < 89.13, "{direction:?} band {b}: {f} Hz");
                } else {
                    assert!((f - 55.0).abs() < 0.5, "{direction:?} band {b}: {f} Hz");
                }
            }
        }
    }

    /// A reversed decay's frames do not depend on what the thread's frame arrays held before
    /// (they are not zeroed: every entry is written): after NaN-filled arrays longer than the
    /// decay needs, and after a longer decay of other samples, the same bits as in a fresh
    /// thread.
    #[test]
    fn reversed_frames_ignore_what_the_frame_arrays_held() {
        let fs = 4096.0;
        let bands = [
            Band::new(44.67, 89.13).unwrap(),
            Band::new(89.13, 177.8).unwrap(),
            Band::new(177.8, 354.8).unwrap(),
        ];
        use crate::frontend::test_frames::{decay_frame_bits, decaying_sine};
        let decay = |f_hz: f64, n: usize| decaying_sine(fs, f_hz, 3.0, n);
        let frames_of = |x: &[f64]| -> Vec<u64> {
            let settings = OctaveBankSettings::default();
            decay_frame_bits(
                &mut OctaveBankFrontEnd::new(settings, fs, &bands).unwrap(),
                x,
            )
        };
        let x = decay(130.0, 9000);
        let fresh = std::thread::scope(|s| s.spawn(|| frames_of(&x)).join().unwrap());
        assert!(!fresh.is_empty());
        crate::frontend::with_band_frame_arrays(100_000, false, |e, f| {
            e.fill(f64::NAN);
            f.fill(f64::NAN);
        });
        assert_eq!(frames_of(&x), fresh, "after NaN-filled arrays");
        frames_of(&decay(70.0, 30_000));
        assert_eq!(frames_of(&x), fresh, "after a longer decay");
    }
}

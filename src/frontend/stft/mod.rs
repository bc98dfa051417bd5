//! Short-time Fourier transform front end (report section 2.3).
//!
//! Hann window of `window_ms` (200 ms by default, as the report and Norambuena et al.), hop
//! `window · (1 − overlap)`, optional zero padding. The first frame starts at the first sample it
//! is given (the decay onset): then the sliding-window energy of an exponential decay is again
//! exactly exponential with the same rate, so the STFT adds no slope bias (METHODS.md §1).
//! Band energy = Σ w_b |X_b|² over the band's bins, where w_b is the fraction of bin b's
//! extent [f_b − Δf/2, f_b + Δf/2] that lies inside the band (partial edge bins weighted).
//! Only whole frames are emitted.

use std::sync::Arc;

mod kernels;
mod prime_factor;
mod tables;
mod transform;

use super::gain_memo::{memoized_flat_gain, FlatGainKey, STFT_TAG};
use kernels::band_energy_and_peak;
use tables::{shared_band_bins, shared_hann};
use transform::{with_frame_buffers, Transform};

use super::simd::Isa;
use super::{Band, Frame, FrameSink, FrontEnd, Resolution};
use crate::error::{Error, Result};

/// Settings of the STFT front end.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StftSettings {
    /// Window length in milliseconds (200 by default).
    pub window_ms: f64,
    /// Fraction of the window shared by successive frames, 0 ≤ overlap < 1 (0.5 by default).
    pub overlap: f64,
    /// FFT length = window length × this factor (1 = no zero padding).
    pub zero_pad: usize,
}

/// Default of [`StftSettings::window_ms`]: the report's 200 ms Hann window.
pub const DEFAULT_WINDOW_MS: f64 = 200.0;
/// Default of [`StftSettings::overlap`]: half a window between frames.
pub const DEFAULT_OVERLAP: f64 = 0.5;
/// Default of [`StftSettings::zero_pad`]: no zero padding.
pub const DEFAULT_ZERO_PAD: usize = 1;

impl Default for StftSettings {
    fn default() -> Self {
        StftSettings {
            window_ms: DEFAULT_WINDOW_MS,
            overlap: DEFAULT_OVERLAP,
            zero_pad: DEFAULT_ZERO_PAD,
        }
    }
}

/// The bins of one band and their weights.
#[derive(Clone, Debug)]
struct BandBins {
    first_bin: usize,
    weights: Vec<f64>,
    /// Positions (in `weights`) of the bins with a positive weight: contiguous, since only the
    /// edge bins can lie wholly outside the band.
    weighted: std::ops::Range<usize>,
    /// Running sums of `weights` (`[0]` = 0): the weight of any run of bins in O(1), for the
    /// mode gain's bound.
    cumulative: Vec<f64>,
}

/// Streaming STFT: samples in, per band one energy (and peak frequency) per hop out.
#[derive(Clone)]
pub struct StftFrontEnd {
    bands: Vec<Band>,
    /// The bands' bins and weights, shared by every front end of the same transform and bands
    /// (like the window: one copy in the cache for all channels — one per channel made reading
    /// the weights the largest per-frame cost after the FFT at 48 kHz).
    band_bins: Arc<[BandBins]>,
    /// The periodic Hann window, shared by every front end of the same length (one copy in the
    /// cache for all channels).
    window: Arc<[f64]>,
    hop: usize,
    bin_hz: f64,
    /// The FFT plans; for an odd FFT length, where a real transform costs a whole complex one,
    /// two successive frames share one complex transform whenever both are in hand.
    transform: Transform,
    pending: Vec<f64>,
    /// Where the next frame starts in `pending` (samples before it are spent; they are dropped
    /// once they outnumber a window, so that each sample is moved O(1) times).
    next_frame: usize,
    /// The bands of the frame at `next_frame`, computed early (with samples not yet fed, in one
    /// transform with the frame before it) and emitted once the input completes that frame;
    /// valid while `has_early`.
    early: EarlyFrame,
    has_early: bool,
    /// The frame after a lone one, put together from `pending` and the samples ahead.
    assembled: Vec<f64>,
    energy: Vec<f64>,
    frequency_hz: Vec<f64>,
    sample_rate_hz: f64,
    zero_pad: usize,
    /// Instruction set of the per-frame loops (window, power spectrum).
    isa: Isa,
    /// The spectrum the bands' bins lie on, for the leakage test's gains.
    hann_grid: super::hann_gain::HannGrid,
}

/// One frame's band figures, kept until the frame may be emitted.
#[derive(Clone, Debug)]
struct EarlyFrame {
    energy: Vec<f64>,
    frequency_hz: Vec<f64>,
}

/// Bytes one STFT front end holds: window, FFT buffers and plan, power spectrum, band weights
/// (each about one spectrum in total), the pending input, and the per-band figures.
fn stft_memory_bytes(win_len: usize, zero_pad: usize, n_bands: usize) -> f64 {
    let nfft = (win_len * zero_pad) as f64;
    nfft * 104.0 + win_len as f64 * 24.0 + n_bands as f64 * 128.0
}

impl StftFrontEnd {
    /// A front end for `bands` at `sample_rate_hz`. Errors on impossible settings.
    pub fn new(settings: StftSettings, sample_rate_hz: f64, bands: &[Band]) -> Result<Self> {
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(Error::setting(
                "fs",
                format!("expected > 0 Hz, got {sample_rate_hz}"),
            ));
        }
        if !(settings.overlap >= 0.0 && settings.overlap < 1.0) {
            return Err(Error::setting(
                "overlap",
                format!("expected 0 <= overlap < 1, got {}", settings.overlap),
            ));
        }
        let win_len = (settings.window_ms * 1e-3 * sample_rate_hz).round();
        if !(4.0..=1e8).contains(&win_len) {
            return Err(Error::setting(
                "window_ms",
                format!(
                    "{} ms at {sample_rate_hz} Hz gives {win_len} samples; expected 4 to 1e8",
                    settings.window_ms
                ),
            ));
        }
        if settings.zero_pad == 0 || settings.zero_pad > 64 {
            return Err(Error::setting(
                "zero_pad",
                format!("expected 1 to 64, got {}", settings.zero_pad),
            ));
        }
        if bands.is_empty() {
            return Err(Error::setting("bands", "no bands given"));
        }
        let win_len = win_len as usize;
        let estimate = stft_memory_bytes(win_len, settings.zero_pad, bands.len());
        crate::budget::check(
            &format!(
                "an STFT window of {win_len} samples × zero-pad {}",
                settings.zero_pad
            ),
            estimate,
        )?;
        let hop = ((win_len as f64) * (1.0 - settings.overlap))
            .round()
            .max(1.0) as usize;
        let nfft = win_len * settings.zero_pad;
        let window = shared_hann(win_len);
        let n_bins = nfft / 2 + 1;
        let bin_hz = sample_rate_hz / nfft as f64;
        let band_bins = shared_band_bins(bands, bin_hz, n_bins);
        Ok(StftFrontEnd {
            bands: bands.to_vec(),
            band_bins,
            window,
            hop,
            bin_hz,
            transform: Transform::new(nfft),
            pending: Vec::new(),
            next_frame: 0,
            early: EarlyFrame {
                energy: vec![0.0; bands.len()],
                frequency_hz: vec![f64::NAN; bands.len()],
            },
            has_early: false,
            assembled: Vec::new(),
            energy: vec![0.0; bands.len()],
            frequency_hz: vec![f64::NAN; bands.len()],
            sample_rate_hz,
            zero_pad: settings.zero_pad,
            isa: Isa::detect(),
            hann_grid: super::hann_gain::HannGrid::new(
                2.0 * std::f64::consts::PI * bin_hz / sample_rate_hz,
                win_len,
            ),
        })
    }

    /// Samples per hop.
    pub fn hop_samples(&self) -> usize {
        self.hop
    }

    /// Samples per window.
    pub fn window_samples(&self) -> usize {
        self.window.len()
    }

    /// The frame starting at `pending[start]`, emitted.
    fn compute_frame(&mut self, start: usize, sink: &mut dyn FrameSink) {
        let w = self.window.len();
        with_frame_buffers(|buffers| {
            let frame = &self.pending[start..start + w];
            self.transform
                .frame_power(self.isa, frame, &self.window, buffers);
            self.take_bands(&buffers.power);
        });
        self.emit(sink);
    }

    /// The frames starting at `pending[start]` and one hop later, through one transform (at
    /// odd lengths a lone frame costs a whole complex FFT of its length, as much as two). The
    /// first is emitted; the second too when `pending` holds it, else its missing samples are
    /// taken from `ahead` and its bands kept in `early` until the input completes it.
    fn compute_pair(&mut self, start: usize, ahead: &[f64], sink: &mut dyn FrameSink) {
        let (w, second) = (self.window.len(), start + self.hop);
        let in_hand = second + w <= self.pending.len();
        let mut assembled = std::mem::take(&mut self.assembled);
        if !in_hand {
            let have = self.pending.len() - second;
            assembled.clear();
            assembled.extend_from_slice(&self.pending[second..]);
            assembled.extend_from_slice(&ahead[..w - have]);
        }
        with_frame_buffers(|buffers| {
            let a = &self.pending[start..start + w];
            let b = match in_hand {
                true => &self.pending[second..second + w],
                false => &assembled[..],
            };
            self.transform
                .pair_powers(self.isa, a, b, &self.window, buffers);
            self.take_bands(&buffers.power);
            self.emit(sink);
            self.take_bands(&buffers.power_b);
        });
        if in_hand {
            self.emit(sink);
        } else {
            self.early.energy.copy_from_slice(&self.energy);
            self.early.frequency_hz.copy_from_slice(&self.frequency_hz);
            self.has_early = true;
        }
        self.assembled = assembled;
    }

    fn emit(&self, sink: &mut dyn FrameSink) {
        sink.frame(Frame {
            energy: &self.energy,
            frequency_hz: &self.frequency_hz,
            active: None,
        });
    }

    /// Every band's energy and peak frequency from one frame's power spectrum.
    fn take_bands(&mut self, power: &[f64]) {
        for (k, bb) in self.band_bins.iter().enumerate() {
            let powers = &power[bb.first_bin..bb.first_bin + bb.weights.len()];
            // The bins with a positive weight are contiguous (only edge bins can have none):
            // the strongest of them, the first on a tie.
            let (e, strongest) =
                band_energy_and_peak(self.isa, powers, &bb.weights, bb.weighted.clone());
            let (first, last) = (
                bb.first_bin + bb.weighted.start,
                (bb.first_bin + bb.weighted.end).saturating_sub(1),
            );
            self.energy[k] = e;
            // A maximum on the band's edge with more power outside is the skirt of a peak
            // outside the band: follow it uphill, so that the frame reports the frequency that
            // carries the band's energy (and the leakage test sees it off-band).
            let peak = strongest.map_or(usize::MAX, |i| {
                let peak = bb.first_bin + i;
                if peak == first || peak == last {
                    climb(power, peak)
                } else {
                    peak
                }
            });
            // Below bin 2 the mirror image at −f overlaps the Hann main lobe (±2 bins): the
            // window holds less than two periods and the peak position is not the frequency.
            self.frequency_hz[k] = if peak == usize::MAX || peak < 2 * self.zero_pad {
                f64::NAN
            } else {
                peak_frequency(power, peak) * self.bin_hz
            };
        }
    }
}

/// Bin weights of `band`: the fraction of each bin's extent inside the band.
fn band_weights(band: &Band, bin_hz: f64, n_bins: usize) -> BandBins {
    let lo_bin = ((band.lo_hz / bin_hz) - 0.5).floor().max(0.0) as usize;
    if lo_bin >= n_bins {
        // Entirely above Nyquist: no bins (the pipeline flags `band_out_of_range`).
        return BandBins {
            first_bin: 0,
            weights: Vec::new(),
            weighted: 0..0,
            cumulative: vec![0.0],
        };
    }
    let hi_bin = (((band.hi_hz / bin_hz) + 0.5).ceil() as usize).min(n_bins.saturating_sub(1));
    let mut weights = Vec::new();
    for b in lo_bin..=hi_bin.max(lo_bin) {
        let f = b as f64 * bin_hz;
        let (a, z) = (f - 0.5 * bin_hz, f + 0.5 * bin_hz);
        let overlap = (z.min(band.hi_hz) - a.max(band.lo_hz)).max(0.0);
        weights.push(if b < n_bins { overlap / bin_hz } else { 0.0 });
    }
    let start = weights.iter().position(|w| *w > 0.0).unwrap_or(0);
    let end = weights
        .iter()
        .rposition(|w| *w > 0.0)
        .map_or(start, |i| i + 1);
    debug_assert!(weights[start..end].iter().all(|w| *w > 0.0));
    let cumulative = std::iter::once(0.0)
        .chain(weights.iter().scan(0.0, |sum, w| {
            *sum += w;
            Some(*sum)
        }))
        .collect();
    BandBins {
        first_bin: lo_bin,
        weights,
        weighted: start..end,
        cumulative,
    }
}

/// The local maximum of `power` reached from bin `k` by walking uphill.
fn climb(power: &[f64], mut k: usize) -> usize {
    loop {
        if k > 0 && power[k - 1] > power[k] {
            k -= 1;
        } else if k + 1 < power.len() && power[k + 1] > power[k] {
            k += 1;
        } else {
            return k;
        }
    }
}

/// Fractional bin of the spectral peak at integer bin `k`: parabola through the log powers of
/// bins k−1, k, k+1 (Gaussian interpolation).
fn peak_frequency(power: &[f64], k: usize) -> f64 {
    if k == 0 || k + 1 >= power.len() {
        return k as f64;
    }
    let (a, b, c) = (power[k - 1], power[k], power[k + 1]);
    if a <= 0.0 || b <= 0.0 || c <= 0.0 {
        return k as f64;
    }
    let (la, lb, lc) = (a.ln(), b.ln(), c.ln());
    let denom = la - 2.0 * lb + lc;
    if denom >= 0.0 {
        return k as f64;
    }
    let delta = 0.5 * (la - lc) / denom;
    k as f64 + delta.clamp(-0.5, 0.5)
}

impl FrontEnd for StftFrontEnd {
    fn memory_bytes(&self) -> usize {
        stft_memory_bytes(self.window.len(), self.zero_pad, self.bands.len()) as usize
    }

    fn bands(&self) -> &[Band] {
        &self.bands
    }

    fn resolution(&self) -> Resolution {
        let n = self.window.len() as f64;
        Resolution {
            frame_period_s: self.hop as f64 / self.sample_rate_hz,
            time_resolution_s: n / self.sample_rate_hz,
            frequency_resolution_hz: self.sample_rate_hz / n,
        }
    }

    fn process(&mut self, samples: &[f64], sink: &mut dyn FrameSink) {
        self.process_ahead(samples, &[], sink)
    }

    fn process_ahead(&mut self, samples: &[f64], ahead: &[f64], sink: &mut dyn FrameSink) {
        self.pending.extend_from_slice(samples);
        let w = self.window.len();
        let pairs = self.transform.pairs_frames();
        while self.next_frame + w <= self.pending.len() {
            if self.has_early {
                sink.frame(Frame {
                    energy: &self.early.energy,
                    frequency_hz: &self.early.frequency_hz,
                    active: None,
                });
                self.has_early = false;
                self.next_frame += self.hop;
            } else if pairs && self.next_frame + self.hop + w <= self.pending.len() + ahead.len() {
                let both_emitted = self.next_frame + self.hop + w <= self.pending.len();
                self.compute_pair(self.next_frame, ahead, sink);
                self.next_frame += if both_emitted { 2 } else { 1 } * self.hop;
            } else {
                self.compute_frame(self.next_frame, sink);
                self.next_frame += self.hop;
            }
        }
        if self.next_frame >= w {
            let spent = self.next_frame.min(self.pending.len());
            self.pending.drain(..spent);
            self.next_frame -= spent;
        }
    }

    fn lookahead_samples(&self) -> usize {
        match self.transform.pairs_frames() {
            true => self.hop,
            false => 0,
        }
    }

    fn finish(&mut self, _sink: &mut dyn FrameSink) {
        // Only whole frames are emitted: a partial last window would bias the energy (and an
        // early frame was never completed by the input).
        self.reset();
    }

    fn reset(&mut self) {
        self.pending.clear();
        self.next_frame = 0;
        self.has_early = false;
    }

    fn name(&self) -> &'static str {
        "stft"
    }

    fn mode_gain(&self, band: usize, f_hz: f64, sigma_per_s: f64) -> f64 {
        // Every frame sees the mode through the same decaying window (up to a scale), so one
        // frame's band energy is the gain: Σ_bins w |G(θ_bin ∓ ω)|² over both images of the
        // real mode.
        let bb = &self.band_bins[band];
        let a = sigma_per_s / self.sample_rate_hz;
        let omega = 2.0 * std::f64::consts::PI * f_hz / self.sample_rate_hz;
        super::hann_gain::band_mode_gain(
            self.isa,
            &self.hann_grid,
            bb.first_bin,
            &bb.weights,
            a,
            omega,
        )
    }

    fn mode_gain_bound(&self, band: usize, f_hz: f64, sigma_per_s: f64) -> f64 {
        let bb = &self.band_bins[band];
        let a = sigma_per_s / self.sample_rate_hz;
        let omega = 2.0 * std::f64::consts::PI * f_hz / self.sample_rate_hz;
        super::hann_gain::band_mode_gain_bound(
            self.isa,
            &self.hann_grid,
            bb.first_bin,
            &bb.weights,
            &bb.cumulative,
            a,
            omega,
        )
    }

    fn frequency_tolerance_hz(&self) -> f64 {
        0.5 * self.sample_rate_hz / self.window.len() as f64
    }

    fn white_noise_energy(&self, band: usize) -> Option<f64> {
        // Every bin of a windowed white frame holds Σ w² on average (zero padding adds bins,
        // not energy per bin); the band sums its bins with their edge weights. Σ w² of a
        // periodic Hann window of n ≥ 3 samples is 3n/8 (asked per band of every channel:
        // no pass over the window).
        let n = self.window.len();
        let window_energy = if n >= 3 {
            0.375 * n as f64
        } else {
            self.window.iter().map(|w| w * w).sum()
        };
        let bins: f64 = self.band_bins.get(band)?.weights.iter().sum();
        Some(window_energy * bins)
    }

    fn flat_gain(&self, band: usize, lo_hz: f64, hi_hz: f64) -> f64 {
        // It depends only on the transform and the two ranges, and every channel asks for the
        // same few: once per process (its 66 band sums were a third of a short run's time).
        let b = &self.bands[band];
        let key = FlatGainKey(vec![
            STFT_TAG,
            self.sample_rate_hz.to_bits(),
            self.window.len() as u64,
            self.zero_pad as u64,
            b.lo_hz.to_bits(),
            b.hi_hz.to_bits(),
            lo_hz.to_bits(),
            hi_hz.to_bits(),
        ]);
        memoized_flat_gain(key, || {
            super::simpson_flat_gain(|f_hz| self.mode_gain(band, f_hz, 0.0), lo_hz, hi_hz)
        })
    }
}

#[cfg(test)]
mod tests;

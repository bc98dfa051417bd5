//! Front ends: one channel's samples → per band, a sequence of energy values at a frame rate.
//!
//! Every front end is streaming and stateful: [`FrontEnd::process`] may be called with blocks of
//! any size; completed frames are handed to a sink as they become available. One front end
//! instance serves one channel and one decay at a time; [`FrontEnd::reset`] prepares it for the
//! next decay.

pub mod auto_bands;
pub mod bands;
pub mod buffered;
pub(crate) mod decay_arena;
mod gain_memo;
pub mod goyder;
mod hann_gain;
pub mod iec_bands;
pub(crate) mod lane_acos;
pub(crate) mod lane_atan2;
pub mod octave_bank;
pub(crate) mod simd;
pub mod stft;
#[cfg(test)]
pub(crate) mod test_frames;

use crate::decay::FrequencyCoding;
pub use bands::Band;
pub use buffered::FilterDirection;

/// How finely a front end resolves time and frequency, for side-by-side comparisons.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Resolution {
    /// Time between successive energy values, in seconds.
    pub frame_period_s: f64,
    /// Length of the time span that one energy value summarises, in seconds
    /// (STFT: the window; filter bank: about 1/B).
    pub time_resolution_s: f64,
    /// Frequency resolution in Hz (STFT: bin spacing; filter bank: bandwidth).
    pub frequency_resolution_hz: f64,
}

/// One frame of output: per band, the energy and the frequency actually present.
///
/// Both slices have one entry per band, in the order of [`FrontEnd::bands`].
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    /// Band energy of this frame (arbitrary but consistent units, e.g. Σ|X|² over the band).
    pub energy: &'a [f64],
    /// Dominant frequency in the band during this frame, in Hz; `NaN` when unknown.
    pub frequency_hz: &'a [f64],
    /// Which bands this frame holds (`None`: all). A filter bank's narrow bands end earlier
    /// than its wide ones (their start-up transient occupies more of the record's end); their
    /// entries past that point are not part of the decay and must be skipped.
    pub active: Option<&'a [bool]>,
}

/// Receives frames from a front end as they are completed.
pub trait FrameSink {
    /// Called once per completed frame, in time order.
    fn frame(&mut self, frame: Frame<'_>);

    /// Told before `frames` frames come at once (a buffered bank emitting a whole decay), so
    /// that the sink can make room for them in one step.
    fn expect_frames(&mut self, _frames: usize) {}

    /// A whole decay's frames at once (a buffered bank), band by band: with n =
    /// `energy.len() / bands` frames, band b's are `energy[b · n .. (b + 1) · n]` (frequencies
    /// likewise, coded by `coding`), and band b takes part up to frame `band_frames[b]`
    /// (exclusive; `bands` = `band_frames.len()`). The same as one [`FrameSink::frame`] per
    /// frame, in order, with the frequencies decoded and `active` marking the bands still in; a
    /// sink may take them in bulk (each band's frames contiguous: a frame-major layout had every
    /// band's pass stride over all of them) and keep the frequencies coded.
    fn frames(
        &mut self,
        energy: &[f64],
        frequency: &[f64],
        coding: FrequencyCoding,
        band_frames: &[usize],
    ) {
        let nb = band_frames.len();
        if nb == 0 {
            return;
        }
        let n = energy.len() / nb;
        let (mut active, mut row_e, mut row_f) = (vec![true; nb], vec![0.0; nb], vec![0.0; nb]);
        for k in 0..n {
            for b in 0..nb {
                active[b] = k < band_frames[b];
                row_e[b] = energy[b * n + k];
                row_f[b] = coding.to_hz(frequency[b * n + k]);
            }
            self.frame(Frame {
                energy: &row_e,
                frequency_hz: &row_f,
                active: (!active.iter().all(|a| *a)).then_some(active.as_slice()),
            });
        }
    }
}

impl<F: FnMut(Frame<'_>)> FrameSink for F {
    fn frame(&mut self, frame: Frame<'_>) {
        self(frame)
    }
}

/// Turns one channel's samples (starting at a decay onset) into band energies per frame.
pub trait FrontEnd: Send {
    /// The bands this front end produces, in output order.
    fn bands(&self) -> &[Band];

    /// Time and frequency resolution of this front end.
    fn resolution(&self) -> Resolution;

    /// Feeds samples of the current decay. Completed frames go to `sink` in time order.
    fn process(&mut self, samples: &[f64], sink: &mut dyn FrameSink);

    /// [`FrontEnd::process`], told the samples that follow (`ahead`: what the next calls will
    /// pass first, possibly fewer). A front end may compute later frames early with them (the
    /// STFT of an odd frame length transforms two frames at once), but emits only the frames
    /// that `samples` and the earlier calls complete: the same frames, at the same calls, as
    /// [`FrontEnd::process`]. By default the samples ahead are ignored.
    fn process_ahead(&mut self, samples: &[f64], ahead: &[f64], sink: &mut dyn FrameSink) {
        let _ = ahead;
        self.process(samples, sink)
    }

    /// Samples ahead of a completed frame that [`FrontEnd::process_ahead`] needs to share its
    /// work with the next frame (0: it does not look ahead). The pipeline reads blocks of
    /// several times this many frames, so that most frames find it in their block.
    fn lookahead_samples(&self) -> usize {
        0
    }

    /// Ends the current decay: emits whatever frames remain (a filter bank that needs the whole
    /// decay emits everything here).
    fn finish(&mut self, sink: &mut dyn FrameSink);

    /// Forgets the current decay so that the next call to `process` starts a new one.
    fn reset(&mut self);

    /// Samples before a decay's onset that this front end wants with it (0 by default). A bank
    /// that filters the reversed decay smears each band's share of the first arrival to before
    /// the broadband onset; with this much of what preceded the onset it keeps that energy.
    fn pre_roll_samples(&self) -> usize {
        0
    }

    /// Starts a decay (after [`FrontEnd::reset`]) with the samples that preceded its onset, at
    /// most [`FrontEnd::pre_roll_samples`] of them, oldest first. Ignored by default.
    fn begin_decay(&mut self, _pre_roll: &[f64]) {}

    /// True when the current decay outlasted what the front end buffers, so that only its
    /// first part was analysed (the rows then carry `decay_too_long`). Streaming front ends
    /// never are.
    fn decay_cut_short(&self) -> bool {
        false
    }

    /// Bytes this front end holds at most, its buffers grown to their caps (the memory budget
    /// multiplies it by the channel count before the other channels' front ends are built).
    /// The default counts per-band state only; buffering front ends add their buffers.
    fn memory_bytes(&self) -> usize {
        self.bands().len() * 256
    }

    /// A short name for tables and logs (`stft`, `goyder`, `octave`).
    fn name(&self) -> &'static str;

    /// Energy that band `band` receives from a mode at `f_hz` whose amplitude decays at
    /// `sigma_per_s` (1/s), per unit of the mode's energy, in units shared by all bands of this
    /// front end (only ratios between bands are used). The leakage test
    /// ([`crate::decay::leakage`]) predicts with it what a strong band leaks into a weak one.
    fn mode_gain(&self, band: usize, f_hz: f64, sigma_per_s: f64) -> f64;

    /// A number never below [`FrontEnd::mode_gain`] of the same arguments, for front ends that
    /// can bound it more cheaply than they compute it (the leakage test asks for the exact gain
    /// only where the bound cannot clear a band). By default, the gain itself.
    fn mode_gain_bound(&self, band: usize, f_hz: f64, sigma_per_s: f64) -> f64 {
        self.mode_gain(band, f_hz, sigma_per_s)
    }

    /// The shortest T60 (s) band `band` resolves: below it the decay measured is the band
    /// filter's own ringing ([`crate::decay::Flag::FilterLimited`]). 0 where the front end has
    /// no such limit of its own (the STFT's is its frame count, `too_few_frames`).
    fn shortest_t60_s(&self, band: usize) -> f64 {
        let _ = band;
        0.0
    }

    /// How far (Hz) the frequency a band reports may lie outside the band before it counts as
    /// another band's: half a bin for the STFT (a bin holds what lies within it), 0 for a filter.
    fn frequency_tolerance_hz(&self) -> f64 {
        0.0
    }

    /// Mean energy per frame that band `band` receives from white noise of unit variance (one
    /// unit² per sample), in the units of [`Frame::energy`]; `None` where the front end cannot
    /// say. A recording's quantization noise (step² / 12 per sample) sets the floor below which
    /// its bands hold nothing ([`crate::decay::quantization`]).
    fn white_noise_energy(&self, band: usize) -> Option<f64> {
        let _ = band;
        None
    }

    /// Mean of [`FrontEnd::mode_gain`] (stationary, σ = 0) of band `band` over `lo_hz..hi_hz`:
    /// what the band receives from content spread evenly over that range (a diffuse band of a
    /// room response, where a tone at the band's dominant frequency would be the wrong model).
    fn flat_gain(&self, band: usize, lo_hz: f64, hi_hz: f64) -> f64 {
        simpson_flat_gain(|f_hz| self.mode_gain(band, f_hz, 0.0), lo_hz, hi_hz)
    }
}

/// Mean of a stationary gain `gain(f_hz)` over `lo_hz..hi_hz` ([`FrontEnd::flat_gain`]):
/// Simpson's rule on 33 points, fine against a band's own skirts; the gain at `lo_hz` for an
/// empty or NaN range.
pub(crate) fn simpson_flat_gain(gain: impl Fn(f64) -> f64, lo_hz: f64, hi_hz: f64) -> f64 {
    const POINTS: usize = 33;
    // Also catches NaN limits.
    if hi_hz.partial_cmp(&lo_hz) != Some(std::cmp::Ordering::Greater) {
        return gain(lo_hz);
    }
    let h = (hi_hz - lo_hz) / (POINTS - 1) as f64;
    let sum: f64 = (0..POINTS)
        .map(|i| {
            let w = if i == 0 || i == POINTS - 1 {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * gain(lo_hz + i as f64 * h)
        })
        .sum();
    sum * h / 3.0 / (hi_hz - lo_hz)
}

/// Σ h[n]² of the impulse response of a cascade of biquads (as [`cascade_power`]): the mean
/// square its output has for white noise of unit variance. Run until the response has fallen
/// 200 dB below its peak (at most 2²⁴ samples, far beyond the narrowest band's ringing).
pub(crate) fn cascade_impulse_energy(sections: &[[f64; 5]]) -> f64 {
    const MAX_SAMPLES: usize = 1 << 24;
    const QUIET_SAMPLES: usize = 4096;
    let mut state = vec![[0.0f64; 4]; sections.len()];
    let (mut sum, mut peak, mut quiet) = (0.0f64, 0.0f64, 0usize);
    for n in 0..MAX_SAMPLES {
        let mut x = if n == 0 { 1.0 } else { 0.0 };
        for ([b0, b1, b2, a1, a2], [x1, x2, y1, y2]) in sections.iter().zip(&mut state) {
            let y = b0 * x + b1 * *x1 + b2 * *x2 - a1 * *y1 - a2 * *y2;
            (*x2, *x1, *y2, *y1) = (*x1, x, *y1, y);
            x = y;
        }
        let e = x * x;
        sum += e;
        peak = peak.max(e);
        quiet = if e < 1e-20 * peak { quiet + 1 } else { 0 };
        if quiet >= QUIET_SAMPLES {
            break;
        }
    }
    sum
}

/// |Π sections(z)|² of a cascade of biquads `(b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)`
/// at z⁻¹ = `z_inv` (a complex point, so that a decaying or growing mode can be evaluated).
pub(crate) fn cascade_power(
    sections: impl IntoIterator<Item = [f64; 5]>,
    z_inv: rustfft::num_complex::Complex<f64>,
) -> f64 {
    let z2 = z_inv * z_inv;
    sections
        .into_iter()
        .map(|[b0, b1, b2, a1, a2]| {
            let num = b0 + z_inv * b1 + z2 * b2;
            let den = 1.0 + z_inv * a1 + z2 * a2;
            (num / den).norm_sqr()
        })
        .product()
}

/// z⁻¹ = e^{−(σ_f + j2πf)/fs} at which a filter sees a mode at `f_hz` decaying at `sigma_per_s`:
/// in recording order the mode decays (σ_f = −σ); filtered backwards it grows (σ_f = +σ).
pub(crate) fn mode_z_inv(
    f_hz: f64,
    sigma_per_s: f64,
    reversed: bool,
    fs_hz: f64,
) -> rustfft::num_complex::Complex<f64> {
    let sigma_f = if reversed { sigma_per_s } else { -sigma_per_s };
    rustfft::num_complex::Complex::new(-sigma_f / fs_hz, -2.0 * std::f64::consts::PI * f_hz / fs_hz)
        .exp()
}

/// Default transient cut factor of the buffering banks (Goyder, octave): each band drops
/// `BANK_CUT_FACTOR / B` seconds at the end of a reversed decay, where the backward filter's
/// start-up transient lands.
pub const BANK_CUT_FACTOR: f64 = 3.0;

/// B·T60 below which a band filter measures its own ringing rather than the decay (B the
/// filter's −3 dB bandwidth, Hz; T60 in s): a 3rd-order Butterworth band-pass's slowest poles
/// decay at πB·sin(π/6), an energy T60 of 4.4 / B; Jacobsen & Rindel ("Time reversed decay
/// measurements", J. Sound Vib. 117, 1987) give B·T60 > 4 as the limit of time-reversed
/// filtering. Forward filtering stays biased up to B·T60 ≈ 16 (a few %; its number stands).
pub const BT60_MIN: f64 = 4.0;

/// Checks the settings that the buffering filter banks (Goyder, octave) share: frame period in ms
/// (> 0), the transient cut factor (≥ 0) and the longest decay buffered in s (1/fs to 1e10/fs).
/// `bank` names the bank in the error.
pub(crate) fn check_bank_settings(
    bank: &str,
    sample_rate_hz: f64,
    frame_period_ms: f64,
    cut_factor: f64,
    max_decay_s: f64,
) -> crate::error::Result<()> {
    use crate::error::Error;
    if !(frame_period_ms.is_finite() && frame_period_ms > 0.0) {
        return Err(Error::setting(
            format!("{bank} frame period"),
            format!("expected a positive number of ms, got {frame_period_ms}"),
        ));
    }
    if !(cut_factor.is_finite() && cut_factor >= 0.0) {
        return Err(Error::setting(
            format!("{bank} cut factor"),
            format!("expected a finite number >= 0, got {cut_factor}"),
        ));
    }
    if !(1.0..1e10).contains(&(max_decay_s * sample_rate_hz)) {
        return Err(Error::setting(
            format!("{bank} max decay"),
            format!("expected 1/fs to 1e10/fs seconds, got {max_decay_s} s"),
        ));
    }
    Ok(())
}

/// Resolution of a filter bank with frames `hop` samples apart: its time resolution is about
/// 1/B, or the filters' longest rise time `rise_s` when that is longer (a steep filter rings up
/// over its group delay), and its frequency resolution B for the narrowest band B.
pub(crate) fn bank_resolution(
    bands: &[Band],
    hop: usize,
    sample_rate_hz: f64,
    rise_s: f64,
) -> Resolution {
    let b_min = bands
        .iter()
        .map(|b| b.width_hz())
        .fold(f64::INFINITY, f64::min);
    Resolution {
        frame_period_s: hop as f64 / sample_rate_hz,
        time_resolution_s: (1.0 / b_min).max(rise_s),
        frequency_resolution_hz: b_min,
    }
}

/// Group delay, in samples, of a cascade of biquads `[b0, b1, b2, a1, a2]` at `f_hz`:
/// τ = Re(Σ k c_k z⁻ᵏ / Σ c_k z⁻ᵏ) of the numerator minus that of the denominator, per section.
/// A band-pass's envelope peaks about one group delay after an impulse, so this is how long a
/// steep bank takes to ring up.
pub(crate) fn cascade_group_delay_samples(
    sections: impl IntoIterator<Item = [f64; 5]>,
    f_hz: f64,
    fs_hz: f64,
) -> f64 {
    use rustfft::num_complex::Complex;
    let z1 = Complex::from_polar(1.0, -2.0 * std::f64::consts::PI * f_hz / fs_hz);
    let z2 = z1 * z1;
    let delay = |c: [f64; 3]| {
        let sum = c[0] + z1 * c[1] + z2 * c[2];
        let moment = z1 * c[1] + z2 * (2.0 * c[2]);
        if sum.norm() > 0.0 {
            (moment / sum).re
        } else {
            0.0
        }
    };
    sections
        .into_iter()
        .map(|[b0, b1, b2, a1, a2]| delay([b0, b1, b2]) - delay([1.0, a1, a2]))
        .sum()
}

thread_local! {
    /// The frame arrays of buffering banks (energies, frequencies), one pair per thread: every
    /// channel's decay needs them only while it is estimated. Fresh arrays per decay were half a
    /// megabyte per channel faulted in and given back (10 s at 4096 Hz, 2 ms frames, 6 bands).
    static BAND_FRAME_ARRAYS: std::cell::RefCell<(Vec<f64>, Vec<f64>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// Runs `f` with this thread's frame arrays of a buffering bank, both `len` long and zero;
/// with `overwritten` (a bank that writes every entry) they hold whatever the thread's last
/// decay left instead, which spares zeroing half a megabyte per decay (0.8 % of a 64-channel
/// octave-bank run at 4096 Hz).
pub(crate) fn with_band_frame_arrays<R>(
    len: usize,
    overwritten: bool,
    f: impl FnOnce(&mut [f64], &mut [f64]) -> R,
) -> R {
    let run = |arrays: &mut (Vec<f64>, Vec<f64>)| {
        for v in [&mut arrays.0, &mut arrays.1] {
            if overwritten {
                v.truncate(len);
            } else {
                v.clear();
            }
            v.resize(len, 0.0);
        }
        f(&mut arrays.0, &mut arrays.1)
    };
    with_thread_scratch(&BAND_FRAME_ARRAYS, run)
}

/// Runs `f` with this thread's scratch held in `key`. Scratch kept per thread serves every
/// channel the thread analyses and stays mapped (and in the cache); kept per front end or made
/// per decay, it was faulted in again and again. A fresh one only if the scratch is already in
/// use (a transform or bank running inside another's, which none does).
pub(crate) fn with_thread_scratch<T: Default + 'static, R>(
    key: &'static std::thread::LocalKey<std::cell::RefCell<T>>,
    f: impl FnOnce(&mut T) -> R,
) -> R {
    key.with(|cell| match cell.try_borrow_mut() {
        Ok(mut scratch) => f(&mut scratch),
        Err(_) => f(&mut T::default()),
    })
}

/// Emits the frames of a buffering bank, band by band ([`FrameSink::frames`]): band b holds
/// frames `0 .. band_frames[b]` (its own transient cut) and is marked inactive after them. Each
/// band's own start (its energy within 20 dB of its peak) is found by the estimator
/// ([`crate::decay::schroeder::DECAY_START_LEVEL_DB`]), the same for every front end.
pub(crate) fn emit_band_frames(
    sink: &mut dyn FrameSink,
    energy: &[f64],
    frequency: &[f64],
    coding: FrequencyCoding,
    band_frames: &[usize],
) {
    let nb = band_frames.len();
    if nb == 0 {
        return;
    }
    sink.expect_frames(energy.len() / nb);
    sink.frames(energy, frequency, coding, band_frames);
}

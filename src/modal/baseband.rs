//! Band by band: each sub-band of the analysis range is shifted to 0 Hz, low-pass filtered
//! **backwards in time** and decimated to a few times its width (METHODS.md §7).
//!
//! Why backwards: a free decay is a sum of exponentials for t ≥ 0. An anti-causal filter's output
//! at t ≥ 0 only depends on the input at times ≥ t, so it is again an exact sum of the same
//! exponentials (each scaled by the filter's response at its pole); the filter's own ring-down,
//! and whatever the excitation did at t ≤ 0, fall before the start and are discarded. Only the
//! record's end, where the reversed filter starts up, carries a transient: that part is cut.

use faer::{c64, Mat};

/// Order of the Butterworth low-pass (6 biquads): at four times the cut-off, where content
/// begins to fold into the band after decimation, it is 144 dB down.
pub const LOWPASS_ORDER: usize = 12;
/// The decimated rate is at least this many times the analysed half-width (content above
/// (ratio − 1) half-widths folds in, at ≥ 114 dB attenuation).
pub const DECIMATED_RATE_PER_HALF_WIDTH: f64 = 4.0;
/// Time constants of the filter cut from the record's end (the reversed filter's start-up).
const END_CUT_TIME_CONSTANTS: f64 = 3.0;

/// One sub-band: poles are accepted in `lo_hz..hi_hz`; the signal is analysed over that range
/// widened by `guard_hz` on both sides, so that modes near the edges are not cut in half.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubBand {
    /// Lower edge of the accepted range, Hz.
    pub lo_hz: f64,
    /// Upper edge of the accepted range, Hz.
    pub hi_hz: f64,
    /// Extra width analysed beyond each edge, Hz.
    pub guard_hz: f64,
}

impl SubBand {
    /// Centre of the band, Hz (the heterodyne frequency).
    pub fn center_hz(&self) -> f64 {
        0.5 * (self.lo_hz + self.hi_hz)
    }

    /// Half the analysed width (accepted range plus guards), Hz: the low-pass cut-off.
    pub fn half_width_hz(&self) -> f64 {
        0.5 * (self.hi_hz - self.lo_hz) + self.guard_hz
    }
}

/// How the analysis range is cut into sub-bands: each is `relative_width` times its lower edge
/// wide, within `min_width_hz..=max_width_hz`, with `guard_fraction` of its width analysed on
/// both sides. Narrow bands at low frequency keep the in-band noise low where the modes are
/// weakest (acceleration falls as f²); wide bands higher up keep the count of bands down.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SubBandPlan {
    /// Narrowest sub-band, Hz.
    pub min_width_hz: f64,
    /// Widest sub-band, Hz.
    pub max_width_hz: f64,
    /// Width as a fraction of the lower edge.
    pub relative_width: f64,
    /// Guard on each side as a fraction of the width.
    pub guard_fraction: f64,
}

/// Most of an analysed record the end cut of a sub-band may take.
pub const MAX_END_CUT_FRACTION: f64 = 0.3;

impl SubBandPlan {
    /// The plan widened for a record of `record_s` seconds after the analysis start: a band's
    /// filter needs `END_CUT_TIME_CONSTANTS` time constants cut from the end, which for a
    /// narrow band can be most of a short record (0.76 s for 10 Hz bands, so a 1 s impact
    /// record would lose every low band); no band is made so narrow that its cut exceeds
    /// [`MAX_END_CUT_FRACTION`] of the record. Unchanged for records of 3 s and more.
    pub fn fitted_to_record(&self, record_s: f64) -> SubBandPlan {
        let cut_s = MAX_END_CUT_FRACTION * record_s.max(1e-9);
        // end cut = k·order/(2π h), with the filter half-width h = (½ + guard)·width.
        let min_half_width =
            END_CUT_TIME_CONSTANTS * LOWPASS_ORDER as f64 / (2.0 * std::f64::consts::PI * cut_s);
        let min_width = min_half_width / (0.5 + self.guard_fraction);
        SubBandPlan {
            min_width_hz: self.min_width_hz.max(min_width),
            max_width_hz: self.max_width_hz.max(min_width),
            ..*self
        }
    }
}

/// Splits `fmin_hz..fmax_hz` into consecutive sub-bands as `plan` says (the last one ends at
/// `fmax_hz`; a remainder narrower than half the minimum width joins the band before it).
pub fn plan_subbands(fmin_hz: f64, fmax_hz: f64, plan: &SubBandPlan) -> Vec<SubBand> {
    let mut out: Vec<SubBand> = Vec::new();
    if !(fmax_hz > fmin_hz && plan.min_width_hz > 0.0 && plan.max_width_hz >= plan.min_width_hz) {
        return out;
    }
    let width = |lo: f64| (plan.relative_width * lo).clamp(plan.min_width_hz, plan.max_width_hz);
    let mut lo = fmin_hz;
    while lo < fmax_hz {
        let w = width(lo);
        let mut hi = (lo + w).min(fmax_hz);
        if fmax_hz - hi < 0.5 * plan.min_width_hz {
            hi = fmax_hz;
        }
        out.push(SubBand {
            lo_hz: lo,
            hi_hz: hi,
            guard_hz: plan.guard_fraction * (hi - lo),
        });
        lo = hi;
    }
    out
}

/// A sub-band's channels at baseband: `data` is channels × samples, sample `t` at time
/// `t / fs_hz` after the analysis start, frequency `f` of the recording at `f − center_hz`.
pub struct Baseband {
    /// The heterodyne frequency, Hz.
    pub center_hz: f64,
    /// The decimated sample rate, Hz.
    pub fs_hz: f64,
    /// Complex samples, channels × time.
    pub data: Mat<c64>,
    /// Decay rate an exponential window added to every pole, 1/s (1/τ of a window e^(−t/τ));
    /// subtracted from every pole's decay rate.
    pub window_decay_per_s: f64,
}

impl Baseband {
    /// Frequency (Hz) and damping ratio of a pole `z` of the decimated baseband signal.
    pub fn frequency_and_damping(&self, z: c64) -> (f64, f64) {
        let two_pi = 2.0 * std::f64::consts::PI;
        let lambda =
            z.ln() * self.fs_hz + c64::new(self.window_decay_per_s, two_pi * self.center_hz);
        (lambda.im / two_pi, -lambda.re / lambda.norm())
    }
}

/// One biquad section's coefficients (a0 normalised to 1).
#[derive(Clone, Copy, Debug)]
struct Section {
    b: [f64; 3],
    a: [f64; 2],
}

/// Butterworth low-pass of order [`LOWPASS_ORDER`] as biquads (bilinear transform, RBJ form).
fn butterworth_sections(cutoff_hz: f64, fs_hz: f64) -> Vec<Section> {
    let w0 = 2.0 * std::f64::consts::PI * cutoff_hz / fs_hz;
    (0..LOWPASS_ORDER / 2)
        .map(|k| {
            let theta = std::f64::consts::PI * (2 * k + 1) as f64 / (2 * LOWPASS_ORDER) as f64;
            let q = 1.0 / (2.0 * theta.sin());
            let alpha = w0.sin() / (2.0 * q);
            let c = w0.cos();
            let a0 = 1.0 + alpha;
            Section {
                b: [(1.0 - c) / 2.0 / a0, (1.0 - c) / a0, (1.0 - c) / 2.0 / a0],
                a: [-2.0 * c / a0, (1.0 - alpha) / a0],
            }
        })
        .collect()
}

/// Decimation factor and samples kept for a sub-band of a record of `n` samples starting at
/// `start`: (factor, decimated length).
pub fn decimation(sub: &SubBand, fs_hz: f64, start: usize, n: usize) -> (usize, usize) {
    let h = sub.half_width_hz();
    let factor = ((fs_hz / (DECIMATED_RATE_PER_HALF_WIDTH * h)).floor() as usize).max(1);
    let time_constant_s = LOWPASS_ORDER as f64 / (2.0 * std::f64::consts::PI * h);
    let end_cut = (END_CUT_TIME_CONSTANTS * time_constant_s * fs_hz).ceil() as usize;
    let usable = n.saturating_sub(start).saturating_sub(end_cut);
    (factor, usable.div_ceil(factor))
}

/// Heterodynes, filters backwards and decimates every channel of `channels` (equal lengths) for
/// `sub`, keeping samples from index `start` on.
pub fn to_baseband(channels: &[Vec<f64>], fs_hz: f64, sub: &SubBand, start: usize) -> Baseband {
    let n = channels.first().map_or(0, Vec::len);
    let (factor, len) = decimation(sub, fs_hz, start, n);
    let sections = butterworth_sections(sub.half_width_hz(), fs_hz);
    let center = sub.center_hz();
    let dphi = -2.0 * std::f64::consts::PI * center / fs_hz;
    // The carrier e^{−jωn}, computed once for all channels.
    let carrier: Vec<c64> = (0..n)
        .map(|i| {
            let p = dphi * i as f64;
            c64::new(p.cos(), p.sin())
        })
        .collect();
    let mut data = Mat::<c64>::zeros(channels.len(), len);
    let mut y = vec![c64::new(0.0, 0.0); n];
    for (c, x) in channels.iter().enumerate() {
        for i in 0..n {
            y[i] = carrier[i] * x[i];
        }
        for s in &sections {
            // Direct form II transposed, run from the record's end to its start.
            let (mut z1, mut z2) = (c64::new(0.0, 0.0), c64::new(0.0, 0.0));
            for v in y.iter_mut().rev() {
                let input = *v;
                let out = input * s.b[0] + z1;
                z1 = input * s.b[1] - out * s.a[0] + z2;
                z2 = input * s.b[2] - out * s.a[1];
                *v = out;
            }
        }
        for t in 0..len {
            data[(c, t)] = y[start + t * factor];
        }
    }
    Baseband {
        center_hz: center,
        fs_hz: fs_hz / factor as f64,
        data,
        window_decay_per_s: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A decaying tone in the band comes out as one complex exponential with the same pole:
    /// the ratio of successive decimated samples is e^{(−σ + j2π(f − fc)) / fs_d}.
    #[test]
    fn a_free_decay_stays_one_exponential_with_its_pole() {
        let fs = 4000.0;
        let (f, sigma) = (57.0, 2.0);
        let x: Vec<f64> = (0..12000)
            .map(|i| {
                let t = i as f64 / fs;
                (-sigma * t).exp() * (2.0 * std::f64::consts::PI * f * t + 0.3).cos()
            })
            .collect();
        // Strong out-of-band content must not leak in.
        let y: Vec<f64> = (0..12000)
            .map(|i| {
                let t = i as f64 / fs;
                x[i] + 30.0 * (-3.0 * t).exp() * (2.0 * std::f64::consts::PI * 400.0 * t).cos()
            })
            .collect();
        let sub = SubBand {
            lo_hz: 40.0,
            hi_hz: 80.0,
            guard_hz: 10.0,
        };
        let b = to_baseband(&[y], fs, &sub, 0);
        let want = c64::new(
            -sigma / b.fs_hz,
            2.0 * std::f64::consts::PI * (f - b.center_hz) / b.fs_hz,
        )
        .exp();
        let n = b.data.ncols();
        for t in 1..n / 2 {
            let r = b.data[(0, t)] / b.data[(0, t - 1)];
            assert!(
                (r - want).norm() < 1e-4,
                "sample {t}: ratio {r}, want {want}"
            );
        }
    }
}

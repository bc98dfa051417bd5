//! The noise floor of each channel, a measurement fact the diagnosis reports and never takes
//! for damping (the identification's σ carries its effect on each mode).
//!
//! An impulse response's high-frequency content dies out first: a mode at 0.3 fs with 2.5 %
//! damping has decayed by hundreds of dB by the second half of a record of a few seconds,
//! while white measurement noise stays. So the late part of each channel (its last
//! [`LATE_FRACTION`]) is taken to the frequency domain, and the median power density over
//! [`NOISE_BAND`] of the sample rate (clear of the anti-aliasing roll-off, robust to a stray
//! peak) sets the noise level: σ² = PSD_median / ln 2 per bin (the median of an exponential
//! variable is ln 2 times its mean), times the bandwidth. The SNR is on mean signal power, the
//! definition the recordings are judged by: 10 log10((P_channel − σ²) / σ²), P_channel the
//! channel's mean power over the whole record.

use realfft::RealFftPlanner;

use crate::modal::Recordings;

/// The part of the record, from its end, whose spectrum sets the noise level.
pub const LATE_FRACTION: f64 = 0.4;
/// The band, as fractions of the sample rate, whose median power density is the noise's.
pub const NOISE_BAND: (f64, f64) = (0.3, 0.45);
/// A noise floor is reported when the median channel's SNR is below this, dB: a 60 dB decay
/// (T60) with 10 dB to spare cannot be evaluated above such a floor in every band.
pub const REPORT_BELOW_SNR_DB: f64 = 70.0;
/// Least samples in the late part.
const MIN_LATE_SAMPLES: usize = 64;

/// Each channel's SNR on mean signal power, dB (`None` for a channel too short or silent).
pub fn channel_snr_db(rec: &Recordings) -> Vec<Option<f64>> {
    let mut planner = RealFftPlanner::<f64>::new();
    rec.channels
        .iter()
        .map(|x| snr_of(x, &mut planner))
        .collect()
}

fn snr_of(x: &[f64], planner: &mut RealFftPlanner<f64>) -> Option<f64> {
    let n = ((x.len() as f64) * LATE_FRACTION) as usize;
    if n < MIN_LATE_SAMPLES {
        return None;
    }
    let late = &x[x.len() - n..];
    // Hann window, scaled so that white noise of variance σ² gives |X|² = σ² n on average.
    let w: Vec<f64> = (0..n)
        .map(|i| (std::f64::consts::PI * i as f64 / n as f64).sin().powi(2))
        .collect();
    let norm = (w.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    let mut buf: Vec<f64> = late.iter().zip(&w).map(|(v, w)| v * w / norm).collect();
    let fft = planner.plan_fft_forward(n);
    let mut spec = fft.make_output_vec();
    fft.process(&mut buf, &mut spec).ok()?;
    let (lo, hi) = (
        (NOISE_BAND.0 * n as f64) as usize,
        ((NOISE_BAND.1 * n as f64) as usize).min(spec.len()),
    );
    if hi <= lo + 4 {
        return None;
    }
    let mut power: Vec<f64> = spec[lo..hi]
        .iter()
        .map(|c| c.norm_sqr() / n as f64)
        .collect();
    power.sort_by(f64::total_cmp);
    let sigma2 = power[power.len() / 2] / std::f64::consts::LN_2;
    let mean_power = x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64;
    if !(sigma2 > 0.0 && mean_power > sigma2) {
        return if mean_power > 0.0 && sigma2 > 0.0 {
            Some(10.0 * (mean_power / sigma2).log10().min(0.0))
        } else {
            None
        };
    }
    Some(10.0 * ((mean_power - sigma2) / sigma2).log10())
}

/// The median of the channels' SNRs, dB (`None` when none could be measured).
pub fn median_snr_db(snr: &[Option<f64>]) -> Option<f64> {
    let mut v: Vec<f64> = snr.iter().flatten().copied().collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A decaying sine pair with white noise added at 40 dB and 55 dB on mean power: the
    /// measured SNR is within 1.5 dB of the truth.
    #[test]
    fn the_snr_of_a_noisy_decay_is_measured() {
        let fs = 1000.0;
        let n = 3000;
        let clean: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                (-0.8 * t).exp() * (2.0 * std::f64::consts::PI * 12.0 * t).sin()
                    + 0.5 * (-6.0 * t).exp() * (2.0 * std::f64::consts::PI * 90.0 * t).sin()
            })
            .collect();
        let p = clean.iter().map(|v| v * v).sum::<f64>() / n as f64;
        for snr in [40.0, 55.0] {
            let sigma = (p / 10f64.powf(snr / 10.0)).sqrt();
            let mut state = 7u64;
            let x: Vec<f64> = clean
                .iter()
                .map(|v| {
                    // Box–Muller on a splitmix64 stream.
                    let mut next = || {
                        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
                        let mut z = state;
                        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
                        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
                        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
                    };
                    let (u1, u2) = (next().max(1e-300), next());
                    v + sigma * (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
                })
                .collect();
            let rec = Recordings {
                fs_hz: fs,
                names: vec!["a".into()],
                channels: vec![x],
            };
            let got = channel_snr_db(&rec)[0].unwrap();
            assert!((got - snr).abs() < 1.5, "{snr}: {got}");
        }
    }
}

//! Test helpers shared by the front ends' tests: a decaying sine, and a decay's frames as bits.

use super::{Frame, FrontEnd};

/// `n` samples at `fs_hz` of exp(−`sigma_per_s` t) sin(2π `f_hz` t).
pub(crate) fn decaying_sine(fs_hz: f64, f_hz: f64, sigma_per_s: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let t = i as f64 / fs_hz;
            (-sigma_per_s * t).exp() * (2.0 * std::f64::consts::PI * f_hz * t).sin()
        })
        .collect()
}

/// Every frame's energies and frequencies, as bits, of `x` taken by `fe` as one decay.
pub(crate) fn decay_frame_bits(fe: &mut dyn FrontEnd, x: &[f64]) -> Vec<u64> {
    let mut out = Vec::new();
    let mut sink = |f: Frame<'_>| {
        out.extend(f.energy.iter().chain(f.frequency_hz).map(|v| v.to_bits()));
    };
    fe.begin_decay(&[]);
    fe.process(x, &mut sink);
    fe.finish(&mut sink);
    out
}

/// Per band, the mean frame energy of `seconds` of white Gaussian noise of unit variance at
/// `fs_hz` taken by `fe` as one decay: the middle 80 % of each band's active frames (the ends
/// hold the filters' start-up and the reversed banks' cut).
pub(crate) fn white_noise_frame_means(fe: &mut dyn FrontEnd, fs_hz: f64, seconds: f64) -> Vec<f64> {
    let mut noise = crate::source::noise::GaussianNoise::new(0x5eed);
    let x: Vec<f64> = (0..(seconds * fs_hz) as usize)
        .map(|_| noise.next_gaussian())
        .collect();
    let nb = fe.bands().len();
    let mut per_band: Vec<Vec<f64>> = vec![Vec::new(); nb];
    let mut sink = |f: Frame<'_>| {
        for (b, e) in f.energy.iter().enumerate() {
            if f.active.is_none_or(|a| a[b]) {
                per_band[b].push(*e);
            }
        }
    };
    fe.begin_decay(&[]);
    fe.process(&x, &mut sink);
    fe.finish(&mut sink);
    per_band
        .iter()
        .map(|e| {
            let kept = &e[e.len() / 10..e.len() - e.len() / 10];
            kept.iter().sum::<f64>() / kept.len() as f64
        })
        .collect()
}

/// Holds `fe`'s [`FrontEnd::white_noise_energy`] of every band to the mean frame energy of
/// white noise through it, within `tolerance` (relative).
pub(crate) fn assert_white_noise_energy(
    fe: &mut dyn FrontEnd,
    fs_hz: f64,
    seconds: f64,
    tolerance: f64,
) {
    let measured = white_noise_frame_means(fe, fs_hz, seconds);
    for (b, m) in measured.iter().enumerate() {
        let predicted = fe.white_noise_energy(b).expect("a white-noise energy");
        let band = &fe.bands()[b];
        assert!(
            (predicted / m - 1.0).abs() < tolerance,
            "{} band {:.1}–{:.1} Hz: predicted {predicted:.6e}, measured {m:.6e}",
            fe.name(),
            band.lo_hz,
            band.hi_hz
        );
    }
}

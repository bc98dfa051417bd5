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

//! Restarts inside one band's decay: a new hit folded into the decay (the stream was not split
//! there), which makes its Schroeder curve the sum of several decays.
//!
//! A restart is a frame k whose energy is at least [`RESTART_JUMP_DB`] above every frame from
//! k − 2g to k − g, g = `rise_frames` (the gap lets the hit enter the front end's window), and
//! no more than [`RESTART_LEVEL_DB`] below the band's peak. A decaying
//! sum of modes cannot do that, whatever its beating: rising from a beat null by 10 dB of energy
//! takes longer than the gap unless the compared frames still hold the envelope before the null,
//! which is higher (see [`crate::pipeline::segment::onset::RetriggerWatch`] for the same test on samples).

/// Energy rise, in dB, that marks a restart (×10 in energy, ×3.16 in amplitude).
pub const RESTART_JUMP_DB: f64 = 10.0;

/// Restarts further below the band's peak than this, in dB, are not looked at (noise frames
/// fluctuate; a band whose noise lies within 20 dB of its peak has no number anyway).
pub const RESTART_LEVEL_DB: f64 = 20.0;

/// Frames whose level test is made at once before any is looked at alone: most of a decay is
/// tail far below its peak, and one compare and branch per frame was most of this test's time.
const SCAN_CHUNK: usize = 16;

/// The first frame of `energies` that restarts the decay, or `None`. `rise_frames` (≥ 1) is
/// how many frames a new hit takes to enter the front end's window fully.
pub fn first_restart(energies: &[f64], rise_frames: usize) -> Option<usize> {
    let test = RestartTest::new(rise_frames, super::peak_or_zero(energies))?;
    let g = test.g;
    // Frames as the window's maximum counts them (NaN and negative frames as 0).
    let counted = |e: f64| if e > 0.0 { e } else { 0.0 };
    // The window's maximum only where the level test passes (the early decay); the tail is
    // skipped a chunk at a time.
    let mut k = 2 * g;
    while k < energies.len() {
        if let Some(chunk) = energies.get(k..k + SCAN_CHUNK) {
            if !chunk.iter().fold(false, |any, &e| any | (e >= test.level)) {
                k += SCAN_CHUNK;
                continue;
            }
        }
        let e = energies[k];
        // The window's last frame bounds its maximum from below, and a decay almost never
        // rises 10 dB over g frames: one compare rejects nearly every frame before the window
        // (tens of frames with the Goyder bank's slow rise) is folded.
        if e >= test.level
            && e > test.jump * counted(energies[k - g])
            && e > test.jump * super::peak_or_zero(&energies[k - 2 * g..=k - g])
        {
            return Some(k);
        }
        k += 1;
    }
    None
}

/// The restart test's constants for one band's frames, computed once.
struct RestartTest {
    /// Frames a new hit takes to enter the window (≥ 1).
    g: usize,
    /// The lowest energy a restart may have: [`RESTART_LEVEL_DB`] below the band's peak.
    level: f64,
    /// The rise a restart makes: [`RESTART_JUMP_DB`] as an energy ratio.
    jump: f64,
}

impl RestartTest {
    /// The test with `rise_frames` for a band peaking at `peak`; `None` for a band without
    /// energy.
    fn new(rise_frames: usize, peak: f64) -> Option<Self> {
        (peak > 0.0).then(|| RestartTest {
            g: rise_frames.max(1),
            level: peak * 10f64.powf(-RESTART_LEVEL_DB / 10.0),
            jump: 10f64.powf(RESTART_JUMP_DB / 10.0),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scan as first written: every frame in turn, its window's maximum folded anew.
    fn first_restart_naive(energies: &[f64], rise_frames: usize) -> Option<usize> {
        let peak = energies.iter().cloned().fold(0.0, f64::max);
        let test = RestartTest::new(rise_frames, peak)?;
        let g = test.g;
        (2 * g..energies.len()).find(|&k| {
            let e = energies[k];
            e >= test.level
                && e > test.jump
                    * energies[k - 2 * g..=k - g]
                        .iter()
                        .cloned()
                        .fold(0.0, f64::max)
        })
    }

    #[test]
    fn chunked_scan_finds_what_the_frame_by_frame_test_finds() {
        // Restarts at every offset around the scan's chunks, NaN and negative frames, decays
        // of every length up to a few chunks, and no restart at all.
        for n in [0, 1, 2, 5, 15, 16, 17, 33, 64, 100] {
            for at in 0..n {
                for g in [1, 2, 3, 7] {
                    let mut e: Vec<f64> = (0..n).map(|k| (-0.3 * k as f64).exp()).collect();
                    if n > 3 {
                        e[n / 3] = f64::NAN;
                        e[n - 1] = -1.0;
                    }
                    let plain = e.clone();
                    e[at] = 50.0 * e[at].abs().max(1e-3);
                    for x in [&e, &plain] {
                        assert_eq!(
                            first_restart(x, g),
                            first_restart_naive(x, g),
                            "n {n} at {at} g {g}"
                        );
                    }
                }
            }
        }
    }

    /// Long windows over long early decays: slow decays with beating-like ripple, dips below
    /// the level test and back, NaN, zero and negative frames (also as the window's last frame,
    /// which the scan compares first), hits at random places, g up to 60: the same frame as the
    /// plain fold.
    #[test]
    fn long_windows_find_what_the_fold_finds() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut found = 0;
        for case in 0..3000 {
            let n = 1 + (uniform() * 600.0) as usize;
            let g = 1 + (uniform() * 60.0) as usize;
            let slope = 0.002 + 0.05 * uniform();
            let mut e: Vec<f64> = (0..n)
                .map(|k| {
                    let ripple = 1.0 + 0.9 * (0.37 * k as f64 + case as f64).sin();
                    (-slope * k as f64).exp() * ripple * (0.5 + uniform())
                })
                .collect();
            for _ in 0..(uniform() * 4.0) as usize {
                let at = (uniform() * n as f64) as usize;
                e[at.min(n - 1)] = match (uniform() * 4.0) as usize {
                    0 => f64::NAN,
                    1 => -uniform(),
                    2 => 0.0,
                    _ => 30.0 * uniform(),
                };
            }
            let want = first_restart_naive(&e, g);
            found += usize::from(want.is_some());
            assert_eq!(first_restart(&e, g), want, "case {case}, n {n}, g {g}");
        }
        // Both outcomes are exercised.
        assert!(
            found > 100 && found < 2900,
            "{found} of 3000 with a restart"
        );
    }

    /// Frame energies of a decaying mode pair (amplitudes a, b, Δf apart) every `dt` s.
    fn pair(a: f64, b: f64, df: f64, sigma: f64, dt: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                let phase = 2.0 * std::f64::consts::PI * df * t;
                (-2.0 * sigma * t).exp() * (a * a + b * b + 2.0 * a * b * phase.cos())
            })
            .collect()
    }

    #[test]
    fn beating_is_not_a_restart_and_a_second_hit_is() {
        for df in [0.3, 1.0, 3.0, 10.0, 40.0] {
            for g in [1, 2, 4] {
                let e = pair(1.0, 1.0, df, 2.0, 0.005, 800);
                assert_eq!(first_restart(&e, g), None, "Δf {df} Hz, gap {g}");
            }
        }
        let mut e = pair(1.0, 0.7, 2.0, 3.0, 0.01, 400);
        let second = pair(0.5, 0.3, 2.0, 3.0, 0.01, 200);
        for (k, v) in second.iter().enumerate() {
            e[200 + k] += v;
        }
        assert_eq!(first_restart(&e, 1), Some(200));
        assert_eq!(first_restart(&e, 3), Some(200));
        // Far below the peak it is not looked at.
        let mut e = pair(1.0, 0.7, 2.0, 3.0, 0.01, 400);
        for (k, v) in second.iter().enumerate() {
            e[200 + k] += 1e-3 * v;
        }
        assert_eq!(first_restart(&e, 1), None);
    }
}

//! Issue 12, hit streams: a hammer that bounces strikes again a few ms later, inside the onset
//! search's lookahead, and the second impact was folded into the decay without a word. Now the
//! decay's rows carry `double_hit` on every band (the damping still stands: the same modes ring
//! on). Ringing alone — one mode, two beating modes, a dozen modes with random phases — is not
//! flagged, though its envelope falls and rises by tens of dB.

use crate::common::{analyse_stft, decaying_sines, gaussian_noise, rel_err};
use dampscope::decay::Flag;
use dampscope::pipeline::segment::double_hit::{second_impact, SecondImpact};
use dampscope::pipeline::segment::onset::find_onset;
use dampscope::pipeline::{AnalysisConfig, ResultRow};

/// (f_hz, D) of the structure every hit excites (five modes, T60 1.1–1.4 s).
const MODES: [(f64, f64); 5] = [
    (160.0, 0.006),
    (410.0, 0.002),
    (730.0, 0.0012),
    (1150.0, 0.0008),
    (1720.0, 0.0005),
];

/// One band around each mode.
fn bands() -> Vec<(f64, f64)> {
    MODES.iter().map(|&(f, _)| (0.9 * f, 1.1 * f)).collect()
}

/// A hit's response: every mode from zero phase (a driving-point response: all residues of one
/// sign), amplitudes falling with frequency, `seconds` long.
fn hit(fs: f64, seconds: f64) -> Vec<f64> {
    let modes: Vec<(f64, f64, f64, f64)> = MODES
        .iter()
        .enumerate()
        .map(|(k, &(f, d))| (f, d, 1.0 / (1.0 + 0.3 * k as f64), 0.0))
        .collect();
    decaying_sines(&modes, fs, seconds)
}

/// Hits at `times_s`, each followed by a rebound (`delay_s`, relative amplitude) when given,
/// over white noise `noise_db` below a unit-amplitude hit.
fn stream(
    fs: f64,
    seconds: f64,
    hits: &[(f64, Option<(f64, f64)>)],
    noise_db: f64,
    seed: u64,
) -> Vec<f64> {
    let n = (seconds * fs) as usize;
    let mut x = gaussian_noise(n, 10f64.powf(-noise_db / 20.0), seed);
    let h = hit(fs, seconds);
    let mut add = |start: usize, gain: f64| {
        for (i, v) in h.iter().take(n.saturating_sub(start)).enumerate() {
            x[start + i] += gain * v;
        }
    };
    for &(t0, rebound) in hits {
        let start = (t0 * fs) as usize;
        add(start, 1.0);
        if let Some((delay_s, gain)) = rebound {
            add(start + (delay_s * fs).round() as usize, gain);
        }
    }
    x
}

fn flagged(rows: &[ResultRow], decay: usize) -> Vec<bool> {
    rows.iter()
        .filter(|r| r.decay == decay)
        .map(|r| r.estimate.has(Flag::DoubleHit))
        .collect()
}

#[test]
fn a_hammer_that_bounces_is_flagged_on_every_band_and_its_damping_stands() {
    let fs = 8192.0;
    let config = AnalysisConfig::default();
    for seed in [1, 2] {
        for (delay_s, gain) in [(0.005, 0.5), (0.008, 0.3), (0.012, 0.5), (0.020, 0.3)] {
            // Four hits 3 s apart; the second and the fourth bounce.
            let hits = [
                (0.0, None),
                (3.0, Some((delay_s, gain))),
                (6.0, None),
                (9.0, Some((delay_s, gain))),
            ];
            let x = stream(fs, 12.0, &hits, 60.0, seed);
            let case = format!("seed {seed}, rebound {gain} after {} ms", delay_s * 1e3);
            // The check itself sees the rebound where it is, as strong as it is.
            let second = &x[(2.9 * fs) as usize..(4.0 * fs) as usize];
            let s = impact(second, fs).expect("a burst after the first");
            println!("{case}: {}", describe(Some(s)));
            assert!(
                (s.level_db - 20.0 * gain.log10()).abs() < 3.0 && (s.at_s - delay_s).abs() < 2e-3,
                "{case}: {s:?}"
            );
            let rows = analyse_stft(x, fs, &bands(), &config);
            let decays = rows.iter().map(|r| r.decay).max().unwrap() + 1;
            assert_eq!(
                decays, 4,
                "{case}: one decay per hit, the rebound inside it"
            );
            for (k, &(t0, rebound)) in hits.iter().enumerate() {
                let f = flagged(&rows, k);
                assert_eq!(f.len(), MODES.len());
                assert!(
                    f.iter().all(|&b| b == rebound.is_some()),
                    "{case}: decay {k} flags {f:?}"
                );
                for r in rows.iter().filter(|r| r.decay == k) {
                    assert!((r.onset_s.unwrap() - t0).abs() < 0.01, "{case}: {r:?}");
                    let want = MODES
                        .iter()
                        .find(|m| r.band.lo_hz < m.0 && m.0 < r.band.hi_hz)
                        .unwrap()
                        .1;
                    let d = r.estimate.damping_ratio.unwrap_or_else(|| {
                        panic!("{case}: decay {k}: no number {:?}", r.estimate.flags)
                    });
                    assert!(
                        rel_err(d, want) < 0.05,
                        "{case}: decay {k}: D {d} vs {want}"
                    );
                }
            }
        }
    }
}

#[test]
fn a_bounce_is_flagged_at_4096_hz_too() {
    let fs = 4096.0;
    let bands: Vec<(f64, f64)> = bands().into_iter().filter(|b| b.1 < 1900.0).collect();
    for (delay_s, gain) in [(0.008, 0.5), (0.015, 0.3)] {
        let hits = [(0.0, Some((delay_s, gain))), (3.0, None)];
        let rows = analyse_stft(
            stream(fs, 6.0, &hits, 60.0, 3),
            fs,
            &bands,
            &AnalysisConfig::default(),
        );
        assert_eq!(flagged(&rows, 0), vec![true; bands.len()], "{delay_s} s");
        assert_eq!(flagged(&rows, 1), vec![false; bands.len()], "{delay_s} s");
    }
}

/// A mode as `decaying_sines` takes it: (f_hz, D, amplitude, phase °).
type Mode = (f64, f64, f64, f64);

/// Damped sines, 3 s, over noise 60 dB down.
fn ringing(modes: &[Mode], fs: f64, seed: u64) -> Vec<f64> {
    let mut x = gaussian_noise((3.0 * fs) as usize, 1e-3, seed);
    for (i, v) in decaying_sines(modes, fs, 3.0).into_iter().enumerate() {
        x[i] += v;
    }
    x
}

/// Pseudo-random numbers in [0, 1) (a 64-bit LCG: the test's own, reproducible).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// What the library's check sees of `x` from its onset on (the pipeline hands it the same
/// samples, with the pre-roll in front): the strongest excitation after the first impact.
fn impact(x: &[f64], fs: f64) -> Option<SecondImpact> {
    let onset = find_onset(x, 20.0).unwrap();
    let pre = &x[onset.saturating_sub(32)..onset];
    second_impact(pre, &x[onset..], fs)
}

fn describe(s: Option<SecondImpact>) -> String {
    match s {
        Some(s) => format!(
            "{:.1} dB of the first, {:.1} dB above the floor, at {:.1} ms",
            s.level_db,
            s.above_floor_db,
            s.at_s * 1e3
        ),
        None => "the residual never went quiet".into(),
    }
}

#[test]
fn ringing_alone_is_not_a_double_hit() {
    let config = AnalysisConfig::default();
    let mut cases: Vec<(String, f64, Vec<Mode>)> = Vec::new();
    for fs in [4096.0, 8192.0] {
        for (f, psi) in [(120.0, 0.0), (452.0, 90.0), (1500.0, 170.0)] {
            cases.push((format!("one mode {f} Hz"), fs, vec![(f, 0.01, 1.0, psi)]));
        }
        // Equal amplitudes beat to exact nulls; at 30–80 Hz apart the first null and the swell
        // after it both fall within the 50 ms the check looks at.
        for (f1, df) in [(100.0, 1.0), (200.0, 30.0), (450.0, 50.0), (1000.0, 80.0)] {
            for psi in [0.0, 90.0] {
                cases.push((
                    format!("{f1} + {} Hz beating", f1 + df),
                    fs,
                    vec![(f1, 0.01, 1.0, 0.0), (f1 + df, 0.01, 1.0, psi)],
                ));
            }
        }
        // A hit of many modes with random phases: its envelope fades and swells like noise.
        let mut rng = Lcg(fs as u64);
        for n_modes in [3, 6, 12] {
            for k in 0..4 {
                let modes: Vec<_> = (0..n_modes)
                    .map(|_| {
                        (
                            100.0 + 1400.0 * rng.next(),
                            0.002 + 0.008 * rng.next(),
                            0.3 + 0.7 * rng.next(),
                            360.0 * rng.next(),
                        )
                    })
                    .collect();
                cases.push((format!("{n_modes} modes, random phases #{k}"), fs, modes));
            }
        }
        // The bouncing test's own hit, without the rebound.
        let own: Vec<_> = MODES
            .iter()
            .enumerate()
            .map(|(k, &(f, d))| (f, d, 1.0 / (1.0 + 0.3 * k as f64), 0.0))
            .collect();
        cases.push(("the five-mode hit alone".into(), fs, own));
    }
    for (seed, (name, fs, modes)) in cases.iter().enumerate() {
        let x = ringing(modes, *fs, seed as u64);
        let bands: Vec<(f64, f64)> = modes
            .iter()
            .map(|m| (0.95 * m.0, 1.05 * m.0))
            .filter(|b| b.1 < 0.5 * fs)
            .take(1)
            .collect();
        let rows = analyse_stft(x.clone(), *fs, &bands, &config);
        println!("{name} at {fs} Hz: {}", describe(impact(&x, *fs)));
        assert_eq!(rows.len(), 1, "{name} at {fs} Hz: one decay, one band");
        assert!(
            rows[0].onset_s.unwrap() < 0.01,
            "{name} at {fs} Hz: {:?}",
            rows[0]
        );
        for r in &rows {
            assert!(
                !r.estimate.has(Flag::DoubleHit),
                "{name} at {fs} Hz flagged: {}",
                describe(impact(&x, *fs))
            );
        }
    }
}

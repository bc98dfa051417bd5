//! Modal identification with non-proportional damping (issue 8): the reference plate (g = 5 %)
//! with the report's patch made heavily damped (g = 50 %), on a 48 × 72 × 2 mesh with 99
//! off-node sensors. Every mode has its own damping ratio (3.2–4.8 % below 320 Hz) and a
//! slightly complex shape. The truth is the damped poles of that mesh
//! (`dampscope modes --model tests/data/modal/plate-48x72-damped-patch.toml --fmax 320
//! --damping`), which the simulator's FRFs have as their poles.

use dampscope::modal::{identify, ModalSettings, Mode, Recordings};
use dampscope::source::recording_set::open_recording_set;

const SET: &str = "tests/data/modal/plate-48x72-damped-patch";
const POLES: &str = "tests/data/modal/plate-48x72-damped-patch-poles.csv";

fn recordings() -> Recordings {
    let mut set = open_recording_set(std::path::Path::new(SET)).expect("test data");
    Recordings::from_source(set.source.as_mut(), 1 << 20).expect("read")
}

/// (damped frequency in Hz, damping ratio) of every pole below `fmax_hz`.
fn truth(fmax_hz: f64) -> Vec<(f64, f64)> {
    let mut rows = csv::Reader::from_path(POLES).expect("test data");
    rows.deserialize::<(usize, f64, f64, f64)>()
        .map(|r| r.expect("a pole row"))
        .map(|(_, _, f, d)| (f, d))
        .filter(|(f, _)| *f < fmax_hz)
        .collect()
}

/// A true pole (damped f in Hz, D) and the identified mode paired with it.
type Pair<'a> = ((f64, f64), &'a Mode);

/// Every true pole paired with the nearest identified mode (within 0.5 %), and the modes left
/// over.
fn pair_up<'a>(want: &[(f64, f64)], modes: &'a [Mode]) -> (Vec<Pair<'a>>, Vec<f64>) {
    let mut used = vec![false; modes.len()];
    let mut pairs = Vec::new();
    for &(f, d) in want {
        let best = (0..modes.len())
            .filter(|&i| !used[i])
            .min_by(|&a, &b| {
                (modes[a].frequency_hz - f)
                    .abs()
                    .total_cmp(&(modes[b].frequency_hz - f).abs())
            })
            .filter(|&i| (modes[i].frequency_hz / f - 1.0).abs() < 5e-3);
        let Some(i) = best else {
            panic!("no mode near {f:.3} Hz in {:?}", frequencies(modes));
        };
        used[i] = true;
        pairs.push(((f, d), &modes[i]));
    }
    let extra = (0..modes.len())
        .filter(|&i| !used[i])
        .map(|i| modes[i].frequency_hz)
        .collect();
    (pairs, extra)
}

fn frequencies(modes: &[Mode]) -> Vec<f64> {
    modes.iter().map(|m| m.frequency_hz).collect()
}

/// Without noise the identification reproduces each pole's own damping to 0.5 % (0.11 % as
/// measured): the estimator follows non-proportional damping, and the complex shapes pass
/// the MPC test.
#[test]
fn noise_free_poles_with_their_own_damping() {
    let want = truth(80.0);
    assert_eq!(want.len(), 8);
    let result = identify(&recordings(), &ModalSettings::new(0.5, 80.0)).unwrap();
    let (pairs, extra) = pair_up(&want, &result.modes);
    assert!(extra.is_empty(), "spurious {extra:?}");
    for ((f, d), m) in pairs {
        assert!((m.frequency_hz / f - 1.0).abs() < 2e-4, "{f:.3} Hz: {m:?}");
        assert!(
            (m.damping_ratio / d - 1.0).abs() < 5e-3,
            "{f:.3} Hz: D {d}: {m:?}"
        );
    }
}

/// At 50 dB on mean power, three noise seeds: every mode below 80 Hz (the 56.88/57.53 Hz pair
/// as two), nothing spurious, each D within 5 % of its own pole's (the poles' D spread over
/// 3.2–4.2 %, so a single damping for all would fail), f within a tenth of the half-power
/// half-bandwidth D·f (the pair, overlapping six times over, is the hardest: 0.11 Hz measured).
#[test]
fn every_mode_below_80_hz_at_50_db_with_its_own_damping() {
    let clean = recordings();
    let want = truth(80.0);
    for seed in 1..=3 {
        let mut rec = clean.clone();
        rec.add_noise_mean_power(50.0, seed);
        let result = identify(&rec, &ModalSettings::new(0.5, 80.0)).unwrap();
        let (pairs, extra) = pair_up(&want, &result.modes);
        assert!(extra.is_empty(), "seed {seed}: spurious {extra:?}");
        for ((f, d), m) in pairs {
            assert!(
                (m.frequency_hz - f).abs() < 0.1 * d * f,
                "seed {seed}, {f:.3} Hz: {m:?}"
            );
            assert!(
                (m.damping_ratio / d - 1.0).abs() < 0.05,
                "seed {seed}, {f:.3} Hz: D {d}, got {}",
                m.damping_ratio
            );
        }
    }
}

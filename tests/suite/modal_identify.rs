//! Multichannel modal identification (issue 8) on recordings unlike the analysis model: a finer
//! mesh (48 × 72 × 2) with sensors between its nodes, white noise on mean signal power.

use crate::common;

use dampscope::modal::{identify, ModalSettings, Recordings};
use dampscope::source::recording_set::open_recording_set;

const SET: &str = "tests/data/modal/plate-48x72-homogeneous";
const MODES: &str = "tests/data/modal/plate-48x72-homogeneous-modes.csv";
/// Pole of K(1 + 0.05j): ω = ω₀√(1 + 0.05j); damping ratio Im/|·| = sin(atan(0.05)/2) and
/// damped/undamped frequency ratio Re/1.
const TRUE_D: f64 = 0.024977;
const DAMPED_OVER_UNDAMPED: f64 = 1.000312;

fn recordings() -> Recordings {
    let mut set = open_recording_set(std::path::Path::new(SET)).expect("test data");
    Recordings::from_source(set.source.as_mut(), 1 << 20).expect("read")
}

/// Damped natural frequencies of the set's mesh below `fmax_hz`.
fn truth(fmax_hz: f64) -> Vec<f64> {
    let text = std::fs::read_to_string(MODES).expect("test data");
    text.lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse::<f64>().unwrap() * DAMPED_OVER_UNDAMPED)
        .filter(|f| *f < fmax_hz)
        .collect()
}

/// At 50 dB (mean power), 99 sensors, 3 s, three noise seeds: every mode below 80 Hz found —
/// the 56.70/57.47 Hz pair as two — f within 0.05 %, D within 5 % of the truth for every mode and
/// within 2 % in the median, and no other mode below 80 Hz.
#[test]
fn every_mode_below_80_hz_at_50_db() {
    let clean = recordings();
    let want = truth(80.0);
    assert_eq!(want.len(), 8, "truth: {want:?}");
    for seed in 1..=3 {
        let mut rec = clean.clone();
        rec.add_noise_mean_power(50.0, seed);
        let result = identify(&rec, &ModalSettings::new(0.5, 80.0)).unwrap();
        let got: Vec<(f64, f64)> = result
            .modes
            .iter()
            .map(|m| (m.frequency_hz, m.damping_ratio))
            .collect();
        assert_eq!(got.len(), want.len(), "seed {seed}: {got:?}");
        let mut d_err = Vec::new();
        for (&f_true, &(f, d)) in want.iter().zip(&got) {
            assert!(
                (f / f_true - 1.0).abs() < 5e-4,
                "seed {seed}: {f} Hz for {f_true} Hz"
            );
            let e = (d / TRUE_D - 1.0).abs();
            assert!(e < 0.05, "seed {seed}, {f_true} Hz: D {d}");
            d_err.push(e);
        }
        // The uncertainties are informative: each within 10 % of D here (largest 5.4 % over
        // 10 seeds), and they cover the error.
        for m in &result.modes {
            assert!(m.damping_std < 0.1 * TRUE_D, "seed {seed}: {m:?}");
            assert!(
                (m.damping_ratio - TRUE_D).abs() <= 3.0 * m.damping_std,
                "seed {seed}: {m:?}"
            );
        }
        d_err.sort_by(f64::total_cmp);
        let median = 0.5 * (d_err[3] + d_err[4]);
        assert!(median < 0.02, "seed {seed}: median |ΔD|/D {median}");
        for m in &result.modes {
            assert!(
                m.mpc > 0.9,
                "seed {seed}: {} Hz, MPC {}",
                m.frequency_hz,
                m.mpc
            );
            assert_eq!(m.shape.len(), 99);
        }
    }
}

/// (true f, f, D) of the pairs, true modes missed, identified modes left over.
type Pairing = (Vec<(f64, f64, f64)>, Vec<f64>, Vec<f64>);

/// Pairs every true mode with the nearest unused identified mode within 0.5 %: (true f, f, D)
/// of the pairs, the true modes not found, and the identified modes left over (spurious).
fn pair_up(want: &[f64], modes: &[dampscope::modal::Mode]) -> Pairing {
    let mut used = vec![false; modes.len()];
    let (mut found, mut missing) = (Vec::new(), Vec::new());
    for &t in want {
        let best = (0..modes.len()).filter(|&i| !used[i]).min_by(|&a, &b| {
            (modes[a].frequency_hz - t)
                .abs()
                .total_cmp(&(modes[b].frequency_hz - t).abs())
        });
        match best {
            Some(i) if (modes[i].frequency_hz / t - 1.0).abs() < 5e-3 => {
                used[i] = true;
                found.push((t, modes[i].frequency_hz, modes[i].damping_ratio));
            }
            _ => missing.push(t),
        }
    }
    let extra = (0..modes.len())
        .filter(|&i| !used[i])
        .map(|i| modes[i].frequency_hz)
        .collect();
    (found, missing, extra)
}

/// At 35 dB on mean power (the low modes then sit 10–20 dB above the noise in their bands):
/// every mode below 80 Hz found and D within 10 % of the truth, over three noise seeds. The
/// weakest mode (5.23 Hz, modal SNR ≈ 11.5 dB) has a spread of about 7.6 % over 24 seeds, so
/// 10 % is not a wide margin for it; the seeds here are the first three, not chosen.
#[test]
fn every_mode_below_80_hz_at_35_db_within_10_percent() {
    let clean = recordings();
    let want = truth(80.0);
    for seed in 1..=3 {
        let mut rec = clean.clone();
        rec.add_noise_mean_power(35.0, seed);
        let result = identify(&rec, &ModalSettings::new(0.5, 80.0)).unwrap();
        let (found, missing, extra) = pair_up(&want, &result.modes);
        assert!(missing.is_empty(), "seed {seed}: missing {missing:?}");
        assert!(extra.is_empty(), "seed {seed}: spurious {extra:?}");
        for (t, _, d) in found {
            let e = (d / TRUE_D - 1.0).abs();
            assert!(
                e < 0.10,
                "seed {seed}, {t:.2} Hz: D {d:.5} ({:.1} %)",
                100.0 * e
            );
        }
    }
}

/// Up to 300 Hz at 50 dB: at least 90 % of the 32 modes found (a triplet 0.8 Hz apart at
/// 177 Hz and a pair 0.03 Hz apart at 274.5 Hz are among them; the latter is one pole to a
/// single-input test), the median D error within 5 %, nothing spurious.
#[test]
fn ninety_percent_of_the_modes_to_300_hz_at_50_db() {
    let clean = recordings();
    let want = truth(300.0);
    assert_eq!(want.len(), 32);
    for seed in 1..=2 {
        let mut rec = clean.clone();
        rec.add_noise_mean_power(50.0, seed);
        let result = identify(&rec, &ModalSettings::new(0.5, 300.0)).unwrap();
        let (found, missing, extra) = pair_up(&want, &result.modes);
        assert!(
            found.len() * 10 >= want.len() * 9,
            "seed {seed}: {} of {} found, missing {missing:?}",
            found.len(),
            want.len()
        );
        assert!(extra.is_empty(), "seed {seed}: spurious {extra:?}");
        let mut e: Vec<f64> = found
            .iter()
            .map(|(_, _, d)| (d / TRUE_D - 1.0).abs())
            .collect();
        e.sort_by(f64::total_cmp);
        let median = e[e.len() / 2];
        assert!(median < 0.05, "seed {seed}: median |ΔD|/D {median}");
    }
}

/// Seeds whose noise once made modes that are not there (a noise pole at 20.6 Hz with MPC
/// 0.001, a 69.2 Hz pole with D = 0.53 after refinement) or split and merged the close pair
/// (35 dB seed 4: one mode at 57.23 Hz; seed 5: a 21.27 Hz twin with D = 0.005).
#[test]
fn regression_noise_seeds_that_made_spurious_or_merged_modes() {
    let clean = recordings();
    let want = truth(80.0);
    for (snr, seed) in [(50.0, 8), (50.0, 10), (35.0, 4), (35.0, 5)] {
        let mut rec = clean.clone();
        rec.add_noise_mean_power(snr, seed);
        let result = identify(&rec, &ModalSettings::new(0.5, 80.0)).unwrap();
        let (_, missing, extra) = pair_up(&want, &result.modes);
        assert!(
            missing.is_empty(),
            "{snr} dB seed {seed}: missing {missing:?}"
        );
        assert!(extra.is_empty(), "{snr} dB seed {seed}: spurious {extra:?}");
    }
}

/// The stored record without added noise once gave 19 modes below 80 Hz: 11 poles fitted to
/// the record's deterministic residual (D down to 5e-8, modal SNR −3 to −41 dB) beside the 8
/// true ones, in 3 s instead of 0.5. Now: the 8 modes, D within 0.5 % of the truth, nothing else.
#[test]
fn regression_noise_free_record_gave_spurious_modes() {
    let result = identify(&recordings(), &ModalSettings::new(0.5, 80.0)).unwrap();
    let (found, missing, extra) = pair_up(&truth(80.0), &result.modes);
    assert!(missing.is_empty(), "missing {missing:?}");
    assert!(extra.is_empty(), "spurious {extra:?}");
    for (t, f, d) in found {
        assert!((f / t - 1.0).abs() < 5e-4, "{t:.3} Hz: f {f:.4}");
        assert!((d / TRUE_D - 1.0).abs() < 5e-3, "{t:.3} Hz: D {d:.6}");
    }
}

/// Shapes against a coarser model (32 × 48 × 2, the report's reference mesh) read at the set's
/// off-node sensor positions: every mode below 80 Hz at 50 dB pairs with its own model mode
/// (same index) at MAC ≥ 0.98.
#[test]
fn shapes_match_a_coarser_model_with_mac_of_at_least_098() {
    use dampscope::modal::model_shapes::{match_model, model_modes_at, sensor_positions};
    use dampscope::sim::model::Model;
    let set = open_recording_set(std::path::Path::new(SET)).unwrap();
    let positions = sensor_positions(&set.sensors).unwrap();
    let model = Model::load(std::path::Path::new("examples/plate-homogeneous.toml")).unwrap();
    let model_modes = model_modes_at(&model, &positions, 100.0).unwrap();
    let mut rec = recordings();
    rec.add_noise_mean_power(50.0, 1);
    let result = identify(&rec, &ModalSettings::new(0.5, 80.0)).unwrap();
    assert_eq!(result.modes.len(), 8);
    for (k, (m, hit)) in result
        .modes
        .iter()
        .zip(match_model(&result.modes, &model_modes))
        .enumerate()
    {
        let hit = hit.expect("a partner");
        assert_eq!(
            hit.model_mode,
            k + 1,
            "{:.2} Hz paired with {hit:?}",
            m.frequency_hz
        );
        assert!(hit.mac >= 0.98, "{:.2} Hz: {hit:?}", m.frequency_hz);
    }
}

/// The two modes 0.77 Hz apart at 57 Hz (D = 2.5 %, half-power bandwidths 2.8 Hz, so they
/// overlap 370 %) have different shapes: their MAC is small, so they are two modes, not one mode
/// seen twice.
#[test]
fn the_close_pair_has_two_distinct_shapes() {
    let mut rec = recordings();
    rec.add_noise_mean_power(50.0, 7);
    let result = identify(&rec, &ModalSettings::new(50.0, 60.0)).unwrap();
    let pair: Vec<_> = result
        .modes
        .iter()
        .filter(|m| m.frequency_hz > 56.0 && m.frequency_hz < 58.0)
        .collect();
    assert_eq!(pair.len(), 2, "{:?}", result.modes);
    let mac = dampscope::modal::subspace::mac(&pair[0].shape, &pair[1].shape);
    assert!(mac < 0.2, "MAC of the pair {mac}");
}

/// Bad settings are typed errors naming the setting, never a panic.
#[test]
fn bad_ranges_are_errors() {
    let rec = recordings();
    for (lo, hi) in [(80.0, 10.0), (0.5, 5000.0), (-1.0, 10.0)] {
        let e = identify(&rec, &ModalSettings::new(lo, hi)).unwrap_err();
        assert!(e.to_string().contains("frequency range"), "{e}");
    }
    let empty = Recordings {
        fs_hz: 4000.0,
        names: vec![],
        channels: vec![],
    };
    assert!(identify(&empty, &ModalSettings::new(1.0, 10.0)).is_err());
}

/// `dampscope modal SET --fmax 80 --model PLATE --out DIR` prints the modes and writes
/// modes.csv (with each mode's MAC against its model partner), shapes.csv (99 rows per mode),
/// the stabilisation diagram and a shape figure per mode.
#[test]
fn the_command_writes_its_outputs() {
    let dir = common::fresh_dir("modal-cli");
    let out = dir.join("out");
    let o = common::run_dampscope(
        &[
            "modal",
            SET,
            "--fmax",
            "80",
            "--add-noise-db",
            "50",
            "--model",
            "examples/plate-homogeneous.toml",
            "--out",
            out.to_str().unwrap(),
        ],
        b"",
    );
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stdout = String::from_utf8(o.stdout).unwrap();
    assert_eq!(stdout.lines().count(), 9, "{stdout}");
    let modes = std::fs::read_to_string(out.join("modes.csv")).unwrap();
    assert!(modes.starts_with(
        "mode,frequency_hz,damping_ratio,frequency_std_hz,damping_std,mpc,n_stable,modal_snr_db,\
         frequency_order_std_hz,damping_order_std,frequency_sensor_std_hz,damping_sensor_std,\
         model_mode,model_frequency_hz,mac_model"
    ));
    for row in modes.lines().skip(1) {
        let mac: f64 = row.rsplit(',').next().unwrap().parse().unwrap();
        assert!(mac >= 0.98, "{row}");
    }
    let shapes = std::fs::read_to_string(out.join("shapes.csv")).unwrap();
    assert_eq!(shapes.lines().count(), 1 + 8 * 99);
    for f in ["stabilisation.png", "shape-01.png", "shape-08.png"] {
        assert!(std::fs::metadata(out.join(f)).unwrap().len() > 1000, "{f}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Decays of 12 channels (sums of exponentials, no model behind them, white noise at 80 dB
/// and 60 dB below the mean signal power, three seeds each): three modes in the top sub-band
/// of 0.5–100 Hz and two stronger ones above it, 103.6 Hz (10×) and 114.2 Hz (30×), as a
/// plate's acceleration grows with frequency. The top sub-band (83.7–100 Hz, filter half-width
/// h = 12.2 Hz around 91.85 Hz) decimates to 50 Hz: 114.2 Hz sits at 1.83 h, inside the
/// baseband but only 63 dB down. Poles were modelled to 1.8 h: the mode's residual pulled the
/// in-band poles (D of the 87.25 and 88.9 Hz modes off by −2.8 % and +2.2 % at 80 dB) and, on
/// a windowed FRF set of the coarse plate, was fitted by a pole of its own at 99.5 Hz (MAC
/// 0.9999 with the 114 Hz mode; `cli_uff::diagnose_removes_the_exponential_window_a_set_declares`).
/// Now every pole the baseband holds is modelled: the three modes and nothing else, f within
/// 0.1 %, D within 0.5 % of the truth at 80 dB (measured: ≤ 0.07 %) and 1.5 % at 60 dB (≤ 0.68 %,
/// the noise's own spread).
#[test]
fn regression_a_strong_mode_beyond_the_top_band_pulled_the_band_modes() {
    let fs_hz = 800.0;
    let n = 3200;
    let modes = [
        (87.25, 0.8),
        (88.90, 1.0),
        (96.92, 0.7),
        (103.59, 10.0),
        (114.16, 30.0),
    ];
    let d = 0.025;
    // A different shape per mode and channel, reproducible.
    let shape = |m: usize, c: usize| ((1.0 + m as f64) * (0.7 + c as f64) * 1.618).sin();
    let clean: Vec<Vec<f64>> = (0..12)
        .map(|c| {
            (0..n)
                .map(|i| {
                    let t = i as f64 / fs_hz;
                    modes
                        .iter()
                        .enumerate()
                        .map(|(m, &(f, a))| {
                            let w = 2.0 * std::f64::consts::PI * f;
                            a * shape(m, c) * (-d * w * t).exp() * (w * t + 0.3 * m as f64).sin()
                        })
                        .sum()
                })
                .collect()
        })
        .collect();
    // e^{−ζωt}·sin(ωt): damped frequency ω, damping ratio ζ/√(1 + ζ²).
    let d_true = d / (1.0 + d * d).sqrt();
    for (db, d_tolerance) in [(80.0, 0.005), (60.0, 0.015)] {
        for seed in 1..=3u64 {
            let channels = clean
                .iter()
                .enumerate()
                .map(|(c, x)| {
                    let power = x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64;
                    let sigma = (power * 10f64.powf(-db / 10.0)).sqrt();
                    let noise = common::gaussian_noise(x.len(), sigma, 100 * seed + c as u64);
                    x.iter().zip(noise).map(|(v, e)| v + e).collect()
                })
                .collect();
            let rec = Recordings {
                fs_hz,
                names: (0..12).map(|c| format!("ch{c}")).collect(),
                channels,
            };
            let result = identify(&rec, &ModalSettings::new(0.5, 100.0)).expect("identify");
            let found: Vec<(f64, f64)> = result
                .modes
                .iter()
                .map(|m| (m.frequency_hz, m.damping_ratio))
                .collect();
            let what = format!("{db} dB, seed {seed}: {found:?}");
            assert_eq!(found.len(), 3, "{what}");
            for (&(f, dr), &(f_true, _)) in found.iter().zip(&modes) {
                assert!((f / f_true - 1.0).abs() < 1e-3, "{what}");
                assert!((dr / d_true - 1.0).abs() < d_tolerance, "{what}");
            }
        }
    }
}

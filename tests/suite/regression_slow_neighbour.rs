//! Found by `scripts/leakage_probe.py` (2026-11-28): a 50 Hz band holding one mode, beside a
//! stronger mode 1.5–3.5 band widths away that decays 1.5–8× slower, reported its T60 up to 17 %
//! long without a flag, with every front end. The neighbour's skirt, tens of dB under the band
//! in total energy, decays slower than the band's own mode and reaches its curve by the end of
//! the T30 fit. The leakage test now also holds the band's curve at its fit's depth against
//! what the slower bands leak then (test 4 of `decay::leakage`).

use crate::common::{analyze_rows, decaying_sines, fresh_dir, write_float_wav};

/// One of the probe's cases: the band's mode and its stronger, slower neighbour.
struct Case {
    f_hz: f64,
    t60_s: f64,
    neighbour_hz: f64,
    neighbour_t60_s: f64,
    /// The neighbour's level above the band's mode, dB.
    level_db: f64,
}

const fn case(
    f_hz: f64,
    t60_s: f64,
    neighbour_hz: f64,
    neighbour_t60_s: f64,
    level_db: f64,
) -> Case {
    Case {
        f_hz,
        t60_s,
        neighbour_hz,
        neighbour_t60_s,
        level_db,
    }
}

/// The probe's cases that gave an unflagged T60 more than 5 % off (seed 7).
const CASES: [Case; 6] = [
    case(311.3, 0.99, 403.8, 2.23, 10.5),
    case(289.6, 0.97, 417.2, 1.95, 14.0),
    case(313.6, 0.66, 389.7, 1.10, 13.2),
    case(310.9, 0.93, 426.8, 3.55, 5.6),
    case(299.2, 0.97, 155.7, 4.26, 23.4),
    case(313.7, 0.33, 383.1, 1.49, 8.4),
];

const FRONT_ENDS: [&[&str]; 3] = [
    &["--front-end", "octave"],
    &["--front-end", "goyder"],
    &["--front-end", "stft", "--window-ms", "50"],
];

/// The 275–325 Hz band's T60 (if any) and flags for `modes` (f, T60, amplitude) at 4096 Hz.
fn band_275(
    dir: &std::path::Path,
    modes: &[(f64, f64, f64)],
    front_end: &[&str],
) -> (Option<f64>, String) {
    let seconds = modes.iter().map(|m| 1.5 * m.1).fold(3.0, f64::max).min(6.0);
    let sines: Vec<(f64, f64, f64, f64)> = modes
        .iter()
        .map(|&(f, t60, a)| (f, 1.1 / (t60 * f), a, 77.0))
        .collect();
    let path = dir.join("decay.wav");
    write_float_wav(&path, &decaying_sines(&sines, 4096.0, seconds), 4096);
    let mut args = vec!["analyze", path.to_str().unwrap(), "--bands", "75:575:50"];
    args.extend(front_end);
    let rows = analyze_rows(&args, b"");
    let row = rows
        .iter()
        .find(|r| r["f_lo"].parse::<f64>() == Ok(275.0))
        .unwrap();
    (row["t60_s"].parse().ok(), row["flags"].clone())
}

#[test]
fn a_slower_stronger_neighbour_gives_no_unflagged_long_t60() {
    let dir = fresh_dir("slow-neighbour");
    for front_end in FRONT_ENDS {
        for Case {
            f_hz: f,
            t60_s: t60,
            neighbour_hz: fb,
            neighbour_t60_s: t60b,
            level_db,
        } in CASES
        {
            // Alone, the band's mode is measured within 2 %: the cases are not beyond reach.
            let (alone, _) = band_275(&dir, &[(f, t60, 1.0)], front_end);
            let alone = alone.unwrap_or_else(|| panic!("{front_end:?} {f} Hz alone: no number"));
            assert!(
                (alone / t60 - 1.0).abs() < 0.02,
                "{front_end:?} {f} Hz alone: {alone}"
            );
            let b = 10f64.powf(level_db / 20.0);
            let (got, flags) = band_275(&dir, &[(f, t60, 1.0), (fb, t60b, b)], front_end);
            match got {
                Some(t) if flags.is_empty() => assert!(
                    (t / t60 - 1.0).abs() <= 0.05,
                    "{front_end:?} {f} Hz beside {fb} Hz: T60 {t} for {t60}, unflagged"
                ),
                Some(_) => {}
                None => assert!(
                    flags.contains("leakage") || flags.contains("too_few_frames"),
                    "{front_end:?} {f} Hz beside {fb} Hz: withheld as {flags}"
                ),
            }
        }
    }
}

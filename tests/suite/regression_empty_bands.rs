//! Found by piping one synthetic mode through the default bands (50 Hz wide, 25–… Hz): bands
//! holding no mode reported numbers. With the STFT, the 275–325 and 375–425 Hz bands of a
//! noiseless 210 Hz decay gave D 0.007 and 0.005 with no flag although their f_dominant was
//! 210 Hz (the level test overwrote the off-band verdict); with the octave bank at 80 dB SNR, 19
//! empty bands from 425 to 1425 Hz gave D 0.035–0.12, T20 ≈ 0.024 s in every one — the band
//! filters' own response to the onset (B·T60 ≈ 1.2).

use crate::common::{analyze_rows, run_dampscope as dampscope};

/// The rows of `analyze -` on a 3 s, 8 kHz decay of 210 Hz at ζ 1 % (`snr_db`: noise on mean
/// power, `None` for none): (f_lo, damping_ratio_corrected if any, flags).
fn rows(front_end: &str, snr_db: Option<&str>) -> Vec<(f64, Option<f64>, String)> {
    let mut synth = vec![
        "synth",
        "--mode",
        "210:0.01",
        "--fs",
        "8000",
        "--seconds",
        "3",
        "--format",
        "wav",
    ];
    if let Some(snr) = snr_db {
        synth.extend(["--snr-db", snr]);
    }
    let wav = dampscope(&synth, b"");
    assert!(wav.status.success());
    analyze_rows(&["analyze", "-", "--front-end", front_end], &wav.stdout)
        .into_iter()
        .map(|r| {
            (
                r["f_lo"].parse().unwrap(),
                r["damping_ratio_corrected"].parse().ok(),
                r["flags"].clone(),
            )
        })
        .collect()
}

/// Only the 175–225 Hz band, which holds the mode, gives a number, and it is the mode's.
fn assert_only_the_modes_band(rows: &[(f64, Option<f64>, String)]) {
    for (lo, d, flags) in rows {
        if *lo == 175.0 {
            let d = d.unwrap_or_else(|| panic!("the mode's band has no number: {flags}"));
            assert!((d / 0.01 - 1.0).abs() < 0.02, "{d}");
        } else {
            assert!(d.is_none(), "band from {lo} Hz: D {d:?} [{flags}]");
        }
    }
}

#[test]
fn stft_bands_whose_frequency_is_off_band_give_no_number() {
    let rows = rows("stft", None);
    assert_only_the_modes_band(&rows);
    for lo in [275.0, 375.0] {
        let (_, _, flags) = rows.iter().find(|r| r.0 == lo).unwrap();
        assert!(flags.contains("leakage"), "{lo}: {flags}");
    }
}

#[test]
fn octave_bands_ringing_from_the_onset_give_no_number() {
    let rows = rows("octave", Some("80"));
    assert_only_the_modes_band(&rows);
    let limited = rows
        .iter()
        .filter(|r| r.2.contains("filter_limited"))
        .count();
    assert!(limited >= 10, "{limited} bands flagged filter_limited");
}

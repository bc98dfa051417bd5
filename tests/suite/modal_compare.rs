//! `compare --front-ends ...,modal`: the multichannel modal estimate beside the decay-based
//! ones for the same bands (issue 8, item 6), on a noisy WAV of the finer-mesh plate (99
//! off-node sensors, 50 dB on mean power) that the decay fits find hard.

use crate::common;

use dampscope::modal::Recordings;
use dampscope::source::recording_set::open_recording_set;

const SET: &str = "tests/data/modal/plate-48x72-homogeneous";
/// Pole of K(1 + 0.05j).
const TRUE_D: f64 = 0.024977;

#[test]
fn compare_puts_the_modal_estimate_beside_stft_and_goyder() {
    let dir = common::fresh_dir("modal-compare");
    let mut set = open_recording_set(std::path::Path::new(SET)).unwrap();
    let mut rec = Recordings::from_source(set.source.as_mut(), 1 << 20).unwrap();
    rec.add_noise_mean_power(50.0, 1);
    let wav = dir.join("noisy.wav");
    let file = std::io::BufWriter::new(std::fs::File::create(&wav).unwrap());
    dampscope::output::wav::write_wav_f32(file, rec.fs_hz as u32, &rec.channels).unwrap();
    let out = common::run_dampscope(
        &[
            "compare",
            wav.to_str().unwrap(),
            "--band",
            "20:23",
            "--band",
            "55:60",
            "--band",
            "62:70",
            "--front-ends",
            "stft,goyder,modal",
            "--out",
            dir.to_str().unwrap(),
        ],
        b"",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows = common::csv_rows(&dir.join("compare.csv"));
    // 99 channels × 3 bands × 3 front ends.
    assert_eq!(rows.len(), 99 * 3 * 3);
    let modal = |band: &str| -> Vec<&std::collections::HashMap<String, String>> {
        rows.iter()
            .filter(|r| r["front_end"] == "modal" && r["band_hz"] == band)
            .collect()
    };
    // One mode at 21.27 Hz: every channel sees it, with its uncertainty.
    let single = modal("20.00-23.00");
    assert_eq!(single.len(), 99);
    for r in &single {
        let d: f64 = r["d_pct"].parse::<f64>().unwrap() / 100.0;
        let f: f64 = r["f_hz"].parse().unwrap();
        let std: f64 = r["d_std_pct"].parse::<f64>().unwrap() / 100.0;
        assert!((d / TRUE_D - 1.0).abs() < 0.05, "{r:?}");
        assert!((f - 21.271).abs() < 0.02, "{r:?}");
        assert!(std > 0.0 && std < 0.1 * d, "{r:?}");
        assert_eq!(r["flags"], "", "{r:?}");
    }
    // The 56.70/57.47 Hz pair: each channel shows the mode that dominates it, and both modes
    // dominate somewhere (their shapes differ).
    let pair = modal("55.00-60.00");
    let mut seen = std::collections::BTreeSet::new();
    for r in &pair {
        assert_eq!(r["flags"], "several_modes", "{r:?}");
        let d: f64 = r["d_pct"].parse::<f64>().unwrap() / 100.0;
        assert!((d / TRUE_D - 1.0).abs() < 0.05, "{r:?}");
        seen.insert(r["f_hz"].clone());
    }
    assert_eq!(seen.len(), 2, "{seen:?}");
    // No mode between 62 and 70 Hz: reported missing, not invented.
    for r in modal("62.00-70.00") {
        assert_eq!(r["flags"], "no_mode", "{r:?}");
        assert_eq!(r["d_pct"], "", "{r:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

//! Measured records that found bugs (issue 15): a living-room RIR and pyrato's noisy measured
//! RIR against pyrato's own numbers, and a structural shock record with `--bands auto`.

use crate::common::{data, rel_err, run_dampscope};

fn jsonl(out: &std::process::Output) -> Vec<serde_json::Value> {
    assert!(
        out.status.code() == Some(0),
        "exit {:?}: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str(l).expect("one JSON object per line"))
        .collect()
}

/// `--preset pyrato` reproduces pyrato (Chu + Lundeby on pyfar's order-14 octave bank) within
/// 1 % for T20 and T30 and — tighter than the 5 % — 1.5 % for EDT in every octave band
/// 63 Hz … 8 kHz of both records (measured: worst 0.8 %, EDT at 4 kHz of the living room).
/// Before the preset, the closest setting was 5–16 % short on EDT (2 ms frames, the decay from
/// the broadband onset, EDT over 0…−10 dB where pyrato fits −0.1…−10.1 dB), 1.2 % off on T30 at
/// 125 Hz of the noisy RIR (Lundeby's first regression), and withheld six living-room bands.
#[test]
fn pyrato_preset_matches_pyrato_in_every_octave_band() {
    let reference: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(data("pyrato/octave_chu_lundeby_reference.json")).unwrap(),
    )
    .unwrap();
    let files = [
        ("living_room_1.wav", data("rir/living_room_1.wav"), None),
        (
            "room_impulse_response_with_noise.csv",
            data("pyrato/room_impulse_response_with_noise.csv"),
            Some("48000"),
        ),
    ];
    for (name, path, fs) in files {
        for (quantity, range, tol) in [
            ("EDT", "edt", 0.015),
            ("T20", "t20", 0.01),
            ("T30", "t30", 0.01),
        ] {
            let mut args = vec![
                "analyze",
                path.as_str(),
                "--preset",
                "pyrato",
                "--bands",
                "octave",
                "--range",
                range,
                "--format",
                "jsonl",
            ];
            if let Some(fs) = fs {
                args.extend(["--fs", fs]);
            }
            let rows = jsonl(&run_dampscope(&args, &[]));
            let bands = reference["files"][name].as_object().unwrap();
            assert_eq!(bands.len(), 8, "{name}: 63 Hz … 8 kHz in the reference");
            for (band, want) in bands {
                let want = want[quantity].as_f64().unwrap();
                let row = rows
                    .iter()
                    .find(|r| r["f_nominal"].as_f64() == Some(band.parse().unwrap()))
                    .unwrap_or_else(|| panic!("{name}: no {band} Hz row"));
                let got = row["t60_s"].as_f64().unwrap_or_else(|| {
                    panic!(
                        "{name} {band} Hz {quantity}: no number, flags {}",
                        row["flags"]
                    )
                });
                assert!(
                    rel_err(got, want) < tol,
                    "{name} {band} Hz {quantity}: dampscope {got}, pyrato {want}"
                );
            }
        }
    }
}

/// The PCB shock record (50 kHz, 0.11 s): `--bands auto` used to find ripples of the short
/// record's spectrum (495/623/804/996 Hz) capped at 50 Hz, whose 3/B transient cut removed 60 ms
/// of the 100 ms decay. Now one band on the 803 Hz mode, wide enough for its cut, and the octave
/// bank gives D within 3 % of 0.89 % (LSCF and an envelope fit, issue 15; measured 0.910 %).
#[test]
fn shock_record_auto_bands_give_the_803_hz_mode() {
    let path = data("structural/hrshm_dataset5_pcb_shock_a0.csv");
    let rows = jsonl(&run_dampscope(
        &[
            "analyze",
            &path,
            "--bands",
            "auto",
            "--front-end",
            "octave",
            "--range",
            "t20",
            "--format",
            "jsonl",
        ],
        &[],
    ));
    let with_number: Vec<_> = rows
        .iter()
        .filter(|r| r["damping_ratio_corrected"].as_f64().is_some())
        .collect();
    assert_eq!(with_number.len(), 1, "{rows:?}");
    let r = with_number[0];
    let f = r["f_dominant"].as_f64().unwrap();
    let d = r["damping_ratio_corrected"].as_f64().unwrap();
    assert!((f - 803.0).abs() < 3.0, "f_dominant {f}");
    assert!(rel_err(d, 0.0089) < 0.03, "D = {d}");
    let width = r["f_hi"].as_f64().unwrap() - r["f_lo"].as_f64().unwrap();
    // 0.101 s from the onset: the cut 3/B may take at most a quarter (B ≥ 119 Hz).
    assert!(
        3.0 / width <= 0.25 * 0.101,
        "band {width} Hz: its transient cut takes more than a quarter of the record"
    );
}

//! Sources: recording sets (the shared reference example), input opening and detection.

use std::io::Cursor;

use crate::common;
use std::path::Path;

use dampscope::output::{write_recording_set, write_wav_f32};
use dampscope::source::{
    open_input, open_recording_set, open_stream, Block, DecayKind, Excitation, InputOptions,
    RawFormat, RecordingMeta, Sensor, Source, SourceError,
};
use proptest::prelude::*;

const EXAMPLE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/recording-set-example"
);

fn drain(src: &mut dyn Source, block: usize) -> (Vec<Vec<f64>>, Option<SourceError>) {
    let mut out = vec![Vec::new(); src.info().channels()];
    let mut b = Block::default();
    loop {
        match src.read_block(block, &mut b) {
            Ok(true) => {
                for (o, c) in out.iter_mut().zip(&b.channels) {
                    o.extend_from_slice(c);
                }
            }
            Ok(false) => return (out, None),
            Err(e) => return (out, Some(e)),
        }
    }
}

fn tmpdir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("dampscope-sources-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn reference_recording_set_loads_unchanged() {
    let mut set = open_recording_set(Path::new(EXAMPLE)).unwrap();
    assert_eq!(set.meta.kind, DecayKind::ImpulseResponse);
    assert_eq!(set.meta.fs, Some(4000.0));
    assert_eq!(set.meta.snr_db, None);
    assert_eq!(set.sensors.len(), 4);
    assert_eq!(set.sensors[1].id, "E2");
    assert_eq!((set.sensors[1].x_m, set.sensors[1].y_m), (1.0, 1.5));
    assert_eq!(set.sensors[0].dir, "z");
    assert_eq!(set.excitation.len(), 1);
    assert_eq!(set.excitation[0].x_m, 0.0625);
    assert_eq!(set.excitation[0].force_n, 1.0);
    assert_eq!(set.source.info().sample_rate_hz, 4000.0);
    assert_eq!(set.source.info().channel_names, ["E1", "E2", "E3", "E4"]);
    let (wav, err) = drain(set.source.as_mut(), 333);
    assert!(err.is_none(), "{err:?}");
    assert_eq!(wav[0].len(), 2000);

    // The same set with only the CSV gives the same samples (CSV holds 8 significant digits).
    let dir = tmpdir("csv-only");
    for f in [
        "responses.csv",
        "sensors.csv",
        "excitation.csv",
        "meta.json",
    ] {
        std::fs::copy(Path::new(EXAMPLE).join(f), dir.join(f)).unwrap();
    }
    let mut set = open_recording_set(&dir).unwrap();
    assert_eq!(set.source.info().channel_names, ["E1", "E2", "E3", "E4"]);
    assert!((set.source.info().sample_rate_hz - 4000.0).abs() < 1e-9);
    let (csv, err) = drain(set.source.as_mut(), 100);
    assert!(err.is_none(), "{err:?}");
    let mut worst = 0f64;
    for (w, c) in wav.iter().zip(&csv) {
        assert_eq!(w.len(), c.len());
        for (a, b) in w.iter().zip(c) {
            worst = worst.max((a - b).abs() / a.abs().max(1e-30));
        }
    }
    assert!(worst < 1e-7, "worst relative WAV vs CSV difference {worst}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn recording_set_round_trip_and_channel_check() {
    let dir = tmpdir("rt");
    let sensors: Vec<Sensor> = (0..3)
        .map(|k| Sensor {
            id: format!("S{k}"),
            x_m: 0.1 * k as f64,
            y_m: 1.0 / 3.0,
            z_m: (k == 1).then_some(0.01),
            dir: "z".into(),
        })
        .collect();
    let exc = vec![Excitation {
        x_m: 0.0625,
        y_m: 0.125,
        dir: "z".into(),
        force_n: 2.5,
    }];
    let meta = RecordingMeta {
        exponential_window_tau_s: None,
        kind: DecayKind::FreeDecay,
        quantity: Some("acceleration".into()),
        snr_db: Some(40.0),
        ..Default::default()
    };
    let chans: Vec<Vec<f64>> = (0..3)
        .map(|k| (0..50).map(|i| (i as f64 * 0.2 + k as f64).cos()).collect())
        .collect();
    write_recording_set(&dir, &meta, &sensors, &exc, 2000.0, &chans).unwrap();
    let mut set = open_recording_set(&dir).unwrap();
    assert_eq!(set.sensors, sensors);
    assert_eq!(set.excitation, exc);
    assert_eq!(
        set.meta,
        RecordingMeta {
            exponential_window_tau_s: None,
            fs: Some(2000.0),
            ..meta.clone()
        }
    );
    let (got, _) = drain(set.source.as_mut(), 7);
    for (g, c) in got.iter().zip(&chans) {
        for (a, b) in g.iter().zip(c) {
            assert_eq!(*a, f64::from(*b as f32));
        }
    }
    // One sensor row too many → ChannelCount.
    let mut f = std::fs::read_to_string(dir.join("sensors.csv")).unwrap();
    f += "S9,0,0,,z\n";
    std::fs::write(dir.join("sensors.csv"), f).unwrap();
    match open_recording_set(&dir) {
        Err(SourceError::ChannelCount { expected, got, .. }) => assert_eq!((expected, got), (4, 3)),
        other => panic!("expected ChannelCount, got {:?}", other.err()),
    }
    assert!(write_recording_set(&dir, &meta, &sensors, &exc, 2000.5, &chans).is_err());
    assert!(write_recording_set(&dir, &meta, &sensors[..2], &exc, 2000.0, &chans).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn open_input_by_path() {
    let opened = open_input(EXAMPLE, &InputOptions::default()).unwrap();
    assert_eq!(opened.sensors.unwrap().len(), 4);
    assert!(opened.meta.is_some());
    let wav = format!("{EXAMPLE}/responses.wav");
    let o = open_input(&wav, &InputOptions::default()).unwrap();
    assert_eq!(o.source.info().channels(), 4);
    assert!(o.sensors.is_none());
    let wrong = InputOptions {
        channels: Some(2),
        ..Default::default()
    };
    assert!(matches!(
        open_input(&wav, &wrong),
        Err(SourceError::ChannelCount {
            expected: 2,
            got: 4,
            ..
        })
    ));
    // --fs must agree with a WAV header or a recording set (4 kHz here), by path and on stdin.
    let fs_at = |hz| InputOptions {
        fs_hz: Some(hz),
        ..Default::default()
    };
    for path in [wav.as_str(), EXAMPLE] {
        assert!(open_input(path, &fs_at(4000.0)).is_ok(), "{path}");
        match open_input(path, &fs_at(48000.0)) {
            Err(SourceError::SampleRateConflict {
                header_hz,
                option_hz,
                ..
            }) => assert_eq!((header_hz, option_hz), (4000.0, 48000.0)),
            other => panic!("{path}: expected a rate conflict, got {:?}", other.err()),
        }
    }
    let bytes = std::fs::read(&wav).unwrap();
    assert!(matches!(
        open_stream(Cursor::new(bytes), "stdin", &fs_at(44100.0)),
        Err(SourceError::SampleRateConflict { .. })
    ));
    assert!(matches!(
        open_input("/nonexistent/x.wav", &InputOptions::default()),
        Err(SourceError::Io { .. })
    ));
    let s = open_input(
        &common::data("structural/hrshm_dataset5_pcb_impact_Test_001_head.csv"),
        &InputOptions::default(),
    )
    .unwrap();
    assert_eq!(s.source.info().sample_rate_hz, 51200.0);
    assert_eq!(s.source.info().channels(), 2);
}

#[test]
fn stream_detection() {
    let o = InputOptions::default();
    let mut wav = Vec::new();
    write_wav_f32(&mut wav, 4000, &[vec![0.5, 0.25]]).unwrap();
    let mut s = open_stream(Cursor::new(wav), "stdin", &o).unwrap();
    assert_eq!(drain(s.as_mut(), 1).0, [vec![0.5, 0.25]]);
    // Detection must not lose the first bytes, even of a CSV longer than the sniffed prefix.
    let text: String = std::iter::once("t,a\n".to_string())
        .chain((0..100).map(|i| format!("{},{}\n", i as f64 * 0.5, i)))
        .collect();
    let mut s = open_stream(Cursor::new(text.into_bytes()), "stdin", &o).unwrap();
    assert_eq!(s.info().sample_rate_hz, 2.0);
    let (got, _) = drain(s.as_mut(), 9);
    assert_eq!(got[0], (0..100).map(f64::from).collect::<Vec<_>>());
    // Raw.
    let raw = InputOptions {
        raw: Some(RawFormat::F64),
        fs_hz: Some(100.0),
        channels: Some(1),
        ..Default::default()
    };
    let bytes: Vec<u8> = [1.0f64, -2.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let mut s = open_stream(Cursor::new(bytes), "stdin", &raw).unwrap();
    assert_eq!(drain(s.as_mut(), 5).0, [vec![1.0, -2.0]]);
    let no_fs = InputOptions {
        fs_hz: None,
        ..raw.clone()
    };
    assert!(matches!(
        open_stream(Cursor::new(vec![0u8; 8]), "stdin", &no_fs),
        Err(SourceError::Setting { .. })
    ));
    // Garbage and empty.
    match open_stream(
        Cursor::new(vec![0x7f, b'E', b'L', b'F', 2, 1, 1, 0]),
        "stdin",
        &o,
    ) {
        Err(SourceError::UnrecognisedFormat { detail, .. }) => {
            assert!(detail.contains("7f 45 4c 46"), "{detail}")
        }
        other => panic!("expected UnrecognisedFormat, got {:?}", other.err()),
    }
    assert!(matches!(
        open_stream(Cursor::new(Vec::new()), "stdin", &o),
        Err(SourceError::Empty { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    /// Any byte string, with or without a RIFF or CSV-looking prefix, gives samples or a typed
    /// error, never a panic.
    #[test]
    fn detection_never_panics(
        prefix in prop::sample::select(vec![&b""[..], b"RIFF", b"RIFF\x24\0\0\0WAVEfmt ", b"t,a\n", b"# fs=10\n"]),
        body in prop::collection::vec(any::<u8>(), 0..300),
        block in 1usize..50,
    ) {
        let mut bytes = prefix.to_vec();
        bytes.extend_from_slice(&body);
        if let Ok(mut s) = open_stream(Cursor::new(bytes), "stdin", &InputOptions::default()) {
            let _ = drain(s.as_mut(), block);
        }
    }
}

#[test]
fn integer_wav_in_a_set_uses_meta_scale_and_csv_columns_are_taken_by_id() {
    let dir = tmpdir("scale");
    std::fs::write(dir.join("sensors.csv"), "id,x,y\nA,0,0\nB,1,1\n").unwrap();
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: 1000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(dir.join("responses.wav"), spec).unwrap();
    for c in [100i16, -200, 16384, -32768] {
        w.write_sample(c).unwrap();
    }
    w.finalize().unwrap();
    // Without meta.json: scaled to [-1, 1).
    let mut set = open_recording_set(&dir).unwrap();
    assert_eq!(set.meta, RecordingMeta::default());
    let (got, _) = drain(set.source.as_mut(), 10);
    assert_eq!(
        got,
        [vec![100.0 / 32768.0, 0.5], vec![-200.0 / 32768.0, -1.0]]
    );
    // With "scale": physical units per count; unknown keys ignored.
    std::fs::write(
        dir.join("meta.json"),
        r#"{"scale": 0.001, "kind": "free_decay", "x": [1]}"#,
    )
    .unwrap();
    let mut set = open_recording_set(&dir).unwrap();
    assert_eq!(set.meta.kind, DecayKind::FreeDecay);
    let (got, _) = drain(set.source.as_mut(), 10);
    assert_eq!(got, [vec![0.1, 16.384], vec![-0.2, -32.768]]);
    // CSV columns holding the sensor ids in another order are taken by name (FORMATS.md §1:
    // named by sensor id), in sensors.csv order.
    std::fs::remove_file(dir.join("responses.wav")).unwrap();
    std::fs::write(dir.join("responses.csv"), "time,B,A\n0,1,2\n0.001,3,4\n").unwrap();
    let mut set = open_recording_set(&dir).unwrap();
    assert_eq!(set.source.info().channel_names, ["A", "B"]);
    assert_eq!(
        drain(set.source.as_mut(), 10).0,
        [vec![2.0, 4.0], vec![1.0, 3.0]]
    );
    std::fs::write(dir.join("responses.csv"), "time,A,B\n0,1,2\n0.001,3,4\n").unwrap();
    let mut set = open_recording_set(&dir).unwrap();
    assert!((set.source.info().sample_rate_hz - 1000.0).abs() < 1e-9);
    assert_eq!(
        drain(set.source.as_mut(), 10).0,
        [vec![1.0, 3.0], vec![2.0, 4.0]]
    );
    // Neither response file.
    std::fs::remove_file(dir.join("responses.csv")).unwrap();
    assert!(matches!(
        open_recording_set(&dir),
        Err(SourceError::Setting { .. })
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The measured reference RIRs (PCM16, 44.1 and 96 kHz) stream to exactly hound's samples / 2^15.
#[test]
fn reference_pcm16_wavs_match_hound() {
    for name in ["living_room_1.wav", "ir_sportscentre_omni.wav"] {
        let path = common::data(&format!("rir/{name}"));
        let mut h = hound::WavReader::open(&path).unwrap();
        let spec = h.spec();
        let want: Vec<f64> = h
            .samples::<i16>()
            .map(|s| f64::from(s.unwrap()) / 32768.0)
            .collect();
        let mut o = open_input(&path, &InputOptions::default()).unwrap();
        assert_eq!(o.source.info().sample_rate_hz, f64::from(spec.sample_rate));
        assert_eq!(o.source.info().channels(), usize::from(spec.channels));
        let (got, err) = drain(o.source.as_mut(), 4096);
        assert!(err.is_none(), "{name}: {err:?}");
        assert_eq!(got[0], want, "{name}");
    }
}

fn small_wav() -> Vec<u8> {
    let mut wav = Vec::new();
    write_wav_f32(
        &mut wav,
        4000,
        &[vec![0.5, -1.0, 2.0], vec![1.0, 0.0, -3.0]],
    )
    .unwrap();
    wav
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]
    /// A valid WAV or CSV with random bytes overwritten and a random cut: samples or a typed
    /// error, never a panic, whatever the block size.
    #[test]
    fn mutated_inputs_never_panic(
        csv in any::<bool>(),
        edits in prop::collection::vec((0usize..200, any::<u8>()), 0..6),
        cut in 0usize..200,
        block in 1usize..8,
    ) {
        let mut bytes = if csv {
            b"# fs=100\ntime,a,b\n0,1,2\n0.01,3,4\n0.02,5,6\n".to_vec()
        } else {
            small_wav()
        };
        for (pos, val) in edits {
            if let Some(b) = bytes.get_mut(pos) {
                *b = val;
            }
        }
        bytes.truncate(cut.min(bytes.len()));
        if let Ok(mut s) = open_stream(Cursor::new(bytes), "stdin", &InputOptions::default()) {
            let (got, _) = drain(s.as_mut(), block);
            prop_assert!(got.iter().all(|c| c.len() == got[0].len()));
        }
    }
}

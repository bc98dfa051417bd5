//! Sources: format round trips, truncation contract, block-size independence.

use std::io::Cursor;

use dampscope::output::{write_wav_f32, WavStreamWriter};
use dampscope::source::{Block, CsvSource, RawFormat, RawSource, Source, SourceError, WavSource};

/// Reads a source to its end with blocks of `block` frames: the samples and the final error.
fn drain(src: &mut dyn Source, block: usize) -> (Vec<Vec<f64>>, Option<SourceError>) {
    let mut out = vec![Vec::new(); src.info().channels()];
    let mut b = Block::default();
    loop {
        match src.read_block(block, &mut b) {
            Ok(true) => {
                assert!(b.frames() <= block.max(1), "block larger than asked");
                for (o, c) in out.iter_mut().zip(&b.channels) {
                    o.extend_from_slice(c);
                }
            }
            Ok(false) => return (out, None),
            Err(e) => return (out, Some(e)),
        }
    }
}

fn test_signal(channels: usize, frames: usize) -> Vec<Vec<f64>> {
    (0..channels)
        .map(|c| {
            (0..frames)
                .map(|i| ((i * (c + 3)) as f64 * 0.37).sin() * (c as f64 + 0.5))
                .collect()
        })
        .collect()
}

fn as_f32(x: &[Vec<f64>]) -> Vec<Vec<f64>> {
    x.iter()
        .map(|c| c.iter().map(|&v| f64::from(v as f32)).collect())
        .collect()
}

#[test]
fn float_wav_round_trip_any_block_size() {
    let sig = test_signal(3, 1001);
    let mut bytes = Vec::new();
    write_wav_f32(&mut bytes, 4000, &sig).unwrap();
    let want = as_f32(&sig);
    for block in [1, 7, 256, 5000] {
        let mut src = WavSource::new(Cursor::new(bytes.clone()), "mem").unwrap();
        assert_eq!(src.info().sample_rate_hz, 4000.0);
        assert_eq!(src.info().channel_names, ["ch0", "ch1", "ch2"]);
        let (got, err) = drain(&mut src, block);
        assert!(err.is_none(), "{err:?}");
        assert_eq!(got, want, "block size {block}");
    }
}

#[test]
fn stream_writer_equals_whole_writer() {
    let sig = test_signal(2, 500);
    let mut whole = Vec::new();
    write_wav_f32(&mut whole, 8000, &sig).unwrap();
    let mut w = WavStreamWriter::new(Vec::new(), 8000, 2, 500).unwrap();
    for start in (0..500).step_by(77) {
        let end = (start + 77).min(500);
        w.write_block(&Block::new(
            sig.iter().map(|c| c[start..end].to_vec()).collect(),
        ))
        .unwrap();
    }
    assert_eq!(w.finish().unwrap(), whole);
}

/// Integer WAVs written by hound read back scaled to [-1, 1), like hound's own samples / 2^(b-1).
#[test]
fn integer_wavs_from_hound_are_scaled() {
    for bits in [8u16, 16, 24, 32] {
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 44100,
            bits_per_sample: bits,
            sample_format: hound::SampleFormat::Int,
        };
        let mut cur = Cursor::new(Vec::new());
        let full = 2f64.powi(i32::from(bits) - 1);
        let counts: Vec<i32> = (0..200)
            .map(|i| ((i as f64 * 0.1).sin() * (full - 1.0)).round() as i32)
            .collect();
        {
            let mut w = hound::WavWriter::new(&mut cur, spec).unwrap();
            for &c in &counts {
                w.write_sample(c).unwrap();
            }
            w.finalize().unwrap();
        }
        let mut src = WavSource::new(Cursor::new(cur.into_inner()), "mem").unwrap();
        let (got, err) = drain(&mut src, 33);
        assert!(err.is_none());
        for (i, &c) in counts.iter().enumerate() {
            assert_eq!(
                got[i % 2][i / 2],
                f64::from(c) / full,
                "bits {bits} sample {i}"
            );
        }
    }
}

#[test]
fn hound_float_wav_and_unknown_length() {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 1000,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut cur = Cursor::new(Vec::new());
    {
        let mut w = hound::WavWriter::new(&mut cur, spec).unwrap();
        for i in 0..100 {
            w.write_sample(i as f32 * 0.5).unwrap();
        }
        w.finalize().unwrap();
    }
    let bytes = cur.into_inner();
    let want: Vec<f64> = (0..100).map(|i| i as f64 * 0.5).collect();
    let (got, _) = drain(
        &mut WavSource::new(Cursor::new(bytes.clone()), "m").unwrap(),
        9,
    );
    assert_eq!(got[0], want);
    // Streaming writers leave the data length at 0 or 0xFFFFFFFF: read to the end.
    let data_pos = bytes.windows(4).position(|w| w == b"data").unwrap();
    for marker in [0u32, u32::MAX] {
        let mut b = bytes.clone();
        b[data_pos + 4..data_pos + 8].copy_from_slice(&marker.to_le_bytes());
        let mut src = WavSource::new(Cursor::new(b), "m").unwrap();
        assert_eq!(src.header().data_bytes, None);
        let (got, err) = drain(&mut src, 13);
        assert!(err.is_none());
        assert_eq!(got[0], want);
    }
}

#[test]
fn truncated_wav_gives_every_whole_frame_then_the_error() {
    let sig = test_signal(2, 100);
    let mut bytes = Vec::new();
    write_wav_f32(&mut bytes, 4000, &sig).unwrap();
    // Cut inside frame 61 (58-byte header, 8 bytes per frame).
    bytes.truncate(58 + 61 * 8 + 5);
    for block in [1, 10, 61, 1000] {
        let mut src = WavSource::new(Cursor::new(bytes.clone()), "cut.wav").unwrap();
        let (got, err) = drain(&mut src, block);
        assert_eq!(
            got,
            as_f32(&sig)
                .iter()
                .map(|c| c[..61].to_vec())
                .collect::<Vec<_>>()
        );
        match err {
            Some(SourceError::Truncated { expected, got, .. }) => {
                assert!(expected.contains("800 data bytes"), "{expected}");
                assert!(
                    got.contains("493 bytes") && got.contains("61 whole"),
                    "{got}"
                );
            }
            other => panic!("expected Truncated, got {other:?}"),
        }
    }
    // Cut inside the header.
    assert!(matches!(
        WavSource::new(Cursor::new(bytes[..30].to_vec()), "h"),
        Err(SourceError::Truncated { .. })
    ));
}

#[test]
fn wav_without_samples_is_empty_and_bad_headers_are_errors() {
    let mut bytes = Vec::new();
    write_wav_f32(&mut bytes, 4000, &[vec![]]).unwrap();
    let mut src = WavSource::new(Cursor::new(bytes), "e").unwrap();
    assert!(matches!(
        drain(&mut src, 10).1,
        Some(SourceError::Empty { .. })
    ));
    assert!(matches!(
        WavSource::new(Cursor::new(Vec::new()), "e"),
        Err(SourceError::Empty { .. })
    ));
    assert!(matches!(
        WavSource::new(Cursor::new(b"RIFF\0\0\0\0AVI LIST".to_vec()), "e"),
        Err(SourceError::UnrecognisedFormat { .. })
    ));
    // fmt chunk with 0 channels
    let mut bytes = Vec::new();
    write_wav_f32(&mut bytes, 4000, &[vec![1.0]]).unwrap();
    bytes[22] = 0;
    assert!(matches!(
        WavSource::new(Cursor::new(bytes), "e"),
        Err(SourceError::Malformed { .. })
    ));
}

fn raw_bytes(sig: &[Vec<f64>], format: RawFormat) -> Vec<u8> {
    let mut b = Vec::new();
    for i in 0..sig[0].len() {
        for c in sig {
            match format {
                RawFormat::F32 => b.extend_from_slice(&(c[i] as f32).to_le_bytes()),
                RawFormat::F64 => b.extend_from_slice(&c[i].to_le_bytes()),
            }
        }
    }
    b
}

#[test]
fn raw_round_trip_and_truncation() {
    let sig = test_signal(3, 300);
    for (format, want) in [
        (RawFormat::F32, as_f32(&sig)),
        (RawFormat::F64, sig.clone()),
    ] {
        let bytes = raw_bytes(&sig, format);
        for block in [1, 64, 1000] {
            let mut src =
                RawSource::new(Cursor::new(bytes.clone()), "raw", format, 4000.0, 3).unwrap();
            let (got, err) = drain(&mut src, block);
            assert!(err.is_none());
            assert_eq!(got, want);
        }
        let frame = 3 * format.bytes();
        let cut = bytes[..200 * frame + frame - 1].to_vec();
        let mut src = RawSource::new(Cursor::new(cut), "raw", format, 4000.0, 3).unwrap();
        let (got, err) = drain(&mut src, 64);
        assert_eq!(
            got,
            want.iter().map(|c| c[..200].to_vec()).collect::<Vec<_>>()
        );
        match err {
            Some(SourceError::Truncated { got, .. }) => {
                assert!(got.contains(&format!("{} stray bytes", frame - 1)), "{got}")
            }
            other => panic!("expected Truncated, got {other:?}"),
        }
    }
    assert_eq!("F64".parse::<RawFormat>(), Ok(RawFormat::F64));
    assert!("i16".parse::<RawFormat>().is_err());
    assert!(RawSource::new(Cursor::new(vec![]), "r", RawFormat::F32, 0.0, 1).is_err());
    assert!(RawSource::new(Cursor::new(vec![]), "r", RawFormat::F32, 10.0, 0).is_err());
    let mut empty = RawSource::new(Cursor::new(vec![]), "r", RawFormat::F32, 10.0, 1).unwrap();
    assert!(matches!(
        drain(&mut empty, 4).1,
        Some(SourceError::Empty { .. })
    ));
}

fn csv(text: &str, fs: Option<f64>) -> Result<CsvSource<Cursor<Vec<u8>>>, SourceError> {
    CsvSource::new(Cursor::new(text.as_bytes().to_vec()), "t.csv", fs)
}

#[test]
fn csv_layouts() {
    let mut s = csv("time,a,b\n0,1,2\n0.25,3,4\n0.5,5,nan\n", None).unwrap();
    assert_eq!(s.info().sample_rate_hz, 4.0);
    assert_eq!(s.info().channel_names, ["a", "b"]);
    let (got, err) = drain(&mut s, 1);
    assert!(err.is_none());
    assert_eq!(got[0], [1.0, 3.0, 5.0]);
    assert_eq!(got[1][..2], [2.0, 4.0]);
    assert!(got[1][2].is_nan(), "NaN passes through");
    // Headerless with a `# fs=` comment (as in the reference structural data), CRLF, blank lines.
    let mut s = csv("# fs=51200 ; source: x\r\n1.5,-2\r\n\r\n3,inf\r\n", None).unwrap();
    assert_eq!(s.info().sample_rate_hz, 51200.0);
    assert_eq!(s.info().channel_names, ["ch0", "ch1"]);
    let (got, _) = drain(&mut s, 10);
    assert_eq!(got, [vec![1.5, 3.0], vec![-2.0, f64::INFINITY]]);
    // Explicit fs wins; a header without time needs one.
    assert_eq!(
        csv("a\n1\n", Some(10.0)).unwrap().info().sample_rate_hz,
        10.0
    );
    assert!(matches!(
        csv("a\n1\n", None),
        Err(SourceError::Setting { .. })
    ));
    assert!(matches!(csv("", Some(1.0)), Err(SourceError::Empty { .. })));
    assert!(matches!(
        csv("# only\n\n", Some(1.0)),
        Err(SourceError::Empty { .. })
    ));
    let mut header_only = csv("a,b\n", Some(1.0)).unwrap();
    assert!(matches!(
        drain(&mut header_only, 4).1,
        Some(SourceError::Empty { .. })
    ));
}

#[test]
fn csv_errors_come_after_the_good_rows() {
    let cases = [
        (
            "t,a\n0,1\n0.5,2\n1.0,3,4\n1.5,5\n",
            "line 4: expected 2 columns, got 3",
        ),
        (
            "t,a\n0,1\n0.5,2\n1.0,x\n",
            "line 4, a: expected a number, got \"x\"",
        ),
        // Times printed to 0.1 s may be off by 0.05 s each: 1.1 would be within that.
        (
            "t,a\n0,1\n0.5,2\n1.3,3\n",
            "line 4: time column not uniform",
        ),
    ];
    for (text, msg) in cases {
        let mut s = csv(text, None).unwrap();
        let (got, err) = drain(&mut s, 100);
        assert_eq!(got[0], [1.0, 2.0], "{text}");
        match err {
            Some(SourceError::Malformed { detail, .. }) => {
                assert!(detail.contains(msg), "{detail} should contain {msg}")
            }
            other => panic!("expected Malformed, got {other:?}"),
        }
    }
    // A last line cut short by the end of the stream is a truncation.
    let mut s = csv("a,b\n1,2\n3,4\n5", Some(1.0)).unwrap();
    let (got, err) = drain(&mut s, 1);
    assert_eq!(got, [vec![1.0, 3.0], vec![2.0, 4.0]]);
    assert!(
        matches!(err, Some(SourceError::Truncated { .. })),
        "{err:?}"
    );
    // A complete last line without a newline is fine.
    let (got, err) = drain(&mut csv("a,b\n1,2\n3,4", Some(1.0)).unwrap(), 1);
    assert!(err.is_none());
    assert_eq!(got[1], [2.0, 4.0]);
}

#[test]
fn csv_block_sizes_agree() {
    let sig = test_signal(2, 403);
    let mut text = String::from("time,x,y\n");
    for (i, (a, b)) in sig[0].iter().zip(&sig[1]).enumerate() {
        text += &format!("{},{a},{b}\n", i as f64 / 1000.0);
    }
    for block in [1, 2, 50, 403, 1000] {
        let mut s = csv(&text, None).unwrap();
        assert!((s.info().sample_rate_hz - 1000.0).abs() < 1e-9);
        let (got, err) = drain(&mut s, block);
        assert!(err.is_none(), "{err:?}");
        assert_eq!(got, sig, "block {block}");
    }
}

/// A reader that hands out at most `chunk` bytes per call, like a pipe fed slowly.
struct Trickle {
    data: Vec<u8>,
    pos: usize,
    chunk: usize,
}

impl std::io::Read for Trickle {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = buf.len().min(self.chunk).min(self.data.len() - self.pos);
        buf[..n].copy_from_slice(&self.data[self.pos..self.pos + n]);
        self.pos += n;
        Ok(n)
    }
}

#[test]
fn slow_pipes_give_the_same_samples_and_errors() {
    let sig = test_signal(2, 150);
    let mut wav = Vec::new();
    write_wav_f32(&mut wav, 4000, &sig).unwrap();
    let raw = raw_bytes(&sig, RawFormat::F64);
    for chunk in [1, 3, 7, 64, 4096] {
        let t = |data: &[u8]| Trickle {
            data: data.to_vec(),
            pos: 0,
            chunk,
        };
        let mut src = WavSource::new(t(&wav), "pipe").unwrap();
        let (got, err) = drain(&mut src, 16);
        assert!(err.is_none());
        assert_eq!(got, as_f32(&sig), "wav, chunk {chunk}");
        let mut src = WavSource::new(t(&wav[..wav.len() - 3]), "pipe").unwrap();
        let (got, err) = drain(&mut src, 16);
        assert_eq!(got[0].len(), 149, "wav cut, chunk {chunk}");
        assert!(matches!(err, Some(SourceError::Truncated { .. })));
        let mut src = RawSource::new(t(&raw), "pipe", RawFormat::F64, 10.0, 2).unwrap();
        let (got, err) = drain(&mut src, 16);
        assert!(err.is_none());
        assert_eq!(got, sig, "raw, chunk {chunk}");
        let mut src =
            RawSource::new(t(&raw[..raw.len() - 9]), "pipe", RawFormat::F64, 10.0, 2).unwrap();
        let (got, err) = drain(&mut src, 16);
        assert_eq!(got[1][..], sig[1][..149], "raw cut, chunk {chunk}");
        match err {
            Some(SourceError::Truncated { got, .. }) => {
                assert!(got.contains("149 whole frames and 7 stray bytes"), "{got}")
            }
            other => panic!("expected Truncated, got {other:?}"),
        }
    }
}

//! Raw and WAV frames reach the workers undecoded, and each worker decodes its own run of
//! channels. That must not change a single result: the same rows, flags and input errors as
//! when the reader decodes every block itself, for streamed and mapped input, any thread
//! count (runs of 8 channels that take the vector decoder, and runs that do not), a NaN in one
//! channel, and input that ends in a partial frame.

use std::io::Write;
use std::sync::Arc;

use crate::common::{decaying_sines, gaussian_noise};
use dampscope::frontend::stft::{StftFrontEnd, StftSettings};
use dampscope::frontend::{Band, FrontEnd};
use dampscope::pipeline::{run_with, AnalysisConfig, FrontEndFactory, ResultRow, RunOptions};
use dampscope::source::raw::{RawFormat, RawSource};
use dampscope::source::{Block, SignalInfo, Source, SourceError};

const FS: f64 = 4000.0;

/// A source that only decodes (it hides `read_encoded_block`): the reader-side oracle.
struct DecodedOnly(Box<dyn Source>);

impl Source for DecodedOnly {
    fn info(&self) -> &SignalInfo {
        self.0.info()
    }
    fn read_block(&mut self, max_frames: usize, block: &mut Block) -> Result<bool, SourceError> {
        self.0.read_block(max_frames, block)
    }
}

/// `n` channels × 6 s of interleaved f32: two hits per channel at channel-dependent times, one
/// channel with a NaN, and `stray` bytes of a partial last frame.
fn raw_bytes(n: usize, stray: usize) -> Vec<u8> {
    let len = (6.0 * FS) as usize;
    let channels: Vec<Vec<f64>> = (0..n)
        .map(|c| {
            let mut x = gaussian_noise(len, 1e-4, c as u64 + 11);
            for k in 0..2 {
                let start = ((0.3 + 2.9 * k as f64 + 0.07 * (c % 5) as f64) * FS) as usize;
                let f = 95.0 + 30.0 * (c % 4) as f64;
                let hit = decaying_sines(&[(f, 0.008 + 0.001 * c as f64, 1.0, 0.0)], FS, 2.5);
                for (i, v) in hit.into_iter().enumerate() {
                    x[start + i] += v;
                }
            }
            if c == n / 2 {
                x[(4.0 * FS) as usize] = f64::NAN;
            }
            x
        })
        .collect();
    let mut bytes = Vec::with_capacity(n * len * 4 + stray);
    for i in 0..len {
        for ch in &channels {
            bytes.extend_from_slice(&(ch[i] as f32).to_le_bytes());
        }
    }
    bytes.extend(std::iter::repeat_n(0x3f_u8, stray));
    bytes
}

/// Rows and the input error (as text) of one run.
fn analyse(source: Box<dyn Source>, threads: usize) -> (Vec<ResultRow>, Option<String>) {
    let bands: Vec<Band> = (0..4)
        .map(|k| Band::new(80.0 + 30.0 * k as f64, 110.0 + 30.0 * k as f64).unwrap())
        .collect();
    let factory: FrontEndFactory = Arc::new(move || {
        Ok(Box::new(StftFrontEnd::new(StftSettings::default(), FS, &bands)?) as Box<dyn FrontEnd>)
    });
    let config = AnalysisConfig {
        block_frames: 1500,
        ..Default::default()
    };
    let options = RunOptions {
        threads: Some(threads),
        ..Default::default()
    };
    let mut rows = Vec::new();
    let summary = run_with(source, &factory, &config, options, |r| {
        rows.extend_from_slice(r);
        Ok(())
    })
    .unwrap();
    (rows, summary.input_error.map(|e| e.to_string()))
}

#[test]
fn workers_decoding_their_own_channels_give_the_readers_results() {
    let dir = std::env::temp_dir().join(format!("dampscope-encoded-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (n, stray) in [(16usize, 0usize), (13, 5)] {
        let bytes = raw_bytes(n, stray);
        let path = dir.join(format!("{n}.f32"));
        std::fs::File::create(&path)
            .unwrap()
            .write_all(&bytes)
            .unwrap();
        let streamed = || {
            let cursor = std::io::Cursor::new(bytes.clone());
            RawSource::new(cursor, "x", RawFormat::F32, FS, n).unwrap()
        };
        let (oracle, oracle_error) = analyse(Box::new(DecodedOnly(Box::new(streamed()))), 1);
        assert!(oracle.len() >= 2 * n * 4, "{n} ch: {} rows", oracle.len());
        assert!(
            oracle.iter().any(|r| r.channel == format!("ch{}", n / 2)
                && r.estimate.has(dampscope::decay::Flag::NonFiniteInput)),
            "the NaN is flagged"
        );
        assert_eq!(oracle_error.is_some(), stray > 0, "{oracle_error:?}");
        for threads in [1, 2, 3] {
            let mapped = || {
                let file = std::fs::File::open(&path).unwrap();
                RawSource::from_file(file, "x", RawFormat::F32, FS, n).unwrap()
            };
            let runs: [(&str, Box<dyn Source>); 2] = [
                ("streamed", Box::new(streamed())),
                ("mapped", Box::new(mapped())),
            ];
            for (how, source) in runs {
                let (rows, error) = analyse(source, threads);
                assert_eq!(rows, oracle, "{n} ch, {how}, {threads} threads");
                assert_eq!(error, oracle_error, "{n} ch, {how}, {threads} threads");
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

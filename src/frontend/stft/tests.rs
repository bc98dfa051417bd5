//! Unit tests of the STFT front end: band weights, bands above Nyquist, block-size
//! independence, frame pairs against single frames.

use super::*;

#[test]
fn edge_bins_are_weighted_by_overlap() {
    // 10 Hz bins; band 15–40 Hz: bin 1 (5–15) 0, bin 2 (15–25) 1, bin 3 1, bin 4 (35–45) 0.5.
    let bb = band_weights(&Band::new(15.0, 40.0).unwrap(), 10.0, 100);
    let total: f64 = bb.weights.iter().sum();
    assert!((total - 2.5).abs() < 1e-12, "{:?}", bb);
}

/// Found with `map --band 600:700` on a 500 Hz recording: a band wholly above Nyquist
/// sliced past the spectrum and panicked the worker. Now it has no bins and zero energy.
#[test]
fn a_band_above_nyquist_has_no_bins() {
    let bb = band_weights(&Band::new(600.0, 700.0).unwrap(), 10.0, 26);
    assert!(bb.weights.is_empty());
    let mut fe = StftFrontEnd::new(
        StftSettings::default(),
        500.0,
        &[Band::new(600.0, 700.0).unwrap()],
    )
    .unwrap();
    let x: Vec<f64> = (0..2000).map(|i| (0.3 * i as f64).sin()).collect();
    let mut frames = 0;
    fe.process(&x, &mut |f: Frame<'_>| {
        assert_eq!(f.energy[0], 0.0);
        frames += 1;
    });
    assert!(frames > 0);
}

#[test]
fn block_size_does_not_change_frames() {
    let fs = 1000.0;
    let x: Vec<f64> = (0..3000)
        .map(|i| {
            let t = i as f64 / fs;
            (-2.0 * t).exp() * (2.0 * std::f64::consts::PI * 52.0 * t).sin()
        })
        .collect();
    let bands = [
        Band::new(40.0, 60.0).unwrap(),
        Band::new(60.0, 100.0).unwrap(),
    ];
    let run = |block: usize| {
        let mut fe = StftFrontEnd::new(StftSettings::default(), fs, &bands).unwrap();
        let mut out = Vec::new();
        let mut sink = |f: Frame<'_>| out.push((f.energy.to_vec(), f.frequency_hz.to_vec()));
        for c in x.chunks(block) {
            fe.process(c, &mut sink);
        }
        fe.finish(&mut sink);
        out
    };
    let whole = run(x.len());
    assert_eq!(whole.len(), (3000 - 200) / 100 + 1);
    assert_eq!(run(1), whole);
    assert_eq!(run(333), whole);
    // The peak frequency in the first band is the tone's.
    assert!((whole[3].1[0] - 52.0).abs() < 0.3, "{}", whole[3].1[0]);
}
/// Two decaying tones, 52.3 Hz and 131 Hz, `n` samples at `fs`.
fn two_tones(fs: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            (-3.0 * t).exp() * (2.0 * std::f64::consts::PI * 52.3 * t).sin()
                + 0.3 * (-t).exp() * (2.0 * std::f64::consts::PI * 131.0 * t).cos()
        })
        .collect()
}

/// A band around each of [`two_tones`].
fn tone_bands() -> [Band; 2] {
    [
        Band::new(40.0, 60.0).unwrap(),
        Band::new(100.0, 200.0).unwrap(),
    ]
}

/// An odd window (201 samples) takes frames in pairs through one complex FFT whenever two
/// are in hand: fed whole (pairs) or a sample at a time (single real FFTs, the oracle), the
/// frames agree to rounding and give the same peak frequencies.
#[test]
fn frame_pairs_equal_single_frames() {
    let fs = 1005.0;
    let (x, bands) = (two_tones(fs, 4000), tone_bands());
    let run = |block: usize| {
        let mut fe = StftFrontEnd::new(StftSettings::default(), fs, &bands).unwrap();
        assert!(fe.transform.pairs_frames() && fe.window_samples() == 201);
        let mut out = Vec::new();
        let mut sink = |f: Frame<'_>| out.push((f.energy.to_vec(), f.frequency_hz.to_vec()));
        for c in x.chunks(block) {
            fe.process(c, &mut sink);
        }
        out
    };
    let (paired, single) = (run(x.len()), run(1));
    assert_eq!(paired.len(), (4000 - 201) / 100 + 1);
    assert_eq!(paired.len(), single.len());
    for ((ep, fp), (es, fsg)) in paired.iter().zip(&single) {
        for (a, b) in ep.iter().zip(es) {
            assert!((a - b).abs() <= 1e-12 * b.abs(), "{a} vs {b}");
        }
        for (a, b) in fp.iter().zip(fsg) {
            assert!((a - b).abs() <= 1e-9, "{a} vs {b}");
        }
    }
}

/// Told the samples ahead ([`FrontEnd::process_ahead`]), an odd window transforms a lone frame
/// with the next one and emits that one only once the input completes it: the same frames, at
/// the same calls, as without them (to rounding), whether the samples ahead reach the end,
/// stop short of the next frame's end (a new hit cut the decay), or are none. Windows of 201
/// samples (pairs through rustfft) and 819 = 9 · 7 · 13 (pairs through the prime-factor FFT on
/// AVX-512 CPUs).
#[test]
fn samples_ahead_change_neither_frames_nor_when_they_leave() {
    for fs in [1005.0, 4096.0] {
        let (x, bands) = (two_tones(fs, 20_000), tone_bands());
        // Per call: the frames it emitted.
        type Calls = Vec<Vec<(Vec<f64>, Vec<f64>)>>;
        let run = |chunk: usize, ahead_len: Option<usize>| -> Calls {
            let mut fe = StftFrontEnd::new(StftSettings::default(), fs, &bands).unwrap();
            assert!(fe.transform.pairs_frames());
            let mut calls = Vec::new();
            for start in (0..x.len()).step_by(chunk) {
                let end = (start + chunk).min(x.len());
                let mut out = Vec::new();
                let mut sink =
                    |f: Frame<'_>| out.push((f.energy.to_vec(), f.frequency_hz.to_vec()));
                match ahead_len {
                    None => fe.process(&x[start..end], &mut sink),
                    Some(n) => {
                        let ahead = &x[end..end.saturating_add(n).min(x.len())];
                        fe.process_ahead(&x[start..end], ahead, &mut sink)
                    }
                }
                calls.push(out);
            }
            calls
        };
        for chunk in [1024, 333, 4096] {
            let plain = run(chunk, None);
            let frames: usize = plain.iter().map(Vec::len).sum();
            assert!(frames > 40, "{fs} Hz: {frames} frames");
            for ahead_len in [usize::MAX, 100, 0] {
                let told = run(chunk, Some(ahead_len));
                assert_eq!(told.len(), plain.len());
                for (call, (t, p)) in told.iter().zip(&plain).enumerate() {
                    assert_eq!(
                        t.len(),
                        p.len(),
                        "{fs} Hz chunk {chunk} ahead {ahead_len} call {call}"
                    );
                    for ((te, tf), (pe, pf)) in t.iter().zip(p) {
                        // A transform rounds relative to the frame's energy, not a weak band's.
                        let scale = pe.iter().fold(0.0f64, |m, &e| m.max(e));
                        for (a, b) in te.iter().zip(pe) {
                            assert!((a - b).abs() <= 1e-12 * scale, "{a} vs {b}");
                        }
                        for (a, b) in tf.iter().zip(pf) {
                            assert!(
                                (a - b).abs() <= 1e-9 || (a.is_nan() && b.is_nan()),
                                "{a} vs {b}"
                            );
                        }
                    }
                }
            }
        }
    }
}

/// The quantization floor rests on it: white noise through the STFT gives each band the
/// predicted energy per frame, for even and odd window lengths, with zero padding, and for
/// bands with fractional edge bins (4096 and 8192 Hz; 200 and 50 ms).
#[test]
fn white_noise_gives_each_band_its_predicted_energy() {
    let bands: Vec<Band> = [
        (20.0, 70.0),
        (102.5, 152.5),
        (400.0, 1000.0),
        (1500.0, 1530.0),
    ]
    .iter()
    .map(|&(lo, hi)| Band::new(lo, hi).unwrap())
    .collect();
    for (fs, window_ms, zero_pad) in [(4096.0, 200.0, 1), (8192.0, 200.0, 1), (8192.0, 50.0, 2)] {
        let settings = StftSettings {
            window_ms,
            zero_pad,
            ..Default::default()
        };
        let mut fe = StftFrontEnd::new(settings, fs, &bands).unwrap();
        crate::frontend::test_frames::assert_white_noise_energy(&mut fe, fs, 120.0, 0.06);
    }
}

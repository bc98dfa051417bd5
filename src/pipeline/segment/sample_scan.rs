//! Whole-block scans of a channel's samples that every sample of a stream passes through: the
//! largest finite magnitude (the new-hit watch) and whether every sample is finite (the bad-input
//! guard). Both are exact whatever the order (a maximum; a yes/no), so they run in independent
//! lanes that the CPU advances in one vector instruction; a serial `if a > max` chain cost one
//! compare latency per sample and was 7–11 % of a whole STFT run.

use crate::frontend::simd::Isa;

/// Lanes per scan step (two AVX2 vectors: enough independent chains to hide the latency).
const LANES: usize = 8;

/// Slices shorter than this are scanned serially, inline: at low rates the new-hit watch's
/// blocks are a few samples long (an eighth of a quarter period of the lowest band), too short
/// for the lanes to pay for the call.
const SHORT_SCAN: usize = 32;

/// |v| for a finite v, else 0 (`a < ∞` is false for ±∞ and NaN).
#[inline(always)]
fn magnitude(v: f64) -> f64 {
    let a = v.abs();
    if a < f64::INFINITY {
        a
    } else {
        0.0
    }
}

/// [`max_abs_finite`] one sample after the other.
#[inline(always)]
fn serial_max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |best, &v| {
        let a = magnitude(v);
        if a > best {
            a
        } else {
            best
        }
    })
}

/// The largest |x| over the finite samples of `x` (non-finite samples count as 0); 0 if empty.
/// Always inlined: a short slice is scanned in place (the new-hit watch at low rates scans
/// blocks of a few samples, and the call cost more than the scan; as a mere `#[inline]` hint it
/// stayed a call, 2.9 % of an STFT run at 4096 Hz).
#[inline(always)]
pub(crate) fn max_abs_finite(isa: Isa, x: &[f64]) -> f64 {
    if x.len() < SHORT_SCAN {
        serial_max_abs(x)
    } else {
        max_abs_in_lanes(isa, x)
    }
}

/// [`max_abs_finite`] of a slice long enough for the lanes.
fn max_abs_in_lanes(isa: Isa, x: &[f64]) -> f64 {
    #[inline(always)]
    fn run(x: &[f64]) -> f64 {
        let mut lanes = [0.0f64; LANES];
        let chunks = x.chunks_exact(LANES);
        let tail = chunks.remainder();
        for chunk in chunks {
            for (m, &v) in lanes.iter_mut().zip(chunk) {
                let a = magnitude(v);
                *m = if a > *m { a } else { *m };
            }
        }
        serial_max_abs(tail).max(serial_max_abs(&lanes))
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(x: &[f64]) -> f64 {
        run(x)
    }
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU.
        Isa::Avx2Fma | Isa::Avx512 => unsafe { run_avx2(x) },
        Isa::Generic => run(x),
    }
}

/// Samples of small blocks whose maxima are found per piece (a stack buffer of this length).
const PIECE_SAMPLES: usize = 512;

/// Writes the [`max_abs_finite`] of each whole `block`-sample block of `x` into `ring` from
/// `head` on, wrapping at its end; returns the next head. Small blocks (the new-hit watch at
/// low rates: 5 samples at 4096 Hz) take no call and no serial fold each: the magnitudes and
/// their running maxima over 2, 4, … samples are whole-piece passes in lanes, and a block of
/// b samples is the larger of two overlapping windows of the largest power of two ≤ b (a
/// maximum, so exactly the serial one).
pub(crate) fn block_maxima_into_ring(
    isa: Isa,
    x: &[f64],
    block: usize,
    ring: &mut [f64],
    mut head: usize,
) -> usize {
    debug_assert!(block > 0 && x.len().is_multiple_of(block) && head < ring.len());
    let mut put = |m: f64| {
        ring[head] = m;
        head = if head + 1 == ring.len() { 0 } else { head + 1 };
    };
    if block >= SHORT_SCAN || block == 1 {
        x.chunks_exact(block)
            .for_each(|b| put(max_abs_finite(isa, b)));
        return head;
    }
    // Out of place, so that each pass is a plain lane loop: next[i] = max(cur[i], cur[i + w]).
    #[inline(always)]
    fn windows<'a>(cur: &'a mut [f64], next: &'a mut [f64], x: &[f64], width: usize) -> &'a [f64] {
        for (m, &v) in cur.iter_mut().zip(x) {
            *m = magnitude(v);
        }
        let (mut cur, mut next) = (cur, next);
        let mut w = 1;
        while 2 * w <= width {
            let n = cur.len() - w;
            for ((o, &a), &b) in next[..n].iter_mut().zip(&cur[..n]).zip(&cur[w..]) {
                *o = if b > a { b } else { a };
            }
            std::mem::swap(&mut cur, &mut next);
            w *= 2;
        }
        cur
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn windows_avx2<'a>(
        cur: &'a mut [f64],
        next: &'a mut [f64],
        x: &[f64],
        width: usize,
    ) -> &'a [f64] {
        windows(cur, next, x, width)
    }
    let mut width = 1;
    while 2 * width <= block {
        width *= 2;
    }
    // Two pieces of scratch per thread (zero-filled once, not per call).
    thread_local! {
        static SCRATCH: std::cell::RefCell<Vec<f64>> = Default::default();
    }
    crate::frontend::with_thread_scratch(&SCRATCH, |scratch| {
        scratch.resize(2 * PIECE_SAMPLES, 0.0);
        let (cur, next) = scratch.split_at_mut(PIECE_SAMPLES);
        let piece_len = (PIECE_SAMPLES / block * block).min(x.len()).max(block);
        for piece in x.chunks(piece_len) {
            let (cur, next) = (&mut cur[..piece.len()], &mut next[..piece.len()]);
            let window = match isa {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `Isa::detect` found AVX2 on this CPU.
                Isa::Avx2Fma | Isa::Avx512 => unsafe { windows_avx2(cur, next, piece, width) },
                Isa::Generic => windows(cur, next, piece, width),
            };
            // window[i] holds the maximum of `width` samples from i on (i ≤ len − width).
            for start in (0..piece.len()).step_by(block) {
                let (a, b) = (window[start], window[start + block - width]);
                put(if b > a { b } else { a });
            }
        }
    });
    head
}

/// Index of the first non-finite sample of `x`, if any. The common all-finite block is settled
/// by one lane-parallel pass (x·0 is 0 for a finite x and NaN otherwise).
pub(crate) fn first_non_finite(isa: Isa, x: &[f64]) -> Option<usize> {
    #[inline(always)]
    fn all_finite(x: &[f64]) -> bool {
        let mut lanes = [0.0f64; LANES];
        let chunks = x.chunks_exact(LANES);
        let tail = chunks.remainder();
        for chunk in chunks {
            for (s, &v) in lanes.iter_mut().zip(chunk) {
                *s += v * 0.0;
            }
        }
        tail.iter().chain(&lanes).all(|v| (v * 0.0) == 0.0)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn all_finite_avx2(x: &[f64]) -> bool {
        all_finite(x)
    }
    let fine = match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Isa::detect` found AVX2 on this CPU.
        Isa::Avx2Fma | Isa::Avx512 => unsafe { all_finite_avx2(x) },
        Isa::Generic => all_finite(x),
    };
    if fine {
        None
    } else {
        x.iter().position(|v| !v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Block maxima into a ring against one `max_abs_finite` per block: block sizes 1 to 40
    /// (both paths, powers of two and not), stretches longer than a piece, non-finite samples,
    /// rings shorter and longer than the stretch, every head, every instruction set.
    #[test]
    fn block_maxima_equal_one_scan_per_block() {
        for isa in Isa::available() {
            for block in (1..=40).chain([64, 100]) {
                for blocks in [0usize, 1, 3, 97, 230] {
                    let mut x: Vec<f64> = (0..block * blocks)
                        .map(|i| ((i * 7919 % 1013) as f64 - 500.0) * 1e-3)
                        .collect();
                    for (k, s) in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY]
                        .iter()
                        .enumerate()
                    {
                        if let Some(v) = x.get_mut(k * 37 + 5) {
                            *v = *s;
                        }
                    }
                    for ring_len in [1usize, 7, 300] {
                        for head in [0, ring_len / 2, ring_len - 1] {
                            let mut want = vec![-1.0; ring_len];
                            let mut h = head;
                            for b in x.chunks_exact(block) {
                                want[h] = max_abs_finite(isa, b);
                                h = (h + 1) % ring_len;
                            }
                            let mut got = vec![-1.0; ring_len];
                            let got_head = block_maxima_into_ring(isa, &x, block, &mut got, head);
                            assert_eq!(got_head, h, "{isa:?} block {block} × {blocks}");
                            assert!(
                                got.iter()
                                    .zip(&want)
                                    .all(|(g, w)| g.to_bits() == w.to_bits()),
                                "{isa:?} block {block} × {blocks}, ring {ring_len} from {head}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// Against the one-sample-at-a-time definitions, on every instruction set of this CPU, with
    /// lengths around the lane count and non-finite samples at every position class.
    #[test]
    fn lane_scans_equal_the_serial_definitions() {
        let specials = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
        for isa in Isa::available() {
            for len in [0usize, 1, 7, 8, 9, 17, 64, 100] {
                let base: Vec<f64> = (0..len)
                    .map(|i| ((i * 7919 % 101) as f64 - 50.0) * 0.37)
                    .collect();
                let mut cases = vec![base.clone()];
                for pos in [0, len / 2, len.saturating_sub(1)] {
                    for s in specials {
                        if len > 0 {
                            let mut c = base.clone();
                            c[pos] = s;
                            cases.push(c);
                        }
                    }
                }
                for x in cases {
                    let serial_max = x
                        .iter()
                        .map(|v| if v.is_finite() { v.abs() } else { 0.0 })
                        .fold(0.0f64, f64::max);
                    assert_eq!(max_abs_finite(isa, &x), serial_max, "{isa:?} {x:?}");
                    assert_eq!(
                        first_non_finite(isa, &x),
                        x.iter().position(|v| !v.is_finite()),
                        "{isa:?} {x:?}"
                    );
                }
            }
        }
    }
}

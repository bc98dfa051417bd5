//! The end-of-decay scans over a whole decay's frames at once (a buffered bank hands them over
//! together): which frames are low against their band's running peak, and the running sums of
//! the floor test. Each gives the same bits as the frame-by-frame form
//! ([`super::bands::BandTrackers`]'s `push`), which its tests check.
//!
//! Both were chains, one step per frame waiting on the step before: the running peak (a
//! maximum with its NaN rule per frame) and the running sum (an addition per frame), band by
//! band: 7–9 % of a 64-channel octave-bank run at 4096 Hz with 2 ms frames (perf; 3 % after).
//! Here the peak's chain runs only until the peak reaches its final value (near a decay's
//! start), the frames after it compare against a constant; and the sums of up to four bands
//! advance side by side.

/// Marks as not low, in `all_low`, every frame of `band` whose energy is above `end_factor`
/// times the band's running peak, the peak starting at `peak` (a NaN energy never raises it);
/// returns the peak after the band's last frame. The same bits as, frame by frame,
/// `p = p.max(e); *low &= e <= p * end_factor`.
pub(super) fn mark_low(all_low: &mut [bool], band: &[f64], peak: f64, end_factor: f64) -> f64 {
    let last = peak.max(crate::decay::max_ignoring_nan(band));
    // Frame by frame while the running peak is below its final value; from the frame where
    // it reaches it on, it stays there (no later frame is larger; a NaN one leaves it).
    let mut p = peak;
    let mut k = 0;
    while k < band.len() && p != last {
        p = p.max(band[k]);
        all_low[k] &= band[k] <= p * end_factor;
        k += 1;
    }
    let threshold = p * end_factor;
    crate::frontend::simd::in_wide_vectors(|| {
        for (low, &e) in all_low[k..band.len()].iter_mut().zip(&band[k..]) {
            *low &= e <= threshold;
        }
    });
    p
}

/// Appends `frames` entries to one band's running sum `sum` (which holds its leading 0): the
/// energies of `active`, then, past them, the last frame repeated (a band no longer active
/// leaves the floor test neutral).
pub(super) fn extend_sum(sum: &mut Vec<f64>, active: &[f64], frames: usize) {
    let mut last = sum[sum.len() - 1];
    let mut before = sum.len().checked_sub(2).map(|j| sum[j]);
    // From an iterator of known length: no capacity test per entry, which had the running
    // values go through memory at every step.
    sum.extend((0..frames).map(|k| {
        let e = match active.get(k) {
            Some(&e) => e,
            None => before.map_or(0.0, |p| last - p),
        };
        (before, last) = (Some(last), last + e);
        last
    }));
}

/// [`extend_sum`] for every band (`sums[b]` with `actives[b]`), bit for bit; the frames all
/// bands of a group of four still have advance side by side, the rest band by band.
pub(super) fn extend_sums(sums: &mut [Vec<f64>], actives: &[&[f64]], frames: usize) {
    for (group, active) in sums.chunks_mut(4).zip(actives.chunks(4)) {
        let (side_by_side, common) = match (&mut *group, active) {
            ([a, b, c, d], [xa, xb, xc, xd]) => (
                4,
                extend_side_by_side([a, b, c, d], [xa, xb, xc, xd], frames),
            ),
            ([a, b, ..], [xa, xb, ..]) => (2, extend_side_by_side([a, b], [xa, xb], frames)),
            _ => (0, 0),
        };
        // The rest band by band: the bands side by side from their common length on, the
        // others (the third of a group of three, a band alone) from the start.
        for (j, (sum, active)) in group.iter_mut().zip(active).enumerate() {
            let done = if j < side_by_side { common } else { 0 };
            extend_sum(sum, &active[done..], frames - done);
        }
    }
}

/// The first frames (as many as every band of the group has, at most `frames`) of
/// [`extend_sum`] for `N` bands, advanced together; returns how many.
fn extend_side_by_side<const N: usize>(
    sums: [&mut Vec<f64>; N],
    actives: [&&[f64]; N],
    frames: usize,
) -> usize {
    let common = actives
        .iter()
        .map(|a| a.len())
        .min()
        .unwrap_or(0)
        .min(frames);
    let mut last: [f64; N] = std::array::from_fn(|j| sums[j][sums[j].len() - 1]);
    let mut outs = sums.map(|s| {
        let from = s.len();
        s.resize(from + common, 0.0);
        &mut s[from..]
    });
    let inputs = actives.map(|a| &a[..common]);
    // Frame by frame, every band's step; the running values stay in registers.
    for k in 0..common {
        for ((out, input), last) in outs.iter_mut().zip(&inputs).zip(&mut last) {
            *last += input[k];
            out[k] = *last;
        }
    }
    common
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Energies with what the scans must treat exactly: NaN (never raises the peak), a
    /// negative, zero, a late larger peak, a plateau at the peak.
    fn band(len: usize, seed: usize) -> Vec<f64> {
        (0..len)
            .map(|k| match (k * 7 + seed * 13) % 37 {
                0 => f64::NAN,
                1 => -1.0,
                2 => 0.0,
                _ => {
                    let late = if k == len * 2 / 3 && seed.is_multiple_of(3) {
                        50.0
                    } else {
                        1.0
                    };
                    late * (-(k as f64) * 0.01 * (1 + seed % 4) as f64).exp()
                        * (1.0 + 0.3 * ((k * 31 + seed) % 11) as f64)
                }
            })
            .collect()
    }

    #[test]
    fn low_frames_and_peaks_are_the_frame_by_frame_ones() {
        for seed in 0..40 {
            for len in [0, 1, 2, 7, 100, 333] {
                let e = band(len, seed);
                for peak in [0.0, 0.5, 1e3, f64::NAN] {
                    for factor in [0.0, 1e-3, 1e-10] {
                        let start: Vec<bool> = (0..len + 5).map(|k| k % 9 != 4).collect();
                        let mut fast = start.clone();
                        let got = mark_low(&mut fast, &e, peak, factor);
                        let mut slow = start.clone();
                        let mut p = peak;
                        for (low, &x) in slow.iter_mut().zip(&e) {
                            p = p.max(x);
                            *low &= x <= p * factor;
                        }
                        assert_eq!(fast, slow, "seed {seed} len {len} peak {peak} f {factor}");
                        assert_eq!(got.to_bits(), p.to_bits(), "seed {seed} len {len}");
                    }
                }
            }
        }
    }

    #[test]
    fn side_by_side_sums_are_each_band_alone() {
        for bands in 0..=9 {
            for seed in 0..6 {
                let actives: Vec<Vec<f64>> = (0..bands)
                    .map(|b| band((seed * 17 + b * 29) % 90, seed + b))
                    .collect();
                let slices: Vec<&[f64]> = actives.iter().map(|a| a.as_slice()).collect();
                for frames in [0, 5, 60, 100] {
                    // Sums that hold only their leading 0, or frames already.
                    for held in [vec![0.0], vec![0.0, 2.5, 3.0]] {
                        let mut fast = vec![held.clone(); bands];
                        extend_sums(&mut fast, &slices, frames);
                        for (b, a) in slices.iter().enumerate() {
                            let mut alone = held.clone();
                            extend_sum(&mut alone, a, frames);
                            let bits =
                                |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                            assert_eq!(bits(&fast[b]), bits(&alone), "{bands} bands, band {b}");
                        }
                    }
                }
            }
        }
    }
}

//! Lundeby's iterative noise-floor method (Lundeby et al., Acustica 81, 1995), as pyrato
//! implements it (`intersection_time_lundeby`, METHODS.md §2.2): where a decay sinks into the
//! noise (intersection time t_i), the noise energy N, and the late decay's reverberation time.
//! With them the Schroeder integral is truncated at t_i and the missing tail is added back as
//! C = N · T_late / (6 ln 10) (ISO 3382 practice).
//!
//! Works on any non-negative energy sequence at `rate_hz` values per second: squared samples of
//! an impulse response, or a front end's band energies per frame.

/// Lundeby's constants, with pyrato's defaults.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LundebySettings {
    /// Length of the first smoothing blocks, s (pyrato: 30 ms broadband, (800/f + 10) ms per band).
    pub initial_block_s: f64,
    /// Blocks per 10 dB of decay for the second smoothing (5).
    pub intervals_per_10db: f64,
    /// The regression stops this far above the noise, dB (10).
    pub db_above_noise: f64,
    /// Dynamic range used for the late regression, dB (20).
    pub dynamic_range_db: f64,
    /// End of the first regression: the *last* block above noise + 10 dB (pyrato, for smooth
    /// broadband energies) or the *first* block below it after the peak (robust for band energies
    /// at a frame rate, whose noise blocks fluctuate by ±10 dB).
    pub first_regression_end: FirstRegressionEnd,
}

/// Where Lundeby's first regression stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum FirstRegressionEnd {
    /// The last block above noise + `db_above_noise` (pyrato's rule).
    LastAbove,
    /// The first block after the peak below noise + `db_above_noise`.
    FirstBelow,
}

impl Default for LundebySettings {
    fn default() -> Self {
        LundebySettings {
            initial_block_s: 0.03,
            intervals_per_10db: 5.0,
            db_above_noise: 10.0,
            dynamic_range_db: 20.0,
            first_regression_end: FirstRegressionEnd::LastAbove,
        }
    }
}

/// What Lundeby's method found.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LundebyResult {
    /// Where the decay line meets the noise level, s from the start.
    pub intersection_time_s: f64,
    /// Reverberation time of the late decay (−60 / slope), s.
    pub late_t60_s: f64,
    /// Mean noise energy per value (same units as the input).
    pub noise_energy: f64,
}

/// Why the method found nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LundebyFailure {
    /// The decay does not rise far enough above the noise.
    #[error("decay too close to the noise floor for Lundeby's regression")]
    LowSnr,
    /// The late regression does not fall.
    #[error("late decay regression does not fall")]
    NoDecay,
    /// Too few values.
    #[error("too few values")]
    TooShort,
}

fn db(x: f64) -> f64 {
    10.0 * x.log10()
}

/// Block means of `data` with `block` values per block.
fn smooth(data: &[f64], block: usize) -> Vec<f64> {
    let n_blocks = data.len() / block;
    let mut means = block_sums(&data[..n_blocks * block], block);
    let divisor = super::CountDivisor::new(block);
    means.iter_mut().for_each(|m| *m = divisor.divide(*m));
    means
}

/// The centre time, s, of block `b` of `block` values at `rate_hz`. Computed for the blocks a
/// regression takes only: a division per block of the whole decay was a tenth of this method.
fn block_time_s(b: usize, block: usize, rate_hz: f64) -> f64 {
    (0.5 + b as f64) * block as f64 / rate_hz
}

/// The centre times of blocks `range`.
fn block_times_s(range: std::ops::Range<usize>, block: usize, rate_hz: f64) -> Vec<f64> {
    range.map(|b| block_time_s(b, block, rate_hz)).collect()
}

/// Blocks summed side by side in [`block_sums`]: independent additions in flight at once.
const SIDE_BY_SIDE: usize = 4;

/// The sum of each `block` consecutive values of `data` (whole blocks only), each added in
/// order from −0.0 exactly as `Iterator::sum` does (bit for bit, NaN payloads aside), but [`SIDE_BY_SIDE`] blocks at a time: one
/// block's additions wait on each other, and a block at a time waited on every one of them
/// (Lundeby's smoothing was a twentieth of an octave-bank run at 2 ms frames).
fn block_sums(data: &[f64], block: usize) -> Vec<f64> {
    if block == 0 {
        return Vec::new();
    }
    let n_blocks = data.len() / block;
    let mut sums = Vec::with_capacity(n_blocks);
    let whole = n_blocks / SIDE_BY_SIDE * SIDE_BY_SIDE;
    for group in data[..whole * block].chunks_exact(SIDE_BY_SIDE * block) {
        let (first, rest) = group.split_at(block);
        let (second, rest) = rest.split_at(block);
        let (third, fourth) = rest.split_at(block);
        let mut acc = [-0.0f64; SIDE_BY_SIDE];
        for (((a, b), c), d) in first.iter().zip(second).zip(third).zip(fourth) {
            acc[0] += a;
            acc[1] += b;
            acc[2] += c;
            acc[3] += d;
        }
        sums.extend_from_slice(&acc);
    }
    for b in whole..n_blocks {
        sums.push(data[b * block..(b + 1) * block].iter().sum::<f64>());
    }
    sums
}

/// Least squares `level = a + b t`, returns (a, b).
fn regress(times: &[f64], levels: &[f64]) -> Option<(f64, f64)> {
    let fit = super::regression::fit_line(times, levels)?;
    Some((fit.intercept_db, fit.slope_db_per_s))
}

/// The index of the first maximum of `v` (a NaN is replaced by the next value; 0 when empty):
/// the first of the non-NaN values equal to their maximum, or the last index when every value
/// is NaN. The maximum in vector lanes, then a search for it eight values at a time: the
/// one-value-at-a-time fold with its NaN test waited on each comparison (a third of this
/// method's time at 2 ms frames).
fn argmax(v: &[f64]) -> usize {
    const CHUNK: usize = 8;
    let m = super::max_ignoring_nan(v);
    // −∞ both when it is the maximum and when every value is NaN; then no value equals it.
    let mut at = 0;
    for chunk in v.chunks(CHUNK) {
        if chunk.iter().fold(false, |any, &x| any | (x == m)) {
            return at + chunk.iter().position(|&x| x == m).unwrap_or(0);
        }
        at += chunk.len();
    }
    v.len().saturating_sub(1)
}

/// Runs Lundeby's iteration on `energy` (values `1/rate_hz` s apart).
pub fn lundeby(
    energy: &[f64],
    rate_hz: f64,
    settings: &LundebySettings,
) -> Result<LundebyResult, LundebyFailure> {
    let n = energy.len();
    let block = ((settings.initial_block_s * rate_hz).round() as usize).max(1);
    let smoothed = smooth(energy, block);
    if smoothed.len() < 3 {
        return Err(LundebyFailure::TooShort);
    }
    // (2) initial noise: mean of the last 10 % of the raw energies.
    let tail = &energy[(n as f64 * 0.9) as usize..];
    let noise0 = tail.iter().sum::<f64>() / tail.len().max(1) as f64;
    // (3) first regression from the peak to the last block 10 dB above the noise.
    let start = argmax(&smoothed);
    let limit = db(noise0) + settings.db_above_noise;
    let inner = &smoothed[(start + 1).min(smoothed.len() - 1)..smoothed.len() - 1];
    let found = match settings.first_regression_end {
        FirstRegressionEnd::LastAbove => inner.iter().rposition(|&x| db(x) > limit),
        FirstRegressionEnd::FirstBelow => inner.iter().position(|&x| db(x) <= limit),
    };
    // pyrato's index arithmetic (one block before the found one), kept for agreement.
    let stop = found.ok_or(LundebyFailure::LowSnr)? + start;
    let dyn_range = db(smoothed[stop]) - db(smoothed[start]);
    if stop == start || dyn_range > -5.0 {
        return Err(LundebyFailure::LowSnr);
    }
    let levels: Vec<f64> = smoothed[start..stop].iter().map(|&x| db(x)).collect();
    let (mut a, mut b) = regress(&block_times_s(start..stop, block, rate_hz), &levels)
        .ok_or(LundebyFailure::LowSnr)?;
    if b == 0.0 || !b.is_finite() {
        return Err(LundebyFailure::NoDecay);
    }
    // (4) preliminary crossing point.
    let mut crossing = (db(noise0) - a) / b;
    // (5) new block length: `intervals_per_10db` blocks per 10 dB.
    let blocks_in_decay = dyn_range / -10.0 * settings.intervals_per_10db;
    let block2 = (((block_time_s(stop, block, rate_hz) - block_time_s(start, block, rate_hz))
        / blocks_in_decay
        * rate_hz)
        .round() as usize)
        .max(1);
    // (6) smooth again.
    let smoothed2 = smooth(energy, block2);
    if smoothed2.len() < 3 {
        return Err(LundebyFailure::TooShort);
    }
    let idx_max = argmax(&smoothed2);
    let t_block = block2 as f64 / rate_hz;
    let mut noise = noise0;
    // Where the last background level started: the same start gives the same level (often the
    // last 10 % in every iteration), and its in-order sum was a third of this method's time.
    let mut noise_from = None;
    for _ in 0..=30 {
        // (7) background level from 10 dB (of decay) after the crossing point, or the last 10 %.
        let idx_last10 = (smoothed2.len() as f64 * 0.9).round();
        let idx_10db = ((crossing - 10.0 / b) / t_block).round().max(1.0);
        let from = (idx_last10.min(idx_10db).max(0.0) as usize).min(smoothed2.len() - 1);
        if noise_from != Some(from) {
            let rest = &smoothed2[from..];
            noise = rest.iter().sum::<f64>() / rest.len() as f64;
            noise_from = Some(from);
        }
        // (8) late decay regression.
        let upper = db(noise) + settings.db_above_noise + settings.dynamic_range_db;
        let start_loop = smoothed2[idx_max..]
            .iter()
            .position(|&x| db(x) < upper)
            .map_or(0, |i| i + idx_max);
        let lower = db(noise) + settings.db_above_noise;
        let stop_loop = smoothed2[(start_loop + 1).min(smoothed2.len())..]
            .iter()
            .position(|&x| db(x) < lower)
            .ok_or(LundebyFailure::LowSnr)?
            + start_loop;
        if stop_loop < start_loop + 2 {
            // Too few blocks for a late regression (band energies at a low frame rate): keep
            // the previous line and crossing point.
            break;
        }
        let levels: Vec<f64> = smoothed2[start_loop..stop_loop]
            .iter()
            .map(|&x| db(x))
            .collect();
        (a, b) = regress(
            &block_times_s(start_loop..stop_loop, block2, rate_hz),
            &levels,
        )
        .ok_or(LundebyFailure::LowSnr)?;
        if b >= 0.0 {
            return Err(LundebyFailure::NoDecay);
        }
        // (9) new crossing point.
        let old = crossing;
        crossing = (db(noise) - a) / b;
        if (old - crossing).abs() < 0.01 {
            break;
        }
    }
    Ok(LundebyResult {
        intersection_time_s: crossing,
        late_t60_s: -60.0 / b,
        noise_energy: noise,
    })
}

/// The Lundeby-compensated Schroeder curve of `energy` into `out` (emptied first):
/// Σ_{k ≤ m < i} (e_m − n) + C for every frame k before the intersection index i (the curve
/// ends there), with C = N · T_late / (6 ln 10) · rate, and n = N when `subtract_noise`
/// (Chu + Lundeby, Guski & Vorländer 2014) else 0. Into a caller's vector, so that a decay's
/// curve can reuse memory.
pub fn compensated_curve_into(
    energy: &[f64],
    rate_hz: f64,
    found: &LundebyResult,
    subtract_noise: bool,
    out: &mut Vec<f64>,
) {
    let n = if subtract_noise {
        found.noise_energy
    } else {
        0.0
    };
    let i = ((found.intersection_time_s * rate_hz).round().max(0.0) as usize).min(energy.len());
    let tail = found.noise_energy * found.late_t60_s / (6.0 * std::f64::consts::LN_10) * rate_hz;
    out.clear();
    out.resize(i, 0.0);
    let mut acc = tail;
    for k in (0..i).rev() {
        acc += energy[k] - n;
        out[k] = acc;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn energy_that_peaks_at_the_end_is_an_error_not_a_panic() {
        // Found by the Schroeder proptest: the peak block was the last one.
        let e: Vec<f64> = (0..40).map(|k| (0.2 * k as f64).exp()).collect();
        for end in [
            FirstRegressionEnd::LastAbove,
            FirstRegressionEnd::FirstBelow,
        ] {
            let s = LundebySettings {
                initial_block_s: 0.1,
                first_regression_end: end,
                ..Default::default()
            };
            assert!(lundeby(&e, 10.0, &s).is_err());
        }
    }

    #[test]
    fn short_frame_rate_decay_into_noise() {
        let levels = [
            0.0, -7.0, -15.0, -22.0, -31.0, -40.0, -33.0, -43.0, -53.0, -45.0, -40.0, -42.0, -47.0,
            -35.0, -37.0, -39.0, -45.0, -40.0, -40.0, -44.0, -42.0, -39.0, -44.0, -36.0, -36.0,
            -41.0, -43.0, -46.0, -41.0, -44.0, -46.0, -44.0, -46.0, -37.0, -39.0, -37.0, -34.0,
            -42.0, -46.0, -43.0,
        ];
        let e: Vec<f64> = levels.iter().map(|l| 10f64.powf(l / 10.0)).collect();
        let s = LundebySettings {
            initial_block_s: 0.1,
            first_regression_end: FirstRegressionEnd::FirstBelow,
            ..Default::default()
        };
        let r = lundeby(&e, 10.0, &s);
        assert!(r.is_ok(), "{r:?}");
    }

    #[test]
    fn block_sums_are_iterator_sums_bit_for_bit() {
        // Signed zeros, NaN, infinities and values whose sum depends on the order. Any NaN
        // counts as one: which operand's NaN an addition passes on is the compiler's choice.
        let bits = |v: f64| {
            if v.is_nan() {
                f64::NAN.to_bits()
            } else {
                v.to_bits()
            }
        };
        let odd = [
            -0.0,
            0.0,
            f64::NAN,
            f64::INFINITY,
            1e300,
            -1e300,
            1e-300,
            0.1,
            3.0,
        ];
        let data: Vec<f64> = (0..203)
            .map(|k| odd[k % odd.len()] * if k % 5 == 0 { -1.0 } else { 1.0 })
            .chain((0..500).map(|k| 1.0 + (k as f64 * 0.37).sin() * 1e-9))
            .chain(std::iter::repeat_n(-0.0, 40))
            .collect();
        for block in [1, 2, 3, 4, 5, 7, 8, 16, 31, 100, 743, 744, 800] {
            let naive: Vec<u64> = data
                .chunks_exact(block)
                .map(|c| bits(c.iter().sum::<f64>()))
                .collect();
            let fast: Vec<u64> = block_sums(&data, block).iter().map(|&v| bits(v)).collect();
            assert_eq!(fast, naive, "block {block}");
        }
    }

    #[test]
    fn block_means_are_sums_over_the_block_length_bit_for_bit() {
        let data: Vec<f64> = (0..1000)
            .map(|k| (k as f64 * 0.37).sin().abs() * 10f64.powi(k % 40 - 320))
            .collect();
        for block in [1, 2, 3, 4, 5, 8, 16, 17, 64, 1000] {
            let naive: Vec<u64> = data
                .chunks_exact(block)
                .map(|c| (c.iter().sum::<f64>() / block as f64).to_bits())
                .collect();
            let means: Vec<u64> = smooth(&data, block).iter().map(|m| m.to_bits()).collect();
            assert_eq!(means, naive, "block {block}");
        }
    }

    #[test]
    fn argmax_is_the_first_maximum_past_leading_nans() {
        let nan = f64::NAN;
        assert_eq!(argmax(&[]), 0);
        assert_eq!(argmax(&[1.0, 3.0, 2.0, 3.0]), 1);
        assert_eq!(argmax(&[nan, nan, 2.0, 5.0, nan, 5.0]), 3);
        assert_eq!(argmax(&[4.0, nan, 9.0]), 2);
        assert_eq!(argmax(&[nan]), 0);
        assert_eq!(argmax(&[nan, f64::NEG_INFINITY, nan]), 1);
        assert_eq!(argmax(&[nan; 11]), 10);
        // Against the plain fold (the definition): NaN, ±∞, signed zeros and ties at every
        // position of 0–40 values.
        let fold = |v: &[f64]| {
            let (mut best, mut best_value) = (0, v.first().copied().unwrap_or(f64::NAN));
            for (i, &x) in v.iter().enumerate() {
                if x > best_value || best_value.is_nan() {
                    (best, best_value) = (i, x);
                }
            }
            best
        };
        let pool = [
            nan,
            0.0,
            -0.0,
            1.0,
            -1.0,
            2.5,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        for n in 0..=40 {
            for _ in 0..200 {
                let v: Vec<f64> = (0..n)
                    .map(|_| {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        pool[(state % pool.len() as u64) as usize]
                    })
                    .collect();
                assert_eq!(argmax(&v), fold(&v), "{v:?}");
            }
        }
    }
}

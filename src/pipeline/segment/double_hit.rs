//! Double hits: a hammer that bounces strikes a second time a few ms to a few tens of ms after
//! the first impact. The second impact lies inside the onset search's lookahead, so it is not a
//! new decay; its decay is folded into the first one. This module says whether a decay's first
//! samples hold one, so that its rows can be flagged `double_hit`.
//!
//! Why not the envelope: the envelope of an ordinary ringing decay rises and falls by tens of dB
//! on its own (two close modes beat to exact nulls; a dozen modes with random phases fade and
//! swell like narrow-band noise), and a bounce on top of the first impact's ringing rises by a
//! few dB at most. Measured on synthetic hits, no envelope threshold separates the two.
//!
//! What separates them: a free decay is predictable, an impact is not. The ringing of a linear
//! structure is a sum of damped sines, which a linear predictor of `2 × modes` taps continues
//! exactly; what it cannot predict (its residual) is the excitation: a burst at each impact,
//! noise in between. So [`second_impact`] fits a predictor of [`DOUBLE_HIT_ORDER`] taps by least
//! squares to the decay's first [`DOUBLE_HIT_WINDOW_S`] (robustly: samples the fit cannot
//! predict are dropped and the fit repeated, so a second impact does not bend it), and looks
//! at its residual: the first impact's burst, then — for a double hit — a quiet stretch
//! ([`DOUBLE_HIT_QUIET_DB`] below the first burst) followed by a second burst that comes within
//! [`DOUBLE_HIT_LEVEL_DB`] of the first and stands [`DOUBLE_HIT_FLOOR_DB`] above the residual's
//! robust spread.
//!
//! Limits: the first burst lasts about [`DOUBLE_HIT_ORDER`] samples, so a bounce must come later
//! than that (4 ms at 4096 Hz, 0.3 ms at 48 kHz) to be seen apart. A structure with more than
//! eight strong modes per 16 taps leaves a residual floor where the predictor misses them; at a
//! low sample rate with many modes this floor can hide a bounce (it then goes unflagged, not
//! the other way round). Measured (`regression_double_hits`): single modes, beating pairs and
//! hits of 3–12 modes with random phases at 4096 and 8192 Hz stay ≥ 22 dB below the first burst
//! and ≤ 13 dB above the floor; rebounds of 0.3 and 0.5 after 5–20 ms read −10.5 and −6.1 dB,
//! 34–42 dB above the floor. A prototype of the same test flagged no single hit of up to 60
//! modes at 4096–48 000 Hz with noise 20–60 dB down.
//!
//! Memory: the decay's first samples are the onset buffer already held; the fit adds a
//! [`DOUBLE_HIT_ORDER`]² matrix and the residual of the window.

use nalgebra::{SMatrix, SVector};

/// Taps of the linear predictor: it continues up to eight damped sines exactly (two taps each).
/// More taps describe more modes but lengthen the first impact's residual burst (about one
/// sample per tap), inside which a bounce cannot be told apart.
pub const DOUBLE_HIT_ORDER: usize = 16;

/// How long after the onset a second impact is looked for, s. A hammer's rebound lands within
/// a few ms to a few tens of ms of its first contact; later second hits rise clear of the decay
/// and are split off as new decays by the new-hit watch.
pub const DOUBLE_HIT_WINDOW_S: f64 = 0.05;

/// A second impact counts when its excitation burst comes within this many dB of the first's:
/// a rebound of a tenth of the hit. Smaller rebounds change each mode's amplitude by less than
/// 10 % (1 dB) and are harmless even to an FRF.
pub const DOUBLE_HIT_LEVEL_DB: f64 = 20.0;

/// The first impact is over once the residual has fallen this many dB below its burst: 6 dB
/// under [`DOUBLE_HIT_LEVEL_DB`], so that the tail of one long (soft-tipped) contact is not
/// taken for two.
pub const DOUBLE_HIT_QUIET_DB: f64 = 26.0;

/// A second burst must stand this many dB above the residual's robust spread (1.4826 × its
/// median magnitude, σ for Gaussian noise): 8 σ, which white noise reaches once in 10¹⁵
/// samples, and above what a predictor that misses a few weak modes leaves (≤ 13 dB measured
/// on single hits, see the module note).
pub const DOUBLE_HIT_FLOOR_DB: f64 = 18.0;

/// Samples before the onset the check wants (the first impact's burst starts there when the
/// hit rises from below the onset level): two predictor lengths.
pub const DOUBLE_HIT_HISTORY_SAMPLES: usize = 2 * DOUBLE_HIT_ORDER;

/// Fewest predicted samples (beyond the first burst) for a fit: four per tap.
const MIN_FIT_SAMPLES: usize = 4 * DOUBLE_HIT_ORDER;

/// Residual samples per block of the burst search: a quarter of the predictor, so that a burst
/// (about one predictor long) fills whole blocks and single low samples inside it do not count
/// as quiet.
const BLOCK_SAMPLES: usize = DOUBLE_HIT_ORDER / 4;

/// Fit, drop what it cannot predict, fit again: this many fits.
const ROBUST_FITS: usize = 3;

/// Samples further than this many robust σ from the prediction are left out of the next fit.
const OUTLIER_SIGMA: f64 = 5.0;

/// Ridge added to the normal equations, relative to their mean diagonal: keeps the fit
/// defined for over-sampled signals (taps nearly collinear) without changing a well-posed one.
const RIDGE: f64 = 1e-9;

/// σ of Gaussian noise per median absolute value.
const MAD_TO_SIGMA: f64 = 1.4826;

/// The strongest excitation (residual) after the first impact's burst went quiet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SecondImpact {
    /// Its level relative to the first impact's burst, dB (≤ 0 for a weaker rebound).
    pub level_db: f64,
    /// Its level above the residual's robust spread, dB.
    pub above_floor_db: f64,
    /// When it came, s after the onset.
    pub at_s: f64,
}

impl SecondImpact {
    /// True when it counts as a second impact: within [`DOUBLE_HIT_LEVEL_DB`] of the first and
    /// [`DOUBLE_HIT_FLOOR_DB`] above the residual floor.
    pub fn is_double_hit(&self) -> bool {
        self.level_db >= -DOUBLE_HIT_LEVEL_DB && self.above_floor_db >= DOUBLE_HIT_FLOOR_DB
    }
}

/// Whether the decay starting at `first` (its samples from the onset on; `pre_roll` the samples
/// before it, oldest first, fewer at the start of a stream) holds a second impact within
/// [`DOUBLE_HIT_WINDOW_S`]. See the module documentation for the test and its limits.
pub fn is_double_hit(pre_roll: &[f64], first: &[f64], sample_rate_hz: f64) -> bool {
    second_impact(pre_roll, first, sample_rate_hz).is_some_and(|s| s.is_double_hit())
}

/// The strongest residual block from where the first impact's burst has gone quiet on, whether
/// or not it counts ([`SecondImpact::is_double_hit`]); `None` when the residual never went
/// quiet (no second impact can be told apart), or the window is too short for a fit, or
/// silent, or not finite.
pub fn second_impact(pre_roll: &[f64], first: &[f64], sample_rate_hz: f64) -> Option<SecondImpact> {
    let p = DOUBLE_HIT_ORDER;
    let history = DOUBLE_HIT_HISTORY_SAMPLES;
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return None;
    }
    let window = ((DOUBLE_HIT_WINDOW_S * sample_rate_hz).round() as usize).min(first.len());
    // z: zeros where the stream had no history, the pre-roll's tail, the window.
    let given = pre_roll.len().min(history);
    let mut z = vec![0.0; history - given];
    z.extend_from_slice(&pre_roll[pre_roll.len() - given..]);
    z.extend_from_slice(&first[..window]);
    if z.iter().any(|x| !x.is_finite()) {
        return None;
    }
    // Rows of the fit: samples whose taps all lie after the onset.
    let fit_from = history + p;
    if z.len() < fit_from + MIN_FIT_SAMPLES {
        return None;
    }
    let all = NormalEquations::over(&z, fit_from);
    let mut kept = all.clone();
    let mut residual = Vec::new();
    let mut sigma = 0.0;
    let mut dropped = Vec::new();
    for fit in 0..ROBUST_FITS {
        let coef = kept.solve()?;
        residual = predict_residual(&z, &coef);
        sigma = robust_sigma(&residual[fit_from - p..]);
        if sigma <= 0.0 || fit + 1 == ROBUST_FITS {
            break;
        }
        let outliers: Vec<usize> = (fit_from..z.len())
            .filter(|&t| residual[t - p].abs() > OUTLIER_SIGMA * sigma)
            .collect();
        // The same rows as the last fit's would give the same fit again.
        if outliers == dropped || z.len() - fit_from - outliers.len() < MIN_FIT_SAMPLES {
            break;
        }
        kept = all.without(&z, &outliers);
        dropped = outliers;
    }
    // residual[i] belongs to z[i + p]. The first impact: every sample up to one predictor length
    // after the onset.
    let first_burst = residual[..history]
        .iter()
        .fold(0.0f64, |m, e| m.max(e.abs()));
    if first_burst <= 0.0 {
        return None;
    }
    let quiet = first_burst * db_to_amplitude(-DOUBLE_HIT_QUIET_DB);
    let mut quiet_seen = false;
    let mut best: Option<(f64, usize)> = None;
    for (b, block) in residual[history..].chunks(BLOCK_SAMPLES).enumerate() {
        let m = block.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        quiet_seen |= m < quiet;
        if quiet_seen && best.is_none_or(|(v, _)| m > v) {
            best = Some((m, b * BLOCK_SAMPLES));
        }
    }
    let (m, offset) = best?;
    Some(SecondImpact {
        level_db: 20.0 * (m / first_burst).log10(),
        above_floor_db: if sigma > 0.0 {
            20.0 * (m / sigma).log10()
        } else {
            f64::INFINITY
        },
        // z index history + p + offset is the block's first sample; the onset is z[history].
        at_s: (p + offset) as f64 / sample_rate_hz,
    })
}

fn db_to_amplitude(db: f64) -> f64 {
    10f64.powf(db / 20.0)
}

/// The predictor's coefficients: z[t] ≈ Σ c_i z[t − 1 − i].
type Coefficients = SVector<f64, DOUBLE_HIT_ORDER>;

/// The least-squares normal equations of the predictor of z[t] from x = (z[t−1], …, z[t−p]):
/// Σ x xᵀ and Σ x z[t] over a set of rows t.
#[derive(Clone, Debug)]
struct NormalEquations {
    a: SMatrix<f64, DOUBLE_HIT_ORDER, DOUBLE_HIT_ORDER>,
    b: Coefficients,
}

impl NormalEquations {
    /// Over every row t = `from` … len − 1 (`from` ≥ p + 1). Σ x xᵀ is a sliding sum: its
    /// first column takes p dot products, every other entry follows from the one up and left
    /// of it (the same sum shifted by a sample: one product in, one out), so the cost is
    /// p dot products rather than p² per row.
    fn over(z: &[f64], from: usize) -> Self {
        const P: usize = DOUBLE_HIT_ORDER;
        let end = z.len();
        // The first column and the right-hand side in one pass over the rows, all 2P sums side
        // by side (lanes over the taps; one serial sum per entry was a tenth of a short run).
        // taps[k] = z[t − P + k], so tap i (z[t − 1 − i]) is taps[P − 1 − i].
        let (mut first_col, mut rhs) = ([0.0f64; P], [0.0f64; P]);
        for t in from..end {
            let taps: &[f64; P] = z[t - P..t].try_into().expect("P taps");
            let (newest, target) = (z[t - 1], z[t]);
            for k in 0..P {
                first_col[k] += taps[k] * newest;
                rhs[k] += taps[k] * target;
            }
        }
        let mut a = SMatrix::<f64, P, P>::zeros();
        for i in 0..P {
            a[(i, 0)] = first_col[P - 1 - i];
        }
        for j in 1..P {
            for i in j..P {
                a[(i, j)] = a[(i - 1, j - 1)] + z[from - 1 - i] * z[from - 1 - j]
                    - z[end - 1 - i] * z[end - 1 - j];
            }
        }
        for j in 1..P {
            for i in 0..j {
                a[(i, j)] = a[(j, i)];
            }
        }
        let b = Coefficients::from_fn(|i, _| rhs[P - 1 - i]);
        NormalEquations { a, b }
    }

    /// These equations without `rows` (each among those they were summed over).
    fn without(&self, z: &[f64], rows: &[usize]) -> Self {
        let mut out = self.clone();
        for &t in rows {
            let x = Coefficients::from_fn(|i, _| z[t - 1 - i]);
            out.a -= x * x.transpose();
            out.b -= x * z[t];
        }
        out
    }

    /// The coefficients, with a ridge of [`RIDGE`] × the mean diagonal; `None` when the rows
    /// carry no energy.
    fn solve(&self) -> Option<Coefficients> {
        let trace = self.a.trace();
        if !(trace.is_finite() && trace > 0.0) {
            return None;
        }
        let mut a = self.a;
        for i in 0..DOUBLE_HIT_ORDER {
            a[(i, i)] += RIDGE * trace / DOUBLE_HIT_ORDER as f64;
        }
        a.cholesky().map(|c| c.solve(&self.b))
    }
}

/// z[t] minus its prediction, for t = p … len − 1 (the samples before the first have no taps).
fn predict_residual(z: &[f64], coef: &Coefficients) -> Vec<f64> {
    let p = DOUBLE_HIT_ORDER;
    if z.len() <= p {
        return Vec::new();
    }
    // One pass per tap over all samples (lanes over t), rather than one serial sum per sample.
    let mut residual = z[p..].to_vec();
    let n = residual.len();
    for i in 0..p {
        let c = coef[i];
        for (r, &x) in residual.iter_mut().zip(&z[p - 1 - i..p - 1 - i + n]) {
            *r -= c * x;
        }
    }
    residual
}

/// 1.4826 × the median magnitude: σ of Gaussian noise, unmoved by a few bursts.
fn robust_sigma(e: &[f64]) -> f64 {
    if e.is_empty() {
        return 0.0;
    }
    let mut m: Vec<f64> = e.iter().map(|x| x.abs()).collect();
    let mid = m.len() / 2;
    let (_, median, _) = m.select_nth_unstable_by(mid, f64::total_cmp);
    MAD_TO_SIGMA * *median
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Damped sines (f_hz, amplitude), D = 1 %, from the onset on.
    fn ringing(modes: &[(f64, f64)], fs: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                modes
                    .iter()
                    .map(|&(f, a)| {
                        a * (-0.01 * std::f64::consts::TAU * f * t).exp()
                            * (std::f64::consts::TAU * f * t).sin()
                    })
                    .sum()
            })
            .collect()
    }

    #[test]
    fn the_residual_of_a_free_decay_is_quiet_and_a_second_impact_stands_out() {
        let fs = 8192.0;
        let modes = [(210.0, 1.0), (530.0, 0.7), (1210.0, 0.5)];
        let hit = ringing(&modes, fs, 2000);
        // Without a rebound the residual goes quiet and stays there (no float noise: the
        // predictor continues three modes to ~1e-9 of the burst).
        let alone = second_impact(&[], &hit, fs);
        assert!(
            alone.is_none_or(|s| !s.is_double_hit() && s.level_db < -60.0),
            "{alone:?}"
        );
        // A rebound of 0.3 after 10 ms: a burst at −10.5 dB, 10 ms after the onset.
        let k = (0.010 * fs) as usize;
        let mut twice = hit.clone();
        for (i, v) in hit.iter().take(hit.len() - k).enumerate() {
            twice[k + i] += 0.3 * v;
        }
        let s = second_impact(&[], &twice, fs).expect("a burst");
        assert!(s.is_double_hit(), "{s:?}");
        assert!((s.level_db + 10.5).abs() < 1.5, "{s:?}");
        assert!((s.at_s - 0.010).abs() < 1.5e-3, "{s:?}");
    }

    #[test]
    fn too_short_silent_or_broken_windows_give_nothing() {
        assert_eq!(second_impact(&[], &[], 8192.0), None);
        assert_eq!(second_impact(&[], &[1.0; 20], 8192.0), None);
        assert_eq!(second_impact(&[], &[0.0; 4000], 8192.0), None);
        let mut x = ringing(&[(300.0, 1.0)], 8192.0, 4000);
        x[100] = f64::NAN;
        assert_eq!(second_impact(&[], &x, 8192.0), None);
        assert_eq!(second_impact(&[], &x[..1000], f64::NAN), None);
    }

    /// The normal equations and the residual, summed in lanes, against their definitions
    /// (Σ x xᵀ and Σ x z[t] over the rows, z[t] − Σ c_i z[t − 1 − i]) on a noisy ringing.
    #[test]
    fn lane_sums_equal_the_definitions() {
        const P: usize = DOUBLE_HIT_ORDER;
        let mut z = ringing(&[(440.0, 1.0), (1250.0, 0.4), (3100.0, 0.2)], 48000.0, 700);
        for (i, v) in z.iter_mut().enumerate() {
            *v += 1e-3 * ((i * 7919 % 1013) as f64 / 1013.0 - 0.5);
        }
        let from = 2 * P + P;
        let eq = NormalEquations::over(&z, from);
        let scale = z.iter().map(|v| v * v).sum::<f64>();
        for i in 0..P {
            for j in 0..P {
                let want: f64 = (from..z.len()).map(|t| z[t - 1 - i] * z[t - 1 - j]).sum();
                assert!((eq.a[(i, j)] - want).abs() <= 1e-12 * scale, "a[{i},{j}]");
            }
            let want: f64 = (from..z.len()).map(|t| z[t - 1 - i] * z[t]).sum();
            assert!((eq.b[i] - want).abs() <= 1e-12 * scale, "b[{i}]");
        }
        let coef = eq.solve().unwrap();
        let residual = predict_residual(&z, &coef);
        assert_eq!(residual.len(), z.len() - P);
        for t in P..z.len() {
            let predicted: f64 = (0..P).map(|i| coef[i] * z[t - 1 - i]).sum();
            let want = z[t] - predicted;
            assert!(
                (residual[t - P] - want).abs() <= 1e-12,
                "t {t}: {} vs {want}",
                residual[t - P]
            );
        }
    }
}

//! Whether an update fits the measured modes worse than the model as given: the last check
//! before a finding is returned (a BIC can prefer a change whose re-solved model fits worse).

use super::evidence::Evidence;
use super::fit::residual_rms_hz;

/// Most of the modes paired before that an update may leave unpaired (a mass that mixes a close
/// pair as the structure does may lose one of them; a quarter lost are no longer the same modes).
pub const MAX_LOST_PAIRS_FRACTION: f64 = 0.25;

/// Relative growth of the calibrated frequency RMS beyond which an update fits worse
/// ([`fits_worse`]), unless its damping RMS fell by as much.
pub const WORSE_FIT_RATIO: f64 = 1.1;

/// Whether the model behind `after` fits the measured modes worse than the one behind `before`:
/// its frequency RMS with the model-form nuisance fitted away (offset, trends in f and f², and
/// `before`'s model's discretisation `pattern` per model mode, as the scorer profiles it) grew
/// by more than [`WORSE_FIT_RATIO`], and its damping RMS did not fall by as much. Both are taken
/// over the measured modes paired in both: an update that mixes a close pair of modes as the
/// structure does pairs them anew, and the RMS of a larger set is no measure of fit (found on
/// a point mass beside a close triple of a small plate: the triple paired only after the
/// update, and the mass was rejected).
///
/// An update that leaves more than [`MAX_LOST_PAIRS_FRACTION`] of the modes paired before
/// unpaired fits worse whatever the rest says: its modes no longer match the structure's
/// (found: a second finding, a region +75 % stiff over three quarters of a small plate, left no
/// mode paired, and a comparison over no modes could not say worse).
pub fn fits_worse(before: &Evidence, after: &Evidence, patterns: &[Vec<f64>]) -> bool {
    let common: Vec<_> = before
        .pairs
        .iter()
        .filter_map(|b| {
            let a = after.pairs.iter().find(|a| a.measured == b.measured)?;
            Some((b, a))
        })
        .collect();
    let lost = before.pairs.len() - common.len();
    if lost as f64 > MAX_LOST_PAIRS_FRACTION * before.pairs.len() as f64 {
        return true;
    }
    let f_hz: Vec<f64> = common
        .iter()
        .map(|(b, _)| before.model[b.model].damped_frequency_hz)
        .collect();
    let patterns: Vec<Vec<f64>> = patterns
        .iter()
        .filter(|pattern| common.iter().all(|(b, _)| b.model < pattern.len()))
        .map(|pattern| common.iter().map(|(b, _)| pattern[b.model]).collect())
        .collect();
    let rms = |y: Vec<f64>| residual_rms_hz(&f_hz, &y, &patterns);
    let frequency_before = rms(common
        .iter()
        .map(|(b, _)| b.frequency_rel.ln_1p())
        .collect());
    let frequency_after = rms(common
        .iter()
        .map(|(_, a)| a.frequency_rel.ln_1p())
        .collect());
    let damping_rms = |d: &mut dyn Iterator<Item = f64>| {
        (d.map(|x| x * x).sum::<f64>() / common.len().max(1) as f64).sqrt()
    };
    let damping_before = damping_rms(&mut common.iter().map(|(b, _)| b.damping_diff));
    let damping_after = damping_rms(&mut common.iter().map(|(_, a)| a.damping_diff));
    let frequency_worse = frequency_after > WORSE_FIT_RATIO * frequency_before + 1e-9;
    let damping_better = damping_after * WORSE_FIT_RATIO < damping_before;
    frequency_worse && !damping_better
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::evidence::{ModePair, ModelPole};

    fn pole(f_hz: f64) -> ModelPole {
        ModelPole {
            mode: 0,
            frequency_hz: f_hz,
            damped_frequency_hz: f_hz,
            damping_ratio: 0.0,
            shape: Vec::new(),
        }
    }

    /// Evidence pairing measured mode k with model mode k at ln f ratio `y[k]` (`None`: unpaired).
    fn evidence(f_hz: &[f64], y: &[Option<f64>]) -> Evidence {
        Evidence {
            model: f_hz.iter().map(|&f| pole(f)).collect(),
            pairs: y
                .iter()
                .enumerate()
                .filter_map(|(k, y)| {
                    Some(ModePair {
                        measured: k,
                        model: k,
                        mac: 1.0,
                        frequency_rel: (*y)?.exp_m1(),
                        damping_diff: 0.0,
                        damping_std: 1e-4,
                    })
                })
                .collect(),
            unpaired_measured: Vec::new(),
            unpaired_model: Vec::new(),
            calibration: None,
        }
    }

    /// An update that fixes the modes paired before but pairs one more mode far off is not
    /// worse (it was, by the RMS over all pairs); one that spoils the common modes is.
    #[test]
    fn only_the_modes_paired_before_and_after_are_compared() {
        let f = [20.0, 46.0, 85.0, 119.0, 144.0, 193.0, 226.0, 336.0];
        let bumpy = [0.0, 0.004, -0.003, 0.005, -0.004, 0.003, -0.005, 0.0];
        let before: Vec<Option<f64>> = bumpy[..7].iter().map(|&b| Some(b)).chain([None]).collect();
        let fixed: Vec<Option<f64>> = (0..7).map(|_| Some(0.0)).chain([Some(0.05)]).collect();
        assert!(!fits_worse(
            &evidence(&f, &before),
            &evidence(&f, &fixed),
            &[]
        ));
        let spoiled: Vec<Option<f64>> = bumpy[..7]
            .iter()
            .map(|&b| Some(3.0 * b))
            .chain([None])
            .collect();
        assert!(fits_worse(
            &evidence(&f, &before),
            &evidence(&f, &spoiled),
            &[]
        ));
        let lost: Vec<Option<f64>> = (0..8).map(|k| (k < 4).then_some(0.0)).collect();
        assert!(fits_worse(
            &evidence(&f, &before),
            &evidence(&f, &lost),
            &[]
        ));
        assert!(fits_worse(
            &evidence(&f, &before),
            &evidence(&f, &[None; 8]),
            &[]
        ));
    }

    /// The discretisation pattern is profiled as the scorer profiles it: a mismatch that is the
    /// pattern alone does not make an update worse.
    #[test]
    fn the_pattern_is_profiled() {
        let f = [20.0, 46.0, 85.0, 119.0, 144.0, 193.0, 226.0];
        let pattern = [0.002, 0.006, 0.007, 0.013, 0.006, 0.014, 0.015];
        let before: Vec<Option<f64>> = (0..7).map(|_| Some(0.0)).collect();
        let after: Vec<Option<f64>> = pattern.iter().map(|&p| Some(-2.0 * p)).collect();
        assert!(!fits_worse(
            &evidence(&f, &before),
            &evidence(&f, &after),
            &[pattern.to_vec()]
        ));
        assert!(fits_worse(
            &evidence(&f, &before),
            &evidence(&f, &after),
            &[]
        ));
    }
}

//! Flat gains ([`super::FrontEnd::flat_gain`]) computed once per process: every channel of a
//! run asks for the same few (same bands, same ranges), and each is a 33-point integral of the
//! band's response; the STFT's 66 band sums were a third of a short run's time, the banks'
//! biquad responses a twentieth of a tiny octave run.

/// What a flat gain depends on, as bits: a tag of the front end's kind, then every number its
/// band response and the range depend on (the same inputs give the same number).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(crate) struct FlatGainKey(pub(crate) Vec<u64>);

/// Tags of [`FlatGainKey`]s (keys of different front ends never meet).
pub(crate) const STFT_TAG: u64 = 1;
/// See [`STFT_TAG`].
pub(crate) const OCTAVE_TAG: u64 = 2;
/// See [`STFT_TAG`].
pub(crate) const GOYDER_TAG: u64 = 3;

/// See [`STFT_TAG`]: a cascade's white-noise energy ([`impulse_energy`]).
pub(crate) const IMPULSE_ENERGY_TAG: u64 = 4;

/// [`super::cascade_impulse_energy`] of `sections`, once per process (every channel's bank has
/// the same bands; a narrow band's response runs for tens of thousands of samples).
pub(crate) fn impulse_energy(sections: &[[f64; 5]]) -> f64 {
    let mut key = vec![IMPULSE_ENERGY_TAG];
    key.extend(sections.iter().flatten().map(|c| c.to_bits()));
    memoized_flat_gain(FlatGainKey(key), || super::cascade_impulse_energy(sections))
}

/// Flat gains kept at most (a run asks for a few per pair of bands; beyond, computed anew).
const FLAT_GAIN_MEMO_ENTRIES: usize = 1 << 16;

/// The flat gain of `key`, computed by `compute` the first time in the process.
pub(crate) fn memoized_flat_gain(key: FlatGainKey, compute: impl FnOnce() -> f64) -> f64 {
    type Memo = std::sync::Mutex<std::collections::HashMap<FlatGainKey, f64>>;
    static MEMO: std::sync::OnceLock<Memo> = std::sync::OnceLock::new();
    let memo = MEMO.get_or_init(Default::default);
    if let Some(g) = memo.lock().ok().and_then(|m| m.get(&key).copied()) {
        return g;
    }
    // Computed outside the lock: two threads may both compute it, to the same value.
    let g = compute();
    if let Ok(mut m) = memo.lock() {
        if m.len() < FLAT_GAIN_MEMO_ENTRIES {
            m.insert(key, g);
        }
    }
    g
}

/// A biquad bank's flat gain over `range_hz`, memoized: Simpson's mean of `stationary_gain`
/// (the band's [`super::FrontEnd::mode_gain`] at σ = 0), keyed by the tag, the sample rate,
/// the direction, the range, `extra` numbers and every coefficient of the band's sections.
pub(crate) fn bank_flat_gain(
    tag: u64,
    sample_rate_hz: f64,
    reversed: bool,
    range_hz: (f64, f64),
    extra: &[f64],
    sections: &[[f64; 5]],
    stationary_gain: impl Fn(f64) -> f64,
) -> f64 {
    let mut key = vec![
        tag,
        sample_rate_hz.to_bits(),
        u64::from(reversed),
        range_hz.0.to_bits(),
        range_hz.1.to_bits(),
    ];
    key.extend(extra.iter().map(|x| x.to_bits()));
    key.extend(sections.iter().flatten().map(|c| c.to_bits()));
    memoized_flat_gain(FlatGainKey(key), || {
        super::simpson_flat_gain(stationary_gain, range_hz.0, range_hz.1)
    })
}

#[cfg(test)]
mod tests {
    use crate::frontend::goyder::{GoyderFrontEnd, GoyderSettings};
    use crate::frontend::octave_bank::{OctaveBankFrontEnd, OctaveBankSettings};
    use crate::frontend::{simpson_flat_gain, Band, FilterDirection, FrontEnd};

    /// Each front end's flat gain, asked twice (the second time from the memo), is the integral
    /// of its own band's response, for banks that differ only in the filter order, so that a
    /// key missing it would hand one bank another's number.
    #[test]
    fn memoized_flat_gains_are_each_banks_own() {
        let fs = 4096.0;
        let bands = [
            Band::new(44.67, 89.13).unwrap(),
            Band::new(89.13, 177.8).unwrap(),
        ];
        let mut banks: Vec<Box<dyn FrontEnd>> = Vec::new();
        for direction in [FilterDirection::Reversed, FilterDirection::Forward] {
            for order in [2, 3] {
                let s = OctaveBankSettings {
                    order,
                    direction,
                    ..Default::default()
                };
                banks.push(Box::new(OctaveBankFrontEnd::new(s, fs, &bands).unwrap()));
            }
            for order in [2, 4] {
                let s = GoyderSettings {
                    order,
                    direction,
                    ..Default::default()
                };
                banks.push(Box::new(GoyderFrontEnd::new(s, fs, &bands).unwrap()));
            }
        }
        let ranges = [(30.0, 120.0), (60.0, 70.0), (80.0, 200.0)];
        let mut values = Vec::new();
        for _ in 0..2 {
            for bank in &banks {
                for band in 0..2 {
                    for &(lo, hi) in &ranges {
                        let want = simpson_flat_gain(|f| bank.mode_gain(band, f, 0.0), lo, hi);
                        let got = bank.flat_gain(band, lo, hi);
                        assert_eq!(got.to_bits(), want.to_bits(), "{} band {band}", bank.name());
                        values.push(got);
                    }
                }
            }
        }
        // The orders and kinds really differ (else the test could not tell one bank from
        // another); the direction does not change a stationary gain.
        let first = &values[..values.len() / 2];
        let per_bank = 2 * ranges.len();
        let distinct = first
            .chunks(per_bank)
            .map(|c| c.iter().map(|v| v.to_bits()).collect::<Vec<_>>())
            .collect::<std::collections::HashSet<_>>();
        assert_eq!(distinct.len(), banks.len() / 2);
    }
}

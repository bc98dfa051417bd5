//! Per-decay results combined with their spread: a hit stream gives many decays per channel and
//! band, and one number per decay says little until the decays are put together.
//!
//! [`Spread`] gathers result rows (from a running analysis, [`Spread::add_row`], or from a
//! results table written by `analyze`, [`summarize_table`]) and gives, per channel × band, one
//! [`SpreadRow`]: how many decays, how many have a damping ratio and why the others have none,
//! the median, quartiles, IQR and extremes of D and T60 over the decays that have one, and how
//! many decays carry a flag. Missing numbers are counted by reason, never filled in.
//!
//! Quantiles are Hyndman and Fan's type 7 (R's default, NumPy's `linear`) over the sorted
//! values x₀ ≤ … ≤ x_(n−1): q(p) = x_⌊h⌋ + (h − ⌊h⌋)(x_(⌊h⌋+1) − x_⌊h⌋) with h = (n − 1)p. The
//! median (p = ½) is the middle value, or the mean of the two middle ones; the quartiles are
//! p = ¼ and ¾; one value is its own median and quartiles.
//!
//! Memory: two numbers (D, T60) per decay and band that has them; counters per channel × band.

use std::collections::{BTreeMap, HashMap};
use std::io::Read;

use crate::decay::Flag;
use crate::frontend::Band;
use crate::pipeline::ResultRow;
use crate::source::SourceError;
use crate::{Error, Result};

/// The quantile at `p` (0 ≤ p ≤ 1) of `sorted` (ascending, finite), Hyndman and Fan's type 7:
/// with h = (n − 1)p, x_⌊h⌋ + (h − ⌊h⌋)(x_(⌊h⌋+1) − x_⌊h⌋) — the straight line through the
/// sorted values placed at k/(n − 1). p = ½ gives the middle value or the mean of the two middle
/// ones. `None` for no values or a `p` outside [0, 1].
pub fn quantile(sorted: &[f64], p: f64) -> Option<f64> {
    if sorted.is_empty() || !(0.0..=1.0).contains(&p) {
        return None;
    }
    let h = (sorted.len() - 1) as f64 * p;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(sorted.len() - 1);
    Some(sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo]))
}

/// The spread of one channel × band over its decays. Damping ratios are fractions.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SpreadRow {
    /// Channel (sensor id).
    pub channel: String,
    /// Band lower edge, Hz.
    pub f_lo_hz: f64,
    /// Band upper edge, Hz.
    pub f_hi_hz: f64,
    /// Band centre, Hz.
    pub f_center_hz: f64,
    /// Result rows of this channel and band: its decays (and a row without a decay when the
    /// channel had none or stopped).
    pub n_decays: usize,
    /// Of those, decays with a damping ratio.
    pub n_estimated: usize,
    /// The others, by reason ([`Flag::missing_reason`]): `reason:count;…`, sorted by reason.
    pub missing: String,
    /// Smallest damping ratio.
    pub d_min: Option<f64>,
    /// Lower quartile of the damping ratios.
    pub d_q1: Option<f64>,
    /// Median damping ratio.
    pub d_median: Option<f64>,
    /// Upper quartile of the damping ratios.
    pub d_q3: Option<f64>,
    /// Largest damping ratio.
    pub d_max: Option<f64>,
    /// Interquartile range of the damping ratios, `d_q3 − d_q1`.
    pub d_iqr: Option<f64>,
    /// Shortest T60, s.
    pub t60_min_s: Option<f64>,
    /// Lower quartile of T60, s.
    pub t60_q1_s: Option<f64>,
    /// Median T60, s.
    pub t60_median_s: Option<f64>,
    /// Upper quartile of T60, s.
    pub t60_q3_s: Option<f64>,
    /// Longest T60, s.
    pub t60_max_s: Option<f64>,
    /// Share of the decays that carry at least one flag (0–1; qualifying flags such as
    /// `noise_compensated` count too: see `flags`).
    pub flagged_share: f64,
    /// Every flag raised on these decays, with how many carry it: `flag:count;…`, sorted.
    pub flags: String,
}

/// One channel × band being gathered.
#[derive(Clone, Debug)]
struct Group {
    channel: String,
    band: Band,
    d: Vec<f64>,
    t60_s: Vec<f64>,
    n: usize,
    flagged: usize,
    missing: BTreeMap<&'static str, usize>,
    flags: BTreeMap<&'static str, usize>,
}

/// Result rows gathered per channel × band, in the order each channel × band first came.
#[derive(Clone, Debug, Default)]
pub struct Spread {
    groups: Vec<Group>,
    index: HashMap<(String, u64, u64), usize>,
}

fn joined(counts: &BTreeMap<&'static str, usize>) -> String {
    counts
        .iter()
        .map(|(k, v)| format!("{k}:{v}"))
        .collect::<Vec<_>>()
        .join(";")
}

fn sorted_finite(v: &[f64]) -> Vec<f64> {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v
}

impl Spread {
    /// Nothing gathered yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one decay's result in `band` of `channel`: its damping ratio and T60 when it has
    /// them (non-finite values count as missing), and its flags.
    pub fn add(
        &mut self,
        channel: &str,
        band: Band,
        damping_ratio: Option<f64>,
        t60_s: Option<f64>,
        flags: &[Flag],
    ) {
        let key = (
            channel.to_string(),
            band.lo_hz.to_bits(),
            band.hi_hz.to_bits(),
        );
        let k = *self.index.entry(key).or_insert_with(|| {
            self.groups.push(Group {
                channel: channel.to_string(),
                band,
                d: Vec::new(),
                t60_s: Vec::new(),
                n: 0,
                flagged: 0,
                missing: BTreeMap::new(),
                flags: BTreeMap::new(),
            });
            self.groups.len() - 1
        });
        let g = &mut self.groups[k];
        g.n += 1;
        match damping_ratio.filter(|d| d.is_finite()) {
            Some(d) => g.d.push(d),
            None => *g.missing.entry(Flag::missing_reason(flags)).or_default() += 1,
        }
        if let Some(t) = t60_s.filter(|t| t.is_finite()) {
            g.t60_s.push(t);
        }
        if !flags.is_empty() {
            g.flagged += 1;
        }
        let mut seen: Vec<&'static str> = flags.iter().map(Flag::as_str).collect();
        seen.sort_unstable();
        seen.dedup();
        for f in seen {
            *g.flags.entry(f).or_default() += 1;
        }
    }

    /// Adds a result row of the analysis.
    pub fn add_row(&mut self, r: &ResultRow) {
        let e = &r.estimate;
        self.add(&r.channel, r.band, e.damping_ratio, e.t60_s, &e.flags);
    }

    /// The spread of every channel × band gathered, in the order they first came.
    pub fn rows(&self) -> Vec<SpreadRow> {
        self.groups
            .iter()
            .map(|g| {
                let d = sorted_finite(&g.d);
                let t = sorted_finite(&g.t60_s);
                let (q1, q3) = (quantile(&d, 0.25), quantile(&d, 0.75));
                SpreadRow {
                    channel: g.channel.clone(),
                    f_lo_hz: g.band.lo_hz,
                    f_hi_hz: g.band.hi_hz,
                    f_center_hz: g.band.center_hz,
                    n_decays: g.n,
                    n_estimated: d.len(),
                    missing: joined(&g.missing),
                    d_min: d.first().copied(),
                    d_q1: q1,
                    d_median: quantile(&d, 0.5),
                    d_q3: q3,
                    d_max: d.last().copied(),
                    d_iqr: q1.zip(q3).map(|(a, b)| b - a),
                    t60_min_s: t.first().copied(),
                    t60_q1_s: quantile(&t, 0.25),
                    t60_median_s: quantile(&t, 0.5),
                    t60_q3_s: quantile(&t, 0.75),
                    t60_max_s: t.last().copied(),
                    flagged_share: g.flagged as f64 / g.n as f64,
                    flags: joined(&g.flags),
                }
            })
            .collect()
    }
}

/// [`Spread`] of `rows`.
pub fn summarize(rows: &[ResultRow]) -> Vec<SpreadRow> {
    let mut s = Spread::new();
    for r in rows {
        s.add_row(r);
    }
    s.rows()
}

/// Columns of a results table that [`summarize_table`] reads.
const NEEDED: [&str; 7] = [
    "channel",
    "f_lo",
    "f_hi",
    "f_center",
    "t60_s",
    "damping_ratio",
    "flags",
];

/// [`Spread`] of a results table as `analyze` writes it (CSV with a header row, flags joined by
/// `;`), read row by row from `input` (`what` names it in errors). Errors: a missing column, a
/// cell that is not a number, a band that is not one, a flag dampscope does not know.
pub fn summarize_table(input: impl Read, what: &str) -> Result<Vec<SpreadRow>> {
    let bad = |detail: String| {
        Error::Source(SourceError::Malformed {
            what: what.to_string(),
            format: "results table",
            detail,
        })
    };
    let mut reader = csv::Reader::from_reader(input);
    let header = reader.headers().map_err(|e| bad(e.to_string()))?.clone();
    let mut at = [0usize; NEEDED.len()];
    for (slot, name) in at.iter_mut().zip(NEEDED) {
        *slot = header.iter().position(|h| h == name).ok_or_else(|| {
            bad(format!(
                "no column {name:?} (expected the table `dampscope analyze` writes, CSV)"
            ))
        })?;
    }
    let mut spread = Spread::new();
    for (i, record) in reader.records().enumerate() {
        let line = i + 2;
        let record = record.map_err(|e| bad(format!("line {line}: {e}")))?;
        let cell = |k: usize| record.get(at[k]).unwrap_or("").trim();
        let number = |k: usize| -> Result<Option<f64>> {
            let c = cell(k);
            if c.is_empty() {
                return Ok(None);
            }
            c.parse::<f64>().map(Some).map_err(|_| {
                bad(format!(
                    "line {line}: column {}: expected a number or nothing, got {c:?}",
                    NEEDED[k]
                ))
            })
        };
        let edge = |k: usize| {
            number(k)?.ok_or_else(|| bad(format!("line {line}: column {} is empty", NEEDED[k])))
        };
        let (lo, hi, center) = (edge(1)?, edge(2)?, edge(3)?);
        if !(lo.is_finite() && hi.is_finite() && center.is_finite() && 0.0 <= lo && lo < hi) {
            return Err(bad(format!(
                "line {line}: expected a band 0 <= f_lo < f_hi, got {lo}:{hi}"
            )));
        }
        let band = Band {
            lo_hz: lo,
            hi_hz: hi,
            center_hz: center,
            nominal_hz: center,
        };
        let flags = cell(6)
            .split(';')
            .filter(|f| !f.is_empty())
            .map(|f| Flag::parse(f).ok_or_else(|| bad(format!("line {line}: unknown flag {f:?}"))))
            .collect::<Result<Vec<Flag>>>()?;
        spread.add(cell(0), band, number(5)?, number(4)?, &flags);
    }
    Ok(spread.rows())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn band() -> Band {
        Band::new(100.0, 140.0).unwrap()
    }

    #[test]
    fn quantiles_of_known_lists() {
        let x = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(quantile(&x, 0.5), Some(2.5));
        assert_eq!(quantile(&x, 0.25), Some(1.75));
        assert_eq!(quantile(&x, 0.75), Some(3.25));
        assert_eq!(quantile(&x, 0.0), Some(1.0));
        assert_eq!(quantile(&x, 1.0), Some(4.0));
        assert_eq!(quantile(&[7.0], 0.25), Some(7.0));
        assert_eq!(quantile(&[], 0.5), None);
        assert_eq!(quantile(&x, 1.5), None);
        assert_eq!(quantile(&x, f64::NAN), None);
    }

    #[test]
    fn missing_numbers_are_counted_by_reason_and_flags_by_name() {
        let mut s = Spread::new();
        s.add("a", band(), Some(0.02), Some(0.39), &[]);
        s.add(
            "a",
            band(),
            Some(0.01),
            Some(0.78),
            &[Flag::NoiseCompensated],
        );
        s.add(
            "a",
            band(),
            None,
            None,
            &[Flag::NoiseCompensated, Flag::PoorFit],
        );
        s.add("a", band(), None, None, &[Flag::TooShort]);
        s.add("a", band(), Some(f64::NAN), None, &[]);
        s.add("b", band(), Some(0.03), Some(0.26), &[]);
        let rows = s.rows();
        assert_eq!(rows.len(), 2);
        let a = &rows[0];
        assert_eq!((a.channel.as_str(), a.n_decays, a.n_estimated), ("a", 5, 2));
        assert_eq!(a.missing, "no_estimate:1;poor_fit:1;too_short:1");
        assert_eq!(a.flags, "noise_compensated:2;poor_fit:1;too_short:1");
        assert_eq!(a.flagged_share, 3.0 / 5.0);
        assert_eq!((a.d_min, a.d_max), (Some(0.01), Some(0.02)));
        assert!((a.d_median.unwrap() - 0.015).abs() < 1e-15, "{a:?}");
        assert!((a.t60_median_s.unwrap() - 0.585).abs() < 1e-15, "{a:?}");
        assert_eq!(rows[1].channel, "b");
        assert_eq!(rows[1].d_iqr, Some(0.0));
    }

    #[test]
    fn a_broken_table_is_an_error_naming_the_line() {
        let head = "channel,f_lo,f_hi,f_center,t60_s,damping_ratio,flags\n";
        let err = |text: &str| {
            summarize_table(text.as_bytes(), "t.csv")
                .unwrap_err()
                .to_string()
        };
        assert!(err("channel,f_lo\na,1\n").contains("no column \"f_hi\""));
        assert!(err(&format!("{head}a,1,2,1.5,x,0.1,\n")).contains("line 2"));
        assert!(err(&format!("{head}a,3,2,2.5,,,\n")).contains("f_lo < f_hi"));
        assert!(err(&format!("{head}a,1,2,1.5,,,no_such_flag\n")).contains("unknown flag"));
        assert!(err(&format!("{head}a,,2,1.5,,,\n")).contains("f_lo is empty"));
        let ok = summarize_table(format!("{head}a,1,2,1.5,,,too_short\n").as_bytes(), "t").unwrap();
        assert_eq!(ok[0].missing, "too_short:1");
    }
}

//! ISO 3382 evaluation ranges on the normalised Schroeder curve.

use std::fmt;
use std::str::FromStr;

/// The part of the normalised decay curve that the line is fitted to.
///
/// `Edt` is 0…−10 dB, `T20` −5…−25 dB, `T30` −5…−35 dB, `Drop(n)` −5…−(5 + n) dB and
/// `Between` any other interval (e.g. 0…−30 dB, the report's "30 dB drop" read from the start of
/// the curve, or pyrato's T15/T40/LDT); the fitted slope is extrapolated to 60 dB.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum EvaluationRange {
    /// Early decay time, 0 … −10 dB.
    Edt,
    /// −5 … −25 dB.
    T20,
    /// −5 … −35 dB.
    T30,
    /// −5 … −(5 + drop) dB, drop in dB.
    Drop(f64),
    /// −`from_db` … −`to_db` dB (0 ≤ from_db < to_db).
    Between {
        /// Upper limit below the start of the curve, dB (positive number).
        from_db: f64,
        /// Lower limit below the start of the curve, dB (positive number).
        to_db: f64,
    },
}

impl EvaluationRange {
    /// Upper and lower limit of the range in dB (both ≤ 0, upper > lower).
    pub fn limits_db(&self) -> (f64, f64) {
        match *self {
            EvaluationRange::Edt => (0.0, -10.0),
            EvaluationRange::T20 => (-5.0, -25.0),
            EvaluationRange::T30 => (-5.0, -35.0),
            EvaluationRange::Drop(n) => (-5.0, -5.0 - n),
            EvaluationRange::Between { from_db, to_db } => (-from_db, -to_db),
        }
    }
}

impl fmt::Display for EvaluationRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EvaluationRange::Edt => write!(f, "edt"),
            EvaluationRange::T20 => write!(f, "t20"),
            EvaluationRange::T30 => write!(f, "t30"),
            EvaluationRange::Drop(n) => write!(f, "drop:{n}"),
            EvaluationRange::Between { from_db, to_db } => write!(f, "from:{from_db}:{to_db}"),
        }
    }
}

/// Why a range description could not be read.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error(
    "invalid evaluation range '{given}': expected edt, t20, t30, drop:N with 0 < N <= 100 dB, or from:A:B with 0 <= A < B <= 100 dB"
)]
pub struct RangeParseError {
    /// The text that was given.
    pub given: String,
}

impl FromStr for EvaluationRange {
    type Err = RangeParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = || RangeParseError {
            given: s.to_string(),
        };
        match s.to_ascii_lowercase().as_str() {
            "edt" => Ok(EvaluationRange::Edt),
            "t20" => Ok(EvaluationRange::T20),
            "t30" => Ok(EvaluationRange::T30),
            other if other.starts_with("from:") => {
                let mut parts = other["from:".len()..].split(':');
                let (a, b) = match (parts.next(), parts.next(), parts.next()) {
                    (Some(a), Some(b), None) => (a, b),
                    _ => return Err(err()),
                };
                let (from_db, to_db): (f64, f64) =
                    (a.parse().map_err(|_| err())?, b.parse().map_err(|_| err())?);
                if from_db >= 0.0 && to_db > from_db && to_db <= 100.0 {
                    Ok(EvaluationRange::Between { from_db, to_db })
                } else {
                    Err(err())
                }
            }
            other => {
                let n: f64 = other
                    .strip_prefix("drop:")
                    .ok_or_else(err)?
                    .parse()
                    .map_err(|_| err())?;
                if n.is_finite() && n > 0.0 && n <= 100.0 {
                    Ok(EvaluationRange::Drop(n))
                } else {
                    Err(err())
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_named_and_drop_ranges() {
        assert_eq!("T30".parse(), Ok(EvaluationRange::T30));
        assert_eq!("drop:15".parse(), Ok(EvaluationRange::Drop(15.0)));
        assert_eq!(EvaluationRange::Drop(15.0).limits_db(), (-5.0, -20.0));
        assert!("drop:-3".parse::<EvaluationRange>().is_err());
        assert!("t25".parse::<EvaluationRange>().is_err());
    }

    #[test]
    fn parses_any_interval_and_round_trips() {
        let r: EvaluationRange = "from:0:30".parse().unwrap();
        assert_eq!(r.limits_db(), (0.0, -30.0));
        assert_eq!(r.to_string(), "from:0:30");
        assert_eq!(r.to_string().parse(), Ok(r));
        let late: EvaluationRange = "FROM:25:35".parse().unwrap();
        assert_eq!(late.limits_db(), (-25.0, -35.0));
        for bad in [
            "from:30:0",
            "from:5:5",
            "from:-1:20",
            "from:0:120",
            "from:0",
            "from:0:10:20",
            "from:a:b",
        ] {
            assert!(bad.parse::<EvaluationRange>().is_err(), "{bad}");
        }
    }
}

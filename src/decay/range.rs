//! ISO 3382 evaluation ranges on the normalised Schroeder curve.

use std::fmt;
use std::str::FromStr;

/// The part of the normalised decay curve that the line is fitted to.
///
/// `Edt` is 0…−10 dB, `T20` −5…−25 dB, `T30` −5…−35 dB and `Drop(n)` −5…−(5 + n) dB; the fitted
/// slope is extrapolated to 60 dB.
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
}

impl EvaluationRange {
    /// Upper and lower limit of the range in dB (both ≤ 0, upper > lower).
    pub fn limits_db(&self) -> (f64, f64) {
        match *self {
            EvaluationRange::Edt => (0.0, -10.0),
            EvaluationRange::T20 => (-5.0, -25.0),
            EvaluationRange::T30 => (-5.0, -35.0),
            EvaluationRange::Drop(n) => (-5.0, -5.0 - n),
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
        }
    }
}

/// Why a range description could not be read.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error(
    "invalid evaluation range '{given}': expected edt, t20, t30 or drop:N with 0 < N <= 100 dB"
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
}

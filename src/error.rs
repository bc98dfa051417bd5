//! Crate-level error type: every library error says what was expected, what was found, and where.

use crate::source::SourceError;

/// Any error that stops a dampscope operation.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The input could not be read or decoded.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// A setting is impossible (empty band, window longer than allowed, …).
    #[error("invalid setting {name}: {reason}")]
    InvalidSetting {
        /// The option or field at fault.
        name: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The work would need more memory than the budget allows (checked before allocating).
    #[error("memory: {what} needs about {estimate}, more than the limit of {limit} (raise the memory limit, or reduce the work)")]
    MemoryLimit {
        /// What was to be allocated.
        what: String,
        /// The estimate, readable.
        estimate: String,
        /// The limit, readable.
        limit: String,
    },
    /// Writing results failed.
    #[error("cannot write results: {0}")]
    Output(String),
    /// An I/O failure outside of input decoding.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// Result with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Shorthand for [`Error::InvalidSetting`].
    pub fn setting(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::InvalidSetting {
            name: name.into(),
            reason: reason.into(),
        }
    }
}

/// `x` as a message shows a number a user gave: as written for ordinary magnitudes, in
/// exponent form outside 10⁻⁴…10¹⁵ (`--fs 1e-300` printed 300 zeros).
pub(crate) fn shown(x: f64) -> String {
    let magnitude = x.abs();
    if x == 0.0 || !x.is_finite() || (1e-4..1e15).contains(&magnitude) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

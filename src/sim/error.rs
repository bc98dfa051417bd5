//! Errors of the plate simulator: every variant names what is at fault (TOML key, element, dof).

use std::path::PathBuf;

/// What went wrong while reading a model, meshing, assembling or solving it.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The model file could not be read.
    #[error("cannot read model file {path}: {message}")]
    Io {
        /// The file that was read.
        path: PathBuf,
        /// The operating system's message.
        message: String,
    },
    /// The TOML text is malformed or has unknown/missing keys (the message names the key and line).
    #[error("model TOML: {0}")]
    Toml(String),
    /// A value in the model is impossible; `key` is the TOML key path (e.g. `plate.thickness`).
    #[error("{key}: {message}")]
    InvalidValue {
        /// TOML key path, e.g. `patch[1].x` or `output.sensors.file`.
        key: String,
        /// Expected vs got.
        message: String,
    },
    /// An element's geometry or matrices are unusable (e.g. a non-positive Jacobian).
    #[error("element {element}: {message}")]
    Element {
        /// Element index in the mesh numbering.
        element: usize,
        /// What is wrong.
        message: String,
    },
    /// A sparse matrix could not be built or factorised; `what` names the matrix.
    #[error("{what}: {message}")]
    Linear {
        /// Which matrix (e.g. `K0 - sigma M`).
        what: String,
        /// The solver's message.
        message: String,
    },
    /// The eigen-solver could not deliver what was requested.
    #[error("eigen-solver: {0}")]
    Eigen(String),
}

/// Shorthand for an [`SimError::InvalidValue`].
pub(crate) fn invalid(key: impl Into<String>, message: impl Into<String>) -> SimError {
    SimError::InvalidValue {
        key: key.into(),
        message: message.into(),
    }
}

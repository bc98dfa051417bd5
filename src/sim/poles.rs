//! The damped poles of a plate model: what a free decay of the structure is made of, each
//! with its own damping ratio. With non-proportional damping (a damped patch) the modal strain
//! energy gives these only to first order; here they are the eigenvalues of the damped system
//! reduced to its modes and residual vectors (see [`ReducedModel::damped_poles`]).

use super::eigen::{lowest_modes_with, EigenOptions, ModeRequest};
use super::reduced::{BasisOptions, ReducedModel};
use super::{FeSystem, SimError};

/// The basis of the reduction holds every mode below this multiple of the highest pole asked
/// for: the damping couples a mode mostly to its near neighbours, and the residual vectors
/// carry the rest.
pub const POLE_BASIS_FACTOR: f64 = 2.0;

/// One damped pole: a free response e^{st} with s = 2π f (−D + j√(1 − D²)) / √(1 − D²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DampedPole {
    /// Damped natural frequency Im s / 2π, Hz.
    pub damped_frequency_hz: f64,
    /// Damping ratio −Re s / |s|.
    pub damping_ratio: f64,
}

/// The damped poles of `system` below `fmax_hz`, by frequency. Errors for a viscoelastic (SLS)
/// region, whose poles depend on frequency, and when the eigensolver fails.
pub fn damped_poles_below(
    system: &FeSystem,
    fmax_hz: f64,
    options: &EigenOptions,
) -> Result<Vec<DampedPole>, SimError> {
    let (modes, _) = lowest_modes_with(
        system,
        ModeRequest::BelowHz(POLE_BASIS_FACTOR * fmax_hz),
        options,
    )?;
    let reduced = ReducedModel::build(
        system,
        &modes.frequencies_hz,
        modes.shapes.as_ref(),
        BasisOptions::default(),
    )?;
    Ok(reduced
        .damped_poles()?
        .into_iter()
        .filter(|p| p.0 < fmax_hz)
        .map(|(f, d)| DampedPole {
            damped_frequency_hz: f,
            damping_ratio: d,
        })
        .collect())
}

//! The damped poles of a plate model: what a free decay of the structure is made of, each
//! with its own damping ratio. With non-proportional damping (a damped patch) the modal strain
//! energy gives these only to first order; here they are the eigenvalues of the damped system
//! reduced to its modes and residual vectors (see [`ReducedModel::damped_poles`]).

use super::eigen::{lowest_modes_with, EigenOptions, ModeRequest, Modes};
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

/// The `count` lowest damped poles of `system`, by frequency, whose undamped modes lie at or
/// below `highest_mode_hz` (the basis holds the modes below [`POLE_BASIS_FACTOR`] times that).
/// A viscoelastic (SLS) region's frequency dependence is exact (internal variables, see
/// `ReducedModel::damped_poles`). Errors when the eigensolver fails, and when fewer than `count` poles come out.
pub fn lowest_damped_poles(
    system: &FeSystem,
    count: usize,
    highest_mode_hz: f64,
    options: &EigenOptions,
) -> Result<Vec<DampedPole>, SimError> {
    let (modes, _) = lowest_modes_with(
        system,
        ModeRequest::BelowHz(POLE_BASIS_FACTOR * highest_mode_hz),
        options,
    )?;
    damped_poles_from_modes(system, &modes, count)
}

/// The `count` lowest damped poles of `system` in the basis of `modes` (its undamped modes,
/// which should reach well above the poles asked for; see [`POLE_BASIS_FACTOR`]) and residual
/// vectors. Errors as [`lowest_damped_poles`].
pub fn damped_poles_from_modes(
    system: &FeSystem,
    modes: &Modes,
    count: usize,
) -> Result<Vec<DampedPole>, SimError> {
    let reduced = ReducedModel::build(
        system,
        &modes.frequencies_hz,
        modes.shapes.as_ref(),
        BasisOptions::default(),
    )?;
    let poles = reduced.damped_poles()?;
    if poles.len() < count {
        return Err(SimError::Eigen(format!(
            "expected {count} damped poles, got {}",
            poles.len()
        )));
    }
    Ok(poles[..count]
        .iter()
        .map(|&(f, d)| DampedPole {
            damped_frequency_hz: f,
            damping_ratio: d,
        })
        .collect())
}

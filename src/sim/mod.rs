//! The finite-element plate simulator (8-node hexahedra), one more source of decays.

pub mod frf;
pub mod impulse;
pub mod reduced;
pub mod system;
pub mod truncation;

pub use system::{FeSystem, Sls, StiffnessTerm};

//! The finite-element plate simulator (8-node hexahedra), one more source of decays.

pub mod frf;
pub mod system;

pub use system::{FeSystem, Sls, StiffnessTerm};

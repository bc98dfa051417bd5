//! The finite-element plate simulator (8-node hexahedra), one more source of decays.

pub mod assembly;
pub mod eigen;
pub mod element;
pub mod error;
pub mod mesh;
pub mod model;
pub mod system;
pub mod validate;

pub use error::SimError;
pub use system::{FeSystem, Sls, StiffnessTerm};

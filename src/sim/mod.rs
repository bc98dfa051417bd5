//! The finite-element plate simulator (8-node hexahedra), one more source of decays.

pub mod assembly;
pub mod basis;
pub mod combination;
pub mod eigen;
pub mod element;
pub mod error;
pub mod factored;
pub mod frf;
pub mod impulse;
pub mod interface;
pub mod limits;
pub mod mesh;
pub mod model;
pub mod poles;
pub mod reduced;
pub mod reduced_poles;
pub mod resolution;
pub mod reuse;
mod scatter_plan;
pub mod simulate;
pub mod spmm;
pub mod state_space;
pub mod stream;
pub mod substructure;
pub mod system;
pub mod truncation;
pub mod validate;

pub use error::SimError;
pub use system::{FeSystem, Sls, StiffnessTerm};

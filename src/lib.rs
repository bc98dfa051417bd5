//! # dampscope
//!
//! Measures how a structure loses vibration energy: where, at which frequencies and why.
//!
//! Decays (impulse responses or free decays, one per sensor) flow through
//!
//! ```text
//! source ──▶ front end ──▶ decay estimator ──▶ results (rows per band × channel)
//! (WAV, CSV,  (STFT, Goyder   (online backward     (CSV / JSON lines,
//!  raw, FE     filter bank,    Schroeder + line     maps, global D)
//!  simulator)  octave bank)    fit, flags)
//! ```
//!
//! The seams are traits: [`source::Source`] yields multichannel blocks,
//! [`frontend::FrontEnd`] turns one channel's samples into band energies per frame, and
//! [`decay::DecayEstimator`] turns one band's energy sequence into a [`decay::DecayEstimate`].
//! Plain data structs travel between them.

pub mod analysis;
pub mod budget;
pub mod cli;
pub mod decay;
pub mod diagnose;
pub mod error;
pub mod frontend;
pub mod modal;
pub mod output;
pub mod pipeline;
pub mod plan;
pub mod plot;
pub mod presets;
pub mod sim;
pub mod source;

pub use error::{Error, Result};

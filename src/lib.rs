//! # dampscope
//!
//! Measures how a structure loses vibration energy: where, at which frequencies and why.
//!
//! Decays (impulse responses or free decays, one per sensor) flow through
//!
//! ```text
//! source ──▶ segmentation ──▶ front end ──▶ decay estimator ──▶ rows per decay × band × channel
//! (WAV, CSV,  (onset, new     (STFT, Goyder  (online backward    ──▶ maps, global D, modal
//!  raw, FE     hit, end)       bank, octave   Schroeder + line       identification, diagnosis
//!  simulator)                  bank)          fit, flags)
//! ```
//!
//! The seams are traits: [`source::Source`] yields multichannel blocks,
//! [`frontend::FrontEnd`] turns one channel's samples into band energies per frame, and
//! [`decay::DecayEstimator`] turns one band's energy sequence into a [`decay::DecayEstimate`].
//! Plain data structs travel between them. Above them, [`plan`] holds what an analysis is to
//! do ([`plan::AnalysisPlan`], [`plan::FrontEndSpec`], [`plan::BandLayout`]); the procedures
//! are library functions ([`pipeline::run`], [`analysis::compare::compare`],
//! [`modal::identify`], [`diagnose::procedure::diagnose`]); the command line ([`cli`]) only
//! parses, calls and prints. The plate simulator ([`sim`]) stands apart, one more source.
//!
//! ## Damping of a synthetic decay
//!
//! One mode at 55 Hz with 2.5 % damping (the report's eq. 4.5), through the report's 200 ms
//! STFT in one 5 Hz band, T30:
//!
//! ```
//! use dampscope::decay::estimate::EstimateSettings;
//! use dampscope::frontend::Band;
//! use dampscope::pipeline::analyze_decay;
//! use dampscope::plan::FrontEndSpec;
//! use dampscope::source::synth::{decaying_sines, Mode};
//!
//! let fs_hz = 4000.0;
//! let x = decaying_sines(&[Mode::new(55.0, 0.025, 1.0, 0.0)], fs_hz, 4.0);
//! let band = Band::new(52.5, 57.5)?;
//! let mut stft = FrontEndSpec::default().build(fs_hz, &[band])?;
//! let estimate = analyze_decay(&x, stft.as_mut(), &EstimateSettings::default()).remove(0);
//! let d = estimate.damping_ratio_corrected.expect("a number");
//! assert!((d - 0.025).abs() < 0.001, "D = {d}");
//! # Ok::<(), dampscope::Error>(())
//! ```
//!
//! ## Modes of a plate
//!
//! The lowest modes of a small finite-element plate (the reference plate's material and size on
//! a coarse 8 × 12 × 2 mesh); mode 1 of the 32 × 48 × 2 model is at 5.23 Hz:
//!
//! ```
//! use dampscope::sim::eigen::{model_modes, ModeRequest};
//! use dampscope::sim::model::Model;
//!
//! let mut plate = Model::reference_plate();
//! (plate.mesh.nx, plate.mesh.ny) = (8, 12);
//! let modes = model_modes(&plate, ModeRequest::Count(3))?;
//! assert_eq!(modes.frequencies_hz.len(), 3);
//! assert!((modes.frequencies_hz[0] - 5.23).abs() < 0.2, "{:?}", modes.frequencies_hz);
//! # Ok::<(), dampscope::sim::SimError>(())
//! ```

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
pub mod uff;

pub use error::{Error, Result};

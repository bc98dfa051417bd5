//! The application layer: plans that say what to analyse and how, validated once, and the
//! factories that turn them into working parts.
//!
//! The lower floors (sources, front ends, decay estimators, the pipeline) know nothing of how a
//! user asks for an analysis; the command line knows nothing of how one is done. Between them:
//!
//! - [`FrontEndSpec`] (in [`front_end`]), the one factory of front ends;
//! - [`BandLayout`] (in [`bands`]), the band grammar and its resolution into bands;
//! - [`AnalysisPlan`] (in [`analysis`]): layout + front end + estimate and segmentation
//!   settings, and its [`AnalysisPlan::prepare`].
//!
//! ```
//! use dampscope::plan::{AnalysisPlan, BandLayout};
//! use dampscope::frontend::Band;
//! use dampscope::source::{memory::MemorySource, SignalInfo};
//!
//! // One mode at 100 Hz with 1 % damping, 2 s at 4 kHz.
//! let fs = 4000.0;
//! let x: Vec<f64> = (0..8000)
//!     .map(|i| {
//!         let t = i as f64 / fs;
//!         let w = 2.0 * std::f64::consts::PI * 100.0;
//!         (-0.01 * w * t).exp() * (w * t).sin()
//!     })
//!     .collect();
//! let info = SignalInfo { sample_rate_hz: fs, channel_names: vec!["s1".into()] };
//! let source = Box::new(MemorySource::new(info, vec![x]).unwrap());
//! let plan = AnalysisPlan {
//!     bands: BandLayout::of_bands(&[Band::new(75.0, 125.0).unwrap()]),
//!     ..Default::default()
//! };
//! let run = plan.prepare(source).unwrap();
//! let mut rows = Vec::new();
//! dampscope::pipeline::run(run.source, &run.factory, &run.config, |r| {
//!     rows.extend_from_slice(r);
//!     Ok(())
//! })
//! .unwrap();
//! let d = rows[0].estimate.damping_ratio.unwrap();
//! assert!((d - 0.01).abs() < 0.0005, "D = {d}");
//! ```

pub mod analysis;
pub mod bands;
pub mod front_end;

pub use analysis::{AnalysisPlan, PreparedRun};
pub use bands::{BandLayout, BandSpec, ResolvedBands};
pub use front_end::{FrontEndKind, FrontEndSpec};

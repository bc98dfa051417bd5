//! Mismatch diagnosis (DESIGN.md §4): when recordings and the model differ, what physics the
//! model left out, where, how much, and the fit before and after adding it.
//!
//! The data flow, one file each:
//!
//! - [`evidence`]: the recordings' modes (identified from all sensors at once) paired by shape
//!   with the model's damped poles at the same sensors; [`noise`]: each channel's noise floor;
//! - [`score`]: one score for every hypothesis (frequencies with the model-form
//!   [`nuisance`] profiled out, damping against the identification's σ, parameters and
//!   scanned locations paid for);
//! - the hypothesis families, each scanning its locations with first-order sensitivities:
//!   [`mass`] (a point), [`stiffness`] and [`damping`] (any rectangle of [`regions`]),
//!   [`viscoelastic`] (a rectangle and a loss peak), [`boundary`] (an edge's spring, through
//!   a reduced model of both limits), [`damping`]'s laws;
//! - [`mirror`]: images of a finding that the evidence cannot tell apart, settled by the shapes;
//! - [`hypothesis`]: the change each finding makes to the model file (the update), and
//!   [`refine`]: its size re-fitted through the re-solved model;
//! - [`fit`]: the fit of a model to the recordings (modes and FRFs, eq. 4.8); [`fit_compare`]:
//!   whether an update fits worse than the model as given;
//! - [`candidates`]: one round's best explanation of each family, and its size settled;
//! - [`procedure`]: runs it all and keeps what pays for its parameters; [`report`]: the
//!   findings in `diagnosis.json` form and in plain words; [`output`]: the files of a
//!   diagnosis (JSON, updated model, modes.csv, report.md, figures); [`workers`]: independent
//!   re-solves on every core.

pub mod boundary;
pub mod candidates;
pub mod damping;
pub mod evidence;
pub mod fit;
pub mod fit_compare;
pub mod hypothesis;
pub mod mass;
pub mod mirror;
pub mod nnls;
pub mod noise;
pub mod nuisance;
pub mod output;
pub mod procedure;
pub mod refine;
pub mod regions;
pub mod report;
pub mod reweigh;
pub mod score;
pub mod stiffness;
pub mod viscoelastic;
pub mod workers;

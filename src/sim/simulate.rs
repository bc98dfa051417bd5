//! Orchestration: model → assembly → modes → FRFs (direct, fast or truncated) → impulse
//! responses at fs = 2 fmax, with optional seeded measurement noise at a peak SNR.

use std::io::IsTerminal;
use std::time::Instant;

use super::assembly::assemble;
use super::eigen::{lowest_modes, ModeRequest, Modes};
use super::error::SimError;
use super::factored::FactoredFrf;
use super::frf::{direct_frf, Frf, FrfError};
use super::impulse::impulse_response;
use super::interface::{build as build_interface, partition};
use super::limits::ModelSize;
use super::model::{Excitation, Model};
use super::reduced::{BasisOptions, ReducedModel, ReducedSolve};
use super::stream::{streamed_bytes, SimulatedSource};
use super::substructure::{craig_bampton_vectors, DENSE_INTERIOR_MAX_DOFS};
use super::system::{FeSystem, SensorWeights};
use super::truncation::{truncated_factored_frf, ModalDamping};
use crate::source::noise::GaussianNoise;

impl From<FrfError> for SimError {
    fn from(e: FrfError) -> Self {
        match e {
            FrfError::Factorisation { what, message } => SimError::Linear { what, message },
            FrfError::Invalid { what, message } => SimError::InvalidValue { key: what, message },
            FrfError::Dimension {
                what,
                expected,
                got,
            } => SimError::InvalidValue {
                key: what,
                message: format!("expected {expected}, got {got}"),
            },
        }
    }
}

/// How the frequency responses are computed.
#[derive(Clone, Debug, PartialEq)]
pub enum Method {
    /// Sparse complex solve per frequency (report eq. 2.6): the slow reference.
    Direct,
    /// Projection onto modes + residual vectors with exact regional damping (the default);
    /// viscoelastic regions are substructured (Craig–Bampton, [`super::substructure`]) and
    /// the responses come from one state-space eigen-solve ([`super::state_space`]).
    Fast,
    /// Only the given modes (1-based numbers, report eq. 2.7 / 4.6).
    Truncated(Vec<usize>),
}

/// Settings of [`simulate`].
#[derive(Clone, Debug)]
pub struct SimulateOptions {
    /// FRF method.
    pub method: Method,
    /// For [`Method::Truncated`]: given modal damping ratios D_i (one per kept mode) instead of
    /// the modal strain energy loss factors.
    pub modal_damping_ratios: Option<Vec<f64>>,
    /// For [`Method::Fast`]: modes below `mode_cutoff_factor × fmax` form the basis.
    pub mode_cutoff_factor: f64,
    /// Peak SNR of added white Gaussian noise per channel, dB (σ = max|h| · 10^(−snr/20)).
    pub snr_db: Option<f64>,
    /// Seed of the noise (channel k uses seed + k).
    pub seed: u64,
    /// Show a progress bar on stderr (only drawn when stderr is a terminal).
    pub progress: bool,
}

impl Default for SimulateOptions {
    fn default() -> Self {
        Self {
            method: Method::Fast,
            modal_damping_ratios: None,
            mode_cutoff_factor: 1.5,
            snr_db: None,
            seed: 0,
            progress: false,
        }
    }
}

/// Wall-clock time of each phase, s.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Timings {
    /// Model → FeSystem.
    pub assembly_s: f64,
    /// Eigen-solve (0 for the direct method).
    pub modes_s: f64,
    /// Basis, projection, diagonalisation.
    pub reduction_s: f64,
    /// FRFs at every frequency and sensor.
    pub frf_s: f64,
    /// How the reduced responses were solved (`None`: the direct method, or no reduction).
    pub frf_solve: Option<super::factored::FrfSolve>,
    /// Inverse FFTs and noise.
    pub impulse_s: f64,
}

/// What a simulation produces.
#[derive(Clone, Debug)]
pub struct SimulationResult {
    /// Sample rate of the impulse responses, Hz (= 2 fmax).
    pub fs_hz: f64,
    /// Receptances at every sensor (accelerance via [`Frf::accelerance`]).
    pub frf: Frf,
    /// One impulse response per sensor, (m/s²)/(N·s), length 1/(df Δt).
    pub impulse_responses: Vec<Vec<f64>>,
    /// The sensors (ids, positions).
    pub sensors: Vec<SensorWeights>,
    /// The excitation, if the result came from a model.
    pub excitation: Option<Excitation>,
    /// How many modes the method used (0 for the direct method).
    pub modes_used: usize,
    /// Phase times.
    pub timings: Timings,
}

/// The frequency grid 0, df, …, fmax; fmax must be a whole multiple of df.
pub fn frequency_grid(fmax_hz: f64, df_hz: f64) -> Result<Vec<f64>, SimError> {
    if !(fmax_hz.is_finite() && fmax_hz > 0.0 && df_hz.is_finite() && df_hz > 0.0) {
        return Err(SimError::InvalidValue {
            key: "output.fmax / output.df".into(),
            message: format!("expected finite values > 0 Hz, got fmax {fmax_hz}, df {df_hz}"),
        });
    }
    let steps = fmax_hz / df_hz;
    let n = steps.round();
    if (steps - n).abs() > 1e-6 * steps.max(1.0) || !(1.0..=1e8).contains(&n) {
        return Err(SimError::InvalidValue {
            key: "output.df".into(),
            message: format!(
                "expected fmax/df to be a whole number ≥ 1, got {fmax_hz}/{df_hz} = {steps}"
            ),
        });
    }
    let n = n as usize;
    Ok((0..=n).map(|k| fmax_hz * k as f64 / n as f64).collect())
}

fn progress_bar(enabled: bool, phases: u64) -> indicatif::ProgressBar {
    if enabled && std::io::stderr().is_terminal() {
        let pb = indicatif::ProgressBar::new(phases);
        pb.set_style(
            indicatif::ProgressStyle::with_template("{elapsed:>4} [{bar:30}] {pos}/{len} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb
    } else {
        indicatif::ProgressBar::hidden()
    }
}

/// Bytes a simulation of `model` needs at most when it holds every output (see
/// [`memory_estimate`]).
pub fn memory_estimate_bytes(model: &Model) -> f64 {
    memory_estimate(model, true)
}

/// Bytes a simulation of `model` needs, estimated from its sizes before anything is allocated
/// ([`ModelSize`]): the system (matrices, factor, basis) and, when `held_outputs`, every
/// sensor's FRF and impulse response. A streamed simulation is checked again once its basis
/// size is known ([`streamed_bytes`]).
pub fn memory_estimate(model: &Model, held_outputs: bool) -> f64 {
    let size = ModelSize::of(model);
    size.system_bytes()
        + if held_outputs {
            size.held_output_bytes()
        } else {
            0.0
        }
}

/// Refuses a force that reaches no free dof — zero, or applied on a pinned edge's line — whose
/// simulation is a recording set of exact zeros (it was written with exit 0).
fn check_force(sys: &FeSystem) -> Result<(), SimError> {
    if sys.force.iter().all(|&f| f == 0.0) {
        return Err(SimError::InvalidValue {
            key: "excitation".into(),
            message: "expected a force on the free structure, got none: the force is 0 or acts on a pinned edge only (every response would be zero)".into(),
        });
    }
    Ok(())
}

/// Refuses `model` when `estimate` bytes exceed the process memory budget.
fn check_budget(model: &Model, estimate: f64) -> Result<(), SimError> {
    super::limits::check_budget(model, "simulating", estimate)
}

/// Simulates `model`: assembly, modes (if the method needs them), FRFs over 0…fmax at df,
/// impulse responses.
pub fn simulate(model: &Model, opts: &SimulateOptions) -> Result<SimulationResult, SimError> {
    check_budget(model, memory_estimate(model, true))?;
    let t0 = Instant::now();
    let sys = assemble(model)?;
    check_force(&sys)?;
    let assembly_s = t0.elapsed().as_secs_f64();
    let mut r = simulate_system(&sys, None, model.output.fmax, model.output.df, opts)?;
    r.timings.assembly_s = assembly_s;
    r.excitation = Some(model.excitation.clone());
    Ok(r)
}

/// The frequency responses as a method leaves them: held per sensor (direct) or factored.
enum FrfParts {
    Held(Frf),
    Factored(FactoredFrf),
}

impl FrfParts {
    fn into_frf(self) -> Frf {
        match self {
            FrfParts::Held(f) => f,
            FrfParts::Factored(f) => f.to_frf(),
        }
    }
}

/// Simulates an assembled system; `modes` may be given (else computed as the method needs).
pub fn simulate_system(
    sys: &FeSystem,
    modes: Option<&Modes>,
    fmax_hz: f64,
    df_hz: f64,
    opts: &SimulateOptions,
) -> Result<SimulationResult, SimError> {
    let pb = progress_bar(opts.progress, 3);
    let (parts, modes_used, mut timings) = frf_parts(sys, modes, fmax_hz, df_hz, opts, &pb)?;
    let frf = parts.into_frf();
    pb.set_message("impulse responses");
    let t = Instant::now();
    let irs = impulse_responses(&frf, fmax_hz, opts.snr_db, opts.seed)?;
    timings.impulse_s = t.elapsed().as_secs_f64();
    pb.finish_and_clear();
    Ok(SimulationResult {
        fs_hz: 2.0 * fmax_hz,
        frf,
        impulse_responses: irs,
        sensors: sys.sensors.clone(),
        excitation: None,
        modes_used,
        timings,
    })
}

/// A simulation served as a stream of impulse responses ([`simulate_stream`]).
pub struct StreamedSimulation {
    /// The impulse responses of every sensor, block by block.
    pub source: SimulatedSource,
    /// Sample rate, Hz (= 2 fmax).
    pub fs_hz: f64,
    /// Number of FRF lines (0, df, …, fmax).
    pub n_frequencies: usize,
    /// The sensors (ids, positions).
    pub sensors: Vec<SensorWeights>,
    /// The excitation of the model.
    pub excitation: Excitation,
    /// How many modes the method used (0 for the direct method).
    pub modes_used: usize,
    /// Phase times (`impulse_s`: the basis-vector signals and the noise scan).
    pub timings: Timings,
}

/// Simulates `model` like [`simulate`] but leaves the impulse responses as a [`Source`]: the
/// fast and truncated methods never hold sensors × samples (a recording set of any sensor grid
/// is written block by block); the direct method holds them, within the memory budget.
///
/// [`Source`]: crate::source::Source
pub fn simulate_stream(
    model: &Model,
    opts: &SimulateOptions,
) -> Result<StreamedSimulation, SimError> {
    let held = opts.method == Method::Direct;
    check_budget(model, memory_estimate(model, held))?;
    let t0 = Instant::now();
    let sys = assemble(model)?;
    check_force(&sys)?;
    let assembly_s = t0.elapsed().as_secs_f64();
    let (fmax_hz, df_hz) = (model.output.fmax, model.output.df);
    let pb = progress_bar(opts.progress, 3);
    let (parts, modes_used, mut timings) = frf_parts(&sys, None, fmax_hz, df_hz, opts, &pb)?;
    timings.assembly_s = assembly_s;
    pb.set_message("impulse responses");
    let t = Instant::now();
    let (source, n_frequencies) = match parts {
        FrfParts::Held(frf) => {
            let irs = impulse_responses(&frf, fmax_hz, opts.snr_db, opts.seed)?;
            let info = crate::source::SignalInfo {
                sample_rate_hz: 2.0 * fmax_hz,
                channel_names: frf.sensor_ids.clone(),
            };
            let n = frf.frequencies_hz.len();
            (SimulatedSource::held(info, irs)?, n)
        }
        FrfParts::Factored(f) => {
            let n = f.frequencies_hz.len();
            let samples = 2 * (n - 1);
            crate::budget::check(
                &format!(
                    "streaming {} sensors from {} basis vectors",
                    f.n_sensors(),
                    f.basis_size()
                ),
                streamed_bytes(f.n_sensors(), f.basis_size(), samples, STREAM_BLOCK_FRAMES),
            )
            .map_err(|e| SimError::InvalidValue {
                key: "model size".into(),
                message: e.to_string(),
            })?;
            let src = SimulatedSource::from_factored(&f, fmax_hz, opts.snr_db, opts.seed)?;
            (src, n)
        }
    };
    timings.impulse_s = t.elapsed().as_secs_f64();
    pb.finish_and_clear();
    Ok(StreamedSimulation {
        source,
        fs_hz: 2.0 * fmax_hz,
        n_frequencies,
        sensors: sys.sensors.clone(),
        excitation: model.excitation.clone(),
        modes_used,
        timings,
    })
}

/// Sample frames per block that callers of [`simulate_stream`] are expected to read.
pub const STREAM_BLOCK_FRAMES: usize = 4096;

/// The FRF of `sys` by the method of `opts`, with the modes it used and the phase times.
fn frf_parts(
    sys: &FeSystem,
    modes: Option<&Modes>,
    fmax_hz: f64,
    df_hz: f64,
    opts: &SimulateOptions,
    pb: &indicatif::ProgressBar,
) -> Result<(FrfParts, usize, Timings), SimError> {
    let freqs = frequency_grid(fmax_hz, df_hz)?;
    let mut timings = Timings::default();
    let mut owned = None;
    let mut get_modes = |req: ModeRequest, timings: &mut Timings| -> Result<(), SimError> {
        if modes.is_none() {
            pb.set_message("modes");
            let t = Instant::now();
            owned = Some(lowest_modes(sys, req)?);
            timings.modes_s = t.elapsed().as_secs_f64();
        }
        Ok(())
    };
    let (parts, modes_used) = match &opts.method {
        Method::Direct => {
            pb.set_message("direct FRF");
            let t = Instant::now();
            let f = direct_frf(sys, &freqs)?;
            timings.frf_s = t.elapsed().as_secs_f64();
            (FrfParts::Held(f), 0)
        }
        Method::Fast => {
            if !(opts.mode_cutoff_factor.is_finite() && opts.mode_cutoff_factor >= 1.0) {
                return Err(SimError::InvalidValue {
                    key: "mode cut-off factor".into(),
                    message: format!("expected ≥ 1, got {}", opts.mode_cutoff_factor),
                });
            }
            let cutoff_hz = opts.mode_cutoff_factor * fmax_hz;
            if modes.is_none() {
                if let Some(done) = interface_form(sys, &freqs, cutoff_hz, &mut timings, pb)? {
                    return Ok(done);
                }
                pb.set_message("modes (Craig–Bampton)");
                let t = Instant::now();
                if let Some(cb) = craig_bampton_vectors(sys, fmax_hz, cutoff_hz)? {
                    timings.modes_s = t.elapsed().as_secs_f64();
                    let f = reduce_and_solve(&freqs, &mut timings, pb, || {
                        ReducedModel::craig_bampton(sys, &cb)
                    })?;
                    pb.inc(1);
                    let used = cb.boundary_modes.frequencies_hz.len()
                        + cb.interior_modes.frequencies_hz.len();
                    return Ok((FrfParts::Factored(f), used, timings));
                }
            }
            get_modes(ModeRequest::BelowHz(cutoff_hz), &mut timings)?;
            let m = modes
                .or(owned.as_ref())
                .ok_or_else(|| SimError::Eigen("no modes".into()))?;
            let f = reduce_and_solve(&freqs, &mut timings, pb, || {
                ReducedModel::build(
                    sys,
                    &m.frequencies_hz,
                    m.shapes.as_ref(),
                    BasisOptions {
                        mode_residuals_below_hz: fmax_hz,
                        ..BasisOptions::default()
                    },
                )
            })?;
            (FrfParts::Factored(f), m.frequencies_hz.len())
        }
        Method::Truncated(keep) => {
            let highest = keep.iter().copied().max().unwrap_or(0);
            get_modes(ModeRequest::Count(highest.max(1)), &mut timings)?;
            let m = modes
                .or(owned.as_ref())
                .ok_or_else(|| SimError::Eigen("no modes".into()))?;
            pb.inc(2);
            pb.set_message("truncated FRF");
            let t = Instant::now();
            let damping = match &opts.modal_damping_ratios {
                Some(d) => ModalDamping::Ratios(d.clone()),
                None => ModalDamping::StrainEnergy,
            };
            let f = truncated_factored_frf(
                sys,
                &m.frequencies_hz,
                m.shapes.as_ref(),
                keep,
                &damping,
                &freqs,
            )?;
            timings.frf_s = t.elapsed().as_secs_f64();
            (FrfParts::Factored(f), keep.len())
        }
    };
    pb.inc(1);
    Ok((parts, modes_used, timings))
}

/// The fast FRF in the interface form ([`super::interface`]) when the system has its structure
/// (viscoelastic regions with interiors, no Rayleigh damping, one constant loss factor), with
/// the modes it used; `None` otherwise.
fn interface_form(
    sys: &FeSystem,
    freqs: &[f64],
    cutoff_hz: f64,
    timings: &mut Timings,
    pb: &indicatif::ProgressBar,
) -> Result<Option<(FrfParts, usize, Timings)>, SimError> {
    let Ok(part) = partition(sys, DENSE_INTERIOR_MAX_DOFS) else {
        return Ok(None);
    };
    pb.set_message("modes (interface form)");
    let Some((model, built, _)) = build_interface(sys, &part, cutoff_hz, false)? else {
        return Ok(None);
    };
    timings.modes_s = built.modes_s;
    timings.reduction_s = built.reduction_s;
    pb.inc(2);
    pb.set_message("fast FRF (interface form)");
    let t = Instant::now();
    let f = model.factored_frf(freqs)?;
    timings.frf_s = t.elapsed().as_secs_f64();
    timings.frf_solve = Some(f.solve);
    pb.inc(1);
    let used = model.basis_size() - model.interface_dofs;
    Ok(Some((FrfParts::Factored(f), used, timings.clone())))
}

/// The reduction `build` (timed as `reduction_s`) and its fast FRF (timed as `frf_s`), with
/// the progress bar's phases.
fn reduce_and_solve(
    freqs: &[f64],
    timings: &mut Timings,
    pb: &indicatif::ProgressBar,
    build: impl FnOnce() -> Result<ReducedModel, FrfError>,
) -> Result<FactoredFrf, SimError> {
    pb.inc(1);
    pb.set_message("reduction");
    let t = Instant::now();
    let red = build()?;
    timings.reduction_s = t.elapsed().as_secs_f64();
    pb.inc(1);
    pb.set_message("fast FRF");
    let t = Instant::now();
    let f = red.factored_frf(freqs, ReducedSolve::Auto)?;
    timings.frf_s = t.elapsed().as_secs_f64();
    timings.frf_solve = Some(f.solve);
    Ok(f)
}

/// Impulse response of every sensor from its accelerance, with optional peak-SNR noise
/// (channel k seeded with `seed + k`). Channels are split over two threads.
pub fn impulse_responses(
    frf: &Frf,
    fmax_hz: f64,
    snr_db: Option<f64>,
    seed: u64,
) -> Result<Vec<Vec<f64>>, SimError> {
    check_snr_db(snr_db)?;
    let ns = frf.n_sensors();
    let one = |k: usize| -> Result<Vec<f64>, SimError> {
        let mut h = impulse_response(&frf.accelerance(k), fmax_hz)?;
        if let Some(snr) = snr_db {
            let peak = h.iter().fold(0.0f64, |a, x| a.max(x.abs()));
            let (sigma, mut g) = channel_noise(peak, snr, seed, k);
            h.iter_mut().for_each(|x| *x += sigma * g.next_gaussian());
        }
        Ok(h)
    };
    let half = ns.div_ceil(2);
    let (a, b) = std::thread::scope(|sc| {
        let ha = sc.spawn(|| (0..half).map(one).collect::<Result<Vec<_>, _>>());
        let b = (half..ns).map(one).collect::<Result<Vec<_>, _>>();
        (ha.join(), b)
    });
    let mut out = a.map_err(|_| SimError::Eigen("impulse-response worker panicked".into()))??;
    out.extend(b?);
    Ok(out)
}

/// Refuses a peak SNR that is not a finite number of dB.
pub(crate) fn check_snr_db(snr_db: Option<f64>) -> Result<(), SimError> {
    match snr_db {
        Some(s) if !s.is_finite() => Err(SimError::InvalidValue {
            key: "snr-db".into(),
            message: format!("expected a finite dB value, got {s}"),
        }),
        _ => Ok(()),
    }
}

/// The noise of channel `k` at a peak SNR: σ = peak · 10^(−snr/20) and its generator, seeded
/// with `seed + k` (the held and the streamed simulations draw the same noise).
pub(crate) fn channel_noise(peak: f64, snr_db: f64, seed: u64, k: usize) -> (f64, GaussianNoise) {
    (
        peak * 10f64.powf(-snr_db / 20.0),
        GaussianNoise::new(seed.wrapping_add(k as u64)),
    )
}

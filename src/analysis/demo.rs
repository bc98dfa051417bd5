//! The built-in demonstration (`dampscope demo`): the report's reference cases on synthetic
//! decays (eq. 4.5) and on the FE plate, analysed by the same chain as recordings, with the
//! truth and the report's numbers beside each result.

use crate::decay::estimate::EstimateSettings;
use crate::decay::{DecayEstimate, EvaluationRange};
use crate::error::Result;
use crate::frontend::bands::Band;
use crate::frontend::stft::{StftSettings, DEFAULT_WINDOW_MS};
use crate::pipeline::analyze_decay;
use crate::pipeline::segment::onset::find_onset;
use crate::pipeline::segment::DEFAULT_ONSET_LEVEL_DB;
use crate::plan::{FrontEndKind, FrontEndSpec};
use crate::sim::model::Model;
use crate::sim::simulate::{simulate, Method, SimulateOptions};
use crate::source::synth::{synthesize, Mode, SynthSpec};

/// Sample rate of the synthetic cases, Hz.
pub const DEMO_FS_HZ: f64 = 4000.0;

/// One synthetic case: modes, how they are analysed, the truth and the report's number.
#[derive(Clone, Debug)]
pub struct DemoCase {
    /// What the case shows.
    pub name: &'static str,
    /// The front end.
    pub front_end: FrontEndKind,
    /// The decaying sines.
    pub modes: Vec<Mode>,
    /// Record length, s.
    pub seconds: f64,
    /// STFT window, ms (unused by the banks).
    pub window_ms: f64,
    /// Band edges, Hz.
    pub band: (f64, f64),
    /// Evaluation range.
    pub range: EvaluationRange,
    /// The true damping ratio, %.
    pub truth_pct: f64,
    /// What the report says about it.
    pub report: &'static str,
}

fn mode(f: f64, d: f64, a: f64, psi: f64) -> Mode {
    Mode {
        frequency_hz: f,
        damping_ratio: d,
        amplitude: a,
        phase_deg: psi,
    }
}

/// The synthetic cases: single modes (55, 56.84, 400, 800 Hz), the three sines of Table 4.1,
/// beating modes 7 + 8 over their relative phase, and the Goyder bank.
pub fn demo_cases() -> Vec<DemoCase> {
    let mut cases = vec![
        DemoCase {
            name: "single mode 55 Hz",
            front_end: FrontEndKind::Stft,
            modes: vec![mode(55.0, 0.025, 1.0, 0.0)],
            seconds: 4.0,
            window_ms: DEFAULT_WINDOW_MS,
            band: (52.5, 57.5),
            range: EvaluationRange::T30,
            truth_pct: 2.5,
            report: "",
        },
        DemoCase {
            name: "plate mode 7 alone (56.84 Hz) in the 55 Hz band",
            front_end: FrontEndKind::Stft,
            modes: vec![mode(56.84, 0.025, 1.0, 0.0)],
            seconds: 4.0,
            window_ms: DEFAULT_WINDOW_MS,
            band: (52.5, 57.5),
            range: EvaluationRange::T30,
            truth_pct: 2.5,
            report: "2.6 uncorrected (Fig. 3.6)",
        },
        DemoCase {
            name: "single mode 400 Hz, 200 ms window",
            front_end: FrontEndKind::Stft,
            modes: vec![mode(400.0, 0.01, 1.0, 0.0)],
            seconds: 2.0,
            window_ms: DEFAULT_WINDOW_MS,
            band: (380.0, 420.0),
            range: EvaluationRange::T20,
            truth_pct: 1.0,
            report: "too few frames (sec. 3.5)",
        },
        DemoCase {
            name: "single mode 400 Hz, 25 ms window",
            front_end: FrontEndKind::Stft,
            modes: vec![mode(400.0, 0.01, 1.0, 0.0)],
            seconds: 2.0,
            window_ms: 25.0,
            band: (380.0, 420.0),
            range: EvaluationRange::T20,
            truth_pct: 1.0,
            report: "",
        },
        DemoCase {
            name: "three sines 170/200/230 Hz (Table 4.1), 10 ms",
            front_end: FrontEndKind::Stft,
            modes: vec![
                mode(170.0, 0.025, 1.0, 0.0),
                mode(200.0, 0.025, 1.0, 0.0),
                mode(230.0, 0.025, 1.0, 0.0),
            ],
            seconds: 2.0,
            window_ms: 10.0,
            band: (150.0, 250.0),
            range: EvaluationRange::T20,
            truth_pct: 2.5,
            report: "D_eq,ref = 2.16",
        },
    ];
    for (k, psi) in [0.0, 90.0, 180.0, 270.0].iter().enumerate() {
        cases.push(DemoCase {
            name: [
                "modes 7+8 beating, relative phase 0°",
                "modes 7+8 beating, relative phase 90°",
                "modes 7+8 beating, relative phase 180°",
                "modes 7+8 beating, relative phase 270°",
            ][k],
            front_end: FrontEndKind::Stft,
            modes: vec![mode(56.84, 0.005, 1.0, 0.0), mode(57.51, 0.005, 1.0, *psi)],
            seconds: 16.0,
            window_ms: DEFAULT_WINDOW_MS,
            band: (52.5, 62.5),
            range: EvaluationRange::T20,
            truth_pct: 0.5,
            report: "0.35…0.73 over phase (METHODS §1)",
        });
    }
    for (f, d) in [(400.0, 0.01), (800.0, 0.02)] {
        cases.push(DemoCase {
            name: if f < 500.0 {
                "single mode 400 Hz, Goyder bank (reversed)"
            } else {
                "single mode 800 Hz, Goyder bank (reversed)"
            },
            front_end: FrontEndKind::Goyder,
            modes: vec![mode(f, d, 1.0, 0.0)],
            seconds: 2.0,
            window_ms: 0.0,
            band: (f - 20.0, f + 20.0),
            range: EvaluationRange::T20,
            truth_pct: 100.0 * d,
            report: "filter bank (sec. 3.5 outlook)",
        });
    }
    cases
}

/// Analyses one synthetic case at [`DEMO_FS_HZ`].
pub fn run_case(case: &DemoCase) -> Result<DecayEstimate> {
    let x = synthesize(&SynthSpec {
        modes: case.modes.clone(),
        sample_rate_hz: DEMO_FS_HZ,
        duration_s: case.seconds,
        snr_db: None,
        seed: 1,
    });
    let band = Band::new(case.band.0, case.band.1)?;
    let spec = FrontEndSpec {
        kind: case.front_end,
        stft: StftSettings {
            window_ms: case.window_ms,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut fe = spec.build(DEMO_FS_HZ, &[band])?;
    let settings = EstimateSettings {
        range: case.range,
        ..Default::default()
    };
    Ok(analyze_decay(&x, fe.as_mut(), &settings).remove(0))
}

/// One FE plate case: mean D over the sensors that give one.
#[derive(Clone, Debug)]
pub struct PlateCase {
    /// Which modes the model keeps.
    pub name: &'static str,
    /// Sensors with an estimate.
    pub sensors: usize,
    /// Mean D, fraction (`None`: no sensor gave one).
    pub mean_d: Option<f64>,
    /// Mean frequency-corrected D, fraction.
    pub mean_d_corrected: Option<f64>,
    /// The report's number.
    pub report: &'static str,
}

/// The FE plate of the report reduced to mode 7, and to modes 7 and 8 (section 3.2): mean D
/// over the sensors that move on the model's 33 × 49 grid, 55 Hz band, 200 ms STFT, T30.
pub fn plate_cases() -> Result<Vec<PlateCase>> {
    let model = Model::reference_plate();
    let mut out = Vec::new();
    for (name, keep, report) in [
        ("mode 7 only (eq. 2.7)", vec![7], "2.6 (Fig. 3.6)"),
        ("modes 7 + 8", vec![7, 8], "2.7 (Fig. 3.7)"),
    ] {
        let sim = simulate(
            &model,
            &SimulateOptions {
                method: Method::Truncated(keep),
                ..Default::default()
            },
        )
        .map_err(|e| crate::error::Error::setting("model", e.to_string()))?;
        let band = Band::new(52.5, 57.5)?;
        let settings = EstimateSettings::default();
        let spec = FrontEndSpec::default();
        let (mut n, mut sum, mut sum_c) = (0, 0.0, 0.0);
        for h in &sim.impulse_responses {
            let Some(start) = find_onset(h, DEFAULT_ONSET_LEVEL_DB) else {
                continue;
            };
            let mut fe = spec.build(sim.fs_hz, &[band])?;
            let est = analyze_decay(&h[start..], fe.as_mut(), &settings).remove(0);
            if let (Some(d), Some(dc)) = (est.damping_ratio, est.damping_ratio_corrected) {
                n += 1;
                sum += d;
                sum_c += dc;
            }
        }
        out.push(PlateCase {
            name,
            sensors: n,
            mean_d: (n > 0).then(|| sum / n as f64),
            mean_d_corrected: (n > 0).then(|| sum_c / n as f64),
            report,
        });
    }
    Ok(out)
}

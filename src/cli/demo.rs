//! `dampscope demo`: the report's reference cases on built-in synthetic decays, analysed by the
//! same pipeline as recordings, with the truth and the report's numbers side by side.

use super::analyze::{make_front_end, FrontEndChoice};
use super::bands_arg::BandArgs;
use super::compare::DirectionArg;
use crate::decay::estimate::EstimateSettings;
use crate::decay::{DecayEstimate, EvaluationRange};
use crate::frontend::bands::Band;
use crate::frontend::onset::find_onset;
use crate::frontend::stft::{StftFrontEnd, StftSettings};
use crate::pipeline::analyze_decay;
use crate::sim::model::Model;
use crate::sim::simulate::{simulate, Method, SimulateOptions};
use crate::source::synth::{synthesize, Mode, SynthSpec};

/// Options of `dampscope demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {}

/// One demonstration case.
struct Case {
    name: &'static str,
    front_end: FrontEndChoice,
    modes: Vec<Mode>,
    seconds: f64,
    window_ms: f64,
    band: (f64, f64),
    range: EvaluationRange,
    truth_pct: f64,
    report: &'static str,
}

fn mode(f: f64, d: f64, a: f64, psi: f64) -> Mode {
    Mode {
        frequency_hz: f,
        damping_ratio: d,
        amplitude: a,
        phase_deg: psi,
    }
}

fn estimate(case: &Case, fs: f64) -> anyhow::Result<DecayEstimate> {
    let x = synthesize(&SynthSpec {
        modes: case.modes.clone(),
        sample_rate_hz: fs,
        duration_s: case.seconds,
        snr_db: None,
        seed: 1,
    });
    let band = Band::new(case.band.0, case.band.1)?;
    let band_args = BandArgs {
        window_ms: case.window_ms,
        ..BandArgs::default()
    };
    let mut fe = make_front_end(
        case.front_end,
        &band_args,
        DirectionArg::Reversed,
        fs,
        &[band],
    )?;
    let settings = EstimateSettings {
        range: case.range,
        ..Default::default()
    };
    Ok(analyze_decay(&x, &mut *fe, &settings).remove(0))
}

fn pct(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |d| format!("{:.3}", 100.0 * d))
}

/// Runs the demonstration and prints its table.
pub fn run(_args: &DemoArgs) -> anyhow::Result<()> {
    let fs = 4000.0;
    let mut cases = vec![
        Case {
            name: "single mode 55 Hz",
            front_end: FrontEndChoice::Stft,
            modes: vec![mode(55.0, 0.025, 1.0, 0.0)],
            seconds: 4.0,
            window_ms: 200.0,
            band: (52.5, 57.5),
            range: EvaluationRange::T30,
            truth_pct: 2.5,
            report: "",
        },
        Case {
            name: "plate mode 7 alone (56.84 Hz) in the 55 Hz band",
            front_end: FrontEndChoice::Stft,
            modes: vec![mode(56.84, 0.025, 1.0, 0.0)],
            seconds: 4.0,
            window_ms: 200.0,
            band: (52.5, 57.5),
            range: EvaluationRange::T30,
            truth_pct: 2.5,
            report: "2.6 uncorrected (Fig. 3.6)",
        },
        Case {
            name: "single mode 400 Hz, 200 ms window",
            front_end: FrontEndChoice::Stft,
            modes: vec![mode(400.0, 0.01, 1.0, 0.0)],
            seconds: 2.0,
            window_ms: 200.0,
            band: (380.0, 420.0),
            range: EvaluationRange::T20,
            truth_pct: 1.0,
            report: "too few frames (sec. 3.5)",
        },
        Case {
            name: "single mode 400 Hz, 25 ms window",
            front_end: FrontEndChoice::Stft,
            modes: vec![mode(400.0, 0.01, 1.0, 0.0)],
            seconds: 2.0,
            window_ms: 25.0,
            band: (380.0, 420.0),
            range: EvaluationRange::T20,
            truth_pct: 1.0,
            report: "",
        },
        Case {
            name: "three sines 170/200/230 Hz (Table 4.1), 10 ms",
            front_end: FrontEndChoice::Stft,
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
        cases.push(Case {
            name: [
                "modes 7+8 beating, relative phase 0°",
                "modes 7+8 beating, relative phase 90°",
                "modes 7+8 beating, relative phase 180°",
                "modes 7+8 beating, relative phase 270°",
            ][k],
            front_end: FrontEndChoice::Stft,
            modes: vec![mode(56.84, 0.005, 1.0, 0.0), mode(57.51, 0.005, 1.0, *psi)],
            seconds: 16.0,
            window_ms: 200.0,
            band: (52.5, 62.5),
            range: EvaluationRange::T20,
            truth_pct: 0.5,
            report: "0.35…0.73 over phase (METHODS §1)",
        });
    }
    for (f, d) in [(400.0, 0.01), (800.0, 0.02)] {
        cases.push(Case {
            name: if f < 500.0 {
                "single mode 400 Hz, Goyder bank (reversed)"
            } else {
                "single mode 800 Hz, Goyder bank (reversed)"
            },
            front_end: FrontEndChoice::Goyder,
            modes: vec![mode(f, d, 1.0, 0.0)],
            seconds: 2.0,
            window_ms: 0.0,
            band: (f - 20.0, f + 20.0),
            range: EvaluationRange::T20,
            truth_pct: 100.0 * d,
            report: "filter bank (sec. 3.5 outlook)",
        });
    }
    println!(
        "dampscope demo: synthetic decays (report eq. 4.5), fs = {fs} Hz, STFT Hann 50 % overlap or Goyder bank"
    );
    println!(
        "{:<48} {:>7} {:>11} {:>5} {:>7} {:>7} {:>9}  {:<22} report",
        "case", "window", "band Hz", "range", "true %", "D %", "D_corr %", "flags"
    );
    for case in &cases {
        let est = estimate(case, fs)?;
        let flags: Vec<&str> = est.flags.iter().map(|f| f.as_str()).collect();
        println!(
            "{:<48} {:>7} {:>5}–{:<5} {:>5} {:>7.3} {:>7} {:>9}  {:<22} {}",
            case.name,
            if case.front_end == FrontEndChoice::Stft {
                format!("{}ms", case.window_ms)
            } else {
                "goyder".to_string()
            },
            case.band.0,
            case.band.1,
            case.range.to_string(),
            case.truth_pct,
            pct(est.damping_ratio),
            pct(est.damping_ratio_corrected),
            flags.join(";"),
            case.report
        );
    }
    plate_cases()?;
    Ok(())
}

/// The FE plate of the report reduced to mode 7, and to modes 7 and 8 (section 3.2): mean D
/// over the sensors that move on the model's 33 × 49 grid (`dampscope map` does the same with
/// a figure), 55 Hz band, 200 ms STFT, T30.
fn plate_cases() -> anyhow::Result<()> {
    let model = Model::reference_plate();
    println!();
    println!("FE plate (report sec. 3.1: 2 × 3 × 0.02 m aluminium, 32 × 48 × 2 C3D8I hexahedra, g = 5 %), 55 Hz band, 200 ms STFT, T30");
    println!(
        "{:<34} {:>8} {:>9} {:>10}  report",
        "model", "sensors", "mean D %", "mean D_c %"
    );
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
        )?;
        let band = Band::new(52.5, 57.5)?;
        let settings = EstimateSettings::default();
        let (mut n, mut sum, mut sum_c) = (0, 0.0, 0.0);
        for h in &sim.impulse_responses {
            let Some(start) = find_onset(h, 20.0) else {
                continue;
            };
            let mut fe = StftFrontEnd::new(StftSettings::default(), sim.fs_hz, &[band])?;
            let est = analyze_decay(&h[start..], &mut fe, &settings).remove(0);
            if let (Some(d), Some(dc)) = (est.damping_ratio, est.damping_ratio_corrected) {
                n += 1;
                sum += d;
                sum_c += dc;
            }
        }
        println!(
            "{:<34} {:>8} {:>9.3} {:>10.3}  {}",
            name,
            n,
            100.0 * sum / n.max(1) as f64,
            100.0 * sum_c / n.max(1) as f64,
            report
        );
    }
    Ok(())
}

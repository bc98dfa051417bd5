//! `dampscope demo`: prints the built-in demonstration ([`crate::analysis::demo`]).

use crate::analysis::demo::{demo_cases, plate_cases, run_case, DEMO_FS_HZ};
use crate::plan::FrontEndKind;

/// Run the built-in demonstration: the report's reference cases, no input files needed.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {}

fn pct(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |d| format!("{:.3}", 100.0 * d))
}

/// Runs the demonstration and prints its table.
pub fn run(_args: &DemoArgs) -> anyhow::Result<()> {
    println!(
        "dampscope demo: synthetic decays (report eq. 4.5), fs = {DEMO_FS_HZ} Hz, STFT Hann 50 % overlap or Goyder bank"
    );
    println!(
        "{:<48} {:>7} {:>11} {:>5} {:>7} {:>7} {:>9}  {:<22} report",
        "case", "window", "band Hz", "range", "true %", "D %", "D_corr %", "flags"
    );
    for case in &demo_cases() {
        let est = run_case(case)?;
        let flags: Vec<&str> = est.flags.iter().map(|f| f.as_str()).collect();
        println!(
            "{:<48} {:>7} {:>5}–{:<5} {:>5} {:>7.3} {:>7} {:>9}  {:<22} {}",
            case.name,
            if case.front_end == FrontEndKind::Stft {
                format!("{}ms", case.window_ms)
            } else {
                case.front_end.name().to_string()
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
    println!();
    println!("FE plate (report sec. 3.1: 2 × 3 × 0.02 m aluminium, 32 × 48 × 2 C3D8I hexahedra, g = 5 %), 55 Hz band, 200 ms STFT, T30");
    println!(
        "{:<34} {:>8} {:>9} {:>10}  report",
        "model", "sensors", "mean D %", "mean D_c %"
    );
    for c in plate_cases()? {
        println!(
            "{:<34} {:>8} {:>9} {:>10}  {}",
            c.name,
            c.sensors,
            pct(c.mean_d),
            pct(c.mean_d_corrected),
            c.report
        );
    }
    Ok(())
}

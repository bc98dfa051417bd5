//! `dampscope modes`: natural frequencies of a plate model as CSV `mode,frequency_hz`.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use crate::sim::assembly::assemble;
use crate::sim::eigen::{check_modes, lowest_modes_with, EigenOptions, ModeRequest};
use crate::sim::model::Model;

/// Natural frequencies of the finite-element plate model (CSV `mode,frequency_hz`).
#[derive(Debug, Clone, clap::Args)]
pub struct ModesArgs {
    /// Plate model (TOML, FORMATS.md §3); default: the report's reference plate.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Compute the lowest N modes.
    #[arg(long, conflicts_with = "fmax")]
    pub count: Option<usize>,
    /// Compute every mode below this frequency, Hz (default: the model's `output.fmax`).
    #[arg(long)]
    pub fmax: Option<f64>,
    /// Also the damped poles: columns damped_frequency_hz and damping_ratio of each mode (the
    /// eigenvalues of the damped system reduced to the modes below twice the range and residual
    /// vectors; exact for a damped patch, where modal strain energy is first-order only).
    #[arg(long)]
    pub damping: bool,
    /// Write the CSV here instead of standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print assembly / factorisation / Lanczos times, residuals and peak memory to stderr.
    #[arg(long)]
    pub timings: bool,
}

/// Runs `dampscope modes`.
pub fn run(args: &ModesArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let model = Model::load_or_reference(args.model.as_deref())?;
    let request = match (args.count, args.fmax) {
        (Some(n), _) => ModeRequest::Count(n),
        (None, Some(f)) => ModeRequest::BelowHz(f),
        (None, None) => ModeRequest::BelowHz(model.output.fmax),
    };
    super::warn_all(&crate::sim::mesh::Mesh::new(&model).warnings);
    let system = assemble(&model)?;
    let t_assembly = t0.elapsed().as_secs_f64();
    let (modes, report) = lowest_modes_with(&system, request, &EigenOptions::default())?;
    // Whether the mesh resolves the highest mode found (known only now for `--count`).
    let highest_hz = modes.frequencies_hz.last().copied().unwrap_or(0.0);
    super::warn_all(crate::sim::resolution::resolution_warning(&model, highest_hz).as_slice());
    let text = if args.damping {
        let poles = crate::sim::poles::lowest_damped_poles(
            &system,
            modes.frequencies_hz.len(),
            highest_hz,
            &EigenOptions::default(),
        )?;
        let mut text = String::from("mode,frequency_hz,damped_frequency_hz,damping_ratio\n");
        for (i, (f, p)) in modes.frequencies_hz.iter().zip(&poles).enumerate() {
            text.push_str(&format!(
                "{},{f:.6},{:.6},{:.7}\n",
                i + 1,
                p.damped_frequency_hz,
                p.damping_ratio
            ));
        }
        text
    } else {
        let mut text = String::from("mode,frequency_hz\n");
        for (i, f) in modes.frequencies_hz.iter().enumerate() {
            text.push_str(&format!("{},{f:.6}\n", i + 1));
        }
        text
    };
    match &args.out {
        Some(path) => crate::output::write_text_file(path, &text)?,
        None => std::io::stdout().lock().write_all(text.as_bytes())?,
    }
    if args.timings {
        let (res, orth) = check_modes(&system, &modes)?;
        eprintln!(
            "modes: {} modes, {} free dofs, {} Lanczos steps",
            modes.frequencies_hz.len(),
            system.n_free,
            report.steps
        );
        eprintln!(
            "times: assembly {t_assembly:.3} s, factorisation {:.3} s, Lanczos {:.3} s, total {:.3} s",
            report.factorisation_s,
            report.lanczos_s,
            t0.elapsed().as_secs_f64()
        );
        eprintln!(
            "  of Lanczos: solves {:.3} s, re-orthogonalisation {:.3} s, tridiagonal {:.3} s, \
             Ritz vectors {:.3} s",
            report.solve_s, report.reorth_s, report.tridiagonal_s, report.ritz_s
        );
        eprintln!("quality: max relative residual {res:.2e}, max |Phi^T M Phi - I| {orth:.2e}");
        if let Some(hwm) = crate::budget::peak_memory_kib() {
            eprintln!("peak memory (VmHWM): {:.1} MiB", hwm as f64 / 1024.0);
        }
    }
    Ok(())
}

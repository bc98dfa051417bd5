//! `dampscope resynth --model M.toml --global DIR/global.csv --out DIR`: applies the global
//! damping per band (from `dampscope map`) to the model's undamped modes as modal structural
//! damping and compares the re-synthesised FRF with the model's own, per band (report section
//! 4.2.2, eqs. 4.6–4.8).
//!
//! Writes `resynth.csv` (per band: D_global, the model's mean modal D there, ε at the driving
//! point and over all sensors), `modes.csv` (per mode: model vs assigned D),
//! `frf_driving_point.csv` and `resynth.png`; prints the band table.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

use crate::analysis::resynthesis::{resynthesize_model, BandDamping, DEFAULT_MODE_CUTOFF_FACTOR};
use crate::output::write_csv_file;
use crate::sim::model::Model;

/// Re-synthesise the model's FRF from the global damping per band and compare (eq. 4.8).
#[derive(Debug, clap::Args)]
pub struct ResynthArgs {
    /// Plate model (TOML) whose FRF is re-synthesised; default: the report's reference plate.
    #[arg(long, value_name = "PATH")]
    pub model: Option<PathBuf>,
    /// The global damping per band: a `global.csv` written by `dampscope map` (columns
    /// f_lo_hz, f_hi_hz, f_center_hz, mean_d; bands without a mean are skipped).
    #[arg(long, value_name = "FILE")]
    pub global: PathBuf,
    /// Highest frequency, Hz (default: the model's fmax).
    #[arg(long, value_name = "HZ", value_parser = super::args::parse_positive_hz)]
    pub fmax: Option<f64>,
    /// Modes below this × fmax carry the re-synthesis (the rest enter as a static residual,
    /// which misses their dynamic amplification 1/(1 − (f/f_i)²): 3 keeps that below 12.5 %
    /// of an already small residual).
    #[arg(long, default_value_t = DEFAULT_MODE_CUTOFF_FACTOR)]
    pub mode_cutoff_factor: f64,
    /// Leave out the residual flexibility of the modes above the kept ones (eq. 4.6 exactly
    /// as the report writes it; ε at the driving point then mostly measures the truncation).
    #[arg(long)]
    pub no_residual: bool,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

#[derive(serde::Deserialize)]
struct GlobalRow {
    f_lo_hz: f64,
    f_hi_hz: f64,
    f_center_hz: f64,
    mean_d: Option<f64>,
}

/// Reads the bands with a global damping ratio from a `global.csv`; warns about the others.
pub fn read_global(path: &Path) -> anyhow::Result<Vec<BandDamping>> {
    let mut r =
        csv::Reader::from_path(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut bands = Vec::new();
    for (i, row) in r.deserialize::<GlobalRow>().enumerate() {
        let row = row.with_context(|| {
            format!(
                "{} row {}: expected f_lo_hz, f_hi_hz, f_center_hz, mean_d",
                path.display(),
                i + 1
            )
        })?;
        match row.mean_d {
            Some(d) if d.is_finite() && d >= 0.0 => bands.push(BandDamping {
                f_lo_hz: row.f_lo_hz,
                f_hi_hz: row.f_hi_hz,
                f_center_hz: row.f_center_hz,
                damping_ratio: d,
            }),
            Some(d) => bail!(
                "{} row {}: mean_d {d} is not a damping ratio",
                path.display(),
                i + 1
            ),
            None => eprintln!(
                "dampscope: warning: band {}–{} Hz has no global damping; skipped",
                row.f_lo_hz, row.f_hi_hz
            ),
        }
    }
    if bands.is_empty() {
        bail!("{}: no band with a global damping ratio", path.display());
    }
    Ok(bands)
}

fn pct(v: Option<f64>) -> String {
    v.map_or("—".into(), |v| format!("{:.2}", 100.0 * v))
}

/// Runs `resynth`.
pub fn run(args: &ResynthArgs) -> anyhow::Result<()> {
    let mut model = Model::load_or_reference(args.model.as_deref())?;
    if let Some(f) = args.fmax {
        model.output.fmax = f;
    }
    let bands = read_global(&args.global)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let done = resynthesize_model(&model, &bands, args.mode_cutoff_factor, !args.no_residual)?;
    let (r, original, driving_point) = (&done.result, &done.original, done.driving_point);
    let cutoff_hz = done.cutoff_hz;
    write_csv_file(&args.out.join("resynth.csv"), &r.bands)?;
    write_csv_file(&args.out.join("modes.csv"), &r.modes)?;
    #[derive(serde::Serialize)]
    struct FrfRow {
        f_hz: f64,
        abs_original_m_per_n: f64,
        abs_estimated_m_per_n: f64,
    }
    let frf_rows: Vec<FrfRow> = original
        .frequencies_hz
        .iter()
        .enumerate()
        .map(|(k, f)| FrfRow {
            f_hz: *f,
            abs_original_m_per_n: original.receptance_m_per_n[(k, driving_point)].norm(),
            abs_estimated_m_per_n: r.estimated.receptance_m_per_n[(k, driving_point)].norm(),
        })
        .collect();
    write_csv_file(&args.out.join("frf_driving_point.csv"), &frf_rows)?;
    crate::plot::resynthesis_figure(r, original, driving_point, &args.out.join("resynth.png"))?;

    println!(
        "re-synthesis over {} modes below {:.0} Hz; driving point at ({}, {}) m",
        done.n_modes, cutoff_hz, model.excitation.x, model.excitation.y
    );
    println!(
        "{:>16} {:>10} {:>10} {:>6} {:>12} {:>12}",
        "band Hz", "D_global%", "D_model%", "modes", "eps_drive%", "eps_all%"
    );
    for b in &r.bands {
        println!(
            "{:>16} {:>10} {:>10} {:>6} {:>12} {:>12}",
            format!("{:.1}–{:.1}", b.f_lo_hz, b.f_hi_hz),
            pct(Some(b.d_global)),
            pct(b.d_model_mean),
            b.n_modes,
            pct(b.eps_driving_point),
            pct(b.eps_all_sensors)
        );
    }
    println!(
        "wrote {}/resynth.csv, modes.csv, frf_driving_point.csv, resynth.png",
        args.out.display()
    );
    Ok(())
}

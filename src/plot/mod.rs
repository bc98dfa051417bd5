//! Figures (PNG via plotters' bitmap backend). Text uses DejaVu Sans embedded in the binary
//! (`assets/DejaVuSans.ttf`, Bitstream Vera licence in `assets/DejaVuSans.LICENSE`), so no
//! system fonts are needed.

mod diagnose;
mod map;
mod modal;
mod resynth;

pub use diagnose::{frf_overlay, mode_errors, residual_map};
pub use map::damping_map;
pub use modal::{mode_shape, stabilisation_diagram};
pub use resynth::resynthesis_figure;

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::analysis::sweep::{SweepRow, SWEEP_FRONT_ENDS};
use crate::error::{Error, Result};

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Registers the embedded font as `sans-serif` (once per process).
pub fn register_font() {
    REGISTER.call_once(|| {
        // The embedded font is a valid TTF; a failure would only leave text unrendered.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// Error classes of the sweep figure: upper bound of |error| and colour.
const CLASSES: [(f64, RGBColor, &str); 4] = [
    (0.02, RGBColor(46, 160, 67), "|err| < 2 %"),
    (0.05, RGBColor(210, 190, 40), "< 5 %"),
    (0.20, RGBColor(235, 130, 40), "< 20 %"),
    (f64::INFINITY, RGBColor(200, 40, 40), ">= 20 %"),
];
const NO_ESTIMATE: RGBColor = RGBColor(170, 170, 170);

fn colour(row: Option<&SweepRow>) -> RGBColor {
    match row.and_then(|r| r.rel_err) {
        None => NO_ESTIMATE,
        Some(e) => CLASSES
            .iter()
            .find(|c| e.abs() < c.0)
            .map(|c| c.1)
            .unwrap_or(NO_ESTIMATE),
    }
}

/// The label of grid value `values[i]` when `v` is the integer `i` (cell centres), else empty.
fn label_at(v: f64, values: &[f64], scale: f64, unit: &str) -> String {
    let i = v.round();
    if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < values.len() {
        format!("{}{unit}", (values[i as usize] * scale * 1e6).round() / 1e6)
    } else {
        String::new()
    }
}

pub(crate) fn plot_err<E: std::fmt::Display>(e: E) -> Error {
    Error::Output(format!("plot: {e}"))
}

/// Draws the sweep as heat maps: one panel per front end (columns) and case (rows: single
/// modes, close pairs), frequency across, damping up, each cell coloured by the class of its
/// relative error in D (grey: no estimate, e.g. flagged `too_few_frames`).
pub fn sweep_heatmap(rows: &[SweepRow], path: &Path) -> Result<()> {
    register_font();
    let mut freqs: Vec<f64> = rows.iter().map(|r| r.f_hz).collect();
    let mut damps: Vec<f64> = rows.iter().map(|r| r.d_true).collect();
    for v in [&mut freqs, &mut damps] {
        v.sort_by(f64::total_cmp);
        v.dedup();
    }
    let cases: Vec<&str> = ["single", "pair"]
        .into_iter()
        .filter(|c| rows.iter().any(|r| r.case == *c))
        .collect();
    if freqs.is_empty() || damps.is_empty() || cases.is_empty() {
        return Err(Error::Output("plot: no sweep rows to draw".into()));
    }
    let (w, h) = (1600u32, 300 + 380 * cases.len() as u32);
    let staged = crate::output::atomic::StagedPath::new(path);
    let temp = staged.path().to_path_buf();
    let root = BitMapBackend::new(&temp, (w, h)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (title, body) = root.split_vertically(110);
    title
        .draw(&Text::new(
            "Relative error of D against the truth (T30 fit); grey = no estimate",
            (20, 15),
            ("sans-serif", 26).into_font(),
        ))
        .map_err(plot_err)?;
    for (i, (_, c, label)) in CLASSES.iter().enumerate() {
        let x = 20 + 230 * i as i32;
        title
            .draw(&Rectangle::new([(x, 60), (x + 30, 85)], c.filled()))
            .map_err(plot_err)?;
        title
            .draw(&Text::new(
                *label,
                (x + 38, 62),
                ("sans-serif", 20).into_font(),
            ))
            .map_err(plot_err)?;
    }
    let x = 20 + 230 * CLASSES.len() as i32;
    title
        .draw(&Rectangle::new(
            [(x, 60), (x + 30, 85)],
            NO_ESTIMATE.filled(),
        ))
        .map_err(plot_err)?;
    title
        .draw(&Text::new(
            "no estimate",
            (x + 38, 62),
            ("sans-serif", 20).into_font(),
        ))
        .map_err(plot_err)?;

    let panels = body.split_evenly((cases.len(), SWEEP_FRONT_ENDS.len()));
    for (p, area) in panels.iter().enumerate() {
        let case = cases[p / SWEEP_FRONT_ENDS.len()];
        let fe = SWEEP_FRONT_ENDS[p % SWEEP_FRONT_ENDS.len()];
        let (nf, nd) = (freqs.len(), damps.len());
        let fl = freqs.clone();
        let dl = damps.clone();
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{fe}, {case}"), ("sans-serif", 22))
            .margin(8)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(-0.5f64..nf as f64 - 0.5, -0.5f64..nd as f64 - 0.5)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(nf)
            .y_labels(nd)
            .x_label_formatter(&move |v| label_at(*v, &fl, 1.0, ""))
            .y_label_formatter(&move |v| label_at(*v, &dl, 100.0, "%"))
            .x_desc("f [Hz]")
            .y_desc("D")
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(plot_err)?;
        let cells = (0..nf).flat_map(|i| (0..nd).map(move |j| (i, j)));
        chart
            .draw_series(cells.map(|(i, j)| {
                let row = rows.iter().find(|r| {
                    r.case == case
                        && r.front_end == fe
                        && r.f_hz == freqs[i]
                        && r.d_true == damps[j]
                });
                Rectangle::new(
                    [
                        (i as f64 - 0.46, j as f64 - 0.46),
                        (i as f64 + 0.46, j as f64 + 0.46),
                    ],
                    colour(row).filled(),
                )
            }))
            .map_err(plot_err)?;
    }
    root.present().map_err(plot_err)?;
    staged.commit().map_err(plot_err)?;
    Ok(())
}

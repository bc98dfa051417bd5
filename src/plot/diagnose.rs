//! Figures of a diagnosis: each paired mode's frequency and damping error before and after the
//! update; the shape residual over the plate with what was found drawn on it; measured and
//! modelled FRFs at a few sensors before and after.

use std::path::Path;

use plotters::prelude::*;

use super::{plot_err, register_font};
use crate::diagnose::report::{Diagnosis, Finding};
use crate::error::{Error, Result};

const BEFORE: RGBColor = RGBColor(40, 90, 200);
const AFTER: RGBColor = RGBColor(210, 50, 40);
const MEASURED: RGBColor = RGBColor(20, 20, 20);
const FOUND: RGBColor = RGBColor(0, 150, 70);

/// Per paired mode (by measured frequency): Δf/f in % and ΔD (measured − model), before and
/// after, as two panels.
pub fn mode_errors(d: &Diagnosis, path: &Path) -> Result<()> {
    register_font();
    let rows: Vec<(f64, f64, f64, f64, f64)> = d
        .evidence
        .pairs
        .iter()
        .filter_map(|p| {
            let after = d
                .evidence_after
                .pairs
                .iter()
                .find(|a| a.measured == p.measured)?;
            Some((
                d.modes[p.measured].frequency_hz,
                100.0 * p.frequency_rel,
                100.0 * after.frequency_rel,
                100.0 * p.damping_diff,
                100.0 * after.damping_diff,
            ))
        })
        .collect();
    if rows.is_empty() {
        return Err(Error::Output("plot: no paired modes".into()));
    }
    let fmax = rows.iter().map(|r| r.0).fold(0.0, f64::max) * 1.05;
    let staged = crate::output::atomic::StagedPath::new(path);
    let temp = staged.path().to_path_buf();
    let root = BitMapBackend::new(&temp, (1200, 800)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let panels = root.split_evenly((2, 1));
    let specs = [
        ("frequency error (measured/model − 1) [%]", 1usize, 2usize),
        ("damping ratio error (measured − model) [% points]", 3, 4),
    ];
    for (area, (label, b, a)) in panels.iter().zip(specs) {
        let pick = |r: &(f64, f64, f64, f64, f64), i: usize| match i {
            1 => r.1,
            2 => r.2,
            3 => r.3,
            _ => r.4,
        };
        let big = rows
            .iter()
            .flat_map(|r| [pick(r, b).abs(), pick(r, a).abs()])
            .fold(1e-6, f64::max)
            * 1.15;
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("{label}: before (blue), after the update (red)"),
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..fmax, -big..big)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc("measured mode frequency [Hz]")
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(plot_err)?;
        chart
            .draw_series(LineSeries::new([(0.0, 0.0), (fmax, 0.0)], BLACK))
            .map_err(plot_err)?;
        for (i, colour) in [(b, BEFORE), (a, AFTER)] {
            chart
                .draw_series(
                    rows.iter()
                        .map(|r| Circle::new((r.0, pick(r, i)), 5, colour.filled())),
                )
                .map_err(plot_err)?;
        }
    }
    root.present().map_err(plot_err)?;
    staged.commit().map_err(plot_err)?;
    Ok(())
}

/// The shape residual per sensor (`values`, at `positions_m`) over the plate (lx × ly), with
/// each finding's region, point or edge drawn in green.
pub fn residual_map(
    title: &str,
    plate_m: (f64, f64),
    positions_m: &[(f64, f64)],
    values: &[f64],
    findings: &[Finding],
    path: &Path,
) -> Result<()> {
    register_font();
    if positions_m.is_empty() || positions_m.len() != values.len() {
        return Err(Error::Output(format!(
            "plot: {} sensor positions for {} residuals",
            positions_m.len(),
            values.len()
        )));
    }
    let (lx, ly) = plate_m;
    let big = values.iter().fold(1e-300f64, |m, v| m.max(v.abs()));
    let staged = crate::output::atomic::StagedPath::new(path);
    let temp = staged.path().to_path_buf();
    let root = BitMapBackend::new(&temp, (700, 950)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.05 * lx..1.05 * lx, -0.05 * ly..1.05 * ly)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("x [m]")
        .y_desc("y [m]")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(plot_err)?;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(0.0, 0.0), (lx, ly)],
            BLACK.stroke_width(1),
        )))
        .map_err(plot_err)?;
    chart
        .draw_series(positions_m.iter().zip(values).map(|(&p, &v)| {
            let t = (v / big).clamp(0.0, 1.0);
            let c = RGBColor(
                255,
                (255.0 * (1.0 - t)) as u8,
                (255.0 * (1.0 - 0.8 * t)) as u8,
            );
            Circle::new(p, (3.0 + 12.0 * t) as i32, c.filled())
        }))
        .map_err(plot_err)?;
    for f in findings {
        if let Some(r) = &f.region {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(r.x[0], r.y[0]), (r.x[1], r.y[1])],
                    FOUND.stroke_width(3),
                )))
                .map_err(plot_err)?;
        }
        if let Some(p) = &f.point {
            chart
                .draw_series(std::iter::once(Cross::new(
                    (p.x, p.y),
                    10,
                    FOUND.stroke_width(3),
                )))
                .map_err(plot_err)?;
        }
        if let Some(e) = &f.edge {
            let line = match e.as_str() {
                "x0" => [(0.0, 0.0), (0.0, ly)],
                "x1" => [(lx, 0.0), (lx, ly)],
                "y0" => [(0.0, 0.0), (lx, 0.0)],
                _ => [(0.0, ly), (lx, ly)],
            };
            chart
                .draw_series(LineSeries::new(line, FOUND.stroke_width(6)))
                .map_err(plot_err)?;
        }
    }
    root.present().map_err(plot_err)?;
    staged.commit().map_err(plot_err)?;
    Ok(())
}

/// |H| in dB at the overlay's sensors: measured (black), model before (blue), after (red).
pub fn frf_overlay(d: &Diagnosis, path: &Path) -> Result<()> {
    register_font();
    let Some(o) = &d.frf else {
        return Err(Error::Output("plot: no FRFs to overlay".into()));
    };
    if o.curves.is_empty() || o.frequencies_hz.is_empty() {
        return Err(Error::Output("plot: no FRFs to overlay".into()));
    }
    let f0 = o.frequencies_hz[0];
    let f1 = *o.frequencies_hz.last().expect("not empty");
    let staged = crate::output::atomic::StagedPath::new(path);
    let temp = staged.path().to_path_buf();
    let root = BitMapBackend::new(&temp, (1200, 330 * o.curves.len() as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let panels = root.split_evenly((o.curves.len(), 1));
    for (k, (area, curves)) in panels.iter().zip(&o.curves).enumerate() {
        let db: Vec<Vec<f64>> = curves
            .iter()
            .map(|c| {
                c.iter()
                    .map(|h| 20.0 * h.norm().max(1e-30).log10())
                    .collect()
            })
            .collect();
        let hi = db
            .iter()
            .flatten()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max)
            + 5.0;
        let lo = hi - 80.0;
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!(
                    "sensor {}: measured (black), model before (blue), after (red)",
                    o.sensors[k]
                ),
                ("sans-serif", 16),
            )
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(f0..f1, lo..hi)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc("f [Hz]")
            .y_desc("|H| [dB re 1 (m/s²)/N]")
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(plot_err)?;
        for (curve, colour) in db.iter().zip([MEASURED, BEFORE, AFTER]) {
            chart
                .draw_series(LineSeries::new(
                    o.frequencies_hz
                        .iter()
                        .zip(curve)
                        .map(|(&f, &v)| (f, v.max(lo))),
                    colour.stroke_width(1),
                ))
                .map_err(plot_err)?;
        }
    }
    root.present().map_err(plot_err)?;
    staged.commit().map_err(plot_err)?;
    Ok(())
}

//! Figures of the modal identification: the stabilisation diagram over the channels' mean
//! spectrum, and one mode shape over the sensor positions.

use std::path::Path;

use plotters::prelude::*;

use super::{plot_err, register_font};
use crate::error::{Error, Result};
use crate::modal::stabilise::PoleClass;
use crate::modal::ModalResult;

const STABLE: RGBColor = RGBColor(210, 50, 40);
const UNSTABLE: RGBColor = RGBColor(150, 150, 150);
const SPECTRUM: RGBColor = RGBColor(40, 90, 200);

/// Draws the stabilisation diagram (poles by model order over frequency; stable red,
/// unstable grey, rejected not drawn; the identified modes as vertical lines) over
/// `spectrum_db` ((f, dB) of the channels' mean power spectrum, scaled onto the order axis).
pub fn stabilisation_diagram(
    result: &ModalResult,
    spectrum_db: &[(f64, f64)],
    f_range_hz: (f64, f64),
    path: &Path,
) -> Result<()> {
    register_font();
    let (f0, f1) = f_range_hz;
    if f1.partial_cmp(&f0) != Some(std::cmp::Ordering::Greater) {
        return Err(Error::Output("plot: empty frequency range".into()));
    }
    let max_order = result.diagram.iter().map(|p| p.order).max().unwrap_or(1) as f64 + 1.0;
    let staged = crate::output::atomic::StagedPath::new(path);
    let temp = staged.path().to_path_buf();
    let root = BitMapBackend::new(&temp, (1400, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Stabilisation diagram: stable poles (red), unstable (grey), modes (lines), mean spectrum (blue)",
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(f0..f1, 0.0..max_order)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("f [Hz]")
        .y_desc("model order")
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(plot_err)?;
    let inside: Vec<(f64, f64)> = spectrum_db
        .iter()
        .copied()
        .filter(|(f, v)| *f >= f0 && *f <= f1 && v.is_finite())
        .collect();
    let hi = inside.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    if hi.is_finite() {
        // The top 60 dB of the spectrum over the order axis.
        let scale = |v: f64| ((v - hi + 60.0) / 60.0).clamp(0.0, 1.0) * max_order;
        chart
            .draw_series(LineSeries::new(
                inside.iter().map(|&(f, v)| (f, scale(v))),
                SPECTRUM.stroke_width(1),
            ))
            .map_err(plot_err)?;
    }
    for m in &result.modes {
        chart
            .draw_series(LineSeries::new(
                [(m.frequency_hz, 0.0), (m.frequency_hz, max_order)],
                RGBColor(255, 190, 120),
            ))
            .map_err(plot_err)?;
    }
    let points = |class: PoleClass| {
        result
            .diagram
            .iter()
            .filter(move |p| p.class == class && p.f_hz >= f0 && p.f_hz <= f1)
            .map(|p| (p.f_hz, p.order as f64))
    };
    chart
        .draw_series(points(PoleClass::Unstable).map(|p| Circle::new(p, 2, UNSTABLE.filled())))
        .map_err(plot_err)?;
    chart
        .draw_series(points(PoleClass::Stable).map(|p| Circle::new(p, 3, STABLE.filled())))
        .map_err(plot_err)?;
    root.present().map_err(plot_err)?;
    staged.commit().map_err(plot_err)?;
    Ok(())
}

/// Draws one mode shape: each sensor at (x, y) m as a disc whose colour is the signed real
/// part of the shape (after rotating it to its best real direction) and whose size its
/// magnitude.
pub fn mode_shape(
    title: &str,
    positions_m: &[(f64, f64)],
    values: &[f64],
    path: &Path,
) -> Result<()> {
    register_font();
    if positions_m.is_empty() || positions_m.len() != values.len() {
        return Err(Error::Output(format!(
            "plot: {} sensor positions for {} shape values",
            positions_m.len(),
            values.len()
        )));
    }
    let (xmin, xmax) = bounds(positions_m.iter().map(|p| p.0));
    let (ymin, ymax) = bounds(positions_m.iter().map(|p| p.1));
    let pad = 0.05 * (xmax - xmin).max(ymax - ymin).max(1e-3);
    let big = values
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-300);
    let staged = crate::output::atomic::StagedPath::new(path);
    let temp = staged.path().to_path_buf();
    let root = BitMapBackend::new(&temp, (700, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d((xmin - pad)..(xmax + pad), (ymin - pad)..(ymax + pad))
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("x [m]")
        .y_desc("y [m]")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(plot_err)?;
    chart
        .draw_series(positions_m.iter().zip(values).map(|(&p, &v)| {
            let t = v / big;
            let colour = if t >= 0.0 {
                RGBColor(255, (255.0 * (1.0 - t)) as u8, (255.0 * (1.0 - t)) as u8)
            } else {
                RGBColor((255.0 * (1.0 + t)) as u8, (255.0 * (1.0 + t)) as u8, 255)
            };
            Circle::new(p, (4.0 + 10.0 * t.abs()) as i32, colour.filled())
        }))
        .map_err(plot_err)?;
    root.present().map_err(plot_err)?;
    staged.commit().map_err(plot_err)?;
    Ok(())
}

fn bounds(v: impl Iterator<Item = f64>) -> (f64, f64) {
    v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    })
}

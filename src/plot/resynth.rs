//! The re-synthesis figure: driving-point FRF of the model and of its re-synthesis from the
//! global damping (report Fig. 4.11), and the damping per mode against the bands' (Fig. 4.10).

use std::path::Path;

use plotters::prelude::*;

use super::{plot_err, register_font};
use crate::analysis::resynthesis::Resynthesis;
use crate::error::{Error, Result};
use crate::sim::frf::Frf;

const ORIGINAL: RGBColor = RGBColor(40, 90, 200);
const ESTIMATED: RGBColor = RGBColor(210, 50, 40);

fn db(h: faer::c64) -> f64 {
    20.0 * h.norm().max(1e-300).log10()
}

/// Draws the figure to a PNG at `path`; `driving_point` is the sensor column shown.
pub fn resynthesis_figure(
    r: &Resynthesis,
    original: &Frf,
    driving_point: usize,
    path: &Path,
) -> Result<()> {
    register_font();
    let f = &original.frequencies_hz;
    let (Some(&f0), Some(&f1)) = (
        r.bands.iter().map(|b| b.f_lo_hz).reduce(f64::min).as_ref(),
        r.bands.iter().map(|b| b.f_hi_hz).reduce(f64::max).as_ref(),
    ) else {
        return Err(Error::Output("plot: no bands to draw".into()));
    };
    let pick = |frf: &Frf| -> Vec<(f64, f64)> {
        f.iter()
            .enumerate()
            .filter(|(_, v)| **v >= f0 && **v <= f1)
            .map(|(k, v)| (*v, db(frf.receptance_m_per_n[(k, driving_point)])))
            .collect()
    };
    let (orig, est) = (pick(original), pick(&r.estimated));
    let lo = orig
        .iter()
        .chain(&est)
        .map(|p| p.1)
        .fold(f64::INFINITY, f64::min);
    let hi = orig
        .iter()
        .chain(&est)
        .map(|p| p.1)
        .fold(f64::NEG_INFINITY, f64::max);
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(Error::Output(
            "plot: no frequencies inside the bands".into(),
        ));
    }
    let staged = crate::output::atomic::StagedPath::new(path);
    let temp = staged.path().to_path_buf();
    let root = BitMapBackend::new(&temp, (1200, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (top, bottom) = root.split_vertically(520);
    let mut chart = ChartBuilder::on(&top)
        .caption(
            "Driving point: model (blue) and re-synthesis from the global D per band (red)",
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(f0..f1, (lo - 5.0)..(hi + 5.0))
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("f [Hz]")
        .y_desc("|H| [dB re 1 m/N]")
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(plot_err)?;
    for b in &r.bands {
        chart
            .draw_series(LineSeries::new(
                [(b.f_lo_hz, lo - 5.0), (b.f_lo_hz, hi + 5.0)],
                RGBColor(200, 200, 200),
            ))
            .map_err(plot_err)?;
    }
    chart
        .draw_series(LineSeries::new(orig, ORIGINAL.stroke_width(2)))
        .map_err(plot_err)?;
    chart
        .draw_series(LineSeries::new(est, ESTIMATED.stroke_width(1)))
        .map_err(plot_err)?;

    let modes: Vec<(f64, f64)> = r
        .modes
        .iter()
        .filter(|m| m.frequency_hz >= f0 && m.frequency_hz <= f1)
        .map(|m| (m.frequency_hz, 100.0 * m.d_model))
        .collect();
    let global: Vec<(f64, f64)> = r
        .bands
        .iter()
        .map(|b| (0.5 * (b.f_lo_hz + b.f_hi_hz), 100.0 * b.d_global))
        .collect();
    let dmax = modes
        .iter()
        .chain(&global)
        .map(|p| p.1)
        .fold(0.0, f64::max)
        .max(0.1);
    let mut chart = ChartBuilder::on(&bottom)
        .caption(
            "Damping ratio: model modes (×, modal strain energy) and global D per band (line)",
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(f0..f1, 0.0..1.15 * dmax)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("f [Hz]")
        .y_desc("D [%]")
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(plot_err)?;
    chart
        .draw_series(
            modes
                .iter()
                .map(|p| Cross::new(*p, 4, ORIGINAL.stroke_width(2))),
        )
        .map_err(plot_err)?;
    chart
        .draw_series(LineSeries::new(global.clone(), ESTIMATED.stroke_width(2)))
        .map_err(plot_err)?;
    chart
        .draw_series(
            global
                .iter()
                .map(|p| Circle::new(*p, 4, ESTIMATED.filled())),
        )
        .map_err(plot_err)?;
    root.present().map_err(plot_err)?;
    staged.commit().map_err(plot_err)?;
    Ok(())
}

//! The damping map figure: one cell per sensor at its position, coloured by the local damping
//! ratio, grey with a cross where there is no estimate.

use std::path::Path;

use plotters::prelude::*;

use super::{plot_err, register_font};
use crate::analysis::maps::BandMap;
use crate::error::{Error, Result};

/// Viridis-like colour ramp (anchors from matplotlib's viridis), `t` in 0…1.
fn ramp(t: f64) -> RGBColor {
    const ANCHORS: [(f64, f64, f64); 6] = [
        (68.0, 1.0, 84.0),
        (65.0, 68.0, 135.0),
        (42.0, 120.0, 142.0),
        (34.0, 168.0, 132.0),
        (122.0, 209.0, 81.0),
        (253.0, 231.0, 37.0),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = t * (ANCHORS.len() - 1) as f64;
    let i = (s.floor() as usize).min(ANCHORS.len() - 2);
    let f = s - i as f64;
    let (a, b) = (ANCHORS[i], ANCHORS[i + 1]);
    let mix = |p: f64, q: f64| (p + f * (q - p)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

const MISSING: RGBColor = RGBColor(190, 190, 190);

/// The typical spacing of the sensors: the median distance to the nearest other sensor
/// (1 when there is a single sensor).
fn typical_spacing(map: &BandMap) -> f64 {
    let pts: Vec<(f64, f64)> = map.nodes.iter().map(|n| (n.x_m, n.y_m)).collect();
    let mut nearest: Vec<f64> = pts
        .iter()
        .enumerate()
        .filter_map(|(i, p)| {
            pts.iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, q)| ((p.0 - q.0).powi(2) + (p.1 - q.1).powi(2)).sqrt())
                .filter(|d| *d > 0.0)
                .min_by(f64::total_cmp)
        })
        .collect();
    nearest.sort_by(f64::total_cmp);
    nearest.get(nearest.len() / 2).copied().unwrap_or(1.0)
}

/// Draws `map` to a PNG at `path`. The colour scale runs from the 2nd to the 98th percentile of
/// the local ratios (values beyond are drawn at the ends), so that a few nodal-line outliers do
/// not flatten the rest of the map.
pub fn damping_map(map: &BandMap, path: &Path) -> Result<()> {
    register_font();
    if map.nodes.is_empty() {
        return Err(Error::Output("plot: a damping map needs sensors".into()));
    }
    let g = map.global();
    let mut d: Vec<f64> = map.nodes.iter().filter_map(|n| n.damping_ratio).collect();
    d.sort_by(f64::total_cmp);
    let pick = |q: f64| d[((d.len() - 1) as f64 * q).round() as usize];
    let (lo, hi) = if d.is_empty() {
        (0.0, 1.0)
    } else if pick(0.98) > pick(0.02) {
        (pick(0.02), pick(0.98))
    } else {
        (0.9 * pick(0.5), 1.1 * pick(0.5) + 1e-12)
    };
    let h = typical_spacing(map);
    let fold =
        |f: fn(f64, f64) -> f64, init: f64, get: fn(&crate::analysis::maps::MapNode) -> f64| {
            map.nodes.iter().map(get).fold(init, f)
        };
    let (x0, x1) = (
        fold(f64::min, f64::INFINITY, |n| n.x_m) - 0.5 * h,
        fold(f64::max, f64::NEG_INFINITY, |n| n.x_m) + 0.5 * h,
    );
    let (y0, y1) = (
        fold(f64::min, f64::INFINITY, |n| n.y_m) - 0.5 * h,
        fold(f64::max, f64::NEG_INFINITY, |n| n.y_m) + 0.5 * h,
    );
    // Equal scales in x and y: a 700 px wide plot area, height to match (bounded).
    let plot_w = 700.0;
    let plot_h = (plot_w * (y1 - y0) / (x1 - x0)).clamp(250.0, 1400.0);
    let (w, hgt) = (plot_w as u32 + 330, plot_h as u32 + 190);
    let staged = crate::output::atomic::StagedPath::new(path);
    let temp = staged.path().to_path_buf();
    let root = BitMapBackend::new(&temp, (w, hgt)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (main, bar) = root.split_horizontally(w - 190);
    let mean = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{:.2} %", 100.0 * v));
    let mut chart = ChartBuilder::on(&main)
        .caption(
            format!(
                "D, {:.1}–{:.1} Hz: mean {} ({} of {} sensors)",
                map.band.lo_hz,
                map.band.hi_hz,
                mean(g.mean_d),
                g.n_estimated,
                g.n_nodes
            ),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x [m]")
        .y_desc("y [m]")
        .label_style(("sans-serif", 16))
        .draw()
        .map_err(plot_err)?;
    let half = 0.5 * h;
    chart
        .draw_series(map.nodes.iter().map(|n| {
            let c = match n.damping_ratio {
                Some(v) => ramp((v - lo) / (hi - lo)),
                None => MISSING,
            };
            Rectangle::new(
                [(n.x_m - half, n.y_m - half), (n.x_m + half, n.y_m + half)],
                c.filled(),
            )
        }))
        .map_err(plot_err)?;
    chart
        .draw_series(
            map.nodes
                .iter()
                .filter(|n| n.damping_ratio.is_none())
                .map(|n| Cross::new((n.x_m, n.y_m), 3, RGBColor(90, 90, 90).stroke_width(1))),
        )
        .map_err(plot_err)?;

    // Colour bar with five labels, and the legend of missing sensors.
    let (top, bottom) = (60i32, hgt as i32 - 120);
    let steps = 100;
    for k in 0..steps {
        let t = k as f64 / steps as f64;
        let y_hi = bottom - ((bottom - top) as f64 * (t + 1.0 / steps as f64)) as i32;
        let y_lo = bottom - ((bottom - top) as f64 * t) as i32;
        bar.draw(&Rectangle::new([(20, y_hi), (50, y_lo)], ramp(t).filled()))
            .map_err(plot_err)?;
    }
    for k in 0..=4 {
        let t = k as f64 / 4.0;
        let y = bottom - ((bottom - top) as f64 * t) as i32;
        bar.draw(&Text::new(
            format!("{:.2} %", 100.0 * (lo + t * (hi - lo))),
            (58, y - 8),
            ("sans-serif", 16).into_font(),
        ))
        .map_err(plot_err)?;
    }
    bar.draw(&Text::new(
        "D",
        (25, top - 35),
        ("sans-serif", 20).into_font(),
    ))
    .map_err(plot_err)?;
    bar.draw(&Rectangle::new(
        [(20, bottom + 30), (50, bottom + 55)],
        MISSING.filled(),
    ))
    .map_err(plot_err)?;
    bar.draw(&Text::new(
        "no estimate",
        (58, bottom + 34),
        ("sans-serif", 16).into_font(),
    ))
    .map_err(plot_err)?;
    root.present().map_err(plot_err)?;
    staged.commit().map_err(plot_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_ends_and_middle() {
        assert_eq!(ramp(0.0), RGBColor(68, 1, 84));
        assert_eq!(ramp(1.0), RGBColor(253, 231, 37));
        assert_eq!(ramp(-3.0), ramp(0.0));
        assert_eq!(ramp(f64::NAN), ramp(0.0));
        assert_eq!(ramp(0.4), RGBColor(42, 120, 142));
    }
}

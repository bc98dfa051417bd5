//! The report's section 3.4 study, part (a): the driving-point FRF of the reference plate
//! (g = 0.5 %) with and without the soft viscoelastic patch of
//! `examples/plate-viscoelastic-patch.toml` (report Fig. 3.13 a: the patch shifts the
//! eigenfrequencies down). Part (b), the damping map at 48.5–52.5 Hz, is `dampscope map` on the
//! simulated set (README).
//!
//! `cargo run --release --example viscoelastic_study [FMAX_HZ] [OUT.png]`

use dampscope::sim::model::Model;
use dampscope::sim::simulate::{simulate, SimulateOptions, SimulationResult};
use plotters::prelude::*;

/// |accelerance| in dB at the sensor nearest the excitation.
fn driving_point_db(r: &SimulationResult) -> anyhow::Result<Vec<f64>> {
    let ex = r
        .excitation
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("no excitation"))?;
    let k = (0..r.sensors.len())
        .min_by(|&a, &b| {
            let d = |s: usize| (r.sensors[s].x_m - ex.x).hypot(r.sensors[s].y_m - ex.y);
            d(a).total_cmp(&d(b))
        })
        .ok_or_else(|| anyhow::anyhow!("no sensors"))?;
    Ok(r.frf
        .accelerance(k)
        .iter()
        .map(|h| 20.0 * h.norm().max(1e-30).log10())
        .collect())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let fmax: f64 = args.get(1).map(|a| a.parse()).transpose()?.unwrap_or(150.0);
    let out = args
        .get(2)
        .cloned()
        .unwrap_or_else(|| "docs/figures/viscoelastic-driving-point-frf.png".into());
    let mut visco = Model::load(std::path::Path::new(
        "examples/plate-viscoelastic-patch.toml",
    ))?;
    visco.output.fmax = fmax;
    let mut plain = visco.clone();
    plain.patches.clear();
    let opts = SimulateOptions::default();
    let t = std::time::Instant::now();
    let with_patch = simulate(&visco, &opts)?;
    eprintln!(
        "with the patch: {:.1} s ({} modes)",
        t.elapsed().as_secs_f64(),
        with_patch.modes_used
    );
    let without = simulate(&plain, &opts)?;
    let freqs = &with_patch.frf.frequencies_hz;
    let (a, b) = (driving_point_db(&without)?, driving_point_db(&with_patch)?);
    dampscope::plot::register_font();
    let root = BitMapBackend::new(&out, (1200, 450)).into_drawing_area();
    root.fill(&WHITE)?;
    let hi = a
        .iter()
        .chain(&b)
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
        + 5.0;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "driving point: plate g = 0.5 % (blue), with the viscoelastic patch (red)",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(65)
        .build_cartesian_2d(0.0..fmax, (hi - 90.0)..hi)?;
    chart
        .configure_mesh()
        .x_desc("f [Hz]")
        .y_desc("|H| [dB re 1 (m/s²)/N]")
        .label_style(("sans-serif", 14))
        .draw()?;
    for (curve, colour) in [(&a, BLUE), (&b, RED)] {
        chart.draw_series(LineSeries::new(
            freqs
                .iter()
                .zip(curve.iter())
                .map(|(&f, &v)| (f, v.max(hi - 90.0))),
            colour.stroke_width(1),
        ))?;
    }
    root.present()?;
    eprintln!("wrote {out}");
    Ok(())
}

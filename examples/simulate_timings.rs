//! Phase times of `simulate` on a model (default: the reference plate, 8001 frequencies ×
//! 33 × 49 sensors), the figures of issue 3's speed acceptance.
//!
//! `cargo run --profile test --example simulate_timings [MODEL.toml] [direct|fast]`

use dampscope::sim::model::Model;
use dampscope::sim::simulate::{simulate, Method, SimulateOptions};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let model = match args.get(1).filter(|a| a.ends_with(".toml")) {
        Some(p) => Model::load(std::path::Path::new(p))?,
        None => Model::reference_plate(),
    };
    let method = if args.iter().any(|a| a == "direct") {
        Method::Direct
    } else {
        Method::Fast
    };
    let t = std::time::Instant::now();
    let r = simulate(
        &model,
        &SimulateOptions {
            method,
            progress: true,
            ..SimulateOptions::default()
        },
    )?;
    let total = t.elapsed().as_secs_f64();
    let tm = &r.timings;
    println!(
        "{} frequencies × {} sensors, {} modes: assembly {:.2} s, modes {:.2} s, reduction {:.2} s, FRF {:.2} s, impulse responses {:.2} s; total {:.2} s, without modes {:.2} s",
        r.frf.frequencies_hz.len(),
        r.frf.n_sensors(),
        r.modes_used,
        tm.assembly_s,
        tm.modes_s,
        tm.reduction_s,
        tm.frf_s,
        tm.impulse_s,
        total,
        total - tm.modes_s
    );
    Ok(())
}

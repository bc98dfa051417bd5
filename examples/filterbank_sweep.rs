//! Runs the full front-end sweep (`dampscope compare --sweep`) and writes sweep.csv and
//! sweep.png into the directory given (default `target/sweep`).
//!
//! `cargo run --release --example filterbank_sweep -- target/sweep`

use dampscope::analysis::sweep::SweepConfig;
use dampscope::analysis::sweep::{sweep_summary, sweep_to_dir};

fn main() -> anyhow::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "target/sweep".into());
    let t0 = std::time::Instant::now();
    let rows = sweep_to_dir(&SweepConfig::default(), std::path::Path::new(&dir))?;
    print!("{}", sweep_summary(&rows));
    println!(
        "{} rows in {:.2} s; wrote {dir}/sweep.csv and {dir}/sweep.png",
        rows.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

//! `dampscope simulate --out DIR` writes a recording set that the readers accept, with the
//! impulse responses of the simulation.

use clap::Parser;
use dampscope::cli::simulate::{run, SimulateArgs};
use dampscope::sim::model::Model;
use dampscope::sim::simulate::simulate;
use dampscope::source::{open_recording_set, Block, DecayKind};

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: SimulateArgs,
}

const MODEL: &str = r#"
[plate]
lx = 2.0
ly = 3.0
thickness = 0.02
[mesh]
nx = 8
ny = 12
nz = 1
[material]
youngs_modulus = 7.0e10
poisson = 0.34
density = 2700.0
loss_factor = 0.05
[supports]
pinned_edges = ["y0", "y1"]
[excitation]
x = 0.5
y = 0.75
[output]
fmax = 250.0
df = 0.5
sensors = { nx = 3, ny = 3 }
"#;

#[test]
fn out_dir_is_a_readable_recording_set() {
    let dir = std::env::temp_dir().join(format!("dampscope-sim-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model_path = dir.join("plate.toml");
    std::fs::write(&model_path, MODEL).unwrap();
    let out = dir.join("set");
    let cli = Cli::try_parse_from([
        "simulate",
        "--model",
        model_path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--keep-modes",
        "2,3",
    ])
    .unwrap();
    run(&cli.args).unwrap();

    let mut set = open_recording_set(&out).unwrap();
    assert_eq!(set.meta.kind, DecayKind::ImpulseResponse);
    assert_eq!(set.meta.quantity.as_deref(), Some("acceleration"));
    assert_eq!(set.meta.fs, Some(500.0));
    assert_eq!(set.sensors.len(), 9);
    assert_eq!(set.excitation.len(), 1);
    assert_eq!(set.source.info().sample_rate_hz, 500.0);
    let mut block = Block::default();
    let mut got: Vec<Vec<f64>> = vec![Vec::new(); 9];
    while set.source.read_block(4096, &mut block).unwrap() {
        for (g, c) in got.iter_mut().zip(&block.channels) {
            g.extend_from_slice(c);
        }
    }
    // the same simulation in-process: the WAV holds it rounded to f32
    let model = Model::load(&model_path).unwrap();
    let want = simulate(&model, &cli.args.options()).unwrap();
    assert_eq!(got[0].len(), 1000);
    for (g, w) in got.iter().zip(&want.impulse_responses) {
        let peak = w.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        for (a, b) in g.iter().zip(w) {
            assert!((a - b).abs() <= 1e-6 * peak.max(1e-30), "{a} vs {b}");
        }
    }
    // --keep-modes and --method direct parse; --out and --stdout exclude each other
    assert!(Cli::try_parse_from(["simulate", "--out", "x", "--stdout"]).is_err());
    assert!(Cli::try_parse_from(["simulate"]).is_err());
    std::fs::remove_dir_all(&dir).ok();
}

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

/// `--snr-definition mean-power`: one σ for all channels, σ² = mean channel power / 10^(snr/10),
/// and exactly the noise `Recordings::add_noise_mean_power` draws for the same seed (so that
/// `simulate` and `modal --add-noise-db` make the same test data). The peak definition gives
/// each channel its own σ from its peak.
#[test]
fn mean_power_snr_sets_one_noise_level_from_the_mean_power() {
    use dampscope::modal::Recordings;
    let dir = std::env::temp_dir().join(format!("dampscope-sim-snr-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model_path = dir.join("plate.toml");
    std::fs::write(&model_path, MODEL).unwrap();
    let read = |name: &str, extra: &[&str]| -> Recordings {
        let out = dir.join(name);
        let mut argv = vec![
            "simulate",
            "--model",
            model_path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--keep-modes",
            "2,3",
        ];
        argv.extend_from_slice(extra);
        run(&Cli::try_parse_from(argv).unwrap().args).unwrap();
        let mut set = open_recording_set(&out).unwrap();
        Recordings::from_source(set.source.as_mut(), usize::MAX).unwrap()
    };
    let clean = read("clean", &[]);
    let noisy = read(
        "mean",
        &[
            "--snr-db",
            "20",
            "--snr-definition",
            "mean-power",
            "--seed",
            "7",
        ],
    );
    let peak = read("peak", &["--snr-db", "20", "--seed", "7"]);
    let n = clean.channels[0].len() as f64;
    let power: f64 = clean
        .channels
        .iter()
        .map(|x| x.iter().map(|v| v * v).sum::<f64>() / n)
        .sum::<f64>()
        / clean.channels.len() as f64;
    let want_var = power / 100.0;
    let mut all = 0.0;
    for (c, (x, y)) in clean.channels.iter().zip(&noisy.channels).enumerate() {
        let var = x.iter().zip(y).map(|(a, b)| (b - a).powi(2)).sum::<f64>() / n;
        all += var;
        // Each channel's own noise variance (a few thousand samples: ±10 %).
        assert!(
            (var / want_var - 1.0).abs() < 0.1,
            "channel {c}: noise variance {var:.3e}, want {want_var:.3e}"
        );
    }
    let mean_var = all / clean.channels.len() as f64;
    assert!(
        (mean_var / want_var - 1.0).abs() < 0.03,
        "{mean_var} vs {want_var}"
    );
    // The same noise as the library's own noise model (WAV float32 rounding aside).
    let mut again = clean.clone();
    again.add_noise_mean_power(20.0, 7);
    for (x, y) in again.channels.iter().zip(&noisy.channels) {
        for (a, b) in x.iter().zip(y) {
            assert!(
                (a - b).abs() <= 1e-6 * a.abs().max(want_var.sqrt()),
                "{a} vs {b}"
            );
        }
    }
    // The peak definition gives each channel its own σ = max|h| · 10^(−snr/20) instead.
    for (c, (x, y)) in clean.channels.iter().zip(&peak.channels).enumerate() {
        let var = x.iter().zip(y).map(|(a, b)| (b - a).powi(2)).sum::<f64>() / n;
        let peak_amp = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let want = peak_amp * peak_amp / 100.0;
        // (Sensors on the pinned edges do not move: no peak, no noise.)
        assert!(
            (want == 0.0 && var == 0.0) || (var / want - 1.0).abs() < 0.1,
            "channel {c}: peak-SNR noise variance {var:.3e}, want {want:.3e}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

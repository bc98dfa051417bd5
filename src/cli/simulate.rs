//! `dampscope simulate`: impulse responses of the finite-element plate, as a recording set
//! (FORMATS.md §1) or a 32-bit float WAV on standard output for `dampscope analyze -`.

use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

use crate::modal::Recordings;
use crate::output::{write_recording_set_streamed, WavStreamWriter};
use crate::sim::model::Model;
use crate::sim::simulate::{simulate_stream, Method, SimulateOptions, STREAM_BLOCK_FRAMES};
use crate::sim::system::SensorWeights;
use crate::source::recording_set::{DecayKind, Excitation, RecordingMeta, Sensor};
use crate::source::{Block, Source};

/// FRF method on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    /// Sparse complex solve per frequency (slow reference).
    Direct,
    /// Modal projection with residual vectors and exact regional damping.
    Fast,
}

/// How `simulate --snr-db` is defined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SnrDefinition {
    /// Per channel, on the channel's peak amplitude.
    Peak,
    /// On the mean over channels of the signal power over the record.
    MeanPower,
}

/// Simulate the finite-element plate: a recording set (--out DIR) or a WAV stream (--stdout).
#[derive(Clone, Debug, clap::Args)]
pub struct SimulateArgs {
    /// Plate model (TOML, docs/FORMATS.md §3); default: the report's reference plate.
    #[arg(long, value_name = "PATH")]
    pub model: Option<PathBuf>,
    /// Write a recording set to this directory.
    #[arg(
        long,
        value_name = "DIR",
        conflicts_with = "stdout",
        required_unless_present = "stdout"
    )]
    pub out: Option<PathBuf>,
    /// Stream the responses as a 32-bit float WAV on standard output.
    #[arg(long)]
    pub stdout: bool,
    /// FRF method.
    #[arg(long, value_enum, default_value_t = MethodArg::Fast)]
    pub method: MethodArg,
    /// Keep only these modes (1-based, comma separated, e.g. 7,8): modal truncation.
    #[arg(long, value_name = "N,N,…", value_delimiter = ',')]
    pub keep_modes: Option<Vec<usize>>,
    /// With --keep-modes: given modal damping ratios D_i (comma separated, one per kept mode)
    /// instead of the modal strain energy loss factors.
    #[arg(
        long,
        value_name = "D,D,…",
        value_delimiter = ',',
        requires = "keep_modes"
    )]
    pub modal_damping: Option<Vec<f64>>,
    /// Add white Gaussian noise at this SNR, dB (defined by --snr-definition).
    #[arg(long = "snr-db", value_name = "DB")]
    pub snr_db: Option<f64>,
    /// How --snr-db is defined: `peak` (per channel: σ = max|h| · 10^(−snr/20), kind to decays)
    /// or `mean-power` (one σ for all channels: the mean over channels of each channel's
    /// power over the record, over 10^(snr/10); what a lab's noise floor looks like, and the
    /// same noise as `dampscope modal --add-noise-db` draws for the same seed).
    #[arg(long, value_enum, default_value_t = SnrDefinition::Peak)]
    pub snr_definition: SnrDefinition,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print phase times on stderr.
    #[arg(long)]
    pub timings: bool,
    /// What the recording set holds: `wav` (impulse responses, responses.wav) or `uff`
    /// (accelerance FRFs as UFF dataset 58 with the sensor nodes as dataset 2411,
    /// responses.uff, for modal-analysis software).
    #[arg(long, value_enum, default_value_t = SetFormat::Wav, requires = "out")]
    pub format: SetFormat,
}

/// What `simulate --out` writes the responses as.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SetFormat {
    /// Impulse responses, 32-bit float WAV.
    Wav,
    /// FRFs, universal file dataset 58.
    Uff,
}

impl SimulateArgs {
    /// The simulation options these arguments ask for.
    pub fn options(&self) -> SimulateOptions {
        let method = match (&self.keep_modes, self.method) {
            (Some(k), _) => Method::Truncated(k.clone()),
            (None, MethodArg::Direct) => Method::Direct,
            (None, MethodArg::Fast) => Method::Fast,
        };
        SimulateOptions {
            method,
            modal_damping_ratios: self.modal_damping.clone(),
            snr_db: self
                .snr_db
                .filter(|_| self.snr_definition == SnrDefinition::Peak),
            seed: self.seed,
            progress: true,
            ..SimulateOptions::default()
        }
    }
}

/// The FRFs whose inverse FFT the impulse responses are (report eq. 3.1 backwards:
/// H = FFT(h)/(2 fmax) on 0, df, …, fmax), with noise if the responses carry it. The responses
/// are read whole (checked against the memory budget first).
fn frfs_of(
    source: &mut dyn Source,
    fs: f64,
) -> anyhow::Result<(f64, Vec<Vec<rustfft::num_complex::Complex<f64>>>)> {
    let frames = source.duration_frames().unwrap_or(0) as f64;
    let channels = source.info().channels() as f64;
    crate::budget::check(
        "the FRFs of the simulated set",
        channels * frames * 8.0 * 3.0,
    )?;
    let h = crate::source::memory::read_all(source, usize::MAX)?;
    let n = h.first().map_or(0, Vec::len);
    if n < 2 {
        bail!("too few samples ({n}) for FRFs");
    }
    let fft = realfft::RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let scale = 1.0 / fs;
    let frfs = h
        .into_iter()
        .map(|mut x| {
            let mut spectrum = fft.make_output_vec();
            let _ = fft.process(&mut x, &mut spectrum);
            spectrum.iter_mut().for_each(|c| *c *= scale);
            spectrum
        })
        .collect();
    Ok((fs / n as f64, frfs))
}

/// The model at `path` (or the reference plate); its mesh's warnings go to stderr.
fn load_model(path: Option<&Path>) -> anyhow::Result<Model> {
    let model = Model::load_or_reference(path)?;
    super::warn_all(&crate::sim::resolution::model_warnings(
        &model,
        model.output.fmax,
    ));
    Ok(model)
}

/// The recording-set pieces of a simulation: sensors (z, mid-plane) and excitation rows.
pub fn recording_parts(
    sensors: &[SensorWeights],
    excitation: Option<&crate::sim::model::Excitation>,
) -> (Vec<Sensor>, Vec<Excitation>) {
    let sensors = sensors
        .iter()
        .map(|s| Sensor {
            id: s.id.clone(),
            x_m: s.x_m,
            y_m: s.y_m,
            z_m: None,
            dir: "z".into(),
        })
        .collect();
    let excitation = excitation
        .iter()
        .map(|e| Excitation {
            x_m: e.x,
            y_m: e.y,
            dir: e.dir.clone(),
            force_n: e.force,
        })
        .collect();
    (sensors, excitation)
}

/// The `meta.json` of a simulated set.
pub fn meta(fs_hz: f64, snr_db: Option<f64>) -> RecordingMeta {
    RecordingMeta {
        exponential_window_tau_s: None,
        fs: Some(fs_hz),
        kind: DecayKind::ImpulseResponse,
        quantity: Some("acceleration".into()),
        unit: Some("m/s^2 per N s".into()),
        snr_db,
        scale: None,
    }
}

/// Runs `dampscope simulate`: the responses go to disk (or standard output) block by block.
pub fn run(args: &SimulateArgs) -> anyhow::Result<()> {
    let model = load_model(args.model.as_deref())?;
    let opts = args.options();
    if args.timings {
        let size = crate::sim::limits::ModelSize::of(&model);
        eprintln!("estimate before the run: {}", size.describe());
    }
    let mut r = simulate_stream(&model, &opts).context("simulation")?;
    if args.timings {
        let t = &r.timings;
        eprintln!(
            "timings: assembly {:.2} s, modes {:.2} s ({} modes), reduction {:.2} s, FRF {:.2} s ({}{} frequencies × {} sensors), impulse responses {:.2} s",
            t.assembly_s,
            t.modes_s,
            r.modes_used,
            t.reduction_s,
            t.frf_s,
            t.frf_solve.map_or(String::new(), |s| format!("{s}, ")),
            r.n_frequencies,
            r.sensors.len(),
            t.impulse_s
        );
    }
    let fs = r.fs_hz;
    // Noise on mean power needs the whole record's power first: the (small) simulated set is
    // held in memory for it.
    let mut source: Box<dyn Source> = match (args.snr_db, args.snr_definition) {
        (Some(snr), SnrDefinition::MeanPower) => {
            if !snr.is_finite() {
                bail!("--snr-db: expected a finite dB value, got {snr}");
            }
            let mut rec = Recordings::from_source(&mut r.source, usize::MAX)
                .context("reading the simulated responses")?;
            rec.add_noise_mean_power(snr, args.seed);
            Box::new(rec.into_source()?)
        }
        _ => Box::new(r.source),
    };
    if args.format == SetFormat::Uff {
        let Some(dir) = &args.out else {
            bail!("--format uff writes a recording set: give --out DIR");
        };
        let (sensors, excitation) = recording_parts(&r.sensors, Some(&r.excitation));
        let (df_hz, frfs) = frfs_of(source.as_mut(), fs)?;
        crate::output::write_recording_set_uff(
            dir,
            &meta(fs, args.snr_db),
            &sensors,
            &excitation,
            df_hz,
            &frfs,
        )
        .with_context(|| format!("writing the recording set {}", dir.display()))?;
        return Ok(());
    }
    if fs.fract() != 0.0 || fs > f64::from(u32::MAX) {
        bail!("a WAV header needs a whole number of Hz: fs = 2·fmax = {fs}");
    }
    if args.stdout {
        let stdout = io::stdout();
        let mut w = BufWriter::new(stdout.lock());
        let frames = source.duration_frames().unwrap_or(0);
        let mut out = WavStreamWriter::new(&mut w, fs as u32, r.sensors.len(), frames)
            .context("writing the WAV header to standard output")?;
        let mut block = Block::default();
        while source.read_block(STREAM_BLOCK_FRAMES, &mut block)? {
            out.write_block(&block)
                .context("writing the WAV to standard output")?;
        }
        out.finish().context("writing the WAV to standard output")?;
        w.flush().context("writing standard output")?;
        return Ok(());
    }
    let Some(dir) = &args.out else {
        bail!("give --out DIR or --stdout");
    };
    let (sensors, excitation) = recording_parts(&r.sensors, Some(&r.excitation));
    write_recording_set_streamed(
        dir,
        &meta(fs, args.snr_db),
        &sensors,
        &excitation,
        source.as_mut(),
        STREAM_BLOCK_FRAMES,
    )
    .with_context(|| format!("writing the recording set {}", dir.display()))?;
    Ok(())
}

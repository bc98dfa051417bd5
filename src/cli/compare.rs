//! `dampscope compare INPUT`: the same decays through several front ends, side by side; and
//! `dampscope compare --sweep`: the built-in study on synthetic decays with known damping.
//!
//! Compare is offline: the whole input is read into memory (at most
//! [`MAX_COMPARE_SAMPLES`] samples per channel), each channel's decay starts at its onset
//! (first sample within `--onset-level-db` of the peak) and runs to the end of the input.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context;

use super::analyze::{make_front_end, FrontEndChoice};
use super::bands_arg::{BandArgs, InputFormatArgs};
use crate::analysis::sweep::{sweep_summary, sweep_to_dir, SweepConfig};
use crate::decay::DecayEstimate;
use crate::error::{Error, Result};
use crate::frontend::goyder::FilterDirection;
use crate::frontend::onset::find_onset;
use crate::frontend::{Band, FrontEnd};
use crate::modal::{identify, ModalResult, ModalSettings, Recordings};
use crate::pipeline::analyze_decay;
use crate::source::recording_set::RecordingMeta;
use crate::source::stdin::open_input;
use crate::source::Block;

/// The `--front-ends` name of the multichannel modal estimate.
pub const MODAL_FRONT_END: &str = "modal";

/// Most samples per channel that `compare` reads (2^27 ≈ 50 min at 44.1 kHz, 1 GiB as f64).
pub const MAX_COMPARE_SAMPLES: usize = 1 << 27;

/// Options of `dampscope compare`.
#[derive(Debug, clap::Args)]
pub struct CompareArgs {
    /// A .wav or .csv file, a recording-set directory, or `-` (not needed with --sweep).
    pub input: Option<String>,
    /// How to read raw or headerless input.
    #[command(flatten)]
    pub input_format: InputFormatArgs,
    /// Bands, STFT window and evaluation range (as for analyze). `--bands` also takes
    /// `auto` (one band per spectral peak of each channel's decay), `octave`, `third-octave`.
    #[command(flatten)]
    pub bands: BandArgs,
    /// Front ends to compare, comma-separated: stft, goyder, octave, and `modal` (the
    /// multichannel identification of `dampscope modal` over the bands' range: per channel and
    /// band, the mode that carries most of that channel's energy in the band).
    #[arg(long, value_delimiter = ',', default_value = "stft,goyder")]
    pub front_ends: Vec<String>,
    /// Time direction of the Goyder and octave filters.
    #[arg(long, value_enum, default_value_t = DirectionArg::Reversed)]
    pub filter_direction: DirectionArg,
    /// Decay onset: first sample within this many dB of the peak.
    #[arg(long, default_value_t = 20.0)]
    pub onset_level_db: f64,
    /// Run the built-in sweep on synthetic decays instead of reading INPUT.
    #[arg(long)]
    pub sweep: bool,
    /// With --sweep: a reduced grid (2 frequencies × 2 dampings) for a quick look.
    #[arg(long)]
    pub sweep_reduced: bool,
    /// Directory for compare.csv, or for sweep.csv and sweep.png (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// `--filter-direction`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DirectionArg {
    /// Causal, in recording order.
    Forward,
    /// On the time-reversed decay (the decay rate is preserved).
    Reversed,
}

impl From<DirectionArg> for FilterDirection {
    fn from(d: DirectionArg) -> Self {
        match d {
            DirectionArg::Forward => FilterDirection::Forward,
            DirectionArg::Reversed => FilterDirection::Reversed,
        }
    }
}

impl From<FilterDirection> for DirectionArg {
    fn from(d: FilterDirection) -> Self {
        match d {
            FilterDirection::Forward => DirectionArg::Forward,
            FilterDirection::Reversed => DirectionArg::Reversed,
        }
    }
}

/// Resolves the band options for one decay (see [`BandArgs::resolve_with`]).
pub fn resolve_bands(
    args: &BandArgs,
    decay: &[f64],
    fs_hz: f64,
) -> Result<(Vec<Band>, Vec<String>)> {
    args.resolve_with(fs_hz, Some(&[decay]))
}

/// Builds the named front end.
pub fn build_front_end(
    name: &str,
    args: &CompareArgs,
    fs_hz: f64,
    bands: &[Band],
) -> Result<Box<dyn FrontEnd>> {
    let choice = match name.trim() {
        "stft" => FrontEndChoice::Stft,
        "goyder" => FrontEndChoice::Goyder,
        "octave" => FrontEndChoice::Octave,
        other => {
            return Err(Error::setting(
                "--front-ends",
                format!("expected stft, goyder, octave or modal, got '{other}'"),
            ))
        }
    };
    make_front_end(choice, &args.bands, args.filter_direction, fs_hz, bands)
}

fn fmt_opt(v: Option<f64>, scale: f64, digits: usize) -> String {
    v.map_or("-".into(), |x| format!("{:.*}", digits, x * scale))
}

/// One table line for one channel, band and front end.
fn table_line(channel: &str, band: &Band, fe: &dyn FrontEnd, e: &DecayEstimate) -> Vec<String> {
    let r = fe.resolution();
    vec![
        channel.to_string(),
        format!("{:.2}-{:.2}", band.lo_hz, band.hi_hz),
        format!("{}", band.nominal_hz),
        fe.name().to_string(),
        fmt_opt(e.damping_ratio_corrected.or(e.damping_ratio), 100.0, 4),
        fmt_opt(e.t60_s, 1.0, 4),
        fmt_opt(e.r2, 1.0, 5),
        e.n_points.to_string(),
        format!("{:.3}", r.frame_period_s * 1e3),
        format!("{:.3}", r.time_resolution_s * 1e3),
        format!("{:.3}", r.frequency_resolution_hz),
        e.flags
            .iter()
            .map(|f| f.as_str())
            .collect::<Vec<_>>()
            .join(";"),
        "-".into(),
        fmt_opt(e.f_dominant_hz, 1.0, 3),
    ]
}

/// The modal estimate of one channel and band: the dominant mode's D and its standard
/// deviation, T60 = 1.1/(D f), n_stable in `n_points`; flags `no_mode` (none in the band),
/// `several_modes` (the band holds more than one; the dominant one is shown),
/// `outside_modal_range` or `modal_failed` (with the reason on stderr).
fn modal_line(channel: &str, index: usize, band: &Band, modal: &ModalOutcome) -> Vec<String> {
    let mut row = vec![
        channel.to_string(),
        format!("{:.2}-{:.2}", band.lo_hz, band.hi_hz),
        format!("{}", band.nominal_hz),
        "modal".to_string(),
    ];
    let dash = || "-".to_string();
    let found = match modal {
        ModalOutcome::Failed => Err("modal_failed"),
        ModalOutcome::Done { fmax_hz, .. } if band.hi_hz > *fmax_hz => Err("outside_modal_range"),
        ModalOutcome::Done { result, .. } => result
            .dominant_mode(band.lo_hz, band.hi_hz, index)
            .ok_or("no_mode"),
    };
    match found {
        Ok((m, count)) => row.extend([
            format!("{:.4}", m.damping_ratio * 100.0),
            format!("{:.4}", 1.1 / (m.damping_ratio * m.frequency_hz)),
            dash(),
            m.n_stable.to_string(),
            dash(),
            dash(),
            dash(),
            if count > 1 { "several_modes" } else { "" }.to_string(),
            format!("{:.4}", m.damping_std * 100.0),
            format!("{:.3}", m.frequency_hz),
        ]),
        Err(flag) => {
            row.extend([dash(), dash(), dash(), "0".into(), dash(), dash(), dash()]);
            row.extend([flag.to_string(), dash(), dash()]);
        }
    }
    row
}

/// The multichannel identification behind the `modal` rows.
enum ModalOutcome {
    /// Identified up to `fmax_hz`.
    Done { result: ModalResult, fmax_hz: f64 },
    /// Identification could not run (reason printed).
    Failed,
}

/// Identifies the modes of all channels over the bands' range (clamped below the highest
/// frequency the sample rate allows), with the recording set's exponential window, if any.
fn identify_for_bands(
    fs_hz: f64,
    names: &[String],
    data: &[Vec<f64>],
    bands: &[Band],
    meta: Option<&RecordingMeta>,
) -> ModalOutcome {
    let lo = bands.iter().map(|b| b.lo_hz).fold(f64::INFINITY, f64::min);
    let hi = bands.iter().map(|b| b.hi_hz).fold(0.0, f64::max);
    let plan = crate::modal::DEFAULT_SUBBANDS;
    let fmax_hz = hi.min(0.5 * fs_hz - plan.guard_fraction * plan.max_width_hz - 1.0);
    let settings = ModalSettings {
        exponential_window_tau_s: meta.and_then(|m| m.exponential_window_tau_s),
        ..ModalSettings::new(lo.max(0.0), fmax_hz)
    };
    let rec = Recordings {
        fs_hz,
        names: names.to_vec(),
        channels: data.to_vec(),
    };
    match identify(&rec, &settings) {
        Ok(result) => ModalOutcome::Done { result, fmax_hz },
        Err(e) => {
            eprintln!("dampscope: warning: modal identification failed: {e}");
            ModalOutcome::Failed
        }
    }
}

/// Columns of the table and of compare.csv (`f_hz`: the decay's dominant frequency or the
/// mode's frequency; `d_std_pct`: the modal estimate's standard deviation).
const HEADER: [&str; 14] = [
    "channel",
    "band_hz",
    "nominal_hz",
    "front_end",
    "d_pct",
    "t60_s",
    "r2",
    "n_points",
    "frame_ms",
    "t_res_ms",
    "f_res_hz",
    "flags",
    "d_std_pct",
    "f_hz",
];

/// Sample rate, channel names, samples and the recording set's metadata of `input`.
type ReadInput = (f64, Vec<String>, Vec<Vec<f64>>, Option<RecordingMeta>);

fn read_all(args: &CompareArgs, input: &str) -> anyhow::Result<ReadInput> {
    let opts = args.input_format.options();
    let mut opened = open_input(input, &opts)?;
    let info = opened.source.info().clone();
    let mut data: Vec<Vec<f64>> = vec![Vec::new(); info.channels()];
    let mut block = Block::default();
    while opened.source.read_block(1 << 16, &mut block)? {
        for (d, c) in data.iter_mut().zip(&block.channels) {
            d.extend_from_slice(c);
        }
        anyhow::ensure!(
            data.first().map_or(0, Vec::len) <= MAX_COMPARE_SAMPLES,
            "input {input} is longer than {MAX_COMPARE_SAMPLES} samples per channel, the most compare reads"
        );
    }
    Ok((info.sample_rate_hz, info.channel_names, data, opened.meta))
}

/// Runs `compare` (or the sweep with `--sweep`).
pub fn run(args: &CompareArgs) -> anyhow::Result<()> {
    if args.sweep || args.sweep_reduced {
        let dir = args.out.clone().unwrap_or_else(|| PathBuf::from("."));
        let cfg = if args.sweep_reduced {
            SweepConfig::reduced()
        } else {
            SweepConfig::default()
        };
        let rows = sweep_to_dir(&cfg, &dir)?;
        print!("{}", sweep_summary(&rows));
        println!(
            "wrote {} and {}",
            dir.join("sweep.csv").display(),
            dir.join("sweep.png").display()
        );
        return Ok(());
    }
    let input = args
        .input
        .as_deref()
        .context("compare needs INPUT (a file, a directory or -), or --sweep")?;
    let (fs, names, data, meta) = read_all(args, input)?;
    let decay_front_ends: Vec<&String> = args
        .front_ends
        .iter()
        .filter(|n| n.trim() != MODAL_FRONT_END)
        .collect();
    let want_modal = decay_front_ends.len() < args.front_ends.len();
    let settings = args.bands.estimate()?;
    // Per channel: its index, its decay (from the onset) and its bands.
    let mut channels = Vec::new();
    for (index, (name, x)) in names.iter().zip(&data).enumerate() {
        let Some(onset) = find_onset(x, args.onset_level_db) else {
            eprintln!("dampscope: warning: channel {name} is silent; skipped");
            continue;
        };
        let decay = &x[onset..];
        let (bands, warnings) = resolve_bands(&args.bands, decay, fs)?;
        for w in warnings {
            eprintln!("dampscope: warning: {w}");
        }
        channels.push((index, decay, bands));
    }
    let modal = want_modal.then(|| {
        let all_bands: Vec<Band> = channels.iter().flat_map(|c| c.2.clone()).collect();
        identify_for_bands(fs, &names, &data, &all_bands, meta.as_ref())
    });
    let mut table: Vec<Vec<String>> = Vec::new();
    for (index, decay, bands) in &channels {
        let name = &names[*index];
        let mut per_fe = Vec::new();
        for fe_name in &decay_front_ends {
            let mut fe = build_front_end(fe_name, args, fs, bands)?;
            let est = analyze_decay(decay, fe.as_mut(), &settings);
            per_fe.push((fe, est));
        }
        for (b, band) in bands.iter().enumerate() {
            for (fe, est) in &per_fe {
                table.push(table_line(name, band, fe.as_ref(), &est[b]));
            }
            if let Some(m) = &modal {
                table.push(modal_line(name, *index, band, m));
            }
        }
    }
    print!("{}", aligned(&table));
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let path = dir.join("compare.csv");
        let mut w = csv::Writer::from_path(&path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        w.write_record(HEADER)?;
        for row in &table {
            w.write_record(row)?;
        }
        w.flush()?;
    }
    Ok(())
}

fn aligned(table: &[Vec<String>]) -> String {
    let mut widths: Vec<usize> = HEADER.iter().map(|h| h.len()).collect();
    for row in table {
        for (w, c) in widths.iter_mut().zip(row) {
            *w = (*w).max(c.chars().count());
        }
    }
    let mut out = String::new();
    let header: Vec<String> = HEADER.iter().map(|h| h.to_string()).collect();
    for row in std::iter::once(&header).chain(table) {
        for (c, w) in row.iter().zip(&widths) {
            let _ = write!(out, "{c:<w$}  ");
        }
        out.truncate(out.trim_end().len());
        out.push('\n');
    }
    out
}

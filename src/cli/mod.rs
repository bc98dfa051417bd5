//! The `dampscope` command line: one module per subcommand, each with a clap `Args` struct and a
//! `run` function, so that the binary stays a thin dispatcher and every command is testable.

pub mod analyze;
pub mod args;
pub mod bench;
pub mod compare;
pub mod demo;
pub mod diagnose;
pub mod map;
pub mod modal;
pub mod modes;
pub mod resynth;
pub mod simulate;
pub mod summarize;
pub mod synth;

use clap::{Parser, Subcommand};

/// Exit code: everything worked.
pub const EXIT_OK: i32 = 0;
/// Exit code: unusable input or a failed operation; nothing (more) could be done.
pub const EXIT_FAILURE: i32 = 1;
/// Exit code: bad command-line usage (clap's own code).
pub const EXIT_USAGE: i32 = 2;
/// Exit code: results were written, but part of the input was damaged (truncated stream,
/// NaN/Inf samples in a channel): see the flags in the table and the messages on stderr.
pub const EXIT_PARTIAL: i32 = 3;

/// Measures how a structure loses vibration energy: decay times and damping ratios per band and
/// sensor, from recordings or a finite-element plate simulation.
#[derive(Debug, Parser)]
#[command(name = "dampscope", version, about, long_about = None)]
pub struct Cli {
    /// Largest memory any step may be estimated to need, e.g. 200M or 4G (default: half of the
    /// memory the machine has available). Checked before allocating; a refusal names both.
    #[arg(long, global = true, value_name = "SIZE", value_parser = crate::budget::parse_size)]
    pub max_memory: Option<u64>,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands. Each one's arguments are built only for the one that runs (`defer`):
/// building all twelve for every run was a fifth of a short analysis's start-up. A deferred
/// subcommand's description then comes from its arguments struct's doc comment, so each
/// struct carries its variant's text (the test below holds them equal).
#[derive(Debug, Subcommand)]
#[command(defer = true)]
pub enum Command {
    /// Estimate decay times and damping ratios per band and channel (file, directory or `-`).
    Analyze(analyze::AnalyzeArgs),
    /// Run the built-in demonstration: the report's reference cases, no input files needed.
    Demo(demo::DemoArgs),
    /// Run STFT, Goyder bank and octave bank side by side on one input, or the built-in sweep.
    Compare(compare::CompareArgs),
    /// Local damping maps over the sensors and the global damping per band (recording set).
    Map(map::MapArgs),
    /// Re-synthesise the model's FRF from the global damping per band and compare (eq. 4.8).
    Resynth(resynth::ResynthArgs),
    /// Name the physics the model lacks (mass, stiffness, edge support, loss, damping law, noise), where and how much; update the model, show the fit.
    Diagnose(diagnose::DiagnoseArgs),
    /// Time the whole analysis per front end on synthetic (or given) multichannel decays.
    Bench(bench::BenchArgs),
    /// Modal identification from all channels at once: modes.csv, shapes.csv, stabilisation.png.
    Modal(modal::ModalArgs),
    /// Natural frequencies of the finite-element plate model (CSV `mode,frequency_hz`).
    Modes(modes::ModesArgs),
    /// Simulate the finite-element plate: a recording set (--out DIR) or a WAV stream (--stdout).
    Simulate(simulate::SimulateArgs),
    /// Write decaying sines (report eq. 4.5) as WAV, raw f32 or CSV (stdout or --out).
    Synth(synth::SynthArgs),
    /// Combine the decays of an analyze results table per channel and band: count, missing by reason, median/quartiles/min/max of D and T60.
    Summarize(summarize::SummarizeArgs),
}

/// Parses the command line, runs the command and returns the process exit code.
pub fn main_exit_code() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { EXIT_USAGE } else { EXIT_OK };
            let _ = e.print();
            return code;
        }
    };
    if let Some(limit) = cli.max_memory {
        crate::budget::set_process_limit(limit);
    }
    let result = match &cli.command {
        Command::Analyze(args) => analyze::run(args),
        Command::Demo(args) => demo::run(args).map(|_| EXIT_OK),
        Command::Synth(args) => synth::run(args).map(|_| EXIT_OK),
        Command::Simulate(args) => simulate::run(args).map(|_| EXIT_OK),
        Command::Modes(args) => modes::run(args).map(|_| EXIT_OK),
        Command::Modal(args) => modal::run(args).map(|_| EXIT_OK),
        Command::Compare(args) => compare::run(args).map(|_| EXIT_OK),
        Command::Map(args) => map::run(args),
        Command::Resynth(args) => resynth::run(args).map(|_| EXIT_OK),
        Command::Diagnose(args) => diagnose::run(args).map(|_| EXIT_OK),
        Command::Bench(args) => bench::run(args).map(|_| EXIT_OK),
        Command::Summarize(args) => summarize::run(args).map(|_| EXIT_OK),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("dampscope: error: {}", in_flags(&error_chain(&e)));
            EXIT_FAILURE
        }
    }
}

/// An error and its causes, joined by ": ", each cause left out where the text so far already
/// ends with it (the library's errors name their cause in their own message, so the chain
/// repeated it: "cannot read x: No such file …: No such file …").
/// Prints what the library read otherwise than the input's files said, one warning a line.
fn warn_all(warnings: &[String]) {
    for w in warnings {
        eprintln!("dampscope: warning: {w}");
    }
}

fn error_chain(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let cause = cause.to_string();
        if text.is_empty() {
            text = cause;
        } else if !text.ends_with(&cause) {
            text.push_str(": ");
            text.push_str(&cause);
        }
    }
    text
}

/// Library fields that the command line sets with a flag of the same name in kebab case
/// (`min_points` → `--min-points`).
const FIELDS_WITH_FLAGS: &[&str] = &[
    "band",
    "bands",
    "overlap",
    "window_ms",
    "zero_pad",
    "min_points",
    "noise_margin_db",
    "max_curvature_pct",
    "min_r2",
    "max_band_hz",
    "max_decay_s",
    "onset_level_db",
    "end_drop_db",
    "retrigger_db",
    "retrigger_jump_db",
    "floor_min_s",
    "floor_flat_db",
    "front_end",
    "model",
    "mode_cutoff_factor",
];

/// The library's words, and what the command line prints instead (besides
/// [`FIELDS_WITH_FLAGS`]).
const LIBRARY_TO_FLAGS: &[(&str, &str)] = &[
    (
        "invalid setting auto_bands:",
        "invalid setting --bands auto:",
    ),
    ("a model file (model)", "a model file (--model M.toml)"),
    ("raise the memory limit", "raise it with --max-memory"),
    ("the sample rate (fs_hz)", "the sample rate (--fs HZ)"),
    (
        "the channel count (channels)",
        "the channel count (--channels N)",
    ),
    ("raw samples (declared raw)", "raw samples with --raw"),
    ("the given sample rate is", "--fs says"),
    ("(give none: a WAV", "(drop --fs: a WAV"),
    (
        "a recording set or a sensor file",
        "a recording set or --sensors FILE",
    ),
];

/// `message` (a library error's text) in the command line's words: setting names become the
/// flags that set them.
fn in_flags(message: &str) -> String {
    let fields = FIELDS_WITH_FLAGS
        .iter()
        .fold(message.to_string(), |m, field| {
            m.replace(
                &format!("invalid setting {field}:"),
                &format!("invalid setting --{}:", field.replace('_', "-")),
            )
        });
    LIBRARY_TO_FLAGS
        .iter()
        .fold(fields, |m, (library, flag)| m.replace(library, flag))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cause is named once: a library error that ends with its source's text is not
    /// followed by that text again; context added over it still shows every new part.
    #[test]
    fn an_error_chain_names_each_cause_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let source = crate::source::SourceError::Io {
            what: "x.wav".into(),
            source: io,
        };
        let e = anyhow::Error::new(source);
        assert_eq!(error_chain(&e), "cannot read x.wav: no such file");
        let e = e.context("analysis");
        assert_eq!(error_chain(&e), "analysis: cannot read x.wav: no such file");
        let plain = anyhow::anyhow!("outer").context("top");
        assert_eq!(error_chain(&plain), "top: outer");
    }

    #[test]
    fn fields_become_flags() {
        assert_eq!(
            in_flags("invalid setting min_points: expected >= 2, got 1"),
            "invalid setting --min-points: expected >= 2, got 1"
        );
        assert_eq!(
            in_flags("invalid setting bands: model needs a model file (model)"),
            "invalid setting --bands: model needs a model file (--model M.toml)"
        );
    }

    /// Every subcommand's own help opens with the description the top-level help lists for
    /// it (deferred arguments bring their struct's doc comment, which must be the variant's).
    #[test]
    fn subcommand_help_opens_with_its_listed_description() {
        use clap::CommandFactory;
        let listed: Vec<(String, String)> = Cli::command()
            .get_subcommands()
            .map(|c| {
                let about = c.get_about().map(|a| a.to_string()).unwrap_or_default();
                (c.get_name().to_string(), about)
            })
            .collect();
        assert_eq!(listed.len(), 12);
        for (name, about) in listed {
            assert!(!about.is_empty(), "{name}");
            let err = Cli::command()
                .try_get_matches_from(["dampscope", name.as_str(), "--help"])
                .unwrap_err();
            let help = err.render().to_string();
            let first = help.lines().next().unwrap_or_default();
            assert_eq!(first, about, "{name}");
        }
    }
}

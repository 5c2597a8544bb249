//! The command line: one file per command (its arguments, their checks, the study, the output), argument
//! groups shared by several commands (`args.rs`) and value parsers (`parse.rs`). Lower layers never word a
//! message as a flag: each command checks its flags and says them.

mod args;
mod assemble;
mod compensate;
mod curve;
mod diagnose;
mod map;
mod parse;
mod plan;
mod plot;
mod point;
mod shard;
mod sweep;
mod synth;

use anyhow::Result;
use clap::{ArgMatches, CommandFactory, FromArgMatches, Parser, Subcommand};

/// `stiff`'s arguments.
#[derive(Parser, Debug)]
#[command(
    name = "stiff",
    version = VERSION,
    about = "Stiffness of parallel robots (units: mm, N, N mm, rad): compliance maps, one pose, force-deflection \
             curves, assembly with geometric errors, compliance error compensation, design sweeps, diagnosis against \
             measurements, synthetic measurements, measurement plans, pictures; batch runs sharded and merged",
    after_help = "Exit status: 0 success, 1 the run failed (the message says why), 2 the command line is wrong \
                  (unknown option, missing value); `diagnose --fail-on` turns a verdict into 1.\n\n\
                  Example: stiff map manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-cube.toml \
                  -o cube.csv"
)]
pub struct Cli {
    /// What to run.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
#[allow(private_interfaces)]
pub enum Command {
    /// Compliance map over a grid or a list of points, as CSV (one row per point, in input order).
    #[command(after_help = map::EXAMPLES)]
    Map(map::MapArgs),
    /// Stiffness and compliance matrices at one pose, printed with units.
    #[command(after_help = point::EXAMPLES)]
    Point(point::PointArgs),
    /// Force-deflection curve at one pose (loaded mode), as CSV.
    #[command(after_help = curve::EXAMPLES)]
    Curve(curve::CurveArgs),
    /// Assembly of legs with geometric errors (paper 000 s. 4.2): platform displacement, internal loads,
    /// joint deflections, linear and non-linear, with an optional external wrench; tolerance studies.
    #[command(after_help = assemble::EXAMPLES)]
    Assemble(assemble::AssembleArgs),
    /// Compliance error compensation: the commands that put the real robot (leg errors, corrections,
    /// process wrench) on the targets, by Newton's method or the mirror method; residuals checked.
    #[command(after_help = compensate::EXAMPLES)]
    Compensate(compensate::CompensateArgs),
    /// Where measured deflections and the model disagree: names the missing effect (or none), fits it,
    /// and writes the corrected model.
    #[command(after_help = diagnose::EXAMPLES)]
    Diagnose(diagnose::DiagnoseArgs),
    /// Synthetic measurements with hidden effects, in the format `diagnose` reads.
    #[command(after_help = synth::EXAMPLES)]
    Synth(synth::SynthArgs),
    /// Which measurements (pose and load) to take so that diagnose can name and separate the effects.
    #[command(after_help = plan::EXAMPLES)]
    Plan(plan::PlanArgs),
    /// Design study: many parameter sets of one description (factorial, Latin hypercube or a CSV), each
    /// mapped over a workspace and summarised in one row (statuses, compliance statistics, worst point).
    #[command(after_help = sweep::EXAMPLES)]
    Sweep(sweep::SweepArgs),
    /// Joins the shards of a batch run (`--shard K/N` on map, assemble, compensate, synth, sweep) into the
    /// file the unsharded run writes, after checking that each shard of the run is there exactly once.
    #[command(after_help = shard::MERGE_EXAMPLES)]
    Merge(shard::MergeArgs),
    /// An SVG picture of a study's output (map, curve or assemble CSV, or diagnose JSON).
    #[command(after_help = plot::EXAMPLES)]
    Plot(plot::PlotArgs),
    /// Shell completions for stiff, generated from its own options (bash, zsh, fish, elvish, powershell).
    #[command(after_help = "Example:\n  stiff completions bash > ~/.local/share/bash-completion/completions/stiff")]
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
    /// The manual page (roff), generated from the same definitions as --help.
    #[command(after_help = "Example:\n  stiff man > stiff.1 && man ./stiff.1")]
    Man,
}

/// The version and the git commit the binary was built from (`build.rs`; "unknown" outside a checkout).
const VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), " (", env!("STIFF_GIT_COMMIT"), ")");

/// Parses the command line and runs the command.
pub fn run() -> Result<()> {
    let matches = Cli::command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // The command's options as parsed: a shard's preamble names its run by them.
    let options = matches.subcommand().map(|(_, m)| m.clone()).unwrap_or_default();
    let options: &ArgMatches = &options;
    match cli.command {
        Command::Map(a) => map::run(a, options),
        Command::Point(a) => point::run(a),
        Command::Curve(a) => curve::run(a),
        Command::Assemble(a) => assemble::run(a, options),
        Command::Compensate(a) => compensate::run(a, options),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Synth(a) => synth::run(a, options),
        Command::Sweep(a) => sweep::run(a, options),
        Command::Merge(a) => shard::merge(a),
        Command::Plan(a) => plan::run(a),
        Command::Plot(a) => plot::run(a),
        Command::Completions { shell } => {
            let mut text = Vec::new();
            clap_complete::generate(shell, &mut Cli::command(), "stiff", &mut text);
            args::write_stdout(&String::from_utf8_lossy(&text))
        }
        Command::Man => {
            let mut text = Vec::new();
            clap_mangen::Man::new(Cli::command()).render(&mut text)?;
            args::write_stdout(&String::from_utf8_lossy(&text))
        }
    }
}

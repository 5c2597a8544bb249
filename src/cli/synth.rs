//! `stiff synth`: synthetic measurements with hidden effects.

use anyhow::{bail, Result};
use clap::{ArgMatches, Args};

use super::args::{progress_bar, thread_pool, ModelArgs, OutputArgs, PointsArgs, RunArgs};
use super::parse::parse_vec6;
use super::shard::{write_shard_preamble, ShardArgs};

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff synth manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-small.toml --effect tool-offset=0.05,0,0 --wrenches \"200,0,0,0,0,0;0,200,0,0,0,0\" --noise 0.002 --seed 7 -o data.csv
  stiff synth manipulators/orthoglide-3prpar.toml --grid manipulators/grids/orthoglide-small.toml --effect link-compliance:parallelogram=2 --wrenches \"0,0,-300,0,0,0\" --noise 0.001 --seed 1 --repeats 3 -o repeats.csv

Exit status: 0 success, 1 the run failed, 2 usage error.";

#[derive(Args, Debug)]
pub(crate) struct SynthArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// A hidden effect NAME[:TARGET]=V1,V2,... (repeatable), e.g. actuator-compliance:2=1.5, tool-offset=0.05,0,0.
    #[arg(long = "effect", value_name = "NAME[:TARGET]=VALUES")]
    pub(crate) effects: Vec<String>,
    #[command(flatten)]
    pub(crate) points: PointsArgs,
    /// Wrenches applied at every pose: Fx,Fy,Fz,Mx,My,Mz (N, N mm) separated by `;` (default: each point's
    /// own, from the points' Fx_N..Mz_Nmm columns, as `stiff plan` writes them).
    #[arg(long, allow_hyphen_values = true)]
    pub(crate) wrenches: Option<String>,
    /// Standard deviation of the measurement noise, mm.
    #[arg(long)]
    pub(crate) noise: f64,
    #[arg(long)]
    pub(crate) seed: u64,
    /// Measurements per pose and wrench.
    #[arg(long, default_value_t = 1)]
    pub(crate) repeats: usize,
    /// Measure the linear response C w with every effect as a first-order term, instead of the loaded
    /// equilibrium of the model with the hidden robot changes (payload, actuator offset, spring scalings)
    /// built in (the default: what a real robot shows, deflecting non-linearly under ordinary loads).
    #[arg(long)]
    pub(crate) linear: bool,
    #[command(flatten)]
    pub(crate) output: OutputArgs,
    #[command(flatten)]
    pub(crate) shard: ShardArgs,
    #[command(flatten)]
    pub(crate) run: RunArgs,
}

pub(crate) fn run(a: SynthArgs, matches: &ArgMatches) -> Result<()> {
    use crate::diagnose::synth;
    use crate::model::effect::Effect;
    let model = a.model.load_model()?;
    let effects = a
        .effects
        .iter()
        .map(|e| Effect::parse(e, &model.manipulator))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow::anyhow!("--effect {e}"))?;
    let wrenches = match &a.wrenches {
        Some(text) => text
            .split(';')
            .map(|w| parse_vec6(w.trim()))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| anyhow::anyhow!("--wrenches: {e}"))?,
        None => Vec::new(),
    };
    if !(a.noise >= 0.0 && a.noise.is_finite()) {
        bail!("--noise must be >= 0 (mm)");
    }
    let mut points = a.points.load()?;
    let shard = a.shard.split_points(&mut points, crate::batch::RUN, &a.output, None)?;
    let options = synth::SynthOptions {
        effects,
        wrenches,
        noise: a.noise,
        seed: a.seed,
        repeats: a.repeats,
        linear: a.linear,
        portion: shard.is_some(),
    };
    let pool = thread_pool(a.run.threads)?;
    let table = synth::synth_table();
    let mut sink = a.output.open(&table)?;
    write_shard_preamble(&shard, &mut sink, matches, "synth", table)?;
    let bar = progress_bar(points.len, a.run.quiet);
    let summary = synth::synthesize(&pool, &model, &mut points, &options, sink.writer(), &bar)?;
    sink.finish()?;
    bar.finish_and_clear();
    if summary.skipped > 0 {
        eprintln!("{} poses left out (unreachable, singular, or without a loaded equilibrium)", summary.skipped);
    }
    Ok(())
}

//! `--shard K/N` on the batch commands (map, assemble, compensate, synth, sweep), and `stiff merge`.

use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use clap::{ArgMatches, Args, CommandFactory};

use super::args::OutputArgs;
use crate::batch::shard::{file_sha256, list, RunIdentity, Shard, ShardSet};
use crate::model::grid::PointSet;
use crate::output::sink::{is_parquet, Sink};
use crate::output::table::Column;

/// Worked examples on shipped files, shown after `stiff merge --help`.
pub(crate) const MERGE_EXAMPLES: &str = "Examples:
  stiff map manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-cube.toml --shard 1/2 -o s1.csv
  stiff map manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-cube.toml --shard 2/2 -o s2.csv
  stiff merge cube.csv s1.csv s2.csv
  stiff merge --missing cube.csv s1.csv

--missing prints the numbers of the shards with no file (here 2), e.g. for sbatch --array=.

Exit status: 0 merged (or, with --missing, listed), 1 a shard is missing, foreign or given twice, 2 usage error.";

/// The flag every batch command takes.
#[derive(Args, Debug)]
pub(crate) struct ShardArgs {
    /// Solve only shard K of N (1-based: K = 1..N, as Slurm's SLURM_ARRAY_TASK_ID with --array=1-N): a
    /// contiguous portion of the input in whole runs (256 points, or one design), rows keeping their global
    /// index. The file starts with `# stiff` comment lines naming the shard and the run (a fingerprint of
    /// the version, the options and the inputs' contents); `stiff merge` joins the N files into the one the
    /// unsharded run writes. CSV only (plain, .gz or .zst); the points must be in a file.
    #[arg(long, value_name = "K/N")]
    pub(crate) shard: Option<Shard>,
}

/// A shard about to run: which, and the portion of the input it solves.
pub(crate) struct ShardPlan {
    shard: Shard,
    items: u64,
    block: u64,
    /// The input indices it solves.
    pub(crate) portion: Range<u64>,
}

impl ShardArgs {
    /// With `--shard`: refuses what a shard cannot write (Parquet, a picture) and cuts `items` (counted by
    /// the caller) into the portion this shard solves, in blocks of `block` items.
    pub(crate) fn plan(
        &self,
        items: impl FnOnce() -> Result<u64>,
        block: usize,
        output: &OutputArgs,
        plot: Option<&PathBuf>,
    ) -> Result<Option<ShardPlan>> {
        let Some(shard) = self.shard else { return Ok(None) };
        if output.output.as_deref().is_some_and(is_parquet) {
            bail!(
                "--shard writes CSV (.csv, .csv.gz or .csv.zst): `stiff merge OUT.parquet SHARDS...` writes the \
                 Parquet table"
            );
        }
        if plot.is_some() {
            bail!("--plot draws a whole run: merge the shards (stiff merge), then draw with stiff plot");
        }
        let items = items()?;
        let block = block as u64;
        Ok(Some(ShardPlan { shard, items, block, portion: shard.portion(items, block) }))
    }
}

impl ShardArgs {
    /// `plan` for the poses of a map, assembly, compensation or synth: counts them, then keeps this
    /// shard's portion in whole runs of `run` points (the study's `Study::run_length`, whose warm starts
    /// begin afresh), so that the shards' rows are the whole run's.
    pub(crate) fn split_points(
        &self,
        points: &mut PointSet,
        run: usize,
        output: &OutputArgs,
        plot: Option<&PathBuf>,
    ) -> Result<Option<ShardPlan>> {
        let plan = self.plan(|| Ok(points.count()?), run, output, plot)?;
        if let Some(p) = &plan {
            points.keep_portion(p.portion.clone())?;
        }
        Ok(plan)
    }
}

/// Writes a shard's preamble (`ShardPlan::write_preamble`) where there is one.
pub(crate) fn write_shard_preamble(
    plan: &Option<ShardPlan>,
    sink: &mut Sink,
    matches: &ArgMatches,
    command: &str,
    columns: Vec<Column>,
) -> Result<()> {
    match plan {
        Some(p) => p.write_preamble(sink.writer(), matches, command, columns),
        None => Ok(()),
    }
}

impl ShardPlan {
    /// Writes the preamble naming this shard and its run: `command`'s options as parsed in `matches`
    /// (where the output goes, threads, progress and the shard excepted), the contents of every file they
    /// name (and the files a model description reads), the input's size and the blocks, the version.
    pub(crate) fn write_preamble(
        &self,
        out: &mut dyn std::io::Write,
        matches: &ArgMatches,
        command: &str,
        columns: Vec<Column>,
    ) -> Result<()> {
        let identity = RunIdentity { lines: run_lines(matches, command, self.items, self.block)?, columns };
        identity.write_preamble(self.shard, &self.portion, out)?;
        Ok(())
    }
}

/// Options that do not change a run's rows.
const NOT_THE_RUN: [&str; 4] = ["output", "threads", "quiet", "shard"];

/// What names a run, one `name = value` line each.
fn run_lines(matches: &ArgMatches, command: &str, items: u64, block: u64) -> Result<Vec<String>> {
    let mut lines = vec![format!("version = {}", super::VERSION), format!("command = {command}")];
    let cli = super::Cli::command();
    let sub = cli.find_subcommand(command).expect("the command is one of stiff's");
    for arg in sub.get_arguments() {
        let id = arg.get_id().as_str();
        if NOT_THE_RUN.contains(&id) {
            continue;
        }
        let Ok(Some(values)) = matches.try_get_raw(id) else { continue };
        let values: Vec<String> = values.map(|v| v.to_string_lossy().into_owned()).collect();
        lines.push(format!("{id} = {}", values.join(" ")));
        for v in &values {
            let path = Path::new(v);
            if path.is_file() {
                lines.push(format!("sha256 {v} = {}", file_sha256(path)?));
                if id == "model" {
                    for other in crate::model::build::referenced_files(path)? {
                        lines.push(format!("sha256 {} = {}", other.display(), file_sha256(&other)?));
                    }
                }
            }
        }
    }
    lines.push(format!("items = {items}"));
    lines.push(format!("block = {block}"));
    Ok(lines)
}

/// `stiff merge`'s arguments.
#[derive(Args, Debug)]
pub(crate) struct MergeArgs {
    /// The merged table: `-` for stdout; .csv, .csv.gz, .csv.zst or .parquet as `-o` of the batch commands.
    pub(crate) output: PathBuf,
    /// The shard files of one run (any order).
    #[arg(required = true)]
    pub(crate) shards: Vec<PathBuf>,
    /// Write nothing: print the numbers of the shards with no file, comma-separated (empty when none is
    /// missing), e.g. for `sbatch --array=$(stiff merge --missing OUT SHARDS...)`.
    #[arg(long)]
    pub(crate) missing: bool,
}

pub(crate) fn merge(a: MergeArgs) -> Result<()> {
    let set = ShardSet::open(&a.shards)?;
    if a.missing {
        return super::args::write_stdout(&format!("{}\n", list(&set.missing)));
    }
    let out = (a.output.as_os_str() != "-").then_some(a.output.as_path());
    set.merge(out)
}

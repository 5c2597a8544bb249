//! Shards of a batch run and their merge: `--shard K/N` runs one contiguous portion of the input (points
//! or designs) and writes its rows after a preamble of comment lines that name the run; `stiff merge`
//! checks that the shards of one run are all there, once each, and writes the file the unsharded run
//! writes.
//!
//! The portions are whole runs of `block` items (`batch::RUN` points, whose warm starts begin afresh at
//! each run; one design), so every row is solved exactly as without shards and the merge is the shards'
//! rows one after the other: the same bytes, for any table (a synth pose's several rows, or none, too).

use std::fmt;
use std::io::{BufRead, Read, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use anyhow::{anyhow, bail, Context, Result};
use sha2::{Digest, Sha256};

use crate::output::sink::Sink;
use crate::output::table::{CellKind, Column};

/// Most shards of one run (a Slurm array is at most a few thousand jobs by default).
pub const MAX_SHARDS: u64 = 1_000_000;

/// What every preamble line starts with.
const PREFIX: &str = "# stiff ";

/// Shard `k` of `n` (1-based, as test runners and Slurm's array task ids count).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, 1..=n.
    pub k: u64,
    /// How many shards the run has.
    pub n: u64,
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Shard, String> {
        let usage = || format!("`{s}` is not K/N: shard K of N, 1 <= K <= N <= {MAX_SHARDS}, e.g. 2/8");
        let (k, n) = s.split_once('/').ok_or_else(usage)?;
        let (k, n): (u64, u64) = (k.trim().parse().map_err(|_| usage())?, n.trim().parse().map_err(|_| usage())?);
        if k < 1 || k > n || n > MAX_SHARDS {
            return Err(usage());
        }
        Ok(Shard { k, n })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{}/{}", self.k, self.n)
    }
}

impl Shard {
    /// The input indices this shard solves out of `items`, cut at whole blocks of `block` items: shard k
    /// takes blocks floor((k-1) B / n) up to floor(k B / n) of the B blocks (some shards are empty when
    /// there are fewer blocks than shards).
    pub fn portion(&self, items: u64, block: u64) -> Range<u64> {
        let blocks = items.div_ceil(block.max(1)) as u128;
        let edge = |k: u64| ((k as u128 * blocks / self.n as u128) as u64).saturating_mul(block).min(items);
        edge(self.k - 1)..edge(self.k)
    }
}

/// What names a run: the text its fingerprint hashes (version, command, options, inputs' contents) and
/// the table's columns.
pub struct RunIdentity {
    /// One line per element of the run, as `name = value` (the fingerprint is their SHA-256).
    pub lines: Vec<String>,
    /// The table's columns.
    pub columns: Vec<Column>,
}

impl RunIdentity {
    /// The run's fingerprint: the SHA-256 of its lines, in hex.
    pub fn fingerprint(&self) -> String {
        let mut h = Sha256::new();
        for l in &self.lines {
            h.update(l.as_bytes());
            h.update(b"\n");
        }
        hex(&h.finalize())
    }

    /// Writes the preamble of shard `shard`: its number and the run's fingerprint, the run's elements (for
    /// a reader), the kinds of the columns (for a merge into a typed table).
    pub fn write_preamble(&self, shard: Shard, portion: &Range<u64>, out: &mut dyn Write) -> std::io::Result<()> {
        writeln!(out, "{PREFIX}shard {shard} run {}", self.fingerprint())?;
        writeln!(out, "{PREFIX}portion {}..{} (input indices, end excluded)", portion.start, portion.end)?;
        for l in &self.lines {
            writeln!(out, "{PREFIX}run {}", l.replace('\n', " "))?;
        }
        writeln!(out, "{PREFIX}kinds {}", kinds_text(&self.columns))
    }
}

/// The SHA-256 of a file's bytes (as stored: a compressed file's compressed bytes), in hex.
pub fn file_sha256(path: &Path) -> std::io::Result<String> {
    let mut file = std::fs::File::open(path)?;
    let mut h = Sha256::new();
    let mut buffer = vec![0u8; 1 << 16];
    loop {
        let n = file.read(&mut buffer)?;
        if n == 0 {
            return Ok(hex(&h.finalize()));
        }
        h.update(&buffer[..n]);
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A column kind as one letter: n number, c count, t text.
fn kinds_text(columns: &[Column]) -> String {
    columns
        .iter()
        .map(|c| match c.kind {
            CellKind::Number => 'n',
            CellKind::Count => 'c',
            CellKind::Text => 't',
        })
        .collect()
}

/// A shard file as its preamble names it. Only the preamble is read when the shards are checked; a file is
/// opened again, one at a time, to copy its rows (a run of thousands of shards must not hold thousands of
/// files open: the usual limit is 1,024).
struct ShardFile {
    path: PathBuf,
    shard: Shard,
    run: String,
    kinds: String,
}

impl ShardFile {
    fn open(path: &Path) -> Result<ShardFile> {
        let mut reader = Self::reader(path)?;
        let not_shard = || {
            anyhow!(
                "{} is not a shard file (no `{PREFIX}shard K/N run ...` first line): write shards with --shard",
                path.display()
            )
        };
        let mut line = String::new();
        reader.read_line(&mut line).with_context(|| format!("cannot read {}", path.display()))?;
        let first =
            line.trim_end().strip_prefix(PREFIX).and_then(|l| l.strip_prefix("shard ")).ok_or_else(not_shard)?;
        let (shard, run) = first.split_once(" run ").ok_or_else(not_shard)?;
        let shard: Shard = shard.parse().map_err(|e| anyhow!("{}: {e}", path.display()))?;
        let run = run.to_string();
        let mut kinds = None;
        while let Some(l) = Self::comment_line(&mut reader, path)? {
            if let Some(k) = l.trim_end().strip_prefix(PREFIX).and_then(|l| l.strip_prefix("kinds ")) {
                kinds = Some(k.to_string());
            }
        }
        let kinds = kinds.ok_or_else(|| anyhow!("{}: the preamble has no `{PREFIX}kinds` line", path.display()))?;
        Ok(ShardFile { path: path.to_path_buf(), shard, run, kinds })
    }

    fn reader(path: &Path) -> Result<Box<dyn BufRead + Send>> {
        let input = crate::model::error::open_input(path)?;
        Ok(Box::new(std::io::BufReader::with_capacity(1 << 20, input)))
    }

    /// The next preamble line, or None at the table's header line (which does not start with `#`).
    fn comment_line(reader: &mut Box<dyn BufRead + Send>, path: &Path) -> Result<Option<String>> {
        if reader.fill_buf().with_context(|| format!("cannot read {}", path.display()))?.first() != Some(&b'#') {
            return Ok(None);
        }
        let mut line = String::new();
        reader.read_line(&mut line).with_context(|| format!("cannot read {}", path.display()))?;
        Ok(Some(line))
    }

    /// The file opened again past its preamble, and its table's header line (newline included).
    fn table(&self) -> Result<(Box<dyn BufRead + Send>, String)> {
        let mut reader = Self::reader(&self.path)?;
        while Self::comment_line(&mut reader, &self.path)?.is_some() {}
        let mut line = String::new();
        reader.read_line(&mut line).with_context(|| format!("cannot read {}", self.path.display()))?;
        if !line.ends_with('\n') {
            bail!(
                "{} ends before its table's header line (a shard writes one even when it has no rows)",
                self.path.display()
            );
        }
        Ok((reader, line))
    }
}

/// The shards given for a merge, checked: one run (the fingerprint most of them carry), each shard once.
pub struct ShardSet {
    files: Vec<ShardFile>,
    /// The shards the run has.
    pub n: u64,
    /// Shard numbers with no file.
    pub missing: Vec<u64>,
}

impl ShardSet {
    /// Reads the preambles of `paths`; refuses files of another run (naming them) and a shard given twice.
    pub fn open(paths: &[PathBuf]) -> Result<ShardSet> {
        let mut files = paths.iter().map(|p| ShardFile::open(p)).collect::<Result<Vec<_>>>()?;
        let Some(run) = most_common(files.iter().map(|f| (f.run.as_str(), f.shard.n))) else {
            bail!("no shard files given");
        };
        let (run, n) = (run.0.to_string(), run.1);
        let foreign: Vec<String> = files
            .iter()
            .filter(|f| f.run != run || f.shard.n != n)
            .map(|f| format!("{} (shard {}, run {})", f.path.display(), f.shard, short(&f.run)))
            .collect();
        if !foreign.is_empty() {
            bail!(
                "not shards of the run the others are (run {} in {n} shards): {} (another run differs in model, \
                 options, inputs or version, or was cut into another number of shards)",
                short(&run),
                foreign.join(", ")
            );
        }
        files.sort_by_key(|f| f.shard.k);
        for pair in files.windows(2) {
            if pair[0].shard.k == pair[1].shard.k {
                bail!(
                    "shard {} is given twice: {} and {}",
                    pair[0].shard,
                    pair[0].path.display(),
                    pair[1].path.display()
                );
            }
        }
        let present: std::collections::BTreeSet<u64> = files.iter().map(|f| f.shard.k).collect();
        let missing = (1..=n).filter(|k| !present.contains(k)).collect();
        Ok(ShardSet { files, n, missing })
    }

    /// Writes the unsharded run's table to `out` (its format by its name, as `-o`): the header, then each
    /// shard's rows in shard order.
    pub fn merge(self, out: Option<&Path>) -> Result<()> {
        if !self.missing.is_empty() {
            let (what, are) = if self.missing.len() == 1 { ("shard", "is") } else { ("shards", "are") };
            bail!(
                "{what} {} of {} {are} missing: resubmit (e.g. sbatch --array={}) and merge again; `stiff merge \
                 --missing` lists them",
                list(&self.missing),
                self.n,
                list(&self.missing)
            );
        }
        let files = self.files;
        let (_, header) = files[0].table()?;
        let names: Vec<&str> = header.trim_end().split(',').collect();
        let kinds = &files[0].kinds;
        if kinds.len() != names.len() {
            bail!(
                "{}: the preamble's kinds do not match its header's {} columns",
                files[0].path.display(),
                names.len()
            );
        }
        let columns: Vec<Column> = names
            .iter()
            .zip(kinds.chars())
            .map(|(name, k)| {
                let kind = match k {
                    'n' => CellKind::Number,
                    'c' => CellKind::Count,
                    _ => CellKind::Text,
                };
                Column { name: name.to_string(), kind }
            })
            .collect();
        let mut sink = Sink::table(out, &columns)?;
        let w = sink.writer();
        w.write_all(header.as_bytes())?;
        for f in &files {
            let (mut rows, h) = f.table()?;
            if h != header {
                bail!("{}: its table's header differs from shard 1's", f.path.display());
            }
            std::io::copy(&mut rows, w).with_context(|| format!("cannot merge {}", f.path.display()))?;
        }
        sink.finish()
    }
}

/// The (run, shard count) most files carry; the first file's where counts tie.
fn most_common<'a>(runs: impl Iterator<Item = (&'a str, u64)>) -> Option<(&'a str, u64)> {
    let mut counts: std::collections::HashMap<(&str, u64), (usize, usize)> = std::collections::HashMap::new();
    for (order, r) in runs.enumerate() {
        counts.entry(r).or_insert((0, order)).0 += 1;
    }
    // Most files first, then the earliest first seen.
    counts.into_iter().max_by(|a, b| a.1 .0.cmp(&b.1 .0).then(b.1 .1.cmp(&a.1 .1))).map(|(r, _)| r)
}

/// A fingerprint's first 12 digits, for messages.
fn short(run: &str) -> &str {
    &run[..run.len().min(12)]
}

/// Shard numbers as a comma-separated list (what `sbatch --array=` takes).
pub fn list(shards: &[u64]) -> String {
    shards.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(",")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every input index is in exactly one shard, shards are contiguous in shard order, and each cut falls
    /// on a block boundary (so warm-started runs are solved as without shards).
    #[test]
    fn portions_cover_the_input_once_at_block_boundaries() {
        for items in [0u64, 1, 255, 256, 257, 6627, 100_000] {
            for n in [1u64, 2, 3, 4, 7, 64, 1000] {
                let mut next = 0;
                for k in 1..=n {
                    let p = Shard { k, n }.portion(items, 256);
                    assert_eq!(p.start, next, "{items} items, shard {k}/{n}");
                    assert!(p.start <= p.end);
                    assert!(p.start.is_multiple_of(256) || p.start == items);
                    next = p.end;
                }
                assert_eq!(next, items, "{items} items in {n} shards");
            }
        }
    }

    #[test]
    fn shard_numbers_are_one_based_and_checked() {
        assert_eq!("2/8".parse::<Shard>(), Ok(Shard { k: 2, n: 8 }));
        for bad in ["0/4", "5/4", "1", "a/b", "1/0", "-1/4", "1/2000000"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}

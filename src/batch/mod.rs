//! The streaming routine every batch command shares (map, assemble, synth, compensate, sweep): a `Study`
//! solves one item (a pose, a design) into rows; `stream` runs it over a `Source` on the worker pool and
//! writes the rows in input order. Shards of a run and their merge: `shard`.
//!
//! A reader thread cuts the input into runs of `Study::run_length` consecutive items (`RUN` points); the worker pool solves runs in
//! parallel (each run in order, so warm starts carry from point to point); a writer thread puts the rows
//! back in input order. Runs are fixed by the input, never by the thread count, so the bytes written are
//! the same for any number of threads. At most `WINDOW_PER_THREAD` runs per worker are in flight, so
//! memory stays bounded whatever the number of points, and no worker ever waits on a block barrier.

pub mod shard;

use std::collections::BTreeMap;
use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, sync_channel};

use anyhow::{anyhow, Result};
use indicatif::ProgressBar;

use crate::model::error::InputError;
use crate::model::grid::{PointSet, PosePoint};
use crate::output::table::{header_line, Column};

/// Consecutive points solved by one worker with warm starts.
pub const RUN: usize = 256;
/// Runs in flight (being solved or waiting for their turn to be written) per worker thread.
pub const WINDOW_PER_THREAD: usize = 4;

/// Counts a study adds up over its rows.
pub trait Tally: Default + Send {
    /// Adds another run's counts.
    fn merge(&mut self, other: &Self);
}

/// Where a study's items come from, read in blocks: the poses of a grid or points file
/// (`model::grid::PointSet`), a sweep's designs.
pub trait Source: Send {
    /// What one row is solved from.
    type Item: Send;
    /// Appends up to `n` items to `out`; returns how many were added (0 at the end).
    fn next_block(&mut self, n: usize, out: &mut Vec<Self::Item>) -> Result<usize, InputError>;
    /// The input index of the first item read (not 0 where a shard's portion starts further in).
    fn first_index(&self) -> u64;
}

impl Source for PointSet {
    type Item = PosePoint;

    fn next_block(&mut self, n: usize, out: &mut Vec<PosePoint>) -> Result<usize, InputError> {
        PointSet::next_block(self, n, out)
    }

    fn first_index(&self) -> u64 {
        self.next_index()
    }
}

/// A batch study, as every streamed command runs it: a header, then the rows of each item (a pose, a
/// design) in input order, each solved by a worker with the state it carries from the previous item of its
/// run.
pub trait Study: Sync {
    /// What one row is solved from.
    type Item: Send + Sync;
    /// What a worker carries from one point to the next (warm starts); fresh at the start of each run.
    type State;
    /// Counts over the rows (the summary on stderr).
    type Tally: Tally;
    /// The table's columns (the header line, and the types of a columnar output).
    fn columns(&self) -> Vec<Column>;
    /// Items per run: consecutive items one worker solves in order, its state carried from one to the
    /// next (a shard's portion is cut at whole runs).
    fn run_length(&self) -> usize {
        RUN
    }
    /// A worker's state at the start of a run.
    fn new_state(&self) -> Self::State;
    /// Solves the item with input index `index`, appends its rows to `out` and counts it in `tally`.
    fn solve(&self, index: u64, item: &Self::Item, state: &mut Self::State, tally: &mut Self::Tally, out: &mut String);
}

/// Runs `study` over `points` on `pool`, writing its table to `out`; returns the summed tally.
pub fn stream<S: Study>(
    pool: &rayon::ThreadPool,
    study: &S,
    points: &mut dyn Source<Item = S::Item>,
    out: &mut (dyn Write + Send),
    progress: &ProgressBar,
) -> Result<S::Tally> {
    let header = header_line(&study.columns());
    stream_rows(pool, points, study.run_length(), &header, out, progress, |first_index, run| {
        let mut state = study.new_state();
        let mut tally = S::Tally::default();
        let mut text = String::with_capacity(run.len() * TYPICAL_ROW_BYTES);
        for (k, p) in run.iter().enumerate() {
            study.solve(first_index + k as u64, p, &mut state, &mut tally, &mut text);
        }
        (text, tally)
    })
}

/// The seed of point `index`'s random draws: the run's seed mixed with the index (a Weyl sequence step), so
/// a point's draws depend on neither the thread count nor the other points.
pub fn point_seed(seed: u64, index: u64) -> u64 {
    seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// A run solved: its first input index, its items, and its rows and tally, or the message of the panic
/// that stopped its worker.
type Solved<T> = (u64, usize, std::result::Result<(String, T), String>);

/// Room reserved per row (a map row with K and C is ~700 bytes; the buffer grows if needed).
const TYPICAL_ROW_BYTES: usize = 700;

/// Writes `header`, then for every run of points the text `solve_run(first_index, points)` returns, in
/// input order.
fn stream_rows<I, T, F>(
    pool: &rayon::ThreadPool,
    points: &mut dyn Source<Item = I>,
    run_length: usize,
    header: &str,
    out: &mut (dyn Write + Send),
    progress: &ProgressBar,
    solve_run: F,
) -> Result<T>
where
    I: Send,
    T: Tally,
    F: Fn(u64, &[I]) -> (String, T) + Sync,
{
    out.write_all(header.as_bytes())?;
    let window = WINDOW_PER_THREAD * pool.current_num_threads();
    let mut first_index = points.first_index();
    let (run_tx, run_rx) = sync_channel::<Result<Vec<I>>>(window);
    // Each run's rows, or the message of the panic that stopped its worker.
    let (done_tx, done_rx) = channel::<(usize, Solved<T>)>();
    let (token_tx, token_rx) = sync_channel::<()>(window);
    for _ in 0..window {
        token_tx.send(()).expect("the token channel holds the window");
    }
    // Set by the writer at its first failed write (a closed pipe, a full disk): no new run is started.
    let stop = AtomicBool::new(false);
    let stop = &stop;
    std::thread::scope(|threads| -> Result<T> {
        let reader = threads.spawn(move || loop {
            let mut run = Vec::with_capacity(run_length);
            match points.next_block(run_length, &mut run) {
                Ok(0) => break,
                Ok(_) => {
                    if run_tx.send(Ok(run)).is_err() {
                        break;
                    }
                }
                Err(e) => {
                    let _ = run_tx.send(Err(e.into()));
                    break;
                }
            }
        });
        let writer = threads.spawn(move || -> Result<T> {
            let mut tally = T::default();
            let mut pending: BTreeMap<usize, Solved<T>> = BTreeMap::new();
            let mut next = 0usize;
            let mut failure: Option<anyhow::Error> = None;
            for (index, solved) in done_rx {
                pending.insert(index, solved);
                while let Some((first, points, solved)) = pending.remove(&next) {
                    // After a failure keep draining, so that workers and the dispatcher never block.
                    match solved {
                        Ok((text, t)) if failure.is_none() => {
                            if let Err(e) = out.write_all(text.as_bytes()) {
                                failure = Some(e.into());
                                stop.store(true, Ordering::Relaxed);
                            }
                            tally.merge(&t);
                        }
                        Ok(_) => {}
                        Err(message) => {
                            if failure.is_none() {
                                failure = Some(anyhow!(
                                    "internal error: a worker stopped ({message}) on the {points} items from input \
                                     index {first}; no output file was put in place. This is a bug in stiff: please \
                                     report it with the command and its input"
                                ));
                            }
                            stop.store(true, Ordering::Relaxed);
                        }
                    }
                    progress.inc(points as u64);
                    next += 1;
                    let _ = token_tx.send(());
                }
            }
            match failure {
                Some(e) => Err(e),
                None => Ok(tally),
            }
        });
        let mut read_failure: Option<anyhow::Error> = None;
        let solve_run = &solve_run;
        pool.in_place_scope(|scope| {
            for (index, run) in run_rx.iter().enumerate() {
                let run = match run {
                    Ok(r) => r,
                    Err(e) => {
                        read_failure = Some(e);
                        break;
                    }
                };
                if token_rx.recv().is_err() || stop.load(Ordering::Relaxed) {
                    break;
                }
                let done = done_tx.clone();
                let first = first_index;
                first_index += run.len() as u64;
                scope.spawn(move |_| {
                    // A panic is a bug, but it must not hang the run: the writer waits for every run in
                    // order, and the dispatcher for the tokens the writer hands back. The panic is caught
                    // and reported as the run's outcome (its message was printed by the panic hook).
                    let solved = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| solve_run(first, &run)))
                        .map_err(|payload| {
                            payload
                                .downcast_ref::<&str>()
                                .map(|s| s.to_string())
                                .or_else(|| payload.downcast_ref::<String>().cloned())
                                .unwrap_or_else(|| "a panic".to_string())
                        });
                    let _ = done.send((index, (first, run.len(), solved)));
                });
            }
            drop(run_rx);
        });
        drop(done_tx);
        let tally = writer.join().map_err(|_| anyhow!("the writer thread panicked"))?;
        reader.join().map_err(|_| anyhow!("the reader thread panicked"))?;
        if let Some(e) = read_failure {
            return Err(e);
        }
        tally
    })
}

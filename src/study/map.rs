//! `stiff map`: the manipulator's stiffness at every point of a grid, in parallel, streamed in input order.
//!
//! Points are cut into runs of `RUN` consecutive points; one worker solves a run in order, warm-starting
//! inverse kinematics from the previous point. Runs are fixed by the input, not by the thread count, so the
//! output bytes are the same for any `--threads`. Blocks of runs are computed in parallel and written
//! before the next block is read, so memory does not grow with the number of points.

use std::io::Write;

use anyhow::Result;
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::point::{unloaded_point, Status};
use crate::model::grid::{PointSet, PosePoint};
use crate::output::table::{map_header, push_map_row, MapColumns};
use crate::platform::manipulator::Manipulator;

/// Consecutive points solved by one worker with warm starts.
pub const RUN: usize = 256;
/// Runs computed in parallel before their rows are written.
pub const RUNS_PER_BLOCK: usize = 64;

#[derive(Clone, Copy, Debug, Default)]
pub struct MapOptions {
    /// Also write the 21 entries of the stiffness matrix.
    pub stiffness: bool,
}

/// How many points ended with each status.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MapSummary {
    pub points: u64,
    pub ok: u64,
    pub unreachable: u64,
    pub singular: u64,
}

impl MapSummary {
    fn add(&mut self, s: Status) {
        self.points += 1;
        match s {
            Status::Ok => self.ok += 1,
            Status::Unreachable => self.unreachable += 1,
            Status::Singular | Status::SingularLeg => self.singular += 1,
        }
    }
    fn merge(&mut self, o: &MapSummary) {
        self.points += o.points;
        self.ok += o.ok;
        self.unreachable += o.unreachable;
        self.singular += o.singular;
    }
}

pub fn run_map(
    m: &Manipulator,
    points: &mut PointSet,
    options: MapOptions,
    out: &mut dyn Write,
    progress: &ProgressBar,
) -> Result<MapSummary> {
    let columns = MapColumns {
        orientation: points.has_orientation,
        stiffness: options.stiffness,
        deflection: points.has_wrench,
    };
    out.write_all(map_header(&columns).as_bytes())?;
    let mut block: Vec<PosePoint> = Vec::with_capacity(RUN * RUNS_PER_BLOCK);
    let mut first_index: u64 = 0;
    let mut summary = MapSummary::default();
    loop {
        block.clear();
        let n = points.next_block(RUN * RUNS_PER_BLOCK, &mut block)?;
        if n == 0 {
            break;
        }
        let texts: Vec<(String, MapSummary)> = block
            .par_chunks(RUN)
            .enumerate()
            .map(|(run, chunk)| {
                let mut state = m.new_state();
                let mut text = String::with_capacity(chunk.len() * 700);
                let mut s = MapSummary::default();
                for (k, p) in chunk.iter().enumerate() {
                    let r = unloaded_point(m, p, &mut state);
                    s.add(r.status);
                    push_map_row(
                        &mut text,
                        &columns,
                        first_index + (run * RUN + k) as u64,
                        p,
                        &r,
                    );
                }
                (text, s)
            })
            .collect();
        for (text, s) in &texts {
            out.write_all(text.as_bytes())?;
            summary.merge(s);
        }
        first_index += n as u64;
        progress.inc(n as u64);
    }
    Ok(summary)
}

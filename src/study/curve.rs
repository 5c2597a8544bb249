//! `stiff curve`: a force-deflection curve at one pose, under force control (a wrench growing along a
//! direction) or displacement control (a displacement growing along a direction), with the spectrum of the
//! tangent stiffness and stability at every step.
//!
//! Definitions (docs/GUIDE.md, "Force-deflection curves"), implemented exactly:
//! - `stable`: the symmetric part of the manipulator's tangent stiffness is positive definite (decided on the
//!   equilibrated matrix, `compliance::positive_definite`) and every leg is stable with its end held;
//!   `instability` names what failed (`platform`, `leg N`).
//! - `buckling` / `restabilised`: positive definiteness is lost / regained between two converged rows; the
//!   crossing is located by bisection between them to `BISECTION_TOLERANCE` of their interval and written
//!   in `event_load_factor`.
//! - `leg_unstable` / `leg_stable`: some leg stops / every leg starts again being stable with its end held
//!   (at the row, not bisected).
//! - `limit_point` (force control): the load factor reaches a maximum along the equilibrium path, found
//!   from the converged rows (a row whose load factor exceeds both neighbours'); the vertex of the parabola
//!   through the three rows against path length goes to `event_load_factor`. Where force control finds no
//!   equilibrium, the path is followed by displacement control (its load factor is the projection of the
//!   holding wrench on the wrench direction) for the remaining steps and never beyond `max`.
//! - `not_converged`: a row's equilibrium was not found (with the residual); the curve stops there and
//!   every earlier row is kept.

use crate::kinematics::frame::apply_twist;
use crate::kinematics::frame::{Frame, Vec6};
use crate::output::table::{header_line, names, selected_columns, write_row, Column, Record, Row};
use crate::platform::compliance::{positive_definite, spectrum, Spectrum};
use crate::platform::leg::LegFailure;
use crate::platform::loaded::Held;
use crate::platform::manipulator::{Manipulator, ManipulatorState, PoseFailure};

/// Largest number of intervals a curve accepts: each row costs a loaded equilibrium and rows are kept in
/// memory (about 300 bytes each), so a million rows is far beyond any plot and still small.
pub const MAX_INTERVALS: usize = 1_000_000;

/// Bisection of an event stops when the bracket is below this fraction of the interval between the two
/// rows (or after 60 halvings).
pub const BISECTION_TOLERANCE: f64 = 1e-9;

/// What the load factor scales.
#[derive(Clone, Copy, Debug)]
pub enum Control {
    /// The wrench is `load_factor * W`.
    Force(Vec6),
    /// The displacement is `load_factor * D` (mm, rad).
    Displacement(Vec6),
}

/// A row's outcome.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RowStatus {
    /// Converged.
    Ok,
    /// No equilibrium found at this row's target; `residual` is the largest remaining leg residual (mm or
    /// rad), NaN where the solver did not report one.
    NotConverged {
        /// The largest remaining residual.
        residual: f64,
    },
    /// The equilibrium's numbers overflowed (a load beyond what doubles hold); the curve stops there.
    Overflow,
}

/// One row of a force-deflection curve.
#[derive(Clone, Debug, PartialEq)]
pub struct CurveRow {
    /// Row number, from 0.
    pub step: usize,
    /// "force" or "displacement".
    pub control: &'static str,
    /// The load factor of the row.
    pub load_factor: f64,
    /// External wrench holding the platform (N, N mm); under force control exactly `load_factor * W`.
    pub wrench: Option<Vec6>,
    /// Platform displacement from the commanded pose (mm, rad).
    pub displacement: Option<Vec6>,
    /// Spectrum of the tangent stiffness' symmetric part (None where not converged).
    pub spectrum: Option<Spectrum>,
    /// Symmetric part of the tangent stiffness positive definite.
    pub positive_definite: bool,
    /// Legs (0-based) unstable with their end held.
    pub unstable_legs: Vec<usize>,
    /// Newton iterations.
    pub iterations: usize,
    /// Converged, not converged or overflowed.
    pub status: RowStatus,
    /// Events at this row, `;`-separated: "buckling", "restabilised", "limit_point".
    pub event: String,
    /// Where the event lies, located between this row and the previous one (bisection) or, for a limit
    /// point, by the parabola through this row and its neighbours.
    pub event_load_factor: Option<f64>,
}

impl CurveRow {
    /// The row's equilibrium was found.
    pub fn converged(&self) -> bool {
        self.status == RowStatus::Ok
    }

    /// Tangent stiffness positive definite and every leg stable.
    pub fn stable(&self) -> bool {
        self.converged() && self.positive_definite && self.unstable_legs.is_empty()
    }

    /// What makes the row unstable: `platform`, `leg N` (1-based), `;`-separated.
    pub fn instability(&self) -> String {
        if !self.converged() {
            return String::new();
        }
        let mut parts: Vec<String> = Vec::new();
        if !self.positive_definite {
            parts.push("platform".into());
        }
        parts.extend(self.unstable_legs.iter().map(|l| format!("leg {}", l + 1)));
        parts.join(";")
    }

    fn add_event(&mut self, name: &str, at: f64) {
        if !self.event.is_empty() {
            self.event.push(';');
        }
        self.event.push_str(name);
        self.event_load_factor.get_or_insert(at);
    }
}

impl Row for CurveRow {
    type Layout = ();

    fn record(&self, _: &(), r: &mut impl Record) {
        r.count("step", Some(self.step as u64));
        r.text("control", self.control);
        r.number(names::LOAD_FACTOR, self.load_factor);
        r.six(names::WRENCH, self.wrench.as_ref());
        r.six(names::DISPLACEMENT, self.displacement.as_ref());
        let s = self.spectrum;
        r.optional("k_tran_min_N_per_mm", s.map(|s| s.translational_min));
        r.optional("k_rot_min_Nmm_per_rad", s.map(|s| s.rotational_min));
        r.optional("k_scaled_min_N_per_mm", s.map(|s| s.scaled_min));
        r.prefixed_six("mode", ["dx", "dy", "dz", "rx", "ry", "rz"], s.map(|s| s.critical_mode).as_ref());
        let stable = match (self.converged(), self.stable()) {
            (false, _) => "",
            (true, true) => "true",
            (true, false) => "false",
        };
        r.text(names::STABLE, stable);
        r.text("instability", &self.instability());
        r.count(names::ITERATIONS, Some(self.iterations as u64));
        let (status, residual) = match self.status {
            RowStatus::Ok => ("ok", None),
            RowStatus::NotConverged { residual } => ("not_converged", Some(residual).filter(|r| r.is_finite())),
            RowStatus::Overflow => ("overflow", None),
        };
        r.text(names::STATUS, status);
        r.optional("residual", residual);
        r.text(names::EVENT, &self.event);
        r.optional("event_load_factor", self.event_load_factor);
    }
}

/// The header line of a curve.
pub fn curve_header() -> String {
    header_line(&curve_table())
}

/// The columns of a curve, in order.
pub fn curve_table() -> Vec<Column> {
    let blank = CurveRow {
        step: 0,
        control: "",
        load_factor: 0.0,
        wrench: None,
        displacement: None,
        spectrum: None,
        positive_definite: false,
        unstable_legs: Vec::new(),
        iterations: 0,
        status: RowStatus::Ok,
        event: String::new(),
        event_load_factor: None,
    };
    selected_columns(&blank, &(), None)
}

/// Appends one curve row as a CSV line.
pub fn push_curve_row(out: &mut String, r: &CurveRow) {
    write_row(r, &(), out);
}

/// Why a curve could not start or be written.
#[derive(Debug)]
pub enum CurveError {
    /// The commanded pose cannot be reached by some leg.
    Unreachable(PoseFailure),
    /// No equilibrium even at the first row (zero load).
    NoStart(PoseFailure),
    /// Writing a row failed (a closed pipe, a full disk).
    Write(std::io::Error),
}

impl std::fmt::Display for CurveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CurveError::Unreachable(e) => write!(f, "the commanded pose cannot be reached: {e}"),
            CurveError::NoStart(e) => write!(f, "no equilibrium at zero load: {e}"),
            CurveError::Write(e) => write!(f, "cannot write the curve: {e}"),
        }
    }
}

impl std::error::Error for CurveError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            CurveError::Write(e) => Some(e),
            _ => None,
        }
    }
}

/// One equilibrium on the curve.
#[derive(Clone)]
struct Solved {
    pose: Frame,
    held: Held,
    wrench: Vec6,
    iterations: usize,
}

/// A point of the path to solve for: a load factor under force control, or a displacement.
#[derive(Clone, Copy)]
enum Target {
    Load(f64),
    Displacement(Vec6),
}

struct Tracer<'a> {
    m: &'a Manipulator,
    at: Frame,
    control: Control,
}

impl Tracer<'_> {
    fn solve(&self, target: Target, start: &Frame, state: &mut ManipulatorState) -> Result<Solved, f64> {
        match (target, self.control) {
            (Target::Load(lambda), Control::Force(w)) => {
                let wrench = w * lambda;
                let d = self.m.deflect(&self.at, &wrench, Some(start), state).map_err(|_| f64::NAN)?;
                Ok(Solved { pose: d.pose, held: d.held, wrench, iterations: d.iterations })
            }
            (Target::Load(lambda), Control::Displacement(d)) => self.hold(&(d * lambda), state),
            (Target::Displacement(d), _) => self.hold(&d, state),
        }
    }

    fn hold(&self, displacement: &Vec6, state: &mut ManipulatorState) -> Result<Solved, f64> {
        let pose = apply_twist(&self.at, displacement);
        let held = self.m.hold(&pose, state).map_err(|e| residual_of(&e))?;
        Ok(Solved { pose, held, wrench: held.force, iterations: held.iterations })
    }

    /// The load factor a solution stands for: the applied factor under force control (or the projection of
    /// the holding wrench on W on the displacement-controlled continuation), the displacement factor
    /// under displacement control.
    fn load_factor(&self, target: Target, s: &Solved) -> f64 {
        match (target, self.control) {
            (Target::Load(lambda), _) => lambda,
            (Target::Displacement(_), Control::Force(w)) => s.wrench.dot(&w) / w.dot(&w),
            (Target::Displacement(d), Control::Displacement(dir)) => d.dot(&dir) / dir.dot(&dir),
        }
    }

    fn row(&self, step: usize, target: Target, s: &Solved) -> CurveRow {
        let by_force = matches!(target, Target::Load(_)) && matches!(self.control, Control::Force(_));
        let finite = s.wrench.iter().chain(s.held.stiffness.iter()).all(|v| v.is_finite())
            && self.at.error_to(&s.pose).iter().all(|v| v.is_finite());
        if !finite {
            let mut row = not_converged_row(step, self, target, f64::NAN);
            row.status = RowStatus::Overflow;
            return row;
        }
        CurveRow {
            step,
            control: if by_force { "force" } else { "displacement" },
            load_factor: self.load_factor(target, s),
            wrench: Some(s.wrench),
            displacement: Some(self.at.error_to(&s.pose)),
            spectrum: spectrum(&s.held.stiffness, self.m.length_scale),
            positive_definite: positive_definite(&s.held.stiffness, &s.held.magnitude, self.m.length_scale),
            unstable_legs: s.held.unstable_legs().collect(),
            iterations: s.iterations,
            status: RowStatus::Ok,
            event: String::new(),
            event_load_factor: None,
        }
    }

    /// Bisects between two solved targets for the change of positive definiteness; returns the load factor
    /// at the crossing (the middle of the last bracket).
    fn locate_crossing(&self, from: (Target, &Solved, &ManipulatorState), to: (Target, &Solved)) -> f64 {
        let ((a_target, a_solved, a_state), (b_target, b_solved)) = (from, to);
        let blend = |s: f64| match (a_target, b_target) {
            (Target::Load(a), Target::Load(b)) => Target::Load(a + (b - a) * s),
            (Target::Displacement(a), Target::Displacement(b)) => Target::Displacement(a + (b - a) * s),
            (_, b) => b, // not reached: the caller passes targets of one kind
        };
        let pd_a = positive_definite(&a_solved.held.stiffness, &a_solved.held.magnitude, self.m.length_scale);
        let smallest = |s: &Solved| spectrum(&s.held.stiffness, self.m.length_scale).map_or(f64::NAN, |e| e.scaled_min);
        // (parameter, load factor, smallest scaled eigenvalue) at both ends of the bracket.
        let mut lo = (0.0f64, self.load_factor(a_target, a_solved), smallest(a_solved));
        let mut hi = (1.0f64, self.load_factor(b_target, b_solved), smallest(b_solved));
        // Every trial starts from the row before the crossing, so that it follows the branch the rows
        // followed (past a bifurcation, a start nearer the crossing can slide onto the other branch).
        for _ in 0..60 {
            if hi.0 - lo.0 <= BISECTION_TOLERANCE {
                break;
            }
            let mid = 0.5 * (lo.0 + hi.0);
            let mut trial = a_state.clone();
            // Near the critical load Newton's matrix is nearly singular and a solve may fail: the bracket
            // found so far is then interpolated.
            let Ok(solved) = self.solve(blend(mid), &a_solved.pose, &mut trial) else { break };
            let point = (mid, self.load_factor(blend(mid), &solved), smallest(&solved));
            if positive_definite(&solved.held.stiffness, &solved.held.magnitude, self.m.length_scale) == pd_a {
                lo = point;
            } else {
                hi = point;
            }
        }
        // Linear interpolation of the smallest eigenvalue across the final bracket (its midpoint where the
        // eigenvalues are not finite or do not straddle zero).
        let (e_lo, e_hi) = (lo.2, hi.2);
        if e_lo.is_finite() && e_hi.is_finite() && (e_lo - e_hi).abs() > 0.0 && e_lo * e_hi <= 0.0 {
            lo.1 + (hi.1 - lo.1) * e_lo / (e_lo - e_hi)
        } else {
            0.5 * (lo.1 + hi.1)
        }
    }
}

fn residual_of(e: &PoseFailure) -> f64 {
    match e.failure {
        LegFailure::NotConverged { residual, .. } => residual,
        LegFailure::Unreachable(f) => f.residual_mm,
        _ => f64::NAN,
    }
}

/// The curve's rows in a Vec (for library users and tests; `run_curve` streams them).
pub fn curve_rows(
    m: &Manipulator,
    at: &Frame,
    control: Control,
    max: f64,
    intervals: usize,
) -> Result<Vec<CurveRow>, CurveError> {
    let mut rows = Vec::new();
    run_curve(m, at, control, max, intervals, &mut |r| {
        rows.push(r.clone());
        Ok(())
    })?;
    Ok(rows)
}

/// The curve from zero to `max` in `intervals` equal steps (rows 0..=intervals), each row handed to `emit`
/// as soon as it is final (one row behind the computation: a limit point needs the next row). Memory does
/// not grow with the number of rows. `intervals` must lie in 1..=`MAX_INTERVALS` and `max` be positive and
/// finite (checked by the caller, which words the message). Returns the summary of the rows written.
pub fn run_curve(
    m: &Manipulator,
    at: &Frame,
    control: Control,
    max: f64,
    intervals: usize,
    emit: &mut dyn FnMut(&CurveRow) -> std::io::Result<()>,
) -> Result<CurveSummary, CurveError> {
    run_curve_from(m, at, m.new_state(), control, max, intervals, emit)
}

/// `run_curve` from `state` (seeded at a serial arm's joint coordinates, so that the placement at `at` keeps
/// that configuration).
pub fn run_curve_from(
    m: &Manipulator,
    at: &Frame,
    mut state: ManipulatorState,
    control: Control,
    max: f64,
    intervals: usize,
    emit: &mut dyn FnMut(&CurveRow) -> std::io::Result<()>,
) -> Result<CurveSummary, CurveError> {
    assert!((1..=MAX_INTERVALS).contains(&intervals) && max.is_finite() && max > 0.0, "checked by the caller");
    let tracer = Tracer { m, at: *at, control };
    m.place(at, &mut state).map_err(CurveError::Unreachable)?;
    let mut rows = Window {
        recent: Vec::with_capacity(3),
        limit_points: matches!(control, Control::Force(_)),
        emit,
        summary: CurveSummary::default(),
    };
    // The last converged row: its target, solution and state (the warm start and the bisection bracket).
    let mut last: Option<(Target, Solved, ManipulatorState)> = None;
    // After force control found no equilibrium: the displacement increment per row of the continuation.
    let mut continuation: Option<Vec6> = None;
    for step in 0..=intervals {
        let lambda = max * step as f64 / intervals as f64;
        let start = last.as_ref().map_or(*at, |(_, s, _)| s.pose);
        let mut attempt = None;
        if continuation.is_none() {
            let target = Target::Load(lambda);
            let mut trial = state.clone();
            match tracer.solve(target, &start, &mut trial) {
                Ok(s) => {
                    state = trial;
                    attempt = Some((target, Ok(s)));
                }
                Err(residual) => match (control, &last) {
                    (Control::Force(w), Some((_, prev, _))) => {
                        continuation = continuation_step(&rows.rows(), prev, &(w * (max / intervals as f64)));
                        if continuation.is_none() {
                            attempt = Some((target, Err(residual)));
                        }
                    }
                    _ => attempt = Some((target, Err(residual))),
                },
            }
        }
        if let (Some(increment), None) = (continuation, &attempt) {
            let prev = rows.last().and_then(|r| r.displacement).unwrap_or_else(Vec6::zeros);
            let target = Target::Displacement(prev + increment);
            attempt = Some((target, tracer.solve(target, &start, &mut state)));
        }
        let (target, outcome) = attempt.expect("one of the two branches ran");
        match outcome {
            Ok(solved) => {
                let mut row = tracer.row(step, target, &solved);
                if row.status == RowStatus::Overflow {
                    rows.push(row)?;
                    break;
                }
                if continuation.is_some() && row.load_factor > max {
                    break; // never beyond --max in the quantity the user gave
                }
                if let Some((prev_target, prev_solved, prev_state)) = &last {
                    let was = rows.last().is_some_and(|r| r.positive_definite);
                    if was != row.positive_definite {
                        // Across the switch to displacement control, bisect in displacement from the
                        // previous row's equilibrium (holding it there is the same equilibrium).
                        let from = match (same_kind(*prev_target, target), rows.last().and_then(|r| r.displacement)) {
                            (false, Some(d)) => Target::Displacement(d),
                            _ => *prev_target,
                        };
                        let at = tracer.locate_crossing((from, prev_solved, prev_state), (target, &solved));
                        row.add_event(if was { "buckling" } else { "restabilised" }, at);
                    }
                }
                if let Some(prev) = rows.last().filter(|r| r.converged()) {
                    match (prev.unstable_legs.is_empty(), row.unstable_legs.is_empty()) {
                        (true, false) => row.add_event("leg_unstable", row.load_factor),
                        (false, true) => row.add_event("leg_stable", row.load_factor),
                        _ => {}
                    }
                }
                rows.push(row)?;
                last = Some((target, solved, state.clone()));
            }
            Err(residual) => {
                if rows.summary.rows == 0 && rows.recent.is_empty() {
                    let failure = m.hold(at, &mut state).err();
                    return Err(CurveError::NoStart(failure.unwrap_or(PoseFailure {
                        leg: 0,
                        failure: LegFailure::NotConverged { iterations: 0, residual },
                    })));
                }
                rows.push(not_converged_row(step, &tracer, target, residual))?;
                break;
            }
        }
    }
    rows.finish().map_err(CurveError::Write)
}

/// The rows not yet written: a row is final once the next one is known (a limit point is a converged row
/// whose load factor exceeds both neighbours'), so at most three are held, with their path lengths.
struct Window<'e> {
    recent: Vec<(CurveRow, f64)>,
    /// Mark limit points (force control).
    limit_points: bool,
    emit: &'e mut dyn FnMut(&CurveRow) -> std::io::Result<()>,
    summary: CurveSummary,
}

impl Window<'_> {
    /// The rows held, oldest first.
    fn rows(&self) -> Vec<&CurveRow> {
        self.recent.iter().map(|(r, _)| r).collect()
    }

    fn last(&self) -> Option<&CurveRow> {
        self.recent.last().map(|(r, _)| r)
    }

    fn push(&mut self, row: CurveRow) -> Result<(), CurveError> {
        let path = match (self.recent.last(), row.displacement) {
            (Some((prev, s)), Some(d)) => s + prev.displacement.map_or(0.0, |p| (d - p).norm()),
            (Some((_, s)), None) => *s,
            (None, _) => 0.0,
        };
        self.recent.push((row, path));
        if self.recent.len() == 3 {
            if self.limit_points {
                mark_limit_point(&mut self.recent);
            }
            let (first, _) = self.recent.remove(0);
            self.write(first).map_err(CurveError::Write)?;
        }
        Ok(())
    }

    fn write(&mut self, row: CurveRow) -> std::io::Result<()> {
        self.summary.add(&row);
        (self.emit)(&row)
    }

    fn finish(mut self) -> std::io::Result<CurveSummary> {
        for (row, _) in std::mem::take(&mut self.recent) {
            self.write(row)?;
        }
        Ok(self.summary)
    }
}

fn same_kind(a: Target, b: Target) -> bool {
    matches!((a, b), (Target::Load(_), Target::Load(_)) | (Target::Displacement(_), Target::Displacement(_)))
}

/// The displacement increment that continues the path past a failed force step: the last increment along
/// the path, or at the first step the tangent compliance times the load increment.
fn continuation_step(rows: &[&CurveRow], prev: &Solved, load_step: &Vec6) -> Option<Vec6> {
    let n = rows.len();
    if n >= 2 {
        if let (Some(a), Some(b)) = (rows[n - 2].displacement, rows[n - 1].displacement) {
            return Some(b - a).filter(|d| d.norm() > 0.0);
        }
    }
    prev.held.stiffness.lu().solve(load_step).filter(|d| d.iter().all(|v| v.is_finite()))
}

fn not_converged_row(step: usize, tracer: &Tracer, target: Target, residual: f64) -> CurveRow {
    let (control, load_factor, displacement) = match (target, tracer.control) {
        (Target::Load(l), Control::Force(_)) => ("force", l, None),
        (Target::Load(l), Control::Displacement(d)) => ("displacement", l, Some(d * l)),
        (Target::Displacement(d), _) => ("displacement", f64::NAN, Some(d)),
    };
    CurveRow {
        step,
        control,
        load_factor,
        wrench: None,
        displacement,
        spectrum: None,
        positive_definite: false,
        unstable_legs: Vec::new(),
        iterations: 0,
        status: RowStatus::NotConverged { residual },
        event: String::new(),
        event_load_factor: None,
    }
}

/// A limit point: the middle of three consecutive converged rows, its load factor above both neighbours'
/// along the path; the maximum of the parabola through the three (against path length) locates it.
fn mark_limit_point(three: &mut [(CurveRow, f64)]) {
    let [(a, pa), (b, pb), (c, pc)] = three else { return };
    if a.converged() && b.converged() && c.converged() && b.load_factor > a.load_factor && b.load_factor > c.load_factor
    {
        let peak = parabola_peak((*pa, a.load_factor), (*pb, b.load_factor), (*pc, c.load_factor));
        b.add_event("limit_point", peak);
    }
}

/// The largest value of the parabola through three points (the middle one highest).
fn parabola_peak(p0: (f64, f64), p1: (f64, f64), p2: (f64, f64)) -> f64 {
    let (x0, y0) = p0;
    let (x1, y1) = p1;
    let (x2, y2) = p2;
    let d = (x0 - x1) * (x0 - x2) * (x1 - x2);
    if d.abs() <= f64::MIN_POSITIVE {
        return y1;
    }
    let a = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / d;
    let b = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / d;
    let c = y1 - a * x1 * x1 - b * x1;
    if a >= 0.0 {
        return y1;
    }
    (c - b * b / (4.0 * a)).max(y1)
}

/// The first buckling crossing (bisected), if any.
pub fn critical_load_factor(rows: &[CurveRow]) -> Option<f64> {
    rows.iter().find(|r| r.event.split(';').any(|e| e == "buckling")).and_then(|r| r.event_load_factor)
}

/// What the closing summary says, accumulated from the rows as they are written (so it is derived from
/// exactly the rows of the CSV).
#[derive(Clone, Debug, Default)]
pub struct CurveSummary {
    /// Rows written.
    pub rows: usize,
    /// First converged row: positive definite, load factor.
    first: Option<(bool, f64)>,
    /// A converged row that is not positive definite was seen.
    any_indefinite: bool,
    last_load_factor: Option<f64>,
    /// (step, event, where), the first `MAX_EVENTS_LISTED`.
    events: Vec<(usize, String, Option<f64>)>,
    more_events: usize,
    first_unstable_legs: Option<(usize, String)>,
    first_force_row: bool,
    switched_at: Option<usize>,
    stopped: Option<(usize, RowStatus)>,
}

/// Events listed in the summary (an oscillating path could have thousands).
const MAX_EVENTS_LISTED: usize = 20;

impl CurveSummary {
    fn add(&mut self, r: &CurveRow) {
        if self.rows == 0 {
            self.first_force_row = r.control == "force";
        }
        self.rows += 1;
        if self.first_force_row && r.control == "displacement" && self.switched_at.is_none() {
            self.switched_at = Some(r.step);
        }
        if !r.converged() {
            self.stopped = Some((r.step, r.status));
            return;
        }
        self.first.get_or_insert((r.positive_definite, r.load_factor));
        self.any_indefinite |= !r.positive_definite;
        self.last_load_factor = Some(r.load_factor);
        if !r.unstable_legs.is_empty() && self.first_unstable_legs.is_none() {
            let legs: Vec<String> = r.unstable_legs.iter().map(|l| format!("leg {}", l + 1)).collect();
            self.first_unstable_legs = Some((r.step, legs.join(", ")));
        }
        for e in r.event.split(';').filter(|e| !e.is_empty()) {
            if self.events.len() < MAX_EVENTS_LISTED {
                self.events.push((r.step, e.to_string(), r.event_load_factor));
            } else {
                self.more_events += 1;
            }
        }
    }

    /// The closing summary on stderr.
    pub fn text(&self, length_scale: f64) -> String {
        let mut lines = Vec::new();
        match (self.first, self.last_load_factor) {
            (Some((false, at)), _) => lines.push(format!(
                "the tangent stiffness is not positive definite at the start (load factor {at}): the manipulator is \
                 singular or unstable there"
            )),
            (Some((true, _)), Some(last)) if !self.any_indefinite => {
                lines.push(format!("the tangent stiffness stays positive definite up to load factor {last}"))
            }
            _ => {}
        }
        for (step, e, at) in &self.events {
            let at = at.map_or(String::from("?"), |v| format!("{v:.6}"));
            let what = match e.as_str() {
                "buckling" => "the tangent stiffness stops being positive definite (buckling)",
                "restabilised" => "the tangent stiffness is positive definite again",
                "limit_point" => "the load reaches a maximum (limit point)",
                "leg_unstable" => "a leg becomes unstable with its end held (see the instability column)",
                "leg_stable" => "every leg is stable again",
                other => other,
            };
            lines.push(format!("step {step}: {what} at load factor {at}"));
        }
        if self.more_events > 0 {
            lines.push(format!("... and {} more events (see the event column)", self.more_events));
        }
        if let Some(step) = self.switched_at {
            lines.push(format!(
                "from step {step}, no equilibrium under force control: path followed by displacement control"
            ));
        }
        if let Some((step, legs)) = &self.first_unstable_legs {
            lines.push(format!("from step {step}, {legs} unstable with its end held: the curve is unstable there"));
        }
        match self.stopped {
            Some((step, RowStatus::Overflow)) => lines.push(format!(
                "step {step}: the numbers overflowed (a load beyond what doubles hold); the curve stops there ({} rows \
                 written)",
                self.rows
            )),
            Some((step, _)) => lines
                .push(format!("step {step}: no equilibrium found; the curve stops there ({} rows written)", self.rows)),
            None => {}
        }
        lines.push(format!(
            "k_scaled_min weighs rotations by the model's length scale, {length_scale:.6} mm/rad (docs/GUIDE.md: force-deflection curves)"
        ));
        lines.join("\n")
    }
}

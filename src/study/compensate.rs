//! `stiff compensate`: compliance error compensation along a tool path (paper 000 s. 5.2 and conclusion;
//! its ref. [73], Klimchik, Pashkevich, Chablat, Hovland, "Compliance error compensation technique for
//! parallel robots composed of non-perfect serial chains", Robotics and Computer-Integrated Manufacturing 29
//! (2013) 385-393).
//!
//! The controller knows only the nominal geometry: a commanded pose c becomes actuator coordinates a(c) by
//! the nominal inverse kinematics. The real robot (the description with its corrections, plus the legs'
//! errors) holds its actuators at a(c) and settles under the process wrench at P(c). For every target T
//! the study finds the command with P(c) = T in the directions the actuators move the platform (the
//! reference point for a translational robot, the whole pose for a Stewart platform): Newton's method on
//! the command, started from the better of the mirror command c = T - (P(T) - T) of [73] and the command
//! extrapolated from the targets before along a line, with the Jacobian dP/dc from differences of loaded
//! equilibria where needed and Broyden's secant updates otherwise, carried from one target to the next
//! along the path. Newton's evaluations need only the pose the robot settles at (`Manipulator::settle`).
//! The command found is checked by an independent forward solve with stability
//! (`Manipulator::settle_stable`): the command placed by its own inverse kinematics and the real robot's
//! equilibrium with those actuator coordinates, from the last forward solve's equilibrium (as a controller
//! stepping along the path would see it; at a run's first target, from the uncompensated equilibrium), never
//! from Newton's evaluations. The extrapolated command, Newton's first, is evaluated by that forward solve:
//! where it meets the tolerance (along a fine path, nearly every target) it is the check, and the target
//! costs three loaded equilibria instead of four.

use std::borrow::Cow;
use std::io::Write;

use anyhow::Result;
use indicatif::ProgressBar;

use super::assemble::{real_manipulator, LegErrors};
use super::map::MapSummary;
use super::point::Status;
use super::warm_start::{LoadedHistory, Trail};
use crate::batch::{stream, Study, Tally};
use crate::kinematics::frame::{apply_twist, rotation_vector, weigh_rotations, Frame, Mat6, Vec6};
use crate::linalg::SmallLu;
use crate::model::grid::{PointSet, PosePoint};
use crate::output::table::{header_line, names, Column, Record, Row};
use crate::platform::command::Directions;
use crate::platform::loaded::DeflectionFailure;
use crate::platform::manipulator::{Manipulator, ManipulatorState};

/// How the command is computed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Method {
    /// Newton's method on the command until the real robot reaches the target.
    #[default]
    Newton,
    /// The first-order correction of [73]: command = target - the error predicted at the target.
    Mirror,
}

impl Method {
    /// Its name in the table and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Newton => "newton",
            Method::Mirror => "mirror",
        }
    }
}

/// What `stiff compensate` computes.
#[derive(Clone, Copy, Debug, Default)]
pub struct CompensateOptions {
    /// The process wrench at every target (N, N mm at the reference point); None: each point's own wrench
    /// (zero where it gives none).
    pub wrench: Option<Vec6>,
    /// How the command is computed.
    pub method: Method,
    /// Factor on every leg error.
    pub scale: f64,
    /// Only what a controller needs (Newton's method): the command, its actuator coordinates and the forward
    /// solve that checks it. Along a path the command extrapolated from the last targets is evaluated
    /// first and, where it meets the tolerance with the robot stable there, is the target's answer: the
    /// uncompensated and mirror equilibria are not solved, and their columns stay empty at every target.
    pub commands_only: bool,
}

/// Targets per run of the study (`Study::run_length`): 8 times a map's, so that the cold start of each run
/// (about 20 targets' work on the milling path with Case B errors) costs about 1% of the run, while 100,000
/// targets still make 49 runs to share between threads.
pub const COMPENSATE_RUN: usize = 8 * crate::batch::RUN;

/// The compensated command meets the target within this (mm, rotations weighted by the length scale), in
/// the directions the actuators move the platform: far below any machining tolerance, and 25 times what
/// separates two solves of one loaded equilibrium from different starts (up to 4e-10 mm on the milling
/// path of paper 000 s. 5.2 with Case A errors), so that the noise of the evaluations never stalls Newton.
pub const COMMAND_TOLERANCE_MM: f64 = 1e-8;
/// Most commands tried per target after the mirror command (along a fine path one or two).
pub const MAX_COMMAND_ITERATIONS: usize = 30;
/// A Newton step that does not shrink the residual at least by this factor refreshes the Jacobian by
/// differences (Broyden's updates have drifted, or the path jumped).
const CONTRACTION: f64 = 0.5;
/// Step of the Jacobian's one-sided differences, mm: truncation ~1e-7 relative (curvatures ~1e-3/mm),
/// round-off 1e-12 / 1e-4 = 1e-8.
const DIFFERENCE_STEP_MM: f64 = 1e-4;
/// Broyden's update is skipped for a smaller step (mm): its secant would carry the evaluations' noise
/// (~1e-10 mm) as a relative error above 1e-5.
const SECANT_MIN_STEP_MM: f64 = 1e-5;
/// Halvings of a step whose command cannot be reached (leaves the workspace) before giving up.
const MAX_HALVINGS: usize = 12;
/// The independent forward solve must agree with Newton's last evaluation within this (mm): two different
/// equilibria reached from two starts mean the robot's pose depends on its history (near a limit point).
const CHECK_AGREEMENT_MM: f64 = 1e-6;

/// The commands of one target, and how good they are.
#[derive(Clone, Debug)]
pub struct Compensation {
    /// How it ended.
    pub status: Status,
    /// The real robot's error with the target as command: P(T) - T (translation mm, rotation vector).
    pub uncompensated: Option<Vec6>,
    /// Its error with the mirror command.
    pub mirror: Option<Vec6>,
    /// The command (the pose the nominal inverse kinematics is given).
    pub command: Option<Frame>,
    /// The actuator coordinates the command gives, every leg's in turn (mm or rad).
    pub actuators: Vec<f64>,
    /// For a serial arm, the same command in its controller's angles (the inverse of its `controller` map).
    pub controller: Option<Vec<f64>>,
    /// The error with the command, from an independent forward solve.
    pub residual: Option<Vec6>,
    /// Commands evaluated after the mirror command: the extrapolated one and Newton's steps (None for the
    /// mirror method).
    pub iterations: Option<usize>,
    /// Loaded equilibria solved for this target.
    pub equilibria: usize,
}

impl Compensation {
    fn failed(status: Status) -> Self {
        Compensation {
            status,
            uncompensated: None,
            mirror: None,
            command: None,
            actuators: Vec::new(),
            controller: None,
            residual: None,
            iterations: None,
            equilibria: 0,
        }
    }
}

/// What fixes a compensation table's columns: the actuated coordinates' names.
#[derive(Clone, Debug)]
pub struct CompensateLayout {
    /// `leg{i}_actuator{j}_{unit}`, leg by leg.
    pub actuators: Vec<Vec<String>>,
    /// For a serial arm: the columns of the command in its controller's angles (`command_q_<joint>_<unit>`).
    pub arm: Option<Vec<String>>,
}

impl CompensateLayout {
    /// The columns for `m`'s actuated coordinates.
    pub fn new(m: &Manipulator) -> Self {
        let actuators = (m.actuator_units().iter().enumerate())
            .map(|(i, units)| {
                units.iter().enumerate().map(|(j, u)| format!("leg{}_actuator{}_{u}", i + 1, j + 1)).collect()
            })
            .collect();
        let arm = m.joint_space.as_ref().map(|space| {
            let units = m.actuator_units();
            (space.names.iter().enumerate())
                .map(|(k, n)| {
                    let unit = units.first().and_then(|u| u.get(k)).copied().unwrap_or("rad");
                    format!("command_q_{n}_{unit}")
                })
                .collect()
        });
        CompensateLayout { actuators, arm }
    }
}

/// One row of a compensation table.
pub struct CompensationRow<'a> {
    /// Row number in input order.
    pub index: u64,
    /// The target.
    pub point: &'a PosePoint,
    /// The process wrench at the target.
    pub wrench: Vec6,
    /// The method.
    pub method: Method,
    /// What was found.
    pub result: &'a Compensation,
}

/// The position error's length (mm).
fn error_mm(e: &Vec6) -> f64 {
    e.fixed_rows::<3>(0).norm()
}

impl Row for CompensationRow<'_> {
    type Layout = CompensateLayout;

    fn record(&self, l: &CompensateLayout, r: &mut impl Record) {
        let (p, res) = (self.point, self.result);
        super::point::record_pose(r, self.index, p, true);
        r.six(names::WRENCH, Some(&self.wrench));
        r.text(names::STATUS, res.status.as_str());
        r.text(names::METHOD, self.method.as_str());
        let command = res.command.map(|c| {
            let rv = rotation_vector(&c.rot);
            Vec6::new(c.pos.x, c.pos.y, c.pos.z, rv.x, rv.y, rv.z)
        });
        r.six(names::COMMAND, command.as_ref());
        for (k, name) in l.actuators.iter().flatten().enumerate() {
            r.optional(name, res.actuators.get(k).copied());
        }
        for (k, name) in l.arm.iter().flatten().enumerate() {
            r.optional(name, res.controller.as_ref().map(|a| a[k]));
        }
        for (prefix, e) in
            [(names::UNCOMPENSATED, &res.uncompensated), (names::MIRROR, &res.mirror), (names::RESIDUAL, &res.residual)]
        {
            r.prefixed_six(prefix, names::DISPLACEMENT, e.as_ref());
            r.optional(format_args!("{prefix}_error_mm"), e.as_ref().map(error_mm));
        }
        r.count(names::ITERATIONS, res.iterations.map(|n| n as u64));
    }
}

/// The columns a compensation of `m` writes, in order.
pub fn compensate_table(m: &Manipulator) -> Vec<Column> {
    let point = PosePoint::default();
    let blank = Compensation::failed(Status::Ok);
    let row =
        CompensationRow { index: 0, point: &point, wrench: Vec6::zeros(), method: Method::Newton, result: &blank };
    crate::output::table::selected_columns(&row, &CompensateLayout::new(m), None)
}

/// The CSV header of a compensation of `m`.
pub fn compensate_header(m: &Manipulator) -> String {
    header_line(&compensate_table(m))
}

/// Counts of a compensation run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CompensateSummary {
    /// Targets by status.
    pub statuses: MapSummary,
    /// Commands tried after the mirror command (the extrapolated one, Newton steps), over all targets.
    pub iterations: u64,
    /// Loaded equilibria solved, over all targets.
    pub equilibria: u64,
}

impl Tally for CompensateSummary {
    fn merge(&mut self, o: &Self) {
        self.statuses.merge(&o.statuses);
        self.iterations += o.iterations;
        self.equilibria += o.equilibria;
    }
}

impl CompensateSummary {
    /// `N targets: a ok, ...; m commands after the mirror and e loaded equilibria per target`.
    pub fn line(&self) -> String {
        let targets = self.statuses.points.max(1) as f64;
        format!(
            "{}; {:.2} commands after the mirror and {:.2} loaded equilibria per target",
            self.statuses.line().replacen("points", "targets", 1),
            self.iterations as f64 / targets,
            self.equilibria as f64 / targets
        )
    }
}

/// The real robot: the description (its corrections built in) and the legs' errors, if any.
pub struct RealRobot<'a> {
    /// The description: the controller's nominal geometry, and the real robot without leg errors.
    pub nominal: &'a Manipulator,
    /// The legs' errors and their scale.
    pub errors: Option<(LegErrors<'a>, f64)>,
}

impl RealRobot<'_> {
    /// Whether the errors build the same real legs at every target (no direct end error, which is given
    /// about the reference point of the target).
    fn fixed(&self) -> bool {
        self.errors.as_ref().is_none_or(|(e, _)| e.set.legs.iter().all(|l| l.eps == Vec6::zeros()))
    }

    /// The real manipulator at a target.
    fn at(&self, target: &Frame) -> Cow<'_, Manipulator> {
        match &self.errors {
            None => Cow::Borrowed(self.nominal),
            Some((e, scale)) => Cow::Owned(real_manipulator(self.nominal, e, target, *scale)),
        }
    }
}

/// Compensates every target, streaming rows to `out` in input order.
pub fn run_compensate(
    pool: &rayon::ThreadPool,
    robot: &RealRobot,
    points: &mut PointSet,
    o: &CompensateOptions,
    out: &mut (dyn Write + Send),
    progress: &ProgressBar,
) -> Result<CompensateSummary> {
    stream(pool, &Compensator::new(robot, o), points, out, progress)
}

/// Compensation one target at a time, each warm-started from the one before (the study streams it in runs;
/// a controller stepping along a path, or a benchmark, calls `next` directly).
pub struct Compensator<'a> {
    robot: &'a RealRobot<'a>,
    /// The real manipulator when it is the same at every target (`RealRobot::fixed`).
    fixed: Option<Manipulator>,
    o: &'a CompensateOptions,
    layout: CompensateLayout,
}

impl<'a> Compensator<'a> {
    /// The compensator of a real robot with these options.
    pub fn new(robot: &'a RealRobot<'a>, o: &'a CompensateOptions) -> Self {
        let fixed = robot.fixed().then(|| robot.at(&Frame::IDENTITY).into_owned());
        Compensator { robot, fixed, o, layout: CompensateLayout::new(robot.nominal) }
    }

    /// The command for one target (and its wrench: the options', else the point's own, else zero), from
    /// the state the previous target left.
    pub fn next(&self, p: &PosePoint, st: &mut CompensateState) -> (Vec6, Compensation) {
        let wrench = self.o.wrench.or(p.wrench).unwrap_or_else(Vec6::zeros);
        let target = p.frame();
        let real = match &self.fixed {
            Some(m) => Cow::Borrowed(m),
            None => self.robot.at(&target),
        };
        let solver = Solver { nominal: self.robot.nominal, real: &real, target, wrench };
        let result = match (self.o.method, self.o.commands_only) {
            (Method::Newton, true) => solver.command_only(st),
            (method, _) => solver.compensate(method, st),
        };
        // A failed target leaves no Jacobian and no command to extrapolate from for the next one.
        if result.status != Status::Ok {
            st.jacobian = None;
            st.commands.clear();
        }
        (wrench, result)
    }

    /// The target as a pose: `p` itself, or where a serial arm's joint coordinates put its tool, with every
    /// nominal placement of `st` seeded there, so that the controller's inverse kinematics keeps the
    /// configuration given (a wrist flip reaches the same pose). None where the angles give no finite pose.
    pub fn target_of_joints<'p>(&self, p: &'p PosePoint, st: &mut CompensateState) -> Option<Cow<'p, PosePoint>> {
        let nominal = self.robot.nominal;
        let target = crate::study::point::pose_of_joints(nominal, p, &mut st.directions)?;
        if !p.joints.is_empty() {
            for c in [&mut st.uncompensated, &mut st.mirror, &mut st.compensated, &mut st.check] {
                nominal.pose_at_joints(&p.joints, &mut c.nominal)?;
            }
        }
        Some(target)
    }

    /// A fresh state (no warm start).
    pub fn start(&self) -> CompensateState {
        let m = self.robot.nominal;
        CompensateState {
            uncompensated: Commanded::new(m),
            mirror: Commanded::new(m),
            compensated: Commanded::new(m),
            check: Commanded::new(m),
            jacobian: None,
            commands: Trail::default(),
            directions: m.new_state(),
            skipped: false,
        }
    }
}

/// A controller and a real robot commanded together: the nominal legs' placement (the controller's
/// inverse kinematics) and the real legs' loaded equilibrium, with the last solutions keyed by their
/// targets (the next solve's start, extrapolated along the path as a map's rows are).
#[derive(Clone)]
struct Commanded {
    nominal: ManipulatorState,
    real: ManipulatorState,
    history: LoadedHistory,
}

impl Commanded {
    fn new(m: &Manipulator) -> Self {
        let nominal = m.new_state();
        Commanded { nominal, real: m.new_state(), history: LoadedHistory::default() }
    }
}

/// What a worker carries from one target to the next. Each sequence of commands has its own pair, so that
/// every solve starts from its predecessor along the path (a neighbouring command).
pub struct CompensateState {
    /// Commanded with the targets themselves.
    uncompensated: Commanded,
    /// Commanded with the mirror commands.
    mirror: Commanded,
    /// Commanded with Newton's commands.
    compensated: Commanded,
    /// Commanded with the command found: the independent forward solve.
    check: Commanded,
    /// The Jacobian of the reached pose by the command (weighted coordinates), from the last target.
    jacobian: Option<Mat6>,
    /// The commands found for the last targets, as the command's offset from its target (weighted
    /// coordinates): the compensation is a smooth function of the target along a path, and its
    /// extrapolation starts the next target's Newton method.
    commands: Trail,
    /// With `commands_only`, the nominal robot placed at the target for the task's directions alone (the
    /// controller's own placements are at the commands, in `check`).
    directions: ManipulatorState,
    /// With `commands_only`, targets answered by the extrapolated command alone have passed since the
    /// uncompensated and mirror pairs last solved: their solutions lie back along the path.
    skipped: bool,
}

impl Study for Compensator<'_> {
    type Item = PosePoint;
    type State = CompensateState;
    type Tally = CompensateSummary;

    fn columns(&self) -> Vec<Column> {
        compensate_table(self.robot.nominal)
    }

    /// Runs eight times a map's (`COMPENSATE_RUN`): a run's first target is solved cold, its uncompensated
    /// equilibrium from the placement (a dozen or more damped full linearisations where the leg errors are
    /// large), where the next targets cost one.
    fn run_length(&self) -> usize {
        COMPENSATE_RUN
    }

    fn new_state(&self) -> CompensateState {
        self.start()
    }

    fn solve(
        &self,
        index: u64,
        p: &PosePoint,
        st: &mut CompensateState,
        tally: &mut CompensateSummary,
        out: &mut String,
    ) {
        let Some(p) = self.target_of_joints(p, st) else {
            tally.statuses.add(Status::Unreachable);
            let result = Compensation::failed(Status::Unreachable);
            let wrench = self.o.wrench.or(p.wrench).unwrap_or_else(Vec6::zeros);
            let row = CompensationRow { index, point: p, wrench, method: self.o.method, result: &result };
            return crate::output::table::write_row(&row, &self.layout, out);
        };
        let p = p.as_ref();
        let (wrench, result) = self.next(p, st);
        tally.statuses.add(result.status);
        tally.iterations += result.iterations.unwrap_or(0) as u64;
        tally.equilibria += result.equilibria as u64;
        let row = CompensationRow { index, point: p, wrench, method: self.o.method, result: &result };
        crate::output::table::write_row(&row, &self.layout, out);
    }
}

/// The status of a loaded equilibrium that was not found: a tangent stiffness that turned singular on the
/// way is the load buckling the robot.
fn deflection_status(e: &DeflectionFailure) -> Status {
    match e {
        DeflectionFailure::Leg(e) => Status::of(e),
        DeflectionFailure::SingularStiffness { .. } => Status::Unstable,
        DeflectionFailure::NotConverged { .. } => Status::NotConverged,
    }
}

/// The directions a command moves the platform in: an orthonormal basis Q (weighted coordinates, rotations
/// times the length scale) of the span of the actuators' platform motions. Q has at most six columns, kept
/// in a 6x6 matrix whose columns past `dimension` are zero, and coordinates along it are six-vectors whose
/// entries past `dimension` are zero: nothing is allocated per target.
struct Task {
    basis: Mat6,
    dimension: usize,
    length_scale: f64,
}

impl Task {
    /// The target moved by `y` along the basis.
    fn command(&self, target: &Frame, y: &Vec6) -> Frame {
        apply_twist(target, &self.unweighted(&self.motion(y)))
    }

    /// Q y: the weighted platform motion of the coordinates `y`.
    fn motion(&self, y: &Vec6) -> Vec6 {
        let mut w = Vec6::zeros();
        for k in 0..self.dimension {
            w += self.basis.column(k) * y[k];
        }
        w
    }

    /// A pose error in weighted coordinates.
    fn weighted(&self, e: &Vec6) -> Vec6 {
        weigh_rotations(e, self.length_scale)
    }

    /// A weighted displacement back in mm and rad.
    fn unweighted(&self, e_w: &Vec6) -> Vec6 {
        weigh_rotations(e_w, 1.0 / self.length_scale)
    }

    /// Q^T e: the components of a weighted error along the basis.
    fn along(&self, e_w: &Vec6) -> Vec6 {
        Vec6::from_fn(|k, _| if k < self.dimension { self.basis.column(k).dot(e_w) } else { 0.0 })
    }

    /// The Newton step -(Q^T J Q)^-1 r on the task residual `r` (zero past `dimension`), Q^T J Q the
    /// Jacobian's block on the basis; None where the block is singular or the step not finite. On the
    /// basis's own size, known when compiled: nothing is allocated.
    fn step(&self, jacobian: &Mat6, residual: &Vec6) -> Option<Vec6> {
        macro_rules! on_sizes {
            ($($n:literal)*) => {
                match self.dimension {
                    $($n => {
                        let q = self.basis.fixed_columns::<$n>(0);
                        let block = q.tr_mul(&(jacobian * q));
                        let step = SmallLu::new(&block).solve(&-residual.fixed_rows::<$n>(0))?;
                        let mut padded = Vec6::zeros();
                        padded.fixed_rows_mut::<$n>(0).copy_from(&step);
                        Some(padded)
                    })*
                    _ => None,
                }
            };
        }
        on_sizes!(1 2 3 4 5 6).filter(|s| s.iter().all(|v| v.is_finite()))
    }

    /// The offset of `trial`'s command from its target (weighted coordinates) moved by the Newton step its
    /// residual still asks with `jacobian`.
    fn refined_offset(&self, jacobian: &Mat6, trial: &Trial) -> Vec6 {
        let refined = match self.step(jacobian, &trial.task) {
            Some(step) => trial.y + step,
            None => trial.y,
        };
        self.motion(&refined)
    }

    fn column(&self, k: usize) -> Vec6 {
        self.basis.column(k).into()
    }
}

/// One evaluated command: its coordinates along the task basis, the weighted error and its task part.
#[derive(Clone)]
struct Trial {
    y: Vec6,
    error_w: Vec6,
    task: Vec6,
    /// The forward solve's answer where the check pair evaluated this command (the extrapolated one):
    /// its check is made.
    checked: Option<Reached>,
}

/// One target's compensation.
struct Solver<'a> {
    nominal: &'a Manipulator,
    real: &'a Manipulator,
    target: Frame,
    wrench: Vec6,
}

/// Where the real robot settled under a command; with a stability solve, whether it is stable there.
#[derive(Clone, Copy)]
struct Reached {
    pose: Frame,
    stable: Option<bool>,
}

impl Solver<'_> {
    /// The actuator coordinates the command found gives (the nominal placement of the check), every leg's
    /// in turn, and for a serial arm (one leg) the controller's angles whose map gives them.
    fn commanded(&self, st: &CompensateState) -> (Vec<f64>, Option<Vec<f64>>) {
        let actuators = st.check.nominal.actuators().flatten().copied().collect();
        let controller = (self.nominal.joint_space.as_ref())
            .and_then(|space| st.check.nominal.actuators().next().and_then(|q| space.controller_angles(q)));
        (actuators, controller)
    }

    /// Commands the real robot with `command` through the controller's nominal inverse kinematics and
    /// solves its loaded equilibrium, starting from the pair's last one: the pose alone (`settle`), or with
    /// `stability` the stability there too (`settle_stable`).
    fn reach(&self, command: &Frame, pair: &mut Commanded, stability: bool) -> Result<Reached, Status> {
        self.nominal.place_along(command, &self.target, &mut pair.nominal).map_err(|e| Status::of(&e))?;
        self.real.take_command(&pair.nominal, &mut pair.real);
        // Keyed by the target: every pair's command is a smooth function of it, equally spaced along a path
        // as the commands themselves are not.
        let predicted = pair.history.start(&self.target.pos, command, &mut pair.real.legs);
        // Always a start: without one the solve would place the real legs by their own inverse kinematics,
        // where the controller's placement must hold them.
        let solve = |start: &Frame, real: &mut ManipulatorState| match stability {
            true => (self.real.settle_stable(command, &self.wrench, Some(start), real))
                .map(|(d, stable)| Reached { pose: d.pose, stable: Some(stable) }),
            false => (self.real.settle(command, &self.wrench, Some(start), real))
                .map(|d| Reached { pose: d.pose, stable: None }),
        };
        let mut reached = solve(predicted.as_ref().unwrap_or(command), &mut pair.real);
        // An extrapolation can start too far (a path where the deflection grows fast): from the placement.
        if reached.is_err() && predicted.is_some() {
            self.real.take_command(&pair.nominal, &mut pair.real);
            reached = solve(command, &mut pair.real);
        }
        match reached {
            Ok(r) => {
                pair.history.supersede(self.target.pos, command.error_to(&r.pose), &pair.real.legs);
                Ok(r)
            }
            Err(e) => {
                pair.history.clear();
                Err(deflection_status(&e))
            }
        }
    }

    fn compensate(&self, method: Method, st: &mut CompensateState) -> Compensation {
        let mut out = Compensation::failed(Status::Ok);
        // The target as the command: the error compensation has to remove.
        out.equilibria += 1;
        let reached = match self.reach(&self.target, &mut st.uncompensated, false) {
            Ok(d) => d,
            Err(s) => return Compensation { status: s, ..out },
        };
        let uncompensated = self.target.error_to(&reached.pose);
        out.uncompensated = Some(uncompensated);
        // Where another pair has no solution yet (a run's first target, or the first after a failure),
        // it starts from this one's: its command differs by about the error, so its legs' departures from
        // their placement and the platform's deflection are nearly these. Cold, from the placement, the
        // load would cost a dozen or more damped full linearisations where leg errors are large.
        for pair in [&mut st.mirror, &mut st.compensated, &mut st.check] {
            if pair.history.is_empty() {
                pair.history.clone_from(&st.uncompensated.history);
            }
        }
        let task = match self.task(&mut st.uncompensated.nominal) {
            Ok(t) => t,
            Err(s) => return Compensation { status: s, ..out },
        };
        let start = Trial {
            y: Vec6::zeros(),
            error_w: task.weighted(&uncompensated),
            task: task.along(&task.weighted(&uncompensated)),
            checked: None,
        };
        // The mirror command of [73]: the target minus the error predicted there, in the directions the
        // actuators move.
        let y_mirror = -start.task;
        let mirror = self.evaluate(&task, &y_mirror, &mut st.mirror, false, &mut out.equilibria);
        out.mirror = mirror.as_ref().ok().map(|t| task.unweighted(&t.error_w));
        // With Newton's method, also the converged command's offset refined for the next target's start.
        let found = match method {
            Method::Mirror => mirror.map(|t| (t, None)),
            Method::Newton => {
                let mut iterations = 0;
                let predicted = st.commands.predict(&self.target.pos).map(|offset| task.along(&offset));
                let found = self.newton(&task, start, mirror.ok(), predicted, st, &mut iterations, &mut out.equilibria);
                out.iterations = Some(iterations);
                found.map(|(t, refined)| (t, Some(refined)))
            }
        };
        let (found, refined) = match found {
            Ok(t) => t,
            Err(s) => return Compensation { status: s, ..out },
        };
        let command = task.command(&self.target, &found.y);
        out.command = Some(command);
        // The independent forward solve: the command placed by its own inverse kinematics, the real legs'
        // equilibrium from the last forward solve's (nothing carried from Newton's evaluations). Made
        // already where Newton's first evaluation, the extrapolated command, was that solve and met the
        // tolerance (along a path, most targets).
        let checked = match found.checked {
            Some(r) => Ok(r),
            None => {
                out.equilibria += 1;
                self.reach(&command, &mut st.check, true)
            }
        };
        (out.actuators, out.controller) = self.commanded(st);
        let checked = match checked {
            Ok(d) => d,
            Err(s) => return Compensation { status: s, ..out },
        };
        let residual = self.target.error_to(&checked.pose);
        out.residual = Some(residual);
        let agrees = task.along(&(task.weighted(&residual) - found.error_w)).norm() <= CHECK_AGREEMENT_MM;
        out.status = if checked.stable != Some(true) {
            Status::Unstable
        } else if !agrees {
            Status::NotConverged
        } else {
            Status::Ok
        };
        // Only a target that ends `ok` starts the next one (`Compensator::next` forgets the history on
        // any other status).
        if let (Status::Ok, Some(offset)) = (out.status, refined) {
            st.commands.record(self.target.pos, offset);
        }
        out
    }

    /// `commands_only`: the command extrapolated from the last targets, evaluated by the forward solve that
    /// checks it, is the answer where it meets the tolerance with the robot stable there (along a fine
    /// path, nearly every target: one loaded equilibrium instead of three). Anywhere else (a run's first
    /// target, the first after a failure, a miss, a failure or instability, whose status the full
    /// procedure then decides as it does without this option) the full procedure follows, its
    /// uncompensated and mirror errors left out of the row as at every other target.
    fn command_only(&self, st: &mut CompensateState) -> Compensation {
        let mut tried = 0;
        if let Some(found) = self.extrapolated_command(st, &mut tried) {
            st.skipped = true;
            return found;
        }
        // The uncompensated, mirror and search pairs' last solutions lie back along the path: the
        // uncompensated pair starts from the check's (its command differs by about the error) and seeds
        // the others.
        if st.skipped {
            for pair in [&mut st.uncompensated, &mut st.mirror, &mut st.compensated] {
                pair.history.clear();
            }
            st.uncompensated.history.clone_from(&st.check.history);
            st.skipped = false;
        }
        let full = self.compensate(Method::Newton, st);
        Compensation { uncompensated: None, mirror: None, equilibria: full.equilibria + tried, ..full }
    }

    /// The target's compensation by the extrapolated command alone where it meets the tolerance and the
    /// robot is stable there, else None; `equilibria` counts the loaded equilibrium solved either way.
    fn extrapolated_command(&self, st: &mut CompensateState, equilibria: &mut usize) -> Option<Compensation> {
        let jacobian = st.jacobian?;
        let offset = st.commands.predict(&self.target.pos)?;
        let task = self.task(&mut st.directions).ok()?;
        let mut out = Compensation::failed(Status::Ok);
        let found = self.evaluate(&task, &task.along(&offset), &mut st.check, true, equilibria).ok()?;
        out.equilibria = *equilibria;
        let checked = found.checked.filter(|c| c.stable == Some(true))?;
        if found.task.norm() > COMMAND_TOLERANCE_MM {
            return None;
        }
        out.command = Some(task.command(&self.target, &found.y));
        (out.actuators, out.controller) = self.commanded(st);
        out.residual = Some(self.target.error_to(&checked.pose));
        out.iterations = Some(1);
        st.commands.record(self.target.pos, task.refined_offset(&jacobian, &found));
        Some(out)
    }

    /// The directions the actuators move the platform at the target (the nominal robot placed there).
    fn task(&self, nominal: &mut ManipulatorState) -> Result<Task, Status> {
        match self.nominal.commanded_directions(&self.target, nominal) {
            Ok(Directions::Span(basis)) => {
                let mut columns = Mat6::zeros();
                for (mut column, direction) in columns.column_iter_mut().zip(&basis) {
                    column.copy_from(direction);
                }
                Ok(Task { basis: columns, dimension: basis.len().min(6), length_scale: self.nominal.length_scale })
            }
            Ok(Directions::Singular) => Err(Status::Singular),
            Ok(Directions::NotFinite) => Err(Status::Overflow),
            Err(e) => Err(Status::of(&e)),
        }
    }

    /// Where the real robot settles under the command at `y`, commanded through `pair`; with `check`, the
    /// stability there too, and the trial keeps the answer as its check.
    fn evaluate(
        &self,
        task: &Task,
        y: &Vec6,
        pair: &mut Commanded,
        check: bool,
        equilibria: &mut usize,
    ) -> Result<Trial, Status> {
        *equilibria += 1;
        let command = task.command(&self.target, y);
        let d = self.reach(&command, pair, check)?;
        let error_w = task.weighted(&self.target.error_to(&d.pose));
        Ok(Trial { y: *y, task: task.along(&error_w), error_w, checked: check.then_some(d) })
    }

    /// Newton's method on the command from the target (`start`), the mirror command (`mirror`, its first
    /// step with the nominal Jacobian, the identity) and the command extrapolated from the targets before
    /// (`predicted`, coordinates along the task basis), whichever comes closer. Returns the converged
    /// trial and its command's offset from the target (weighted coordinates) refined by the step its last
    /// residual asks: the next target's extrapolation starts from that.
    #[allow(clippy::too_many_arguments)]
    fn newton(
        &self,
        task: &Task,
        start: Trial,
        mirror: Option<Trial>,
        predicted: Option<Vec6>,
        st: &mut CompensateState,
        iterations: &mut usize,
        equilibria: &mut usize,
    ) -> Result<(Trial, Vec6), Status> {
        let carried = st.jacobian.take();
        let mut jacobian = carried.unwrap_or_else(Mat6::identity);
        let mut best = start;
        if best.task.norm() > COMMAND_TOLERANCE_MM {
            if let Some(m) = mirror {
                broyden(&mut jacobian, task, &best, &m);
                if m.task.norm() < best.task.norm() {
                    best = m;
                }
            }
        }
        // Along a path the command's offset from its target changes smoothly: its extrapolation is
        // usually within the tolerance already, a far better start than the mirror command. It is
        // evaluated by the check's forward solve, which then is the check of the command found; where it
        // misses, Newton's evaluations go on from that equilibrium.
        if let Some(y) = predicted.filter(|_| best.task.norm() > COMMAND_TOLERANCE_MM) {
            *iterations += 1;
            if let Ok(p) = self.evaluate(task, &y, &mut st.check, true, equilibria) {
                broyden(&mut jacobian, task, &best, &p);
                if p.task.norm() > COMMAND_TOLERANCE_MM {
                    st.compensated.clone_from(&st.check);
                }
                if p.task.norm() < best.task.norm() {
                    best = p;
                }
            }
        }
        // The first target of a run: the Jacobian from differences (Broyden's updates along steps that all
        // point the same way would learn it in one direction only).
        let mut refreshed = false;
        if carried.is_none() && best.task.norm() > COMMAND_TOLERANCE_MM {
            jacobian = self.differences(task, &best, jacobian, st, equilibria)?;
            refreshed = true;
        }
        // A command the robot cannot take (outside the workspace or a leg's reach) seen on the way makes a
        // failure `unreachable`: the target needs a command beyond what the robot reaches.
        let mut outside = false;
        let fail = |status: Status, outside: bool| if outside { Status::Unreachable } else { status };
        while best.task.norm() > COMMAND_TOLERANCE_MM {
            if *iterations == MAX_COMMAND_ITERATIONS {
                return Err(fail(Status::NotConverged, outside));
            }
            *iterations += 1;
            let step = task.step(&jacobian, &best.task);
            let Some(step) = step else {
                if refreshed {
                    return Err(fail(Status::NotConverged, outside));
                }
                jacobian = self.differences(task, &best, jacobian, st, equilibria).map_err(|s| fail(s, outside))?;
                refreshed = true;
                continue;
            };
            // Halve a step whose command the robot cannot take.
            let mut fraction = 1.0;
            let mut trial = Err(Status::NotConverged);
            for _ in 0..MAX_HALVINGS {
                trial = self.evaluate(task, &(best.y + step * fraction), &mut st.compensated, false, equilibria);
                match &trial {
                    Ok(_) => break,
                    Err(s) => outside |= matches!(s, Status::Unreachable | Status::IllConditioned),
                }
                fraction /= 2.0;
            }
            let trial = trial.map_err(|s| fail(s, outside))?;
            broyden(&mut jacobian, task, &best, &trial);
            let progress = trial.task.norm() < best.task.norm();
            let contracted = trial.task.norm() <= CONTRACTION * best.task.norm();
            if progress {
                best = trial;
            }
            if contracted {
                refreshed = false;
            } else if refreshed && !progress {
                return Err(fail(Status::NotConverged, outside));
            } else if !refreshed {
                jacobian = self.differences(task, &best, jacobian, st, equilibria).map_err(|s| fail(s, outside))?;
                refreshed = true;
            }
        }
        // The command meets the tolerance; the step its residual still asks (second order small with the
        // Jacobian Newton ends with) gives the next target's extrapolation a start far inside it, where
        // the command itself carries up to the tolerance, which extrapolation would amplify.
        let refined = task.refined_offset(&jacobian, &best);
        st.jacobian = Some(jacobian);
        Ok((best, refined))
    }

    /// The Jacobian with its columns along the task basis replaced by one-sided differences at `at`.
    fn differences(
        &self,
        task: &Task,
        at: &Trial,
        mut jacobian: Mat6,
        st: &mut CompensateState,
        equilibria: &mut usize,
    ) -> Result<Mat6, Status> {
        for k in 0..task.dimension {
            let mut y = at.y;
            y[k] += DIFFERENCE_STEP_MM;
            let t = self.evaluate(task, &y, &mut st.compensated, false, equilibria)?;
            let q = task.column(k);
            let column = (t.error_w - at.error_w) / DIFFERENCE_STEP_MM;
            jacobian += (column - jacobian * q) * q.transpose();
        }
        Ok(jacobian)
    }
}

/// Broyden's update of the Jacobian (weighted coordinates) from two evaluated commands: J += (dr - J dc)
/// dc^T / |dc|^2, so that J maps the step dc onto the change dr it caused.
fn broyden(jacobian: &mut Mat6, task: &Task, from: &Trial, to: &Trial) {
    let dc = task.motion(&(to.y - from.y));
    let size = dc.norm_squared();
    if size >= SECANT_MIN_STEP_MM.powi(2) && size.is_finite() {
        let dr = to.error_w - from.error_w;
        *jacobian += (dr - *jacobian * dc) * dc.transpose() / size;
    }
}

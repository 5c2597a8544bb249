//! `stiff assemble`: legs with geometric errors put together (paper 000 s. 4.2-4.3, 5.2), at every point of
//! a grid, a points file or a path, streamed like the map. Per point: the linear assembly of eq (57)-(65)
//! (platform displacement, legs' end loads, joint and spring deflections and loads), the non-linear one of
//! eq (69)-(72) (the legs with their errors built in, the loaded equilibrium with zero external wrench),
//! and with an external wrench the compliance error due to the load, the total, and their superposition.
//! Tolerance studies draw the errors at random within the given values (seeded per point, so the rows do
//! not depend on the thread count) and report mean, spread and worst case.

use std::io::Write;

use anyhow::Result;
use indicatif::ProgressBar;
use rand::{Rng, SeedableRng};

use super::point::Status;
use crate::batch::{point_seed, stream, Study, Tally};
use crate::kinematics::frame::{Frame, Vec6};
use crate::model::assembly_errors::ErrorSet;
use crate::model::grid::{PointSet, PosePoint};
use crate::output::table::{
    column_names, header_line, names, selected_columns, write_selected_row, Column, ColumnTest, Record, Row, Selection,
};
use crate::platform::assembly::EndErrors;
use crate::platform::assembly::{linear_assembly, JointDeflections};
use crate::platform::leg::{Leg, LegResponse};
use crate::platform::loaded::DeflectionFailure;
use crate::platform::manipulator::{Manipulator, ManipulatorState, PoseFailure};

/// What `stiff assemble` computes.
#[derive(Clone, Debug, Default)]
pub struct AssembleOptions {
    /// External wrench at the reference point (N, N mm): adds the load, total and superposition columns.
    pub wrench: Option<Vec6>,
    /// Factor on every error.
    pub scale: f64,
    /// Random draws of the errors within +-(scale x the given values), each source of each leg with its own
    /// uniform factor; 0: the errors as given.
    pub samples: usize,
    /// Seed of the random draws.
    pub seed: u64,
    /// The columns written (`--columns`), all where None.
    pub selection: Option<Selection>,
}

/// The groups `--columns` knows for an assembly table.
pub const COLUMN_GROUPS: [&str; 10] =
    ["pose", "status", "linear", "nonlinear", "loads", "joints", "load", "total", "super", "samples"];

/// A group's test on a column name (None: not a group).
fn column_group(name: &str) -> Option<ColumnTest> {
    let prefixed = |prefix: &'static str| -> ColumnTest { Box::new(move |c: &str| c.starts_with(prefix)) };
    Some(match name {
        "pose" => Box::new(|c: &str| [names::INDEX, names::NAME].contains(&c) || names::POSITION.contains(&c)),
        "status" => Box::new(|c: &str| c == names::STATUS),
        "linear" => Box::new(|c: &str| names::DISPLACEMENT.contains(&c)),
        "nonlinear" => prefixed("nl_"),
        "loads" => Box::new(|c: &str| {
            ["force_max_N", "moment_max_Nmm", "force_sum_N"].contains(&c)
                || (c.starts_with("leg") && (c.ends_with("_force_N") || c.ends_with("_moment_Nmm")))
        }),
        "joints" => Box::new(|c: &str| c == "passive_max_rad" || c.starts_with("spring_")),
        "load" => prefixed("load_"),
        "total" => prefixed("total_"),
        "super" => Box::new(|c: &str| c.starts_with("super")),
        "samples" => Box::new(|c: &str| {
            c == "samples"
                || c.starts_with("mean_")
                || c.contains("_mean_")
                || c.contains("_std_")
                || c.contains("_worst_")
        }),
        _ => return None,
    })
}

/// The selection `--columns` asks of an assembly table for `legs` legs with these options.
pub fn assemble_selection(legs: usize, o: &AssembleOptions, wanted: &[&str]) -> Result<Selection, String> {
    let point = PosePoint::default();
    let blank = AssemblyRow { index: 0, point: &point, outcome: AssemblyOutcome::Failed(Status::Ok) };
    let names = column_names(&blank, &AssembleLayout::new(legs, o));
    Selection::new(&names, wanted, column_group, &COLUMN_GROUPS)
}

/// What fixes an assembly table's columns.
#[derive(Clone, Copy, Debug)]
pub struct AssembleLayout {
    /// Number of legs (a load per leg).
    pub legs: usize,
    /// An external wrench is given (load, total and superposition columns).
    pub wrench: bool,
    /// A tolerance study: the samples' statistics instead of one assembly.
    pub samples: usize,
}

impl AssembleLayout {
    /// The columns of an assembly of `m` with these options.
    pub fn new(legs: usize, o: &AssembleOptions) -> Self {
        AssembleLayout { legs, wrench: o.wrench.is_some(), samples: o.samples }
    }
}

/// The outcome of one point: an assembly, the statistics of a tolerance study, or a status.
pub enum AssemblyOutcome {
    /// One assembly with the errors as given.
    Assembled(Box<Assembled>),
    /// A tolerance study: mean displacement, and mean / std / worst of the displacement norm, the largest
    /// leg force and the largest leg moment.
    Sampled(Vec6, [Stats; 3]),
    /// Nothing assembled, and why.
    Failed(Status),
}

/// One row of an assembly table.
pub struct AssemblyRow<'a> {
    /// Row number in input order.
    pub index: u64,
    /// The point.
    pub point: &'a PosePoint,
    /// What was found there.
    pub outcome: AssemblyOutcome,
}

impl Row for AssemblyRow<'_> {
    type Layout = AssembleLayout;

    fn record(&self, l: &AssembleLayout, r: &mut impl Record) {
        let p = self.point;
        super::point::record_pose(r, self.index, p, false);
        let (assembled, sampled) = match &self.outcome {
            AssemblyOutcome::Assembled(a) => (Some(&**a), None),
            AssemblyOutcome::Sampled(mean, stats) => (None, Some((mean, stats))),
            AssemblyOutcome::Failed(_) => (None, None),
        };
        let status = match &self.outcome {
            AssemblyOutcome::Assembled(a) if a.nonlinear.is_none() => Status::NotConverged,
            AssemblyOutcome::Assembled(_) | AssemblyOutcome::Sampled(..) => Status::Ok,
            AssemblyOutcome::Failed(s) => *s,
        };
        r.text(names::STATUS, status.as_str());
        if l.samples > 0 {
            r.count("samples", sampled.map(|_| l.samples as u64));
            // mean_dx_mm ... mean_rz_rad: the mean platform displacement over the samples (`dx_mm` keeps one
            // meaning: one assembly's displacement).
            r.prefixed_six("mean", names::DISPLACEMENT, sampled.map(|(mean, _)| mean));
            for (k, (q, u)) in [("displacement", "mm"), ("force_max", "N"), ("moment_max", "Nmm")].iter().enumerate() {
                let st = sampled.map(|(_, stats)| &stats[k]);
                r.optional(format_args!("{q}_mean_{u}"), st.map(Stats::mean));
                r.optional(format_args!("{q}_std_{u}"), st.map(Stats::std));
                r.optional(format_args!("{q}_worst_{u}"), st.map(|s| s.worst));
            }
            return;
        }
        r.six(names::DISPLACEMENT, assembled.map(|a| &a.displacement));
        r.prefixed_six(names::NONLINEAR, names::DISPLACEMENT, assembled.and_then(|a| a.nonlinear.as_ref()));
        let force = |w: &Vec6| w.fixed_rows::<3>(0).norm();
        let moment = |w: &Vec6| w.fixed_rows::<3>(3).norm();
        let loads = assembled.map(|a| &a.loads);
        r.optional("force_max_N", loads.map(|l| l.iter().map(force).fold(0.0, f64::max)));
        r.optional("moment_max_Nmm", loads.map(|l| l.iter().map(moment).fold(0.0, f64::max)));
        r.optional("force_sum_N", loads.map(|l| force(&l.iter().sum())));
        let j = assembled.and_then(|a| a.joints.as_ref());
        r.optional("passive_max_rad", j.map(|j| j.passive_max));
        r.optional("spring_deflection_max_mm", j.map(|j| j.spring_deflection_max));
        r.optional("spring_force_max_N", j.map(|j| j.spring_force_max));
        r.optional("spring_rotation_max_rad", j.map(|j| j.spring_rotation_max));
        r.optional("spring_torque_max_Nmm", j.map(|j| j.spring_torque_max));
        for k in 0..l.legs {
            let load = loads.and_then(|l| l.get(k));
            r.optional(format_args!("leg{}_force_N", k + 1), load.map(force));
            r.optional(format_args!("leg{}_moment_Nmm", k + 1), load.map(moment));
        }
        if l.wrench {
            let loaded = assembled.and_then(|a| a.loaded.as_ref());
            r.prefixed_six("load", names::DISPLACEMENT, loaded.map(|(load, _, _)| load));
            r.prefixed_six("total", names::DISPLACEMENT, loaded.map(|(_, total, _)| total));
            r.prefixed_six("super", names::DISPLACEMENT, loaded.map(|(_, _, sup)| sup));
            r.optional("superposition_gap_mm", loaded.map(|(_, total, sup)| (total - sup).fixed_rows::<3>(0).norm()));
        }
    }
}

/// The CSV header for `legs` legs.
pub fn assemble_header(legs: usize, o: &AssembleOptions) -> String {
    header_line(&assemble_table(legs, o))
}

/// The columns an assembly of `legs` legs with these options writes, in order.
pub fn assemble_table(legs: usize, o: &AssembleOptions) -> Vec<Column> {
    let point = PosePoint::default();
    let blank = AssemblyRow { index: 0, point: &point, outcome: AssemblyOutcome::Failed(Status::Ok) };
    selected_columns(&blank, &AssembleLayout::new(legs, o), o.selection.as_ref())
}

/// Counts of an assembly run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AssembleSummary {
    /// Points in the input.
    pub points: u64,
    /// Points assembled without failure.
    pub ok: u64,
}

impl Tally for AssembleSummary {
    fn merge(&mut self, o: &Self) {
        self.points += o.points;
        self.ok += o.ok;
    }
}

/// What the assembly gives at one point.
#[derive(Clone, Debug)]
pub struct Assembled {
    /// Linear assembly (eq 60).
    pub displacement: Vec6,
    /// Load each leg's end takes (eq 63: F_i = K_i (dt - eps_i)), at the reference point.
    pub loads: Vec<Vec6>,
    /// Joint and spring deflections and loads (eq 64-65), where computed.
    pub joints: Option<JointDeflections>,
    /// Non-linear assembly (eq 71), None where it did not converge.
    pub nonlinear: Option<Vec6>,
    /// With a wrench: displacement due to the load alone, total, superposition.
    pub loaded: Option<(Vec6, Vec6, Vec6)>,
}

/// The nominal legs' answers at a pose and their end errors by source.
pub struct Placed {
    /// Each leg's answer at the pose.
    pub responses: Vec<LegResponse>,
    /// Each leg's end-point errors by source.
    pub errors: Vec<EndErrors>,
}

/// Places the manipulator and computes each leg's stiffness and end-point errors (scaled).
pub fn place_with_errors(
    m: &Manipulator,
    set: &ErrorSet,
    perturbed: &[Option<Leg>],
    pose: &Frame,
    scale: f64,
    state: &mut ManipulatorState,
) -> Result<Placed, Status> {
    let status = |e: PoseFailure| Status::of(&e);
    let mut responses = Vec::with_capacity(m.legs.len());
    m.unloaded_each(pose, state, |_, r| responses.push(*r)).map_err(status)?;
    let mut errors = Vec::with_capacity(m.legs.len());
    for (k, leg) in m.legs.iter().enumerate() {
        let e = &set.legs[k];
        let base = e.base_frame(scale);
        let ends = leg
            .end_errors(pose, &state.legs[k], &(e.eps * scale), &base, perturbed[k].as_ref())
            .map_err(|failure| status(PoseFailure { leg: k, failure }))?;
        errors.push(ends);
    }
    Ok(Placed { responses, errors })
}

/// The linear assembly with the given end errors, and the joints' deflections.
fn linear(
    m: &Manipulator,
    pose: &Frame,
    placed: &Placed,
    eps: &[Vec6],
    state: &mut ManipulatorState,
) -> Result<(Vec6, Vec<Vec6>, Option<JointDeflections>), Status> {
    let a = linear_assembly(&placed.responses, eps, m.length_scale).ok_or(Status::Singular)?;
    // eq (63): the load on leg i's end is minus the wrench it exerts on the platform.
    let loads: Vec<Vec6> = a.leg_wrenches.iter().map(|w| -w).collect();
    let mut joints: Option<JointDeflections> = None;
    for (k, leg) in m.legs.iter().enumerate() {
        let dt = a.displacement - eps[k];
        if let Some(j) = leg.joint_deflections(pose, &dt, &mut state.legs[k]) {
            joints = Some(joints.map_or(j, |o| o.max(j)));
        }
    }
    Ok((a.displacement, loads, joints))
}

/// The manipulator with every leg's errors built in (times `scale`) at `pose`: VJM legs rebuilt with their
/// parameter errors, moved by their base error and by their direct end error (a rigid motion about the
/// reference point at `pose`); MSA legs as they are (their errors offset their placement, `with_errors`).
pub fn real_manipulator(m: &Manipulator, errors: &LegErrors, pose: &Frame, scale: f64) -> Manipulator {
    let legs = (m.legs.iter().enumerate())
        .map(|(k, leg)| {
            let e = &errors.set.legs[k];
            leg.with_errors(pose, &(e.eps * scale), &e.base_frame(scale), errors.perturbed[k].as_ref())
        })
        .collect();
    Manipulator { legs, ..m.clone() }
}

/// The manipulator with every leg's errors built in, and its state placed with the nominal actuators.
fn with_errors(
    m: &Manipulator,
    errors: &LegErrors,
    pose: &Frame,
    scale: f64,
    placed: &Placed,
    state: &ManipulatorState,
) -> (Manipulator, ManipulatorState) {
    let mut s = state.clone();
    for (k, leg_state) in s.legs.iter_mut().enumerate() {
        leg_state.offset_placement(&placed.errors[k].total());
    }
    (real_manipulator(m, errors, pose, scale), s)
}

/// One point, errors as given (times the scale).
pub fn assemble_point(
    m: &Manipulator,
    set: &ErrorSet,
    perturbed: &[Option<Leg>],
    p: &PosePoint,
    o: &AssembleOptions,
    state: &mut ManipulatorState,
) -> Result<Assembled, Status> {
    let pose = p.frame();
    let placed = place_with_errors(m, set, perturbed, &pose, o.scale, state)?;
    let eps: Vec<Vec6> = placed.errors.iter().map(EndErrors::total).collect();
    let (displacement, loads, joints) = linear(m, &pose, &placed, &eps, state)?;
    // eq (71): sum_i f_i(t_eps | t0) = 0 with the legs' own (erroneous) geometry, actuators as placed.
    let errors = LegErrors { set, perturbed };
    let (perturbed_m, mut perturbed_state) = with_errors(m, &errors, &pose, o.scale, &placed, state);
    let zero = Vec6::zeros();
    // A robot that carries weight (its links', a payload) sags without errors too: the non-linear
    // displacements are measured from that sag, so that they are the errors' and the load's own, as the
    // linear assembly's are.
    let reference = match m.carries_weight() {
        true => m.deflect(&pose, &zero, None, state).map_err(deflection_status)?.pose,
        false => pose,
    };
    let nl = perturbed_m.deflect(&pose, &zero, Some(&reference), &mut perturbed_state);
    let nonlinear = nl.as_ref().ok().map(|d| reference.error_to(&d.pose));
    let loaded = match (&o.wrench, &nl) {
        (Some(w), Ok(assembled)) => {
            let load = reference.error_to(&m.deflect(&pose, w, None, state).map_err(deflection_status)?.pose);
            let total = perturbed_m
                .deflect(&pose, w, Some(&assembled.pose), &mut perturbed_state)
                .map_err(deflection_status)?;
            let assembled = reference.error_to(&assembled.pose);
            Some((load, reference.error_to(&total.pose), load + assembled))
        }
        (Some(_), Err(e)) => return Err(deflection_status(*e)),
        (None, _) => None,
    };
    Ok(Assembled { displacement, loads, joints, nonlinear, loaded })
}

fn deflection_status(e: DeflectionFailure) -> Status {
    match e {
        DeflectionFailure::Leg(e) => Status::of(&e),
        _ => Status::NotConverged,
    }
}

/// Statistics of one quantity over the samples, by Welford's one-pass update: the textbook
/// `(sum_sq - sum^2 / n) / (n - 1)` cancels catastrophically when the spread is small against the mean
/// (a 1 mm error with micrometre scatter loses every digit of the variance).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    n: f64,
    mean: f64,
    /// Sum of squared deviations from the running mean.
    m2: f64,
    worst: f64,
}

impl Stats {
    /// Adds a sample.
    pub fn add(&mut self, v: f64) {
        self.n += 1.0;
        let delta = v - self.mean;
        self.mean += delta / self.n;
        self.m2 += delta * (v - self.mean);
        self.worst = if self.n == 1.0 { v } else { self.worst.max(v) };
    }
    /// Mean of the samples.
    pub fn mean(&self) -> f64 {
        self.mean
    }
    /// Sample standard deviation (n - 1 in the denominator); 0 for fewer than two samples.
    pub fn std(&self) -> f64 {
        if self.n < 2.0 {
            return 0.0;
        }
        (self.m2 / (self.n - 1.0)).max(0.0).sqrt()
    }
}

/// A tolerance study at one point: each leg's three error sources scaled by independent uniform factors in
/// [-1, 1], combined to first order (the linear assembly, eq 60-63), `samples` times. The generator is
/// seeded by the seed and the point's index, so rows do not depend on threads or on the other points.
fn sample_point(
    m: &Manipulator,
    set: &ErrorSet,
    perturbed: &[Option<Leg>],
    index: u64,
    p: &PosePoint,
    o: &AssembleOptions,
    state: &mut ManipulatorState,
) -> Result<(Vec6, [Stats; 3]), Status> {
    let pose = p.frame();
    let placed = place_with_errors(m, set, perturbed, &pose, o.scale, state)?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(point_seed(o.seed, index));
    let mut stats = [Stats::default(); 3];
    let mut mean = Vec6::zeros();
    for _ in 0..o.samples {
        let eps: Vec<Vec6> = placed
            .errors
            .iter()
            .map(|e| {
                let mut u = || rng.random_range(-1.0..=1.0);
                e.direct * u() + e.base * u() + e.parameters * u()
            })
            .collect();
        let a = linear_assembly(&placed.responses, &eps, m.length_scale).ok_or(Status::Singular)?;
        mean += a.displacement / o.samples as f64;
        stats[0].add(a.displacement.fixed_rows::<3>(0).norm());
        stats[1].add(a.leg_wrenches.iter().map(|w| w.fixed_rows::<3>(0).norm()).fold(0.0, f64::max));
        stats[2].add(a.leg_wrenches.iter().map(|w| w.fixed_rows::<3>(3).norm()).fold(0.0, f64::max));
    }
    Ok((mean, stats))
}

/// The legs' geometric errors: as read, and each leg rebuilt with its parameter errors (None where it has
/// none).
#[derive(Clone, Copy)]
pub struct LegErrors<'a> {
    /// The error file, resolved for the model.
    pub set: &'a ErrorSet,
    /// Legs rebuilt with their parameter errors.
    pub perturbed: &'a [Option<Leg>],
}

/// Assembles the legs with their errors at every point, streaming rows to `out` in input order.
pub fn run_assemble(
    pool: &rayon::ThreadPool,
    m: &Manipulator,
    errors: &LegErrors,
    points: &mut PointSet,
    o: &AssembleOptions,
    out: &mut (dyn Write + Send),
    progress: &ProgressBar,
) -> Result<AssembleSummary> {
    let study = AssembleStudy { m, errors: *errors, o, layout: AssembleLayout::new(m.legs.len(), o) };
    stream(pool, &study, points, out, progress)
}

/// Assembly as a streamed study.
struct AssembleStudy<'a> {
    m: &'a Manipulator,
    errors: LegErrors<'a>,
    o: &'a AssembleOptions,
    layout: AssembleLayout,
}

impl Study for AssembleStudy<'_> {
    type Item = PosePoint;
    type State = ManipulatorState;
    type Tally = AssembleSummary;

    fn columns(&self) -> Vec<Column> {
        assemble_table(self.m.legs.len(), self.o)
    }

    fn new_state(&self) -> ManipulatorState {
        self.m.new_state()
    }

    fn solve(
        &self,
        index: u64,
        p: &PosePoint,
        state: &mut ManipulatorState,
        tally: &mut AssembleSummary,
        out: &mut String,
    ) {
        let (m, o, LegErrors { set, perturbed }) = (self.m, self.o, self.errors);
        let Some(placed) = super::point::pose_of_joints(m, p, state) else {
            tally.points += 1;
            let row = AssemblyRow { index, point: p, outcome: AssemblyOutcome::Failed(Status::Unreachable) };
            return write_selected_row(&row, &self.layout, self.o.selection.as_ref(), out);
        };
        let p = placed.as_ref();
        let outcome = if o.samples > 0 {
            match sample_point(m, set, perturbed, index, p, o, state) {
                Ok((mean, stats)) => AssemblyOutcome::Sampled(mean, stats),
                Err(s) => AssemblyOutcome::Failed(s),
            }
        } else {
            match assemble_point(m, set, perturbed, p, o, state) {
                Ok(a) => AssemblyOutcome::Assembled(Box::new(a)),
                Err(s) => AssemblyOutcome::Failed(s),
            }
        };
        tally.points += 1;
        tally.ok += u64::from(!matches!(outcome, AssemblyOutcome::Failed(_)));
        let row = AssemblyRow { index, point: p, outcome };
        write_selected_row(&row, &self.layout, self.o.selection.as_ref(), out);
    }
}

#[cfg(test)]
mod tests {
    use super::Stats;

    /// Regression: the sample variance was computed as (sum_sq - sum^2/n)/(n - 1), which cancels when the
    /// spread is small against the mean. Values 1e6 + k * 1e-4 (k = 0..9): mean 1e6 + 4.5e-4, standard
    /// deviation 1e-4 * sqrt(55/6) exactly.
    #[test]
    fn sample_spread_is_exact_when_small_against_the_mean() {
        let mut s = Stats::default();
        for k in 0..10 {
            s.add(1e6 + k as f64 * 1e-4);
        }
        let exact = 1e-4 * (55.0f64 / 6.0).sqrt();
        assert!((s.std() - exact).abs() < 1e-6 * exact, "{} vs {exact}", s.std());
        assert!((s.mean() - (1e6 + 4.5e-4)).abs() < 1e-9);
    }
}

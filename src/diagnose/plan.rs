//! `stiff plan`: which measurements (pose and load) to take so that the diagnosis can name every listed
//! effect and tell every pair apart. Each candidate measurement (a pose of the candidates with one of the
//! loads) contributes its three rows of the effects' signatures J (weighted by 1/sigma, each parameter in
//! units of its typical size); the plan is the greedy D-optimal design on all the effects' parameters
//! together: N times the measurement that most increases log det(J^T J) (the matrix determinant lemma,
//! log det(I3 + J_i M^-1 J_i^T)), each at most once. Maximising the joint determinant keeps every
//! effect's own information and the part of it the others cannot mimic, so identifiability and
//! separability are one criterion. The report gives, per effect, the smallest size detectable at 5 sigma
//! (alone, and beside the other effects) and the pairs whose signatures stay within `ABSORBED_SHARE` of
//! each other on the plan (inseparable).

use nalgebra::DMatrix;
use rand::seq::SliceRandom;
use rand::SeedableRng;

use super::data::{Dataset, Measurement, Pose};
use super::error::DiagnoseError;
use super::fit::{jacobian, settled, Candidate, Problem};
use super::measurement::PoseModel;
use super::select::{candidates, probe_step};
use crate::kinematics::frame::{Frame, Vec3, Vec6};
use crate::linalg::{capped_svd, outside_span, span_basis};
use crate::model::effect::Kind;
use crate::model::grid::PosePoint;
use crate::model::Model;
use crate::output::table::{header_line, names, selected_columns, write_row, Column, Record, Row};
use crate::platform::manipulator::Manipulator;

/// How to plan.
pub struct PlanOptions {
    /// The loads to choose from (N, N mm).
    pub loads: Vec<Vec6>,
    /// Measurements to choose.
    pub budget: usize,
    /// Effects to plan for (`NAME` for every target, or `NAME:TARGET`); empty: every candidate.
    pub effects: Vec<String>,
    /// Measurement noise, mm (each axis).
    pub noise: f64,
    /// A serial arm's calibration: the noise of a measured orientation about each axis (rad), where the
    /// instrument measures the target's orientation too.
    pub orientation_noise: Option<f64>,
    /// Choose at random (seeded) instead: a baseline to compare a plan with.
    pub random: Option<u64>,
}

/// One chosen measurement.
#[derive(Clone, Debug)]
pub struct Planned {
    /// The pose's name (its input name, or `p` and its index among the candidates).
    pub pose: String,
    /// Its position, mm.
    pub position: Vec3,
    /// The load, N and N mm.
    pub wrench: Vec6,
    /// A serial arm's configuration: the controller's angles (`Plan::joint_names`); empty for a pose.
    pub joints: Vec<f64>,
}

impl Row for Planned {
    /// The joint columns' names (`q_<joint>`): empty for poses.
    type Layout = Vec<String>;

    /// A points file `synth --points` measures, each row with its own load.
    fn record(&self, joints: &Vec<String>, r: &mut impl Record) {
        r.text(names::NAME, &self.pose);
        for (name, q) in joints.iter().zip(self.joints.iter().chain(std::iter::repeat(&0.0))) {
            r.number(name, *q);
        }
        for k in 0..3 {
            r.number(names::POSITION[k], self.position[k]);
        }
        for k in 0..6 {
            r.number(names::WRENCH[k], self.wrench[k]);
        }
    }
}

/// The columns of a plan, in order: `q_<joint>` for each of `joint_names` (a serial arm's plan), then the
/// position and the load.
pub fn plan_table(joint_names: &[String]) -> Vec<Column> {
    let blank = Planned { pose: String::new(), position: Vec3::zeros(), wrench: Vec6::zeros(), joints: Vec::new() };
    selected_columns(&blank, &joint_columns(joint_names), None)
}

fn joint_columns(joint_names: &[String]) -> Vec<String> {
    joint_names.iter().map(|n| format!("{}{n}", crate::columns::JOINT_PREFIX)).collect()
}

/// Writes the plan's measurements as a CSV table (header and rows).
pub fn write_plan(p: &Plan, out: &mut String) {
    out.push_str(&header_line(&plan_table(&p.joint_names)));
    let layout = joint_columns(&p.joint_names);
    for m in &p.measurements {
        write_row(m, &layout, out);
    }
}

/// What the plan lets a diagnosis see, per effect.
#[derive(Clone, Debug)]
pub struct Detectable {
    /// `NAME[:TARGET]`.
    pub label: String,
    /// Number of parameters.
    pub dim: usize,
    /// The smallest change of its weakest parameter direction seen at 5 sigma, alone (in the parameter's
    /// units: factor - 1 for a compliance factor, kg, mm, rad, mm/N, ...); infinite where not identifiable.
    pub alone: f64,
    /// The same beside every other listed effect (only the part of its signature they cannot mimic).
    pub beside_others: f64,
}

/// A plan and what it achieves.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The chosen measurements, in the order chosen.
    pub measurements: Vec<Planned>,
    /// A serial arm's joints (the plan's configurations give their angles); empty for poses.
    pub joint_names: Vec<String>,
    /// Per effect, the smallest detectable size.
    pub detectable: Vec<Detectable>,
    /// Pairs whose signatures on the plan are closer than `SEPARABLE_SINE`: (a, b, sine of the smallest
    /// angle between them).
    pub inseparable: Vec<(String, String, f64)>,
    /// Effects no candidate measurement sees (left out of the plan).
    pub unseen: Vec<String>,
    /// Candidate measurements considered (poses with a loaded equilibrium under the load).
    pub candidates: usize,
    /// log det of the information matrix of the plan (parameters in typical-size units).
    pub log_det: f64,
}

/// Why a plan cannot be made.
#[derive(Debug)]
pub enum PlanError {
    /// No candidate pose has a loaded equilibrium under any load.
    NoCandidates,
    /// The budget exceeds the candidate measurements.
    BudgetTooLarge {
        /// The budget asked.
        budget: usize,
        /// Candidate measurements available.
        candidates: usize,
    },
    /// An `--effects` entry names no candidate of this model and these candidates.
    UnknownEffect {
        /// The entry.
        name: String,
        /// What there is.
        known: Vec<String>,
    },
    /// The model could not predict at the candidates.
    Model(DiagnoseError),
    /// A serial arm's plan could not be made (why).
    Arm(String),
}

impl std::fmt::Display for PlanError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PlanError::NoCandidates => f.write_str("no candidate pose has a loaded equilibrium under any of the loads"),
            PlanError::BudgetTooLarge { budget, candidates } => write!(
                f,
                "the budget ({budget}) exceeds the candidate measurements ({candidates} poses x loads that can be \
                 measured): give more poses or loads, or a smaller budget"
            ),
            PlanError::UnknownEffect { name, known } => {
                write!(f, "`{name}` is not a candidate effect here (candidates: {})", known.join(", "))
            }
            PlanError::Model(e) => write!(f, "{e}"),
            PlanError::Arm(why) => f.write_str(why),
        }
    }
}

impl std::error::Error for PlanError {}

/// Plans `o.budget` measurements among `poses` x `o.loads`.
pub fn plan(model: &Model, poses: &[PosePoint], o: &PlanOptions) -> Result<Plan, PlanError> {
    let m = &model.manipulator;
    // Every (pose, load) the robot can be measured at.
    let mut data = Dataset { rows: Vec::new(), poses: Vec::new() };
    let mut state = m.new_state();
    for (index, p) in poses.iter().enumerate() {
        if PoseModel::at(m, &Frame::translation(p.position), &mut state).is_err() {
            continue;
        }
        let id = p.name.clone().unwrap_or_else(|| format!("p{index}"));
        let mut pose = Pose { id: id.clone(), position: p.position, rows: Vec::new() };
        for w in &o.loads {
            if settled(m, p.position, w, &mut state).is_ok() {
                pose.rows.push(data.rows.len());
                data.rows.push(Measurement {
                    pose_id: id.clone(),
                    position: p.position,
                    wrench: *w,
                    sigma: Some(o.noise),
                    ..Measurement::default()
                });
            }
        }
        if !pose.rows.is_empty() {
            data.poses.push(pose);
        }
    }
    let n = data.rows.len();
    if n == 0 {
        return Err(PlanError::NoCandidates);
    }
    if o.budget > n {
        return Err(PlanError::BudgetTooLarge { budget: o.budget, candidates: n });
    }
    let weights = vec![1.0 / o.noise; n];
    let problem = Problem::new(m, &model.measurement_terms, &data, weights, true, true).map_err(PlanError::Model)?;
    // The measurement order of a plan is not known yet: drift is not planned for.
    let offered: Vec<Candidate> = candidates(&problem, true).into_iter().filter(|c| c.kind != Kind::Drift).collect();
    let chosen = choose_effects(offered, &o.effects)?;
    let rows: Vec<usize> = (0..n).collect();
    let effects: Vec<Signature> = chosen
        .iter()
        .map(|c| {
            let probe = probe_step(c.kind);
            jacobian(&problem, std::slice::from_ref(c), &c.neutral(), 0, &rows)
                .map(|j| Signature {
                    label: c.label(),
                    signature: j * probe,
                    probe,
                    log_factor: c.kind.scales_springs(),
                })
                .map_err(|e| PlanError::Model(e.into()))
        })
        .collect::<Result<_, _>>()?;
    let chosen = choose(&effects, None, (n, 3), o);
    let measurements = chosen
        .picks
        .iter()
        .map(|&r| {
            let row = &data.rows[r];
            Planned { pose: row.pose_id.clone(), position: row.position, wrench: row.wrench, joints: Vec::new() }
        })
        .collect();
    Ok(Plan { measurements, joint_names: Vec::new(), ..chosen.plan(n) })
}

/// Plans `o.budget` measurements of a serial arm's target position (in an instrument's frame) among
/// `configurations` (a name, the controller's angles and the row's load) x `o.loads` (where none are given,
/// each configuration under its own load: zero, the arm's own weight, where its row gives none), for the calibration `stiff diagnose` makes of joint-space data: the effects it
/// offers by default (or `o.effects`, named as its `--candidates`), beside the instrument's frame and the
/// target's place that every calibration fits.
///
/// With `poses` (a parallel robot's commanded poses, one per configuration, whose joints are empty), the
/// plan is for the calibration of its legs from positions at those poses.
pub fn plan_arm(
    m: &Manipulator,
    configurations: &[super::calibrate::Configuration],
    poses: Option<&[Frame]>,
    o: &PlanOptions,
) -> Result<Plan, PlanError> {
    use super::calibrate::{joint_names, signatures, ArmEffect};
    if m.joint_space.is_none() && poses.is_none() {
        return Err(PlanError::Arm(format!("{} is not a serial arm read from URDF", m.name)));
    }
    let names = joint_names(m);
    let loads: Vec<Option<Vec6>> = match o.loads.is_empty() {
        true => vec![None],
        false => o.loads.iter().copied().map(Some).collect(),
    };
    // Every configuration under every load (its own where none are given), its pose beside it.
    let (candidates, candidate_poses): (Vec<super::calibrate::Configuration>, Vec<Option<Frame>>) = configurations
        .iter()
        .enumerate()
        .flat_map(|(k, (name, q, own))| {
            let pose = poses.map(|p| p[k]);
            loads.iter().map(move |w| ((name.clone(), q.clone(), w.unwrap_or(*own)), pose))
        })
        .unzip();
    let candidate_poses: Option<Vec<Frame>> = candidate_poses.into_iter().collect();
    let effects = o
        .effects
        .iter()
        .map(|e| ArmEffect::parse(e, &names))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|why| PlanError::Arm(format!("--effects {why}")))?;
    let found = signatures(m, &candidates, candidate_poses.as_deref(), &effects, o.noise, o.orientation_noise)
        .map_err(|e| PlanError::Arm(e.to_string()))?;
    let per = found.rows_per_candidate;
    let n = found.usable.len();
    if n == 0 {
        return Err(PlanError::NoCandidates);
    }
    if o.budget > n {
        return Err(PlanError::BudgetTooLarge { budget: o.budget, candidates: n });
    }
    // Each effect in units of the size that moves the candidates' points by one noise RMS: the choice does
    // not depend on units, the ridge that orders the first choices does.
    let scaled = |j: &DMatrix<f64>| {
        let probe = (j.ncols() as f64 * n as f64).sqrt() / j.norm().max(1e-300);
        (j * probe, probe)
    };
    // By default, the effects the candidates cannot see at all (a vertical first axis's compliance under
    // the arm's weight alone) are named, not planned for.
    let (seen, unseen): (Vec<_>, Vec<_>) =
        found.effects.iter().partition(|(_, j)| !o.effects.is_empty() || j.norm() > 0.0);
    let effects: Vec<Signature> = seen
        .into_iter()
        .map(|(label, j)| {
            let (signature, probe) = scaled(j);
            Signature { label: label.clone(), signature, probe, log_factor: false }
        })
        .collect();
    let nuisance = DMatrix::from_fn(found.nuisance.nrows(), found.nuisance.ncols(), |r, c| {
        let column = found.nuisance.column(c);
        column[r] * (n as f64).sqrt() / column.norm().max(1e-300)
    });
    let chosen = choose(&effects, Some(&nuisance), (n, per), o);
    let mut state = m.new_state();
    let measurements = chosen
        .picks
        .iter()
        .map(|&k| {
            let c = found.usable[k];
            let (pose, joints, wrench) = &candidates[c];
            let frame = match &candidate_poses {
                Some(p) => Some(p[c]),
                None => m.pose_at_joints(joints, &mut state),
            };
            let position = frame.map_or(Vec3::zeros(), |f| f.pos);
            Planned { pose: pose.clone(), position, wrench: *wrench, joints: joints.clone() }
        })
        .collect();
    let unseen = unseen.into_iter().map(|(label, _)| label.clone()).collect();
    // A parallel robot's plan gives poses (its joints are its legs, not columns of the plan).
    let joint_names = if m.joint_space.is_some() { names } else { Vec::new() };
    Ok(Plan { measurements, joint_names, unseen, ..chosen.plan(n) })
}

/// One effect's signature over the candidate measurements, in units of a typical size (`probe` of its own
/// units; a compliance factor's logarithm where `log_factor`).
struct Signature {
    label: String,
    signature: DMatrix<f64>,
    probe: f64,
    log_factor: bool,
}

/// A plan's choice and what it achieves.
struct Chosen {
    picks: Vec<usize>,
    detectable: Vec<Detectable>,
    inseparable: Vec<(String, String, f64)>,
    log_det: f64,
}

impl Chosen {
    fn plan(self, candidates: usize) -> Plan {
        let Chosen { detectable, inseparable, log_det, .. } = self;
        Plan {
            measurements: Vec::new(),
            joint_names: Vec::new(),
            detectable,
            inseparable,
            unseen: Vec::new(),
            candidates,
            log_det,
        }
    }
}

/// Chooses `o.budget` of the `n` candidate measurements (each `per` rows of the signatures) for `effects`
/// (and the parameters fitted beside them, `nuisance`, which are not reported), greedy D-optimal or at
/// random.
fn choose(effects: &[Signature], nuisance: Option<&DMatrix<f64>>, (n, per): (usize, usize), o: &PlanOptions) -> Chosen {
    let signatures: Vec<&DMatrix<f64>> = effects.iter().map(|e| &e.signature).collect();
    let all = hstack(&[signatures.clone(), nuisance.into_iter().collect()].concat());
    let picks = match o.random {
        Some(seed) => {
            let mut order: Vec<usize> = (0..n).collect();
            order.shuffle(&mut rand::rngs::StdRng::seed_from_u64(seed));
            order.truncate(o.budget);
            order
        }
        None => greedy_d_optimal(&all, o.budget, per),
    };
    let on_plan = |j: &DMatrix<f64>| rows_of(j, &picks, per);
    let planned: Vec<DMatrix<f64>> = signatures.iter().map(|j| on_plan(j)).collect();
    let fitted_beside = nuisance.map(on_plan);
    // Nested pairs (one effect's signature inside a larger one's: gravity in gravity-offset, an actuator
    // offset in its leg's geometry) are told apart by parsimony, not by the data: a larger effect that
    // contains this one is left out of "the others", and nested pairs are not called inseparable.
    let contains = |big: usize, small: usize| {
        planned[big].ncols() > planned[small].ncols() && share_outside(&planned[small], &planned[big]) < NESTED
    };
    let detectable = effects
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let others: Vec<&DMatrix<f64>> = (0..effects.len())
                .filter(|&k| k != i && !contains(k, i))
                .map(|k| &planned[k])
                .chain(fitted_beside.as_ref())
                .collect();
            let own = &planned[i];
            let rest = outside_span(own, &hstack(&others)).unwrap_or_else(|| own * 0.0);
            let size = |j: &DMatrix<f64>| to_units(e, 5.0 * e.probe / smallest_singular(j));
            Detectable { label: e.label.clone(), dim: own.ncols(), alone: size(own), beside_others: size(&rest) }
        })
        .collect();
    let mut inseparable = Vec::new();
    for a in 0..effects.len() {
        for b in a + 1..effects.len() {
            let sine = smallest_angle_sine(&planned[a], &planned[b]);
            if sine < SEPARABLE_SINE && !contains(a, b) && !contains(b, a) {
                inseparable.push((effects[a].label.clone(), effects[b].label.clone(), sine));
            }
        }
    }
    let information = on_plan(&all);
    let log_det = log_det_regularised(&(information.transpose() * &information), &all);
    Chosen { picks, detectable, inseparable, log_det }
}

/// The listed effects among those offered: `NAME` takes every target, `NAME:TARGET` one.
fn choose_effects(offered: Vec<Candidate>, wanted: &[String]) -> Result<Vec<Candidate>, PlanError> {
    if wanted.is_empty() {
        return Ok(offered);
    }
    let mut out: Vec<Candidate> = Vec::new();
    for w in wanted {
        let matching: Vec<&Candidate> =
            offered.iter().filter(|c| c.label() == *w || c.kind.name() == w.as_str()).collect();
        if matching.is_empty() {
            return Err(PlanError::UnknownEffect {
                name: w.clone(),
                known: offered.iter().map(|c| c.label()).collect(),
            });
        }
        for c in matching {
            if !out.contains(c) {
                out.push(c.clone());
            }
        }
    }
    Ok(out)
}

/// Columns side by side.
fn hstack(blocks: &[&DMatrix<f64>]) -> DMatrix<f64> {
    let rows = blocks.first().map_or(0, |b| b.nrows());
    let cols = blocks.iter().map(|b| b.ncols()).sum();
    let mut out = DMatrix::zeros(rows, cols);
    let mut at = 0;
    for b in blocks {
        out.columns_mut(at, b.ncols()).copy_from(b);
        at += b.ncols();
    }
    out
}

/// The `per` rows of each picked measurement.
fn rows_of(j: &DMatrix<f64>, picks: &[usize], per: usize) -> DMatrix<f64> {
    DMatrix::from_fn(per * picks.len(), j.ncols(), |r, c| j[(per * picks[r / per] + r % per, c)])
}

/// Two effects are inseparable on a plan when the sine of the smallest angle between their signatures is
/// below this: an effect at the size the plan detects (5 sigma) then differs from the other's best mimic by
/// less than 1 sigma, so it must be five times larger before a diagnosis can tell them apart.
const SEPARABLE_SINE: f64 = 0.2;

/// A signature lies inside another's span when less than this share of it is outside.
const NESTED: f64 = 1e-6;

/// The share (Frobenius) of `j` outside the span of `other` (all of it where `other` is not finite).
fn share_outside(j: &DMatrix<f64>, other: &DMatrix<f64>) -> f64 {
    outside_span(j, other).map_or(1.0, |rest| rest.norm() / j.norm().max(1e-300))
}

/// The smallest singular value of `j` (0 where it has fewer rows than columns or is not finite).
fn smallest_singular(j: &DMatrix<f64>) -> f64 {
    if j.nrows() < j.ncols() {
        return 0.0;
    }
    capped_svd(j.clone(), false, false).map_or(0.0, |svd| svd.singular_values.min())
}

/// The sine of the smallest angle between the column spaces of `a` and `b` (0: some combination of one is a
/// combination of the other, or either is rank-deficient).
fn smallest_angle_sine(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    let (Some(qa), Some(qb)) = (span_basis(a), span_basis(b)) else { return 0.0 };
    if qa.ncols() < a.ncols() || qb.ncols() < b.ncols() || a.nrows() < a.ncols() + b.ncols() {
        return 0.0;
    }
    let residual = &qa - &qb * (qb.transpose() * &qa);
    let rb = &qb - &qa * (qa.transpose() * &qb);
    smallest_singular(&residual).min(smallest_singular(&rb))
}

/// A size in the effect's own units: a compliance factor's logarithm to `factor - 1`.
fn to_units(e: &Signature, size: f64) -> f64 {
    if !size.is_finite() {
        return f64::INFINITY;
    }
    if e.log_factor {
        size.exp() - 1.0
    } else {
        size
    }
}

/// Ridge added to the information matrix while choosing (share of its mean diagonal over every candidate):
/// it keeps the first choices, when the matrix is still singular, ordered by what they add.
const RIDGE: f64 = 1e-9;

fn ridge(all: &DMatrix<f64>) -> f64 {
    let p = all.ncols().max(1) as f64;
    RIDGE * all.norm_squared() / p
}

fn log_det_regularised(m: &DMatrix<f64>, all: &DMatrix<f64>) -> f64 {
    let r = ridge(all);
    let mut a = m.clone();
    for i in 0..a.nrows() {
        a[(i, i)] += r;
    }
    a.cholesky().map_or(f64::NEG_INFINITY, |c| 2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>())
}

/// Greedy D-optimal choice of `budget` measurements (three rows each of `all`), each at most once.
fn greedy_d_optimal(all: &DMatrix<f64>, budget: usize, per: usize) -> Vec<usize> {
    let p = all.ncols();
    let count = all.nrows() / per;
    let mut inverse = DMatrix::<f64>::identity(p, p) / ridge(all);
    let mut picked = vec![false; count];
    let mut out = Vec::with_capacity(budget);
    for _ in 0..budget {
        let mut best = (f64::NEG_INFINITY, usize::MAX);
        for i in (0..count).filter(|&i| !picked[i]) {
            let ji = all.rows(per * i, per);
            let a = ji * &inverse;
            let g = DMatrix::identity(per, per) + DMatrix::from_fn(per, per, |r, c| a.row(r).dot(&ji.row(c)));
            let gain = g.determinant().ln();
            if gain > best.0 {
                best = (gain, i);
            }
        }
        let i = best.1;
        if i == usize::MAX {
            break;
        }
        picked[i] = true;
        out.push(i);
        // Woodbury: (M + J^T J)^-1 = M^-1 - M^-1 J^T (I + J M^-1 J^T)^-1 J M^-1.
        let ji = all.rows(per * i, per).into_owned();
        let mj = &inverse * ji.transpose();
        let g = DMatrix::<f64>::identity(per, per) + &ji * &mj;
        if let Some(gi) = g.try_inverse() {
            inverse -= &mj * gi * mj.transpose();
        }
    }
    out
}

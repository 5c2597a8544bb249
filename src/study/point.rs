//! One pose of a study: the manipulator's stiffness there (unloaded, or at its loaded equilibrium under a
//! wrench) and what follows from it.

use std::fmt::Write;

pub use super::warm_start::LoadedHistory;
use crate::kinematics::frame::{Mat6, Vec3, Vec6};
use crate::linalg::all_finite;
use crate::model::grid::PosePoint;
use crate::output::report::{fmt6, matrix, TWIST, WRENCH};
use crate::platform::compliance::{analyse, analyse_compliance, principal, ArmOutcome, Outcome, PrincipalCompliance};
use crate::platform::leg::LegFailure;
use crate::platform::loaded::{Deflection, DeflectionFailure};
use crate::platform::manipulator::{Manipulator, ManipulatorState, PoseFailure};
use crate::platform::serial::ArmAnswer;

/// The outcome of one point, as the map reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Computed and written.
    Ok,
    /// Inverse kinematics found no configuration of some leg.
    Unreachable,
    /// The sum over legs has rank below 6.
    Singular,
    /// A leg's springs do not restrain what its passive joints leave free.
    SingularLeg,
    /// The loaded equilibrium was not found.
    NotConverged,
    /// The loaded equilibrium was found but is unstable (tangent stiffness not positive definite, or a leg
    /// unstable with its end held).
    Unstable,
    /// Full rank, but the equilibrated stiffness' condition number exceeds
    /// `compliance::CONDITION_LIMIT` (or, unloaded, round-off made it indefinite): too few correct digits
    /// to write a compliance. Typical within a fraction of a millimetre of a reach boundary.
    IllConditioned,
    /// A number overflowed (non-finite stiffness or displacement), e.g. under an astronomically large load.
    Overflow,
    /// A serial arm whose elastic joints leave directions the tip cannot move along (fewer than six springs,
    /// or a configuration where their motions lose rank): the compliance is written and singular, the
    /// stiffness is infinite along those directions (`PointResult::rigid`); nothing is free.
    RigidDirections,
}

impl Status {
    /// Every status, in the order of `as_str`'s list.
    pub const ALL: [Status; 9] = [
        Status::Ok,
        Status::Unreachable,
        Status::Singular,
        Status::SingularLeg,
        Status::NotConverged,
        Status::Unstable,
        Status::IllConditioned,
        Status::Overflow,
        Status::RigidDirections,
    ];

    /// The status's name in CSV and reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Unreachable => "unreachable",
            Status::Singular => "singular",
            Status::SingularLeg => "singular_leg",
            Status::NotConverged => "not_converged",
            Status::Unstable => "unstable",
            Status::IllConditioned => "ill_conditioned",
            Status::Overflow => "overflow",
            Status::RigidDirections => "rigid_directions",
        }
    }

    /// The status of a pose where a leg failed.
    pub fn of(e: &PoseFailure) -> Self {
        match e.failure {
            LegFailure::Unreachable(f) if f.at_reach_boundary() => Status::IllConditioned,
            LegFailure::Unreachable(_) | LegFailure::OutOfReach { .. } => Status::Unreachable,
            LegFailure::SingularChain => Status::SingularLeg,
            LegFailure::NotConverged { .. } => Status::NotConverged,
            LegFailure::NotFinite => Status::Overflow,
        }
    }
}

/// What a study reports at one point.
#[derive(Clone, Debug)]
pub struct PointResult {
    /// Its status.
    pub status: Status,
    /// Rank of the stiffness matrix (None where it was not computed).
    pub rank: Option<usize>,
    /// Condition number of the equilibrated stiffness (None where it was not computed).
    pub condition: Option<f64>,
    /// Stiffness at the reference point (tangent, in loaded mode).
    pub stiffness: Option<Mat6>,
    /// Compliance C = K^-1.
    pub compliance: Option<Mat6>,
    /// Principal compliances of C's symmetric part.
    pub principal: Option<PrincipalCompliance>,
    /// Deflection under the point's wrench: linear (C w) unloaded, the loaded equilibrium's displacement
    /// in loaded mode.
    pub deflection: Option<Vec6>,
    /// Free directions of a singular manipulator.
    pub free: Vec<Vec6>,
    /// Rigid directions of a serial arm (`Status::RigidDirections`): unit wrenches (N, N mm; moments
    /// weighed by the length scale) that deflect nothing, a basis of the null space of C.
    pub rigid: Vec<Vec6>,
    /// Manipulator-level Newton iterations (loaded mode).
    pub iterations: usize,
    /// Why nothing was computed, where a leg or the loaded equilibrium failed.
    pub failure: Option<PointFailure>,
}

/// Why a point has no stiffness: a leg failed there, or the loaded equilibrium was not found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PointFailure {
    /// A leg failed (unreachable, singular, ...).
    Pose(PoseFailure),
    /// The loaded equilibrium was not found.
    Equilibrium(DeflectionFailure),
}

impl std::fmt::Display for PointFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PointFailure::Pose(e) => write!(f, "{e}"),
            PointFailure::Equilibrium(e) => write!(f, "{e}"),
        }
    }
}

impl PointResult {
    /// A result with nothing computed (a header's blank row).
    pub fn blank() -> Self {
        Self::failed(Status::Ok)
    }

    pub(crate) fn failed(status: Status) -> Self {
        Self {
            status,
            rank: None,
            condition: None,
            stiffness: None,
            compliance: None,
            principal: None,
            deflection: None,
            free: Vec::new(),
            rigid: Vec::new(),
            iterations: 0,
            failure: None,
        }
    }

    fn failed_at(e: PoseFailure) -> Self {
        Self { failure: Some(PointFailure::Pose(e)), ..Self::failed(Status::of(&e)) }
    }

    /// A result from a stiffness matrix: compliance, rank, condition and principal compliances. `loaded`:
    /// K is a tangent stiffness (not symmetric in general; its full inverse is written, and an indefinite
    /// symmetric part is instability, decided by the caller); else K is symmetric positive semi-definite
    /// by theory, so an indefinite one can only come from lost digits.
    fn from_stiffness(k: Mat6, magnitude: &Vec6, length_scale: f64, loaded: bool) -> Self {
        let a = analyse(&k, magnitude, length_scale, !loaded);
        let base = PointResult { stiffness: Some(k), condition: Some(a.condition), ..PointResult::failed(Status::Ok) };
        match a.outcome {
            Outcome::Regular { compliance } => {
                let status = if loaded || a.positive_definite { Status::Ok } else { Status::IllConditioned };
                PointResult {
                    status,
                    rank: Some(6),
                    compliance: Some(compliance),
                    principal: principal(&compliance),
                    ..base
                }
            }
            Outcome::IllConditioned => PointResult { status: Status::IllConditioned, rank: Some(6), ..base },
            Outcome::Singular { rank, free } => {
                PointResult { status: Status::Singular, rank: Some(rank), free, ..base }
            }
            Outcome::NotFinite => PointResult { status: Status::Overflow, condition: None, ..base },
        }
    }

    /// A result from a serial arm's compliance C (`platform::serial`): where C has rank below 6 the arm is
    /// rigid along the rest (`RigidDirections`: C written, no stiffness); otherwise K = C^-1 and its
    /// condition as `from_stiffness` finds them, with C itself written (it was computed directly); the
    /// definiteness is no question here (`analyse_compliance`).
    /// A direction K resists least is never called free: an arm has no passive joint, so nothing is free
    /// (a nearly singular configuration is `ill_conditioned`).
    fn from_compliance(c: Mat6, length_scale: f64, loaded: bool) -> Self {
        let base = PointResult { compliance: Some(c), principal: principal(&c), ..PointResult::failed(Status::Ok) };
        match analyse_compliance(&c, length_scale, !loaded) {
            ArmOutcome::Regular { stiffness, condition } => PointResult {
                status: Status::Ok,
                rank: Some(6),
                condition: Some(condition),
                stiffness: Some(stiffness),
                ..base
            },
            ArmOutcome::IllConditioned { condition } => PointResult {
                status: Status::IllConditioned,
                rank: Some(6),
                condition: Some(condition),
                ..PointResult::failed(Status::IllConditioned)
            },
            ArmOutcome::Rigid { rank, rigid } => PointResult {
                status: Status::RigidDirections,
                rank: Some(rank),
                condition: Some(f64::INFINITY),
                rigid,
                ..base
            },
            ArmOutcome::NotFinite => PointResult::failed(Status::Overflow),
        }
    }

    /// Marks a row whose numbers overflowed: nothing non-finite is ever written under `ok`.
    fn check_finite(mut self) -> Self {
        let finite = |m: &Option<Mat6>| m.is_none_or(|m| all_finite(m.as_slice()));
        let finite_v = self.deflection.is_none_or(|d| all_finite(d.as_slice()));
        if self.status == Status::Ok && !(finite(&self.compliance) && finite_v) {
            self.status = Status::Overflow;
            self.compliance = None;
            self.principal = None;
        }
        self
    }
}

/// The unloaded stiffness and compliance at the point's pose.
pub fn unloaded_point(m: &Manipulator, p: &PosePoint, state: &mut ManipulatorState) -> PointResult {
    arm_answer(m.arm_unloaded(&p.frame(), state), p, m.length_scale).unwrap_or_else(|| unloaded_parallel(m, p, state))
}

/// A serial arm's unloaded result at the joint coordinates `pose_of_joints` seeded `state` with (`placed`
/// the pose they give): no placement, the configuration being given. As `unloaded_point` for any other
/// manipulator.
pub fn unloaded_at_joints(m: &Manipulator, placed: &PosePoint, state: &mut ManipulatorState) -> PointResult {
    arm_answer(m.arm_unloaded_at_joints(state), placed, m.length_scale)
        .unwrap_or_else(|| unloaded_point(m, placed, state))
}

/// A serial arm's unloaded answer as a result (its deflection under the point's wrench); None where the
/// manipulator is no serial arm.
fn arm_answer(answer: Option<Result<ArmAnswer, PoseFailure>>, p: &PosePoint, length_scale: f64) -> Option<PointResult> {
    let mut r = match answer? {
        Ok(a) => PointResult::from_compliance(a.compliance, length_scale, false),
        Err(e) => return Some(PointResult::failed_at(e)),
    };
    r.deflection = match (&r.compliance, &p.wrench) {
        (Some(c), Some(w)) => Some(c * w),
        _ => None,
    };
    Some(r.check_finite())
}

/// A parallel manipulator's unloaded result at `p`.
fn unloaded_parallel(m: &Manipulator, p: &PosePoint, state: &mut ManipulatorState) -> PointResult {
    let agg = match m.unloaded(&p.frame(), state) {
        Ok(a) => a,
        Err(e) => return PointResult::failed_at(e),
    };
    let mut r = PointResult::from_stiffness(agg.stiffness, &agg.magnitude, m.length_scale, false);
    r.deflection = match (&r.compliance, &p.wrench) {
        (Some(c), Some(w)) => Some(c * w),
        _ => None,
    };
    r.check_finite()
}

/// A point as a pose: itself where it is given as a pose; where it is given by a serial arm's joint
/// coordinates (`PosePoint::joints`, in the arm's order: `PointSet::order_joints`), the pose forward
/// kinematics puts its tool at, with `state` seeded at those coordinates (so the placement keeps the
/// configuration given). None where the angles give no finite pose (the row is then `unreachable`).
pub fn pose_of_joints<'a>(
    m: &Manipulator,
    p: &'a PosePoint,
    state: &mut ManipulatorState,
) -> Option<std::borrow::Cow<'a, PosePoint>> {
    if p.joints.is_empty() {
        return Some(std::borrow::Cow::Borrowed(p));
    }
    let f = m.pose_at_joints(&p.joints, state)?;
    // The joints are not copied: the placed point is a pose.
    Some(std::borrow::Cow::Owned(PosePoint {
        name: p.name.clone(),
        position: f.pos,
        rotation: crate::kinematics::frame::rotation_vector(&f.rot),
        wrench: p.wrench,
        joints: Vec::new(),
    }))
}

/// For each joint of `m`'s joint space, the index of its column among `columns` (a points file's joint
/// names), or why the two do not match (the arm's joint names; the file's missing or extra ones).
pub fn joint_order(m: &Manipulator, columns: &[String]) -> Result<Vec<usize>, String> {
    let Some(space) = &m.joint_space else {
        return Err(format!(
            "the points give joint coordinates ({}), but {} is not a serial arm read from URDF: give poses (x_mm, y_mm, z_mm)",
            columns.iter().map(|c| format!("q_{c}")).collect::<Vec<_>>().join(", "),
            m.name
        ));
    };
    let missing: Vec<&String> = space.names.iter().filter(|n| !columns.contains(n)).collect();
    let extra: Vec<&String> = columns.iter().filter(|c| !space.names.contains(c)).collect();
    if !missing.is_empty() || !extra.is_empty() {
        let list = |v: &[&String]| v.iter().map(|n| format!("q_{n}")).collect::<Vec<_>>().join(", ");
        return Err(format!(
            "the joint columns must be exactly q_ and each of the arm's joints ({}): missing {}; not joints of the arm {}",
            space.names.join(", "),
            if missing.is_empty() { "none".into() } else { list(&missing) },
            if extra.is_empty() { "none".into() } else { list(&extra) },
        ));
    }
    Ok(space.names.iter().map(|n| columns.iter().position(|c| c == n).expect("checked")).collect())
}

/// The loaded equilibrium under `wrench` at a commanded pose: where the platform settles (its displacement
/// is the compliance error paper 000 computes for milling) and the tangent compliance there. `history`
/// carries the run's last solutions as the warm start of the next point.
pub fn loaded_point(
    m: &Manipulator,
    p: &PosePoint,
    wrench: &Vec6,
    state: &mut ManipulatorState,
    history: &mut LoadedHistory,
) -> PointResult {
    if m.is_serial_arm() {
        return loaded_arm_point(m, p, wrench, state, true);
    }
    let commanded = p.frame();
    if let Err(e) = m.place_for_load(&commanded, state) {
        history.clear();
        return PointResult::failed_at(e);
    }
    // The first point of a line (or of the run) keeps its factorisations for the first of the next.
    let begins_line = history.begins_line(&p.position);
    let first_of_line = begins_line || history.is_empty();
    if begins_line {
        state.resume_line_start();
    }
    let start = history.start(&p.position, &commanded, &mut state.legs);
    let mut attempt = m.deflect(&commanded, wrench, start.as_ref(), state);
    if attempt.is_err() && start.is_some() {
        m.place_for_load(&commanded, state).ok();
        attempt = m.deflect(&commanded, wrench, None, state);
    }
    match &attempt {
        Ok(d) => {
            if first_of_line {
                state.keep_line_start();
            }
            history.push(p.position, d.displacement, &state.legs);
        }
        Err(_) => history.clear(),
    }
    loaded_result(m, attempt.map(Loaded::of))
}

/// A serial arm's loaded result at `p` (placed there first with `place`; without, at the configuration
/// `pose_of_joints` seeded `state` with): Newton's method on its joints from their rest, which no warm
/// start from the points before would shorten.
fn loaded_arm_point(
    m: &Manipulator,
    p: &PosePoint,
    wrench: &Vec6,
    state: &mut ManipulatorState,
    place: bool,
) -> PointResult {
    let commanded = p.frame();
    if place {
        if let Err(e) = m.place_for_load(&commanded, state) {
            return PointResult::failed_at(e);
        }
    }
    // The arm's own answer, not `deflect`'s: a map writes the tangent compliance, and the stiffness
    // `deflect` inverts it to for its other callers would be computed for nothing.
    match m.arm_deflect(&commanded, wrench, state) {
        Some(answer) => loaded_result(m, answer.map(Loaded::of_arm)),
        None => loaded_result(m, m.deflect(&commanded, wrench, None, state).map(Loaded::of)),
    }
}

/// What a loaded result is made of: the tangent (a serial arm's compliance, computed directly, or the
/// stiffness holding a parallel platform), the displacement, stability and the Newton iterations.
struct Loaded {
    tangent: Tangent,
    displacement: Vec6,
    stable: bool,
    iterations: usize,
}

enum Tangent {
    Compliance(Mat6),
    Stiffness { stiffness: Mat6, magnitude: Vec6 },
}

impl Loaded {
    fn of(d: Deflection) -> Self {
        let tangent = match d.compliance {
            Some(c) => Tangent::Compliance(c),
            None => Tangent::Stiffness { stiffness: d.held.stiffness, magnitude: d.held.magnitude },
        };
        Loaded { tangent, displacement: d.displacement, stable: d.stable, iterations: d.iterations }
    }

    fn of_arm(a: ArmAnswer) -> Self {
        let tangent = Tangent::Compliance(a.compliance);
        Loaded { tangent, displacement: a.displacement, stable: a.stable, iterations: a.iterations }
    }
}

/// A serial arm's loaded result at the joint coordinates `pose_of_joints` seeded `state` with (`placed`
/// the pose they give), not placed again; as `loaded_point` for any other manipulator.
pub fn loaded_at_joints(
    m: &Manipulator,
    placed: &PosePoint,
    wrench: &Vec6,
    state: &mut ManipulatorState,
    history: &mut LoadedHistory,
) -> PointResult {
    if m.is_serial_arm() {
        loaded_arm_point(m, placed, wrench, state, false)
    } else {
        loaded_point(m, placed, wrench, state, history)
    }
}

/// The result of a loaded solve.
fn loaded_result(m: &Manipulator, attempt: Result<Loaded, DeflectionFailure>) -> PointResult {
    match attempt {
        Ok(d) => {
            let mut r = match d.tangent {
                Tangent::Compliance(c) => PointResult::from_compliance(c, m.length_scale, true),
                Tangent::Stiffness { stiffness, magnitude } => {
                    PointResult::from_stiffness(stiffness, &magnitude, m.length_scale, true)
                }
            };
            r.deflection = Some(d.displacement);
            r.iterations = d.iterations;
            // An unstable equilibrium says more than its conditioning: ill-conditioned or not, it is not where
            // the platform stays.
            if matches!(r.status, Status::Ok | Status::IllConditioned | Status::RigidDirections) && !d.stable {
                r.status = Status::Unstable;
            }
            r.check_finite()
        }
        Err(DeflectionFailure::Leg(e)) => PointResult::failed_at(e),
        Err(e @ (DeflectionFailure::NotConverged { .. } | DeflectionFailure::SingularStiffness { .. })) => {
            PointResult { failure: Some(PointFailure::Equilibrium(e)), ..PointResult::failed(Status::NotConverged) }
        }
    }
}

/// What one free direction of a singular manipulator is, read from its twist (v, w) at the reference point
/// r: a translation (w = 0), or a screw about the axis w through the point p = r + (w x v) / |w|^2 with
/// pitch h = w . v / |w|^2, a rotation where h = 0 (v = w x (r - p): the reference point turning about p).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FreeMotion {
    /// A translation along a unit direction.
    Translation {
        /// Unit direction.
        direction: Vec3,
    },
    /// A rotation about an axis.
    Rotation {
        /// Unit axis.
        axis: Vec3,
        /// The point of the axis nearest the reference point, mm.
        through: Vec3,
    },
    /// A screw: rotation about an axis with translation along it.
    Screw {
        /// Unit axis.
        axis: Vec3,
        /// The point of the axis nearest the reference point, mm.
        through: Vec3,
        /// Translation per rotation, mm/rad.
        pitch: f64,
    },
}

/// A rotation part below this (in mm-equivalent units of the unit twist, rotations weighed by the length
/// scale) is no rotation; a pitch below this times the length scale is none: round-off of the SVD basis.
const FREE_MOTION_TOLERANCE: f64 = 1e-9;

/// The kind of each free direction (`twist` at the reference point `reference`, rotations weighed by
/// `length_scale` as in `PointResult::free`).
pub fn free_motion(twist: &Vec6, reference: &Vec3, length_scale: f64) -> FreeMotion {
    let v = Vec3::new(twist[0], twist[1], twist[2]);
    let w = Vec3::new(twist[3], twist[4], twist[5]);
    if w.norm() * length_scale <= FREE_MOTION_TOLERANCE * (v.norm() + w.norm() * length_scale) {
        return FreeMotion::Translation { direction: v.normalize() };
    }
    let w2 = w.norm_squared();
    let through = reference + w.cross(&v) / w2;
    let pitch = w.dot(&v) / w2;
    let axis = w.normalize();
    if pitch.abs() <= FREE_MOTION_TOLERANCE * length_scale {
        FreeMotion::Rotation { axis, through }
    } else {
        FreeMotion::Screw { axis, through, pitch }
    }
}

/// The point every free rotation's axis passes through, when the free directions are all rotations about
/// axes through one point (a Stewart-Gough platform whose leg lines meet): least squares of
/// w_i x p = w_i x r - v_i over the free twists, accepted where it holds to round-off.
pub fn common_centre(free: &[Vec6], reference: &Vec3, length_scale: f64) -> Option<Vec3> {
    if free.len() < 2 {
        return None;
    }
    let mut a = nalgebra::DMatrix::zeros(3 * free.len(), 3);
    let mut b = nalgebra::DVector::zeros(3 * free.len());
    for (i, t) in free.iter().enumerate() {
        let v = Vec3::new(t[0], t[1], t[2]);
        let w = Vec3::new(t[3], t[4], t[5]);
        let rhs = w.cross(reference) - v;
        let skew = crate::kinematics::frame::skew(&w);
        for r in 0..3 {
            for c in 0..3 {
                a[(3 * i + r, c)] = skew[(r, c)];
            }
            b[3 * i + r] = rhs[r];
        }
    }
    let svd = crate::linalg::capped_svd(a.clone(), true, true)?;
    let p = svd.solve(&b, 1e-12).ok()?;
    let residual = (&a * &p - &b).amax();
    let centre = Vec3::new(p[0], p[1], p[2]);
    let scale = 1.0 + centre.norm() / length_scale;
    (residual <= 1e-9 * scale).then_some(centre)
}

/// The free directions in words, one line each (or one line for rotations about a common point).
pub fn describe_free(free: &[Vec6], reference: &Vec3, length_scale: f64) -> Vec<String> {
    let fmt3 = |v: &Vec3| {
        // A coordinate that rounds to zero in four decimals prints without its round-off's sign.
        let t = |x: f64| if x.abs() < 0.5e-4 { 0.0 } else { x };
        format!("({:.4}, {:.4}, {:.4})", t(v.x), t(v.y), t(v.z))
    };
    let motions: Vec<FreeMotion> = free.iter().map(|t| free_motion(t, reference, length_scale)).collect();
    let all_rotations = motions.iter().all(|m| matches!(m, FreeMotion::Rotation { .. }));
    if all_rotations {
        if let Some(c) = common_centre(free, reference, length_scale) {
            let span = match free.len() {
                3 => "about any axis".to_string(),
                n => format!("about axes in a {n}-dimensional family"),
            };
            return vec![format!("free rotations {span} through {} mm", fmt3(&c))];
        }
    }
    motions
        .iter()
        .map(|m| match m {
            FreeMotion::Translation { direction } => format!("translation along {}", fmt3(direction)),
            FreeMotion::Rotation { axis, through } => {
                format!("rotation about the axis {} through {} mm", fmt3(axis), fmt3(through))
            }
            FreeMotion::Screw { axis, through, pitch } => {
                format!("screw about the axis {} through {} mm, pitch {pitch:.4e} mm/rad", fmt3(axis), fmt3(through))
            }
        })
        .collect()
}

/// The report of `stiff point`. `loaded`: `r` is the loaded equilibrium under the point's wrench (its
/// displacement and tangent matrices, not symmetric, every entry shown).
pub fn point_report(model: &str, p: &PosePoint, r: &PointResult, loaded: bool, length_scale: f64) -> String {
    let mut out = String::new();
    let (x, o) = (p.position, p.rotation);
    let _ = writeln!(out, "{model}");
    let _ = writeln!(
        out,
        "pose: x = {} mm, y = {} mm, z = {} mm; orientation (rotation vector) {} {} {} rad",
        x.x, x.y, x.z, o.x, o.y, o.z
    );
    let rank = r.rank.map_or(String::from("not computed"), |k| k.to_string());
    let condition = r.condition.map_or(String::from("not computed"), |c| format!("{c:.3e}"));
    let _ = writeln!(out, "status: {}, rank {rank}, condition {condition}\n", r.status.as_str());
    if let Some(k) = &r.stiffness {
        matrix(
            &mut out,
            "Stiffness K: wrench (rows) per displacement (columns) at the reference point, base frame",
            k,
            WRENCH,
            TWIST,
        );
    }
    if let Some(c) = &r.compliance {
        matrix(&mut out, "Compliance C = K^-1: displacement (rows) per wrench (columns)", c, TWIST, WRENCH);
    }
    if let Some(pc) = &r.principal {
        let _ = writeln!(
            out,
            "principal compliance (of C's symmetric part): translation max {:.4e} / min {:.4e} mm/N, rotation max {:.4e} rad/(N mm)",
            pc.translation_max, pc.translation_min, pc.rotation_max
        );
    }
    if let (Some(d), Some(w)) = (&r.deflection, &p.wrench) {
        let what = if loaded { "loaded equilibrium displacement" } else { "linear deflection C w" };
        let _ = writeln!(out, "{what} under the wrench {}: {}", fmt6(w), fmt6(d));
    }
    if !r.free.is_empty() {
        let _ = writeln!(out, "free directions (unit twists dx dy dz [mm], rx ry rz [rad]):");
        for f in &r.free {
            let _ = writeln!(out, "  {}", fmt6(f));
        }
        let reference = p.position + r.deflection.map_or(Vec3::zeros(), |d| Vec3::new(d[0], d[1], d[2]));
        let _ = writeln!(out, "that is:");
        for line in describe_free(&r.free, &reference, length_scale) {
            let _ = writeln!(out, "  {line}");
        }
    }
    if !r.rigid.is_empty() {
        let _ = writeln!(
            out,
            "rigid directions: unit wrenches (Fx Fy Fz [N], Mx My Mz [N mm]) that deflect nothing, the arm's elastic joints cannot move the tip against them:"
        );
        for w in &r.rigid {
            let _ = writeln!(out, "  {}", fmt6(w));
        }
    }
    if let Some(f) = &r.failure {
        let _ = writeln!(out, "why: {f}");
    }
    out
}

/// `stiff point --json`: the report's content for programs (units in the key names; matrices row by row).
#[derive(Clone, Debug, serde::Serialize)]
pub struct PointJson {
    /// The model's name.
    pub model: String,
    /// A tree's tip the pose is at (a model with several tips).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tip: Option<String>,
    /// The commanded pose.
    pub pose: PoseJson,
    /// At the commanded pose, unloaded.
    pub unloaded: ResultJson,
    /// Under the wrench: the loaded equilibrium (when a wrench is given).
    pub loaded: Option<ResultJson>,
}

/// A commanded pose.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PoseJson {
    /// Reference point, mm.
    pub position_mm: [f64; 3],
    /// Orientation, rotation vector, rad.
    pub rotation_rad: [f64; 3],
    /// The wrench given (N, N mm), if any.
    pub wrench: Option<[f64; 6]>,
}

/// One result: status and why, matrices, principal compliances, deflection, free directions.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ResultJson {
    /// The status (docs/GUIDE.md: statuses).
    pub status: &'static str,
    /// Why there is no compliance, where a leg or the loaded equilibrium failed.
    pub reason: Option<String>,
    /// Rank of K.
    pub rank: Option<usize>,
    /// Condition number of the equilibrated K.
    pub condition: Option<f64>,
    /// K: wrench (N, N mm) per displacement (mm, rad), rows Fx..Mz, columns dx..rz.
    pub stiffness: Option<[[f64; 6]; 6]>,
    /// C = K^-1: displacement per wrench.
    pub compliance: Option<[[f64; 6]; 6]>,
    /// Principal compliances of C's symmetric part: translation max / min (mm/N), rotation max (rad/(N mm)).
    pub principal: Option<[f64; 3]>,
    /// Deflection under the wrench (linear C w unloaded, the equilibrium's displacement loaded), mm and rad.
    pub deflection: Option<[f64; 6]>,
    /// Free directions of a singular pose: unit twists (dx, dy, dz mm; rx, ry, rz rad).
    pub free_directions: Vec<[f64; 6]>,
    /// The same in words (translations, rotations about an axis through a point, screws).
    pub free_motions: Vec<String>,
    /// Rigid directions of a serial arm (`rigid_directions`): unit wrenches (N; N mm) that deflect nothing.
    pub rigid_directions: Vec<[f64; 6]>,
    /// Newton iterations of the loaded equilibrium.
    pub iterations: usize,
}

fn rows(m: &Mat6) -> [[f64; 6]; 6] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

impl ResultJson {
    /// The JSON form of `r` at the pose `p` (free motions described about the displaced reference point).
    pub fn new(p: &PosePoint, r: &PointResult, length_scale: f64) -> Self {
        let reference = p.position + r.deflection.map_or(Vec3::zeros(), |d| Vec3::new(d[0], d[1], d[2]));
        ResultJson {
            status: r.status.as_str(),
            reason: r.failure.map(|f| f.to_string()),
            rank: r.rank,
            condition: r.condition.filter(|c| c.is_finite()),
            stiffness: r.stiffness.as_ref().map(rows),
            compliance: r.compliance.as_ref().map(rows),
            principal: r.principal.map(|p| [p.translation_max, p.translation_min, p.rotation_max]),
            deflection: r.deflection.map(|d| std::array::from_fn(|k| d[k])),
            free_directions: r.free.iter().map(|t| std::array::from_fn(|k| t[k])).collect(),
            free_motions: if r.free.is_empty() { Vec::new() } else { describe_free(&r.free, &reference, length_scale) },
            rigid_directions: r.rigid.iter().map(|w| std::array::from_fn(|k| w[k])).collect(),
            iterations: r.iterations,
        }
    }
}

/// A row's first cells, as every table over poses writes them: its index, the point's name, its position
/// and, with `orientation`, its orientation (so a table's output reads back as a points file).
pub fn record_pose(r: &mut impl crate::output::table::Record, index: u64, p: &PosePoint, orientation: bool) {
    record_pose_at(r, index, None, p, orientation);
}

/// As `record_pose`, a tree's row naming its tip (`Some`) after the point's name: the pose is the tip's.
pub fn record_pose_at(
    r: &mut impl crate::output::table::Record,
    index: u64,
    tip: Option<&str>,
    p: &PosePoint,
    orientation: bool,
) {
    use crate::output::table::names;
    r.count(names::INDEX, Some(index));
    r.text(names::NAME, p.name.as_deref().unwrap_or(""));
    if let Some(tip) = tip {
        r.text(names::TIP, tip);
    }
    for k in 0..3 {
        r.number(names::POSITION[k], p.position[k]);
    }
    if orientation {
        for k in 0..3 {
            r.number(names::ORIENTATION[k], p.rotation[k]);
        }
    }
}

//! A serial arm answered in its own coordinates. An arm (one VJM chain with no passive joint, its end the
//! reference point: a URDF arm) has no leg stiffness to sum: its compliance is Salisbury's
//! C = J_e K_e^-1 J_e^T over its elastic joints (paper 001 eq 9 with no passive joint), which is singular,
//! honestly, where fewer than six springs leave directions the tip cannot move along (rigid directions,
//! never free ones), and its loaded equilibrium is K_e (theta - theta0) = J_e^T w + tau_g(theta) on the
//! elastic coordinates alone (paper 000 eq 31 with the end free), solved by Newton's method with the exact
//! load Hessian H (`ChainJacobians::add_load_hessian`), whose tangent compliance is J_e (K_e - H)^-1 J_e^T.

use nalgebra::DMatrix;

use super::leg::{Leg, LegFailure, LegState};
use super::loaded::DeflectionFailure;
use super::manipulator::{Manipulator, ManipulatorState, PoseFailure};
use super::vjm_leg::VjmLeg;
use crate::kinematics::chain::Coordinates;
use crate::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use crate::linalg::{all_finite, positive_definite_in_place, DenseLu};
use crate::vjm::stiffness::spring_compliance_at_end;

/// A serial arm's answer at one configuration.
#[derive(Clone, Copy, Debug)]
pub struct ArmAnswer {
    /// Where the reference frame is (at the loaded equilibrium, for a loaded answer).
    pub pose: Frame,
    /// Its displacement from the commanded pose (mm, base-frame rotation vector; zero unloaded).
    pub displacement: Vec6,
    /// The compliance at the reference point, base frame: C = J_e K_e^-1 J_e^T, or the loaded tangent
    /// J_e (K_e - H)^-1 J_e^T (mm/N, mm/(N mm), rad/(N mm)).
    pub compliance: Mat6,
    /// The equilibrium is stable: the energy's Hessian K_e - H on the elastic coordinates (its symmetric
    /// part) is positive definite (always, unloaded).
    pub stable: bool,
    /// Newton iterations (0 unloaded).
    pub iterations: usize,
}

/// Largest Newton iterations of one load step.
const MAX_NEWTON: usize = 50;
/// A step of the elastic coordinates below this (rad, or a length over the arm's length scale), or a step
/// whose contraction from the last leaves less than this after it, ends Newton's method: the tangent is
/// then evaluated where it left the coordinates.
const NEWTON_TOLERANCE: f64 = 1e-13;
/// The smallest share of the load a continuation step may take before the solve gives up.
const SMALLEST_LOAD_STEP: f64 = 1.0 / 4096.0;

impl Manipulator {
    /// The chain of a serial arm answered in its own coordinates (`serial.rs`): one VJM leg with a joint
    /// space, no passive joint and its end at the reference point (a tree with several tips has one such
    /// leg per tip, the reference point's first, all reading one set of coordinates); None for any other
    /// manipulator.
    pub(super) fn serial_arm(&self) -> Option<&VjmLeg> {
        self.joint_space.as_ref()?;
        let arm_chain = |l: &Leg| matches!(l, Leg::Vjm(v) if v.chain.n_passive == 0 && v.attachment == Frame::IDENTITY);
        if self.legs.len() != self.tips().len().max(1) || !self.legs.iter().all(arm_chain) {
            return None;
        }
        match &self.legs[0] {
            Leg::Vjm(leg) => Some(leg),
            Leg::Msa(_) => None,
        }
    }

    /// A serial arm's chains, the reference point's first (one per tip).
    pub(super) fn arm_chains(&self) -> impl Iterator<Item = &VjmLeg> {
        self.legs.iter().filter_map(|l| match l {
            Leg::Vjm(v) => Some(v),
            Leg::Msa(_) => None,
        })
    }

    /// True where this is a serial arm answered in its own coordinates (C = J_e K_e^-1 J_e^T).
    pub fn is_serial_arm(&self) -> bool {
        self.serial_arm().is_some()
    }

    /// A serial arm's unloaded compliance at the commanded pose `platform` (placed by inverse kinematics,
    /// or at the joint coordinates a state was seeded with). None where this is no serial arm.
    pub fn arm_unloaded(
        &self,
        platform: &Frame,
        state: &mut ManipulatorState,
    ) -> Option<Result<ArmAnswer, PoseFailure>> {
        self.serial_arm()?;
        if let Err(e) = self.place(platform, state) {
            return Some(Err(e));
        }
        self.arm_unloaded_as_seeded(Some(platform), state)
    }

    /// A serial arm's unloaded compliance at the configuration `pose_at_joints` seeded `state` with, its
    /// reference point where that configuration puts it: no placement (inverse kinematics would find the
    /// configuration it starts from). None where this is no serial arm.
    pub fn arm_unloaded_at_joints(&self, state: &mut ManipulatorState) -> Option<Result<ArmAnswer, PoseFailure>> {
        self.arm_unloaded_as_seeded(None, state)
    }

    /// The compliance of the arm as its state is placed, moved to `platform`'s origin where one is given
    /// (inverse kinematics left the end within its tolerance of it).
    fn arm_unloaded_as_seeded(
        &self,
        platform: Option<&Frame>,
        state: &mut ManipulatorState,
    ) -> Option<Result<ArmAnswer, PoseFailure>> {
        let leg = self.serial_arm()?;
        let s = &mut state.legs[0];
        if !springs_positive(leg, &s.coords) {
            return Some(Err(PoseFailure { leg: 0, failure: LegFailure::SingularChain }));
        }
        let (jac, coords) = leg.evaluated(s);
        let at_end = spring_compliance_at_end(&jac.virtual_, &leg.springs, coords);
        let (pose, compliance) = match platform {
            Some(p) => (*p, shifted(&at_end, &(p.pos - jac.end.pos))),
            None => (jac.end, at_end),
        };
        if !all_finite(compliance.as_slice()) {
            return Some(Err(PoseFailure { leg: 0, failure: LegFailure::NotFinite }));
        }
        Some(Ok(ArmAnswer { pose, displacement: Vec6::zeros(), compliance, stable: true, iterations: 0 }))
    }

    /// A serial arm's loaded equilibrium under `wrench` (N, N mm at the reference point, fixed in the base
    /// frame) with its links' and payload's weight, the arm placed for `commanded` before: Newton's method on
    /// the elastic coordinates from their rest, the load cut into steps where a direct solve fails. None where
    /// this is no serial arm.
    pub fn arm_deflect(
        &self,
        commanded: &Frame,
        wrench: &Vec6,
        state: &mut ManipulatorState,
    ) -> Option<Result<ArmAnswer, DeflectionFailure>> {
        let leg = self.serial_arm()?;
        let played = self.played(wrench, state);
        let s = &mut state.legs[0];
        if !springs_positive(leg, &s.coords) {
            return Some(Err(DeflectionFailure::Leg(PoseFailure { leg: 0, failure: LegFailure::SingularChain })));
        }
        let mut work = std::mem::take(&mut state.arm);
        work.coords.clone_from(&s.coords);
        work.coords.virtual_.iter_mut().for_each(|t| *t = 0.0);
        if let Some(q) = played {
            work.coords.actuated.copy_from_slice(&q);
        }
        let evaluated = take_placement_evaluations(&mut state.legs, &work.coords);
        let mut solver =
            ArmSolver { m: self, leg, states: &mut state.legs, wrench: *wrench, work: &mut work, evaluated };
        let answer = solver.continuation(commanded);
        state.arm = work;
        Some(answer)
    }

    /// The arm's coordinates as its state is placed, each moved by its joint's play in the sense of the load
    /// the joint carries there under `wrench`, the links' and the payload's weight (`ArmStatics::load`; no
    /// move where that is round-off): where the loaded solve starts and stays. None where no joint has play,
    /// or the statics fail (the solve then fails as it would).
    fn played(&self, wrench: &Vec6, state: &mut ManipulatorState) -> Option<Vec<f64>> {
        let play = &self.joint_space.as_ref()?.play;
        if play.iter().all(|b| *b == 0.0) {
            return None;
        }
        let q = state.legs[0].coords.actuated.clone();
        let statics = self.arm_statics_at(&q, wrench, state)?;
        let sign = |l: f64| if l == 0.0 { 0.0 } else { l.signum() };
        Some(q.iter().zip(play).enumerate().map(|(j, (q, b))| q + b * sign(statics.load(j))).collect())
    }
}

/// Where every chain's placement (`pose_at_joints`, or inverse kinematics' solution) left its evaluation
/// at exactly `rest`, the coordinates a loaded solve starts from, moves those evaluations to the chains'
/// solve buffers, so that the solve's first statics makes none: true where it did (the placements' kept
/// evaluations are then gone, and said so).
fn take_placement_evaluations(states: &mut [LegState], rest: &Coordinates) -> bool {
    if !states.iter().all(|s| s.ik.kept().is_some() && s.coords == *rest) {
        return false;
    }
    for s in states.iter_mut() {
        std::mem::swap(&mut s.jac, &mut s.ik.current);
        s.ik.invalidate();
    }
    true
}

/// Every spring whose stiffness depends on the configuration (a formula of its joint's coordinate) has a
/// positive one there: where it has none the arm has no stiffness at that configuration (`singular_leg`,
/// docs/GUIDE.md).
fn springs_positive(leg: &VjmLeg, coords: &Coordinates) -> bool {
    leg.springs.iter().filter(|g| g.varies()).all(|g| {
        let k = g.at(coords).0;
        (0..g.dim).all(|i| k[(i, i)].is_finite() && k[(i, i)] > 0.0)
    })
}

/// A compliance seen at the end point moved to the point `arm` away (the reference point, where inverse
/// kinematics left the end within its tolerance of it): twists move as v + w x arm, so C' = A C A^T with
/// A = [[I, -[arm]x], [0, I]]. The identity where the two points coincide, as they do at joint coordinates.
fn shifted(c: &Mat6, arm: &Vec3) -> Mat6 {
    if *arm == Vec3::zeros() {
        return *c;
    }
    let mut a = Mat6::identity();
    a.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-arm.cross_matrix()));
    a * c * a.transpose()
}

/// A serial arm's loaded solve's buffers, sized by its first solve and reused at every point after it.
#[derive(Clone, Debug, Default)]
pub struct ArmWork {
    /// The elastic coordinates being solved for.
    coords: Coordinates,
    /// The residual g - K (theta - theta0), then Newton's step solved in its place.
    residual: Vec<f64>,
    /// The Newton matrix K - H (column-major), and its factorisation.
    matrix: DMatrix<f64>,
    factor: DenseLu,
    /// The factorisation is the matrix at the current coordinates' iterate (false: compute it afresh).
    factored: bool,
    /// The coordinates before a load step, restored where it fails.
    saved: Vec<f64>,
    /// The tangent's (K - H)^-1 J^T by rows, and the symmetric part of K - H for the stability test.
    solved: Vec<[f64; 6]>,
    symmetric: Vec<f64>,
}

/// One loaded solve of a serial arm.
struct ArmSolver<'a> {
    m: &'a Manipulator,
    /// The reference point's chain, whose springs are the arm's.
    leg: &'a VjmLeg,
    /// One per chain: their evaluations (`jac`) are the solve's buffers.
    states: &'a mut [LegState],
    wrench: Vec6,
    work: &'a mut ArmWork,
    /// The chains' buffers hold their evaluations at the work's coordinates (`take_placement_evaluations`),
    /// until the first statics has used them.
    evaluated: bool,
}

/// What one statics of a loaded solve computes: the residual of a chord step, the residual and the Newton
/// matrix of a full step, or the matrix alone of the tangent at the equilibrium.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Statics {
    Residual,
    ResidualAndMatrix,
    Matrix,
}

/// A chord step that shrinks the step by less than this has a matrix too far from the state's: the next
/// step computes it afresh.
const CHORD_STALL: f64 = 0.1;

impl ArmSolver<'_> {
    /// The statics at the work's coordinates under the share `load` of every load (the wrench, the links'
    /// and the payload's weight), the chain evaluated there into `jac`: as `what` asks, the residual
    /// g - K (theta - theta0) into `work.residual` and the Newton matrix K - H into `work.matrix` (its load
    /// Hessian costs more than the rest).
    fn statics(&mut self, load: f64, what: Statics) {
        let (with_residual, with_matrix) = (what != Statics::Matrix, what != Statics::Residual);
        let work = &mut *self.work;
        let coords = &work.coords;
        let n = coords.virtual_.len();
        let gravity = self.leg.gravity * load;
        work.residual.clear();
        work.residual.resize(n, 0.0);
        if with_matrix {
            if work.matrix.nrows() != n {
                work.matrix = DMatrix::zeros(n, n);
            } else {
                work.matrix.fill(0.0);
            }
        }
        let residual = &mut work.residual;
        let mut matrix = with_matrix.then_some(&mut work.matrix);
        let evaluated = std::mem::take(&mut self.evaluated);
        // Every chain's weight, the wrench at the reference point's: the chains of a tree share their
        // coordinates, and each body is in one chain, so their generalised forces and Hessians add.
        for (k, chain) in self.m.arm_chains().enumerate() {
            let jac = &mut self.states[k].jac;
            let wrench = if k == 0 { self.wrench * load } else { Vec6::zeros() };
            if evaluated {
                // An evaluation is a placement too (every chain's, the reference one's with its columns).
            } else if k == 0 {
                chain.chain.evaluate(coords, jac);
            } else {
                chain.chain.place_joints(coords, jac);
            }
            if k == 0 {
                jac.fill_virtual();
            }
            if with_residual {
                jac.add_generalised_forces(&wrench, &gravity, 0, residual);
            }
            if let Some(h) = matrix.as_deref_mut() {
                jac.add_load_hessian(&wrench, &gravity, 0, h);
            }
        }
        let jac = &mut self.states[0].jac;
        let payload = self.m.payload.map(|p| {
            let end = jac.end;
            (end.pos + end.rot * p.centre, self.m.weight_gravity() * (p.mass_kg * load))
        });
        if let Some((point, force)) = payload {
            if with_residual {
                jac.add_point_force(&point, &force, 0, residual);
            }
            if let Some(h) = matrix.as_deref_mut() {
                jac.add_point_force_hessian(&point, &force, 0, h);
            }
        }
        if let Some(h) = matrix.as_deref_mut() {
            h.neg_mut();
        }
        for g in &self.leg.springs {
            let varying;
            let k = match g.constant_stiffness() {
                Some(k) => k,
                None => {
                    varying = g.stiffness_at(coords);
                    &varying
                }
            };
            let rest = &self.leg.preload[g.first..g.first + g.dim];
            let theta = &coords.virtual_[g.first..g.first + g.dim];
            for i in 0..g.dim {
                for j in 0..g.dim {
                    if with_residual {
                        residual[g.first + i] -= k[(i, j)] * (theta[j] - rest[j]);
                    }
                    if let Some(m) = matrix.as_deref_mut() {
                        m[(g.first + i, g.first + j)] += k[(i, j)];
                    }
                }
            }
        }
    }

    /// Newton's method for the share `load` from the work's coordinates (left at the solution), chord
    /// steps on the last matrix while they shrink the step tenfold or more: the iterations.
    fn newton(&mut self, load: f64) -> Result<usize, DeflectionFailure> {
        let scale = self.leg.length_scale;
        let singular = DeflectionFailure::SingularStiffness { load_fraction: load };
        self.work.factored = false;
        let mut last_size = f64::INFINITY;
        for iteration in 1..=MAX_NEWTON {
            let fresh = !self.work.factored;
            self.statics(load, if fresh { Statics::ResidualAndMatrix } else { Statics::Residual });
            let work = &mut *self.work;
            if fresh {
                let n = work.matrix.nrows();
                if !work.factor.factor(work.matrix.as_slice(), n) {
                    return Err(singular);
                }
                work.factored = true;
            }
            work.factor.solve_in_place(&mut work.residual);
            let step = &work.residual;
            if !all_finite(step) {
                return Err(singular);
            }
            let lengths = self.leg.chain.length_coordinates();
            let size = step
                .iter()
                .zip(lengths)
                .map(|(d, is_length)| if *is_length { d.abs() / scale } else { d.abs() })
                .fold(0.0, f64::max);
            if size > 1.0 {
                // A step past a radian (or the arm's length) has left the region the linearisation describes.
                return Err(DeflectionFailure::NotConverged { load_fraction: load });
            }
            for (t, d) in work.coords.virtual_.iter_mut().zip(step.iter()) {
                *t += d;
            }
            // Converged where this step was within the tolerance, or where the contraction of the last two
            // steps puts what is left after it there: each step leaves about the next one's size, r times
            // this one for a contraction r (a full step's quadratic convergence leaves less). On a sagging
            // FANUC R-2000iC the second step's 3e-10 rad, a ratio of 4e-7 to the first, leaves 1e-16: the
            // third step measured that, and a statics, the solve's fourth, only to confirm it.
            let left = if last_size.is_finite() { size * (size / last_size) } else { f64::INFINITY };
            if size <= NEWTON_TOLERANCE || left <= NEWTON_TOLERANCE {
                return Ok(iteration);
            }
            if size > CHORD_STALL * last_size {
                work.factored = false;
            }
            last_size = size;
        }
        Err(DeflectionFailure::NotConverged { load_fraction: load })
    }

    /// The equilibrium under the whole load, by load steps where a direct solve fails, and its answer.
    fn continuation(&mut self, commanded: &Frame) -> Result<ArmAnswer, DeflectionFailure> {
        let (mut done, mut step, mut iterations) = (0.0f64, 1.0f64, 0);
        while done < 1.0 {
            let target = (done + step).min(1.0);
            self.work.saved.clone_from(&self.work.coords.virtual_);
            match self.newton(target) {
                Ok(its) => {
                    iterations += its;
                    done = target;
                    step = (step * 2.0).min(1.0);
                }
                Err(e) => {
                    let work = &mut *self.work;
                    work.coords.virtual_.copy_from_slice(&work.saved);
                    step /= 4.0;
                    if step < SMALLEST_LOAD_STEP {
                        return Err(match e {
                            DeflectionFailure::SingularStiffness { .. } => {
                                DeflectionFailure::SingularStiffness { load_fraction: done }
                            }
                            _ => DeflectionFailure::NotConverged { load_fraction: done },
                        });
                    }
                }
            }
        }
        // At the equilibrium (the last step moved it by round-off): the pose, the Jacobian and the matrix of
        // the tangent, C = J (K - H)^-1 J^T with (K - H)^-1 J^T solved for J's six rows at once.
        self.statics(1.0, Statics::Matrix);
        let singular = DeflectionFailure::SingularStiffness { load_fraction: 1.0 };
        let work = &mut *self.work;
        let jac = &self.states[0].jac;
        let pose = jac.end;
        let n = work.matrix.nrows();
        if !work.factor.factor(work.matrix.as_slice(), n) {
            return Err(singular);
        }
        work.solved.clear();
        work.solved.extend(jac.virtual_.iter().map(|c| [c[0], c[1], c[2], c[3], c[4], c[5]]));
        work.factor.solve_rows(&mut work.solved);
        let compliance =
            Mat6::from_fn(|r, k| jac.virtual_.iter().zip(&work.solved).map(|(column, x)| column[r] * x[k]).sum());
        if !all_finite(compliance.as_slice()) || !all_finite(pose.pos.as_slice()) {
            return Err(DeflectionFailure::Leg(PoseFailure { leg: 0, failure: LegFailure::NotFinite }));
        }
        let stable = energy_minimum(&work.matrix, &mut work.symmetric);
        Ok(ArmAnswer { pose, displacement: commanded.error_to(&pose), compliance, stable, iterations })
    }
}

/// The symmetric part of the energy's Hessian `m` is positive definite (Cholesky, after a diagonal
/// equilibration, which changes no eigenvalue's sign), formed in `buffer`.
fn energy_minimum(m: &DMatrix<f64>, buffer: &mut Vec<f64>) -> bool {
    let n = m.nrows();
    if (0..n).any(|i| m[(i, i)].is_nan() || m[(i, i)] <= 0.0) {
        return false;
    }
    // The diagonal's scales first, then the matrix after them: one square root per row, not per entry.
    buffer.clear();
    buffer.extend((0..n).map(|i| 1.0 / m[(i, i)].sqrt()));
    for j in 0..n {
        for i in 0..n {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]) * buffer[i] * buffer[j];
            buffer.push(v);
        }
    }
    positive_definite_in_place(&mut buffer[n..], n)
}

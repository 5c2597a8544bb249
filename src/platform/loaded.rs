//! The manipulator under load: the force-deflection relation F = sum_i f_i(t | t0) (paper 000 eq 66-67),
//! its tangent stiffness, stability, and its inverse, the deflection under a given wrench by Newton's
//! method with load continuation (eq 73-75).

use super::compliance::positive_definite;
use super::leg::{LegLinear, LegState};
use super::manipulator::{Manipulator, ManipulatorState, PoseFailure};
use crate::kinematics::frame::apply_twist;
use crate::kinematics::frame::{weigh_rotations, Frame, Mat6, Vec6};
use crate::linalg::SmallLu;

/// The manipulator held at a platform pose, its legs placed for the commanded pose before.
#[derive(Clone, Copy, Debug)]
pub struct Held {
    /// The external wrench (N, N mm, at the reference point) that holds the platform there: sum_i f_i.
    pub force: Vec6,
    /// Tangent stiffness dF/dt at the reference point.
    pub stiffness: Mat6,
    /// The size of the legs' terms on each diagonal entry (see `Aggregate::magnitude`).
    pub magnitude: Vec6,
    /// Legs whose equilibrium is unstable with their end held, as bits (leg i -> bit min(i, 63)).
    pub unstable_legs: u64,
    /// Most Newton iterations over the legs.
    pub iterations: usize,
}

impl Held {
    /// Every leg's equilibrium is stable with its end held.
    pub fn legs_stable(&self) -> bool {
        self.unstable_legs == 0
    }

    /// The legs (0-based) unstable with their end held.
    pub fn unstable_legs(&self) -> impl Iterator<Item = usize> + '_ {
        (0..64).filter(|i| self.unstable_legs & (1 << i) != 0)
    }
}

fn leg_bit(i: usize) -> u64 {
    1 << i.min(63)
}

/// The deflection under an external wrench.
#[derive(Clone, Copy, Debug)]
pub struct Deflection {
    /// Where the platform settles.
    pub pose: Frame,
    /// Its displacement from the commanded pose (mm, base-frame rotation vector).
    pub displacement: Vec6,
    /// The external wrench and tangent stiffness holding the platform there.
    pub held: Held,
    /// Stable under force control: tangent stiffness positive definite and every leg stable.
    pub stable: bool,
    /// Newton iterations at the manipulator level, over all load steps.
    pub iterations: usize,
    /// The tangent compliance, where it was computed directly (a serial arm, `serial.rs`: singular where
    /// the arm is rigid along some direction, and `held.stiffness` then not finite).
    pub compliance: Option<Mat6>,
}

/// The platform's loaded equilibrium without its tangent (`Manipulator::settle`).
#[derive(Clone, Copy, Debug)]
pub struct Settled {
    /// Where the platform settles.
    pub pose: Frame,
    /// Its displacement from the commanded pose (mm, base-frame rotation vector).
    pub displacement: Vec6,
    /// Newton iterations at the manipulator level (full and chord steps), over all load steps.
    pub iterations: usize,
}

/// The factorisations the last loaded solve ended with, for the next solve's chord steps: the
/// manipulator's tangent stiffness of that full linearisation (the legs keep theirs), the chord
/// iteration's last measured contraction with them (infinite where none was measured since), and how far
/// from its equilibrium that solve started (its first step's distance).
#[derive(Clone, Copy, Debug)]
pub struct Chord {
    stiffness: Mat6,
    contraction: f64,
    start_distance: f64,
}

/// What a loaded solve must deliver besides the pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Finish {
    /// The tangent stiffness at the equilibrium and the legs' stability: the solve ends on a full
    /// linearisation within `TANGENT_TOLERANCE` of the equilibrium.
    Tangent,
    /// The pose alone: chord steps that have converged end the solve, and a full linearisation is made
    /// only where they stop contracting.
    Pose,
    /// The pose and the stability there: chord steps until the next would be within `STABILITY_TOLERANCE`
    /// (none where the last solve started within `FULL_FIRST_RANGE`), then one full linearisation, which
    /// ends the solve once its step is within `STABILITY_TOLERANCE` (the pose's error is then far below it).
    /// Its tangent is that close to the equilibrium's: enough to decide stability, not to report the
    /// stiffness to `TANGENT_TOLERANCE`.
    Stability,
}

impl Finish {
    /// How close to the equilibrium a full step must be to end the solve (relative, as `distance`).
    fn full_step_tolerance(self) -> f64 {
        match self {
            Finish::Stability => STABILITY_TOLERANCE,
            Finish::Tangent | Finish::Pose => NEWTON_TOLERANCE,
        }
    }
}

/// Why the platform's loaded equilibrium was not found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DeflectionFailure {
    /// A leg could not be linearised (its equilibrium matrix is singular).
    Leg(PoseFailure),
    /// The manipulator's tangent stiffness became singular on the way.
    SingularStiffness {
        /// The share of the load reached (0..1).
        load_fraction: f64,
    },
    /// Newton's method found no equilibrium even with load continuation (e.g. past a limit point).
    NotConverged {
        /// The share of the load reached (0..1).
        load_fraction: f64,
    },
}

impl std::fmt::Display for DeflectionFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DeflectionFailure::Leg(e) => write!(f, "{e}"),
            DeflectionFailure::SingularStiffness { load_fraction } => write!(
                f,
                "the tangent stiffness became singular at {:.1}% of the load (a buckling or limit point: try \
                 `stiff curve` to follow the path)",
                100.0 * load_fraction
            ),
            DeflectionFailure::NotConverged { load_fraction } => write!(
                f,
                "no equilibrium found beyond {:.1}% of the load, even with load continuation (past a limit \
                 point?)",
                100.0 * load_fraction
            ),
        }
    }
}

impl std::error::Error for DeflectionFailure {}

/// A serial arm's loaded answer as a `Deflection`: the holding wrench is the one applied, the stiffness the
/// inverse of the tangent compliance (not finite where the arm is rigid along some direction).
fn arm_deflection(a: &super::serial::ArmAnswer, wrench: &Vec6) -> Deflection {
    let stiffness = SmallLu::new(&a.compliance).inverse().unwrap_or(Mat6::from_element(f64::NAN));
    let held = Held {
        force: *wrench,
        stiffness,
        magnitude: Vec6::from_fn(|i, _| stiffness[(i, i)].abs()),
        unstable_legs: if a.stable { 0 } else { 1 },
        iterations: a.iterations,
    };
    Deflection {
        pose: a.pose,
        displacement: a.displacement,
        held,
        stable: a.stable,
        iterations: a.iterations,
        compliance: Some(a.compliance),
    }
}

const MAX_NEWTON: usize = 30;
/// Convergence of the manipulator-level Newton method: the last step below this times the length scale
/// (mm, rotations weighted) and every leg within this of its equilibrium (its corrections in rad, or in mm
/// over its length scale: `LegLinear::distance`).
const NEWTON_TOLERANCE: f64 = 1e-8;
/// The linearisation whose tangent stiffness is reported is this close to the equilibrium (platform step
/// over the length scale, legs' corrections as above): the stiffness's error is first order in it.
const TANGENT_TOLERANCE: f64 = 1e-12;
/// A stability solve (`settle_stable`) ends on a full step within this of the equilibrium (relative, as
/// above). At `NEWTON_TOLERANCE` the pose it left was not as close as the step's square: the 3-PUU's
/// compensation checks along a milling path (Case B errors) reported residual rotations up to 4e-10 of
/// themselves (1e-11 rad) from the same solves made to round-off; at 1e-10, 6e-14 rad, for no more steps
/// (the chord steps before it gain a factor of about 20 each).
const STABILITY_TOLERANCE: f64 = 1e-10;
/// A pose-only solve (`settle`) ends on chord steps this close to the equilibrium (relative, as above): its
/// pose is all it delivers, and no last full step squares its error as `deflect`'s does. A hundredth of
/// `TANGENT_TOLERANCE` puts it within 1e-11 mm of the equilibrium on the 3-PUU (length scale 900 mm), about
/// as close as `deflect`'s pose.
const SETTLE_TOLERANCE: f64 = 1e-14;
/// Chord steps follow a full step whose distance from equilibrium is below this (relative, as above): from
/// there the matrices change by so little that a chord step gains several digits.
const CHORD_RANGE: f64 = 1e-3;
/// Largest platform step in one Newton iteration, in mm (rotations weighted by the length scale).
const MAX_STEP_MM: f64 = 5.0;
/// A chord step that shrinks the distance by less than this (its contraction) has matrices too far from
/// the state's: a full linearisation follows.
const CHORD_STALL: f64 = 0.1;
/// How much a chord contraction measured by the last solve may have grown by the next (`newton`).
const CARRIED_GROWTH: f64 = 2.0;
/// A stability solve whose predecessor started this close to its equilibrium (relative, as `distance`)
/// starts with its full linearisation: its start is then expected within `STABILITY_TOLERANCE` too (a
/// hundredth of it, for a prediction twice as far off), and the chord step before it would only confirm
/// that.
const FULL_FIRST_RANGE: f64 = 1e-2 * STABILITY_TOLERANCE;

impl Manipulator {
    /// The external wrench that holds the platform at `platform`, and the tangent stiffness there.
    pub fn hold(&self, platform: &Frame, state: &mut ManipulatorState) -> Result<Held, PoseFailure> {
        let mut held = Held {
            force: Vec6::zeros(),
            stiffness: Mat6::zeros(),
            magnitude: Vec6::zeros(),
            unstable_legs: 0,
            iterations: 0,
        };
        for (i, (leg, s)) in self.legs.iter().zip(state.legs.iter_mut()).enumerate() {
            let r = leg.respond(platform, s).map_err(|failure| PoseFailure { leg: i, failure })?;
            held.force -= r.wrench;
            held.stiffness += r.stiffness;
            held.magnitude += r.magnitude;
            if !r.stable {
                held.unstable_legs |= leg_bit(i);
            }
            held.iterations = held.iterations.max(r.iterations);
        }
        // The payload's weight is carried too: h = -sum w_i - W, dh/dt = sum K_i - dW/dt.
        let (weight, d_weight) = self.weight(platform);
        held.force -= weight;
        held.stiffness -= d_weight;
        Ok(held)
    }

    /// Newton's method on the whole manipulator for `sum_i f_i(t) = load`: the platform pose and every
    /// leg's configuration and end wrench move together, each step built from the legs' linearised
    /// equilibria (eq 45) and the sum of their stiffnesses, so no leg is solved to convergence at a pose
    /// the platform then leaves (the nested scheme of eq 73-75 costs several times more).
    ///
    /// Once a full step has brought the start within `CHORD_RANGE`, chord steps follow: the legs' residuals
    /// afresh, solved with the factorisations and stiffnesses of that step, contracting by the small
    /// change of the matrices since, for the price of one evaluation per leg. When they have converged, a
    /// last full linearisation confirms the equilibrium and gives the tangent stiffness there; a chord step
    /// that fails to contract gives way to full steps.
    ///
    /// With `Finish::Pose` the solve ends on the chord step after which the distance left, estimated from
    /// the contraction as `distance * contraction`, is within `SETTLE_TOLERANCE` (linear convergence: the
    /// next step would be that small), or on a full step within `NEWTON_TOLERANCE` (quadratic: the error
    /// left is of the order of its square); no `Held` is returned, as no tangent was made there. With
    /// `Finish::Stability` it ends on the first full step within `STABILITY_TOLERANCE`, made once the chord
    /// steps would be within it.
    fn newton(
        &self,
        load: &Vec6,
        weight_share: f64,
        t: &mut Frame,
        state: &mut ManipulatorState,
        finish: Finish,
    ) -> Result<(Option<Held>, usize), DeflectionFailure> {
        let leg_failure = |i: usize| move |failure| DeflectionFailure::Leg(PoseFailure { leg: i, failure });
        let ManipulatorState { legs: states, linear: lins, chord, .. } = state;
        lins.resize_with(self.legs.len(), LegLinear::default);
        // Chord steps first where the last solve's factorisations are at hand (the neighbouring point's, or
        // the last load step's): from a warm start they contract by the small change of the matrices
        // between neighbours, and the one full linearisation the point needs is then the last. A stability
        // solve whose predecessor started within `FULL_FIRST_RANGE` is expected within `STABILITY_TOLERANCE`
        // from its start: the full linearisation there is its only step.
        let (mut stiffness, mut full, mut chord_contraction) = match chord.take() {
            Some(c) => {
                let full_first = finish == Finish::Stability && c.start_distance <= FULL_FIRST_RANGE;
                (c.stiffness, full_first, c.contraction)
            }
            None => (Mat6::zeros(), true, f64::INFINITY),
        };
        let mut start_distance = f64::INFINITY;
        // A contraction measured in this solve (not carried): the next solve may start from it.
        let mut measured = false;
        let mut last_distance = f64::INFINITY;
        // The slowest contraction of the chord steps since the last full one (see `full` below).
        let mut slowest = 0.0f64;
        // The manipulator's stiffness factorised once per linearisation: chord steps reuse it. The carried
        // one is factorised only where a chord step comes first (at the first solve, below).
        let mut stiffness_lu: Option<SmallLu<6>> = None;
        for it in 0..MAX_NEWTON {
            let (weight, d_weight) = self.weight(t);
            if !full {
                for (i, ((leg, s), l)) in self.legs.iter().zip(states.iter_mut()).zip(lins.iter_mut()).enumerate() {
                    full |= !leg.refresh(t, s, l).map_err(leg_failure(i))?;
                }
            }
            if full {
                for (i, ((leg, s), l)) in self.legs.iter().zip(states.iter_mut()).zip(lins.iter_mut()).enumerate() {
                    leg.linearize_into(t, s, l).map_err(leg_failure(i))?;
                }
                stiffness = lins.iter().map(|l| l.stiffness).sum::<Mat6>() - d_weight * weight_share;
                stiffness_lu = Some(SmallLu::new(&stiffness));
            }
            // The payload's weight (a share of it under load continuation) is a load the legs carry.
            let force: Vec6 = lins.iter().map(|l| l.corrected_force).sum::<Vec6>() - weight * weight_share;
            let Some(step) = stiffness_lu.get_or_insert_with(|| SmallLu::new(&stiffness)).solve(&(load - force)) else {
                return Err(DeflectionFailure::SingularStiffness { load_fraction: f64::NAN });
            };
            let step_size = weigh_rotations(&step, self.length_scale).norm() / self.length_scale;
            let distance = lins.iter().map(|l| l.distance).fold(step_size, f64::max);
            if it == 0 {
                start_distance = distance;
            }
            // Quadratic convergence: after this last full step the pose's error is of the order of its
            // square. The stiffness is the one linearised before the step, so its error is of the order of
            // the step itself: it is taken once the step is below `TANGENT_TOLERANCE`, or where the steps no
            // longer shrink (round-off).
            let stalled = distance > CHORD_STALL * last_distance;
            let contraction = if last_distance.is_finite() { distance / last_distance } else { 1.0 };
            slowest = if !full && last_distance.is_finite() { slowest.max(contraction) } else { 0.0 };
            // The chord iteration's contraction with these factorisations: measured on this step, or for a
            // first chord step twice the one the last solve measured with them (the matrices have moved on
            // by one neighbouring point since, and the contraction grows in proportion to how far they
            // are from the factorised ones: at most doubled by one more step of a path). Unknown after a
            // full step.
            (chord_contraction, measured) = match (full, last_distance.is_finite()) {
                (true, _) => (f64::INFINITY, false),
                (false, true) => (contraction, true),
                (false, false) => (CARRIED_GROWTH * chord_contraction, measured),
            };
            // A chord step within `SETTLE_TOLERANCE` leaves less than itself (a contracting iteration), and
            // its contraction, a ratio of two steps at round-off, means nothing there.
            let pose_converged = distance <= NEWTON_TOLERANCE
                && (full
                    || distance <= SETTLE_TOLERANCE
                    || (chord_contraction <= CHORD_STALL && distance * chord_contraction <= SETTLE_TOLERANCE));
            if finish == Finish::Pose && pose_converged {
                for ((leg, l), s) in self.legs.iter().zip(lins.iter_mut()).zip(states.iter_mut()) {
                    leg.advance(l, &step, 1.0, s);
                }
                *t = apply_twist(t, &step);
                // A contraction carried once is not carried again: the next solve measures its own.
                let contraction = if measured { chord_contraction } else { f64::INFINITY };
                *chord = Some(Chord { stiffness, contraction, start_distance });
                return Ok((None, it + 1));
            }
            let tangent_close = finish == Finish::Stability || distance <= TANGENT_TOLERANCE || stalled;
            if full && distance <= finish.full_step_tolerance() && tangent_close {
                let unstable_legs = (self.legs.iter().zip(states.iter_mut()).enumerate())
                    .filter_map(|(i, (leg, s))| (!leg.stable(s)).then_some(i))
                    .fold(0, |bits, i| bits | leg_bit(i));
                for ((leg, l), s) in self.legs.iter().zip(lins.iter_mut()).zip(states.iter_mut()) {
                    leg.advance(l, &step, 1.0, s);
                }
                *t = apply_twist(t, &step);
                let magnitude: Vec6 = lins.iter().map(|l| l.magnitude).sum();
                *chord = Some(Chord { stiffness, contraction: chord_contraction, start_distance });
                let held =
                    Held { force: force + stiffness * step, stiffness, magnitude, unstable_legs, iterations: it + 1 };
                return Ok((Some(held), it + 1));
            }
            // The next step: chord steps while they contract, a full one to confirm their convergence once
            // the distance left after this step is within the tolerance, the step contracting as the slowest
            // of this run of chord steps did: their ratios fluctuate (by 2.5 times along the loaded 3-PUU's
            // rows), and a full linearisation made short of `TANGENT_TOLERANCE` is followed by another.
            // (A first chord step, from the last solve's factorisations, has no contraction to go by yet.)
            full = match (full, finish) {
                (true, _) => distance > CHORD_RANGE,
                (false, Finish::Tangent) => stalled || distance * contraction.max(slowest) <= TANGENT_TOLERANCE,
                (false, Finish::Pose) => stalled,
                // The carried contraction where the first chord step has none of its own (at most 1: an
                // unknown one, infinite or NaN, asks for the step itself within the tolerance).
                (false, Finish::Stability) => {
                    stalled || distance * chord_contraction.min(1.0) <= finish.full_step_tolerance()
                }
            };
            last_distance = distance;
            let step_mm = step_size * self.length_scale;
            let mut fraction = if step_mm > MAX_STEP_MM { MAX_STEP_MM / step_mm } else { 1.0 };
            for (leg, l) in self.legs.iter().zip(lins.iter_mut()) {
                fraction = fraction.min(leg.step_fraction(l, &step));
            }
            for ((leg, l), s) in self.legs.iter().zip(lins.iter()).zip(states.iter_mut()) {
                leg.advance_measured(l, fraction, s);
            }
            *t = apply_twist(t, &(step * fraction));
        }
        Err(DeflectionFailure::NotConverged { load_fraction: f64::NAN })
    }

    /// The platform pose the unloaded compliance predicts under `wrench`, a start for Newton's method
    /// (None where the legs are loaded at placement, or the manipulator is singular).
    fn linear_prediction(&self, commanded: &Frame, wrench: &Vec6, state: &mut ManipulatorState) -> Option<Frame> {
        if !self.legs.iter().all(|l| l.unloaded_at_placement()) {
            return None;
        }
        let k = self.unloaded(commanded, state).ok()?.stiffness;
        let step = SmallLu::new(&k).solve(&(wrench + self.weight(commanded).0))?;
        Some(apply_twist(commanded, &step))
    }

    /// The deflection of the platform under `wrench` (N, N mm at the reference point), the legs placed for
    /// `commanded` before (eq 73-75), with the tangent stiffness and stability there. Starts from `start`
    /// (a neighbouring solution) or the commanded pose, and cuts the load into smaller steps where a
    /// direct Newton solve fails.
    pub fn deflect(
        &self,
        commanded: &Frame,
        wrench: &Vec6,
        start: Option<&Frame>,
        state: &mut ManipulatorState,
    ) -> Result<Deflection, DeflectionFailure> {
        if let Some(arm) = self.arm_deflect(commanded, wrench, state) {
            return arm.map(|a| arm_deflection(&a, wrench));
        }
        let (t, held, iterations) = self.continuation(commanded, wrench, start, state, Finish::Tangent)?;
        let held = held.expect("a tangent solve ends on a full linearisation");
        let stable = self.stable(&held);
        Ok(Deflection { pose: t, displacement: commanded.error_to(&t), held, stable, iterations, compliance: None })
    }

    /// Stable under force control: the tangent stiffness positive definite and every leg stable.
    fn stable(&self, held: &Held) -> bool {
        held.legs_stable() && positive_definite(&held.stiffness, &held.magnitude, self.length_scale)
    }

    /// Where the platform settles under `wrench`, as `settle` finds it, and whether it is stable there
    /// (as `deflect` decides it): the solve ends on one full linearisation within `STABILITY_TOLERANCE` of
    /// the equilibrium rather than `TANGENT_TOLERANCE`, which decides stability but is not reported as a
    /// stiffness (a forward solve that checks a command, for the price of `settle` and one linearisation).
    pub fn settle_stable(
        &self,
        commanded: &Frame,
        wrench: &Vec6,
        start: Option<&Frame>,
        state: &mut ManipulatorState,
    ) -> Result<(Settled, bool), DeflectionFailure> {
        if let Some(arm) = self.arm_deflect(commanded, wrench, state) {
            return arm
                .map(|a| (Settled { pose: a.pose, displacement: a.displacement, iterations: a.iterations }, a.stable));
        }
        let (t, held, iterations) = self.continuation(commanded, wrench, start, state, Finish::Stability)?;
        let held = held.expect("a stability solve ends on a full linearisation");
        Ok((Settled { pose: t, displacement: commanded.error_to(&t), iterations }, self.stable(&held)))
    }

    /// Where the platform settles under `wrench`, as `deflect` finds it but without the tangent stiffness
    /// and the stability test: the equilibrium's pose as close, for the price of chord steps
    /// where `deflect` must end on a full linearisation (a controller's model of the robot along a path,
    /// which needs only where the tool goes).
    pub fn settle(
        &self,
        commanded: &Frame,
        wrench: &Vec6,
        start: Option<&Frame>,
        state: &mut ManipulatorState,
    ) -> Result<Settled, DeflectionFailure> {
        if let Some(arm) = self.arm_deflect(commanded, wrench, state) {
            return arm.map(|a| Settled { pose: a.pose, displacement: a.displacement, iterations: a.iterations });
        }
        let (t, _, iterations) = self.continuation(commanded, wrench, start, state, Finish::Pose)?;
        Ok(Settled { pose: t, displacement: commanded.error_to(&t), iterations })
    }

    /// Newton's method with load continuation: the platform's pose, the last load step's `Held` (with a
    /// tangent finish) and the iterations over all load steps.
    fn continuation(
        &self,
        commanded: &Frame,
        wrench: &Vec6,
        start: Option<&Frame>,
        state: &mut ManipulatorState,
        finish: Finish,
    ) -> Result<(Frame, Option<Held>, usize), DeflectionFailure> {
        let mut t = match start {
            Some(s) => *s,
            None => self.linear_prediction(commanded, wrench, state).unwrap_or(*commanded),
        };
        let (mut done, mut step) = (0.0f64, 1.0f64);
        let mut total_iterations = 0;
        let mut last: Option<Held> = None;
        while done < 1.0 {
            let target = (done + step).min(1.0);
            let saved_t = t;
            state.legs.iter_mut().for_each(LegState::checkpoint);
            match self.newton(&(wrench * target), target, &mut t, state, finish) {
                Ok((held, its)) => {
                    total_iterations += its;
                    last = held;
                    done = target;
                    step = (step * 2.0).min(1.0);
                }
                Err(e) => {
                    t = saved_t;
                    state.legs.iter_mut().for_each(LegState::rollback);
                    step /= 4.0;
                    if step < 1.0 / 4096.0 {
                        return Err(match e {
                            DeflectionFailure::Leg(_) => e,
                            DeflectionFailure::SingularStiffness { .. } => {
                                DeflectionFailure::SingularStiffness { load_fraction: done }
                            }
                            DeflectionFailure::NotConverged { .. } => {
                                DeflectionFailure::NotConverged { load_fraction: done }
                            }
                        });
                    }
                }
            }
        }
        Ok((t, last, total_iterations))
    }
}

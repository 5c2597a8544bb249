//! A parallel manipulator: legs summed at the platform reference point (paper 001 s. 3.3, paper 000 eq 54).

use super::leg::{Leg, LegFailure, LegLinear, LegResponse, LegState};
use super::loaded::Chord;
use crate::kinematics::frame::{Frame, Mat3, Mat6, Vec3, Vec6};
use crate::kinematics::ik::Needs;

/// A parallel manipulator: its legs, summed at the platform's reference point.
#[derive(Clone, Debug)]
pub struct Manipulator {
    /// Its name.
    pub name: String,
    /// Its legs.
    pub legs: Vec<Leg>,
    /// mm per rad: weighs rotations against translations in rank decisions.
    pub length_scale: f64,
    /// The model's gravity (m/s^2), when it gives one.
    pub gravity: Option<crate::kinematics::frame::Vec3>,
    /// A mass carried by the platform (`[[payload]]`), weighed under `weight_gravity`.
    pub payload: Option<Payload>,
    /// A serial arm's joint coordinates by name (a manipulator of one chain read from URDF), so that poses
    /// can be given as the joint angles its controller reports.
    pub joint_space: Option<JointSpace>,
}

/// The joint coordinates of a serial arm (one chain) by name, and how its controller's angles map to them.
#[derive(Clone, Debug)]
pub struct JointSpace {
    /// The actuated joints' names, in the order of the chain's actuated coordinates.
    pub names: Vec<String>,
    /// Per coordinate: its formula of the controller's angles (slot i is the angle of `names[i]`, as the
    /// controller gives it), or None for the angle itself (a coupling such as a parallelogram's
    /// q3 = -(theta2 + theta3)).
    pub controller: Vec<Option<crate::expr::Expr>>,
    /// Per joint, added to the controller's angle before the map (an encoder's zero offset found by
    /// calibration, `[[joint_correction]]`).
    pub offsets: Vec<f64>,
    /// Per joint, its play (rad or mm, zero or above; `[[joint_correction]] play`): under load the joint's
    /// model coordinate sits this far off in the sense of the load it carries (`ArmStatics::load`), in
    /// every loaded solve (`Manipulator::arm_deflect`).
    pub play: Vec<f64>,
    /// Per joint, its range (lower, upper; rad or mm) where the description gives one (URDF's `<limit>`).
    pub limits: Vec<Option<(f64, f64)>>,
    /// The mass the arm carries, as the description shares it.
    pub carried: CarriedMass,
    /// The reference points' links, one per leg in the legs' order (a tree with several tips has a chain
    /// per tip, all reading these coordinates: `legs[0]`'s end is the reference point, `Manipulator::at_tip`).
    pub tips: Vec<String>,
}

/// How a serial arm's mass is shared (kg): what its moving links carry, the part of it on bodies off the
/// root-to-tip path (branches, a tool beyond the tip), and what weighs on the base instead.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CarriedMass {
    /// Carried by the moving links, kg.
    pub kg: f64,
    /// Of `kg`, on bodies off the path, kg.
    pub off_path_kg: f64,
    /// On the base, not carried by any joint, kg.
    pub on_base_kg: f64,
}

impl Manipulator {
    /// Whether some leg has a spring: a rigid manipulator stays where its joints put it under any load.
    pub fn is_compliant(&self) -> bool {
        self.legs.iter().any(|l| l.spring_groups().next().is_some())
    }

    /// Its loaded pose differs from its rigid one: it has springs, or (a serial arm) a joint with play.
    pub fn deflects(&self) -> bool {
        self.is_compliant() || self.joint_space.as_ref().is_some_and(|s| s.play.iter().any(|b| *b > 0.0))
    }

    /// The tips of a serial arm read from URDF, the reference point's first (one for a chain; empty for
    /// any other manipulator).
    pub fn tips(&self) -> &[String] {
        self.joint_space.as_ref().map_or(&[], |s| s.tips.as_slice())
    }

    /// The same tree with its reference point at tip `tip` (a name of `tips`): its legs turned so that the
    /// tip's chain comes first, the others after in their order. None where no tip has that name.
    pub fn at_tip(&self, tip: &str) -> Option<Manipulator> {
        let k = self.tips().iter().position(|t| t == tip)?;
        let mut m = self.clone();
        m.legs.rotate_left(k);
        if let Some(space) = m.joint_space.as_mut() {
            space.tips.rotate_left(k);
        }
        Some(m)
    }
}

impl JointSpace {
    /// Where the controller's angles `controller` put a joint outside the range its description gives
    /// (URDF's `<limit>`, on the model's coordinate): what a user reads, naming the joint, the value and the
    /// range; None where every joint is within its range (or has none).
    pub fn outside_limits(&self, controller: &[f64]) -> Option<String> {
        if controller.len() != self.names.len() {
            return None;
        }
        let q = self.model_coordinates(controller);
        self.limits.iter().zip(&q).zip(&self.names).find_map(|((range, v), name)| {
            let (lower, upper) = (*range)?;
            (!(lower..=upper).contains(v)).then(|| {
                // Far outside (past the range's own width): more likely a unit than a pose past a stop.
                let far = *v < lower - (upper - lower) || *v > upper + (upper - lower);
                let hint = if far { " (degrees given as radians, or metres where millimetres are meant?)" } else { "" };
                format!(
                    "joint `{name}` is at {v} (the model's coordinate), outside its URDF limits [{lower}, {upper}] (rad, or mm \
                     for a prismatic joint){hint}; the values are used as given; said for the first such row only"
                )
            })
        })
    }

    /// How the model's coordinates change per unit of the controller's angle `j` at `controller` (central
    /// differences of the map: exact for the linear couplings of parallelograms and reversed joints).
    pub fn coordinate_rates(&self, controller: &[f64], j: usize) -> Vec<f64> {
        const STEP: f64 = 1e-6;
        let mut shifted = controller.to_vec();
        shifted[j] += STEP;
        let up = self.model_coordinates(&shifted);
        shifted[j] -= 2.0 * STEP;
        let down = self.model_coordinates(&shifted);
        up.iter().zip(&down).map(|(u, d)| (u - d) / (2.0 * STEP)).collect()
    }

    /// The controller's angles that give the model's coordinates `model` (the inverse of
    /// `model_coordinates`, offsets included): Newton's method on the map, one step for the linear couplings
    /// of parallelograms and reversed joints. None where it does not converge (a map that is not invertible
    /// there).
    pub fn controller_angles(&self, model: &[f64]) -> Option<Vec<f64>> {
        let n = model.len();
        let scale = model.iter().fold(1.0f64, |a, q| a.max(q.abs()));
        let mut t = model.to_vec();
        for _ in 0..CONTROLLER_ITERATIONS {
            let q = self.model_coordinates(&t);
            let r = nalgebra::DVector::from_iterator(n, model.iter().zip(&q).map(|(m, q)| m - q));
            if !r.iter().all(|v| v.is_finite()) {
                return None;
            }
            if r.amax() <= CONTROLLER_TOLERANCE * scale {
                return Some(t);
            }
            let mut jacobian = nalgebra::DMatrix::zeros(n, n);
            for j in 0..n {
                for (i, rate) in self.coordinate_rates(&t, j).into_iter().enumerate() {
                    jacobian[(i, j)] = rate;
                }
            }
            let step = jacobian.lu().solve(&r)?;
            for (a, d) in t.iter_mut().zip(step.iter()) {
                *a += d;
            }
        }
        None
    }

    /// The model's coordinates from the controller's angles (in the order of `names`).
    pub fn model_coordinates(&self, controller: &[f64]) -> Vec<f64> {
        let mut q = vec![0.0; controller.len()];
        self.model_coordinates_into(controller, &mut q);
        q
    }

    /// As `model_coordinates`, into `q` (as long as `controller`), allocation-free for up to
    /// `STACK_JOINTS` joints: a map in joint space calls it at every point.
    pub fn model_coordinates_into(&self, controller: &[f64], q: &mut [f64]) {
        with_scratch(controller.len(), |corrected| {
            for ((c, a), o) in corrected.iter_mut().zip(controller).zip(&self.offsets) {
                *c = a + o;
            }
            for (i, (out, f)) in q.iter_mut().zip(&self.controller).enumerate() {
                *out = f.as_ref().map_or(corrected[i], |f| f.eval(corrected));
            }
        })
    }
}

/// Newton steps `JointSpace::controller_angles` takes at most, and its tolerance relative to the largest
/// coordinate: a few ulps.
const CONTROLLER_ITERATIONS: usize = 20;
const CONTROLLER_TOLERANCE: f64 = 1e-14;

/// Joints a scratch buffer holds on the stack (`with_scratch`).
const STACK_JOINTS: usize = 16;

/// Runs `f` on a zeroed buffer of `n` numbers: on the stack up to `STACK_JOINTS`, else on the heap.
fn with_scratch<T>(n: usize, f: impl FnOnce(&mut [f64]) -> T) -> T {
    let mut stack = [0.0; STACK_JOINTS];
    match n <= STACK_JOINTS {
        true => f(&mut stack[..n]),
        false => f(&mut vec![0.0; n]),
    }
}

/// A serial arm's rigid statics at one configuration (`Manipulator::arm_statics`).
#[derive(Clone, Debug)]
pub struct ArmStatics {
    /// The platform frame (the reference point's).
    pub frame: Frame,
    /// Per joint (in joint-space order), the twist of the reference point per unit of the joint's model
    /// coordinate (rad or mm), base frame.
    pub columns: Vec<Vec6>,
    /// Per joint, the load it carries (N mm about a revolute joint, N along a prismatic one) from the
    /// wrench, the links' weight and the payload: a spring there turns by its compliance times this.
    pub loads: Vec<f64>,
    /// Per joint, its frame before its motion (base frame): a change of the fixed transform leading to the
    /// joint moves everything after it as a rigid motion about this frame.
    pub joint_frames: Vec<Frame>,
    /// Per joint, the wrench everything beyond it puts through its frame (the links' weight, the payload and
    /// the wrench; force, then moment about the frame's origin; base frame): what bends the link there.
    pub transmitted: Vec<Vec6>,
}

/// A joint load below this fraction of the configuration's largest is round-off (`ArmStatics::load`).
const LOAD_ROUND_OFF: f64 = 1e-9;

impl ArmStatics {
    /// The load joint `j` carries, zero where it is round-off (below `LOAD_ROUND_OFF` of the largest joint
    /// load: a vertical first axis carries no weight, and the sign of its round-off is no play).
    pub fn load(&self, j: usize) -> f64 {
        let largest = self.loads.iter().fold(0.0f64, |a, l| a.max(l.abs()));
        let load = self.loads[j];
        if load.abs() <= LOAD_ROUND_OFF * largest {
            0.0
        } else {
            load
        }
    }
}

/// A wrench `w` (force, moment) acting at a point `arm` from another point, as the wrench at that other point:
/// the same force, the moment plus arm x force.
pub fn moved_wrench(w: &Vec6, arm: &Vec3) -> Vec6 {
    let f = w.fixed_rows::<3>(0).into_owned();
    let m = w.fixed_rows::<3>(3) + arm.cross(&f);
    Vec6::new(f.x, f.y, f.z, m.x, m.y, m.z)
}

/// Standard gravity (m/s^2) along -z: what a payload weighs under when the model gives no gravity.
pub const STANDARD_GRAVITY: Vec3 = Vec3::new(0.0, 0.0, -9.81);

/// A mass carried by the platform: its weight is a load on the platform at every pose, so the loaded
/// studies (map --loaded, curve, assemble) and diagnose's loaded nominal all see it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Payload {
    /// Its mass, kg.
    pub mass_kg: f64,
    /// Its centre of mass in the platform frame, mm.
    pub centre: Vec3,
}

impl Payload {
    /// Two masses as one: total mass at their common centre of mass.
    pub fn combined(self, other: Payload) -> Payload {
        let mass_kg = self.mass_kg + other.mass_kg;
        let centre = if mass_kg != 0.0 {
            (self.centre * self.mass_kg + other.centre * other.mass_kg) / mass_kg
        } else {
            (self.centre + other.centre) / 2.0
        };
        Payload { mass_kg, centre }
    }
}

/// Warm starts of every leg, carried from one point to the next by one worker.
#[derive(Clone, Debug)]
pub struct ManipulatorState {
    /// One per leg.
    pub legs: Vec<LegState>,
    /// The legs' linearised equilibria of the loaded Newton method, one per leg (sized by the method
    /// itself), their buffers reused from one iteration and one point to the next.
    pub(super) linear: Vec<LegLinear>,
    /// What the last loaded solve's full linearisation left, while the legs' linearisations and
    /// factorisations are still those: the next point starts with chord steps on them.
    pub(super) chord: Option<Chord>,
    /// What the loaded solve at the first point of the last line left (`keep_line_start`): the legs'
    /// linearisations, whose factorisations each leg's workspace sets aside, and its chord.
    line_start: Option<(Vec<LegLinear>, Chord)>,
    /// A serial arm's loaded solve's buffers (`serial.rs`), reused from one point to the next.
    pub(super) arm: super::serial::ArmWork,
}

impl ManipulatorState {
    /// Keeps what the last loaded solve ended with, made at the first point of a line, for the first
    /// point of the next line (`resume_line_start`). Nothing is kept where the solve left no chord.
    pub fn keep_line_start(&mut self) {
        let Some(chord) = self.chord else { return };
        let kept = self.linear.iter().zip(self.legs.iter_mut()).all(|(l, s)| l.keep(s));
        self.line_start = kept.then(|| (self.linear.clone(), chord));
    }

    /// The next loaded solve begins a line beside the last line's first point: it starts with chord steps
    /// on the factorisations made there (`keep_line_start`), a neighbour's, rather than on the last solve's,
    /// made at the far end of the last line, where chord steps would not contract and two would be spent
    /// finding that out. A full linearisation comes first where none was kept.
    pub fn resume_line_start(&mut self) {
        self.chord = None;
        let Some((linear, chord)) = self.line_start.take() else { return };
        self.linear = linear;
        if self.linear.iter_mut().zip(self.legs.iter_mut()).all(|(l, s)| l.resume(s)) {
            self.chord = Some(chord);
        }
    }
}

/// The sum over legs at one pose.
#[derive(Clone, Copy, Debug)]
pub struct Aggregate {
    /// Sum of the legs' wrenches at the reference point.
    pub wrench: Vec6,
    /// Sum of their stiffnesses.
    pub stiffness: Mat6,
    /// The size of the legs' terms on each diagonal entry (the sum of their `LegResponse::magnitude`), so
    /// that a diagonal entry that cancelled to round-off can be told from a genuinely small one
    /// (`compliance::analyse`).
    pub magnitude: Vec6,
}

/// Which leg failed, and how.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseFailure {
    /// The leg, 0-based.
    pub leg: usize,
    /// How it failed.
    pub failure: LegFailure,
}

impl std::fmt::Display for PoseFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "leg {}: {}", self.leg + 1, self.failure)
    }
}

impl std::error::Error for PoseFailure {}

/// The springs a compliance scaling acts on.
#[derive(Clone, Copy, Debug)]
pub enum SpringSet<'a> {
    /// The actuator springs of one leg (0-based).
    ActuatorOf(usize),
    /// Every spring group of this name, in every leg.
    Group(&'a str),
}

impl Manipulator {
    /// Multiplies the compliance of a set of springs by `factor` (a model correction such as a softer
    /// actuator). Posture-dependent springs carry the factor into their derivation, so it acts at every pose.
    pub fn scale_compliance(&mut self, set: &SpringSet, factor: f64) {
        for (k, leg) in self.legs.iter_mut().enumerate() {
            match set {
                SpringSet::ActuatorOf(target) if *target == k => leg.scale_springs(|_, actuator| actuator, factor),
                SpringSet::Group(name) => leg.scale_springs(|group, _| group == *name, factor),
                SpringSet::ActuatorOf(_) => {}
            }
        }
    }

    /// Multiplies the axial compliance (L/EA) of the beam springs named `group` by `axial` and their
    /// bending and torsion compliance by `bending`, in every leg (a link diameter changed by (1 + e) gives
    /// (1 + e)^-2 and (1 + e)^-4).
    pub fn scale_beam_parts(&mut self, group: &str, axial: f64, bending: f64) {
        for leg in &mut self.legs {
            leg.scale_beam_parts(|name, _| name == group, axial, bending);
        }
    }

    /// Whether some leg has a spring group of this name.
    pub fn has_spring_group(&self, name: &str) -> bool {
        self.legs.iter().any(|l| l.spring_groups().any(|(group, _)| group == name))
    }

    /// The names of the link (not actuator) spring groups, each once, in order of first appearance.
    pub fn link_spring_groups(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for (name, actuator) in self.legs.iter().flat_map(Leg::spring_groups) {
            if !actuator && !out.iter().any(|n| n == name) {
                out.push(name.to_string());
            }
        }
        out
    }

    /// Adds a mass carried by the platform (combined with any payload it has).
    pub fn add_payload(&mut self, p: Payload) {
        self.payload = Some(self.payload.map_or(p, |q| q.combined(p)));
    }

    /// True when the model carries a load with no external wrench (a payload, a preload, weighed chain
    /// masses): its platform then settles away from the commanded pose at rest.
    pub fn loaded_at_rest(&self) -> bool {
        self.payload.is_some() || !self.legs.iter().all(Leg::unloaded_at_placement)
    }

    /// The same manipulator under gravity along `direction` (base frame; its magnitude is the model's, or
    /// standard gravity's): a base that is not level, as an accelerometer on it reads the tilt.
    pub fn with_gravity_direction(&self, direction: &Vec3) -> Manipulator {
        let g = direction.normalize() * self.weight_gravity().norm();
        let mut tilted = self.clone();
        tilted.gravity = Some(g);
        for leg in &mut tilted.legs {
            if let Leg::Vjm(v) = leg {
                v.gravity = g;
            }
        }
        tilted
    }

    /// The gravity a payload weighs under: the model's, or standard gravity along -z.
    pub fn weight_gravity(&self) -> Vec3 {
        self.gravity.unwrap_or(STANDARD_GRAVITY)
    }

    /// True where the robot carries weight in loaded studies: its links' (gravity set) or a payload's.
    pub fn carries_weight(&self) -> bool {
        self.gravity.is_some() || self.payload.is_some()
    }

    /// The payload's weight as a wrench at the reference point with the platform at `platform` (N, N mm;
    /// the mass in kg times m/s^2 is N, its lever arm in mm), and its derivative with respect to the
    /// platform's displacement (dp, dphi): the force is fixed in the base frame and its arm r = R c turns
    /// with the platform, so d(r x f)/dphi = -((f . r) I - r f^T). Zero without a payload.
    pub fn weight(&self, platform: &Frame) -> (Vec6, Mat6) {
        let Some(p) = self.payload else { return (Vec6::zeros(), Mat6::zeros()) };
        let f = self.weight_gravity() * p.mass_kg;
        let r = platform.rot * p.centre;
        let m = r.cross(&f);
        let mut d = Mat6::zeros();
        let block: Mat3 = -(Mat3::identity() * f.dot(&r) - r * f.transpose());
        d.fixed_view_mut::<3, 3>(3, 3).copy_from(&block);
        (Vec6::new(f.x, f.y, f.z, m.x, m.y, m.z), d)
    }

    /// A fresh state (no warm starts).
    pub fn new_state(&self) -> ManipulatorState {
        ManipulatorState {
            legs: self.legs.iter().map(Leg::new_state).collect(),
            linear: Vec::new(),
            arm: Default::default(),
            chord: None,
            line_start: None,
        }
    }

    /// The platform frame of a serial arm at the controller's joint angles `controller` (in the order of
    /// `joint_space`'s names), by forward kinematics, with the state seeded there so that a study placing
    /// the arm at that frame keeps the configuration given. None where the manipulator has no joint space
    /// or the angles give no finite frame.
    pub fn pose_at_joints(&self, controller: &[f64], state: &mut ManipulatorState) -> Option<Frame> {
        let space = self.joint_space.as_ref()?;
        if controller.len() != space.names.len() || self.serial_arm().is_none() {
            return None;
        }
        with_scratch(controller.len(), |q| {
            space.model_coordinates_into(controller, q);
            // Every chain of a tree seeded at the coordinates; the reference point's (the first) gives the
            // frame. No allocation: a map in joint space calls this at every point.
            self.arm_chains()
                .zip(state.legs.iter_mut())
                .try_fold(None, |first: Option<Frame>, (leg, s)| Some(first.or(Some(leg.pose_at_joints(q, s)?))))
                .flatten()
        })
    }

    /// A serial arm's rigid statics at the controller's angles (as `pose_at_joints`) under `wrench` (N, N mm
    /// at the reference point) with the links' weight and the payload's: where the reference point is, how
    /// each joint moves it, and what each joint carries. None as `pose_at_joints`.
    pub fn arm_statics(&self, controller: &[f64], wrench: &Vec6, state: &mut ManipulatorState) -> Option<ArmStatics> {
        let space = self.joint_space.as_ref()?;
        if controller.len() != space.names.len() || self.serial_arm().is_none() {
            return None;
        }
        self.arm_statics_at(&space.model_coordinates(controller), wrench, state)
    }

    /// As `arm_statics`, at the model's coordinates `q` (one per joint, as the chain reads them).
    pub(super) fn arm_statics_at(&self, q: &[f64], wrench: &Vec6, state: &mut ManipulatorState) -> Option<ArmStatics> {
        let mut chains = self.arm_chains().zip(state.legs.iter_mut());
        let (leg, s) = chains.next()?;
        let ArmStatics { frame: end, columns, mut loads, mut joint_frames, mut transmitted } = leg.statics(q, s)?;
        // The other chains of a tree (their columns at their own tips are not the reference point's): their
        // weight on the joints they share, each joint's frame where the reference chain does not reach it.
        for (other, s) in chains {
            let o = other.statics(q, s)?;
            loads.iter_mut().zip(&o.loads).for_each(|(a, b)| *a += b);
            transmitted.iter_mut().zip(&o.transmitted).for_each(|(a, b)| *a += b);
            for ((frame, seen), theirs) in joint_frames.iter_mut().zip(&columns).zip(&o.joint_frames) {
                if *seen == Vec6::zeros() {
                    *frame = *theirs;
                }
            }
        }
        let platform = end.compose(&leg.attachment.inverse());
        // The columns moved from the end point to the reference point: v_ref = v_end + w x (ref - end).
        let arm = end.pos - platform.pos;
        let columns: Vec<Vec6> = columns
            .iter()
            .map(|c| {
                let (v, w) = (c.fixed_rows::<3>(0).into_owned(), c.fixed_rows::<3>(3).into_owned());
                let v = v - w.cross(&arm);
                Vec6::new(v.x, v.y, v.z, w.x, w.y, w.z)
            })
            .collect();
        // A wrench at the reference point loads each joint by its twist there (virtual work).
        let total = *wrench + self.weight(&platform).0;
        for (load, column) in loads.iter_mut().zip(&columns) {
            *load += column.dot(&total);
        }
        for (through, joint) in transmitted.iter_mut().zip(&joint_frames) {
            *through += moved_wrench(&total, &(platform.pos - joint.pos));
        }
        Some(ArmStatics { frame: platform, columns, loads, joint_frames, transmitted })
    }

    /// The compliance of a serial arm's joint `name` about (or along) its axis, rad/(N mm) or mm/N, where the
    /// description gives it a spring; None where the joint is rigid or not a joint of the arm.
    pub fn joint_compliance(&self, name: &str) -> Option<f64> {
        let Some(Leg::Vjm(leg)) = self.legs.first() else { return None };
        leg.springs.iter().find(|g| g.name == name && g.dim == 1).map(|g| g.compliance[(0, 0)])
    }

    /// Places every leg for the commanded pose (inverse kinematics).
    pub fn place(&self, platform: &Frame, state: &mut ManipulatorState) -> Result<(), PoseFailure> {
        self.place_for(platform, state, Needs::Jacobians, None)
    }

    /// As `place`, for a loaded equilibrium, which reads the placement's coordinates and evaluates the legs'
    /// chains itself: their evaluation there is left to be made where it is asked for.
    pub fn place_for_load(&self, platform: &Frame, state: &mut ManipulatorState) -> Result<(), PoseFailure> {
        self.place_for(platform, state, Needs::Pose, None)
    }

    /// As `place_for_load`, each leg's start extrapolated from its placements before as a function of
    /// `along` in place of the pose: a path's target, of which the commands that compensate it are a smooth
    /// function where, unlike the targets, they lie unequally spaced (and, on a robot that turns its
    /// platform, not at one orientation), so that extrapolated by their own poses they would start from the
    /// last placement alone, a path's step away. A state placed this way is placed so throughout.
    pub fn place_along(
        &self,
        platform: &Frame,
        along: &Frame,
        state: &mut ManipulatorState,
    ) -> Result<(), PoseFailure> {
        self.place_for(platform, state, Needs::Pose, Some(along))
    }

    /// Places every leg; `along` keys the legs' placement trails where given (`place_along`), else each
    /// leg's own target does.
    fn place_for(
        &self,
        platform: &Frame,
        state: &mut ManipulatorState,
        needs: Needs,
        along: Option<&Frame>,
    ) -> Result<(), PoseFailure> {
        if self.legs.len() > 1 && self.serial_arm().is_some() {
            // A tree's chains read one set of coordinates: the reference point's chain is placed, and the
            // others take its coordinates.
            self.legs[0]
                .place_along(platform, along, &mut state.legs[0], needs)
                .map_err(|failure| PoseFailure { leg: 0, failure })?;
            let (first, rest) = state.legs.split_at_mut(1);
            for s in rest {
                s.coords.clone_from(&first[0].coords);
            }
            return Ok(());
        }
        for (i, (leg, s)) in self.legs.iter().zip(state.legs.iter_mut()).enumerate() {
            leg.place_along(platform, along, s, needs).map_err(|failure| PoseFailure { leg: i, failure })?;
        }
        Ok(())
    }

    /// Unloaded stiffness at a commanded pose: K = sum_i K_i at the reference point.
    pub fn unloaded(&self, platform: &Frame, state: &mut ManipulatorState) -> Result<Aggregate, PoseFailure> {
        self.unloaded_each(platform, state, |_, _| {})
    }

    /// As `unloaded`, also handing each leg's own answer to `each(leg_index, response)`.
    pub fn unloaded_each(
        &self,
        platform: &Frame,
        state: &mut ManipulatorState,
        mut each: impl FnMut(usize, &LegResponse),
    ) -> Result<Aggregate, PoseFailure> {
        self.place(platform, state)?;
        let mut total = Aggregate { wrench: Vec6::zeros(), stiffness: Mat6::zeros(), magnitude: Vec6::zeros() };
        for (i, (leg, s)) in self.legs.iter().zip(state.legs.iter_mut()).enumerate() {
            let r = leg.respond_unloaded(platform, s).map_err(|failure| PoseFailure { leg: i, failure })?;
            total.wrench += r.wrench;
            total.stiffness += r.stiffness;
            total.magnitude += r.magnitude;
            each(i, &r);
        }
        Ok(total)
    }
}

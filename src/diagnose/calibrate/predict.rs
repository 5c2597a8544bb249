//! A row's prediction and its derivative in every parameter (`PositionProblem::predict`): the model's own
//! deflection, each effect's motion of what the row sees (`unit_moves`), the registration; a serial arm's
//! offsets move its configuration exactly, the other effects act at first order about its loaded
//! equilibrium.

use std::borrow::Cow;

use nalgebra::DMatrix;

use super::effect::{effect_gain, ArmEffect, ArmKind, Seen};
use super::fit::Params;
use super::problem::PositionProblem;
use crate::diagnose::positions::Observed;
use crate::kinematics::frame::{rotation_from_vector, skew, Mat3, Vec3, Vec6};
use crate::platform::manipulator::{ArmStatics, ManipulatorState};

/// A row's prediction before the registration: the controller angles with the offsets, the arm's statics
/// there (and at zero wrench for a displacement), what the row sees, the tool's axes and the body's point
/// (target, or the tool point of a displacement), or the tool's turn for an orientation (base axes).
pub(super) struct Body<'p> {
    pub(super) joints: Vec<f64>,
    pub(super) statics: Cow<'p, (ArmStatics, Option<ArmStatics>)>,
    pub(super) seen: Seen,
    pub(super) loaded_rot: Mat3,
    pub(super) y: Vec3,
}

impl PositionProblem<'_> {
    /// Row `r`'s prediction before the registration (`Body`), with the miss kept for `effects` or without it
    /// (`kept`: `exact_misses` compares the first order with the exact equilibrium).
    pub(super) fn body(
        &self,
        r: usize,
        effects: &[ArmEffect],
        params: &Params,
        state: &mut ManipulatorState,
        kept: bool,
    ) -> Option<Body<'_>> {
        let row = &self.data.rows[r];
        // A serial arm's offsets move its configuration (exactly); a parallel robot's act through their
        // first-order moves (`unit_moves`).
        let mut joints = row.joints.clone();
        for (e, v) in effects.iter().zip(&params.effects) {
            if e.kind == ArmKind::JointOffset && self.space.is_some() {
                joints[e.joint] += v[0];
            }
        }
        // The arm's statics at the configuration: the row's own (computed once) unless offsets move it.
        let statics = if joints == row.joints {
            Cow::Borrowed(&self.statics[r])
        } else {
            Cow::Owned(self.statics_at(r, row, &joints, state)?)
        };
        let (s, zero) = &*statics;
        // The model's own deflection and the miss kept for these effects, a twist at the reference point
        // (a serial arm's miss is what the body's point or the tool's turn misses: `exact_misses`). A
        // parallel robot's turn carries the target's lever exactly (an Orthoglide under a milling moment
        // turns by 0.05 rad, whose second order on a lever of 10 mm is 12 um); a serial arm's lever turns at
        // first order here, its second order is in its kept miss.
        let miss = if kept { self.kept_miss(effects, r) } else { Vec6::zeros() };
        let deflected = self.deflection[r] + miss;
        let loaded_rot = self.tool_turned(r, s);
        let (seen, tool) = match row.observed {
            Observed::Position { target, .. } => {
                let lever = loaded_rot * params.targets[target];
                (Seen::Point(lever), s.frame.pos + lever)
            }
            Observed::Orientation { .. } => (Seen::Turn, Vec3::zeros()),
            Observed::Displacement(_) => (Seen::Point(Vec3::zeros()), Vec3::zeros()),
        };
        // A payload being fitted weighs on every joint: its wrench at the reference point, (m g, (R s) x g).
        let payload = self.fitted_payload_weight(r, effects, params, s, zero);
        // The body's point (target, or the tool point of a displacement) under the loads, before registration;
        // for an orientation, the tool's turn under them (base axes).
        let mut y = match (seen, self.space) {
            // The lever already turned with the deflection (a parallel robot).
            (Seen::Point(_), None) => tool + deflected.fixed_rows::<3>(0),
            // A serial arm's lever turned at first order, v + w x lever; an orientation turns by w.
            _ => tool + seen.of(&deflected),
        };
        // What the effects' first order moves on a serial arm: the target where the loads put it (the model's
        // own deflection; not the kept miss, which the first order it completes must not see), so that a
        // joint's turn or a geometry's moves it as it stands.
        // At a first joint, whose axis no load moves, that is exactly the set-up's turn: before, the turn
        // was taken at the unloaded target, which differed from the set-up's by the sag, and a base's tilt
        // seemed seen through that difference alone (its first order leaves out the weight's lever).
        let seen = match (seen, self.space, row.observed) {
            (Seen::Point(lever), Some(_), Observed::Position { .. }) => {
                let sag = &self.deflection[r];
                let (t, w) = (sag.fixed_rows::<3>(0).into_owned(), sag.fixed_rows::<3>(3).into_owned());
                Seen::Point(lever + t + w.cross(&lever))
            }
            _ => seen,
        };
        for (e, v) in effects.iter().zip(&params.effects) {
            for (unit, value) in self.unit_moves(r, e, s, zero, &seen, &payload).iter().zip(v) {
                y += unit * *value;
            }
        }
        Some(Body { joints, statics, seen, loaded_rot, y })
    }

    /// The prediction of row `r` and its derivative in every parameter (3 x p, weighted by the row's weight
    /// along with the residual).
    pub(super) fn predict(
        &self,
        r: usize,
        effects: &[ArmEffect],
        params: &Params,
        state: &mut ManipulatorState,
        jacobian: Option<&mut DMatrix<f64>>,
    ) -> Option<Vec3> {
        let row = &self.data.rows[r];
        let Body { joints, statics, seen, loaded_rot, y } = self.body(r, effects, params, state, true)?;
        let (s, zero) = &*statics;
        let payload = |s: &ArmStatics| self.fitted_payload_weight(r, effects, params, s, zero);
        let (rotation, translation) = match row.observed {
            Observed::Position { setup, .. } | Observed::Orientation { setup, .. } => {
                (params.rotations[setup], params.translations[setup])
            }
            Observed::Displacement(_) => (Mat3::identity(), Vec3::zeros()),
        };
        // An orientation is predicted as the target's axes in the instrument's frame, R exp(y) R_tool R_target;
        // its prediction is its rotation vector away from the measured one (`measured` gives zero for it).
        let turned = match row.observed {
            Observed::Orientation { target, at, .. } => {
                let axes = rotation * rotation_from_vector(&y) * s.frame.rot;
                Some((axes, crate::kinematics::frame::rotation_vector(&(axes * params.turns[target] * at.transpose()))))
            }
            _ => None,
        };
        let prediction = match turned {
            Some((_, off)) => off,
            None => rotation * y + translation,
        };
        if let Some(jac) = jacobian {
            let w = self.weight[r];
            jac.fill(0.0);
            let mut k = 0;
            if let Some((target, setup)) = row.observed.target_and_setup() {
                let base = 6 * setup;
                if let Some((axes, _)) = turned {
                    // A small rotation d after R turns the prediction by d (to first order about a small
                    // misfit); the target's turn e in the tool's axes by R exp(y) R_tool e.
                    jac.view_mut((0, base + 3), (3, 3)).copy_from(&(Mat3::identity() * w));
                    if let Some(t) = self.turn_parameter(target) {
                        jac.view_mut((0, t), (3, 3)).copy_from(&(axes * w));
                    }
                } else {
                    let ry = rotation * y;
                    for a in 0..3 {
                        jac[(a, base + a)] = w;
                    }
                    // A small rotation d applied after R: d(R y) = d x (R y) = -[R y]x d.
                    let cross = -skew(&ry) * w;
                    jac.view_mut((0, base + 3), (3, 3)).copy_from(&cross);
                    let t = 6 * self.data.setups.len() + 3 * target;
                    jac.view_mut((0, t), (3, 3)).copy_from(&(rotation * loaded_rot * w));
                }
                k = self.nuisance_count();
            }
            for e in effects {
                let columns = match (e.kind, self.space) {
                    (ArmKind::JointOffset, Some(space)) => {
                        // The offset turns every model coordinate the controller map ties to its angle; the
                        // body's point moves with each by its twist column (the loads' change with it is of
                        // second order, left to the iterations, which evaluate the prediction exactly).
                        let rates = space.coordinate_rates(&joints, e.joint);
                        let mut column = Vec3::zeros();
                        for (rate, c) in rates.iter().zip(&s.columns) {
                            if *rate != 0.0 && zero.is_none() {
                                column += seen.of(c) * *rate;
                            }
                        }
                        vec![column]
                    }
                    (ArmKind::Payload, _) => {
                        // Its weight loads the compliances being fitted too (their term is the compliance
                        // times the joint's load, payload included): the derivative has that part as well.
                        let mut columns = self.unit_moves(r, e, s, zero, &seen, &payload(s));
                        let g = self.arm(r).weight_gravity();
                        for (k, column) in columns.iter_mut().enumerate() {
                            let unit = if k == 0 {
                                Vec6::new(g.x, g.y, g.z, 0.0, 0.0, 0.0)
                            } else {
                                let m = self.tool_turned(r, s).column(k - 1).into_owned().cross(&g);
                                Vec6::new(0.0, 0.0, 0.0, m.x, m.y, m.z)
                            };
                            for (other, v) in effects.iter().zip(&params.effects) {
                                if other.kind == ArmKind::JointCompliance && zero.is_none() {
                                    let joint = &s.columns[other.joint];
                                    *column += seen.of(joint) * (v[0] * joint.dot(&unit));
                                }
                            }
                        }
                        columns
                    }
                    _ => self.unit_moves(r, e, s, zero, &seen, &payload(s)),
                };
                for column in columns {
                    jac.view_mut((0, k), (3, 1)).copy_from(&(rotation * column * w));
                    k += 1;
                }
            }
        }
        Some(prediction)
    }

    /// The weight of a payload being fitted (`effects`, `params`) at the reference point of row `r`, (m g,
    /// (R s) x g) with s = m c its first moment in the tool frame: the joints carry it too. Zero without
    /// one, and for a displacement (the weight is in both states).
    pub(super) fn fitted_payload_weight(
        &self,
        r: usize,
        effects: &[ArmEffect],
        params: &Params,
        s: &ArmStatics,
        zero: &Option<ArmStatics>,
    ) -> Vec6 {
        let Some(k) = effects.iter().position(|e| e.kind == ArmKind::Payload) else { return Vec6::zeros() };
        if zero.is_some() {
            return Vec6::zeros();
        }
        let (v, g) = (&params.effects[k], self.arm(r).weight_gravity());
        let moment = (self.tool_turned(r, s) * Vec3::new(v[1], v[2], v[3])).cross(&g);
        let force = g * v[0];
        Vec6::new(force.x, force.y, force.z, moment.x, moment.y, moment.z)
    }

    /// The tool's axes at row `r` under the model's own loads, for a parallel robot: a payload's centre turns
    /// with them, so its moment (R c) x g sees the centre's component along gravity once the load turns the
    /// tool (an Orthoglide under the milling moment turns by 0.05 rad: 20 kg 50 mm above the reference point
    /// then weigh 490 N mm, which the unturned axes put on the centre's other components). A serial arm's
    /// axes as the unloaded kinematics gives them (see `predict`).
    pub(super) fn tool_turned(&self, r: usize, s: &ArmStatics) -> Mat3 {
        match self.space {
            Some(_) => s.frame.rot,
            None => rotation_from_vector(&self.deflection[r].fixed_rows::<3>(3).into_owned()) * s.frame.rot,
        }
    }

    /// How the body's point (before registration), or the tool's turn for an orientation, moves per unit of
    /// each parameter of effect `e` in row `r` (`s` the arm's statics there, `zero` at zero wrench for a
    /// displacement, `seen` what the row sees, `payload` the weight of a payload being fitted); an offset's are
    /// found by differences in `predict`.
    pub(super) fn unit_moves(
        &self,
        r: usize,
        e: &ArmEffect,
        s: &ArmStatics,
        zero: &Option<ArmStatics>,
        seen: &Seen,
        payload: &Vec6,
    ) -> Vec<Vec3> {
        let point = |c: &Vec6| seen.of(c);
        let turning = matches!(seen, Seen::Turn);
        match e.kind {
            // A serial arm's offset moves its configuration (`predict`); a parallel robot's actuator offset
            // moves the platform by C K_i a_i per unit (a displacement does not see it).
            ArmKind::JointOffset if self.space.is_some() || zero.is_some() => vec![Vec3::zeros()],
            ArmKind::JointOffset => vec![point(&s.columns[e.joint])],
            // A parallel robot's leg geometry: its end-point error eps (base axes, at the reference point)
            // moves the platform by C K_i eps (paper 000 eq 60).
            ArmKind::JointGeometry if self.space.is_none() => {
                if zero.is_some() {
                    return vec![Vec3::zeros(); 6];
                }
                let moves = &self.leg_moves[r][e.joint];
                (0..6).map(|k| point(&moves.column(k).into_owned())).collect()
            }
            ArmKind::JointCompliance | ArmKind::Backlash => {
                vec![point(&s.columns[e.joint]) * effect_gain(e, s, zero, payload)]
            }
            ArmKind::JointGeometry => {
                // The fixed transform before the joint moved by (v, w) in the joint's frame: everything after it
                // moves rigidly, R v + (R w) x (x - o) at the point x (a displacement does not see it).
                if zero.is_some() {
                    return vec![Vec3::zeros(); 6];
                }
                let f = &s.joint_frames[e.joint];
                (0..6)
                    .map(|k| {
                        let axis = f.rot.column(k % 3).into_owned();
                        if k < 3 {
                            seen.rigid(axis, Vec3::zeros(), &f.pos, &s.frame.pos)
                        } else {
                            seen.rigid(Vec3::zeros(), axis, &f.pos, &s.frame.pos)
                        }
                    })
                    .collect()
            }
            ArmKind::FrameCompliance => {
                // The wrench through the frame (for a displacement, its change with the row's wrench), in the
                // frame's axes: each compliance turns one of its components into a motion of everything beyond.
                let f = &s.joint_frames[e.joint];
                let through = |st: &ArmStatics| {
                    st.transmitted[e.joint]
                        + crate::platform::manipulator::moved_wrench(payload, &(st.frame.pos - f.pos))
                };
                let mut w = through(s);
                if let Some(z) = zero {
                    w -= z.transmitted[e.joint];
                }
                (0..6)
                    .map(|k| {
                        let axis = f.rot.column(k % 3).into_owned();
                        let local = axis.dot(&Vec3::new(w[3 * (k / 3)], w[3 * (k / 3) + 1], w[3 * (k / 3) + 2]));
                        if k < 3 {
                            seen.rigid(axis * local, Vec3::zeros(), &f.pos, &s.frame.pos)
                        } else {
                            seen.rigid(Vec3::zeros(), axis * local, &f.pos, &s.frame.pos)
                        }
                    })
                    .collect()
            }
            ArmKind::Payload => {
                // Its weight at the reference point, (m g, (R s) x g) with s = m c its first moment, seen through
                // the model's tangent compliance (a rigid model, or a displacement, does not see it).
                let Some(c) = &self.compliance[r] else { return vec![Vec3::zeros(); 4] };
                let g = self.arm(r).weight_gravity();
                let mut moves = vec![point(&(c * Vec6::new(g.x, g.y, g.z, 0.0, 0.0, 0.0)))];
                for k in 0..3 {
                    let moment = self.tool_turned(r, s).column(k).into_owned().cross(&g);
                    moves.push(point(&(c * Vec6::new(0.0, 0.0, 0.0, moment.x, moment.y, moment.z))));
                }
                moves
            }
            // The instrument's position readings drift; the tool's turn is not one of them.
            ArmKind::Drift if turning => vec![Vec3::zeros(); 3],
            // A rate per row of the file (its line: the targets of one line were seen together), from the
            // first row; what is common to every row is the registration's.
            ArmKind::Drift => {
                let t = (self.data.rows[r].line - self.data.rows[0].line) as f64;
                (0..3).map(|k| Vec3::ith(k, t)).collect()
            }
            // It moves the tool along its own axes (a spring in translation): no turn.
            ArmKind::ToolCompliance if turning => vec![Vec3::zeros(); 3],
            // The force through the tool: the row's wrench, the description's payload and one being fitted
            // (for a displacement, the wrench's alone: the weights are in both states).
            ArmKind::ToolCompliance => {
                let row = &self.data.rows[r];
                let mut force = row.wrench.fixed_rows::<3>(0).into_owned();
                if zero.is_none() {
                    force += (self.arm(r).weight(&s.frame).0 + payload).fixed_rows::<3>(0);
                }
                (0..3)
                    .map(|k| {
                        let axis = s.frame.rot.column(k).into_owned();
                        axis * axis.dot(&force)
                    })
                    .collect()
            }
        }
    }

    /// The unweighted residual (measured minus predicted) of every row, None where a row has no pose.
    /// Each position row's residual (`residuals`) in the robot base's axes: a set-up's turned back from its
    /// instrument's frame (R^T e); a displacement's is already there; an orientation's is None.
    pub(super) fn in_base_axes(&self, residuals: &[Option<Vec3>], params: &Params) -> Vec<Option<Vec3>> {
        residuals
            .iter()
            .zip(&self.data.rows)
            .map(|(e, row)| match row.observed {
                Observed::Position { setup, .. } => e.map(|e| params.rotations[setup].transpose() * e),
                Observed::Displacement(_) => *e,
                Observed::Orientation { .. } => None,
            })
            .collect()
    }

    pub(super) fn residuals(&self, effects: &[ArmEffect], params: &Params) -> Vec<Option<Vec3>> {
        let mut state = self.m.new_state();
        (0..self.data.rows.len())
            .map(|r| self.predict(r, effects, params, &mut state, None).map(|p| self.measured(r) - p))
            .collect()
    }
}

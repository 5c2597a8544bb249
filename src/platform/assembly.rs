//! Assembly of legs whose free end points miss the platform (paper 000 s. 4.2), linear version
//! (eq 57-65): each leg, deformed from its own end point t0 + eps_i to the common platform pose t0 + dt,
//! pushes back with w_i = -K_i (dt - eps_i); equilibrium sum_i w_i = 0 gives dt = K^-1 sum_i K_i eps_i.

use super::compliance::analyse;
use super::leg::{Leg, LegFailure, LegResponse, LegState, VjmLeg};
use crate::kinematics::frame::{apply_twist, point_shift, Frame, Vec3, Vec6};

/// The linear assembly of legs with end-point errors (eq 60-63).
#[derive(Clone, Debug, PartialEq)]
pub struct LinearAssembly {
    /// Platform displacement at the reference point (mm, rad).
    pub displacement: Vec6,
    /// Wrench each leg exerts on the platform (N, N mm); they sum to zero.
    pub leg_wrenches: Vec<Vec6>,
}

/// `eps[i]`: leg i's end-point error as a twist at the reference point. None where the manipulator's
/// stiffness is singular.
pub fn linear_assembly(legs: &[LegResponse], eps: &[Vec6], length_scale: f64) -> Option<LinearAssembly> {
    let k: nalgebra::Matrix6<f64> = legs.iter().map(|l| l.stiffness).sum();
    let magnitude: Vec6 = legs.iter().map(|l| l.magnitude).sum();
    let compliance = *analyse(&k, &magnitude, length_scale, true).compliance()?;
    let load: Vec6 = legs.iter().zip(eps).map(|(l, e)| l.stiffness * e).sum();
    let displacement = compliance * load;
    let leg_wrenches = legs.iter().zip(eps).map(|(l, e)| -(l.stiffness * (displacement - e))).collect();
    Some(LinearAssembly { displacement, leg_wrenches })
}

/// A leg's joints after its end moved by dt from where the leg was placed (paper 000 eq 64-65): the largest
/// passive-joint change, virtual-spring deflections and spring loads, translational and rotational apart.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JointDeflections {
    /// Largest |dq| of a passive joint (rad for revolute, mm for prismatic joints).
    pub passive_max: f64,
    /// Largest translational spring deflection (mm) and its force (N).
    pub spring_deflection_max: f64,
    /// Largest spring force, N.
    pub spring_force_max: f64,
    /// Largest rotational spring deflection (rad) and its torque (N mm).
    pub spring_rotation_max: f64,
    /// Largest spring torque, N mm.
    pub spring_torque_max: f64,
}

impl JointDeflections {
    /// The larger of each maximum.
    pub fn max(self, o: JointDeflections) -> JointDeflections {
        JointDeflections {
            passive_max: self.passive_max.max(o.passive_max),
            spring_deflection_max: self.spring_deflection_max.max(o.spring_deflection_max),
            spring_force_max: self.spring_force_max.max(o.spring_force_max),
            spring_rotation_max: self.spring_rotation_max.max(o.spring_rotation_max),
            spring_torque_max: self.spring_torque_max.max(o.spring_torque_max),
        }
    }
}

// Assembly-only operations of a leg (paper 000 eq 64-65, 69, 71): its end-point error by source, its
// joints' deflections for an end displacement, and the leg with its errors built in.

/// A leg's end-point error eps_i at the reference point (paper 000 eq 69) by source: given directly, from
/// the base error, and from the parameter errors through the leg's own kinematics.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EndErrors {
    /// Given directly in the error file.
    pub direct: Vec6,
    /// From the leg's base error.
    pub base: Vec6,
    /// From its parameter errors, through its own kinematics (eq 69).
    pub parameters: Vec6,
}

impl EndErrors {
    /// The leg's end-point error, all sources.
    pub fn total(&self) -> Vec6 {
        self.direct + self.base + self.parameters
    }
}

impl Leg {
    /// After `place`: where the leg with errors puts the platform's reference point when its actuated and
    /// passive coordinates keep their nominal values (eq 69: g*(q0, theta0) = t0 + eps), as a twist at the
    /// reference point. `base` is the leg's rigid base error (a frame in the base frame); `perturbed` the leg
    /// rebuilt with its parameter errors (a VJM leg of the same structure).
    pub fn end_errors(
        &self,
        platform: &Frame,
        state: &LegState,
        direct: &Vec6,
        base: &Frame,
        perturbed: Option<&Leg>,
    ) -> Result<EndErrors, LegFailure> {
        // The whole leg moved rigidly by `base` carries the platform with it: P' = base P.
        let base_error = platform.error_to(&base.compose(platform));
        let parameters = match (self, perturbed) {
            (_, None) => Vec6::zeros(),
            (Leg::Vjm(l), Some(Leg::Vjm(p))) if p.chain.elements().len() == l.chain.elements().len() => {
                let end = p.chain.end_frame(&state.coords);
                platform.error_to(&end.compose(&p.attachment.inverse()))
            }
            // An MSA leg's geometry is solved from the pose, so its parameters do not move its end: the error
            // file refuses parameter errors for it (`ErrorSet::load`), so only a rebuild that does not match lands here.
            _ => return Err(LegFailure::SingularChain),
        };
        Ok(EndErrors { direct: *direct, base: base_error, parameters })
    }

    /// After `place`: the leg's joints when its end is moved by `dt` (a twist at the reference point) from
    /// the placement with the actuators held (paper 000 eq 64-65, from K_Cq and K_Ctheta of eq 46). None for
    /// an MSA leg (its joints are not coordinates of a chain).
    pub fn joint_deflections(
        &self,
        platform: &Frame,
        dt: &Vec6,
        state: &mut LegState,
    ) -> Option<super::assembly::JointDeflections> {
        let Leg::Vjm(l) = self else { return None };
        let target = l.target(platform);
        let lin = l.loaded_chain().linearize(&target, &state.coords, &Vec6::zeros(), &mut state.equilibrium)?;
        let twist = point_shift(&(lin.end - platform.pos)) * dt;
        let delta = lin.response(&twist);
        let n_q = state.coords.passive.len();
        let mut out =
            super::assembly::JointDeflections { passive_max: delta.rows(0, n_q).amax(), ..Default::default() };
        let theta = delta.rows(n_q, state.coords.virtual_.len());
        let kinds = l.chain.virtual_kinds();
        for g in &l.springs {
            let th = nalgebra::DVector::from_fn(g.dim, |r, _| theta[g.first + r]);
            let k = g.stiffness.view((0, 0), (g.dim, g.dim));
            let tau = k * &th;
            for r in 0..g.dim {
                if kinds[g.first + r] == crate::kinematics::chain::JointKind::Prismatic {
                    out.spring_deflection_max = out.spring_deflection_max.max(th[r].abs());
                    out.spring_force_max = out.spring_force_max.max(tau[r].abs());
                } else {
                    out.spring_rotation_max = out.spring_rotation_max.max(th[r].abs());
                    out.spring_torque_max = out.spring_torque_max.max(tau[r].abs());
                }
            }
        }
        Some(out)
    }

    /// The same leg with its errors built in, for the non-linear assembly (eq 69-72): a VJM leg's chain
    /// (its parameter-perturbed version if given) moved by the base error and by the direct end error (a
    /// rigid motion about the reference point of `platform`).
    pub fn with_errors(&self, platform: &Frame, direct: &Vec6, base: &Frame, perturbed: Option<&Leg>) -> Leg {
        match (self, perturbed) {
            (Leg::Vjm(l), p) => {
                let chain = match p {
                    Some(Leg::Vjm(p)) => &p.chain,
                    _ => &l.chain,
                };
                let r = crate::kinematics::frame::rotation_from_vector(&Vec3::new(direct[3], direct[4], direct[5]));
                let about_rp =
                    Frame::new(r, platform.pos + Vec3::new(direct[0], direct[1], direct[2]) - r * platform.pos);
                Leg::Vjm(VjmLeg { chain: chain.prepended(*base).prepended(about_rp), ..l.clone() })
            }
            (Leg::Msa(_), _) => self.clone(),
        }
    }
}

impl LegState {
    /// For a linear (MSA) leg, placed nominally: makes it answer as if its end sat `eps` away (the leg's
    /// end-point error). Nothing for a VJM leg, whose errors are built into its chain (`Leg::with_errors`).
    pub fn offset_placement(&mut self, eps: &Vec6) {
        if let Some((placed, _)) = self.msa.placed.as_mut() {
            *placed = apply_twist(placed, eps);
        }
    }
}

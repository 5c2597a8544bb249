//! Assembly of legs whose free end points miss the platform (paper 000 s. 4.2), linear version
//! (eq 57-65): each leg, deformed from its own end point t0 + eps_i to the common platform pose t0 + dt,
//! pushes back with w_i = -K_i (dt - eps_i); equilibrium sum_i w_i = 0 gives dt = K^-1 sum_i K_i eps_i.

use super::compliance::analyse;
use super::leg::LegResponse;
use crate::kinematics::frame::Vec6;

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
    pub spring_force_max: f64,
    /// Largest rotational spring deflection (rad) and its torque (N mm).
    pub spring_rotation_max: f64,
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

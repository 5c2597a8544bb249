//! Virtual springs: a group of virtual coordinates with a stiffness matrix K_theta block (paper 001 eq 6),
//! and the compliance of a clamped-free beam, the simplest source of a link's 6-dof spring (paper 001 s. 4.2).

use crate::kinematics::chain::{Element, Joint, JointKind, Role};
use crate::kinematics::frame::{block_rotation, Mat3, Mat6, Vec3};

/// A block of K_theta: `dim` consecutive virtual coordinates starting at `first`.
#[derive(Clone, Debug, PartialEq)]
pub struct SpringGroup {
    pub name: String,
    /// The control-loop spring of an actuator (V_a(q + theta), paper 001 eq 1).
    pub actuator: bool,
    pub first: usize,
    pub dim: usize,
    /// Stiffness (top-left dim x dim block used; the rest zero).
    pub stiffness: Mat6,
    /// Its inverse, computed once (K_theta^-1 of paper 001 eq 9).
    pub compliance: Mat6,
    /// Where the spring depends on the posture (a parallelogram's angle), how; `stiffness` and
    /// `compliance` then hold its value at the nominal posture.
    pub posture: Option<super::parallelogram::Parallelogram>,
}

impl SpringGroup {
    /// Multiplies the spring's compliance by `factor` (divides its stiffness), at every posture: a
    /// posture-dependent spring is rebuilt by `at` from its own derivation, so the factor goes there too.
    pub fn scale_compliance(&mut self, factor: f64) {
        self.stiffness /= factor;
        self.compliance *= factor;
        if let Some(p) = &mut self.posture {
            p.compliance_factor *= factor;
        }
    }

    /// Stiffness and compliance at the given passive coordinates. Where a posture-dependent spring has no
    /// finite value (`Parallelogram::stiffness`), both are NaN: the leg's answer is then not finite and
    /// its point is reported as `overflow` (statuses in README), never a panic.
    pub fn at(&self, passive: &[f64]) -> (Mat6, Mat6) {
        match &self.posture {
            None => (self.stiffness, self.compliance),
            Some(p) => {
                let q = passive.get(p.angle).copied().unwrap_or(0.0);
                let not_finite = Mat6::from_element(f64::NAN);
                let Some(k) = p.stiffness(q) else { return (not_finite, not_finite) };
                let c = k.try_inverse().unwrap_or(not_finite);
                (k, (c + c.transpose()) * 0.5)
            }
        }
    }
}

/// Step (rad) of the central differences that give a posture-dependent spring's derivatives: the
/// truncation error of K' is (h^2/6) K''' ~ 2e-9 relative and round-off in K'' eps/h^2 ~ 1e-8.
const POSTURE_STEP: f64 = 1e-4;

impl SpringGroup {
    /// For a spring whose stiffness depends on a passive coordinate q (a parallelogram's angle): that
    /// coordinate's index and dK/dq, d2K/dq2 at the given posture, by central differences of the spring's own
    /// derivation. The loaded equilibrium needs them: with the energy 1/2 dtheta^T K(q) dtheta, q feels
    /// 1/2 dtheta^T K'(q) dtheta and the Newton matrix gains K'(q) dtheta and 1/2 dtheta^T K''(q) dtheta.
    /// `mid` is the stiffness at the posture itself, as `at` gave it (not derived twice).
    pub fn posture_derivatives(&self, passive: &[f64], mid: &Mat6) -> Option<(usize, Mat6, Mat6)> {
        let p = self.posture.as_ref()?;
        let q = passive.get(p.angle).copied().unwrap_or(0.0);
        let h = POSTURE_STEP;
        let not_finite = Mat6::from_element(f64::NAN);
        let at = |q: f64| p.stiffness(q).unwrap_or(not_finite);
        let (minus, plus) = (at(q - h), at(q + h));
        Some((p.angle, (plus - minus) / (2.0 * h), (plus - mid * 2.0 + minus) / (h * h)))
    }
}

/// The elementary joints of a 6-dof spring, in order: translations along the frame's x, y, z, then
/// rotations about them (paper 001 eq 1, V_s(theta1..theta6)).
pub const SIX_DOF: [(JointKind, Vec3); 6] = [
    (JointKind::Prismatic, Vec3::new(1.0, 0.0, 0.0)),
    (JointKind::Prismatic, Vec3::new(0.0, 1.0, 0.0)),
    (JointKind::Prismatic, Vec3::new(0.0, 0.0, 1.0)),
    (JointKind::Revolute, Vec3::new(1.0, 0.0, 0.0)),
    (JointKind::Revolute, Vec3::new(0.0, 1.0, 0.0)),
    (JointKind::Revolute, Vec3::new(0.0, 0.0, 1.0)),
];

/// Appends the six virtual joints of a 6-dof spring whose coordinates start at `first`.
pub fn push_six_dof(elements: &mut Vec<Element>, first: usize) {
    for (k, (kind, axis)) in SIX_DOF.iter().enumerate() {
        elements.push(Element::Joint(Joint {
            kind: *kind,
            axis: *axis,
            role: Role::Virtual,
            index: first + k,
            gain: 1.0,
        }));
    }
}

/// Cross-section and material of a straight beam; units N, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamSection {
    /// Young's modulus, N/mm^2 (MPa).
    pub e: f64,
    /// Shear modulus, N/mm^2.
    pub g: f64,
    /// Area, mm^2.
    pub area: f64,
    /// Second moments of area about the section's y and z axes, mm^4.
    pub iy: f64,
    pub iz: f64,
    /// Torsion constant, mm^4.
    pub j: f64,
}

impl BeamSection {
    /// A round solid section of diameter `d` (mm).
    pub fn round(e: f64, g: f64, d: f64) -> Self {
        let area = std::f64::consts::PI * d * d / 4.0;
        let i = std::f64::consts::PI * d.powi(4) / 64.0;
        Self { e, g, area, iy: i, iz: i, j: 2.0 * i }
    }
}

/// Compliance of a clamped-free beam of length `l` along its local x axis, at its free end, in the frame of
/// the free end (Euler-Bernoulli; translations first, then rotations; units mm/N, 1/N, rad/(N mm)).
pub fn cantilever_compliance(s: &BeamSection, l: f64) -> Mat6 {
    let mut c = Mat6::zeros();
    c[(0, 0)] = l / (s.e * s.area);
    c[(1, 1)] = l.powi(3) / (3.0 * s.e * s.iz);
    c[(2, 2)] = l.powi(3) / (3.0 * s.e * s.iy);
    c[(3, 3)] = l / (s.g * s.j);
    c[(4, 4)] = l / (s.e * s.iy);
    c[(5, 5)] = l / (s.e * s.iz);
    // Bending couples: a force Fy turns the tip about +z, a force Fz about -y.
    c[(1, 5)] = l * l / (2.0 * s.e * s.iz);
    c[(5, 1)] = c[(1, 5)];
    c[(2, 4)] = -l * l / (2.0 * s.e * s.iy);
    c[(4, 2)] = c[(2, 4)];
    c
}

/// A rotation taking the x axis to `direction` (the beam's axis); the section's y axis is chosen
/// perpendicular to it in a fixed way (irrelevant for round sections).
pub fn frame_along(direction: &Vec3) -> Mat3 {
    let x = direction.normalize();
    let helper = if x.z.abs() < 0.9 { Vec3::z() } else { Vec3::x() };
    let y = helper.cross(&x).normalize();
    let z = x.cross(&y);
    Mat3::from_columns(&[x, y, z])
}

/// The compliance of a beam along `direction`, expressed in the spring's frame.
pub fn beam_compliance(s: &BeamSection, l: f64, direction: &Vec3) -> Mat6 {
    let r = block_rotation(&frame_along(direction));
    r * cantilever_compliance(s, l) * r.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cantilever_compliance_is_symmetric_positive_definite() {
        let s = BeamSection::round(210000.0, 80769.0, 12.0);
        let c = cantilever_compliance(&s, 300.0);
        assert_eq!(c, c.transpose());
        assert!(c.cholesky().is_some());
    }

    #[test]
    fn beam_along_x_keeps_the_local_compliance() {
        let s = BeamSection { e: 2e5, g: 8e4, area: 100.0, iy: 900.0, iz: 400.0, j: 1300.0 };
        let c0 = cantilever_compliance(&s, 250.0);
        let c1 = beam_compliance(&s, 250.0, &Vec3::new(3.0, 0.0, 0.0));
        assert!((c0 - c1).abs().max() < 1e-15 * c0.abs().max());
    }
}

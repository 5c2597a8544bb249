//! Virtual springs: a group of virtual coordinates with a stiffness matrix K_theta block (paper 001 eq 6).
//! A link's 6-dof spring usually comes from a beam's compliance (`crate::beam`, paper 001 s. 4.2).

use crate::expr::Expr;
use crate::kinematics::chain::{Coordinates, Element, Joint, JointKind, Role};
use crate::kinematics::frame::{Mat6, Vec3};
use crate::linalg::spd_inverse6;

/// A block of K_theta: `dim` consecutive virtual coordinates starting at `first`.
#[derive(Clone, Debug, PartialEq)]
pub struct SpringGroup {
    /// The group's name (the element's), shared by copies of a leg.
    pub name: String,
    /// The control-loop spring of an actuator (V_a(q + theta), paper 001 eq 1).
    pub actuator: bool,
    /// Index of its first virtual coordinate.
    pub first: usize,
    /// Number of its coordinates (1 to 6).
    pub dim: usize,
    /// Stiffness (top-left dim x dim block used; the rest zero).
    pub stiffness: Mat6,
    /// Its inverse, computed once (K_theta^-1 of paper 001 eq 9).
    pub compliance: Mat6,
    /// Where the spring depends on the posture (a parallelogram's angle), how; `stiffness` and
    /// `compliance` then hold its value at the nominal posture.
    pub posture: Option<super::parallelogram::Parallelogram>,
    /// Where the stiffness is a formula of one of the chain's actuated coordinates (a joint with a gravity
    /// compensator), how; `stiffness` and `compliance` then hold its value at that coordinate's zero.
    pub of_coordinate: Option<CoordinateStiffness>,
    /// For a spring derived from a straight beam: its axis (unit, in the spring's coordinates), along
    /// which the translation is the beam's axial compliance L/EA, uncoupled from bending and torsion.
    pub beam_axis: Option<Vec3>,
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
        if let Some(c) = &mut self.of_coordinate {
            c.compliance_factor *= factor;
        }
    }

    /// True where the stiffness depends on the chain's coordinates (`at` then needs them).
    pub fn varies(&self) -> bool {
        self.posture.is_some() || self.of_coordinate.is_some()
    }

    /// Multiplies a beam spring's axial compliance (L/EA) by `axial` and the rest (bending L^3/3EI and
    /// torsion L/GJ, all proportional to d^-4 for a round section where the axial part goes as d^-2) by
    /// `bending`. A spring that is not a straight beam is left as it is.
    pub fn scale_beam_parts(&mut self, axial: f64, bending: f64) {
        let Some(u) = self.beam_axis else { return };
        let mut along = Mat6::zeros();
        let a = (u.transpose() * self.compliance.fixed_view::<3, 3>(0, 0) * u)[0];
        along.fixed_view_mut::<3, 3>(0, 0).copy_from(&(u * u.transpose() * a));
        let c = along * axial + (self.compliance - along) * bending;
        if let Some(k) = c.try_inverse() {
            self.compliance = c;
            self.stiffness = (k + k.transpose()) * 0.5;
        }
    }

    /// Stiffness and compliance at the given coordinates. Where a posture-dependent spring has no
    /// finite value (`Parallelogram::stiffness`, a formula's), both are NaN: the leg's answer is then not
    /// finite and its point is reported as `overflow` (statuses in docs/GUIDE.md), never a panic.
    pub fn at(&self, coords: &Coordinates) -> (Mat6, Mat6) {
        if let Some(c) = &self.of_coordinate {
            return one_coordinate(c.compliance(coords));
        }
        if self.posture.is_none() {
            return (self.stiffness, self.compliance);
        }
        let k = self.stiffness_at(coords);
        // Positive definite as built (the regularised parallelogram); LU where round-off says not.
        let c = spd_inverse6(&k).or_else(|| k.try_inverse().map(|c| (c + c.transpose()) * 0.5));
        (k, c.unwrap_or(Mat6::from_element(f64::NAN)))
    }

    /// The stiffness where it does not depend on the coordinates (no copy of the block: a Newton
    /// iteration reads every spring's).
    pub fn constant_stiffness(&self) -> Option<&Mat6> {
        (!self.varies()).then_some(&self.stiffness)
    }

    /// The stiffness alone at the given coordinates (`at` without the compliance).
    pub fn stiffness_at(&self, coords: &Coordinates) -> Mat6 {
        match (&self.posture, &self.of_coordinate) {
            (Some(p), _) => {
                let q = coords.passive.get(p.angle).copied().unwrap_or(0.0);
                p.stiffness(q).unwrap_or(Mat6::from_element(f64::NAN))
            }
            (None, Some(_)) => self.at(coords).0,
            (None, None) => self.stiffness,
        }
    }

    /// For a spring whose stiffness depends on a passive coordinate q (a parallelogram's angle): that
    /// coordinate's index and dK/dq, d2K/dq2 at the given posture, exact
    /// (`Parallelogram::stiffness_derivatives`). The loaded equilibrium needs them: with the energy
    /// 1/2 dtheta^T K(q) dtheta, q feels 1/2 dtheta^T K'(q) dtheta and the Newton matrix gains K'(q) dtheta
    /// and 1/2 dtheta^T K''(q) dtheta.
    pub fn posture_derivatives(&self, passive: &[f64]) -> Option<(usize, Mat6, Mat6)> {
        let p = self.posture.as_ref()?;
        let q = passive.get(p.angle).copied().unwrap_or(0.0);
        let not_finite = Mat6::from_element(f64::NAN);
        let [_, first, second] = p.stiffness_derivatives(q).unwrap_or([not_finite; 3]);
        Some((p.angle, first, second))
    }
}

/// The stiffness and compliance blocks of a one-coordinate spring of this compliance (the top-left entry).
pub fn one_coordinate(compliance: f64) -> (Mat6, Mat6) {
    let (mut stiffness, mut block) = (Mat6::zeros(), Mat6::zeros());
    stiffness[(0, 0)] = 1.0 / compliance;
    block[(0, 0)] = compliance;
    (stiffness, block)
}

/// A one-coordinate spring whose stiffness is a formula of an actuated coordinate of its chain: a joint
/// with a gravity compensator, whose equivalent stiffness depends on the configuration (paper 000 s. 5). The
/// actuators hold that coordinate in a loaded equilibrium, so the stiffness is constant there: the
/// equilibrium needs no derivative of it.
#[derive(Clone, Debug)]
pub struct CoordinateStiffness {
    /// The actuated coordinate (index among the chain's actuated coordinates).
    pub coordinate: usize,
    /// The stiffness (N mm/rad, or N/mm along a prismatic axis) as a formula of the coordinate (slot 0).
    pub stiffness: Expr,
    /// The formula as written (two springs are equal when their formulas read alike).
    pub formula: String,
    /// A compliance in series with it (a calibration's correction).
    pub added_compliance: f64,
    /// A factor on the whole compliance (a spring scaling).
    pub compliance_factor: f64,
}

impl PartialEq for CoordinateStiffness {
    fn eq(&self, other: &Self) -> bool {
        (self.coordinate, &self.formula, self.added_compliance, self.compliance_factor)
            == (other.coordinate, &other.formula, other.added_compliance, other.compliance_factor)
    }
}

impl CoordinateStiffness {
    /// The compliance at `coords`; NaN where the formula gives no positive finite stiffness there.
    pub fn compliance(&self, coords: &Coordinates) -> f64 {
        let q = coords.actuated.get(self.coordinate).copied().unwrap_or(0.0);
        let k = self.stiffness.eval(&[q]);
        let c = (1.0 / k + self.added_compliance) * self.compliance_factor;
        if k > 0.0 && c.is_finite() && c > 0.0 {
            c
        } else {
            f64::NAN
        }
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

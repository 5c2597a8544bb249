//! The 6-dof spring of a parallelogram link (paper 001 eq 22, s. 4.2; paper 000 s. 6), derived in code: the
//! parallelogram is split into its two bars, each a serial chain (a passive revolute joint, the bar as a
//! clamped-free beam, a passive revolute joint) from the base side to the end side, and the two chains'
//! stiffnesses (paper 001 eq 9) are summed at the end side. The sum leaves free exactly the parallelogram's
//! own motion (the end side translating across the bars), which the chain carrying this spring gives back as
//! its passive joint pair Rz(q) ... Rz(-q); a stiffness along that motion is added only to make the spring
//! invertible, and cancels out of every result (tested). The spring depends on the parallelogram angle q.

use super::spring::{push_six_dof, SpringGroup};
use super::stiffness::{leg_stiffness, passive_range, spring_compliance_at_end};
use crate::beam::{beam_compliance, BeamSection};
use crate::kinematics::chain::{Chain, ChainJacobians, Coordinates, Element, Joint, JointKind, Role};
use crate::kinematics::frame::{rotation_about, Frame, Mat6, Vec3, Vec6};

/// A parallelogram whose bars turn about the local z axis by the angle of passive coordinate `angle`, bars
/// along local x at angle 0, separated along local y.
#[derive(Clone, Debug, PartialEq)]
pub struct Parallelogram {
    /// Each bar's section (round bars: both alike).
    pub bar: BeamSection,
    /// Bar length, mm.
    pub length: f64,
    /// Distance between the bars, mm.
    pub separation: f64,
    /// Index of the passive coordinate that is the parallelogram angle.
    pub angle: usize,
    /// Factor on the compliance derived from the bars (1 as built; `SpringGroup::scale_compliance` changes
    /// it, so a scaling reaches every posture).
    pub compliance_factor: f64,
}

impl Parallelogram {
    /// The stiffness of the parallelogram at its end side (frame with the base side's axes, at the middle of
    /// the end side), for parallelogram angle `q` (rad). None where the bars give no finite stiffness
    /// (parameters at the edge of doubles: a modulus of 5e-324, a length of 1e300, a gap of 4e9 mm).
    pub fn stiffness(&self, q: f64) -> Option<Mat6> {
        let bar_dir = Vec3::new(q.cos(), q.sin(), 0.0);
        let compliance = beam_compliance(&self.bar, self.length, &Vec3::x());
        let stiffness = compliance.try_inverse().filter(|k| k.iter().all(|v| v.is_finite()))?;
        let spring = SpringGroup {
            name: "bar".into(),
            actuator: false,
            first: 0,
            dim: 6,
            stiffness,
            compliance,
            posture: None,
            beam_axis: None,
        };
        let mut total = Mat6::zeros();
        for side in [-0.5, 0.5] {
            let offset = Vec3::new(0.0, side * self.separation, 0.0);
            let z = Vec3::z();
            let mut elements = vec![
                Element::Fixed(Frame::translation(offset - bar_dir * self.length)),
                Element::Joint(Joint { kind: JointKind::Revolute, axis: z, role: Role::Passive, index: 0, gain: 1.0 }),
                Element::Fixed(Frame::new(rotation_about(&z, q), Vec3::zeros())),
                Element::Fixed(Frame::translation(Vec3::new(self.length, 0.0, 0.0))),
            ];
            push_six_dof(&mut elements, 0);
            elements.push(Element::Joint(Joint {
                kind: JointKind::Revolute,
                axis: z,
                role: Role::Passive,
                index: 1,
                gain: 1.0,
            }));
            elements.push(Element::Fixed(Frame::new(rotation_about(&z, -q), Vec3::zeros())));
            elements.push(Element::Fixed(Frame::translation(-offset)));
            let chain = Chain::new(elements);
            let mut j = ChainJacobians::default();
            chain.evaluate(&Coordinates::zeros(&chain), &mut j);
            j.fill_virtual();
            let s = spring_compliance_at_end(&j.virtual_, std::slice::from_ref(&spring), &[]);
            total += leg_stiffness(&s, &passive_range(&j.passive, self.length))?;
        }
        // The parallelogram's own motion: the end side translating across the bars, without turning.
        let motion = Vec6::new(-q.sin(), q.cos(), 0.0, 0.0, 0.0, 0.0);
        let scale = total.trace() / 6.0;
        total += motion * motion.transpose() * scale;
        Some((total + total.transpose()) * (0.5 / self.compliance_factor)).filter(|k| k.iter().all(|v| v.is_finite()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Parallelogram {
        Parallelogram {
            bar: BeamSection::round(210000.0, 80769.0, 8.5),
            length: 310.25,
            separation: 196.0,
            angle: 0,
            compliance_factor: 1.0,
        }
    }

    /// At angle 0 the bars run along x, pinned at both ends in the plane: the end side resists a pull along
    /// x by both bars' axial stiffness, 2 E A / L, and a turn about z by their opposite stretching,
    /// E A s^2 / (2 L), without coupling (symmetry).
    #[test]
    fn axial_and_in_plane_rotational_stiffness_match_closed_forms() {
        let p = sample();
        let k = p.stiffness(0.0).unwrap();
        let ea_l = p.bar.e * p.bar.area / p.length;
        assert!((k[(0, 0)] - 2.0 * ea_l).abs() < 1e-9 * k[(0, 0)], "{}", k[(0, 0)]);
        let krz = ea_l * p.separation * p.separation / 2.0;
        assert!((k[(5, 5)] - krz).abs() < 1e-9 * krz, "{} vs {krz}", k[(5, 5)]);
        assert!(k[(0, 5)].abs() < 1e-9 * (k[(0, 0)] * k[(5, 5)]).sqrt());
    }

    /// The stiffness added along the parallelogram's own motion (only to make the spring invertible) does
    /// not reach the chain that carries the spring: with the passive pair Rz(q) Tx(L) Rz(-q) in front of it,
    /// the chain's stiffness is the same whatever that added stiffness.
    #[test]
    fn the_regularising_stiffness_cancels_in_the_chain() {
        let p = sample();
        let q = 0.3;
        let leg = |k: Mat6| {
            let c = k.try_inverse().unwrap();
            let spring = SpringGroup {
                name: "p".into(),
                actuator: false,
                first: 0,
                dim: 6,
                stiffness: k,
                compliance: c,
                posture: None,
                beam_axis: None,
            };
            let z = Vec3::z();
            let mut elements = vec![
                Element::Joint(Joint { kind: JointKind::Revolute, axis: z, role: Role::Passive, index: 0, gain: 1.0 }),
                Element::Fixed(Frame::translation(Vec3::new(p.length, 0.0, 0.0))),
                Element::Joint(Joint { kind: JointKind::Revolute, axis: z, role: Role::Passive, index: 0, gain: -1.0 }),
            ];
            push_six_dof(&mut elements, 0);
            elements.push(Element::Fixed(Frame::translation(Vec3::new(30.0, 5.0, -2.0))));
            let chain = Chain::new(elements);
            let mut coords = Coordinates::zeros(&chain);
            coords.passive[0] = q;
            let mut j = ChainJacobians::default();
            chain.evaluate(&coords, &mut j);
            j.fill_virtual();
            let s = spring_compliance_at_end(&j.virtual_, std::slice::from_ref(&spring), &[]);
            leg_stiffness(&s, &passive_range(&j.passive, 300.0)).unwrap()
        };
        let k = p.stiffness(q).unwrap();
        let motion = Vec6::new(-q.sin(), q.cos(), 0.0, 0.0, 0.0, 0.0);
        let a = leg(k);
        let b = leg(k + motion * motion.transpose() * 1e3 * k.trace());
        assert!((a - b).abs().max() < 1e-9 * a.abs().max(), "{a}\n{b}");
    }
}

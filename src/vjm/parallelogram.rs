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
use crate::kinematics::frame::{block_rotation, rotation_about, shift_stiffness, Frame, Mat6, Vec3, Vec6};

/// A parallelogram whose bars turn about the local z axis by the angle of passive coordinate `angle`, bars
/// along local x at angle 0, separated along local y.
#[derive(Clone, Debug, PartialEq)]
pub struct Parallelogram {
    /// Each bar's section (round bars: both alike).
    bar: BeamSection,
    /// Bar length, mm.
    length: f64,
    /// Distance between the bars, mm.
    separation: f64,
    /// Index of the passive coordinate that is the parallelogram angle.
    pub angle: usize,
    /// Factor on the compliance derived from the bars (1 as built; `SpringGroup::scale_compliance` changes
    /// it, so a scaling reaches every posture).
    pub compliance_factor: f64,
    /// One bar pinned at both ends, its stiffness at its end pin (None: not finite), derived once.
    pinned_bar: Option<Mat6>,
}

impl Parallelogram {
    /// The parallelogram of two bars of this section and length, `separation` apart (mm), its angle the
    /// passive coordinate `angle`.
    pub fn new(bar: BeamSection, length: f64, separation: f64, angle: usize) -> Parallelogram {
        let pinned_bar = pinned_bar(&bar, length);
        let mut p = Parallelogram { bar, length, separation, angle, compliance_factor: 1.0, pinned_bar };
        // The turned bar checked once against the derivation from scratch: parameters at the edge of
        // doubles (a gap of 4e9 mm, a modulus of 5e-324) fail the derivation or disagree with it, and the
        // spring then has no stiffness (the description is refused).
        let agrees = p
            .stiffness(0.0)
            .zip(p.derived_at(0.0))
            .is_some_and(|(fast, derived)| (fast - derived).amax() <= AGREEMENT * derived.amax());
        if !agrees {
            p.pinned_bar = None;
        }
        p
    }

    /// The stiffness at angle q derived from scratch, as paper 001 s. 4.2 builds it: each bar's chain (pin,
    /// bar, pin) placed at its angle and side, eq (9) at the middle of the end side, the two summed, the
    /// parallelogram's own motion stiffened as in `stiffness`. None where eq (9) has no answer.
    pub fn derived_at(&self, q: f64) -> Option<Mat6> {
        let compliance = beam_compliance(&self.bar, self.length, &Vec3::x());
        let spring = bar_spring(compliance)?;
        let (z, bar_dir) = (Vec3::z(), Vec3::new(q.cos(), q.sin(), 0.0));
        let mut total = Mat6::zeros();
        for side in [-0.5, 0.5] {
            let offset = Vec3::new(0.0, side * self.separation, 0.0);
            let mut elements = vec![
                Element::Fixed(Frame::translation(offset - bar_dir * self.length)),
                pin(0),
                Element::Fixed(Frame::new(rotation_about(&z, q), Vec3::zeros())),
                Element::Fixed(Frame::translation(Vec3::new(self.length, 0.0, 0.0))),
            ];
            push_six_dof(&mut elements, 0);
            elements.push(pin(1));
            elements.push(Element::Fixed(Frame::new(rotation_about(&z, -q), Vec3::zeros())));
            elements.push(Element::Fixed(Frame::translation(-offset)));
            total += chain_stiffness(elements, &spring, self.length)?;
        }
        let motion = Vec6::new(-q.sin(), q.cos(), 0.0, 0.0, 0.0, 0.0);
        total += motion * motion.transpose() * (total.trace() / 6.0);
        Some((total + total.transpose()) * (0.5 / self.compliance_factor)).filter(|k| k.iter().all(|v| v.is_finite()))
    }

    /// The stiffness of the parallelogram at its end side (frame with the base side's axes, at the middle of
    /// the end side), for parallelogram angle `q` (rad). None where the bars give no finite stiffness
    /// (parameters at the edge of doubles: a modulus of 5e-324, a length of 1e300, a gap of 4e9 mm).
    ///
    /// Each bar with its two pins is the bar of `pinned_bar` turned by q about z (a rigid copy), its end pin
    /// at (0, +-separation/2, 0): its stiffness turned, then moved to the middle of the end side (paper 000
    /// eq 54-55), and the two summed (paper 001 eq 22).
    pub fn stiffness(&self, q: f64) -> Option<Mat6> {
        let r = block_rotation(&rotation_about(&Vec3::z(), q));
        let turned = r * self.pinned_bar? * r.transpose();
        let mut total = Mat6::zeros();
        for side in [-0.5, 0.5] {
            total += shift_stiffness(&turned, &Vec3::new(0.0, side * self.separation, 0.0));
        }
        // The parallelogram's own motion: the end side translating across the bars, without turning.
        let motion = Vec6::new(-q.sin(), q.cos(), 0.0, 0.0, 0.0, 0.0);
        let scale = total.trace() / 6.0;
        total += motion * motion.transpose() * scale;
        Some((total + total.transpose()) * (0.5 / self.compliance_factor)).filter(|k| k.iter().all(|v| v.is_finite()))
    }
}

/// The turned bar and the derivation from scratch agree to this share of the stiffness' largest entry
/// (both are eq 9 to round-off: the unit test holds them to 1e-10 from -70 to 80 degrees).
const AGREEMENT: f64 = 1e-8;

/// A bar along x pinned about z at both ends (a passive revolute joint, the bar as a clamped-free beam, a
/// passive revolute joint): the stiffness of this chain at its end pin, paper 001 eq (9). It is singular
/// along the two motions the pins allow (a turn about the end pin, a swing about the first).
fn pinned_bar(bar: &BeamSection, length: f64) -> Option<Mat6> {
    let spring = bar_spring(beam_compliance(bar, length, &Vec3::x()))?;
    let mut elements = vec![
        Element::Fixed(Frame::translation(Vec3::new(-length, 0.0, 0.0))),
        pin(0),
        Element::Fixed(Frame::translation(Vec3::new(length, 0.0, 0.0))),
    ];
    push_six_dof(&mut elements, 0);
    elements.push(pin(1));
    chain_stiffness(elements, &spring, length)
}

/// A bar's 6-dof spring from its compliance; None where it has no finite stiffness.
fn bar_spring(compliance: Mat6) -> Option<SpringGroup> {
    let stiffness = compliance.try_inverse().filter(|k| k.iter().all(|v| v.is_finite()))?;
    Some(SpringGroup {
        name: "bar".into(),
        actuator: false,
        first: 0,
        dim: 6,
        stiffness,
        compliance,
        posture: None,
        beam_axis: None,
    })
}

/// A passive revolute joint about z, coordinate `index`.
fn pin(index: usize) -> Element {
    Element::Joint(Joint { kind: JointKind::Revolute, axis: Vec3::z(), role: Role::Passive, index, gain: 1.0 })
}

/// Eq (9) for a chain of fixed transforms, pins and one bar spring, at its zero coordinates.
fn chain_stiffness(elements: Vec<Element>, spring: &SpringGroup, length: f64) -> Option<Mat6> {
    let chain = Chain::new(elements);
    let mut j = ChainJacobians::default();
    chain.evaluate(&Coordinates::zeros(&chain), &mut j);
    j.fill_virtual();
    let s = spring_compliance_at_end(&j.virtual_, std::slice::from_ref(spring), &[]);
    leg_stiffness(&s, &passive_range(&j.passive, length))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Parallelogram {
        Parallelogram::new(BeamSection::round(210000.0, 80769.0, 8.5), 310.25, 196.0, 0)
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

    /// Physics: a bar with its pins at angle q is a rigid copy of the bar at angle 0 turned about z, so
    /// turning one pinned bar's stiffness and moving it to the end side's middle gives what deriving both
    /// bars' chains at q gives (the derivation the spring did at every posture before it was done once).
    #[test]
    fn the_turned_pinned_bar_equals_both_bars_derived_at_the_angle() {
        let p = sample();
        for q in [-1.2, -0.4, 0.0, 0.25, 0.7, 1.4] {
            let (fast, derived) = (p.stiffness(q).unwrap(), p.derived_at(q).unwrap());
            assert!((fast - derived).amax() < 1e-10 * derived.amax(), "q = {q}\n{fast}\n{derived}");
        }
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

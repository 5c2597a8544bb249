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
use crate::kinematics::frame::{block_rotation, rotation_about, shift_stiffness, Frame, Mat3, Mat6, Vec3, Vec6};
use crate::linalg::all_finite;

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
    /// Both bars' stiffness at the middle of the end side as a polynomial in the angle's cosine c and
    /// sine s, the coefficients of (1, c, s, c^2, s^2, c s) (None: not finite), derived once.
    expansion: Option<[Mat6; 6]>,
}

impl Parallelogram {
    /// The parallelogram of two bars of this section and length, `separation` apart (mm), its angle the
    /// passive coordinate `angle`.
    pub fn new(bar: BeamSection, length: f64, separation: f64, angle: usize) -> Parallelogram {
        let expansion = pinned_bar(&bar, length).map(|k| expansion(&k, separation));
        let mut p = Parallelogram { bar, length, separation, angle, compliance_factor: 1.0, expansion };
        // The turned bar checked once against the derivation from scratch: parameters at the edge of
        // doubles (a gap of 4e9 mm, a modulus of 5e-324) fail the derivation or disagree with it, and the
        // spring then has no stiffness (the description is refused).
        let agrees = p
            .stiffness(0.0)
            .zip(p.derived_at(0.0))
            .is_some_and(|(fast, derived)| (fast - derived).amax() <= AGREEMENT * derived.amax());
        if !agrees {
            p.expansion = None;
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
        Some((total + total.transpose()) * (0.5 / self.compliance_factor)).filter(|k| all_finite(k.as_slice()))
    }

    /// The stiffness of the parallelogram at its end side (frame with the base side's axes, at the middle of
    /// the end side), for parallelogram angle `q` (rad). None where the bars give no finite stiffness
    /// (parameters at the edge of doubles: a modulus of 5e-324, a length of 1e300, a gap of 4e9 mm).
    ///
    /// Each bar with its two pins is the bar of `pinned_bar` turned by q about z (a rigid copy), its end pin
    /// at (0, +-separation/2, 0): its stiffness turned, then moved to the middle of the end side (paper 000
    /// eq 54-55), and the two summed (paper 001 eq 22); `expansion` holds that sum as a polynomial in
    /// cos q and sin q.
    pub fn stiffness(&self, q: f64) -> Option<Mat6> {
        self.series::<1>(q).map(|[k]| k)
    }

    /// The stiffness at angle q and its first and second derivatives in q, exact: the polynomial in
    /// (cos q, sin q) of `expansion` differentiated term by term, and the product rule on the stiffness
    /// added along the parallelogram's own motion (its scale follows the bars' trace).
    pub fn stiffness_derivatives(&self, q: f64) -> Option<[Mat6; 3]> {
        self.series::<3>(q)
    }

    /// The stiffness and its first N - 1 derivatives in q (N at most 3).
    fn series<const N: usize>(&self, q: f64) -> Option<[Mat6; N]> {
        let (s, c) = q.sin_cos();
        let terms = self.expansion.as_ref()?;
        let factors = [
            [1.0, c, s, c * c, s * s, c * s],
            [0.0, -s, c, -2.0 * c * s, 2.0 * c * s, c * c - s * s],
            [0.0, -c, -s, 2.0 * (s * s - c * c), 2.0 * (c * c - s * s), -4.0 * c * s],
        ];
        let bars: [Mat6; N] = std::array::from_fn(|order| {
            let mut sum = Mat6::zeros();
            for (term, factor) in terms.iter().zip(&factors[order]) {
                sum += term * *factor;
            }
            sum
        });
        // The parallelogram's own motion m (the end side translating across the bars, without turning),
        // stiffened by a scale of the bars' trace: dm/dq = m1, d2m/dq2 = -m.
        let m = Vec6::new(-s, c, 0.0, 0.0, 0.0, 0.0);
        let m1 = Vec6::new(-c, -s, 0.0, 0.0, 0.0, 0.0);
        let scale: [f64; N] = std::array::from_fn(|order| bars[order].trace() / 6.0);
        let mm = m * m.transpose();
        let mixed = || m1 * m.transpose() + m * m1.transpose();
        let out: [Mat6; N] = std::array::from_fn(|order| {
            let motion = match order {
                0 => mm * scale[0],
                1 => mm * scale[1] + mixed() * scale[0],
                _ => mm * scale[2] + mixed() * (2.0 * scale[1]) + (m1 * m1.transpose() - mm) * (2.0 * scale[0]),
            };
            let total = bars[order] + motion;
            (total + total.transpose()) * (0.5 / self.compliance_factor)
        });
        out.iter().all(|k| all_finite(k.as_slice())).then_some(out)
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

/// The pinned bar turned by q about z and moved to both pins, summed, as a polynomial in c = cos q and
/// s = sin q. The block rotation is `B(q) = B0 + c Bc + s Bs` (Rz(q) = z z^T + c (x x^T + y y^T) + s (y x^T -
/// x y^T) in both blocks), so `B K B^T` is quadratic in (c, s), and moving a stiffness to a point
/// (`A^T K A`) is linear: the coefficients of (1, c, s, c^2, s^2, c s) follow term by term.
fn expansion(pinned: &Mat6, separation: f64) -> [Mat6; 6] {
    let block = |m: [[f64; 3]; 3]| block_rotation(&Mat3::from_fn(|i, j| m[i][j]));
    let b0 = block([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
    let bc = block([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]]);
    let bs = block([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]);
    let product = |a: &Mat6, b: &Mat6| a * pinned * b.transpose();
    let turned = [
        product(&b0, &b0),
        product(&bc, &b0) + product(&b0, &bc),
        product(&bs, &b0) + product(&b0, &bs),
        product(&bc, &bc),
        product(&bs, &bs),
        product(&bc, &bs) + product(&bs, &bc),
    ];
    turned.map(|t| [-0.5, 0.5].iter().map(|side| shift_stiffness(&t, &Vec3::new(0.0, side * separation, 0.0))).sum())
}

/// A bar's 6-dof spring from its compliance; None where it has no finite stiffness.
fn bar_spring(compliance: Mat6) -> Option<SpringGroup> {
    let stiffness = compliance.try_inverse().filter(|k| all_finite(k.as_slice()))?;
    Some(SpringGroup {
        name: "bar".into(),
        actuator: false,
        first: 0,
        dim: 6,
        stiffness,
        compliance,
        posture: None,
        of_coordinate: None,
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
    let s = spring_compliance_at_end(&j.virtual_, std::slice::from_ref(spring), &Default::default());
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

    /// The exact derivatives of the stiffness in the angle against central differences of the stiffness
    /// itself: K' to 1e-9 (step 1e-5: truncation h^2/6 times the third derivative, ~1e-11 of K; round-off
    /// eps/h ~ 2e-11), K'' to 2e-8 (second differences at steps 1e-3 and 5e-4, Richardson-extrapolated:
    /// truncation O(h^4), round-off ~ eps/h^2 ~ 1e-9).
    #[test]
    fn stiffness_derivatives_match_differences() {
        let p = sample();
        for q in [-1.2, -0.4, 0.0, 0.25, 0.7, 1.4] {
            let [k, k1, k2] = p.stiffness_derivatives(q).unwrap();
            let at = |q: f64| p.stiffness(q).unwrap();
            assert_eq!(k, at(q));
            let h = 1e-5;
            let d1 = (at(q + h) - at(q - h)) / (2.0 * h);
            assert!((k1 - d1).amax() < 1e-9 * k.amax(), "q = {q}\n{k1}\n{d1}");
            let second = |h: f64| (at(q + h) - k * 2.0 + at(q - h)) / (h * h);
            let d2 = (second(5e-4) * 4.0 - second(1e-3)) / 3.0;
            assert!((k2 - d2).amax() < 2e-8 * k.amax(), "q = {q}\n{k2}\n{d2}");
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
                of_coordinate: None,
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
            let s = spring_compliance_at_end(&j.virtual_, std::slice::from_ref(&spring), &Default::default());
            leg_stiffness(&s, &passive_range(&j.passive, 300.0)).unwrap()
        };
        let k = p.stiffness(q).unwrap();
        let motion = Vec6::new(-q.sin(), q.cos(), 0.0, 0.0, 0.0, 0.0);
        let a = leg(k);
        let b = leg(k + motion * motion.transpose() * 1e3 * k.trace());
        assert!((a - b).abs().max() < 1e-9 * a.abs().max(), "{a}\n{b}");
    }
}

//! Straight beams: cross-section, material and the compliance of a clamped-free beam (Euler-Bernoulli) and its
//! inverse, shared by VJM link springs (paper 001 s. 4.2) and MSA flexible links (paper 003 eq 3).

use crate::kinematics::frame::{block_rotation, Mat3, Mat6, Vec3};

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
    /// Second moment of area about the section's z axis, mm^4.
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

/// The inverse of `cantilever_compliance`: the stiffness at the free end with the other clamped, in closed
/// form (each bending pair [[l^3/3EI, +-l^2/2EI], [+-l^2/2EI, l/EI]] inverts to
/// [[12EI/l^3, -+6EI/l^2], [-+6EI/l^2, 4EI/l]]).
pub fn cantilever_stiffness(s: &BeamSection, l: f64) -> Mat6 {
    let (eiy, eiz) = (s.e * s.iy, s.e * s.iz);
    let mut k = Mat6::zeros();
    k[(0, 0)] = s.e * s.area / l;
    k[(1, 1)] = 12.0 * eiz / l.powi(3);
    k[(2, 2)] = 12.0 * eiy / l.powi(3);
    k[(3, 3)] = s.g * s.j / l;
    k[(4, 4)] = 4.0 * eiy / l;
    k[(5, 5)] = 4.0 * eiz / l;
    k[(1, 5)] = -6.0 * eiz / (l * l);
    k[(5, 1)] = k[(1, 5)];
    k[(2, 4)] = 6.0 * eiy / (l * l);
    k[(4, 2)] = k[(2, 4)];
    k
}

/// `cantilever_stiffness` turned into the frame whose columns are the beam's x, y, z axes:
/// `B K B^T` with B = `block_rotation(frame)`. Each 3x3 block of the local stiffness is diagonal or holds
/// two entries, so each turned block is a sum of outer products of the frame's axes, about a third of the
/// dense 6x6 products' work (an MSA beam is turned at every pose).
pub fn turned_cantilever_stiffness(s: &BeamSection, l: f64, frame: &Mat3) -> Mat6 {
    let k = cantilever_stiffness(s, l);
    let axes = [frame.column(0).into_owned(), frame.column(1).into_owned(), frame.column(2).into_owned()];
    let outer = |u: &Vec3, v: &Vec3| u * v.transpose();
    let (mut forces, mut moments) = (Mat3::zeros(), Mat3::zeros());
    for (i, a) in axes.iter().enumerate() {
        let aa = outer(a, a);
        forces += aa * k[(i, i)];
        moments += aa * k[(3 + i, 3 + i)];
    }
    // The couplings: a lateral force along y with a moment about z, along z with a moment about y.
    let coupling = outer(&axes[1], &axes[2]) * k[(1, 5)] + outer(&axes[2], &axes[1]) * k[(2, 4)];
    let mut turned = Mat6::zeros();
    turned.fixed_view_mut::<3, 3>(0, 0).copy_from(&forces);
    turned.fixed_view_mut::<3, 3>(0, 3).copy_from(&coupling);
    turned.fixed_view_mut::<3, 3>(3, 0).copy_from(&coupling.transpose());
    turned.fixed_view_mut::<3, 3>(3, 3).copy_from(&moments);
    turned
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
    fn the_closed_form_stiffness_inverts_the_compliance() {
        let s = BeamSection { e: 2e5, g: 8e4, area: 100.0, iy: 900.0, iz: 400.0, j: 1300.0 };
        for l in [0.5, 30.0, 250.0, 4000.0] {
            let product = cantilever_stiffness(&s, l) * cantilever_compliance(&s, l);
            assert!((product - Mat6::identity()).amax() < 1e-12, "l = {l}: {product}");
        }
    }

    #[test]
    fn cantilever_compliance_is_symmetric_positive_definite() {
        let s = BeamSection::round(210000.0, 80769.0, 12.0);
        let c = cantilever_compliance(&s, 300.0);
        assert_eq!(c, c.transpose());
        assert!(c.cholesky().is_some());
    }

    /// The turned stiffness by outer products equals the dense product B K B^T, for sections with
    /// Iy != Iz in frames of every orientation.
    #[test]
    fn turned_stiffness_equals_the_dense_product() {
        let s = BeamSection { e: 2e5, g: 8e4, area: 100.0, iy: 900.0, iz: 400.0, j: 1300.0 };
        for (k, d) in
            [Vec3::new(3.0, 0.0, 0.0), Vec3::new(1.0, -2.0, 0.5), Vec3::new(0.0, 0.1, -4.0)].iter().enumerate()
        {
            let frame = frame_along(d);
            let b = block_rotation(&frame);
            let dense = b * cantilever_stiffness(&s, 120.0 + 50.0 * k as f64) * b.transpose();
            let turned = turned_cantilever_stiffness(&s, 120.0 + 50.0 * k as f64, &frame);
            assert!((dense - turned).amax() < 1e-13 * dense.amax(), "{d}: {dense}\n{turned}");
        }
    }

    #[test]
    fn beam_along_x_keeps_the_local_compliance() {
        let s = BeamSection { e: 2e5, g: 8e4, area: 100.0, iy: 900.0, iz: 400.0, j: 1300.0 };
        let c0 = cantilever_compliance(&s, 250.0);
        let c1 = beam_compliance(&s, 250.0, &Vec3::new(3.0, 0.0, 0.0));
        assert!((c0 - c1).abs().max() < 1e-15 * c0.abs().max());
    }
}

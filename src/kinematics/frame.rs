//! Rigid frames, rotation vectors and the small linear-algebra vocabulary of the engine.
//!
//! Conventions (ARCHITECTURE.md): lengths in mm, angles in rad. A small displacement or a pose error is
//! (x, y, z, rx, ry, rz): translation first, then a rotation vector expressed in the base frame.

use nalgebra::{Matrix3, Matrix6, Rotation3, Unit, Vector3, Vector6};

/// A 3-vector (mm, rad, N, N mm).
pub type Vec3 = Vector3<f64>;
/// A 3x3 matrix.
pub type Mat3 = Matrix3<f64>;
/// A twist (dx, dy, dz, rx, ry, rz) or a wrench (Fx, Fy, Fz, Mx, My, Mz).
pub type Vec6 = Vector6<f64>;
/// A 6x6 matrix (stiffness, compliance, Jacobian blocks).
pub type Mat6 = Matrix6<f64>;

/// A rigid transform: `p_world = rot * p_local + pos`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Orientation.
    pub rot: Mat3,
    /// Position, mm.
    pub pos: Vec3,
}

impl Default for Frame {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Frame {
    /// The identity.
    pub const IDENTITY: Frame =
        Frame { rot: Mat3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), pos: Vec3::new(0.0, 0.0, 0.0) };

    /// A frame from its orientation and position.
    pub fn new(rot: Mat3, pos: Vec3) -> Self {
        Self { rot, pos }
    }

    /// A pure translation.
    pub fn translation(pos: Vec3) -> Self {
        Self { rot: Mat3::identity(), pos }
    }

    /// A pure rotation.
    pub fn rotation(rot: Mat3) -> Self {
        Self { rot, pos: Vec3::zeros() }
    }

    /// A pose from a position and a rotation vector (axis times angle, rad).
    pub fn from_position_rotvec(pos: Vec3, rotvec: Vec3) -> Self {
        Self { rot: rotation_from_vector(&rotvec), pos }
    }

    /// `self * other`: express `other` (given in self's local frame) in self's parent frame.
    #[inline]
    pub fn compose(&self, other: &Frame) -> Frame {
        Frame { rot: self.rot * other.rot, pos: self.pos + self.rot * other.pos }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Frame {
        let rt = self.rot.transpose();
        Frame { rot: rt, pos: -(rt * self.pos) }
    }

    /// A point given in this frame, in the parent frame.
    #[inline]
    pub fn transform_point(&self, p: &Vec3) -> Vec3 {
        self.pos + self.rot * p
    }

    /// The small displacement (translation, base-frame rotation vector) that carries `self` to `target`.
    pub fn error_to(&self, target: &Frame) -> Vec6 {
        let dp = target.pos - self.pos;
        let dr = rotation_vector(&(target.rot * self.rot.transpose()));
        Vec6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
    }
}

/// A small displacement (or wrench) with its rotational part multiplied by `factor`: with a length scale
/// l (mm/rad), `weigh_rotations(t, l)` puts a twist's rotations in mm, so that a norm or a rank decision
/// compares mm with rad fairly.
#[inline]
pub fn weigh_rotations(v: &Vec6, factor: f64) -> Vec6 {
    Vec6::new(v[0], v[1], v[2], v[3] * factor, v[4] * factor, v[5] * factor)
}

/// Rotation about a unit axis by an angle (Rodrigues).
pub fn rotation_about(axis: &Vec3, angle: f64) -> Mat3 {
    Rotation3::from_axis_angle(&Unit::new_unchecked(*axis), angle).into_inner()
}

/// The rotation whose rotation vector is `v` (exponential map).
pub fn rotation_from_vector(v: &Vec3) -> Mat3 {
    Rotation3::new(*v).into_inner()
}

/// The rotation vector of `r` (logarithm map), angle in [0, pi]. The angle comes from atan2 of the sine
/// and cosine parts, accurate to round-off for small rotations (an acos of the trace is not: it loses half
/// the digits, enough to stall a Newton solve).
pub fn rotation_vector(r: &Mat3) -> Vec3 {
    let v = Vec3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)]) * 0.5;
    let sin = v.norm();
    let cos = (r.trace() - 1.0) * 0.5;
    let angle = sin.atan2(cos);
    if cos > -0.9 {
        // sin(angle) * axis = v
        return if sin < 1e-300 { v } else { v * (angle / sin) };
    }
    // Near pi the antisymmetric part vanishes: take the axis from the symmetric part (1 - cos) a a^T.
    let b = (r + r.transpose()) * 0.5 - Mat3::identity() * cos;
    let k = (0..3).max_by(|&i, &j| b[(i, i)].total_cmp(&b[(j, j)])).unwrap();
    let mut axis: Vec3 = b.column(k).into();
    axis /= axis.norm();
    if axis.dot(&v) < 0.0 {
        axis = -axis;
    }
    axis * angle
}

/// The skew-symmetric matrix `[v]x` with `[v]x w = v x w` (paper 000 eq 56).
pub fn skew(v: &Vec3) -> Mat3 {
    Mat3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// `diag(R, R)`: maps a 6-vector (twist or wrench) from a rotated frame to the base frame (paper 000 eq 53).
pub fn block_rotation(r: &Mat3) -> Mat6 {
    let mut m = Mat6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(r);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(r);
    m
}

/// The map from a platform twist at a reference point RP to the twist of a point EP of the same rigid
/// body, with `v = EP - RP`: `dt_EP = A dt_RP`, `A = [[I, -[v]x], [0, I]]` (paper 000 eq 55, with the sign of
/// v corrected as in tests/reference/README.md: v runs from the reference point to the leg's end point).
pub fn point_shift(v: &Vec3) -> Mat6 {
    let mut a = Mat6::identity();
    a.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-skew(v)));
    a
}

/// The diagonal of the entrywise bound `|A|^T |K| |A|` of `shift_stiffness(k, v)`'s terms: the size of what
/// the shift adds and subtracts on each diagonal entry, against which one that cancelled to round-off is
/// recognised (a Stewart-Gough leg whose line passes through the vertical axis has a zero rz stiffness
/// that comes out as 1e-14).
pub fn shift_magnitude(k: &Mat6, v: &Vec3) -> Vec6 {
    let s = skew(v).abs();
    let mut out = Vec6::zeros();
    for i in 0..3 {
        out[i] = k[(i, i)].abs();
        // (S |K11| S + S |K12| + |K21| S + |K22|)_ii, S = |[v]x| symmetric.
        let mut sum = k[(3 + i, 3 + i)].abs();
        for a in 0..3 {
            let sa = s[(i, a)];
            if sa == 0.0 {
                continue;
            }
            sum += sa * (k[(a, 3 + i)].abs() + k[(3 + i, a)].abs());
            for b in 0..3 {
                sum += sa * k[(a, b)].abs() * s[(b, i)];
            }
        }
        out[3 + i] = sum;
    }
    out
}

/// A stiffness matrix moved from a body point EP to the point RP of the same rigid body: `A^T K A` with
/// `A = point_shift(v)`, `v = EP - RP` (paper 000 eq 54-55), by 3x3 blocks.
pub fn shift_stiffness(k: &Mat6, v: &Vec3) -> Mat6 {
    if *v == Vec3::zeros() {
        return *k;
    }
    let s = skew(v);
    let k11: Mat3 = k.fixed_view::<3, 3>(0, 0).into();
    let k12: Mat3 = k.fixed_view::<3, 3>(0, 3).into();
    let k21: Mat3 = k.fixed_view::<3, 3>(3, 0).into();
    let k22: Mat3 = k.fixed_view::<3, 3>(3, 3).into();
    let top_right = k12 - k11 * s;
    let mut out = Mat6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&k11);
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&top_right);
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&(s * k11 + k21));
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&(s * top_right + k22 - k21 * s));
    out
}

/// The frame a fraction `a` of the way along the twist `delta` from `start` (rotation about a fixed axis).
pub fn interpolate(start: &Frame, delta: &Vec6, a: f64) -> Frame {
    apply_twist(start, &(delta * a))
}

/// `start` moved by a small displacement (translation, base-frame rotation vector): the inverse of
/// `Frame::error_to`.
pub fn apply_twist(start: &Frame, d: &Vec6) -> Frame {
    let r = rotation_from_vector(&Vec3::new(d[3], d[4], d[5]));
    Frame::new(r * start.rot, start.pos + Vec3::new(d[0], d[1], d[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_vector_round_trip() {
        for v in [
            Vec3::new(0.3, -0.2, 0.7),
            Vec3::new(1e-9, -3e-9, 2e-9),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 2.0, -2.0).normalize() * 3.1,
            Vec3::new(-1.0, 0.5, 0.2).normalize() * (std::f64::consts::PI - 1e-7),
        ] {
            let back = rotation_vector(&rotation_from_vector(&v));
            assert!(
                (back - v).norm() <= 1e-13 * v.norm().max(1e-300) + 1e-9 * (v.norm() > 3.0) as u8 as f64,
                "{v:?} -> {back:?}"
            );
        }
    }

    #[test]
    fn the_error_back_is_the_error_there_negated_exactly() {
        // The displacement carrying b to a undoes the one carrying a to b exactly: a translation's difference
        // negated, and the rotation vector of a transposed rotation (the same products, summed in the same
        // order; near pi the axis from the symmetric part takes the antisymmetric part's sign). The loaded
        // equilibrium reads the end's error from its residual's evaluation on this (`target_error`).
        let angles = [0.0, 1e-9, 0.3, 1.7, 2.9, std::f64::consts::PI - 1e-6];
        let axes = [Vec3::new(0.3, -0.2, 0.9), Vec3::new(-1.0, 0.5, 0.2), Vec3::new(0.0, 0.0, 1.0)];
        for (i, &angle) in angles.iter().enumerate() {
            for (j, axis) in axes.iter().enumerate() {
                let a = Frame {
                    pos: Vec3::new(1.5, -2.0, 300.0 + i as f64),
                    rot: rotation_from_vector(&(Vec3::new(0.2, 0.1, -0.4) * j as f64)),
                };
                let b = Frame {
                    pos: Vec3::new(-0.25, 7.0, 12.5 * j as f64),
                    rot: rotation_about(&axis.normalize(), angle) * a.rot,
                };
                let there = a.error_to(&b);
                let back = b.error_to(&a);
                for k in 0..6 {
                    // Exactly equal (a zero's sign aside, which `==` ignores and a norm does too).
                    assert_eq!(-there[k], back[k], "angle {angle}, axis {axis:?}: {there} {back}");
                }
            }
        }
    }

    #[test]
    fn shift_stiffness_equals_the_congruence_it_stands_for() {
        let k = Mat6::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 + if i == j { 20.0 } else { 0.0 });
        let k = k + k.transpose();
        let v = Vec3::new(0.3, -1.2, 2.5);
        let a = point_shift(&v);
        let expected = a.transpose() * k * a;
        assert!((shift_stiffness(&k, &v) - expected).abs().max() < 1e-12 * expected.abs().max());
    }

    #[test]
    fn point_shift_moves_a_rotation_about_rp_to_ep() {
        // A rotation w about RP moves EP = RP + v by w x v.
        let v = Vec3::new(1.0, 2.0, 3.0);
        let w = Vec3::new(0.1, -0.4, 0.2);
        let t = point_shift(&v) * Vec6::new(0.0, 0.0, 0.0, w.x, w.y, w.z);
        let expected = w.cross(&v);
        assert!((t.fixed_rows::<3>(0) - expected).norm() < 1e-15);
    }
}

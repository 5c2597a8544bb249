//! From the manipulator's stiffness to what a designer reads: compliance where K is invertible and well
//! conditioned, its rank and free directions where it is not, its condition figure, and the principal
//! compliances.
//!
//! Definiteness and conditioning are decided on the *equilibrated* stiffness: rotations weighted by the
//! model's length scale (every entry in N/mm), then scaled symmetrically to a unit diagonal. A diagonal
//! congruence changes neither the rank nor the signs of the eigenvalues (Sylvester's law of inertia), but it
//! makes the decisions independent of units and of springs written as "rigid" with huge numbers (a link
//! with E = 1e30 no longer hides the 2e4 N/mm of the others under a relative tolerance: well conditioned
//! after a diagonal scaling, K is regular). A diagonal entry is not scaled up where it is round-off: where
//! the legs' contributions cancelled to below `CANCELLATION_TOLERANCE` of their own size (`magnitude`, the
//! entrywise sum of |K_i|), as the free rotations of a singular Stewart-Gough platform do.
//!
//! Where the equilibrated stiffness is not regular, its rank and free directions are one decision on the
//! length-scaled stiffness alone (`rank_deficiency`), which no equilibration can move: equilibration
//! magnifies the round-off of small entries, and it hid a free direction.

use nalgebra::{SymmetricEigen, SVD};

use crate::kinematics::frame::{weigh_rotations, Mat3, Mat6, Vec6};
use crate::linalg::{all_finite, small_cholesky, MAX_ENTRY, MAX_SWEEPS};

/// Relative eigenvalue of the equilibrated stiffness's symmetric part at or below which it is not positive
/// definite: a few hundred times round-off.
pub const RANK_TOLERANCE: f64 = 1e-13;

/// Relative size, against the largest, of the length-scaled stiffness along a direction that is free
/// (`rank_deficiency`). A stiffness condensed from much stiffer parts carries round-off of about 1e-13 of
/// its largest singular value (a NaVARo II leg: entries cancelled from its beams' stiffness); a hundred times
/// that is free. Any direction resisted by less is a mechanism for every purpose: the condition limit calls
/// a point ill-conditioned five orders of magnitude earlier.
pub const FREE_DIRECTION_TOLERANCE: f64 = 1e-11;

/// A diagonal entry of the sum over legs smaller than this times the sum of its terms' sizes is round-off
/// (a few thousand times the unit round-off: the legs' own stiffnesses carry errors of that order).
pub const CANCELLATION_TOLERANCE: f64 = 1e-12;

/// Condition number of the equilibrated stiffness beyond which a point is `ill_conditioned`. The
/// compliance's relative error is about 1e-10 times the condition number (the model is evaluated to that
/// accuracy: inverse kinematics stops at 1e-9 of the length scale): the VJM and MSA descriptions of the
/// 3-PUU differ (largest compliance) by 7e-7 at condition 6.3e4 and 4e-5 at 3.1e5 near the reach boundary
/// on x, and by 1e-3 at 3.1e6.
/// Beyond 1e6 fewer than four digits of C can be trusted, so none are written.
pub const CONDITION_LIMIT: f64 = 1e6;

#[derive(Clone, Debug)]
// Returned by value once per point on the hot path of every map; boxing the 6x6 would allocate there.
/// What the analysis of K decides.
#[allow(clippy::large_enum_variant)]
pub enum Outcome {
    /// Full rank, condition within `CONDITION_LIMIT`: C = K^-1 (LU with pivoting; symmetrised where K is).
    Regular {
        /// C = K^-1.
        compliance: Mat6,
    },
    /// Full rank but beyond `CONDITION_LIMIT`: C would carry too few correct digits to be written.
    IllConditioned,
    /// Rank below 6; `free` holds unit twists (translation mm, rotation rad, scaled alike) K does not resist.
    Singular {
        /// The rank of K.
        rank: usize,
        /// A basis of the free directions.
        free: Vec<Vec6>,
    },
    /// K has non-finite entries (an overflow upstream).
    NotFinite,
}

/// The analysis of a manipulator's stiffness at one pose.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// Regular, ill-conditioned, singular or not finite.
    pub outcome: Outcome,
    /// Condition number (1-norm, exact: ||A||_1 ||A^-1||_1) of the equilibrated stiffness; infinite where
    /// singular, NaN where K is not finite.
    pub condition: f64,
    /// The symmetric part of K is positive definite (decided on the equilibrated matrix).
    pub positive_definite: bool,
}

impl Analysis {
    /// The compliance, where the outcome is regular.
    pub fn compliance(&self) -> Option<&Mat6> {
        match &self.outcome {
            Outcome::Regular { compliance } => Some(compliance),
            _ => None,
        }
    }
}

/// `D K D` with `D = diag(1, 1, 1, 1/l, 1/l, 1/l)`: every entry in N/mm, so that eigenvalues compare.
pub fn scaled(k: &Mat6, length_scale: f64) -> Mat6 {
    let d = length_weights(length_scale);
    Mat6::from_fn(|i, j| k[(i, j)] * d[i] * d[j])
}

/// The length-scaled stiffness brought to a unit diagonal, `T K T` with `T = D E`: `D` weighs rotations by
/// the length scale (`scaled`), `E` brings the diagonal to one. A diagonal entry that is round-off (below
/// `CANCELLATION_TOLERANCE` of its terms' size `magnitude`) or not positive is scaled as the largest
/// diagonal is, so that noise is never magnified into a stiffness. Returns the matrix and `T`'s diagonal.
fn equilibrated(k: &Mat6, magnitude: &Vec6, length_scale: f64) -> (Mat6, Vec6) {
    let d = length_weights(length_scale);
    let diagonal = Vec6::from_fn(|i, _| k[(i, i)] * d[i] * d[i]);
    let largest = diagonal.max().max(0.0);
    let fallback = if largest > 0.0 { 1.0 / largest.sqrt() } else { 1.0 };
    let t = Vec6::from_fn(|i, _| {
        let s = diagonal[i];
        let e =
            if s > CANCELLATION_TOLERANCE * magnitude[i] * d[i] * d[i] && s > 0.0 { 1.0 / s.sqrt() } else { fallback };
        d[i] * e
    });
    (Mat6::from_fn(|i, j| k[(i, j)] * t[i] * t[j]), t)
}

/// `diag(1, 1, 1, 1/l, 1/l, 1/l)`: rotations weighed against translations by the length scale `l`.
fn length_weights(length_scale: f64) -> Vec6 {
    weigh_rotations(&Vec6::repeat(1.0), 1.0 / length_scale)
}

/// Eigenvalues (ascending) of a symmetric 3x3 matrix. The closed-form trigonometric method is exact away
/// from repeated roots, but loses half its digits near them (its angle is an arccos near +-1, as on the
/// Orthoglide's diagonal x = y = z). Near a double root the isolated root is still exact (the cosine is flat
/// there), so the other two come from the 2x2 matrix on the plane orthogonal to its eigenvector, whose
/// eigenvalues `(a + c)/2 +- hypot((a - c)/2, b)` keep their digits. None on non-finite input.
pub fn symmetric_eigenvalues3(m: &Mat3) -> Option<[f64; 3]> {
    if !all_finite(m.as_slice()) {
        return None;
    }
    let p1 = m[(0, 1)].powi(2) + m[(0, 2)].powi(2) + m[(1, 2)].powi(2);
    let tr = m.trace();
    let q = tr / 3.0;
    let p2 = (m[(0, 0)] - q).powi(2) + (m[(1, 1)] - q).powi(2) + (m[(2, 2)] - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    if p == 0.0 {
        return Some([q, q, q]);
    }
    let r = (((m - Mat3::identity() * q) / p).determinant() / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let largest = q + 2.0 * p * phi.cos();
    let smallest = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    // 1e-3 from +-1 the arccos has lost at most ~5e-15 of its argument.
    if r.abs() < 1.0 - 1e-3 {
        return Some([smallest, tr - largest - smallest, largest]);
    }
    let isolated = if r > 0.0 { largest } else { smallest };
    // No plane to deflate onto: m - isolated I is zero to round-off, all three roots are `isolated` (a
    // multiple of the identity whose trace / 3 was rounded, so that p came out as round-off, not zero).
    let pair = deflated_pair(m, isolated).unwrap_or((isolated, isolated));
    let mut v = [isolated, pair.0, pair.1];
    v.sort_by(f64::total_cmp);
    Some(v)
}

/// The two eigenvalues of a symmetric 3x3 matrix other than `isolated` (a simple eigenvalue, well
/// separated): its eigenvector is the largest cross product of two rows of `m - isolated I`; on the plane
/// orthogonal to it `m` is a 2x2 symmetric matrix.
fn deflated_pair(m: &Mat3, isolated: f64) -> Option<(f64, f64)> {
    let a = m - Mat3::identity() * isolated;
    let rows = [a.row(0).transpose(), a.row(1).transpose(), a.row(2).transpose()];
    let v = [rows[0].cross(&rows[1]), rows[0].cross(&rows[2]), rows[1].cross(&rows[2])]
        .into_iter()
        .max_by(|x, y| x.norm_squared().total_cmp(&y.norm_squared()))?;
    if v.norm().is_nan() || v.norm() <= 0.0 {
        return None;
    }
    let v = v.normalize();
    let helper =
        if v.x.abs() < 0.9 { crate::kinematics::frame::Vec3::x() } else { crate::kinematics::frame::Vec3::y() };
    let u = v.cross(&helper).normalize();
    let w = v.cross(&u);
    let (aa, cc, bb) = (u.dot(&(m * u)), w.dot(&(m * w)), u.dot(&(m * w)));
    let (mid, half) = (0.5 * (aa + cc), (0.5 * (aa - cc)).hypot(bb));
    Some((mid - half, mid + half))
}

/// Smallest eigenvalue of the symmetric part of the equilibrated stiffness, relative to the largest:
/// positive exactly where the stiffness is positive definite (the stability test of loaded mode).
fn definiteness(ke: &Mat6) -> Option<f64> {
    Some(relative_smallest(&capped_eigenvalues(&((ke + ke.transpose()) * 0.5))?))
}

/// The smallest eigenvalue over the largest magnitude (0 for a zero matrix).
fn relative_smallest(e: &Vec6) -> f64 {
    let largest = e.abs().max();
    if largest > 0.0 {
        e.min() / largest
    } else {
        0.0
    }
}

/// The symmetric part of `k` is positive definite, decided on the equilibrated matrix with the rank
/// tolerance. `magnitude`: the entrywise sum of the legs' |K_i| (`Aggregate::magnitude`).
pub fn positive_definite(k: &Mat6, magnitude: &Vec6, length_scale: f64) -> bool {
    definite_beyond_rank_tolerance(&equilibrated(k, magnitude, length_scale).0)
}

/// `definiteness(ke) > RANK_TOLERANCE` (the smallest eigenvalue of the symmetric part S above the rank
/// tolerance times the largest magnitude rho), mostly without the eigenvalues: rho lies between
/// |S|_F / sqrt(6) and |S|_F, so S - tol |S|_F I positive definite proves it and S - tol |S|_F / sqrt(6) I
/// not positive definite disproves it, a Cholesky factorisation each (a 6x6 eigensolve costs 20 times
/// more, twice per loaded point). Only a smallest eigenvalue within that factor sqrt(6) of the threshold,
/// a condition near 1e13, is left to the eigenvalues.
fn definite_beyond_rank_tolerance(ke: &Mat6) -> bool {
    let s = (ke + ke.transpose()) * 0.5;
    if !s.iter().all(|v| v.is_finite() && v.abs() <= MAX_ENTRY) {
        return false;
    }
    let frobenius = s.norm();
    let definite_after_shift = |shift: f64| {
        let mut a: [[f64; 6]; 6] = std::array::from_fn(|i| std::array::from_fn(|j| s[(i, j)]));
        (0..6).for_each(|d| a[d][d] -= shift);
        small_cholesky(&mut a)
    };
    if definite_after_shift(RANK_TOLERANCE * frobenius) {
        true
    } else if !definite_after_shift(RANK_TOLERANCE * frobenius / 6f64.sqrt()) {
        false
    } else {
        definiteness(ke).is_some_and(|d| d > RANK_TOLERANCE)
    }
}

/// Rank, conditioning, definiteness and (where meaningful) the compliance of a 6x6 stiffness. `magnitude`:
/// the diagonal of the entrywise sum of the sizes of the legs' terms (`Aggregate::magnitude`; K's own
/// diagonal magnitudes where K is not a sum).
/// `symmetric`: K is symmetric by theory (unloaded), so C is symmetrised; otherwise (loaded tangent
/// stiffness) C is the full inverse.
pub fn analyse(k: &Mat6, magnitude: &Vec6, length_scale: f64, symmetric: bool) -> Analysis {
    let not_finite = Analysis { outcome: Outcome::NotFinite, condition: f64::NAN, positive_definite: false };
    if !all_finite(k.as_slice()) {
        return not_finite;
    }
    let (ke, t) = equilibrated(k, magnitude, length_scale);
    let compliance_of = |inv: &Mat6| {
        // C = K^-1 = T (T K T)^-1 T
        let c = Mat6::from_fn(|i, j| inv[(i, j)] * t[i] * t[j]);
        if symmetric {
            (c + c.transpose()) * 0.5
        } else {
            c
        }
    };
    // The common case first, at the cost of one factorisation: the inverse (Cholesky where K is symmetric,
    // which succeeds only where it is positive definite; LU with pivoting otherwise) and the exact 1-norm
    // condition number from it. Within the limit the rank is full and, for a symmetric K, definiteness
    // is settled too (lambda_min / lambda_max >= 1 / (6 condition)).
    let inverse = if symmetric { ke.cholesky().map(|c| c.inverse()) } else { ke.lu().try_inverse() };
    let inverse = inverse.filter(|inv| all_finite(inv.as_slice()));
    let condition = inverse.as_ref().map_or(f64::INFINITY, |inv| norm1(&ke) * norm1(inv));
    if condition <= CONDITION_LIMIT {
        let inv = inverse.expect("a finite condition comes from an inverse");
        let positive_definite = symmetric || definite_beyond_rank_tolerance(&ke);
        return Analysis {
            outcome: Outcome::Regular { compliance: compliance_of(&inv) },
            condition,
            positive_definite,
        };
    }
    // Ill-conditioned, singular or indefinite: eigenvalues of the symmetric part for definiteness, singular
    // values for the rank (an SVD), vectors for the free directions.
    let Some(values) = capped_eigenvalues(&((ke + ke.transpose()) * 0.5)) else { return not_finite };
    let positive_definite = relative_smallest(&values) > RANK_TOLERANCE;
    if let Some((rank, free)) = rank_deficiency(k, length_scale) {
        return Analysis { outcome: Outcome::Singular { rank, free }, condition: f64::INFINITY, positive_definite };
    }
    // Full rank: the condition from an LU inverse where Cholesky failed (an indefinite symmetric K).
    let condition = match (&inverse, ke.lu().try_inverse()) {
        (None, Some(inv)) => norm1(&ke) * norm1(&inv),
        _ => condition,
    };
    Analysis { outcome: Outcome::IllConditioned, condition, positive_definite }
}

/// What the analysis of a serial arm's compliance decides (`serial.rs`: C computed directly).
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)]
pub enum ArmOutcome {
    /// Full rank, the equilibrated stiffness's condition within `CONDITION_LIMIT`: K = C^-1.
    Regular {
        /// K = C^-1.
        stiffness: Mat6,
        /// Its condition number, as `analyse` computes it.
        condition: f64,
    },
    /// Full rank, but past `CONDITION_LIMIT` (or, unloaded, indefinite by round-off).
    IllConditioned {
        /// Its condition number (infinite where K could not be formed).
        condition: f64,
    },
    /// Rank below 6: the rigid directions (`rigid_directions`).
    Rigid {
        /// The rank of C.
        rank: usize,
        /// A basis of the rigid unit wrenches.
        rigid: Vec<Vec6>,
    },
    /// C has non-finite entries.
    NotFinite,
}

/// A serial arm's compliance C analysed as `analyse` analyses K = C^-1, for one inversion: C inverted
/// (Cholesky where it is symmetric, LU otherwise, on C equilibrated to a unit diagonal), the equilibrated
/// K's condition taken from K and from C itself (the equilibrated K's inverse is T^-1 C T^-1: no second
/// inversion), and the rank decided on C (`rigid_directions`) only where the inversion fails or the
/// condition is past the limit. `symmetric`: C is symmetric by theory (unloaded).
pub fn analyse_compliance(c: &Mat6, length_scale: f64, symmetric: bool) -> ArmOutcome {
    if !all_finite(c.as_slice()) {
        return ArmOutcome::NotFinite;
    }
    let rank_or = |fallback: ArmOutcome| match rigid_directions(c, length_scale) {
        Some((rank, rigid)) => ArmOutcome::Rigid { rank, rigid },
        None => fallback,
    };
    // C brought to a unit diagonal (its diagonal is positive wherever C has full rank), inverted.
    let d = Vec6::from_fn(|i, _| c[(i, i)]);
    if d.iter().any(|v| v.is_nan() || *v <= 0.0) {
        return rank_or(ArmOutcome::IllConditioned { condition: f64::INFINITY });
    }
    let e = d.map(|v| 1.0 / v.sqrt());
    let ce = Mat6::from_fn(|i, j| c[(i, j)] * e[i] * e[j]);
    let inverse = if symmetric { crate::linalg::spd_inverse6(&ce) } else { ce.lu().try_inverse() };
    let Some(inverse) = inverse.filter(|m| all_finite(m.as_slice())) else {
        return rank_or(ArmOutcome::IllConditioned { condition: f64::INFINITY });
    };
    let k = Mat6::from_fn(|i, j| inverse[(i, j)] * e[i] * e[j]);
    let magnitude = Vec6::from_fn(|i, _| k[(i, i)].abs());
    let (ke, t) = equilibrated(&k, &magnitude, length_scale);
    let equilibrated_inverse = Mat6::from_fn(|i, j| c[(i, j)] / (t[i] * t[j]));
    let condition = norm1(&ke) * norm1(&equilibrated_inverse);
    // No definiteness test: unloaded, the Cholesky factorisation that inverted C proved it; loaded, a
    // tangent's definiteness is the equilibrium's stability, which the solve decided on K_e - H itself.
    if condition <= CONDITION_LIMIT {
        return ArmOutcome::Regular { stiffness: k, condition };
    }
    rank_or(ArmOutcome::IllConditioned { condition })
}

/// A serial arm's compliance C of rank below 6 (`serial.rs`): its rank and a basis of its rigid directions,
/// the unit wrenches (N, N mm; moments weighed by the length scale, as the free twists are) C maps to no
/// displacement. The same one decision as `rank_deficiency`'s, on the length-scaled compliance D^-1 C D^-1
/// (every entry in mm/N): a unit wrench w is rigid where |C w| <= `FREE_DIRECTION_TOLERANCE` |C|. None at
/// full rank.
pub fn rigid_directions(c: &Mat6, length_scale: f64) -> Option<(usize, Vec<Vec6>)> {
    rank_deficiency(c, 1.0 / length_scale)
}

/// The matrix 1-norm: the largest column sum of magnitudes.
fn norm1(m: &Mat6) -> f64 {
    m.column_iter().map(|c| c.iter().map(|v| v.abs()).sum::<f64>()).fold(0.0, f64::max)
}

/// Eigenvalues of a symmetric 6x6 matrix, without eigenvectors. nalgebra's eigenvalue-only solve has no
/// iteration cap, so it is called only on finite entries of bounded size (an equilibrated matrix has a
/// unit diagonal), where its shifted QR converges.
fn capped_eigenvalues(m: &Mat6) -> Option<Vec6> {
    (m.iter().all(|v| v.is_finite() && v.abs() <= MAX_ENTRY)).then(|| m.symmetric_eigenvalues())
}

/// The rank of a stiffness the equilibrated analysis did not find regular, and its free directions, where
/// the rank is below 6 (None at full rank).
///
/// One decision, on the length-scaled stiffness Ks = D K D (every entry in N/mm: a change of length unit
/// scales Ks as a whole, so the decision does not depend on units, and no equilibration enters it): a unit
/// twist t (unit in that metric) is free where |Ks t| <= `FREE_DIRECTION_TOLERANCE` |Ks| (2-norms), so the
/// free directions are Ks's right singular vectors below the tolerance and every direction orthogonal to
/// them is resisted. (Equilibrating first magnified the round-off of a leg's small in-plane stiffness,
/// cancelled from beam stiffnesses a million times larger, above the rank tolerance: a NaVARo II leg's free
/// translation along its passive slider was lost.)
fn rank_deficiency(k: &Mat6, length_scale: f64) -> Option<(usize, Vec<Vec6>)> {
    let svd = SVD::try_new(scaled(k, length_scale), false, true, f64::EPSILON, MAX_SWEEPS)?;
    let sigma_max = svd.singular_values.max();
    let free_index = |i: &usize| svd.singular_values[*i] <= FREE_DIRECTION_TOLERANCE * sigma_max;
    let rank = (0..6).filter(|i| !free_index(i)).count();
    if rank == 6 {
        return None;
    }
    let v_t = svd.v_t.expect("requested");
    // Right singular vectors are orthonormal in the scaled metric: written in mm and rad (t = D y), each
    // normalised.
    let free = (0..6)
        .filter(free_index)
        .map(|i| weigh_rotations(&v_t.row(i).transpose(), 1.0 / length_scale).normalize())
        .collect();
    Some((rank, free))
}

/// Largest and smallest translational compliance (eigenvalues of the 3x3 translational block of the
/// symmetric part of C, mm/N) and largest rotational compliance (of its rotational block, rad/(N mm)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrincipalCompliance {
    /// Largest principal translational compliance, mm/N.
    pub translation_max: f64,
    /// Smallest principal translational compliance, mm/N.
    pub translation_min: f64,
    /// Largest principal rotational compliance, rad/(N mm).
    pub rotation_max: f64,
}

/// Principal compliances of the symmetric part of C: the energy a wrench stores, w^T C w, sees only that
/// part, and it is positive definite wherever the symmetric part of K is (so these are positive under `ok`).
pub fn principal(c: &Mat6) -> Option<PrincipalCompliance> {
    let s = (c + c.transpose()) * 0.5;
    let t: Mat3 = s.fixed_view::<3, 3>(0, 0).into();
    let r: Mat3 = s.fixed_view::<3, 3>(3, 3).into();
    let et = symmetric_eigenvalues3(&t)?;
    let er = symmetric_eigenvalues3(&r)?;
    Some(PrincipalCompliance { translation_max: et[2], translation_min: et[0], rotation_max: er[2] })
}

/// The spectrum of a tangent stiffness' symmetric part, as a force-deflection curve reports it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spectrum {
    /// Smallest eigenvalue of the translational 3x3 block (N/mm).
    pub translational_min: f64,
    /// Smallest eigenvalue of the rotational 3x3 block (N mm/rad).
    pub rotational_min: f64,
    /// Smallest eigenvalue of the whole matrix with rotations weighted by the length scale (N/mm): its sign
    /// is the stability test.
    pub scaled_min: f64,
    /// The eigenvector of `scaled_min` (the critical mode), unit twist in mm and rad, sign fixed so that
    /// its largest component is positive.
    pub critical_mode: Vec6,
}

/// Eigenvalues of the symmetric part of K that decide stability (translational and rotational blocks,
/// and the whole with rotations weighed by `length_scale`), with the critical mode; None if not finite.
pub fn spectrum(k: &Mat6, length_scale: f64) -> Option<Spectrum> {
    let s = (k + k.transpose()) * 0.5;
    let t: Mat3 = s.fixed_view::<3, 3>(0, 0).into();
    let r: Mat3 = s.fixed_view::<3, 3>(3, 3).into();
    let ks = scaled(&s, length_scale);
    if !all_finite(ks.as_slice()) {
        return None;
    }
    let e = SymmetricEigen::try_new(ks, f64::EPSILON, MAX_SWEEPS)?;
    let i = e.eigenvalues.imin();
    let mut mode = weigh_rotations(&e.eigenvectors.column(i).into(), 1.0 / length_scale).normalize();
    if mode.iter().fold(0.0f64, |a, &b| if b.abs() > a.abs() { b } else { a }) < 0.0 {
        mode = -mode;
    }
    Some(Spectrum {
        translational_min: symmetric_eigenvalues3(&t)?[0],
        rotational_min: symmetric_eigenvalues3(&r)?[0],
        scaled_min: e.eigenvalues[i],
        critical_mode: mode,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: 0.1 I (an isotropic inertia or compliance block) has the triple root 0.1, but its mean
    /// 0.3 / 3 rounds below 0.1, so the spread p came out as round-off rather than zero and the deflation
    /// found no plane (m - 0.1 I is zero): None, which the URDF reader took for a non-finite inertia.
    #[test]
    fn a_multiple_of_the_identity_has_a_triple_root() {
        for v in [0.1, 1.0 / 3.0, 7e-9, 2.5e6] {
            let e = symmetric_eigenvalues3(&(Mat3::identity() * v)).expect("finite");
            assert!(e.iter().all(|x| (x - v).abs() <= 4.0 * f64::EPSILON * v), "{v}: {e:?}");
        }
    }

    /// Stability (loaded mode) is decided as the eigenvalues decide it: S = Q diag(lambda) Q^T with a
    /// random orthogonal Q, the smallest eigenvalue at ratios to the largest from 1 down through the rank
    /// tolerance (on both sides of it, within and beyond the factor sqrt(6) the Cholesky tests leave to the
    /// eigenvalues) to negative, at scales from 1e-6 to 1e9, with an antisymmetric part the test ignores.
    #[test]
    fn definiteness_by_cholesky_agrees_with_the_eigenvalues() {
        let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
        let mut uniform = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (mut definite, mut not) = (0, 0);
        for ratio in [1.0, 1e-3, 1e-12, 3e-13, 2.5e-13, 1.5e-13, 1.2e-13, 8e-14, 5e-14, 1e-14, 0.0, -1e-14, -0.3] {
            for scale in [1e-6, 1.0, 1e9] {
                for others in [1, 3, 5] {
                    let q = Mat6::from_fn(|_, _| uniform()).qr().q();
                    // `others` eigenvalues at the largest size, the rest spread below it, one at `ratio`.
                    let lambda = Vec6::from_fn(|i, _| match i {
                        0 => ratio,
                        i if i <= others => 1.0,
                        _ => 0.1 + 0.8 * (uniform() + 0.5),
                    }) * scale;
                    let s = q * Mat6::from_diagonal(&lambda) * q.transpose();
                    let a = Mat6::from_fn(|_, _| uniform()) * scale;
                    let k = s + (a - a.transpose()) * 0.5;
                    let by_eigenvalues = definiteness(&k).is_some_and(|d| d > RANK_TOLERANCE);
                    assert_eq!(definite_beyond_rank_tolerance(&k), by_eigenvalues, "ratio {ratio} scale {scale}");
                    if by_eigenvalues {
                        definite += 1;
                    } else {
                        not += 1;
                    }
                }
            }
        }
        assert!(definite >= 40 && not >= 40, "{definite} definite, {not} not");
        assert!(!definite_beyond_rank_tolerance(&Mat6::zeros()));
        assert!(!definite_beyond_rank_tolerance(&(Mat6::identity() * f64::NAN)));
    }

    /// Near a double root the closed form loses half its digits; the deflated pair keeps them. A rotated
    /// diag(2, 1 + d, 1) with d from 1e-3 down to 0: eigenvalues to 1e-14.
    #[test]
    fn eigenvalues_near_a_double_root_keep_their_digits() {
        let r = crate::kinematics::frame::rotation_from_vector(&crate::kinematics::frame::Vec3::new(0.3, -0.7, 0.4));
        for d in [1e-3, 1e-6, 1e-9, 1e-12, 0.0] {
            for (a, b, c) in [(2.0, 1.0 + d, 1.0), (1.0, 2.0 + d, 2.0)] {
                let m = r * Mat3::from_diagonal(&crate::kinematics::frame::Vec3::new(a, b, c)) * r.transpose();
                let got = symmetric_eigenvalues3(&((m + m.transpose()) * 0.5)).unwrap();
                let mut want = [a, b, c];
                want.sort_by(f64::total_cmp);
                for k in 0..3 {
                    assert!((got[k] - want[k]).abs() < 1e-14 * 2.0, "d {d}: {got:?} vs {want:?}");
                }
            }
        }
    }
}

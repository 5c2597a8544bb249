//! Unloaded stiffness of one VJM chain (paper 001 eq 9), never inverting the leg's own stiffness.

use nalgebra::{Matrix6xX, SMatrix};

use super::spring::SpringGroup;
use crate::kinematics::frame::{Mat6, Vec6};

/// Relative pivot below which a passive-joint direction is taken as dependent on the others.
pub const PASSIVE_RANK_TOLERANCE: f64 = 1e-9;

/// `S_theta = J_theta K_theta^-1 J_theta^T`: the springs' compliance seen at the end point (paper 001 eq 9).
pub fn spring_compliance_at_end(j_virtual: &[Vec6], springs: &[SpringGroup]) -> Mat6 {
    let mut s = Mat6::zeros();
    for g in springs {
        let mut j = Mat6::zeros();
        for k in 0..g.dim {
            j.set_column(k, &j_virtual[g.first + k]);
        }
        s += j * g.compliance * j.transpose();
    }
    (s + s.transpose()) * 0.5
}

/// An independent basis of the range of the passive-joint Jacobian J_q, with the rank decision made on
/// columns whose rotational rows are weighted by `length_scale` (mm/rad) so that mm and rad compare.
///
/// Where passive axes become collinear J_q loses rank and the bordered matrix of eq 9 is singular although
/// the stiffness is well defined; replacing J_q by a basis of its range is exact (shared/reference/errata.md).
#[derive(Clone, Copy, Debug)]
pub struct PassiveRange {
    pub basis: [Vec6; 6],
    pub rank: usize,
    /// Smallest accepted pivot over the largest column norm (1 when there are no passive joints).
    pub smallest_pivot_ratio: f64,
}

pub fn passive_range(j_passive: &[Vec6], length_scale: f64) -> PassiveRange {
    let w = |v: &Vec6, f: f64| Vec6::new(v[0], v[1], v[2], v[3] * f, v[4] * f, v[5] * f);
    let mut cols: Vec<Vec6> = j_passive.iter().map(|c| w(c, length_scale)).collect();
    let largest = cols.iter().map(|c| c.norm()).fold(0.0, f64::max);
    let mut out = PassiveRange {
        basis: [Vec6::zeros(); 6],
        rank: 0,
        smallest_pivot_ratio: 1.0,
    };
    if largest == 0.0 {
        return out;
    }
    // Modified Gram-Schmidt with column pivoting (a rank-revealing QR).
    while out.rank < 6 && !cols.is_empty() {
        let (best, norm) = cols
            .iter()
            .enumerate()
            .map(|(i, c)| (i, c.norm()))
            .fold((0, -1.0), |a, b| if b.1 > a.1 { b } else { a });
        if norm <= PASSIVE_RANK_TOLERANCE * largest {
            break;
        }
        let q = cols.swap_remove(best) / norm;
        for c in cols.iter_mut() {
            *c -= q * q.dot(c);
        }
        out.basis[out.rank] = w(&q, 1.0 / length_scale);
        out.smallest_pivot_ratio = norm / largest;
        out.rank += 1;
    }
    out
}

/// Paper 001 eq (9): the leg's stiffness is the upper-left 6x6 block of the inverse of the bordered matrix
/// `[[S, U], [U^T, 0]]`, U a basis of range(J_q). The system is padded to a fixed 12x12 with an identity so it
/// stays on the stack; U is scaled to S's magnitude, which leaves that block unchanged but keeps the
/// factorisation well balanced. Returns None where the bordered matrix is singular (springs that do not
/// restrain every direction the passive joints leave).
pub fn leg_stiffness(s: &Mat6, range: &PassiveRange) -> Option<Mat6> {
    let scale = s.abs().max();
    if scale == 0.0 {
        return None;
    }
    let mut b = SMatrix::<f64, 12, 12>::zeros();
    b.fixed_view_mut::<6, 6>(0, 0).copy_from(s);
    for k in 0..range.rank {
        let u = range.basis[k] * scale;
        b.fixed_view_mut::<6, 1>(0, 6 + k).copy_from(&u);
        b.fixed_view_mut::<1, 6>(6 + k, 0).copy_from(&u.transpose());
    }
    for k in range.rank..6 {
        b[(6 + k, 6 + k)] = 1.0;
    }
    let mut rhs = SMatrix::<f64, 12, 6>::zeros();
    rhs.fixed_view_mut::<6, 6>(0, 0).fill_with_identity();
    let lu = b.lu();
    if !lu.is_invertible() {
        return None;
    }
    let x = lu.solve(&rhs)?;
    let k: Mat6 = x.fixed_view::<6, 6>(0, 0).into();
    if !k.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some((k + k.transpose()) * 0.5)
}

/// The same stiffness by an independent route, used as a test oracle: with N a basis of the wrenches that
/// the passive joints let through (J_q^T F = 0), `K = N (N^T S N)^-1 N^T` (the Schur complement of eq 9).
pub fn leg_stiffness_by_null_space(s: &Mat6, j_passive: &[Vec6]) -> Option<Mat6> {
    let jq = Matrix6xX::from_columns(j_passive);
    let jjt: Mat6 = if j_passive.is_empty() {
        Mat6::zeros()
    } else {
        &jq * jq.transpose()
    };
    let eig = jjt.symmetric_eigen();
    let largest = eig.eigenvalues.max().max(0.0);
    let cols: Vec<Vec6> = (0..6)
        .filter(|&i| eig.eigenvalues[i] <= 1e-12 * largest.max(1e-300) || largest == 0.0)
        .map(|i| eig.eigenvectors.column(i).into())
        .collect();
    if cols.is_empty() {
        return Some(Mat6::zeros());
    }
    let n = Matrix6xX::from_columns(&cols);
    let reduced = n.transpose() * s * &n;
    let inv = reduced.try_inverse()?;
    let k: Mat6 = &n * inv * n.transpose();
    Some((k + k.transpose()) * 0.5)
}

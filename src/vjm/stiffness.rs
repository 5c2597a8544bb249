//! Unloaded stiffness of one VJM chain (paper 001 eq 9), never inverting the leg's own stiffness.

use nalgebra::{Matrix6xX, SMatrix};

use super::spring::SpringGroup;
use crate::kinematics::chain::Coordinates;
use crate::kinematics::frame::{weigh_rotations, Mat3, Mat6, Vec3, Vec6};
use crate::linalg::{all_finite, small_cholesky, small_forward};

/// Relative pivot below which a passive-joint direction is taken as dependent on the others.
pub const PASSIVE_RANK_TOLERANCE: f64 = 1e-9;

/// `S_theta = J_theta K_theta^-1 J_theta^T`: the springs' compliance seen at the end point (paper 001 eq 9).
/// `coords` holds the coordinates on which a posture-dependent spring depends (`SpringGroup::varies`).
pub fn spring_compliance_at_end(j_virtual: &[Vec6], springs: &[SpringGroup], coords: &Coordinates) -> Mat6 {
    let mut s = Mat6::zeros();
    for g in springs {
        let cols = &j_virtual[g.first..g.first + g.dim];
        let varying;
        let compliance = if g.varies() {
            varying = g.at(coords).1;
            &varying
        } else {
            &g.compliance
        };
        if g.dim == 1 {
            s += cols[0] * cols[0].transpose() * compliance[(0, 0)];
        } else if g.dim == 6 && cols[..3].iter().all(|c| c.fixed_rows::<3>(3) == Vec3::zeros()) {
            s += six_dof_spring_compliance(cols, compliance);
        } else {
            let mut j = Mat6::zeros();
            for (k, c) in cols.iter().enumerate() {
                j.set_column(k, c);
            }
            s += j * compliance * j.transpose();
        }
    }
    (s + s.transpose()) * 0.5
}

/// `J C J^T` for a 6-dof spring whose first three coordinates are translations, so that
/// `J = [[A, B], [0, D]]` by 3x3 blocks: the product by blocks skips the zero block (hot path).
fn six_dof_spring_compliance(cols: &[Vec6], c: &Mat6) -> Mat6 {
    let a = Mat3::from_fn(|i, k| cols[k][i]);
    let b = Mat3::from_fn(|i, k| cols[3 + k][i]);
    let d = Mat3::from_fn(|i, k| cols[3 + k][3 + i]);
    let c11: Mat3 = c.fixed_view::<3, 3>(0, 0).into();
    let c12: Mat3 = c.fixed_view::<3, 3>(0, 3).into();
    let c21: Mat3 = c.fixed_view::<3, 3>(3, 0).into();
    let c22: Mat3 = c.fixed_view::<3, 3>(3, 3).into();
    // M = J C = [[A C11 + B C21, A C12 + B C22], [D C21, D C22]]; S = M J^T needs no D C21 (its block
    // below the diagonal is the transpose of the one above).
    let m11 = a * c11 + b * c21;
    let m12 = a * c12 + b * c22;
    let m22 = d * c22;
    let top = m11 * a.transpose() + m12 * b.transpose();
    let off = m12 * d.transpose();
    let bottom = m22 * d.transpose();
    let mut s = Mat6::zeros();
    s.fixed_view_mut::<3, 3>(0, 0).copy_from(&top);
    s.fixed_view_mut::<3, 3>(0, 3).copy_from(&off);
    s.fixed_view_mut::<3, 3>(3, 0).copy_from(&off.transpose());
    s.fixed_view_mut::<3, 3>(3, 3).copy_from(&bottom);
    s
}

/// An independent basis of the range of the passive-joint Jacobian J_q and a basis of the wrenches the
/// passive joints transmit (J_q^T F = 0), with the rank decision made on columns whose rotational rows are
/// weighted by `length_scale` (mm/rad) so that mm and rad compare.
///
/// Where passive axes become collinear J_q loses rank and the bordered matrix of eq 9 is singular although
/// the stiffness is well defined; replacing J_q by a basis of its range is exact (tests/reference/README.md).
#[derive(Clone, Copy, Debug)]
pub struct PassiveRange {
    /// `basis[..rank]` spans range(J_q).
    pub basis: [Vec6; 6],
    /// `transmitted[..6 - rank]` spans the wrenches F with J_q^T F = 0.
    pub transmitted: [Vec6; 6],
    /// Rank of J_q (number of independent passive motions).
    pub rank: usize,
}

/// Modified Gram-Schmidt with column pivoting (a rank-revealing QR) in the weighted metric, then completed
/// to an orthonormal basis of R^6 whose last 6 - rank vectors give the transmitted wrenches.
pub fn passive_range(j_passive: &[Vec6], length_scale: f64) -> PassiveRange {
    if j_passive.is_empty() {
        // No passive joint (a serial arm): every wrench is transmitted, and the completion below would
        // take the unit vectors in order; they are written directly.
        let transmitted =
            std::array::from_fn(|k| weigh_rotations(&Vec6::from_fn(|i, _| f64::from(i == k)), length_scale));
        return PassiveRange { basis: [Vec6::zeros(); 6], transmitted, rank: 0 };
    }
    let mut stack = [Vec6::zeros(); 16];
    let mut heap = Vec::new();
    let cols: &mut [Vec6] = if j_passive.len() <= stack.len() {
        &mut stack[..j_passive.len()]
    } else {
        heap.resize(j_passive.len(), Vec6::zeros());
        &mut heap
    };
    for (c, j) in cols.iter_mut().zip(j_passive) {
        *c = weigh_rotations(j, length_scale);
    }
    let largest = cols.iter().map(|c| c.norm()).fold(0.0, f64::max);
    let mut q = [Vec6::zeros(); 6];
    let mut out = PassiveRange { basis: q, transmitted: q, rank: 0 };
    let mut live = cols.len();
    while out.rank < 6 && live > 0 && largest > 0.0 {
        let (best, norm) = (0..live).map(|i| (i, cols[i].norm())).fold((0, -1.0), |a, b| if b.1 > a.1 { b } else { a });
        if norm <= PASSIVE_RANK_TOLERANCE * largest {
            break;
        }
        let v = cols[best] / norm;
        cols.swap(best, live - 1);
        live -= 1;
        for c in cols[..live].iter_mut() {
            *c -= v * v.dot(c);
        }
        q[out.rank] = v;
        out.basis[out.rank] = weigh_rotations(&v, 1.0 / length_scale);
        out.rank += 1;
    }
    // Complete to a basis of R^6 from the projector onto the orthogonal complement of the range: its
    // columns span the complement; take them largest first and orthonormalise.
    let mut p = Mat6::identity();
    for v in &q[..out.rank] {
        p -= v * v.transpose();
    }
    let mut n = out.rank;
    while n < 6 {
        let (mut best, mut best_norm) = (Vec6::zeros(), -1.0);
        for k in 0..6 {
            let mut e: Vec6 = p.column(k).into();
            for v in &q[out.rank..n] {
                e -= v * v.dot(&e);
            }
            let en = e.norm_squared();
            if en > best_norm {
                best = e;
                best_norm = en;
            }
        }
        q[n] = best / best_norm.sqrt();
        // A wrench F with J_q^T F = 0 is W g with g orthogonal (weighted) to range(W J_q).
        out.transmitted[n - out.rank] = weigh_rotations(&q[n], length_scale);
        n += 1;
    }
    out
}

/// The leg's stiffness on the hot path: the upper-left block of the inverse of the bordered matrix of
/// paper 001 eq (9) in closed form. With N a basis of the wrenches the passive joints transmit,
/// `K = N (N^T S N)^-1 N^T` (the Schur complement of the zero block), a (6 - rank)-sized SPD solve.
/// Returns None where N^T S N is singular (springs that do not restrain what the passive joints leave).
pub fn leg_stiffness(s: &Mat6, range: &PassiveRange) -> Option<Mat6> {
    match 6 - range.rank {
        0 => Some(Mat6::zeros()),
        1 => schur::<1>(s, range),
        2 => schur::<2>(s, range),
        3 => schur::<3>(s, range),
        4 => schur::<4>(s, range),
        5 => schur::<5>(s, range),
        _ => schur::<6>(s, range),
    }
}

/// `K = N M^-1 N^T` with `M = N^T S N = L L^T` (Cholesky): `K = Z Z^T`, `Z = N L^-T`, symmetric by
/// construction. None where M is not positive definite.
fn schur<const D: usize>(s: &Mat6, range: &PassiveRange) -> Option<Mat6> {
    let n = &range.transmitted[..D];
    let sn: [Vec6; D] = std::array::from_fn(|j| s * n[j]);
    let mut l: [[f64; D]; D] = std::array::from_fn(|i| std::array::from_fn(|j| n[i].dot(&sn[j])));
    if !small_cholesky(&mut l) {
        return None;
    }
    // Row r of Z solves L z = (row r of N).
    let z: [[f64; D]; 6] = std::array::from_fn(|r| {
        let mut row = std::array::from_fn(|i| n[i][r]);
        small_forward(&l, &mut row);
        row
    });
    let k = Mat6::from_fn(|a, b| (0..D).map(|i| z[a][i] * z[b][i]).sum());
    all_finite(k.as_slice()).then_some(k)
}

/// Paper 001 eq (9) as printed, a test oracle for `leg_stiffness`: the leg's stiffness is the upper-left 6x6 block of the inverse of the bordered matrix
/// `[[S, U], [U^T, 0]]`, U a basis of range(J_q). The system is padded to a fixed 12x12 with an identity so it
/// stays on the stack; U is scaled to S's magnitude, which leaves that block unchanged but keeps the
/// factorisation well balanced. Returns None where the bordered matrix is singular (springs that do not
/// restrain every direction the passive joints leave).
pub fn leg_stiffness_bordered(s: &Mat6, range: &PassiveRange) -> Option<Mat6> {
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
    let jjt: Mat6 = j_passive.iter().map(|c| c * c.transpose()).sum();
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

/// Paper 002 eq (4)/(7): the leg's stiffness by eliminating one passive joint at a time from the stiffness
/// of the chain without passive joints, `K0 = S^-1` (which needs at least six independent springs,
/// Remark 1): `K <- K - u u^T / mu`, `u = K j`, `mu = j^T K j`, one rank-1 update per passive joint. A column
/// already annihilated by the previous ones (mu ~ 0: a redundant passive joint) is skipped. Where the joint
/// is trivial (its column a unit vector, eq 8) the update reads `K_jk - K_jp K_pk / K_pp`, which this form
/// computes without a special case. None where S is singular.
pub fn leg_stiffness_recursive(s: &Mat6, j_passive: &[Vec6]) -> Option<Mat6> {
    let mut k = s.cholesky()?.inverse();
    let scale = k.abs().max();
    for j in j_passive {
        let u = k * j;
        let mu = j.dot(&u);
        if mu.abs() <= 1e-12 * scale * j.norm_squared() {
            continue;
        }
        k -= u * u.transpose() / mu;
    }
    Some((k + k.transpose()) * 0.5)
}

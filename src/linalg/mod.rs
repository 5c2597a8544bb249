//! Small dense linear algebra the hot paths need beyond nalgebra's fixed-size types: an in-place LU
//! factorisation with partial pivoting on a reused buffer (the loaded equilibrium factorises a
//! (n + m + 6)-square matrix several times per point, and allocating or going through generic dynamic
//! dimensions there costs more than the arithmetic).

/// Largest entry magnitude a decomposition is asked to handle: beyond it squares and products overflow.
pub const MAX_ENTRY: f64 = 1e150;
/// Iteration cap of the decompositions below (a converging SVD of a few dozen columns takes well under a
/// hundred sweeps).
pub const MAX_SWEEPS: usize = 1000;

/// nalgebra's SVD with a check of its input and an iteration cap: its plain `svd` iterates without a cap and
/// never returns on non-finite or overflowing matrices. None where the input is not finite, has an entry
/// beyond `MAX_ENTRY`, or the iteration does not converge.
pub fn capped_svd(
    m: nalgebra::DMatrix<f64>,
    compute_u: bool,
    compute_v: bool,
) -> Option<nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>> {
    if !m.iter().all(|v| v.is_finite() && v.abs() <= MAX_ENTRY) {
        return None;
    }
    nalgebra::SVD::try_new(m, compute_u, compute_v, f64::EPSILON, MAX_SWEEPS)
}

/// Singular values below this share of the largest are round-off: their directions are not in the span.
pub const SPAN_SHARE: f64 = 1e-10;

/// An orthonormal basis of the column space of `y` (rank-revealing: directions whose singular value is below
/// `SPAN_SHARE` of the largest are left out). None where `y` is not finite (`capped_svd`).
pub fn span_basis(y: &nalgebra::DMatrix<f64>) -> Option<nalgebra::DMatrix<f64>> {
    if y.ncols() == 0 {
        return Some(nalgebra::DMatrix::zeros(y.nrows(), 0));
    }
    let svd = capped_svd(y.clone(), true, false)?;
    let top = svd.singular_values.max();
    let keep: Vec<usize> =
        (0..svd.singular_values.len()).filter(|&i| top > 0.0 && svd.singular_values[i] > SPAN_SHARE * top).collect();
    Some(svd.u?.select_columns(&keep))
}

/// The part of `x`'s columns outside the column space of `y` (x - Q Q^T x, Q = `span_basis(y)`). None where
/// `y` is not finite.
pub fn outside_span(x: &nalgebra::DMatrix<f64>, y: &nalgebra::DMatrix<f64>) -> Option<nalgebra::DMatrix<f64>> {
    let q = span_basis(y)?;
    Some(x - &q * (q.transpose() * x))
}

/// LU factorisation with partial pivoting of a column-major square matrix, kept in place.
#[derive(Clone, Debug, Default)]
pub struct DenseLu {
    n: usize,
    a: Vec<f64>,
    pivots: Vec<usize>,
}

impl DenseLu {
    /// Factorises the n x n column-major matrix `m` (copied into the buffer). False where a pivot is
    /// exactly zero or an entry is not finite. No relative threshold: in the equilibrium's matrix the
    /// multiplier columns' pivots are compliances, legitimately 1e-15 of their column's entries with stiff
    /// springs; callers judge the result (a near-singular system shows as a Newton method that fails).
    pub fn factor(&mut self, m: &[f64], n: usize) -> bool {
        assert_eq!(m.len(), n * n);
        self.n = n;
        self.a.clear();
        self.a.extend_from_slice(m);
        self.pivots.clear();
        self.pivots.resize(n, 0);
        let a = &mut self.a;
        if !a.iter().all(|v| v.is_finite()) {
            return false;
        }

        for k in 0..n {
            let (mut p, mut best) = (k, a[k * n + k].abs());
            for (i, v) in a[k * n + k + 1..k * n + n].iter().enumerate() {
                if v.abs() > best {
                    best = v.abs();
                    p = k + 1 + i;
                }
            }
            if best == 0.0 {
                return false;
            }
            self.pivots[k] = p;
            if p != k {
                for col in a.chunks_exact_mut(n) {
                    col.swap(k, p);
                }
            }
            // Right-looking elimination: column k below the pivot becomes L's, and every later column j
            // loses l * a_kj (the same operations, in the same order, as row by row).
            let (left, right) = a.split_at_mut((k + 1) * n);
            let pivot_column = &mut left[k * n + k..k * n + n];
            let d = pivot_column[0];
            for x in &mut pivot_column[1..] {
                *x /= d;
            }
            let lcol = &pivot_column[1..];
            for col in right.chunks_exact_mut(n) {
                let f = col[k];
                if f != 0.0 {
                    for (x, l) in col[k + 1..].iter_mut().zip(lcol) {
                        *x -= l * f;
                    }
                }
            }
        }
        true
    }

    /// The factorisation's row exchanges applied to a right-hand side (its values, or its rows).
    fn exchange_rows<T>(&self, b: &mut [T]) {
        for (k, &p) in self.pivots.iter().enumerate() {
            if p != k {
                b.swap(k, p);
            }
        }
    }

    /// Solves in place for W right-hand sides at once, stored by rows (row i of every right-hand side in
    /// `b[i]`): each elimination updates a whole row of W values, which the compiler keeps in vector
    /// registers, where W separate solves would each walk the factors. Per right-hand side, the same
    /// operations in the same order as `solve_in_place`.
    pub fn solve_rows<const W: usize>(&self, b: &mut [[f64; W]]) {
        let (n, a) = (self.n, &self.a);
        let b = &mut b[..n];
        self.exchange_rows(b);
        for k in 0..n {
            let (done, below) = b.split_at_mut(k + 1);
            let bk = done[k];
            for (row, l) in below.iter_mut().zip(&a[k * n + k + 1..k * n + n]) {
                for (x, v) in row.iter_mut().zip(&bk) {
                    *x -= l * v;
                }
            }
        }
        for k in (0..n).rev() {
            let col = &a[k * n..k * n + k + 1];
            let (above, rest) = b.split_at_mut(k);
            for v in rest[0].iter_mut() {
                *v /= col[k];
            }
            let bk = rest[0];
            for (row, u) in above.iter_mut().zip(&col[..k]) {
                for (x, v) in row.iter_mut().zip(&bk) {
                    *x -= u * v;
                }
            }
        }
    }

    /// Solves in place for one right-hand side of length n.
    pub fn solve_in_place(&self, b: &mut [f64]) {
        let (n, a) = (self.n, &self.a);
        let b = &mut b[..n];
        self.exchange_rows(b);
        // Forward substitution with the unit lower triangle, column by column.
        for k in 0..n {
            let bk = b[k];
            if bk != 0.0 {
                let col = &a[k * n + k + 1..k * n + n];
                for (x, l) in b[k + 1..].iter_mut().zip(col) {
                    *x -= l * bk;
                }
            }
        }
        // Back substitution with the upper triangle.
        for k in (0..n).rev() {
            let col = &a[k * n..k * n + k + 1];
            b[k] /= col[k];
            let bk = b[k];
            if bk != 0.0 {
                for (x, u) in b[..k].iter_mut().zip(&col[..k]) {
                    *x -= u * bk;
                }
            }
        }
    }
}

/// Cholesky factorisation of a small symmetric matrix in place (its lower triangle read, L written there;
/// the strict upper triangle left as it is): false where a pivot is not positive or not finite (not
/// positive definite to round-off).
pub fn small_cholesky<const D: usize>(a: &mut [[f64; D]; D]) -> bool {
    for i in 0..D {
        for j in 0..=i {
            let v = a[i][j] - (0..j).map(|k| a[i][k] * a[j][k]).sum::<f64>();
            if i == j {
                if !(v.is_finite() && v > 0.0) {
                    return false;
                }
                a[i][i] = v.sqrt();
            } else {
                a[i][j] = v / a[j][j];
            }
        }
    }
    true
}

/// Solves L x = b in place, L the lower triangle of a `small_cholesky` factor.
pub fn small_forward<const D: usize>(l: &[[f64; D]; D], b: &mut [f64; D]) {
    for i in 0..D {
        b[i] = (b[i] - (0..i).map(|k| l[i][k] * b[k]).sum::<f64>()) / l[i][i];
    }
}

/// The inverse of a symmetric positive definite 6x6 matrix from its Cholesky factor: `A^-1 = M^T M` with
/// `M = L^-1`, symmetric by construction. None where A is not positive definite to round-off or the
/// inverse is not finite.
pub fn spd_inverse6(a: &nalgebra::Matrix6<f64>) -> Option<nalgebra::Matrix6<f64>> {
    let mut l: [[f64; 6]; 6] = std::array::from_fn(|i| std::array::from_fn(|j| a[(i, j)]));
    if !small_cholesky(&mut l) {
        return None;
    }
    // Row j of M^T (column j of M) solves L x = e_j.
    let mut m = [[0.0; 6]; 6];
    for (j, column) in m.iter_mut().enumerate() {
        column[j] = 1.0;
        small_forward(&l, column);
    }
    let mut inverse = nalgebra::Matrix6::zeros();
    for i in 0..6 {
        for j in 0..=i {
            let v: f64 = (i..6).map(|k| m[i][k] * m[j][k]).sum();
            inverse[(i, j)] = v;
            inverse[(j, i)] = v;
        }
    }
    inverse.iter().all(|v| v.is_finite()).then_some(inverse)
}

/// A Cholesky factorisation A = L L^T made in the caller's buffer (MSA's reduced stiffness at every pose,
/// factorised where it was assembled), with the envelope of A kept: row r of L is zero left of row r's
/// first non-zero in A (no fill outside the envelope), so column j of L is worked only down to the last
/// row whose envelope reaches j. A banded or block-structured matrix then costs what its envelope holds,
/// not n^3 / 6.
#[derive(Clone, Debug, Default)]
pub struct EnvelopeCholesky {
    n: usize,
    /// Per row: its first non-zero column in the lower triangle.
    first: Vec<usize>,
    /// Per column: the last row whose envelope reaches it (L's column is zero below).
    last: Vec<usize>,
}

impl EnvelopeCholesky {
    /// Factorises the leading n x n block of the column-major matrix `a` (columns `stride` long) in place:
    /// its lower triangle (read) becomes L, its strict upper triangle is left untouched. The smallest and
    /// largest pivot L_ii^2, or None where a pivot is not positive or not finite (not positive definite).
    pub fn factor(&mut self, a: &mut [f64], stride: usize, n: usize) -> Option<(f64, f64)> {
        self.eliminate(a, stride, n, n)
    }

    /// Eliminates the first `m` of the n coordinates of the symmetric n x n block: with A = [[A_yy, A_yu],
    /// [A_uy, A_uu]], A_yy = L L^T, the lower triangle's first m columns become [L; A_uy L^-T] and the
    /// trailing block's lower triangle becomes the Schur complement A_uu - A_uy A_yy^-1 A_yu (static
    /// condensation, as one factorisation). Pivots as `factor`, over the m eliminated.
    pub fn eliminate(&mut self, a: &mut [f64], stride: usize, n: usize, m: usize) -> Option<(f64, f64)> {
        assert!(m <= n && n <= stride && a.len() >= stride * n.saturating_sub(1) + n);
        self.n = m;
        self.first.clear();
        self.first.extend((0..n).map(|r| (0..r).find(|&j| a[j * stride + r] != 0.0).unwrap_or(r)));
        self.last.clear();
        self.last.extend(0..n);
        for (r, &f) in self.first.iter().enumerate() {
            self.last[f] = self.last[f].max(r);
        }
        for j in 1..n {
            self.last[j] = self.last[j].max(self.last[j - 1]);
        }
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for k in 0..n {
            // Column k, left-looking: a_rk - sum_{j<k, j<m} l_rj l_kj over the envelope.
            let (left, right) = a.split_at_mut(k * stride);
            let column = &mut right[..n];
            for j in self.first[k]..k.min(m) {
                let lkj = left[j * stride + k];
                if lkj != 0.0 {
                    let end = self.last[j] + 1;
                    for (x, l) in column[k..end].iter_mut().zip(&left[j * stride + k..j * stride + end]) {
                        *x -= l * lkj;
                    }
                }
            }
            if k >= m {
                continue;
            }
            let d = column[k];
            if !(d > 0.0 && d.is_finite()) {
                return None;
            }
            lo = lo.min(d);
            hi = hi.max(d);
            let root = d.sqrt();
            for x in &mut column[k..self.last[k] + 1] {
                *x /= root;
            }
        }
        Some((lo, hi))
    }

    /// Solves L y = b in place (the first half of a solve: with it, B^T A^-1 C = (L^-1 B)^T (L^-1 C)), `l`
    /// the buffer `factor` worked in.
    pub fn forward_in_place(&self, l: &[f64], stride: usize, b: &mut [f64]) {
        let b = &mut b[..self.n];
        for k in 0..self.n {
            let end = (self.last[k] + 1).min(self.n);
            let col = &l[k * stride + k..k * stride + end];
            b[k] /= col[0];
            let bk = b[k];
            if bk != 0.0 {
                for (x, l) in b[k + 1..end].iter_mut().zip(&col[1..]) {
                    *x -= l * bk;
                }
            }
        }
    }

    /// Solves A x = b in place for one right-hand side, `l` the buffer `factor` worked in.
    pub fn solve_in_place(&self, l: &[f64], stride: usize, b: &mut [f64]) {
        self.forward_in_place(l, stride, b);
        let b = &mut b[..self.n];
        for k in (0..self.n).rev() {
            let end = (self.last[k] + 1).min(self.n);
            let col = &l[k * stride + k..k * stride + end];
            let dot: f64 = b[k + 1..end].iter().zip(&col[1..]).map(|(x, l)| x * l).sum();
            b[k] = (b[k] - dot) / col[0];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// The Cholesky inverse of SPD matrices Q D Q^T (Q orthogonal, condition 1 to 1e8) is exactly symmetric and
    /// equals Q D^-1 Q^T to the condition times round-off; an indefinite or singular matrix is refused.
    #[test]
    fn spd_inverse_is_the_inverse_and_refuses_indefinite_matrices() {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for spread in [1.0f64, 1e4, 1e8] {
            let q = nalgebra::Matrix6::from_fn(|_, _| next()).qr().q();
            let d = nalgebra::Vector6::from_fn(|i, _| spread.powf(i as f64 / 5.0));
            let a = q * nalgebra::Matrix6::from_diagonal(&d) * q.transpose();
            let exact = q * nalgebra::Matrix6::from_diagonal(&d.map(|v| 1.0 / v)) * q.transpose();
            let inverse = spd_inverse6(&a).unwrap();
            assert_eq!(inverse, inverse.transpose());
            assert!((inverse - exact).amax() < 1e-14 * spread * exact.amax(), "{inverse}\n{exact}");
        }
        let indefinite = nalgebra::Matrix6::from_diagonal(&nalgebra::Vector6::new(1.0, 2.0, -1.0, 3.0, 1.0, 1.0));
        assert!(spd_inverse6(&indefinite).is_none());
        assert!(spd_inverse6(&nalgebra::Matrix6::zeros()).is_none());
        assert!(spd_inverse6(&nalgebra::Matrix6::from_element(f64::NAN)).is_none());
    }

    #[test]
    fn solves_like_nalgebra_with_pivoting() {
        let n = 9;
        let m = DMatrix::from_fn(n, n, |i, j| {
            ((i * 7 + j * 13) % 11) as f64 - 5.0 + if i == (j + 3) % n { 9.0 } else { 0.0 }
        });
        let b = DVector::from_fn(n, |i, _| i as f64 - 2.5);
        let expected = m.clone().lu().solve(&b).unwrap();
        let mut lu = DenseLu::default();
        assert!(lu.factor(m.as_slice(), n));
        let mut x = b.as_slice().to_vec();
        lu.solve_in_place(&mut x);
        for i in 0..n {
            assert!((x[i] - expected[i]).abs() < 1e-12 * expected.amax());
        }
        assert!(!lu.factor(DMatrix::<f64>::zeros(3, 3).as_slice(), 3));
    }

    /// Several right-hand sides solved together by rows give, bit for bit, what one solve per right-hand
    /// side gives (the same operations in the same order), on a system that needs row exchanges.
    #[test]
    fn solving_by_rows_equals_one_solve_per_right_hand_side() {
        let n = 9;
        let m = DMatrix::from_fn(n, n, |i, j| {
            ((i * 7 + j * 13) % 11) as f64 - 5.0 + if i == (j + 3) % n { 9.0 } else { 0.0 }
        });
        let mut lu = DenseLu::default();
        assert!(lu.factor(m.as_slice(), n));
        let rhs = |c: usize, i: usize| ((i * 3 + c * 5) % 7) as f64 - 2.5 + if i == c { 1.0 } else { 0.0 };
        let mut rows: Vec<[f64; 3]> = (0..n).map(|i| [rhs(0, i), rhs(1, i), rhs(2, i)]).collect();
        lu.solve_rows(&mut rows);
        for c in 0..3 {
            let mut x: Vec<f64> = (0..n).map(|i| rhs(c, i)).collect();
            lu.solve_in_place(&mut x);
            let by_rows: Vec<f64> = rows.iter().map(|r| r[c]).collect();
            assert_eq!(x, by_rows, "right-hand side {c}");
            let residual = &m * DVector::from_vec(x) - DVector::from_fn(n, |i, _| rhs(c, i));
            assert!(residual.amax() < 1e-12, "right-hand side {c}: residual {}", residual.amax());
        }
    }

    /// A symmetric positive definite system solved as nalgebra's Cholesky solves it, dense and with an
    /// envelope (a banded block with zeros inside the band and a stray far entry), factorised in a larger
    /// buffer whose strict upper triangle is left as it was; the pivots are the squares of L's diagonal; an
    /// indefinite matrix is refused.
    #[test]
    fn envelope_cholesky_solves_like_nalgebra() {
        let n = 11;
        let dense = DMatrix::from_fn(n, n, |i, j| ((i * 5 + j * 3) % 7) as f64 - 3.0 + if i == j { 4.0 } else { 0.0 });
        let banded = DMatrix::from_fn(n, n, |i, j| {
            let near = i.abs_diff(j) <= 2 && (i + j) % 5 != 1;
            if i == j {
                3.0
            } else if near || (i, j) == (9, 1) || (i, j) == (1, 9) {
                0.3 + 0.05 * (i + j) as f64
            } else {
                0.0
            }
        });
        for g in [dense, banded] {
            let m = &g * g.transpose();
            let b = DVector::from_fn(n, |i, _| 1.5 - i as f64);
            let expected = m.clone().cholesky().unwrap();
            let stride = n + 3;
            let mut buffer = DMatrix::from_fn(stride, n + 1, |i, j| if i < n && j < n { m[(i, j)] } else { 7.0 });
            let upper_before: Vec<f64> = (0..n).flat_map(|j| (0..j).map(move |i| (i, j))).map(|p| buffer[p]).collect();
            let mut c = EnvelopeCholesky::default();
            let (lo, hi) = c.factor(buffer.as_mut_slice(), stride, n).unwrap();
            let upper_after: Vec<f64> = (0..n).flat_map(|j| (0..j).map(move |i| (i, j))).map(|p| buffer[p]).collect();
            assert_eq!(upper_before, upper_after);
            let l = expected.l();
            for j in 0..n {
                for i in j..n {
                    assert!((buffer[(i, j)] - l[(i, j)]).abs() < 1e-12 * l.amax(), "L[{i},{j}]");
                }
            }
            let squares: Vec<f64> = (0..n).map(|i| l[(i, i)] * l[(i, i)]).collect();
            assert!((lo - squares.iter().cloned().fold(f64::MAX, f64::min)).abs() < 1e-12 * hi);
            assert!((hi - squares.iter().cloned().fold(0.0, f64::max)).abs() < 1e-12 * hi);
            let mut x = b.as_slice().to_vec();
            c.solve_in_place(buffer.as_slice(), stride, &mut x);
            let x_expected = expected.solve(&b);
            for i in 0..n {
                assert!((x[i] - x_expected[i]).abs() < 1e-12 * x_expected.amax());
            }
        }
        let mut indefinite = DMatrix::<f64>::identity(3, 3);
        indefinite[(1, 1)] = -1.0;
        assert!(EnvelopeCholesky::default().factor(indefinite.as_mut_slice(), 3, 3).is_none());
    }

    /// Eliminating the first m coordinates leaves the Schur complement A_uu - A_uy A_yy^-1 A_yu (computed
    /// here with nalgebra's inverse) in the trailing block, and A_uy L^-T below L.
    #[test]
    fn elimination_leaves_the_schur_complement() {
        let (n, m) = (10, 7);
        let g = DMatrix::from_fn(n, n, |i, j| {
            if i.abs_diff(j) <= 3 || i >= m || j >= m {
                ((i * 3 + j * 5) % 7) as f64 - 3.0 + if i == j { 5.0 } else { 0.0 }
            } else {
                0.0
            }
        });
        let a = &g * g.transpose();
        let (ayy, ayu, auu) = (a.view((0, 0), (m, m)), a.view((0, m), (m, n - m)), a.view((m, m), (n - m, n - m)));
        let schur = auu - ayu.transpose() * ayy.clone_owned().try_inverse().unwrap() * ayu;
        let l = ayy.clone_owned().cholesky().unwrap().l();
        let below = ayu.transpose() * l.transpose().try_inverse().unwrap();
        let mut buffer = a.clone();
        let mut c = EnvelopeCholesky::default();
        c.eliminate(buffer.as_mut_slice(), n, n, m).unwrap();
        for j in 0..n - m {
            for i in j..n - m {
                assert!((buffer[(m + i, m + j)] - schur[(i, j)]).abs() < 1e-10 * schur.amax(), "S[{i},{j}]");
            }
            for k in 0..m {
                assert!((buffer[(m + j, k)] - below[(j, k)]).abs() < 1e-10 * below.amax(), "W[{j},{k}]");
            }
        }
    }
}

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

    /// Solves in place for one right-hand side of length n.
    pub fn solve_in_place(&self, b: &mut [f64]) {
        let (n, a) = (self.n, &self.a);
        let b = &mut b[..n];
        for (k, &p) in self.pivots.iter().enumerate() {
            if p != k {
                b.swap(k, p);
            }
        }
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

/// An in-place Cholesky factorisation A = L L^T of a dense symmetric column-major matrix (its lower
/// triangle read), its buffer kept between uses: MSA's reduced stiffness at every pose.
#[derive(Clone, Debug, Default)]
pub struct DenseCholesky {
    n: usize,
    a: Vec<f64>,
}

impl DenseCholesky {
    /// Factorises the n x n matrix `m`; the smallest and largest pivot L_ii^2, or None where a pivot is
    /// not positive or not finite (not positive definite).
    pub fn factor(&mut self, m: &[f64], n: usize) -> Option<(f64, f64)> {
        assert_eq!(m.len(), n * n);
        self.n = n;
        self.a.clear();
        self.a.extend_from_slice(m);
        let a = &mut self.a;
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for k in 0..n {
            // Column k of L: a_ik - sum_{j<k} l_ij l_kj, left-looking.
            for j in 0..k {
                let lkj = a[j * n + k];
                if lkj != 0.0 {
                    let (left, right) = a.split_at_mut(k * n);
                    let lcol = &left[j * n + k..j * n + n];
                    for (x, l) in right[k..n].iter_mut().zip(lcol) {
                        *x -= l * lkj;
                    }
                }
            }
            let d = a[k * n + k];
            if !(d > 0.0 && d.is_finite()) {
                return None;
            }
            lo = lo.min(d);
            hi = hi.max(d);
            let root = d.sqrt();
            for x in &mut a[k * n + k..k * n + n] {
                *x /= root;
            }
        }
        Some((lo, hi))
    }

    /// Solves L y = b in place (the first half of a solve: with it, B^T A^-1 C = (L^-1 B)^T (L^-1 C)).
    pub fn forward_in_place(&self, b: &mut [f64]) {
        let (n, a) = (self.n, &self.a);
        let b = &mut b[..n];
        for k in 0..n {
            let col = &a[k * n + k..k * n + n];
            b[k] /= col[0];
            let bk = b[k];
            if bk != 0.0 {
                for (x, l) in b[k + 1..].iter_mut().zip(&col[1..]) {
                    *x -= l * bk;
                }
            }
        }
    }

    /// Solves A x = b in place for one right-hand side of length n.
    pub fn solve_in_place(&self, b: &mut [f64]) {
        let (n, a) = (self.n, &self.a);
        self.forward_in_place(b);
        let b = &mut b[..n];
        for k in (0..n).rev() {
            let col = &a[k * n + k..k * n + n];
            let dot: f64 = b[k + 1..].iter().zip(&col[1..]).map(|(x, l)| x * l).sum();
            b[k] = (b[k] - dot) / col[0];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

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

    /// A symmetric positive definite system solved as nalgebra's Cholesky solves it; the pivots are the
    /// squares of L's diagonal; an indefinite matrix is refused.
    #[test]
    fn cholesky_solves_like_nalgebra() {
        let n = 11;
        let g = DMatrix::from_fn(n, n, |i, j| ((i * 5 + j * 3) % 7) as f64 - 3.0 + if i == j { 4.0 } else { 0.0 });
        let m = &g * g.transpose();
        let b = DVector::from_fn(n, |i, _| 1.5 - i as f64);
        let expected = m.clone().cholesky().unwrap();
        let mut c = DenseCholesky::default();
        let (lo, hi) = c.factor(m.as_slice(), n).unwrap();
        let l = expected.l();
        let squares: Vec<f64> = (0..n).map(|i| l[(i, i)] * l[(i, i)]).collect();
        assert!((lo - squares.iter().cloned().fold(f64::MAX, f64::min)).abs() < 1e-12 * hi);
        assert!((hi - squares.iter().cloned().fold(0.0, f64::max)).abs() < 1e-12 * hi);
        let mut x = b.as_slice().to_vec();
        c.solve_in_place(&mut x);
        let x_expected = expected.solve(&b);
        for i in 0..n {
            assert!((x[i] - x_expected[i]).abs() < 1e-12 * x_expected.amax());
        }
        let mut indefinite = DMatrix::<f64>::identity(3, 3);
        indefinite[(1, 1)] = -1.0;
        assert!(c.factor(indefinite.as_slice(), 3).is_none());
    }
}

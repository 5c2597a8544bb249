//! LU factorisations with partial pivoting: on the stack for a size known when compiled (`SmallLu`), and in
//! place on kept buffers, by rows (`DenseLu`).

use super::all_finite;

/// LU factorisation with partial pivoting of an N x N matrix on the stack, N known when compiled (the
/// platform's 6 x 6 stiffness at each step of the loaded solve, a compensation's block on its task
/// directions). It makes nalgebra's `LU` arithmetic, operation for operation (the pivot the first largest
/// size in its column; the multipliers times the pivot's reciprocal; each update y - u l; a solve's back
/// substitution dividing by the pivot), so its solutions are nalgebra's to the bit, in about half the
/// instructions (nalgebra's generic views spend the rest on set-up for a matrix this small).
#[derive(Clone, Copy, Debug)]
pub struct SmallLu<const N: usize> {
    /// By columns: L's multipliers below the diagonal (its unit diagonal implied), U on and above it.
    columns: [[f64; N]; N],
    /// Step i exchanged rows i and `exchanges[i]`.
    exchanges: [usize; N],
}

impl<const N: usize> SmallLu<N> {
    /// Factorises `m`. A column with no nonzero entry left is passed over (as nalgebra does): `solve` then
    /// finds its zero pivot.
    pub fn new(m: &nalgebra::SMatrix<f64, N, N>) -> Self {
        let mut a: [[f64; N]; N] = std::array::from_fn(|c| std::array::from_fn(|r| m[(r, c)]));
        let mut exchanges: [usize; N] = std::array::from_fn(|i| i);
        for i in 0..N {
            let (mut p, mut best) = (i, a[i][i].abs());
            for (r, v) in (i + 1..).zip(&a[i][i + 1..]) {
                if v.abs() > best {
                    (p, best) = (r, v.abs());
                }
            }
            let pivot = a[i][p];
            if pivot == 0.0 {
                continue;
            }
            exchanges[i] = p;
            if p != i {
                a.iter_mut().for_each(|column| column.swap(i, p));
            }
            let inverse = 1.0 / pivot;
            let (done, later) = a.split_at_mut(i + 1);
            let multipliers = &mut done[i];
            for l in &mut multipliers[i + 1..] {
                *l *= inverse;
            }
            for column in later {
                let u = column[i];
                for (v, l) in column[i + 1..].iter_mut().zip(&multipliers[i + 1..]) {
                    *v -= u * l;
                }
            }
        }
        SmallLu { columns: a, exchanges }
    }

    /// The inverse, column by column as the solutions for the identity's columns (nalgebra's
    /// `try_inverse` for a matrix larger than 4 x 4, to the bit); None where a pivot is zero.
    pub fn inverse(&self) -> Option<nalgebra::SMatrix<f64, N, N>> {
        let mut inverse = nalgebra::SMatrix::<f64, N, N>::zeros();
        for c in 0..N {
            let column = self.solve(&nalgebra::SVector::<f64, N>::from_fn(|r, _| if r == c { 1.0 } else { 0.0 }))?;
            inverse.set_column(c, &column);
        }
        Some(inverse)
    }

    /// Solves for one right-hand side; None where a pivot is zero.
    pub fn solve(&self, b: &nalgebra::SVector<f64, N>) -> Option<nalgebra::SVector<f64, N>> {
        let mut x: [f64; N] = std::array::from_fn(|i| b[i]);
        for (i, &p) in self.exchanges.iter().enumerate() {
            x.swap(i, p);
        }
        for (i, column) in self.columns.iter().enumerate() {
            let c = x[i];
            for (v, l) in x[i + 1..].iter_mut().zip(&column[i + 1..]) {
                *v -= c * l;
            }
        }
        for (i, column) in self.columns.iter().enumerate().rev() {
            if column[i] == 0.0 {
                return None;
            }
            let c = x[i] / column[i];
            x[i] = c;
            for (v, u) in x[..i].iter_mut().zip(&column[..i]) {
                *v -= c * u;
            }
        }
        Some(nalgebra::SVector::from(x))
    }
}

/// LU factorisation with partial pivoting of a column-major square matrix, copied by rows and factorised
/// there: each solved entry of the substitutions is then a dot product along a row of the factors, summed
/// in registers, where column-by-column substitutions update the right-hand side in memory once per
/// column (on the loaded equilibrium's reduced matrices, about 11 square, with vector loops a few entries
/// long whose set-up costs more than their arithmetic: the several right-hand sides of `solve_rows` took
/// 40% more instructions that way). The elimination updates each later row along the pivot row, the same
/// operations in the same order per entry as column by column, and a row exchange swaps two contiguous
/// rows.
#[derive(Clone, Debug, Default)]
pub struct DenseLu {
    n: usize,
    /// The factors, row-major (L below the diagonal, unit diagonal implied; U on and above it).
    rows: Vec<f64>,
    pivots: Vec<usize>,
}

impl DenseLu {
    /// Factorises the n x n column-major matrix `m` (copied into the buffer). False where a pivot is
    /// exactly zero or an entry is not finite. No relative threshold: callers judge the result (in the
    /// loaded equilibrium's reduced system, stiff springs beside soft load terms span many orders of
    /// magnitude, and a near-singular system shows as a Newton method that fails).
    pub fn factor(&mut self, m: &[f64], n: usize) -> bool {
        assert_eq!(m.len(), n * n);
        self.n = n;
        self.rows.resize(n * n, 0.0);
        self.pivots.resize(n, 0);
        let (a, pivots) = (&mut self.rows, &mut self.pivots);
        with_known_size!(n, n => transpose_into(m, a, n) && lu_rows_in_place(a, pivots, n))
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
    /// `b[i]`): each row is summed in registers over the rows before it (forward) or after it (back), W
    /// values at a time. Per right-hand side, the same operations in the same order as `solve_in_place`.
    pub fn solve_rows<const W: usize>(&self, b: &mut [[f64; W]]) {
        let (n, lu) = (self.n, &self.rows);
        let b = &mut b[..n];
        self.exchange_rows(b);
        for i in 1..n {
            let (done, rest) = b.split_at_mut(i);
            rest[0] = subtract_rows(rest[0], lu[i * n..i * n + i].iter().zip(done.iter()));
        }
        for i in (0..n).rev() {
            let row = &lu[i * n..i * n + n];
            let (upto, later) = b.split_at_mut(i + 1);
            let mut v = subtract_rows(upto[i], row[i + 1..].iter().zip(later.iter()).rev());
            for x in &mut v {
                *x /= row[i];
            }
            upto[i] = v;
        }
    }

    /// Solves in place for one right-hand side of length n: forward substitution with the unit lower
    /// triangle, then back substitution with the upper one, each entry a dot product along its row of the
    /// factors (the back substitution's in the order of decreasing k, as a column-by-column one makes it).
    pub fn solve_in_place(&self, b: &mut [f64]) {
        let b = &mut b[..self.n];
        self.exchange_rows(b);
        with_known_size!(self.n, n => substitute(&self.rows, b, n))
    }
}

/// The n x n column-major `m` into `rows` by rows; false where an entry is not finite.
#[inline(always)]
pub(super) fn transpose_into(m: &[f64], rows: &mut [f64], n: usize) -> bool {
    let (m, rows) = (&m[..n * n], &mut rows[..n * n]);
    for (j, column) in m.chunks_exact(n.max(1)).enumerate() {
        for (i, v) in column.iter().enumerate() {
            rows[i * n + j] = *v;
        }
    }
    all_finite(rows)
}

/// LU factorisation with partial pivoting in place of the n x n row-major `a` (`DenseLu::factor`), the
/// pivots' rows into `pivots`. False where a pivot is exactly zero.
#[inline(always)]
pub(super) fn lu_rows_in_place(a: &mut [f64], pivots: &mut [usize], n: usize) -> bool {
    let (a, pivots) = (&mut a[..n * n], &mut pivots[..n]);
    for k in 0..n {
        let (mut p, mut best) = (k, a[k * n + k].abs());
        // By index: a strided iterator (`step_by`) stepped through a call per entry, a quarter of the
        // factorisation's instructions.
        for i in k + 1..n {
            let v = a[i * n + k].abs();
            if v > best {
                best = v;
                p = i;
            }
        }
        if best == 0.0 {
            return false;
        }
        pivots[k] = p;
        if p != k {
            let (upper, lower) = a.split_at_mut(p * n);
            upper[k * n..k * n + n].swap_with_slice(&mut lower[..n]);
        }
        // Right-looking elimination: each later row's entry in column k becomes L's, l = a_ik / a_kk, and
        // the row's later entries lose l * a_kj.
        let (done, later) = a.split_at_mut((k + 1) * n);
        let pivot_row = &done[k * n + k..k * n + n];
        let (d, u) = (pivot_row[0], &pivot_row[1..]);
        for row in later.chunks_exact_mut(n) {
            let l = row[k] / d;
            row[k] = l;
            for (x, u) in row[k + 1..].iter_mut().zip(u) {
                *x -= l * u;
            }
        }
    }
    true
}

/// The forward and back substitutions of `DenseLu::solve_in_place` (its row exchanges made) with the
/// n x n row-major factors `lu`.
#[inline(always)]
pub(super) fn substitute(lu: &[f64], b: &mut [f64], n: usize) {
    let (lu, b) = (&lu[..n * n], &mut b[..n]);
    for i in 1..n {
        let (done, rest) = b.split_at_mut(i);
        rest[0] = lu[i * n..i * n + i].iter().zip(done.iter()).fold(rest[0], |v, (l, x)| v - l * x);
    }
    for i in (0..n).rev() {
        let row = &lu[i * n..i * n + n];
        let (upto, later) = b.split_at_mut(i + 1);
        let v = row[i + 1..].iter().zip(later.iter()).rev().fold(upto[i], |v, (u, x)| v - u * x);
        upto[i] = v / row[i];
    }
}

/// `start - sum_k c_k row_k`, the products subtracted one at a time in order, the sum held in a local and
/// returned whole: summed in place in a buffer, each product's store may alias the next load for the
/// compiler, which then kept `SaddlePointLu::solve_rows`' loops scalar, a store per product.
#[inline(always)]
pub(super) fn subtract_rows<'a, const R: usize>(
    start: [f64; R],
    terms: impl Iterator<Item = (&'a f64, &'a [f64; R])>,
) -> [f64; R] {
    terms.fold(start, |mut sum, (c, row)| {
        for (v, x) in sum.iter_mut().zip(row) {
            *v -= c * x;
        }
        sum
    })
}

/// The larger of a running maximum `m` (not NaN) and `v`, ignoring a NaN `v` as `f64::max` does: the same
/// value for the values met here, in one comparison where `max` also tests both for NaN.
#[inline]
pub(super) fn larger(m: f64, v: f64) -> f64 {
    if v > m {
        v
    } else {
        m
    }
}

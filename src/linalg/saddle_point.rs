//! The saddle-point factorisation of the loaded equilibrium's matrix [[J, 0], [W, J^T]] through the null
//! space of J, and the stability test from it.

use super::all_finite;
use super::cholesky::positive_definite_in_place;
use super::lu::larger;
use super::lu::subtract_rows;
use super::lu::DenseLu;

/// Rows of the constraint block of a `SaddlePointLu` system: the six components of a pose.
pub const CONSTRAINTS: usize = 6;

/// A saddle-point system [[J, 0], [W, J^T]] [x; F] = [b; a], J (6 x k) of full row rank, W (k x k) any
/// matrix, factorised through the null space of J (the range-and-null-space method): J's rows are reduced by
/// Gauss-Jordan elimination with complete pivoting to the identity on six basic coordinates and X = B^-1 N
/// on the f = k - 6 free ones, so that Z = [-X; I] (on basic; free) spans J's null space, and the reduced
/// matrix Z^T W Z (f x f) is LU-factorised. A solve takes x = x_p + Z y with J x_p = b (x_p zero on the
/// free coordinates), (Z^T W Z) y = Z^T (a - W x_p), then F from the basic rows, B^T F = (a - W x)_b (the
/// free rows then hold too: Z^T (a - W x) = 0).
///
/// Where W is minus the Hessian of an energy and J the Jacobian of the constraints (the loaded equilibrium,
/// paper 000 eq 45), -sym(Z^T W Z) is the energy's Hessian on the motions the constraints allow: the
/// stability test (`reduced_negative_definite`) comes with the factorisation. With the reduced system only
/// f square, the factorisation costs a fraction of a dense LU of the whole (k + 6)-square matrix.
#[derive(Clone, Debug, Default)]
pub struct SaddlePointLu {
    /// [J | I6] reduced in place (k + 6 columns of six rows): J's columns become unit columns on the basic
    /// coordinates and X's on the free ones, the identity's the row operations T (T J = the reduced rows).
    reduced_rows: Vec<[f64; CONSTRAINTS]>,
    /// The basic coordinates in pivot order, the free ones in order (k = their count plus six, which the
    /// solves read).
    basic: [usize; CONSTRAINTS],
    free: Vec<usize>,
    /// B^-1 by rows: row i is the row of T at the i-th basic coordinate's pivot row.
    basic_inverse: [[f64; CONSTRAINTS]; CONSTRAINTS],
    /// Per free coordinate: X's column, its entries on the basic coordinates.
    x: Vec<[f64; CONSTRAINTS]>,
    /// Per coordinate j: W's entries in row j on the basic columns, and in column j on the basic rows.
    w_basic_columns: Vec<[f64; CONSTRAINTS]>,
    w_basic_rows: Vec<[f64; CONSTRAINTS]>,
    /// W Z, column-major (k x f): per free coordinate, W times its null-space direction.
    wz: Vec<f64>,
    /// Z^T W Z (f x f, column-major), kept for the definiteness test, and its LU factorisation.
    reduced: Vec<f64>,
    lu: DenseLu,
    /// Scratch of the solves and of the definiteness test.
    residual: Vec<f64>,
    free_part: Vec<f64>,
    symmetric: Vec<f64>,
}

impl SaddlePointLu {
    /// Factorises the system with J given by its k columns and W column-major (k x k). False where an entry
    /// is not finite, J's rank is below six (no pivot above 1e-12 of its largest entry is left: the
    /// constraints cannot all be met, the system is singular), or the reduced matrix has an exactly zero
    /// pivot.
    pub fn factor(&mut self, j_columns: impl IntoIterator<Item = [f64; CONSTRAINTS]>, w: &[f64], k: usize) -> bool {
        self.reduced_rows.clear();
        self.reduced_rows.extend(j_columns);
        assert_eq!(self.reduced_rows.len(), k, "one column of J per coordinate");
        assert_eq!(w.len(), k * k, "W is k x k");
        if k < CONSTRAINTS || !all_finite(self.reduced_rows.as_flattened()) || !all_finite(w) {
            return false;
        }
        with_known_size!(k - CONSTRAINTS, f => self.factor_checked(w, f + CONSTRAINTS))
    }

    /// `factor` once J's columns are in `reduced_rows` and every entry is known finite, k = f + 6 (the same
    /// steps for a literal f).
    #[inline(always)]
    fn factor_checked(&mut self, w: &[f64], k: usize) -> bool {
        let w = &w[..k * k];
        // J's largest entry: the scale of the rank decision.
        let largest = self.reduced_rows.as_flattened().iter().fold(0.0f64, |l, v| larger(l, v.abs()));
        self.reduced_rows.extend((0..CONSTRAINTS).map(|c| std::array::from_fn(|r| if r == c { 1.0 } else { 0.0 })));
        // The row of each basic coordinate's pivot, in pivot order; 1 for the rows without a pivot yet, 0 for
        // the others. A basic column is zero outside its pivot's row (cleared below), so searching the rows
        // left skips the basic columns too.
        let mut pivot_rows = [0usize; CONSTRAINTS];
        let mut rows_left = [1.0f64; CONSTRAINTS];
        // An entry's size on the rows left (zero on the others), and column c as a pivot candidate: kept where
        // its largest such entry beats the best so far (found without a branch per entry).
        let size =
            |column: &[f64; CONSTRAINTS], rows_left: &[f64; CONSTRAINTS], r: usize| column[r].abs() * rows_left[r];
        // The largest of the six sizes, as three pairs then across them (the maximum of finite values is
        // exact in any order, so the pivot is the same; pairs make vector maxima of two lanes).
        let consider =
            |best: &mut (usize, f64), c: usize, column: &[f64; CONSTRAINTS], rows_left: &[f64; CONSTRAINTS]| {
                let s: [f64; CONSTRAINTS] = std::array::from_fn(|r| size(column, rows_left, r));
                let pairs = [larger(s[0], s[2]), larger(s[1], s[3])];
                let pairs = [larger(pairs[0], s[4]), larger(pairs[1], s[5])];
                let largest_left = larger(pairs[0], pairs[1]);
                if largest_left > best.1 {
                    *best = (c, largest_left);
                }
            };
        // The pivot: the largest entry left, the first in column-major order among equals (the first column
        // holding it, then its first row there). The first is searched here; each later one while the
        // elimination before it updates the columns, in the same pass.
        let mut best = (0usize, 0.0f64);
        for (c, column) in self.reduced_rows[..k].iter().enumerate() {
            consider(&mut best, c, column, &rows_left);
        }
        for (i, (pivot_row, basic)) in pivot_rows.iter_mut().zip(self.basic.iter_mut()).enumerate() {
            if best.1 <= 1e-12 * largest {
                return false;
            }
            let pc = best.0;
            let column = &self.reduced_rows[pc];
            let pr = (0..CONSTRAINTS).find(|&r| size(column, &rows_left, r) == best.1).expect("the largest's row");
            rows_left[pr] = 0.0;
            // The next pivot is searched among J's columns but this one, which becomes a unit column on a
            // row no longer left (as every earlier one is), and after the last pivot not at all.
            let search = i + 1 < CONSTRAINTS;
            best = (0, 0.0);
            // The pivot row scaled to a unit pivot, then the pivot column cleared from every other row.
            let inverse = 1.0 / self.reduced_rows[pc][pr];
            let mut factors = self.reduced_rows[pc];
            factors[pr] = 0.0;
            let eliminate = |column: &mut [f64; CONSTRAINTS]| {
                let p = column[pr] * inverse;
                for (v, f) in column.iter_mut().zip(&factors) {
                    *v -= f * p;
                }
                // The pivot row's entry is written after the loop, as the loop would have updated it had p been
                // stored first (p - 0 p: the same bits); storing p first made the loop's vector loads wait on
                // that store (a failed store forwarding).
                column[pr] = p - factors[pr] * p;
            };
            // J's columns, then the identity's (the row operations), which are no pivot candidates.
            let (j_columns, operations) = self.reduced_rows[..k + CONSTRAINTS].split_at_mut(k);
            for (c, column) in j_columns.iter_mut().enumerate() {
                eliminate(column);
                if search && c != pc {
                    consider(&mut best, c, column, &rows_left);
                }
            }
            operations.iter_mut().for_each(eliminate);
            // Exactly a unit column (p above is 1 to round-off only).
            self.reduced_rows[pc] = std::array::from_fn(|r| if r == pr { 1.0 } else { 0.0 });
            *pivot_row = pr;
            *basic = pc;
        }
        let t = &self.reduced_rows[k..];
        for (row, &pr) in self.basic_inverse.iter_mut().zip(&pivot_rows) {
            for (v, column) in row.iter_mut().zip(t) {
                *v = column[pr];
            }
        }
        let basic = self.basic;
        // The six basic coordinates are distinct (each pivot's column a unit column after it): f are free.
        let f = k - CONSTRAINTS;
        self.free.resize(f, 0);
        let mut free_slots = self.free[..f].iter_mut();
        for c in (0..k).filter(|c| !basic.contains(c)) {
            *free_slots.next().expect("f free coordinates") = c;
        }
        // Filled in place (a resize, then stores): `extend` over an iterator was compiled out of line once
        // per size of `with_known_size!`.
        self.x.resize(f, [0.0; CONSTRAINTS]);
        for (xc, &c) in self.x.iter_mut().zip(&self.free[..f]) {
            *xc = std::array::from_fn(|i| self.reduced_rows[c][pivot_rows[i]]);
        }
        self.w_basic_columns.resize(k, [0.0; CONSTRAINTS]);
        // Each basic column of W read whole (contiguous), its entries spread over the rows' arrays.
        for (i, &b) in basic.iter().enumerate() {
            for (wb, v) in self.w_basic_columns.iter_mut().zip(&w[b * k..b * k + k]) {
                wb[i] = *v;
            }
        }
        self.w_basic_rows.resize(k, [0.0; CONSTRAINTS]);
        for (c, wb) in self.w_basic_rows.iter_mut().enumerate() {
            *wb = std::array::from_fn(|i| w[c * k + basic[i]]);
        }
        // W Z, column by column of Z: z_c = e_free[c] - sum_i X[c, i] e_basic[i].
        self.wz.resize(k * f, 0.0);
        for ((wz_c, &fc), xc) in self.wz.chunks_exact_mut(k).zip(&self.free[..f]).zip(&self.x[..f]) {
            let column = &w[fc * k..fc * k + k];
            for ((out, v), wb) in wz_c.iter_mut().zip(column).zip(&self.w_basic_columns[..k]) {
                *out = v - dot(wb, xc);
            }
        }
        // Z^T (W Z): entry (r, c) = (W Z)[free[r], c] - sum_i X[r, i] (W Z)[basic[i], c].
        self.reduced.resize(f * f, 0.0);
        for (reduced_c, wz_c) in self.reduced.chunks_exact_mut(f.max(1)).zip(self.wz.chunks_exact(k)) {
            let on_basic: [f64; CONSTRAINTS] = std::array::from_fn(|i| wz_c[basic[i]]);
            for ((out, &fr), xr) in reduced_c.iter_mut().zip(&self.free[..f]).zip(&self.x[..f]) {
                *out = wz_c[fr] - dot(xr, &on_basic);
            }
        }
        f == 0 || self.lu.factor(&self.reduced, f)
    }

    /// Solves in place for R right-hand sides at once, stored by rows in equation order (b's six rows, then
    /// a's k); on return the rows hold the unknowns in their order (x's k, then F's six).
    pub fn solve_rows<const R: usize>(&mut self, rows: &mut [[f64; R]]) {
        with_known_size!(self.free.len(), f => self.solve_many(rows, f))
    }

    /// `solve_rows` with f the number of free coordinates (the same steps for a literal f).
    #[inline(always)]
    fn solve_many<const R: usize>(&mut self, rows: &mut [[f64; R]], f: usize) {
        let k = f + CONSTRAINTS;
        let (free, x, w_basic_columns) = (&self.free[..f], &self.x[..f], &self.w_basic_columns[..k]);
        let rows = &mut rows[..k + CONSTRAINTS];
        let (b, a) = rows.split_at(CONSTRAINTS);
        // x_p on the basic coordinates: B^-1 b.
        let mut x_basic = [[0.0; R]; CONSTRAINTS];
        for (xi, bi) in x_basic.iter_mut().zip(&self.basic_inverse) {
            for (bc, t) in b.iter().zip(bi) {
                for (x, v) in xi.iter_mut().zip(bc) {
                    *x += t * v;
                }
            }
        }
        // The residual a - W x_p.
        self.residual.clear();
        self.residual.resize(k * R, 0.0);
        let (residual, _) = self.residual.as_chunks_mut::<R>();
        // Each row is summed in a local and stored once (`subtract_rows`).
        for ((r, aj), wb) in residual.iter_mut().zip(a).zip(w_basic_columns) {
            *r = subtract_rows(*aj, wb.iter().zip(&x_basic));
        }
        // y = (Z^T W Z)^-1 Z^T (a - W x_p).
        self.free_part.clear();
        self.free_part.resize(f * R, 0.0);
        let (y, _) = self.free_part.as_chunks_mut::<R>();
        for ((yc, &fc), xc) in y.iter_mut().zip(free).zip(x) {
            *yc = subtract_rows(residual[fc], xc.iter().zip(&self.basic).map(|(xi, &bi)| (xi, &residual[bi])));
        }
        if f > 0 {
            self.lu.solve_rows(y);
        }
        // x = x_p + Z y on the basic coordinates (each summed over the free coordinates in their order).
        for (i, xb) in x_basic.iter_mut().enumerate() {
            *xb = subtract_rows(*xb, x.iter().zip(y.iter()).map(|(xc, yc)| (&xc[i], yc)));
        }
        // The basic rows' (a - W x)_b, then F = B^-T (a - W x)_b.
        let mut statics = [[0.0; R]; CONSTRAINTS];
        for (s, &bi) in statics.iter_mut().zip(&self.basic) {
            *s = a[bi];
        }
        // The free coordinates' terms, then the basic ones' (two loops: a chained iterator's halves
        // compiled to a branch per term).
        let w_rows = &self.w_basic_rows;
        let subtract = |statics: &mut [[f64; R]; CONSTRAINTS], wr: &[f64; CONSTRAINTS], xv: &[f64; R]| {
            for (s, w) in statics.iter_mut().zip(wr) {
                for (v, x) in s.iter_mut().zip(xv) {
                    *v -= w * x;
                }
            }
        };
        for (&fc, yc) in free.iter().zip(y.iter()) {
            subtract(&mut statics, &w_rows[fc], yc);
        }
        for (&bc, xb) in self.basic.iter().zip(&x_basic) {
            subtract(&mut statics, &w_rows[bc], xb);
        }
        let mut multipliers = [[0.0; R]; CONSTRAINTS];
        for (si, bi) in statics.iter().zip(&self.basic_inverse) {
            for (m, t) in multipliers.iter_mut().zip(bi) {
                for (v, s) in m.iter_mut().zip(si) {
                    *v += t * s;
                }
            }
        }
        for (&fc, yc) in free.iter().zip(y.iter()) {
            rows[fc] = *yc;
        }
        for (&bc, xb) in self.basic.iter().zip(&x_basic) {
            rows[bc] = *xb;
        }
        rows[k..].copy_from_slice(&multipliers);
    }

    /// Solves in place for one right-hand side (as `solve_rows`, the same steps): every product with the
    /// basic coordinates is one of six-entry arrays, where `solve_rows::<1>` would walk them one
    /// single-entry row at a time (a chord step of the loaded equilibrium makes one such solve per leg).
    pub fn solve_in_place(&mut self, rows: &mut [f64]) {
        with_known_size!(self.free.len(), f => self.solve_one(rows, f))
    }

    /// `solve_in_place` with f the number of free coordinates (the same steps for a literal f).
    #[inline(always)]
    fn solve_one(&mut self, rows: &mut [f64], f: usize) {
        let k = f + CONSTRAINTS;
        let (free, x, w_basic_columns) = (&self.free[..f], &self.x[..f], &self.w_basic_columns[..k]);
        let rows = &mut rows[..k + CONSTRAINTS];
        let (b, a) = rows.split_at(CONSTRAINTS);
        let b: &[f64; CONSTRAINTS] = b.try_into().expect("six constraint rows");
        // x_p on the basic coordinates: B^-1 b; the residual a - W x_p.
        let mut x_basic: [f64; CONSTRAINTS] = std::array::from_fn(|i| dot(&self.basic_inverse[i], b));
        self.residual.resize(k, 0.0);
        for ((r, aj), wb) in self.residual.iter_mut().zip(a).zip(w_basic_columns) {
            *r = aj - dot(wb, &x_basic);
        }
        let residual = &self.residual[..k];
        // y = (Z^T W Z)^-1 Z^T (a - W x_p).
        let on_basic: [f64; CONSTRAINTS] = std::array::from_fn(|i| residual[self.basic[i]]);
        self.free_part.resize(f, 0.0);
        for ((y, &fc), xc) in self.free_part.iter_mut().zip(free).zip(x) {
            *y = residual[fc] - dot(xc, &on_basic);
        }
        let y = &mut self.free_part[..f];
        if f > 0 {
            self.lu.solve_in_place(y);
        }
        // x = x_p + Z y on the basic coordinates; then the basic rows' (a - W x)_b, and F = B^-T (a - W x)_b.
        for (xc, yc) in x.iter().zip(y.iter()) {
            axpy(&mut x_basic, -yc, xc);
        }
        let mut statics: [f64; CONSTRAINTS] = std::array::from_fn(|i| a[self.basic[i]]);
        for (&fc, yc) in free.iter().zip(y.iter()) {
            axpy(&mut statics, -yc, &self.w_basic_rows[fc]);
        }
        for (&bc, xb) in self.basic.iter().zip(&x_basic) {
            axpy(&mut statics, -xb, &self.w_basic_rows[bc]);
        }
        let mut multipliers = [0.0; CONSTRAINTS];
        for (si, bi) in statics.iter().zip(&self.basic_inverse) {
            axpy(&mut multipliers, *si, bi);
        }
        // The unknowns in their order: x's k (free and basic coordinates), then F's six.
        for (&fc, yc) in free.iter().zip(y.iter()) {
            rows[fc] = *yc;
        }
        for (&bc, xb) in self.basic.iter().zip(&x_basic) {
            rows[bc] = *xb;
        }
        rows[k..].copy_from_slice(&multipliers);
    }

    /// The symmetric part of the reduced matrix Z^T W Z is negative definite, to a margin of 1e-12 of its
    /// largest entry (true where J leaves no free coordinate). Any basis of J's null space gives the same
    /// answer (Sylvester's law of inertia), so the one of the factorisation serves.
    pub fn reduced_negative_definite(&mut self) -> bool {
        let f = self.free.len();
        if f == 0 {
            return true;
        }
        let (r, s) = (&self.reduced, &mut self.symmetric);
        s.clear();
        s.resize(f * f, 0.0);
        with_known_size!(f, f => negative_definite_symmetric_part(r, s, f))
    }
}

/// The symmetric part of the f x f column-major matrix `r` is negative definite, to a margin of 1e-12 of
/// its largest entry (`SaddlePointLu::reduced_negative_definite`), `s` (f x f) the scratch.
#[inline(always)]
pub(super) fn negative_definite_symmetric_part(r: &[f64], s: &mut [f64], f: usize) -> bool {
    let (r, s) = (&r[..f * f], &mut s[..f * f]);
    // Only the half the Cholesky reads (entries (c, row) with row <= c; the sum is exactly symmetric, so
    // the largest entry is there too).
    let mut largest = 0.0f64;
    for c in 0..f {
        for row in 0..=c {
            let v = -0.5 * (r[c * f + row] + r[row * f + c]);
            s[c * f + row] = v;
            largest = larger(largest, v.abs());
        }
    }
    let margin = 1e-12 * largest.max(f64::MIN_POSITIVE);
    for d in 0..f {
        s[d * f + d] -= margin;
    }
    positive_definite_in_place(s, f)
}

pub(super) fn dot(a: &[f64; CONSTRAINTS], b: &[f64; CONSTRAINTS]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// `y += c x` on six entries.
#[inline(always)]
pub(super) fn axpy(y: &mut [f64; CONSTRAINTS], c: f64, x: &[f64; CONSTRAINTS]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += c * x;
    }
}

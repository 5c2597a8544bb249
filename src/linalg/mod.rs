//! Small dense linear algebra the hot paths need beyond nalgebra's fixed-size types: the saddle-point
//! factorisation of the loaded equilibrium's (n + m + 6)-square matrix through the null space of its
//! constraints, and an in-place LU factorisation with partial pivoting, on reused buffers (the loaded
//! equilibrium factorises several times per point, and allocating or going through generic dynamic
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

/// Orthonormal directions of R^6 grown by Gram-Schmidt: the spans of vectors added, then their orthogonal
/// complement (`complement`). A vector's part outside the directions so far is a new direction when it is
/// above `SPAN_SHARE` of the largest vector added (the rank decision `span_basis` makes with singular
/// values), largest part first; each direction is orthogonalised twice, so the set is orthonormal to
/// round-off even where the vectors are nearly dependent. For a handful of six-vectors this costs a few
/// hundred operations where an SVD costs thousands, and nothing is allocated.
#[derive(Clone, Copy, Debug)]
pub struct Orthonormal6 {
    directions: [nalgebra::Vector6<f64>; 6],
    len: usize,
    largest: f64,
}

impl Default for Orthonormal6 {
    fn default() -> Self {
        Orthonormal6 { directions: [nalgebra::Vector6::zeros(); 6], len: 0, largest: 0.0 }
    }
}

impl Orthonormal6 {
    /// The directions so far.
    pub fn directions(&self) -> &[nalgebra::Vector6<f64>] {
        &self.directions[..self.len]
    }

    /// Adds the span of `vectors`, six at a time. False, leaving the set unusable, where a vector is not
    /// finite or has an entry beyond `MAX_ENTRY`.
    pub fn span(&mut self, vectors: impl IntoIterator<Item = nalgebra::Vector6<f64>>) -> bool {
        let mut part = [nalgebra::Vector6::zeros(); 6];
        let mut count = 0;
        for v in vectors {
            part[count] = v;
            count += 1;
            if count == 6 {
                if !self.span_part(&mut part) {
                    return false;
                }
                count = 0;
            }
        }
        count == 0 || self.span_part(&mut part[..count])
    }

    /// `span` of at most six vectors, which it overwrites.
    fn span_part(&mut self, candidates: &mut [nalgebra::Vector6<f64>]) -> bool {
        if !candidates.iter().flatten().all(|v| v.is_finite() && v.abs() <= MAX_ENTRY) {
            return false;
        }
        self.largest = candidates.iter().map(|v| v.norm_squared()).fold(self.largest, f64::max);
        self.grow(candidates, SPAN_SHARE * SPAN_SHARE * self.largest);
        true
    }

    /// Adds the directions orthogonal to `other` (`complement`: unit vectors, so the rank decision's scale
    /// is at least 1).
    pub fn span_complement_of(&mut self, other: &Orthonormal6) {
        let mut candidates = [nalgebra::Vector6::zeros(); 6];
        let count = other.complement_into(&mut candidates);
        self.largest = self.largest.max(1.0);
        self.grow(&mut candidates[..count], SPAN_SHARE * SPAN_SHARE * self.largest);
    }

    /// An orthonormal basis of the directions orthogonal to the set. The projector P = I - sum q q^T onto
    /// them has the unit vectors' parts outside the set as its columns and their squared norms on its
    /// diagonal; while a direction is missing the largest is at least 1/6 (the trace is the dimension
    /// left), so the largest column, normalised, is a direction, and P loses it.
    pub fn complement(&self) -> impl Iterator<Item = nalgebra::Vector6<f64>> {
        let mut new = [nalgebra::Vector6::zeros(); 6];
        let count = self.complement_into(&mut new);
        new.into_iter().take(count)
    }

    /// `complement` into the first entries of `new`; returns their count.
    fn complement_into(&self, new: &mut [nalgebra::Vector6<f64>; 6]) -> usize {
        // P is not formed: its diagonal is kept, and the one column a direction is taken from is made when
        // it is chosen, each entry reduced by the directions in their order (the same products in the same
        // order as P's, at a fifth of the cost where one or two directions are missing).
        let mut diagonal = [1.0f64; 6];
        for q in self.directions() {
            for (d, v) in diagonal.iter_mut().zip(q.iter()) {
                *d -= v * v;
            }
        }
        // The new directions apart from the set's (which are not copied), each reduced by the set's and
        // then by the new ones before it.
        let missing = 6 - self.len;
        for n in 0..missing {
            let k = (0..6).fold(0, |best, k| if diagonal[k] > diagonal[best] { k } else { best });
            let mut column = nalgebra::Vector6::ith(k, 1.0);
            for q in self.directions() {
                column -= q * q[k];
            }
            for q in &new[..n] {
                column -= q * q[k];
            }
            // Once more against every direction: the column carries round-off of what P removed.
            let mut q = column / diagonal[k].sqrt();
            remove_parts_along(&mut q, self.directions());
            remove_parts_along(&mut q, &new[..n]);
            q /= q.norm();
            for (d, v) in diagonal.iter_mut().zip(q.iter()) {
                *d -= v * v;
            }
            new[n] = q;
        }
        missing
    }

    /// Adds the candidates' parts outside the set, largest first, while its squared norm is above
    /// `threshold` (candidates finite).
    fn grow(&mut self, candidates: &mut [nalgebra::Vector6<f64>], threshold: f64) {
        candidates.iter_mut().for_each(|c| remove_parts_along(c, self.directions()));
        let mut left = candidates.len();
        while self.len < 6 && left > 0 {
            let (i, size) = (0..left).map(|i| (i, candidates[i].norm_squared())).fold((0, -1.0), |best, c| {
                if c.1 > best.1 {
                    c
                } else {
                    best
                }
            });
            if size <= threshold {
                break;
            }
            // Again against the set: the first pass leaves round-off of the size of what it removed.
            let mut q = candidates[i] / size.sqrt();
            candidates.swap(i, left - 1);
            left -= 1;
            remove_parts_along(&mut q, self.directions());
            q /= q.norm();
            candidates[..left].iter_mut().for_each(|c| remove_parts_along(c, &[q]));
            self.directions[self.len] = q;
            self.len += 1;
        }
    }
}

/// Removes from `v` its parts along each of the orthonormal `directions`, one after the other (modified
/// Gram-Schmidt).
fn remove_parts_along(v: &mut nalgebra::Vector6<f64>, directions: &[nalgebra::Vector6<f64>]) {
    for q in directions {
        *v -= q * q.dot(v);
    }
}

/// The part of `x`'s columns outside the column space of `y` (x - Q Q^T x, Q = `span_basis(y)`). None where
/// `y` is not finite.
pub fn outside_span(x: &nalgebra::DMatrix<f64>, y: &nalgebra::DMatrix<f64>) -> Option<nalgebra::DMatrix<f64>> {
    let q = span_basis(y)?;
    Some(x - &q * (q.transpose() * x))
}

/// `$body` with `$size` bound to `$n`, a literal where `$n` is one of the small sizes the shipped legs'
/// reduced systems have (1 to 12): after inlining, the body's loops have lengths known when compiled, and
/// the compiler drops their bounds checks and unrolls them. The same operations in the same order for
/// every size.
macro_rules! with_known_size {
    ($n:expr, $size:ident => $body:expr) => {
        with_known_size!(@literals $n, $size => $body; 1 2 3 4 5 6 7 8 9 10 11 12)
    };
    (@literals $n:expr, $size:ident => $body:expr; $($literal:literal)*) => {
        match $n {
            $($literal => {
                let $size = $literal;
                $body
            })*
            other => {
                let $size = other;
                $body
            }
        }
    };
}

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
fn negative_definite_symmetric_part(r: &[f64], s: &mut [f64], f: usize) -> bool {
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

/// The n x n column-major `m` into `rows` by rows; false where an entry is not finite.
#[inline(always)]
fn transpose_into(m: &[f64], rows: &mut [f64], n: usize) -> bool {
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
fn lu_rows_in_place(a: &mut [f64], pivots: &mut [usize], n: usize) -> bool {
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
fn substitute(lu: &[f64], b: &mut [f64], n: usize) {
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
fn subtract_rows<'a, const R: usize>(
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

/// Every value finite: v * 0 is zero for a finite v and NaN for any other, so the products summed in four
/// lanes (two vector registers, no branch per value) sum to zero exactly where every value is finite. A
/// matrix's entries are its `as_slice()`: nalgebra's iterator over them took a dozen instructions per entry
/// (on the unloaded 3-PUU, 0.4 k per leg's stiffness).
pub fn all_finite(values: &[f64]) -> bool {
    let chunks = values.chunks_exact(4);
    let rest = chunks.remainder().iter().fold(0.0, |sum, v| sum + v * 0.0);
    let lanes = chunks.fold([0.0f64; 4], |mut lanes, chunk| {
        for (lane, v) in lanes.iter_mut().zip(chunk) {
            *lane += v * 0.0;
        }
        lanes
    });
    lanes.iter().sum::<f64>() + rest == 0.0
}

/// The larger of a running maximum `m` (not NaN) and `v`, ignoring a NaN `v` as `f64::max` does: the same
/// value for the values met here, in one comparison where `max` also tests both for NaN.
#[inline]
fn larger(m: f64, v: f64) -> f64 {
    if v > m {
        v
    } else {
        m
    }
}

/// Cholesky factorisation in place of a dense n x n symmetric matrix (row-major, or column-major: the same
/// for a symmetric one): its lower triangle is read and overwritten by L row by row, each entry one dot
/// product of two rows' leading parts (L_ij = (a_ij - sum_k<j L_ik L_jk) / L_jj) summed in order: its
/// callers read the factor's values (`small_cholesky`, `spd_inverse6`), which keep their bits so. False
/// where a pivot is not positive or not finite (not positive definite to round-off).
fn dense_cholesky(a: &mut [f64], n: usize) -> bool {
    cholesky_rows(a, n, |x, y| x.iter().zip(y).map(|(x, y)| x * y).sum())
}

/// True where the dense n x n symmetric matrix (its lower triangle read, by rows) is positive definite to
/// round-off: `dense_cholesky`'s factorisation with the dot products taken as two running sums
/// (`paired_dot`: two terms per vector operation). Only the pivots' signs are read, so the order of the
/// sums changes no result but at a pivot within round-off of zero (the stability test's margin, 1e-12 of
/// the largest entry, is ten thousand times round-off), and the factor's values go nowhere.
#[inline(always)]
fn positive_definite_in_place(a: &mut [f64], n: usize) -> bool {
    cholesky_rows(a, n, paired_dot)
}

/// The row-by-row Cholesky factorisation of `dense_cholesky`, each entry's dot product of two rows' leading
/// parts taken by `dot`.
#[inline(always)]
fn cholesky_rows(a: &mut [f64], n: usize, dot: impl Fn(&[f64], &[f64]) -> f64) -> bool {
    for i in 0..n {
        let (above, rest) = a.split_at_mut(i * n);
        let row = &mut rest[..=i];
        for j in 0..i {
            let row_j = &above[j * n..j * n + j + 1];
            row[j] = (row[j] - dot(&row[..j], &row_j[..j])) / row_j[j];
        }
        let d = row[i] - dot(&row[..i], &row[..i]);
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        row[i] = d.sqrt();
    }
    true
}

/// x . y as two running sums, of the even and of the odd terms (which the compiler keeps side by side in
/// one vector register), added at the end.
#[inline(always)]
fn paired_dot(x: &[f64], y: &[f64]) -> f64 {
    let (x_pairs, y_pairs) = (x.chunks_exact(2), y[..x.len()].chunks_exact(2));
    let last = x_pairs.remainder().iter().zip(y_pairs.remainder()).map(|(x, y)| x * y).sum::<f64>();
    let mut sum = [0.0f64; 2];
    for (a, b) in x_pairs.zip(y_pairs) {
        sum[0] += a[0] * b[0];
        sum[1] += a[1] * b[1];
    }
    sum[0] + sum[1] + last
}

fn dot(a: &[f64; CONSTRAINTS], b: &[f64; CONSTRAINTS]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// `y += c x` on six entries.
#[inline(always)]
fn axpy(y: &mut [f64; CONSTRAINTS], c: f64, x: &[f64; CONSTRAINTS]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += c * x;
    }
}

/// Cholesky factorisation of a small symmetric matrix in place (its lower triangle read, L written there;
/// the strict upper triangle left as it is): false where a pivot is not positive or not finite (not
/// positive definite to round-off). The fixed-size face of `dense_cholesky` (the rows laid end to end).
pub fn small_cholesky<const D: usize>(a: &mut [[f64; D]; D]) -> bool {
    dense_cholesky(a.as_flattened_mut(), D)
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
    all_finite(inverse.as_slice()).then_some(inverse)
}

/// A Cholesky factorisation A = U^T U made in the caller's buffer over A's envelope (MSA's reduced stiffness
/// at every pose, factorised where it was assembled): column i holds A's upper triangle from row `first[i]`,
/// its first entry that may be non-zero, down to the diagonal. The envelope is given, from the structure's
/// shape, rather than found in the numbers: the entries above it must be zero, and the factor's are
/// (a Cholesky factor has no fill outside the envelope), so a banded or block-structured matrix costs what
/// its envelope holds, not n^3 / 6, and only the envelope need be assembled or cleared. The skyline
/// factorisation of Bathe & Wilson, "Numerical Methods in Finite Element Analysis" (1976), s. 8.2: each
/// entry one dot product of two columns' overlapping parts.
#[derive(Clone, Debug, Default)]
pub struct EnvelopeCholesky {
    /// Per column: the first row of its upper triangle inside the envelope.
    first: Vec<usize>,
    /// 1 / U_ii of the coordinates the last factorisation eliminated (as many as it eliminated).
    reciprocal: Vec<f64>,
    /// Two columns' entries side by side while they are made.
    pairs: Vec<[f64; 2]>,
}

impl EnvelopeCholesky {
    /// The factorisation of matrices whose column i is zero above row `first[i]` (at most i).
    pub fn new(first: Vec<usize>) -> EnvelopeCholesky {
        assert!(first.iter().enumerate().all(|(i, &f)| f <= i), "an envelope starts at or above the diagonal");
        EnvelopeCholesky { first, reciprocal: Vec::new(), pairs: Vec::new() }
    }

    /// The envelope's first row in each column.
    pub fn first(&self) -> &[usize] {
        &self.first
    }

    /// Factorises the n x n matrix (n the envelope's size; column-major, columns `stride` long) in place:
    /// its upper triangle (read) becomes U, its strict lower triangle is left untouched. The smallest and
    /// largest pivot U_ii^2, or None where a pivot is not positive or not finite (not positive definite).
    pub fn factor(&mut self, a: &mut [f64], stride: usize) -> Option<(f64, f64)> {
        self.eliminate(a, stride, self.first.len())
    }

    /// Eliminates the first `m` of the n coordinates of the symmetric n x n matrix: with A = [[A_yy, A_yu],
    /// [A_uy, A_uu]], A_yy = U^T U, the upper triangle's first m rows become [U, U^-T A_yu] and the
    /// trailing block's upper triangle the Schur complement A_uu - A_uy A_yy^-1 A_yu (static condensation,
    /// as one factorisation). Pivots as `factor`, over the m eliminated.
    ///
    /// Each entry of a column waits for the one above it (a triangular solve), so the columns are made two
    /// at a time, entry j of both from one reading of column j: two chains of dependent operations side by
    /// side, which the processor overlaps, and half the loops. The entries made are read back from a buffer
    /// of pairs (this column's and the next's), each pair stored whole and read whole: reading two entries
    /// of a column stored one by one stalls until both stores complete. The pivots' reciprocals are kept, so
    /// those chains multiply where a division would take several times as long. A dot product may start
    /// above a column's envelope: the entries there are zeros.
    pub fn eliminate(&mut self, a: &mut [f64], stride: usize, m: usize) -> Option<(f64, f64)> {
        let n = self.first.len();
        assert!(m <= n && n <= stride && a.len() >= stride * n.saturating_sub(1) + n);
        self.reciprocal.clear();
        self.reciprocal.resize(m, 0.0);
        let (first, reciprocal, pairs) = (&self.first, &mut self.reciprocal, &mut self.pairs);
        let mut pivots = (f64::INFINITY, 0.0f64);
        let mut i = 0;
        while i < n {
            let (before, rest) = a.split_at_mut(i * stride);
            if i + 1 < n {
                let (this, next) = rest.split_at_mut(stride);
                let (this, next) = (&mut this[..=i], &mut next[..=i + 1]);
                let top = first[i].min(first[i + 1]);
                // Indexed by row; rows above `top` are zeros in both columns and never read.
                pairs.resize(i + 1, [0.0; 2]);
                for j in top..i {
                    // Below m: U_jk = (a_jk - sum_p<j U_pj U_pk) / U_jj; from m: a_jk - sum_p<m U_pj U_pk.
                    let end = j.min(m);
                    let start = top.max(first[j]).min(end);
                    let sum = pair_dot(&before[j * stride + start..j * stride + end], &pairs[start..end]);
                    let scale = if j < m { reciprocal[j] } else { 1.0 };
                    let entry = [(this[j] - sum[0]) * scale, (next[j] - sum[1]) * scale];
                    pairs[j] = entry;
                    [this[j], next[j]] = entry;
                }
                // Column i's pivot, then column i + 1's entry in row i and its pivot, from the sums of
                // column i's entries times both columns' and of column i + 1's squared.
                let end = i.min(m);
                let above = &pairs[top.min(end)..end];
                let (by_this, by_next) = above.iter().fold(([0.0f64; 2], 0.0f64), |(s, q), p| {
                    ([s[0] + p[0] * p[0], s[1] + p[0] * p[1]], q + p[1] * p[1])
                });
                pivots = pivot(this[i] - by_this[0], i, m, reciprocal, pivots, &mut this[i])?;
                let scale = if i < m { reciprocal[i] } else { 1.0 };
                next[i] = (next[i] - by_this[1]) * scale;
                let from_row_i = if i < m { next[i] * next[i] } else { 0.0 };
                pivots = pivot(next[i + 1] - by_next - from_row_i, i + 1, m, reciprocal, pivots, &mut next[i + 1])?;
                i += 2;
            } else {
                // The last column of an odd count, alone.
                let this = &mut rest[..=i];
                for j in first[i]..i {
                    let end = j.min(m);
                    let start = first[i].max(first[j]).min(end);
                    let dot = paired_dot(&before[j * stride + start..j * stride + end], &this[start..end]);
                    this[j] = (this[j] - dot) * if j < m { reciprocal[j] } else { 1.0 };
                }
                let leading = &this[first[i].min(m)..i.min(m)];
                let d = this[i] - paired_dot(leading, leading);
                pivots = pivot(d, i, m, reciprocal, pivots, &mut this[i])?;
                i += 1;
            }
        }
        Some(pivots)
    }

    /// Solves U^T y = b in place (the first half of a solve: with it, B^T A^-1 C = (U^-T B)^T (U^-T C)), `u`
    /// the buffer the factorisation worked in: y_i = (b_i - sum_k<i U_ki y_k) / U_ii.
    pub fn forward_in_place(&self, u: &[f64], stride: usize, b: &mut [f64]) {
        let b = &mut b[..self.reciprocal.len()];
        for i in 0..b.len() {
            let column = &u[i * stride..i * stride + i + 1];
            let f = self.first[i];
            b[i] = (b[i] - paired_dot(&b[f..i], &column[f..i])) * self.reciprocal[i];
        }
    }

    /// Solves A x = b in place for one right-hand side, `u` the buffer `factor` worked in.
    pub fn solve_in_place(&self, u: &[f64], stride: usize, b: &mut [f64]) {
        self.forward_in_place(u, stride, b);
        let b = &mut b[..self.reciprocal.len()];
        for i in (0..b.len()).rev() {
            let column = &u[i * stride..i * stride + i + 1];
            b[i] *= self.reciprocal[i];
            let bi = b[i];
            let f = self.first[i];
            for (x, l) in b[f..i].iter_mut().zip(&column[f..i]) {
                *x -= l * bi;
            }
        }
    }
}

/// sum_k x_k [p_k0, p_k1]: one column's entries times two columns' side by side, as two running sums (even
/// and odd k) of pairs, which the compiler keeps in vector registers.
#[inline(always)]
fn pair_dot(x: &[f64], pairs: &[[f64; 2]]) -> [f64; 2] {
    let (x_two, p_two) = (x.chunks_exact(2), pairs[..x.len()].chunks_exact(2));
    let mut last = [0.0f64; 2];
    if let (Some(x), Some(p)) = (x_two.remainder().first(), p_two.remainder().first()) {
        last = [x * p[0], x * p[1]];
    }
    let (mut even, mut odd) = ([0.0f64; 2], [0.0f64; 2]);
    for (x, p) in x_two.zip(p_two) {
        even[0] += x[0] * p[0][0];
        even[1] += x[0] * p[0][1];
        odd[0] += x[1] * p[1][0];
        odd[1] += x[1] * p[1][1];
    }
    [even[0] + odd[0] + last[0], even[1] + odd[1] + last[1]]
}

/// A column's diagonal from its pivot d (a_ii less the squares of the entries above): below m, U_ii =
/// sqrt(d) into `diagonal` and its reciprocal kept, `pivots` (smallest, largest) widened, or None where d is
/// not positive or not finite; from m, d itself (the Schur complement's diagonal).
#[inline(always)]
fn pivot(
    d: f64,
    i: usize,
    m: usize,
    reciprocal: &mut [f64],
    pivots: (f64, f64),
    diagonal: &mut f64,
) -> Option<(f64, f64)> {
    if i >= m {
        *diagonal = d;
        return Some(pivots);
    }
    if !(d > 0.0 && d.is_finite()) {
        return None;
    }
    let root = d.sqrt();
    *diagonal = root;
    reciprocal[i] = 1.0 / root;
    Some((pivots.0.min(d), pivots.1.max(d)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// The finiteness test by products with zero: true for finite values of any size and sign (the largest,
    /// the smallest subnormal, minus zero), false for one NaN or infinity of either sign at any place, in
    /// the four lanes or the remainder, for every length up to nine.
    #[test]
    fn all_finite_finds_any_nan_or_infinity() {
        let finite = [1.0, -0.0, f64::MAX, -f64::MAX, 5e-324, -3.5, 0.0, 1e-300, 7.0];
        for n in 0..=finite.len() {
            assert!(all_finite(&finite[..n]), "{n} finite values");
            for place in 0..n {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut values = finite[..n].to_vec();
                    values[place] = bad;
                    assert!(!all_finite(&values), "{bad} at {place} of {n}");
                }
            }
        }
    }

    /// Gaussian elimination with partial pivoting is one sequence of roundings: the stack LU's solutions
    /// are nalgebra's `LU` solutions to the bit, on matrices whose pivots need row exchanges (entries
    /// spread over six orders of magnitude), on one with a zero column part-way (passed over, then no
    /// solution), on an exactly singular one and on sizes 1, 3 and 6; and they solve the system (residual
    /// at round-off).
    #[test]
    fn small_lu_solves_as_nalgebras_lu_to_the_bit() {
        fn agree<const N: usize>(m: nalgebra::SMatrix<f64, N, N>, b: nalgebra::SVector<f64, N>) {
            let ours = SmallLu::new(&m).solve(&b);
            // nalgebra's on the dynamic size (the same steps as on a fixed one, compared below for six).
            let theirs =
                DMatrix::from_column_slice(N, N, m.as_slice()).lu().solve(&DVector::from_column_slice(b.as_slice()));
            match (ours, theirs) {
                (Some(x), Some(y)) => {
                    let bits = |v: &[f64]| v.iter().map(|e| e.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(x.as_slice()), bits(y.as_slice()), "{m}");
                    if x.iter().all(|v| v.is_finite()) && m.iter().all(|v| v.is_finite()) {
                        assert!((m * x - b).amax() <= 1e-9 * (m.amax() * x.amax() + b.amax()), "{m} {x}");
                    }
                }
                (None, None) => {}
                (x, y) => panic!("{m}: ours {x:?}, nalgebra's {y:?}"),
            }
        }
        let mut next = stream(11);
        for _ in 0..200 {
            let spread = nalgebra::Matrix6::from_fn(|_, _| 10f64.powf(6.0 * next()));
            let (m, b) =
                (nalgebra::Matrix6::from_fn(|r, c| next() * spread[(r, c)]), nalgebra::Vector6::from_fn(|_, _| next()));
            agree(m, b);
            let (x, y) = (SmallLu::new(&m).solve(&b).unwrap(), m.lu().solve(&b).unwrap());
            assert!(x.iter().zip(&y).all(|(x, y)| x.to_bits() == y.to_bits()), "{m}");
            agree(nalgebra::Matrix3::from_fn(|_, _| next()), nalgebra::Vector3::from_fn(|_, _| next()));
            agree(nalgebra::Matrix1::new(next()), nalgebra::Vector1::new(next()));
        }
        let mut zero_column = nalgebra::Matrix6::from_fn(|_, _| next());
        zero_column.column_mut(2).fill(0.0);
        agree(zero_column, nalgebra::Vector6::from_fn(|_, _| next()));
        let mut rank_five = nalgebra::Matrix6::from_fn(|_, _| next());
        let sum = rank_five.column(0) + rank_five.column(1);
        rank_five.set_column(4, &sum);
        agree(rank_five, nalgebra::Vector6::from_fn(|_, _| next()));
        agree(nalgebra::Matrix6::zeros(), nalgebra::Vector6::from_fn(|_, _| next()));
        assert!(SmallLu::new(&zero_column).solve(&nalgebra::Vector6::repeat(1.0)).is_none());
    }

    /// The Cholesky inverse of SPD matrices Q D Q^T (Q orthogonal, condition 1 to 1e8) is exactly symmetric and
    /// equals Q D^-1 Q^T to the condition times round-off; an indefinite or singular matrix is refused.
    #[test]
    fn spd_inverse_is_the_inverse_and_refuses_indefinite_matrices() {
        let mut next = stream(7);
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

    /// The complement of k random combinations of r independent six-vectors (scaled 1 to 1e6, plus
    /// round-off-sized noise that is not a direction) has 6 - r directions, orthonormal and orthogonal to
    /// every vector to round-off: the dimension the SVD's rank decision (`span_basis`) gives. Nothing
    /// finite is refused; a NaN is.
    #[test]
    fn the_orthonormal_complement_has_the_dimension_the_svd_gives() {
        let mut next = stream(11);
        for rank in 0..=6 {
            for count in [rank, rank + 2, 7] {
                let spanning: Vec<nalgebra::Vector6<f64>> =
                    (0..rank).map(|k| nalgebra::Vector6::from_fn(|_, _| next()) * 1e3f64.powi(k as i32 % 3)).collect();
                let vectors: Vec<nalgebra::Vector6<f64>> = (0..count)
                    .map(|_| {
                        let mixed = spanning.iter().fold(nalgebra::Vector6::zeros(), |s, v| s + v * next());
                        mixed + nalgebra::Vector6::from_fn(|_, _| next() * 1e-14 * mixed.norm())
                    })
                    .collect();
                let mut set = Orthonormal6::default();
                assert!(set.span(vectors.iter().copied()));
                let complement: Vec<nalgebra::Vector6<f64>> = set.complement().collect();
                let columns = DMatrix::from_fn(6, count, |r, c| vectors[c][r]);
                let svd_rank = span_basis(&columns).unwrap().ncols();
                assert_eq!(complement.len(), 6 - svd_rank, "rank {rank}, {count} vectors");
                assert_eq!(svd_rank, rank.min(count));
                for (i, q) in complement.iter().enumerate() {
                    assert!((q.norm() - 1.0).abs() < 1e-14);
                    for p in &complement[..i] {
                        assert!(q.dot(p).abs() < 1e-14);
                    }
                    for v in &vectors {
                        assert!(q.dot(v).abs() < 1e-12 * v.norm().max(1e-300), "rank {rank}: {}", q.dot(v));
                    }
                }
            }
        }
        let mut not_finite = [nalgebra::Vector6::repeat(1.0)];
        not_finite[0][3] = f64::NAN;
        assert!(!Orthonormal6::default().span(not_finite));
        assert_eq!(Orthonormal6::default().complement().count(), 6);
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

    /// A pseudo-random stream in [-0.5, 0.5) (a linear congruential generator: the tests need no crate).
    fn stream(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// The branch-free helpers of the factorisations decide as the library's tests do: `larger` is
    /// `f64::max` on a running maximum (a NaN argument ignored, an infinite one kept), so pivots and margins
    /// do not move; `all_finite` is `all(is_finite)` (one infinity or NaN anywhere refuses the values).
    #[test]
    fn branch_free_maximum_and_finiteness_decide_as_the_library_does() {
        let mut next = stream(3);
        let specials = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -0.0, f64::MIN_POSITIVE, f64::MAX];
        for trial in 0..200 {
            let values: Vec<f64> = (0..1 + trial % 23)
                .map(|i| if (trial + i) % 9 == 0 { specials[(trial + i) % specials.len()] } else { next() * 1e3 })
                .collect();
            let expected = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let got = values.iter().fold(0.0f64, |m, v| larger(m, v.abs()));
            assert_eq!(got.to_bits(), expected.to_bits(), "trial {trial}: {values:?}");
            assert_eq!(all_finite(&values), values.iter().all(|v| v.is_finite()), "trial {trial}: {values:?}");
        }
        assert!(all_finite(&[]));
    }

    /// The whole saddle-point matrix [[J, 0], [W, J^T]] of `SaddlePointLu`, dense.
    fn saddle_matrix(j: &DMatrix<f64>, w: &DMatrix<f64>) -> DMatrix<f64> {
        let k = w.nrows();
        let mut m = DMatrix::zeros(k + 6, k + 6);
        m.view_mut((0, 0), (6, k)).copy_from(j);
        m.view_mut((6, 0), (k, k)).copy_from(w);
        m.view_mut((6, k), (k, 6)).copy_from(&j.transpose());
        m
    }

    /// The null-space factorisation solves the saddle-point system as a dense LU of the whole matrix does
    /// (nalgebra's, to 1e-10 of the solution), for constraint Jacobians with entries of mixed scales (lever
    /// arms in mm beside unit columns, as a chain's twist Jacobian has), W non-symmetric and spanning eight
    /// orders of magnitude (stiff springs beside soft load terms), no free coordinate, and several
    /// right-hand sides solved by rows or one at a time.
    #[test]
    fn saddle_point_solves_like_a_dense_lu_of_the_whole_matrix() {
        let mut next = stream(11);
        for (case, k) in [6usize, 7, 9, 17, 17, 23].into_iter().enumerate() {
            let j = DMatrix::from_fn(6, k, |r, c| next() * if r < 3 && c % 2 == 0 { 300.0 } else { 1.0 });
            let spread = if case % 2 == 0 { 1.0 } else { 1e8 };
            let w = DMatrix::from_fn(k, k, |r, c| next() + if r == c { spread * (0.5 + next()) } else { 0.0 });
            let dense = saddle_matrix(&j, &w);
            let mut saddle = SaddlePointLu::default();
            let columns = j.column_iter().map(|c| std::array::from_fn(|r| c[r]));
            assert!(saddle.factor(columns, w.as_slice(), k), "k = {k}");
            let rhs = DMatrix::from_fn(k + 6, 3, |_, _| next());
            let expected = dense.clone().lu().solve(&rhs).unwrap();
            let mut rows: Vec<[f64; 3]> = (0..k + 6).map(|r| std::array::from_fn(|c| rhs[(r, c)])).collect();
            saddle.solve_rows(&mut rows);
            for (c, column) in expected.column_iter().enumerate() {
                let error = rows.iter().zip(column.iter()).fold(0.0f64, |e, (row, x)| e.max((row[c] - x).abs()));
                assert!(error <= 1e-10 * column.amax(), "k = {k}, right-hand side {c}: error {error}");
                // One at a time (its own sums, on six-entry arrays): as the dense LU, and as by rows to
                // round-off.
                let mut one: Vec<f64> = rhs.column(c).iter().copied().collect();
                saddle.solve_in_place(&mut one);
                let error = one.iter().zip(column.iter()).fold(0.0f64, |e, (v, x)| e.max((v - x).abs()));
                assert!(error <= 1e-10 * column.amax(), "k = {k}, one at a time {c}: error {error}");
                let apart = one.iter().zip(&rows).fold(0.0f64, |e, (v, row)| e.max((v - row[c]).abs()));
                assert!(apart <= 1e-12 * column.amax(), "k = {k}, one at a time {c} and by rows: {apart}");
            }
        }
    }

    /// Constraints that cannot all be met (J of rank five: two rows equal) make the system singular, and the
    /// factorisation says so rather than dividing by round-off; so do non-finite entries and fewer
    /// coordinates than constraints.
    #[test]
    fn saddle_point_refuses_rank_deficient_constraints() {
        let mut next = stream(5);
        let k = 10;
        let mut j = DMatrix::from_fn(6, k, |_, _| next());
        let row = j.row(1).into_owned();
        j.row_mut(4).copy_from(&row);
        let w = DMatrix::from_fn(k, k, |r, c| next() + if r == c { 3.0 } else { 0.0 });
        let columns = |j: &DMatrix<f64>| j.column_iter().map(|c| std::array::from_fn(|r| c[r])).collect::<Vec<_>>();
        let mut saddle = SaddlePointLu::default();
        assert!(!saddle.factor(columns(&j), w.as_slice(), k));
        j.row_mut(4).copy_from(&DMatrix::from_fn(1, k, |_, _| next()));
        assert!(saddle.factor(columns(&j), w.as_slice(), k));
        let mut not_finite = w.clone();
        not_finite[(3, 2)] = f64::NAN;
        assert!(!saddle.factor(columns(&j), not_finite.as_slice(), k));
        let short = j.columns(0, 5).into_owned();
        assert!(!saddle.factor(columns(&short), DMatrix::<f64>::identity(5, 5).as_slice(), 5));
    }

    /// The definiteness test against an independent route: the eigenvalues of N^T H N, N an orthonormal basis
    /// of J's null space from the eigenvectors of J^T J, H = -sym(W). W = -(H + A) with H symmetric of random spectrum shifted
    /// so that some cases are definite on the null space and others not, and A antisymmetric (a
    /// non-conservative part, which the test must ignore). Cases within 1e-6 of the boundary are skipped.
    #[test]
    fn saddle_point_definiteness_follows_the_null_space_eigenvalues() {
        let mut next = stream(23);
        let (mut definite, mut indefinite) = (0, 0);
        for case in 0..60 {
            // f = k - 6 from 2 to 13: sizes `with_known_size!` names and one past them.
            let k = 8 + case % 12;
            let j = DMatrix::from_fn(6, k, |_, _| next());
            let m = DMatrix::from_fn(k, k, |_, _| next());
            let shift = 0.6 * (case % 5) as f64 / 4.0 * k as f64 / 8.0;
            let h = &m * m.transpose() - DMatrix::identity(k, k) * shift;
            let a = DMatrix::from_fn(k, k, |_, _| next());
            let w = -(&h + (&a - a.transpose()));
            // J^T J's eigenvectors of eigenvalue zero span J's null space (J has full row rank).
            let gram = (j.transpose() * &j).symmetric_eigen();
            let top = gram.eigenvalues.amax();
            let kept: Vec<usize> = (0..k).filter(|&i| gram.eigenvalues[i] < 1e-10 * top).collect();
            assert_eq!(kept.len(), k - 6);
            let null = gram.eigenvectors.select_columns(&kept);
            let smallest = (null.transpose() * &h * &null).symmetric_eigen().eigenvalues.min();
            if smallest.abs() < 1e-6 * h.amax() {
                continue;
            }
            let mut saddle = SaddlePointLu::default();
            assert!(saddle.factor(j.column_iter().map(|c| std::array::from_fn(|r| c[r])), w.as_slice(), k));
            assert_eq!(saddle.reduced_negative_definite(), smallest > 0.0, "case {case}: smallest {smallest}");
            if smallest > 0.0 {
                definite += 1;
            } else {
                indefinite += 1;
            }
        }
        assert!(definite >= 10 && indefinite >= 10, "both kinds tested: {definite} and {indefinite}");
    }

    /// The envelope of a symmetric matrix from its numbers: each column's first non-zero above the diagonal.
    fn envelope_of(m: &DMatrix<f64>) -> EnvelopeCholesky {
        EnvelopeCholesky::new((0..m.ncols()).map(|j| (0..j).find(|&i| m[(i, j)] != 0.0).unwrap_or(j)).collect())
    }

    /// A symmetric positive definite system solved as nalgebra's Cholesky solves it, dense and with an
    /// envelope (a banded block with zeros inside the band and a stray far entry), factorised in a larger
    /// buffer whose strict lower triangle is left as it was; U is nalgebra's L transposed, the pivots are the
    /// squares of its diagonal; an indefinite matrix is refused.
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
            let lower_before: Vec<f64> =
                (0..n).flat_map(|j| (j + 1..n).map(move |i| (i, j))).map(|p| buffer[p]).collect();
            let mut c = envelope_of(&m);
            let (lo, hi) = c.factor(buffer.as_mut_slice(), stride).unwrap();
            let lower_after: Vec<f64> =
                (0..n).flat_map(|j| (j + 1..n).map(move |i| (i, j))).map(|p| buffer[p]).collect();
            assert_eq!(lower_before, lower_after);
            let l = expected.l();
            for j in 0..n {
                for i in j..n {
                    assert!((buffer[(j, i)] - l[(i, j)]).abs() < 1e-12 * l.amax(), "U[{j},{i}]");
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
        assert!(envelope_of(&indefinite).factor(indefinite.as_mut_slice(), 3).is_none());
    }

    /// Eliminating the first m coordinates of a matrix with an envelope (a band in the eliminated block,
    /// trailing rows that reach only part of it) leaves the Schur complement A_uu - A_uy A_yy^-1 A_yu
    /// (computed here with nalgebra's inverse) in the trailing block's upper triangle, and U^-T A_yu
    /// (= (A_uy L^-T)^T, L nalgebra's factor of A_yy) above it.
    #[test]
    fn elimination_leaves_the_schur_complement() {
        let (n, m) = (10, 7);
        let g = DMatrix::from_fn(n, n, |i, j| {
            if i.abs_diff(j) <= 2 || (i >= m && j >= 3) || (j >= m && i >= 3) {
                ((i * 3 + j * 5) % 7) as f64 - 3.0 + if i == j { 5.0 } else { 0.0 }
            } else {
                0.0
            }
        });
        let a = &g * g.transpose();
        assert!(envelope_of(&a).first()[m] > 0, "the trailing rows reach only part of the eliminated block");
        check_schur_complement(&a, m);
    }

    /// Trailing columns whose envelope starts below the eliminated block (coupled only among themselves,
    /// two of them side by side), and nothing eliminated at all, condense as the explicit formula says.
    #[test]
    fn trailing_columns_outside_the_eliminated_block_condense_too() {
        let n = 10;
        let g = DMatrix::from_fn(n, n, |i, j| {
            let coupled = if i < 6 && j < 6 { i.abs_diff(j) <= 2 } else { i >= 6 && j >= 6 };
            if coupled {
                ((i * 3 + j * 5) % 7) as f64 - 3.0 + if i == j { 6.0 } else { 0.0 }
            } else {
                0.0
            }
        });
        let a = &g * g.transpose();
        assert!(envelope_of(&a).first()[6] >= 6 && envelope_of(&a).first()[7] >= 6, "columns 6 and 7 start below m");
        check_schur_complement(&a, 4);
        check_schur_complement(&a, 6);
        let mut untouched = a.clone();
        envelope_of(&a).eliminate(untouched.as_mut_slice(), n, 0).unwrap();
        assert!((untouched - &a).upper_triangle().amax() == 0.0, "nothing eliminated leaves the matrix as it is");
    }

    /// `eliminate(m)` against the Schur complement A_uu - A_uy A_yy^-1 A_yu and U^-T A_yu computed with
    /// nalgebra's inverse and Cholesky.
    fn check_schur_complement(a: &DMatrix<f64>, m: usize) {
        let n = a.nrows();
        let (ayy, ayu, auu) = (a.view((0, 0), (m, m)), a.view((0, m), (m, n - m)), a.view((m, m), (n - m, n - m)));
        let schur = auu - ayu.transpose() * ayy.clone_owned().try_inverse().unwrap() * ayu;
        let l = ayy.clone_owned().cholesky().unwrap().l();
        let below = ayu.transpose() * l.transpose().try_inverse().unwrap();
        let mut buffer = a.clone();
        envelope_of(a).eliminate(buffer.as_mut_slice(), n, m).unwrap();
        for j in 0..n - m {
            for i in 0..=j {
                assert!((buffer[(m + i, m + j)] - schur[(i, j)]).abs() <= 1e-10 * schur.amax(), "S[{i},{j}], m = {m}");
            }
            for k in 0..m {
                assert!((buffer[(k, m + j)] - below[(j, k)]).abs() <= 1e-10 * below.amax(), "W[{j},{k}], m = {m}");
            }
        }
    }
}

//! The envelope (skyline) Cholesky factorisation, with partial elimination for static condensation.

use super::cholesky::paired_dot;

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
pub(super) fn pair_dot(x: &[f64], pairs: &[[f64; 2]]) -> [f64; 2] {
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
pub(super) fn pivot(
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

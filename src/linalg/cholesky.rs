//! Cholesky factorisations of small dense matrices: by rows on a buffer, on fixed-size arrays, the
//! definiteness test, and the 6 x 6 SPD inverse.

use super::all_finite;

/// Cholesky factorisation in place of a dense n x n symmetric matrix (row-major, or column-major: the same
/// for a symmetric one): its lower triangle is read and overwritten by L row by row, each entry one dot
/// product of two rows' leading parts (L_ij = (a_ij - sum_k<j L_ik L_jk) / L_jj) summed in order: its
/// callers read the factor's values (`small_cholesky`, `spd_inverse6`), which keep their bits so. False
/// where a pivot is not positive or not finite (not positive definite to round-off).
pub(super) fn dense_cholesky(a: &mut [f64], n: usize) -> bool {
    cholesky_rows(a, n, |x, y| x.iter().zip(y).map(|(x, y)| x * y).sum())
}

/// True where the dense n x n symmetric matrix (its lower triangle read, by rows) is positive definite to
/// round-off: `dense_cholesky`'s factorisation with the dot products taken as two running sums
/// (`paired_dot`: two terms per vector operation). Only the pivots' signs are read, so the order of the
/// sums changes no result but at a pivot within round-off of zero (the stability test's margin, 1e-12 of
/// the largest entry, is ten thousand times round-off), and the factor's values go nowhere.
#[inline(always)]
pub fn positive_definite_in_place(a: &mut [f64], n: usize) -> bool {
    cholesky_rows(a, n, paired_dot)
}

/// The row-by-row Cholesky factorisation of `dense_cholesky`, each entry's dot product of two rows' leading
/// parts taken by `dot`.
#[inline(always)]
pub(super) fn cholesky_rows(a: &mut [f64], n: usize, dot: impl Fn(&[f64], &[f64]) -> f64) -> bool {
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
pub(super) fn paired_dot(x: &[f64], y: &[f64]) -> f64 {
    let (x_pairs, y_pairs) = (x.chunks_exact(2), y[..x.len()].chunks_exact(2));
    let last = x_pairs.remainder().iter().zip(y_pairs.remainder()).map(|(x, y)| x * y).sum::<f64>();
    let mut sum = [0.0f64; 2];
    for (a, b) in x_pairs.zip(y_pairs) {
        sum[0] += a[0] * b[0];
        sum[1] += a[1] * b[1];
    }
    sum[0] + sum[1] + last
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

//! The singular value decomposition with a cap on its input and its sweeps, and the spans and complements
//! read from it.

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

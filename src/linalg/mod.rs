//! Small dense linear algebra the hot paths need beyond nalgebra's fixed-size types: the saddle-point
//! factorisation of the loaded equilibrium's (n + m + 6)-square matrix through the null space of its
//! constraints, and an in-place LU factorisation with partial pivoting, on reused buffers (the loaded
//! equilibrium factorises several times per point, and allocating or going through generic dynamic
//! dimensions there costs more than the arithmetic).
//!
//! One decomposition per file: the capped SVD and the spans read from it (`svd.rs`), Gram-Schmidt in R^6
//! (`orthonormal.rs`), LU with partial pivoting on the stack and in place (`lu.rs`), the saddle-point
//! factorisation (`saddle_point.rs`), small dense Cholesky factorisations (`cholesky.rs`) and the envelope
//! Cholesky of MSA's condensation (`envelope.rs`). This file holds what they share: `with_known_size!`
//! (defined before the files, which use it) and `all_finite`.

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

mod cholesky;
mod envelope;
mod lu;
mod orthonormal;
mod saddle_point;
mod svd;

pub use cholesky::{positive_definite_in_place, small_cholesky, small_forward, spd_inverse6};
pub use envelope::EnvelopeCholesky;
pub use lu::{DenseLu, SmallLu};
pub use orthonormal::Orthonormal6;
pub use saddle_point::{SaddlePointLu, CONSTRAINTS};
pub use svd::{capped_svd, outside_span, span_basis, MAX_ENTRY, MAX_SWEEPS, SPAN_SHARE};

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

#[cfg(test)]
mod tests;

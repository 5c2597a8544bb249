//! The statistics both diagnoses use, once: the tail probabilities of the F and chi-square tests, the
//! evidence an effect must bring, the robust scale of misfits and the rule that calls a row gross.
//!
//! The deflection diagnosis (`select.rs`, displacements under load) and the calibration (`calibrate/`,
//! measured positions) decide with the same tests and the same evidence; their gross-row thresholds differ,
//! for the reason given at `GROSS_FACTOR_DEFLECTIONS`.

use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor};

/// A BIC lower by more than this is "very strong" evidence (Kass and Raftery 1995, Bayes factors, JASA
/// 90:773): an effect is accepted only with it, so that one of six parameters on few rows pays for them.
pub const STRONG_EVIDENCE: f64 = 10.0;

/// The median length of a standard normal 3-vector (the chi distribution's with 3 degrees of freedom): the
/// robust scale of a row's misfit is the median misfit divided by it, one standard deviation for pure noise.
pub const CHI3_MEDIAN: f64 = 1.5382;

/// A row of measured deflections whose misfit is beyond this many robust scales is gross. For pure noise the
/// misfit of a row is the length of a standard normal 3-vector: beyond 12 with probability below 1e-30, so
/// no honest row is ever left out by either rule. The deflection diagnosis first screens against the
/// nominal model, before any effect is fitted, where a missing effect's misfit varies from row to row by
/// the load and the pose (rarely by more than a factor of ten around its median): it needs the wider
/// margin. The calibration first screens after the registration is fitted, which takes up the bulk of a
/// position misfit, so what is left spreads much less and a gross row stands out at 12.
pub const GROSS_FACTOR_DEFLECTIONS: f64 = 30.0;

/// A calibration row whose misfit is beyond this many robust scales is gross (see
/// `GROSS_FACTOR_DEFLECTIONS` for why the two differ).
pub const GROSS_FACTOR_POSITIONS: f64 = 12.0;

/// The robust scale of misfits (lengths of weighted residual 3-vectors): their median over `CHI3_MEDIAN`.
/// `sorted` ascending and not empty.
pub fn robust_scale(sorted: &[f64]) -> f64 {
    sorted[sorted.len() / 2] / CHI3_MEDIAN
}

/// The chi-square distribution's upper-tail probability at `x` with `dof` degrees of freedom. By the
/// survival function, not `1 - cdf`, which underflows to 0 beyond p ~ 1e-16 and made every strong effect
/// look equally (infinitely) significant.
pub fn chi2_sf(x: f64, dof: usize) -> f64 {
    ChiSquared::new(dof.max(1) as f64).map(|d| d.sf(x)).unwrap_or(f64::NAN)
}

/// The F distribution's upper-tail probability at `x` with `d1` and `d2` degrees of freedom (by its survival
/// function, as `chi2_sf`); 1 where there is nothing to test, 0 at an infinite statistic.
pub fn f_sf(x: f64, d1: usize, d2: usize) -> f64 {
    if d1 == 0 || d2 == 0 || !x.is_finite() {
        return if x.is_infinite() { 0.0 } else { 1.0 };
    }
    FisherSnedecor::new(d1 as f64, d2 as f64).map(|d| d.sf(x.max(0.0))).unwrap_or(f64::NAN)
}

/// The BIC of a least-squares fit whose noise level is fitted too: n ln(rss / n) + k ln n, for `k`
/// parameters the data see. (Where the noise is known, the BIC is rss in sigma^2 units plus k ln n: the
/// deflection diagnosis compares its fits so, `select.rs`.)
pub fn bic_unknown_noise(rss: f64, n: usize, k: usize) -> f64 {
    let n = n as f64;
    n * (rss / n).max(1e-300).ln() + k as f64 * n.ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: p-values were `1 - cdf`, which is 0 below 1e-16. Closed forms: the chi-square
    /// distribution with 2 degrees of freedom has sf(x) = exp(-x/2); the F distribution with d1 = 2 has
    /// sf(x) = (1 + 2x/d2)^(-d2/2).
    #[test]
    fn p_values_keep_their_digits_far_in_the_tail() {
        for x in [1.0, 40.0, 200.0, 1000.0] {
            let exact = (-x / 2.0f64).exp();
            assert!((chi2_sf(x, 2) - exact).abs() <= 1e-10 * exact, "chi2 sf({x}) {} vs {exact}", chi2_sf(x, 2));
        }
        for (x, d2) in [(3.0, 20usize), (200.0, 30), (5000.0, 40)] {
            let exact = (1.0 + 2.0 * x / d2 as f64).powf(-(d2 as f64) / 2.0);
            assert!((f_sf(x, 2, d2) - exact).abs() <= 1e-8 * exact, "F sf({x}) {} vs {exact}", f_sf(x, 2, d2));
        }
    }
}

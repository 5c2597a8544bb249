//! The least-squares core both diagnoses fit with: Levenberg-Marquardt on the column-scaled Jacobian by its
//! singular value decomposition, with a rank decision by a stated tolerance (`RANK_TOLERANCE`), the
//! directions the data cannot see, and the covariance of the ones they see.
//!
//! A problem (`LeastSquares`) gives its weighted residuals (data less model, in standard deviations) and,
//! when asked, the Jacobian of the model's prediction in its parameters; and how a step moves its
//! parameters, so that a set-up's rotation lives on its manifold (the step turns it, the rotation is never a
//! sum of numbers). The calibration of measured positions (`calibrate/fit.rs`) and the deflection diagnosis
//! (`fit.rs`) are both such problems.

use nalgebra::{DMatrix, DVector};

/// Relative singular value of the column-scaled Jacobian below which a direction is not identifiable: a
/// combination of parameters that moves the prediction by less than a millionth of what each does alone
/// would amplify the noise a millionfold. Such directions are neither stepped along nor given a variance.
pub const RANK_TOLERANCE: f64 = 1e-6;
/// The first damping, relative to the largest squared singular value: nearly a Gauss-Newton step.
const FIRST_DAMPING: f64 = 1e-6;
/// A floor on the damping after a success: steps along directions the data barely see (below a hundredth
/// of a percent of the best seen) stay damped.
const DAMPING_FLOOR: f64 = 1e-8;
/// The damping at which no step is found to lower the sum of squares: the fit is at its minimum.
const DAMPING_CEILING: f64 = 1e12;
/// Steps at most.
const MAX_STEPS: usize = 100;
/// A step lowering the sum of squares by less than this share of it ends the fit (the parameters are then
/// within about 1e-5 of a standard error of the minimum).
const CONVERGED: f64 = 1e-10;

/// A direction of the parameters, by its entries above 0.05: (parameter index, weight).
pub type Direction = Vec<(usize, f64)>;

/// A weighted least-squares problem.
pub trait LeastSquares {
    /// Where the problem is evaluated: its parameters, in whatever form they live.
    type Point: Clone;
    /// Why an evaluation fails (a row without a prediction there).
    type Error;

    /// The number of parameters (the columns of the Jacobian).
    fn parameters(&self) -> usize;

    /// The weighted residuals at `at` (data less model); with `jacobian`, also the Jacobian of the weighted
    /// prediction in the parameters, written into it (resized by the problem to residuals x parameters).
    fn evaluate(&self, at: &Self::Point, jacobian: Option<&mut DMatrix<f64>>) -> Result<DVector<f64>, Self::Error>;

    /// The point moved by `step` (one entry per parameter, in the Jacobian's order).
    fn step(&self, at: &Self::Point, step: &DVector<f64>) -> Self::Point;
}

/// A fit: where it ended, its weighted sum of squares and residuals, the rank the data see, the covariance
/// (unscaled: (J^T J)^+ over the seen directions, in the parameters' units; scale it by the residual
/// variance) and the directions the data cannot see.
#[derive(Clone, Debug)]
pub struct Solution<P> {
    /// The fitted point.
    pub point: P,
    /// Weighted residual sum of squares.
    pub rss: f64,
    /// The weighted residuals there.
    pub residuals: DVector<f64>,
    /// Directions the data see (singular values above `RANK_TOLERANCE` of the largest).
    pub rank: usize,
    /// (J^T J)^+ of the weighted Jacobian over the seen directions, in the parameters' order.
    pub covariance: DMatrix<f64>,
    /// Each direction the data cannot see, in the column-scaled parameters (each column's effect on the
    /// prediction at unit norm, so that a rotation and a translation weigh alike): (parameter, weight) of
    /// its entries above 0.05.
    pub hidden: Vec<Direction>,
    /// Each parameter's column scale there (the norm of its Jacobian column; 1 for a column of zeros): a
    /// hidden direction's weight over it is the parameter's own change along the direction.
    pub scales: Vec<f64>,
}

impl<P> Solution<P> {
    /// Whether the data see every parameter.
    pub fn full_rank(&self) -> bool {
        self.rank == self.covariance.ncols()
    }
}

/// Each column's norm, the scale its parameter is stepped and judged in; a column of zeros (a parameter that
/// moves nothing here) keeps scale 1, so that round-off in the steps is not blown up by dividing by it.
fn column_scales(jac: &DMatrix<f64>) -> DVector<f64> {
    DVector::from_iterator(jac.ncols(), jac.column_iter().map(|c| if c.norm() > 0.0 { c.norm() } else { 1.0 }))
}

/// Levenberg-Marquardt from `start`: each step the damped pseudo-inverse of the column-scaled Jacobian
/// (singular values below `RANK_TOLERANCE` of the largest left out), the damping raised tenfold until a
/// step lowers the sum of squares and lowered tenfold after; then the rank, hidden directions and covariance
/// at the solution. A failed evaluation at a trial step counts as no improvement; at an accepted point it is
/// the fit's failure.
pub fn solve<L: LeastSquares>(problem: &L, start: L::Point) -> Result<Solution<L::Point>, L::Error> {
    let p = problem.parameters();
    let mut point = start;
    let mut jac = DMatrix::zeros(0, p);
    let mut e = problem.evaluate(&point, Some(&mut jac))?;
    let mut rss = e.norm_squared();
    if p == 0 {
        // Nothing to fit: the model as it is.
        return Ok(Solution {
            point,
            rss,
            residuals: e,
            rank: 0,
            covariance: DMatrix::zeros(0, 0),
            hidden: Vec::new(),
            scales: Vec::new(),
        });
    }
    let mut lambda = FIRST_DAMPING;
    // The decomposition of the Jacobian the last step was chosen with: where the loop ends without moving
    // on (no improvement, or converged), the solution's rank and covariance are read from it.
    let mut last: Option<ScaledSvd> = None;
    for _ in 0..MAX_STEPS {
        let ScaledSvd { scale, singular_values, v_t } = last.insert(scaled_svd(&jac));
        if v_t.nrows() == 0 {
            break;
        }
        // U^T e along a seen direction is v_k . (J^T e) / s_k (no U is formed), and no step is taken along the
        // others.
        let jte = DVector::from_fn(p, |j, _| jac.column(j).dot(&e) / scale[j]);
        let top = singular_values.max();
        let ue = DVector::from_fn(singular_values.len(), |k, _| {
            let s = singular_values[k];
            if s > 0.0 {
                v_t.row(k).transpose().dot(&jte) / s
            } else {
                0.0
            }
        });
        let mut improved = false;
        while lambda < DAMPING_CEILING {
            let mut step = DVector::zeros(p);
            for (k, &s) in singular_values.iter().enumerate() {
                if s > RANK_TOLERANCE * top {
                    let damped = s / (s * s + lambda * top * top);
                    step += v_t.row(k).transpose() * (ue[k] * damped);
                }
            }
            let step = step.component_div(scale);
            let trial = problem.step(&point, &step);
            if let Ok(e_trial) = problem.evaluate(&trial, None) {
                let rss_trial = e_trial.norm_squared();
                if rss_trial < rss {
                    let converged = rss - rss_trial <= CONVERGED * rss.max(1e-300);
                    point = trial;
                    rss = rss_trial;
                    e = e_trial;
                    lambda = (lambda / 10.0).max(DAMPING_FLOOR);
                    improved = !converged;
                    break;
                }
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
        e = problem.evaluate(&point, Some(&mut jac))?;
        rss = e.norm_squared();
        last = None;
    }
    let decomposed = last.unwrap_or_else(|| scaled_svd(&jac));
    let (rank, covariance, hidden) = seen_directions(&decomposed);
    let scales = decomposed.scale.iter().copied().collect();
    Ok(Solution { point, rss, residuals: e, rank, covariance, hidden, scales })
}

/// The column-scaled Jacobian's singular values and right singular vectors, with the scales.
struct ScaledSvd {
    scale: DVector<f64>,
    singular_values: DVector<f64>,
    v_t: DMatrix<f64>,
}

/// The SVD of `jac` with its columns scaled (`column_scales`), without U. A Jacobian with more rows than
/// columns (many rows, a few set-ups' parameters) is reduced to its p x p triangle R by Householder QR first:
/// J = Q R has R's singular values and right vectors, and the SVD's bidiagonalisation then works on p rows,
/// not n (half the work where n is several times p).
fn scaled_svd(jac: &DMatrix<f64>) -> ScaledSvd {
    let (n, p) = jac.shape();
    let scale = column_scales(jac);
    let scaled = DMatrix::from_fn(n, p, |i, j| jac[(i, j)] / scale[j]);
    let svd = match n > 2 * p {
        true => scaled.qr().r().svd(false, true),
        false => scaled.svd(false, true),
    };
    let v_t = svd.v_t.unwrap_or_else(|| DMatrix::zeros(0, p));
    ScaledSvd { scale, singular_values: svd.singular_values, v_t }
}

/// The rank of the column-scaled Jacobian `d` decomposes, the covariance (J^T J)^+ over the directions it
/// sees, and the ones it does not see (`Solution`).
fn seen_directions(d: &ScaledSvd) -> (usize, DMatrix<f64>, Vec<Direction>) {
    let p = d.scale.len();
    let (scale, v_t) = (&d.scale, &d.v_t);
    let mut covariance = DMatrix::zeros(p, p);
    let mut hidden = Vec::new();
    let mut rank = 0;
    if v_t.nrows() == 0 {
        return (0, covariance, hidden);
    }
    let top = d.singular_values.max();
    for (k, &s) in d.singular_values.iter().enumerate() {
        let v = v_t.row(k).transpose();
        if s > RANK_TOLERANCE * top {
            rank += 1;
            covariance += &v * v.transpose() / (s * s);
        } else {
            hidden.push((0..p).filter(|&j| v[j].abs() > 0.05).map(|j| (j, v[j])).collect());
        }
    }
    let covariance = DMatrix::from_fn(p, p, |i, j| covariance[(i, j)] / (scale[i] * scale[j]));
    (rank, covariance, hidden)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight line y = a + b x through noise-free points, with a third parameter c that moves nothing
    /// (its column is zero) and a fourth d that is the same as a (y = a + d + b x): the fit finds a + d and
    /// b exactly (closed form: the points' own line), sees rank 2, names one hidden direction along c alone
    /// and one along a - d, and its covariance over the seen directions is (J^T J)^+ (checked by J^T J C
    /// J^T J = J^T J, the pseudo-inverse's defining identity).
    struct Line {
        x: Vec<f64>,
        y: Vec<f64>,
    }

    impl LeastSquares for Line {
        type Point = Vec<f64>;
        type Error = ();
        fn parameters(&self) -> usize {
            4
        }
        fn evaluate(&self, at: &Vec<f64>, jacobian: Option<&mut DMatrix<f64>>) -> Result<DVector<f64>, ()> {
            let n = self.x.len();
            if let Some(j) = jacobian {
                *j = DMatrix::from_fn(n, 4, |i, k| [1.0, self.x[i], 0.0, 1.0][k]);
            }
            Ok(DVector::from_fn(n, |i, _| self.y[i] - (at[0] + at[3] + at[1] * self.x[i])))
        }
        fn step(&self, at: &Vec<f64>, step: &DVector<f64>) -> Vec<f64> {
            at.iter().zip(step.iter()).map(|(a, s)| a + s).collect()
        }
    }

    #[test]
    fn a_line_is_fitted_exactly_and_its_unseen_directions_are_named() {
        let x: Vec<f64> = (0..8).map(|i| i as f64 * 0.5).collect();
        let y = x.iter().map(|x| 2.0 - 3.0 * x).collect();
        let line = Line { x, y };
        let s = solve(&line, vec![0.0; 4]).unwrap();
        assert!((s.point[0] + s.point[3] - 2.0).abs() < 1e-12 && (s.point[1] + 3.0).abs() < 1e-12, "{:?}", s.point);
        assert!(s.rss < 1e-20, "{}", s.rss);
        assert_eq!(s.rank, 2);
        assert!(!s.full_rank());
        assert_eq!(s.hidden.len(), 2);
        assert!(s.hidden.iter().any(|d| d.len() == 1 && d[0].0 == 2), "{:?}", s.hidden);
        assert!(
            s.hidden.iter().any(|d| d.len() == 2 && d[0].0 == 0 && d[1].0 == 3 && (d[0].1 + d[1].1).abs() < 1e-9),
            "{:?}",
            s.hidden
        );
        let mut j = DMatrix::zeros(0, 4);
        line.evaluate(&s.point, Some(&mut j)).unwrap();
        let jtj = j.transpose() * &j;
        let back = &jtj * &s.covariance * &jtj;
        assert!((back - &jtj).norm() < 1e-9 * jtj.norm());
    }
}

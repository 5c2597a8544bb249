//! Inverse kinematics of one chain: the actuated and passive coordinates that put the chain's end frame on a
//! target frame, by a damped Newton (Gauss-Newton with back-tracking) solve, warm-started by the caller.

use super::chain::{Chain, ChainJacobians, Coordinates};
use super::frame::{Frame, Mat6, Vec6};

/// Why inverse kinematics gave up, with the numbers a user needs to judge it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkFailure {
    pub iterations: usize,
    /// Remaining pose error, rotations weighted by the chain's length scale (mm).
    pub residual_mm: f64,
}

pub const MAX_ITERATIONS: usize = 60;

/// Weighted pose error: rotations (rad) times `length_scale` (mm/rad), so both parts are in mm.
#[inline]
fn weighted(e: &Vec6, length_scale: f64) -> Vec6 {
    Vec6::new(
        e[0],
        e[1],
        e[2],
        e[3] * length_scale,
        e[4] * length_scale,
        e[5] * length_scale,
    )
}

/// Solves `end_frame(coords) = target` for the actuated and passive coordinates; virtual coordinates are
/// left as they are. Returns the number of iterations.
///
/// The step is the minimum-norm damped solution `du = J^T (J J^T + lambda I)^-1 e` in the weighted metric,
/// a 6x6 solve whatever the number of unknowns, so redundant and deficient chains (a 3-PUU leg has five
/// unknowns for six equations, consistent only at reachable poses) are handled alike.
pub fn solve(
    chain: &Chain,
    target: &Frame,
    coords: &mut Coordinates,
    ws: &mut ChainJacobians,
    length_scale: f64,
) -> Result<usize, IkFailure> {
    let tolerance = 1e-10 * length_scale.max(1.0);
    let mut trial = coords.clone();
    chain.evaluate(coords, false, ws);
    let mut err = weighted(&ws.end.error_to(target), length_scale);
    let mut norm = err.norm();
    for iteration in 0..MAX_ITERATIONS {
        if norm <= tolerance {
            return Ok(iteration);
        }
        let w = |j: &Vec6| weighted(j, length_scale);
        let mut a = Mat6::zeros();
        for j in ws.actuated.iter().chain(ws.passive.iter()) {
            let jw = w(j);
            a += jw * jw.transpose();
        }
        let damping = 1e-12 * a.trace() + 1e-300;
        for k in 0..6 {
            a[(k, k)] += damping;
        }
        let Some(chol) = a.cholesky() else {
            return Err(IkFailure {
                iterations: iteration,
                residual_mm: norm,
            });
        };
        let y = chol.solve(&err);
        // Back-tracking: halve the step until the error decreases.
        let mut step = 1.0;
        let mut accepted = false;
        for _ in 0..30 {
            for (k, j) in ws.actuated.iter().enumerate() {
                trial.actuated[k] = coords.actuated[k] + step * w(j).dot(&y);
            }
            for (k, j) in ws.passive.iter().enumerate() {
                trial.passive[k] = coords.passive[k] + step * w(j).dot(&y);
            }
            let trial_norm =
                weighted(&chain.end_frame(&trial).error_to(target), length_scale).norm();
            if trial_norm < norm {
                coords.actuated.copy_from_slice(&trial.actuated);
                coords.passive.copy_from_slice(&trial.passive);
                accepted = true;
                break;
            }
            step *= 0.5;
        }
        if !accepted {
            return Err(IkFailure {
                iterations: iteration,
                residual_mm: norm,
            });
        }
        chain.evaluate(coords, false, ws);
        err = weighted(&ws.end.error_to(target), length_scale);
        norm = err.norm();
    }
    if norm <= tolerance {
        Ok(MAX_ITERATIONS)
    } else {
        Err(IkFailure {
            iterations: MAX_ITERATIONS,
            residual_mm: norm,
        })
    }
}

//! Inverse kinematics of one chain: the actuated and passive coordinates that put the chain's end frame on a
//! target frame, by a damped Newton (Gauss-Newton with back-tracking) solve, warm-started by the caller.

use super::chain::{Chain, ChainJacobians, Coordinates};
use super::frame::{weigh_rotations, Frame, Mat6, Vec6};

/// Why inverse kinematics gave up, with the numbers a user needs to judge it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkFailure {
    /// Iterations spent.
    pub iterations: usize,
    /// Remaining pose error, rotations weighted by the chain's length scale (mm).
    pub residual_mm: f64,
}

impl IkFailure {
    /// The solve ended within `REACH_TOLERANCE_MM` of the pose: it lies at the reach boundary.
    pub fn at_reach_boundary(&self) -> bool {
        self.residual_mm <= REACH_TOLERANCE_MM
    }
}

impl std::fmt::Display for IkFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "inverse kinematics ended {:.3e} mm from the pose after {} iterations (the pose lies outside the \
             leg's reach, or across a singularity from the previous pose)",
            self.residual_mm, self.iterations
        )
    }
}

/// Most Gauss-Newton iterations per solve.
pub const MAX_ITERATIONS: usize = 60;
/// Convergence: weighted pose error below this times the chain's length scale (a 900 mm leg: 1e-6 mm and
/// 1e-9 rad), far below what changes a stiffness in its printed digits.
pub const TOLERANCE: f64 = 1e-9;
/// A pose error below this times the tolerance counts as polished: a polishing step leaves about the
/// tolerance's square, round-off, and this is within a few hundred times round-off.
const POLISHED: f64 = 1e-5;
/// The reach decision's tolerance (mm, rotations weighted by the length scale). At a reach boundary (a leg
/// stretched to a fold of its kinematics) Gauss-Newton converges sublinearly: a 3-PUU pose 1e-5 mm inside
/// its boundary ends 60 iterations 7e-6 mm away, as does one 1e-6 mm outside. A solve that ends within
/// this distance therefore says "at the reach boundary, within 1e-4 mm", not "unreachable": the pose may
/// lie on either side, and its stiffness is degenerate there (status `ill_conditioned`).
pub const REACH_TOLERANCE_MM: f64 = 1e-4;

/// Buffers reused from one solve to the next (no allocation per point).
#[derive(Clone, Debug, Default)]
pub struct IkWorkspace {
    /// The chain evaluated at the current coordinates.
    pub current: ChainJacobians,
    /// True when `current` was evaluated at the coordinates the next solve starts from (the previous
    /// solution), so the first Newton step needs no new evaluation.
    current_is_valid: bool,
    trial: ChainJacobians,
    trial_coords: Coordinates,
}

impl IkWorkspace {
    /// To be called when the coordinates are changed by anything but `solve`.
    pub fn invalidate(&mut self) {
        self.current_is_valid = false;
    }

    /// Evaluates `chain` at `coords` as the start of the next solve (the coordinates it will be handed): a
    /// solve at the pose they reach then converges on this evaluation without a new one.
    pub fn evaluate_at(&mut self, chain: &Chain, coords: &Coordinates) -> &ChainJacobians {
        chain.evaluate(coords, &mut self.current);
        self.current_is_valid = true;
        &self.current
    }

    /// The evaluation at the last solution (virtual columns included), while the coordinates have not
    /// changed since.
    pub fn solution(&mut self) -> Option<&ChainJacobians> {
        if !self.current_is_valid {
            return None;
        }
        self.current.fill_virtual();
        Some(&self.current)
    }

    /// As `solution`, without filling the virtual coordinates' columns (for the joints' twists alone).
    pub fn joints_at_solution(&self) -> Option<&ChainJacobians> {
        self.current_is_valid.then_some(&self.current)
    }
}

/// Solves `end_frame(coords) = target` for the actuated and passive coordinates; virtual coordinates are
/// left as they are. Returns the number of iterations; `ws.current` then holds the evaluation at the solution.
///
/// Once within `TOLERANCE`, one more step is taken (kept where it lowers the error): the error then falls to
/// about the tolerance's square, round-off, so that the solution does not depend on where the solve
/// started (a map's placements, and every loaded result through its actuators, are then the same whatever
/// order the poses are visited in), and a command changed by less than the tolerance still moves the
/// actuators (compliance compensation iterates on such commands).
///
/// The step is the minimum-norm damped solution `du = J^T (J J^T + lambda I)^-1 e` in the weighted metric,
/// a 6x6 solve whatever the number of unknowns, so redundant and deficient chains (a 3-PUU leg has five
/// unknowns for six equations, consistent only at reachable poses) are handled alike.
pub fn solve(
    chain: &Chain,
    target: &Frame,
    coords: &mut Coordinates,
    ws: &mut IkWorkspace,
    length_scale: f64,
) -> Result<usize, IkFailure> {
    let tolerance = TOLERANCE * length_scale.max(1.0);
    ws.trial_coords.clone_from(coords);
    // A start evaluated and kept is a solution (the last one, or a seeded configuration's own pose).
    let start_is_solution = ws.current_is_valid;
    if !ws.current_is_valid {
        chain.evaluate(coords, &mut ws.current);
    }
    ws.current_is_valid = false;
    let mut err = weigh_rotations(&ws.current.end.error_to(target), length_scale);
    let mut norm = err.norm();
    let mut polished = false;
    for iteration in 0..MAX_ITERATIONS {
        let converged = norm <= tolerance;
        // A Newton iterate or a solution already at the polished level needs no polishing step. Any other
        // start (an extrapolation, a loaded configuration) takes at least one step: its error, however
        // small, is the start's (an extrapolation's within 1e-11 mm would stay in every loaded answer).
        polished |= (iteration > 0 || start_is_solution) && norm <= POLISHED * tolerance;
        if converged && polished {
            ws.current_is_valid = true;
            return Ok(iteration);
        }
        let jw = |j: &Vec6| weigh_rotations(j, length_scale);
        let mut a = Mat6::zeros();
        for j in ws.current.actuated.iter().chain(ws.current.passive.iter()) {
            let w = jw(j);
            a += w * w.transpose();
        }
        // The damping keeps the Cholesky pivots of a chain with fewer unknowns than equations (a 3-PUU
        // leg: five for six) positive, above the round-off of `a` (1e-16 of its trace); its step errs by
        // about damping / (the smallest eigenvalue J gives), so it must stay small for the polishing step
        // to reach round-off: at 1e-12 of the trace the 3-PUU converged linearly, 3e-6 per step, and a
        // polishing step left 3e-12 mm; at 1e-14 it leaves 1e-13 mm.
        let damping = 1e-14 * a.trace() + 1e-300;
        for k in 0..6 {
            a[(k, k)] += damping;
        }
        let Some(y) = cholesky_solve(&a, &err) else {
            return finish(converged, iteration, norm, ws);
        };
        // Back-tracking: halve the step until the error decreases. A polishing step is tried whole only:
        // from within the tolerance the full step lowers the error unless round-off already dominates it,
        // where halving it would only spend evaluations.
        let mut step = 1.0;
        let mut accepted = false;
        let tries = if converged { 1 } else { 30 };
        for _ in 0..tries {
            let t = &mut ws.trial_coords;
            for (k, j) in ws.current.actuated.iter().enumerate() {
                t.actuated[k] = coords.actuated[k] + step * jw(j).dot(&y);
            }
            for (k, j) in ws.current.passive.iter().enumerate() {
                t.passive[k] = coords.passive[k] + step * jw(j).dot(&y);
            }
            chain.evaluate(t, &mut ws.trial);
            let trial_err = weigh_rotations(&ws.trial.end.error_to(target), length_scale);
            let trial_norm = trial_err.norm();
            if trial_norm < norm {
                coords.actuated.copy_from_slice(&t.actuated);
                coords.passive.copy_from_slice(&t.passive);
                std::mem::swap(&mut ws.current, &mut ws.trial);
                norm = trial_norm;
                err = trial_err;
                accepted = true;
                break;
            }
            step *= 0.5;
        }
        if !accepted {
            // A polishing step that cannot lower the error leaves the converged solution as it is.
            return finish(converged, iteration, norm, ws);
        }
        polished = converged;
    }
    finish(norm <= tolerance, MAX_ITERATIONS, norm, ws)
}

/// Solves `a y = e` for a symmetric positive definite 6x6 `a` (its lower triangle is read), or None where a
/// pivot is not positive. The operations and their order are those of nalgebra's `Cholesky::new` and
/// `solve` (left-looking column updates, each column divided by its pivot's square root, then forward and
/// back substitution with dot products summed from zero), so every iterate, and every map, is the same to
/// the bit; on fixed arrays it costs a fraction of the generic code's time.
fn cholesky_solve(a: &Mat6, e: &Vec6) -> Option<Vec6> {
    // l[j][i]: column j, row i (i >= j), as nalgebra stores it.
    let mut l: [[f64; 6]; 6] = std::array::from_fn(|j| std::array::from_fn(|i| a[(i, j)]));
    for j in 0..6 {
        let (done, rest) = l.split_at_mut(j);
        let column = &mut rest[0];
        for earlier in done.iter() {
            let factor = earlier[j];
            for (x, lk) in column[j..].iter_mut().zip(&earlier[j..]) {
                *x -= factor * lk;
            }
        }
        let diag = column[j];
        if diag <= 0.0 || diag.is_nan() {
            return None;
        }
        let root = diag.sqrt();
        column[j] = root;
        for x in column[j + 1..].iter_mut() {
            *x /= root;
        }
    }
    let mut y: [f64; 6] = std::array::from_fn(|i| e[i]);
    for i in 0..6 {
        let c = y[i] / l[i][i];
        y[i] = c;
        for k in i + 1..6 {
            y[k] -= c * l[i][k];
        }
    }
    for i in (0..6).rev() {
        let mut dot = 0.0;
        for k in i + 1..6 {
            dot += l[i][k] * y[k];
        }
        y[i] = (y[i] - dot) / l[i][i];
    }
    Some(Vec6::from(y))
}

/// The end of a solve: converged (the evaluation in `ws` is the solution's) or not.
fn finish(converged: bool, iterations: usize, norm: f64, ws: &mut IkWorkspace) -> Result<usize, IkFailure> {
    if converged {
        ws.current_is_valid = true;
        Ok(iterations)
    } else {
        Err(IkFailure { iterations, residual_mm: norm })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Gauss-Newton step solves the damped normal equations (J J^T + lambda I) y = e by Cholesky. The
    /// fixed-size solve must give nalgebra's numbers bit for bit (maps are byte-identical across the change),
    /// on well and badly conditioned matrices alike, and refuse what nalgebra refuses.
    #[test]
    fn normal_equations_solve_matches_nalgebra_cholesky_bit_for_bit() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut refused = 0;
        for case in 0..2000 {
            // Five columns (a 3-PUU leg's unknowns) or six, with column scales over ten decades.
            let columns = 5 + case % 2;
            let mut a = Mat6::zeros();
            for _ in 0..columns {
                let scale = 10f64.powf(5.0 * next());
                let w = Vec6::from_fn(|_, _| next() * scale);
                a += w * w.transpose();
            }
            if case % 7 == 0 {
                a[(2, 2)] = -a[(2, 2)];
            }
            let e = Vec6::from_fn(|_, _| next() * 10f64.powf(3.0 * next()));
            let ours = cholesky_solve(&a, &e);
            let theirs = a.cholesky().map(|c| c.solve(&e));
            match (ours, theirs) {
                (Some(x), Some(y)) => {
                    for k in 0..6 {
                        assert_eq!(x[k].to_bits(), y[k].to_bits(), "case {case}, entry {k}: {} vs {}", x[k], y[k]);
                    }
                }
                (None, None) => refused += 1,
                (x, y) => panic!("case {case}: ours {x:?}, nalgebra {y:?}"),
            }
        }
        assert!(refused > 100, "the indefinite cases are refused ({refused})");
    }
}

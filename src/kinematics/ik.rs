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
/// Round-off, as a fraction of the tolerance: 1e-16 of the length scale (9e-14 mm on a 900 mm 3-PUU leg),
/// about what a Newton step from within the tolerance leaves (2e-14 to 9e-14 mm there). An extrapolated
/// start below it is a solution already for a caller that reads the pose alone (`Needs::Pose`: a loaded
/// equilibrium starts there). Accepting extrapolations at the polished level for those left placements
/// 1e-13 to 4e-12 mm from their poses, noise in the next loaded starts extrapolated from the loaded
/// solutions they shift: along a finely sampled line, settling took two chord steps at 57% of the points
/// instead of 22%. A caller that reads the Jacobians there (`Needs::Jacobians`: a stiffness, a joint's
/// twists) takes an extrapolated start at the polished level as it is: the Jacobians of a configuration
/// 1e-14 of the length scale away differ by about that much, relatively (the unloaded 3-PUU's compliance
/// moved by 2e-12 of its scale at most), where a polishing step costs a second evaluation of the chain
/// (on the unloaded 3-PUU's bench grid, half its placements).
const ROUND_OFF: f64 = 1e-7;
/// Chord steps (on the last factorisation) are taken from iterates the step before brought this much
/// closer, or more: they then converge at least about as fast as that step did.
const CHORD_CONTRACTION: f64 = 1e-3;
/// Steps from within this many length scales of the pose (0.09 mm on a 900 mm leg) are tried on the end
/// frame alone: the extrapolated starts of a map's rows (3e-3 mm on a 3-PUU grid 13 mm apart) land within
/// the tolerance in one Newton step (1e-9 mm), and a chord step then polishes them.
const POSE_ONLY_RANGE: f64 = 1e-4;
/// A first Newton step from an error e is expected to leave this many times e^2 over the length scale, or
/// less (quadratic convergence; on the 3-PUU's legs, from starts 1e-9 to 1e-1 of the length scale away,
/// 0.04 to 2.6 times, and up to 11 times where what is left is round-off): where that is within the
/// polished level the step is the solution, and a caller of the Jacobians has it evaluated in full rather
/// than tried on the end frame first.
const NEWTON_MARGIN: f64 = 100.0;
/// The reach decision's tolerance (mm, rotations weighted by the length scale). At a reach boundary (a leg
/// stretched to a fold of its kinematics) Gauss-Newton converges sublinearly: a 3-PUU pose 1e-5 mm inside
/// its boundary ends 60 iterations 7e-6 mm away, as does one 1e-6 mm outside. A solve that ends within
/// this distance therefore says "at the reach boundary, within 1e-4 mm", not "unreachable": the pose may
/// lie on either side, and its stiffness is degenerate there (status `ill_conditioned`).
pub const REACH_TOLERANCE_MM: f64 = 1e-4;

/// What a solve's caller reads at the solution besides its coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Needs {
    /// The chain's Jacobians there (a stiffness, a joint's twists): a trial expected to be the solution is
    /// evaluated in full, and an extrapolated start at the polished level is a solution as it is.
    Jacobians,
    /// The pose alone (a loaded equilibrium, which evaluates its own chain from there): every trial expected
    /// to be the solution is tried on the end frame, and the solution's evaluation is left to be made where
    /// it is asked for.
    Pose,
}

/// Buffers reused from one solve to the next (no allocation per point).
#[derive(Clone, Debug, Default)]
pub struct IkWorkspace {
    /// The chain evaluated at the current coordinates.
    pub current: ChainJacobians,
    /// True when `current` was evaluated at the coordinates the next solve starts from (the previous
    /// solution), so the first Newton step needs no new evaluation.
    current_is_valid: bool,
    /// True when the last solve converged on an iterate reached on its end frame alone, whose evaluation
    /// is made only where it is asked for (`solution`, `joints_at_solution`, or the next solve's start): a
    /// loaded equilibrium placed there evaluates its own chain and never reads it.
    pending: bool,
    trial: ChainJacobians,
    trial_coords: Coordinates,
}

impl IkWorkspace {
    /// To be called when the coordinates are changed by anything but `solve`.
    pub fn invalidate(&mut self) {
        self.current_is_valid = false;
        self.pending = false;
    }

    /// Evaluates `chain` at `coords` as the start of the next solve (the coordinates it will be handed): a
    /// solve at the pose they reach then converges on this evaluation without a new one.
    pub fn evaluate_at(&mut self, chain: &Chain, coords: &Coordinates) -> &ChainJacobians {
        chain.evaluate(coords, &mut self.current);
        self.current_is_valid = true;
        self.pending = false;
        &self.current
    }

    /// The evaluation at the last solution (virtual columns included), while the coordinates have not
    /// changed since: `coords` are the solution, where its evaluation is still to be made.
    pub fn solution(&mut self, chain: &Chain, coords: &Coordinates) -> Option<&ChainJacobians> {
        self.joints_at_solution(chain, coords)?;
        self.current.fill_virtual();
        Some(&self.current)
    }

    /// As `solution`, without filling the virtual coordinates' columns (for the joints' twists alone).
    pub fn joints_at_solution(&mut self, chain: &Chain, coords: &Coordinates) -> Option<&ChainJacobians> {
        if self.pending {
            self.evaluate_at(chain, coords);
        }
        self.kept()
    }

    /// The evaluation at the last solution where it has been made (`solution` makes it where it is still to
    /// be made).
    pub fn kept(&self) -> Option<&ChainJacobians> {
        self.current_is_valid.then_some(&self.current)
    }
}

/// Solves `end_frame(coords) = target` for the actuated and passive coordinates; virtual coordinates are
/// left as they are. Returns the number of iterations; `ws.solution` then gives the evaluation at the
/// solution.
///
/// Once within `TOLERANCE`, the solve goes on to the polished level (`POLISHED` of it, a few hundred times
/// round-off) or takes one more Newton step (kept where it lowers the error, it leaves about the
/// tolerance's square): so that the solution does not depend on where the solve started (a map's
/// placements, and every loaded result through its actuators, are then the same whatever order the poses
/// are visited in), and a command changed by less than the tolerance still moves the actuators
/// (compliance compensation iterates on such commands). A previous solution already at the polished level,
/// or an extrapolation at round-off (a leg moving along its own actuator's line), is the solution.
///
/// Only the solution and Newton steps need the Jacobians' columns. Close to the pose, an iterate that is
/// not expected to be the solution is reached on its end frame alone (forward kinematics, 60% of a full
/// evaluation's instructions on a 3-PUU leg), and the next step reuses the last factorisation (a chord
/// step) where the step that led there contracted the error enough for it: a map's placement from an
/// extrapolated start is then one full evaluation at the start, a Newton step tried on the end frame, and
/// a chord step to the solution, evaluated in full; from a start the rows before corrected to within the
/// tolerance (`platform::leg_state::PlacementTrail`), the evaluation at the start and one polishing step.
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
    needs: Needs,
) -> Result<usize, IkFailure> {
    let tolerance = TOLERANCE * length_scale.max(1.0);
    let polished_level = POLISHED * tolerance;
    // The level at which an extrapolated start is a solution as it is (see `ROUND_OFF`).
    let start_level = match needs {
        Needs::Jacobians => polished_level,
        Needs::Pose => ROUND_OFF * tolerance,
    };
    ws.trial_coords.clone_from(coords);
    // A start evaluated and kept is a solution (the last one, or a seeded configuration's own pose), as is
    // one whose evaluation was left to be made.
    let start_is_solution = ws.current_is_valid || ws.pending;
    if !ws.current_is_valid {
        chain.evaluate(coords, &mut ws.current);
    }
    ws.current_is_valid = false;
    ws.pending = false;
    // True while `ws.current` is the evaluation at `coords`. A step tried on the end frame alone leaves it
    // the evaluation at the step's origin, whose factorisation `normal` still holds.
    let mut evaluated = true;
    let mut normal = NormalEquations::default();
    let mut err = weigh_rotations(&ws.current.end.error_to(target), length_scale);
    let mut norm = err.norm();
    let mut norm_before_step = f64::INFINITY;
    // A Newton step taken from within the tolerance leaves about the tolerance's square, round-off.
    let mut newton_polished = false;
    let mut chord_failed = false;
    for iteration in 0..MAX_ITERATIONS {
        let converged = norm <= tolerance;
        // A Newton iterate or a solution already at the polished level needs no polishing step. Any other
        // start (an extrapolation, a loaded configuration) takes at least one step unless it is within
        // `start_level`: its error, however small, is the start's (for a pose alone, an extrapolation's
        // within 1e-11 mm would stay in every loaded answer, and as noise in the extrapolations of the
        // next loaded starts).
        let at_level = if iteration > 0 || start_is_solution { polished_level } else { start_level };
        if converged && (newton_polished || norm <= at_level) {
            return finish(true, iteration, norm, evaluated, ws);
        }
        // From an iterate reached on the end frame alone, a chord step (the factorisation of the step that
        // led there) where that step contracted the error well: its contraction measures how far the
        // Jacobian turned over it, and a chord step contracts about as much again (twice, to first order).
        let contraction = norm / norm_before_step;
        let chord = !evaluated && !chord_failed && contraction <= CHORD_CONTRACTION;
        if !chord {
            if !evaluated {
                chain.evaluate(coords, &mut ws.current);
                evaluated = true;
            }
            if !normal.factorise(&ws.current, length_scale) {
                return finish(converged, iteration, norm, evaluated, ws);
            }
        }
        let y = normal.solve(&err);
        // The trial is tried on the end frame alone (forward kinematics without the Jacobians' columns)
        // where neither its Jacobian nor a full evaluation is expected to be needed: a chord step expected
        // to leave more than the polished level (about twice `contraction` of the error), or a Newton step
        // expected to land within the tolerance but not at the polished level (about the error's square,
        // `contraction` squared; a first step from within `POSE_ONLY_RANGE`), where chord steps follow.
        // A caller that reads no Jacobian at the solution has every trial expected to be the solution
        // tried on the end frame too (its evaluation is then made only where it is asked for).
        let pose_wanted = needs == Needs::Pose;
        let pose_only = if chord {
            2.0 * contraction * norm > polished_level || pose_wanted
        } else if norm_before_step.is_finite() {
            let expected = contraction * contraction * norm;
            (polished_level..=tolerance).contains(&expected) || (pose_wanted && expected < polished_level)
        } else {
            // A first step: a Newton step from near the pose, unless it is expected to land at the
            // polished level (`NEWTON_MARGIN`; a caller of the Jacobians evaluates the solution in full
            // anyway), or a polishing step from a start within the tolerance, expected to be the solution.
            let lands_polished = NEWTON_MARGIN * norm * norm / length_scale <= polished_level;
            let newton = !converged && norm <= POSE_ONLY_RANGE * length_scale && (pose_wanted || !lands_polished);
            newton || (pose_wanted && converged)
        };
        // Back-tracking: halve the step until the error decreases. A polishing step is tried whole only:
        // from within the tolerance the full step lowers the error unless round-off already dominates it,
        // where halving it would only spend evaluations.
        let jw = |j: &Vec6| weigh_rotations(j, length_scale);
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
            let trial_end = if pose_only {
                chain.end_frame(t)
            } else {
                chain.evaluate(t, &mut ws.trial);
                ws.trial.end
            };
            let trial_err = weigh_rotations(&trial_end.error_to(target), length_scale);
            let trial_norm = trial_err.norm();
            if trial_norm < norm {
                coords.actuated.copy_from_slice(&t.actuated);
                coords.passive.copy_from_slice(&t.passive);
                if pose_only {
                    evaluated = false;
                } else {
                    std::mem::swap(&mut ws.current, &mut ws.trial);
                    evaluated = true;
                }
                norm_before_step = norm;
                norm = trial_norm;
                err = trial_err;
                accepted = true;
                break;
            }
            step *= 0.5;
        }
        if chord && !accepted {
            // The Jacobian turned more than its last step promised: a Newton step from here.
            chord_failed = true;
            continue;
        }
        if !accepted {
            // A polishing step that cannot lower the error leaves the converged solution as it is.
            return finish(converged, iteration, norm, evaluated, ws);
        }
        newton_polished = converged && !chord;
    }
    finish(norm <= tolerance, MAX_ITERATIONS, norm, evaluated, ws)
}

/// The damped normal equations `(J J^T + lambda I) y = e` of a Gauss-Newton step in the weighted metric,
/// factorised (Cholesky) once and solved for as many right-hand sides as a chord iteration takes.
#[derive(Default)]
struct NormalEquations {
    /// l[j][i]: the factor's column j, row i (i >= j), as nalgebra stores it.
    l: [[f64; 6]; 6],
}

impl NormalEquations {
    /// Forms and factorises the equations of the evaluation's actuated and passive columns; false where a
    /// pivot is not positive.
    fn factorise(&mut self, at: &ChainJacobians, length_scale: f64) -> bool {
        let mut a = Mat6::zeros();
        for j in at.actuated.iter().chain(at.passive.iter()) {
            let w = weigh_rotations(j, length_scale);
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
        match cholesky_factor(&a) {
            Some(l) => {
                self.l = l;
                true
            }
            None => false,
        }
    }

    fn solve(&self, e: &Vec6) -> Vec6 {
        cholesky_substitute(&self.l, e)
    }
}

/// Solves `a y = e` for a symmetric positive definite 6x6 `a` (its lower triangle is read), or None where a
/// pivot is not positive: `cholesky_factor` then `cholesky_substitute`, as the normal equations use them,
/// composed for the test that holds them to nalgebra. The operations and their order are those of
/// nalgebra's `Cholesky::new` and `solve` (left-looking column updates, each column divided by its pivot's
/// square root, then forward and back substitution with dot products summed from zero), so every iterate,
/// and every map, is the same to the bit; on fixed arrays it costs a fraction of the generic code's time.
#[cfg(test)]
fn cholesky_solve(a: &Mat6, e: &Vec6) -> Option<Vec6> {
    cholesky_factor(a).map(|l| cholesky_substitute(&l, e))
}

/// The Cholesky factor of `a` by columns, l[j][i] column j, row i (i >= j), as nalgebra stores it; None
/// where a pivot is not positive.
fn cholesky_factor(a: &Mat6) -> Option<[[f64; 6]; 6]> {
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
    Some(l)
}

/// Forward and back substitution on the factor of `cholesky_factor`.
fn cholesky_substitute(l: &[[f64; 6]; 6], e: &Vec6) -> Vec6 {
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
    Vec6::from(y)
}

/// The end of a solve: converged (the evaluation at the solution kept, or left to be made where the last
/// step was tried on the end frame alone) or not.
fn finish(
    converged: bool,
    iterations: usize,
    norm: f64,
    evaluated: bool,
    ws: &mut IkWorkspace,
) -> Result<usize, IkFailure> {
    if !converged {
        return Err(IkFailure { iterations, residual_mm: norm });
    }
    // The solution's evaluation is the last one made where it was evaluated in full; else it is made where
    // it is asked for.
    ws.current_is_valid = evaluated;
    ws.pending = !evaluated;
    Ok(iterations)
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

//! Loaded mode of one VJM chain (paper 000 s. 3.3-3.4, paper 001 s. 3.2-3.3): the equilibrium with the
//! chain's end held at a given frame (the dual problem, eq 32-36), and the tangent stiffness there with its
//! sensitivity matrices K_Cq and K_Ctheta (eq 45-47).
//!
//! Unknowns: passive coordinates q, virtual coordinates theta, and the wrench F the platform applies to the
//! chain's end. Equations (eq 31):
//!   g(q, theta) = t                                            (6)
//!   J_q^T F + sum_j J_qj^T G_j = 0                             (n)
//!   J_theta^T F + sum_j J_thetaj^T G_j = K_theta (theta - theta0)   (m)
//! solved by a full Newton method using the exact Hessians (tests/reference/README.md: the frozen-Jacobian fixed point of
//! paper 001 eq 15 stalls at some workspace points; Newton converges in a few iterations). The same
//! factorisation at the solution gives the tangent stiffness (eq 45: six more right-hand sides) and the
//! stability test (its reduced matrix, `linalg::SaddlePointLu`).

use nalgebra::{DMatrix, DVector};

use super::spring::SpringGroup;
use crate::kinematics::chain::{Chain, ChainJacobians, Coordinates};
use crate::kinematics::frame::{weigh_rotations, Frame, Mat6, Vec3, Vec6};
use crate::linalg::{all_finite, SaddlePointLu};

/// What a loaded chain needs besides its kinematics.
pub struct LoadedChain<'a> {
    /// The leg's chain.
    pub chain: &'a Chain,
    /// Its spring groups.
    pub springs: &'a [SpringGroup],
    /// Gravity, m/s^2 (masses in kg give weights in N).
    pub gravity: Vec3,
    /// Spring preload theta0 (rest values of the virtual coordinates), one per virtual coordinate.
    pub preload: &'a [f64],
    /// mm per rad, to weigh rotations against translations.
    pub length_scale: f64,
}

/// The chain at equilibrium.
#[derive(Clone, Debug)]
pub struct LoadedAnswer {
    /// Wrench the platform applies to the chain's end (N, N mm), base frame, at the end point.
    pub wrench: Vec6,
    /// Tangent stiffness dF/dt at the end point (eq 45-47).
    pub stiffness: Mat6,
    /// The chain is stable with its end held: the energy's Hessian is positive definite on the motions
    /// that keep the end fixed (paper 000 eq 14, reduced form).
    pub stable: bool,
    /// Newton iterations spent.
    pub iterations: usize,
    /// End point, base frame.
    pub end: Vec3,
}

/// Why a chain's loaded equilibrium was not found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EquilibriumFailure {
    /// Newton's method did not converge.
    NotConverged {
        /// Iterations spent.
        iterations: usize,
        /// The largest remaining residual (mm, rad or N).
        residual: f64,
    },
    /// The Newton matrix (paper 000 eq 45) is singular.
    Singular,
}

/// Most Newton iterations per equilibrium.
pub const MAX_ITERATIONS: usize = 40;

/// Buffers reused between solves.
#[derive(Clone, Debug, Default)]
pub struct EquilibriumWorkspace {
    jac: ChainJacobians,
    generalised: Vec<f64>,
    residual: Vec<f64>,
    /// The statics block W of eq (45)'s matrix [[J, 0], [W, J^T]] at the last linearisation (k x k, k = n +
    /// m: the load Hessian less the springs' stiffness, that is minus the energy's Hessian), the right-hand
    /// sides by rows (the residuals, then a unit end displacement along each axis: solved together), and the
    /// matrix's factorisation through the null space of J (`SaddlePointLu`), which the stability test
    /// reads too.
    statics: DMatrix<f64>,
    rhs: Vec<[f64; 7]>,
    factors: SaddlePointLu,
    /// Factorisations made in `factors` so far: a linearisation records the number of its own, so that a
    /// chord step knows whether `factors` still holds it.
    factorizations: u64,
    /// A factorisation set aside by `keep_factorisation`, and the number it had there (0: none).
    kept: SaddlePointLu,
    kept_number: u64,
}

impl EquilibriumWorkspace {
    /// Sets aside a copy of the factorisation of `lin`, the last linearisation made here, for
    /// `resume_kept` (chord steps at a point near the one it was made at, after others in between). False
    /// where the workspace no longer holds `lin`'s factorisation.
    pub fn keep_factorisation(&mut self, lin: &Linearization) -> bool {
        if lin.factorization == 0 || lin.factorization != self.factorizations {
            return false;
        }
        self.kept.clone_from(&self.factors);
        self.kept_number = self.factorizations;
        true
    }

    /// Makes the factorisation set aside for `lin` (the linearisation it was made by, kept by the caller)
    /// the current one again, under a new number that `lin` takes: chord steps may follow on it. The
    /// factorisation it replaces is dropped. False where none is set aside for `lin`.
    pub fn resume_kept(&mut self, lin: &mut Linearization) -> bool {
        if self.kept_number == 0 || lin.factorization != self.kept_number {
            return false;
        }
        std::mem::swap(&mut self.factors, &mut self.kept);
        self.kept_number = 0;
        self.factorizations += 1;
        lin.factorization = self.factorizations;
        true
    }
}

/// The linearised equilibrium of eq (45) at the current configuration: one factorisation serves the Newton
/// correction at a fixed end, the response to a moving end, the tangent stiffness and the stability test.
#[derive(Clone, Debug)]
pub struct Linearization {
    /// `M^-1 [e; -r]`: the change of (q, theta, F) that restores equilibrium with the end where it is asked.
    correction: Vec<f64>,
    /// `M^-1 [I6; 0]`: the change of (q, theta, F) per unit displacement of the end (N x 6, by rows: each
    /// coordinate's response is one contiguous dot product). Its F rows are the tangent stiffness K_C, its
    /// q and theta rows K_Cq and K_Ctheta (eq 46).
    sensitivity: Vec<[f64; 6]>,
    /// End point (base frame) and wrench at the configuration linearised.
    pub end: Vec3,
    /// The wrench at the end.
    pub wrench: Vec6,
    /// Where the end is minus where it was asked (translation, rotation vector).
    pub end_error: Vec6,
    /// The number of its factorisation in the workspace that made it (see `EquilibriumWorkspace`).
    factorization: u64,
    /// The change of every unknown in the last step `damping` measured (its end twist), for
    /// `advance_measured` to apply: each change is computed once.
    step: Vec<f64>,
}

impl Linearization {
    /// An empty linearisation, for `LoadedChain::linearize_into` to fill.
    pub fn empty() -> Self {
        Linearization {
            correction: Vec::new(),
            sensitivity: Vec::new(),
            end: Vec3::zeros(),
            wrench: Vec6::zeros(),
            end_error: Vec6::zeros(),
            factorization: 0,
            step: Vec::new(),
        }
    }

    /// The change of coordinate `k` (in unknown order q, theta, F) for the end moved by `end_twist`:
    /// the correction plus the sensitivities' response.
    fn delta(&self, k: usize, end_twist: &Vec6) -> f64 {
        self.correction[k] + along(&self.sensitivity[k], end_twist)
    }

    /// The change of (q, theta, F) per end displacement `end_twist` with the equilibrium kept (eq 46's
    /// K_Cq, K_Ctheta and K_C times it), without the correction.
    pub fn response(&self, end_twist: &Vec6) -> DVector<f64> {
        DVector::from_iterator(self.sensitivity.len(), self.sensitivity.iter().map(|s| along(s, end_twist)))
    }

    /// The wrench at the end once the correction is made.
    pub fn corrected_wrench(&self) -> Vec6 {
        let o = self.correction.len() - 6;
        self.wrench + Vec6::from_column_slice(&self.correction[o..])
    }

    /// The tangent stiffness at the end (the last six rows of the sensitivities).
    pub fn stiffness(&self) -> Mat6 {
        let o = self.sensitivity.len() - 6;
        Mat6::from_fn(|r, c| self.sensitivity[o + r][c])
    }

    /// How far the configuration linearised is from equilibrium, relative as the platform's steps are
    /// measured: the larger of the largest coordinate correction (rad, or mm over `length_scale` for the
    /// coordinates `length_coordinates` marks, passive then virtual) and the end's pose error (rotations
    /// weighted by `length_scale`) over `length_scale`. A length and an angle are then held alike: a
    /// tolerance in mm would hold a spring's deflection `length_scale` times tighter than its rotation, for
    /// chord steps that move neither the stiffness nor the pose beyond round-off.
    pub fn distance_from_equilibrium(&self, length_scale: f64, length_coordinates: &[bool]) -> f64 {
        let pose = weigh_rotations(&self.end_error, length_scale).norm();
        let o = self.correction.len() - 6;
        debug_assert_eq!(length_coordinates.len(), o, "one mark per passive and virtual coordinate");
        let per_length = 1.0 / length_scale;
        let coordinates = (self.correction[..o].iter().zip(length_coordinates))
            .fold(0.0f64, |m, (v, &is_length)| m.max(v.abs() * if is_length { per_length } else { 1.0 }));
        coordinates.max(pose / length_scale)
    }

    /// Largest change of a coordinate (rad or mm) in the correction.
    fn coordinate_correction(&self) -> f64 {
        let o = self.correction.len() - 6;
        self.correction[..o].iter().fold(0.0f64, |m, v| m.max(v.abs()))
    }
}

/// Tolerance on the end's pose error (times the length scale) and on the Newton step (rad or mm).
const POSE_TOLERANCE: f64 = 1e-10;
/// Newton converges when the step is below this too (rad or mm).
pub const STEP_TOLERANCE: f64 = 1e-11;
/// Largest change of a coordinate in one Newton step (rad or mm): a damped step, not a line search.
pub const MAX_STEP: f64 = 0.2;

impl LoadedChain<'_> {
    fn sizes(&self) -> (usize, usize) {
        (self.chain.n_passive, self.chain.n_virtual)
    }

    /// Builds the Newton matrix of eq (45) at the current evaluation, and the residuals, into the
    /// workspace: its statics block W (the kinematic blocks are J and J^T, the chain's Jacobian).
    /// Unknown order: (q, theta, F); equation order: (kinematics, q-statics, theta-statics). Right-hand
    /// sides: the residuals, then a unit displacement of the end along each axis.
    fn assemble(&self, coords: &Coordinates, wrench: &Vec6, target: &Frame, ws: &mut EquilibriumWorkspace) {
        let (n, m) = self.sizes();
        let size = n + m + 6;
        let EquilibriumWorkspace { jac, generalised, residual, statics: w, rhs, .. } = ws;
        resize_zeroed(w, n + m, n + m);
        rhs.clear();
        rhs.resize(size, [0.0; 7]);
        residual.resize(size, 0.0);
        self.residual(coords, wrench, target, jac, generalised, residual);
        for (row, value) in rhs.iter_mut().zip(residual.iter()) {
            row[0] = *value;
        }
        for (r, row) in rhs.iter_mut().take(6).enumerate() {
            row[1 + r] = 1.0;
        }
        jac.add_load_hessian(wrench, &self.gravity, n, w);
        for s in self.springs {
            let varying;
            let stiffness = if s.varies() {
                varying = s.stiffness_at(coords);
                &varying
            } else {
                &s.stiffness
            };
            // The block's columns as slices of W (column-major), each entry still one subtraction.
            let (first, size) = (n + s.first, w.nrows());
            for (j, k_column) in stiffness.column_iter().take(s.dim).enumerate() {
                let w_column = &mut w.as_mut_slice()[(first + j) * size + first..][..s.dim];
                for (v, k) in w_column.iter_mut().zip(k_column.iter()) {
                    *v -= k;
                }
            }
            // A spring whose stiffness depends on a passive coordinate q (paper 000 s. 6: "an equivalent
            // non-linear virtual spring whose stiffness depends on the internal variable"): its energy
            // 1/2 dtheta^T K(q) dtheta also pushes on q, and both statics rows depend on q.
            if let Some((q, dk, ddk)) = s.posture_derivatives(&coords.passive) {
                let d = self.deflection(s, coords);
                let dk_d = dk * d;
                w[(q, q)] -= 0.5 * d.dot(&(ddk * d));
                for i in 0..s.dim {
                    w[(n + s.first + i, q)] -= dk_d[i];
                    w[(q, n + s.first + i)] -= dk_d[i];
                }
            }
        }
    }

    /// The spring group's deflection theta - theta0, zero past its coordinates (its matrices are zero
    /// there too, so a whole 6x6 product serves every group).
    fn deflection(&self, s: &SpringGroup, coords: &Coordinates) -> Vec6 {
        let (theta, rest) = (&coords.virtual_[s.first..s.first + s.dim], &self.preload[s.first..s.first + s.dim]);
        Vec6::from_fn(|j, _| if j < s.dim { theta[j] - rest[j] } else { 0.0 })
    }

    /// The residuals `[e; -r]` of eq (31) at the evaluation in `jac`, in equation order (kinematics,
    /// q-statics, theta-statics), written into `out` (length n + m + 6): the end's pose error, and the
    /// generalised forces the springs do not balance.
    fn residual(
        &self,
        coords: &Coordinates,
        wrench: &Vec6,
        target: &Frame,
        jac: &ChainJacobians,
        generalised: &mut Vec<f64>,
        out: &mut [f64],
    ) {
        let (n, m) = self.sizes();
        out.fill(0.0);
        out[..6].copy_from_slice(jac.end.error_to(target).as_slice());
        generalised.clear();
        generalised.resize(n + m, 0.0);
        jac.add_generalised_forces(wrench, &self.gravity, n, generalised);
        for (k, g) in generalised.iter().enumerate() {
            out[6 + k] = -g;
        }
        for s in self.springs {
            let d = self.deflection(s, coords);
            // A constant spring's stiffness is read in place (copying the 6x6 matrix cost more than the
            // product): only a varying one is evaluated.
            let force = if s.varies() { s.stiffness_at(coords) * d } else { s.stiffness * d };
            for (o, f) in out[6 + n + s.first..6 + n + s.first + s.dim].iter_mut().zip(force.iter()) {
                *o += f;
            }
            // The posture-dependent spring's energy pushes on its passive coordinate (see `assemble`).
            if let Some((q, dk, _)) = s.posture_derivatives(&coords.passive) {
                out[6 + q] += 0.5 * d.dot(&(dk * d));
            }
        }
    }

    /// A chord step (simplified Newton): the residuals at `coords` solved with the factorisation of the
    /// last full linearisation in `ws`, into `lin`, whose sensitivities stay those of that linearisation.
    /// Near the solution it contracts by the relative change of the matrix since, for the price of one
    /// evaluation and one solve. None where `ws` no longer holds `lin`'s factorisation (the chain was
    /// linearised since for another purpose): a full linearisation must come first. Some(false) where the
    /// solution is not finite.
    pub fn refresh(
        &self,
        target: &Frame,
        coords: &Coordinates,
        wrench: &Vec6,
        ws: &mut EquilibriumWorkspace,
        lin: &mut Linearization,
    ) -> Option<bool> {
        if lin.factorization == 0 || lin.factorization != ws.factorizations {
            return None;
        }
        // The residual reads the joints' placements, not the Jacobian columns (only a factorisation needs
        // those), so none is made.
        self.chain.place_joints(coords, &mut ws.jac);
        let correction = &mut lin.correction[..];
        self.residual(coords, wrench, target, &ws.jac, &mut ws.generalised, correction);
        lin.end_error = target_error(correction);
        ws.factors.solve_in_place(correction);
        lin.end = ws.jac.end.pos;
        lin.wrench = *wrench;
        Some(correction.iter().all(|v| v.is_finite()))
    }

    /// Linearises the equilibrium with the chain's end asked at `target`.
    pub fn linearize(
        &self,
        target: &Frame,
        coords: &Coordinates,
        wrench: &Vec6,
        ws: &mut EquilibriumWorkspace,
    ) -> Option<Linearization> {
        let mut lin = Linearization::empty();
        self.linearize_into(target, coords, wrench, ws, &mut lin).then_some(lin)
    }

    /// `linearize` into `lin`'s buffers (the manipulator's Newton method linearises every leg several
    /// times per point). False where the matrix is singular or the solution not finite.
    pub fn linearize_into(
        &self,
        target: &Frame,
        coords: &Coordinates,
        wrench: &Vec6,
        ws: &mut EquilibriumWorkspace,
        lin: &mut Linearization,
    ) -> bool {
        self.chain.evaluate(coords, &mut ws.jac);
        ws.jac.fill_virtual();
        self.assemble(coords, wrench, target, ws);
        ws.factorizations += 1;
        let jacobian = ws.jac.passive.iter().chain(&ws.jac.virtual_).map(|c| (*c).into());
        if !ws.factors.factor(jacobian, ws.statics.as_slice(), ws.statics.nrows()) {
            return false;
        }
        ws.factors.solve_rows(&mut ws.rhs);
        if !all_finite(ws.rhs.as_flattened()) {
            return false;
        }
        // Filled in place (a resize, then stores), as every buffer of a linearisation.
        let size = ws.rhs.len();
        lin.correction.resize(size, 0.0);
        lin.sensitivity.resize(size, [0.0; 6]);
        for ((row, correction), sensitivity) in ws.rhs.iter().zip(&mut lin.correction).zip(&mut lin.sensitivity) {
            *correction = row[0];
            *sensitivity = std::array::from_fn(|c| row[1 + c]);
        }
        lin.end = ws.jac.end.pos;
        lin.wrench = *wrench;
        lin.end_error = target_error(&ws.residual);
        lin.factorization = ws.factorizations;
        true
    }

    /// Moves (q, theta, F) by the linearisation's correction plus its response to an end displacement
    /// `end_twist` (at the end point), scaled by `fraction` (1 for a full Newton step).
    pub fn advance(
        &self,
        lin: &mut Linearization,
        end_twist: &Vec6,
        fraction: f64,
        coords: &mut Coordinates,
        wrench: &mut Vec6,
    ) {
        self.measure_step(lin, end_twist);
        self.advance_measured(lin, fraction, coords, wrench);
    }

    /// The change of every unknown (q, theta, F) in the step with the end moved by `end_twist`, into `lin`.
    fn measure_step(&self, lin: &mut Linearization, end_twist: &Vec6) {
        let (n, m) = self.sizes();
        let mut step = std::mem::take(&mut lin.step);
        step.clear();
        step.extend((0..n + m + 6).map(|k| lin.delta(k, end_twist)));
        lin.step = step;
    }

    /// The fraction of a Newton step (the end moved by `end_twist`) that keeps every coordinate change
    /// within `MAX_STEP`; the step's changes are kept in `lin` for `advance_measured`.
    pub fn damping(&self, lin: &mut Linearization, end_twist: &Vec6) -> f64 {
        let (n, m) = self.sizes();
        self.measure_step(lin, end_twist);
        let largest = lin.step[..n + m].iter().fold(0.0f64, |largest, d| largest.max(d.abs()));
        if largest > MAX_STEP {
            MAX_STEP / largest
        } else {
            1.0
        }
    }

    /// `advance` by `fraction` of the step `damping` measured last.
    pub fn advance_measured(&self, lin: &Linearization, fraction: f64, coords: &mut Coordinates, wrench: &mut Vec6) {
        let (n, m) = self.sizes();
        let (passive, rest) = lin.step.split_at(n);
        let (virtual_, end) = rest.split_at(m);
        for (q, d) in coords.passive.iter_mut().zip(passive) {
            *q += fraction * d;
        }
        for (theta, d) in coords.virtual_.iter_mut().zip(virtual_) {
            *theta += fraction * d;
        }
        for (f, d) in wrench.iter_mut().zip(end) {
            *f += fraction * d;
        }
    }

    /// True when the configuration linearised is an equilibrium: its correction is below the step
    /// tolerance and the end is where it was asked (within the pose tolerance).
    pub fn at_equilibrium(&self, lin: &Linearization, end_error: &Vec6) -> bool {
        let pose_error = weigh_rotations(end_error, self.length_scale).norm();
        lin.coordinate_correction() <= STEP_TOLERANCE && pose_error <= POSE_TOLERANCE * self.length_scale
    }

    /// Newton iterations from the given configuration and wrench (the warm start) to the equilibrium with
    /// the chain's end at `target`; on success `coords` and `wrench` hold it.
    pub fn solve(
        &self,
        target: &Frame,
        coords: &mut Coordinates,
        wrench: &mut Vec6,
        ws: &mut EquilibriumWorkspace,
    ) -> Result<LoadedAnswer, EquilibriumFailure> {
        for iteration in 0..MAX_ITERATIONS {
            let lin = self.linearize(target, coords, wrench, ws).ok_or(EquilibriumFailure::Singular)?;
            if self.at_equilibrium(&lin, &lin.end_error) {
                return Ok(LoadedAnswer {
                    wrench: *wrench,
                    stiffness: lin.stiffness(),
                    stable: self.stable(ws),
                    iterations: iteration,
                    end: lin.end,
                });
            }
            let mut lin = lin;
            let fraction = self.damping(&mut lin, &Vec6::zeros());
            self.advance_measured(&lin, fraction, coords, wrench);
        }
        let e = ws.jac.end.error_to(target);
        Err(EquilibriumFailure::NotConverged { iterations: MAX_ITERATIONS, residual: e.norm() })
    }

    /// Stability with the end held, at the last linearisation in `ws`: the Hessian of the energy (minus
    /// the statics block W of eq 45, spring stiffness included) positive definite on the null space of the
    /// constraint Jacobian J = [J_q J_theta], the motions that keep the end fixed (paper 000 eq 14, reduced
    /// form). The linearisation's factorisation has reduced W to that null space already
    /// (`SaddlePointLu::reduced_negative_definite`).
    pub fn stable(&self, ws: &mut EquilibriumWorkspace) -> bool {
        ws.factors.reduced_negative_definite()
    }
}

/// Where the end is minus where it was asked, from the residuals `[e; -r]` (e: the displacement carrying the
/// end to the target): `target.error_to(end)` is `-end.error_to(target)` exactly (the same products summed in
/// the same order, of a transposed rotation; a zero's sign aside), so the residual's evaluation serves.
fn target_error(residual: &[f64]) -> Vec6 {
    -Vec6::from_column_slice(&residual[..6])
}

/// One coordinate's response to an end displacement: its sensitivity row times the twist.
fn along(sensitivity: &[f64; 6], end_twist: &Vec6) -> f64 {
    sensitivity.iter().zip(end_twist.iter()).fold(0.0, |sum, (s, t)| sum + s * t)
}

fn resize_zeroed(m: &mut DMatrix<f64>, rows: usize, cols: usize) {
    if m.nrows() != rows || m.ncols() != cols {
        *m = DMatrix::zeros(rows, cols);
    } else {
        // In parts of 1 KB: libc's memset fills more than 2 KB (a whole matrix, 2.3 KB on the 3-PUU's legs)
        // by `rep stosb`, which callgrind counts once per byte, and below 2 KB by vector stores; a fill per
        // column costs a call each (17 there).
        for part in m.as_mut_slice().chunks_mut(128) {
            part.fill(0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A leg's distance from its equilibrium is relative, as the platform's steps are: a correction of x L
    /// mm on a length coordinate counts as x rad on an angle and as an end error of x L mm (L the length
    /// scale), so that neither a spring's deflection nor its rotation is held L times tighter than the
    /// other. The end wrench's correction (N) is not a distance.
    #[test]
    fn a_length_correction_counts_over_the_length_scale_as_an_angle_does() {
        let (l, x) = (900.0, 1e-6);
        let lengths = [false, true, false];
        let distance = |coordinates: [f64; 3], end_error: Vec6| {
            let mut lin = Linearization::empty();
            lin.correction = coordinates.iter().copied().chain([1e3; 6]).collect();
            lin.end_error = end_error;
            lin.distance_from_equilibrium(l, &lengths)
        };
        let none = Vec6::zeros();
        assert_eq!(distance([x, 0.0, 0.0], none), x);
        assert_eq!(distance([0.0, -x * l, 0.0], none), x);
        assert_eq!(distance([0.0, 0.0, x], none), x);
        assert_eq!(distance([0.0, 0.0, 0.0], Vec6::new(x * l, 0.0, 0.0, 0.0, 0.0, 0.0)), x);
        assert_eq!(distance([0.0, 0.0, 0.0], Vec6::new(0.0, 0.0, 0.0, 0.0, 0.0, x)), x);
        // The largest counts: an angle's x beside a length's x mm (x / L relative).
        assert_eq!(distance([0.5 * x, x, 0.0], none), 0.5 * x);
    }

    /// A chain whose end is held by its actuated joint alone (no passive joint, no spring) has no unknown
    /// but the end wrench: six constraints on none, a singular equilibrium. Its linearisation says so,
    /// again at the second call, whose statics block (empty) is reused; cutting that block into columns
    /// of its height, zero, panicked.
    #[test]
    fn a_chain_without_unknowns_linearises_to_a_singular_system_every_time() {
        use crate::kinematics::chain::{Element, Joint, JointKind, Role};
        let joint = Joint { kind: JointKind::Prismatic, axis: Vec3::x(), role: Role::Actuated, index: 0, gain: 1.0 };
        let chain = Chain::new(vec![Element::Joint(joint)]);
        let loaded =
            LoadedChain { chain: &chain, springs: &[], gravity: Vec3::zeros(), preload: &[], length_scale: 1.0 };
        let coords = Coordinates::zeros(&chain);
        let mut ws = EquilibriumWorkspace::default();
        let wrench = Vec6::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for _ in 0..2 {
            assert!(loaded.linearize(&Frame::IDENTITY, &coords, &wrench, &mut ws).is_none());
        }
    }
}

//! Loaded mode of one VJM chain (paper 000 s. 3.3-3.4, paper 001 s. 3.2-3.3): the equilibrium with the
//! chain's end held at a given frame (the dual problem, eq 32-36), and the tangent stiffness there with its
//! sensitivity matrices K_Cq and K_Ctheta (eq 45-47).
//!
//! Unknowns: passive coordinates q, virtual coordinates theta, and the wrench F the platform applies to the
//! chain's end. Equations (eq 31):
//!   g(q, theta) = t                                            (6)
//!   J_q^T F + sum_j J_qj^T G_j = 0                             (n)
//!   J_theta^T F + sum_j J_thetaj^T G_j = K_theta (theta - theta0)   (m)
//! solved by a full Newton method using the exact Hessians (errata.md: the frozen-Jacobian fixed point of
//! paper 001 eq 15 stalls at some workspace points; Newton converges in a few iterations). The same matrix
//! at the solution gives the tangent stiffness (eq 45), so the stiffness costs one more factorisation only.

use nalgebra::{DMatrix, DVector};

use super::spring::SpringGroup;
use crate::kinematics::chain::{Chain, ChainJacobians, Coordinates};
use crate::kinematics::frame::{Frame, Mat6, Vec3, Vec6};

/// What a loaded chain needs besides its kinematics.
pub struct LoadedChain<'a> {
    pub chain: &'a Chain,
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
    /// Sensitivities of the passive and virtual coordinates to the end displacement (eq 46).
    pub k_cq: DMatrix<f64>,
    pub k_ctheta: DMatrix<f64>,
    /// The chain is stable with its end held: the energy's Hessian is positive definite on the motions
    /// that keep the end fixed (paper 000 eq 14, reduced form).
    pub stable: bool,
    pub iterations: usize,
    /// End point, base frame.
    pub end: Vec3,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EquilibriumFailure {
    NotConverged { iterations: usize, residual: f64 },
    Singular,
}

pub const MAX_ITERATIONS: usize = 40;

/// Buffers reused between solves.
#[derive(Clone, Debug, Default)]
pub struct EquilibriumWorkspace {
    jac: ChainJacobians,
    generalised: Vec<f64>,
}

/// Tolerance on the end's pose error (times the length scale) and on the Newton step (rad or mm).
const POSE_TOLERANCE: f64 = 1e-10;
const STEP_TOLERANCE: f64 = 1e-11;
/// Largest change of a coordinate in one Newton step (rad or mm): a damped step, not a line search.
const MAX_STEP: f64 = 0.2;

impl LoadedChain<'_> {
    fn sizes(&self) -> (usize, usize) {
        (self.chain.n_passive, self.chain.n_virtual)
    }

    /// Builds the Newton matrix of eq (45) at the current evaluation, and the residuals.
    /// Unknown order: (q, theta, F); equation order: (kinematics, q-statics, theta-statics).
    fn assemble(
        &self,
        coords: &Coordinates,
        wrench: &Vec6,
        target: &Frame,
        ws: &mut EquilibriumWorkspace,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let (n, m) = self.sizes();
        let size = n + m + 6;
        let jac = &ws.jac;
        let mut a = DMatrix::zeros(size, size);
        let mut rhs = DVector::zeros(size);
        let e = jac.end.error_to(target);
        for r in 0..6 {
            rhs[r] = e[r];
            for (k, c) in jac.passive.iter().enumerate() {
                a[(r, k)] = c[r];
                a[(6 + k, n + m + r)] = c[r];
            }
            for (k, c) in jac.virtual_.iter().enumerate() {
                a[(r, n + k)] = c[r];
                a[(6 + n + k, n + m + r)] = c[r];
            }
        }
        let mut h = DMatrix::zeros(n + m, n + m);
        jac.add_load_hessian(wrench, &self.gravity, n, &mut h);
        a.view_mut((6, 0), (n + m, n + m)).copy_from(&h);
        ws.generalised.clear();
        ws.generalised.resize(n + m, 0.0);
        jac.add_generalised_forces(wrench, &self.gravity, n, &mut ws.generalised);
        for (k, g) in ws.generalised.iter().enumerate() {
            rhs[6 + k] = -g;
        }
        for s in self.springs {
            for i in 0..s.dim {
                let mut reaction = 0.0;
                for j in 0..s.dim {
                    let col = n + s.first + j;
                    a[(6 + n + s.first + i, col)] -= s.stiffness[(i, j)];
                    reaction += s.stiffness[(i, j)] * (coords.virtual_[s.first + j] - self.preload[s.first + j]);
                }
                rhs[6 + n + s.first + i] += reaction;
            }
        }
        (a, rhs)
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
        let (n, m) = self.sizes();
        let mut converged = false;
        for iteration in 0..MAX_ITERATIONS {
            self.chain.evaluate(coords, &mut ws.jac);
            ws.jac.fill_virtual();
            let (a, rhs) = self.assemble(coords, wrench, target, ws);
            let lu = a.clone().lu();
            if converged {
                return self.answer(&a, lu, wrench, iteration, ws.jac.end.pos).ok_or(EquilibriumFailure::Singular);
            }
            let Some(step) = lu.solve(&rhs) else {
                return Err(EquilibriumFailure::Singular);
            };
            let largest = step.rows(0, n + m).amax();
            let damping = if largest > MAX_STEP { MAX_STEP / largest } else { 1.0 };
            for k in 0..n {
                coords.passive[k] += damping * step[k];
            }
            for k in 0..m {
                coords.virtual_[k] += damping * step[n + k];
            }
            for r in 0..6 {
                wrench[r] += damping * step[n + m + r];
            }
            let pose_error = {
                let e = ws.jac.end.error_to(target);
                (e.fixed_rows::<3>(0).norm_squared() + (e.fixed_rows::<3>(3) * self.length_scale).norm_squared()).sqrt()
            };
            if damping == 1.0 && largest <= STEP_TOLERANCE && pose_error <= POSE_TOLERANCE * self.length_scale {
                converged = true;
            }
        }
        let e = ws.jac.end.error_to(target);
        Err(EquilibriumFailure::NotConverged { iterations: MAX_ITERATIONS, residual: e.norm() })
    }

    /// The tangent stiffness and sensitivities from the factorised matrix of eq (45) at the equilibrium.
    fn answer(
        &self,
        a: &DMatrix<f64>,
        lu: nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
        wrench: &Vec6,
        iterations: usize,
        end: Vec3,
    ) -> Option<LoadedAnswer> {
        let (n, m) = self.sizes();
        let size = n + m + 6;
        let mut unit = DMatrix::zeros(size, 6);
        for r in 0..6 {
            unit[(r, r)] = 1.0;
        }
        let x = lu.solve(&unit)?;
        if !x.iter().all(|v| v.is_finite()) {
            return None;
        }
        let stiffness = Mat6::from_fn(|r, c| x[(n + m + r, c)]);
        Some(LoadedAnswer {
            wrench: *wrench,
            stiffness,
            k_cq: x.view((0, 0), (n, 6)).into_owned(),
            k_ctheta: x.view((n, 0), (m, 6)).into_owned(),
            stable: self.stable(a),
            iterations,
            end,
        })
    }

    /// Stability with the end held: the Hessian of the energy (minus the load block of eq 45, spring
    /// stiffness included) positive definite on the null space of the constraint Jacobian [J_q J_theta].
    fn stable(&self, a: &DMatrix<f64>) -> bool {
        let (n, m) = self.sizes();
        let k = n + m;
        let j = a.view((0, 0), (6, k)).into_owned();
        let hess = -(a.view((6, 0), (k, k)).into_owned());
        let hess = (&hess + hess.transpose()) * 0.5;
        let svd = j.svd(false, true);
        let Some(vt) = svd.v_t else { return false };
        let smax = svd.singular_values.max();
        let mut projector = DMatrix::<f64>::identity(k, k);
        for (i, sv) in svd.singular_values.iter().enumerate() {
            if *sv > 1e-10 * smax {
                let v = vt.row(i).transpose();
                projector -= &v * v.transpose();
            }
        }
        let eig = projector.symmetric_eigen();
        let z_cols: Vec<DVector<f64>> =
            (0..k).filter(|&i| eig.eigenvalues[i] > 0.5).map(|i| eig.eigenvectors.column(i).into_owned()).collect();
        if z_cols.is_empty() {
            return true;
        }
        let z = DMatrix::from_columns(&z_cols);
        let reduced = z.transpose() * hess * &z;
        let scale = reduced.amax().max(f64::MIN_POSITIVE);
        reduced.symmetric_eigen().eigenvalues.iter().all(|ev| *ev > -1e-9 * scale)
    }
}

//! A serial arm answered in its own coordinates. An arm (one VJM chain with no passive joint, its end the
//! reference point: a URDF arm) has no leg stiffness to sum: its compliance is Salisbury's
//! C = J_e K_e^-1 J_e^T over its elastic joints (paper 001 eq 9 with no passive joint), which is singular,
//! honestly, where fewer than six springs leave directions the tip cannot move along (rigid directions,
//! never free ones), and its loaded equilibrium is K_e (theta - theta0) = J_e^T w + tau_g(theta) on the
//! elastic coordinates alone (paper 000 eq 31 with the end free), solved by Newton's method with the exact
//! load Hessian H (`ChainJacobians::add_load_hessian`), whose tangent compliance is J_e (K_e - H)^-1 J_e^T.

use nalgebra::DMatrix;

use super::leg::{Leg, LegFailure};
use super::loaded::DeflectionFailure;
use super::manipulator::{Manipulator, ManipulatorState, PoseFailure};
use super::vjm_leg::VjmLeg;
use crate::kinematics::chain::{ChainJacobians, Coordinates};
use crate::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use crate::linalg::all_finite;
use crate::vjm::stiffness::spring_compliance_at_end;

/// A serial arm's answer at one configuration.
#[derive(Clone, Copy, Debug)]
pub struct ArmAnswer {
    /// Where the reference frame is (at the loaded equilibrium, for a loaded answer).
    pub pose: Frame,
    /// Its displacement from the commanded pose (mm, base-frame rotation vector; zero unloaded).
    pub displacement: Vec6,
    /// The compliance at the reference point, base frame: C = J_e K_e^-1 J_e^T, or the loaded tangent
    /// J_e (K_e - H)^-1 J_e^T (mm/N, mm/(N mm), rad/(N mm)).
    pub compliance: Mat6,
    /// The equilibrium is stable: the energy's Hessian K_e - H on the elastic coordinates (its symmetric
    /// part) is positive definite (always, unloaded).
    pub stable: bool,
    /// Newton iterations (0 unloaded).
    pub iterations: usize,
}

/// Largest Newton iterations of one load step.
const MAX_NEWTON: usize = 50;
/// A step of the elastic coordinates below this (rad, or a length over the arm's length scale) ends
/// Newton's method: the matrix it was solved with, then within that of the equilibrium's, gives the tangent.
const NEWTON_TOLERANCE: f64 = 1e-13;
/// The smallest share of the load a continuation step may take before the solve gives up.
const SMALLEST_LOAD_STEP: f64 = 1.0 / 4096.0;

impl Manipulator {
    /// The chain of a serial arm answered in its own coordinates (`serial.rs`): one VJM leg with a joint
    /// space, no passive joint and its end at the reference point; None for any other manipulator.
    pub(super) fn serial_arm(&self) -> Option<&VjmLeg> {
        match (&self.joint_space, self.legs.as_slice()) {
            (Some(_), [Leg::Vjm(leg)]) if leg.chain.n_passive == 0 && leg.attachment == Frame::IDENTITY => Some(leg),
            _ => None,
        }
    }

    /// True where this is a serial arm answered in its own coordinates (C = J_e K_e^-1 J_e^T).
    pub fn is_serial_arm(&self) -> bool {
        self.serial_arm().is_some()
    }

    /// A serial arm's unloaded compliance at the commanded pose `platform` (placed by inverse kinematics,
    /// or at the joint coordinates a state was seeded with). None where this is no serial arm.
    pub fn arm_unloaded(
        &self,
        platform: &Frame,
        state: &mut ManipulatorState,
    ) -> Option<Result<ArmAnswer, PoseFailure>> {
        let leg = self.serial_arm()?;
        if let Err(e) = self.place(platform, state) {
            return Some(Err(e));
        }
        let s = &mut state.legs[0];
        if !springs_positive(leg, &s.coords) {
            return Some(Err(PoseFailure { leg: 0, failure: LegFailure::SingularChain }));
        }
        let (jac, coords) = leg.evaluated(s);
        let columns: Vec<Vec6> = jac.virtual_.iter().map(|c| shifted(c, &(platform.pos - jac.end.pos))).collect();
        let compliance = spring_compliance_at_end(&columns, &leg.springs, coords);
        if !all_finite(compliance.as_slice()) {
            return Some(Err(PoseFailure { leg: 0, failure: LegFailure::NotFinite }));
        }
        Some(Ok(ArmAnswer { pose: *platform, displacement: Vec6::zeros(), compliance, stable: true, iterations: 0 }))
    }

    /// A serial arm's loaded equilibrium under `wrench` (N, N mm at the reference point, fixed in the base
    /// frame) with its links' and payload's weight, the arm placed for `commanded` before: Newton's method on
    /// the elastic coordinates from their rest, the load cut into steps where a direct solve fails. None where
    /// this is no serial arm.
    pub fn arm_deflect(
        &self,
        commanded: &Frame,
        wrench: &Vec6,
        state: &mut ManipulatorState,
    ) -> Option<Result<ArmAnswer, DeflectionFailure>> {
        let leg = self.serial_arm()?;
        let s = &mut state.legs[0];
        if !springs_positive(leg, &s.coords) {
            return Some(Err(DeflectionFailure::Leg(PoseFailure { leg: 0, failure: LegFailure::SingularChain })));
        }
        let mut coords = s.coords.clone();
        coords.virtual_.iter_mut().for_each(|t| *t = 0.0);
        let mut solver = ArmSolver { m: self, leg, jac: &mut s.jac, wrench: *wrench };
        Some(solver.continuation(commanded, &mut coords))
    }
}

/// Every spring whose stiffness depends on the configuration (a formula of its joint's coordinate) has a
/// positive one there: where it has none the arm has no stiffness at that configuration (`singular_leg`,
/// docs/GUIDE.md).
fn springs_positive(leg: &VjmLeg, coords: &Coordinates) -> bool {
    leg.springs.iter().filter(|g| g.varies()).all(|g| {
        let k = g.at(coords).0;
        (0..g.dim).all(|i| k[(i, i)].is_finite() && k[(i, i)] > 0.0)
    })
}

/// A twist moved to the point `arm` away from where it was seen: v + w x arm.
fn shifted(c: &Vec6, arm: &Vec3) -> Vec6 {
    let (v, w) = (c.fixed_rows::<3>(0).into_owned(), c.fixed_rows::<3>(3).into_owned());
    let v = v + w.cross(arm);
    Vec6::new(v.x, v.y, v.z, w.x, w.y, w.z)
}

/// One loaded solve of a serial arm.
struct ArmSolver<'a> {
    m: &'a Manipulator,
    leg: &'a VjmLeg,
    jac: &'a mut ChainJacobians,
    wrench: Vec6,
}

/// What one evaluation of the arm's statics gives: the residual g - K (theta - theta0) and the Newton
/// matrix K - H.
struct Statics {
    residual: Vec<f64>,
    matrix: DMatrix<f64>,
}

impl ArmSolver<'_> {
    /// The statics at `coords` under the share `load` of every load (the wrench, the links' and the
    /// payload's weight), the chain evaluated there into `jac`.
    fn statics(&mut self, coords: &Coordinates, load: f64) -> Statics {
        let n = coords.virtual_.len();
        self.leg.chain.evaluate(coords, self.jac);
        self.jac.fill_virtual();
        let gravity = self.leg.gravity * load;
        let wrench = self.wrench * load;
        let mut residual = vec![0.0; n];
        self.jac.add_generalised_forces(&wrench, &gravity, 0, &mut residual);
        let mut h = DMatrix::zeros(n, n);
        self.jac.add_load_hessian(&wrench, &gravity, 0, &mut h);
        if let Some(p) = self.m.payload {
            let end = self.jac.end;
            let (point, force) = (end.pos + end.rot * p.centre, self.m.weight_gravity() * (p.mass_kg * load));
            self.jac.add_point_force(&point, &force, 0, &mut residual);
            self.jac.add_point_force_hessian(&point, &force, 0, &mut h);
        }
        let mut matrix = -h;
        for g in &self.leg.springs {
            let k = g.stiffness_at(coords);
            let rest = &self.leg.preload[g.first..g.first + g.dim];
            let deflection: Vec<f64> =
                coords.virtual_[g.first..g.first + g.dim].iter().zip(rest).map(|(t, r)| t - r).collect();
            for i in 0..g.dim {
                for (j, d) in deflection.iter().enumerate() {
                    matrix[(g.first + i, g.first + j)] += k[(i, j)];
                    residual[g.first + i] -= k[(i, j)] * d;
                }
            }
        }
        Statics { residual, matrix }
    }

    /// Newton's method for the share `load` from `coords` (left at the solution): the iterations and the
    /// last Newton matrix (within `NEWTON_TOLERANCE` of the equilibrium's).
    fn newton(&mut self, coords: &mut Coordinates, load: f64) -> Result<(usize, DMatrix<f64>), DeflectionFailure> {
        let lengths = self.leg.chain.length_coordinates().to_vec();
        let scale = self.leg.length_scale;
        for iteration in 1..=MAX_NEWTON {
            let Statics { residual, matrix } = self.statics(coords, load);
            let step = matrix
                .clone()
                .lu()
                .solve(&nalgebra::DVector::from_vec(residual))
                .filter(|s| all_finite(s.as_slice()))
                .ok_or(DeflectionFailure::SingularStiffness { load_fraction: load })?;
            let size = step
                .iter()
                .zip(&lengths)
                .map(|(d, is_length)| if *is_length { d.abs() / scale } else { d.abs() })
                .fold(0.0, f64::max);
            if size > 1.0 {
                // A step past a radian (or the arm's length) has left the region the linearisation describes.
                return Err(DeflectionFailure::NotConverged { load_fraction: load });
            }
            for (t, d) in coords.virtual_.iter_mut().zip(step.iter()) {
                *t += d;
            }
            if size <= NEWTON_TOLERANCE {
                return Ok((iteration, matrix));
            }
        }
        Err(DeflectionFailure::NotConverged { load_fraction: load })
    }

    /// The equilibrium under the whole load, by load steps where a direct solve fails, and its answer.
    fn continuation(&mut self, commanded: &Frame, coords: &mut Coordinates) -> Result<ArmAnswer, DeflectionFailure> {
        let (mut done, mut step, mut iterations) = (0.0f64, 1.0f64, 0);
        let mut last = None;
        while done < 1.0 {
            let target = (done + step).min(1.0);
            let saved = coords.virtual_.clone();
            match self.newton(coords, target) {
                Ok((its, matrix)) => {
                    iterations += its;
                    last = Some(matrix);
                    done = target;
                    step = (step * 2.0).min(1.0);
                }
                Err(e) => {
                    coords.virtual_.copy_from_slice(&saved);
                    step /= 4.0;
                    if step < SMALLEST_LOAD_STEP {
                        return Err(match e {
                            DeflectionFailure::SingularStiffness { .. } => {
                                DeflectionFailure::SingularStiffness { load_fraction: done }
                            }
                            _ => DeflectionFailure::NotConverged { load_fraction: done },
                        });
                    }
                }
            }
        }
        let matrix = last.expect("a finished continuation solved its last step");
        // The pose and the Jacobian at the equilibrium (the last step moved it by round-off).
        self.leg.chain.evaluate(coords, self.jac);
        self.jac.fill_virtual();
        let pose = self.jac.end;
        let inverse =
            matrix.clone().lu().try_inverse().ok_or(DeflectionFailure::SingularStiffness { load_fraction: 1.0 })?;
        let n = coords.virtual_.len();
        let j = DMatrix::from_fn(6, n, |r, c| self.jac.virtual_[c][r]);
        let c = &j * inverse * j.transpose();
        let compliance = Mat6::from_fn(|r, k| c[(r, k)]);
        if !all_finite(compliance.as_slice()) || !all_finite(pose.pos.as_slice()) {
            return Err(DeflectionFailure::Leg(PoseFailure { leg: 0, failure: LegFailure::NotFinite }));
        }
        Ok(ArmAnswer {
            pose,
            displacement: commanded.error_to(&pose),
            compliance,
            stable: energy_minimum(&matrix),
            iterations,
        })
    }
}

/// The symmetric part of the energy's Hessian `m` is positive definite (Cholesky, after a diagonal
/// equilibration, which changes no eigenvalue's sign).
fn energy_minimum(m: &DMatrix<f64>) -> bool {
    let n = m.nrows();
    let d: Vec<f64> = (0..n).map(|i| m[(i, i)]).collect();
    if d.iter().any(|v| v.is_nan() || *v <= 0.0) {
        return false;
    }
    let s = DMatrix::from_fn(n, n, |i, j| 0.5 * (m[(i, j)] + m[(j, i)]) / (d[i] * d[j]).sqrt());
    s.cholesky().is_some()
}

//! From the manipulator's stiffness to what a designer reads: compliance where K is invertible and well
//! conditioned, its rank and free directions where it is not, its condition figure, and the principal
//! compliances.
//!
//! Every decision (rank, definiteness, conditioning) is taken on the *equilibrated* stiffness: rotations
//! weighted by the model's length scale (every entry in N/mm), then scaled symmetrically to a unit diagonal.
//! A diagonal congruence changes neither the rank nor the signs of the eigenvalues (Sylvester's law of
//! inertia), but it makes the decisions independent of units and of springs written as "rigid" with huge
//! numbers (a link with E = 1e30 no longer hides the 2e4 N/mm of the others under a relative tolerance).
//! A diagonal entry is not scaled up where it is round-off: where the legs' contributions cancelled to
//! below `CANCELLATION_TOLERANCE` of their own size (`magnitude`, the entrywise sum of |K_i|), as the
//! free rotations of a singular Stewart-Gough platform do.

use nalgebra::{SymmetricEigen, SVD};

use crate::kinematics::frame::{weigh_rotations, Mat3, Mat6, Vec6};

/// Relative singular value of the equilibrated stiffness below which a direction is free: a few hundred
/// times round-off.
pub const RANK_TOLERANCE: f64 = 1e-13;

/// A diagonal entry of the sum over legs smaller than this times the sum of its terms' sizes is round-off
/// (a few thousand times the unit round-off: the legs' own stiffnesses carry errors of that order).
pub const CANCELLATION_TOLERANCE: f64 = 1e-12;

/// Condition number of the equilibrated stiffness beyond which a point is `ill_conditioned`. The
/// compliance's relative error is about 1e-10 times the condition number (the model is evaluated to that
/// accuracy: inverse kinematics stops at 1e-9 of the length scale): the VJM and MSA descriptions of the
/// 3-PUU differ by 7e-7 at condition 5.6e4, 4e-5 at 2.8e5 and 1e-3 at 2.8e6 near the reach boundary on x.
/// Beyond 1e6 fewer than four digits of C can be trusted, so none are written.
pub const CONDITION_LIMIT: f64 = 1e6;

/// Iteration cap for the 6x6 SVD and symmetric eigen-solvers (nalgebra iterates without one by default;
/// these converge in a few dozen sweeps on finite input).
const MAX_SWEEPS: usize = 200;

#[derive(Clone, Debug)]
pub enum Outcome {
    /// Full rank, condition within `CONDITION_LIMIT`: C = K^-1 (LU with pivoting; symmetrised where K is).
    Regular { compliance: Mat6 },
    /// Full rank but beyond `CONDITION_LIMIT`: C would carry too few correct digits to be written.
    IllConditioned,
    /// Rank below 6; `free` holds unit twists (translation mm, rotation rad, scaled alike) K does not resist.
    Singular { rank: usize, free: Vec<Vec6> },
    /// K has non-finite entries (an overflow upstream).
    NotFinite,
}

#[derive(Clone, Debug)]
pub struct Analysis {
    pub outcome: Outcome,
    /// Condition number (2-norm) of the equilibrated stiffness; infinite where singular, NaN where K is not
    /// finite.
    pub condition: f64,
    /// The symmetric part of K is positive definite (decided on the equilibrated matrix).
    pub positive_definite: bool,
}

impl Analysis {
    /// The compliance, where the outcome is regular.
    pub fn compliance(&self) -> Option<&Mat6> {
        match &self.outcome {
            Outcome::Regular { compliance } => Some(compliance),
            _ => None,
        }
    }
}

/// `D K D` with `D = diag(1, 1, 1, 1/l, 1/l, 1/l)`: every entry in N/mm, so that eigenvalues compare.
pub fn scaled(k: &Mat6, length_scale: f64) -> Mat6 {
    let d = weigh_rotations(&Vec6::repeat(1.0), 1.0 / length_scale);
    Mat6::from_fn(|i, j| k[(i, j)] * d[i] * d[j])
}

/// The diagonal `E` that brings a length-scaled stiffness to a unit diagonal (`E Ks E`). A diagonal entry
/// that is round-off (below `CANCELLATION_TOLERANCE` of its terms' size `ms`) or not positive is scaled as
/// the largest diagonal is, so that noise is never magnified into a stiffness.
fn equilibration(ks: &Mat6, ms: &Mat6) -> Vec6 {
    let largest = (0..6).map(|i| ks[(i, i)]).fold(0.0f64, f64::max);
    let fallback = if largest > 0.0 { 1.0 / largest.sqrt() } else { 1.0 };
    Vec6::from_fn(|i, _| {
        let d = ks[(i, i)];
        if d > CANCELLATION_TOLERANCE * ms[(i, i)] && d > 0.0 {
            1.0 / d.sqrt()
        } else {
            fallback
        }
    })
}

/// The length-scaled stiffness brought to a unit diagonal, and the scaling used.
fn equilibrated(k: &Mat6, magnitude: &Mat6, length_scale: f64) -> (Mat6, Vec6) {
    let ks = scaled(k, length_scale);
    let e = equilibration(&ks, &scaled(magnitude, length_scale));
    (Mat6::from_fn(|i, j| ks[(i, j)] * e[i] * e[j]), e)
}

/// Eigenvalues (ascending) of a symmetric 3x3 matrix by nalgebra's iterative solver with an iteration
/// cap: accurate at repeated roots, where the closed-form trigonometric method loses half its digits. None
/// on non-finite input.
pub fn symmetric_eigenvalues3(m: &Mat3) -> Option<[f64; 3]> {
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let e = SymmetricEigen::try_new(*m, f64::EPSILON, MAX_SWEEPS)?.eigenvalues;
    let mut v = [e[0], e[1], e[2]];
    v.sort_by(f64::total_cmp);
    Some(v)
}

/// Smallest eigenvalue of the symmetric part of the equilibrated stiffness, relative to the largest:
/// positive exactly where the stiffness is positive definite (the stability test of loaded mode).
fn definiteness(ke: &Mat6) -> Option<f64> {
    let e = SymmetricEigen::try_new((ke + ke.transpose()) * 0.5, f64::EPSILON, MAX_SWEEPS)?.eigenvalues;
    let largest = e.abs().max();
    Some(if largest > 0.0 { e.min() / largest } else { 0.0 })
}

/// The symmetric part of `k` is positive definite, decided on the equilibrated matrix with the rank
/// tolerance. `magnitude`: the entrywise sum of the legs' |K_i| (`Aggregate::magnitude`).
pub fn positive_definite(k: &Mat6, magnitude: &Mat6, length_scale: f64) -> bool {
    definiteness(&equilibrated(k, magnitude, length_scale).0).is_some_and(|d| d > RANK_TOLERANCE)
}

/// Rank, conditioning, definiteness and (where meaningful) the compliance of a 6x6 stiffness. `magnitude`:
/// the entrywise sum of the legs' |K_i| (`Aggregate::magnitude`; `k.abs()` where K is not a sum).
/// `symmetric`: K is symmetric by theory (unloaded), so C is symmetrised; otherwise (loaded tangent
/// stiffness) C is the full inverse.
pub fn analyse(k: &Mat6, magnitude: &Mat6, length_scale: f64, symmetric: bool) -> Analysis {
    if !k.iter().all(|v| v.is_finite()) {
        return Analysis { outcome: Outcome::NotFinite, condition: f64::NAN, positive_definite: false };
    }
    let (ke, e) = equilibrated(k, magnitude, length_scale);
    let positive_definite = definiteness(&ke).is_some_and(|d| d > RANK_TOLERANCE);
    let Some(svd) = SVD::try_new(ke, false, true, f64::EPSILON, MAX_SWEEPS) else {
        return Analysis { outcome: Outcome::NotFinite, condition: f64::NAN, positive_definite: false };
    };
    let sigma_max = svd.singular_values.max();
    let sigma_min = svd.singular_values.min();
    let condition = if sigma_min > 0.0 { sigma_max / sigma_min } else { f64::INFINITY };
    let rank = svd.singular_values.iter().filter(|s| **s > RANK_TOLERANCE * sigma_max).count();
    if rank < 6 {
        let v_t = svd.v_t.expect("requested");
        let free = free_directions(&v_t, &svd.singular_values, sigma_max, &e, length_scale);
        return Analysis { outcome: Outcome::Singular { rank, free }, condition, positive_definite };
    }
    if condition > CONDITION_LIMIT {
        return Analysis { outcome: Outcome::IllConditioned, condition, positive_definite };
    }
    let Some(inv) = ke.lu().try_inverse() else {
        return Analysis { outcome: Outcome::IllConditioned, condition, positive_definite };
    };
    // C = K^-1 = D E (E D K D E)^-1 E D
    let c = scaled(&Mat6::from_fn(|i, j| inv[(i, j)] * e[i] * e[j]), length_scale);
    let compliance = if symmetric { (c + c.transpose()) * 0.5 } else { c };
    Analysis { outcome: Outcome::Regular { compliance }, condition, positive_definite }
}

/// The null space of the equilibrated stiffness mapped back to twists: orthonormal in the length-scaled
/// metric, then each written in mm and rad and normalised.
fn free_directions(v_t: &Mat6, sigma: &Vec6, sigma_max: f64, e: &Vec6, length_scale: f64) -> Vec<Vec6> {
    let mut basis: Vec<Vec6> = Vec::new();
    for (i, s) in sigma.iter().enumerate() {
        if *s > RANK_TOLERANCE * sigma_max {
            continue;
        }
        // A null vector y of E Ks E gives E y in the null space of Ks.
        let mut u: Vec6 = v_t.row(i).transpose().component_mul(e);
        for b in &basis {
            u -= b * b.dot(&u);
        }
        if u.norm() > 0.0 {
            basis.push(u.normalize());
        }
    }
    basis.iter().map(|u| weigh_rotations(u, 1.0 / length_scale).normalize()).collect()
}

/// Largest and smallest translational compliance (eigenvalues of the 3x3 translational block of the
/// symmetric part of C, mm/N) and largest rotational compliance (of its rotational block, rad/(N mm)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrincipalCompliance {
    pub translation_max: f64,
    pub translation_min: f64,
    pub rotation_max: f64,
}

/// Principal compliances of the symmetric part of C: the energy a wrench stores, w^T C w, sees only that
/// part, and it is positive definite wherever the symmetric part of K is (so these are positive under `ok`).
pub fn principal(c: &Mat6) -> Option<PrincipalCompliance> {
    let s = (c + c.transpose()) * 0.5;
    let t: Mat3 = s.fixed_view::<3, 3>(0, 0).into();
    let r: Mat3 = s.fixed_view::<3, 3>(3, 3).into();
    let et = symmetric_eigenvalues3(&t)?;
    let er = symmetric_eigenvalues3(&r)?;
    Some(PrincipalCompliance { translation_max: et[2], translation_min: et[0], rotation_max: er[2] })
}

/// The spectrum of a tangent stiffness' symmetric part, as a force-deflection curve reports it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spectrum {
    /// Smallest eigenvalue of the translational 3x3 block (N/mm).
    pub translational_min: f64,
    /// Smallest eigenvalue of the rotational 3x3 block (N mm/rad).
    pub rotational_min: f64,
    /// Smallest eigenvalue of the whole matrix with rotations weighted by the length scale (N/mm): its sign
    /// is the stability test.
    pub scaled_min: f64,
    /// The eigenvector of `scaled_min` (the critical mode), unit twist in mm and rad, sign fixed so that
    /// its largest component is positive.
    pub critical_mode: Vec6,
}

pub fn spectrum(k: &Mat6, length_scale: f64) -> Option<Spectrum> {
    let s = (k + k.transpose()) * 0.5;
    let t: Mat3 = s.fixed_view::<3, 3>(0, 0).into();
    let r: Mat3 = s.fixed_view::<3, 3>(3, 3).into();
    let ks = scaled(&s, length_scale);
    if !ks.iter().all(|v| v.is_finite()) {
        return None;
    }
    let e = SymmetricEigen::try_new(ks, f64::EPSILON, MAX_SWEEPS)?;
    let i = e.eigenvalues.imin();
    let mut mode = weigh_rotations(&e.eigenvectors.column(i).into(), 1.0 / length_scale).normalize();
    if mode.iter().fold(0.0f64, |a, &b| if b.abs() > a.abs() { b } else { a }) < 0.0 {
        mode = -mode;
    }
    Some(Spectrum {
        translational_min: symmetric_eigenvalues3(&t)?[0],
        rotational_min: symmetric_eigenvalues3(&r)?[0],
        scaled_min: e.eigenvalues[i],
        critical_mode: mode,
    })
}

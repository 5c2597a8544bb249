//! From the manipulator's stiffness to what a designer reads: compliance where K is invertible, its rank
//! and free directions where it is not, and the principal compliances.

use crate::kinematics::frame::{symmetric_eigenvalues3, weigh_rotations, Mat3, Mat6, Vec6};

/// Relative eigenvalue (or Cholesky pivot) of the length-scaled stiffness below which a direction is free:
/// a few hundred times round-off, so that models with springs 1e12 times stiffer than others (a common way
/// to write "rigid") stay regular.
pub const RANK_TOLERANCE: f64 = 1e-13;

#[derive(Clone, Debug)]
pub enum Analysis {
    Regular {
        compliance: Mat6,
    },
    /// Rank below 6; `free` holds unit twists (translation mm, rotation rad, scaled alike) K does not resist.
    Singular {
        rank: usize,
        free: Vec<Vec6>,
    },
}

/// `D K D` with `D = diag(1, 1, 1, 1/l, 1/l, 1/l)`: every entry in N/mm, so that eigenvalues compare.
pub fn scaled(k: &Mat6, length_scale: f64) -> Mat6 {
    let d = weigh_rotations(&Vec6::repeat(1.0), 1.0 / length_scale);
    Mat6::from_fn(|i, j| k[(i, j)] * d[i] * d[j])
}

pub fn analyse(k: &Mat6, length_scale: f64) -> Analysis {
    let ks = scaled(k, length_scale);
    let largest_diag = (0..6).map(|i| ks[(i, i)]).fold(0.0, f64::max);
    if largest_diag > 0.0 {
        if let Some(ch) = ks.cholesky() {
            let l = ch.l_dirty();
            let smallest_pivot = (0..6).map(|i| l[(i, i)] * l[(i, i)]).fold(f64::INFINITY, f64::min);
            if smallest_pivot > RANK_TOLERANCE * largest_diag {
                let inv_scaled = ch.inverse();
                // C = K^-1 = D (D K D)^-1 D
                let c = scaled(&inv_scaled, length_scale);
                return Analysis::Regular { compliance: (c + c.transpose()) * 0.5 };
            }
        }
    }
    let eig = ks.symmetric_eigen();
    let largest = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let mut rank = 0;
    let mut free = Vec::new();
    for i in 0..6 {
        if largest > 0.0 && eig.eigenvalues[i] > RANK_TOLERANCE * largest {
            rank += 1;
        } else {
            let mut t: Vec6 = eig.eigenvectors.column(i).into();
            for r in 3..6 {
                t[r] /= length_scale;
            }
            free.push(t.normalize());
        }
    }
    Analysis::Singular { rank, free }
}

/// Largest and smallest translational compliance (eigenvalues of the 3x3 translational block of C, mm/N)
/// and largest rotational compliance (of the rotational block, rad/(N mm)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrincipalCompliance {
    pub translation_max: f64,
    pub translation_min: f64,
    pub rotation_max: f64,
}

pub fn principal(c: &Mat6) -> PrincipalCompliance {
    let t: Mat3 = c.fixed_view::<3, 3>(0, 0).into();
    let r: Mat3 = c.fixed_view::<3, 3>(3, 3).into();
    let et = symmetric_eigenvalues3(&t);
    let er = symmetric_eigenvalues3(&r);
    PrincipalCompliance { translation_max: et[2], translation_min: et[0], rotation_max: er[2] }
}

//! Analytic Jacobians (joint twists, paper 001 eq 5) against central differences of the forward kinematics,
//! at random configurations of random chains, every kind of coordinate included.

use crate::common;
use common::*;
use rand::Rng;
use stiff::kinematics::chain::{ChainJacobians, Coordinates, Role};
use stiff::kinematics::frame::Vec6;

fn finite_difference(chain: &stiff::kinematics::chain::Chain, c: &Coordinates, role: Role, i: usize) -> Vec6 {
    let h = 1e-6;
    let bump = |d: f64| {
        let mut x = c.clone();
        match role {
            Role::Actuated => x.actuated[i] += d,
            Role::Passive => x.passive[i] += d,
            Role::Virtual => x.virtual_[i] += d,
        }
        chain.end_frame(&x)
    };
    // The twist carrying the end frame from -h to +h, over 2h: translation and base-frame rotation vector.
    bump(-h).error_to(&bump(h)) / (2.0 * h)
}

#[test]
fn analytic_jacobians_match_central_differences_on_random_chains() {
    let mut r = rng(7);
    for trial in 0..40 {
        let joints = r.random_range(3..9);
        let b = random_chain(&mut r, joints, false);
        let chain = b.chain();
        let c = random_coords(&mut r, &chain, 0.8);
        let mut j = ChainJacobians::default();
        chain.evaluate(&c, &mut j);
        j.fill_virtual();
        for (role, cols) in [(Role::Actuated, &j.actuated), (Role::Passive, &j.passive), (Role::Virtual, &j.virtual_)] {
            for (i, col) in cols.iter().enumerate() {
                let fd = finite_difference(&chain, &c, role, i);
                let err = (col - fd).norm() / col.norm().max(1.0);
                assert!(err < 1e-7, "trial {trial}, {role:?} {i}: analytic {col:?} vs differences {fd:?}");
            }
        }
        assert!((j.end.pos - chain.end_frame(&c).pos).norm() < 1e-12);
    }
}

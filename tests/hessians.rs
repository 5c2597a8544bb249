//! Second derivatives of the kinematics (paper 000 eq 41-44): the load Hessian against central
//! differences of the generalised forces J^T w + sum_j J_j^T G_j, on random chains with masses.

use crate::common;
use common::*;
use rand::Rng;
use stiff::kinematics::chain::{ChainJacobians, Coordinates};
use stiff::kinematics::frame::{Vec3, Vec6};

fn forces(chain: &stiff::kinematics::chain::Chain, c: &Coordinates, w: &Vec6, g: &Vec3) -> Vec<f64> {
    let mut j = ChainJacobians::default();
    chain.evaluate(c, &mut j);
    let mut out = vec![0.0; chain.n_passive + chain.n_virtual];
    j.add_generalised_forces(w, g, chain.n_passive, &mut out);
    out
}

#[test]
fn load_hessian_matches_central_differences_on_random_chains() {
    let mut r = rng(21);
    for trial in 0..30 {
        let joints = r.random_range(2..7);
        let b = random_chain(&mut r, joints, true);
        let chain = b.chain();
        let c = random_coords(&mut r, &chain, 0.7);
        let w = Vec6::from_fn(|i, _| r.random_range(-1.0..1.0) * if i < 3 { 100.0 } else { 1e4 });
        // Every other chain without gravity: the end's wrench alone takes the one-load terms, the weights
        // the sums beyond each joint (`ChainJacobians::add_load_hessian`).
        let g = if trial % 2 == 0 { Vec3::new(0.0, 0.0, -9.81) } else { Vec3::zeros() };
        let n = chain.n_passive + chain.n_virtual;
        let mut j = ChainJacobians::default();
        chain.evaluate(&c, &mut j);
        let mut h = nalgebra::DMatrix::zeros(n, n);
        j.add_load_hessian(&w, &g, chain.n_passive, &mut h);
        let step = 1e-6;
        for col in 0..n {
            let bump = |d: f64| {
                let mut x = c.clone();
                if col < chain.n_passive {
                    x.passive[col] += d;
                } else {
                    x.virtual_[col - chain.n_passive] += d;
                }
                forces(&chain, &x, &w, &g)
            };
            let (plus, minus) = (bump(step), bump(-step));
            for row in 0..n {
                let fd = (plus[row] - minus[row]) / (2.0 * step);
                let scale = h.abs().max().max(1.0);
                assert!(
                    (h[(row, col)] - fd).abs() < 1e-6 * scale,
                    "trial {trial}: H[{row},{col}] = {} vs {fd}",
                    h[(row, col)]
                );
            }
        }
    }
}

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

/// Inverse kinematics reaches its iterates close to the pose on the end frame alone (forward kinematics)
/// and polishes them with chord steps on an earlier factorisation; the evaluation it hands on (kept from
/// the solve, or made where it is asked for) must still be the solution's own, since every stiffness reads
/// it. On random square chains (six actuated and passive joints), from starts 1e-1 to 1e-11 (rad or mm)
/// off a known solution (paths through Newton steps with full trials, pose-only trials and chord steps),
/// for a caller that reads the Jacobians and for one that reads the pose alone (whose solution is not
/// evaluated during the solve), the evaluation handed on is a fresh evaluation at the returned coordinates
/// bit for bit, the pose is reached within 1e-14 of the length scale, and the coordinates are the known
/// solution's.
#[test]
fn inverse_kinematics_keeps_the_evaluation_of_its_solution_whatever_its_path() {
    use stiff::kinematics::chain::JointKind;
    use stiff::kinematics::frame::weigh_rotations;
    use stiff::kinematics::ik::{solve, IkWorkspace, Needs};
    let mut r = rng(48);
    let mut checked = 0;
    for _ in 0..40 {
        let mut b = ChainBuilder::default();
        b.fixed(random_frame(&mut r, 200.0));
        for k in 0..6 {
            let kind = if k % 3 == 0 { JointKind::Prismatic } else { JointKind::Revolute };
            let role = if k == 0 { Role::Actuated } else { Role::Passive };
            b.joint(kind, unit_vector(&mut r), role).fixed(random_frame(&mut r, 150.0));
        }
        b.spring6(random_spring(&mut r)).fixed(random_frame(&mut r, 50.0));
        let chain = b.chain();
        let length = chain.length_scale();
        let solution = random_coords(&mut r, &chain, 0.5);
        let mut at_solution = solution.clone();
        at_solution.virtual_.iter_mut().for_each(|t| *t = 0.0);
        let target = chain.end_frame(&at_solution);
        let mut fresh = ChainJacobians::default();
        chain.evaluate(&at_solution, &mut fresh);
        // Skip configurations near a singularity, where the solution is not locally unique.
        let columns: Vec<Vec6> =
            fresh.actuated.iter().chain(&fresh.passive).map(|c| weigh_rotations(c, length)).collect();
        let j = nalgebra::Matrix6::from_columns(&columns);
        let singular = j.singular_values();
        if singular.min() < 1e-4 * singular.max() {
            continue;
        }
        // From 1e-9 and 1e-11 the start is within the tolerance: its first step is a polishing one (tried on the
        // end frame alone where the pose is all that is needed).
        for (offset, needs) in [1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-9, 1e-11]
            .into_iter()
            .flat_map(|offset| [(offset, Needs::Jacobians), (offset, Needs::Pose)])
        {
            let mut coords = at_solution.clone();
            let direction: Vec<f64> = (0..6).map(|_| r.random_range(-1.0..1.0)).collect();
            for (q, d) in coords.actuated.iter_mut().chain(coords.passive.iter_mut()).zip(&direction) {
                *q += offset * d;
            }
            let mut ws = IkWorkspace::default();
            let iterations = solve(&chain, &target, &mut coords, &mut ws, length, needs).expect("converges");
            let kept = ws.joints_at_solution(&chain, &coords).expect("a solution's evaluation is kept").clone();
            chain.evaluate(&coords, &mut fresh);
            assert_eq!(kept.end, fresh.end, "offset {offset:e}, {needs:?}: the end frame handed on is the solution's");
            assert_eq!(kept.actuated, fresh.actuated, "offset {offset:e}: actuated columns");
            assert_eq!(kept.passive, fresh.passive, "offset {offset:e}: passive columns");
            let miss = weigh_rotations(&fresh.end.error_to(&target), length).norm();
            assert!(miss <= 1e-14 * length, "offset {offset:e}: {miss:e} mm from the pose ({iterations} iterations)");
            let moved = coords
                .actuated
                .iter()
                .chain(&coords.passive)
                .zip(at_solution.actuated.iter().chain(&at_solution.passive))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(moved < 1e-9, "offset {offset:e}: {moved:e} from the known solution");
            checked += 1;
        }
    }
    assert!(checked >= 120, "{checked} solves checked");
}

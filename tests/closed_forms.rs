//! Leg stiffness (paper 001 eq 9) against closed forms, and three routes to it against each other.

use crate::common;
use common::*;
use rand::Rng;
use stiff::kinematics::chain::{ChainJacobians, Coordinates, JointKind, Role};
use stiff::kinematics::frame::{rotation_about, Frame, Mat6, Vec3, Vec6};
use stiff::vjm::stiffness::{
    leg_stiffness, leg_stiffness_bordered, leg_stiffness_by_null_space, leg_stiffness_recursive, passive_range,
    spring_compliance_at_end,
};

/// An actuated prismatic joint with a spring k along x, the other five directions freed by passive joints:
/// the leg resists only along x, with stiffness k.
#[test]
fn single_actuated_prismatic_spring() {
    let k = 20491.0;
    let mut b = ChainBuilder::default();
    b.fixed(Frame::translation(Vec3::new(-300.0, 10.0, 5.0)))
        .joint(JointKind::Prismatic, Vec3::x(), Role::Actuated)
        .elastic(JointKind::Prismatic, Vec3::x(), k)
        .joint(JointKind::Prismatic, Vec3::y(), Role::Passive)
        .joint(JointKind::Prismatic, Vec3::z(), Role::Passive)
        .joint(JointKind::Revolute, Vec3::x(), Role::Passive)
        .joint(JointKind::Revolute, Vec3::y(), Role::Passive)
        .joint(JointKind::Revolute, Vec3::z(), Role::Passive);
    let chain = b.chain();
    let kl = chain_stiffness(&chain, &b.springs, &Coordinates::zeros(&chain), 300.0).unwrap();
    let mut expected = Mat6::zeros();
    expected[(0, 0)] = k;
    assert!((kl - expected).abs().max() < 1e-9 * k, "{kl}");
}

/// A planar two-link chain, elastic revolute joints k1 at the base and k2 at the elbow (links L1 along x,
/// then L2 at angle beta), a pin at the tip and out-of-plane freedoms at the base: the in-plane stiffness
/// is (J C J^T)^-1 with the columns z x (p - o_i), C = diag(1/k1, 1/k2); all else is zero.
#[test]
fn planar_two_link_chain() {
    let (k1, k2, l1, l2, beta) = (4.0e6, 2.5e6, 300.0, 200.0, 0.7f64);
    let mut b = ChainBuilder::default();
    b.joint(JointKind::Prismatic, Vec3::z(), Role::Passive)
        .joint(JointKind::Revolute, Vec3::x(), Role::Passive)
        .joint(JointKind::Revolute, Vec3::y(), Role::Passive)
        .elastic(JointKind::Revolute, Vec3::z(), k1)
        .fixed(Frame::translation(Vec3::new(l1, 0.0, 0.0)))
        .elastic(JointKind::Revolute, Vec3::z(), k2)
        .fixed(Frame::new(rotation_about(&Vec3::z(), beta), Vec3::zeros()))
        .fixed(Frame::translation(Vec3::new(l2, 0.0, 0.0)))
        .joint(JointKind::Revolute, Vec3::z(), Role::Passive);
    let chain = b.chain();
    let kl = chain_stiffness(&chain, &b.springs, &Coordinates::zeros(&chain), 500.0).unwrap();
    let p = nalgebra::Vector2::new(l1 + l2 * beta.cos(), l2 * beta.sin());
    let a = nalgebra::Vector2::new(-p.y, p.x);
    let bcol = nalgebra::Vector2::new(-p.y, p.x - l1);
    let compliance = a * a.transpose() / k1 + bcol * bcol.transpose() / k2;
    let k_plane = compliance.try_inverse().unwrap();
    let mut expected = Mat6::zeros();
    expected.fixed_view_mut::<2, 2>(0, 0).copy_from(&k_plane);
    assert!((kl - expected).abs().max() < 1e-9 * k_plane.abs().max(), "{kl}\nvs\n{expected}");
}

/// A chain with n_q independent passive joints and a full 6-dof spring: the leg's stiffness has rank
/// 6 - n_q, is symmetric and positive semi-definite, and annihilates every passive twist (paper 002
/// remarks 1-4).
#[test]
fn passive_joints_remove_exactly_their_directions() {
    let mut r = rng(11);
    for n_q in 0..=6 {
        for _ in 0..10 {
            let mut b = ChainBuilder::default();
            b.fixed(random_frame(&mut r, 200.0)).spring6(random_spring(&mut r));
            for i in 0..n_q {
                b.fixed(random_frame(&mut r, 150.0));
                // At most two prismatic joints, so that the freedoms are independent in general.
                let kind = if i >= 2 || r.random_bool(0.6) { JointKind::Revolute } else { JointKind::Prismatic };
                b.joint(kind, unit_vector(&mut r), Role::Passive);
            }
            b.fixed(random_frame(&mut r, 100.0));
            let chain = b.chain();
            let c = random_coords(&mut r, &chain, 0.5);
            let l = 300.0;
            let kl = chain_stiffness(&chain, &b.springs, &c, l).unwrap();
            assert!((kl - kl.transpose()).abs().max() <= 1e-12 * kl.abs().max());
            if n_q == 6 {
                assert_eq!(kl, Mat6::zeros());
                continue;
            }
            let e = scaled_eigenvalues(&kl, l);
            let top = e[5];
            let zero = e.iter().filter(|v| v.abs() < 1e-9 * top).count();
            assert_eq!(zero, n_q, "eigenvalues {e:?}");
            assert!(e.iter().all(|v| *v > -1e-9 * top), "not PSD: {e:?}");
            let mut j = ChainJacobians::default();
            chain.evaluate(&c, &mut j);
            for t in &j.passive {
                assert!((kl * t).norm() <= 1e-8 * top * t.norm().max(l));
            }
        }
    }
}

/// Where two passive axes become collinear (a U-joint folded onto the next joint's axis), J_q loses rank
/// and the bordered matrix of eq 9 as printed is singular; with J_q replaced by a basis of its range
/// (tests/reference/README.md) the stiffness is still computed and loses exactly one rank per independent freedom.
#[test]
fn collinear_passive_axes_are_handled() {
    let mut r = rng(5);
    let mut b = ChainBuilder::default();
    b.fixed(random_frame(&mut r, 100.0))
        .spring6(random_spring(&mut r))
        .joint(JointKind::Revolute, Vec3::z(), Role::Passive)
        .joint(JointKind::Revolute, Vec3::z(), Role::Passive)
        .fixed(Frame::translation(Vec3::new(250.0, 0.0, 0.0)));
    let chain = b.chain();
    let c = Coordinates::zeros(&chain);
    let mut j = ChainJacobians::default();
    chain.evaluate(&c, &mut j);
    j.fill_virtual();
    let range = passive_range(&j.passive, 250.0);
    assert_eq!(range.rank, 1);
    let kl = chain_stiffness(&chain, &b.springs, &c, 250.0).unwrap();
    let zero = scaled_eigenvalues(&kl, 250.0).iter().filter(|v| v.abs() < 1e-9 * kl.abs().max()).count();
    assert_eq!(zero, 1);
}

/// Four routes to the same leg stiffness: the Schur form on the hot path, eq (9)'s bordered matrix
/// inverted as printed, the null space of J_q^T from an eigendecomposition, and paper 002's recursive
/// elimination of one passive joint at a time (eq 4/7).
#[test]
fn schur_form_equals_bordered_inverse_and_null_space_route() {
    let mut r = rng(3);
    for _ in 0..50 {
        let mut b = ChainBuilder::default();
        b.fixed(random_frame(&mut r, 200.0));
        b.elastic(JointKind::Prismatic, unit_vector(&mut r), r.random_range(1e3..1e5));
        b.fixed(random_frame(&mut r, 100.0)).spring6(random_spring(&mut r));
        for _ in 0..r.random_range(0..5) {
            b.fixed(random_frame(&mut r, 150.0));
            b.joint(JointKind::Revolute, unit_vector(&mut r), Role::Passive);
        }
        b.fixed(random_frame(&mut r, 100.0)).spring6(random_spring(&mut r));
        b.fixed(random_frame(&mut r, 50.0));
        let chain = b.chain();
        let c = random_coords(&mut r, &chain, 0.3);
        let mut j = ChainJacobians::default();
        chain.evaluate(&c, &mut j);
        j.fill_virtual();
        let s = spring_compliance_at_end(&j.virtual_, &b.springs, &c);
        let range = passive_range(&j.passive, 300.0);
        let hot = leg_stiffness(&s, &range).unwrap();
        let bordered = leg_stiffness_bordered(&s, &range).unwrap();
        let null = leg_stiffness_by_null_space(&s, &j.passive).unwrap();
        let recursive = leg_stiffness_recursive(&s, &j.passive).unwrap();
        assert!(scaled_rel_diff(&hot, &bordered, 300.0) < 1e-9, "{hot}\n{bordered}");
        assert!(scaled_rel_diff(&hot, &recursive, 300.0) < 1e-8, "{hot}\n{recursive}");
        assert!(scaled_rel_diff(&hot, &null, 300.0) < 1e-8, "{hot}\n{null}");
        // And S itself against the plain product J_theta K_theta^-1 J_theta^T.
        let jt = nalgebra::Matrix6xX::from_columns(&j.virtual_);
        let mut ctheta = nalgebra::DMatrix::zeros(j.virtual_.len(), j.virtual_.len());
        for g in &b.springs {
            for a in 0..g.dim {
                for bb in 0..g.dim {
                    ctheta[(g.first + a, g.first + bb)] = g.compliance[(a, bb)];
                }
            }
        }
        let plain: Mat6 = (&jt * ctheta * jt.transpose()).fixed_view::<6, 6>(0, 0).into();
        assert!(scaled_rel_diff(&s, &plain, 300.0) < 1e-12);
    }
    let _ = Vec6::zeros();
}

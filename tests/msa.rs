//! Matrix structural analysis (paper 003 s. 2) against beam closed forms, a portal frame solved by hand, and
//! the VJM model of the same Orthoglide leg.

use crate::common;
use common::*;
use nalgebra::DMatrix;
use rand::Rng;
use stiff::beam::BeamSection;
use stiff::kinematics::chain::{Chain, Element as ChainElement, JointKind, Role};
use stiff::kinematics::frame::{block_rotation, Frame, Mat6, Vec3, Vec6};
use stiff::msa::{beam_stiffness, Connection, Element, Structure};
use stiff::platform::leg::Leg;

fn section() -> BeamSection {
    BeamSection { e: 210000.0, g: 80769.0, area: 120.0, iy: 1500.0, iz: 900.0, j: 2100.0 }
}

/// A cantilever along x, clamped at node 0: the tip compliance is F L^3 / 3 E Iz (y), F L^3 / 3 E Iy (z),
/// F L / E A (x), T L / G J (torsion).
#[test]
fn cantilever_tip_deflections() {
    let s = section();
    let l = 400.0;
    let (p0, p1) = (Vec3::zeros(), Vec3::new(l, 0.0, 0.0));
    let st = Structure {
        nodes: vec![p0, p1],
        elements: vec![
            Element::Flexible { i: 0, j: 1, kjj: beam_stiffness(&s, &p0, &p1).unwrap() },
            Element::Base { node: 0, connection: Connection::rigid() },
        ],
        end: 1,
    };
    let c = st.end_stiffness().unwrap().try_inverse().unwrap();
    let rel = |a: f64, b: f64| (a - b).abs() / b;
    assert!(rel(c[(0, 0)], l / (s.e * s.area)) < 1e-9);
    assert!(rel(c[(1, 1)], l.powi(3) / (3.0 * s.e * s.iz)) < 1e-9);
    assert!(rel(c[(2, 2)], l.powi(3) / (3.0 * s.e * s.iy)) < 1e-9);
    assert!(rel(c[(3, 3)], l / (s.g * s.j)) < 1e-9);
}

/// Two beams in series through a middle node give exactly the one-beam answer (Euler-Bernoulli beams are
/// exact between nodes), in any direction.
#[test]
fn beams_in_series_equal_one_beam() {
    let s = section();
    let (p0, p2) = (Vec3::new(10.0, -5.0, 3.0), Vec3::new(250.0, 120.0, -80.0));
    let p1 = (p0 + p2) * 0.5;
    let one = Structure {
        nodes: vec![p0, p2],
        elements: vec![
            Element::Flexible { i: 0, j: 1, kjj: beam_stiffness(&s, &p0, &p2).unwrap() },
            Element::Base { node: 0, connection: Connection::rigid() },
        ],
        end: 1,
    };
    let two = Structure {
        nodes: vec![p0, p1, p2],
        elements: vec![
            Element::Flexible { i: 0, j: 1, kjj: beam_stiffness(&s, &p0, &p1).unwrap() },
            Element::Flexible { i: 1, j: 2, kjj: beam_stiffness(&s, &p1, &p2).unwrap() },
            Element::Base { node: 0, connection: Connection::rigid() },
        ],
        end: 2,
    };
    let (a, b) = (one.end_stiffness().unwrap(), two.end_stiffness().unwrap());
    assert!((a - b).abs().max() < 1e-9 * a.abs().max());
}

/// A portal frame solved by hand: two columns of height H clamped at the base, their tops joined rigidly
/// (a rigid beam), axially rigid in practice (huge A): each column sways as a clamped-guided beam, so the
/// frame's lateral stiffness is 2 x 12 E I / H^3.
#[test]
fn portal_frame_lateral_stiffness() {
    let s = BeamSection { e: 210000.0, g: 80769.0, area: 1e12, iy: 2000.0, iz: 2000.0, j: 3000.0 };
    let (h, b) = (500.0, 300.0);
    let nodes = vec![Vec3::zeros(), Vec3::new(b, 0.0, 0.0), Vec3::new(0.0, 0.0, h), Vec3::new(b, 0.0, h)];
    let st = Structure {
        elements: vec![
            Element::Flexible { i: 0, j: 2, kjj: beam_stiffness(&s, &nodes[0], &nodes[2]).unwrap() },
            Element::Flexible { i: 1, j: 3, kjj: beam_stiffness(&s, &nodes[1], &nodes[3]).unwrap() },
            Element::Rigid { i: 2, j: 3 },
            Element::Base { node: 0, connection: Connection::rigid() },
            Element::Base { node: 1, connection: Connection::rigid() },
        ],
        nodes,
        end: 2,
    };
    let k = st.end_stiffness().unwrap();
    let expected = 24.0 * s.e * s.iy / h.powi(3);
    assert!((k[(0, 0)] - expected).abs() < 1e-6 * expected, "{} vs {expected}", k[(0, 0)]);
}

/// A passive revolute joint removes exactly its direction: a cantilever with a pin (free rotation about z)
/// at its root has no stiffness against the tip's motion the pin allows, and rank 5.
#[test]
fn a_pin_removes_one_direction() {
    let s = section();
    let (p0, p1) = (Vec3::zeros(), Vec3::new(300.0, 0.0, 0.0));
    let st = Structure {
        nodes: vec![p0, p0, p1],
        elements: vec![
            Element::Base { node: 0, connection: Connection::rigid() },
            Element::Joint {
                i: 0,
                j: 1,
                connection: Connection::passive(vec![Vec6::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0)]),
            },
            Element::Flexible { i: 1, j: 2, kjj: beam_stiffness(&s, &p0, &p1).unwrap() },
        ],
        end: 2,
    };
    let k = st.end_stiffness().unwrap();
    let allowed = Vec6::new(0.0, 300.0, 0.0, 0.0, 0.0, 1.0); // rotation about z at the root, seen at the tip
    assert!((k * allowed).norm() < 1e-9 * k.abs().max());
    let e = scaled_eigenvalues(&k, 300.0);
    assert!(e[0].abs() < 1e-9 * e[5] && e[1] > 1e-6 * e[5], "{e:?}");
}

/// The Orthoglide 3-PUU's first leg at Q0 as an MSA structure: the actuator's carriage on an elastic base
/// connection (k_act along the axis), the foot and the leg as beams with the VJM springs' tip stiffness,
/// the U-joints as passive joints, the tool as a rigid link. Its stiffness at the reference point equals
/// the VJM leg's (paper 001 eq 9) to 1e-8: the two methods agree on a structure both describe.
#[test]
fn msa_equals_vjm_on_an_orthoglide_leg() {
    let m = orthoglide();
    let pose = Frame::IDENTITY;
    let mut state = m.new_state();
    let mut vjm = Vec::new();
    m.unloaded_each(&pose, &mut state, |_, r| vjm.push(r.stiffness)).unwrap();
    let Leg::Vjm(leg) = &m.legs[0] else { panic!("a VJM leg") };
    let coords = &state.legs[0].coords;
    let elements = leg.chain.elements();
    // Frames after each element.
    let frame_after = |k: usize| Chain::new(elements[..=k].to_vec()).end_frame(coords);
    let mut nodes: Vec<Vec3> = Vec::new();
    let mut msa: Vec<Element> = Vec::new();
    let mut current: Option<usize> = None;
    let mut k = 0;
    let mut spring_index = 0;
    while k < elements.len() {
        match &elements[k] {
            ChainElement::Joint(j) if j.role == Role::Actuated => {
                // Actuator and its spring along the same axis: the carriage on an elastic base connection.
                let f = frame_after(k);
                let axis = f.rot * j.axis;
                nodes.push(f.pos);
                let kact = leg.springs[spring_index].stiffness[(0, 0)];
                spring_index += 1;
                msa.push(Element::Base {
                    node: nodes.len() - 1,
                    connection: Connection::elastic(
                        vec![Vec6::new(axis.x, axis.y, axis.z, 0.0, 0.0, 0.0)],
                        DMatrix::from_element(1, 1, kact),
                    ),
                });
                current = Some(nodes.len() - 1);
                k += 2;
            }
            ChainElement::Fixed(_) if matches!(elements.get(k + 1), Some(ChainElement::Joint(j)) if j.role == Role::Virtual) =>
            {
                // A link and its 6-dof spring: a flexible link with the spring's stiffness at its tip.
                let f = frame_after(k);
                let i = current.unwrap();
                nodes.push(f.pos);
                let spring = &leg.springs[spring_index];
                spring_index += 1;
                let b = block_rotation(&f.rot);
                let kjj: Mat6 = b * spring.stiffness * b.transpose();
                msa.push(Element::Flexible { i, j: nodes.len() - 1, kjj });
                current = Some(nodes.len() - 1);
                k += 7;
            }
            ChainElement::Fixed(_) => {
                let f = frame_after(k);
                match current {
                    None => {}
                    Some(i) => {
                        nodes.push(f.pos);
                        msa.push(Element::Rigid { i, j: nodes.len() - 1 });
                        current = Some(nodes.len() - 1);
                    }
                }
                k += 1;
            }
            ChainElement::Joint(j) if j.role == Role::Passive => {
                // A passive revolute: free rotation about its axis at the node.
                assert_eq!(j.kind, JointKind::Revolute);
                let before = if k == 0 { Frame::IDENTITY } else { frame_after(k - 1) };
                let axis = before.rot * j.axis;
                let i = current.unwrap();
                nodes.push(nodes[i]);
                msa.push(Element::Joint {
                    i,
                    j: nodes.len() - 1,
                    connection: Connection::passive(vec![Vec6::new(0.0, 0.0, 0.0, axis.x, axis.y, axis.z)]),
                });
                current = Some(nodes.len() - 1);
                k += 1;
            }
            other => panic!("unexpected element {other:?}"),
        }
    }
    let end = current.unwrap();
    assert!((nodes[end] - pose.pos).norm() < 1e-9, "the chain ends at the reference point");
    let st = Structure { nodes, elements: msa, end };
    let k_msa = st.end_stiffness().unwrap();
    assert!(scaled_rel_diff(&k_msa, &vjm[0], 300.0) < 1e-8, "{k_msa}\nvs VJM\n{}", vjm[0]);
}

/// Two pins about the same axis in series leave the node between them free with the end held: a mechanism,
/// reported with one free motion and the node it moves, not a garbage stiffness.
#[test]
fn a_redundant_pin_is_reported_as_a_mechanism() {
    let s = section();
    let (p0, p1) = (Vec3::zeros(), Vec3::new(300.0, 0.0, 0.0));
    let pin = || Connection::passive(vec![Vec6::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0)]);
    let st = Structure {
        nodes: vec![p0, p0, p0, p1],
        elements: vec![
            Element::Base { node: 0, connection: Connection::rigid() },
            Element::Joint { i: 0, j: 1, connection: pin() },
            Element::Joint { i: 1, j: 2, connection: pin() },
            Element::Flexible { i: 2, j: 3, kjj: beam_stiffness(&s, &p0, &p1).unwrap() },
        ],
        end: 3,
    };
    assert_eq!(st.end_stiffness(), Err(stiff::msa::MsaFailure::Mechanism { free: 1, nodes: vec![1] }));
}

/// An elastic base connection with a preload s0 in series with a beam along the same axis: the end held in
/// place needs the force -k1 kb s0 / (k1 + kb) (kb = E A / L), and the axial stiffness is k1 kb / (k1 + kb).
#[test]
fn an_elastic_joint_preload_loads_the_held_end() {
    let s = section();
    let l = 250.0;
    let (p0, p1) = (Vec3::zeros(), Vec3::new(l, 0.0, 0.0));
    let (k1, s0) = (3000.0, 0.02);
    let mut spring =
        Connection::elastic(vec![Vec6::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)], DMatrix::from_element(1, 1, k1));
    spring.preload[0] = s0;
    let st = Structure {
        nodes: vec![p0, p1],
        elements: vec![
            Element::Base { node: 0, connection: spring },
            Element::Flexible { i: 0, j: 1, kjj: beam_stiffness(&s, &p0, &p1).unwrap() },
        ],
        end: 1,
    };
    let a = st.condense().unwrap();
    let kb = s.e * s.area / l;
    let series = k1 * kb / (k1 + kb);
    assert!((a.stiffness[(0, 0)] - series).abs() < 1e-9 * series);
    assert!((a.holding_wrench[0] + series * s0).abs() < 1e-9 * series * s0, "{}", a.holding_wrench);
    assert!(a.holding_wrench.rows(1, 5).norm() < 1e-9 * series * s0);
}

/// A loop closed through a joint away from the forest (the same pin as a base connection written twice)
/// changes nothing; a structure whose end is reached through the forest (a rigid base link to the end's
/// neighbour) gives the same stiffness as with the end as a root.
#[test]
fn forest_choice_does_not_change_the_answer() {
    let s = section();
    let (p0, p1, p2) = (Vec3::zeros(), Vec3::new(200.0, 50.0, 0.0), Vec3::new(200.0, 50.0, 180.0));
    let pin = Connection::passive(vec![Vec6::new(0.0, 0.0, 0.0, 0.0, 1.0, 0.0)]);
    let beams = vec![
        Element::Flexible { i: 0, j: 1, kjj: beam_stiffness(&s, &p0, &p1).unwrap() },
        Element::Flexible { i: 1, j: 2, kjj: beam_stiffness(&s, &p1, &p2).unwrap() },
    ];
    let mut single = beams.clone();
    single.push(Element::Base { node: 0, connection: pin.clone() });
    let mut doubled = single.clone();
    doubled.push(Element::Base { node: 0, connection: pin });
    let nodes = vec![p0, p1, p2];
    let a = Structure { nodes: nodes.clone(), elements: single, end: 2 }.end_stiffness().unwrap();
    let b = Structure { nodes: nodes.clone(), elements: doubled, end: 2 }.end_stiffness().unwrap();
    assert!((a - b).abs().max() < 1e-9 * a.abs().max());
    // The same cantilever seen from its other end: clamp node 2, load node 0 (reached through the forest
    // only if the clamp is a rigid chain; here the end is a root and the base edge is met in reverse).
    let mut reversed = beams;
    reversed.push(Element::Base { node: 2, connection: Connection::rigid() });
    let c = Structure { nodes, elements: reversed, end: 0 }.end_stiffness().unwrap();
    let c_tip = c.try_inverse().unwrap();
    // Compliance at node 0 of the clamped-at-2 structure = compliance at 2 of the clamped-at-0 one, moved.
    let mut clamped0 = vec![
        Element::Flexible { i: 0, j: 1, kjj: beam_stiffness(&s, &p0, &p1).unwrap() },
        Element::Flexible { i: 1, j: 2, kjj: beam_stiffness(&s, &p1, &p2).unwrap() },
    ];
    clamped0.push(Element::Base { node: 0, connection: Connection::rigid() });
    let d = Structure { nodes: vec![p0, p1, p2], elements: clamped0, end: 2 }.end_stiffness().unwrap();
    // Rigid-body invariance: the two are related by the shift between the ends.
    let a02 = stiff::kinematics::frame::point_shift(&(p2 - p0));
    let moved = a02 * c_tip * a02.transpose();
    let d_tip = d.try_inverse().unwrap();
    assert!((moved - d_tip).abs().max() < 1e-8 * d_tip.abs().max(), "{moved}\nvs\n{d_tip}");
}

/// A spring closing a loop acts as the same spring in the forest: a pin about z at a beam's end, in parallel
/// with a six-direction spring (a loop outside the forest, all its directions elastic, so the reduced
/// system is solved by the envelope Cholesky), is rigid in the pin's five held directions and turns against
/// the spring's k_rz alone: the end's stiffness and preload's holding wrench equal those of one elastic
/// joint about z with k_rz and the same preload, and its torsion is the beam's G J / L and k_rz in series.
#[test]
fn a_spring_closing_a_loop_equals_the_spring_in_the_forest() {
    let s = section();
    let (p0, p1) = (Vec3::zeros(), Vec3::new(0.0, 0.0, 300.0));
    let unit = |k: usize| Vec6::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
    let k_rz = 4.0e6;
    let stiffnesses = [2.0e5, 3.0e5, 4.0e5, 5.0e7, 6.0e7, k_rz];
    let mut six = Connection::elastic(
        (0..6).map(unit).collect(),
        DMatrix::from_fn(6, 6, |r, c| if r == c { stiffnesses[r] } else { 0.0 }),
    );
    six.preload[5] = 0.01;
    let mut one = Connection::elastic(vec![unit(5)], DMatrix::from_element(1, 1, k_rz));
    one.preload[0] = 0.01;
    let beam = || Element::Flexible { i: 0, j: 1, kjj: beam_stiffness(&s, &p0, &p1).unwrap() };
    let base = || Element::Base { node: 0, connection: Connection::rigid() };
    let looped = Structure {
        nodes: vec![p0, p1, p1],
        elements: vec![
            base(),
            beam(),
            Element::Joint { i: 1, j: 2, connection: Connection::passive(vec![unit(5)]) },
            Element::Joint { i: 1, j: 2, connection: six },
        ],
        end: 2,
    };
    let single = Structure {
        nodes: vec![p0, p1, p1],
        elements: vec![base(), beam(), Element::Joint { i: 1, j: 2, connection: one }],
        end: 2,
    };
    let (a, b) = (looped.condense().unwrap(), single.condense().unwrap());
    assert!(
        (a.stiffness - b.stiffness).abs().max() < 1e-9 * b.stiffness.abs().max(),
        "{}\nvs\n{}",
        a.stiffness,
        b.stiffness
    );
    assert!(
        (a.holding_wrench - b.holding_wrench).norm() < 1e-9 * b.holding_wrench.norm(),
        "{} vs {}",
        a.holding_wrench,
        b.holding_wrench
    );
    let torsion = s.g * s.j / (p1 - p0).norm();
    let series = torsion * k_rz / (torsion + k_rz);
    assert!((a.stiffness[(5, 5)] - series).abs() < 1e-9 * series, "{} vs {series}", a.stiffness[(5, 5)]);
    assert!((a.holding_wrench[5] + series * 0.01).abs() < 1e-9 * series * 0.01, "{}", a.holding_wrench);
}

fn model(path: &str) -> stiff::platform::manipulator::Manipulator {
    stiff::model::load_manipulator(std::path::Path::new(path)).unwrap()
}

fn stiffness_at(m: &stiff::platform::manipulator::Manipulator, pose: &Frame) -> Mat6 {
    let mut state = m.new_state();
    m.unloaded(pose, &mut state).unwrap().stiffness
}

/// The whole 3-PUU written as an MSA structure (manipulators/orthoglide-3puu-msa.toml: closed-form
/// geometry from the pose, every node, beam and joint named) and as VJM chains (orthoglide-3puu.toml, inverse
/// kinematics by Newton) agree to 1e-8 over the workspace: two methods, two geometry routes, one robot.
#[test]
fn msa_equals_vjm_on_the_whole_orthoglide() {
    let (vjm, msa) = (orthoglide(), model("manipulators/orthoglide-3puu-msa.toml"));
    let mut r = rng(11);
    for _ in 0..40 {
        let p = Vec3::new(r.random_range(-70.0..120.0), r.random_range(-70.0..120.0), r.random_range(-70.0..120.0));
        let pose = Frame::translation(p);
        let (a, b) = (stiffness_at(&vjm, &pose), stiffness_at(&msa, &pose));
        assert!(scaled_rel_diff(&b, &a, 300.0) < 1e-8, "at {p}: {a}\n{b}");
    }
}

/// A rotated platform is out of the translational leg's reach in the MSA description (status unreachable),
/// as in the VJM one (no U-joint configuration reaches it).
#[test]
fn msa_orthoglide_refuses_a_rotated_platform() {
    let msa = model("manipulators/orthoglide-3puu-msa.toml");
    let mut state = msa.new_state();
    let pose = Frame::from_position_rotvec(Vec3::zeros(), Vec3::new(0.0, 0.0, 0.05));
    let e = msa.unloaded(&pose, &mut state).unwrap_err();
    assert!(matches!(e.failure, stiff::platform::leg::LegFailure::OutOfReach { condition: Some(1) }), "{e:?}");
}

fn model_with(path: &str, overrides: &[(&str, f64)]) -> stiff::platform::manipulator::Manipulator {
    let p = std::path::Path::new(path);
    let source = std::fs::read_to_string(p).unwrap();
    let o = overrides.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    stiff::model::parse_with(p, &source, &o, 0).unwrap().manipulator
}

/// NaVARo II leg 1's base pivot A (navaro2-leg-passive.toml: radius 400 mm at 90 degrees), bar length 250 mm.
const R_B: f64 = 400.0;
const BAR: f64 = 250.0;

/// One pantograph leg with (nearly) rigid bars, its end at B: in mode 2 the only spring is the slider, and
/// the pantograph's kinematics (rho = 2 l cos beta, slider height h = l sin beta, so d rho / d h =
/// -2 tan beta) give the axial stiffness k_slider / (2 tan beta)^2; in mode 1 the only spring is the leg's
/// rotation, giving k_theta / rho^2 across the leg. The clutch let go removes exactly its direction: along
/// the leg in mode 1, across it in mode 2, with the platform joint's rotation about z free in both.
#[test]
fn pantograph_leg_closed_forms_and_free_directions() {
    let a = Vec3::new(0.0, R_B, 0.0);
    for (b, seed) in
        [(Vec3::new(0.0, 0.0, 0.0), 0), (Vec3::new(90.0, 60.0, 0.0), 1), (Vec3::new(-120.0, 180.0, 0.0), 2)]
    {
        let d = b - a;
        let (rho, u) = (d.norm(), d.normalize());
        let n = Vec3::new(-u.y, u.x, 0.0);
        let beta = (rho / (2.0 * BAR)).acos();
        let pose = Frame::translation(b);
        let along = Vec6::new(u.x, u.y, 0.0, 0.0, 0.0, 0.0);
        let across = Vec6::new(n.x, n.y, 0.0, 0.0, 0.0, 0.0);
        let spin = Vec6::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        // Mode 2 (active pantograph), bars 1e7 times stiffer than aluminium.
        let m2 = model_with("manipulators/navaro2-leg-active.toml", &[]);
        let stiff_bars =
            model_with("manipulators/navaro2-leg-passive.toml", &[("clutch1", 0.0), ("clutch2", 1.0), ("E", 6.9e11)]);
        let k = stiffness_at(&stiff_bars, &pose);
        let expected = 2e4 / (2.0 * beta.tan()).powi(2);
        let got = along.dot(&(k * along));
        assert!((got - expected).abs() < 1e-5 * expected, "B {b} ({seed}): {got} vs {expected}");
        let k2 = stiffness_at(&m2, &pose);
        let scale = k2.abs().max();
        assert!((k2 * across).norm() < 1e-9 * scale && (k2 * spin).norm() < 1e-9 * scale, "mode 2 frees the angle");
        assert!(along.dot(&(k2 * along)) > 1e-3 * expected, "mode 2 holds the length");
        // Mode 1 (passive pantograph).
        let m1 = model_with("manipulators/navaro2-leg-passive.toml", &[]);
        let stiff_bars = model_with("manipulators/navaro2-leg-passive.toml", &[("E", 6.9e11)]);
        let k = stiffness_at(&stiff_bars, &pose);
        let expected = 1e7 / (rho * rho);
        let got = across.dot(&(k * across));
        assert!((got - expected).abs() < 1e-5 * expected, "B {b}: {got} vs {expected}");
        let k1 = stiffness_at(&m1, &pose);
        let scale = k1.abs().max();
        assert!((k1 * along).norm() < 1e-9 * scale && (k1 * spin).norm() < 1e-9 * scale, "mode 1 frees the length");
        // Rank 4: the two freed directions only.
        for k in [k1, k2] {
            let e = scaled_eigenvalues(&k, 300.0);
            assert!(e[1].abs() < 1e-9 * e[5] && e[2] > 1e-8 * e[5], "{e:?}");
        }
    }
}

/// Regression: a NaVARo II leg on its own is a mechanism with two free motions, the platform joint's
/// rotation about z at B and the clutch let go (the leg's length in mode 1, its angle about the base pivot A
/// in mode 2: a translation of B across the leg). At about half the poses the reported rank was 5 with the
/// rotation alone: the in-plane stiffness, cancelled from bar stiffnesses a million times larger, carries
/// round-off that equilibrating K to a unit diagonal magnified above the rank tolerance. The rank and free
/// directions a map row reports are checked against the mechanism (which end motions leave every link
/// unstrained), independently of any factorisation: exactly two directions listed, spanning the two
/// mechanism motions; each listed direction satisfies |K t| <= 1e-11 |K| in the length-scaled metric,
/// and every direction orthogonal to them does not.
#[test]
fn a_pantograph_legs_rank_and_free_directions_follow_its_mechanism() {
    use stiff::platform::compliance::FREE_DIRECTION_TOLERANCE;
    use stiff::study::point::{unloaded_point, Status};
    let a = Vec3::new(0.0, R_B, 0.0);
    let mut poses = vec![
        Vec3::new(150.0, 100.0, 0.0),
        Vec3::new(-120.0, 250.0, 0.0),
        Vec3::new(200.0, 0.0, 0.0),
        Vec3::new(-200.0, 50.0, 0.0),
    ];
    let mut r = rng(44);
    while poses.len() < 40 {
        let (rho, angle) = (r.random_range(135.0..475.0), r.random_range(0.0..std::f64::consts::TAU));
        poses.push(a + Vec3::new(rho * f64::cos(angle), rho * f64::sin(angle), 0.0));
    }
    for (file, passive_length) in
        [("manipulators/navaro2-leg-passive.toml", true), ("manipulators/navaro2-leg-active.toml", false)]
    {
        let m = model_with(file, &[]);
        let l = m.length_scale;
        let weigh = |t: &Vec6| Vec6::from_fn(|i, _| if i < 3 { t[i] } else { t[i] * l });
        for b in &poses {
            let pose = stiff::model::grid::PosePoint {
                name: None,
                position: *b,
                rotation: Vec3::zeros(),
                wrench: None,
                joints: Vec::new(),
            };
            let row = unloaded_point(&m, &pose, &mut m.new_state());
            assert_eq!((row.status, row.rank), (Status::Singular, Some(4)), "{file} at {b}");
            // The mechanism's two motions, in the length-scaled metric (rotations times l), orthonormal.
            let u = (b - a).normalize();
            let slide = if passive_length { u } else { Vec3::new(-u.y, u.x, 0.0) };
            let mechanism = [Vec6::new(slide.x, slide.y, 0.0, 0.0, 0.0, 0.0), Vec6::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0)];
            assert_eq!(row.free.len(), 2, "{file} at {b}: {:?}", row.free);
            let ks = stiff::platform::compliance::scaled(&row.stiffness.unwrap(), l);
            let norm_k = ks.singular_values().max();
            for t in &row.free {
                let t = weigh(t).normalize();
                let outside = t - mechanism.iter().map(|m| m * m.dot(&t)).sum::<Vec6>();
                assert!(outside.norm() < 1e-9, "{file} at {b}: {t:?} is not a mechanism motion");
                assert!(
                    (ks * t).norm() <= FREE_DIRECTION_TOLERANCE * norm_k,
                    "{file} at {b}: |K t| {}",
                    (ks * t).norm()
                );
            }
            // The four directions orthogonal to the mechanism are all resisted: K times the projector onto
            // them has four singular values (those of K restricted there), the smallest of which must not vanish.
            let m6 = nalgebra::Matrix6x2::from_columns(&mechanism);
            let projector = Mat6::identity() - m6 * m6.transpose();
            let mut sigma: Vec<f64> = (ks * projector).singular_values().iter().copied().collect();
            sigma.sort_by(|x, y| y.total_cmp(x));
            let resisted = sigma[3];
            assert!(resisted > 1e3 * FREE_DIRECTION_TOLERANCE * norm_k, "{file} at {b}: {resisted} of {norm_k}");
        }
    }
}

/// Eq (18)-(20) computed here independently: a pose is reachable exactly when every leg length
/// |B_i - A_i| lies in [rho_min, rho_max]; the whole manipulator then has full rank in both modes (the leg
/// lines do not meet in one point), and its two modes differ.
#[test]
fn navaro_reach_and_rank_in_both_modes() {
    let (rho_min, rho_max) = (2.0 * BAR * 75f64.to_radians().cos(), 2.0 * BAR * 15f64.to_radians().cos());
    let modes = [
        model_with("manipulators/navaro2.toml", &[("mode", 1.0)]),
        model_with("manipulators/navaro2.toml", &[("mode", 2.0)]),
    ];
    let mut r = rng(5);
    let (mut reachable, mut unreachable) = (0, 0);
    for _ in 0..200 {
        let o = Vec3::new(r.random_range(-220.0..220.0), r.random_range(-220.0..220.0), 0.0);
        let phi: f64 = r.random_range(-0.3..0.3);
        let pose = Frame::from_position_rotvec(o, Vec3::new(0.0, 0.0, phi));
        let inside = (1..=3).all(|i| {
            let rz = |a: f64| stiff::kinematics::frame::rotation_about(&Vec3::z(), a);
            let b = o - rz(-std::f64::consts::PI / 6.0 + 2.0 * std::f64::consts::PI / 3.0 * (i as f64 - 2.0) + phi)
                * Vec3::new(80.0, 0.0, 0.0);
            let a = rz(2.0 * std::f64::consts::PI / 3.0 * (i as f64 - 1.0)) * Vec3::new(0.0, R_B, 0.0);
            let rho = (b - a).norm();
            rho_min <= rho && rho <= rho_max
        });
        let mut ks = Vec::new();
        for m in &modes {
            let mut state = m.new_state();
            match m.unloaded(&pose, &mut state) {
                Ok(a) => ks.push(a.stiffness),
                Err(e) => assert!(
                    matches!(e.failure, stiff::platform::leg::LegFailure::OutOfReach { condition: Some(0 | 1) }),
                    "{e:?}"
                ),
            }
        }
        if inside {
            reachable += 1;
            assert_eq!(ks.len(), 2, "reachable by eq (20) at {o}, phi {phi}");
            for k in &ks {
                let e = scaled_eigenvalues(k, 300.0);
                assert!(e[0] > 1e-9 * e[5], "full rank at {o}: {e:?}");
            }
            assert!(scaled_rel_diff(&ks[0], &ks[1], 300.0) > 1e-3, "the modes differ");
        } else {
            unreachable += 1;
            assert!(ks.is_empty(), "out of reach by eq (20) at {o}, phi {phi}");
        }
    }
    assert!(reachable > 40 && unreachable > 40, "{reachable} / {unreachable}");
}

/// The reduced system's forest, columns and envelope ordering depend only on a structure's shape (which
/// elements join which nodes, with how many free and elastic directions), not on its pose: one condenser
/// carried across the poses of a map, and across a structure of another shape and back, answers bit for
/// bit as a fresh one does at every pose.
#[test]
fn a_reused_condenser_answers_as_a_fresh_one() {
    let navaro = model_with("manipulators/navaro2.toml", &[("mode", 1.0)]);
    let puu = model("manipulators/orthoglide-3puu-msa.toml");
    let msa_leg = |m: &stiff::platform::manipulator::Manipulator, k: usize| match &m.legs[k] {
        Leg::Msa(l) => l.clone(),
        Leg::Vjm(_) => panic!("an MSA leg"),
    };
    let (pantograph, puu_leg) = (msa_leg(&navaro, 1), msa_leg(&puu, 0));
    let mut condenser = stiff::msa::Condenser::default();
    let mut r = rng(3);
    for step in 0..12 {
        let (leg, p) = if step % 4 == 3 {
            (&puu_leg, Vec3::new(r.random_range(-50.0..50.0), r.random_range(-50.0..50.0), r.random_range(-50.0..50.0)))
        } else {
            (&pantograph, Vec3::new(r.random_range(-60.0..60.0), r.random_range(-60.0..60.0), 0.0))
        };
        let structure = leg.structure_at(&Frame::translation(p)).unwrap();
        assert_eq!(condenser.condense(&structure), structure.condense(), "step {step} at {p}");
    }
}

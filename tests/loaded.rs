//! Loaded mode (paper 000 s. 3-4, paper 001 s. 3): zero-load agreement with eq (9), the loaded stiffness
//! against finite differences of equilibria, paper 001 Table 1 loaded rows and Table 3, a closed-form
//! buckling load, a cantilever under its own weight, and spring preload.

use crate::common;
use common::*;
use stiff::kinematics::frame::apply_twist;
use stiff::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use stiff::platform::manipulator::Manipulator;
use stiff::study::curve::{critical_load_factor, curve_rows as run_curve, Control};

/// Places the legs for `commanded` and holds the platform at `actual`: the external wrench and tangent
/// stiffness there.
fn held(m: &Manipulator, commanded: &Frame, actual: &Frame) -> (Vec6, Mat6) {
    let mut s = m.new_state();
    m.place(commanded, &mut s).unwrap();
    let h = m.hold(actual, &mut s).unwrap();
    (h.force, h.stiffness)
}

fn model(text: &str) -> Manipulator {
    stiff::model::parse_manipulator(std::path::Path::new("test.toml"), text).unwrap()
}

fn orthoglide_attached_at_u2() -> Manipulator {
    let text = std::fs::read_to_string("manipulators/orthoglide-3puu.toml").unwrap();
    let tool_line = text.lines().find(|l| l.contains("name = \"tool\"")).unwrap();
    model(&text.replace(tool_line, "").replace(
        "name = \"chain\"\n",
        "name = \"chain\"\nattachment = { translation = [\"-t_x\", \"-t_y\", \"-t_z\"] }\n",
    ))
}

/// With no load the loaded equilibrium is the placement itself, its wrench zero, and eq (45) reduces to
/// eq (9): the loaded stiffness equals the unloaded one to round-off.
#[test]
fn at_zero_load_the_loaded_answer_is_the_unloaded_one() {
    for m in [orthoglide(), orthoglide_attached_at_u2()] {
        for x in [0.0, -73.65, 126.35, 40.0] {
            let pose = Frame::translation(Vec3::new(x, -0.3 * x, 0.5 * x));
            let (f, k) = held(&m, &pose, &pose);
            let k0 = m.unloaded(&pose, &mut m.new_state()).unwrap().stiffness;
            // Equilibrium tolerance: 1e-10 of the leg size in pose, a few 1e-5 N at these stiffnesses.
            assert!(f.norm() < 1e-3, "{f}");
            assert!(scaled_rel_diff(&k, &k0, 300.0) < 1e-9, "{k}\n{k0}");
        }
    }
}

/// The tangent stiffness of the loaded manipulator against central differences of the force-deflection
/// relation between nearby equilibria, at displaced (loaded) poses, for legs that end at the reference
/// point and for legs attached away from it (the turning lever arm adds [F]x[v]x).
#[test]
fn loaded_stiffness_matches_differences_of_equilibria() {
    for m in [orthoglide(), orthoglide_attached_at_u2()] {
        for (x, d) in
            [(0.0, Vec6::new(0.5, 0.5, 0.5, 0.0, 0.0, 0.0)), (-73.65, Vec6::new(0.3, -0.8, 0.2, 0.004, -0.002, 0.003))]
        {
            let commanded = Frame::translation(Vec3::new(x, x, x));
            let actual = apply_twist(&commanded, &d);
            let mut s = m.new_state();
            m.place(&commanded, &mut s).unwrap();
            let k = m.hold(&actual, &mut s).unwrap().stiffness;
            let fd = held_differences(&m, &mut s, &actual);
            assert!(scaled_rel_diff(&k, &fd, 300.0) < 1e-5, "at {x}: {k}\nvs differences\n{fd}");
            // A real load: the loaded stiffness differs from the unloaded one.
            let k0 = m.unloaded(&commanded, &mut m.new_state()).unwrap().stiffness;
            assert!(scaled_rel_diff(&k, &k0, 300.0) > 1e-3);
        }
    }
}

/// Paper 001 Table 1, loaded rows (platform displaced by (0.5, 0.5, 0.5) mm, no rotation) and Table 3 (F,
/// one component of F = (f, f, f)). Predicted, not fitted (the link parameters were fitted to unloaded
/// rows). Reached: Q0 within 0.5%, Q1 within 1.5%, Q2 k_tran within 2.4% and k_rot diagonal 2.2%; the Q2
/// k_rot off-diagonal is -2.53e-7 against -0.7e-7 (the independent model of tests/reference/README.md gets
/// -2.51e-7; a small difference of large terms, sensitive to geometry). Table 3: 1828 / 230 / 3962 N against
/// 1823 / 234 / 4104 N (3.5% at Q2). The printed moments M (lever arms under 2 mm) are not reproduced.
#[test]
fn table_1_loaded_rows_and_table_3_forces() {
    let m = orthoglide();
    // (x, k_tran diag, k_tran off, k_rot diag, k_rot off (None: gap reported), F, tolerance)
    let rows = [
        (0.0, 2.74e-4, None, 16.7e-7, None, 1823.0, 0.01),
        (-73.65, 10.5e-4, Some(5.3e-4), 22.0e-7, Some(6.0e-7), 234.0, 0.02),
        (126.35, 39.1e-4, Some(-18.9e-4), 15.4e-7, None, 4104.0, 0.04),
    ];
    for (x, td, to, rd, ro, f, tol) in rows {
        let commanded = Frame::translation(Vec3::new(x, x, x));
        let actual = Frame::translation(Vec3::new(x + 0.5, x + 0.5, x + 0.5));
        let (force, k) = held(&m, &commanded, &actual);
        let c = k.try_inverse().unwrap();
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
        assert!(rel(c[(0, 0)], td) < tol, "{x}: k_tran {:e} vs {td:e}", c[(0, 0)]);
        assert!(rel(c[(3, 3)], rd) < tol, "{x}: k_rot {:e} vs {rd:e}", c[(3, 3)]);
        if let Some(to) = to {
            assert!(rel(c[(0, 1)], to) < tol, "{x}: k_tran off {:e} vs {to:e}", c[(0, 1)]);
        }
        if let Some(ro) = ro {
            assert!(rel(c[(3, 4)], ro) < tol, "{x}: k_rot off {:e} vs {ro:e}", c[(3, 4)]);
        }
        assert!(rel(force[0], f) < tol, "{x}: F {} vs {f}", force[0]);
        assert!((force[0] - force[1]).abs() < 1e-6 * f && (force[0] - force[2]).abs() < 1e-6 * f);
    }
}

/// An inverted pendulum: a rigid link of length L on a rotational spring k, loaded by a vertical force P at
/// its tip, buckles at P = k / L. A second leg holds every direction but x and z, so the manipulator's
/// stiffness along x is k / L^2 - P / L. `stiff curve` under force control must locate the loss of
/// positive definiteness within 1% and go on past it, flagging the unstable branch.
#[test]
fn inverted_pendulum_buckles_at_k_over_l() {
    let (k, l) = (2.0e6, 250.0);
    let m = model(&format!(
        r#"
name = "inverted pendulum"
[parameters]
k = {k}
L = {l}
[[leg]]
name = "pendulum"
chain = [
  {{ type = "fixed", translation = [0, 0, "-L"] }},
  {{ type = "revolute", axis = "y", role = "elastic", stiffness = "k" }},
  {{ type = "fixed", translation = [0, 0, "L"] }},
  {{ type = "prismatic", axis = "z", role = "elastic", stiffness = 1e7 }},
  {{ type = "prismatic", axis = "y", role = "passive" }},
  {{ type = "spherical" }},
]
[[leg]]
name = "guide"
chain = [
  {{ type = "prismatic", axis = "x", role = "passive" }},
  {{ type = "prismatic", axis = "z", role = "passive" }},
  {{ type = "spring6", stiffness_matrix = [[1e4,0,0,0,0,0],[0,1e4,0,0,0,0],[0,0,1e4,0,0,0],[0,0,0,1e8,0,0],[0,0,0,0,1e8,0],[0,0,0,0,0,1e8]] }},
]
"#
    ));
    let p_cr = k / l;
    let rows =
        run_curve(&m, &Frame::IDENTITY, Control::Force(Vec6::new(0.0, 0.0, -1.0, 0.0, 0.0, 0.0)), 1.5 * p_cr, 37)
            .unwrap();
    // Bisected between the two rows that bracket it. The axial spring (k_a = 1e7 N/mm) shortens the
    // pendulum to L - P/k_a, so the exact critical load solves P (L - P/k_a) = k.
    let k_axial = 1e7;
    let p_exact = (l - (l * l - 4.0 * k / k_axial).sqrt()) * k_axial / 2.0;
    let found = critical_load_factor(&rows).expect("a buckling point");
    assert!((found - p_exact).abs() < 1e-8 * p_exact, "found {found}, closed form {p_exact} (k/L = {p_cr})");
    let flagged = rows.iter().find(|r| r.event == "buckling").unwrap();
    assert!(flagged.load_factor >= p_cr && !flagged.stable() && flagged.instability() == "platform");
    let last = rows.last().unwrap();
    assert!(last.load_factor == 1.5 * p_cr && !last.stable(), "continues past it");
    // `stable` follows the same definition as the events: every row before the crossing is stable, every
    // row after it is not, and the smallest eigenvalue's sign agrees.
    for r in &rows {
        assert_eq!(r.stable(), r.load_factor < p_cr, "row {}", r.step);
        assert_eq!(r.spectrum.unwrap().scaled_min > 0.0, r.stable(), "row {}", r.step);
    }
}

/// A horizontal rigid link of length L on a rotational spring k, with its mass m at mid-length, under
/// gravity g: the equilibrium angle solves k theta = m g (L / 2) cos(theta) (closed form, solved here by
/// bisection); the tip drops by L sin(theta). Every other direction is held by stiff springs.
#[test]
fn cantilever_under_its_own_weight() {
    let (k, l, mass, g) = (3.0e5, 400.0, 2.5, 9.81);
    let m = model(&format!(
        r#"
name = "cantilever"
gravity = [0, 0, -{g}]
[[leg]]
name = "beam"
chain = [
  {{ type = "fixed", translation = [-{l}, 0, 0] }},
  {{ type = "spring6", stiffness_matrix = [[1e9,0,0,0,0,0],[0,1e9,0,0,0,0],[0,0,1e9,0,0,0],[0,0,0,1e12,0,0],[0,0,0,0,{k},0],[0,0,0,0,0,1e12]] }},
  {{ type = "fixed", translation = [{half}, 0, 0] }},
  {{ type = "mass", mass_kg = {mass} }},
  {{ type = "fixed", translation = [{half}, 0, 0] }},
]
"#,
        half = l / 2.0
    ));
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if k * mid < mass * g * l / 2.0 * mid.cos() {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let theta = 0.5 * (lo + hi);
    let mut s = m.new_state();
    m.place(&Frame::IDENTITY, &mut s).unwrap();
    let d = m.deflect(&Frame::IDENTITY, &Vec6::zeros(), None, &mut s).unwrap();
    let drop = -d.displacement[2];
    assert!((drop - l * theta.sin()).abs() < 1e-6 * l * theta.sin(), "drop {drop}, closed form {}", l * theta.sin());
    assert!((d.displacement[4] - theta).abs() < 1e-6 * theta);
    assert!(d.stable);
}

/// A leg that buckles with its end held (paper 000 eq 14: the energy's Hessian on the motions that keep the
/// end fixed): two rigid bars of length L pinned at the base and at the platform, joined by a spring whose
/// axial stiffness is k_a and whose hinge stiffness in the plane is k_r (every other direction stiff).
/// Pushed along its line by e, it carries P = k_a e; with its end held, the hinge can still move sideways by
/// an angle a per bar while the axial spring stretches by about a^2 (L - e/2), so the energy changes by
/// (2 k_r - P (L - e/2)) a^2: the leg is unstable exactly when P > 2 k_r / (L - e/2). The stability test
/// must say so on both sides of that load.
#[test]
fn a_leg_buckles_with_its_end_held_at_twice_its_hinge_stiffness_over_its_length() {
    let (l, k_a, k_r) = (200.0, 1.0e5, 1.0e6);
    let m = model(&format!(
        r#"
name = "hinged column"
[[leg]]
name = "column"
chain = [
  {{ type = "revolute", axis = "z", role = "passive" }},
  {{ type = "fixed", translation = [{l}, 0, 0] }},
  {{ type = "spring6", stiffness_matrix = [[{k_a},0,0,0,0,0],[0,1e9,0,0,0,0],[0,0,1e9,0,0,0],[0,0,0,1e10,0,0],[0,0,0,0,1e10,0],[0,0,0,0,0,{k_r}]] }},
  {{ type = "fixed", translation = [{l}, 0, 0] }},
  {{ type = "revolute", axis = "z", role = "passive" }},
]
"#
    ));
    let commanded = Frame::translation(Vec3::new(2.0 * l, 0.0, 0.0));
    for ratio in [0.5, 0.99, 1.01, 1.5] {
        // P = k_a e = ratio * 2 k_r / (L - e/2), solved for e.
        let e = {
            let target = ratio * 2.0 * k_r / k_a;
            // e (L - e/2) = target: the smaller root.
            l - (l * l - 2.0 * target).sqrt()
        };
        let mut s = m.new_state();
        m.place(&commanded, &mut s).unwrap();
        let h = m.hold(&Frame::translation(Vec3::new(2.0 * l - e, 0.0, 0.0)), &mut s).unwrap();
        let p = -h.force[0];
        assert!((p - k_a * e).abs() < 1e-6 * k_a * e, "P {p} vs k_a e {}", k_a * e);
        assert_eq!(
            h.legs_stable(),
            ratio < 1.0,
            "P / P_cr = {ratio}: unstable legs {:?}",
            h.unstable_legs().collect::<Vec<_>>()
        );
    }
}

/// Two axial springs in parallel between the base and the platform, one preloaded (rest length shifted by
/// p): the platform settles at x = k1 p / (k1 + k2), and the springs carry k2 x each way.
#[test]
fn preloaded_spring_shifts_the_platform() {
    let (k1, k2, p) = (3000.0, 5000.0, 0.2);
    let m = model(&format!(
        r#"
name = "preloaded pair"
[[leg]]
name = "a"
chain = [
  {{ type = "prismatic", axis = "x", role = "elastic", stiffness = {k1}, preload = [{p}] }},
  {{ type = "prismatic", axis = "y", role = "passive" }},
  {{ type = "prismatic", axis = "z", role = "passive" }},
  {{ type = "spherical" }},
]
[[leg]]
name = "b"
chain = [
  {{ type = "prismatic", axis = "x", role = "elastic", stiffness = {k2} }},
  {{ type = "spring6", stiffness_matrix = [[1e9,0,0,0,0,0],[0,1e4,0,0,0,0],[0,0,1e4,0,0,0],[0,0,0,1e7,0,0],[0,0,0,0,1e7,0],[0,0,0,0,0,1e7]] }},
]
"#
    ));
    let mut s = m.new_state();
    m.place(&Frame::IDENTITY, &mut s).unwrap();
    let d = m.deflect(&Frame::IDENTITY, &Vec6::zeros(), None, &mut s).unwrap();
    // Leg b's axial spring in series with its 6-dof spring (1e9 N/mm along x).
    let k2_series = 1.0 / (1.0 / k2 + 1.0 / 1e9);
    let expected = k1 * p / (k1 + k2_series);
    assert!((d.displacement[0] - expected).abs() < 1e-9 * expected, "{} vs {expected}", d.displacement[0]);
    assert!(d.displacement.fixed_rows::<5>(1).norm() < 1e-9);
}

/// A shallow two-bar truss (von Mises truss): bars from (+-a, 0, 0) to the apex (0, 0, h), pinned at both
/// ends, axial stiffness k. Under a vertical load the apex goes down by w with P(w) = 2 k (L0 - L) (h - w) / L,
/// L = sqrt(a^2 + (h - w)^2), which peaks at a limit point and then falls (snap-through). Force control
/// cannot pass the peak: `stiff curve` must flag it and go on by displacement control along the falling,
/// unstable branch. A guide leg holds y and the rotations. (Each bar: a spherical joint at the base and a
/// universal joint at the apex, so no passive freedom is redundant.)
#[test]
fn snap_through_limit_point_switches_to_displacement_control() {
    let (a, h, k) = (100.0f64, 20.0f64, 1000.0f64);
    let l0 = (a * a + h * h).sqrt();
    let load = |w: f64| {
        let l = (a * a + (h - w) * (h - w)).sqrt();
        2.0 * k * (l0 - l) * (h - w) / l
    };
    let p_max = (0..200_000).map(|i| load(h * i as f64 / 200_000.0)).fold(0.0, f64::max);
    let m = model(&format!(
        r#"
name = "von Mises truss"
[parameters]
a = {a}
h = {h}
k = {k}
[[leg]]
name = "bar"
copies = [{{ name = "left", rotation_axis = "z", rotation_deg = 0 }}, {{ name = "right", rotation_axis = "z", rotation_deg = 180 }}]
chain = [
  {{ type = "fixed", translation = ["-a", 0, 0] }},
  {{ type = "spherical" }},
  {{ type = "prismatic", axis = ["a", 0, "h"], role = "elastic", stiffness = "k" }},
  {{ type = "fixed", translation = ["a", 0, "h"] }},
  {{ type = "universal", axes = ["y", ["h", 0, "-a"]] }},
]
[[leg]]
name = "guide"
chain = [
  {{ type = "prismatic", axis = "z", role = "passive" }},
  {{ type = "spring6", stiffness_matrix = [[1e2,0,0,0,0,0],[0,1e5,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1e8,0,0],[0,0,0,0,1e8,0],[0,0,0,0,0,1e8]] }},
]
"#
    ));
    let at = Frame::translation(Vec3::new(0.0, 0.0, h));
    // Displacement control passes the peak and the snap-through branch (load falling, then rising again
    // past w = h) with every row on the closed form; the stiffness along z changes sign exactly where the
    // closed-form load peaks, so the buckling events bracket the snap-through (no limit point is marked:
    // that is a force-control event).
    let w_max = 2.2 * h;
    let rows = run_curve(&m, &at, Control::Displacement(Vec6::new(0.0, 0.0, -1.0, 0.0, 0.0, 0.0)), w_max, 44).unwrap();
    assert_eq!(rows.len(), 45);
    for r in &rows {
        let w = -r.displacement.unwrap()[2];
        let force = -r.wrench.unwrap()[2];
        assert!((force - load(w)).abs() < 1e-6 * p_max, "w {w}: {force} vs {}", load(w));
        assert!(!r.event.contains("limit_point"));
    }
    let buckling = rows.iter().find(|r| r.event.contains("buckling")).expect("the peak is passed");
    let restabilised = rows.iter().find(|r| r.event.contains("restabilised")).expect("and the valley");
    // dP/dw = 0 at the peak and the valley of P(w), symmetric about w = h.
    let w_peak = (0..200_000).map(|i| h * i as f64 / 200_000.0).max_by(|x, y| load(*x).total_cmp(&load(*y))).unwrap();
    assert!(
        (buckling.event_load_factor.unwrap() - w_peak).abs() < 1e-3 * h,
        "{:?} vs {w_peak}",
        buckling.event_load_factor
    );
    assert!((restabilised.event_load_factor.unwrap() - (2.0 * h - w_peak)).abs() < 1e-3 * h);
    let rows = run_curve(&m, &at, Control::Force(Vec6::new(0.0, 0.0, -1.0, 0.0, 0.0, 0.0)), 1.3 * p_max, 40).unwrap();
    // The limit point is found from the path (the load factor's maximum), not from the solver's failure.
    let limit = rows.iter().find(|r| r.event.contains("limit_point")).expect("a limit point");
    let located = limit.event_load_factor.unwrap();
    assert!((located - p_max).abs() < 0.02 * p_max, "limit point at {located}, closed form {p_max}");
    let switch = rows.iter().position(|r| r.control == "displacement").expect("continued by displacement");
    assert!(rows[..switch].iter().all(|r| r.control == "force" && r.load_factor < p_max && r.stable()));
    assert!(rows[switch..].iter().all(|r| r.control == "displacement"));
    assert!(rows[switch - 1].load_factor > 0.9 * p_max, "force control went to {}", rows[switch - 1].load_factor);
    // Every row lies on the closed-form curve: the load factor is the vertical force, the drop is w; and no
    // row goes beyond --max in the load factor.
    for r in &rows {
        let w = -r.displacement.unwrap()[2];
        assert!((r.load_factor - load(w)).abs() < 1e-6 * p_max, "w {w}: {} vs {}", r.load_factor, load(w));
        assert!(r.load_factor <= 1.3 * p_max);
    }
    let peak = rows.iter().map(|r| r.load_factor).fold(0.0, f64::max);
    assert!(peak <= p_max * (1.0 + 1e-9));
    // Past the peak the load falls as the apex goes down, and that branch is unstable under force control.
    assert!(rows[switch..].iter().any(|r| !r.stable()));
    for r in &rows {
        assert_eq!(r.spectrum.unwrap().scaled_min > 0.0 && r.unstable_legs.is_empty(), r.stable(), "row {}", r.step);
    }
}

/// The Stewart-Gough leg pair of `stewart_leg_pair_loses_lateral_stiffness_under_axial_load`: half-span a,
/// height h, axial stiffness k.
struct LegPair {
    a: f64,
    h: f64,
    k: f64,
}

impl LegPair {
    /// The vertical load and the apex' lateral stiffness with the apex lowered by w (closed form on the
    /// deformed geometry).
    fn geometry(&self, w: f64) -> (f64, f64) {
        let (a, h, k) = (self.a, self.h, self.k);
        let l0 = (a * a + h * h).sqrt();
        let l = (a * a + (h - w) * (h - w)).sqrt();
        let (sin, cos) = (a / l, (h - w) / l);
        let n = k * (l0 - l);
        (2.0 * n * cos, 2.0 * (k * sin * sin - n / l * cos * cos))
    }

    /// The load at which the lateral stiffness vanishes, by bisection on the apex drop.
    fn critical_load(&self) -> f64 {
        let (mut lo, mut hi) = (0.0, 0.5 * self.h);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if self.geometry(mid).1 > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        self.geometry(lo).0
    }

    fn model(&self) -> Manipulator {
        let (a, h, k) = (self.a, self.h, self.k);
        model(&format!(
            r#"
name = "Stewart-Gough leg pair"
[parameters]
a = {a}
h = {h}
k = {k}
[[leg]]
name = "leg"
copies = [{{ name = "left", rotation_axis = "z", rotation_deg = 0 }}, {{ name = "right", rotation_axis = "z", rotation_deg = 180 }}]
chain = [
  {{ type = "fixed", translation = ["-a", 0, 0] }},
  {{ type = "universal", axes = ["y", ["h", 0, "-a"]] }},
  {{ type = "prismatic", axis = ["a", 0, "h"], role = "actuated", stiffness = "k" }},
  {{ type = "fixed", translation = ["a", 0, "h"] }},
  {{ type = "spherical" }},
]
[[leg]]
name = "guide"
chain = [
  {{ type = "prismatic", axis = "x", role = "passive" }},
  {{ type = "prismatic", axis = "z", role = "passive" }},
  {{ type = "spring6", stiffness_matrix = [[1,0,0,0,0,0],[0,1e5,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1e9,0,0],[0,0,0,0,1e9,0],[0,0,0,0,0,1e9]] }},
]
"#
        ))
    }
}

/// The leg pair under a vertical load P is stable under force control below the closed-form critical load
/// and unstable above it (its lateral stiffness changes sign there). `settle_stable`, which decides
/// stability on a linearisation within the Newton tolerance of the equilibrium (compensation's check),
/// must settle where `deflect` does and decide as it does on both sides, from a fresh state, from the
/// state of a load 1% smaller (chord steps first), and solved again from its own equilibrium (a start that
/// close is linearised at once: one iteration, the linearisation that decides).
#[test]
fn settling_with_stability_decides_as_the_tangent_solve_on_both_sides_of_buckling() {
    let pair = LegPair { a: 100.0, h: 300.0, k: 1.0e5 };
    let p_cr = pair.critical_load();
    let m = pair.model();
    let at = Frame::translation(Vec3::new(0.0, 0.0, pair.h));
    let wrench = |ratio: f64| Vec6::new(0.0, 0.0, -ratio * p_cr, 0.0, 0.0, 0.0);
    let placed = || {
        let mut s = m.new_state();
        m.place(&at, &mut s).unwrap();
        s
    };
    for ratio in [0.5, 0.9, 0.95, 1.05, 1.1, 1.3] {
        let tangent = m.deflect(&at, &wrench(ratio), None, &mut placed()).unwrap();
        let (fresh, fresh_stable) = m.settle_stable(&at, &wrench(ratio), None, &mut placed()).unwrap();
        // The neighbour: 1% less load, solved first in the same state.
        let mut neighbour = placed();
        let (before, _) = m.settle_stable(&at, &wrench(0.99 * ratio), None, &mut neighbour).unwrap();
        let (carried, carried_stable) =
            m.settle_stable(&at, &wrench(ratio), Some(&before.pose), &mut neighbour).unwrap();
        assert_eq!(tangent.stable, ratio < 1.0, "P / P_cr = {ratio}");
        assert_eq!(fresh_stable, tangent.stable, "P / P_cr = {ratio}, fresh");
        assert_eq!(carried_stable, tangent.stable, "P / P_cr = {ratio}, from the neighbour");
        // Twice from the equilibrium itself: the second solve follows one that started within round-off.
        let (again, _) = m.settle_stable(&at, &wrench(ratio), Some(&carried.pose), &mut neighbour).unwrap();
        let (settled, settled_stable) =
            m.settle_stable(&at, &wrench(ratio), Some(&again.pose), &mut neighbour).unwrap();
        assert_eq!(settled_stable, tangent.stable, "P / P_cr = {ratio}, from the equilibrium");
        assert_eq!(settled.iterations, 1, "P / P_cr = {ratio}: a start at the equilibrium is linearised at once");
        for (name, d) in [
            ("fresh", fresh.displacement),
            ("from the neighbour", carried.displacement),
            ("from the equilibrium", settled.displacement),
        ] {
            let gap = (d - tangent.displacement).norm();
            assert!(gap < 1e-9 * pair.h, "P / P_cr = {ratio}, {name}: {gap:e} mm from the tangent solve's pose");
        }
        // And the pose is the closed form's: the load carried at that drop.
        let w = -tangent.displacement[2];
        assert!((pair.geometry(w).0 - ratio * p_cr).abs() < 1e-6 * p_cr, "P / P_cr = {ratio}: drop {w}");
    }
}

/// Two Stewart-Gough legs (universal joint at the base, axial spring k, spherical joint at the platform)
/// from (-a, 0, 0) and (a, 0, 0) to the apex (0, 0, h), loaded by a vertical force P: each leg, compressed
/// by N, loses lateral stiffness N / L as a pinned strut does (Euler-like), so the apex' stiffness along x,
/// 2 (k sin^2(alpha) - (N / L) cos^2(alpha)), vanishes at a load found in closed form on the deformed
/// geometry (apex lowered by w: L = sqrt(a^2 + (h - w)^2), N = k (L0 - L), P = 2 N cos(alpha)). A guide holds
/// y and the rotations. Force control must find the buckling there, every row's smallest translational
/// eigenvalue must follow the closed form, and `stable` must follow it.
#[test]
fn stewart_leg_pair_loses_lateral_stiffness_under_axial_load() {
    let pair = LegPair { a: 100.0, h: 300.0, k: 1.0e5 };
    let (h, k) = (pair.h, pair.k);
    let geometry = |w: f64| pair.geometry(w);
    let p_cr = pair.critical_load();
    let m = pair.model();
    let at = Frame::translation(Vec3::new(0.0, 0.0, h));
    let rows = run_curve(&m, &at, Control::Force(Vec6::new(0.0, 0.0, -1.0, 0.0, 0.0, 0.0)), 1.4 * p_cr, 28).unwrap();
    let found = critical_load_factor(&rows).expect("the lateral stiffness vanishes");
    assert!((found - p_cr).abs() < 1e-6 * p_cr, "found {found}, closed form {p_cr}");
    for r in rows.iter().filter(|r| r.converged()) {
        let w = -r.displacement.unwrap()[2];
        let (p, lateral) = geometry(w);
        assert!((p - r.load_factor).abs() < 1e-6 * p_cr, "row {}: P {} vs {p}", r.step, r.load_factor);
        let smallest = r.spectrum.unwrap().translational_min;
        assert!((smallest - lateral.min(1e5)).abs() < 1e-6 * k, "row {}: {smallest} vs {lateral}", r.step);
        // At the critical row itself the lateral stiffness is zero to round-off (1e-11 of k): its sign,
        // and so the flag, is not the model's to decide.
        if lateral.abs() > 1e-12 * k {
            assert_eq!(r.stable(), lateral > 0.0, "row {}: lateral stiffness {lateral}", r.step);
        }
    }
}

/// The equilibrium under a load and its tangent stiffness are properties of the pose, not of the path the
/// solver took: a point solved with chord steps on its neighbour's factorisations (the state carried from
/// a solve 3 mm away, as along a map's row), or after the legs were linearised for something else in
/// between (`hold`, which leaves other factorisations in the legs' workspaces), agrees with the same point
/// solved from a fresh state, to the solver's tolerance.
#[test]
fn a_point_solved_from_its_neighbours_factorisations_agrees_with_a_fresh_solve() {
    let m = orthoglide();
    let wrench = Vec6::new(215.0, -10.0, -25.0, 1000.0, 21500.0, 0.0);
    let at = |x: f64| Frame::translation(Vec3::new(x, 20.0 - 0.4 * x, -10.0 + 0.2 * x));
    let fresh = |x: f64| {
        let mut s = m.new_state();
        m.place(&at(x), &mut s).unwrap();
        m.deflect(&at(x), &wrench, None, &mut s).unwrap()
    };
    // Placements converged past the usual tolerance, so that both solves hold the same actuators.
    let mut carried = m.new_state();
    m.place(&at(-30.0), &mut carried).unwrap();
    let mut last = m.deflect(&at(-30.0), &wrench, None, &mut carried).unwrap();
    for (k, x) in [-27.0, -24.0, -21.0, 0.0].into_iter().enumerate() {
        m.place(&at(x), &mut carried).unwrap();
        if k == 2 {
            m.hold(&at(x), &mut carried).unwrap();
        }
        let start = apply_twist(&at(x), &last.displacement);
        let path = m.deflect(&at(x), &wrench, Some(&start), &mut carried).unwrap();
        let alone = fresh(x);
        let scale = alone.displacement.norm();
        let gap = (path.displacement - alone.displacement).norm() / scale;
        assert!(gap < 1e-8, "x = {x}: displacement gap {gap:e}, {}", path.displacement - alone.displacement);
        let k_scale = alone.held.stiffness.norm();
        assert!((path.held.stiffness - alone.held.stiffness).norm() < 1e-8 * k_scale, "x = {x}: stiffness");
        assert_eq!(path.stable, alone.stable, "x = {x}");
        last = path;
    }
}

/// A chord step solves eq (45)'s residuals with the factorisation its linearisation made. Once the leg's
/// workspace holds another (the leg linearised since at another pose), or where there never was one, the
/// chord step is refused (the Newton method then linearises afresh) rather than solved with a matrix that
/// belongs to another configuration.
#[test]
fn a_chord_step_on_a_factorisation_no_longer_held_is_refused() {
    use stiff::platform::leg::LegLinear;
    let m = orthoglide();
    let leg = &m.legs[1];
    let mut s = leg.new_state();
    let (pose, moved) =
        (Frame::translation(Vec3::new(10.0, -20.0, 5.0)), Frame::translation(Vec3::new(10.2, -20.0, 5.0)));
    leg.place(&pose, &mut s, stiff::kinematics::ik::Needs::Pose).unwrap();
    assert!(!leg.refresh(&pose, &mut s, &mut LegLinear::default()).unwrap(), "never linearised");
    let (mut first, mut second) = (LegLinear::default(), LegLinear::default());
    leg.linearize_into(&pose, &mut s, &mut first).unwrap();
    assert!(leg.refresh(&pose, &mut s, &mut first).unwrap(), "its own factorisation");
    leg.linearize_into(&moved, &mut s, &mut second).unwrap();
    assert!(!leg.refresh(&pose, &mut s, &mut first).unwrap(), "another factorisation in the workspace");
    assert!(leg.refresh(&moved, &mut s, &mut second).unwrap(), "the latest one");
}

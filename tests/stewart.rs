//! Stewart-Gough platforms of paper 002 (s. V): the numerical stiffness at the symmetric home pose against
//! the closed forms of eq (10) (case A) and eq (11) with its misprint corrected (case B,
//! tests/reference/README.md), for several geometries; case A's rank and free rotations.

use crate::common;
use common::*;
use stiff::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use stiff::platform::compliance::{analyse, Outcome};
use stiff::platform::manipulator::Manipulator;

const K11: f64 = 1e5;

fn stewart(case: &str, big_r: f64, r: f64, h: f64) -> Manipulator {
    let path = format!("manipulators/stewart-gough-{case}.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let set = |t: String, name: &str, v: f64| {
        let line = t.lines().find(|l| l.starts_with(&format!("{name} = "))).unwrap().to_string();
        t.replace(&line, &format!("{name} = {v}"))
    };
    let text = set(set(set(text, "R", big_r), "r", r), "h", h);
    stiff::model::parse_manipulator(std::path::Path::new(&path), &text).unwrap()
}

fn home_stiffness(m: &Manipulator, h: f64) -> Mat6 {
    m.unloaded(&Frame::translation(Vec3::new(0.0, 0.0, h)), &mut m.new_state()).unwrap().stiffness
}

fn symmetric(rows: [[f64; 6]; 6], factor: f64) -> Mat6 {
    Mat6::from_fn(|i, j| rows[i][j] * factor)
}

const GEOMETRIES: [(f64, f64, f64); 4] =
    [(200.0, 80.0, 300.0), (200.0, 100.0, 300.0), (350.0, 120.0, 180.0), (150.0, 140.0, 500.0)];

/// Paper 002 eq (10): K = 3 K11 / L^2 [...], d = R - r, L^2 = d^2 + h^2.
#[test]
fn case_a_matches_eq_10() {
    for (big_r, r, h) in GEOMETRIES {
        let k = home_stiffness(&stewart("a", big_r, r, h), h);
        let d = big_r - r;
        let l2 = d * d + h * h;
        let (rhd, r2h2) = (r * h * d, r * r * h * h);
        let closed = symmetric(
            [
                [d * d, 0.0, 0.0, 0.0, rhd, 0.0],
                [0.0, d * d, 0.0, -rhd, 0.0, 0.0],
                [0.0, 0.0, 2.0 * h * h, 0.0, 0.0, 0.0],
                [0.0, -rhd, 0.0, r2h2, 0.0, 0.0],
                [rhd, 0.0, 0.0, 0.0, r2h2, 0.0],
                [0.0; 6],
            ],
            3.0 * K11 / l2,
        );
        let rel = (k - closed).abs().max() / closed.abs().max();
        assert!(rel < 1e-9, "R {big_r} r {r} h {h}: relative difference {rel}\n{k}\n{closed}");
    }
}

/// Paper 002 eq (11) without its stray entry: e = R^2 - R r + r^2, b = R/2 - r, L^2 = e + h^2.
#[test]
fn case_b_matches_eq_11_corrected() {
    for (big_r, r, h) in GEOMETRIES {
        let m = stewart("b", big_r, r, h);
        let k = home_stiffness(&m, h);
        let e = big_r * big_r - big_r * r + r * r;
        let b = big_r / 2.0 - r;
        let l2 = e + h * h;
        let (rhb, r2h2) = (r * h * b, r * r * h * h);
        let closed = symmetric(
            [
                [e, 0.0, 0.0, 0.0, rhb, 0.0],
                [0.0, e, 0.0, -rhb, 0.0, 0.0],
                [0.0, 0.0, 2.0 * h * h, 0.0, 0.0, 0.0],
                [0.0, -rhb, 0.0, r2h2, 0.0, 0.0],
                [rhb, 0.0, 0.0, 0.0, r2h2, 0.0],
                [0.0, 0.0, 0.0, 0.0, 0.0, 1.5 * r * r * big_r * big_r],
            ],
            3.0 * K11 / l2,
        );
        let rel = (k - closed).abs().max() / closed.abs().max();
        assert!(rel < 1e-9, "R {big_r} r {r} h {h}: relative difference {rel}\n{k}\n{closed}");
        assert!(
            matches!(analyse(&k, &k.diagonal().abs(), m.length_scale, true).outcome, Outcome::Regular { .. }),
            "case B has full rank"
        );
    }
}

/// Case A has rank 3: all six leg lines meet at Q = (0, 0, h R / (R - r)), so the platform turns freely about
/// every axis through Q. The reported free directions span exactly those three rotations, seen at the
/// platform centre C as twists (w x (C - Q), w).
#[test]
fn case_a_has_rank_3_and_turns_about_the_meeting_point() {
    for (big_r, r, h) in GEOMETRIES {
        let m = stewart("a", big_r, r, h);
        let total = m.unloaded(&Frame::translation(Vec3::new(0.0, 0.0, h)), &mut m.new_state()).unwrap();
        let k = total.stiffness;
        let Outcome::Singular { rank, free } = analyse(&k, &total.magnitude, m.length_scale, true).outcome else {
            panic!("case A must be singular")
        };
        assert_eq!(rank, 3);
        assert_eq!(free.len(), 3);
        let q = Vec3::new(0.0, 0.0, h * big_r / (big_r - r));
        let c = Vec3::new(0.0, 0.0, h);
        let basis = nalgebra::Matrix6xX::from_columns(&free);
        for w in [Vec3::x(), Vec3::y(), Vec3::z()] {
            let lin = w.cross(&(c - q));
            let t = Vec6::new(lin.x, lin.y, lin.z, w.x, w.y, w.z);
            // K does not resist it ...
            assert!((k * t).norm() < 1e-9 * k.abs().max() * t.norm().max(1.0), "{}", k * t);
            // ... and it lies in the span of the reported free directions.
            let coef = basis.clone().svd(true, true).solve(&t, 1e-12).unwrap();
            assert!(
                (&basis * coef - t).norm() < 1e-8 * t.norm(),
                "rotation about {w:?} through Q not in the free span"
            );
        }
        for f in &free {
            assert!((k * f).norm() < 1e-9 * k.abs().max());
        }
    }
}

/// The map reports the rank and the free directions (and no compliance) at the singular home pose.
#[test]
fn the_map_reports_rank_and_free_directions() {
    let out = assert_cmd::Command::cargo_bin("stiff")
        .unwrap()
        .args([
            "map",
            "manipulators/stewart-gough-a.toml",
            "--points",
            "manipulators/grids/stewart-gough-home.csv",
            "-q",
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let row = text.lines().nth(1).unwrap();
    assert!(row.starts_with("0,home,0.0,0.0,300.0,singular,3,"), "{row}");
    let free = row.split(',').nth(7).unwrap();
    assert_eq!(free.split(';').count(), 3);
    assert!(row.ends_with(&",".repeat(24)), "no compliance for a singular manipulator: {row}");
    let _ = rng(0);
}

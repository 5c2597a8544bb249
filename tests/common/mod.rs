//! Helpers shared by the integration tests: random chains, the shipped models, matrix comparisons.
#![allow(dead_code)]

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use stiff::kinematics::chain::{Chain, ChainJacobians, Coordinates, Element, Joint, JointKind, Role};
use stiff::kinematics::frame::{rotation_from_vector, Frame, Mat6, Vec3, Vec6};
use stiff::platform::manipulator::Manipulator;
use stiff::vjm::spring::SpringGroup;
use stiff::vjm::stiffness::{leg_stiffness, passive_range, spring_compliance_at_end};

pub fn rng(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed)
}

pub fn orthoglide() -> Manipulator {
    stiff::model::load_manipulator(std::path::Path::new("manipulators/orthoglide-3puu.toml")).unwrap()
}

pub fn unit_vector(r: &mut StdRng) -> Vec3 {
    loop {
        let v = Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0));
        if v.norm() > 0.2 && v.norm() <= 1.0 {
            return v.normalize();
        }
    }
}

pub fn random_frame(r: &mut StdRng, reach: f64) -> Frame {
    let rv = unit_vector(r) * r.random_range(0.0..3.0);
    Frame::new(rotation_from_vector(&rv), unit_vector(r) * r.random_range(0.0..reach))
}

/// A random symmetric positive definite 6x6 stiffness in N/mm, N, N mm/rad orders of magnitude.
pub fn random_spring(r: &mut StdRng) -> Mat6 {
    let mut a = Mat6::from_fn(|_, _| r.random_range(-1.0..1.0));
    for i in 0..6 {
        a[(i, i)] += 3.0;
    }
    let d = Mat6::from_diagonal(&Vec6::new(1e2, 1e2, 1e2, 1e5, 1e5, 1e5).map(f64::sqrt));
    d * (a * a.transpose()) * d
}

/// A chain builder that numbers coordinates as it goes.
#[derive(Default)]
pub struct ChainBuilder {
    pub elements: Vec<Element>,
    pub springs: Vec<SpringGroup>,
    counts: [usize; 3],
}

impl ChainBuilder {
    pub fn fixed(&mut self, f: Frame) -> &mut Self {
        self.elements.push(Element::Fixed(f));
        self
    }
    pub fn joint(&mut self, kind: JointKind, axis: Vec3, role: Role) -> &mut Self {
        let slot = match role {
            Role::Actuated => 0,
            Role::Passive => 1,
            Role::Virtual => 2,
        };
        let index = self.counts[slot];
        self.counts[slot] += 1;
        self.elements.push(Element::Joint(Joint { kind, axis: axis.normalize(), role, index, gain: 1.0 }));
        self
    }
    /// A 1-dof elastic joint of stiffness k.
    pub fn elastic(&mut self, kind: JointKind, axis: Vec3, k: f64) -> &mut Self {
        let first = self.counts[2];
        self.joint(kind, axis, Role::Virtual);
        let mut km = Mat6::zeros();
        km[(0, 0)] = k;
        let mut cm = Mat6::zeros();
        cm[(0, 0)] = 1.0 / k;
        self.springs.push(SpringGroup {
            actuator: false,
            name: format!("s{first}"),
            first,
            dim: 1,
            stiffness: km,
            compliance: cm,
            posture: None,
            of_coordinate: None,
            beam_axis: None,
        });
        self
    }
    /// A 6-dof spring Tx Ty Tz Rx Ry Rz with stiffness k.
    pub fn spring6(&mut self, k: Mat6) -> &mut Self {
        let first = self.counts[2];
        for (kind, axis) in [
            (JointKind::Prismatic, Vec3::x()),
            (JointKind::Prismatic, Vec3::y()),
            (JointKind::Prismatic, Vec3::z()),
            (JointKind::Revolute, Vec3::x()),
            (JointKind::Revolute, Vec3::y()),
            (JointKind::Revolute, Vec3::z()),
        ] {
            self.joint(kind, axis, Role::Virtual);
        }
        let c = k.try_inverse().unwrap();
        self.springs.push(SpringGroup {
            actuator: false,
            name: format!("s{first}"),
            first,
            dim: 6,
            stiffness: k,
            compliance: c,
            posture: None,
            of_coordinate: None,
            beam_axis: None,
        });
        self
    }
    pub fn chain(&self) -> Chain {
        Chain::new(self.elements.clone())
    }
}

/// Random coordinates for every joint of a chain.
pub fn random_coords(r: &mut StdRng, chain: &Chain, spread: f64) -> Coordinates {
    let mut c = Coordinates::zeros(chain);
    for v in c.actuated.iter_mut().chain(c.passive.iter_mut()).chain(c.virtual_.iter_mut()) {
        *v = r.random_range(-spread..spread);
    }
    c
}

/// The unloaded stiffness of one chain at its end point, by the engine's hot path.
pub fn chain_stiffness(chain: &Chain, springs: &[SpringGroup], c: &Coordinates, length_scale: f64) -> Option<Mat6> {
    let mut j = ChainJacobians::default();
    chain.evaluate(c, &mut j);
    j.fill_virtual();
    let s = spring_compliance_at_end(&j.virtual_, springs, c);
    leg_stiffness(&s, &passive_range(&j.passive, length_scale))
}

/// Largest entry difference after scaling rotations by `l` (so mm and rad compare), relative to the
/// largest scaled entry of `b`.
pub fn scaled_rel_diff(a: &Mat6, b: &Mat6, l: f64) -> f64 {
    let d = Vec6::new(1.0, 1.0, 1.0, 1.0 / l, 1.0 / l, 1.0 / l);
    let s = |m: &Mat6| Mat6::from_fn(|i, j| m[(i, j)] * d[i] * d[j]);
    (s(a) - s(b)).abs().max() / s(b).abs().max()
}

/// Eigenvalues of the length-scaled matrix, ascending.
pub fn scaled_eigenvalues(k: &Mat6, l: f64) -> Vec<f64> {
    let d = Vec6::new(1.0, 1.0, 1.0, 1.0 / l, 1.0 / l, 1.0 / l);
    let ks = Mat6::from_fn(|i, j| k[(i, j)] * d[i] * d[j]);
    let mut e: Vec<f64> = ks.symmetric_eigen().eigenvalues.iter().copied().collect();
    e.sort_by(f64::total_cmp);
    e
}

/// A random chain: a base transform, `joints` joints of random kind, axis and role (actuated, passive, or
/// elastic) separated by random links, optionally masses on the links, then a random 6-dof spring and a
/// tool transform. Every kind of coordinate appears in general.
pub fn random_chain(r: &mut StdRng, joints: usize, masses: bool) -> ChainBuilder {
    let mut b = ChainBuilder::default();
    b.fixed(random_frame(r, 100.0));
    for _ in 0..joints {
        let kind = if r.random_bool(0.55) { JointKind::Revolute } else { JointKind::Prismatic };
        let role = [Role::Actuated, Role::Passive, Role::Virtual][r.random_range(0..3)];
        let axis = unit_vector(r);
        match role {
            Role::Virtual => b.elastic(kind, axis, 1e3),
            _ => b.joint(kind, axis, role),
        };
        b.fixed(random_frame(r, 150.0));
        if masses && r.random_bool(0.5) {
            b.elements.push(Element::Mass { kg: r.random_range(0.1..5.0), centre: unit_vector(r) * 40.0 });
        }
    }
    b.spring6(random_spring(r));
    b.fixed(random_frame(r, 80.0));
    b
}

/// The tangent stiffness at `pose` by central differences of the wrench that holds the platform at poses
/// displaced from it (steps 1e-4 mm and 1e-7 rad), the legs placed as `state` holds them.
pub fn held_differences(
    m: &Manipulator,
    state: &mut stiff::platform::manipulator::ManipulatorState,
    pose: &Frame,
) -> Mat6 {
    let mut fd = Mat6::zeros();
    for c in 0..6 {
        let h = if c < 3 { 1e-4 } else { 1e-7 };
        let mut e = Vec6::zeros();
        e[c] = h;
        let plus = m.hold(&stiff::kinematics::frame::apply_twist(pose, &e), state).unwrap().force;
        let minus = m.hold(&stiff::kinematics::frame::apply_twist(pose, &-e), state).unwrap().force;
        fd.set_column(c, &((plus - minus) / (2.0 * h)));
    }
    fd
}

/// What a command did within its deadline: its status, at most `stdout_limit` bytes of its stdout (the
/// pipe is closed after them), and its stderr.
pub struct Finished {
    pub status: std::process::ExitStatus,
    pub stdout: Vec<u8>,
    pub stderr: String,
}

/// Runs `cmd` (stdout and stderr piped) and waits at most `deadline`; None when it had to be killed (a hang).
pub fn run_with_deadline(
    cmd: &mut std::process::Command,
    stdout_limit: usize,
    deadline: std::time::Duration,
) -> Option<Finished> {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let out_reader = std::thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = (&mut stdout).take(stdout_limit as u64).read_to_end(&mut buf);
        buf // the pipe closes here
    });
    let err_reader = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = stderr.read_to_end(&mut s);
        String::from_utf8_lossy(&s).into_owned()
    });
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if start.elapsed() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    };
    let (stdout, stderr) = (out_reader.join().unwrap(), err_reader.join().unwrap());
    status.map(|status| Finished { status, stdout, stderr })
}

/// Runs `stiff` with `args`, expecting success; returns stdout.
pub fn run_stiff(args: &[&str]) -> String {
    let o = assert_cmd::Command::cargo_bin("stiff").unwrap().args(args).output().unwrap();
    assert!(o.status.success(), "stiff {}: {}", args.join(" "), String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

/// A CSV table's named columns, row by row, as numbers (empty cells NaN).
pub fn csv_columns(text: &str, names: &[&str]) -> Vec<Vec<f64>> {
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let header = reader.headers().unwrap().clone();
    let at: Vec<usize> = names.iter().map(|n| header.iter().position(|h| h == *n).expect(n)).collect();
    reader
        .records()
        .map(|r| {
            let r = r.unwrap();
            at.iter().map(|&i| r[i].parse().unwrap_or(f64::NAN)).collect()
        })
        .collect()
}

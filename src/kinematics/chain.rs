//! A serial chain as an ordered product of fixed transforms and one-coordinate joints (paper 001 eq 1).
//!
//! Every coordinate of the VJM model is an elementary joint: actuated joints, passive joints and the
//! virtual springs alike (a 6-dof spring is Tx Ty Tz Rx Ry Rz about the axes of the frame where it sits).
//! The Jacobian column of a coordinate is the twist of its joint seen at the chain's end point, in the base
//! frame: a revolute joint of world axis w through o gives (w x (p_end - o), w), a prismatic one (w, 0).

use super::frame::{rotation_about, Frame, Mat3, Vec3, Vec6};

/// An elementary joint's motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis.
    Revolute,
    /// Translation along the axis.
    Prismatic,
}

/// Which vector of coordinates a joint reads: actuated (fixed by inverse kinematics), passive (free, zero
/// reaction at equilibrium, paper 001 eq 7) or virtual (elastic, reaction K_theta theta, eq 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// An actuator's coordinate.
    Actuated,
    /// A passive joint's coordinate.
    Passive,
    /// A virtual spring's coordinate.
    Virtual,
}

/// An elementary joint of a chain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Joint {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Unit axis in the joint's local frame.
    pub axis: Vec3,
    /// Which coordinate vector it reads.
    pub role: Role,
    /// Index in that vector.
    pub index: usize,
    /// The joint value is `gain * coordinate` (a gain of -1 lets one coordinate drive two joints, as the
    /// parallelogram constraint q3 = -q2 of paper 001 eq 22 needs).
    pub gain: f64,
}

impl Joint {
    /// The principal axis (0, 1 or 2) a revolute joint turns about, where its axis is a unit vector of the
    /// frame: its rotation then only mixes two columns (`apply`).
    fn principal_axis(&self) -> Option<usize> {
        if self.kind != JointKind::Revolute {
            return None;
        }
        self.unit_axis()
    }

    /// The frame axis (0, 1 or 2) that is the joint's axis, where it is one (a unit vector of the frame):
    /// its world axis is then that column of the frame's rotation, with no product.
    fn unit_axis(&self) -> Option<usize> {
        if self.axis.norm_squared() != 1.0 {
            return None;
        }
        [self.axis.x, self.axis.y, self.axis.z].iter().position(|&c| c == 1.0)
    }

    /// `f * motion(value)`: the frame after this joint moves by `value` (rad or mm) about or along its axis.
    /// Rotations about a principal axis (`principal`, from `principal_axis`) only mix two columns, the
    /// common case on the hot path.
    #[inline(always)]
    fn apply(&self, f: &Frame, value: f64, principal: Option<usize>) -> Frame {
        match (self.kind, principal) {
            (JointKind::Prismatic, _) => Frame { rot: f.rot, pos: f.pos + f.rot * (self.axis * value) },
            (JointKind::Revolute, Some(k)) => {
                let (s, c) = small_angle_sin_cos(value);
                turned_about_column(f, k, s, c)
            }
            (JointKind::Revolute, None) => Frame { rot: f.rot * rotation_about(&self.axis, value), pos: f.pos },
        }
    }
}

/// `f` turned about its own column `k` by the angle whose sine and cosine are `s` and `c`: two columns
/// mixed.
#[inline(always)]
fn turned_about_column(f: &Frame, k: usize, s: f64, c: f64) -> Frame {
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    let (ci, cj) = (f.rot.column(i).into_owned(), f.rot.column(j).into_owned());
    let (new_i, new_j) = (ci * c + cj * s, cj * c - ci * s);
    let kept = f.rot.column(k).into_owned();
    // Built whole rather than copied and overwritten column by column, so that the frame is not stored in
    // pieces that the next joint's loads must wait for.
    let rot = match k {
        0 => Mat3::from_columns(&[kept, new_i, new_j]),
        1 => Mat3::from_columns(&[new_j, kept, new_i]),
        _ => Mat3::from_columns(&[new_i, new_j, kept]),
    };
    Frame { rot, pos: f.pos }
}

/// Below this angle (rad) `small_angle_sin_cos` sums the Taylor series: its first omitted terms,
/// x^11/11! and x^10/10!, are below 3e-19 there, a thousandth of the last bit of the values.
const SMALL_ANGLE: f64 = 0.0625;

/// `x.sin_cos()`, by the Taylor series where |x| <= `SMALL_ANGLE` (to within an ulp, as libm): the virtual
/// springs of a loaded chain turn by 1e-2 rad or less, and there the series costs a fifth of libm's
/// general reduction, at every joint of every evaluation.
#[inline]
pub fn small_angle_sin_cos(x: f64) -> (f64, f64) {
    if x.abs() > SMALL_ANGLE {
        return x.sin_cos();
    }
    let x2 = x * x;
    // sin x = x + x^3 (-1/3! + x^2 (1/5! + x^2 (-1/7! + x^2 / 9!))),
    // cos x = 1 + x^2 (-1/2! + x^2 (1/4! + x^2 (-1/6! + x^2 / 8!))).
    let sin_tail = -1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362_880.0)));
    let cos_tail = -0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40_320.0)));
    (x + x * x2 * sin_tail, 1.0 + x2 * cos_tail)
}

/// What `evaluate` and `walk` do at each element, decided once when the chain is built: a fixed transform
/// that only translates (most link vectors) needs no rotation product, and a revolute joint's principal
/// axis is found once rather than at every evaluation.
#[derive(Clone, Debug, PartialEq)]
enum Step {
    Translate(Vec3),
    Transform(Frame),
    Mass { kg: f64, centre: Vec3 },
    Joint { joint: Joint, principal: Option<usize>, tag: JointTag, unit_axis: Option<usize> },
}

impl Step {
    fn of(e: &Element) -> Step {
        match e {
            Element::Fixed(t) if t.rot == Mat3::identity() => Step::Translate(t.pos),
            Element::Fixed(t) => Step::Transform(*t),
            Element::Mass { kg, centre } => Step::Mass { kg: *kg, centre: *centre },
            Element::Joint(j) => Step::Joint {
                joint: *j,
                principal: j.principal_axis(),
                tag: JointTag { gain: j.gain, index: j.index, kind: j.kind, role: j.role },
                unit_axis: j.unit_axis(),
            },
        }
    }
}

/// One element of a serial chain.
#[derive(Clone, Debug, PartialEq)]
pub enum Element {
    /// A fixed transform.
    Fixed(Frame),
    /// A one-coordinate joint.
    Joint(Joint),
    /// A point mass (kg) at `centre` in the current frame: under the model's gravity it is an auxiliary
    /// load G_j at an intermediate node (paper 000 eq 28-31).
    Mass {
        /// Mass, kg.
        kg: f64,
        /// Its centre in the current frame, mm.
        centre: Vec3,
    },
}

/// Values of a chain's coordinates, by role.
#[derive(Debug, Default, PartialEq)]
pub struct Coordinates {
    /// Actuated coordinates (mm or rad).
    pub actuated: Vec<f64>,
    /// Passive coordinates.
    pub passive: Vec<f64>,
    /// Virtual (spring) coordinates.
    pub virtual_: Vec<f64>,
}

impl Clone for Coordinates {
    fn clone(&self) -> Self {
        Self { actuated: self.actuated.clone(), passive: self.passive.clone(), virtual_: self.virtual_.clone() }
    }

    /// Into the existing buffers (warm starts are saved and restored at every point).
    fn clone_from(&mut self, source: &Self) {
        copy_values(&mut self.actuated, &source.actuated);
        copy_values(&mut self.passive, &source.passive);
        copy_values(&mut self.virtual_, &source.virtual_);
    }
}

/// `to.clone_from(from)`, as one copy where the lengths agree (the same chain's coordinates always do):
/// `Vec::clone_from` truncates, copies and extends by the rest, a few dozen instructions more for a
/// handful of values, two dozen times per compensated target.
fn copy_values(to: &mut Vec<f64>, from: &[f64]) {
    if to.len() == from.len() {
        to.copy_from_slice(from);
    } else {
        to.clear();
        to.extend_from_slice(from);
    }
}

impl Coordinates {
    /// All coordinates of `chain` at zero.
    pub fn zeros(chain: &Chain) -> Self {
        Self {
            actuated: vec![0.0; chain.n_actuated],
            passive: vec![0.0; chain.n_passive],
            virtual_: vec![0.0; chain.n_virtual],
        }
    }

    /// The coordinate a joint of `role` with `index` reads.
    #[inline]
    pub fn get(&self, role: Role, index: usize) -> f64 {
        match role {
            Role::Actuated => self.actuated[index],
            Role::Passive => self.passive[index],
            Role::Virtual => self.virtual_[index],
        }
    }
}

/// A joint's placement in the base frame during one evaluation.
#[derive(Clone, Copy, Debug)]
struct PlacedJoint {
    joint: JointTag,
    axis_world: Vec3,
    origin_world: Vec3,
}

/// What the Jacobian columns and load terms need of a joint besides its placement, made once per chain
/// (`Step::of`): copying the whole `Joint` at every evaluation, the compiler moved its bytes in overlapping
/// pieces that later loads had to wait for (failed store forwarding: 8% of the evaluation's time samples in
/// a loaded map sat on one such load).
#[derive(Clone, Copy, Debug, PartialEq)]
struct JointTag {
    gain: f64,
    index: usize,
    kind: JointKind,
    role: Role,
}

impl PlacedJoint {
    /// The joint's unit-rate twist seen at point `p`, times its gain.
    #[inline]
    fn twist_at(&self, p: &Vec3) -> Vec6 {
        let w = self.axis_world;
        let g = self.joint.gain;
        match self.joint.kind {
            JointKind::Revolute => {
                let lin = w.cross(&(p - self.origin_world));
                Vec6::new(lin.x * g, lin.y * g, lin.z * g, w.x * g, w.y * g, w.z * g)
            }
            JointKind::Prismatic => Vec6::new(w.x * g, w.y * g, w.z * g, 0.0, 0.0, 0.0),
        }
    }
}

/// The point loads (force f at x, moment m; base frame) beyond one joint of a chain, summed so that the
/// joint's generalised force and its Hessian entries read them once rather than once per load: the force
/// F = sum f, the moment about the base origin T = sum (m + x x f), and P = sum x f^T. A joint of origin o
/// then carries the moment T - o x F, and the bilinear sums of `add_load_hessian` are linear in P.
#[derive(Clone, Copy, Debug)]
struct LoadSum {
    force: Vec3,
    moment: Vec3,
    spread: Mat3,
}

impl LoadSum {
    const ZERO: LoadSum = LoadSum {
        force: Vec3::new(0.0, 0.0, 0.0),
        moment: Vec3::new(0.0, 0.0, 0.0),
        spread: Mat3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    };

    fn add_load(&mut self, x: &Vec3, f: &Vec3, m: &Vec3) {
        self.force += f;
        self.moment += m + x.cross(f);
        self.spread += x * f.transpose();
    }

    fn add(&mut self, other: &LoadSum) {
        self.force += other.force;
        self.moment += other.moment;
        self.spread += other.spread;
    }
}

/// What `ChainJacobians::add_pairs` needs of one joint with an unknown: the unknown's index, gain, kind and
/// world axis, the vector u of its pairs with the joints before it (they read `axis . u`), and the vectors
/// of its pairs with the joints at or after it, which read `motion_l . s_k`.
#[derive(Clone, Copy, Debug)]
struct HessianTerm {
    index: usize,
    gain: f64,
    revolute: bool,
    axis: Vec3,
    u: Vec3,
    motion: Vec3,
    s: Vec3,
}

/// A mass's place in the base frame during one evaluation, and how many joints lie before it.
#[derive(Clone, Copy, Debug)]
struct PlacedMass {
    kg: f64,
    point: Vec3,
    upstream: usize,
}

/// The end frame and the Jacobian columns of one evaluation; buffers are reused between calls.
#[derive(Clone, Debug, Default)]
pub struct ChainJacobians {
    /// The end frame.
    pub end: Frame,
    /// Twist columns of the actuated coordinates at the end point.
    pub actuated: Vec<Vec6>,
    /// Twist columns of the passive coordinates.
    pub passive: Vec<Vec6>,
    /// Filled by `fill_virtual`; empty until then (a read fails rather than finding stale numbers).
    pub virtual_: Vec<Vec6>,
    virtual_filled: bool,
    /// The chain's number of virtual coordinates, for `fill_virtual`.
    n_virtual: usize,
    placed: Vec<PlacedJoint>,
    masses: Vec<PlacedMass>,
    /// Each joint's last angle with its sine and cosine (NaN before the first).
    turns: Vec<(f64, f64, f64)>,
    /// Scratch of the load terms: the loads beyond each joint (`LoadSum`), in chain order, and the
    /// Hessian's per-joint vectors.
    load_sums: Vec<LoadSum>,
    hessian_terms: Vec<HessianTerm>,
    earlier_revolute: Vec<HessianTerm>,
}

/// Where a coordinate sits among the unknowns of an equilibrium: passive coordinates first, then virtual
/// ones; actuated coordinates are held fixed and have no place.
#[inline]
fn unknown_index(j: &JointTag, n_passive: usize) -> Option<usize> {
    match j.role {
        Role::Actuated => None,
        Role::Passive => Some(j.index),
        Role::Virtual => Some(n_passive + j.index),
    }
}

impl ChainJacobians {
    /// Generalised forces on the unknowns (passive, then virtual coordinates) of a wrench `w` (force,
    /// moment) acting on the chain's end and of the weights `kg * gravity` (N, gravity in m/s^2) of its
    /// masses: `J^T w + sum_j J_j^T G_j` (paper 000 eq 28-29). Added into `out`.
    pub fn add_generalised_forces(&self, w: &Vec6, gravity: &Vec3, n_passive: usize, out: &mut [f64]) {
        let (f, m) = (w.fixed_rows::<3>(0).into_owned(), w.fixed_rows::<3>(3).into_owned());
        let weighed = if *gravity == Vec3::zeros() { &[][..] } else { &self.masses[..] };
        self.add_forces(&self.end.pos, &f, &m, weighed, gravity, n_passive, out);
    }

    /// The generalised forces of a load (f at x, moment m) on the end and of the weights of `masses`
    /// (the chain's, in chain order), added into `out`: a revolute joint k of axis w_k through o_k takes
    /// w_k . (T_k - o_k x F_k), a prismatic one w_k . F_k, times its gain, where F_k and T_k (about the base
    /// origin) sum the loads beyond it, gathered from the chain's end back.
    #[allow(clippy::too_many_arguments)]
    fn add_forces(
        &self,
        x: &Vec3,
        f: &Vec3,
        m: &Vec3,
        masses: &[PlacedMass],
        gravity: &Vec3,
        n_passive: usize,
        out: &mut [f64],
    ) {
        let (mut force, mut moment) = (*f, m + x.cross(f));
        let mut next = masses.len();
        for (a, pj) in self.placed.iter().enumerate().rev() {
            while next > 0 && masses[next - 1].upstream > a {
                next -= 1;
                let weight = gravity * masses[next].kg;
                force += weight;
                moment += masses[next].point.cross(&weight);
            }
            let Some(k) = unknown_index(&pj.joint, n_passive) else { continue };
            let w = pj.axis_world;
            out[k] += pj.joint.gain
                * match pj.joint.kind {
                    JointKind::Revolute => w.dot(&(moment - pj.origin_world.cross(&force))),
                    JointKind::Prismatic => w.dot(&force),
                };
        }
    }

    /// Fills `load_sums` so that `load_sums[a + 1]` sums the loads the joint placed `a`-th in chain order
    /// carries: the wrench `w` on the end (every joint's) and the weights of the masses beyond it.
    fn sum_end_and_weights(&mut self, w: &Vec6, gravity: &Vec3) {
        let n = self.placed.len();
        let (f, m) = (w.fixed_rows::<3>(0).into_owned(), w.fixed_rows::<3>(3).into_owned());
        self.load_sums.clear();
        self.load_sums.resize(n + 1, LoadSum::ZERO);
        // Each load where its carriers end, then summed from the chain's end back.
        self.load_sums[n].add_load(&self.end.pos, &f, &m);
        for pm in &self.masses {
            self.load_sums[pm.upstream.min(n)].add_load(&pm.point, &(gravity * pm.kg), &Vec3::zeros());
        }
        for a in (1..n).rev() {
            let beyond = self.load_sums[a + 1];
            self.load_sums[a].add(&beyond);
        }
    }

    /// The loads on the actuated coordinates (N mm about a revolute joint, N along a prismatic one) of a
    /// wrench `w` on the chain's end and of its masses' weights: what the joints' drives and springs carry,
    /// `J_a^T w + sum_j J_aj^T G_j` (paper 000 eq 28-29 for the actuated columns). Added into `out`.
    pub fn add_actuated_loads(&self, w: &Vec6, gravity: &Vec3, out: &mut [f64]) {
        let (f, m) = (w.fixed_rows::<3>(0).into_owned(), w.fixed_rows::<3>(3).into_owned());
        let mut add = |x: &Vec3, f: &Vec3, m: &Vec3, upto: usize| {
            for pj in self.placed[..upto].iter().filter(|pj| pj.joint.role == Role::Actuated) {
                out[pj.joint.index] += pj.twist_at(x).dot(&Vec6::new(f.x, f.y, f.z, m.x, m.y, m.z));
            }
        };
        add(&self.end.pos, &f, &m, self.placed.len());
        if *gravity != Vec3::zeros() {
            for pm in &self.masses {
                add(&pm.point, &(gravity * pm.kg), &Vec3::zeros(), pm.upstream);
            }
        }
    }

    /// The wrench the chain's masses beyond each actuated coordinate's first joint put through that joint
    /// (force, and moment about the joint's origin; base frame): what the link leading to the joint carries.
    pub fn actuated_transmitted_weights(&self, gravity: &Vec3, n_actuated: usize) -> Vec<Vec6> {
        let mut out = vec![Vec6::zeros(); n_actuated];
        let mut seen = vec![false; n_actuated];
        for (p, pj) in self.placed.iter().enumerate() {
            if pj.joint.role != Role::Actuated || seen[pj.joint.index] {
                continue;
            }
            seen[pj.joint.index] = true;
            for pm in self.masses.iter().filter(|pm| pm.upstream > p) {
                let f = gravity * pm.kg;
                let m = (pm.point - pj.origin_world).cross(&f);
                out[pj.joint.index] += Vec6::new(f.x, f.y, f.z, m.x, m.y, m.z);
            }
        }
        out
    }

    /// Generalised forces of a force `f` (N, fixed in the base frame) at a point `x` carried by the chain's
    /// end (a payload's weight at its centre), added into `out` as `add_generalised_forces` does.
    pub fn add_point_force(&self, x: &Vec3, f: &Vec3, n_passive: usize, out: &mut [f64]) {
        self.add_forces(x, f, &Vec3::zeros(), &[], &Vec3::zeros(), n_passive, out);
    }

    /// The derivative of `add_point_force` with respect to the unknowns, as `add_load_hessian`'s.
    pub fn add_point_force_hessian(&mut self, x: &Vec3, f: &Vec3, n_passive: usize, out: &mut nalgebra::DMatrix<f64>) {
        self.add_one_load_hessian(x, f, &Vec3::zeros(), n_passive, out);
    }

    /// The derivative of `add_generalised_forces` with respect to the unknowns, the loads held fixed in the
    /// base frame: the Hessians H_qq, H_q theta, H_theta q, H_theta theta of paper 000 eq (41)-(44), exact
    /// for twist Jacobians (a joint moves the axes, origins and load points downstream of it). Added into
    /// `out`, square in the unknowns (rows: generalised force, columns: coordinate): the statics block of
    /// eq 45's Newton matrix takes them in place.
    pub fn add_load_hessian(&mut self, w: &Vec6, gravity: &Vec3, n_passive: usize, out: &mut nalgebra::DMatrix<f64>) {
        if *gravity == Vec3::zeros() || self.masses.is_empty() {
            // The end's wrench alone (a parallel robot's leg): its terms without the sums.
            let (f, m) = (w.fixed_rows::<3>(0).into_owned(), w.fixed_rows::<3>(3).into_owned());
            let x = self.end.pos;
            return self.add_one_load_hessian(&x, &f, &m, n_passive, out);
        }
        self.sum_end_and_weights(w, gravity);
        self.add_summed_hessian(n_passive, out);
    }

    /// The Hessian of one load (f at x, moment m) that every joint carries, added into `out`: the terms of
    /// `add_summed_hessian` for that load alone, u_k = w_k x (m + (x - o_k) x f) + (x - o_k) x (f x w_k)
    /// (revolute k; w_k x f prismatic), the later pairs' dx_l . s_k with s_k = f x w_k.
    fn add_one_load_hessian(
        &mut self,
        x: &Vec3,
        f: &Vec3,
        m: &Vec3,
        n_passive: usize,
        out: &mut nalgebra::DMatrix<f64>,
    ) {
        let mut terms = std::mem::take(&mut self.hessian_terms);
        terms.clear();
        terms.extend(self.placed.iter().filter_map(|p| {
            let index = unknown_index(&p.joint, n_passive)?;
            let w = p.axis_world;
            let revolute = p.joint.kind == JointKind::Revolute;
            let (motion, u, s) = if revolute {
                let arm = x - p.origin_world;
                let fxw = f.cross(&w);
                (w.cross(&arm), w.cross(&(m + arm.cross(f))) + arm.cross(&fxw), fxw)
            } else {
                (w, w.cross(f), Vec3::zeros())
            };
            Some(HessianTerm { index, gain: p.joint.gain, revolute, axis: w, u, motion, s })
        }));
        self.add_pairs(&terms, out);
        self.hessian_terms = terms;
    }

    /// The Hessian of the loads `sum_end_and_weights` summed, added into `out`.
    ///
    /// For one load (f at x, moment m) and a joint k, phi_k = w_k . (m + (x - o_k) x f) (revolute) or
    /// w_k . f (prismatic). A unit motion of joint l moves x by dx_l = w_l x (x - o_l) (revolute) or w_l
    /// (prismatic); if l comes before k it also turns w_k by w_l x w_k and carries o_k with x (revolute l):
    ///   l before k, l revolute:  dphi_k = w_l . u_k,  u_k = w_k x (m + (x - o_k) x f) + (x - o_k) x (f x w_k)
    ///                            (revolute k), u_k = w_k x f (prismatic k)
    ///   l before k, l prismatic: dphi_k = 0
    ///   l at or after k:         dphi_k = dx_l . (f x w_k) (revolute k), 0 (prismatic k).
    /// A pair reads the loads both joints carry, those beyond the later one. Summed over them with
    /// (a x b) . (c x d) = (a . c)(b . d) - (a . d)(b . c), both are linear in the sums F, T, P:
    ///   sum u_k = w_k x (T - o_k x F) + P^T w_k - (o_k . w_k) F - (tr P - o_k . F) w_k   (revolute k)
    ///   sum dx_l . (f x w_k) = v_l . w_k, v_l = P w_l - (w_l . F) o_l - (tr P - o_l . F) w_l (revolute l),
    ///                          v_l = w_l x F (prismatic l),
    /// so each pair costs one dot product whatever the number of loads.
    fn add_summed_hessian(&mut self, n_passive: usize, out: &mut nalgebra::DMatrix<f64>) {
        // Per joint with an unknown, in chain order, what its pairs read: once per joint, not per pair.
        let mut terms = std::mem::take(&mut self.hessian_terms);
        terms.clear();
        terms.extend(self.placed.iter().zip(&self.load_sums[1..]).filter_map(|(p, s)| {
            let index = unknown_index(&p.joint, n_passive)?;
            let (w, o, f) = (p.axis_world, p.origin_world, s.force);
            let revolute = p.joint.kind == JointKind::Revolute;
            let spread = s.spread.trace() - o.dot(&f);
            let (u, v) = if revolute {
                (
                    w.cross(&(s.moment - o.cross(&f))) + s.spread.tr_mul(&w) - f * o.dot(&w) - w * spread,
                    s.spread * w - o * w.dot(&f) - w * spread,
                )
            } else {
                (w.cross(&f), w.cross(&f))
            };
            Some(HessianTerm { index, gain: p.joint.gain, revolute, axis: w, u, motion: v, s: w })
        }));
        self.add_pairs(&terms, out);
        self.hessian_terms = terms;
    }

    /// Each pair's Hessian entry from the per-joint `terms` (in chain order), added into `out`: entry (k, l)
    /// of the column-major matrix at l * rows + k takes g_k g_l w_l . u_k for a revolute l before k and
    /// g_k g_l motion_l . s_k for l at or after a revolute k (v_l . w_k for summed loads). A pair whose term is zero (an earlier prismatic l;
    /// a prismatic k with a later l) adds nothing: the entries start at +0 and never become -0, so skipping
    /// it leaves the same bits; the revolute joints before k are kept apart as k goes on, so the zero pairs
    /// are skipped without a test each.
    fn add_pairs(&mut self, terms: &[HessianTerm], out: &mut nalgebra::DMatrix<f64>) {
        let rows = out.nrows();
        debug_assert!(terms.iter().all(|t| t.index < rows), "an unknown's index within the matrix");
        let entries = out.as_mut_slice();
        let mut earlier_revolute = std::mem::take(&mut self.earlier_revolute);
        earlier_revolute.clear();
        for (a, tk) in terms.iter().enumerate() {
            for tl in &earlier_revolute {
                entries[tl.index * rows + tk.index] += tk.gain * tl.gain * tl.axis.dot(&tk.u);
            }
            if tk.revolute {
                for tl in &terms[a..] {
                    entries[tl.index * rows + tk.index] += tk.gain * tl.gain * tl.motion.dot(&tk.s);
                }
                earlier_revolute.push(*tk);
            }
        }
        self.earlier_revolute = earlier_revolute;
    }

    /// Computes the Jacobian columns of the virtual coordinates from the last evaluation.
    pub fn fill_virtual(&mut self) {
        if self.virtual_filled {
            return;
        }
        reset(&mut self.virtual_, self.n_virtual);
        let p = self.end.pos;
        for pj in &self.placed {
            if pj.joint.role == Role::Virtual {
                self.virtual_[pj.joint.index] += pj.twist_at(&p);
            }
        }
        self.virtual_filled = true;
    }
}

/// A serial chain from the base frame to the leg's end frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Chain {
    elements: Vec<Element>,
    /// The elements as `evaluate` walks them.
    steps: Vec<Step>,
    /// Number of joints (elements with a coordinate).
    n_joints: usize,
    /// Number of actuated coordinates.
    pub n_actuated: usize,
    /// Number of passive coordinates.
    pub n_passive: usize,
    /// Number of virtual coordinates.
    pub n_virtual: usize,
    /// Per passive then virtual coordinate: it is a length (a prismatic joint's, mm), not an angle (rad).
    length_coordinates: Vec<bool>,
}

impl Chain {
    /// Builds a chain; consecutive fixed transforms are merged, since only joints carry coordinates.
    pub fn new(elements: Vec<Element>) -> Self {
        let mut merged: Vec<Element> = Vec::with_capacity(elements.len());
        let (mut na, mut np, mut nv) = (0, 0, 0);
        for e in elements {
            if let Element::Joint(j) = &e {
                let n = match j.role {
                    Role::Actuated => &mut na,
                    Role::Passive => &mut np,
                    Role::Virtual => &mut nv,
                };
                *n = (*n).max(j.index + 1);
            }
            match (merged.last_mut(), &e) {
                (Some(Element::Fixed(a)), Element::Fixed(b)) => *a = a.compose(b),
                _ => merged.push(e),
            }
        }
        let steps = merged.iter().map(Step::of).collect();
        let n_joints = merged.iter().filter(|e| matches!(e, Element::Joint(_))).count();
        let chain = Self {
            elements: merged,
            steps,
            n_joints,
            n_actuated: na,
            n_passive: np,
            n_virtual: nv,
            length_coordinates: Vec::new(),
        };
        chain.with_counts(na, np, nv)
    }

    /// A chain reading coordinates of a larger set (one chain of a tree, whose coordinates the tree's
    /// chains share): these counts, at least those its joints read.
    pub fn with_coordinates(elements: Vec<Element>, n_actuated: usize, n_passive: usize, n_virtual: usize) -> Self {
        let chain = Self::new(elements);
        let (na, np, nv) =
            (chain.n_actuated.max(n_actuated), chain.n_passive.max(n_passive), chain.n_virtual.max(n_virtual));
        chain.with_counts(na, np, nv)
    }

    /// The chain with these coordinate counts (at least those its joints read: coordinates that never
    /// appear may be counted too), and the kinds of its coordinates recorded for them.
    fn with_counts(mut self, n_actuated: usize, n_passive: usize, n_virtual: usize) -> Self {
        (self.n_actuated, self.n_passive, self.n_virtual) = (n_actuated, n_passive, n_virtual);
        let (passive, virtual_) = (self.kinds(Role::Passive), self.kinds(Role::Virtual));
        let is_length = |kinds: &[JointKind], i: usize| kinds.get(i) == Some(&JointKind::Prismatic);
        self.length_coordinates = (0..n_passive)
            .map(|i| is_length(&passive, i))
            .chain((0..n_virtual).map(|i| is_length(&virtual_, i)))
            .collect();
        self
    }

    /// Per passive then virtual coordinate: true where it is a length (mm), false where an angle (rad).
    pub fn length_coordinates(&self) -> &[bool] {
        &self.length_coordinates
    }

    /// The kind of each virtual joint, by virtual coordinate index.
    pub fn virtual_kinds(&self) -> Vec<JointKind> {
        self.kinds(Role::Virtual)
    }

    /// The kind of each joint of a role, by its coordinate index.
    pub fn kinds(&self, role: Role) -> Vec<JointKind> {
        let mut kinds = Vec::new();
        for e in &self.elements {
            if let Element::Joint(j) = e {
                if j.role == role {
                    if kinds.len() <= j.index {
                        kinds.resize(j.index + 1, JointKind::Revolute);
                    }
                    kinds[j.index] = j.kind;
                }
            }
        }
        kinds
    }

    /// Its elements, base first.
    pub fn elements(&self) -> &[Element] {
        &self.elements
    }

    /// The chain with a fixed transform in front of it (used to place a copy of a leg, and by the
    /// invariance tests to move a whole description rigidly).
    pub fn prepended(&self, frame: Frame) -> Chain {
        let mut e = vec![Element::Fixed(frame)];
        e.extend(self.elements.iter().cloned());
        // Coordinates that never appear keep their counts.
        Chain::new(e).with_counts(self.n_actuated, self.n_passive, self.n_virtual)
    }

    /// The chain followed by a fixed transform.
    pub fn appended(&self, frame: Frame) -> Chain {
        let mut e: Vec<Element> = self.elements.clone();
        e.push(Element::Fixed(frame));
        Chain::new(e).with_counts(self.n_actuated, self.n_passive, self.n_virtual)
    }

    /// The frame at each actuated coordinate's first joint, before its motion (base frame), at coordinates
    /// `c`: where a change of the fixed transform leading to that joint acts.
    pub fn actuated_joint_frames(&self, c: &Coordinates) -> Vec<Frame> {
        let mut frames = vec![None; self.n_actuated];
        self.walk(c, |j, f| {
            if j.role == Role::Actuated && frames[j.index].is_none() {
                frames[j.index] = Some(*f);
            }
        });
        frames.into_iter().map(|f| f.unwrap_or(Frame::IDENTITY)).collect()
    }

    /// Forward kinematics: the end frame for the given coordinates.
    pub fn end_frame(&self, c: &Coordinates) -> Frame {
        self.walk(c, |_, _| {})
    }

    /// The end frame, showing `at_joint` each joint and the frame just before its motion.
    #[inline(always)]
    fn walk(&self, c: &Coordinates, mut at_joint: impl FnMut(&Joint, &Frame)) -> Frame {
        let mut f = Frame::IDENTITY;
        for step in &self.steps {
            match step {
                Step::Translate(p) => f.pos += f.rot * p,
                Step::Transform(t) => f = f.compose(t),
                Step::Mass { .. } => {}
                Step::Joint { joint: j, principal, .. } => {
                    at_joint(j, &f);
                    let v = j.gain * c.get(j.role, j.index);
                    if v != 0.0 {
                        f = j.apply(&f, v, *principal);
                    }
                }
            }
        }
        f
    }

    /// Forward kinematics recording every joint's placement and the masses' points, without the Jacobian
    /// columns, which are left empty (a read of one fails rather than finding stale numbers): what the
    /// loaded equilibrium's residual reads (the generalised forces come from the placements), at each of its
    /// chord steps.
    pub fn place_joints(&self, c: &Coordinates, out: &mut ChainJacobians) {
        self.place_joints_only(c, out);
        out.actuated.clear();
        out.passive.clear();
        out.virtual_.clear();
        out.virtual_filled = false;
    }

    /// The placements and masses into `out` and its end frame, which is returned too (`evaluate` goes on
    /// from it to the columns).
    #[inline(always)]
    fn place_joints_only(&self, c: &Coordinates, out: &mut ChainJacobians) -> Frame {
        // Every joint's placement is written in place, in chain order: the buffer keeps its length between
        // evaluations of the same chain, so no push (a capacity test and a length store per joint) is made.
        let placeholder = PlacedJoint {
            joint: JointTag { gain: 0.0, index: 0, kind: JointKind::Revolute, role: Role::Actuated },
            axis_world: Vec3::zeros(),
            origin_world: Vec3::zeros(),
        };
        out.placed.resize(self.n_joints, placeholder);
        out.turns.resize(self.n_joints, (f64::NAN, 0.0, 1.0));
        out.masses.clear();
        let mut f = Frame::IDENTITY;
        let mut placed = 0;
        for step in &self.steps {
            match step {
                // Most fixed transforms are translations (link vectors): no rotation product for them.
                Step::Translate(p) => f.pos += f.rot * p,
                Step::Transform(t) => f = f.compose(t),
                Step::Mass { kg, centre } => {
                    out.masses.push(PlacedMass { kg: *kg, point: f.transform_point(centre), upstream: placed })
                }
                Step::Joint { joint: j, principal, tag, unit_axis } => {
                    let axis_world = match unit_axis {
                        Some(k) => f.rot.column(*k).into_owned(),
                        None => f.rot * j.axis,
                    };
                    out.placed[placed] = PlacedJoint { joint: *tag, axis_world, origin_world: f.pos };
                    placed += 1;
                    let v = j.gain * c.get(j.role, j.index);
                    if v != 0.0 {
                        f = match (j.kind, principal) {
                            // An actuated joint keeps its angle through an equilibrium's iterations: its
                            // sine and cosine are kept with it (libm's reduction of a large angle is a third
                            // of an evaluation).
                            (JointKind::Revolute, Some(k)) => {
                                let turn = &mut out.turns[placed - 1];
                                if turn.0 != v {
                                    let (s, c) = small_angle_sin_cos(v);
                                    *turn = (v, s, c);
                                }
                                turned_about_column(&f, *k, turn.1, turn.2)
                            }
                            _ => j.apply(&f, v, *principal),
                        };
                    }
                }
            }
        }
        out.end = f;
        f
    }

    /// Forward kinematics with the analytic Jacobians of the end point with respect to the actuated and
    /// passive coordinates. Every joint's placement is recorded, so the virtual columns can follow on
    /// demand (`ChainJacobians::fill_virtual`) without another pass: inverse kinematics needs them only at
    /// its solution.
    pub fn evaluate(&self, c: &Coordinates, out: &mut ChainJacobians) {
        let f = self.place_joints_only(c, out);
        reset(&mut out.actuated, self.n_actuated);
        reset(&mut out.passive, self.n_passive);
        // Zeroed where they are filled: most evaluations (inverse kinematics' iterates) never are.
        out.virtual_.clear();
        out.n_virtual = self.n_virtual;
        out.virtual_filled = false;
        for pj in &out.placed {
            let col = match pj.joint.role {
                Role::Actuated => &mut out.actuated[pj.joint.index],
                Role::Passive => &mut out.passive[pj.joint.index],
                Role::Virtual => continue,
            };
            *col += pj.twist_at(&f.pos);
        }
    }

    /// Sum of the lengths of the fixed translations: a size of the chain, used to weigh rotations
    /// against translations (mm per rad) in rank decisions and in inverse kinematics.
    pub fn length_scale(&self) -> f64 {
        self.elements
            .iter()
            .map(|e| match e {
                Element::Fixed(t) => t.pos.norm(),
                Element::Joint(_) | Element::Mass { .. } => 0.0,
            })
            .sum()
    }
}

fn reset(v: &mut Vec<Vec6>, n: usize) {
    v.clear();
    v.resize(n, Vec6::zeros());
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two finite values of the same sign.
    fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    /// The series that turns a virtual spring's joint is sin and cos to round-off: within one unit in the
    /// last place of libm's values over its whole range (libm is itself within one of the true values), on
    /// both sides of zero and down to angles whose cube is below the last bit (where sin x is x and cos x is
    /// 1 exactly), and libm's own values past the range.
    #[test]
    fn small_angle_sin_cos_is_libm_to_an_ulp() {
        let mut worst = (0u64, 0u64);
        for i in 0..=200_000 {
            let x = SMALL_ANGLE * (i as f64 / 100_000.0 - 1.0);
            for x in [x, x * 1e-3, x * 1e-6, x * 1e-9] {
                let (s, c) = small_angle_sin_cos(x);
                let (ls, lc) = x.sin_cos();
                if x == 0.0 {
                    assert_eq!((s, c), (x, 1.0));
                    continue;
                }
                worst = (worst.0.max(ulps(s, ls)), worst.1.max(ulps(c, lc)));
            }
        }
        assert!(worst.0 <= 1 && worst.1 <= 1, "sin, cos off libm by {worst:?} ulps");
        assert_eq!(small_angle_sin_cos(1e-9), (1e-9, 1.0));
        for x in [SMALL_ANGLE * 1.0001, -0.5, 3.0] {
            assert_eq!(small_angle_sin_cos(x), x.sin_cos());
        }
    }

    /// A leg's coordinates are lengths (mm) where a prismatic joint reads them and angles (rad) where a
    /// revolute one does: its distance from equilibrium weighs the lengths by the length scale
    /// (`Linearization::distance_from_equilibrium`). Passive then virtual, a coordinate read by two joints
    /// (a gain of -1) once, the actuated ones apart, and the counts a copy keeps (a coordinate no joint
    /// reads is an angle) with the marks.
    #[test]
    fn a_chains_length_coordinates_are_those_its_prismatic_joints_read() {
        let joint = |kind, role, index, gain| Element::Joint(Joint { kind, axis: Vec3::x(), role, index, gain });
        let (p, r) = (JointKind::Prismatic, JointKind::Revolute);
        let chain = Chain::new(vec![
            joint(p, Role::Actuated, 0, 1.0),
            Element::Fixed(Frame { rot: Mat3::identity(), pos: Vec3::new(100.0, 0.0, 0.0) }),
            joint(r, Role::Passive, 0, 1.0),
            joint(p, Role::Virtual, 0, 1.0),
            joint(p, Role::Passive, 1, 1.0),
            joint(r, Role::Virtual, 1, 1.0),
            joint(r, Role::Passive, 0, -1.0),
        ]);
        assert_eq!(chain.length_coordinates(), &[false, true, true, false]);
        let mut counted = chain.clone();
        counted.n_virtual = 3;
        let copy = counted.prepended(Frame::IDENTITY).appended(Frame::IDENTITY);
        assert_eq!(copy.length_coordinates(), &[false, true, true, false, false]);
    }
}

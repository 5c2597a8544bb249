//! A serial chain as an ordered product of fixed transforms and one-coordinate joints (paper 001 eq 1).
//!
//! Every coordinate of the VJM model is an elementary joint: actuated joints, passive joints and the
//! virtual springs alike (a 6-dof spring is Tx Ty Tz Rx Ry Rz about the axes of the frame where it sits).
//! The Jacobian column of a coordinate is the twist of its joint seen at the chain's end point, in the base
//! frame: a revolute joint of world axis w through o gives (w x (p_end - o), w), a prismatic one (w, 0).

use super::frame::{rotation_about, Frame, Vec3, Vec6};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    Revolute,
    Prismatic,
}

/// Which vector of coordinates a joint reads: actuated (fixed by inverse kinematics), passive (free, zero
/// reaction at equilibrium, paper 001 eq 7) or virtual (elastic, reaction K_theta theta, eq 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    Actuated,
    Passive,
    Virtual,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Joint {
    pub kind: JointKind,
    /// Unit axis in the joint's local frame.
    pub axis: Vec3,
    pub role: Role,
    pub index: usize,
    /// The joint value is `gain * coordinate` (a gain of -1 lets one coordinate drive two joints, as the
    /// parallelogram constraint q3 = -q2 of paper 001 eq 22 needs).
    pub gain: f64,
}

impl Joint {
    /// `f * motion(value)`: the frame after this joint moves by `value` (rad or mm) about or along its axis.
    /// Rotations about a principal axis only mix two columns, the common case on the hot path.
    #[inline]
    fn apply(&self, f: &Frame, value: f64) -> Frame {
        match self.kind {
            JointKind::Prismatic => Frame { rot: f.rot, pos: f.pos + f.rot * (self.axis * value) },
            JointKind::Revolute => {
                let principal = [self.axis.x, self.axis.y, self.axis.z].iter().position(|&c| c == 1.0);
                match principal {
                    Some(k) if self.axis.norm_squared() == 1.0 => {
                        let (s, c) = value.sin_cos();
                        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                        let (ci, cj) = (f.rot.column(i).into_owned(), f.rot.column(j).into_owned());
                        let mut rot = f.rot;
                        rot.set_column(i, &(ci * c + cj * s));
                        rot.set_column(j, &(cj * c - ci * s));
                        Frame { rot, pos: f.pos }
                    }
                    _ => Frame { rot: f.rot * rotation_about(&self.axis, value), pos: f.pos },
                }
            }
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum Element {
    Fixed(Frame),
    Joint(Joint),
}

/// Values of a chain's coordinates, by role.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Coordinates {
    pub actuated: Vec<f64>,
    pub passive: Vec<f64>,
    pub virtual_: Vec<f64>,
}

impl Coordinates {
    pub fn zeros(chain: &Chain) -> Self {
        Self {
            actuated: vec![0.0; chain.n_actuated],
            passive: vec![0.0; chain.n_passive],
            virtual_: vec![0.0; chain.n_virtual],
        }
    }

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
    joint: Joint,
    axis_world: Vec3,
    origin_world: Vec3,
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

/// The end frame and the Jacobian columns of one evaluation; buffers are reused between calls.
#[derive(Clone, Debug, Default)]
pub struct ChainJacobians {
    pub end: Frame,
    pub actuated: Vec<Vec6>,
    pub passive: Vec<Vec6>,
    /// Filled by `fill_virtual`; zero until then.
    pub virtual_: Vec<Vec6>,
    virtual_filled: bool,
    placed: Vec<PlacedJoint>,
}

impl ChainJacobians {
    /// Computes the Jacobian columns of the virtual coordinates from the last evaluation.
    pub fn fill_virtual(&mut self) {
        if self.virtual_filled {
            return;
        }
        let p = self.end.pos;
        for pj in &self.placed {
            if pj.joint.role == Role::Virtual {
                self.virtual_[pj.joint.index] += pj.twist_at(&p);
            }
        }
        self.virtual_filled = true;
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Chain {
    elements: Vec<Element>,
    pub n_actuated: usize,
    pub n_passive: usize,
    pub n_virtual: usize,
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
        Self { elements: merged, n_actuated: na, n_passive: np, n_virtual: nv }
    }

    pub fn elements(&self) -> &[Element] {
        &self.elements
    }

    /// The chain with a fixed transform in front of it (used to place a copy of a leg, and by the
    /// invariance tests to move a whole description rigidly).
    pub fn prepended(&self, frame: Frame) -> Chain {
        let mut e = vec![Element::Fixed(frame)];
        e.extend(self.elements.iter().cloned());
        let mut c = Chain::new(e);
        // Coordinates that never appear keep their counts.
        c.n_actuated = self.n_actuated;
        c.n_passive = self.n_passive;
        c.n_virtual = self.n_virtual;
        c
    }

    /// The chain followed by a fixed transform.
    pub fn appended(&self, frame: Frame) -> Chain {
        let mut e: Vec<Element> = self.elements.clone();
        e.push(Element::Fixed(frame));
        let mut c = Chain::new(e);
        c.n_actuated = self.n_actuated;
        c.n_passive = self.n_passive;
        c.n_virtual = self.n_virtual;
        c
    }

    /// Forward kinematics: the end frame for the given coordinates.
    pub fn end_frame(&self, c: &Coordinates) -> Frame {
        let mut f = Frame::IDENTITY;
        for e in &self.elements {
            match e {
                Element::Fixed(t) => f = f.compose(t),
                Element::Joint(j) => {
                    let v = j.gain * c.get(j.role, j.index);
                    if v != 0.0 {
                        f = j.apply(&f, v);
                    }
                }
            }
        }
        f
    }

    /// Forward kinematics with the analytic Jacobians of the end point with respect to the actuated and
    /// passive coordinates. Every joint's placement is recorded, so the virtual columns can follow on
    /// demand (`ChainJacobians::fill_virtual`) without another pass: inverse kinematics needs them only at
    /// its solution.
    pub fn evaluate(&self, c: &Coordinates, out: &mut ChainJacobians) {
        out.placed.clear();
        let mut f = Frame::IDENTITY;
        for e in &self.elements {
            match e {
                Element::Fixed(t) => f = f.compose(t),
                Element::Joint(j) => {
                    out.placed.push(PlacedJoint { joint: *j, axis_world: f.rot * j.axis, origin_world: f.pos });
                    let v = j.gain * c.get(j.role, j.index);
                    if v != 0.0 {
                        f = j.apply(&f, v);
                    }
                }
            }
        }
        out.end = f;
        reset(&mut out.actuated, self.n_actuated);
        reset(&mut out.passive, self.n_passive);
        reset(&mut out.virtual_, self.n_virtual);
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
                Element::Joint(_) => 0.0,
            })
            .sum()
    }
}

fn reset(v: &mut Vec<Vec6>, n: usize) {
    v.clear();
    v.resize(n, Vec6::zeros());
}

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
    #[inline]
    fn motion(&self, value: f64) -> Frame {
        match self.kind {
            JointKind::Revolute => Frame::rotation(rotation_about(&self.axis, value)),
            JointKind::Prismatic => Frame::translation(self.axis * value),
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

/// The end frame and the Jacobian columns of one evaluation; buffers are reused between calls.
#[derive(Clone, Debug, Default)]
pub struct ChainJacobians {
    pub end: Frame,
    pub actuated: Vec<Vec6>,
    pub passive: Vec<Vec6>,
    pub virtual_: Vec<Vec6>,
    placed: Vec<PlacedJoint>,
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
        Self {
            elements: merged,
            n_actuated: na,
            n_passive: np,
            n_virtual: nv,
        }
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
                        f = f.compose(&j.motion(v));
                    }
                }
            }
        }
        f
    }

    /// Forward kinematics with the analytic Jacobians of the end point with respect to every coordinate
    /// (columns of the virtual coordinates only when `with_virtual`).
    pub fn evaluate(&self, c: &Coordinates, with_virtual: bool, out: &mut ChainJacobians) {
        out.placed.clear();
        let mut f = Frame::IDENTITY;
        for e in &self.elements {
            match e {
                Element::Fixed(t) => f = f.compose(t),
                Element::Joint(j) => {
                    if with_virtual || j.role != Role::Virtual {
                        out.placed.push(PlacedJoint {
                            joint: *j,
                            axis_world: f.rot * j.axis,
                            origin_world: f.pos,
                        });
                    }
                    let v = j.gain * c.get(j.role, j.index);
                    if v != 0.0 {
                        f = f.compose(&j.motion(v));
                    }
                }
            }
        }
        out.end = f;
        reset(&mut out.actuated, self.n_actuated);
        reset(&mut out.passive, self.n_passive);
        reset(
            &mut out.virtual_,
            if with_virtual { self.n_virtual } else { 0 },
        );
        let p_end = f.pos;
        for pj in &out.placed {
            let w = pj.axis_world;
            let twist = match pj.joint.kind {
                JointKind::Revolute => {
                    let lin = w.cross(&(p_end - pj.origin_world));
                    Vec6::new(lin.x, lin.y, lin.z, w.x, w.y, w.z)
                }
                JointKind::Prismatic => Vec6::new(w.x, w.y, w.z, 0.0, 0.0, 0.0),
            };
            let col = match pj.joint.role {
                Role::Actuated => &mut out.actuated[pj.joint.index],
                Role::Passive => &mut out.passive[pj.joint.index],
                Role::Virtual => &mut out.virtual_[pj.joint.index],
            };
            *col += twist * pj.joint.gain;
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

//! An MSA structure whose geometry follows the pose (paper 003 s. 3.2-3.3): node positions and joint axes
//! are formulas over per-pose quantities (leg length and angle by eq 18-19, pantograph angle by eq 21-22),
//! themselves formulas of the leg's end point. Built once from the description (formulas parsed once),
//! evaluated into a `Structure` at every pose.

use nalgebra::{DMatrix, DVector};

use super::{oriented_beam_stiffness, Connection, Element, Structure};
use crate::beam::BeamSection;
use crate::expr::Expr;
use crate::kinematics::frame::{block_rotation, rotation_vector, Frame, Mat6, Vec3, Vec6};

/// Slots 0..6 of every evaluation: the leg's end point and its orientation (rotation vector), in the leg's
/// own frame (before the copy that places the leg).
pub const END_VARIABLES: [&str; 6] = ["end_x", "end_y", "end_z", "end_rx", "end_ry", "end_rz"];

/// A direction that follows the pose: a unit twist (translation part, rotation part) of formulas.
#[derive(Clone, Debug)]
pub struct DirectionTemplate {
    /// The direction's six components (dx, dy, dz, rx, ry, rz), formulas of the pose.
    pub twist: [Expr; 6],
}

/// An element of an MSA leg, its geometry as formulas evaluated at each pose.
#[derive(Clone, Debug)]
pub enum ElementTemplate {
    /// A beam between two nodes; its section's y axis across the beam, if given.
    Beam {
        /// First node.
        i: usize,
        /// Second node.
        j: usize,
        /// The beam's section and material.
        section: BeamSection,
        /// The section's y axis (for sections with Iy != Iz).
        y_axis: Option<[Expr; 3]>,
    },
    /// A link given by its stiffness at j with i clamped (leg frame, at j).
    Link {
        /// First node (clamped).
        i: usize,
        /// Second node.
        j: usize,
        /// Stiffness at j with i clamped (leg frame).
        kjj: Mat6,
    },
    /// A rigid link from node i to node j (paper 003 eq 3-5).
    Rigid {
        /// The node carried from.
        i: usize,
        /// The node carried.
        j: usize,
    },
    /// A connection (i = None: to the base) with free and elastic directions.
    Joint {
        /// First node (None: the base).
        i: Option<usize>,
        /// Second node (where the joint sits).
        j: usize,
        /// Free directions (passive motions).
        free: Vec<DirectionTemplate>,
        /// Elastic directions.
        elastic: Vec<DirectionTemplate>,
        /// Stiffness on the elastic directions.
        stiffness: DMatrix<f64>,
        /// Rest values of the elastic directions.
        preload: DVector<f64>,
    },
}

/// An MSA leg as written: formulas evaluated at each pose into a `Structure`.
#[derive(Clone, Debug)]
pub struct Template {
    /// Per-pose quantities in evaluation order (each may use the end variables and earlier ones); the
    /// value of `pose[k]` goes to slot 6 + k.
    pub pose: Vec<Expr>,
    /// Each must be >= 0 at a reachable pose (eq 20).
    pub reach: Vec<Expr>,
    /// Node positions (formulas), leg frame.
    pub nodes: Vec<[Expr; 3]>,
    /// Node names, for messages.
    pub node_names: Vec<String>,
    /// The end node.
    pub end: usize,
    /// The elements.
    pub elements: Vec<ElementTemplate>,
}

/// Why a template gives no structure at a pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PoseOutOfReach {
    /// A reach condition is negative (its index).
    Condition(usize),
    /// A per-pose quantity or a node position is not a finite number there (e.g. acos of more than 1).
    NotFinite,
    /// The geometry has values but a beam has no finite stiffness there (zero length, or a length or
    /// section at the edge of doubles).
    Degenerate,
}

impl Template {
    /// True when no elastic joint is preloaded: the leg carries no load where it was placed.
    pub fn unloaded(&self) -> bool {
        self.elements.iter().all(|e| match e {
            ElementTemplate::Joint { preload, .. } => preload.iter().all(|p| *p == 0.0),
            _ => true,
        })
    }

    /// The structure at a pose: `end` is the leg's end frame in the leg's own frame, `place` the copy's frame
    /// (leg frame -> base frame); the structure comes out in the base frame.
    pub fn structure(&self, end: &Frame, place: &Frame, slots: &mut Vec<f64>) -> Result<Structure, PoseOutOfReach> {
        let mut structure = Structure::default();
        self.fill(end, place, slots, &mut structure)?;
        Ok(structure)
    }

    /// As `structure`, written over `out`, whose vectors are reused (a map fills one structure per leg
    /// without allocating once it has this template's shape). On an error `out` is left part-filled.
    pub fn fill(
        &self,
        end: &Frame,
        place: &Frame,
        slots: &mut Vec<f64>,
        out: &mut Structure,
    ) -> Result<(), PoseOutOfReach> {
        slots.clear();
        slots.extend(end.pos.iter());
        slots.extend(rotation_vector(&end.rot).iter());
        for e in &self.pose {
            let v = e.eval(slots);
            slots.push(v);
        }
        // The reach conditions first: they say why a pose is out of reach better than the NaN of a
        // quantity that has no value there (acos of more than 1).
        for (k, r) in self.reach.iter().enumerate() {
            if r.eval(slots) < 0.0 {
                return Err(PoseOutOfReach::Condition(k));
            }
        }
        if !slots.iter().all(|v| v.is_finite()) {
            return Err(PoseOutOfReach::NotFinite);
        }
        let point = |p: &[Expr; 3]| Vec3::new(p[0].eval(slots), p[1].eval(slots), p[2].eval(slots));
        let nodes = &mut out.nodes;
        nodes.clear();
        for p in &self.nodes {
            let local = point(p);
            if !local.iter().all(|v| v.is_finite()) {
                return Err(PoseOutOfReach::NotFinite);
            }
            nodes.push(place.transform_point(&local));
        }
        out.end = self.end;
        let rot6 = block_rotation(&place.rot);
        let direction = |d: &DirectionTemplate| -> Result<Vec6, PoseOutOfReach> {
            let v = Vec6::from_fn(|r, _| d.twist[r].eval(slots));
            let n = v.norm();
            if !(n > 0.0 && n.is_finite()) {
                return Err(PoseOutOfReach::NotFinite);
            }
            Ok(rot6 * (v / n))
        };
        out.elements.truncate(self.elements.len());
        for (k, e) in self.elements.iter().enumerate() {
            let element = match e {
                ElementTemplate::Beam { i, j, section, y_axis } => {
                    let hint = y_axis.as_ref().map(|y| place.rot * point(y));
                    let kjj = oriented_beam_stiffness(section, &nodes[*i], &nodes[*j], hint)
                        .ok_or(PoseOutOfReach::Degenerate)?;
                    // Written where the slot holds a flexible link already, as a joint's connection is.
                    if let Some(Element::Flexible { i: held_i, j: held_j, kjj: held }) = out.elements.get_mut(k) {
                        (*held_i, *held_j, *held) = (*i, *j, kjj);
                        continue;
                    }
                    Element::Flexible { i: *i, j: *j, kjj }
                }
                ElementTemplate::Link { i, j, kjj } => {
                    Element::Flexible { i: *i, j: *j, kjj: rot6 * kjj * rot6.transpose() }
                }
                ElementTemplate::Rigid { i, j } => Element::Rigid { i: *i, j: *j },
                ElementTemplate::Joint { i, j, free, elastic, stiffness, preload } => {
                    // Refilled in place where this slot held the same kind of connection at the last pose
                    // (its vectors reused, nothing moved), made anew otherwise.
                    if out.elements.len() == k {
                        out.elements.push(Element::Rigid { i: 0, j: 0 });
                    }
                    let slot = &mut out.elements[k];
                    match (i, &mut *slot) {
                        (Some(i), Element::Joint { i: held_i, j: held_j, .. }) => (*held_i, *held_j) = (*i, *j),
                        (None, Element::Base { node, .. }) => *node = *j,
                        (Some(i), slot) => *slot = Element::Joint { i: *i, j: *j, connection: Connection::rigid() },
                        (None, slot) => *slot = Element::Base { node: *j, connection: Connection::rigid() },
                    }
                    let (Element::Joint { connection, .. } | Element::Base { connection, .. }) = slot else {
                        unreachable!("the slot holds a joint now")
                    };
                    connection.free.clear();
                    for d in free {
                        connection.free.push(direction(d)?);
                    }
                    connection.elastic.clear();
                    for d in elastic {
                        connection.elastic.push(direction(d)?);
                    }
                    if connection.stiffness.shape() == stiffness.shape() && connection.preload.len() == preload.len() {
                        connection.stiffness.copy_from(stiffness);
                        connection.preload.copy_from(preload);
                    } else {
                        connection.stiffness = stiffness.clone();
                        connection.preload = preload.clone();
                    }
                    continue;
                }
            };
            match out.elements.get_mut(k) {
                Some(slot) => *slot = element,
                None => out.elements.push(element),
            }
        }
        Ok(())
    }
}

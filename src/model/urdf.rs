//! URDF (the Unified Robot Description Format of ROS, MoveIt, Pinocchio and Drake) for a chain's
//! kinematics and its links' weight: the path of joints from a root link to a tip link (the file may be a
//! tree), each joint's fixed origin, axis and type, `<mimic>` joints following their master, and each
//! link's `<inertial>` mass and centre. URDF is in metres and kilograms; what this module returns is in the
//! model's millimetres (masses stay in kilograms, weighed by the model's gravity). XML is read with
//! roxmltree; every error names the file, the line and the link or joint.

use std::path::{Path, PathBuf};

use super::error::InputError;
use crate::kinematics::frame::{Frame, Mat3, Vec3};

/// Millimetres per metre: URDF lengths are converted once, when they are read.
const MM_PER_M: f64 = 1000.0;

/// How a URDF joint moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UrdfJointKind {
    /// `revolute` or `continuous`: a rotation about the axis.
    Revolute,
    /// `prismatic`: a translation along the axis.
    Prismatic,
    /// `fixed`: folded into the transforms.
    Fixed,
}

/// A joint on the path, as the chain needs it.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfJoint {
    /// Its name.
    pub name: String,
    /// Revolute, prismatic or fixed.
    pub kind: UrdfJointKind,
    /// The joint frame in its parent link's frame (mm).
    pub origin: Frame,
    /// Unit axis in the joint frame.
    pub axis: Vec3,
    /// `<mimic joint= multiplier= offset=>`: the master's name, the multiplier and the offset (rad or mm).
    pub mimic: Option<(String, f64, f64)>,
    /// The child link's mass (kg) and centre in the joint frame (mm), where it has an `<inertial>`.
    pub child_mass: Option<(f64, Vec3)>,
    /// The child link's name.
    pub child: String,
}

/// The chain from a root link to a tip link of a URDF file.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfChain {
    /// The joints from root to tip.
    pub joints: Vec<UrdfJoint>,
    /// The root link's own mass, if any (it does not move: it weighs on the base, not on the chain).
    pub root_mass: Option<(f64, Vec3)>,
}

struct Reader<'a> {
    path: &'a Path,
    doc: &'a roxmltree::Document<'a>,
}

impl Reader<'_> {
    fn at(&self, node: roxmltree::Node, message: String) -> InputError {
        let pos = self.doc.text_pos_at(node.range().start);
        InputError::At { path: self.path.to_path_buf(), line: pos.row as usize, column: pos.col as usize, message }
    }

    /// A number attribute's values (`xyz="0 0 1"`), `count` of them, finite.
    fn numbers(
        &self,
        node: roxmltree::Node,
        attribute: &str,
        count: usize,
        default: f64,
    ) -> Result<Vec<f64>, InputError> {
        let Some(text) = node.attribute(attribute) else { return Ok(vec![default; count]) };
        let values: Vec<f64> = text
            .split_whitespace()
            .map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<_>>()
            .ok_or_else(|| self.at(node, format!("`{attribute}=\"{text}\"` is not {count} finite numbers")))?;
        if values.len() != count {
            return Err(self.at(node, format!("`{attribute}=\"{text}\"` needs {count} numbers, got {}", values.len())));
        }
        Ok(values)
    }

    /// An `<origin xyz= rpy=>` child of `node` as a frame in mm (identity where absent).
    fn origin(&self, node: roxmltree::Node) -> Result<Frame, InputError> {
        let Some(o) = child(node, "origin") else { return Ok(Frame::IDENTITY) };
        let xyz = self.numbers(o, "xyz", 3, 0.0)?;
        let rpy = self.numbers(o, "rpy", 3, 0.0)?;
        Ok(Frame { rot: rpy_matrix(rpy[0], rpy[1], rpy[2]), pos: Vec3::new(xyz[0], xyz[1], xyz[2]) * MM_PER_M })
    }
}

/// URDF's roll-pitch-yaw: fixed-axis rotations about x, then y, then z: R = Rz(yaw) Ry(pitch) Rx(roll).
pub fn rpy_matrix(roll: f64, pitch: f64, yaw: f64) -> Mat3 {
    use crate::kinematics::frame::rotation_about;
    rotation_about(&Vec3::z(), yaw) * rotation_about(&Vec3::y(), pitch) * rotation_about(&Vec3::x(), roll)
}

fn child<'a, 'input>(node: roxmltree::Node<'a, 'input>, name: &str) -> Option<roxmltree::Node<'a, 'input>> {
    node.children().find(|c| c.has_tag_name(name))
}

/// Reads the chain from `root` to `tip` of the URDF file `path` (its text `text`).
pub fn read_chain(path: &Path, text: &str, root: &str, tip: &str) -> Result<UrdfChain, InputError> {
    let doc = roxmltree::Document::parse(text)
        .map_err(|e| InputError::Syntax { path: path.to_path_buf(), message: format!("not a URDF (XML) file: {e}") })?;
    let r = Reader { path, doc: &doc };
    let robot = doc.root_element();
    if !robot.has_tag_name("robot") {
        return Err(r.at(robot, format!("the root element is <{}>, not <robot>", robot.tag_name().name())));
    }
    let links: Vec<roxmltree::Node> = robot.children().filter(|c| c.has_tag_name("link")).collect();
    let joints: Vec<roxmltree::Node> = robot.children().filter(|c| c.has_tag_name("joint")).collect();
    let name_of = |n: roxmltree::Node| n.attribute("name").unwrap_or("").to_string();
    for n in links.iter().chain(&joints) {
        if name_of(*n).is_empty() {
            return Err(r.at(*n, format!("a <{}> without a name", n.tag_name().name())));
        }
    }
    let link = |name: &str| links.iter().copied().find(|l| name_of(*l) == name);
    let known = |name: &str| -> Result<(), InputError> {
        if link(name).is_some() {
            Ok(())
        } else {
            let names: Vec<String> = links.iter().map(|l| name_of(*l)).collect();
            Err(InputError::Whole {
                path: path.to_path_buf(),
                message: format!("no link named `{name}` (links: {})", names.join(", ")),
            })
        }
    };
    known(root)?;
    known(tip)?;
    // Each joint's parent and child links.
    let mut edges: Vec<(roxmltree::Node, String, String)> = Vec::new();
    for j in &joints {
        let end = |which: &str| -> Result<String, InputError> {
            let name = child(*j, which).and_then(|c| c.attribute("link")).unwrap_or("");
            if name.is_empty() {
                return Err(r.at(*j, format!("joint `{}` has no <{which} link=...>", name_of(*j))));
            }
            if link(name).is_none() {
                return Err(r.at(*j, format!("joint `{}`: its {which} link `{name}` is not in the file", name_of(*j))));
            }
            Ok(name.to_string())
        };
        edges.push((*j, end("parent")?, end("child")?));
    }
    // The path from the tip up to the root: every link has at most one parent joint in a tree.
    let mut path_joints = Vec::new();
    let mut at = tip.to_string();
    while at != root {
        let parents: Vec<&(roxmltree::Node, String, String)> = edges.iter().filter(|(_, _, c)| *c == at).collect();
        match parents.as_slice() {
            [] => {
                return Err(InputError::Whole {
                    path: path.to_path_buf(),
                    message: format!("links `{root}` and `{tip}` are not connected: `{at}` has no parent joint and is not `{root}` (is `{tip}` below `{root}`?)"),
                })
            }
            [one] => {
                if path_joints.len() > edges.len() {
                    return Err(r.at(one.0, "the joints form a loop: URDF describes a tree".into()));
                }
                path_joints.push(*one);
                at = one.1.clone();
            }
            _ => {
                return Err(r.at(parents[1].0, format!("link `{at}` has two parent joints: URDF describes a tree")));
            }
        }
    }
    path_joints.reverse();
    let inertial = |name: &str| -> Result<Option<(f64, Vec3)>, InputError> {
        let Some(l) = link(name) else { return Ok(None) };
        let Some(i) = child(l, "inertial") else { return Ok(None) };
        let mass_node = child(i, "mass").ok_or_else(|| r.at(i, format!("link `{name}`: <inertial> without <mass>")))?;
        let kg = r.numbers(mass_node, "value", 1, f64::NAN)?[0];
        if kg < 0.0 {
            return Err(r.at(mass_node, format!("link `{name}`: the mass must be a number >= 0 kg")));
        }
        Ok((kg > 0.0).then_some((kg, r.origin(i)?.pos)))
    };
    let mut out = Vec::with_capacity(path_joints.len());
    for (j, _, child_link) in &path_joints {
        let name = name_of(*j);
        let kind = match j.attribute("type").unwrap_or("") {
            "revolute" | "continuous" => UrdfJointKind::Revolute,
            "prismatic" => UrdfJointKind::Prismatic,
            "fixed" => UrdfJointKind::Fixed,
            other @ ("floating" | "planar") => {
                return Err(r.at(
                    *j,
                    format!(
                    "joint `{name}` is `{other}`: only revolute, continuous, prismatic and fixed joints make a chain"
                ),
                ))
            }
            other => return Err(r.at(*j, format!("joint `{name}` has the unknown type `{other}`"))),
        };
        let axis = match child(*j, "axis") {
            // A fixed joint does not move: its axis is never read (descriptions in use write `0 0 0` there).
            _ if kind == UrdfJointKind::Fixed => Vec3::x(),
            Some(a) => {
                let v = r.numbers(a, "xyz", 3, 0.0)?;
                let v = Vec3::new(v[0], v[1], v[2]);
                if v.norm() == 0.0 {
                    return Err(r.at(a, format!("joint `{name}`: the axis must not be zero")));
                }
                v.normalize()
            }
            None => Vec3::x(),
        };
        let mimic = match child(*j, "mimic") {
            Some(m) => {
                let master = m.attribute("joint").unwrap_or("").to_string();
                if master.is_empty() {
                    return Err(r.at(m, format!("joint `{name}`: <mimic> needs `joint`")));
                }
                Some((master, r.numbers(m, "multiplier", 1, 1.0)?[0], r.numbers(m, "offset", 1, 0.0)?[0]))
            }
            None => None,
        };
        let offset_unit = if kind == UrdfJointKind::Prismatic { MM_PER_M } else { 1.0 };
        let mimic = mimic.map(|(m, k, o)| (m, k, o * offset_unit));
        let child = child_link.clone();
        out.push(UrdfJoint {
            name,
            kind,
            origin: r.origin(*j)?,
            axis,
            mimic,
            child_mass: inertial(child_link)?,
            child,
        });
    }
    Ok(UrdfChain { joints: out, root_mass: inertial(root)? })
}

/// The URDF file a description names, relative to the description's folder.
pub fn resolve(description: &Path, file: &str) -> PathBuf {
    description.parent().unwrap_or(Path::new(".")).join(file)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// URDF's rpy is fixed-axis x-y-z (ROS REP 103): a pure yaw turns x to y, and roll then pitch equals
    /// the product Ry(pitch) Rx(roll).
    #[test]
    fn rpy_is_fixed_axis_roll_pitch_yaw() {
        let r = rpy_matrix(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        assert!((r * Vec3::x() - Vec3::y()).norm() < 1e-15);
        let (a, b) = (0.3, -0.7);
        use crate::kinematics::frame::rotation_about;
        let want = rotation_about(&Vec3::y(), b) * rotation_about(&Vec3::x(), a);
        assert!((rpy_matrix(a, b, 0.0) - want).norm() < 1e-15);
    }
}

//! URDF (the Unified Robot Description Format of ROS, MoveIt, Pinocchio and Drake) for a chain's
//! kinematics and the weight it carries: the path of joints from a root link to a tip link of the tree,
//! each joint's fixed origin, axis, type and limits, `<mimic>` joints following their master (which may be
//! off the path), and the mass each link of the chain carries: its own `<inertial>` and every body
//! attached to it off the path (through fixed joints, or through moving joints held at their URDF zero:
//! branches, and everything beyond the tip), lumped as one rigid body. URDF is in metres and kilograms;
//! what this module returns is in the model's millimetres (masses stay in kilograms). XML is read with
//! roxmltree; every error names the file, the line and the link or joint. Reading is linear in the file's
//! size (a map from each link to its parent joint and its child joints).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::error::InputError;
use crate::kinematics::frame::{rotation_about, Frame, Mat3, Vec3};

/// Millimetres per metre: URDF lengths are converted once, when they are read.
const MM_PER_M: f64 = 1000.0;

/// Largest length (m) an origin, a centre of mass or a prismatic limit may have: ten kilometres is no
/// robot, and past it a number is a typo or a fuzzed value whose products overflow downstream.
const MAX_LENGTH_M: f64 = 1e4;

/// Largest magnitude of an angle (rad), an axis component, a multiplier or an offset.
const MAX_PLAIN: f64 = 1e6;

/// Largest mass of one link (kg).
const MAX_MASS_KG: f64 = 1e6;

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

/// A joint of the chain (or a master a joint of the chain mimics), as the chain needs it.
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
    /// `<limit lower= upper=>` (rad, or mm for a prismatic joint), where both are given and differ.
    pub limits: Option<(f64, f64)>,
    /// The mass the child link carries (kg) and its centre in the joint frame (mm): the link's own
    /// `<inertial>` and every body attached to it off the path, lumped; None where that is no mass.
    pub child_mass: Option<(f64, Vec3)>,
    /// The child link's name.
    pub child: String,
}

/// How the tree's mass is shared (kg): what the chain's links carry, the part of it that hangs off the
/// root-to-tip path (branches, bodies beyond the tip), and what weighs on the base (the root link and
/// everything attached to it off the path, and links not below the root).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MassShare {
    /// Carried by the chain's moving links, kg.
    pub carried: f64,
    /// Of `carried`, on bodies off the path, kg.
    pub off_path: f64,
    /// On the base (not carried by any joint of the chain), kg.
    pub on_base: f64,
}

/// The chain from a root link to a tip link of a URDF file.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfChain {
    /// The joints from root to tip.
    pub joints: Vec<UrdfJoint>,
    /// Moving joints off the path that a joint of the path mimics (directly or through other mimics): their
    /// coordinates are coordinates of the model too.
    pub masters: Vec<UrdfJoint>,
    /// The mass the root link carries, if any (it does not move: it weighs on the base, not on the chain).
    pub root_mass: Option<(f64, Vec3)>,
    /// How the tree's mass is shared.
    pub masses: MassShare,
}

/// A body's mass (kg) and first moment m c (kg mm) in some frame: lumped bodies add.
#[derive(Clone, Copy, Debug, Default)]
struct Body {
    kg: f64,
    moment: Vec3,
}

impl Body {
    fn plus(self, other: Body) -> Body {
        Body { kg: self.kg + other.kg, moment: self.moment + other.moment }
    }

    /// The same body seen from the frame in which `f` places the body's frame.
    fn moved(self, f: &Frame) -> Body {
        Body { kg: self.kg, moment: f.rot * self.moment + f.pos * self.kg }
    }

    /// Its mass and centre, where it has a mass.
    fn as_mass(self) -> Option<(f64, Vec3)> {
        (self.kg > 0.0).then(|| (self.kg, self.moment / self.kg))
    }
}

/// A joint of the file, read whole (every joint is checked, on the path or not).
struct ReadJoint<'a, 'input> {
    node: roxmltree::Node<'a, 'input>,
    name: String,
    /// Its kind, or the type's name where it is one a chain cannot have (floating, planar).
    kind: Result<UrdfJointKind, String>,
    origin: Frame,
    axis: Vec3,
    mimic: Option<(String, f64, f64)>,
    limits: Option<(f64, f64)>,
    parent: usize,
    child: usize,
}

impl ReadJoint<'_, '_> {
    /// The joint's frame moved by `value` (rad or mm) from its origin.
    fn at(&self, value: f64) -> Frame {
        match self.kind {
            Ok(UrdfJointKind::Revolute) => {
                self.origin.compose(&Frame::new(rotation_about(&self.axis, value), Vec3::zeros()))
            }
            Ok(UrdfJointKind::Prismatic) => self.origin.compose(&Frame::translation(self.axis * value)),
            _ => self.origin,
        }
    }

    fn as_chain_joint(&self, kind: UrdfJointKind, child_mass: Option<(f64, Vec3)>, child: String) -> UrdfJoint {
        UrdfJoint {
            name: self.name.clone(),
            kind,
            origin: self.origin,
            axis: self.axis,
            mimic: self.mimic.clone(),
            limits: self.limits,
            child_mass,
            child,
        }
    }
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

    fn line_of(&self, node: roxmltree::Node) -> u32 {
        self.doc.text_pos_at(node.range().start).row
    }

    /// A number attribute's values (`xyz="0 0 1"`), `count` of them, finite and at most `largest` in
    /// magnitude.
    fn numbers(
        &self,
        node: roxmltree::Node,
        attribute: &str,
        count: usize,
        default: f64,
        largest: f64,
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
        if let Some(v) = values.iter().find(|v| v.abs() > largest) {
            return Err(self
                .at(node, format!("`{attribute}=\"{text}\"`: {v} is past the largest value read here, {largest:e}")));
        }
        Ok(values)
    }

    /// An `<origin xyz= rpy=>` child of `node` as a frame in mm (identity where absent).
    fn origin(&self, node: roxmltree::Node) -> Result<Frame, InputError> {
        let Some(o) = child(node, "origin") else { return Ok(Frame::IDENTITY) };
        let xyz = self.numbers(o, "xyz", 3, 0.0, MAX_LENGTH_M)?;
        let rpy = self.numbers(o, "rpy", 3, 0.0, MAX_PLAIN)?;
        Ok(Frame { rot: rpy_matrix(rpy[0], rpy[1], rpy[2]), pos: Vec3::new(xyz[0], xyz[1], xyz[2]) * MM_PER_M })
    }

    /// A link's `<inertial>`: its mass and first moment in the link's frame (none where absent); the
    /// inertia's numbers, where given, must be finite.
    fn inertial(&self, link: roxmltree::Node, name: &str) -> Result<Body, InputError> {
        let Some(i) = child(link, "inertial") else { return Ok(Body::default()) };
        let mass_node =
            child(i, "mass").ok_or_else(|| self.at(i, format!("link `{name}`: <inertial> without <mass>")))?;
        let kg = self.numbers(mass_node, "value", 1, f64::NAN, MAX_MASS_KG)?[0];
        if kg.is_nan() || kg < 0.0 {
            return Err(self.at(mass_node, format!("link `{name}`: the mass must be a number >= 0 kg")));
        }
        // The inertia is not used (the model's loads are weights: mass and centre), so only its numbers are
        // checked: real descriptions carry tensors that are not positive semi-definite (TIAGo's antennas,
        // principal moments -3.5e-8 to 9.1e-8 kg m^2), and refusing them would refuse the robot.
        if let Some(n) = child(i, "inertia") {
            for a in ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"] {
                self.numbers(n, a, 1, 0.0, MAX_MASS_KG * MAX_LENGTH_M * MAX_LENGTH_M)?;
            }
        }
        let centre = self.origin(i)?.pos;
        Ok(Body { kg, moment: centre * kg })
    }

    /// A joint's `<limit lower= upper=>` in the model's units, where both bounds are given and differ
    /// (a `<limit>` with only effort and velocity says nothing of the range).
    fn limits(
        &self,
        j: roxmltree::Node,
        name: &str,
        kind: UrdfJointKind,
        continuous: bool,
    ) -> Result<Option<(f64, f64)>, InputError> {
        let Some(l) = child(j, "limit") else { return Ok(None) };
        if continuous
            || kind == UrdfJointKind::Fixed
            || l.attribute("lower").is_none()
            || l.attribute("upper").is_none()
        {
            return Ok(None);
        }
        let largest = if kind == UrdfJointKind::Prismatic { MAX_LENGTH_M } else { MAX_PLAIN };
        let lower = self.numbers(l, "lower", 1, 0.0, largest)?[0];
        let upper = self.numbers(l, "upper", 1, 0.0, largest)?[0];
        if lower > upper {
            return Err(self.at(l, format!("joint `{name}`: its lower limit {lower} is above its upper limit {upper}")));
        }
        let unit = if kind == UrdfJointKind::Prismatic { MM_PER_M } else { 1.0 };
        Ok((lower < upper).then_some((lower * unit, upper * unit)))
    }

    /// A `<joint>` read whole, its links found by name.
    fn joint<'a, 'input>(
        &self,
        j: roxmltree::Node<'a, 'input>,
        link_index: &HashMap<&str, usize>,
    ) -> Result<ReadJoint<'a, 'input>, InputError> {
        let name = j.attribute("name").unwrap_or("").to_string();
        let end = |which: &str| -> Result<usize, InputError> {
            let link = child(j, which).and_then(|c| c.attribute("link")).unwrap_or("");
            if link.is_empty() {
                return Err(self.at(j, format!("joint `{name}` has no <{which} link=...>")));
            }
            link_index
                .get(link)
                .copied()
                .ok_or_else(|| self.at(j, format!("joint `{name}`: its {which} link `{link}` is not in the file")))
        };
        let (parent, child_link) = (end("parent")?, end("child")?);
        let type_name = j.attribute("type").unwrap_or("");
        let kind = match type_name {
            "revolute" | "continuous" => Ok(UrdfJointKind::Revolute),
            "prismatic" => Ok(UrdfJointKind::Prismatic),
            "fixed" => Ok(UrdfJointKind::Fixed),
            other @ ("floating" | "planar") => Err(other.to_string()),
            other => return Err(self.at(j, format!("joint `{name}` has the unknown type `{other}`"))),
        };
        let moving = matches!(kind, Ok(UrdfJointKind::Revolute | UrdfJointKind::Prismatic));
        let axis = match child(j, "axis") {
            // A joint that does not move along an axis never reads it (descriptions in use write `0 0 0` at
            // a fixed joint).
            Some(a) if moving => {
                let v = self.numbers(a, "xyz", 3, 0.0, MAX_PLAIN)?;
                let v = Vec3::new(v[0], v[1], v[2]);
                if v.norm() == 0.0 {
                    return Err(self.at(a, format!("joint `{name}`: the axis must not be zero")));
                }
                v.normalize()
            }
            _ => Vec3::x(),
        };
        let unit = if kind == Ok(UrdfJointKind::Prismatic) { MM_PER_M } else { 1.0 };
        let mimic = match child(j, "mimic") {
            Some(m) if moving => {
                let master = m.attribute("joint").unwrap_or("").to_string();
                if master.is_empty() {
                    return Err(self.at(m, format!("joint `{name}`: <mimic> needs `joint`")));
                }
                let gain = self.numbers(m, "multiplier", 1, 1.0, MAX_PLAIN)?[0];
                let offset = self.numbers(m, "offset", 1, 0.0, MAX_PLAIN)?[0];
                Some((master, gain, offset * unit))
            }
            _ => None,
        };
        let limits = match kind {
            Ok(k) => self.limits(j, &name, k, type_name == "continuous")?,
            Err(_) => None,
        };
        Ok(ReadJoint { node: j, name, kind, origin: self.origin(j)?, axis, mimic, limits, parent, child: child_link })
    }
}

/// URDF's roll-pitch-yaw: fixed-axis rotations about x, then y, then z: R = Rz(yaw) Ry(pitch) Rx(roll).
pub fn rpy_matrix(roll: f64, pitch: f64, yaw: f64) -> Mat3 {
    rotation_about(&Vec3::z(), yaw) * rotation_about(&Vec3::y(), pitch) * rotation_about(&Vec3::x(), roll)
}

fn child<'a, 'input>(node: roxmltree::Node<'a, 'input>, name: &str) -> Option<roxmltree::Node<'a, 'input>> {
    node.children().find(|c| c.has_tag_name(name))
}

/// The file's tree: every link's parent joint and child joints.
struct Tree {
    parent_joint: Vec<Option<usize>>,
    child_joints: Vec<Vec<usize>>,
}

impl Tree {
    /// The tree of `joints` over `n_links` links: a link with two parent joints, or joints that close a loop,
    /// are located errors (URDF describes a tree).
    fn new(r: &Reader, joints: &[ReadJoint], link_names: &[&str]) -> Result<Tree, InputError> {
        let n_links = link_names.len();
        let mut parent_joint: Vec<Option<usize>> = vec![None; n_links];
        let mut child_joints: Vec<Vec<usize>> = vec![Vec::new(); n_links];
        for (k, j) in joints.iter().enumerate() {
            if let Some(first) = parent_joint[j.child] {
                return Err(r.at(
                    j.node,
                    format!(
                        "link `{}` has two parent joints (`{}` on line {} and `{}`): URDF describes a tree",
                        link_names[j.child],
                        joints[first].name,
                        r.line_of(joints[first].node),
                        j.name
                    ),
                ));
            }
            parent_joint[j.child] = Some(k);
            child_joints[j.parent].push(k);
        }
        // Each link has at most one parent, so a loop is a cycle of parents: walked once from each link,
        // marking the links a walk has settled (linear in all).
        let mut state = vec![0u8; n_links]; // 0 unseen, 1 on the current walk, 2 settled
        for start in 0..n_links {
            let mut walk = Vec::new();
            let mut at = start;
            while state[at] == 0 {
                state[at] = 1;
                walk.push(at);
                match parent_joint[at] {
                    Some(j) => at = joints[j].parent,
                    None => break,
                }
            }
            // A walk stops on a link it marked itself only where the parents came back round to it.
            if state[at] == 1 && parent_joint[at].is_some() {
                let j = &joints[parent_joint[at].expect("checked")];
                return Err(r.at(
                    j.node,
                    format!(
                        "joint `{}` closes a loop through link `{}`: URDF describes a tree",
                        j.name, link_names[at]
                    ),
                ));
            }
            walk.iter().for_each(|&l| state[l] = 2);
        }
        Ok(Tree { parent_joint, child_joints })
    }
}

/// Reads the chain from `root` to `tip` of the URDF file `path` (its text `text`).
pub fn read_chain(path: &Path, text: &str, root: &str, tip: &str) -> Result<UrdfChain, InputError> {
    Ok(read_tree(path, text, root, &[tip])?.remove(0))
}

/// Reads the chains from `root` to each of `tips` of the URDF file `path` (its text `text`), in the order
/// of `tips`. Together they are the tree's skeleton: a link on several paths (a torso) is one body, whose
/// mass is given to the first chain that reaches it (`UrdfJoint::child_mass` is None on the later ones), so
/// that summing the chains' loads counts every body once; every body off the skeleton weighs on the link of
/// it that it hangs from.
pub fn read_tree(path: &Path, text: &str, root: &str, tips: &[&str]) -> Result<Vec<UrdfChain>, InputError> {
    let doc = roxmltree::Document::parse(text)
        .map_err(|e| InputError::Syntax { path: path.to_path_buf(), message: format!("not a URDF (XML) file: {e}") })?;
    let r = Reader { path, doc: &doc };
    let robot = doc.root_element();
    if !robot.has_tag_name("robot") {
        return Err(r.at(robot, format!("the root element is <{}>, not <robot>", robot.tag_name().name())));
    }
    let name_of = |n| name_of(&r, n);
    // Links by name, once.
    let link_nodes: Vec<roxmltree::Node> = robot.children().filter(|c| c.has_tag_name("link")).collect();
    let mut link_index: HashMap<&str, usize> = HashMap::with_capacity(link_nodes.len());
    let mut link_names: Vec<&str> = Vec::with_capacity(link_nodes.len());
    for (k, l) in link_nodes.iter().enumerate() {
        let name = name_of(*l)?;
        if let Some(first) = link_index.insert(name, k) {
            return Err(r.at(
                *l,
                format!("a second link named `{name}` (the first is on line {})", r.line_of(link_nodes[first])),
            ));
        }
        link_names.push(name);
    }
    let own: Vec<Body> =
        link_nodes.iter().zip(&link_names).map(|(l, n)| r.inertial(*l, n)).collect::<Result<_, _>>()?;
    let mut joint_index: HashMap<&str, usize> = HashMap::new();
    let mut joints: Vec<ReadJoint> = Vec::new();
    for j in robot.children().filter(|c| c.has_tag_name("joint")) {
        let name = name_of(j)?;
        if let Some(first) = joint_index.insert(name, joints.len()) {
            return Err(r.at(
                j,
                format!("a second joint named `{name}` (the first is on line {})", r.line_of(joints[first].node)),
            ));
        }
        joints.push(r.joint(j, &link_index)?);
    }
    let tree = Tree::new(&r, &joints, &link_names)?;
    let known = |name: &str| -> Result<usize, InputError> {
        link_index.get(name).copied().ok_or_else(|| {
            let shown: Vec<&str> = link_names.iter().take(40).copied().collect();
            let more =
                if link_names.len() > 40 { format!(" and {} more", link_names.len() - 40) } else { String::new() };
            InputError::Whole {
                path: path.to_path_buf(),
                message: format!("no link named `{name}` (links: {}{more})", shown.join(", ")),
            }
        })
    };
    let root_link = known(root)?;
    // Each tip's path up to the root: every link has at most one parent joint.
    let mut paths: Vec<Vec<usize>> = Vec::with_capacity(tips.len());
    for (k, tip) in tips.iter().enumerate() {
        if tips[..k].contains(tip) {
            return Err(InputError::Whole { path: path.to_path_buf(), message: format!("tip `{tip}` is named twice") });
        }
        let mut path_joints = Vec::new();
        let mut at = known(tip)?;
        while at != root_link {
            match tree.parent_joint[at] {
                Some(j) => {
                    path_joints.push(j);
                    at = joints[j].parent;
                }
                None => {
                    return Err(InputError::Whole {
                        path: path.to_path_buf(),
                        message: format!("links `{root}` and `{tip}` are not connected: `{}` has no parent joint and is not `{root}` (is `{tip}` below `{root}`?)", link_names[at]),
                    })
                }
            }
        }
        path_joints.reverse();
        paths.push(path_joints);
    }
    // The skeleton: the joints of every path; and which chain carries each of its links' masses.
    let mut on_path = vec![false; joints.len()];
    let mut mass_owner: Vec<Option<usize>> = vec![None; joints.len()];
    for (k, p) in paths.iter().enumerate() {
        for &j in p {
            on_path[j] = true;
            mass_owner[j].get_or_insert(k);
        }
    }
    let held = held_values(&r, &joints, &joint_index)?;
    let lumped = subtree_bodies(&joints, &tree, &own, &held);
    // What a link of the skeleton carries: its own body and every subtree hanging from it off the skeleton.
    let carried = |link: usize| -> Body {
        tree.child_joints[link]
            .iter()
            .filter(|&&j| !on_path[j])
            .fold(own[link], |sum, &j| sum.plus(lumped[joints[j].child].moved(&joints[j].at(held[j]))))
    };
    let mut masses = MassShare::default();
    let mut chains = Vec::with_capacity(paths.len());
    for (k, path_joints) in paths.iter().enumerate() {
        let mut out = Vec::with_capacity(path_joints.len());
        for &j in path_joints {
            let joint = &joints[j];
            let kind = joint.kind.clone().map_err(|other| {
                r.at(
                    joint.node,
                    format!(
                        "joint `{}` is `{other}`: only revolute, continuous, prismatic and fixed joints make a chain",
                        joint.name
                    ),
                )
            })?;
            let mass = if mass_owner[j] == Some(k) {
                let body = carried(joint.child);
                masses.carried += body.kg;
                masses.off_path += body.kg - own[joint.child].kg;
                body.as_mass()
            } else {
                None
            };
            out.push(joint.as_chain_joint(kind, mass, link_names[joint.child].to_string()));
        }
        let masters = off_path_masters(&r, &joints, &joint_index, path_joints, &on_path)?;
        chains.push(UrdfChain { joints: out, masters, root_mass: carried(root_link).as_mass(), masses });
    }
    let total: f64 = own.iter().map(|b| b.kg).sum();
    masses.on_base = (total - masses.carried).max(0.0);
    chains.iter_mut().for_each(|c| c.masses = masses);
    Ok(chains)
}

/// An element's `name`, which must not be empty.
fn name_of<'a>(r: &Reader, n: roxmltree::Node<'a, '_>) -> Result<&'a str, InputError> {
    match n.attribute("name") {
        Some(name) if !name.is_empty() => Ok(name),
        _ => Err(r.at(n, format!("a <{}> without a name", n.tag_name().name()))),
    }
}

/// Each joint's value where the tree is held at its URDF zero: 0, or a mimic joint's multiplier times its
/// master's held value plus its offset. A mimic whose master is not a joint of the file, or mimics that
/// form a loop, are located errors.
fn held_values(r: &Reader, joints: &[ReadJoint], joint_index: &HashMap<&str, usize>) -> Result<Vec<f64>, InputError> {
    let mut held: Vec<Option<f64>> = vec![None; joints.len()];
    for start in 0..joints.len() {
        // The mimic chain from `start` to a joint that is no mimic, then its values back down.
        let mut chain = vec![start];
        let mut at = start;
        while held[at].is_none() {
            let Some((master, _, _)) = &joints[at].mimic else { break };
            let m = *joint_index.get(master.as_str()).ok_or_else(|| {
                r.at(
                    joints[at].node,
                    format!("joint `{}` mimics `{master}`, which is not a joint of the file", joints[at].name),
                )
            })?;
            if chain.contains(&m) {
                let names: Vec<&str> = chain.iter().chain([&m]).map(|&k| joints[k].name.as_str()).collect();
                return Err(r.at(joints[at].node, format!("the <mimic> joints form a loop: {}", names.join(" -> "))));
            }
            if joints[m].mimic.is_none() && held[m].is_none() {
                held[m] = Some(0.0);
            }
            chain.push(m);
            at = m;
        }
        let mut value = held[at].unwrap_or(0.0);
        for &k in chain.iter().rev() {
            if held[k].is_none() {
                value = match &joints[k].mimic {
                    Some((_, gain, offset)) => gain * value + offset,
                    None => 0.0,
                };
                held[k] = Some(value);
            } else {
                value = held[k].expect("set");
            }
        }
    }
    Ok(held.into_iter().map(|v| v.unwrap_or(0.0)).collect())
}

/// Every link's subtree (itself and everything below it) as one body in the link's frame, the joints below
/// held at `held`: children are lumped before their parents (links in reverse order of a breadth-first walk
/// from the tree's roots).
fn subtree_bodies(joints: &[ReadJoint], tree: &Tree, own: &[Body], held: &[f64]) -> Vec<Body> {
    let mut order: Vec<usize> = (0..own.len()).filter(|&l| tree.parent_joint[l].is_none()).collect();
    let mut next = 0;
    while next < order.len() {
        let l = order[next];
        order.extend(tree.child_joints[l].iter().map(|&j| joints[j].child));
        next += 1;
    }
    let mut lumped = own.to_vec();
    for &l in order.iter().rev() {
        for &j in &tree.child_joints[l] {
            let below = lumped[joints[j].child].moved(&joints[j].at(held[j]));
            lumped[l] = lumped[l].plus(below);
        }
    }
    lumped
}

/// The moving joints off the path that a joint of the path mimics, directly or through other mimics.
fn off_path_masters(
    r: &Reader,
    joints: &[ReadJoint],
    joint_index: &HashMap<&str, usize>,
    path_joints: &[usize],
    on_path: &[bool],
) -> Result<Vec<UrdfJoint>, InputError> {
    let mut masters: Vec<usize> = Vec::new();
    for &k in path_joints {
        let mut at = k;
        while let Some((master, _, _)) = &joints[at].mimic {
            let m = joint_index[master.as_str()];
            if !on_path[m] && !masters.contains(&m) {
                masters.push(m);
            }
            at = m;
        }
    }
    masters
        .iter()
        .map(|&m| {
            let j = &joints[m];
            let kind = j.kind.clone().map_err(|other| {
                r.at(j.node, format!("joint `{}` is `{other}`: a joint the chain's <mimic> joints follow must be revolute, continuous or prismatic", j.name))
            })?;
            Ok(j.as_chain_joint(kind, None, String::new()))
        })
        .collect()
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
        let want = rotation_about(&Vec3::y(), b) * rotation_about(&Vec3::x(), a);
        assert!((rpy_matrix(a, b, 0.0) - want).norm() < 1e-15);
    }
}

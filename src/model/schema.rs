//! The TOML schema of a manipulator description, as written by users (docs in docs/GUIDE.md).
//! Every table refuses unknown keys; positions are kept (`Spanned`) where validation may need to point.

use std::collections::BTreeMap;
use std::fmt;

use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;
use toml::Spanned;

use crate::expr::ExprSrc;

/// A number as written: a literal or a formula, with its position for messages.
pub type Num = Spanned<ExprSrc>;

/// A manipulator description file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    /// The manipulator's name (reports, CSV metadata).
    pub name: String,
    /// Free text about the model and its sources.
    #[serde(default)]
    pub description: Option<String>,
    /// Named numbers, usable in any formula of the file (and in each other).
    #[serde(default)]
    pub parameters: BTreeMap<String, Num>,
    /// Another model file (path relative to this one) whose parameters this file uses too (its own
    /// `parameters` may add to them, not redefine them): one robot described twice shares its numbers.
    #[serde(default)]
    pub parameters_from: Option<Spanned<String>>,
    /// Gravity acting on the chains' masses, m/s^2 (default: none).
    #[serde(default)]
    pub gravity: Option<[Num; 3]>,
    /// The legs (`[[leg]]` tables), each a chain, an MSA structure or a leg of another file.
    #[serde(rename = "leg")]
    pub legs: Spanned<Vec<Spanned<LegSpec>>>,
    /// Masses carried by the platform (`[[payload]]`), weighed under `gravity` (standard gravity along -z
    /// when the file gives none).
    #[serde(default, rename = "payload")]
    pub payloads: Vec<Spanned<PayloadSpec>>,
    /// Actuators sitting away from where they are commanded (`[[actuator_offset]]`, encoder zero offsets).
    #[serde(default, rename = "actuator_offset")]
    pub actuator_offsets: Vec<Spanned<ActuatorOffsetSpec>>,
    /// Corrections to the nominal model (spring scalings) and measurement terms, as `stiff diagnose
    /// --model-out` writes them.
    #[serde(default, rename = "effect")]
    pub effects: Vec<Spanned<EffectSpec>>,
    /// Corrections of a serial arm's joints (`[[joint_correction]]`), as a calibration finds them and
    /// `stiff diagnose --model-out` writes them for joint-space data.
    #[serde(default, rename = "joint_correction")]
    pub joint_corrections: Vec<Spanned<JointCorrectionSpec>>,
}

/// What a calibration found at one joint of a serial arm read from URDF.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointCorrectionSpec {
    /// The joint's name (a joint of the `[leg.urdf]` chain with a coordinate of its own).
    pub joint: Spanned<String>,
    /// Added to the controller's angle before its map to the model's coordinates (an encoder's zero), rad
    /// (mm for a prismatic joint).
    #[serde(default)]
    pub offset: Option<Num>,
    /// The joint's play (backlash), rad (mm for a prismatic joint), zero or above: under load its model
    /// coordinate sits this far off in the sense of the load it carries (at the commanded configuration),
    /// in every loaded study; unloaded compliance does not see it.
    #[serde(default)]
    pub play: Option<Num>,
    /// Added to the joint's compliance (a spring where `joints` gives none), rad/(N mm) or mm/N.
    #[serde(default)]
    pub compliance: Option<Num>,
    /// The fixed transform leading to the joint, moved by a translation (mm) and then turned by a rotation
    /// vector (rad), in the joint's frame: `[dx, dy, dz, rx, ry, rz]`.
    #[serde(default)]
    pub geometry: Option<[Num; 6]>,
    /// A compliance at the frame leading to the joint (before its motion), where the chain is otherwise
    /// rigid: along its x, y, z (mm/N) and about them (rad/(N mm)), `[cx, cy, cz, crx, cry, crz]`; zero is
    /// rigid in that direction.
    #[serde(default)]
    pub frame_compliance: Option<Spanned<[Num; 6]>>,
}

/// A mass carried by the platform.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PayloadSpec {
    /// Its mass, kg.
    pub mass_kg: Num,
    /// Its centre of mass in the platform frame, mm (default: the reference point).
    #[serde(default)]
    pub centre: Option<[Num; 3]>,
}

/// An actuator further along its axis than commanded.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuatorOffsetSpec {
    /// The leg, by number (1-based, in the order the legs and their copies are listed).
    pub leg: Spanned<i64>,
    /// Where the actuator sits minus where it is commanded, mm (prismatic) or rad (revolute).
    pub offset: Num,
}

/// An effect of the diagnose library: `name`, `target` (a leg number or a spring group) and its values.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectSpec {
    /// The effect's name, as on the command line (`actuator-compliance`, `gravity`, ...).
    pub name: String,
    /// Its target: a leg number (1-based) or a spring group, where the effect takes one.
    #[serde(default)]
    pub target: Option<String>,
    /// Its values, as many as the effect takes.
    pub values: Vec<f64>,
}

/// A leg: its body (chain, MSA or `from`), where it attaches, and its copies.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegSpec {
    /// The leg's name (a copy's name replaces it).
    pub name: String,
    /// Copies of the leg, each moved rigidly (base part and platform attachment together) about the
    /// world/platform origin; without copies the leg appears once as written.
    #[serde(default)]
    pub copies: Vec<CopySpec>,
    /// The leg's end frame in the platform frame, as written before any copy transform (default: the
    /// platform's reference point, platform axes).
    #[serde(default)]
    pub attachment: Option<TransformSpec>,
    /// A VJM leg: a serial chain of elements.
    #[serde(default)]
    pub chain: Option<Spanned<Vec<Spanned<ElementSpec>>>>,
    /// An MSA leg: nodes, links and joints (paper 003 Table 1).
    #[serde(default)]
    pub msa: Option<Spanned<MsaSpec>>,
    /// A chain read from a URDF file, with the joints' stiffnesses beside it (`[leg.urdf]`).
    #[serde(default)]
    pub urdf: Option<Spanned<UrdfSpec>>,
    /// The leg of another model file (path relative to this one), its parameters overridden by `parameters`.
    #[serde(default)]
    pub from: Option<Spanned<String>>,
    /// With `from`: values (formulas over this file's parameters) replacing the other file's parameters.
    #[serde(default)]
    pub parameters: BTreeMap<String, Num>,
}

/// An MSA leg, written like paper 003 Table 1. Every formula may use the file's parameters, the leg's end
/// point and orientation in the leg's own frame (`end_x`, `end_y`, `end_z` in mm, `end_rx`, `end_ry`, `end_rz`
/// rotation vector in rad), and the per-pose quantities of `pose`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MsaSpec {
    /// The node at the leg's end (where its stiffness is wanted).
    pub end: Spanned<String>,
    /// Per-pose quantities (eq 18-22), in any order, each a formula of the others.
    #[serde(default)]
    pub pose: BTreeMap<String, Num>,
    /// Formulas that must be >= 0 at a reachable pose (eq 20); elsewhere the pose is unreachable.
    #[serde(default)]
    pub reach: Vec<Num>,
    /// Node positions in the leg's frame (mm): three formulas, or the name of a node at the same point.
    pub nodes: Spanned<BTreeMap<String, Spanned<NodeSpec>>>,
    /// Named beam sections used by the links.
    #[serde(default)]
    pub sections: BTreeMap<String, Spanned<SectionSpec>>,
    /// The links between nodes (`[[leg.msa.link]]`).
    #[serde(default, rename = "link")]
    pub links: Vec<Spanned<MsaLinkSpec>>,
    /// The joints between nodes or to the base (`[[leg.msa.joint]]`).
    #[serde(default, rename = "joint")]
    pub joints: Vec<Spanned<MsaJointSpec>>,
}

/// A node's position: three formulas, or another node's name (the same point).
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum NodeSpec {
    /// Three formulas: x, y, z in mm, in the leg's frame.
    At([ExprSrc; 3]),
    /// The name of another node at the same point.
    Same(String),
}

/// A beam section (N, mm): material and either a round diameter or A, Iy, Iz, J.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionSpec {
    /// Young's modulus, N/mm^2.
    #[serde(rename = "E")]
    pub e: Num,
    /// Shear modulus, N/mm^2 (or give `nu`).
    #[serde(rename = "G", default)]
    pub g: Option<Num>,
    /// Poisson's ratio: G = E / (2 (1 + nu)).
    #[serde(default)]
    pub nu: Option<Num>,
    /// Round solid section of this diameter (mm), instead of A, Iy, Iz, J.
    #[serde(default)]
    pub diameter: Option<Num>,
    /// Area, mm^2.
    #[serde(rename = "A", default)]
    pub area: Option<Num>,
    /// Second moment of area about the section's y axis, mm^4.
    #[serde(rename = "Iy", default)]
    pub iy: Option<Num>,
    /// Second moment of area about the section's z axis, mm^4.
    #[serde(rename = "Iz", default)]
    pub iz: Option<Num>,
    /// Torsion constant, mm^4.
    #[serde(rename = "J", default)]
    pub j: Option<Num>,
}

/// A link between two nodes: `beam` (a section; `y_axis` orients a section with Iy != Iz), `rigid`
/// (eq 3-5), or `link` with its 6x6 `stiffness_matrix` at the second node with the first clamped (leg frame).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MsaLinkSpec {
    /// `beam`, `rigid` or `link`.
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    /// The two nodes joined, by name.
    pub nodes: Spanned<Vec<Spanned<String>>>,
    /// A `beam`'s section, by name in `sections`.
    #[serde(default)]
    pub section: Option<Spanned<String>>,
    /// A `beam`'s section y axis (for sections with Iy != Iz).
    #[serde(default)]
    pub y_axis: Option<Spanned<AxisSpec>>,
    /// A `link`'s 6x6 stiffness at the second node, the first clamped (leg frame).
    #[serde(default)]
    pub stiffness_matrix: Option<Spanned<Vec<Vec<Num>>>>,
}

/// A joint between two nodes (at the second one's point), or a node's connection to the base when the
/// first node is `base`. `type`: rigid, revolute (`axis`), prismatic (`axis`), universal (`axes`),
/// spherical, free (`free`: the passive unit twists, Lambda^p of eq 8) or spring (`stiffness_matrix`, all
/// six directions elastic). A revolute or prismatic joint with a `stiffness` (and optional `preload`) is
/// elastic (eq 10); without, passive.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MsaJointSpec {
    /// `rigid`, `revolute`, `prismatic`, `universal`, `spherical`, `free` or `spring`.
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    /// The two nodes joined (the first may be `base`).
    pub nodes: Spanned<Vec<Spanned<String>>>,
    /// A revolute or prismatic joint's axis.
    #[serde(default)]
    pub axis: Option<Spanned<AxisSpec>>,
    /// A universal joint's two axes.
    #[serde(default)]
    pub axes: Option<Spanned<Vec<Spanned<AxisSpec>>>>,
    /// A `free` joint's passive unit twists (dx, dy, dz, rx, ry, rz), one row each.
    #[serde(default)]
    pub free: Option<Spanned<Vec<[ExprSrc; 6]>>>,
    /// A revolute or prismatic joint's stiffness (N/mm or N mm/rad): elastic; zero: passive.
    #[serde(default)]
    pub stiffness: Option<Num>,
    /// The rest value of an elastic joint's coordinate (mm or rad).
    #[serde(default)]
    pub preload: Option<Num>,
    /// A `spring` joint's 6x6 stiffness (leg frame).
    #[serde(default)]
    pub stiffness_matrix: Option<Spanned<Vec<Vec<Num>>>>,
}

/// A leg whose chain comes from a URDF file: the joints on the path from `root` to `tip`, then `tool` (a fixed
/// transform in the tip link's frame, mm and degrees) to the reference point. Each actuated joint's
/// stiffness is given by name in `joints` (what is not given is rigid); `controller` maps the controller's
/// angles to the model's coordinates (formulas of the joints' names).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UrdfSpec {
    /// The URDF file, relative to the description.
    pub file: Spanned<String>,
    /// The link the chain starts from (fixed to the base).
    pub root: Spanned<String>,
    /// The link it ends at (or `tips`).
    #[serde(default)]
    pub tip: Option<Spanned<String>>,
    /// The links a tree ends at, each a reference point with its own rows (a dual-arm cell, a humanoid's
    /// hands); joints shared by their paths are one coordinate and one spring.
    #[serde(default)]
    pub tips: Option<Spanned<Vec<Spanned<String>>>>,
    /// From the tip link's frame to the reference point (the tool point), mm and degrees.
    #[serde(default)]
    pub tool: Option<TransformSpec>,
    /// Per tip (with `tips`): its tool transform.
    #[serde(default)]
    pub tools: BTreeMap<String, Spanned<TransformSpec>>,
    /// Per joint name: its stiffness or compliance.
    #[serde(default)]
    pub joints: BTreeMap<String, Spanned<JointStiffnessSpec>>,
    /// Per joint name: its model coordinate as a formula of the controller's angles (by joint name).
    #[serde(default)]
    pub controller: BTreeMap<String, Spanned<String>>,
    /// Per joint name: the controller's angle a pose's inverse kinematics starts from when it has no
    /// previous point to start from (the others 0), which picks the arm's elbow and wrist branch.
    #[serde(default)]
    pub seed: BTreeMap<String, Num>,
    /// Per link name: a 6-dof spring at the link's frame (the link bends; its own weight and everything
    /// beyond load it).
    #[serde(default)]
    pub links: BTreeMap<String, Spanned<LinkSpringSpec>>,
}

/// A link's 6-dof spring, in the link's frame (N, mm, rad): exactly one of its stiffness matrix, its
/// compliance matrix or a clamped-free beam.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkSpringSpec {
    /// Stiffness matrix (translations along, then rotations about, the link frame's x, y, z).
    #[serde(default)]
    pub stiffness_matrix: Option<Spanned<Vec<Vec<Num>>>>,
    /// Compliance matrix.
    #[serde(default)]
    pub compliance_matrix: Option<Spanned<Vec<Vec<Num>>>>,
    /// A clamped-free beam from the link's frame.
    #[serde(default)]
    pub beam: Option<Spanned<BeamSpec>>,
}

/// A URDF joint's spring: a stiffness (N mm/rad for a revolute joint, N/mm for a prismatic one) or a
/// compliance (rad/(N mm), mm/N).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointStiffnessSpec {
    /// N mm/rad or N/mm.
    #[serde(default)]
    pub stiffness: Option<Num>,
    /// rad/(N mm) or mm/N.
    #[serde(default)]
    pub compliance: Option<Num>,
}

/// A copy of a leg, moved rigidly about the world / platform origin.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CopySpec {
    /// The copy's name.
    pub name: String,
    /// Translation of the copy, mm.
    #[serde(default)]
    pub translation: Option<[Num; 3]>,
    /// Axis of the copy's rotation.
    #[serde(default)]
    pub rotation_axis: Option<Spanned<AxisSpec>>,
    /// Angle of the copy's rotation, degrees.
    #[serde(default)]
    pub rotation_deg: Option<Num>,
}

/// A rigid transform: a translation and a rotation about an axis.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformSpec {
    /// Translation, mm.
    #[serde(default)]
    pub translation: Option<[Num; 3]>,
    /// Rotation axis.
    #[serde(default)]
    pub rotation_axis: Option<Spanned<AxisSpec>>,
    /// Rotation angle, degrees.
    #[serde(default)]
    pub rotation_deg: Option<Num>,
}

/// One element of a chain. Which keys apply depends on `type`; the builder refuses the others.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElementSpec {
    /// `fixed`, `prismatic`, `revolute`, `universal`, `spherical`, `spring6` or `mass`.
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    /// A name (springs are grouped by it; joints are followed by it); default: type and position.
    #[serde(default)]
    pub name: Option<String>,
    // fixed
    /// A fixed transform's translation, mm.
    #[serde(default)]
    pub translation: Option<[Num; 3]>,
    /// A fixed transform's rotation axis.
    #[serde(default)]
    pub rotation_axis: Option<Spanned<AxisSpec>>,
    /// A fixed transform's rotation angle, degrees.
    #[serde(default)]
    pub rotation_deg: Option<Num>,
    // prismatic, revolute
    /// A joint's axis.
    #[serde(default)]
    pub axis: Option<Spanned<AxisSpec>>,
    /// A joint's role: `actuated`, `passive` or `elastic`.
    #[serde(default)]
    pub role: Option<Spanned<String>>,
    /// A joint's spring stiffness (N/mm or N mm/rad): an actuator's control loop, or an elastic joint.
    #[serde(default)]
    pub stiffness: Option<Num>,
    /// A passive joint driven by another passive joint's coordinate (named), times `gain`: a parallelogram's
    /// q3 = -q2 (paper 001 eq 22).
    #[serde(default)]
    pub follows: Option<Spanned<String>>,
    /// Gain of a following joint (default 1).
    #[serde(default)]
    pub gain: Option<Num>,
    // universal
    /// A universal joint's two axes.
    #[serde(default)]
    pub axes: Option<Spanned<Vec<Spanned<AxisSpec>>>>,
    // spring6
    /// A 6-dof spring's stiffness matrix (N, mm, rad).
    #[serde(default)]
    pub stiffness_matrix: Option<Spanned<Vec<Vec<Num>>>>,
    /// A 6-dof spring's compliance matrix.
    #[serde(default)]
    pub compliance_matrix: Option<Spanned<Vec<Vec<Num>>>>,
    /// A 6-dof spring from a clamped-free beam.
    #[serde(default)]
    pub beam: Option<Spanned<BeamSpec>>,
    /// A 6-dof spring from a parallelogram's two bars, at the current angle.
    #[serde(default)]
    pub parallelogram: Option<Spanned<ParallelogramSpec>>,
    /// Spring preload: the rest values theta0 of the spring's coordinates (mm, rad), one per coordinate.
    #[serde(default)]
    pub preload: Option<Spanned<Vec<Num>>>,
    // mass
    /// A point mass, kg, carried by the chain at this element (weighed by the model's gravity).
    #[serde(default)]
    pub mass_kg: Option<Num>,
    /// The mass's centre in the element's frame, mm (default: its origin).
    #[serde(default)]
    pub centre: Option<[Num; 3]>,
}

/// A beam whose clamped-free compliance gives a 6-dof spring: material, section and length (N, mm).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BeamSpec {
    /// Young's modulus, N/mm^2.
    #[serde(rename = "E")]
    pub e: Num,
    /// Shear modulus, N/mm^2 (or give `nu`).
    #[serde(rename = "G", default)]
    pub g: Option<Num>,
    /// Poisson's ratio: G = E / (2 (1 + nu)).
    #[serde(default)]
    pub nu: Option<Num>,
    /// Round solid section of this diameter (mm), instead of A, Iy, Iz, J.
    #[serde(default)]
    pub diameter: Option<Num>,
    /// Area, mm^2.
    #[serde(rename = "A", default)]
    pub area: Option<Num>,
    /// Second moment of area about the section's y axis, mm^4.
    #[serde(rename = "Iy", default)]
    pub iy: Option<Num>,
    /// Second moment of area about the section's z axis, mm^4.
    #[serde(rename = "Iz", default)]
    pub iz: Option<Num>,
    /// Torsion constant, mm^4.
    #[serde(rename = "J", default)]
    pub j: Option<Num>,
    /// Length, mm.
    pub length: Num,
    /// The beam's axis in the spring's frame (default x).
    #[serde(default)]
    pub direction: Option<Spanned<AxisSpec>>,
}

/// A parallelogram link's spring, derived from its two bars (round beams) at the current parallelogram angle:
/// bars along local x at angle 0, turning about local z, separated along local y.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParallelogramSpec {
    /// Young's modulus of the bars, N/mm^2.
    #[serde(rename = "E")]
    pub e: Num,
    /// Shear modulus of the bars, N/mm^2 (or give `nu`).
    #[serde(rename = "G", default)]
    pub g: Option<Num>,
    /// Poisson's ratio of the bars.
    #[serde(default)]
    pub nu: Option<Num>,
    /// Diameter of each (round, solid) bar, mm.
    pub bar_diameter: Num,
    /// Bar length, mm.
    pub length: Num,
    /// Distance between the bars, mm.
    pub separation: Num,
    /// Name of the passive joint whose coordinate is the parallelogram angle.
    pub angle: Spanned<String>,
}

/// An axis: "x", "-y", ... or a vector of three numbers or formulas.
#[derive(Clone, Debug, PartialEq)]
pub enum AxisSpec {
    /// `x`, `y`, `z`, optionally with a sign (`-y`).
    Named(String),
    /// Three numbers or formulas.
    Vector([ExprSrc; 3]),
}

impl<'de> Deserialize<'de> for AxisSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = AxisSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an axis name (\"x\", \"-y\", ...) or a vector of three numbers")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<AxisSpec, E> {
                Ok(AxisSpec::Named(v.to_string()))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<AxisSpec, A::Error> {
                let mut out: Vec<ExprSrc> = Vec::new();
                while let Some(e) = seq.next_element::<ExprSrc>()? {
                    out.push(e);
                }
                let n = out.len();
                out.try_into().map(AxisSpec::Vector).map_err(|_| de::Error::invalid_length(n, &"three components"))
            }
        }
        d.deserialize_any(V)
    }
}

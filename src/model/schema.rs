//! The TOML schema of a manipulator description, as written by users (docs in README.md).
//! Every table refuses unknown keys; positions are kept (`Spanned`) where validation may need to point.

use std::collections::BTreeMap;
use std::fmt;

use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;
use toml::Spanned;

use crate::expr::ExprSrc;

pub type Num = Spanned<ExprSrc>;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    pub name: String,
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
    #[serde(rename = "leg")]
    pub legs: Spanned<Vec<Spanned<LegSpec>>>,
    /// Corrections to the nominal model, as `stiff diagnose --model-out` writes them.
    #[serde(default, rename = "effect")]
    pub effects: Vec<Spanned<EffectSpec>>,
}

/// An effect of the diagnose library: `name`, `target` (a leg number or a spring group) and its values.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectSpec {
    pub name: String,
    #[serde(default)]
    pub target: Option<String>,
    pub values: Vec<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegSpec {
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
    #[serde(default, rename = "link")]
    pub links: Vec<Spanned<MsaLinkSpec>>,
    #[serde(default, rename = "joint")]
    pub joints: Vec<Spanned<MsaJointSpec>>,
}

/// A node's position: three formulas, or another node's name (the same point).
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum NodeSpec {
    At([ExprSrc; 3]),
    Same(String),
}

/// A beam section (N, mm): material and either a round diameter or A, Iy, Iz, J.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionSpec {
    #[serde(rename = "E")]
    pub e: Num,
    #[serde(rename = "G", default)]
    pub g: Option<Num>,
    #[serde(default)]
    pub nu: Option<Num>,
    #[serde(default)]
    pub diameter: Option<Num>,
    #[serde(rename = "A", default)]
    pub area: Option<Num>,
    #[serde(rename = "Iy", default)]
    pub iy: Option<Num>,
    #[serde(rename = "Iz", default)]
    pub iz: Option<Num>,
    #[serde(rename = "J", default)]
    pub j: Option<Num>,
}

/// A link between two nodes: `beam` (a section; `y_axis` orients a section with Iy != Iz), `rigid`
/// (eq 3-5), or `link` with its 6x6 `stiffness_matrix` at the second node with the first clamped (leg frame).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MsaLinkSpec {
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    pub nodes: Spanned<Vec<Spanned<String>>>,
    #[serde(default)]
    pub section: Option<Spanned<String>>,
    #[serde(default)]
    pub y_axis: Option<Spanned<AxisSpec>>,
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
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    pub nodes: Spanned<Vec<Spanned<String>>>,
    #[serde(default)]
    pub axis: Option<Spanned<AxisSpec>>,
    #[serde(default)]
    pub axes: Option<Spanned<Vec<Spanned<AxisSpec>>>>,
    #[serde(default)]
    pub free: Option<Spanned<Vec<[ExprSrc; 6]>>>,
    #[serde(default)]
    pub stiffness: Option<Num>,
    #[serde(default)]
    pub preload: Option<Num>,
    #[serde(default)]
    pub stiffness_matrix: Option<Spanned<Vec<Vec<Num>>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CopySpec {
    pub name: String,
    #[serde(default)]
    pub translation: Option<[Num; 3]>,
    #[serde(default)]
    pub rotation_axis: Option<Spanned<AxisSpec>>,
    #[serde(default)]
    pub rotation_deg: Option<Num>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformSpec {
    #[serde(default)]
    pub translation: Option<[Num; 3]>,
    #[serde(default)]
    pub rotation_axis: Option<Spanned<AxisSpec>>,
    #[serde(default)]
    pub rotation_deg: Option<Num>,
}

/// One element of a chain. Which keys apply depends on `type`; the builder refuses the others.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElementSpec {
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    #[serde(default)]
    pub name: Option<String>,
    // fixed
    #[serde(default)]
    pub translation: Option<[Num; 3]>,
    #[serde(default)]
    pub rotation_axis: Option<Spanned<AxisSpec>>,
    #[serde(default)]
    pub rotation_deg: Option<Num>,
    // prismatic, revolute
    #[serde(default)]
    pub axis: Option<Spanned<AxisSpec>>,
    #[serde(default)]
    pub role: Option<Spanned<String>>,
    #[serde(default)]
    pub stiffness: Option<Num>,
    /// A passive joint driven by another passive joint's coordinate (named), times `gain`: a parallelogram's
    /// q3 = -q2 (paper 001 eq 22).
    #[serde(default)]
    pub follows: Option<Spanned<String>>,
    #[serde(default)]
    pub gain: Option<Num>,
    // universal
    #[serde(default)]
    pub axes: Option<Spanned<Vec<Spanned<AxisSpec>>>>,
    // spring6
    #[serde(default)]
    pub stiffness_matrix: Option<Spanned<Vec<Vec<Num>>>>,
    #[serde(default)]
    pub compliance_matrix: Option<Spanned<Vec<Vec<Num>>>>,
    #[serde(default)]
    pub beam: Option<Spanned<BeamSpec>>,
    #[serde(default)]
    pub parallelogram: Option<Spanned<ParallelogramSpec>>,
    /// Spring preload: the rest values theta0 of the spring's coordinates (mm, rad), one per coordinate.
    #[serde(default)]
    pub preload: Option<Spanned<Vec<Num>>>,
    // mass
    #[serde(default)]
    pub mass_kg: Option<Num>,
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
    #[serde(rename = "A", default)]
    pub area: Option<Num>,
    #[serde(rename = "Iy", default)]
    pub iy: Option<Num>,
    #[serde(rename = "Iz", default)]
    pub iz: Option<Num>,
    #[serde(rename = "J", default)]
    pub j: Option<Num>,
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
    #[serde(rename = "E")]
    pub e: Num,
    #[serde(rename = "G", default)]
    pub g: Option<Num>,
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
    Named(String),
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

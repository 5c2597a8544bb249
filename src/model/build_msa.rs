//! Validation of an MSA leg (`[leg.msa]`) into a `Template`: per-pose quantities ordered by dependency,
//! formulas parsed once with the file's parameters folded in, nodes, sections, links and joints checked and
//! located in the file.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};
use toml::Spanned;

use super::build::Builder;
use super::error::InputError;
use super::schema::{AxisSpec, MsaJointSpec, MsaLinkSpec, MsaSpec, NodeSpec, SectionSpec};
use crate::beam::BeamSection;
use crate::expr::{Expr, ExprSrc};
use crate::msa::template::{DirectionTemplate, ElementTemplate, Template, END_VARIABLES};

/// Names visible to a leg's formulas: parameters (constants) and per-pose slots.
struct Names<'a> {
    params: &'a BTreeMap<String, f64>,
    slots: BTreeMap<String, usize>,
}

impl Names<'_> {
    fn resolve(&self, name: &str) -> Result<Expr, String> {
        if let Some(s) = self.slots.get(name) {
            return Ok(Expr::Slot(*s));
        }
        self.params
            .get(name)
            .map(|v| Expr::Const(*v))
            .ok_or_else(|| format!("unknown name `{name}` (not a parameter, an end variable or a pose quantity)"))
    }

    fn compile(&self, e: &ExprSrc) -> Result<Expr, String> {
        e.compile(&mut |n| self.resolve(n))
    }
}

impl Builder<'_> {
    pub(super) fn msa_leg(&self, spec: &Spanned<MsaSpec>) -> Result<Template, InputError> {
        let s = spec.get_ref();
        let names = self.pose_names(s)?;
        let pose_order: Vec<&String> = {
            let mut by_slot: Vec<(&usize, &String)> = names.slots.iter().map(|(n, k)| (k, n)).collect();
            by_slot.sort();
            by_slot.into_iter().filter(|(k, _)| **k >= END_VARIABLES.len()).map(|(_, n)| n).collect()
        };
        let pose = pose_order
            .iter()
            .map(|n| {
                let src = &s.pose[*n];
                names.compile(src.get_ref()).map_err(|e| self.loc.at(src.span(), format!("pose `{n}`: {e}")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let reach = s
            .reach
            .iter()
            .map(|r| names.compile(r.get_ref()).map_err(|e| self.loc.at(r.span(), e)))
            .collect::<Result<Vec<_>, _>>()?;
        // Nodes: index by name; a node written as another's name sits at that node's point.
        let node_names: Vec<String> = s.nodes.get_ref().keys().cloned().collect();
        let index = |n: &Spanned<String>| {
            node_names
                .iter()
                .position(|m| m == n.get_ref())
                .ok_or_else(|| self.loc.at(n.span(), format!("no node named `{}` in [leg.msa.nodes]", n.get_ref())))
        };
        let mut nodes = Vec::with_capacity(node_names.len());
        for name in &node_names {
            let mut spec = &s.nodes.get_ref()[name];
            let mut seen = vec![name.as_str()];
            let point = loop {
                match spec.get_ref() {
                    NodeSpec::At(p) => break p,
                    NodeSpec::Same(other) => {
                        if seen.contains(&other.as_str()) {
                            return Err(self.loc.at(spec.span(), format!("node `{name}` refers to itself")));
                        }
                        seen.push(other);
                        spec = s.nodes.get_ref().get(other).ok_or_else(|| {
                            self.loc.at(spec.span(), format!("node `{name}` names no node `{other}`"))
                        })?;
                    }
                }
            };
            let at = |k: usize| names.compile(&point[k]).map_err(|e| self.loc.at(spec.span(), e));
            nodes.push([at(0)?, at(1)?, at(2)?]);
        }
        let end = index(&s.end)?;
        let sections = s
            .sections
            .iter()
            .map(|(n, sec)| Ok((n.clone(), self.section_spec(sec)?)))
            .collect::<Result<BTreeMap<_, _>, InputError>>()?;
        let mut elements = Vec::new();
        for link in &s.links {
            elements.push(self.msa_link(link, &names, &sections, &index)?);
        }
        for joint in &s.joints {
            elements.push(self.msa_joint(joint, &names, &index)?);
        }
        if elements.is_empty() {
            return Err(self.loc.at(spec.span(), "an MSA leg needs links and joints"));
        }
        Ok(Template { pose, reach, nodes, node_names, end, elements })
    }

    /// Slots for the end variables and the per-pose quantities, the latter ordered so that each comes
    /// after those it uses (cycles refused).
    fn pose_names<'a>(&'a self, s: &MsaSpec) -> Result<Names<'a>, InputError> {
        for (n, src) in &s.pose {
            if self.params.contains_key(n) || END_VARIABLES.contains(&n.as_str()) {
                return Err(self.loc.at(src.span(), format!("pose quantity `{n}` hides a parameter or end variable")));
            }
        }
        // First pass: provisional slots to learn the dependencies.
        let provisional: BTreeMap<String, usize> = END_VARIABLES
            .iter()
            .map(|n| n.to_string())
            .chain(s.pose.keys().cloned())
            .enumerate()
            .map(|(k, n)| (n, k))
            .collect();
        let first = Names { params: &self.params, slots: provisional.clone() };
        let keys: Vec<&String> = s.pose.keys().collect();
        let mut deps: Vec<Vec<usize>> = Vec::new();
        for n in &keys {
            let src = &s.pose[*n];
            let e = first.compile(src.get_ref()).map_err(|e| self.loc.at(src.span(), format!("pose `{n}`: {e}")))?;
            let mut used = Vec::new();
            e.slots(&mut used);
            deps.push(
                used.into_iter().filter(|k| *k >= END_VARIABLES.len()).map(|k| k - END_VARIABLES.len()).collect(),
            );
        }
        // Depth-first topological order.
        let mut order: Vec<usize> = Vec::new();
        let mut state = vec![0u8; keys.len()]; // 0 new, 1 on the stack, 2 done
        fn visit(k: usize, deps: &[Vec<usize>], state: &mut [u8], order: &mut Vec<usize>) -> Result<(), usize> {
            match state[k] {
                2 => return Ok(()),
                1 => return Err(k),
                _ => {}
            }
            state[k] = 1;
            for &d in &deps[k] {
                visit(d, deps, state, order)?;
            }
            state[k] = 2;
            order.push(k);
            Ok(())
        }
        for k in 0..keys.len() {
            visit(k, &deps, &mut state, &mut order).map_err(|c| {
                self.loc.at(
                    s.pose[keys[c]].span(),
                    format!("pose quantities depend on each other in a cycle through `{}`", keys[c]),
                )
            })?;
        }
        let mut slots: BTreeMap<String, usize> =
            END_VARIABLES.iter().enumerate().map(|(k, n)| (n.to_string(), k)).collect();
        for (position, k) in order.iter().enumerate() {
            slots.insert(keys[*k].clone(), END_VARIABLES.len() + position);
        }
        Ok(Names { params: &self.params, slots })
    }

    pub(super) fn section_spec(&self, sec: &Spanned<SectionSpec>) -> Result<BeamSection, InputError> {
        let s = sec.get_ref();
        let e = self.positive(&s.e, "E")?;
        let g = self.shear_modulus(e, &s.g, &s.nu, sec.span())?;
        self.section(e, g, &s.diameter, [&s.area, &s.iy, &s.iz, &s.j], sec.span())
    }

    fn node_pair<F>(
        &self,
        nodes: &Spanned<Vec<Spanned<String>>>,
        index: &F,
    ) -> Result<(Option<usize>, usize), InputError>
    where
        F: Fn(&Spanned<String>) -> Result<usize, InputError>,
    {
        match nodes.get_ref().as_slice() {
            [a, b] if a.get_ref() == "base" => Ok((None, index(b)?)),
            [a, b] => {
                let (a, b) = (index(a)?, index(b)?);
                if a == b {
                    return Err(self.loc.at(nodes.span(), "a link or joint joins two different nodes"));
                }
                Ok((Some(a), b))
            }
            _ => Err(self.loc.at(nodes.span(), "give two nodes: [\"i\", \"j\"] (or [\"base\", \"j\"] for a joint)")),
        }
    }

    fn msa_link<F>(
        &self,
        link: &Spanned<MsaLinkSpec>,
        names: &Names,
        sections: &BTreeMap<String, BeamSection>,
        index: &F,
    ) -> Result<ElementTemplate, InputError>
    where
        F: Fn(&Spanned<String>) -> Result<usize, InputError>,
    {
        let s = link.get_ref();
        let (i, j) = self.node_pair(&s.nodes, index)?;
        let i = i.ok_or_else(|| self.loc.at(s.nodes.span(), "a link joins two nodes; the base takes a joint"))?;
        let refuse = |key: &str, present: bool| {
            if present {
                Err(self.loc.at(link.span(), format!("`{key}` does not apply to a `{}` link", s.kind.get_ref())))
            } else {
                Ok(())
            }
        };
        match s.kind.get_ref().as_str() {
            "beam" => {
                refuse("stiffness_matrix", s.stiffness_matrix.is_some())?;
                let name = s.section.as_ref().ok_or_else(|| self.loc.at(link.span(), "a beam needs a `section`"))?;
                let section = *sections.get(name.get_ref()).ok_or_else(|| {
                    self.loc.at(name.span(), format!("no section named `{}` in [leg.msa.sections]", name.get_ref()))
                })?;
                let y_axis = match &s.y_axis {
                    Some(a) => Some(self.axis_template(a, names)?),
                    None => None,
                };
                Ok(ElementTemplate::Beam { i, j, section, y_axis })
            }
            "rigid" => {
                refuse("section", s.section.is_some())?;
                refuse("y_axis", s.y_axis.is_some())?;
                refuse("stiffness_matrix", s.stiffness_matrix.is_some())?;
                Ok(ElementTemplate::Rigid { i, j })
            }
            "link" => {
                refuse("section", s.section.is_some())?;
                refuse("y_axis", s.y_axis.is_some())?;
                let m = s
                    .stiffness_matrix
                    .as_ref()
                    .ok_or_else(|| self.loc.at(link.span(), "a `link` needs its `stiffness_matrix`"))?;
                Ok(ElementTemplate::Link { i, j, kjj: self.matrix6(m, "stiffness_matrix")? })
            }
            other => Err(self.loc.at(s.kind.span(), format!("unknown link type `{other}`: use beam, rigid or link"))),
        }
    }

    /// An axis as three formulas (a named axis is constant).
    fn axis_template(&self, a: &Spanned<AxisSpec>, names: &Names) -> Result<[Expr; 3], InputError> {
        match a.get_ref() {
            AxisSpec::Named(_) => {
                let v = self.axis(a)?;
                Ok([Expr::Const(v.x), Expr::Const(v.y), Expr::Const(v.z)])
            }
            AxisSpec::Vector(c) => {
                let at = |k: usize| names.compile(&c[k]).map_err(|e| self.loc.at(a.span(), e));
                Ok([at(0)?, at(1)?, at(2)?])
            }
        }
    }

    /// A joint between two nodes of an MSA structure: its free and elastic directions, as templates
    /// evaluated at each pose.
    fn msa_joint<F>(
        &self,
        joint: &Spanned<MsaJointSpec>,
        names: &Names,
        index: &F,
    ) -> Result<ElementTemplate, InputError>
    where
        F: Fn(&Spanned<String>) -> Result<usize, InputError>,
    {
        let s = joint.get_ref();
        let kind = s.kind.get_ref().as_str();
        let (i, j) = self.node_pair(&s.nodes, index)?;
        self.check_joint_keys(joint, kind)?;
        let mut m = Motions::default();
        match kind {
            "rigid" => {}
            "spherical" => m.free.extend((3..6).map(unit_direction)),
            "revolute" | "prismatic" => m = self.axial_joint(joint, kind, names)?,
            "universal" => {
                let axes =
                    s.axes.as_ref().ok_or_else(|| self.loc.at(joint.span(), "a universal joint needs two `axes`"))?;
                if axes.get_ref().len() != 2 {
                    return Err(self.loc.at(axes.span(), "a universal joint has exactly two axes"));
                }
                for a in axes.get_ref() {
                    m.free.push(rotation_direction(self.axis_template(a, names)?));
                }
            }
            "free" => {
                let rows = s.free.as_ref().expect("checked by check_joint_keys");
                for row in rows.get_ref() {
                    let twist = std::array::from_fn(|k| names.compile(&row[k]));
                    if let Some(Err(e)) = twist.iter().find(|t| t.is_err()) {
                        return Err(self.loc.at(rows.span(), e.clone()));
                    }
                    m.free.push(DirectionTemplate { twist: twist.map(|t| t.expect("checked")) });
                }
            }
            "spring" => {
                let spec = s
                    .stiffness_matrix
                    .as_ref()
                    .ok_or_else(|| self.loc.at(joint.span(), "a `spring` joint needs its `stiffness_matrix`"))?;
                let k = self.matrix6(spec, "stiffness_matrix")?;
                m.elastic.extend((0..6).map(unit_direction));
                m.stiffness = DMatrix::from_fn(6, 6, |r, c| k[(r, c)]);
                m.preload = DVector::zeros(6);
            }
            _ => unreachable!("joint types are checked by check_joint_keys"),
        }
        let Motions { free, elastic, stiffness, preload } = m;
        Ok(ElementTemplate::Joint { i, j, free, elastic, stiffness, preload })
    }

    /// The joint's type is known and it has only the keys that apply to it.
    fn check_joint_keys(&self, joint: &Spanned<MsaJointSpec>, kind: &str) -> Result<(), InputError> {
        let s = joint.get_ref();
        let present = [
            ("axis", s.axis.is_some()),
            ("axes", s.axes.is_some()),
            ("free", s.free.is_some()),
            ("stiffness", s.stiffness.is_some()),
            ("preload", s.preload.is_some()),
            ("stiffness_matrix", s.stiffness_matrix.is_some()),
        ];
        let allowed: &[&str] = match kind {
            "rigid" | "spherical" => &[],
            "revolute" | "prismatic" => &["axis", "stiffness", "preload"],
            "universal" => &["axes"],
            "free" => &["free"],
            "spring" => &["stiffness_matrix"],
            other => {
                return Err(self.loc.at(
                    s.kind.span(),
                    format!("unknown joint type `{other}`: use rigid, revolute, prismatic, universal, spherical, free or spring"),
                ))
            }
        };
        if let Some((key, _)) = present.iter().find(|(k, p)| *p && !allowed.contains(k)) {
            return Err(self.loc.at(joint.span(), format!("`{key}` does not apply to a `{kind}` joint")));
        }
        Ok(())
    }

    /// A revolute or prismatic joint: free about / along its axis, or elastic with a stiffness (zero
    /// stiffness is a passive joint).
    fn axial_joint(&self, joint: &Spanned<MsaJointSpec>, kind: &str, names: &Names) -> Result<Motions, InputError> {
        let s = joint.get_ref();
        let a =
            s.axis.as_ref().ok_or_else(|| self.loc.at(joint.span(), format!("a `{kind}` joint needs an `axis`")))?;
        let a = self.axis_template(a, names)?;
        let d = if kind == "revolute" {
            rotation_direction(a)
        } else {
            let [x, y, z] = a;
            let zero = || Expr::Const(0.0);
            DirectionTemplate { twist: [x, y, z, zero(), zero(), zero()] }
        };
        let mut m = Motions::default();
        match &s.stiffness {
            // Zero stiffness is a passive joint (a clutch let go): no constraint, no spring.
            Some(k) => {
                let k = self.num(k)?;
                if !(k >= 0.0 && k.is_finite()) {
                    return Err(self.loc.at(joint.span(), format!("stiffness must be >= 0, got {k}")));
                }
                m.elastic.push(d);
                m.stiffness = DMatrix::from_element(1, 1, k);
                m.preload = DVector::from_element(
                    1,
                    match &s.preload {
                        Some(p) => self.num(p)?,
                        None => 0.0,
                    },
                );
            }
            None if s.preload.is_some() => {
                return Err(self.loc.at(joint.span(), "`preload` applies to an elastic joint: give a `stiffness`"))
            }
            None => m.free.push(d),
        }
        Ok(m)
    }
}

/// A joint's motions: free directions, elastic ones with their stiffness and rest values.
#[derive(Default)]
struct Motions {
    free: Vec<DirectionTemplate>,
    elastic: Vec<DirectionTemplate>,
    stiffness: DMatrix<f64>,
    preload: DVector<f64>,
}

/// A rotation about the axis `a` as a twist template.
fn rotation_direction(a: [Expr; 3]) -> DirectionTemplate {
    let zero = || Expr::Const(0.0);
    let [x, y, z] = a;
    DirectionTemplate { twist: [zero(), zero(), zero(), x, y, z] }
}

/// The unit twist along coordinate k.
fn unit_direction(k: usize) -> DirectionTemplate {
    DirectionTemplate { twist: std::array::from_fn(|r| Expr::Const(if r == k { 1.0 } else { 0.0 })) }
}

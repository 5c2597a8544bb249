//! A serial arm's leg from its URDF (`urdf.rs` reads the path from the root to the tip): per joint on the
//! path its fixed origin, the `[[joint_correction]]` geometry and frame compliance before it, the joint
//! with the spring `[leg.urdf] joints` gives it (a `<mimic>` joint on its master's coordinate), the link
//! springs `links` gives and the child link's mass; the tool transform last; and the arm's `JointSpace`
//! (its joints' names, the controller's angle map, the corrections' offsets).

use toml::Spanned;

use super::build::{Builder, ChainParts};
use super::error::{read_regular_file, InputError};
use super::schema::{JointCorrectionSpec, JointStiffnessSpec, LinkSpringSpec, TransformSpec, UrdfSpec};
use super::urdf::{UrdfChain, UrdfJoint, UrdfJointKind};
use crate::expr::{Expr, ExprSrc};
use crate::kinematics::chain::{Element, Joint, JointKind, Role};
use crate::kinematics::frame::{rotation_about, Frame, Mat6, Vec3};
use crate::platform::leg::Leg;
use crate::platform::manipulator::{CarriedMass, JointSpace};
use crate::vjm::spring::{one_coordinate, CoordinateStiffness, SIX_DOF};

/// The `[[joint_correction]]` tables of joint `name`, in file order.
fn corrections_of<'a>(
    corrections: &'a [Spanned<JointCorrectionSpec>],
    name: &'a str,
) -> impl Iterator<Item = &'a JointCorrectionSpec> + 'a {
    corrections.iter().map(Spanned::get_ref).filter(move |c| c.joint.get_ref() == name)
}

/// One URDF description being built: its table, the chains read from its file (one per tip), the
/// skeleton they make and the corrections.
struct UrdfLeg<'s> {
    spec: &'s Spanned<UrdfSpec>,
    path: std::path::PathBuf,
    /// The tips, as the description names them.
    tips: Vec<String>,
    /// Per tip, its chain from the root.
    chains: Vec<UrdfChain>,
    /// The joints of every chain, each once: the first chain's in order, then each later chain's new ones.
    joints: Vec<UrdfJoint>,
    /// The moving joints off the skeleton that a joint of it mimics, each once.
    masters: Vec<UrdfJoint>,
    corrections: &'s [Spanned<JointCorrectionSpec>],
}

impl<'s> UrdfLeg<'s> {
    fn new(
        spec: &'s Spanned<UrdfSpec>,
        path: std::path::PathBuf,
        tips: Vec<String>,
        chains: Vec<UrdfChain>,
        corrections: &'s [Spanned<JointCorrectionSpec>],
    ) -> Self {
        let mut joints: Vec<UrdfJoint> = Vec::new();
        let mut masters: Vec<UrdfJoint> = Vec::new();
        for c in &chains {
            for j in &c.joints {
                if !joints.iter().any(|k| k.name == j.name) {
                    joints.push(j.clone());
                }
            }
        }
        for c in &chains {
            for m in &c.masters {
                if !masters.iter().any(|k| k.name == m.name) && !joints.iter().any(|k| k.name == m.name) {
                    masters.push(m.clone());
                }
            }
        }
        UrdfLeg { spec, path, tips, chains, joints, masters, corrections }
    }

    fn u(&self) -> &UrdfSpec {
        self.spec.get_ref()
    }

    /// `the chain from ROOT to TIP of FILE` (or `the chains from ROOT to TIP, TIP`), as the messages name it.
    fn chain_named(&self) -> String {
        let (chains, tips) = match self.tips.len() {
            1 => ("chain", format!("`{}`", self.tips[0])),
            _ => ("chains", self.tips.iter().map(|t| format!("`{t}`")).collect::<Vec<_>>().join(", ")),
        };
        format!("the {chains} from `{}` to {tips} of {}", self.u().root.get_ref(), self.path.display())
    }
}

impl Builder<'_> {
    /// The tips a `[leg.urdf]` names: `tip`, or the list `tips` (a tree with several reference points).
    fn urdf_tips(&self, spec: &Spanned<UrdfSpec>) -> Result<Vec<String>, InputError> {
        let u = spec.get_ref();
        match (&u.tip, &u.tips) {
            (Some(t), None) => Ok(vec![t.get_ref().clone()]),
            (None, Some(list)) if !list.get_ref().is_empty() => {
                if u.tool.is_some() && list.get_ref().len() > 1 {
                    return Err(self.loc.at(
                        spec.span(),
                        "with several tips, give each its tool transform in `tools` (`tools.<tip> = { translation = [...] }`), not `tool`",
                    ));
                }
                Ok(list.get_ref().iter().map(|t| t.get_ref().clone()).collect())
            }
            (None, Some(list)) => Err(self.loc.at(list.span(), "`tips` names no link: give at least one")),
            _ => Err(self.loc.at(
                spec.span(),
                "`[leg.urdf]` needs exactly one of `tip` (the link the chain ends at) and `tips` (several, for a tree)",
            )),
        }
    }

    /// The legs read from URDF (`crate::model::urdf`), one per tip, sharing their coordinates and springs
    /// (`JointSpace::tips`): per joint of each path, its fixed origin, then the joint (actuated, with the
    /// spring `joints` gives it; a `<mimic>` joint driven by its master's coordinate times the multiplier,
    /// after its offset), then the child link's mass (in the first chain that reaches it); each tip's tool
    /// transform last. Returns the legs (the first tip's first) and their joint space (the actuated joints'
    /// names and the controller's map).
    pub(super) fn urdf_legs(
        &self,
        leg_name: &str,
        spec: &Spanned<UrdfSpec>,
        gravity: Vec3,
        corrections: &[Spanned<JointCorrectionSpec>],
    ) -> Result<(Vec<Leg>, JointSpace), InputError> {
        let u = spec.get_ref();
        let tips = self.urdf_tips(spec)?;
        let path = super::urdf::resolve(self.loc.path, u.file.get_ref());
        let text = read_regular_file(&path)?;
        let tip_names: Vec<&str> = tips.iter().map(String::as_str).collect();
        let chains = super::urdf::read_tree(&path, &text, u.root.get_ref(), &tip_names)?;
        let arm = UrdfLeg::new(spec, path, tips, chains, corrections);
        self.check_urdf_names(&arm)?;
        // The model's coordinates: the skeleton's moving joints that mimic none, then the masters off it that
        // its <mimic> joints follow; each with its spring (None: rigid), made into a spring group where the
        // skeleton first reads the coordinate.
        let coordinates: Vec<&UrdfJoint> = arm
            .joints
            .iter()
            .filter(|j| j.kind != UrdfJointKind::Fixed && j.mimic.is_none())
            .chain(&arm.masters)
            .collect();
        let names: Vec<String> = coordinates.iter().map(|j| j.name.clone()).collect();
        if names.is_empty() {
            return Err(self.loc.at(spec.span(), format!("{} has no moving joint", arm.chain_named())));
        }
        let springs = coordinates
            .iter()
            .enumerate()
            .map(|(c, j)| self.joint_spring(&arm, j, Some(c)))
            .collect::<Result<Vec<_>, _>>()?;
        let mut spring_first: Vec<Option<usize>> = vec![None; names.len()];
        let mut parts = ChainParts::default();
        self.link_spring(u, u.root.get_ref(), &mut parts)?;
        let root_elements: Vec<Element> = parts.elements.drain(..).collect();
        // Each joint of the skeleton's elements, made once (its springs are one set of coordinates, whichever
        // chains pass through it); its child link's mass joins only the chain that carries it.
        let mut segments: Vec<Vec<Element>> = Vec::with_capacity(arm.joints.len());
        for j in &arm.joints {
            self.joint_segment(&arm, j, &names, &springs, &mut spring_first, &mut parts)?;
            segments.push(parts.elements.drain(..).collect());
        }
        let mut chains = Vec::with_capacity(arm.tips.len());
        for (tip, chain) in arm.tips.iter().zip(&arm.chains) {
            let mut elements = root_elements.clone();
            for j in &chain.joints {
                let k = arm.joints.iter().position(|s| s.name == j.name).expect("a chain's joint is on the skeleton");
                elements.extend(segments[k].iter().cloned());
                if let Some((kg, centre)) = j.child_mass {
                    elements.push(Element::Mass { kg, centre });
                }
            }
            if let Some(tool) = self.tool_of(&arm, tip)? {
                elements.push(Element::Fixed(tool));
            }
            let name = if arm.tips.len() == 1 { leg_name.to_string() } else { format!("{leg_name}.{tip}") };
            chains.push((name, elements));
        }
        let controller = self.controller_map(u, &names)?;
        let offsets = self.joint_offsets(corrections, &names)?;
        let play = self.joint_play(corrections, &names)?;
        let limits = coordinates.iter().map(|j| j.limits).collect();
        let masses = arm.chains[0].masses;
        let carried = CarriedMass { kg: masses.carried, off_path_kg: masses.off_path, on_base_kg: masses.on_base };
        let space = JointSpace { names, controller, offsets, play, limits, carried, tips: arm.tips.clone() };
        let mut legs = parts.into_tree_legs(chains, space.names.len(), gravity);
        if !u.seed.is_empty() {
            // The seed is given in the controller's angles, like the points: mapped to the model's coordinates.
            let angles = space
                .names
                .iter()
                .map(|n| u.seed.get(n).map_or(Ok(0.0), |v| self.num(v)))
                .collect::<Result<Vec<f64>, InputError>>()?;
            let home = space.model_coordinates(&angles);
            for leg in &mut legs {
                if let Leg::Vjm(v) = leg {
                    v.home = home.clone();
                }
            }
        }
        Ok((legs, space))
    }

    /// The tool transform of `tip` (`tool`, or `tools.<tip>`), None where none is given.
    fn tool_of(&self, arm: &UrdfLeg, tip: &str) -> Result<Option<Frame>, InputError> {
        let u = arm.u();
        let spec = match &u.tool {
            Some(t) => Some(t),
            None => u.tools.get(tip).map(Spanned::get_ref),
        };
        spec.map(|TransformSpec { translation, rotation_axis, rotation_deg }| {
            self.transform(translation, rotation_axis, rotation_deg, arm.spec.span())
        })
        .transpose()
    }

    /// The elements of joint `j` of the skeleton, pushed to `parts`: its fixed origin; for a moving joint the
    /// corrections' geometry and frame compliance, the joint on its coordinate (a <mimic> joint on its
    /// master's, after the offset) and the coordinate's spring (made where the coordinate is first read, a
    /// virtual joint on it after), a <mimic> joint's own spring in series; its child link's spring.
    fn joint_segment(
        &self,
        arm: &UrdfLeg,
        j: &UrdfJoint,
        names: &[String],
        springs: &[Option<(f64, Option<CoordinateStiffness>)>],
        spring_first: &mut [Option<usize>],
        parts: &mut ChainParts,
    ) -> Result<(), InputError> {
        parts.elements.push(Element::Fixed(j.origin));
        let kind = match j.kind {
            UrdfJointKind::Fixed => None,
            UrdfJointKind::Revolute => Some(JointKind::Revolute),
            UrdfJointKind::Prismatic => Some(JointKind::Prismatic),
        };
        if let Some(jk) = kind {
            if let Some(change) = self.geometry_change(arm.corrections, &j.name)? {
                parts.elements.push(Element::Fixed(change));
            }
            self.frame_compliance(arm.corrections, &j.name, parts)?;
            let (coordinate, gain) = match self.master_of(arm, j)? {
                Some((master, gain, offset)) => {
                    if offset != 0.0 {
                        parts.elements.push(Element::Fixed(joint_motion(jk, &j.axis, offset)));
                    }
                    (names.iter().position(|n| *n == master).expect("a master is a coordinate"), gain)
                }
                None => (names.iter().position(|n| *n == j.name).expect("a joint mimicking none is a coordinate"), 1.0),
            };
            let joint = Joint { kind: jk, axis: j.axis, role: Role::Actuated, index: coordinate, gain };
            parts.elements.push(Element::Joint(joint));
            // The coordinate's spring deflects every joint that reads it, by its gain: a mimic joint is a
            // transmission its master's spring drives (the URDF relation holds under load).
            if let Some((compliance, of_coordinate)) = &springs[coordinate] {
                match spring_first[coordinate] {
                    Some(first) => parts.elements.push(Element::Joint(Joint {
                        kind: jk,
                        axis: j.axis,
                        role: Role::Virtual,
                        index: first,
                        gain,
                    })),
                    None => {
                        spring_first[coordinate] = Some(parts.n_virtual());
                        let (km, cm) = one_coordinate(*compliance);
                        parts.spring(names[coordinate].clone(), &[(jk, j.axis)], km, cm, &[0.0], None);
                        parts.springs.last_mut().expect("just pushed").of_coordinate = of_coordinate.clone();
                        if let Some(Element::Joint(v)) = parts.elements.last_mut() {
                            v.gain = gain;
                        }
                    }
                }
            }
            // A mimic joint's own compliance, in series after the transmission.
            if j.mimic.is_some() {
                if let Some((compliance, _)) = self.joint_spring(arm, j, None)? {
                    let (km, cm) = one_coordinate(compliance);
                    parts.spring(j.name.clone(), &[(jk, j.axis)], km, cm, &[0.0], None);
                }
            }
        }
        self.link_spring(arm.u(), &j.child, parts)
    }

    /// Every joint the description names (`joints`, `controller`, `seed`, `[[joint_correction]]`) is a
    /// moving joint of the path with a coordinate of its own, and every link `links` names is on the path.
    fn check_urdf_names(&self, arm: &UrdfLeg) -> Result<(), InputError> {
        let u = arm.u();
        let on_path: Vec<&str> = arm.joints.iter().map(|j| j.name.as_str()).collect();
        // What a table may name: a coordinate (a moving joint of the path that mimics none, or a master off
        // the path that one follows), or any moving joint of the path (a <mimic> joint has a place there:
        // its own spring in series, its frame and geometry).
        let named_joint = |name: &str, span: std::ops::Range<usize>, table: &str, on_chain: bool| {
            let path_joint = arm.joints.iter().find(|j| j.name == name);
            let master = arm.masters.iter().any(|j| j.name == name);
            match path_joint {
                Some(j) if j.kind == UrdfJointKind::Fixed => {
                    Err(self.loc.at(span, format!("joint `{name}` in `{table}` is fixed: it does not move")))
                }
                Some(j) if j.mimic.is_some() && !on_chain => Err(self.loc.at(
                    span,
                    format!(
                        "joint `{name}` in `{table}` is a <mimic> joint: it has no coordinate of its own (name its master, `{}`)",
                        j.mimic.as_ref().map_or("", |m| m.0.as_str())
                    ),
                )),
                Some(_) => Ok(()),
                None if master && !on_chain => Ok(()),
                None if master => Err(self.loc.at(
                    span,
                    format!("joint `{name}` in `{table}` is off {}: only the <mimic> joints that follow it are on it", arm.chain_named()),
                )),
                None => Err(self.loc.at(
                    span,
                    format!("joint `{name}` in `{table}` is not on {} (joints: {})", arm.chain_named(), on_path.join(", ")),
                )),
            }
        };
        let is_master = |name: &str| arm.masters.iter().any(|m| m.name == name);
        // A spring may sit on a coordinate or, for a <mimic> joint, in series after its transmission.
        for (name, j) in &u.joints {
            named_joint(name, j.span(), "joints", !is_master(name))?;
        }
        for (name, f) in &u.controller {
            named_joint(name, f.span(), "controller", false)?;
        }
        for (name, v) in &u.seed {
            named_joint(name, v.span(), "seed", false)?;
        }
        for c in arm.corrections {
            let c = c.get_ref();
            let (name, span) = (c.joint.get_ref().as_str(), c.joint.span());
            if c.offset.is_some() || c.play.is_some() {
                named_joint(name, span.clone(), "joint_correction", false)?;
            }
            if c.geometry.is_some() || c.frame_compliance.is_some() {
                named_joint(name, span.clone(), "joint_correction", true)?;
            }
            if c.compliance.is_some() {
                named_joint(name, span, "joint_correction", !is_master(name))?;
            }
        }
        for (tip, t) in &u.tools {
            if !arm.tips.contains(tip) {
                return Err(self
                    .loc
                    .at(t.span(), format!("`tools.{tip}`: `{tip}` is not one of the tips ({})", arm.tips.join(", "))));
            }
        }
        let links: Vec<&str> =
            std::iter::once(u.root.get_ref().as_str()).chain(arm.joints.iter().map(|j| j.child.as_str())).collect();
        for (name, l) in &u.links {
            if !links.contains(&name.as_str()) {
                return Err(self.loc.at(
                    l.span(),
                    format!("link `{name}` in `links` is not on {} (links: {})", arm.chain_named(), links.join(", ")),
                ));
            }
        }
        Ok(())
    }

    /// A link's 6-dof spring at its frame, where `links` gives one.
    fn link_spring(&self, u: &UrdfSpec, name: &str, parts: &mut ChainParts) -> Result<(), InputError> {
        let Some(l) = u.links.get(name) else { return Ok(()) };
        let LinkSpringSpec { stiffness_matrix, compliance_matrix, beam } = l.get_ref();
        let exactly_one = "a link's spring needs exactly one of `stiffness_matrix`, `compliance_matrix` and `beam`";
        let (compliance, axis) =
            self.six_dof_compliance(l.span(), stiffness_matrix, compliance_matrix, beam, exactly_one)?;
        let (stiffness, compliance) = self.invertible(l.span(), compliance)?;
        parts.spring(name.to_string(), &SIX_DOF, stiffness, compliance, &[0.0; 6], None);
        if let Some(spring) = parts.springs.last_mut() {
            spring.beam_axis = axis;
        }
        Ok(())
    }

    /// A joint's spring: its compliance (for a formula of its coordinate, the value at zero, which stands for
    /// it where one number is asked) with the corrections' added compliance, and the formula; None: rigid.
    /// `coordinate`: the joint's coordinate, or None for a mimic joint's own spring in series with its
    /// transmission (a number: a formula of its coordinate has none to read).
    fn joint_spring(
        &self,
        arm: &UrdfLeg,
        j: &UrdfJoint,
        coordinate: Option<usize>,
    ) -> Result<Option<(f64, Option<CoordinateStiffness>)>, InputError> {
        let joint_spec = arm.u().joints.get(&j.name);
        let added = self.added_compliance(arm.corrections, &j.name)?;
        if let Some((stiffness, formula)) = joint_spec.map(|k| self.coordinate_stiffness(k)).transpose()?.flatten() {
            let Some(coordinate) = coordinate else {
                return Err(self.loc.at(
                    joint_spec.expect("a formula was read").span(),
                    format!(
                        "joint `{}` is a <mimic> joint: its own stiffness is a number, not a formula of `q`",
                        j.name
                    ),
                ));
            };
            let of_coordinate =
                CoordinateStiffness { coordinate, stiffness, formula, added_compliance: added, compliance_factor: 1.0 };
            return Ok(Some((of_coordinate.compliance(&Default::default()), Some(of_coordinate))));
        }
        let given = joint_spec.map(|k| self.joint_stiffness(k)).transpose()?;
        let compliance = given.map_or(0.0, |k| 1.0 / k) + added;
        if compliance < 0.0 || (compliance == 0.0 && given.is_some()) {
            return Err(self.loc.at(
                arm.spec.span(),
                format!("joint `{}`: its compliance with the correction added is {compliance:e}, not positive", j.name),
            ));
        }
        Ok((compliance > 0.0).then_some((compliance, None)))
    }

    /// A joint's added compliance: the sum of its corrections'.
    fn added_compliance(&self, corrections: &[Spanned<JointCorrectionSpec>], name: &str) -> Result<f64, InputError> {
        let mut sum = 0.0;
        for c in corrections_of(corrections, name) {
            if let Some(v) = &c.compliance {
                sum += self.num(v)?;
            }
        }
        Ok(sum)
    }

    /// The change of the fixed transform leading to a joint: its corrections' geometries composed.
    fn geometry_change(
        &self,
        corrections: &[Spanned<JointCorrectionSpec>],
        name: &str,
    ) -> Result<Option<Frame>, InputError> {
        let mut moved: Option<Frame> = None;
        for c in corrections_of(corrections, name) {
            if let Some(g) = &c.geometry {
                let v: Vec<f64> = g.iter().map(|n| self.num(n)).collect::<Result<_, _>>()?;
                let change = Frame::new(
                    crate::kinematics::frame::rotation_from_vector(&Vec3::new(v[3], v[4], v[5])),
                    Vec3::new(v[0], v[1], v[2]),
                );
                moved = Some(moved.map_or(change, |m| m.compose(&change)));
            }
        }
        Ok(moved)
    }

    /// A joint's frame compliance: the directions the corrections make compliant (summed), each a virtual
    /// joint of one spring at the frame leading to the joint.
    fn frame_compliance(
        &self,
        corrections: &[Spanned<JointCorrectionSpec>],
        name: &str,
        parts: &mut ChainParts,
    ) -> Result<(), InputError> {
        let mut sum = [0.0; 6];
        let mut span = None;
        for c in corrections_of(corrections, name) {
            if let Some(v) = &c.frame_compliance {
                for (s, n) in sum.iter_mut().zip(v.get_ref()) {
                    *s += self.num(n)?;
                }
                span = Some(v.span());
            }
        }
        let Some(span) = span else { return Ok(()) };
        if sum.iter().any(|c| !(c.is_finite() && *c >= 0.0)) {
            return Err(self.loc.at(
                span,
                format!("joint `{name}`: its frame compliance {sum:?} must be finite and >= 0 in every direction (0: rigid)"),
            ));
        }
        let directions: Vec<usize> = (0..6).filter(|&k| sum[k] > 0.0).collect();
        let (mut stiffness, mut compliance) = (Mat6::zeros(), Mat6::zeros());
        for (i, &k) in directions.iter().enumerate() {
            compliance[(i, i)] = sum[k];
            stiffness[(i, i)] = 1.0 / sum[k];
        }
        let joints: Vec<(JointKind, Vec3)> = directions.iter().map(|&k| SIX_DOF[k]).collect();
        if !joints.is_empty() {
            parts.spring(format!("{name} frame"), &joints, stiffness, compliance, &vec![0.0; joints.len()], None);
        }
        Ok(())
    }

    /// A mimic joint's ultimate master (a mimic of a mimic composed), its gain and offset; None for a joint
    /// with a coordinate of its own.
    fn master_of(&self, arm: &UrdfLeg, j: &UrdfJoint) -> Result<Option<(String, f64, f64)>, InputError> {
        let Some((mut master, mut gain, mut offset)) = j.mimic.clone() else { return Ok(None) };
        let mut seen = vec![j.name.clone()];
        loop {
            if seen.contains(&master) {
                seen.push(master);
                return Err(self.loc.at(
                    arm.spec.span(),
                    format!("{}: the <mimic> joints form a loop: {}", arm.path.display(), seen.join(" -> ")),
                ));
            }
            let m = arm.joints.iter().chain(&arm.masters).find(|k| k.name == master).ok_or_else(|| {
                self.loc.at(
                    arm.spec.span(),
                    format!("{}: joint `{}` mimics `{master}`, which is not on the chain", arm.path.display(), j.name),
                )
            })?;
            match &m.mimic {
                Some((next, k, o)) => {
                    seen.push(master.clone());
                    offset += gain * o;
                    gain *= k;
                    master = next.clone();
                }
                None => return Ok(Some((master, gain, offset))),
            }
        }
    }

    /// The controller's angle map: per joint, its formula over the joints' angles and the parameters, where
    /// `controller` gives one (None: the angle is the coordinate).
    fn controller_map(&self, u: &UrdfSpec, names: &[String]) -> Result<Vec<Option<Expr>>, InputError> {
        names
            .iter()
            .map(|n| {
                u.controller
                    .get(n)
                    .map(|f| {
                        crate::expr::compile(
                            f.get_ref(),
                            &mut |name: &str| match names.iter().position(|m| m == name) {
                                Some(i) => Ok(Expr::Slot(i)),
                                None => self.params.get(name).map(|v| Expr::Const(*v)).ok_or_else(|| {
                                    format!("unknown name `{name}` (the joints: {}; or a parameter)", names.join(", "))
                                }),
                            },
                        )
                        .map_err(|e| self.loc.at(f.span(), e))
                    })
                    .transpose()
            })
            .collect()
    }

    /// Each joint's offset added to its controller angle: its corrections' offsets summed.
    fn joint_offsets(
        &self,
        corrections: &[Spanned<JointCorrectionSpec>],
        names: &[String],
    ) -> Result<Vec<f64>, InputError> {
        summed_per_joint(corrections, names, |c| c.get_ref().offset.as_ref().map(|o| self.num(o)).transpose())
    }

    /// Each joint's play: its corrections' plays summed, each zero or above.
    fn joint_play(
        &self,
        corrections: &[Spanned<JointCorrectionSpec>],
        names: &[String],
    ) -> Result<Vec<f64>, InputError> {
        summed_per_joint(corrections, names, |c| {
            let Some(b) = &c.get_ref().play else { return Ok(None) };
            let value = self.num(b)?;
            if !(value.is_finite() && value >= 0.0) {
                return Err(self.loc.at(
                    c.span(),
                    format!(
                        "`play` of joint `{}` is {value}: a play is a width, zero or above (rad, or mm for a prismatic joint)",
                        c.get_ref().joint.get_ref()
                    ),
                ));
            }
            Ok(Some(value))
        })
    }

    /// A URDF joint's spring stiffness: `stiffness`, or the inverse of `compliance`.
    /// A joint's stiffness given as a formula of its own coordinate `q` (rad, or mm for a prismatic joint;
    /// a gravity compensator's joint), compiled with the parameters' values as constants, with the text
    /// it was written as: None where the spring is a number.
    fn coordinate_stiffness(&self, k: &Spanned<JointStiffnessSpec>) -> Result<Option<(Expr, String)>, InputError> {
        let spec = k.get_ref();
        let (n, inverted) = match (&spec.stiffness, &spec.compliance) {
            (Some(s), None) => (s, false),
            (None, Some(c)) => (c, true),
            _ => return Ok(None),
        };
        let ExprSrc::Formula(text) = n.get_ref() else { return Ok(None) };
        let mut uses_q = false;
        let mut resolve = |name: &str| -> Result<Expr, String> {
            match self.params.get(name) {
                Some(v) => Ok(Expr::Const(*v)),
                None if name == "q" => {
                    uses_q = true;
                    Ok(Expr::Slot(0))
                }
                None => Err(format!("unknown parameter `{name}` (`q` is the joint's own coordinate)")),
            }
        };
        let formula = n.get_ref().compile(&mut resolve).map_err(|e| self.loc.at(n.span(), e))?;
        if !uses_q {
            return Ok(None);
        }
        let formula = match inverted {
            true => Expr::Binary(crate::expr::Op::Div, Box::new(Expr::Const(1.0)), Box::new(formula)),
            false => formula,
        };
        let written = if inverted { format!("1 / ({text})") } else { text.clone() };
        Ok(Some((formula, written)))
    }

    fn joint_stiffness(&self, k: &Spanned<JointStiffnessSpec>) -> Result<f64, InputError> {
        match (&k.get_ref().stiffness, &k.get_ref().compliance) {
            (Some(s), None) => self.positive(s, "stiffness"),
            (None, Some(c)) => Ok(1.0 / self.positive(c, "compliance")?),
            _ => Err(self.loc.at(k.span(), "give exactly one of `stiffness` (N mm/rad or N/mm) and `compliance`")),
        }
    }
}

/// Per joint of `names`, the sum of what `read` gives of each correction naming it (its joint checked on
/// the path before), zero where none gives anything.
fn summed_per_joint(
    corrections: &[Spanned<JointCorrectionSpec>],
    names: &[String],
    read: impl Fn(&Spanned<JointCorrectionSpec>) -> Result<Option<f64>, InputError>,
) -> Result<Vec<f64>, InputError> {
    let mut sums = vec![0.0; names.len()];
    for c in corrections {
        if let Some(v) = read(c)? {
            let k = names.iter().position(|n| n == c.get_ref().joint.get_ref()).expect("checked on the path");
            sums[k] += v;
        }
    }
    Ok(sums)
}

/// A joint's motion by `value` (rad, or mm for a prismatic joint) along its axis: a mimic joint's offset.
fn joint_motion(kind: JointKind, axis: &Vec3, value: f64) -> Frame {
    match kind {
        JointKind::Revolute => Frame::new(rotation_about(axis, value), Vec3::zeros()),
        JointKind::Prismatic => Frame::translation(axis * value),
    }
}

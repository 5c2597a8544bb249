//! Validation of a parsed description into engine types: formulas evaluated, axes normalised, springs
//! checked symmetric positive definite, each error located in the file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use toml::Spanned;

use super::effect::{with_model_effects, Effect, EffectError, Form, Kind};
use super::error::{read_text, InputError, Locator};
use super::schema::{
    AxisSpec, BeamSpec, ElementSpec, JointCorrectionSpec, LegSpec, ModelFile, Num, ParallelogramSpec, TransformSpec,
};
use crate::beam::{beam_compliance, BeamSection};
use crate::expr::ExprSrc;
use crate::expr::Scope;
use crate::kinematics::chain::{Chain, Element, Joint, JointKind, Role};
use crate::kinematics::frame::{rotation_about, Frame, Mat6, Vec3};
use crate::platform::leg::{Leg, VjmLeg};
use crate::platform::manipulator::{JointSpace, Manipulator, Payload};
use crate::platform::msa_leg::MsaLeg;
use crate::vjm::parallelogram::Parallelogram;
use crate::vjm::spring::{SpringGroup, SIX_DOF};

/// A description as built: the manipulator (with the spring scalings of its `[[effect]]` entries applied)
/// and, side by side, the effects that are terms of the measurement model (used by diagnose and synth).
#[derive(Clone, Debug)]
pub struct Model {
    /// The manipulator every study analyses.
    pub manipulator: Manipulator,
    /// `[[effect]]` entries that are measurement-model terms (`Form::Measurement`: leg geometry, tool offset,
    /// backlash, ...); the model-form ones are built into `manipulator`.
    pub measurement_terms: Vec<Effect>,
}

impl Model {
    /// A manipulator with no measurement-model terms.
    pub fn nominal(manipulator: Manipulator) -> Model {
        Model { manipulator, measurement_terms: Vec::new() }
    }
}

/// Reads and validates a description, with its `[[effect]]` entries.
pub fn load_model(path: &Path) -> Result<Model, InputError> {
    let source = read_text(path)?;
    parse_with(path, &source, &BTreeMap::new(), 0)
}

/// Reads and validates a manipulator description (its spring scalings applied).
pub fn load_manipulator(path: &Path) -> Result<Manipulator, InputError> {
    Ok(load_model(path)?.manipulator)
}

/// As `load_manipulator`, from the file's text.
pub fn parse_manipulator(path: &Path, source: &str) -> Result<Manipulator, InputError> {
    Ok(parse_with(path, source, &BTreeMap::new(), 0)?.manipulator)
}

/// As `load_model`, from the file's text, with some parameters replaced by given values (a parametric
/// study, or a leg taken `from` this file by another), `depth` files down a chain of `from`.
pub fn parse_with(
    path: &Path,
    source: &str,
    overrides: &BTreeMap<String, f64>,
    depth: usize,
) -> Result<Model, InputError> {
    let loc = Locator { path, source };
    let file: ModelFile = toml::from_str(source).map_err(|e| loc.syntax(e))?;
    let params = file_parameters(&loc, &file, overrides)?;
    let b = Builder { loc, params };
    b.model(&file, depth)
}

/// The evaluated parameters of a model file: its own, those it shares by `parameters_from`, with
/// `overrides` replacing some.
fn file_parameters(
    loc: &Locator,
    file: &ModelFile,
    overrides: &BTreeMap<String, f64>,
) -> Result<BTreeMap<String, f64>, InputError> {
    let mut specs = file.parameters.clone();
    if let Some(other) = &file.parameters_from {
        let other_path = loc.path.parent().unwrap_or(Path::new(".")).join(other.get_ref());
        let other_source = read_text(&other_path)?;
        let other_loc = Locator { path: &other_path, source: &other_source };
        let other_file: ModelFile = toml::from_str(&other_source).map_err(|e| other_loc.syntax(e))?;
        for (name, value) in evaluate_parameters(&other_loc, &other_file.parameters)? {
            if let Some(mine) = specs.get(&name) {
                return Err(
                    loc.at(mine.span(), format!("parameter `{name}` is already given by `{}`", other.get_ref()))
                );
            }
            specs.insert(name, Spanned::new(other.span(), ExprSrc::Number(value)));
        }
    }
    for (name, value) in overrides {
        let Some(spec) = specs.get(name) else {
            return Err(loc.whole(format!("no parameter `{name}` to override")));
        };
        let span = spec.span();
        specs.insert(name.clone(), Spanned::new(span, ExprSrc::Number(*value)));
    }
    evaluate_parameters(loc, &specs)
}

/// The files a description at `path` reads besides itself (`parameters_from`, legs taken `from` other
/// files, and theirs), in the order it reads them: what a run's fingerprint must hash with it.
pub fn referenced_files(path: &Path) -> Result<Vec<PathBuf>, InputError> {
    let mut found = Vec::new();
    collect_referenced(path, 0, &mut found)?;
    Ok(found)
}

fn collect_referenced(path: &Path, depth: usize, found: &mut Vec<PathBuf>) -> Result<(), InputError> {
    let source = read_text(path)?;
    let loc = Locator { path, source: &source };
    let file: ModelFile = toml::from_str(&source).map_err(|e| loc.syntax(e))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let others =
        file.parameters_from.iter().chain(file.legs.get_ref().iter().filter_map(|l| l.get_ref().from.as_ref()));
    for other in others {
        let other_path = dir.join(other.get_ref());
        if depth >= 8 {
            return Err(loc.at(other.span(), "`from` nests more than 8 files deep (a cycle?)"));
        }
        found.push(other_path.clone());
        collect_referenced(&other_path, depth + 1, found)?;
    }
    Ok(())
}

/// The evaluated parameters of the model file at `path` (for errors given as parameter values).
pub fn parameter_values(path: &Path, source: &str) -> Result<BTreeMap<String, f64>, InputError> {
    let loc = Locator { path, source };
    let file: ModelFile = toml::from_str(source).map_err(|e| loc.syntax(e))?;
    file_parameters(&loc, &file, &BTreeMap::new())
}

/// Evaluates every parameter (parameters may use each other, in any order, without cycles).
fn evaluate_parameters(loc: &Locator, specs: &BTreeMap<String, Num>) -> Result<BTreeMap<String, f64>, InputError> {
    struct Params<'a> {
        specs: &'a BTreeMap<String, Num>,
        done: BTreeMap<String, f64>,
        stack: Vec<String>,
    }
    impl Scope for Params<'_> {
        fn lookup(&mut self, name: &str) -> Result<f64, String> {
            if let Some(v) = self.done.get(name) {
                return Ok(*v);
            }
            let spec = self.specs.get(name).ok_or_else(|| format!("unknown parameter `{name}`"))?;
            if self.stack.iter().any(|s| s == name) {
                return Err(format!(
                    "parameters depend on each other in a cycle: {} -> {name}",
                    self.stack.join(" -> ")
                ));
            }
            self.stack.push(name.to_string());
            let r = spec.get_ref().eval(self);
            self.stack.pop();
            let v = r?;
            self.done.insert(name.to_string(), v);
            Ok(v)
        }
    }
    let mut p = Params { specs, done: BTreeMap::new(), stack: Vec::new() };
    for (name, spec) in specs {
        if name == "pi" {
            return Err(loc.at(spec.span(), "`pi` is built in and cannot be a parameter name"));
        }
        p.lookup(name).map_err(|e| loc.at(spec.span(), format!("parameter `{name}`: {e}")))?;
    }
    Ok(p.done)
}

pub(super) struct Builder<'a> {
    pub(super) loc: Locator<'a>,
    pub(super) params: BTreeMap<String, f64>,
}

/// Largest translation of a transform (mm): ten kilometres is no robot, and past it products overflow.
const MAX_TRANSLATION_MM: f64 = 1e7;

/// Coordinates and springs collected while walking one chain.
#[derive(Default)]
pub(super) struct ChainParts {
    pub(super) elements: Vec<Element>,
    pub(super) springs: Vec<SpringGroup>,
    preload: Vec<f64>,
    /// Passive joints by name, with their coordinate index (for `follows` and parallelogram angles).
    passive_names: Vec<(String, usize)>,
    n_actuated: usize,
    n_passive: usize,
    n_virtual: usize,
}

impl ChainParts {
    /// The leg these parts make, written once (not copied, not placed), its masses under `gravity`.
    pub(super) fn into_leg(self, name: String, gravity: Vec3) -> Leg {
        let chain = Chain::new(self.elements);
        let length_scale = chain.length_scale().max(1.0);
        Leg::Vjm(VjmLeg {
            name,
            place: Frame::IDENTITY,
            preload: self.preload,
            gravity,
            chain,
            attachment: Frame::IDENTITY,
            springs: self.springs,
            length_scale,
            home: Vec::new(),
        })
    }

    /// The legs of a tree with several tips: one per chain (its name and elements), all reading one set of
    /// `n_actuated` coordinates and these parts' virtual ones, each carrying the springs (the serial route,
    /// `platform/serial.rs`, counts them once), their length scale the largest chain's.
    pub(super) fn into_tree_legs(
        self,
        chains: Vec<(String, Vec<Element>)>,
        n_actuated: usize,
        gravity: Vec3,
    ) -> Vec<Leg> {
        let chains: Vec<(String, Chain)> = chains
            .into_iter()
            .map(|(name, elements)| (name, Chain::with_coordinates(elements, n_actuated, 0, self.n_virtual)))
            .collect();
        let length_scale = chains.iter().map(|(_, c)| c.length_scale()).fold(1.0, f64::max);
        chains
            .into_iter()
            .map(|(name, chain)| {
                Leg::Vjm(VjmLeg {
                    name,
                    place: Frame::IDENTITY,
                    preload: self.preload.clone(),
                    gravity,
                    chain,
                    attachment: Frame::IDENTITY,
                    springs: self.springs.clone(),
                    length_scale,
                    home: Vec::new(),
                })
            })
            .collect()
    }

    fn passive_index(&self, name: &Spanned<String>) -> Option<usize> {
        self.passive_names.iter().find(|(n, _)| n == name.get_ref()).map(|(_, i)| *i)
    }

    /// The index the next virtual coordinate takes.
    pub(super) fn n_virtual(&self) -> usize {
        self.n_virtual
    }

    pub(super) fn joint(&mut self, kind: JointKind, axis: Vec3, role: Role) {
        let counter = match role {
            Role::Actuated => &mut self.n_actuated,
            Role::Passive => &mut self.n_passive,
            Role::Virtual => &mut self.n_virtual,
        };
        let index = *counter;
        *counter += 1;
        self.elements.push(Element::Joint(Joint { kind, axis, role, index, gain: 1.0 }));
    }

    /// Virtual joints for a spring group of `dim` coordinates with the given stiffness block.
    pub(super) fn spring(
        &mut self,
        name: String,
        joints: &[(JointKind, Vec3)],
        stiffness: Mat6,
        compliance: Mat6,
        preload: &[f64],
        posture: Option<Parallelogram>,
    ) {
        let first = self.n_virtual;
        self.preload.extend_from_slice(preload);
        for (kind, axis) in joints {
            self.joint(*kind, *axis, Role::Virtual);
        }
        let actuator =
            matches!(self.elements.iter().rev().nth(joints.len()), Some(Element::Joint(j)) if j.role == Role::Actuated);
        let dim = joints.len();
        self.springs.push(SpringGroup {
            name,
            actuator,
            first,
            dim,
            stiffness,
            compliance,
            posture,
            of_coordinate: None,
            beam_axis: None,
        });
    }
}

impl Builder<'_> {
    /// A number of the description, evaluated: finite, or an error located at it (a NaN tool rotation was
    /// accepted and then reported as an unreachable pose).
    pub(super) fn num(&self, n: &Num) -> Result<f64, InputError> {
        let mut scope = self.params.clone();
        let v = n.get_ref().eval(&mut scope).map_err(|e| self.loc.at(n.span(), e))?;
        if !v.is_finite() {
            return Err(self.loc.at(n.span(), format!("{v} is not a finite number")));
        }
        Ok(v)
    }

    pub(super) fn positive(&self, n: &Num, what: &str) -> Result<f64, InputError> {
        let v = self.num(n)?;
        if v > 0.0 {
            Ok(v)
        } else {
            Err(self.loc.at(n.span(), format!("{what} must be positive, got {v}")))
        }
    }

    fn vec3(&self, v: &[Num; 3]) -> Result<Vec3, InputError> {
        Ok(Vec3::new(self.num(&v[0])?, self.num(&v[1])?, self.num(&v[2])?))
    }

    pub(super) fn axis(&self, a: &Spanned<AxisSpec>) -> Result<Vec3, InputError> {
        let v = match a.get_ref() {
            AxisSpec::Named(n) => match n.as_str() {
                "x" | "+x" => Vec3::x(),
                "y" | "+y" => Vec3::y(),
                "z" | "+z" => Vec3::z(),
                "-x" => -Vec3::x(),
                "-y" => -Vec3::y(),
                "-z" => -Vec3::z(),
                other => {
                    return Err(self
                        .loc
                        .at(a.span(), format!("unknown axis `{other}`: use x, y, z, -x, -y, -z or [ax, ay, az]")))
                }
            },
            AxisSpec::Vector(c) => {
                let mut scope = self.params.clone();
                let mut v = Vec3::zeros();
                for k in 0..3 {
                    v[k] = c[k].eval(&mut scope).map_err(|e| self.loc.at(a.span(), e))?;
                }
                v
            }
        };
        let n = v.norm();
        if !(n > 0.0 && n.is_finite()) {
            return Err(self.loc.at(a.span(), "an axis must be a non-zero vector"));
        }
        Ok(v / n)
    }

    pub(super) fn transform(
        &self,
        translation: &Option<[Num; 3]>,
        rotation_axis: &Option<Spanned<AxisSpec>>,
        rotation_deg: &Option<Num>,
        span: std::ops::Range<usize>,
    ) -> Result<Frame, InputError> {
        let pos = match translation {
            Some(t) => self.vec3(t)?,
            None => Vec3::zeros(),
        };
        if let Some(t) = translation {
            if let Some(k) = (0..3).find(|&k| pos[k].abs() > MAX_TRANSLATION_MM) {
                return Err(self.loc.at(
                    t[k].span(),
                    format!("the translation {} mm is past {MAX_TRANSLATION_MM:e} mm (ten kilometres)", pos[k]),
                ));
            }
        }
        let rot = match (rotation_axis, rotation_deg) {
            (Some(a), Some(d)) => rotation_about(&self.axis(a)?, self.num(d)?.to_radians()),
            (None, None) => nalgebra::Matrix3::identity(),
            _ => return Err(self.loc.at(span, "give both `rotation_axis` and `rotation_deg`, or neither")),
        };
        Ok(Frame::new(rot, pos))
    }

    pub(super) fn matrix6(&self, m: &Spanned<Vec<Vec<Num>>>, what: &str) -> Result<Mat6, InputError> {
        let rows = m.get_ref();
        if rows.len() != 6 || rows.iter().any(|r| r.len() != 6) {
            return Err(self.loc.at(m.span(), format!("{what} must be 6 rows of 6 numbers")));
        }
        let mut out = Mat6::zeros();
        for (i, row) in rows.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                out[(i, j)] = self.num(v)?;
            }
        }
        let scale = out.abs().max();
        if (out - out.transpose()).abs().max() > 1e-9 * scale {
            return Err(self.loc.at(m.span(), format!("{what} is not symmetric")));
        }
        let sym = (out + out.transpose()) * 0.5;
        if sym.cholesky().is_none() {
            return Err(self.loc.at(m.span(), format!("{what} is not positive definite")));
        }
        Ok(sym)
    }

    /// A beam spring's compliance and its axis (unit, in the spring's coordinates).
    fn beam(&self, b: &Spanned<BeamSpec>) -> Result<(Mat6, Vec3), InputError> {
        let s = b.get_ref();
        let e = self.positive(&s.e, "E")?;
        let g = self.shear_modulus(e, &s.g, &s.nu, b.span())?;
        let section = self.section(e, g, &s.diameter, [&s.area, &s.iy, &s.iz, &s.j], b.span())?;
        let length = self.positive(&s.length, "length")?;
        let direction = match &s.direction {
            Some(d) => self.axis(d)?,
            None => Vec3::x(),
        };
        Ok((beam_compliance(&section, length, &direction), direction.normalize()))
    }

    /// A beam section: a round `diameter`, or all of A, Iy, Iz, J.
    pub(super) fn section(
        &self,
        e: f64,
        g: f64,
        diameter: &Option<Num>,
        [area, iy, iz, j]: [&Option<Num>; 4],
        span: std::ops::Range<usize>,
    ) -> Result<BeamSection, InputError> {
        match (diameter, area, iy, iz, j) {
            (Some(d), None, None, None, None) => Ok(BeamSection::round(e, g, self.positive(d, "diameter")?)),
            (None, Some(a), Some(iy), Some(iz), Some(j)) => Ok(BeamSection {
                e,
                g,
                area: self.positive(a, "A")?,
                iy: self.positive(iy, "Iy")?,
                iz: self.positive(iz, "Iz")?,
                j: self.positive(j, "J")?,
            }),
            _ => Err(self.loc.at(span, "a beam's section is either `diameter` or all of `A`, `Iy`, `Iz`, `J`")),
        }
    }

    pub(super) fn shear_modulus(
        &self,
        e: f64,
        g: &Option<Num>,
        nu: &Option<Num>,
        span: std::ops::Range<usize>,
    ) -> Result<f64, InputError> {
        match (g, nu) {
            (Some(g), None) => self.positive(g, "G"),
            (None, Some(nu_spec)) => {
                let nu = self.num(nu_spec)?;
                if !(-1.0 < nu && nu < 0.5) {
                    return Err(self.loc.at(nu_spec.span(), format!("nu must lie in (-1, 0.5), got {nu}")));
                }
                Ok(e / (2.0 * (1.0 + nu)))
            }
            _ => Err(self.loc.at(span, "give exactly one of `G` and `nu`")),
        }
    }

    fn parallelogram(&self, p: &Spanned<ParallelogramSpec>, parts: &ChainParts) -> Result<Parallelogram, InputError> {
        let s = p.get_ref();
        let e = self.positive(&s.e, "E")?;
        let g = self.shear_modulus(e, &s.g, &s.nu, p.span())?;
        let angle = parts.passive_index(&s.angle).ok_or_else(|| {
            self.loc.at(s.angle.span(), format!("no passive joint named `{}` before this spring", s.angle.get_ref()))
        })?;
        Ok(Parallelogram::new(
            BeamSection::round(e, g, self.positive(&s.bar_diameter, "bar_diameter")?),
            self.positive(&s.length, "length")?,
            self.positive(&s.separation, "separation")?,
            angle,
        ))
    }

    /// One element of a chain, appended to `parts` (joints, springs, fixed transforms, masses).
    fn element(&self, e: &Spanned<ElementSpec>, position: usize, parts: &mut ChainParts) -> Result<(), InputError> {
        let s = e.get_ref();
        let kind = s.kind.get_ref().as_str();
        self.check_keys(e, kind)?;
        let name = s.name.clone().unwrap_or_else(|| format!("{kind}{}", position + 1));
        match kind {
            "fixed" => {
                let f = self.transform(&s.translation, &s.rotation_axis, &s.rotation_deg, e.span())?;
                parts.elements.push(Element::Fixed(f));
            }
            "prismatic" | "revolute" => self.single_joint(e, kind, name, parts)?,
            "universal" => {
                let axes =
                    s.axes.as_ref().ok_or_else(|| self.loc.at(e.span(), "a universal joint needs two `axes`"))?;
                if axes.get_ref().len() != 2 {
                    return Err(self.loc.at(axes.span(), "a universal joint has exactly two axes"));
                }
                for a in axes.get_ref() {
                    parts.joint(JointKind::Revolute, self.axis(a)?, Role::Passive);
                }
            }
            "mass" => {
                let kg = match &s.mass_kg {
                    Some(m) => self.positive(m, "mass_kg")?,
                    None => return Err(self.loc.at(e.span(), "a mass needs `mass_kg`")),
                };
                let centre = match &s.centre {
                    Some(c) => self.vec3(c)?,
                    None => Vec3::zeros(),
                };
                parts.elements.push(Element::Mass { kg, centre });
            }
            "spherical" => {
                for (_, a) in &SIX_DOF[3..] {
                    parts.joint(JointKind::Revolute, *a, Role::Passive);
                }
            }
            "spring6" => self.spring6(e, name, parts)?,
            _ => unreachable!("element types are checked by check_keys"),
        }
        Ok(())
    }

    /// The element's type is known and it has only the keys that apply to it.
    fn check_keys(&self, e: &Spanned<ElementSpec>, kind: &str) -> Result<(), InputError> {
        let s = e.get_ref();
        let present = [
            ("translation", s.translation.is_some()),
            ("rotation_axis", s.rotation_axis.is_some()),
            ("rotation_deg", s.rotation_deg.is_some()),
            ("axis", s.axis.is_some()),
            ("role", s.role.is_some()),
            ("stiffness", s.stiffness.is_some()),
            ("axes", s.axes.is_some()),
            ("stiffness_matrix", s.stiffness_matrix.is_some()),
            ("compliance_matrix", s.compliance_matrix.is_some()),
            ("beam", s.beam.is_some()),
            ("preload", s.preload.is_some()),
            ("mass_kg", s.mass_kg.is_some()),
            ("centre", s.centre.is_some()),
            ("follows", s.follows.is_some()),
            ("gain", s.gain.is_some()),
            ("parallelogram", s.parallelogram.is_some()),
        ];
        let allowed: &[&str] = match kind {
            "fixed" => &["translation", "rotation_axis", "rotation_deg"],
            "prismatic" | "revolute" => &["axis", "role", "stiffness", "preload", "follows", "gain"],
            "mass" => &["mass_kg", "centre"],
            "universal" => &["axes"],
            "spherical" => &[],
            "spring6" => &["stiffness_matrix", "compliance_matrix", "beam", "parallelogram", "preload"],
            other => {
                return Err(self.loc.at(
                    s.kind.span(),
                    format!(
                    "unknown element type `{other}`: use fixed, prismatic, revolute, universal, spherical, spring6 or mass"
                ),
                ))
            }
        };
        if let Some((key, _)) = present.iter().find(|(k, p)| *p && !allowed.contains(k)) {
            return Err(self.loc.at(e.span(), format!("`{key}` does not apply to a `{kind}` element")));
        }
        Ok(())
    }

    /// The spring's rest values (preload), `dim` of them (zeros when not given).
    fn preload(&self, s: &ElementSpec, dim: usize) -> Result<Vec<f64>, InputError> {
        match &s.preload {
            None => Ok(vec![0.0; dim]),
            Some(p) if p.get_ref().len() == dim => p.get_ref().iter().map(|v| self.num(v)).collect(),
            Some(p) => Err(self.loc.at(p.span(), format!("`preload` needs {dim} values, one per spring coordinate"))),
        }
    }

    /// A prismatic or revolute joint: actuated (with its control-loop spring), passive (possibly following
    /// another), or elastic.
    fn single_joint(
        &self,
        e: &Spanned<ElementSpec>,
        kind: &str,
        name: String,
        parts: &mut ChainParts,
    ) -> Result<(), InputError> {
        let s = e.get_ref();
        let jk = if kind == "prismatic" { JointKind::Prismatic } else { JointKind::Revolute };
        let axis = match &s.axis {
            Some(a) => self.axis(a)?,
            None => return Err(self.loc.at(e.span(), format!("a `{kind}` joint needs an `axis`"))),
        };
        let role = s.role.as_ref().ok_or_else(|| {
            self.loc.at(e.span(), format!("a `{kind}` joint needs a `role`: actuated, passive or elastic"))
        })?;
        let stiffness = match &s.stiffness {
            Some(k) => Some(self.positive(k, "stiffness")?),
            None => None,
        };
        if s.preload.is_some() && stiffness.is_none() {
            return Err(self.loc.at(e.span(), "`preload` applies to a joint's spring: give a `stiffness`"));
        }
        let theta0 = self.preload(s, 1)?;
        let spring = |parts: &mut ChainParts, k: f64| {
            let mut km = Mat6::zeros();
            km[(0, 0)] = k;
            let mut cm = Mat6::zeros();
            cm[(0, 0)] = 1.0 / k;
            parts.spring(name.clone(), &[(jk, axis)], km, cm, &theta0, None);
        };
        match (role.get_ref().as_str(), stiffness) {
            // V_a(q + theta): the actuator and its control-loop spring move along one axis (eq 1).
            ("actuated", k) => {
                parts.joint(jk, axis, Role::Actuated);
                if let Some(k) = k {
                    spring(parts, k);
                }
            }
            ("passive", None) => match &s.follows {
                None => {
                    parts.passive_names.push((name.clone(), parts.n_passive));
                    parts.joint(jk, axis, Role::Passive)
                }
                Some(leader) => {
                    let index = parts.passive_index(leader).ok_or_else(|| {
                        self.loc
                            .at(leader.span(), format!("no passive joint named `{}` before this one", leader.get_ref()))
                    })?;
                    let gain = match &s.gain {
                        Some(g) => self.num(g)?,
                        None => 1.0,
                    };
                    parts.elements.push(Element::Joint(Joint { kind: jk, axis, role: Role::Passive, index, gain }));
                }
            },
            ("passive", Some(_)) => {
                return Err(self.loc.at(e.span(), "a passive joint has no stiffness: use role = \"elastic\""))
            }
            ("elastic", Some(k)) => spring(parts, k),
            ("elastic", None) => return Err(self.loc.at(e.span(), "an elastic joint needs a `stiffness`")),
            (other, _) => {
                return Err(self
                    .loc
                    .at(role.span(), format!("unknown role `{other}`: use actuated, passive or elastic")))
            }
        }
        Ok(())
    }

    /// A 6-dof spring from its stiffness or compliance matrix, a beam, or a parallelogram's bars.
    fn spring6(&self, e: &Spanned<ElementSpec>, name: String, parts: &mut ChainParts) -> Result<(), InputError> {
        let s = e.get_ref();
        let mut posture = None;
        let mut beam_axis = None;
        let exactly_one =
            "a spring6 needs exactly one of `stiffness_matrix`, `compliance_matrix`, `beam` and `parallelogram`";
        let compliance = match (&s.stiffness_matrix, &s.compliance_matrix, &s.beam, &s.parallelogram) {
            (k, c, b, None) => {
                let (c, axis) = self.six_dof_compliance(e.span(), k, c, b, exactly_one)?;
                beam_axis = axis;
                c
            }
            (None, None, None, Some(p)) => {
                let spec = self.parallelogram(p, parts)?;
                let k = spec.stiffness(0.0).ok_or_else(|| {
                    self.loc.at(
                        e.span(),
                        "the parallelogram's bars give no finite stiffness: check E, bar_diameter, length \
                         and separation",
                    )
                })?;
                posture = Some(spec);
                k.try_inverse()
            }
            _ => return Err(self.loc.at(e.span(), exactly_one)),
        };
        let (stiffness, compliance) = self.invertible(e.span(), compliance)?;
        parts.spring(name, &SIX_DOF, stiffness, compliance, &self.preload(s, 6)?, posture);
        if let Some(spring) = parts.springs.last_mut() {
            spring.beam_axis = beam_axis;
        }
        Ok(())
    }

    /// A 6-dof spring's compliance from exactly one of a stiffness matrix, a compliance matrix and a beam
    /// (with the beam's axis); `exactly_one` says what to give otherwise. None where a stiffness matrix
    /// cannot be inverted.
    pub(super) fn six_dof_compliance(
        &self,
        span: std::ops::Range<usize>,
        stiffness_matrix: &Option<Spanned<Vec<Vec<Num>>>>,
        compliance_matrix: &Option<Spanned<Vec<Vec<Num>>>>,
        beam: &Option<Spanned<BeamSpec>>,
        exactly_one: &str,
    ) -> Result<(Option<Mat6>, Option<Vec3>), InputError> {
        Ok(match (stiffness_matrix, compliance_matrix, beam) {
            (Some(k), None, None) => (self.matrix6(k, "stiffness_matrix")?.try_inverse(), None),
            (None, Some(c), None) => (Some(self.matrix6(c, "compliance_matrix")?), None),
            (None, None, Some(b)) => {
                let (c, axis) = self.beam(b)?;
                (Some(c), Some(axis))
            }
            _ => return Err(self.loc.at(span, exactly_one)),
        })
    }

    /// A spring's symmetric stiffness and its compliance, both finite, or a located error.
    pub(super) fn invertible(
        &self,
        span: std::ops::Range<usize>,
        compliance: Option<Mat6>,
    ) -> Result<(Mat6, Mat6), InputError> {
        let finite = |m: &Mat6| m.iter().all(|v| v.is_finite());
        let not_invertible = "the spring's matrix cannot be inverted (or is not finite: check its numbers)";
        let compliance = compliance.filter(finite).ok_or_else(|| self.loc.at(span.clone(), not_invertible))?;
        let stiffness = compliance.try_inverse().filter(finite).ok_or_else(|| self.loc.at(span, not_invertible))?;
        Ok(((stiffness + stiffness.transpose()) * 0.5, compliance))
    }

    fn model(&self, file: &ModelFile, depth: usize) -> Result<Model, InputError> {
        let gravity = match &file.gravity {
            Some(g) => self.vec3(g)?,
            None => Vec3::zeros(),
        };
        let mut legs = Vec::new();
        if file.legs.get_ref().is_empty() {
            return Err(self.loc.at(file.legs.span(), "a manipulator needs at least one [[leg]]"));
        }
        let mut joint_space = None;
        if let Some(first) = file.joint_corrections.first() {
            if !file.legs.get_ref().iter().any(|l| l.get_ref().urdf.is_some()) {
                return Err(self.loc.at(
                    first.span(),
                    "`[[joint_correction]]` corrects the joints of a serial arm read from URDF: this file has no `[leg.urdf]`",
                ));
            }
        }
        for leg_spec in file.legs.get_ref() {
            let spec = leg_spec.get_ref();
            let (mut bodies, space) = self.leg_body(leg_spec, gravity, depth, &file.joint_corrections)?;
            // A serial arm (one leg, read from URDF, not copied) takes poses as its joint angles too.
            if file.legs.get_ref().len() == 1 && spec.copies.is_empty() {
                joint_space = space;
            }
            if bodies.len() > 1 {
                // A tree's chains (one per tip) are one serial arm: its legs share their coordinates.
                if file.legs.get_ref().len() > 1 || !spec.copies.is_empty() || spec.attachment.is_some() {
                    return Err(self.loc.at(
                        leg_spec.span(),
                        format!("leg `{}` names several tips: a tree is the description's only leg, with no copies or attachment", spec.name),
                    ));
                }
                if !file.payloads.is_empty() {
                    return Err(self.loc.at(
                        file.payloads[0].span(),
                        "a `[[payload]]` is carried by the platform, and a tree with several tips has none: give the mass as an <inertial> of the tip link it hangs from in the URDF",
                    ));
                }
                legs.append(&mut bodies);
                continue;
            }
            let body = bodies.pop().expect("a leg has a body");
            let attachment = match &spec.attachment {
                Some(TransformSpec { translation, rotation_axis, rotation_deg }) => {
                    self.transform(translation, rotation_axis, rotation_deg, leg_spec.span())?
                }
                None => Frame::IDENTITY,
            };
            let copies: Vec<(String, Frame)> = if spec.copies.is_empty() {
                vec![(spec.name.clone(), Frame::IDENTITY)]
            } else {
                spec.copies
                    .iter()
                    .map(|c| {
                        let f = self.transform(&c.translation, &c.rotation_axis, &c.rotation_deg, leg_spec.span())?;
                        Ok((format!("{}.{}", spec.name, c.name), f))
                    })
                    .collect::<Result<_, InputError>>()?
            };
            for (name, place) in copies {
                if legs.iter().any(|l: &Leg| l.name() == name) {
                    return Err(self.loc.at(leg_spec.span(), format!("two legs are named `{name}`")));
                }
                let attachment = place.compose(&attachment);
                legs.push(match &body {
                    Leg::Vjm(v) => Leg::Vjm(VjmLeg {
                        name,
                        chain: v.chain.prepended(place),
                        place: place.compose(&v.place),
                        attachment,
                        ..v.clone()
                    }),
                    Leg::Msa(m) => Leg::Msa(MsaLeg { name, place: place.compose(&m.place), attachment, ..m.clone() }),
                });
            }
        }
        let length_scale = legs.iter().map(Leg::length_scale).fold(1.0, f64::max);
        let mut nominal = Manipulator {
            name: file.name.clone(),
            legs,
            length_scale,
            gravity: file.gravity.as_ref().map(|_| gravity),
            payload: None,
            joint_space,
        };
        for spec in &file.payloads {
            let p = spec.get_ref();
            let centre = p.centre.as_ref().map(|c| self.vec3(c)).transpose()?.unwrap_or_else(Vec3::zeros);
            nominal.add_payload(Payload { mass_kg: self.num(&p.mass_kg)?, centre });
        }
        // An actuator offset is the library's effect of that name: the same checks (a leg with an actuator
        // spring) and the same model change.
        for spec in &file.actuator_offsets {
            let o = spec.get_ref();
            let leg = o.leg.get_ref().to_string();
            let e = Effect::new(Kind::ActuatorOffset, Some(&leg), vec![self.num(&o.offset)?], &nominal)
                .map_err(|e| self.loc.at(o.leg.span(), e.to_string()))?;
            nominal = with_model_effects(&nominal, &[e]);
        }
        let mut effects = Vec::with_capacity(file.effects.len());
        for spec in &file.effects {
            let s = spec.get_ref();
            let kind = Kind::parse(&s.name)
                .ok_or_else(|| self.loc.at(spec.span(), EffectError::UnknownKind(s.name.clone()).to_string()))?;
            let e = Effect::new(kind, s.target.as_deref(), s.values.clone(), &nominal)
                .map_err(|e| self.loc.at(spec.span(), e.to_string()))?;
            effects.push(e);
        }
        let manipulator = with_model_effects(&nominal, &effects);
        let measurement_terms = effects.into_iter().filter(|e| e.kind.form() == Form::Measurement).collect();
        Ok(Model { manipulator, measurement_terms })
    }

    /// One leg as written (a chain, an MSA structure, a URDF chain, or the leg of another file), before
    /// copies, with its joint space where it was read from URDF.
    fn leg_body(
        &self,
        leg_spec: &Spanned<LegSpec>,
        gravity: Vec3,
        depth: usize,
        corrections: &[Spanned<JointCorrectionSpec>],
    ) -> Result<(Vec<Leg>, Option<JointSpace>), InputError> {
        let spec = leg_spec.get_ref();
        let given = [spec.chain.is_some(), spec.msa.is_some(), spec.from.is_some(), spec.urdf.is_some()];
        if given.iter().filter(|g| **g).count() != 1 {
            return Err(self.loc.at(
                leg_spec.span(),
                format!("leg `{}` needs exactly one of `chain`, `msa`, `urdf` and `from`", spec.name),
            ));
        }
        if let Some(urdf) = &spec.urdf {
            let (legs, space) = self.urdf_legs(&spec.name, urdf, gravity, corrections)?;
            return Ok((legs, Some(space)));
        }
        if !spec.parameters.is_empty() && spec.from.is_none() {
            return Err(self
                .loc
                .at(leg_spec.span(), "a leg's `parameters` override those of the file named by `from`"));
        }
        if let Some(chain_spec) = &spec.chain {
            if chain_spec.get_ref().is_empty() {
                return Err(self.loc.at(chain_spec.span(), format!("leg `{}` has an empty chain", spec.name)));
            }
            let mut parts = ChainParts::default();
            for (i, e) in chain_spec.get_ref().iter().enumerate() {
                self.element(e, i, &mut parts)?;
            }
            return Ok((vec![parts.into_leg(spec.name.clone(), gravity)], None));
        }
        if let Some(msa) = &spec.msa {
            let template = self.msa_leg(msa)?;
            let mut leg = MsaLeg {
                name: spec.name.clone(),
                template,
                place: Frame::IDENTITY,
                attachment: Frame::IDENTITY,
                length_scale: 1.0,
            };
            // Rotations weigh as the leg's size: its nodes' largest distance from the end at the home pose
            // (platform at the origin), where the description should be reachable.
            let home = leg.structure_at(&Frame::IDENTITY).map_err(|_| {
                self.loc.at(msa.span(), format!("leg `{}` cannot be evaluated with the platform at the origin (home pose): check `reach` and the formulas", spec.name))
            })?;
            let end = home.nodes[home.end];
            leg.length_scale = home.nodes.iter().map(|p| (p - end).norm()).fold(1.0, f64::max);
            return Ok((vec![Leg::Msa(leg)], None));
        }
        let from = spec.from.as_ref().expect("one of the three is given");
        if depth > 8 {
            return Err(self.loc.at(from.span(), "`from` nests more than 8 files deep (a cycle?)"));
        }
        let path = self.loc.path.parent().unwrap_or(Path::new(".")).join(from.get_ref());
        let overrides = spec
            .parameters
            .iter()
            .map(|(n, v)| Ok((n.clone(), self.num(v)?)))
            .collect::<Result<BTreeMap<_, _>, InputError>>()?;
        let source = read_text(&path)?;
        let other = parse_with(&path, &source, &overrides, depth + 1)?;
        let mut legs = other.manipulator.legs.into_iter();
        match (legs.next(), legs.next()) {
            // The other file's arm keeps its joint space.
            (Some(leg), None) => Ok((
                vec![match leg {
                    Leg::Vjm(v) => Leg::Vjm(VjmLeg { name: spec.name.clone(), gravity, ..v }),
                    Leg::Msa(m) => Leg::Msa(MsaLeg { name: spec.name.clone(), ..m }),
                }],
                other.manipulator.joint_space,
            )),
            _ => {
                Err(self.loc.at(from.span(), format!("`{}` must describe exactly one leg (no copies)", from.get_ref())))
            }
        }
    }
}

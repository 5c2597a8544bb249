//! Geometric errors of legs for `stiff assemble` (paper 000 s. 4.2): per leg, an end-point error eps_i given
//! directly, a rigid error of the leg's base (an actuator's location: offset along or rotation about its
//! axis), and errors of named parameters of the description, from which eps_i follows through the leg's
//! own kinematics. Directions are in the leg's own frame (before the copy that places it) unless
//! `frame = "base"`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::build::parse_with;
use super::error::{not_finite, read_text, InputError, Locator};
use crate::kinematics::frame::{rotation_about, Frame, Vec3, Vec6};
use crate::platform::leg::Leg;
use crate::platform::manipulator::Manipulator;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ErrorFile {
    #[serde(default)]
    description: Option<String>,
    #[serde(rename = "leg")]
    legs: Spanned<Vec<Spanned<LegErrorSpec>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LegErrorSpec {
    /// A leg's name as in the model (copies: "chain.2"), or "*" for every leg.
    name: Spanned<String>,
    /// "leg" (default: the leg's own frame, so one entry serves every copy) or "base".
    #[serde(default)]
    frame: Option<Spanned<String>>,
    #[serde(default)]
    eps: Option<EpsSpec>,
    #[serde(default)]
    base: Option<BaseSpec>,
    /// Values replacing parameters of the model for this leg only (its own geometry with errors).
    #[serde(default)]
    parameters: BTreeMap<String, f64>,
}

/// An end-point error at the platform's reference point.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EpsSpec {
    #[serde(default)]
    translation_mm: Option<Spanned<Vec<f64>>>,
    #[serde(default)]
    rotation_deg: Option<Spanned<Vec<f64>>>,
}

/// A rigid error of the whole leg from its base: a rotation by `rotation_deg` about the line along
/// `rotation_axis` through `through` (mm), then a translation.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BaseSpec {
    #[serde(default)]
    rotation_axis: Option<Spanned<Vec<f64>>>,
    #[serde(default)]
    rotation_deg: Option<Spanned<f64>>,
    #[serde(default)]
    through: Option<Spanned<Vec<f64>>>,
    #[serde(default)]
    translation_mm: Option<Spanned<Vec<f64>>>,
}

/// One leg's errors, resolved in the base frame.
#[derive(Clone, Debug)]
pub struct LegErrors {
    /// Direct end-point error at the reference point (translation mm, rotation vector rad), base frame.
    pub eps: Vec6,
    /// Rigid error of the leg's base as a small twist (translation of the base frame origin, rotation
    /// vector), base frame: the leg moved by exp of it.
    pub base: Vec6,
    /// Parameter changes for this leg (name -> error added to the nominal value).
    pub parameters: BTreeMap<String, f64>,
}

impl LegErrors {
    fn none() -> Self {
        LegErrors { eps: Vec6::zeros(), base: Vec6::zeros(), parameters: BTreeMap::new() }
    }

    /// The rigid motion of the base error, scaled, as a frame.
    pub fn base_frame(&self, scale: f64) -> Frame {
        crate::kinematics::frame::apply_twist(&Frame::IDENTITY, &(self.base * scale))
    }
}

/// The errors of every leg of a manipulator, and where to rebuild legs whose parameters change.
#[derive(Clone, Debug)]
pub struct ErrorSet {
    /// Free text about the errors and their source.
    pub description: Option<String>,
    /// Per leg, its errors.
    pub legs: Vec<LegErrors>,
    model_path: PathBuf,
    model_source: String,
    nominal_parameters: BTreeMap<String, f64>,
}

impl ErrorSet {
    /// Reads an error file for a manipulator read from `model_path`.
    pub fn load(path: &Path, model_path: &Path, m: &Manipulator) -> Result<ErrorSet, InputError> {
        let source = read_text(path)?;
        let loc = Locator { path, source: &source };
        let file: ErrorFile = toml::from_str(&source).map_err(|e| loc.syntax(e))?;
        let model_source = read_text(model_path)?;
        let nominal_parameters = super::build::parameter_values(model_path, &model_source)?;
        let mut legs: Vec<LegErrors> = m.legs.iter().map(|_| LegErrors::none()).collect();
        let mut named = vec![false; m.legs.len()];
        for spec in file.legs.get_ref() {
            let s = spec.get_ref();
            let targets: Vec<usize> = if s.name.get_ref() == "*" {
                (0..m.legs.len()).collect()
            } else {
                let k = m.legs.iter().position(|l| l.name() == s.name.get_ref()).ok_or_else(|| {
                    let names: Vec<&str> = m.legs.iter().map(Leg::name).collect();
                    loc.at(s.name.span(), format!("no leg named `{}` (legs: {})", s.name.get_ref(), names.join(", ")))
                })?;
                vec![k]
            };
            let leg_frame = match s.frame.as_ref().map(|f| f.get_ref().as_str()) {
                None | Some("leg") => true,
                Some("base") => false,
                Some(other) => {
                    let span = s.frame.as_ref().expect("matched Some").span();
                    return Err(loc.at(span, format!("unknown frame `{other}`: use leg or base")));
                }
            };
            if let Some(k) =
                targets.iter().find(|&&k| matches!(m.legs[k], Leg::Msa(_))).filter(|_| !s.parameters.is_empty())
            {
                return Err(loc.at(
                    spec.span(),
                    format!(
                        "leg `{}` is an MSA leg: its geometry is solved from the pose, so give its errors as eps or a base error, not parameters",
                        m.legs[*k].name()
                    ),
                ));
            }
            for (name, value) in &s.parameters {
                if !nominal_parameters.contains_key(name) {
                    return Err(loc.at(spec.span(), format!("the model has no parameter `{name}`")));
                }
                if !value.is_finite() {
                    return Err(loc.at(spec.span(), format!("parameter `{name}`: not a finite number")));
                }
            }
            for k in targets {
                if named[k] && s.name.get_ref() != "*" {
                    return Err(loc.at(s.name.span(), format!("leg `{}` is given errors twice", s.name.get_ref())));
                }
                named[k] = true;
                let place = if leg_frame { m.legs[k].copy_frame() } else { Frame::IDENTITY };
                let e = &mut legs[k];
                let vector = |v: &Option<Spanned<Vec<f64>>>, key: &str| -> Result<Vec3, InputError> {
                    Ok(Vec3::from(loc.optional_array(v, key)?.unwrap_or([0.0; 3])))
                };
                if let Some(eps) = &s.eps {
                    let t = place.rot * vector(&eps.translation_mm, "translation_mm")?;
                    let r = place.rot * vector(&eps.rotation_deg, "rotation_deg")?.map(f64::to_radians);
                    e.eps += Vec6::new(t.x, t.y, t.z, r.x, r.y, r.z);
                }
                if let Some(b) = &s.base {
                    let rotation_deg = match &b.rotation_deg {
                        Some(d) if !d.get_ref().is_finite() => {
                            return Err(
                                loc.at(d.span(), format!("`rotation_deg`: {}", not_finite(&d.get_ref().to_string())))
                            )
                        }
                        Some(d) => *d.get_ref(),
                        None => 0.0,
                    };
                    let axis = match &b.rotation_axis {
                        Some(_) => {
                            let a = vector(&b.rotation_axis, "rotation_axis")?;
                            if a.norm().is_nan() || a.norm() <= 0.0 {
                                return Err(loc.at(spec.span(), "`rotation_axis` must be a non-zero vector"));
                            }
                            a.normalize()
                        }
                        None if rotation_deg != 0.0 => {
                            return Err(loc.at(spec.span(), "a base rotation needs its `rotation_axis`"))
                        }
                        None => Vec3::x(),
                    };
                    // Rotation about the line through c, then translation: x -> R (x - c) + c + t, in the leg
                    // frame; carried to the base frame by the copy's place.
                    let rot = rotation_about(&axis, rotation_deg.to_radians());
                    let c = vector(&b.through, "through")?;
                    let local = Frame::new(rot, c - rot * c + vector(&b.translation_mm, "translation_mm")?);
                    let world = place.compose(&local).compose(&place.inverse());
                    e.base = Frame::IDENTITY.error_to(&world);
                }
                for (name, value) in &s.parameters {
                    e.parameters.insert(name.clone(), value - nominal_parameters[name]);
                }
            }
        }
        Ok(ErrorSet {
            description: file.description,
            legs,
            model_path: model_path.to_path_buf(),
            model_source,
            nominal_parameters,
        })
    }

    /// The legs rebuilt with their parameter errors times `scale` (None for a leg without any), in the
    /// model's leg order.
    pub fn perturbed_legs(&self, scale: f64) -> Result<Vec<Option<Leg>>, InputError> {
        let mut out = Vec::with_capacity(self.legs.len());
        for (k, e) in self.legs.iter().enumerate() {
            if e.parameters.is_empty() {
                out.push(None);
                continue;
            }
            let overrides: BTreeMap<String, f64> =
                e.parameters.iter().map(|(n, d)| (n.clone(), self.nominal_parameters[n] + scale * d)).collect();
            let m = parse_with(&self.model_path, &self.model_source, &overrides, 0)?;
            out.push(m.manipulator.legs.into_iter().nth(k));
        }
        Ok(out)
    }
}

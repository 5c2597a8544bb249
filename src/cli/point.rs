//! `stiff point`: stiffness and compliance at one pose, as a report.

use anyhow::{bail, Result};
use clap::Args;

use super::args::{write_stdout, ModelArgs, PoseArgs};
use super::parse::parse_vec6;
use crate::kinematics::frame::Vec6;
use crate::model::grid::PosePoint;
use crate::study::point::{
    loaded_point, point_report, unloaded_point, LoadedHistory, PointJson, PoseJson, ResultJson, Status,
};

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff point manipulators/orthoglide-3puu.toml --at 0,0,0
  stiff point manipulators/orthoglide-3prpar.toml --at 0,0,0 --wrench 215,-10,-25,1000,21500,0
  stiff point manipulators/stewart-gough-b.toml --at 0,0,300 --orientation 0,0,0.1
  stiff point manipulators/orthoglide-3puu.toml --at 0,0,0 --wrench 215,-10,-25,1000,21500,0 --json -o q0.json
  stiff point manipulators/fanuc-r2000ic.toml --joints=-1.047,-0.291,-0.505,0.066,-1.098,2.529 --wrench=-120,-78,-15,0,0,0

Exit status: 0 the pose has a compliance (status ok, or rigid_directions: a serial arm with rigid joints), 1 it has not (unreachable, singular, unstable, ...:\nthe report says why) or the run failed, 2 usage error.";

#[derive(Args, Debug)]
pub(crate) struct PointArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    #[command(flatten)]
    pub(crate) pose: PoseArgs,
    /// A wrench Fx,Fy,Fz,Mx,My,Mz (N, N mm): reports its linear deflection C w and the loaded equilibrium
    /// under it (displacement, tangent stiffness and its full inverse).
    #[arg(long, value_parser = parse_vec6, allow_hyphen_values = true)]
    pub(crate) wrench: Option<Vec6>,
    /// Write the report as JSON (the same content, for programs) instead of text.
    #[arg(long)]
    pub(crate) json: bool,
    /// Where the report goes; `-` or absent: stdout.
    #[arg(short, long)]
    pub(crate) output: Option<std::path::PathBuf>,
}

pub(crate) fn run(a: PointArgs) -> Result<()> {
    let model = a.model.load()?;
    let mut state = model.new_state();
    let p = PosePoint { wrench: a.wrench, ..a.pose.resolve(&model, &mut state)? };
    let r = unloaded_point(&model, &p, &mut state);
    let tip = (model.tips().len() > 1).then(|| model.tips()[0].clone());
    let loaded = a.wrench.map(|w| loaded_point(&model, &p, &w, &mut state, &mut LoadedHistory::default()));
    let text = if a.json {
        let json = PointJson {
            model: model.name.clone(),
            tip: tip.clone(),
            pose: PoseJson {
                position_mm: [p.position.x, p.position.y, p.position.z],
                rotation_rad: [p.rotation.x, p.rotation.y, p.rotation.z],
                wrench: p.wrench.map(|w| std::array::from_fn(|k| w[k])),
            },
            unloaded: ResultJson::new(&p, &r, model.length_scale),
            loaded: loaded.as_ref().map(|l| ResultJson::new(&p, l, model.length_scale)),
        };
        serde_json::to_string_pretty(&json)? + "\n"
    } else {
        let mut text = point_report(&model.name, &p, &r, false, model.length_scale);
        if let Some(tip) = &tip {
            // After the model's name: which of the tree's reference points the report is at.
            let at = text.find('\n').map_or(text.len(), |k| k + 1);
            let others = model.tips().join(", ");
            text.insert_str(at, &format!("tip: {tip} (of the tree's tips {others}; --tip names another)\n"));
        }
        if let Some(l) = &loaded {
            text.push_str("\nUnder the wrench: the loaded equilibrium (paper 000 s. 3-4)\n");
            text.push_str(&point_report(&model.name, &p, l, true, model.length_scale));
        }
        text
    };
    match a.output.as_deref() {
        Some(path) if path != std::path::Path::new("-") => {
            let mut sink = crate::output::sink::Sink::create(Some(path))?;
            sink.writer().write_all(text.as_bytes())?;
            sink.finish()?;
        }
        _ => write_stdout(&text)?,
    }
    let statuses: Vec<Status> = std::iter::once(r.status).chain(loaded.as_ref().map(|l| l.status)).collect();
    // The report is written first (a singular pose's free directions are the answer a user wants); the
    // exit status then says the pose has no compliance.
    if let Some(s) = statuses.iter().find(|s| !matches!(s, Status::Ok | Status::RigidDirections)) {
        bail!("the pose is {} (the report says why)", s.as_str());
    }
    Ok(())
}

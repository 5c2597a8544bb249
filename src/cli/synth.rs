//! `stiff synth`: synthetic measurements with hidden effects.

use anyhow::{bail, Result};
use clap::{ArgMatches, Args};

use super::args::{progress_bar, thread_pool, ModelArgs, OutputArgs, PointsArgs, RunArgs};
use super::parse::parse_wrench_list;
use super::shard::{write_shard_preamble, ShardArgs};

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff synth manipulators/fanuc-r2000ic.toml --points manipulators/grids/fanuc-r2000ic-cable-tests.csv --effect registration=0.1,0,0.2,1500,0,300 --effect target=20,0,30 --effect joint-offset:J2=0.001 --noise 0.05 --seed 1 --check-every 3 -o positions.csv
  stiff synth manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-small.toml --effect tool-offset=0.05,0,0 --wrenches \"200,0,0,0,0,0;0,200,0,0,0,0\" --noise 0.002 --seed 7 -o data.csv
  stiff synth manipulators/orthoglide-3prpar.toml --grid manipulators/grids/orthoglide-small.toml --effect link-compliance:parallelogram=2 --wrenches \"0,0,-300,0,0,0\" --noise 0.001 --seed 1 --repeats 3 -o repeats.csv
  stiff synth manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-small.toml --positions --effect registration=0.1,0.2,-0.3,1000,200,-50 --effect actuator-offset:1=0.5 --noise 0.002 --seed 1 --check-every 3 -o legs.csv

Exit status: 0 success, 1 the run failed, 2 usage error.";

#[derive(Args, Debug)]
pub(crate) struct SynthArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// A hidden effect NAME[:TARGET]=V1,V2,... (repeatable), e.g. actuator-compliance:2=1.5, tool-offset=0.05,0,0.
    /// For a serial arm's joint-space points (q_<joint> columns): joint-offset:J=RAD, joint-compliance:J=ADDED,
    /// backlash:J=B (play, rad), joint-geometry:J=DX,DY,DZ,RX,RY,RZ (mm, rad), frame-compliance:J=CX,CY,CZ,CRX,CRY,CRZ (mm/N, rad/(N mm)),
    /// payload=KG,CX,CY,CZ (tool frame, mm), and the set-up:
    /// registration=RX,RY,RZ,TX,TY,TZ (the instrument sees a base point p at R p + t; rad, mm; repeated: one
    /// set-up each, the configurations measured in that many blocks), target=X,Y,Z (on the tool, mm),
    /// gross=FRACTION,MM, drift=DX,DY,DZ (mm per row written, base frame axes), target-axes=RX,RY,RZ (the
    /// target's axes in the tool frame, rad; with --orientation-noise).
    #[arg(long = "effect", value_name = "NAME[:TARGET]=VALUES")]
    pub(crate) effects: Vec<String>,
    #[command(flatten)]
    pub(crate) points: PointsArgs,
    /// Wrenches applied at every pose: Fx,Fy,Fz,Mx,My,Mz (N, N mm) separated by `;` (default: each point's
    /// own, from the points' Fx_N..Mz_Nmm columns, as `stiff plan` writes them).
    #[arg(long, allow_hyphen_values = true)]
    pub(crate) wrenches: Option<String>,
    /// Standard deviation of the measurement noise, mm.
    #[arg(long)]
    pub(crate) noise: f64,
    #[arg(long)]
    pub(crate) seed: u64,
    /// Measurements per pose and wrench.
    #[arg(long, default_value_t = 1)]
    pub(crate) repeats: usize,
    /// Joint-space points: also measure the target's orientation (mqw,mqx,mqy,mqz and sigma_mrad columns), with
    /// this standard deviation about each axis, mrad.
    #[arg(long, value_name = "MRAD")]
    pub(crate) orientation_noise: Option<f64>,
    /// A parallel robot's poses measured as a lab records them: the target's position in an instrument's
    /// frame (mx_mm,my_mm,mz_mm) at each commanded pose, with the set-up's effects below (a serial arm's
    /// joint-space points always are).
    #[arg(long)]
    pub(crate) positions: bool,
    /// Positions: every N-th configuration is held out (`set` = check; 0: none).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub(crate) check_every: usize,
    /// Measure the linear response C w with every effect as a first-order term, instead of the loaded
    /// equilibrium of the model with the hidden robot changes (payload, actuator offset, spring scalings)
    /// built in (the default: what a real robot shows, deflecting non-linearly under ordinary loads).
    #[arg(long)]
    pub(crate) linear: bool,
    #[command(flatten)]
    pub(crate) output: OutputArgs,
    #[command(flatten)]
    pub(crate) shard: ShardArgs,
    #[command(flatten)]
    pub(crate) run: RunArgs,
}

pub(crate) fn run(a: SynthArgs, matches: &ArgMatches) -> Result<()> {
    use crate::diagnose::synth;
    use crate::model::effect::Effect;
    let model = a.model.load_model()?;
    if !(a.noise >= 0.0 && a.noise.is_finite()) {
        bail!("--noise must be >= 0 (mm)");
    }
    let mut points = a.points.load(&model.manipulator)?;
    if !points.joint_names.is_empty() || a.positions {
        return run_positions(&a, &model.manipulator, points);
    }
    if a.orientation_noise.is_some() {
        bail!("--orientation-noise is for joint-space points (q_<joint> columns): a pose diagnosis measures displacements");
    }
    let effects = a
        .effects
        .iter()
        .map(|e| Effect::parse(e, &model.manipulator))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow::anyhow!("--effect {e}"))?;
    let wrenches = parse_wrench_list(a.wrenches.as_deref()).map_err(|e| anyhow::anyhow!("--wrenches: {e}"))?;
    let shard = a.shard.split_points(&mut points, crate::batch::RUN, &a.output, None)?;
    let options = synth::SynthOptions {
        effects,
        wrenches,
        noise: a.noise,
        seed: a.seed,
        repeats: a.repeats,
        linear: a.linear,
        portion: shard.is_some(),
    };
    let pool = thread_pool(a.run.threads)?;
    let table = synth::synth_table();
    let mut sink = a.output.open(&table)?;
    write_shard_preamble(&shard, &mut sink, matches, "synth", table)?;
    let bar = progress_bar(points.len, a.run.quiet);
    let summary = synth::synthesize(&pool, &model, &mut points, &options, sink.writer(), &bar)?;
    sink.finish()?;
    bar.finish_and_clear();
    if summary.skipped > 0 {
        eprintln!("{} poses left out (unreachable, singular, or without a loaded equilibrium)", summary.skipped);
    }
    Ok(())
}

/// A synthetic row as the calibration's reader reads it (`poses`: a parallel robot's commanded poses).
fn measured_row<'a>(
    r: &'a crate::diagnose::calibrate::SynthRow,
    configurations: &'a [crate::diagnose::calibrate::Configuration],
    poses: Option<&'a [crate::kinematics::frame::Frame]>,
) -> crate::diagnose::positions::MeasuredRow<'a> {
    let (k, (at, seen), gross, held, setup) = r;
    let (name, joints, wrench) = &configurations[*k];
    crate::diagnose::positions::MeasuredRow {
        name,
        joints,
        pose: poses.map(|p| &p[*k]),
        wrench,
        at,
        orientation: seen.as_ref(),
        check: *held,
        setup: *setup,
        gross: *gross,
    }
}

/// Measurements as a lab records them: the target's position in an instrument's frame, at a serial arm's
/// joint coordinates (the hidden changes written into its description) or at a parallel robot's commanded
/// poses (`--positions`; the hidden changes are the model-form effects of the diagnosis: actuator offsets,
/// spring scalings, a payload), with noise, gross rows and held-out rows.
fn run_positions(
    a: &SynthArgs,
    nominal: &crate::platform::manipulator::Manipulator,
    mut points: crate::model::grid::PointSet,
) -> Result<()> {
    use crate::diagnose::calibrate::{
        correction_table, synthesize_leg_positions, synthesize_positions, ArmEffect, ArmKind, PositionSynth,
    };
    use crate::kinematics::frame::Vec3;
    use crate::model::effect::{Effect, Form};
    if a.wrenches.is_some() || a.linear || a.repeats != 1 || a.shard.shard.is_some() {
        bail!("--wrenches, --linear, --repeats and --shard are not for positions in an instrument's frame: each point is measured under its own wrench (Fx_N.. columns) and the robot's weight");
    }
    let arm = nominal.joint_space.as_ref();
    let names: Vec<String> = arm.map_or_else(Vec::new, |space| space.names.clone());
    let mut hidden = PositionSynth {
        setups: Vec::new(),
        target: Vec3::zeros(),
        noise: a.noise,
        gross: (0.0, 0.0),
        check_every: a.check_every,
        seed: a.seed,
        drift: Vec3::zeros(),
        orientation: match a.orientation_noise {
            Some(n) if n >= 0.0 && n.is_finite() => Some((Vec3::zeros(), n * 1e-3)),
            Some(_) => bail!("--orientation-noise must be >= 0 (mrad)"),
            None => None,
        },
        play: vec![0.0; names.len()],
    };
    let mut tables = String::new();
    let mut leg_effects = Vec::new();
    for e in &a.effects {
        let (name, values) = e.split_once('=').ok_or_else(|| anyhow::anyhow!("--effect `{e}`: give NAME=VALUES"))?;
        let values: Vec<f64> = values
            .split(',')
            .map(|v| v.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<_>>()
            .ok_or_else(|| anyhow::anyhow!("--effect `{e}`: the values must be finite numbers"))?;
        let count = |n: usize| {
            if values.len() == n {
                Ok(())
            } else {
                Err(anyhow::anyhow!("--effect `{e}`: {name} takes {n} values"))
            }
        };
        match name {
            "registration" => {
                count(6)?;
                let rotation = Vec3::new(values[0], values[1], values[2]);
                hidden.setups.push((rotation, Vec3::new(values[3], values[4], values[5])));
            }
            "target" => {
                count(3)?;
                hidden.target = Vec3::new(values[0], values[1], values[2]);
            }
            "drift" => {
                count(3)?;
                hidden.drift = Vec3::new(values[0], values[1], values[2]);
            }
            "target-axes" => {
                count(3)?;
                let Some((axes, _)) = hidden.orientation.as_mut() else {
                    bail!("--effect `{e}`: the target's axes are seen only with --orientation-noise")
                };
                *axes = Vec3::new(values[0], values[1], values[2]);
            }
            "gross" => {
                count(2)?;
                if !(0.0..=1.0).contains(&values[0]) {
                    bail!("--effect `{e}`: the fraction of gross rows lies in [0, 1]");
                }
                hidden.gross = (values[0], values[1]);
            }
            // A parallel robot's hidden changes are the diagnosis's model-form effects.
            _ if arm.is_none() => {
                let effect = Effect::parse(e, nominal).map_err(|why| anyhow::anyhow!("--effect {why}"))?;
                if effect.kind.form() != Form::Model {
                    bail!("--effect `{e}`: with --positions a parallel robot's hidden changes are those a description holds (actuator-offset, actuator-compliance, link-compliance, link-sections, gravity, gravity-offset), with registration, target, drift and gross for the instrument");
                }
                leg_effects.push(effect);
            }
            _ => {
                let effect = ArmEffect::parse(name, &names).map_err(|why| anyhow::anyhow!("--effect `{e}`: {why}"))?;
                let joint = names[effect.joint].as_str();
                match effect.kind {
                    ArmKind::ToolCompliance => {
                        bail!("--effect `{e}`: a description of a URDF arm cannot hold it yet; synth makes offsets, compliances, play, geometry, frame compliances, payload and drift")
                    }
                    // Play, which no description holds, is applied where each configuration is measured.
                    ArmKind::Backlash => {
                        count(1)?;
                        hidden.play[effect.joint] = values[0];
                    }
                    ArmKind::Payload => {
                        count(4)?;
                        let moment: Vec<f64> = values[1..].iter().map(|c| c * values[0]).collect();
                        tables += &correction_table(ArmKind::Payload, joint, &[&values[..1], &moment[..]].concat());
                    }
                    kind => {
                        count(effect.size())?;
                        tables += &correction_table(kind, joint, &values);
                    }
                }
            }
        }
    }
    let mut read = Vec::new();
    while points.next_block(4096, &mut read)? > 0 {}
    let configurations = crate::diagnose::calibrate::configurations(&read);
    let poses: Vec<crate::kinematics::frame::Frame> = read.iter().map(|p| p.frame()).collect();
    let loaded = read.iter().any(|p| p.wrench.is_some_and(|w| w != crate::kinematics::frame::Vec6::zeros()));
    let (rows, skipped) = if arm.is_some() {
        let source = crate::model::error::read_text(&a.model.model)?;
        let overrides = a.model.set.iter().cloned().collect();
        let real = crate::model::parse_with(&a.model.model, &format!("{source}\n{tables}"), &overrides, 0)?.manipulator;
        synthesize_positions(&real, &configurations, &hidden).map_err(|e| anyhow::anyhow!("{e}"))?
    } else {
        let real = crate::model::effect::with_model_effects(nominal, &leg_effects);
        synthesize_leg_positions(&real, &configurations, &poses, &hidden)
    };
    use crate::diagnose::positions::MeasuredLayout;
    use crate::output::table::{header_line, selected_columns, write_row};
    let layout = MeasuredLayout {
        joints: names.clone(),
        loaded,
        sigma_mm: a.noise.max(crate::diagnose::data::MIN_SIGMA_MM),
        sigma_mrad: a.orientation_noise.map(|n| n.max(crate::diagnose::data::MIN_SIGMA_MM)),
        setups: hidden.setups.len() > 1,
    };
    let poses = arm.is_none().then_some(&poses[..]);
    let row = |r| measured_row(r, &configurations, poses);

    let Some(first) = rows.first() else {
        bail!("no configuration could be measured ({skipped} left out: no finite pose or no loaded equilibrium)");
    };
    let columns = selected_columns(&row(first), &layout, None);
    let mut sink = a.output.open(&columns)?;
    let mut text = header_line(&columns);
    for r in &rows {
        write_row(&row(r), &layout, &mut text);
    }
    sink.writer().write_all(text.as_bytes())?;
    sink.finish()?;
    if skipped > 0 {
        eprintln!("{skipped} configurations left out (no finite pose or no loaded equilibrium)");
    }
    Ok(())
}

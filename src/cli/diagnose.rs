//! `stiff diagnose`: where measurements and the model disagree, and the effect that explains it.

use std::io::Read;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use super::args::{picture_bytes, write_stdout, ModelArgs};
use crate::model::error::read_text;
use crate::output::sink::Sink;

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff synth manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-small.toml --effect actuator-compliance:2=1.5 --wrenches \"200,0,0,0,0,0;0,200,0,0,0,0;0,0,-200,0,0,0\" --noise 0.002 --seed 1 -o data.csv
  stiff diagnose manipulators/orthoglide-3puu.toml --data data.csv --json verdict.json --model-out corrected.toml --plot verdict.svg
  stiff synth manipulators/fanuc-r2000ic.toml --points manipulators/grids/fanuc-r2000ic-cable-tests.csv --effect registration=0.1,0,0.2,1500,0,300 --effect target=20,0,30 --effect joint-offset:J2=0.001 --noise 0.05 --seed 1 --check-every 3 -o positions.csv
  stiff diagnose manipulators/fanuc-r2000ic.toml --data positions.csv --model-out calibrated.toml
  stiff synth manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-small.toml --positions --effect registration=0.1,0.2,-0.3,1000,200,-50 --effect actuator-offset:1=0.5 --noise 0.002 --seed 1 --check-every 3 -o legs.csv
  stiff diagnose manipulators/orthoglide-3puu.toml --data legs.csv --model-out legs-calibrated.toml

Exit status: 0 success whatever the verdict (unless --fail-on), 1 the run failed or --fail-on matched the\nverdict, 2 usage error.";

#[derive(Args, Debug)]
pub(crate) struct DiagnoseArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// Measurements (CSV): pose_id,x_mm,y_mm,z_mm,Fx_N,...,Mz_Nmm,dx_mm,dy_mm,dz_mm[,sigma_mm]; or, for a
    /// serial arm, as a lab records them: q_<joint> columns and the target's measured position in the
    /// instrument's frame (mx_mm,my_mm,mz_mm or mx_m,...; several targets mx1_mm,... or a `target` column;
    /// optional setup, set = fit|check, sigma_mm, Fx_N..Mz_Nmm; the target's orientation as mqw,mqx,mqy,mqz,
    /// mroll_deg,mpitch_deg,myaw_deg or mrx_rad,mry_rad,mrz_rad with sigma_mrad), or dx_mm,dy_mm,dz_mm under
    /// the row's wrench; or, for a parallel robot, the same measured positions at commanded poses
    /// (x_mm,y_mm,z_mm[,pose_rx_rad,pose_ry_rad,pose_rz_rad] in place of q_<joint>): its legs are calibrated.
    #[arg(long)]
    pub(crate) data: PathBuf,
    /// Positions (joint-space data, or a parallel robot's at commanded poses): hold out this fraction of the configurations (drawn with --seed) as check rows,
    /// never fitted.
    #[arg(long, value_name = "F")]
    pub(crate) check_fraction: Option<f64>,
    /// Seed of --check-fraction's draw.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Positions: an effect always fitted, not selected (repeat; e.g. --fit joint-compliance:J2):
    /// joint-offset:J, joint-compliance:J, backlash:J, joint-geometry:J, frame-compliance:J, payload,
    /// tool-compliance, drift (a parallel robot's J: a leg's number, its actuator).
    #[arg(long, value_name = "EFFECT")]
    pub(crate) fit: Vec<String>,
    /// Positions: the candidates offered (comma-separated, as --fit); default every joint's offset
    /// (positions only), compliance and backlash, a serial arm's joints' geometry and the payload.
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub(crate) candidates: Vec<String>,
    /// Positions: validate a calibrated model (one `--model-out` wrote) on new data: only the set-up is
    /// fitted (each set-up's frame and each target's place on the tool), no effect is offered, and the
    /// held-out rows' errors are the model's on this data (half the configurations are held out, drawn
    /// with --seed, where the file marks none `check` and --check-fraction is not given).
    #[arg(long, conflicts_with_all = ["fit", "candidates"])]
    pub(crate) validate: bool,
    /// --model-out writes the effects the held-out rows do not confirm (their RMS error grows with them) too;
    /// without it they are left out, as a comment.
    #[arg(long, requires = "model_out")]
    pub(crate) write_unconfirmed: bool,
    /// Measurement standard deviation, mm (when the data has no sigma_mm column).
    #[arg(long)]
    pub(crate) sigma: Option<f64>,
    /// Positions: the standard deviation of a measured orientation about each axis, mrad (when the
    /// data has no sigma_mrad column; without either, orientations are not fitted and the report says so).
    #[arg(long, value_name = "MRAD")]
    pub(crate) sigma_mrad: Option<f64>,
    /// Predict by the linear response (rest displacement + C w) instead of the loaded equilibrium (the
    /// default: real robots deflect non-linearly under ordinary loads); `loaded-nonlinearity` is then a
    /// candidate.
    #[arg(long)]
    pub(crate) linear: bool,
    /// The default (predictions by the loaded equilibrium); kept so that earlier scripts still run.
    #[arg(long, hide = true, conflicts_with = "linear")]
    pub(crate) loaded: bool,
    /// Significance level (candidates are tested at alpha / their number).
    #[arg(long, default_value_t = 0.01)]
    pub(crate) alpha: f64,
    /// Write the verdict, accepted effects and candidate table as JSON.
    #[arg(long)]
    pub(crate) json: Option<PathBuf>,
    /// Write the model description with the accepted effects added.
    #[arg(long)]
    pub(crate) model_out: Option<PathBuf>,
    /// Measured positions: write every row's residual under the model selected (name, line, setup, target,
    /// set, observed, ex_mm..e_mm in the instrument's frame, base_ex_mm..base_exy_mm in the robot base's axes,
    /// erx_mrad..er_mrad for an orientation, left_out: why a row is not in the report's figures). CSV, or by
    /// the extension .csv.gz, .csv.zst, .parquet.
    #[arg(long)]
    pub(crate) residuals: Option<PathBuf>,
    /// Also draw the diagnosis (SVG, or PNG for a .png name): residual arrows before and after, per-axis RMS, candidates' delta BIC.
    #[arg(long)]
    pub(crate) plot: Option<PathBuf>,
    /// Exit with status 1 (after writing every output) when the verdict is `effect` or worse (any verdict but
    /// none), or `unexplained` (unexplained, ambiguous or noise): a CI gate on measured data.
    #[arg(long, value_enum)]
    pub(crate) fail_on: Option<FailOn>,
}

/// Which verdicts `--fail-on` turns into a failing exit status.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum FailOn {
    /// Any discrepancy: effect, ambiguous, unexplained or noise.
    Effect,
    /// A discrepancy not attributed to named effects: ambiguous, unexplained or noise.
    Unexplained,
}

/// The share of configurations `--validate` holds out where the file marks none.
const VALIDATION_HELD_OUT: f64 = 0.5;

pub(crate) fn run(a: DiagnoseArgs) -> Result<()> {
    use crate::diagnose::{data::Dataset, error::DiagnoseError, report, screen, select};
    if !(a.alpha > 0.0 && a.alpha < 1.0) {
        bail!("--alpha must lie in (0, 1)");
    }
    let model = a.model.load_model()?;
    // Read once (standard input cannot be read twice): its header says which kind of data it is.
    let mut input = Vec::new();
    crate::model::error::open_input(&a.data)?
        .read_to_end(&mut input)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.data.display()))?;
    if joint_space_data(&input) {
        return run_calibration(&a, &model.manipulator, &input);
    }
    if absolute_positions(&input) {
        // A parallel robot's legs are calibrated from positions in an instrument's frame at commanded poses
        // (a serial arm's data without q_<joint> columns get the reader's message naming them).
        return run_calibration(&a, &model.manipulator, &input);
    }
    if a.check_fraction.is_some()
        || !a.fit.is_empty()
        || !a.candidates.is_empty()
        || a.sigma_mrad.is_some()
        || a.residuals.is_some()
        || a.validate
        || a.write_unconfirmed
    {
        bail!(
            "--check-fraction, --fit, --candidates, --validate, --write-unconfirmed, --sigma-mrad and --residuals are for measured positions (mx_mm,my_mm,mz_mm: a serial arm's at q_<joint> columns, a parallel robot's at commanded poses); {} gives displacements",
            a.data.display()
        );
    }
    let data = Dataset::read_from(&a.data, input.as_slice())?;
    let loaded = !a.linear;
    let options = select::Options { alpha: a.alpha, loaded, max_effects: 3 };
    // The outputs are opened before the work, so an unwritable path fails at once.
    let json_sink = a.json.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let model_sink = a.model_out.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let plot_sink = a.plot.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    // The loaded equilibrium of every row is computed either way: the linear nominal offers its difference
    // as the loaded-nonlinearity candidate. Gross rows are left out of the fits (and named in the report).
    let d = screen::diagnose_screened(&model.manipulator, &model.measurement_terms, &data, a.sigma, &options).map_err(
        |e| match e {
            // The command line says how to give the noise level: its flag.
            DiagnoseError::NoiseUnknown => anyhow::anyhow!("{}: {e}: --sigma MM", a.data.display()),
            DiagnoseError::NoiseOutOfRange { .. } => anyhow::anyhow!("--sigma: {e}"),
            e @ DiagnoseError::Pose { .. } => anyhow::anyhow!("{}, {e}", a.data.display()),
            e => anyhow::anyhow!("{}: {e}", a.data.display()),
        },
    )?;
    let name = a.model.model.display().to_string();
    write_stdout(&report::text(&d, &name))?;
    let json = report::json(&d, &name);
    if let Some(mut sink) = json_sink {
        serde_json::to_writer_pretty(&mut *sink.writer(), &json)?;
        sink.finish()?;
    }
    if let Some(mut sink) = plot_sink {
        let title = format!("{}, data {}", a.model.model.display(), a.data.display());
        let options = crate::plot::PlotOptions { title: Some(title), ..Default::default() };
        let svg = crate::plot::diagnosis(&json, &options)?;
        let path = a.plot.as_deref().expect("a sink only with --plot");
        sink.writer().write_all(&picture_bytes(&svg, path)?)?;
        sink.finish()?;
    }
    if let Some(sink) = model_sink {
        write_corrected(sink, &a.model.model, a.model_out.as_deref(), |source, dir, written| {
            report::corrected_model(source, dir, written, &d)
        })?;
    }
    let fails = match (a.fail_on, d.verdict) {
        (None, _) | (_, select::Verdict::None) => false,
        (Some(FailOn::Effect), _) => true,
        (Some(FailOn::Unexplained), v) => v != select::Verdict::Effect,
    };
    if fails {
        bail!(
            "verdict `{}` (--fail-on {})",
            d.verdict.as_str(),
            if a.fail_on == Some(FailOn::Effect) { "effect" } else { "unexplained" }
        );
    }
    Ok(())
}

/// The data's header (empty where it has none).
fn header_of(input: &[u8]) -> Vec<String> {
    let mut reader = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(input);
    reader.headers().map(|h| h.iter().map(String::from).collect()).unwrap_or_default()
}

/// True when the data's header names measured positions in an instrument's frame (`mx_mm,...`).
fn absolute_positions(input: &[u8]) -> bool {
    crate::diagnose::positions::has_positions(&header_of(input))
}

/// True when the data's header names joint coordinates (`q_<joint>`): it is calibration data.
fn joint_space_data(input: &[u8]) -> bool {
    crate::diagnose::positions::is_joint_space(&header_of(input))
}

/// A serial arm against joint-space measurements, or a parallel robot against positions at commanded
/// poses: registration fitted, effects selected, held-out rows reported.
fn run_calibration(a: &DiagnoseArgs, m: &crate::platform::manipulator::Manipulator, input: &[u8]) -> Result<()> {
    use crate::diagnose::calibrate::{self, ArmEffect};
    use crate::diagnose::positions::PositionData;
    use crate::output::calibration::{CalibrationFile, CalibrationVerdict};
    if a.linear {
        bail!("--linear is not available for measured positions: the calibration's predictions are first order about each row's loaded equilibrium");
    }
    // A serial arm's joints are named by its joint space; a parallel robot's rows give commanded poses and
    // its effects name its legs' actuators by number.
    let joints = calibrate::joint_names(m);
    let mut data = match &m.joint_space {
        Some(space) => {
            let data = PositionData::read_from(&a.data, input, &space.names)?;
            if let Some((row, outside)) = data.rows.iter().find_map(|r| space.outside_limits(&r.joints).map(|o| (r, o)))
            {
                eprintln!("warning: {}, line {}: {outside}", a.data.display(), row.line);
            }
            data
        }
        None => {
            // The actuators' readings a parallel robot's rows may give: q_<leg> for each leg with one actuator.
            let readable: Vec<String> = m
                .actuator_units()
                .iter()
                .enumerate()
                .filter(|(_, units)| units.len() == 1)
                .map(|(k, _)| (k + 1).to_string())
                .collect();
            PositionData::read_at_poses(&a.data, input, &readable)?
        }
    };
    if let Some(f) = a.check_fraction {
        if !(0.0..1.0).contains(&f) {
            bail!("--check-fraction must lie in [0, 1), got {f}");
        }
        data.hold_out(f, a.seed);
    } else if a.validate && !data.rows.iter().any(|r| r.check) {
        // A validation's figures are of rows the set-up was not fitted to.
        data.hold_out(VALIDATION_HELD_OUT, a.seed);
    }
    if let Some(s) = a.sigma {
        crate::diagnose::data::checked_sigma(s).map_err(|e| anyhow::anyhow!("--sigma: {e}"))?;
    }
    if let Some(s) = a.sigma_mrad {
        crate::diagnose::data::checked_sigma(s).map_err(|e| anyhow::anyhow!("--sigma-mrad: {e}"))?;
    }
    let parse = |list: &[String], flag: &str| -> Result<Vec<ArmEffect>> {
        list.iter()
            .map(|e| ArmEffect::parse(e.trim(), &joints).map_err(|why| anyhow::anyhow!("{flag}: {why}")))
            .collect()
    };
    let options = calibrate::CalibrationOptions {
        alpha: a.alpha,
        sigma: a.sigma,
        sigma_rad: a.sigma_mrad.map(|s| s * 1e-3),
        fitted: parse(&a.fit, "--fit")?,
        max_effects: if a.validate { 0 } else { 6 },
        rebuild: m.joint_space.is_some().then(|| a.model.rebuild()).transpose()?,
        progress: Some(super::args::fit_counter()),
    };
    let candidates = parse(&a.candidates, "--candidates")?;
    let json_sink = a.json.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let model_sink = a.model_out.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let plot_sink = a.plot.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let residual_columns = crate::output::table::selected_columns(&residual_example(), &(), None);
    let residual_sink = a.residuals.as_deref().map(|p| Sink::table(Some(p), &residual_columns)).transpose()?;
    let c = calibrate::calibrate(m, &data, &candidates, &options);
    if let Some(bar) = &options.progress {
        bar.finish_and_clear();
    }
    let c = c.map_err(|e| anyhow::anyhow!("{}: {e}", a.data.display()))?;
    let name = a.model.model.display().to_string();
    write_stdout(&calibrate::text(&c.report, &name))?;
    let file = CalibrationFile { model: name, calibration: c.report.clone() };
    if let Some(mut sink) = json_sink {
        // Through a JSON value, whose keys are sorted, as every JSON file stiff writes.
        serde_json::to_writer_pretty(&mut *sink.writer(), &serde_json::to_value(&file)?)?;
        sink.finish()?;
    }
    if let Some(mut sink) = plot_sink {
        let title = format!("{}, data {}", a.model.model.display(), a.data.display());
        let options = crate::plot::PlotOptions { title: Some(title), ..Default::default() };
        let svg = crate::plot::calibration::calibration(&file, &options)?;
        let path = a.plot.as_deref().expect("a sink only with --plot");
        sink.writer().write_all(&picture_bytes(&svg, path)?)?;
        sink.finish()?;
    }
    if let Some(sink) = model_sink {
        write_corrected(sink, &a.model.model, a.model_out.as_deref(), |source, dir, written| {
            calibrate::corrected_model(source, dir, written, &c, a.write_unconfirmed)
        })?;
    }
    if let Some(mut sink) = residual_sink {
        let mut text = crate::output::table::header_line(&residual_columns);
        for row in &c.rows {
            crate::output::table::write_row(row, &(), &mut text);
        }
        sink.writer().write_all(text.as_bytes())?;
        sink.finish()?;
    }
    let fails = match (a.fail_on, c.report.verdict) {
        (None, _) | (_, CalibrationVerdict::None) => false,
        (Some(FailOn::Effect), _) => true,
        (Some(FailOn::Unexplained), v) => v == CalibrationVerdict::Unexplained,
    };
    if fails {
        bail!("verdict `{:?}` (--fail-on)", c.report.verdict);
    }
    Ok(())
}

/// A row of the residual table, for its columns.
fn residual_example() -> crate::diagnose::calibrate::RowResidual {
    crate::diagnose::calibrate::RowResidual {
        name: String::new(),
        line: 0,
        setup: String::new(),
        target: String::new(),
        set: "fit",
        observed: "position",
        error_mm: None,
        base_mm: None,
        turn_mrad: None,
        left_out: String::new(),
    }
}

/// Writes the description `model` corrected by `correct` (its text, its folder and the folder of `written`,
/// the file written, from which the corrected text's references to other files are made relative; absolute
/// where it goes to standard output) to `sink`.
fn write_corrected(
    mut sink: Sink,
    model: &std::path::Path,
    written: Option<&std::path::Path>,
    correct: impl FnOnce(&str, &std::path::Path, Option<&std::path::Path>) -> String,
) -> Result<()> {
    let source = read_text(model)?;
    let dir = canonical_folder(model);
    let written_dir = written.filter(|p| p.as_os_str() != "-").map(canonical_folder);
    sink.writer().write_all(correct(&source, &dir, written_dir.as_deref()).as_bytes())?;
    sink.finish()?;
    Ok(())
}

/// The folder of the file at `path`, absolute where it exists (a bare file name's folder is "", the working
/// folder: ".").
fn canonical_folder(path: &std::path::Path) -> std::path::PathBuf {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(std::path::Path::new("."));
    std::fs::canonicalize(dir).unwrap_or(dir.to_path_buf())
}

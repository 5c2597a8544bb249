//! `stiff diagnose`: where measurements and the model disagree, and the effect that explains it.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use super::args::{write_stdout, ModelArgs};
use crate::model::error::read_text;
use crate::output::sink::Sink;

#[derive(Args, Debug)]
pub(crate) struct DiagnoseArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// Measurements (CSV): pose_id,x_mm,y_mm,z_mm,Fx_N,...,Mz_Nmm,dx_mm,dy_mm,dz_mm[,sigma_mm].
    #[arg(long)]
    pub(crate) data: PathBuf,
    /// Measurement standard deviation, mm (when the data has no sigma_mm column).
    #[arg(long)]
    pub(crate) sigma: Option<f64>,
    /// Predict by the loaded equilibrium instead of the linear C w.
    #[arg(long)]
    pub(crate) loaded: bool,
    /// Significance level (default 0.01; candidates are tested at alpha / their number).
    #[arg(long, default_value_t = 0.01)]
    pub(crate) alpha: f64,
    /// Write the verdict, accepted effects and candidate table as JSON.
    #[arg(long)]
    pub(crate) json: Option<PathBuf>,
    /// Write the model description with the accepted effects added.
    #[arg(long)]
    pub(crate) model_out: Option<PathBuf>,
    /// Also draw the diagnosis (SVG): residual arrows before and after, per-axis RMS, candidates' delta BIC.
    #[arg(long)]
    pub(crate) plot: Option<PathBuf>,
}

pub(crate) fn run(a: DiagnoseArgs) -> Result<()> {
    use crate::diagnose::{data::Dataset, error::DiagnoseError, fit::Problem, report, select};
    let model = a.model.load_model()?;
    let data = Dataset::read(&a.data)?;
    if !(a.alpha > 0.0 && a.alpha < 1.0) {
        bail!("--alpha must lie in (0, 1)");
    }
    let (weights, sigma, source) = select::noise(&data, a.sigma).map_err(|e| match e {
        // The command line says how to give the noise level: its flag.
        DiagnoseError::NoiseUnknown => anyhow::anyhow!("{}: {e}: --sigma MM", a.data.display()),
        DiagnoseError::NoiseOutOfRange { .. } => anyhow::anyhow!("--sigma: {e}"),
        e => anyhow::anyhow!("{}: {e}", a.data.display()),
    })?;
    let needs_loaded = !a.loaded;
    let problem = Problem::new(&model.manipulator, &model.measurement_terms, &data, weights, a.loaded, needs_loaded)
        .map_err(|e| anyhow::anyhow!("{}, {e}", a.data.display()))?;
    let options = select::Options { alpha: a.alpha, loaded: a.loaded, max_effects: 3 };
    // The outputs are opened before the work, so an unwritable path fails at once.
    let json_sink = a.json.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let model_sink = a.model_out.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let plot_sink = a.plot.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let d = select::diagnose(&problem, sigma, source, &options)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.data.display()))?;
    let name = a.model.model.display().to_string();
    write_stdout(&report::text(&d, &name))?;
    let json = report::json(&d, &name);
    if let Some(mut sink) = json_sink {
        serde_json::to_writer_pretty(&mut *sink.writer(), &json)?;
        sink.finish()?;
    }
    if let Some(mut sink) = plot_sink {
        let svg = crate::plot::diagnosis(&json)?;
        sink.writer().write_all(svg.as_bytes())?;
        sink.finish()?;
    }
    if let Some(mut sink) = model_sink {
        let source = read_text(&a.model.model)?;
        let dir = a.model.model.parent().map(|p| p.to_path_buf()).unwrap_or_default();
        let dir = std::fs::canonicalize(&dir).unwrap_or(dir);
        sink.writer().write_all(report::corrected_model(&source, &dir, &d).as_bytes())?;
        sink.finish()?;
    }
    Ok(())
}

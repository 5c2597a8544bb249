//! Pictures of studies, drawn from what the studies write (their CSV, or diagnose's JSON), so `--plot` on a
//! study and `stiff plot FILE` afterwards give the same picture: a colour map of a map column over grid
//! sections, a force-deflection curve with its events, the displacements along an assembly path (paper 000
//! Figures 10-11) and the errors along a compensated one, and a diagnosis (residual arrows before and after, per-axis RMS, the candidates' delta BIC).
pub mod assembly;
pub mod calibration;
pub mod compensation;
pub mod curve;
pub mod diagnosis;
pub mod glyphs;
pub mod png;
pub mod points;
pub mod raster;
pub mod scale;
pub mod svg;
pub mod table;

use anyhow::{bail, Context, Result};

use crate::output::diagnosis::DiagnosisReport;
use crate::output::table::names;
pub use diagnosis::diagnosis;
pub use scale::Scale;
use svg::{text_width, Svg};
use table::{Table, TableKind};

/// What to draw and how.
#[derive(Clone, Debug, Default)]
pub struct PlotOptions {
    /// Map: the column to colour (default: largest translational compliance).
    pub column: Option<String>,
    /// Map: a planar section `axis=value`, e.g. `z=0`.
    pub section: Option<String>,
    /// Curve: the displacement axis (x, y, z, rx, ry, rz; default: the one that moves most).
    pub direction: Option<String>,
    /// Colour maps: linear or logarithmic colours.
    pub scale: Scale,
    /// Colour maps: the values of the first and the last colour (default: the data's range).
    pub range: Option<(f64, f64)>,
    /// What the picture is of, above what it shows: model, `--set` values, load (None: nothing).
    pub title: Option<String>,
}

/// Draws a study's output: a map, curve or assemble CSV, or a diagnose JSON.
pub fn plot_text(text: &str, o: &PlotOptions) -> Result<String> {
    plot_reader(text.as_bytes(), o)
}

/// Draws a study's output read from a stream, keeping only the columns the picture needs.
pub fn plot_reader(input: impl std::io::Read, o: &PlotOptions) -> Result<String> {
    use std::io::BufRead;
    let mut input = std::io::BufReader::with_capacity(1 << 20, input);
    let starts_json = loop {
        let buffer = input.fill_buf()?;
        match buffer.iter().position(|b| !b.is_ascii_whitespace()) {
            Some(k) => break buffer[k] == b'{',
            None if buffer.is_empty() => bail!("the input is empty: nothing to draw"),
            None => {
                let n = buffer.len();
                input.consume(n);
            }
        }
    };
    if starts_json {
        let what = "reading the diagnosis JSON (written by stiff diagnose --json?)";
        let value: serde_json::Value = serde_json::from_reader(input).context(what)?;
        // A serial arm's calibration (joint-space data) or a diagnosis of displacements at poses.
        if value.get("calibration").is_some() {
            let report: crate::output::calibration::CalibrationFile = serde_json::from_value(value).context(what)?;
            return calibration::calibration(&report, o);
        }
        let report: DiagnosisReport = serde_json::from_value(value).context(what)?;
        return diagnosis(&report, o);
    }
    let (header, reader) = Table::header_of(input)?;
    let kind = kind_of(&header)?;
    let (numbers, texts) = (wanted_numbers(kind, o), wanted_texts(kind));
    let t = Table::read_rows(header, reader, &table::Wanted { numbers: &numbers, texts: &texts })?;
    draw(&t, kind, o)
}

/// Draws a Parquet table written by a study, reading only the columns the picture needs.
pub fn plot_parquet(file: std::fs::File, o: &PlotOptions) -> Result<String> {
    let numbers = |header: &[String], c: &str| TableKind::of(header).is_some_and(|k| wanted_numbers(k, o)(c));
    let texts = |header: &[String], c: &str| TableKind::of(header).is_some_and(|k| wanted_texts(k)(c));
    let read = crate::output::parquet::read_columns(file, &numbers, &texts)?;
    let kind = kind_of(&read.header)?;
    let t = Table::from_columns(read.header, read.rows, read.numbers, read.texts);
    draw(&t, kind, o)
}

/// Which study wrote a table with this header, or why it is none of them.
fn kind_of(header: &[String]) -> Result<TableKind> {
    TableKind::of(header).ok_or_else(|| {
        anyhow::anyhow!(
            "not a table stiff draws: a map, curve, assemble, assemble --samples or compensate CSV, or a diagnose JSON \
             (columns: {})",
            header.join(", ")
        )
    })
}

/// The numeric columns a picture of a `kind` table draws: a curve's all; else the positions, the column
/// drawn, and an assembly path's series.
fn wanted_numbers(kind: TableKind, o: &PlotOptions) -> impl Fn(&str) -> bool + '_ {
    move |c: &str| match kind {
        TableKind::Curve => true,
        _ => {
            names::POSITION.contains(&c)
                || o.column.as_deref() == Some(c)
                || o.column.is_none() && points::default_column(kind).is_some_and(|d| d == c)
                || kind == TableKind::Assembly && assembly::SERIES.iter().any(|p| c.starts_with(&format!("{p}_d")))
                || kind == TableKind::Compensation && compensation::SERIES.iter().any(|p| c.starts_with(p))
        }
    }
}

/// The text columns: a curve's stability and events, the poses' names.
fn wanted_texts(kind: TableKind) -> impl Fn(&str) -> bool {
    move |c: &str| match kind {
        TableKind::Curve => [names::STABLE, names::EVENT].contains(&c),
        TableKind::Compensation => [names::NAME, names::METHOD].contains(&c),
        _ => c == names::NAME,
    }
}

/// The picture of a table of this kind.
fn draw(t: &Table, kind: TableKind, o: &PlotOptions) -> Result<String> {
    match kind {
        TableKind::Curve => curve::curve(t, o),
        TableKind::Assembly if o.column.is_none() && points::is_path(t)? => assembly::assembly_path(t, o),
        TableKind::Compensation if o.column.is_none() && points::is_path(t)? => compensation::compensation_path(t, o),
        _ => points::picture(t, &points::quantity(t, kind, o.column.as_deref())?, o),
    }
}

/// Writes the picture's heading: the title (what it is of) on the first line where given, what it shows
/// below; returns the height it takes.
pub fn heading(s: &mut Svg, width: f64, o: &PlotOptions, what: &str) -> f64 {
    let mut y = 22.0;
    if let Some(title) = o.title.as_deref().filter(|t| !t.is_empty()) {
        for line in wrap(title, 14.0, width - 20.0) {
            s.text(width / 2.0, y, &line, 14.0, "middle", 0.0);
            y += 18.0;
        }
        y += 2.0;
    }
    let size = if o.title.is_some() { 12.0 } else { 14.0 };
    for line in wrap(what, size, width - 20.0) {
        s.text(width / 2.0, y, &line, size, "middle", 0.0);
        y += size + 4.0;
    }
    y - 10.0
}

/// A text cut into lines no wider than `width` at its `, ` and spaces (a word wider than the line keeps
/// its own line).
fn wrap(text: &str, size: f64, width: f64) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split(' ') {
        let candidate = if line.is_empty() { word.to_string() } else { format!("{line} {word}") };
        if text_width(&candidate, size) > width && !line.is_empty() {
            lines.push(std::mem::replace(&mut line, word.to_string()));
        } else {
            line = candidate;
        }
    }
    lines.push(line);
    lines
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// The distinct values, sorted (values within 1e-9 relative of each other are one).
fn distinct(values: &[f64]) -> Vec<f64> {
    let mut v: Vec<f64> = values.to_vec();
    v.sort_unstable_by(f64::total_cmp);
    v.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * (1.0 + a.abs()));
    v
}

/// Largest minus smallest value (negative infinity when there is none).
fn extent(values: impl Iterator<Item = f64>) -> f64 {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    hi - lo
}

/// The smallest gap between sorted distinct values (infinity for fewer than two).
fn spacing(sorted_distinct: &[f64]) -> f64 {
    sorted_distinct.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min)
}

/// A picture option that cannot be used: the command line names its flag (`PlotOptions` field).
#[derive(Clone, Debug, PartialEq)]
pub enum OptionError {
    /// The section is not AXIS=VALUE with a finite value.
    Section(String),
    /// The map has no such column.
    Column {
        /// The column asked for.
        column: String,
        /// The columns the map has.
        columns: String,
    },
    /// The curve direction is not one of x, y, z, rx, ry, rz.
    Direction(String),
}

impl std::fmt::Display for OptionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OptionError::Section(why) => f.write_str(why),
            OptionError::Column { column, columns } => {
                write!(f, "the table has no column `{column}` (columns: {columns})")
            }
            OptionError::Direction(d) => write!(f, "`{d}` is not one of x, y, z, rx, ry, rz"),
        }
    }
}

impl std::error::Error for OptionError {}

/// A section AXIS=VALUE: the axis (0, 1, 2 for x, y, z) and the value (mm).
pub fn parse_section(s: &str) -> Result<(usize, f64), OptionError> {
    let bad = |why: String| OptionError::Section(why);
    let (a, v) = s.split_once('=').ok_or_else(|| bad("wants AXIS=VALUE, e.g. z=0".into()))?;
    let axis = AXES.iter().position(|x| *x == a.trim()).ok_or_else(|| bad("the axis must be x, y or z".into()))?;
    let v: f64 = v.trim().parse().map_err(|_| bad(format!("value `{v}` is not a number")))?;
    if !v.is_finite() {
        return Err(bad(format!("value `{v}` is not a finite number")));
    }
    Ok((axis, v))
}

/// Checks a map picture's options against the header of the map that will be written, before the map is
/// computed (a bad `--section` used to fail after a million-point map was written).
pub fn check_map_options(header: &str, o: &PlotOptions) -> Result<()> {
    if let Some(s) = &o.section {
        parse_section(s)?;
    }
    let column = o.column.as_deref().or(points::default_column(TableKind::Map)).unwrap_or(names::C_TRAN_MAX);
    let columns: Vec<&str> = header.trim_end().split(',').collect();
    if !columns.contains(&column) {
        return Err(OptionError::Column { column: column.into(), columns: header.trim_end().into() }.into());
    }
    // The picture places each row by its position.
    if let Some(missing) = names::POSITION.iter().find(|c| !columns.contains(c)) {
        bail!("the picture places each point by x_mm, y_mm, z_mm, and `{missing}` is not written (keep the group pose in --columns)");
    }
    Ok(())
}

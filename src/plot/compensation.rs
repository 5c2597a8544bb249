//! The error along a compensated path (paper 000 Figures 10-11 with the compensation its s. 5.2 calls
//! for): per axis, the error of the reference point without compensation, with the mirror command and with
//! the command written (its independent forward solve), each named with its largest length.

use anyhow::Result;

use super::assembly::{path_panels, Series};
use super::svg::tick_label;
use super::table::Table;
use super::PlotOptions;
use crate::output::table::names;

/// The series of a compensation table, by their columns' prefix.
pub const SERIES: [&str; 3] = [names::UNCOMPENSATED, names::MIRROR, names::RESIDUAL];

/// The path picture of a compensation table whose targets lie on a line.
pub fn compensation_path(t: &Table, o: &PlotOptions) -> Result<String> {
    let method = t.texts(names::METHOD)?.first().cloned().unwrap_or_default();
    let largest = |prefix: &str| -> Result<String> {
        let values = t.numbers(&format!("{prefix}_error_mm"))?;
        let top = values.iter().flatten().fold(f64::NAN, |m, v| m.max(*v));
        Ok(if top.is_finite() { format!("largest {} mm", tick_label(top)) } else { "no value".into() })
    };
    let mut series = vec![Series {
        columns: names::UNCOMPENSATED,
        name: format!("without compensation ({})", largest(names::UNCOMPENSATED)?),
        colour: "#c0392b",
        dashed: false,
    }];
    // With the mirror method the command written is the mirror command: one line.
    if method != "mirror" {
        series.push(Series {
            columns: names::MIRROR,
            name: format!("mirror command ({})", largest(names::MIRROR)?),
            colour: "#e67e22",
            dashed: true,
        });
    }
    let method = if method == "newton" { "Newton's" } else { method.as_str() };
    series.push(Series {
        columns: names::RESIDUAL,
        name: format!("{method} command, forward solve ({})", largest(names::RESIDUAL)?),
        colour: "#2471a3",
        dashed: false,
    });
    path_panels(t, o, "error of the reference point along the path (target = 0)", series)
}

//! A study's table read back for its picture, and which study wrote it.

use anyhow::{anyhow, Result};

use crate::output::table::names;

/// A CSV held as text cells.
pub struct Table {
    /// Column names.
    pub header: Vec<String>,
    /// Cells, row by row.
    pub rows: Vec<Vec<String>>,
}

/// Which study wrote a table, told by a column only that study writes (`output::table::names`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableKind {
    /// `stiff curve`: has `load_factor`.
    Curve,
    /// `stiff assemble`: has the non-linear assembly's displacement `nl_dx_mm`.
    Assembly,
    /// `stiff assemble --samples`: has `samples` and the mean displacement `mean_dx_mm`.
    Samples,
    /// `stiff map`: has `c_tran_max_mm_per_N`, or at least the poses.
    Map,
}

impl Table {
    /// Parses a CSV a study wrote.
    pub fn parse(text: &str) -> Result<Table> {
        let mut reader = csv::ReaderBuilder::new().from_reader(text.as_bytes());
        let header = reader.headers()?.iter().map(String::from).collect();
        let rows =
            reader.records().map(|r| r.map(|r| r.iter().map(String::from).collect())).collect::<Result<_, _>>()?;
        Ok(Table { header, rows })
    }

    /// Which study wrote this table; None when it is none of them.
    pub fn kind(&self) -> Option<TableKind> {
        let nonlinear = format!("{}_{}", names::NONLINEAR, names::DISPLACEMENT[0]);
        if self.has(names::LOAD_FACTOR) {
            Some(TableKind::Curve)
        } else if self.has(&nonlinear) {
            Some(TableKind::Assembly)
        } else if self.has("samples") && self.has("mean_dx_mm") {
            Some(TableKind::Samples)
        } else if self.has(names::C_TRAN_MAX) || names::POSITION.iter().all(|c| self.has(c)) {
            Some(TableKind::Map)
        } else {
            None
        }
    }

    /// Whether a column of this name exists.
    pub fn has(&self, c: &str) -> bool {
        self.header.iter().any(|h| h == c)
    }

    fn index(&self, c: &str) -> Result<usize> {
        self.header
            .iter()
            .position(|h| h == c)
            .ok_or_else(|| anyhow!("no column `{c}` (columns: {})", self.header.join(", ")))
    }

    /// A numeric column; empty or non-numeric cells are None.
    pub fn numbers(&self, c: &str) -> Result<Vec<Option<f64>>> {
        let i = self.index(c)?;
        Ok(self.rows.iter().map(|r| r.get(i).and_then(|v| v.parse::<f64>().ok()).filter(|v| v.is_finite())).collect())
    }

    /// A numeric column with missing cells as NaN.
    pub fn numbers_or_nan(&self, c: &str) -> Result<Vec<f64>> {
        Ok(self.numbers(c)?.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect())
    }

    /// A text column.
    pub fn texts(&self, c: &str) -> Result<Vec<String>> {
        let i = self.index(c)?;
        Ok(self.rows.iter().map(|r| r.get(i).cloned().unwrap_or_default()).collect())
    }

    /// The rows' positions, one vector per axis (x, y, z; NaN where missing).
    pub fn positions(&self) -> Result<[Vec<f64>; 3]> {
        Ok([
            self.numbers_or_nan(names::POSITION[0])?,
            self.numbers_or_nan(names::POSITION[1])?,
            self.numbers_or_nan(names::POSITION[2])?,
        ])
    }
}

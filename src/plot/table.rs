//! A study's table read back for its picture, and which study wrote it.
//!
//! Only the columns a picture draws are kept, numbers as f64 and texts as text, read as the file streams
//! by: a million-point map is drawn from a few columns of 8 bytes per row, not from its 600 MB of text.

use std::collections::HashMap;
use std::io::Read;

use anyhow::{anyhow, Context, Result};

use crate::output::table::names;

/// The columns of a study's table that a picture needs.
pub struct Table {
    /// Every column name of the file, in order.
    pub header: Vec<String>,
    rows: usize,
    /// Numeric columns, NaN where a cell is empty, not a number or not finite.
    numbers: HashMap<String, Vec<f64>>,
    texts: HashMap<String, TextColumn>,
}

/// A column of texts in one buffer: a million empty names take 8 MB of offsets, not 24 MB of `String`s.
#[derive(Default)]
struct TextColumn {
    text: String,
    ends: Vec<usize>,
}

impl TextColumn {
    fn push(&mut self, cell: &str) {
        self.text.push_str(cell);
        self.ends.push(self.text.len());
    }

    fn iter(&self) -> impl Iterator<Item = &str> + '_ {
        let starts = std::iter::once(0).chain(self.ends.iter().copied());
        starts.zip(&self.ends).map(|(a, b)| &self.text[a..*b])
    }
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
    /// `stiff compensate`: has the command `command_x_mm`.
    Compensation,
    /// `stiff map`: has `c_tran_max_mm_per_N`, or at least the poses.
    Map,
}

impl TableKind {
    /// Which study wrote a table with this header; None when it is none of them.
    pub fn of(header: &[String]) -> Option<TableKind> {
        let has = |c: &str| header.iter().any(|h| h == c);
        let nonlinear = format!("{}_{}", names::NONLINEAR, names::DISPLACEMENT[0]);
        if has(names::LOAD_FACTOR) {
            Some(TableKind::Curve)
        } else if has(&nonlinear) {
            Some(TableKind::Assembly)
        } else if has("samples") && has("mean_dx_mm") {
            Some(TableKind::Samples)
        } else if has(names::COMMAND[0]) {
            Some(TableKind::Compensation)
        } else if has(names::C_TRAN_MAX) || names::POSITION.iter().all(|c| has(c)) {
            Some(TableKind::Map)
        } else {
            None
        }
    }
}

/// Which columns to keep, and how.
pub struct Wanted<'a> {
    /// Columns kept as numbers (empty or non-numeric cells: missing).
    pub numbers: &'a dyn Fn(&str) -> bool,
    /// Columns kept as text.
    pub texts: &'a dyn Fn(&str) -> bool,
}

impl Table {
    /// Parses a CSV a study wrote, keeping every column as text and as numbers (small tables, tests).
    pub fn parse(text: &str) -> Result<Table> {
        Table::read(text.as_bytes(), &Wanted { numbers: &|_| true, texts: &|_| true })
    }

    /// The header of a CSV stream, and the rest of it.
    pub fn header_of(input: impl Read) -> Result<(Vec<String>, csv::Reader<impl Read>)> {
        let mut reader = csv::ReaderBuilder::new().from_reader(input);
        let header = reader.headers().context("reading the table's header")?.iter().map(String::from).collect();
        Ok((header, reader))
    }

    /// Reads a CSV a study wrote, keeping the columns `wanted` names.
    pub fn read(input: impl Read, wanted: &Wanted) -> Result<Table> {
        let (header, reader) = Table::header_of(input)?;
        Table::read_rows(header, reader, wanted)
    }

    /// Reads the rows after `header`, keeping the columns `wanted` names.
    pub fn read_rows(header: Vec<String>, mut reader: csv::Reader<impl Read>, wanted: &Wanted) -> Result<Table> {
        let number_columns: Vec<(usize, Vec<f64>)> =
            header.iter().enumerate().filter(|(_, h)| (wanted.numbers)(h)).map(|(k, _)| (k, Vec::new())).collect();
        let text_columns: Vec<(usize, TextColumn)> = header
            .iter()
            .enumerate()
            .filter(|(_, h)| (wanted.texts)(h))
            .map(|(k, _)| (k, TextColumn::default()))
            .collect();
        let (mut number_columns, mut text_columns) = (number_columns, text_columns);
        let mut record = csv::ByteRecord::new();
        let mut rows = 0;
        while reader.read_byte_record(&mut record).with_context(|| format!("reading row {}", rows + 1))? {
            for (k, values) in &mut number_columns {
                let cell = record.get(*k).unwrap_or(b"");
                let v = std::str::from_utf8(cell).ok().and_then(|s| s.parse::<f64>().ok());
                values.push(v.filter(|v| v.is_finite()).unwrap_or(f64::NAN));
            }
            for (k, values) in &mut text_columns {
                values.push(&String::from_utf8_lossy(record.get(*k).unwrap_or(b"")));
            }
            rows += 1;
        }
        let numbers = number_columns.into_iter().map(|(k, v)| (header[k].clone(), v)).collect();
        let texts = text_columns.into_iter().map(|(k, v)| (header[k].clone(), v)).collect();
        Ok(Table { header, rows, numbers, texts })
    }

    /// A table of columns already read (a Parquet file's projection).
    pub fn from_columns(
        header: Vec<String>,
        rows: usize,
        numbers: Vec<(String, Vec<f64>)>,
        texts: Vec<(String, Vec<String>)>,
    ) -> Table {
        let numbers = numbers
            .into_iter()
            .map(|(c, mut v)| {
                v.iter_mut().filter(|x| !x.is_finite()).for_each(|x| *x = f64::NAN);
                (c, v)
            })
            .collect();
        let texts = texts
            .into_iter()
            .map(|(c, v)| {
                let mut column = TextColumn::default();
                v.iter().for_each(|cell| column.push(cell));
                (c, column)
            })
            .collect();
        Table { header, rows, numbers, texts }
    }

    /// Which study wrote this table; None when it is none of them.
    pub fn kind(&self) -> Option<TableKind> {
        TableKind::of(&self.header)
    }

    /// The number of rows.
    pub fn len(&self) -> usize {
        self.rows
    }

    /// Whether the table has no rows.
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// Whether a column of this name exists.
    pub fn has(&self, c: &str) -> bool {
        self.header.iter().any(|h| h == c)
    }

    fn missing(&self, c: &str) -> anyhow::Error {
        anyhow!("no column `{c}` (columns: {})", self.header.join(", "))
    }

    /// A numeric column; empty, non-numeric and non-finite cells are None.
    pub fn numbers(&self, c: &str) -> Result<Vec<Option<f64>>> {
        Ok(self.numbers_or_nan(c)?.iter().map(|v| Some(*v).filter(|v| v.is_finite())).collect())
    }

    /// A numeric column with missing cells as NaN, as it is kept.
    pub fn numbers_or_nan(&self, c: &str) -> Result<&[f64]> {
        self.numbers.get(c).map(Vec::as_slice).ok_or_else(|| self.missing(c))
    }

    /// A text column.
    pub fn texts(&self, c: &str) -> Result<Vec<String>> {
        Ok(self.text_cells(c)?.map(String::from).collect())
    }

    /// A text column's cells, without copying them.
    pub fn text_cells(&self, c: &str) -> Result<impl Iterator<Item = &str> + '_> {
        self.texts.get(c).map(TextColumn::iter).ok_or_else(|| self.missing(c))
    }

    /// The rows' positions, one column per axis (x, y, z; NaN where missing), as they are kept.
    pub fn positions(&self) -> Result<[&[f64]; 3]> {
        Ok([
            self.numbers_or_nan(names::POSITION[0])?,
            self.numbers_or_nan(names::POSITION[1])?,
            self.numbers_or_nan(names::POSITION[2])?,
        ])
    }
}

//! Tables as Parquet (`-o map.parquet`): one column per CSV column, with the same name, its type
//! (`CellKind`: f64, u64 or UTF-8 text), its unit in the field metadata (`unit`, absent for a dimensionless
//! column), an empty CSV cell as a null, zstd compression.
//!
//! A study writes its rows as CSV text whatever the output (so that the rows, the thread-count
//! independence and the selection of columns have one implementation); `ParquetTable` reads that text back
//! record by record and fills typed columns. The numbers are written in shortest round-trip form, so reading
//! them back gives the same f64 bit for bit. Row groups of `ROWS_PER_GROUP` rows keep memory bounded on
//! maps of millions of points.
//!
//! `read_columns` reads back the columns a picture needs (`stiff plot`, `--plot`), and no others.

use std::io::{self, Write};
use std::sync::Arc;

use arrow_array::builder::{Float64Builder, StringBuilder, UInt64Builder};
use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch, StringArray, UInt64Array};
use arrow_schema::{DataType, Field, Schema, SchemaRef};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression, ZstdLevel};
use parquet::file::properties::WriterProperties;

use super::table::{header_line, unit_of, CellKind, Column};

/// Rows per row group (and per batch handed to the Parquet writer): about 30 MB of a 60-column map.
const ROWS_PER_GROUP: usize = 65_536;

/// The field metadata key holding a column's unit.
pub const UNIT_KEY: &str = "unit";

/// The Arrow schema of a table: each column's type and unit.
pub fn schema(columns: &[Column]) -> Schema {
    Schema::new(
        columns
            .iter()
            .map(|c| {
                let data_type = match c.kind {
                    CellKind::Number => DataType::Float64,
                    CellKind::Count => DataType::UInt64,
                    CellKind::Text => DataType::Utf8,
                };
                let field = Field::new(&c.name, data_type, true);
                match unit_of(&c.name) {
                    Some(unit) => field.with_metadata([(UNIT_KEY, unit)]),
                    None => field,
                }
            })
            .collect::<Vec<_>>(),
    )
}

/// One column being filled.
enum Builder {
    Number(Float64Builder),
    Count(UInt64Builder),
    Text(StringBuilder),
}

impl Builder {
    fn new(kind: CellKind) -> Builder {
        match kind {
            CellKind::Number => Builder::Number(Float64Builder::with_capacity(ROWS_PER_GROUP)),
            CellKind::Count => Builder::Count(UInt64Builder::with_capacity(ROWS_PER_GROUP)),
            CellKind::Text => Builder::Text(StringBuilder::new()),
        }
    }

    /// Appends one CSV cell (unquoted); empty is null.
    fn push(&mut self, cell: &str, column: &str) -> io::Result<()> {
        let bad =
            |what: &str| io::Error::new(io::ErrorKind::InvalidData, format!("column {column}: `{cell}` is not {what}"));
        match self {
            _ if cell.is_empty() => self.push_null(),
            Builder::Number(b) => b.append_value(cell.parse().map_err(|_| bad("a number"))?),
            Builder::Count(b) => b.append_value(cell.parse().map_err(|_| bad("a count"))?),
            Builder::Text(b) => b.append_value(cell),
        }
        Ok(())
    }

    fn push_null(&mut self) {
        match self {
            Builder::Number(b) => b.append_null(),
            Builder::Count(b) => b.append_null(),
            Builder::Text(b) => b.append_null(),
        }
    }

    fn finish(&mut self) -> ArrayRef {
        match self {
            Builder::Number(b) => Arc::new(b.finish()),
            Builder::Count(b) => Arc::new(b.finish()),
            Builder::Text(b) => Arc::new(b.finish()),
        }
    }
}

/// A Parquet file being written from a study's CSV text (`Write`): the header line, then rows.
pub struct ParquetTable<W: Write + Send> {
    writer: ArrowWriter<W>,
    schema: SchemaRef,
    header: String,
    builders: Vec<Builder>,
    /// Bytes received that do not yet end a record.
    pending: Vec<u8>,
    /// How far `pending` has been scanned for a record's end, and whether that point is inside quotes.
    scanned: usize,
    in_quotes: bool,
    header_seen: bool,
    rows: usize,
}

fn parquet_error(e: parquet::errors::ParquetError) -> io::Error {
    io::Error::other(e.to_string())
}

impl<W: Write + Send> ParquetTable<W> {
    /// A table with these columns, written to `out`.
    pub fn new(out: W, columns: &[Column]) -> io::Result<Self> {
        let schema = Arc::new(schema(columns));
        let properties = WriterProperties::builder()
            .set_compression(Compression::ZSTD(ZstdLevel::default()))
            .set_max_row_group_row_count(Some(ROWS_PER_GROUP))
            .set_created_by(format!("stiff {}", env!("CARGO_PKG_VERSION")))
            .build();
        let writer = ArrowWriter::try_new(out, schema.clone(), Some(properties)).map_err(parquet_error)?;
        Ok(ParquetTable {
            writer,
            schema,
            header: header_line(columns).trim_end().to_string(),
            builders: columns.iter().map(|c| Builder::new(c.kind)).collect(),
            pending: Vec::new(),
            scanned: 0,
            in_quotes: false,
            header_seen: false,
            rows: 0,
        })
    }

    /// Takes every complete record out of `pending`.
    fn take_records(&mut self) -> io::Result<()> {
        let mut start = 0;
        let mut k = self.scanned;
        while k < self.pending.len() {
            match self.pending[k] {
                b'"' => self.in_quotes = !self.in_quotes,
                b'\n' if !self.in_quotes => {
                    let record = std::mem::take(&mut self.pending);
                    let line = std::str::from_utf8(&record[start..k])
                        .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "a row is not UTF-8"));
                    let result = line.and_then(|line| self.record(line.trim_end_matches('\r')));
                    self.pending = record;
                    result?;
                    start = k + 1;
                }
                _ => {}
            }
            k += 1;
        }
        self.pending.drain(..start);
        self.scanned = self.pending.len();
        Ok(())
    }

    /// One CSV record: the header (checked against the columns) or a row.
    fn record(&mut self, line: &str) -> io::Result<()> {
        if !self.header_seen {
            if line != self.header {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!("the table's header `{line}` is not its columns `{}`", self.header),
                ));
            }
            self.header_seen = true;
            return Ok(());
        }
        // Most rows hold no quoted cell: split them without copying.
        let cells: Vec<std::borrow::Cow<str>> = if line.contains('"') {
            split_record(line).into_iter().map(Into::into).collect()
        } else {
            line.split(',').map(Into::into).collect()
        };
        if cells.len() != self.builders.len() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("a row has {} cells for {} columns", cells.len(), self.builders.len()),
            ));
        }
        for ((builder, cell), field) in self.builders.iter_mut().zip(&cells).zip(self.schema.fields()) {
            builder.push(cell, field.name())?;
        }
        self.rows += 1;
        if self.rows == ROWS_PER_GROUP {
            self.flush_rows()?;
        }
        Ok(())
    }

    /// Hands the rows gathered to the Parquet writer.
    fn flush_rows(&mut self) -> io::Result<()> {
        if self.rows == 0 {
            return Ok(());
        }
        let arrays: Vec<ArrayRef> = self.builders.iter_mut().map(Builder::finish).collect();
        let batch = RecordBatch::try_new(self.schema.clone(), arrays).map_err(|e| io::Error::other(e.to_string()))?;
        self.writer.write(&batch).map_err(parquet_error)?;
        self.rows = 0;
        Ok(())
    }

    /// Writes the last rows and the file's footer; hands back the output.
    pub fn finish(mut self) -> io::Result<W> {
        if !self.pending.is_empty() {
            return Err(io::Error::new(io::ErrorKind::InvalidData, "the table ends inside a row"));
        }
        self.flush_rows()?;
        self.writer.into_inner().map_err(parquet_error)
    }
}

impl<W: Write + Send> Write for ParquetTable<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.pending.extend_from_slice(buf);
        self.take_records()?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// The cells of one CSV record, unquoted (`push_text` quotes a cell holding `,`, `"` or a line break and
/// doubles its quotes).
fn split_record(line: &str) -> Vec<String> {
    let mut cells = Vec::new();
    let mut cell = String::new();
    let mut in_quotes = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '"' if in_quotes && chars.peek() == Some(&'"') => {
                cell.push('"');
                chars.next();
            }
            '"' => in_quotes = !in_quotes,
            ',' if !in_quotes => cells.push(std::mem::take(&mut cell)),
            _ => cell.push(c),
        }
    }
    cells.push(cell);
    cells
}

/// Columns of a Parquet table read back: every column name, the row count, and the columns kept, numbers
/// as f64 (counts converted, nulls as NaN) and texts as text (nulls empty).
pub struct ColumnsRead {
    /// Every column name of the file, in order.
    pub header: Vec<String>,
    /// Rows.
    pub rows: usize,
    /// The numeric columns kept.
    pub numbers: Vec<(String, Vec<f64>)>,
    /// The text columns kept.
    pub texts: Vec<(String, Vec<String>)>,
}

/// The column names of a Parquet table, then the columns `numbers` and `texts` choose among them, read
/// alone (a projection: a picture of a million-point map reads 4 columns, not 40).
pub fn read_columns(
    file: std::fs::File,
    numbers: &dyn Fn(&[String], &str) -> bool,
    texts: &dyn Fn(&[String], &str) -> bool,
) -> io::Result<ColumnsRead> {
    let invalid = |e: parquet::errors::ParquetError| {
        io::Error::new(io::ErrorKind::InvalidData, format!("not a Parquet table: {e}"))
    };
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(invalid)?;
    let header: Vec<String> = builder.schema().fields().iter().map(|f| f.name().clone()).collect();
    let keep: Vec<usize> =
        (0..header.len()).filter(|&k| numbers(&header, &header[k]) || texts(&header, &header[k])).collect();
    let mask = parquet::arrow::ProjectionMask::roots(builder.parquet_schema(), keep.iter().copied());
    let reader = builder.with_projection(mask).build().map_err(invalid)?;
    let kept: Vec<String> = keep.iter().map(|&k| header[k].clone()).collect();
    let mut number_columns: Vec<(String, Vec<f64>)> =
        kept.iter().filter(|c| numbers(&header, c)).map(|c| (c.clone(), Vec::new())).collect();
    let mut text_columns: Vec<(String, Vec<String>)> =
        kept.iter().filter(|c| texts(&header, c)).map(|c| (c.clone(), Vec::new())).collect();
    let mut rows = 0;
    for batch in reader {
        let batch = batch.map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e.to_string()))?;
        for (name, values) in &mut number_columns {
            let column = batch.column_by_name(name).ok_or_else(|| io::Error::other(format!("no column {name}")))?;
            let any = column.as_any();
            for r in 0..batch.num_rows() {
                values.push(if column.is_null(r) {
                    f64::NAN
                } else if let Some(a) = any.downcast_ref::<Float64Array>() {
                    a.value(r)
                } else if let Some(a) = any.downcast_ref::<UInt64Array>() {
                    a.value(r) as f64
                } else {
                    f64::NAN
                });
            }
        }
        for (name, values) in &mut text_columns {
            let column = batch.column_by_name(name).ok_or_else(|| io::Error::other(format!("no column {name}")))?;
            let strings = column.as_any().downcast_ref::<StringArray>();
            for r in 0..batch.num_rows() {
                values.push(match strings {
                    Some(a) if !a.is_null(r) => a.value(r).to_string(),
                    _ => String::new(),
                });
            }
        }
        rows += batch.num_rows();
    }
    Ok(ColumnsRead { header, rows, numbers: number_columns, texts: text_columns })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Quoted cells (a point named `a,"b"`) split as the CSV writer quoted them.
    #[test]
    fn records_split_as_they_were_quoted() {
        assert_eq!(split_record(r#"1,"a,""b""",,x"#), vec!["1", r#"a,"b""#, "", "x"]);
    }
}

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

use parquet::basic::{Compression, IntType, LogicalType, Repetition, Type as PhysicalType, ZstdLevel};
use parquet::column::reader::ColumnReader;
use parquet::column::writer::ColumnWriter;
use parquet::data_type::ByteArray;
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::reader::{FileReader, SerializedFileReader};
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;

use super::table::{header_line, CellKind, Column};

mod arrow_schema;

/// Rows per row group: about 30 MB of a 60-column map.
const ROWS_PER_GROUP: usize = 65_536;

/// The field metadata key holding a column's unit.
pub const UNIT_KEY: &str = "unit";

/// The Parquet schema of a table: each column optional (an empty cell is a null), f64 as DOUBLE, a count
/// as an unsigned 64-bit INT64, text as UTF-8 BYTE_ARRAY (the types Arrow readers map to float64, uint64
/// and string).
fn parquet_schema(columns: &[Column]) -> io::Result<Type> {
    let fields = columns
        .iter()
        .map(|c| {
            let (physical, logical) = match c.kind {
                CellKind::Number => (PhysicalType::DOUBLE, None),
                CellKind::Count => {
                    (PhysicalType::INT64, Some(LogicalType::Integer(IntType { bit_width: 64, is_signed: false })))
                }
                CellKind::Text => (PhysicalType::BYTE_ARRAY, Some(LogicalType::String)),
            };
            Type::primitive_type_builder(&c.name, physical)
                .with_repetition(Repetition::OPTIONAL)
                .with_logical_type(logical)
                .build()
                .map(Arc::new)
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(parquet_error)?;
    Type::group_type_builder("arrow_schema").with_fields(fields).build().map_err(parquet_error)
}

/// One column being filled: its non-null values and its definition levels (1 a value, 0 a null).
enum Values {
    Number(Vec<f64>),
    Count(Vec<i64>),
    Text(Vec<ByteArray>),
}

struct Builder {
    values: Values,
    defined: Vec<i16>,
}

impl Builder {
    fn new(kind: CellKind) -> Builder {
        let values = match kind {
            CellKind::Number => Values::Number(Vec::with_capacity(ROWS_PER_GROUP)),
            CellKind::Count => Values::Count(Vec::with_capacity(ROWS_PER_GROUP)),
            CellKind::Text => Values::Text(Vec::new()),
        };
        Builder { values, defined: Vec::with_capacity(ROWS_PER_GROUP) }
    }

    /// Appends one CSV cell (unquoted); empty is null.
    fn push(&mut self, cell: &str, column: &str) -> io::Result<()> {
        let bad =
            |what: &str| io::Error::new(io::ErrorKind::InvalidData, format!("column {column}: `{cell}` is not {what}"));
        if cell.is_empty() {
            self.defined.push(0);
            return Ok(());
        }
        match &mut self.values {
            Values::Number(v) => v.push(cell.parse().map_err(|_| bad("a number"))?),
            // An unsigned count is stored in INT64's bits, as Parquet's UINT_64 logical type says.
            Values::Count(v) => v.push(cell.parse::<u64>().map_err(|_| bad("a count"))? as i64),
            Values::Text(v) => v.push(ByteArray::from(cell)),
        }
        self.defined.push(1);
        Ok(())
    }

    /// Writes the column's rows gathered and empties it.
    fn write(&mut self, writer: &mut ColumnWriter<'_>) -> parquet::errors::Result<()> {
        let defined = Some(self.defined.as_slice());
        match (&mut self.values, writer) {
            (Values::Number(v), ColumnWriter::DoubleColumnWriter(w)) => {
                w.write_batch(v, defined, None)?;
                v.clear();
            }
            (Values::Count(v), ColumnWriter::Int64ColumnWriter(w)) => {
                w.write_batch(v, defined, None)?;
                v.clear();
            }
            (Values::Text(v), ColumnWriter::ByteArrayColumnWriter(w)) => {
                w.write_batch(v, defined, None)?;
                v.clear();
            }
            _ => return Err(parquet::errors::ParquetError::General("a column's type changed".into())),
        }
        self.defined.clear();
        Ok(())
    }
}

/// A Parquet file being written from a study's CSV text (`Write`): the header line, then rows.
pub struct ParquetTable<W: Write + Send> {
    writer: SerializedFileWriter<W>,
    names: Vec<String>,
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
        // The Arrow schema rides along as Arrow's own writers store it, so pyarrow, pandas and polars read
        // each column's unit as its field metadata.
        let arrow = KeyValue::new(arrow_schema::KEY.to_string(), arrow_schema::encode(columns));
        let properties = WriterProperties::builder()
            .set_compression(Compression::ZSTD(ZstdLevel::default()))
            .set_max_row_group_row_count(Some(ROWS_PER_GROUP))
            .set_created_by(format!("stiff {}", env!("CARGO_PKG_VERSION")))
            .set_key_value_metadata(Some(vec![arrow]))
            .build();
        let writer = SerializedFileWriter::new(out, Arc::new(parquet_schema(columns)?), Arc::new(properties))
            .map_err(parquet_error)?;
        Ok(ParquetTable {
            writer,
            names: columns.iter().map(|c| c.name.clone()).collect(),
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
        for ((builder, cell), name) in self.builders.iter_mut().zip(&cells).zip(&self.names) {
            builder.push(cell, name)?;
        }
        self.rows += 1;
        if self.rows == ROWS_PER_GROUP {
            self.flush_rows()?;
        }
        Ok(())
    }

    /// Writes the rows gathered as one row group.
    fn flush_rows(&mut self) -> io::Result<()> {
        if self.rows == 0 {
            return Ok(());
        }
        let mut group = self.writer.next_row_group().map_err(parquet_error)?;
        for builder in &mut self.builders {
            let mut column =
                group.next_column().map_err(parquet_error)?.ok_or_else(|| io::Error::other("a column too many"))?;
            builder.write(column.untyped()).map_err(parquet_error)?;
            column.close().map_err(parquet_error)?;
        }
        group.close().map_err(parquet_error)?;
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
    let reader = SerializedFileReader::new(file).map_err(invalid)?;
    let metadata = reader.metadata();
    let header: Vec<String> =
        metadata.file_metadata().schema_descr().columns().iter().map(|c| c.name().to_string()).collect();
    let mut number_columns: Vec<(usize, String, Vec<f64>)> = Vec::new();
    let mut text_columns: Vec<(usize, String, Vec<String>)> = Vec::new();
    for (k, name) in header.iter().enumerate() {
        if numbers(&header, name) {
            number_columns.push((k, name.clone(), Vec::new()));
        } else if texts(&header, name) {
            text_columns.push((k, name.clone(), Vec::new()));
        }
    }
    let rows = usize::try_from(metadata.file_metadata().num_rows()).map_err(|_| io::Error::other("negative rows"))?;
    let mut defined: Vec<i16> = Vec::new();
    for group in 0..reader.num_row_groups() {
        let group = reader.get_row_group(group).map_err(invalid)?;
        let group_rows = usize::try_from(group.metadata().num_rows()).unwrap_or(0);
        for (k, name, values) in &mut number_columns {
            let column = group.get_column_reader(*k).map_err(invalid)?;
            let numbers: Vec<f64> = match column {
                ColumnReader::DoubleColumnReader(mut r) => read_all(&mut r, group_rows, &mut defined)?,
                ColumnReader::Int64ColumnReader(mut r) => {
                    read_all(&mut r, group_rows, &mut defined)?.into_iter().map(|v| v as u64 as f64).collect()
                }
                _ => return Err(io::Error::new(io::ErrorKind::InvalidData, format!("column {name} is not numeric"))),
            };
            spread(values, numbers, &defined, f64::NAN);
        }
        for (k, name, values) in &mut text_columns {
            let column = group.get_column_reader(*k).map_err(invalid)?;
            let ColumnReader::ByteArrayColumnReader(mut r) = column else {
                return Err(io::Error::new(io::ErrorKind::InvalidData, format!("column {name} is not text")));
            };
            let texts = read_all(&mut r, group_rows, &mut defined)?
                .into_iter()
                .map(|b| String::from_utf8_lossy(b.data()).into_owned())
                .collect();
            spread(values, texts, &defined, String::new());
        }
    }
    Ok(ColumnsRead {
        header,
        rows,
        numbers: number_columns.into_iter().map(|(_, n, v)| (n, v)).collect(),
        texts: text_columns.into_iter().map(|(_, n, v)| (n, v)).collect(),
    })
}

/// Every value of one column chunk of `rows` rows, its definition levels left in `defined`.
fn read_all<T: parquet::data_type::DataType>(
    reader: &mut parquet::column::reader::ColumnReaderImpl<T>,
    rows: usize,
    defined: &mut Vec<i16>,
) -> io::Result<Vec<T::T>>
where
    T::T: Default + Clone,
{
    defined.clear();
    let mut values = Vec::new();
    let mut read = 0;
    while read < rows {
        let (records, _, _) = reader
            .read_records(rows - read, Some(defined), None, &mut values)
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e.to_string()))?;
        if records == 0 {
            return Err(io::Error::new(io::ErrorKind::InvalidData, "a column chunk ends early"));
        }
        read += records;
    }
    Ok(values)
}

/// Appends a column chunk's rows: its values where defined, `null` where not.
fn spread<T: Clone>(out: &mut Vec<T>, values: Vec<T>, defined: &[i16], null: T) {
    let mut values = values.into_iter();
    for &d in defined {
        out.push(if d > 0 { values.next().unwrap_or_else(|| null.clone()) } else { null.clone() });
    }
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

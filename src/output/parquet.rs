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
//! The file is written here from the format's specification (apache/parquet-format, `parquet.thrift`): "PAR1",
//! per row group one data page per column (version 1: the definition levels run-length encoded, the values
//! PLAIN, both compressed by zstd), then the footer (`FileMetaData` in Thrift's compact protocol, `thrift.rs`),
//! its length and "PAR1". `read_columns` (`read.rs`) reads back the columns a picture needs (`stiff plot`,
//! `--plot`), and no others.

use std::io::{self, Write};

use super::table::{header_line, CellKind, Column};

mod arrow_schema;
mod read;
mod thrift;

pub use read::{read_columns, ColumnsRead};

/// Rows per row group: about 30 MB of a 60-column map.
const ROWS_PER_GROUP: usize = 65_536;

/// The field metadata key holding a column's unit.
pub const UNIT_KEY: &str = "unit";

/// The file's first and last four bytes.
const MAGIC: &[u8; 4] = b"PAR1";

/// zstd's level for the pages (its fastest regular level, as Arrow's writer defaults to).
const ZSTD_LEVEL: i32 = 1;

/// Enumeration values of `parquet.thrift`.
mod code {
    /// `Type`.
    pub const INT64: i32 = 2;
    pub const DOUBLE: i32 = 5;
    pub const BYTE_ARRAY: i32 = 6;
    /// `FieldRepetitionType`.
    pub const OPTIONAL: i32 = 1;
    /// `ConvertedType`.
    pub const UTF8: i32 = 0;
    pub const UINT_64: i32 = 14;
    /// `Encoding`.
    pub const PLAIN: i32 = 0;
    pub const RLE: i32 = 3;
    /// `CompressionCodec`.
    pub const ZSTD: i32 = 6;
    /// `PageType`.
    pub const DATA_PAGE: i32 = 0;
}

/// The physical type a column's cells are stored as.
fn physical_type(kind: CellKind) -> i32 {
    match kind {
        CellKind::Number => code::DOUBLE,
        CellKind::Count => code::INT64,
        CellKind::Text => code::BYTE_ARRAY,
    }
}

/// One column being filled: its non-null values PLAIN-encoded, its definition levels (1 a value, 0 a
/// null) and its extremes (numbers and counts; a NaN is no extreme).
struct Builder {
    kind: CellKind,
    plain: Vec<u8>,
    defined: Vec<u8>,
    nulls: u64,
    range: Option<(f64, f64)>,
    count_range: Option<(u64, u64)>,
}

impl Builder {
    fn new(kind: CellKind) -> Builder {
        let plain = if kind == CellKind::Text { Vec::new() } else { Vec::with_capacity(8 * ROWS_PER_GROUP) };
        Builder { kind, plain, defined: Vec::with_capacity(ROWS_PER_GROUP), nulls: 0, range: None, count_range: None }
    }

    /// Appends one CSV cell (unquoted); empty is null.
    fn push(&mut self, cell: &str, column: &str) -> io::Result<()> {
        let bad =
            |what: &str| io::Error::new(io::ErrorKind::InvalidData, format!("column {column}: `{cell}` is not {what}"));
        if cell.is_empty() {
            self.defined.push(0);
            self.nulls += 1;
            return Ok(());
        }
        match self.kind {
            CellKind::Number => {
                let v: f64 = cell.parse().map_err(|_| bad("a number"))?;
                self.plain.extend_from_slice(&v.to_le_bytes());
                if !v.is_nan() {
                    let (lo, hi) = self.range.get_or_insert((v, v));
                    (*lo, *hi) = (lo.min(v), hi.max(v));
                }
            }
            // An unsigned count is stored in INT64's bits, as Parquet's UINT_64 logical type says.
            CellKind::Count => {
                let v: u64 = cell.parse().map_err(|_| bad("a count"))?;
                self.plain.extend_from_slice(&v.to_le_bytes());
                let (lo, hi) = self.count_range.get_or_insert((v, v));
                (*lo, *hi) = ((*lo).min(v), (*hi).max(v));
            }
            CellKind::Text => {
                let len = u32::try_from(cell.len()).map_err(|_| bad("a text under 4 GiB"))?;
                self.plain.extend_from_slice(&len.to_le_bytes());
                self.plain.extend_from_slice(cell.as_bytes());
            }
        }
        self.defined.push(1);
        Ok(())
    }

    /// The rows' largest and smallest values PLAIN-encoded (`Statistics.max_value`, `min_value`): None for
    /// texts and where every value is null or NaN; a zero minimum is written as -0 and a zero maximum as +0,
    /// as the format asks of floating-point extremes.
    fn extremes(&self) -> Option<([u8; 8], [u8; 8])> {
        match (self.range, self.count_range) {
            (Some((lo, hi)), _) => {
                let lo = if lo == 0.0 { -0.0f64 } else { lo };
                let hi = if hi == 0.0 { 0.0f64 } else { hi };
                Some((hi.to_le_bytes(), lo.to_le_bytes()))
            }
            (None, Some((lo, hi))) => Some((hi.to_le_bytes(), lo.to_le_bytes())),
            (None, None) => None,
        }
    }

    /// Empties the column for the next row group.
    fn clear(&mut self) {
        self.plain.clear();
        self.defined.clear();
        (self.nulls, self.range, self.count_range) = (0, None, None);
    }
}

/// The definition levels (each 0 or 1) in the run-length/bit-packing hybrid encoding, as runs only: per run
/// its length shifted left by one (the low bit 0 says a run) as a varint, then its value in one byte.
fn run_length_levels(levels: &[u8], out: &mut Vec<u8>) {
    let mut k = 0;
    while k < levels.len() {
        let value = levels[k];
        let run = levels[k..].iter().take_while(|l| **l == value).count();
        let mut header = (run as u64) << 1;
        while header >= 0x80 {
            out.push((header as u8) | 0x80);
            header >>= 7;
        }
        out.push(header as u8);
        out.push(value);
        k += run;
    }
}

/// Where one column chunk lies and what it holds, for the footer.
struct ChunkMeta {
    offset: u64,
    values: u64,
    uncompressed: u64,
    compressed: u64,
    nulls: u64,
    extremes: Option<([u8; 8], [u8; 8])>,
}

/// A row group written, for the footer.
struct GroupMeta {
    rows: u64,
    chunks: Vec<ChunkMeta>,
}

/// A Parquet file being written from a study's CSV text (`Write`): the header line, then rows.
pub struct ParquetTable<W: Write + Send> {
    out: W,
    /// Bytes written to `out`.
    written: u64,
    columns: Vec<Column>,
    header: String,
    builders: Vec<Builder>,
    groups: Vec<GroupMeta>,
    /// A page's uncompressed body and its compressed bytes, kept from page to page.
    page: Vec<u8>,
    compressed: Vec<u8>,
    compressor: zstd::bulk::Compressor<'static>,
    /// Bytes received that do not yet end a record.
    pending: Vec<u8>,
    /// How far `pending` has been scanned for a record's end, and whether that point is inside quotes.
    scanned: usize,
    in_quotes: bool,
    header_seen: bool,
    rows: usize,
}

fn too_large(what: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, format!("a Parquet page over 2 GiB ({what})"))
}

impl<W: Write + Send> ParquetTable<W> {
    /// A table with these columns, written to `out`.
    pub fn new(mut out: W, columns: &[Column]) -> io::Result<Self> {
        out.write_all(MAGIC)?;
        Ok(ParquetTable {
            out,
            written: MAGIC.len() as u64,
            columns: columns.to_vec(),
            header: header_line(columns).trim_end().to_string(),
            builders: columns.iter().map(|c| Builder::new(c.kind)).collect(),
            groups: Vec::new(),
            page: Vec::new(),
            compressed: Vec::new(),
            compressor: zstd::bulk::Compressor::new(ZSTD_LEVEL)?,
            pending: Vec::new(),
            scanned: 0,
            in_quotes: false,
            header_seen: false,
            rows: 0,
        })
    }

    fn emit(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.out.write_all(bytes)?;
        self.written += bytes.len() as u64;
        Ok(())
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
        for ((builder, cell), column) in self.builders.iter_mut().zip(&cells).zip(&self.columns) {
            builder.push(cell, &column.name)?;
        }
        self.rows += 1;
        if self.rows == ROWS_PER_GROUP {
            self.flush_rows()?;
        }
        Ok(())
    }

    /// Writes the rows gathered as one row group: per column one data page, its header then its body
    /// (the levels' byte length, the levels, the values) compressed.
    fn flush_rows(&mut self) -> io::Result<()> {
        if self.rows == 0 {
            return Ok(());
        }
        let mut chunks = Vec::with_capacity(self.builders.len());
        for k in 0..self.builders.len() {
            let b = &self.builders[k];
            self.page.clear();
            self.page.extend_from_slice(&[0; 4]);
            run_length_levels(&b.defined, &mut self.page);
            let levels = u32::try_from(self.page.len() - 4).map_err(|_| too_large("its levels"))?;
            self.page[..4].copy_from_slice(&levels.to_le_bytes());
            self.page.extend_from_slice(&b.plain);
            self.compressed.clear();
            self.compressed.reserve(zstd::zstd_safe::compress_bound(self.page.len()));
            self.compressor.compress_to_buffer(&self.page, &mut self.compressed)?;
            let size = |n: usize| i32::try_from(n).map_err(|_| too_large(&self.columns[k].name));
            let mut header = thrift::Writer::default();
            header.begin();
            header.i32(1, code::DATA_PAGE);
            header.i32(2, size(self.page.len())?);
            header.i32(3, size(self.compressed.len())?);
            header.field_struct(5);
            header.i32(1, size(b.defined.len())?);
            header.i32(2, code::PLAIN);
            header.i32(3, code::RLE);
            header.i32(4, code::RLE);
            header.end();
            header.end();
            let (values, nulls, extremes) = (b.defined.len() as u64, b.nulls, b.extremes());
            let offset = self.written;
            self.emit(&header.bytes)?;
            let compressed = std::mem::take(&mut self.compressed);
            let emitted = self.emit(&compressed);
            self.compressed = compressed;
            emitted?;
            chunks.push(ChunkMeta {
                offset,
                values,
                uncompressed: (header.bytes.len() + self.page.len()) as u64,
                compressed: self.written - offset,
                nulls,
                extremes,
            });
            self.builders[k].clear();
        }
        self.groups.push(GroupMeta { rows: self.rows as u64, chunks });
        self.rows = 0;
        Ok(())
    }

    /// The footer: `FileMetaData` (version 1, the schema, the row groups, the Arrow schema under its key,
    /// who wrote it, each column's sort order as its type's).
    fn footer(&self) -> Vec<u8> {
        let mut w = thrift::Writer::default();
        w.begin();
        w.i32(1, 1);
        w.list(2, thrift::STRUCT, self.columns.len() + 1);
        w.begin();
        w.binary(4, b"arrow_schema");
        w.i32(5, self.columns.len() as i32);
        w.end();
        for c in &self.columns {
            w.begin();
            w.i32(1, physical_type(c.kind));
            w.i32(3, code::OPTIONAL);
            w.binary(4, c.name.as_bytes());
            match c.kind {
                CellKind::Number => {}
                CellKind::Count => {
                    w.i32(6, code::UINT_64);
                    // LogicalType INTEGER (10): IntType { bitWidth 64, isSigned false }.
                    w.field_struct(10);
                    w.field_struct(10);
                    w.byte(1, 64);
                    w.bool(2, false);
                    w.end();
                    w.end();
                }
                CellKind::Text => {
                    w.i32(6, code::UTF8);
                    // LogicalType STRING (1): StringType {}.
                    w.field_struct(10);
                    w.field_struct(1);
                    w.end();
                    w.end();
                }
            }
            w.end();
        }
        w.i64(3, self.groups.iter().map(|g| g.rows as i64).sum());
        w.list(4, thrift::STRUCT, self.groups.len());
        for (ordinal, g) in self.groups.iter().enumerate() {
            w.begin();
            w.list(1, thrift::STRUCT, g.chunks.len());
            for (chunk, c) in g.chunks.iter().zip(&self.columns) {
                w.begin();
                w.i64(2, 0);
                w.field_struct(3);
                w.i32(1, physical_type(c.kind));
                w.list(2, thrift::I32, 2);
                w.element_i32(code::PLAIN);
                w.element_i32(code::RLE);
                w.list(3, thrift::BINARY, 1);
                w.element_binary(c.name.as_bytes());
                w.i32(4, code::ZSTD);
                w.i64(5, chunk.values as i64);
                w.i64(6, chunk.uncompressed as i64);
                w.i64(7, chunk.compressed as i64);
                w.i64(9, chunk.offset as i64);
                w.field_struct(12);
                w.i64(3, chunk.nulls as i64);
                if let Some((max, min)) = chunk.extremes {
                    w.binary(5, &max);
                    w.binary(6, &min);
                }
                w.end();
                w.end();
                w.end();
            }
            w.i64(2, g.chunks.iter().map(|c| c.uncompressed as i64).sum());
            w.i64(3, g.rows as i64);
            w.i64(5, g.chunks.first().map_or(0, |c| c.offset as i64));
            w.i64(6, g.chunks.iter().map(|c| c.compressed as i64).sum());
            w.i32(7, ordinal as i32);
            w.end();
        }
        // The Arrow schema rides along as Arrow's own writers store it, so pyarrow, pandas and polars read
        // each column's unit as its field metadata.
        w.list(5, thrift::STRUCT, 1);
        w.begin();
        w.binary(1, arrow_schema::KEY.as_bytes());
        w.binary(2, arrow_schema::encode(&self.columns).as_bytes());
        w.end();
        w.binary(6, format!("stiff version {}", env!("CARGO_PKG_VERSION")).as_bytes());
        // ColumnOrder TYPE_ORDER (1) for every column: its extremes are ordered as its type (and logical
        // type) say, unsigned for a count.
        w.list(7, thrift::STRUCT, self.columns.len());
        for _ in &self.columns {
            w.begin();
            w.field_struct(1);
            w.end();
            w.end();
        }
        w.end();
        w.bytes
    }

    /// Writes the last rows and the file's footer; hands back the output.
    pub fn finish(mut self) -> io::Result<W> {
        if !self.pending.is_empty() {
            return Err(io::Error::new(io::ErrorKind::InvalidData, "the table ends inside a row"));
        }
        self.flush_rows()?;
        let footer = self.footer();
        let length = u32::try_from(footer.len()).map_err(|_| too_large("the footer"))?;
        self.emit(&footer)?;
        self.emit(&length.to_le_bytes())?;
        self.emit(MAGIC)?;
        Ok(self.out)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Quoted cells (a point named `a,"b"`) split as the CSV writer quoted them.
    #[test]
    fn records_split_as_they_were_quoted() {
        assert_eq!(split_record(r#"1,"a,""b""",,x"#), vec!["1", r#"a,"b""#, "", "x"]);
    }
}

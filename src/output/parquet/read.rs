//! A Parquet table's columns read back (`stiff plot map.parquet`): the footer parsed, then only the column
//! chunks a picture needs read and decoded. Beside what stiff writes it reads the common forms other writers
//! use for flat tables (pyarrow, polars, arrow-rs): data pages of version 1 and 2, PLAIN values or a
//! dictionary (PLAIN_DICTIONARY, RLE_DICTIONARY), levels in the run-length/bit-packing hybrid, zstd or no
//! compression; DOUBLE, FLOAT, INT64 and INT32 read as numbers, BYTE_ARRAY as text. Anything else is refused
//! with what it is. Every length and count is checked against the bytes there are: a damaged file gives an
//! error, never a panic or an allocation its size does not hold.

use std::io::{self, Read, Seek, SeekFrom};

use super::thrift::{self, Reader};
use super::MAGIC;

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

fn invalid(what: impl std::fmt::Display) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, format!("not a Parquet table stiff reads: {what}"))
}

/// Physical types (`parquet.thrift`'s `Type`).
const INT32: i32 = 1;
const INT64: i32 = 2;
const FLOAT: i32 = 4;
const DOUBLE: i32 = 5;
const BYTE_ARRAY: i32 = 6;
/// Encodings.
const PLAIN: i32 = 0;
const PLAIN_DICTIONARY: i32 = 2;
const RLE_DICTIONARY: i32 = 8;
/// Page types.
const DATA_PAGE: i32 = 0;
const DICTIONARY_PAGE: i32 = 2;
const DATA_PAGE_V2: i32 = 3;
/// Compression codecs.
const UNCOMPRESSED: i32 = 0;
const ZSTD: i32 = 6;

/// A leaf of the flat schema.
struct Leaf {
    name: String,
    physical: i32,
    /// OPTIONAL (definition levels 0 or 1) rather than REQUIRED.
    optional: bool,
    /// An INT64 or INT32 holding an unsigned integer (`UINT_64`, `UINT_32`; a count as stiff writes it).
    unsigned: bool,
}

/// Where a column chunk's pages lie.
struct Chunk {
    physical: i32,
    codec: i32,
    values: u64,
    start: u64,
    length: u64,
}

struct Footer {
    leaves: Vec<Leaf>,
    rows: u64,
    /// Per row group: its rows and its column chunks (one per leaf).
    groups: Vec<(u64, Vec<Chunk>)>,
}

/// The column names of a Parquet table, then the columns `numbers` and `texts` choose among them, read
/// alone (a projection: a picture of a million-point map reads 4 columns, not 40).
pub fn read_columns(
    mut file: std::fs::File,
    numbers: &dyn Fn(&[String], &str) -> bool,
    texts: &dyn Fn(&[String], &str) -> bool,
) -> io::Result<ColumnsRead> {
    let size = file.seek(SeekFrom::End(0))?;
    let footer = read_footer(&mut file, size)?;
    let header: Vec<String> = footer.leaves.iter().map(|l| l.name.clone()).collect();
    let rows = usize::try_from(footer.rows).map_err(|_| invalid("more rows than memory holds"))?;
    let mut number_columns: Vec<(usize, String, Vec<f64>)> = Vec::new();
    let mut text_columns: Vec<(usize, String, Vec<String>)> = Vec::new();
    for (k, name) in header.iter().enumerate() {
        if numbers(&header, name) {
            number_columns.push((k, name.clone(), Vec::new()));
        } else if texts(&header, name) {
            text_columns.push((k, name.clone(), Vec::new()));
        }
    }
    let mut buffer = Vec::new();
    for (group_rows, chunks) in &footer.groups {
        for (k, name, out) in &mut number_columns {
            let chunk = &chunks[*k];
            if !matches!(chunk.physical, DOUBLE | FLOAT | INT64 | INT32) {
                return Err(invalid(format!("column {name} is not numeric")));
            }
            read_chunk(&mut file, size, chunk, &footer.leaves[*k], *group_rows, &mut buffer, &mut |v| {
                out.push(match v {
                    Some(Value::Number(x)) => x,
                    _ => f64::NAN,
                });
            })?;
        }
        for (k, name, out) in &mut text_columns {
            let chunk = &chunks[*k];
            if chunk.physical != BYTE_ARRAY {
                return Err(invalid(format!("column {name} is not text")));
            }
            read_chunk(&mut file, size, chunk, &footer.leaves[*k], *group_rows, &mut buffer, &mut |v| {
                out.push(match v {
                    Some(Value::Text(t)) => String::from_utf8_lossy(t).into_owned(),
                    _ => String::new(),
                });
            })?;
        }
    }
    Ok(ColumnsRead {
        header,
        rows,
        numbers: number_columns.into_iter().map(|(_, n, v)| (n, v)).collect(),
        texts: text_columns.into_iter().map(|(_, n, v)| (n, v)).collect(),
    })
}

/// The footer: the last eight bytes (its length, "PAR1"), then `FileMetaData`.
fn read_footer(file: &mut std::fs::File, size: u64) -> io::Result<Footer> {
    if size < 12 {
        return Err(invalid("shorter than a Parquet file's header and footer"));
    }
    let mut tail = [0u8; 8];
    file.seek(SeekFrom::Start(size - 8))?;
    file.read_exact(&mut tail)?;
    if &tail[4..] != MAGIC {
        return Err(invalid("it does not end in PAR1 (an encrypted footer, or not Parquet)"));
    }
    let length = u64::from(u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]));
    if length > size - 12 {
        return Err(invalid("its footer's length runs past the file's start"));
    }
    let mut bytes = vec![0u8; length as usize];
    file.seek(SeekFrom::Start(size - 8 - length))?;
    file.read_exact(&mut bytes)?;
    parse_file_metadata(&bytes)
}

/// `FileMetaData`: the schema (2), the rows (3) and the row groups (4); a flat schema of primitive leaves.
fn parse_file_metadata(bytes: &[u8]) -> io::Result<Footer> {
    let mut r = Reader::new(bytes);
    r.begin()?;
    let (mut elements, mut rows, mut groups) = (Vec::new(), None, Vec::new());
    while let Some((id, t)) = r.field()? {
        match id {
            2 => {
                let (kind, len) = r.list(t)?;
                for _ in 0..len {
                    expect_struct(kind)?;
                    elements.push(parse_schema_element(&mut r)?);
                }
            }
            3 => rows = Some(r.int(t)?),
            4 => {
                let (kind, len) = r.list(t)?;
                for _ in 0..len {
                    expect_struct(kind)?;
                    groups.push(parse_row_group(&mut r)?);
                }
            }
            _ => r.skip(t)?,
        }
    }
    // The root, then its children: a flat table's leaves each have a type and no children.
    let Some((root, leaves)) = elements.split_first() else {
        return Err(invalid("no schema"));
    };
    if root.children != Some(leaves.len() as i64) || leaves.iter().any(|e| e.children.is_some() || e.physical.is_none())
    {
        return Err(invalid("nested columns (stiff reads flat tables)"));
    }
    let leaves = leaves
        .iter()
        .map(|e| match e.repetition {
            0 | 1 => Ok(Leaf {
                name: e.name.clone(),
                physical: e.physical.unwrap_or(-1),
                optional: e.repetition == 1,
                unsigned: e.unsigned,
            }),
            _ => Err(invalid(format!("column {} is repeated (stiff reads flat tables)", e.name))),
        })
        .collect::<io::Result<Vec<_>>>()?;
    let rows = u64::try_from(rows.ok_or_else(|| invalid("no row count"))?).map_err(|_| invalid("negative rows"))?;
    if groups.iter().any(|(_, chunks)| chunks.len() != leaves.len()) {
        return Err(invalid("a row group's columns are not the schema's"));
    }
    if groups.iter().map(|(n, _)| *n).sum::<u64>() != rows {
        return Err(invalid("its row groups' rows do not add up to its rows"));
    }
    for (_, chunks) in &groups {
        for (chunk, leaf) in chunks.iter().zip(&leaves) {
            if chunk.physical != leaf.physical {
                return Err(invalid(format!("column {}'s chunk is of another type than its schema", leaf.name)));
            }
        }
    }
    Ok(Footer { leaves, rows, groups })
}

fn expect_struct(kind: u8) -> io::Result<()> {
    if kind == thrift::STRUCT {
        Ok(())
    } else {
        Err(invalid("a list of structs holds another type"))
    }
}

struct SchemaElement {
    name: String,
    physical: Option<i32>,
    repetition: i32,
    children: Option<i64>,
    unsigned: bool,
}

fn parse_schema_element(r: &mut Reader) -> io::Result<SchemaElement> {
    r.begin()?;
    let mut e = SchemaElement { name: String::new(), physical: None, repetition: 0, children: None, unsigned: false };
    while let Some((id, t)) = r.field()? {
        match id {
            1 => e.physical = Some(r.i32(t)?),
            3 => e.repetition = r.i32(t)?,
            4 => e.name = String::from_utf8_lossy(r.binary(t)?).into_owned(),
            5 => e.children = Some(r.int(t)?),
            // ConvertedType UINT_32 (13) or UINT_64 (14).
            6 => e.unsigned |= matches!(r.i32(t)?, 13 | 14),
            // LogicalType INTEGER (10): IntType's isSigned (2).
            10 if t.0 == thrift::STRUCT => {
                r.begin()?;
                while let Some((member, t)) = r.field()? {
                    if member == 10 && t.0 == thrift::STRUCT {
                        r.begin()?;
                        while let Some((field, t)) = r.field()? {
                            match field {
                                2 => e.unsigned = !r.bool(t)?,
                                _ => r.skip(t)?,
                            }
                        }
                    } else {
                        r.skip(t)?;
                    }
                }
            }
            _ => r.skip(t)?,
        }
    }
    Ok(e)
}

/// `RowGroup`: its column chunks (1) and rows (3).
fn parse_row_group(r: &mut Reader) -> io::Result<(u64, Vec<Chunk>)> {
    r.begin()?;
    let (mut chunks, mut rows) = (Vec::new(), None);
    while let Some((id, t)) = r.field()? {
        match id {
            1 => {
                let (kind, len) = r.list(t)?;
                for _ in 0..len {
                    expect_struct(kind)?;
                    chunks.push(parse_column_chunk(r)?);
                }
            }
            3 => rows = Some(r.int(t)?),
            _ => r.skip(t)?,
        }
    }
    let rows = u64::try_from(rows.ok_or_else(|| invalid("a row group without rows"))?)
        .map_err(|_| invalid("a row group of negative rows"))?;
    Ok((rows, chunks))
}

/// `ColumnChunk` (its `file_path` refused: another file's columns) and its `ColumnMetaData` (3).
fn parse_column_chunk(r: &mut Reader) -> io::Result<Chunk> {
    r.begin()?;
    let mut chunk = None;
    while let Some((id, t)) = r.field()? {
        match id {
            1 => return Err(invalid("its columns are in other files")),
            3 if t.0 == thrift::STRUCT => chunk = Some(parse_column_metadata(r)?),
            _ => r.skip(t)?,
        }
    }
    chunk.ok_or_else(|| invalid("a column chunk without metadata"))
}

fn parse_column_metadata(r: &mut Reader) -> io::Result<Chunk> {
    r.begin()?;
    let (mut physical, mut codec, mut values, mut length) = (None, None, None, None);
    let (mut data, mut dictionary) = (None, None);
    while let Some((id, t)) = r.field()? {
        match id {
            1 => physical = Some(r.i32(t)?),
            4 => codec = Some(r.i32(t)?),
            5 => values = Some(r.int(t)?),
            7 => length = Some(r.int(t)?),
            9 => data = Some(r.int(t)?),
            11 => dictionary = Some(r.int(t)?),
            _ => r.skip(t)?,
        }
    }
    let missing = || invalid("a column chunk's metadata lacks a required field");
    let non_negative = |v: Option<i64>| v.ok_or_else(missing).and_then(|v| u64::try_from(v).map_err(|_| missing()));
    let data = non_negative(data)?;
    // The chunk starts at its dictionary page where it has one (some writers put 0 there for none).
    let start = match dictionary.map(u64::try_from) {
        Some(Ok(d)) if d > 0 && d < data => d,
        _ => data,
    };
    Ok(Chunk {
        physical: physical.ok_or_else(missing)?,
        codec: codec.ok_or_else(missing)?,
        values: non_negative(values)?,
        start,
        length: non_negative(length)?,
    })
}

/// One decoded cell.
enum Value<'a> {
    Number(f64),
    Text(&'a [u8]),
}

/// A dictionary's entry, kept while its pages are read.
enum Owned {
    Number(f64),
    Text(Vec<u8>),
}

/// A page's header: its type, its sizes, and what its data page header (v1 or v2) or dictionary page
/// header says.
#[derive(Default)]
struct PageHeader {
    kind: i32,
    uncompressed: usize,
    compressed: usize,
    values: usize,
    encoding: i32,
    /// Version 2: the levels' byte lengths (stored uncompressed before the values), and whether the values
    /// are compressed.
    v2_levels: Option<(usize, usize)>,
    v2_compressed: bool,
}

fn parse_page_header(r: &mut Reader) -> io::Result<PageHeader> {
    r.begin()?;
    let mut h = PageHeader { kind: -1, v2_compressed: true, ..PageHeader::default() };
    let size = |v: i32| usize::try_from(v).map_err(|_| invalid("a negative size in a page header"));
    while let Some((id, t)) = r.field()? {
        match id {
            1 => h.kind = r.i32(t)?,
            2 => h.uncompressed = size(r.i32(t)?)?,
            3 => h.compressed = size(r.i32(t)?)?,
            5 | 7 | 8 if t.0 == thrift::STRUCT => {
                r.begin()?;
                let (mut definition, mut repetition) = (0, 0);
                while let Some((field, t)) = r.field()? {
                    match (id, field) {
                        (_, 1) => h.values = size(r.i32(t)?)?,
                        (5 | 7, 2) | (8, 4) => h.encoding = r.i32(t)?,
                        (8, 5) => definition = size(r.i32(t)?)?,
                        (8, 6) => repetition = size(r.i32(t)?)?,
                        (8, 7) => h.v2_compressed = r.bool(t)?,
                        _ => r.skip(t)?,
                    }
                }
                if id == 8 {
                    h.v2_levels = Some((repetition, definition));
                }
            }
            _ => r.skip(t)?,
        }
    }
    Ok(h)
}

/// Reads one column chunk of `rows` rows, handing each row's cell (None for a null) to `emit`.
fn read_chunk(
    file: &mut std::fs::File,
    size: u64,
    chunk: &Chunk,
    leaf: &Leaf,
    rows: u64,
    buffer: &mut Vec<u8>,
    emit: &mut dyn FnMut(Option<Value>),
) -> io::Result<()> {
    if chunk.codec != UNCOMPRESSED && chunk.codec != ZSTD {
        let name = ["uncompressed", "snappy", "gzip", "lzo", "brotli", "lz4", "zstd", "lz4_raw"];
        let codec = usize::try_from(chunk.codec).ok().and_then(|c| name.get(c)).copied().unwrap_or("an unknown codec");
        return Err(invalid(format!(
            "column {} is compressed by {codec} (stiff reads zstd or uncompressed Parquet; rewrite it with \
             compression='zstd', or plot the CSV)",
            leaf.name
        )));
    }
    if chunk.values != rows {
        return Err(invalid(format!("column {} holds {} values in {rows} rows", leaf.name, chunk.values)));
    }
    let end = chunk.start.checked_add(chunk.length).filter(|e| *e <= size);
    if end.is_none() || chunk.start < MAGIC.len() as u64 {
        return Err(invalid(format!("column {}'s pages lie outside the file", leaf.name)));
    }
    buffer.clear();
    file.seek(SeekFrom::Start(chunk.start))?;
    file.by_ref().take(chunk.length).read_to_end(buffer)?;
    let bytes = &buffer[..];
    let mut at = 0;
    let mut dictionary: Vec<Owned> = Vec::new();
    let mut dictionary_bytes = Vec::new();
    let mut done = 0u64;
    let mut page = Vec::new();
    while done < rows {
        let mut r = Reader::new(&bytes[at..]);
        let h = parse_page_header(&mut r)?;
        let body_start = at + r.at;
        let body = bytes
            .get(body_start..body_start.saturating_add(h.compressed))
            .ok_or_else(|| invalid(format!("column {}'s page runs past its chunk", leaf.name)))?;
        at = body_start + h.compressed;
        match h.kind {
            DICTIONARY_PAGE => {
                if h.encoding != PLAIN && h.encoding != PLAIN_DICTIONARY {
                    return Err(invalid(format!("column {}'s dictionary is not PLAIN", leaf.name)));
                }
                decompress(chunk.codec, body, h.uncompressed, &mut dictionary_bytes)?;
                let values = plain_values(&dictionary_bytes, leaf, h.values)?;
                dictionary = values
                    .into_iter()
                    .map(|v| match v {
                        Value::Number(x) => Owned::Number(x),
                        Value::Text(t) => Owned::Text(t.to_vec()),
                    })
                    .collect();
            }
            DATA_PAGE | DATA_PAGE_V2 => {
                let left = rows - done;
                if h.values as u64 > left {
                    return Err(invalid(format!("column {} has more values than rows", leaf.name)));
                }
                // The definition levels, and the values' bytes after them.
                let (levels, values): (Vec<u8>, &[u8]) = if let Some((repetition, definition)) = h.v2_levels {
                    if repetition != 0 {
                        return Err(invalid(format!("column {} is repeated", leaf.name)));
                    }
                    let levels = body.get(..definition).ok_or_else(|| invalid("levels past their page"))?;
                    let levels = decode_levels(levels, leaf.optional, h.values)?;
                    let rest = &body[definition..];
                    if h.v2_compressed {
                        let expected = h.uncompressed.checked_sub(definition).ok_or_else(|| invalid("a page size"))?;
                        decompress(chunk.codec, rest, expected, &mut page)?;
                    } else {
                        page.clear();
                        page.extend_from_slice(rest);
                    }
                    (levels, &page[..])
                } else {
                    decompress(chunk.codec, body, h.uncompressed, &mut page)?;
                    if leaf.optional {
                        let length = page.get(..4).ok_or_else(|| invalid("levels past their page"))?;
                        let length = u32::from_le_bytes([length[0], length[1], length[2], length[3]]) as usize;
                        let levels = page
                            .get(4..4usize.saturating_add(length))
                            .ok_or_else(|| invalid("levels past their page"))?;
                        (decode_levels(levels, true, h.values)?, &page[4 + length..])
                    } else {
                        (vec![1; h.values], &page[..])
                    }
                };
                let defined = levels.iter().filter(|l| **l == 1).count();
                let cells: Vec<Value> = match h.encoding {
                    PLAIN => plain_values(values, leaf, defined)?,
                    PLAIN_DICTIONARY | RLE_DICTIONARY => {
                        let (&width, indices) = values.split_first().ok_or_else(|| invalid("an empty page"))?;
                        let indices = hybrid(indices, u32::from(width), defined)?;
                        indices
                            .iter()
                            .map(|i| match dictionary.get(*i as usize) {
                                Some(Owned::Number(x)) => Ok(Value::Number(*x)),
                                Some(Owned::Text(t)) => Ok(Value::Text(t)),
                                None => Err(invalid(format!("column {}: an index past its dictionary", leaf.name))),
                            })
                            .collect::<io::Result<_>>()?
                    }
                    e => {
                        return Err(invalid(format!(
                            "column {}'s encoding {e} (stiff reads PLAIN or a dictionary)",
                            leaf.name
                        )))
                    }
                };
                let mut cells = cells.into_iter();
                for level in levels {
                    emit(if level == 1 { cells.next() } else { None });
                }
                done += h.values as u64;
                if h.values == 0 && at >= bytes.len() {
                    return Err(invalid(format!("column {} ends early", leaf.name)));
                }
            }
            _ => {}
        }
        if at >= bytes.len() && done < rows {
            return Err(invalid(format!("column {} ends early", leaf.name)));
        }
    }
    Ok(())
}

/// A page's body decompressed into `out`, checked to be `size` bytes (read no further than that, so that a
/// forged size never allocates more than the data make).
fn decompress(codec: i32, body: &[u8], size: usize, out: &mut Vec<u8>) -> io::Result<()> {
    out.clear();
    if codec == UNCOMPRESSED {
        out.extend_from_slice(body);
    } else {
        let decoder = zstd::stream::read::Decoder::with_buffer(body).map_err(|e| invalid(format!("zstd: {e}")))?;
        decoder.take(size as u64).read_to_end(out).map_err(|e| invalid(format!("zstd: {e}")))?;
    }
    if out.len() != size {
        return Err(invalid("a page's size is not its header's"));
    }
    Ok(())
}

/// `count` definition levels of a flat column (each 0 or 1): bit width 1 where the column is optional.
fn decode_levels(bytes: &[u8], optional: bool, count: usize) -> io::Result<Vec<u8>> {
    if !optional {
        return Ok(vec![1; count]);
    }
    let levels = hybrid(bytes, 1, count)?;
    if levels.iter().any(|l| *l > 1) {
        return Err(invalid("a definition level above one"));
    }
    Ok(levels.into_iter().map(|l| l as u8).collect())
}

/// `count` values of `width` bits in the run-length/bit-packing hybrid: each run's varint header, its low
/// bit 0 for a repeated value (count = header >> 1, the value in ceil(width / 8) bytes), 1 for bit-packed
/// groups of eight values (groups = header >> 1, least significant bit first).
fn hybrid(bytes: &[u8], width: u32, count: usize) -> io::Result<Vec<u32>> {
    if width > 32 {
        return Err(invalid("a bit width above 32"));
    }
    let mut out = Vec::with_capacity(count.min(bytes.len().saturating_mul(8)));
    let mut at = 0;
    let byte = |at: usize| bytes.get(at).copied().ok_or_else(|| invalid("levels or indices end early"));
    while out.len() < count {
        let mut header = 0u64;
        for shift in (0..).step_by(7) {
            if shift > 56 {
                return Err(invalid("a run header too long"));
            }
            let b = byte(at)?;
            at += 1;
            header |= u64::from(b & 0x7F) << shift;
            if b & 0x80 == 0 {
                break;
            }
        }
        let left = count - out.len();
        if header & 1 == 0 {
            let run = usize::try_from(header >> 1).unwrap_or(usize::MAX).min(left);
            let mut value = 0u32;
            for k in 0..width.div_ceil(8) as usize {
                value |= u32::from(byte(at + k)?) << (8 * k);
            }
            at += width.div_ceil(8) as usize;
            if run == 0 {
                return Err(invalid("an empty run"));
            }
            out.extend(std::iter::repeat_n(value, run));
        } else {
            let groups = usize::try_from(header >> 1).unwrap_or(usize::MAX);
            let values = groups.saturating_mul(8);
            let width = width as usize;
            let needed = groups.saturating_mul(width);
            if needed > bytes.len() - at || groups == 0 {
                return Err(invalid("bit-packed values past their page"));
            }
            for v in 0..values.min(left) {
                let mut value = 0u32;
                for bit in 0..width {
                    let position = v * width + bit;
                    let b = bytes[at + position / 8];
                    value |= u32::from((b >> (position % 8)) & 1) << bit;
                }
                out.push(value);
            }
            at += needed;
        }
    }
    Ok(out)
}

/// `count` PLAIN values of a column's physical type.
fn plain_values<'a>(bytes: &'a [u8], leaf: &Leaf, count: usize) -> io::Result<Vec<Value<'a>>> {
    let unsigned = leaf.unsigned;
    let fixed = |width: usize| {
        if bytes.len() / width < count {
            return Err(invalid("values past their page"));
        }
        Ok(bytes.chunks_exact(width).take(count))
    };
    Ok(match leaf.physical {
        DOUBLE => fixed(8)?.map(|c| Value::Number(f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))).collect(),
        FLOAT => {
            fixed(4)?.map(|c| Value::Number(f64::from(f32::from_le_bytes(c.try_into().unwrap_or([0; 4]))))).collect()
        }
        // A count is an unsigned 64-bit integer in INT64's bits (as stiff writes it).
        INT64 => fixed(8)?
            .map(|c| {
                let bits = c.try_into().unwrap_or([0; 8]);
                Value::Number(if unsigned { u64::from_le_bytes(bits) as f64 } else { i64::from_le_bytes(bits) as f64 })
            })
            .collect(),
        INT32 => fixed(4)?
            .map(|c| {
                let bits = c.try_into().unwrap_or([0; 4]);
                Value::Number(if unsigned {
                    f64::from(u32::from_le_bytes(bits))
                } else {
                    f64::from(i32::from_le_bytes(bits))
                })
            })
            .collect(),
        BYTE_ARRAY => {
            let mut values = Vec::with_capacity(count.min(bytes.len() / 4));
            let mut at = 0;
            for _ in 0..count {
                let length = bytes.get(at..at + 4).ok_or_else(|| invalid("texts past their page"))?;
                let length = u32::from_le_bytes([length[0], length[1], length[2], length[3]]) as usize;
                let text = bytes
                    .get(at + 4..(at + 4).saturating_add(length))
                    .ok_or_else(|| invalid("texts past their page"))?;
                values.push(Value::Text(text));
                at += 4 + length;
            }
            values
        }
        t => return Err(invalid(format!("physical type {t}"))),
    })
}

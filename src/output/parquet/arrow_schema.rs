//! A table's Arrow schema in the form Arrow's Parquet writers store it (the `ARROW:schema` key of the
//! file's metadata): base64 of an Arrow IPC message (the continuation marker, the flatbuffer's length, the
//! flatbuffer) holding a `Schema` of nullable fields, each with its type (`Float64`, `UInt64`, `Utf8`) and its
//! unit as field metadata. Readers built on Arrow (pyarrow, pandas, polars, arrow-rs) take the column types
//! and the units from it.
//!
//! The flatbuffer is laid out front to back: every table is followed by what it refers to, so each offset
//! (unsigned, counted from where it is stored) points forward, and each vtable sits just before its table.
//! Field numbers and enumeration values are those of Arrow's `Schema.fbs` and `Message.fbs` (format V5).

use super::super::table::{unit_of, CellKind, Column};

/// The metadata key under which Arrow's Parquet writers keep the schema.
pub const KEY: &str = "ARROW:schema";

/// `MetadataVersion.V5`.
const METADATA_V5: i16 = 4;
/// `MessageHeader.Schema`.
const HEADER_SCHEMA: u8 = 1;
/// `Type` union members.
const TYPE_INT: u8 = 2;
const TYPE_FLOATING_POINT: u8 = 3;
const TYPE_UTF8: u8 = 5;
/// `Precision.DOUBLE`.
const PRECISION_DOUBLE: i16 = 2;

/// A scalar or a forward reference stored in a table's field.
#[derive(Clone, Copy)]
enum Slot {
    Byte(u8),
    Short(i16),
    Int(i32),
    /// A reference to something written later; patched by `Flatbuffer::point`.
    Reference,
}

impl Slot {
    fn size(self) -> usize {
        match self {
            Slot::Byte(_) => 1,
            Slot::Short(_) => 2,
            Slot::Int(_) | Slot::Reference => 4,
        }
    }
}

#[derive(Default)]
struct Flatbuffer {
    bytes: Vec<u8>,
}

impl Flatbuffer {
    fn pad_to(&mut self, alignment: usize) {
        while !self.bytes.len().is_multiple_of(alignment) {
            self.bytes.push(0);
        }
    }

    fn u16(&mut self, v: u16) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    fn u32(&mut self, v: u32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    /// Makes the reference stored at `at` point to `target` (later in the buffer).
    fn point(&mut self, at: usize, target: usize) {
        self.bytes[at..at + 4].copy_from_slice(&((target - at) as u32).to_le_bytes());
    }

    /// Makes the reference stored at `at` point here (after aligning to 4).
    fn point_here(&mut self, at: usize) {
        self.pad_to(4);
        self.point(at, self.bytes.len());
    }

    /// Writes a table referred to from `at`, with its fields in slot order (`None`: absent), and returns where
    /// each `Reference` slot is stored, in slot order.
    fn table(&mut self, at: usize, slots: &[Option<Slot>]) -> Vec<usize> {
        // The table: its vtable offset, then the fields, largest first, each aligned to its size.
        let mut layout = vec![0usize; slots.len()];
        let mut order: Vec<usize> = (0..slots.len()).filter(|&k| slots[k].is_some()).collect();
        order.sort_by_key(|&k| std::cmp::Reverse(slots[k].map_or(0, Slot::size)));
        let mut size = 4usize;
        for &k in &order {
            let field = slots[k].map_or(0, Slot::size);
            size = size.next_multiple_of(field);
            layout[k] = size;
            size += field;
        }
        // The vtable, just before the table (itself aligned to 4).
        self.pad_to(2);
        let vtable = self.bytes.len();
        self.u16((4 + 2 * slots.len()) as u16);
        self.u16(size as u16);
        for (k, slot) in slots.iter().enumerate() {
            self.u16(if slot.is_some() { layout[k] as u16 } else { 0 });
        }
        self.pad_to(4);
        let table = self.bytes.len();
        self.point(at, table);
        self.bytes.resize(table + size, 0);
        self.bytes[table..table + 4].copy_from_slice(&((table - vtable) as i32).to_le_bytes());
        let mut references = Vec::new();
        for (k, slot) in slots.iter().enumerate() {
            let at = table + layout[k];
            match slot {
                Some(Slot::Byte(v)) => self.bytes[at] = *v,
                Some(Slot::Short(v)) => self.bytes[at..at + 2].copy_from_slice(&v.to_le_bytes()),
                Some(Slot::Int(v)) => self.bytes[at..at + 4].copy_from_slice(&v.to_le_bytes()),
                Some(Slot::Reference) => references.push(at),
                None => {}
            }
        }
        references
    }

    /// A string (length, bytes, a terminating zero), referred to from `at`.
    fn string(&mut self, at: usize, text: &str) {
        self.point_here(at);
        self.u32(text.len() as u32);
        self.bytes.extend_from_slice(text.as_bytes());
        self.bytes.push(0);
    }

    /// A vector of `n` references, referred to from `at`; returns where each element is stored.
    fn references(&mut self, at: usize, n: usize) -> Vec<usize> {
        self.point_here(at);
        self.u32(n as u32);
        let first = self.bytes.len();
        self.bytes.resize(first + 4 * n, 0);
        (0..n).map(|k| first + 4 * k).collect()
    }
}

/// The `ARROW:schema` value of a table with these columns.
pub fn encode(columns: &[Column]) -> String {
    let mut fb = Flatbuffer::default();
    fb.u32(0); // the root: the Message
               // Message: version, header_type, header (the Schema).
    let message =
        fb.table(0, &[Some(Slot::Short(METADATA_V5)), Some(Slot::Byte(HEADER_SCHEMA)), Some(Slot::Reference)]);
    // Schema: endianness (Little, the default, omitted), fields.
    let schema = fb.table(message[0], &[None, Some(Slot::Reference)]);
    let fields = fb.references(schema[0], columns.len());
    for (column, at) in columns.iter().zip(fields) {
        let type_type = match column.kind {
            CellKind::Number => TYPE_FLOATING_POINT,
            CellKind::Count => TYPE_INT,
            CellKind::Text => TYPE_UTF8,
        };
        let unit = unit_of(&column.name);
        // Field: name, nullable, type_type, type, dictionary, children, custom_metadata.
        let field = fb.table(
            at,
            &[
                Some(Slot::Reference),
                Some(Slot::Byte(1)),
                Some(Slot::Byte(type_type)),
                Some(Slot::Reference),
                None,
                Some(Slot::Reference),
                unit.map(|_| Slot::Reference),
            ],
        );
        fb.string(field[0], &column.name);
        let no_references = match column.kind {
            CellKind::Number => fb.table(field[1], &[Some(Slot::Short(PRECISION_DOUBLE))]),
            CellKind::Count => fb.table(field[1], &[Some(Slot::Int(64)), Some(Slot::Byte(0))]),
            CellKind::Text => fb.table(field[1], &[]),
        };
        debug_assert!(no_references.is_empty());
        // Arrow's C++ reader requires the children vector, even empty.
        fb.references(field[2], 0);
        if let Some(unit) = unit {
            let pairs = fb.references(field[3], 1);
            let pair = fb.table(pairs[0], &[Some(Slot::Reference), Some(Slot::Reference)]);
            fb.string(pair[0], super::UNIT_KEY);
            fb.string(pair[1], unit);
        }
    }
    fb.pad_to(8);
    let mut message = Vec::with_capacity(8 + fb.bytes.len());
    message.extend_from_slice(&0xFFFF_FFFFu32.to_le_bytes());
    message.extend_from_slice(&(fb.bytes.len() as u32).to_le_bytes());
    message.extend_from_slice(&fb.bytes);
    base64(&message)
}

/// Standard base64 with padding.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let n = (u32::from(chunk[0]) << 16)
            | (u32::from(*chunk.get(1).unwrap_or(&0)) << 8)
            | u32::from(*chunk.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

//! Thrift's compact protocol, the encoding of a Parquet file's footer and page headers: the part Parquet
//! uses (structs of integers, binaries, lists and nested structs; no maps or sets are written).
//!
//! A field's header is one byte, `(id - previous id) << 4 | type` where the difference is 1..=15, else the
//! type byte followed by the id as a zigzag varint; a boolean field carries its value in its type (1 true,
//! 2 false); integers are zigzag varints; a binary is its varint length and its bytes; a list is one byte
//! `size << 4 | element type` (size below 15) or `0xF0 | type` and the size as a varint; a struct ends with
//! a 0 byte.

use std::io;

/// Compact protocol type codes.
pub const BOOL_TRUE: u8 = 1;
pub const BOOL_FALSE: u8 = 2;
pub const BYTE: u8 = 3;
pub const I16: u8 = 4;
pub const I32: u8 = 5;
pub const I64: u8 = 6;
pub const DOUBLE: u8 = 7;
pub const BINARY: u8 = 8;
pub const LIST: u8 = 9;
pub const SET: u8 = 10;
pub const MAP: u8 = 11;
pub const STRUCT: u8 = 12;

/// A compact-protocol encoder into a byte buffer; `begin` and `end` bracket each struct.
#[derive(Default)]
pub struct Writer {
    pub bytes: Vec<u8>,
    /// The last field id of each open struct.
    last_ids: Vec<i16>,
}

impl Writer {
    fn varint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.bytes.push((v as u8) | 0x80);
            v >>= 7;
        }
        self.bytes.push(v as u8);
    }

    fn zigzag(&mut self, v: i64) {
        self.varint(((v << 1) ^ (v >> 63)) as u64);
    }

    fn field(&mut self, id: i16, kind: u8) {
        let last = self.last_ids.last_mut().expect("a field outside a struct");
        let delta = id - *last;
        *last = id;
        if (1..=15).contains(&delta) {
            self.bytes.push(((delta as u8) << 4) | kind);
        } else {
            self.bytes.push(kind);
            self.zigzag(i64::from(id));
        }
    }

    /// Opens a struct: the top-level one, a list's element, or (after `field_struct`) a field's.
    pub fn begin(&mut self) {
        self.last_ids.push(0);
    }

    /// Closes the innermost struct.
    pub fn end(&mut self) {
        self.bytes.push(0);
        self.last_ids.pop();
    }

    pub fn i32(&mut self, id: i16, v: i32) {
        self.field(id, I32);
        self.zigzag(i64::from(v));
    }

    pub fn i64(&mut self, id: i16, v: i64) {
        self.field(id, I64);
        self.zigzag(v);
    }

    pub fn byte(&mut self, id: i16, v: i8) {
        self.field(id, BYTE);
        self.bytes.push(v as u8);
    }

    pub fn bool(&mut self, id: i16, v: bool) {
        self.field(id, if v { BOOL_TRUE } else { BOOL_FALSE });
    }

    pub fn binary(&mut self, id: i16, v: &[u8]) {
        self.field(id, BINARY);
        self.raw_binary(v);
    }

    fn raw_binary(&mut self, v: &[u8]) {
        self.varint(v.len() as u64);
        self.bytes.extend_from_slice(v);
    }

    /// Opens a struct-valued field; close it with `end`.
    pub fn field_struct(&mut self, id: i16) {
        self.field(id, STRUCT);
        self.begin();
    }

    /// A list field's header: `len` elements of `kind` follow (structs each bracketed by `begin`/`end`).
    pub fn list(&mut self, id: i16, kind: u8, len: usize) {
        self.field(id, LIST);
        if len < 15 {
            self.bytes.push(((len as u8) << 4) | kind);
        } else {
            self.bytes.push(0xF0 | kind);
            self.varint(len as u64);
        }
    }

    /// A list element of type I32.
    pub fn element_i32(&mut self, v: i32) {
        self.zigzag(i64::from(v));
    }

    /// A list element of type BINARY.
    pub fn element_binary(&mut self, v: &[u8]) {
        self.raw_binary(v);
    }
}

/// Nesting deeper than this is refused (a footer's deepest is five: file, row group, column chunk, column
/// metadata, statistics); it bounds the recursion of skipping unknown fields.
const MAX_DEPTH: usize = 32;

/// A compact-protocol decoder over a byte slice. Every read is checked: malformed bytes give an error,
/// never a panic.
pub struct Reader<'a> {
    bytes: &'a [u8],
    pub at: usize,
    last_ids: Vec<i16>,
}

fn malformed(what: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, format!("not a Parquet table: {what}"))
}

/// A field's value type (for a boolean, also its value).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldType(pub u8);

impl<'a> Reader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes, at: 0, last_ids: Vec::new() }
    }

    fn u8(&mut self) -> io::Result<u8> {
        let b = *self.bytes.get(self.at).ok_or_else(|| malformed("its metadata ends early"))?;
        self.at += 1;
        Ok(b)
    }

    fn varint(&mut self) -> io::Result<u64> {
        let mut v = 0u64;
        for shift in (0..70).step_by(7) {
            let b = self.u8()?;
            if shift == 63 && b > 1 {
                break;
            }
            v |= u64::from(b & 0x7F) << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(malformed("an integer longer than 64 bits"))
    }

    fn zigzag(&mut self) -> io::Result<i64> {
        let v = self.varint()?;
        Ok((v >> 1) as i64 ^ -((v & 1) as i64))
    }

    /// Opens a struct (the top-level one, a list's element, or after a struct field's header).
    pub fn begin(&mut self) -> io::Result<()> {
        if self.last_ids.len() >= MAX_DEPTH {
            return Err(malformed("its metadata is nested too deeply"));
        }
        self.last_ids.push(0);
        Ok(())
    }

    /// The next field's id and type, or None at the struct's end (which closes it).
    pub fn field(&mut self) -> io::Result<Option<(i16, FieldType)>> {
        let b = self.u8()?;
        if b == 0 {
            self.last_ids.pop();
            return Ok(None);
        }
        let kind = b & 0x0F;
        let last = *self.last_ids.last().ok_or_else(|| malformed("a field outside a struct"))?;
        let id = match b >> 4 {
            0 => i16::try_from(self.zigzag()?).map_err(|_| malformed("a field id out of range"))?,
            delta => last.checked_add(i16::from(delta)).ok_or_else(|| malformed("a field id out of range"))?,
        };
        if let Some(l) = self.last_ids.last_mut() {
            *l = id;
        }
        Ok(Some((id, FieldType(kind))))
    }

    /// An integer field's value (any of BYTE, I16, I32, I64).
    pub fn int(&mut self, t: FieldType) -> io::Result<i64> {
        match t.0 {
            BYTE => Ok(i64::from(self.u8()? as i8)),
            I16 | I32 | I64 => self.zigzag(),
            _ => Err(malformed("an integer field of another type")),
        }
    }

    /// An integer field that must fit an i32 (counts, sizes, enumerations).
    pub fn i32(&mut self, t: FieldType) -> io::Result<i32> {
        i32::try_from(self.int(t)?).map_err(|_| malformed("a 32-bit field out of range"))
    }

    pub fn bool(&mut self, t: FieldType) -> io::Result<bool> {
        match t.0 {
            BOOL_TRUE => Ok(true),
            BOOL_FALSE => Ok(false),
            _ => Err(malformed("a boolean field of another type")),
        }
    }

    /// A binary field's bytes (borrowed from the input).
    pub fn binary(&mut self, t: FieldType) -> io::Result<&'a [u8]> {
        if t.0 != BINARY {
            return Err(malformed("a binary field of another type"));
        }
        self.raw_binary()
    }

    fn raw_binary(&mut self) -> io::Result<&'a [u8]> {
        let len = usize::try_from(self.varint()?).map_err(|_| malformed("a length out of range"))?;
        let end = self.at.checked_add(len).filter(|e| *e <= self.bytes.len());
        let end = end.ok_or_else(|| malformed("a binary runs past its metadata"))?;
        let v = &self.bytes[self.at..end];
        self.at = end;
        Ok(v)
    }

    /// A list field's element type and length (the elements follow). The length is checked against the
    /// bytes left, each element taking at least one, so that no caller reserves for a forged count.
    pub fn list(&mut self, t: FieldType) -> io::Result<(u8, usize)> {
        if t.0 != LIST && t.0 != SET {
            return Err(malformed("a list field of another type"));
        }
        let b = self.u8()?;
        let len = match b >> 4 {
            15 => usize::try_from(self.varint()?).map_err(|_| malformed("a length out of range"))?,
            n => usize::from(n),
        };
        if len > self.bytes.len() - self.at {
            return Err(malformed("a list longer than its metadata"));
        }
        Ok((b & 0x0F, len))
    }

    /// Skips a field's value of this type (an unknown field, or a known one not needed).
    pub fn skip(&mut self, t: FieldType) -> io::Result<()> {
        self.skip_value(t.0, 0)
    }

    fn skip_value(&mut self, kind: u8, depth: usize) -> io::Result<()> {
        if depth > MAX_DEPTH {
            return Err(malformed("its metadata is nested too deeply"));
        }
        match kind {
            BOOL_TRUE | BOOL_FALSE => Ok(()),
            BYTE => self.u8().map(drop),
            I16 | I32 | I64 => self.varint().map(drop),
            DOUBLE => {
                let end = self.at.checked_add(8).filter(|e| *e <= self.bytes.len());
                self.at = end.ok_or_else(|| malformed("its metadata ends early"))?;
                Ok(())
            }
            BINARY => self.raw_binary().map(drop),
            LIST | SET => {
                let (element, len) = self.list(FieldType(kind))?;
                for _ in 0..len {
                    // A boolean element is a whole byte.
                    if element == BOOL_TRUE || element == BOOL_FALSE {
                        self.u8()?;
                    } else {
                        self.skip_value(element, depth + 1)?;
                    }
                }
                Ok(())
            }
            MAP => {
                let len = usize::try_from(self.varint()?).map_err(|_| malformed("a length out of range"))?;
                if len == 0 {
                    return Ok(());
                }
                if len > self.bytes.len() - self.at {
                    return Err(malformed("a map longer than its metadata"));
                }
                let types = self.u8()?;
                for _ in 0..len {
                    self.skip_value(types >> 4, depth + 1)?;
                    self.skip_value(types & 0x0F, depth + 1)?;
                }
                Ok(())
            }
            STRUCT => {
                self.begin()?;
                while let Some((_, t)) = self.field()? {
                    self.skip_value(t.0, depth + 1)?;
                }
                Ok(())
            }
            _ => Err(malformed("an unknown field type")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The compact protocol's own examples: field ids 1 then 3 as deltas, 20 after 3 as a long header;
    /// -1 as zigzag 1; a list of 20 as the long list header; and the reader gives back what was written.
    #[test]
    fn compact_fields_read_back_as_written() {
        let mut w = Writer::default();
        w.begin();
        w.i32(1, -1);
        w.i64(3, 300);
        w.binary(20, b"ab");
        w.list(21, I32, 20);
        (0..20).for_each(|v| w.element_i32(v));
        w.bool(22, false);
        w.end();
        assert_eq!(&w.bytes[..6], &[0x15, 0x01, 0x26, 0xD8, 0x04, 0x08]);
        assert_eq!(&w.bytes[6..10], &[0x28, 0x02, b'a', b'b']);
        assert_eq!(&w.bytes[10..13], &[0x19, 0xF5, 20]);
        let mut r = Reader::new(&w.bytes);
        r.begin().unwrap();
        let (id, t) = r.field().unwrap().unwrap();
        assert_eq!((id, r.int(t).unwrap()), (1, -1));
        let (id, t) = r.field().unwrap().unwrap();
        assert_eq!((id, r.int(t).unwrap()), (3, 300));
        let (id, t) = r.field().unwrap().unwrap();
        assert_eq!((id, r.binary(t).unwrap()), (20, &b"ab"[..]));
        let (id, t) = r.field().unwrap().unwrap();
        assert_eq!(id, 21);
        let (kind, len) = r.list(t).unwrap();
        let values: Vec<i64> = (0..len).map(|_| r.int(FieldType(kind)).unwrap()).collect();
        assert_eq!(values, (0..20).collect::<Vec<_>>());
        let (id, t) = r.field().unwrap().unwrap();
        assert_eq!((id, r.bool(t).unwrap()), (22, false));
        assert!(r.field().unwrap().is_none());
    }
}

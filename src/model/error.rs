//! Errors in input files, located by file, line and column so a user can go straight to the mistake.

use std::path::{Path, PathBuf};

/// An input that cannot be used, located where possible (file, line, column), worded to say what to do.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The cause is written here, once: it is not also a `source`, which `{:#}` would print again.
    #[error("cannot read {}: {cause}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why it could not be read.
        cause: std::io::Error,
    },
    /// The file is not valid TOML (or CSV) at all.
    #[error("{}: {message}", path.display())]
    Syntax {
        /// The file.
        path: PathBuf,
        /// The parser's message, with its location.
        message: String,
    },
    /// A value at a known place is wrong.
    #[error("{}, line {line}, column {column}: {message}", path.display())]
    At {
        /// The file.
        path: PathBuf,
        /// Line, from 1.
        line: usize,
        /// Column, from 1.
        column: usize,
        /// What is wrong and what to do.
        message: String,
    },
    /// The file as a whole is wrong (no single place to point at).
    #[error("{}: {message}", path.display())]
    Whole {
        /// The file.
        path: PathBuf,
        /// What is wrong and what to do.
        message: String,
    },
}

/// 1-based line and column of a byte offset.
pub fn line_column(source: &str, offset: usize) -> (usize, usize) {
    let before = &source[..offset.min(source.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rfind('\n').map_or(before.len(), |n| before.len() - n - 1) + 1;
    (line, column)
}

/// Builds located errors for one file.
pub struct Locator<'a> {
    /// The file.
    pub path: &'a Path,
    /// Its text.
    pub source: &'a str,
}

/// The one rule every reader of numbers applies (grids, points CSV, error files, command-line values): the
/// message for a value that is not a finite number.
pub fn not_finite(text: &str) -> String {
    format!("`{text}` is not a finite number")
}

impl Locator<'_> {
    /// An array of exactly `N` finite numbers, or a located error naming the key.
    pub fn finite_array<const N: usize>(&self, v: &toml::Spanned<Vec<f64>>, key: &str) -> Result<[f64; N], InputError> {
        let values = v.get_ref();
        if values.len() != N {
            return Err(self.at(v.span(), format!("`{key}` needs {N} numbers, got {}", values.len())));
        }
        if let Some(bad) = values.iter().find(|x| !x.is_finite()) {
            return Err(self.at(v.span(), format!("`{key}`: {}", not_finite(&bad.to_string()))));
        }
        Ok(std::array::from_fn(|k| values[k]))
    }

    /// As `finite_array`, for an optional key.
    pub fn optional_array<const N: usize>(
        &self,
        v: &Option<toml::Spanned<Vec<f64>>>,
        key: &str,
    ) -> Result<Option<[f64; N]>, InputError> {
        v.as_ref().map(|v| self.finite_array(v, key)).transpose()
    }

    /// An error at the bytes `span` of the file (line and column computed).
    pub fn at(&self, span: std::ops::Range<usize>, message: impl Into<String>) -> InputError {
        let (line, column) = line_column(self.source, span.start);
        InputError::At { path: self.path.to_path_buf(), line, column, message: message.into() }
    }

    /// An error about the whole file.
    pub fn whole(&self, message: impl Into<String>) -> InputError {
        InputError::Whole { path: self.path.to_path_buf(), message: message.into() }
    }

    /// A TOML parse error, located.
    pub fn syntax(&self, e: toml::de::Error) -> InputError {
        InputError::Syntax { path: self.path.to_path_buf(), message: e.to_string().trim_end().to_string() }
    }
}

/// Reads a text file, with an error that names it.
/// `-` means standard input (as `-o -` means standard output); a name ending in `.gz` or `.zst` is
/// decompressed (what `-o FILE.csv.gz` wrote reads back).
pub fn read_text(path: &Path) -> Result<String, InputError> {
    let mut text = String::new();
    std::io::Read::read_to_string(&mut open_input(path)?, &mut text)
        .map_err(|cause| InputError::Read { path: path.to_path_buf(), cause })?;
    Ok(text)
}

/// Largest URDF file read (bytes): the largest robot descriptions in use are a few megabytes.
pub const MAX_DESCRIPTION_BYTES: u64 = 64 << 20;

/// A description file's text (a URDF): a regular file of at most `MAX_DESCRIPTION_BYTES`, else a message
/// saying what it is (`/dev/zero`, a folder, a pipe would be read until memory runs out, or not at all).
pub fn read_regular_file(path: &Path) -> Result<String, InputError> {
    let whole = |message: String| InputError::Whole { path: path.to_path_buf(), message };
    let meta = std::fs::metadata(path).map_err(|cause| InputError::Read { path: path.to_path_buf(), cause })?;
    if !meta.is_file() {
        return Err(whole("not a regular file: give the path of the description file itself".into()));
    }
    if meta.len() > MAX_DESCRIPTION_BYTES {
        return Err(whole(format!(
            "{} bytes, past the {} MiB a description may have",
            meta.len(),
            MAX_DESCRIPTION_BYTES >> 20
        )));
    }
    let mut text = String::new();
    let file = std::fs::File::open(path).map_err(|cause| InputError::Read { path: path.to_path_buf(), cause })?;
    // The file may grow while it is read: never more than the limit.
    std::io::Read::read_to_string(&mut std::io::Read::take(file, MAX_DESCRIPTION_BYTES + 1), &mut text)
        .map_err(|cause| InputError::Read { path: path.to_path_buf(), cause })?;
    if text.len() as u64 > MAX_DESCRIPTION_BYTES {
        return Err(whole(format!("past the {} MiB a description may have", MAX_DESCRIPTION_BYTES >> 20)));
    }
    Ok(text)
}

/// An input opened for streaming: the file, or standard input for `-`, decompressed by its name.
pub fn open_input(path: &Path) -> Result<Box<dyn std::io::Read + Send>, InputError> {
    let failed = |cause| InputError::Read { path: path.to_path_buf(), cause };
    let raw: Box<dyn std::io::Read + Send> =
        if is_stdin(path) { Box::new(std::io::stdin()) } else { Box::new(std::fs::File::open(path).map_err(failed)?) };
    let name = path.to_string_lossy();
    if name.to_ascii_lowercase().ends_with(".parquet") {
        return Err(InputError::Whole {
            path: path.to_path_buf(),
            message: "Parquet tables are read by `stiff plot`; points, grids, models and measurements are CSV \
                      or TOML (plain, .gz or .zst)"
                .into(),
        });
    }
    let decoded: Box<dyn std::io::Read + Send> = if name.ends_with(".gz") {
        Box::new(flate2::read::MultiGzDecoder::new(std::io::BufReader::new(raw)))
    } else if name.ends_with(".zst") {
        Box::new(zstd::Decoder::new(raw).map_err(failed)?)
    } else {
        raw
    };
    Ok(Box::new(LfLineEnds::new(decoded)))
}

/// A reader that turns each CR LF line end into LF and leaves every other byte as it is. A file written on
/// Windows then reads as any other: the csv crate reports the line of a record after a CR LF one line early
/// (rust-csv issue #395), so every located error in such a file named the line above the faulty one.
pub struct LfLineEnds<R> {
    inner: R,
    buf: Box<[u8]>,
    start: usize,
    end: usize,
    eof: bool,
}

impl<R> LfLineEnds<R> {
    /// Wraps `inner`.
    pub fn new(inner: R) -> Self {
        LfLineEnds { inner, buf: vec![0; 64 * 1024].into_boxed_slice(), start: 0, end: 0, eof: false }
    }
}

impl<R: std::io::Read> std::io::Read for LfLineEnds<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        if out.is_empty() {
            return Ok(0);
        }
        loop {
            // A CR is judged by the byte after it: keep at least two bytes at hand until the input ends.
            if self.end - self.start < 2 && !self.eof {
                self.buf.copy_within(self.start..self.end, 0);
                self.end -= self.start;
                self.start = 0;
                match self.inner.read(&mut self.buf[self.end..]) {
                    Ok(0) => self.eof = true,
                    Ok(n) => self.end += n,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(e),
                }
                continue;
            }
            let mut written = 0;
            while written < out.len() && self.start < self.end {
                let rest = &self.buf[self.start..self.end];
                let room = out.len() - written;
                match memchr::memchr(b'\r', &rest[..rest.len().min(room)]) {
                    // No CR in what fits: copy it whole.
                    None => {
                        let n = rest.len().min(room);
                        out[written..written + n].copy_from_slice(&rest[..n]);
                        written += n;
                        self.start += n;
                    }
                    Some(k) => {
                        out[written..written + k].copy_from_slice(&rest[..k]);
                        written += k;
                        self.start += k;
                        match rest.get(k + 1) {
                            // CR LF: the CR is dropped.
                            Some(b'\n') => self.start += 1,
                            // A CR whose next byte has not been read: stop here and read on.
                            None if !self.eof => break,
                            // A lone CR (or the input's last byte) stays: there is room for it, as the search
                            // above stopped short of the room left.
                            _ => {
                                out[written] = b'\r';
                                written += 1;
                                self.start += 1;
                            }
                        }
                    }
                }
            }
            if written > 0 || (self.eof && self.start == self.end) {
                return Ok(written);
            }
        }
    }
}

/// Whether a path names standard input.
pub fn is_stdin(path: &Path) -> bool {
    path.as_os_str() == "-"
}

#[cfg(test)]
mod tests {
    use super::LfLineEnds;
    use std::io::Read;

    /// An input read in pieces of at most `piece` bytes (the inner reader's side of a buffer boundary).
    struct Pieces<'a>(&'a [u8], usize);

    impl Read for Pieces<'_> {
        fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
            let n = self.0.len().min(self.1).min(out.len());
            out[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    /// Every CR LF becomes LF and nothing else changes (a lone CR, a CR at the end), whatever the pieces
    /// the input arrives in and the sizes asked for: checked against the text with "\r\n" replaced, over
    /// random inputs rich in CR and LF.
    #[test]
    fn crlf_line_ends_become_lf_and_nothing_else_changes() {
        use rand::{Rng, SeedableRng};
        let mut r = rand::rngs::StdRng::seed_from_u64(395);
        let alphabet = b"\r\n,a";
        for _ in 0..2000 {
            let len = r.random_range(0..40);
            let input: Vec<u8> = (0..len).map(|_| alphabet[r.random_range(0..alphabet.len())]).collect();
            let expected = String::from_utf8(input.clone()).unwrap().replace("\r\n", "\n").into_bytes();
            let (piece, ask) = (r.random_range(1..5), r.random_range(1..5));
            let mut reader = LfLineEnds::new(Pieces(&input, piece));
            let mut got = Vec::new();
            let mut out = vec![0; ask];
            loop {
                let n = reader.read(&mut out).unwrap();
                if n == 0 {
                    break;
                }
                got.extend_from_slice(&out[..n]);
            }
            assert_eq!(got, expected, "{input:?} in pieces of {piece}, asked {ask} at a time");
        }
    }
}

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
    Ok(if name.ends_with(".gz") {
        Box::new(flate2::read::MultiGzDecoder::new(std::io::BufReader::new(raw)))
    } else if name.ends_with(".zst") {
        Box::new(zstd::Decoder::new(raw).map_err(failed)?)
    } else {
        raw
    })
}

/// Whether a path names standard input.
pub fn is_stdin(path: &Path) -> bool {
    path.as_os_str() == "-"
}

//! Errors in input files, located by file, line and column so a user can go straight to the mistake.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The cause is written here, once: it is not also a `source`, which `{:#}` would print again.
    #[error("cannot read {}: {cause}", path.display())]
    Read { path: PathBuf, cause: std::io::Error },
    #[error("{}: {message}", path.display())]
    Syntax { path: PathBuf, message: String },
    #[error("{}, line {line}, column {column}: {message}", path.display())]
    At { path: PathBuf, line: usize, column: usize, message: String },
    #[error("{}: {message}", path.display())]
    Whole { path: PathBuf, message: String },
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
    pub path: &'a Path,
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

    pub fn at(&self, span: std::ops::Range<usize>, message: impl Into<String>) -> InputError {
        let (line, column) = line_column(self.source, span.start);
        InputError::At { path: self.path.to_path_buf(), line, column, message: message.into() }
    }

    pub fn whole(&self, message: impl Into<String>) -> InputError {
        InputError::Whole { path: self.path.to_path_buf(), message: message.into() }
    }

    pub fn syntax(&self, e: toml::de::Error) -> InputError {
        InputError::Syntax { path: self.path.to_path_buf(), message: e.to_string().trim_end().to_string() }
    }
}

pub fn read_text(path: &Path) -> Result<String, InputError> {
    std::fs::read_to_string(path).map_err(|cause| InputError::Read { path: path.to_path_buf(), cause })
}

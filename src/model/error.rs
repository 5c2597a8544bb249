//! Errors in input files, located by file, line and column so a user can go straight to the mistake.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("cannot read {}: {source}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
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

impl Locator<'_> {
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
    std::fs::read_to_string(path).map_err(|source| InputError::Read { path: path.to_path_buf(), source })
}

//! Where a study's rows go: stdout, or a file written through a temporary file in the same folder and
//! renamed into place on success, so an interrupted or failed run never leaves a file that looks complete.

use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};

pub enum Sink {
    Stdout(BufWriter<io::Stdout>),
    File { temp: BufWriter<tempfile::NamedTempFile>, path: PathBuf },
}

impl Sink {
    /// `None` or `-` is stdout. The temporary file is created at once, so an unwritable path fails before
    /// any work is done.
    pub fn create(path: Option<&Path>) -> Result<Self> {
        let p = match path {
            None => return Ok(Sink::Stdout(BufWriter::new(io::stdout()))),
            Some(p) if p.as_os_str() == "-" => return Ok(Sink::Stdout(BufWriter::new(io::stdout()))),
            Some(p) => p,
        };
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if p.is_dir() {
            bail!("cannot write {}: it is a folder", p.display());
        }
        if !dir.is_dir() {
            bail!("cannot write {}: the folder {} does not exist", p.display(), dir.display());
        }
        let temp = tempfile::Builder::new()
            .prefix(".stiff-")
            .suffix(".partial")
            .tempfile_in(&dir)
            .map_err(|e| anyhow!("cannot write {}: {}", p.display(), e.kind()))?;
        Ok(Sink::File { temp: BufWriter::with_capacity(1 << 20, temp), path: p.to_path_buf() })
    }

    pub fn writer(&mut self) -> &mut (dyn Write + Send) {
        match self {
            Sink::Stdout(w) => w,
            Sink::File { temp, .. } => temp,
        }
    }

    /// Flushes and moves the file into place (readable by others, as a plain file would be).
    pub fn finish(self) -> Result<()> {
        match self {
            Sink::Stdout(mut w) => w.flush().context("cannot write to stdout"),
            Sink::File { temp, path } => {
                let temp = temp
                    .into_inner()
                    .map_err(|e| e.into_error())
                    .with_context(|| format!("cannot write {}", path.display()))?;
                #[cfg(unix)]
                {
                    use std::os::unix::fs::PermissionsExt;
                    let _ = temp.as_file().set_permissions(std::fs::Permissions::from_mode(0o644));
                }
                temp.persist(&path)
                    .map_err(|e| e.error)
                    .with_context(|| format!("cannot move the result to {}", path.display()))?;
                Ok(())
            }
        }
    }
}

//! Where a study's rows go: stdout; a regular file, written through a temporary file in the same folder and
//! renamed into place on success, so an interrupted or failed run never leaves a file that looks complete;
//! or anything else that exists and is not a regular file (`/dev/null`, a FIFO), written through directly,
//! since renaming over it would replace the device node by a plain file. A symbolic link is followed: its
//! target is written (the temporary file beside the target, renamed over it) and the link stays.
//!
//! The temporary files in use are registered, so that Ctrl-C or SIGTERM removes them before the process
//! exits (`install_signal_cleanup`). A SIGKILL cannot be caught: it leaves a hidden `.stiff-XXXXXX.partial`
//! beside the target (docs/GUIDE.md).

use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::{anyhow, bail, Context, Result};

use super::parquet::ParquetTable;
use super::table::Column;

/// Whether `path` names a Parquet file (by its extension, as the compressed outputs are chosen).
pub fn is_parquet(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("parquet"))
}

/// Temporary files being written, removed if the process is interrupted.
static PARTIAL: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// On SIGINT, SIGTERM or SIGHUP: remove every registered temporary file, then exit with 130 (the shell's
/// code for an interrupted command). Call once at start-up.
pub fn install_signal_cleanup() {
    let _ = ctrlc::set_handler(|| {
        if let Ok(files) = PARTIAL.lock() {
            for f in files.iter() {
                let _ = std::fs::remove_file(f);
            }
        }
        std::process::exit(130);
    });
}

fn register(path: &Path) {
    if let Ok(mut files) = PARTIAL.lock() {
        files.push(path.to_path_buf());
    }
}

fn unregister(path: &Path) {
    if let Ok(mut files) = PARTIAL.lock() {
        files.retain(|f| f != path);
    }
}

/// Symbolic links followed before a path is given up as a loop (Linux's own limit).
const MAX_LINK_HOPS: usize = 40;

/// The file a path names once its symbolic links are followed: a link is written through (its target
/// replaced atomically, the link kept), as a user who keeps results on another disk expects. A link to a
/// missing file names the file to create; its folder must exist. Relative targets are read from the link's
/// own folder.
fn follow_links(path: &Path) -> Result<PathBuf> {
    let mut current = path.to_path_buf();
    for _ in 0..MAX_LINK_HOPS {
        let Ok(meta) = std::fs::symlink_metadata(&current) else { return Ok(current) };
        if !meta.file_type().is_symlink() {
            return Ok(current);
        }
        let target = std::fs::read_link(&current).map_err(|e| {
            anyhow!("cannot write {}: cannot read the link {}: {}", path.display(), current.display(), e.kind())
        })?;
        current = match current.parent() {
            Some(folder) if target.is_relative() => folder.join(target),
            _ => target,
        };
        if let Some(folder) = current.parent().filter(|f| !f.as_os_str().is_empty()) {
            if !folder.is_dir() {
                bail!(
                    "cannot write {}: it is a symbolic link to {}, whose folder {} does not exist (create it, or point the link elsewhere)",
                    path.display(),
                    current.display(),
                    folder.display()
                );
            }
        }
    }
    bail!("cannot write {}: more than {MAX_LINK_HOPS} symbolic links in a row (a loop?)", path.display())
}

/// Where a command's output goes.
pub enum Sink {
    /// Standard output.
    Stdout(BufWriter<io::Stdout>),
    /// An existing path that is not a regular file: written in place.
    Direct {
        /// The file.
        file: BufWriter<File>,
        /// Its path (for messages).
        path: PathBuf,
    },
    /// A regular file: written to a temporary file beside it and renamed on success; compressed when
    /// the name ends in `.gz` or `.zst`.
    File {
        /// The temporary file, through its encoder.
        temp: Encoded,
        /// The final path.
        path: PathBuf,
    },
}

/// A file's encoding, chosen by its name: `.parquet` for a table, `.gz` (gzip, flate2), `.zst` (zstandard),
/// else plain.
pub enum Encoded {
    /// Plain text.
    Plain(BufWriter<tempfile::NamedTempFile>),
    /// gzip at the default level.
    Gzip(flate2::write::GzEncoder<BufWriter<tempfile::NamedTempFile>>),
    /// zstandard at its default level (3).
    Zstd(zstd::Encoder<'static, BufWriter<tempfile::NamedTempFile>>),
    /// A Parquet table, filled from the CSV text written to it.
    Parquet(Box<ParquetTable<BufWriter<tempfile::NamedTempFile>>>),
}

/// Bytes buffered before a write to the file. A batch study hands over whole runs (a map's 256 rows are
/// ~160 KB), which a buffer smaller than them passes straight to the file without copying them first.
const WRITE_BUFFER: usize = 64 << 10;

impl Encoded {
    fn new(temp: tempfile::NamedTempFile, path: &Path, columns: Option<&[Column]>) -> io::Result<Encoded> {
        let file = BufWriter::with_capacity(WRITE_BUFFER, temp);
        let name = path.to_string_lossy();
        Ok(if let Some(columns) = columns.filter(|_| is_parquet(path)) {
            Encoded::Parquet(Box::new(ParquetTable::new(file, columns)?))
        } else if name.ends_with(".gz") {
            Encoded::Gzip(flate2::write::GzEncoder::new(file, flate2::Compression::default()))
        } else if name.ends_with(".zst") {
            Encoded::Zstd(zstd::Encoder::new(file, 0)?)
        } else {
            Encoded::Plain(file)
        })
    }

    fn writer(&mut self) -> &mut (dyn Write + Send) {
        match self {
            Encoded::Plain(w) => w,
            Encoded::Gzip(w) => w,
            Encoded::Zstd(w) => w,
            Encoded::Parquet(w) => w.as_mut(),
        }
    }

    /// Ends the encoding (trailer written) and hands back the file.
    fn finish(self) -> io::Result<BufWriter<tempfile::NamedTempFile>> {
        match self {
            Encoded::Plain(w) => Ok(w),
            Encoded::Gzip(w) => w.finish(),
            Encoded::Zstd(w) => w.finish(),
            Encoded::Parquet(w) => w.finish(),
        }
    }
}

impl Sink {
    /// `None` or `-` is stdout. The temporary file is created at once, so an unwritable path fails before
    /// any work is done. A `.parquet` name is refused: only tables are written as Parquet (`table`).
    pub fn create(path: Option<&Path>) -> Result<Self> {
        if let Some(p) = path.filter(|p| is_parquet(p)) {
            bail!(
                "cannot write {}: only tables (map, assemble, synth and curve -o) are written as Parquet",
                p.display()
            );
        }
        Self::open(path, None)
    }

    /// Where a table with these columns goes: as `create`, and a Parquet table where the name ends in
    /// `.parquet` (the CSV text written to it fills typed columns).
    pub fn table(path: Option<&Path>, columns: &[Column]) -> Result<Self> {
        Self::open(path, Some(columns))
    }

    fn open(path: Option<&Path>, columns: Option<&[Column]>) -> Result<Self> {
        let p = match path {
            None => return Ok(Sink::Stdout(BufWriter::new(io::stdout()))),
            Some(p) if p.as_os_str() == "-" => return Ok(Sink::Stdout(BufWriter::new(io::stdout()))),
            Some(p) => p,
        };
        // The format follows the name given; the file written is where its links lead.
        let given = p;
        let target = follow_links(given)?;
        let p = target.as_path();
        if p.is_dir() {
            bail!("cannot write {}: it is a folder", p.display());
        }
        if let Ok(meta) = std::fs::metadata(p) {
            if !meta.is_file() {
                let file = OpenOptions::new()
                    .write(true)
                    .open(p)
                    .map_err(|e| anyhow!("cannot write {}: {}", p.display(), e.kind()))?;
                return Ok(Sink::Direct { file: BufWriter::with_capacity(WRITE_BUFFER, file), path: p.to_path_buf() });
            }
        }
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if !dir.is_dir() {
            bail!("cannot write {}: the folder {} does not exist", p.display(), dir.display());
        }
        let temp = tempfile::Builder::new()
            .prefix(".stiff-")
            .suffix(".partial")
            .tempfile_in(&dir)
            .map_err(|e| anyhow!("cannot write {}: {}", p.display(), e.kind()))?;
        register(temp.path());
        let temp = Encoded::new(temp, given, columns).map_err(|e| anyhow!("cannot write {}: {e}", p.display()))?;
        Ok(Sink::File { temp, path: p.to_path_buf() })
    }

    /// The stream to write to.
    pub fn writer(&mut self) -> &mut (dyn Write + Send) {
        match self {
            Sink::Stdout(w) => w,
            Sink::Direct { file, .. } => file,
            Sink::File { temp, .. } => temp.writer(),
        }
    }

    /// Flushes and moves the file into place (readable by others, as a plain file would be).
    pub fn finish(self) -> Result<()> {
        match self {
            Sink::Stdout(mut w) => w.flush().context("cannot write to stdout"),
            Sink::Direct { mut file, path } => file.flush().with_context(|| format!("cannot write {}", path.display())),
            Sink::File { temp, path } => {
                let temp = temp
                    .finish()
                    .with_context(|| format!("cannot write {}", path.display()))?
                    .into_inner()
                    .map_err(|e| e.into_error())
                    .with_context(|| format!("cannot write {}", path.display()))?;
                #[cfg(unix)]
                {
                    use std::os::unix::fs::PermissionsExt;
                    let _ = temp.as_file().set_permissions(std::fs::Permissions::from_mode(0o644));
                }
                let temp_path = temp.path().to_path_buf();
                let result = temp
                    .persist(&path)
                    .map_err(|e| e.error)
                    .with_context(|| format!("cannot move the result to {}", path.display()));
                unregister(&temp_path);
                result.map(|_| ())
            }
        }
    }
}

//! Output files that appear only when complete (every `-o` of the command line).

use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::diag::printable;

/// An output file that appears only when complete: the text goes to a temporary file in the
/// same directory, which [`commit`](Self::commit) renames over the target. A run that fails
/// or is interrupted before leaves the previous file as it was (an interrupted process may
/// leave its temporary file, named `.NAME.XXXXXX.tmp`, beside it). A target that exists and
/// is not a regular file (`/dev/stdout`, a named pipe) is written directly: renaming over it
/// would replace the device instead of writing to it.
pub struct OutputFile {
    out: BufWriter<Target>,
    path: PathBuf,
}

/// Where an [`OutputFile`] writes.
enum Target {
    Temporary(tempfile::NamedTempFile),
    Direct(std::fs::File),
}

impl Write for Target {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Self::Temporary(f) => f.write(buf),
            Self::Direct(f) => f.write(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Self::Temporary(f) => f.flush(),
            Self::Direct(f) => f.flush(),
        }
    }
}

impl OutputFile {
    /// Starts writing `path`. The file keeps the permissions it had, or gets the usual ones
    /// of a new file (0666 less the umask), not the temporary file's private ones.
    ///
    /// # Errors
    /// When the temporary file cannot be created; the message names `path`.
    pub fn create(path: &Path) -> io::Result<Self> {
        let previous = std::fs::metadata(path).ok();
        if previous.as_ref().is_some_and(|m| !m.is_file()) {
            let file =
                std::fs::OpenOptions::new().write(true).open(path).map_err(|e| naming(path, e))?;
            return Ok(Self { out: BufWriter::new(Target::Direct(file)), path: path.to_owned() });
        }
        let name = path.file_name().ok_or_else(|| {
            naming(path, io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))
        })?;
        let prefix = format!(".{}.", name.to_string_lossy());
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        #[cfg(unix)]
        let permissions = {
            use std::os::unix::fs::PermissionsExt;
            std::fs::Permissions::from_mode(0o666)
        };
        #[cfg(unix)]
        builder.permissions(permissions);
        let temp = builder.tempfile_in(directory_of(path)).map_err(|e| naming(path, e))?;
        if let Some(previous) = previous {
            temp.as_file().set_permissions(previous.permissions()).map_err(|e| naming(path, e))?;
        }
        Ok(Self { out: BufWriter::new(Target::Temporary(temp)), path: path.to_owned() })
    }

    /// The file to be written.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes the rest out, syncs it to the disk and renames it over the target.
    ///
    /// # Errors
    /// When writing, syncing or renaming fails (the target is then unchanged); the message
    /// names the file.
    pub fn commit(self) -> io::Result<()> {
        let path = self.path;
        match self.out.into_inner().map_err(|e| naming(&path, e.into_error()))? {
            Target::Temporary(temp) => {
                temp.as_file().sync_all().map_err(|e| naming(&path, e))?;
                temp.persist(&path).map_err(|e| naming(&path, e.error))?;
            }
            Target::Direct(mut file) => file.flush().map_err(|e| naming(&path, e))?,
        }
        Ok(())
    }
}

impl Write for OutputFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.out.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

/// Writes `contents` to `path` through an [`OutputFile`]: all of it, or nothing.
///
/// # Errors
/// As [`OutputFile::create`] and [`OutputFile::commit`].
pub fn write_file(path: &Path, contents: &[u8]) -> io::Result<()> {
    let mut file = OutputFile::create(path)?;
    file.write_all(contents).map_err(|e| naming(path, e))?;
    file.commit()
}

/// The directory a file is written in (`.` for a bare file name).
#[must_use]
pub fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    }
}

/// `e` with the file it concerns named, keeping its kind.
fn naming(path: &Path, e: io::Error) -> io::Error {
    io::Error::new(
        e.kind(),
        format!("cannot write {}: {e}", printable(&path.display().to_string())),
    )
}

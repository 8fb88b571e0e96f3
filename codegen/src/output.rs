//! Output files that appear only when complete (every `-o` of the command line).

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, SyncSender};
use std::thread::JoinHandle;

use crate::diag::printable;

/// An output file that appears only when complete: the text goes to a temporary file in the
/// same directory, which [`commit`](Self::commit) renames over the target. A run that fails
/// or is interrupted before leaves the previous file as it was (an interrupted process may
/// leave its temporary file, named `.NAME.XXXXXX.tmp`, beside it). A target that exists and
/// is not a regular file (`/dev/stdout`, a named pipe) is written directly: renaming over it
/// would replace the device instead of writing to it.
///
/// The writing itself (the system calls, the kernel's copy into its page cache, and for a
/// temporary file the syncs to the disk) happens on a thread of its own, one chunk of
/// [`CHUNK`] bytes at a time, so that a long output costs the caller the formatting only: the
/// writes and the final sync overlap with what the caller computes meanwhile. A failed write
/// is returned by the next write or by [`commit`](Self::commit).
pub struct OutputFile {
    /// What has not been handed to the writer yet.
    buf: Vec<u8>,
    /// The target until the first full chunk, then the writer that owns it.
    sink: Option<Sink>,
    path: PathBuf,
}

/// The bytes handed to the writer thread at a time.
pub const CHUNK: usize = 1 << 20;

/// A temporary file is synced to the disk by the writer each time this many more bytes are
/// written, so that the sync before the rename has only the last part left to wait for.
const SYNC_EVERY: u64 = 16 << 20;

/// Where an [`OutputFile`]'s chunks go.
enum Sink {
    /// Written by the caller (nothing longer than a chunk was written yet).
    Here(Target),
    /// Written by a thread, which returns the target when the channel closes.
    Thread {
        chunks: SyncSender<Vec<u8>>,
        spare: Receiver<Vec<u8>>,
        writer: JoinHandle<io::Result<Target>>,
    },
}

impl Sink {
    /// Hands a full chunk over, starting the writer with the first; `buf` comes back empty
    /// (a spare chunk when one was returned).
    fn send(&mut self, buf: &mut Vec<u8>) -> Result<(), ()> {
        if let Sink::Here(_) = self {
            let Sink::Here(target) = std::mem::replace(self, Sink::Here(Target::Nothing)) else {
                unreachable!("matched above")
            };
            // A few chunks in flight: enough to keep the writer busy, bounded memory.
            let (chunks, queue) = std::sync::mpsc::sync_channel::<Vec<u8>>(16);
            let (give_back, spare) = std::sync::mpsc::channel();
            let writer = std::thread::spawn(move || write_chunks(target, &queue, &give_back));
            *self = Sink::Thread { chunks, spare, writer };
        }
        let Sink::Thread { chunks, spare, .. } = self else { unreachable!("started above") };
        let mut next = spare.try_recv().unwrap_or_else(|_| Vec::with_capacity(CHUNK));
        // Whole chunks only, so that every write starts on a page boundary of the file and
        // the kernel never reads or zeroes part of a page first.
        if buf.len() > CHUNK {
            next.extend_from_slice(&buf[CHUNK..]);
            buf.truncate(CHUNK);
        }
        chunks.send(std::mem::replace(buf, next)).map_err(|_| ())
    }

    /// Waits for everything handed over to be written and returns the target.
    fn finish(self) -> io::Result<Target> {
        match self {
            Sink::Here(target) => Ok(target),
            Sink::Thread { chunks, writer, .. } => {
                drop(chunks);
                writer.join().unwrap_or_else(|_| Err(io::Error::other("the writer panicked")))
            }
        }
    }
}

/// The writer thread: every chunk to `target`, each returned through `spare` for reuse,
/// syncing a temporary file every [`SYNC_EVERY`] bytes.
fn write_chunks(
    mut target: Target,
    chunks: &Receiver<Vec<u8>>,
    spare: &std::sync::mpsc::Sender<Vec<u8>>,
) -> io::Result<Target> {
    let (mut written, mut synced) = (0u64, 0u64);
    for mut chunk in chunks {
        target.write_all(&chunk)?;
        written += chunk.len() as u64;
        if let Target::Temporary(temp) = &target
            && written - synced >= SYNC_EVERY
        {
            temp.as_file().sync_data()?;
            synced = written;
        }
        chunk.clear();
        // The caller may have finished: a chunk nobody takes back is simply freed.
        let _ = spare.send(chunk);
    }
    Ok(target)
}

/// Where an [`OutputFile`] writes.
enum Target {
    Temporary(tempfile::NamedTempFile),
    Direct(std::fs::File),
    /// A placeholder while the target moves to the writer thread.
    Nothing,
}

impl Write for Target {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Self::Temporary(f) => f.write(buf),
            Self::Direct(f) => f.write(buf),
            Self::Nothing => Ok(buf.len()),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Self::Temporary(f) => f.flush(),
            Self::Direct(f) => f.flush(),
            Self::Nothing => Ok(()),
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
            return Ok(Self::new(Target::Direct(file), path));
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
        Ok(Self::new(Target::Temporary(temp), path))
    }

    fn new(target: Target, path: &Path) -> Self {
        Self {
            buf: Vec::with_capacity(CHUNK),
            sink: Some(Sink::Here(target)),
            path: path.to_owned(),
        }
    }

    /// Hands the buffer to the writer thread; a writer that stopped returns its error.
    fn send(&mut self) -> io::Result<()> {
        let sink = self.sink.as_mut().expect("present until commit or drop");
        if sink.send(&mut self.buf).is_ok() {
            return Ok(());
        }
        let failed = self.sink.take().expect("present").finish();
        Err(failed.err().unwrap_or_else(|| io::Error::other("the writer stopped")))
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
    pub fn commit(mut self) -> io::Result<()> {
        let path = std::mem::take(&mut self.path);
        let sink = self.sink.take().ok_or_else(|| naming(&path, io::Error::other("closed")))?;
        let mut target = sink.finish().map_err(|e| naming(&path, e))?;
        target.write_all(&self.buf).map_err(|e| naming(&path, e))?;
        match target {
            Target::Temporary(temp) => {
                temp.as_file().sync_all().map_err(|e| naming(&path, e))?;
                temp.persist(&path).map_err(|e| naming(&path, e.error))?;
            }
            Target::Direct(mut file) => file.flush().map_err(|e| naming(&path, e))?,
            Target::Nothing => {}
        }
        Ok(())
    }
}

impl Drop for OutputFile {
    fn drop(&mut self) {
        // Not committed: the writer ends and its temporary file is removed before this
        // returns.
        if let Some(sink) = self.sink.take() {
            let _ = sink.finish();
        }
    }
}

impl Write for OutputFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.sink.is_none() {
            return Err(io::Error::other("the output file was closed after a failed write"));
        }
        self.buf.extend_from_slice(buf);
        if self.buf.len() >= CHUNK {
            self.send()?;
        }
        Ok(buf.len())
    }

    /// Hands what is buffered to the writer (it reaches the file asynchronously; `commit`
    /// waits for all of it).
    fn flush(&mut self) -> io::Result<()> {
        if self.buf.is_empty() || self.sink.is_none() { Ok(()) } else { self.send() }
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

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
///
/// On Linux, the whole chunks of a temporary file go to the disk unbuffered (`O_DIRECT`),
/// straight from the chunk's memory, where the file system allows it: the kernel neither
/// copies them into its page cache nor writes them back later, which costs more CPU than
/// formatting them when the page cache has to take memory the machine gave back to its
/// host (BENCHMARKS.md, "End to end, again"). The tail, anything not page-aligned and every
/// file system that refuses unbuffered writes take the ordinary buffered path.
pub struct OutputFile {
    /// What has not been handed to the writer yet: the bytes from `start` on.
    buf: Vec<u8>,
    /// Where the text starts in `buf`: the padding before it puts it on a page boundary in
    /// memory, as unbuffered writes need.
    start: usize,
    /// The target until the first full chunk, then the writer that owns it.
    sink: Option<Sink>,
    path: PathBuf,
}

/// The bytes handed to the writer thread at a time.
pub const CHUNK: usize = 1 << 20;

/// A temporary file is synced to the disk by the writer each time this many more bytes are
/// written through the page cache, so that the sync before the rename has only the last part
/// left to wait for.
const SYNC_EVERY: u64 = 16 << 20;

/// The alignment, in memory, in the file and in length, of an unbuffered write: a page,
/// a multiple of every block size Linux's file systems ask `O_DIRECT` writes to keep to.
const PAGE: usize = 4096;

/// An empty buffer for a chunk with room for a whole chunk and a row beyond it, and the
/// padding that starts its text on a page boundary in memory ([`PAGE`]); `reuse` is an old
/// one to refill.
fn chunk_buffer(reuse: Option<Vec<u8>>) -> (Vec<u8>, usize) {
    let mut buf = reuse.unwrap_or_else(|| Vec::with_capacity(CHUNK + 2 * PAGE));
    buf.clear();
    let start = buf.as_ptr().addr().wrapping_neg() % PAGE;
    buf.resize(start, 0);
    (buf, start)
}

/// Where an [`OutputFile`]'s chunks go.
enum Sink {
    /// Written by the caller (nothing longer than a chunk was written yet).
    Here(Target),
    /// Written by a thread, which returns the target when the channel closes. A chunk is
    /// the buffer and where its text starts.
    Thread {
        chunks: SyncSender<(Vec<u8>, usize)>,
        spare: Receiver<Vec<u8>>,
        writer: JoinHandle<io::Result<Target>>,
    },
}

impl Sink {
    /// Hands a full chunk, the text of `buf` from `start` on, over, starting the writer with
    /// the first; `buf` and `start` come back with what went beyond the chunk (in a spare
    /// chunk when one was returned).
    fn send(&mut self, buf: &mut Vec<u8>, start: &mut usize) -> Result<(), ()> {
        if let Sink::Here(_) = self {
            let Sink::Here(target) = std::mem::replace(self, Sink::Here(Target::Nothing)) else {
                unreachable!("matched above")
            };
            // A few chunks in flight: enough to keep the writer busy, bounded memory.
            let (chunks, queue) = std::sync::mpsc::sync_channel(16);
            let (give_back, spare) = std::sync::mpsc::channel();
            let writer = std::thread::spawn(move || write_chunks(target, &queue, &give_back));
            *self = Sink::Thread { chunks, spare, writer };
        }
        let Sink::Thread { chunks, spare, .. } = self else { unreachable!("started above") };
        let (mut next, next_start) = chunk_buffer(spare.try_recv().ok());
        // Whole chunks only, so that every write starts on a page boundary of the file and
        // the kernel never reads or zeroes part of a page first.
        if buf.len() - *start > CHUNK {
            next.extend_from_slice(&buf[*start + CHUNK..]);
            buf.truncate(*start + CHUNK);
        }
        let chunk = (std::mem::replace(buf, next), std::mem::replace(start, next_start));
        chunks.send(chunk).map_err(|_| ())
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

/// The writer thread: every chunk to `target`, each returned through `spare` for reuse; a
/// temporary file's whole chunks unbuffered where the file system allows ([`Unbuffered`]),
/// the others through the page cache, synced every [`SYNC_EVERY`] bytes.
fn write_chunks(
    mut target: Target,
    chunks: &Receiver<(Vec<u8>, usize)>,
    spare: &std::sync::mpsc::Sender<Vec<u8>>,
) -> io::Result<Target> {
    let mut unbuffered = match &target {
        Target::Temporary(temp) => Unbuffered::open(temp),
        _ => None,
    };
    let (mut written, mut buffered, mut synced) = (0u64, 0u64, 0u64);
    for (chunk, start) in chunks {
        let text = &chunk[start..];
        let direct = unbuffered.as_ref().is_some_and(|u| u.fits(text, written));
        if direct && unbuffered.as_ref().is_some_and(|u| u.write(text, written).is_ok()) {
            written += text.len() as u64;
        } else {
            if direct {
                // Refused (or failed part way): this chunk and the rest go through the page
                // cache, where an error that is no refusal shows again.
                unbuffered = None;
            }
            write_at(&mut target, text, written)?;
            written += text.len() as u64;
            buffered += text.len() as u64;
            if let Target::Temporary(temp) = &target
                && buffered - synced >= SYNC_EVERY
            {
                temp.as_file().sync_data()?;
                synced = buffered;
            }
        }
        // The caller may have finished: a chunk nobody takes back is simply freed.
        let _ = spare.send(chunk);
    }
    if let Target::Temporary(temp) = &mut target {
        // What the caller writes after the chunks (`commit`) follows them.
        use std::io::Seek;
        temp.as_file_mut().seek(io::SeekFrom::Start(written))?;
    }
    Ok(target)
}

/// Writes `text` to `target` at `offset`, the number of bytes written before: a temporary
/// file at that offset (unbuffered writes do not move its position), anything else where it
/// stands.
fn write_at(target: &mut Target, text: &[u8], offset: u64) -> io::Result<()> {
    #[cfg(unix)]
    if let Target::Temporary(temp) = target {
        use std::os::unix::fs::FileExt;
        return temp.as_file().write_all_at(text, offset);
    }
    let _ = offset;
    target.write_all(text)
}

/// A second handle on a temporary file that writes past the page cache (`O_DIRECT`, Linux):
/// whole pages from page-aligned memory at page-aligned offsets only.
struct Unbuffered {
    #[cfg(target_os = "linux")]
    file: std::fs::File,
}

impl Unbuffered {
    /// The handle, when the file system allows unbuffered writes to `temp` and the path still
    /// names the same file; `None` otherwise (and on other systems).
    #[cfg(target_os = "linux")]
    fn open(temp: &tempfile::NamedTempFile) -> Option<Self> {
        use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
        let file = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_DIRECT)
            .open(temp.path())
            .ok()?;
        let (ours, opened) = (temp.as_file().metadata().ok()?, file.metadata().ok()?);
        ((ours.dev(), ours.ino()) == (opened.dev(), opened.ino())).then_some(Self { file })
    }

    #[cfg(not(target_os = "linux"))]
    fn open(_temp: &tempfile::NamedTempFile) -> Option<Self> {
        None
    }

    /// Whether `text` at `offset` may be written unbuffered: page-aligned in memory, in the
    /// file and in length.
    fn fits(&self, text: &[u8], offset: u64) -> bool {
        let page = PAGE as u64;
        text.as_ptr().addr().is_multiple_of(PAGE)
            && text.len().is_multiple_of(PAGE)
            && offset.is_multiple_of(page)
    }

    /// Writes `text` at `offset`.
    #[cfg(target_os = "linux")]
    fn write(&self, text: &[u8], offset: u64) -> io::Result<()> {
        use std::os::unix::fs::FileExt;
        self.file.write_all_at(text, offset)
    }

    #[cfg(not(target_os = "linux"))]
    fn write(&self, _text: &[u8], _offset: u64) -> io::Result<()> {
        Err(io::Error::from(io::ErrorKind::Unsupported))
    }
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
        let (buf, start) = chunk_buffer(None);
        Self { buf, start, sink: Some(Sink::Here(target)), path: path.to_owned() }
    }

    /// Hands the buffer to the writer thread; a writer that stopped returns its error.
    fn send(&mut self) -> io::Result<()> {
        let sink = self.sink.as_mut().expect("present until commit or drop");
        if sink.send(&mut self.buf, &mut self.start).is_ok() {
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
        target.write_all(&self.buf[self.start..]).map_err(|e| naming(&path, e))?;
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
        if self.buf.len() - self.start >= CHUNK {
            self.send()?;
        }
        Ok(buf.len())
    }

    /// Hands what is buffered to the writer (it reaches the file asynchronously; `commit`
    /// waits for all of it).
    fn flush(&mut self) -> io::Result<()> {
        if self.buf.len() == self.start || self.sink.is_none() { Ok(()) } else { self.send() }
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

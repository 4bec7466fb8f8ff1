//! Files opened and written on a user's behalf, safe against the ways a path can surprise.
//!
//! - **Reading** ([`open_regular`]): a path is opened without blocking and refused unless it
//!   is a regular file, so a FIFO, socket or device named as a bag, a split file or a config
//!   is refused by name instead of blocking `open()` forever or never ending.
//! - **Writing** ([`NewFile`]): an output is written into a file that has no name yet (Linux
//!   `O_TMPFILE`, in the output's own directory) and given its name only once it is complete
//!   ([`NewFile::commit`]: linked beside under a fresh hidden name, then renamed over the
//!   target). So a killed run leaves nothing behind, a reader never sees half a file, an
//!   existing file is replaced only by a complete one, and a link planted at the output's
//!   path or at any name the writer might use is replaced, never written through. Where the
//!   file system has no `O_TMPFILE` (or `/proc` is not mounted) the file is created new
//!   (`O_EXCL`, which never follows a link) under a hidden name beside the target and
//!   removed if the writer is dropped; only a kill at that moment can leave it.
//! - **Staged directories** ([`stage_dir`], [`replace_dir`]): a directory output (a rosbag2
//!   bag) is assembled under a hidden name beside its target and renamed into place.
//! - **Identity** ([`FileId`]): two paths name the same file when they resolve to the same
//!   device and inode, whatever links or spellings lead there.
//! - **Room** ([`free_bytes`]): the space left on a file system, so that a temporary copy can
//!   be capped by what the disk can take.

use std::ffi::CString;
use std::fs::{File, Metadata};
use std::io;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::{FileTypeExt, MetadataExt, OpenOptionsExt};
use std::os::unix::io::AsRawFd;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// What a path that is not a regular file is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpecialKind {
    /// A directory.
    Directory,
    /// A FIFO (named pipe): opening it blocks until a writer comes.
    Fifo,
    /// A socket.
    Socket,
    /// A character device (`/dev/zero` never ends).
    CharDevice,
    /// A block device.
    BlockDevice,
    /// Something else.
    Other,
}

impl SpecialKind {
    /// The kind of a file that is not a regular file.
    pub fn of(meta: &Metadata) -> Option<Self> {
        let t = meta.file_type();
        if t.is_file() {
            None
        } else if t.is_dir() {
            Some(Self::Directory)
        } else if t.is_fifo() {
            Some(Self::Fifo)
        } else if t.is_socket() {
            Some(Self::Socket)
        } else if t.is_char_device() {
            Some(Self::CharDevice)
        } else if t.is_block_device() {
            Some(Self::BlockDevice)
        } else {
            Some(Self::Other)
        }
    }
}

impl std::fmt::Display for SpecialKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Directory => "a directory",
            Self::Fifo => "a FIFO (named pipe)",
            Self::Socket => "a socket",
            Self::CharDevice => "a character device",
            Self::BlockDevice => "a block device",
            Self::Other => "not a regular file",
        })
    }
}

/// Why a file cannot be opened for reading.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The operating system refused.
    #[error("{0}")]
    Io(#[from] io::Error),
    /// The path names something other than a regular file.
    #[error("it is {0}, not a regular file (it could block or never end); give a file")]
    Special(SpecialKind),
}

impl OpenError {
    /// True if the file does not exist.
    pub fn is_not_found(&self) -> bool {
        matches!(self, Self::Io(e) if e.kind() == io::ErrorKind::NotFound)
    }
}

/// Opens `path` for reading if it is a regular file (following links). The open itself does
/// not block (`O_NONBLOCK`, cleared once the file is known to be regular), so a FIFO is
/// refused at once instead of waiting for a writer.
///
/// # Errors
/// [`OpenError::Io`] if it cannot be opened, [`OpenError::Special`] for anything but a
/// regular file.
pub fn open_regular(path: &Path) -> Result<File, OpenError> {
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_CLOEXEC)
        .open(path)?;
    let meta = file.metadata()?;
    if let Some(kind) = SpecialKind::of(&meta) {
        return Err(OpenError::Special(kind));
    }
    let fd = file.as_raw_fd();
    // SAFETY: fcntl on a descriptor this function owns; only the status flags change.
    unsafe {
        let flags = libc::fcntl(fd, libc::F_GETFL);
        if flags >= 0 {
            libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK);
        }
    }
    Ok(file)
}

/// The device and inode of a file: two paths with the same id name the same file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FileId {
    dev: u64,
    ino: u64,
}

impl FileId {
    /// The id of what `meta` describes.
    pub fn of(meta: &Metadata) -> Self {
        Self {
            dev: meta.dev(),
            ino: meta.ino(),
        }
    }

    /// The id of the file `path` leads to (following links), if it exists.
    pub fn of_path(path: &Path) -> Option<Self> {
        std::fs::metadata(path).ok().map(|m| Self::of(&m))
    }
}

/// Bytes free for an unprivileged user on the file system holding `dir`, if it can be asked.
pub fn free_bytes(dir: &Path) -> Option<u64> {
    let c = CString::new(dir.as_os_str().as_bytes()).ok()?;
    let mut s = std::mem::MaybeUninit::<libc::statvfs>::uninit();
    // SAFETY: statvfs writes the struct on success; it is read only then.
    let r = unsafe { libc::statvfs(c.as_ptr(), s.as_mut_ptr()) };
    if r != 0 {
        return None;
    }
    // SAFETY: statvfs returned 0, so the struct is initialised.
    let s = unsafe { s.assume_init() };
    Some((s.f_bavail as u64).saturating_mul(s.f_frsize as u64))
}

/// The directory a path's file lies in (`.` for a bare name).
pub fn parent_dir(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// A hidden name beside `target` that nothing has yet: `.<name>.<pid>-<n>.<suffix>`.
fn hidden_name(target: &Path, suffix: &str) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".to_owned());
    parent_dir(target).join(format!(
        ".{name}.{}-{n}-{nanos:08x}.{suffix}",
        std::process::id()
    ))
}

/// How a [`NewFile`]'s content waits for its name.
#[derive(Debug)]
enum Staged {
    /// An `O_TMPFILE` file: no name at all until committed.
    Unnamed,
    /// A file created new under a hidden name beside the target (removed if not committed).
    Named(PathBuf),
    /// Committed or given up.
    Done,
}

/// A file being written that takes its name only once complete (see the module
/// documentation): dropping it without [`commit`](Self::commit) leaves nothing.
#[derive(Debug)]
pub struct NewFile {
    file: File,
    target: PathBuf,
    staged: Staged,
}

impl NewFile {
    /// Starts the file that will become `target`. Its directory must exist.
    ///
    /// # Errors
    /// The directory cannot take a new file.
    pub fn create(target: &Path) -> io::Result<Self> {
        Self::create_staged_in(target, parent_dir(target))
    }

    /// Starts the file that will become `target`, its content kept meanwhile in `stage_dir`
    /// (on the same file system as `target`: a directory output not yet made is staged in
    /// its parent).
    ///
    /// # Errors
    /// `stage_dir` cannot take a new file.
    pub fn create_staged_in(target: &Path, stage_dir: &Path) -> io::Result<Self> {
        if proc_fd_available() {
            match open_unnamed(stage_dir) {
                Ok(file) => {
                    return Ok(Self {
                        file,
                        target: target.to_path_buf(),
                        staged: Staged::Unnamed,
                    })
                }
                // No O_TMPFILE on this file system (or kernel): a hidden named file instead.
                Err(e)
                    if matches!(
                        e.raw_os_error(),
                        Some(libc::EOPNOTSUPP | libc::EISDIR | libc::EINVAL | libc::ENOSYS)
                    ) => {}
                Err(e) => return Err(e),
            }
        }
        let (file, path) = create_hidden_beside(
            &stage_dir.join(
                target
                    .file_name()
                    .unwrap_or_else(|| std::ffi::OsStr::new("output")),
            ),
        )?;
        Ok(Self {
            file,
            target: target.to_path_buf(),
            staged: Staged::Named(path),
        })
    }

    /// The file, to write into.
    pub fn file(&mut self) -> &mut File {
        &mut self.file
    }

    /// The path the file will have.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Gives the complete file its name, replacing whatever `target` named (a link there is
    /// replaced, not followed).
    ///
    /// # Errors
    /// The file cannot be linked or renamed into place (nothing is left behind then).
    pub fn commit(mut self) -> io::Result<()> {
        let target = self.target.clone();
        self.commit_as(&target)
    }

    /// As [`commit`](Self::commit), under another path than the target given at creation
    /// (a directory output links its files into its staging directory).
    ///
    /// # Errors
    /// As [`commit`](Self::commit).
    pub fn commit_as(&mut self, target: &Path) -> io::Result<()> {
        use std::io::Write;
        self.file.flush()?;
        match std::mem::replace(&mut self.staged, Staged::Done) {
            Staged::Unnamed => {
                let temp = link_unnamed(&self.file, target)?;
                std::fs::rename(&temp, target).inspect_err(|_| {
                    let _ = std::fs::remove_file(&temp);
                })
            }
            Staged::Named(path) => std::fs::rename(&path, target).inspect_err(|_| {
                let _ = std::fs::remove_file(&path);
            }),
            Staged::Done => Err(io::Error::other("the file was already committed")),
        }
    }
}

impl Drop for NewFile {
    fn drop(&mut self) {
        if let Staged::Named(path) = &self.staged {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// Whether `/proc/self/fd` can name an open file (needed to link an `O_TMPFILE` file).
fn proc_fd_available() -> bool {
    static AVAILABLE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVAILABLE.get_or_init(|| Path::new("/proc/self/fd").is_dir())
}

/// The path under which `/proc` names an open file of this process.
pub fn proc_path(file: &File) -> Option<PathBuf> {
    proc_fd_available().then(|| PathBuf::from(format!("/proc/self/fd/{}", file.as_raw_fd())))
}

/// Opens a file without a name in `dir` (`O_TMPFILE`), readable and writable, with the
/// permissions a new file gets (0666 less the umask).
fn open_unnamed(dir: &Path) -> io::Result<File> {
    let c = CString::new(dir.as_os_str().as_bytes())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "a NUL byte in the path"))?;
    // SAFETY: open with a valid C string; the descriptor returned is owned by the File.
    let fd = unsafe {
        libc::open(
            c.as_ptr(),
            libc::O_TMPFILE | libc::O_RDWR | libc::O_CLOEXEC,
            0o666 as libc::c_uint,
        )
    };
    if fd < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: fd is a fresh descriptor nothing else owns.
    Ok(unsafe { <File as std::os::unix::io::FromRawFd>::from_raw_fd(fd) })
}

/// Gives an unnamed file a fresh hidden name beside `target` (never an existing name);
/// returns that name.
fn link_unnamed(file: &File, target: &Path) -> io::Result<PathBuf> {
    let from = CString::new(format!("/proc/self/fd/{}", file.as_raw_fd()))
        .map_err(|_| io::Error::other("a descriptor path with a NUL byte"))?;
    for _ in 0..64 {
        let temp = hidden_name(target, "part");
        let to = CString::new(temp.as_os_str().as_bytes())
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "a NUL byte in the path"))?;
        // SAFETY: linkat with valid C strings; AT_SYMLINK_FOLLOW resolves the /proc link to
        // the open file itself.
        let r = unsafe {
            libc::linkat(
                libc::AT_FDCWD,
                from.as_ptr(),
                libc::AT_FDCWD,
                to.as_ptr(),
                libc::AT_SYMLINK_FOLLOW,
            )
        };
        if r == 0 {
            return Ok(temp);
        }
        let e = io::Error::last_os_error();
        if e.kind() != io::ErrorKind::AlreadyExists {
            return Err(e);
        }
    }
    Err(io::Error::new(
        io::ErrorKind::AlreadyExists,
        "no free hidden name beside the output",
    ))
}

/// Creates a new file under a hidden name beside `target` (`O_EXCL`: an existing name or a
/// link there is never opened); returns it and its name.
///
/// # Errors
/// The directory cannot take a new file.
pub fn create_hidden_beside(target: &Path) -> io::Result<(File, PathBuf)> {
    for _ in 0..64 {
        let path = hidden_name(target, "part");
        match std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .custom_flags(libc::O_CLOEXEC)
            .open(&path)
        {
            Ok(f) => return Ok((f, path)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(io::Error::new(
        io::ErrorKind::AlreadyExists,
        "no free hidden name beside the output",
    ))
}

/// Makes a new, empty staging directory beside `target` (a hidden name nothing has).
///
/// # Errors
/// The parent directory cannot take it.
pub fn stage_dir(target: &Path) -> io::Result<PathBuf> {
    for _ in 0..64 {
        let path = hidden_name(target, "part");
        match std::fs::create_dir(&path) {
            Ok(()) => return Ok(path),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(io::Error::new(
        io::ErrorKind::AlreadyExists,
        "no free hidden name beside the output",
    ))
}

/// Moves the complete directory `staged` to `target`. An existing `target` (which the caller
/// has checked may be replaced: empty, or a bag it may replace) is moved aside first and
/// removed once `staged` is in its place.
///
/// # Errors
/// A rename fails (the staged directory is removed then, and an old target put back).
pub fn replace_dir(staged: &Path, target: &Path) -> io::Result<()> {
    let old = match std::fs::symlink_metadata(target) {
        Err(e) if e.kind() == io::ErrorKind::NotFound => None,
        Err(e) => return Err(e),
        Ok(_) => {
            let old = hidden_name(target, "old");
            std::fs::rename(target, &old)?;
            Some(old)
        }
    };
    if let Err(e) = std::fs::rename(staged, target) {
        if let Some(old) = &old {
            let _ = std::fs::rename(old, target);
        }
        let _ = std::fs::remove_dir_all(staged);
        return Err(e);
    }
    if let Some(old) = old {
        let meta = std::fs::symlink_metadata(&old)?;
        if meta.is_dir() {
            std::fs::remove_dir_all(&old)?;
        } else {
            std::fs::remove_file(&old)?;
        }
    }
    Ok(())
}

/// Writes `bytes` as the file `target` through a [`NewFile`] (complete or not at all).
///
/// # Errors
/// The file cannot be created, written or renamed into place.
pub fn write_atomic(target: &Path, bytes: &[u8]) -> io::Result<()> {
    use std::io::Write;
    let mut f = NewFile::create(target)?;
    f.file().write_all(bytes)?;
    f.commit()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn listing(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_new_file_has_no_name_until_committed() {
        let d = tempfile::tempdir().unwrap();
        let target = d.path().join("out.bin");
        let mut f = NewFile::create(&target).unwrap();
        f.file().write_all(b"complete").unwrap();
        assert!(listing(d.path()).is_empty(), "{:?}", listing(d.path()));
        f.commit().unwrap();
        assert_eq!(listing(d.path()), ["out.bin"]);
        assert_eq!(std::fs::read(&target).unwrap(), b"complete");
    }

    #[test]
    fn a_dropped_file_leaves_nothing_and_the_old_one_stays() {
        let d = tempfile::tempdir().unwrap();
        let target = d.path().join("out.bin");
        std::fs::write(&target, b"old").unwrap();
        {
            let mut f = NewFile::create(&target).unwrap();
            f.file().write_all(b"half").unwrap();
        }
        assert_eq!(listing(d.path()), ["out.bin"]);
        assert_eq!(std::fs::read(&target).unwrap(), b"old");
    }

    #[test]
    fn a_link_at_the_target_is_replaced_not_written_through() {
        let d = tempfile::tempdir().unwrap();
        let outside = d.path().join("outside.txt");
        std::fs::write(&outside, b"precious").unwrap();
        let sub = d.path().join("out");
        std::fs::create_dir(&sub).unwrap();
        let target = sub.join("report.json");
        std::os::unix::fs::symlink(&outside, &target).unwrap();
        write_atomic(&target, b"{}").unwrap();
        assert_eq!(std::fs::read(&outside).unwrap(), b"precious");
        assert!(!std::fs::symlink_metadata(&target)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(&target).unwrap(), b"{}");
    }

    #[test]
    fn a_hidden_name_already_taken_by_a_link_is_never_opened() {
        let d = tempfile::tempdir().unwrap();
        let outside = d.path().join("outside.txt");
        std::fs::write(&outside, b"precious").unwrap();
        let target = d.path().join("x");
        // The fallback's names: a link planted at one is skipped, not followed.
        let planted = hidden_name(&target, "part");
        std::os::unix::fs::symlink(&outside, &planted).unwrap();
        let (mut f, path) = create_hidden_beside(&target).unwrap();
        assert_ne!(path, planted);
        f.write_all(b"new").unwrap();
        assert_eq!(std::fs::read(&outside).unwrap(), b"precious");
    }

    #[test]
    fn fifos_and_directories_are_refused_without_blocking() {
        let d = tempfile::tempdir().unwrap();
        let fifo = d.path().join("bag.mcap");
        let c = CString::new(fifo.as_os_str().as_bytes()).unwrap();
        // SAFETY: mkfifo with a valid C string.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
        assert!(matches!(
            open_regular(&fifo),
            Err(OpenError::Special(SpecialKind::Fifo))
        ));
        assert!(matches!(
            open_regular(d.path()),
            Err(OpenError::Special(SpecialKind::Directory))
        ));
        let dev = open_regular(Path::new("/dev/zero")).unwrap_err();
        assert!(dev.to_string().contains("character device"), "{dev}");
    }

    #[test]
    fn a_staged_directory_replaces_the_old_one_whole() {
        let d = tempfile::tempdir().unwrap();
        let target = d.path().join("bag");
        std::fs::create_dir(&target).unwrap();
        std::fs::write(target.join("old.mcap"), b"old").unwrap();
        let staged = stage_dir(&target).unwrap();
        std::fs::write(staged.join("new.mcap"), b"new").unwrap();
        replace_dir(&staged, &target).unwrap();
        assert_eq!(listing(&target), ["new.mcap"]);
        assert_eq!(listing(d.path()), ["bag"]);
    }

    #[test]
    fn identity_sees_through_links() {
        let d = tempfile::tempdir().unwrap();
        let a = d.path().join("a");
        std::fs::write(&a, b"x").unwrap();
        std::os::unix::fs::symlink(&a, d.path().join("l")).unwrap();
        std::fs::hard_link(&a, d.path().join("h")).unwrap();
        let id = FileId::of_path(&a).unwrap();
        assert_eq!(FileId::of_path(&d.path().join("l")), Some(id));
        assert_eq!(FileId::of_path(&d.path().join("h")), Some(id));
        assert!(free_bytes(d.path()).is_some_and(|b| b > 0));
    }
}

//! File operations confined to one directory: what funcorr deletes, renames or opens in a
//! directory whose contents it does not control (an output directory, the eigenbasis cache)
//! resolves only beneath that directory.
//!
//! - [`Dir`] is a directory opened once; its subdirectories are entered one component at a time
//!   without following a symbolic link (`openat` with `O_NOFOLLOW | O_DIRECTORY` on Unix), and
//!   files are removed, renamed into it and inspected relative to that handle (`unlinkat`,
//!   `renameat`, `fstatat` with `AT_SYMLINK_NOFOLLOW`). A link swapped in for a directory while a
//!   run works is refused, never followed. Elsewhere than Unix the same checks are made on paths
//!   (`symlink_metadata` before each step).
//! - [`open_regular`] and [`open_lock`] open a file only when it is a regular file: never through
//!   a link (`O_NOFOLLOW`) and without blocking (`O_NONBLOCK`, then `fstat`), so that a FIFO or a
//!   device in place of a cache entry or a lock file is an error, not a hang.

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// What a directory entry is, seen without following a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    /// A regular file.
    File,
    /// A directory.
    Dir,
    /// A symbolic link (never followed).
    Symlink,
    /// A FIFO, socket or device.
    Other,
}

impl Kind {
    fn of(t: std::fs::FileType) -> Kind {
        if t.is_symlink() {
            Kind::Symlink
        } else if t.is_dir() {
            Kind::Dir
        } else if t.is_file() {
            Kind::File
        } else {
            Kind::Other
        }
    }
}

/// The error for an entry of the wrong kind at `path` (`what` says what was expected).
pub(crate) fn wrong_kind(path: &Path, kind: Kind, what: &str) -> Error {
    let found = match kind {
        Kind::Symlink => "a symbolic link (funcorr never follows links in its output or cache directories)",
        Kind::Dir => "a directory",
        Kind::File => "a regular file",
        Kind::Other => "a FIFO, socket or device",
    };
    Error::io(path, std::io::Error::other(format!("expected {what}, found {found}; remove it or choose another path")))
}

/// Opens `path` for reading only when it is a regular file: a symbolic link is refused
/// (`O_NOFOLLOW`), a FIFO or device is opened without blocking (`O_NONBLOCK`) and refused after
/// `fstat`. For files in directories the user does not write by hand (cache entries, manifests).
///
/// Errors: [`Error::Io`] naming `path`.
pub(crate) fn open_regular(path: &Path) -> Result<File> {
    let mut o = std::fs::OpenOptions::new();
    o.read(true);
    no_follow_no_block(&mut o);
    let file = o.open(path).map_err(|e| refine_open_error(path, e, "a regular file"))?;
    check_regular(path, &file)?;
    Ok(file)
}

/// Opens (creating it when absent) the lock file `path` for writing, only as a regular file:
/// never through a symbolic link (a dangling link is not created either), never blocking on a
/// FIFO. Errors: [`Error::Io`] naming `path`.
pub(crate) fn open_lock(path: &Path) -> Result<File> {
    let mut o = std::fs::OpenOptions::new();
    o.create(true).truncate(false).write(true);
    no_follow_no_block(&mut o);
    let file = o.open(path).map_err(|e| refine_open_error(path, e, "a regular lock file"))?;
    check_regular(path, &file)?;
    Ok(file)
}

#[cfg(unix)]
fn no_follow_no_block(o: &mut std::fs::OpenOptions) {
    use std::os::unix::fs::OpenOptionsExt;
    o.custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK | libc::O_CLOEXEC);
}

#[cfg(not(unix))]
fn no_follow_no_block(_: &mut std::fs::OpenOptions) {}

/// An open that failed because of what is at `path` says so (a link, a FIFO without a writer).
fn refine_open_error(path: &Path, e: std::io::Error, what: &str) -> Error {
    match std::fs::symlink_metadata(path) {
        Ok(m) if !m.file_type().is_file() => wrong_kind(path, Kind::of(m.file_type()), what),
        _ => Error::io(path, e),
    }
}

fn check_regular(path: &Path, file: &File) -> Result<()> {
    let m = file.metadata().map_err(|e| Error::io(path, e))?;
    if !m.file_type().is_file() {
        return Err(wrong_kind(path, Kind::of(m.file_type()), "a regular file"));
    }
    // Elsewhere than Unix the open itself may have followed a link: check the path too.
    #[cfg(not(unix))]
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
        return Err(wrong_kind(path, Kind::Symlink, "a regular file"));
    }
    Ok(())
}

/// A directory opened once; every operation below it resolves one component at a time without
/// following a symbolic link (see the module documentation).
#[derive(Debug)]
pub(crate) struct Dir {
    /// The directory's path, for error messages (and the operations elsewhere than Unix).
    path: PathBuf,
    #[cfg(unix)]
    fd: std::os::fd::OwnedFd,
}

/// `name` as one path component: not empty, no separator, not `.` or `..`, no NUL.
fn check_name(dir: &Path, name: &str) -> Result<()> {
    if name.is_empty() || name == "." || name == ".." || name.contains(['/', '\\', '\0']) {
        let e = std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a plain file name");
        return Err(Error::io(dir.join(crate::error::escape(name).as_ref()), e));
    }
    Ok(())
}

#[cfg(unix)]
mod sys {
    use std::ffi::CString;
    use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};

    pub(super) fn cstr(name: &str) -> std::io::Result<CString> {
        CString::new(name).map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "NUL in a file name"))
    }

    fn check(r: libc::c_int) -> std::io::Result<libc::c_int> {
        if r < 0 {
            Err(std::io::Error::last_os_error())
        } else {
            Ok(r)
        }
    }

    /// `openat(dir, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW)`, or the cwd-relative open of a
    /// whole path when `dir` is None (the anchor, which the caller named).
    pub(super) fn open_dir(dir: Option<&OwnedFd>, name: &std::path::Path) -> std::io::Result<OwnedFd> {
        use std::os::unix::ffi::OsStrExt;
        let c = CString::new(name.as_os_str().as_bytes())
            .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "NUL in a path"))?;
        let (at, extra) = match dir {
            Some(d) => (d.as_raw_fd(), libc::O_NOFOLLOW),
            None => (libc::AT_FDCWD, 0),
        };
        // SAFETY: `c` is a valid NUL-terminated string; `at` is an open directory or AT_FDCWD.
        let fd = check(unsafe {
            libc::openat(at, c.as_ptr(), libc::O_RDONLY | libc::O_DIRECTORY | libc::O_CLOEXEC | extra)
        })?;
        // SAFETY: `fd` was just returned by openat and is owned by nobody else.
        Ok(unsafe { OwnedFd::from_raw_fd(fd) })
    }

    /// The file type of `name` in `dir` without following a link (`fstatat`), None when absent.
    pub(super) fn kind(dir: &OwnedFd, name: &str) -> std::io::Result<Option<libc::mode_t>> {
        let c = cstr(name)?;
        let mut st = std::mem::MaybeUninit::<libc::stat>::uninit();
        // SAFETY: valid string, valid directory fd, `st` is written by fstatat on success.
        let r = unsafe { libc::fstatat(dir.as_raw_fd(), c.as_ptr(), st.as_mut_ptr(), libc::AT_SYMLINK_NOFOLLOW) };
        if r < 0 {
            let e = std::io::Error::last_os_error();
            return match e.kind() {
                std::io::ErrorKind::NotFound => Ok(None),
                _ => Err(e),
            };
        }
        // SAFETY: fstatat succeeded, so `st` is initialized.
        Ok(Some(unsafe { st.assume_init() }.st_mode & libc::S_IFMT))
    }

    pub(super) fn mkdir(dir: &OwnedFd, name: &str) -> std::io::Result<()> {
        let c = cstr(name)?;
        // SAFETY: valid string and directory fd.
        check(unsafe { libc::mkdirat(dir.as_raw_fd(), c.as_ptr(), 0o777) }).map(drop)
    }

    pub(super) fn unlink(dir: &OwnedFd, name: &str, remove_dir: bool) -> std::io::Result<()> {
        let c = cstr(name)?;
        let flags = if remove_dir { libc::AT_REMOVEDIR } else { 0 };
        // SAFETY: valid string and directory fd.
        check(unsafe { libc::unlinkat(dir.as_raw_fd(), c.as_ptr(), flags) }).map(drop)
    }

    pub(super) fn rename(from: &std::path::Path, dir: &OwnedFd, name: &str) -> std::io::Result<()> {
        use std::os::unix::ffi::OsStrExt;
        let f = CString::new(from.as_os_str().as_bytes())
            .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "NUL in a path"))?;
        let c = cstr(name)?;
        // SAFETY: valid strings, AT_FDCWD and a valid directory fd.
        check(unsafe { libc::renameat(libc::AT_FDCWD, f.as_ptr(), dir.as_raw_fd(), c.as_ptr()) }).map(drop)
    }
}

impl Dir {
    /// Opens the directory `path` (links in `path` itself are followed: the caller named it).
    ///
    /// Errors: [`Error::Io`] naming `path`.
    pub(crate) fn open(path: &Path) -> Result<Dir> {
        #[cfg(unix)]
        {
            let fd = sys::open_dir(None, path).map_err(|e| Error::io(path, e))?;
            Ok(Dir { path: path.to_path_buf(), fd })
        }
        #[cfg(not(unix))]
        {
            match std::fs::metadata(path) {
                Ok(m) if m.is_dir() => Ok(Dir { path: path.to_path_buf() }),
                Ok(m) => Err(wrong_kind(path, Kind::of(m.file_type()), "a directory")),
                Err(e) => Err(Error::io(path, e)),
            }
        }
    }

    /// Another handle on the same directory.
    pub(crate) fn try_clone(&self) -> Result<Dir> {
        #[cfg(unix)]
        {
            let fd = self.fd.try_clone().map_err(|e| Error::io(&self.path, e))?;
            Ok(Dir { path: self.path.clone(), fd })
        }
        #[cfg(not(unix))]
        {
            Ok(Dir { path: self.path.clone() })
        }
    }

    /// The directory's path (for messages).
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// What `name` (one component) is, without following a link; None when it does not exist.
    pub(crate) fn kind(&self, name: &str) -> Result<Option<Kind>> {
        check_name(&self.path, name)?;
        #[cfg(unix)]
        {
            let mode = sys::kind(&self.fd, name).map_err(|e| Error::io(self.path.join(name), e))?;
            Ok(mode.map(|m| match m {
                libc::S_IFREG => Kind::File,
                libc::S_IFDIR => Kind::Dir,
                libc::S_IFLNK => Kind::Symlink,
                _ => Kind::Other,
            }))
        }
        #[cfg(not(unix))]
        {
            match std::fs::symlink_metadata(self.path.join(name)) {
                Ok(m) => Ok(Some(Kind::of(m.file_type()))),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
                Err(e) => Err(Error::io(self.path.join(name), e)),
            }
        }
    }

    /// The subdirectory `name`, entered without following a link. `Ok(None)` when it does not
    /// exist and `create` is false; created when absent and `create` is true.
    ///
    /// Errors: [`Error::Io`] naming the entry when it is a symbolic link or not a directory.
    pub(crate) fn subdir(&self, name: &str, create: bool) -> Result<Option<Dir>> {
        let path = self.path.join(name);
        match self.kind(name)? {
            Some(Kind::Dir) => {}
            None if create => {
                #[cfg(unix)]
                let made = sys::mkdir(&self.fd, name);
                #[cfg(not(unix))]
                let made = std::fs::create_dir(&path);
                match made {
                    Ok(()) => {}
                    Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
                    Err(e) => return Err(Error::io(&path, e)),
                }
            }
            None => return Ok(None),
            Some(k) => return Err(wrong_kind(&path, k, "a directory")),
        }
        #[cfg(unix)]
        {
            // O_NOFOLLOW: a link swapped in since the check above is refused, not followed.
            match sys::open_dir(Some(&self.fd), Path::new(name)) {
                Ok(fd) => Ok(Some(Dir { path, fd })),
                Err(e) => match self.kind(name)? {
                    Some(k) if k != Kind::Dir => Err(wrong_kind(&path, k, "a directory")),
                    _ => Err(Error::io(&path, e)),
                },
            }
        }
        #[cfg(not(unix))]
        {
            match self.kind(name)? {
                Some(Kind::Dir) => Ok(Some(Dir { path })),
                Some(k) => Err(wrong_kind(&path, k, "a directory")),
                None => Err(Error::io(&path, std::io::Error::from(std::io::ErrorKind::NotFound))),
            }
        }
    }

    /// Removes the entry `name` (a file or a link itself, never what a link points to).
    pub(crate) fn remove_file(&self, name: &str) -> Result<()> {
        check_name(&self.path, name)?;
        let path = self.path.join(name);
        #[cfg(unix)]
        let r = sys::unlink(&self.fd, name, false);
        #[cfg(not(unix))]
        let r = std::fs::remove_file(&path);
        r.map_err(|e| Error::io(path, e))
    }

    /// Removes the subdirectory `name` if it is empty; false when it stays (not empty, absent).
    pub(crate) fn remove_empty_dir(&self, name: &str) -> bool {
        if check_name(&self.path, name).is_err() {
            return false;
        }
        #[cfg(unix)]
        let r = sys::unlink(&self.fd, name, true);
        #[cfg(not(unix))]
        let r = match self.kind(name) {
            Ok(Some(Kind::Dir)) => std::fs::remove_dir(self.path.join(name)),
            _ => Err(std::io::Error::from(std::io::ErrorKind::NotFound)),
        };
        r.is_ok()
    }

    /// Renames the file `from` (anywhere on the same file system) to `name` in this directory,
    /// replacing an entry of that name (a link is replaced, not followed).
    pub(crate) fn rename_into(&self, from: &Path, name: &str) -> Result<()> {
        check_name(&self.path, name)?;
        let path = self.path.join(name);
        #[cfg(unix)]
        let r = sys::rename(from, &self.fd, name);
        #[cfg(not(unix))]
        let r = std::fs::rename(from, &path);
        r.map_err(|e| Error::io(path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_util::tmp_dir;

    #[cfg(unix)]
    fn fifo(p: &Path) {
        let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
        // SAFETY: valid path string.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    }

    #[cfg(unix)]
    #[test]
    fn links_and_fifos_are_refused_without_blocking() {
        let d = tmp_dir("beneath_kinds");
        let outside = d.join("outside");
        std::fs::create_dir_all(outside.join("sub")).unwrap();
        std::fs::write(outside.join("sub/v.txt"), "keep").unwrap();
        let root = d.join("root");
        std::fs::create_dir_all(&root).unwrap();
        std::os::unix::fs::symlink(&outside, root.join("link")).unwrap();
        std::os::unix::fs::symlink(d.join("created-through-link"), root.join("dangling")).unwrap();
        fifo(&root.join("fifo"));
        std::fs::write(root.join("plain"), "x").unwrap();

        let dir = Dir::open(&root).unwrap();
        assert_eq!(dir.kind("link").unwrap(), Some(Kind::Symlink));
        assert_eq!(dir.kind("fifo").unwrap(), Some(Kind::Other));
        assert_eq!(dir.kind("plain").unwrap(), Some(Kind::File));
        assert_eq!(dir.kind("absent").unwrap(), None);
        let e = dir.subdir("link", false).unwrap_err().to_string();
        assert!(e.contains("link") && e.contains("symbolic link"), "{e}");
        assert!(dir.subdir("link", true).is_err());
        assert!(dir.subdir("absent", false).unwrap().is_none());
        let sub = dir.subdir("made", true).unwrap().unwrap();
        assert!(root.join("made").is_dir() && sub.path().ends_with("made"));
        for bad in ["", ".", "..", "a/b", "../x", "nul\0"] {
            assert!(dir.kind(bad).is_err(), "{bad:?}");
            assert!(dir.remove_file(bad).is_err(), "{bad:?}");
        }
        // Removing a link removes the link, never its target.
        dir.remove_file("link").unwrap();
        assert!(outside.join("sub/v.txt").exists());
        assert!(dir.remove_empty_dir("made") && !root.join("made").exists());

        // Regular files only, never blocking.
        let e = open_regular(&root.join("fifo")).unwrap_err().to_string();
        assert!(e.contains("FIFO"), "{e}");
        let e = open_lock(&root.join("fifo")).unwrap_err().to_string();
        assert!(e.contains("FIFO"), "{e}");
        let e = open_lock(&root.join("dangling")).unwrap_err().to_string();
        assert!(e.contains("symbolic link"), "{e}");
        assert!(!d.join("created-through-link").exists(), "the lock followed a dangling link");
        assert!(open_regular(&root.join("plain")).is_ok());
        assert!(open_lock(&root.join("new.lock")).is_ok() && root.join("new.lock").is_file());
    }
}

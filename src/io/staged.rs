//! Output directories published whole: a run writes into a private staging directory and
//! moves its files into place only when all of them are written.
//!
//! Protocol (what a reader of an output directory can rely on):
//! 1. While a run works, its files live in `<dir>/.funcorr-staging.<pid>-<counter>/`; the
//!    visible directory is untouched. A run that fails or is killed before publishing leaves
//!    nothing new in `<dir>` (the staging directory is removed on failure; a killed run leaves only
//!    the hidden staging directory).
//! 2. Publishing, under an exclusive lock on `<dir>/.funcorr.lock` (so two runs into the same
//!    directory publish one after the other, never interleaved): the manifest
//!    `funcorr-manifest.json` of the previous run is removed first, the new files are renamed
//!    into place (each rename atomic), the files the previous manifest listed and this run did not
//!    write are deleted, and the new manifest is written last (atomically).
//! 3. Hence: a directory with a manifest holds exactly the files it lists, all from one run;
//!    no manifest means a publish is in progress or was interrupted. Files the user put in
//!    `<dir>` themselves are never touched: only names listed in a funcorr manifest are deleted.
//! 4. Nothing is deleted, renamed or opened outside `<dir>`: every step resolves one component
//!    at a time below `<dir>` without following a symbolic link (`super::beneath`). A
//!    manifest entry under a link is skipped; a link (or a file) in the way of an output's
//!    directory is an error before anything changes; the lock file and the manifest are opened
//!    only as regular files (never through a link, never blocking on a FIFO).
//! 5. [`StagedDir::create`] runs first, before any computation: a directory that cannot be
//!    created or written, or a lock file that is not a regular file, fails the run at once.

use std::path::{Path, PathBuf};

use super::beneath::{self, Dir, Kind};
use crate::error::{Error, Result};

/// Name of the manifest written last into a published output directory.
pub const MANIFEST: &str = "funcorr-manifest.json";

/// Name of the lock file publishers of one directory take turns on.
const LOCK: &str = ".funcorr.lock";

/// Upper bound on the bytes of a manifest that is read back (a hostile or damaged manifest
/// larger than this is ignored rather than read).
const MAX_MANIFEST_BYTES: u64 = 64 << 20;

/// An output directory being written: files go into [`StagedDir::path`] and appear in the
/// target directory only when [`StagedDir::publish`] succeeds (see the module docs). Dropping
/// it (published or not) removes the staging directory, and, when nothing was published, the
/// target directory too if [`StagedDir::create`] made it and it is empty.
#[derive(Debug)]
pub struct StagedDir {
    target: PathBuf,
    staging: PathBuf,
    /// Whether `create` made `target` (then a run that publishes nothing removes it again).
    created: bool,
}

impl StagedDir {
    /// Creates `target` if needed and a fresh, exclusively created staging directory inside it
    /// (private to the user on Unix). Call it before computing: it is the check that the
    /// output can be written.
    ///
    /// Errors: [`Error::Io`] naming `target` when either cannot be created, or when `target`
    /// exists and is not a directory; naming `target/.funcorr.lock` when that is not a regular
    /// file (a symbolic link, a FIFO, a directory).
    pub fn create(target: &Path) -> Result<StagedDir> {
        use std::sync::atomic::{AtomicU64, Ordering};
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let created = std::fs::symlink_metadata(target).is_err();
        std::fs::create_dir_all(target).map_err(|e| Error::io(target, e))?;
        match Dir::open(target)?.kind(LOCK)? {
            None | Some(Kind::File) => {}
            Some(k) => return Err(beneath::wrong_kind(&target.join(LOCK), k, "a regular lock file")),
        }
        remove_dead_staging(target);
        let mut attempt = 0;
        loop {
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let staging = target.join(format!(".funcorr-staging.{}-{n}", std::process::id()));
            let mut builder = std::fs::DirBuilder::new();
            #[cfg(unix)]
            std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
            match builder.create(&staging) {
                Ok(()) => return Ok(StagedDir { target: target.to_path_buf(), staging, created }),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && attempt < 100 => attempt += 1,
                Err(e) => return Err(Error::io(target, e)),
            }
        }
    }

    /// The directory to write into (inside the target, hidden, removed after publishing).
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// `path().join(rel)`: where to write the output that will be published as `target/rel`.
    pub fn join(&self, rel: impl AsRef<Path>) -> PathBuf {
        self.staging.join(rel)
    }

    /// Where a path inside the staging directory ends up after publishing (other paths are
    /// returned unchanged).
    pub fn published_path(&self, staged: &Path) -> PathBuf {
        match staged.strip_prefix(&self.staging) {
            Ok(rel) => self.target.join(rel),
            Err(_) => staged.to_path_buf(),
        }
    }

    /// Runs `f` on the staging directory and publishes it when `f` succeeds; errors of `f` name
    /// the files as they would be published (see [`StagedDir::attribute`]). On error nothing is
    /// published and the staging directory is removed.
    pub fn write_with<T>(self, f: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
        let value = f(&self.staging).map_err(|e| self.attribute(e))?;
        self.publish()?;
        Ok(value)
    }

    /// Rewrites an error about a file in the staging directory to name the file the user will
    /// see (`target/rel`) instead of the hidden temporary path.
    pub fn attribute(&self, e: Error) -> Error {
        match e {
            Error::Io { path, source } => Error::Io { path: self.published_path(&path), source },
            Error::Parse { path, line, msg } => Error::Parse { path: self.published_path(&path), line, msg },
            other => other,
        }
    }

    /// Moves every staged file into the target directory, deletes the files of the previous run
    /// that this run did not write, and writes the manifest last (see the module docs).
    /// Returns the published files, relative to the target, sorted.
    ///
    /// Errors: [`Error::Io`] naming the file that could not be moved or deleted; the manifest
    /// is then absent, which marks the directory as incomplete. [`Error::Cancelled`] when the
    /// computation was cancelled ([`crate::progress`]): nothing is published.
    pub fn publish(mut self) -> Result<Vec<String>> {
        // A run cancelled before publishing publishes nothing (dropping `self` removes the
        // staging directory); once the publish has begun it is not interrupted.
        crate::progress::check()?;
        let files = staged_files(&self.staging)?;
        let root = Dir::open(&self.target)?;
        let lock = beneath::open_lock(&self.target.join(LOCK))?;
        lock.lock().map_err(|e| Error::io(self.target.join(LOCK), e))?;
        // Before anything changes: a target name taken by a directory, or a file or a link where
        // a subdirectory must go, would stop the publish halfway, so it fails here, untouched.
        for rel in &files {
            let (dirs, name) = split(rel);
            let Some(dir) = walk(&root, &dirs, false)? else { continue };
            if dir.kind(name)? == Some(Kind::Dir) {
                let e = std::io::Error::new(
                    std::io::ErrorKind::IsADirectory,
                    "a directory is in the way of an output file",
                );
                return Err(Error::io(dir.path().join(name), e));
            }
        }
        // From here on the directory holds this run's output (or a partial publish): it stays.
        self.created = false;
        let previous = read_manifest(&root);
        match root.remove_file(MANIFEST) {
            Ok(()) => {}
            Err(Error::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
        for rel in &files {
            let (dirs, name) = split(rel);
            if let Some(dir) = walk(&root, &dirs, true)? {
                dir.rename_into(&self.staging.join(rel), name)?;
            }
        }
        for rel in previous.iter().filter(|r| files.binary_search(r).is_err()) {
            remove_stale(&root, rel)?;
        }
        let json = Manifest { tool: "funcorr", version: env!("CARGO_PKG_VERSION"), files: &files };
        super::write_atomic(self.target.join(MANIFEST), super::to_json_sorted(&json)? + "\n")?;
        drop(lock);
        // `self` drops on return: the (now empty) staging directory goes.
        Ok(files)
    }
}

/// A published path `a/b/c.txt` as its directories `[a, b]` and its name `c.txt`.
fn split(rel: &str) -> (Vec<&str>, &str) {
    let mut parts: Vec<&str> = rel.split('/').collect();
    let name = parts.pop().unwrap_or_default();
    (parts, name)
}

/// The directory `root/dirs…`, entered one component at a time without following a link.
/// `Ok(None)` when a component is absent (and `create` is false); created when `create` is true.
/// Errors: a component that is a link, a file or anything but a directory, named.
fn walk(root: &Dir, dirs: &[&str], create: bool) -> Result<Option<Dir>> {
    let mut cur: Option<Dir> = None;
    for d in dirs {
        let next = cur.as_ref().unwrap_or(root).subdir(d, create)?;
        match next {
            Some(n) => cur = Some(n),
            None => return Ok(None),
        }
    }
    match cur {
        Some(c) => Ok(Some(c)),
        None => root.try_clone().map(Some),
    }
}

/// Deletes the stale output `rel` of a previous run when it is a regular file reached through
/// real directories only (an entry under a link, or no longer a file, is left alone), then the
/// subdirectories it leaves empty.
fn remove_stale(root: &Dir, rel: &str) -> Result<()> {
    let (dirs, name) = split(rel);
    let mut chain: Vec<Dir> = Vec::with_capacity(dirs.len());
    for d in &dirs {
        match chain.last().unwrap_or(root).subdir(d, false) {
            Ok(Some(next)) => chain.push(next),
            // Absent, a link, or not a directory: not an output of ours any more.
            _ => return Ok(()),
        }
    }
    let dir = chain.last().unwrap_or(root);
    if dir.kind(name)? != Some(Kind::File) {
        return Ok(());
    }
    dir.remove_file(name)?;
    // Subdirectories that the stale file leaves empty go too (a non-empty one stays).
    for i in (0..dirs.len()).rev() {
        let parent = if i == 0 { root } else { &chain[i - 1] };
        if !parent.remove_empty_dir(dirs[i]) {
            break;
        }
    }
    Ok(())
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.staging);
        if self.created {
            // A directory this run made and never published into: removed if still empty.
            let _ = std::fs::remove_dir(&self.target);
        }
    }
}

/// Output files at arbitrary paths (not one directory) that appear together: each is written to
/// a hidden temporary path beside its target ([`StagedFiles::stage`]) and all are renamed into
/// place by [`StagedFiles::publish`] once every one is written. Dropping without publishing
/// removes the temporaries, so a failed run changes none of the targets.
#[derive(Debug, Default)]
pub struct StagedFiles {
    pending: Vec<(PathBuf, PathBuf)>,
}

impl StagedFiles {
    /// No files staged yet.
    pub fn new() -> StagedFiles {
        StagedFiles::default()
    }

    /// The temporary path to write the future `path` to: `.<name>.<pid>-<counter>.staged` in the
    /// same directory (so that the final rename stays on one file system).
    pub fn stage(&mut self, path: &Path) -> PathBuf {
        let tmp = super::temporary_beside(path, "staged");
        self.pending.push((tmp.clone(), path.to_path_buf()));
        tmp
    }

    /// Writes the future `path` through `f`, which receives the temporary path to write to;
    /// errors of `f` name `path`, not the temporary.
    pub fn write_with(&mut self, path: &Path, f: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
        let tmp = self.stage(path);
        f(&tmp).map_err(|e| match e {
            Error::Io { path: p, source } if p == tmp => Error::io(path, source),
            other => other,
        })
    }

    /// Renames every staged file into place, in the order staged.
    ///
    /// Errors: [`Error::Io`] naming the target that could not be replaced (or whose temporary
    /// was never written).
    pub fn publish(mut self) -> Result<()> {
        for (tmp, path) in std::mem::take(&mut self.pending) {
            if let Err(e) = std::fs::rename(&tmp, &path) {
                let _ = std::fs::remove_file(&tmp);
                return Err(Error::io(&path, e));
            }
        }
        Ok(())
    }
}

impl Drop for StagedFiles {
    fn drop(&mut self) {
        for (tmp, _) in &self.pending {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Removes the staging directories that runs killed before publishing left in `target`
/// (`.funcorr-staging.<pid>-<n>` whose process no longer exists). Only where `/proc` tells
/// which processes exist (Linux); elsewhere they stay, hidden and harmless.
fn remove_dead_staging(target: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(target) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = name.strip_prefix(".funcorr-staging.").and_then(|r| r.split_once('-')).map(|(p, _)| p) else {
            continue;
        };
        let alive = pid.parse::<u32>().is_ok_and(|p| Path::new(&format!("/proc/{p}")).exists());
        if !alive && entry.file_type().is_ok_and(|t| t.is_dir()) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// The regular files under `dir`, as sorted relative paths with `/` separators.
fn staged_files(dir: &Path) -> Result<Vec<String>> {
    let mut out = Vec::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        let abs = dir.join(&rel);
        for entry in std::fs::read_dir(&abs).map_err(|e| Error::io(&abs, e))? {
            let entry = entry.map_err(|e| Error::io(&abs, e))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let kind = entry.file_type().map_err(|e| Error::io(&abs, e))?;
            if name.starts_with('.') {
                // Hidden names are temporaries of writers (or other runs' staging directories);
                // they are not outputs.
                continue;
            }
            if kind.is_dir() {
                stack.push(rel.join(&name));
            } else if kind.is_file() {
                out.push(rel.join(&name).to_string_lossy().replace(std::path::MAIN_SEPARATOR, "/"));
            }
        }
    }
    out.sort();
    Ok(out)
}

/// `funcorr-manifest.json`: which tool wrote the directory and the files it published.
#[derive(serde::Serialize)]
struct Manifest<'a> {
    tool: &'a str,
    version: &'a str,
    files: &'a [String],
}

/// The files listed in a previous manifest, keeping only plain relative paths (no `..`, no
/// root, no hidden component), so that a damaged or hostile manifest cannot make a run delete
/// anything outside its directory. An unreadable manifest lists nothing.
/// The manifest of `root`, read only when it is a regular file (never through a link, never
/// blocking on a FIFO); see [`manifest_files`].
fn read_manifest(root: &Dir) -> Vec<String> {
    use std::io::Read;
    let Ok(file) = beneath::open_regular(&root.path().join(MANIFEST)) else { return Vec::new() };
    let mut bytes = Vec::new();
    if file.take(MAX_MANIFEST_BYTES).read_to_end(&mut bytes).is_err() {
        return Vec::new();
    }
    manifest_files(&bytes)
}

/// The files a manifest's bytes list (its `"files"` array), keeping only plain relative paths:
/// `/`-separated names, none empty, hidden (`.`, `..`, `.x`) or holding a backslash or a control
/// character, so that a damaged or hostile manifest cannot make a run delete anything outside
/// its directory or any of its own hidden files. Anything that is not such a manifest lists
/// nothing. Never fails.
pub fn manifest_files(bytes: &[u8]) -> Vec<String> {
    let Ok(v) = serde_json::from_slice::<serde_json::Value>(bytes) else { return Vec::new() };
    let Some(files) = v.get("files").and_then(|f| f.as_array()) else { return Vec::new() };
    files.iter().filter_map(|f| f.as_str()).filter(|f| is_plain_relative(f)).map(str::to_string).collect()
}

fn is_plain_relative(rel: &str) -> bool {
    rel.split('/')
        .all(|c| !c.is_empty() && !c.starts_with('.') && !c.contains(|ch: char| ch == '\\' || ch.is_control()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_util::tmp_dir;

    fn write(p: &Path, s: &str) {
        if let Some(d) = p.parent() {
            std::fs::create_dir_all(d).unwrap();
        }
        crate::io::write_atomic(p, s).unwrap();
    }

    fn listing(dir: &Path) -> Vec<String> {
        let mut v = staged_files(dir).unwrap();
        v.retain(|f| f != MANIFEST);
        v
    }

    #[test]
    fn nothing_appears_before_publish_and_a_failed_run_leaves_nothing() {
        let dir = tmp_dir("staged_fail");
        {
            let s = StagedDir::create(&dir).unwrap();
            write(&s.join("map.txt"), "1\n");
            assert!(!dir.join("map.txt").exists());
            // dropped without publishing: as a run that failed after writing map.txt
        }
        let entries: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert!(entries.is_empty(), "left behind: {entries:?}");
        // A directory the failed run created is gone too; one that existed stays.
        drop(StagedDir::create(&dir.join("new/out")).unwrap());
        assert!(!dir.join("new/out").exists() && dir.exists());
    }

    #[test]
    fn staging_left_by_a_killed_run_is_removed_by_the_next_run() {
        let dir = tmp_dir("staged_killed");
        // pid 0 is never a user process; the live one is ours.
        let dead = dir.join(".funcorr-staging.0-3");
        let live = dir.join(format!(".funcorr-staging.{}-999", std::process::id()));
        for d in [&dead, &live] {
            write(&d.join("map.txt"), "partial");
        }
        let s = StagedDir::create(&dir).unwrap();
        s.publish().unwrap();
        assert!(!dead.exists() || !Path::new("/proc/self").exists(), "a dead run's staging stayed");
        assert!(live.exists(), "a live run's staging was removed");
    }

    #[test]
    fn a_rerun_leaves_only_its_own_files_and_never_the_users() {
        let dir = tmp_dir("staged_rerun");
        write(&dir.join("notes.txt"), "mine");
        let s = StagedDir::create(&dir).unwrap();
        for f in ["map.txt", "C_method.npy", "maps/a.txt", "render.png"] {
            write(&s.join(f), "old");
        }
        assert_eq!(s.publish().unwrap(), ["C_method.npy", "map.txt", "maps/a.txt", "render.png"]);
        let s = StagedDir::create(&dir).unwrap();
        write(&s.join("map.txt"), "new");
        write(&s.join("maps/b.txt"), "new");
        let published = s.publish().unwrap();
        assert_eq!(published, ["map.txt", "maps/b.txt"]);
        assert_eq!(listing(&dir), ["map.txt", "maps/b.txt", "notes.txt"]);
        assert_eq!(std::fs::read_to_string(dir.join("map.txt")).unwrap(), "new");
        assert_eq!(std::fs::read_to_string(dir.join("notes.txt")).unwrap(), "mine");
        let manifest: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join(MANIFEST)).unwrap()).unwrap();
        assert_eq!(manifest["files"], serde_json::json!(["map.txt", "maps/b.txt"]));
    }

    #[test]
    fn a_directory_in_the_way_fails_before_anything_is_published() {
        let dir = tmp_dir("staged_in_the_way");
        std::fs::create_dir_all(dir.join("render.png")).unwrap();
        let s = StagedDir::create(&dir).unwrap();
        write(&s.join("map.txt"), "new");
        write(&s.join("render.png"), "png");
        let e = s.publish().unwrap_err().to_string();
        assert!(e.contains("render.png"), "{e}");
        assert!(!dir.join("map.txt").exists(), "published halfway");
    }

    #[test]
    fn a_hostile_manifest_cannot_delete_outside_the_directory() {
        let root = tmp_dir("staged_hostile");
        let dir = root.join("out");
        write(&root.join("victim.txt"), "keep");
        write(&dir.join(".hidden"), "keep");
        write(
            &dir.join(MANIFEST),
            r#"{"files": ["../victim.txt", "/etc/passwd", ".hidden", "", "a/../../victim.txt"]}"#,
        );
        let s = StagedDir::create(&dir).unwrap();
        write(&s.join("map.txt"), "x");
        s.publish().unwrap();
        assert!(root.join("victim.txt").exists());
        assert!(dir.join(".hidden").exists());
        assert!(is_plain_relative("maps/a.txt"));
        for bad in ["../a", "/a", ".a", "a/./b/../c", "", "a/.b", "a/./b", "a//b", "a/", "a\\b", "a\0b"] {
            assert!(!is_plain_relative(bad), "{bad}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn nothing_is_deleted_or_written_through_a_link_in_the_directory() {
        use std::os::unix::fs::symlink;
        let root = tmp_dir("staged_links");
        let (dir, ext) = (root.join("out"), root.join("ext"));
        write(&ext.join("v.txt"), "keep");
        write(&ext.join("deep/w.txt"), "keep");
        std::fs::create_dir_all(&dir).unwrap();
        symlink("../ext", dir.join("sub")).unwrap();
        symlink(ext.join("v.txt"), dir.join("link.txt")).unwrap();
        write(&dir.join(MANIFEST), r#"{"files": ["sub/v.txt", "sub/deep/w.txt", "link.txt"]}"#);
        let s = StagedDir::create(&dir).unwrap();
        write(&s.join("map.txt"), "x");
        assert_eq!(s.publish().unwrap(), ["map.txt"]);
        assert_eq!(std::fs::read_to_string(ext.join("v.txt")).unwrap(), "keep", "deleted through a link");
        assert!(ext.join("deep/w.txt").exists(), "deleted through a link");
        assert!(std::fs::symlink_metadata(dir.join("link.txt")).is_ok(), "a link is not a stale output");
        // An output whose directory is a link: an error naming it before anything is published.
        let s = StagedDir::create(&dir).unwrap();
        write(&s.join("map.txt"), "new");
        write(&s.join("sub/a.txt"), "would land outside");
        let e = s.publish().unwrap_err().to_string();
        assert!(e.contains("sub") && e.contains("symbolic link"), "{e}");
        assert!(!ext.join("a.txt").exists(), "written through a link");
        assert_eq!(std::fs::read_to_string(dir.join("map.txt")).unwrap(), "x", "published halfway");
    }

    #[cfg(unix)]
    #[test]
    fn a_lock_or_manifest_that_is_a_fifo_or_a_link_never_hangs_or_follows() {
        let mkfifo = |p: &Path| {
            let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
            // SAFETY: a valid NUL-terminated path.
            assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        };
        let root = tmp_dir("staged_fifo");
        // A FIFO lock: refused up front, and at publish time (swapped in after create).
        let dir = root.join("a");
        std::fs::create_dir_all(&dir).unwrap();
        mkfifo(&dir.join(LOCK));
        let e = StagedDir::create(&dir).unwrap_err().to_string();
        assert!(e.contains(LOCK) && e.contains("FIFO"), "{e}");
        std::fs::remove_file(dir.join(LOCK)).unwrap();
        let s = StagedDir::create(&dir).unwrap();
        write(&s.join("map.txt"), "x");
        mkfifo(&dir.join(LOCK));
        let e = s.publish().unwrap_err().to_string();
        assert!(e.contains("FIFO"), "{e}");
        assert_eq!(staged_files(&dir).unwrap(), Vec::<String>::new(), "published without the lock");
        // A dangling link as the lock: refused, its target never created.
        let dir = root.join("b");
        std::fs::create_dir_all(&dir).unwrap();
        std::os::unix::fs::symlink(root.join("anywhere"), dir.join(LOCK)).unwrap();
        assert!(StagedDir::create(&dir).unwrap_err().to_string().contains("symbolic link"));
        assert!(std::fs::symlink_metadata(root.join("anywhere")).is_err());
        // A FIFO manifest is not read (nor waited on): it lists nothing and is replaced.
        let dir = root.join("c");
        std::fs::create_dir_all(&dir).unwrap();
        mkfifo(&dir.join(MANIFEST));
        let s = StagedDir::create(&dir).unwrap();
        write(&s.join("map.txt"), "x");
        assert_eq!(s.publish().unwrap(), ["map.txt"]);
        assert!(std::fs::metadata(dir.join(MANIFEST)).unwrap().is_file());
    }

    #[test]
    fn manifest_entries_are_plain_relative_names_only() {
        let m = br#"{"files": ["map.txt", "maps/a.txt", "a//b", "a/./b", "../x", "/etc/x", "a\\b", ".h", "a/.h", "x\u0000y", 3]}"#;
        assert_eq!(manifest_files(m), ["map.txt", "maps/a.txt"]);
        for bad in [&b"not json"[..], b"{}", br#"{"files": "map.txt"}"#, b"[1, 2]", b"\xff\xfe"] {
            assert!(manifest_files(bad).is_empty());
        }
    }

    #[test]
    fn staged_files_appear_together_or_not_at_all() {
        let dir = tmp_dir("staged_files");
        let (a, b) = (dir.join("d.npy"), dir.join("names.txt"));
        write(&a, "old a");
        {
            let mut s = StagedFiles::new();
            write(&s.stage(&a), "new a");
            let _never_written = s.stage(&b);
            // dropped: a failure between the two writes
        }
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        assert!(!b.exists());
        assert_eq!(staged_files(&dir).unwrap(), ["d.npy"], "temporaries left behind");
        let mut s = StagedFiles::new();
        write(&s.stage(&a), "new a");
        write(&s.stage(&b), "new b");
        s.publish().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b");
        let hidden = std::fs::read_dir(&dir)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().starts_with('.'));
        assert_eq!(hidden.count(), 0);
    }

    #[test]
    fn concurrent_publishers_each_leave_a_consistent_directory() {
        let dir = tmp_dir("staged_concurrent");
        std::thread::scope(|scope| {
            for t in 0..4 {
                let dir = &dir;
                scope.spawn(move || {
                    let s = StagedDir::create(dir).unwrap();
                    write(&s.join("map.txt"), &format!("{t}"));
                    write(&s.join(format!("only_{t}.txt")), &format!("{t}"));
                    s.publish().unwrap();
                });
            }
        });
        // The last publisher's manifest lists its own two files and nothing else is left.
        let manifest: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join(MANIFEST)).unwrap()).unwrap();
        let files: Vec<String> =
            manifest["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap().to_string()).collect();
        assert_eq!(files.len(), 2);
        assert_eq!(listing(&dir), files);
        let t = std::fs::read_to_string(dir.join("map.txt")).unwrap();
        assert_eq!(files, ["map.txt".to_string(), format!("only_{t}.txt")]);
    }
}

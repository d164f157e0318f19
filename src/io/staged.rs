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

use std::path::{Component, Path, PathBuf};

use crate::error::{Error, Result};

/// Name of the manifest written last into a published output directory.
pub const MANIFEST: &str = "funcorr-manifest.json";

/// Upper bound on the bytes of a manifest that is read back (a hostile or damaged manifest
/// larger than this is ignored rather than read).
const MAX_MANIFEST_BYTES: u64 = 64 << 20;

/// An output directory being written: files go into [`StagedDir::path`] and appear in the
/// target directory only when [`StagedDir::publish`] succeeds (see the module docs). Dropping
/// it (published or not) removes the staging directory.
#[derive(Debug)]
pub struct StagedDir {
    target: PathBuf,
    staging: PathBuf,
}

impl StagedDir {
    /// Creates `target` if needed and a fresh, exclusively created staging directory inside it.
    ///
    /// Errors: [`Error::Io`] naming `target` when either cannot be created, or when `target`
    /// exists and is not a directory.
    pub fn create(target: &Path) -> Result<StagedDir> {
        use std::sync::atomic::{AtomicU64, Ordering};
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        std::fs::create_dir_all(target).map_err(|e| Error::io(target, e))?;
        remove_dead_staging(target);
        let mut attempt = 0;
        loop {
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let staging = target.join(format!(".funcorr-staging.{}-{n}", std::process::id()));
            match std::fs::create_dir(&staging) {
                Ok(()) => return Ok(StagedDir { target: target.to_path_buf(), staging }),
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
    /// is then absent, which marks the directory as incomplete.
    pub fn publish(self) -> Result<Vec<String>> {
        let files = staged_files(&self.staging)?;
        let lock_path = self.target.join(".funcorr.lock");
        let lock = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&lock_path)
            .map_err(|e| Error::io(&lock_path, e))?;
        lock.lock().map_err(|e| Error::io(&lock_path, e))?;
        // Before anything changes: a target name taken by a directory (or a file where a
        // subdirectory must go) would stop the publish halfway, so it fails here, untouched.
        for rel in &files {
            let to = self.target.join(rel);
            if std::fs::symlink_metadata(&to).is_ok_and(|m| m.is_dir()) {
                let e = std::io::Error::new(
                    std::io::ErrorKind::IsADirectory,
                    "a directory is in the way of an output file",
                );
                return Err(Error::io(&to, e));
            }
            let mut parent = to.parent();
            while let Some(d) = parent.filter(|d| *d != self.target) {
                if std::fs::symlink_metadata(d).is_ok_and(|m| !m.is_dir()) {
                    let e = std::io::Error::new(
                        std::io::ErrorKind::NotADirectory,
                        "a file is in the way of an output directory",
                    );
                    return Err(Error::io(d, e));
                }
                parent = d.parent();
            }
        }
        let manifest = self.target.join(MANIFEST);
        let previous = read_manifest(&manifest);
        match std::fs::remove_file(&manifest) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(&manifest, e)),
        }
        for rel in &files {
            let (from, to) = (self.staging.join(rel), self.target.join(rel));
            if let Some(parent) = to.parent() {
                std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
            }
            std::fs::rename(&from, &to).map_err(|e| Error::io(&to, e))?;
        }
        for rel in previous.iter().filter(|r| files.binary_search(r).is_err()) {
            let stale = self.target.join(rel);
            match std::fs::symlink_metadata(&stale) {
                Ok(m) if m.is_file() => std::fs::remove_file(&stale).map_err(|e| Error::io(&stale, e))?,
                _ => continue,
            }
            // Subdirectories that the stale file leaves empty go too (a non-empty one stays).
            let mut dir = stale.parent();
            while let Some(d) = dir.filter(|d| *d != self.target) {
                if std::fs::remove_dir(d).is_err() {
                    break;
                }
                dir = d.parent();
            }
        }
        let json = Manifest { tool: "funcorr", version: env!("CARGO_PKG_VERSION"), files: &files };
        super::write_atomic(&manifest, super::to_json_sorted(&json)? + "\n")?;
        drop(lock);
        // `self` drops on return: the (now empty) staging directory goes.
        Ok(files)
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.staging);
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
fn read_manifest(path: &Path) -> Vec<String> {
    use std::io::Read;
    let Ok(file) = std::fs::File::open(path) else { return Vec::new() };
    let mut text = String::new();
    if file.take(MAX_MANIFEST_BYTES).read_to_string(&mut text).is_err() {
        return Vec::new();
    }
    let Ok(v) = serde_json::from_str::<serde_json::Value>(&text) else { return Vec::new() };
    let Some(files) = v.get("files").and_then(|f| f.as_array()) else { return Vec::new() };
    files.iter().filter_map(|f| f.as_str()).filter(|f| is_plain_relative(f)).map(str::to_string).collect()
}

fn is_plain_relative(rel: &str) -> bool {
    !rel.is_empty()
        && Path::new(rel).components().all(|c| match c {
            Component::Normal(s) => !s.to_string_lossy().starts_with('.'),
            _ => false,
        })
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
        for bad in ["../a", "/a", ".a", "a/./b/../c", "", "a/.b"] {
            assert!(!is_plain_relative(bad), "{bad}");
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

//! Reading and writing geometry and arrays.
//!
//! Meshes and point clouds: OFF/COFF/NOFF ([`off`]), Wavefront OBJ ([`obj`]), PLY in ASCII and
//! binary ([`ply`]), text point lists `.xyz/.txt/.pts/.csv` ([`points`]) and `n × 3` `.npy` arrays.
//! Dense arrays: `.npy` and uncompressed `.npz` ([`npy`]).
//!
//! Every reader treats its input as untrusted: it never panics, never allocates more than the input
//! can hold (header counts are checked against the bytes actually present or the capacity reserved
//! from them is bounded), rejects NaN/infinite coordinates and out-of-range face indices, and reports
//! problems as [`Error::Parse`] (with a 1-based line number for text formats) saying what was
//! expected and what was found.

pub(crate) mod beneath;
pub mod indices;
pub mod npy;
pub mod obj;
pub mod off;
pub mod ply;
pub mod points;
pub mod staged;
mod text;

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::Path;

use crate::error::{Error, Result};

/// Raw geometry as read from a file.
///
/// `vertices` are `n` points `[x, y, z]` in the file's units; `faces` are triangles of 0-based
/// vertex indices (all `< n`; polygons are fan-triangulated on reading); `colors`, when present,
/// hold one RGB colour (0–255) per vertex. A point cloud has no faces.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshData {
    /// Vertex positions, `n × 3`, any units.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as 0-based vertex indices, each `< vertices.len()`.
    pub faces: Vec<[u32; 3]>,
    /// Optional per-vertex RGB colours (0–255), `colors.len() == vertices.len()`.
    pub colors: Option<Vec<[u8; 3]>>,
}

/// Dense row-major matrix read from `.npy` or `.csv`/`.txt`: element `(i, j)` is
/// `data[i * cols + j]`, and `data.len() == rows * cols`.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseMatrix {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// Row-major values, `rows * cols` of them.
    pub data: Vec<f64>,
}

/// Lower-cased extension of `path` (empty when it has none).
fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

fn open(path: &Path) -> Result<BufReader<File>> {
    File::open(path).map(BufReader::new).map_err(|e| Error::io(path, e))
}

/// Reads a mesh or point cloud, choosing the format from the extension (case-insensitive):
/// `off`, `obj`, `ply`, `xyz`/`csv`/`txt`/`pts` (text points) or `npy` (an `n × 3` array of points).
///
/// Errors: [`Error::Invalid`] for an unknown extension, [`Error::Io`] when the file cannot be
/// read, [`Error::Parse`] when its content is malformed.
pub fn read_mesh(path: &Path) -> Result<MeshData> {
    match extension(path).as_str() {
        "off" => off::read_off(open(path)?, path),
        "obj" => obj::read_obj(open(path)?, path),
        "ply" => ply::read_ply(open(path)?, path),
        "xyz" | "csv" | "txt" | "pts" => points::read_points_text(open(path)?, path),
        "npy" => {
            let m = npy::read_npy_matrix(path)?;
            if m.cols != 3 || m.rows == 0 {
                return Err(Error::parse(
                    path,
                    None,
                    format!("expected an n × 3 array of points, found {} × {}", m.rows, m.cols),
                ));
            }
            let vertices = m.data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            Ok(MeshData { vertices, ..MeshData::default() })
        }
        ext => Err(unknown_extension(path, ext, "off, obj, ply, xyz, csv, txt, pts or npy")),
    }
}

/// Writes a mesh, choosing the format from the extension: `off` (ASCII, exact round trip) or
/// `ply` (binary little endian, `double` coordinates). The file is written whole or not at all
/// (a temporary file beside it, then a rename; see `write_file`).
///
/// Errors: [`Error::Invalid`] for another extension or an inconsistent mesh (non-finite
/// coordinate, face index out of range, wrong number of colours), [`Error::Io`] on write failure.
pub fn write_mesh(path: &Path, mesh: &MeshData) -> Result<()> {
    match extension(path).as_str() {
        "off" => write_file(path, |w| off::write_off(w, mesh, path)),
        "ply" => write_file(path, |w| ply::write_ply_to(w, mesh, false, path)),
        ext => Err(unknown_extension(path, ext, "off or ply")),
    }
}

/// Reads a dense matrix: `.npy` (see [`npy::read_npy_matrix`]) or `.csv`/`.txt`
/// (see [`points::read_matrix_text`]).
pub fn read_matrix(path: &Path) -> Result<DenseMatrix> {
    match extension(path).as_str() {
        "npy" => npy::read_npy_matrix(path),
        "csv" | "txt" => points::read_matrix_text(open(path)?, path),
        ext => Err(unknown_extension(path, ext, "npy, csv or txt")),
    }
}

fn unknown_extension(path: &Path, ext: &str, expected: &str) -> Error {
    Error::invalid("path", format!("{}: unsupported extension '{ext}' (expected {expected})", path.display()))
}

/// `value` as pretty-printed JSON (two-space indent) with the keys of every object in sorted
/// order: the form of every JSON file funcorr writes, so that a file's bytes do not depend on the
/// order in which a struct declares its fields. Errors ([`Error::Invalid`] naming `json`) only
/// for values JSON cannot hold (maps with non-string keys).
pub fn to_json_sorted<T: serde::Serialize + ?Sized>(value: &T) -> Result<String> {
    let v = serde_json::to_value(value).map_err(|e| Error::invalid("json", e.to_string()))?;
    serde_json::to_string_pretty(&v).map_err(|e| Error::invalid("json", e.to_string()))
}

/// Writes `contents` to `path` whole or not at all: a reader sees the old file or the complete
/// new one, never a part (a temporary file beside it, synced, then renamed; see `write_file`).
/// Every output file of the library and the CLI goes through this or `write_file`.
pub fn write_atomic(path: impl AsRef<Path>, contents: impl AsRef<[u8]>) -> Result<()> {
    let path = path.as_ref();
    write_file(path, |w| w.write_all(contents.as_ref()).map_err(|e| Error::io(path, e)))
}

/// Writes a file whole or not at all: through `f` into a new temporary file beside `path`
/// (`.<name>.<pid>-<counter>.tmp`, created exclusively — `O_CREAT | O_EXCL | O_NOFOLLOW`, so an
/// existing file or symbolic link of that name is never opened or followed), flushed and
/// synced to disk, then renamed over `path`. Concurrent writers of the same `path` each use their
/// own temporary file, so all succeed and the last rename wins with a complete file; on failure
/// the temporary file is removed and `path` is untouched.
pub(crate) fn write_file(path: &Path, f: impl FnOnce(&mut BufWriter<File>) -> Result<()>) -> Result<()> {
    let (file, tmp) = {
        let mut attempt = 0;
        loop {
            // Unique among live writers; a stale file of a dead process with the same pid is
            // skipped by the retry with the next counter value.
            let tmp = temporary_beside(path, "tmp");
            let mut options = std::fs::OpenOptions::new();
            options.write(true).create_new(true);
            #[cfg(unix)]
            {
                // O_EXCL already refuses an existing name, link or not; O_NOFOLLOW says so twice.
                use std::os::unix::fs::OpenOptionsExt;
                options.custom_flags(libc::O_NOFOLLOW);
            }
            match options.open(&tmp) {
                Ok(file) => break (file, tmp),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && attempt < 100 => attempt += 1,
                // Errors name the file the user asked for, not our temporary.
                Err(e) => return Err(Error::io(path, e)),
            }
        }
    };
    let res = (|| {
        let mut w = BufWriter::new(file);
        f(&mut w)?;
        let file = w.into_inner().map_err(|e| Error::io(path, e.into_error()))?;
        file.sync_all().map_err(|e| Error::io(path, e))?;
        std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
    })();
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res
}

/// Most records one file may hold: vertices, triangles (after fan triangulation), values of a
/// matrix, lines of an index file — 2²⁷ ≈ 1.3 · 10⁸. Far beyond what the pipeline can process (an
/// eigenbasis of 50 functions on 2²⁷ vertices alone takes 54 GB), and small enough that an input
/// that never ends (a pipe or a device such as `/dev/zero` behind a valid header) fails with an
/// error after at most a few GB instead of exhausting memory.
pub const MAX_RECORDS: usize = 1 << 27;

/// Most bytes read as the body of one PLY file (8 GiB; the whole body is held in memory).
pub const MAX_PLY_BODY: u64 = 1 << 33;

/// Errors when a reader is about to store record number `len` (0-based) of kind `what`
/// beyond [`MAX_RECORDS`].
pub(crate) fn check_records(len: usize, what: &str, path: &Path, line: Option<usize>) -> Result<()> {
    if len >= MAX_RECORDS {
        return Err(Error::parse(path, line, format!("expected at most {MAX_RECORDS} {what}, found more")));
    }
    Ok(())
}

/// A hidden name for a temporary file in `path`'s directory (so that renaming it over `path`
/// stays on one file system): `.<name>.<pid>-<counter>.<suffix>`, the counter shared by every
/// caller in the process, so no two calls return the same name.
pub(crate) fn temporary_beside(path: &Path, suffix: &str) -> std::path::PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    dir.join(format!(".{name}.{}-{n}.{suffix}", std::process::id()))
}

/// Capacity to reserve for `n` records announced by an untrusted header: at most `limit`.
pub(crate) fn bounded_capacity(n: u64, limit: usize) -> usize {
    usize::try_from(n).unwrap_or(usize::MAX).min(limit)
}

/// Checks that vertex `i` has finite coordinates.
pub(crate) fn check_vertex(p: [f64; 3], i: usize, path: &Path, line: Option<usize>) -> Result<[f64; 3]> {
    if p.iter().all(|c| c.is_finite()) {
        Ok(p)
    } else {
        let msg = format!("vertex {i}: expected finite coordinates, found ({}, {}, {})", p[0], p[1], p[2]);
        Err(Error::parse(path, line, msg))
    }
}

/// Converts face `face`'s vertex index `idx` (already 0-based) to `u32`, checking `0 <= idx < nv`.
pub(crate) fn check_index(idx: f64, nv: usize, face: usize, path: &Path, line: Option<usize>) -> Result<u32> {
    if idx.fract() == 0.0 && idx >= 0.0 && idx < nv as f64 {
        Ok(idx as u32)
    } else {
        let msg = format!("face {face}: vertex index {idx} out of range (expected 0 ≤ index < {nv}, the vertex count)");
        Err(Error::parse(path, line, msg))
    }
}

/// Appends the fan triangulation of polygon `poly` (at least 3 vertices) to `faces`, at most
/// [`MAX_RECORDS`] triangles in all.
pub(crate) fn push_fan(faces: &mut Vec<[u32; 3]>, poly: &[u32], path: &Path, line: Option<usize>) -> Result<()> {
    check_records((faces.len() + poly.len()).saturating_sub(3), "triangles", path, line)?;
    for k in 1..poly.len().saturating_sub(1) {
        faces.push([poly[0], poly[k], poly[k + 1]]);
    }
    Ok(())
}

/// Converts a colour channel: an integer 0–255, or when `float` a value in [0, 1] (scaled by 255).
pub(crate) fn color_channel(v: f64, float: bool) -> Option<u8> {
    if float {
        (0.0..=1.0).contains(&v).then(|| (v * 255.0).round() as u8)
    } else {
        (v.fract() == 0.0 && (0.0..=255.0).contains(&v)).then_some(v as u8)
    }
}

/// Final checks shared by the mesh readers: at least one vertex.
pub(crate) fn finish(mesh: MeshData, path: &Path, line: Option<usize>) -> Result<MeshData> {
    if mesh.vertices.is_empty() {
        return Err(Error::parse(path, line, "expected at least one vertex, found none"));
    }
    Ok(mesh)
}

/// Checks a mesh before writing: finite coordinates, indices in range, one colour per vertex,
/// counts that fit the formats' signed 32-bit integers.
pub(crate) fn validate_for_write(mesh: &MeshData) -> Result<()> {
    let n = mesh.vertices.len();
    let bad = |msg: String| Err(Error::invalid("mesh", msg));
    if n > i32::MAX as usize || mesh.faces.len() > i32::MAX as usize {
        return bad(format!("{n} vertices / {} faces exceed 2^31 - 1", mesh.faces.len()));
    }
    if let Some(i) = mesh.vertices.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return bad(format!("vertex {i} has a non-finite coordinate {:?}", mesh.vertices[i]));
    }
    if let Some(f) = mesh.faces.iter().position(|f| f.iter().any(|&v| v as usize >= n)) {
        return bad(format!("face {f} {:?} has an index ≥ the vertex count {n}", mesh.faces[f]));
    }
    match &mesh.colors {
        Some(c) if c.len() != n => bad(format!("{} colours for {n} vertices", c.len())),
        _ => Ok(()),
    }
}

#[cfg(test)]
pub(crate) mod test_util {
    use std::path::PathBuf;

    use crate::error::{Error, Result};

    /// Asserts that `r` is an [`Error::Parse`] whose message contains `needle` (case-insensitive)
    /// and, when `line` is given, whose line is `line`.
    #[track_caller]
    pub fn assert_parse<T: std::fmt::Debug>(r: Result<T>, line: Option<Option<usize>>, needle: &str) {
        match r {
            Err(Error::Parse { line: l, msg, .. }) => {
                assert!(msg.to_lowercase().contains(&needle.to_lowercase()), "message {msg:?} lacks {needle:?}");
                if let Some(line) = line {
                    assert_eq!(l, line, "wrong line for {msg:?}");
                }
            }
            other => panic!("expected a parse error containing {needle:?}, got {other:?}"),
        }
    }

    /// `n` pseudo-random bytes (xorshift, deterministic for a `seed`).
    pub fn noise(n: usize, seed: u32) -> Vec<u8> {
        let mut x = seed.wrapping_mul(2_654_435_761) | 1;
        (0..n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                (x >> 11) as u8
            })
            .collect()
    }

    /// A fresh directory for one test's files.
    pub fn tmp_dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("funcorr_io_{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}

#[cfg(test)]
mod tests {
    use super::test_util::{assert_parse, tmp_dir};
    use super::*;

    #[test]
    fn json_files_list_keys_in_sorted_order() {
        #[derive(serde::Serialize)]
        struct Row {
            zeta: u32,
            alpha: Option<f64>,
            inner: std::collections::HashMap<&'static str, u8>,
        }
        let text = to_json_sorted(&Row { zeta: 1, alpha: None, inner: [("b", 2), ("a", 1)].into() }).unwrap();
        assert_eq!(text, "{\n  \"alpha\": null,\n  \"inner\": {\n    \"a\": 1,\n    \"b\": 2\n  },\n  \"zeta\": 1\n}");
    }

    fn tetra(colors: bool) -> MeshData {
        MeshData {
            vertices: vec![[0.1, 0.2, 0.3], [1.0 / 3.0, -2.5e-300, 1e22], [0.0, 1.0, 0.0], [-7.25, 3.0, 1e-7]],
            faces: vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]],
            colors: colors.then(|| vec![[255, 0, 0], [0, 255, 0], [0, 0, 255], [1, 2, 3]]),
        }
    }

    /// No temporary file of the writer is left in `d`.
    fn no_temporaries(d: &Path) -> bool {
        std::fs::read_dir(d).unwrap().flatten().all(|e| !e.file_name().to_string_lossy().ends_with(".tmp"))
    }

    #[test]
    fn a_write_that_fails_midway_leaves_the_old_file() {
        let d = tmp_dir("midway");
        let p = d.join("map.txt");
        write_atomic(&p, "old run\n").unwrap();
        let failed = write_file(&p, |w| {
            w.write_all(b"first lines of a new run").map_err(|e| Error::io(&p, e))?;
            Err(Error::invalid("disk", "injected failure"))
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "old run\n");
        assert!(no_temporaries(&d));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn writes_never_follow_links_and_concurrent_writers_all_succeed() {
        let d = tmp_dir("atomic");
        // A link at the old predictable temporary name (and at the target's) is not followed.
        let victim = d.join("victim.txt");
        std::fs::write(&victim, b"keep me").unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(&victim, d.join("a.off.tmp")).unwrap();
        write_mesh(&d.join("a.off"), &tetra(false)).unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep me");
        assert_eq!(read_mesh(&d.join("a.off")).unwrap(), tetra(false));
        // Eight threads writing the same file: every write succeeds, the result is complete.
        let p = d.join("same.ply");
        std::thread::scope(|s| {
            for _ in 0..8 {
                s.spawn(|| write_mesh(&p, &tetra(true)).unwrap());
            }
        });
        assert_eq!(read_mesh(&p).unwrap(), tetra(true));
        #[cfg(unix)]
        std::fs::remove_file(d.join("a.off.tmp")).unwrap();
        assert!(no_temporaries(&d));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn write_then_read_mesh_by_extension() {
        let d = tmp_dir("mesh_ext");
        for (name, colors) in [("a.off", false), ("b.ply", true), ("c.PLY", false), ("d.OFF", true)] {
            let p = d.join(name);
            write_mesh(&p, &tetra(colors)).unwrap();
            assert_eq!(read_mesh(&p).unwrap(), tetra(colors), "{name}");
            assert!(no_temporaries(&d), "{name}");
        }
        let p = d.join("e.obj");
        assert!(matches!(write_mesh(&p, &tetra(false)), Err(Error::Invalid { .. })));
        std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(read_mesh(&p).unwrap().faces, vec![[0, 1, 2]]);
        for (name, text) in
            [("f.xyz", "0 0 1\n"), ("g.CSV", "x,y,z\n0,0,1\n"), ("h.pts", "0 0 1\n"), ("i.txt", "0 0 1\n")]
        {
            std::fs::write(d.join(name), text).unwrap();
            assert_eq!(read_mesh(&d.join(name)).unwrap().vertices, vec![[0.0, 0.0, 1.0]], "{name}");
        }
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn read_mesh_npy_points_and_errors() {
        let d = tmp_dir("mesh_npy");
        let p = d.join("pts.npy");
        npy::write_npy_matrix(&p, &DenseMatrix { rows: 2, cols: 3, data: vec![1., 2., 3., 4., 5., 6.] }).unwrap();
        assert_eq!(read_mesh(&p).unwrap().vertices, vec![[1., 2., 3.], [4., 5., 6.]]);
        npy::write_npy_matrix(&p, &DenseMatrix { rows: 3, cols: 2, data: vec![1., 2., 3., 4., 5., 6.] }).unwrap();
        assert_parse(read_mesh(&p), Some(None), "n × 3");
        match read_mesh(&d.join("x.stl")) {
            Err(Error::Invalid { msg, .. }) => {
                assert!(msg.contains("x.stl") && msg.contains("'stl'"), "{msg}")
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(read_mesh(&d.join("missing.off")), Err(Error::Io { .. })));
        assert!(matches!(read_mesh(&d.join("noext")), Err(Error::Invalid { .. })));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn read_matrix_dispatch() {
        let d = tmp_dir("matrix");
        std::fs::write(d.join("m.csv"), "a,b\n1,2\n3,4\n").unwrap();
        let m = read_matrix(&d.join("m.csv")).unwrap();
        assert_eq!(m, DenseMatrix { rows: 2, cols: 2, data: vec![1., 2., 3., 4.] });
        npy::write_npy_matrix(&d.join("m.npy"), &m).unwrap();
        assert_eq!(read_matrix(&d.join("m.npy")).unwrap(), m);
        assert!(matches!(read_matrix(&d.join("m.json")), Err(Error::Invalid { .. })));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn write_rejects_inconsistent_meshes() {
        let d = tmp_dir("bad_write");
        let mut m = tetra(false);
        m.vertices[2][1] = f64::NAN;
        assert!(matches!(write_mesh(&d.join("a.off"), &m), Err(Error::Invalid { .. })));
        let mut m = tetra(false);
        m.faces[1][2] = 4;
        assert!(matches!(write_mesh(&d.join("a.ply"), &m), Err(Error::Invalid { .. })));
        let mut m = tetra(true);
        m.colors.as_mut().unwrap().pop();
        assert!(matches!(write_mesh(&d.join("a.ply"), &m), Err(Error::Invalid { .. })));
        assert!(!d.join("a.ply").exists() && no_temporaries(&d));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn helpers() {
        let mut f = Vec::new();
        push_fan(&mut f, &[4, 5, 6, 7, 8], Path::new("t"), None).unwrap();
        assert_eq!(f, vec![[4, 5, 6], [4, 6, 7], [4, 7, 8]]);
        assert_eq!(color_channel(1.0, true), Some(255));
        assert_eq!(color_channel(0.5, true), Some(128));
        assert_eq!(color_channel(1.5, true), None);
        assert_eq!(color_channel(200.0, false), Some(200));
        assert_eq!(color_channel(256.0, false), None);
        assert_eq!(color_channel(2.5, false), None);
        assert_eq!(color_channel(f64::NAN, true), None);
        assert_eq!(bounded_capacity(u64::MAX, 10), 10);
        assert_eq!(bounded_capacity(3, 10), 3);
    }
}

//! Basis files (`.npz`, readable by numpy) and an on-disk cache of eigenbases.
//!
//! A basis file holds `eigenvalues` (k), `eigenvectors` (n × k, f64, C order), `mass` (n) and
//! `residuals` (k): `np.load("basis.npz")["eigenvectors"]` is Φ.
//!
//! The cache is keyed by a hash of the Laplacian itself (the bits of W and A), so any two runs
//! that build the same operator — whatever file, format or options they came from — share the
//! basis; a cached basis with k' ≥ k eigenpairs, computed with a tolerance at least as strict as
//! the request's, serves a request for k by truncation. Entries are
//! `<key>-tol<tol>-k<K>.npz`; every read checks the archive's CRC-32 and the arrays' shapes, and
//! anything that fails is a miss (the caller recomputes), never a wrong basis.
//!
//! The directory is shared and not written by hand, so its entries are opened only as regular
//! files: never through a symbolic link, never blocking on a FIFO (a warning and a miss). A write
//! goes to a hidden temporary (`.<entry>.<pid>-<n>.tmp`) renamed into place; the temporaries of
//! writers that were killed are swept by the next write into the directory: a temporary not
//! modified for [`ORPHAN_AGE`] is removed (a writer at work keeps its temporary's modification
//! time fresh, and no entry takes that long to write; the rule needs no process ids, which mean
//! nothing on another host sharing the directory).

use std::path::{Path, PathBuf};

use faer::Mat;

use super::Basis;
use crate::error::{Error, Result};
use crate::io::npy::{read_npz, write_npz, NpzArray};
use crate::laplacian::{Fnv, Laplacian};

/// Writes `basis` to `path` as an uncompressed `.npz` (see the module documentation).
pub fn save_basis(path: &Path, basis: &Basis) -> Result<()> {
    let (n, k) = (basis.n(), basis.k());
    // C order: row i holds φ₁(i) … φ_k(i).
    let mut phi = Vec::with_capacity(n * k);
    for i in 0..n {
        phi.extend((0..k).map(|j| basis.eigenvectors[(i, j)]));
    }
    write_npz(
        path,
        &[
            ("eigenvalues", NpzArray::F64 { shape: vec![k], data: basis.eigenvalues.clone() }),
            ("eigenvectors", NpzArray::F64 { shape: vec![n, k], data: phi }),
            ("mass", NpzArray::F64 { shape: vec![n], data: basis.mass.clone() }),
            ("residuals", NpzArray::F64 { shape: vec![k], data: basis.residuals.clone() }),
        ],
    )
}

/// A hidden temporary in the cache directory not modified for this long belongs to a writer
/// that is gone, and the next write removes it (one hour).
pub const ORPHAN_AGE: std::time::Duration = std::time::Duration::from_secs(3600);

/// Reads a basis written by [`save_basis`] (or by numpy with the same arrays; `residuals` is
/// optional). Errors name the file and the array that is missing, misshapen or not finite.
pub fn load_basis(path: &Path) -> Result<Basis> {
    basis_from_arrays(read_npz(path)?, path)
}

/// [`load_basis`] of a cache entry: the file is opened only if it is a regular file (no link
/// followed, no FIFO waited on).
fn load_entry(path: &Path) -> Result<Basis> {
    let file = crate::io::beneath::open_regular(path)?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    basis_from_arrays(crate::io::npy::read_npz_from(std::io::BufReader::new(file), len, path)?, path)
}

fn basis_from_arrays(arrays: Vec<(String, NpzArray)>, path: &Path) -> Result<Basis> {
    let get = |name: &str| -> Result<(&[usize], &[f64])> {
        match arrays.iter().find(|(n, _)| n == name) {
            Some((_, NpzArray::F64 { shape, data })) => {
                if let Some(p) = data.iter().position(|v| !v.is_finite()) {
                    return Err(Error::parse(path, None, format!("array '{name}' has a non-finite value at {p}")));
                }
                Ok((shape, data))
            }
            Some(_) => Err(Error::parse(path, None, format!("array '{name}' must be floating point"))),
            None => Err(Error::parse(path, None, format!("no array '{name}' (is this a funcorr basis file?)"))),
        }
    };
    let (s_val, val) = get("eigenvalues")?;
    let (s_vec, vec) = get("eigenvectors")?;
    let (s_mass, mass) = get("mass")?;
    let k = val.len();
    let n = mass.len();
    if s_val.len() != 1 || s_mass.len() != 1 || s_vec != [n, k] || k == 0 {
        return Err(Error::parse(
            path,
            None,
            format!(
                "inconsistent shapes: eigenvalues {s_val:?}, eigenvectors {s_vec:?}, mass {s_mass:?} (want k, n×k, n)"
            ),
        ));
    }
    let residuals = match get("residuals") {
        Ok((s, r)) if s == [k] => r.to_vec(),
        Ok((s, _)) => return Err(Error::parse(path, None, format!("residuals has shape {s:?}, want [{k}]"))),
        Err(_) => vec![f64::NAN; k],
    };
    Ok(Basis {
        eigenvalues: val.to_vec(),
        eigenvectors: Mat::from_fn(n, k, |i, j| vec[i * k + j]),
        mass: mass.to_vec(),
        residuals,
    })
}

/// A directory of cached bases, `<key>-tol<tol>-k<K>.npz`.
#[derive(Debug, Clone)]
pub struct BasisCache {
    dir: PathBuf,
}

impl BasisCache {
    /// A cache in `dir` (created on first write).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        BasisCache { dir: dir.into() }
    }

    /// `$FUNCORR_CACHE_DIR`, else `$XDG_CACHE_HOME/funcorr`, else `$HOME/.cache/funcorr`.
    pub fn default_dir() -> Option<PathBuf> {
        let env = |v: &str| std::env::var_os(v).filter(|s| !s.is_empty()).map(PathBuf::from);
        env("FUNCORR_CACHE_DIR")
            .or_else(|| env("XDG_CACHE_HOME").map(|p| p.join("funcorr")))
            .or_else(|| env("HOME").map(|p| p.join(".cache").join("funcorr")))
    }

    /// The cache directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Key of a Laplacian: a hash of n, the sparsity pattern and values of W, and A.
    pub fn key(lap: &Laplacian) -> String {
        let mut h = Fnv::new();
        h.write_pattern(lap);
        for v in lap.w.val().iter().chain(&lap.mass) {
            h.write(&v.to_bits().to_le_bytes());
        }
        format!("{:016x}", h.0)
    }

    /// The cached basis for `key` with the fewest eigenpairs k' ≥ k among those computed with a
    /// tolerance ≤ `tol`, truncated to k. Unreadable, corrupt (CRC-32) or mismatched files are
    /// skipped with a warning on stderr: the next candidate is tried, and `None` means the caller
    /// recomputes.
    pub fn get(&self, key: &str, n: usize, k: usize, tol: f64) -> Option<Basis> {
        let prefix = format!("{key}-tol");
        let mut candidates: Vec<(usize, PathBuf)> = Vec::new();
        for entry in std::fs::read_dir(&self.dir).ok()?.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let Some((t, kk)) = name
                .strip_prefix(&prefix)
                .and_then(|r| r.strip_suffix(".npz"))
                .and_then(|r| r.split_once("-k"))
                .and_then(|(t, kk)| Some((t.parse::<f64>().ok()?, kk.parse::<usize>().ok()?)))
            else {
                continue;
            };
            if kk >= k && t <= tol {
                candidates.push((kk, entry.path()));
            }
        }
        candidates.sort();
        candidates.into_iter().find_map(|(_, path)| {
            // A damaged entry is a miss, said out loud (the basis is recomputed and rewritten).
            let basis = load_entry(&path)
                .and_then(|b| match b.n() == n {
                    true => Ok(b),
                    false => Err(Error::parse(&path, None, format!("{} rows, expected {n}", b.n()))),
                })
                .map_err(|e| eprintln!("warning: ignoring a damaged cached eigenbasis ({e}); recomputing"))
                .ok()?;
            basis.truncate(k).ok()
        })
    }

    /// Stores `basis`, computed with tolerance `tol`, under `key` (whole or not at all; concurrent
    /// writers of the same entry all succeed).
    /// Removes the orphaned temporaries of killed writers first (see the module documentation).
    pub fn put(&self, key: &str, basis: &Basis, tol: f64) -> Result<()> {
        std::fs::create_dir_all(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        self.sweep_orphans();
        save_basis(&self.dir.join(format!("{key}-tol{tol:e}-k{}.npz", basis.k())), basis)
    }

    /// Removes the hidden temporaries of entries (`.<…>.npz.<pid>-<n>.tmp`) that were not
    /// modified for [`ORPHAN_AGE`]; links and anything else are left alone. Failures are ignored
    /// (another process may sweep the same file).
    fn sweep_orphans(&self) {
        let Ok(dir) = crate::io::beneath::Dir::open(&self.dir) else { return };
        let Ok(entries) = std::fs::read_dir(&self.dir) else { return };
        let now = std::time::SystemTime::now();
        for entry in entries.flatten() {
            let name = entry.file_name();
            let Some(name) = name.to_str() else { continue };
            if !is_entry_temporary(name) || !entry.file_type().is_ok_and(|t| t.is_file()) {
                continue;
            }
            let age = entry.metadata().and_then(|m| m.modified()).ok().and_then(|t| now.duration_since(t).ok());
            if age.is_some_and(|a| a > ORPHAN_AGE) {
                let _ = dir.remove_file(name);
            }
        }
    }
}

/// Whether `name` is the temporary of a cache entry's writer: `.<entry>.npz.<pid>-<n>.tmp`.
fn is_entry_temporary(name: &str) -> bool {
    let Some(rest) = name.strip_prefix('.').and_then(|r| r.strip_suffix(".tmp")) else { return false };
    let Some((entry, id)) = rest.rsplit_once(".npz.") else { return false };
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    !entry.is_empty() && id.split_once('-').is_some_and(|(pid, n)| digits(pid) && digits(n))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laplacian::cotangent;
    use crate::primitives::icosphere;
    use crate::spectral::{eigen_basis, SpectralOptions};

    /// The Laplacian of an icosphere, its first 12 eigenpairs and an empty directory `name`.
    fn sphere_basis_and_dir(name: &str) -> (Laplacian, Basis, PathBuf) {
        let lap = cotangent(&icosphere(2)).unwrap();
        let (b, _) = eigen_basis(&lap, &SpectralOptions::new(12), None).unwrap();
        let dir = std::env::temp_dir().join(format!("funcorr-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        (lap, b, dir)
    }

    #[test]
    fn basis_round_trip_and_cache() {
        let (lap, b, dir) = sphere_basis_and_dir("cache-test");
        let file = dir.join("b.npz");
        std::fs::create_dir_all(&dir).unwrap();
        save_basis(&file, &b).unwrap();
        let r = load_basis(&file).unwrap();
        assert_eq!(r.eigenvalues, b.eigenvalues);
        assert_eq!(r.mass, b.mass);
        assert_eq!(r.eigenvectors, b.eigenvectors);

        let cache = BasisCache::new(dir.join("cache"));
        let key = BasisCache::key(&lap);
        let tol = 1e-8;
        assert!(cache.get(&key, lap.n(), 5, tol).is_none());
        cache.put(&key, &b, tol).unwrap();
        let t = cache.get(&key, lap.n(), 5, tol).unwrap();
        assert_eq!(t.k(), 5);
        assert_eq!(t.eigenvalues[..], b.eigenvalues[..5]);
        assert!(cache.get(&key, lap.n(), 13, tol).is_none(), "cannot serve more eigenpairs than stored");
        assert!(cache.get(&key, lap.n() + 1, 5, tol).is_none());
        // The tolerance is part of the entry: a 1e-8 basis serves 1e-5, not 1e-13.
        assert!(cache.get(&key, lap.n(), 5, 1e-5).is_some());
        assert!(cache.get(&key, lap.n(), 5, 1e-13).is_none());
        // A different Laplacian has a different key.
        let other = cotangent(&icosphere(1)).unwrap();
        assert_ne!(BasisCache::key(&other), key);
        // A corrupt file is ignored, not an error.
        std::fs::write(cache.dir().join(format!("{key}-tol1e-8-k20.npz")), b"garbage").unwrap();
        assert!(cache.get(&key, lap.n(), 13, tol).is_none());
        assert!(load_basis(&cache.dir().join(format!("{key}-tol1e-8-k20.npz"))).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn fifos_and_links_are_misses_and_orphaned_temporaries_are_swept() {
        let (lap, b, dir) = sphere_basis_and_dir("cache-hostile");
        let cache = BasisCache::new(&dir);
        let key = BasisCache::key(&lap);
        cache.put(&key, &b, 1e-8).unwrap();
        let entry = std::fs::read_dir(&dir).unwrap().next().unwrap().unwrap().path();
        // A FIFO in place of the entry: a miss at once, not a hang.
        std::fs::remove_file(&entry).unwrap();
        let c = std::ffi::CString::new(entry.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        assert!(cache.get(&key, lap.n(), 12, 1e-8).is_none());
        // A link to a good basis elsewhere: not followed.
        std::fs::remove_file(&entry).unwrap();
        let elsewhere = dir.with_extension("elsewhere.npz");
        save_basis(&elsewhere, &b).unwrap();
        std::os::unix::fs::symlink(&elsewhere, &entry).unwrap();
        assert!(cache.get(&key, lap.n(), 12, 1e-8).is_none(), "a link was followed");
        std::fs::remove_file(&entry).unwrap();
        std::fs::remove_file(&elsewhere).unwrap();
        // Temporaries: an old one is an orphan, a fresh one a writer at work; other names stay.
        let name = entry.file_name().unwrap().to_str().unwrap().to_string();
        let old = dir.join(format!(".{name}.4242-7.tmp"));
        let fresh = dir.join(format!(".{name}.4242-8.tmp"));
        let other = dir.join(".notes.tmp");
        for p in [&old, &fresh, &other] {
            std::fs::write(p, "partial").unwrap();
        }
        let then = std::time::SystemTime::now() - 2 * ORPHAN_AGE;
        for p in [&old, &other] {
            std::fs::File::options().write(true).open(p).unwrap().set_modified(then).unwrap();
        }
        cache.put(&key, &b, 1e-8).unwrap();
        assert!(!old.exists() && fresh.exists() && other.exists());
        assert!(cache.get(&key, lap.n(), 12, 1e-8).is_some());
        assert!(is_entry_temporary(".0123abcd-tol1e-8-k12.npz.17-0.tmp"));
        for bad in [".x.npz.17-.tmp", "x.npz.1-2.tmp", ".x.npz.a-2.tmp", ".npz.1-2.tmp", ".x.npz.1-2"] {
            assert!(!is_entry_temporary(bad), "{bad}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_corrupt_byte_is_a_miss_and_concurrent_writers_all_succeed() {
        let (lap, b, dir) = sphere_basis_and_dir("cache-crc");
        let cache = BasisCache::new(&dir);
        let key = BasisCache::key(&lap);
        // Four writers of the same entry at once: all succeed, the entry is complete.
        std::thread::scope(|s| {
            for _ in 0..4 {
                s.spawn(|| cache.put(&key, &b, 1e-8).unwrap());
            }
        });
        let entries: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().map(|e| e.path()).collect();
        assert_eq!(entries.len(), 1, "one entry, no temporary files: {entries:?}");
        assert_eq!(cache.get(&key, lap.n(), 12, 1e-8).unwrap().eigenvectors, b.eigenvectors);
        // Flip one bit in the middle of the eigenvectors: the CRC-32 no longer matches.
        let mut bytes = std::fs::read(&entries[0]).unwrap();
        let mid = bytes.len() / 2;
        bytes[mid] ^= 0x10;
        std::fs::write(&entries[0], &bytes).unwrap();
        assert!(load_basis(&entries[0]).is_err(), "a corrupt basis file is an error");
        assert!(cache.get(&key, lap.n(), 12, 1e-8).is_none(), "a corrupt entry is a miss");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

//! NumPy arrays: `.npy` files and uncompressed `.npz` archives (as written by `np.savez`).
//!
//! Readable dtypes: `f4`/`f8` (to `f64`) and the signed/unsigned integers of 1, 2, 4 and 8 bytes
//! (to `i64`), either byte order, C or Fortran order (always returned in C order). Written
//! arrays are little-endian `f8`/`i8`/`u8` in C order.

use std::fs::File;
use std::io::{self, BufReader, ErrorKind, Read, Write};
use std::path::Path;

use npyz::{
    AutoSerialize, DType, Deserialize, NpyFile, NpyHeader, Order, Serialize, TypeChar, WriteOptions, WriterBuilder,
};
use zip::result::ZipError;
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipArchive, ZipWriter};

use super::text::clip;
use super::{bounded_capacity, write_file, DenseMatrix};
use crate::error::{Error, Result};

/// One array of an `.npz` archive, with its shape and its elements in C (row-major) order;
/// `data.len()` is the product of `shape` (1 for a 0-d array).
#[derive(Debug, Clone, PartialEq)]
pub enum NpzArray {
    /// Floating-point array (read from `f4` or `f8`, written as `f8`).
    F64 {
        /// Dimensions.
        shape: Vec<usize>,
        /// Elements in C order.
        data: Vec<f64>,
    },
    /// Integer array (read from any integer dtype that fits, written as `i8`).
    I64 {
        /// Dimensions.
        shape: Vec<usize>,
        /// Elements in C order.
        data: Vec<i64>,
    },
}

/// Largest `.npy` header accepted (numpy itself refuses more than 10 000 bytes by default).
const MAX_HEADER: usize = 1 << 20;
/// Most elements reserved ahead when the input length is unknown.
const RESERVE_LIMIT: usize = 1 << 20;

/// Reads a 1-D (`n × 1`) or 2-D `.npy` array of finite numbers as a row-major matrix.
///
/// Errors ([`Error::Parse`]): bad magic or header, unsupported dtype (see the module
/// documentation), other numbers of dimensions, data shorter than the shape, non-finite values.
pub fn read_npy_matrix(path: &Path) -> Result<DenseMatrix> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    to_matrix(read_array(BufReader::new(file), path, Some(len), true)?, path)
}

/// [`read_npy_matrix`] from any reader; `path` is only used in error messages.
pub fn read_npy_matrix_from<R: Read>(r: R, path: &Path) -> Result<DenseMatrix> {
    to_matrix(read_array(r, path, None, true)?, path)
}

fn to_matrix(a: NpzArray, path: &Path) -> Result<DenseMatrix> {
    let (shape, data) = match a {
        NpzArray::F64 { shape, data } => (shape, data),
        NpzArray::I64 { shape, data } => (shape, data.into_iter().map(|v| v as f64).collect()),
    };
    let (rows, cols) = (shape[0], shape.get(1).copied().unwrap_or(1));
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        let msg = format!("element ({}, {}): expected a finite number, found {}", i / cols, i % cols, data[i]);
        return Err(Error::parse(path, None, msg));
    }
    Ok(DenseMatrix { rows, cols, data })
}

/// Reads the `shape` tuple from a header dict, e.g. `{'descr': '<f8', 'shape': (3, 4), ...}`.
fn header_shape(text: &str) -> Option<Vec<u64>> {
    let at = text.find("'shape'").or_else(|| text.find("\"shape\""))?;
    let rest = text[at + 7..].trim_start().strip_prefix(':')?.trim_start();
    let close = match rest.chars().next()? {
        '(' => ')',
        '[' => ']',
        _ => return None,
    };
    let inner = &rest[1..rest.find(close)?];
    inner.split(',').map(str::trim).filter(|s| !s.is_empty()).map(|s| s.parse().ok()).collect()
}

/// Reads one `.npy` array from `r`. `len`, when known, is the input size in bytes: the data the
/// header announces must fit in it. With `matrix`, only 1-D and 2-D arrays are accepted.
fn read_array<R: Read>(mut r: R, path: &Path, len: Option<u64>, matrix: bool) -> Result<NpzArray> {
    let err = |msg: String| Error::parse(path, None, msg);
    let read = |r: &mut R, buf: &mut [u8], what: &str| {
        r.read_exact(buf).map_err(|e| match e.kind() {
            ErrorKind::UnexpectedEof => err(format!("truncated file: expected {what}, found end of file")),
            _ => Error::io(path, e),
        })
    };
    // Magic, version and header length (npyz reads them again from `head`).
    let mut head = vec![0u8; 10];
    read(&mut r, &mut head, "the .npy magic \\x93NUMPY, version and header length")?;
    if &head[..6] != b"\x93NUMPY" {
        return Err(err(format!("expected the .npy magic \\x93NUMPY, found '{}'", head[..6].escape_ascii())));
    }
    let hlen = match head[6] {
        1 => usize::from(u16::from_le_bytes([head[8], head[9]])),
        2 | 3 => {
            head.resize(12, 0);
            read(&mut r, &mut head[10..], "the header length")?;
            u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as usize
        }
        v => return Err(err(format!("expected .npy format version 1, 2 or 3, found {v}"))),
    };
    if hlen > MAX_HEADER {
        return Err(err(format!("expected a header of at most {MAX_HEADER} bytes, found a length of {hlen}")));
    }
    let start = head.len();
    head.resize(start + hlen, 0);
    read(&mut r, &mut head[start..], &format!("a {hlen}-byte header"))?;
    let text = String::from_utf8_lossy(&head[start..]);

    // Check the shape before npyz computes with it (its products are unchecked).
    let shape = header_shape(&text).ok_or_else(|| {
        err(format!("expected a 'shape' tuple of integers in the header, found '{}'", clip(text.trim())))
    })?;
    if matrix && !(1..=2).contains(&shape.len()) {
        return Err(err(format!("expected a 1-D or 2-D array, found shape {shape:?}")));
    }
    // Every partial product of the dimensions (zeros aside) must fit in u64.
    if shape.iter().try_fold(1u64, |a, &d| a.checked_mul(d.max(1))).is_none() {
        return Err(err(format!("expected a valid shape, found {shape:?} (too many elements)")));
    }
    let n: u64 = shape.iter().product();
    let header = NpyHeader::from_reader(&head[..]).map_err(|e| err(format!("invalid .npy header: {e}")))?;
    let descr = header.dtype().descr();
    let (kind, size) = match header.dtype() {
        DType::Plain(t) => (t.type_char(), t.size_field()),
        _ => (TypeChar::Bool, 0),
    };
    let (Some(bytes), true) = (n.checked_mul(size), header.shape() == shape.as_slice()) else {
        return Err(err(format!("expected a valid shape, found {shape:?} of {descr}")));
    };
    if let Some(len) = len {
        let avail = len.saturating_sub(head.len() as u64);
        if bytes > avail {
            return Err(err(format!(
                "truncated file: shape {shape:?} of {descr} needs {bytes} data bytes, found {avail}"
            )));
        }
    }
    // Without a known length, reserve a bounded amount and let the vectors grow with the data.
    let cap = if len.is_some() { n as usize } else { bounded_capacity(n, RESERVE_LIMIT) };
    let fortran = header.order() == Order::Fortran;
    let npy = NpyFile::with_header(header, r);
    let shape: Vec<usize> = shape.into_iter().map(|d| d as usize).collect();
    let mut arr = match (kind, size) {
        (TypeChar::Float, 4) => NpzArray::F64 { data: collect(npy, n, cap, path, |v: f32| Some(f64::from(v)))?, shape },
        (TypeChar::Float, 8) => NpzArray::F64 { data: collect(npy, n, cap, path, Some)?, shape },
        (TypeChar::Int, 1) => NpzArray::I64 { data: collect(npy, n, cap, path, |v: i8| Some(i64::from(v)))?, shape },
        (TypeChar::Int, 2) => NpzArray::I64 { data: collect(npy, n, cap, path, |v: i16| Some(i64::from(v)))?, shape },
        (TypeChar::Int, 4) => NpzArray::I64 { data: collect(npy, n, cap, path, |v: i32| Some(i64::from(v)))?, shape },
        (TypeChar::Int, 8) => NpzArray::I64 { data: collect(npy, n, cap, path, Some)?, shape },
        (TypeChar::Uint, 1) => NpzArray::I64 { data: collect(npy, n, cap, path, |v: u8| Some(i64::from(v)))?, shape },
        (TypeChar::Uint, 2) => NpzArray::I64 { data: collect(npy, n, cap, path, |v: u16| Some(i64::from(v)))?, shape },
        (TypeChar::Uint, 4) => NpzArray::I64 { data: collect(npy, n, cap, path, |v: u32| Some(i64::from(v)))?, shape },
        (TypeChar::Uint, 8) => {
            NpzArray::I64 { data: collect(npy, n, cap, path, |v: u64| i64::try_from(v).ok())?, shape }
        }
        _ => return Err(err(format!("expected dtype float32/float64 or an integer type, found {descr}"))),
    };
    if fortran {
        match &mut arr {
            NpzArray::F64 { shape, data } => *data = fortran_to_c(data, shape),
            NpzArray::I64 { shape, data } => *data = fortran_to_c(data, shape),
        }
    }
    Ok(arr)
}

/// Reads the `n` elements of `npy` as `T`, converting each with `conv` (`None` = does not fit).
fn collect<T: Deserialize, U, R: Read>(
    npy: NpyFile<R>,
    n: u64,
    cap: usize,
    path: &Path,
    conv: impl Fn(T) -> Option<U>,
) -> Result<Vec<U>> {
    let err = |msg: String| Error::parse(path, None, msg);
    let reader = npy.data::<T>().map_err(|e| err(format!("unsupported dtype: {e}")))?;
    let mut out = Vec::with_capacity(cap);
    for (i, v) in reader.enumerate() {
        let v = v.map_err(|e| match e.kind() {
            ErrorKind::UnexpectedEof => err(format!("truncated file: expected {n} elements, found {i}")),
            _ => Error::io(path, e),
        })?;
        out.push(
            conv(v)
                .ok_or_else(|| err(format!("element {i}: expected a value that fits in i64, found a larger uint64")))?,
        );
    }
    Ok(out)
}

/// Reorders elements stored in Fortran order (first index fastest) into C order.
fn fortran_to_c<T: Copy>(data: &[T], shape: &[usize]) -> Vec<T> {
    let mut stride = vec![1; shape.len()];
    for k in 1..shape.len() {
        stride[k] = stride[k - 1] * shape[k - 1];
    }
    let mut idx = vec![0; shape.len()];
    let mut out = Vec::with_capacity(data.len());
    for _ in 0..data.len() {
        out.push(data[idx.iter().zip(&stride).map(|(i, s)| i * s).sum::<usize>()]);
        for k in (0..shape.len()).rev() {
            idx[k] += 1;
            if idx[k] < shape[k] {
                break;
            }
            idx[k] = 0;
        }
    }
    out
}

/// Checks that `shape` holds exactly `len` elements.
fn check_shape(shape: &[usize], len: usize, what: &str) -> Result<()> {
    match shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d)) {
        Some(n) if n == len => Ok(()),
        _ => Err(Error::invalid(what, format!("shape {shape:?} does not hold the {len} elements given"))),
    }
}

/// Writes `data` as a little-endian, C-order `.npy` array of the given shape.
fn write_array<W: Write, T: Serialize + AutoSerialize + Copy>(w: W, shape: &[usize], data: &[T]) -> io::Result<()> {
    let shape: Vec<u64> = shape.iter().map(|&d| d as u64).collect();
    let mut npy = WriteOptions::new().default_dtype().shape(&shape).writer(w).begin_nd()?;
    npy.extend(data.iter().copied())?;
    npy.finish()
}

fn write_npy<T: Serialize + AutoSerialize + Copy>(path: &Path, shape: &[usize], data: &[T]) -> Result<()> {
    check_shape(shape, data.len(), "array")?;
    write_file(path, |w| write_array(w, shape, data).map_err(|e| Error::io(path, e)))
}

/// Writes a matrix as a 2-D `rows × cols` little-endian `f8` `.npy` file in C order
/// (whole or not at all: a temporary file beside it, then a rename).
///
/// Errors: [`Error::Invalid`] when `data.len() != rows * cols`, [`Error::Io`] on write failure.
pub fn write_npy_matrix(path: &Path, m: &DenseMatrix) -> Result<()> {
    write_npy(path, &[m.rows, m.cols], &m.data)
}

/// Writes a 1-D little-endian `f8` `.npy` file.
pub fn write_npy_vec_f64(path: &Path, v: &[f64]) -> Result<()> {
    write_npy(path, &[v.len()], v)
}

/// Writes a 1-D little-endian `u8` (unsigned 64-bit) `.npy` file, e.g. a vertex map.
pub fn write_npy_vec_u64(path: &Path, v: &[u64]) -> Result<()> {
    write_npy(path, &[v.len()], v)
}

fn zip_error(path: &Path, e: ZipError) -> Error {
    match e {
        ZipError::Io(e) if e.kind() != ErrorKind::UnexpectedEof => Error::io(path, e),
        e => Error::parse(path, None, format!("expected a valid zip (.npz) archive: {e}")),
    }
}

/// Writes arrays to an uncompressed `.npz` archive (what `np.savez` writes): member `name.npy`
/// for each `(name, array)`, little-endian, C order. Written whole or not at all (a temporary file, then a rename).
///
/// Errors: [`Error::Invalid`] for an empty or repeated name or a shape that does not match the
/// data length, [`Error::Io`] on write failure.
pub fn write_npz(path: &Path, arrays: &[(&str, NpzArray)]) -> Result<()> {
    for (i, (name, a)) in arrays.iter().enumerate() {
        if name.is_empty() || arrays[..i].iter().any(|(n, _)| n == name) {
            return Err(Error::invalid(
                "npz arrays",
                format!("expected unique non-empty names, found '{name}' at position {i}"),
            ));
        }
        match a {
            NpzArray::F64 { shape, data } => check_shape(shape, data.len(), name)?,
            NpzArray::I64 { shape, data } => check_shape(shape, data.len(), name)?,
        }
    }
    write_file(path, |w| {
        // The zip writer finalizes itself when dropped and prints a failure of that to stderr
        // ("ZipWriter drop failed"); behind a `Fuse` its writes after the first I/O error go
        // nowhere, so the drop succeeds quietly and the first error is returned, naming `path`.
        let mut fuse = Fuse { inner: w, failed: None, pos: 0, end: 0 };
        let written = write_members(&mut fuse, arrays, path);
        match fuse.failed.take() {
            Some(e) => Err(Error::io(path, e)),
            None => written,
        }
    })
}

/// The members of an `.npz` archive into `w` (see [`write_npz`]); the archive is finished
/// explicitly, so that its errors are returned rather than printed by the writer's drop.
fn write_members<W: Write + io::Seek>(w: W, arrays: &[(&str, NpzArray)], path: &Path) -> Result<()> {
    let io = |e| Error::io(path, e);
    let mut zip = ZipWriter::new(w);
    {
        for (name, a) in arrays {
            let len = match a {
                NpzArray::F64 { data, .. } => data.len(),
                NpzArray::I64 { data, .. } => data.len(),
            };
            let opts = SimpleFileOptions::default()
                .compression_method(CompressionMethod::Stored)
                .large_file(len as u64 * 8 >= u64::from(u32::MAX) / 2);
            zip.start_file(format!("{name}.npy"), opts).map_err(|e| zip_error(path, e))?;
            match a {
                NpzArray::F64 { shape, data } => write_array(&mut zip, shape, data).map_err(io)?,
                NpzArray::I64 { shape, data } => write_array(&mut zip, shape, data).map_err(io)?,
            }
        }
    }
    zip.finish().map_err(|e| zip_error(path, e))?;
    Ok(())
}

/// A writer that keeps the first I/O error of `inner` and, after it, accepts every write and
/// seek without doing anything (tracking only the position), so that a writer which retries
/// on drop (the zip writer) fails once, never twice.
struct Fuse<W> {
    inner: W,
    failed: Option<io::Error>,
    pos: u64,
    end: u64,
}

impl<W> Fuse<W> {
    fn fail(&mut self, e: io::Error) -> io::Error {
        let copy = io::Error::new(e.kind(), e.to_string());
        self.failed = Some(e);
        copy
    }
}

impl<W: Write> Write for Fuse<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.failed.is_some() {
            self.pos += buf.len() as u64;
            self.end = self.end.max(self.pos);
            return Ok(buf.len());
        }
        match self.inner.write(buf) {
            Ok(n) => {
                self.pos += n as u64;
                self.end = self.end.max(self.pos);
                Ok(n)
            }
            Err(e) if e.kind() == ErrorKind::Interrupted => Err(e),
            Err(e) => Err(self.fail(e)),
        }
    }
    fn flush(&mut self) -> io::Result<()> {
        if self.failed.is_some() {
            return Ok(());
        }
        self.inner.flush().map_err(|e| self.fail(e))
    }
}

impl<W: io::Seek> io::Seek for Fuse<W> {
    fn seek(&mut self, to: io::SeekFrom) -> io::Result<u64> {
        if self.failed.is_some() {
            let base = match to {
                io::SeekFrom::Start(p) => Some(p),
                io::SeekFrom::Current(d) => self.pos.checked_add_signed(d),
                io::SeekFrom::End(d) => self.end.checked_add_signed(d),
            };
            self.pos = base.ok_or_else(|| io::Error::from(ErrorKind::InvalidInput))?;
            return Ok(self.pos);
        }
        match self.inner.seek(to) {
            Ok(p) => {
                self.pos = p;
                self.end = self.end.max(p);
                Ok(p)
            }
            Err(e) => Err(self.fail(e)),
        }
    }
}

/// Reads every array of an uncompressed `.npz` archive, in archive order, as `(name, array)`
/// with the `.npy` suffix stripped from the member name. Values are returned as stored
/// (non-finite floats included).
///
/// Errors ([`Error::Parse`], naming `path/member` for member problems): not a zip archive, a
/// member that is not `.npy`, a compressed member (`np.savez_compressed` output is unsupported:
/// this build has no deflate decoder), or an invalid array (see [`read_npy_matrix`]).
pub fn read_npz(path: &Path) -> Result<Vec<(String, NpzArray)>> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    read_npz_from(BufReader::new(file), len, path)
}

/// [`read_npz`] from a seekable reader of `len` bytes (e.g. an in-memory archive); `path` is
/// only used in error messages.
pub fn read_npz_from<R: std::io::Read + std::io::Seek>(r: R, len: u64, path: &Path) -> Result<Vec<(String, NpzArray)>> {
    let mut zip = ZipArchive::new(r).map_err(|e| zip_error(path, e))?;
    let mut out = Vec::with_capacity(zip.len());
    for i in 0..zip.len() {
        let (name, method, size) = {
            let f = zip.by_index_raw(i).map_err(|e| zip_error(path, e))?;
            (f.name().to_string(), f.compression(), f.size())
        };
        if name.ends_with('/') {
            continue;
        }
        let member = path.join(&name);
        let Some(key) = name.strip_suffix(".npy") else {
            return Err(Error::parse(&member, None, "expected a .npy member, found another file"));
        };
        if method != CompressionMethod::Stored {
            let msg = format!("expected an uncompressed member as written by np.savez, found zip compression {method:?} (compressed .npz files, e.g. from np.savez_compressed, are unsupported)");
            return Err(Error::parse(&member, None, msg));
        }
        let mut f = zip.by_index(i).map_err(|e| zip_error(&member, e))?;
        let array = read_array(&mut f, &member, Some(size.min(len)), false)?;
        // Read the member to its end: the zip reader checks the CRC-32 there, so a flipped bit or
        // a zeroed hole anywhere in the member is an error, not silently wrong numbers.
        std::io::copy(&mut f, &mut std::io::sink()).map_err(|e| {
            Error::parse(&member, None, format!("the member does not match its stored CRC-32 (corrupt archive): {e}"))
        })?;
        out.push((key.to_string(), array));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_util::{assert_parse, noise, tmp_dir};

    /// A writer of at most `room` bytes, then "no space left on device".
    struct Full {
        data: std::io::Cursor<Vec<u8>>,
        room: usize,
    }

    impl Write for Full {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            let left = self.room.saturating_sub(self.data.get_ref().len().max(self.data.position() as usize));
            if left == 0 {
                return Err(io::Error::new(ErrorKind::StorageFull, "No space left on device"));
            }
            self.data.write(&buf[..buf.len().min(left)])
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl io::Seek for Full {
        fn seek(&mut self, to: io::SeekFrom) -> io::Result<u64> {
            self.data.seek(to)
        }
    }

    #[test]
    fn a_full_disk_while_zipping_is_one_error_naming_the_file() {
        let arrays = [("a", NpzArray::F64 { shape: vec![4000], data: vec![1.5; 4000] })];
        let path = Path::new("out/b.npz");
        for room in [0, 10, 100, 5000, 32_000, 32_100] {
            let mut fuse = Fuse { inner: Full { data: Default::default(), room }, failed: None, pos: 0, end: 0 };
            let r = write_members(&mut fuse, &arrays, path);
            // The zip writer, dropped inside write_members, found nothing more to fail on.
            let e = match fuse.failed.take() {
                Some(e) => Error::io(path, e),
                None => r.expect_err("the archive cannot fit"),
            };
            let text = e.to_string();
            assert!(text.starts_with("out/b.npz: ") && text.contains("No space left"), "{room}: {text}");
        }
        let mut fuse = Fuse { inner: Full { data: Default::default(), room: 1 << 20 }, failed: None, pos: 0, end: 0 };
        write_members(&mut fuse, &arrays, path).unwrap();
        assert!(fuse.failed.is_none());
        let bytes = fuse.inner.data.into_inner();
        let back = read_npz_from(std::io::Cursor::new(&bytes), bytes.len() as u64, path).unwrap();
        assert_eq!(back[0].1, arrays[0].1);
    }

    /// A version-1 `.npy` file with the given header fields and raw data bytes.
    fn npy(descr: &str, fortran: bool, shape: &str, data: &[u8]) -> Vec<u8> {
        let order = if fortran { "True" } else { "False" };
        npy_raw(&format!("{{'descr': '{descr}', 'fortran_order': {order}, 'shape': {shape}, }}"), data)
    }

    /// A version-1 `.npy` file with the header dict `dict`.
    fn npy_raw(dict: &str, data: &[u8]) -> Vec<u8> {
        let mut h = dict.to_string();
        while !(10 + h.len() + 1).is_multiple_of(64) {
            h.push(' ');
        }
        h.push('\n');
        [&b"\x93NUMPY\x01\x00"[..], &(h.len() as u16).to_le_bytes(), h.as_bytes(), data].concat()
    }

    fn read(b: &[u8]) -> Result<DenseMatrix> {
        read_npy_matrix_from(b, Path::new("t.npy"))
    }

    fn bytes<const N: usize>(v: impl IntoIterator<Item = [u8; N]>) -> Vec<u8> {
        v.into_iter().flatten().collect()
    }

    #[test]
    fn reads_dtypes_byte_orders_and_fortran_order() {
        let m = |rows, cols, data: &[f64]| DenseMatrix { rows, cols, data: data.to_vec() };
        let le8 = bytes([1.5f64, 2., 3., 4., 5., 6.].map(f64::to_le_bytes));
        assert_eq!(read(&npy("<f8", false, "(2, 3)", &le8)).unwrap(), m(2, 3, &[1.5, 2., 3., 4., 5., 6.]));
        let be4 = bytes([1.5f32, 2., 3., 4., 5., 6.].map(f32::to_be_bytes));
        assert_eq!(read(&npy(">f4", false, "(3, 2)", &be4)).unwrap(), m(3, 2, &[1.5, 2., 3., 4., 5., 6.]));
        // Fortran order: stored column by column.
        let f = bytes([1i32, 4, 2, 5, 3, 6].map(i32::to_le_bytes));
        assert_eq!(read(&npy("<i4", true, "(2, 3)", &f)).unwrap(), m(2, 3, &[1., 2., 3., 4., 5., 6.]));
        let be8 = bytes([1.0f64, 4., 2., 5., 3., 6.].map(f64::to_be_bytes));
        assert_eq!(read(&npy(">f8", true, "(2, 3)", &be8)).unwrap(), m(2, 3, &[1., 2., 3., 4., 5., 6.]));
        assert_eq!(read(&npy("|u1", false, "(3,)", &[7, 8, 255])).unwrap(), m(3, 1, &[7., 8., 255.]));
        let i2 = bytes([-3i16, 9].map(i16::to_be_bytes));
        assert_eq!(read(&npy(">i2", false, "(1, 2)", &i2)).unwrap(), m(1, 2, &[-3., 9.]));
        let u8s = bytes([5u64, 1 << 40].map(u64::to_le_bytes));
        assert_eq!(read(&npy("<u8", false, "(2,)", &u8s)).unwrap(), m(2, 1, &[5., (1u64 << 40) as f64]));
        assert_eq!(read(&npy("<f8", false, "(0, 3)", &[])).unwrap(), m(0, 3, &[]));
    }

    #[test]
    fn write_read_round_trip() {
        let d = tmp_dir("npy_rt");
        let m = DenseMatrix { rows: 2, cols: 3, data: vec![0.1, -2.5e-300, 1e22, f64::MAX, 5e-324, 1.0 / 3.0] };
        let p = d.join("m.npy");
        write_npy_matrix(&p, &m).unwrap();
        assert_eq!(read_npy_matrix(&p).unwrap(), m);
        assert!(!d.join("m.npy.tmp").exists());
        write_npy_vec_f64(&p, &[1.0, 2.5]).unwrap();
        assert_eq!(read_npy_matrix(&p).unwrap(), DenseMatrix { rows: 2, cols: 1, data: vec![1.0, 2.5] });
        write_npy_vec_u64(&p, &[3, 1 << 50]).unwrap();
        assert_eq!(read_npy_matrix(&p).unwrap().data, vec![3.0, (1u64 << 50) as f64]);
        let bad = DenseMatrix { rows: 2, cols: 2, data: vec![1.0] };
        assert!(matches!(write_npy_matrix(&p, &bad), Err(Error::Invalid { .. })));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn bad_npy() {
        let f8 = |n: usize| bytes((0..n).map(|i| (i as f64).to_le_bytes()));
        assert_parse(read(b""), Some(None), "truncated file: expected the .npy magic");
        assert_parse(read(b"\x93NUMPY\x01"), Some(None), "truncated file");
        assert_parse(read(b"PK\x03\x04 not npy at all"), Some(None), "expected the .npy magic \\x93NUMPY, found 'PK");
        assert_parse(read(&noise(1000, 3)), Some(None), "expected the .npy magic");
        assert_parse(
            read(&npy("<f8", false, "(2, 2, 2)", &f8(8))),
            Some(None),
            "expected a 1-D or 2-D array, found shape [2, 2, 2]",
        );
        assert_parse(read(&npy("<f8", false, "()", &f8(1))), Some(None), "found shape []");
        assert_parse(
            read(&npy("<c16", false, "(2,)", &f8(4))),
            Some(None),
            "expected dtype float32/float64 or an integer type, found '<c16'",
        );
        assert_parse(read(&npy("<f2", false, "(2,)", &[0; 4])), Some(None), "found '<f2'");
        assert_parse(read(&npy("|b1", false, "(2,)", &[0; 2])), Some(None), "found '|b1'");
        assert_parse(read(&npy("<U3", false, "(2,)", &[0; 24])), Some(None), "found '<U3'");
        assert_parse(read(&npy("x", false, "(2,)", &f8(2))), Some(None), "invalid .npy header");
        let structured =
            npy_raw("{'descr': [('a', '<f8'), ('b', '<i4')], 'fortran_order': False, 'shape': (2,), }", &[0; 24]);
        assert_parse(
            read(&structured),
            Some(None),
            "expected dtype float32/float64 or an integer type, found [('a', '<f8'), ('b', '<i4')",
        );
        let no_shape = npy_raw("{'descr': '<f8', 'fortran_order': False, }", &f8(1));
        assert_parse(read(&no_shape), Some(None), "expected a 'shape' tuple");
        assert_parse(
            read(&npy("<f8", false, "(2, 3)", &f8(5))),
            Some(None),
            "truncated file: expected 6 elements, found 5",
        );
        assert_parse(
            read(&npy("<f8", false, "(2, 3)", &f8(6)[..44])),
            Some(None),
            "truncated file: expected 6 elements, found 5",
        );
        assert_parse(read(&npy("<f8", false, "(2, 'a')", &f8(6))), Some(None), "expected a 'shape' tuple of integers");
        assert_parse(read(&npy("<f8", false, "(-2, 3)", &f8(6))), Some(None), "expected a 'shape' tuple");
        let mut nan = f8(4);
        nan[24..].copy_from_slice(&f64::NAN.to_le_bytes());
        assert_parse(
            read(&npy("<f8", false, "(2, 2)", &nan)),
            Some(None),
            "element (1, 1): expected a finite number, found NaN",
        );
        let mut wrong_version = npy("<f8", false, "(1,)", &f8(1));
        wrong_version[6] = 9;
        assert_parse(read(&wrong_version), Some(None), "expected .npy format version 1, 2 or 3, found 9");
        let huge_header = [&b"\x93NUMPY\x02\x00"[..], &u32::MAX.to_le_bytes(), b"{}"].concat();
        assert_parse(read(&huge_header), Some(None), "expected a header of at most");
        let uint_overflow = bytes([u64::MAX].map(u64::to_le_bytes));
        assert_parse(read_npz_array(&npy("<u8", false, "(1,)", &uint_overflow)), Some(None), "fits in i64");
    }

    fn read_npz_array(b: &[u8]) -> Result<NpzArray> {
        read_array(b, Path::new("t.npy"), Some(b.len() as u64), false)
    }

    #[test]
    fn absurd_shapes_fail_without_huge_allocation() {
        let d = tmp_dir("npy_absurd");
        // Length known (file): rejected before reading.
        let p = d.join("big.npy");
        std::fs::write(&p, npy("<f8", false, "(1000000000000, 3)", &[0; 64])).unwrap();
        assert_parse(read_npy_matrix(&p), Some(None), "needs 24000000000000 data bytes, found 64");
        // Length unknown (reader): bounded reservation, then a truncation error.
        assert_parse(
            read(&npy("<f8", false, "(1000000000000, 3)", &[0; 64])),
            Some(None),
            "truncated file: expected 3000000000000 elements, found 8",
        );
        // Products that overflow u64 are rejected instead of wrapping or panicking.
        assert_parse(read(&npy("<f8", false, "(4294967296, 4294967296)", &[])), Some(None), "expected a valid shape");
        assert_parse(read(&npy("<f8", false, "(18446744073709551615, 2)", &[])), Some(None), "expected a valid shape");
        assert_parse(
            read(&npy("<f8", false, "(0, 18446744073709551615, 18446744073709551615)", &[])),
            Some(None),
            "1-D or 2-D",
        );
        let zero_but_overflowing = npy("<f8", true, "(0, 18446744073709551615, 18446744073709551615)", &[]);
        assert_parse(read_npz_array(&zero_but_overflowing), Some(None), "too many elements");
        let nested = [&b"\x93NUMPY\x01\x00"[..], &50_000u16.to_le_bytes(), &[b'('; 50_000]].concat();
        assert_parse(read(&nested), Some(None), "expected a 'shape' tuple");
        std::fs::remove_dir_all(&d).unwrap();
    }

    fn sample() -> Vec<(&'static str, NpzArray)> {
        vec![
            ("eigenvectors", NpzArray::F64 { shape: vec![3, 2], data: vec![0.1, 0.2, 0.3, -1e-300, 1e22, 6.0] }),
            ("eigenvalues", NpzArray::F64 { shape: vec![4], data: vec![0.0, 1.5, 2.25, f64::INFINITY] }),
            ("landmarks", NpzArray::I64 { shape: vec![2, 2], data: vec![0, -1, i64::MAX, 42] }),
            ("scalar", NpzArray::I64 { shape: vec![], data: vec![7] }),
        ]
    }

    #[test]
    fn npz_round_trip_and_zip_layout() {
        let d = tmp_dir("npz_rt");
        let p = d.join("x.npz");
        write_npz(&p, &sample()).unwrap();
        assert!(!d.join("x.npz.tmp").exists());
        let back = read_npz(&p).unwrap();
        let expected: Vec<(String, NpzArray)> = sample().into_iter().map(|(n, a)| (n.to_string(), a)).collect();
        assert_eq!(back, expected);
        // A valid zip with stored `name.npy` members holding valid .npy files.
        let mut zip = ZipArchive::new(File::open(&p).unwrap()).unwrap();
        let names: Vec<String> = (0..zip.len()).map(|i| zip.by_index(i).unwrap().name().to_string()).collect();
        assert_eq!(names, ["eigenvectors.npy", "eigenvalues.npy", "landmarks.npy", "scalar.npy"]);
        let mut member = zip.by_name("eigenvectors.npy").unwrap();
        assert_eq!(member.compression(), CompressionMethod::Stored);
        let mut raw = Vec::new();
        member.read_to_end(&mut raw).unwrap();
        assert!(raw.starts_with(b"\x93NUMPY"));
        let m = read_npy_matrix_from(&raw[..], Path::new("m")).unwrap();
        assert_eq!((m.rows, m.cols, m.data[3]), (3, 2, -1e-300));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn npz_reads_fortran_and_other_dtypes() {
        let d = tmp_dir("npz_dtypes");
        let p = d.join("y.npz");
        {
            let mut zip = ZipWriter::new(File::create(&p).unwrap());
            let opts = SimpleFileOptions::default().compression_method(CompressionMethod::Stored);
            zip.start_file("f.npy", opts).unwrap();
            zip.write_all(&npy(">f4", true, "(2, 2, 2)", &bytes((0..8).map(|i| (i as f32).to_be_bytes())))).unwrap();
            zip.start_file("u.npy", opts).unwrap();
            zip.write_all(&npy("|u1", false, "(3,)", &[1, 2, 255])).unwrap();
            zip.finish().unwrap();
        }
        let back = read_npz(&p).unwrap();
        // Fortran (i, j, k) is stored at i + 2j + 4k; C order lists (0,0,0), (0,0,1), (0,1,0), ...
        assert_eq!(
            back[0],
            ("f".to_string(), NpzArray::F64 { shape: vec![2, 2, 2], data: vec![0., 4., 2., 6., 1., 5., 3., 7.] })
        );
        assert_eq!(back[1], ("u".to_string(), NpzArray::I64 { shape: vec![3], data: vec![1, 2, 255] }));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn bad_npz() {
        let d = tmp_dir("npz_bad");
        let p = d.join("bad.npz");
        let bad = |arrays: &[(&str, NpzArray)]| matches!(write_npz(&p, arrays), Err(Error::Invalid { .. }));
        assert!(bad(&[("a", NpzArray::F64 { shape: vec![2, 2], data: vec![1.0; 3] })]));
        assert!(bad(&[("a", NpzArray::I64 { shape: vec![1], data: vec![] })]));
        assert!(bad(&[
            ("a", NpzArray::I64 { shape: vec![], data: vec![] }),
            ("a", NpzArray::I64 { shape: vec![0], data: vec![] })
        ]));
        assert!(bad(&[("", NpzArray::I64 { shape: vec![0], data: vec![] })]));
        assert!(!p.exists() && !d.join("bad.npz.tmp").exists());

        for content in [&b""[..], b"not a zip file at all", &noise(3000, 9)] {
            std::fs::write(&p, content).unwrap();
            assert_parse(read_npz(&p), Some(None), "expected a valid zip");
        }
        assert!(matches!(read_npz(&d.join("missing.npz")), Err(Error::Io { .. })));

        // A deflate-compressed member (what np.savez_compressed writes): patch the method fields.
        write_npz(&p, &sample()[..1]).unwrap();
        let mut z = std::fs::read(&p).unwrap();
        for sig in [&b"PK\x03\x04"[..], b"PK\x01\x02"] {
            let at = z.windows(4).position(|w| w == sig).unwrap();
            let field = if sig[2] == 3 { 8 } else { 10 };
            z[at + field] = 8;
        }
        std::fs::write(&p, &z).unwrap();
        assert_parse(read_npz(&p), Some(None), "compressed .npz files, e.g. from np.savez_compressed, are unsupported");

        // Members that are not .npy, or hold a bad array.
        let mut zip = ZipWriter::new(File::create(&p).unwrap());
        let opts = SimpleFileOptions::default().compression_method(CompressionMethod::Stored);
        zip.start_file("a.npy", opts).unwrap();
        zip.write_all(&npy("<f8", false, "(1000000000,)", &[0; 16])).unwrap();
        zip.finish().unwrap();
        match read_npz(&p) {
            Err(Error::Parse { path, msg, .. }) => {
                assert!(path.ends_with("bad.npz/a.npy"), "{path:?}");
                assert!(msg.contains("needs 8000000000 data bytes, found 16"), "{msg}");
            }
            other => panic!("{other:?}"),
        }
        let mut zip = ZipWriter::new(File::create(&p).unwrap());
        zip.start_file("readme.txt", opts).unwrap();
        zip.write_all(b"hello").unwrap();
        zip.finish().unwrap();
        assert_parse(read_npz(&p), Some(None), "expected a .npy member");
        std::fs::remove_dir_all(&d).unwrap();
    }
}

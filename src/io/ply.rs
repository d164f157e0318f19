//! Polygon File Format (`.ply`): `ascii`, `binary_little_endian` and `binary_big_endian` 1.0.
//!
//! Read: any elements in any order (elements other than `vertex` and `face` are decoded and
//! skipped); vertex properties `x`, `y`, `z` of any scalar type, optional `red`/`green`/`blue`
//! (integers 0–255, or floats 0–1), other vertex properties skipped; faces from the list property
//! `vertex_indices` (or `vertex_index`) with any integer count/index types, fan-triangulated.
//! The face element is optional (point clouds). ASCII records are one per line.

use std::borrow::Cow;
use std::io::{BufRead, Read, Write};
use std::path::Path;

use super::text::{clip, parse_tok, LineReader, MAX_LINE};
use super::{
    check_index, check_vertex, color_channel, finish, push_fan, validate_for_write, MeshData, MAX_PLY_BODY, MAX_RECORDS,
};
use crate::error::{Error, Result};

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

/// The first `N` bytes of `b` in little-endian order.
fn le<const N: usize>(b: &[u8], big: bool) -> [u8; N] {
    let mut a = [0; N];
    a.copy_from_slice(&b[..N]);
    if big {
        a.reverse();
    }
    a
}

impl Scalar {
    fn parse(s: &str) -> Option<Self> {
        use Scalar::*;
        Some(match s {
            "char" | "int8" => I8,
            "uchar" | "uint8" => U8,
            "short" | "int16" => I16,
            "ushort" | "uint16" => U16,
            "int" | "int32" => I32,
            "uint" | "uint32" => U32,
            "float" | "float32" => F32,
            "double" | "float64" => F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        use Scalar::*;
        match self {
            I8 | U8 => 1,
            I16 | U16 => 2,
            I32 | U32 | F32 => 4,
            F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes a value from exactly `self.size()` bytes (all types are exact in `f64`).
    fn decode(self, b: &[u8], big: bool) -> f64 {
        use Scalar::*;
        match self {
            I8 => f64::from(b[0] as i8),
            U8 => f64::from(b[0]),
            I16 => f64::from(i16::from_le_bytes(le(b, big))),
            U16 => f64::from(u16::from_le_bytes(le(b, big))),
            I32 => f64::from(i32::from_le_bytes(le(b, big))),
            U32 => f64::from(u32::from_le_bytes(le(b, big))),
            F32 => f64::from(f32::from_le_bytes(le(b, big))),
            F64 => f64::from_le_bytes(le(b, big)),
        }
    }
}

/// A property: a scalar, or a list with its count type and item type.
#[derive(Debug)]
enum Kind {
    Scalar(Scalar),
    List(Scalar, Scalar),
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<(String, Kind)>,
}

impl Element {
    fn prop(&self, names: &[&str]) -> Option<(usize, &Kind)> {
        self.props.iter().enumerate().find(|(_, (n, _))| names.contains(&n.as_str())).map(|(i, (_, k))| (i, k))
    }

    /// Smallest possible size of a record in bytes (ASCII: one character and a separator per value).
    /// Largest size of one record in bytes: binary with every list at its longest (the count
    /// type's maximum, at most [`MAX_RECORDS`] + 2 entries); ASCII one line of at most
    /// [`MAX_LINE`] bytes. Saturates instead of overflowing.
    fn max_record_bytes(&self, ascii: bool) -> u64 {
        if ascii {
            return MAX_LINE as u64 + 1;
        }
        self.props
            .iter()
            .map(|(_, k)| match k {
                Kind::Scalar(t) => t.size() as u64,
                Kind::List(ct, it) => {
                    let longest = (1u64 << (8 * ct.size()).min(63)).min(MAX_RECORDS as u64 + 2);
                    (ct.size() as u64).saturating_add(longest.saturating_mul(it.size() as u64))
                }
            })
            .fold(0u64, u64::saturating_add)
    }

    fn min_record_bytes(&self, ascii: bool) -> u64 {
        let size = |k: &Kind| match k {
            Kind::Scalar(t) | Kind::List(t, _) => t.size() as u64,
        };
        self.props.iter().map(|(_, k)| if ascii { 2 } else { size(k) }).sum()
    }
}

/// Parsed header: format (`None` = ASCII, `Some(big_endian)` = binary), elements, offset of the
/// body, and number of header lines.
struct Header {
    binary: Option<bool>,
    elements: Vec<Element>,
    body: usize,
    lines: usize,
}

fn parse_header(data: &[u8], path: &Path) -> Result<Header> {
    let (mut pos, mut ln) = (0, 0);
    let mut binary: Option<Option<bool>> = None;
    let mut elements: Vec<Element> = Vec::new();
    // Names seen so far: a set, so a header of E element lines costs O(E), not O(E²).
    let mut names: std::collections::HashSet<String> = std::collections::HashSet::new();
    loop {
        let err = |ln: usize, msg: String| Error::parse(path, Some(ln), msg);
        let Some(len) = data[pos..].iter().position(|&b| b == b'\n') else {
            let msg = if ln == 0 {
                "expected 'ply' magic line, found none"
            } else {
                "expected 'end_header', found end of file"
            };
            return Err(err(ln + 1, msg.into()));
        };
        ln += 1;
        // Comments may hold any bytes (e.g. Latin-1); everything else must be text.
        let raw = String::from_utf8_lossy(&data[pos..pos + len]);
        let line = raw.trim();
        let comment = line.starts_with("comment") || line.starts_with("obj_info");
        if matches!(raw, Cow::Owned(_)) && !comment {
            let msg = "expected an ASCII header line, found invalid bytes";
            return Err(err(ln, msg.into()));
        }
        pos += len + 1;
        let toks: Vec<&str> = line.split_whitespace().collect();
        if ln == 1 {
            if line != "ply" {
                return Err(err(ln, format!("expected 'ply' magic line, found '{}'", clip(line))));
            }
            continue;
        }
        match toks.as_slice() {
            [] | ["comment" | "obj_info", ..] => {}
            ["format", f, "1.0"] if binary.is_none() => {
                binary = Some(match *f {
                    "ascii" => None,
                    "binary_little_endian" => Some(false),
                    "binary_big_endian" => Some(true),
                    _ => {
                        return Err(err(
                            ln,
                            format!(
                                "expected format ascii, binary_little_endian or binary_big_endian, found '{}'",
                                clip(f)
                            ),
                        ))
                    }
                });
            }
            ["element", name, count] => {
                if !names.insert(name.to_string()) {
                    return Err(err(ln, format!("expected unique element names, found a second '{}'", clip(name))));
                }
                let count: u64 = parse_tok(count, &format!("the count of element '{}'", clip(name)), path, ln)?;
                if count > MAX_RECORDS as u64 {
                    let msg =
                        format!("element '{}': expected at most {MAX_RECORDS} records, found {count}", clip(name));
                    return Err(err(ln, msg));
                }
                elements.push(Element { name: name.to_string(), count, props: Vec::new() });
            }
            ["property", rest @ ..] => {
                let el = elements.last_mut().ok_or_else(|| err(ln, "expected 'element' before 'property'".into()))?;
                let ty = |s: &str| {
                    Scalar::parse(s).ok_or_else(|| err(ln, format!("expected a PLY scalar type, found '{}'", clip(s))))
                };
                let (name, kind) = match rest {
                    ["list", ct, it, name] => {
                        let (ct, it) = (ty(ct)?, ty(it)?);
                        if ct.is_float() {
                            return Err(err(ln, format!("expected an integer list count type, found {ct:?}")));
                        }
                        (name, Kind::List(ct, it))
                    }
                    [t, name] => (name, Kind::Scalar(ty(t)?)),
                    _ => {
                        return Err(err(
                            ln,
                            format!(
                                "expected 'property TYPE NAME' or 'property list TYPE TYPE NAME', found '{}'",
                                clip(line)
                            ),
                        ))
                    }
                };
                el.props.push((name.to_string(), kind));
            }
            ["end_header"] => break,
            _ => {
                return Err(err(
                    ln,
                    format!(
                        "expected a PLY header line (format/element/property/comment/end_header), found '{}'",
                        clip(line)
                    ),
                ))
            }
        }
    }
    let binary =
        binary.ok_or_else(|| Error::parse(path, Some(ln), "expected a 'format' line in the header, found none"))?;
    if let Some(e) = elements.iter().find(|e| e.props.is_empty() && e.count > 0) {
        return Err(Error::parse(
            path,
            Some(ln),
            format!("element '{}': expected at least one property, found none", e.name),
        ));
    }
    Ok(Header { binary, elements, body: pos, lines: ln })
}

/// The body being decoded.
enum Body<'a> {
    Ascii(LineReader<'a, &'a [u8]>),
    Binary { data: &'a [u8], pos: usize, big: bool },
}

impl Body<'_> {
    fn remaining(&self) -> usize {
        match self {
            Body::Ascii(lines) => lines.inner().len(),
            Body::Binary { data, pos, .. } => data.len() - pos,
        }
    }

    /// Line of the last ASCII record (`None` for binary).
    fn line(&self) -> Option<usize> {
        match self {
            Body::Ascii(lines) => Some(lines.line),
            Body::Binary { .. } => None,
        }
    }

    /// Decodes record `rec` of `el`: the values of property `k` end up in `vals[starts[k]..starts[k + 1]]`
    /// (list counts are not stored).
    fn record(
        &mut self,
        el: &Element,
        rec: u64,
        vals: &mut Vec<f64>,
        starts: &mut Vec<usize>,
        path: &Path,
    ) -> Result<()> {
        vals.clear();
        starts.clear();
        let what = format!("element '{}' record {rec}", el.name);
        match self {
            Body::Binary { data, pos, big } => {
                let big = *big;
                decode(el, vals, starts, path, None, |t| {
                    let b = data.get(*pos..*pos + t.size()).ok_or_else(|| {
                        let msg = format!(
                            "truncated file: {what}: expected a {t:?} value ({} bytes), found {} bytes",
                            t.size(),
                            data.len() - *pos
                        );
                        Error::parse(path, None, msg)
                    })?;
                    *pos += t.size();
                    Ok(t.decode(b, big))
                })
            }
            Body::Ascii(lines) => {
                let (ln, l) = lines.expect_content(&what)?;
                let mut toks = l.split_whitespace();
                decode(el, vals, starts, path, Some(ln), |t| {
                    let Some(tok) = toks.next() else {
                        return Err(Error::parse(
                            path,
                            Some(ln),
                            format!("{what}: expected a {t:?} value, found end of line"),
                        ));
                    };
                    let v: f64 = parse_tok(tok, &format!("a {t:?} value in {what}"), path, ln)?;
                    if !t.is_float() && v.fract() != 0.0 {
                        return Err(Error::parse(
                            path,
                            Some(ln),
                            format!("{what}: expected an integer {t:?}, found '{}'", clip(tok)),
                        ));
                    }
                    Ok(v)
                })?;
                match toks.next() {
                    Some(tok) => Err(Error::parse(
                        path,
                        Some(ln),
                        format!("{what}: expected end of line, found '{}'", clip(tok)),
                    )),
                    None => Ok(()),
                }
            }
        }
    }
}

/// Decodes one record of `el`, taking each value from `next`.
fn decode(
    el: &Element,
    vals: &mut Vec<f64>,
    starts: &mut Vec<usize>,
    path: &Path,
    line: Option<usize>,
    mut next: impl FnMut(Scalar) -> Result<f64>,
) -> Result<()> {
    for (name, kind) in &el.props {
        starts.push(vals.len());
        match *kind {
            Kind::Scalar(t) => vals.push(next(t)?),
            Kind::List(ct, it) => {
                let n = next(ct)?;
                if n < 0.0 {
                    return Err(Error::parse(path, line, format!("list '{name}': expected a count ≥ 0, found {n}")));
                }
                for _ in 0..n as u64 {
                    vals.push(next(it)?);
                }
            }
        }
    }
    starts.push(vals.len());
    Ok(())
}

/// Reads a PLY file from `r`; `path` is only used in error messages. The whole input is read
/// into memory first, so every count in the header is checked against the bytes present before
/// anything is reserved.
///
/// Errors ([`Error::Parse`]; with line numbers for the header and ASCII bodies): missing magic,
/// format or `end_header`; unknown types or keywords; no vertex element or no `x`/`y`/`z`;
/// counts larger than the data; truncated records; non-finite coordinates; colours out of range;
/// faces with fewer than 3 vertices or indices outside `0..nv`; data after the last element.
pub fn read_ply<R: Read>(r: R, path: &Path) -> Result<MeshData> {
    // The header line by line, each line and the whole header capped, so that an input without
    // an end (`ln -s /dev/zero z.ply`) is an error after a few MiB instead of an allocation as
    // large as memory; then the body, whose counts the header announced.
    const MAX_HEADER: usize = 64 << 20;
    let mut r = std::io::BufReader::new(r);
    let mut data = Vec::new();
    loop {
        let start = data.len();
        let n = (&mut r).take(MAX_LINE as u64 + 1).read_until(b'\n', &mut data).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        if n > MAX_LINE || data.len() > MAX_HEADER {
            let msg = format!(
                "expected a header of lines of at most {} MiB ending with 'end_header' within {} MiB, found none",
                MAX_LINE >> 20,
                MAX_HEADER >> 20
            );
            return Err(Error::parse(path, None, msg));
        }
        if data[start..].trim_ascii() == b"end_header" {
            break;
        }
    }
    let header = parse_header(&data, path)?;
    // The body: at most what the header's counts allow (and MAX_PLY_BODY), so that an input
    // that never ends after a valid header is an error, not an allocation as large as memory.
    let ascii = header.binary.is_none();
    let limit = header
        .elements
        .iter()
        .map(|e| e.count.saturating_mul(e.max_record_bytes(ascii)))
        .fold(MAX_LINE as u64, u64::saturating_add)
        .min(MAX_PLY_BODY);
    let read = (&mut r).take(limit + 1).read_to_end(&mut data).map_err(|e| Error::io(path, e))?;
    if read as u64 > limit {
        let msg = format!(
            "expected at most {limit} bytes after the header (what its element counts allow{}), found more",
            if limit == MAX_PLY_BODY { ", capped at 8 GiB" } else { "" }
        );
        return Err(Error::parse(path, Some(header.lines), msg));
    }
    let hline = Some(header.lines);
    let herr = |msg: String| Error::parse(path, hline, msg);

    let vertex = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .ok_or_else(|| herr("expected an 'element vertex', found none".into()))?;
    let nv = usize::try_from(vertex.count)
        .ok()
        .filter(|&n| n <= u32::MAX as usize)
        .ok_or_else(|| herr(format!("expected at most 2^32 - 1 vertices, found {}", vertex.count)))?;
    let coord = |c: &str| match vertex.prop(&[c]) {
        Some((i, Kind::Scalar(_))) => Ok(i),
        _ => Err(herr(format!("expected a scalar vertex property '{c}', found none"))),
    };
    let xyz = [coord("x")?, coord("y")?, coord("z")?];
    let rgb: Option<Vec<(usize, bool)>> = ["red", "green", "blue"]
        .iter()
        .map(|c| match vertex.prop(&[c]) {
            Some((i, Kind::Scalar(t))) => Some((i, t.is_float())),
            _ => None,
        })
        .collect();
    let face_list = match header.elements.iter().find(|e| e.name == "face") {
        None => None,
        Some(face) => match face.prop(&["vertex_indices", "vertex_index"]) {
            Some((i, Kind::List(_, it))) if !it.is_float() => Some(i),
            _ => {
                return Err(herr(
                    "expected an integer list property 'vertex_indices' in element 'face', found none".into(),
                ))
            }
        },
    };

    let body = &data[header.body..];
    let mut body = match header.binary {
        None => Body::Ascii(LineReader::new(body, path, header.lines + 1)),
        Some(big) => Body::Binary { data: body, pos: 0, big },
    };
    let mut mesh = MeshData::default();
    let (mut vals, mut starts) = (Vec::new(), Vec::new());
    for el in &header.elements {
        let (min, left) = (el.min_record_bytes(header.binary.is_none()), body.remaining() as u64);
        if el.count.saturating_mul(min) > left + 1 {
            let msg = format!("truncated file: element '{}' declares {} records of at least {min} bytes, but only {left} bytes remain", el.name, el.count);
            return Err(Error::parse(path, body.line().map(|l| l + 1), msg));
        }
        // The check above bounds `count` by the input size, so reserving it is safe.
        let count = el.count as usize;
        let is_vertex = el.name == "vertex";
        if is_vertex {
            mesh.vertices.reserve(count);
            mesh.colors = rgb.as_ref().map(|_| Vec::with_capacity(count));
        } else if face_list.is_some() && el.name == "face" {
            mesh.faces.reserve(count);
        }
        for rec in 0..count {
            body.record(el, rec as u64, &mut vals, &mut starts, path)?;
            let line = body.line();
            if is_vertex {
                let p = xyz.map(|k| vals[starts[k]]);
                mesh.vertices.push(check_vertex(p, rec, path, line)?);
                if let (Some(rgb), Some(colors)) = (&rgb, &mut mesh.colors) {
                    let c: Option<Vec<u8>> =
                        rgb.iter().map(|&(k, float)| color_channel(vals[starts[k]], float)).collect();
                    let c = c.ok_or_else(|| {
                        let found: Vec<f64> = rgb.iter().map(|&(k, _)| vals[starts[k]]).collect();
                        Error::parse(path, line, format!("vertex {rec}: expected a colour as integers 0..=255 or floats in [0, 1], found {found:?}"))
                    })?;
                    colors.push([c[0], c[1], c[2]]);
                }
            } else if let (Some(k), "face") = (face_list, el.name.as_str()) {
                let idx = &vals[starts[k]..starts[k + 1]];
                if idx.len() < 3 {
                    return Err(Error::parse(
                        path,
                        line,
                        format!("face {rec}: expected at least 3 vertices, found {}", idx.len()),
                    ));
                }
                let poly = idx.iter().map(|&v| check_index(v, nv, rec, path, line)).collect::<Result<Vec<u32>>>()?;
                push_fan(&mut mesh.faces, &poly, path, line)?;
            }
        }
    }
    let rest = match &mut body {
        Body::Ascii(lines) => lines.next_content()?.map(|(_, l)| clip(l)),
        Body::Binary { data, pos, .. } => {
            let rest = &data[*pos..];
            (!rest.iter().all(u8::is_ascii_whitespace)).then(|| format!("{} bytes", rest.len()))
        }
    };
    if let Some(rest) = rest {
        let msg = format!("expected end of file after the declared elements, found '{rest}'");
        return Err(Error::parse(path, body.line(), msg));
    }
    finish(mesh, path, None)
}

/// Writes `mesh` as PLY, ASCII or binary little endian: `double` x, y, z; `uchar` red, green,
/// blue when it has colours; and, when it has faces, `element face` with
/// `property list uchar int vertex_indices`. Values round-trip exactly through [`read_ply`].
///
/// Errors: [`Error::Invalid`] for an inconsistent mesh, [`Error::Io`] on write failure.
pub fn write_ply<W: Write>(w: W, mesh: &MeshData, ascii: bool) -> Result<()> {
    write_ply_to(w, mesh, ascii, Path::new("<PLY output>"))
}

/// [`write_ply`] with the `path` named in I/O errors.
pub(crate) fn write_ply_to<W: Write>(mut w: W, mesh: &MeshData, ascii: bool, path: &Path) -> Result<()> {
    validate_for_write(mesh)?;
    let io = |e| Error::io(path, e);
    let format = if ascii { "ascii" } else { "binary_little_endian" };
    let mut h =
        format!("ply\nformat {format} 1.0\ncomment written by funcorr\nelement vertex {}\n", mesh.vertices.len());
    h += "property double x\nproperty double y\nproperty double z\n";
    if mesh.colors.is_some() {
        h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    if !mesh.faces.is_empty() {
        h += &format!("element face {}\nproperty list uchar int vertex_indices\n", mesh.faces.len());
    }
    h += "end_header\n";
    w.write_all(h.as_bytes()).map_err(io)?;
    for (i, p) in mesh.vertices.iter().enumerate() {
        let c = mesh.colors.as_ref().map(|c| c[i]);
        if ascii {
            write!(w, "{:?} {:?} {:?}", p[0], p[1], p[2]).map_err(io)?;
            if let Some(c) = c {
                write!(w, " {} {} {}", c[0], c[1], c[2]).map_err(io)?;
            }
            writeln!(w).map_err(io)?;
        } else {
            let mut rec = [0u8; 27];
            for (k, x) in p.iter().enumerate() {
                rec[8 * k..8 * k + 8].copy_from_slice(&x.to_le_bytes());
            }
            rec[24..].copy_from_slice(&c.unwrap_or_default());
            let len = if c.is_some() { 27 } else { 24 };
            w.write_all(&rec[..len]).map_err(io)?;
        }
    }
    for f in &mesh.faces {
        if ascii {
            writeln!(w, "3 {} {} {}", f[0], f[1], f[2]).map_err(io)?;
        } else {
            let mut rec = [3u8; 13];
            for (k, &v) in f.iter().enumerate() {
                rec[1 + 4 * k..5 + 4 * k].copy_from_slice(&(v as i32).to_le_bytes());
            }
            w.write_all(&rec).map_err(io)?;
        }
    }
    w.flush().map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_util::{assert_parse, noise};

    fn read(s: &[u8]) -> Result<MeshData> {
        read_ply(s, Path::new("t.ply"))
    }

    /// A PLY file: `header` lines (between the magic and `end_header`) followed by `body`.
    fn ply(header: &str, body: &[u8]) -> Vec<u8> {
        [format!("ply\n{header}end_header\n").as_bytes(), body].concat()
    }

    /// Little-endian binary body builder.
    #[derive(Default)]
    struct Le(Vec<u8>);
    impl Le {
        fn f32(mut self, v: &[f32]) -> Self {
            v.iter().for_each(|x| self.0.extend(x.to_le_bytes()));
            self
        }
        fn u8(mut self, v: &[u8]) -> Self {
            self.0.extend(v);
            self
        }
        fn u16(mut self, v: &[u16]) -> Self {
            v.iter().for_each(|x| self.0.extend(x.to_le_bytes()));
            self
        }
        fn i32(mut self, v: &[i32]) -> Self {
            v.iter().for_each(|x| self.0.extend(x.to_le_bytes()));
            self
        }
        fn f64(mut self, v: &[f64]) -> Self {
            v.iter().for_each(|x| self.0.extend(x.to_le_bytes()));
            self
        }
    }

    fn sample(colors: bool, faces: bool) -> MeshData {
        MeshData {
            vertices: vec![[0.1, 0.2, 0.3], [1.0 / 3.0, -2.5e-300, 1e22], [f64::MAX, 5e-324, -0.0], [4.0, 5.0, 6.0]],
            faces: if faces { vec![[0, 1, 2], [3, 2, 1]] } else { vec![] },
            colors: colors.then(|| vec![[255, 0, 0], [0, 255, 0], [0, 0, 255], [7, 8, 9]]),
        }
    }

    #[test]
    fn round_trips_are_exact() {
        for ascii in [true, false] {
            for (colors, faces) in [(true, true), (false, true), (true, false), (false, false)] {
                let m = sample(colors, faces);
                let mut buf = Vec::new();
                write_ply(&mut buf, &m, ascii).unwrap();
                let text = String::from_utf8_lossy(&buf);
                assert_eq!(text.contains("element face"), faces);
                assert_eq!(text.contains("property uchar red"), colors);
                let back = read(&buf).unwrap();
                assert_eq!(back, m, "ascii={ascii} colors={colors} faces={faces}");
                // Bit-exact, including the sign of zero.
                assert_eq!(back.vertices[2][2].to_bits(), (-0.0f64).to_bits());
            }
        }
        let mut buf = Vec::new();
        write_ply(&mut buf, &sample(false, true), false).unwrap();
        assert_eq!(buf.len(), ply_header_len(&buf) + 4 * 24 + 2 * 13);
    }

    fn ply_header_len(b: &[u8]) -> usize {
        b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11
    }

    #[test]
    fn ascii_with_comments_float_colours_and_polygons() {
        let h = "format ascii 1.0\ncomment made by hand\nobj_info none\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float red\nproperty float green\nproperty float blue\nproperty float alpha\nelement face 1\nproperty list uchar int vertex_index\n";
        let b = b"0 0 0 1 0 0 1\n1 0 0 0 1 0 1\n1 1 0 0 0 0.5 1\n0 1 0 0 0 0 0\n4 0 1 2 3\n";
        let m = read(&ply(h, b)).unwrap();
        assert_eq!(m.vertices[2], [1., 1., 0.]);
        assert_eq!(m.colors, Some(vec![[255, 0, 0], [0, 255, 0], [0, 0, 128], [0, 0, 0]]));
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn ascii_face_element_first_and_crlf() {
        let h = "format ascii 1.0\r\nelement face 1\r\nproperty list uchar uint vertex_indices\r\nelement vertex 3\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\n";
        let m = read(&ply(h, b"3 2 1 0\r\n0 0 0\r\n1 0 0\r\n0 1 0\r\n")).unwrap();
        assert_eq!(m.faces, vec![[2, 1, 0]]);
        assert_eq!(m.vertices.len(), 3);
    }

    #[test]
    fn big_endian_float_vertices_uchar_int_list() {
        let h = "format binary_big_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\n";
        let mut b = Vec::new();
        for v in [[0.5f32, 0.0, 0.0], [1.0, 0.0, -2.0], [0.0, 1.0, 0.0], [0.25, 0.125, 1e-3]] {
            v.iter().for_each(|x| b.extend(x.to_be_bytes()));
        }
        for f in [&[0i32, 1, 2][..], &[0, 2, 3, 1]] {
            b.push(f.len() as u8);
            f.iter().for_each(|x| b.extend(x.to_be_bytes()));
        }
        let m = read(&ply(h, &b)).unwrap();
        assert_eq!(m.vertices, vec![[0.5, 0., 0.], [1., 0., -2.], [0., 1., 0.], [0.25, 0.125, f64::from(1e-3f32)]]);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [0, 3, 1]]);
    }

    #[test]
    fn extra_elements_and_properties_are_skipped() {
        let h = "format binary_little_endian 1.0\ncomment extras\nelement material 2\nproperty uchar a\nproperty list int uint16 b\nelement vertex 3\nproperty int16 id\nproperty float32 x\nproperty float32 y\nproperty list uint8 uint16 junk\nproperty float32 z\nproperty uint8 red\nproperty uint8 green\nproperty uint8 blue\nproperty float64 quality\nelement face 1\nproperty uchar flags\nproperty list uint16 uint32 vertex_indices\nproperty double q\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n";
        let b = Le::default()
            .u8(&[9])
            .i32(&[2])
            .u16(&[1, 2]) // material 0
            .u8(&[8])
            .i32(&[0]) // material 1
            .u16(&[7])
            .f32(&[1., 2.])
            .u8(&[2])
            .u16(&[5, 5])
            .f32(&[3.])
            .u8(&[10, 20, 30])
            .f64(&[0.5])
            .u16(&[7])
            .f32(&[4., 5.])
            .u8(&[0])
            .f32(&[6.])
            .u8(&[0, 0, 0])
            .f64(&[0.5])
            .u16(&[7])
            .f32(&[7., 8.])
            .u8(&[1])
            .u16(&[1])
            .f32(&[9.])
            .u8(&[1, 2, 3])
            .f64(&[0.5])
            .u8(&[1])
            .u16(&[3])
            .i32(&[2, 1, 0])
            .f64(&[1.0]) // face (count as uint16)
            .i32(&[0, 1]); // edge
        let m = read(&ply(h, &b.0)).unwrap();
        assert_eq!(m.vertices, vec![[1., 2., 3.], [4., 5., 6.], [7., 8., 9.]]);
        assert_eq!(m.colors, Some(vec![[10, 20, 30], [0, 0, 0], [1, 2, 3]]));
        assert_eq!(m.faces, vec![[2, 1, 0]]);
        // Same structure in ASCII.
        let a = b"9 2 1 2\n8 0\n7 1 2 2 5 5 3 10 20 30 0.5\n7 4 5 0 6 0 0 0 0.5\n7 7 8 1 1 9 1 2 3 0.5\n1 3 2 1 0 1.0\n0 1\n";
        let m2 = read(&ply(&h.replace("binary_little_endian", "ascii"), a)).unwrap();
        assert_eq!(m2, m);
    }

    #[test]
    fn point_cloud_without_faces() {
        let h = "format binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\n";
        let m = read(&ply(h, &Le::default().f64(&[1., 2., 3., 4., 5., 6.]).0)).unwrap();
        assert_eq!(m, MeshData { vertices: vec![[1., 2., 3.], [4., 5., 6.]], ..MeshData::default() });
    }

    const XYZ: &str = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    const FACE: &str = "element face 1\nproperty list uchar int vertex_indices\n";

    fn bin(extra_header: &str, body: &[u8]) -> Result<MeshData> {
        read(&ply(&format!("format binary_little_endian 1.0\n{XYZ}{extra_header}"), body))
    }

    fn verts() -> Le {
        Le::default().f32(&[0., 0., 0., 1., 0., 0., 0., 1., 0.])
    }

    #[test]
    fn bad_headers() {
        assert_parse(read(b""), Some(Some(1)), "expected 'ply' magic line, found none");
        assert_parse(read(b"ply"), Some(Some(1)), "expected 'ply' magic line, found none");
        assert_parse(read(b"PLY\nformat ascii 1.0\n"), Some(Some(1)), "expected 'ply' magic line, found 'PLY'");
        assert_parse(read(b"OFF\n3 1 0\n"), Some(Some(1)), "expected 'ply' magic");
        assert_parse(
            read(b"ply\nformat ascii 1.0\nelement vertex 1\n"),
            Some(Some(4)),
            "expected 'end_header', found end of file",
        );
        assert_parse(read(&ply(XYZ, b"")), Some(Some(6)), "expected a 'format' line");
        assert_parse(read(&ply("format binary 1.0\n", b"")), Some(Some(2)), "found 'binary'");
        assert_parse(read(&ply("format ascii 2.0\n", b"")), Some(Some(2)), "expected a PLY header line");
        assert_parse(
            read(&ply("format ascii 1.0\nproperty float x\n", b"")),
            Some(Some(3)),
            "expected 'element' before 'property'",
        );
        assert_parse(
            read(&ply("format ascii 1.0\nelement vertex 1\nproperty real x\n", b"")),
            Some(Some(4)),
            "expected a PLY scalar type, found 'real'",
        );
        assert_parse(
            read(&ply("format ascii 1.0\nelement vertex 1\nproperty list float int x\n", b"")),
            Some(Some(4)),
            "integer list count type",
        );
        assert_parse(
            read(&ply("format ascii 1.0\nelement vertex many\n", b"")),
            Some(Some(3)),
            "expected the count of element 'vertex', found 'many'",
        );
        assert_parse(read(&ply("format ascii 1.0\nelement vertex -1\n", b"")), Some(Some(3)), "found '-1'");
        assert_parse(
            read(&ply("format ascii 1.0\nelement vertex 2\n", b"")),
            Some(Some(4)),
            "element 'vertex': expected at least one property",
        );
        assert_parse(
            read(&ply("format ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\n", b"")),
            None,
            "expected an 'element vertex'",
        );
        assert_parse(
            read(&ply("format ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n", b"0 0\n")),
            None,
            "scalar vertex property 'z'",
        );
        assert_parse(read(&ply(&format!("format ascii 1.0\n{XYZ}{XYZ}"), b"")), Some(Some(7)), "a second 'vertex'");
        assert_parse(
            bin("element face 1\nproperty list uchar float vertex_indices\n", &verts().0),
            None,
            "integer list property 'vertex_indices'",
        );
        assert_parse(
            bin("element face 1\nproperty int vertex_indices\n", &verts().0),
            None,
            "'vertex_indices' in element 'face'",
        );
        let latin1 =
            [&b"ply\nformat ascii 1.0\ncomment cr\xe9\xe9\n"[..], XYZ.as_bytes(), b"end_header\n0 0 0\n1 0 0\n0 1 0\n"]
                .concat();
        assert_eq!(read(&latin1).unwrap().vertices.len(), 3, "non-UTF-8 comments are allowed");
        let bad = [&b"ply\nformat ascii 1.0\nelement vert\xff\xfe 1\n"[..], b"end_header\n"].concat();
        assert_parse(read(&bad), Some(Some(3)), "expected an ASCII header line, found invalid bytes");
    }

    #[test]
    fn absurd_counts_fail_before_allocating() {
        let h = "format binary_little_endian 1.0\nelement vertex 100000000\nproperty float x\nproperty float y\nproperty float z\n";
        assert_parse(
            read(&ply(h, &[0u8; 100])),
            None,
            "element 'vertex' declares 100000000 records of at least 12 bytes, but only 100 bytes remain",
        );
        let h = h.replace("100000000", "18446744073709551615").replace("binary_little_endian", "ascii");
        assert_parse(
            read(&ply(&h, b"0 0 0\n")),
            Some(Some(3)),
            "at most 134217728 records, found 18446744073709551615",
        );
        let h = "format ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\n";
        assert_parse(read(&ply(h, b"0 0 0\n")), Some(Some(3)), "at most 134217728 records, found 4000000000");
        let h = "format ascii 1.0\nelement vertex 100000000\nproperty float x\nproperty float y\nproperty float z\n";
        assert_parse(read(&ply(h, b"0 0 0\n")), Some(Some(8)), "declares 100000000 records");
        let h = format!(
            "format binary_little_endian 1.0\n{XYZ}element face 100000000\nproperty list uchar int vertex_indices\n"
        );
        assert_parse(read(&ply(&h, &verts().i32(&[0; 20]).0)), None, "element 'face' declares 100000000 records");
        // A valid header followed by a body that never ends (as /dev/zero): an error after the
        // bytes the header's counts allow, not an allocation as large as memory.
        let h =
            format!("format binary_little_endian 1.0\n{XYZ}element face 1\nproperty list uchar int vertex_indices\n");
        let head = ply(&h, &[]);
        let endless = std::io::Read::chain(head.as_slice(), std::io::repeat(0));
        let e = read_ply(endless, Path::new("z.ply")).unwrap_err().to_string();
        assert!(e.contains("after the header") && e.contains("found more"), "{e}");
    }

    #[test]
    fn truncated_binary() {
        let v = verts().0;
        assert_parse(bin("", &v[..v.len() - 4]), None, "but only 32 bytes remain");
        assert_parse(bin(FACE, &v[..v.len() - 4]), None, "but only 32 bytes remain");
        // Mid-record: the element size check passes (a face needs ≥ 1 byte) but its list is cut.
        let cut = verts().u8(&[3]).i32(&[0, 1]).0;
        assert_parse(
            bin(FACE, &cut),
            None,
            "truncated file: element 'face' record 0: expected a I32 value (4 bytes), found 0 bytes",
        );
        // A list count larger than what remains.
        let huge = verts().u8(&[255]).i32(&[0, 1, 2]).0;
        assert_parse(bin(FACE, &huge), None, "truncated file: element 'face' record 0");
        let big_count = "element face 1\nproperty list uint int vertex_indices\n";
        assert_parse(bin(big_count, &verts().u8(&[255, 255, 255, 255]).i32(&[0, 1, 2]).0), None, "truncated file");
        // Mid-vertex truncation of a later element's record.
        let h = format!("{FACE}element extra 2\nproperty double w\nproperty uchar k\n");
        let body = verts().u8(&[3]).i32(&[0, 1, 2]).f64(&[1.0]).u8(&[1]).f64(&[2.0]).0;
        assert_parse(bin(&h, &body), None, "truncated file: element 'extra' record 1: expected a U8 value");
    }

    #[test]
    fn truncated_or_long_ascii() {
        let h = format!("format ascii 1.0\n{XYZ}{FACE}");
        assert_parse(
            read(&ply(&h, b"0 0 0\n1 0 0\n0 1 0\n")),
            Some(Some(13)),
            "truncated file: element 'face' declares 1 records of at least 2 bytes, but only 0 bytes remain",
        );
        let long = b"0 0 0\n1.000000 0.000000 0.000000 \n";
        assert_parse(
            read(&ply(&format!("format ascii 1.0\n{XYZ}"), long)),
            Some(Some(10)),
            "truncated file: expected element 'vertex' record 2, found end of file",
        );
        assert_parse(
            read(&ply(&h, b"0 0 0\n1 0 0\n0 1\n3 0 1 2\n")),
            Some(Some(12)),
            "element 'vertex' record 2: expected a F32 value, found end of line",
        );
        assert_parse(
            read(&ply(&h, b"0 0 0\n1 0 0\n0 1 0 7\n3 0 1 2\n")),
            Some(Some(12)),
            "expected end of line, found '7'",
        );
        assert_parse(
            read(&ply(&h, b"0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n")),
            Some(Some(13)),
            "expected a I32 value, found end of line",
        );
        assert_parse(
            read(&ply(&h, b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n")),
            Some(Some(14)),
            "expected end of file after the declared elements, found '3 0 1 2'",
        );
        assert_parse(
            read(&ply(&h, b"0 0 0\n1 0 0\n0 one 0\n3 0 1 2\n")),
            Some(Some(12)),
            "expected a F32 value in element 'vertex' record 2, found 'one'",
        );
    }

    #[test]
    fn bad_values() {
        let nan = verts().0.into_iter().take(24).chain(f32::NAN.to_le_bytes()).chain([0; 8]).collect::<Vec<u8>>();
        assert_parse(bin("", &nan), None, "vertex 2: expected finite coordinates");
        let inf = Le(verts().0[..12].to_vec()).f32(&[f32::INFINITY, 0., 0., 0., 1., 0.]).0;
        assert_parse(bin("", &inf), None, "vertex 1: expected finite");
        assert_parse(
            bin(FACE, &verts().u8(&[2]).i32(&[0, 1]).0),
            None,
            "face 0: expected at least 3 vertices, found 2",
        );
        assert_parse(bin(FACE, &verts().u8(&[3]).i32(&[0, 1, 3]).0), None, "face 0: vertex index 3 out of range");
        assert_parse(bin(FACE, &verts().u8(&[3]).i32(&[0, -1, 2]).0), None, "face 0: vertex index -1 out of range");
        let neg = "element face 1\nproperty list char int vertex_indices\n";
        assert_parse(
            bin(neg, &verts().u8(&[0xff]).i32(&[0, 1, 2]).0),
            None,
            "list 'vertex_indices': expected a count ≥ 0, found -1",
        );
        assert_parse(
            bin("", &verts().u8(&[1, 2, 3]).0),
            None,
            "expected end of file after the declared elements, found '3 bytes'",
        );
        assert!(bin("", &verts().u8(b"\n").0).is_ok(), "a trailing newline is tolerated");
        let h = format!("format ascii 1.0\n{XYZ}{FACE}");
        assert_parse(
            read(&ply(&h, b"0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n")),
            Some(Some(13)),
            "expected an integer I32, found '1.5'",
        );
        assert_parse(
            read(&ply(&h, b"0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")),
            Some(Some(13)),
            "face 0: vertex index 7 out of range",
        );
        assert_parse(read(&ply(&h, b"0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n")), Some(Some(11)), "vertex 1: expected finite");
        let c = "format ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty int red\nproperty int green\nproperty int blue\n";
        assert_parse(read(&ply(c, b"0 0 0 300 0 0\n")), Some(Some(11)), "vertex 0: expected a colour");
        assert_parse(
            read(&ply(
                "format ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n",
                b"",
            )),
            None,
            "expected at least one vertex",
        );
    }

    #[test]
    fn binary_garbage() {
        for seed in 1..5 {
            assert!(matches!(read(&noise(5000, seed)), Err(Error::Parse { .. })));
            // A valid header followed by noise: either parses into finite values or errors, never panics.
            let h = format!(
                "format binary_little_endian 1.0\n{XYZ}element face 2\nproperty list uchar int vertex_indices\n"
            );
            if let Ok(m) = read(&ply(&h, &noise(60, seed))) {
                assert!(m.vertices.iter().flatten().all(|c| c.is_finite()));
            }
            let h = h.replace("binary_little_endian", "ascii");
            assert!(matches!(read(&ply(&h, &noise(200, seed))), Err(Error::Parse { .. })));
        }
    }

    #[test]
    fn endless_input_and_long_headers() {
        // No end at all (`ln -s /dev/zero z.ply`): an error after the header cap, not OOM.
        let zeros = std::io::repeat(0).take((MAX_LINE as u64) * 5);
        let err = read_ply(zeros, Path::new("z.ply")).unwrap_err().to_string();
        assert!(err.contains("z.ply") && err.contains("end_header"), "{err}");
        // Many element lines (each name checked for uniqueness in a set): still read, and a
        // repeated name is still an error.
        let mut h =
            String::from("format ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n");
        for i in 0..20_000 {
            h += &format!("element e{i} 0\n");
        }
        let m = read(&ply(&h, b"0 0 0\n1 0 0\n0 1 0\n")).unwrap();
        assert_eq!(m.vertices.len(), 3);
        h += "element e7 0\n";
        assert!(read(&ply(&h, b"0 0 0\n1 0 0\n0 1 0\n")).unwrap_err().to_string().contains("second 'e7'"));
    }
}

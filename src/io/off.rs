//! Object File Format (`.off`): `OFF`, `COFF` (vertex colours), `NOFF` (vertex normals, ignored)
//! and `CNOFF`/`NCOFF`.
//!
//! Layout: a header keyword (`OFF`, optionally followed by the counts on the same line), the
//! counts `nv nf [ne]`, `nv` vertex lines `x y z [nx ny nz] [r g b [a]]`, then `nf` face lines
//! `k i1 … ik [face colour]`. `#` starts a comment anywhere; blank lines are skipped. Polygons are
//! fan-triangulated; face colours are ignored. Vertex colours are integers 0–255 or floats 0–1
//! (decided per vertex: all-integer tokens are read as 0–255).

use std::io::{BufRead, Write};
use std::path::Path;

use super::text::{clip, parse_tok, LineReader};
use super::{bounded_capacity, check_index, check_vertex, color_channel, finish, push_fan, MeshData, MAX_RECORDS};
use crate::error::{Error, Result};

/// Most records reserved ahead from a header count (the vectors grow past it as data arrives).
const RESERVE_LIMIT: usize = 1 << 16;

/// Reads an OFF file from `r`; `path` is only used in error messages.
///
/// Errors ([`Error::Parse`] with the line number): missing or unsupported header (`STOFF`, `4OFF`,
/// `nOFF`), bad counts, fewer vertices or faces than declared, non-numeric or non-finite values,
/// faces with fewer than 3 vertices or indices outside `0..nv`, and non-comment data after the
/// declared faces.
pub fn read_off<R: BufRead>(r: R, path: &Path) -> Result<MeshData> {
    let mut lines = LineReader::new(r, path, 1);
    let err = |line: usize, msg: String| Error::parse(path, Some(line), msg);

    // Header keyword, then counts (on the same line or the next one).
    let (ln, header) = lines.expect_content("an OFF header")?;
    let mut toks = header.split_whitespace();
    let kw = toks.next().unwrap_or_default().to_string();
    let (color, normal) = header_flags(&kw).map_err(|m| err(ln, m))?;
    let mut counts: Vec<String> = toks.map(str::to_string).collect();
    let mut counts_line = ln;
    if counts.is_empty() {
        let (ln, l) = lines.expect_content("the counts 'nv nf ne'")?;
        counts = l.split_whitespace().map(str::to_string).collect();
        counts_line = ln;
    }
    if !(2..=3).contains(&counts.len()) {
        let msg = format!("expected the counts 'nv nf ne', found '{}'", clip(&counts.join(" ")));
        return Err(err(counts_line, msg));
    }
    let nv: u64 = parse_tok(&counts[0], "a vertex count", path, counts_line)?;
    let nf: u64 = parse_tok(&counts[1], "a face count", path, counts_line)?;
    if let Some(ne) = counts.get(2) {
        parse_tok::<u64>(ne, "an edge count", path, counts_line)?;
    }
    if nv > MAX_RECORDS as u64 || nf > MAX_RECORDS as u64 {
        return Err(err(
            counts_line,
            format!("expected at most {MAX_RECORDS} vertices and faces, found {nv} and {nf}"),
        ));
    }

    let mut mesh = MeshData {
        vertices: Vec::with_capacity(bounded_capacity(nv, RESERVE_LIMIT)),
        colors: color.then(|| Vec::with_capacity(bounded_capacity(nv, RESERVE_LIMIT))),
        ..MeshData::default()
    };
    let nxyz = if normal { 6 } else { 3 };
    let mut vals = Vec::with_capacity(8);
    for i in 0..nv as usize {
        let (ln, l) = lines.expect_content(&format!("vertex {i} of {nv}"))?;
        vals.clear();
        for t in l.split_whitespace() {
            vals.push(parse_tok::<f64>(t, &format!("a number in vertex {i}"), path, ln)?);
        }
        let ok = match color {
            true => vals.len() == nxyz + 3 || vals.len() == nxyz + 4,
            false => vals.len() == nxyz,
        };
        if !ok {
            let want = if color { format!("{nxyz} + 3 or 4 (colour)") } else { nxyz.to_string() };
            let msg = format!("vertex {i}: expected {want} values for a '{kw}' file, found {}", vals.len());
            return Err(err(ln, msg));
        }
        mesh.vertices.push(check_vertex([vals[0], vals[1], vals[2]], i, path, Some(ln))?);
        if let Some(colors) = &mut mesh.colors {
            let float = l.split_whitespace().skip(nxyz).any(|t| t.parse::<u64>().is_err());
            let c: Option<Vec<u8>> = vals[nxyz..nxyz + 3].iter().map(|&v| color_channel(v, float)).collect();
            let c = c.ok_or_else(|| {
                let range = if float { "floats in [0, 1]" } else { "integers in 0..=255" };
                err(ln, format!("vertex {i}: expected a colour as {range}, found {:?}", &vals[nxyz..]))
            })?;
            colors.push([c[0], c[1], c[2]]);
        }
    }

    mesh.faces.reserve(bounded_capacity(nf, RESERVE_LIMIT));
    let mut poly: Vec<u32> = Vec::with_capacity(8);
    for f in 0..nf as usize {
        let (ln, l) = lines.expect_content(&format!("face {f} of {nf}"))?;
        let mut toks = l.split_whitespace();
        let k: usize = parse_tok(toks.next().unwrap_or_default(), &format!("the vertex count of face {f}"), path, ln)?;
        if k < 3 {
            return Err(err(ln, format!("face {f}: expected at least 3 vertices, found {k}")));
        }
        poly.clear();
        for t in toks.by_ref().take(k) {
            let idx: i64 = parse_tok(t, &format!("a vertex index in face {f}"), path, ln)?;
            poly.push(check_index(idx as f64, mesh.vertices.len(), f, path, Some(ln))?);
        }
        if poly.len() < k {
            return Err(err(ln, format!("face {f}: expected {k} vertex indices, found {}", poly.len())));
        }
        let extra: Vec<&str> = toks.collect();
        if extra.len() > 4 || extra.iter().any(|t| t.parse::<f64>().is_err()) {
            let msg = format!(
                "face {f}: expected at most a colour after the {k} indices, found '{}'",
                clip(&extra.join(" "))
            );
            return Err(err(ln, msg));
        }
        push_fan(&mut mesh.faces, &poly, path, Some(ln))?;
    }

    if let Some((ln, l)) = lines.next_content()? {
        let msg = format!("expected end of file after the {nf} declared faces, found '{}'", clip(l));
        return Err(err(ln, msg));
    }
    finish(mesh, path, Some(lines.line))
}

/// Parses the header keyword into `(has colours, has normals)`.
fn header_flags(kw: &str) -> std::result::Result<(bool, bool), String> {
    let Some(prefix) = kw.strip_suffix("OFF") else {
        return Err(format!("expected an 'OFF' header, found '{}'", clip(kw)));
    };
    match prefix {
        "" => Ok((false, false)),
        "C" => Ok((true, false)),
        "N" => Ok((false, true)),
        "CN" | "NC" => Ok((true, true)),
        _ => Err(format!(
            "expected OFF, COFF, NOFF, CNOFF or NCOFF, found '{}' (texture coordinates, 4-D and n-D OFF are not supported)",
            clip(kw)
        )),
    }
}

/// Writes `mesh` as OFF (`COFF` with integer 0–255 colours when it has colours). Coordinates
/// are written in Rust's shortest round-trip form, so reading the file back gives the same `f64`s.
///
/// Errors: [`Error::Invalid`] for an inconsistent mesh, [`Error::Io`] (naming `path`) on write
/// failure.
pub fn write_off<W: Write>(mut w: W, mesh: &MeshData, path: &Path) -> Result<()> {
    super::validate_for_write(mesh)?;
    let io = |e| Error::io(path, e);
    let kw = if mesh.colors.is_some() { "COFF" } else { "OFF" };
    writeln!(w, "{kw}\n{} {} 0", mesh.vertices.len(), mesh.faces.len()).map_err(io)?;
    for (i, p) in mesh.vertices.iter().enumerate() {
        write!(w, "{:?} {:?} {:?}", p[0], p[1], p[2]).map_err(io)?;
        if let Some(c) = mesh.colors.as_ref().map(|c| c[i]) {
            write!(w, " {} {} {}", c[0], c[1], c[2]).map_err(io)?;
        }
        writeln!(w).map_err(io)?;
    }
    for f in &mesh.faces {
        writeln!(w, "3 {} {} {}", f[0], f[1], f[2]).map_err(io)?;
    }
    w.flush().map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_util::{assert_parse, noise};

    fn read(s: &[u8]) -> Result<MeshData> {
        read_off(s, Path::new("t.off"))
    }

    #[test]
    fn round_trip_is_exact() {
        let m = MeshData {
            vertices: vec![[0.1, 0.2, 0.3], [1.0 / 3.0, -2.5e-300, 1e22], [f64::MAX, f64::MIN_POSITIVE, 5e-324]],
            faces: vec![[0, 1, 2], [2, 1, 0]],
            colors: Some(vec![[255, 0, 0], [0, 255, 0], [9, 8, 7]]),
        };
        for m in [m.clone(), MeshData { colors: None, ..m.clone() }, MeshData { faces: vec![], ..m }] {
            let mut buf = Vec::new();
            write_off(&mut buf, &m, Path::new("t.off")).unwrap();
            assert_eq!(read(&buf).unwrap(), m);
        }
    }

    #[test]
    fn project_style_file() {
        let m = read(b"OFF\n4 2 0\n0.1 0.2 0.3\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 2 3\n").unwrap();
        assert_eq!(m.vertices[0], [0.1, 0.2, 0.3]);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.colors, None);
    }

    #[test]
    fn counts_on_header_line_comments_blank_lines_crlf() {
        let s = b"# leading comment\n\nOFF 3 1 0 # counts here\r\n# full-line comment\n0 0 0\n\n1 0 0 # trailing\n0 1 0\n3 0 1 2 # face\n# end\n\n";
        let m = read(s).unwrap();
        assert_eq!(m.vertices.len(), 3);
        assert_eq!(m.faces, vec![[0, 1, 2]]);
        assert_eq!(read(b"OFF\n3 1\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2").unwrap().faces.len(), 1);
    }

    #[test]
    fn coff_int_float_and_rgba_colours() {
        let m = read(b"COFF\n3 0 0\n0 0 0 255 0 10\n1 0 0 0.0 1.0 0.5 1.0\n0 1 0 1 2 3 255\n").unwrap();
        assert_eq!(m.colors, Some(vec![[255, 0, 10], [0, 255, 128], [1, 2, 3]]));
        assert!(m.faces.is_empty());
    }

    #[test]
    fn noff_and_cnoff_ignore_normals() {
        let m = read(b"NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n").unwrap();
        assert_eq!(m.vertices[1], [1.0, 0.0, 0.0]);
        assert_eq!(m.colors, None);
        for kw in ["CNOFF", "NCOFF"] {
            let s = format!("{kw}\n3 0 0\n0 0 0 0 0 1 10 20 30\n1 0 0 0 0 1 1 2 3 4\n0 1 0 0 0 1 0 0 0\n");
            let m = read(s.as_bytes()).unwrap();
            assert_eq!(m.colors, Some(vec![[10, 20, 30], [1, 2, 3], [0, 0, 0]]), "{kw}");
        }
    }

    #[test]
    fn polygons_are_fan_triangulated_and_face_colours_ignored() {
        let s = b"OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 2 0\n4 0 1 2 3 255 0 0\n5 4 3 2 1 0 0.5 0.5 0.5 1\n";
        let m = read(s).unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [4, 3, 2], [4, 2, 1], [4, 1, 0]]);
    }

    #[test]
    fn bad_headers() {
        assert_parse(read(b""), None, "expected an OFF header, found end of file");
        assert_parse(read(b"# only a comment\n\n"), None, "end of file");
        assert_parse(read(b"4 2 0\n0 0 0\n"), Some(Some(1)), "expected an 'OFF' header, found '4'");
        assert_parse(read(b"PLY\n"), Some(Some(1)), "expected an 'OFF' header");
        assert_parse(read(b"STOFF\n1 0 0\n0 0 0 0 0\n"), Some(Some(1)), "not supported");
        assert_parse(read(b"4OFF\n1 0 0\n0 0 0 0\n"), Some(Some(1)), "not supported");
        assert_parse(read(b"OFF\n"), Some(Some(2)), "expected the counts");
        assert_parse(read(b"OFF\n3\n"), Some(Some(2)), "expected the counts");
        assert_parse(read(b"OFF\n3 1 0 7\n"), Some(Some(2)), "expected the counts");
        assert_parse(read(b"OFF\nthree 1 0\n"), Some(Some(2)), "expected a vertex count, found 'three'");
        assert_parse(read(b"OFF\n3 -1 0\n"), Some(Some(2)), "expected a face count, found '-1'");
    }

    #[test]
    fn absurd_counts_fail_without_huge_allocation() {
        assert_parse(
            read(b"OFF\n999999999999 1 0\n0 0 0\n"),
            Some(Some(2)),
            "at most 134217728 vertices and faces, found 999999999999",
        );
        assert_parse(
            read(b"OFF\n100000000 1 0\n0 0 0\n"),
            Some(Some(4)),
            "expected vertex 1 of 100000000, found end of file",
        );
        let faces = read(b"OFF\n3 18446744073709551615 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
        assert_parse(faces, Some(Some(2)), "found 3 and 18446744073709551615");
        let faces = read(b"OFF\n3 100000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
        assert_parse(faces, Some(Some(7)), "expected face 1 of 100000000");
        let huge_poly = read(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4000000000 0 1 2\n");
        assert_parse(huge_poly, Some(Some(6)), "face 0: expected 4000000000 vertex indices, found 3");
    }

    #[test]
    fn truncated_and_extra_data() {
        assert_parse(read(b"OFF\n3 1 0\n0 0 0\n1 0 0\n"), Some(Some(5)), "truncated file: expected vertex 2 of 3");
        assert_parse(
            read(b"OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
            Some(Some(7)),
            "truncated file: expected face 1 of 2",
        );
        let extra = read(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 2 1 0\n");
        assert_parse(extra, Some(Some(7)), "expected end of file after the 1 declared faces, found '3 2 1 0'");
        let half_vertex = read(b"OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n");
        assert_parse(half_vertex, Some(Some(4)), "vertex 1: expected 3 values");
    }

    #[test]
    fn bad_values() {
        let v = |line: &str| format!("OFF\n3 1 0\n0 0 0\n{line}\n0 1 0\n3 0 1 2\n");
        assert_parse(read(v("1 zero 0").as_bytes()), Some(Some(4)), "expected a number in vertex 1, found 'zero'");
        assert_parse(read(v("1 nan 0").as_bytes()), Some(Some(4)), "vertex 1: expected finite coordinates");
        assert_parse(read(v("inf 0 0").as_bytes()), Some(Some(4)), "vertex 1: expected finite coordinates");
        assert_parse(
            read(v("1 0 0 0.5 0.5 0.5").as_bytes()),
            Some(Some(4)),
            "expected 3 values for a 'OFF' file, found 6",
        );
        let coff = read(b"COFF\n1 0 0\n0 0 0 300 0 0\n");
        assert_parse(coff, Some(Some(3)), "expected a colour as integers in 0..=255");
        let coff = read(b"COFF\n1 0 0\n0 0 0 1.5 0 0\n");
        assert_parse(coff, Some(Some(3)), "expected a colour as floats in [0, 1]");
        assert_parse(read(b"COFF\n1 0 0\n0 0 0\n"), Some(Some(3)), "vertex 0: expected 3 + 3 or 4 (colour) values");
        let f = |line: &str| format!("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n{line}\n");
        assert_parse(read(f("2 0 1").as_bytes()), Some(Some(6)), "face 0: expected at least 3 vertices, found 2");
        assert_parse(read(f("3 0 1 3").as_bytes()), Some(Some(6)), "face 0: vertex index 3 out of range");
        assert_parse(read(f("3 0 -1 2").as_bytes()), Some(Some(6)), "face 0: vertex index -1 out of range");
        assert_parse(read(f("3 0 1.5 2").as_bytes()), Some(Some(6)), "expected a vertex index in face 0, found '1.5'");
        assert_parse(read(f("three 0 1 2").as_bytes()), Some(Some(6)), "expected the vertex count of face 0");
        assert_parse(read(f("3 0 1 2 red").as_bytes()), Some(Some(6)), "expected at most a colour after the 3 indices");
    }

    #[test]
    fn binary_garbage() {
        let mut s = b"OFF\n3 1 0\n".to_vec();
        s.extend([0xff, 0xfe, 0x00, 0x81, b'\n']);
        assert_parse(read(&s), Some(Some(3)), "invalid bytes");
        let noise = noise(4096, 1);
        assert!(matches!(read(&noise), Err(Error::Parse { .. })));
        assert!(matches!(read(&[&b"OFF\n"[..], &noise].concat()), Err(Error::Parse { .. })));
    }
}

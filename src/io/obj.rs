//! Wavefront OBJ (`.obj`): geometry only.
//!
//! Read: `v x y z [w]` and `v x y z r g b` (colours as floats 0–1, kept only when every vertex
//! has one), and `f` with `i`, `i/t`, `i//n` or `i/t/n` corners; indices are 1-based, negative
//! ones count back from the last vertex defined so far, and must refer to a vertex defined
//! before the face. Polygons are fan-triangulated. Other standard statements (`vt`, `vn`, `g`,
//! `o`, `s`, `usemtl`, `mtllib`, `l`, free-form geometry, …) and `#` comments are ignored;
//! an unknown statement is an error.

use std::io::BufRead;
use std::path::Path;

use super::text::{clip, parse_tok, LineReader};
use super::{check_records, check_vertex, color_channel, finish, push_fan, MeshData};
use crate::error::{Error, Result};

/// Statements that are valid OBJ but carry nothing this reader keeps.
const IGNORED: &[&str] = &[
    "vt",
    "vn",
    "vp",
    "l",
    "p",
    "g",
    "o",
    "s",
    "mg",
    "usemtl",
    "mtllib",
    "usemap",
    "maplib",
    "bevel",
    "c_interp",
    "d_interp",
    "lod",
    "shadow_obj",
    "trace_obj",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "ctech",
    "stech",
    "call",
    "csh",
];

/// Reads an OBJ file from `r`; `path` is only used in error messages.
///
/// Errors ([`Error::Parse`] with the line number): no vertices, unknown statements, non-numeric
/// or non-finite coordinates, colours outside [0, 1], faces with fewer than 3 corners, index 0,
/// or indices referring to vertices not (yet) defined.
pub fn read_obj<R: BufRead>(r: R, path: &Path) -> Result<MeshData> {
    let mut lines = LineReader::new(r, path, 1);
    let mut mesh = MeshData::default();
    let mut colors: Vec<[u8; 3]> = Vec::new();
    let mut poly: Vec<u32> = Vec::with_capacity(8);
    while let Some((ln, l)) = lines.next_content()? {
        let err = |msg: String| Error::parse(path, Some(ln), msg);
        let mut toks = l.split_whitespace();
        match toks.next().unwrap_or_default() {
            "v" => {
                let i = mesh.vertices.len();
                let what = format!("a number in vertex {i}");
                let vals = toks.map(|t| parse_tok::<f64>(t, &what, path, ln)).collect::<Result<Vec<_>>>()?;
                if ![3, 4, 6].contains(&vals.len()) {
                    let msg = format!(
                        "vertex {i}: expected 'x y z', 'x y z w' or 'x y z r g b', found {} values",
                        vals.len()
                    );
                    return Err(err(msg));
                }
                check_records(i, "vertices", path, Some(ln))?;
                mesh.vertices.push(check_vertex([vals[0], vals[1], vals[2]], i, path, Some(ln))?);
                if vals.len() == 6 {
                    let c: Option<Vec<u8>> = vals[3..].iter().map(|&v| color_channel(v, true)).collect();
                    let c = c.ok_or_else(|| {
                        err(format!("vertex {i}: expected colour values in [0, 1], found {:?}", &vals[3..]))
                    })?;
                    colors.push([c[0], c[1], c[2]]);
                }
            }
            "f" => {
                let f = mesh.faces.len();
                let nv = mesh.vertices.len() as i64;
                poly.clear();
                for t in toks {
                    let first = t.split('/').next().unwrap_or_default();
                    let idx: i64 = parse_tok(first, &format!("a vertex index in face {f}"), path, ln)?;
                    let resolved = if idx < 0 { nv + idx } else { idx - 1 };
                    if idx == 0 || !(0..nv).contains(&resolved) {
                        let msg = format!("face {f}: vertex index {idx} out of range (expected 1..={nv} or -{nv}..=-1 with {nv} vertices defined so far)");
                        return Err(err(msg));
                    }
                    poly.push(resolved as u32);
                }
                if poly.len() < 3 {
                    return Err(err(format!("face {f}: expected at least 3 vertices, found {}", poly.len())));
                }
                push_fan(&mut mesh.faces, &poly, path, Some(ln))?;
            }
            kw if IGNORED.contains(&kw) => {}
            kw => return Err(err(format!("expected an OBJ statement (v, f, vt, vn, g, …), found '{}'", clip(kw)))),
        }
    }
    if !colors.is_empty() && colors.len() == mesh.vertices.len() {
        mesh.colors = Some(colors);
    }
    finish(mesh, path, Some(lines.line))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_util::{assert_parse, noise};

    fn read(s: &str) -> Result<MeshData> {
        read_obj(s.as_bytes(), Path::new("t.obj"))
    }

    const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

    #[test]
    fn corner_forms_negative_indices_and_polygons() {
        let m = read(&format!(
            "{QUAD}f 1 2 3\nf 1/1 3/2 4/3\nf 4//1 3//1 2//1\nf 1/1/1 2/2/2 3/3/3 4/4/4\nf -4 -3 -2 -1\n"
        ))
        .unwrap();
        assert_eq!(m.vertices.len(), 4);
        let expected = [[0, 1, 2], [0, 2, 3], [3, 2, 1], [0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3]];
        assert_eq!(m.faces, expected);
        assert_eq!(m.colors, None);
        // Negative indices are relative to the vertices defined so far.
        let m = read("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf -1 -2 -3\n").unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2], [3, 2, 1]]);
    }

    #[test]
    fn ignored_statements_comments_and_w() {
        let s = "# exported\nmtllib a.mtl\no thing\ng group\ns off\nusemtl red\nv 0 0 0 1\nv 1 0 0\nv 0 1 0 # c\nvt 0 0\nvn 0 0 1\nl 1 2\n\nf 1/1/1 2/1/1 3/1/1\n";
        let m = read(s).unwrap();
        assert_eq!(m.vertices, vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
        assert_eq!(m.faces, vec![[0, 1, 2]]);
    }

    #[test]
    fn vertex_colours_only_when_on_every_vertex() {
        let m = read("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 0.5\nf 1 2 3\n").unwrap();
        assert_eq!(m.colors, Some(vec![[255, 0, 0], [0, 255, 0], [0, 0, 128]]));
        let m = read("v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(m.colors, None);
    }

    #[test]
    fn bad_input() {
        assert_parse(read(""), None, "expected at least one vertex, found none");
        assert_parse(read("# nothing\n\n"), None, "expected at least one vertex");
        assert_parse(read("vt 0 0\nf 1 2 3\n"), Some(Some(2)), "face 0: vertex index 1 out of range");
        assert_parse(read("v 0 0 0\nbogus 1 2\n"), Some(Some(2)), "found 'bogus'");
        assert_parse(read("v 0 0 zero\n"), Some(Some(1)), "expected a number in vertex 0, found 'zero'");
        assert_parse(read("v 0 0 0\nv 0 NaN 0\n"), Some(Some(2)), "vertex 1: expected finite coordinates");
        assert_parse(read("v 0 0 0\nv 0 0 -inf\n"), Some(Some(2)), "vertex 1: expected finite");
        assert_parse(read("v 0 0\n"), Some(Some(1)), "found 2 values");
        assert_parse(read("v 0 0 0 1 0\n"), Some(Some(1)), "found 5 values");
        assert_parse(read("v 0 0 0 2 0 0\n"), Some(Some(1)), "expected colour values in [0, 1]");
        let q = |f: &str| read(&format!("{QUAD}{f}\n"));
        assert_parse(q("f 1 2"), Some(Some(5)), "face 0: expected at least 3 vertices, found 2");
        assert_parse(q("f"), Some(Some(5)), "found 0");
        assert_parse(q("f 1 2 0"), Some(Some(5)), "face 0: vertex index 0 out of range");
        assert_parse(q("f 1 2 5"), Some(Some(5)), "vertex index 5 out of range (expected 1..=4");
        assert_parse(q("f 1 2 -5"), Some(Some(5)), "vertex index -5 out of range");
        assert_parse(q("f 1 2 x/1"), Some(Some(5)), "expected a vertex index in face 0, found 'x'");
        assert_parse(q("f 1 2 99999999999999999999"), Some(Some(5)), "expected a vertex index");
        // Forward references are not allowed.
        assert_parse(read("v 0 0 0\nf 1 2 3\nv 1 0 0\nv 0 1 0\n"), Some(Some(2)), "vertex index 2 out of range");
    }

    #[test]
    fn binary_garbage() {
        assert_parse(read_obj(&b"v 0 0 0\n\xff\xfe\n"[..], Path::new("t.obj")), Some(Some(2)), "invalid bytes");
        for seed in 1..5 {
            assert!(matches!(read_obj(&noise(2000, seed)[..], Path::new("t.obj")), Err(Error::Parse { .. })));
        }
    }
}

//! Text point lists (`.xyz`, `.txt`, `.pts`, `.csv`) and text matrices.
//!
//! One record per line, fields separated by commas (when the line contains one) or else by
//! whitespace; `#` starts a comment; the first non-comment line may be a non-numeric header
//! (e.g. `x,y,z`), which is skipped.

use std::io::BufRead;
use std::path::Path;

use super::text::{clip, parse_tok, LineReader};
use super::{check_records, check_vertex, finish, DenseMatrix, MeshData};
use crate::error::{Error, Result};

/// Calls `row(line, index, fields)` for each data line of `r`, skipping a header line whose
/// first `header_cols` fields are not all numbers when it is the first content line.
fn for_each_row<R: BufRead>(
    r: R,
    path: &Path,
    header_cols: usize,
    mut row: impl FnMut(usize, usize, &[&str]) -> Result<()>,
) -> Result<()> {
    let mut lines = LineReader::new(r, path, 1);
    let mut n = 0;
    let mut first = true;
    while let Some((ln, l)) = lines.next_content()? {
        let fields: Vec<&str> = match l.contains(',') {
            true => l.split(',').map(str::trim).collect(),
            false => l.split_whitespace().collect(),
        };
        let is_header = fields.iter().take(header_cols).any(|t| t.parse::<f64>().is_err());
        if !(first && is_header) {
            row(ln, n, &fields)?;
            n += 1;
        }
        first = false;
    }
    Ok(())
}

/// Reads a point cloud: at least 3 numeric columns `x y z` per line (extra columns are ignored).
/// `path` is only used in error messages.
///
/// Errors ([`Error::Parse`] with the line number): no points, invalid UTF-8, fewer than 3
/// columns, non-numeric or non-finite coordinates.
pub fn read_points_text<R: BufRead>(r: R, path: &Path) -> Result<MeshData> {
    let mut mesh = MeshData::default();
    for_each_row(r, path, 3, |ln, i, f| {
        if f.len() < 3 {
            let msg = format!("point {i}: expected at least 3 columns (x y z), found {}", f.len());
            return Err(Error::parse(path, Some(ln), msg));
        }
        let what = format!("a coordinate of point {i}");
        let c = |k: usize| parse_tok::<f64>(f[k], &what, path, ln);
        check_records(i, "points", path, Some(ln))?;
        mesh.vertices.push(check_vertex([c(0)?, c(1)?, c(2)?], i, path, Some(ln))?);
        Ok(())
    })?;
    finish(mesh, path, None)
}

/// Reads a dense matrix from text: one row per line, every row with the same number of finite
/// numeric columns. `path` is only used in error messages.
///
/// Errors ([`Error::Parse`] with the line number): no rows, ragged rows, non-numeric or
/// non-finite values.
pub fn read_matrix_text<R: BufRead>(r: R, path: &Path) -> Result<DenseMatrix> {
    let mut m = DenseMatrix { rows: 0, cols: 0, data: Vec::new() };
    for_each_row(r, path, usize::MAX, |ln, i, f| {
        if i == 0 {
            m.cols = f.len();
        } else if f.len() != m.cols {
            let msg = format!("row {i}: expected {} columns like the first row, found {}", m.cols, f.len());
            return Err(Error::parse(path, Some(ln), msg));
        }
        for (j, t) in f.iter().enumerate() {
            let v: f64 = parse_tok(t, &format!("a number at row {i}, column {j}"), path, ln)?;
            if !v.is_finite() {
                let msg = format!("row {i}, column {j}: expected a finite number, found '{}'", clip(t));
                return Err(Error::parse(path, Some(ln), msg));
            }
            check_records(m.data.len(), "values", path, Some(ln))?;
            m.data.push(v);
        }
        m.rows += 1;
        Ok(())
    })?;
    if m.rows == 0 {
        return Err(Error::parse(path, None, "expected at least one row of numbers, found none"));
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_util::{assert_parse, noise};

    fn read(s: &str) -> Result<MeshData> {
        read_points_text(s.as_bytes(), Path::new("t.xyz"))
    }

    #[test]
    fn whitespace_csv_header_comments_extra_columns() {
        let m = read("# scan\n0 0 0\n\n1.5\t-2 3e2   # trailing\n").unwrap();
        assert_eq!(m.vertices, vec![[0., 0., 0.], [1.5, -2., 300.]]);
        assert!(m.faces.is_empty() && m.colors.is_none());
        let m = read("x,y,z,label\n1, 2, 3, a\n4,5,6,b\r\n").unwrap();
        assert_eq!(m.vertices, vec![[1., 2., 3.], [4., 5., 6.]]);
        let m = read("1 2 3 255 0 0 0.1\n").unwrap();
        assert_eq!(m.vertices, vec![[1., 2., 3.]]);
    }

    #[test]
    fn bad_input() {
        assert_parse(read(""), None, "expected at least one vertex, found none");
        assert_parse(read("x y z\n"), None, "expected at least one vertex");
        assert_parse(read("1 2\n"), Some(Some(1)), "point 0: expected at least 3 columns (x y z), found 2");
        assert_parse(read("1 2 3\n4 5\n"), Some(Some(2)), "point 1: expected at least 3 columns");
        assert_parse(read("1 2 3\nx y z\n"), Some(Some(2)), "expected a coordinate of point 1, found 'x'");
        assert_parse(read("x,y,z\n1,,3\n"), Some(Some(2)), "expected a coordinate of point 0, found ''");
        assert_parse(read("1 2 3\n4 nan 6\n"), Some(Some(2)), "vertex 1: expected finite coordinates");
        assert_parse(read("1 2 3\n4 5 inf\n"), Some(Some(2)), "vertex 1: expected finite");
        assert_parse(read_points_text(&b"1 2 3\n\x80\x81\x82\n"[..], Path::new("t")), Some(Some(2)), "invalid bytes");
        for seed in 1..5 {
            assert!(matches!(read_points_text(&noise(3000, seed)[..], Path::new("t")), Err(Error::Parse { .. })));
        }
    }

    #[test]
    fn matrix_text() {
        let m = read_matrix_text(&b"# c\na b c\n1 2 3\n4 5 6\n"[..], Path::new("m.txt")).unwrap();
        assert_eq!(m, DenseMatrix { rows: 2, cols: 3, data: vec![1., 2., 3., 4., 5., 6.] });
        let m = read_matrix_text(&b"7\n8\n"[..], Path::new("m.txt")).unwrap();
        assert_eq!((m.rows, m.cols), (2, 1));
        let r = |s: &str| read_matrix_text(s.as_bytes(), Path::new("m.csv"));
        assert_parse(r(""), Some(None), "expected at least one row");
        assert_parse(r("1,2\n3\n"), Some(Some(2)), "row 1: expected 2 columns like the first row, found 1");
        assert_parse(r("1,2\n3,x\n"), Some(Some(2)), "expected a number at row 1, column 1, found 'x'");
        assert_parse(r("1,2\n3,nan\n"), Some(Some(2)), "row 1, column 1: expected a finite number");
    }
}

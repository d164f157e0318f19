//! Vertex-index files: landmark pairs, vertex lists, per-vertex labels, point-to-point maps.
//!
//! All are text, one record per line, `#` comments and blank lines ignored.
//! - landmark pairs: two vertex indices per line, `i j` (vertex i of X corresponds to vertex j of Y);
//! - vertex lists: one vertex index per line (seeds, `.vts` ground-truth files);
//! - labels: one integer label per line, one line per vertex (the format of
//!   `shared/data/*/segmentation`: 1-based labels).
//!
//! Indices are 0-based unless `one_based` is set (MATLAB-style files, `.vts`); every index is
//! checked against the number of vertices it refers to.

use std::io::BufRead;
use std::path::Path;

use super::text::{parse_tok, LineReader};
use crate::error::{Error, Result};

fn index(tok: &str, one_based: bool, limit: usize, path: &Path, line: usize, what: &str) -> Result<usize> {
    let v: i64 = parse_tok(tok, &format!("an integer {what}"), path, line)?;
    let first = if one_based { 1 } else { 0 };
    if v < first || (v - first) as u64 >= limit as u64 {
        // `limit` is usize::MAX when the file is read without a shape to check against.
        let range = match u64::try_from(limit).ok().and_then(|l| i64::try_from(l).ok()) {
            Some(l) if limit < usize::MAX => format!("{first}..={}", l - 1 + first),
            _ => format!("{first} or more"),
        };
        return Err(Error::parse(path, Some(line), format!("{what} {v} is out of range (expected {range})")));
    }
    Ok((v - first) as usize)
}

/// Reads landmark pairs `(i on X, j on Y)`; X has `n` vertices and Y has `m`.
pub fn read_index_pairs<R: BufRead>(
    r: R,
    path: &Path,
    one_based: bool,
    n: usize,
    m: usize,
) -> Result<Vec<(usize, usize)>> {
    let mut lines = LineReader::new(r, path, 1);
    let mut out = Vec::new();
    while let Some((line, text)) = lines.next_content()? {
        let toks: Vec<&str> = text.split(|c: char| c.is_whitespace() || c == ',').filter(|t| !t.is_empty()).collect();
        if toks.len() != 2 {
            return Err(Error::parse(
                path,
                Some(line),
                format!("expected two vertex indices, found {} values", toks.len()),
            ));
        }
        super::check_records(out.len(), "index pairs", path, Some(line))?;
        out.push((
            index(toks[0], one_based, n, path, line, "source vertex")?,
            index(toks[1], one_based, m, path, line, "target vertex")?,
        ));
    }
    if out.is_empty() {
        return Err(Error::parse(path, None, "expected at least one pair of vertex indices, found none"));
    }
    Ok(out)
}

/// Reads a list of vertex indices (one per line) on a shape with `n` vertices.
pub fn read_index_list<R: BufRead>(r: R, path: &Path, one_based: bool, n: usize) -> Result<Vec<usize>> {
    let mut lines = LineReader::new(r, path, 1);
    let mut out = Vec::new();
    while let Some((line, text)) = lines.next_content()? {
        super::check_records(out.len(), "vertex indices", path, Some(line))?;
        out.push(index(text, one_based, n, path, line, "vertex")?);
    }
    if out.is_empty() {
        return Err(Error::parse(path, None, "expected at least one vertex index, found none"));
    }
    Ok(out)
}

/// Reads a ground-truth template file (`.vts`): one 1-based vertex index per line on a shape
/// with `n` vertices, where 0 marks a template point the shape lacks (a part cut from a whole
/// shape): None. Errors as [`read_index_list`] (an index beyond n, a negative one, no line).
pub fn read_template_list<R: BufRead>(r: R, path: &Path, n: usize) -> Result<Vec<Option<usize>>> {
    let mut lines = LineReader::new(r, path, 1);
    let mut out = Vec::new();
    while let Some((line, text)) = lines.next_content()? {
        super::check_records(out.len(), "vertex indices", path, Some(line))?;
        let v: i64 = parse_tok(text, "an integer vertex", path, line)?;
        out.push(if v == 0 { None } else { Some(index(text, true, n, path, line, "vertex")?) });
    }
    if out.is_empty() {
        return Err(Error::parse(path, None, "expected at least one vertex index, found none"));
    }
    Ok(out)
}

/// [`read_template_list`] from a file.
pub fn read_template_list_file(path: &Path, n: usize) -> Result<Vec<Option<usize>>> {
    read_template_list(super::open(path)?, path, n)
}

/// Reads per-vertex integer labels: exactly `n` lines, each a non-negative integer.
pub fn read_labels<R: BufRead>(r: R, path: &Path, n: usize) -> Result<Vec<u32>> {
    let mut lines = LineReader::new(r, path, 1);
    let mut out = Vec::new();
    while let Some((line, text)) = lines.next_content()? {
        if out.len() == n {
            return Err(Error::parse(path, Some(line), format!("expected {n} labels (one per vertex), found more")));
        }
        out.push(parse_tok::<u32>(text, "a non-negative integer label", path, line)?);
    }
    if out.len() != n {
        return Err(Error::parse(path, None, format!("expected {n} labels (one per vertex), found {}", out.len())));
    }
    Ok(out)
}

/// [`read_index_pairs`] from a file.
pub fn read_index_pairs_file(path: &Path, one_based: bool, n: usize, m: usize) -> Result<Vec<(usize, usize)>> {
    read_index_pairs(super::open(path)?, path, one_based, n, m)
}

/// [`read_index_list`] from a file.
pub fn read_index_list_file(path: &Path, one_based: bool, n: usize) -> Result<Vec<usize>> {
    read_index_list(super::open(path)?, path, one_based, n)
}

/// [`read_labels`] from a file.
pub fn read_labels_file(path: &Path, n: usize) -> Result<Vec<u32>> {
    read_labels(super::open(path)?, path, n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("t.txt")
    }

    #[test]
    fn pairs_lists_labels() {
        let pairs = read_index_pairs("# seeds\n0 4\n2,1\n\n".as_bytes(), p(), false, 3, 5).unwrap();
        assert_eq!(pairs, vec![(0, 4), (2, 1)]);
        let one = read_index_pairs("1 5\n".as_bytes(), p(), true, 3, 5).unwrap();
        assert_eq!(one, vec![(0, 4)]);
        assert_eq!(read_index_list("3\n1\n".as_bytes(), p(), true, 3).unwrap(), vec![2, 0]);
        assert_eq!(read_labels("1\n2\n2\n".as_bytes(), p(), 3).unwrap(), vec![1, 2, 2]);
    }

    #[test]
    fn bad_files_are_errors_naming_the_line() {
        let e = read_index_pairs("0 1\n0 5\n".as_bytes(), p(), false, 3, 5).unwrap_err().to_string();
        assert!(e.contains("t.txt:2") && e.contains("target vertex 5 is out of range"), "{e}");
        let e = read_index_pairs("0 -1\n".as_bytes(), p(), false, 3, 5).unwrap_err().to_string();
        assert!(e.contains("out of range"), "{e}");
        let e = read_index_pairs("0 1 2\n".as_bytes(), p(), false, 3, 5).unwrap_err().to_string();
        assert!(e.contains("two vertex indices"), "{e}");
        assert!(read_index_pairs("".as_bytes(), p(), false, 3, 5).is_err());
        let e = read_index_list("0\n".as_bytes(), p(), true, 3).unwrap_err().to_string();
        assert!(e.contains("out of range (expected 1..=3)"), "{e}");
        let e = read_labels("1\n2\n".as_bytes(), p(), 3).unwrap_err().to_string();
        assert!(e.contains("expected 3 labels") && e.contains("found 2"), "{e}");
        let e = read_labels("1\n2\n3\n4\n".as_bytes(), p(), 3).unwrap_err().to_string();
        assert!(e.contains("t.txt:4"), "{e}");
        let e = read_labels("1\n2.5\n3\n".as_bytes(), p(), 3).unwrap_err().to_string();
        assert!(e.contains("t.txt:2") && e.contains("integer"), "{e}");
        assert!(read_labels("1\nx\n3\n".as_bytes(), p(), 3).is_err());
        assert!(read_labels(&[0xffu8, 0xfe, b'\n'][..], p(), 1).is_err());
    }
}

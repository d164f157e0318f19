//! The layer rule of ARCHITECTURE.md, checked: every `crate::module` path in the non-test code of
//! `src/` names a module of the same or a lower layer. A new upward import fails this test with
//! the file, line and the two layers.

use std::path::Path;

/// Layer of every top-level module (ARCHITECTURE.md's table; inside a layer, the order in which
/// modules may import each other, lowest first).
const LAYERS: &[(&str, f64)] = &[
    ("alloc", 0.0),
    ("error", 0.0),
    ("rng", 0.0),
    ("linalg", 0.0),
    ("cholesky", 0.1),
    ("progress", 0.0),
    ("optim", 0.1),
    ("io", 1.0),
    ("shape", 2.0),
    ("spatial", 2.1),
    ("primitives", 2.1),
    ("laplacian", 3.0),
    ("geodesic", 3.1),
    ("operators", 3.1),
    ("cell_quadrature", 3.15),
    ("cloud", 3.2),
    ("denoise", 3.3),
    ("spectral", 4.0),
    ("prepared", 4.1),
    ("descriptors", 5.0),
    ("fmap", 6.0),
    ("completion", 6.1),
    ("pointwise", 7.0),
    ("certified_search", 7.05),
    ("refine", 7.1),
    ("matching", 7.2),
    ("eval", 8.0),
    ("benchmark", 9.0),
    ("experiments", 9.0),
    ("viz", 10.0),
];

fn layer(module: &str) -> Option<f64> {
    LAYERS.iter().find(|(m, _)| *m == module).map(|&(_, l)| l)
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn imports_point_down_the_layers() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    let mut upward = Vec::new();
    let mut unknown = Vec::new();
    for path in &files {
        let rel = path.strip_prefix(&src).unwrap();
        let top = rel.components().next().unwrap().as_os_str().to_string_lossy().trim_end_matches(".rs").to_string();
        if top == "lib" || rel.ends_with("tests.rs") {
            continue;
        }
        let Some(own) = layer(&top) else {
            unknown.push(top);
            continue;
        };
        let text = std::fs::read_to_string(path).unwrap();
        let code = text.split("#[cfg(test)]").next().unwrap();
        for (i, line) in code.lines().enumerate() {
            let line = line.trim_start();
            if line.starts_with("//") {
                continue;
            }
            for (pos, _) in line.match_indices("crate::") {
                let name: String =
                    line[pos + 7..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
                if let Some(l) = layer(&name) {
                    if name != top && l > own {
                        upward.push(format!("{}:{}: {top} ({own}) -> {name} ({l})", rel.display(), i + 1));
                    }
                }
            }
        }
    }
    assert!(unknown.is_empty(), "modules missing from LAYERS (add them to ARCHITECTURE.md too): {unknown:?}");
    assert!(upward.is_empty(), "imports pointing up the layers:\n{}", upward.join("\n"));
    // The check sees the code: a known downward import is found.
    let eval = std::fs::read_to_string(src.join("eval.rs")).unwrap();
    assert!(eval.contains("crate::geodesic"));
}

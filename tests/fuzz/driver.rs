//! A mutation fuzzer for funcorr's parsers that runs on the stable toolchain (no nightly, so no
//! cargo-fuzz / libFuzzer instrumentation): valid seed files of every format, mutated by byte-
//! and token-level operators (flips, extreme numbers, format keywords, splices, truncations),
//! fed to each parser in-process. An input fails when the parser panics, takes longer than
//! [`SLOW`], or allocates more than [`alloc_budget`] for its size (a counting global allocator,
//! [`CountingAlloc`], measures the peak) — "never panic, never allocate by an untrusted number".
//!
//! Used by `tests/fuzz.rs` (a short run of every target and the regression corpus under
//! `tests/fuzz_corpus/`) and `examples/fuzz.rs` (the long runs of BENCHMARKS.md). Written here
//! rather than with `arbitrary`/`proptest` because the inputs are byte strings whose useful
//! mutations are format-specific tokens, which a 200-line driver expresses directly.

#![allow(dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Cursor;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use funcorr::io::{self, MeshData};

/// An input taking longer than this is a failure (inputs are at most a few kB).
pub const SLOW: Duration = Duration::from_secs(2);

/// Allocation allowed for an input of `len` bytes: 64 MiB plus 1000 bytes per input byte.
/// A parser that reserves by a header's claim instead of the data present exceeds it.
pub fn alloc_budget(len: usize) -> usize {
    (64 << 20) + 1000 * len
}

static CURRENT: AtomicUsize = AtomicUsize::new(0);
/// Inputs a parser accepted (returned Ok) since the last [`fuzz`] started.
static ACCEPTED: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

/// The system allocator, counting the bytes in use and their peak.
pub struct CountingAlloc;

unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = CURRENT.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size >= layout.size() {
                let now = CURRENT.fetch_add(new_size - layout.size(), Ordering::Relaxed) + new_size - layout.size();
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                CURRENT.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

/// xorshift64*: a seeded generator for the mutations (the library's own is crate-private).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// A parser under test: its name, the seed inputs and the call. Ok and a clean error both pass;
/// the call returns a message when a property is violated (an error that does not name the
/// file).
pub struct Target {
    pub name: &'static str,
    pub seeds: Vec<Vec<u8>>,
    pub run: fn(&[u8]) -> Option<String>,
}

/// Distinct error messages (their first 48 letters, quoted text removed) seen since the last [`fuzz`]
/// started: a rough measure of how many error paths the mutations reach.
static OUTCOMES: std::sync::Mutex<Option<std::collections::HashSet<String>>> = std::sync::Mutex::new(None);

fn record_error(e: &funcorr::Error) {
    let text = e.to_string();
    // After an echoed input ("'…': reason") only the reason counts.
    let text = text.rsplit_once("': ").map_or(text.as_str(), |(_, reason)| reason);
    let mut kind = String::new();
    let mut quoted = false;
    for c in text.chars() {
        if c == '\'' {
            quoted = !quoted;
        } else if !quoted && !c.is_ascii_digit() {
            kind.push(c);
        }
    }
    // The leading words name the check that failed; the tail echoes the input.
    let kind: String = kind.chars().filter(|c| c.is_ascii_alphabetic() || *c == ' ').take(48).collect();
    if let Ok(mut set) = OUTCOMES.lock() {
        set.get_or_insert_with(Default::default).insert(kind);
    }
}

/// A parse error must name the file it is about.
fn names_file<T>(r: funcorr::Result<T>) -> Option<String> {
    match &r {
        Ok(_) => {
            ACCEPTED.fetch_add(1, Ordering::Relaxed);
        }
        Err(e) => record_error(e),
    }
    match r {
        Err(e) if !e.to_string().contains("fuzz-input") => Some(format!("error without the file name: {e}")),
        _ => None,
    }
}

/// Beyond parsing, a mesh that parses is built into a shape and, when it has faces, its
/// cotangent Laplacian is assembled: geometry code sees the same hostile values.
fn mesh_checks(m: funcorr::Result<MeshData>) -> Option<String> {
    match m {
        Ok(m) => {
            ACCEPTED.fetch_add(1, Ordering::Relaxed);
            if let Ok(funcorr::shape::Shape::Mesh(mesh)) = funcorr::shape::Shape::from_data(m) {
                let _ = funcorr::laplacian::cotangent(&mesh);
            }
            None
        }
        Err(e) => names_file::<()>(Err(e)),
    }
}

fn p() -> &'static Path {
    Path::new("fuzz-input")
}

/// A small valid mesh (an octahedron with colours) for the seeds.
fn octahedron() -> MeshData {
    let v = vec![[1., 0., 0.], [-1., 0., 0.], [0., 1., 0.], [0., -1., 0.], [0., 0., 1.], [0., 0., -1.]];
    let f = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    let colors = Some((0..6).map(|i| [40 * i as u8, 255 - 40 * i as u8, 7]).collect());
    MeshData { vertices: v, faces: f, colors }
}

fn npy_bytes(rows: usize, cols: usize) -> Vec<u8> {
    let dir = std::env::temp_dir().join(format!("funcorr-fuzz-seed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("m{rows}x{cols}.npy"));
    let data = (0..rows * cols).map(|i| i as f64 * 0.5 - 1.0).collect();
    io::npy::write_npy_matrix(&path, &io::DenseMatrix { rows, cols, data }).unwrap();
    std::fs::read(&path).unwrap()
}

fn npz_bytes() -> Vec<u8> {
    use io::npy::NpzArray;
    let dir = std::env::temp_dir().join(format!("funcorr-fuzz-seed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("b.npz");
    let arrays = [
        ("eigenvalues", NpzArray::F64 { shape: vec![3], data: vec![0.0, 1.5, 2.5] }),
        ("eigenvectors", NpzArray::F64 { shape: vec![4, 3], data: (0..12).map(f64::from).collect() }),
        ("map", NpzArray::I64 { shape: vec![2], data: vec![1, 0] }),
    ];
    io::npy::write_npz(&path, &arrays).unwrap();
    std::fs::read(&path).unwrap()
}

/// Every parser of issue 15 with its seeds.
pub fn targets() -> Vec<Target> {
    let oct = octahedron();
    let mut off = Vec::new();
    io::off::write_off(&mut off, &oct, p()).unwrap();
    let coff = {
        let mut s = String::from("COFF\n6 8 0\n");
        for (v, c) in oct.vertices.iter().zip(oct.colors.as_ref().unwrap()) {
            s += &format!("{} {} {} {} {} {} 255\n", v[0], v[1], v[2], c[0], c[1], c[2]);
        }
        s += "4 0 2 1 3\n3 0 4 2\n";
        s.into_bytes()
    };
    let mut ply_ascii = Vec::new();
    io::ply::write_ply(&mut ply_ascii, &oct, true).unwrap();
    let mut ply_bin = Vec::new();
    io::ply::write_ply(&mut ply_bin, &oct, false).unwrap();
    let ply_be =
        b"ply\nformat binary_big_endian 1.0\ncomment x\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
            .iter()
            .copied()
            .chain([0f32, 0., 0., 1., 0., 0., 0., 1., 0.].iter().flat_map(|v| v.to_be_bytes()))
            .chain([3u8])
            .chain([0i32, 1, 2].iter().flat_map(|v| v.to_be_bytes()))
            .collect::<Vec<u8>>();
    let obj = b"# octahedron\nv 1 0 0\nv -1 0 0\nv 0 1 0 1 0 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\nvn 0 0 1\nvt 0.5 0.5\n\
g body\nf 1/1/1 3/1/1 5/1/1\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf -4 -6 -1 -3\nusemtl skin\ns off\n"
        .to_vec();
    vec![
        Target { name: "off", seeds: vec![off, coff], run: |b| mesh_checks(io::off::read_off(Cursor::new(b), p())) },
        Target { name: "obj", seeds: vec![obj], run: |b| mesh_checks(io::obj::read_obj(Cursor::new(b), p())) },
        Target {
            name: "ply-ascii",
            seeds: vec![ply_ascii],
            run: |b| mesh_checks(io::ply::read_ply(Cursor::new(b), p())),
        },
        Target {
            name: "ply-binary",
            seeds: vec![ply_bin, ply_be],
            run: |b| mesh_checks(io::ply::read_ply(Cursor::new(b), p())),
        },
        Target {
            name: "npy",
            seeds: vec![npy_bytes(4, 3), npy_bytes(1, 1)],
            run: |b| names_file(io::npy::read_npy_matrix_from(Cursor::new(b), p())),
        },
        Target {
            name: "npz",
            seeds: vec![npz_bytes()],
            run: |b| names_file(io::npy::read_npz_from(Cursor::new(b), b.len() as u64, p())),
        },
        Target {
            name: "xyz",
            seeds: vec![b"# scan\n0 0 0\n1 0 0\n0 1 0 255\n".to_vec(), b"x,y,z\n1,2,3\n4,5,6\r\n".to_vec()],
            run: |b| mesh_checks(io::points::read_points_text(Cursor::new(b), p())),
        },
        Target {
            name: "matrix-text",
            seeds: vec![b"1 2 3\n4 5 6\n".to_vec(), b"0.5,1e-3\n-2,7\n".to_vec()],
            run: |b| names_file(io::points::read_matrix_text(Cursor::new(b), p())),
        },
        Target {
            name: "landmarks",
            seeds: vec![b"# i j\n0 5\n3, 4\n".to_vec()],
            run: |b| names_file(io::indices::read_index_pairs(Cursor::new(b), p(), false, 10, 10)),
        },
        Target {
            name: "vts",
            seeds: vec![b"1\n10\n5\n".to_vec()],
            run: |b| {
                // 1-based on 10 vertices (.vts) and 0-based unbounded (a map file before its
                // target is known); only the first counts as accepted.
                let unbounded = match io::indices::read_index_list(Cursor::new(b), p(), false, usize::MAX) {
                    Err(e) if !e.to_string().contains("fuzz-input") => {
                        Some(format!("error without the file name: {e}"))
                    }
                    _ => None,
                };
                names_file(io::indices::read_index_list(Cursor::new(b), p(), true, 10)).or(unbounded)
            },
        },
        Target {
            name: "labels",
            seeds: vec![b"1\n1\n2\n3\n".to_vec()],
            run: |b| names_file(io::indices::read_labels(Cursor::new(b), p(), 4)),
        },
        Target {
            name: "manifest",
            seeds: vec![
                br#"{"files":["map.txt","maps/a.txt"],"tool":"funcorr","version":"0.1.0"}"#.to_vec(),
                br#"{"files":["../v.txt","sub/v.txt","/etc/passwd",".hidden","a\\b","x\u0000y"]}"#.to_vec(),
                b"{\n  \"files\": [\n    \"C.npy\",\n    \"render.png\"\n  ]\n}\n".to_vec(),
            ],
            run: |b| {
                // A previous run's manifest decides what a publish deletes: every name it keeps
                // must stay below the output directory and off its hidden files.
                let files = funcorr::io::staged::manifest_files(b);
                if !files.is_empty() {
                    ACCEPTED.fetch_add(1, Ordering::Relaxed);
                }
                files.iter().find_map(|f| {
                    let plain = f.split('/').all(|c| {
                        !c.is_empty() && !c.starts_with('.') && !c.chars().any(|ch| ch == '\\' || ch.is_control())
                    });
                    (!plain).then(|| format!("kept a manifest entry that leaves the directory: {f:?}"))
                })
            },
        },
        Target {
            name: "data-spec",
            seeds: [
                "wks",
                "wks:50",
                "hks:3",
                "wks+hks",
                "segments:a.seg,b.seg",
                "rich:a,b",
                "landmarks:l.txt",
                "matrix:f.npy,g.csv",
                "mser",
                "persistence",
            ]
            .iter()
            .map(|s| s.as_bytes().to_vec())
            .collect(),
            run: |b| match String::from_utf8_lossy(b).parse::<funcorr::descriptors::spec::PairDataSpec>() {
                Ok(_) => {
                    ACCEPTED.fetch_add(1, Ordering::Relaxed);
                    None
                }
                Err(e) if !e.to_string().starts_with("invalid data:") => {
                    Some(format!("error without the parameter name: {e}"))
                }
                Err(e) => {
                    record_error(&e);
                    None
                }
            },
        },
    ]
}

/// Tokens spliced into inputs: format keywords, extreme and malformed numbers, separators.
const DICTIONARY: &[&str] = &[
    "OFF",
    "COFF",
    "NOFF",
    "ply",
    "format",
    "ascii",
    "binary_little_endian",
    "binary_big_endian",
    "1.0",
    "element",
    "vertex",
    "face",
    "property",
    "list",
    "uchar",
    "int",
    "uint",
    "float",
    "double",
    "char",
    "vertex_indices",
    "end_header",
    "comment",
    "v",
    "f",
    "vn",
    "vt",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "1e-310",
    "1e300",
    "-0",
    "0",
    "1",
    "2",
    "3",
    "-1",
    "-2",
    "255",
    "256",
    "65535",
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "100000000",
    "134217727",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999",
    "0x10",
    "1/2/3",
    "//",
    ",",
    ",,",
    " ",
    "\t",
    "\n",
    "\r\n",
    "\r",
    "#",
    "\u{feff}",
    "\0",
    "é",
    ":",
    "+",
    "wks",
    "hks",
    "segments",
    "rich",
    "matrix",
    "landmarks",
    "{'descr': '<f8', 'fortran_order': False, 'shape': (99999999999, 3), }",
    "'shape': (0,)",
    "\u{93}NUMPY",
    "PK\u{3}\u{4}",
    ".npy",
    "\"files\"",
    "[",
    "]",
    "{",
    "}",
    "\"",
    "/",
    "..",
    "\\\\",
    "\\u0000",
    "\\/",
];

/// Numbers that replace a digit: extremes, malformed, signs.
const NUMBERS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e308",
    "1e-310",
    "1e300",
    "-0",
    "-1",
    "255",
    "256",
    "65535",
    "2147483648",
    "4294967295",
    "4294967296",
    "18446744073709551616",
    "99999999999999999999999",
    "0x10",
    "1.5",
    "-3",
    "1e5",
    // Counts just below the record cap: a reader that reserves by them allocates gigabytes.
    "100000000",
    "134217727",
    "5000000",
];

/// Applies 1–8 random mutations to `input`.
pub fn mutate(input: &[u8], rng: &mut Rng, seeds: &[Vec<u8>]) -> Vec<u8> {
    let mut b = input.to_vec();
    // Mostly one mutation (inputs stay close to valid and reach deep code), sometimes a stack.
    let count = if rng.below(4) == 0 { 2 + rng.below(7) } else { 1 };
    for _ in 0..count {
        let len = b.len();
        match rng.below(11) {
            0 if len > 0 => {
                let i = rng.below(len);
                b[i] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let i = rng.below(len);
                b[i] = [0u8, 0xff, b'\n', b' ', b'-', b'9', b'.', b'e', b'0', 0x7f, 0x80][rng.below(11)];
            }
            2 => {
                let i = rng.below(len + 1);
                let tok = DICTIONARY[rng.below(DICTIONARY.len())].as_bytes();
                b.splice(i..i, tok.iter().copied());
            }
            3 if len > 0 => {
                // Replace a whitespace-separated token by a dictionary token.
                let i = rng.below(len);
                let start = b[..i].iter().rposition(|c| c.is_ascii_whitespace()).map_or(0, |p| p + 1);
                let end = b[i..].iter().position(|c| c.is_ascii_whitespace()).map_or(len, |p| i + p);
                let tok = DICTIONARY[rng.below(DICTIONARY.len())].as_bytes();
                b.splice(start..end, tok.iter().copied());
            }
            4 if len > 0 => {
                let i = rng.below(len);
                let n = 1 + rng.below((len - i).min(64));
                b.drain(i..i + n);
            }
            5 if len > 0 => {
                // Duplicate a range (repeated records, repeated header lines).
                let i = rng.below(len);
                let n = 1 + rng.below((len - i).min(256));
                let chunk: Vec<u8> = b[i..i + n].to_vec();
                let at = rng.below(b.len() + 1);
                b.splice(at..at, chunk);
            }
            6 if len > 0 => b.truncate(rng.below(len)),
            7 => {
                let i = rng.below(len + 1);
                let n = 1 + rng.below(16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
                b.splice(i..i, bytes);
            }
            8 if len >= 4 => {
                // Overwrite 1, 2, 4 or 8 bytes with an extreme little/big-endian integer or float.
                let w = [1usize, 2, 4, 8][rng.below(4)].min(len);
                let i = rng.below(len - w + 1);
                let v: u64 =
                    [0, 1, u64::MAX, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, f64::NAN.to_bits(), 1e300f64.to_bits()]
                        [rng.below(8)];
                let bytes = if rng.below(2) == 0 { v.to_le_bytes() } else { v.to_be_bytes() };
                b[i..i + w].copy_from_slice(&bytes[..w]);
            }
            9 if !seeds.is_empty() => {
                // Splice with another seed.
                let other = &seeds[rng.below(seeds.len())];
                let cut = rng.below(b.len() + 1);
                let from = rng.below(other.len() + 1);
                b.truncate(cut);
                b.extend_from_slice(&other[from..]);
            }
            _ => {
                // Change a number in place (digits to a larger count, sign flips).
                if let Some(i) = (0..len).map(|_| rng.below(len)).find(|&i| b[i].is_ascii_digit()) {
                    let d = NUMBERS[rng.below(NUMBERS.len())].as_bytes();
                    b.splice(i..i + 1, d.iter().copied());
                }
            }
        }
        if b.len() > 1 << 16 {
            b.truncate(1 << 16);
        }
    }
    b
}

/// One failing input.
#[derive(Debug)]
pub struct Failure {
    pub target: &'static str,
    pub input: Vec<u8>,
    pub what: String,
}

/// Runs one input: a panic, a slow run or an allocation over budget is a failure.
pub fn check(target: &Target, input: &[u8]) -> Option<String> {
    let base = CURRENT.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let t = Instant::now();
    let outcome = std::panic::catch_unwind(|| (target.run)(input));
    let elapsed = t.elapsed();
    let peak = PEAK.load(Ordering::Relaxed).saturating_sub(base);
    match outcome {
        Ok(Some(violation)) => Some(violation),
        Err(e) => {
            let msg = e
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Some(format!("panic: {msg}"))
        }
        Ok(_) if elapsed > SLOW => Some(format!("slow: {:.1} s", elapsed.as_secs_f64())),
        Ok(_) if peak > alloc_budget(input.len()) => {
            Some(format!("allocated {peak} bytes for a {}-byte input", input.len()))
        }
        Ok(_) => None,
    }
}

/// Statistics of one target's run.
#[derive(Debug)]
pub struct Run {
    pub target: &'static str,
    pub inputs: u64,
    pub seconds: f64,
    /// Inputs the parser accepted (the rest were rejected with an error).
    pub accepted: u64,
    /// Distinct error messages (first 48 letters, quoted text removed) of the rejected inputs.
    pub distinct_errors: usize,
    pub failures: Vec<Failure>,
}

/// Feeds `inputs` mutated inputs (seeded by `seed`) to `target`; stops collecting after 20
/// failures.
pub fn fuzz(target: &Target, inputs: u64, seed: u64) -> Run {
    let mut rng = Rng::new(seed ^ target.name.bytes().fold(0u64, |h, c| h.wrapping_mul(31).wrapping_add(c as u64)));
    let mut failures = Vec::new();
    ACCEPTED.store(0, Ordering::Relaxed);
    if let Ok(mut set) = OUTCOMES.lock() {
        *set = Some(Default::default());
    }
    let t = Instant::now();
    // Mutations compound: most inputs derive from a seed, some from an earlier mutant.
    let mut pool: Vec<Vec<u8>> = target.seeds.clone();
    for seed_input in &target.seeds {
        if let Some(what) = check(target, seed_input) {
            failures.push(Failure { target: target.name, input: seed_input.clone(), what });
        }
    }
    for i in 0..inputs {
        let parent = &pool[rng.below(pool.len())];
        let input = mutate(parent, &mut rng, &target.seeds);
        let before = ACCEPTED.load(Ordering::Relaxed);
        if let Some(what) = check(target, &input) {
            if failures.len() < 20 {
                failures.push(Failure { target: target.name, input: input.clone(), what });
            }
        }
        // Accepted mutants join the pool (they are valid inputs of another shape, the best
        // parents for reaching deeper code); a few rejected ones too, to explore error paths.
        if ACCEPTED.load(Ordering::Relaxed) > before || i % 256 == 0 {
            if pool.len() < 512 {
                pool.push(input);
            } else {
                let k = target.seeds.len() + rng.below(pool.len() - target.seeds.len());
                pool[k] = input;
            }
        }
    }
    let accepted = ACCEPTED.load(Ordering::Relaxed) as u64;
    let distinct_errors = OUTCOMES.lock().map(|s| s.as_ref().map_or(0, |s| s.len())).unwrap_or(0);
    Run { target: target.name, inputs, seconds: t.elapsed().as_secs_f64(), accepted, distinct_errors, failures }
}

/// Silences the default panic message while fuzzing (panics are caught and reported).
pub fn quiet_panics() {
    std::panic::set_hook(Box::new(|_| {}));
}

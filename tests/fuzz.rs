//! Short fuzz runs of every parser and the regression corpus (issue 15). The long runs
//! (≥ 10⁶ inputs per parser) are `cargo run --release --example fuzz`, reported in BENCHMARKS.md.
//!
//! One test function, so that the counting allocator measures one input at a time.

#[path = "fuzz/driver.rs"]
mod driver;

#[global_allocator]
static ALLOC: driver::CountingAlloc = driver::CountingAlloc;

/// Inputs per target in the test suite (a few seconds in all).
const SHORT_RUN: u64 = 3_000;

#[test]
fn parsers_survive_mutated_inputs_and_the_regression_corpus() {
    driver::quiet_panics();
    driver_detects_panics_big_allocations_and_violations();
    let targets = driver::targets();
    let mut problems = Vec::new();
    // Every file under tests/fuzz_corpus/<target>/ once failed (or is a hostile case from
    // issue 15); each must now pass its target's checks.
    let corpus = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_corpus");
    let mut replayed = 0;
    for t in &targets {
        let dir = corpus.join(t.name);
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        for e in entries {
            let path = e.unwrap().path();
            let input = std::fs::read(&path).unwrap();
            replayed += 1;
            if let Some(what) = driver::check(t, &input) {
                problems.push(format!("{}: {what}", path.display()));
            }
        }
    }
    assert!(replayed >= 10, "the regression corpus went missing ({replayed} files)");
    for t in &targets {
        let run = driver::fuzz(t, SHORT_RUN, 2026);
        for f in &run.failures {
            problems.push(format!("{}: {} (input {:?})", f.target, f.what, String::from_utf8_lossy(&f.input)));
        }
    }
    assert!(problems.is_empty(), "{} problems:\n{}", problems.len(), problems.join("\n"));
}

/// The checks themselves must be able to fail (run inside the one test: the allocation
/// counter is process-wide).
fn driver_detects_panics_big_allocations_and_violations() {
    let seeds = vec![b"x".to_vec()];
    let panics = driver::Target { name: "panics", seeds: seeds.clone(), run: |_| panic!("boom") };
    assert!(driver::check(&panics, b"x").unwrap().contains("boom"));
    let greedy = driver::Target {
        name: "greedy",
        seeds: seeds.clone(),
        run: |_| {
            let v = vec![1u8; 200 << 20];
            std::hint::black_box(&v);
            None
        },
    };
    assert!(driver::check(&greedy, b"x").unwrap().contains("allocated"));
    let rude = driver::Target { name: "rude", seeds, run: |_| Some("error without the file name".into()) };
    assert!(driver::check(&rude, b"x").is_some());
}

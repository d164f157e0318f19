//! The long fuzz runs of issue 15: every parser fed N mutated inputs (default 10⁶).
//!
//! ```text
//! cargo run --release --example fuzz -- [INPUTS] [SEED] [TARGET…]
//! ```
//! Prints one line per target (inputs, seconds, executions per second, failures) and writes each
//! failing input to `target/fuzz-failures/<target>/<n>.bin`; copy the ones that failed into
//! `tests/fuzz_corpus/<target>/` once fixed, so that `cargo test` replays them forever.

#[path = "../tests/fuzz/driver.rs"]
mod driver;

#[global_allocator]
static ALLOC: driver::CountingAlloc = driver::CountingAlloc;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let inputs: u64 = args.first().and_then(|a| a.parse().ok()).unwrap_or(1_000_000);
    let seed: u64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(1);
    let only: Vec<&str> = args.iter().skip(2).map(String::as_str).collect();
    driver::quiet_panics();
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fuzz-failures");
    println!("| target | inputs | accepted | distinct errors | seconds | inputs/s | failures |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    let mut total = 0;
    for t in driver::targets().iter().filter(|t| only.is_empty() || only.contains(&t.name)) {
        let run = driver::fuzz(t, inputs, seed);
        println!(
            "| {} | {} | {:.1}% | {} | {:.1} | {:.0} | {} |",
            run.target,
            run.inputs,
            100.0 * run.accepted as f64 / (run.inputs + t.seeds.len() as u64) as f64,
            run.distinct_errors,
            run.seconds,
            run.inputs as f64 / run.seconds,
            run.failures.len()
        );
        for (i, f) in run.failures.iter().enumerate() {
            let dir = out.join(f.target);
            std::fs::create_dir_all(&dir).unwrap();
            let path = dir.join(format!("{i}.bin"));
            std::fs::write(&path, &f.input).unwrap();
            eprintln!("  {}: {} -> {}", f.target, f.what, path.display());
        }
        total += run.failures.len();
    }
    if total > 0 {
        std::process::exit(1);
    }
}

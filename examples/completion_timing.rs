//! Timing of the L1 term of (11) (value + gradient), the hot loop of the completion solver.
//!
//! ```sh
//! cargo run --release --example completion_timing -- [m n k' k reps block]
//! ```
//! Defaults: m = n = 5000, k' = 350, k = 250, 5 repetitions, 512-row blocks; random bases.
//! Prints seconds per evaluation and GFLOP/s counting 6·m·n·k flops (2·m·n·k for the value).
//!
//! ```sh
//! cargo run --release --example completion_timing -- faust [k' k iterations]
//! ```
//! Runs the optimizer on the bundled FAUST pair (paper defaults, 100 WKS, identity start) for a
//! few iterations and prints the seconds per iteration.

use std::time::Instant;

use faer::Mat;
use funcorr::completion::terms;

/// Deterministic pseudo-random matrix, entries uniform in [−scale, scale].
fn random(rows: usize, cols: usize, seed: u64, scale: f64) -> Mat<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    Mat::from_fn(rows, cols, |_, _| {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        scale * ((s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0)
    })
}

fn faust(args: &[String]) {
    use funcorr::completion::{init_from_c, optimize, CompletionParams, OptimizeOptions, Problem};
    use funcorr::shape::Shape;
    use funcorr::{descriptors::signatures::wks, laplacian, spectral};
    let get = |i: usize, d: usize| args.get(i).map_or(d, |a| a.parse().expect("integer arguments"));
    let (kp, k, iterations) = (get(0, 350), get(1, 250), get(2, 5));
    let load = |p: &str| {
        let Shape::Mesh(mesh) = Shape::load(p.as_ref()).unwrap() else { panic!("{p}: not a triangle mesh") };
        let start = Instant::now();
        let lap = laplacian::cotangent(&mesh).unwrap();
        let (basis, _) = spectral::eigen_basis(&lap, &spectral::SpectralOptions::new(kp), None).unwrap();
        println!("{p}: {} vertices, basis of {kp} in {:.1} s", basis.n(), start.elapsed().as_secs_f64());
        basis
    };
    let (bx, by) = (load("data/faust/tr_reg_000.off"), load("data/faust/tr_reg_001.off"));
    let (f, g) = (wks(&bx, 100, true).unwrap(), wks(&by, 100, true).unwrap());
    let problem = Problem::new(&bx, &by, &f, &g, kp, funcorr::completion::Scaling::Paper).unwrap();
    let (a0, b0) = init_from_c(Mat::<f64>::identity(k, k).as_ref(), kp, k).unwrap();
    let opts = OptimizeOptions { max_iterations: iterations, ..Default::default() };
    let (_, _, report) = optimize(&problem, &CompletionParams::default(), &opts, a0.as_ref(), b0.as_ref()).unwrap();
    println!(
        "optimize: {} iterations, {} evaluations, {:.3} s per iteration, {:.3} s per evaluation",
        report.iterations,
        report.evaluations,
        report.seconds_per_iteration,
        report.seconds_total / report.evaluations as f64
    );
    println!("{}", serde_json::to_string(&report.terms).unwrap());
}

fn main() {
    let raw: Vec<String> = std::env::args().skip(1).collect();
    if raw.first().map(String::as_str) == Some("faust") {
        faust(&raw[1..]);
        return;
    }
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("integer arguments")).collect();
    let get = |i: usize, d: usize| args.get(i).copied().unwrap_or(d);
    let (m, n, kp, k, reps, block) = (get(0, 5000), get(1, 5000), get(2, 350), get(3, 250), get(4, 5), get(5, 512));
    let phi = random(n, kp, 1, 0.02);
    let psi = random(m, kp, 2, 0.02);
    let a = random(kp, k, 3, 0.1);
    let b = random(kp, k, 4, 0.1);
    let xi = 1e-3;
    println!("m = {m}, n = {n}, k' = {kp}, k = {k}, block = {block}, threads = {}", rayon::current_num_threads());
    // Warm-up.
    let t = terms::l1(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), xi, None, block);
    println!(
        "value {:e}, ‖∇_A‖ {:e}, ‖∇_B‖ {:e} (bit-identical for any thread count)",
        t.value,
        t.grad_a.norm_l2(),
        t.grad_b.norm_l2()
    );
    let mut times = Vec::new();
    for _ in 0..reps {
        let start = Instant::now();
        let r = terms::l1(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), xi, None, block);
        times.push(start.elapsed().as_secs_f64());
        assert_eq!(r.value, t.value, "deterministic");
    }
    let best = times.iter().cloned().fold(f64::MAX, f64::min);
    let mean = times.iter().sum::<f64>() / times.len() as f64;
    let flops = 6.0 * m as f64 * n as f64 * k as f64;
    println!(
        "value+gradient: best {best:.4} s, mean {mean:.4} s, {:.1} GFLOP/s (best, 6·m·n·k = {:.2e} flops)",
        flops / best / 1e9,
        flops
    );
    let mut vtimes = Vec::new();
    for _ in 0..reps {
        let start = Instant::now();
        let v = terms::l1_value(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), xi, None, block);
        vtimes.push(start.elapsed().as_secs_f64());
        assert!((v - t.value).abs() <= 1e-12 * t.value);
    }
    let vbest = vtimes.iter().cloned().fold(f64::MAX, f64::min);
    println!("value only: best {vbest:.4} s, {:.1} GFLOP/s (2·m·n·k)", flops / 3.0 / vbest / 1e9);
}

//! Timing of the L1 term of (11) (value + gradient), the hot loop of the completion solver.
//!
//! ```sh
//! cargo run --release --example completion_timing -- [m n k' k reps block]
//! ```
//! Defaults: m = n = 5000, k' = 350, k = 250, 5 repetitions, 512-row blocks; random bases.
//! Prints seconds per evaluation and GFLOP/s counting 6·m·n·k flops (2·m·n·k for the value).
//!
//! ```sh
//! cargo run --release --example completion_timing -- pair X.off Y.off [k' k iterations]
//! ```
//! Runs the subspace optimizer (Unit defaults, 100 WKS, start from eq. (5)) on a pair of shapes
//! for a few iterations and prints the seconds per iteration and per evaluation.

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

fn pair(args: &[String]) {
    use funcorr::completion::{init_from_c, optimize, CompletionParams, OptimizeOptions, Problem, Scaling};
    use funcorr::fmap::{ovsjanikov, OvsjanikovOptions};
    use funcorr::shape::Shape;
    use funcorr::{descriptors::signatures::wks, laplacian, spectral};
    let (px, py) = (args[0].as_str(), args[1].as_str());
    let get = |i: usize, d: usize| args.get(i).map_or(d, |a| a.parse().expect("integer arguments"));
    let (kp, k, iterations) = (get(2, 350), get(3, 250), get(4, 5));
    let cache = spectral::BasisCache::new(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/exp-cache"));
    let load = |p: &str| {
        let Shape::Mesh(mesh) = Shape::load(p.as_ref()).unwrap() else { panic!("{p}: not a triangle mesh") };
        let start = Instant::now();
        let lap = laplacian::cotangent(&mesh).unwrap();
        let (basis, _) =
            spectral::eigen_basis_cached(&lap, &spectral::SpectralOptions::new(kp), Some(&cache), None).unwrap();
        println!(
            "{p}: {} vertices, basis of {kp} in {:.1} s (cached after the first run)",
            basis.n(),
            start.elapsed().as_secs_f64()
        );
        basis
    };
    let (bx, by) = (load(px), load(py));
    let (f, g) = (wks(&bx, 100, true).unwrap(), wks(&by, 100, true).unwrap());
    let problem = Problem::new(&bx, &by, &f, &g, kp, Scaling::Unit).unwrap();
    let c0 = ovsjanikov(&bx, &by, &f, &g, 50.min(k), &OvsjanikovOptions { commutativity: 1e-3 }).unwrap();
    let (a0, b0) = init_from_c(problem.c_from_bases(c0.as_ref()).as_ref(), kp, k).unwrap();
    let opts = OptimizeOptions { max_iterations: iterations, ..Default::default() };
    let params = CompletionParams::defaults_for(Scaling::Unit);
    let (_, _, report) = optimize(&problem, &params, &opts, a0.as_ref(), b0.as_ref()).unwrap();
    println!(
        "optimize (k' = {kp}, k = {k}, Unit defaults, 100 WKS, eq. (5) start): {} iterations, {} evaluations, {:.3} s per iteration, {:.3} s per evaluation, {} ",
        report.iterations,
        report.evaluations,
        report.seconds_per_iteration,
        report.seconds_total / report.evaluations as f64,
        report.stop_reason
    );
    println!("{}", serde_json::to_string(&report.terms).unwrap());
}

fn main() {
    let raw: Vec<String> = std::env::args().skip(1).collect();
    if raw.first().map(String::as_str) == Some("pair") {
        pair(&raw[1..]);
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
    let (mf, nf, kf, kpf) = (m as f64, n as f64, k as f64, kp as f64);
    let flops = 6.0 * mf * nf * kf;
    // What the kernel does: U = Ψ A, V = Φ B, then per block T = U Vᵀ and either Z = Ψᵀ S Φ
    // (k' < 2k) or S V and Sᵀ U, then the k' × k products.
    let actual = 2.0 * (mf + nf) * kpf * kf
        + if kp < 2 * k {
            2.0 * mf * nf * (kf + kpf) + 2.0 * mf * kpf * kpf + 4.0 * kpf * kpf * kf
        } else {
            6.0 * mf * nf * kf + 2.0 * (mf + nf) * kf * kpf
        };
    println!(
        "value+gradient: best {best:.4} s, mean {mean:.4} s; {:.1} GFLOP/s counted as 6·m·n·k = {:.2e} flops; {:.1} GFLOP/s of the {:.2e} flops done",
        flops / best / 1e9,
        flops,
        actual / best / 1e9,
        actual
    );
    let mut vtimes = Vec::new();
    for _ in 0..reps {
        let start = Instant::now();
        let v = terms::l1_value(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), xi, None, block);
        vtimes.push(start.elapsed().as_secs_f64());
        assert!((v - t.value).abs() <= 1e-12 * t.value);
    }
    let vbest = vtimes.iter().cloned().fold(f64::MAX, f64::min);
    let vflops = 2.0 * mf * nf * kf + 2.0 * (mf + nf) * kpf * kf;
    println!(
        "value only: best {vbest:.4} s, {:.1} GFLOP/s (2·m·n·k + 2·(m + n)·k'·k = {vflops:.2e} flops)",
        vflops / vbest / 1e9
    );
}

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
//! ```sh
//! cargo run --release --example completion_timing -- precision [m n k' k reps block]
//! ```
//! The L1 kernel with f64 and with f32 products (`Precision`), random bases: their differences
//! (value, gradient), their times run alternately (min of `reps` each), and the bare GEMMs of the
//! same shapes in f64 and f32 (the bound of each kernel).
//!
//! ```sh
//! cargo run --release --example completion_timing -- pair-precision X.off Y.off [k' k iterations]
//! ```
//! The same comparison on a pair of shapes (Unit defaults, weighted L1), at the eq. (5) start and
//! after `iterations` f64 iterations of the subspace optimizer.
//!
//! `pair` (below) runs the subspace optimizer (Unit defaults, 100 WKS, start from eq. (5)) on a pair of shapes
//! for a few iterations and prints the seconds per iteration and per evaluation.

use std::time::Instant;

use faer::Mat;
use funcorr::completion::{terms, Precision};

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

/// Relative differences of the f32 kernel's value and gradients from the f64 one's.
fn compare(f64_: &terms::TermValue, f32_: &terms::TermValue) -> (f64, f64, f64) {
    let ga = (&f32_.grad_a - &f64_.grad_a).norm_l2() / f64_.grad_a.norm_l2();
    let gb = (&f32_.grad_b - &f64_.grad_b).norm_l2() / f64_.grad_b.norm_l2();
    ((f32_.value - f64_.value).abs() / f64_.value.abs(), ga, gb)
}

/// The minimum over `reps` alternating runs of `f` and `g`.
fn alternate(reps: usize, mut f: impl FnMut(), mut g: impl FnMut()) -> (f64, f64) {
    let (mut bf, mut bg) = (f64::MAX, f64::MAX);
    for _ in 0..reps {
        let start = Instant::now();
        f();
        bf = bf.min(start.elapsed().as_secs_f64());
        let start = Instant::now();
        g();
        bg = bg.min(start.elapsed().as_secs_f64());
    }
    (bf, bg)
}

/// The GEMMs of the kernel's projected path alone, in the same four groups of row blocks:
/// T_r = U_r Vᵀ, S_r Φ, Ψ_rᵀ (S_r Φ) (no √ pass, no conversions, full-length sums).
fn bare_gemms<E: faer::traits::ComplexField + Copy>(
    u: faer::MatRef<E>,
    v: faer::MatRef<E>,
    psi: faer::MatRef<E>,
    phi: faer::MatRef<E>,
    block: usize,
    one: E,
) {
    use faer::linalg::matmul::matmul;
    use faer::{Accum, Par};
    use rayon::prelude::*;
    let (m, n) = (u.nrows(), v.nrows());
    let nblocks = m.div_ceil(block);
    (0..4usize).into_par_iter().for_each(|g| {
        let mut t = Mat::<E>::zeros(block, n);
        let mut sp = Mat::<E>::zeros(block, phi.ncols());
        let mut z = Mat::<E>::zeros(psi.ncols(), phi.ncols());
        for bi in g * nblocks / 4..(g + 1) * nblocks / 4 {
            let r0 = bi * block;
            let len = block.min(m - r0);
            let mut t = t.as_mut().subrows_mut(0, len);
            matmul(t.as_mut(), Accum::Replace, u.subrows(r0, len), v.transpose(), one, Par::Seq);
            let mut sp = sp.as_mut().subrows_mut(0, len);
            matmul(sp.as_mut(), Accum::Replace, t.as_ref(), phi, one, Par::Seq);
            matmul(z.as_mut(), Accum::Add, psi.subrows(r0, len).transpose(), sp.as_ref(), one, Par::Seq);
        }
        std::hint::black_box(&z);
    });
}

fn precision(args: &[usize]) {
    let get = |i: usize, d: usize| args.get(i).copied().unwrap_or(d);
    let (m, n, kp, k, reps, block) = (get(0, 5000), get(1, 5000), get(2, 350), get(3, 250), get(4, 5), get(5, 256));
    let phi = random(n, kp, 1, 0.02);
    let psi = random(m, kp, 2, 0.02);
    let a = random(kp, k, 3, 0.1);
    let b = random(kp, k, 4, 0.1);
    let xi = 1e-3;
    println!("m = {m}, n = {n}, k' = {kp}, k = {k}, block = {block}, threads = {}", rayon::current_num_threads());
    let run = |p: Precision| terms::l1(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), xi, None, block, p);
    let (r64, r32) = (run(Precision::F64), run(Precision::F32));
    let (ev, ea, eb) = compare(&r64, &r32);
    println!(
        "random bases, ξ = {xi}: value {:e}; f32 vs f64: value rel. {ev:.2e}, ∇_A rel. {ea:.2e}, ∇_B rel. {eb:.2e}",
        r64.value
    );
    let (t64, t32) = alternate(
        reps,
        || {
            std::hint::black_box(run(Precision::F64));
        },
        || {
            std::hint::black_box(run(Precision::F32));
        },
    );
    let flops = 2.0 * (m * n) as f64 * (k + kp) as f64 + 2.0 * (m * kp * kp) as f64;
    println!(
        "value+gradient (min of {reps}, alternating): f64 {t64:.4} s, f32 {t32:.4} s, ratio {:.2}; {:.2e} flops in the blocks",
        t64 / t32,
        flops
    );
    let u = &psi * &a;
    let v = &phi * &b;
    let f32m = |x: &Mat<f64>| Mat::<f32>::from_fn(x.nrows(), x.ncols(), |i, j| x[(i, j)] as f32);
    let (u32_, v32, psi32, phi32) = (f32m(&u), f32m(&v), f32m(&psi), f32m(&phi));
    let (g64, g32) = alternate(
        reps,
        || bare_gemms(u.as_ref(), v.as_ref(), psi.as_ref(), phi.as_ref(), block, 1.0f64),
        || bare_gemms(u32_.as_ref(), v32.as_ref(), psi32.as_ref(), phi32.as_ref(), block, 1.0f32),
    );
    println!(
        "bare GEMMs of the same shapes (same groups): f64 {g64:.4} s ({:.1} GFLOP/s), f32 {g32:.4} s ({:.1} GFLOP/s); kernel / bound: f64 {:.2}, f32 {:.2}",
        flops / g64 / 1e9,
        flops / g32 / 1e9,
        t64 / g64,
        t32 / g32
    );
    // One large GEMM, T = U Vᵀ (m × n × k), faer's parallel GEMM on all threads.
    use faer::linalg::matmul::matmul;
    let par = faer::Par::rayon(rayon::current_num_threads());
    let mut t64m = Mat::<f64>::zeros(m, n);
    let mut t32m = Mat::<f32>::zeros(m, n);
    let (l64, l32) = alternate(
        reps,
        || matmul(t64m.as_mut(), faer::Accum::Replace, u.as_ref(), v.transpose(), 1.0f64, par),
        || matmul(t32m.as_mut(), faer::Accum::Replace, u32_.as_ref(), v32.transpose(), 1.0f32, par),
    );
    let lf = 2.0 * (m * n * k) as f64;
    println!(
        "one GEMM m × k by k × n (Par::rayon): f64 {l64:.4} s ({:.1} GFLOP/s), f32 {l32:.4} s ({:.1} GFLOP/s)",
        lf / l64 / 1e9,
        lf / l32 / 1e9
    );
}

fn pair_precision(args: &[String]) {
    use funcorr::completion::{init_from_c, optimize, CompletionParams, OptimizeOptions, Problem, Scaling};
    use funcorr::fmap::{ovsjanikov, OvsjanikovOptions};
    use funcorr::shape::Shape;
    use funcorr::{descriptors::signatures::wks, laplacian, spectral};
    let (px, py) = (args[0].as_str(), args[1].as_str());
    let get = |i: usize, d: usize| args.get(i).map_or(d, |a| a.parse().expect("integer arguments"));
    let (kp, k, iterations) = (get(2, 350), get(3, 250), get(4, 20));
    let cache = spectral::BasisCache::new(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/exp-cache"));
    let load = |p: &str| {
        let Shape::Mesh(mesh) = Shape::load(p.as_ref()).unwrap() else { panic!("{p}: not a triangle mesh") };
        let lap = laplacian::cotangent(&mesh).unwrap();
        spectral::eigen_basis_cached(&lap, &spectral::SpectralOptions::new(kp), Some(&cache), None).unwrap().0
    };
    let (bx, by) = (load(px), load(py));
    let (f, g) = (wks(&bx, 100, true).unwrap(), wks(&by, 100, true).unwrap());
    let problem = Problem::new(&bx, &by, &f, &g, kp, Scaling::Unit).unwrap();
    let c0 = ovsjanikov(&bx, &by, &f, &g, 50.min(k), &OvsjanikovOptions { commutativity: 1e-3 }).unwrap();
    let (a0, b0) = init_from_c(problem.c_from_bases(c0.as_ref()).as_ref(), kp, k).unwrap();
    let params = CompletionParams::defaults_for(Scaling::Unit);
    let (phi, psi, weights) = problem.l1_operands();
    let report = |label: &str, a: faer::MatRef<f64>, b: faer::MatRef<f64>, timed: bool| {
        let run = |p: Precision| terms::l1(a, b, phi, psi, params.xi, weights, params.block_rows, p);
        let (r64, r32) = (run(Precision::F64), run(Precision::F32));
        let (ev, ea, eb) = compare(&r64, &r32);
        println!(
            "{px} → {py} ({} × {}, k' = {kp}, k = {k}, ξ = {}, weighted) {label}: L1 {:e}; f32 vs f64: value rel. {ev:.2e}, ∇_A rel. {ea:.2e}, ∇_B rel. {eb:.2e}",
            phi.nrows(),
            psi.nrows(),
            params.xi,
            r64.value
        );
        if !timed {
            return;
        }
        let (t64, t32) = alternate(
            5,
            || {
                std::hint::black_box(run(Precision::F64));
            },
            || {
                std::hint::black_box(run(Precision::F32));
            },
        );
        println!("  value+gradient (min of 5, alternating): f64 {t64:.4} s, f32 {t32:.4} s, ratio {:.2}", t64 / t32);
    };
    report("at the eq. (5) start", a0.as_ref(), b0.as_ref(), true);
    // The optimizer with either kernel from the same start.
    let opts = OptimizeOptions { max_iterations: iterations, ..Default::default() };
    let (a, b, r64) = optimize(&problem, &params, &opts, a0.as_ref(), b0.as_ref()).unwrap();
    report(&format!("after {iterations} f64 iterations"), a.as_ref(), b.as_ref(), false);
    let p32 = CompletionParams { l1_precision: Precision::F32, ..params.clone() };
    let (a32, b32, r32) = optimize(&problem, &p32, &opts, a0.as_ref(), b0.as_ref()).unwrap();
    // A reference for the sensitivity of the trajectory: f64 with another block size (the same
    // sums in another order, differences ~1e-16 per evaluation).
    let p128 = CompletionParams { block_rows: params.block_rows / 2, ..params.clone() };
    let (a128, b128, r128) = optimize(&problem, &p128, &opts, a0.as_ref(), b0.as_ref()).unwrap();
    let f64b = format!("f64, {}-row blocks", p128.block_rows);
    for (name, r) in [("f64", &r64), ("f32", &r32), (f64b.as_str(), &r128)] {
        println!(
            "  optimizer, L1 products in {name}: {} iterations, {} evaluations, {:.3} s per iteration, objective {:.9e}, {}",
            r.iterations, r.evaluations, r.seconds_per_iteration, r.terms.total, r.stop_reason
        );
    }
    let (h64, h32, h128) = (&r64.objective_history, &r32.objective_history, &r128.objective_history);
    let (mut worst, mut worst128) = (0.0f64, 0.0f64);
    let last = h64.len().min(h32.len()).min(h128.len());
    for i in 0..last {
        let (x, y, z) = (h64[i], h32[i], h128[i]);
        let (d, d128) = ((y - x).abs() / x.abs(), (z - x).abs() / x.abs());
        (worst, worst128) = (worst.max(d), worst128.max(d128));
        if i % 10 == 0 || i + 1 == last {
            println!(
                "  iteration {i}: objective f64 {x:.9e}, f32 {y:.9e} (rel. difference {d:.2e}), {f64b} {z:.9e} ({d128:.2e})"
            );
        }
    }
    let c64 = &a * b.transpose();
    let dc = |a: &Mat<f64>, b: &Mat<f64>| (a * b.transpose() - &c64).norm_l2() / c64.norm_l2();
    println!(
        "  largest relative difference from the f64 history: f32 {worst:.2e}, {f64b} {worst128:.2e}; final C = A Bᵀ relative difference: f32 {:.2e}, {f64b} {:.2e}",
        dc(&a32, &b32),
        dc(&a128, &b128)
    );
}

fn main() {
    let raw: Vec<String> = std::env::args().skip(1).collect();
    match raw.first().map(String::as_str) {
        Some("pair") => return pair(&raw[1..]),
        Some("pair-precision") => return pair_precision(&raw[1..]),
        Some("precision") => {
            return precision(&raw[1..].iter().map(|a| a.parse().expect("integer arguments")).collect::<Vec<_>>())
        }
        _ => {}
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
    let t = terms::l1(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), xi, None, block, Precision::F64);
    println!(
        "value {:e}, ‖∇_A‖ {:e}, ‖∇_B‖ {:e} (bit-identical for any thread count)",
        t.value,
        t.grad_a.norm_l2(),
        t.grad_b.norm_l2()
    );
    let mut times = Vec::new();
    for _ in 0..reps {
        let start = Instant::now();
        let r = terms::l1(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), xi, None, block, Precision::F64);
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
        let v = terms::l1_value(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), xi, None, block, Precision::F64);
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

//! `funcorr spectrum`: Laplacian eigenpairs of a shape.

use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use funcorr::io::npy::{write_npz, NpzArray};
use funcorr::laplacian::Laplacian;
use funcorr::shape::Shape;
use funcorr::spectral::SpectralOptions;
use funcorr::{spectral, Error, Result};

use crate::args::{CacheArgs, LaplacianArgs};
use crate::options::build_laplacian;
use crate::Stages;

#[derive(clap::Args)]
pub(crate) struct SpectrumArgs {
    /// Shape file (see `funcorr info --help` for formats).
    pub(crate) shape: PathBuf,
    /// Number of eigenpairs k (1 ≤ k < n; the paper uses up to k' = 350).
    #[arg(short)]
    pub(crate) k: usize,
    /// Output .npz file. Without it, the eigenvalues are printed to stdout, one per line.
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) lap: LaplacianArgs,
    /// Convergence tolerance on the relative residual ‖Wφ − λAφ‖_{A⁻¹} / λ_k of every pair.
    #[arg(long, default_value_t = 1e-8)]
    pub(crate) tol: f64,
    /// Lanczos block size (default: 4 for k ≤ 120, 8 for k ≤ 250 or fewer than 16,384 vertices,
    /// else 16).
    #[arg(long)]
    pub(crate) block_size: Option<usize>,
    /// Seed of the random start block.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    #[command(flatten)]
    pub(crate) cache: CacheArgs,
    /// Also write W (CSC arrays W_data, W_indices, W_indptr, W_shape) and the mass to this .npz,
    /// e.g. to compare with scipy.
    #[arg(long)]
    pub(crate) save_laplacian: Option<PathBuf>,
    /// No progress bar or timings on stderr.
    #[arg(short, long)]
    pub(crate) quiet: bool,
}

pub(crate) fn progress_bar(k: usize, quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(k as u64);
    pb.set_style(
        ProgressStyle::with_template("{spinner} eigenpairs converged {pos}/{len} [{bar:30}] {elapsed}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb
}

pub(crate) fn spectrum(args: &SpectrumArgs) -> Result<()> {
    let mut st = Stages { quiet: args.quiet, parts: vec![] };
    // Options first: a bad one fails before any work.
    let opts =
        SpectralOptions { tol: args.tol, block_size: args.block_size, seed: args.seed, ..SpectralOptions::new(args.k) };
    if args.block_size == Some(0) {
        return Err(Error::invalid("--block-size", "must be at least 1"));
    }
    opts.validate().map_err(spectral_flag)?;
    let shape = st.run("read", || Shape::load(&args.shape))?;
    let lap = st.run("laplacian", || build_laplacian(&shape, &args.shape, &args.lap))?;
    if let Some(p) = &args.save_laplacian {
        st.run("save laplacian", || save_laplacian(p, &lap))?;
    }
    let cache = args.cache.cache();
    let pb = progress_bar(args.k, args.quiet);
    let update = |done: usize, _k: usize| pb.set_position(done as u64);
    let t = Instant::now();
    let (basis, info) =
        spectral::eigen_basis_cached(&lap, &opts, cache.as_ref(), Some(&update)).map_err(spectral_flag)?;
    pb.finish_and_clear();
    match info {
        Some(i) => st.note(format!(
            "factor {:.3} s | eigensolve {:.3} s ({}, {} restarts, {} solves)",
            i.factor_seconds, i.iterate_seconds, i.method, i.restarts, i.operator_applications
        )),
        None => st.note(format!("cached basis {:.3} s", t.elapsed().as_secs_f64())),
    }
    match &args.output {
        Some(out) => st.run("write", || spectral::save_basis(out, &basis))?,
        None => {
            for l in &basis.eigenvalues {
                outln!("{l:.17e}");
            }
        }
    }
    st.note(format!(
        "n {} k {} λ_k {:.6e} max residual {:.2e}",
        basis.n(),
        basis.k(),
        basis.eigenvalues[basis.k() - 1],
        basis.residuals.iter().copied().fold(0.0, f64::max)
    ));
    st.finish();
    Ok(())
}

/// The eigensolver's parameters as the flags of `funcorr spectrum`.
fn spectral_flag(e: Error) -> Error {
    match e {
        Error::Invalid { what, msg } if what == "block_size" => Error::invalid("--block-size", msg),
        Error::Invalid { what, msg } if what == "tol" => Error::invalid("--tol", msg),
        Error::Invalid { what, msg } if what == "k" => Error::invalid("-k", msg),
        e => e,
    }
}

pub(crate) fn save_laplacian(path: &Path, lap: &Laplacian) -> Result<()> {
    let w = lap.w.as_ref();
    let n = lap.n();
    let as_i64 = |v: &[usize]| v.iter().map(|&x| x as i64).collect::<Vec<i64>>();
    write_npz(
        path,
        &[
            ("W_data", NpzArray::F64 { shape: vec![w.val().len()], data: w.val().to_vec() }),
            ("W_indices", NpzArray::I64 { shape: vec![w.val().len()], data: as_i64(w.symbolic().row_idx()) }),
            ("W_indptr", NpzArray::I64 { shape: vec![n + 1], data: as_i64(w.symbolic().col_ptr()) }),
            ("W_shape", NpzArray::I64 { shape: vec![2], data: vec![n as i64, n as i64] }),
            ("mass", NpzArray::F64 { shape: vec![n], data: lap.mass.clone() }),
        ],
    )
}

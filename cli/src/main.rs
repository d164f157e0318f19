//! The `funcorr` command-line tool: a thin layer over the library.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand};

use funcorr::{Error, Result};

use crate::descriptors::DescriptorArgs;
use crate::eval::EvalArgs;
use crate::match_cmd::MatchArgs;
use crate::regions::RegionArgs;
use crate::spectrum::SpectrumArgs;

/// Large arrays on transparent huge pages (`funcorr::alloc`): fewer page faults, same results.
#[global_allocator]
static ALLOC: funcorr::alloc::HugePageAlloc = funcorr::alloc::HugePageAlloc;

/// Dense shape correspondence with functional maps (Kovnatsky et al., CVPR 2015).
#[derive(Parser)]
#[command(name = "funcorr", version, about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print facts about a shape: vertices, faces, area, components, boundary loops,
    /// degenerate and duplicate faces, non-manifold and inconsistently oriented edges.
    Info {
        /// Shape file: OFF, OBJ, PLY, XYZ/CSV/TXT/PTS point list, or NPY (n×3 points, n×d features).
        shape: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Compute the first k Laplacian eigenpairs W φ = λ A φ and write them as .npz
    /// (arrays eigenvalues [k], eigenvectors [n×k], mass [n], residuals [k]).
    Spectrum(SpectrumArgs),
    /// Compute data functions F (n × q) on a shape and write them as .npy: landmark deltas,
    /// HKS, WKS, heat kernel maps, segment indicators, localized descriptors, or a given matrix.
    Descriptors(DescriptorArgs),
    /// Corresponding region indicators F (n × s) and G (m × s) for two shapes: segments from
    /// label files, persistence segments or ShapeMSER regions, matched by their signatures.
    /// Writes OUTDIR/F.npy, OUTDIR/G.npy and OUTDIR/matches.json.
    Regions(RegionArgs),
    /// Match X to Y: data functions on both shapes, a functional map, a point-to-point map.
    /// Writes OUTDIR/map.txt (for every vertex of X its vertex on Y), map.npy, map_yx.npy (for
    /// every vertex of Y a vertex of X), C.npy, report.json, X.ply and Y.ply (colour transfer),
    /// render.png and view.html (the interactive viewer: open it in a browser).
    Match(MatchArgs),
    /// Evaluate a point-to-point map X → Y against ground-truth template correspondences
    /// (.vts files) with the Princeton protocol: geodesic errors on Y / √area(Y).
    Eval(EvalArgs),
    /// Run methods on the pairs of a data set (the Princeton protocol: hard error (12), symmetric
    /// flips allowed) and write per-pair CSV/JSON, maps, a summary table and a plot of the
    /// cumulative error curves (one line per method).
    Bench(bench::BenchArgs),
    /// Reproduce the paper's experiments: `rank` (Figure 5), `l1` (Figure 6), `benchmark`
    /// (Figure 7); each writes its table, JSON and plot.
    Reproduce {
        #[command(subcommand)]
        what: bench::ReproduceWhat,
    },
    /// Write the interactive viewer page of a map (view.html: X and Y side by side in the
    /// browser, colour transfer, error heat map, click a vertex to see its image), from a match
    /// directory or from two shapes and a map.
    View(view::ViewArgs),
    /// Run the default pipeline on a pair of bundled FAUST shapes and write results to
    /// ./funcorr-demo/.
    Demo {
        /// Output directory.
        #[arg(long, default_value = "funcorr-demo")]
        out: PathBuf,
        /// Number of eigenpairs.
        #[arg(short, default_value_t = 100)]
        k: usize,
    },
}

/// `println!` that ends the program quietly when stdout is closed early (`funcorr … | head`),
/// as a well-behaved Unix filter does, instead of panicking.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write;
        if let Err(e) = writeln!(std::io::stdout().lock(), $($arg)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
            return Err(funcorr::Error::io("<stdout>", e));
        }
    }};
}

mod args;
mod bench;
mod demo;
mod descriptors;
mod eval;
mod info;
mod match_cmd;
mod options;
mod output;
mod regions;
mod spectrum;
mod view;

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Ctrl-C cancels the computation (funcorr::progress): it stops at its next check, outputs
    // staged so far are removed and nothing is published; a second Ctrl-C kills the process.
    if let Err(e) = funcorr::progress::interrupt_on_sigint() {
        eprintln!("funcorr: warning: Ctrl-C will kill the process without cleaning up: {e}");
    }
    let result = match cli.command {
        Command::Info { shape, json } => info::info(&shape, json),
        Command::Spectrum(args) => spectrum::spectrum(&args),
        Command::Descriptors(args) => descriptors::descriptors(&args),
        Command::Regions(args) => regions::regions(&args),
        Command::Match(args) => match_cmd::match_shapes(&args),
        Command::Eval(args) => eval::eval(&args),
        Command::View(args) => view::view(&args),
        Command::Demo { out, k } => demo::demo(&out, k),
        Command::Bench(args) => bench::bench(&args),
        Command::Reproduce { what } => bench::reproduce(&what),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Error::Cancelled { stage }) => {
            let during =
                if stage.is_empty() { String::new() } else { format!(" during {}", funcorr::error::escape(&stage)) };
            eprintln!("funcorr: interrupted (Ctrl-C){during}: stopped, no output written");
            // 128 + SIGINT, as a shell reports a process ended by Ctrl-C.
            ExitCode::from(130)
        }
        Err(e) => {
            let e = as_flag(e);
            eprintln!("funcorr: error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The library names its parameters (`data`, `view`, ...); on the command line they are flags.
fn as_flag(e: Error) -> Error {
    match e {
        Error::Invalid { what, msg } if ["data", "view", "dataset", "methods"].contains(&what.as_str()) => {
            Error::invalid(format!("--{what}"), msg)
        }
        e => e,
    }
}

/// Stage timer printing `stage: seconds` to stderr unless quiet.
struct Stages {
    quiet: bool,
    parts: Vec<String>,
}

impl Stages {
    fn run<T>(&mut self, name: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
        let t = Instant::now();
        let r = f()?;
        self.parts.push(format!("{name} {:.3} s", t.elapsed().as_secs_f64()));
        Ok(r)
    }
    fn note(&mut self, s: String) {
        self.parts.push(s);
    }
    fn finish(&self) {
        if !self.quiet {
            eprintln!("funcorr: {}", self.parts.join(" | "));
        }
    }
}

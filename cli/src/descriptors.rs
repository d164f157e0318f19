//! `funcorr descriptors`: HKS, WKS, heat kernel maps, segments and regions of a shape.

use std::path::{Path, PathBuf};

use clap::ValueEnum;

use funcorr::shape::Shape;
use funcorr::{Error, Result};

use crate::args::{CacheArgs, LaplacianArgs, SegmentationArgs};
use crate::options::{persistence_labels, shape_basis};
use crate::Stages;

#[derive(Clone, Copy, PartialEq, ValueEnum)]
pub(crate) enum DescriptorKind {
    /// Delta functions at landmark vertices (--landmarks, one column per pair).
    Landmarks,
    /// Heat kernel signature (Sun et al. 2009), --count log-spaced times.
    Hks,
    /// Wave kernel signature (Aubry et al. 2011), --count log-energies.
    Wks,
    /// Heat kernel maps (Ovsjanikov et al. 2010) from the --seeds vertices at --times times.
    Hkm,
    /// Indicator functions of the segments in --labels (one column per label).
    Segments,
    /// Indicators of the segments of a persistence-based segmentation (Skraba et al. 2010) of
    /// --function (default: HKS at t = --hks-time/λ₁) with persistence threshold --threshold.
    Persistence,
    /// Indicators of the maximally stable regions of the heat kernel diagonal (ShapeMSER,
    /// Litman et al. 2011); meshes only.
    Mser,
    /// WKS (and HKM when --seeds is given) multiplied by the indicators of the --labels segments
    /// (or, without --labels, of the persistence segments).
    Localized,
    /// A given n × q matrix (--matrix .npy or .csv), checked and passed through.
    Matrix,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum Side2 {
    /// First column of the landmark file (the source shape X).
    Source,
    /// Second column (the target shape Y).
    Target,
}

#[derive(clap::Args)]
pub(crate) struct DescriptorArgs {
    /// Shape file (see `funcorr info --help` for formats).
    pub(crate) shape: PathBuf,
    /// Which functions to compute.
    #[arg(long, value_enum)]
    pub(crate) kind: DescriptorKind,
    /// Output .npy file (n × q, f64).
    #[arg(short, long)]
    pub(crate) output: PathBuf,
    /// Also write the q column names, one per line, to this file.
    #[arg(long)]
    pub(crate) names: Option<PathBuf>,
    /// Number of HKS times or WKS energies.
    #[arg(long, default_value_t = 100)]
    pub(crate) count: usize,
    /// Keep the raw signatures (default: scale-normalized, area-weighted mean 1 per column).
    #[arg(long)]
    pub(crate) no_normalize: bool,
    /// Landmark pairs file: two vertex indices per line, `i j` (X vertex, Y vertex).
    #[arg(long)]
    pub(crate) landmarks: Option<PathBuf>,
    /// Which column of the landmark file belongs to this shape.
    #[arg(long, value_enum, default_value = "source")]
    pub(crate) side: Side2,
    /// Vertex indices in --landmarks / --seeds files are 1-based (MATLAB).
    #[arg(long)]
    pub(crate) one_based: bool,
    /// Seed vertices of heat kernel maps: one vertex index per line.
    #[arg(long)]
    pub(crate) seeds: Option<PathBuf>,
    /// Number of heat kernel map times (log-spaced over the HKS range).
    #[arg(long, default_value_t = 5)]
    pub(crate) times: usize,
    /// Per-vertex segment labels: one integer per line, one line per vertex.
    #[arg(long)]
    pub(crate) labels: Option<PathBuf>,
    /// Data matrix (.npy or .csv), n rows.
    #[arg(long)]
    pub(crate) matrix: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) seg: SegmentationArgs,
    /// Also write the per-vertex segment labels (1-based, one per line) of --kind persistence.
    #[arg(long)]
    pub(crate) write_labels: Option<PathBuf>,
    /// Number of eigenpairs of the basis the signatures are computed from.
    #[arg(short, default_value_t = 100)]
    pub(crate) k: usize,
    /// Use this basis file (from `funcorr spectrum`) instead of computing one.
    #[arg(long)]
    pub(crate) basis: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) lap: LaplacianArgs,
    #[command(flatten)]
    pub(crate) cache: CacheArgs,
    /// No progress bar or timings on stderr.
    #[arg(short, long)]
    pub(crate) quiet: bool,
}

/// `flag` must be given for this descriptor kind.
pub(crate) fn need<'a>(v: &'a Option<PathBuf>, flag: &str, kind: &str) -> Result<&'a PathBuf> {
    v.as_ref().ok_or_else(|| Error::invalid(flag, format!("--kind {kind} needs {flag} FILE")))
}

pub(crate) fn descriptors(args: &DescriptorArgs) -> Result<()> {
    use funcorr::descriptors::{self as desc, signatures};
    use funcorr::io::indices;
    let mut st = Stages { quiet: args.quiet, parts: vec![] };
    // The counts of the kinds that use them, before any work.
    let uses_count = matches!(args.kind, DescriptorKind::Hks | DescriptorKind::Wks | DescriptorKind::Localized);
    let uses_times = matches!(args.kind, DescriptorKind::Hkm)
        || (matches!(args.kind, DescriptorKind::Localized) && args.seeds.is_some());
    for (flag, v, used) in [("--count", args.count, uses_count), ("--times", args.times, uses_times)] {
        if used && !(1..=signatures::MAX_COUNT).contains(&v) {
            return Err(Error::invalid(flag, format!("need 1 ≤ {flag} ≤ {}, got {v}", signatures::MAX_COUNT)));
        }
    }
    let shape = st.run("read", || Shape::load(&args.shape))?;
    let n = shape.n_vertices();
    let normalize = !args.no_normalize;
    let needs_basis =
        !matches!(args.kind, DescriptorKind::Landmarks | DescriptorKind::Segments | DescriptorKind::Matrix);
    let lb = if needs_basis {
        Some(shape_basis(&shape, &args.shape, &args.lap, &args.cache, args.k, args.basis.as_deref(), &mut st)?)
    } else {
        None
    };
    let basis = lb.as_ref().map(|(_, b)| b);
    let seeds = |path: &Path| indices::read_index_list_file(path, args.one_based, n);
    let mut computed_labels = None;
    let d = st.run("descriptors", || {
        let b = || basis.expect("basis computed for this kind");
        let lap = || &lb.as_ref().expect("Laplacian computed for this kind").0;
        match args.kind {
            DescriptorKind::Landmarks => {
                let p = need(&args.landmarks, "--landmarks", "landmarks")?;
                // Only the chosen side refers to this shape; the other is checked by its own run.
                let (nx, ny) = if matches!(args.side, Side2::Source) { (n, usize::MAX) } else { (usize::MAX, n) };
                let pairs = indices::read_index_pairs_file(p, args.one_based, nx, ny)?;
                let v: Vec<usize> =
                    pairs.iter().map(|&(i, j)| if matches!(args.side, Side2::Source) { i } else { j }).collect();
                desc::landmarks(n, &v).map_err(|e| Error::parse(p, None, e.to_string()))
            }
            DescriptorKind::Hks => signatures::hks(b(), &signatures::hks_times(b(), args.count)?, normalize),
            DescriptorKind::Wks => signatures::wks(b(), args.count, normalize),
            DescriptorKind::Hkm => {
                let s = seeds(need(&args.seeds, "--seeds", "hkm")?)?;
                signatures::hkm(b(), &s, &signatures::hks_times(b(), args.times)?, normalize)
            }
            DescriptorKind::Segments => {
                desc::segments(&indices::read_labels_file(need(&args.labels, "--labels", "segments")?, n)?)
            }
            DescriptorKind::Persistence => {
                let labels = persistence_labels(&shape, lap(), b(), &args.seg)?;
                let d = desc::segments(&labels);
                computed_labels = Some(labels);
                d
            }
            DescriptorKind::Mser => match &shape {
                Shape::Mesh(m) => Ok(desc::mser::shape_mser(m, b(), &desc::mser::MserOptions::default())?.1),
                Shape::Points(_) => Err(Error::invalid("--kind", "mser needs a triangle mesh; this file has no faces")),
            },
            DescriptorKind::Localized => {
                let labels = match &args.labels {
                    Some(p) => indices::read_labels_file(p, n)?,
                    None => persistence_labels(&shape, lap(), b(), &args.seg)?,
                };
                let segs = desc::segments(&labels)?;
                let mut base = signatures::wks(b(), args.count, normalize)?;
                if let Some(p) = &args.seeds {
                    base = base.concat(&signatures::hkm(
                        b(),
                        &seeds(p)?,
                        &signatures::hks_times(b(), args.times)?,
                        normalize,
                    )?)?;
                }
                desc::localized(&base, &segs)
            }
            DescriptorKind::Matrix => {
                let p = need(&args.matrix, "--matrix", "matrix")?;
                desc::Descriptors::from_matrix(&funcorr::io::read_matrix(p)?, n).map_err(|e| match e {
                    Error::Invalid { what, msg } => Error::parse(p, None, format!("invalid {what}: {msg}")),
                    e => e,
                })
            }
        }
    })?;
    st.run("write", || {
        // All outputs appear together or none does (io::staged).
        let mut staged = funcorr::io::staged::StagedFiles::new();
        staged.write_with(&args.output, |p| funcorr::io::npy::write_npy_matrix(p, &d.to_dense()))?;
        if let Some(p) = &args.names {
            staged.write_with(p, |p| funcorr::io::write_atomic(p, d.names.join("\n") + "\n"))?;
        }
        if let (Some(p), Some(labels)) = (&args.write_labels, &computed_labels) {
            let text: String = labels.iter().map(|l| format!("{l}\n")).collect();
            staged.write_with(p, |p| funcorr::io::write_atomic(p, text))?;
        }
        staged.publish()
    })?;
    st.note(format!("n {} q {}", d.n(), d.q()));
    st.finish();
    Ok(())
}

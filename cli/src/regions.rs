//! `funcorr regions`: matched regions (persistence segments or MSER) of two shapes.

use std::path::PathBuf;

use clap::ValueEnum;

use funcorr::shape::Shape;
use funcorr::{Error, Result};

use crate::args::{CacheArgs, LaplacianArgs, SegmentationArgs};
use crate::descriptors::need;
use crate::options::{persistence_labels, shape_basis};
use crate::Stages;

#[derive(Clone, Copy, PartialEq, ValueEnum)]
pub(crate) enum RegionKind {
    /// Segments given by --labels-x and --labels-y (e.g. the data set's segmentations).
    Labels,
    /// Persistence-based segments of both shapes.
    Persistence,
    /// ShapeMSER regions of both shapes (meshes only).
    Mser,
}

#[derive(clap::Args)]
pub(crate) struct RegionArgs {
    /// Source shape X.
    pub(crate) x: PathBuf,
    /// Target shape Y.
    pub(crate) y: PathBuf,
    /// Where the regions come from.
    #[arg(long, value_enum, default_value = "persistence")]
    pub(crate) kind: RegionKind,
    /// Per-vertex labels of X (--kind labels).
    #[arg(long)]
    pub(crate) labels_x: Option<PathBuf>,
    /// Per-vertex labels of Y (--kind labels).
    #[arg(long)]
    pub(crate) labels_y: Option<PathBuf>,
    /// Output directory.
    #[arg(short, long)]
    pub(crate) output: PathBuf,
    /// Number of eigenpairs of the bases the signatures are computed from.
    #[arg(short, default_value_t = 100)]
    pub(crate) k: usize,
    #[command(flatten)]
    pub(crate) seg: SegmentationArgs,
    #[command(flatten)]
    pub(crate) lap: LaplacianArgs,
    #[command(flatten)]
    pub(crate) cache: CacheArgs,
    /// No timings on stderr.
    #[arg(short, long)]
    pub(crate) quiet: bool,
}

pub(crate) fn regions(args: &RegionArgs) -> Result<()> {
    use funcorr::descriptors::{mser, persistence as pers};
    let mut st = Stages { quiet: args.quiet, parts: vec![] };
    // Checked writable before any work (published at the end, removed on failure).
    let staged = funcorr::io::staged::StagedDir::create(&args.output)?;
    let x = st.run("read", || Shape::load(&args.x))?;
    let y = st.run("read", || Shape::load(&args.y))?;
    let (lx, bx) = shape_basis(&x, &args.x, &args.lap, &args.cache, args.k, None, &mut st)?;
    let (ly, by) = shape_basis(&y, &args.y, &args.lap, &args.cache, args.k, None, &mut st)?;
    let (f, g, matches) = st.run("regions", || match args.kind {
        RegionKind::Labels => {
            let read = |p: &Option<PathBuf>, flag: &str, n| {
                funcorr::io::indices::read_labels_file(need(p, flag, "labels")?, n)
            };
            let (a, b) = (
                read(&args.labels_x, "--labels-x", x.n_vertices())?,
                read(&args.labels_y, "--labels-y", y.n_vertices())?,
            );
            pers::matched_segment_indicators(&a, &bx, &b, &by)
        }
        RegionKind::Persistence => {
            let a = persistence_labels(&x, &lx, &bx, &args.seg)?;
            let b = persistence_labels(&y, &ly, &by, &args.seg)?;
            pers::matched_segment_indicators(&a, &bx, &b, &by)
        }
        RegionKind::Mser => match (&x, &y) {
            (Shape::Mesh(mx), Shape::Mesh(my)) => {
                mser::matched_mser_indicators((mx, &bx), (my, &by), &mser::MserOptions::default())
            }
            _ => Err(Error::invalid("--kind", "mser needs two triangle meshes")),
        },
    })?;
    st.run("write", || {
        staged.write_with(|out| {
            funcorr::io::npy::write_npy_matrix(&out.join("F.npy"), &f.to_dense())?;
            funcorr::io::npy::write_npy_matrix(&out.join("G.npy"), &g.to_dense())?;
            let list: Vec<serde_json::Value> = (0..f.q())
                .map(|j| serde_json::json!({"x": f.names[j], "y": g.names[j], "cost": matches.get(j).map(|m| m.cost)}))
                .collect();
            let path = out.join("matches.json");
            let text = serde_json::to_string_pretty(&serde_json::json!({ "pairs": list })).expect("plain JSON");
            funcorr::io::write_atomic(&path, text)
        })
    })?;
    st.note(format!("{} matched regions", f.q()));
    st.finish();
    Ok(())
}

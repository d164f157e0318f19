//! `funcorr eval`: geodesic error of a map against ground truth.

use std::path::{Path, PathBuf};

use funcorr::shape::Shape;
use funcorr::{Error, Result};

use crate::args::GeodesicsChoice;

#[derive(clap::Args)]
pub(crate) struct EvalArgs {
    /// Source shape X.
    #[arg(long)]
    pub(crate) source: PathBuf,
    /// Target shape Y (a triangle mesh).
    #[arg(long)]
    pub(crate) target: PathBuf,
    /// The map: one vertex id of Y per line for every vertex of X (map.txt of `funcorr match`).
    #[arg(long)]
    pub(crate) map: PathBuf,
    /// The map file is 1-based.
    #[arg(long)]
    pub(crate) one_based: bool,
    /// Template points on X (1-based .vts).
    #[arg(long)]
    pub(crate) gt_source: PathBuf,
    /// Corresponding template points on Y (1-based .vts).
    #[arg(long)]
    pub(crate) gt_target: PathBuf,
    /// Left–right mirrored template points on Y (1-based .sym.vts): allow symmetric flips.
    #[arg(long)]
    pub(crate) gt_target_sym: Option<PathBuf>,
    /// Geodesic distances on Y.
    #[arg(long, value_enum, default_value_t = GeodesicsChoice::Exact)]
    pub(crate) geodesics: GeodesicsChoice,
    /// Print JSON (summary, cumulative curve, per-point errors) instead of text.
    #[arg(long)]
    pub(crate) json: bool,
}

pub(crate) fn eval(args: &EvalArgs) -> Result<()> {
    let x = Shape::load(&args.source)?;
    let target = Shape::load(&args.target)?;
    let method = funcorr::geodesic::GeodesicMethod::from(args.geodesics);
    let surface = target_surface(&target, &args.target, method)?;
    let (n, m) = (x.n_vertices(), target.n_vertices());
    let map = read_index_list_file(&args.map, args.one_based, m)?;
    if map.len() != n {
        return Err(Error::parse(
            &args.map,
            None,
            format!("expected {n} lines (one per vertex of X), found {}", map.len()),
        ));
    }
    let gt = read_ground_truth(&args.gt_source, &args.gt_target, args.gt_target_sym.as_deref(), n, m)?;
    let (geo, area, description) = target_distances(&target, surface.as_ref(), method)?;
    let ev = funcorr::eval::Evaluation::of_map(&map, &gt, &*geo, area, description)?;
    let s = ev.summary;
    if args.json {
        outln!("{}", funcorr::io::to_json_sorted(&ev)?);
    } else {
        outln!("points            {}", ev.errors.len());
        outln!("symmetric flips   {}", if gt.y_sym.is_some() { "allowed" } else { "not allowed" });
        outln!("mean error ×100   {:.3}", 100.0 * s.mean);
        outln!("≤ 0.05            {:.1}%", 100.0 * s.at_005);
        outln!("≤ 0.10            {:.1}%", 100.0 * s.at_010);
        outln!("≤ 0.25            {:.1}%", 100.0 * s.at_025);
        outln!("geodesics         {}", description);
    }
    Ok(())
}

use funcorr::io::indices::read_index_list_file;

/// The surface of a point-cloud target for its geodesics (its local triangulation,
/// `funcorr::cloud`); None for a mesh. Errors name `--target` when the target (`path`) is
/// neither a mesh nor 3-D points.
pub(crate) fn target_surface(
    target: &Shape,
    path: &Path,
    method: funcorr::geodesic::GeodesicMethod,
) -> Result<Option<funcorr::cloud::CloudSurface>> {
    // A point-cloud target: geodesics along the edges of its local triangulation, area of its
    // surface (funcorr::cloud); a mesh: the chosen geodesics.
    match target {
        Shape::Mesh(_) => Ok(None),
        Shape::Points(p) if p.dim() == 3 && p.len() > 3 => {
            let pts: Vec<[f64; 3]> = (0..p.len()).map(|i| [p.point(i)[0], p.point(i)[1], p.point(i)[2]]).collect();
            let k = funcorr::cloud::DEFAULT_NEIGHBOURS.min(p.len() - 1);
            let surface = funcorr::cloud::cloud_surface(&pts, k)
                .map_err(|e| Error::invalid("--target", format!("{}: {e}", path.display())))?;
            if method != funcorr::geodesic::GeodesicMethod::Dijkstra {
                eprintln!(
                    "note: {} is a point cloud: geodesics along the edges of its local triangulation",
                    path.display()
                );
            }
            Ok(Some(surface))
        }
        Shape::Points(_) => Err(Error::invalid(
            "--target",
            format!("{}: geodesic evaluation needs a triangle mesh or 3-D points", path.display()),
        )),
    }
}

/// Distances on the target (the chosen geodesics on a mesh, Dijkstra on the local triangulation
/// `surface` of a point cloud), its area and a description of the distances.
pub(crate) type TargetDistances<'a> = (Box<dyn funcorr::eval::Distances + Send + Sync + 'a>, f64, &'static str);

/// See [`TargetDistances`]; `surface` is [`target_surface`] of `target`.
pub(crate) fn target_distances<'a>(
    target: &'a Shape,
    surface: Option<&funcorr::cloud::CloudSurface>,
    method: funcorr::geodesic::GeodesicMethod,
) -> Result<TargetDistances<'a>> {
    match (target, surface) {
        (Shape::Mesh(y), _) => Ok((method.build(y)?, y.total_area(), method.description())),
        (_, Some(s)) => {
            Ok((Box::new(s.geodesics()?), s.area(), "Dijkstra on the edges of the point cloud's local triangulation"))
        }
        _ => Err(Error::invalid("--target", "geodesic evaluation needs a triangle mesh or 3-D points")),
    }
}

/// Ground truth from 1-based `.vts` files: template points on X (n vertices), their
/// counterparts on Y (m vertices) and, optionally, the mirrored ones. Template lists correspond
/// line by line: a length mismatch names both files.
pub(crate) fn read_ground_truth(
    source: &Path,
    target: &Path,
    target_sym: Option<&Path>,
    n: usize,
    m: usize,
) -> Result<funcorr::eval::GroundTruth> {
    use funcorr::io::indices::read_template_list_file;
    let (tx, ty) = (read_template_list_file(source, n)?, read_template_list_file(target, m)?);
    let ts = target_sym.map(|p| read_template_list_file(p, m)).transpose()?;
    let others = [(Some(target), Some(ty.len())), (target_sym, ts.as_ref().map(Vec::len))];
    for (path, len) in others {
        if let (Some(path), Some(len)) = (path, len) {
            if len != tx.len() {
                return Err(Error::parse(
                    path,
                    None,
                    format!(
                        "{len} template points, but {} has {} (the files must correspond line by line)",
                        source.display(),
                        tx.len()
                    ),
                ));
            }
        }
    }
    // Template points a part lacks (0 in its .vts) are left out.
    let gt = funcorr::eval::GroundTruth::from_templates(&tx, &ty, ts.as_deref())?;
    Ok(gt)
}

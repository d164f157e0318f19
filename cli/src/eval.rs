//! `funcorr eval`: geodesic error of a map against ground truth.

#[allow(unused_imports)]
use super::*;

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
    use funcorr::eval::GroundTruth;
    use funcorr::io::indices::read_index_list_file;
    let x = Shape::load(&args.source)?;
    let target = Shape::load(&args.target)?;
    let method = funcorr::geodesic::GeodesicMethod::from(args.geodesics);
    // A point-cloud target: geodesics along the edges of its local triangulation, area of its
    // surface (funcorr::cloud); a mesh: the chosen geodesics.
    let cloud = match &target {
        Shape::Mesh(_) => None,
        Shape::Points(p) if p.dim() == 3 && p.len() > 3 => {
            let pts: Vec<[f64; 3]> = (0..p.len()).map(|i| [p.point(i)[0], p.point(i)[1], p.point(i)[2]]).collect();
            let k = funcorr::cloud::DEFAULT_NEIGHBOURS.min(p.len() - 1);
            let surface = funcorr::cloud::cloud_surface(&pts, k)
                .map_err(|e| Error::invalid("--target", format!("{}: {e}", args.target.display())))?;
            if method != funcorr::geodesic::GeodesicMethod::Dijkstra {
                eprintln!(
                    "note: {} is a point cloud: geodesics along the edges of its local triangulation",
                    args.target.display()
                );
            }
            Some(surface)
        }
        Shape::Points(_) => {
            return Err(Error::invalid(
                "--target",
                format!("{}: geodesic evaluation needs a triangle mesh or 3-D points", args.target.display()),
            ))
        }
    };
    let (n, m) = (x.n_vertices(), target.n_vertices());
    let map = read_index_list_file(&args.map, args.one_based, m)?;
    if map.len() != n {
        return Err(Error::parse(
            &args.map,
            None,
            format!("expected {n} lines (one per vertex of X), found {}", map.len()),
        ));
    }
    let gt = GroundTruth {
        x: read_index_list_file(&args.gt_source, true, n)?,
        y: read_index_list_file(&args.gt_target, true, m)?,
        y_sym: args.gt_target_sym.as_ref().map(|p| read_index_list_file(p, true, m)).transpose()?,
    };
    // Template lists correspond line by line: a length mismatch names both files.
    let others =
        [(Some(&args.gt_target), Some(gt.y.len())), (args.gt_target_sym.as_ref(), gt.y_sym.as_ref().map(Vec::len))];
    for (path, len) in others {
        if let (Some(path), Some(len)) = (path, len) {
            if len != gt.x.len() {
                return Err(Error::parse(
                    path,
                    None,
                    format!(
                        "{len} template points, but {} has {} (the files must correspond line by line)",
                        args.gt_source.display(),
                        gt.x.len()
                    ),
                ));
            }
        }
    }
    let (geo, area, description): (Box<dyn funcorr::eval::Distances + Send + Sync + '_>, f64, &str) =
        match (&target, &cloud) {
            (Shape::Mesh(y), _) => (method.build(y)?, y.total_area(), method.description()),
            (_, Some(s)) => {
                (Box::new(s.geodesics()?), s.area(), "Dijkstra on the edges of the point cloud's local triangulation")
            }
            _ => unreachable!("point sets without a surface were rejected above"),
        };
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

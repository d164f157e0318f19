//! The partial path's last step: once the map of a part X has found its basin and its coverage
//! of Y, the region of Y it covers is a shape of its own, about isometric to X, boundary
//! included. The two are then matched as whole shapes are: the whole pipeline's refinement
//! (ZoomOut to `refine.k_final`, then its bijective polish; [`super::axiomatic`]) between X and
//! the covered region Y', started from the partial map, then the metric polish
//! ([`crate::refine::metric_polish`]) with the region's own distances, and the result read back
//! on Y.
//!
//! **Why.** The partial refinement reads its maps with Y's eigenfunctions, which do not see the
//! cut: the restrictions of Y's first functions to the covered region are smooth across the
//! edge where X's Neumann functions turn, so the rectangular maps C_yx hold the basin but leave
//! the map slid by a few edges everywhere (tr_reg_000_cut → 004: 4.30 as a part, the error
//! spread over all of X, not at the cut; 1.14 for the same bodies whole). Y' has a boundary
//! where X has its cut, so its own eigenfunctions turn where X's do and the whole pipeline's
//! square maps and bijective polish apply (that pair: 3.09). The region's distances are the
//! part's (no geodesic of Y' runs around the cut through what X lacks), which the metric polish
//! on Y has to trim. On faust_r_partial the pairs below 10 went from 4.10 to 3.27, on
//! tosca_r_partial from 4.83 to 4.37 (EXPERIMENTS.md); about 1 s on a 2k → 5k pair.
//!
//! Y' is the set of vertices the coverage ([`super::partial::coverage`]) gives a confidence of
//! at least ½, with every image of X: for a mesh the faces of those vertices, its largest
//! connected component (a spectral basis of several components has several constant functions);
//! for a point cloud the points. Images of X outside Y' go to the nearest vertex of Y' in space.
//! The region is only as good as the basin and the area ratio: a map in a wrong basin stays
//! there, and a ratio too small squeezes X into too small a region (tr_reg_001_cut → 021, ratio
//! 0.66 for 0.79: 3.21 → 4.42).

use faer::Mat;

use super::axiomatic::{near_positions, refine_from, samples_of, AxiomaticPipeline};
use crate::error::{Error, Result};
use crate::fmap::Pullback;
use crate::geodesic::GraphGeodesics;
use crate::prepared::{LaplacianChoice, PreparedShape};
use crate::shape::{PointSet, Shape};
use crate::spatial::Samples;

/// Fewest vertices of a covered region that is refined on: with fewer, a basis of the pipeline's
/// size (`refine.k_final` and more) is not a smooth one (and the step is skipped).
pub const MIN_REGION_VERTICES: usize = 400;

/// A covered region Y' of Y.
pub struct CoveredRegion {
    /// Y' with its Laplacian and basis (input units as loaded, at unit area as all prepared
    /// shapes).
    pub shape: PreparedShape,
    /// For every vertex of Y', its id in Y (#Y', increasing).
    pub vertices: Vec<usize>,
}

/// The covered region Y' of Y (module docs) from the confidence `coverage` (length m) and the
/// images `map_xy` (length n, ids of Y), with a basis of `k` eigenpairs (fewer when Y' has at
/// most k vertices). None when it has fewer than [`MIN_REGION_VERTICES`] vertices or Y is
/// neither a mesh nor a 3-D point cloud. Errors: sizes that do not match, an image out of
/// range, those of the Laplacian and eigensolver.
pub fn covered_region(
    y: &PreparedShape,
    coverage: &[f64],
    map_xy: &[usize],
    k: usize,
) -> Result<Option<CoveredRegion>> {
    let m = y.n();
    if coverage.len() != m {
        return Err(Error::invalid("coverage", format!("{} values for {m} vertices of Y", coverage.len())));
    }
    let mut keep: Vec<bool> = coverage.iter().map(|&c| c >= 0.5).collect();
    for &j in map_xy {
        *keep.get_mut(j).ok_or_else(|| Error::invalid("map_xy", format!("image {j} out of range (m = {m})")))? = true;
    }
    let (shape, vertices) = match &y.shape {
        Shape::Mesh(mesh) => {
            let Some((sub, ids)) = mesh.submesh(&keep)? else { return Ok(None) };
            let (count, labels) = sub.components();
            let (sub, ids) = if count > 1 {
                let mut size = vec![0usize; count];
                labels.iter().for_each(|&l| size[l as usize] += 1);
                let largest = (0..count).max_by_key(|&c| (size[c], std::cmp::Reverse(c))).unwrap_or(0) as u32;
                let inner: Vec<bool> = labels.iter().map(|&l| l == largest).collect();
                let Some((sub2, ids2)) = sub.submesh(&inner)? else { return Ok(None) };
                let ids = ids2.iter().map(|&i| ids[i]).collect();
                (sub2, ids)
            } else {
                (sub, ids)
            };
            (Shape::Mesh(sub), ids)
        }
        Shape::Points(p) if p.dim() == 3 => {
            let ids: Vec<usize> = (0..m).filter(|&j| keep[j]).collect();
            let coords = ids.iter().flat_map(|&j| p.point(j).iter().copied()).collect();
            (Shape::Points(PointSet::new(ids.len(), 3, coords)?), ids)
        }
        Shape::Points(_) => return Ok(None),
    };
    if vertices.len() < MIN_REGION_VERTICES {
        return Ok(None);
    }
    let k = k.min(vertices.len() - 1);
    let shape = PreparedShape::new(shape, LaplacianChoice::Auto, k, None)?;
    Ok(Some(CoveredRegion { shape, vertices }))
}

/// The images `map_xy` (ids of Y) as ids of the region: an image outside it goes to the region's
/// vertex nearest to it in space (Y's positions, any units).
fn into_region(y: &PreparedShape, region: &CoveredRegion, map_xy: &[usize]) -> Result<Vec<usize>> {
    let mut id = vec![usize::MAX; y.n()];
    region.vertices.iter().enumerate().for_each(|(i, &v)| id[v] = i);
    let outside: Vec<usize> = map_xy.iter().copied().filter(|&j| id[j] == usize::MAX).collect();
    let mut snapped = std::collections::HashMap::new();
    if !outside.is_empty() {
        let p = y.positions().ok_or_else(|| Error::invalid("shapes", "Y has no positions"))?;
        let reference = Mat::from_fn(region.vertices.len(), 3, |i, d| p[region.vertices[i]][d]);
        let query = Mat::from_fn(outside.len(), 3, |i, d| p[outside[i]][d]);
        let near = crate::pointwise::nearest_neighbors(reference.as_ref(), query.as_ref())?;
        snapped.extend(outside.iter().copied().zip(near));
    }
    Ok(map_xy.iter().map(|&j| if id[j] == usize::MAX { snapped[&j] } else { id[j] }).collect())
}

/// What [`refine_on_covered_region`] did (reported in `report.json` by the partial path).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CoveredRefinement {
    /// The refined map X → Y (length n, vertex ids of Y; the partial path moves it out into
    /// its result, as it does the metric polish's).
    #[serde(skip)]
    pub map_xy: Vec<usize>,
    /// Vertices of the covered region Y' it was refined on.
    pub region_vertices: usize,
    /// Vertices of X whose image it changed.
    pub moved: usize,
    /// The metric polish on the region, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metric_polish: Option<crate::refine::MetricPolished>,
    /// Seconds per stage (covered region, its ZoomOut and polish, its metric polish; moved into
    /// the partial path's stages).
    #[serde(skip)]
    pub stages: Vec<(String, f64)>,
}

/// The map X → Y refined on the covered region (module docs): `map_xy` (n ids of Y) with its
/// coverage (m confidences) in, the refined map out, or None when the region is too small to
/// refine on. The refinement starts from the pull-back of `map_xy` (every vertex of X) at k =
/// the least of the pipeline's candidate sizes, so that ZoomOut rebuilds the map from its
/// smooth part, and runs as the whole pipeline's final refinement with the options `p` (no
/// landmarks); then, with `metric_anchors` > 0, the metric polish
/// ([`crate::refine::metric_polish`]) to that many farthest-point anchors of X, with the
/// distances of X and of the region (a geodesic of the part is one of the region, none runs
/// outside it) and the refinement's spectral reading. X needs a surface (a mesh or a 3-D point
/// cloud) for the polish. Errors: those of [`covered_region`], the refinement and the polish.
pub fn refine_on_covered_region(
    x: &PreparedShape,
    y: &PreparedShape,
    map_xy: &[usize],
    coverage: &[f64],
    p: &AxiomaticPipeline,
    metric_anchors: usize,
) -> Result<Option<CoveredRefinement>> {
    let t = std::time::Instant::now();
    crate::progress::stage("covered region")?;
    if map_xy.len() != x.n() {
        return Err(Error::invalid("map_xy", format!("{} images for {} vertices of X", map_xy.len(), x.n())));
    }
    let Some(region) = covered_region(y, coverage, map_xy, p.basis_size())? else { return Ok(None) };
    let k_final = p.refine.k_final.min(region.shape.basis.k()).min(x.basis.k());
    let k0 = p.candidates.iter().copied().min().unwrap_or(20).clamp(1, k_final.max(1));
    let start = into_region(y, &region, map_xy)?;
    let (phi, psi) = (x.basis.eigenvectors.as_ref(), region.shape.basis.eigenvectors.as_ref());
    let c0 = crate::refine::pullback(phi, psi, &Samples::all(&x.basis.mass), &start, k0, k0)?;
    let mut stages = vec![("covered region".to_string(), t.elapsed().as_secs_f64())];
    let mut q = p.clone();
    q.refine.k_final = k_final;
    q.landmarks = Default::default();
    let mut refine_stages = Vec::new();
    // Large pairs: the whole pipeline's searches near the samples' map.
    let near = near_positions(x, &region.shape, &q);
    let (c, map, _) =
        refine_from(x, &region.shape, Pullback(c0.clone()), &Pullback(c0), &q, &near, (&[], None), &mut refine_stages)?;
    stages.extend(refine_stages.into_iter().map(|(s, t)| (format!("covered {s}"), t)));
    let (map, metric_polish) = match (metric_anchors, x.triangles(), region.shape.triangles()) {
        (a, Some(tx), Some(tr)) if a > 0 => {
            let t = std::time::Instant::now();
            crate::progress::stage("covered metric polish")?;
            let anchors = samples_of(x, a.max(3))?.vertices;
            let (gx, gr) = rayon::join(|| GraphGeodesics::mesh_edges(tx), || GraphGeodesics::mesh_edges(tr));
            let (gx, gr) = (gx?, gr?);
            let c = c.0;
            let embedded = crate::linalg::mul(phi.subcols(0, c.nrows()), c.as_ref());
            let reading = Some((embedded.as_ref(), psi.subcols(0, c.ncols())));
            let o = crate::refine::MetricPolishOptions::default();
            let mut r = crate::refine::metric_polish(&gx, &gr, &gr, &anchors, &map, &o, reading)?;
            let map = std::mem::take(&mut r.map_xy);
            stages.push(("covered metric polish".to_string(), t.elapsed().as_secs_f64()));
            (map, Some(r))
        }
        _ => (map, None),
    };
    let map_xy_new: Vec<usize> = map.iter().map(|&j| region.vertices[j]).collect();
    let moved = map_xy_new.iter().zip(map_xy).filter(|(a, b)| a != b).count();
    Ok(Some(CoveredRefinement {
        map_xy: map_xy_new,
        region_vertices: region.vertices.len(),
        moved,
        metric_polish,
        stages,
    }))
}

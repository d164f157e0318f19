//! The basin search's correction on a real pair: the bundled FAUST pair, a sample map that is
//! the ground truth except on one leg, which is sent to the other leg (its mirror image through
//! the left–right symmetry, as in the limb swaps of faust_r). The correction by distances — alone
//! and with the pipeline's descriptors — brings the leg back.

use std::path::{Path, PathBuf};

use funcorr::descriptors::signatures::{wks_recipe, WksRecipe};
use funcorr::geodesic::GraphGeodesics;
use funcorr::io::indices::read_index_list_file;
use funcorr::matching::search::{correct, descriptor_distances, distortion, SampleDistances};
use funcorr::prepared::{LaplacianChoice, PreparedShape};
use funcorr::shape::Shape;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/faust").join(name)
}

/// The ground truth of X's samples on the bundled pair: for each sample (a vertex of X with
/// positions `px`) its nearest template point t, and then gt_y[t] (its true image on Y, `m`
/// vertices) and gt_s[t] (the mirror image of that).
fn sample_truth(px: &[[f64; 3]], samples: &[usize], m: usize) -> (Vec<usize>, Vec<usize>) {
    let read = |n: &str, len: usize| read_index_list_file(&data(n), true, len).unwrap();
    let (gt_x, gt_y, gt_s) =
        (read("tr_reg_000.vts", px.len()), read("tr_reg_001.vts", m), read("tr_reg_001.sym.vts", m));
    let template_of = |v: usize| {
        let d = |t: usize| (0..3).map(|c| (px[gt_x[t]][c] - px[v][c]).powi(2)).sum::<f64>();
        (0..gt_x.len()).min_by(|&a, &b| d(a).total_cmp(&d(b))).unwrap()
    };
    samples.iter().map(|&v| template_of(v)).map(|t| (gt_y[t], gt_s[t])).unzip()
}

#[test]
fn the_correction_brings_a_swapped_leg_back() {
    let prep = |n: &str| PreparedShape::new(Shape::load(&data(n)).unwrap(), LaplacianChoice::Auto, 130, None).unwrap();
    let (x, y) = (prep("tr_reg_000.off"), prep("tr_reg_001.off"));
    let (tx, ty) = (x.triangles().unwrap(), y.triangles().unwrap());
    let (gx, gy) = (GraphGeodesics::mesh_edges(tx).unwrap(), GraphGeodesics::mesh_edges(ty).unwrap());
    let sx = SampleDistances::new(tx, &x.basis.mass, &gx, 200).unwrap();
    let sy = SampleDistances::new(ty, &y.basis.mass, &gy, 1000).unwrap();
    // Ground truth of the samples and its mirror image.
    let px = tx.vertices();
    let (truth, mirrored) = sample_truth(px, &sx.samples.vertices, y.n());
    // One leg: below 40 % of the height, on one side of the body's middle (x ≈ 0.225 on this
    // shape at its own units; the prepared positions are scaled, so compare relative extents).
    let (lo, hi) = tx.bounding_box();
    let on_leg = |v: usize| {
        let p = px[v];
        (p[1] - lo[1]) < 0.4 * (hi[1] - lo[1]) && (p[0] - lo[0]) < 0.5 * (hi[0] - lo[0])
    };
    let swapped: Vec<usize> =
        sx.samples.vertices.iter().enumerate().map(|(i, &v)| if on_leg(v) { mirrored[i] } else { truth[i] }).collect();
    let leg = sx.samples.vertices.iter().filter(|&&v| on_leg(v)).count();
    assert!(leg >= 15, "{leg} samples on the leg");
    let close = |images: &[usize]| {
        let d = gy.pair_distances(&images.iter().zip(&truth).map(|(&a, &b)| (a, b)).collect::<Vec<_>>()).unwrap();
        d.iter().filter(|&&e| e <= sx.radius).count() as f64 / images.len() as f64
    };
    assert!(close(&swapped) < 0.95, "the swap must move the leg: {}", close(&swapped));
    assert!(distortion(&sx, &sy, &swapped) > distortion(&sx, &sy, &truth));
    let r = WksRecipe::default();
    let (f, g) = (wks_recipe(&x.basis, &r).unwrap(), wks_recipe(&y.basis, &r).unwrap());
    let desc = descriptor_distances(&sx, &sy, f.values.as_ref(), g.values.as_ref());
    for d in [None, Some(&desc)] {
        let (fixed, report) = correct(&sx, &sy, &swapped, d, 10).unwrap();
        let share = close(&fixed);
        assert!(
            share >= 0.97,
            "with descriptors {}: {share} of the samples back near the truth ({report:?})",
            d.is_some()
        );
        assert!(report.moved >= leg / 2, "{report:?}");
    }
}

/// The orientation that decides between a map and its mirror image (the humans are nearly
/// left–right symmetric, so the mirrored map fits distances about as well as the true one): on
/// the bundled pair the true sample map preserves orientation at almost every sample and the
/// mirrored one reverses it, with Y a mesh and with Y given as its vertices only (a point cloud,
/// whose normals come from the points and are oriented by propagation).
#[test]
fn orientation_tells_the_true_map_from_its_mirror_image() {
    use funcorr::matching::search::{orientation, sample_neighbours};
    use funcorr::shape::PointSet;
    let prep = |s: Shape| PreparedShape::new(s, LaplacianChoice::Auto, 60, None).unwrap();
    let x = prep(Shape::load(&data("tr_reg_000.off")).unwrap());
    let Shape::Mesh(ym) = Shape::load(&data("tr_reg_001.off")).unwrap() else { panic!("a mesh") };
    let flat: Vec<f64> = ym.vertices().iter().flatten().copied().collect();
    let cloud = Shape::Points(PointSet::new(ym.n_vertices(), 3, flat).unwrap());
    let tx = x.triangles().unwrap();
    let sx = SampleDistances::new(tx, &x.basis.mass, &GraphGeodesics::mesh_edges(tx).unwrap(), 200).unwrap();
    let neighbours = sample_neighbours(&sx, 8);
    let px = tx.vertices();
    let (truth, mirrored) = sample_truth(px, &sx.samples.vertices, ym.n_vertices());
    for (what, y) in [("mesh", prep(Shape::Mesh(ym.clone()))), ("cloud", prep(cloud))] {
        let (py, ny) = (y.positions().unwrap(), y.normals().unwrap());
        let o =
            |images: &[usize]| orientation(px, x.normals().unwrap(), py, ny, &sx.samples.vertices, images, &neighbours);
        let (ot, om) = (o(&truth), o(&mirrored));
        assert!(ot > 0.7, "{what}: the true map's orientation {ot}");
        assert!(om < -0.7, "{what}: the mirrored map's orientation {om}");
    }
}

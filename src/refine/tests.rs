use super::*;
use crate::laplacian::cotangent;
use crate::primitives::bumpy_sphere;
use crate::shape::TriMesh;
use crate::spatial::farthest_point_samples;
use crate::spatial::Samples;
use crate::spectral::{eigen_basis, Basis, SpectralOptions};
use faer::Mat;

/// The bumpy sphere X (3 subdivisions), a copy Y with its vertices renumbered, the map X → Y
/// (vertex i of X is vertex `perm[i]` of Y), its inverse, and both shapes' first k eigenpairs.
fn permuted_pair(k: usize) -> (TriMesh, TriMesh, Vec<usize>, Vec<usize>, Basis, Basis) {
    let x = bumpy_sphere(3);
    let n = x.n_vertices();
    let perm: Vec<usize> = (0..n).map(|i| (i * 101 + 7) % n).collect();
    let mut inv = vec![0; n];
    for (i, &p) in perm.iter().enumerate() {
        inv[p] = i;
    }
    let y = x.permuted(&inv).unwrap();
    let basis = |m: &TriMesh| eigen_basis(&cotangent(m).unwrap(), &SpectralOptions::new(k), None).unwrap().0;
    let (bx, by) = (basis(&x), basis(&y));
    (x, y, perm, inv, bx, by)
}

#[test]
fn zoomout_recovers_a_permutation_from_a_coarse_start_on_samples() {
    let (x, y, perm, inv, bx, by) = permuted_pair(40);
    assert_eq!(y.vertices()[perm[17]], x.vertices()[17]);
    let (phi, psi) = (bx.eigenvectors.as_ref(), by.eigenvectors.as_ref());
    let full = pullback(phi, psi, &Samples::all(&bx.mass), &perm, 40, 40).unwrap();
    let c0 = full.submatrix(0, 0, 4, 4).to_owned();
    let samples = farthest_point_samples(x.vertices(), &bx.mass, 300).unwrap();
    assert_eq!(samples.len(), 300);
    let total: f64 = samples.weights.iter().sum();
    assert!((total - bx.mass.iter().sum::<f64>()).abs() < 1e-12);
    let c = zoomout(phi, psi, &samples, c0.as_ref(), &ZoomOutOptions { k_final: 40, step: 3 }, Scope::Exact).unwrap();
    let map = map_of_pullback(phi, psi, c.as_ref(), None, Scope::Exact).unwrap();
    assert_eq!(c.nrows(), 40);
    assert_eq!(map, perm, "ZoomOut on samples must recover the permutation");
    // The map Y → X read off the same pull-back is the inverse permutation.
    assert_eq!(map_yx_of_pullback(phi, psi, c.as_ref(), Scope::Exact).unwrap(), inv);
    assert!(map_yx_of_pullback(phi, psi, Mat::<f64>::zeros(41, 40).as_ref(), Scope::Exact).is_err());
    // The identity permutation is orientation-preserving; the same map read on a mirrored
    // copy of Y is orientation-reversing.
    let normals = y.vertex_normals();
    let s = orientation_agreement(&x, y.vertices(), &normals, &map).unwrap();
    assert!(s > 0.99, "agreement {s}");
    let ym: Vec<[f64; 3]> = y.vertices().iter().map(|p| [-p[0], p[1], p[2]]).collect();
    let nm: Vec<[f64; 3]> = normals.iter().map(|p| [-p[0], p[1], p[2]]).collect();
    let s = orientation_agreement(&x, &ym, &nm, &map).unwrap();
    assert!(s < -0.99, "mirrored agreement {s}");
}

/// ZoomOut coarse to fine in Y: the steps before the last match the samples among 150 of Y's
/// 642 vertices only; the last step searches every vertex, so the final pull-back still
/// recovers the permutation. With every vertex as the coarse set it is plain ZoomOut.
#[test]
fn coarse_to_fine_zoomout_recovers_a_permutation() {
    let (x, y, perm, _, bx, by) = permuted_pair(40);
    let n = x.n_vertices();
    let (phi, psi) = (bx.eigenvectors.as_ref(), by.eigenvectors.as_ref());
    let full = pullback(phi, psi, &Samples::all(&bx.mass), &perm, 40, 40).unwrap();
    let c0 = full.submatrix(0, 0, 4, 4).to_owned();
    let samples = farthest_point_samples(x.vertices(), &bx.mass, 300).unwrap();
    let o = ZoomOutOptions { k_final: 40, step: 3 };
    let coarse = farthest_point_samples(y.vertices(), &by.mass, 150).unwrap().vertices;
    // The coarse steps' images are coarse vertices.
    let among = map_of_pullback_among(phi, psi, c0.as_ref(), &samples.vertices, &coarse).unwrap();
    assert!(among.iter().all(|j| coarse.contains(j)));
    let c = zoomout_coarse_to_fine(phi, psi, &samples, c0.as_ref(), &o, Scope::Exact, &[], Some(&coarse)).unwrap();
    assert_eq!(c.nrows(), 40);
    assert_eq!(map_of_pullback(phi, psi, c.as_ref(), None, Scope::Exact).unwrap(), perm);
    // Every vertex as the coarse set: the same functional map as ZoomOut's.
    let all: Vec<usize> = (0..n).collect();
    let same = zoomout_coarse_to_fine(phi, psi, &samples, c0.as_ref(), &o, Scope::Exact, &[], Some(&all)).unwrap();
    let plain = zoomout(phi, psi, &samples, c0.as_ref(), &o, Scope::Exact).unwrap();
    assert!((&same - &plain).norm_max() < 1e-10);
    assert_eq!(
        map_of_pullback_among(phi, psi, c0.as_ref(), &samples.vertices, &all).unwrap(),
        map_of_pullback(phi, psi, c0.as_ref(), Some(&samples.vertices), Scope::Exact).unwrap()
    );
    // The same near a coarse map (the restricted searches of large pairs): the last step matches
    // near the coarse steps' images.
    let y_cells = farthest_point_samples(y.vertices(), &by.mass, 100).unwrap().vertices;
    let near = Near { x: x.vertices(), y: y.vertices(), cells: 8, certify: false };
    let scope = Scope::Near { near: &near, x_cells: &samples.vertices, y_cells: &y_cells };
    let c = zoomout_coarse_to_fine(phi, psi, &samples, c0.as_ref(), &o, scope, &[], Some(&coarse)).unwrap();
    assert_eq!(map_of_pullback(phi, psi, c.as_ref(), None, Scope::Exact).unwrap(), perm);
    // Coarse vertices out of range or none at all are errors.
    let bad = zoomout_coarse_to_fine(phi, psi, &samples, c0.as_ref(), &o, Scope::Exact, &[], Some(&[n]));
    assert!(bad.is_err());
    assert!(zoomout_coarse_to_fine(phi, psi, &samples, c0.as_ref(), &o, Scope::Exact, &[], Some(&[])).is_err());
}

#[test]
fn distortion_and_orientation_around_samples_estimate_the_whole() {
    let x = bumpy_sphere(4);
    let n = x.n_vertices();
    let mass = vec![1.0; n];
    // A map that is right on one half and sends the other half to one vertex.
    let map: Vec<usize> = (0..n).map(|i| if x.vertices()[i][0] > 0.0 { i } else { 0 }).collect();
    let normals = x.vertex_normals();
    let (whole_d, whole_o) = (
        metric_distortion(&x, x.vertices(), 1.0, &map).unwrap(),
        orientation_agreement(&x, x.vertices(), &normals, &map).unwrap(),
    );
    // Around every vertex: exactly the whole.
    let all: Vec<usize> = (0..n).collect();
    assert_eq!(incident_vertices(&x, &all), all);
    assert!((metric_distortion_around(&x, x.vertices(), 1.0, &map, &all).unwrap() - whole_d).abs() < 1e-14);
    assert!((orientation_agreement_around(&x, x.vertices(), &normals, &map, &all).unwrap() - whole_o).abs() < 1e-14);
    // Around 60 farthest-point samples, with the map known on their one-rings only: close.
    let centres = farthest_point_samples(x.vertices(), &mass, 60).unwrap().vertices;
    let patch = incident_vertices(&x, &centres);
    assert!(patch.len() > centres.len() && patch.len() < n / 2, "{} of {n}", patch.len());
    let mut partial = vec![0usize; n];
    patch.iter().for_each(|&v| partial[v] = map[v]);
    let d = metric_distortion_around(&x, x.vertices(), 1.0, &partial, &centres).unwrap();
    let o = orientation_agreement_around(&x, x.vertices(), &normals, &partial, &centres).unwrap();
    assert!((d - whole_d).abs() < 0.25 * whole_d, "{d} vs {whole_d}");
    assert!((o - whole_o).abs() < 0.25, "{o} vs {whole_o}");
    assert!(whole_d > 0.1 && metric_distortion_around(&x, x.vertices(), 1.0, &all, &centres).unwrap() == 0.0);
    assert!(metric_distortion_around(&x, x.vertices(), 1.0, &map, &[n]).is_err());
    assert!(orientation_agreement_around(&x, x.vertices(), &normals, &map, &[n]).is_err());
}

#[test]
fn bijective_polish_repairs_a_noisy_map() {
    let (x, y, perm, _, bx, by) = permuted_pair(30);
    let n = x.n_vertices();
    let (phi, psi) = (bx.eigenvectors.as_ref(), by.eigenvectors.as_ref());
    let truth = pullback(phi, psi, &Samples::all(&bx.mass), &perm, 30, 30).unwrap();
    // A deterministic perturbation of the true map.
    let noisy = Mat::from_fn(30, 30, |i, j| truth[(i, j)] + 0.15 * (((i * 31 + j * 17) % 13) as f64 / 6.0 - 1.0));
    let agreement = |m: &[usize]| m.iter().zip(&perm).filter(|(a, b)| a == b).count() as f64 / n as f64;
    let plain = agreement(&map_of_pullback(phi, psi, noisy.as_ref(), None, Scope::Exact).unwrap());
    assert!(plain < 0.95, "the perturbation must break the plain read-off ({plain})");
    let (sx, sy) = (
        farthest_point_samples(x.vertices(), &bx.mass, 300).unwrap(),
        farthest_point_samples(y.vertices(), &by.mass, 300).unwrap(),
    );
    let (c, map) = bijective_polish(phi, psi, &sx, &sy, noisy.as_ref(), 3, Scope::Exact).unwrap();
    assert_eq!(c.nrows(), 30);
    let polished = agreement(&map);
    assert!(polished > 0.99 && polished > plain, "polish {polished}, plain read-off {plain}");
    assert!(bijective_polish(phi, psi, &sx, &sy, noisy.submatrix(0, 0, 30, 20), 1, Scope::Exact).is_err());
}

#[test]
fn pullback_of_all_vertices_is_the_mass_projection() {
    let x = bumpy_sphere(2);
    let b = eigen_basis(&cotangent(&x).unwrap(), &SpectralOptions::new(10), None).unwrap().0;
    let phi = b.eigenvectors.as_ref();
    let id: Vec<usize> = (0..x.n_vertices()).collect();
    let c = pullback(phi, phi, &Samples::all(&b.mass), &id, 10, 10).unwrap();
    assert!((&c - Mat::<f64>::identity(10, 10)).norm_max() < 1e-10);
    assert!(pullback(phi, phi, &Samples::all(&b.mass), &id[1..], 10, 10).is_err());
    assert!(farthest_point_samples(x.vertices(), &b.mass, 0).is_err());
}

/// The restricted search through finer levels ([`pullback::rows_near`]) on a 10,242-vertex
/// sphere and a renumbered copy whose cells hold 1,000 vertices each (10 cells: a level of
/// 160 finer cells is added) agrees with the exact search on ≥ 99.9 % of the vertices for a right
/// coarse map, as the one-level search does.
#[test]
fn finer_levels_keep_the_exact_map() {
    use crate::pointwise::{nearest_neighbors, nearest_neighbors_near_rows, CoarseMap};
    let x = crate::primitives::icosphere(5);
    let n = x.n_vertices();
    let (px, py, truth, query, reference) = crate::pointwise::tests::renumbered_embeddings(&x, 0.002);
    let exact = nearest_neighbors(reference.as_ref(), query.as_ref()).unwrap();
    let mass = vec![1.0; n];
    let sx = farthest_point_samples(&px, &mass, 10).unwrap().vertices;
    let sy = farthest_point_samples(&py, &mass, 10).unwrap().vertices;
    let images: Vec<usize> = sx.iter().map(|&s| truth[s]).collect();
    let near = pullback::Near { x: &px, y: &py, cells: 4, certify: false };
    let all: Vec<usize> = (0..n).collect();
    let levels = pullback::rows_near(reference.as_ref(), query.as_ref(), &near, (&sx, &images, &sy), &all).unwrap();
    let agree = levels.iter().zip(&exact).filter(|(a, b)| a == b).count();
    assert!(agree as f64 >= 0.999 * n as f64, "{agree} of {n}");
    // With one level the same cells give the same map here (the finer level changes the
    // candidates, not the answer).
    let coarse = CoarseMap { x: &px, y: &py, samples: &sx, images: &images, y_cells: &sy };
    let one = nearest_neighbors_near_rows(reference.as_ref(), query.as_ref(), &coarse, 4, &all).unwrap();
    let same = levels.iter().zip(&one).filter(|(a, b)| a == b).count();
    assert!(same as f64 >= 0.999 * n as f64, "{same} of {n}");
}

/// The map Y → X near the preimages of the map X → Y ([`map_yx_near_map`]): with the true map
/// X → Y it is the inverse permutation, certified or not; with a map X → Y that folds a third of
/// X onto one vertex of Y (Y's cells there have no preimage near them, or only wrong ones), the
/// certified search is still the exact one (uncertified, over a quarter of its answers are
/// not). Wrong sizes and `cells` = 0 are errors.
#[test]
fn the_map_back_near_the_preimages_is_the_exact_one() {
    let (x, y, perm, inv, bx, by) = permuted_pair(40);
    let (phi, psi) = (bx.eigenvectors.as_ref(), by.eigenvectors.as_ref());
    let c = pullback(phi, psi, &Samples::all(&bx.mass), &perm, 40, 40).unwrap();
    let near = |cells, certify| Near { x: x.vertices(), y: y.vertices(), cells, certify };
    for certify in [false, true] {
        assert_eq!(map_yx_near_map(phi, psi, c.as_ref(), &near(4, certify), &perm).unwrap(), inv);
    }
    let n = perm.len();
    let folded: Vec<usize> =
        (0..n).map(|i| if i % 3 == 0 || x.vertices()[i][0] > 0.3 { perm[0] } else { perm[i] }).collect();
    let exact = map_yx_of_pullback(phi, psi, c.as_ref(), Scope::Exact).unwrap();
    assert_eq!(map_yx_near_map(phi, psi, c.as_ref(), &near(4, true), &folded).unwrap(), exact);
    // (Uncertified, the fold leaves half of the answers wrong: the certificate did the work.)
    let uncertified = map_yx_near_map(phi, psi, c.as_ref(), &near(4, false), &folded).unwrap();
    assert!(uncertified.iter().zip(&exact).filter(|(a, b)| a != b).count() > n / 4);
    assert!(map_yx_near_map(phi, psi, c.as_ref(), &near(4, true), &perm[1..]).is_err());
    assert!(map_yx_near_map(phi, psi, c.as_ref(), &near(0, false), &perm).is_err());
    let mut out_of_range = perm.clone();
    out_of_range[5] = n;
    assert!(map_yx_near_map(phi, psi, c.as_ref(), &near(4, false), &out_of_range).is_err());
}

//! Units, rigid motions and vertex order do not matter: the default pipeline on the bundled pair
//! with either shape scaled by 10⁻³ … 10³, rotated, or its vertices permuted gives the same map
//! as on the shapes as given, up to ties (≥ 99 % of the vertices identical).

use std::path::Path;

use funcorr::descriptors::signatures::{wks_recipe, WksRecipe};
use funcorr::matching::{run, MatchOptions};
use funcorr::prepared::{LaplacianChoice, PreparedShape};
use funcorr::shape::{Shape, TriMesh};

fn mesh(name: &str) -> TriMesh {
    match Shape::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/faust").join(name)).unwrap() {
        Shape::Mesh(m) => m,
        Shape::Points(_) => panic!("{name} is not a mesh"),
    }
}

/// The default map X → Y.
fn default_map(x: &TriMesh, y: &TriMesh) -> Vec<usize> {
    let opts = MatchOptions::default();
    let k = opts.basis_size().max(funcorr::matching::DEFAULT_BASIS_SIZE);
    let prep = |m: &TriMesh| PreparedShape::new(Shape::Mesh(m.clone()), LaplacianChoice::Auto, k, None).unwrap();
    let (px, py) = (prep(x), prep(y));
    let r = WksRecipe::default();
    let (f, g) = (wks_recipe(&px.basis, &r).unwrap(), wks_recipe(&py.basis, &r).unwrap());
    run(&px, &py, &f, &g, &opts).unwrap().map_xy
}

/// A rotation by `angle` about the unit axis (1, 2, 3) / √14, then a scaling by `s`.
fn moved(m: &TriMesh, s: f64, angle: f64) -> TriMesh {
    let k = [1.0 / 14f64.sqrt(), 2.0 / 14f64.sqrt(), 3.0 / 14f64.sqrt()];
    let (sn, cs) = angle.sin_cos();
    m.map_vertices(|p| {
        // Rodrigues' formula.
        let kxp = [k[1] * p[2] - k[2] * p[1], k[2] * p[0] - k[0] * p[2], k[0] * p[1] - k[1] * p[0]];
        let kp = k[0] * p[0] + k[1] * p[1] + k[2] * p[2];
        std::array::from_fn(|c| s * (p[c] * cs + kxp[c] * sn + k[c] * kp * (1.0 - cs)))
    })
    .unwrap()
}

#[test]
fn units_rigid_motions_and_vertex_order_do_not_change_the_map() {
    let (x, y) = (mesh("tr_reg_000.off"), mesh("tr_reg_001.off"));
    let base = default_map(&x, &y);
    let agreement = |a: &[usize]| a.iter().zip(&base).filter(|(p, q)| p == q).count() as f64 / base.len() as f64;
    for (sx, sy) in [(1e-3, 1.0), (1.0, 1e3), (1e-1, 10.0), (1e3, 1e-3)] {
        let a = agreement(&default_map(&moved(&x, sx, 0.0), &moved(&y, sy, 0.0)));
        assert!(a >= 0.99, "X scaled by {sx}, Y by {sy}: {a} of the map unchanged");
    }
    // Y rotated and its vertices in another order: vertex q of Y' is vertex order[q] of Y.
    let m = y.n_vertices();
    let order: Vec<usize> = (0..m).map(|q| (q * 2749 + 11) % m).collect();
    let y2 = moved(&y, 1.0, 1.1).permuted(&order).unwrap();
    let map: Vec<usize> = default_map(&moved(&x, 1.0, -0.4), &y2).iter().map(|&q| order[q]).collect();
    let a = agreement(&map);
    assert!(a >= 0.99, "rotated and permuted: {a} of the map unchanged");
}

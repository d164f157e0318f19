//! The paper's Figure 5 claim on a real pair (issue 4): with segment indicators only (scarce
//! data) and the same k = 250, the completion method does clearly better than Ovsjanikov's
//! eq. (5), measured with the mean geodesic error (Princeton protocol, symmetric flips allowed,
//! exact geodesics) on the bundled FAUST pair, without point-wise refinement.
//!
//! Measured (EXPERIMENTS.md): eq. (5) at k = 250: 7.48; pure (11) at k' = 350, k = 250 from an
//! eq. (5) start: 9.91 (worse: nothing in (11) rewards a near-isometric map); (11) with the
//! Laplacian-commutativity term: 5.15. The test asserts the last at most 0.8 × the first.

use std::path::{Path, PathBuf};

use funcorr::descriptors::{self, Descriptors};
use funcorr::eval::{hard_errors, summarize, GroundTruth};
use funcorr::geodesic::ExactGeodesics;
use funcorr::io::indices::{read_index_list_file, read_labels_file};
use funcorr::laplacian::cotangent;
use funcorr::matching::{self, MatchOptions, Method, Refine};
use funcorr::shape::{Shape, TriMesh};
use funcorr::spectral::{eigen_basis, SpectralOptions};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/faust").join(name)
}

fn mesh(name: &str) -> TriMesh {
    match Shape::load(&data(name)).unwrap() {
        Shape::Mesh(m) => m,
        Shape::Points(_) => panic!("{name} is not a mesh"),
    }
}

#[test]
fn completion_beats_eq5_with_scarce_data_at_the_same_rank() {
    let (mx, my) = (mesh("tr_reg_000.off"), mesh("tr_reg_001.off"));
    let (lx, ly) = (cotangent(&mx).unwrap(), cotangent(&my).unwrap());
    let (bx, _) = eigen_basis(&lx, &SpectralOptions::new(350), None).unwrap();
    let (by, _) = eigen_basis(&ly, &SpectralOptions::new(350), None).unwrap();
    // The provided segmentation of the pair: 11 segment indicators (labels agree across shapes).
    let seg = |s: &str, n: usize| read_labels_file(&data(&format!("tr_reg_000_tr_reg_001.{s}.seg.sym")), n).unwrap();
    let (f, g): (Descriptors, Descriptors) = (
        descriptors::segments(&seg("tr_reg_000", bx.n())).unwrap(),
        descriptors::segments(&seg("tr_reg_001", by.n())).unwrap(),
    );
    assert_eq!((f.q(), g.q(), f.names.clone()), (11, 11, g.names.clone()));
    let vts = |s: &str, n: usize| read_index_list_file(&data(s), true, n).unwrap();
    let gt = GroundTruth {
        x: vts("tr_reg_000.vts", bx.n()),
        y: vts("tr_reg_001.vts", by.n()),
        y_sym: Some(vts("tr_reg_001.sym.vts", by.n())),
    };
    let geo = ExactGeodesics::new(&my).unwrap();
    let error = |opts: &MatchOptions| {
        let r = matching::run_on_bases(&bx, &by, Some((&lx, &ly)), &f, &g, opts).unwrap();
        100.0 * summarize(&hard_errors(&r.map_xy, &gt, &geo, my.total_area()).unwrap()).mean
    };
    let base =
        MatchOptions { refine: Refine::None, commutativity: 0.0, ..MatchOptions::for_method(Method::Fmap, false) };
    let eq5 = error(&MatchOptions { method: Method::Fmap, k: 250, ..base.clone() });
    let mut comp = MatchOptions { method: Method::Completion, ..base };
    assert_eq!((comp.completion.k_prime, comp.completion.k), (350, 250)); // the paper's scarce-data setting
    comp.completion.optimize.max_iterations = 100;
    comp.completion.params.mu_comm = 1e-2;
    comp.completion.params.k_comm = 50;
    let completion = error(&comp);
    eprintln!("mean error ×100: eq. (5) at k = 250: {eq5:.2}; completion (11) + commutativity, k' = 350, k = 250: {completion:.2}");
    assert!(completion < 0.8 * eq5, "completion {completion:.2} vs eq. (5) {eq5:.2}");
}

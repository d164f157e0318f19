//! `funcorr demo`: the default pipeline on the bundled FAUST pair.

use std::path::Path;
use std::time::Instant;

use funcorr::shape::{Shape, TriMesh};
use funcorr::spectral::{Basis, SpectralOptions};
use funcorr::{laplacian, spectral, Error, Result};

use crate::args::{DEFAULT_DATA, DEFAULT_SIZE, DEFAULT_VIEW};
use crate::output::{describe, parse_size, write_colour_transfer, write_map_files};
use crate::spectrum::progress_bar;

/// Ground-truth template correspondences of the demo pair (1-based vertex ids; line i of X's file
/// corresponds to line i of Y's; `.sym` is the left–right mirrored version).
pub(crate) const DEMO_VTS: [&str; 4] = [
    include_str!("../../data/faust/tr_reg_000.vts"),
    include_str!("../../data/faust/tr_reg_001.vts"),
    include_str!("../../data/faust/tr_reg_000.sym.vts"),
    include_str!("../../data/faust/tr_reg_001.sym.vts"),
];

/// Demo step: persistence segments of both shapes, matched by their signatures, checked against
/// the ground truth; writes the matched indicators F.npy, G.npy (the paper's scarce data).
pub(crate) fn demo_segments(out: &Path, (mx, bx): (&TriMesh, &Basis), (my, by): (&TriMesh, &Basis)) -> Result<()> {
    use funcorr::descriptors::persistence as pers;
    let t = Instant::now();
    let lx = pers::segment(&mx.edges(), bx, pers::DEFAULT_THRESHOLD)?.labels;
    let ly = pers::segment(&my.edges(), by, pers::DEFAULT_THRESHOLD)?.labels;
    let (f, g, matches) = pers::matched_segment_indicators(&lx, bx, &ly, by)?;
    let seconds = t.elapsed().as_secs_f64();
    let label = |name: &str| name.trim_start_matches("segment:").parse::<u32>().unwrap_or(0);
    let map: std::collections::HashMap<u32, u32> =
        f.names.iter().zip(&g.names).map(|(a, b)| (label(a), label(b))).collect();
    let vts = |i: usize, n: usize| {
        funcorr::io::indices::read_index_list(DEMO_VTS[i].as_bytes(), Path::new("demo.vts"), true, n)
    };
    let (vx, vy, sx, sy) =
        (vts(0, mx.n_vertices())?, vts(1, my.n_vertices())?, vts(2, mx.n_vertices())?, vts(3, my.n_vertices())?);
    let hit = |a: usize, b: usize| map.get(&lx[a]) == Some(&ly[b]);
    let exact = (0..vx.len()).filter(|&i| hit(vx[i], vy[i])).count();
    let flips = (0..vx.len()).filter(|&i| hit(vx[i], vy[i]) || hit(sx[i], sy[i])).count();
    outln!(
        "\nPersistence segments (scarce data): {} on X, {} on Y, {} matched by signature in {seconds:.2} s",
        lx.iter().max().unwrap_or(&0),
        ly.iter().max().unwrap_or(&0),
        matches.len()
    );
    outln!(
        "  ground truth: {:.1}% of {} template points fall in matched segments ({:.1}% allowing the left-right flip)",
        100.0 * exact as f64 / vx.len() as f64,
        vx.len(),
        100.0 * flips as f64 / vx.len() as f64
    );
    funcorr::io::npy::write_npy_matrix(&out.join("F.npy"), &f.to_dense())?;
    funcorr::io::npy::write_npy_matrix(&out.join("G.npy"), &g.to_dense())?;
    Ok(())
}

/// Demo step: the default `funcorr match` pipeline evaluated against the bundled ground truth;
/// writes map.txt, X.ply, Y.ply, render.png and view.html (with the error heat map on X).
pub(crate) fn demo_match(out: &Path, (mx, bx): (&TriMesh, &Basis), (my, by): (&TriMesh, &Basis)) -> Result<()> {
    use funcorr::eval::{hard_errors, summarize, GroundTruth};
    // What `funcorr match X Y` runs: the library's defaults, data `wks`.
    let opts = funcorr::matching::MatchOptions::default();
    let t = Instant::now();
    use funcorr::prepared::Surface;
    let px = funcorr::PreparedShape::from_parts(
        Shape::Mesh(mx.clone()),
        laplacian::cotangent(mx)?,
        bx.clone(),
        Some(Surface::Mesh),
    );
    let py = funcorr::PreparedShape::from_parts(
        Shape::Mesh(my.clone()),
        laplacian::cotangent(my)?,
        by.clone(),
        Some(Surface::Mesh),
    );
    // `--data wks` (the default): pyFM's WKS recipe, through the one `--data` grammar.
    let spec: funcorr::descriptors::spec::PairDataSpec = DEFAULT_DATA.parse()?;
    let (f, g) = spec.functions(px.parts(), py.parts(), &Default::default())?;
    let r = funcorr::matching::run(&px, &py, &f, &g, &opts)?;
    let (x, y) = (&px.shape, &py.shape);
    let seconds = t.elapsed().as_secs_f64();
    let vts = |i: usize, n: usize| {
        funcorr::io::indices::read_index_list(DEMO_VTS[i].as_bytes(), Path::new("demo.vts"), true, n)
    };
    let geo = funcorr::geodesic::ExactGeodesics::new(my)?;
    let gt = GroundTruth { x: vts(0, mx.n_vertices())?, y: vts(1, my.n_vertices())?, y_sym: None };
    let errors = hard_errors(&r.map_xy, &gt, &geo, my.total_area())?;
    let plain = summarize(&errors);
    let vertex_errors = funcorr::viz::html::VertexErrors::spread(mx.vertices(), &gt, &errors, "exact geodesics")?;
    let gt = GroundTruth { y_sym: Some(vts(3, my.n_vertices())?), ..gt };
    let sym = summarize(&hard_errors(&r.map_xy, &gt, &geo, my.total_area())?);
    outln!("\nMatching X → Y with the defaults of `funcorr match` ({}): {seconds:.1} s", describe(DEFAULT_DATA, &opts));
    for (name, secs) in &r.stages {
        outln!("  {name}: {secs:.2} s");
    }
    outln!(
        "  geodesic error (Princeton protocol, exact geodesics): mean ×100 = {:.2}, {:.1}% of points ≤ 0.05, {:.1}% ≤ 0.10",
        100.0 * plain.mean,
        100.0 * plain.at_005,
        100.0 * plain.at_010
    );
    outln!("  allowing the left-right flip: mean ×100 = {:.2}", 100.0 * sym.mean);
    write_map_files(out, &r.map_xy, false)?;
    let view = funcorr::viz::View::parse(DEFAULT_VIEW)?;
    write_colour_transfer(out, x, y, &r.map_yx, r.coverage.as_deref(), Some((parse_size(DEFAULT_SIZE)?, &view)))?;
    outln!("  colour transfer: X.ply, Y.ply (per-vertex colours) and render.png");
    let name = |(n, _): (&str, &[u8])| n.trim_end_matches(".off").to_string();
    crate::view::write_match_view(
        out,
        (x, &name(DEMO_X)),
        (y, &name(DEMO_Y)),
        &r.map_xy,
        &r.map_yx,
        describe(DEFAULT_DATA, &opts),
        &[],
        Some(vertex_errors),
    )?;
    outln!("  interactive viewer: view.html (colour transfer, error on X, click a vertex to see its image on Y)");
    Ok(())
}

/// The two bundled FAUST shapes (remeshed, ~5k vertices; Bogo et al. 2014, remeshed for
/// Ren et al. 2018), embedded so that the demo runs from any directory.
pub(crate) const DEMO_X: (&str, &[u8]) = ("tr_reg_000.off", include_bytes!("../../data/faust/tr_reg_000.off"));
pub(crate) const DEMO_Y: (&str, &[u8]) = ("tr_reg_001.off", include_bytes!("../../data/faust/tr_reg_001.off"));

pub(crate) fn demo(target: &Path, k: usize) -> Result<()> {
    let staged = funcorr::io::staged::StagedDir::create(target)?;
    demo_into(&staged, k).map_err(|e| staged.attribute(e))?;
    staged.publish()?;
    outln!("\nwrote {}", target.display());
    outln!("open {} in a browser to explore the map", target.join("view.html").display());
    Ok(())
}

/// The demo, writing into a staging directory that `demo` publishes.
pub(crate) fn demo_into(staged: &funcorr::io::staged::StagedDir, k: usize) -> Result<()> {
    let out = staged.path();
    // Enough eigenpairs for the default match pipeline (as many as `funcorr match` computes).
    let k = k.max(funcorr::matching::MatchOptions::default().basis_size()).max(funcorr::matching::DEFAULT_BASIS_SIZE);
    outln!("funcorr demo: two FAUST humans (same subject, different poses), k = {k} eigenpairs\n");
    let mut shapes: Vec<(TriMesh, Basis)> = Vec::new();
    for (name, bytes) in [DEMO_X, DEMO_Y] {
        let t = Instant::now();
        let data = funcorr::io::off::read_off(std::io::Cursor::new(bytes), Path::new(name))?;
        let mesh = match Shape::from_data(data)? {
            Shape::Mesh(m) => m,
            Shape::Points(_) => return Err(Error::invalid("demo data", "expected a mesh")),
        };
        let t_read = t.elapsed().as_secs_f64();
        outln!(
            "{name}: {} vertices, {} faces, area {:.4} m², {} component(s), {} boundary loop(s), {} degenerate face(s)",
            mesh.n_vertices(),
            mesh.n_faces(),
            mesh.total_area(),
            mesh.components().0,
            mesh.boundary_loops().len(),
            mesh.degenerate_faces().len()
        );
        let t = Instant::now();
        let lap = laplacian::cotangent(&mesh)?;
        let t_lap = t.elapsed().as_secs_f64();
        let pb = progress_bar(k, false);
        let update = |done: usize, _k: usize| pb.set_position(done as u64);
        let (basis, info) = spectral::eigen_basis(&lap, &SpectralOptions::new(k), Some(&update))?;
        pb.finish_and_clear();
        let file = out.join(name.replace(".off", ".basis.npz"));
        spectral::save_basis(&file, &basis)?;
        outln!(
            "  read {t_read:.3} s, Laplacian {t_lap:.3} s, eigenbasis {:.3} s ({} restarts), max residual {:.1e} -> {}",
            info.factor_seconds + info.iterate_seconds,
            info.restarts,
            basis.residuals.iter().copied().fold(0.0, f64::max),
            staged.published_path(&file).display()
        );
        shapes.push((mesh, basis));
    }
    let ((mesh_x, x), (mesh_y, y)) = (&shapes[0], &shapes[1]);
    let (area_x, area_y) = (mesh_x.total_area(), mesh_y.total_area());
    outln!("\nNear-isometric shapes have nearly equal scale-free spectra λ_i · area:");
    outln!("{:>4} {:>14} {:>14} {:>10}", "i", "λ_i(X)·area", "λ_i(Y)·area", "rel. diff");
    for i in (1..11).chain([k / 2, k - 1]).filter(|&i| i < k) {
        let (a, b) = (x.eigenvalues[i] * area_x, y.eigenvalues[i] * area_y);
        outln!("{i:>4} {a:>14.6} {b:>14.6} {:>9.2}%", 100.0 * (a - b).abs() / a.max(b));
    }
    demo_segments(out, (mesh_x, x), (mesh_y, y))?;
    demo_match(out, (mesh_x, x), (mesh_y, y))
}

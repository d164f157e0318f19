use super::*;
use crate::geodesic::GraphGeodesics;
use crate::primitives::{bumpy_sphere, icosphere};

fn norm3(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Deterministic uniform numbers in [−1, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// Grid of nx × ny cells over [0, a] × [0, b] with vertices moved by up to `jitter` cells
/// (boundary vertices only along the boundary), cells split along random diagonals, and cells
/// for which `keep(i, j)` is false left out. `on_boundary(x, y)` says which grid points must
/// stay on their line. Panics if a triangle is inverted.
fn jittered_grid(
    (a, b): (f64, f64),
    (nx, ny): (u32, u32),
    jitter: f64,
    seed: u64,
    keep: impl Fn(u32, u32) -> bool,
    fixed: impl Fn(u32, u32) -> (bool, bool),
) -> TriMesh {
    let mut rng = Lcg(seed);
    let (hx, hy) = (a / nx as f64, b / ny as f64);
    let mut v = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let (fx, fy) = fixed(i, j);
            let dx = if fx { 0.0 } else { jitter * hx * rng.next() };
            let dy = if fy { 0.0 } else { jitter * hy * rng.next() };
            v.push([i as f64 * hx + dx, j as f64 * hy + dy, 0.0]);
        }
    }
    let id = |i: u32, j: u32| j * (nx + 1) + i;
    let mut f = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            if !keep(i, j) {
                continue;
            }
            let (p00, p10, p01, p11) = (id(i, j), id(i + 1, j), id(i, j + 1), id(i + 1, j + 1));
            if rng.next() < 0.0 {
                f.extend([[p00, p10, p11], [p00, p11, p01]]);
            } else {
                f.extend([[p00, p10, p01], [p10, p11, p01]]);
            }
        }
    }
    for t in &f {
        let (p, q, r) = (v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]);
        let area2 = (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
        assert!(area2 > 0.0, "inverted triangle {t:?}");
    }
    // Drop vertices of removed cells by keeping them (unreferenced): they must come out as ∞.
    TriMesh::new(v, f).unwrap()
}

fn rectangle_mesh(nx: u32, ny: u32, seed: u64) -> TriMesh {
    jittered_grid((2.0, 1.0), (nx, ny), 0.3, seed, |_, _| true, move |i, j| (i == 0 || i == nx, j == 0 || j == ny))
}

fn count_obtuse(mesh: &TriMesh) -> usize {
    (0..mesh.n_faces())
        .filter(|&f| {
            let p = mesh.corners(f);
            (0..3).any(|k| {
                let (a, b, c) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
                let (u, w) = ([b[0] - a[0], b[1] - a[1]], [c[0] - a[0], c[1] - a[1]]);
                u[0] * w[0] + u[1] * w[1] < 0.0
            })
        })
        .count()
}

#[test]
fn flat_rectangle_distances_are_euclidean() {
    // Anisotropic jittered cells (2/60 × 1/50): irregular, many obtuse triangles.
    let mesh = rectangle_mesh(60, 50, 7);
    let obtuse = count_obtuse(&mesh);
    assert!(obtuse > mesh.n_faces() / 10, "only {obtuse} obtuse triangles");
    let g = ExactGeodesics::new(&mesh).unwrap();
    let n = mesh.n_vertices();
    let mut worst: f64 = 0.0;
    // A corner, a boundary vertex, an interior vertex.
    for s in [0usize, 30, 25 * 61 + 17] {
        let d = g.distances_from_vertex(s).unwrap();
        let ps = mesh.vertices()[s];
        assert_eq!(d[s], 0.0);
        for i in (0..n).filter(|&i| i != s) {
            let e = norm3(mesh.vertices()[i], ps);
            worst = worst.max((d[i] - e).abs() / e);
        }
    }
    assert!(worst <= 1e-9, "max relative error {worst:e}");
    eprintln!("flat rectangle ({n} vertices, {obtuse} obtuse faces): max relative error {worst:e}");
}

#[test]
fn l_shape_paths_bend_around_the_reflex_corner() {
    // [0,2]² without the open square (1,2)²; the reflex corner c = (1, 1) is grid vertex (20, 20).
    let nx = 40;
    let keep = |i: u32, j: u32| i < 20 || j < 20;
    let fixed = |i: u32, j: u32| {
        let on_x = i == 0 || i == nx || (i == 20 && j >= 20);
        let on_y = j == 0 || j == nx || (j == 20 && i >= 20);
        (on_x, on_y)
    };
    let mesh = jittered_grid((2.0, 2.0), (nx, nx), 0.3, 11, keep, fixed);
    let g = ExactGeodesics::new(&mesh).unwrap();
    let c = [1.0, 1.0];
    let s = 5 * 41 + 35; // near (1.75, 0.25), in the lower-right arm
    let d = g.distances_from_vertex(s).unwrap();
    let ps = mesh.vertices()[s];
    // Does the segment p → q cross the open removed square? (Liang–Barsky clipping.)
    let crosses = |p: [f64; 3], q: [f64; 3]| {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (pk, dk, lo, hi) in [(p[0], q[0] - p[0], 1.0, 2.0), (p[1], q[1] - p[1], 1.0, 2.0)] {
            if dk.abs() < 1e-300 {
                if pk <= lo || pk >= hi {
                    return false;
                }
            } else {
                let (a, b) = ((lo - pk) / dk, (hi - pk) / dk);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
        }
        t1 - t0 > 1e-12
    };
    let (mut worst, mut bent) = (0.0f64, 0);
    let used: std::collections::HashSet<u32> = mesh.faces().iter().flatten().copied().collect();
    for (i, p) in mesh.vertices().iter().enumerate() {
        if !used.contains(&(i as u32)) {
            assert_eq!(d[i], f64::INFINITY, "vertex {i} of a removed cell");
            continue;
        }
        if i == s {
            continue;
        }
        let exact = if crosses(ps, *p) {
            bent += 1;
            norm3(ps, [c[0], c[1], 0.0]) + norm3([c[0], c[1], 0.0], *p)
        } else {
            norm3(ps, *p)
        };
        worst = worst.max((d[i] - exact).abs() / exact);
    }
    assert!(bent > 200, "{bent} vertices behind the corner");
    assert!(worst <= 1e-9, "max relative error {worst:e}");
    eprintln!("L-shape: {bent} paths bend at the corner, max relative error {worst:e}");
}

#[test]
fn sphere_distances_approach_great_circles() {
    let mesh = icosphere(5); // 10,242 vertices
    let g = ExactGeodesics::new(&mesh).unwrap();
    let sources = [0usize, 1000, 7777];
    let d = g.distances(&sources).unwrap();
    let (mut sum, mut cnt, mut worst, mut below) = (0.0, 0, 0.0f64, 0);
    for (j, &s) in sources.iter().enumerate() {
        let ps = mesh.vertices()[s];
        for (i, p) in mesh.vertices().iter().enumerate() {
            let arc = (ps[0] * p[0] + ps[1] * p[1] + ps[2] * p[2]).clamp(-1.0, 1.0).acos();
            let chord = norm3(ps, *p);
            assert!(d[(i, j)] >= chord * (1.0 - 1e-12), "{s} → {i}: {} shorter than the chord {chord}", d[(i, j)]);
            if arc > 0.1 {
                let rel = (d[(i, j)] - arc) / arc;
                sum += rel.abs();
                worst = worst.max(rel.abs());
                below += (rel < 0.0) as usize;
                cnt += 1;
            }
        }
    }
    let mean = sum / cnt as f64;
    eprintln!("icosphere(5): mean relative error {mean:.2e}, max {worst:.2e}, {below}/{cnt} below the arc");
    assert!(worst < 0.01 && mean < 0.005, "mean {mean}, max {worst}");
}

#[test]
fn distances_are_symmetric_and_between_chord_and_dijkstra() {
    let mesh = bumpy_sphere(4); // 2,562 vertices, saddles in the dents
    let g = ExactGeodesics::new(&mesh).unwrap();
    let saddles = g.topo.bend.iter().filter(|&&b| b).count();
    assert!(saddles > 50, "{saddles} saddle vertices");
    let sources: Vec<usize> = (0..mesh.n_vertices()).step_by(127).collect();
    let d = g.distances(&sources).unwrap();
    let mut worst: f64 = 0.0;
    for (a, &sa) in sources.iter().enumerate() {
        for (b, &sb) in sources.iter().enumerate() {
            let (x, y) = (d[(sb, a)], d[(sa, b)]);
            if a != b {
                worst = worst.max((x - y).abs() / x.max(y));
            }
        }
    }
    eprintln!("bumpy sphere: {saddles} saddles, symmetry max relative difference {worst:e}");
    assert!(worst < 1e-9, "asymmetry {worst:e}");
    let dij = GraphGeodesics::mesh_edges(&mesh).unwrap().distances(&sources).unwrap();
    for (j, &s) in sources.iter().enumerate() {
        for (i, p) in mesh.vertices().iter().enumerate() {
            let chord = norm3(*p, mesh.vertices()[s]);
            assert!(d[(i, j)] >= chord * (1.0 - 1e-12) && d[(i, j)] <= dij[(i, j)] * (1.0 + 1e-12));
        }
    }
}

#[test]
fn early_terminated_pairs_match_full_solves() {
    let mesh = bumpy_sphere(3);
    let g = ExactGeodesics::new(&mesh).unwrap();
    let n = mesh.n_vertices();
    let pairs: Vec<(usize, usize)> =
        (0..200).map(|i| ((i * 37) % n, (i * 91 + 5) % n)).chain([(3, 3), (3, 4)]).collect();
    let got = g.pair_distances(&pairs).unwrap();
    for (&(s, t), &x) in pairs.iter().zip(&got) {
        let full = g.distances_from_vertex(s).unwrap()[t];
        assert!((x - full).abs() <= 1e-12 * full, "({s}, {t}): {x} vs {full}");
    }
    assert_eq!(g.distance(3, 3).unwrap(), 0.0);
    // Caps: min(d, cap).
    let caps: Vec<f64> = got.iter().enumerate().map(|(i, &x)| if i % 2 == 0 { 0.5 * x } else { 2.0 * x }).collect();
    let capped = g.pair_distances_capped(&pairs, &caps).unwrap();
    for i in 0..pairs.len() {
        assert!((capped[i] - got[i].min(caps[i])).abs() <= 1e-12 * got[i], "pair {i}");
    }
}

#[test]
fn disconnected_and_unreferenced_vertices_are_infinitely_far() {
    let s = icosphere(2);
    let n = s.n_vertices() as u32;
    let mut v = s.vertices().to_vec();
    v.extend(s.vertices().iter().map(|p| [p[0] + 3.0, p[1], p[2]]));
    v.push([9.0, 9.0, 9.0]); // unreferenced
    let mut f = s.faces().to_vec();
    f.extend(s.faces().iter().map(|t| [t[0] + n, t[1] + n, t[2] + n]));
    let mesh = TriMesh::new(v, f).unwrap();
    let g = ExactGeodesics::new(&mesh).unwrap();
    let d = g.distances_from_vertex(0).unwrap();
    assert!(d[..n as usize].iter().all(|x| x.is_finite()));
    assert!(d[n as usize..].iter().all(|&x| x == f64::INFINITY));
    assert_eq!(g.pair_distances(&[(0, n as usize + 3), (2 * n as usize, 0)]).unwrap(), vec![f64::INFINITY; 2]);
    let lone = g.distances_from_vertex(2 * n as usize).unwrap();
    assert_eq!(lone[2 * n as usize], 0.0);
    assert!(lone.iter().filter(|x| x.is_finite()).count() == 1);
}

#[test]
fn bad_inputs_are_errors() {
    let mesh = icosphere(1);
    let g = ExactGeodesics::new(&mesh).unwrap();
    let n = mesh.n_vertices();
    assert!(g.distances_from_vertex(n).is_err());
    assert!(g.distances(&[0, n]).is_err());
    assert!(g.distance(0, n).is_err());
    assert!(g.pair_distances(&[(n, 0)]).is_err());
    assert!(g.pair_distances_capped(&[(0, 1)], &[1.0, 2.0]).is_err());
    assert!(g.pair_distances_capped(&[(0, 1)], &[f64::NAN]).is_err());
    // A mesh without faces: only the source is reachable.
    let bare = TriMesh::new(vec![[0.0; 3], [1.0, 0.0, 0.0]], vec![]).unwrap();
    let d = ExactGeodesics::new(&bare).unwrap().distances_from_vertex(1).unwrap();
    assert_eq!(d, vec![f64::INFINITY, 0.0]);
}

#[test]
fn degenerate_faces_are_skipped() {
    // A flat strip; one interior edge (a, b) is split at its midpoint m on one side only,
    // leaving the zero-area face (a, m, b) between the two sides, plus a face with a repeated
    // vertex. The slit costs at most a detour through a, m or b.
    let base = rectangle_mesh(10, 6, 3);
    let mut v = base.vertices().to_vec();
    let mut f = base.faces().to_vec();
    // An interior face and its neighbour across the edge opposite its corner 0.
    let t0 = f[60];
    let (a, b) = (t0[1], t0[2]);
    let j = f.iter().position(|t| t != &t0 && t.contains(&a) && t.contains(&b)).unwrap();
    let d_corner = *f[j].iter().find(|&&x| x != a && x != b).unwrap();
    let (pa, pb) = (v[a as usize], v[b as usize]);
    let m = v.len() as u32;
    v.push([(pa[0] + pb[0]) / 2.0, (pa[1] + pb[1]) / 2.0, 0.0]);
    // Replace face j = (b, a, d) (some rotation) by (b, m, d) and (m, a, d) with its orientation.
    let tj = f[j];
    let rot = |t: [u32; 3], x: u32| {
        let k = t.iter().position(|&y| y == x).unwrap();
        [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
    };
    let [_, p, q] = rot(tj, d_corner);
    f[j] = [d_corner, p, m];
    f.push([d_corner, m, q]);
    f.push([a, m, b]); // zero area
    f.push([a, a, b]); // repeated vertex
    let mesh = TriMesh::new(v, f).unwrap();
    let g = ExactGeodesics::new(&mesh).unwrap();
    assert_eq!(g.skipped_faces().len(), 2);
    let h = mesh.mean_edge_length();
    let mut detour: f64 = 0.0;
    for s in [0usize, 33, m as usize] {
        let d = g.distances_from_vertex(s).unwrap();
        let ps = mesh.vertices()[s];
        for (i, p) in mesh.vertices().iter().enumerate() {
            let e = norm3(ps, *p);
            assert!(d[i].is_finite() && d[i] >= e * (1.0 - 1e-12) && d[i] <= e + h, "{s} → {i}: {} vs {e}", d[i]);
            detour = detour.max(d[i] - e);
        }
    }
    eprintln!("degenerate faces: largest detour round the slit {:.3} mean edge lengths", detour / h);
}

#[test]
fn non_manifold_book_unfolds_pages_pairwise() {
    // Three unit-square pages around the spine x = z = 0, y ∈ [0, 1], at angles 0, 2π/3, 4π/3.
    let k = 8u32;
    let mut v: Vec<[f64; 3]> = Vec::new();
    let mut f: Vec<[u32; 3]> = Vec::new();
    let spine: Vec<u32> = (0..=k).collect();
    for j in 0..=k {
        v.push([0.0, j as f64 / k as f64, 0.0]);
    }
    let mut page_ids = vec![];
    for page in 0..3 {
        let th = page as f64 * std::f64::consts::TAU / 3.0;
        let mut ids = vec![vec![0u32; (k + 1) as usize]; (k + 1) as usize];
        for i in 0..=k {
            for j in 0..=k {
                ids[i as usize][j as usize] = if i == 0 {
                    spine[j as usize]
                } else {
                    let u = i as f64 / k as f64;
                    v.push([u * th.cos(), j as f64 / k as f64, u * th.sin()]);
                    (v.len() - 1) as u32
                };
            }
        }
        for i in 0..k as usize {
            for j in 0..k as usize {
                let (a, b, c, d) = (ids[i][j], ids[i + 1][j], ids[i + 1][j + 1], ids[i][j + 1]);
                f.extend([[a, b, c], [a, c, d]]);
            }
        }
        page_ids.push(ids);
    }
    let mesh = TriMesh::new(v, f).unwrap();
    let g = ExactGeodesics::new(&mesh).unwrap();
    let s = page_ids[0][5][2] as usize; // u = 5/8, y = 2/8 on page 0
    let d = g.distances_from_vertex(s).unwrap();
    let mut worst: f64 = 0.0;
    for (page, ids) in page_ids.iter().enumerate() {
        for i in 0..=k as usize {
            for j in 0..=k as usize {
                let (u, y) = (i as f64 / k as f64, j as f64 / k as f64);
                let (u0, y0) = (5.0 / 8.0, 2.0 / 8.0);
                let exact = if page == 0 { (u - u0).hypot(y - y0) } else { (u + u0).hypot(y - y0) };
                let t = ids[i][j] as usize;
                if t != s {
                    worst = worst.max((d[t] - exact).abs() / exact);
                }
            }
        }
    }
    assert!(worst < 1e-9, "max relative error {worst:e}");
    eprintln!("book with three pages: max relative error {worst:e}");
}

#[test]
fn regular_grid_with_collinear_vertices_is_exact() {
    // Rays through rows of collinear vertices: the degenerate case of window splitting.
    let mesh = crate::primitives::rectangle(2.0, 1.0, 40, 20);
    let g = ExactGeodesics::new(&mesh).unwrap();
    let mut worst: f64 = 0.0;
    for s in [0usize, 20, 10 * 41 + 20] {
        let d = g.distances_from_vertex(s).unwrap();
        let ps = mesh.vertices()[s];
        for (i, p) in mesh.vertices().iter().enumerate() {
            if i != s {
                let e = norm3(ps, *p);
                worst = worst.max((d[i] - e).abs() / e);
            }
        }
    }
    eprintln!("regular grid: max relative error {worst:e}");
    assert!(worst <= 1e-9, "max relative error {worst:e}");
}

#[test]
fn bowtie_vertex_joins_two_sheets() {
    // Two unit squares in different planes touching only at the vertex v = (0, 0, 0):
    // a non-manifold vertex, the only way from one sheet to the other.
    let k = 6u32;
    let mut v: Vec<[f64; 3]> = vec![[0.0; 3]];
    let mut f = Vec::new();
    let mut grids = vec![];
    for sheet in 0..2 {
        let mut ids = vec![vec![0u32; (k + 1) as usize]; (k + 1) as usize];
        for i in 0..=k {
            for j in 0..=k {
                ids[i as usize][j as usize] = if i == 0 && j == 0 {
                    0
                } else {
                    let (a, b) = (i as f64 / k as f64, j as f64 / k as f64);
                    v.push(if sheet == 0 { [a, b, 0.0] } else { [-a, 0.0, -b] });
                    (v.len() - 1) as u32
                };
            }
        }
        for i in 0..k as usize {
            for j in 0..k as usize {
                f.extend([
                    [ids[i][j], ids[i + 1][j], ids[i + 1][j + 1]],
                    [ids[i][j], ids[i + 1][j + 1], ids[i][j + 1]],
                ]);
            }
        }
        grids.push(ids);
    }
    let mesh = TriMesh::new(v, f).unwrap();
    let g = ExactGeodesics::new(&mesh).unwrap();
    assert!(g.topo.bend[0]);
    let (s, t) = (grids[0][4][3] as usize, grids[1][5][2] as usize);
    let (ps, pt) = (mesh.vertices()[s], mesh.vertices()[t]);
    let exact = norm3(ps, [0.0; 3]) + norm3([0.0; 3], pt);
    let d = g.distance(s, t).unwrap();
    assert!((d - exact).abs() <= 1e-12 * exact, "{d} vs {exact}");
}

#[test]
fn closed_cones_touching_at_their_apex() {
    // Two closed thin tetrahedra sharing only their apex (total angle there ≈ 2 × 58° < 2π):
    // a non-manifold vertex found by its two fans.
    let mut v = vec![[0.0, 0.0, 0.0]];
    let mut f = Vec::new();
    for side in [1.0, -1.0] {
        let b = v.len() as u32;
        for k in 0..3 {
            let t = k as f64 * std::f64::consts::TAU / 3.0;
            v.push([0.2 * t.cos(), 0.2 * t.sin(), side]);
        }
        f.extend([[0, b, b + 1], [0, b + 1, b + 2], [0, b + 2, b], [b, b + 2, b + 1]]);
    }
    let mesh = TriMesh::new(v, f).unwrap();
    let g = ExactGeodesics::new(&mesh).unwrap();
    assert!(g.topo.bend[0]);
    let (ps, pt) = (mesh.vertices()[1], mesh.vertices()[4]);
    let exact = norm3(ps, [0.0; 3]) + norm3([0.0; 3], pt);
    let d = g.distance(1, 4).unwrap();
    assert!((d - exact).abs() <= 1e-12 * exact, "{d} vs {exact}");
}

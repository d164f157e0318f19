//! Topological checks of a triangle mesh, one function per quantity (as libigl's
//! `unique_simplices`, `is_edge_manifold`, `orientable_patches`): what `funcorr info` reports,
//! since duplicated, finned or flipped faces change the cotangent Laplacian and its spectrum
//! without being an error.

use super::TriMesh;

/// The undirected edges of every face with their direction and face: `(min, max, forward)`,
/// where `forward` is true when the face runs min → max. Edges of repeated vertex indices
/// (`[a, a, b]`) are left out. Sorted by edge.
fn half_edges(faces: &[[u32; 3]]) -> Vec<(u32, u32, bool)> {
    let mut h = Vec::with_capacity(faces.len() * 3);
    for f in faces {
        for c in 0..3 {
            let (a, b) = (f[c], f[(c + 1) % 3]);
            if a != b {
                h.push((a.min(b), a.max(b), a < b));
            }
        }
    }
    h.sort_unstable();
    h
}

/// Runs of equal edges in sorted half-edges: (edge, its half-edges).
fn edge_runs(h: &[(u32, u32, bool)]) -> impl Iterator<Item = ([u32; 2], &[(u32, u32, bool)])> {
    h.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)).map(|run| ([run[0].0, run[0].1], run))
}

impl TriMesh {
    /// Faces that repeat an earlier face: the same three vertices in any order, so an exact copy
    /// or a copy with the opposite orientation. Returns face indices (into [`TriMesh::faces`]),
    /// ascending, every copy after the first of its vertex set; length ≤ n_faces, empty for a
    /// mesh without duplicates.
    pub fn duplicate_faces(&self) -> Vec<usize> {
        let key = |f: &[u32; 3]| {
            let mut k = *f;
            k.sort_unstable();
            k
        };
        let mut order: Vec<usize> = (0..self.faces.len()).collect();
        // Stable: within a vertex set the faces stay in index order, the first is the original.
        order.sort_by_key(|&f| key(&self.faces[f]));
        let mut dup: Vec<usize> =
            order.windows(2).filter(|w| key(&self.faces[w[0]]) == key(&self.faces[w[1]])).map(|w| w[1]).collect();
        dup.sort_unstable();
        dup
    }

    /// Non-manifold edges: edges `[i, j]` (i < j) of more than two faces (a "fin" on a surface,
    /// or a face and its copy). Sorted; length ≤ the number of edges ([`TriMesh::edges`]).
    /// Faces count with multiplicity, so every edge of a duplicated face is one.
    pub fn non_manifold_edges(&self) -> Vec<[u32; 2]> {
        let h = half_edges(&self.faces);
        edge_runs(&h).filter(|(_, run)| run.len() > 2).map(|(e, _)| e).collect()
    }

    /// Inconsistently oriented edges: edges `[i, j]` (i < j) of exactly two faces that both run
    /// i → j (or both j → i), so that the two faces' normals disagree (on a consistently oriented
    /// surface every interior edge is run once each way). Sorted; length ≤ the number of edges.
    /// Empty for an orientable mesh stored consistently; a face flipped inside a surface makes
    /// its three edges inconsistent.
    pub fn inconsistently_oriented_edges(&self) -> Vec<[u32; 2]> {
        let h = half_edges(&self.faces);
        edge_runs(&h).filter(|(_, run)| run.len() == 2 && run[0].2 == run[1].2).map(|(e, _)| e).collect()
    }
}

#[cfg(test)]
mod tests {
    use crate::primitives::icosphere;
    use crate::shape::TriMesh;

    #[test]
    fn duplicates_fins_and_flips_are_found_and_a_clean_sphere_has_none() {
        let s = icosphere(1);
        assert!(s.duplicate_faces().is_empty());
        assert!(s.non_manifold_edges().is_empty());
        assert!(s.inconsistently_oriented_edges().is_empty());
        let (v, f) = (s.vertices().to_vec(), s.faces().to_vec());
        let nf = f.len();

        // A copy and a reversed copy of face 0, a copy of face 3.
        let mut dup = f.clone();
        dup.push(f[0]);
        dup.push([f[0][2], f[0][1], f[0][0]]);
        dup.push(f[3]);
        let m = TriMesh::new(v.clone(), dup).unwrap();
        assert_eq!(m.duplicate_faces(), [nf, nf + 1, nf + 2]);
        // Every edge of faces 0 and 3 is now in 3 or 4 faces.
        assert_eq!(m.non_manifold_edges().len(), 6 - shared_edges(f[0], f[3]));

        // A fin: a new vertex and a triangle on an edge of face 0.
        let mut fv = v.clone();
        fv.push([0.0, 0.0, 3.0]);
        let mut fin = f.clone();
        let apex = (fv.len() - 1) as u32;
        fin.push([f[0][0], f[0][1], apex]);
        let m = TriMesh::new(fv, fin).unwrap();
        let e = [f[0][0].min(f[0][1]), f[0][0].max(f[0][1])];
        assert_eq!(m.non_manifold_edges(), [e]);
        assert!(m.duplicate_faces().is_empty());

        // One face turned over: its three edges.
        let mut flip = f.clone();
        flip[7] = [f[7][1], f[7][0], f[7][2]];
        let m = TriMesh::new(v, flip).unwrap();
        let mut want: Vec<[u32; 2]> =
            (0..3).map(|c| (f[7][c], f[7][(c + 1) % 3])).map(|(a, b)| [a.min(b), a.max(b)]).collect();
        want.sort_unstable();
        assert_eq!(m.inconsistently_oriented_edges(), want);
        assert!(m.non_manifold_edges().is_empty() && m.duplicate_faces().is_empty());
    }

    fn shared_edges(a: [u32; 3], b: [u32; 3]) -> usize {
        let edges = |f: [u32; 3]| (0..3).map(move |c| [f[c].min(f[(c + 1) % 3]), f[c].max(f[(c + 1) % 3])]);
        edges(a).filter(|e| edges(b).any(|g| g == *e)).count()
    }
}

//! Midpoint subdivision of a triangle mesh (`primitives::midpoint_subdivision`), repeated, for
//! the large-shape benchmarks: the surface is unchanged and vertex i of the input stays vertex i,
//! so the data set's ground truth on the coarse vertices still holds.
//!
//! ```sh
//! cargo run --release --example subdivide -- ../shared/data/tosca_hires/david0.off 2 /tmp/david0_x16.off
//! ```

use std::path::Path;

use funcorr::io::{read_mesh, write_mesh, MeshData};
use funcorr::primitives::midpoint_subdivision;
use funcorr::shape::TriMesh;
use funcorr::{Error, Result};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [input, levels, output] = args.as_slice() else {
        return Err(Error::invalid("arguments", "usage: subdivide INPUT.off LEVELS OUTPUT.off"));
    };
    let levels: u32 =
        levels.parse().map_err(|_| Error::invalid("levels", format!("{levels:?} is not a whole number")))?;
    if levels > 6 {
        return Err(Error::invalid("levels", format!("{levels} levels multiply the vertex count by ~4^{levels}")));
    }
    let data = read_mesh(Path::new(input))?;
    let mut mesh = TriMesh::new(data.vertices, data.faces)?;
    for _ in 0..levels {
        mesh = midpoint_subdivision(&mesh)?;
    }
    eprintln!("{input}: {} vertices, {} faces after {levels} levels", mesh.n_vertices(), mesh.n_faces());
    let out = MeshData { vertices: mesh.vertices().to_vec(), faces: mesh.faces().to_vec(), colors: None };
    write_mesh(Path::new(output), &out)
}

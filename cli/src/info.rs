//! `funcorr info`: facts about a shape file.

use std::path::Path;

use funcorr::shape::{Shape, TriMesh};
use funcorr::Result;

pub(crate) fn info(path: &Path, json: bool) -> Result<()> {
    let shape = Shape::load(path)?;
    let mut facts = vec![("file", serde_json::json!(path.display().to_string()))];
    match &shape {
        Shape::Mesh(m) => facts.extend(mesh_facts(m)),
        Shape::Points(p) => facts.extend([
            ("kind", serde_json::json!(if p.dim() == 3 { "point cloud" } else { "feature matrix" })),
            ("vertices", serde_json::json!(p.len())),
            ("dimension", serde_json::json!(p.dim())),
        ]),
    };
    if json {
        let obj: serde_json::Map<String, serde_json::Value> =
            facts.into_iter().map(|(k, v)| (k.to_string(), v)).collect();
        outln!("{}", serde_json::to_string_pretty(&obj).expect("JSON of plain values"));
    } else {
        for (key, value) in facts {
            let text = match value {
                // A path's control characters are escaped (JSON escapes its own).
                serde_json::Value::String(s) => funcorr::error::escape(&s).into_owned(),
                other => other.to_string(),
            };
            outln!("{:<22} {text}", key.replace('_', " "));
        }
    }
    Ok(())
}

/// Facts about a mesh, in display order.
pub(crate) fn mesh_facts(m: &TriMesh) -> Vec<(&'static str, serde_json::Value)> {
    use serde_json::json;
    let (components, _) = m.components();
    let (lo, hi) = m.bounding_box();
    vec![
        ("kind", json!("triangle mesh")),
        ("vertices", json!(m.n_vertices())),
        ("faces", json!(m.n_faces())),
        ("edges", json!(m.edges().len())),
        ("area", json!(m.total_area())),
        ("components", json!(components)),
        ("boundary_loops", json!(m.boundary_loops().len())),
        ("degenerate_faces", json!(m.degenerate_faces().len())),
        ("duplicate_faces", json!(m.duplicate_faces().len())),
        ("non_manifold_edges", json!(m.non_manifold_edges().len())),
        ("inconsistently_oriented_edges", json!(m.inconsistently_oriented_edges().len())),
        ("unreferenced_vertices", json!(m.unreferenced_vertices().len())),
        ("mean_edge_length", json!(m.mean_edge_length())),
        ("bounding_box_min", json!(lo)),
        ("bounding_box_max", json!(hi)),
    ]
}

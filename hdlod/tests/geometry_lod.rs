//! A discrete LOD chain in one GLB (MSFT_lod): every method's chain passes
//! the Khronos glTF validator with zero errors, and the extension lists the
//! coarser levels from the root node in order, with one screen coverage per
//! level.

mod common;

use hdlod::geometry::{Mesh, Method, SimplifyOptions};
use hdlod::io::glb;

fn chain(mesh: &Mesh, method: Method, ratios: &[f64]) -> Vec<Mesh> {
    let n = mesh.triangle_count();
    ratios
        .iter()
        .map(|r| {
            let options = SimplifyOptions {
                max_error: f32::INFINITY,
                target_triangles: Some((r * n as f64).ceil() as usize),
                prune: false,
            };
            method.run(mesh, &options)
        })
        .collect()
}

#[test]
fn lod_chains_pass_the_validator() {
    let Some(mesh) = common::data_mesh("fandisk.obj") else {
        return;
    };
    let ratios = [1.0, 0.5, 0.25, 0.1];
    let coverage = [0.5, 0.25, 0.125, 0.0];
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for method in Method::ALL {
        let mut levels = chain(&mesh, method, &ratios);
        // Normals of any length (as in horse.ply) must come out unit; a
        // zero normal becomes the normal of a triangle at its vertex (the
        // validator checks that every normal written is unit length).
        for k in [1, 2] {
            let l = &mut levels[k];
            l.normals = l
                .positions
                .iter()
                .map(|p| *p * 3.0 + glam::Vec3::X)
                .collect();
        }
        levels[2].normals[0] = glam::Vec3::ZERO;
        for pair in levels.windows(2) {
            assert!(pair[1].triangle_count() < pair[0].triangle_count());
        }
        let path = dir.path().join(format!("{}.glb", method.name()));
        glb::write_lod(&levels, &coverage, &path).unwrap();

        let bytes = std::fs::read(&path).unwrap();
        let json: serde_json::Value =
            serde_json::from_slice(&gltf::binary::Glb::from_slice(&bytes).unwrap().json).unwrap();
        assert_eq!(json["extensionsUsed"], serde_json::json!(["MSFT_lod"]));
        let root = json["scenes"][0]["nodes"][0].as_u64().unwrap() as usize;
        let node = &json["nodes"][root];
        let ids: Vec<usize> = node["extensions"]["MSFT_lod"]["ids"]
            .as_array()
            .unwrap()
            .iter()
            .map(|i| i.as_u64().unwrap() as usize)
            .collect();
        assert_eq!(ids.len(), 3);
        assert_eq!(
            node["extras"]["MSFT_screencoverage"],
            serde_json::json!(coverage)
        );
        // Each id is a node with its own mesh, in decreasing detail.
        let indices = |node: usize| {
            let m = json["nodes"][node]["mesh"].as_u64().unwrap() as usize;
            let a = json["meshes"][m]["primitives"][0]["indices"]
                .as_u64()
                .unwrap() as usize;
            json["accessors"][a]["count"].as_u64().unwrap() / 3
        };
        let has_normals = |node: usize| {
            let m = json["nodes"][node]["mesh"].as_u64().unwrap() as usize;
            json["meshes"][m]["primitives"][0]["attributes"]
                .get("NORMAL")
                .is_some()
        };
        assert!(has_normals(ids[0]) && has_normals(ids[1]));
        let counts: Vec<u64> = std::iter::once(root).chain(ids).map(indices).collect();
        let expected: Vec<u64> = levels.iter().map(|l| l.triangle_count() as u64).collect();
        assert_eq!(counts, expected);
        files.push(path);
    }
    common::assert_no_gltf_errors(&files);
}

#[test]
fn bad_chains_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.glb");
    let mesh = common::unit_box();
    let e = glb::write_lod(std::slice::from_ref(&mesh), &[0.5, 0.1], &path).unwrap_err();
    assert!(e.to_string().contains("bad.glb"), "{e}");
    let e = glb::write_lod(&[mesh, Mesh::default()], &[0.5, 0.0], &path).unwrap_err();
    assert!(e.to_string().contains("level 1"), "{e}");
    assert!(!path.exists());
}

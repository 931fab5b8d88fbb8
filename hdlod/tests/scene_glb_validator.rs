//! The GLB files we write pass the Khronos glTF validator with zero errors.
//! The validator is the npm package `gltf-validator`, installed into
//! `tools/` by `scripts/test`.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{coloured_tetra, sample_scene, unit_box};
use hdlod::io::glb;
use hdlod::scene::format::save;

fn tools() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools")
}

/// Runs the validator on `files` and returns its reports.
fn validate(files: &[PathBuf]) -> Vec<serde_json::Value> {
    let tools = tools();
    assert!(
        tools.join("node_modules/gltf-validator").is_dir(),
        "the glTF validator is not installed in {}: run scripts/test (it runs `npm ci --prefix tools`)",
        tools.display()
    );
    let out = Command::new("node")
        .arg(tools.join("validate-gltf.js"))
        .args(files)
        .output()
        .expect("node runs (scripts/test needs Node.js for the glTF validator)");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code() != Some(2), "validator failed: {stderr}");
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("report: {e}; {stderr}"))
}

#[test]
fn written_glbs_have_zero_validator_errors() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("box.glb");
    let coloured = dir.path().join("tetra.glb");
    glb::write_mesh(&unit_box(), &plain).unwrap();
    glb::write_mesh(&coloured_tetra(), &coloured).unwrap();
    let scene_dir = dir.path().join("scene");
    save(&sample_scene(), &scene_dir).unwrap();
    let files = [plain, coloured, scene_dir.join("sample.glb")];
    let reports = validate(&files);
    assert_eq!(reports.len(), files.len());
    for (file, report) in files.iter().zip(&reports) {
        let issues = &report["issues"];
        assert_eq!(
            issues["numErrors"],
            0,
            "{}: {}",
            file.display(),
            serde_json::to_string_pretty(&issues["messages"]).unwrap()
        );
        assert_eq!(issues["numWarnings"], 0, "{}: {issues}", file.display());
        // Each file really was read: the validator saw its meshes.
        assert!(
            report["info"]["drawCallCount"].as_u64().unwrap() >= 1,
            "{report}"
        );
    }
    // The scene GLB: one primitive per (mesh, colour) pair, 3 for 4 objects.
    let scene = &reports[2]["info"];
    assert_eq!(scene["drawCallCount"], 3, "{scene}");
    assert_eq!(scene["materialCount"], 3, "{scene}");
}

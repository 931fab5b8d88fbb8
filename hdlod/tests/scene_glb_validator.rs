//! The GLB files we write pass the Khronos glTF validator with zero errors.
//! The validator is the npm package `gltf-validator`, installed into
//! `tools/` by `scripts/test`.

mod common;

use common::{assert_no_gltf_errors, coloured_tetra, saved_sample, unit_box};
use hdlod::io::glb;

#[test]
fn written_glbs_have_zero_validator_errors() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("box.glb");
    let coloured = dir.path().join("tetra.glb");
    glb::write_mesh(&unit_box(), &plain).unwrap();
    glb::write_mesh(&coloured_tetra(), &coloured).unwrap();
    let scene_dir = saved_sample(dir.path());
    let files = [plain, coloured, scene_dir.join("sample.glb")];
    let reports = assert_no_gltf_errors(&files);
    for (file, report) in files.iter().zip(&reports) {
        let issues = &report["issues"];
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

//! Round trips of the scene format and the GLB writer/reader.

mod common;

use std::path::Path;

use common::{sample_scene, saved_sample, unit_box};
use hdlod::io::{glb, gltf};
use hdlod::scene::format::{load, save};

#[test]
fn scene_round_trip_keeps_everything() {
    let dir = tempfile::tempdir().unwrap();
    let out = saved_sample(dir.path());
    let scene = sample_scene();
    assert!(out.join("scene.json").is_file());
    assert!(out.join("sample.glb").is_file());
    let back = load(&out).unwrap();
    assert_eq!(back, scene);
    // The same through the scene.json path.
    assert_eq!(load(&out.join("scene.json")).unwrap(), scene);
}

#[test]
fn instancing_survives_the_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let out = saved_sample(dir.path());
    let scene = sample_scene();
    let back = load(&out).unwrap();
    // Two objects share mesh 0 with different colours: still one mesh.
    assert_eq!(back.meshes.len(), scene.meshes.len());
    assert_eq!(back.objects[0].mesh, back.objects[1].mesh);
    assert_ne!(back.objects[0].color, back.objects[1].color);
}

#[test]
fn saving_again_replaces_the_directory() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    let mut scene = sample_scene();
    save(&scene, &out).unwrap();
    std::fs::write(out.join("stale.txt"), "x").unwrap();
    scene.name = "renamed".into();
    save(&scene, &out).unwrap();
    assert!(!out.join("stale.txt").exists());
    assert!(!out.join("sample.glb").exists());
    assert_eq!(load(&out).unwrap().name, "renamed");
    let entries: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(entries.len(), 1, "no temporary directory is left behind");
}

#[test]
fn mesh_glb_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.glb");
    let mesh = unit_box();
    glb::write_mesh(&mesh, &path).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), glb::mesh_to_glb(&mesh));
    assert_eq!(gltf::read_mesh(&path).unwrap(), mesh);
}

#[test]
fn read_mesh_flattens_nodes_with_their_transforms() {
    let dir = tempfile::tempdir().unwrap();
    let out = saved_sample(dir.path());
    let scene = sample_scene();
    let flat = gltf::read_mesh(&out.join("sample.glb")).unwrap();
    let triangles: usize = scene
        .objects
        .iter()
        .map(|o| scene.meshes[o.mesh].triangle_count())
        .sum();
    assert_eq!(flat.triangle_count(), triangles);
    let (lo, hi) = flat.bounds().unwrap();
    let expect = scene
        .objects
        .iter()
        .flat_map(|o| {
            scene.meshes[o.mesh]
                .positions
                .iter()
                .map(|p| o.transform.transform_point3(*p))
        })
        .fold((lo, hi), |(a, b), p| (a.min(p), b.max(p)));
    assert_eq!((lo, hi), expect);
    assert!(
        !flat.colors.is_empty(),
        "differing colours become vertex colours"
    );
}

#[test]
fn write_mesh_rejects_a_bad_mesh_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.glb");
    let mut mesh = unit_box();
    mesh.positions[0].x = f32::NAN;
    let err = glb::write_mesh(&mesh, &path).unwrap_err().to_string();
    assert!(
        err.contains("bad.glb") && err.contains("non-finite"),
        "{err}"
    );
    assert!(!Path::new(&path).exists());
}

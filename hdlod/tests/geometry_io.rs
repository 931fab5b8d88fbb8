//! OBJ and PLY readers, and the reader by extension, on the shared meshes
//! and on bad files.

mod common;

use std::path::Path;

use hdlod::geometry::measure;

#[test]
fn horse_ply_binary() {
    let Some(meshes) = common::data("meshes") else {
        return;
    };
    let m = hdlod::io::ply::read_mesh(&meshes.join("horse.ply")).unwrap();
    assert_eq!((m.positions.len(), m.triangle_count()), (48_485, 96_966));
    assert_eq!(m.normals.len(), m.positions.len());
    m.validate().unwrap();
    assert!(measure::volume(&m).abs() > 0.0);
}

#[test]
fn obj_meshes() {
    let Some(meshes) = common::data("meshes") else {
        return;
    };
    for (name, triangles) in [
        ("stanford-bunny.obj", 69_451),
        ("fandisk.obj", 12_946),
        ("rocker-arm.obj", 20_088),
    ] {
        let m = hdlod::io::obj::read_mesh(&meshes.join(name)).unwrap();
        m.validate().unwrap();
        assert_eq!(m.triangle_count(), triangles, "{name}");
    }
}

#[test]
fn unreadable_and_truncated_files() {
    let e = hdlod::io::obj::read_mesh(Path::new("/nonexistent/x.obj"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("/nonexistent/x.obj"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let binary = dir.path().join("binary.obj");
    std::fs::write(&binary, [0xff, 0xfe, 0x00]).unwrap();
    assert!(
        hdlod::io::obj::read_mesh(&binary)
            .unwrap_err()
            .to_string()
            .contains("binary.obj")
    );
}

#[test]
fn a_truncated_horse_names_the_file_and_the_faces() {
    let Some(meshes) = common::data("meshes") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let cut = dir.path().join("cut.ply");
    let bytes = std::fs::read(meshes.join("horse.ply")).unwrap();
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = hdlod::io::ply::read_mesh(&cut).unwrap_err().to_string();
    assert!(e.contains("cut.ply") && e.contains("face"), "{e}");
}

/// `io::read_mesh` picks the reader by the extension, in any case, and
/// names the file when it knows no reader or the reader fails.
#[test]
fn read_mesh_by_extension() {
    let Some(meshes) = common::data("meshes") else {
        return;
    };
    let data = |name: &str| meshes.join(name);
    let dir = tempfile::tempdir().unwrap();
    let upper = dir.path().join("HORSE.PLY");
    std::fs::copy(data("horse.ply"), &upper).unwrap();
    assert_eq!(
        hdlod::io::read_mesh(&upper).unwrap(),
        hdlod::io::ply::read_mesh(&data("horse.ply")).unwrap()
    );
    assert_eq!(
        hdlod::io::read_mesh(&data("fandisk.obj")).unwrap(),
        hdlod::io::obj::read_mesh(&data("fandisk.obj")).unwrap()
    );
    let stl = dir.path().join("part.stl");
    std::fs::write(&stl, "solid part\nendsolid part\n").unwrap();
    let e = hdlod::io::read_mesh(&stl).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "{}: unknown mesh format \"stl\" (expected .obj, .ply, .glb or .gltf)",
            stl.display()
        )
    );
    let nan = dir.path().join("nan.obj");
    std::fs::write(&nan, "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n").unwrap();
    let e = hdlod::io::read_mesh(&nan).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}: line 3", nan.display())), "{e}");
}

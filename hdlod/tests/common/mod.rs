//! Shared by the tests of the library and of the server: small hand-built
//! scenes, the repository and `shared/data` beside it, JSON Schema checks.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3};
use hdlod::geometry::Mesh;
use hdlod::scene::{
    Instant, Keyframe, Motion, Object, Scene, ScheduleOptions, Task, TaskType, Up, Visibility,
};
use hdlod::time::{TimeSpan, parse_date};

/// A unit cube with flat normals (24 vertices, 12 triangles).
pub fn unit_box() -> Mesh {
    let mut mesh = Mesh::default();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let n = Vec3::from_array(std::array::from_fn(|k| if k == axis { sign } else { 0.0 }));
            let u = Vec3::from_array(std::array::from_fn(|k| {
                if k == (axis + 1) % 3 { 1.0 } else { 0.0 }
            }));
            let v = n.cross(u);
            let base = mesh.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                mesh.positions.push(0.5 * (n + a * u + b * v));
                mesh.normals.push(n);
            }
            mesh.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    mesh
}

/// A tetrahedron with vertex colours and no normals.
pub fn coloured_tetra() -> Mesh {
    Mesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
        normals: vec![],
        colors: vec![
            [1.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0, 1.0],
            [1.0, 1.0, 0.0, 0.5],
        ],
        indices: vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3],
    }
}

fn object(id: &str, mesh: usize, transform: Mat4, color: [f32; 4]) -> Object {
    Object {
        id: id.into(),
        mesh,
        transform,
        color,
        visibility: Visibility::always(),
        motion: None,
        properties: BTreeMap::new(),
    }
}

/// Two instances of one box in different colours, a tetra that moves, a
/// third box with properties; a schedule with whole and fractional times.
pub fn sample_scene() -> Scene {
    let day = 86400.0;
    let mut column = object(
        "C-1",
        0,
        Mat4::from_translation(Vec3::new(1.0, 0.5, 0.0)),
        [0.8, 0.8, 0.8, 1.0],
    );
    column.properties.insert("storey".into(), "L01".into());
    column.properties.insert("ifc".into(), "IfcColumn".into());
    let beam = object(
        "B-1",
        0,
        Mat4::from_scale_rotation_translation(
            Vec3::new(4.0, 0.3, 0.3),
            Quat::from_rotation_y(0.25),
            Vec3::new(2.0, 3.0, 0.0),
        ),
        [0.5, 0.2, 0.1, 1.0],
    );
    let mut truck = object("truck-1", 1, Mat4::IDENTITY, [1.0; 4]);
    truck.motion = Some(
        Motion::new(vec![
            Keyframe {
                t: 0.0,
                translation: Vec3::ZERO,
                rotation: Quat::IDENTITY,
                scale: Vec3::ONE,
            },
            Keyframe {
                t: 2.5 * day,
                translation: Vec3::new(10.0, 0.0, -3.0),
                rotation: Quat::from_xyzw(0.0, 1.0, 0.0, 0.0),
                scale: Vec3::ONE,
            },
        ])
        .unwrap(),
    );
    let scaffold = object(
        "S-1",
        0,
        Mat4::from_translation(Vec3::new(-5.0, 1.0, 2.0)),
        [0.8, 0.8, 0.8, 1.0],
    );
    let mut scene = Scene {
        name: "sample".into(),
        up: Up::Y,
        time: TimeSpan {
            start: parse_date("2025-03-01T00:00:00Z").unwrap(),
            seconds: 10.0 * day,
        },
        meshes: vec![unit_box(), coloured_tetra()],
        objects: vec![column, beam, truck, scaffold],
        tasks: vec![
            Task {
                id: "T1".into(),
                name: "Level 1 columns".into(),
                kind: TaskType::Construct,
                start: day,
                finish: 2.0 * day + 0.25,
                objects: vec!["C-1".into()],
            },
            Task {
                id: "T2".into(),
                name: "Beams".into(),
                kind: TaskType::Construct,
                start: 3.0 * day,
                finish: 4.0 * day,
                objects: vec!["B-1".into()],
            },
            Task {
                id: "T3".into(),
                name: "Scaffolding".into(),
                kind: TaskType::Temporary,
                start: 0.5,
                finish: 6.0 * day,
                objects: vec!["S-1".into()],
            },
        ],
        schedule_options: ScheduleOptions {
            construct_at: Instant::Finish,
            demolish_at: Instant::Start,
        },
    };
    scene.apply_schedule();
    scene
}

/// [`sample_scene`] saved in `dir/sample`; returns that directory.
pub fn saved_sample(dir: &Path) -> PathBuf {
    let out = dir.join("sample");
    hdlod::scene::format::save(&sample_scene(), &out).unwrap();
    out
}

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .unwrap()
}

/// `shared/data/SUB` beside the repository: in the directory that holds it,
/// or in the nearest ancestor that has one.
pub fn shared_data(sub: &str) -> PathBuf {
    let repo = repo();
    repo.ancestors()
        .skip(1)
        .map(|a| a.join("shared/data").join(sub))
        .find(|d| d.exists())
        .unwrap_or_else(|| panic!("no shared/data/{sub} beside {}", repo.display()))
}

/// One of the classic meshes in `shared/data/meshes` (OBJ or PLY).
pub fn shared_mesh(name: &str) -> Mesh {
    hdlod::io::read_mesh(&shared_data("meshes").join(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// The first errors of `value` against `v`, each with where it is.
pub fn schema_errors(v: &jsonschema::Validator, value: &serde_json::Value) -> Vec<String> {
    v.iter_errors(value)
        .take(5)
        .map(|e| format!("{}: {e}", e.instance_path()))
        .collect()
}

/// Asserts that `value` follows `v`; `what` names it in the failure.
pub fn assert_valid(v: &jsonschema::Validator, value: &serde_json::Value, what: &str) {
    let errors = schema_errors(v, value);
    assert!(errors.is_empty(), "{what}: {errors:?}");
}

/// The validator of `schemas/NAME` of the repository.
pub fn schema(name: &str) -> jsonschema::Validator {
    let path = repo().join("schemas").join(name);
    let schema: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    jsonschema::validator_for(&schema).unwrap()
}

/// Asserts that `value` follows `schemas/NAME` of the repository.
pub fn assert_matches_schema(value: &serde_json::Value, name: &str) {
    assert_valid(&schema(name), value, name);
}

/// The official 3D Tiles 1.1 `tileset.schema.json` from
/// `shared/data/3d-tiles-schema`; its relative `$ref`s resolve as files next
/// to it.
pub fn tileset_validator() -> jsonschema::Validator {
    let path = shared_data("3d-tiles-schema").join("tileset.schema.json");
    let schema: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    jsonschema::options()
        .with_base_uri(format!("file://{}", path.display()))
        .build(&schema)
        .expect("the official 3D Tiles schemas compile")
}

/// The Khronos glTF validator's reports on `files`, in order
/// (`tools/validate-gltf.js`, installed by `npm ci --prefix tools`).
pub fn gltf_reports(files: &[PathBuf]) -> Vec<serde_json::Value> {
    let tools = repo().join("tools");
    assert!(
        tools.join("node_modules/gltf-validator").is_dir(),
        "the glTF validator is not installed in {}: run scripts/test (it runs `npm ci --prefix tools`)",
        tools.display()
    );
    let out = std::process::Command::new("node")
        .arg(tools.join("validate-gltf.js"))
        .args(files)
        .output()
        .expect("node runs (scripts/test needs Node.js for the glTF validator)");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code() != Some(2), "validator failed: {stderr}");
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("report: {e}; {stderr}"))
}

/// The validator's reports on `files`, in order, after asserting that each
/// file was reported on and has no error.
pub fn assert_no_gltf_errors(files: &[PathBuf]) -> Vec<serde_json::Value> {
    let reports = gltf_reports(files);
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
    }
    reports
}

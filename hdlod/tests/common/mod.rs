//! Shared by the tests of the library and of the server: small hand-built
//! scenes, the repository, the test data (`shared/data` beside the
//! repository, or `$HDLOD_DATA`) or a loud skip, JSON Schema checks.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3};
use hdlod::geometry::Mesh;
use hdlod::geometry::skin::Skin;
use hdlod::scene::appearance::Look;
use hdlod::scene::{
    Actual, Geographic, Georeference, Instant, Joint, Keyframe, LinkType, Motion, Object,
    ObjectSkin, Predecessor, Profile, Scene, ScheduleOptions, Span, Task, TaskType, Up, Visibility,
};
use hdlod::time::{TimeSpan, parse_date};

/// A unit cube about the origin with flat normals (24 vertices, 12
/// triangles).
pub fn unit_box() -> Mesh {
    Mesh::cuboid(Vec3::splat(-0.5), Vec3::splat(0.5), 1)
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
        ..Mesh::default()
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
        skin: None,
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
            Task::planned(
                "T1",
                "Level 1 columns",
                TaskType::Construct,
                day,
                2.0 * day + 0.25,
                vec!["C-1".into()],
            ),
            // The beams started a day late and run on; an earlier plan
            // had them a day sooner; they belong to the columns' work.
            Task {
                actual: Actual {
                    start: Some(4.0 * day),
                    finish: None,
                },
                baseline: Some(Span {
                    start: 2.0 * day,
                    finish: 3.0 * day,
                }),
                parent: Some("T1".into()),
                ..Task::planned(
                    "T2",
                    "Beams",
                    TaskType::Construct,
                    3.0 * day,
                    4.0 * day,
                    vec!["B-1".into()],
                )
            },
            // The scaffold stands from the start; it is struck a day
            // after the beams are done.
            Task {
                predecessors: vec![Predecessor {
                    task: "T2".into(),
                    kind: LinkType::FinishFinish,
                    lag: day,
                }],
                ..Task::planned(
                    "T3",
                    "Scaffolding",
                    TaskType::Temporary,
                    0.5,
                    6.0 * day,
                    vec!["S-1".into()],
                )
            },
        ],
        schedule_options: ScheduleOptions {
            construct_at: Instant::Finish,
            demolish_at: Instant::Start,
            ..ScheduleOptions::default()
        },
        appearance: Some(sample_profile()),
        georeference: Some(Georeference::Geographic(Geographic {
            latitude: 51.9225,
            longitude: 4.4792,
            height: 2.0,
            heading: 30.0,
        })),
    };
    scene.tasks[0].actual = Actual {
        start: Some(day),
        finish: Some(2.0 * day),
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

/// A square tube along Y from 0 to 4 in rings every 0.25 m: below 1.5 m
/// on joint 0 (at the origin), above 2.5 m on joint 1 (at y = 2), blended
/// between. Joint 1 turns a quarter about X from 10 s to 20 s.
pub fn skinned_bar() -> (Mesh, ObjectSkin) {
    let mut mesh = Mesh::default();
    let mut vertices = Skin {
        joints: Vec::new(),
        weights: Vec::new(),
    };
    const RINGS: u32 = 17;
    for r in 0..RINGS {
        let y = 0.25 * r as f32;
        let top = ((y - 1.5) / 1.0).clamp(0.0, 1.0);
        for (x, z) in [(0.2, 0.2), (-0.2, 0.2), (-0.2, -0.2), (0.2, -0.2)] {
            mesh.positions.push(Vec3::new(x, y, z));
            vertices.joints.push([0, 1, 0, 0]);
            vertices.weights.push([1.0 - top, top, 0.0, 0.0]);
        }
    }
    for r in 0..RINGS - 1 {
        for k in 0..4 {
            let at = |r: u32, k: u32| r * 4 + k % 4;
            let (a, b, c, d) = (at(r, k), at(r, k + 1), at(r + 1, k), at(r + 1, k + 1));
            mesh.indices.extend([a, c, b, b, c, d]);
        }
    }
    let turn = |t: f64, angle: f32| Keyframe {
        t,
        translation: Vec3::Y * 2.0,
        rotation: Quat::from_rotation_x(angle),
        scale: Vec3::ONE,
    };
    let skin = ObjectSkin {
        vertices,
        inverse_bind: vec![Mat4::IDENTITY, Mat4::from_translation(-Vec3::Y * 2.0)],
        joints: vec![
            Joint {
                name: Some("base".into()),
                transform: Mat4::IDENTITY,
                motion: None,
            },
            Joint {
                name: Some("middle".into()),
                transform: Mat4::from_translation(Vec3::Y * 2.0),
                motion: Some(
                    Motion::new(vec![
                        turn(10.0, 0.0),
                        turn(20.0, std::f32::consts::FRAC_PI_2),
                    ])
                    .unwrap(),
                ),
            },
        ],
    };
    (mesh, skin)
}

/// The scene `bar` of 100 s: [`skinned_bar`] (object 0, mesh 1) and a
/// static unit box 3 m aside (object 1, mesh 0).
pub fn skinned_bar_scene() -> Scene {
    let (mesh, skin) = skinned_bar();
    let object = |id: &str, mesh: usize, transform: Mat4| Object {
        id: id.into(),
        mesh,
        transform,
        color: [0.6, 0.6, 0.6, 1.0],
        visibility: Visibility::always(),
        motion: None,
        skin: None,
        properties: Default::default(),
    };
    let mut bar = object("bar", 1, Mat4::IDENTITY);
    bar.skin = Some(Box::new(skin));
    let cube = Mesh {
        positions: (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
            .collect(),
        indices: vec![
            0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4,
            6, 1, 3, 5, 3, 7, 5,
        ],
        ..Mesh::default()
    };
    Scene {
        name: "bar".into(),
        up: Up::Y,
        time: TimeSpan {
            start: parse_date("2026-03-02T08:00:00Z").unwrap(),
            seconds: 100.0,
        },
        meshes: vec![cube, mesh],
        objects: vec![
            bar,
            object("box", 0, Mat4::from_translation(Vec3::new(-3.0, 0.0, 0.0))),
        ],
        tasks: Vec::new(),
        schedule_options: ScheduleOptions::default(),
        appearance: None,
        georeference: None,
    }
}

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .unwrap()
}

/// The data sets the tests read, none of them in the repository: what each
/// holds and where to get it (`shared/data/README.md` beside the
/// repository describes them in full).
const DATA_SETS: [(&str, &str); 3] = [
    (
        "meshes",
        "the classic meshes stanford-bunny.obj, horse.ply, fandisk.obj, rocker-arm.obj \
         from the folder data/ of github.com/alecjacobson/common-3d-test-models",
    ),
    (
        "schependomlaan",
        "the Schependomlaan building, CC BY 4.0, from github.com/SvSchaijk/DataSetSchependomlaan: \
         into ifc/ the twelve ROOT-*.ifczip of 'Coordination model and subcontractors \
         models/BIMsight Projectdata1/' except ROOT-Compleet, a space in a name made _; \
         as planning.xml 'Planning/XML/Uitvoering Schependomlaan 18-02-2015.xml'; as \
         eventlog-as-planned.csv and eventlog-as-built.csv its event logs 'eventlog IFC \
         schependomlaan.csv' and 'Schependomlaan eventlog as planned data incl as built data.csv'",
    ),
    (
        "3d-tiles-schema",
        "the 3D Tiles 1.1 JSON schemas (tileset.schema.json and the files it refers to) \
         from the folder specification/schema/ of github.com/CesiumGS/3d-tiles",
    ),
];

/// Where the data sets are: `$HDLOD_DATA`, else `shared/data` beside the
/// repository.
fn data_root() -> PathBuf {
    match std::env::var_os("HDLOD_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => repo()
            .parent()
            .expect("the repository has a parent")
            .join("shared/data"),
    }
}

/// The directory of the data set `set` (a name of [`DATA_SETS`]), or `None`
/// after one line on stderr that says which test is skipped, what is
/// missing and where to get it; with `HDLOD_REQUIRE_DATA=1` a missing set
/// fails the test instead. Read as
/// `let Some(dir) = common::data("meshes") else { return };`.
pub fn data(set: &str) -> Option<PathBuf> {
    let (_, what) = DATA_SETS
        .iter()
        .find(|(name, _)| *name == set)
        .unwrap_or_else(|| panic!("no data set {set:?}"));
    let dir = data_root().join(set);
    if dir.is_dir() {
        return Some(dir);
    }
    let thread = std::thread::current();
    let test = format!(
        "{}::{}",
        env!("CARGO_CRATE_NAME"),
        thread.name().unwrap_or("?")
    );
    let missing = format!(
        "{test}: needs {} ({what}; HDLOD_DATA=DIR reads DIR/{set} instead)",
        dir.display()
    );
    assert!(
        std::env::var("HDLOD_REQUIRE_DATA").as_deref() != Ok("1"),
        "HDLOD_REQUIRE_DATA=1 but {missing}"
    );
    // Straight to stderr, in one write: the test harness captures
    // `eprintln!` of tests that pass, and a skip must be seen whole.
    let line = format!("SKIPPED {missing}\n");
    let _ = std::io::stderr().write_all(line.as_bytes());
    None
}

/// One of the classic meshes of the data set `meshes` (OBJ or PLY), or
/// `None` when the set is missing (see [`data`]).
pub fn data_mesh(name: &str) -> Option<Mesh> {
    let path = data("meshes")?.join(name);
    Some(hdlod::io::read_mesh(&path).unwrap_or_else(|e| panic!("{e}")))
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

/// The sample scene's appearance profile: late work red, the rest default.
pub fn sample_profile() -> Profile {
    let mut profile = Profile {
        name: "sample review".into(),
        ..Profile::default()
    };
    profile.types[TaskType::Construct.index()].late = Some(Look::Colour {
        rgb: [255, 0, 0],
        transparency: 0.0,
    });
    profile
}

/// The validator of `schemas/NAME` of the repository; the schemas it
/// refers to by relative name are read from the same folder.
pub fn schema(name: &str) -> jsonschema::Validator {
    let path = repo().join("schemas").join(name);
    let schema: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    jsonschema::options()
        .with_retriever(SchemaFolder)
        .build(&schema)
        .unwrap()
}

/// Resolves a schema's `$id` (`https://hdlod.example/schemas/NAME`, or
/// another of the placeholder hosts the files use) to `schemas/NAME`.
struct SchemaFolder;

impl jsonschema::Retrieve for SchemaFolder {
    fn retrieve(
        &self,
        uri: &jsonschema::Uri<String>,
    ) -> Result<serde_json::Value, Box<dyn std::error::Error + Send + Sync>> {
        let name = ["hdlod.example", "hdlod.invalid", "hdlod.dev"]
            .iter()
            .find_map(|host| {
                uri.as_str()
                    .strip_prefix(&format!("https://{host}/schemas/"))
            })
            .ok_or_else(|| format!("{uri} is not one of our schemas"))?;
        let text = std::fs::read_to_string(repo().join("schemas").join(name))?;
        Ok(serde_json::from_str(&text)?)
    }
}

/// Asserts that `value` follows `schemas/NAME` of the repository.
pub fn assert_matches_schema(value: &serde_json::Value, name: &str) {
    assert_valid(&schema(name), value, name);
}

/// The official 3D Tiles 1.1 `tileset.schema.json` of the data set
/// `3d-tiles-schema` (its relative `$ref`s resolve as files next to it), or
/// `None` when the set is missing (see [`data`]).
pub fn tileset_validator() -> Option<jsonschema::Validator> {
    let path = data("3d-tiles-schema")?.join("tileset.schema.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let schema: serde_json::Value = serde_json::from_str(&text).unwrap();
    let validator = jsonschema::options()
        .with_base_uri(format!("file://{}", path.display()))
        .build(&schema)
        .expect("the official 3D Tiles schemas compile");
    Some(validator)
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

/// The geometry files of the tree in `dir`, sorted: those in `geometry/`
/// and in its shard directories (through a link to a shared store).
pub fn geometry_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir.join("geometry")).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            for file in std::fs::read_dir(&path).unwrap() {
                files.push(file.unwrap().path());
            }
        } else {
            files.push(path);
        }
    }
    files.sort();
    files
}

/// Lays the tree in `dir` out as the previous format, `hdlod-tree/1`:
/// each geometry file moved out of its shard into `geometry/`, the shards
/// removed, the manifest's format `"hdlod-tree/1"`.
pub fn flatten_tree(dir: &Path) {
    let geometry = dir.join("geometry");
    for entry in std::fs::read_dir(&geometry).unwrap() {
        let shard = entry.unwrap().path();
        if !shard.is_dir() {
            continue;
        }
        for file in std::fs::read_dir(&shard).unwrap() {
            let file = file.unwrap().path();
            std::fs::rename(&file, geometry.join(file.file_name().unwrap())).unwrap();
        }
        std::fs::remove_dir(&shard).unwrap();
    }
    let path = dir.join("manifest.json");
    let mut manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    manifest["format"] = "hdlod-tree/1".into();
    std::fs::write(&path, serde_json::to_vec_pretty(&manifest).unwrap()).unwrap();
}

/// The manifest of the tree in `dir`, checked against its schema.
pub fn checked_manifest(dir: &Path) -> serde_json::Value {
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    assert_matches_schema(&manifest, "tree-manifest.schema.json");
    manifest
}

/// The leaf clusters below cluster `id` of `tree` (itself, if a leaf).
pub fn leaves_below(tree: &hdlod::tree::Tree, id: u32) -> Vec<u32> {
    let c = tree.cluster(id);
    if c.is_leaf() {
        return vec![id];
    }
    c.children
        .iter()
        .flat_map(|&k| leaves_below(tree, k))
        .collect()
}

/// Checks that the geometry of cluster `c` of the tree at `dir` lies within
/// its `eps` of the objects of `scene` below it, measured to 1% of it.
pub fn assert_eps_bound(
    tree: &hdlod::tree::Tree,
    dir: &Path,
    scene: &Scene,
    c: &hdlod::tree::Cluster,
) {
    let file = tree.geometry_file(dir, c.geometry.as_ref().expect("geometry"));
    let geometry = hdlod::io::gltf::read_mesh(&file).expect("cluster geometry reads");
    let union = objects_below(tree, scene, c.id);
    let h = hdlod::geometry::hausdorff(
        &geometry,
        &union,
        &hdlod::geometry::HausdorffOptions {
            tolerance: (c.eps * 0.01).max(1e-4) as f32,
            seed: 1,
        },
    );
    assert!(
        f64::from(h.lower) <= c.eps + 1e-4,
        "cluster {} (level {}): distance {} to its objects above its eps {}",
        c.id,
        c.level,
        h.lower,
        c.eps
    );
}

/// The original objects of `scene` below cluster `id` of `tree`, merged,
/// each placed where it is at a time its leaf shows it (a moving object's
/// resting part at its held pose): what the cluster's `eps` bounds the
/// distance to.
pub fn objects_below(tree: &hdlod::tree::Tree, scene: &Scene, id: u32) -> Mesh {
    let objects: std::collections::HashMap<&str, &Object> =
        scene.objects.iter().map(|o| (o.id.as_str(), o)).collect();
    let leaves: Vec<(usize, Mat4, [f32; 4])> = leaves_below(tree, id)
        .iter()
        .map(|&l| {
            let leaf = tree.cluster(l);
            let o = objects[leaf.objects[0].as_str()];
            let shown = leaf
                .visibility
                .steps()
                .iter()
                .find(|s| s.1 > 0.0)
                .unwrap()
                .0;
            (o.mesh, o.pose(shown), o.color)
        })
        .collect();
    let parts: Vec<hdlod::geometry::Part> = leaves
        .iter()
        .map(|&(mesh, transform, color)| hdlod::geometry::Part {
            mesh: &scene.meshes[mesh],
            transform,
            color,
            feature: None,
        })
        .collect();
    hdlod::geometry::merge(&parts, 0.0)
}

/// Asserts that every cluster's `v_c` and `gamma_c` are what its children
/// and the leaves below it make of them now, within the rounding of the
/// stored values, however the tree was made or updated: `v_c` the
/// `w`-weighted mean of the children's, simplified to `config.max_steps`,
/// `gamma_c` its largest L1 distance to a leaf below, over the period.
pub fn assert_visibility_follows_children(
    tree: &hdlod::tree::Tree,
    config: &hdlod::build::BuildConfig,
) {
    use hdlod::build::StepFunction;
    use hdlod::tree::ClusterClass;
    let span = tree.time.seconds;
    let clusters: Vec<hdlod::tree::Cluster> = tree.clusters().map(|c| c.into_owned()).collect();
    let steps: Vec<StepFunction> = clusters
        .iter()
        .map(|c| StepFunction::from_tree(&c.visibility))
        .collect();
    // Children come before parents: each cluster's leaves from its
    // children's.
    let mut leaves: Vec<Vec<u32>> = Vec::with_capacity(clusters.len());
    let mut checked = 0;
    for c in &clusters {
        let mut below: Vec<u32> = c
            .children
            .iter()
            .flat_map(|&k| leaves[k as usize].iter().copied())
            .collect();
        if c.children.is_empty() {
            below.push(c.id);
        }
        below.sort_unstable();
        below.dedup();
        let at = |what: &str, got: f64, want: f64| {
            assert!(
                (got - want).abs() <= 1e-6,
                "cluster {} ({:?}, level {}): {what} {got} where its children make {want}",
                c.id,
                c.class,
                c.level
            );
        };
        if c.class != ClusterClass::Root && c.children.len() > 1 {
            let parts: Vec<(f64, &StepFunction)> = c
                .children
                .iter()
                .map(|&k| (clusters[k as usize].w.max(1e-9), &steps[k as usize]))
                .collect();
            let want = StepFunction::weighted_mean(&parts).simplified(config.max_steps, span);
            let own = &steps[c.id as usize];
            at("v_c", own.l1_distance(&want, span) / span, 0.0);
            let gamma = below
                .iter()
                .map(|&l| own.l1_distance(&steps[l as usize], span) / span)
                .fold(0.0, f64::max);
            at("gamma_c", c.gamma, gamma);
            checked += 1;
        } else if c.children.len() == 1 {
            let child = &clusters[c.children[0] as usize];
            assert_eq!(c.visibility, child.visibility, "lone cluster {}", c.id);
            at("gamma_c", c.gamma, child.gamma);
        }
        leaves.push(below);
    }
    assert!(checked > 0, "no group to check");
}

//! A skinned object in a build: a leg (a cylinder of rings around a
//! hip and a knee, as in `scene_skins.rs`, finer) whose knee bends and
//! hip swings, beside static boxes. Its chain is reduced and measured over
//! sampled poses, its box holds it in every pose, the tree keeps its
//! joints and the cut poses its clusters with them.

mod common;

use std::path::Path;

use glam::{DVec3, Mat4, Vec3};
use hdlod::build::{BuildConfig, Silent, build_to};
use hdlod::geometry::skin::Skin;
use hdlod::geometry::{HausdorffOptions, Mesh, hausdorff};
use hdlod::scene::{
    Joint, Keyframe, Motion, Object, ObjectSkin, Scene, ScheduleOptions, Up, Visibility,
};
use hdlod::time::{TimeSpan, parse_date};
use hdlod::tree::{CameraSpec, ClusterClass, Tree, View, Viewport, load};

const RINGS: usize = 33;
const SIDES: usize = 24;
const RADIUS: f32 = 0.2;
/// The leg stands here, its foot at y = 0, its hip at y = 2.
const ROOT: Vec3 = Vec3::new(1.0, 0.0, 0.0);
/// The bend: from the bind pose at `BEND.0` to a right-angled knee and a
/// hip swung 30 degrees at `BEND.1`.
const BEND: (f64, f64) = (10.0, 20.0);
const SPAN: f64 = 100.0;

/// The leg's mesh and its skin over the hip (joint 0) and the knee
/// (joint 1): rings below 0.75 m on the knee, above 1.25 m on the hip,
/// blended between.
fn leg() -> (Mesh, Skin) {
    let mut mesh = Mesh::default();
    let mut skin = Skin {
        joints: Vec::new(),
        weights: Vec::new(),
    };
    for r in 0..RINGS {
        let y = 2.0 * r as f32 / (RINGS - 1) as f32;
        let hip = ((y - 0.75) / 0.5).clamp(0.0, 1.0);
        for k in 0..SIDES {
            let a = std::f32::consts::TAU * k as f32 / SIDES as f32;
            mesh.positions
                .push(ROOT + Vec3::new(RADIUS * a.cos(), y, RADIUS * a.sin()));
            skin.joints.push([0, 1, 0, 0]);
            skin.weights.push([hip, 1.0 - hip, 0.0, 0.0]);
        }
    }
    for r in 0..RINGS - 1 {
        for k in 0..SIDES {
            let at = |r: usize, k: usize| (r * SIDES + k % SIDES) as u32;
            let (a, b, c, d) = (at(r, k), at(r, k + 1), at(r + 1, k), at(r + 1, k + 1));
            mesh.indices.extend([a, c, b, b, c, d]);
        }
    }
    (mesh, skin)
}

/// The joints' world transforms: the hip at (1, 2, 0) turned about Z by
/// `hip`, the knee 1 m below it along the turned leg, turned about X by
/// `knee` after the hip.
fn joint_poses(hip: f32, knee: f32) -> [Mat4; 2] {
    let hip_world = Mat4::from_translation(ROOT + Vec3::Y * 2.0) * Mat4::from_rotation_z(hip);
    let knee_world = hip_world * Mat4::from_translation(-Vec3::Y) * Mat4::from_rotation_x(knee);
    [hip_world, knee_world]
}

/// The leg's skin: keyframes of both joints at five times over the bend
/// (held before and after).
fn leg_skin(skin: Skin) -> ObjectSkin {
    let keys: Vec<(f64, [Mat4; 2])> = (0..5)
        .map(|k| {
            let s = k as f32 / 4.0;
            let t = BEND.0 + (BEND.1 - BEND.0) * f64::from(s);
            (
                t,
                joint_poses(s * 30f32.to_radians(), s * std::f32::consts::FRAC_PI_2),
            )
        })
        .collect();
    let joint = |j: usize, name: &str| Joint {
        name: Some(name.into()),
        transform: keys[0].1[j],
        motion: Some(
            Motion::new(
                keys.iter()
                    .map(|(t, m)| Keyframe::of_matrix(*t, &m[j]))
                    .collect(),
            )
            .unwrap(),
        ),
    };
    let bind = joint_poses(0.0, 0.0);
    ObjectSkin {
        vertices: skin,
        inverse_bind: vec![bind[0].inverse(), bind[1].inverse()],
        joints: vec![joint(0, "hip"), joint(1, "knee")],
    }
}

fn object(id: &str, mesh: usize, transform: Mat4) -> Object {
    Object {
        id: id.into(),
        mesh,
        transform,
        color: [0.7, 0.7, 0.7, 1.0],
        visibility: Visibility::always(),
        motion: None,
        skin: None,
        properties: Default::default(),
    }
}

fn scene() -> Scene {
    let (mesh, skin) = leg();
    let mut leg = object("leg", 1, Mat4::IDENTITY);
    leg.skin = Some(Box::new(leg_skin(skin)));
    let boxes = (0..3).map(|k| {
        object(
            &format!("box-{k}"),
            0,
            Mat4::from_translation(Vec3::new(-3.0 * k as f32 - 2.0, 0.5, 0.0)),
        )
    });
    Scene {
        name: "skinned".into(),
        up: Up::Y,
        time: TimeSpan {
            start: parse_date("2026-03-02T08:00:00Z").unwrap(),
            seconds: SPAN,
        },
        meshes: vec![common::unit_box(), mesh],
        objects: std::iter::once(leg).chain(boxes).collect(),
        tasks: Vec::new(),
        schedule_options: ScheduleOptions::default(),
        appearance: None,
        georeference: None,
    }
}

/// The skinned chain's clusters, finest first.
fn chain(tree: &Tree) -> Vec<u32> {
    let leaf = (0..tree.cluster_count() as u32)
        .find(|&c| tree.objects_of(c) == ["leg"])
        .expect("the leg has a leaf");
    let mut out = vec![leaf];
    while let Some(p) = tree.cluster(*out.last().unwrap()).parent {
        if tree.class_of(p) != ClusterClass::Dynamic {
            break;
        }
        out.push(p);
    }
    out
}

/// A stored skinned GLB's mesh and its joints and weights, read by the
/// gltf crate from its plain form (the crate decodes no
/// `EXT_meshopt_compression`).
fn read_skinned(path: &Path) -> (Mesh, Skin) {
    let bytes = std::fs::read(path).unwrap();
    let plain = hdlod::io::compact::plain(&bytes).unwrap();
    let (doc, buffers, _) = gltf::import_slice(&plain).unwrap();
    let node = doc.nodes().find(|n| n.mesh().is_some()).unwrap();
    assert!(
        node.skin().is_some(),
        "{}: the mesh node has a skin",
        path.display()
    );
    let primitive = node.mesh().unwrap().primitives().next().unwrap();
    let reader = primitive.reader(|b| Some(&buffers[b.index()]));
    let mesh = Mesh {
        positions: reader.read_positions().unwrap().map(Vec3::from).collect(),
        indices: reader.read_indices().unwrap().into_u32().collect(),
        ..Mesh::default()
    };
    let skin = Skin {
        joints: reader.read_joints(0).unwrap().into_u16().collect(),
        weights: reader.read_weights(0).unwrap().into_f32().collect(),
    };
    (mesh, skin)
}

/// The Hausdorff bound between the leg and `level` posed at `t`.
fn posed_error(scene: &Scene, level: &(Mesh, Skin), t: f64) -> f64 {
    let o = &scene.objects[0];
    let skin = o.skin.as_ref().unwrap();
    let full = skin.pose(&scene.meshes[o.mesh], t);
    let reduced = level.1.pose(&level.0, &skin.matrices(t));
    f64::from(hausdorff(&full, &reduced, &HausdorffOptions::default()).bound)
}

struct Built {
    scene: Scene,
    tree: Tree,
    dir: tempfile::TempDir,
}

fn built() -> Built {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    build_to(
        &scene,
        &BuildConfig::default(),
        &dir.path().join("tree"),
        &Silent,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let tree = load(dir.path().join("tree")).unwrap_or_else(|e| panic!("{e}"));
    Built { scene, tree, dir }
}

#[test]
fn a_skinned_chain_is_reduced_and_measured_over_its_poses() {
    let b = built();
    let ids = chain(&b.tree);
    assert!(ids.len() >= 2, "the leg has coarser levels: {ids:?}");
    let clusters: Vec<_> = ids
        .iter()
        .map(|&c| b.tree.cluster(c).into_owned())
        .collect();
    for w in clusters.windows(2) {
        assert!(
            w[1].triangles < w[0].triangles,
            "fewer triangles up the chain"
        );
        assert!(w[1].eps >= w[0].eps);
    }
    let dir = b.dir.path().join("tree");
    // The poses the chain was reduced and measured in: eight spread over
    // the bend, the object being present throughout.
    let sampled: Vec<f64> = (0..8)
        .map(|k| BEND.0 + (BEND.1 - BEND.0) * f64::from(k) / 7.0)
        .collect();
    let mut bind_only_fails = false;
    for c in &clusters[1..] {
        let glb = b.tree.geometry_file(&dir, c.geometry.as_deref().unwrap());
        let level = read_skinned(&glb);
        assert_eq!(level.0.triangle_count() as u64, c.triangles);
        let worst = sampled
            .iter()
            .map(|&t| posed_error(&b.scene, &level, t))
            .fold(0.0, f64::max);
        assert!(
            c.eps >= worst,
            "cluster {}: eps {} below its error {worst} in a sampled pose",
            c.id,
            c.eps
        );
        // What an error measured in the bind pose alone would have been.
        let bind = posed_error(&b.scene, &level, 0.0);
        bind_only_fails |= bind < worst;
    }
    assert!(
        bind_only_fails,
        "the bend makes some level stray more than in the bind pose"
    );
}

#[test]
fn a_skinned_cluster_s_box_holds_the_leg_in_every_pose() {
    let b = built();
    let o = &b.scene.objects[0];
    let skin = o.skin.as_ref().unwrap();
    for id in chain(&b.tree) {
        let c = b.tree.cluster(id);
        let motion = c.motion.as_ref().expect("a dynamic cluster has a motion");
        for k in 0..50 {
            // Between keyframes too: the keys are 2.5 s apart.
            let t = 7.0 + 16.0 * f64::from(k) / 49.0;
            let bounds = c.bounds.transformed(&motion.at(t).as_dmat4());
            for p in skin.pose(&b.scene.meshes[o.mesh], t).positions {
                let p = p.as_dvec3();
                assert!(
                    p.cmpge(bounds.min - 1e-6).all() && p.cmple(bounds.max + 1e-6).all(),
                    "cluster {id} at {t}: {p} outside {bounds:?}"
                );
            }
        }
    }
}

#[test]
fn the_cut_poses_a_skinned_cluster_with_its_joint_matrices() {
    let b = built();
    let skin = b.scene.objects[0].skin.as_ref().unwrap();
    let skeleton = b.tree.skins.as_ref().unwrap().get("leg").unwrap();
    assert_eq!(skeleton.joints, skin.joints);
    let view = View::new(
        &CameraSpec {
            position: Some([1.0, 1.0, 6.0]),
            target: Some([1.0, 1.0, 0.0]),
            ..Default::default()
        },
        Viewport {
            width: 1280,
            height: 720,
        },
        1.0,
        DVec3::Y,
    )
    .unwrap();
    let ids = chain(&b.tree);
    let mut answers = Vec::new();
    for t in [12.0, 18.0] {
        let cut = hdlod::tree::cut(&b.tree, &view, t);
        let leg = cut
            .items
            .iter()
            .find(|i| ids.contains(&i.id))
            .expect("the leg is in the cut");
        let joints = cut.joints_of(leg);
        assert_eq!(joints, skin.matrices(t).as_slice(), "at {t}");
        assert_eq!(leg.transform, Some(Mat4::IDENTITY));
        // Rigid clusters carry none.
        for item in cut.items.iter().filter(|i| !ids.contains(&i.id)) {
            assert!(item.joints.is_none() && cut.joints_of(item).is_empty());
        }
        answers.push(joints.to_vec());
    }
    assert_ne!(answers[0], answers[1]);
}

#[test]
fn the_skins_file_is_checked_on_load_and_optional() {
    let b = built();
    let dir = b.dir.path().join("tree");
    let path = dir.join("skins.json");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    common::assert_matches_schema(&json, "tree-skins.schema.json");
    let mut wrong = json.clone();
    wrong["skins"][0]["object"] = "box-0".into();
    std::fs::write(&path, serde_json::to_vec(&wrong).unwrap()).unwrap();
    let e = load(&dir).unwrap_err().to_string();
    assert!(
        e.contains("skins.json") && e.contains("skins[0].object") && e.contains("box-0"),
        "{e}"
    );
    let mut wrong = json.clone();
    wrong["skins"][0]["inverse_bind"]
        .as_array_mut()
        .unwrap()
        .pop();
    std::fs::write(&path, serde_json::to_vec(&wrong).unwrap()).unwrap();
    let e = load(&dir).unwrap_err().to_string();
    assert!(e.contains("skins[0].inverse_bind"), "{e}");
    std::fs::remove_file(&path).unwrap();
    let rigid = load(&dir).unwrap();
    assert!(
        rigid.skins.is_none(),
        "a tree without skins.json loads as before"
    );
}

#[test]
fn a_skinned_level_s_glb_passes_the_khronos_validator() {
    let b = built();
    let dir = b.dir.path().join("tree");
    let files: Vec<_> = chain(&b.tree)
        .iter()
        .map(|&c| b.tree.geometry_file(&dir, &b.tree.geometry_of(c).unwrap()))
        .collect();
    common::assert_no_gltf_errors(&files);
    for file in &files {
        let (mesh, skin) = read_skinned(file);
        assert_eq!(skin.joints.len(), mesh.positions.len());
    }
    // Stored compressed, nothing quantized; the plain form is valid too,
    // and larger.
    let plains = tempfile::tempdir().unwrap();
    let mut plain_files = Vec::new();
    for (k, file) in files.iter().enumerate() {
        let bytes = std::fs::read(file).unwrap();
        let container = gltf::binary::Glb::from_slice(&bytes).unwrap();
        let json: serde_json::Value = serde_json::from_slice(&container.json).unwrap();
        assert_eq!(
            json["extensionsRequired"],
            serde_json::json!(["EXT_meshopt_compression"]),
            "{}",
            file.display()
        );
        let plain = hdlod::io::compact::plain(&bytes).unwrap().into_owned();
        assert!(plain.len() > bytes.len(), "{}", file.display());
        let path = plains.path().join(format!("plain-{k}.glb"));
        std::fs::write(&path, plain).unwrap();
        plain_files.push(path);
    }
    common::assert_no_gltf_errors(&plain_files);
}

//! Skinned models: a hand-built glTF leg, a cylinder of rings around a
//! two-bone chain (hip, knee) whose knee bends while the hip swings, placed
//! on the timeline by `scene.json`. Its joints, weights and inverse bind
//! matrices are read, the joints move with the clip as articulated parts
//! do, `save` writes it all back, and bad skins are refused naming the
//! file, the node or skin and what is wrong.

mod common;

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};
use hdlod::scene::{Scene, format};

/// Rings of the cylinder, from the foot (y = 0) to the hip (y = 2).
const RINGS: usize = 9;
/// Vertices per ring.
const SIDES: usize = 8;
const RADIUS: f32 = 0.2;
/// The skeleton's root stands 1 m out along X: the joints' world
/// transforms are composed through it.
const ROOT: Vec3 = Vec3::new(1.0, 0.0, 0.0);

/// The leg's vertex data, as the test writes it into the file.
struct Leg {
    positions: Vec<[f32; 3]>,
    indices: Vec<u16>,
    joints: Vec<[u8; 4]>,
    weights: Vec<[f32; 4]>,
    inverse_bind: Vec<Mat4>,
    /// Weights as normalized UNSIGNED_SHORT instead of FLOAT.
    weights_u16: bool,
}

/// Ring `r` of the leg at height `0.25 r`, on the knee below 0.75 m, on
/// the hip above 1.25 m, blended between.
fn leg() -> Leg {
    let mut leg = Leg {
        positions: Vec::new(),
        indices: Vec::new(),
        joints: Vec::new(),
        weights: Vec::new(),
        // The inverses of the joints' world transforms in the bind pose:
        // hip at (1, 2, 0), knee at (1, 1, 0).
        inverse_bind: vec![
            Mat4::from_translation(-(ROOT + Vec3::Y * 2.0)),
            Mat4::from_translation(-(ROOT + Vec3::Y)),
        ],
        weights_u16: false,
    };
    for r in 0..RINGS {
        let y = 0.25 * r as f32;
        let hip = ((y - 0.75) / 0.5).clamp(0.0, 1.0);
        for k in 0..SIDES {
            let a = std::f32::consts::TAU * k as f32 / SIDES as f32;
            let p = ROOT + Vec3::new(RADIUS * a.cos(), y, RADIUS * a.sin());
            leg.positions.push(p.to_array());
            // A joint under a zero weight is 0, as glTF recommends.
            let (joints, weights) = match hip {
                1.0 => ([0, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
                0.0 => ([1, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
                _ => ([0, 1, 0, 0], [hip, 1.0 - hip, 0.0, 0.0]),
            };
            leg.joints.push(joints);
            leg.weights.push(weights);
        }
    }
    for r in 0..RINGS - 1 {
        for k in 0..SIDES {
            let at = |r: usize, k: usize| (r * SIDES + k % SIDES) as u16;
            let (a, b, c, d) = (at(r, k), at(r, k + 1), at(r + 1, k), at(r + 1, k + 1));
            leg.indices.extend([a, c, b, b, c, d]);
        }
    }
    leg
}

/// Writes `dir/leg.gltf` and its buffer `dir/leg.bin`: node 0 `leg`, the
/// skinned mesh, placed 5 m out along X (glTF ignores a skinned mesh
/// node's transform: the joints place it); node 1 the skeleton's root at
/// [`ROOT`], node 2 the hip 2 m above it, node 3 the knee 1 m below the
/// hip. Animation `bend` over 2 s (linear): the knee turns a quarter about
/// X and the hip 20 degrees about Z. Returns the glTF JSON, for tests that
/// break it.
fn write_leg(dir: &Path, leg: &Leg) -> serde_json::Value {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |bytes: &[u8], accessor: serde_json::Value| {
        let offset = bin.len();
        bin.extend_from_slice(bytes);
        bin.resize(bin.len().next_multiple_of(4), 0);
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}),
        );
        let mut a = accessor;
        a["bufferView"] = serde_json::json!(views.len() - 1);
        accessors.push(a);
        accessors.len() - 1
    };
    let floats = |v: &[f32]| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    let flat: Vec<f32> = leg.positions.iter().flatten().copied().collect();
    let (lo, hi) = leg.positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), p| (lo.min(Vec3::from(*p)), hi.max(Vec3::from(*p))),
    );
    let n = leg.positions.len();
    let positions = push(
        &floats(&flat),
        serde_json::json!({"componentType": 5126, "count": n, "type": "VEC3",
                           "min": lo.to_array(), "max": hi.to_array()}),
    );
    let index_bytes: Vec<u8> = leg.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    let indices = push(
        &index_bytes,
        serde_json::json!({"componentType": 5123, "count": leg.indices.len(), "type": "SCALAR"}),
    );
    let joints = push(
        &leg.joints.concat(),
        serde_json::json!({"componentType": 5121, "count": n, "type": "VEC4"}),
    );
    let weights = if leg.weights_u16 {
        let shorts: Vec<u8> = (leg.weights.iter().flatten())
            .flat_map(|w| ((w * 65535.0).round() as u16).to_le_bytes())
            .collect();
        push(
            &shorts,
            serde_json::json!({"componentType": 5123, "normalized": true, "count": n,
                               "type": "VEC4"}),
        )
    } else {
        let flat: Vec<f32> = leg.weights.iter().flatten().copied().collect();
        push(
            &floats(&flat),
            serde_json::json!({"componentType": 5126, "count": n, "type": "VEC4"}),
        )
    };
    let ibm: Vec<f32> = leg
        .inverse_bind
        .iter()
        .flat_map(|m| m.to_cols_array())
        .collect();
    let inverse_bind = push(
        &floats(&ibm),
        serde_json::json!({"componentType": 5126, "count": leg.inverse_bind.len(),
                           "type": "MAT4"}),
    );
    let input = push(
        &floats(&[0.0, 2.0]),
        serde_json::json!({"componentType": 5126, "count": 2, "type": "SCALAR",
                           "min": [0.0], "max": [2.0]}),
    );
    let knee = glam::Quat::from_rotation_x(std::f32::consts::FRAC_PI_2).to_array();
    let hip = glam::Quat::from_rotation_z(20f32.to_radians()).to_array();
    let knee_out = push(
        &floats(&[[0.0, 0.0, 0.0, 1.0], knee].concat()),
        serde_json::json!({"componentType": 5126, "count": 2, "type": "VEC4"}),
    );
    let hip_out = push(
        &floats(&[[0.0, 0.0, 0.0, 1.0], hip].concat()),
        serde_json::json!({"componentType": 5126, "count": 2, "type": "VEC4"}),
    );
    std::fs::write(dir.join("leg.bin"), &bin).unwrap();
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"name": "leg", "mesh": 0, "skin": 0, "translation": [5.0, 0.0, 0.0]},
            {"name": "root", "translation": ROOT.to_array(), "children": [2]},
            {"name": "hip", "translation": [0.0, 2.0, 0.0], "children": [3]},
            {"name": "knee", "translation": [0.0, -1.0, 0.0]}
        ],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": positions, "JOINTS_0": joints, "WEIGHTS_0": weights},
            "indices": indices
        }]}],
        "skins": [{"joints": [2, 3], "inverseBindMatrices": inverse_bind, "skeleton": 1}],
        "animations": [{
            "name": "bend",
            "samplers": [
                {"input": input, "output": knee_out, "interpolation": "LINEAR"},
                {"input": input, "output": hip_out, "interpolation": "LINEAR"}
            ],
            "channels": [
                {"sampler": 0, "target": {"node": 3, "path": "rotation"}},
                {"sampler": 1, "target": {"node": 2, "path": "rotation"}}
            ]
        }],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"uri": "leg.bin", "byteLength": bin.len()}]
    });
    write_gltf(dir, &gltf);
    gltf
}

fn write_gltf(dir: &Path, gltf: &serde_json::Value) {
    std::fs::write(dir.join("leg.gltf"), serde_json::to_vec(gltf).unwrap()).unwrap();
}

/// `dir/scene.json`: the leg, the clip `bend` played once at 10 s.
fn write_scene(dir: &Path) -> PathBuf {
    let scene = serde_json::json!({
        "format": "hdlod-scene/1",
        "name": "leg",
        "time": {"start": "2026-03-02T08:00:00Z", "end": 100},
        "models": ["leg.gltf"],
        "clips": [{"animation": "bend", "play": [10]}]
    });
    let path = dir.join("scene.json");
    std::fs::write(&path, serde_json::to_vec(&scene).unwrap()).unwrap();
    path
}

fn load_leg(dir: &Path, leg: &Leg) -> Scene {
    write_leg(dir, leg);
    format::load(&write_scene(dir)).unwrap_or_else(|e| panic!("{e}"))
}

/// The leg's vertices in the world at `t`.
fn posed(scene: &Scene, t: f64) -> Vec<Vec3> {
    let o = &scene.objects[0];
    let skin = o.skin.as_ref().expect("the leg is skinned");
    skin.pose(&scene.meshes[o.mesh], t).positions
}

/// Times before, during and after the bend.
const TIMES: [f64; 8] = [0.0, 10.0, 10.3, 10.5, 11.0, 11.7, 12.0, 50.0];

#[test]
fn a_skin_is_read_its_joints_move_with_the_clip_and_the_mesh_stays_in_its_bind_pose() {
    let dir = tempfile::tempdir().unwrap();
    let scene = load_leg(dir.path(), &leg());
    assert_eq!(scene.objects.len(), 1, "joints are no objects");
    let o = &scene.objects[0];
    // What the stages that do not skin see is what they saw before: the
    // bind-pose mesh placed by the node's transform, which does not move.
    assert_eq!(o.transform, Mat4::from_translation(Vec3::X * 5.0));
    assert!(o.motion.is_none());
    assert_eq!(scene.meshes[o.mesh].positions.len(), RINGS * SIDES);
    let skin = o.skin.as_ref().unwrap();
    let names: Vec<_> = skin.joints.iter().map(|j| j.name.as_deref()).collect();
    assert_eq!(names, [Some("hip"), Some("knee")]);
    assert_eq!(skin.inverse_bind, leg().inverse_bind);
    assert_eq!(skin.vertices.joints[0], [1, 0, 0, 0]);
    // Ring 4 (y = 1) is half on each joint.
    assert_eq!(skin.vertices.weights[4 * SIDES], [0.5, 0.5, 0.0, 0.0]);
    assert_eq!(skin.vertices.problem(&scene.meshes[o.mesh], 2), None);
    assert!(skin.joints.iter().all(|j| j.motion.is_some()));
    // Before the clip, every joint is where the inverse bind matrices say
    // it binds: the pose is the mesh.
    let mesh = &scene.meshes[o.mesh].positions;
    for (p, q) in posed(&scene, 0.0).iter().zip(mesh) {
        assert!(p.distance(*q) < 1e-5, "{p} vs {q}");
    }
    // The hip ring turns about its centre, the hip; the foot swings.
    let at_end = posed(&scene, 50.0);
    let top = &at_end[(RINGS - 1) * SIDES..];
    let centre = top.iter().sum::<Vec3>() / SIDES as f32;
    assert!(centre.distance(ROOT + Vec3::Y * 2.0) < 1e-5, "{centre}");
    assert!(at_end[0].distance(mesh[0]) > 1.0);
}

/// Vertex 0 (foot ring, on the knee alone, at (1.2, 0, 0) in the bind
/// pose) by hand: 1.2 m along X is 0.2 m off the knee's axis and 1 m below
/// it; the knee turns it by `knee` about X, the hip, 1 m above, turns the
/// lot by `hip` about Z, and the hip stands at (1, 2, 0).
fn foot(hip: f64, knee: f64) -> Vec3 {
    let (x, y, z) = (0.2, -knee.cos(), -knee.sin());
    let y = y - 1.0;
    let (x, y) = (x * hip.cos() - y * hip.sin(), x * hip.sin() + y * hip.cos());
    Vec3::new((x + 1.0) as f32, (y + 2.0) as f32, z as f32)
}

#[test]
fn the_bent_knee_places_a_vertex_where_a_hand_computation_does() {
    let dir = tempfile::tempdir().unwrap();
    let scene = load_leg(dir.path(), &leg());
    let (hip, knee) = (20f64.to_radians(), 90f64.to_radians());
    // Half way through the clip: half of each turn (slerp of one axis is
    // linear in the angle).
    for (t, expected) in [
        (11.0, foot(hip / 2.0, knee / 2.0)),
        (12.0, foot(hip, knee)),
        (60.0, foot(hip, knee)),
    ] {
        let got = posed(&scene, t)[0];
        assert!(
            got.distance(expected) <= 1e-3,
            "t {t}: {got} vs {expected} by hand"
        );
    }
    // A blended vertex: ring 3 (y = 0.75) is on the knee alone, ring 5
    // (y = 1.25) on the hip alone, ring 4 half way between them moves to
    // the mean of where each joint alone would take it.
    let at = |ring: usize| 4 * SIDES + ring;
    let bent = posed(&scene, 12.0);
    let pose = scene.objects[0].skin.as_ref().unwrap().matrices(12.0);
    let bind = Vec3::from(leg().positions[at(0)]);
    let mean = (pose[0].transform_point3(bind) + pose[1].transform_point3(bind)) / 2.0;
    assert!(bent[at(0)].distance(mean) < 1e-5);
}

#[test]
fn a_saved_skinned_scene_reads_back_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let scene = load_leg(dir.path(), &leg());
    let saved = dir.path().join("saved");
    format::save(&scene, &saved).unwrap();
    // The joints move with a clip placed by keys, one key per keyframe.
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(saved.join("scene.json")).unwrap()).unwrap();
    common::assert_matches_schema(&json, "scene.schema.json");
    let clips = json["clips"].as_array().unwrap();
    assert_eq!(clips.len(), 1, "{json}");
    assert!(clips[0]["keys"].as_array().unwrap().len() > 2, "{json}");
    let again = format::load(&saved).unwrap_or_else(|e| panic!("{e}"));
    let (a, b) = (&scene.objects[0], &again.objects[0]);
    assert_eq!(a.transform, b.transform);
    assert!(b.motion.is_none());
    let (sa, sb) = (a.skin.as_ref().unwrap(), b.skin.as_ref().unwrap());
    assert_eq!(sa.vertices.joints, sb.vertices.joints);
    for (wa, wb) in sa.vertices.weights.iter().zip(&sb.vertices.weights) {
        for (x, y) in wa.iter().zip(wb) {
            assert!((x - y).abs() <= 1e-7, "{wa:?} vs {wb:?}");
        }
    }
    assert_eq!(sa.inverse_bind, sb.inverse_bind);
    let names = |s: &hdlod::scene::ObjectSkin| -> Vec<Option<String>> {
        s.joints.iter().map(|j| j.name.clone()).collect()
    };
    assert_eq!(names(sa), names(sb));
    for t in TIMES {
        for (p, q) in posed(&scene, t).iter().zip(&posed(&again, t)) {
            assert!(p.distance(*q) <= 1e-3, "t {t}: {p} vs {q}");
        }
    }
    // The joints' motions come back keyframe for keyframe (the saved clip
    // plays the keyframes; the load samples it at every key).
    for (ja, jb) in sa.joints.iter().zip(&sb.joints) {
        let (ka, kb) = (ja.motion.as_ref().unwrap(), jb.motion.as_ref().unwrap());
        for k in ka.keyframes() {
            let m = kb.sample(k.t);
            assert!(m.translation.distance(k.translation) < 1e-5);
            assert!(m.rotation.dot(k.rotation).abs() > 1.0 - 1e-6);
        }
    }
    // And saved again, the same once more.
    let twice = dir.path().join("twice");
    format::save(&again, &twice).unwrap();
    let third = format::load(&twice).unwrap();
    for t in TIMES {
        for (p, q) in posed(&scene, t).iter().zip(&posed(&third, t)) {
            assert!(p.distance(*q) <= 1e-3, "t {t}: {p} vs {q}");
        }
    }
    // A scene that was read from a file saves and reads back bit for bit:
    // an update would otherwise see the leg as edited.
    let motions = |s: &Scene| -> Vec<Option<hdlod::scene::Motion>> {
        let skin = s.objects[0].skin.as_ref().unwrap();
        skin.joints.iter().map(|j| j.motion.clone()).collect()
    };
    assert_eq!(motions(&again), motions(&third));
    assert_eq!(
        hdlod::build::object_sources(&again),
        hdlod::build::object_sources(&third)
    );
}

#[test]
fn normalized_short_weights_are_read_and_scaled_to_sum_to_one() {
    let dir = tempfile::tempdir().unwrap();
    let scene = load_leg(
        dir.path(),
        &Leg {
            weights_u16: true,
            ..leg()
        },
    );
    let skin = scene.objects[0].skin.as_ref().unwrap();
    for (got, written) in skin.vertices.weights.iter().zip(&leg().weights) {
        let sum: f32 = got.iter().sum();
        assert!((sum - 1.0).abs() < 1e-6, "{got:?}");
        for (x, y) in got.iter().zip(written) {
            assert!((x - y).abs() < 1e-4, "{got:?} vs {written:?}");
        }
    }
}

#[test]
fn a_skin_without_inverse_binds_binds_at_identity_and_a_node_without_a_skin_is_rigid() {
    let dir = tempfile::tempdir().unwrap();
    let mut gltf = write_leg(dir.path(), &leg());
    gltf["skins"][0]
        .as_object_mut()
        .unwrap()
        .remove("inverseBindMatrices");
    // The same mesh on a node of its own, without the skin.
    gltf["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"name": "rigid", "mesh": 0}));
    gltf["scenes"][0]["nodes"] = serde_json::json!([0, 1, 4]);
    write_gltf(dir.path(), &gltf);
    let scene = format::load(&write_scene(dir.path())).unwrap_or_else(|e| panic!("{e}"));
    let skin = scene.objects[0].skin.as_ref().unwrap();
    assert_eq!(skin.inverse_bind, [Mat4::IDENTITY; 2]);
    // At identity inverse binds each joint carries the mesh from the
    // origin to where it stands: the knee-only foot ring 1 m up.
    let foot = Vec3::from(leg().positions[0]);
    assert!(posed(&scene, 0.0)[0].distance(foot + ROOT + Vec3::Y) < 1e-5);
    let rigid = &scene.objects[1];
    assert_eq!(rigid.id, "rigid");
    assert!(rigid.skin.is_none() && rigid.motion.is_none());
    assert_eq!(scene.meshes[rigid.mesh].positions.len(), RINGS * SIDES);
}

/// The error loading the scene of the leg `leg`, its glTF changed by
/// `edit`.
fn leg_error(leg: &Leg, edit: impl FnOnce(&mut serde_json::Value)) -> (String, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let mut gltf = write_leg(dir.path(), leg);
    edit(&mut gltf);
    write_gltf(dir.path(), &gltf);
    let err = format::load(&write_scene(dir.path()))
        .map(|_| ())
        .expect_err("a bad skin loads");
    (err.to_string(), dir.path().join("leg.gltf"))
}

#[test]
fn bad_skins_are_refused_naming_the_file_the_node_or_skin_and_the_fault() {
    let expect = |(got, file): (String, PathBuf), at: &str| {
        assert_eq!(got, format!("{}: {at}", file.display()));
    };
    let mesh = "node 0 \"leg\" mesh 0";

    // Two joints, one inverse bind matrix.
    let mut short = leg();
    short.inverse_bind.pop();
    expect(
        leg_error(&short, |_| {}),
        "skins[0]: 1 inverse bind matrices for 2 joints",
    );

    let mut beyond = leg();
    beyond.joints[3] = [0, 2, 0, 0];
    expect(
        leg_error(&beyond, |_| {}),
        &format!(
            "{mesh}: primitive 0: JOINTS_0 names joint 2 at vertex 3, but the skin has 2 joints"
        ),
    );

    let mut nan = leg();
    nan.weights[5] = [f32::NAN, 1.0, 0.0, 0.0];
    expect(
        leg_error(&nan, |_| {}),
        &format!(
            "{mesh}: primitive 0: WEIGHTS_0 at vertex 5 are not all finite and >= 0: \
             [NaN, 1.0, 0.0, 0.0]"
        ),
    );

    let mut zero = leg();
    zero.weights[7] = [0.0; 4];
    expect(
        leg_error(&zero, |_| {}),
        &format!("{mesh}: primitive 0: WEIGHTS_0 at vertex 7 are all 0"),
    );

    expect(
        leg_error(&leg(), |g| {
            let attributes = &mut g["meshes"][0]["primitives"][0]["attributes"];
            attributes.as_object_mut().unwrap().remove("WEIGHTS_0");
        }),
        &format!("{mesh}: primitive 0: has JOINTS_0 but no WEIGHTS_0"),
    );

    // A second primitive over the same positions, without joints.
    expect(
        leg_error(&leg(), |g| {
            let first = g["meshes"][0]["primitives"][0].clone();
            let mut plain = first.clone();
            let attributes = plain["attributes"].as_object_mut().unwrap();
            attributes.remove("JOINTS_0");
            attributes.remove("WEIGHTS_0");
            g["meshes"][0]["primitives"] = serde_json::json!([first, plain]);
        }),
        &format!(
            "{mesh}: primitive 1: has no JOINTS_0 while primitive 0 has: a skinned primitive \
             cannot be merged with an unskinned one"
        ),
    );

    expect(
        leg_error(&leg(), |g| {
            let attributes = &mut g["meshes"][0]["primitives"][0]["attributes"];
            let attributes = attributes.as_object_mut().unwrap();
            attributes.remove("JOINTS_0");
            attributes.remove("WEIGHTS_0");
        }),
        &format!("{mesh}: has no JOINTS_0, which the node's skins[0] needs"),
    );
}

#[test]
fn the_saved_skinned_glb_passes_the_khronos_validator() {
    let dir = tempfile::tempdir().unwrap();
    let scene = load_leg(dir.path(), &leg());
    let saved = dir.path().join("saved");
    format::save(&scene, &saved).unwrap();
    let glb = saved.join("leg.glb");
    let reports = common::assert_no_gltf_errors(std::slice::from_ref(&glb));
    let info = &reports[0]["info"];
    assert_eq!(info["animationCount"], 1, "{info}");
    assert_eq!(info["hasSkins"], true, "{info}");
    assert_eq!(info["maxInfluences"], 4, "{info}");
    // The one warning a skinned node with a transform earns: glTF ignores
    // it, the scene keeps it as the bind pose's placement.
    let messages = reports[0]["issues"]["messages"].as_array().unwrap();
    for m in messages.iter().filter(|m| m["severity"] == 1) {
        assert_eq!(m["code"], "NODE_SKINNED_MESH_LOCAL_TRANSFORMS", "{m}");
    }
}

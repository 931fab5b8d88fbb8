//! Articulated models: a hand-built glTF crane (mast, slewing jib, running
//! trolley, hook) whose animations `scene.json` places on the timeline. The
//! parts move with their world transforms composed down the hierarchy,
//! within a millimetre of the exact composition, and bad placements are
//! refused naming the field.

mod common;

use std::path::Path;

use glam::{Mat4, Quat, Vec3};
use hdlod::scene::{Class, Scene, format};

const DAY: f64 = 86_400.0;

/// A `.gltf` with its buffer beside it (`crane.bin`): four box nodes in a
/// chain mast > jib > trolley > hook and three animations:
/// - `slew`: the jib turns a quarter about Y over 10 s (linear);
/// - `trolley`: the trolley runs from 10 to 20 m out over 5 s (cubic
///   spline, zero tangents);
/// - `hook`: the hook drops from 5 to 15 m below the trolley at 4 s (step);
/// - `spin`: the mast turns a quarter over 2 s (linear), for conflicts.
fn write_crane(dir: &Path) {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |bin: &mut Vec<u8>, floats: &[f32], kind: &str, count: usize, minmax: bool| {
        let offset = bin.len();
        for f in floats {
            bin.extend_from_slice(&f.to_le_bytes());
        }
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": floats.len() * 4}),
        );
        let mut a = serde_json::json!({
            "bufferView": views.len() - 1, "componentType": 5126, "count": count, "type": kind
        });
        if minmax {
            let width = floats.len() / count;
            // Each component's extremes, as the specification asks of inputs.
            let component = |k: usize, pick: fn(f32, f32) -> f32, start: f32| {
                floats
                    .iter()
                    .skip(k)
                    .step_by(width)
                    .copied()
                    .fold(start, pick)
            };
            let min: Vec<f32> = (0..width)
                .map(|k| component(k, f32::min, f32::MAX))
                .collect();
            let max: Vec<f32> = (0..width)
                .map(|k| component(k, f32::max, f32::MIN))
                .collect();
            a["min"] = serde_json::json!(min);
            a["max"] = serde_json::json!(max);
        }
        accessors.push(a);
        accessors.len() - 1
    };
    // One triangle per part is enough to be an object with a box.
    let positions = push(
        &mut bin,
        &[-0.5, 0.0, -0.5, 0.5, 0.0, -0.5, 0.0, 1.0, 0.5],
        "VEC3",
        3,
        true,
    );
    let q = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2).to_array();
    let slew_in = push(&mut bin, &[0.0, 10.0], "SCALAR", 2, true);
    let slew_out = push(
        &mut bin,
        &[0.0, 0.0, 0.0, 1.0, q[0], q[1], q[2], q[3]],
        "VEC4",
        2,
        false,
    );
    let trolley_in = push(&mut bin, &[0.0, 5.0], "SCALAR", 2, true);
    #[rustfmt::skip]
    let trolley_out = push(&mut bin, &[
        0.0, 0.0, 0.0,  10.0, 0.0, 0.0,  0.0, 0.0, 0.0,
        0.0, 0.0, 0.0,  20.0, 0.0, 0.0,  0.0, 0.0, 0.0,
    ], "VEC3", 6, false);
    let hook_in = push(&mut bin, &[0.0, 4.0], "SCALAR", 2, true);
    let hook_out = push(
        &mut bin,
        &[0.0, -5.0, 0.0, 0.0, -15.0, 0.0],
        "VEC3",
        2,
        false,
    );
    let spin_in = push(&mut bin, &[0.0, 2.0], "SCALAR", 2, true);
    std::fs::write(dir.join("crane.bin"), &bin).unwrap();
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "mast", "mesh": 0, "children": [1]},
            {"name": "jib", "mesh": 0, "translation": [0.0, 20.0, 0.0], "children": [2]},
            {"name": "trolley", "mesh": 0, "translation": [10.0, 0.0, 0.0], "children": [3]},
            {"name": "hook", "mesh": 0, "translation": [0.0, -5.0, 0.0]}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": positions}}]}],
        "animations": [
            {"name": "slew",
             "samplers": [{"input": slew_in, "output": slew_out, "interpolation": "LINEAR"}],
             "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}]},
            {"name": "trolley",
             "samplers": [{"input": trolley_in, "output": trolley_out, "interpolation": "CUBICSPLINE"}],
             "channels": [{"sampler": 0, "target": {"node": 2, "path": "translation"}}]},
            {"name": "hook",
             "samplers": [{"input": hook_in, "output": hook_out, "interpolation": "STEP"}],
             "channels": [{"sampler": 0, "target": {"node": 3, "path": "translation"}}]},
            {"name": "spin",
             "samplers": [{"input": spin_in, "output": slew_out, "interpolation": "LINEAR"}],
             "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}]}
        ],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"uri": "crane.bin", "byteLength": bin.len()}]
    });
    std::fs::write(dir.join("crane.gltf"), gltf.to_string()).unwrap();
}

/// The scene file over the crane, with `clips`.
fn scene_json(clips: serde_json::Value) -> serde_json::Value {
    serde_json::json!({
        "format": "hdlod-scene/1",
        "name": "crane",
        "time": {"start": "2025-01-01T00:00:00Z", "end": "2025-01-11T00:00:00Z"},
        "models": ["crane.gltf"],
        "clips": clips
    })
}

fn load(dir: &Path, json: &serde_json::Value) -> hdlod::Result<Scene> {
    std::fs::write(dir.join("scene.json"), json.to_string()).unwrap();
    format::load(dir)
}

/// The placements of the first test: the jib slews on day 1 at twice the
/// speed (5 s), the trolley runs out and back... (a loop over 12 s from day
/// 2: two and a half cycles), and the hook is driven to clip time 4 s at
/// day 3 from 0 at day 3 minus 10 s.
fn placements() -> serde_json::Value {
    serde_json::json!([
        {"animation": "slew", "play": ["2025-01-02T00:00:00Z"], "speed": 2.0},
        {"animation": "trolley", "loop": {"from": "2025-01-03T00:00:00Z", "to": 2.0 * DAY + 12.0}},
        {"animation": 2, "keys": [{"t": 3.0 * DAY - 10.0, "clip_time": 0.0}, {"t": 3.0 * DAY, "clip_time": 4.0}]}
    ])
}

/// The exact world transforms of the parts at scene time `t` under
/// [`placements`].
fn exact(t: f64) -> [Mat4; 4] {
    let slew = ((t - DAY) * 2.0 / 10.0).clamp(0.0, 1.0) as f32;
    let jib_turn = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2 * slew);
    let trolley_x = if t < 2.0 * DAY {
        10.0
    } else {
        let local = (t - 2.0 * DAY).min(12.0);
        // The loop's last piece ends at 2 s into its third cycle.
        let tau = if local >= 12.0 { 2.0 } else { local % 5.0 };
        let s = (tau / 5.0) as f32;
        10.0 + 10.0 * (3.0 * s * s - 2.0 * s * s * s)
    };
    let hook_tau = ((t - (3.0 * DAY - 10.0)) * 0.4).clamp(0.0, 4.0);
    let hook_y = if hook_tau >= 4.0 { -15.0 } else { -5.0 };
    let mast = Mat4::IDENTITY;
    let jib = mast * Mat4::from_rotation_translation(jib_turn, Vec3::new(0.0, 20.0, 0.0));
    let trolley = jib * Mat4::from_translation(Vec3::new(trolley_x, 0.0, 0.0));
    let hook = trolley * Mat4::from_translation(Vec3::new(0.0, hook_y, 0.0));
    [mast, jib, trolley, hook]
}

#[test]
fn parts_move_with_their_transforms_composed_down_the_hierarchy() {
    let dir = tempfile::tempdir().unwrap();
    write_crane(dir.path());
    // The hand-built file is valid glTF, animations included.
    common::assert_no_gltf_errors(&[dir.path().join("crane.gltf")]);
    let json = scene_json(placements());
    common::assert_matches_schema(&json, "scene.schema.json");
    let scene = load(dir.path(), &json).unwrap();
    let ids: Vec<&str> = scene.objects.iter().map(|o| o.id.as_str()).collect();
    assert_eq!(ids, ["mast", "jib", "trolley", "hook"]);
    let span = scene.time.seconds;
    assert_eq!(scene.objects[0].motion, None, "nothing animates the mast");
    for o in &scene.objects[1..] {
        assert_eq!(scene.class_of(o), Class::Dynamic, "{}", o.id);
    }
    // The triangle's corners, and its box's, within a millimetre of the
    // exact composition, at times that fall inside and between the
    // placements (a step's jump excepted: the hook's, at day 3, and the
    // loop's returns to the start of its clip).
    let corners = [
        Vec3::new(-0.5, 0.0, -0.5),
        Vec3::new(0.5, 0.0, -0.5),
        Vec3::new(0.0, 1.0, 0.5),
        Vec3::new(0.5, 1.0, 0.5),
    ];
    let mut times: Vec<f64> = (0..=400).map(|k| k as f64 * span / 400.0).collect();
    for base in [DAY, 2.0 * DAY, 3.0 * DAY - 10.0] {
        times.extend((0..=300).map(|k| base + k as f64 * 0.05));
    }
    let near_jump = |t: f64| {
        [3.0 * DAY, 2.0 * DAY + 5.0, 2.0 * DAY + 10.0]
            .iter()
            .any(|j| (t - j).abs() < 2e-3)
    };
    let mut worst = 0.0f32;
    for &t in times.iter().filter(|&&t| t <= span && !near_jump(t)) {
        let want = exact(t);
        for (k, o) in scene.objects.iter().enumerate() {
            let got = o.pose(t);
            for c in corners {
                let d = got
                    .transform_point3(c)
                    .distance(want[k].transform_point3(c));
                worst = worst.max(d);
                assert!(d <= 1.01e-3, "{} at t = {t}: {d} m off", o.id);
            }
        }
    }
    assert!(worst > 0.0, "the composition was resampled, not copied");
    // The slew's arc needs keyframes between its ends: 5 s of a 30 m
    // radius turn is not two keys.
    let hook_keys = scene.objects[3].motion.as_ref().unwrap().keyframes().len();
    assert!(hook_keys > 10, "{hook_keys}");
}

#[test]
fn a_saved_scene_keeps_the_motions_the_clips_made() {
    let dir = tempfile::tempdir().unwrap();
    write_crane(dir.path());
    let scene = load(dir.path(), &scene_json(placements())).unwrap();
    let out = dir.path().join("saved");
    format::save(&scene, &out).unwrap();
    let again = format::load(&out).unwrap();
    for (a, b) in scene.objects.iter().zip(&again.objects) {
        assert_eq!(a.id, b.id);
        for k in 0..50 {
            let t = k as f64 * scene.time.seconds / 49.0;
            let (p, q) = (a.pose(t), b.pose(t));
            assert!(p.abs_diff_eq(q, 1e-4), "{} at {t}", a.id);
        }
    }
}

#[test]
fn a_crane_with_clips_builds_dynamic_clusters() {
    let dir = tempfile::tempdir().unwrap();
    write_crane(dir.path());
    let scene = load(dir.path(), &scene_json(placements())).unwrap();
    let out = dir.path().join("tree");
    let config = hdlod::build::BuildConfig::default();
    hdlod::build::build_to(&scene, &config, &out, &hdlod::build::Silent).unwrap();
    let tree = hdlod::tree::load(&out).unwrap();
    let dynamic = (0..tree.cluster_count() as u32)
        .filter_map(|id| tree.get_cluster(id))
        .filter(|c| c.class == hdlod::tree::ClusterClass::Dynamic && c.motion.is_some())
        .count();
    assert!(dynamic >= 3, "{dynamic} moving dynamic clusters");
}

#[test]
fn bad_placements_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    write_crane(dir.path());
    let cases: Vec<(serde_json::Value, &str, &str)> = vec![
        (
            serde_json::json!([{"animation": "dig", "play": [0]}]),
            "clips[0].animation",
            "no model has animation \"dig\"",
        ),
        (
            serde_json::json!([{"animation": 9, "play": [0]}]),
            "clips[0].animation",
            "no model has animation 9",
        ),
        (
            serde_json::json!([{"animation": "slew", "model": "other.glb", "play": [0]}]),
            "clips[0].model",
            "is not one of models",
        ),
        (
            serde_json::json!([{"animation": "slew"}]),
            "clips[0]",
            "exactly one of play, loop and keys",
        ),
        (
            serde_json::json!([{"animation": "slew", "play": [0], "keys": [{"t": 0, "clip_time": 0}]}]),
            "clips[0]",
            "exactly one of play, loop and keys",
        ),
        (
            serde_json::json!([{"animation": "slew", "play": [0, 5]}]),
            "clips[0]",
            "plays twice at once",
        ),
        (
            serde_json::json!([{"animation": "slew", "loop": {"from": 100, "to": 50}}]),
            "clips[0].loop.to",
            "is not after loop.from",
        ),
        (
            serde_json::json!([{"animation": "slew", "speed": 2.0, "loop": {"from": 0, "to": 9.0 * DAY}}]),
            "clips[0].loop",
            "at most 100000",
        ),
        (
            serde_json::json!([{"animation": "slew", "speed": 0, "play": [0]}]),
            "clips[0].speed",
            "is not above 0",
        ),
        (
            serde_json::json!([{"animation": "slew", "keys": [{"t": 10, "clip_time": 0}, {"t": 5, "clip_time": 1}]}]),
            "clips[0].keys[1].t",
            "keys go forward in time",
        ),
        (
            serde_json::json!([{"animation": "slew", "play": ["2025-13-01"]}]),
            "clips[0].play[0]",
            "",
        ),
        (
            serde_json::json!([
                {"animation": "slew", "play": [0]},
                {"animation": "slew", "play": [5]}
            ]),
            "clips",
            "animate node 1 at the same time",
        ),
    ];
    for (clips, at, message) in cases {
        let err = load(dir.path(), &scene_json(clips.clone())).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("scene.json"), "{clips}: {text}");
        assert!(text.contains(at), "{clips}: {text} does not name {at}");
        assert!(
            text.contains(message),
            "{clips}: {text} does not say {message}"
        );
    }
    // A clip on an object that also has keyframes of its own.
    let mut json = scene_json(serde_json::json!([{"animation": "slew", "play": [0]}]));
    json["motion"] =
        serde_json::json!({"trolley": [{"t": 0}, {"t": 10, "translation": [1, 0, 0]}]});
    let text = load(dir.path(), &json).unwrap_err().to_string();
    assert!(text.contains("motion.\"trolley\""), "{text}");
    assert!(text.contains("also moves with a clip"), "{text}");
    // Two clips over one node at different times are fine; over a parent
    // and a child at once too (they compose).
    let fine = serde_json::json!([
        {"animation": "slew", "play": [0, 100]},
        {"animation": "spin", "play": [3]}
    ]);
    load(dir.path(), &scene_json(fine)).unwrap();
}

#[test]
fn bad_animation_data_is_refused_naming_the_channel() {
    let dir = tempfile::tempdir().unwrap();
    write_crane(dir.path());
    let path = dir.path().join("crane.gltf");
    let good: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    // Six values (a cubic spline's) for two linear keys; key times that go
    // back.
    let mut wrong_count = good.clone();
    wrong_count["animations"][1]["samplers"][0]["interpolation"] = "LINEAR".into();
    let mut backwards = good.clone();
    let input = backwards["animations"][0]["samplers"][0]["input"]
        .as_u64()
        .unwrap() as usize;
    let view = backwards["accessors"][input]["bufferView"]
        .as_u64()
        .unwrap() as usize;
    let offset = backwards["bufferViews"][view]["byteOffset"]
        .as_u64()
        .unwrap() as usize;
    let mut bin = std::fs::read(dir.path().join("crane.bin")).unwrap();
    bin[offset..offset + 8].copy_from_slice(&[5.0f32.to_le_bytes(), 1.0f32.to_le_bytes()].concat());
    backwards["accessors"][input]["min"] = serde_json::json!([1.0]);
    backwards["accessors"][input]["max"] = serde_json::json!([5.0]);
    for (gltf, bin_bytes, at, message) in [
        (
            &wrong_count,
            None,
            "animations[1].channels[0]",
            "6 output values for 2 keys (expected 2)",
        ),
        (
            &backwards,
            Some(&bin),
            "animations[0].channels[0]",
            "key 1 at 1 s is not after key 0 at 5 s",
        ),
    ] {
        std::fs::write(&path, gltf.to_string()).unwrap();
        if let Some(b) = bin_bytes {
            std::fs::write(dir.path().join("crane.bin"), b).unwrap();
        }
        let text = load(dir.path(), &scene_json(placements()))
            .unwrap_err()
            .to_string();
        assert!(text.contains("crane.gltf"), "{text}");
        assert!(text.contains(at), "{text} does not name {at}");
        assert!(text.contains(message), "{text} does not say {message}");
    }
}

//! Every kind of bad input of a scene gives an error that names the file and
//! the task, object or field at fault, and a failed save writes nothing.

mod common;

use std::path::{Path, PathBuf};

use common::{sample_scene, saved_sample};
use hdlod::scene::format::{load, save};
use serde_json::{Value, json};

/// A saved copy of the sample scene to break.
struct Site {
    _tmp: tempfile::TempDir,
    dir: PathBuf,
}

impl Site {
    fn new() -> Site {
        let tmp = tempfile::tempdir().unwrap();
        let dir = saved_sample(tmp.path());
        Site { _tmp: tmp, dir }
    }

    fn json(&self) -> Value {
        serde_json::from_str(&std::fs::read_to_string(self.dir.join("scene.json")).unwrap())
            .unwrap()
    }

    fn write_json(&self, json: &Value) {
        std::fs::write(self.dir.join("scene.json"), json.to_string()).unwrap();
    }

    /// Edits scene.json, loads, and returns the error message.
    fn error_after(&self, edit: impl FnOnce(&mut Value)) -> String {
        let mut json = self.json();
        edit(&mut json);
        self.write_json(&json);
        self.error()
    }

    fn error(&self) -> String {
        match load(&self.dir) {
            Ok(_) => panic!("the broken scene loaded"),
            Err(e) => e.to_string(),
        }
    }
}

fn assert_names(message: &str, parts: &[&str]) {
    for p in parts {
        assert!(message.contains(p), "{message:?} does not name {p:?}");
    }
}

#[test]
fn malformed_json() {
    let site = Site::new();
    std::fs::write(
        site.dir.join("scene.json"),
        "{\"format\": \"hdlod-scene/1\",\n  \"name\": ",
    )
    .unwrap();
    assert_names(&site.error(), &["scene.json", "line 2"]);
}

#[test]
fn unknown_field() {
    let site = Site::new();
    let e = site.error_after(|j| j["tasks"][1]["colour"] = "red".into());
    assert_names(&e, &["scene.json", "tasks[1]", "unknown field `colour`"]);
    let e = site.error_after(|j| {
        j["tasks"][1].as_object_mut().unwrap().remove("colour");
        j["extra"] = 1.into();
    });
    assert_names(&e, &["scene.json", "unknown field `extra`"]);
}

#[test]
fn task_naming_a_missing_object() {
    let site = Site::new();
    let e = site.error_after(|j| j["tasks"][2]["objects"] = json!(["S-1", "ghost"]));
    assert_names(
        &e,
        &["scene.json", "tasks[2] \"T3\"", "\"ghost\" does not exist"],
    );
}

#[test]
fn task_finishing_before_it_starts() {
    let site = Site::new();
    let e = site.error_after(|j| {
        j["tasks"][0]["start"] = "2025-03-05".into();
        j["tasks"][0]["finish"] = "2025-03-04".into();
    });
    assert_names(
        &e,
        &[
            "scene.json",
            "tasks[0] \"T1\"",
            "finish 2025-03-04 is before start 2025-03-05",
        ],
    );
}

#[test]
fn unknown_task_type() {
    let site = Site::new();
    let e = site.error_after(|j| j["tasks"][1]["type"] = "party".into());
    assert_names(
        &e,
        &[
            "scene.json",
            "tasks[1] \"T2\".type",
            "\"party\"",
            "INSTALLATION",
        ],
    );
}

#[test]
fn huge_or_invalid_times() {
    let site = Site::new();
    let e = site.error_after(|j| j["tasks"][0]["start"] = "2025-13-45".into());
    assert_names(
        &e,
        &[
            "scene.json",
            "tasks[0] \"T1\".start",
            "2025-13-45",
            "ISO 8601",
        ],
    );
    let e = site.error_after(|j| j["tasks"][0]["start"] = 1e300.into());
    assert_names(
        &e,
        &[
            "scene.json",
            "tasks[0] \"T1\".start",
            "1e300 s is more than",
        ],
    );
    let e = site.error_after(|j| j["time"]["end"] = "99999-01-01".into());
    assert_names(&e, &["scene.json", "time.end"]);
    let e = site.error_after(|j| j["time"]["end"] = "2025-02-01".into());
    assert_names(&e, &["scene.json", "time.end", "not after the start"]);
    // JSON has no NaN or infinity; a number too large for f64 is the closest.
    let mut text = std::fs::read_to_string(site.dir.join("scene.json")).unwrap();
    text = text.replacen("\"end\":\"2025-02-01\"", "\"end\":1e999", 1);
    std::fs::write(site.dir.join("scene.json"), text).unwrap();
    assert_names(&site.error(), &["scene.json", "time.end", "out of range"]);
}

#[test]
fn bad_motion() {
    let site = Site::new();
    let e = site.error_after(|j| j["motion"]["truck-1"][1]["t"] = 0.into());
    assert_names(
        &e,
        &[
            "scene.json",
            "motion.\"truck-1\"[1].t",
            "not after keyframe 0",
        ],
    );
    let e = site.error_after(|j| j["motion"]["truck-1"][1]["translation"][0] = 1e300.into());
    assert_names(
        &e,
        &[
            "scene.json",
            "motion.truck-1[1].translation[0]",
            "out of range",
        ],
    );
    let e = site.error_after(|j| {
        j["motion"]["truck-1"][1]["translation"][0] = 1.into();
        j["motion"]["digger"] = json!([{"t": 0}]);
    });
    assert_names(&e, &["scene.json", "motion.\"digger\"", "does not exist"]);
}

#[test]
fn objects_entry_naming_no_node() {
    let site = Site::new();
    let e = site.error_after(|j| j["objects"]["ghost"] = json!({"properties": {"a": "b"}}));
    assert_names(
        &e,
        &["scene.json", "objects.\"ghost\"", "names no mesh node"],
    );
}

#[test]
fn skipped_objects_are_left_out_and_may_not_be_scheduled() {
    let site = Site::new();
    let mut j = site.json();
    j["objects"]["B-1"] = json!({"skip": true});
    j["tasks"].as_array_mut().unwrap().remove(1);
    // The scaffolding followed the task removed.
    j["tasks"][1]
        .as_object_mut()
        .unwrap()
        .remove("predecessors");
    site.write_json(&j);
    let scene = load(&site.dir).unwrap();
    assert_eq!(scene.objects.len(), 3);
    assert!(scene.objects.iter().all(|o| o.id != "B-1"));
    let e = site.error_after(|j| j["tasks"][0]["objects"] = json!(["B-1"]));
    assert_names(&e, &["scene.json", "tasks[0] \"T1\"", "\"B-1\" is skipped"]);
}

#[test]
fn missing_gltf() {
    let site = Site::new();
    std::fs::remove_file(site.dir.join("sample.glb")).unwrap();
    assert_names(&site.error(), &["scene.json", "models[0]", "sample.glb"]);
}

#[test]
fn corrupt_gltf() {
    let site = Site::new();
    let glb = site.dir.join("sample.glb");
    let bytes = std::fs::read(&glb).unwrap();
    std::fs::write(&glb, &bytes[..bytes.len() / 2]).unwrap();
    assert_names(&site.error(), &["sample.glb", "glTF"]);
    std::fs::write(&glb, b"definitely not a model").unwrap();
    assert_names(&site.error(), &["sample.glb", "not a valid glTF"]);
}

/// Overwrites the first position of the GLB's binary chunk (node 0's mesh
/// starts there).
fn poison_first_vertex(glb: &Path, value: f32) {
    let mut bytes = std::fs::read(glb).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let bin = 12 + 8 + json_len + 8;
    bytes[bin..bin + 4].copy_from_slice(&value.to_le_bytes());
    std::fs::write(glb, bytes).unwrap();
}

#[test]
fn nan_or_infinite_coordinates() {
    for value in [f32::NAN, f32::INFINITY] {
        let site = Site::new();
        poison_first_vertex(&site.dir.join("sample.glb"), value);
        assert_names(
            &site.error(),
            &[
                "sample.glb",
                "node 0 \"C-1\"",
                "mesh",
                "non-finite coordinate",
            ],
        );
    }
}

/// A .gltf with one triangle (or line) in an external .bin, nodes as given.
fn write_gltf(dir: &Path, mode: u32, nodes: Value) -> PathBuf {
    let positions: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let bytes: Vec<u8> = positions.iter().flat_map(|f| f.to_le_bytes()).collect();
    std::fs::write(dir.join("tri.bin"), &bytes).unwrap();
    let count = nodes.as_array().unwrap().len();
    let gltf = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"uri": "tri.bin", "byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "meshes": [{"name": "wire", "primitives": [{"attributes": {"POSITION": 0}, "mode": mode}]}],
        "nodes": nodes,
        "scenes": [{"nodes": (0..count).collect::<Vec<_>>()}],
        "scene": 0
    });
    let path = dir.join("extra.gltf");
    std::fs::write(&path, gltf.to_string()).unwrap();
    path
}

fn add_model(site: &Site, nodes: Value, mode: u32) -> String {
    write_gltf(&site.dir, mode, nodes);
    site.error_after(|j| {
        j["models"]
            .as_array_mut()
            .unwrap()
            .push("extra.gltf".into())
    })
}

#[test]
fn non_triangle_primitive() {
    let site = Site::new();
    let e = add_model(&site, json!([{"name": "rope", "mesh": 0}]), 1);
    assert_names(
        &e,
        &[
            "extra.gltf",
            "node 0 \"rope\"",
            "mesh 0 \"wire\"",
            "primitive 0",
            "only TRIANGLES",
        ],
    );
}

#[test]
fn node_without_an_id() {
    let site = Site::new();
    let e = add_model(&site, json!([{"mesh": 0}]), 4);
    assert_names(
        &e,
        &["extra.gltf", "node 0", "neither extras.id nor a name"],
    );
}

#[test]
fn duplicate_object_id() {
    let site = Site::new();
    let e = add_model(&site, json!([{"mesh": 0, "extras": {"id": "C-1"}}]), 4);
    assert_names(&e, &["extra.gltf", "node 0 \"C-1\"", "sample.glb node 0"]);
}

#[test]
fn a_valid_extra_gltf_model_loads_with_world_transforms() {
    let site = Site::new();
    write_gltf(
        &site.dir,
        4,
        json!([
            {"name": "frame", "translation": [10, 0, 0], "children": [1]},
            {"name": "tri", "mesh": 0, "translation": [0, 5, 0]}
        ]),
    );
    let mut j = site.json();
    j["models"]
        .as_array_mut()
        .unwrap()
        .push("extra.gltf".into());
    site.write_json(&j);
    let scene = load(&site.dir).unwrap();
    let tri = scene.objects.iter().find(|o| o.id == "tri").unwrap();
    assert_eq!(
        tri.transform.w_axis.truncate(),
        glam::Vec3::new(10.0, 5.0, 0.0)
    );
    assert_eq!(scene.meshes[tri.mesh].triangle_count(), 1);
    assert_eq!(tri.color, [1.0; 4], "glTF's default material is white");
}

#[test]
fn failed_save_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let mut bad = sample_scene();
    bad.meshes[0].positions[3].y = f32::NAN;
    let fresh = tmp.path().join("fresh");
    let e = save(&bad, &fresh).unwrap_err().to_string();
    assert_names(&e, &["mesh 0", "non-finite"]);
    assert!(!fresh.exists());

    let existing = tmp.path().join("existing");
    save(&sample_scene(), &existing).unwrap();
    let before = std::fs::read(existing.join("sample.glb")).unwrap();
    let mut bad = sample_scene();
    bad.tasks[0].objects.push("ghost".into());
    let e = save(&bad, &existing).unwrap_err().to_string();
    assert_names(&e, &["task \"T1\"", "\"ghost\""]);
    assert_eq!(std::fs::read(existing.join("sample.glb")).unwrap(), before);
    let names: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("existing")]);
}

#[test]
fn bad_actual_and_baseline_dates_and_parents_are_named() {
    let e = Site::new().error_after(|j| {
        j["tasks"][0]
            .as_object_mut()
            .unwrap()
            .remove("actual_start");
    });
    assert_names(
        &e,
        &[
            "scene.json",
            "tasks[0] \"T1\".actual_finish",
            "needs an actual start",
        ],
    );
    let e = Site::new().error_after(|j| {
        j["tasks"][0]["actual_start"] = json!(86400 * 3);
        j["tasks"][0]["actual_finish"] = json!(86400 * 2);
    });
    assert_names(
        &e,
        &["tasks[0] \"T1\".actual_finish", "before the actual start"],
    );
    let e = Site::new().error_after(|j| {
        j["tasks"][1]
            .as_object_mut()
            .unwrap()
            .remove("baseline_finish");
    });
    assert_names(
        &e,
        &["tasks[1] \"T2\"", "both baseline_start and baseline_finish"],
    );
    let e = Site::new().error_after(|j| j["tasks"][1]["parent"] = json!("T9"));
    assert_names(
        &e,
        &["tasks[1] \"T2\".parent", "\"T9\" is not the id of a task"],
    );
    let e = Site::new().error_after(|j| {
        j["tasks"][1]["parent"] = json!("T1");
        j["tasks"][0]["parent"] = json!("T2");
    });
    assert_names(&e, &["parent", "cycle"]);
    let e = Site::new().error_after(|j| j["tasks"][0]["actual_start"] = json!("soon"));
    assert_names(&e, &["tasks[0] \"T1\".actual_start"]);
}

#[test]
fn bad_links_are_named() {
    // The sample's scaffolding (T3) follows the beams (T2), FF + 1 day.
    let e = Site::new().error_after(|j| j["tasks"][2]["predecessors"][0]["task"] = json!("T9"));
    assert_names(
        &e,
        &[
            "tasks[2] \"T3\".predecessors[0]",
            "\"T9\" is not the id of a task",
        ],
    );
    let e = Site::new().error_after(|j| j["tasks"][2]["predecessors"][0]["task"] = json!("T3"));
    assert_names(
        &e,
        &["tasks[2] \"T3\".predecessors[0]", "cannot follow itself"],
    );
    let e = Site::new().error_after(|j| j["tasks"][2]["predecessors"][0]["type"] = json!("XX"));
    assert_names(&e, &["tasks[2].predecessors[0].type", "XX"]);
    let e = Site::new().error_after(|j| j["tasks"][2]["predecessors"][0]["lag"] = json!(1e12));
    assert_names(&e, &["tasks[2] \"T3\".predecessors[0].lag", "out of range"]);
    // T1 after T3, T2 after T1, T3 after T2: a cycle, named task by task.
    let e = Site::new().error_after(|j| {
        j["tasks"][0]["predecessors"] = json!([{"task": "T3"}]);
        j["tasks"][1]["predecessors"] = json!([{"task": "T1", "type": "SS", "lag": -3600}]);
    });
    assert_names(
        &e,
        &[
            "scene.json",
            "predecessors",
            "cycle",
            "T1 -> T2 -> T3 -> T1",
        ],
    );
}

#[test]
fn a_bad_appearance_profile_is_named() {
    let e =
        Site::new().error_after(|j| j["appearance"]["types"]["construct"]["after"] = json!("gone"));
    assert_names(
        &e,
        &["scene.json", "appearance.types.construct.after", "\"gone\""],
    );
    let e = Site::new().error_after(|j| {
        j["appearance"]["types"]["construct"]["active"] =
            json!({"color": "#00ff00", "transparency": 2});
    });
    assert_names(&e, &["appearance.types.construct.active", "transparency 2"]);
    let e = Site::new().error_after(|j| j["appearance"]["format"] = json!("hdlod-appearance/9"));
    assert_names(&e, &["appearance.format", "hdlod-appearance/1"]);
}

#[test]
fn actual_dates_drive_presence_when_the_schedule_follows_them() {
    let site = Site::new();
    let day = 86400.0;
    let mut json = site.json();
    json["schedule_options"] = json!({"construct_at": "start"});
    site.write_json(&json);
    let planned = load(&site.dir).unwrap();
    // The dates alone, the instants at their defaults.
    json["schedule_options"] = json!("actual");
    site.write_json(&json);
    let actual = load(&site.dir).unwrap();
    let beam = |s: &hdlod::scene::Scene| {
        s.objects
            .iter()
            .find(|o| o.id == "B-1")
            .unwrap()
            .visibility
            .clone()
    };
    // Planned: the beams appear at their task's planned start; on the
    // record, a day later (the sample builds at the start).
    assert!(beam(&planned).at(3.5 * day) && !beam(&actual).at(3.5 * day));
    assert!(beam(&actual).at(4.5 * day));
    // A task the record never started never acts.
    json["tasks"][1]
        .as_object_mut()
        .unwrap()
        .remove("actual_start");
    site.write_json(&json);
    let unstarted = load(&site.dir).unwrap();
    assert!(!beam(&unstarted).at(9.0 * day));
}

#[test]
fn a_bad_georeference_is_named() {
    let e = Site::new().error_after(|j| j["georeference"]["latitude"] = json!(95.0));
    assert_names(&e, &["scene.json", "georeference.latitude", "95"]);
    let e = Site::new().error_after(|j| j["georeference"]["datum"] = json!("RD"));
    assert_names(&e, &["georeference", "datum"]);
}

#[test]
fn a_gltf_buffer_stays_inside_and_is_a_regular_file() {
    let site = Site::new();
    write_gltf(&site.dir, 4, json!([{"name": "tri", "mesh": 0}]));
    let gltf = site.dir.join("extra.gltf");
    let text = std::fs::read_to_string(&gltf).unwrap();
    std::fs::write(site.dir.join("../outside.bin"), [0u8; 36]).unwrap();
    for (uri, why) in [
        ("/dev/zero", "leads outside"),
        ("../outside.bin", "leads outside"),
        ("%2e%2e/outside.bin", "leads outside"),
        ("file:///dev/zero", "only relative paths and data URIs"),
    ] {
        std::fs::write(&gltf, text.replace("\"tri.bin\"", &format!("{uri:?}"))).unwrap();
        let e = site.error_after(|j| j["models"] = json!(["sample.glb", "extra.gltf"]));
        assert_names(&e, &["extra.gltf", "buffers[0]", why]);
    }
}

#[test]
fn a_scene_name_is_a_url_path_segment() {
    let site = Site::new();
    for (name, why) in [
        ("", "empty"),
        ("../../evil", "starts with a dot"),
        ("a/b\0c", "holds '/'"),
        ("two words", "holds ' '"),
    ] {
        let e = site.error_after(|j| j["name"] = json!(name));
        assert_names(&e, &["scene.json", "name", why]);
    }
    let mut scene = sample_scene();
    scene.name = String::new();
    let tmp = tempfile::tempdir().unwrap();
    let e = save(&scene, &tmp.path().join("out"))
        .unwrap_err()
        .to_string();
    assert_names(&e, &["scene name", "empty"]);
}

#[test]
fn a_skipped_object_must_name_a_mesh_node() {
    let site = Site::new();
    let e = site.error_after(|j| j["objects"]["nobody"] = json!({"skip": true}));
    assert_names(
        &e,
        &["scene.json", "objects.\"nobody\"", "names no mesh node"],
    );
}

/// The first moving object's id in the sample's scene.json.
fn mover(j: &Value) -> String {
    j["motion"]
        .as_object()
        .unwrap()
        .keys()
        .next()
        .unwrap()
        .clone()
}

#[test]
fn keyframes_go_forward_with_positive_scales() {
    let site = Site::new();
    let id = mover(&site.json());
    let e = site.error_after(|j| {
        let keys = j["motion"][&id].as_array_mut().unwrap();
        assert!(keys.len() >= 2);
        keys.reverse();
    });
    assert_names(
        &e,
        &[
            "scene.json",
            &format!("motion.{id:?}[1].t"),
            "not after keyframe 0",
        ],
    );
    for scale in [json!([1, 0, 1]), json!([1, -1, 1])] {
        let site = Site::new();
        let e = site.error_after(|j| j["motion"][&id][0]["scale"] = scale.clone());
        assert_names(
            &e,
            &["scene.json", &format!("motion.{id:?}[0]"), "scale", "<= 0"],
        );
    }
    let site = Site::new();
    let e = site.error_after(|j| j["motion"][&id][0]["translation"] = json!([1e300, 0, 0]));
    assert_names(
        &e,
        &["scene.json", "translation[0]", "1e300", "32-bit float"],
    );
    assert!(!e.contains("non-finite"), "{e}");
}

#[test]
fn a_task_names_each_object_once_and_some_unless_a_summary() {
    let site = Site::new();
    let e = site.error_after(|j| {
        let first = j["tasks"][0]["objects"][0].clone();
        j["tasks"][0]["objects"].as_array_mut().unwrap().push(first);
    });
    assert_names(
        &e,
        &["scene.json", "tasks[0]", "objects[", "is also objects[0]"],
    );
    // T3 is nobody's parent.
    let site = Site::new();
    let e = site.error_after(|j| j["tasks"][2]["objects"] = json!([]));
    assert_names(&e, &["scene.json", "tasks[2]", "objects", "summary task"]);
    // A summary task (some task's parent) has none.
    let site = Site::new();
    let mut j = site.json();
    j["tasks"]
        .as_array_mut()
        .unwrap()
        .push(json!({"id": "S", "type": "construct", "start": 0, "finish": 10, "objects": []}));
    j["tasks"][2]["parent"] = json!("S");
    site.write_json(&j);
    load(&site.dir).unwrap();
}

#[test]
fn a_primitive_naming_a_missing_position_accessor_is_an_error() {
    // gltf-json's validation used to panic on it (a fuzzing finding).
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("bad.gltf");
    let gltf = json!({
        "asset": {"version": "2.0"},
        "meshes": [{"primitives": [{"attributes": {"POSITION": 3}}]}],
        "nodes": [{"name": "n", "mesh": 0}],
        "scenes": [{"nodes": [0]}]
    });
    std::fs::write(&path, gltf.to_string()).unwrap();
    let e = hdlod::io::read_mesh(&path).unwrap_err().to_string();
    assert_names(
        &e,
        &[
            "bad.gltf",
            "meshes[0].primitives[0].attributes.POSITION",
            "accessor 3 does not exist",
        ],
    );
}

#[test]
fn a_glb_shorter_than_its_header_is_an_error() {
    // gltf's GLB parser subtracted the header from it unchecked (a fuzzing
    // finding).
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("short.glb");
    let mut bytes = b"glTF".to_vec();
    bytes.extend(2u32.to_le_bytes());
    bytes.extend(0u32.to_le_bytes());
    bytes.extend(b"JSON{}  ");
    std::fs::write(&path, bytes).unwrap();
    let e = hdlod::io::read_mesh(&path).unwrap_err().to_string();
    assert_names(&e, &["short.glb", "GLB header", "length 0"]);
}

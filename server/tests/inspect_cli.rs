//! `hdlod inspect` on a saved scene: the JSON follows its schema and has the
//! right counts, the table is readable, bad input exits non-zero.

mod common;

use common::{assert_success, hdlod, saved_sample};

#[test]
fn json_follows_the_schema_and_counts() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = saved_sample(tmp.path());
    let out = hdlod(&["inspect".as_ref(), scene.as_os_str(), "--json".as_ref()]);
    assert_success(&out);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&json, "inspect.schema.json");
    assert_eq!(json["classes"]["pseudo_dynamic"]["objects"], 3);
    assert_eq!(json["classes"]["pseudo_dynamic"]["triangles"], 36);
    assert_eq!(json["classes"]["dynamic"]["triangles"], 4);
    assert_eq!(json["visibility_types"]["appearing"], 2);
    assert_eq!(json["bounds"]["max"][0], 10.0);
    assert_eq!(json["time"]["end"], "2025-03-11T00:00:00Z");
}

#[test]
fn table_is_readable() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = saved_sample(tmp.path());
    let out = hdlod(&["inspect".as_ref(), scene.join("scene.json").as_os_str()]);
    assert_success(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.contains("scene sample: 4 objects, 2 distinct meshes, 40 triangles"),
        "{text}"
    );
    assert!(
        text.lines()
            .any(|l| l.split_whitespace().collect::<Vec<_>>() == ["pseudo_dynamic", "3", "36"]),
        "{text}"
    );
    assert!(
        text.contains("2025-03-01T00:00:00Z .. 2025-03-11T00:00:00Z"),
        "{text}"
    );
}

#[test]
fn bad_scene_exits_non_zero_with_the_reason() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = saved_sample(tmp.path());
    let file = scene.join("scene.json");
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    json["tasks"][0]["objects"] = serde_json::json!(["nobody"]);
    std::fs::write(&file, json.to_string()).unwrap();
    let out = hdlod(&["inspect".as_ref(), scene.as_os_str(), "--json".as_ref()]);
    assert!(!out.status.success());
    assert!(out.stdout.is_empty());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("scene.json")
            && stderr.contains("tasks[0] \"T1\"")
            && stderr.contains("\"nobody\""),
        "{stderr}"
    );

    let out = hdlod(&["inspect".as_ref(), tmp.path().join("missing").as_os_str()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing"));
}

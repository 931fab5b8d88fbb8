//! The scene.json files we write, and any committed under fixtures/, follow
//! schemas/scene.schema.json.

mod common;

use common::{repo, saved_sample, schema, schema_errors as errors};

fn validator() -> jsonschema::Validator {
    schema("scene.schema.json")
}

#[test]
fn written_scene_json_follows_the_schema() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(saved_sample(dir.path()).join("scene.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    // The sample has every section, so the schema sees all of them.
    for key in ["objects", "tasks", "motion", "schedule_options"] {
        assert!(json.get(key).is_some(), "{key} missing in {text}");
    }
    assert_eq!(errors(&validator(), &json), Vec::<String>::new());
}

#[test]
fn committed_scenes_follow_the_schema() {
    let v = validator();
    let mut found = Vec::new();
    for dir in [repo().join("fixtures"), repo().join("docs")] {
        let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        for entry in entries.flatten() {
            let path = entry.path().join("scene.json");
            if path.is_file() {
                let json = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
                assert_eq!(
                    errors(&v, &json),
                    Vec::<String>::new(),
                    "{}",
                    path.display()
                );
                found.push(path);
            }
        }
    }
    // A search that finds nothing must not pass: the committed fixture is
    // among what it checked.
    let tiny = repo().join("fixtures/skyscraper-tiny/scene.json");
    assert!(
        found.contains(&tiny),
        "{} not checked: {found:?}",
        tiny.display()
    );
}

#[test]
fn the_documented_example_follows_the_schema() {
    let example = serde_json::json!({
        "format": "hdlod-scene/1",
        "name": "skyscraper-tiny",
        "up": "y",
        "time": {"start": "2025-03-01T00:00:00Z", "end": "2026-03-01T00:00:00Z"},
        "models": ["skyscraper-tiny.glb"],
        "objects": {"crane-1": {"properties": {"kind": "tower crane"}}, "helper": {"skip": true}},
        "tasks": [{"id": "T1", "name": "Level 1 columns", "type": "INSTALLATION",
                   "start": "2025-03-02T08:00:00Z", "finish": 86400, "objects": ["L01-C-001"]}],
        "motion": {"truck-3": [{"t": 0, "translation": [0, 0, 0], "rotation": [0, 0, 0, 1], "scale": [1, 1, 1]},
                               {"t": "2025-03-05", "translation": [10, 0, 0]}]},
        "schedule_options": {"construct_at": "start", "demolish_at": "finish"}
    });
    let v = validator();
    assert_eq!(errors(&v, &example), Vec::<String>::new());
    // And the schema is strict where the loader is.
    let mut bad = example.clone();
    bad["tasks"][0]["colour"] = "red".into();
    assert!(!errors(&v, &bad).is_empty());
    let mut bad = example;
    bad["time"]["start"] = "next monday".into();
    assert!(!errors(&v, &bad).is_empty());
}

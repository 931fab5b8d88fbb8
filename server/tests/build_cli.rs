//! `hdlod build` and `hdlod inspect TREE` on the committed tiny fixture: the
//! JSON follows the schemas, bad configurations are clear errors, a failed
//! build leaves the previous tree as it was.

mod common;

use common::{assert_success, hdlod, repo};

#[test]
fn builds_the_tiny_fixture_and_inspects_the_tree() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = tmp.path().join("tree");
    let fixture = repo().join("fixtures/skyscraper-tiny");
    let out = hdlod(&[
        "build".as_ref(),
        fixture.as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
        "--json".as_ref(),
    ]);
    assert_success(&out);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&summary, "build-summary.schema.json");
    assert_eq!(summary["objects"], 628);

    let out = hdlod(&["inspect".as_ref(), tree.as_os_str(), "--json".as_ref()]);
    assert_success(&out);
    let inspect: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&inspect, "inspect-tree.schema.json");
    assert_eq!(inspect["clusters"], summary["clusters"]);
    // Level 0 holds the leaves: every visible object (a moving object that
    // stands still before or after its motion has more than one).
    let levels = inspect["levels"].as_array().unwrap();
    assert_eq!(levels[0]["level"], 0);
    assert_eq!(levels[0]["clusters"], inspect["leaves"]);
    assert!(
        levels[0]["clusters"].as_u64().unwrap()
            >= 628 - summary["absent_objects"].as_u64().unwrap()
    );

    let table = hdlod(&["inspect".as_ref(), tree.as_os_str()]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(
        text.contains("tree skyscraper-tiny") && text.contains("max eps"),
        "{text}"
    );
}

#[test]
fn a_bad_configuration_names_the_field_and_keeps_the_old_tree() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = tmp.path().join("tree");
    std::fs::create_dir_all(&tree).unwrap();
    std::fs::write(tree.join("marker"), "the previous tree").unwrap();
    let fixture = repo().join("fixtures/skyscraper-tiny");
    for (config, field) in [
        (r#"{"max_children": 1}"#, "max_children"),
        (r#"{"k_eps": -1}"#, "k_eps"),
        (r#"{"gamma_maxx": 0.1}"#, "gamma_maxx"),
    ] {
        let path = tmp.path().join("config.json");
        std::fs::write(&path, config).unwrap();
        let out = hdlod(&[
            "build".as_ref(),
            fixture.as_os_str(),
            "--out".as_ref(),
            tree.as_os_str(),
            "--config".as_ref(),
            path.as_os_str(),
        ]);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("config.json") && err.contains(field), "{err}");
    }
    let out = hdlod(&[
        "build".as_ref(),
        tmp.path().join("no-such-scene").as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no-such-scene"));
    assert_eq!(
        std::fs::read_to_string(tree.join("marker")).unwrap(),
        "the previous tree"
    );
}

/// The README's main command: `hdlod demo` generates, builds and serves.
#[test]
fn demo_generates_builds_and_serves() {
    let tmp = tempfile::tempdir().unwrap();
    let demo = common::Server::spawn(&[
        "demo".as_ref(),
        "--scale".as_ref(),
        "tiny".as_ref(),
        "--addr".as_ref(),
        "127.0.0.1:0".as_ref(),
        "--dir".as_ref(),
        tmp.path().as_os_str(),
    ]);
    let scenes = demo.get_json("/api/v1/scenes");
    drop(demo);
    assert_eq!(scenes["scenes"][0]["name"], "skyscraper-tiny");
    assert!(
        tmp.path()
            .join("skyscraper-tiny-tree/manifest.json")
            .is_file()
    );
}

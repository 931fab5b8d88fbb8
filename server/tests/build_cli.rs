//! `hdlod build` and `hdlod inspect TREE` on the committed tiny fixture: the
//! JSON follows the schemas, bad configurations are clear errors, a failed
//! build leaves the previous tree as it was.

#[path = "../../hdlod/tests/common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn hdlod(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hdlod"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap()
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn builds_the_tiny_fixture_and_inspects_the_tree() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = tmp.path().join("tree");
    let fixture = root().join("fixtures/skyscraper-tiny");
    let out = hdlod(&[
        "build".as_ref(),
        fixture.as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
        "--json".as_ref(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&summary, "build-summary.schema.json");
    assert_eq!(summary["objects"], 628);

    let out = hdlod(&["inspect".as_ref(), tree.as_os_str(), "--json".as_ref()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
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
    let fixture = root().join("fixtures/skyscraper-tiny");
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
    use std::io::{BufRead, BufReader};
    let tmp = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_hdlod"))
        .args(["demo", "--scale", "tiny", "--addr", "127.0.0.1:0", "--dir"])
        .arg(tmp.path())
        .env("RUST_LOG", "warn")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let line = BufReader::new(stdout)
        .lines()
        .map_while(Result::ok)
        .find(|l| l.starts_with("listening on "));
    let answer = line.map(|l| {
        let base = l.trim_start_matches("listening on ").to_string();
        reqwest::blocking::get(format!("{base}/api/v1/scenes"))
            .and_then(|r| r.json::<serde_json::Value>())
    });
    child.kill().unwrap();
    child.wait().unwrap();
    let scenes = answer.expect("the demo prints its address").unwrap();
    assert_eq!(scenes["scenes"][0]["name"], "skyscraper-tiny");
    assert!(
        tmp.path()
            .join("skyscraper-tiny-tree/manifest.json")
            .is_file()
    );
}

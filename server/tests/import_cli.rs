//! `hdlod import ifc` on fixtures/ifc-tiny: the report and the scene follow
//! their schemas, the scene builds, bad input is a clear error.
#![cfg(feature = "ifc")]

#[path = "../../hdlod/tests/common/mod.rs"]
mod common;

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn hdlod(args: &[&OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hdlod"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap()
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/ifc-tiny")
        .join(name)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn imports_the_tiny_model_with_its_plan_and_builds_it() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("tiny");
    let (model, plan, links) = (
        fixture("tiny.ifc"),
        fixture("plan.xml"),
        fixture("links.json"),
    );
    let out = hdlod(&[
        "import".as_ref(),
        "ifc".as_ref(),
        model.as_os_str(),
        "--schedule".as_ref(),
        plan.as_os_str(),
        "--links".as_ref(),
        links.as_os_str(),
        "--out".as_ref(),
        scene.as_os_str(),
        "--json".as_ref(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&report, "import-report.schema.json");
    assert_eq!(report["elements"], 2);
    assert_eq!(
        report["skipped"]["IfcOpeningElement"]["opening: subtracted from its host"],
        1
    );
    let matched: Vec<u64> = report["rules"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["matched"].as_u64().unwrap())
        .collect();
    assert_eq!(matched, [1, 1, 1]);
    assert_eq!(report["unmatched"], serde_json::json!([]));

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(scene.join("scene.json")).unwrap()).unwrap();
    common::assert_matches_schema(&json, "scene.schema.json");
    assert_eq!(json["up"], "z");
    assert_eq!(
        json["objects"]["2WallTinyHdlod00000001"]["properties"]["storey"],
        "00 ground floor"
    );

    // The imported scene loads and builds like any other.
    let tree = tmp.path().join("tree");
    let out = hdlod(&[
        "build".as_ref(),
        scene.as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
        "--json".as_ref(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["objects"], 2);
    // Its object table names each element by what the import gave it.
    let objects: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tree.join("objects.json")).unwrap()).unwrap();
    common::assert_matches_schema(&objects, "tree-objects.schema.json");
    let wall = objects["objects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|o| o["id"] == "2WallTinyHdlod00000001")
        .expect("the wall is in the table");
    assert_eq!(wall["class"], "IfcWall");
    assert_eq!(wall["properties"]["source_file"], "tiny.ifc");
    assert_eq!(wall["name"], wall["properties"]["name"]);
    assert!(!wall["tasks"].as_array().unwrap().is_empty());

    // Without --json: the table with the rules and their counts.
    let out = hdlod(&[
        "import".as_ref(),
        "ifc".as_ref(),
        model.as_os_str(),
        "--schedule".as_ref(),
        plan.as_os_str(),
        "--links".as_ref(),
        links.as_os_str(),
        "--out".as_ref(),
        scene.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(
        table.contains("tiny.ifc") && table.contains("ground-floor walls"),
        "{table}"
    );
}

#[test]
fn bad_input_is_a_clear_error() {
    let tmp = tempfile::tempdir().unwrap();
    let broken = tmp.path().join("broken.ifc");
    let model = std::fs::read_to_string(fixture("tiny.ifc")).unwrap();
    std::fs::write(
        &broken,
        model.replace(
            "#63=IFCCARTESIANPOINT((1000.,-100.,500.));",
            "#63=IFCCARTESIANPOINT((1000.,-100.,500.)",
        ),
    )
    .unwrap();
    let out_dir = tmp.path().join("scene");
    let out = hdlod(&[
        "import".as_ref(),
        "ifc".as_ref(),
        broken.as_os_str(),
        "--out".as_ref(),
        out_dir.as_os_str(),
    ]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains("broken.ifc") && err.contains("#63"), "{err}");
    assert!(!out_dir.exists());

    let rules = tmp.path().join("links.json");
    std::fs::write(
        &rules,
        r#"{"format": "hdlod-links/1", "rules": [{"name": "x", "select": {}, "task": "nope"}]}"#,
    )
    .unwrap();
    let (model, plan) = (fixture("tiny.ifc"), fixture("plan.xml"));
    let out = hdlod(&[
        "import".as_ref(),
        "ifc".as_ref(),
        model.as_os_str(),
        "--schedule".as_ref(),
        plan.as_os_str(),
        "--links".as_ref(),
        rules.as_os_str(),
        "--out".as_ref(),
        out_dir.as_os_str(),
    ]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(
        err.contains("links.json") && err.contains("\"nope\""),
        "{err}"
    );
}

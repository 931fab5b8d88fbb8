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

#[test]
fn failed_geometry_is_named_and_a_file_without_any_element_is_an_error() {
    let tmp = tempfile::tempdir().unwrap();
    let model = std::fs::read_to_string(fixture("tiny.ifc")).unwrap();
    // The wall's placement is relative to itself.
    let looping = model.replace(
        "#41=IFCLOCALPLACEMENT(#35,#42);",
        "#41=IFCLOCALPLACEMENT(#41,#42);",
    );
    let path = tmp.path().join("looping.ifc");
    std::fs::write(&path, &looping).unwrap();
    let scene = tmp.path().join("scene");
    let out = hdlod(&[
        "import".as_ref(),
        "ifc".as_ref(),
        path.as_os_str(),
        "--out".as_ref(),
        scene.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(
        stdout.contains("1 elements whose geometry failed"),
        "{stdout}"
    );
    let warning = stderr
        .lines()
        .find(|l| l.starts_with("warning: looping.ifc: #40 "))
        .unwrap_or_else(|| panic!("{stderr}"));
    assert!(
        warning.contains("IfcWall 2WallTinyHdlod00000001") && warning.contains("cyclic"),
        "{warning}"
    );

    // The slab's brep names a record the file does not hold: nothing is
    // left to import.
    let hopeless = looping.replace("#121=IFCFACETEDBREP(#120);", "#121=IFCFACETEDBREP(#999);");
    let path = tmp.path().join("hopeless.ifc");
    std::fs::write(&path, hopeless).unwrap();
    let scene = tmp.path().join("nothing");
    let out = hdlod(&[
        "import".as_ref(),
        "ifc".as_ref(),
        path.as_os_str(),
        "--out".as_ref(),
        scene.as_os_str(),
    ]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(
        err.contains("hopeless.ifc") && err.contains("none of its 2 elements"),
        "{err}"
    );
    assert!(!scene.exists());
}

#[test]
fn imports_an_as_built_log_beside_the_plan() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("tiny");
    let log = tmp.path().join("built.csv");
    // "Walls" is two tasks of the plan (UIDs 2 and 4): the one planned to
    // start nearest 9-1-2024 is 2. "Paint" is in no plan.
    std::fs::write(
        &log,
        "GUID,TaskID,TaskName,TaskStart,TaskFinish\n\
         e1,ST10,Walls,9-1-2024,16-1-2024\n\
         e2,ST90,Paint,1-5-2024,2-5-2024\n",
    )
    .unwrap();
    let (model, plan, links) = (
        fixture("tiny.ifc"),
        fixture("plan.xml"),
        fixture("links.json"),
    );
    let args = |extra: &[&OsStr]| {
        let mut a: Vec<&OsStr> = vec![
            "import".as_ref(),
            "ifc".as_ref(),
            model.as_os_str(),
            "--schedule".as_ref(),
            plan.as_os_str(),
            "--actual".as_ref(),
            log.as_os_str(),
            "--links".as_ref(),
            links.as_os_str(),
            "--out".as_ref(),
            scene.as_os_str(),
        ];
        a.extend_from_slice(extra);
        hdlod(&a)
    };
    let out = args(&["--json".as_ref(), "--dates".as_ref(), "actual".as_ref()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&report, "import-report.schema.json");
    let a = &report["actual"];
    assert_eq!(
        [
            &a["rows"],
            &a["tasks"],
            &a["by_id"],
            &a["by_name"],
            &a["dated"],
            &a["unmatched_rows"]
        ],
        [2, 2, 0, 1, 1, 1]
    );
    assert_eq!(
        a["unmatched"],
        serde_json::json!(["built.csv: ST90 \"Paint\""])
    );
    assert_eq!(
        (&report["actual_tasks"], &report["summary_tasks"]),
        (&1.into(), &1.into())
    );
    assert!(text(&out.stderr).contains("match no task of the schedule"));

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(scene.join("scene.json")).unwrap()).unwrap();
    common::assert_matches_schema(&json, "scene.schema.json");
    assert_eq!(json["schedule_options"]["dates"], "actual");
    let tasks = json["tasks"].as_array().unwrap();
    let task = |id: &str| tasks.iter().find(|t| t["id"] == id).unwrap();
    assert_eq!(task("2")["actual_start"], "2024-01-09T00:00:00Z");
    assert_eq!(task("2")["actual_finish"], "2024-01-17T00:00:00Z");
    assert_eq!(task("2")["parent"], "1");
    assert_eq!(task("1")["objects"], serde_json::json!([]));

    // The table says it too.
    let out = args(&[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(
        table.contains("as built: 2 rows, 2 tasks (0 matched by id, 1 by name)")
            && table.contains("1 rows match no task"),
        "{table}"
    );

    // A log that is not a CSV is refused by name.
    let out = hdlod(&[
        "import".as_ref(),
        "ifc".as_ref(),
        model.as_os_str(),
        "--actual".as_ref(),
        plan.as_os_str(),
        "--out".as_ref(),
        scene.as_os_str(),
    ]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains("plan.xml") && err.contains(".csv"), "{err}");
}

#[test]
fn imports_a_p6_schedule_with_its_links_and_inspects_them() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("p6");
    let model = fixture("tiny.ifc");
    let xer = fixture("../schedules/tiny.xer");
    let rules = tmp.path().join("links.json");
    std::fs::write(
        &rules,
        r#"{"format": "hdlod-links/1", "rules": [
            {"name": "walls by level", "select": {"class": "IfcWall*"},
             "tasks": {"codes": {"Trade": "WALLS"}}, "match": {"storey": "code:Level"}},
            {"name": "slab", "select": {"class": "IfcSlab"}, "task": "A1010"}]}"#,
    )
    .unwrap();
    let args = |project: Option<&'static str>| {
        let mut a: Vec<&OsStr> = vec![
            "import".as_ref(),
            "ifc".as_ref(),
            model.as_os_str(),
            "--schedule".as_ref(),
            xer.as_os_str(),
            "--links".as_ref(),
            rules.as_os_str(),
            "--out".as_ref(),
            scene.as_os_str(),
            "--json".as_ref(),
        ];
        if let Some(p) = project {
            a.extend::<[&OsStr; 2]>(["--project".as_ref(), p.as_ref()]);
        }
        a
    };
    // Two projects in the file: the error lists them.
    let out = hdlod(&args(None));
    assert!(!out.status.success());
    let e = text(&out.stderr);
    assert!(
        e.contains("--project") && e.contains("TINY") && e.contains("OTHER"),
        "{e}"
    );

    let out = hdlod(&args(Some("TINY")));
    assert!(out.status.success(), "{}", text(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&report, "import-report.schema.json");
    assert_eq!(
        (report["links"].as_u64(), report["unmatched_tasks"].as_u64()),
        (Some(1), Some(2))
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(scene.join("scene.json")).unwrap()).unwrap();
    common::assert_matches_schema(&json, "scene.schema.json");
    let slab = json["tasks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["id"] == "A1010")
        .unwrap();
    assert_eq!(
        slab["predecessors"],
        serde_json::json!([{"task": "A1000", "type": "FS", "lag": 57600.0}])
    );

    let out = hdlod(&["inspect".as_ref(), scene.as_os_str(), "--json".as_ref()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&summary, "inspect.schema.json");
    assert_eq!(
        summary["schedule"],
        serde_json::json!({"tasks": 6, "summary_tasks": 2, "depth": 3, "linked_tasks": 2, "links": 1})
    );
    let out = hdlod(&["inspect".as_ref(), scene.as_os_str()]);
    assert!(
        text(&out.stdout)
            .contains("2 summary tasks, 3 levels of work breakdown; 2 tasks linked by 1 links")
    );
}

#[test]
fn bench_xer_reads_the_site_schedule_it_writes() {
    let tmp = tempfile::tempdir().unwrap();
    let xer = tmp.path().join("site.xer");
    let out = hdlod(&[
        "bench".as_ref(),
        "xer".as_ref(),
        "--scale".as_ref(),
        "tiny".as_ref(),
        "--repeats".as_ref(),
        "1".as_ref(),
        "--out".as_ref(),
        xer.as_os_str(),
        "--json".as_ref(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let n = |k: &str| report[k].as_u64().unwrap();
    // Every activity and every WBS node below the project's is a task.
    assert!(n("activities") > 500 && n("links") > 0);
    assert_eq!(n("tasks"), n("activities") + n("wbs_nodes") - 1);
    assert!(xer.is_file());
}

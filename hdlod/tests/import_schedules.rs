//! Schedules and linking rules: Microsoft Project XML, the element-task CSV,
//! and rules over the objects of fixtures/ifc-tiny/tiny.ifc.
#![cfg(feature = "ifc")]

use std::path::{Path, PathBuf};

use hdlod::import::{Options, import, links_csv, msproject};
use hdlod::scene::{TaskType, VisibilityType};
use hdlod::time::parse_date;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn tiny() -> PathBuf {
    root().join("fixtures/ifc-tiny/tiny.ifc")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

const PLAN: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Project xmlns="http://schemas.microsoft.com/project">
  <Name>tiny</Name>
  <Tasks>
    <Task><UID>1</UID><Name>Shell</Name><OutlineLevel>1</OutlineLevel><Summary>1</Summary>
      <Start>2024-01-08T08:00:00</Start><Finish>2024-03-29T17:00:00</Finish></Task>
    <Task><UID>2</UID><Name>Walls</Name><OutlineLevel>2</OutlineLevel><Summary>0</Summary>
      <Start>2024-01-08T08:00:00</Start><Finish>2024-01-12T17:00:00</Finish></Task>
    <Task><UID>3</UID><Name>Slabs</Name><OutlineLevel>2</OutlineLevel><Summary>0</Summary>
      <Start>2024-02-05T08:00:00</Start><Finish>2024-02-09T17:00:00</Finish></Task>
    <Task><UID>4</UID><Name>Walls</Name><OutlineLevel>2</OutlineLevel><Summary>0</Summary>
      <Start>2024-03-04T08:00:00</Start><Finish>2024-03-08T17:00:00</Finish></Task>
    <Task><UID>5</UID><Name>Handover</Name><OutlineLevel>1</OutlineLevel><Summary>0</Summary>
      <Start>2024-04-02T08:00:00</Start><Finish>2024-04-02T17:00:00</Finish></Task>
  </Tasks>
</Project>"#;

#[test]
fn ms_project_tasks_carry_their_summary_names() {
    let dir = tempfile::tempdir().unwrap();
    let tasks = msproject::read(&write(dir.path(), "plan.xml", PLAN)).unwrap();
    let got: Vec<(&str, &str)> = tasks
        .iter()
        .map(|t| (t.id.as_str(), t.name.as_str()))
        .collect();
    assert_eq!(
        got,
        [
            ("2", "Shell / Walls"),
            ("3", "Shell / Slabs"),
            ("4", "Shell / Walls"),
            ("5", "Handover")
        ]
    );
    assert_eq!(tasks[1].start, parse_date("2024-02-05T08:00:00").unwrap());
    assert_eq!(tasks[1].finish, parse_date("2024-02-09T17:00:00").unwrap());
    assert!(
        tasks
            .iter()
            .all(|t| t.kind.is_none() && t.objects.is_empty())
    );

    let bad = PLAN.replace("2024-02-05T08:00:00", "next monday");
    let e = msproject::read(&write(dir.path(), "bad.xml", &bad))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad.xml") && e.contains("Task[2]/Start") && e.contains("next monday"),
        "{e}"
    );
    let e = msproject::read(&write(dir.path(), "other.xml", "<Plan/>"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("other.xml") && e.contains("<Project>"), "{e}");
}

#[test]
fn link_csv_groups_rows_by_task() {
    let dir = tempfile::tempdir().unwrap();
    // The column names and day-first dates of a 4D tool's event log.
    let csv = "BuildingGUID,GUID,ifcClass,Task,TaskName,TaskStart,TaskFinish\n\
               b,2WallTinyHdlod00000001,Wall,ST10,Walls,8-1-2024,12-1-2024\n\
               b,2SlabTinyHdlod00000001,Slab,ST20,Slabs,5-2-2024,5-2-2024\n\
               b,2WallTinyHdlod00000001,Wall,ST20,Slabs,5-2-2024,5-2-2024\n";
    let tasks = links_csv::read(&write(dir.path(), "links.csv", csv)).unwrap();
    assert_eq!(tasks.len(), 2);
    assert_eq!(tasks[0].id, "ST10");
    assert_eq!(tasks[0].objects, ["2WallTinyHdlod00000001"]);
    assert_eq!(
        tasks[1].objects,
        ["2SlabTinyHdlod00000001", "2WallTinyHdlod00000001"]
    );
    assert_eq!(tasks[0].start, parse_date("2024-01-08").unwrap());
    // A one-day task lasts its day.
    assert_eq!(tasks[1].finish, parse_date("2024-02-06").unwrap());

    let typed = "guid,task,start,finish,type\nA,T,2024-01-01,2024-01-02,DEMOLITION\n";
    let tasks = links_csv::read(&write(dir.path(), "typed.csv", typed)).unwrap();
    assert_eq!(tasks[0].kind, Some(TaskType::Demolish));

    let e = links_csv::read(&write(
        dir.path(),
        "nocol.csv",
        "guid,start,finish\nA,1,2\n",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("nocol.csv") && e.contains("task"), "{e}");
    let e = links_csv::read(&write(
        dir.path(),
        "baddate.csv",
        "guid,task,start,finish\nA,T,2024-01-01,soon\n",
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("line 2") && e.contains("finish") && e.contains("soon"),
        "{e}"
    );
}

#[test]
fn schedules_by_extension() {
    let dir = tempfile::tempdir().unwrap();
    // IFC4 tasks from another file.
    let tasks = hdlod::import::read_schedule(&tiny()).unwrap();
    assert_eq!(tasks.len(), 2);
    let e = hdlod::import::read_schedule(&write(dir.path(), "plan.ifc", "hello"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("plan.ifc") && e.contains("FILE_SCHEMA"), "{e}");
    let e = hdlod::import::read_schedule(&write(dir.path(), "plan.mpp", ""))
        .unwrap_err()
        .to_string();
    assert!(e.contains("plan.mpp") && e.contains(".xml"), "{e}");
}

fn rules(dir: &Path, rules: &str) -> PathBuf {
    write(
        dir,
        "links.json",
        &format!(r#"{{"format": "hdlod-links/1", "rules": {rules}}}"#),
    )
}

#[test]
fn rules_link_objects_and_report_matches() {
    let dir = tempfile::tempdir().unwrap();
    // The tiny model's own IFC4 tasks are read too; these rules add the
    // plan's tasks on top.
    let links = rules(
        dir.path(),
        r#"[
        {"name": "walls", "select": {"class": "ifcwall*", "storey": "00 *"}, "task": "2"},
        {"name": "slab by regex", "select": {"name": {"regex": "^sla"}}, "task": "3", "type": "temporary"},
        {"name": "handover", "select": {"file": ["nothing.ifc", "tiny.*"], "properties": {"ifc_class": "IfcSlab"}}, "task_name": "Handover"},
        {"name": "doors", "select": {"class": "IfcDoor"}, "task": "4"}
    ]"#,
    );
    let options = Options {
        name: "tiny".into(),
        schedule: Some(write(dir.path(), "plan.xml", PLAN)),
        links: Some(links),
    };
    let (scene, report) = import(&[tiny()], &options, &|_| {}).unwrap();
    let matched: Vec<(&str, usize, TaskType)> = report
        .rules
        .iter()
        .map(|r| (r.name.as_str(), r.matched, r.kind))
        .collect();
    assert_eq!(
        matched,
        [
            ("walls", 1, TaskType::Construct),
            ("slab by regex", 1, TaskType::Temporary),
            ("handover", 1, TaskType::Construct),
            ("doors", 0, TaskType::Construct)
        ]
    );
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("\"doors\"") && w.contains("matches no object")),
        "{:?}",
        report.warnings
    );
    assert_eq!(report.tasks, 6, "2 IFC4 tasks and 4 of the plan");
    assert!(report.unmatched.is_empty());
    // The slab: removed by T2 on 2024-02-02, there again during "Slabs"
    // (temporary, 2024-02-05..09), built for good at "Handover".
    let slab = scene
        .objects
        .iter()
        .find(|o| o.id == "2SlabTinyHdlod00000001")
        .unwrap();
    let at = |d: &str| scene.time.seconds_of(parse_date(d).unwrap());
    assert!(slab.visibility.at(at("2024-01-10")));
    assert!(!slab.visibility.at(at("2024-02-03")));
    assert!(slab.visibility.at(at("2024-02-07")));
    assert!(!slab.visibility.at(at("2024-03-01")));
    assert!(slab.visibility.at(at("2024-04-02T12:00:00")));
    // The wall's first task starts the scene: it stands from the start.
    let wall = &scene.objects[0];
    assert_eq!(report.time.start, "2024-01-08T08:00:00Z");
    assert_eq!(
        wall.visibility.kind(scene.time.seconds),
        VisibilityType::Static
    );
}

#[test]
fn bad_rules_name_the_rule() {
    let dir = tempfile::tempdir().unwrap();
    let plan = write(dir.path(), "plan.xml", PLAN);
    let run = |rule: &str| {
        let options = Options {
            name: "tiny".into(),
            schedule: Some(plan.clone()),
            links: Some(rules(dir.path(), &format!("[{rule}]"))),
        };
        import(&[tiny()], &options, &|_| {})
            .unwrap_err()
            .to_string()
    };
    let e = run(r#"{"name": "r1", "select": {}, "task": "99"}"#);
    assert!(
        e.contains("rules[0].task") && e.contains("\"r1\"") && e.contains("99"),
        "{e}"
    );
    let e = run(r#"{"name": "r2", "select": {}, "task_name": "Shell / Walls"}"#);
    assert!(e.contains("task_name") && e.contains("ids 2, 4"), "{e}");
    let e = run(r#"{"name": "r3", "select": {"name": {"regex": "("}}, "task": "2"}"#);
    assert!(e.contains("select.name") && e.contains("bad regex"), "{e}");
    let e = run(r#"{"name": "r4", "select": {}, "task": "2", "type": "party"}"#);
    assert!(e.contains("rules[0].type") && e.contains("party"), "{e}");
    let e = run(r#"{"name": "r5", "select": {"colour": "red"}, "task": "2"}"#);
    assert!(e.contains("links.json") && e.contains("colour"), "{e}");
}

#[test]
fn links_files_follow_their_schema() {
    let text = std::fs::read_to_string(root().join("schemas/links.schema.json")).unwrap();
    let schema: serde_json::Value = serde_json::from_str(&text).unwrap();
    let v = jsonschema::validator_for(&schema).unwrap();
    for rel in [
        "fixtures/schependomlaan/links.json",
        "fixtures/ifc-tiny/links.json",
    ] {
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(root().join(rel)).unwrap()).unwrap();
        let errors: Vec<String> = v.iter_errors(&json).map(|e| e.to_string()).collect();
        assert!(errors.is_empty(), "{rel}: {errors:?}");
    }
    // The schema rejects what the reader rejects.
    let bad = serde_json::json!({"format": "hdlod-links/1", "rules": [
        {"name": "both", "select": {}, "task": "1", "task_name": "x"}]});
    assert!(!v.is_valid(&bad));
}

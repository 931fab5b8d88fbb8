//! Schedules and linking rules: Microsoft Project XML, the element-task CSV,
//! and rules over the objects of fixtures/ifc-tiny/tiny.ifc.
#![cfg(feature = "ifc")]

use std::path::{Path, PathBuf};

use hdlod::import::{Options, Recorded, import, links_csv, msproject};
use hdlod::scene::{Dates, TaskType, VisibilityType};
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
    let got: Vec<(&str, &str, Option<&str>)> = tasks
        .iter()
        .map(|t| (t.id.as_str(), t.name.as_str(), t.parent.as_deref()))
        .collect();
    assert_eq!(
        got,
        [
            ("1", "Shell", None),
            ("2", "Shell / Walls", Some("1")),
            ("3", "Shell / Slabs", Some("1")),
            ("4", "Shell / Walls", Some("1")),
            ("5", "Handover", None)
        ]
    );
    assert_eq!(tasks[2].start, parse_date("2024-02-05T08:00:00").unwrap());
    assert_eq!(tasks[2].finish, parse_date("2024-02-09T17:00:00").unwrap());
    assert!(tasks.iter().all(|t| t.kind.is_none()
        && t.objects.is_empty()
        && t.actual == Recorded::default()
        && t.baseline.is_none()));

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
    // A task given in days ends at the end of its last day.
    assert_eq!(tasks[0].finish, parse_date("2024-01-13").unwrap());
    assert_eq!(tasks[1].finish, parse_date("2024-02-06").unwrap());

    // The padding rows of a spreadsheet export are left out.
    let padded = format!("{csv},,,,,,\n , ,,,,,\n");
    assert_eq!(
        links_csv::read(&write(dir.path(), "padded.csv", &padded)).unwrap(),
        tasks
    );

    let typed = "guid,task,start,finish,type\nA,T,2024-01-01,2024-01-02,DEMOLITION\n";
    let tasks = links_csv::read(&write(dir.path(), "typed.csv", typed)).unwrap();
    let kind = tasks[0].kind.unwrap();
    assert_eq!(
        (kind.kind, kind.ifc),
        (TaskType::Demolish, Some("DEMOLITION"))
    );

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
    let tasks = hdlod::import::read_schedule(&tiny(), &Default::default()).unwrap();
    assert_eq!(tasks.len(), 2);
    let e =
        hdlod::import::read_schedule(&write(dir.path(), "plan.ifc", "hello"), &Default::default())
            .unwrap_err()
            .to_string();
    assert!(e.contains("plan.ifc") && e.contains("FILE_SCHEMA"), "{e}");
    let e = hdlod::import::read_schedule(&write(dir.path(), "plan.mpp", ""), &Default::default())
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
        ..Options::default()
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
    assert_eq!(report.tasks, 7, "2 IFC4 tasks and 5 of the plan");
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
            ..Options::default()
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
    // Task selectors: one that selects nothing, an empty one, a bad
    // pattern, a match on no task attribute, two ways to name tasks.
    let e = run(r#"{"name": "r6", "select": {}, "tasks": {"wbs": "9.*"}}"#);
    assert!(
        e.contains("rules[0].tasks (rule \"r6\")") && e.contains("selects no task"),
        "{e}"
    );
    let e = run(r#"{"name": "r7", "select": {}, "tasks": {}}"#);
    assert!(
        e.contains("rules[0].tasks") && e.contains("empty task selector"),
        "{e}"
    );
    let e = run(r#"{"name": "r8", "select": {}, "tasks": {"codes": {"Trade": {"regex": "["}}}}"#);
    assert!(
        e.contains("tasks.codes.Trade") && e.contains("bad regex"),
        "{e}"
    );
    let e = run(
        r#"{"name": "r9", "select": {}, "tasks": {"name": "*"}, "match": {"storey": "level"}}"#,
    );
    assert!(
        e.contains("match.storey") && e.contains("not a task attribute"),
        "{e}"
    );
    let e = run(r#"{"name": "r10", "select": {}, "task": "2", "tasks": {"name": "*"}}"#);
    assert!(e.contains("exactly one of"), "{e}");
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
    // Task selectors, matches, property sets and a spreadsheet mapping.
    let selectors = serde_json::json!({"format": "hdlod-links/1",
        "spreadsheet": {"sheet": "Plan", "columns": {"id": "Code", "start": "Begin"}},
        "rules": [
            {"name": "walls by level", "select": {"class": "IfcWall*"},
             "tasks": {"codes": {"Trade": "WALLS"}, "wbs": "TWR.*"}, "match": {"storey": "code:Level"}},
            {"name": "rated", "select": {"properties": {"Pset_WallCommon.FireRating": "REI*"}},
             "tasks": {"fields": {"Zone": "north", "early_start": "2024-*"}}, "type": "temporary"}]});
    let errors: Vec<String> = v.iter_errors(&selectors).map(|e| e.to_string()).collect();
    assert!(errors.is_empty(), "{errors:?}");
    // The schema rejects what the reader rejects.
    for bad in [
        serde_json::json!({"format": "hdlod-links/1", "rules": [
            {"name": "both", "select": {}, "task": "1", "task_name": "x"}]}),
        serde_json::json!({"format": "hdlod-links/1", "rules": [
            {"name": "two", "select": {}, "task": "1", "tasks": {"id": "x"}}]}),
        serde_json::json!({"format": "hdlod-links/1", "rules": [
            {"name": "match", "select": {}, "tasks": {"id": "x"}, "match": {"storey": "level"}}]}),
        serde_json::json!({"format": "hdlod-links/1", "spreadsheet": {"columns": {"colour": "Zone"}}, "rules": []}),
    ] {
        assert!(!v.is_valid(&bad), "{bad}");
    }
}

/// A Project status update: actual dates, baselines, a task still running.
const PROGRESS: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Project xmlns="http://schemas.microsoft.com/project">
  <Tasks>
    <Task><UID>1</UID><Name>Shell</Name><OutlineLevel>1</OutlineLevel><Summary>1</Summary>
      <Start>2024-01-08T08:00:00</Start><Finish>2024-03-08T17:00:00</Finish>
      <ActualStart>2024-01-09T08:00:00</ActualStart></Task>
    <Task><UID>2</UID><Name>Walls</Name><OutlineLevel>2</OutlineLevel>
      <Start>2024-01-08T08:00:00</Start><Finish>2024-01-12T17:00:00</Finish>
      <ActualStart>2024-01-09T08:00:00</ActualStart><ActualFinish>2024-01-16T17:00:00</ActualFinish>
      <Baseline><Number>1</Number><Start>2024-01-01T08:00:00</Start><Finish>2024-01-05T17:00:00</Finish></Baseline>
      <Baseline><Number>0</Number><Start>2023-12-18T08:00:00</Start><Finish>2023-12-22T17:00:00</Finish></Baseline></Task>
    <Task><UID>3</UID><Name>Slabs</Name><OutlineLevel>2</OutlineLevel>
      <Start>2024-02-05T08:00:00</Start><Finish>2024-02-09T17:00:00</Finish>
      <ActualStart>2024-02-06T08:00:00</ActualStart>
      <Baseline><Number>2</Number><Start>2024-01-29T08:00:00</Start><Finish>2024-02-02T17:00:00</Finish></Baseline>
      <Baseline><Number>1</Number><Cost>100</Cost></Baseline></Task>
    <Task><UID>4</UID><Name>Roof</Name><OutlineLevel>2</OutlineLevel>
      <Start>2024-03-04T08:00:00</Start><Finish>2024-03-08T17:00:00</Finish></Task>
  </Tasks>
</Project>"#;

#[test]
fn ms_project_actual_and_baseline_dates() {
    let dir = tempfile::tempdir().unwrap();
    let tasks = msproject::read(&write(dir.path(), "progress.xml", PROGRESS)).unwrap();
    let d = |s: &str| Some(parse_date(s).unwrap());
    let actual: Vec<(&str, Recorded)> = tasks.iter().map(|t| (t.id.as_str(), t.actual)).collect();
    assert_eq!(
        actual,
        [
            (
                "1",
                Recorded {
                    start: d("2024-01-09T08:00:00"),
                    finish: None
                }
            ),
            (
                "2",
                Recorded {
                    start: d("2024-01-09T08:00:00"),
                    finish: d("2024-01-16T17:00:00")
                }
            ),
            // Still running.
            (
                "3",
                Recorded {
                    start: d("2024-02-06T08:00:00"),
                    finish: None
                }
            ),
            ("4", Recorded::default()),
        ]
    );
    // Baseline 0 first; else the lowest-numbered one with both dates.
    let baseline: Vec<_> = tasks.iter().map(|t| t.baseline).collect();
    assert_eq!(
        baseline,
        [
            None,
            Some((
                parse_date("2023-12-18T08:00:00").unwrap(),
                parse_date("2023-12-22T17:00:00").unwrap()
            )),
            Some((
                parse_date("2024-01-29T08:00:00").unwrap(),
                parse_date("2024-02-02T17:00:00").unwrap()
            )),
            None
        ]
    );

    // Bad actual dates name the file, the task's field and the task.
    let run = |name: &str, text: String| {
        msproject::read(&write(dir.path(), name, &text))
            .unwrap_err()
            .to_string()
    };
    let e = run(
        "orphan.xml",
        PROGRESS.replace(
            "<ActualStart>2024-02-06T08:00:00</ActualStart>",
            "<ActualFinish>2024-02-09T17:00:00</ActualFinish>",
        ),
    );
    assert!(
        e.contains("orphan.xml")
            && e.contains("Task[2]/ActualFinish")
            && e.contains("needs an actual start"),
        "{e}"
    );
    let e = run(
        "backwards.xml",
        PROGRESS.replace(
            "<ActualFinish>2024-01-16T17:00:00",
            "<ActualFinish>2024-01-02T17:00:00",
        ),
    );
    assert!(
        e.contains("Task[1]/ActualFinish") && e.contains("task 2") && e.contains("before"),
        "{e}"
    );
    let e = run(
        "garbled.xml",
        PROGRESS.replace("2024-02-06T08:00:00", "Tuesday"),
    );
    assert!(
        e.contains("Task[2]/ActualStart") && e.contains("Tuesday"),
        "{e}"
    );
    let e = run(
        "baseline.xml",
        PROGRESS.replace("2023-12-22T17:00:00", "2023-12-01T17:00:00"),
    );
    assert!(
        e.contains("Task[1]/Baseline[1]/Finish") && e.contains("baseline finishes before"),
        "{e}"
    );
}

#[test]
fn summary_tasks_group_the_scene_tasks_under_them() {
    let dir = tempfile::tempdir().unwrap();
    let links = rules(
        dir.path(),
        r#"[{"name": "walls", "select": {"class": "IfcWall"}, "task": "2"},
            {"name": "slab", "select": {"class": "IfcSlab"}, "task": "3"}]"#,
    );
    let options = Options {
        name: "tiny".into(),
        schedule: Some(write(dir.path(), "progress.xml", PROGRESS)),
        links: Some(links),
        ..Options::default()
    };
    let (scene, report) = import(&[tiny()], &options, &|_| {}).unwrap();
    // The model's own IFC4 tasks, the two linked by rules, then their
    // summary: a task without objects. "Roof" acts on nothing: left out.
    let got: Vec<(&str, Option<&str>, usize)> = scene
        .tasks
        .iter()
        .map(|t| (t.id.as_str(), t.parent.as_deref(), t.objects.len()))
        .collect();
    assert_eq!(
        got,
        [
            ("T1", None, 1),
            ("T2", None, 1),
            ("2", Some("1"), 1),
            ("3", Some("1"), 1),
            ("1", None, 0)
        ]
    );
    assert_eq!((report.scene_tasks, report.summary_tasks), (4, 1));
    assert_eq!(report.actual_tasks, 3);
    let walls = &scene.tasks[2];
    let at = |d: &str| scene.time.seconds_of(parse_date(d).unwrap());
    assert_eq!(walls.actual.start, Some(at("2024-01-09T08:00:00")));
    assert_eq!(walls.actual.finish, Some(at("2024-01-16T17:00:00")));
    assert_eq!(walls.baseline.unwrap().start, at("2023-12-18T08:00:00"));
    assert_eq!(scene.tasks[3].actual.finish, None);

    // The scene keeps it all through its file.
    let out = dir.path().join("scene");
    hdlod::scene::format::save(&scene, &out).unwrap();
    let back = hdlod::scene::format::load(&out).unwrap();
    assert_eq!(back.tasks, scene.tasks);
}

/// Linking rules for the tiny model against `PLAN`.
fn plan_rules(dir: &Path) -> PathBuf {
    rules(
        dir,
        r#"[{"name": "walls", "select": {"class": "IfcWall"}, "task": "4"},
            {"name": "slab", "select": {"class": "IfcSlab"}, "task": "3"}]"#,
    )
}

#[test]
fn as_built_logs_date_the_plan_by_id_then_by_name() {
    let dir = tempfile::tempdir().unwrap();
    // An as-built log in the event-log shape: "2" by id; "Walls" by name,
    // nearest in start to UID 4 (not 2); "Slabs" by name with one element
    // still to do; "Paint" in no plan; padding rows.
    let log = "GUID,TaskID,TaskName,TaskStart,TaskFinish\n\
               e1,2,Walls,9-1-2024,15-1-2024\n\
               e2,ST40,walls ,4-3-2024,11-3-2024\n\
               e3,ST40,Walls,5-3-2024,12-3-2024\n\
               e4,ST30,Slabs,6-2-2024,8-2-2024\n\
               e5,ST30,Slabs,7-2-2024,\n\
               e6,ST30,Slabs,,\n\
               e7,ST90,Paint,1-4-2024,2-4-2024\n\
               ,,,,\n";
    let options = Options {
        name: "tiny".into(),
        schedule: Some(write(dir.path(), "plan.xml", PLAN)),
        links: Some(plan_rules(dir.path())),
        actual: vec![write(dir.path(), "built.csv", log)],
        ..Options::default()
    };
    let (scene, report) = import(&[tiny()], &options, &|_| {}).unwrap();
    let a = report.actual.as_ref().unwrap();
    assert_eq!(
        (
            a.rows,
            a.tasks,
            a.by_id,
            a.by_name,
            a.dated,
            a.unmatched_rows
        ),
        (7, 4, 1, 2, 3, 1)
    );
    assert_eq!(a.unmatched, ["built.csv: ST90 \"Paint\""]);
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("built.csv") && w.contains("1 task(s) (1 rows)")),
        "{:?}",
        report.warnings
    );
    let task = |id: &str| scene.tasks.iter().find(|t| t.id == id).unwrap();
    let at = |d: &str| scene.time.seconds_of(parse_date(d).unwrap());
    // Walls 4: from its first element's start to the end of its last day;
    // the log gives days, and the start's day is the planned one, so the
    // planned hour stands for it.
    assert_eq!(task("4").actual.start, Some(at("2024-03-04T08:00:00Z")));
    assert_eq!(task("4").actual.finish, Some(at("2024-03-13")));
    // Slabs: started, not finished while an element is still to do.
    assert_eq!(task("3").actual.start, Some(at("2024-02-06")));
    assert_eq!(task("3").actual.finish, None);
    assert_eq!(report.actual_tasks, 2);
    // The span reaches the last actual finish (after the plan's 03-08).
    assert_eq!(report.time.end, "2024-03-13T00:00:00Z");

    // The wall is built by the model's T1 (2024-03-01, never recorded) and
    // the plan's 4. Planned, it stands from T1's start; on the actual dates
    // from 4's actual start, as T1 has not started by the record.
    let wall = |scene: &hdlod::scene::Scene, d: &str| {
        let o = scene
            .objects
            .iter()
            .find(|o| o.id == "2WallTinyHdlod00000001")
            .unwrap();
        o.visibility
            .at(scene.time.seconds_of(parse_date(d).unwrap()))
    };
    assert!(wall(&scene, "2024-03-02") && wall(&scene, "2024-03-05"));
    let actual = Options {
        dates: Dates::Actual,
        ..options.clone()
    };
    let (scene, _) = import(&[tiny()], &actual, &|_| {}).unwrap();
    assert_eq!(scene.schedule_options.dates, Dates::Actual);
    assert!(!wall(&scene, "2024-03-02") && wall(&scene, "2024-03-05"));
}

#[test]
fn bad_as_built_rows_name_the_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, log: &str| {
        hdlod::import::actual::read(&write(dir.path(), name, log))
            .unwrap_err()
            .to_string()
    };
    let e = run("a.csv", "Task,Start,Finish\nT,1-2-2024,soon\n");
    assert!(
        e.contains("a.csv")
            && e.contains("line 2")
            && e.contains("\"Finish\"")
            && e.contains("soon"),
        "{e}"
    );
    let e = run(
        "b.csv",
        "Task,Start,Finish\nT,1-2-2024,2-2-2024\nT,5-2-2024,3-2-2024\n",
    );
    assert!(
        e.contains("b.csv")
            && e.contains("line 3")
            && e.contains("\"Finish\"")
            && e.contains("before the actual start"),
        "{e}"
    );
    let e = run("c.csv", "Task,Start,Finish\nT,,3-2-2024\n");
    assert!(
        e.contains("line 2") && e.contains("needs an actual start"),
        "{e}"
    );
    let e = run("d.csv", "GUID,Start,Finish\nx,1-2-2024,2-2-2024\n");
    assert!(
        e.contains("d.csv") && e.contains("header") && e.contains("taskname"),
        "{e}"
    );
    let e = run("e.csv", "Task,TaskName,Start,Finish\n,,1-2-2024,2-2-2024\n");
    assert!(
        e.contains("line 2") && e.contains("no task id or name"),
        "{e}"
    );
}

/// `PLAN` with links and custom fields: Slabs 2 days after Walls (2), the
/// second Walls (4) with Slabs (SS), Handover after everything else.
const LINKED: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Project xmlns="http://schemas.microsoft.com/project">
  <ExtendedAttributes>
    <ExtendedAttribute><FieldID>188743731</FieldID><FieldName>Text1</FieldName><Alias>Zone</Alias></ExtendedAttribute>
    <ExtendedAttribute><FieldID>188743734</FieldID><FieldName>Text2</FieldName></ExtendedAttribute>
  </ExtendedAttributes>
  <Tasks>
    <Task><UID>1</UID><Name>Shell</Name><WBS>1</WBS><OutlineLevel>1</OutlineLevel><Summary>1</Summary>
      <Start>2024-01-08T08:00:00</Start><Finish>2024-03-29T17:00:00</Finish></Task>
    <Task><UID>2</UID><Name>Walls</Name><WBS>1.1</WBS><OutlineLevel>2</OutlineLevel>
      <Start>2024-01-08T08:00:00</Start><Finish>2024-01-12T17:00:00</Finish>
      <ExtendedAttribute><FieldID>188743731</FieldID><Value>North</Value></ExtendedAttribute>
      <ExtendedAttribute><FieldID>188743734</FieldID><Value>masonry</Value></ExtendedAttribute></Task>
    <Task><UID>3</UID><Name>Slabs</Name><WBS>1.2</WBS><OutlineLevel>2</OutlineLevel>
      <Start>2024-02-05T08:00:00</Start><Finish>2024-02-09T17:00:00</Finish>
      <PredecessorLink><PredecessorUID>2</PredecessorUID><Type>1</Type><LinkLag>9600</LinkLag><LagFormat>7</LagFormat></PredecessorLink>
      <ExtendedAttribute><FieldID>188743731</FieldID><Value>South</Value></ExtendedAttribute></Task>
    <Task><UID>4</UID><Name>Walls</Name><WBS>1.3</WBS><OutlineLevel>2</OutlineLevel>
      <Start>2024-03-04T08:00:00</Start><Finish>2024-03-08T17:00:00</Finish>
      <PredecessorLink><PredecessorUID>3</PredecessorUID><Type>3</Type></PredecessorLink>
      <PredecessorLink><PredecessorUID>77</PredecessorUID><CrossProject>1</CrossProject></PredecessorLink></Task>
    <Task><UID>5</UID><Name>Handover</Name><WBS>2</WBS><OutlineLevel>1</OutlineLevel>
      <Start>2024-04-02T08:00:00</Start><Finish>2024-04-02T17:00:00</Finish>
      <PredecessorLink><PredecessorUID>4</PredecessorUID><Type>0</Type><LinkLag>-4800</LinkLag></PredecessorLink>
      <PredecessorLink><PredecessorUID>3</PredecessorUID><Type>2</Type><LinkLag>500</LinkLag><LagFormat>19</LagFormat></PredecessorLink></Task>
  </Tasks>
</Project>"#;

#[test]
fn ms_project_links_and_custom_fields() {
    use hdlod::scene::{LinkType, Predecessor};
    let dir = tempfile::tempdir().unwrap();
    let tasks = msproject::read(&write(dir.path(), "linked.xml", LINKED)).unwrap();
    let links = |k: usize| -> Vec<(&str, LinkType, f64)> {
        tasks[k]
            .predecessors
            .iter()
            .map(|p| (p.task.as_str(), p.kind, p.lag / 3600.0))
            .collect()
    };
    assert!(links(0).is_empty() && links(1).is_empty());
    // 9600 tenths of a minute: 16 hours; a percent lag reads as none.
    assert_eq!(links(2), [("2", LinkType::FinishStart, 16.0)]);
    assert_eq!(links(3), [("3", LinkType::StartStart, 0.0)]);
    assert_eq!(
        links(4),
        [
            ("4", LinkType::FinishFinish, -8.0),
            ("3", LinkType::StartFinish, 0.0)
        ]
    );
    assert_eq!(tasks[1].fields["Zone"], "North");
    assert_eq!(tasks[1].fields["Text2"], "masonry");
    assert_eq!(tasks[2].fields["Zone"], "South");
    assert_eq!(tasks[2].wbs.as_deref(), Some("1.2"));

    // Rules on the fields and the WBS; the scene keeps the link between
    // its two tasks.
    let links_file = rules(
        dir.path(),
        r#"[{"name": "north", "select": {"class": "IfcWall"}, "tasks": {"fields": {"Zone": "north"}}},
            {"name": "slab", "select": {"class": "IfcSlab"}, "tasks": {"wbs": "1.2", "name": "*slabs"}}]"#,
    );
    let options = Options {
        name: "tiny".into(),
        schedule: Some(write(dir.path(), "linked.xml", LINKED)),
        links: Some(links_file),
        ..Options::default()
    };
    let (scene, report) = import(&[tiny()], &options, &|_| {}).unwrap();
    let slabs = scene.tasks.iter().find(|t| t.id == "3").unwrap();
    assert_eq!(
        slabs.predecessors,
        [Predecessor {
            task: "2".into(),
            kind: LinkType::FinishStart,
            lag: 16.0 * 3600.0
        }]
    );
    assert_eq!((report.links, report.links_outside), (1, 0));

    // A cycle, and a link of no known type.
    let cycle = LINKED.replace(
        "<Task><UID>2</UID><Name>Walls</Name><WBS>1.1</WBS><OutlineLevel>2</OutlineLevel>",
        "<Task><UID>2</UID><Name>Walls</Name><WBS>1.1</WBS><OutlineLevel>2</OutlineLevel>\
         <PredecessorLink><PredecessorUID>5</PredecessorUID></PredecessorLink>",
    );
    let e = msproject::read(&write(dir.path(), "cycle.xml", &cycle))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cycle.xml")
            && e.contains("PredecessorLink")
            && e.contains("2 -> 3 -> 4 -> 5 -> 2"),
        "{e}"
    );
    let bad = LINKED.replace("<Type>3</Type>", "<Type>7</Type>");
    let e = msproject::read(&write(dir.path(), "bad.xml", &bad))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("Task[3]/PredecessorLink[0]/Type") && e.contains("\"7\""),
        "{e}"
    );
}

/// The tiny model with property sets: the wall's own (fire rating, and
/// external) and its type's (a rating the wall's own set overrides, and an
/// acoustic rating).
fn tiny_with_psets(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(tiny()).unwrap();
    let psets = "\
#300=IFCPROPERTYSINGLEVALUE('FireRating',$,IFCLABEL('REI60'),$);
#301=IFCPROPERTYSINGLEVALUE('IsExternal',$,IFCBOOLEAN(.T.),$);
#302=IFCPROPERTYSET('3PsetTinyHdlod00000001',$,'Pset_WallCommon',$,(#300,#301));
#303=IFCRELDEFINESBYPROPERTIES('3RelPTinyHdlod00000001',$,$,$,(#40),#302);
#310=IFCPROPERTYSINGLEVALUE('FireRating',$,IFCLABEL('REI30'),$);
#311=IFCPROPERTYSINGLEVALUE('AcousticRating',$,IFCLABEL('45 dB'),$);
#312=IFCPROPERTYSET('3PsetTinyHdlod00000002',$,'Pset_WallCommon',$,(#310,#311));
#313=IFCWALLTYPE('3TypeTinyHdlod00000001',$,'brick wall',$,$,(#312),$,$,$,.SOLIDWALL.);
#314=IFCRELDEFINESBYTYPE('3RelTTinyHdlod00000001',$,$,$,(#40),#313);
ENDSEC;
END-ISO-10303-21;";
    let at = text.rfind("ENDSEC;").unwrap();
    let path = dir.join("tiny-psets.ifc");
    std::fs::write(&path, format!("{}{psets}\n", &text[..at])).unwrap();
    path
}

#[test]
fn rules_select_by_property_set_values() {
    let dir = tempfile::tempdir().unwrap();
    let links = rules(
        dir.path(),
        r#"[{"name": "fire-rated external walls", "task": "2",
             "select": {"properties": {"Pset_WallCommon.FireRating": "REI6?",
                                       "Pset_WallCommon.IsExternal": "true",
                                       "Pset_WallCommon.AcousticRating": "45*"}}}]"#,
    );
    let options = Options {
        name: "tiny".into(),
        schedule: Some(write(dir.path(), "plan.xml", PLAN)),
        links: Some(links),
        ..Options::default()
    };
    let (scene, report) = import(&[tiny_with_psets(dir.path())], &options, &|_| {}).unwrap();
    assert_eq!(report.rules[0].matched, 1);
    let wall = scene
        .objects
        .iter()
        .find(|o| o.id == "2WallTinyHdlod00000001")
        .unwrap();
    // Only the properties a rule names are imported; the element's own
    // value wins over its type's.
    let psets: Vec<(&str, &str)> = wall
        .properties
        .iter()
        .filter(|(k, _)| k.starts_with("Pset_"))
        .map(|(k, v)| (k.as_str(), v.as_str()))
        .collect();
    assert_eq!(
        psets,
        [
            ("Pset_WallCommon.AcousticRating", "45 dB"),
            ("Pset_WallCommon.FireRating", "REI60"),
            ("Pset_WallCommon.IsExternal", "true")
        ]
    );
    let slab = scene
        .objects
        .iter()
        .find(|o| o.id == "2SlabTinyHdlod00000001")
        .unwrap();
    assert!(!slab.properties.keys().any(|k| k.starts_with("Pset_")));
}

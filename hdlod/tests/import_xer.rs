//! Primavera P6 XER schedules: fixtures/schedules/tiny.xer (Windows-1252,
//! two projects, a work breakdown, links, activity codes and user fields)
//! and every bad input the reader names.
#![cfg(feature = "ifc")]

use std::path::{Path, PathBuf};

use hdlod::import::{Options, Source, import, read_schedule, xer};
use hdlod::scene::{LinkType, Predecessor, SceneSummary};
use hdlod::time::parse_date;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn fixture() -> PathBuf {
    root().join("fixtures/schedules/tiny.xer")
}

fn tiny_ifc() -> PathBuf {
    root().join("fixtures/ifc-tiny/tiny.ifc")
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The fixture with `from` replaced by `to` (bytes, Windows-1252).
fn variant(dir: &Path, from: &[u8], to: &[u8]) -> PathBuf {
    let bytes = std::fs::read(fixture()).unwrap();
    let at = bytes
        .windows(from.len())
        .position(|w| w == from)
        .unwrap_or_else(|| panic!("{:?} not in the fixture", String::from_utf8_lossy(from)));
    let mut out = bytes[..at].to_vec();
    out.extend_from_slice(to);
    out.extend_from_slice(&bytes[at + from.len()..]);
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    write(&dir.join(n.to_string()), "bad.xer", &out)
}

fn error(path: &Path, project: Option<&str>) -> String {
    xer::read(path, project).unwrap_err().to_string()
}

#[test]
fn reads_one_project_with_its_wbs_links_codes_and_fields() {
    let tasks = xer::read(&fixture(), Some("TINY")).unwrap();
    let got: Vec<(&str, &str, Option<&str>, Option<&str>)> = tasks
        .iter()
        .map(|t| {
            (
                t.id.as_str(),
                t.name.as_str(),
                t.parent.as_deref(),
                t.wbs.as_deref(),
            )
        })
        .collect();
    assert_eq!(
        got,
        [
            // Windows-1252 "é" read right.
            (
                "A1000",
                "Shell / Ground floor / Murs en béton",
                Some("TINY.SHELL.L00"),
                Some("TINY.SHELL.L00")
            ),
            (
                "A1010",
                "Shell / Ground floor / Slab",
                Some("TINY.SHELL.L00"),
                Some("TINY.SHELL.L00")
            ),
            (
                "A1020",
                "Finishes / Paint",
                Some("TINY.FIN"),
                Some("TINY.FIN")
            ),
            // At the project's own node: no parent.
            ("M9000", "Handover", None, Some("TINY")),
            // The WBS nodes as summary tasks, spanning their activities.
            ("TINY.SHELL", "Shell", None, Some("TINY.SHELL")),
            (
                "TINY.SHELL.L00",
                "Shell / Ground floor",
                Some("TINY.SHELL"),
                Some("TINY.SHELL.L00")
            ),
            ("TINY.FIN", "Finishes", None, Some("TINY.FIN")),
        ]
    );
    let d = |s: &str| parse_date(s).unwrap();
    let walls = &tasks[0];
    assert_eq!(
        (walls.start, walls.finish),
        (d("2024-01-08T08:00:00"), d("2024-01-12T17:00:00"))
    );
    assert_eq!(walls.actual.start, Some(d("2024-01-09T08:00:00")));
    assert_eq!(walls.actual.finish, Some(d("2024-01-16T17:00:00")));
    assert_eq!(
        walls.early,
        Some((d("2024-01-09T08:00:00"), d("2024-01-16T17:00:00")))
    );
    assert_eq!(walls.late.unwrap().0, d("2024-01-08T08:00:00"));
    assert_eq!(walls.codes["Trade"], "WALLS");
    assert_eq!(walls.codes["Level"], "00 ground floor");
    assert_eq!(walls.fields["Zone"], "North");
    assert_eq!(walls.fields["Crew size"], "4");
    assert_eq!(
        walls.field("early_start").as_deref(),
        Some("2024-01-09T08:00:00Z")
    );
    // A running task; the links with their types and lags (hours).
    let slab = &tasks[1];
    assert_eq!(
        (slab.actual.start.is_some(), slab.actual.finish),
        (true, None)
    );
    assert_eq!(
        slab.predecessors,
        [Predecessor {
            task: "A1000".into(),
            kind: LinkType::FinishStart,
            lag: 16.0 * 3600.0
        }]
    );
    assert_eq!(tasks[2].predecessors[0].kind, LinkType::StartStart);
    assert_eq!(tasks[2].predecessors[0].lag, -8.0 * 3600.0);
    assert_eq!(tasks[3].predecessors[0].kind, LinkType::FinishFinish);
    // The short row (no update_user) reads as if its last field were empty.
    assert!(tasks[2].fields.is_empty() && tasks[2].codes.is_empty());
    // Summary: first planned start to last planned finish below it; actual
    // started, not finished (the slab runs).
    let shell = &tasks[4];
    assert_eq!(
        (shell.start, shell.finish),
        (d("2024-01-08T08:00:00"), d("2024-02-09T17:00:00"))
    );
    assert_eq!(shell.actual.start, Some(d("2024-01-09T08:00:00")));
    assert_eq!(shell.actual.finish, None);

    // The other project, by its proj_id; its link to TINY is external.
    let other = xer::read(&fixture(), Some("102")).unwrap();
    assert_eq!(other.len(), 1);
    assert_eq!(other[0].id, "B1000");
    assert!(other[0].predecessors.is_empty());
}

#[test]
fn several_projects_need_a_choice() {
    let e = error(&fixture(), None);
    assert!(
        e.contains("tiny.xer")
            && e.contains("2 projects")
            && e.contains("--project")
            && e.contains("TINY (proj_id 101, 4 activities)")
            && e.contains("OTHER (proj_id 102, 1 activities)"),
        "{e}"
    );
    let e = error(&fixture(), Some("NOPE"));
    assert!(
        e.contains("no project \"NOPE\"") && e.contains("TINY"),
        "{e}"
    );
    // Chosen through the import's options too; --project is for P6 only.
    let source = Source {
        project: Some("TINY".into()),
        ..Source::default()
    };
    assert_eq!(read_schedule(&fixture(), &source).unwrap().len(), 7);
    let e = read_schedule(&root().join("fixtures/ifc-tiny/plan.xml"), &source)
        .unwrap_err()
        .to_string();
    assert!(e.contains("project") && e.contains("P6"), "{e}");
}

#[test]
fn malformed_xer_names_the_table_row_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases: Vec<(PathBuf, &[&str])> = vec![
        // A missing %T: the PROJWBS rows follow the PROJECT table's.
        (
            variant(d, b"%T\tPROJWBS\r\n", b""),
            &["line 9 (%T PROJECT)", "second %F line"],
        ),
        (
            variant(d, b"ERMHDR", b"%F\tx\r\nERMHDR"),
            &["line 1", "ERMHDR"],
        ),
        (
            variant(d, b"%T\tCURRTYPE\r\n", b""),
            &["line 2", "%F line before any %T"],
        ),
        // A ragged row: one field too many.
        (
            variant(d, b"Slab\t", b"Slab\textra\t"),
            &["TASK row 2 (line 28)", "ragged", "17 fields", "16"],
        ),
        // A byte Windows-1252 leaves undefined, in a task name.
        (
            variant(d, b"Paint", b"Pa\x81nt"),
            &[
                "TASK row 3 (line 29), field task_name",
                "undecodable",
                "Windows-1252",
            ],
        ),
        // Dates: out of range, not a date, a finish before the start.
        (
            variant(
                d,
                b"2024-03-04 08:00\t2024-03-08 17:00\r\n",
                b"1850-03-04 08:00\t2024-03-08 17:00\r\n",
            ),
            &[
                "TASK row 3 (line 29), field target_start_date",
                "out of range",
            ],
        ),
        (
            variant(
                d,
                b"2024-01-12 17:00\tplanner",
                b"2024-13-12 17:00\tplanner",
            ),
            &["TASK row 1 (line 27), field target_end_date", "not a date"],
        ),
        (
            variant(
                d,
                b"2024-01-16 17:00\t2024-01-08",
                b"2024-01-01 17:00\t2024-01-08",
            ),
            &["field act_end_date", "A1000", "before the actual start"],
        ),
        // Links: a cycle, an unknown type, an unknown task.
        (
            variant(d, b"70\t2\t1\t", b"70\t2\t4\t"),
            &["TASKPRED", "cycle", "A1010 -> A1020 -> M9000 -> A1010"],
        ),
        (
            variant(d, b"PR_SS", b"PR_XX"),
            &["TASKPRED row 2 (line 35), field pred_type", "PR_XX"],
        ),
        (
            variant(d, b"71\t3\t2\t", b"71\t3\t77\t"),
            &["TASKPRED row 2 (line 35), field pred_task_id", "\"77\""],
        ),
        // Tables and fields that must be there.
        (
            variant(d, b"%T\tTASK\r\n", b"%T\tTASKS\r\n"),
            &["%T TASK", "no such table"],
        ),
        (
            variant(d, b"\ttask_code\t", b"\tcode\t"),
            &["%T TASK", "no field task_code"],
        ),
        (
            variant(d, b"%R\t1\t101\t1002", b"%X\t1\t101\t1002"),
            &["line 27", "expected a %T, %F, %R or %E line"],
        ),
    ];
    for (path, wanted) in cases {
        let e = error(&path, Some("TINY"));
        for w in wanted {
            assert!(e.contains(w), "{w:?} not in {e:?}");
        }
        assert!(e.contains("bad.xer"), "{e}");
    }
    // A NUL byte in a UTF-8 file, and UTF-16 by its byte-order mark.
    let text = std::fs::read_to_string(fixture().with_file_name("tiny-utf8.xer")).unwrap();
    let nul = write(d, "nul.xer", text.replace("Paint", "Pa\0nt").as_bytes());
    let e = error(&nul, Some("TINY"));
    assert!(
        e.contains("field task_name") && e.contains("undecodable"),
        "{e}"
    );
    let mut utf16 = vec![0xFF, 0xFE];
    utf16.extend(text.encode_utf16().flat_map(u16::to_le_bytes));
    let tasks = xer::read(&write(d, "utf16.xer", &utf16), Some("TINY")).unwrap();
    assert_eq!(tasks[0].name, "Shell / Ground floor / Murs en béton");
    let mut broken = vec![0xFF, 0xFE, 0x00, 0xD8];
    broken.extend_from_slice(&utf16[2..]);
    let e = error(&write(d, "broken16.xer", &broken), Some("TINY"));
    assert!(e.contains("UTF-16"), "{e}");
}

#[test]
fn utf8_and_windows_1252_read_alike() {
    let utf8 = xer::read(&fixture().with_file_name("tiny-utf8.xer"), Some("TINY")).unwrap();
    assert_eq!(utf8, xer::read(&fixture(), Some("TINY")).unwrap());
}

/// Rules on the P6 codes: the walls and the slab by their trade code, each
/// matched to its storey through the Level code.
const RULES: &str = r#"{"format": "hdlod-links/1", "rules": [
  {"name": "walls by level", "select": {"class": "IfcWall*"},
   "tasks": {"codes": {"Trade": "WALLS"}}, "match": {"storey": "code:Level"}},
  {"name": "slabs in the south", "select": {"class": "IfcSlab"},
   "tasks": {"wbs": "TINY.SHELL.*", "fields": {"Zone": "south"}}}
]}"#;

#[test]
fn imports_with_rules_on_codes_and_keeps_the_links() {
    let dir = tempfile::tempdir().unwrap();
    let options = Options {
        name: "tiny".into(),
        schedule: Some(fixture()),
        project: Some("TINY".into()),
        links: Some(write(dir.path(), "links.json", RULES.as_bytes())),
        ..Options::default()
    };
    let (scene, report) = import(&[tiny_ifc()], &options, &|_| {}).unwrap();
    let rules: Vec<(&str, &str, usize, usize)> = report
        .rules
        .iter()
        .map(|r| (r.name.as_str(), r.task.as_str(), r.tasks, r.matched))
        .collect();
    assert_eq!(
        rules,
        [
            ("walls by level", "A1000", 1, 1),
            ("slabs in the south", "A1010", 1, 1)
        ]
    );
    // The IFC model's own two tasks, the two linked, their summaries.
    let ids: Vec<&str> = scene.tasks.iter().map(|t| t.id.as_str()).collect();
    assert_eq!(
        ids,
        ["T1", "T2", "A1000", "A1010", "TINY.SHELL", "TINY.SHELL.L00"]
    );
    let slab = &scene.tasks[3];
    assert_eq!(slab.predecessors.len(), 1);
    assert_eq!(slab.predecessors[0].task, "A1000");
    assert_eq!((report.links, report.links_outside), (1, 0));
    // Paint and the handover act on nothing.
    assert_eq!(report.unmatched_tasks, 2);
    assert_eq!(
        report.unmatched_task_examples,
        ["A1020 \"Finishes / Paint\"", "M9000 \"Handover\""]
    );

    // The scene keeps the links through its file, and sums them up.
    let out = dir.path().join("scene");
    hdlod::scene::format::save(&scene, &out).unwrap();
    let back = hdlod::scene::format::load(&out).unwrap();
    assert_eq!(back.tasks, scene.tasks);
    let s = SceneSummary::of(&back).schedule;
    assert_eq!(
        (s.tasks, s.summary_tasks, s.depth, s.linked_tasks, s.links),
        (6, 2, 3, 2, 1)
    );
}

//! Schedules written by the planners' tools themselves, not by this
//! project: MPXJ's test corpus (fixtures/schedules/mpxj/README.md, LGPL-2.1),
//! exported by Primavera P6 8.2, 8.4 and 20.12 (XER), P6 XML of the 18.1
//! and 20.12 schemas, and Microsoft Project XML from Project 2019 and from
//! older versions. Every expected value below was
//! read off the files' text, not off this reader.
#![cfg(feature = "ifc")]

use std::path::{Path, PathBuf};

use hdlod::import::{ScheduleTask, msproject, pmxml, xer};
use hdlod::scene::{LinkType, Predecessor};
use hdlod::time::parse_date;

fn public(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/schedules/mpxj")
        .join(name)
}

fn d(s: &str) -> chrono::DateTime<chrono::Utc> {
    parse_date(s).unwrap()
}

fn task<'a>(tasks: &'a [ScheduleTask], id: &str) -> &'a ScheduleTask {
    tasks
        .iter()
        .find(|t| t.id == id)
        .unwrap_or_else(|| panic!("no task {id}"))
}

/// P6 8.4, Windows-1252: twelve activities of one WBS node, nine of them
/// started (`act_start_date`), none finished, no CPM dates exported.
#[test]
fn p6_8_4_xer_reads_planned_and_actual_dates() {
    let tasks = xer::read(&public("percent-complete-8.4.xer"), None).unwrap();
    assert_eq!(tasks.len(), 12);
    assert!(tasks.iter().all(|t| t.wbs.as_deref() == Some("EC00640")));
    assert!(
        tasks
            .iter()
            .all(|t| (t.start, t.finish) == (d("2015-02-24T08:00:00"), d("2015-07-13T16:00:00")))
    );
    let started: Vec<&str> = tasks
        .iter()
        .filter(|t| t.actual.start.is_some())
        .map(|t| t.id.as_str())
        .collect();
    assert_eq!(
        started,
        [
            "A1010", "A1020", "A1030", "A1050", "A1060", "A1070", "A1090", "A1100", "A1110"
        ]
    );
    assert!(tasks.iter().all(|t| t.actual.finish.is_none()));
    assert_eq!(task(&tasks, "A1000").name, "Duration 0%");
    assert_eq!(
        task(&tasks, "A1110").actual.start,
        Some(d("2015-02-24T00:00:00"))
    );
}

/// P6 8.2, UTF-8: one finished activity with its early and late dates.
#[test]
fn p6_8_2_xer_reads_actual_early_and_late_dates() {
    let tasks = xer::read(&public("PredecessorCalendar.xer"), None).unwrap();
    assert_eq!(tasks.len(), 1);
    let t = &tasks[0];
    assert_eq!((t.id.as_str(), t.name.as_str()), ("A1000", "Test"));
    assert_eq!(
        (t.start, t.finish),
        (d("2019-06-10T08:00:00"), d("2019-06-12T17:00:00"))
    );
    assert_eq!(
        (t.actual.start, t.actual.finish),
        (
            Some(d("2019-06-10T08:00:00")),
            Some(d("2019-06-12T17:00:00"))
        )
    );
    assert_eq!(
        t.early,
        Some((d("2019-10-02T00:00:00"), d("2019-10-02T00:00:00")))
    );
    assert_eq!(
        t.late,
        Some((d("2020-12-30T08:00:00"), d("2020-12-30T08:00:00")))
    );
}

/// The same kind of project exported by P6 20.12 as XER and as P6 XML
/// reads the same.
#[test]
fn p6_20_12_xer_and_p6_xml_agree() {
    let from_xer = xer::read(&public("resource-rates-test.xer"), None).unwrap();
    let from_xml = pmxml::read(&public("resource-rates-test.xml"), None).unwrap();
    for tasks in [&from_xer, &from_xml] {
        assert_eq!(tasks.len(), 1);
        let t = &tasks[0];
        assert_eq!((t.id.as_str(), t.name.as_str()), ("A1000", "Activity 1"));
        assert_eq!(
            (t.start, t.finish),
            (d("2022-08-22T08:00:00"), d("2022-09-30T17:00:00"))
        );
        assert_eq!(t.actual.start, None);
    }
}

/// P6 XML (the 18.1 schema): the activity under its WBS node, which becomes its
/// summary task; actual dates before the planned ones, as the file has them.
#[test]
fn p6_8_2_xml_reads_the_wbs_and_dates() {
    let tasks = pmxml::read(&public("PredecessorCalendar.xml"), None).unwrap();
    let t = task(&tasks, "A1000");
    assert_eq!(
        (t.start, t.finish),
        (d("2021-03-16T08:00:00"), d("2021-05-18T08:00:00"))
    );
    assert_eq!(
        (t.actual.start, t.actual.finish),
        (
            Some(d("2021-02-05T08:00:00")),
            Some(d("2021-04-19T15:30:00"))
        )
    );
    let parent = task(&tasks, t.parent.as_deref().expect("a WBS parent"));
    assert_eq!(parent.name, "Test Project");
    assert_eq!(tasks.len(), 2);
}

/// Project 2019: eight links of the four types, lags of 0, 1 and 2 days
/// (`LagFormat` 7) and 1 and 2 weeks (`LagFormat` 9), in tenths of a
/// minute of working time: 8 h a day, 40 h a week.
#[test]
fn project_2019_reads_every_link_type_and_lag() {
    let tasks = msproject::read(&public("task-links-project2019-mspdi.xml")).unwrap();
    assert_eq!(tasks.len(), 17);
    let h = 3600.0;
    let links: Vec<(&str, &Predecessor)> = tasks
        .iter()
        .flat_map(|t| t.predecessors.iter().map(move |p| (t.id.as_str(), p)))
        .collect();
    let want = [
        ("2", "1", LinkType::FinishStart, 0.0),
        ("4", "3", LinkType::FinishStart, 8.0 * h),
        ("6", "5", LinkType::FinishStart, 16.0 * h),
        ("8", "7", LinkType::FinishStart, 40.0 * h),
        ("10", "9", LinkType::FinishStart, 80.0 * h),
        ("12", "11", LinkType::StartFinish, 16.0 * h),
        ("14", "13", LinkType::StartStart, 16.0 * h),
        ("16", "15", LinkType::FinishFinish, 16.0 * h),
    ];
    assert_eq!(links.len(), want.len());
    for ((id, p), (wid, wpred, wkind, wlag)) in links.iter().zip(want) {
        assert_eq!(
            (*id, p.task.as_str(), p.kind, p.lag),
            (wid, wpred, wkind, wlag)
        );
    }
}

/// An older Project XML (no `SaveVersion`; a 2003 plan): summary tasks, names carrying
/// their path, and links with a lead (a negative lag).
#[test]
fn older_project_xml_reads_summaries_and_leads() {
    let tasks = msproject::read(&public("sample.xml")).unwrap();
    assert_eq!(tasks.len(), 20);
    let t = task(&tasks, "14");
    assert_eq!(t.name, "Task Relationships / Related Task 3b");
    assert_eq!(t.parent.as_deref(), Some("19"));
    assert_eq!(t.wbs.as_deref(), Some("3.6"));
    assert_eq!(
        t.predecessors,
        [Predecessor {
            task: "13".into(),
            kind: LinkType::FinishStart,
            lag: -8.0 * 3600.0
        }]
    );
    assert_eq!(task(&tasks, "7").parent.as_deref(), Some("6"));
    let summaries: Vec<&str> = ["1", "6", "19"]
        .into_iter()
        .filter(|id| tasks.iter().any(|t| t.parent.as_deref() == Some(*id)))
        .collect();
    assert_eq!(summaries, ["1", "6", "19"]);
}

/// Extended attributes named by the project's definitions (`FieldName`
/// where no `Alias`): text, cost, dates, flag, number, duration.
#[test]
fn project_extended_attributes_become_fields() {
    let tasks = msproject::read(&public("mspextattr.xml")).unwrap();
    let t = task(&tasks, "1");
    assert_eq!(t.name, "Task One");
    assert_eq!(t.fields["Text1"], "Task Text One");
    assert_eq!(t.fields["Cost1"], "9995");
    assert_eq!(t.fields["Start1"], "2004-01-01T08:00:00");
    assert_eq!(t.fields["Date1"], "2004-07-18T08:00:00");
    assert_eq!(t.fields["Flag1"], "1");
}

/// A test file of baselines 1 to 10 that each finish a year before they
/// start: an error that names the file, the element and the task.
#[test]
fn a_baseline_that_finishes_before_it_starts_is_named() {
    let e = msproject::read(&public("baselines.xml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("baselines.xml"), "{e}");
    assert!(e.contains("Tasks/Task[1]/Baseline[0]/Finish"), "{e}");
    assert!(e.contains("task 1"), "{e}");
}

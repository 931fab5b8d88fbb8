//! Microsoft Project XML schedules (the `http://schemas.microsoft.com/project`
//! format that Project saves as "XML"): every task with a start and a finish
//! becomes a schedule task, id = its `UID`. Names carry the path of their
//! summary tasks (outline levels), so that tasks repeated storey by storey
//! stay tellable apart in reports; each task's `parent` is the `UID` of its
//! summary task, and summary tasks are tasks of their own (the import keeps
//! those above its scene's tasks, for a Gantt chart to group them).
//!
//! Actual dates are `ActualStart` and `ActualFinish`; the baseline is the
//! `Baseline` with `Number` 0, else the lowest-numbered one with a start and
//! a finish (Project keeps up to eleven, 0 to 10).
//!
//! Reference: Microsoft Office Project XML Data Interchange Schema
//! (mspdi_pj12.xsd): `Project/Tasks/Task` with `UID`, `Name`, `OutlineLevel`,
//! `Summary`, `Start`, `Finish`, `ActualStart`, `ActualFinish` and
//! `Baseline` (`Number`, `Start`, `Finish`).

use std::path::Path;

use chrono::{DateTime, Utc};
use roxmltree::Node;

use super::{Recorded, ScheduleTask};
use crate::error::{Error, Result};
use crate::time::parse_date;

/// The text of the first child element `name`, trimmed, if not empty.
fn child<'a>(n: Node<'a, '_>, name: &str) -> Option<&'a str> {
    n.children()
        .find(|c| c.tag_name().name() == name)
        .and_then(|c| c.text())
        .map(str::trim)
        .filter(|t| !t.is_empty())
}

/// Reads the tasks of a Project XML file, summary tasks included.
pub fn read(path: &Path) -> Result<Vec<ScheduleTask>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let doc = roxmltree::Document::parse(&text)
        .map_err(|e| Error::invalid(path, "XML", e.to_string()))?;
    let root = doc.root_element();
    if root.tag_name().name() != "Project" {
        return Err(Error::invalid(
            path,
            root.tag_name().name(),
            "not a Microsoft Project XML file (the root element is not <Project>)",
        ));
    }
    let mut tasks = Vec::new();
    // The open summary tasks by outline level: name and UID.
    let mut outline: Vec<Option<(String, String)>> = Vec::new();
    let list = root.children().find(|c| c.tag_name().name() == "Tasks");
    for (i, task) in list
        .into_iter()
        .flat_map(|l| l.children())
        .filter(|c| c.tag_name().name() == "Task")
        .enumerate()
    {
        let at = |field: &str| format!("Tasks/Task[{i}]/{field}");
        let Some(uid) = child(task, "UID") else {
            return Err(Error::invalid(path, at("UID"), "missing"));
        };
        let level: usize = child(task, "OutlineLevel")
            .and_then(|l| l.parse().ok())
            .unwrap_or(1)
            .max(1);
        let name = child(task, "Name").unwrap_or_default().to_string();
        outline.truncate(level - 1);
        let mut path_name: Vec<&str> = outline
            .iter()
            .flatten()
            .map(|(n, _)| n.as_str())
            .filter(|s| !s.is_empty())
            .collect();
        path_name.push(&name);
        let full_name = path_name.join(" / ");
        let parent = outline
            .iter()
            .rev()
            .flatten()
            .next()
            .map(|(_, u)| u.clone());
        if child(task, "Summary") == Some("1") {
            outline.resize(level - 1, None);
            outline.push(Some((name.clone(), uid.to_string())));
        }
        let date = |field: &str, at: &str| -> Result<Option<DateTime<Utc>>> {
            child(task, field)
                .map(|t| parse_date(t).map_err(|m| Error::invalid(path, at, m.to_string())))
                .transpose()
        };
        let (Some(start), Some(finish)) =
            (date("Start", &at("Start"))?, date("Finish", &at("Finish"))?)
        else {
            continue;
        };
        if finish < start {
            return Err(Error::invalid(
                path,
                at("Finish"),
                format!("task {uid} finishes before it starts"),
            ));
        }
        let actual = Recorded::new(
            date("ActualStart", &at("ActualStart"))?,
            date("ActualFinish", &at("ActualFinish"))?,
        )
        .map_err(|m| Error::invalid(path, at("ActualFinish"), format!("task {uid}: {m}")))?;
        tasks.push(ScheduleTask {
            actual,
            baseline: baseline(path, task, &at, uid)?,
            parent,
            ..ScheduleTask::planned(uid, full_name, start, finish)
        });
    }
    Ok(tasks)
}

/// Baseline 0, else the lowest-numbered baseline with both dates.
fn baseline(
    path: &Path,
    task: Node,
    at: &dyn Fn(&str) -> String,
    uid: &str,
) -> Result<Option<(DateTime<Utc>, DateTime<Utc>)>> {
    let mut found: Vec<(u32, usize, Node)> = task
        .children()
        .filter(|c| c.tag_name().name() == "Baseline")
        .enumerate()
        .filter(|(_, b)| child(*b, "Start").is_some() && child(*b, "Finish").is_some())
        .map(|(j, b)| {
            let number = child(b, "Number").and_then(|n| n.parse().ok());
            (number.unwrap_or(u32::MAX), j, b)
        })
        .collect();
    found.sort_by_key(|&(number, j, _)| (number, j));
    let Some(&(_, j, b)) = found.first() else {
        return Ok(None);
    };
    let date = |field: &str| {
        let at = at(&format!("Baseline[{j}]/{field}"));
        parse_date(child(b, field).unwrap_or_default())
            .map_err(|m| Error::invalid(path, at, m.to_string()))
    };
    let (start, finish) = (date("Start")?, date("Finish")?);
    if finish < start {
        return Err(Error::invalid(
            path,
            at(&format!("Baseline[{j}]/Finish")),
            format!("task {uid}: the baseline finishes before it starts"),
        ));
    }
    Ok(Some((start, finish)))
}

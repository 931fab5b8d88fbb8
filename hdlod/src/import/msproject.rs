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
//! Links are the task's `PredecessorLink`s (`PredecessorUID`; `Type` 0 FF,
//! 1 FS, 2 SF, 3 SS; `LinkLag` in tenths of a minute; percent lags,
//! `LagFormat` 19 and 20, are read as none); a link to another project
//! (`CrossProject` 1) is left out. Custom fields are the task's
//! `ExtendedAttribute` values, named by the project's `ExtendedAttributes`
//! definitions (`Alias`, else `FieldName`, such as `Text1`), and the
//! task's `WBS` code (else its `OutlineNumber`) is its place in the work
//! breakdown: both are there for the linking rules.
//!
//! Reference: Microsoft Office Project XML Data Interchange Schema
//! (mspdi_pj12.xsd): `Project/Tasks/Task` with `UID`, `Name`, `WBS`,
//! `OutlineNumber`, `OutlineLevel`, `Summary`, `Start`, `Finish`,
//! `ActualStart`, `ActualFinish`, `Baseline` (`Number`, `Start`, `Finish`),
//! `PredecessorLink` (`PredecessorUID`, `Type`, `CrossProject`, `LinkLag`,
//! `LagFormat`) and `ExtendedAttribute` (`FieldID`, `Value`);
//! `Project/ExtendedAttributes/ExtendedAttribute` (`FieldID`, `FieldName`,
//! `Alias`).

use std::collections::HashMap;
use std::path::Path;

use chrono::{DateTime, Utc};
use roxmltree::Node;

use super::{Recorded, ScheduleTask, check_links};
use crate::error::{Error, Result};
use crate::scene::{LinkType, Predecessor};
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
    let text = crate::input::read_to_string(path)?;
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
    let names = field_names(root);
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
        let fields = task
            .children()
            .filter(|c| c.tag_name().name() == "ExtendedAttribute")
            .filter_map(|a| {
                let id = child(a, "FieldID")?;
                let value = child(a, "Value")?;
                let name = names.get(id).cloned().unwrap_or_else(|| id.to_string());
                Some((name, value.to_string()))
            })
            .collect();
        tasks.push(ScheduleTask {
            actual,
            baseline: baseline(path, task, &at, uid)?,
            parent,
            predecessors: links(path, task, &at)?,
            wbs: child(task, "WBS")
                .or(child(task, "OutlineNumber"))
                .map(str::to_string),
            fields,
            ..ScheduleTask::planned(uid, full_name, start, finish)
        });
    }
    // Links to tasks without dates (not read) are left out with them.
    let known: std::collections::HashSet<String> = tasks.iter().map(|t| t.id.clone()).collect();
    for t in &mut tasks {
        t.predecessors.retain(|p| known.contains(&p.task));
    }
    check_links(path, "Tasks/Task/PredecessorLink", &tasks)?;
    Ok(tasks)
}

/// The names of the project's custom fields by `FieldID`: the alias a
/// planner gave, else the field's own name.
fn field_names(root: Node) -> HashMap<String, String> {
    root.children()
        .filter(|c| c.tag_name().name() == "ExtendedAttributes")
        .flat_map(|l| l.children())
        .filter(|c| c.tag_name().name() == "ExtendedAttribute")
        .filter_map(|a| {
            let id = child(a, "FieldID")?;
            let name = child(a, "Alias").or(child(a, "FieldName"))?;
            Some((id.to_string(), name.to_string()))
        })
        .collect()
}

/// A task's `PredecessorLink`s within the project.
fn links(path: &Path, task: Node, at: &dyn Fn(&str) -> String) -> Result<Vec<Predecessor>> {
    let mut out = Vec::new();
    for (j, link) in task
        .children()
        .filter(|c| c.tag_name().name() == "PredecessorLink")
        .enumerate()
    {
        let field = |f: &str| at(&format!("PredecessorLink[{j}]/{f}"));
        if child(link, "CrossProject") == Some("1") {
            continue;
        }
        let Some(uid) = child(link, "PredecessorUID") else {
            return Err(Error::invalid(path, field("PredecessorUID"), "missing"));
        };
        let kind = match child(link, "Type").unwrap_or("1") {
            "0" => LinkType::FinishFinish,
            "1" => LinkType::FinishStart,
            "2" => LinkType::StartFinish,
            "3" => LinkType::StartStart,
            other => {
                return Err(Error::invalid(
                    path,
                    field("Type"),
                    format!("{other:?} is not a link type (0 FF, 1 FS, 2 SF, 3 SS)"),
                ));
            }
        };
        let percent = matches!(child(link, "LagFormat"), Some("19" | "20"));
        let lag = match child(link, "LinkLag") {
            Some(_) if percent => 0.0,
            Some(l) => {
                l.parse::<f64>()
                    .ok()
                    .filter(|l| l.is_finite() && l.abs() < 1e10)
                    .ok_or_else(|| {
                        Error::invalid(
                            path,
                            field("LinkLag"),
                            format!("{l:?} is not a lag in tenths of a minute"),
                        )
                    })?
                    * 6.0
            }
            None => 0.0,
        };
        out.push(Predecessor {
            task: uid.to_string(),
            kind,
            lag,
        });
    }
    Ok(out)
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

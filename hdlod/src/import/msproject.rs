//! Microsoft Project XML schedules (the `http://schemas.microsoft.com/project`
//! format that Project saves as "XML"): every task with a start and a finish
//! becomes a schedule task, id = its `UID`. Names carry the path of their
//! summary tasks (outline levels), so that tasks repeated storey by storey
//! stay tellable apart in reports.
//!
//! Reference: Microsoft Office Project XML Data Interchange Schema
//! (mspdi_pj12.xsd): `Project/Tasks/Task` with `UID`, `Name`, `OutlineLevel`,
//! `Summary`, `Start`, `Finish`.

use std::path::Path;

use super::ScheduleTask;
use crate::error::{Error, Result};
use crate::time::parse_date;

/// Reads the tasks of a Project XML file. Summary tasks are not tasks of
/// their own: their names prefix those of the tasks under them.
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
    fn child<'a>(n: roxmltree::Node<'a, '_>, name: &str) -> Option<&'a str> {
        n.children()
            .find(|c| c.tag_name().name() == name)
            .and_then(|c| c.text())
            .map(str::trim)
            .filter(|t| !t.is_empty())
    }
    let mut tasks = Vec::new();
    // The names of the open summary tasks, by outline level.
    let mut outline: Vec<String> = Vec::new();
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
        if child(task, "Summary") == Some("1") {
            outline.resize(level - 1, String::new());
            outline.push(name);
            continue;
        }
        let date = |field: &str| -> Result<Option<_>> {
            child(task, field)
                .map(|t| parse_date(t).map_err(|m| Error::invalid(path, at(field), m.to_string())))
                .transpose()
        };
        let (Some(start), Some(finish)) = (date("Start")?, date("Finish")?) else {
            continue;
        };
        if finish < start {
            return Err(Error::invalid(
                path,
                at("Finish"),
                format!("task {uid} finishes before it starts"),
            ));
        }
        let mut path_name: Vec<&str> = outline
            .iter()
            .map(String::as_str)
            .filter(|s| !s.is_empty())
            .collect();
        path_name.push(&name);
        tasks.push(ScheduleTask {
            id: uid.to_string(),
            name: path_name.join(" / "),
            kind: None,
            start,
            finish,
            objects: Vec::new(),
        });
    }
    Ok(tasks)
}

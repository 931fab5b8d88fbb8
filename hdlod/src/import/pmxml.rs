//! Primavera P6 XML (PMXML, "Primavera PM - XML" exports): the same
//! schedule as XER, as business objects under `APIBusinessObjects`. Read
//! as XER is (`xer.rs`): one project (`--project`, by `Id` or `ObjectId`,
//! when the file holds several), its activities with planned
//! (`PlannedStartDate`/`PlannedFinishDate`), actual, early and late dates,
//! its WBS nodes as summary tasks (code path from the project's `Id`), its
//! relationships, activity codes and user fields.
//!
//! P6 writes a project's `WBS`, `Activity` and `Relationship` inside its
//! `Project` element; other tools write them beside it with a
//! `ProjectObjectId`: both are read. Activity codes (`ActivityCodeType`,
//! `ActivityCode`) and user field types (`UDFType`) may be global (under
//! the root) or the project's.
//!
//! Reference: Oracle Primavera P6 EPPM XML schema (`p6apibo.xsd`):
//! `Project` (`ObjectId`, `Id`, `Name`), `WBS` (`ObjectId`,
//! `ParentObjectId`, `ProjectObjectId`, `Code`, `Name`), `Activity`
//! (`ObjectId`, `Id`, `Name`, `WBSObjectId`, `PlannedStartDate`,
//! `PlannedFinishDate`, `ActualStartDate`, `ActualFinishDate`,
//! `EarlyStartDate`, `EarlyFinishDate`, `LateStartDate`, `LateFinishDate`,
//! `Code` (`TypeObjectId`, `ValueObjectId`), `UDF` (`TypeObjectId`, a
//! `...Value`)), `Relationship` (`PredecessorActivityObjectId`,
//! `SuccessorActivityObjectId`, `Type`, `Lag` in hours), `ActivityCodeType`
//! (`ObjectId`, `Name`), `ActivityCode` (`ObjectId`, `CodeTypeObjectId`,
//! `CodeValue`), `UDFType` (`ObjectId`, `Title`, `SubjectArea`).

use std::collections::HashMap;
use std::path::Path;

use chrono::{DateTime, Utc};
use roxmltree::Node;

use super::wbs::{RawNode, Wbs};
use super::xer::YEARS;
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

fn named<'a, 'i>(n: Node<'a, 'i>, name: &'static str) -> impl Iterator<Item = Node<'a, 'i>> {
    n.children().filter(move |c| c.tag_name().name() == name)
}

/// A business object of the file with where it is, for errors:
/// `Activity[3]` (its index among its kind in the project).
struct Object<'a, 'i> {
    node: Node<'a, 'i>,
    at: String,
}

impl Object<'_, '_> {
    fn field(&self, name: &str) -> String {
        format!("{}/{name}", self.at)
    }

    fn date(&self, path: &Path, name: &str) -> Result<Option<DateTime<Utc>>> {
        let Some(text) = child(self.node, name) else {
            return Ok(None);
        };
        let date =
            parse_date(text).map_err(|m| Error::invalid(path, self.field(name), m.to_string()))?;
        let year: i32 = date.format("%Y").to_string().parse().unwrap_or(0);
        if !YEARS.contains(&year) {
            return Err(Error::invalid(
                path,
                self.field(name),
                format!(
                    "{text:?} is out of range (years {} to {})",
                    YEARS.start(),
                    YEARS.end()
                ),
            ));
        }
        Ok(Some(date))
    }

    fn dates(
        &self,
        path: &Path,
        start: &str,
        finish: &str,
    ) -> Result<Option<(DateTime<Utc>, DateTime<Utc>)>> {
        match (self.date(path, start)?, self.date(path, finish)?) {
            (Some(s), Some(f)) if f < s => Err(Error::invalid(
                path,
                self.field(finish),
                format!("{f} is before the start {s}"),
            )),
            (Some(s), Some(f)) => Ok(Some((s, f))),
            _ => Ok(None),
        }
    }
}

/// Reads the activities of one project of a P6 XML file, with its WBS
/// nodes as summary tasks.
pub fn read(path: &Path, project: Option<&str>) -> Result<Vec<ScheduleTask>> {
    let text = crate::input::read_to_string(path)?;
    let doc = roxmltree::Document::parse(&text)
        .map_err(|e| Error::invalid(path, "XML", e.to_string()))?;
    let root = doc.root_element();
    if root.tag_name().name() != "APIBusinessObjects" {
        return Err(Error::invalid(
            path,
            root.tag_name().name(),
            "not a P6 XML file (the root element is not <APIBusinessObjects>)",
        ));
    }
    let projects: Vec<Node> = named(root, "Project").collect();
    let described = |p: &Node| {
        let n = named(*p, "Activity").count()
            + named(root, "Activity")
                .filter(|a| child(*a, "ProjectObjectId") == child(*p, "ObjectId"))
                .count();
        format!(
            "{} (ObjectId {}, {n} activities)",
            child(*p, "Id").unwrap_or("?"),
            child(*p, "ObjectId").unwrap_or("?")
        )
    };
    let list = || {
        projects
            .iter()
            .map(described)
            .collect::<Vec<_>>()
            .join(", ")
    };
    let (k, chosen) = match (project, &projects[..]) {
        (_, []) => return Err(Error::invalid(path, "Project", "the file holds no project")),
        (None, [p]) => (0, *p),
        (None, _) => {
            return Err(Error::invalid(
                path,
                "Project",
                format!(
                    "the file holds {} projects; choose one with --project: {}",
                    projects.len(),
                    list()
                ),
            ));
        }
        (Some(w), _) => projects
            .iter()
            .enumerate()
            .find(|(_, p)| child(**p, "Id") == Some(w) || child(**p, "ObjectId") == Some(w))
            .map(|(k, p)| (k, *p))
            .ok_or_else(|| {
                Error::invalid(
                    path,
                    "Project",
                    format!("no project {w:?} in the file; it holds {}", list()),
                )
            })?,
    };
    let project_id = child(chosen, "ObjectId").unwrap_or_default();
    let project_code = child(chosen, "Id").unwrap_or(project_id);
    // The project's objects of a kind: inside it, or beside it naming it.
    let objects = |kind: &'static str| -> Vec<Object> {
        let inside = named(chosen, kind)
            .enumerate()
            .map(move |(i, node)| Object {
                node,
                at: format!("Project[{k}]/{kind}[{i}]"),
            });
        let beside = named(root, kind)
            .enumerate()
            .filter(|(_, n)| child(*n, "ProjectObjectId") == Some(project_id))
            .map(move |(i, node)| Object {
                node,
                at: format!("{kind}[{i}]"),
            });
        inside.chain(beside).collect()
    };
    let global = |kind: &'static str| -> Vec<Node> {
        named(root, kind).chain(named(chosen, kind)).collect()
    };

    // The WBS under the project's own node.
    let wbs_objects = objects("WBS");
    let mut raw = vec![RawNode {
        id: project_id,
        parent: "",
        short: project_code,
        name: child(chosen, "Name").unwrap_or_default(),
        root: true,
    }];
    for w in &wbs_objects {
        raw.push(RawNode {
            id: child(w.node, "ObjectId").unwrap_or_default(),
            parent: child(w.node, "ParentObjectId").unwrap_or(project_id),
            short: child(w.node, "Code").unwrap_or_default(),
            name: child(w.node, "Name").unwrap_or_default(),
            root: false,
        });
    }
    let wbs = Wbs::new(&raw).map_err(|id| {
        Error::invalid(
            path,
            format!("WBS {id}/ParentObjectId"),
            "the WBS parents form a cycle",
        )
    })?;

    let code_types: HashMap<&str, &str> = global("ActivityCodeType")
        .into_iter()
        .filter_map(|n| Some((child(n, "ObjectId")?, child(n, "Name")?)))
        .collect();
    let code_values: HashMap<&str, (&str, &str)> = global("ActivityCode")
        .into_iter()
        .filter_map(|n| {
            Some((
                child(n, "ObjectId")?,
                (child(n, "CodeTypeObjectId")?, child(n, "CodeValue")?),
            ))
        })
        .collect();
    let udf_titles: HashMap<&str, &str> = global("UDFType")
        .into_iter()
        .filter(|n| child(*n, "SubjectArea").is_none_or(|a| a == "Activity"))
        .filter_map(|n| Some((child(n, "ObjectId")?, child(n, "Title")?)))
        .collect();

    let mut tasks = Vec::new();
    let mut by_object: HashMap<&str, usize> = HashMap::new();
    for a in objects("Activity") {
        let Some(id) = child(a.node, "Id") else {
            return Err(Error::invalid(
                path,
                a.field("Id"),
                "an activity without an Activity ID",
            ));
        };
        let early = a.dates(path, "EarlyStartDate", "EarlyFinishDate")?;
        let planned = match a.dates(path, "PlannedStartDate", "PlannedFinishDate")? {
            Some(p) => p,
            None => early.ok_or_else(|| {
                Error::invalid(
                    path,
                    a.field("PlannedStartDate"),
                    format!("activity {id}: no planned dates and no early dates"),
                )
            })?,
        };
        let actual = Recorded::new(
            a.date(path, "ActualStartDate")?,
            a.date(path, "ActualFinishDate")?,
        )
        .map_err(|m| {
            Error::invalid(
                path,
                a.field("ActualFinishDate"),
                format!("activity {id}: {m}"),
            )
        })?;
        let node = wbs.node(child(a.node, "WBSObjectId").unwrap_or_default());
        let name = child(a.node, "Name").unwrap_or_default();
        let mut task = ScheduleTask {
            actual,
            early,
            late: a.dates(path, "LateStartDate", "LateFinishDate")?,
            parent: node.and_then(|n| n.summary.then(|| n.code.clone())),
            wbs: node.map(|n| n.code.clone()),
            ..ScheduleTask::planned(
                id,
                match node {
                    Some(n) if !n.names.is_empty() => format!("{} / {name}", n.names),
                    _ => name.to_string(),
                },
                planned.0,
                planned.1,
            )
        };
        for (j, c) in named(a.node, "Code").enumerate() {
            let value = child(c, "ValueObjectId").unwrap_or_default();
            let Some(&(ty, v)) = code_values.get(value) else {
                return Err(Error::invalid(
                    path,
                    a.field(&format!("Code[{j}]/ValueObjectId")),
                    format!("no ActivityCode has ObjectId {value:?}"),
                ));
            };
            let Some(&type_name) = code_types.get(ty) else {
                return Err(Error::invalid(
                    path,
                    a.field(&format!("Code[{j}]/ValueObjectId")),
                    format!("its code's type {ty:?} is no ActivityCodeType"),
                ));
            };
            task.codes.insert(type_name.to_string(), v.to_string());
        }
        for u in named(a.node, "UDF") {
            let Some(&title) = child(u, "TypeObjectId").and_then(|t| udf_titles.get(t)) else {
                continue;
            };
            let value = u
                .children()
                .filter(|c| c.is_element() && c.tag_name().name() != "TypeObjectId")
                .find_map(|c| c.text().map(str::trim).filter(|t| !t.is_empty()));
            if let Some(v) = value {
                task.fields.insert(title.to_string(), v.to_string());
            }
        }
        if let Some(o) = child(a.node, "ObjectId") {
            by_object.insert(o, tasks.len());
        }
        tasks.push(task);
    }

    for r in objects("Relationship") {
        let end = |field: &str| -> Result<Option<usize>> {
            let Some(o) = child(r.node, field) else {
                return Err(Error::invalid(path, r.field(field), "missing"));
            };
            Ok(by_object.get(o).copied())
        };
        // A link to an activity of another project is left out.
        let (Some(pred), Some(succ)) = (
            end("PredecessorActivityObjectId")?,
            end("SuccessorActivityObjectId")?,
        ) else {
            continue;
        };
        let kind = child(r.node, "Type").unwrap_or("Finish to Start");
        let kind = LinkType::parse(kind).ok_or_else(|| {
            Error::invalid(
                path,
                r.field("Type"),
                format!("{kind:?} is not a link type (Finish to Start, ...)"),
            )
        })?;
        let lag = match child(r.node, "Lag") {
            None => 0.0,
            Some(l) => l
                .parse::<f64>()
                .ok()
                .filter(|h| h.is_finite() && h.abs() < 1e6)
                .ok_or_else(|| {
                    Error::invalid(path, r.field("Lag"), format!("{l:?} is not a lag in hours"))
                })?,
        };
        let task = tasks[pred].id.clone();
        tasks[succ].predecessors.push(Predecessor {
            task,
            kind,
            lag: lag * 3600.0,
        });
    }
    check_links(path, "Relationship", &tasks)?;
    let summaries = wbs.summaries(&tasks);
    tasks.extend(summaries);
    Ok(tasks)
}

//! Element-task links as 4D tools export them: one CSV row per (element,
//! task) with the element's GlobalId, the task id, its start and finish, and
//! optionally the task's name and type. Headers are matched by the names
//! these exports use (`GUID`/`GlobalId`, `Task`/`TaskId`, `TaskStart`/
//! `Start`, `TaskFinish`/`Finish`, `TaskName`/`Name`, `Type`), any case.
//! Dates are ISO 8601 or day-month-year (`26-2-2015`, `26/02/2015`).

use std::collections::BTreeMap;
use std::path::Path;

use chrono::{DateTime, NaiveDate, Utc};

use super::ScheduleTask;
use crate::error::{Error, Result};
use crate::scene::TaskType;
use crate::time::parse_date;

const GUID: &[&str] = &["guid", "globalid", "element", "elementguid", "element_guid"];
const TASK: &[&str] = &["task", "taskid", "task_id"];
const START: &[&str] = &["taskstart", "start", "task_start"];
const FINISH: &[&str] = &["taskfinish", "finish", "task_finish", "end"];
const NAME: &[&str] = &["taskname", "name", "task_name"];
const TYPE: &[&str] = &["type", "tasktype", "task_type"];

/// Reads the links into tasks: one task per task id (its objects in file
/// order), with the dates of its first row.
pub fn read(path: &Path) -> Result<Vec<ScheduleTask>> {
    let mut reader = csv::ReaderBuilder::new()
        .flexible(false)
        .from_path(path)
        .map_err(|e| Error::invalid(path, "CSV", e.to_string()))?;
    let headers = reader
        .headers()
        .map_err(|e| Error::invalid(path, "header", e.to_string()))?
        .clone();
    let column = |names: &[&str]| {
        headers
            .iter()
            .position(|h| names.contains(&h.trim().to_ascii_lowercase().as_str()))
    };
    let need = |names: &[&str]| {
        column(names).ok_or_else(|| {
            Error::invalid(
                path,
                "header",
                format!("no column named {} (any case)", names.join(" or ")),
            )
        })
    };
    let (guid, task, start, finish) = (need(GUID)?, need(TASK)?, need(START)?, need(FINISH)?);
    let (name, kind) = (column(NAME), column(TYPE));

    let mut tasks: Vec<ScheduleTask> = Vec::new();
    let mut by_id: BTreeMap<String, usize> = BTreeMap::new();
    for (i, row) in reader.records().enumerate() {
        let line = i + 2;
        let row = row.map_err(|e| Error::invalid(path, format!("line {line}"), e.to_string()))?;
        let field = |c: usize| row.get(c).unwrap_or_default().trim();
        let at = |c: usize| format!("line {line}, column {:?}", &headers[c]);
        let id = field(task);
        let element = field(guid);
        if id.is_empty() || element.is_empty() {
            return Err(Error::invalid(
                path,
                at(if id.is_empty() { task } else { guid }),
                "empty",
            ));
        }
        let index = match by_id.get(id) {
            Some(&k) => k,
            None => {
                let date =
                    |c: usize| parse_csv_date(field(c)).map_err(|m| Error::invalid(path, at(c), m));
                let (s, f) = (date(start)?, date(finish)?);
                if f < s {
                    return Err(Error::invalid(
                        path,
                        at(finish),
                        format!("task {id} finishes before it starts"),
                    ));
                }
                let kind = match kind.map(field).filter(|k| !k.is_empty()) {
                    Some(k) => Some(TaskType::parse(k).ok_or_else(|| {
                        Error::invalid(
                            path,
                            at(kind.unwrap_or(0)),
                            format!("unknown task type {k:?}; expected {}", TaskType::NAMES),
                        )
                    })?),
                    None => None,
                };
                tasks.push(ScheduleTask {
                    id: id.to_string(),
                    name: name.map(field).unwrap_or_default().to_string(),
                    kind,
                    start: s,
                    // A task given by days ends at the end of its last day.
                    finish: if f == s && !field(finish).contains('T') {
                        f + chrono::Duration::days(1)
                    } else {
                        f
                    },
                    objects: Vec::new(),
                });
                by_id.insert(id.to_string(), tasks.len() - 1);
                tasks.len() - 1
            }
        };
        let objects = &mut tasks[index].objects;
        if !objects.iter().any(|o| o == element) {
            objects.push(element.to_string());
        }
    }
    Ok(tasks)
}

/// ISO 8601, or the day-first dates of European exports.
fn parse_csv_date(text: &str) -> std::result::Result<DateTime<Utc>, String> {
    if let Ok(d) = parse_date(text) {
        return Ok(d);
    }
    for format in ["%d-%m-%Y", "%d/%m/%Y", "%d.%m.%Y"] {
        if let Ok(d) = NaiveDate::parse_from_str(text, format) {
            return Ok(d.and_hms_opt(0, 0, 0).expect("midnight exists").and_utc());
        }
    }
    Err(format!(
        "{text:?} is not a date (ISO 8601 such as 2015-02-26, or day-month-year such as 26-2-2015)"
    ))
}

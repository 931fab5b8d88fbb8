//! Element-task links as 4D tools export them: one CSV row per (element,
//! task) with the element's GlobalId, the task id, its start and finish, and
//! optionally the task's name and type. Headers are matched by the names
//! these exports use (`GUID`/`GlobalId`, `Task`/`TaskId`, `TaskStart`/
//! `Start`, `TaskFinish`/`Finish`, `TaskName`/`Name`, `Type`), any case.
//! Dates are ISO 8601 or day-month-year (`26-2-2015`, `26/02/2015`); a
//! finish given as a day, without a time, is the end of that day. Rows
//! with every field empty (the padding of spreadsheet exports) are left
//! out. [`super::actual`] reads the same files as as-built records.

use std::collections::BTreeMap;
use std::path::Path;

use chrono::{DateTime, NaiveDate, Utc};

use super::ScheduleTask;
use crate::error::{Error, Result};
use crate::scene::{NamedType, TaskType};
use crate::time::parse_date;

pub(super) const GUID: &[&str] = &["guid", "globalid", "element", "elementguid", "element_guid"];
pub(super) const TASK: &[&str] = &["task", "taskid", "task_id"];
pub(super) const START: &[&str] = &["taskstart", "start", "task_start"];
pub(super) const FINISH: &[&str] = &["taskfinish", "finish", "task_finish", "end"];
pub(super) const NAME: &[&str] = &["taskname", "name", "task_name"];
const TYPE: &[&str] = &["type", "tasktype", "task_type"];

/// A CSV file's rows with its header: columns found by their names.
pub(super) struct Table<'a> {
    pub path: &'a Path,
    pub headers: csv::StringRecord,
    reader: csv::Reader<std::fs::File>,
}

impl<'a> Table<'a> {
    pub fn open(path: &'a Path) -> Result<Table<'a>> {
        let mut reader = csv::ReaderBuilder::new()
            .flexible(false)
            .from_reader(crate::input::open(path)?);
        let headers = reader
            .headers()
            .map_err(|e| Error::invalid(path, "header", e.to_string()))?
            .clone();
        Ok(Table {
            path,
            headers,
            reader,
        })
    }

    /// The first column with one of `names`, any case.
    pub fn column(&self, names: &[&str]) -> Option<usize> {
        self.headers
            .iter()
            .position(|h| names.contains(&h.trim().to_ascii_lowercase().as_str()))
    }

    pub fn need(&self, names: &[&str]) -> Result<usize> {
        self.column(names).ok_or_else(|| {
            Error::invalid(
                self.path,
                "header",
                format!("no column named {} (any case)", names.join(" or ")),
            )
        })
    }

    /// The rows that are not blank, with their line numbers (the header is
    /// line 1; a row's line is its record's, as no field spans lines in
    /// these exports).
    pub fn rows(&mut self) -> impl Iterator<Item = Result<(usize, csv::StringRecord)>> + '_ {
        let path = self.path;
        self.reader
            .records()
            .enumerate()
            .map(move |(i, row)| {
                let line = i + 2;
                row.map(|r| (line, r))
                    .map_err(|e| Error::invalid(path, format!("line {line}"), e.to_string()))
            })
            .filter(|row| !matches!(row, Ok((_, r)) if r.iter().all(|f| f.trim().is_empty())))
    }
}

/// Reads the links into tasks: one task per task id (its objects in file
/// order), with the dates of its first row.
pub fn read(path: &Path) -> Result<Vec<ScheduleTask>> {
    let mut table = Table::open(path)?;
    let (guid, task, start, finish) = (
        table.need(GUID)?,
        table.need(TASK)?,
        table.need(START)?,
        table.need(FINISH)?,
    );
    let (name, kind) = (table.column(NAME), table.column(TYPE));

    let mut tasks: Vec<ScheduleTask> = Vec::new();
    let mut by_id: BTreeMap<String, usize> = BTreeMap::new();
    let headers = table.headers.clone();
    for row in table.rows() {
        let (line, row) = row?;
        let field = |c: usize| row.get(c).unwrap_or_default().trim();
        let at = |c: usize| at(&headers, line, c);
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
                let f = end_of(field(finish), f);
                let kind = match kind.map(field).filter(|k| !k.is_empty()) {
                    Some(k) => Some(NamedType::parse(k).ok_or_else(|| {
                        Error::invalid(
                            path,
                            at(kind.unwrap_or(0)),
                            format!("unknown task type {k:?}; expected {}", TaskType::NAMES),
                        )
                    })?),
                    None => None,
                };
                tasks.push(ScheduleTask {
                    kind,
                    ..ScheduleTask::planned(id, name.map(field).unwrap_or_default(), s, f)
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

/// Where a field is: `line N, column "NAME"`.
pub(super) fn at(headers: &csv::StringRecord, line: usize, column: usize) -> String {
    format!("line {line}, column {:?}", &headers[column])
}

/// A finish as written: given as a day, without a time, it is the end of
/// that day (a task from 26-2 to 27-2 takes both days).
pub(super) fn end_of(text: &str, date: DateTime<Utc>) -> DateTime<Utc> {
    if text.contains('T') {
        date
    } else {
        date + chrono::Duration::days(1)
    }
}

/// ISO 8601, or the day-first dates of European exports.
pub(super) fn parse_csv_date(text: &str) -> std::result::Result<DateTime<Utc>, String> {
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

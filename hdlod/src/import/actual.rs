//! As-built logs: element-task rows in the shape of the links CSV
//! ([`super::links_csv`]) read as what happened: their dates become the
//! actual dates of the schedule's tasks (`hdlod import ... --actual
//! FILE.csv`, docs/import.md).
//!
//! A task of the log is its rows with one task id (or, without an id
//! column, one name). It started at its rows' first start and finished at
//! their last finish once every row has one; a row without a finish is
//! still running, one without dates has not started. A finish given as a
//! day is the end of that day, as in the links CSV. A log that gives days
//! says nothing of the hour: where its day is the day of the planned
//! instant, the planned instant stands for it, so a task finished on its
//! planned day is on time, not late by the evening hours.
//!
//! Logs and plans often come from different tools, so a log's task is
//! matched to the schedule by id first, else by name: equal names after
//! trimming, any case, spaces collapsed, or the last part of a Project
//! task's path (`Shell / Walls` for `Walls`). Plans repeat names (a trade
//! storey by storey), so of several tasks with the name the one planned to
//! start nearest the log's actual start is taken. The log's dates replace
//! any actual dates the schedule has for the task; two log tasks on one
//! schedule task are combined, with a warning.

use std::collections::HashMap;
use std::path::Path;

use chrono::{DateTime, Utc};
use serde::Serialize;

use super::links_csv::{FINISH, NAME, START, TASK, Table, at, end_of, parse_csv_date};
use super::{Recorded, ScheduleTask, first_by_id};
use crate::error::{Error, Result};

/// One as-built log.
#[derive(Debug, Clone)]
pub struct Log {
    /// The file name, for reports.
    pub file: String,
    pub tasks: Vec<LogTask>,
}

/// A task as a log records it.
#[derive(Debug, Clone, PartialEq)]
pub struct LogTask {
    /// Empty when the file has no task id column.
    pub id: String,
    pub name: String,
    pub actual: Recorded,
    /// Its rows in the file.
    pub rows: usize,
    /// Every date of its rows was given as a day, with no time of day.
    pub by_day: bool,
}

/// What the as-built logs gave (schemas/import-report.schema.json,
/// `actual`).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Report {
    /// Rows read, blank rows left out.
    pub rows: usize,
    /// Tasks the logs record.
    pub tasks: usize,
    /// Of those, matched to a schedule task by id, and by name.
    pub by_id: usize,
    pub by_name: usize,
    /// Schedule tasks given an actual start by the logs.
    pub dated: usize,
    /// Rows of the log tasks that match no schedule task, and those tasks
    /// (`file: id "name"`).
    pub unmatched_rows: usize,
    pub unmatched: Vec<String>,
}

/// Reads an as-built log: columns `Task`/`TaskId` and/or `TaskName`,
/// `TaskStart`/`Start` and `TaskFinish`/`Finish` as in the links CSV; an
/// element column may be there and is not needed. Blank dates are allowed
/// (not started, or still running); bad ones are errors naming the line
/// and column.
pub fn read(path: &Path) -> Result<Log> {
    let mut table = Table::open(path)?;
    let (task, name) = (table.column(TASK), table.column(NAME));
    if task.is_none() && name.is_none() {
        return Err(Error::invalid(
            path,
            "header",
            format!(
                "no task column: none named {} nor {} (any case)",
                TASK.join(" or "),
                NAME.join(" or ")
            ),
        ));
    }
    let (start, finish) = (table.need(START)?, table.need(FINISH)?);
    let headers = table.headers.clone();

    // Per task: first start, last finish, whether every row finished.
    struct Acc {
        task: LogTask,
        first: Option<DateTime<Utc>>,
        last: Option<DateTime<Utc>>,
        finished: bool,
    }
    let day_only = |text: &str| text.is_empty() || !text.contains('T');
    let mut tasks: Vec<Acc> = Vec::new();
    let mut by_key: HashMap<String, usize> = HashMap::new();
    for row in table.rows() {
        let (line, row) = row?;
        let field = |c: Option<usize>| c.and_then(|c| row.get(c)).unwrap_or_default().trim();
        let (id, task_name) = (field(task), field(name));
        if id.is_empty() && task_name.is_empty() {
            return Err(Error::invalid(
                path,
                at(&headers, line, task.or(name).unwrap_or_default()),
                "no task id or name",
            ));
        }
        let date = |c: usize| -> Result<Option<DateTime<Utc>>> {
            let text = field(Some(c));
            if text.is_empty() {
                return Ok(None);
            }
            parse_csv_date(text)
                .map(Some)
                .map_err(|m| Error::invalid(path, at(&headers, line, c), m))
        };
        let record = Recorded::new(date(start)?, date(finish)?)
            .map_err(|m| Error::invalid(path, at(&headers, line, finish), m))?;
        let key = if id.is_empty() {
            format!("name:{}", normal(task_name))
        } else {
            format!("id:{id}")
        };
        let k = *by_key.entry(key).or_insert_with(|| {
            tasks.push(Acc {
                task: LogTask {
                    id: id.to_string(),
                    name: task_name.to_string(),
                    actual: Recorded::default(),
                    rows: 0,
                    by_day: true,
                },
                first: None,
                last: None,
                finished: true,
            });
            tasks.len() - 1
        });
        let acc = &mut tasks[k];
        acc.task.rows += 1;
        acc.task.by_day &= day_only(field(Some(start))) && day_only(field(Some(finish)));
        if let Some(s) = record.start {
            acc.first = Some(acc.first.map_or(s, |f| f.min(s)));
        }
        match record.finish {
            Some(f) => {
                let f = end_of(field(Some(finish)), f);
                acc.last = Some(acc.last.map_or(f, |l| l.max(f)));
            }
            None => acc.finished = false,
        }
    }
    let file = path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok(Log {
        file,
        tasks: tasks
            .into_iter()
            .map(|a| LogTask {
                actual: Recorded {
                    start: a.first,
                    finish: a.last.filter(|_| a.finished && a.first.is_some()),
                },
                ..a.task
            })
            .collect(),
    })
}

/// A name as matched: trimmed, lower case, runs of white space as one
/// space.
fn normal(name: &str) -> String {
    name.split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .to_lowercase()
}

/// Gives the schedule's tasks the logs' dates and says what matched.
pub fn apply(schedule: &mut [ScheduleTask], logs: &[Log], warnings: &mut Vec<String>) -> Report {
    let mut report = Report::default();
    let first = first_by_id(schedule);
    let names: Vec<String> = schedule.iter().map(|t| normal(&t.name)).collect();
    // Schedule task -> the log tasks recording it.
    let mut records: Vec<Vec<(&str, &LogTask)>> = vec![Vec::new(); schedule.len()];
    for log in logs {
        let mut unmatched = (0, 0);
        for t in &log.tasks {
            report.rows += t.rows;
            report.tasks += 1;
            let k = match first.get(t.id.as_str()).filter(|_| !t.id.is_empty()) {
                Some(&k) => {
                    report.by_id += 1;
                    Some(k)
                }
                None => {
                    let k = by_name(schedule, &names, t);
                    report.by_name += usize::from(k.is_some());
                    k
                }
            };
            match k {
                Some(k) => records[k].push((&log.file, t)),
                None => {
                    unmatched.0 += 1;
                    unmatched.1 += t.rows;
                    report.unmatched_rows += t.rows;
                    report
                        .unmatched
                        .push(format!("{}: {} {:?}", log.file, t.id, t.name));
                }
            }
        }
        if unmatched.0 > 0 {
            warnings.push(format!(
                "{}: {} task(s) ({} rows) match no task of the schedule by id or name",
                log.file, unmatched.0, unmatched.1
            ));
        }
    }
    for (task, recs) in schedule.iter_mut().zip(records) {
        if recs.is_empty() {
            continue;
        }
        if recs.len() > 1 {
            let which: Vec<String> = recs
                .iter()
                .map(|(file, t)| format!("{file}: {} {:?}", t.id, t.name))
                .collect();
            warnings.push(format!(
                "task {} {:?} is recorded by {}; their dates are combined",
                task.id,
                task.name,
                which.join(" and ")
            ));
        }
        let start = recs.iter().filter_map(|(_, t)| t.actual.start).min();
        let finish = if recs.iter().all(|(_, t)| t.actual.finish.is_some()) {
            recs.iter().filter_map(|(_, t)| t.actual.finish).max()
        } else {
            None
        };
        let (start, finish) = if recs.iter().all(|(_, t)| t.by_day) {
            on_planned_day(task, start, finish)
        } else {
            (start, finish)
        };
        task.actual = Recorded { start, finish };
        report.dated += usize::from(start.is_some());
    }
    report
}

/// Day-given actual dates with the planned instant where the day is the
/// planned one: a start on the planned start's day (from its midnight), a
/// finish at the end of the planned finish's day.
fn on_planned_day(
    task: &ScheduleTask,
    start: Option<DateTime<Utc>>,
    finish: Option<DateTime<Utc>>,
) -> (Option<DateTime<Utc>>, Option<DateTime<Utc>>) {
    let day = chrono::Duration::days(1);
    let start = start.map(|s| {
        if (s..s + day).contains(&task.start) {
            task.start
        } else {
            s
        }
    });
    let finish = finish.map(|f| {
        if task.finish > f - day && task.finish <= f {
            task.finish
        } else {
            f
        }
    });
    // A snapped start may pass an unsnapped finish on the same day.
    let finish = finish.map(|f| start.map_or(f, |s| f.max(s)));
    (start, finish)
}

/// The schedule task a log task names: its name, or the last part of a
/// Project path; of several, the one planned to start nearest the actual
/// start (the first of them without one).
fn by_name(schedule: &[ScheduleTask], names: &[String], t: &LogTask) -> Option<usize> {
    let name = normal(&t.name);
    if name.is_empty() {
        return None;
    }
    let suffix = format!(" / {name}");
    let mut candidates =
        (0..schedule.len()).filter(|&k| names[k] == name || names[k].ends_with(&suffix));
    match t.actual.start {
        Some(start) => candidates.min_by_key(|&k| (schedule[k].start - start).abs()),
        None => candidates.next(),
    }
}

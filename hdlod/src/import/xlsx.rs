//! Task lists in spreadsheets (`.xlsx`), read with the calamine crate: one
//! sheet, a header row, one task per row. The columns are found by their
//! header, by the mapping of the rules file's `spreadsheet` section or by
//! the usual names (any case): `id` (`Id`, `Task Id`, `Activity ID`),
//! `name` (`Name`, `Task Name`, `Activity Name`), `start`, `finish`
//! (`Start`, `Planned Start`, `Finish`, `Planned Finish`, `End`),
//! `actual_start`, `actual_finish`, `baseline_start`, `baseline_finish`,
//! `wbs`, `parent` (the id of its summary task), `predecessors` and `type`.
//! Every other column is a custom field of the task, named by its header,
//! for the linking rules.
//!
//! Dates are date cells, or text as the CSV readers take it (ISO 8601 or
//! day-month-year). Predecessors are a list separated by `,` or `;` of
//! task ids, each optionally followed by a link type and a lag, as Project
//! writes them: `A1000`, `A1000FS`, `A1010SS+2d`, `7FF-4h` (lags in
//! hours, days or weeks of calendar time).
//!
//! Reference: ECMA-376 (Office Open XML) for the cell types calamine maps
//! (date cells are serial days since 1899-12-30).

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use calamine::{Data, Reader, Xlsx};
use chrono::{DateTime, Utc};
use serde::Deserialize;

use super::links_csv::parse_csv_date;
use super::{Recorded, ScheduleTask, check_links};
use crate::error::{Error, Result};
use crate::scene::{LinkType, NamedType, Predecessor, TaskType};

/// The columns read as what they are; the others are custom fields.
pub const FIELDS: [&str; 12] = [
    "id",
    "name",
    "start",
    "finish",
    "actual_start",
    "actual_finish",
    "baseline_start",
    "baseline_finish",
    "wbs",
    "parent",
    "predecessors",
    "type",
];

/// The usual headers of each column, lower case.
fn usual(field: &str) -> &'static [&'static str] {
    match field {
        "id" => &["id", "task id", "activity id", "task", "uid"],
        "name" => &["name", "task name", "activity name"],
        "start" => &["start", "planned start", "start date"],
        "finish" => &["finish", "planned finish", "end", "finish date", "end date"],
        "actual_start" => &["actual start"],
        "actual_finish" => &["actual finish"],
        "baseline_start" => &["baseline start"],
        "baseline_finish" => &["baseline finish"],
        "wbs" => &["wbs", "wbs code"],
        "parent" => &["parent", "parent id", "summary"],
        "predecessors" => &["predecessors", "predecessor"],
        "type" => &["type", "task type"],
        _ => &[],
    }
}

/// The rules file's `spreadsheet` section: the sheet, and the header of
/// each column that the usual names do not find.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mapping {
    /// The sheet's name (default: the first sheet).
    #[serde(default)]
    pub sheet: Option<String>,
    /// Our column (`id`, `start`, ...) -> its header in the sheet.
    #[serde(default)]
    pub columns: BTreeMap<String, String>,
}

/// Dates outside these years are taken for mistakes.
const YEARS: std::ops::RangeInclusive<i32> = 1900..=2200;

/// `A`, `B`, ..., `Z`, `AA`: a column's letters.
fn letters(mut column: usize) -> String {
    let mut out = Vec::new();
    loop {
        out.push(b'A' + (column % 26) as u8);
        if column < 26 {
            break;
        }
        column = column / 26 - 1;
    }
    out.reverse();
    String::from_utf8(out).expect("ASCII")
}

/// A cell's text as a field: numbers without a needless `.0`.
fn text(cell: &Data) -> String {
    match cell {
        Data::Empty => String::new(),
        Data::String(s) => s.trim().to_string(),
        Data::Float(f) if f.fract() == 0.0 && f.abs() < 1e15 => format!("{}", *f as i64),
        other => other.to_string().trim().to_string(),
    }
}

/// Reads the tasks of a spreadsheet.
pub fn read(path: &Path, mapping: &Mapping) -> Result<Vec<ScheduleTask>> {
    let file = std::io::BufReader::new(crate::input::open(path)?);
    let mut book = Xlsx::new(file)
        .map_err(|e| Error::file(path, format!("not a readable .xlsx workbook: {e}")))?;
    let names = book.sheet_names();
    let sheet = match &mapping.sheet {
        Some(s) if names.contains(s) => s.clone(),
        Some(s) => {
            return Err(Error::invalid(
                path,
                format!("sheet {s:?}"),
                format!("no such sheet; the workbook has {}", names.join(", ")),
            ));
        }
        None => names
            .first()
            .cloned()
            .ok_or_else(|| Error::file(path, "the workbook has no sheet"))?,
    };
    let range = book
        .worksheet_range(&sheet)
        .map_err(|e| Error::invalid(path, format!("sheet {sheet:?}"), e.to_string()))?;
    let (row0, col0) = range
        .start()
        .map_or((0, 0), |(r, c)| (r as usize, c as usize));
    let mut rows = range
        .rows()
        .enumerate()
        .map(|(i, r)| (row0 + i + 1, r))
        .filter(|(_, r)| r.iter().any(|c| !matches!(c, Data::Empty)));
    let Some((header_row, header)) = rows.next() else {
        return Err(Error::invalid(
            path,
            format!("sheet {sheet:?}"),
            "the sheet is empty",
        ));
    };
    let headers: Vec<String> = header.iter().map(text).collect();
    let cell_at = |row: usize, c: usize| format!("{sheet}!{}{row}", letters(col0 + c));
    let column_at = |row: usize, c: usize| format!("{} (column {:?})", cell_at(row, c), headers[c]);

    // Our columns by header: the mapping's, else the usual names.
    let mut ours: HashMap<&str, usize> = HashMap::new();
    for field in FIELDS {
        let found = match mapping.columns.get(field) {
            Some(h) => Some(
                headers
                    .iter()
                    .position(|x| x.eq_ignore_ascii_case(h))
                    .ok_or_else(|| {
                        Error::invalid(
                            path,
                            format!("sheet {sheet:?}, row {header_row}"),
                            format!("no column {h:?} (the {field} column of the mapping)"),
                        )
                    })?,
            ),
            None => headers
                .iter()
                .position(|x| usual(field).contains(&x.to_lowercase().as_str())),
        };
        if let Some(c) = found {
            ours.insert(field, c);
        }
    }
    for field in ["id", "start", "finish"] {
        if !ours.contains_key(field) {
            return Err(Error::invalid(
                path,
                format!("sheet {sheet:?}, row {header_row}"),
                format!(
                    "no {field} column (headers {}); name it in the rules file's \
                     spreadsheet.columns",
                    headers.join(", ")
                ),
            ));
        }
    }
    let custom: Vec<usize> = (0..headers.len())
        .filter(|c| !ours.values().any(|o| o == c) && !headers[*c].is_empty())
        .collect();

    let mut tasks: Vec<ScheduleTask> = Vec::new();
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut parents: Vec<(usize, usize)> = Vec::new();
    for (n, row) in rows {
        let cell = |field: &str| ours.get(field).and_then(|&c| row.get(c).map(|v| (c, v)));
        let value = |field: &str| cell(field).map(|(_, v)| text(v)).unwrap_or_default();
        let id = value("id");
        if id.is_empty() {
            continue;
        }
        let at = |field: &str| column_at(n, ours[field]);
        if let Some(first) = seen.insert(id.clone(), n) {
            return Err(Error::invalid(
                path,
                at("id"),
                format!("task {id:?} is also that of row {first}"),
            ));
        }
        let date = |field: &str| -> Result<Option<DateTime<Utc>>> {
            let Some((c, v)) = cell(field) else {
                return Ok(None);
            };
            date_of(v).map_err(|m| Error::invalid(path, column_at(n, c), m))
        };
        let (Some(start), Some(finish)) = (date("start")?, date("finish")?) else {
            return Err(Error::invalid(
                path,
                at("start"),
                format!("task {id:?} has no start and finish"),
            ));
        };
        if finish < start {
            return Err(Error::invalid(
                path,
                at("finish"),
                format!("task {id:?} finishes before it starts"),
            ));
        }
        let actual = Recorded::new(date("actual_start")?, date("actual_finish")?)
            .map_err(|m| Error::invalid(path, at("actual_finish"), format!("task {id:?}: {m}")))?;
        let baseline = match (date("baseline_start")?, date("baseline_finish")?) {
            (Some(s), Some(f)) if f >= s => Some((s, f)),
            (None, None) => None,
            _ => {
                return Err(Error::invalid(
                    path,
                    at("baseline_finish"),
                    format!("task {id:?}: a baseline needs a start and a finish not before it"),
                ));
            }
        };
        let kind = match value("type").as_str() {
            "" => None,
            t => Some(NamedType::parse(t).ok_or_else(|| {
                Error::invalid(
                    path,
                    at("type"),
                    format!("{t:?} is not a task type; use {}", TaskType::NAMES),
                )
            })?),
        };
        let predecessors = parse_predecessors(&value("predecessors"))
            .map_err(|m| Error::invalid(path, at("predecessors"), m))?;
        if ours.contains_key("parent") && !value("parent").is_empty() {
            parents.push((tasks.len(), n));
        }
        let fields = custom
            .iter()
            .filter_map(|&c| {
                let v = text(row.get(c)?);
                (!v.is_empty()).then(|| (headers[c].clone(), v))
            })
            .collect();
        tasks.push(ScheduleTask {
            kind,
            actual,
            baseline,
            parent: Some(value("parent")).filter(|p| !p.is_empty()),
            predecessors,
            wbs: Some(value("wbs")).filter(|w| !w.is_empty()),
            fields,
            ..ScheduleTask::planned(id, value("name"), start, finish)
        });
    }
    // Parents and predecessors name tasks of the sheet.
    for (k, n) in parents {
        let p = tasks[k].parent.as_deref().unwrap_or_default();
        if !seen.contains_key(p) || p == tasks[k].id {
            return Err(Error::invalid(
                path,
                column_at(n, ours["parent"]),
                format!("{p:?} is not the id of another task"),
            ));
        }
    }
    for t in &tasks {
        if let Some(p) = t.predecessors.iter().find(|p| !seen.contains_key(&p.task)) {
            let n = seen[&t.id];
            return Err(Error::invalid(
                path,
                column_at(n, ours["predecessors"]),
                format!("{:?} is not the id of a task", p.task),
            ));
        }
    }
    let links = ours.get("predecessors").map_or_else(
        || format!("sheet {sheet:?}"),
        |&c| format!("sheet {sheet:?}, column {:?}", headers[c]),
    );
    check_links(path, &links, &tasks)?;
    Ok(tasks)
}

/// A date cell, or a date written as text; `None` for an empty cell.
fn date_of(cell: &Data) -> std::result::Result<Option<DateTime<Utc>>, String> {
    let date = match cell {
        Data::Empty => return Ok(None),
        Data::String(s) if s.trim().is_empty() => return Ok(None),
        Data::String(s) | Data::DateTimeIso(s) => parse_csv_date(s.trim())?,
        Data::DateTime(d) => d
            .as_datetime()
            .ok_or_else(|| format!("date cell {} is out of range", d.as_f64()))?
            .and_utc(),
        other => return Err(format!("{other:?} is not a date")),
    };
    let year: i32 = date.format("%Y").to_string().parse().unwrap_or(0);
    if !YEARS.contains(&year) {
        return Err(format!(
            "{} is out of range (years {} to {})",
            crate::time::format_date(date),
            YEARS.start(),
            YEARS.end()
        ));
    }
    Ok(Some(date))
}

/// A predecessor as Project writes it, compiled once.
static PREDECESSOR: std::sync::LazyLock<regex::Regex> = std::sync::LazyLock::new(|| {
    regex::Regex::new(r"^(?P<id>.+?)(?P<type>FS|SS|FF|SF)?(?:\s*(?P<lag>[+-]\s*\d+(?:\.\d+)?)\s*(?P<unit>h|d|w|hours?|days?|weeks?)?)?$").expect("a valid pattern")
});

/// `A1000, A1010SS+2d; 7FF-4h`: ids with an optional link type and lag.
fn parse_predecessors(text: &str) -> std::result::Result<Vec<Predecessor>, String> {
    text.split([',', ';'])
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|item| {
            let m = PREDECESSOR
                .captures(item)
                .ok_or_else(|| format!("{item:?} is not a predecessor (ID, ID FS+2d)"))?;
            let kind = m
                .name("type")
                .and_then(|t| LinkType::parse(t.as_str()))
                .unwrap_or_default();
            let hours = match m.name("lag") {
                None => 0.0,
                Some(l) => {
                    let n: f64 = l
                        .as_str()
                        .replace(' ', "")
                        .parse()
                        .map_err(|_| format!("{item:?}: a bad lag"))?;
                    let unit = m.name("unit").map_or("d", |u| u.as_str());
                    n * match unit.chars().next() {
                        Some('h') => 1.0,
                        Some('w') => 7.0 * 24.0,
                        _ => 24.0,
                    }
                }
            };
            Ok(Predecessor {
                task: m["id"].trim().to_string(),
                kind,
                lag: hours * 3600.0,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn predecessors_as_project_writes_them() {
        let got = parse_predecessors("A1000, A1010SS+2d; 7FF-4h;A12 FS + 1w").unwrap();
        let got: Vec<(&str, LinkType, f64)> = got
            .iter()
            .map(|p| (p.task.as_str(), p.kind, p.lag / 3600.0))
            .collect();
        assert_eq!(
            got,
            [
                ("A1000", LinkType::FinishStart, 0.0),
                ("A1010", LinkType::StartStart, 48.0),
                ("7", LinkType::FinishFinish, -4.0),
                ("A12", LinkType::FinishStart, 168.0)
            ]
        );
        assert_eq!(letters(0), "A");
        assert_eq!(letters(27), "AB");
    }
}

//! Primavera P6 XER schedules: the tab-separated export of P6's database
//! tables. A file opens with an `ERMHDR` line; then each table is a `%T`
//! line with its name, a `%F` line with its field names and `%R` lines
//! with its rows; `%E` ends the file.
//!
//! Read here, for one project (`--project`, by short name or `proj_id`,
//! when the file holds several): activities (`TASK`) with their planned
//! dates (`target_start_date`/`target_end_date`, P6's "Planned Start" and
//! "Planned Finish"), actual dates (`act_start_date`/`act_end_date`) and
//! early and late dates; the work breakdown (`PROJWBS`); the logic links
//! (`TASKPRED`: type `PR_FS`..., lag in hours); activity codes (`ACTVTYPE`,
//! `ACTVCODE`, `TASKACTV`) and user fields (`UDFTYPE`, `UDFVALUE`) of the
//! activities.
//!
//! A task's id is its Activity ID (`task_code`), its name the names of its
//! WBS nodes and its own, joined by " / " as Project's outline paths are.
//! Every WBS node below the project's root node is a summary task, id = its
//! WBS code path as P6 shows it (`TWR.L01.FRM`: the short names from the
//! project's node down), spanning the activities below it: the planner's
//! Gantt chart groups activities under their WBS bands the same way. An
//! activity's `parent` is its WBS node (none for one at the project's
//! root) and its `wbs` the node's code path, for the linking rules.
//!
//! Files come from P6 in Windows-1252 (or the database's code page) as
//! often as in UTF-8: a file that is not valid UTF-8 is read as
//! Windows-1252, and a file that is neither (a NUL byte, a byte
//! Windows-1252 leaves undefined) is an error naming the table, row and
//! field. A byte-order mark selects UTF-8 or UTF-16. Rows shorter than
//! their `%F` line have their trailing fields empty (P6 and other
//! exporters leave trailing empty fields out); longer rows are an error.
//!
//! References: Oracle, "Primavera P6 Enterprise Project Portfolio
//! Management Data Dictionary" (the tables and fields); the XER layout as
//! MPXJ documents it ("How To: Read XER files", mpxj.org).

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use chrono::{DateTime, NaiveDate, NaiveDateTime, Utc};

use super::wbs::{RawNode, Wbs};
use super::{Recorded, ScheduleTask, check_links};
use crate::error::{Error, Result};
use crate::scene::{LinkType, Predecessor};

/// The tables read; the others are skipped undecoded.
const TABLES: [&str; 9] = [
    "PROJECT", "PROJWBS", "TASK", "TASKPRED", "ACTVTYPE", "ACTVCODE", "TASKACTV", "UDFTYPE",
    "UDFVALUE",
];

/// Dates outside these years are taken for mistakes (P6 itself keeps
/// dates within them).
pub(super) const YEARS: std::ops::RangeInclusive<i32> = 1900..=2200;

/// One table: its field names and rows (fields borrowed from the text).
struct Table<'a> {
    name: &'a str,
    fields: Vec<&'a str>,
    /// (line number, fields).
    rows: Vec<(usize, Vec<&'a str>)>,
}

impl<'a> Table<'a> {
    /// The column of `field`: an error naming the table when its `%F` line
    /// lacks it.
    fn column(&self, path: &Path, field: &str) -> Result<Column> {
        self.fields
            .iter()
            .position(|f| *f == field)
            .map(|i| Column {
                index: i,
                name: field.to_string(),
            })
            .ok_or_else(|| {
                Error::invalid(
                    path,
                    format!("%T {}", self.name),
                    format!("its %F line has no field {field}"),
                )
            })
    }

    /// The column of `field` if the table has it.
    fn optional(&self, field: &str) -> Option<Column> {
        self.fields
            .iter()
            .position(|f| *f == field)
            .map(|i| Column {
                index: i,
                name: field.to_string(),
            })
    }
}

struct Column {
    index: usize,
    name: String,
}

/// One row with where it is, for errors.
struct Row<'t, 'a> {
    table: &'a str,
    /// 1-based among the table's rows.
    number: usize,
    line: usize,
    fields: &'t [&'a str],
}

impl<'a> Row<'_, 'a> {
    fn get(&self, c: &Column) -> &'a str {
        self.fields.get(c.index).copied().unwrap_or("")
    }

    fn opt(&self, c: &Option<Column>) -> &'a str {
        c.as_ref().map_or("", |c| self.get(c))
    }

    /// Where a field is: `TASK row 12 (line 40), field task_code`.
    fn at(&self, c: &Column) -> String {
        format!(
            "{} row {} (line {}), field {}",
            self.table, self.number, self.line, c.name
        )
    }

    fn date(&self, path: &Path, c: &Option<Column>) -> Result<Option<DateTime<Utc>>> {
        let Some(c) = c else { return Ok(None) };
        let text = self.get(c).trim();
        if text.is_empty() {
            return Ok(None);
        }
        parse_xer_date(text)
            .map(Some)
            .map_err(|m| Error::invalid(path, self.at(c), m))
    }

    fn dates(
        &self,
        path: &Path,
        start: &Option<Column>,
        finish: &Option<Column>,
    ) -> Result<Option<(DateTime<Utc>, DateTime<Utc>)>> {
        match (self.date(path, start)?, self.date(path, finish)?) {
            (Some(s), Some(f)) if f < s => Err(Error::invalid(
                path,
                self.at(finish.as_ref().expect("a finish was read")),
                format!("{f} is before the start {s}"),
            )),
            (Some(s), Some(f)) => Ok(Some((s, f))),
            _ => Ok(None),
        }
    }
}

/// An XER date: `2024-01-08 08:00` (seconds optional), or a day.
fn parse_xer_date(text: &str) -> std::result::Result<DateTime<Utc>, String> {
    let naive = NaiveDateTime::parse_from_str(text, "%Y-%m-%d %H:%M")
        .or_else(|_| NaiveDateTime::parse_from_str(text, "%Y-%m-%d %H:%M:%S"))
        .or_else(|_| {
            NaiveDate::parse_from_str(text, "%Y-%m-%d")
                .map(|d| d.and_hms_opt(0, 0, 0).expect("midnight exists"))
        })
        .map_err(|_| format!("{text:?} is not a date (yyyy-mm-dd hh:mm)"))?;
    let year = naive.format("%Y").to_string().parse::<i32>().unwrap_or(0);
    if !YEARS.contains(&year) {
        return Err(format!(
            "{text:?} is out of range (years {} to {})",
            YEARS.start(),
            YEARS.end()
        ));
    }
    Ok(naive.and_utc())
}

/// The file's text: UTF-8 or UTF-16 by a byte-order mark, else UTF-8 if it
/// is valid, else Windows-1252. The flag says whether Windows-1252 was
/// used (whose undefined bytes the parser then looks for).
fn decode(path: &Path, bytes: &[u8]) -> Result<(String, bool)> {
    if let Some((encoding, bom)) = encoding_rs::Encoding::for_bom(bytes) {
        return encoding
            .decode_without_bom_handling_and_without_replacement(&bytes[bom..])
            .map(|t| (t.into_owned(), false))
            .ok_or_else(|| {
                Error::file(
                    path,
                    format!(
                        "the byte-order mark says {}, but the file is not valid {}",
                        encoding.name(),
                        encoding.name()
                    ),
                )
            });
    }
    if let Ok(text) = std::str::from_utf8(bytes) {
        return Ok((text.to_string(), false));
    }
    let (text, _) = encoding_rs::WINDOWS_1252.decode_without_bom_handling(bytes);
    Ok((text.into_owned(), true))
}

/// A character no XER text holds: NUL, or a byte Windows-1252 leaves
/// undefined (decoded to its C1 control).
fn undecodable(c: char, cp1252: bool) -> bool {
    c == '\0' || (cp1252 && matches!(c, '\u{81}' | '\u{8d}' | '\u{8f}' | '\u{90}' | '\u{9d}'))
}

/// Splits the text into the tables read, checking the layout of every
/// table.
fn tables<'a>(path: &Path, text: &'a str, cp1252: bool) -> Result<HashMap<&'a str, Table<'a>>> {
    let suspect = text.chars().any(|c| undecodable(c, cp1252));
    let mut lines = text
        .split('\n')
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')));
    let header = lines.next().map(|(_, l)| l).unwrap_or_default();
    if !header.starts_with("ERMHDR") {
        return Err(Error::invalid(
            path,
            "line 1",
            "not a Primavera P6 XER file (it does not begin with ERMHDR)",
        ));
    }
    let mut out: HashMap<&str, Table> = HashMap::new();
    // The open table: its name, whether it is read, its field count.
    let mut open: Option<(&str, bool, Option<usize>)> = None;
    let mut rows = 0usize;
    for (n, line) in lines {
        if line.is_empty() {
            continue;
        }
        let at = |what: &str| format!("line {n}{what}");
        let (tag, rest) = line.split_once('\t').unwrap_or((line, ""));
        match tag {
            "%T" => {
                let name = rest.trim();
                if name.is_empty() {
                    return Err(Error::invalid(
                        path,
                        at(""),
                        "a %T line without a table name",
                    ));
                }
                let read = TABLES.contains(&name);
                if read && out.contains_key(name) {
                    return Err(Error::invalid(
                        path,
                        at(&format!(" (%T {name})")),
                        "the table appears twice",
                    ));
                }
                open = Some((name, read, None));
                rows = 0;
            }
            "%F" => {
                let Some((name, read, fields)) = open.as_mut() else {
                    return Err(Error::invalid(
                        path,
                        at(""),
                        "a %F line before any %T table line",
                    ));
                };
                if fields.is_some() {
                    return Err(Error::invalid(
                        path,
                        at(&format!(" (%T {name})")),
                        "a second %F line in the table",
                    ));
                }
                let names: Vec<&str> = rest.split('\t').collect();
                *fields = Some(names.len());
                if *read {
                    out.insert(
                        name,
                        Table {
                            name,
                            fields: names,
                            rows: Vec::new(),
                        },
                    );
                }
            }
            "%R" => {
                let Some((name, read, fields)) = open else {
                    return Err(Error::invalid(
                        path,
                        at(""),
                        "a %R row before any %T table line",
                    ));
                };
                rows += 1;
                let Some(count) = fields else {
                    return Err(Error::invalid(
                        path,
                        format!("{name} row {rows} (line {n})"),
                        "a %R row before the table's %F line",
                    ));
                };
                let values: Vec<&str> = rest.split('\t').collect();
                if values.len() > count {
                    return Err(Error::invalid(
                        path,
                        format!("{name} row {rows} (line {n})"),
                        format!(
                            "a ragged row: {} fields, but the %F line names {count}",
                            values.len()
                        ),
                    ));
                }
                if suspect
                    && let Some(k) = values
                        .iter()
                        .position(|v| v.chars().any(|c| undecodable(c, cp1252)))
                {
                    let field = out
                        .get(name)
                        .and_then(|t| t.fields.get(k).copied())
                        .unwrap_or("?");
                    return Err(Error::invalid(
                        path,
                        format!("{name} row {rows} (line {n}), field {field}"),
                        "undecodable text: neither UTF-8 nor Windows-1252 (a NUL byte or a byte \
                         Windows-1252 leaves undefined)",
                    ));
                }
                if read && let Some(t) = out.get_mut(name) {
                    t.rows.push((n, values));
                }
            }
            "%E" => break,
            _ => {
                return Err(Error::invalid(
                    path,
                    at(""),
                    format!(
                        "expected a %T, %F, %R or %E line, found {:?}",
                        line.chars().take(20).collect::<String>()
                    ),
                ));
            }
        }
    }
    Ok(out)
}

/// The rows of a table with where they are.
fn rows<'t, 'a>(t: &'t Table<'a>) -> impl Iterator<Item = Row<'t, 'a>> {
    t.rows.iter().enumerate().map(|(i, (line, fields))| Row {
        table: t.name,
        number: i + 1,
        line: *line,
        fields,
    })
}

/// Reads the activities of one project of an XER file, with its WBS nodes
/// as summary tasks. `project` chooses by short name or `proj_id`; without
/// it, a file of several projects is an error listing them.
pub fn read(path: &Path, project: Option<&str>) -> Result<Vec<ScheduleTask>> {
    let bytes = crate::input::read(path)?;
    let (text, cp1252) = decode(path, &bytes)?;
    let tables = tables(path, &text, cp1252)?;
    let table = |name: &str| {
        tables
            .get(name)
            .ok_or_else(|| Error::invalid(path, format!("%T {name}"), "the file has no such table"))
    };

    let projects = table("PROJECT")?;
    let proj_id = projects.column(path, "proj_id")?;
    let short = projects.column(path, "proj_short_name")?;
    let task_table = table("TASK")?;
    let task_proj = task_table.column(path, "proj_id")?;
    let chosen = choose_project(
        path, projects, &proj_id, &short, task_table, &task_proj, project,
    )?;

    let wbs = match tables.get("PROJWBS") {
        Some(t) => read_wbs(path, t, &chosen)?,
        None => Wbs::default(),
    };

    let c = |f: &str| task_table.column(path, f);
    let o = |f: &str| task_table.optional(f);
    let (task_id, code, name, wbs_id) =
        (c("task_id")?, c("task_code")?, c("task_name")?, o("wbs_id"));
    let (target_start, target_end) = (o("target_start_date"), o("target_end_date"));
    let (early_start, early_end) = (o("early_start_date"), o("early_end_date"));
    let (late_start, late_end) = (o("late_start_date"), o("late_end_date"));
    let (act_start, act_end) = (o("act_start_date"), o("act_end_date"));

    let mut tasks = Vec::new();
    // task_id -> index in tasks, for this project; task_ids of others.
    let mut by_task_id: HashMap<&str, usize> = HashMap::new();
    let mut elsewhere: std::collections::HashSet<&str> = std::collections::HashSet::new();
    let mut codes_seen: HashMap<&str, usize> = HashMap::new();
    for row in rows(task_table) {
        let id = row.get(&task_id).trim();
        if row.get(&task_proj).trim() != chosen {
            elsewhere.insert(id);
            continue;
        }
        let activity = row.get(&code).trim();
        if activity.is_empty() {
            return Err(Error::invalid(
                path,
                row.at(&code),
                "an activity without an Activity ID",
            ));
        }
        if let Some(first) = codes_seen.insert(activity, row.number) {
            return Err(Error::invalid(
                path,
                row.at(&code),
                format!("Activity ID {activity:?} is also that of TASK row {first}"),
            ));
        }
        let early = row.dates(path, &early_start, &early_end)?;
        let planned = match row.dates(path, &target_start, &target_end)? {
            Some(p) => p,
            None => early.ok_or_else(|| {
                let field = target_start.as_ref().unwrap_or(&code);
                Error::invalid(
                    path,
                    row.at(field),
                    format!("activity {activity}: no planned (target) dates and no early dates"),
                )
            })?,
        };
        let actual = Recorded::new(row.date(path, &act_start)?, row.date(path, &act_end)?)
            .map_err(|m| {
                let field = act_end.as_ref().expect("an actual finish was read");
                Error::invalid(path, row.at(field), format!("activity {activity}: {m}"))
            })?;
        let node = wbs.node(row.opt(&wbs_id).trim());
        let full_name = match node {
            Some(n) if !n.names.is_empty() => format!("{} / {}", n.names, row.get(&name).trim()),
            _ => row.get(&name).trim().to_string(),
        };
        by_task_id.insert(id, tasks.len());
        tasks.push(ScheduleTask {
            actual,
            early,
            late: row.dates(path, &late_start, &late_end)?,
            parent: node.and_then(|n| n.summary.then(|| n.code.clone())),
            wbs: node.map(|n| n.code.clone()),
            ..ScheduleTask::planned(activity, full_name, planned.0, planned.1)
        });
    }

    links(path, &tables, &mut tasks, &by_task_id, &elsewhere)?;
    codes(path, &tables, &mut tasks, &by_task_id)?;
    user_fields(path, &tables, &mut tasks, &by_task_id)?;
    check_links(path, "TASKPRED", &tasks)?;
    let summaries = wbs.summaries(&tasks);
    tasks.extend(summaries);
    Ok(tasks)
}

/// The `proj_id` of the project to read.
fn choose_project(
    path: &Path,
    projects: &Table,
    proj_id: &Column,
    short: &Column,
    tasks: &Table,
    task_proj: &Column,
    wanted: Option<&str>,
) -> Result<String> {
    let all: Vec<(&str, &str)> = rows(projects)
        .map(|r| (r.get(proj_id).trim(), r.get(short).trim()))
        .collect();
    let list = || {
        all.iter()
            .map(|(id, name)| {
                let n = rows(tasks)
                    .filter(|r| r.get(task_proj).trim() == *id)
                    .count();
                format!("{name} (proj_id {id}, {n} activities)")
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match (wanted, &all[..]) {
        (_, []) => Err(Error::invalid(
            path,
            "%T PROJECT",
            "the file holds no project",
        )),
        (None, [(id, _)]) => Ok(id.to_string()),
        (None, _) => Err(Error::invalid(
            path,
            "%T PROJECT",
            format!(
                "the file holds {} projects; choose one with --project: {}",
                all.len(),
                list()
            ),
        )),
        (Some(w), _) => all
            .iter()
            .find(|(id, name)| *name == w || *id == w)
            .map(|(id, _)| id.to_string())
            .ok_or_else(|| {
                Error::invalid(
                    path,
                    "%T PROJECT",
                    format!("no project {w:?} in the file; it holds {}", list()),
                )
            }),
    }
}

/// `PROJWBS`: the project's WBS nodes.
fn read_wbs(path: &Path, t: &Table, project: &str) -> Result<Wbs> {
    let (id, proj, parent, short, name) = (
        t.column(path, "wbs_id")?,
        t.column(path, "proj_id")?,
        t.column(path, "parent_wbs_id")?,
        t.column(path, "wbs_short_name")?,
        t.column(path, "wbs_name")?,
    );
    let root_flag = t.optional("proj_node_flag");
    let nodes: Vec<RawNode> = rows(t)
        .filter(|r| r.get(&proj).trim() == project)
        .map(|row| RawNode {
            id: row.get(&id).trim(),
            parent: row.get(&parent).trim(),
            short: row.get(&short).trim(),
            name: row.get(&name).trim(),
            root: row.opt(&root_flag).trim() == "Y",
        })
        .collect();
    Wbs::new(&nodes).map_err(|key| {
        Error::invalid(
            path,
            format!("PROJWBS wbs_id {key}, field parent_wbs_id"),
            "the WBS parents form a cycle",
        )
    })
}

/// `TASKPRED`: the links among the project's activities. A link from an
/// activity of another project (external) is left out.
fn links(
    path: &Path,
    tables: &HashMap<&str, Table>,
    tasks: &mut [ScheduleTask],
    by_task_id: &HashMap<&str, usize>,
    elsewhere: &std::collections::HashSet<&str>,
) -> Result<()> {
    let Some(t) = tables.get("TASKPRED") else {
        return Ok(());
    };
    let (task, pred, kind) = (
        t.column(path, "task_id")?,
        t.column(path, "pred_task_id")?,
        t.column(path, "pred_type")?,
    );
    let lag = t.optional("lag_hr_cnt");
    for row in rows(t) {
        let id = row.get(&task).trim();
        let Some(&k) = by_task_id.get(id) else {
            if elsewhere.contains(id) {
                continue;
            }
            return Err(Error::invalid(
                path,
                row.at(&task),
                format!("no TASK has task_id {id:?}"),
            ));
        };
        let p = row.get(&pred).trim();
        let Some(&j) = by_task_id.get(p) else {
            if elsewhere.contains(p) {
                continue;
            }
            return Err(Error::invalid(
                path,
                row.at(&pred),
                format!("no TASK has task_id {p:?}"),
            ));
        };
        let link = LinkType::parse(row.get(&kind).trim()).ok_or_else(|| {
            Error::invalid(
                path,
                row.at(&kind),
                format!(
                    "{:?} is not a link type (PR_FS, PR_SS, PR_FF, PR_SF)",
                    row.get(&kind)
                ),
            )
        })?;
        let hours = match row.opt(&lag).trim() {
            "" => 0.0,
            h => h
                .parse::<f64>()
                .ok()
                .filter(|h| h.is_finite() && h.abs() < 1e6)
                .ok_or_else(|| {
                    Error::invalid(
                        path,
                        row.at(lag.as_ref().expect("a lag was read")),
                        format!("{h:?} is not a lag in hours"),
                    )
                })?,
        };
        let predecessor = tasks[j].id.clone();
        tasks[k].predecessors.push(Predecessor {
            task: predecessor,
            kind: link,
            lag: hours * 3600.0,
        });
    }
    Ok(())
}

/// `ACTVTYPE`, `ACTVCODE`, `TASKACTV`: each activity's code values by code
/// type name (the value is the code's short name).
fn codes(
    path: &Path,
    tables: &HashMap<&str, Table>,
    tasks: &mut [ScheduleTask],
    by_task_id: &HashMap<&str, usize>,
) -> Result<()> {
    let (Some(types), Some(values), Some(assigned)) = (
        tables.get("ACTVTYPE"),
        tables.get("ACTVCODE"),
        tables.get("TASKACTV"),
    ) else {
        return Ok(());
    };
    let (type_id, type_name) = (
        types.column(path, "actv_code_type_id")?,
        types.column(path, "actv_code_type")?,
    );
    let type_names: HashMap<&str, &str> = rows(types)
        .map(|r| (r.get(&type_id).trim(), r.get(&type_name).trim()))
        .collect();
    let (code_id, code_type, short) = (
        values.column(path, "actv_code_id")?,
        values.column(path, "actv_code_type_id")?,
        values.column(path, "short_name")?,
    );
    let code_values: HashMap<&str, (&str, &str)> = rows(values)
        .map(|r| {
            (
                r.get(&code_id).trim(),
                (r.get(&code_type).trim(), r.get(&short).trim()),
            )
        })
        .collect();
    let (task, code) = (
        assigned.column(path, "task_id")?,
        assigned.column(path, "actv_code_id")?,
    );
    for row in rows(assigned) {
        let Some(&k) = by_task_id.get(row.get(&task).trim()) else {
            continue;
        };
        let id = row.get(&code).trim();
        let Some(&(ty, value)) = code_values.get(id) else {
            return Err(Error::invalid(
                path,
                row.at(&code),
                format!("no ACTVCODE has actv_code_id {id:?}"),
            ));
        };
        let Some(&name) = type_names.get(ty) else {
            return Err(Error::invalid(
                path,
                row.at(&code),
                format!("its code's type {ty:?} is in no ACTVTYPE row"),
            ));
        };
        tasks[k].codes.insert(name.to_string(), value.to_string());
    }
    Ok(())
}

/// `UDFTYPE`, `UDFVALUE`: the activities' user fields by label (text,
/// number, date or code, whichever the value holds).
fn user_fields(
    path: &Path,
    tables: &HashMap<&str, Table>,
    tasks: &mut [ScheduleTask],
    by_task_id: &HashMap<&str, usize>,
) -> Result<()> {
    let (Some(types), Some(values)) = (tables.get("UDFTYPE"), tables.get("UDFVALUE")) else {
        return Ok(());
    };
    let (type_id, table, label) = (
        types.column(path, "udf_type_id")?,
        types.column(path, "table_name")?,
        types.column(path, "udf_type_label")?,
    );
    let labels: HashMap<&str, &str> = rows(types)
        .filter(|r| r.get(&table).trim() == "TASK")
        .map(|r| (r.get(&type_id).trim(), r.get(&label).trim()))
        .collect();
    let (value_type, fk) = (
        values.column(path, "udf_type_id")?,
        values.column(path, "fk_id")?,
    );
    let kinds = [
        values.optional("udf_text"),
        values.optional("udf_number"),
        values.optional("udf_date"),
        values.optional("udf_code_id"),
    ];
    let date = values.optional("udf_date");
    let mut fields: BTreeMap<(usize, &str), String> = BTreeMap::new();
    for row in rows(values) {
        let Some(&name) = labels.get(row.get(&value_type).trim()) else {
            continue;
        };
        let Some(&k) = by_task_id.get(row.get(&fk).trim()) else {
            continue;
        };
        // A date is checked, and written as the other readers' dates are.
        let value = match row.date(path, &date)? {
            Some(d)
                if row.opt(&kinds[0]).trim().is_empty() && row.opt(&kinds[1]).trim().is_empty() =>
            {
                crate::time::format_date(d)
            }
            _ => kinds
                .iter()
                .map(|c| row.opt(c).trim())
                .find(|v| !v.is_empty())
                .unwrap_or_default()
                .to_string(),
        };
        fields.insert((k, name), value);
    }
    for ((k, name), value) in fields {
        tasks[k].fields.insert(name.to_string(), value);
    }
    Ok(())
}

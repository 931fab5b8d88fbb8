//! Import of BIM models and their 4D schedules into an `hdlod-scene/1`
//! scene (docs/import.md): IFC geometry ([`ifc`]), schedules from IFC work
//! schedules ([`ifc_tasks`]), Primavera P6 XER ([`xer`]) and XML
//! ([`pmxml`]), Microsoft Project XML ([`msproject`]), spreadsheets
//! ([`xlsx`]) or a CSV of element-task links ([`links_csv`]), with their
//! work breakdown and logic links; linking rules ([`rules`]) for schedules
//! that name no elements, and as-built logs whose dates are the actual
//! dates of the plan's tasks ([`actual`]).
//!
//! The result is an ordinary [`Scene`]: one object per IFC element, id = its
//! GlobalId, z up, metres; its tasks drive the visibility as everywhere else
//! (`Scene::apply_schedule`).

pub mod actual;
pub mod ifc;
mod ifc_checks;
mod ifc_spatial;
mod ifc_styles;
pub mod ifc_tasks;
pub mod links_csv;
pub mod msproject;
mod placement;
pub mod pmxml;
mod psets;
pub mod rules;
mod wbs;
pub mod xer;
pub mod xlsx;

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use chrono::{DateTime, Utc};
use glam::Mat4;
use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::scene::links::{find_cycle, show_cycle};
use crate::scene::{
    Actual, Dates, Georeference, NamedType, Object, Predecessor, Scene, ScheduleOptions, Span,
    Task, TaskType, Up, Visibility,
};
use crate::time::{TimeSpan, format_date};

/// A start and a finish.
pub type Dated = (DateTime<Utc>, DateTime<Utc>);

/// A task as a schedule file gives it, with absolute dates.
#[derive(Debug, Clone, PartialEq)]
pub struct ScheduleTask {
    pub id: String,
    pub name: String,
    /// The type the schedule gives, if any (a rule may set it; the default
    /// is construct).
    pub kind: Option<NamedType>,
    /// The planned start and finish.
    pub start: DateTime<Utc>,
    pub finish: DateTime<Utc>,
    /// What was recorded of its execution.
    pub actual: Recorded,
    /// An earlier plan's start and finish.
    pub baseline: Option<Dated>,
    /// The critical path method's early and late dates, where the schedule
    /// gives them (P6).
    pub early: Option<Dated>,
    pub late: Option<Dated>,
    /// The id of its summary task in the same schedule, if any.
    pub parent: Option<String>,
    /// The tasks it follows, by id in the same schedule.
    pub predecessors: Vec<Predecessor>,
    /// Its place in the work breakdown as the planner codes it (P6's WBS
    /// code path `TWR.L01.FRM`, Project's `WBS` field `1.2.3`).
    pub wbs: Option<String>,
    /// Activity codes: code type -> value (P6).
    pub codes: BTreeMap<String, String>,
    /// User-defined and custom fields: name -> value (P6 user fields,
    /// Project's extended attributes, spreadsheet columns).
    pub fields: BTreeMap<String, String>,
    /// GlobalIds of the elements the schedule itself links to the task.
    pub objects: Vec<String>,
}

impl ScheduleTask {
    /// A planned task: no type, actual, baseline, early or late dates,
    /// parent, links, codes, fields or elements.
    pub fn planned(
        id: impl Into<String>,
        name: impl Into<String>,
        start: DateTime<Utc>,
        finish: DateTime<Utc>,
    ) -> ScheduleTask {
        ScheduleTask {
            id: id.into(),
            name: name.into(),
            kind: None,
            start,
            finish,
            actual: Recorded::default(),
            baseline: None,
            early: None,
            late: None,
            parent: None,
            predecessors: Vec::new(),
            wbs: None,
            codes: BTreeMap::new(),
            fields: BTreeMap::new(),
            objects: Vec::new(),
        }
    }
}

impl ScheduleTask {
    /// A user or custom field by name, else the CPM date of that name
    /// (`early_start`, `early_finish`, `late_start`, `late_finish`, as ISO
    /// 8601), for the linking rules.
    pub fn field(&self, name: &str) -> Option<String> {
        if let Some(v) = self.fields.get(name) {
            return Some(v.clone());
        }
        let (span, end) = match name {
            "early_start" => (self.early, false),
            "early_finish" => (self.early, true),
            "late_start" => (self.late, false),
            "late_finish" => (self.late, true),
            _ => return None,
        };
        span.map(|(s, f)| format_date(if end { f } else { s }))
    }
}

/// The links of a schedule's tasks form no cycle: an error naming the
/// file, `at` (the table or element of the links) and the tasks of a
/// cycle.
pub fn check_links(path: &Path, at: &str, tasks: &[ScheduleTask]) -> Result<()> {
    let ids: Vec<&str> = tasks.iter().map(|t| t.id.as_str()).collect();
    match find_cycle(&ids, |i| {
        tasks[i].predecessors.iter().map(|p| p.task.as_str())
    }) {
        Some(cycle) => Err(Error::invalid(
            path,
            at,
            format!("the links form a cycle: {}", show_cycle(&ids, &cycle)),
        )),
        None => Ok(()),
    }
}

/// A task's recorded execution as a schedule gives it: a start once it
/// began, a finish once it ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Recorded {
    pub start: Option<DateTime<Utc>>,
    pub finish: Option<DateTime<Utc>>,
}

impl Recorded {
    /// The record of a start and a finish as read; the message says what is
    /// wrong with the finish (the readers name the file and field).
    pub fn new(
        start: Option<DateTime<Utc>>,
        finish: Option<DateTime<Utc>>,
    ) -> std::result::Result<Recorded, &'static str> {
        match (start, finish) {
            (None, Some(_)) => Err("an actual finish needs an actual start"),
            (Some(s), Some(f)) if f < s => Err("the actual finish is before the actual start"),
            _ => Ok(Recorded { start, finish }),
        }
    }
}

/// What to import besides the models.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// The scene's name.
    pub name: String,
    /// A schedule: `.xer` (Primavera P6), `.xml` (Microsoft Project or P6
    /// XML), `.xlsx` (a task list), `.csv` (element-task links) or
    /// `.ifc`/`.ifczip` (IFC work schedules).
    pub schedule: Option<PathBuf>,
    /// Linking rules (`hdlod-links/1`).
    pub links: Option<PathBuf>,
    /// As-built logs (`.csv`): their dates are the actual dates of the
    /// schedule's tasks, matched by task id, else by name.
    pub actual: Vec<PathBuf>,
    /// The dates the scene's presence follows.
    pub dates: Dates,
    /// The project to read of a schedule file that holds several (P6 XER
    /// or XML): its short name or id.
    pub project: Option<String>,
}

/// What a schedule reader needs besides the file.
#[derive(Debug, Clone, Default)]
pub struct Source {
    /// The project of a file of several (P6).
    pub project: Option<String>,
    /// The columns of a spreadsheet, from the rules file.
    pub mapping: Option<xlsx::Mapping>,
}

/// What an import did (schemas/import-report.schema.json).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Report {
    pub files: Vec<FileReport>,
    pub elements: usize,
    pub triangles: usize,
    /// Entities left out, over all files: IFC class -> reason -> count.
    pub skipped: BTreeMap<String, BTreeMap<String, usize>>,
    /// Tasks of the schedule (all sources) and those that act on objects.
    pub tasks: usize,
    pub scene_tasks: usize,
    /// Summary tasks the scene holds, without objects, so that the parents
    /// of its tasks resolve.
    pub summary_tasks: usize,
    /// Tasks of the scene with an actual start (from any source).
    pub actual_tasks: usize,
    /// Links between the scene's tasks, and links of its tasks to tasks it
    /// does not hold (left out).
    pub links: usize,
    pub links_outside: usize,
    /// Tasks of the schedule, summary tasks aside, that act on no object,
    /// and a few of them (`id "name"`).
    pub unmatched_tasks: usize,
    pub unmatched_task_examples: Vec<String>,
    /// What the as-built logs gave, when there are any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub actual: Option<actual::Report>,
    pub rules: Vec<RuleReport>,
    /// Objects some task acts on.
    pub scheduled: usize,
    /// Objects no task acts on (shown throughout), when there is a schedule.
    pub unmatched: Vec<String>,
    pub time: TimeReport,
    pub warnings: Vec<String>,
    pub seconds: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct FileReport {
    pub file: String,
    pub schema: String,
    pub elements: usize,
    pub triangles: usize,
    /// Entities left out of this file.
    pub skipped: usize,
    /// Of those, elements with a body that gave no mesh (each named in the
    /// warnings).
    pub failed: usize,
    /// Of the elements, those the file styles (not a default colour) and
    /// those on a storey.
    pub styled: usize,
    pub in_storey: usize,
    /// Tasks found in the file (IFC4 and IFC2x3 work schedules).
    pub tasks: usize,
    pub seconds: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct RuleReport {
    pub name: String,
    /// The (first) task the rule assigns.
    pub task: String,
    pub task_name: String,
    /// The tasks it assigns: one, or those its task selector matched.
    pub tasks: usize,
    #[serde(rename = "type")]
    pub kind: TaskType,
    pub matched: usize,
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct TimeReport {
    pub start: String,
    pub end: String,
}

/// How many unmatched tasks the report names.
const EXAMPLES: usize = 10;

/// Imports IFC models, a schedule and linking rules into a scene. Files are
/// read in parallel; `progress` is called as each one is done. Problems that
/// do not stop the import (a rule that matches nothing, links to unknown
/// elements, duplicate GlobalIds) are warnings in the report.
pub fn import(
    models: &[PathBuf],
    options: &Options,
    progress: &(dyn Fn(&Path) + Sync),
) -> Result<(Scene, Report)> {
    let clock = Instant::now();
    if models.is_empty() {
        return Err(Error::argument("models", "no IFC model given"));
    }
    let name = &options.name;
    let psets = match &options.links {
        Some(links) => rules::property_sets(links)?,
        None => HashSet::new(),
    };
    let read: Vec<(f64, ifc::Model)> = models
        .par_iter()
        .map(|path| {
            let t = Instant::now();
            let model = ifc::read_with(path, &psets)?;
            progress(path);
            Ok((t.elapsed().as_secs_f64(), model))
        })
        .collect::<Result<_>>()?;

    let mut report = Report::default();
    let mut meshes = Vec::new();
    let mut objects: Vec<Object> = Vec::new();
    // Each object's placement in the models' coordinates, kept in f64
    // until the scene's origin is chosen.
    let mut origins = Vec::new();
    let mut georeference: Option<(Georeference, String)> = None;
    let mut seen = HashSet::new();
    let mut schedule: Vec<ScheduleTask> = Vec::new();
    for (path, (seconds, model)) in models.iter().zip(read) {
        let file = path
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut skipped = model.skipped;
        let mut file_report = FileReport {
            file: file.clone(),
            schema: model.schema,
            elements: 0,
            triangles: 0,
            skipped: 0,
            failed: model.warnings.len(),
            styled: 0,
            in_storey: 0,
            tasks: model.tasks.len(),
            seconds,
        };
        report.warnings.extend(model.warnings);
        if let Some(w) = model.georeference_warning {
            report.warnings.push(format!("{file}: {w}"));
        }
        match (&georeference, model.georeference) {
            (None, Some(g)) => georeference = Some((g, file.clone())),
            (Some((first, from)), Some(g)) if *first != g => report.warnings.push(format!(
                "{file}: its georeference differs from that of {from}; kept that one"
            )),
            _ => {}
        }
        let mut duplicates = Vec::new();
        for e in model.elements {
            if !seen.insert(e.id.clone()) {
                duplicates.push(e.id);
                *skipped
                    .entry(e.class)
                    .or_default()
                    .entry("duplicate GlobalId".into())
                    .or_default() += 1;
                continue;
            }
            file_report.elements += 1;
            file_report.triangles += e.mesh.triangle_count();
            file_report.styled += usize::from(e.styled);
            file_report.in_storey += usize::from(e.storey.is_some());
            let mut properties = BTreeMap::new();
            properties.insert(rules::FILE.to_string(), file.clone());
            properties.insert(rules::CLASS.to_string(), e.class);
            if !e.name.is_empty() {
                properties.insert(rules::NAME.to_string(), e.name);
            }
            if let Some(s) = e.storey {
                properties.insert(rules::STOREY.to_string(), s);
            }
            properties.extend(e.properties);
            objects.push(Object {
                id: e.id,
                mesh: meshes.len(),
                transform: Mat4::IDENTITY,
                color: e.color,
                visibility: Visibility::always(),
                motion: None,
                skin: None,
                properties,
            });
            meshes.push(e.mesh);
            origins.push(e.origin);
        }
        if let Some(first) = duplicates.first() {
            report.warnings.push(format!(
                "{file}: {} element(s) with a GlobalId already imported (e.g. {first}); kept the \
                 first",
                duplicates.len()
            ));
        }
        for (class, reasons) in skipped {
            for (reason, n) in reasons {
                file_report.skipped += n;
                *report
                    .skipped
                    .entry(class.clone())
                    .or_default()
                    .entry(reason)
                    .or_default() += n;
            }
        }
        report.elements += file_report.elements;
        report.triangles += file_report.triangles;
        report.files.push(file_report);
        schedule.extend(model.tasks);
    }

    let origin = placement::local_origin(&origins);
    for (object, at) in objects.iter_mut().zip(&origins) {
        object.transform = Mat4::from_translation((*at - origin).as_vec3());
    }
    let georeference = placement::at_origin(georeference.map(|(g, _)| g), origin);

    if let Some(path) = &options.schedule {
        let source = Source {
            project: options.project.clone(),
            mapping: match &options.links {
                Some(links) => rules::read_mapping(links)?,
                None => None,
            },
        };
        schedule.extend(read_schedule(path, &source)?);
    } else if options.project.is_some() {
        return Err(Error::argument(
            "project",
            "a project is chosen of a --schedule file; none is given",
        ));
    }
    if !options.actual.is_empty() {
        let logs = options
            .actual
            .iter()
            .map(|path| {
                if extension(path) != "csv" {
                    return Err(Error::argument(
                        "actual",
                        format!(
                            "{}: an as-built log is a .csv of element-task rows",
                            path.display()
                        ),
                    ));
                }
                actual::read(path)
            })
            .collect::<Result<Vec<_>>>()?;
        report.actual = Some(actual::apply(&mut schedule, &logs, &mut report.warnings));
    }
    let rules = match &options.links {
        Some(path) => rules::read(path, &schedule)?,
        None => Vec::new(),
    };
    report.tasks = schedule.len();

    // (task, type) -> object ids, in order of first use.
    let mut groups: Vec<((usize, NamedType), Vec<String>)> = Vec::new();
    let mut group_of: HashMap<(usize, NamedType), usize> = HashMap::new();
    let mut add = |key: (usize, NamedType), id: &str| {
        let g = *group_of.entry(key).or_insert_with(|| {
            groups.push((key, Vec::new()));
            groups.len() - 1
        });
        groups[g].1.push(id.to_string());
    };
    let known: HashSet<&str> = objects.iter().map(|o| o.id.as_str()).collect();
    let mut unknown = 0usize;
    for (k, t) in schedule.iter().enumerate() {
        let kind = t.kind.unwrap_or(TaskType::Construct.into());
        for id in &t.objects {
            if known.contains(id.as_str()) {
                add((k, kind), id);
            } else {
                unknown += 1;
            }
        }
    }
    if unknown > 0 {
        report.warnings.push(format!(
            "{unknown} element links of the schedule name GlobalIds that are not in the models"
        ));
    }
    for rule in &rules {
        let first = &schedule[rule.tasks[0]];
        let mut matched = 0;
        for o in &objects {
            let tasks = rule.tasks_of(o);
            for &k in tasks {
                let kind = rule
                    .kind
                    .or(schedule[k].kind)
                    .unwrap_or(TaskType::Construct.into());
                add((k, kind), &o.id);
            }
            matched += usize::from(!tasks.is_empty());
        }
        if matched == 0 {
            report
                .warnings
                .push(format!("rule {:?} matches no object", rule.name));
        }
        report.rules.push(RuleReport {
            name: rule.name.clone(),
            task: first.id.clone(),
            task_name: first.name.clone(),
            tasks: rule.tasks.len(),
            kind: rule
                .kind
                .or(first.kind)
                .map_or(TaskType::Construct, |t| t.kind),
            matched,
        });
    }

    let linked: HashSet<&str> = groups
        .iter()
        .flat_map(|(_, ids)| ids.iter().map(String::as_str))
        .collect();
    report.scheduled = linked.len();
    if !schedule.is_empty() || !rules.is_empty() {
        report.unmatched = objects
            .iter()
            .filter(|o| !linked.contains(o.id.as_str()))
            .map(|o| o.id.clone())
            .collect();
        // Tasks that act on nothing, summary tasks aside (their work is
        // that of the tasks below them).
        let acting: HashSet<usize> = groups.iter().map(|((k, _), _)| *k).collect();
        let first = first_by_id(&schedule);
        let summaries: HashSet<usize> = schedule
            .iter()
            .filter_map(|t| t.parent.as_deref().and_then(|p| first.get(p).copied()))
            .collect();
        let idle: Vec<&ScheduleTask> = (0..schedule.len())
            .filter(|k| !acting.contains(k) && !summaries.contains(k))
            .map(|k| &schedule[k])
            .collect();
        report.unmatched_tasks = idle.len();
        report.unmatched_task_examples = idle
            .iter()
            .take(EXAMPLES)
            .map(|t| format!("{} {:?}", t.id, t.name))
            .collect();
    }

    // The span covers the planned and the actual dates of the tasks that
    // act on objects, so that either choice of dates plays within it.
    let acting: Vec<&ScheduleTask> = if groups.is_empty() {
        schedule.iter().collect()
    } else {
        groups.iter().map(|((k, _), _)| &schedule[*k]).collect()
    };
    let time = match (
        acting
            .iter()
            .flat_map(|t| [Some(t.start), t.actual.start])
            .flatten()
            .min(),
        acting
            .iter()
            .flat_map(|t| [Some(t.finish), t.actual.start, t.actual.finish])
            .flatten()
            .max(),
    ) {
        (Some(start), Some(end)) if end > start => TimeSpan {
            start,
            seconds: (end - start).num_milliseconds() as f64 / 1000.0,
        },
        // Nothing scheduled: a static scene over a nominal day.
        (start, _) => TimeSpan {
            start: start.unwrap_or(DateTime::UNIX_EPOCH),
            seconds: 86_400.0,
        },
    };
    report.time = TimeReport {
        start: format_date(time.start),
        end: format_date(time.end()),
    };

    report.scene_tasks = groups.len();
    let mut rows: Vec<(usize, NamedType, Vec<String>)> = groups
        .into_iter()
        .map(|((k, kind), objects)| (k, kind, objects))
        .collect();
    let summaries = summary_rows(&schedule, rows.iter().map(|r| r.0));
    report.summary_tasks = summaries.len();
    rows.extend(summaries.into_iter().map(|k| {
        let kind = schedule[k].kind.unwrap_or(TaskType::Construct.into());
        (k, kind, Vec::new())
    }));

    let mut tasks = Vec::new();
    let mut ids = HashSet::new();
    // Schedule task -> the id of its first scene task.
    let mut scene_id: HashMap<usize, String> = HashMap::new();
    for (k, kind, objects) in &rows {
        let t = &schedule[*k];
        let mut id = t.id.clone();
        if !ids.insert(id.clone()) {
            id = format!("{}:{}", t.id, kind.name());
            ids.insert(id.clone());
        }
        scene_id.entry(*k).or_insert_with(|| id.clone());
        let at = |d: DateTime<Utc>| time.seconds_of(d);
        tasks.push(Task {
            id,
            name: t.name.clone(),
            kind: kind.kind,
            ifc_type: kind.ifc,
            start: at(t.start),
            finish: at(t.finish),
            actual: Actual {
                start: t.actual.start.map(at),
                finish: t.actual.finish.map(at),
            },
            baseline: t.baseline.map(|(s, f)| Span {
                start: at(s),
                finish: at(f),
            }),
            parent: None,
            predecessors: Vec::new(),
            objects: objects.clone(),
        });
    }
    // Parents by scene id; one naming a task that is not in the scene (not
    // in the schedule, or without dates) is dropped.
    let first = first_by_id(&schedule);
    for ((k, ..), task) in rows.iter().zip(&mut tasks) {
        task.parent = schedule[*k]
            .parent
            .as_deref()
            .and_then(|p| first.get(p))
            .and_then(|j| scene_id.get(j))
            .cloned();
    }
    break_cycles(&mut tasks, &mut report.warnings);
    // Links between tasks of the scene; a link to a task the scene does not
    // hold (one acting on no element) is counted, not kept.
    for ((k, ..), task) in rows.iter().zip(&mut tasks) {
        for p in &schedule[*k].predecessors {
            match first.get(p.task.as_str()).and_then(|j| scene_id.get(j)) {
                Some(id) if *id != task.id => {
                    task.predecessors.push(Predecessor {
                        task: id.clone(),
                        ..p.clone()
                    });
                    report.links += 1;
                }
                _ => report.links_outside += 1,
            }
        }
    }
    // Each schedule is checked as it is read; tasks of several sources
    // sharing ids could still close a cycle.
    let ids: Vec<&str> = tasks.iter().map(|t| t.id.as_str()).collect();
    if let Some(cycle) = find_cycle(&ids, |i| {
        tasks[i].predecessors.iter().map(|p| p.task.as_str())
    }) {
        return Err(Error::argument(
            "schedule",
            format!(
                "the links of the scene's tasks form a cycle: {}",
                show_cycle(&ids, &cycle)
            ),
        ));
    }
    report.actual_tasks = tasks.iter().filter(|t| t.actual.start.is_some()).count();

    let mut scene = Scene {
        name: name.clone(),
        up: Up::Z,
        time,
        meshes,
        objects,
        tasks,
        schedule_options: ScheduleOptions {
            dates: options.dates,
            ..ScheduleOptions::default()
        },
        appearance: None,
        georeference,
    };
    scene.apply_schedule();
    report.seconds = clock.elapsed().as_secs_f64();
    Ok((scene, report))
}

/// The first task of the schedule with each id.
fn first_by_id(schedule: &[ScheduleTask]) -> HashMap<&str, usize> {
    let mut first = HashMap::new();
    for (k, t) in schedule.iter().enumerate() {
        first.entry(t.id.as_str()).or_insert(k);
    }
    first
}

/// The summary tasks above the acting tasks that do not act themselves, in
/// schedule order: a Gantt chart groups its rows under them, so the scene
/// keeps them as tasks without objects. Summary tasks with nothing of the
/// scene below them are left out.
fn summary_rows(schedule: &[ScheduleTask], acting: impl Iterator<Item = usize>) -> Vec<usize> {
    let first = first_by_id(schedule);
    let acting: HashSet<usize> = acting.collect();
    let mut above = HashSet::new();
    for &k in &acting {
        let mut at = schedule[k].parent.as_deref();
        // At most one step per task: a cycle of parents ends the walk.
        for _ in 0..schedule.len() {
            let Some(&j) = at.and_then(|p| first.get(p)) else {
                break;
            };
            if !acting.contains(&j) {
                above.insert(j);
            }
            at = schedule[j].parent.as_deref();
        }
    }
    let mut rows: Vec<usize> = above.into_iter().collect();
    rows.sort_unstable();
    rows
}

/// Drops the parent of a task whose parents lead back to itself (a nesting
/// cycle in a broken file), with a warning: the scene's parents form a tree.
fn break_cycles(tasks: &mut [Task], warnings: &mut Vec<String>) {
    let index: HashMap<String, usize> = tasks
        .iter()
        .enumerate()
        .map(|(i, t)| (t.id.clone(), i))
        .collect();
    for i in 0..tasks.len() {
        let mut at = i;
        for _ in 0..tasks.len() {
            let Some(&p) = tasks[at].parent.as_ref().and_then(|p| index.get(p)) else {
                break;
            };
            if p == i {
                warnings.push(format!(
                    "task {:?}: its parents lead back to it; parent {:?} dropped",
                    tasks[i].id,
                    tasks[i].parent.as_deref().unwrap_or_default()
                ));
                tasks[i].parent = None;
                break;
            }
            at = p;
        }
    }
}

/// A file's extension in lower case.
fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// Whether an `.xml` file is P6 XML rather than Project XML: its root
/// element, `APIBusinessObjects`, opens its first few kilobytes.
fn is_p6_xml(path: &Path) -> Result<bool> {
    use std::io::Read;
    let mut head = Vec::with_capacity(4096);
    crate::input::open(path)?
        .take(4096)
        .read_to_end(&mut head)
        .map_err(|e| Error::io(path, e))?;
    Ok(String::from_utf8_lossy(&head).contains("<APIBusinessObjects"))
}

/// Reads a schedule by its extension (and, for `.xml`, its root element).
pub fn read_schedule(path: &Path, source: &Source) -> Result<Vec<ScheduleTask>> {
    let ext = extension(path);
    let p6_xml = ext == "xml" && is_p6_xml(path)?;
    let multi = ext == "xer" || p6_xml;
    if source.project.is_some() && !multi {
        return Err(Error::argument(
            "project",
            format!(
                "{}: only a Primavera P6 file (.xer, P6 XML) holds several projects",
                path.display()
            ),
        ));
    }
    match ext.as_str() {
        "xer" => xer::read(path, source.project.as_deref()),
        "xml" if p6_xml => pmxml::read(path, source.project.as_deref()),
        "xml" => msproject::read(path),
        "csv" => links_csv::read(path),
        "xlsx" => xlsx::read(path, &source.mapping.clone().unwrap_or_default()),
        "ifc" | "ifczip" => {
            let step = ifc::read_step(path)?;
            let schema = ifc::header_schema(&step).ok_or_else(|| {
                Error::invalid(path, "HEADER", "no FILE_SCHEMA: not an IFC (STEP) file")
            })?;
            ifc_tasks::read(path, &schema, &step)
        }
        _ => Err(Error::argument(
            "schedule",
            format!(
                "{}: unknown schedule format; expected .xer (Primavera P6), .xml (Microsoft \
                 Project or P6 XML), .xlsx (a task list), .csv (element-task links) or .ifc/.ifczip \
                 (IFC work schedules)",
                path.display()
            ),
        )),
    }
}

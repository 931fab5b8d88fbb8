//! The object and task tables of a tree (`objects.json`, `hdlod-objects/1`;
//! docs/formats.md): every scene object in scene order, absent ones too, so
//! that an object's index is the feature id its vertices carry in the
//! cluster geometry; with its properties, class, tasks, presence and leaf
//! clusters; and every task with its times and objects.
//!
//! The file is optional in a tree (either format): the builder writes it, a tree
//! without it still loads. The tables are kept apart from the clusters: the
//! cut never reads them, they only answer what an object or task is.
//!
//! The object rows are held in the binary layout of `objects.bin`
//! ([`super::object_index`]), made in memory from the JSON or mapped from
//! that file: one form for both, read row by row.

use std::collections::BTreeMap;

use rustc_hash::FxHashMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::object_index::{self, ObjectRows};
use super::{Cluster, Tree};
use crate::error::{Error, Result};
use crate::scene::appearance::{Look, Profile, ProfileFile};
use crate::scene::status::{Actual, Dates, Deviation, Progress, Span, TaskDates};
use crate::scene::{Class, LinkType, NamedType, Scene, TaskType, Visibility, property};
use crate::time::{TimeSpan, format_date};

/// The value of the file's `format` field.
pub const FORMAT: &str = "hdlod-objects/1";

/// The class property of scenes that do not name it as the IFC import
/// does (`scene::property::CLASS`).
const CLASS_FALLBACK: &str = "class";

/// One scene object; its index in [`ObjectTables::objects`] is its index in
/// the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectEntry {
    pub id: String,
    /// The `name` property.
    pub name: Option<String>,
    /// The element's class: the `ifc_class` property, else `class`.
    pub class: Option<String>,
    pub properties: BTreeMap<String, String>,
    pub visibility_class: Class,
    /// Indices of the tasks acting on it, increasing.
    pub tasks: Vec<u32>,
    /// When it is present, as the schedule composes it (the first interval
    /// may start at minus infinity, the last end at plus infinity).
    pub presence: Visibility,
    /// Its leaf clusters, increasing: one, or the pieces of a moving object
    /// split where it stands still.
    pub clusters: Vec<u32>,
}

impl ObjectEntry {
    /// Its presence as the files and the API write it: `[start, end)`,
    /// `None` for an open end.
    pub fn open_presence(&self) -> Vec<[Option<f64>; 2]> {
        open_presence(self.presence.intervals().iter().map(|&(a, b)| [a, b]))
    }
}

/// Intervals as the files and the API write them: `None` for an open end.
pub(crate) fn open_presence(intervals: impl Iterator<Item = [f64; 2]>) -> Vec<[Option<f64>; 2]> {
    let open = |x: f64| x.is_finite().then_some(x);
    intervals.map(|[a, b]| [open(a), open(b)]).collect()
}

/// One schedule task, times in seconds since the scene's start.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskEntry {
    pub id: String,
    pub name: Option<String>,
    pub kind: TaskType,
    /// The IFC task type its schedule named, if any.
    pub ifc_type: Option<&'static str>,
    /// Planned, actual and baseline dates.
    pub dates: TaskDates,
    /// The index of its summary task, if any.
    pub parent: Option<u32>,
    /// The tasks it follows, by index.
    pub predecessors: Vec<LinkEntry>,
    /// Indices of the objects it acts on, increasing.
    pub objects: Vec<u32>,
}

impl TaskEntry {
    /// Its type with the IFC name it was given.
    pub fn named(&self) -> NamedType {
        NamedType {
            kind: self.kind,
            ifc: self.ifc_type,
        }
    }
}

/// A logic link to a predecessor, by the predecessor's task index.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinkEntry {
    pub task: u32,
    #[serde(rename = "type")]
    pub kind: LinkType,
    /// Seconds.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub lag: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// An element at a time: the task that governs its look, where that task
/// stands and how it runs against its plan, and the look.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElementState {
    pub task: Option<u32>,
    pub progress: Option<Progress>,
    pub deviation: Option<Deviation>,
    pub look: Look,
}

/// The tables, and what answers a look-up or a search without a scan of
/// the strings: made once, when the tables are made or read (so the rows
/// are read-only). The object rows carry their own (`ObjectRows`).
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectTables {
    objects: ObjectRows,
    tasks: Vec<TaskEntry>,
    /// The dates the build's presence followed.
    dates: Dates,
    /// The scene's own appearance profile, if it has one.
    appearance: Option<Profile>,
    task_ids: ById,
    task_text: SearchText,
}

/// One page of a search: matching indices in order, and where the next
/// page starts.
#[derive(Debug, Clone, PartialEq)]
pub struct Page {
    pub items: Vec<u32>,
    /// The index the next page's scan starts at; `None` on the last page.
    pub next: Option<u32>,
    /// Matches in the whole table.
    pub total: usize,
}

impl ObjectTables {
    pub fn new(
        objects: Vec<ObjectEntry>,
        tasks: Vec<TaskEntry>,
        dates: Dates,
        appearance: Option<Profile>,
    ) -> ObjectTables {
        let rows = object_index::rows_of(&objects);
        ObjectTables::with_rows(rows, tasks, dates, appearance)
    }

    /// The tables of the same objects after the tree's clusters were
    /// renumbered: each leaf `c` is now `new_id(c)`, in the same order.
    /// Encoding the rows again was a tenth of a geometry update at paper
    /// scale.
    pub fn renumbered(self, new_id: impl Fn(u32) -> u32) -> ObjectTables {
        ObjectTables {
            objects: self.objects.renumbered(new_id),
            ..self
        }
    }

    fn with_rows(
        objects: ObjectRows,
        tasks: Vec<TaskEntry>,
        dates: Dates,
        appearance: Option<Profile>,
    ) -> ObjectTables {
        let task_ids = ById::new(|k| &tasks[k as usize].id, tasks.len());
        let task_text = SearchText::new(tasks.iter().map(|t| {
            [
                t.id.as_str(),
                t.name.as_deref().unwrap_or_default(),
                t.kind.name(),
            ]
        }));
        ObjectTables {
            objects,
            tasks,
            dates,
            appearance,
            task_ids,
            task_text,
        }
    }

    /// The tables of `scene` (as built: its schedule applied) over the
    /// leaf clusters that name its objects.
    pub fn of(scene: &Scene, clusters: &[Cluster]) -> ObjectTables {
        Self::of_leaves(
            scene,
            (clusters.iter()).map(|c| (c.id, c.objects.iter().map(String::as_str))),
        )
    }

    /// [`ObjectTables::of`] over the clusters' ids and objects alone.
    pub fn of_leaves<'a, I: IntoIterator<Item = &'a str>>(
        scene: &Scene,
        clusters: impl IntoIterator<Item = (u32, I)>,
    ) -> ObjectTables {
        let index: FxHashMap<&str, u32> = scene
            .objects
            .iter()
            .enumerate()
            .map(|(i, o)| (o.id.as_str(), i as u32))
            .collect();
        let mut leaves: Vec<Vec<u32>> = vec![Vec::new(); scene.objects.len()];
        for (cluster, objects) in clusters {
            for id in objects {
                if let Some(&i) = index.get(id) {
                    leaves[i as usize].push(cluster);
                }
            }
        }
        let mut acting: Vec<Vec<u32>> = vec![Vec::new(); scene.objects.len()];
        let task_index: FxHashMap<&str, u32> = scene
            .tasks
            .iter()
            .enumerate()
            .map(|(k, t)| (t.id.as_str(), k as u32))
            .collect();
        let tasks = scene
            .tasks
            .iter()
            .enumerate()
            .map(|(k, t)| {
                let mut objects: Vec<u32> = t
                    .objects
                    .iter()
                    .filter_map(|id| index.get(id.as_str()).copied())
                    .collect();
                objects.sort_unstable();
                objects.dedup();
                for &i in &objects {
                    acting[i as usize].push(k as u32);
                }
                TaskEntry {
                    id: t.id.clone(),
                    name: Some(t.name.clone()).filter(|n| !n.is_empty()),
                    kind: t.kind,
                    ifc_type: t.ifc_type,
                    dates: t.dates(),
                    parent: t.parent.as_deref().and_then(|p| task_index.get(p).copied()),
                    predecessors: t
                        .predecessors
                        .iter()
                        .filter_map(|p| {
                            Some(LinkEntry {
                                task: *task_index.get(p.task.as_str())?,
                                kind: p.kind,
                                lag: p.lag,
                            })
                        })
                        .collect(),
                    objects,
                }
            })
            .collect();
        let objects = scene
            .objects
            .iter()
            .zip(leaves.into_iter().zip(acting))
            .map(|(o, (mut clusters, tasks))| {
                clusters.sort_unstable();
                clusters.dedup();
                ObjectEntry {
                    id: o.id.clone(),
                    name: o.properties.get(property::NAME).cloned(),
                    class: o
                        .properties
                        .get(property::CLASS)
                        .or_else(|| o.properties.get(CLASS_FALLBACK))
                        .cloned(),
                    properties: o.properties.clone(),
                    visibility_class: scene.class_of(o),
                    tasks,
                    presence: o.visibility.clone(),
                    clusters,
                }
            })
            .collect();
        ObjectTables::new(
            objects,
            tasks,
            scene.schedule_options.dates,
            scene.appearance.clone(),
        )
    }

    /// The number of objects: every object of the scene.
    pub fn object_count(&self) -> usize {
        self.objects.len()
    }

    /// Object `i` (its index in the scene), decoded.
    pub fn object(&self, i: u32) -> ObjectEntry {
        self.objects.entry(i)
    }

    /// The object rows, read in place: ids, properties, lists.
    pub fn rows(&self) -> &ObjectRows {
        &self.objects
    }

    pub fn tasks(&self) -> &[TaskEntry] {
        &self.tasks
    }

    /// The dates the build's presence followed.
    pub fn dates(&self) -> Dates {
        self.dates
    }

    /// The scene's own appearance profile, if it has one.
    pub fn appearance(&self) -> Option<&Profile> {
        self.appearance.as_ref()
    }

    /// The task that governs how object `i` looks at `t`, on the tables'
    /// dates: of its tasks, the one in progress that started last; else the
    /// finished one that finished last; else the one to start first (ties:
    /// the later task). The viewer applies the same rule
    /// (`server/viewer/appearance.js`).
    pub fn governing_task(&self, i: u32, t: f64) -> Option<u32> {
        let tasks = self.objects.tasks(i);
        let of = |k: u32| (k, &self.tasks[k as usize].dates);
        let by = |progress: Progress| {
            tasks
                .iter()
                .map(|&k| of(k))
                .filter(move |(_, d)| d.progress(t, self.dates) == progress)
        };
        let latest = |key: fn(&TaskDates, Dates) -> f64, progress| {
            by(progress)
                .max_by(|a, b| {
                    key(a.1, self.dates)
                        .total_cmp(&key(b.1, self.dates))
                        .then(a.0.cmp(&b.0))
                })
                .map(|(k, _)| k)
        };
        latest(|d, dates| d.running(dates).0, Progress::Active)
            .or_else(|| latest(|d, dates| d.running(dates).1, Progress::Finished))
            .or_else(|| {
                by(Progress::NotStarted)
                    .min_by(|a, b| {
                        a.1.running(self.dates)
                            .0
                            .total_cmp(&b.1.running(self.dates).0)
                            .then(b.0.cmp(&a.0))
                    })
                    .map(|(k, _)| k)
            })
    }

    /// Object `i` at `t` under `profile`: its governing task's state and
    /// the look that gives; the model's own look for an object with no
    /// task.
    pub fn state_at(&self, i: u32, t: f64, profile: &Profile) -> ElementState {
        let Some(k) = self.governing_task(i, t) else {
            return ElementState {
                task: None,
                progress: None,
                deviation: None,
                look: Look::Model,
            };
        };
        let task = &self.tasks[k as usize];
        let progress = task.dates.progress(t, self.dates);
        let deviation = task.dates.deviation(t);
        ElementState {
            task: Some(k),
            progress: Some(progress),
            deviation,
            look: profile.look(task.named(), progress, deviation),
        }
    }

    /// The index of the object with this id.
    pub fn object_index(&self, id: &str) -> Option<u32> {
        self.objects.find(id)
    }

    /// The index of the task with this id.
    pub fn task_index(&self, id: &str) -> Option<u32> {
        self.task_ids.find(|k| &self.tasks[k as usize].id, id)
    }

    /// Objects whose id, name or any property value contains `query`,
    /// ignoring case; an empty query matches every object. The scan starts
    /// at index `from` and stops after `limit` matches.
    pub fn search_objects(&self, query: &str, from: usize, limit: usize) -> Page {
        self.objects.search(query, from, limit)
    }

    /// Tasks whose id, name or type contains `query`, as [`Self::search_objects`].
    pub fn search_tasks(&self, query: &str, from: usize, limit: usize) -> Page {
        self.task_text.search(query, from, limit)
    }

    /// Checks the tables against themselves and the tree's clusters; `file`
    /// names the table in errors.
    pub fn validate(&self, tree: &Tree, file: &Path) -> Result<()> {
        let clusters = tree.cluster_count();
        let n = self.objects.len();
        let m = self.tasks.len();
        let bad = |at: String, message: String| Error::invalid(file, at, message);
        let increasing = |list: &[u32], below: usize| {
            list.windows(2).all(|w| w[0] < w[1])
                && list.last().is_none_or(|&x| (x as usize) < below)
        };
        if n > u32::MAX as usize || m > u32::MAX as usize {
            return Err(bad("objects".into(), "too many objects or tasks".into()));
        }
        let rows = &self.objects;
        if let Some((i, first)) = rows.duplicate() {
            return Err(bad(
                format!("objects[{i}].id"),
                format!(
                    "{:?} is also objects[{first}].id: ids must be unique",
                    rows.id(i)
                ),
            ));
        }
        if let Some((k, first)) = self.task_ids.duplicate(|k| &self.tasks[k as usize].id) {
            return Err(bad(
                format!("tasks[{k}].id"),
                format!(
                    "{:?} is also tasks[{first}].id: ids must be unique",
                    self.tasks[k as usize].id
                ),
            ));
        }
        let mut named = 0usize;
        for i in 0..n as u32 {
            let at = |field: &str| format!("objects[{i}].{field}");
            let (id, own) = (rows.id(i), rows.clusters(i));
            if !increasing(rows.tasks(i), m) {
                return Err(bad(
                    at("tasks"),
                    format!("must be increasing task indices below {m}"),
                ));
            }
            if !increasing(own, clusters) {
                return Err(bad(
                    at("clusters"),
                    format!("must be increasing cluster ids below {clusters}"),
                ));
            }
            if let Some(&c) = own.iter().find(|&&c| !tree.names_object(c, id)) {
                return Err(bad(
                    at("clusters"),
                    format!("cluster {c} does not list {id:?} among its objects"),
                ));
            }
            named += own.len();
        }
        // Every object a cluster names lists it (each listing was checked
        // above, so equal counts mean equal sets).
        let listed: usize = (0..clusters as u32).map(|c| tree.object_count_of(c)).sum();
        if listed != named {
            let stray = (0..clusters as u32)
                .flat_map(|c| tree.objects_of(c).into_iter().map(move |id| (c, id)))
                .find(|&(c, id)| {
                    self.object_index(id)
                        .is_none_or(|i| !rows.clusters(i).contains(&c))
                });
            let message = match stray {
                Some((c, id)) => {
                    format!("cluster {c} lists object {id:?}, which does not list the cluster")
                }
                None => "a cluster lists one object twice".into(),
            };
            return Err(bad("objects".into(), message));
        }
        let mut pairs = 0usize;
        for (k, t) in self.tasks.iter().enumerate() {
            let at = |field: &str| format!("tasks[{k}].{field}");
            let d = &t.dates;
            let ordered = |a: f64, b: f64| a.is_finite() && b.is_finite() && a <= b;
            if !ordered(d.start, d.finish) {
                return Err(bad(
                    at("finish"),
                    format!(
                        "start {} and finish {} must be finite, the finish not before the start",
                        d.start, d.finish
                    ),
                ));
            }
            let actual_ok = match (d.actual.start, d.actual.finish) {
                (None, None) => true,
                (Some(a), None) => a.is_finite(),
                (Some(a), Some(b)) => ordered(a, b),
                (None, Some(_)) => false,
            };
            if !actual_ok {
                return Err(bad(
                    at("actual_finish"),
                    "an actual finish needs an actual start, finite and not after it".into(),
                ));
            }
            if d.baseline.is_some_and(|b| !ordered(b.start, b.finish)) {
                return Err(bad(
                    at("baseline_finish"),
                    "the baseline must be finite, its finish not before its start".into(),
                ));
            }
            if let Some(p) = t
                .predecessors
                .iter()
                .find(|p| p.task as usize >= m || p.task as usize == k || !p.lag.is_finite())
            {
                return Err(bad(
                    at("predecessors"),
                    format!(
                        "link to task {} (lag {}): another task's index below {m}, a finite lag",
                        p.task, p.lag
                    ),
                ));
            }
            if t.parent.is_some_and(|p| p as usize >= m || p as usize == k) {
                return Err(bad(
                    at("parent"),
                    format!("must be the index of another task, below {m}"),
                ));
            }
            if !increasing(&t.objects, n) {
                return Err(bad(
                    at("objects"),
                    format!("must be increasing object indices below {n}"),
                ));
            }
            if let Some(&i) = t
                .objects
                .iter()
                .find(|&&i| rows.tasks(i).binary_search(&(k as u32)).is_err())
            {
                return Err(bad(
                    at("objects"),
                    format!("objects[{i}] does not list task {k} among its tasks"),
                ));
            }
            pairs += t.objects.len();
        }
        // As with the clusters: each task's objects list it, so equal
        // counts mean every object's tasks list it too.
        let listed: usize = (0..n as u32).map(|i| rows.tasks(i).len()).sum();
        if listed != pairs {
            let stray = (0..n as u32)
                .flat_map(|i| rows.tasks(i).iter().map(move |&k| (i, k)))
                .find(|&(i, k)| self.tasks[k as usize].objects.binary_search(&i).is_err());
            if let Some((i, k)) = stray {
                return Err(bad(
                    format!("objects[{i}].tasks"),
                    format!("task {k} does not list objects[{i}] among its objects"),
                ));
            }
        }
        Ok(())
    }

    /// The on-disk record; `time` gives the tasks' dates.
    pub fn to_record(&self, time: &TimeSpan) -> ObjectsRecord {
        ObjectsRecord {
            objects: (0..self.objects.len() as u32)
                .map(|i| self.object_record(i))
                .collect(),
            ..self.to_record_without_objects(time)
        }
    }

    /// Object `i`'s record in `objects.json`.
    pub(crate) fn object_record(&self, i: u32) -> ObjectRecord {
        let o = self.object(i);
        ObjectRecord {
            presence: o.open_presence(),
            id: o.id,
            name: o.name,
            class: o.class,
            properties: o.properties,
            visibility_class: o.visibility_class,
            tasks: o.tasks,
            clusters: o.clusters,
        }
    }

    /// [`ObjectTables::to_record`] with no objects: what `objects.bin`
    /// keeps as JSON.
    pub(crate) fn to_record_without_objects(&self, time: &TimeSpan) -> ObjectsRecord {
        ObjectsRecord {
            format: FORMAT.into(),
            objects: Vec::new(),
            tasks: self.task_records(time),
            dates: self.dates,
            appearance: self.appearance.as_ref().map(Profile::to_file),
        }
    }

    /// `objects.bin` (`hdlod-objects-index/1`) for these tables, written
    /// beside an `objects.json` of `json_len` bytes; `rest`: their
    /// [`ObjectTables::to_record_without_objects`], serialised.
    pub(crate) fn to_index<'a>(
        &'a self,
        rest: &'a [u8],
        json_len: u64,
    ) -> object_index::IndexFile<'a> {
        object_index::file(&self.objects, rest, json_len)
    }

    fn task_records(&self, time: &TimeSpan) -> Vec<TaskRecord> {
        self.tasks
            .iter()
            .map(|t| {
                let d = &t.dates;
                TaskRecord {
                    id: t.id.clone(),
                    name: t.name.clone(),
                    kind: t.kind,
                    ifc_type: t.ifc_type.map(str::to_owned),
                    start: d.start,
                    finish: d.finish,
                    start_date: format_date(time.date_at(d.start)),
                    finish_date: format_date(time.date_at(d.finish)),
                    actual_start: d.actual.start,
                    actual_finish: d.actual.finish,
                    baseline_start: d.baseline.map(|b| b.start),
                    baseline_finish: d.baseline.map(|b| b.finish),
                    parent: t.parent,
                    predecessors: t.predecessors.clone(),
                    objects: t.objects.clone(),
                }
            })
            .collect()
    }

    /// The tables of a record, checked against the tree's clusters; `file`
    /// names the table in errors. The tasks' dates are for the file's
    /// readers: the times are the seconds.
    pub fn from_record(record: ObjectsRecord, tree: &Tree, file: &Path) -> Result<Self> {
        if record.format != FORMAT {
            return Err(Error::invalid(
                file,
                "format",
                format!("{:?} is not {FORMAT:?}", record.format),
            ));
        }
        let mut record = record;
        let mut objects = Vec::with_capacity(record.objects.len());
        for (i, r) in std::mem::take(&mut record.objects).into_iter().enumerate() {
            let raw: Vec<(f64, f64)> = r
                .presence
                .iter()
                .map(|&[a, b]| (a.unwrap_or(f64::NEG_INFINITY), b.unwrap_or(f64::INFINITY)))
                .collect();
            let Some(presence) = Visibility::from_normalised(raw) else {
                return Err(Error::invalid(
                    file,
                    format!("objects[{i}].presence"),
                    "intervals must be non-empty, sorted, apart, and open-ended (null) only at \
                     the first start and the last end",
                ));
            };
            objects.push(ObjectEntry {
                id: r.id,
                name: r.name,
                class: r.class,
                properties: r.properties,
                visibility_class: r.visibility_class,
                tasks: r.tasks,
                presence,
                clusters: r.clusters,
            });
        }
        let rows = object_index::rows_of(&objects);
        ObjectTables::with_records(rows, record, tree, file)
    }

    /// The tables of a mapped `objects.bin`: its rows, and the tasks, dates
    /// and profile of its JSON section, checked against the tree's
    /// clusters; `file` names the file in errors.
    pub fn from_index(rows: ObjectRows, tree: &Tree, file: &Path) -> Result<Self> {
        let record: ObjectsRecord = serde_json::from_slice(rows.rest()).map_err(|e| {
            Error::invalid(file, format!("rest, column {}", e.column()), e.to_string())
        })?;
        if record.format != FORMAT || !record.objects.is_empty() {
            return Err(Error::invalid(
                file,
                "rest",
                format!("must be {FORMAT:?} tables with no objects of their own"),
            ));
        }
        ObjectTables::with_records(rows, record, tree, file)
    }

    /// The tables of `rows` and the tasks, dates and profile of `record`
    /// (whose objects are in the rows), checked.
    fn with_records(
        rows: ObjectRows,
        record: ObjectsRecord,
        tree: &Tree,
        file: &Path,
    ) -> Result<Self> {
        let mut tasks = Vec::with_capacity(record.tasks.len());
        for (k, r) in record.tasks.into_iter().enumerate() {
            let ifc_type = match &r.ifc_type {
                None => None,
                Some(name) => Some(
                    NamedType::parse(name)
                        .filter(|t| t.kind == r.kind)
                        .and_then(|t| t.ifc)
                        .ok_or_else(|| {
                            Error::invalid(
                                file,
                                format!("tasks[{k}].ifc_type"),
                                format!(
                                    "{name:?} is not an IFC task type that does {}",
                                    r.kind.name()
                                ),
                            )
                        })?,
                ),
            };
            tasks.push(TaskEntry {
                id: r.id,
                name: r.name,
                kind: r.kind,
                ifc_type,
                dates: TaskDates {
                    start: r.start,
                    finish: r.finish,
                    actual: Actual {
                        start: r.actual_start,
                        finish: r.actual_finish,
                    },
                    baseline: r
                        .baseline_start
                        .zip(r.baseline_finish)
                        .map(|(start, finish)| Span { start, finish }),
                },
                parent: r.parent,
                predecessors: r.predecessors,
                objects: r.objects,
            });
        }
        let appearance = record
            .appearance
            .map(|p| Profile::from_file(p, file, "appearance."))
            .transpose()?;
        let tables = ObjectTables::with_rows(rows, tasks, record.dates, appearance);
        tables.validate(tree, file)?;
        Ok(tables)
    }
}

/// Row indices sorted by id, equal ids by index: a look-up is a binary
/// search, and no id is copied.
#[derive(Debug, Clone, PartialEq, Default)]
struct ById(Vec<u32>);

impl ById {
    fn new<'a>(id: impl Fn(u32) -> &'a str, rows: usize) -> ById {
        let mut order: Vec<u32> = (0..rows as u32).collect();
        order.sort_unstable_by(|&a, &b| id(a).cmp(id(b)).then(a.cmp(&b)));
        ById(order)
    }

    /// The first row with this id.
    fn find<'a>(&self, id: impl Fn(u32) -> &'a str, key: &str) -> Option<u32> {
        let i = self.0.partition_point(|&r| id(r) < key);
        self.0.get(i).copied().filter(|&r| id(r) == key)
    }

    /// A row whose id an earlier row has, and that earlier row.
    fn duplicate<'a>(&self, id: impl Fn(u32) -> &'a str) -> Option<(u32, u32)> {
        self.0
            .windows(2)
            .find(|w| id(w[0]) == id(w[1]))
            .map(|w| (w[1], w[0]))
    }
}

/// The searchable strings of every row, lower-cased once and kept in one
/// buffer: a search is then a scan of slices, with no allocation per row.
#[derive(Debug, Clone, PartialEq, Default)]
struct SearchText {
    text: String,
    /// Row `i` is `text[ends[i - 1]..ends[i]]`.
    ends: Vec<usize>,
}

impl SearchText {
    fn new<'a, R: IntoIterator<Item = &'a str>>(rows: impl Iterator<Item = R>) -> SearchText {
        let mut out = SearchText::default();
        for row in rows {
            for field in row {
                // A separator no query holds (`search` matches nothing
                // for one that does), so that no match spans two fields.
                out.text.push('\0');
                push_lowercase(&mut out.text, field);
            }
            out.ends.push(out.text.len());
        }
        out
    }

    fn row(&self, i: usize) -> &str {
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        &self.text[start..self.ends[i]]
    }

    fn search(&self, query: &str, from: usize, limit: usize) -> Page {
        search_rows(self.ends.len(), |i| self.row(i), query, from, limit)
    }
}

/// The rows among `rows` whose text (`row`, lower-cased with fields
/// separated by NUL) contains `query` ignoring case, from `from` on, at
/// most `limit` of them: one page.
pub(crate) fn search_rows<'a>(
    rows: usize,
    row: impl Fn(usize) -> &'a str,
    query: &str,
    from: usize,
    limit: usize,
) -> Page {
    let mut lower = String::with_capacity(query.len());
    push_lowercase(&mut lower, query);
    let query = lower;
    let mut page = Page {
        items: Vec::with_capacity(limit.min(rows)),
        next: None,
        total: 0,
    };
    if query.is_empty() {
        page.items
            .extend((from..rows.min(from.saturating_add(limit))).map(|i| i as u32));
        page.next = Some(from.saturating_add(limit))
            .filter(|&i| i < rows)
            .map(|i| i as u32);
        page.total = rows;
        return page;
    }
    if query.contains('\0') {
        return page;
    }
    for i in 0..rows {
        if !row(i).contains(query.as_str()) {
            continue;
        }
        page.total += 1;
        if i < from || page.next.is_some() {
            continue;
        }
        if page.items.len() < limit {
            page.items.push(i as u32);
        } else {
            page.next = Some(i as u32);
        }
    }
    page
}

/// Appends `text` lower-cased. Most ids, names and values are ASCII, which
/// is lower-cased in place, with no allocation: the search text of a
/// paper-scale scene is made at every load.
pub(crate) fn push_lowercase(out: &mut String, text: &str) {
    if text.is_ascii() {
        let start = out.len();
        out.push_str(text);
        out[start..].make_ascii_lowercase();
    } else {
        out.push_str(&text.to_lowercase());
    }
}

/// `objects.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectsRecord {
    pub format: String,
    pub objects: Vec<ObjectRecord>,
    pub tasks: Vec<TaskRecord>,
    /// The dates the build's presence followed (planned when absent: trees
    /// written before the field).
    #[serde(default)]
    pub dates: Dates,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<ProfileFile>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectRecord {
    pub id: String,
    pub name: Option<String>,
    pub class: Option<String>,
    pub properties: BTreeMap<String, String>,
    pub visibility_class: Class,
    pub tasks: Vec<u32>,
    /// Half-open intervals `[start, end)`, `null` for an open end.
    pub presence: Vec<[Option<f64>; 2]>,
    pub clusters: Vec<u32>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskRecord {
    pub id: String,
    pub name: Option<String>,
    #[serde(rename = "type")]
    pub kind: TaskType,
    /// The IFC task type its schedule named (`INSTALLATION`), when it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ifc_type: Option<String>,
    pub start: f64,
    pub finish: f64,
    pub start_date: String,
    pub finish_date: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actual_start: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actual_finish: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline_start: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline_finish: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parent: Option<u32>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub predecessors: Vec<LinkEntry>,
    pub objects: Vec<u32>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One object under three construct tasks: [0, 10), [5, 20) and
    /// [30, 40); the second recorded as started late.
    fn tables(dates: Dates) -> ObjectTables {
        let task = |k: u32, start: f64, finish: f64, actual: Actual| TaskEntry {
            id: format!("T{k}"),
            name: None,
            kind: TaskType::Construct,
            ifc_type: None,
            dates: TaskDates {
                start,
                finish,
                actual,
                baseline: None,
            },
            parent: None,
            predecessors: Vec::new(),
            objects: vec![0],
        };
        let late = Actual {
            start: Some(8.0),
            finish: Some(25.0),
        };
        ObjectTables::new(
            vec![ObjectEntry {
                id: "E".into(),
                name: None,
                class: None,
                properties: BTreeMap::new(),
                visibility_class: Class::PseudoDynamic,
                tasks: vec![0, 1, 2],
                presence: Visibility::always(),
                clusters: vec![],
            }],
            vec![
                task(0, 0.0, 10.0, Actual::default()),
                task(1, 5.0, 20.0, late),
                task(2, 30.0, 40.0, Actual::default()),
            ],
            dates,
            None,
        )
    }

    #[test]
    fn the_governing_task_is_the_latest_running_then_the_latest_finished_then_the_next() {
        let t = tables(Dates::Planned);
        assert_eq!(t.governing_task(0, 2.0), Some(0));
        assert_eq!(t.governing_task(0, 6.0), Some(1));
        assert_eq!(t.governing_task(0, 25.0), Some(1));
        assert_eq!(t.governing_task(0, 35.0), Some(2));
        // On the record task 0 never started and task 1 started at 8: at 6
        // task 1 is the next to start.
        let t = tables(Dates::Actual);
        assert_eq!(t.governing_task(0, 6.0), Some(1));
        assert_eq!(t.governing_task(0, 9.0), Some(1));
        assert_eq!(t.governing_task(0, 27.0), Some(1));
    }

    #[test]
    fn an_element_takes_its_governing_tasks_look() {
        let t = tables(Dates::Planned);
        let mut profile = Profile::default();
        let red = Look::Colour {
            rgb: [255, 0, 0],
            transparency: 0.0,
        };
        profile.types[TaskType::Construct.index()].late = Some(red);
        // At 6 task 1 runs on the plan but the record has not started it.
        let s = t.state_at(0, 6.0, &profile);
        assert_eq!(
            (s.task, s.progress, s.deviation, s.look),
            (Some(1), Some(Progress::Active), Some(Deviation::Late), red)
        );
        let s = t.state_at(0, 12.0, &profile);
        assert_eq!(s.deviation, Some(Deviation::OnTime));
        assert_eq!(s.look, Profile::default().types[0].active);
        let s = t.state_at(0, 45.0, &profile);
        assert_eq!((s.task, s.look), (Some(2), Look::Model));
    }
}

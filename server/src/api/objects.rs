//! The object and task tables of a scene's tree (`hdlod::tree::objects`;
//! docs/api.md):
//!
//! - `GET /api/v1/scenes/{scene}/objects?q=&limit=&cursor=`: a search,
//!   one page at a time;
//! - `GET /api/v1/scenes/{scene}/objects/{id}?time=&by=`: one object, by
//!   its id (or its index with `by=index`), and its state at `time`;
//! - `GET /api/v1/scenes/{scene}/tasks?q=&limit=&cursor=` and
//!   `.../tasks/{id}?time=&by=`: the same for tasks.
//!
//! A tree without `objects.json` answers them with 404.

use std::collections::BTreeMap;
use std::sync::Arc;

use axum::Json;
use axum::extract::{FromRequestParts, State};
use axum::http::request::Parts;
use axum::response::{IntoResponse, Response};
use hdlod::scene::status::{Deviation, Progress};
use hdlod::scene::{Class, property};
use hdlod::time::{TimeValue, format_date};
use hdlod::tree::object_index::ObjectRows;
use hdlod::tree::objects::{LinkEntry, ObjectTables, TaskEntry};
use serde::Serialize;

use super::error::{ApiError, quote};
use super::extract::{Pairs, Segments};
use super::handlers::find;
use super::{AppState, LoadedScene};
use crate::protocol::{parse_time, resolve_time, scene_path, segment};

type Answer = Result<Response, ApiError>;

/// Matches per page unless `limit` says otherwise, and the most it may say.
const DEFAULT_LIMIT: usize = 50;
const MAX_LIMIT: usize = 1000;

/// A cursor is the index the next page's scan starts at, behind a prefix
/// that keeps clients from taking it for an index.
const CURSOR_PREFIX: &str = "i";

/// The query parameters, each parsed by its name; an unknown one is an
/// error naming it.
fn query_pairs(parts: &Parts) -> Result<Vec<(String, String)>, ApiError> {
    Pairs::from_parts(parts).map(|Pairs(pairs)| pairs)
}

/// `?q=TEXT&limit=N&cursor=C` of a listing.
pub struct Listing {
    q: String,
    limit: usize,
    from: usize,
}

impl<S: Send + Sync> FromRequestParts<S> for Listing {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        let mut listing = Listing {
            q: String::new(),
            limit: DEFAULT_LIMIT,
            from: 0,
        };
        for (key, value) in query_pairs(parts)? {
            match key.as_str() {
                "q" => listing.q = value,
                "limit" => {
                    listing.limit = value
                        .parse()
                        .ok()
                        .filter(|n| (1..=MAX_LIMIT).contains(n))
                        .ok_or_else(|| {
                            ApiError::bad(
                                "limit",
                                format!(
                                    "{} is not a whole number from 1 to {MAX_LIMIT}",
                                    quote(&value)
                                ),
                            )
                        })?
                }
                "cursor" => {
                    listing.from = value
                        .strip_prefix(CURSOR_PREFIX)
                        .and_then(|n| n.parse().ok())
                        .ok_or_else(|| {
                            ApiError::bad(
                                "cursor",
                                format!("{} is not a cursor this API gave (`next`)", quote(&value)),
                            )
                        })?
                }
                other => return Err(ApiError::bad(other, "unknown query parameter")),
            }
        }
        Ok(listing)
    }
}

/// `?time=T&by=id|index` of a single object or task.
pub struct Lookup {
    time: Option<TimeValue>,
    by_index: bool,
}

impl<S: Send + Sync> FromRequestParts<S> for Lookup {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        let mut lookup = Lookup {
            time: None,
            by_index: false,
        };
        for (key, value) in query_pairs(parts)? {
            match key.as_str() {
                "time" => lookup.time = Some(parse_time(&value)),
                "by" => {
                    lookup.by_index = match value.as_str() {
                        "id" => false,
                        "index" => true,
                        _ => {
                            return Err(ApiError::bad(
                                "by",
                                format!("{} is neither \"id\" nor \"index\"", quote(&value)),
                            ));
                        }
                    }
                }
                other => return Err(ApiError::bad(other, "unknown query parameter")),
            }
        }
        Ok(lookup)
    }
}

/// The scene's tables: a tree built without them is a 404 that says so.
pub(super) fn tables(s: &LoadedScene) -> Result<&ObjectTables, ApiError> {
    s.tree.objects.as_ref().ok_or_else(|| {
        ApiError::not_found(
            "scene",
            format!(
                "the tree of scene {:?} has no object and task tables (objects.json); \
                 trees built by this version of hdlod build have them",
                s.tree.scene
            ),
        )
    })
}

/// The row `key` names: its id, or its index with `by=index`. `what` is
/// "object" or "task".
fn row(
    key: &str,
    by_index: bool,
    rows: usize,
    index_of: impl Fn(&str) -> Option<u32>,
    what: &str,
) -> Result<u32, ApiError> {
    if !by_index {
        return index_of(key)
            .ok_or_else(|| ApiError::not_found("id", format!("no {what} with id {}", quote(key))));
    }
    let i: u32 = key.parse().map_err(|_| {
        ApiError::bad(
            "id",
            format!(
                "{} is not an index (a whole number), as by=index asks",
                quote(key)
            ),
        )
    })?;
    if i as usize >= rows {
        return Err(ApiError::not_found(
            "id",
            format!("no {what} at index {i}: there are {rows}"),
        ));
    }
    Ok(i)
}

fn object_url(scene: &str, id: &str) -> String {
    format!("{}/objects/{}", scene_path(scene), segment(id))
}

fn task_url(scene: &str, id: &str) -> String {
    format!("{}/tasks/{}", scene_path(scene), segment(id))
}

fn next_cursor(next: Option<u32>) -> Option<String> {
    next.map(|i| format!("{CURSOR_PREFIX}{i}"))
}

fn json<T: Serialize>(value: &T) -> Answer {
    Ok(Json(value).into_response())
}

#[derive(Serialize)]
struct ObjectItem<'a> {
    index: u32,
    id: &'a str,
    name: Option<&'a str>,
    class: Option<&'a str>,
    /// The `storey` property, which the viewer colours by.
    storey: Option<&'a str>,
    visibility_class: Class,
    url: String,
}

impl<'a> ObjectItem<'a> {
    fn of(scene: &str, rows: &'a ObjectRows, index: u32) -> Self {
        ObjectItem {
            index,
            id: rows.id(index),
            name: rows.name(index),
            class: rows.class(index),
            storey: rows.property(index, property::STOREY),
            visibility_class: rows.visibility_class(index),
            url: object_url(scene, rows.id(index)),
        }
    }
}

#[derive(Serialize)]
struct TaskItem<'a> {
    index: u32,
    id: &'a str,
    name: Option<&'a str>,
    #[serde(rename = "type")]
    kind: &'static str,
    /// The IFC task type its schedule named, when it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    ifc_type: Option<&'static str>,
    start: f64,
    finish: f64,
    start_date: String,
    finish_date: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    actual_start: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    actual_finish: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    baseline_start: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    baseline_finish: Option<f64>,
    /// The index of its summary task.
    #[serde(skip_serializing_if = "Option::is_none")]
    parent: Option<u32>,
    /// The tasks it follows, by index.
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    predecessors: &'a [LinkEntry],
    url: String,
    /// Where it stands at the request's time, when one is given, on the
    /// dates the tree was built on.
    #[serde(skip_serializing_if = "Option::is_none")]
    state: Option<Progress>,
    /// Against its plan at that time, when it has actual dates.
    #[serde(skip_serializing_if = "Option::is_none")]
    deviation: Option<Deviation>,
}

impl<'a> TaskItem<'a> {
    fn of(
        s: &LoadedScene,
        tables: &ObjectTables,
        index: u32,
        t: &'a TaskEntry,
        at: Option<f64>,
    ) -> Self {
        let date = |x: f64| format_date(s.tree.time.date_at(x));
        let d = &t.dates;
        TaskItem {
            index,
            id: &t.id,
            name: t.name.as_deref(),
            kind: t.kind.name(),
            ifc_type: t.ifc_type,
            start: d.start,
            finish: d.finish,
            start_date: date(d.start),
            finish_date: date(d.finish),
            actual_start: d.actual.start,
            actual_finish: d.actual.finish,
            baseline_start: d.baseline.map(|b| b.start),
            baseline_finish: d.baseline.map(|b| b.finish),
            parent: t.parent,
            predecessors: &t.predecessors,
            url: task_url(&s.tree.scene, &t.id),
            state: at.map(|x| d.progress(x, tables.dates())),
            deviation: at.and_then(|x| d.deviation(x)),
        }
    }
}

#[derive(Serialize)]
struct Listed<T> {
    scene: String,
    q: String,
    /// Matches in the whole table.
    total: usize,
    items: Vec<T>,
    /// The cursor of the next page; null on the last.
    next: Option<String>,
}

pub async fn objects(
    State(state): State<Arc<AppState>>,
    Segments(scene): Segments<String>,
    listing: Listing,
) -> Answer {
    let s = find(&state, &scene)?;
    let tables = tables(&s)?;
    let page = tables.search_objects(&listing.q, listing.from, listing.limit);
    json(&Listed {
        items: page
            .items
            .iter()
            .map(|&i| ObjectItem::of(&s.tree.scene, tables.rows(), i))
            .collect(),
        scene: s.tree.scene.clone(),
        q: listing.q,
        total: page.total,
        next: next_cursor(page.next),
    })
}

pub async fn tasks(
    State(state): State<Arc<AppState>>,
    Segments(scene): Segments<String>,
    listing: Listing,
) -> Answer {
    let s = find(&state, &scene)?;
    let tables = tables(&s)?;
    let page = tables.search_tasks(&listing.q, listing.from, listing.limit);
    json(&Listed {
        items: page
            .items
            .iter()
            .map(|&i| TaskItem::of(&s, tables, i, &tables.tasks()[i as usize], None))
            .collect(),
        scene: s.tree.scene.clone(),
        q: listing.q,
        total: page.total,
        next: next_cursor(page.next),
    })
}

/// The request's time in seconds and as a date.
#[derive(Serialize)]
struct At {
    time: f64,
    date: String,
}

fn at(s: &LoadedScene, time: &Option<TimeValue>) -> Result<Option<At>, ApiError> {
    time.as_ref()
        .map(|time| {
            let t = resolve_time(&s.tree, "time", time)?;
            Ok(At {
                time: t,
                date: format_date(s.tree.time.date_at(t)),
            })
        })
        .transpose()
}

#[derive(Serialize)]
struct ObjectAnswer<'a> {
    scene: &'a str,
    #[serde(flatten)]
    item: ObjectItem<'a>,
    properties: &'a BTreeMap<String, String>,
    /// `[start, end)` in seconds, null for an open end.
    presence: Vec<[Option<f64>; 2]>,
    clusters: &'a [u32],
    /// Each with its state at the request's time, when one is given.
    tasks: Vec<TaskItem<'a>>,
    /// The request's time; null without one.
    at: Option<At>,
    /// Whether it is present at the request's time, when one is given.
    #[serde(skip_serializing_if = "Option::is_none")]
    present: Option<bool>,
}

pub async fn object(
    State(state): State<Arc<AppState>>,
    Segments((scene, key)): Segments<(String, String)>,
    lookup: Lookup,
) -> Answer {
    let s = find(&state, &scene)?;
    let tables = tables(&s)?;
    let i = row(
        &key,
        lookup.by_index,
        tables.object_count(),
        |id| tables.object_index(id),
        "object",
    )?;
    let o = tables.object(i);
    let at = at(&s, &lookup.time)?;
    let t = at.as_ref().map(|a| a.time);
    json(&ObjectAnswer {
        scene: &s.tree.scene,
        item: ObjectItem::of(&s.tree.scene, tables.rows(), i),
        properties: &o.properties,
        presence: o.open_presence(),
        clusters: &o.clusters,
        tasks: o
            .tasks
            .iter()
            .map(|&k| TaskItem::of(&s, tables, k, &tables.tasks()[k as usize], t))
            .collect(),
        present: t.map(|t| o.presence.at(t)),
        at,
    })
}

#[derive(Serialize)]
struct ObjectRef<'a> {
    index: u32,
    id: &'a str,
}

#[derive(Serialize)]
struct TaskAnswer<'a> {
    scene: &'a str,
    #[serde(flatten)]
    item: TaskItem<'a>,
    objects: Vec<ObjectRef<'a>>,
    /// The request's time, when given; the task's `state` is at it.
    at: Option<At>,
}

pub async fn task(
    State(state): State<Arc<AppState>>,
    Segments((scene, key)): Segments<(String, String)>,
    lookup: Lookup,
) -> Answer {
    let s = find(&state, &scene)?;
    let tables = tables(&s)?;
    let k = row(
        &key,
        lookup.by_index,
        tables.tasks().len(),
        |id| tables.task_index(id),
        "task",
    )?;
    let task = &tables.tasks()[k as usize];
    let at = at(&s, &lookup.time)?;
    json(&TaskAnswer {
        scene: &s.tree.scene,
        item: TaskItem::of(&s, tables, k, task, at.as_ref().map(|a| a.time)),
        objects: task
            .objects
            .iter()
            .map(|&i| ObjectRef {
                index: i,
                id: tables.rows().id(i),
            })
            .collect(),
        at,
    })
}

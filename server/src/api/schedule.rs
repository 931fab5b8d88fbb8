//! The schedule of a scene in one answer, for a 4D review (docs/api.md):
//!
//! - `GET /api/v1/scenes/{scene}/schedule`: every task with its planned,
//!   actual and baseline dates, its summary task and its objects' feature
//!   indices. The viewer works each feature's status and look out from it
//!   at every frame, so scrubbing time costs no request beyond the cut.
//! - `GET /api/v1/scenes/{scene}/appearance`: the scene's appearance
//!   profile (`hdlod-appearance/1`), or the default one.
//!
//! Both bodies are made once per loaded tree and sent with an ETag: a
//! reload makes new ones, a client that has the current one gets 304.

use std::sync::Arc;

use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::Response;
use hdlod::scene::status::Dates;
use hdlod::time::format_date;
use hdlod::tree::ObjectTables;
use hdlod::tree::objects::LinkEntry;
use serde::Serialize;

use super::cached::Cached;
use super::error::ApiError;
use super::extract::{Pairs, Segments};
use super::handlers::find;
use super::objects::tables;
use super::{AppState, LoadedScene};

#[derive(Serialize)]
struct ScheduleAnswer<'a> {
    scene: &'a str,
    /// The scene's start date; every time is in seconds since it.
    start: String,
    /// The span's length in seconds.
    seconds: f64,
    /// The dates the tree's presence follows.
    dates: Dates,
    tasks: Vec<TaskRow<'a>>,
}

#[derive(Serialize)]
struct TaskRow<'a> {
    id: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    name: Option<&'a str>,
    #[serde(rename = "type")]
    kind: &'static str,
    /// The IFC task type its schedule named, when it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    ifc_type: Option<&'static str>,
    start: f64,
    finish: f64,
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
    /// The tasks it follows, by index, with the link's type and lag.
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    predecessors: &'a [LinkEntry],
    /// Its objects' indices (the feature ids of their vertices).
    objects: &'a [u32],
}

fn schedule_of(s: &LoadedScene, tables: &ObjectTables) -> Cached {
    let time = &s.tree.time;
    Cached::of(&ScheduleAnswer {
        scene: &s.tree.scene,
        start: format_date(time.start),
        seconds: time.seconds,
        dates: tables.dates(),
        tasks: tables
            .tasks()
            .iter()
            .map(|t| {
                let d = &t.dates;
                TaskRow {
                    id: &t.id,
                    name: t.name.as_deref(),
                    kind: t.kind.name(),
                    ifc_type: t.ifc_type,
                    start: d.start,
                    finish: d.finish,
                    actual_start: d.actual.start,
                    actual_finish: d.actual.finish,
                    baseline_start: d.baseline.map(|b| b.start),
                    baseline_finish: d.baseline.map(|b| b.finish),
                    parent: t.parent,
                    predecessors: &t.predecessors,
                    objects: &t.objects,
                }
            })
            .collect(),
    })
}

/// The scene a route names, for a request that takes no query parameter.
fn scene_of(
    state: &AppState,
    scene: String,
    pairs: Vec<(String, String)>,
) -> Result<Arc<LoadedScene>, ApiError> {
    if let Some((key, _)) = pairs.first() {
        return Err(ApiError::bad(key.as_str(), "unknown query parameter"));
    }
    find(state, &scene)
}

pub async fn schedule(
    State(state): State<Arc<AppState>>,
    Segments(scene): Segments<String>,
    Pairs(pairs): Pairs,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let s = scene_of(&state, scene, pairs)?;
    let tables = tables(&s)?;
    Ok(s.schedule
        .get_or_init(|| schedule_of(&s, tables))
        .answer(&headers))
}

pub async fn appearance(
    State(state): State<Arc<AppState>>,
    Segments(scene): Segments<String>,
    Pairs(pairs): Pairs,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let s = scene_of(&state, scene, pairs)?;
    let own = s.tree.objects.as_ref().and_then(ObjectTables::appearance);
    Ok(s.appearance
        .get_or_init(|| Cached::of(&own.cloned().unwrap_or_default().to_file()))
        .answer(&headers))
}

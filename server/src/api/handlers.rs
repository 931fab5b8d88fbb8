//! The request handlers: each parses, looks the scene up in a snapshot of
//! the state and answers JSON (or an [`ApiError`]).

use std::sync::{Arc, OnceLock};

use axum::Json;
use axum::body::{Body, Bytes};
use axum::extract::State;
use axum::extract::rejection::BytesRejection;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use hdlod::time::format_date;
use serde_json::{Value, json};

use super::error::{ApiError, quote};
use super::extract::{Pairs, Segments};
use super::{AppState, LoadedScene};
use crate::protocol::{self, CutRequest, scene_path};

type Answer<T> = Result<T, ApiError>;

pub fn find(state: &AppState, name: &str) -> Answer<Arc<LoadedScene>> {
    state
        .scenes()
        .get(name)
        .cloned()
        .ok_or_else(|| ApiError::not_found("scene", format!("no scene named {}", quote(name))))
}

fn time_json(scene: &LoadedScene) -> Value {
    let t = &scene.tree.time;
    json!({"start": format_date(t.start), "end": format_date(t.end()), "seconds": t.seconds})
}

pub async fn healthz(State(state): State<Arc<AppState>>) -> Json<Value> {
    Json(json!({"status": "ok", "scenes": state.scenes().len()}))
}

pub async fn metrics(State(state): State<Arc<AppState>>) -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        state.metrics.render(),
    )
}

/// `schemas/api/openapi.json` with every `components.schemas` entry that
/// refers to a schema file replaced by that file (the schemas live once,
/// in `schemas/api/`). Each file's references (`#/$defs/vec3`,
/// `task-list.schema.json#/$defs/task`, `error.schema.json`) are rewritten
/// to point into the document (`#/components/schemas/TaskList/$defs/task`)
/// and the files' `$id`s dropped: a client resolves every `$ref` of the
/// served document within it, without knowing the files.
pub fn openapi_document() -> &'static Value {
    static DOC: OnceLock<Value> = OnceLock::new();
    DOC.get_or_init(|| {
        let files: [(&str, &str); 14] = [
            (
                "error.schema.json",
                include_str!("../../../schemas/api/error.schema.json"),
            ),
            (
                "health.schema.json",
                include_str!("../../../schemas/api/health.schema.json"),
            ),
            (
                "scene-list.schema.json",
                include_str!("../../../schemas/api/scene-list.schema.json"),
            ),
            (
                "scene.schema.json",
                include_str!("../../../schemas/api/scene.schema.json"),
            ),
            (
                "cut-request.schema.json",
                include_str!("../../../schemas/api/cut-request.schema.json"),
            ),
            (
                "cut-response.schema.json",
                include_str!("../../../schemas/api/cut-response.schema.json"),
            ),
            (
                "stream-message.schema.json",
                include_str!("../../../schemas/api/stream-message.schema.json"),
            ),
            (
                "object-list.schema.json",
                include_str!("../../../schemas/api/object-list.schema.json"),
            ),
            (
                "object.schema.json",
                include_str!("../../../schemas/api/object.schema.json"),
            ),
            (
                "task-list.schema.json",
                include_str!("../../../schemas/api/task-list.schema.json"),
            ),
            (
                "task.schema.json",
                include_str!("../../../schemas/api/task.schema.json"),
            ),
            (
                "presence.schema.json",
                include_str!("../../../schemas/api/presence.schema.json"),
            ),
            (
                "schedule.schema.json",
                include_str!("../../../schemas/api/schedule.schema.json"),
            ),
            (
                "../appearance.schema.json",
                include_str!("../../../schemas/appearance.schema.json"),
            ),
        ];
        let mut doc: Value =
            serde_json::from_str(include_str!("../../../schemas/api/openapi.json"))
                .expect("schemas/api/openapi.json is JSON (checked by the tests)");
        let Some(Value::Object(schemas)) = doc.pointer_mut("/components/schemas") else {
            return doc;
        };
        // Schema file -> its component's name.
        let names: Vec<(String, String)> = schemas
            .iter()
            .filter_map(|(name, schema)| {
                let file = schema.get("$ref")?.as_str()?.trim_start_matches("./");
                Some((file.to_owned(), name.clone()))
            })
            .collect();
        for (name, schema) in schemas.iter_mut() {
            let file = schema
                .get("$ref")
                .and_then(Value::as_str)
                .map(|r| r.trim_start_matches("./").to_owned());
            if let Some((_, text)) = file.and_then(|f| files.iter().find(|(n, _)| *n == f)) {
                let mut inlined: Value = serde_json::from_str(text)
                    .expect("schema files are JSON (checked by the tests)");
                if let Value::Object(o) = &mut inlined {
                    o.remove("$id");
                    o.remove("$schema");
                }
                rebase(&mut inlined, name, &names);
                *schema = inlined;
            }
        }
        doc
    })
}

/// Points every `$ref` of the schema of component `own` into the
/// document: `#/...` at its own component, `FILE#/...` at the file's.
fn rebase(value: &mut Value, own: &str, names: &[(String, String)]) {
    match value {
        Value::Object(o) => {
            if let Some(Value::String(r)) = o.get_mut("$ref") {
                let (file, pointer) = r.split_once('#').unwrap_or((r.as_str(), ""));
                let file = file.trim_start_matches("./");
                let component = if file.is_empty() {
                    Some(own)
                } else {
                    // `../appearance.schema.json` is listed under that name.
                    names
                        .iter()
                        .find(|(f, _)| {
                            f.trim_start_matches("../") == file.trim_start_matches("../")
                        })
                        .map(|(_, n)| n.as_str())
                };
                if let Some(component) = component {
                    *r = format!("#/components/schemas/{component}{pointer}");
                }
            }
            for v in o.values_mut() {
                rebase(v, own, names);
            }
        }
        Value::Array(a) => a.iter_mut().for_each(|v| rebase(v, own, names)),
        _ => {}
    }
}

pub async fn openapi() -> Json<Value> {
    Json(openapi_document().clone())
}

pub async fn scenes(State(state): State<Arc<AppState>>) -> Json<Value> {
    let list: Vec<Value> = state
        .scenes()
        .values()
        .map(|s| {
            json!({
                "name": s.tree.scene,
                "url": scene_path(&s.tree.scene),
                "time": time_json(s),
                "clusters": s.summary.clusters,
            })
        })
        .collect();
    Json(json!({"scenes": list}))
}

pub async fn scene(
    State(state): State<Arc<AppState>>,
    Segments(name): Segments<String>,
) -> Answer<Json<Value>> {
    let s = find(&state, &name)?;
    let tree = &s.tree;
    let b = &tree.bounds;
    Ok(Json(json!({
        "name": tree.scene,
        "time": time_json(&s),
        "bounds": {"min": b.min.to_array(), "max": b.max.to_array()},
        "up": tree.up,
        "georeference": tree.georeference,
        "root": tree.root,
        "clusters": s.summary.clusters,
        "leaves": s.summary.leaves,
        "leaf_triangles": s.summary.leaf_triangles,
        "classes": s.summary.classes,
        "levels": s.summary.levels,
        "cut": format!("{}/cut", scene_path(&tree.scene)),
        "stream": format!("{}/stream", scene_path(&tree.scene)),
    })))
}

fn cut_answer(state: &AppState, s: &LoadedScene, request: &CutRequest) -> Answer<Response> {
    let mut body = Vec::new();
    let stats = protocol::write_answer(&s.tree, &s.baseline, &s.fragments, request, &mut body)?;
    state.metrics.cut(stats.clusters, stats.triangles);
    Ok((
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/json"),
        )],
        body,
    )
        .into_response())
}

pub async fn cut_post(
    State(state): State<Arc<AppState>>,
    Segments(name): Segments<String>,
    body: Result<Bytes, BytesRejection>,
) -> Answer<Response> {
    let body = body.map_err(|r| ApiError::new(r.status(), Some("body".into()), r.body_text()))?;
    // The scene is checked first: an unknown scene is a 404 whatever the body.
    let s = find(&state, &name)?;
    cut_answer(&state, &s, &protocol::parse_json(&body)?)
}

pub async fn cut_get(
    State(state): State<Arc<AppState>>,
    Segments(name): Segments<String>,
    Pairs(pairs): Pairs,
) -> Answer<Response> {
    let s = find(&state, &name)?;
    cut_answer(&state, &s, &protocol::parse_query(&pairs)?)
}

/// Content that never changes under its URL: cached for a year.
pub(super) fn immutable() -> HeaderValue {
    HeaderValue::from_static("public, max-age=31536000, immutable")
}

/// `304 Not Modified` when the request already holds `etag` of immutable
/// content.
pub(super) fn not_modified(headers: &HeaderMap, etag: &HeaderValue) -> Option<Response> {
    let matches = headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| {
            v.split(',')
                .any(|t| t.trim().as_bytes() == etag.as_bytes() || t.trim() == "*")
        });
    matches.then(|| {
        (
            StatusCode::NOT_MODIFIED,
            [
                (header::ETAG, etag.clone()),
                (header::CACHE_CONTROL, immutable()),
            ],
        )
            .into_response()
    })
}

/// A GLB that never changes under its URL, with its ETag.
pub(super) fn immutable_glb(etag: HeaderValue, bytes: Vec<u8>) -> Response {
    (
        [
            (
                header::CONTENT_TYPE,
                HeaderValue::from_static("model/gltf-binary"),
            ),
            (header::ETAG, etag),
            (header::CACHE_CONTROL, immutable()),
        ],
        Body::from(bytes),
    )
        .into_response()
}

pub async fn not_found() -> ApiError {
    ApiError::not_found("path", "no such endpoint")
}

pub async fn method_not_allowed() -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        Some("method".into()),
        "method not allowed here",
    )
}

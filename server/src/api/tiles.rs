//! Time slices as 3D Tiles 1.1 (`hdlod::tiles`; docs/tiles.md):
//!
//! - `GET /api/v1/scenes/{scene}/tiles/tileset.json?time=T`: the root
//!   tileset at `T` (ISO 8601 or seconds);
//! - `GET /api/v1/scenes/{scene}/tiles/{seconds}/{id}.json`: its external
//!   tilesets, which the root file names relatively (`{seconds}/{id}.json`),
//!   so a client follows them without knowing this layout.
//!
//! Content URIs point at the geometry endpoint (`../geometry/HASH.glb` from
//! the root file), whose GLBs are content-addressed and cached forever.

use std::sync::Arc;

use axum::Json;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, State};
use hdlod::tiles::{Options, Tileset, time_slice};
use hdlod::tree::Tree;

use super::AppState;
use super::cut::parse_time;
use super::error::ApiError;
use super::handlers::find;

/// Dates are computed in milliseconds; keep far from their overflow.
const MAX_SECONDS: f64 = 1e12;

/// The options of a slice at `t` served from `.../tiles/tileset.json`: the
/// external tilesets sit in `.../tiles/{t}/`, the GLBs in `.../geometry/`.
fn options(t: f64) -> Options {
    Options::new("../geometry", format!("{t}"))
}

fn within(t: f64) -> Result<f64, ApiError> {
    if t.abs() > MAX_SECONDS {
        return Err(ApiError::bad("time", "is too far from the scene's period"));
    }
    Ok(t)
}

fn seconds(tree: &Tree, text: &str) -> Result<f64, ApiError> {
    let t = tree
        .time
        .resolve(&parse_time(text))
        .map_err(|m| ApiError::bad("time", m))?;
    within(t)
}

pub async fn tileset(
    State(state): State<Arc<AppState>>,
    Path(name): Path<String>,
    query: Result<Query<Vec<(String, String)>>, QueryRejection>,
) -> Result<Json<Tileset>, ApiError> {
    let Query(pairs) = query.map_err(|r| ApiError::bad("query", r.body_text()))?;
    let s = find(&state, &name)?;
    let mut time = None;
    for (key, value) in &pairs {
        match key.as_str() {
            "time" => time = Some(value),
            other => return Err(ApiError::bad(other, "unknown query parameter")),
        }
    }
    let time = time.ok_or_else(|| ApiError::bad("time", "is required"))?;
    let t = seconds(&s.tree, time)?;
    Ok(Json(time_slice(&s.tree, t, &options(t))?.root))
}

pub async fn external(
    State(state): State<Arc<AppState>>,
    Path((name, time, file)): Path<(String, String, String)>,
) -> Result<Json<Tileset>, ApiError> {
    let s = find(&state, &name)?;
    let t = time
        .parse::<f64>()
        .ok()
        .filter(|t| t.is_finite())
        .ok_or_else(|| {
            ApiError::not_found("time", format!("{time:?} is not a number of seconds"))
        })?;
    let t = within(t)?;
    let id: u32 = file
        .strip_suffix(".json")
        .and_then(|id| id.parse().ok())
        .ok_or_else(|| ApiError::not_found("subtree", format!("{file:?} is not ID.json")))?;
    let mut slice = time_slice(&s.tree, t, &options(t))?;
    slice.external.remove(&id).map(Json).ok_or_else(|| {
        ApiError::not_found(
            "subtree",
            format!("no external tileset {id} in the slice at {t} s"),
        )
    })
}

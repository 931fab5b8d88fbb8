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
use hdlod::tiles::{DEFAULT_MAX_BYTES, Options, Tileset, time_slice};
use hdlod::time::TimeValue;
use hdlod::tree::Tree;

use super::AppState;
use super::error::ApiError;
use super::handlers::find;
use crate::protocol::{parse_time_query, resolve_time, within_period};

/// The options of a slice at `t` served from `.../tiles/tileset.json`: the
/// external tilesets sit in `.../tiles/{t}/`, the GLBs in `.../geometry/`.
fn options(t: f64, max_bytes: usize) -> Options {
    Options {
        max_bytes,
        ..Options::new("../geometry", format!("{t}"))
    }
}

/// The root file for the query's `time`.
fn root_file(tree: &Tree, time: &TimeValue, max_bytes: usize) -> Result<Tileset, ApiError> {
    let t = resolve_time(tree, "time", time)?;
    Ok(time_slice(tree, t, &options(t, max_bytes))?.root)
}

/// The external file `{time}/{file}` that a root file names.
fn external_file(
    tree: &Tree,
    time: &str,
    file: &str,
    max_bytes: usize,
) -> Result<Tileset, ApiError> {
    let t = time
        .parse::<f64>()
        .ok()
        .filter(|t| t.is_finite())
        .ok_or_else(|| {
            ApiError::not_found("time", format!("{time:?} is not a number of seconds"))
        })?;
    let t = within_period("time", t)?;
    let id: u32 = file
        .strip_suffix(".json")
        .and_then(|id| id.parse().ok())
        .ok_or_else(|| ApiError::not_found("subtree", format!("{file:?} is not ID.json")))?;
    let mut slice = time_slice(tree, t, &options(t, max_bytes))?;
    slice.external.remove(&id).ok_or_else(|| {
        ApiError::not_found(
            "subtree",
            format!("no external tileset {id} in the slice at {t} s"),
        )
    })
}

pub async fn tileset(
    State(state): State<Arc<AppState>>,
    Path(name): Path<String>,
    query: Result<Query<Vec<(String, String)>>, QueryRejection>,
) -> Result<Json<Tileset>, ApiError> {
    let Query(pairs) = query.map_err(|r| ApiError::bad("query", r.body_text()))?;
    let s = find(&state, &name)?;
    let time = parse_time_query(&pairs)?;
    root_file(&s.tree, &time, DEFAULT_MAX_BYTES).map(Json)
}

pub async fn external(
    State(state): State<Arc<AppState>>,
    Path((name, time, file)): Path<(String, String, String)>,
) -> Result<Json<Tileset>, ApiError> {
    let s = find(&state, &name)?;
    external_file(&s.tree, &time, &file, DEFAULT_MAX_BYTES).map(Json)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every stub URI of a split slice, resolved as a client does from the
    /// file that holds it, names an external file the server answers.
    #[test]
    fn stub_uris_name_served_files() {
        let dir = tempfile::tempdir().unwrap();
        let tree = hdlod_fixtures::sample::write_sample_tree(&dir.path().join("t"), 2, 6).unwrap();
        let small = 8 * 1024;
        let t = tree.time.seconds / 2.0;
        let mut pending: Vec<(Option<String>, Tileset)> = vec![(
            None,
            root_file(&tree, &TimeValue::Seconds(t), small).unwrap(),
        )];
        let mut served = 0;
        while let Some((dir, tileset)) = pending.pop() {
            let mut stack = vec![&tileset.root];
            while let Some(tile) = stack.pop() {
                stack.extend(&tile.children);
                let Some(uri) = tile.content.as_ref().map(|c| c.uri.as_str()) else {
                    continue;
                };
                if let Some(file) = uri.strip_suffix(".json") {
                    let path = match &dir {
                        None => file.to_owned(),
                        Some(d) => format!("{d}/{file}"),
                    };
                    let (time, id) = path.split_once('/').expect("tiles/{time}/{id}.json");
                    let next = external_file(&tree, time, &format!("{id}.json"), small).unwrap();
                    assert_eq!(next.root.extras.unwrap().cluster.to_string(), id);
                    pending.push((Some(time.to_owned()), next));
                    served += 1;
                } else {
                    let depth = if dir.is_some() { "../../" } else { "../" };
                    assert!(uri.starts_with(&format!("{depth}geometry/")), "{uri}");
                }
            }
        }
        assert!(served > 1, "the slice was split ({served} files)");
    }
}

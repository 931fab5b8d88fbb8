//! Time slices as 3D Tiles 1.1 (`hdlod::tiles`; docs/tiles.md):
//!
//! - `GET /api/v1/scenes/{scene}/tiles/tileset.json?time=T`: the root
//!   tileset at `T` (ISO 8601 or seconds);
//! - `GET /api/v1/scenes/{scene}/tiles/{seconds}/{id}.json`: its external
//!   tilesets, which the root file names relatively (`{seconds}/{id}.json`),
//!   so a client follows them without knowing this layout.
//!
//! - `GET /api/v1/scenes/{scene}/tiles/{seconds}/content/{cluster}.glb`:
//!   a tile's content at that time, the cluster's geometry with its
//!   elements' task status and look as per-feature properties
//!   (`hdlod::tiles::content`).
//!
//! A tree with object tables names that content; one without them points
//! at the geometry endpoint (`../geometry/HASH.glb` from the root file),
//! whose GLBs are content-addressed and cached forever.

use std::sync::Arc;

use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use hdlod::scene::Profile;
use hdlod::tiles::{ContentNames, DEFAULT_MAX_BYTES, Frame, Options, Tileset, content, time_slice};
use hdlod::time::TimeValue;
use hdlod::tree::Tree;

use super::AppState;
use super::cached::Cached;
use super::error::ApiError;
use super::handlers::find;
use crate::protocol::{parse_time_query, resolve_time, within_period};

/// The options of a slice at `t` served from `.../tiles/tileset.json`: the
/// external tilesets sit in `.../tiles/{t}/`; the content in
/// `.../tiles/{t}/content/` when the tree has object tables, else the GLBs
/// in `.../geometry/`. The frame only matters to the root file.
fn options(tree: &Tree, t: f64, max_bytes: usize, frame: Frame) -> Options {
    let (dir, content) = match tree.objects {
        Some(_) => (format!("{t}/content"), ContentNames::Cluster),
        None => ("../geometry".to_owned(), ContentNames::Geometry),
    };
    Options {
        max_bytes,
        content,
        frame,
        ..Options::new(dir, format!("{t}"))
    }
}

/// The root file for the query's `time`.
fn root_file(
    tree: &Tree,
    time: &TimeValue,
    frame: Frame,
    max_bytes: usize,
) -> Result<Tileset, ApiError> {
    let t = resolve_time(tree, "time", time)?;
    Ok(time_slice(tree, t, &options(tree, t, max_bytes, frame))?.root)
}

/// `?time=T[&frame=earth|local]`.
fn tileset_query(pairs: &[(String, String)]) -> Result<(TimeValue, Frame), ApiError> {
    let mut frame = Frame::Earth;
    let mut rest = Vec::new();
    for (key, value) in pairs {
        if key == "frame" {
            frame = match value.as_str() {
                "earth" => Frame::Earth,
                "local" => Frame::Local,
                other => {
                    return Err(ApiError::bad(
                        "frame",
                        format!("{other:?} is not a frame: use earth or local"),
                    ));
                }
            };
        } else {
            rest.push((key.clone(), value.clone()));
        }
    }
    Ok((parse_time_query(&rest)?, frame))
}

/// The external file `{time}/{file}` that a root file names.
fn external_file(
    tree: &Tree,
    time: &str,
    file: &str,
    max_bytes: usize,
) -> Result<Tileset, ApiError> {
    let t = seconds(time)?;
    let id: u32 = file
        .strip_suffix(".json")
        .and_then(|id| id.parse().ok())
        .ok_or_else(|| ApiError::not_found("subtree", format!("{file:?} is not ID.json")))?;
    let mut slice = time_slice(tree, t, &options(tree, t, max_bytes, Frame::Earth))?;
    slice.external.remove(&id).ok_or_else(|| {
        ApiError::not_found(
            "subtree",
            format!("no external tileset {id} in the slice at {t} s"),
        )
    })
}

/// The `{seconds}` segment of a slice's paths.
fn seconds(time: &str) -> Result<f64, ApiError> {
    let t = time
        .parse::<f64>()
        .ok()
        .filter(|t| t.is_finite())
        .ok_or_else(|| {
            ApiError::not_found("time", format!("{time:?} is not a number of seconds"))
        })?;
    Ok(within_period("time", t)?)
}

/// `{seconds}/content/{cluster}.glb`.
pub async fn content(
    State(state): State<Arc<AppState>>,
    Path((name, time, file)): Path<(String, String, String)>,
) -> Result<Response, ApiError> {
    let s = find(&state, &name)?;
    let t = seconds(&time)?;
    let tree = &s.tree;
    let id: u32 = file
        .strip_suffix(".glb")
        .and_then(|id| id.parse().ok())
        .ok_or_else(|| ApiError::not_found("cluster", format!("{file:?} is not CLUSTER.glb")))?;
    let hash = tree
        .clusters
        .get(id as usize)
        .and_then(|c| c.geometry.clone())
        .ok_or_else(|| ApiError::not_found("cluster", format!("no cluster {id} with geometry")))?;
    let path = s.dir.join("geometry").join(format!("{hash}.glb"));
    let scene = s.clone();
    // Reading and writing a GLB is blocking work.
    let glb = tokio::task::spawn_blocking(move || -> Result<Vec<u8>, ApiError> {
        let mesh = hdlod::io::read_mesh(&path)?;
        let tree = &scene.tree;
        let Some(tables) = &tree.objects else {
            return Err(ApiError::not_found(
                "scene",
                "the tree has no object tables: its tiles point at geometry/",
            ));
        };
        let default = Profile::default();
        let profile = tables.appearance().unwrap_or(&default);
        let object = tree.dynamic_object(id);
        Ok(content::content(&mesh, object, tables, profile, t))
    })
    .await
    .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, None, e.to_string()))??;
    Ok((
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("model/gltf-binary"),
        )],
        glb,
    )
        .into_response())
}

pub async fn tileset(
    State(state): State<Arc<AppState>>,
    Path(name): Path<String>,
    query: Result<Query<Vec<(String, String)>>, QueryRejection>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let Query(pairs) = query.map_err(|r| ApiError::bad("query", r.body_text()))?;
    let s = find(&state, &name)?;
    let (time, frame) = tileset_query(&pairs)?;
    let root = root_file(&s.tree, &time, frame, DEFAULT_MAX_BYTES)?;
    Ok(Cached::of(&root).answer(&headers))
}

pub async fn external(
    State(state): State<Arc<AppState>>,
    Path((name, time, file)): Path<(String, String, String)>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let s = find(&state, &name)?;
    let tileset = external_file(&s.tree, &time, &file, DEFAULT_MAX_BYTES)?;
    Ok(Cached::of(&tileset).answer(&headers))
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
            root_file(&tree, &TimeValue::Seconds(t), Frame::Earth, small).unwrap(),
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

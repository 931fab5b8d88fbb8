//! Time slices as 3D Tiles 1.1 (`hdlod::tiles`; docs/tiles.md):
//!
//! - `GET /api/v1/scenes/{scene}/tiles/tileset.json?time=T`: the root
//!   tileset at `T` (ISO 8601 or seconds); `&status=true` for content with
//!   each element's state at `T`, `&frame=local` for the local frame;
//! - `GET /api/v1/scenes/{scene}/tiles/{time}.json`: the same file with
//!   the time in its path, for clients that carry the tileset URL's query
//!   to every URL it names (CesiumJS);
//! - `GET /api/v1/scenes/{scene}/tiles/{dir}/{id}.json`: its external
//!   tilesets, which the root file names relatively (`{dir}` is the slice's
//!   seconds, `status-{seconds}` for a slice with state), so a client
//!   follows them without knowing this layout;
//! - `GET /api/v1/scenes/{scene}/tiles/content/{version}/{cluster}.glb`:
//!   a tile's content, the cluster's geometry with its elements' id, name,
//!   class, storey and task as per-feature properties
//!   (`hdlod::tiles::content`). The same for every date, so one URL is one
//!   GLB whatever the slice, cached as immutable: `{version}` is the tree's
//!   ([`LoadedScene::version`]), which a rebuild changes;
//! - `GET /api/v1/scenes/{scene}/tiles/{seconds}/content/{cluster}.glb`:
//!   the same with each element's task status, deviation and look at that
//!   time, for `status=true` slices (a skinned cluster's posed then);
//! - `GET /api/v1/scenes/{scene}/tiles/posed/{version}/{seconds}/{cluster}.glb`:
//!   a skinned cluster's content, its mesh posed by its skeleton at that
//!   time, which the default slices name instead of its bind pose; cached
//!   as immutable as `content/`, the time being in the URL.
//!
//! A tree without object tables points at the geometry endpoint
//! (`../geometry/HASH.glb` from the root file), whose GLBs are
//! content-addressed and cached forever.

use std::sync::Arc;

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use hdlod::scene::Profile;
use hdlod::tiles::{ContentNames, DEFAULT_MAX_BYTES, Frame, Options, Tileset, content, time_slice};
use hdlod::time::TimeValue;

use super::cached::Cached;
use super::error::{ApiError, quote};
use super::extract::{Pairs, Segments};
use super::handlers::{find, immutable_glb, not_modified};
use super::{AppState, LoadedScene};
use crate::protocol::{parse_time_query, resolve_time, within_period};

/// The prefix of the directory of a slice with state.
const STATUS: &str = "status-";

/// What a slice's content holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// The same content at every date (the default).
    Static,
    /// Each element's state at the slice's time too.
    Status,
}

/// The options of a slice at `t` served from `.../tiles/tileset.json`: the
/// external tilesets sit in `.../tiles/{t}/` (`status-{t}/` with state);
/// the content in `.../tiles/content/{version}/` or, with state,
/// `.../tiles/{t}/content/` when the tree has object tables, else the GLBs
/// in `.../geometry/`; skinned clusters' posed content in
/// `.../tiles/posed/{version}/{t}/`, or with the rest of a slice with
/// state. The frame only matters to the root file.
fn options(s: &LoadedScene, t: f64, max_bytes: usize, frame: Frame, kind: Kind) -> Options {
    let (dir, content) = match (&s.tree.objects, kind) {
        (None, _) => ("../geometry".to_owned(), ContentNames::Geometry),
        (Some(_), Kind::Static) => (format!("content/{}", s.version), ContentNames::Cluster),
        (Some(_), Kind::Status) => (format!("{t}/content"), ContentNames::Cluster),
    };
    let posed_dir = match kind {
        Kind::Static => format!("posed/{}/{t}", s.version),
        Kind::Status => format!("{t}/content"),
    };
    let subtilesets = match kind {
        Kind::Static => format!("{t}"),
        Kind::Status => format!("{STATUS}{t}"),
    };
    Options {
        max_bytes,
        content,
        posed_dir,
        frame,
        ..Options::new(dir, subtilesets)
    }
}

/// The root file for the query's `time`.
fn root_file(s: &LoadedScene, query: &TilesetQuery, max_bytes: usize) -> Result<Tileset, ApiError> {
    let t = resolve_time(&s.tree, "time", &query.time)?;
    Ok(time_slice(
        &s.tree,
        t,
        &options(s, t, max_bytes, query.frame, query.kind),
    )?
    .root)
}

struct TilesetQuery {
    time: TimeValue,
    frame: Frame,
    kind: Kind,
}

/// `?time=T[&frame=earth|local][&status=true|false]`.
fn tileset_query(pairs: &[(String, String)]) -> Result<TilesetQuery, ApiError> {
    let mut frame = Frame::Earth;
    let mut kind = Kind::Static;
    let mut rest = Vec::new();
    for (key, value) in pairs {
        match key.as_str() {
            "frame" => {
                frame = match value.as_str() {
                    "earth" => Frame::Earth,
                    "local" => Frame::Local,
                    other => {
                        return Err(ApiError::bad(
                            "frame",
                            format!("{} is not a frame: use earth or local", quote(other)),
                        ));
                    }
                };
            }
            "status" => {
                kind = match value.as_str() {
                    "true" => Kind::Status,
                    "false" => Kind::Static,
                    other => {
                        return Err(ApiError::bad(
                            "status",
                            format!("{} is not true or false", quote(other)),
                        ));
                    }
                };
            }
            _ => rest.push((key.clone(), value.clone())),
        }
    }
    Ok(TilesetQuery {
        time: parse_time_query(&rest)?,
        frame,
        kind,
    })
}

/// The external file `{dir}/{file}` that a root file names.
fn external_file(
    s: &LoadedScene,
    dir: &str,
    file: &str,
    max_bytes: usize,
) -> Result<Tileset, ApiError> {
    let (kind, time) = match dir.strip_prefix(STATUS) {
        Some(time) => (Kind::Status, time),
        None => (Kind::Static, dir),
    };
    let t = seconds(time)?;
    let id: u32 = file
        .strip_suffix(".json")
        .and_then(|id| id.parse().ok())
        .ok_or_else(|| ApiError::not_found("subtree", format!("{} is not ID.json", quote(file))))?;
    let mut slice = time_slice(&s.tree, t, &options(s, t, max_bytes, Frame::Earth, kind))?;
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
            ApiError::not_found(
                "time",
                format!("{} is not a number of seconds", quote(time)),
            )
        })?;
    Ok(within_period("time", t)?)
}

/// The cluster `{cluster}.glb` names.
fn cluster_of(file: &str) -> Result<u32, ApiError> {
    file.strip_suffix(".glb")
        .and_then(|id| id.parse().ok())
        .ok_or_else(|| {
            ApiError::not_found("cluster", format!("{} is not CLUSTER.glb", quote(file)))
        })
}

/// The GLB of cluster `id`: a skinned cluster posed at `pose`, with the
/// elements' state at `status` when given.
async fn cluster_glb(
    s: Arc<LoadedScene>,
    id: u32,
    pose: Option<f64>,
    status: Option<f64>,
) -> Result<Vec<u8>, ApiError> {
    let tree = &s.tree;
    let hash = tree
        .get_cluster(id)
        .and_then(|c| c.geometry.clone())
        .ok_or_else(|| ApiError::not_found("cluster", format!("no cluster {id} with geometry")))?;
    if tree.objects.is_none() {
        return Err(ApiError::not_found(
            "scene",
            "the tree has no object tables: its tiles point at geometry/",
        ));
    }
    let path = s.geometry_file(&hash);
    // Reading and writing a GLB is blocking work.
    tokio::task::spawn_blocking(move || -> Result<Vec<u8>, ApiError> {
        let tree = &s.tree;
        let tables = tree.objects.as_ref().expect("checked above");
        let default = Profile::default();
        let profile = tables.appearance().unwrap_or(&default);
        let state = status.map(|t| content::State { profile, t });
        Ok(content::cluster(tree, tables, id, &path, pose, state)?)
    })
    .await
    .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, None, e.to_string()))?
}

/// The tree's version, when `version` names it.
fn current(s: &LoadedScene, version: &str) -> Result<(), ApiError> {
    if version == s.version {
        return Ok(());
    }
    Err(ApiError::not_found(
        "version",
        format!(
            "the tree is at version {}, not {}: it was rebuilt, ask for the tileset again",
            s.version,
            quote(version)
        ),
    ))
}

/// `content/{version}/{cluster}.glb`: the same at every date.
pub async fn content(
    State(state): State<Arc<AppState>>,
    Segments((name, version, file)): Segments<(String, String, String)>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let s = find(&state, &name)?;
    current(&s, &version)?;
    let id = cluster_of(&file)?;
    let etag = HeaderValue::from_str(&format!("\"{version}-{id}.glb\"")).expect("ASCII");
    if let Some(answer) = not_modified(&headers, &etag) {
        return Ok(answer);
    }
    let glb = cluster_glb(s, id, None, None).await?;
    Ok(immutable_glb(etag, glb))
}

/// `posed/{version}/{seconds}/{cluster}.glb`: a skinned cluster posed at
/// that time. A rigid cluster's content is the same at every time, so it
/// has no URL here: one GLB, one URL.
pub async fn posed(
    State(state): State<Arc<AppState>>,
    Segments((name, version, time, file)): Segments<(String, String, String, String)>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let s = find(&state, &name)?;
    current(&s, &version)?;
    let t = seconds(&time)?;
    let id = cluster_of(&file)?;
    if s.tree.get_cluster(id).is_some() && s.tree.skeleton_of(id).is_none() {
        return Err(ApiError::not_found(
            "cluster",
            format!("cluster {id} is not skinned: its content is content/{version}/{id}.glb"),
        ));
    }
    let etag = HeaderValue::from_str(&format!("\"{version}-{t}-{id}.glb\"")).expect("ASCII");
    if let Some(answer) = not_modified(&headers, &etag) {
        return Ok(answer);
    }
    let glb = cluster_glb(s, id, Some(t), None).await?;
    Ok(immutable_glb(etag, glb))
}

/// `{seconds}/content/{cluster}.glb`: with the elements' state then. Not
/// cached as immutable: the tree's version is not in the URL.
pub async fn content_at(
    State(state): State<Arc<AppState>>,
    Segments((name, time, file)): Segments<(String, String, String)>,
) -> Result<Response, ApiError> {
    let s = find(&state, &name)?;
    let t = seconds(&time)?;
    let glb = cluster_glb(s, cluster_of(&file)?, Some(t), Some(t)).await?;
    Ok((
        [(
            axum::http::header::CONTENT_TYPE,
            HeaderValue::from_static("model/gltf-binary"),
        )],
        glb,
    )
        .into_response())
}

/// The root file for the query's pairs, with its ETag.
fn root_answer(
    state: &AppState,
    name: &str,
    pairs: &[(String, String)],
    headers: &HeaderMap,
) -> Result<Response, ApiError> {
    let s = find(state, name)?;
    let root = root_file(&s, &tileset_query(pairs)?, DEFAULT_MAX_BYTES)?;
    Ok(Cached::of(&root).answer(headers))
}

pub async fn tileset(
    State(state): State<Arc<AppState>>,
    Segments(name): Segments<String>,
    Pairs(pairs): Pairs,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    root_answer(&state, &name, &pairs, &headers)
}

/// `{time}.json`: the root file of `tileset.json?time=` with the time in its
/// path, beside it, so that it names the same files by the same relative
/// URIs. For clients that carry a tileset URL's query to every URL the
/// tileset names (CesiumJS does): there `?time=` would give each date's
/// content URLs of their own, which no cache of an earlier date answers.
pub async fn tileset_at(
    State(state): State<Arc<AppState>>,
    Segments((name, file)): Segments<(String, String)>,
    Pairs(mut pairs): Pairs,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let time = file
        .strip_suffix(".json")
        .ok_or_else(|| ApiError::not_found("time", format!("{} is not TIME.json", quote(&file))))?;
    if pairs.iter().any(|(key, _)| key == "time") {
        return Err(ApiError::bad(
            "time",
            "is given by the path (tiles/TIME.json), not the query",
        ));
    }
    pairs.push(("time".to_owned(), time.to_owned()));
    root_answer(&state, &name, &pairs, &headers)
}

pub async fn external(
    State(state): State<Arc<AppState>>,
    Segments((name, dir, file)): Segments<(String, String, String)>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let s = find(&state, &name)?;
    let tileset = external_file(&s, &dir, &file, DEFAULT_MAX_BYTES)?;
    Ok(Cached::of(&tileset).answer(&headers))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every stub URI of a split slice, with or without state, resolved as
    /// a client does from the file that holds it, names an external file
    /// the server answers.
    #[test]
    fn stub_uris_name_served_files() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t");
        let tree = hdlod_fixtures::sample::write_sample_tree(&path, 2, 6).unwrap();
        let s = super::super::load_one(&path).unwrap();
        for kind in [Kind::Static, Kind::Status] {
            stubs_are_served(&s, tree.time.seconds / 2.0, kind);
        }
    }

    fn stubs_are_served(s: &LoadedScene, t: f64, kind: Kind) {
        let small = 8 * 1024;
        let query = TilesetQuery {
            time: TimeValue::Seconds(t),
            frame: Frame::Earth,
            kind,
        };
        let mut pending: Vec<(Option<String>, Tileset)> =
            vec![(None, root_file(s, &query, small).unwrap())];
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
                    assert_eq!(time.starts_with(STATUS), kind == Kind::Status, "{time}");
                    let next = external_file(s, time, &format!("{id}.json"), small).unwrap();
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

//! The HTTP API (axum): `/api/v1/...`, `/healthz`, `/metrics`. The state
//! holds the loaded trees behind one `RwLock<Arc<_>>`: a request clones the
//! `Arc` and works on that snapshot, so a reload (SIGHUP) swaps in new trees
//! without disturbing requests in flight.

mod cached;
mod connection;
mod cors;
pub mod error;
mod extract;
mod geometry;
mod handlers;
pub mod listener;
pub mod memory;
pub mod metrics;
mod objects;
mod presence;
mod schedule;
mod stream;
mod tiles;
mod viewer;

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock, RwLock};
use std::time::Instant;

use axum::Router;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::middleware::Next;
use axum::response::Response;
use axum::routing::get;
use hdlod::tree::format::{
    CLUSTERS_FILE, INDEX_FILE, MANIFEST_FILE, OBJECTS_FILE, OBJECTS_INDEX_FILE,
};
use hdlod::tree::{Baseline, Layout, Tree, TreeSummary};
use tokio::sync::{OwnedSemaphorePermit, Semaphore, watch};
use tower_http::compression::CompressionLayer;

pub use self::cors::Cors;
use self::metrics::Metrics;
use crate::protocol::Fragments;

/// Largest request body: a cut request is well under 1 KiB.
pub const BODY_LIMIT: usize = 64 * 1024;

pub struct LoadedScene {
    pub tree: Tree,
    pub dir: PathBuf,
    pub summary: TreeSummary,
    pub baseline: Baseline,
    pub fragments: Fragments,
    /// What of the tree's files its tiles' content depends on, hashed: the
    /// content URLs carry it, so that one URL is one GLB for good and a
    /// rebuilt tree's content has new ones.
    pub version: String,
    /// The schedule and appearance answers, made on first request.
    pub schedule: OnceLock<cached::Cached>,
    pub appearance: OnceLock<cached::Cached>,
}

impl LoadedScene {
    /// Where the geometry file `hash` of the scene's tree is. A flat
    /// (`hdlod-tree/1`) tree migrated while served has its files moved
    /// into shards before the watcher reloads it: a file no longer at its
    /// flat path is looked for in its shard.
    pub fn geometry_file(&self, hash: &str) -> PathBuf {
        let path = self.tree.geometry_file(&self.dir, hash);
        if self.tree.layout == Layout::Flat && !path.exists() {
            return Layout::Sharded.geometry_file(&self.dir, hash);
        }
        path
    }
}

pub type Scenes = BTreeMap<String, Arc<LoadedScene>>;

pub struct AppState {
    scenes: RwLock<Arc<Scenes>>,
    sources: Vec<PathBuf>,
    pub metrics: Metrics,
    /// A place per WebSocket stream that may be open at once.
    streams: Arc<Semaphore>,
    max_streams: usize,
    /// Set once the server shuts down: every stream closes with 1001.
    closing: watch::Sender<bool>,
}

fn load_one(dir: &PathBuf) -> anyhow::Result<LoadedScene> {
    let tree = hdlod::tree::load(dir)?;
    // The name is the scene's URL: one that is no path segment would be
    // served where no request reaches it.
    if let Some(why) = hdlod::scene::format::name_problem(&tree.scene) {
        anyhow::bail!(
            "{}: the scene's name cannot be served: {why}",
            dir.display()
        );
    }
    if let Some(index) = tree
        .index()
        .filter(|i| i.version() < hdlod::tree::index::VERSION)
    {
        let made = if index.version() < 2 {
            "counts, baseline and node records are"
        } else {
            "node records (the clusters' triangles added) are"
        };
        tracing::info!(
            "{}: its index is of version {}, whose {made} made at every load: `hdlod index {}` \
             writes the current version",
            dir.display(),
            index.version(),
            dir.display()
        );
    }
    let summary = tree.summary();
    let baseline = tree.baseline().clone();
    let fragments = Fragments::of(&tree);
    let mut hasher = blake3::Hasher::new();
    // Mapped clusters and object rows are named by their index's
    // checksum: the JSON files are not read again.
    let clusters = match tree.index() {
        Some(index) => {
            hasher
                .update(INDEX_FILE.as_bytes())
                .update(&index.checksum());
            None
        }
        None => Some(CLUSTERS_FILE),
    };
    let objects = match tree.objects.as_ref().map(|t| t.rows()) {
        Some(rows) if rows.is_mapped() => {
            hasher
                .update(OBJECTS_INDEX_FILE.as_bytes())
                .update(&rows.checksum());
            None
        }
        _ => Some(OBJECTS_FILE),
    };
    for file in [Some(MANIFEST_FILE), clusters, objects]
        .into_iter()
        .flatten()
    {
        // A tree without object tables has no objects.json.
        if let Ok(bytes) = std::fs::read(dir.join(file)) {
            hasher.update(file.as_bytes()).update(&bytes);
        }
    }
    let version = hasher.finalize().to_hex()[..16].to_owned();
    Ok(LoadedScene {
        fragments,
        version,
        tree,
        baseline,
        dir: dir.clone(),
        summary,
        schedule: OnceLock::new(),
        appearance: OnceLock::new(),
    })
}

impl AppState {
    /// Loads every tree; two trees of the same scene name are an error.
    pub fn load(sources: Vec<PathBuf>, limits: &listener::Limits) -> anyhow::Result<Arc<AppState>> {
        let mut scenes = Scenes::new();
        for dir in &sources {
            let scene = load_one(dir)?;
            let name = scene.tree.scene.clone();
            if let Some(other) = scenes.insert(name.clone(), Arc::new(scene)) {
                anyhow::bail!(
                    "{} and {} both hold scene {name:?}",
                    other.dir.display(),
                    dir.display()
                );
            }
        }
        memory::loaded();
        Ok(Arc::new(AppState {
            scenes: RwLock::new(Arc::new(scenes)),
            sources,
            metrics: Metrics::default(),
            streams: Arc::new(Semaphore::new(limits.max_streams)),
            max_streams: limits.max_streams,
            closing: watch::channel(false).0,
        }))
    }

    /// Checks that every geometry file of every tree served is present
    /// (`store::check_geometry`, one listing of each geometry directory),
    /// and returns the errors. The start does not wait for it: a server
    /// runs it beside its first requests, and a GLB found missing is also
    /// answered as such by the request for it.
    pub fn check_geometry(&self) -> Vec<String> {
        let errors = self
            .scenes()
            .values()
            .filter_map(|s| hdlod::tree::store::check_geometry(&s.dir, &s.tree).err())
            .map(|e| format!("{e:#}"))
            .collect();
        // The listing's names (120,000 at paper scale) are freed: the
        // server goes on at the size it started with.
        memory::loaded();
        errors
    }

    /// A place for one more WebSocket stream, if the cap leaves one.
    pub fn stream_place(&self) -> Option<OwnedSemaphorePermit> {
        self.streams.clone().try_acquire_owned().ok()
    }

    pub fn max_streams(&self) -> usize {
        self.max_streams
    }

    /// Resolves once the server shuts down.
    pub fn closing(&self) -> impl Future<Output = ()> + Send + 'static {
        raised(self.closing.subscribe())
    }

    fn close_streams(&self) {
        self.closing.send_replace(true);
    }

    pub fn scenes(&self) -> Arc<Scenes> {
        self.scenes.read().expect("no panic while holding").clone()
    }

    /// Re-reads every tree from disk. A tree that fails to load keeps its
    /// previous version (and the error is returned for the log).
    pub fn reload(&self) -> Vec<String> {
        let old = self.scenes();
        let mut next = Scenes::new();
        let mut errors = Vec::new();
        for dir in &self.sources {
            // A tree replaced under a running server is checked whole
            // before it is served: one missing GLB keeps the previous tree.
            let checked = load_one(dir).and_then(|scene| {
                hdlod::tree::store::check_geometry(dir, &scene.tree)?;
                Ok(scene)
            });
            match checked {
                Ok(scene) => {
                    next.insert(scene.tree.scene.clone(), Arc::new(scene));
                }
                Err(e) => {
                    errors.push(format!("{e:#}"));
                    if let Some(previous) = old.values().find(|s| &s.dir == dir) {
                        next.insert(previous.tree.scene.clone(), previous.clone());
                    }
                }
            }
        }
        *self.scenes.write().expect("no panic while holding") = Arc::new(next);
        drop(old);
        memory::loaded();
        self.metrics.reloaded();
        errors
    }
}

/// Resolves once `flag` is set (or its sender is gone).
pub async fn raised(mut flag: watch::Receiver<bool>) {
    while !*flag.borrow_and_update() {
        if flag.changed().await.is_err() {
            return;
        }
    }
}

async fn record(State(state): State<Arc<AppState>>, request: Request, next: Next) -> Response {
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map(|p| p.as_str().to_owned())
        .unwrap_or_else(|| "unmatched".into());
    let start = Instant::now();
    let response = next.run(request).await;
    state.metrics.request(
        &route,
        response.status().as_u16(),
        start.elapsed().as_secs_f64(),
    );
    response
}

pub fn router(state: Arc<AppState>, cors: &Cors) -> Router {
    Router::new()
        .route("/", get(viewer::index))
        .route("/viewer/{file}", get(viewer::asset))
        .route("/healthz", get(handlers::healthz))
        .route("/metrics", get(handlers::metrics))
        .route("/api/v1/openapi.json", get(handlers::openapi))
        .route("/api/v1/scenes", get(handlers::scenes))
        .route("/api/v1/scenes/{scene}", get(handlers::scene))
        .route(
            "/api/v1/scenes/{scene}/cut",
            get(handlers::cut_get).post(handlers::cut_post),
        )
        .route("/api/v1/scenes/{scene}/geometry", get(geometry::batch))
        .route("/api/v1/scenes/{scene}/geometry/{file}", get(geometry::one))
        .route("/api/v1/scenes/{scene}/stream", get(stream::stream))
        .route("/api/v1/scenes/{scene}/objects", get(objects::objects))
        .route("/api/v1/scenes/{scene}/objects/{id}", get(objects::object))
        .route("/api/v1/scenes/{scene}/presence", get(presence::presence))
        .route("/api/v1/scenes/{scene}/schedule", get(schedule::schedule))
        .route(
            "/api/v1/scenes/{scene}/appearance",
            get(schedule::appearance),
        )
        .route("/api/v1/scenes/{scene}/tasks", get(objects::tasks))
        .route("/api/v1/scenes/{scene}/tasks/{id}", get(objects::task))
        .route(
            "/api/v1/scenes/{scene}/tiles/tileset.json",
            get(tiles::tileset),
        )
        .route(
            // `{time}.json`, the segment named as in the external tilesets' route
            // (the router takes one name per segment).
            "/api/v1/scenes/{scene}/tiles/{time}",
            get(tiles::tileset_at),
        )
        .route(
            "/api/v1/scenes/{scene}/tiles/content/{version}/{file}",
            get(tiles::content),
        )
        .route(
            "/api/v1/scenes/{scene}/tiles/posed/{version}/{time}/{file}",
            get(tiles::posed),
        )
        .route(
            "/api/v1/scenes/{scene}/tiles/{time}/{file}",
            get(tiles::external),
        )
        .route(
            "/api/v1/scenes/{scene}/tiles/{time}/content/{file}",
            get(tiles::content_at),
        )
        .fallback(handlers::not_found)
        .method_not_allowed_fallback(handlers::method_not_allowed)
        .layer(axum::middleware::from_fn(extract::json_errors))
        .layer(axum::middleware::from_fn_with_state(state.clone(), record))
        .layer(DefaultBodyLimit::max(BODY_LIMIT))
        .layer(CompressionLayer::new())
        .layer(cors.layer())
        .with_state(state)
}

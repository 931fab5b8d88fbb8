//! `GET /api/v1/scenes/{scene}/stream`: a WebSocket of cut diffs. The client
//! sends cut requests (the body of `POST .../cut`) as text messages; the
//! server answers each with what changed since its previous answer
//! (`schemas/api/stream-message.schema.json`): clusters to add, ids to
//! remove, new transforms of kept clusters. When the tree was reloaded in
//! between, ids may mean other clusters, so the answer has `reset: true`
//! and removes everything the client held.

use std::collections::HashMap;
use std::sync::Arc;

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, State};
use axum::response::Response;
use hdlod::tree::Cut;
use serde::Serialize;

use super::cut::{self, ClusterOut, StatsOut, cluster_out, scene_path};
use super::error::ApiError;
use super::handlers::find;
use super::{AppState, LoadedScene};

pub async fn stream(
    State(state): State<Arc<AppState>>,
    Path(name): Path<String>,
    ws: WebSocketUpgrade,
) -> Result<Response, ApiError> {
    find(&state, &name)?;
    Ok(ws
        .max_message_size(super::BODY_LIMIT)
        .on_upgrade(move |socket| serve(state, name, socket)))
}

/// Typed rather than `serde_json::Value` so that transforms keep their
/// shortest `f32` text, exactly as `POST .../cut` writes them.
#[derive(Serialize)]
struct Update {
    seq: u64,
    reset: bool,
    time: f64,
    add: Vec<ClusterOut>,
    remove: Vec<u32>,
    update: Vec<Moved>,
    stats: StatsOut,
}

#[derive(Serialize)]
struct Moved {
    id: u32,
    transform: Option<[f32; 16]>,
}

struct Session {
    scene: Option<Arc<LoadedScene>>,
    /// Cluster id -> its transform in the last answer.
    held: HashMap<u32, Option<[f32; 16]>>,
    cut: Cut,
    stack: Vec<u32>,
    seq: u64,
}

impl Session {
    fn update(&mut self, state: &AppState, name: &str, text: &str) -> Result<String, ApiError> {
        let scene = find(state, name)?;
        let request = cut::parse_json(text.as_bytes())?;
        let tree = &scene.tree;
        let (view, t) = cut::prepare(tree, &request)?;
        let micros = cut::run(tree, &view, t, &mut self.cut, &mut self.stack);
        state
            .metrics
            .cut(self.cut.stats.clusters, self.cut.stats.triangles);

        let reset = !self.scene.as_ref().is_some_and(|s| Arc::ptr_eq(s, &scene));
        let mut remove: Vec<u32> = Vec::new();
        if reset {
            remove.extend(self.held.keys());
            self.held.clear();
        }
        let prefix = scene_path(&tree.scene);
        let (mut add, mut update) = (Vec::new(), Vec::new());
        let mut next = HashMap::with_capacity(self.cut.items.len());
        for item in &self.cut.items {
            let transform = item.transform.map(|m| m.to_cols_array());
            match self.held.remove(&item.id) {
                None => add.push(cluster_out(tree, &prefix, item)),
                Some(old) if old != transform => update.push(Moved {
                    id: item.id,
                    transform,
                }),
                Some(_) => {}
            }
            next.insert(item.id, transform);
        }
        remove.extend(self.held.keys());
        remove.sort_unstable();
        self.held = next;
        self.scene = Some(scene.clone());
        self.seq += 1;
        let (baseline_triangles, baseline_objects) = scene.baseline.at(t);
        let message = Update {
            seq: self.seq,
            reset,
            time: t,
            add,
            remove,
            update,
            stats: StatsOut {
                clusters: self.cut.stats.clusters,
                triangles: self.cut.stats.triangles,
                visited: self.cut.stats.visited,
                micros,
                baseline_triangles,
                baseline_objects,
            },
        };
        Ok(serde_json::to_string(&message).expect("plain data serialises"))
    }
}

async fn serve(state: Arc<AppState>, name: String, mut socket: WebSocket) {
    state
        .metrics
        .ws_connections
        .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut session = Session {
        scene: None,
        held: HashMap::new(),
        cut: Cut::default(),
        stack: Vec::new(),
        seq: 0,
    };
    while let Some(Ok(message)) = socket.recv().await {
        let reply = match message {
            Message::Text(text) => match session.update(&state, &name, text.as_str()) {
                Ok(value) => {
                    state.metrics.ws_update();
                    value
                }
                Err(e) => e.body().to_string(),
            },
            Message::Binary(_) => ApiError::bad("message", "send cut requests as JSON text")
                .body()
                .to_string(),
            Message::Close(_) => break,
            Message::Ping(_) | Message::Pong(_) => continue,
        };
        if socket
            .send(Message::Text(reply.to_string().into()))
            .await
            .is_err()
        {
            break;
        }
    }
    state
        .metrics
        .ws_connections
        .fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
}

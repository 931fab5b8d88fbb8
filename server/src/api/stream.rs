//! `GET /api/v1/scenes/{scene}/stream`: a WebSocket of cut diffs. The client
//! sends cut requests (the body of `POST .../cut`) as text messages; the
//! server answers each with what changed since its previous answer
//! (`schemas/api/stream-message.schema.json`): clusters to add, ids to
//! remove, new transforms of kept clusters. When the tree was reloaded in
//! between, ids may mean other clusters, so the answer has `reset: true`
//! and removes everything the client held.

use std::sync::Arc;

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, State};
use axum::response::Response;
use hdlod::tree::Cut;
use rustc_hash::FxHashMap;

use super::error::ApiError;
use super::handlers::find;
use super::{AppState, LoadedScene};
use crate::protocol::{self, stats_out, write_number, write_transform};

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

/// What the client holds after the last answer. `stamp[id]` is the answer
/// (counted from 1) that last held cluster `id`: one `u32` per cluster of
/// the tree, so the diff indexes an array where a map would hash each
/// cluster twice, in less memory than a map of a large cut.
#[derive(Default)]
struct Held {
    stamp: Vec<u32>,
    answer: u32,
    /// The clusters of the last answer.
    ids: Vec<u32>,
    /// The transforms of the moving ones among them. Ids are small integers
    /// from our own tree, so a fast non-keyed hash is safe.
    transforms: FxHashMap<u32, [f32; 16]>,
}

#[derive(Default)]
struct Session {
    scene: Option<Arc<LoadedScene>>,
    held: Held,
    cut: Cut,
    stack: Vec<u32>,
    seq: u64,
    /// The last answer's length: the next one's buffer starts that big.
    last_len: usize,
}

impl Session {
    /// The answer to one request: `{"seq", "reset", "time", "add", "remove",
    /// "update", "stats"}`, written from the tree's JSON fragments (the
    /// added clusters exactly as `POST .../cut` writes them).
    fn update(&mut self, state: &AppState, name: &str, text: &str) -> Result<String, ApiError> {
        let scene = find(state, name)?;
        let request = protocol::parse_json(text.as_bytes())?;
        let tree = &scene.tree;
        let (view, t) = protocol::prepare(tree, &request)?;
        let micros = protocol::run(
            tree,
            &view,
            t,
            request.presence,
            &mut self.cut,
            &mut self.stack,
        );
        state
            .metrics
            .cut(self.cut.stats.clusters, self.cut.stats.triangles);

        // A reloaded tree's ids may mean other clusters; the stamps start
        // over then, and when they would wrap (after 4 billion answers).
        let held = &mut self.held;
        let reset =
            !self.scene.as_ref().is_some_and(|s| Arc::ptr_eq(s, &scene)) || held.answer == u32::MAX;
        let mut remove: Vec<u32> = Vec::new();
        if reset {
            remove.append(&mut held.ids);
            held.stamp.clear();
            held.stamp.resize(tree.clusters.len(), 0);
            held.answer = 0;
            held.transforms.clear();
        }
        let mut out = Vec::with_capacity(self.last_len.max(256));
        out.extend_from_slice(b"{\"seq\":");
        write_number(&mut out, &(self.seq + 1));
        out.extend_from_slice(if reset {
            b",\"reset\":true,\"time\":"
        } else {
            b",\"reset\":false,\"time\":"
        });
        write_number(&mut out, &t);
        out.extend_from_slice(b",\"add\":[");
        let (before, now) = (held.answer, held.answer + 1);
        held.answer = now;
        let mut moved: Vec<(u32, [f32; 16])> = Vec::new();
        let mut first = true;
        for item in &self.cut.items {
            let stamp = &mut held.stamp[item.id as usize];
            let kept = before != 0 && *stamp == before;
            *stamp = now;
            let transform = item.transform.map(|m| m.to_cols_array());
            if !kept {
                if !first {
                    out.push(b',');
                }
                first = false;
                scene.fragments.write_cluster(item, &mut out);
            } else if let Some(m) = transform
                && held.transforms.get(&item.id) != Some(&m)
            {
                moved.push((item.id, m));
            }
            if let Some(m) = transform {
                held.transforms.insert(item.id, m);
            }
        }
        for &id in &held.ids {
            if held.stamp[id as usize] != now {
                remove.push(id);
                held.transforms.remove(&id);
            }
        }
        held.ids.clear();
        held.ids.extend(self.cut.items.iter().map(|i| i.id));
        remove.sort_unstable();
        out.extend_from_slice(b"],\"remove\":");
        serde_json::to_writer(&mut out, &remove).expect("numbers serialise");
        out.extend_from_slice(b",\"update\":[");
        for (k, (id, transform)) in moved.iter().enumerate() {
            if k > 0 {
                out.push(b',');
            }
            out.extend_from_slice(b"{\"id\":");
            write_number(&mut out, id);
            out.extend_from_slice(b",\"transform\":");
            write_transform(&mut out, Some(transform));
            out.push(b'}');
        }
        out.extend_from_slice(b"],\"stats\":");
        serde_json::to_writer(&mut out, &stats_out(&self.cut, micros, &scene.baseline, t))
            .expect("plain data serialises");
        out.push(b'}');
        self.scene = Some(scene.clone());
        self.seq += 1;
        self.last_len = out.len();
        Ok(String::from_utf8(out).expect("JSON text is UTF-8"))
    }
}

async fn serve(state: Arc<AppState>, name: String, mut socket: WebSocket) {
    state
        .metrics
        .ws_connections
        .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut session = Session::default();
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
        if socket.send(Message::Text(reply.into())).await.is_err() {
            break;
        }
    }
    state
        .metrics
        .ws_connections
        .fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
}

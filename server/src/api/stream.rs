//! `GET /api/v1/scenes/{scene}/stream`: a WebSocket of cut diffs. The client
//! sends cut requests (the body of `POST .../cut`) as text messages; the
//! server answers each with what changed since its previous answer
//! (`schemas/api/stream-message.schema.json`): clusters to add, ids to
//! remove, new transforms (and a skinned cluster's new joint matrices) of
//! kept clusters. When the tree was reloaded in between, ids may mean other
//! clusters, so the answer has `reset: true` and removes everything the
//! client held.
//!
//! Limits (docs/api.md): a message is at most [`super::BODY_LIMIT`] bytes,
//! like a `POST .../cut` body; a longer one closes the stream with 1009
//! (message too big) and a reason. At most `--max-streams` streams are open
//! at once (the next gets a 503 before the upgrade), and shutdown closes
//! each with 1001 (going away).

use std::sync::Arc;

use axum::extract::State;
use axum::extract::ws::{CloseFrame, Message, WebSocket, close_code};
use axum::http::StatusCode;
use axum::response::Response;
use glam::Mat4;
use hdlod::tree::{Cut, CutItem};
use rustc_hash::FxHashMap;
use tokio::sync::OwnedSemaphorePermit;

use super::error::ApiError;
use super::extract::{Segments, Upgrade};
use super::handlers::find;
use super::{AppState, LoadedScene};
use crate::protocol::{self, stats_out, write_number, write_transform};

pub async fn stream(
    State(state): State<Arc<AppState>>,
    Segments(name): Segments<String>,
    Upgrade(ws): Upgrade,
) -> Result<Response, ApiError> {
    find(&state, &name)?;
    let place = state.stream_place().ok_or_else(|| {
        ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            Some("stream".into()),
            format!(
                "the server holds its maximum of {} streams; try again shortly",
                state.max_streams()
            ),
        )
    })?;
    // The transport reads messages up to TRANSPORT_LIMIT, so that one over
    // our limit is read whole and answered with a close frame; past the
    // transport's limit the frame is not even read, and the close is sent
    // as the connection breaks off.
    Ok(ws
        .max_message_size(TRANSPORT_LIMIT)
        .max_frame_size(TRANSPORT_LIMIT)
        .on_upgrade(move |socket| serve(state, name, socket, place)))
}

/// The largest message the WebSocket layer reads at all.
const TRANSPORT_LIMIT: usize = 16 * super::BODY_LIMIT;

/// Closes the stream with `code` and `reason` (at most 123 bytes, the
/// room a close frame has).
async fn close(socket: &mut WebSocket, code: u16, reason: &str) {
    let frame = CloseFrame {
        code,
        reason: reason.into(),
    };
    let _ = socket.send(Message::Close(Some(frame))).await;
}

fn too_big() -> String {
    format!("a message is at most {} bytes", super::BODY_LIMIT)
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
    /// The joint matrices of the skinned ones among them: a skinned
    /// cluster stands still (its transform is the identity) while its
    /// joints pose it.
    joints: FxHashMap<u32, Vec<[f32; 16]>>,
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
            (request.presence, request.lod),
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
            held.stamp.resize(tree.cluster_count(), 0);
            held.answer = 0;
            held.transforms.clear();
            held.joints.clear();
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
        // Kept clusters whose transform or joints changed: the item, and
        // whether its joints did.
        let mut moved: Vec<(&CutItem, bool)> = Vec::new();
        let mut first = true;
        for item in &self.cut.items {
            let stamp = &mut held.stamp[item.id as usize];
            let kept = before != 0 && *stamp == before;
            *stamp = now;
            let transform = item.transform.map(|m| m.to_cols_array());
            let joints: Option<Vec<[f32; 16]>> = item.joints.map(|_| {
                let matrices = self.cut.joints_of(item);
                matrices.iter().map(Mat4::to_cols_array).collect()
            });
            if !kept {
                if !first {
                    out.push(b',');
                }
                first = false;
                scene
                    .fragments
                    .write_cluster(&scene.tree, &self.cut, item, &mut out);
            } else {
                let turned = transform.is_some_and(|m| held.transforms.get(&item.id) != Some(&m));
                let posed = joints
                    .as_ref()
                    .is_some_and(|j| held.joints.get(&item.id) != Some(j));
                if turned || posed {
                    moved.push((item, posed));
                }
            }
            if let Some(m) = transform {
                held.transforms.insert(item.id, m);
            }
            if let Some(j) = joints {
                held.joints.insert(item.id, j);
            }
        }
        for &id in &held.ids {
            if held.stamp[id as usize] != now {
                remove.push(id);
                held.transforms.remove(&id);
                held.joints.remove(&id);
            }
        }
        held.ids.clear();
        held.ids.extend(self.cut.items.iter().map(|i| i.id));
        remove.sort_unstable();
        out.extend_from_slice(b"],\"remove\":");
        serde_json::to_writer(&mut out, &remove).expect("numbers serialise");
        out.extend_from_slice(b",\"update\":[");
        for (k, (item, posed)) in moved.iter().enumerate() {
            if k > 0 {
                out.push(b',');
            }
            out.extend_from_slice(b"{\"id\":");
            write_number(&mut out, &item.id);
            out.extend_from_slice(b",\"transform\":");
            write_transform(&mut out, item.transform.map(|m| m.to_cols_array()).as_ref());
            if *posed {
                out.extend_from_slice(b",\"joints\":[");
                for (j, m) in self.cut.joints_of(item).iter().enumerate() {
                    if j > 0 {
                        out.push(b',');
                    }
                    write_transform(&mut out, Some(&m.to_cols_array()));
                }
                out.push(b']');
            }
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

async fn serve(
    state: Arc<AppState>,
    name: String,
    mut socket: WebSocket,
    _place: OwnedSemaphorePermit,
) {
    state
        .metrics
        .ws_connections
        .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut session = Session::default();
    let closing = state.closing();
    tokio::pin!(closing);
    loop {
        let message = tokio::select! {
            message = socket.recv() => message,
            () = &mut closing => {
                close(&mut socket, close_code::AWAY, "the server is shutting down").await;
                break;
            }
        };
        let message = match message {
            None => break,
            Some(Ok(m)) => m,
            Some(Err(e)) => {
                // tungstenite's word for a message past the transport's
                // limit (its error type is not ours to match on: axum
                // wraps its own version).
                if e.to_string().contains("Space limit exceeded") {
                    close(&mut socket, close_code::SIZE, &too_big()).await;
                }
                break;
            }
        };
        let too_long = match &message {
            Message::Text(text) => text.len() > super::BODY_LIMIT,
            Message::Binary(bytes) => bytes.len() > super::BODY_LIMIT,
            _ => false,
        };
        if too_long {
            close(&mut socket, close_code::SIZE, &too_big()).await;
            break;
        }
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
    let before = state
        .metrics
        .ws_connections
        .fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
    // Dropped now rather than at the end of the scope: the trim below
    // should find the session's buffers already freed.
    drop(session);
    drop(socket);
    if before == 1 {
        super::memory::streams_idle();
    }
}

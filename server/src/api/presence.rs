//! `GET /api/v1/scenes/{scene}/presence`: when every object of the scene is
//! present, in one answer, by object index (the feature id its vertices
//! carry in the cluster geometry). The viewer fetches it once per scene and
//! hides, at any time and with no further request, the features of a drawn
//! cluster that are absent then (docs/viewer.md). A tree without
//! `objects.json` answers 404, as the object routes do.

use std::sync::Arc;

use axum::Json;
use axum::extract::State;
use axum::response::{IntoResponse, Response};
use serde::Serialize;

use super::AppState;
use super::error::ApiError;
use super::extract::{Pairs, Segments};
use super::handlers::find;
use super::objects::tables;

#[derive(Serialize)]
struct PresenceAnswer<'a> {
    scene: &'a str,
    /// `presence[i]` is object `i`'s half-open intervals `[start, end)` in
    /// seconds since the scene's start, sorted and apart; null is an open
    /// end; empty for an object never present.
    presence: Vec<Vec<[Option<f64>; 2]>>,
}

pub async fn presence(
    State(state): State<Arc<AppState>>,
    Segments(scene): Segments<String>,
    Pairs(pairs): Pairs,
) -> Result<Response, ApiError> {
    if let Some((key, _)) = pairs.first() {
        return Err(ApiError::bad(key, "unknown query parameter"));
    }
    let s = find(&state, &scene)?;
    let answer = PresenceAnswer {
        scene: &s.tree.scene,
        presence: {
            let rows = tables(&s)?.rows();
            (0..rows.len() as u32)
                .map(|i| rows.open_presence(i))
                .collect()
        },
    };
    Ok(Json(answer).into_response())
}

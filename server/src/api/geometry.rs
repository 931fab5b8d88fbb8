//! Cluster geometry: one GLB by its content hash, or many in one answer.
//!
//! A tree stores each cluster's GLB in the compact form
//! (`hdlod::io::compact`: quantized, meshopt-compressed), and the hash
//! names those bytes: they are what a request gets by default. The plain
//! form (`?encoding=plain`: `f32` attributes, no required extension) is
//! derived from them on request, the same bytes every time, under its own
//! ETag (`"HASH-plain"`).
//!
//! The batch (`GET .../geometry?h=HASH,HASH,...`) carries up to
//! [`MAX_BATCH`] GLBs in one body (docs/api.md, "Geometry batches"): a
//! little-endian `u32` length, the JSON index of that length
//! (`{"files": [{"hash", "offset", "length"}]}`, offsets from the start of
//! the body), then each GLB 8-byte aligned, in the order asked. The same
//! list asks for the same bytes, so it is cached as immutable too.

use std::sync::Arc;

use axum::body::Body;
use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

use super::error::{ApiError, quote};
use super::extract::{Pairs, Segments};
use super::handlers::{find, immutable, immutable_glb, not_modified};
use super::{AppState, LoadedScene};

/// The most GLBs one batch carries: 100 hashes fill 6.5 KiB of the request
/// line, within the server's 8 KiB.
pub const MAX_BATCH: usize = 100;

/// The content type of a batch body.
const BATCH_TYPE: &str = "application/vnd.hdlod.geometry-batch";

/// Which form of a GLB is asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Form {
    /// As stored: the compact form of trees built now.
    Stored,
    Plain,
}

impl Form {
    fn of(pairs: &[(String, String)]) -> Result<Form, ApiError> {
        match pairs.iter().find(|(k, _)| k == "encoding") {
            None => Ok(Form::Stored),
            Some((_, v)) if v == "compact" => Ok(Form::Stored),
            Some((_, v)) if v == "plain" => Ok(Form::Plain),
            Some((_, v)) => Err(ApiError::bad(
                "encoding",
                format!("{} is neither plain nor compact", quote(v)),
            )),
        }
    }

    fn suffix(self) -> &'static str {
        match self {
            Form::Stored => "",
            Form::Plain => "-plain",
        }
    }
}

/// Query keys other than `allowed` are an error naming the first.
fn only(pairs: &[(String, String)], allowed: &[&str]) -> Result<(), ApiError> {
    match pairs.iter().find(|(k, _)| !allowed.contains(&k.as_str())) {
        Some((k, _)) => Err(ApiError::bad(
            k.as_str(),
            format!("is not a parameter here (only {})", allowed.join(", ")),
        )),
        None => Ok(()),
    }
}

/// The GLB `hash` of scene `s` in the asked form.
async fn read(s: &Arc<LoadedScene>, hash: &str, form: Form) -> Result<Vec<u8>, ApiError> {
    let path = s.geometry_file(hash);
    let bytes = match tokio::fs::read(&path).await {
        Ok(bytes) => bytes,
        // The load does not list the geometry directory (docs/formats.md,
        // "Loading"): a file the tree names but that is not there is found
        // here, a damaged tree on this server, not a wrong request. 503,
        // not 404 (the request is right) nor 500: a load balancer retries
        // a 503 on another replica (docs/deploy.md).
        Err(e) if s.tree.names_geometry(hash) => {
            tracing::error!("{}: {e}: the tree is incomplete", path.display());
            return Err(ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                Some("hash".into()),
                format!(
                    "geometry {hash} of scene {} cannot be read ({e}): the tree on the server \
                     is incomplete",
                    quote(&s.tree.scene)
                ),
            ));
        }
        Err(_) => {
            return Err(ApiError::not_found(
                "hash",
                format!("no geometry {hash} in scene {}", quote(&s.tree.scene)),
            ));
        }
    };
    if form == Form::Stored {
        return Ok(bytes);
    }
    // Decoding and writing again is blocking work.
    tokio::task::spawn_blocking(move || match hdlod::io::compact::plain(&bytes) {
        Ok(std::borrow::Cow::Borrowed(_)) => Ok(bytes),
        Ok(std::borrow::Cow::Owned(plain)) => Ok(plain),
        Err(m) => Err(ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            Some("hash".into()),
            format!("{}: {m}", path.display()),
        )),
    })
    .await
    .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, None, e.to_string()))?
}

/// `GET .../geometry/{hash}.glb[?encoding=plain]`.
pub async fn one(
    State(state): State<Arc<AppState>>,
    Segments((name, file)): Segments<(String, String)>,
    Pairs(pairs): Pairs,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let s = find(&state, &name)?;
    let hash = file
        .strip_suffix(".glb")
        .filter(|h| hdlod::tree::is_hash(h))
        .ok_or_else(|| ApiError::not_found("hash", format!("{} is not HASH.glb", quote(&file))))?;
    only(&pairs, &["encoding"])?;
    let form = Form::of(&pairs)?;
    let etag =
        HeaderValue::from_str(&format!("\"{hash}{}\"", form.suffix())).expect("hex in quotes");
    if let Some(answer) = not_modified(&headers, &etag) {
        return Ok(answer);
    }
    Ok(immutable_glb(etag, read(&s, hash, form).await?))
}

/// `GET .../geometry?h=HASH,HASH,...[&encoding=plain]`.
pub async fn batch(
    State(state): State<Arc<AppState>>,
    Segments(name): Segments<String>,
    Pairs(pairs): Pairs,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let s = find(&state, &name)?;
    only(&pairs, &["h", "encoding"])?;
    let form = Form::of(&pairs)?;
    let list = pairs
        .iter()
        .find(|(k, _)| k == "h")
        .map(|(_, v)| v.as_str())
        .ok_or_else(|| ApiError::bad("h", "is required: the hashes, separated by commas"))?;
    let hashes: Vec<&str> = list.split(',').collect();
    if hashes.len() > MAX_BATCH {
        return Err(ApiError::bad(
            "h",
            format!(
                "{} hashes: at most {MAX_BATCH} in one request",
                hashes.len()
            ),
        ));
    }
    for (i, h) in hashes.iter().enumerate() {
        if !hdlod::tree::is_hash(h) {
            return Err(ApiError::bad(
                "h",
                format!(
                    "item {i}, {}, is not a geometry hash (64 hex digits)",
                    quote(h)
                ),
            ));
        }
        if hashes[..i].contains(h) {
            return Err(ApiError::bad("h", format!("{h} is given more than once")));
        }
    }
    let key = blake3::hash(format!("{list}{}", form.suffix()).as_bytes()).to_hex();
    let etag = HeaderValue::from_str(&format!("\"batch-{}\"", &key[..32])).expect("hex in quotes");
    if let Some(answer) = not_modified(&headers, &etag) {
        return Ok(answer);
    }
    let mut files = Vec::with_capacity(hashes.len());
    for h in &hashes {
        files.push(read(&s, h, form).await?);
    }
    Ok((
        [
            (header::CONTENT_TYPE, HeaderValue::from_static(BATCH_TYPE)),
            (header::ETAG, etag),
            (header::CACHE_CONTROL, immutable()),
        ],
        Body::from(pack(&hashes, &files)),
    )
        .into_response())
}

/// The batch body: the index's length, the index, the files 8-byte aligned.
fn pack(hashes: &[&str], files: &[Vec<u8>]) -> Vec<u8> {
    // The offsets depend on the index's length, which depends on the
    // offsets' digits: lay out with a guess, then again until it holds.
    let mut start = 0;
    loop {
        let mut at = start;
        let entries: Vec<_> = hashes
            .iter()
            .zip(files)
            .map(|(h, f)| {
                let entry = serde_json::json!({ "hash": h, "offset": at, "length": f.len() });
                at = (at + f.len()).next_multiple_of(8);
                entry
            })
            .collect();
        let index =
            serde_json::to_vec(&serde_json::json!({ "files": entries })).expect("JSON serialises");
        let first = (4 + index.len()).next_multiple_of(8);
        if first != start {
            start = first;
            continue;
        }
        let mut body = Vec::with_capacity(at);
        body.extend_from_slice(&(index.len() as u32).to_le_bytes());
        body.extend_from_slice(&index);
        for f in files {
            body.resize(body.len().next_multiple_of(8), 0);
            body.extend_from_slice(f);
        }
        return body;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_batch_body_indexes_each_file_where_it_lies() {
        let files = vec![vec![1u8; 13], vec![2u8; 1000], vec![3u8; 8]];
        let hashes = ["a", "b", "c"];
        let body = pack(&hashes, &files);
        let n = u32::from_le_bytes(body[..4].try_into().unwrap()) as usize;
        let index: serde_json::Value = serde_json::from_slice(&body[4..4 + n]).unwrap();
        for (k, entry) in index["files"].as_array().unwrap().iter().enumerate() {
            let offset = entry["offset"].as_u64().unwrap() as usize;
            let length = entry["length"].as_u64().unwrap() as usize;
            assert_eq!(offset % 8, 0);
            assert_eq!(entry["hash"], hashes[k]);
            assert_eq!(&body[offset..offset + length], &files[k][..]);
        }
    }
}

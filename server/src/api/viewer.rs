//! The web viewer (`server/viewer/`, docs/viewer.md), embedded in the
//! binary so that `hdlod serve` needs no files beside the trees: `/` is its
//! page, `/viewer/FILE` its scripts and style. Plain files, no build step.

use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};

use super::error::{ApiError, quote};
use super::extract::Segments;

const HTML: &str = "text/html; charset=utf-8";
const JS: &str = "text/javascript; charset=utf-8";
const CSS: &str = "text/css; charset=utf-8";

/// Name, content type, bytes of every file under `/viewer/`.
const FILES: [(&str, &str, &str); 15] = [
    ("index.html", HTML, include_str!("../../viewer/index.html")),
    ("viewer.css", CSS, include_str!("../../viewer/viewer.css")),
    ("main.js", JS, include_str!("../../viewer/main.js")),
    ("glb.js", JS, include_str!("../../viewer/glb.js")),
    ("mat4.js", JS, include_str!("../../viewer/mat4.js")),
    ("camera.js", JS, include_str!("../../viewer/camera.js")),
    ("renderer.js", JS, include_str!("../../viewer/renderer.js")),
    ("stream.js", JS, include_str!("../../viewer/stream.js")),
    ("pages.js", JS, include_str!("../../viewer/pages.js")),
    (
        "featurestate.js",
        JS,
        include_str!("../../viewer/featurestate.js"),
    ),
    ("objects.js", JS, include_str!("../../viewer/objects.js")),
    (
        "appearance.js",
        JS,
        include_str!("../../viewer/appearance.js"),
    ),
    ("colours.js", JS, include_str!("../../viewer/colours.js")),
    ("gantt.js", JS, include_str!("../../viewer/gantt.js")),
    // meshoptimizer's decoder as npm ships it (`meshopt_decoder.mjs` of
    // the `meshoptimizer` package, MIT), for the compact GLBs.
    (
        "meshopt_decoder.js",
        JS,
        include_str!("../../viewer/meshopt_decoder.js"),
    ),
];

fn file(name: &str) -> Option<Response> {
    let (_, kind, text) = FILES.iter().find(|(n, _, _)| *n == name)?;
    Some(
        (
            [
                (header::CONTENT_TYPE, HeaderValue::from_static(kind)),
                // The files change with the binary: revalidate, never go stale.
                (header::CACHE_CONTROL, HeaderValue::from_static("no-cache")),
            ],
            *text,
        )
            .into_response(),
    )
}

pub async fn index() -> Response {
    file("index.html").expect("index.html is embedded")
}

pub async fn asset(Segments(name): Segments<String>) -> Result<Response, ApiError> {
    file(&name)
        .ok_or_else(|| ApiError::not_found("file", format!("no viewer file {}", quote(&name))))
}

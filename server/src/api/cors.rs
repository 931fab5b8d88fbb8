//! Cross-origin access (CORS, the Fetch standard's "CORS protocol"): a
//! CesiumJS page or any web app on another origin reads tilesets, geometry,
//! cuts and tables. By default every origin may use the read-only routes
//! (GET and HEAD, preflights answered); `hdlod serve --cors-origin ORIGIN`
//! (repeatable, `*` for any) names the origins that may also POST cuts.
//! tower-http's `CorsLayer` does the protocol; this file only says who may
//! do what.

use axum::http::{HeaderName, HeaderValue, Method, header};
use tower_http::cors::{AllowOrigin, Any, CorsLayer};

/// Who may call the API from another origin.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum Cors {
    /// Any origin, read-only routes only.
    #[default]
    ReadOnly,
    /// These origins (or any, for `*`), every route.
    Origins(Vec<String>),
}

impl Cors {
    /// From the `--cors-origin` values; each is `*` or an origin such as
    /// `https://example.com` (scheme, host and port, no path).
    pub fn from_args(origins: &[String]) -> anyhow::Result<Cors> {
        for o in origins {
            if o != "*" && !is_origin(o) {
                anyhow::bail!(
                    "--cors-origin {o:?}: expected * or an origin such as https://example.com (scheme, host, optional port; no path)"
                );
            }
        }
        Ok(if origins.is_empty() {
            Cors::ReadOnly
        } else {
            Cors::Origins(
                origins
                    .iter()
                    .map(|o| o.trim_end_matches('/').to_owned())
                    .collect(),
            )
        })
    }

    /// The layer answering preflights and adding the CORS headers.
    pub fn layer(&self) -> CorsLayer {
        let exposed: [HeaderName; 2] = [header::ETAG, header::CONTENT_LENGTH];
        let base = CorsLayer::new()
            .allow_headers([header::CONTENT_TYPE, header::IF_NONE_MATCH])
            .expose_headers(exposed);
        match self {
            Cors::ReadOnly => base
                .allow_origin(Any)
                .allow_methods([Method::GET, Method::HEAD]),
            Cors::Origins(list) => {
                let origin = if list.iter().any(|o| o == "*") {
                    AllowOrigin::any()
                } else {
                    AllowOrigin::list(
                        list.iter()
                            .map(|o| HeaderValue::from_str(o).expect("checked in from_args")),
                    )
                };
                base.allow_origin(origin)
                    .allow_methods([Method::GET, Method::HEAD, Method::POST])
            }
        }
    }
}

/// `scheme://host[:port]`, http or https, a trailing `/` tolerated.
fn is_origin(o: &str) -> bool {
    let Some((scheme, rest)) = o.split_once("://") else {
        return false;
    };
    let host = rest.strip_suffix('/').unwrap_or(rest);
    matches!(scheme, "http" | "https")
        && !host.is_empty()
        && !host.contains('/')
        && HeaderValue::from_str(o).is_ok()
}
